"""Seventh probe (after tests/test_hostile_probe6.py): runs interrupted or killed as a user or a
batch system stops them, run folders others tampered with, and resource limits (file size, open
files, memory). One test per finding, each failing on the code before its fix."""

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

import numpy as np
import pytest

from tests.test_sweep import SCENARIO, SWEEP, _processes_using, _wait_for

REPO = Path(__file__).resolve().parents[1]
posix_only = pytest.mark.skipif(os.name != "posix", reason="process groups and rlimits are POSIX")


def _env() -> dict:
    return dict(os.environ, PYTHONPATH=str(REPO) + os.pathsep + os.environ.get("PYTHONPATH", ""))


def _workers(pid: int) -> list[int]:
    """Child processes of ``pid`` that are FMU workers already (exec'd, importing)."""
    try:
        with open(f"/proc/{pid}/task/{pid}/children") as f:
            kids = [int(p) for p in f.read().split()]
    except OSError:
        return []
    found = []
    for k in kids:
        try:
            with open(f"/proc/{k}/cmdline", "rb") as f:
                if b"worker_main" in f.read():
                    found.append(k)
        except OSError:
            pass
    return found


def _two_mass(tmp_path: Path, test_fmus, *, stop: str = "50.0", extra: str = "") -> Path:
    p = tmp_path / "s.yaml"
    p.write_text(f"name: two-mass\nstop_time: {stop}\nfmus:\n"
                 f"  left: {{path: {test_fmus['LeftMass']}, parameters: {{x1_0: 1.0}}}}\n"
                 f"  right: {{path: {test_fmus['RightMass']}}}\n"
                 "connections:\n  - {from: left.x1, to: right.x1}\n  - {from: right.F, to: left.F}\n"
                 f"coupling: {{macro_step: 1.0e-3{extra}}}\noutput: {{signals: [left.x1, right.F]}}\n")
    return p


@posix_only
@pytest.mark.skipif(not os.path.exists("/proc/self/task"), reason="needs /proc")
def test_ctrl_c_while_the_workers_start_is_an_interrupt_not_an_fmu_crash(tmp_path, test_fmus):
    """The terminal sends Ctrl-C (SIGINT) to the whole foreground process group. A worker process
    (isolation: process) ignored it only once its imports were done, so a Ctrl-C in its first
    0.3 s killed it with a KeyboardInterrupt traceback on the terminal, and the run ended with
    exit code 1, "FMU instance 'left' ... crashed in starting the worker process: its worker
    process was killed by signal SIGINT ...; the FMU's binary failed" and summary.json "setup
    failed" (the same for a SIGTERM to the group, as batch systems send). Now the workers are a
    process group of their own: the run stops as interrupted (exit 130, stopped_by SIGINT)."""
    scen = _two_mass(tmp_path, test_fmus)          # one worker: 'left'
    scen.write_text(scen.read_text().replace("parameters: {x1_0: 1.0}", "parameters: {x1_0: 1.0}, isolation: process"))
    out = tmp_path / "out"
    for signum, code in ((signal.SIGINT, 130), (signal.SIGTERM, 143)):
        proc = subprocess.Popen([sys.executable, "-m", "orchestrator", "run", str(scen), "--out", str(out)],
                                stdout=subprocess.PIPE, stderr=subprocess.STDOUT, env=_env(), cwd=tmp_path,
                                start_new_session=True)
        try:
            deadline = time.monotonic() + 60
            while not _workers(proc.pid) and time.monotonic() < deadline and proc.poll() is None:
                time.sleep(0.002)
            assert _workers(proc.pid), "no worker process started"
            os.killpg(proc.pid, signum)          # what the terminal (or `kill -- -PGID`) does, while it imports
            text = proc.communicate(timeout=120)[0].decode(errors="replace")
        finally:
            if proc.poll() is None:
                os.killpg(proc.pid, signal.SIGKILL)
                proc.wait()
        assert proc.returncode == code, text
        assert "crashed" not in text and "Traceback" not in text, text
        summary = json.loads((out / "summary.json").read_text())
        assert summary["status"] == "failed" and summary.get("stopped_by") == signum.name, summary


@posix_only
def test_sigterm_to_a_sweep_writes_its_table_and_says_how_to_resume(tmp_path, test_fmus):
    """`kill PID` (SIGTERM, what a batch system or a service manager sends) of `rotorcosim sweep`
    killed it outright: exit -15, no sweep.csv, no message (its run processes stopped only once
    they noticed their worker was gone). Now SIGTERM stops a sweep as Ctrl-C does: the table of what
    finished is written (the rest `cancelled`), the runs in progress are stopped, and the
    message says how to resume; exit 143."""
    (tmp_path / "fmus").mkdir()
    for name in ("Faulty", "Gain"):
        shutil.copy(test_fmus[name], tmp_path / "fmus" / f"{name}.fmu")
    (tmp_path / "ramp.yaml").write_text(SCENARIO)
    # t_fail beyond stop_time: no run can fail on its own before the signal is handled (with
    # t_fail 2.0 the first run's 10000 steps could reach its failure first on a fast host: CI, 9ac42e7)
    (tmp_path / "long.yaml").write_text(SWEEP.replace("[0.05, 0.5, 1.0]", "[200.0, 300.0, 400.0, 500.0]")
                                        .replace("stop_time: 0.1", "stop_time: 100.0, coupling.macro_step: 2.0e-4"))
    out = tmp_path / "o"
    proc = subprocess.Popen([sys.executable, "-m", "orchestrator", "sweep", str(tmp_path / "long.yaml"), "--out",
                             str(out), "--workers", "1", "--no-progress"], stdout=subprocess.PIPE,
                            stderr=subprocess.PIPE, text=True, env=_env(), start_new_session=True)
    try:
        _wait_for(lambda: any((out / "runs").glob("*/summary.json")), 240, "the first run to start")
        os.kill(proc.pid, signal.SIGTERM)                 # the sweep's process only, not its group
        _, err = proc.communicate(timeout=120)
    finally:
        if proc.poll() is None:
            os.killpg(proc.pid, signal.SIGKILL)
            proc.wait()
    assert proc.returncode == 143, err
    assert "terminated by signal SIGTERM" in err and "--resume" in err and "Traceback" not in err, err
    rows = (out / "sweep.csv").read_text().splitlines()[1:]
    assert len(rows) == 4 and all(",cancelled," in r for r in rows), rows
    _wait_for(lambda: not _processes_using(out), 30, "the run processes to end")      # none left running


