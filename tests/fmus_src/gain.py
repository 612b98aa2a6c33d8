"""Gain: y = k * u (direct feedthrough, no state). Third-party style test FMU."""

from pythonfmu import Fmi2Causality, Fmi2Slave, Fmi2Variability, Real


class Gain(Fmi2Slave):

    author = "rotorcosim tests"
    description = "Static gain y = k*u"

    def __init__(self, **kwargs):
        super().__init__(**kwargs)
        self.k = 1.0
        self.u = 0.0
        self.register_variable(Real("k", causality=Fmi2Causality.parameter,
                                    variability=Fmi2Variability.tunable, description="gain [-]"))
        self.register_variable(Real("u", causality=Fmi2Causality.input, description="input [-]"))
        self.register_variable(Real("y", causality=Fmi2Causality.output, description="output k*u [-]",
                                    getter=lambda: self.k * self.u))

    def do_step(self, current_time, step_size):
        return True
