"""Switches: a third-party style FMU with Integer parameters named as our bearing's switches
(``contact``, ``cavitation``, ``axial_bc``, ``theta_transport``) but meaning something else:
``contact`` declares no names for its values, the others a malformed list of names
(tests/test_switch_names.py: their sweep axes keep the numbers). Output ``y``: the sum of
the parameters."""

from pythonfmu import Fmi2Causality, Fmi2Slave, Fmi2Variability, Integer, Real

DESCRIPTIONS = {
    "contact": "contact points of the gear mesh in this model [-]",           # no names
    "cavitation": "pump model (0 = half-Sommerfeld, one = mass-conserving)",  # a value that is no integer
    "axial_bc": "valve (0 = oil bath, 0 = free to air)",                      # a value twice
    "theta_transport": "filter (0 = upwind, 1 = MUSCL (limited))",            # a name with brackets
}


class Switches(Fmi2Slave):

    author = "rotorcosim tests"
    description = "Integer parameters named as rotorcosim's bearing switches, without valid value names"

    def __init__(self, **kwargs):
        super().__init__(**kwargs)
        for name, desc in DESCRIPTIONS.items():
            setattr(self, name, 0)
            self.register_variable(Integer(name, causality=Fmi2Causality.parameter,
                                           variability=Fmi2Variability.tunable, description=desc))
        self.register_variable(Real("y", causality=Fmi2Causality.output, description="sum of the parameters [-]",
                                    getter=lambda: float(sum(getattr(self, n) for n in DESCRIPTIONS))))

    def do_step(self, current_time, step_size):
        return True
