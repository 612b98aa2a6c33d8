"""Oracle bound for issue 18's goal on the seeded run-up: the fewest doSteps ANY piecewise-constant
macro-step schedule needs for a given error, against the best constant step.

    OPENBLAS_NUM_THREADS=1 nice -n 10 .venv/bin/python benchmarks/bench_goal_oracle.py weights
    OPENBLAS_NUM_THREADS=1 nice -n 10 .venv/bin/python benchmarks/bench_goal_oracle.py verify \\
        --reference out/compare/jeffcott_seeded_error_control_whole
    .venv/bin/python benchmarks/bench_goal_oracle.py report [--reference ...]
    OPENBLAS_NUM_THREADS=1 nice -n 10 .venv/bin/python benchmarks/bench_goal_oracle.py tail [--splits T ...]

Case: scenarios/jeffcott_runup_half_sommerfeld_seeded.yaml (t = 0.55-0.95 s through the whirl
onset), IJ Gauss-Seidel k = q = 0, output every 1.6 ms, the rotor's ``max_phase_per_substep``
0.02: the settings of compare/jeffcott_seeded_error_control_whole.yaml and of session 4's
error-controlled runs (docs/coupling.md). The master is driven with a :class:`ScheduledStep`
controller (a given step per time window, each window's edges on the output grid).

1. ``weights``: a fine run (``--fine``, 25 us everywhere), and for every window k of ``--windows``
   equal windows a run with the coarse step h_c (``--coarse``, 0.2 and 0.1 ms) in window k and
   the fine step elsewhere. delta_k(t) = x_k(t) - x_fine(t) is the error that window k's steps
   leave in the journals (x_1, y_1, x_2, y_2, / c) wherever it ends up (amplified by the whirl
   or damped); its size |delta_k| = max over t and signals gives the window weight
   w_k = |delta_k| / (h_c^p - h_f^p). Also the constant steps (0.4 .. 0.05 ms) for the order p
   and the superposition check (sum_k delta_k against the all-coarse run).
2. Model: E(H_1..H_K) = sum_k w_k H_k^p, cost N = sum_k T_k / H_k. Lagrange: H_k ~ (T_k /
   w_k)^(1/(p+1)), clipped to [--h-min, --h-max] (water-filling on the multiplier). Its doStep
   ratio against the constant step with the same model error (the bound) is printed per target.
3. ``verify``: the optimal schedules for the errors of the constant 0.2 / 0.1 / 0.05 ms steps are
   run, and their error (against the fine run, and against the monolithic reference's Richardson
   combination of a compare folder, as bench_error_control_runup.py) and doSteps compared with the
   constant ladder interpolated log-log at the same error.

4. ``tail``: every step after a split time free (no cost, no error: fine steps, not counted); the
   bound for any step sequence that is constant before it (see :func:`tail_free`).

Results are cached as ``--out/<name>.npz`` (delete to rerun). Results: docs/coupling.md
("Session 5: the oracle bound"), BENCHMARKS.md.
"""

from __future__ import annotations

import argparse
import csv
import math
import sys
import time
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

from orchestrator.coupling.adaptive import OutputGrid                          # noqa: E402
from orchestrator.coupling.error_control import next_stop                      # noqa: E402
from orchestrator.coupling.step_control import StepSizeController              # noqa: E402

SCENARIO = ROOT / "scenarios" / "jeffcott_runup_half_sommerfeld_seeded.yaml"
SIGNALS = ("rotor.x_1", "rotor.y_1", "rotor.x_2", "rotor.y_2")
CLEARANCE = 1.372e-5
INTERVAL = 1.6e-3
T0, T1 = 0.55, 0.95
OVERRIDES = [f"output.interval={INTERVAL}", "fmus.rotor.parameters.max_phase_per_substep=0.02"]


