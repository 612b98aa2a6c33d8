"""Asperity contact of journal and shell (bearing_fmu/contact.py), checked against
independent quadratures of the Greenwood-Tripp integrals."""

import math

import numpy as np
import pytest
from scipy.integrate import quad

from bearing_fmu.contact import F52, H_CUTOFF, contact_coefficients, contact_force, normal_force
from bearing_fmu.linearize import linearization
from bearing_fmu.model import BearingParams, BearingModel

R, B, PSI = 4.9e-3, 7.84e-3, 2.8e-3
C = PSI * R
KW = dict(c=C, R=R, B=B, sigma=0.3e-6, KE=2.0e7, mu=0.1)


def f52_quad(H):
    """F_5/2 by direct quadrature of its definition (Greenwood & Tripp 1970)."""
    val, _ = quad(lambda s: (s - H) ** 2.5 * math.exp(-0.5 * s * s), H, np.inf,
                  epsabs=0.0, epsrel=1e-12, limit=200)
    return val / math.sqrt(2.0 * math.pi)


@pytest.mark.parametrize("H", [-1.5, 0.0, 0.7, 2.0, 3.5, 5.0])
def test_f52_closed_form_matches_its_integral(H):
    assert float(F52(H)) == pytest.approx(f52_quad(H), rel=1e-7)


def test_f52_series_matches_the_integral_over_its_range():
    """The compiled series the force uses (contact.f52_series) against the definition
    integrated independently here, on points that are not its interpolation nodes."""
    from bearing_fmu.contact import CHEB_LO, f52_cheb, f52_series
    coef = f52_series()
    H = np.linspace(CHEB_LO, H_CUTOFF, 57) + 0.0123
    H = H[H <= H_CUTOFF]
    rel = [f52_cheb(h, coef) / f52_quad(h) - 1.0 for h in H]
    assert max(abs(r) for r in rel) < 2e-12


def test_normal_force_beyond_the_series_uses_the_closed_form():
    """Deeper than CHEB_LO (e = 1.2 c: H down to -9.1) the force comes from F52 itself; at the
    series' lower end both give the same force."""
    from bearing_fmu.contact import CHEB_LO
    kw = dict(c=C, R=R, B=B, sigma=KW["sigma"], KE=KW["KE"])
    deep = 1.2 * C
    assert (C - deep) / KW["sigma"] < CHEB_LO
    psi6 = math.acos((C - H_CUTOFF * KW["sigma"]) / deep)
    closed = 2 * R * B * KW["KE"] * quad(
        lambda p: float(F52((C - deep * math.cos(p)) / KW["sigma"])) * math.cos(p), 0.0, psi6,
        epsrel=1e-12, limit=200)[0]
    assert normal_force(deep, **kw) == pytest.approx(closed, rel=1e-9)
    edge = C - CHEB_LO * KW["sigma"]                 # H = CHEB_LO exactly at psi = 0
    below, above = normal_force(edge * (1 + 1e-12), **kw), normal_force(edge * (1 - 1e-12), **kw)
    assert below == pytest.approx(above, rel=1e-9)


def force_by_quadrature(x, y, vx, vy, omega, *, c, R, B, sigma, KE, mu):
    """Contact force ON the journal by adaptive quadrature over the whole circumference,
    h(phi) = c - x cos phi - y sin phi, friction against the sliding direction; no
    line-of-centres argument (independent of the model's closed form)."""
    e = math.hypot(x, y)
    tx, ty = -y / e, x / e
    s = math.tanh((vx * tx + vy * ty + omega * R) / 1e-3)

    def p(phi):
        H = (c - x * math.cos(phi) - y * math.sin(phi)) / sigma
        return KE * f52_quad(H) if H < H_CUTOFF else 0.0

    a = math.atan2(y, x)
    pts = [a + d for d in (-0.5, -0.2, 0.0, 0.2, 0.5)]
    fx = -R * B * quad(lambda f: p(f) * math.cos(f), a - math.pi, a + math.pi, points=pts, limit=400)[0]
    fy = -R * B * quad(lambda f: p(f) * math.sin(f), a - math.pi, a + math.pi, points=pts, limit=400)[0]
    fn = math.hypot(fx, fy)
    return fx - mu * fn * s * tx, fy - mu * fn * s * ty, fn


