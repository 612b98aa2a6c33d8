"""`rotorcosim stability --film mc` with floating-ring bearings (orchestrator/stability/films.py
``_RingMCFilm``; rotor_fmu/floating_ring_stability.py ``RingRotor``, ``MCRingStation``): each
ring's operating point with its two steady mass-conserving films (torque balance of their wall
shear), the inner film's impedance on the journal's motion relative to the ring, the outer's on
the ring's, the ring's translation as two more degrees of freedom, its spin held.

Checks, all on 16 x 8 films of the shipped free-to-air floating-ring scenarios:

* the counted solver (sparse Arnoldi + argument principle) finds the dense QZ solve's least-damped
  root at several speeds (as tests/test_film_system.py for plain bearings), and that root makes
  the characteristic matrix assembled independently in the physical coordinates (journal, ring;
  the inner film between them, ``P = [I, -I]``, with ``MCFilmLinear.impedance``) singular: the
  check of the coordinate change ``RingRotor`` makes for the solver;
* a locked ring (outer film 833 x as viscous, 3.5 x tighter: the ring speed falls to 1.7e-4 of
  the journal's and the ring cannot move at the rotor's frequencies) leaves the rotor in its
  inner films alone: the ring system then has the least-damped eigenvalue of the plain-bearing
  ``--film mc`` path (``_MCFilm``, its own equilibria, no ring) with JournalBearings of the inner
  films' parameters, at the inner film's wedge speed (the Jeffcott rotor has no gyroscopic
  terms). An independent reference, to 1e-4;
* the command: its threshold is a root on the imaginary axis (the dense solve there), the
  refusals (HS films, --ring-spin);
* continuation in the speed (MCRingStation.continued, the search's pass over the speeds its scan
  left out): speeds whose cold start fails (32 x 16 Jeffcott rings at 29 and 29.97 Hz) computed
  with the values of a walk down from above, one it cannot reach left out with both reasons, the
  order of the pass and a stop during it (plain functions);
* the hint shift of film_system._shifts: the least-damped root itself as the hint is counted and
  found as without it (16 x 8 turbocharger rings).
"""

from __future__ import annotations

import dataclasses
import json
import math
from pathlib import Path

import numpy as np
import pytest

from hostile_builders import run_verb

REPO = Path(__file__).resolve().parents[1]
JEFF = REPO / "scenarios" / "jeffcott_runup_floating_ring_free_to_air.yaml"
TURBO = REPO / "scenarios" / "turbocharger_runup_floating_ring_free_to_air.yaml"
JEFF_HS = REPO / "scenarios" / "jeffcott_runup_floating_ring_half_sommerfeld.yaml"
SMALL = [f"fmus.{b}.parameters.{k}_{s}={v}" for b in ("bearing1", "bearing2") for s in ("inner", "outer")
         for k, v in (("n_phi", 16), ("n_z", 8))]


def _system(path, sets=SMALL):
    from orchestrator.scenario import load_scenario
    from orchestrator.stability import build_system
    return build_system(load_scenario(str(path), sets, build_fmus=True))


def _same_root(a, b):
    """As tests/test_film_system.py: the same eigenvalue to the dense solve's accuracy."""
    return abs(a.real - b.real) < 1e-5 * abs(b) and abs(abs(a.imag) - abs(b.imag)) < 1e-5 * abs(b)


def _physical_D(system, omega, points, s):
    """s^2 M + s C + K + sum P^T Z(s) P in the physical coordinates (rotor dofs, then each ring's x, y),
    the inner film on journal minus ring, the outer on the ring: assembled here, not by RingRotor."""
    M, C, K = system.rotor.system_matrices(omega)
    n, ns = M.shape[0], len(points)
    N = n + 2 * ns
    D = np.zeros((N, N), complex)
    D[:n, :n] = s * s * M + s * C + K
    for k, (pt, (ix, iy)) in enumerate(zip(points, system.rotor.bearing_dofs)):
        r = [n + 2 * k, n + 2 * k + 1]
        D[r, r] += s * s * pt.params.m_ring
        Pi = np.zeros((2, N))
        Pi[0, ix], Pi[1, iy], Pi[0, r[0]], Pi[1, r[1]] = 1.0, 1.0, -1.0, -1.0
        Po = np.zeros((2, N))
        Po[0, r[0]] = Po[1, r[1]] = 1.0
        D += Pi.T @ pt.inner.impedance(s) @ Pi + Po.T @ pt.outer.impedance(s) @ Po
    return D


