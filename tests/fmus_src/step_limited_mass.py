"""StepLimitedMass: LeftMass (m1 * x1'' = -k1 * x1 + F, integrated exactly with F
held over the step) that returns fmi2Discard for a doStep longer than `h_max`
that overlaps the time window [t_lo, t_hi).

Before discarding it corrupts its state (x1 = v1 = NaN), as a failed solver
might: the master has to restore the state it saved (fmi2SetFMUstate) before it
retries with smaller steps. With the defaults it never discards. Used by
tests/test_master_retry.py (built there with canGetAndSetFMUstate).
"""

from left_mass import LeftMass      # bundled with this FMU (project file, tests/conftest.py)
from pythonfmu import Fmi2Causality, Fmi2Variability, Real


class StepLimitedMass(LeftMass):

    author = "rotorcosim tests"
    description = "LeftMass that discards steps longer than h_max inside [t_lo, t_hi)"

    def __init__(self, **kwargs):
        super().__init__(**kwargs)
        self.h_max = 1e9
        self.t_lo = 0.0
        self.t_hi = 1e9
        for name, desc in (("h_max", "longest step accepted inside [t_lo, t_hi) [s]"),
                           ("t_lo", "start of the window where long steps are discarded [s]"),
                           ("t_hi", "end of that window [s]")):
            self.register_variable(Real(name, causality=Fmi2Causality.parameter,
                                        variability=Fmi2Variability.tunable, description=desc))

    def do_step(self, current_time, step_size):
        t_end = current_time + step_size
        if step_size > self.h_max * (1 + 1e-9) and current_time < self.t_hi and t_end > self.t_lo:
            self.x1 = self.v1 = float("nan")
            return False
        return super().do_step(current_time, step_size)
