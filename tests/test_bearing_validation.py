"""Validation of the journal-bearing film solver against independent references.

References (``bearing_fmu/reference.py``, each checked on its own in
``tests/test_bearing_validation_reference.py``):

* Ocvirk short bearing, half-Sommerfeld, with squeeze (Ocvirk 1952; Childs 1993,
  *Turbomachinery Rotordynamics*, sec. 3.4; Booker 1965 integrals);
* Sommerfeld long bearing, Guembel condition, with squeeze (Sommerfeld 1904; Szeri
  2011, *Fluid Film Lubrication*, ch. 4);
* finite full bearing with the Reynolds condition: Khonsari & Booser 2008, *Applied
  Tribology*, Table 8.6 (cross-checked with Raimondi & Boyd 1958 at L/D = 1);
* the paper's stationary case (section 3.1 of
  ``/work/shared/paper/transient-run-up-mass-conserving-cavitation.md``).

Tolerances are set by the reference (its limit error or its printed digits) and by
the grid error measured in the grid study, never by what the solver happens to give.
Long studies are ``@pytest.mark.slow``; ``docs/scripts/bearing_validation_tables.py``
prints every table of ``docs/bearing-validation.md``.
"""

from __future__ import annotations

import math

import numpy as np
import pytest

from bearing_fmu import reference as ref

model = pytest.importorskip("bearing_fmu.model")

R = 0.02
PSI = 2.8e-3
C = PSI * R
ETA = 0.012
P0 = 1e5
OMEGA = 2 * math.pi * 100.0


def params(*, B, n_phi, n_z, cavitation=0, axial_bc=0, groove_width=0.0,
           groove_angle=math.pi / 2, **extra):
    return model.BearingParams(R=R, B=B, psi=PSI, eta0=ETA, p0=P0, p_feed=P0,
                               groove_width=groove_width, groove_angle=groove_angle,
                               n_phi=n_phi, n_z=n_z, cavitation=cavitation,
                               axial_bc=axial_bc, **extra)


def hs_force(p, x, y, vx, vy, omega=OMEGA):
    b = model.BearingModel(p)
    b.initialize(x, y, vx, vy, omega)
    return np.array([b.outputs["Fx"], b.outputs["Fy"]]), b


def steady(p, x, y, omega=OMEGA):
    """Stationary mass-conserving film at fixed kinematics (the solver's steady
    Newton, ``bearing_fmu.model.solve_stationary``; paper section 3.1 solves eq. 4
    "with constant kinematic input variables")."""
    return model.solve_stationary(p, x, y, omega)


def rel(a, b):
    return float(np.linalg.norm(np.asarray(a) - np.asarray(b)) / np.linalg.norm(b))


# --------------------------------------------------------------- short-bearing limit
SQUEEZE_CASES = {
    "rotation": (0.0, -0.6 * C, 0.0, 0.0),
    "squeeze+whirl": (0.25 * C, -0.45 * C, 0.08 * C * OMEGA, 0.05 * C * OMEGA),
}


@pytest.mark.parametrize("case", sorted(SQUEEZE_CASES))
def test_half_sommerfeld_tends_to_ocvirk(case):
    """HS film force vs Ocvirk's short bearing as B/D -> 0, with squeeze.

    Reference: :func:`bearing_fmu.reference.short_bearing_force` (Ocvirk 1952;
    Childs 1993, sec. 3.4), exact in the limit B/D -> 0. The finite-length
    correction is O((B/D)^2) (the circumferential Poiseuille term is (B/D)^2
    smaller than the axial one), so the error must fall by about 4 per halving of
    B/D (accepted: 3 to 5.5, leaving room for the O((B/D)^4) term and the grid
    error, which is about 0.1 % on 360 x 40), and be below 1 % at B/D = 1/16.
    """
    x, y, vx, vy = SQUEEZE_CASES[case]
    errs = []
    for b_over_d in (0.25, 0.125, 0.0625):
        B = b_over_d * 2 * R
        f, _ = hs_force(params(B=B, n_phi=360, n_z=40), x, y, vx, vy)
        f_ref = ref.short_bearing_force(x, y, vx, vy, OMEGA, R=R, B=B, c=C, eta=ETA)
        errs.append(rel(f, f_ref))
    for e1, e2 in zip(errs, errs[1:]):
        assert 3.0 < e1 / e2 < 5.5
    assert errs[2] < 0.01


