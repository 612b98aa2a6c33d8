"""Sweeps (orchestrator.sweep, `rotorcosim sweep`): the file format, expansion, runs on Dask.

The runs use the small test FMUs (Faulty: a ramp that raises at t_fail; Gain), so a run
takes about a second, most of it the fresh process each run gets.
"""

from __future__ import annotations

import json
import os
import shutil
import signal
import subprocess
import sys
import time
import warnings
from pathlib import Path

import pytest

from orchestrator.cli import main
from orchestrator.sweep import SweepError, load_sweep
from orchestrator.sweep.plan import expand, plan_sweep, run_id_of
from orchestrator.sweep.task import _outcome, execute_run

REPO = Path(__file__).resolve().parents[1]
SCENARIO = ("name: ramp\nstop_time: 0.1\nfmus:\n"
            "  f: {path: fmus/Faulty.fmu, parameters: {t_fail: 1.0, mode: 1}}\n"
            "  g: {path: fmus/Gain.fmu}\nconnections:\n  - {from: f.y, to: g.u}\ncoupling: {macro_step: 0.01}\n")
# t_fail 0.05 < stop_time: that run fails (the FMU raises); the others finish
SWEEP = """sweep: 1
scenario: ramp.yaml
set: {stop_time: 0.1}
parameters:
  - name: t_fail
    set: [fmus.f.parameters.t_fail]
    values: [0.05, 0.5, 1.0]
collect:
  end: end_time
  steps: macro_steps
"""


@pytest.fixture
def sdir(tmp_path, test_fmus) -> Path:
    (tmp_path / "fmus").mkdir()
    for name in ("Faulty", "Gain"):
        shutil.copy(test_fmus[name], tmp_path / "fmus" / f"{name}.fmu")
    (tmp_path / "ramp.yaml").write_text(SCENARIO)
    (tmp_path / "sweep.yaml").write_text(SWEEP)
    return tmp_path


def problems(path) -> list[str]:
    with pytest.raises(SweepError) as info:
        plan_sweep(load_sweep(path), build_fmus=False)
    assert info.value.problems
    return info.value.problems


# ------------------------------------------------------------------ the file
@pytest.mark.parametrize("text, needles", [
    ("sweep: 2\nscenario: ramp.yaml\nparameters: []\n",
     [":1: 'sweep' must be between 1 and 1 (got 2); this rotorcosim reads sweep format 1",
      ":3: 'parameters' must be a non-empty list"]),
    ("sweep: 1\nscenaro: ramp.yaml\nparameters:\n  - {name: a, set: [stop_time], values: [0.1]}\n",
     [":2: unknown key 'scenaro' in 'sweep file'; did you mean 'scenario'?",
      "missing the required key 'scenario'"]),
    ("sweep: 1\nscenario: nope.yaml\nparameters:\n  - {name: a, set: [stop_time], value: [0.1]}\n",
     ["'scenario' names 'nope.yaml', which is not a file", ":4: unknown key 'value' in 'parameters[0]'; "
      "did you mean 'values'?"]),
    ("sweep: 1\nscenario: ramp.yaml\nparameters:\n  - {name: a, set: [stop_time], linspace: [0.1, 0.2]}\n"
     "  - {name: status, set: [coupling.macro_step], logspace: [-1, 1, 3]}\n",
     ["'parameters[0].linspace' must be a list [first, last, count]",
      "'parameters[1].name' becomes a sweep.csv column", "'parameters[1].logspace[0]' must be positive"]),
    ("sweep: 1\nscenario: ramp.yaml\nmode: zipp\nsamples: 3\nparameters:\n"
     "  - {name: a, set: [stop_time], values: [0.1, 0.1]}\n",
     [":3: 'mode' must be one of ['grid', 'zip', 'random'] (got 'zipp'); did you mean 'zip'?",
      ":4: 'samples' belongs to mode: random", ":6: the values of parameter 'a' repeat"]),
    ("sweep: 1\nscenario: ramp.yaml\nmode: zip\nparameters:\n  - {name: a, set: [stop_time], values: [0.1, 0.2]}\n"
     "  - {name: b, set: [coupling.macro_step], values: [0.01]}\n",
     ["mode 'zip' runs the i-th value of every parameter together", "{'a': 2, 'b': 1}"]),
])
def test_bad_sweep_files_list_every_problem_with_line(sdir, text, needles):
    (sdir / "bad.yaml").write_text(text)
    with pytest.raises(SweepError) as info:
        load_sweep(sdir / "bad.yaml")
    msg = "\n".join(info.value.problems)
    for needle in needles:
        assert needle in msg, msg
    assert all(p.startswith(str(sdir / "bad.yaml")) for p in info.value.problems)
    assert str(info.value).startswith("invalid sweep")


def test_every_run_scenario_is_validated_before_running(sdir):
    """A key typo in a parameter's 'set' and a bad value of one run are reported at their sweep
    file lines, with the run, before anything runs (no runs/ folder appears)."""
    (sdir / "bad.yaml").write_text(
        "sweep: 1\nscenario: ramp.yaml\nparameters:\n"
        "  - name: t\n    set: [fmus.f.parameters.t_fail]\n    values: [0.5, abc]\n"
        "  - name: h\n    set: [coupling.macro_stp]\n    values: [0.01]\n")
    found = problems(sdir / "bad.yaml")
    text = "\n".join(found)
    assert f"{sdir / 'bad.yaml'}:8: run t=0.5, h=0.01: --set coupling.macro_stp=0.01: unknown key 'macro_stp'" in text
    assert "did you mean 'macro_step'?" in text
    assert f"{sdir / 'bad.yaml'}:5: run t='abc', h=0.01: --set fmus.f.parameters.t_fail=\"abc\"" in text
    assert sum("macro_stp" in p for p in found) == 1            # once, not once per run
    assert main(["sweep", str(sdir / "bad.yaml"), "--out", str(sdir / "o")]) == 1
    assert not (sdir / "o").exists()


