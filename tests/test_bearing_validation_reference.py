"""Self-checks of the independent references in ``bearing_fmu/reference.py``.

These tests do not touch the solver. They check each reference against a second,
independent way of computing the same thing (closed form vs quadrature, closed form
vs a finite-difference solution written here), so that a later disagreement between
the solver and a reference points at the solver or the setup.
"""

from __future__ import annotations

import math

import numpy as np
import pytest
import scipy.sparse as sp
import scipy.sparse.linalg as spla

from bearing_fmu import reference as ref

R, C, ETA = 0.02, 0.02 * 2.8e-3, 0.012
OMEGA = 2 * math.pi * 100.0

# (x/c, y/c, vx/(c omega), vy/(c omega)): rotation only, squeeze, whirl, mixed, near 0
KINEMATICS = [
    (-0.7, 0.0, 0.0, 0.0),
    (0.0, -0.5, 0.02, 0.05),
    (0.3, 0.4, -0.1, 0.06),
    (0.6, -0.2, 0.0, -0.9),
    (0.64, 0.5, 0.3, -0.2),
    (-0.2, 0.1, -0.4, 0.0),
    (0.0, 0.0, 0.1, -0.05),
]


def _kin(k):
    xc, yc, vxc, vyc = k
    return xc * C, yc * C, vxc * C * OMEGA, vyc * C * OMEGA


@pytest.mark.parametrize("k", KINEMATICS)
def test_short_bearing_closed_form_matches_quadrature(k):
    """Ocvirk HS force with squeeze: Booker-integral closed form vs adaptive
    quadrature of the closed-form pressure in the x-y frame (two independent
    derivations; Booker 1965, Childs 1993 sec. 3.4)."""
    B = 0.1 * 2 * R
    fa = np.array(ref.short_bearing_force(*_kin(k), OMEGA, R=R, B=B, c=C, eta=ETA))
    fb = np.array(ref.short_bearing_force_quad(*_kin(k), OMEGA, R=R, B=B, c=C, eta=ETA))
    assert np.linalg.norm(fa - fb) <= 1e-9 * np.linalg.norm(fb)


@pytest.mark.parametrize("eps", [0.1, 0.5, 0.7, 0.9])
def test_short_bearing_pure_rotation_classical(eps):
    """Pure rotation: F_r = -eta w R B^3 eps^2/(c^2 (1-eps^2)^2),
    F_t = pi eta w R B^3 eps/(4 c^2 (1-eps^2)^1.5) (Childs 1993, eq. 3.44; Szeri 2011)."""
    B = 0.05 * 2 * R
    gamma = -0.5 * math.pi  # journal displaced downwards
    x, y = eps * C * math.cos(gamma), eps * C * math.sin(gamma)
    fx, fy = ref.short_bearing_force(x, y, 0.0, 0.0, OMEGA, R=R, B=B, c=C, eta=ETA)
    f_r = fx * math.cos(gamma) + fy * math.sin(gamma)
    f_t = -fx * math.sin(gamma) + fy * math.cos(gamma)
    k = ETA * OMEGA * R * B**3 / C**2
    assert f_r == pytest.approx(-k * eps**2 / (1 - eps**2) ** 2, rel=1e-12)
    assert f_t == pytest.approx(k * math.pi * eps / (4 * (1 - eps**2) ** 1.5), rel=1e-12)
    # attitude angle: tan(phi) = pi sqrt(1-eps^2)/(4 eps) (short bearing)
    att = ref.attitude_angle(fx, fy, x, y)
    assert att == pytest.approx(math.atan2(math.pi * math.sqrt(1 - eps**2), 4 * eps), rel=1e-12)


def test_short_bearing_pressure_integrates_to_force():
    """The clipped Ocvirk pressure field, integrated on a fine grid (trapezoid in z
    is exact for the parabola up to rounding; midpoint in phi), gives the force."""
    B = 0.1 * 2 * R
    x, y, vx, vy = _kin((0.3, 0.4, -0.1, 0.06))
    n = 20000
    phi = (np.arange(n) + 0.5) * 2 * np.pi / n
    z = np.linspace(-B / 2, B / 2, 41)
    p = ref.short_bearing_pressure(phi[None, :], z[:, None], x, y, vx, vy, OMEGA,
                                   R=R, B=B, c=C, eta=ETA)
    pz = np.trapezoid(p, z, axis=0)
    fx = -R * np.sum(pz * np.cos(phi)) * 2 * np.pi / n
    fy = -R * np.sum(pz * np.sin(phi)) * 2 * np.pi / n
    fa = ref.short_bearing_force(x, y, vx, vy, OMEGA, R=R, B=B, c=C, eta=ETA)
    # trapezoid on a 40-interval parabola: error (B/40)^2-relative ~ 1e-3 at most
    assert math.hypot(fx - fa[0], fy - fa[1]) <= 2e-3 * math.hypot(*fa)


