"""Old against new film code on the recorded kinematics of a shipped run-up (issue 16, speed).

Replays the journal kinematics that the shipped oil-bath Jeffcott run-up delivered to
``bearing1`` over short windows on two films, one built from this checkout's ``bearing_fmu`` and
one from an older checkout's (imported as ``bearing_fmu_old`` through a symlink, as
``bench_bearing_ab.py`` does), each started from the stationary film 30 macro steps before the
window. The two advance in turn over the same 0.1 ms macro steps (which goes first alternates),
so both see the machine in the same state; per window it prints the median and mean CPU time
per macro step (``BearingModel.step``, with ``--lin`` also ``linearization``: the interface
coefficients the FMU computes), their ratio, whether the film forces of the two are equal bit
for bit, and the LU and Newton counts of both.

Run (the kinematics are recorded once into ``--kin`` if that folder has no results.csv):
    git worktree add --detach /tmp/old <commit>
    OPENBLAS_NUM_THREADS=1 .venv/bin/python benchmarks/bench_film_replay_ab.py --old /tmp/old \\
        --kin /tmp/kin_oil_bath --windows 0.30:0.33,0.70:0.73,1.50:1.53 --lin
"""

from __future__ import annotations

import argparse
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--old", required=True, help="root of the old checkout (git worktree)")
    ap.add_argument("--kin", required=True, help="folder of a recorded run (made if it has no results.csv)")
    ap.add_argument("--windows", default="0.30:0.33,0.70:0.73,1.50:1.53", help="t0:t1 [s], comma-separated")
    ap.add_argument("--lin", action="store_true", help="time the interface coefficients too")
    a = ap.parse_args(argv)
    windows = [tuple(float(x) for x in w.split(":")) for w in a.windows.split(",")]
    from bench_newton_reuse import bearing_params, record
    kin_dir = Path(a.kin)
    kin_dir.mkdir(parents=True, exist_ok=True)
    record("oil_bath", max(t1 for _, t1 in windows) + 0.01, kin_dir)
    tmp = Path(tempfile.mkdtemp(prefix="bench_replay_"))
    (tmp / "bearing_fmu_old").symlink_to(Path(a.old).resolve() / "bearing_fmu")
    sys.path.insert(0, str(tmp))
    import bearing_fmu.linearize as LN
    import bearing_fmu.model as MN
    import bearing_fmu_old.linearize as LO
    import bearing_fmu_old.model as MO
    from orchestrator.results.run_directory import RunDirectory
    data = RunDirectory(kin_dir).columns()
    t = data["time"]
    prm = {k: getattr(bearing_params("oil_bath"), k) for k in ("R", "B", "psi", "eta0", "p0", "p_feed", "n_phi",
                                                                "n_z", "cavitation", "axial_bc", "groove_width",
                                                                "cav_width", "theta_transport")}

    def kin(i):
        return tuple(float(data[k][i]) for k in ("rotor.x_1", "rotor.y_1", "rotor.vx_1", "rotor.vy_1",
                                                 "rotor.omega"))
    print("| window [s] | old: median / mean ms | new: median / mean ms | new / old (median, mean) | "
          "forces | LU old / new | Newton old / new |")
    print("|---|---|---|---|---|---|---|")
    for t0, t1 in windows:
        i0, i1 = int(np.searchsorted(t, t0)), int(np.searchsorted(t, t1))
        beds = {}
        for name, M, L in (("old", MO, LO), ("new", MN, LN)):
            b = M.BearingModel(M.BearingParams(**prm))
            b.initialize(*kin(i0 - 30), init="stationary")
            for i in range(i0 - 30, i0):
                b.step(1e-4, *kin(i + 1))
            beds[name] = (b, L, [], [])
        for i in range(i0, i1):
            for name in (("old", "new") if i % 2 else ("new", "old")):
                b, L, ts, F = beds[name]
                c0 = time.thread_time()
                b.step(1e-4, *kin(i + 1))
                if a.lin:
                    L.linearization(b)
                ts.append(time.thread_time() - c0)
                F.append((b.outputs["Fx"], b.outputs["Fy"]))
        to, tn = np.array(beds["old"][2]) * 1e3, np.array(beds["new"][2]) * 1e3
        Fo, Fn = np.array(beds["old"][3]), np.array(beds["new"][3])
        so, sn = beds["old"][0].stats, beds["new"][0].stats
        same = "identical" if np.array_equal(Fo, Fn) else f"max rel. diff {np.abs(Fo - Fn).max() / np.abs(Fo).max():.1e}"
        print(f"| {t0:g}-{t1:g} | {np.median(to):.3f} / {to.mean():.3f} | {np.median(tn):.3f} / {tn.mean():.3f} | "
              f"{np.median(tn) / np.median(to):.3f}, {tn.mean() / to.mean():.3f} | {same} | "
              f"{so['factor']} / {sn['factor']} | {so['newton']} / {sn['newton']} |")


if __name__ == "__main__":
    main()
