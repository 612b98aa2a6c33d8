"""Journal-bearing film model: parameters and the stepping API (no FMI import).

Physics: the transient Reynolds equation with the mass-conserving two-phase
cavitation model of the paper (``/work/shared/paper/transient-run-up-mass-
conserving-cavitation.md``, eq. 2-6), or the quasi-static half-Sommerfeld
(Guembel) model. See docs/bearing-model.md for the derivation and choices.

Conventions
-----------
* SI units throughout. Frame: x horizontal, y vertical up, z along the shaft;
  the journal spins counter-clockwise (omega > 0 about +z); phi is measured
  from +x counter-clockwise (docs/dev/contracts.md).
* Inputs: journal centre (x, y) [m] relative to the bearing centre, its
  velocity (vx, vy) [m/s], spin omega [rad/s]. Clearance ``c = psi R``; gap
  ``h = c - x cos(phi) - y sin(phi)``; ``eps = sqrt(x^2 + y^2) / c`` must stay
  below 1 (with ``contact = 1``: below ``1 - contact_h_limit sigma_rough / c``, the
  film then using the expected gap of the roughness, bearing_fmu/contact.py).
* Outputs (``BearingModel.outputs``): ``Fx, Fy`` film force ON the journal
  [N] (``F = -int (p - p0) (cos phi, sin phi) dA``: a journal displaced down
  (-y) gets +Fy); ``eps`` [-]; ``attitude`` [rad] angle from the load line
  (direction of -F) to the eccentricity vector, counter-clockwise positive (> 0
  for omega > 0); ``p_max, p_min`` [Pa] absolute; ``h_min`` [m] (the film's gap:
  with contact the expected gap); ``torque`` [N m] friction torque ON the journal
  about +z (< 0 when omega > 0; plus the contact friction); ``F_contact`` [N] normal
  asperity contact force (0 without contact; Fx, Fy include the contact force);
  ``q_feed`` [m^3/s] flow out of the groove into the film, ``q_side`` [m^3/s]
  net flow out through both axial edges (in a steady state q_feed = q_side).
* ``fields()``: ``phi`` (n_phi,) [rad], ``z`` (n_z,) [m] from 0 to B, ``p``
  [Pa], ``theta`` [-], ``h`` [m], each (n_z, n_phi); ``cavitation`` (the film model, 0 or 1) and
  ``p0`` [Pa] (a half-Sommerfeld film has theta = 1 and p clipped to p0 where it ruptures).
* Time: ``t`` is the film time; ``initialize`` sets t = 0.
"""

from __future__ import annotations

import math
import os
import warnings
from dataclasses import dataclass, fields as dc_fields

import numba as nb
import numpy as np

from .cavitation import CavitationLaw
from .contact import average_gap, contact_force
from .film import hs_force_pressure, integrals
from .grid import groove_columns, make_grid
from .hs import HalfSommerfeld
from .limits import (B_RANGE, CONTACT_KE_MAX, ETA0_RANGE, MAX_FILM_CELLS, MAX_N_PHI, MAX_N_Z,  # noqa: F401
                     MU_CONTACT_MAX, PRESSURE_MAX, PSI_MAX, PSI_MIN, R_RANGE, SIGMA_ROUGH_MAX)
from .solver import StepFailed, TransientFilm

__all__ = ["BearingParams", "BearingModel", "StepFailed", "film_memory_estimate", "solve_stationary"]


# Bounds of the film grid (checked before anything is allocated): memory and time grow with the
# cells, n_phi = 10^9 took 23 GB before failing. The finest grids we use are 1536 x 40 (the
# phi refinement of docs/bearing-validation.md), 40 x 320 (its axial one) and 160 x 160; the
# bounds leave at least 4 times that (bearing_fmu.limits; bearing_fmu.journal_bearing declares the
# same as the FMU parameters' max). At MAX_FILM_CELLS the mass-conserving film needs
# 0.1-3.2 GiB (its band matrix; film_memory_estimate) and about a minute per internal step on a
# square grid (BENCHMARKS.md session 19): time, not memory, is what limits it.


def film_band(n_phi: int, n_z: int, cavitation: int, groove_width: float,
              groove_angle: float, theta_transport: int = 0) -> tuple[int, int]:
    """(unknowns n, band half width bw) of the mass-conserving film's Newton matrix from the
    grid sizes (no field allocated): the bandwidth :func:`.grid.best_ordering` finds, or
    more (z-fastest after the groove: rows; phi-fastest: n_phi; folded: 2 rows; the
    7-point stencil of ``theta_transport = 1`` doubles the z-fastest ones, and its i +- 2
    couplings jump a one-column groove)."""
    rows = n_z // 2 if cavitation == 1 and n_z % 2 == 0 else n_z
    wide = 2 if cavitation == 1 and theta_transport == 1 else 1
    cands = [n_phi, 2 * wide * rows]
    n_groove = int(groove_columns(n_phi, groove_width, groove_angle).sum())
    if n_groove >= wide:
        cands.append(wide * rows)
    return n_phi * rows, max(1, min(cands))


def film_memory_estimate(p: "BearingParams") -> int:
    """Estimated peak memory [bytes] of a :class:`BearingModel` of ``p`` beyond the
    interpreter and its compiled kernels: the Newton band matrix ((3 bw + 1) x n doubles,
    solver.TransientFilm.ab) plus about FILM_VECTORS_PER_CELL vectors of n doubles (the
    integrator's state, buffers and stencil Jacobians) and HS_ARRAYS_PER_CELL arrays of the
    full grid (the half-Sommerfeld solver, the fields, and the candidate orderings while the
    grid is built): 0-70 % above the peak measured over the process's base, the band matrix
    90-96 % of it on square grids (benchmarks/bench_film_memory.py, BENCHMARKS.md session 19)."""
    N = p.n_phi * p.n_z
    est = HS_ARRAYS_PER_CELL * 8 * N
    if p.cavitation == 1:
        n, bw = film_band(p.n_phi, p.n_z, p.cavitation, p.groove_width, p.groove_angle,
                          p.theta_transport)
        est += (3 * bw + 1) * n * 8 + FILM_VECTORS_PER_CELL * 8 * n
    return est


