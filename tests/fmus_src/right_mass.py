"""RightMass: mass m2 on spring k2 / damper d2 to ground, coupled to the left
mass by the spring kc / damper dc.

    m2 * x2'' = -k2 x2 - d2 v2 - kc (x2 - x1) - dc (v2 - v1)
    F = kc (x2 - x1) + dc (v2 - v1)        (force of the coupling on the left mass)

Inputs x1, v1 are held constant over each doStep and the step is integrated
exactly with the matrix exponential of the augmented linear system
[x2, v2, x1, v1]' = M [x2, v2, x1, v1] (x1' = v1' = 0 over the step), cached per
step size. F has direct feedthrough from x1, v1 (computed when read).
"""

import numpy as np
from scipy.linalg import expm

from pythonfmu import Fmi2Causality, Fmi2Slave, Fmi2Variability, Real


class RightMass(Fmi2Slave):

    author = "rotorcosim tests"
    description = "Mass m2 with spring/damper to ground and coupling spring/damper to x1, v1; output coupling force F [N]"

    def __init__(self, **kwargs):
        super().__init__(**kwargs)
        self.m2 = 1.0
        self.k2 = 1.0
        self.d2 = 0.0
        self.kc = 1.0
        self.dc = 0.0
        self.kc_after = 1.0
        self.t_switch = 1e30
        self.x2_0 = 0.0
        self.v2_0 = 0.0
        self.x1 = 0.0
        self.v1 = 0.0
        self.x2 = 0.0
        self.v2 = 0.0
        self._cache = {}
        self._t = 0.0           # time of the state (for kc at t_switch in the output F)
        for name, desc in (("m2", "mass [kg]"), ("k2", "spring to ground [N/m]"),
                           ("d2", "damper to ground [N s/m]"), ("kc", "coupling spring [N/m]"),
                           ("dc", "coupling damper [N s/m]"),
                           ("kc_after", "coupling spring from t_switch on [N/m]"),
                           ("t_switch", "time the coupling spring changes from kc to kc_after [s]"),
                           ("x2_0", "initial position [m]"),
                           ("v2_0", "initial velocity [m/s]")):
            self.register_variable(Real(name, causality=Fmi2Causality.parameter,
                                        variability=Fmi2Variability.tunable, description=desc))
        self.register_variable(Real("x1", causality=Fmi2Causality.input, description="left mass position [m]"))
        self.register_variable(Real("v1", causality=Fmi2Causality.input, description="left mass velocity [m/s]"))
        self.register_variable(Real("F", causality=Fmi2Causality.output,
                                    description="coupling force on the left mass [N]",
                                    getter=self._force))
        self.register_variable(Real("x2", causality=Fmi2Causality.output, description="position [m]"))
        self.register_variable(Real("v2", causality=Fmi2Causality.output, description="velocity [m/s]"))
        self.register_variable(Real("t_state", causality=Fmi2Causality.local, description="time of the state [s]",
                                    getter=lambda: self._t, setter=self._set_t))

    def _set_t(self, value):
        self._t = value

    def enter_initialization_mode(self):
        self.x2 = self.x2_0
        self.v2 = self.v2_0
        self._cache = {}

    def setup_experiment(self, start_time, stop_time=None, tolerance=None):
        self._t = start_time

    def _kc(self, t):
        return self.kc_after if t >= self.t_switch else self.kc

    def _force(self):
        return self._kc(self._t) * (self.x2 - self.x1) + self.dc * (self.v2 - self.v1)

    def do_step(self, current_time, step_size):
        t_end = current_time + step_size
        if current_time < self.t_switch < t_end:
            self._advance(self.t_switch - current_time, self.kc)
            self._advance(t_end - self.t_switch, self.kc_after)
        else:
            self._advance(step_size, self._kc(current_time))
        self._t = t_end
        return True

    def _advance(self, step_size, kc):
        E = self._cache.get((step_size, kc))
        if E is None:
            m2, k2, d2, dc = self.m2, self.k2, self.d2, self.dc
            M = np.array([[0.0, 1.0, 0.0, 0.0],
                          [-(k2 + kc) / m2, -(d2 + dc) / m2, kc / m2, dc / m2],
                          [0.0, 0.0, 0.0, 0.0],
                          [0.0, 0.0, 0.0, 0.0]])
            E = expm(M * step_size)
            if len(self._cache) > 64:
                self._cache.clear()
            self._cache[(step_size, kc)] = E
        z = E @ np.array([self.x2, self.v2, self.x1, self.v1])
        self.x2 = float(z[0])
        self.v2 = float(z[1])
