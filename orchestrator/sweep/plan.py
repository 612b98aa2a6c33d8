"""From a checked sweep file to its runs: expansion (grid / zip / random), run ids, validation.

``plan_sweep(spec)`` expands the parameters into :class:`RunPlan` objects and loads and
validates the scenario of every run (``orchestrator.load_scenario`` with the run's
overrides) before anything runs, so that a bad value fails in seconds, not after an hour.
A run's id is a stable hash of its overrides: the same overrides give the same folder
``runs/<run_id>`` in every sweep, which is what ``--resume`` relies on.
"""

from __future__ import annotations

import hashlib
import itertools
import json
import re
from dataclasses import dataclass
from typing import Any

from orchestrator.errors import ScenarioError
from orchestrator.sweep.spec import SweepError, SweepSpec

__all__ = ["RunPlan", "expand", "plan_sweep", "override_text", "run_id_of"]


@dataclass(frozen=True, kw_only=True)
class RunPlan:
    """One run of a sweep: its id, parameter values by name and ``--set`` overrides."""

    run_id: str
    index: int                                   # position in the sweep (0-based)
    values: dict[str, Any]                       # parameter name -> value
    overrides: tuple[str, ...]                   # "key.path=value", the sweep's 'set' first


def override_text(path: str, value: Any) -> str:
    """``path=value`` with the value written as JSON, which the scenario loader reads as YAML
    (floats keep all their digits: ``repr``)."""
    return f"{path}={json.dumps(value)}"


def run_id_of(overrides) -> str:
    """A stable 12-hex-digit id of a run's overrides (order-independent; SHA-256)."""
    text = "\n".join(sorted(overrides))
    return hashlib.sha256(text.encode("utf-8")).hexdigest()[:12]


def _combinations(spec: SweepSpec) -> list[tuple]:
    lists = [p.values for p in spec.parameters]
    if spec.mode == "zip":
        return list(zip(*lists, strict=True))
    grid = list(itertools.product(*lists))
    if spec.mode == "grid":
        return grid
    if spec.samples > len(grid):
        raise SweepError(f"{spec.source}: 'samples' is {spec.samples} but the grid of the parameters has only "
                         f"{len(grid)} combinations; draw at most {len(grid)} or use mode: grid")
    import numpy as np
    picks = np.random.default_rng(spec.seed).choice(len(grid), size=spec.samples, replace=False)
    return [grid[i] for i in sorted(int(i) for i in picks)]


def expand(spec: SweepSpec) -> list[RunPlan]:
    """The runs of ``spec`` in sweep order (no scenario is loaded)."""
    common = [override_text(path, value) for path, value in spec.common]
    runs = []
    for i, combo in enumerate(_combinations(spec)):
        values = {p.name: v for p, v in zip(spec.parameters, combo, strict=True)}
        sets = [override_text(path, v) for p, v in zip(spec.parameters, combo, strict=True) for path in p.paths]
        overrides = tuple(common + sets)
        runs.append(RunPlan(run_id=run_id_of(overrides), index=i, values=values, overrides=overrides))
    first: dict[str, RunPlan] = {}
    for run in runs:
        if run.run_id in first:
            raise SweepError(f"{spec.source}: runs {first[run.run_id].index + 1} and {run.index + 1} are the same "
                             f"run ({run.values}); in mode zip every column of values must differ somewhere: "
                             "remove the repetition")
        first[run.run_id] = run
    return runs


def _where(spec: SweepSpec, problem: str, run: RunPlan) -> str:
    """A scenario problem of one run, placed at the sweep file line its override came from."""
    m = re.match(r"^--set ([^=]+)=", problem)
    label = ", ".join(f"{k}={v!r}" for k, v in run.values.items())
    if m and m.group(1).strip() in spec.lines:
        return f"{spec.source}:{spec.lines[m.group(1).strip()]}: run {label}: {problem}"
    return f"{spec.source}: run {label}: scenario {spec.scenario.name}: {problem}"


def plan_sweep(spec: SweepSpec, *, build_fmus: bool = True) -> list[RunPlan]:
    """Expand ``spec`` and validate every run's scenario; raises :class:`SweepError` with every
    problem (each once, placed at its sweep-file line where an override caused it).

    ``build_fmus``: the first run's load may build our own FMUs when missing or stale (as
    ``rotorcosim run`` does), once, here in the client, so that parallel runs never race
    to build them; the other runs only check.
    """
    from orchestrator import load_scenario

    runs = expand(spec)
    problems: list[str] = []
    for k, run in enumerate(runs):
        try:
            load_scenario(spec.scenario, list(run.overrides), build_fmus=build_fmus and k == 0)
        except ScenarioError as exc:
            for p in exc.problems:
                text = _where(spec, p, run)
                generic = re.sub(r"run [^:]*: ", "", text, count=1)
                if text not in problems and not any(re.sub(r"run [^:]*: ", "", q, count=1) == generic
                                                    for q in problems):
                    problems.append(text)
        if len(problems) >= 50:
            problems.append(f"{spec.source}: stopped after 50 problems; fix these first")
            break
    if problems:
        raise SweepError(problems)
    return runs