FILM_VECTORS_PER_CELL = 80
HS_ARRAYS_PER_CELL = 32
# film_memory_estimate above which BearingParams compares it with the memory available (below
# it /proc/meminfo is not read: 40 x 40 needs 2 MiB, 512 x 512 with a groove 0.9 GiB)
MEMORY_CHECK_ABOVE = 2**28


def available_memory() -> int | None:
    """Bytes of memory available to a new allocation: ``MemAvailable`` of /proc/meminfo (free
    plus reclaimable cache; Linux), else the physical pages (os.sysconf), None if unknown."""
    try:
        with open("/proc/meminfo", "rb") as fh:
            for line in fh:
                if line.startswith(b"MemAvailable:"):
                    return int(line.split()[1]) * 1024
    except (OSError, ValueError, IndexError):
        pass
    try:
        return os.sysconf("SC_PAGE_SIZE") * os.sysconf("SC_PHYS_PAGES")
    except (OSError, ValueError, AttributeError):
        return None


#: an oil bath without a groove whose cavity pressure p0 - cav_width lies above half of p0 warns
#: (gaseous cavities in oil sit at a fraction of ambient; the 1 kPa default is 0.99 p0)
OIL_BATH_MIN_CAV_WIDTH = 0.5
# A journal that left the clearance (eps >= 1, contact = 0): its message gives the film's static
# load capacity at eps = CAPACITY_EPS and the current speed; with eta0 below THIN_OIL_ETA0 the
# cause is named as the oil, not the coupling.
CAPACITY_EPS = 0.95
THIN_OIL_ETA0 = 1e-4        # Pa s: below every lubricating oil (water 1e-3, air 1.8e-5)


def _type_problems(params) -> list[str]:
    """One line per field of the dataclass ``params`` whose value is not of its declared kind: a
    ``float`` field a real number (an int is fine), an ``int`` field an integer, a ``str`` field a
    text; a boolean is neither (``R=True`` was a 1 m journal). A text or None reached the range
    checks, which raised a bare TypeError ('>=' not supported between 'str' and 'int')."""
    import numbers
    out = []
    for f in dc_fields(params):
        v, kind = getattr(params, f.name), str(f.type)
        if kind == "float":
            ok, what = isinstance(v, numbers.Real) and not isinstance(v, bool), "a number"
        elif kind == "int":
            ok, what = isinstance(v, int) and not isinstance(v, bool), "an integer"
        elif kind == "str":
            ok, what = isinstance(v, str), "a text"
        else:
            continue
        if not ok:
            shown = repr(v) if len(repr(v)) <= 80 else repr(v)[:80] + "..."
            out.append(f"{type(params).__name__}.{f.name} must be {what} (got {shown}, a {type(v).__name__})")
    return out


