"""The film models of ``rotorcosim stability``: each station's bearing linearised at its static
equilibrium under its static load (module doc of :mod:`orchestrator.stability.system`), at a
given speed. Each model (:func:`film_model` chooses it) has a ``method`` (the result's words for
it), ``max_re(omega)`` (the largest real part of the rotor-bearing system's eigenvalues and |Im|
there) and ``eccentricities(omega)``; the short and half-Sommerfeld films are given by their
linear coefficients (K, C) at each station, ``__call__(omega)`` (:class:`_CoefficientFilms`).

* ``film="short"`` (:class:`_ShortFilm`): the closed-form short-bearing (Ocvirk 1952, NACA TN
  2808) pi-film coefficients (:func:`rotor_fmu.stability.short_bearing_coefficients`) of each
  bearing's R, B (length), c = psi R and eta0 - a bound for B/D not small; grooves and feed
  pressure are not in the closed form;
* ``film="hs"`` (:class:`_HSFilm`): the scenario's own finite-length half-Sommerfeld film (its R,
  B, psi, eta0, p0, p_feed, groove, grid): the equilibrium by Newton on the journal centre
  (:func:`bearing_fmu.linearize.hs_static_equilibrium`), the coefficients
  by :func:`bearing_fmu.linearize.hs_linearization` (what the FMU outputs as ``kxx .. cyy``;
  with ``contact = 1`` plus the asperity contact's force and coefficients, as the FMU adds them),
  as docs/paper_cases_radius.py does. For a mass-conserving bearing (``cavitation = 1``) these
  are the half-Sommerfeld film's coefficients (the HS linearisation), said so in the result.
* ``film="mc"`` (:class:`_MCFilm`): each mass-conserving bearing's own film linearised with its
  cavity dynamics (film impedance; docs/analysis.md, "Linear threshold of the mass-conserving
  film").

Floating-ring bearings (:class:`_RingFilms`; :func:`rotor_fmu.floating_ring_stability.ring_system_eigen`,
docs/floating-ring.md): at each speed, each ring's steady operating point under the station's
static load (its weight share plus any ``loads``, downward only; ring speed from the torque
balance of its two films, journal and ring at their static equilibria), the half-Sommerfeld
coefficients of its inner film (at the wedge speed omega + Omega) and outer film, and the ring's
translation as two more degrees of freedom per station (mass ``m_ring``). The ring spin is held
at its steady value, as the classical linear analyses do (Tatara 1970; Tanaka & Hori 1972);
``ring_spin=True`` adds each ring's spin perturbation as a first-order degree of freedom. With
``film="mc"`` (:class:`_RingMCFilm`) each ring's own mass-conserving films instead, linearised with
their cavity dynamics at the ring's mass-conserving operating point (spin held; ``ring_spin`` is
refused there). The short-bearing closed form has no ring.
"""

from __future__ import annotations

import dataclasses
import math

import numpy as np

from orchestrator.stability.system import Bearing, EigenvaluesFailed, StabilityError, System

MC_SOLVERS = ("counted", "dense")   # the --film mc eigenvalue solvers (_MCFilm)
#: largest floating-ring descriptor system (unknowns) that --film mc solves densely where the count
#: disagrees: 4 films of 40 x 40 (~3200, 1-3 min); the turbocharger's 160 x 40 (~12900) would take hours
RING_DENSE_MAX = 5000


def _short(p) -> dict:
    """The short-bearing closed form's geometry and viscosity of a bearing's BearingParams."""
    return dict(R=p.R, L=p.B, C=p.psi * p.R, eta=p.eta0)


_NUMERIC = (ValueError, ArithmeticError, np.linalg.LinAlgError)   # what an absurd parameter makes the numerics raise


