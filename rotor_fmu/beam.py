"""Timoshenko shaft finite elements with gyroscopic matrices, rigid discs, assembly.

Element: two nodes, per node and plane the dofs ``[w, beta]`` (lateral displacement
and cross-section rotation, ``beta = dw/dz`` for Euler-Bernoulli).  We use the *slope*
convention in both planes: ``beta_x = d x / d z`` (= rotation psi about +y) and
``beta_y = d y / d z`` (= minus the rotation theta about +x), so both bending planes
have identical element matrices and the pair (beta_x, beta_y) rotates like (x, y)
under a rotation about z.  Global dof order: ``q = [plane x; plane y]`` with each plane
``[w_0, beta_0, w_1, beta_1, ...]``.

Matrices (Nelson 1980, "A finite rotating shaft element using Timoshenko beam theory",
J. Mech. Des. 102:793; Friswell et al. 2010, "Dynamics of Rotating Machines", sec. 5.4.3,
Przemieniecki 1968) with ``Phi = 12 E I / (kappa G A L^2)``:

* stiffness ``K_e`` (Timoshenko, interdependent interpolation),
* translational mass ``M_T`` and rotary inertia ``M_R`` (consistent, Phi-dependent),
* gyroscopic: ``G_e = [[0, R], [-R, 0]]`` on (plane x, plane y) with ``R = 2 M_R``
  (polar moment 2 I of a circular section).  Derived from the kinetic energy
  ``T = ... - Omega rho J beta_y' beta_x`` (Lagrange); for a spinning rigid body
  this gives the forward nutation ``Ip/Id Omega`` (checked in the tests);
* angular-acceleration term ``Ka = [[0, 0], [-R, 0]]`` (multiplies dOmega/dt).

Discs (rigid wheels): mass m on both translations, transverse inertia Id on both
slopes, gyroscopic block ``Ip [[0, 1], [-1, 0]]`` on (beta_x, beta_y), acceleration
term ``-Ip alpha beta_x`` in the beta_y equation.

Rotating internal damping (optional, stiffness proportional, coefficient
``beta_i`` [s]): ``C_i = beta_i K`` and circulatory ``Kc = beta_i [[0, K], [-K, 0]]``
(force ``-beta_i K (q' - Omega e_z x q)`` written in the fixed frame).

Shear coefficient of a (hollow) circular section, Cowper (1966), J. Appl. Mech. 33:335:
``kappa = 6 (1 + nu) (1 + m^2)^2 / ((7 + 6 nu)(1 + m^2)^2 + (20 + 12 nu) m^2)``,
``m = d_inner / d_outer``.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np


def cowper_kappa(nu: float, d_outer: float, d_inner: float = 0.0) -> float:
    m = d_inner / d_outer
    a = (1.0 + m * m) ** 2
    return 6.0 * (1.0 + nu) * a / ((7.0 + 6.0 * nu) * a + (20.0 + 12.0 * nu) * m * m)


def section_properties(d_outer: float, d_inner: float = 0.0):
    """Area A [m^2] and area moment I [m^4] of a (hollow) circular section."""
    A = np.pi / 4.0 * (d_outer**2 - d_inner**2)
    I = np.pi / 64.0 * (d_outer**4 - d_inner**4)
    return A, I


def timoshenko_element(L, E, G, rho, d_outer, d_inner=0.0, nu=0.3, shear=True):
    """Plane matrices (K, M_T, M_R) 4x4 of one Timoshenko element, dofs [w1, b1, w2, b2].

    ``shear=False`` gives the Euler-Bernoulli element (Phi = 0); rotary inertia is in
    ``M_R`` (drop it for a Rayleigh-free model).
    """
    A, I = section_properties(d_outer, d_inner)
    kappa = cowper_kappa(nu, d_outer, d_inner)
    Phi = 12.0 * E * I / (kappa * G * A * L * L) if shear else 0.0
    c = E * I / ((1.0 + Phi) * L**3)
    K = c * np.array([
        [12.0, 6 * L, -12.0, 6 * L],
        [6 * L, (4 + Phi) * L * L, -6 * L, (2 - Phi) * L * L],
        [-12.0, -6 * L, 12.0, -6 * L],
        [6 * L, (2 - Phi) * L * L, -6 * L, (4 + Phi) * L * L]])
    P = Phi
    m1 = 312 + 588 * P + 280 * P * P
    m2 = (44 + 77 * P + 35 * P * P) * L
    m3 = 108 + 252 * P + 140 * P * P
    m4 = (26 + 63 * P + 35 * P * P) * L
    m5 = (8 + 14 * P + 7 * P * P) * L * L
    m6 = -(6 + 14 * P + 7 * P * P) * L * L
    MT = rho * A * L / (840.0 * (1 + P) ** 2) * np.array([
        [m1, m2, m3, -m4],
        [m2, m5, m4, m6],
        [m3, m4, m1, -m2],
        [-m4, m6, -m2, m5]])
    m7 = (3 - 15 * P) * L
    m8 = (4 + 5 * P + 10 * P * P) * L * L
    m9 = (-1 - 5 * P + 5 * P * P) * L * L
    MR = rho * I / (30.0 * L * (1 + P) ** 2) * np.array([
        [36.0, m7, -36.0, m7],
        [m7, m8, -m7, m9],
        [-36.0, -m7, 36.0, -m7],
        [m7, m9, -m7, m8]])
    return K, MT, MR


@dataclass(frozen=True, kw_only=True)
class Element:
    z0: float          # left node position [m]
    length: float      # [m]
    d_outer: float     # [m]
    d_inner: float     # [m]
    E: float           # Young's modulus [Pa]
    G: float           # shear modulus [Pa]
    rho: float         # density [kg/m^3]
    nu: float          # Poisson's ratio [-]


@dataclass(frozen=True, kw_only=True)
class Disc:
    node: int
    mass: float        # [kg]
    Ip: float          # polar moment of inertia [kg m^2]
    Id: float          # transverse (diametral) moment of inertia [kg m^2]


@dataclass
class AssembledRotor:
    """Global matrices of a free-free shaft with discs, q = [plane x; plane y]."""

    M: np.ndarray
    K: np.ndarray
    G: np.ndarray
    Ka: np.ndarray
    C: np.ndarray
    Kc: np.ndarray
    n_nodes: int
    z_nodes: np.ndarray

    def dof(self, node: int, kind: str) -> int:
        """Index of 'x', 'y' (translations) or 'bx', 'by' (slopes) of a node."""
        base = {"x": 0, "bx": 1, "y": 0, "by": 1}[kind]
        plane = 0 if kind in ("x", "bx") else 1
        return plane * 2 * self.n_nodes + 2 * node + base

    def rigid_translation(self, direction: str) -> np.ndarray:
        """Rigid-body translation vector (1 on every 'x' or 'y' dof)."""
        r = np.zeros(self.M.shape[0])
        for i in range(self.n_nodes):
            r[self.dof(i, direction)] = 1.0
        return r


def assemble(elements: list[Element], discs: list[Disc], *, shear: bool = True,
             rotary_inertia: bool = True, beta_internal: float = 0.0) -> AssembledRotor:
    """Assemble consecutive elements (node i to i+1) and discs into global matrices."""
    ne = len(elements)
    nn = ne + 1
    npl = 2 * nn
    Kp = np.zeros((npl, npl))
    Mp = np.zeros((npl, npl))
    Rp = np.zeros((npl, npl))
    for e, el in enumerate(elements):
        K, MT, MR = timoshenko_element(el.length, el.E, el.G, el.rho, el.d_outer,
                                       el.d_inner, el.nu, shear=shear)
        sl = slice(2 * e, 2 * e + 4)
        Kp[sl, sl] += K
        Mp[sl, sl] += MT + (MR if rotary_inertia else 0.0)
        Rp[sl, sl] += 2.0 * MR
    n = 2 * npl
    Z = np.zeros((npl, npl))
    M = np.block([[Mp, Z], [Z, Mp]])
    K = np.block([[Kp, Z], [Z, Kp]])
    G = np.block([[Z, Rp], [-Rp, Z]])
    Ka = np.block([[Z, Z], [-Rp, Z]])
    C = beta_internal * K
    Kc = beta_internal * np.block([[Z, Kp], [-Kp, Z]])
    z = np.concatenate([[elements[0].z0], [el.z0 + el.length for el in elements]])
    rot = AssembledRotor(M=M, K=K, G=G, Ka=Ka, C=C, Kc=Kc, n_nodes=nn, z_nodes=z)
    for d in discs:
        ix, iy = rot.dof(d.node, "x"), rot.dof(d.node, "y")
        bx, by = rot.dof(d.node, "bx"), rot.dof(d.node, "by")
        M[ix, ix] += d.mass
        M[iy, iy] += d.mass
        M[bx, bx] += d.Id
        M[by, by] += d.Id
        G[bx, by] += d.Ip
        G[by, bx] -= d.Ip
        Ka[by, bx] -= d.Ip
    assert M.shape == (n, n)
    return rot