def test_expansion_modes_and_stable_run_ids(sdir):
    (sdir / "g.yaml").write_text(
        "sweep: 1\nscenario: ramp.yaml\nparameters:\n  - {name: a, set: [stop_time, output.interval], "
        "linspace: [0.1, 0.2, 3]}\n  - {name: b, set: [coupling.macro_step], logspace: [1e-3, 1e-1, 3]}\n")
    spec = load_sweep(sdir / "g.yaml")
    runs = expand(spec)
    assert len(runs) == 9 and [r.index for r in runs] == list(range(9))
    assert runs[0].values == {"a": 0.1, "b": pytest.approx(1e-3)}
    assert runs[4].values["a"] == pytest.approx(0.15) and runs[4].values["b"] == pytest.approx(1e-2)
    assert runs[1].overrides == ("stop_time=0.1", "output.interval=0.1", f"coupling.macro_step={runs[1].values['b']!r}")
    assert len({r.run_id for r in runs}) == 9
    assert runs[3].run_id == run_id_of(reversed(runs[3].overrides))         # stable, order-independent
    assert [r.run_id for r in expand(load_sweep(sdir / "g.yaml"))] == [r.run_id for r in runs]
    (sdir / "z.yaml").write_text((sdir / "g.yaml").read_text() + "mode: zip\n")
    assert [tuple(r.values.values()) for r in expand(load_sweep(sdir / "z.yaml"))] == [
        tuple(runs[i].values.values()) for i in (0, 4, 8)]
    (sdir / "r.yaml").write_text((sdir / "g.yaml").read_text() + "mode: random\nsamples: 4\nseed: 3\n")
    drawn = expand(load_sweep(sdir / "r.yaml"))
    assert len(drawn) == 4 and {r.run_id for r in drawn} <= {r.run_id for r in runs}
    assert [r.run_id for r in drawn] == [r.run_id for r in expand(load_sweep(sdir / "r.yaml"))]
    (sdir / "r.yaml").write_text((sdir / "g.yaml").read_text() + "mode: random\nsamples: 10\n")
    with pytest.raises(SweepError, match="'samples' is 10 but the grid of the parameters has only 9"):
        expand(load_sweep(sdir / "r.yaml"))
    (sdir / "d.yaml").write_text("sweep: 1\nscenario: ramp.yaml\nmode: zip\nparameters:\n"
                                 "  - {name: a, set: [stop_time], values: [0.1, 0.2, 0.1]}\n"
                                 "  - {name: b, set: [coupling.macro_step], values: [0.01, 0.01, 0.02]}\n")
    assert len(expand(load_sweep(sdir / "d.yaml"))) == 3          # zip columns may repeat values
    (sdir / "d.yaml").write_text((sdir / "d.yaml").read_text().replace("0.01, 0.01, 0.02", "0.01, 0.01, 0.01"))
    with pytest.raises(SweepError, match="runs 1 and 3 are the same run"):
        expand(load_sweep(sdir / "d.yaml"))


def test_missing_and_null_collect_values_are_empty_cells_with_their_own_warnings(sdir):
    import warnings
    from orchestrator.sweep.table import build_rows
    spec = load_sweep(sdir / "sweep.yaml")
    runs = plan_sweep(spec, build_fmus=False)
    done = {"status": "finished", "message": "", "wall_time_s": 1.0}
    records = {runs[0].run_id: {**done, "summary": {"end_time": 0.1, "macro_steps": None}},
               runs[1].run_id: {**done, "summary": {"end_time": 0.1}},
               runs[2].run_id: {**done, "summary": {"end_time": 0.1, "macro_steps": 10}}}
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        rows = build_rows(spec, runs, records, sdir)
    assert [r["steps"] for r in rows] == [None, None, 10] and [r["end"] for r in rows] == [0.1] * 3
    texts = [str(w.message) for w in caught]
    assert len(texts) == 2
    assert any("1 finished run(s) have no 'macro_steps'" in t for t in texts)
    assert any("1 finished run(s) have 'macro_steps' = null" in t and "computed no value" in t for t in texts)


def test_task_outcome_classification():
    assert _outcome(0, {"status": "finished"}, "") == ("finished", "")
    status, msg = _outcome(-6, {"status": "finished"}, "corrupted double-linked list")
    assert status == "finished" and "exited with code -6" in msg
    assert _outcome(1, {"status": "failed", "message": "FMU f raised"}, "") == ("failed", "FMU f raised")
    status, msg = _outcome(-11, None, "Fatal Python error: Segmentation fault")
    assert status == "crashed" and "killed by signal 11" in msg and "Segmentation fault" in msg
    status, msg = _outcome(-9, {"status": "running", "message": "the run is in progress"}, "")
    assert status == "crashed" and "killed by signal 9" in msg     # the summary a run writes at its start
    # a run a signal stopped did not fail: it is cancelled, and --resume runs it again
    status, msg = _outcome(130, {"status": "failed", "stopped_by": "SIGINT",
                                 "message": "interrupted by the user at t=0.3 s"}, "")
    assert status == "cancelled" and "interrupted by the user at t=0.3 s" in msg and "--resume" in msg
    assert _outcome(143, {"status": "failed", "stopped_by": "SIGTERM", "message": "terminated"}, "")[0] == "cancelled"


