"""Chatty: y = u, logging ``n_lines`` lines a step through Python's ``logging`` (logger
``chatty_model``, as PythonFMU FMUs such as crane-fmu's do), ``n_warnings`` Python warnings
a step (``warnings.warn``) and one message a step through the FMI logger (``Fmi2Slave.log``).
Built by tests/test_fmu_python_logging.py only (the leading underscore keeps it out of the
``test_fmus`` fixture).
"""

import logging
import warnings

from pythonfmu import Fmi2Causality, Fmi2Slave, Fmi2Variability, Integer, Real
from pythonfmu.enums import Fmi2Status

logger = logging.getLogger("chatty_model")


class Chatty(Fmi2Slave):

    author = "rotorcosim tests"
    description = "Pass-through that logs through Python logging and the FMI logger"

    def __init__(self, **kwargs):
        super().__init__(**kwargs)
        self.n_lines = 1
        self.n_warnings = 0
        self.u = 0.0
        self.y = 0.0
        self.register_variable(Integer("n_lines", causality=Fmi2Causality.parameter,
                                       variability=Fmi2Variability.tunable,
                                       description="Python log lines per step [-]"))
        self.register_variable(Integer("n_warnings", causality=Fmi2Causality.parameter,
                                       variability=Fmi2Variability.tunable,
                                       description="Python warnings (warnings.warn) per step [-]"))
        self.register_variable(Real("u", causality=Fmi2Causality.input, description="input [-]"))
        self.register_variable(Real("y", causality=Fmi2Causality.output, description="output [-]"))

    def do_step(self, current_time, step_size):
        for i in range(self.n_warnings):
            warnings.warn(f"python warning {i} at t={current_time:g}")
        for i in range(self.n_lines):
            logger.warning("python line %d at t=%g \x1b[2J", i, current_time)
        self.log(f"fmi line at t={current_time:g}", Fmi2Status.warning)
        self.y = self.u
        return True
