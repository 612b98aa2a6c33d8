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

from tests import test_sweep

SWEEP = test_sweep.SWEEP          # the ramp scenario's sweep (its run at t_fail 0.05 fails)
sdir = test_sweep.sdir            # fixture: the ramp scenario and its FMUs in tmp_path


@pytest.mark.filterwarnings("ignore:collect")
@pytest.mark.parametrize("warm", [True, False], ids=["warm", "fresh-processes"])
def test_interrupted_row_says_what_the_run_summary_says_after_the_run_stopped(sdir, warm):
    """Ctrl-C while a run is in progress: closing the local cluster stops that run, which then
    writes its final summary (failed, stopped_by SIGTERM). The row's message was composed
    before the cluster was closed and said "its summary.json still says running" while the
    summary.json beside it said failed; now the folder is read after the run stopped. With
    --fresh-processes the run was not stopped at all (its worker thread outlives the closed
    cluster): the row said "still says running" and the run went on, here to 'finished'."""
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
    outcome = runner.run_sweep(spec, runs, sdir / "o", workers=1, warm=warm, progress=False)
    assert outcome.interrupted
    row = outcome.rows[0]
    assert row["status"] == "cancelled"
    final = json.loads(summary.read_text())
    assert final["status"] != "running", final     # the run was stopped and said so
    assert "still says running" not in row["message"], (row["message"], final)
    assert "SIGTERM" in final["message"] and "SIGTERM" in row["message"], (row["message"], final)
    assert "--resume" in row["message"]


REPO = Path(__file__).resolve().parents[1]
JEFFCOTT_SWEEP = """sweep: 1
scenario: {scenario}
parameters:
  - {{name: psi, set: [fmus.bearing1.parameters.psi, fmus.bearing2.parameters.psi], values: [2.8e-3]}}
  - {{name: eta0, set: [fmus.bearing1.parameters.eta0, fmus.bearing2.parameters.eta0], values: [0.008, 0.016]}}
  - {{name: tau, set: [coupling.macro_step], values: [1.0e-4]}}
collect:
  onset_hz: analysis.journals.bearing1.onset_speed_hz
  max_eps: analysis.journals.bearing1.max_eps
  steps: macro_steps
  x_end: output.final.rotor.x_1
"""


def test_sweep_units_come_from_the_fmus_and_the_summary_paths(tmp_path):
    """The maps' axes were the bare column names (psi, eta0, onset_hz): no unit anywhere, though
    the FMU's modelDescription has them. sweep_units finds them: FMU parameters from the
    modelDescription, the scenario's times in s, summary paths by their meaning; none where none
    is known (macro_steps, a count)."""
    from orchestrator.sweep import load_sweep
    from orchestrator.sweep.plan import expand
    from orchestrator.sweep.units import sweep_units
    (tmp_path / "sw.yaml").write_text(JEFFCOTT_SWEEP.format(scenario=REPO / "scenarios" / "quickstart.yaml"))
    spec = load_sweep(tmp_path / "sw.yaml")
    params, collect = sweep_units(spec, expand(spec)[0].overrides)
    assert params == {"psi": "1", "eta0": "Pa.s", "tau": "s"}
    assert collect == {"onset_hz": "Hz", "max_eps": "1", "x_end": "m"}


def _captured_figures(monkeypatch):
    from orchestrator.sweep import plot
    figs = {}
    monkeypatch.setattr(plot, "save_figure", lambda fig, path: figs.__setitem__(Path(path).name, fig))
    return figs


def _sweep_folder(tmp_path, rows: str, units: bool) -> Path:
    out = tmp_path / "o"
    out.mkdir()
    meta = {"sweep": 1, "scenario": "/x/jeffcott.yaml", "mode": "grid",
            "parameters": [{"name": "psi", "set": ["fmus.b.parameters.psi"]},
                           {"name": "eta0", "set": ["fmus.b.parameters.eta0"]}],
            "collect": {"onset_hz": "analysis.journals.b.onset_speed_hz"}}
    if units:
        meta["parameters"][0]["unit"] = "1"
        meta["parameters"][1]["unit"] = "Pa.s"
        meta["collect_units"] = {"onset_hz": "Hz"}
    (out / "sweep.json").write_text(json.dumps(meta))
    (out / "sweep.csv").write_text("run_id,psi,eta0,onset_hz,status,message,wall_time_s,run_dir\n" + rows)
    return out