@dataclass(frozen=True, kw_only=True)
class BearingParams:
    """Bearing geometry, lubricant, grid and solver settings (SI units).

    Geometry and lubricant
        R [m] journal radius; B [m] axial width; psi [-] relative clearance
        (c = psi R); eta0 [Pa s] oil viscosity; p0 [Pa] ambient pressure;
        p_feed [Pa] groove pressure (>= p0); groove_width [rad] opening angle
        of the axial feed groove (0: no groove); groove_angle [rad] its centre.
    Model
        cavitation: 0 half-Sommerfeld (quasi-static), 1 mass-conserving
        (transient, paper eq. 4). axial_bc: 0 oil bath (Dirichlet p0, eq. 5),
        1 free to air (Neumann penalty, eq. 6).
        theta_transport: Couette transport of the fluid fraction in the
        mass-conserving film: 0 (default) first-order upwind, 1 limited second
        order (MUSCL, smooth TVD limiter; bearing_fmu/film.py). Only the cavity
        (theta < 1) is affected; the half-Sommerfeld model ignores it.
        cav_width [Pa]: the smooth theta(p) step lies between p0 - cav_width
        (cavity pressure) and p0; default 1 kPa (1 % of an atmosphere, below
        0.1 % of typical film pressures of 1-10 MPa; see docs/bearing-model.md
        for its effect). NOTE: cav_width is also the largest suction an oil
        bath (axial_bc=0) can exert on the cavity, so an oil-bath bearing
        WITHOUT a feed groove drains to a starved film at the default (the
        paper's section 3.1 bath case at p_max within 0.6 % of the free-to-air
        case needs cav_width ~ 0.9 p0, found by bearing-validation). cav_smoothing [-]: width of the switch in the
        universal variable (Newton smoothness; 0.05).
        penalty_a, penalty_b [-]: slopes of g(p) below/above p0 (eq. 6), in
        units of the nominal axial film conductance, applied AT the edge (the
        edge pressure from the flux through the edge half cell,
        cavitation.penalty_edge). a = 0.01 as the paper; b = 1e4 (the paper's
        100 is in its own, unstated units): the paper's penalty is to hold
        p ~ p0 at the full-film edge, and with b = 100 in our units the edge
        resistance raised the edge pressure so that the load was +2.8 % above
        the Dirichlet value at B/D 0.5, eps 0.5 (+0.03 % with 1e4, the error
        falls as 1/b; docs/bearing-validation.md). The edge flux's Jacobian is
        bounded by the half-cell conductance, so a large b costs Newton nothing.
        penalty_smoothing [Pa]: half-width of the C1 rounding of the g(p) kink
        at p0 (10 Pa; must be below cav_width).
    Asperity contact (bearing_fmu/contact.py; both cavitation models)
        contact: 0 (default) none, the journal must stay off the shell; 1
        Greenwood-Tripp asperity contact with boundary friction, added to the
        film force (outputs Fx, Fy, torque; F_contact its normal part).
        sigma_rough [m]: composite RMS roughness of journal and shell (0.3 um);
        contact_KE [Pa]: Greenwood-Tripp K E' (2e7 Pa); mu_contact [-]: boundary
        friction coefficient (0.1); contact_h_limit [-]: smallest nominal gap
        h / sigma_rough a step may reach (-1: the film refuses the step, fmi2Discard in
        the FMU, so that a master can retry with smaller steps). Defaults and their
        sources: docs/bearing-model.md.
    Grid
        n_phi, n_z: cells in phi (periodic) and across the width.
    Solver (mass-conserving model)
        theta_atol: local-error tolerance of theta per internal step (RMS).
        newton_atol: Newton tolerance on theta (1e-4, a tenth of theta_atol);
        newton_rtol: on p, relative to the pressure range of the film (1e-5).
        newton_max_iter. krylov_refactor: 0 (default) = fresh band LU and a
        direct solve every Newton iteration; m > 0 = GMRES preconditioned by
        the reused LU, refreshed after m GMRES iterations (krylov_tol: GMRES
        relative tolerance).
        h_init, h_min, h_max [s]: internal steps.
        linear_solver: "band" (default: band LU without row interchanges when partial
        pivoting would make none, else LAPACK dgbtrf; solver.BandLU), "lapack" (LAPACK
        dgbtrf always) or "splu" (SuperLU).
    """

    R: float = 0.02
    B: float = 0.032
    psi: float = 2.8e-3
    eta0: float = 0.012
    p0: float = 1.0e5
    p_feed: float = 1.0e5
    groove_width: float = 0.0
    groove_angle: float = math.pi / 2
    n_phi: int = 40
    n_z: int = 40
    cavitation: int = 1
    axial_bc: int = 0
    theta_transport: int = 0
    cav_width: float = 1.0e3
    cav_smoothing: float = 0.05
    penalty_a: float = 0.01
    penalty_b: float = 1.0e4
    penalty_smoothing: float = 10.0
    contact: int = 0
    sigma_rough: float = 0.3e-6
    contact_KE: float = 2.0e7
    mu_contact: float = 0.1
    contact_h_limit: float = -1.0
    theta_atol: float = 1.0e-3
    newton_atol: float = 1.0e-4
    newton_rtol: float = 1.0e-5
    newton_max_iter: int = 30
    krylov_tol: float = 1.0e-4
    krylov_refactor: int = 0
    h_init: float = 1.0e-6
    h_min: float = 1.0e-12
    h_max: float = 1.0
    linear_solver: str = "band"

    def __post_init__(self):
        wrong = _type_problems(self)            # before the checks below compare them with numbers
        if wrong:
            raise ValueError("invalid bearing parameters:\n  " + "\n  ".join(wrong))
        problems = []

        def need(name, ok, expected):
            if not ok:
                problems.append(f"BearingParams.{name} must be {expected} "
                                f"(got {getattr(self, name)!r})")

        what = {"R": " [m], the journal radius (e.g. 0.02 for 20 mm; a value in mm is 1000 times too large)",
                "B": " [m], the axial bearing width (e.g. 0.032 for 32 mm; a value in mm is 1000 times too large)",
                "psi": " [-], the relative radial clearance C/R (typically 1e-3 to 3e-3)",
                "eta0": " [Pa s], the dynamic viscosity (e.g. 0.012 for 12 mPa s; a value in mPa s or cP is "
                        "1000 times too large)"}
        for name in ("R", "B", "psi", "eta0", "cav_width", "cav_smoothing",
                     "penalty_b", "theta_atol", "newton_atol", "h_init", "h_min",
                     "h_max"):
            v = getattr(self, name)
            need(name, isinstance(v, (int, float)) and math.isfinite(v) and v > 0,
                 "a positive finite number" + what.get(name, ""))
        if isinstance(self.psi, (int, float)) and math.isfinite(self.psi) and not PSI_MIN <= self.psi <= PSI_MAX:
            problems.append(
                f"BearingParams.psi must be the relative radial clearance C/R (radial clearance over "
                f"journal radius) in [{PSI_MIN:g}, {PSI_MAX:g}], typically 1e-3 to 3e-3 (got {self.psi!r} = "
                f"{self.psi * 1e3:.4g} per mille): a value in per mille is 1000 times too large (1.5 per mille "
                f"is psi = 1.5e-3); a clearance C in m is not psi (psi = C / R, e.g. 15e-6 m / 10e-3 m = 1.5e-3)")
        # the same upper bounds as the FMU declares (bearing_fmu.limits): a value in the wrong unit
        # (R in mm, eta0 in mPa s) is refused here too, not only by a scenario's loader
        for name, (lo, hi), unit in (("R", R_RANGE, "m"), ("B", B_RANGE, "m"), ("eta0", ETA0_RANGE, "Pa s")):
            v = getattr(self, name)
            if isinstance(v, (int, float)) and math.isfinite(v) and v > 0 and not lo <= v <= hi:
                problems.append(f"BearingParams.{name} must be in [{lo:g}, {hi:g}] [{unit}]{what[name][len(f' [{unit}]'):]} "
                                f"(got {v!r})")
        for name, hi, unit in (("p0", PRESSURE_MAX, "Pa"), ("p_feed", PRESSURE_MAX, "Pa"),
                               ("sigma_rough", SIGMA_ROUGH_MAX, "m (a value in um is 1e6 times too large)"),
                               ("contact_KE", CONTACT_KE_MAX, "Pa"), ("mu_contact", MU_CONTACT_MAX, "[-]")):
            v = getattr(self, name)
            if isinstance(v, (int, float)) and math.isfinite(v) and v > hi:
                problems.append(f"BearingParams.{name} must be at most {hi:g} {unit} (got {v!r})")
        for name in ("p0", "p_feed", "groove_width", "groove_angle", "penalty_a",
                     "newton_rtol"):
            v = getattr(self, name)
            need(name, isinstance(v, (int, float)) and math.isfinite(v), "a finite number")
        need("p0", self.p0 >= 0, ">= 0 (absolute pressure)")
        need("cav_width", self.cav_width < max(self.p0, 1e-300) or self.cavitation == 0,
             "below p0 (the cavity pressure p0 - cav_width must stay positive)")
        need("p_feed", self.p_feed >= self.p0, ">= p0 (a groove feeds oil)")
        need("groove_width", 0 <= self.groove_width < 2 * math.pi, "in [0, 2 pi) [rad]")
        need("penalty_a", self.penalty_a >= 0, ">= 0")
        need("penalty_smoothing", 0 < self.penalty_smoothing < self.cav_width,
             f"in (0, cav_width = {self.cav_width:g}) [Pa], so that the cavity edge flux "
             "is exactly penalty_a (p - p0)")
        need("n_phi", isinstance(self.n_phi, int) and 8 <= self.n_phi <= MAX_N_PHI,
             f"an integer in [8, {MAX_N_PHI}] (MAX_N_PHI)")
        need("n_z", isinstance(self.n_z, int) and 2 <= self.n_z <= MAX_N_Z, f"an integer in [2, {MAX_N_Z}] (MAX_N_Z)")
        if isinstance(self.n_phi, int) and isinstance(self.n_z, int) and self.n_phi * self.n_z > MAX_FILM_CELLS:
            problems.append(f"BearingParams: the film grid n_phi x n_z must have at most {MAX_FILM_CELLS} cells "
                            f"(MAX_FILM_CELLS) (got {self.n_phi} x {self.n_z} = {self.n_phi * self.n_z}); use a "
                            "coarser grid (the finest we use: 1536 x 40, 160 x 160)")
        need("cavitation", self.cavitation in (0, 1),
             "0 (half-Sommerfeld) or 1 (mass-conserving)")
        need("axial_bc", self.axial_bc in (0, 1), "0 (oil bath) or 1 (free to air)")
        need("theta_transport", self.theta_transport in (0, 1),
             "0 (first-order upwind) or 1 (limited second order)")
        need("contact", self.contact in (0, 1), "0 (no contact) or 1 (Greenwood-Tripp asperity contact)")
        for name in ("sigma_rough", "contact_KE", "mu_contact"):
            v = getattr(self, name)
            need(name, isinstance(v, (int, float)) and math.isfinite(v) and v >= 0,
                 "a finite number >= 0")
        need("contact_h_limit", isinstance(self.contact_h_limit, (int, float))
             and -6.0 <= self.contact_h_limit <= 0.0, "in [-6, 0] (units of sigma_rough; e.g. -1)")
        need("sigma_rough", self.sigma_rough > 0, "> 0 [m] (composite RMS roughness, e.g. 0.3e-6)")
        need("newton_max_iter", isinstance(self.newton_max_iter, int)
             and self.newton_max_iter >= 2, "an integer >= 2")
        need("krylov_tol", 0 < self.krylov_tol < 1, "in (0, 1)")
        need("krylov_refactor", isinstance(self.krylov_refactor, int)
             and self.krylov_refactor >= 0, "an integer >= 0 (0: fresh LU every Newton iteration)")
        need("h_min", self.h_min <= self.h_init <= self.h_max, "h_min <= h_init <= h_max")
        need("linear_solver", self.linear_solver in ("band", "lapack", "splu"),
             "'band', 'lapack' or 'splu'")
        if not problems:
            self._check_memory(problems)
        if problems:
            raise ValueError("invalid bearing parameters:\n  " + "\n  ".join(problems))
        if self.cavitation == 1 and self.axial_bc == 1 and self.groove_width == 0:
            warnings.warn(
                "BearingParams: mass-conserving model free to air (axial_bc=1) without "
                "a feed groove (groove_width=0): nothing refills the cavity except the "
                "weak sub-ambient suction penalty_a, so the film drains over time. "
                "Set groove_width > 0 (e.g. 15 deg = 0.2618 rad) to feed the bearing.",
                stacklevel=3)
        if (self.cavitation == 1 and self.axial_bc == 0 and self.groove_width == 0
                and self.cav_width < OIL_BATH_MIN_CAV_WIDTH * self.p0):
            warnings.warn(
                f"BearingParams: mass-conserving model in an oil bath (axial_bc=0) without a feed "
                f"groove (groove_width=0) and cav_width = {self.cav_width:g} Pa: the bath refills the "
                f"cavity only through the suction p0 - p_cav = cav_width, so the film drains to a "
                f"starved state (a 25 mm, L/D 0.5 bearing at eps 0.6 then carries 1.5 % of the load of "
                f"a flooded one at the 1 kPa default; docs/bearing-model.md, 'Oil bath without a "
                f"groove'). For a flooded bearing give it a feed groove (groove_width > 0, e.g. "
                f"0.2618 rad at groove_angle pi/2; within 1 % of Raimondi-Boyd); for a bath without "
                f"one give the cavity's pressure, cav_width = p0 - p_cav, e.g. 0.9 p0 = "
                f"{0.9 * self.p0:g} Pa for a cavity at 0.1 p0",
                stacklevel=3)

    def _check_memory(self, problems: list[str]) -> None:
        """Refuse a film whose estimated memory (:func:`film_memory_estimate`) exceeds what the
        machine has available now: Linux would hand out the zeroed arrays anyway and the OOM
        killer end the run (or another process) when the solver first fills them."""
        est = film_memory_estimate(self)
        if est <= MEMORY_CHECK_ABOVE:
            return
        avail = available_memory()
        if avail is None or est <= avail:
            return
        n, bw = film_band(self.n_phi, self.n_z, self.cavitation, self.groove_width,
                          self.groove_angle, self.theta_transport)
        what = (f"its Newton band matrix is {n} unknowns x {3 * bw + 1} band rows"
                if self.cavitation == 1 else "its arrays")
        problems.append(
            f"BearingParams: the film grid n_phi x n_z = {self.n_phi} x {self.n_z} needs about "
            f"{est / 2**30:.1f} GiB ({what}), more than this machine has available "
            f"({avail / 2**30:.1f} GiB, MemAvailable); use a coarser grid (memory grows as n_phi n_z "
            "min(n_phi, n_z); an even n_z and a feed groove halve the band of the mass-conserving "
            "film) or free memory")

    @property
    def c(self) -> float:
        """Radial clearance [m]."""
        return self.psi * self.R

    def replace(self, **kw) -> "BearingParams":
        vals = {f.name: getattr(self, f.name) for f in dc_fields(self)}
        vals.update(kw)
        return BearingParams(**vals)