@pytest.mark.parametrize("eps,ang", [(0.95, -1.2), (0.985, 2.0), (1.0, 0.3), (1.01, -2.8)])
def test_contact_force_matches_full_circumference_quadrature(eps, ang):
    x, y = eps * C * math.cos(ang), eps * C * math.sin(ang)
    Fx, Fy, Fn, T = contact_force(x, y, 1e-3, -2e-3, 500.0, **KW)
    qx, qy, qn = force_by_quadrature(x, y, 1e-3, -2e-3, 500.0, **KW)
    assert Fn == pytest.approx(qn, rel=1e-6)
    assert Fx == pytest.approx(qx, rel=1e-6, abs=1e-9 * qn)
    assert Fy == pytest.approx(qy, rel=1e-6, abs=1e-9 * qn)
    # pushes the journal back (normal part) and brakes it (torque against omega > 0)
    assert (Fx * x + Fy * y) < 0
    assert T == pytest.approx(-KW["mu"] * Fn * R, rel=1e-9)


def test_no_contact_away_from_the_shell():
    e = C - H_CUTOFF * KW["sigma"] - 1e-9
    assert contact_force(e, 0.0, 0.0, 0.0, 500.0, **KW) == (0.0, 0.0, 0.0, 0.0)
    K, Cc = contact_coefficients(0.5 * C, 0.0, 0.0, 0.0, 500.0, **KW)
    assert not K.any() and not Cc.any()


def test_contact_force_grows_monotonically_into_the_shell():
    e = np.linspace(0.9, 1.02, 61) * C
    f = [normal_force(v, c=C, R=R, B=B, sigma=KW["sigma"], KE=KW["KE"]) for v in e]
    assert np.all(np.diff(f) > 0)


def test_contact_coefficients_match_the_line_of_centres_derivatives():
    """Normal part: K = dFn/de e e^T + Fn/e t t^T (derivative of Fn(e) e_r), checked
    with mu = 0 against a derivative of the independent quadrature."""
    kw = dict(KW, mu=0.0)
    ang = 0.7
    e0 = 0.99 * C
    x, y = e0 * math.cos(ang), e0 * math.sin(ang)
    K, Cc = contact_coefficients(x, y, 0.0, 0.0, 500.0, **kw)
    d = 1e-10
    dfn = (force_by_quadrature(x + d * math.cos(ang), y + d * math.sin(ang), 0, 0, 500.0, **kw)[2]
           - force_by_quadrature(x - d * math.cos(ang), y - d * math.sin(ang), 0, 0, 500.0, **kw)[2]) / (2 * d)
    fn = normal_force(e0, c=C, R=R, B=B, sigma=kw["sigma"], KE=kw["KE"])
    er = np.array([math.cos(ang), math.sin(ang)])
    et = np.array([-er[1], er[0]])
    want = dfn * np.outer(er, er) + fn / e0 * np.outer(et, et)
    assert np.allclose(K, want, rtol=1e-4, atol=1e-6 * np.abs(want).max())
    assert np.allclose(Cc, 0.0)


def small(**kw):
    return BearingParams(R=R, B=B, psi=PSI, eta0=0.012, n_phi=24, n_z=8, **kw)


