"""Every run of a comparison through the scenario loader's checks, when the file is loaded.

A variant (or the reference, or the comparison's ``set``) changes values of the base scenario
after the loader checked it: FMU parameters (``bearing1.n_phi``), coupling keys
(``macro_step``), times, the output grid. Before, those values were checked by no one until the
variant's FMU started, minutes into the comparison (a 2.5 for an Integer, a ``psi`` outside the
FMU's declared range, an unknown parameter, a film grid over ``MAX_FILM_CELLS``, a macro step
longer than the run), or not at all (an analysed bearing whose clearance no longer fits the
analysis). Now each run's changes are given to the scenario loader as ``--set`` overrides of the
base scenario's file (:func:`orchestrator.scenario.load_scenario`, as ``rotorcosim validate
--set`` and a sweep's planning do), so every check of the loader applies, in its words: the
FMUs' declared ranges and types, unknown parameter names, the film grids
(``checks.check_film_grids``), the coupling and output keys and the step limits. The analysis
clearance (:func:`~orchestrator.scenario.analysis_clearance.analysis_clearance_problems`) is
checked on the scenario the run is given (the base with the changes), whose analysis keeps the
base's clearance. The parameter values the loader converted (``"2.0e-3"`` for a Real) are handed
back, so that each run is given what was checked, as a scenario's run is.

Each problem is reported at the comparison file's line of the value that caused it, with the
run's name: ``cmp.yaml:9: 'compare.variants[1].set' variant 'fine' sets bearing1.n_phi: 2.5:
parameter 'bearing1.n_phi' is Integer (got 2.5, a number); write an Integer value such as 3``.
"""

from __future__ import annotations

import contextlib
import json
import logging
import math
import re
from dataclasses import dataclass
from pathlib import Path
from typing import Any, Callable, Mapping

from orchestrator.errors import ScenarioError

#: a place in the comparison file: (the 'compare.' key to name, the mapping holding it, its key there)
Place = tuple[str, Any, Any]


@dataclass(frozen=True)
class RunChanges:
    """One run of a comparison as the loader sees it: ``changes`` (the comparison's dotted keys,
    in the order they apply: the common ``set``, the run's own, the output grid), ``who`` names
    the run in messages (``variant 'x'``), ``places`` the comparison file's place of each change
    and ``home`` the run's own place (its variant group) for a problem no single value caused."""

    who: str
    changes: Mapping[str, Any]
    places: Mapping[str, Place]
    home: Place


def override_path(key: str) -> str:
    """The loader's ``--set`` path of a comparison's dotted key: ``<instance>.<parameter>`` is
    ``fmus.<instance>.parameters.<parameter>``; ``stop_time``, ``coupling.*`` and ``output.*`` are
    the same path."""
    head = key.split(".", 1)[0]
    if "." in key and head not in ("coupling", "output"):
        inst, param = key.split(".", 1)
        return f"fmus.{inst}.parameters.{param}"
    return key


def value_text(value: Any) -> str:
    """``value`` as YAML text that the loader reads back as the same value (JSON, with YAML's
    ``.inf``/``.nan`` for the numbers JSON has no text for)."""
    if isinstance(value, float) and not math.isfinite(value):
        return ".nan" if math.isnan(value) else (".inf" if value > 0 else "-.inf")
    if isinstance(value, Mapping):          # e.g. coupling.step_control.atol: {'bearing*.*': .inf}
        return "{" + ", ".join(f"{json.dumps(str(k))}: {value_text(v)}" for k, v in value.items()) + "}"
    if isinstance(value, (list, tuple)):
        return "[" + ", ".join(value_text(v) for v in value) + "]"
    return json.dumps(value)


def _quiet_loader():
    """The loader's warnings (an interpolation order below the extrapolation order, ...) are said
    once for the base scenario; not again for each run, whose coupling the report describes."""
    from orchestrator.preflight import quiet_logger
    return quiet_logger("orchestrator.scenario", logging.ERROR)


_BEARING = re.compile(r"the bearing it analyses, '(?P<inst>[^']+)'")
_GIVEN = re.compile(r"\.clearance' is (?P<given>\S+) m, ")


def check_run_scenarios(source: Path | None, base, runs: list[RunChanges], apply: Callable,
                        bad: Callable[..., None]) -> dict[str, dict[str, Any]]:
    """Report through ``bad(key, msg, mapping, at)`` every problem the scenario loader finds in
    each run of ``runs`` (the base scenario's file ``source`` with the run's changes as
    ``--set`` overrides), and every analysis clearance that the run's bearing no longer has
    (``apply(base, changes)`` is the scenario the run is given). A problem the comparison's own
    ``set`` causes is reported once, not for every run. ``source`` None (a base made in code):
    nothing to load, only the clearance is checked.

    Returns, per run (``RunChanges.who``), the parameter values the loader converted: ``{key:
    value}`` for each ``<instance>.<parameter>`` change whose checked value differs from the one
    written (``"2.0e-3"`` for a Real is 0.002, ``40.0`` for an Integer is 40), so that the run is
    given what the loader checked, as a scenario's run is."""
    said: set[tuple] = set()
    loaded: dict[tuple, tuple] = {}
    converted: dict[str, dict[str, Any]] = {}
    with _extracted_once(source) as load:
        for run in runs:
            texts = {f"--set {override_path(k)}={value_text(v)}": k for k, v in run.changes.items()}
            overrides = tuple(t[len("--set "):] for t in texts)
            if load is not None and overrides not in loaded:
                loaded[overrides] = load(list(overrides))
            found, sc = loaded.get(overrides, ([], None))
            converted[run.who] = _converted(run, sc) if sc is not None else {}
            _report(run, base, texts, found, converted[run.who], apply, bad, said)
    return converted