def _journal_run(tmp_path: Path, journals: dict, n: int = 60) -> Path:
    run = tmp_path / "run"
    run.mkdir()
    rows = "".join(f"{i * 1e-3!r},{1e-6 * float(np.cos(i / 3))!r},{1e-6 * float(np.sin(i / 3))!r},{300.0 + i}\n"
                   for i in range(n))
    (run / "results.csv").write_text("time,r.x_1,r.y_1,r.omega\n" + rows)
    (run / "summary.json").write_text(json.dumps({"scenario": "s", "status": "finished", "analysis": {
        "spec": {"speed": "r.omega", "journals": journals}}}))
    return run


def test_a_clearance_of_1e308_skips_the_waterfall_with_a_reason(tmp_path):
    """A summary.json whose journal clearance is 1e308 m (positive and finite, so the checks let it
    through) made `rotorcosim plot` end in "internal error: ValueError: Invalid vmin or vmax": the
    waterfall's amplitudes / clearance fell below the smallest normal float and matplotlib's
    logarithmic colour bar failed. Now that waterfall is skipped with a warning naming the
    clearance; the other figures are drawn."""
    from orchestrator.results.plots import plot_run
    t = np.arange(4000) * 2e-4                      # 0.8 s at 300 Hz: enough revolutions for a waterfall
    x, y = 1e-6 * np.cos(2 * np.pi * 300 * t), 1e-6 * np.sin(2 * np.pi * 300 * t)
    run = tmp_path / "run"
    run.mkdir()
    (run / "results.csv").write_text("time,r.x_1,r.y_1,r.omega\n" + "".join(
        f"{a!r},{b!r},{c!r},{2 * np.pi * 300}\n" for a, b, c in zip(t.tolist(), x.tolist(), y.tolist())))
    for c, ok in ((1.372e-5, True), (1e308, False)):
        (run / "summary.json").write_text(json.dumps({"scenario": "s", "status": "finished", "analysis": {
            "spec": {"speed": "r.omega", "journals": {"b1": {"x": "r.x_1", "y": "r.y_1", "clearance": c}}}}}))
        with warnings.catch_warnings(record=True) as rec:
            warnings.simplefilter("always")
            written = [p.name for p in plot_run(run)]
        assert ("waterfall_b1.png" in written) is ok, written
        assert "orbit_b1.png" in written
        if not ok:
            assert any("waterfall of 'b1'" in str(w.message) and "clearance 1e+308 m" in str(w.message)
                       for w in rec), [str(w.message) for w in rec]


def test_the_journals_one_plot_draws_are_bounded(tmp_path, monkeypatch):
    """A summary.json (or a results.csv of x_i/y_i column pairs) listing 2000 journals kept
    `rotorcosim plot` drawing 4000 figures (still at it after 5 minutes). Now at most MAX_JOURNALS (50) are drawn
    and a warning says how many were left out."""
    import orchestrator.results.plots as plots
    monkeypatch.setattr(plots, "MAX_JOURNALS", 3, raising=False)      # 8 journals: fast either way
    run = _journal_run(tmp_path, {f"j{i}": {"x": "r.x_1", "y": "r.y_1"} for i in range(8)})
    with warnings.catch_warnings(record=True) as rec:
        warnings.simplefilter("always")
        written = [p.name for p in plots.plot_run(run)]
    assert sorted(n for n in written if n.startswith("orbit_")) == ["orbit_j0.png", "orbit_j1.png", "orbit_j2.png"]
    assert any("8 journals in the analysis spec" in str(w.message) and "the other 5 are not" in str(w.message)
               for w in rec), [str(w.message) for w in rec]


@posix_only
def test_plot_does_not_write_figures_through_a_plots_link(tmp_path, capsys):
    """A run folder from someone else whose `plots` is a symbolic link to another folder (`plots -> ~`)
    made `rotorcosim plot` write its PNGs there, replacing files of the same names
    (orbit_<journal>.png, eccentricity.png). Now the link is refused, naming where it points, and
    nothing is written; the same for a sweep folder's plots/."""
    from orchestrator.cli import main
    run = _journal_run(tmp_path, {"b1": {"x": "r.x_1", "y": "r.y_1"}})
    elsewhere = tmp_path / "elsewhere"
    elsewhere.mkdir()
    (elsewhere / "orbit_b1.png").write_text("my own file")
    (run / "plots").symlink_to(elsewhere)
    assert main(["plot", str(run)]) == 1
    err = capsys.readouterr().err
    assert f"{run / 'plots'} is a symbolic link (to {elsewhere})" in err and "remove the link" in err, err
    assert sorted(p.name for p in elsewhere.iterdir()) == ["orbit_b1.png"]
    assert (elsewhere / "orbit_b1.png").read_text() == "my own file"
    from tests.test_sweep_hostile import sweep_folder
    d = sweep_folder(tmp_path)
    (d / "plots").symlink_to(elsewhere)
    assert main(["plot", str(d)]) == 1
    assert f"{d / 'plots'} is a symbolic link" in capsys.readouterr().err
    assert sorted(p.name for p in elsewhere.iterdir()) == ["orbit_b1.png"]