@pytest.mark.parametrize("eps", [0.2, 0.6, 0.9])
def test_long_bearing_quadrature_matches_closed_form(eps):
    """Guembel long bearing, pure rotation: quadrature of the clipped Sommerfeld
    pressure vs F_r = -12 eta w R^3 B eps^2/(c^2 (2+eps^2)(1-eps^2)),
    F_t = 6 pi eta w R^3 B eps/(c^2 (2+eps^2) sqrt(1-eps^2)) (Szeri 2011; Hamrock 2004)."""
    B = 1.0
    fx, fy = ref.long_bearing_force(0.0, -eps * C, 0.0, 0.0, OMEGA, R=R, B=B, c=C, eta=ETA)
    f_r, f_t = ref.long_bearing_force_rotation(eps, OMEGA, R=R, B=B, c=C, eta=ETA)
    # gamma = -pi/2: e_r = (0, -1), e_t = (1, 0)
    assert -fy == pytest.approx(f_r, rel=1e-9)
    assert fx == pytest.approx(f_t, rel=1e-9)


def _fd_periodic_1d(n, eps, eps_dot, gamma_dot, omega):
    """Conservative 2nd-order FD of (1/R^2)(h^3 p')'/(12 eta) = (w/2) h' + h_t on a
    periodic theta grid; the free constant is fixed by sum(h^3 p) = 0."""
    th = np.arange(n) * 2 * np.pi / n
    d = 2 * np.pi / n
    hf = C * (1 + eps * np.cos(th + 0.5 * d))  # faces i+1/2
    rhs = C * (-(0.5 * omega - gamma_dot) * eps * np.sin(th) + eps_dot * np.cos(th))
    rhs = 12 * ETA * R**2 * rhs * d**2
    a = sp.lil_matrix((n + 1, n + 1))
    for i in range(n):
        w, e = hf[i - 1] ** 3, hf[i] ** 3
        a[i, (i - 1) % n] += w
        a[i, (i + 1) % n] += e
        a[i, i] -= w + e
        a[i, n] = 1.0  # Lagrange multiplier column (singular operator)
    h3 = (C * (1 + eps * np.cos(th))) ** 3
    a[n, :n] = h3 / h3.max()
    b = np.append(rhs, 0.0)
    sol = spla.spsolve(a.tocsr(), b)
    return th, sol[:n]


@pytest.mark.parametrize("eps,eps_dot,gamma_dot", [(0.6, 0.0, 0.0), (0.5, 30.0, 0.0),
                                                   (0.7, -20.0, 150.0)])
def test_long_bearing_pressure_matches_1d_fd(eps, eps_dot, gamma_dot):
    """Closed-form Sommerfeld pressure (with squeeze and whirl, h^3-mean constant)
    vs a direct periodic 1-D finite-difference solution; the FD error must fall at
    second order (ratio ~4 per grid halving), and be small on the fine grid."""
    errs = []
    for n in (256, 512):
        th, p = _fd_periodic_1d(n, eps, eps_dot, gamma_dot, OMEGA)
        pe = ref.long_bearing_pressure(th, eps, eps_dot, gamma_dot, OMEGA, R=R, c=C, eta=ETA)
        errs.append(np.max(np.abs(p - pe)) / np.max(np.abs(pe)))
    assert errs[1] < 2e-4
    assert 3.0 < errs[0] / errs[1] < 5.0


def _fd_full_sommerfeld_2d(eps, eps_dot, B, n_phi=96, n_z=None):
    """Linear 2-D FD (full Sommerfeld, no cavitation) with p = 0 at z = 0 and z = B,
    periodic in phi; theta measured from h_max. Returns theta, z, p (n_z, n_phi)."""
    d = 2 * np.pi / n_phi
    if n_z is None:
        n_z = int(round(B / (R * d))) + 1  # square cells
    th = np.arange(n_phi) * d
    z = np.linspace(0.0, B, n_z)
    dz = z[1] - z[0]
    hn = C * (1 + eps * np.cos(th))
    hf = C * (1 + eps * np.cos(th + 0.5 * d))
    rhs1 = 12 * ETA * C * (-0.5 * OMEGA * eps * np.sin(th) + eps_dot * np.cos(th))
    ni = n_z - 2
    idx = np.arange(ni * n_phi).reshape(ni, n_phi)
    rows, cols, vals = [], [], []
    for j in range(ni):
        for i in range(n_phi):
            k = idx[j, i]
            w, e = hf[i - 1] ** 3 / (R * d) ** 2, hf[i] ** 3 / (R * d) ** 2
            s = hn[i] ** 3 / dz**2
            rows += [k, k, k]
            cols += [idx[j, (i - 1) % n_phi], idx[j, (i + 1) % n_phi], k]
            vals += [w, e, -(w + e + 2 * s)]
            for j2 in (j - 1, j + 1):
                if 0 <= j2 < ni:
                    rows.append(k)
                    cols.append(idx[j2, i])
                    vals.append(s)
    a = sp.csr_matrix((vals, (rows, cols)), shape=(ni * n_phi, ni * n_phi))
    b = np.tile(rhs1, ni)
    p = np.zeros((n_z, n_phi))
    p[1:-1] = spla.spsolve(a.tocsc(), b).reshape(ni, n_phi)
    return th, z, p