def test_a_run_stopped_by_a_signal_says_so_in_its_summary(sdir):
    """SIGINT to a running `rotorcosim run`: the summary is failed with ``stopped_by: SIGINT``
    (what a sweep reads to count the run as cancelled, not failed)."""
    out = sdir / "stopped"
    proc = subprocess.Popen([sys.executable, "-m", "orchestrator", "run", str(sdir / "ramp.yaml"), "--out", str(out),
                             "--no-progress", "--set", "stop_time=1000", "--set", "fmus.f.parameters.t_fail=1.0e9"],
                            stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True, start_new_session=True)
    try:
        _wait_for(lambda: (out / "results.csv").is_file(), 120, "the run's results file")
        time.sleep(1.0)                                              # well into the stepping
        os.killpg(proc.pid, signal.SIGINT)
        proc.communicate(timeout=60)
    finally:
        if proc.poll() is None:
            os.killpg(proc.pid, signal.SIGKILL)
    assert proc.returncode == 130
    summary = json.loads((out / "summary.json").read_text())
    assert summary["status"] == "failed" and summary["stopped_by"] == "SIGINT"
    assert "interrupted by the user" in summary["message"]
    assert _outcome(proc.returncode, summary, "")[0] == "cancelled"


def test_a_run_that_dies_without_summary_is_a_crashed_record(sdir):
    rec = execute_run(str(sdir / "ramp.yaml"), ["coupling.macro_step=-1"], str(sdir / "r"))
    assert rec["status"] == "crashed" and "exit code 1" in rec["message"] and "macro_step" in rec["message"]
    assert json.loads((sdir / "r" / "sweep_run.json").read_text())["status"] == "crashed"


# ------------------------------------------------------------------ warm run processes
@pytest.fixture
def warm():
    from orchestrator.sweep import warm as warm_mod
    yield warm_mod
    warm_mod.close_warm()


def _child_pid(warm_mod):
    """The pid of this process's one idle warm child (None when there is none)."""
    pids = warm_mod.warm_pids()
    assert not pids["busy"] and len(pids["idle"]) <= 1, pids
    return pids["idle"][0] if pids["idle"] else None


def test_warm_process_runs_many_scenarios_like_fresh_processes(sdir, warm):
    """Two runs in the warm process share it; their results are byte for byte those of fresh
    processes; a failed run retires the process (the next run gets a new one)."""
    scen, runs = str(sdir / "ramp.yaml"), sdir / "runs"
    a = execute_run(scen, ["fmus.f.parameters.t_fail=0.5"], str(runs / "a"))
    pid = _child_pid(warm)
    b = execute_run(scen, ["fmus.f.parameters.t_fail=0.7", "coupling.macro_step=0.02"], str(runs / "b"))
    assert a["status"] == b["status"] == "finished" and pid is not None and _child_pid(warm) == pid
    assert b["summary"]["macro_steps"] == 5 and a["summary"]["macro_steps"] == 10
    fa = execute_run(scen, ["fmus.f.parameters.t_fail=0.5"], str(runs / "fa"), warm=False)
    fb = execute_run(scen, ["fmus.f.parameters.t_fail=0.7", "coupling.macro_step=0.02"], str(runs / "fb"),
                     warm=False)
    for w, f in (("a", "fa"), ("b", "fb")):
        assert (runs / w / "results.csv").read_bytes() == (runs / f / "results.csv").read_bytes()
    assert "status: finished" in (runs / "a" / "run.log").read_text()      # the run's own output
    bad = execute_run(scen, ["fmus.f.parameters.t_fail=0.05"], str(runs / "bad"))
    assert bad["status"] == "failed" and "deliberate failure" in bad["message"]
    assert _child_pid(warm) is None and not psutil_alive(pid)
    again = execute_run(scen, ["fmus.f.parameters.t_fail=0.5"], str(runs / "again"))
    assert again["status"] == "finished" and _child_pid(warm) not in (None, pid)
    assert (runs / "again" / "results.csv").read_bytes() == (runs / "a" / "results.csv").read_bytes()


def test_prestarted_warm_processes_serve_concurrent_runs(sdir, warm):
    """prestart() starts the children before the first run; two runs at once (two worker
    threads of one process, as in the local cluster) take two different prestarted children
    and give them back; results are those of a fresh process."""
    from concurrent.futures import ThreadPoolExecutor
    scen, runs = str(sdir / "ramp.yaml"), sdir / "runs"
    warm.prestart(str(runs), 2)
    started = set(warm.warm_pids()["idle"])
    assert len(started) == 2
    warm.prestart(str(runs), 2)                       # idle ones for the same folder count
    assert set(warm.warm_pids()["idle"]) == started
    with ThreadPoolExecutor(2) as pool:
        recs = list(pool.map(lambda i: execute_run(scen, [f"fmus.f.parameters.t_fail={0.5 + i / 10}"],
                                                   str(runs / f"c{i}")), range(4)))
    assert [r["status"] for r in recs] == ["finished"] * 4, recs
    assert set(warm.warm_pids()["idle"]) == started and not warm.warm_pids()["busy"]
    fresh = execute_run(scen, ["fmus.f.parameters.t_fail=0.5"], str(runs / "f0"), warm=False)
    assert fresh["status"] == "finished"
    assert (runs / "c0" / "results.csv").read_bytes() == (runs / "f0" / "results.csv").read_bytes()
    other = execute_run(scen, ["fmus.f.parameters.t_fail=0.5"], str(sdir / "elsewhere" / "runs" / "x"))
    assert other["status"] == "finished"              # another sweep folder: a new child, the old ones retired
    assert not set(warm.warm_pids()["idle"]) & started and not any(psutil_alive(p) for p in started)