@posix_only
def test_an_fmu_that_cannot_be_extracted_names_the_fmu_the_folder_and_the_limit(tmp_path, test_fmus):
    """Under a file size limit (`ulimit -f`) below an FMU's largest file, `rotorcosim run` ended in
    "error: File too large" (a full temporary folder: "error: No space left on device; the disk is
    full"), naming neither the FMU nor the folder, which is in TMPDIR, not the output folder the
    user then looked at. Now the message names both and the fix (raise the limit / set TMPDIR)."""
    import resource
    scen = _two_mass(tmp_path, test_fmus, stop="0.01")
    limit = 64 * 1024                                   # the FMUs' shared libraries are larger

    def small_files():
        resource.setrlimit(resource.RLIMIT_FSIZE, (limit, limit))

    proc = subprocess.run([sys.executable, "-m", "orchestrator", "run", str(scen), "--out", str(tmp_path / "o")],
                          capture_output=True, text=True, env=_env(), cwd=tmp_path, preexec_fn=small_files,
                          timeout=300)
    assert proc.returncode == 1, proc.stderr
    err = proc.stderr
    assert "cannot extract the FMU into" in err and "File too large" in err and "ulimit -f" in err, err
    assert str(test_fmus["LeftMass"]) in err or str(test_fmus["RightMass"]) in err, err
    summary = json.loads((tmp_path / "o" / "summary.json").read_text())
    assert summary["status"] == "failed" and "cannot extract the FMU" in summary["message"], summary


@posix_only
def test_shared_memory_a_file_size_limit_refuses_is_named_with_the_fix(tmp_path, test_fmus):
    """The shared memory of a worker process (isolation: process, 1 MiB at least) counts against the
    file size limit (`ulimit -f`): below it, `rotorcosim run` and `validate` (which loads every FMU
    in a worker) ended in "error: File too large". Now the message names the instance, the size and
    the fix."""
    import resource
    scen = _two_mass(tmp_path, test_fmus, stop="0.01", extra=", isolation: process")
    limit = 768 * 1024                                  # above the FMUs' files, below the 1 MiB arena

    def small_files():
        resource.setrlimit(resource.RLIMIT_FSIZE, (limit, limit))

    for verb in (["run", str(scen), "--out", str(tmp_path / "o")], ["validate", str(scen)]):
        proc = subprocess.run([sys.executable, "-m", "orchestrator", *verb], capture_output=True, text=True,
                              env=_env(), cwd=tmp_path, preexec_fn=small_files, timeout=300)
        assert proc.returncode == 1, proc.stderr
        out = proc.stdout + proc.stderr
        assert "cannot make the shared memory (1048576 bytes) of its worker process" in out, out
        assert "ulimit -f" in out and "FMU instance 'left'" in out, out


@posix_only
def test_too_few_open_files_for_the_worker_processes_is_named_with_the_fix(tmp_path, test_fmus):
    """Each worker process (isolation: process) needs file descriptors of the master (its socket,
    its shared memory, a pipe while it starts). Under a low limit of open files (`ulimit -n`) the
    run ended in a bare "error: Too many open files" (or "error: /dev/null: Too many open files").
    Now the instance, the limit and the fix are named."""
    import resource
    scen = _two_mass(tmp_path, test_fmus, stop="0.01", extra=", isolation: process")

    def few_files():
        resource.setrlimit(resource.RLIMIT_NOFILE, (12, resource.getrlimit(resource.RLIMIT_NOFILE)[1]))

    proc = subprocess.run([sys.executable, "-m", "orchestrator", "run", str(scen), "--out", str(tmp_path / "o")],
                          capture_output=True, text=True, env=_env(), cwd=tmp_path, preexec_fn=few_files,
                          timeout=300)
    assert proc.returncode == 1, proc.stderr
    assert "cannot start its worker process (isolation: process): Too many open files" in proc.stderr, proc.stderr
    assert "`ulimit -n`, now 12" in proc.stderr, proc.stderr
    summary = json.loads((tmp_path / "o" / "summary.json").read_text())
    assert "cannot start its worker process" in summary["message"], summary


def test_a_full_disk_at_the_lock_file_is_named_and_does_not_keep_the_folder_locked(tmp_path, monkeypatch):
    """On an output disk with no room left, the run's first write (its record in .rotorcosim.lock)
    failed with a bare "error: No space left on device", and the lock's descriptor stayed open: the
    next run of the same process (a notebook, a script's retry) into that folder, once there was
    room, was refused as "in use by another run" - its own. Now the message names the lock file and
    the fix, and the folder is free again."""
    import errno
    from types import SimpleNamespace

    from orchestrator.coupling import lifecycle
    from orchestrator.errors import OutputWriteError
    sc = SimpleNamespace(name="a", source=tmp_path / "a.yaml", fmus=())
    real = os.pwrite

    def full(fd, data, offset):
        raise OSError(errno.ENOSPC, "No space left on device")

    monkeypatch.setattr(lifecycle.os, "pwrite", full)
    with pytest.raises(OutputWriteError) as info:
        with lifecycle.RunFolder(tmp_path / "out", sc):
            pass
    assert f"cannot write the lock file {tmp_path / 'out' / '.rotorcosim.lock'} (No space left on device)" in \
        str(info.value) and "free some space" in str(info.value)
    monkeypatch.setattr(lifecycle.os, "pwrite", real)                  # room again
    assert lifecycle.folder_in_use(tmp_path / "out") is False
    with lifecycle.RunFolder(tmp_path / "out", sc) as folder:
        folder.finish({"status": "finished"})


