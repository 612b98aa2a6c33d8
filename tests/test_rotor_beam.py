"""Shaft finite elements against analytical beam theory and gyroscopic closed forms.

References: Timoshenko pinned-pinned frequency equation (e.g. Han, Benaroya & Wei 1999,
J. Sound Vib. 225:935, "Dynamics of transversely vibrating beams using four engineering
theories"); free-free Euler-Bernoulli cosh(l) cos(l) = 1 (Blevins 1979, "Formulas for
natural frequency and mode shape", table 8-1); overhung disc on a massless cantilever
(Friswell et al. 2010, "Dynamics of Rotating Machines", sec. 3.6: gyroscopic split of
forward/backward whirl).
"""

import numpy as np
import pytest
import scipy.linalg as sla

from rotor_fmu.beam import Disc, Element, assemble, cowper_kappa, section_properties

E, NU, RHO = 2.1e11, 0.3, 7850.0
G = E / (2 * (1 + NU))


def uniform(L, d, ne, **kw):
    els = [Element(z0=i * L / ne, length=L / ne, d_outer=d, d_inner=0.0, E=E, G=G, rho=RHO, nu=NU)
           for i in range(ne)]
    return assemble(els, [], **kw)


def plane_freqs(rot, fixed=()):
    npl = 2 * rot.n_nodes
    keep = [i for i in range(npl) if i not in fixed]
    M = rot.M[np.ix_(keep, keep)]
    K = rot.K[np.ix_(keep, keep)]
    return np.sqrt(np.abs(sla.eigh(K, M, eigvals_only=True)))


def timoshenko_pinned(L, d, n):
    A, I = section_properties(d)
    kap = cowper_kappa(NU, d)
    k = n * np.pi / L
    kga = kap * G * A
    # det [[kGA k^2 - rho A w^2, -kGA k], [-kGA k, EI k^2 + kGA - rho I w^2]] = 0
    a = RHO * A * RHO * I
    b = -(RHO * A * (E * I * k * k + kga) + RHO * I * kga * k * k)
    c = kga * k * k * (E * I * k * k + kga) - (kga * k) ** 2
    return np.sqrt(np.min(np.roots([a, b, c]).real))


def test_timoshenko_pinned_pinned_thick_shaft_converges_to_closed_form():
    L, d = 0.5, 0.05          # L/d = 10: shear and rotary inertia matter (~3 % on mode 3)
    ref = np.array([timoshenko_pinned(L, d, n) for n in (1, 2, 3)])
    A, I = section_properties(d)
    eb = (np.arange(1, 4) * np.pi / L) ** 2 * np.sqrt(E * I / (RHO * A))
    assert np.all(ref < eb * 0.999)          # the test is sensitive to the Timoshenko terms
    errs = []
    for ne in (8, 16, 32):
        rot = uniform(L, d, ne)
        w = plane_freqs(rot, fixed=(0, 2 * ne))[:3]
        errs.append(np.abs(w / ref - 1))
    assert np.all(errs[-1] < 5e-4)
    assert np.all(errs[1] < errs[0]) and np.all(errs[2] < errs[1])


def test_euler_bernoulli_free_free_fourth_order_convergence():
    L, d = 1.0, 0.02
    A, I = section_properties(d)
    lam = np.array([4.730040745, 7.853204624, 10.99560784])
    ref = lam**2 / L**2 * np.sqrt(E * I / (RHO * A))
    errs = []
    for ne in (4, 8, 16):
        w = plane_freqs(uniform(L, d, ne, shear=False, rotary_inertia=False))
        assert np.all(w[:2] < 1e-3 * ref[0])       # two rigid-body modes per plane
        errs.append(w[2:5] / ref - 1)
    errs = np.array(errs)
    assert np.all(errs > 0)                         # consistent mass: upper bounds
    assert np.all(np.abs(errs[-1]) < 2e-4)
    rate = np.log2(errs[1] / errs[2])
    assert np.all(rate > 3.5)                       # O(h^4)


