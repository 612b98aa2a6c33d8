"""StepLimitedMass: LeftMass (m1 * x1'' = -k1 * x1 + F, integrated exactly with F
held over the step) that returns fmi2Discard for a doStep longer than `h_max`
that overlaps the time window [t_lo, t_hi).

Before discarding it corrupts its state (x1 = v1 = NaN), as a failed solver
might: the master has to restore the state it saved (fmi2SetFMUstate) before it
retries with smaller steps. With the defaults it never discards. Used by
tests/test_master_retry.py (built there with canGetAndSetFMUstate).
"""

import math

from pythonfmu import Fmi2Causality, Fmi2Slave, Fmi2Variability, Real


class StepLimitedMass(Fmi2Slave):

    author = "rotorcosim tests"
    description = "LeftMass that discards steps longer than h_max inside [t_lo, t_hi)"

    def __init__(self, **kwargs):
        super().__init__(**kwargs)
        self.m1 = 1.0
        self.k1 = 1.0
        self.x1_0 = 1.0
        self.v1_0 = 0.0
        self.h_max = 1e9
        self.t_lo = 0.0
        self.t_hi = 1e9
        self.F = 0.0
        self.x1 = 1.0
        self.v1 = 0.0
        for name, desc in (("m1", "mass [kg]"), ("k1", "spring to ground [N/m]"),
                           ("x1_0", "initial position [m]"), ("v1_0", "initial velocity [m/s]"),
                           ("h_max", "longest step accepted inside [t_lo, t_hi) [s]"),
                           ("t_lo", "start of the window where long steps are discarded [s]"),
                           ("t_hi", "end of that window [s]")):
            self.register_variable(Real(name, causality=Fmi2Causality.parameter,
                                        variability=Fmi2Variability.tunable, description=desc))
        self.register_variable(Real("F", causality=Fmi2Causality.input, description="force on the mass [N]"))
        self.register_variable(Real("x1", causality=Fmi2Causality.output, description="position [m]"))
        self.register_variable(Real("v1", causality=Fmi2Causality.output, description="velocity [m/s]"))

    def enter_initialization_mode(self):
        self.x1 = self.x1_0
        self.v1 = self.v1_0

    def do_step(self, current_time, step_size):
        t_end = current_time + step_size
        if step_size > self.h_max * (1 + 1e-9) and current_time < self.t_hi and t_end > self.t_lo:
            self.x1 = self.v1 = float("nan")
            return False
        w = math.sqrt(self.k1 / self.m1)
        xe = self.F / self.k1
        c, s = math.cos(w * step_size), math.sin(w * step_size)
        dx = self.x1 - xe
        self.x1 = xe + dx * c + self.v1 / w * s
        self.v1 = -dx * w * s + self.v1 * c
        return True