ROWS = ("a1,0.0024,0.008,{v1},finished,,1.0,runs/a1\na2,0.0024,0.016,{v2},finished,,1.0,runs/a2\n"
        "a3,0.0032,0.008,{v3},finished,,1.0,runs/a3\na4,0.0032,0.016,,failed,x,1.0,runs/a4\n")


def test_map_axes_carry_units_and_the_scenario(tmp_path, monkeypatch):
    from orchestrator.sweep.plot import plot_sweep
    figs = _captured_figures(monkeypatch)
    plot_sweep(_sweep_folder(tmp_path, ROWS.format(v1=300.0, v2=290.0, v3=310.0), units=True))
    fig = figs["sweep_onset_hz.png"]
    ax, bar = fig.axes                                   # the map and its colour bar
    assert ax.get_xlabel() == "psi [-]" and ax.get_ylabel() == "eta0 [Pa s]"
    assert bar.get_ylabel() == "onset_hz [Hz]"
    assert ax.get_title() == "onset_hz over psi and eta0 (jeffcott)"


def test_map_of_a_sweep_folder_without_units_keeps_the_names(tmp_path, monkeypatch):
    """A sweep.json written before units were recorded (or with a unit that is no short text)."""
    from orchestrator.sweep.plot import plot_sweep
    out = _sweep_folder(tmp_path, ROWS.format(v1=300.0, v2=290.0, v3=310.0), units=False)
    meta = json.loads((out / "sweep.json").read_text())
    meta["collect_units"] = {"onset_hz": "x" * 500}
    (out / "sweep.json").write_text(json.dumps(meta))
    figs = _captured_figures(monkeypatch)
    plot_sweep(out)
    ax, bar = figs["sweep_onset_hz.png"].axes
    assert (ax.get_xlabel(), ax.get_ylabel(), bar.get_ylabel()) == ("psi", "eta0", "onset_hz")


def test_map_without_any_value_has_no_made_up_colour_bar(tmp_path, monkeypatch):
    """Every run finished without an onset (the whirl not reached by stop_time): the map had a
    colour bar from -0.1 to 0.1 (matplotlib's default for no data), as if there were values.
    Now no colour bar, and the title says no run computed a value."""
    from orchestrator.sweep.plot import plot_sweep
    figs = _captured_figures(monkeypatch)
    plot_sweep(_sweep_folder(tmp_path, ROWS.format(v1="", v2="", v3=""), units=True))
    axes = figs["sweep_onset_hz.png"].axes
    assert len(axes) == 1
    assert "no run computed a value" in axes[0].get_title()


def test_map_draws_dollar_signs_in_units_scenario_and_values_as_written(tmp_path, monkeypatch):
    """sweep.json and sweep.csv come from anyone (a unit from a third-party FMU's modelDescription,
    the scenario's file name, a text parameter value): with two '$' matplotlib parsed the text as
    mathtext, and one it cannot parse ('$\\foo$', 'cost_$a_$') made drawing the map raise."""
    from orchestrator.sweep import plot
    drawn = {}

    def draw(fig, path):
        fig.canvas.draw()                                # where mathtext was parsed
        drawn[Path(path).name] = fig
    monkeypatch.setattr(plot, "save_figure", draw)
    out = _sweep_folder(tmp_path, ROWS.format(v1=300.0, v2=290.0, v3=310.0), units=True)
    meta = json.loads((out / "sweep.json").read_text())
    meta["scenario"] = "/x/cost_$a_$.yaml"
    meta["parameters"][1]["unit"] = "$\\foo$"
    (out / "sweep.json").write_text(json.dumps(meta))
    plot.plot_sweep(out)
    ax = drawn["sweep_onset_hz.png"].axes[0]
    assert ax.get_ylabel() == "eta0 [$\\foo$]" and ax.get_title().endswith("(cost_$a_$)")
    (out / "sweep.csv").write_text("run_id,psi,eta0,onset_hz,status,message,wall_time_s,run_dir\n"
                                   "a1,$\\foo$,0.008,1.0,finished,,1.0,runs/a1\n"
                                   "a2,$b_$,0.008,2.0,finished,,1.0,runs/a2\n")
    plot.plot_sweep(out)
    labels = [t.get_text() for t in drawn["sweep_onset_hz.png"].axes[0].get_xticklabels()]
    assert sorted(labels) == ["$\\foo$", "$b_$"]