def test_ctrl_c_while_a_figure_is_written_leaves_no_temporary_file(tmp_path):
    """Ctrl-C during `rotorcosim plot` (a figure takes a second or more to draw) left
    `plots/.eccentricity.png.XXXX.part` behind: the temporary file was removed only after an
    OSError. Now after any exception, and the interrupt goes on."""
    from orchestrator.results.safe_write import save_figure

    class Figure:
        def savefig(self, f, **kw):
            f.write(b"\x89PNG half")
            raise KeyboardInterrupt

    (tmp_path / "plots").mkdir()
    with pytest.raises(KeyboardInterrupt):
        save_figure(Figure(), tmp_path / "plots" / "eccentricity.png")
    assert list((tmp_path / "plots").iterdir()) == []


def test_ctrl_c_while_build_fmus_writes_an_fmu_leaves_no_temporary_file(tmp_path, monkeypatch):
    """The same for `rotorcosim build-fmus`: Ctrl-C while the built FMU was copied into place left
    `.JeffcottRotor.fmu.<pid>.tmp` in the FMU folder."""
    from orchestrator.fmi import build

    real = build.shutil.copyfile

    def copy_half(src, dst, **kw):
        if Path(dst).parent != tmp_path:                # the build's own copies
            return real(src, dst, **kw)
        Path(dst).write_bytes(b"PK half an FMU")
        raise KeyboardInterrupt

    monkeypatch.setattr(build.shutil, "copyfile", copy_half)
    with pytest.raises(KeyboardInterrupt):
        build.build_one(build.RECIPES["JeffcottRotor"], tmp_path)
    assert list(tmp_path.iterdir()) == []


def test_a_crafted_call_record_nested_too_deeply_is_ignored_by_plot(tmp_path):
    """`rotorcosim plot` of a folder whose run ended without a final summary reads the FMI call
    record `.rotorcosim.calls` to say which call the run died in. One holding "[[[[..." (500 000
    deep, well within its 1 MiB bound) ended `plot` in "internal error: RecursionError". Now the
    record is ignored like any other unreadable one and the figures are drawn."""
    from orchestrator.fmi.call_record import read_calls
    from orchestrator.results.plots import plot_run
    run = _journal_run(tmp_path, {"b1": {"x": "r.x_1", "y": "r.y_1"}})
    (run / "summary.json").write_text(json.dumps({"scenario": "s", "status": "running", "pid": 1}))
    (run / ".rotorcosim.lock").write_text("")
    (run / ".rotorcosim.calls").write_text("[" * 500_000)
    assert read_calls(run / ".rotorcosim.calls") == []
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        assert [p.name for p in plot_run(run) if p.name.startswith("orbit_")]


@pytest.mark.parametrize("record", ["[" * 3000, "[1, 2]"])
def test_a_lock_record_that_is_no_json_object_is_unreadable_not_an_internal_error(tmp_path, record):
    """A second run into a folder in use reads who holds it from `.rotorcosim.lock`. A record of
    "[[[[..." ended in "internal error: RecursionError", a JSON list in "AttributeError: 'list' object
    has no attribute 'get'"; now both say the folder is in use by another process that has not said
    which run it is (the message of a holder whose details cannot be read, after its bounded wait)."""
    import fcntl
    from types import SimpleNamespace

    from orchestrator.coupling import lifecycle
    from orchestrator.errors import LifecycleError
    (tmp_path / ".rotorcosim.lock").write_text(record)
    with open(tmp_path / ".rotorcosim.lock") as held:
        fcntl.flock(held, fcntl.LOCK_EX)              # a live run holds it
        with pytest.raises(LifecycleError,
                           match=r"in use by another process: it holds .* but had not written which run it is"):
            with lifecycle.RunFolder(tmp_path, SimpleNamespace(name="a", source=None, fmus=())):
                pass


