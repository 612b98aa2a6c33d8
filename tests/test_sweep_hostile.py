"""Hostile sweep files and sweep folders: limits on runs, --resume records, the map's table.

Each test feeds one hostile input and checks the refusal (or the warning) names the file,
line or field, what was expected and the fix, without building anything in full first. No
test here runs a simulation: the grids are expanded, the resume records read and the maps
drawn from files written by the test.
"""

from __future__ import annotations

import itertools
from pathlib import Path

import pytest

from orchestrator.cli import main
from orchestrator.sweep import SweepError, load_sweep
from orchestrator.sweep import plan

HEAD = "sweep: 1\nscenario: s.yaml\n"


def sweep_file(tmp_path: Path, body: str, name: str = "sweep.yaml") -> Path:
    (tmp_path / "s.yaml").write_text("name: s\n")     # load_sweep only checks that it is a file
    path = tmp_path / name
    path.write_text(HEAD + body)
    return path


def linspaces(*counts: int) -> str:
    paths = ["stop_time", "coupling.macro_step", "output.interval", "start_time", "coupling.substeps",
             "coupling.call_timeout"]
    return "parameters:\n" + "".join(f"  - {{name: p{i}, set: {paths[i]}, linspace: [1, 2, {n}]}}\n"
                                     for i, n in enumerate(counts))


@pytest.fixture
def no_grid(monkeypatch):
    """Building the grid in full (itertools.product) is what these tests forbid."""
    def product(*args, **kwargs):
        raise AssertionError("the grid was built in full")
    monkeypatch.setattr(plan.itertools, "product", product)


# ------------------------------------------------------------------ 1. the number of runs
def test_a_grid_of_1e12_runs_is_refused_from_the_counts(tmp_path, no_grid):
    spec = load_sweep(sweep_file(tmp_path, linspaces(10000, 10000, 10000)))
    with pytest.raises(SweepError) as info:
        plan.expand(spec)
    text = str(info.value)
    assert f"{spec.source}:4: the grid of the parameters p0 (10000, line 4) x p1 (10000, line 5) x " \
           "p2 (10000, line 6) makes about 10^12 runs" in text
    assert f"the limit is {plan.MAX_RUNS}, orchestrator.sweep.plan.MAX_RUNS" in text
    assert "fewer values" in text and "'mode: random' and 'samples: N'" in text


def test_a_grid_just_over_the_limit_is_refused_and_the_cli_says_so(tmp_path, capsys):
    path = sweep_file(tmp_path, linspaces(101, 100))
    with pytest.raises(SweepError, match=r":4: the grid of the parameters p0 \(101, line 4\) x p1 \(100, line 5\) "
                                         r"makes 10100 runs"):
        plan.expand(load_sweep(path))
    assert main(["sweep", str(path), "--out", str(tmp_path / "o"), "--no-progress"]) == 1
    err = capsys.readouterr().err
    assert "makes 10100 runs" in err and "internal error" not in err
    assert not (tmp_path / "o").exists()
    assert plan.count_runs(load_sweep(sweep_file(tmp_path, linspaces(100, 100), "ok.yaml"))) == plan.MAX_RUNS


def test_zip_and_random_counts_are_bounded_too(tmp_path, monkeypatch, no_grid):
    monkeypatch.setattr(plan, "MAX_RUNS", 5)               # a module constant, read when used
    spec = load_sweep(sweep_file(tmp_path, "mode: zip\n" + linspaces(6, 6)))
    with pytest.raises(SweepError, match=r"mode zip over the parameters p0 \(6, line 5\) x p1 \(6, line 6\) "
                                         r"makes 6 runs.*the limit is 5"):
        plan.expand(spec)
    spec = load_sweep(sweep_file(tmp_path, "mode: random\nsamples: 6\n" + linspaces(10, 10), "r.yaml"))
    with pytest.raises(SweepError, match=r"'samples' is 6, more runs than a sweep may have \(the limit is 5"):
        plan.expand(spec)