@pytest.mark.parametrize("path, speeds", [
    (JEFF, (116.85490562919915, 150.0, 300.0, 500.0, 650.0, 800.0)),   # 116.85 Hz: see test_count_at_116_hz
    (TURBO, (80.0, 90.0, 105.0)),
])
def test_counted_rightmost_is_the_dense_solves_least_damped_root(path, speeds):
    import rotor_fmu.film_system as fs
    from orchestrator.stability.films import _RingMCFilm
    from rotor_fmu.floating_ring_stability import mc_ring_films
    from rotor_fmu.stability import static_bearing_loads
    system = _system(path)
    films = _RingMCFilm(system, static_bearing_loads(system.rotor))
    hint = ()
    for f in speeds:
        w = 2 * math.pi * f
        points = films.points(w)
        for pt in points:        # the operating point: torques balance, the films carry the load
            Tri, Tro, Tj = pt.torques
            assert abs(Tri + Tro) < 1e-4 * abs(Tj), (f, pt.torques)
            assert 0.05 < pt.Om / w < 0.6 and 0.0 < pt.outputs["eps"] < 1.0 and 0.0 < pt.outputs["eps_outer"] < 1.0
        lins = mc_ring_films(points)
        r = fs.rightmost(films.rotor, w, lins, hint=hint)
        lam = fs.eigenvalues_dense(films.rotor, w, lins)
        assert r.method == "counted", f
        assert _same_root(r.eigenvalues[0], lam[0]), (f, r.eigenvalues[0], lam[0])
        right = lam[lam.real > r.alpha]
        assert r.eigenvalues.size == right.size and all(min(abs(right - v)) < 1e-5 * abs(v) for v in r.eigenvalues)
        sv = np.linalg.svd(_physical_D(system, w, points, r.eigenvalues[0]), compute_uv=False)
        assert sv[-1] < 1e-10 * sv[0], (f, sv[-1] / sv[0])
        hint = (r.eigenvalues[0],)


def test_a_locked_ring_is_the_plain_bearing_mc_path():
    import rotor_fmu.film_system as fs
    from orchestrator.stability import Bearing
    from orchestrator.stability.films import _MCFilm, _RingMCFilm
    from rotor_fmu.floating_ring_stability import mc_ring_films
    from rotor_fmu.stability import static_bearing_loads
    lock = [f"fmus.{b}.parameters.{k}={v}" for b in ("bearing1", "bearing2")
            for k, v in (("eta0_outer", 10.0), ("psi_outer", 1.0e-3))]
    system = _system(JEFF, SMALL + lock)
    loads = static_bearing_loads(system.rotor)
    rings = _RingMCFilm(system, loads)
    plain_system = dataclasses.replace(system, bearings=[Bearing(b.instance, b.station, b.params.inner)
                                                         for b in system.bearings])
    plain = _MCFilm(plain_system, loads)
    for f in (200.0, 400.0, 700.0):
        w = 2 * math.pi * f
        points = rings.points(w)
        Om = points[0].Om
        assert Om / w < 3e-4 and points[1].Om == Om
        lam = fs.eigenvalues_dense(rings.rotor, w, mc_ring_films(points))
        # the plain path's films at the inner film's wedge speed, the rotor at its own speed
        ref = fs.rightmost(system.rotor, w, plain._films(w + Om)).eigenvalues[0]
        near = lam[np.argmin(np.abs(lam - ref))]
        assert abs(near - ref) < 1e-4 * abs(ref), (f, near, ref)


def test_command_threshold_is_a_root_on_the_axis(capsys, tmp_path):
    import rotor_fmu.film_system as fs
    from orchestrator.stability.films import _RingMCFilm
    from rotor_fmu.floating_ring_stability import mc_ring_films
    from rotor_fmu.stability import static_bearing_loads
    out = tmp_path / "r.json"
    sets = [a for s in SMALL for a in ("--set", s)]
    code, text, err = run_verb(capsys, "stability", JEFF, "--film", "mc", "--speeds", "500:800", "--scan", "8",
                               "--json", out, *sets)
    assert code == 0, err
    r = json.loads(out.read_text())
    assert r["film"] == "mc" and r["status"] == "threshold" and r["complete"]
    assert "mass-conserving inner and outer films" in r["method"]
    assert not any("those of the half-Sommerfeld film" in n for n in r["notes"])
    b1 = r["bearings"]["bearing1"]
    assert 0.2 < b1["ring_speed_ratio_at_threshold"] < 0.5 and 0.0 < b1["eps_outer_at_threshold"] < 1.0
    system = _system(JEFF)
    films = _RingMCFilm(system, static_bearing_loads(system.rotor))
    w = 2 * math.pi * r["threshold_hz"]
    lam = fs.eigenvalues_dense(films.rotor, w, mc_ring_films(films.points(w)))
    assert abs(lam[0].real) < 0.05 and abs(abs(lam[0].imag) / (2 * math.pi) - r["whirl_hz"]) < 1e-6 * r["whirl_hz"]


