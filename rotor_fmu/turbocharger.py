"""Flexible turbocharger rotor (paper section 3.3) from a rotor file, optionally reduced.

The shaft is modelled with Timoshenko beam elements with gyroscopic matrices
(:mod:`rotor_fmu.beam`), the wheels as rigid discs (mass, polar and transverse
inertia, unbalance); the film forces act on the translations of the bearing-station
nodes.  Default rotor: ``rotor_fmu/data/turbocharger.yaml`` (6 kg, 3 g mm, heavier
turbine wheel, no external damping).

Reduction (default on): Craig-Bampton (Craig & Bampton 1968, AIAA J. 6:1313) per
bending plane, with the *translations of the bearing stations and of the wheel
centres* kept as physical boundary dofs (static constraint modes = static correction
at the bearing stations and at the unbalance load points) plus ``n_modes``
fixed-interface normal modes per plane, plus one static-correction vector for the
distributed gravity load (so the static sag is exact).  The same transformation ``T`` (identical in
both planes) projects M, K, G, Ka, C, Kc and the gravity load, so gyroscopic coupling,
rotating damping and loads stay consistent.  Accuracy vs the full model: see
``docs/rotor-models.md`` and ``tests/test_rotor_turbocharger.py``.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import scipy.linalg as sla

from .beam import assemble
from .drive import make_profile
from .linear_rotor import LinearRotor
from .param_ranges import range_problems
from .rotor_file import RotorDefinition, load_rotor_file

__all__ = ["TurbochargerParams", "TurbochargerRotor", "load_rotor_file", "craig_bampton"]


@dataclass(frozen=True, kw_only=True)
class TurbochargerParams:
    """Parameters of :class:`TurbochargerRotor` (SI units); defaults from the paper."""

    rotor_file: str | None = None      # YAML rotor file; None -> rotor_fmu/data/turbocharger.yaml
    f_max: float = 105.0               # ramp end speed [Hz] (paper: 105 Hz)
    t_ramp: float = 7.0                # ramp duration [s] (paper: 7 s)
    speed_table: object = None         # optional {"t": [...], "f": [...]} instead of the ramp
    g: float = 9.81                    # gravity [m/s^2] in -y
    t0: float = 0.0                    # start time [s]
    journal_x0: float = 0.0            # initial x of every bearing station [m]
    journal_y0: float = 0.0            # initial y of every bearing station [m]
    journal_dx0_2: float = 0.0         # station 2 starts at (journal_x0 + journal_dx0_2,
    journal_dy0_2: float = 0.0         #   journal_y0 + journal_dy0_2) [m] (unequal bearing loads)
    initial_sag: bool = True           # start in static equilibrium with the stations held
    reduce: bool = True                # Craig-Bampton reduction (False: full FE model)
    n_modes: int | None = None         # fixed-interface modes per plane (None: from the file)
    shear: bool = True                 # Timoshenko (True) or Euler-Bernoulli elements
    max_phase_per_substep: float = 0.25  # omega_max * h bound of the internal sub-steps [rad]

    def validate(self) -> None:
        problems = range_problems(self, "TurbochargerParams")      # the FMU declares the same ranges
        if self.n_modes is not None and not (isinstance(self.n_modes, int) or float(self.n_modes).is_integer()):
            problems.append(f"TurbochargerParams.n_modes must be an integer >= 0 or None "
                            f"(got {self.n_modes!r})")
        if problems:
            raise ValueError("; ".join(problems))


def craig_bampton(M, K, boundary, n_modes, loads=()):
    """Craig-Bampton basis T (n x (nb + n_modes + len(loads))) of a symmetric (M, K)
    plane model.

    ``q = T [q_b; eta]`` with ``q_b`` the boundary dofs (in the given order) and ``eta``
    the amplitudes of the ``n_modes`` lowest fixed-interface modes (mass-normalized),
    followed by one static-correction vector per distributed load in ``loads`` (the
    fixed-interface static deflection ``K_ii^-1 f_i``, M-orthogonalized against the
    modes), so that the statics under those loads are exact (used for gravity).
    """
    n = M.shape[0]
    b = np.asarray(boundary, int)
    i = np.setdiff1d(np.arange(n), b)
    Kii = K[np.ix_(i, i)]
    try:
        Psi = -np.linalg.solve(Kii, K[np.ix_(i, b)])
    except np.linalg.LinAlgError:
        raise ValueError("Craig-Bampton: the structure with the boundary dofs held is not "
                         "statically determinate (singular K_ii); give at least two bearing "
                         "stations / discs") from None
    Mii = M[np.ix_(i, i)]
    vecs = []
    if n_modes > len(i):      # scipy said "Requested eigenvalue indices are not valid. Valid range is [0, 63]"
        raise ValueError(f"Craig-Bampton: {n_modes} fixed-interface modes per plane asked for, but the shaft has "
                         f"only {len(i)} (its degrees of freedom per plane with the bearing and disc nodes held); "
                         f"use at most {len(i)}: 'reduction.n_modes' of the rotor file, or the rotor's n_modes "
                         "parameter (or a finer shaft: a smaller 'shaft.max_element_length')")
    if n_modes > 0:
        lam, Phi = sla.eigh(Kii, Mii, subset_by_index=[0, n_modes - 1])
        vecs = [Phi[:, k] for k in range(n_modes)]
    for f in loads:
        u = np.linalg.solve(Kii, np.asarray(f, float)[i])
        for w in vecs:
            u = u - (w @ Mii @ u) / (w @ Mii @ w) * w
        nrm = np.sqrt(u @ Mii @ u)
        if nrm > 1e-12 * np.sqrt(np.abs(np.linalg.solve(Kii, np.asarray(f, float)[i])) @ Mii
                                 @ np.abs(np.linalg.solve(Kii, np.asarray(f, float)[i]))):
            vecs.append(u / nrm)
    T = np.zeros((n, len(b) + len(vecs)))
    T[b, np.arange(len(b))] = 1.0
    T[np.ix_(i, np.arange(len(b)))] = Psi
    for k, w in enumerate(vecs):
        T[i, len(b) + k] = w
    return T


class TurbochargerRotor(LinearRotor):
    """Flexible rotor with rigid wheels from a rotor file; API in docs/dev/contracts.md.

    Extra outputs per wheel ``<name>``: ``x_<name>, y_<name>, vx_<name>, vy_<name>``
    (default file: ``comp``, ``turb``).
    """

    def __init__(self, params: TurbochargerParams | None = None, *,
                 rotor: RotorDefinition | None = None):
        p = TurbochargerParams() if params is None else params
        p.validate()
        self.params = p
        rd = rotor if rotor is not None else load_rotor_file(p.rotor_file)
        self.rotor_def = rd
        fe = assemble(rd.elements, rd.fe_discs(), shear=p.shear, beta_internal=rd.internal_damping)
        self.fe = fe
        f_g_full = -p.g * (fe.M @ fe.rigid_translation("y"))
        nb = len(rd.bearing_nodes)
        # boundary nodes, each once (a disc may sit on a bearing station, e.g. a journal sleeve)
        point_nodes = list(dict.fromkeys(list(rd.bearing_nodes) + list(rd.disc_nodes)))
        npl = 2 * fe.n_nodes
        if p.reduce:
            n_modes = rd.n_modes if p.n_modes is None else int(p.n_modes)
            Mp, Kp = fe.M[:npl, :npl], fe.K[:npl, :npl]
            # static correction for the distributed gravity load (plane y == plane x)
            Tp = craig_bampton(Mp, Kp, [2 * nd for nd in point_nodes], n_modes,
                               loads=[f_g_full[npl:]])
            T = sla.block_diag(Tp, Tp)
            nr = Tp.shape[1]
            mats = [T.T @ A @ T for A in (fe.M, fe.C, fe.G, fe.K, fe.Kc, fe.Ka)]
            f_g = T.T @ f_g_full
            xdof = {nd: k for k, nd in enumerate(point_nodes)}
            ydof = {nd: nr + k for k, nd in enumerate(point_nodes)}
            self.T = T
        else:
            mats = [fe.M, fe.C, fe.G, fe.K, fe.Kc, fe.Ka]
            f_g = f_g_full
            xdof = {nd: fe.dof(nd, "x") for nd in point_nodes}
            ydof = {nd: fe.dof(nd, "y") for nd in point_nodes}
            self.T = None
        M, C, G, K, Kc, Ka = [0.5 * (A + A.T) if k in (0, 3) else A for k, A in enumerate(mats)]
        extra = {}
        unb = []
        for k, (d, nd) in enumerate(zip(rd.discs, rd.disc_nodes), 1):
            for name in (d.name, f"disc{k}"):      # by name, and by position in the file (FMU outputs)
                extra[f"x_{name}"] = ("q", xdof[nd])
                extra[f"y_{name}"] = ("q", ydof[nd])
                extra[f"vx_{name}"] = ("v", xdof[nd])
                extra[f"vy_{name}"] = ("v", ydof[nd])
            if d.unbalance > 0:
                unb.append((xdof[nd], ydof[nd], d.unbalance, d.unbalance_phase))
        self._setup(
            M=M, C=C, G=G, K=K, Kc=Kc, Ka=Ka,
            bearing_dofs=[[xdof[nd], ydof[nd]] for nd in rd.bearing_nodes],
            unbalances=unb, f_g=f_g,
            drive=make_profile(f_max=p.f_max, t_ramp=p.t_ramp, speed_table=p.speed_table),
            t0=p.t0, max_phase_per_substep=p.max_phase_per_substep,
            extra_outputs=extra,
            journal_q0=[[p.journal_x0 + (p.journal_dx0_2 if k == 1 else 0.0),
                         p.journal_y0 + (p.journal_dy0_2 if k == 1 else 0.0)] for k in range(nb)],
            initial_sag=p.initial_sag,
        )

    def full_displacements(self, s=None) -> np.ndarray:
        """Physical FE dofs q (full model order) from a (reduced) state s."""
        s = self.s if s is None else np.asarray(s, float)
        q = s[:self.n_dof]
        return q if self.T is None else self.T @ q