def test_random_samples_of_a_huge_grid_are_drawn_without_building_it(tmp_path, no_grid):
    spec = load_sweep(sweep_file(tmp_path, "mode: random\nsamples: 5\nseed: 7\n" + linspaces(10000, 10000, 10000)))
    runs = plan.expand(spec)
    assert len(runs) == 5 and len({r.run_id for r in runs}) == 5
    lists = [p.values for p in spec.parameters]
    for run in runs:
        assert all(run.values[p.name] in p.values for p in spec.parameters)
    positions = [sum(lists[k].index(run.values[f"p{k}"]) * 10000 ** (2 - k) for k in range(3)) for run in runs]
    assert positions == sorted(positions)                        # grid order, as before
    assert [r.run_id for r in plan.expand(spec)] == [r.run_id for r in runs]     # the same seed, the same runs
    # beyond int64 (10^24 combinations): Python's generator draws from the range
    big = load_sweep(sweep_file(tmp_path, "mode: random\nsamples: 3\n" + linspaces(*[10000] * 6), "big.yaml"))
    assert len(plan.expand(big)) == 3
    with pytest.raises(SweepError, match="'samples' is 3 but the grid of the parameters has only 2"):
        plan.expand(load_sweep(sweep_file(tmp_path, "mode: random\nsamples: 3\n" + linspaces(2), "few.yaml")))


def test_random_draw_of_a_small_grid_is_the_draw_of_earlier_versions(tmp_path):
    import numpy as np
    spec = load_sweep(sweep_file(tmp_path, "mode: random\nsamples: 7\nseed: 3\n" + linspaces(4, 5, 3)))
    grid = list(itertools.product(*[p.values for p in spec.parameters]))
    picks = np.random.default_rng(3).choice(len(grid), size=7, replace=False)
    expected = [grid[i] for i in sorted(int(i) for i in picks)]  # what 5c8011d ran: resume keeps working
    assert [tuple(r.values.values()) for r in plan.expand(spec)] == expected
    lists = [(1, 2, 3), ("a", "b"), (True, False, None, 0)]
    assert [plan._decode(i, lists) for i in range(24)] == list(itertools.product(*lists))


# ------------------------------------------------------------------ 2. --resume reads run folders
def _run(tmp_path: Path):
    from orchestrator.sweep.plan import RunPlan, run_id_of
    overrides = ("stop_time=0.1",)
    run = RunPlan(run_id=run_id_of(overrides), index=0, values={"a": 0.1}, overrides=overrides)
    run_dir = tmp_path / "runs" / run.run_id
    run_dir.mkdir(parents=True)
    return run, run_dir


def _finished(run_dir: Path, run, summary: str | None = None, record: str | None = None) -> None:
    import json
    (run_dir / "summary.json").write_text(summary if summary is not None else
                                          json.dumps({"status": "finished", "end_time": 0.1}))
    (run_dir / "sweep_run.json").write_text(record if record is not None else json.dumps(
        {"status": "finished", "message": "", "wall_time_s": 1.0, "overrides": list(run.overrides)}))


DEEP = "[" * 100000 + "]" * 100000