class BearingModel:
    """One journal bearing film; call order: ``initialize`` then ``step`` ...

    ``step(dt, x, y, vx, vy, omega)`` advances the film from ``t`` to ``t + dt``
    with the kinematics held constant (FMI semantics), taking internal BDF
    sub-steps with error control (mass-conserving model) or evaluating the
    quasi-static solution at the new kinematics (half-Sommerfeld). A step that
    cannot be completed raises :class:`StepFailed` and leaves the state as it
    was before the call (the caller may restore/retry with a smaller dt).
    """

    #: :meth:`get_state` returns copies the model does not keep (the FMU wrapper's state
    #: need not deep-copy them again: fmu_common.slave.get_slave_state)
    STATE_IS_COPY = True

    def __init__(self, params: BearingParams):
        if not isinstance(params, BearingParams):
            raise TypeError(f"BearingModel(params): expected BearingParams, got "
                            f"{type(params).__name__}")
        p = self.params = params
        # full grid (fields, half-Sommerfeld) and the grid the transient solver
        # works on: the lower half when n_z is even (mid-plane symmetry, grid.py)
        self.grid_full = make_grid(p.n_phi, p.n_z, p.groove_width, p.groove_angle)
        self.sym = bool(p.cavitation == 1 and p.n_z % 2 == 0)
        muscl = bool(p.cavitation == 1 and p.theta_transport == 1)   # 7-point Jacobian
        # the mass-conserving film holds the groove at its true width (grid.groove_weights);
        # grid_full (fields, the half-Sommerfeld solver and its coefficients) keeps whole columns
        true_groove = bool(p.cavitation == 1 and p.groove_width > 0)
        self.grid = (make_grid(p.n_phi, p.n_z, p.groove_width, p.groove_angle, half=self.sym,
                               wide=muscl, true_groove=true_groove)
                     if self.sym or muscl or true_groove else self.grid_full)
        self.c = p.c
        self.contact_kw = dict(c=p.c, R=p.R, B=p.B, sigma=p.sigma_rough, KE=p.contact_KE,
                               mu=p.mu_contact)
        self.a_phi = p.psi ** 2 / (6 * p.eta0)
        self.a_z = (p.R / p.B) ** 2 * self.a_phi
        self.p0 = p.p0
        self.bath = p.axial_bc == 0
        self.law = CavitationLaw(p.p0, p.cav_width, p.cav_smoothing)
        self.u_feed = float(self.law.u_from_p(p.p_feed)) if p.cavitation else 0.0
        self.hs = HalfSommerfeld(self.grid_full, self.a_phi, self.a_z, p.p0, p.p_feed)
        self.film = TransientFilm(self, linear_solver=p.linear_solver) if p.cavitation else None
        self.outputs: dict[str, float] = {}
        self._t = 0.0
        self._kin = None
        self._initialized = False
        # set by the FMU when it passes film coefficients to the rotor (linearize >= 1): the
        # blow-up message then does not advise turning interface-Jacobian coupling on
        self.linearized = False

    # ----------------------------------------------------------- helpers
    def _kinematics(self, x, y, vx, vy, omega):
        isfinite = math.isfinite
        if not (isfinite(x) and isfinite(y) and isfinite(vx) and isfinite(vy) and isfinite(omega)):
            raise ValueError(f"BearingModel: non-finite input (x, y, vx, vy, omega) = "
                             f"{(x, y, vx, vy, omega)}")
        eps = math.hypot(x, y) / self.c
        if self.params.contact:
            depth = -self.params.contact_h_limit
            lim = 1.0 + depth * self.params.sigma_rough / self.c
            if eps >= lim:
                raise StepFailed(
                    f"BearingModel: journal pressed {depth:g} sigma_rough into the shell's "
                    f"asperity layer (nominal gap below contact_h_limit = "
                    f"{self.params.contact_h_limit:g} sigma_rough): eps = {eps:.4f} >= {lim:.4f} "
                    f"(x = {x:g} m, y = {y:g} m, clearance c = {self.c:g} m, sigma_rough = "
                    f"{self.params.sigma_rough:g} m). Either the coupling step overshot the stiff "
                    "contact (set coupling.discard_retries so that the master retries with smaller "
                    "steps, or reduce the macro step) or the contact cannot carry the load (raise "
                    "contact_KE or sigma_rough, or lower contact_h_limit)")
        elif eps >= 1.0:
            where = (f"eps = {eps:.4f} (x = {x:g} m, y = {y:g} m, clearance c = {self.c:g} m)")
            cap = self._capacity_clause(float(omega))
            if self.params.eta0 < THIN_OIL_ETA0 and self._initialized:
                raise StepFailed(
                    f"BearingModel: the journal ran into the shell: {where}. The film cannot carry "
                    f"the load: eta0 = {self.params.eta0:g} Pa s is far below any oil (about 0.005 "
                    f"to 0.1 Pa s; water is 0.001); {cap}. This is not a coupling instability and "
                    "no macro step helps: give eta0 in Pa s (0.012 for 12 mPa s), and check the "
                    "clearance (psi, R) and the speed")
            if eps < 1.05:
                raise StepFailed(
                    f"BearingModel: journal touches the shell: {where} >= 1; the rotor left "
                    "the clearance: reduce the macro step or check the loads, or set contact = 1 "
                    f"(asperity contact) if the journal really reaches the shell; {cap}: if the "
                    "load on this bearing (e.g. its share of the rotor's weight) is larger, the film "
                    "cannot carry it and no macro step helps: check eta0 [Pa s], the clearance "
                    "(psi, R) and the speed")
            coupling = ("reduce the macro step (interface-Jacobian coupling is already on)"
                        if self.linearized else
                        "reduce the macro step or use interface-Jacobian coupling (linearize: 1)")
            raise StepFailed(
                f"BearingModel: journal far outside the clearance: {where}; the coupled "
                f"simulation went unstable before this step (a blow-up, not a contact): {coupling}, "
                f"and check the loads: {cap}; if the load on this bearing (e.g. its share of the "
                "rotor's weight) is larger, the film cannot carry it (check eta0 [Pa s], the "
                "clearance (psi, R) and the speed) and no macro step helps")
        return self.gap(x, y, vx, vy) + (float(omega),)

    def load_capacity(self, omega, eps=CAPACITY_EPS) -> float:
        """Static half-Sommerfeld film force [N] of this bearing with the journal at rest at
        eccentricity ``eps`` and speed ``omega`` [rad/s]: about the largest static load its film
        carries (it grows without bound only as eps -> 1). Scales as eta0 omega B R / psi^2."""
        from .linearize import hs_force       # linearize imports this module
        return float(np.hypot(*hs_force(self, 0.0, -eps * self.c, 0.0, 0.0, float(omega))))

    def _capacity_clause(self, omega: float) -> str:
        """'the film's static load capacity ... is about X N ...' for the messages of a journal
        that left the clearance (the load the film can hold at this viscosity and speed)."""
        p = self.params
        try:
            cap = f"about {self.load_capacity(omega):.3g} N"
        except Exception:       # noqa: BLE001 - a diagnosis must not hide the failure it explains
            cap = "not computable"
        return (f"the film's static load capacity at this viscosity and speed is {cap} at "
                f"eps = {CAPACITY_EPS:g} (half-Sommerfeld, eta0 = {p.eta0:g} Pa s, omega = "
                f"{omega:.4g} rad/s = {omega / (2 * math.pi):.4g} Hz, clearance c = psi R = "
                f"{p.psi:g} x {p.R:g} m, B = {p.B:g} m; it scales as eta0 omega B R / psi^2)")

    def _start_outside_message(self, x, y) -> str:
        p, eps = self.params, math.hypot(x, y) / self.c
        limit = ("eps >= 1" if not p.contact else
                 f"deeper into the shell than contact_h_limit = {p.contact_h_limit:g} sigma_rough allows")
        return (f"BearingModel.initialize: the journal starts outside the clearance: eps = {eps:.4g} "
                f"(x = {x:g} m, y = {y:g} m; clearance c = psi R = {p.psi:g} x {p.R:g} m = {self.c:g} m), "
                f"{limit}. No step has been taken: the start position is the inputs x, y at "
                "initialization, i.e. the rotor's start position (for our rotor FMUs the parameters "
                "journal_x0, journal_y0 [m], relative to the bearing centre; the turbocharger's second "
                "journal also journal_dx0_2, journal_dy0_2). Give a start inside the clearance, "
                "|(x, y)| < c, e.g. the static equilibrium or 0; lengths are in metres (a value in mm "
                "is 1000 times too large)"
                + ("; to start with the journal resting on the shell, set contact = 1 (asperity contact)"
                   if not p.contact else ""))

    def gap(self, x, y, vx, vy, grid=None):
        """(H, He, Hdot) of the film (non-dimensional, grid.Grid.gap; ``grid``: another grid
        of this bearing, e.g. ``grid_full`` for the half-Sommerfeld solver); with contact = 1
        the expected gap of the roughness (:func:`.contact.average_gap`)."""
        H, He, Hdot = (grid or self.grid).gap(x, y, vx, vy, self.c)
        if self.params.contact:
            return average_gap(H, He, Hdot, self.params.sigma_rough / self.c)
        return H, He, Hdot

    def _hs_clipped(self, kin):
        """Half-Sommerfeld pressure ``p0 + max(P, 0)`` on the full grid, (n_z, n_phi)."""
        H, He, Hdot, omega = kin
        P = self.hs.solve(H, He, Hdot, omega)
        return self.p0 + np.maximum(P, 0.0)

    def _hs_pressure(self, kin):
        """Cell pressures of the half-Sommerfeld FORCE on the full grid, (n_z, n_phi):
        equal to ``p0 + max(P, 0)`` except in the cells at the rupture/inception lines,
        where the zero crossing is located inside the cell (:func:`.film.hs_force_pressure`);
        their midpoint force (``integrals``) is ``outputs`` Fx, Fy exactly. Used by
        :func:`bearing_fmu.linearize.hs_force`; fields and p_max/p_min use the clipped
        pressure."""
        return self._hs_fields(kin)[1]

    def _hs_fields(self, kin):
        """(clipped pressure, force pressure) of the half-Sommerfeld film on the full grid:
        ``p0 + max(P, 0)`` (outputs p_max/p_min, fields, torque, flows) and the cell
        pressures of the force quadrature (:func:`.film.hs_force_pressure`)."""
        H, He, Hdot, omega = kin
        P = self.hs.solve(H, He, Hdot, omega)
        pf = np.empty_like(P)
        hs_force_pressure(P, pf)
        return self.p0 + np.maximum(P, 0.0), self.p0 + pf


    def _mirror(self, a):
        """Full-width field from the solver grid's rows (mid-plane symmetry)."""
        return np.concatenate([a, a[::-1]], axis=0) if self.sym else a

    def _update_outputs(self):
        p, th = self._pth(full=False, copy=False)
        H, He, Hdot, omega = self._kin
        prm = self.params
        sym = self.sym and self.film is not None
        g = self.grid if self.film is not None else self.grid_full
        Fx, Fy, T, qf, qs = integrals(
            p.ravel(), th.ravel(), H, He, g.groove, g.phi, omega, self.a_phi, self.a_z,
            g.dphi, g.dz, self.bath, self.p0, prm.penalty_a, prm.penalty_b,
            prm.penalty_smoothing, prm.R, prm.B, self.c, prm.eta0, sym,
            prm.theta_transport if self.film is not None else 0, g.wrel, g.frel,
            self.law.delta, self.law.K)
        if self.film is None:       # half-Sommerfeld: force with the rupture inside the cells
            Fx, Fy, *_ = integrals(
                self._pf_hs.ravel(), th.ravel(), H, He, g.groove, g.phi, omega, self.a_phi,
                self.a_z, g.dphi, g.dz, self.bath, self.p0, prm.penalty_a, prm.penalty_b,
                prm.penalty_smoothing, prm.R, prm.B, self.c, prm.eta0, sym)
        x, y = self._xy
        Fc = 0.0
        if prm.contact:             # asperity contact on top of the film (bearing_fmu/contact.py)
            cx, cy, Fc, Tc = contact_force(*self._inputs, **self.contact_kw)
            Fx, Fy, T = Fx + cx, Fy + cy, T + Tc
        e_ang = math.atan2(y, x)
        l_ang = math.atan2(-Fy, -Fx)
        att = (e_ang - l_ang + math.pi) % (2 * math.pi) - math.pi
        p_max, p_min, H_min = _extrema(p, H)
        self.outputs = dict(Fx=Fx, Fy=Fy, eps=math.hypot(x, y) / self.c, attitude=att,
                            p_max=p_max, p_min=p_min, h_min=H_min * self.c, torque=T,
                            q_feed=qf, q_side=qs, F_contact=Fc)

    def _pth(self, full=True, copy=True):
        """(p, theta); full width, or the solver grid's rows (full=False); ``copy=False``:
        the film's kept arrays where it has them (read them at once, :meth:`.p_theta`)."""
        if self.film is None:
            return self._p_hs, np.ones_like(self._p_hs)
        shape = (self.grid.n_z, self.grid.n_phi)
        p, th = self.film.p_theta(copy)
        p, th = p.reshape(shape), th.reshape(shape)
        if full:
            return self._mirror(p), self._mirror(th)
        return p, th

    def _check_init(self, what):
        if not self._initialized:
            raise RuntimeError(f"BearingModel.{what}: call initialize(x, y, vx, vy, "
                               "omega) first")

    # ----------------------------------------------------------- API
    def initialize(self, x, y, vx, vy, omega, *, init="flooded"):
        """Build the initial film at t = 0; outputs are valid afterwards.

        ``init="flooded"`` (default, a run-up from rest): theta = 1 everywhere,
        the universal variable started from the half-Sommerfeld pressure (the
        first step finds the cavity). ``init="stationary"``: the steady
        mass-conserving solution at the given kinematics (see
        :func:`solve_stationary`). Half-Sommerfeld ignores ``init``.
        """
        if init not in ("flooded", "stationary"):
            raise ValueError(f"initialize: init must be 'flooded' or 'stationary' (got {init!r})")
        try:
            kin = self._kinematics(x, y, vx, vy, omega)
        except StepFailed as exc:
            # no step has been taken: the start position itself is outside, not a blow-up
            raise StepFailed(self._start_outside_message(x, y)) from exc
        self._kin, self._t = kin, 0.0
        self._set_inputs(x, y, vx, vy, omega)
        if self.film is None:
            self._p_hs, self._pf_hs = self._hs_fields(kin)
        else:
            p = self._hs_clipped(kin)[: self.grid.n_z]
            u = self.law.u_from_p(p.ravel())
            self.film.init_state(u)
            if init == "stationary":
                self.film.init_state(self._steady(kin, u))
        self._initialized = True
        self._update_outputs()

    def step(self, dt, x, y, vx, vy, omega):
        """Advance the film by dt [s] with the kinematics held constant.

        A step that raises (StepFailed, a floating-point error, anything) leaves the model
        as it was before the call: state, inputs, time and outputs (the FMU's fmi2Discard
        relies on it, ``JournalBearing.do_step``)."""
        self._check_init("step")
        if not (dt > 0 and math.isfinite(dt)):
            raise ValueError(f"BearingModel.step: dt must be a positive finite time [s] (got {dt!r})")
        kin = self._kinematics(x, y, vx, vy, omega)
        before = (self._kin, self._inputs, self._xy, self._t, self.outputs)
        if self.film is None:
            hs_before = (self._p_hs, self._pf_hs)
        else:
            saved = self.film.get_state()
        try:
            if self.film is None:
                self._p_hs, self._pf_hs = self._hs_fields(kin)
                self._t += dt
            else:
                self.film.advance_restarting(dt, kin, saved)
                self._t = self.film.t
            self._kin = kin
            self._set_inputs(x, y, vx, vy, omega)
            self._update_outputs()
        except BaseException:
            if self.film is None:
                self._p_hs, self._pf_hs = hs_before
            else:
                self.film.set_state(saved)
            self._kin, self._inputs, self._xy, self._t, self.outputs = before
            raise

    @property
    def t(self) -> float:
        return self._t

    @property
    def stats(self) -> dict:
        """Counters: internal steps, rejected steps, Newton iterations, factorisations."""
        return dict(self.film.stats) if self.film else {}

    def get_state(self) -> dict:
        """Return the complete state as a dict of numpy arrays and floats."""
        self._check_init("get_state")
        s = dict(t=self._t, inputs=np.array(self._inputs))
        if self.film is None:
            s["p_hs"] = self._p_hs.copy()
            s["pf_hs"] = self._pf_hs.copy()
        else:
            s.update({"film_" + k: v for k, v in self.film.get_state().items()})
        return s

    def _set_inputs(self, x, y, vx, vy, omega):
        self._inputs = (float(x), float(y), float(vx), float(vy), float(omega))
        self._xy = self._inputs[:2]

    def set_state(self, s: dict):
        """Restore a state from :meth:`get_state` exactly."""
        self._check_init("set_state")
        x, y, vx, vy, omega = (float(v) for v in s["inputs"])
        self._kin = self._kinematics(x, y, vx, vy, omega)
        self._set_inputs(x, y, vx, vy, omega)
        self._t = float(s["t"])
        if self.film is None:
            self._p_hs = np.array(s["p_hs"])
            self._pf_hs = np.array(s["pf_hs"])
        else:
            self.film.set_state({k[5:]: v for k, v in s.items() if k.startswith("film_")})
        self._update_outputs()

    def fields(self) -> dict:
        """Pressure, fluid fraction and gap fields (shape (n_z, n_phi)), with the film model
        (``cavitation``: 0 half-Sommerfeld, whose theta is 1 by definition and whose ruptured
        region is where p is clipped to ``p0``; 1 mass-conserving) and ``p0`` [Pa], so that a
        reader of the fields file knows what theta means."""
        self._check_init("fields")
        p, th = self._pth()
        H = self._kin[0]
        g = self.grid_full
        return dict(phi=g.phi.copy(), z=g.zbar * self.params.B, p=p.copy(), theta=th.copy(),
                    h=np.broadcast_to(H * self.c, (g.n_z, g.n_phi)).copy(),
                    cavitation=np.int64(self.params.cavitation), p0=np.float64(self.params.p0))

    # ----------------------------------------------------------- steady
    def _steady(self, kin, u0, max_iter=40):
        """Steady mass-conserving film: Newton on the steady equations (no time
        term), falling back to pseudo-transient continuation (BDF1 with growing
        steps) when plain Newton does not converge. With Newton tolerances tighter than
        the defaults, the continuation's inner Newton steps may not reach them (flat cells,
        e.g. 40 x 160: the increments stall at rounding): then the continuation runs at the
        default tolerances and the last Newton polishes to the requested ones."""
        f = self.film
        zero = np.zeros(f.n)
        u, its = self._steady_newton(kin, u0, zero, max_iter)
        if u is not None:
            return u
        us, its = self._steady_newton(kin, self._continuation(kin, u0), zero, max_iter)
        prm = self.params
        atol0, rtol0 = (BearingParams.__dataclass_fields__[k].default
                        for k in ("newton_atol", "newton_rtol"))
        tight = prm.newton_atol < atol0 or prm.newton_rtol < rtol0
        if us is None and tight:
            self.params = prm.replace(newton_atol=max(prm.newton_atol, atol0),
                                      newton_rtol=max(prm.newton_rtol, rtol0))
            try:
                u = self._continuation(kin, u0)
            finally:
                self.params = prm
            us, its = self._steady_newton(kin, u, zero, max_iter)
        if us is None:
            hint = (f"; the Newton tolerances (newton_atol = {prm.newton_atol:g}, newton_rtol = "
                    f"{prm.newton_rtol:g}) may be below what this grid reaches: loosen them"
                    if tight else "")
            raise StepFailed("solve_stationary: steady Newton did not converge even "
                             "after pseudo-transient continuation; check the inputs "
                             "(eps < 1, a groove or oil bath feeding the film)" + hint)
        return us

    def _continuation(self, kin, u0):
        """Pseudo-transient continuation from ``u0`` (BDF1 steps growing from 0.1 / omega
        while the inner Newton converges in a few iterations) towards the steady film."""
        f = self.film
        omega = abs(kin[3]) or 1.0
        h = 0.1 / omega
        u = u0.copy()
        for _ in range(200):
            th = f.theta(u)
            f._factored = False
            un, its = f.newton(u, 1.0 / h, -th / h, kin, max_iter=20)
            if un is None:
                h *= 0.25
                continue
            change = float(np.max(np.abs(f.theta(un) - th)))
            u = un
            h *= 2.0 if its <= 6 else 1.0
            if change < 1e-8 or h * omega > 1e6:
                break
        return u

    def _steady_newton(self, kin, u0, zero, max_iter):
        """Full Newton with backtracking on the steady residual."""
        f = self.film
        prm = self.params
        u = u0.copy()
        r = f.residual(u, 0.0, zero, kin).copy()
        for it in range(max_iter):
            f._factor(u, 0.0, kin)
            r = f.residual(u, 0.0, zero, kin).copy()
            dx = f._solve(r)
            if not np.all(np.isfinite(dx)):
                return None, it
            nr0 = np.linalg.norm(r)
            lam = 1.0
            while lam > 1e-3:
                un = u + lam * dx
                rn = f.residual(un, 0.0, zero, kin)
                if np.linalg.norm(rn) < (1 - 1e-4 * lam) * nr0 or lam == 1.0 and \
                        np.max(np.abs(dx) / (prm.newton_atol + prm.newton_rtol * np.abs(u))) <= 1:
                    break
                lam *= 0.5
            u = un
            if lam == 1.0 and np.max(np.abs(dx) / (prm.newton_atol + prm.newton_rtol * np.abs(u))) <= 1:
                f._factored = False
                return u, it + 1
        f._factored = False
        return None, max_iter


@nb.njit(cache=True, nogil=True)
def _extrema(p, H):
    """(max p, min p, min H) in one call, as ``p.max(), p.min(), H.min()`` return them (nan
    when the array holds one)."""
    pmax, pmin, hmin = -np.inf, np.inf, np.inf
    for v in p.flat:
        if v != v:
            pmax = pmin = np.nan
            break
        if v > pmax:
            pmax = v
        if v < pmin:
            pmin = v
    for v in H.flat:
        if v != v:
            hmin = np.nan
            break
        if v < hmin:
            hmin = v
    return pmax, pmin, hmin


def solve_stationary(params: BearingParams, x, y, omega, vx=0.0, vy=0.0) -> BearingModel:
    """Stationary film at fixed kinematics; returns the initialised bearing.

    Mass-conserving model: Newton on the steady equations (paper section 3.1,
    "eq. 4 solved with constant kinematic input variables"), with
    pseudo-transient continuation as fallback. Half-Sommerfeld: the
    quasi-static solution. Read ``.outputs`` and ``.fields()`` of the result;
    it can also be stepped further.
    """
    b = BearingModel(params)
    b.initialize(x, y, vx, vy, omega, init="stationary")
    return b
