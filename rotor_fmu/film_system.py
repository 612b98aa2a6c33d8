"""The rotor with a linearised mass-conserving film at each bearing station as one linear system,
and its least-damped eigenvalues (``rotorcosim stability --film mc``; docs/analysis.md, "Linear
threshold of the mass-conserving film (film impedance)").

The descriptor system ``E x' = A x``, ``x = (q, q', u_1, u_2, ...)``: the rotor
``M q'' + C q' + K q = sum P_j^T (F_u u_j + F_q P_j q + F_v P_j q')`` (minus the asperity contact's
``K_c P_j q + C_c P_j q'``) and each film ``M_j u_j' = -J_s u_j - R_q P_j q - R_v P_j q'``
(:class:`bearing_fmu.linearize.MCFilmLinear`: ``Js`` sparse, ``Mdiag`` with zeros on algebraic
cells, ``Rq``, ``Rv``, ``Fu``, ``Fq``, ``Fv``, ``contact``). Eliminating the u_j gives the
characteristic equation ``det D(s) = 0``, ``D(s) = s^2 M + s C + K + sum P_j^T Z_j(s) P_j`` with the
film impedances ``Z_j`` (:meth:`~bearing_fmu.linearize.MCFilmLinear.impedance`), so the finite
eigenvalues of the pencil are its roots.

* :func:`pencil` - ``(A, E)`` sparse (one assembly for both solvers).
* :func:`eigenvalues_dense` - all finite eigenvalues by QZ of the dense pencil (N = 2 n_rotor +
  the film cells, 1612 at 40 x 40 with two stations: ~15 s). The reference.
* :func:`rightmost` - the eigenvalues right of a line ``Re s = alpha`` just left of the least-damped
  one, found by sparse shift-invert Arnoldi and **counted** by the argument principle on
  ``det D`` along that line; when the count and the eigenvalues found disagree, the dense solve
  (~0.3-0.6 s a speed at 40 x 40 with two stations on a quiet host; the turbocharger ~1-2 s).

Why the count is a guarantee. ``det D(s)`` is a rational function: its zeros are the system's
eigenvalues, its poles the films' own modes with the journal held (the zeros of
``det(s M_j + J_s,j)``, :meth:`~bearing_fmu.linearize.MCFilmLinear.poles`), and
``det D(s) ~ det(M) s^(2n)`` for large ``|s|`` (``Z_j`` grows at most like ``|s|``). Divided by 2n
factors ``s - a_k`` (``a_k`` real, left of the line), ``g(s) -> 1`` at infinity and
``g(conj s) = conj g(s)``, so the change of ``arg g`` along the upper half of the line, ``y`` from
0 to infinity, gives ``(zeros - poles right of the line) = -(change of arg g) / pi`` exactly (the
argument principle on the half plane, its lower half by symmetry): the far-right and the
high-frequency eigenvalues are counted too. The eigenvalues the Arnoldi runs found and the films'
own modes near the line (Arnoldi on each film) are divided out first (:func:`count_right`), so
the count is that of those **not found**: 0, or the least-damped root may have been missed (then
Arnoldi again where the phase fell, and at last the dense solve). What the count assumes: that
the films have no mode right of the line besides those found (they are stable alone: their
poles lie left of -500 1/s in the 40 x 40 oil bath at 200 Hz, the tests check them), and that
the phase is followed without losing a turn: the grid is refined until each step changes
``ln g`` by less than ``PHASE_STEP`` in phase and ``LOG_STEP`` in magnitude and is shorter than
``RATE_STEP / |d ln g / dy|`` at both ends (a root or pole close to the line inside a step makes
that derivative large at its ends), up to where ``|g - 1| < 0.05`` (g then goes to 1 as
``1 / |s|``). tests/test_film_system.py: the same least-damped root as the dense solve at every
speed of the Jeffcott (oil bath, free to air) and turbocharger rotors on 16 x 8 films, and the
count, told only the eigenvalues left of its line, finds all 2-12 right of it.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

#: largest change of arg g [rad] and of ln |g| between neighbouring points of the count's grid
PHASE_STEP = math.pi / 4
LOG_STEP = 1.0
#: largest step times |d ln g / dy| at either end: a root or pole of g inside a step, closer to the
#: line than the step is long, makes |d ln g / dy| >~ 1 / step at the nearer end, so such steps are
#: halved however the phase changes across them (two roots near the line inside one step could
#: turn the phase by 2 pi and look like none)
RATE_STEP = 1.5
#: the count's first grid: y = scale sinh(t), t in steps of GRID_STEP (points 30 % apart above the
#: scale), refined where PHASE_STEP, LOG_STEP or RATE_STEP ask
GRID_STEP = 0.3
#: largest distance [rad] of arg h(alpha) from a multiple of pi taken as rounding (count_right)
PHI0_TOL = 1e-3
#: eigenvalues nearest each shift taken by the Arnoldi runs
PER_SHIFT = 8


def pencil(rotor, omega, films):
    """``(A, E)`` scipy CSC (N, N), real: the descriptor system of the module doc at speed omega."""
    import scipy.sparse as sp
    M, C, K = rotor.system_matrices(omega)
    n = M.shape[0]
    sizes = [f.Js.shape[0] for f in films]
    N = 2 * n + sum(sizes)
    top = np.zeros((2 * n, 2 * n))
    top[:n, n:] = np.eye(n)
    top[n:, :n], top[n:, n:] = -K, -C
    coupling = []                        # (n, m_j) dense rows F_u of the rotor's force equations
    films_rows = []
    o = 2 * n
    for f, (ix, iy), m in zip(films, rotor.bearing_dofs, sizes):
        P = np.zeros((2, n))
        P[0, ix] = P[1, iy] = 1.0
        coupling.append(P.T @ f.Fu)
        top[n:, :n] += P.T @ f.Fq @ P
        top[n:, n:] += P.T @ f.Fv @ P
        if getattr(f, "contact", None) is not None:      # asperity contact: -K_c q - C_c q'
            Kc, Cc = f.contact
            top[n:, :n] -= P.T @ Kc @ P
            top[n:, n:] -= P.T @ Cc @ P
        films_rows.append(sp.hstack([sp.csr_matrix(np.hstack([-f.Rq @ P, -f.Rv @ P])),
                                     sp.csr_matrix((m, o - 2 * n)), -f.Js,
                                     sp.csr_matrix((m, N - o - m))]))
        o += m
    rotor_rows = sp.hstack([sp.csr_matrix(top),
                            sp.vstack([sp.csr_matrix((n, N - 2 * n)), sp.csr_matrix(np.hstack(coupling))])])
    A = sp.vstack([rotor_rows] + films_rows).tocsc()
    E = sp.block_diag([sp.eye(n), sp.csr_matrix(M)] + [sp.diags(f.Mdiag) for f in films]).tocsc()
    return A, E


def eigenvalues_dense(rotor, omega, films):
    """All finite eigenvalues [1/s] of the pencil (largest real part first): QZ of the dense pencil,
    the infinite ones (algebraic full-film cells, M = 0) and those beyond 1e8 1/s dropped."""
    import scipy.linalg as sl
    A, E = pencil(rotor, omega, films)
    lam = sl.eigvals(A.toarray(), E.toarray())
    lam = lam[np.isfinite(lam) & (np.abs(lam) < 1e8)]
    return lam[np.argsort(-lam.real)]


class ImpedanceDeterminant:
    """``g(s) = det D(s) / (det(M) (s - c)^(2n))`` of the module doc (``c`` set per count): one
    impedance per distinct film per value (films with identical arrays, e.g. both stations of a
    symmetric rotor, share it)."""

    def __init__(self, rotor, omega, films):
        self.M, self.C, self.K = rotor.system_matrices(omega)
        self.n = self.M.shape[0]
        self.det_m = float(np.linalg.det(self.M))
        self.films = films
        self.dofs = [np.ix_([ix, iy], [ix, iy]) for ix, iy in rotor.bearing_dofs]
        self.first = [next(k for k in range(j + 1) if _identical(films[k], films[j])) for j in range(len(films))]
        self.evaluations = 0

    def D(self, s: complex, slope: bool = False):
        """D(s) (n, n) complex; with ``slope``, (D(s), dD/ds)."""
        D = (s * s) * self.M + s * self.C + self.K.astype(complex)
        dD = 2 * s * self.M + self.C.astype(complex)
        Z: dict = {}
        for j, (f, idx) in enumerate(zip(self.films, self.dofs)):
            k = self.first[j]
            if k not in Z:
                Z[k] = f.impedance(s, slope=True) if slope else (f.impedance(s), None)
            D[idx] += Z[k][0]
            if slope:
                dD[idx] += Z[k][1]
        self.evaluations += 1
        return (D, dD) if slope else D

    def log_det(self, s: complex) -> tuple[complex, complex]:
        """``ln(det D(s) / det M)`` (principal phase; -inf real part when D(s) is singular) and its
        derivative ``tr(D^-1 dD/ds)``."""
        D, dD = self.D(s, slope=True)
        sign, logabs = np.linalg.slogdet(D)
        if sign == 0:
            return complex(-math.inf, 0.0), complex(math.inf)
        return (complex(logabs - math.log(abs(self.det_m)), np.angle(sign * np.sign(self.det_m))),
                complex(np.trace(np.linalg.solve(D, dD))))


def _identical(a, b) -> bool:
    if a is b:
        return True
    arrays = lambda f: (f.Js.indptr, f.Js.indices, f.Js.data, f.Mdiag, f.Rq, f.Rv, f.Fu, f.Fq, f.Fv)  # noqa: E731
    ca, cb = getattr(a, "contact", None), getattr(b, "contact", None)
    return (a.Js.shape == b.Js.shape and all(x.shape == y.shape and np.array_equal(x, y)
                                             for x, y in zip(arrays(a), arrays(b)))
            and (ca is None) == (cb is None)
            and (ca is None or all(np.array_equal(x, y) for x, y in zip(ca, cb))))


def _wrap(x: float) -> float:
    return (x + math.pi) % (2 * math.pi) - math.pi


@dataclass
class Count:
    """What :func:`count_right` found: ``missing``, the eigenvalues (minus film poles) right of the
    line that are not among the ``known`` ones (None: not counted, the line meets a root or the
    grid would be too fine), the impedance evaluations ``points``, and ``drop``, the ``y`` where
    ``arg h`` falls fastest (near a missing eigenvalue right of the line)."""
    missing: int | None
    points: int
    drop: float


def count_right(det: ImpedanceDeterminant, alpha: float, scale: float, known=(), modes=(), poles=(), *,
                max_points=3000) -> Count:
    """Eigenvalues minus film poles with ``Re s > alpha`` that are not among ``known`` (module doc),
    by the argument principle for

        h(s) = det D(s) / det M / prod_k (s - a_k) / prod_j (s - lambda_j) / (s - b_j)
                                            * prod_i (s - p_i) / (s - b_i)

    along ``s = alpha + i y``, ``y = scale sinh(t)``, from y = 0 to infinity. The 2n ``a_k`` and the
    ``b_j`` are real, left of the line (they add nothing to the count), each as far left as its
    approximate rotor mode (``modes``, :func:`_rotor_modes`) or known eigenvalue ``lambda_j`` is
    far from ``alpha`` (at least ``scale``), so h -> 1 at infinity and stays of order 1 between;
    dividing the known eigenvalues out leaves h smooth where they are, so the grid stays coarse,
    and the count of det D is that of h plus the known ones right of the line, exactly, whatever
    they are. The known film poles ``p_i`` (:func:`_film_poles`, once per station) are taken out
    alike: ``missing`` is then the eigenvalues right of the line not known minus the film poles
    there not known. The grid is refined until neighbouring points differ by less than ``PHASE_STEP`` in
    phase and ``LOG_STEP`` in ``ln |h|``, up to where ``|h - 1| < 0.05``; it has a point at the
    frequency of each approximate mode (a lightly damped rotor mode not found would otherwise need
    a fine grid to be seen)."""
    known = np.asarray(known, dtype=complex)
    modes = np.asarray(modes, dtype=complex)
    far = lambda z: alpha - np.maximum(scale, np.abs(z - alpha))     # noqa: E731
    pm = np.concatenate([far(modes), np.full(max(0, 2 * det.n - modes.size), alpha - scale)])[:2 * det.n]
    pk = far(known)
    poles = np.asarray(poles, dtype=complex)
    pp = far(poles)
    t_end = math.asinh(1e4)
    ts = set(np.arange(0.0, t_end, GRID_STEP).tolist()) | {math.asinh(y / scale) for y in modes.imag if y > 0}
    vals: dict[float, complex] = {}

    def at(t):
        """(ln h, |d ln h / dy|) at y = scale sinh(t)."""
        if t not in vals:
            s = complex(alpha, scale * math.sinh(t))
            lg, dlg = det.log_det(s)
            vals[t] = (lg - complex(np.sum(np.log(s - pm)) + np.sum(np.log(s - known) - np.log(s - pk))
                                    - np.sum(np.log(s - poles) - np.log(s - pp))),
                       abs(dlg - np.sum(1 / (s - pm)) - np.sum(1 / (s - known) - 1 / (s - pk))
                           + np.sum(1 / (s - poles) - 1 / (s - pp))))
        return vals[t]

    while True:
        grid = sorted(ts)
        phase = phi0 = at(0.0)[0].imag
        drop = (0.0, 0.0)
        stack = list(reversed(list(zip(grid[:-1], grid[1:]))))
        while stack:
            a, b = stack.pop()
            (la, ra), (lb, rb) = at(a), at(b)
            if not (math.isfinite(la.real) and math.isfinite(lb.real)) or len(vals) > max_points:
                return Count(None, len(vals), math.nan)
            d = _wrap(lb.imag - la.imag)
            ya, yb = scale * math.sinh(a), scale * math.sinh(b)
            if ((abs(d) > PHASE_STEP or abs(lb.real - la.real) > LOG_STEP or (yb - ya) * max(ra, rb) > RATE_STEP)
                    and b - a > 1e-9):
                m = 0.5 * (a + b)
                stack += [(m, b), (a, m)]
                continue
            phase += d
            drop = min(drop, (d / (yb - ya), 0.5 * (ya + yb)))
        h_end = at(grid[-1])[0]
        if abs(np.exp(h_end) - 1.0) < 0.05:
            break
        if t_end > math.asinh(1e12):      # h does not approach 1: not the function of the module doc
            return Count(None, len(vals), math.nan)
        ts.update((t_end + math.log(10.0) * np.linspace(0, 1, 6)[1:]).tolist())
        t_end += math.log(10.0)
    # the change of arg h from y = 0 (phi0, a multiple of pi: h is real there) to infinity (h -> 1: the
    # multiple of 2 pi nearest the phase followed to the grid's end). phi0 is taken as that multiple of
    # pi when within PHI0_TOL of it: the computed h(alpha) has a phase of rounding where D(alpha) is
    # ill-conditioned (a root and a film pole near each other on the real axis: 1e-5 rad in the Jeffcott
    # floating-ring system at 116.85 Hz, which made the count 3e-6 off an integer and sent the speed to
    # the dense solve); a missing conjugate would make it of order 1
    if abs(_wrap(2.0 * phi0) / 2.0) > PHI0_TOL:
        return Count(None, len(vals), math.nan)
    count = -(phase - _wrap(h_end.imag) - math.pi * round(phi0 / math.pi)) / math.pi
    if abs(count - round(count)) > 1e-6:
        return Count(None, len(vals), math.nan)
    return Count(int(round(count)), len(vals), drop[1])


def _shift_invert(A, E, sigma: complex, k: int):
    """The k eigenpairs of the pencil nearest sigma (ARPACK on (A - sigma E)^-1 E): values (m,),
    unit vectors (N, m); fewer where ARPACK converged on fewer."""
    import scipy.sparse.linalg as spla
    real = sigma.imag == 0.0
    dtype = float if real else complex
    lu = spla.splu((A - (sigma.real if real else sigma) * E).astype(dtype).tocsc())
    Ed = E.astype(dtype)
    op = spla.LinearOperator(A.shape, matvec=lambda x: lu.solve(Ed @ x), dtype=dtype)
    # a fixed start vector: ARPACK's own is random, so the same scan gave values differing in
    # the 11th digit from run to run (a seeded one is not orthogonal to any mode in practice)
    v0 = np.random.default_rng(20261207).standard_normal(A.shape[0]).astype(dtype)
    try:
        mu, x = spla.eigs(op, k=k, which="LM", ncv=min(A.shape[0] - 1, 30), tol=1e-10, maxiter=10, v0=v0)
    except spla.ArpackNoConvergence as exc:     # in a crowd of damped film modes: those converged
        mu, x = exc.eigenvalues, exc.eigenvectors
    keep = mu != 0.0
    x = x[:, keep]
    return sigma + 1.0 / mu[keep], x / np.linalg.norm(x, axis=0)


class _Found:
    """Eigenpairs found so far, each once: a value from another run is the same eigenvalue when it
    lies within 1e-4 (relative) of a kept one and its vector is parallel to that one's (ARPACK's
    values of one eigenvalue from different shifts differ by up to ~1e-6 relative, while distinct
    eigenvalues that close, e.g. the two films' nearly uncoupled modes of a symmetric rotor, have
    different vectors); complex pairs come with their conjugates (the pencil is real)."""

    def __init__(self):
        self.values: list = []
        self.vectors: list = []

    def add(self, pairs):
        values, vectors = pairs
        for v, x in zip(values, vectors.T):
            for vv, xx in ((v, x), (np.conj(v), np.conj(x))) if v.imag != 0.0 else ((v, x),):
                if not any(abs(w - vv) <= 1e-4 * max(abs(vv), 1.0) and abs(np.vdot(z, xx)) > 0.9
                           for w, z in zip(self.values, self.vectors)):
                    self.values.append(vv)
                    self.vectors.append(xx)

    def array(self) -> np.ndarray:
        lam = np.array(self.values, dtype=complex)
        return lam[np.argsort(-lam.real)]


@dataclass
class Rightmost:
    """What :func:`rightmost` found: ``eigenvalues`` [1/s] right of ``alpha`` (all of them,
    largest real part first), how they were found (``method``: "counted" or "dense"), the count's
    ``alpha`` and its impedance evaluations, the Arnoldi shifts."""
    eigenvalues: np.ndarray
    method: str
    alpha: float
    evaluations: int
    shifts: list


def _rotor_modes(det: ImpedanceDeterminant) -> np.ndarray:
    """Approximate rotor modes: the eigenvalues of ``s^2 M + s (C + sum P^T Z'(0) P) + K + sum P^T Z(0) P``
    (each film by its impedance's first two Taylor terms; gyroscopic terms included), all 2n."""
    K = det.D(0.0).real
    C = det.C.copy()
    slopes: dict[int, np.ndarray] = {}
    for j, (f, idx) in enumerate(zip(det.films, det.dofs)):
        k = det.first[j]
        if k not in slopes:
            slopes[k] = np.real(f.slope0())
        C[idx] += slopes[k]
    n = det.n
    Minv = np.linalg.inv(det.M)
    return np.linalg.eigvals(np.block([[np.zeros((n, n)), np.eye(n)], [-Minv @ K, -Minv @ C]]))


def _shifts(modes, omega: float, hint=()) -> list:
    """Where to look first: the real axis, half the speed (oil whirl), the oscillating approximate
    rotor modes (:func:`_rotor_modes`, ``|Re| <= Im``: not the overdamped ones, nor real ones that
    the Taylor terms make up) and ``hint``; shifts within 2 % of one another taken once."""
    osc = modes[(modes.imag >= 0.0) & (np.abs(modes.real) <= modes.imag)]
    # a hint 1e-3 |h| right of itself: the last speed's root is within rounding of this speed's during a
    # refinement, and a shift on an eigenvalue gives ARPACK a near-singular operator
    out = [0j, 0.5j * omega] + list(osc) + [complex(h.real + 1e-3 * abs(h), abs(h.imag)) for h in hint]
    uniq: list = []
    for s in out:
        if all(abs(s - u) > 0.02 * max(abs(u), omega) for u in uniq):
            uniq.append(complex(s))
    return uniq


def _film_poles(det: ImpedanceDeterminant, alpha: float, scale: float) -> np.ndarray:
    """The films' own modes (the poles of their impedances, :meth:`~bearing_fmu.linearize.MCFilmLinear.poles`)
    nearest the line ``Re s = alpha`` at ``y = 0, scale / 2, scale, 2 scale`` (Arnoldi on each distinct film's
    pencil), each station's film's once, with their conjugates."""
    import scipy.sparse as sp
    per_film: dict[int, list] = {}
    for k in sorted(set(det.first)):
        f = det.films[k]
        A, E = -f.Js.tocsc(), sp.diags(f.Mdiag).tocsc()
        found = _Found()
        for y in (0.0, 0.5 * scale, scale, 2.0 * scale):
            try:
                found.add(_shift_invert(A, E, complex(alpha, y), PER_SHIFT))
            except RuntimeError:
                pass
        per_film[k] = found.values
    return np.array([p for k in det.first for p in per_film[k]], dtype=complex)


def rightmost(rotor, omega, films, *, hint=(), margin=50.0, retries=2, dense_max=None) -> Rightmost:
    """The least-damped eigenvalues of the rotor-film system (``films``: one
    :class:`~bearing_fmu.linearize.MCFilmLinear` per station): all those right of a line
    ``Re s = alpha`` (module doc). Shift-invert Arnoldi on the sparse pencil at the shifts of
    :func:`_shifts` (and at ``hint``, e.g. the last speed's least-damped eigenvalue); ``alpha``
    halfway between the largest real part found and the next (at most ``margin`` [1/s] below it);
    the argument-principle count on that line (:func:`count_right`). When it says eigenvalues are
    missing, Arnoldi again where its phase falls fastest (up to ``retries`` times), then
    :func:`eigenvalues_dense` (``method = "dense"``). BLAS runs on one thread here: its many small
    products (ARPACK's on 1612 x 30 complex blocks at 40 x 40) took 2-20 x longer with two threads
    on a shared 2-core host. ``dense_max``: the largest pencil (unknowns) solved densely; a larger one
    that would need it is returned unsolved (``method = "unresolved"``, no eigenvalues)."""
    from threadpoolctl import threadpool_limits
    with threadpool_limits(1, user_api="blas"):
        found = _rightmost(rotor, omega, films, hint, margin, retries)
    if found.method == "dense":
        size = 2 * rotor.n_dof + sum(f.Js.shape[0] for f in films)
        if dense_max is not None and size > dense_max:     # QZ is O(N^3): hours at N ~ 13000
            found.method = "unresolved"
            return found
        found.eigenvalues = eigenvalues_dense(rotor, omega, films)
    return found


def _rightmost(rotor, omega, films, hint, margin, retries) -> Rightmost:
    """:func:`rightmost` without its dense solve (``method = "dense"``, no eigenvalues, where that
    is needed)."""
    A, E = pencil(rotor, omega, films)
    det = ImpedanceDeterminant(rotor, omega, films)
    if not (abs(det.det_m) > 0.0 and math.isfinite(det.det_m)):    # a massless degree of freedom: no
        return Rightmost(np.empty(0, complex), "dense", math.nan, 0, [])    # s^(2n) to count against
    modes = _rotor_modes(det)
    shifts = _shifts(modes, omega, hint)
    found = _Found()
    for s in shifts:
        try:
            found.add(_shift_invert(A, E, s, PER_SHIFT))
        except RuntimeError:                # a shift on an eigenvalue, or ARPACK failed: the count decides
            pass
    poles = None
    for attempt in range(retries + 1):
        if not found.values:
            break
        lam = found.array()
        top = lam[0].real
        below = lam.real[lam.real < top - 1e-9 * max(abs(lam[0]), 1.0)]
        alpha = top - min(margin, 0.5 * (top - below.max())) if below.size else top - margin
        right = lam[lam.real > alpha]
        scale = max(omega, float(np.max(np.abs(right.imag))))
        if poles is None:
            poles = _film_poles(det, alpha, scale)
        n = count_right(det, alpha, scale, lam, modes, poles)
        if n.missing == 0:
            return Rightmost(right, "counted", alpha, det.evaluations, shifts)
        if n.missing is None or n.missing < 0 or attempt == retries:
            break                           # a film pole not found right of the line, or no count: dense
        s = complex(top, n.drop)
        shifts.append(s)
        try:
            found.add(_shift_invert(A, E, s, 2 * PER_SHIFT))
        except RuntimeError:
            break
    return Rightmost(np.empty(0, complex), "dense", math.nan, det.evaluations, shifts)