def _failed(b: Bearing, omega: float | None, exc: BaseException) -> StabilityError:
    """The message of a film computation of bearing b that failed (an absurd parameter, a speed far off)."""
    p = b.params
    at = f" at {omega / (2 * math.pi):.4g} Hz" if omega is not None else ""
    return StabilityError(f"bearing '{b.instance}' (station {b.station}; R = {p.R:g} m, B = {p.B:g} m, "
                          f"c = psi R = {p.psi * p.R:g} m, eta0 = {p.eta0:g} Pa s): its film has no usable static "
                          f"equilibrium{at}: {exc or type(exc).__name__}; check these parameters (--set "
                          f"fmus.{b.instance}.parameters.NAME=VALUE) against the load, or give a --speeds LO:HI "
                          "nearer the rotor's running speeds")


class _CoefficientFilms:
    """Films given by their linear coefficients at each station, ``self(omega) -> (K, C)``
    (n_stations, 2, 2) each: the rotor's eigenvalues with them added at its stations."""

    system: System

    def max_re(self, omega: float) -> tuple[float, float]:
        """(largest real part [1/s], |Im| of that eigenvalue [rad/s]) at journal speed omega."""
        from rotor_fmu.stability import max_real_eigenvalue
        return max_real_eigenvalue(self.system.rotor, omega, self.finite_coefficients)

    def finite_coefficients(self, omega):
        """The film's (K, C) at omega, refused when not finite (NaN would read as "stable")."""
        K, C = self(omega)
        for b, k, c in zip(self.system.bearings, K, C):
            if not (np.all(np.isfinite(k)) and np.all(np.isfinite(c))):
                raise _failed(b, omega, ValueError(f"its linear coefficients are not finite (K = {k.tolist()}, "
                                                   f"C = {c.tolist()})"))
        return K, C


class _ShortFilm(_CoefficientFilms):
    """Ocvirk coefficients of each station under its static load (closed form)."""

    method = ("short-bearing (Ocvirk) pi-film closed form (rotor_fmu/stability.py), at the static equilibrium "
              "under its static load (the rotor's weight share, plus --load)")

    def __init__(self, system: System, loads: np.ndarray):
        self.loads = loads
        self.system = system

    def __call__(self, omega):
        from rotor_fmu.stability import short_bearing_coefficients
        K, C = [], []
        for b, ld in zip(self.system.bearings, self.loads):
            try:
                k, c = short_bearing_coefficients(ld, omega, **_short(b.params))
            except _NUMERIC as exc:
                raise _failed(b, omega, exc) from None
            K.append(k)
            C.append(c)
        return np.array(K), np.array(C)

    def eccentricities(self, omega):
        from rotor_fmu.stability import short_bearing_equilibrium
        out = []
        for b, ld in zip(self.system.bearings, self.loads):
            try:
                out.append(short_bearing_equilibrium(ld, omega, **_short(b.params))[0])
            except _NUMERIC as exc:
                raise _failed(b, omega, exc) from None
        return out


