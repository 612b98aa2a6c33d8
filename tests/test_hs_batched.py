"""The batched half-Sommerfeld path of the interface-Jacobian coefficients
(bearing_fmu/hs.py solve_many, bearing_fmu/linearize.py hs_forces_many) against the
scalar reference it replaced: equal to round-off (a performance change, not a model one)."""

from __future__ import annotations

import math

import numpy as np
import pytest

from bearing_fmu.linearize import (hs_force, hs_forces_many, hs_linearization,
                                   hs_linearization_scalar, linearization)
from bearing_fmu.model import BearingParams, BearingModel

R, PSI = 4.9e-3, 2.8e-3
C = R * PSI

CASES = {
    "jeffcott-bath": dict(n_phi=40, n_z=40, cavitation=1, axial_bc=0, groove_width=0.0, cav_width=9e4),
    "groove-air": dict(n_phi=48, n_z=30, cavitation=0, axial_bc=1, groove_width=0.26,
                       groove_angle=0.3, p_feed=2e5),
    "odd-hs": dict(n_phi=36, n_z=15, cavitation=0, axial_bc=0, groove_width=0.0),
}
KINS = [(0.36 * C, -0.15 * C, 0.0, 0.0, 2 * math.pi * 100),
        (0.2 * C, -0.5 * C, 0.3, -0.1, 2 * math.pi * 300),
        (-0.6 * C, 0.3 * C, -2e-2, 1e-2, 2 * math.pi * 500),
        (0.7 * C, 0.5 * C, 0.0, 0.0, 2 * math.pi * 50)]


def bearing(**kw):
    base = dict(R=R, B=1.6 * R, psi=PSI, eta0=0.012, p0=1e5, p_feed=1e5)
    base.update(kw)
    return BearingModel(BearingParams(**base))


@pytest.mark.parametrize("case", sorted(CASES))
def test_solve_many_equals_solve(case):
    b = bearing(**CASES[case])
    g = b.grid_full
    gaps = [g.gap(*k[:4], b.c) for k in KINS]
    w = KINS[1][4]
    P = b.hs.solve_many(*(np.array([gp[i] for gp in gaps]) for i in range(3)), w)
    for k, (H, He, Hdot) in enumerate(gaps):
        ref = b.hs.solve(H, He, Hdot, w)
        np.testing.assert_allclose(P[k], ref, rtol=0, atol=1e-13 * np.abs(ref).max())


@pytest.mark.parametrize("case", sorted(CASES))
def test_batched_forces_and_coefficients_equal_scalar(case):
    b = bearing(**CASES[case])
    for k in KINS:
        Z = np.array([k[:4], [k[0] * 0.9, k[1] * 1.1, 0.01, -0.02]])
        F = hs_forces_many(b, Z, k[4])
        for z, f in zip(Z, F):
            ref = hs_force(b, *z, k[4])
            np.testing.assert_allclose(f, ref, rtol=0, atol=1e-12 * np.abs(ref).max())
        K, Cm = hs_linearization(b, *k)
        Ks, Cs = hs_linearization_scalar(b, *k)
        # central differences over 2e-5 of the clearance amplify round-off by ~1e5
        np.testing.assert_allclose(K, Ks, rtol=0, atol=1e-8 * np.abs(Ks).max())
        np.testing.assert_allclose(Cm, Cs, rtol=0, atol=1e-8 * np.abs(Cs).max())


def test_fmu_default_coefficients_use_the_batched_path_unchanged():
    """linearization(b) (what the FMU outputs) after film steps equals the scalar path."""
    b = bearing(**CASES["jeffcott-bath"])
    w = 2 * math.pi * 200
    b.initialize(0.3 * C, -0.2 * C, 0.0, 0.0, w, init="stationary")
    for n in range(3):
        b.step(1e-4, 0.3 * C, (-0.2 + 0.01 * n) * C, 0.0, 0.1 * C * w, w)
        K, Cm = linearization(b)
        Ks, Cs = hs_linearization_scalar(b, *b._inputs)
        np.testing.assert_allclose(K, Ks, rtol=0, atol=1e-8 * np.abs(Ks).max())
        np.testing.assert_allclose(Cm, Cs, rtol=0, atol=1e-8 * np.abs(Cs).max())


