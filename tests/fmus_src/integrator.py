"""Integrator: x' = u, y = x (input held over the step, so the step is exact).

Also has a `time` output (the end time of the last step) so that tests can
check that the master passes the right communication points, and supports
FMU state save/restore (canGetAndSetFMUstate) through local variables.
"""

from pythonfmu import Fmi2Causality, Fmi2Slave, Fmi2Variability, Real


class Integrator(Fmi2Slave):

    author = "rotorcosim tests"
    description = "Integrator y(t) = y0 + int u dt"

    def __init__(self, **kwargs):
        super().__init__(**kwargs)
        self.y0 = 0.0
        self.u = 0.0
        self.y = 0.0
        self.time = 0.0
        self.register_variable(Real("y0", causality=Fmi2Causality.parameter,
                                    variability=Fmi2Variability.tunable, description="initial value [-]"))
        self.register_variable(Real("u", causality=Fmi2Causality.input, description="rate [1/s]"))
        self.register_variable(Real("y", causality=Fmi2Causality.output, description="integral [-]"))
        self.register_variable(Real("time", causality=Fmi2Causality.output, description="time reached [s]"))

    def enter_initialization_mode(self):
        self.y = self.y0

    def do_step(self, current_time, step_size):
        self.y += self.u * step_size
        self.time = current_time + step_size
        return True
