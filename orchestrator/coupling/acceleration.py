"""Fixed-point acceleration of the coupling iteration: plain, Aitken, IQN-ILS.

The iterative coupling scheme and the initial exchange solve a fixed-point
problem ``x = G(x)`` on the vector ``x`` of interface values (every coupling
signal at the end of the macro step, resp. at t0): one evaluation of ``G`` is
one pass of the subsystems from the saved states with inputs built from ``x``.
An :class:`Acceleration` turns the pair ``(x_k, G(x_k))`` into the next iterate.

Call order (rules for implementers)::

    acc.start(scale)                 # once per fixed-point problem (macro step)
    x = x0
    for k in range(max_iterations):
        g = G(x)
        if converged(x, g): break    # decided by the caller (solve_fixed_point)
        x = acc.update(x, g)         # must not modify x or g
    acc.finish()                     # problem solved or abandoned

``scale`` (positive, one entry per signal) makes the signals comparable: the
least-squares problem of IQN-ILS and the Aitken factor are computed on
``x / scale`` (preCICE's "value" preconditioner), so a force in kN and a
displacement in um weigh alike.

Methods
-------
* :class:`FixedPoint`: ``x_{k+1} = x_k + omega (G(x_k) - x_k)`` (omega = 1: plain
  Gauss-Seidel / Picard iteration). Converges linearly at the spectral radius
  of the (relaxed) iteration map; diverges for a stiff coupling.
* :class:`Aitken`: dynamic relaxation, Irons & Tuck (1969), in the vector form
  of Kuettler & Wall, "Fixed-point fluid-structure interaction solvers with
  dynamic relaxation", Comput. Mech. 43 (2008) 61-72, eq. (44):
  ``omega_k = -omega_{k-1} r_{k-1}.(r_k - r_{k-1}) / |r_k - r_{k-1}|^2``.
  Exact in two updates for a scalar linear map, whatever its slope.
* :class:`IQNILS`: interface quasi-Newton with an inverse Jacobian from a least-
  squares model, Degroote, Bathe & Vierendeels, "Performance of a new
  partitioned procedure versus a monolithic procedure in fluid-structure
  interaction", Comput. Struct. 87 (2009) 793-801, sec. 3; as implemented in
  preCICE (Uekermann, "Partitioned fluid-structure interaction on massively
  parallel systems", PhD thesis TU Munich 2016, ch. 3): with residuals
  ``r_k = G(x_k) - x_k``, ``V = [r_k - r_{k-1}, ...]``, ``W = [G_k - G_{k-1}, ...]``,
  ``alpha = argmin |V alpha + r_k|`` (QR), ``x_{k+1} = G(x_k) + W alpha``. The
  QR2 filter of Haelterman et al., "Improving the performance of the
  partitioned QN-ILS procedure for fluid-structure interaction problems:
  filtering", Comput. Struct. 171 (2016) 9-17, drops columns that are nearly
  linearly dependent. For a linear map of dimension n it reaches the fixed point
  after at most n + 1 evaluations (secant property), stiff or not.
"""

from __future__ import annotations

import math
from abc import ABC, abstractmethod
from dataclasses import dataclass
from typing import Callable

import numpy as np

from orchestrator.scenario.model import ACCELERATIONS

INITIAL_RELAXATION = 0.5     # first update of Aitken and IQN-ILS (no secant information yet)
MAX_BACKTRACKS = 8           # refused iterates per fixed-point problem, each halving the last update


class PassRejected(Exception):
    """Raised by ``G`` when a subsystem refused the iterate (an FMU discarded the pass, e.g. a
    quasi-Newton update that put a journal outside its bearing): :func:`solve_fixed_point` then
    backtracks towards the last iterate that was evaluated. ``error`` is raised if it cannot."""

    def __init__(self, error: Exception):
        super().__init__(str(error))
        self.error = error


class Acceleration(ABC):
    """Turns ``(x_k, G(x_k))`` into ``x_{k+1}`` (call order in the module docstring)."""

    name = ""

    def start(self, scale: np.ndarray) -> None:
        """Begin a new fixed-point problem; ``scale`` > 0 per signal."""
        self.scale = np.asarray(scale, dtype=float)

    @abstractmethod
    def update(self, x: np.ndarray, g: np.ndarray) -> np.ndarray:
        """The next iterate (a new array)."""

    def finish(self) -> None:
        """The problem is over (converged or abandoned)."""


