"""NamedSwitches: a third-party style FMU whose Integer parameter ``contact`` (a clutch) declares
the names of its values as rotorcosim's FMUs do, at the end of its description (docs/fmus.md,
"Names of switch values"): a sweep's axis over it shows these names, not our bearing's."""

from pythonfmu import Fmi2Causality, Fmi2Slave, Fmi2Variability, Integer, Real


class NamedSwitches(Fmi2Slave):

    author = "rotorcosim tests"
    description = "An Integer switch that names its values"

    def __init__(self, **kwargs):
        super().__init__(**kwargs)
        self.contact = 0
        self.register_variable(Integer("contact", causality=Fmi2Causality.parameter,
                                       variability=Fmi2Variability.tunable,
                                       description="clutch of the drive train (0 = open, 1 = slipping, 2 = locked)"))
        self.register_variable(Real("y", causality=Fmi2Causality.output, description="the clutch state [-]",
                                    getter=lambda: float(self.contact)))

    def do_step(self, current_time, step_size):
        return True