# ---------------------------------------------------------------- long-bearing limit
@pytest.mark.parametrize("case", sorted(SQUEEZE_CASES))
def test_half_sommerfeld_tends_to_long_bearing(case):
    """HS film force vs the Guembel long bearing as B/D -> infinity, with squeeze.

    Reference: :func:`bearing_fmu.reference.long_bearing_force` (Sommerfeld 1904;
    Szeri 2011 ch. 4), exact as B/D -> infinity, with the squeeze constant of the
    finite bearing with p = p0 at its ends (checked by an independent 2-D FD in
    ``test_bearing_validation_reference.py``). Near each end a boundary layer of
    width ~R carries a pressure deficit, so the force error falls like D/B: the
    error must halve per doubling of B (accepted 1.8 to 2.2), and the Richardson
    extrapolation in D/B of the force per unit length, 2 F(2B)/(2B) - F(B)/B, must
    match the reference to 0.5 % (the grid error of 72 cells in phi, measured
    against 144 cells, is below 0.1 %).
    """
    x, y, vx, vy = SQUEEZE_CASES[case]
    errs, per_len = [], []
    for b_over_d in (2.0, 4.0, 8.0):
        B = b_over_d * 2 * R
        n_phi = 72
        n_z = int(round(B / (R * 2 * math.pi / n_phi)))  # square cells
        f, _ = hs_force(params(B=B, n_phi=n_phi, n_z=n_z), x, y, vx, vy)
        f_ref = ref.long_bearing_force(x, y, vx, vy, OMEGA, R=R, B=B, c=C, eta=ETA)
        errs.append(rel(f, f_ref))
        per_len.append(f / B)
    for e1, e2 in zip(errs, errs[1:]):
        assert 1.8 < e1 / e2 < 2.2
    f_ref_len = np.array(ref.long_bearing_force(x, y, vx, vy, OMEGA, R=R, B=1.0, c=C, eta=ETA))
    assert rel(2 * per_len[2] - per_len[1], f_ref_len) < 0.005


# ------------------------------------------------------- finite bearing vs the table
def finite_case(b_over_d, eps, *, n_phi, n_z, **extra):
    """Mass-conserving film, oil bath, narrow flooded groove (p_feed = p0) at the
    thickest film; journal displaced downwards. Returns (S, attitude_deg, bearing)."""
    B = b_over_d * 2 * R
    x, y = 0.0, -eps * C
    p = params(B=B, n_phi=n_phi, n_z=n_z, cavitation=1, axial_bc=0,
               groove_width=1e-9, groove_angle=math.pi / 2, **extra)
    b = steady(p, x, y)
    fx, fy = b.outputs["Fx"], b.outputs["Fy"]
    s = ref.sommerfeld_number(math.hypot(fx, fy), R=R, B=B, c=C, eta=ETA, omega=OMEGA)
    att = math.degrees(ref.attitude_angle(fx, fy, x, y))
    return s, att, b


def _table_row(b_over_d, eps):
    return next(r for r in ref.FINITE_BEARING_TABLE[b_over_d] if r[0] == eps)


#: Tolerance on S against the table: 1.5 % is the spread between the two published
#: sources at L/D = 1 (Khonsari & Booser vs Raimondi & Boyd, up to 1.4 %); the grid
#: error of the 90 x 30 grid is added from the grid study (below 1 % for the force).
S_TOL = 0.015 + 0.01
#: attitude angle: the tables print 0.01 deg, the two sources differ by up to 0.54 deg
#: (eps = 0.4, L/D = 1: 62.56 vs 63.10); grid error of the angle < 0.5 deg.
ATT_TOL_DEG = 0.6 + 0.5


