"""The oil-bath Jeffcott rotor's `stability --film mc` above its threshold: stable again at 413.86 Hz,
unstable again at 670.20 Hz (docs/analysis.md, "Above the threshold: stable again, unstable again").

    PY=".venv/bin/python docs/scripts/mc_above_threshold.py"
    $PY modes 40x40 700 --dense          # least-damped modes, their shape, the films' own poles, dense QZ
    $PY modes 80x80 700                   # (16x8 24x12 32x16 40x20 60x60 80x40 40x80 likewise)
    $PY modes 40x40 700 fmus.bearing1.parameters.theta_transport=0 fmus.bearing2.parameters.theta_transport=0
    $PY modes 40x40 700 fmus.rotor.parameters.m_journal=0.25 fmus.rotor.parameters.m_disc=5.5
    $PY impedance 40x40 700               # forward / backward impedance of the film against HS
    $PY series 40x40                      # equilibria (MC, HS) and the disc mode's damping, 300-700 Hz
    $PY timedomain 40 700 625 32          # the film alone under a forward whirl, shipped tolerances
    $PY runup RUN_DIR MC_JSON             # a run's whirl and near-synchronous bands against the linear scan
    $PY bands RUN_DIR                     # band amplitudes and growth rates over time (constant-speed runs)

GRID is n_phi x n_z of both bearings (the shipped scenario: 40x40), SPEED in Hz; further arguments
are --set values of the scenario. MC_JSON: `rotorcosim stability ... --film mc --json MC_JSON`.
"""

from __future__ import annotations

import json
import math
import sys
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[2]
sys.path.insert(0, str(ROOT))
BATH = ROOT / "scenarios" / "jeffcott_runup_oil_bath.yaml"
FWD = np.array([1.0, -1.0j]) / math.sqrt(2.0)      # e^H Z e: forward circular whirl (x = cos, y = sin)


def _grid(text: str) -> list[str]:
    n_phi, n_z = (int(v) for v in text.lower().split("x"))
    return [f"fmus.{b}.parameters.{k}={v}" for b in ("bearing1", "bearing2")
            for k, v in (("n_phi", n_phi), ("n_z", n_z))]


def _setup(grid: str, sets):
    from orchestrator.scenario import load_scenario
    from orchestrator.stability import _HSFilm, _MCFilm, build_system
    from rotor_fmu.stability import static_bearing_loads
    system = build_system(load_scenario(str(BATH), _grid(grid) + list(sets), build_fmus=True))
    loads = static_bearing_loads(system.rotor)
    return system, _MCFilm(system, loads), _HSFilm(system, loads)


def _pair(s) -> str:
    return f"{s.real:9.2f} 1/s at {abs(s.imag) / (2 * math.pi):7.2f} Hz"


def _angle(q) -> float:
    """Attitude angle [deg] of the journal centre from straight down (load direction), towards +x."""
    return math.degrees(math.atan2(q[0], -q[1]))


def modes(grid: str, f: float, *rest):
    """The least-damped eigenvalues near 0.9 f, 0.5 f and 135 Hz (shift-invert on the pencil), each
    with the disc's and the journals' amplitude (the journals' largest scaled to 0.01 c) and the
    ratio of the two films' parts; the films' own poles nearest the least-damped one; the dense QZ."""
    import scipy.sparse as sp

    import rotor_fmu.film_system as fs
    dense = "--dense" in rest
    system, mc, _ = _setup(grid, [a for a in rest if a != "--dense"])
    w = 2 * math.pi * f
    films = mc._films(w)
    rotor = system.rotor
    c = mc.models[0].c
    q = mc.q[0]
    print(f"{grid} at {f:g} Hz: eps {math.hypot(*q) / c:.4f}, attitude {_angle(q):.2f} deg, "
          f"film force {films[0].F0.tolist()} N")
    r = fs.rightmost(rotor, w, films)
    print(f"counted ({r.method}):", "; ".join(_pair(s) for s in r.eigenvalues if s.imag >= 0))
    A, E = fs.pencil(rotor, w, films)
    n = rotor.system_matrices(w)[0].shape[0]
    m = films[0].Js.shape[0]
    found = fs._Found()
    for sh in (0.9j * w, 0.5j * w, 2j * math.pi * 135.0):
        found.add(fs._shift_invert(A, E, complex(sh), 8))
    disc = [k for k in range(n) if k not in np.ravel(rotor.bearing_dofs)]
    for s, x in sorted(zip(found.values, found.vectors, strict=True), key=lambda p: -p[0].real)[:12]:
        if s.imag <= 0:
            continue
        jq = np.abs(x[np.ravel(rotor.bearing_dofs)]).max()
        scale = 0.01 * c / jq
        print(f"  {_pair(s)}: disc {np.abs(x[disc]).max() * scale / c:.2e} c, journals 0.01 c, "
              f"film 2 / film 1 {np.linalg.norm(x[2 * n + m:]) / np.linalg.norm(x[2 * n:2 * n + m]):.3f}")
    top = found.array()[0]
    f0 = films[0]
    poles, _ = fs._shift_invert(-f0.Js.tocsc(), sp.diags(f0.Mdiag).tocsc(), complex(top.real, abs(top.imag)), 12)
    print("film 1's own poles nearest it:", "; ".join(_pair(p) for p in sorted(poles, key=lambda p: -p.real)
                                                   if p.imag >= 0))
    if dense:
        lam = fs.eigenvalues_dense(rotor, w, films)
        print("dense QZ:", "; ".join(_pair(s) for s in lam[:10] if s.imag >= 0))