@pytest.mark.parametrize("cav", [0, 1])
def test_bearing_adds_contact_to_film_force_and_coefficients(cav):
    """Outputs = the film's force on the (expected) gap + contact_force; coefficients =
    the film's + contact_coefficients."""
    from bearing_fmu.linearize import _force, hs_linearization
    x, y, w = 0.25 * C, -0.93 * C, 2 * math.pi * 70
    kw = dict(cavitation=cav, groove_width=0.26, axial_bc=1)
    b0, b1 = BearingModel(small(contact=0, **kw)), BearingModel(small(contact=1, **kw))
    for b in (b0, b1):
        b.initialize(x, y, 0.0, 0.0, w)
    fx, fy, fn, tq = contact_force(x, y, 0.0, 0.0, w, **KW)
    assert fn > 1.0
    o0, o1 = b0.outputs, b1.outputs
    assert o0["F_contact"] == 0.0 and o1["F_contact"] == fn
    if cav == 0:
        film = _force(b1, b1._pf_hs, np.ones_like(b1._pf_hs), b1._kin, film=False)
    else:
        p, th = b1._pth(full=False)
        film = _force(b1, p, th, b1._kin)
    assert o1["Fx"] == pytest.approx(film[0] + fx, rel=1e-12)
    assert o1["Fy"] == pytest.approx(film[1] + fy, rel=1e-12)
    # the expected gap changes the film only a little at h_min = 1.9 sigma
    assert o1["Fx"] - fx == pytest.approx(o0["Fx"], rel=0.02)
    assert o1["Fy"] - fy == pytest.approx(o0["Fy"], rel=0.02)
    K1, C1 = linearization(b1)
    Kf, Cf = hs_linearization(b1, *b1._inputs)
    Kc, Cc = contact_coefficients(x, y, 0.0, 0.0, w, **KW)
    assert np.allclose(K1, Kf + Kc) and np.allclose(C1, Cf + Cc)


def test_contact_parameters_are_checked():
    with pytest.raises(ValueError, match="contact"):
        small(contact=2)
    with pytest.raises(ValueError, match="sigma_rough"):
        small(contact=1, sigma_rough=0.0)
    with pytest.raises(ValueError, match="mu_contact"):
        small(contact=1, mu_contact=-0.1)
    with pytest.raises(ValueError, match="contact_h_limit"):
        small(contact=1, contact_h_limit=0.5)


# -- film solver: BDF restart when a macro step fails (bearing_fmu/solver.py) ---------

def _mc_bearing():
    b = BearingModel(small(cavitation=1, axial_bc=1, groove_width=0.26))
    b.initialize(0.2 * C, -0.6 * C, 0.0, 0.0, 2 * math.pi * 70, init="stationary")
    for _ in range(3):
        b.step(1e-4, 0.2 * C, -0.6 * C, 1e-3, -1e-3, 2 * math.pi * 70)
    return b


def test_restart_is_not_used_when_the_step_succeeds():
    a, b = _mc_bearing(), _mc_bearing()
    kin = (0.25 * C, -0.62 * C, 2e-3, -1e-3, 2 * math.pi * 70)
    a.step(1e-4, *kin)
    b.film.advance(1e-4, b._kinematics(*kin))
    assert np.array_equal(a.film.u, b.film.u)
    assert a.film.stats["restarts"] == 0


def test_failed_macro_step_is_retried_with_restarted_history(monkeypatch):
    from bearing_fmu.solver import StepFailed, TransientFilm
    kin = (0.25 * C, -0.62 * C, 2e-3, -1e-3, 2 * math.pi * 70)
    ref = _mc_bearing()                       # what the retry must compute
    ref.film.restart_history()
    ref.film.advance(1e-4, ref._kinematics(*kin))
    b = _mc_bearing()
    orig = TransientFilm.advance

    def fails_with_history(self, dt, k):      # the history-based estimate "fails"
        if self.n_hist > 0:
            raise StepFailed("film step size fell below h_min (simulated)")
        return orig(self, dt, k)

    monkeypatch.setattr(TransientFilm, "advance", fails_with_history)
    b.step(1e-4, *kin)
    assert b.film.stats["restarts"] == 1
    assert np.array_equal(b.film.u, ref.film.u)

    def always_fails(self, dt, k):
        raise StepFailed("film step size fell below h_min (simulated)")

    monkeypatch.setattr(TransientFilm, "advance", always_fails)
    u0, t0 = b.film.u.copy(), b.t
    with pytest.raises(StepFailed, match="also after restarting the BDF history"):
        b.step(1e-4, *kin)
    assert np.array_equal(b.film.u, u0) and b.t == t0