@pytest.mark.parametrize("case, why", [
    ("record_devzero", "sweep_run.json is a character device, expected a regular file"),
    ("record_deep", "sweep_run.json is nested too deeply to read"),
    ("record_list", "sweep_run.json: expected a JSON object, got list"),
    ("record_overrides_text", "sweep_run.json: 'overrides' is not a list of texts"),
    ("record_wall_text", "sweep_run.json: 'wall_time_s' is not a number"),
    ("record_not_utf8", "sweep_run.json is not UTF-8 text"),
    ("summary_deep", "summary.json is nested too deeply to read"),
    ("summary_nested_100", "summary.json: nested more than 64 levels deep"),
    ("summary_dir", "summary.json is a directory, expected a regular file"),
    ("summary_too_large", "summary.json is larger than 1000 bytes (the limit)"),
    ("summary_fifo", "summary.json is a named pipe (FIFO), expected a regular file"),
])
def test_resume_redoes_a_run_whose_files_are_unreadable_with_a_warning(tmp_path, monkeypatch, case, why):
    import os

    from orchestrator.sweep.runner import resumable
    run, run_dir = _run(tmp_path)
    _finished(run_dir, run)
    record, summary = run_dir / "sweep_run.json", run_dir / "summary.json"
    if case == "record_devzero":
        record.unlink()
        record.symlink_to("/dev/zero")
    elif case == "record_deep":
        record.write_text(DEEP)
    elif case == "record_list":
        record.write_text("[1, 2]")
    elif case == "record_overrides_text":
        record.write_text('{"status": "finished", "overrides": "stop_time=0.1"}')
    elif case == "record_wall_text":
        record.write_text('{"status": "finished", "wall_time_s": "fast", "overrides": ["stop_time=0.1"]}')
    elif case == "record_not_utf8":
        record.write_bytes(b"\xff\xfe{}")
    elif case == "summary_deep":
        summary.write_text('{"status": "finished", "end_time": ' + DEEP + "}")
    elif case == "summary_nested_100":
        summary.write_text('{"status": "finished", "end_time": ' + "[" * 100 + "]" * 100 + "}")
    elif case == "summary_dir":
        summary.unlink()
        summary.mkdir()
    elif case == "summary_too_large":
        monkeypatch.setattr("orchestrator.untrusted.MAX_TEXT_BYTES", 1000)
        summary.write_text('{"status": "finished", "x": "' + "y" * 2000 + '"}')
    elif case == "summary_fifo":
        summary.unlink()
        os.mkfifo(summary)
    with pytest.warns(UserWarning) as caught:
        assert resumable(run_dir, run) is None
    text = " ".join(str(w.message) for w in caught)
    assert f"--resume: {run_dir}/" in text and why in text and "running that run again" in text


def test_resume_keeps_a_good_run_and_silently_redoes_unfinished_ones(tmp_path, recwarn):
    import json

    from orchestrator.sweep.runner import _recorded, resumable
    run, run_dir = _run(tmp_path)
    _finished(run_dir, run)
    rec = resumable(run_dir, run)
    assert rec["status"] == "finished" and rec["summary"]["end_time"] == 0.1 and rec["wall_time_s"] == 1.0
    assert _recorded(run_dir, run)["summary"] == {"status": "finished", "end_time": 0.1}
    (run_dir / "summary.json").write_text(json.dumps({"status": "failed"}))
    assert resumable(run_dir, run) is None                    # not finished: no warning needed
    (run_dir / "sweep_run.json").write_text(DEEP)             # after Ctrl-C: unreadable record, no record
    assert _recorded(run_dir, run) is None
    assert not recwarn.list


def test_a_run_clears_a_directory_or_symlink_left_where_its_summary_goes(tmp_path):
    from orchestrator.sweep.task import _clear_stale
    (tmp_path / "summary.json").mkdir()
    (tmp_path / "summary.json" / "x").write_text("x")
    target = tmp_path / "keep.txt"
    target.write_text("keep")
    (tmp_path / "sweep_run.json").symlink_to(target)
    _clear_stale(tmp_path)
    assert not (tmp_path / "summary.json").exists() and not (tmp_path / "sweep_run.json").is_symlink()
    assert target.read_text() == "keep"


# ------------------------------------------------------------------ 3. rotorcosim plot SWEEP_FOLDER
META = {"sweep": 1, "source": "s.yaml", "scenario": "base.yaml", "mode": "grid",
        "parameters": [{"name": "a", "set": ["fmus.rotor.parameters.f_max"]},
                       {"name": "b", "set": ["fmus.rotor.parameters.t_ramp"]}],
        "collect": {"steps": "macro_steps", "endt": "end_time"}}
HEADER = "run_id,a,b,steps,endt,status,message,wall_time_s,run_dir\n"
ROWS = ["r1,700,1,20,0.502,finished,,1.275,runs/r1\n", "r2,700,2,20,0.502,finished,,0.294,runs/r2\n",
        "r3,800,1,20,0.502,failed,\"FMU 'f' failed, at t=0.05\",0.386,runs/r3\n",
        "r4,800,2,,,cancelled,not run,,runs/r4\n"]


