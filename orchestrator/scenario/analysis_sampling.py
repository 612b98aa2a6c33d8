"""Does the recorded output resolve the rotation the run-up reaches?

The whirl analysis works in revolutions and warns *after* the run when ``results.csv`` has
fewer than 8 samples per revolution at the top speed (docs/analysis.md). For our rotor FMUs
the top speed is known before the run - ``f_max`` [Hz] on a ramp of ``t_ramp`` [s] - so the
loader says it at ``validate``, with the likely cause: ``f_max`` is in Hz (rev/s), and a speed
written in rpm is 60 times too large (my pump rotor with f_max: 24000, meant as rpm, ran to
9600 Hz by its stop time at 1 sample per revolution, and printed an onset "at 9010.7 Hz").
A warning, not an error: the run itself is right for the speed it was given.
"""

from __future__ import annotations

from orchestrator.scenario.analysis_clearance import parameter_value

ROTOR_MODELS = ("JeffcottRotor", "TurbochargerRotor")
MIN_SAMPLES_PER_REV = 8          # also the limit of orchestrator.results.whirl's own warning, which imports it


def _number(value):
    return float(value) if isinstance(value, (int, float)) and not isinstance(value, bool) else None


def check_analysis_sampling(loader, draft, params: dict, warn) -> None:
    """Warn (``warn(text)``, once per text) when the rotor whose ``omega`` is the analysis's
    speed signal reaches a speed the output interval does not resolve."""
    analysis = draft.kw.get("analysis")
    speed = analysis.get("speed") if isinstance(analysis, dict) else None
    if not isinstance(speed, str) or not speed.endswith(".omega"):
        return
    inst = speed.rpartition(".")[0]
    md = loader.fmu_caps.get(inst)
    if md is None or md.model_name not in ROTOR_MODELS:
        return
    spec = next((f for f in draft.fmus if f["name"] == inst), None)

    f_max, t_ramp = (parameter_value(inst, n, params, loader.mds) for n in ("f_max", "t_ramp"))
    start, stop = _number(draft.kw.get("start_time")), _number(draft.kw.get("stop_time"))
    h = _number((draft.coupling or {}).get("macro_step"))
    dt = _number(draft.interval) or h
    if None in (f_max, t_ramp, start, stop, dt) or not (f_max > 0 and dt > 0):
        return
    f_top = f_max if t_ramp <= 0 else f_max * min(max(stop, 0.0), t_ramp) / t_ramp
    if f_top <= 0:
        return
    n = 1.0 / (dt * f_top)
    if n >= MIN_SAMPLES_PER_REV:
        return
    node = (spec or {}).get("parameters", {}).get("f_max", (None, None))[1]
    where = loader.loc(node) if node is not None else str(loader.path)
    rpm = (f" (f_max is in Hz, revolutions per second: {f_max:g} rpm would be f_max: {f_max / 60:g})"
           if f_max > 2000 else "")
    warn(f"{where}: '{inst}' runs up to {f_top:g} Hz ({f_top * 60:.4g} rpm) by stop_time {stop:g} s, and "
         f"output.interval {dt:g} s records {n:.2g} samples per revolution there; the whirl analysis needs "
         f"at least {MIN_SAMPLES_PER_REV} (docs/analysis.md), so its amplitudes and onset above "
         f"{1.0 / (dt * MIN_SAMPLES_PER_REV):.4g} Hz are not resolved{rpm}; record every "
         f"{1.0 / (MIN_SAMPLES_PER_REV * f_top):.3g} s or less (output.interval, a multiple of the macro step)")
