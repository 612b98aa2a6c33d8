"""Simplified Newton of the film (solver.LU_REUSE_BELOW) and the fused Newton step
(solver.band_newton_step_nopivot), issue 16 speed part.

A short whirl of the Jeffcott free-to-air bearing on a coarse grid (24 x 12, a few dozen
0.1 ms steps, well under a second): the kept LU must actually be used, must not add Newton
iterations, and must leave the film where full Newton and a much tighter Newton put it
(to the Newton tolerance); the fused step must equal ``TransientFilm._solve`` bit for bit.
"""

import math

import numpy as np
import pytest

from bearing_fmu import solver
from bearing_fmu.model import BearingModel, BearingParams

C = 4.9e-3 * 2.8e-3
KW = dict(R=4.9e-3, B=7.84e-3, psi=2.8e-3, eta0=0.012, p0=1e5, p_feed=1e5, n_phi=24, n_z=12,
          cavitation=1, axial_bc=1, groove_width=math.radians(15), groove_angle=math.pi / 2)


def orbit(k, eps=0.55, spin=500.0, ratio=0.45):
    w = 2 * math.pi * spin
    nu, r, t = ratio * w, eps * C, k * 1e-4
    return (r * math.cos(nu * t), r * math.sin(nu * t), -r * nu * math.sin(nu * t),
            r * nu * math.cos(nu * t), w)


def run(reuse, steps=40, jac=0.0, **extra):
    """The whirl on the film with the two simplified-Newton rules at ``reuse`` (increment,
    LU_REUSE_BELOW) and ``jac`` (Jacobian change, JACOBIAN_REUSE_BELOW); 0: rule off."""
    b = BearingModel(BearingParams(**dict(KW, **extra)))
    b.film.lu_reuse_below = reuse
    b.film.jac_reuse_below = jac
    b.initialize(*orbit(0), init="stationary")
    F = []
    for k in range(1, steps + 1):
        b.step(1e-4, *orbit(k))
        F.append((b.outputs["Fx"], b.outputs["Fy"]))
    return b, np.array(F)


def test_default_bound_is_the_documented_one():
    b = BearingModel(BearingParams(**KW))
    assert b.film.lu_reuse_below == solver.LU_REUSE_BELOW == 10.0
    assert b.film.jac_reuse_below == solver.JACOBIAN_REUSE_BELOW == 0.1


def test_kept_lu_saves_factorisations_not_accuracy():
    full, F_full = run(0.0)
    simp, F_simp = run(solver.LU_REUSE_BELOW)
    tight, F_tight = run(0.0, newton_atol=1e-7, newton_rtol=1e-8)
    assert full.stats["reused"] == 0
    assert simp.stats["reused"] > 0
    # every reuse is a factorisation saved; no extra Newton iterations beyond noise
    assert simp.stats["factor"] == simp.stats["newton"] - simp.stats["reused"] + \
        (full.stats["factor"] - full.stats["newton"])
    assert simp.stats["newton"] <= full.stats["newton"] * 1.02 + 1
    assert simp.stats["failed_newton"] == 0
    scale = np.abs(F_tight).max()
    err_full = np.abs(F_full - F_tight).max() / scale
    err_simp = np.abs(F_simp - F_tight).max() / scale
    # to the Newton tolerance (newton_rtol 1e-5 of the pressure range), and not much worse
    # than full Newton
    assert err_simp < 1e-4
    assert err_simp < 3 * err_full + 1e-9


@pytest.mark.parametrize("extra", [{}, {"axial_bc": 0, "groove_width": 0.0, "cav_width": 9e4}])
def test_kept_lu_while_the_jacobian_holds_saves_factorisations_to_the_newton_tolerance(extra):
    """The second rule (JACOBIAN_REUSE_BELOW) keeps the LU after larger Newton steps as long as
    the assembled Newton matrix stays within 10 % of the factored one: fewer LUs than the first
    rule alone, every kept iteration one LU saved against full Newton, few extra iterations,
    and the film still where a Newton run 1000x tighter puts it to the Newton tolerance."""
    full, F_full = run(0.0, **extra)
    simp, F_simp = run(solver.LU_REUSE_BELOW, **extra)
    both, F_both = run(solver.LU_REUSE_BELOW, jac=solver.JACOBIAN_REUSE_BELOW, **extra)
    tight, F_tight = run(0.0, newton_atol=1e-7, newton_rtol=1e-8, **extra)
    assert both.stats["factor"] < simp.stats["factor"] < full.stats["factor"]
    assert both.stats["factor"] == both.stats["newton"] - both.stats["reused"] + \
        (full.stats["factor"] - full.stats["newton"])
    assert both.stats["newton"] <= full.stats["newton"] * 1.1 + 1
    assert both.stats["failed_newton"] == both.stats["rejected"] == 0
    scale = np.abs(F_tight).max()
    err_both = np.abs(F_both - F_tight).max() / scale
    assert err_both < 1e-4          # newton_rtol 1e-5 of the pressure range, accumulated


def test_jacobian_moved_measures_rows_against_their_factored_diagonal():
    jf = np.array([[4.0, -1.0, -1.0], [1.0, 0.0, 0.0], [2.0, 0.5, 0.0]])
    assert solver.jacobian_moved(jf, jf) == 0.0
    j = jf.copy()
    j[0, 1] -= 0.2          # row 0: 0.2 / 4
    j[2, 0] += 0.3          # row 2: 0.3 / 2
    assert solver.jacobian_moved(j, jf) == pytest.approx(0.15)
    jf0 = jf.copy()
    jf0[1, 0] = 0.0
    assert solver.jacobian_moved(jf0, jf0) == 0.0
    assert solver.jacobian_moved(j, jf0) == np.inf      # a changed row over a zero diagonal