def test_half_sommerfeld_rings_and_ring_spin_are_refused(capsys):
    code, text, err = run_verb(capsys, "stability", JEFF_HS, "--film", "mc", "--scan", "4")
    assert code != 0 and "cavitation_inner = 0" in err and "--film hs" in err
    code, text, err = run_verb(capsys, "stability", JEFF, "--film", "mc", "--ring-spin", "--scan", "4")
    assert code != 0 and "--film mc --ring-spin" in err and "held" in err


def test_count_at_116_hz_is_not_sent_to_the_dense_solve():
    """At 116.85 Hz (a speed of the default 80-speed scan) a real root (-162.06 1/s) and an outer film's
    pole (-161.23 1/s) lie close together left of the count's line: D(alpha) is ill-conditioned and
    arg h(alpha) came out 1e-5 rad off a multiple of pi, the count 3e-6 off an integer, which the
    count refused (the dense solve followed). It is rounding (count_right's PHI0_TOL)."""
    import rotor_fmu.film_system as fs
    from orchestrator.stability.films import _RingMCFilm
    from rotor_fmu.floating_ring_stability import mc_ring_films
    from rotor_fmu.stability import static_bearing_loads
    system = _system(JEFF)
    films = _RingMCFilm(system, static_bearing_loads(system.rotor))
    w = 2 * math.pi * 116.85490562919915
    lins = mc_ring_films(films.points(w))
    r = fs.rightmost(films.rotor, w, lins)
    assert r.method == "counted"
    assert _same_root(r.eigenvalues[0], fs.eigenvalues_dense(films.rotor, w, lins)[0])


def test_a_disagreeing_count_on_a_pencil_too_large_for_qz_leaves_the_speed_out(monkeypatch):
    """Where the count disagrees, the dense QZ of the pencil follows; above RING_DENSE_MAX unknowns
    (the turbocharger's 160 x 40 ring films: ~12900, hours) the speed is refused instead, with the fix."""
    import orchestrator.stability.films as films_mod
    import rotor_fmu.film_system as fs
    from orchestrator.stability import StabilityError
    from orchestrator.stability.films import _RingMCFilm
    from rotor_fmu.stability import static_bearing_loads
    system = _system(JEFF)
    films = _RingMCFilm(system, static_bearing_loads(system.rotor))
    monkeypatch.setattr(fs, "count_right", lambda *a, **k: fs.Count(-1, 0, 0.0))
    w = 2 * math.pi * 300.0
    films.max_re(w)                                    # small: solved densely
    assert films.dense_speeds == [w]
    monkeypatch.setattr(films_mod, "RING_DENSE_MAX", 100)
    with pytest.raises(StabilityError, match=r"at 300 Hz the argument-principle count disagreed.*left out.*n_phi_inner"):
        films.max_re(w)


GRID_32 = [f"fmus.{b}.parameters.{k}_{s}={v}" for b in ("bearing1", "bearing2") for s in ("inner", "outer")
           for k, v in (("n_phi", 32), ("n_z", 16))]