@pytest.mark.filterwarnings("ignore:collect")
def test_sweep_dataframe_column_without_any_value_is_float_nan(sdir):
    """An onset column no run had a value in (the whirl not reached by stop_time) came back from
    sweep() as an object column of None, so df.pivot(...) held None and arithmetic or a
    comparison on it raised; it is now float NaN, as a column with some values already was."""
    pd = pytest.importorskip("pandas")
    from orchestrator.sweep import sweep
    (sdir / "sweep.yaml").write_text(
        "sweep: 1\nscenario: ramp.yaml\nparameters:\n"
        "  - {name: t_fail, set: [fmus.f.parameters.t_fail], values: [1.0e6]}\n"
        "collect: {onset_hz: analysis.journals.bearing1.onset_speed_hz, steps: macro_steps}\n")
    df = sweep(sdir / "sweep.yaml", out_dir=sdir / "o", workers=1)
    assert list(df["status"]) == ["finished"]
    assert df["onset_hz"].dtype == float and df["onset_hz"].isna().all()
    assert (df["onset_hz"] > 300.0).sum() == 0
    assert pd.api.types.is_numeric_dtype(df["steps"]) and df["steps"].iloc[0] == 10


MISBEHAVING = """name: misbehaving
stop_time: 0.01
fmus:
  bearing1: {path: MisbehavingBearing.fmu, parameters: {fault: 2, fault_step: 5}}
  bearing2: {path: LinearBearing.fmu}
connections:
  - {from: bearing1.Fx, to: bearing2.x, gain: 1.0e-9}
  - {from: bearing2.Fx, to: bearing1.x, gain: 1.0e-9, offset: 1.0e-6}
coupling: {scheme: jacobi, macro_step: 1.0e-3, isolation: none}
output: {interval: 1.0e-3, signals: [bearing1.Fx, bearing2.Fx]}
"""


@pytest.mark.integration
@pytest.mark.skipif(shutil.which("gcc") is None, reason="gcc not installed (native test FMU)")
def test_fmu_crash_in_a_sweep_names_the_signal_and_the_isolation_that_keeps_the_rows(tmp_path):
    """A sweep over isolation with an FMU that segfaults at its 5th step: the run with the FMU in
    its own process is 'crashed' (no summary, no rows) and said only "killed by signal 11";
    the row now names the signal (SIGSEGV) and the setting that turns the crash into a failed
    run with its rows kept - which the isolated run of the same sweep shows."""
    from tests.fmus_c.build_c_fmu import build_c_fmu

    from orchestrator.sweep import prepare
    from orchestrator.sweep.runner import run_sweep
    build_c_fmu(tmp_path, "LinearBearing")
    build_c_fmu(tmp_path, "MisbehavingBearing")
    (tmp_path / "mis.yaml").write_text(MISBEHAVING)
    (tmp_path / "sw.yaml").write_text(
        "sweep: 1\nscenario: mis.yaml\nparameters:\n"
        "  - {name: isolation, set: coupling.isolation, values: [none, process]}\n"
        "collect: {steps: macro_steps}\n")
    spec, runs = prepare(tmp_path / "sw.yaml")
    rows = run_sweep(spec, runs, tmp_path / "o", workers=1, progress=False).rows
    crashed, isolated = rows
    assert crashed["status"] == "crashed", crashed
    assert "killed by signal 11 (SIGSEGV), in 'bearing1' in fmi2DoStep" in crashed["message"]
    assert "fmus.bearing1.isolation: process" in crashed["message"]
    assert isolated["status"] == "failed" and isolated["steps"] == 4, isolated
    assert "SIGSEGV" in isolated["message"] and "rows up to t=0.004 s are kept" in isolated["message"]