def psutil_alive(pid: int) -> bool:
    try:
        os.kill(pid, 0)
    except ProcessLookupError:
        return False
    return Path(f"/proc/{pid}/stat").is_file() and ") Z " not in Path(f"/proc/{pid}/stat").read_text()


def test_warm_process_forgets_modules_of_deleted_fmu_folders(tmp_path):
    """What a run imported from an FMU's extracted folder (deleted after the run) must not be
    reused by the next run; modules that still exist stay (the warm kernels)."""
    from orchestrator.sweep.warm_child import forget_vanished
    for name in ("gone_pkg", "kept_pkg"):
        (tmp_path / name / name).mkdir(parents=True)
        (tmp_path / name / name / "__init__.py").write_text("X = 1\n")
    before, path_before = set(sys.modules), list(sys.path)
    sys.path[:0] = [str(tmp_path / "gone_pkg"), str(tmp_path / "kept_pkg")]
    try:
        import gone_pkg  # noqa: F401
        import kept_pkg  # noqa: F401
        shutil.rmtree(tmp_path / "gone_pkg")
        assert forget_vanished(before, path_before) == ["gone_pkg"]
        assert "gone_pkg" not in sys.modules and "kept_pkg" in sys.modules
        assert str(tmp_path / "gone_pkg") not in sys.path and str(tmp_path / "kept_pkg") in sys.path
    finally:
        sys.modules.pop("kept_pkg", None)
        sys.path[:] = [p for p in sys.path if str(tmp_path) not in p]


def test_warm_process_that_crashes_or_hangs_is_a_crashed_row_and_is_replaced(sdir, warm):
    scen, runs = str(sdir / "ramp.yaml"), sdir / "runs"
    rec = execute_run(scen, ["fmus.f.parameters.t_fail=0.05", "fmus.f.parameters.mode=5"], str(runs / "abort"))
    assert rec["status"] == "crashed" and f"killed by signal {int(signal.SIGABRT)}" in rec["message"], rec
    assert "in 'f' in fmi2DoStep at t=" in rec["message"], rec          # where it died (fmi/call_record.py)
    assert _child_pid(warm) is None
    ok = execute_run(scen, [], str(runs / "ok"))
    assert ok["status"] == "finished"
    pid = _child_pid(warm)
    slow = execute_run(scen, ["stop_time=1000", "fmus.f.parameters.t_fail=2000", "coupling.macro_step=1e-4", "output.interval=1.0"], str(runs / "slow"), timeout_s=3)
    assert slow["status"] == "crashed" and "timed out after 3 s" in slow["message"], slow
    assert not psutil_alive(pid)
    assert execute_run(scen, [], str(runs / "ok2"))["status"] == "finished"


# ------------------------------------------------------------------ runs on Dask
def test_small_sweep_on_local_cluster_with_a_failing_run(sdir, recwarn):
    pd = pytest.importorskip("pandas")
    from orchestrator.sweep import sweep
    (sdir / "sweep.yaml").write_text(SWEEP + "  nothing: analysis.none\n")
    df = sweep(sdir / "sweep.yaml", out_dir=sdir / "out", workers=2)
    assert isinstance(df, pd.DataFrame)
    assert list(df.columns) == ["run_id", "t_fail", "end", "steps", "nothing", "status", "message",
                                "wall_time_s", "run_dir"]
    assert list(df.status) == ["failed", "finished", "finished"]
    assert "deliberate failure" in df.message[0]
    assert df.end[1] == pytest.approx(0.1) and df.steps[1] == 10
    assert df.end[0] == pytest.approx(0.05)                       # a failed run's summary still counts
    assert df.nothing.isna().all()
    assert any("collect 'nothing': 2 finished run(s) have no 'analysis.none'" in str(w.message) for w in recwarn)
    for row in df.itertuples():
        assert (sdir / "out" / row.run_dir / "results.csv").is_file()
    table = pd.read_csv(sdir / "out" / "sweep.csv")
    assert list(table.status) == list(df.status) and list(table.run_id) == list(df.run_id)
    pytest.importorskip("pyarrow")
    assert list(pd.read_parquet(sdir / "out" / "sweep.parquet").t_fail) == [0.05, 0.5, 1.0]
    assert main(["plot", str(sdir / "out")]) == 0
    assert (sdir / "out" / "plots" / "sweep_end.png").stat().st_size > 1000


def test_two_parameter_sweep_cli_and_heat_map(sdir, capsys):
    (sdir / "two.yaml").write_text(SWEEP.replace("values: [0.05, 0.5, 1.0]", "values: [0.05, 1.0]")
                                   .replace("collect:", "  - {name: h, set: [coupling.macro_step], "
                                                        "values: [0.01, 0.02]}\ncollect:"))
    assert main(["sweep", str(sdir / "two.yaml"), "--out", str(sdir / "o2"), "--workers", "2",
                 "--no-progress"]) == 1                            # one parameter value fails its runs
    out, err = capsys.readouterr()
    assert "4 runs of ramp.yaml (grid)" in out and "runs: 2 failed, 2 finished" in out
    assert err.count(" failed: ") == 2
    assert main(["plot", str(sdir / "o2")]) == 0
    assert (sdir / "o2" / "plots" / "sweep_steps.png").is_file()
    rows = (sdir / "o2" / "sweep.csv").read_text().splitlines()
    assert rows[0] == "run_id,t_fail,h,end,steps,status,message,wall_time_s,run_dir"


def _wait_for(pred, timeout, what):
    t0 = time.monotonic()
    while not pred():
        if time.monotonic() - t0 > timeout:
            raise AssertionError(f"timed out waiting for {what}")
        time.sleep(0.2)


