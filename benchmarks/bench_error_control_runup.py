"""Error-controlled macro step against the best constant step at the same accuracy (issue 18,
"a run whose dynamics change"), from the runs of a ``rotorcosim compare`` folder.

    OPENBLAS_NUM_THREADS=1 nice -n 10 rotorcosim compare compare/jeffcott_seeded_error_control.yaml \\
        --out out/compare/jeffcott_seeded_error_control
    .venv/bin/python benchmarks/bench_error_control_runup.py out/compare/jeffcott_seeded_error_control

Error = max over rotor.x_1, y_1, x_2, y_2 and the output times of |x - x_ref| / c
(c = 1.372e-5 m), against the Richardson combination of the reference (BDF2, step h) and its
check (h/2, rtol/atol halved): x_ref = x_check + (x_check - x_ref_h) / 3 (BDF2 is second
order), which removes the reference's own error seen in the check (0.11 % of c at h = 25 us).
doStep = the rotor's doStep calls (rejected attempts included), from each run's summary.json.
For every error-controlled run: the constant-step run with the fewest doSteps whose error is
<= its error, and the ratio; and, since the constant ladder is coarse (factors of 2), the
doSteps of a constant step with exactly that error, interpolated log-log between the two
constant runs that bracket it, and that ratio.
"""

from __future__ import annotations

import csv
import json
import sys
from pathlib import Path

import numpy as np

# case -> (signals, their scale, the instance whose doSteps count, Richardson on the reference)
CASES = {
    "runup": (("rotor.x_1", "rotor.y_1", "rotor.x_2", "rotor.y_2"), 1.372e-5, "rotor", True),
    # compare/coupling_switch.yaml: reference Radau rtol 1e-10 (its check changes it by 1e-11): as is
    "switch": (("left.x1", "right.x2"), 0.01, "left", False),
}
SIGNALS, CLEARANCE, INSTANCE, RICHARDSON = CASES["runup"]


def read(run: Path) -> tuple[np.ndarray, np.ndarray]:
    with open(run / "results.csv", newline="") as f:
        rows = list(csv.DictReader(f))
    t = np.array([float(r["time"]) for r in rows])
    return t, np.array([[float(r[s]) for r in rows] for s in SIGNALS])


def error(run: Path, ref: tuple, chk: tuple, until: float = np.inf) -> float:
    t, x = read(run)
    a = np.array([np.interp(t, ref[0], v) for v in ref[1]])
    b = np.array([np.interp(t, chk[0], v) for v in chk[1]])
    keep = t <= until + 1e-12
    best = b + (b - a) / 3.0 if RICHARDSON else a
    return float(np.abs(x - best)[:, keep].max() / CLEARANCE)


def interpolated_dosteps(const: list[dict], err: float) -> float | None:
    """doSteps of a constant step with error ``err``: log-log between the bracketing runs."""
    pts = sorted((c["dostep"], c["err"]) for c in const)
    for (n0, e0), (n1, e1) in zip(pts, pts[1:]):
        if min(e0, e1) <= err <= max(e0, e1) and e0 != e1:
            w = (np.log(err) - np.log(e0)) / (np.log(e1) - np.log(e0))
            return float(np.exp(np.log(n0) + w * (np.log(n1) - np.log(n0))))
    return None


def main(folder: str, extra: list[str], until: float = np.inf) -> None:
    runs = Path(folder) / "runs"
    ref, chk = read(runs / "reference"), read(runs / "reference-check")
    a = np.array([np.interp(chk[0], ref[0], v) for v in ref[1]])
    keep = chk[0] <= until + 1e-12
    print(f"reference against its check: {np.abs(chk[1] - a)[:, keep].max() / CLEARANCE:.3g} (of the scale; "
          f"{'errors against their Richardson combination' if RICHARDSON else 'errors against the reference'})")
    dirs = sorted(p for p in runs.iterdir() if p.is_dir() and not p.name.startswith("reference"))
    dirs += [Path(e) for e in extra]
    rows = []
    for run in dirs:
        s = json.loads((run / "summary.json").read_text())
        if s["status"] != "finished":
            print(f"{run.name}: {s['status']}: {s['message']}")
            continue
        st = s.get("step_control") or {}
        rows.append(dict(name=run.name, err=error(run, ref, chk, until), dostep=s["fmu_calls"][INSTANCE]["doStep"],
                         steps=s["macro_steps"], rejected=st.get("rejected_steps", 0),
                         adaptive=st.get("type") == "error"))
    const = [r for r in rows if not r["adaptive"]]
    print(f"{'run':34s} {'error/c':>9s} {'doStep':>7s} {'rejected':>8s}  best constant at <= error")
    for r in sorted(rows, key=lambda r: (r["adaptive"], -r["dostep"])):
        best = min((c for c in const if c["err"] <= r["err"]), key=lambda c: c["dostep"], default=None)
        tail = ""
        if r["adaptive"]:
            tail = (f"{best['name']} ({best['err']:.3g}, {best['dostep']}): ratio {best['dostep'] / r['dostep']:.2f}"
                    if best else "none of the constant steps")
            n = interpolated_dosteps(const, r["err"])
            tail += f"; interpolated {n:.0f}: ratio {n / r['dostep']:.2f}" if n else "; interpolated: outside the ladder"
            fam = r["name"].split("-error")[0] + "-h"        # the same scheme's constant steps only
            same = [c for c in const if c["name"].startswith(fam)]
            if same and len(same) < len(const):
                n = interpolated_dosteps(same, r["err"])
                tail += (f"; same scheme ({fam}*) interpolated {n:.0f}: ratio {n / r['dostep']:.2f}" if n
                         else f"; same scheme ({fam}*): outside its ladder")
        print(f"{r['name']:34s} {r['err']:9.3g} {r['dostep']:7d} {r['rejected']:8d}  {tail}")


if __name__ == "__main__":
    import argparse
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("folder", nargs="?", default="out/compare/jeffcott_seeded_error_control",
                    help="a rotorcosim compare folder (runs/reference, runs/reference-check, constant steps)")
    ap.add_argument("runs", nargs="*", help="more run folders (rotorcosim run --out), e.g. the error-controlled runs")
    ap.add_argument("--until", type=float, default=np.inf, help="error over t <= this only [s]")
    ap.add_argument("--case", choices=sorted(CASES), default="runup",
                    help="runup: the seeded run-up (errors / c, rotor doSteps); switch: compare/coupling_switch.yaml")
    a = ap.parse_intermixed_args()
    SIGNALS, CLEARANCE, INSTANCE, RICHARDSON = CASES[a.case]
    main(a.folder, a.runs, a.until)
