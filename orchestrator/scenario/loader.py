"""Loading a scenario: read the sections, build our FMUs if asked, check against the FMUs.

:func:`load_scenario` raises one :class:`orchestrator.errors.ScenarioError` listing every
problem with ``file:line``; :func:`validate_scenario` returns them as lines.
"""

from __future__ import annotations

import re
from pathlib import Path
from typing import Sequence

from orchestrator.errors import ScenarioError
from orchestrator.scenario.checks import FmuChecks
from orchestrator.scenario.model import Scenario
from orchestrator.scenario.sections import Draft, SectionReader


class ScenarioLoader(FmuChecks, SectionReader):
    """One loading pass over one file: :meth:`read_sections`, optionally :meth:`build`, :meth:`check`."""

    def build(self, draft: Draft) -> None:
        """Let :func:`orchestrator.fmi.build.ensure_fmus` build our own FMUs when missing or stale."""
        from orchestrator.fmi import build
        try:
            build.ensure_fmus(draft.scenario())
        except Exception as exc:                        # reported with the scenario's other problems
            self.problems.append(f"{self.display}: building the scenario's FMUs failed ({type(exc).__name__}: "
                                 f"{exc}); run `rotorcosim build-fmus --force` to see the details")

    def check(self, draft: Draft) -> Scenario | None:
        """Check ``draft`` against its FMUs; the scenario, or None when any problem was found."""
        params = self.check_draft(draft)
        if self.problems:
            return None
        return draft.scenario(params)


def load_scenario(path: str | Path, overrides: Sequence[str] = (), *, build_fmus: bool = True) -> Scenario:
    """Load and validate a scenario file (format version 1).

    Parameters
    ----------
    path : the YAML file; FMU paths in it are relative to its folder.
    overrides : ``"key.path=value"`` strings (the CLI's ``--set``), applied before
        validation; the value is read as YAML (``5e-5``, ``true``, ``[a, b]``).
        Examples: ``coupling.macro_step=5e-5``, ``fmus.bearing1.parameters.n_phi=60``,
        ``connections.0.gain=2``. Unknown paths are errors.
    build_fmus : when the scenario is otherwise valid, let
        :func:`orchestrator.fmi.build.ensure_fmus` build or rebuild our own FMUs (in the
        repository's ``fmus/``) that are missing or stale, before their model descriptions
        are read. Building is a step between reading and checking, not part of the
        loader: ``build_fmus=False`` reads and checks only.

    Raises
    ------
    ScenarioError
        listing every problem found, each as ``file:line: what is wrong (got X); fix``.
    """
    loader = ScenarioLoader(Path(path), overrides)
    draft = loader.read_sections()
    if build_fmus and draft is not None and not loader.problems and draft.complete:
        loader.build(draft)
    scenario = loader.check(draft) if draft is not None else None
    if loader.problems or scenario is None:
        raise ScenarioError(sorted(loader.problems, key=line_order) or [f"{path}: invalid scenario"])
    return scenario


def line_order(problem: str) -> tuple[int, int]:
    """Sort key: ``--set`` problems first, then by line number in the file."""
    if problem.startswith("--set"):
        return (0, 0)
    m = re.match(r"^.*?:(\d+)(?::\d+)?: ", problem)
    return (1, int(m.group(1)) if m else 0)


def validate_scenario(path: str | Path, overrides: Sequence[str] = (), *,
                      build_fmus: bool = True) -> list[str]:
    """Every problem of a scenario file as readable lines (empty: the scenario is valid).

    Like :func:`load_scenario`, first builds our own FMUs that are missing or
    stale (``build_fmus=False``: only check, and report a missing FMU with the
    command that builds it).
    """
    try:
        load_scenario(path, overrides, build_fmus=build_fmus)
    except ScenarioError as exc:
        return list(exc.problems)
    return []