class _HSFilm(_CoefficientFilms):
    """Half-Sommerfeld film coefficients of each station's own bearing at its static equilibrium."""

    method = ("finite-length half-Sommerfeld film of each bearing (its parameters and grid), linearized by central "
              "differences (bearing_fmu/linearize.py hs_linearization) at the static equilibrium under the rotor's "
              "static load: the rotor's weight share, plus --load (Newton on the journal centre)")

    def __init__(self, system: System, loads: np.ndarray):
        from bearing_fmu.model import BearingModel
        self.system = system
        self.loads = loads
        self.models = []
        for b in system.bearings:
            p = dataclasses.replace(b.params, cavitation=0)
            try:
                m = BearingModel(p)
                m.initialize(0.0, -0.5 * m.c, 0.0, 0.0, 1.0)
            except _NUMERIC as exc:
                raise _failed(b, None, exc) from None
            self.models.append(m)
        self.q: list = [None] * len(self.models)

    def coefficients(self, j: int, q, omega: float):
        """(K, C) of bearing j's HS film at rest at q, plus those of the asperity contact when the
        bearing has ``contact = 1`` (bearing_fmu/contact.py; exactly 0 above 6 roughness heights),
        as ``bearing_fmu.linearize.linearization`` adds them."""
        from bearing_fmu.contact import contact_coefficients
        from bearing_fmu.linearize import hs_linearization
        m = self.models[j]
        K, C = hs_linearization(m, q[0], q[1], 0.0, 0.0, omega)
        if m.params.contact:
            Kc, Cc = contact_coefficients(q[0], q[1], 0.0, 0.0, omega, **m.contact_kw)
            K, C = K + Kc, C + Cc
        return K, C

    def equilibrium(self, j: int, omega: float) -> np.ndarray:
        """Journal centre (x, y) [m] where the bearing force equals -load
        (:func:`bearing_fmu.linearize.hs_static_equilibrium`: Newton with K = -dF/dq, the contact
        force included when the bearing has ``contact = 1``); started from the last speed's
        equilibrium, or from the short-bearing one (kept inside 0.8 c), or, without that, from
        hs_static_equilibrium's default start."""
        from bearing_fmu.linearize import HSEquilibriumError, hs_static_equilibrium
        from rotor_fmu.stability import short_bearing_equilibrium
        b, m, ld = self.system.bearings[j], self.models[j], self.loads[j]
        c = m.c
        target = -np.asarray(ld, float)
        q = self.q[j]
        if q is None:       # start from the short-bearing equilibrium (kept inside 0.8 c)
            try:
                eps, psi = short_bearing_equilibrium(ld, omega, **_short(b.params))
                q = min(eps, 0.8) * c * np.array([math.cos(psi), math.sin(psi)])
            except ValueError:          # no closed-form equilibrium (a load far off its capacity): the
                pass                    # default start, mid-gap on the load's side (also for a sideways --load)
        try:
            q = hs_static_equilibrium(m, target, omega, guess=q, max_iter=60, max_ecc=0.995)
        except HSEquilibriumError as exc:
            # a non-finite film force, or a search that ended near the centre, is a film far stiffer than
            # the load (speed, viscosity), not a speed too low (raising the lower end made it worse)
            stiff = "non-finite" in str(exc) or (exc.eps is not None and exc.eps < 0.01)
            fix = ("give a --speeds LO:HI nearer the rotor's running speeds, or check the bearing's parameters (R, B, "
                   "psi, eta0) against the load" if stiff else "raise the lower end of --speeds")
            raise StabilityError(f"bearing '{b.instance}': no half-Sommerfeld static equilibrium found at "
                                 f"{omega / (2 * math.pi):.4g} Hz under the load {np.hypot(*target):.4g} N "
                                 f"({exc}); {fix}") from None
        except _NUMERIC as exc:
            raise _failed(b, omega, exc) from None
        self.q[j] = q
        return q

    def __call__(self, omega):
        K, C = [], []
        for j in range(len(self.models)):
            q = self.equilibrium(j, omega)
            try:
                k, d = self.coefficients(j, q, omega)
            except _NUMERIC as exc:
                raise _failed(self.system.bearings[j], omega, exc) from None
            K.append(k)
            C.append(d)
        return np.array(K), np.array(C)

    def contact_share(self, omega):
        """Share of each bearing's static load carried by asperity contact at omega (0 without contact)."""
        from bearing_fmu.contact import contact_force
        out = []
        for j, m in enumerate(self.models):
            if not m.params.contact:
                out.append(0.0)
                continue
            q = self.equilibrium(j, omega)
            Fn = contact_force(q[0], q[1], 0.0, 0.0, omega, **m.contact_kw)[2]
            out.append(float(abs(Fn) / np.hypot(*self.loads[j])))
        return out

    def eccentricities(self, omega):
        return [float(np.hypot(*self.equilibrium(j, omega)) / m.c) for j, m in enumerate(self.models)]