class FixedPoint(Acceleration):
    """Relaxed fixed-point iteration ``x + omega (g - x)``."""

    name = "none"

    def __init__(self, relaxation: float = 1.0):
        if not 0.0 < relaxation <= 1.0:
            raise ValueError(f"relaxation must be in (0, 1] (got {relaxation!r})")
        self.relaxation = float(relaxation)

    def update(self, x, g):
        if self.relaxation == 1.0:
            return np.array(g, dtype=float)
        return x + self.relaxation * (g - x)


class Aitken(Acceleration):
    """Aitken dynamic relaxation (Irons & Tuck 1969; Kuettler & Wall 2008, eq. 44)."""

    name = "aitken"

    def __init__(self, initial_relaxation: float = INITIAL_RELAXATION):
        self.initial_relaxation = float(initial_relaxation)
        self._r_old = None
        self.omega = self.initial_relaxation

    def start(self, scale):
        super().start(scale)
        self._r_old = None
        self.omega = self.initial_relaxation

    def update(self, x, g):
        r = (g - x) / self.scale
        if self._r_old is not None:
            d = r - self._r_old
            dd = float(d @ d)
            if dd > 0.0:
                self.omega = -self.omega * float(self._r_old @ d) / dd
        self._r_old = r
        return x + self.omega * (g - x)


class IQNILS(Acceleration):
    """Interface quasi-Newton, inverse Jacobian by least squares (Degroote et al. 2009).

    Parameters
    ----------
    reuse : columns of this many previous fixed-point problems (macro steps) are
        kept (preCICE's ``time-windows-reused``); 0 starts every step afresh.
    filter_eps : QR2 filter threshold (Haelterman et al. 2016): a column whose
        new orthogonal part is below ``filter_eps`` times its norm is dropped.
    """

    name = "iqn-ils"

    def __init__(self, *, initial_relaxation: float = INITIAL_RELAXATION, reuse: int = 0,
                 filter_eps: float = 1e-10):
        self.initial_relaxation = float(initial_relaxation)
        self.reuse = int(reuse)
        self.filter_eps = float(filter_eps)
        self._old: list[tuple[np.ndarray, np.ndarray]] = []     # columns of previous problems
        self._V: list[np.ndarray] = []
        self._W: list[np.ndarray] = []
        self._prev = None

    def start(self, scale):
        super().start(scale)
        self._V, self._W, self._prev = [], [], None

    def update(self, x, g):
        r = g - x
        if self._prev is not None:
            r_old, g_old = self._prev
            self._V.insert(0, r - r_old)
            self._W.insert(0, g - g_old)
        self._prev = (r, np.array(g, dtype=float))
        V, W = self._columns(len(r))
        if V is None:
            return x + self.initial_relaxation * (g - x)
        s = self.scale[:, None]
        alpha = self._least_squares(V / s, -r / self.scale)
        return g + W @ alpha

    def finish(self):
        if self.reuse > 0 and self._V:
            self._old.insert(0, (np.array(self._V).T, np.array(self._W).T))
            del self._old[self.reuse:]
        self._V, self._W, self._prev = [], [], None

    def _columns(self, n: int):
        """V, W of this problem (newest first) and of the reused ones, filtered (QR2) on the
        scaled columns; returned unscaled (columns are stored in the signals' units, so
        reused ones stay valid when the scale changes)."""
        vs = list(self._V)
        ws = list(self._W)
        for Vo, Wo in self._old:
            vs += list(Vo.T)
            ws += list(Wo.T)
        if not vs:
            return None, None
        keep_v, keep_w, basis = [], [], []
        for v_phys, w in zip(vs, ws):
            v = v_phys / self.scale
            nv = math.sqrt(float(v @ v))
            if nv == 0.0 or len(basis) >= n:
                continue
            q = v.copy()
            for b in basis:                      # modified Gram-Schmidt, twice for stability
                q -= (b @ q) * b
            for b in basis:
                q -= (b @ q) * b
            nq = math.sqrt(float(q @ q))
            if nq < self.filter_eps * nv:       # QR2 filter: (nearly) dependent column
                continue
            basis.append(q / nq)
            keep_v.append(v_phys)
            keep_w.append(w)
        if not keep_v:
            return None, None
        return np.array(keep_v).T, np.array(keep_w).T

    @staticmethod
    def _least_squares(V: np.ndarray, b: np.ndarray) -> np.ndarray:
        Q, R = np.linalg.qr(V)
        return np.linalg.solve(R, Q.T @ b)