@pytest.mark.parametrize("b_over_d", [1.0, 0.5, 0.25])
def test_mass_conserving_matches_finite_bearing_table(b_over_d):
    """Mass-conserving model with a flooded groove at the thickest film reproduces
    the Reynolds-condition finite bearing (Khonsari & Booser 2008, Table 8.6;
    Raimondi & Boyd 1958) at eps = 0.6: Sommerfeld number and attitude angle.

    JFO/Elrod-type mass-conserving models reduce to the Reynolds (Swift-Stieber)
    rupture condition for a fully flooded bearing in steady state (Floberg 1974;
    Elrod 1981), and the groove at the thickest film supplies p = p0 on the line of
    maximum film as in the tables' boundary conditions."""
    eps, s_tab, att_tab = _table_row(b_over_d, 0.6)
    s, att, _ = finite_case(b_over_d, eps, n_phi=90, n_z=30)
    assert s == pytest.approx(s_tab, rel=S_TOL)
    assert abs(att - att_tab) < ATT_TOL_DEG


@pytest.mark.slow
@pytest.mark.parametrize("b_over_d", [1.0, 0.5, 0.25])
@pytest.mark.parametrize("eps", [0.4, 0.8])
def test_mass_conserving_matches_finite_bearing_table_more(b_over_d, eps):
    """As above at eps = 0.4 and 0.8 (same tolerances, same sources)."""
    _, s_tab, att_tab = _table_row(b_over_d, eps)
    s, att, _ = finite_case(b_over_d, eps, n_phi=90, n_z=30)
    assert s == pytest.approx(s_tab, rel=S_TOL)
    assert abs(att - att_tab) < ATT_TOL_DEG


# --------------------------------------------------------------- paper, section 3.1
PAPER_B = 1.6 * R


def paper_case(axial_bc, *, n_phi=40, n_z=40, **extra):
    """Section 3.1: 100 Hz, eps = 0.7 with the minimum gap at phi = pi, B/R = 1.6,
    psi = 2.8e-3, eta0 = 12 mPa s, p0 = 1 bar; oil bath without groove (periodic,
    figure 6a) or free to air with a 15 deg groove at phi = 0, p_inlet = p0 (6b)."""
    gw = 0.0 if axial_bc == 0 else math.radians(15.0)
    p = params(B=PAPER_B, n_phi=n_phi, n_z=n_z, cavitation=1, axial_bc=axial_bc,
               groove_width=gw, groove_angle=0.0, **extra)
    b = steady(p, -0.7 * C, 0.0)
    return b


def test_mass_conservation_steady_state():
    """Steady state: inflow through the groove equals the net side outflow to the
    solver tolerance (free to air: the groove is the only source). For the oil bath
    without a groove there is no feed, so the net side flow must vanish."""
    b = paper_case(1)
    q_feed, q_side = b.outputs["q_feed"], b.outputs["q_side"]
    assert q_feed > 0
    assert abs(q_feed - q_side) <= 1e-5 * q_feed
    b = paper_case(0)
    q_scale = C * R * OMEGA * PAPER_B  # Couette flow scale
    assert abs(b.outputs["q_side"] - b.outputs["q_feed"]) <= 1e-6 * q_scale


def test_paper_stationary_case_default_parameters():
    """Paper section 3.1 with the solver defaults (cav_width = 1 kPa), 40 x 40.

    What the paper states and we check: p_min slightly below p0 in both cases
    (here p_min = p0 - cav_width, the model's cavity pressure, 1 % below p0); a
    cavity in both; free to air, the cavity is open to the surroundings (theta < 1
    at the axial edges, figure 7b). The p_max comparison is the next test."""
    for bc in (0, 1):
        b = paper_case(bc)
        o = b.outputs
        width = b.params.cav_width
        assert P0 - width - 1.0 <= o["p_min"] < P0
        th = b.fields()["theta"]
        assert th.min() < 0.9
        if bc == 1:
            assert th[[0, -1]].min() < 0.9


