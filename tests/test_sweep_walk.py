"""Frictions found walking sweeps as a rotordynamics engineer would (docs/sweeps.md): each test
is one item of that walk that was wrong and is fixed."""

from __future__ import annotations

import json
import os
import shutil
import signal
import threading
import time
from pathlib import Path

import pytest

SCENARIO = ("name: ramp\nstop_time: 0.1\nfmus:\n"
            "  f: {path: fmus/Faulty.fmu, parameters: {t_fail: 1.0e6, mode: 1}}\n"
            "  g: {path: fmus/Gain.fmu}\nconnections:\n  - {from: f.y, to: g.u}\ncoupling: {macro_step: 0.01}\n")


@pytest.fixture
def sdir(tmp_path, test_fmus) -> Path:
    (tmp_path / "fmus").mkdir()
    for name in ("Faulty", "Gain"):
        shutil.copy(test_fmus[name], tmp_path / "fmus" / f"{name}.fmu")
    (tmp_path / "ramp.yaml").write_text(SCENARIO)
    return tmp_path


@pytest.mark.filterwarnings("ignore:collect")
def test_interrupted_row_says_what_the_run_summary_says_after_the_run_stopped(sdir):
    """Ctrl-C while a run is in progress: closing the local cluster stops that run, which then
    writes its final summary (failed, stopped_by SIGTERM). The row's message was composed
    before the cluster was closed and said "its summary.json still says running" while the
    summary.json beside it said failed; now the folder is read after the run stopped."""
    from orchestrator.sweep import prepare, runner
    (sdir / "sweep.yaml").write_text(
        "sweep: 1\nscenario: ramp.yaml\nset: {stop_time: 1000.0, coupling.macro_step: 1.0e-3}\n"
        "parameters:\n  - {name: t_fail, set: [fmus.f.parameters.t_fail], values: [1.0e6]}\n"
        "collect: {end: end_time}\n")
    spec, runs = prepare(sdir / "sweep.yaml")
    summary = sdir / "o" / "runs" / runs[0].run_id / "summary.json"

    def interrupt_once_running():
        t0 = time.monotonic()
        while time.monotonic() - t0 < 240:
            try:
                if json.loads(summary.read_text()).get("status") == "running":
                    break
            except (OSError, ValueError):
                pass
            time.sleep(0.2)
        os.kill(os.getpid(), signal.SIGINT)

    threading.Thread(target=interrupt_once_running, daemon=True).start()
    outcome = runner.run_sweep(spec, runs, sdir / "o", workers=1, warm=True, progress=False)
    assert outcome.interrupted
    row = outcome.rows[0]
    assert row["status"] == "cancelled"
    final = json.loads(summary.read_text())
    assert final["status"] != "running", final     # the run was stopped and said so
    assert "still says running" not in row["message"], (row["message"], final)
    assert "SIGTERM" in final["message"] and "SIGTERM" in row["message"], (row["message"], final)
    assert "--resume" in row["message"]