def test_speeds_whose_cold_start_fails_are_reached_by_continuation(capsys, tmp_path):
    """On 32 x 16 films the Jeffcott rings have no operating point at 29 and 29.97 Hz from the cold
    start (the scan's first speeds: the journal Newton leaves 0.995 c), while from 30.97 Hz downwards
    they have one. The search computes them after the scan by continuation in the speed from their
    neighbours (MCRingStation.continued, _RingMCFilm.max_re_continued): before, they were left out.
    The values are those of a walk down from 32 Hz (each speed warm from the last), and the speeds
    that converged in the scan are unchanged."""
    from orchestrator.stability.films import _RingMCFilm
    from rotor_fmu.stability import static_bearing_loads
    out = tmp_path / "r.json"
    sets = [a for s in GRID_32 for a in ("--set", s)]
    code, text, err = run_verb(capsys, "stability", JEFF, "--film", "mc", "--speeds", "29:32", "--scan", "4",
                               "--json", out, *sets)
    assert code == 1 and "linearly stable in that range" in err        # no crossing at 29-32 Hz
    r = json.loads(out.read_text())
    assert r["complete"] and r["status"] == "stable"
    assert "speeds_without_equilibrium_hz" not in r
    assert r["continued_speeds_hz"] == pytest.approx([29.0, 29.96737193391587], rel=1e-12)
    assert any(n.startswith("2 speeds the scan left out (29, 29.97 Hz) computed again by continuation in the speed")
               and "the scan's reason at 29 Hz: floating-ring bearing" in n for n in r["notes"])
    assert all("no steady operating point" in x for x in r["continued_scan_reasons"])
    scan = {s["speed_hz"]: s["max_re_per_s"] for s in r["scan"]}
    assert len(scan) == 4
    # each cold start at the two lowest speeds fails (what made the scan leave them out)
    system = _system(JEFF, GRID_32)
    loads = static_bearing_loads(system.rotor)
    from orchestrator.stability import StabilityError
    for f in (29.0, 29.96737193391587):
        with pytest.raises(StabilityError, match="no steady operating point"):
            _RingMCFilm(system, loads).max_re(2 * math.pi * f)
    # the walk down from 32 Hz, each speed warm from the one above
    down = _RingMCFilm(system, loads)
    for f in sorted(scan, reverse=True):
        re = down.max_re(2 * math.pi * f)[0]
        assert abs(re - scan[f]) < 1e-6 * abs(re), (f, re, scan[f])
    # a speed that fails from the station's own start while another speed's point is known continues
    # from that one at once (as in the scan or Brent's refinement): cold again, then 29 Hz
    for st in down.stations:
        st._reset()
        st.ratio = None
    re = down.max_re(2 * math.pi * 29.0)[0]
    assert abs(re - scan[29.0]) < 1e-6 * abs(re), (re, scan[29.0])


def test_a_hint_on_this_speeds_root_finds_it_counted_as_without_the_hint():
    """rightmost's ``hint`` (the last speed's least-damped root, a shift of its Arnoldi runs) lying ON
    this speed's root, as it does in Brent's last steps of a refinement: _shifts places its shift 1e-3
    |h| right of the hint. With the shift on the hint, ARPACK's shift-invert operator is singular to
    rounding: on these 16 x 8 turbocharger rings at 63, 70 and 105 Hz the count then disagreed and the
    speed went to the dense solve (on the shipped 160 x 40 films that is refused, and the refinement
    stopped one step short at 42.49 and 73.50 Hz). Here the hinted search is counted (no dense solve
    allowed) and finds the root it finds without the hint."""
    import rotor_fmu.film_system as fs
    from orchestrator.stability.films import _RingMCFilm
    from rotor_fmu.floating_ring_stability import mc_ring_films
    from rotor_fmu.stability import static_bearing_loads
    system = _system(TURBO)
    films = _RingMCFilm(system, static_bearing_loads(system.rotor))
    for f in (105.0, 70.0, 63.0):
        w = 2 * math.pi * f
        lins = mc_ring_films(films.points(w))
        free = fs.rightmost(films.rotor, w, lins, dense_max=0)
        assert free.method == "counted", f
        root = free.eigenvalues[0]
        for h in (root, root.conjugate()):
            r = fs.rightmost(films.rotor, w, lins, hint=(h,), dense_max=0)
            assert r.method == "counted", (f, h, r.method)
            got = r.eigenvalues[0]
            assert abs(got.real - root.real) < 1e-9 * abs(root), (f, h, got, root)
            assert abs(abs(got.imag) - abs(root.imag)) < 1e-9 * abs(root), (f, h, got, root)


def test_a_speed_the_continuation_cannot_reach_is_left_out_with_both_reasons(capsys, tmp_path):
    """On 16 x 8 films the turbocharger's turbine-side ring has no operating point below ~62 Hz (its
    outer film cannot carry the load inside 0.98 c): from 63.22 Hz the continuation towards 60.55 Hz
    comes to 62.05 Hz and stops where a step halved 4 times in a row still fails; 60.55 Hz is left
    out with that reason (where it started, how far it came, what failed), 58 Hz beyond it is not
    tried, and the command names the lowest speed with an equilibrium as the one already unstable,
    not the range's lower end."""
    out = tmp_path / "r.json"
    sets = [a for s in SMALL for a in ("--set", s)]
    code, text, err = run_verb(capsys, "stability", TURBO, "--film", "mc", "--speeds", "58:66", "--scan", "4",
                               "--json", out, *sets)
    assert code == 1
    assert "already unstable at the lowest speed with a static equilibrium (63.22 Hz; the speeds from 58 Hz" in err
    r = json.loads(out.read_text())
    assert r["status"] == "unstable_at_lower_bound" and "continued_speeds_hz" not in r
    assert r["speeds_without_equilibrium_hz"] == pytest.approx([58.0, 60.55], abs=0.01)
    note = next(n for n in r["notes"] if n.startswith("no static equilibrium at 2 of the 4 speeds"))
    assert "bearing2': no steady operating point of its mass-conserving films at 60.55 Hz (none from the warm " \
           "start of the scan there; continuation from 63.2177 Hz reached 62.05" in note
    assert "failed after 4 halvings in a row" in note
    assert any(n.startswith("1 speed the scan left out not tried again") for n in r["notes"])