def impedance(grid: str, f: float, *sets):
    """Coefficients and forward / backward impedances of the MC film and of the HS film at f."""
    system, mc, hs = _setup(grid, sets)
    w = 2 * math.pi * f
    lin = mc._films(w)[0]
    K, C = hs(w)
    c = mc.models[0].c
    print(f"MC: eps {math.hypot(*mc.q[0]) / c:.4f}, attitude {_angle(mc.q[0]):.1f} deg; HS: eps "
          f"{math.hypot(*hs.q[0]) / c:.4f}, attitude {_angle(hs.q[0]):.1f} deg")
    print("MC Z(0) [MN/m]", np.round(lin.quasi_steady()[0] / 1e6, 3).tolist(), " HS K [MN/m]",
          np.round(K[0] / 1e6, 3).tolist(), " HS C [N s/m]", np.round(C[0]).tolist())
    print("nu [Hz]: forward e^H Z e  MC | HS;  backward  MC | HS  [MN/m]")
    for nu in (100, 135, 300, 0.5 * f, 500, 600, 630, 650, 700):
        s = 2j * math.pi * nu
        Zm, Zh = lin.impedance(s), K[0] + s * C[0]
        fw = [np.conj(FWD) @ Z @ FWD / 1e6 for Z in (Zm, Zh)]
        bw = [FWD @ Z @ np.conj(FWD) / 1e6 for Z in (Zm, Zh)]
        print(f"  {nu:6.1f}: {fw[0]:.3f} | {fw[1]:.3f};  {bw[0]:.3f} | {bw[1]:.3f}")


def series(grid: str, *sets):
    """The static equilibria of both films and, as a rough picture of the re-stabilisation, the
    damping of the disc mode (nu = 133 Hz) with each journal's film in series with its half of the
    shaft (k_s = 2 MN/m): d_ext nu + 2 Im(k_s Z_f / (k_s + Z_f)), Z_f the forward impedance."""
    system, mc, hs = _setup(grid, sets)
    c = mc.models[0].c
    nu = 2 * math.pi * 133.0
    ks, d_ext = 2.0e6, 500.0
    print("speed [Hz] | MC eps, attitude | HS eps, attitude | disc-mode damping [MN/m] MC, HS | HS max Re [1/s]")
    for f in (300, 350, 400, 414, 450, 500, 550, 600, 650, 665, 700):
        w = 2 * math.pi * f
        lin = mc._films(w)[0]
        K, C = hs(w)
        out = []
        for Z in (lin.impedance(1j * nu), K[0] + 1j * nu * C[0]):
            zf = np.conj(FWD) @ Z @ FWD
            out.append((d_ext * nu + 2 * (ks * zf / (ks + zf)).imag) / 1e6)
        re, im = hs.max_re(w)
        print(f"{f:5d} | {math.hypot(*mc.q[0]) / c:.3f} {_angle(mc.q[0]):5.1f} | {math.hypot(*hs.q[0]) / c:.3f} "
              f"{_angle(hs.q[0]):5.1f} | {out[0]:+.3f} {out[1]:+.3f} | {re:+.2f} at {im / (2 * math.pi):.1f} Hz")


