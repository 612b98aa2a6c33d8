"""From a checked sweep file to its runs: expansion (grid / zip / random), run ids, validation.

``plan_sweep(spec)`` expands the parameters into :class:`RunPlan` objects and loads and
validates the scenario of every run (``orchestrator.load_scenario`` with the run's
overrides) before anything runs, so that a bad value fails in seconds, not after an hour.
A run's id is a stable hash of its overrides: the same overrides give the same folder
``runs/<run_id>`` in every sweep, which is what ``--resume`` relies on.

The number of runs is computed from the parameters' value counts before any run is made
(:func:`count_runs`), and a sweep of more than :data:`MAX_RUNS` runs is refused; mode
``random`` draws its runs' grid positions as numbers and decodes each into one value per
parameter (the last parameter fastest, as in mode ``grid``), so the grid itself is never
built, however large.
"""

from __future__ import annotations

import hashlib
import itertools
import json
import math
import re
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from orchestrator.errors import ScenarioError
from orchestrator.sweep.spec import SweepError, SweepSpec

__all__ = ["RunPlan", "expand", "plan_sweep", "override_text", "run_id_of", "count_runs", "MAX_RUNS"]

# Runs of one sweep. Every run's scenario is loaded and validated before the first run starts
# (5-12 ms each on the shared 2-core host: 10 000 runs take 1-2 min before anything runs), and
# the table and map hold one row per run. Read when used: raise it in a script if you must.
MAX_RUNS = 10_000
PROGRESS_FROM_RUNS = 200


@dataclass(frozen=True, kw_only=True)
class RunPlan:
    """One run of a sweep: its id, parameter values by name and ``--set`` overrides."""

    run_id: str
    index: int                                   # position in the sweep (0-based)
    values: dict[str, Any]                       # parameter name -> value
    overrides: tuple[str, ...]                   # "key.path=value", the sweep's 'set' first
    # what the run computes from besides its overrides: digests of the scenario file, each instance's
    # FMU and every other file its loading read (plan.run_inputs; --resume redoes a run recorded with
    # other inputs)
    inputs: dict[str, Any] = field(default_factory=dict, compare=False, hash=False)


def override_text(path: str, value: Any) -> str:
    """``path=value`` with the value written as JSON, which the scenario loader reads as YAML
    (floats keep all their digits: ``repr``)."""
    return f"{path}={json.dumps(value)}"


def run_id_of(overrides) -> str:
    """A stable 12-hex-digit id of a run's overrides (order-independent; SHA-256)."""
    text = "\n".join(sorted(overrides))
    return hashlib.sha256(text.encode("utf-8")).hexdigest()[:12]


def grid_size(spec: SweepSpec) -> int:
    """The number of combinations of the parameters' values (a Python int: no overflow)."""
    return math.prod(len(p.values) for p in spec.parameters)


def count_runs(spec: SweepSpec) -> int:
    """The number of runs of ``spec``, from the value counts alone (nothing is expanded).

    Raises :class:`SweepError` when it is above :data:`MAX_RUNS`, or when mode ``random``
    draws more samples than the grid has.
    """
    counts = [len(p.values) for p in spec.parameters]
    if spec.mode == "zip":
        n = counts[0] if counts else 0
    elif spec.mode == "grid":
        n = math.prod(counts)
    else:
        n = spec.samples
        size = math.prod(counts)
        if n > size:
            raise SweepError(f"{spec.source}: 'samples' is {n} but the grid of the parameters has only "
                             f"{size} combinations; draw at most {size} or use mode: grid")
    if n > MAX_RUNS:
        first = spec.parameters[0].line if spec.parameters else None
        where = f"{spec.source}:{first}" if first else str(spec.source)
        each = " x ".join(f"{p.name} ({len(p.values)}, line {p.line})" for p in spec.parameters)
        if spec.mode == "random":
            raise SweepError(f"{where}: 'samples' is {n}, more runs than a sweep may have (the limit is "
                             f"{MAX_RUNS}, orchestrator.sweep.plan.MAX_RUNS); draw at most {MAX_RUNS}")
        made = "the grid of" if spec.mode == "grid" else "mode zip over"
        fix = ("give the parameters fewer values (linspace/logspace count, values list), or draw some of "
               f"the combinations with 'mode: random' and 'samples: N' (N <= {MAX_RUNS})")
        raise SweepError(f"{where}: {made} the parameters {each} makes {_count_text(n)} runs, more than a sweep may "
                         f"have (the limit is {MAX_RUNS}, orchestrator.sweep.plan.MAX_RUNS); {fix}")
    return n


def _count_text(n: int) -> str:
    """``n`` in digits, or ``about 10^k`` for a count too long to read (or to print: Python
    refuses ints of more than 4300 digits)."""
    if n < 10**12:
        return str(n)
    return f"about 10^{int(n.bit_length() * math.log10(2))}"


def _decode(index: int, lists: list[tuple]) -> tuple:
    """The combination at position ``index`` of ``itertools.product(*lists)`` (mixed radix,
    the last list fastest), without building the product."""
    combo = []
    for values in reversed(lists):
        index, k = divmod(index, len(values))
        combo.append(values[k])
    return tuple(reversed(combo))