@pytest.mark.parametrize("case", sorted(CASES))
def test_solve_tangent_is_the_derivative_of_solve(case):
    """HalfSommerfeld.solve_tangent: the base field equals solve, each directional field the
    central difference of solve along that gap direction (x, y, vx, vy), to the difference's
    truncation/round-off level."""
    from bearing_fmu.linearize import _tangent_directions
    b = bearing(**CASES[case])
    g = b.grid_full
    cs, sn, ce, se, dH, dHe, dHdot = _tangent_directions(b)
    for x, y, vx, vy, w in KINS:
        H, He, Hdot = g.gap(x, y, vx, vy, C)
        P0, dP = b.hs.solve_tangent(H, He, Hdot, w, dH, dHe, dHdot)
        ref = b.hs.solve(H, He, Hdot, w)
        np.testing.assert_allclose(P0, ref, rtol=0, atol=1e-12 * np.abs(ref).max())
        z0 = np.array([x, y, vx, vy])
        for j, s in enumerate((1e-6 * C, 1e-6 * C, 1e-6 * C * w, 1e-6 * C * w)):
            zp, zm = z0.copy(), z0.copy()
            zp[j] += s
            zm[j] -= s
            fd = (b.hs.solve(*g.gap(*zp, C), w) - b.hs.solve(*g.gap(*zm, C), w)) / (2 * s)
            np.testing.assert_allclose(dP[j], fd, rtol=0, atol=1e-6 * np.abs(fd).max())


def test_coefficients_of_the_tangent_solve_equal_the_finite_differences():
    """hs_linearization (one tangent solve) against hs_linearization_fd (8 perturbed solves)."""
    from bearing_fmu.linearize import hs_linearization_fd
    for case in sorted(CASES):
        b = bearing(**CASES[case])
        for k in KINS:
            (K, Cm), (Kf, Cf) = hs_linearization(b, *k), hs_linearization_fd(b, *k)
            np.testing.assert_allclose(K, Kf, rtol=0, atol=1e-8 * np.abs(Kf).max())
            np.testing.assert_allclose(Cm, Cf, rtol=0, atol=1e-8 * np.abs(Cf).max())


@pytest.mark.parametrize("case", sorted(CASES))
def test_the_dst_matrix_of_the_coefficient_kernel_is_scipys_inverse_dst(case):
    """hs_linearization transforms its fields with HalfSommerfeld.idst_matrix inside numba:
    the product must be scipy's inverse DST-II (ortho) to round-off, on odd and even n_z."""
    import scipy.fft as sfft
    b = bearing(**CASES[case])
    n_z, n_phi = b.hs.grid.n_z, b.hs.grid.n_phi
    X = np.random.default_rng(1).standard_normal((n_z, n_phi))
    ref = sfft.idst(X, type=2, norm="ortho", axis=0)
    np.testing.assert_allclose(b.hs.idst_matrix @ X, ref, rtol=0, atol=1e-13 * np.abs(ref).max())


