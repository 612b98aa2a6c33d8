"""Coupling signals: macro-step history and Lagrange extrapolation/interpolation.

Notation: macro step n goes from T(n) to T(n+1) = T(n) + H(n); inside it the
normalised time is s = (t - T(n)) / H(n) in [0, 1].

* Extrapolation of order k: the Lagrange polynomial through the last k+1
  macro-step values y(T(n)), y(T(n-1)), ..., y(T(n-k)) (fewer at start-up:
  order min(k, available - 1)), evaluated for s in [0, 1].
* Interpolation of order q (Gauss-Seidel, for a signal whose new value
  y(T(n+1)) is already known): the polynomial through y(T(n+1)), y(T(n)), ...,
  y(T(n+1-q)) (q limited by the history available).

Both reproduce polynomials of degree <= order exactly (tests check this). The
global coupling error of an explicit scheme with extrapolation order k is
O(H^(k+1)) when the coupling error dominates (see docs/coupling.md).

:class:`History` keeps, for every registered signal block, the values at the
levels ``[T(n+1) (new, being filled), T(n), T(n-1), ...]`` as rows of one
array per block, so that weights times rows is one ``np.dot`` with no
allocation. The master owns the history and rolls it back with
:meth:`History.snapshot` / :meth:`History.restore`.
"""

from __future__ import annotations

import math
from typing import Sequence

import numpy as np

from orchestrator.scenario.model import MAX_ORDER


def lagrange_weights(nodes: Sequence[float], x: Sequence[float]) -> np.ndarray:
    """Weights ``W[i, j]`` with ``p(x[i]) = sum_j W[i, j] * y[j]`` for the
    Lagrange polynomial through ``(nodes[j], y[j])``."""
    nodes = np.asarray(nodes, dtype=float)
    x = np.atleast_1d(np.asarray(x, dtype=float))
    m = len(nodes)
    W = np.ones((len(x), m))
    for j in range(m):
        for l in range(m):
            if l != j:
                W[:, j] *= (x - nodes[l]) / (nodes[j] - nodes[l])
    return W


def lagrange_derivative_weights(nodes: Sequence[float], x0: float, max_order: int) -> np.ndarray:
    """``D[d-1, j]``: weights of the d-th derivative (d = 1..max_order) at ``x0``
    of the Lagrange polynomial through ``nodes`` (derivatives above its degree are 0)."""
    nodes = np.asarray(nodes, dtype=float)
    m = len(nodes)
    # monomial coefficients in (x - x0): V c = y  ->  c = V^-1 y ; d-th derivative = d! c_d
    V = np.vander(nodes - x0, m, increasing=True)
    Vinv = np.linalg.inv(V)
    D = np.zeros((max_order, m))
    for d in range(1, max_order + 1):
        if d < m:
            D[d - 1] = math.factorial(d) * Vinv[d]
    return D


class History:
    """Macro-step history of coupling signals, shared time levels.

    ``times[0]`` is T(n+1) of the step being computed, ``times[1]`` = T(n), ...;
    ``count`` is how many past levels (rows 1..count) hold valid values.
    Blocks are 2-D arrays ``(depth + 1, n_signals)``, row 0 being the new level.
    """

    def __init__(self, depth: int = MAX_ORDER + 1):
        self.depth = depth
        self.times = np.full(depth + 1, np.nan)
        self.count = 0
        self.blocks: list[np.ndarray] = []
        self._store: np.ndarray | None = None      # one array for all blocks (see allocate)

    def block(self, n_signals: int) -> np.ndarray:
        """A new stand-alone block (for few blocks; the master uses :meth:`allocate`)."""
        if self._store is not None:
            raise RuntimeError("History.block() after allocate(); reserve every block in allocate()")
        b = np.zeros((self.depth + 1, n_signals))
        self.blocks.append(b)
        return b

    def allocate(self, sizes: Sequence[int]) -> list[np.ndarray]:
        """Blocks of ``sizes`` columns as column views of one array, so that
        :meth:`commit` shifts all signals with one copy."""
        if self.blocks:
            raise RuntimeError("History.allocate() must be called once, before any block()")
        self._store = np.zeros((self.depth + 1, int(sum(sizes))))
        start = 0
        for n in sizes:
            self.blocks.append(self._store[:, start:start + n])
            start += n
        return list(self.blocks)

    @property
    def store(self) -> np.ndarray:
        """The one array behind every block (after :meth:`allocate`): row 0 is the level being
        filled, i.e. every coupling signal at T(n+1) side by side (the iterative scheme's
        interface vector)."""
        if self._store is None:
            raise RuntimeError("History.store needs allocate()")
        return self._store

    def start(self, t0: float) -> None:
        """Declare row 0 of every block as the values at ``t0`` and make it level 1."""
        self.times[:] = np.nan
        self.times[0] = t0
        self.count = 0
        self.commit()

    def commit(self) -> None:
        """Row 0 (level T(n+1), filled by the master) becomes the newest past level."""
        if self._store is not None:
            self._store[1:] = self._store[:-1]
        else:
            for b in self.blocks:
                b[1:] = b[:-1]
        self.times[1:] = self.times[:-1]
        self.count = min(self.count + 1, self.depth)

    def snapshot(self):
        return (self.times.copy(), self.count, [b.copy() for b in self.blocks])

    def restore(self, snap) -> None:
        times, count, blocks = snap
        self.times[:] = times
        self.count = count
        for b, s in zip(self.blocks, blocks):
            b[:] = s