def _fake(ws, cold_fails, reach_fails, calls):
    """max_re (crossing zero upwards at 300 Hz) failing from the scan's start at the speed indices
    ``cold_fails`` until the continuation (``continued``) has reached them (as _RingMCFilm, which then
    continues from that speed's point: Brent evaluates its bracket's ends again), the continuation
    failing at ``reach_fails``; the continued calls recorded in ``calls`` (speed indices)."""
    from orchestrator.stability import StabilityError
    index = {float(w): k for k, w in enumerate(ws)}

    def value(w):
        return float(np.cbrt((w - 2 * math.pi * 300.0) / (2 * math.pi * 300.0))), 0.45 * w

    def max_re(w):
        k = index.get(float(w))
        if k in cold_fails and (k not in calls or k in reach_fails):
            raise StabilityError(f"no operating point at {w / (2 * math.pi):.4g} Hz from the start")
        return value(w)

    def continued(w):
        calls.append(index[float(w)])
        if index[float(w)] in reach_fails:
            raise StabilityError(f"no operating point at {w / (2 * math.pi):.4g} Hz (continuation failed)")
        return value(w)
    return max_re, continued


def test_the_search_continues_outwards_from_the_speeds_done():
    """The search's pass over the speeds its scan left out (search._continue_left_out), with plain
    functions: a run below the first speed done walks downwards from it and ends at its first
    failure (the speeds beyond are not tried; the failure's reason is the note's), a run between
    two speeds done is walked from both ends alternately, and the threshold between speeds so
    computed is refined."""
    from orchestrator.stability.search import _search
    ws = 2 * math.pi * np.geomspace(100.0, 800.0, 20)       # 300 Hz between indices 10 and 11
    calls: list = []
    max_re, continued = _fake(ws, cold_fails={0, 1, 2, 3, 9, 10, 11, 12}, reach_fails={1}, calls=calls)
    result = {"speed_range_hz": [100.0, 800.0], "crossings": [], "crossings_bracketed": [], "notes": []}
    found = _search(max_re, ws, result, continued=continued)
    # walks: [3, 2, 1, 0] down from 4; [9, 10] up from 8 and [12, 11] down from 13, one speed of each in turn
    assert calls == [3, 9, 12, 2, 10, 11, 1]
    assert found.stop is None and result["status"] == "threshold"
    assert result["threshold_hz"] == pytest.approx(300.0, rel=1e-6)
    assert result["continued_speeds_hz"] == pytest.approx(sorted(ws[[2, 3, 9, 10, 11, 12]] / (2 * math.pi)))
    assert result["speeds_without_equilibrium_hz"] == pytest.approx(ws[[0, 1]] / (2 * math.pi))
    left = next(n for n in result["notes"] if n.startswith("no static equilibrium at 2 of the 20 speeds"))
    assert "(continuation failed)" in left
    assert any(n.startswith("1 speed the scan left out not tried again") for n in result["notes"])


def test_a_stop_during_the_continuation_names_the_whole_range_as_the_rest():
    from orchestrator.stability.search import _search
    from tests.test_stability_stop import _Requests
    ws = 2 * math.pi * np.geomspace(100.0, 800.0, 20)
    calls: list = []
    max_re, continued = _fake(ws, cold_fails={0, 1, 2}, reach_fails=set(), calls=calls)
    req = _Requests(None)

    def stopping(w):                  # a stop request arrives while the first continued speed is computed
        v = continued(w)
        req.requested, req.signum = True, 2
        return v
    result = {"speed_range_hz": [100.0, 800.0], "crossings": [], "crossings_bracketed": [], "notes": []}
    found = _search(max_re, ws, result, stop=req, continued=stopping)
    assert calls == [2]
    s = found.stop
    assert (s.by, s.phase, s.done, s.planned) == ("SIGINT", "continuation", 20, 20)
    assert s.rest == (100.0, 800.0, 20)
    assert result["continued_speeds_hz"] == pytest.approx([ws[2] / (2 * math.pi)])
    assert result["status"] == "threshold_bracketed"          # nothing computed after the stop (no Brent)
    from orchestrator.stability.partial import stop_message
    result["stopped"] = s.as_dict()
    msg = stop_message(result)
    assert "while computing the speeds the scan left out by continuation" in msg and "--speeds 100:800 --scan 20" in msg