class _RingFilms:
    """Floating-ring bearings: the rotor with each ring's translation as two more degrees of
    freedom, coupled by the half-Sommerfeld coefficients of its two films at the steady operating
    point (:func:`rotor_fmu.floating_ring_stability.ring_system_eigen`; module doc)."""

    def __init__(self, system: System, loads: np.ndarray, spin: bool = False):
        self.system, self.spin = system, spin
        self.loads = loads
        self.rings = [b.params for b in system.bearings]
        self._at: tuple[float, list] | None = None
        held = ("each ring's spin as a first-order degree of freedom (--ring-spin)" if spin else
                "the ring spin held at its steady value (classical; --ring-spin adds its perturbation)")
        self.method = ("finite-length half-Sommerfeld inner and outer films of each floating-ring bearing (their "
                       "parameters and grids), linearized by central differences (bearing_fmu/linearize.py "
                       "linearization) at the ring's steady operating point under its static load (the rotor's "
                       "weight share, plus --load; ring speed from the torque balance of its two films, journal "
                       "and ring at their static equilibria), the ring's translation as two more degrees of "
                       f"freedom per station (mass m_ring), {held} (rotor_fmu/floating_ring_stability.py)")

    def max_re(self, omega: float) -> tuple[float, float]:
        """(largest real part [1/s], |Im| of that eigenvalue [rad/s]) at journal speed omega."""
        from bearing_fmu.model import StepFailed
        from rotor_fmu.floating_ring_stability import ring_system_eigen
        try:
            with np.errstate(all="raise"):
                lam, points = ring_system_eigen(self.system.rotor, self.rings, omega, spin=self.spin,
                                                loads=self.loads)
        except (StepFailed, ArithmeticError, ValueError, RuntimeError, np.linalg.LinAlgError) as exc:
            raise StabilityError(f"no steady operating point of the floating-ring bearings at "
                                 f"{omega / (2 * math.pi):.4g} Hz ({exc}); at low speed a ring's outer film may "
                                 "not carry its load; raise the lower end of --speeds") from None
        if not np.all(np.isfinite(lam)):
            raise StabilityError(f"the floating-ring system's eigenvalues at {omega / (2 * math.pi):.4g} Hz are "
                                 "not finite (a film at the edge of its clearance); raise the lower end of --speeds")
        self._at = (omega, points)
        from rotor_fmu.stability import rightmost
        return rightmost(lam)     # a real part within rounding of zero is no crossing

    def points(self, omega: float) -> list:
        """Each station's FloatingRing model at its steady operating point at omega."""
        if self._at is None or self._at[0] != omega:
            self.max_re(omega)
        return self._at[1]

    def eccentricities(self, omega):
        return [float(p.outputs["eps"]) for p in self.points(omega)]


def _mc_eigenvalues(fm, rotor, omega: float, films: list, dense_max: int | None = None):
    """The eigenvalues of ``rotor`` with the mass-conserving ``films`` by ``fm.solver`` (an
    :class:`_MCFilm` or :class:`_RingMCFilm`): all by dense QZ, or the least-damped ones counted
    (:func:`rotor_fmu.film_system.rightmost`, from ``fm._hint``; a speed it left to the dense solve
    is listed in ``fm.dense_speeds``); None when that dense solve would exceed ``dense_max`` unknowns."""
    if fm.solver == "dense":
        from rotor_fmu.film_system import eigenvalues_dense
        return eigenvalues_dense(rotor, omega, films)
    from rotor_fmu.film_system import rightmost
    found = rightmost(rotor, omega, films, hint=fm._hint, dense_max=dense_max)
    if found.method == "unresolved":
        return None
    if found.method == "dense":
        fm.dense_speeds.append(omega)
    return found.eigenvalues


def _least_damped(fm, lam) -> tuple[float, float]:
    """(real part, |imaginary part|) of the least-damped of ``lam``, kept in ``fm._hint`` (where
    the next speed's search starts)."""
    k = int(np.argmax(lam.real))
    fm._hint = (lam[k],)
    return float(lam.real[k]), float(abs(lam.imag[k]))