def test_long_bearing_limit_constant_is_h3_mean():
    """The squeeze constant of :func:`long_bearing_pressure`: as B/D grows, the
    mid-plane pressure of the finite bearing with p = p0 at both ends tends to the
    'h3_mean' constant, not the 'max_film' one. The end boundary layers decay
    exponentially (measured: 16 %, 1.6 %, 0.15 % at B/D = 2, 4, 8 on 64 cells),
    while the 'max_film' constant stays 4 % off."""
    eps, eps_dot = 0.5, 40.0
    errs = []
    for b_over_d in (4.0, 8.0):
        B = b_over_d * 2 * R
        th, z, p = _fd_full_sommerfeld_2d(eps, eps_dot, B, n_phi=64)
        mid = p[len(z) // 2]
        pe = ref.long_bearing_pressure(th, eps, eps_dot, 0.0, OMEGA, R=R, c=C, eta=ETA)
        pm = ref.long_bearing_pressure(th, eps, eps_dot, 0.0, OMEGA, R=R, c=C, eta=ETA,
                                       squeeze_constant="max_film")
        scale = np.max(np.abs(pe))
        errs.append((np.max(np.abs(mid - pe)) / scale, np.max(np.abs(mid - pm)) / scale))
    assert errs[1][0] < 0.005
    assert errs[1][0] < 0.2 * errs[0][0]
    assert errs[1][1] > 10 * errs[1][0]


def test_short_bearing_coefficients_damping_symmetric():
    """Short HS bearing: the damping matrix is symmetric (Lund 1987; Childs 1993,
    sec. 3.6), and the linearization error of the force falls at 2nd order in the
    perturbation (ratio ~4 when the perturbation is halved)."""
    B = 0.2 * 2 * R
    x, y = 0.2 * C, -0.55 * C
    K, Cm = ref.short_bearing_coefficients(x, y, OMEGA, R=R, B=B, c=C, eta=ETA)
    assert Cm[0, 1] == pytest.approx(Cm[1, 0], rel=1e-6)
    f0 = np.array(ref.short_bearing_force(x, y, 0, 0, OMEGA, R=R, B=B, c=C, eta=ETA))
    res = []
    for s in (1.0, 0.5):
        d = s * np.array([1e-2 * C, -2e-2 * C])
        v = s * np.array([1e-2 * C * OMEGA, 5e-3 * C * OMEGA])
        f1 = np.array(ref.short_bearing_force(x + d[0], y + d[1], v[0], v[1], OMEGA,
                                              R=R, B=B, c=C, eta=ETA))
        res.append(np.linalg.norm(f1 - (f0 - K @ d - Cm @ v)))
    assert 3.5 < res[0] / res[1] < 4.5


def test_finite_table_consistent_with_raimondi_boyd_and_ocvirk():
    """The Khonsari & Booser (2008, Table 8.6) rows against (a) Raimondi & Boyd's
    L/D = 1 Sommerfeld numbers (within 1.5 %, the spread between the two published
    sources) and (b) the short-bearing limit: at L/D = 1/4 the table's S lies above
    Ocvirk's (the short-bearing theory over-predicts load) and within 4 % of it at
    eps = 0.2."""
    table1 = {e: s for e, s, _ in ref.FINITE_BEARING_TABLE[1.0]}
    for eps, s_rb in ref.RAIMONDI_BOYD_LD1_S.items():
        if eps in table1:
            assert table1[eps] == pytest.approx(s_rb, rel=0.015)
    B = 0.25 * 2 * R
    for eps, s_tab, _ in ref.FINITE_BEARING_TABLE[0.25]:
        fx, fy = ref.short_bearing_force(-eps * C, 0, 0, 0, OMEGA, R=R, B=B, c=C, eta=ETA)
        s_o = ref.sommerfeld_number(math.hypot(fx, fy), R=R, B=B, c=C, eta=ETA, omega=OMEGA)
        assert s_tab > s_o
        if eps == 0.2:
            assert s_tab == pytest.approx(s_o, rel=0.04)