class ScheduledStep(StepSizeController):
    """A given macro step per time window: ``steps[k]`` on [edges[k], edges[k+1]].

    Uses the master's variable-grid protocol (coupling/adaptive.py): every step ends on the next
    output time or window edge if it would reach it (``next_stop``, as the error-controlled step),
    so rows stay on the output grid. Nothing is rejected."""

    variable = True
    needs_states = False
    can_reject = False

    def __init__(self, edges, steps, *, interval: float):
        self.edges = np.asarray(edges, float)
        self.steps = np.asarray(steps, float)
        assert len(self.edges) == len(self.steps) + 1 and np.all(np.diff(self.edges) > 0)
        self.t0, self.t_stop = float(self.edges[0]), float(self.edges[-1])
        self.grid = OutputGrid(self.t0, self.t_stop, interval)
        self.h = float(self.steps[0])
        self.n_steps = max(1, int(round(float(np.sum(np.diff(self.edges) / self.steps)))))
        self.accepted = 0

    def time(self, n: int) -> float:
        return self.t0 if n == 0 else self.t_stop

    def bind(self, names, connections, nominals=None) -> None:
        """Nothing to bind (no error estimate)."""

    def _window(self, t: float) -> int:
        return min(int(np.searchsorted(self.edges, t + 1e-12, side="right")) - 1, len(self.steps) - 1)

    def take_variable_step(self, stepper, t: float):
        k = self._window(t)
        self.h = float(self.steps[k])
        edge = float(self.edges[k + 1])
        t_end, on_out = next_stop(t, self.h, lambda s: min(self.grid.after(s), edge))
        stepper.step(t, t_end)
        self.accepted += 1
        return t_end, on_out


def run_schedule(out: Path, name: str, edges, steps) -> dict:
    """Run (or load from the cache) one schedule; returns t, X (signals x times, / c), dostep, wall."""
    f = out / f"{name}.npz"
    if f.exists():
        d = np.load(f)
        return {k: d[k] for k in d.files} | {"dostep": int(d["dostep"])}
    from orchestrator import load_scenario
    from orchestrator.coupling.execution import MasterAlgorithm
    from orchestrator.results import Status
    sc = load_scenario(str(SCENARIO), overrides=OVERRIDES + [f"stop_time={float(edges[-1])!r}"], build_fmus=True)
    grid = ScheduledStep(edges, steps, interval=INTERVAL)
    w0 = time.perf_counter()
    m = MasterAlgorithm(sc, step_size=grid, out_dir=str(out / "work"))
    res = m.run()
    wall = time.perf_counter() - w0
    if res.status is not Status.FINISHED:
        raise RuntimeError(f"{name}: {res.status}: {res.message}")
    X = np.array([res.outputs[s] for s in SIGNALS]) / CLEARANCE
    dostep = res.stats["fmu_calls"]["rotor"]["doStep"]
    np.savez(f, t=np.asarray(res.t), X=X, dostep=dostep, wall=wall)
    print(f"  ran {name}: {dostep} doSteps, {wall:.1f} s wall", flush=True)
    return {"t": np.asarray(res.t), "X": X, "dostep": dostep, "wall": wall}