# -- the film's expected gap with contact (bearing_fmu/contact.average_gap) ---------------

def test_average_gap_is_the_expected_gap_of_gaussian_roughness():
    from bearing_fmu.contact import average_gap
    s = KW["sigma"] / C
    H = np.array([-2.0, -0.5, 0.0, 0.4, 1.0, 3.0, 7.9, 8.0, 20.0]) * s
    Hdot = np.linspace(-1.0, 1.0, H.size)
    HT, HeT, HdT = average_gap(H, H + 0.1 * s, Hdot, s)
    for h, ht in zip(H / s, HT / s):
        # E[max(h + delta, 0)], delta ~ N(0, 1): by quadrature of its definition
        want = quad(lambda d: (h + d) * math.exp(-0.5 * d * d) / math.sqrt(2 * math.pi), -h, np.inf,
                    epsabs=0.0, epsrel=1e-12)[0]
        assert ht == pytest.approx(want, rel=1e-9, abs=1e-15)
    assert np.all(HT > 0) and np.all(HT >= H)
    assert np.array_equal(HT[-2:], H[-2:])          # h >= 8 sigma: unchanged
    # dH_T/dt = dH_T/dH * dH/dt, checked by a difference quotient
    d = 1e-7 * s
    dH = (average_gap(H + d, H, Hdot, s)[0] - average_gap(H - d, H, Hdot, s)[0]) / (2 * d)
    assert np.allclose(HdT, dH * Hdot, rtol=1e-6, atol=1e-12)


def test_average_gap_away_from_the_shell_returns_the_gap_as_the_full_map_does():
    """Every entry at or above 8 sigma (the journal away from its shell) takes the short path of
    average_gap (copies only); its decision is the full map's to the last bit: at the 8 sigma
    line, an entry moved by -3 ... 3 ulps, in H or in He, gives the full map's arrays exactly."""
    from bearing_fmu.contact import H_AVG, _average_gap_map, average_gap
    s = KW["sigma"] / C
    line = H_AVG * s
    H = np.linspace(line, 30 * s, 50)
    He = H + 0.5 * s
    Hdot = np.linspace(-1.0, 1.0, H.size)
    for k in range(-3, 4):
        Hk = H.copy()
        Hk[0] = line + k * np.spacing(line)
        for args in ((Hk, He, Hdot), (He, Hk, Hdot), (Hk - s, He, Hdot)):
            got, want = average_gap(*args, s), _average_gap_map(*args, s)
            for g, w, inp in zip(got, want, args):
                assert g is not inp and np.array_equal(g, w)


@pytest.mark.parametrize("cav", [0, 1])
def test_film_with_contact_runs_into_the_asperity_layer(cav):
    """eps slightly above 1 (nominal gap -0.3 sigma): the film uses the expected gap and
    runs; the contact pushes back; deeper than contact_h_limit (-1 sigma) is refused with a
    clear message."""
    from bearing_fmu.solver import StepFailed
    w = 2 * math.pi * 70
    e = C + 0.3 * KW["sigma"]
    b = BearingModel(small(contact=1, cavitation=cav, groove_width=0.26, axial_bc=1))
    b.initialize(0.0, -e, 0.0, 0.0, w)
    for _ in range(3):
        b.step(1e-5, 0.0, -e, 0.0, 1e-4, w)
    o = b.outputs
    assert o["eps"] > 1.0 and o["h_min"] > 0.0 and o["F_contact"] > 100.0
    assert o["Fy"] > o["F_contact"] * 0.99          # film + contact push the journal up
    assert np.all(np.isfinite([o["Fx"], o["Fy"], o["p_max"]]))
    with pytest.raises(StepFailed, match="asperity layer.*discard_retries.*contact_KE"):
        b.step(1e-5, 0.0, -(C + 1.01 * KW["sigma"]), 0.0, 0.0, w)
    b2 = BearingModel(small(contact=1, contact_h_limit=-3.0, cavitation=cav, groove_width=0.26, axial_bc=1))
    b2.initialize(0.0, -(C + 2.0 * KW["sigma"]), 0.0, 0.0, w)
    assert b2.outputs["F_contact"] > b.outputs["F_contact"]
    b0 = BearingModel(small(contact=0, cavitation=cav, groove_width=0.26, axial_bc=1))
    with pytest.raises(StepFailed, match="contact = 1"):
        b0.initialize(0.0, -e, 0.0, 0.0, w)