def sweep_folder(tmp_path: Path, csv_text: str | bytes | None = None, meta=None) -> Path:
    import json
    d = tmp_path / "sw"
    d.mkdir(exist_ok=True)
    data = HEADER + "".join(ROWS) if csv_text is None else csv_text
    for name in ("sweep.csv", "sweep.json"):
        (d / name).unlink(missing_ok=True)
    (d / "sweep.csv").write_bytes(data if isinstance(data, bytes) else data.encode())
    (d / "sweep.json").write_text(meta if isinstance(meta, str) else json.dumps(META if meta is None else meta))
    return d


def plot_fails(d: Path, capsys) -> str:
    assert main(["plot", str(d)]) == 1
    err = capsys.readouterr().err
    assert err.startswith("error: ") and "internal error" not in err and "Traceback" not in err, err
    return err


def test_plot_of_a_good_sweep_folder(tmp_path, capsys, recwarn):
    d = sweep_folder(tmp_path)
    assert main(["plot", str(d)]) == 0
    assert (d / "plots" / "sweep_steps.png").is_file() and (d / "plots" / "sweep_endt.png").is_file()
    assert not [w for w in recwarn.list if "sweep.csv" in str(w.message)]


@pytest.mark.parametrize("csv_text, needle", [
    (HEADER + ROWS[0] + ROWS[1].replace(",1.275,", ",fast,").replace(",0.294,", ",fast,"),
     "sweep.csv:3: column 'wall_time_s' must be a number"),
    (HEADER + ROWS[0].rstrip() + ",x,y\n", "sweep.csv:2: 11 fields, but the header names 9 columns"),
    (HEADER + ROWS[0] + "r2,700\n", "sweep.csv:3: 2 fields, but the header names 9 columns"),
    (bytes(range(256)) * 4, "sweep.csv:2:118: the sweep table is not UTF-8 text (byte 0x80"),
    (HEADER + ROWS[0].replace("runs/r1", "runs/" + "9" * 200_000), "sweep.csv:2: not a readable CSV row "
                                                                     "(field larger than field limit"),
    ("", "sweep.csv:1: empty; expected the header run_id,a,b,steps,endt,status,..."),
    (HEADER.replace(",b,", ",c,") + ROWS[0], "sweep.csv:1: no column 'b' (a parameter in sweep.json); sweep.csv and "
                                             "sweep.json are not from the same sweep"),
    (HEADER.replace("steps,endt", "steps,steps") + ROWS[0], "sweep.csv:1: the column 'steps' appears twice"),
    (HEADER + ROWS[0].replace(",700,", ",,"), "sweep.csv:2: parameter 'a' has no value"),
    (HEADER + "".join(ROWS) + ROWS[1], "sweep.csv:6: a second row for the run a=700, b=2 (first on line 3); a sweep "
                                       "has one row per run: remove the repeated row"),
])
def test_plot_refuses_a_broken_sweep_csv_naming_its_line(tmp_path, capsys, csv_text, needle):
    err = plot_fails(sweep_folder(tmp_path, csv_text), capsys)
    assert needle in err, err
    assert not (tmp_path / "sw" / "plots").exists()


@pytest.mark.parametrize("meta, needle", [
    ("[1]", "sweep.json: expected a JSON object with 'parameters' and 'collect' (got a list)"),
    (DEEP, "sweep.json: the sweep.json is nested too deeply to read; rerun the sweep"),
    ('{"sweep": 1,', "sweep.json: the sweep.json is not valid JSON"),
    ({**META, "collect": ["x"]}, "'collect' must be an object {column: summary.json path} (got a list)"),
    ({**META, "collect": {"nope": "x"}}, "sweep.csv:1: no column 'nope' (a collected value in sweep.json)"),
    ({**META, "collect": {"../../evil": "x"}}, "'collect' must map column names (letters, digits, '_')"),
    ({**META, "parameters": "abc"}, "'parameters' must be a non-empty list of {\"name\": ...} objects (got 'abc', "
                                    "a text)"),
    ({**META, "parameters": [{"name": 5}]}, "'parameters[0]' must be an object whose 'name' is a sweep.csv column "
                                            "name (letters, digits, '_') (got 5, an integer)"),
    ({**META, "parameters": [{"name": "zz", "set": ["x"]}]}, "sweep.csv:1: no column 'zz' (a parameter in "
                                                              "sweep.json)"),
    ({**META, "collect": {"a": "x"}}, "the column 'a' is named twice"),
])
def test_plot_refuses_a_broken_sweep_json(tmp_path, capsys, meta, needle):
    err = plot_fails(sweep_folder(tmp_path, meta=meta), capsys)
    assert needle in err, err
    assert not list(tmp_path.rglob("evil*"))