def timedomain(n: int, f: float, nu_hz: float, n_per: int, *tight):
    """The film alone (n x n, the scenario's bearing) at its static equilibrium at f under a forward
    whirl... per column: x (then y) = q0 +- 1e-3 c sin(nu t), n_per steps of BearingModel.step a period,
    the shipped tolerances (``tight``: theta_atol 1e-5, Newton 1e-7 / 1e-8); the force's Fourier
    component at nu against Z(i nu), forward part."""
    from bearing_fmu.linearize import MCFilmLinear
    from bearing_fmu.model import BearingModel, BearingParams, solve_stationary
    from orchestrator.scenario import load_scenario
    from orchestrator.stability import _MCFilm, build_system
    from rotor_fmu.stability import static_bearing_loads
    system = build_system(load_scenario(str(BATH), _grid(f"{n}x{n}"), build_fmus=True))
    mc = _MCFilm(system, static_bearing_loads(system.rotor))
    omega = 2 * math.pi * f
    mc._films(omega)
    q0 = mc.q[0]
    p: BearingParams = system.bearings[0].params
    if tight:
        p = p.replace(theta_atol=1e-5, newton_atol=1e-7, newton_rtol=1e-8)
    lin = MCFilmLinear(solve_stationary(p, q0[0], q0[1], omega))
    nu = 2 * math.pi * nu_hz
    T = 2 * math.pi / nu
    dt, delta = T / n_per, 1e-3 * p.c
    n_settle = int(math.ceil(0.03 / T))
    n_tot = (n_settle + 1) * n_per
    tm = (np.arange(n_tot) + 0.5) * dt          # the step's midpoint (docs/analysis.md, check (c))
    cols = []
    for j in (0, 1):
        F = []
        for sg in (1.0, -1.0):
            b = BearingModel(p)
            b.initialize(q0[0], q0[1], 0.0, 0.0, omega)
            b.film.init_state(lin.u.copy())
            Fs = np.empty((n_tot, 2))
            for k in range(n_tot):
                d, v = np.zeros(2), np.zeros(2)
                d[j], v[j] = sg * delta * math.sin(nu * tm[k]), sg * delta * nu * math.cos(nu * tm[k])
                b.step(dt, q0[0] + d[0], q0[1] + d[1], v[0], v[1], omega)
                Fs[k] = b.outputs["Fx"], b.outputs["Fy"]
            F.append(Fs)
        m = slice(n_settle * n_per, n_tot)
        dF = (F[0] - F[1]) / 2
        cols.append(2.0 / n_per * (dF[m] * np.exp(-1j * nu * tm[m])[:, None]).sum(axis=0) / (1j * delta))
    Zt, Zl = np.column_stack(cols), lin.impedance(1j * nu)
    print(f"{n}x{n} at {f:g} Hz, nu {nu_hz:g} Hz, {n_per} steps a period ({dt:.3g} s), "
          f"{'tight' if tight else 'shipped'} tolerances: forward Z transient "
          f"{np.conj(FWD) @ Zt @ FWD / 1e6:.3f}, linear {np.conj(FWD) @ Zl @ FWD / 1e6:.3f} MN/m, "
          f"max rel diff {np.abs(Zt - Zl).max() / np.abs(Zl).max():.3g}")


def _spectra(run: str, window: int, hop: int):
    from orchestrator.results.whirl import WhirlParams, order_spectra
    data = np.genfromtxt(Path(run) / "results.csv", delimiter=",", names=True)
    z = data["rotorx_1"] + 1j * data["rotory_1"]
    return data, order_spectra(data["time"], z, data["rotoromega"], WhirlParams(window_revs=window, hop_revs=hop))