def test_outside_the_clearance_messages_tell_contact_from_blow_up():
    from bearing_fmu.solver import StepFailed
    b = BearingModel(small(cavitation=0))
    b.initialize(0.0, -0.5 * C, 0.0, 0.0, 500.0)
    with pytest.raises(StepFailed, match="touches the shell.*contact = 1"):
        b.step(1e-5, 0.0, -1.01 * C, 0.0, 0.0, 500.0)
    with pytest.raises(StepFailed, match="far outside the clearance.*unstable"):
        b.step(1e-5, 0.0, -9.8 * C, 0.0, 0.0, 500.0)


@pytest.mark.parametrize("contact", [0, 1])
def test_a_start_outside_the_clearance_is_named_as_the_start_not_a_blow_up(contact):
    """A journal start position outside the clearance (journal_x0 in mm, or beyond c) used to
    be reported as 'the coupled simulation went unstable before this step: reduce the macro
    step' although no step had been taken; it must name the start position and its parameters."""
    from bearing_fmu.solver import StepFailed
    b = BearingModel(small(cavitation=0, contact=contact))
    with pytest.raises(StepFailed) as info:
        b.initialize(1.6 * C, 0.0, 0.0, 0.0, 500.0)
    msg = str(info.value)
    assert "starts outside the clearance" in msg and "eps = 1.6" in msg
    assert "journal_x0" in msg and "metres" in msg
    assert f"c = psi R = {PSI:g} x {R:g} m" in msg
    assert "unstable" not in msg and "macro step" not in msg
    assert ("contact = 1" in msg) == (contact == 0)
    b.initialize(0.0, -0.5 * C, 0.0, 0.0, 500.0)          # inside: fine, and after a step ...
    during_run = "far outside the clearance.*unstable" if contact == 0 else "asperity layer"
    with pytest.raises(StepFailed, match=during_run):
        b.step(1e-5, 1.6 * C, 0.0, 0.0, 0.0, 500.0)       # ... the same position is a run's failure


def test_a_step_computes_the_normal_force_once_per_eccentricity(monkeypatch):
    """The FMU's outputs and the interface coefficients ask for the normal force (0.16 ms each: the
    parabolic cylinder function at 48 points) nine times per macro step at five eccentricities:
    each is computed once, and the remembered value is the computed one bit for bit."""
    import bearing_fmu.contact as contact
    contact._normal_force_of.cache_clear()
    calls = []
    real = contact.normal_force
    monkeypatch.setattr(contact, "normal_force", lambda e, **kw: calls.append(e) or real(e, **kw))
    x, y = 0.99 * C * math.cos(0.7), 0.99 * C * math.sin(0.7)
    F = contact_force(x, y, 0.01, -0.02, 500.0, **KW)
    K, Cc = contact_coefficients(x, y, 0.01, -0.02, 500.0, **KW)
    assert len(calls) == len(set(calls)) == 5, calls
    monkeypatch.setattr(contact, "normal_force", real)
    contact._normal_force_of.cache_clear()
    assert F == contact_force(x, y, 0.01, -0.02, 500.0, **KW)
    K2, C2 = contact_coefficients(x, y, 0.01, -0.02, 500.0, **KW)
    assert np.array_equal(K, K2) and np.array_equal(Cc, C2)