def _converted(run: RunChanges, sc) -> dict[str, Any]:
    """The parameter changes of ``run`` whose value in the loaded scenario ``sc`` differs from the
    one written (in value or type)."""
    params = {f.name: f.parameters for f in sc.fmus}
    out = {}
    for k, raw in run.changes.items():
        path = override_path(k)
        if not path.startswith("fmus."):
            continue
        _, inst, _, name = path.split(".", 3)
        if name in params.get(inst, {}):
            new = params[inst][name]
            if type(new) is not type(raw) or new != raw:
                out[k] = new
    return out


@contextlib.contextmanager
def _extracted_once(source: Path | None):
    """A function that loads ``source`` with overrides and returns the loader's problems (None when
    there is no file). An SSP (or a YAML scenario naming one, ``ssp: FILE``) is extracted once for
    all runs, not once per run (its FMUs: megabytes each), and its problems keep naming the SSP."""
    from orchestrator.scenario import load_scenario
    from orchestrator.scenario.loader import from_ssp
    from orchestrator.scenario.nodes import GENERATED

    if source is None:
        yield None
        return
    try:
        made = from_ssp(source)
    except ScenarioError:                         # the base loaded from it: not expected
        made = source
    origins = GENERATED.get(str(made))

    def load(overrides: list[str]) -> tuple[list[str], Any]:
        if origins is not None:
            GENERATED[str(made)] = origins        # the loader forgets them after each load
        try:
            with _quiet_loader():
                return [], load_scenario(made, overrides)
        except ScenarioError as exc:
            return list(exc.problems), None
    try:
        yield load
    finally:
        GENERATED.pop(str(made), None)


def _report(run: RunChanges, base, texts: Mapping[str, str], found: list[str], converted: Mapping[str, Any],
            apply: Callable, bad: Callable[..., None], said: set) -> None:
    """Report the loader's problems ``found`` of ``run`` (each once: ``said``), else the analysis
    clearance problems of the scenario it is given (its changes with the ``converted`` values)."""
    from orchestrator.scenario.analysis_clearance import analysis_clearance_problems
    problems = [_placed(run, p, texts) for p in found]
    if not problems:
        try:
            sc = apply(base, {**run.changes, **converted})
        except (KeyError, ValueError, TypeError):
            sc = None                                 # reported by the comparison's own checks
        for p in analysis_clearance_problems(sc) if sc is not None else ():
            problems.append(_clearance(run, p))
    for (label, m, at), common, msg in problems:
        if (label, msg if common else (run.who, msg)) in said:
            continue
        said.add((label, msg if common else (run.who, msg)))
        bad(label, msg if common else f"{run.who} {msg}", m, at)


def _placed(run: RunChanges, problem: str, texts: Mapping[str, str]) -> tuple[Place, bool, str]:
    """``(place, from the common set, message)`` of one loader problem of ``run``: at the value
    whose ``--set`` text comes first in it (the problem's own place, or a factor it names),
    every ``--set`` text replaced by the comparison's key, value and line."""
    found = sorted((problem.find(t), t) for t in texts if t in problem)
    key = texts[found[0][1]] if found else None
    place = run.places.get(key, run.home) if key is not None else run.home
    text = problem
    if found and problem.startswith(found[0][1] + ": "):
        text = problem[len(found[0][1]) + 2:]
    for t in sorted(texts, key=len, reverse=True):
        if t in text:
            text = text.replace(t, _written(run, texts[t]))
    what = f"sets {_written(run, key)}" if key is not None else "makes its scenario invalid"
    return place, place[0] == "set", f"{what}: {text}"


def _written(run: RunChanges, key: str) -> str:
    """A change as the comparison file writes it: ``macro_step: 0.005`` (a coupling key of a variant
    group), ``bearing1.n_phi: 2.5`` (a ``set`` entry)."""
    place = run.places.get(key)
    return f"{place[2] if place is not None else key}: {run.changes[key]!r}"


def _clearance(run: RunChanges, problem: str) -> tuple[Place, bool, str]:
    """A clearance problem of ``run``: at the value that changed the analysed bearing's ``psi`` or
    ``R``, with the fix a comparison allows (its runs share the base scenario's analysis)."""
    m = _BEARING.search(problem)
    inst = m.group("inst") if m else None
    keys = [k for k in run.changes if inst is not None and k in (f"{inst}.psi", f"{inst}.R")]
    key = keys[-1] if keys else None
    place = run.places.get(key, run.home) if key is not None else run.home
    at = problem.find(": 'analysis.")
    text = problem[at + 2:] if at >= 0 else problem
    text = text.split("; write clearance:", 1)[0]
    what = f"sets {_written(run, key)}" if key is not None else "changes an analysed bearing"
    given = _GIVEN.search(text)
    stays = f" ({given.group('given')} m)" if given else ""
    return place, place[0] == "set", (
        f"{what}: {text}; every run of a comparison is analysed with the base scenario's clearance{stays}: change "
        f"psi and R together so that psi R stays that, or compare this bearing in a comparison of its own whose "
        "base scenario has it")
