"""The least-damped eigenvalues of a rotor in linearised mass-conserving films
(rotor_fmu/film_system.py ``rightmost``: sparse shift-invert Arnoldi, counted by the argument
principle on the impedance determinant) against all eigenvalues of the same descriptor pencil by
dense QZ (``eigenvalues_dense``, the reference, as `stability --film mc` used it before), on 16 x 8
films where the dense solve is cheap: the oil-bath and free-to-air Jeffcott rotors and the
turbocharger (18 degrees of freedom, two different films, lightly damped shaft modes up to
75000 rad/s), over their speed ranges. The count itself against the dense spectrum, with the
eigenvalues right of its line unknown to it; the recovery when the first Arnoldi runs miss the
least-damped root; the dense answer when the count disagrees; and the threshold of both solvers."""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import pytest

import rotor_fmu.film_system as fs

REPO = Path(__file__).resolve().parents[1]
SCEN = {n: REPO / "scenarios" / f"{n}.yaml" for n in ("jeffcott_runup_oil_bath", "jeffcott_runup_free_to_air",
                                                      "turbocharger_runup_oil_bath")}
SMALL = [f"fmus.{b}.parameters.{k}={v}" for b in ("bearing1", "bearing2") for k, v in (("n_phi", 16), ("n_z", 8))]


def _films(name, sets=SMALL):
    from orchestrator.scenario import load_scenario
    from orchestrator.stability import _MCFilm, build_system
    from rotor_fmu.stability import static_bearing_loads
    system = build_system(load_scenario(str(SCEN[name]), sets, build_fmus=True))
    return system.rotor, _MCFilm(system, static_bearing_loads(system.rotor))


def _same_root(a, b):
    """The same eigenvalue to the dense solve's accuracy (its QZ on a pencil whose film cells reach
    1e8 1/s loses ~4e-7 relative; the Arnoldi values are roots of det D to rounding)."""
    return abs(a.real - b.real) < 1e-5 * abs(b) and abs(abs(a.imag) - abs(b.imag)) < 1e-5 * abs(b)


@pytest.mark.parametrize("name, speeds", [
    ("jeffcott_runup_oil_bath", np.geomspace(40.0, 800.0, 9)),
    ("jeffcott_runup_free_to_air", np.geomspace(40.0, 800.0, 9)),
    ("turbocharger_runup_oil_bath", np.geomspace(6.0, 105.0, 7)),
])
def test_rightmost_is_the_dense_solves_least_damped_root(name, speeds):
    rotor, films = _films(name)
    hint = ()
    for f in speeds:
        w = 2 * math.pi * f
        lins = films._films(w)
        r = fs.rightmost(rotor, w, lins, hint=hint)
        lam = fs.eigenvalues_dense(rotor, w, lins)
        assert r.method == "counted", f
        assert _same_root(r.eigenvalues[0], lam[0]), (f, r.eigenvalues[0], lam[0])
        # all eigenvalues right of the count's line, no more, no fewer
        right = lam[lam.real > r.alpha]
        assert r.eigenvalues.size == right.size and all(min(abs(right - v)) < 1e-5 * abs(v) for v in r.eigenvalues)
        det = fs.ImpedanceDeterminant(rotor, w, lins)
        sv = np.linalg.svd(det.D(r.eigenvalues[0]), compute_uv=False)
        assert sv[-1] < 1e-12 * sv[0]              # a root of det D to rounding
        hint = (r.eigenvalues[0],)


@pytest.mark.parametrize("f", [60.0, 182.45, 400.0])
def test_count_finds_every_eigenvalue_right_of_the_line_that_is_not_known(f):
    """count_right as if the Arnoldi runs had found none of the eigenvalues right of the line (only
    those left of it, and the films' own modes, all from the dense solves): for lines just left of
    each of the 12 rightmost eigenvalues, ``missing`` is the number of the dense solve's eigenvalues
    right of the line, one to 20 of them."""
    rotor, films = _films("jeffcott_runup_oil_bath")
    w = 2 * math.pi * f
    lins = films._films(w)
    lam = fs.eigenvalues_dense(rotor, w, lins)
    poles = np.concatenate([lin.poles() for lin in lins])
    det = fs.ImpedanceDeterminant(rotor, w, lins)
    modes = fs._rotor_modes(det)
    for alpha in np.unique(np.round(lam.real[:12], 6))[::-1] - 1.5:     # just left of each of the 12 rightmost
        n = fs.count_right(det, alpha, w, lam[lam.real < alpha], modes, poles)
        assert n.missing == int((lam.real > alpha).sum()), alpha


def test_a_missed_root_is_found_again(monkeypatch):
    """First Arnoldi runs far from the least-damped root (one shift at 3 omega): the count says what
    is missing, the next runs start where its phase falls fastest, and find it."""
    rotor, films = _films("jeffcott_runup_oil_bath")
    monkeypatch.setattr(fs, "_shifts", lambda modes, omega, hint=(): [complex(0.0, 3.0 * omega)])
    for f in (100.0, 300.0):
        w = 2 * math.pi * f
        lins = films._films(w)
        r = fs.rightmost(rotor, w, lins)
        assert r.method == "counted" and len(r.shifts) > 1
        assert _same_root(r.eigenvalues[0], fs.eigenvalues_dense(rotor, w, lins)[0])