def _processes_using(path: Path) -> list[str]:
    """Command lines of running processes that mention ``path`` (Linux /proc; empty elsewhere)."""
    found = []
    for d in Path("/proc").glob("[0-9]*"):
        try:
            cmd = (d / "cmdline").read_bytes().replace(b"\0", b" ").decode(errors="replace")
        except OSError:
            continue
        if str(path) in cmd:
            found.append(cmd)
    return found


def _sleeping_run(scenario, overrides, run_dir, *, warm=True, inputs=None):   # stands in for task.execute_run
    time.sleep(0.05 if any(o.endswith("t_fail=0.05") for o in overrides) else 30.0)
    return {"status": "finished", "message": "", "wall_time_s": 0.0, "summary": {"status": "finished"}}


@pytest.mark.filterwarnings("ignore:collect")        # the stand-in runs write no end_time/steps
def test_ctrl_c_in_the_sweep_process_always_ends_the_sweep(sdir, monkeypatch):
    """SIGINT to the sweep's own process while it waits for its tasks: the outcome is
    interrupted, the run that finished is kept, the others are cancelled (the handler sets a
    flag that the loop checks; a KeyboardInterrupt raised inside Dask's code could be lost)."""
    import threading

    from orchestrator.sweep import prepare
    from orchestrator.sweep import runner
    monkeypatch.setattr(runner, "execute_run", _sleeping_run)
    spec, runs = prepare(sdir / "sweep.yaml")
    before = signal.getsignal(signal.SIGINT)      # Python's default_int_handler, or SIG_IGN when started in the background
    timer = threading.Timer(6.0, os.kill, (os.getpid(), signal.SIGINT))
    timer.start()
    try:
        outcome = runner.run_sweep(spec, runs, sdir / "o", workers=2, warm=False, progress=False)
    finally:
        timer.cancel()
    assert outcome.interrupted
    assert [r["status"] for r in outcome.rows] == ["finished", "cancelled", "cancelled"]
    assert signal.getsignal(signal.SIGINT) is before            # Ctrl-C is handled as before the sweep again


def test_interrupted_sweep_keeps_finished_runs_and_resumes(sdir):
    """Ctrl-C (SIGINT) after the first run finished: exit 130, pending runs are 'cancelled' rows;
    --resume runs only what did not finish."""
    (sdir / "long.yaml").write_text(SWEEP.replace("[0.05, 0.5, 1.0]", "[2.0, 3.0, 4.0, 5.0, 6.0, 7.0]")
                                    .replace("stop_time: 0.1", "stop_time: 0.6, coupling.macro_step: 2.0e-4"))
    cmd = [sys.executable, "-m", "orchestrator", "sweep", str(sdir / "long.yaml"), "--out", str(sdir / "o"),
           "--workers", "1", "--no-progress"]
    proc = subprocess.Popen(cmd, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True,
                            start_new_session=True)
    try:
        _wait_for(lambda: any((sdir / "o" / "runs").glob("*/sweep_run.json")), 240, "the first finished run")
        os.killpg(proc.pid, signal.SIGINT)
        out, err = proc.communicate(timeout=120)
    finally:
        if proc.poll() is None:
            os.killpg(proc.pid, signal.SIGKILL)
    assert proc.returncode == 130, (out, err)
    assert "--resume" in err and "Traceback" not in err
    rows = (sdir / "o" / "sweep.csv").read_text().splitlines()[1:]
    done = [r for r in rows if ",finished," in r]
    assert 1 <= len(done) < 6 and any(",cancelled," in r for r in rows), (rows, out, err)
    _wait_for(lambda: not _processes_using(sdir / "o"), 30, "the interrupted runs to end")   # no orphans
    # a run that was running at the interrupt may still have finished and written its summary
    finished = sum(json.loads(p.read_text())["status"] == "finished"
                   for p in (sdir / "o" / "runs").glob("*/summary.json"))
    assert finished >= len(done)
    proc = subprocess.run(cmd + ["--resume"], capture_output=True, text=True, timeout=600)
    assert proc.returncode == 0, proc.stderr
    assert f"({finished} runs resumed)" in proc.stdout
    rows = (sdir / "o" / "sweep.csv").read_text().splitlines()[1:]
    assert len(rows) == 6 and all(",finished," in r for r in rows)


SSV = ('<?xml version="1.0" encoding="UTF-8"?>\n<ssv:ParameterSet version="1.0" name="p" '
       'xmlns:ssv="http://ssp-standard.org/SSP1/SystemStructureParameterValues"><ssv:Parameters>'
       '<ssv:Parameter name="y0"><ssv:Real value="{y0}"/></ssv:Parameter></ssv:Parameters></ssv:ParameterSet>\n')
SSD = ('<?xml version="1.0" encoding="UTF-8"?>\n<ssd:SystemStructureDescription version="1.0" name="s" '
       'xmlns:ssd="http://ssp-standard.org/SSP1/SystemStructureDescription"><ssd:System name="top">'
       '<ssd:Elements><ssd:Component name="i" source="fmus/Integrator.fmu"><ssd:ParameterBindings>'
       '<ssd:ParameterBinding source="p.ssv"/></ssd:ParameterBindings></ssd:Component>'
       '<ssd:Component name="t" source="fmus/TypedPorts.fmu"/></ssd:Elements></ssd:System>'
       '<ssd:DefaultExperiment startTime="0" stopTime="1"/></ssd:SystemStructureDescription>\n')