class _MCFilm:
    """Each station's own mass-conserving film, linearised about its steady state with its cavity
    (theta) dynamics: the rotor and the films as one descriptor system, its least-damped eigenvalue
    by sparse shift-invert Arnoldi counted by the argument principle (:func:`rotor_fmu.film_system.rightmost`,
    ``solver="counted"``) or from all eigenvalues by dense QZ (``solver="dense"``,
    :func:`rotor_fmu.stability.film_system_eigenvalues`, the reference); :class:`bearing_fmu.linearize.MCFilmLinear`;
    docs/analysis.md, "Linear threshold of the mass-conserving film")."""

    def __init__(self, system: System, loads: np.ndarray, solver: str = "counted"):
        from bearing_fmu.model import BearingModel
        plain = [b.instance for b in system.bearings if b.params.cavitation != 1]
        if plain:
            raise StabilityError(f"--film mc linearises a mass-conserving film (cavitation = 1), but the bearing "
                                 f"'{plain[0]}' is half-Sommerfeld (cavitation = 0): use --film hs")
        if solver not in MC_SOLVERS:
            raise StabilityError(f"the mass-conserving film's eigenvalue solver must be one of "
                                 f"{', '.join(MC_SOLVERS)} (got {solver!r})")
        self.system, self.loads, self.solver = system, loads, solver
        self.models = [BearingModel(b.params) for b in system.bearings]
        self.q: list = [None] * len(self.models)
        self._at: tuple[float, list] | None = None
        self._hint: tuple = ()
        self.dense_speeds: list[float] = []      # speeds the counted solver left to the dense one
        self.method = ("bearing's own mass-conserving film at each station (its parameters and grid) linearised "
                       "about its steady state with its cavity (theta) dynamics, i.e. its film impedance Z(s) "
                       "(bearing_fmu/linearize.py MCFilmLinear), at the static equilibrium of the steady film under "
                       "its static load; the least-damped eigenvalues of the rotor and films as one descriptor "
                       "system (" + ("sparse shift-invert Arnoldi, all of them right of a line just left of the "
                                     "least-damped one counted by the argument principle on det(s^2 M + s C + K + "
                                     "sum P^T Z(s) P), rotor_fmu/film_system.py rightmost)" if solver == "counted" else
                                     "all finite eigenvalues by dense QZ, rotor_fmu/stability.py "
                                     "film_system_eigenvalues)"))

    def _films(self, omega: float) -> list:
        """Each station's MCFilmLinear at its equilibrium at omega (the last speed's kept); a station
        whose bearing and static load equal an earlier one's (a symmetric rotor) shares its film."""
        from bearing_fmu.linearize import HSEquilibriumError, mc_static_equilibrium
        from bearing_fmu.model import StepFailed
        from rotor_fmu.stability import short_bearing_equilibrium
        if self._at is not None and self._at[0] == omega:
            return self._at[1]
        films = []
        for j, (b, m, ld) in enumerate(zip(self.system.bearings, self.models, self.loads)):
            same = next((k for k in range(j) if self.system.bearings[k].params == b.params
                         and np.array_equal(self.loads[k], ld)), None)
            if same is not None:
                self.q[j] = self.q[same]
                films.append(films[same])
                continue
            guess = self.q[j]
            if guess is None:           # the short-bearing equilibrium, kept inside 0.8 c
                try:
                    eps, psi = short_bearing_equilibrium(ld, omega, **_short(b.params))
                except (ArithmeticError, ValueError):
                    eps, psi = 0.5, math.atan2(-ld[1], -ld[0]) + math.pi / 4
                guess = min(eps, 0.8) * m.c * np.array([math.cos(psi), math.sin(psi)])
            try:
                with np.errstate(all="ignore"):
                    q, lin = mc_static_equilibrium(m, -np.asarray(ld, float), omega, guess=guess)
            except (HSEquilibriumError, StepFailed, ArithmeticError, ValueError, RuntimeError,
                    np.linalg.LinAlgError) as exc:
                raise _failed(b, omega, exc) from None
            self.q[j] = q
            films.append(lin)
        self._at = (omega, films)
        return films

    def max_re(self, omega: float) -> tuple[float, float]:
        return _least_damped(self, _mc_eigenvalues(self, self.system.rotor, omega, self._films(omega)))

    def eccentricities(self, omega):
        self._films(omega)
        return [float(np.hypot(*q) / m.c) for q, m in zip(self.q, self.models)]