@posix_only
@pytest.mark.parametrize("signum, code", [(signal.SIGINT, 130), (signal.SIGTERM, 143)])
def test_a_stopped_comparison_starts_no_more_runs_and_stops_the_running_ones(tmp_path, test_fmus, signum, code):
    """Ctrl-C that reached only `rotorcosim compare`'s own process (`kill -INT PID`, an IDE's stop
    button) let every queued run start and run to its end before the comparison said
    "interrupted" (minutes to hours); SIGTERM killed it without a word (exit -15), its runs going
    on; a Ctrl-C to the whole group printed a traceback per run. Now the queued runs never start,
    the running ones stop after their macro step (their summary says why), exit 130 / 143."""
    _two_mass(tmp_path, test_fmus, stop="30.0")
    cmp = tmp_path / "cmp.yaml"
    cmp.write_text("compare:\n  scenario: s.yaml\n  signals: [left.x1]\n  reference: {macro_step: 5.0e-4}\n"
                   "  variants:\n    - {macro_step: 1.0e-3}\n    - {macro_step: 2.0e-3}\n"
                   "    - {scheme: jacobi, macro_step: 1.0e-3}\n")
    out = tmp_path / "c"
    proc = subprocess.Popen([sys.executable, "-m", "orchestrator", "compare", str(cmp), "--out", str(out)],
                            stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True, env=_env(), cwd=tmp_path,
                            start_new_session=True)
    try:
        _wait_for(lambda: len(list((out / "runs").glob("*/summary.json"))) >= 2, 120, "two runs to start")
        os.kill(proc.pid, signum)                     # the comparison's process only
        t0 = time.monotonic()
        _, err = proc.communicate(timeout=300)
        stopped_in = time.monotonic() - t0
    finally:
        if proc.poll() is None:
            os.killpg(proc.pid, signal.SIGKILL)
            proc.wait()
    assert proc.returncode == code, err
    assert "Traceback" not in err, err
    assert stopped_in < 60, stopped_in
    started = sorted(p.parent.name for p in (out / "runs").glob("*/summary.json"))
    assert started == ["reference", "reference-check"], started        # no variant started
    for name in started:
        summary = json.loads((out / "runs" / name / "summary.json").read_text())
        assert summary.get("stopped_by") == signum.name, summary
    _wait_for(lambda: not _processes_using(out), 30, "the run processes to end")


def test_a_sweep_table_with_collected_texts_is_drawn_not_refused(tmp_path, capsys):
    """A sweep writes a collected value as summary.json holds it: a text, or a list or object as
    JSON (`collect: {onset: analysis.journals.bearing1.onset}`, `{why: message}`). `rotorcosim plot`
    then refused the whole folder ("sweep.csv:3: column 'steps' must be a number ...; rerun the
    sweep (or fix the file)"), which no rerun fixes. Now such cells are drawn as no value, with a
    warning naming the column, the line and the value."""
    from orchestrator.cli import main
    from tests.test_sweep_hostile import HEADER, ROWS, sweep_folder
    d = sweep_folder(tmp_path, HEADER + ROWS[0] + ROWS[1].replace(",20,", ',"[1, 2]",') + "".join(ROWS[2:]))
    with warnings.catch_warnings(record=True) as rec:
        warnings.simplefilter("always")
        assert main(["plot", str(d)]) == 0, capsys.readouterr().err
    assert (d / "plots" / "sweep_steps.png").is_file()
    assert any("sweep.csv:3: column 'steps' holds 1 value(s) that are not numbers (first: '[1, 2]')"
               in str(w.message) for w in rec), [str(w.message) for w in rec]


@posix_only
def test_a_file_or_link_where_a_sweep_run_folder_goes_is_replaced_not_a_crash_or_written_through(tmp_path):
    """runs/<run_id> belongs to the sweep. A file there ended that run as "crashed: the task failed
    on its worker: FileExistsError: [Errno 17] File exists"; a symbolic link there (to another
    folder) made the run write results.csv, summary.json, run.log and sweep_run.json where it
    pointed. Now either is removed (the link itself, never its target) and the run runs in a
    folder of its own."""
    from orchestrator.sweep import task
    elsewhere = tmp_path / "elsewhere"
    elsewhere.mkdir()
    runs = tmp_path / "runs"
    runs.mkdir()
    (runs / "aaa").write_text("debris")
    (runs / "bbb").symlink_to(elsewhere)
    seen = []

    def fake(args, out, timeout_s):          # stands in for the run process
        seen.append(out)
        (out / "summary.json").write_text(json.dumps({"status": "finished", "message": ""}))
        return 0, ""

    with pytest.MonkeyPatch.context() as mp:
        mp.setattr(task, "_fresh", fake)
        recs = [task.execute_run("s.yaml", [], str(runs / rid), warm=False) for rid in ("aaa", "bbb")]
    assert [r["status"] for r in recs] == ["finished", "finished"], recs
    for rid in ("aaa", "bbb"):
        assert (runs / rid).is_dir() and not (runs / rid).is_symlink()
        assert (runs / rid / "sweep_run.json").is_file()
    assert list(elsewhere.iterdir()) == []


@posix_only
def test_running_out_of_memory_is_a_message_not_an_internal_error(monkeypatch):
    """A MemoryError (a memory limit, `ulimit -v`, or a machine out of memory while a scenario or
    its FMUs are set up) ended in "internal error: MemoryError (this is a bug in rotorcosim ...)".
    Now it is "error: out of memory; ..." with the limit when one is set, and a library that cannot
    be mapped under such a limit (llvmlite's "Could not find/load shared object file") gets the
    limit as its likely cause."""
    import resource

    from orchestrator import cli
    soft, hard = resource.getrlimit(resource.RLIMIT_AS)
    monkeypatch.setattr(resource, "getrlimit", lambda r: (3 * 2**30, hard) if r == resource.RLIMIT_AS else (soft, hard))
    text = cli._describe(MemoryError())
    assert text.startswith("error: out of memory;") and "3072 MiB" in text and "ulimit -v" in text, text
    text = cli._describe(OSError("Could not find/load shared object file 'libllvmlite.so'"))
    assert "ulimit -v" in text, text
    monkeypatch.setattr(resource, "getrlimit", lambda r: (resource.RLIM_INFINITY, resource.RLIM_INFINITY))
    text = cli._describe(MemoryError())
    assert text.startswith("error: out of memory;") and "internal error" not in text, text