def test_fused_newton_step_equals_solve():
    b, _ = run(0.0, steps=5)
    f = b.film
    u = f.u.copy()
    hist = -f.theta(u) / 1e-5
    kin = b._kin
    r = f.residual(u, 1e5, hist, kin, want_jac=True).copy()
    f._factor(u, 1e5, kin, jst_ready=True)
    assert f.lin.piv is None                     # the no-interchange path
    ref = f._solve(r)
    dx, ok = f._newton_step(r)
    assert ok and np.array_equal(dx, ref)
    bad = r.copy()
    bad[3] = np.nan
    _, ok = f._newton_step(bad)
    assert not ok


def _mixed_case(extra, scale_before):
    """A film's stencil Jacobian J1, its band LU, and J2: the rows at band positions from
    N/2 on scaled by 1.3, the diagonal of the others by ``scale_before``."""
    from bearing_fmu.film import stencil_to_band
    b, _ = run(0.0, steps=3, **extra)
    f, g = b.film, b.film.ctx.grid
    f.residual(f.u, 2e4, np.zeros(f.n), b._kin, want_jac=True)
    J1 = f.jst.copy()
    late = g.pos >= f.n // 2
    J2 = J1 * np.where(late, 1.3, 1.0)[:, None]
    J2[~late, 0] *= scale_before
    ab = np.zeros((3 * g.bw + 1, f.n), order="F")
    stencil_to_band(J1, g.n_phi, g.pos, g.bw, ab)
    assert solver.band_lu_nopivot(ab, g.bw, solver.PIVOT_THRESHOLD) == 0
    return g, J1, J2, ab


def _full_lu(J, g):
    from bearing_fmu.film import stencil_to_band
    ref = np.zeros((3 * g.bw + 1, J.shape[0]), order="F")
    stencil_to_band(J, g.n_phi, g.pos, g.bw, ref)
    assert solver.band_lu_nopivot(ref, g.bw, solver.PIVOT_THRESHOLD) == 0
    return ref


@pytest.mark.parametrize("extra", [{"n_phi": 48}, {"n_phi": 48, "axial_bc": 0, "groove_width": 0.0,
                                                   "theta_transport": 1}])
def test_partial_refactorisation_is_the_lu_of_the_mixed_matrix(extra):
    """solver.refactor_partial keeps the factored rows before the first row that moved by more
    than the bound and refactors from there: the result is, bit for bit, the LU of the matrix
    whose early rows are the factored ones and whose later rows are new, and jst_f becomes that
    matrix. With the bound 0 nothing is kept approximately: the LU of the new matrix itself."""
    g, J1, J2, ab = _mixed_case(extra, 1.01)
    jf = J1.copy()
    code, kmin = solver.refactor_partial(J2, jf, g.n_phi, g.pos, g.bw, ab,
                                         solver.PIVOT_THRESHOLD, 0.1)
    assert code == 0 and solver.PARTIAL_MIN_BW * g.bw <= kmin <= J1.shape[0] // 2
    mixed = np.where((g.pos >= kmin)[:, None], J2, J1)
    assert np.array_equal(jf, mixed)
    assert np.array_equal(ab[g.bw:], _full_lu(mixed, g)[g.bw:])
    g, J1, J2, ab = _mixed_case(extra, 1.0)
    jf = J1.copy()
    code, kmin = solver.refactor_partial(J2, jf, g.n_phi, g.pos, g.bw, ab,
                                         solver.PIVOT_THRESHOLD, 0.0)
    assert code == 0 and kmin == J1.shape[0] // 2
    assert np.array_equal(ab[g.bw:], _full_lu(J2, g)[g.bw:]) and np.array_equal(jf, J2)


def test_partial_refactorisation_factors_everything_when_an_early_row_moved():
    g, J1, J2, ab = _mixed_case({"n_phi": 48}, 1.0)
    J2[int(np.argmin(g.pos))] *= 1.3                 # the first row in the band
    jf = J1.copy()
    code, kmin = solver.refactor_partial(J2, jf, g.n_phi, g.pos, g.bw, ab,
                                         solver.PIVOT_THRESHOLD, 0.1)
    assert (code, kmin) == (0, 0)
    assert np.array_equal(ab[g.bw:], _full_lu(J2, g)[g.bw:]) and np.array_equal(jf, J2)


@pytest.mark.parametrize("reuse,jac", [(0.0, 0.0), (solver.LU_REUSE_BELOW, 0.0),
                                       (solver.LU_REUSE_BELOW, solver.JACOBIAN_REUSE_BELOW)])
def test_restore_repeats_bit_for_bit(reuse, jac):
    # the kept and the partly refactored LU live inside one Newton solve only: a restored
    # state repeats exactly
    b, _ = run(reuse, steps=10, jac=jac)
    s = b.get_state()
    b.step(1e-4, *orbit(11))
    F1 = (b.outputs["Fx"], b.outputs["Fy"])
    b.set_state(s)
    b.step(1e-4, *orbit(11))
    assert (b.outputs["Fx"], b.outputs["Fy"]) == F1
