"""The initial exchange asks every worker for its outputs before reading any
(orchestrator.coupling.macro_step.MacroStep.read_outputs): the calls each FMU sees and the
propagation order are those of one read after the other; a failure is raised after every
asked worker's reply was read, and it is the first one in stepping order."""

from __future__ import annotations

import pytest

from orchestrator.coupling.macro_step import MacroStep
from orchestrator.errors import FmuCallError


class _Sub:
    def __init__(self, name, log, fail=None):
        self.name, self.log, self.fail = name, log, fail

    def _maybe_fail(self, call):
        if self.fail == call:
            raise FmuCallError(self.name, "fmi2GetReal", "error", "on purpose")

    def get_real(self, batch):
        self.log.append(("get", self.name))
        self._maybe_fail("get")

    def request_real(self, batch):
        self.log.append(("request", self.name))

    def receive_real(self, batch):
        self.log.append(("receive", self.name))
        self._maybe_fail("receive")


class _Unit:
    def __init__(self, sub):
        self.sub, self.name, self.outb = sub, sub.name, None


def _stepper(units, log):
    st = MacroStep.__new__(MacroStep)
    st.units = units
    st.propagate = lambda u, t: log.append(("propagate", u.name))
    return st


def test_workers_are_asked_first_and_read_in_order():
    log = []
    w1, inproc, w2 = (_Unit(_Sub(n, log)) for n in ("w1", "rotor", "w2"))
    _stepper([w1, inproc, w2], log).read_outputs(0.0, [w1, w2])
    assert log == [("request", "w1"), ("request", "w2"), ("get", "rotor"), ("receive", "w1"), ("receive", "w2"),
                   ("propagate", "w1"), ("propagate", "rotor"), ("propagate", "w2")]


def test_one_worker_computes_while_the_master_reads_the_others():
    log = []
    w1, inproc = (_Unit(_Sub(n, log)) for n in ("w1", "rotor"))
    _stepper([w1, inproc], log).read_outputs(0.0, [w1])
    assert log == [("request", "w1"), ("get", "rotor"), ("receive", "w1"), ("propagate", "w1"), ("propagate", "rotor")]


def test_without_workers_every_output_is_read_in_turn():
    log = []
    w1, inproc = (_Unit(_Sub(n, log)) for n in ("w1", "rotor"))
    for ask in (None, []):
        log.clear()
        _stepper([w1, inproc], log).read_outputs(0.0, ask)
        assert log == [("get", "w1"), ("propagate", "w1"), ("get", "rotor"), ("propagate", "rotor")]


def test_a_failure_is_raised_in_stepping_order_after_every_reply_was_read():
    log = []
    w1, inproc, w2 = _Unit(_Sub("w1", log, fail="receive")), _Unit(_Sub("rotor", log)), _Unit(_Sub("w2", log, "receive"))
    with pytest.raises(FmuCallError) as info:
        _stepper([w1, inproc, w2], log).read_outputs(0.0, [w1, w2])
    assert info.value.instance == "w1"                     # the first in stepping order
    assert log == [("request", "w1"), ("request", "w2"), ("get", "rotor"), ("receive", "w1"), ("receive", "w2")]
    log.clear()
    first, bad = _Unit(_Sub("rotor", log)), _Unit(_Sub("w", log, fail="receive"))
    with pytest.raises(FmuCallError) as info:
        _stepper([first, bad], log).read_outputs(0.0, [bad])
    assert info.value.instance == "w"
    assert log == [("request", "w"), ("get", "rotor"), ("receive", "w"), ("propagate", "rotor")]