@pytest.mark.filterwarnings("ignore:collect")
def test_resume_reruns_the_runs_whose_ssp_parameter_file_or_named_file_changed(tmp_path, test_fmus):
    """`sweep --resume` compared only the scenario file and the FMUs with what a run was recorded
    with: a scenario that takes its values from an SSP (``ssp: sys.ssd``, its parameter file
    p.ssv) or names a file in a String parameter (a rotor file) kept every run after that file
    was edited, and sweep.csv held the results of the old values. Now the loader records every
    file it reads (and every existing file a String parameter names), each run's sweep_run.json
    keeps their digests, and --resume runs again exactly the runs whose files changed."""
    from orchestrator.results.result import CoSimResult
    from orchestrator.sweep.runner import run_sweep
    (tmp_path / "fmus").mkdir()
    for name in ("Integrator", "TypedPorts"):
        shutil.copy(test_fmus[name], tmp_path / "fmus" / f"{name}.fmu")
    (tmp_path / "sys.ssd").write_text(SSD)
    (tmp_path / "p.ssv").write_text(SSV.format(y0=1.0))
    (tmp_path / "sc.yaml").write_text("ssp: sys.ssd\nname: ssp_inputs\nstop_time: 0.03\ncoupling: {macro_step: 0.01}\n")
    named = {k: tmp_path / f"{k}.txt" for k in ("a", "b")}
    for k, f in named.items():
        f.write_text(f"file {k}\n")
    (tmp_path / "sw.yaml").write_text(
        "sweep: 1\nscenario: sc.yaml\nparameters:\n  - name: prefix\n    set: fmus.t.parameters.prefix\n"
        f"    values: [{json.dumps(str(named['a']))}, {json.dumps(str(named['b']))}]\ncollect:\n  end: end_time\n")
    out = tmp_path / "out"

    def sweep(resume: bool):
        spec = load_sweep(tmp_path / "sw.yaml")
        with warnings.catch_warnings(record=True) as caught:
            warnings.simplefilter("always")
            outcome = run_sweep(spec, plan_sweep(spec, build_fmus=False), out, workers=1, resume=resume,
                                progress=False, warm=False)
        texts = [str(w.message) for w in caught if "--resume" in str(w.message)]
        return outcome, texts

    def y0_of(run_id: str) -> float:
        return float(CoSimResult.load(out / "runs" / run_id).outputs["i.y"][0])

    first, _ = sweep(False)
    ids = [r["run_id"] for r in first.rows]
    assert [r["status"] for r in first.rows] == ["finished", "finished"]
    assert [y0_of(i) for i in ids] == [1.0, 1.0]
    inputs = json.loads((out / "runs" / ids[0] / "sweep_run.json").read_text())["inputs"]
    assert sorted(inputs["files"]) == sorted([str((tmp_path / "sys.ssd").resolve()),
                                              str((tmp_path / "p.ssv").resolve()), str(named["a"].resolve())])
    again, texts = sweep(True)                                    # nothing changed: both kept
    assert again.skipped == 2 and not texts
    named["a"].write_text("file a, edited\n")                    # only the first run names a.txt
    edited, texts = sweep(True)
    assert edited.skipped == 1 and len(texts) == 1, texts
    assert f"runs/{ids[0]}: the file {named['a'].resolve()} changed since this run finished" in texts[0]
    (tmp_path / "p.ssv").write_text(SSV.format(y0=2.0))          # every run reads the SSP's parameters
    fixed, texts = sweep(True)
    assert fixed.skipped == 0 and len(texts) == 2, texts
    assert all(f"the file {(tmp_path / 'p.ssv').resolve()} changed since this run finished" in t for t in texts)
    assert [y0_of(i) for i in ids] == [2.0, 2.0]                  # the new value, not the stale results


@pytest.mark.timeout(600)
def test_sweep_on_a_real_dask_scheduler_and_worker(sdir, tmp_path):
    dask = Path(sys.executable).parent / "dask"
    if not dask.exists():
        pytest.skip("the `dask` command is not installed next to this Python")
    sched_file = tmp_path / "scheduler.json"
    procs = [subprocess.Popen([str(dask), "scheduler", "--host", "127.0.0.1", "--port", "0", "--no-dashboard",
                               "--scheduler-file", str(sched_file)], stdout=subprocess.DEVNULL,
                              stderr=subprocess.DEVNULL)]
    try:
        _wait_for(sched_file.exists, 120, "the scheduler file")
        _wait_for(lambda: "address" in sched_file.read_text(), 30, "the scheduler address")
        address = json.loads(sched_file.read_text())["address"]
        assert address.startswith("tcp://127.0.0.1:")
        procs.append(subprocess.Popen([str(dask), "worker", address, "--nthreads", "1", "--nworkers", "1",
                                       "--no-dashboard", "--host", "127.0.0.1"],
                                      stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL))
        proc = subprocess.run([sys.executable, "-m", "orchestrator", "sweep", str(sdir / "sweep.yaml"), "--out",
                               str(sdir / "ext"), "--scheduler", address, "--no-progress"],
                              capture_output=True, text=True, timeout=480)
        assert proc.returncode == 1, proc.stderr                 # one run fails by design
        assert "runs: 1 failed, 2 finished" in proc.stdout
        rows = (sdir / "ext" / "sweep.csv").read_text().splitlines()
        assert [r.split(",")[1] for r in rows[1:]] == ["0.05", "0.5", "1.0"]
        # DASK_SCHEDULER_ADDRESS is the same as --scheduler: --workers is refused there too
        bad = subprocess.run([sys.executable, "-m", "orchestrator", "sweep", str(sdir / "sweep.yaml"),
                              "--workers", "2"], capture_output=True, text=True, timeout=120,
                             env=dict(os.environ, DASK_SCHEDULER_ADDRESS=address))
        assert bad.returncode == 1 and "drop --workers" in bad.stderr and "Traceback" not in bad.stderr
    finally:
        for p in reversed(procs):
            p.terminate()
        for p in procs:
            try:
                p.wait(timeout=30)
            except subprocess.TimeoutExpired:
                p.kill()


