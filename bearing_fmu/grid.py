"""Finite-volume grid of the developed film and the gap function.

Conventions (project-wide, docs/dev/contracts.md)
-------------------------------------------------
* SI units; x horizontal, y vertical up, z along the shaft; the journal spins
  counter-clockwise (omega > 0 about +z); phi is measured from +x
  counter-clockwise.
* Cells: ``n_phi`` cells in phi over [0, 2 pi) (periodic), cell centres
  ``phi_i = i * dphi`` (cell i spans [phi_i - dphi/2, phi_i + dphi/2]);
  ``n_z`` cells in the dimensionless axial coordinate zbar in [0, 1], centres
  ``zbar_j = (j + 1/2) dz``; the physical axial coordinate is ``z = zbar * B``.
  Field arrays have shape ``(n_z, n_phi)`` (row j, column i); the flat index
  is ``g = j * n_phi + i``.
* Gap (rigid, aligned journal whose centre is at (x, y); clearance
  ``c = psi R``): ``h(phi) = c - x cos(phi) - y sin(phi)``, ``H = h / c``;
  ``dH/dt = -(vx cos(phi) + vy sin(phi)) / c``. H depends on phi only.
* Feed groove: an axial groove over the full width, opening angle
  ``groove_width`` [rad] centred at ``groove_angle``; every cell column whose
  centre lies within half the opening of the groove centre is a groove column
  (at least the nearest column when ``groove_width > 0``), held at p_feed.

Symmetry
--------
The journal is aligned (H depends on phi only), both edges carry the same
condition and the groove spans the full width, so the film is symmetric about
the mid-plane zbar = 1/2. For even n_z the transient solver therefore works
on the lower half only (``make_grid(..., half=True)``) with a zero-flux
mid-plane: exact, not an approximation, and the Newton matrix has half the
unknowns and half the bandwidth (about 8 times cheaper to factorise).

Unknown ordering
----------------
The Newton matrix has the 5-point pattern, periodic in phi. Groove cells are
Dirichlet (their Newton increment is zero), so couplings *into* them can be
dropped and a groove column breaks the periodicity. :func:`best_ordering`
tries a few orderings and keeps the one with the smallest bandwidth (z-fastest
starting after the groove: bandwidth n_z; phi-fastest: bandwidth n_phi, with the
periodic wrap inside the band; z-fastest folded: 2 n_z), so that a LAPACK band
LU (``dgbtrf``) factors it in O(N bw^2).
"""

from __future__ import annotations

from dataclasses import dataclass
from functools import cached_property

import numba as nb
import numpy as np


@dataclass(frozen=True, eq=False)
class Grid:
    """Cell geometry; build with :func:`make_grid`."""

    n_phi: int
    n_z: int
    dphi: float
    dz: float
    phi: np.ndarray          # (n_phi,) cell centres [rad]
    phi_e: np.ndarray        # (n_phi,) east faces phi_i + dphi/2 [rad]
    zbar: np.ndarray         # (n_z,) cell centres [-]
    groove: np.ndarray       # (n_phi,) bool, groove columns
    pos: np.ndarray          # (N,) position of flat cell g in the band ordering
    order: np.ndarray        # (N,) flat cell at each position (inverse of pos)
    bw: int                  # half bandwidth (kl = ku = bw)
    ordering: str            # name of the chosen ordering
    phi_f: np.ndarray = None  # (n_phi,) angle of east face i for the film gap He: phi_e, or
    #                           the groove edge at a face next to the groove (groove_weights)
    wrel: np.ndarray = None   # (n_phi,) column width / dphi (groove_weights)
    frel: np.ndarray = None   # (n_phi,) centre distance across east face i / dphi

    @property
    def n(self) -> int:
        return self.n_phi * self.n_z

    def gap(self, x, y, vx, vy, c):
        """Return H at centres, H at east faces and dH/dt at centres (new arrays)."""
        cs, sn, cf, sf = self._trig
        return _gap(float(x), float(y), float(vx), float(vy), float(c), cs, sn, cf, sf)

    @cached_property
    def _trig(self):
        """cos, sin of the cell centres and of the east faces of the gap (phi_f, else phi_e),
        computed once per grid (the grid is immutable; gap is called every film step)."""
        phi_f = self.phi_e if self.phi_f is None else self.phi_f
        return np.cos(self.phi), np.sin(self.phi), np.cos(phi_f), np.sin(phi_f)


