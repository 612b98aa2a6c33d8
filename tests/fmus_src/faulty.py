"""Faulty: a ramp source y = t that misbehaves from time `t_fail` on.

mode 0: do_step returns False (fmi2Discard); mode 1: do_step raises
(fmi2Error); mode 2: the output becomes NaN; mode 3: the output becomes +inf;
mode 4: the first step past t_fail sends SIGINT to its own process (a Ctrl-C that
arrives while FMU code runs) and then completes normally; mode 5: the process aborts
(SIGABRT, as a crashing native library would); mode 6: do_step raises an exception whose
text holds printf conversions (PythonFMU passes the text to the FMI logger as its format,
without arguments).
"""

import os
import signal

from pythonfmu import Fmi2Causality, Fmi2Slave, Fmi2Variability, Integer, Real


class Faulty(Fmi2Slave):

    author = "rotorcosim tests"
    description = "Ramp source that fails at t_fail"

    def __init__(self, **kwargs):
        super().__init__(**kwargs)
        self.t_fail = 1.0
        self.mode = 0
        self._interrupted = False      # mode 4: SIGINT sent already
        self.u = 0.0
        self.y = 0.0
        self.register_variable(Real("t_fail", causality=Fmi2Causality.parameter,
                                    variability=Fmi2Variability.tunable, description="failure time [s]"))
        self.register_variable(Integer("mode", causality=Fmi2Causality.parameter,
                                       variability=Fmi2Variability.tunable,
                                       description="0 discard, 1 raise, 2 NaN output, 3 inf output, 4 SIGINT once, 5 abort, "
                                                   "6 raise with printf conversions in the text"))
        self.register_variable(Real("u", causality=Fmi2Causality.input, description="ignored input [-]"))
        self.register_variable(Real("y", causality=Fmi2Causality.output, description="ramp output [-]"))

    def do_step(self, current_time, step_size):
        t_end = current_time + step_size
        if t_end > self.t_fail + 1e-12:
            if self.mode == 0:
                return False
            if self.mode == 1:
                raise RuntimeError(f"Faulty FMU: deliberate failure at t={t_end}")
            if self.mode == 2:
                self.y = float("nan")
                return True
            if self.mode == 3:
                self.y = float("inf")
                return True
            if self.mode == 4 and not self._interrupted:
                self._interrupted = True
                os.kill(os.getpid(), signal.SIGINT)
            if self.mode == 5:
                os.abort()
            if self.mode == 6:
                raise RuntimeError("Faulty FMU: 100%s of %s done, %n%n%s%s%s%s%s%s%s%s%s%s%s%s%n"
                                   " at t=" + repr(t_end))
        self.y = t_end
        return True