@pytest.mark.xfail(strict=True, reason=(
    "with the default cav_width = 1 kPa the oil bath without a groove is fed only by "
    "a 1 kPa suction at the edges and drains: p_max 0.985 MPa vs 4.472 MPa free to "
    "air (-78 %), |F| 190 N vs 1988 N (free to air since issue 16 edge fix); see docs/bearing-validation.md and the "
    "wide-step test below"))
def test_paper_pmax_bath_vs_air_default_parameters():
    """Paper: p_max of the oil bath (eq. 5, no groove) and free-to-air (eq. 6, 15 deg
    groove) cases differ by 0.6 %. Accepted: 1 % (0.6 % plus the 0.3 % spread of the
    free-to-air p_max over smoothing widths, see the smoothing table)."""
    pb, pa = paper_case(0).outputs["p_max"], paper_case(1).outputs["p_max"]
    assert abs(pa - pb) / pa < 0.01


def _paper_pmax_wide_step():
    bath = paper_case(0, cav_width=0.9 * P0)
    air = paper_case(1, cav_width=0.9 * P0)
    return bath, air


@pytest.mark.xfail(strict=True, reason=(
    "since the free-to-air edge is second order (issue 16, cavitation.penalty_edge) the "
    "free-to-air p_max is 2.0 % above the oil bath's (4.462 vs 4.372 MPa at 40 x 40, 4.444 vs "
    "4.355 at 80 x 80: a grid-converged model difference), not the paper's 0.6 %; the -0.13 % "
    "measured before was a cancellation with the old edge's first-order error (-2 % in p_max "
    "at n_z = 40). docs/bearing-validation.md, paper section 3.1"))
def test_paper_pmax_bath_vs_air_wide_theta_step():
    """The paper's 0.6 % (bath vs free to air) with theta(p) spanning most of p0 (cav_width =
    0.9 p0), so that the cavity suction can draw oil in from the bath; 1 % acceptance."""
    bath, air = _paper_pmax_wide_step()
    pb, pa = bath.outputs["p_max"], air.outputs["p_max"]
    assert abs(pa - pb) / pa < 0.01


def test_paper_wide_theta_step_bath_refills_the_edges():
    """Figure 5b: the oil bath refills the axial edges (theta ~ 1 there, accepted >= 0.95),
    and the free-to-air p_max is within 2.5 % of the bath's (measured +2.0 %, converged in
    the grid; the paper: 0.6 %, see the xfail above)."""
    bath, air = _paper_pmax_wide_step()
    assert bath.fields()["theta"][[0, -1]].min() >= 0.95
    pb, pa = bath.outputs["p_max"], air.outputs["p_max"]
    assert 0.0 < (pa - pb) / pa < 0.025


def test_smoothing_width_barely_moves_the_free_to_air_film():
    """Free to air (fed by its groove), the film pressure does not depend on the
    smoothing width of theta(p): p_max within 0.5 % from cav_width = 100 Pa to
    10 kPa (the cavity pressure moves by 0.1 bar, against a 4.4 MPa peak; measured
    0.02 %; 0.5 % is well below the grid error of p_max on 40 x 40, so any larger
    change would be a model effect worth knowing)."""
    ref_pmax = paper_case(1, cav_width=1e2).outputs["p_max"]
    for w in (1e3, 1e4):
        assert paper_case(1, cav_width=w).outputs["p_max"] == pytest.approx(ref_pmax, rel=5e-3)