@pytest.mark.parametrize("path", sorted((REPO / "scenarios" / "sweeps").glob("*.yaml")) +
                         [REPO / "benchmarks" / "sweep_bench.yaml"], ids=lambda p: p.name)
def test_shipped_sweep_files_and_all_their_runs_validate(path):
    spec = load_sweep(path)
    runs = plan_sweep(spec)                      # builds our FMUs when missing, like `rotorcosim run`
    assert len(runs) == len({r.run_id for r in runs}) >= 5
    assert {"psi", "eta0"} <= set(runs[0].values) or "eta0" in runs[0].values


def test_collect_takes_the_last_value_of_a_recorded_signal(sdir):
    """A sweep over a coupling parameter of third-party FMUs (no analysis section) could collect
    only macro_steps, end_time and the like: summary.json held no value of any signal, and
    'collect: {x_end: a.x[0]}' gave empty cells. summary.json now has output.final (the last row)
    and collect reads 'output.final.<instance>.<variable>', variable names with dots included."""
    import csv
    import warnings
    from orchestrator import load_scenario, run
    from orchestrator.sweep.table import build_rows, lookup
    run(load_scenario(sdir / "ramp.yaml"), out_dir=sdir / "one", progress=False)
    summary = json.loads((sdir / "one" / "summary.json").read_text())
    with open(sdir / "one" / "results.csv") as f:
        last = list(csv.DictReader(f))[-1]
    assert summary["output"]["final_time"] == pytest.approx(float(last["time"])) == pytest.approx(0.1)
    assert summary["output"]["final"] == {c: pytest.approx(float(last[c])) for c in summary["output"]["columns"]}
    assert lookup(summary, "output.final.g.y") == summary["output"]["final"]["g.y"]
    # a variable whose name has dots (crane-fmu's 'boom.end[0]'), and lists, as before
    doc = {"output": {"final": {"crane.boom.end[0]": 1.5, "crane.boom": 2.0}}, "a": [{"b.c": 3}]}
    assert lookup(doc, "output.final.crane.boom.end[0]") == 1.5
    assert lookup(doc, "output.final.crane.boom") == 2.0
    assert lookup(doc, "a.0.b.c") == 3
    assert lookup(doc, "output.final.crane.nope") is lookup(doc, "nope")          # missing
    # in a sweep table, and the warning for the bare signal name says where its value is
    (sdir / "sweep.yaml").write_text(SWEEP + "  y_end: output.final.g.y\n  bare: g.y\n")
    spec = load_sweep(sdir / "sweep.yaml")
    runs = plan_sweep(spec, build_fmus=False)
    records = {r.run_id: {"status": "finished", "message": "", "wall_time_s": 1.0, "summary": summary} for r in runs}
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        rows = build_rows(spec, runs, records, sdir)
    assert [r["y_end"] for r in rows] == [summary["output"]["final"]["g.y"]] * 3
    assert [r["bare"] for r in rows] == [None] * 3
    assert any("have no 'g.y'" in str(w.message) and "is 'output.final.g.y'" in str(w.message) for w in caught)


def test_a_value_the_fmus_cannot_run_is_reported_at_the_sweep_axis(sdir):
    """An axis over coupling.scheme with 'iterative' for FMUs that cannot save state (Faulty,
    Gain) was reported as ``sweep.yaml: run h=..., scheme='iterative': scenario ramp.yaml:
    ramp.yaml:8: 'coupling.scheme: iterative' ...``: the scenario's coupling line, which the user
    need not change. Now it names the sweep file's line of that axis and the value (--set ...),
    with the scenario's line after it, once for all runs."""
    (sdir / "bad.yaml").write_text(
        "sweep: 1\nscenario: ramp.yaml\nparameters:\n"
        "  - name: h\n    set: [coupling.macro_step]\n    values: [0.01, 0.02]\n"
        "  - name: scheme\n    set: [coupling.scheme]\n    values: [jacobi, iterative]\n")
    found = problems(sdir / "bad.yaml")
    assert len(found) == 1, found
    assert found[0].startswith(f"{sdir / 'bad.yaml'}:8: run h=0.01, scheme='iterative': "
                               "--set coupling.scheme=\"iterative\": 'coupling.scheme: iterative' repeats every "
                               "macro step from saved FMU states, but 'f', 'g' cannot save them"), found
    assert found[0].endswith(f"(the scenario: {sdir / 'ramp.yaml'}:8)"), found     # its coupling: line (no scheme key)


@pytest.mark.skipif(shutil.which("gcc") is None, reason="gcc not installed (native test FMU)")
def test_a_step_control_a_fixed_step_fmu_cannot_take_is_reported_at_the_sweep_axis(tmp_path):
    from tests.fmus_c.build_c_fmu import build_c_fmu
    fixed = build_c_fmu(tmp_path, "AllTypes", fixed_step=True)     # canHandleVariableCommunicationStepSize false
    (tmp_path / "fixed.yaml").write_text(f"name: fixed\nstop_time: 1.0\nfmus:\n  a: {{path: {fixed}}}\n"
                                         "coupling:\n  macro_step: 0.1\n  step_control: {type: constant}\n")
    (tmp_path / "sw.yaml").write_text(
        "sweep: 1\nscenario: fixed.yaml\nparameters:\n"
        "  - name: control\n    set: coupling.step_control.type\n    values: [constant, error]\n")
    found = problems(tmp_path / "sw.yaml")
    assert len(found) == 1, found
    assert found[0].startswith(f"{tmp_path / 'sw.yaml'}:5: run control='error': --set coupling.step_control.type="
                               "\"error\": 'coupling.step_control: {type: error}' varies the macro step, but 'a' "
                               "cannot take varying steps"), found
    assert found[0].endswith(f"(the scenario's line: {tmp_path / 'fixed.yaml'}:7)"), found


