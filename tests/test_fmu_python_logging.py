"""An FMU's log lines name the instance: PythonFMU FMUs log through Python's ``logging`` in our
process (crane-fmu's ``component_model.variable``), and those lines looked like rotorcosim's."""

from __future__ import annotations

import logging
import os
import subprocess
import sys
from pathlib import Path

import pytest

from orchestrator.fmi import fmu_logging

HERE = Path(__file__).parent


@pytest.fixture(scope="module")
def chatty(tmp_path_factory) -> Path:
    from pythonfmu.builder import FmuBuilder
    d = tmp_path_factory.mktemp("chatty")
    return Path(FmuBuilder.build_FMU(HERE / "fmus_src" / "_chatty.py", dest=d))


def _run(tmp_path, chatty, isolation, n_lines, n_warnings=0):
    sc = tmp_path / "chatty.yaml"
    sc.write_text(f"""name: chatty
stop_time: 0.3
fmus:
  talker: {{path: {chatty}, parameters: {{n_lines: {n_lines}, n_warnings: {n_warnings}}}}}
  quiet: {{path: {chatty}, parameters: {{n_lines: 0}}}}
connections:
  - {{from: "talker.y", to: "quiet.u"}}
coupling: {{scheme: jacobi, macro_step: 0.1, extrapolation_order: 0, isolation: {isolation}}}
""")
    env = {**os.environ, "PYTHONPATH": str(HERE.parent)}
    p = subprocess.run([sys.executable, "-m", "orchestrator", "run", str(sc), "--out", str(tmp_path / "out")],
                       cwd=tmp_path, env=env, capture_output=True, text=True, timeout=300)
    return p.returncode, p.stdout + p.stderr


@pytest.mark.parametrize("isolation", ["none", "process"])
def test_an_fmus_python_log_lines_name_the_instance_and_are_capped(tmp_path, chatty, isolation):
    """Before: ``WARNING chatty_model: python line 0 at t=0 <ESC>[2J``, every line of every step, no
    instance named, the FMU's escape sequence raw on the terminal. Now each such line names the
    instance whose FMI call ran, escaped, the first 20 per instance, then one line gives the
    number not shown and the last; the FMI logger's lines name the instance as before, and
    rotorcosim's own lines are unchanged."""
    rc, text = _run(tmp_path, chatty, isolation, 10)
    assert rc == 0, text[-2000:]
    lines = text.splitlines()
    py = [ln for ln in lines if ln.startswith("WARNING chatty_model:")]
    assert len(py) == 20, text
    assert all(ln.startswith("WARNING chatty_model: talker: python line ") for ln in py), text
    assert "\x1b" not in text and "\\x1b[2J" in py[0]
    assert py[-1].endswith("(the FMU's further Python log lines are not shown: 20 shown; their number is given "
                           "when the instance is freed)")
    assert ("WARNING orchestrator.fmi.fmu_logging: talker: 10 more Python log lines of the FMU were not shown "
            "(20 shown; the full log is not kept); the last: python line 9 at t=0.2 \\x1b[2J") in lines, text
    for inst in ("talker", "quiet"):      # the FMI logger's messages (Fmi2Slave.log) name the instance
        assert f"WARNING orchestrator.fmi.subsystem: {inst}: [warning] fmi line at t=0.2" in lines, text
    assert lines[0].startswith("running chatty (")        # ours: unchanged
    assert "status: finished" in lines


@pytest.mark.parametrize("isolation", ["none", "process"])
def test_an_fmus_python_warnings_name_the_instance(tmp_path, chatty, isolation):
    """``warnings.warn`` in the FMU printed ``warning: python warning 0 at t=0``, the form of
    rotorcosim's own warnings; now the text starts with the instance. In a worker process the
    warning was printed on the worker's stderr in Python's own format, with the worker's temporary
    path and the source line that raised it (``/tmp/rotorcosim-.../resources/x.py:457: UserWarning:
    ...`` and the line, stop 45); now it is sent to the master and shown as in the master's own
    process."""
    rc, text = _run(tmp_path, chatty, isolation, 0, n_warnings=1)
    assert rc == 0, text[-2000:]
    assert "python warning 0 at t=0.2" in text
    shown = [ln for ln in text.splitlines() if "python warning 0 at t=" in ln]
    assert len(shown) == 3 and all(ln.startswith("warning: talker: python warning 0 at t=") for ln in shown), text
    assert "warning: talker: python warning 0 at t=0.1" in shown, text
    assert "UserWarning" not in text and "warnings.warn(" not in text, text


def test_only_records_of_other_loggers_made_during_an_fmu_call_are_attributed(caplog):
    fmu_logging.install()
    other, ours = logging.getLogger("some_fmu_package"), logging.getLogger("orchestrator.coupling")
    with caplog.at_level(logging.WARNING):
        other.warning("outside %s", "a call")
        fmu_logging.enter("rotor")
        try:
            other.warning("inside %s\nsecond line", "a call")
            ours.warning("ours %s", "inside")
        finally:
            fmu_logging.leave()
    msgs = [r.getMessage() for r in caplog.records]
    assert msgs == ["outside a call", "rotor: inside a call / second line", "ours inside"]
    assert [getattr(r, "fmu_instance", None) for r in caplog.records] == [None, "rotor", None]
    fmu_logging.forget("rotor")


def test_running_instance_and_an_unattributed_block(caplog):
    """The public reading of this thread's FMI call (channel.py's worker warnings and
    subsystem.py used the module's private thread-local): ``unattributed()`` clears it for a
    block, records made in it are not attributed, and it restores the instance after, also when
    the block raises."""
    fmu_logging.install()
    assert fmu_logging.running_instance() is None
    fmu_logging.enter("rotor")
    try:
        assert fmu_logging.running_instance() == "rotor"
        with caplog.at_level(logging.WARNING):
            with pytest.raises(KeyError):
                with fmu_logging.unattributed():
                    assert fmu_logging.running_instance() is None
                    logging.getLogger("some_fmu_package").warning("relayed")
                    raise KeyError("inside the block")
        assert fmu_logging.running_instance() == "rotor"
        assert [(r.getMessage(), getattr(r, "fmu_instance", None)) for r in caplog.records] == [("relayed", None)]
    finally:
        fmu_logging.leave()
    assert fmu_logging.running_instance() is None
    with fmu_logging.unattributed():
        pass
    assert fmu_logging.running_instance() is None


def test_the_cap_counts_each_record_once_whatever_the_number_of_handlers():
    """A console and a log file handler: each shows the same first 20 records of the instance
    (a record is counted by the first handler's filter, not once per handler)."""
    class Keep(logging.Handler):
        def __init__(self):
            super().__init__()
            self.got = []

        def emit(self, record):
            self.got.append(record.getMessage())

    root = logging.getLogger()
    a, b = Keep(), Keep()
    root.addHandler(a)
    root.addHandler(b)
    try:
        fmu_logging.install()
        fmu_logging.enter("flood")
        try:
            for i in range(25):
                logging.getLogger("some_fmu_package").warning("line %d", i)
        finally:
            fmu_logging.leave()
        fmu_logging.forget("flood")
    finally:
        root.removeHandler(a)
        root.removeHandler(b)
    mine = [m for m in a.got if m.startswith("flood: line")]
    assert mine == [m for m in b.got if m.startswith("flood: line")] and len(mine) == 20
    assert any(m.startswith("flood: 5 more Python log lines of the FMU were not shown (20 shown; the full log is "
                            "not kept); the last: line 24") for m in a.got), a.got