def window_edges(n: int) -> np.ndarray:
    """n equal windows on the output grid (250 output intervals of 1.6 ms)."""
    m = round((T1 - T0) / INTERVAL)
    if m % n:
        raise SystemExit(f"--windows {n}: must divide the {m} output intervals")
    return np.array([T0 + j * (m // n) * INTERVAL for j in range(n)] + [T1])


def const(out: Path, h: float) -> dict:
    return run_schedule(out, f"const_{h:g}", [T0, T1], [h])


def windowed(out: Path, edges, k: int, h_c: float, h_f: float) -> dict:
    steps = np.full(len(edges) - 1, h_f)
    steps[k] = h_c
    return run_schedule(out, f"w{len(edges) - 1}_{k:02d}_{h_c:g}_{h_f:g}", edges, steps)


def on_same_times(a: dict, b: dict) -> np.ndarray:
    """a.X - b.X on a's times (both on the output grid)."""
    assert len(a["t"]) == len(b["t"]) and np.allclose(a["t"], b["t"], atol=1e-9), "different output times"
    return a["X"] - b["X"]


def optimal_steps(w, T, p: float, target: float, h_min: float, h_max: float) -> np.ndarray:
    """argmin sum T_k / H_k subject to sum w_k H_k^p = target, h_min <= H_k <= h_max
    (Lagrange, H_k = (T_k / (lam p w_k))^(1/(p+1)) clipped; lam by bisection in log)."""
    w = np.maximum(np.asarray(w, float), 1e-300)

    def steps(lam):
        return np.clip((T / (lam * p * w)) ** (1.0 / (p + 1.0)), h_min, h_max)

    lo, hi = -200.0, 200.0
    for _ in range(300):
        mid = 0.5 * (lo + hi)
        if np.sum(w * steps(math.exp(mid)) ** p) > target:
            lo = mid
        else:
            hi = mid
    return steps(math.exp(hi))


def optimal_steps_vector(deltas, h_c: float, h_f: float, T, p: float, target: float, h_min: float,
                         h_max: float, h0) -> np.ndarray:
    """The same with the measured error trajectories added as vectors (superposition, cancellation
    between windows allowed): max over t, signals of |sum_k s_k delta_k(t)| <= target,
    s_k = (H_k^p - h_f^p) / (h_c^p - h_f^p); SLSQP in log H_k from ``h0``."""
    from scipy.optimize import minimize
    D = deltas.reshape(len(T), -1)
    keep = np.abs(D).max(axis=0) > 1e-3 * np.abs(D).max()
    D = D[:, keep][:, ::max(1, keep.sum() // 400)]        # thin the constraint set (smooth in t)

    def s_of(z):
        return (np.exp(z) ** p - h_f ** p) / (h_c ** p - h_f ** p)

    cons = [{"type": "ineq", "fun": lambda z: 1.0 - (s_of(z) @ D) / target},
            {"type": "ineq", "fun": lambda z: 1.0 + (s_of(z) @ D) / target}]
    r = minimize(lambda z: float(np.sum(T * np.exp(-z))) / 1e3, np.log(h0), method="SLSQP",
                 bounds=[(math.log(h_min), math.log(h_max))] * len(T), constraints=cons,
                 options={"maxiter": 500, "ftol": 1e-10})
    return np.exp(r.x)


def fit_order(hs, errs) -> float:
    return float(np.polyfit(np.log(hs), np.log(errs), 1)[0])


def interp_dosteps(ladder: list[tuple[int, float]], err: float) -> float | None:
    pts = sorted(ladder)
    for (n0, e0), (n1, e1) in zip(pts, pts[1:]):
        if min(e0, e1) <= err <= max(e0, e1) and e0 != e1:
            w = (math.log(err) - math.log(e0)) / (math.log(e1) - math.log(e0))
            return math.exp(math.log(n0) + w * (math.log(n1) - math.log(n0)))
    return None


def reference(folder: Path | None):
    """Richardson combination of a compare folder's reference (BDF2 h) and check (h/2), or None."""
    if folder is None:
        return None

    def read(run):
        with open(run / "results.csv", newline="") as f:
            rows = list(csv.DictReader(f))
        return np.array([float(r["time"]) for r in rows]), np.array([[float(r[s]) for r in rows] for s in SIGNALS])

    (ta, a), (tb, b) = read(folder / "runs" / "reference"), read(folder / "runs" / "reference-check")
    a = np.array([np.interp(tb, ta, v) for v in a])
    return tb, (b + (b - a) / 3.0) / CLEARANCE


def err_ref(run: dict, ref) -> float:
    tr, xr = ref
    x = np.array([np.interp(run["t"], tr, v) for v in xr])
    return float(np.abs(run["X"] - x).max())


def analyse(out: Path, a) -> dict:
    edges = window_edges(a.windows)
    T = np.diff(edges)
    fine = const(out, a.fine)
    ladder_h = sorted(set(a.ladder + a.coarse + [a.fine]), reverse=True)
    ladder = {h: const(out, h) for h in ladder_h}
    D = {h: float(np.abs(on_same_times(ladder[h], fine)).max()) for h in ladder_h if h != a.fine}
    print(f"fine run {a.fine:g} s: {fine['dostep']} doSteps")
    print("constant steps, max |x_h - x_fine| / c: " + ", ".join(f"{h * 1e3:g} ms {D[h]:.3g}" for h in D))
    hs = [h for h in D if h <= a.order_fit_max]
    p_const = fit_order([h for h in hs], [D[h] for h in hs]) if len(hs) >= 2 else float("nan")
    print(f"order of the constant steps' difference to the fine run (h <= {a.order_fit_max:g}): {p_const:.2f}")
    res = {"edges": edges, "T": T, "fine": fine, "ladder": ladder, "D": D, "p_const": p_const, "W": {}}
    for h_c in a.coarse:
        runs = [windowed(out, edges, k, h_c, a.fine) for k in range(a.windows)]
        deltas = np.array([on_same_times(r, fine) for r in runs])           # K x signals x times
        mag = np.abs(deltas).max(axis=(1, 2))
        total = on_same_times(ladder[h_c], fine)
        lin = np.abs(deltas.sum(axis=0) - total).max() / np.abs(total).max()
        print(f"\ncoarse {h_c * 1e3:g} ms in one window ({a.windows} windows of {T[0] * 1e3:g} ms), fine elsewhere:")
        print(f"  all-coarse run |delta| {np.abs(total).max():.3g}; |sum_k delta_k| {np.abs(deltas.sum(0)).max():.3g}; "
              f"sum_k |delta_k| {mag.sum():.3g}; superposition misfit |sum delta_k - delta_all| / |delta_all| {lin:.2f}")
        tt = fine["t"]
        for k in range(a.windows):
            i = np.abs(deltas[k]).max(axis=0)
            t_half = tt[np.argmax(i >= 0.5 * i.max())]
            at = {s: i[np.searchsorted(tt, s)] if s > edges[k + 1] else float("nan") for s in (0.64, 0.70, 0.78)}
            j_end = int(np.searchsorted(tt, edges[k + 1] - 1e-9))      # the output time at the window's end
            loc = i[:j_end + 1].max()
            print(f"  window {k:2d} {edges[k]:.4f}-{edges[k + 1]:.4f} s: at its end {loc:.2g}, amplified "
                  f"{mag[k] / loc:.3g}x to"
                  f" |delta_k| {mag[k]:.3g} (reached at "
                  f"{tt[np.argmax(i)]:.3f} s, half of it first at {t_half:.3f} s); at 0.64/0.70/0.78 s "
                  f"{at[0.64]:.2g}/{at[0.70]:.2g}/{at[0.78]:.2g}; doSteps {runs[k]['dostep']}")
        res["W"][h_c] = (mag, deltas)
    return res


def bound(res: dict, a, h_c: float, p: float, h_max: float, quiet=False):
    mag, _ = res["W"][h_c]
    T = res["T"]
    w = mag / (h_c ** p - a.fine ** p)
    Wsum, Ttot = w.sum(), T.sum()
    rows = []
    for h in a.targets:
        target = Wsum * h ** p                 # model error of the constant step h
        H = optimal_steps(w, T, p, target, a.h_min, h_max)
        n_opt = float(np.sum(T / H))
        rows.append((h, target, H, n_opt, Ttot / h / n_opt))
    if not quiet:
        _, deltas = res["W"][h_c]
        for h, target, H, n_opt, ratio in rows:
            true = np.abs(np.tensordot((H ** p - a.fine ** p) / (h_c ** p - a.fine ** p), deltas, 1)).max()
            Hv = optimal_steps_vector(deltas, h_c, a.fine, T, p, true, a.h_min, h_max, H)
            tv = np.abs(np.tensordot((Hv ** p - a.fine ** p) / (h_c ** p - a.fine ** p), deltas, 1)).max()
            tc = np.abs(np.tensordot(np.full(len(T), (h ** p - a.fine ** p) / (h_c ** p - a.fine ** p)),
                                     deltas, 1)).max()
            n_c = Ttot / h * (tc / true) ** (1 / p)       # constant step with the vector model's error `true`
            res.setdefault("vector", {})[(h_c, h_max, h)] = Hv
            print(f"  vector model, target {h * 1e3:g} ms: Lagrange schedule's vector error {true:.3g} "
                  f"(constant {h * 1e3:g} ms: {tc:.3g}); SLSQP optimum {np.sum(T / Hv):.0f} doSteps at {tv:.3g}, "
                  f"constant at that error {n_c:.0f}: ratio {n_c / np.sum(T / Hv):.2f}; steps [ms] "
                  + " ".join(f"{x * 1e3:.3g}" for x in Hv))
        om = w / T
        r = 1.0 / (p + 1.0)
        unc = (np.sum(T * om) / Ttot / (np.sum(T * om ** r) / Ttot) ** (1 / r)) ** (1 / p)
        print(f"\nbound from h_c = {h_c * 1e3:g} ms, p = {p:.2f}, steps in [{a.h_min:g}, {h_max:g}] s "
              f"(unclipped asymptotic ratio (M_1(w/T) / M_1/(p+1)(w/T))^(1/p) = {unc:.2f}):")
        for h, target, H, n_opt, ratio in rows:
            print(f"  error of constant {h * 1e3:g} ms ({target:.3g} c model, {Ttot / h:.0f} doSteps): optimal "
                  f"schedule {n_opt:.0f} doSteps, ratio {ratio:.2f}; steps per window [ms] "
                  + " ".join(f"{x * 1e3:.3g}" for x in H))
    return rows


def tail_free(out: Path, a) -> None:
    """Stage ``tail``: the bound with every step after a split time FREE, whatever the steps there.

    For a split t_s and a constant step h before it, the run uses h on [T0, t_s] and the fine step
    after it; its error against the fine run is then made before t_s only (amplified by the whirl
    wherever it ends up), and only its doSteps before t_s are counted. The constant ladder at that
    error, divided by those doSteps, bounds what ANY step sequence that is constant before t_s can
    save, even one that varies within a whirl period after t_s (session 5's caveat), at no cost and
    no error there."""
    fine = const(out, a.fine)
    ladder = {h: const(out, h) for h in sorted(set(a.ladder), reverse=True)}
    lad = [(r["dostep"], float(np.abs(on_same_times(r, fine)).max())) for h, r in ladder.items()]
    print(f"fine run {a.fine:g} s: {fine['dostep']} doSteps; constant steps, max |x_h - x_fine| / c: "
          + ", ".join(f"{h * 1e3:g} ms {e:.3g} ({n})" for h, (n, e) in zip(ladder, lad)))
    m = round((T1 - T0) / INTERVAL)
    for t_s in a.splits:
        j = round((t_s - T0) / INTERVAL)
        if not 0 < j < m:
            raise SystemExit(f"--splits {t_s}: must lie inside ({T0}, {T1})")
        t_s = T0 + j * INTERVAL
        print(f"\nsteps free after t_s = {t_s:.4f} s ({(T1 - t_s) / (T1 - T0):.0%} of the run):")
        for h in ladder:
            r = run_schedule(out, f"tail_{t_s:.4f}_{h:g}_{a.fine:g}", [T0, t_s, T1], [h, a.fine])
            n_pre = int(round((t_s - T0) / h))
            e = float(np.abs(on_same_times(r, fine)).max())
            n_c = interp_dosteps(lad, e)
            print(f"  h = {h * 1e3:g} ms before t_s: {n_pre} doSteps counted ({r['dostep']} run), error vs fine "
                  f"{e:.3g}: " + (f"constant at that error {n_c:.0f}, ratio {n_c / n_pre:.2f}" if n_c
                                  else "outside the ladder"), flush=True)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("stage", choices=["weights", "verify", "report", "tail"])
    ap.add_argument("--out", type=Path, default=ROOT / "out" / "goal_oracle")
    ap.add_argument("--windows", type=int, default=25)
    ap.add_argument("--fine", type=float, default=2.5e-5)
    ap.add_argument("--coarse", type=float, nargs="+", default=[2e-4, 1e-4])
    ap.add_argument("--ladder", type=float, nargs="+", default=[4e-4, 2e-4, 1e-4, 5e-5])
    ap.add_argument("--order-fit-max", type=float, default=2e-4, help="fit p over constant steps <= this")
    ap.add_argument("--p", type=float, default=None, help="order for the model (default: fitted)")
    ap.add_argument("--targets", type=float, nargs="+", default=[2e-4, 1e-4, 5e-5])
    ap.add_argument("--h-min", type=float, default=2.5e-5)
    ap.add_argument("--h-max", type=float, nargs="+", default=[1.6e-3, 4e-4])
    ap.add_argument("--reference", type=Path, default=None, help="a compare folder with runs/reference(-check)")
    ap.add_argument("--splits", type=float, nargs="+", default=[0.8384, 0.7744, 0.6464],
                    help="tail: times (on the output grid) after which the steps are free")
    a = ap.parse_args()
    a.out.mkdir(parents=True, exist_ok=True)
    if a.stage == "tail":
        tail_free(a.out, a)
        return
    res = analyse(a.out, a)
    p = a.p if a.p is not None else res["p_const"]
    if len(a.coarse) >= 2:                   # the order per window: |delta_k(h_c1)| / |delta_k(h_c2)|
        (h1, (m1, d1)), (h2, (m2, d2)) = list(res["W"].items())[:2]
        q = np.log(m1 / m2) / np.log(h1 / h2)
        lin = np.abs(d1 - d2 * (h1 ** p - a.fine ** p) / (h2 ** p - a.fine ** p)).max(axis=(1, 2)) / m1
        print(f"\norder per window from h_c = {h1 * 1e3:g} and {h2 * 1e3:g} ms (log of the |delta_k| ratio / log "
              f"{h1 / h2:g}; p = {p:.2f} gives {math.log((h1 ** p - a.fine ** p) / (h2 ** p - a.fine ** p)) / math.log(h1 / h2):.2f}), "
              "and the misfit of delta_k(h1) against delta_k(h2) scaled by the model, relative:")
        print("  " + " ".join(f"{x:.2f}" for x in q))
        print("  " + " ".join(f"{x:.2f}" for x in lin))
    for h_c in a.coarse:
        for h_max in a.h_max:
            bound(res, a, h_c, p, h_max)
    if a.stage == "weights":
        return
    ref = reference(a.reference)
    fine = res["fine"]
    lad_f = [(r["dostep"], res["D"][h]) for h, r in res["ladder"].items() if h != a.fine]
    lad_r = [(r["dostep"], err_ref(r, ref)) for h, r in res["ladder"].items()] if ref else []
    if ref:
        print("\nconstant steps against the reference: " + ", ".join(
            f"{h * 1e3:g} ms {err_ref(r, ref):.3g} ({r['dostep']})" for h, r in res["ladder"].items()))
    # the macro-step limit of the co-simulation: Richardson of the fine run and the one at twice its step
    # (order 2, measured above); the monolithic reference differs from it by a floor no macro step controls
    x2 = res["ladder"][2 * a.fine] if 2 * a.fine in res["ladder"] else None
    lim = None if x2 is None else {"t": fine["t"], "X": fine["X"] + (fine["X"] - x2["X"]) / 3.0}
    if lim is not None:
        lad_l = [(r["dostep"], float(np.abs(r["X"] - lim["X"]).max())) for h, r in res["ladder"].items()]
        print("constant steps against the macro-step limit (Richardson of the fine run and 2 x its step): "
              + ", ".join(f"{h * 1e3:g} ms {e:.3g} ({n})" for h, (n, e) in zip(res["ladder"], lad_l)))
        if ref:
            print(f"macro-step limit against the reference (a floor no macro step controls): {err_ref(lim, ref):.3g}")
    print(f"\nverification: the schedules run (p = {p:.2f}); 'lagrange': sum_k w_k H_k^p model, 'vector': SLSQP "
          "on the superposed error trajectories")
    todo = []
    for h_c in a.coarse:
        for h_max in a.h_max:
            for h, target, H, n_opt, ratio in bound(res, a, h_c, p, h_max, quiet=True):
                todo.append((f"lagrange_{h:g}_{h_c:g}_{h_max:g}_{a.windows}", h, H, n_opt, ratio, target))
                Hv = res["vector"][(h_c, h_max, h)]
                todo.append((f"vector_{h:g}_{h_c:g}_{h_max:g}_{a.windows}", h, Hv, float(np.sum(res["T"] / Hv)),
                             float("nan"), float("nan")))
    done = []
    for name, h, H, n_opt, ratio, target in todo:
            if any(np.allclose(H, G, rtol=1e-6) for G in done):
                continue
            done.append(H)
            r = run_schedule(a.out, name, res["edges"], H)
            e_f = float(np.abs(on_same_times(r, fine)).max())
            n_f = interp_dosteps(lad_f, e_f)
            line = (f"  {name}: {r['dostep']} doSteps (model "
                    f"{n_opt:.0f}, predicted ratio {ratio:.2f}); error vs fine {e_f:.3g} (model {target:.3g}): "
                    + (f"constant at that error {n_f:.0f}: ratio {n_f / r['dostep']:.2f}" if n_f else "outside the ladder"))
            if lim is not None:
                e_l = float(np.abs(r["X"] - lim["X"]).max())
                n_l = interp_dosteps(lad_l, e_l)
                line += (f"; vs macro-step limit {e_l:.3g}: " + (f"constant {n_l:.0f}: ratio {n_l / r['dostep']:.2f}"
                                                                 if n_l else "outside the ladder"))
            if ref:
                e_r = err_ref(r, ref)
                n_r = interp_dosteps(lad_r, e_r)
                line += (f"; vs reference {e_r:.3g}: " + (f"constant {n_r:.0f}: ratio {n_r / r['dostep']:.2f}"
                                                          if n_r else "outside the ladder"))
            print(line, flush=True)


if __name__ == "__main__":
    main()