def test_a_parquet_file_of_a_killed_run_says_why_it_cannot_be_read(tmp_path, capsys):
    """A run with output.format: parquet killed hard (SIGKILL) leaves results.parquet without its
    footer; `rotorcosim plot` said only "not a readable Parquet file (ArrowInvalid: ... Parquet magic
    bytes not found in footer. Either the file is corrupted or this is not a parquet file.)". Now
    it says the run was killed before it closed the file, that none of its rows can be read, and
    that output.format: csv keeps the rows of a killed run."""
    pa = pytest.importorskip("pyarrow")
    import pyarrow.parquet as pq

    from orchestrator.cli import main
    run = _journal_run(tmp_path, {"b1": {"x": "r.x_1", "y": "r.y_1"}})
    (run / "results.csv").unlink()
    path = run / "results.parquet"
    pq.write_table(pa.table({"time": [0.0, 0.1, 0.2], "r.x_1": [1.0, 2.0, 3.0]}), path)
    path.write_bytes(path.read_bytes()[:-12])          # no footer: what SIGKILL leaves
    assert main(["plot", str(run)]) == 1
    err = capsys.readouterr().err
    assert "the run was killed (or its disk filled) before it ended and none of its rows can be read" in err, err
    assert "output.format: csv" in err, err


def test_the_summary_of_a_run_stopped_by_a_write_error_says_its_reason_once(tmp_path, capsys, monkeypatch,
                                                                          test_fmus):
    """A run whose results.csv could not be written (full disk, `ulimit -f`) wrote a summary message
    holding the whole reason twice: "the run stopped at t=0.006 s: OutputWriteError: cannot write
    ...; free some space ...; stopped by an error (OutputWriteError: cannot write ...; free some
    space ...) at t=0.006 s". Now once."""
    from hostile_builders import two_mass_dir
    from tests.test_hostile_probe3 import _disk_full_after
    d = two_mass_dir(tmp_path, test_fmus)
    _disk_full_after(monkeypatch, 6)
    from orchestrator.cli import main
    assert main(["run", str(d / "two_mass.yaml"), "--out", str(tmp_path / "out")]) == 1
    message = json.loads((tmp_path / "out" / "summary.json").read_text())["message"]
    assert message.count("cannot write") == 1, message
    assert message.startswith("the run stopped at t=0.006 s: OutputWriteError: cannot write"), message


def test_load_names_each_wrong_typed_summary_field_and_drops_it(tmp_path, caplog):
    """CoSimResult.load passed wrong-typed summary.json fields through silently: macro_steps "x"
    and fmu_calls "y" came back as stats, status "exploded" became failed without a word. Now each
    field the loader reads is type-checked; a wrong one is dropped with a warning naming the
    file, the field, what was expected and what came (as plot drops a malformed analysis)."""
    import logging
    from orchestrator import CoSimResult
    from orchestrator.results.result import Status
    (tmp_path / "results.csv").write_text("time,a.y\n0.0,1.0\n0.1,2.0\n")
    (tmp_path / "summary.json").write_text(json.dumps({
        "status": "exploded", "message": ["no"], "macro_steps": "x", "rejected_steps": True,
        "retried_steps": 2, "wall_time_s": "slow", "fmu_calls": "y", "end_time": {"t": 1},
        "analysis": [1, 2]}))
    with caplog.at_level(logging.WARNING, logger="orchestrator.results.result"):
        res = CoSimResult.load(tmp_path)
    assert res.status is Status.FAILED and res.message == "" and res.end_time is None and res.analysis is None
    assert res.stats == {"retried_steps": 2}
    said = caplog.text
    for field, got in (("status", "'exploded'"), ("message", "['no']"), ("macro_steps", "'x'"),
                       ("rejected_steps", "True"), ("wall_time_s", "'slow'"), ("fmu_calls", "'y'"),
                       ("end_time", "{'t': 1}"), ("analysis", "[1, 2]")):
        assert f"summary.json: field '{field}' must be" in said and got in said, field
    assert "the run is taken as failed" in said
    # a summary as a run writes it (counters null while running, a non-finite float as "inf") is quiet
    caplog.clear()
    (tmp_path / "summary.json").write_text(json.dumps({
        "status": "running", "message": "m", "macro_steps": None, "wall_time_s": None, "end_time": "inf",
        "fmu_calls": {"a": {"doStep": 3}}, "analysis": None}))
    with caplog.at_level(logging.WARNING, logger="orchestrator.results.result"):
        res = CoSimResult.load(tmp_path)
    assert caplog.text == "" and res.status is Status.RUNNING and res.end_time == float("inf")
    assert res.stats == {"macro_steps": None, "wall_time_s": None, "fmu_calls": {"a": {"doStep": 3}}}


def _run_in_progress(scenario, overrides, run_dir, *, warm=True, inputs=None):   # stands in for task.execute_run
    out = Path(run_dir)
    out.mkdir(parents=True, exist_ok=True)
    if any(o.endswith("t_fail=0.05") for o in overrides):
        return {"status": "finished", "message": "", "wall_time_s": 0.0, "summary": {"status": "finished"}}
    (out / "results.csv").write_text("time,f.y\n0.0,1.0\n")
    (out / "summary.json").write_text(json.dumps({"status": "running", "message": "the run is in progress"}))
    time.sleep(30.0)
    return {"status": "finished", "message": "", "wall_time_s": 0.0, "summary": {"status": "finished"}}


def _run_again(scenario, overrides, run_dir, *, warm=True, inputs=None):
    (Path(run_dir) / "ran-again").write_text("")
    return {"status": "finished", "message": "", "wall_time_s": 0.0, "summary": {"status": "finished"}}


