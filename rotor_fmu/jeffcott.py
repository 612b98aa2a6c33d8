"""Symmetric Jeffcott rotor with two journals (paper section 3.2).

Degrees of freedom ``q = [x_d, y_d, x_1, y_1, x_2, y_2]`` (disc centre, journal 1,
journal 2; x horizontal, y up, metres).  The shaft stiffness ``k_shaft`` (4000 N/mm)
is the stiffness of the disc relative to the journals (both journals held): it is
split equally between the two massless shaft halves, ``k_h = k_shaft / 2`` each, which
act in parallel on the disc.  The internal (rotating) shaft damping ``d_internal`` is
split the same way, ``d_h = d_internal / 2`` per half, so that with the journals held
the disc sees ``k_shaft`` and ``d_internal``.

Force of half j on the disc, with the deflection ``delta = r_d - r_j`` (fixed frame,
rotating damping written in the fixed frame, e.g. Genta 2005 "Dynamics of Rotating
Systems" sec. 6.2; Friswell et al. 2010 sec. 5.4)::

    F_j = -k_h delta - d_h (delta' - Omega e_z x delta)
        = -k_h delta - d_h delta' - Omega d_h [delta_y, -delta_x]

(the journal gets -F_j).  External viscous damping ``d_external`` acts on the disc
centre (absolute velocity).  Gravity acts in -y on disc and journals.  The unbalance
``m e`` sits on the disc at phase ``unbalance_phase`` relative to the drive angle.

Journal mass ``m_journal``: the part of the shaft inside each bearing (default 0.1 kg,
i.e. 1/60 of the disc; a solid steel journal of R = 20 mm, B = 32 mm would weigh
0.32 kg).  With the journals held by nothing but the shaft, each journal has a mode
at sqrt(k_h / m_journal) = 4472 rad/s (712 Hz); on a film of stiffness k_f it moves
to ~ sqrt((k_h + k_f) / m_journal), which makes the coupled problem stiff.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from .drive import make_profile
from .linear_rotor import LinearRotor
from .param_ranges import range_problems


@dataclass(frozen=True, kw_only=True)
class JeffcottParams:
    """Parameters of :class:`JeffcottModel` (SI units); defaults are the paper's values."""

    m_disc: float = 6.0                # disc mass [kg] (paper: rotor mass 6 kg)
    m_journal: float = 0.1             # mass of each journal [kg] (our choice, see module doc)
    unbalance: float = 3.0e-6          # m e [kg m] (paper: 3 g mm)
    unbalance_phase: float = 0.0       # phase of the unbalance vs the drive angle [rad]
    k_shaft: float = 4.0e6             # disc-to-journals stiffness [N/m] (paper: 4000 N/mm)
    d_internal: float = 0.1            # rotating shaft damping [N s/m] (paper: 0.1 Ns/m)
    d_external: float = 500.0          # non-rotating viscous damping on the disc [N s/m] (paper: 500)
    g: float = 9.81                    # gravity [m/s^2], acting in -y
    f_max: float = 800.0               # ramp end speed [Hz] (paper: 800 Hz)
    t_ramp: float = 2.0                # ramp duration [s] (paper: 2 s)
    speed_table: object = None         # optional {"t": [...], "f": [...]} [s], [Hz] instead of the ramp
    t0: float = 0.0                    # start time [s]
    journal_x0: float = 0.0            # initial journal x (both journals) [m]
    journal_y0: float = 0.0            # initial journal y (both journals) [m]
    initial_sag: bool = True           # disc starts at its static sag below the journals
    max_phase_per_substep: float = 0.25  # omega_max * h bound of the internal sub-steps [rad]

    def validate(self) -> None:
        problems = range_problems(self, "JeffcottParams")      # the FMU declares the same ranges
        if problems:
            raise ValueError("; ".join(problems))


class JeffcottModel(LinearRotor):
    """Jeffcott rotor with two journals; API in docs/dev/contracts.md.

    Extra outputs: ``x_disc, y_disc, vx_disc, vy_disc`` [m, m/s].
    """

    def __init__(self, params: JeffcottParams | None = None):
        p = JeffcottParams() if params is None else params
        p.validate()
        self.params = p
        md, mj = p.m_disc, p.m_journal
        M = np.diag([md, md, mj, mj, mj, mj])
        kh, dh = 0.5 * p.k_shaft, 0.5 * p.d_internal
        I2 = np.eye(2)
        S = np.array([[0.0, 1.0], [-1.0, 0.0]])   # F = -Omega d_h S delta  <=>  Omega d_h [-dy, dx]
        K = np.zeros((6, 6))
        C = np.zeros((6, 6))
        Kc = np.zeros((6, 6))
        for j in (1, 2):
            d, b = slice(0, 2), slice(2 * j, 2 * j + 2)
            for (r, c_, sgn) in ((d, d, 1.0), (d, b, -1.0), (b, d, -1.0), (b, b, 1.0)):
                K[r, c_] += sgn * kh * I2
                C[r, c_] += sgn * dh * I2
                Kc[r, c_] += sgn * dh * S
        C[0:2, 0:2] += p.d_external * I2
        f_g = -p.g * np.array([0.0, md, 0.0, mj, 0.0, mj])
        self._setup(
            M=M, C=C, G=np.zeros((6, 6)), K=K, Kc=Kc, Ka=np.zeros((6, 6)),
            bearing_dofs=[[2, 3], [4, 5]],
            unbalances=[(0, 1, p.unbalance, p.unbalance_phase)],
            f_g=f_g,
            drive=make_profile(f_max=p.f_max, t_ramp=p.t_ramp, speed_table=p.speed_table),
            t0=p.t0, max_phase_per_substep=p.max_phase_per_substep,
            extra_outputs={"x_disc": ("q", 0), "y_disc": ("q", 1),
                           "vx_disc": ("v", 0), "vy_disc": ("v", 1)},
            journal_q0=[[p.journal_x0, p.journal_y0]] * 2,
            initial_sag=p.initial_sag,
        )
