"""Whole-run-up table of docs/compare.md: variants' errors against a reference run directory.

`rotorcosim compare compare/jeffcott_runup_onset.yaml` runs the variants of the whole
half-Sommerfeld run-up; its Radau reference was too slow for the whole ramp on the shared
machine (docs/compare.md, "Whole run-up"), so the reference is a separate BDF2 monolithic
run, and this script measures every finished variant against it with the same functions
as `compare` (orchestrator.compare.metrics), over the signals, scales and derived keys of
the comparison file:

    python compare/onset_table.py compare/jeffcott_runup_onset.yaml REF_DIR RUNS_DIR [RUN_DIR ...]

prints a markdown table: variant, macro step, max/rms signal error, onset/vanish speeds
and their relative errors, macro steps, wall time.
"""

from __future__ import annotations

import math
import sys
from pathlib import Path

from orchestrator.compare import load_compare
from orchestrator.compare.metrics import derived_error, read_run, signal_errors


def main(argv: list[str]) -> int:
    spec = load_compare(argv[0])
    ref = read_run(Path(argv[1]), {})
    if not ref.ok:
        print(f"reference {argv[1]}: {ref.message}", file=sys.stderr)
        return 2
    dirs: list[Path] = []
    for a in argv[2:]:
        p = Path(a)
        dirs += sorted(d for d in p.iterdir() if d.is_dir()) if (p / "reference").exists() or \
            not (p / "summary.json").exists() else [p]
    scales = {s: (sc if sc else float(max(abs(ref.outputs[s])))) for s, sc in spec.signals.items()}
    keys = {n: d["key"] for n, d in spec.derived.items()}
    r_on, r_van = (_get(ref.summary, keys.get(k)) for k in ("onset_speed", "vanish_speed"))
    print(f"reference {argv[1]}: onset {r_on} Hz, vanish {r_van} Hz, "
          f"{ref.macro_steps} steps, {ref.wall_time_s:.0f} s wall")
    print("| variant | H [s] | max err | rms err | onset [Hz] | onset err | vanish [Hz] | vanish err "
          "| macro steps | wall [s] |")
    print("|---|---|---|---|---|---|---|---|---|---|")
    for d in dirs:
        if not (d / "summary.json").exists():
            print(f"| {d.name} | | not finished (stopped) | | | | | | | |")
            continue
        run = read_run(d, {})
        h = (run.summary.get("coupling") or {}).get("macro_step")
        if not run.ok:
            print(f"| {d.name} | {h:g} | unstable ({run.message[:60]}) | | | | | | "
                  f"{run.macro_steps} | {run.wall_time_s:.0f} |")
            continue
        e = [signal_errors(ref.t, ref.outputs[s], run.t, run.outputs[s], scales[s]) for s in scales]
        emax = max(x["max"] for x in e)
        erms = max(x["rms"] for x in e)
        on, van = (_get(run.summary, keys.get(k)) for k in ("onset_speed", "vanish_speed"))
        eon = derived_error(ref.summary, run.summary, keys["onset_speed"], None)
        evan = derived_error(ref.summary, run.summary, keys["vanish_speed"], None)
        print(f"| {d.name} | {h:g} | {emax:.3g} | {erms:.3g} | {_f(on)} | {_pct(eon, on, r_on)} | "
              f"{_f(van)} | {_pct(evan, van, r_van)} | {run.macro_steps} | {run.wall_time_s:.0f} |")
    return 0


def _get(summary, key):
    v = summary
    for part in (key or "").split("."):
        v = v.get(part) if isinstance(v, dict) else None
    return v


def _f(x):
    return "-" if x is None else f"{x:.1f}"


def _pct(e, v, r):
    if not math.isfinite(e):
        return "inf"
    sign = "+" if (v or 0) >= (r or 0) else "-"
    return f"{sign}{100 * e:.2f} %"


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
