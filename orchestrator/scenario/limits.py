"""Numeric limits of a scenario and the checks that apply them outside the YAML reader.

The loader refuses scenarios beyond these (``file:line`` messages that say the limit,
see :meth:`orchestrator.scenario.sections.SectionReader.check_step_count`);
:func:`limit_problems` applies the same limits to a :class:`Scenario` built in code
(a compare variant: the base scenario with changes). docs/limits.md lists them.
"""

from __future__ import annotations

import math

from orchestrator.scenario.model import Scenario

MAX_MACRO_STEPS = 10**8           # (stop_time - start_time) / macro_step
MAX_OUTPUT_ROWS = 10**7           # (stop_time - start_time) / output.interval: rows of results.csv
MAX_SUBSTEPS = 10**4              # coupling.substeps and fmus.<name>.substeps
MIN_RELATIVE_STEP = 1e-10         # macro_step / max(|start_time|, |stop_time|): t0 + n*h stays resolvable
MIN_MACRO_STEP = 1e-15            # s: the master's weights take powers of 1/h up to the third
                                  # (input derivatives; a 1e-301 s step overflowed); 1 fs is far below any step
MAX_FMU_INSTANCES = 256           # entries of 'fmus' (a 10 kB file listed thousands, each an FMU loaded)
MAX_WORKER_PROCESSES = 32         # default of ROTORCOSIM_MAX_WORKERS: FMU instances in worker processes


def step_slack(t0: float, t_stop: float, h: float) -> float:
    """By how much (in macro steps) the grid ``t0 + n*h`` may miss a time between ``t0`` and
    ``t_stop`` through rounding alone: 1e-9, or more when the times are large against the step
    (16 units in the last place of the larger time, over ``h``: up to 3.5e-6 at the limit
    :data:`MIN_RELATIVE_STEP`). At start_time 31536000 s (a year) and h = 0.1 s,
    ``(t0 + 3*h - t0) / h`` is 3.0000000447: a remainder of 1e-9 steps was not absorbed there."""
    return max(1e-9, 16 * math.ulp(max(abs(t0), abs(t_stop))) / h)


def max_worker_processes() -> int:
    """How many FMU instances may run in worker processes at once (``isolation: process``, and
    ``validate``, which loads every FMU in one): ``ROTORCOSIM_MAX_WORKERS`` or
    :data:`MAX_WORKER_PROCESSES`. Each worker is a Python process of about 35 MB; a scenario of
    2000 instances made ``validate`` start 2000 of them at once."""
    from orchestrator.untrusted import env_number
    return int(env_number("ROTORCOSIM_MAX_WORKERS", MAX_WORKER_PROCESSES, minimum=1, maximum=4096, integer=True,
                          meaning="FMU instances in worker processes at once"))


def limit_problems(sc: Scenario) -> list[str]:
    """The numeric limits of the loader applied to a Scenario built in code (e.g. a compare
    variant, the base with changes): [] when it stays within them."""
    start, stop, h = sc.start_time, sc.stop_time, sc.coupling.macro_step
    nums = {"start_time": start, "stop_time": stop, "coupling.macro_step": h}
    bad = [f"'{k}' must be a finite number (got {v!r})" for k, v in nums.items()
           if isinstance(v, bool) or not isinstance(v, (int, float)) or not math.isfinite(v)]
    if bad:
        return bad
    if stop <= start or h <= 0:
        return [f"needs stop_time > start_time and macro_step > 0 (got {start!r}, {stop!r}, {h!r})"]
    scale = max(abs(start), abs(stop))
    if h < MIN_RELATIVE_STEP * scale:
        return [f"macro_step {h!r} is too small for the time {scale:g} s (the limit is macro_step >= "
                f"{MIN_RELATIVE_STEP:g} * max(|start_time|, |stop_time|))"]
    if h < MIN_MACRO_STEP:
        return [f"macro_step {h!r} s is below the smallest macro step, {MIN_MACRO_STEP:g} s"]
    out = []
    if (stop - start) / h > MAX_MACRO_STEPS:
        out.append(f"(stop_time - start_time) / macro_step = {(stop - start) / h:.3g} macro steps (the limit is "
                   f"{MAX_MACRO_STEPS:.0e})")
    every = sc.output.interval or h
    if not (isinstance(every, (int, float)) and every > 0) or (stop - start) / every > MAX_OUTPUT_ROWS:
        out.append(f"output every {every!r} s gives too many rows (the limit is {MAX_OUTPUT_ROWS:.0e})")
    for m in [sc.coupling.substeps] + [f.substeps for f in sc.fmus if f.substeps is not None]:
        if isinstance(m, bool) or not isinstance(m, int) or not 1 <= m <= MAX_SUBSTEPS:
            out.append(f"substeps must be an integer between 1 and {MAX_SUBSTEPS} (got {m!r})")
    return out


def check_overrides(overrides) -> None:
    """``overrides`` must be a sequence of "key.path=value" texts (not one text, which
    would be read letter by letter)."""
    if isinstance(overrides, (str, bytes)):
        raise TypeError(f"load_scenario(overrides=...) takes a list of 'key.path=value' texts (got the text "
                        f"{overrides!r}); write overrides=[{overrides!r}]")
    if hasattr(overrides, "keys") and hasattr(overrides, "items"):     # a mapping: its keys alone were read
        shown = [f"{k}={v}" for k, v in list(overrides.items())[:2]]
        raise TypeError(f"load_scenario(overrides=...) takes a list of 'key.path=value' texts (got a "
                        f"{type(overrides).__name__}); write overrides={shown!r}")
    try:
        items = list(overrides)
    except TypeError:
        raise TypeError(f"load_scenario(overrides=...) takes a list of 'key.path=value' texts (got "
                        f"{type(overrides).__name__}); e.g. overrides=['coupling.macro_step=5e-5']") from None
    bad = [o for o in items if not isinstance(o, str)]
    if bad:
        raise TypeError(f"load_scenario(overrides=...): every override is a 'key.path=value' text (got {bad[0]!r}); "
                        "e.g. overrides=['coupling.macro_step=5e-5']")