def test_plot_without_sweep_json_or_over_the_limits(tmp_path, capsys, monkeypatch):
    d = sweep_folder(tmp_path)
    (d / "sweep.json").unlink()
    assert "sweep.json: not found; `rotorcosim sweep` writes it next to sweep.csv" in plot_fails(d, capsys)
    (d / "sweep.json").symlink_to("/dev/zero")
    assert "sweep.json: the sweep.json is a character device" in plot_fails(d, capsys)
    d = sweep_folder(tmp_path, HEADER + "".join(f"r{k},{k},{k},1,1,finished,,1,runs/x\n" for k in range(10)))
    monkeypatch.setattr(plan, "MAX_RUNS", 5)
    assert ("sweep.csv:7: more than 5 rows, more than a sweep has runs (the limit, "
            "orchestrator.sweep.plan.MAX_RUNS)") in plot_fails(d, capsys)
    monkeypatch.setattr("orchestrator.sweep.table.MAX_TABLE_BYTES", 300)
    assert "sweep.csv: the sweep table is larger than 300 bytes (the limit)" in plot_fails(d, capsys)


def test_plot_warns_with_the_line_for_odd_values_it_can_draw(tmp_path, capsys):
    text = (HEADER + ROWS[0].replace(",700,", ",seven,") + ROWS[1].replace(",20,", ",nan,")
            + ROWS[2].replace(",failed,", ",<script>,") + ROWS[3])
    d = sweep_folder(tmp_path, text)
    with pytest.warns(UserWarning) as caught:
        assert main(["plot", str(d)]) == 0
    texts = [str(w.message) for w in caught]
    assert any(f"{d}/sweep.csv:2: parameter 'a' is 'seven', a text, where other rows have numbers" in t for t in texts)
    assert any(f"{d}/sweep.csv:3: column 'steps' holds 1 non-finite value(s) (nan or inf)" in t for t in texts)
    assert any(f"{d}/sweep.csv:4: status '<script>' is none of finished, failed, crashed, cancelled" in t
               for t in texts)


def _png_size(path: Path) -> tuple[int, int]:
    data = path.read_bytes()[16:24]
    return int.from_bytes(data[:4], "big"), int.from_bytes(data[4:], "big")


def test_large_maps_are_drawn_at_a_bounded_size(tmp_path):
    from orchestrator.sweep.plot import plot_sweep
    grid = "".join(f"r{i}_{j},{i},{j},{i * j},1,{'failed' if (i + j) % 7 == 0 else 'finished'},,1,runs/x\n"
                   for i in range(40) for j in range(40))
    d = sweep_folder(tmp_path, HEADER + grid)
    width, height = _png_size(plot_sweep(d)[0])
    assert width <= 1200 and height <= 1000                      # not 1.15 inch per column
    diag = "".join(f"r{k},{k},{k},{k},1,finished,,1,runs/x\n" for k in range(600))   # 360 000 cells, 600 runs
    (d / "sweep.csv").write_text(HEADER + diag)
    width, height = _png_size(plot_sweep(d)[0])
    assert width <= 1200 and height <= 1000


def test_a_one_parameter_map_of_numbers_and_texts_places_each_value(tmp_path):
    from orchestrator.sweep.plot import plot_sweep
    d = sweep_folder(tmp_path, "run_id,a,v,status,message,wall_time_s,run_dir\n" + "".join(
        f"r{k},{a},{k},{st},,1,runs/x\n" for k, (a, st) in enumerate([("1", "finished"), ("seven", "finished"),
                                                                      ("3", "failed"), ("True", "finished")])),
        meta={"parameters": [{"name": "a"}], "collect": {"v": "x"}})
    with pytest.warns(UserWarning, match=r"sweep.csv:3: parameter 'a' is 'seven'"):
        assert [p.name for p in plot_sweep(d)] == ["sweep_v.png"]


