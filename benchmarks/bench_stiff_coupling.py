"""Interface-Jacobian vs plain coupling of the Jeffcott rotor in two half-Sommerfeld
bearings through the real FMUs and the master (docs/stiff-coupling.md).

    nice -n 10 .venv/bin/python benchmarks/bench_stiff_coupling.py [--stop 1.02] [--steps 1.25e-6,...]

For each macro step H: a Gauss-Seidel run with plain force/displacement coupling
(benchmarks/stiff_coupling/jeffcott_hs_plain.yaml, bearings' linearize = 0) and with
interface-Jacobian coupling (jeffcott_hs_ij.yaml: film coefficients kxx..cyy -> rotor),
both against the monolithic reference (coupling.scheme: monolithic, Radau rtol 1e-8) of
the plain scenario. Error: max over the output rows of |journal 1 and 2 displacement -
reference| / clearance (c = psi R = 5.6e-5 m).
"""

from __future__ import annotations

import argparse
import json
import sys
import time
from pathlib import Path

import numpy as np

from orchestrator import load_scenario, run

HERE = Path(__file__).resolve().parent / "stiff_coupling"
SIG = ["rotor.x_1", "rotor.y_1", "rotor.x_2", "rotor.y_2"]
CLEARANCE = 2.8e-3 * 0.02


def one(path, overrides, out):
    sc = load_scenario(str(path), overrides=overrides, build_fmus=True)
    t0 = time.perf_counter()
    res = run(sc, out_dir=out, progress=False)
    wall = time.perf_counter() - t0
    return res, wall


def main(argv=None):
    ap = argparse.ArgumentParser()
    ap.add_argument("--stop", type=float, default=1.02)
    ap.add_argument("--start", type=float, default=1.0)
    ap.add_argument("--steps", default="1.25e-6,2.5e-6,5e-6,1e-5,2e-5,5e-5,1e-4")
    ap.add_argument("--modes", default="plain,ij")
    ap.add_argument("--interval", type=float, default=1e-4)
    ap.add_argument("--out", default="out/stiff_coupling")
    ap.add_argument("--film", choices=("hs", "mc"), default="hs",
                    help="hs: half-Sommerfeld bearings, monolithic reference; mc: mass-conserving "
                         "bearings (no monolithic model), reference = --ref co-simulation")
    ap.add_argument("--ref", default="plain:1.25e-6", help="mc reference MODE:H")
    ap.add_argument("--ref-csv", default=None, help="reuse the results.csv of an earlier reference run")
    ap.add_argument("--set", action="append", default=[], help="extra scenario override (all runs)")
    a = ap.parse_args(argv)
    common = [f"start_time={a.start}", f"stop_time={a.stop}", f"output.interval={a.interval}",
              f"output.signals=[{','.join(SIG + ['bearing1.eps', 'bearing2.eps'])}]"] + a.set
    out = Path(a.out)
    scen = {m: HERE / f"jeffcott_{a.film}_{m}.yaml" for m in ("plain", "ij")}
    if a.ref_csv:
        import pandas as pd
        from types import SimpleNamespace
        df = pd.read_csv(a.ref_csv)
        ref = SimpleNamespace(success=True, message="", t=df["time"].to_numpy(),
                              outputs={k: df[k].to_numpy() for k in df.columns if k != "time"})
        wall = 0.0
    elif a.film == "hs":
        ref, wall = one(scen["plain"], common + [
            "coupling.scheme=monolithic", "coupling.options.rtol=1e-8",
            f"coupling.macro_step={a.interval}"], out / "monolithic")
    else:
        m, h = a.ref.split(":")
        ref, wall = one(scen[m], common + [f"coupling.macro_step={h}"], out / f"ref_{m}_{h}")
    assert ref.success, ref.message
    R = np.stack([ref.outputs[s] for s in SIG], axis=1)
    rows = [dict(mode="monolithic", H=None, ok=True, err=0.0, wall=wall,
                 eps_max=float(max(ref.outputs["bearing1.eps"].max(), ref.outputs["bearing2.eps"].max())))]
    print(f"reference ({a.ref_csv or ('monolithic' if a.film == 'hs' else a.ref)}): {wall:.1f} s, eps max {rows[0]['eps_max']:.3f}", flush=True)
    for H in [float(h) for h in a.steps.split(",")]:
        for mode in a.modes.split(","):
            f = scen[mode]
            res, wall = one(f, common + [f"coupling.macro_step={H}"], out / f"{mode}_{H:g}")
            row = dict(mode=mode, H=H, ok=bool(res.success), wall=wall, t_end=float(res.t[-1]) if len(res.t) else None)
            if res.success:
                X = np.stack([res.outputs[s] for s in SIG], axis=1)
                n = min(len(X), len(R))
                assert np.allclose(res.t[:n], ref.t[:n], atol=1e-9)
                row["err"] = float(np.abs(X[:n] - R[:n]).max() / CLEARANCE)
            else:
                row["err"] = None
                row["message"] = res.message[:200]
            rows.append(row)
            print(json.dumps(row), flush=True)
    (out / "table.json").write_text(json.dumps(rows, indent=1))
    print("\n| H [us] | plain: max err / c | plain wall [s] | interface-Jacobian: max err / c | IJ wall [s] |")
    print("|---|---|---|---|---|")
    by = {(r["mode"], r["H"]): r for r in rows}
    for H in [float(h) for h in a.steps.split(",")]:
        cells = []
        for mode in ("plain", "ij"):
            r = by.get((mode, H))
            if r is None:
                cells += ["-", "-"]
            elif r["ok"]:
                cells += [f"{r['err']:.2e}", f"{r['wall']:.1f}"]
            else:
                cells += [f"unstable (failed at t = {r['t_end']:.5f} s)" if r.get("t_end") else "failed", f"{r['wall']:.1f}"]
        print(f"| {H * 1e6:g} | " + " | ".join(cells) + " |")
    return 0


if __name__ == "__main__":
    sys.exit(main())