def _draw(size: int, samples: int, seed: int) -> list[int]:
    """``samples`` distinct positions in ``range(size)``, sorted, the same for the same seed.

    numpy's generator as before (its draw without replacement needs memory for the samples
    only, or for the grid when that is under 50 times the samples); beyond int64 Python's own
    generator, drawing positions of any size until ``samples`` differ (``samples`` is at most
    :data:`MAX_RUNS`, the grid at least 2^62: a repeat is next to impossible).
    """
    if size < 2**62:
        import numpy as np
        picks = np.random.default_rng(seed).choice(size, size=samples, replace=False)
        return sorted(int(i) for i in picks)
    import random
    rng, picks = random.Random(seed), set()
    while len(picks) < samples:
        picks.add(rng.randrange(size))
    return sorted(picks)


def _combinations(spec: SweepSpec) -> list[tuple]:
    count_runs(spec)                                  # refuses too many runs before building any
    lists = [p.values for p in spec.parameters]
    if spec.mode == "zip":
        return list(zip(*lists, strict=True))
    if spec.mode == "grid":
        return list(itertools.product(*lists))
    return [_decode(i, lists) for i in _draw(grid_size(spec), spec.samples, spec.seed)]


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
    c = _CLEARANCE_HINT.search(problem)
    axes = [k for k in re.findall(r"--set ([^=\s]+)=", c.group("sets")) if spec.lines.get(k)] if c else []
    if axes:
        # the analysis clearance the scenario's line gives no longer fits the psi (or R) a sweep axis sets
        axis, target, value = axes[0], c.group("target"), c.group("value")
        line = spec.lines[axis]
        fix = (f"the sweep's line {line} sets {axis}: add to the sweep a parameter that sets "
               f"{target} to each run's psi R (here {value}), with as many values as the {axis} column"
               if spec.mode == "zip" else
               f"the sweep's line {line} sets {axis}: leave 'clearance' out of the scenario's "
               f"analysis.journals (each run then takes psi R of its bearing), or use mode: zip with a "
               f"parameter that sets {target} to each run's psi R (here {value})")
        return (f"{spec.source}:{line}: run {label}: scenario {spec.scenario.name}: "
                f"{problem[:c.start()]}; {fix}")
    return f"{spec.source}: run {label}: scenario {spec.scenario.name}: {problem}"


#: the hint of the analysis clearance check when a --set of psi or R made the clearance wrong
#: (orchestrator/scenario/analysis_clearance.py)
_CLEARANCE_HINT = re.compile(r"; (?P<sets>--set .*?) changed it: add --set (?P<target>[^=\s]+)=(?P<value>\S+)$")


def run_inputs(scenario_file: Path, scenario, cache: dict) -> dict[str, Any]:
    """The files a run computes from besides its overrides, as digests
    (:func:`orchestrator.read_log.fingerprint`: SHA-256, or size and time of a file above its
    limit): ``{"scenario": ..., "fmus": {instance: ...}, "files": {path: ...}}``, where ``files``
    holds every other file loading the run's scenario read (``Scenario.inputs``, recorded by the
    loader: an SSP and its .ssd/.ssv files, a file a String parameter names such as a rotor file).
    Recorded in the run's sweep_run.json; ``--resume`` runs again a finished run whose inputs have
    changed since (an edited scenario, a rebuilt FMU, an edited .ssv), where the overrides alone
    would reuse its stale results. A file that cannot be read now is recorded as ``"unreadable"``."""
    from orchestrator.read_log import fingerprint

    def digest(path) -> str:
        try:
            return fingerprint(path, cache)
        except OSError:
            return "unreadable"
    try:
        main = str(Path(scenario_file).resolve())
        fmu_paths = {str(Path(f.path).resolve()) for f in scenario.fmus}
    except (OSError, RuntimeError):
        return {}
    return {"scenario": digest(scenario_file),
            "fmus": {f.name: digest(f.path) for f in scenario.fmus},
            "files": {p: digest(p) for p in getattr(scenario, "inputs", ()) if p != main and p not in fmu_paths}}


def plan_sweep(spec: SweepSpec, *, build_fmus: bool = True, progress: bool | None = False) -> list[RunPlan]:
    """Expand ``spec`` and validate every run's scenario; raises :class:`SweepError` with every
    problem (each once, placed at its sweep-file line where an override caused it).

    ``build_fmus``: the first run's load may build our own FMUs when missing or stale (as
    ``rotorcosim run`` does), once, here in the client, so that parallel runs never race
    to build them; the other runs only check. ``progress``: a bar while validating (None: when
    stderr is a terminal), shown from :data:`PROGRESS_FROM_RUNS` runs on (a few ms per run).
    """
    from tqdm import tqdm

    from orchestrator import load_scenario
    from orchestrator.scenario.analysis_clearance import check_analysis_clearance

    runs = expand(spec)
    problems: list[str] = []
    bar = tqdm(runs, unit="run", desc="validating", leave=False, dynamic_ncols=True,
               disable=len(runs) < PROGRESS_FROM_RUNS or (not progress if progress is not None else None))
    digests: dict = {}
    for k, run in enumerate(bar):
        try:
            sc = load_scenario(spec.scenario, list(run.overrides), build_fmus=build_fmus and k == 0)
            check_analysis_clearance(sc)          # each run analyses its run-up
            run.inputs.update(run_inputs(spec.scenario, sc, digests))
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
    bar.close()
    if problems:
        raise SweepError(problems)
    return runs