@pytest.mark.parametrize("width", [3e4, 9e4])
def test_fluid_fraction_stays_physical_for_wide_steps(width):
    """0 <= theta <= 1 everywhere (a fluid fraction), free to air, wide theta steps.

    Regression: with the penalty kink smoothed over cav_width/3 the cavity edges
    leaked outwards and theta reached -0.04 (30 kPa) and -0.48 (90 kPa); fixed in
    d4c8cd8 (penalty smoothing of its own, 10 Pa)."""
    th = paper_case(1, cav_width=width).fields()["theta"]
    assert th.min() >= 0.0 and th.max() <= 1.0


# ------------------------------------------------------------------ grid convergence
def test_grid_convergence_half_sommerfeld():
    """HS force on the paper geometry (eps = 0.7) on 40, 80, 160 squared grids: the
    scheme is second order (two-point fluxes, force with the rupture located inside
    the cells, film.hs_force_pressure), so the observed order must be 2 (accepted 1.7
    to 2.3); the 40 x 40 error against the Richardson estimate is below 1 % (measured
    0.65 %; 0.06 % with the former cell-resolution clip, whose averaged kink error
    happened to cancel the discretisation error in this case - on the Jeffcott bearing
    both quadratures give the same 0.08-1.1 % at eps 0.2-0.8, docs/bearing-validation.md)."""
    f = []
    for n in (40, 80, 160):
        fn, _ = hs_force(params(B=PAPER_B, n_phi=n, n_z=n), -0.7 * C, 0.0, 0.0, 0.0)
        f.append(np.linalg.norm(fn))
    order = math.log2(abs(f[0] - f[1]) / abs(f[1] - f[2]))
    assert 1.7 < order < 2.3
    rich = f[2] + (f[2] - f[1]) / (2**order - 1)
    assert abs(f[0] - rich) / rich < 1e-2


@pytest.mark.slow
def test_grid_convergence_mass_conserving_table_case():
    """Mass-conserving model, L/D = 1, eps = 0.6, flooded groove (the table case) on
    40x20, 80x40, 160x80: second order in the full film, first-order upwind
    transport of theta in the cavity, so the observed order lies between 1 and 2
    (measured 1.59); the Richardson-extrapolated Sommerfeld number matches the
    table (Khonsari & Booser 2008, Table 8.6: 0.1209) to its 4 digits plus the
    Richardson uncertainty, accepted 0.5 % (measured -0.01 %)."""
    s = []
    for n in (40, 80, 160):
        s.append(finite_case(1.0, 0.6, n_phi=n, n_z=n // 2)[0])
    f = [1.0 / v for v in s]  # the force converges, S is its inverse
    order = math.log2(abs(f[0] - f[1]) / abs(f[1] - f[2]))
    assert 1.0 < order < 2.0
    rich = f[2] + (f[2] - f[1]) / (2**order - 1)
    assert 1.0 / rich == pytest.approx(0.1209, rel=5e-3)


@pytest.mark.slow
def test_transient_run_reaches_the_stationary_solution():
    """Stepping the transient model from a flooded film at fixed kinematics ends at
    the stationary solution of ``solve_stationary`` (free to air, 40 x 40): force
    within 0.1 % after 40 revolutions (the cavity is swept out in about one
    revolution; 40 leave a margin)."""
    p = params(B=PAPER_B, n_phi=40, n_z=40, cavitation=1, axial_bc=1,
               groove_width=math.radians(15.0), groove_angle=0.0)
    st = steady(p, -0.7 * C, 0.0)
    b = model.BearingModel(p)
    b.initialize(-0.7 * C, 0.0, 0.0, 0.0, OMEGA)
    for _ in range(20):
        b.step(2 * 2 * math.pi / OMEGA, -0.7 * C, 0.0, 0.0, 0.0, OMEGA)
    f_t = [b.outputs["Fx"], b.outputs["Fy"]]
    f_s = [st.outputs["Fx"], st.outputs["Fy"]]
    assert rel(f_t, f_s) < 1e-3