def test_the_cli_says_it_validates_many_runs_before_the_first_starts(tmp_path, monkeypatch, capsys):
    monkeypatch.setattr(plan, "PROGRESS_FROM_RUNS", 3)       # 200 in use; each run is validated
    path = sweep_file(tmp_path, linspaces(3))
    assert main(["sweep", str(path), "--out", str(tmp_path / "o"), "--no-progress"]) == 1    # s.yaml is no scenario
    err = capsys.readouterr().err
    assert f"sweep {path}: validating the scenario of each of its 3 runs before the first starts" in err
    assert "invalid sweep" in err and "internal error" not in err


def test_a_planted_run_log_symlink_is_removed_and_a_long_log_read_from_its_end(tmp_path):
    from orchestrator.sweep.task import _clear_stale, _log_tail
    target = tmp_path / "victim.txt"
    target.write_text("keep")
    (tmp_path / "run.log").symlink_to(target)
    _clear_stale(tmp_path)
    assert not (tmp_path / "run.log").is_symlink() and target.read_text() == "keep"
    (tmp_path / "run.log").write_text("x" * 5_000_000 + "\nthe end: FMU 'f' failed\n")
    tail = _log_tail(tmp_path / "run.log")
    assert tail.endswith("the end: FMU 'f' failed\n") and len(tail) == 2400
    assert _log_tail(tmp_path / "missing.log") == ""


# ------------------------------------------------------------------ 4. the inputs --resume compares
def test_run_inputs_of_an_ssp_archive_name_the_archive_not_its_extraction(tmp_path, test_fmus):
    """The loader records the files it reads (orchestrator.read_log) for --resume. An .ssp archive is
    extracted into a new temporary folder at every load: recording the extracted .ssd and FMUs by
    path would make every run look changed on every resume. The archive is the input; the folder
    made while loading is not, and two loads record the same files with the same digests."""
    import orchestrator
    from tests.test_hostile_probe6 import _ssp
    comps = ('<ssd:Elements><ssd:Component name="b" source="resources/Integrator.fmu"/></ssd:Elements>')
    ssp = _ssp(tmp_path / "s.ssp", comps, {"resources/Integrator.fmu": test_fmus["Integrator"]})
    (tmp_path / "s.yaml").write_text("ssp: s.ssp\nname: s\nstop_time: 0.1\n")
    first, second = (orchestrator.load_scenario(tmp_path / "s.yaml") for _ in range(2))
    assert first.inputs == second.inputs == (str((tmp_path / "s.yaml").resolve()), str(ssp.resolve()))
    cache: dict = {}
    a, b = plan.run_inputs(tmp_path / "s.yaml", first, cache), plan.run_inputs(tmp_path / "s.yaml", second, cache)
    assert a == b and list(a["files"]) == [str(ssp.resolve())] and a["fmus"]["b"] != "unreadable"


def test_fingerprint_reads_no_fifo_and_stops_at_its_size_limit(tmp_path, monkeypatch):
    """A recorded input replaced by a FIFO before the digest is taken must not block the sweep; a
    file above read_log.MAX_DIGEST_BYTES is fingerprinted by size and time, not read."""
    import os

    from orchestrator import read_log
    fifo = tmp_path / "p.ssv"
    os.mkfifo(fifo)
    with pytest.raises(OSError, match="not a regular file"):
        read_log.fingerprint(fifo)
    big = tmp_path / "big.bin"
    big.write_bytes(b"x" * 2000)
    monkeypatch.setattr(read_log, "MAX_DIGEST_BYTES", 1000)
    assert read_log.fingerprint(big) == f"size:2000 mtime_ns:{os.stat(big).st_mtime_ns}"
    monkeypatch.setattr(read_log, "MAX_DIGEST_BYTES", 4000)
    assert len(read_log.fingerprint(big)) == 64