class StepWeights:
    """Lagrange weights for one macro step, computed once and shared by all subsystems.

    Attributes (``None`` if not requested):

    ``extrap`` (n_samples, p+1) and ``interp`` (n_samples, q+1): value weights
    at the sub-step midpoints, applied to the history rows ``e0..e1-1``
    (normally ``1..p+1``) resp. ``0..q``; ``extrap_end`` / ``interp_end``:
    the same at s = 1; ``extrap_der`` (n_starts, kmax, p+1) and
    ``interp_der``: time-derivative weights (1/s^d units) at the sub-step
    starts, for subsystems that interpolate inputs themselves.
    """

    __slots__ = ("p", "q", "e0", "e1", "end_same_e", "end_same_i", "extrap", "interp", "extrap_end", "interp_end", "extrap_der", "interp_der",
                 "extrap_start", "interp_start")


class LagrangePredictor:
    """Computes (and caches: the one weight cache of the master) :class:`StepWeights`.

    Parameters
    ----------
    extrapolation_order, interpolation_order : 0..3.
    """

    def __init__(self, *, extrapolation_order: int, interpolation_order: int):
        for nm, k in (("extrapolation_order", extrapolation_order), ("interpolation_order", interpolation_order)):
            if not (isinstance(k, int) and 0 <= k <= MAX_ORDER):
                raise ValueError(f"{nm} must be an integer in 0..{MAX_ORDER} (got {k!r})")
        self.k = extrapolation_order
        self.q = interpolation_order
        self._cache: dict = {}
        self._step_key = None          # (count, q, d0..d3) of the step whose weights _step_weights holds
        self._step_weights: dict = {}  # substeps -> StepWeights of that step

    def step_weights(self, history: History, t_n: float, h: float, substeps: int, *,
                     q: int | None = None) -> StepWeights:
        """:meth:`weights` for the master's hot path: while the available order and the sizes of
        the history's last steps are unchanged (constant steps), the weights of the previous
        macro step are returned without building a cache key (``q`` given: the start-up
        iteration, all inputs interpolated)."""
        ts = history.times.tolist()
        d = (ts[0] - ts[1], ts[1] - ts[2], ts[2] - ts[3], ts[3] - ts[4])
        lk = self._step_key
        if (lk is not None and lk[0] == history.count and lk[1] == q
                and abs(d[0] - lk[2]) + abs(d[1] - lk[3]) + abs(d[2] - lk[4]) + abs(d[3] - lk[5]) <= 1e-9 * h):
            cache = self._step_weights
        else:
            cache = self._step_weights = {}
            self._step_key = (history.count, q, *d)
        w = cache.get(substeps)
        if w is None:
            w = cache[substeps] = self.weights(history, t_n, h, substeps, q=q, all_interp=q is not None)
        return w

    def weights(self, history: History, t_n: float, h: float, substeps: int, *, q: int | None = None,
                all_interp: bool = False) -> StepWeights:
        """Weights for the step [t_n, t_n + h] with ``substeps`` sub-steps.

        Held-input sub-steps use the polynomial at sub-step midpoints
        ``s = (i + 1/2) / substeps`` (second-order accurate hold, see
        docs/coupling.md); derivative-capable subsystems get value and
        derivatives at sub-step starts ``s = i / substeps``.
        """
        count = history.count
        p = min(self.k, count - 1)
        q = min(self.q if q is None else q, count)
        past = (history.times[1:count + 1] - t_n) / h          # 0, -1, -2, ... for constant steps
        # h belongs to the key: the value weights depend only on the normalised nodes, but the
        # derivative weights are scaled by h**-d (a later step of another size with the same
        # normalised nodes, e.g. constant steps of 2H after constant steps of H, must not reuse them)
        key = (p, q, substeps, all_interp, h, tuple(np.round(past[:max(p + 1, q)], 9)))
        w = self._cache.get(key)
        if w is not None:
            return w
        w = StepWeights()
        w.p, w.q = p, q
        mids = (np.arange(substeps) + 0.5) / substeps
        starts = np.arange(substeps) / substeps
        int_nodes = np.concatenate(([1.0], past[:q]))
        if all_interp:
            # every input uses the interpolation polynomial (start-up iteration):
            # the "extrapolated" block is read from row 0 like the interpolated one
            ext_nodes = int_nodes
            w.e0, w.e1 = 0, q + 1
        else:
            ext_nodes = past[:p + 1]
            w.e0, w.e1 = 1, p + 2
        w.extrap = lagrange_weights(ext_nodes, mids)
        w.interp = lagrange_weights(int_nodes, mids)
        w.extrap_end = lagrange_weights(ext_nodes, [1.0])[0]
        w.interp_end = lagrange_weights(int_nodes, [1.0])[0]
        # the value at T(n+1) equals the last sub-step's value (e.g. order 0):
        # the master then skips setting the inputs again before reading outputs
        w.end_same_e = bool(np.array_equal(w.extrap[-1], w.extrap_end))
        w.end_same_i = bool(np.array_equal(w.interp[-1], w.interp_end))
        w.extrap_start = lagrange_weights(ext_nodes, starts)
        w.interp_start = lagrange_weights(int_nodes, starts)
        kmax = MAX_ORDER
        scale = np.array([h ** -d for d in range(1, kmax + 1)])[:, None]
        w.extrap_der = np.stack([lagrange_derivative_weights(ext_nodes, s, kmax) * scale for s in starts])
        w.interp_der = np.stack([lagrange_derivative_weights(int_nodes, s, kmax) * scale for s in starts])
        if len(self._cache) > 64:
            self._cache.clear()
        self._cache[key] = w
        return w
