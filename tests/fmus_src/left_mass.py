"""LeftMass: mass m1 on spring k1 to ground, driven by the coupling force F.

    m1 * x1'' = -k1 * x1 + F

The input F is held constant over each doStep (FMI semantics without input
derivatives) and the step is integrated exactly (closed form of the undamped
oscillator with a constant force), so any error seen by a test is a coupling
error, not an integration error. Outputs x1, v1 are states (no feedthrough).
"""

import math

from pythonfmu import Fmi2Causality, Fmi2Slave, Fmi2Variability, Real


class LeftMass(Fmi2Slave):

    author = "rotorcosim tests"
    description = "Mass m1 on spring k1 to ground; input force F [N]; outputs x1 [m], v1 [m/s]"

    def __init__(self, **kwargs):
        super().__init__(**kwargs)
        self.m1 = 1.0
        self.k1 = 1.0
        self.x1_0 = 1.0
        self.v1_0 = 0.0
        self.F = 0.0
        self.x1 = 1.0
        self.v1 = 0.0
        for name, desc in (("m1", "mass [kg]"), ("k1", "spring to ground [N/m]"),
                           ("x1_0", "initial position [m]"), ("v1_0", "initial velocity [m/s]")):
            self.register_variable(Real(name, causality=Fmi2Causality.parameter,
                                        variability=Fmi2Variability.tunable, description=desc))
        self.register_variable(Real("F", causality=Fmi2Causality.input, description="force on the mass [N]"))
        self.register_variable(Real("x1", causality=Fmi2Causality.output, description="position [m]"))
        self.register_variable(Real("v1", causality=Fmi2Causality.output, description="velocity [m/s]"))

    def enter_initialization_mode(self):
        self.x1 = self.x1_0
        self.v1 = self.v1_0

    def do_step(self, current_time, step_size):
        w = math.sqrt(self.k1 / self.m1)
        xe = self.F / self.k1
        c, s = math.cos(w * step_size), math.sin(w * step_size)
        dx = self.x1 - xe
        self.x1 = xe + dx * c + self.v1 / w * s
        self.v1 = -dx * w * s + self.v1 * c
        return True