@nb.njit(cache=True, nogil=True)
def _gap(x, y, vx, vy, c, cs, sn, cf, sf):
    """``H = 1 - (x cos + y sin) / c`` at the centres, the same at the east faces (``cf``,
    ``sf``) and ``dH/dt = -(vx cos + vy sin) / c``: the numpy expressions this replaces, the
    same operations in the same order per element (so the same values bit for bit), in one
    compiled call instead of nine numpy ones (the gap is formed every film step; issue 16).
    Holds the GIL: a short call, see :func:`.film.integrals`."""
    n = cs.size
    H = np.empty(n)
    He = np.empty(n)
    Hdot = np.empty(n)
    for i in range(n):
        H[i] = 1.0 - (x * cs[i] + y * sn[i]) / c
        He[i] = 1.0 - (x * cf[i] + y * sf[i]) / c
        Hdot[i] = -(vx * cs[i] + vy * sn[i]) / c
    return H, He, Hdot


def groove_columns(n_phi: int, width: float, angle: float) -> np.ndarray:
    """Boolean mask of the groove columns (see module docstring)."""
    phi = 2 * np.pi * np.arange(n_phi) / n_phi
    mask = np.zeros(n_phi, dtype=bool)
    if width <= 0.0:
        return mask
    d = np.abs((phi - angle + np.pi) % (2 * np.pi) - np.pi)
    mask = d <= 0.5 * width + 1e-12
    if not mask.any():
        mask[np.argmin(d)] = True
    return mask


def groove_weights(n_phi: int, width: float, angle: float, groove: np.ndarray):
    """The groove of its true angular width on the cell grid (issue 16): returns
    (phi_f, wrel, frel) for :func:`.film.assemble` and :func:`.film.integrals`.

    The groove columns (:func:`groove_columns`, centres inside the groove) stay Dirichlet;
    the film next to the groove ends AT the groove edges ``angle -+ width / 2``: the film
    cell west of the groove spans from its west face to the west groove edge, so its width
    is ``dphi / 2 + d`` with ``d`` the distance of its centre from the edge, and the flux
    between it and the groove is taken over that distance ``d`` with the gap at the edge
    (a Shortley-Weller boundary cell; mirrored east). The groove columns share the true
    width ``width`` between them, so the column widths add up to 2 pi and the strip held at
    p_feed is exactly ``width`` wide on any grid. ``wrel`` = width / dphi, ``frel`` = centre
    distance across east face i / dphi (both 1 away from the groove), ``phi_f`` = angle of
    east face i (the groove edge at the two faces next to the groove, phi_e elsewhere).
    Without a groove: ones and phi_e."""
    dphi = 2 * np.pi / n_phi
    phi = dphi * np.arange(n_phi)
    phi_f = phi + 0.5 * dphi
    wrel = np.ones(n_phi)
    frel = np.ones(n_phi)
    if width <= 0.0 or not groove.any() or groove.all():
        return phi_f, wrel, frel
    n_g = int(groove.sum())
    wrel[groove] = width / (n_g * dphi)
    for i in range(n_phi):
        e, w = (i + 1) % n_phi, (i - 1) % n_phi
        if not groove[i] and groove[e]:          # film cell west of the groove: east face i
            edge = angle - 0.5 * width
            d = max((edge - phi[i]) % (2 * np.pi), 1e-3 * dphi)
            phi_f[i], frel[i] = phi[i] + d, d / dphi
            wrel[i] = 0.5 + d / dphi
        if not groove[i] and groove[w]:          # film cell east of the groove: face w
            edge = angle + 0.5 * width
            d = max((phi[i] - edge) % (2 * np.pi), 1e-3 * dphi)
            phi_f[w], frel[w] = phi[i] - d, d / dphi
            wrel[i] = (0.5 + d / dphi) if wrel[i] == 1.0 else wrel[i] + d / dphi - 0.5
    return phi_f, wrel, frel