@pytest.mark.parametrize("case", sorted(CASES))
def test_coefficients_from_the_lower_rows_equal_those_of_every_row(case):
    """The coefficient kernel transforms only the modes that carry the film and, for even n_z,
    only the lower half of the rows, each standing for its mirror image
    (HalfSommerfeld.coefficient_rows): the same coefficients as every mode and row, to
    round-off; odd n_z keeps every row."""
    from bearing_fmu.linearize import _hs_coefficients, _steps, _tangent_directions
    b = bearing(**CASES[case])
    g, hs = b.grid_full, b.hs
    Mh, modes, wrow = hs.coefficient_rows
    if g.n_z % 2 == 0:
        assert Mh.shape == (g.n_z // 2, g.n_z // 2) and np.all(wrow == 2.0)
    else:
        assert Mh.shape[0] == g.n_z and np.all(wrow == 1.0)
    every = (np.ascontiguousarray(hs.idst_matrix), np.arange(g.n_z), np.ones(g.n_z))
    cs, sn, ce, se, dH, dHe, dHdot = _tangent_directions(b)
    for k in KINS:
        D = {}
        for name, rows in (("reduced", hs.coefficient_rows), ("every", every)):
            D[name] = np.empty((2, 4))
            _hs_coefficients(*k, b.c, cs, sn, ce, se, dH, dHe, dHdot, g.dz, g.dphi, hs.a_phi,
                             g.dphi * hs.a_z / g.dz, hs.lam, hs.ck, hs.gr, hs.feed_hat, *rows,
                             _steps(b, np.array(k[:4]), k[4], 1e-5, 1e-3), g.phi,
                             b.params.R * g.dphi * b.params.B * g.dz, D[name], np.empty(2))
        # round-off of the force sums (~1e-16 of 2 n_z n_phi terms, summed in another order)
        # over the central difference's 2 s (s = 1e-5 of c): ~1e-10 of the coefficients, a
        # tenth of what the tangent solve itself is held to against the finite differences
        for cols in (slice(0, 2), slice(2, 4)):     # stiffness and damping, each to its scale
            ref = D["every"][:, cols]
            np.testing.assert_allclose(D["reduced"][:, cols], ref, rtol=0,
                                       atol=1e-9 * np.abs(ref).max())


def test_with_contact_the_tangent_solve_equals_the_perturbed_solves_on_and_off_the_shell(monkeypatch):
    """contact = 1: the film sees the expected gap of the roughness, the nominal gap above 8
    roughness heights and a smooth map of it below (contact.average_gap). The tangent solve
    carries the directions through that map by the chain rule (linearize._rough_tangent), so
    away from the shell and on it (the contact phase of a run from rest, down to a nominal gap
    1.5 sigma into the asperities) the coefficients equal the 8 perturbed solves with contact,
    which are not called. The finite differences' own error is O(step^2) in the map's
    curvature: 4e-7 of the stiffness at -1.5 sigma with the default step, 4e-9 with a tenth
    of it, so the bound shrinks with the step (measured: the difference falls 100x per 10x)."""
    import bearing_fmu.linearize as lin
    b = bearing(n_phi=40, n_z=40, cavitation=1, axial_bc=1, groove_width=math.radians(15),
                groove_angle=math.pi / 2, contact=1)
    s = b.params.sigma_rough / C                   # 8 s = 0.175: eps up to 0.825 is away
    calls = []
    fd = lin.hs_linearization_fd
    w = 2 * math.pi * 400
    cases = [(0.5 * C, -0.3 * C, 0.02, -0.01, w)]                      # eps 0.58, away
    for h_sigma in (7.9, 2.0, 0.7, -1.5):                              # nominal gap / sigma
        e = (1.0 - h_sigma * s) * C
        cases += [(e * math.cos(a), e * math.sin(a), vx, vy, w)
                  for a, vx, vy in ((0.0, 0.0, 0.0), (1.0, 0.02, -0.01), (-1.6, -0.3 * C * w, 0.1))]
    monkeypatch.setattr(lin, "hs_linearization_fd", lambda *a, **k: calls.append(a[1:3]) or fd(*a, **k))
    tangent = [hs_linearization(b, *k) for k in cases]
    fine = [hs_linearization(b, *k, rel_step=1e-6) for k in cases[-3:]]
    assert calls == []
    for i, (k, (K, Cm)) in enumerate(zip(cases, tangent)):
        Kf, Cf = fd(b, *k)
        # away from the shell no map: the tangent solve's own accuracy, as without contact
        np.testing.assert_allclose(K, Kf, rtol=0, atol=(1e-8 if i == 0 else 2e-6) * np.abs(Kf).max())
        np.testing.assert_allclose(Cm, Cf, rtol=0, atol=1e-8 * np.abs(Cf).max())
    for k, (K, Cm) in zip(cases[-3:], fine):
        Kf, Cf = fd(b, *k, rel_step=1e-6)
        np.testing.assert_allclose(K, Kf, rtol=0, atol=3e-8 * np.abs(Kf).max())
    # and the force of the tangent solve's base field is the film's force with contact
    F, K, Cm = hs_linearization(b, *cases[-1], with_force=True)
    np.testing.assert_allclose(F, hs_force(b, *cases[-1]), rtol=1e-12)


def _tangent_kernel_per_mode(ce, H3, rhs, dce, dH3, drhs, lam, ck, coef, groove, feed_hat, x):
    """hs._tangent_kernel as it was before its modes ran side by side (one mode after the
    other), in plain Python: the reference of the test below."""
    n, m, n_z = ce.size, dce.shape[0], lam.size
    a, b, c, cp, inv, zz = (np.empty(n) for _ in range(6))
    y = np.empty((n, m + 1))
    db = np.array([[dce[r, i] + dce[r, i - 1 if i > 0 else n - 1] for i in range(n)] for r in range(m)])
    for k in range(n_z):
        if ck[k] == 0.0 and feed_hat[k] == 0.0:
            x[:, k, :] = 0.0
            continue
        for i in range(n):
            iw = i - 1 if i > 0 else n - 1
            if groove[i]:
                a[i], c[i], b[i] = 0.0, 0.0, 1.0
            else:
                a[i], c[i] = -ce[iw], -ce[i]
                b[i] = (ce[i] + ce[iw]) + coef * (lam[k] * H3[i])
        alpha, beta, gamma = c[n - 1], a[0], -b[0]
        inv[0] = 1.0 / (b[0] - gamma)
        cp[0] = c[0] * inv[0]
        zz[0] = gamma * inv[0]
        for i in range(1, n):
            den = (b[i] - alpha * beta / gamma if i == n - 1 else b[i]) - a[i] * cp[i - 1]
            inv[i] = 1.0 / den
            cp[i] = c[i] * inv[i]
            zz[i] = ((alpha if i == n - 1 else 0.0) - a[i] * zz[i - 1]) * inv[i]
        for i in range(n - 2, -1, -1):
            zz[i] -= cp[i] * zz[i + 1]
        zden = 1.0 + zz[0] + beta * zz[n - 1] / gamma
        for i in range(n):
            d0 = feed_hat[k] if groove[i] else ck[k] * rhs[i]
            y[i, 0] = (d0 - a[i] * y[i - 1, 0]) * inv[i] if i > 0 else d0 * inv[0]
        for i in range(n - 2, -1, -1):
            y[i, 0] -= cp[i] * y[i + 1, 0]
        fact = (y[0, 0] + beta * y[n - 1, 0] / gamma) / zden
        for i in range(n):
            x[0, k, i] = y[i, 0] - fact * zz[i]
        lk = coef * lam[k]
        for i in range(n):
            iw, ie = (i - 1 if i > 0 else n - 1), (i + 1 if i + 1 < n else 0)
            xw, xc, xe = x[0, k, iw], x[0, k, i], x[0, k, ie]
            for r in range(m):
                d = 0.0 if groove[i] else (ck[k] * drhs[r, i] + dce[r, iw] * xw
                                           - (db[r, i] + lk * dH3[r, i]) * xc + dce[r, i] * xe)
                y[i, 1 + r] = (d - a[i] * y[i - 1, 1 + r]) * inv[i] if i > 0 else d * inv[0]
        for i in range(n - 2, -1, -1):
            for r in range(m):
                y[i, 1 + r] -= cp[i] * y[i + 1, 1 + r]
        for r in range(m):
            fact = (y[0, 1 + r] + beta * y[n - 1, 1 + r] / gamma) / zden
            for i in range(n):
                x[1 + r, k, i] = y[i, 1 + r] - fact * zz[i]


@pytest.mark.parametrize("case", sorted(CASES))
def test_tangent_kernel_modes_side_by_side_bit_for_bit(case):
    """hs._tangent_kernel solves the modes side by side (issue 16 speed): the base modes and
    their derivatives are those of solving one mode after the other, bit for bit."""
    from bearing_fmu.hs import _tangent_kernel
    b = bearing(**CASES[case])
    g, hs = b.grid_full, b.hs
    rng = np.random.default_rng(7)
    n, m = g.n_phi, 4
    for k in KINS:
        H, He, Hdot = g.gap(*k[:4], b.c)
        ce = g.dz * hs.a_phi * He ** 3 / g.dphi
        rhs = -(g.dz * k[4] * (He - np.roll(He, 1)) + 2.0 * g.dphi * g.dz * Hdot)
        dce, dH3, drhs = (rng.standard_normal((m, n)) for _ in range(3))
        args = (ce, H ** 3, rhs, dce, dH3, drhs, hs.lam, hs.ck, g.dphi * hs.a_z / g.dz, hs.gr,
                hs.feed_hat)
        x, ref = np.full((m + 1, g.n_z, n), 7.0), np.full((m + 1, g.n_z, n), 7.0)
        _tangent_kernel(*args, x)
        _tangent_kernel_per_mode(*args, ref)
        assert np.array_equal(x, ref)


@pytest.mark.parametrize("case", sorted(CASES))
def test_the_force_from_the_tangent_solve_is_hs_force(case):
    """hs_linearization(with_force=True) returns the force of the tangent solve's base field: the
    same model as hs_force (another DST path, half the rows weighted 2 when the field is symmetric),
    so equal to round-off, and the same (K, C) as without it."""
    from bearing_fmu.linearize import hs_force, hs_linearization
    b = bearing(**CASES[case])
    for k in KINS:
        F, K, C = hs_linearization(b, *k, with_force=True)
        F_ref = hs_force(b, *k)
        assert np.all(np.abs(F - F_ref) <= 1e-11 * np.max(np.abs(F_ref))), (k, F, F_ref)
        K2, C2 = hs_linearization(b, *k)
        assert np.array_equal(K, K2) and np.array_equal(C, C2)
