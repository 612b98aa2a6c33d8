"""Trivial: y = u, nothing else (for the master-overhead benchmark)."""

from pythonfmu import Fmi2Causality, Fmi2Slave, Real


class Trivial(Fmi2Slave):

    author = "rotorcosim tests"
    description = "Pass-through y = u with no physics"

    def __init__(self, **kwargs):
        super().__init__(**kwargs)
        self.u = 0.0
        self.y = 0.0
        self.register_variable(Real("u", causality=Fmi2Causality.input, description="input [-]"))
        self.register_variable(Real("y", causality=Fmi2Causality.output, description="output [-]"))

    def do_step(self, current_time, step_size):
        self.y = self.u
        return True