def _edges(n_phi, n_z, groove, wide=False):
    """Couplings (row g, col g2) of the 5-point stencil between non-groove cells
    (``wide``: plus i +- 2, the 7-point stencil of ``theta_transport = 1``)."""
    i, j = np.meshgrid(np.arange(n_phi), np.arange(n_z))
    i, j = i.ravel(), j.ravel()
    g = j * n_phi + i
    rows, cols = [], []
    steps = ((1, 0), (-1, 0), (0, 1), (0, -1)) + (((2, 0), (-2, 0)) if wide else ())
    for di, dj in steps:
        i2, j2 = (i + di) % n_phi, j + dj
        ok = (j2 >= 0) & (j2 < n_z)
        rows.append(g[ok])
        cols.append((j2 * n_phi + i2)[ok])
    rows, cols = np.concatenate(rows), np.concatenate(cols)
    keep = ~groove[rows % n_phi] & ~groove[cols % n_phi]
    return rows[keep], cols[keep]


def best_ordering(n_phi: int, n_z: int, groove: np.ndarray, wide: bool = False):
    """Return (pos, order, bw, name) of the smallest-bandwidth candidate ordering
    (``wide``: for the 7-point stencil with the i +- 2 couplings)."""
    i = np.tile(np.arange(n_phi), n_z)
    j = np.repeat(np.arange(n_z), n_phi)
    i0 = int(np.argmax(groove)) if groove.any() else 0
    ii = (i - i0) % n_phi
    fold = np.empty(n_phi, dtype=np.int64)     # column rank in 0, n-1, 1, n-2, ...
    seq = [k // 2 if k % 2 == 0 else n_phi - 1 - k // 2 for k in range(n_phi)]
    fold[np.array(seq)] = np.arange(n_phi)
    cands = {
        "z-fastest": ii * n_z + j,
        "phi-fastest": j * n_phi + ii,
        "z-fastest-folded": fold[i] * n_z + j,
    }
    rows, cols = _edges(n_phi, n_z, groove, wide)
    best = None
    for name, pos in cands.items():
        bw = int(np.max(np.abs(pos[rows] - pos[cols]))) if rows.size else 0
        if best is None or bw < best[2]:
            best = (pos.astype(np.int64), None, max(bw, 1), name)
    pos = best[0]
    order = np.empty_like(pos)
    order[pos] = np.arange(pos.size)
    return pos, order, best[2], best[3]


def make_grid(n_phi: int, n_z: int, groove_width: float, groove_angle: float,
              half: bool = False, wide: bool = False, true_groove: bool = False) -> Grid:
    """Build the grid and its band ordering.

    ``half=True`` (n_z even): only the cells of the lower half of the width,
    zbar in [0, 1/2], are built (``n_z // 2`` rows of the full grid's cell
    size); the mid-plane zbar = 1/2 is a symmetry plane (see model.py).
    ``wide=True``: the band ordering covers the i +- 2 couplings of the second-order
    theta transport (``theta_transport = 1``; without a groove the phi-fastest
    ordering keeps bandwidth n_phi, with a groove the z-fastest one doubles to 2 n_z).
    ``true_groove=True``: the groove of its true width (:func:`groove_weights`; the
    mass-conserving film); False: whole groove columns, uniform weights (``wrel``,
    ``frel`` None, the half-Sommerfeld solver's grid).
    """
    if half and n_z % 2:
        raise ValueError(f"make_grid: half=True needs an even n_z (got {n_z})")
    dphi = 2 * np.pi / n_phi
    dz = 1.0 / n_z
    rows = n_z // 2 if half else n_z
    phi = dphi * np.arange(n_phi)
    groove = groove_columns(n_phi, groove_width, groove_angle)
    pos, order, bw, name = best_ordering(n_phi, rows, groove, wide)
    phi_f = wrel = frel = None
    if true_groove and groove_width > 0.0:
        phi_f, wrel, frel = groove_weights(n_phi, groove_width, groove_angle, groove)
    return Grid(n_phi=n_phi, n_z=rows, dphi=dphi, dz=dz, phi=phi,
                phi_e=phi + 0.5 * dphi, zbar=(np.arange(rows) + 0.5) * dz,
                groove=groove, pos=pos, order=order, bw=bw, ordering=name,
                phi_f=phi_f, wrel=wrel, frel=frel)