def runup(run: str, mc_json: str):
    """Journal 1 of a run-up: the whirl band (0.15-0.85 x, 16-revolution windows) and a near-synchronous
    band (0.82-0.95 x, 32 revolutions, clear of the 1x bin) with their growth rates, against the
    linear scan's largest real part; the mean journal position over +-5 Hz against the static
    equilibria; the speeds at which the whirl amplitude of 413.86 Hz, decaying at the linear rates
    on the run's ramp (400 Hz/s), would fall to 1/2, 0.05 c and 0.025 c (the vanish level)."""
    from orchestrator.results.whirl import dominant_ratio, growth_rate
    c = 1.372e-5
    scan = json.loads(Path(mc_json).read_text())["scan"]
    ls = np.array([v["speed_hz"] for v in scan])
    lr = np.array([v["max_re_per_s"] for v in scan])
    data, s = _spectra(run, 16, 2)
    sub = s.band_amplitude(0.15, 0.85) / c
    sig = growth_rate(s.t, sub, 9)
    ratio = dominant_ratio(s)
    _, s32 = _spectra(run, 32, 2)
    near = s32.band_amplitude(0.82, 0.95) / c
    print("speed [Hz] | whirl band /c, growth [1/s], ratio | linear max Re | 0.82-0.95 x band /c")
    for k in range(0, s.n_frames, 3):
        f = s.speed_hz[k]
        if f >= 380:
            print(f"{f:6.1f} | {sub[k]:.3e} {sig[k]:6.1f} {ratio[k]:.3f} | {np.interp(f, ls, lr):6.1f} | "
                  f"{np.interp(f, s32.speed_hz, near):.2e}")
    ff = np.linspace(413.86, ls[-1], 20000)
    rate = np.interp(ff, ls, lr)
    decay = np.concatenate([[0.0], np.cumsum(0.5 * np.diff(ff) * (rate[1:] + rate[:-1]) / 400.0)])
    a0 = float(np.interp(413.86, s.speed_hz, sub))
    for level in (0.5 * a0, 0.05, 0.025):
        k = int(np.argmax(a0 * np.exp(decay) < level))
        ran = s.speed_hz[int(np.argmax((sub < level) & (s.speed_hz > 413.86)))]
        print(f"whirl {a0:.3f} c at 413.86 Hz down to {level:.3f} c: linear decay at {ff[k]:.1f} Hz, "
              f"the run at {ran:.1f} Hz")
    fhz = data["rotoromega"] / (2 * math.pi)
    system, mc, _ = _setup("40x40", [])
    for f in (550, 600, 650, 700, 750):
        m = np.abs(fhz - f) < 5
        mx, my = data["rotorx_1"][m].mean(), data["rotory_1"][m].mean()
        mc._films(2 * math.pi * f)
        print(f"{f} Hz: run mean eps {math.hypot(mx, my) / c:.4f}, attitude {_angle((mx, my)):.2f} deg; static "
              f"{math.hypot(*mc.q[0]) / c:.4f}, {_angle(mc.q[0]):.2f} deg")


def bands(run: str, window: str = "8"):
    """Journal 1's band amplitudes (0.1-0.4, 0.4-0.6, 0.8-1.0 x) and growth rates over time."""
    from orchestrator.results.whirl import dominant_ratio, growth_rate
    c = 1.372e-5
    data, s = _spectra(run, int(window), 1)
    amps = [s.band_amplitude(lo, hi) / c for lo, hi in ((0.1, 0.4), (0.4, 0.6), (0.8, 1.0))]
    sig = [growth_rate(s.t, a, 9) for a in amps]
    r = dominant_ratio(s, (0.76, 1.0))
    print("t [s] speed [Hz] | 0.1-0.4 x /c, growth | 0.4-0.6 x | 0.8-1.0 x, ratio")
    for k in range(0, s.n_frames, max(1, s.n_frames // 25)):
        cols = " | ".join(f"{a[k]:.2e} {g[k]:6.1f}" for a, g in zip(amps, sig, strict=True))
        print(f"{s.t[k]:.4f} {s.speed_hz[k]:6.1f} | {cols} {r[k]:.3f}")


if __name__ == "__main__":
    cmd, args = sys.argv[1], sys.argv[2:]
    if cmd == "modes":
        modes(args[0], float(args[1]), *args[2:])
    elif cmd == "impedance":
        impedance(args[0], float(args[1]), *args[2:])
    elif cmd == "series":
        series(args[0], *args[1:])
    elif cmd == "timedomain":
        timedomain(int(args[0]), float(args[1]), float(args[2]), int(args[3]), *args[4:])
    elif cmd == "runup":
        runup(args[0], args[1])
    elif cmd == "bands":
        bands(*args)
    else:
        raise SystemExit(__doc__)