@pytest.mark.filterwarnings("ignore:collect")        # the stand-in runs write no end_time/steps
def test_an_interrupted_sweep_says_which_runs_were_running_not_that_they_never_ran(tmp_path, test_fmus,
                                                                                   monkeypatch):
    """Ctrl-C while a run was in progress: its row said "not run: the sweep was interrupted"
    although its folder held the rows and summary it had written. Now it says "interrupted while
    running" and what its own summary.json says; a run that never started still says "not run",
    one whose folder holds only an earlier sweep's summary too; --resume runs both again."""
    import threading

    from orchestrator.sweep import prepare, runner
    (tmp_path / "fmus").mkdir()
    for name in ("Faulty", "Gain"):
        shutil.copy(test_fmus[name], tmp_path / "fmus" / f"{name}.fmu")
    (tmp_path / "ramp.yaml").write_text(SCENARIO)
    (tmp_path / "sweep.yaml").write_text(SWEEP)
    monkeypatch.setattr(runner, "execute_run", _run_in_progress)
    spec, runs = prepare(tmp_path / "sweep.yaml")
    old = tmp_path / "o" / "runs" / runs[2].run_id          # an earlier sweep's run, never started in this one
    old.mkdir(parents=True)
    (old / "summary.json").write_text(json.dumps({"status": "failed", "message": "of an earlier sweep"}))
    os.utime(old / "summary.json", (time.time() - 3600, time.time() - 3600))
    timer = threading.Timer(8.0, os.kill, (os.getpid(), signal.SIGINT))
    timer.start()
    try:
        outcome = runner.run_sweep(spec, runs, tmp_path / "o", workers=1, warm=False, progress=False)
    finally:
        timer.cancel()
    assert outcome.interrupted
    rows = outcome.rows
    assert [r["status"] for r in rows] == ["finished", "cancelled", "cancelled"], rows
    assert rows[1]["message"].startswith("interrupted while running (its summary.json still says running"), rows[1]
    assert "rows so far" in rows[1]["message"] and "--resume" in rows[1]["message"]
    assert rows[2]["message"].startswith("not run: the sweep was interrupted"), rows[2]
    table = (tmp_path / "o" / "sweep.csv").read_text()
    assert "interrupted while running" in table
    monkeypatch.setattr(runner, "execute_run", _run_again)
    again = runner.run_sweep(spec, runs, tmp_path / "o", workers=1, warm=False, progress=False, resume=True)
    assert [r["status"] for r in again.rows] == ["finished"] * 3
    assert all((tmp_path / "o" / "runs" / r.run_id / "ran-again").exists() for r in runs[1:])


def test_the_printed_summary_of_an_interrupted_sweep_names_the_runs_that_were_running(tmp_path, test_fmus,
                                                                                       monkeypatch, capsys):
    """`rotorcosim sweep` printed no line for the cancelled runs, so a run interrupted while running
    (its rows kept) could not be told from one never started. Now each cancelled run that had
    started is printed with its message; those not run are only counted."""
    from orchestrator.cli import main
    from orchestrator.sweep import runner
    (tmp_path / "fmus").mkdir()
    for name in ("Faulty", "Gain"):
        shutil.copy(test_fmus[name], tmp_path / "fmus" / f"{name}.fmu")
    (tmp_path / "ramp.yaml").write_text(SCENARIO)
    (tmp_path / "sweep.yaml").write_text(SWEEP)
    rows = [{"run_id": "r1", "status": "finished", "message": ""},
            {"run_id": "r2", "status": "cancelled",
             "message": "interrupted while running (its summary.json says failed: interrupted by the user at "
                        "t=0.3 s); rerun with --resume"},
            {"run_id": "r3", "status": "cancelled",
             "message": "not run: the sweep was interrupted; rerun with --resume"}]
    monkeypatch.setattr(runner, "run_sweep", lambda *a, **kw: runner.SweepOutcome(
        rows=rows, out_dir=tmp_path / "o", table=tmp_path / "o" / "sweep.csv", interrupted=True, stopped_by="SIGINT"))
    assert main(["sweep", str(tmp_path / "sweep.yaml"), "--out", str(tmp_path / "o"), "--no-progress"]) == 130
    err = capsys.readouterr().err
    assert "r2 cancelled: interrupted while running (its summary.json says failed: interrupted by the user" in err
    assert "r3" not in err


_KILLED_RUN = """
import os, signal, sys
from pathlib import Path
from types import SimpleNamespace
from orchestrator.coupling.lifecycle import RunFolder
from orchestrator.fmi.call_record import CODE
sc = SimpleNamespace(name="killed", source=None, fmus=[SimpleNamespace(name="rotor"), SimpleNamespace(name="bearing1")])
f = RunFolder(sys.argv[1], sc).__enter__()
(Path(sys.argv[1]) / "results.csv").write_text("time,rotor.x\\n0.0,1.0\\n0.001,2.0\\n")
a, k = f.calls.slot("bearing1")
a[k + 1], a[k] = 0.004, CODE["fmi2DoStep"]
os.kill(os.getpid(), signal.SIGKILL)
"""