@pytest.mark.parametrize("Om", [0.0, 500.0, 2000.0, 5000.0])
def test_overhung_disc_gyroscopic_whirl_split(Om):
    """Rigid disc at the tip of a (nearly) massless cantilever: the four whirl
    frequencies from the FE model vs the closed-form quartic
    det [[k11 - m w^2, k12], [k12, k22 - Id w^2 + Ip Om w]] = 0 (w > 0 forward,
    w < 0 backward) with the Euler-Bernoulli tip stiffness EI/L^3 [[12, -6L], [-6L, 4L^2]]."""
    L, d = 0.3, 0.02
    m, Id, Ip = 5.0, 0.02, 0.04
    els = [Element(z0=i * L / 6, length=L / 6, d_outer=d, d_inner=0.0, E=E, G=1e6 * G,
                   rho=1e-6, nu=NU) for i in range(6)]
    rot = assemble(els, [Disc(node=6, mass=m, Ip=Ip, Id=Id)], shear=False)
    n = rot.M.shape[0]
    fixed = [rot.dof(0, k) for k in ("x", "bx", "y", "by")]
    keep = [i for i in range(n) if i not in fixed]
    M = rot.M[np.ix_(keep, keep)]
    K = rot.K[np.ix_(keep, keep)]
    Gm = rot.G[np.ix_(keep, keep)]
    nk = len(keep)
    A = np.block([[np.zeros((nk, nk)), np.eye(nk)], [-np.linalg.solve(M, K), -np.linalg.solve(M, Om * Gm)]])
    lam = np.linalg.eigvals(A)
    w_fe = np.sort(np.abs(lam.imag[lam.imag > 0]))[:2]
    _, I = section_properties(d)
    k11, k12, k22 = 12 * E * I / L**3, -6 * E * I / L**2, 4 * E * I / L
    # (k11 - m w^2)(k22 - Id w^2 + Ip Om w) - k12^2 = 0
    p = np.polymul([-m, 0, k11], [-Id, Ip * Om, k22])
    p[-1] -= k12**2
    roots = np.roots(p).real
    fwd = np.sort(roots[roots > 0])
    bwd = np.sort(-roots[roots < 0])
    ref = np.sort(np.concatenate([fwd, bwd]))[:2]
    np.testing.assert_allclose(w_fe, ref, rtol=2e-5)
    if Om > 0:
        assert fwd[0] > bwd[0]          # forward whirl stiffened, backward softened
    # the FE eigenvector of the lowest forward mode whirls CCW (same sense as the spin)
    lam1 = lam[np.argmin(np.abs(lam - 1j * fwd[0]))]
    assert abs(lam1.imag - fwd[0]) < 1e-4 * fwd[0]


def test_free_rigid_disc_nutation_is_forward_ip_over_id():
    """A free rigid spinning body: nutation at Ip/Id * Omega, forward (checks the sign
    of the gyroscopic matrix against the spin direction)."""
    rot = assemble([Element(z0=0.0, length=0.01, d_outer=0.01, d_inner=0.0, E=E, G=G, rho=1e-9, nu=NU)],
                   [Disc(node=0, mass=1.0, Ip=0.03, Id=0.02)], shear=False)
    Om = 100.0
    idx = [rot.dof(0, "bx"), rot.dof(0, "by")]
    M = rot.M[np.ix_(idx, idx)]
    Gm = rot.G[np.ix_(idx, idx)]
    # Id b'' + Om G b' = 0 -> b = B exp(i w t), forward if (bx, by) ~ (1, -i)·... rotate CCW
    A = -np.linalg.solve(M, Om * Gm)
    lam = np.linalg.eigvals(A)
    w = np.max(np.abs(lam.imag))
    assert w == pytest.approx(0.03 / 0.02 * Om, rel=1e-6)
    # CCW check: from bx = cos(wt), by = sin(wt): Id b'' + Ip Om [by', -bx'] = 0
    t = 0.3
    wt = 0.03 / 0.02 * Om
    b = np.array([np.cos(wt * t), np.sin(wt * t)])
    bd = wt * np.array([-np.sin(wt * t), np.cos(wt * t)])
    bdd = -wt**2 * b
    np.testing.assert_allclose(M @ bdd + Om * Gm @ bd, 0.0, atol=1e-9)