def make_acceleration(name: str) -> Acceleration:
    """The object for ``coupling.iteration.acceleration`` (strings become classes once, here)."""
    if name == "none":
        return FixedPoint()
    if name == "aitken":
        return Aitken()
    if name == "iqn-ils":
        return IQNILS()
    raise ValueError(f"acceleration must be one of {list(ACCELERATIONS)} (got {name!r})")


@dataclass(frozen=True)
class FixedPointResult:
    """Outcome of :func:`solve_fixed_point`.

    ``x`` is the last evaluation ``G(x_k)`` (consistent with the subsystems'
    states after the last pass), ``iterations`` the number of evaluations of
    ``G``, ``residual`` the largest scaled ``|G(x_k) - x_k| / scale`` of the
    last one, ``worst`` the index of the signal where it occurs.
    """

    x: np.ndarray
    iterations: int
    converged: bool
    residual: float
    worst: int


def scaled_residual(x: np.ndarray, g: np.ndarray, scale: np.ndarray) -> tuple[float, int]:
    """Largest ``|g - x| / scale`` and where (inf for a non-finite entry)."""
    e = np.abs(g - x) / scale
    if not np.all(np.isfinite(e)):
        i = int(np.flatnonzero(~np.isfinite(e))[0])
        return math.inf, i
    i = int(np.argmax(e)) if len(e) else 0
    return (float(e[i]) if len(e) else 0.0), i


def solve_fixed_point(G: Callable[[np.ndarray], np.ndarray], x0: np.ndarray, *, acceleration: Acceleration,
                      tol: float, scale: np.ndarray, max_iterations: int) -> FixedPointResult:
    """Iterate ``x = G(x)`` from ``x0`` until ``max_i |G(x)_i - x_i| / scale_i <= tol``.

    ``scale_i`` is the largest of the given ``scale[i]`` and every ``|x_i|``,
    ``|G(x)_i|`` seen so far (a signal's scale is the largest magnitude it has
    had), so a signal converging to 0 is judged against its own size, not
    against 0. The acceleration works on the scale after the first evaluation
    (entries still 0 there count as 1). At most ``max_iterations`` evaluations of
    ``G``; a non-finite residual stops the iteration at once (not converged).

    ``G`` may raise :class:`PassRejected` for an iterate a subsystem refused: the next
    evaluation is at ``x_last + (x - x_last) / 2`` (``x_last`` the last evaluated iterate;
    a backtracking line search on the update, Dennis & Schnabel, "Numerical methods for
    unconstrained optimization and nonlinear equations", SIAM 1996, sec. 6.3), at most
    ``MAX_BACKTRACKS`` times per problem and counted in ``max_iterations``; the first
    iterate (nothing to go back to) or one refusal too many raises ``PassRejected.error``.
    """
    x = np.array(x0, dtype=float)
    sc = np.maximum(np.abs(np.asarray(scale, dtype=float)), np.abs(x))
    res, worst, g = math.inf, 0, x
    started = False
    x_last, backtracks = None, 0
    try:
        for k in range(1, max_iterations + 1):
            try:
                g = np.array(G(x), dtype=float)
            except PassRejected as e:
                if x_last is None or backtracks >= MAX_BACKTRACKS or k == max_iterations:
                    raise e.error from None
                backtracks += 1
                x = x_last + 0.5 * (x - x_last)
                continue
            x_last = x
            with np.errstate(invalid="ignore"):
                sc = np.fmax(sc, np.abs(g))
            res, worst = scaled_residual(x, g, np.where(sc > 0.0, sc, 1.0))
            if res <= tol:
                return FixedPointResult(g, k, True, res, worst)
            if not math.isfinite(res) or k == max_iterations:
                return FixedPointResult(g, k, False, res, worst)
            if not started:
                acceleration.start(np.where(sc > 0.0, sc, 1.0))
                started = True
            x = acceleration.update(x, g)
    finally:
        if started:
            acceleration.finish()
    return FixedPointResult(g, max_iterations, False, res, worst)    # max_iterations < 1