def test_a_count_that_disagrees_means_the_dense_solve(monkeypatch):
    rotor, films = _films("jeffcott_runup_oil_bath")
    w = 2 * math.pi * 200.0
    lins = films._films(w)
    monkeypatch.setattr(fs, "count_right", lambda *a, **k: fs.Count(-1, 0, 0.0))
    r = fs.rightmost(rotor, w, lins)
    assert r.method == "dense"
    np.testing.assert_array_equal(r.eigenvalues, fs.eigenvalues_dense(rotor, w, lins))


def test_threshold_of_both_solvers():
    """`stability --film mc` with the counted solver (the default) and with the dense reference: the
    same crossing (to the 0.01 Hz of the refinement) and whirl."""
    from orchestrator.scenario import load_scenario
    from orchestrator.stability import stability
    sc = load_scenario(str(SCEN["jeffcott_runup_oil_bath"]), SMALL, build_fmus=True)
    a = stability(sc, film="mc", speeds=(100.0, 400.0), n_scan=6)
    b = stability(sc, film="mc", speeds=(100.0, 400.0), n_scan=6, mc_solver="dense")
    assert a["status"] == b["status"] == "threshold"
    assert abs(a["threshold_hz"] - b["threshold_hz"]) < 0.01
    assert abs(a["whirl_hz"] - b["whirl_hz"]) < 0.01
    assert "argument principle" in a["method"] and "dense QZ" in b["method"]
    assert not any("densely" in n for n in a["notes"])


def test_the_oil_bath_mode_near_the_running_speed_is_the_journals_own():
    """docs/analysis.md, "Above the threshold": the oil-bath rotor's root that crosses again near
    670 Hz (40 x 40) is a forward mode of the journal masses on their films, found by both solvers,
    not a mode of the films (their poles lie far from it, all stable). On 32 x 16 films (the
    coarsest of the grid study where it is unstable at 700 Hz; 16 x 8 and 24 x 12 damp it) at
    700 Hz: unstable near 0.88 x the speed, the disc still, and with lighter journals (0.25 kg,
    the disc 5.5 kg) higher and stable."""
    grid = [f"fmus.{b}.parameters.{k}={v}" for b in ("bearing1", "bearing2") for k, v in (("n_phi", 32), ("n_z", 16))]
    rotor, films = _films("jeffcott_runup_oil_bath", grid)
    w = 2 * math.pi * 700.0
    lins = films._films(w)
    r = fs.rightmost(rotor, w, lins)
    s = r.eigenvalues[0]
    assert r.method == "counted" and s.real > 20.0 and 0.85 < abs(s.imag) / w < 0.92, s
    assert _same_root(s, fs.eigenvalues_dense(rotor, w, lins)[0])
    _, sv, vh = np.linalg.svd(fs.ImpedanceDeterminant(rotor, w, lins).D(s))
    q = np.abs(vh[-1])                                   # the mode's rotor displacement
    journals = np.ravel(rotor.bearing_dofs)
    disc = np.setdiff1d(np.arange(q.size), journals)
    assert sv[-1] < 1e-12 * sv[0] and q[disc].max() < 1e-3 * q[journals].max()
    poles = lins[0].poles()
    assert poles.real.max() < -500.0 and np.abs(poles - s).min() > 0.3 * abs(s)
    rotor, films = _films("jeffcott_runup_oil_bath", grid + ["fmus.rotor.parameters.m_journal=0.25",
                                                             "fmus.rotor.parameters.m_disc=5.5"])
    lins = films._films(w)
    A, E = fs.pencil(rotor, w, lins)
    lam, _ = fs._shift_invert(A, E, complex(0.0, 0.9 * w), 8)
    light = lam[(lam.imag > 0.9 * w) & (lam.imag < 1.1 * w)]      # the journal mode, now above 0.9 x
    assert light.size and light.real.max() < -50.0, lam


@pytest.mark.slow
@pytest.mark.parametrize("name, f", [("jeffcott_runup_oil_bath", 182.45), ("jeffcott_runup_oil_bath", 800.0),
                                     ("turbocharger_runup_oil_bath", 48.0)])
def test_rightmost_on_the_shipped_40x40_films(name, f):
    """The shipped 40 x 40 films (1612 unknowns with the Jeffcott rotor, the dense QZ ~20 s): the
    same least-damped root, the count's eigenvalues those of the dense solve right of its line."""
    rotor, films = _films(name, [])
    w = 2 * math.pi * f
    lins = films._films(w)
    r = fs.rightmost(rotor, w, lins)
    lam = fs.eigenvalues_dense(rotor, w, lins)
    assert r.method == "counted" and _same_root(r.eigenvalues[0], lam[0])
    assert r.eigenvalues.size == int((lam.real > r.alpha).sum())


def test_the_same_pencil_gives_the_same_eigenvalues_bit_for_bit():
    """ARPACK starts from a random vector unless given one: the same `stability --film mc` scan
    then printed values differing in the 11th digit from run to run. _shift_invert gives it a
    fixed start vector, so two solves of one pencil agree bit for bit."""
    rotor, films = _films("jeffcott_runup_oil_bath")
    w = 2 * math.pi * 300.0
    A, E = fs.pencil(rotor, w, films._films(w))
    a = fs._shift_invert(A, E, complex(0.0, 0.5 * w), 8)
    b = fs._shift_invert(A, E, complex(0.0, 0.5 * w), 8)
    assert np.array_equal(a[0], b[0]) and np.array_equal(a[1], b[1])
