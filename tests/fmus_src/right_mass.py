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
        self.x2_0 = 0.0
        self.v2_0 = 0.0
        self.x1 = 0.0
        self.v1 = 0.0
        self.x2 = 0.0
        self.v2 = 0.0
        self._cache = {}
        for name, desc in (("m2", "mass [kg]"), ("k2", "spring to ground [N/m]"),
                           ("d2", "damper to ground [N s/m]"), ("kc", "coupling spring [N/m]"),
                           ("dc", "coupling damper [N s/m]"), ("x2_0", "initial position [m]"),
                           ("v2_0", "initial velocity [m/s]")):
            self.register_variable(Real(name, causality=Fmi2Causality.parameter,
                                        variability=Fmi2Variability.tunable, description=desc))
        self.register_variable(Real("x1", causality=Fmi2Causality.input, description="left mass position [m]"))
        self.register_variable(Real("v1", causality=Fmi2Causality.input, description="left mass velocity [m/s]"))
        self.register_variable(Real("F", causality=Fmi2Causality.output,
                                    description="coupling force on the left mass [N]",
                                    getter=lambda: self.kc * (self.x2 - self.x1) + self.dc * (self.v2 - self.v1)))
        self.register_variable(Real("x2", causality=Fmi2Causality.output, description="position [m]"))
        self.register_variable(Real("v2", causality=Fmi2Causality.output, description="velocity [m/s]"))

    def enter_initialization_mode(self):
        self.x2 = self.x2_0
        self.v2 = self.v2_0
        self._cache = {}

    def do_step(self, current_time, step_size):
        E = self._cache.get(step_size)
        if E is None:
            m2, k2, d2, kc, dc = self.m2, self.k2, self.d2, self.kc, self.dc
            M = np.array([[0.0, 1.0, 0.0, 0.0],
                          [-(k2 + kc) / m2, -(d2 + dc) / m2, kc / m2, dc / m2],
                          [0.0, 0.0, 0.0, 0.0],
                          [0.0, 0.0, 0.0, 0.0]])
            E = expm(M * step_size)
            if len(self._cache) > 64:
                self._cache.clear()
            self._cache[step_size] = E
        z = E @ np.array([self.x2, self.v2, self.x1, self.v1])
        self.x2 = float(z[0])
        self.v2 = float(z[1])
        return True
