"""Params: one parameter of each FMI type; writes its String parameter to a
file named by `out_file` at terminate (tests the `{out_dir}` substitution)."""

from pythonfmu import Boolean, Fmi2Causality, Fmi2Slave, Fmi2Variability, Integer, Real, String


class Params(Fmi2Slave):

    author = "rotorcosim tests"
    description = "Echoes its parameters as outputs"

    def __init__(self, **kwargs):
        super().__init__(**kwargs)
        self.a = 0.0
        self.n = 0
        self.flag = False
        self.out_file = ""
        self.a_out = 0.0
        self.n_out = 0.0
        self.flag_out = 0.0
        self.register_variable(Real("a", causality=Fmi2Causality.parameter, variability=Fmi2Variability.tunable))
        self.register_variable(Integer("n", causality=Fmi2Causality.parameter, variability=Fmi2Variability.tunable))
        self.register_variable(Boolean("flag", causality=Fmi2Causality.parameter, variability=Fmi2Variability.tunable))
        self.register_variable(String("out_file", causality=Fmi2Causality.parameter, variability=Fmi2Variability.tunable))
        self.register_variable(Real("a_out", causality=Fmi2Causality.output, getter=lambda: self.a))
        self.register_variable(Real("n_out", causality=Fmi2Causality.output, getter=lambda: float(self.n)))
        self.register_variable(Real("flag_out", causality=Fmi2Causality.output,
                                    getter=lambda: 1.0 if self.flag else 0.0))

    def do_step(self, current_time, step_size):
        return True

    def terminate(self):
        if self.out_file:
            with open(self.out_file, "w") as f:
                f.write(f"a={self.a} n={self.n} flag={self.flag}\n")
