"""TypedPorts: Integer, Boolean and String ports on a PythonFMU (third-party style test FMU).

Per doStep ``count += step_by``; outputs ``n_out = n_in + count``, ``b_out = b_in XOR (count odd)``,
``s_out = prefix + s_in``, ``y = u`` (Real feedthrough), ``total`` integrates ``u`` (a state with
``initial="exact"``, settable before initialization).
"""

from pythonfmu import Boolean, Fmi2Causality, Fmi2Initial, Fmi2Slave, Fmi2Variability, Integer, Real, String


class TypedPorts(Fmi2Slave):

    author = "rotorcosim tests"
    description = "Integer, Boolean and String ports"

    def __init__(self, **kwargs):
        super().__init__(**kwargs)
        self.step_by = 1
        self.prefix = "got:"
        self.n_in = 0
        self.b_in = False
        self.s_in = ""
        self.u = 0.0
        self.count = 0
        self.total = 0.0
        par, fixed, disc = Fmi2Causality.parameter, Fmi2Variability.fixed, Fmi2Variability.discrete
        self.register_variable(Integer("step_by", causality=par, variability=fixed, description="count increment"))
        self.register_variable(String("prefix", causality=par, variability=fixed, description="prefix of s_out"))
        self.register_variable(Integer("n_in", causality=Fmi2Causality.input, variability=disc))
        self.register_variable(Boolean("b_in", causality=Fmi2Causality.input, variability=disc))
        self.register_variable(String("s_in", causality=Fmi2Causality.input, variability=disc))
        self.register_variable(Real("u", causality=Fmi2Causality.input))
        self.register_variable(Integer("count", causality=Fmi2Causality.output, variability=disc,
                                       initial=Fmi2Initial.exact, description="steps taken times step_by"))
        self.register_variable(Integer("n_out", causality=Fmi2Causality.output, variability=disc,
                                       getter=lambda: self.n_in + self.count))
        self.register_variable(Boolean("b_out", causality=Fmi2Causality.output, variability=disc,
                                       getter=lambda: bool(self.b_in) != bool(self.count % 2)))
        self.register_variable(String("s_out", causality=Fmi2Causality.output, variability=disc,
                                      getter=lambda: self.prefix + self.s_in))
        self.register_variable(Real("y", causality=Fmi2Causality.output, getter=lambda: self.u))
        self.register_variable(Real("total", causality=Fmi2Causality.output, initial=Fmi2Initial.exact,
                                    description="integral of u [-]"))

    def do_step(self, current_time, step_size):
        self.count += self.step_by
        self.total += self.u * step_size
        return True