@pytest.mark.skipif(shutil.which("gcc") is None, reason="gcc not installed (native test FMU)")
def test_a_macro_step_off_a_fixed_step_fmus_grid_is_reported_at_the_sweep_axis(tmp_path):
    """A fixed-step FMU needs stop_time on the grid start_time + n*macro_step: an axis over
    coupling.macro_step with 0.03 (stop_time 1.0) was reported at the scenario's first line
    (``fixed.yaml:1: stop_time 1.0 is not on the macro-step grid ...``); now at the axis, and an
    axis over discard_retries at its own line."""
    from tests.fmus_c.build_c_fmu import build_c_fmu
    fixed = build_c_fmu(tmp_path, "AllTypes", fixed_step=True)     # canHandleVariableCommunicationStepSize false
    (tmp_path / "fixed.yaml").write_text(f"name: fixed\nstop_time: 1.0\nfmus:\n  a: {{path: {fixed}}}\n"
                                         "coupling:\n  macro_step: 0.1\n")
    (tmp_path / "sw.yaml").write_text(
        "sweep: 1\nscenario: fixed.yaml\nparameters:\n"
        "  - name: h\n    set: coupling.macro_step\n    values: [0.1, 0.03]\n"
        "  - name: retries\n    set: coupling.discard_retries\n    values: [0, 2]\n")
    found = problems(tmp_path / "sw.yaml")
    assert len(found) == 2, found
    assert found[0].startswith(f"{tmp_path / 'sw.yaml'}:8: run h=0.1, retries=2: --set coupling.discard_retries=2: "
                               "coupling.discard_retries = 2 redoes discarded steps with halved step sizes"), found
    assert found[1].startswith(f"{tmp_path / 'sw.yaml'}:5: run h=0.03, retries=0: --set coupling.macro_step=0.03: "
                               "stop_time 1.0 is not on the macro-step grid start_time + n*0.03"), found
    assert found[1].endswith(f"(the scenario's line: {tmp_path / 'fixed.yaml'}:6)"), found


def test_discard_retries_the_fmus_cannot_honour_are_refused_before_any_run(sdir):
    """coupling.discard_retries > 0 needs every FMU to save its state (Faulty and Gain cannot):
    the master refused it when each run started, so a sweep over it validated, ran, and every
    such run failed naming the scenario. Now validation refuses it at the axis's line, as does
    step_control type error combined with discard_retries."""
    (sdir / "bad.yaml").write_text(
        "sweep: 1\nscenario: ramp.yaml\nparameters:\n"
        "  - name: retries\n    set: [coupling.discard_retries]\n    values: [0, 2]\n"
        "  - name: control\n    set: [coupling.step_control.type]\n    values: [constant, error]\n")
    found = problems(sdir / "bad.yaml")
    text = "\n".join(found)
    assert (f"{sdir / 'bad.yaml'}:5: run retries=2, control='constant': --set coupling.discard_retries=2: "
            "coupling.discard_retries = 2 needs every FMU to save and restore its state") in text, text
    assert f"(the scenario: {sdir / 'ramp.yaml'}:8)" in text, text
    assert (f"{sdir / 'bad.yaml'}:5: run retries=2, control='error': --set coupling.discard_retries=2: "
            "coupling.step_control type error and coupling.discard_retries cannot be combined") in text, text
    assert main(["sweep", str(sdir / "bad.yaml"), "--out", str(sdir / "o")]) == 1
    assert not (sdir / "o").exists()


def test_the_forward_only_warning_of_a_set_step_control_names_the_set(sdir, caplog):
    """step_control type error with FMUs that cannot save state is a warning (the step adapts
    forward only): given by --set (a sweep axis), it names the --set, then the message, then the
    scenario's place."""
    import logging

    from orchestrator import load_scenario
    with caplog.at_level(logging.WARNING, logger="orchestrator.scenario"):
        load_scenario(sdir / "ramp.yaml", ["coupling.step_control.type=error"], build_fmus=False)
    said = [r.getMessage() for r in caplog.records if "adapts forward" in r.getMessage()]
    assert said and said[0].startswith("--set coupling.step_control.type=error: 'coupling.step_control: "
                                       "{type: error}': 'f', 'g' cannot save and restore its state"), said
    assert said[0].endswith(f"(the next step follows the error of the last) (the scenario: {sdir / 'ramp.yaml'}:8)")


def test_workers_with_a_scheduler_is_refused_before_the_output_folder_is_made(sdir, capsys, monkeypatch):
    """`rotorcosim sweep FILE --scheduler ADDRESS --workers N` contradicts itself (the size of a
    cluster is set where its workers start); it was refused only after DIR/runs/ had been made,
    and left DIR behind for a sweep that never started. Now nothing is written."""
    out = sdir / "never"
    assert main(["sweep", str(sdir / "sweep.yaml"), "--out", str(out), "--scheduler", "tcp://127.0.0.1:1",
                 "--workers", "2", "--no-progress"]) == 1
    printed = capsys.readouterr()
    assert "drop --workers" in printed.err
    assert "runs of" not in printed.out          # refused before the runs are planned (validated)
    assert not out.exists()
    monkeypatch.setenv("DASK_SCHEDULER_ADDRESS", "tcp://127.0.0.1:1")   # the same through the environment
    assert main(["sweep", str(sdir / "sweep.yaml"), "--out", str(out), "--workers", "2", "--no-progress"]) == 1
    assert "drop --workers" in capsys.readouterr().err
    assert not out.exists()