def test_sweep_off_a_terminal_prints_a_line_per_run(sdir):
    """`rotorcosim sweep ... 2> log` (a batch job, nohup): the tqdm bar is off when stderr is no
    terminal, and a sweep of hours said nothing until its end. Now a line per run done, with the
    count of runs that did not finish; --no-progress still silences it."""
    import subprocess
    import sys
    (sdir / "sweep.yaml").write_text(SWEEP)
    cmd = [sys.executable, "-m", "orchestrator", "sweep", str(sdir / "sweep.yaml"), "--workers", "1"]
    proc = subprocess.run(cmd + ["--out", str(sdir / "o")], capture_output=True, text=True, timeout=600)
    assert proc.returncode == 1, proc.stderr                  # the t_fail = 0.05 run fails
    lines = [ln for ln in proc.stderr.splitlines() if ln.startswith("sweep: ") and "runs done" in ln]
    assert [ln.split(" runs done")[0] for ln in lines] == ["sweep: 1/3", "sweep: 2/3", "sweep: 3/3"], proc.stderr
    assert lines[0].endswith("(1 not finished)") and "to go" in lines[0] and "to go" not in lines[-1]
    # the table's line is followed by what draws it (a sweep said nothing of `rotorcosim plot`)
    assert f"maps: `rotorcosim plot {sdir / 'o'}` draws each collected value" in proc.stdout, proc.stdout
    proc = subprocess.run(cmd + ["--out", str(sdir / "o2"), "--no-progress"], capture_output=True, text=True,
                          timeout=600)
    assert proc.returncode == 1 and "runs done" not in proc.stderr, proc.stderr



def test_progress_lines_off_a_terminal_are_bounded_on_a_large_sweep(monkeypatch, capsys):
    """A sweep of 10 000 runs off a terminal wrote 10 000 progress lines into its log; now a line
    each 1 % of the runs (and the last), or once a minute when runs are slow; a small sweep keeps
    its line per run."""
    from orchestrator.sweep import progress
    clock = [0.0]
    monkeypatch.setattr(progress.time, "monotonic", lambda: clock[0])

    def lines(total: int, seconds_per_run: float) -> list[str]:
        bar = progress._Lines(total)
        for _ in range(total):
            clock[0] += seconds_per_run
            bar.update(1)
        return [ln for ln in capsys.readouterr().err.splitlines() if "runs done" in ln]

    fast = lines(10_000, 0.01)
    assert len(fast) == 100 and fast[0].startswith("sweep: 100/10000 runs done")
    assert fast[-1].startswith("sweep: 10000/10000 runs done") and "to go" not in fast[-1]
    slow = lines(1000, 30.0)                              # 10 runs are 5 min: a line a minute
    assert slow[0].startswith("sweep: 2/1000 runs done after 60 s") and len(slow) == 500
    assert [ln.split(" runs done")[0] for ln in lines(3, 0.01)] == ["sweep: 1/3", "sweep: 2/3", "sweep: 3/3"]


def test_workers_zero_is_refused_before_the_runs_are_validated(sdir, capsys):
    """--workers 0 was refused after every run's scenario had been validated and the sweep's
    header printed (1-2 min for a large sweep); now first, like --workers with --scheduler."""
    from orchestrator.cli import main
    (sdir / "sweep.yaml").write_text(SWEEP.replace("ramp.yaml", "missing.yaml"))
    rc = main(["sweep", str(sdir / "sweep.yaml"), "--workers", "0"])
    out, err = capsys.readouterr()
    assert rc != 0
    assert "--workers must be at least 1 (got 0)" in err and "missing.yaml" not in err, err
    assert "runs of" not in out


def test_scheduler_without_workers_is_said(capsys):
    """An external scheduler with no worker took the runs and they waited for ever without a
    word; the sweep now says where it connects and that no worker is there."""
    distributed = pytest.importorskip("distributed")
    from orchestrator.sweep.runner import connect
    cluster = distributed.LocalCluster(n_workers=0, processes=False, dashboard_address=None)
    try:
        client, owned = connect(cluster.scheduler_address, None)
        client.close()
    finally:
        cluster.close()
    assert owned is None
    err = capsys.readouterr().err
    assert f"connecting to the Dask scheduler at {cluster.scheduler_address}" in err
    assert f"has no workers; the runs wait until one connects (start them with `dask worker " \
           f"{cluster.scheduler_address} --nthreads 1`" in err


def test_sweep_help_describes_workers_and_progress_as_they_are(capsys):
    """`--workers` said "worker processes of the local cluster": they are threads of the sweep's
    process since the local cluster runs with processes=False (docs/sweeps.md section 2), each
    handing its runs to a run process; --no-progress also silences the per-run lines."""
    from orchestrator.cli import main
    with pytest.raises(SystemExit):
        main(["sweep", "--help"])
    text = " ".join(capsys.readouterr().out.split())
    assert "worker processes of the local cluster" not in text
    assert "threads of this process, each running its runs in a run process of its own" in text
    assert "no line per run done" in text