@posix_only
def test_the_call_record_of_a_killed_run_goes_to_previous_with_its_other_files(tmp_path):
    """After a SIGKILL of a run, the next run into the folder moved the killed run's summary.json
    and results.csv into previous/ but truncated its FMI call record .rotorcosim.calls (made
    anew for itself), and `plot DIR/previous` (no lock file there) said nothing of the run having
    died. Now the record is moved along, and plot of the previous/ folder of a run folder says
    the run ended without a final summary and which FMI call it died in."""
    from types import SimpleNamespace

    from orchestrator.coupling.lifecycle import CALLS_NAME, RunFolder, open_calls
    from orchestrator.results.plots import plot_run
    out = tmp_path / "out"
    r = subprocess.run([sys.executable, "-c", _KILLED_RUN, str(out)], env=_env(), capture_output=True,
                       text=True, timeout=120)
    assert r.returncode == -signal.SIGKILL, r.stderr
    assert open_calls(out) == [("bearing1", "fmi2DoStep", 0.004)]
    with RunFolder(out, SimpleNamespace(name="next", source=None, fmus=[SimpleNamespace(name="g")])) as f:
        assert open_calls(out) == []                        # the new run's own record, no open call
        f.finish({"status": "finished", "message": "done"})
    assert not (out / CALLS_NAME).exists()                  # a run that ended in order removes its own
    assert open_calls(out / "previous") == [("bearing1", "fmi2DoStep", 0.004)]
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        assert plot_run(out / "previous")
    said = [str(w.message) for w in caught if "ended without a final summary" in str(w.message)]
    assert len(said) == 1 and "'bearing1' in fmi2DoStep at t=0.004 s" in said[0], [str(w.message) for w in caught]


@pytest.mark.parametrize("value", ["1e300", "-1e300", "1e308", "1.7976931348623157e308", "5e-324", "0"])
def test_a_signal_constant_at_an_extreme_value_is_drawn_flat_without_a_stray_warning(tmp_path, value):
    """A signal constant at an extreme value: at 5e-324 plot printed matplotlib's unattributed
    "Attempting to set identical low and high ylims" (0.1 % of the value, the steady axis's pad,
    is 0), at 1e308 it ended in "internal error: ValueError: arange: cannot compute length" (the
    tick finder overflows), at 1.8e308 in "Axis limits cannot be NaN or Inf" (the value + 0.1 %
    is inf). Now signals.steady_limits keeps the limits finite and distinct for any magnitude, a
    steady signal of 1e300 or more is drawn divided by a power of ten, and such a signal's one
    tick is its value, labelled by us: a flat line, no warning."""
    from orchestrator.results.plots import plot_run
    from orchestrator.results.plots.signals import steady_limits, steady_scale, steady_ticks
    y = np.full(20, float(value))
    lims = steady_limits(y)
    assert lims is not None and np.all(np.isfinite(lims)) and lims[0] < lims[1], lims
    assert lims[0] <= y[0] <= lims[1]
    scale = steady_scale(lims)
    if abs(y[0]) >= 1e300:
        assert 1 <= abs(y[0]) / scale < 10 and steady_ticks(lims, y) == [y[0]]
        scaled = steady_limits(y / scale)
        assert scaled[0] < y[0] / scale < scaled[1] and scaled[1] - scaled[0] > 1e-3
    (tmp_path / "results.csv").write_text("time,a.y\n" + "".join(f"{i * 0.1},{value}\n" for i in range(20)))
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        paths = plot_run(tmp_path)
    assert [p.name for p in paths] == ["signals_a.png"]
    assert [str(w.message) for w in caught] == []


@pytest.mark.parametrize("speed", [1e300, 2 * np.pi * 300 * 60 * 1e4])
def test_a_speed_with_too_many_revolutions_skips_the_waterfall_and_the_analysis_with_a_reason(tmp_path, speed):
    """A speed signal constant at 1e300 rad/s in results.csv made `rotorcosim plot` end in
    "internal error: Maximum allowed size exceeded": the orbit was resampled into one angle bin per
    1/32 revolution, with no bound on their number (whirl.order_resample); the run-up analysis
    calls the same code. Now at most whirl.MAX_ORDER_BINS bins: the waterfall is skipped and the
    analysis says why (naming the speed's largest value and asking whether it is in rad/s), and
    the other figures are drawn. Also for a finite but absurd speed (300 Hz given in rpm x 1e4)."""
    from orchestrator.results.plots import plot_run
    from orchestrator.results.whirl import analyze_journal
    t = np.arange(4000) * 2e-4
    x, y = 1e-6 * np.cos(2 * np.pi * 300 * t), 1e-6 * np.sin(2 * np.pi * 300 * t)
    run = tmp_path / "run"
    run.mkdir()
    (run / "results.csv").write_text("time,r.x_1,r.y_1,r.omega\n" + "".join(
        f"{a!r},{b!r},{c!r},{speed!r}\n" for a, b, c in zip(t.tolist(), x.tolist(), y.tolist())))
    (run / "summary.json").write_text(json.dumps({"scenario": "s", "status": "finished", "analysis": {
        "spec": {"speed": "r.omega", "journals": {"b1": {"x": "r.x_1", "y": "r.y_1", "clearance": 1.372e-5}}}}}))
    with warnings.catch_warnings(record=True) as rec:
        warnings.simplefilter("always")
        written = [p.name for p in plot_run(run)]
    assert "waterfall_b1.png" not in written and "orbit_b1.png" in written, written
    said = [str(w.message) for w in rec if "waterfall of 'b1'" in str(w.message)]
    assert len(said) == 1 and "is the speed in rad/s?" in said[0] and "angle bins" in said[0], said
    res = analyze_journal(t, x, y, np.full(t.size, speed), 1.372e-5)
    assert res["whirl"] is False and any("is the speed in rad/s?" in w for w in res["warnings"]), res["warnings"]