class _RingMCFilm:
    """Floating-ring bearings with their own mass-conserving films (``film="mc"``): at each speed
    each ring's steady operating point with its two steady mass-conserving films (ring speed from
    the torque balance of their wall shear, :class:`rotor_fmu.floating_ring_stability.MCRingStation`),
    each film linearised there with its cavity dynamics (:class:`bearing_fmu.linearize.MCFilmLinear`:
    the inner film on the journal's motion relative to the ring, the outer on the ring's), the
    ring's translation as two more degrees of freedom (mass ``m_ring``), its spin held; the rotor,
    rings and films as one descriptor system (:class:`rotor_fmu.floating_ring_stability.RingRotor`)
    solved as :class:`_MCFilm` does (counted or dense). A speed whose operating point fails from the
    warm start a station holds is computed by continuation in the speed from the nearest speed it
    converged at (:meth:`points`, :meth:`max_re_continued`: the search's pass over the speeds its
    scan left out)."""

    def __init__(self, system: System, loads: np.ndarray, solver: str = "counted"):
        from rotor_fmu.floating_ring_stability import MCRingStation, RingRotor
        for b in system.bearings:
            hs = [side for side in ("inner", "outer") if getattr(b.params, side).cavitation != 1]
            if hs:
                raise StabilityError(f"--film mc linearises mass-conserving films (cavitation = 1), but in the "
                                     f"floating-ring bearing '{b.instance}' the {' and '.join(hs)} film"
                                     f"{'s are' if len(hs) > 1 else ' is'} half-Sommerfeld ("
                                     + ", ".join(f"cavitation_{x} = 0" for x in hs) + "): use --film hs, or set "
                                     + " and ".join(f"fmus.{b.instance}.parameters.cavitation_{x}=1" for x in hs))
        if solver not in MC_SOLVERS:
            raise StabilityError(f"the mass-conserving film's eigenvalue solver must be one of "
                                 f"{', '.join(MC_SOLVERS)} (got {solver!r})")
        self.system, self.loads, self.solver = system, loads, solver
        self.stations = [MCRingStation(b.params) for b in system.bearings]
        self.rotor = RingRotor(system.rotor, [b.params.m_ring for b in system.bearings])
        self._at: tuple[float, list] | None = None
        self._hint: tuple = ()
        self._roots: dict[float, tuple] = {}      # speed [rad/s] -> its least-damped root (as _hint)
        self.dense_speeds: list[float] = []
        self.method = ("own mass-conserving inner and outer films of each floating-ring bearing (their parameters "
                       "and grids) linearised about their steady states with their cavity (theta) dynamics, i.e. "
                       "their film impedances (bearing_fmu/linearize.py MCFilmLinear; the inner film on the journal's "
                       "motion relative to the ring, the outer on the ring's), at the ring's steady operating point "
                       "under its static load (the rotor's weight share, plus --load; each film at its "
                       "mass-conserving static equilibrium, the ring speed from the torque balance of the two films' "
                       "wall shear, rotor_fmu/floating_ring_stability.py MCRingStation), the ring's translation as "
                       "two more degrees of freedom per station (mass m_ring), the ring spin held at its steady "
                       "value; the least-damped eigenvalues of the rotor, rings and films as one descriptor system ("
                       + ("sparse shift-invert Arnoldi, counted by the argument principle, rotor_fmu/film_system.py "
                          "rightmost)" if solver == "counted" else
                          "all finite eigenvalues by dense QZ, rotor_fmu/film_system.py eigenvalues_dense)"))

    def points(self, omega: float, *, continued: bool = False) -> list:
        """Each station's :class:`~rotor_fmu.floating_ring_stability.MCRingPoint` at omega: from the
        warm start each station holds (the last speed's); where that fails and another speed's
        operating point is known, by continuation in the speed from the nearest such speed
        (:meth:`~rotor_fmu.floating_ring_stability.MCRingStation.continued`). ``continued``: by that
        continuation at once (a speed that failed before, :meth:`max_re_continued`)."""
        from rotor_fmu.floating_ring_stability import _point_errors
        if self._at is not None and self._at[0] == omega:
            return self._at[1]
        pts = []
        for b, st, ld in zip(self.system.bearings, self.stations, self.loads):
            try:
                pts.append(st.continued(ld, omega) if continued else st.point(ld, omega))
                continue
            except _point_errors() as exc:
                why = (("none from the warm start of the scan there; " if continued else "")
                       + (str(exc) or type(exc).__name__))
                if continued or not st.converged:
                    raise self._no_point(b, omega, why) from None
            try:
                pts.append(st.continued(ld, omega))
            except _point_errors() as exc:
                raise self._no_point(b, omega, f"{why}; {exc}") from None
        self._at = (omega, pts)
        return pts

    @staticmethod
    def _no_point(b: Bearing, omega: float, why: str) -> StabilityError:
        return StabilityError(f"floating-ring bearing '{b.instance}': no steady operating point of its mass-conserving "
                              f"films at {omega / (2 * math.pi):.4g} Hz ({why}); at low speed a ring's outer film may "
                              "not carry its load: raise the lower end of --speeds")

    def max_re(self, omega: float, *, continued: bool = False) -> tuple[float, float]:
        from rotor_fmu.floating_ring_stability import mc_ring_films
        films = mc_ring_films(self.points(omega, continued=continued))
        lam = _mc_eigenvalues(self, self.rotor, omega, films, dense_max=RING_DENSE_MAX)
        if lam is None:
            size = 2 * self.rotor.n_dof + sum(f.Js.shape[0] for f in films)
            raise EigenvaluesFailed(f"at {omega / (2 * math.pi):.4g} Hz the argument-principle count disagreed with "
                                 f"the eigenvalues the Arnoldi runs found, and the dense solve of the {size} "
                                 f"unknowns would take hours (above {RING_DENSE_MAX}): the speed is left out; "
                                 "coarser ring films (--set fmus.BEARING.parameters.n_phi_inner=..., n_z_inner, "
                                 "n_phi_outer, n_z_outer) make it solvable")
        if not (lam.size and np.all(np.isfinite(lam))):
            raise StabilityError(f"the floating-ring system's eigenvalues at {omega / (2 * math.pi):.4g} Hz are "
                                 "not finite (a film at the edge of its clearance); raise the lower end of --speeds")
        out = _least_damped(self, lam)
        self._roots[omega] = self._hint
        return out

    def max_re_continued(self, omega: float) -> tuple[float, float]:
        """:meth:`max_re` at a speed where it failed (the search's second pass, once neighbouring
        speeds are done): each ring's operating point by continuation from its nearest converged
        speed, the eigenvalue search started from the least-damped root of the nearest speed done.
        The warm start of the next :meth:`max_re` (each station's films and guesses, the root it
        starts from) is left as it was, so that the speeds computed after this call are computed as
        without it."""
        held = [(st.inner, st.outer, st.qi, st.qo, st.ratio) for st in self.stations], self._hint
        if self._roots:
            self._hint = self._roots[min(self._roots, key=lambda w: (abs(w - omega), w))]
        try:
            return self.max_re(omega, continued=True)
        finally:
            for st, (inner, outer, qi, qo, ratio) in zip(self.stations, held[0]):
                st.inner, st.outer, st.qi, st.qo, st.ratio = inner, outer, qi, qo, ratio
            self._hint = held[1]

    def eccentricities(self, omega):
        return [p.outputs["eps"] for p in self.points(omega)]


def film_model(system: System, film: str, loads: np.ndarray, *, ring_spin: bool = False,
               mc_solver: str = "counted"):
    """The film model of ``film`` (one of ``"short"``, ``"hs"``, ``"mc"``; floating rings: their
    half-Sommerfeld films, ``ring_spin`` as :class:`_RingFilms`, or with ``"mc"`` their own
    mass-conserving films, :class:`_RingMCFilm`; ``mc_solver`` as :class:`_MCFilm`)
    for the system's bearings under their static ``loads`` (n_stations, 2) [N]."""
    if system.rings:
        if film == "mc":
            return _RingMCFilm(system, loads, mc_solver)
        return _RingFilms(system, loads, spin=ring_spin)
    if film == "mc":
        return _MCFilm(system, loads, mc_solver)
    return _ShortFilm(system, loads) if film == "short" else _HSFilm(system, loads)
