"""Hostile run folders for ``rotorcosim plot`` and every reader of results.csv
(:func:`orchestrator.results.run_directory.read_results`): each refusal names the file and
line, what was expected, what came and the fix; nothing blocks on a FIFO, nothing is read
without bound, and NaN / backwards time is never drawn silently."""

from __future__ import annotations

import os
import threading
import warnings

import numpy as np
import pytest

from hostile_builders import cli
from orchestrator.errors import CosimError
from orchestrator.results import run_directory
from orchestrator.results.plots import plot_run
from orchestrator.results.run_directory import RunDirectory, read_results

HEADER = "time,osc.x,osc.v\n"


def rows(n=40, t0=0.0):
    return "".join(f"{t0 + i * 1e-3!r},{float(np.sin(i / 5))!r},{float(np.cos(i / 5))!r}\n" for i in range(n))


def run_folder(tmp_path, text: str | bytes, name="run"):
    run = tmp_path / name
    run.mkdir()
    data = text.encode() if isinstance(text, str) else text
    (run / "results.csv").write_bytes(data)
    return run


def refused(path, *words):
    with pytest.raises(ValueError) as exc:
        read_results(path)
    msg = str(exc.value)
    for w in words:
        assert w in msg, msg
    return msg


# --------------------------------------------------------------------------- not a regular file
@pytest.mark.skipif(not hasattr(os, "mkfifo"), reason="needs FIFOs")
def test_fifo_results_is_named_and_never_read(tmp_path):
    run = tmp_path / "run"
    run.mkdir()
    os.mkfifo(run / "results.csv")
    box = {}

    def go():
        try:
            plot_run(run)
        except CosimError as exc:
            box["msg"] = str(exc)

    th = threading.Thread(target=go, daemon=True)
    th.start()
    th.join(60)
    assert not th.is_alive(), "plot blocked on the FIFO"
    assert "named pipe (FIFO)" in box["msg"] and "not found" not in box["msg"]


def test_directory_and_device_results_are_named(tmp_path):
    run = tmp_path / "run"
    (run / "results.csv").mkdir(parents=True)
    with pytest.raises(CosimError, match="is a directory"):
        plot_run(run)
    if os.path.exists("/dev/zero"):
        run2 = tmp_path / "run2"
        run2.mkdir()
        (run2 / "results.csv").symlink_to("/dev/zero")
        with pytest.raises(CosimError, match="character device") as exc:
            plot_run(run2)
        assert "not found" not in str(exc.value)


def test_dangling_link_says_not_found(tmp_path):
    run = tmp_path / "run"
    run.mkdir()
    (run / "results.csv").symlink_to(tmp_path / "gone.csv")
    assert RunDirectory(run).has_results()
    with pytest.raises(CosimError, match="not found; check the path"):
        plot_run(run)


# --------------------------------------------------------------------------- content
def test_non_utf8_names_line_and_column(tmp_path):
    run = run_folder(tmp_path, HEADER.encode() + b"0.0,1,2\n0.001,\xe9,2\n")
    refused(run / "results.csv", "results.csv:3:7:", "not UTF-8", "0xe9", "rerun")


def test_missing_time_column(tmp_path):
    run = run_folder(tmp_path, "osc.x,osc.v\n1,2\n3,4\n")
    refused(run / "results.csv", "results.csv:1:", "no 'time' column", "'osc.x'")
    with pytest.raises(CosimError, match="no 'time' column"):     # not "nothing to plot: " with no reason
        plot_run(run)


def test_duplicate_column(tmp_path):
    run = run_folder(tmp_path, "time,osc.x,osc.x\n" + rows(3))
    refused(run / "results.csv", "results.csv:1:", "'osc.x' appears twice", "columns 2 and 3")


def test_ragged_row_names_its_line(tmp_path):
    run = run_folder(tmp_path, HEADER + rows(3) + "0.1,1\n" + rows(3, t0=0.2))
    refused(run / "results.csv", "results.csv:5:", "2 values", "header names 3 columns")


def test_text_in_a_number_column_names_line_and_column(tmp_path):
    body = rows(5).splitlines(keepends=True)
    body[3] = "0.003,hello,1.0\n"
    run = run_folder(tmp_path, HEADER + "".join(body))
    refused(run / "results.csv", "results.csv:5:", "'osc.x'", "'hello'", "expected a number")
    with pytest.raises(CosimError, match="hello"):
        plot_run(run)


def test_text_in_the_time_column(tmp_path):
    run = run_folder(tmp_path, HEADER + "0.5\x00,1,2\n")
    refused(run / "results.csv", "results.csv:2:", "column 'time'", "expected a number")


def test_a_string_signal_column_is_still_read(tmp_path):
    """A String variable is text in every row (the writer quotes it when needed): NaN, as before."""
    run = run_folder(tmp_path, 'time,osc.x,osc.label\n0,1,"a,b"\n0.001,2,ok\n')
    cols = read_results(run / "results.csv")
    assert cols["osc.x"].tolist() == [1.0, 2.0] and np.isnan(cols["osc.label"]).all()


def test_truncated_last_line_is_dropped_but_a_bad_whole_row_is_not(tmp_path):
    run = run_folder(tmp_path, HEADER + rows(4) + "0.004,0.12")          # no line break: still streaming
    assert read_results(run / "results.csv")["time"].size == 4
    run2 = run_folder(tmp_path, HEADER + rows(4) + "0.004,0.12\n", name="run2")
    refused(run2 / "results.csv", "results.csv:6:", "2 values")


def test_empty_line_between_rows(tmp_path):
    run = run_folder(tmp_path, HEADER + rows(2) + "\n" + rows(2, t0=0.1))
    refused(run / "results.csv", "results.csv:4:", "empty line between rows")
    run2 = run_folder(tmp_path, HEADER + rows(2) + "\n\n", name="run2")  # trailing empty lines are fine
    assert read_results(run2 / "results.csv")["time"].size == 2


def test_unclosed_quote(tmp_path):
    run = run_folder(tmp_path, HEADER + '"0.5,1,2\n' + rows(2, t0=1.0))
    refused(run / "results.csv", "results.csv:2:", "not valid CSV")


def test_nan_and_backwards_time(tmp_path):
    run = run_folder(tmp_path, HEADER + rows(3) + "nan,nan,nan\n")
    refused(run / "results.csv", "results.csv:5:", "time is nan", "finite")
    back = rows(6).splitlines(keepends=True)
    back[2], back[3] = back[3], back[2]
    run2 = run_folder(tmp_path, HEADER + "".join(back), name="run2")
    msg = refused(run2 / "results.csv", "results.csv:5:", "time runs backwards", "line 4")
    with pytest.raises(CosimError, match="time runs backwards"):
        plot_run(run2)
    assert "np.float64" not in msg


# --------------------------------------------------------------------------- size bounds
def test_a_long_line_is_refused_without_reading_it_whole(tmp_path, monkeypatch):
    monkeypatch.setattr(run_directory, "MAX_LINE_BYTES", 200)
    run = run_folder(tmp_path, HEADER + rows(2) + "0.5," + "1" * 5000 + ",2\n")
    refused(run / "results.csv", "results.csv:4:", "longer than 200 bytes", "MAX_LINE_BYTES")
    run2 = run_folder(tmp_path, "time," + ",".join(f"osc.c{i}" for i in range(100)) + "\n", name="run2")
    refused(run2 / "results.csv", "results.csv:1:", "longer than 200 bytes")


def test_a_line_longer_than_the_default_limit(tmp_path):
    """A line far longer than a read chunk: refused with its line, not loaded."""
    big = "0.5," + "1" * (run_directory.MAX_LINE_BYTES + 10) + ",2\n"
    run = run_folder(tmp_path, HEADER + big)
    refused(run / "results.csv", "results.csv:2:", "longer than")


def test_many_rows_across_chunks(tmp_path, monkeypatch):
    """Chunks of whole lines (a small chunk forces many): every row read once, in order."""
    monkeypatch.setattr(run_directory, "_CHUNK_BYTES", 97)
    run = run_folder(tmp_path, HEADER + rows(300))
    cols = read_results(run / "results.csv")
    assert cols["time"].size == 300 and np.allclose(np.diff(cols["time"]), 1e-3)
    assert np.allclose(cols["osc.x"], np.sin(np.arange(300) / 5))


# --------------------------------------------------------------------------- plotting
def test_rows_without_any_finite_signal_are_named_and_left_out(tmp_path):
    body = rows(40).splitlines(keepends=True)
    for i in (10, 11, 12, 30):
        t = body[i].split(",")[0]
        body[i] = f"{t},nan,inf\n"
    run = run_folder(tmp_path, HEADER + "".join(body))
    with warnings.catch_warnings(record=True) as rec:
        warnings.simplefilter("always")
        files = plot_run(run)
    msgs = [str(w.message) for w in rec]
    assert not [m for m in msgs if "invalid value" in m or "All-NaN" in m], msgs   # no numpy noise
    assert any("lines 12-14, 32 (4 of 40 rows)" in m and "NaN or infinite" in m for m in msgs), msgs
    assert files


def test_all_rows_non_finite_is_an_error(tmp_path):
    body = "".join(f"{i * 1e-3!r},inf,nan\n" for i in range(20))
    run = run_folder(tmp_path, HEADER + body)
    with pytest.warns(UserWarning), pytest.raises(CosimError, match="nothing to plot.*lines 2-21"):
        plot_run(run)


def test_signals_matching_nothing_is_an_error(tmp_path, capsys):
    run = run_folder(tmp_path, HEADER + rows(40))
    with pytest.raises(CosimError, match=r"--signals 'nope\.\*': no recorded signal matches.*osc\.x"):
        plot_run(run, signals=["nope.*", "osc.x"])
    assert not (run / "plots").exists()
    rc, out = cli(capsys, "plot", run, "--signals", "nope.*")
    assert rc == 1 and "nope.*" in out and "osc.x" in out
    rc, out = cli(capsys, "plot", run, "--signals", "osc.*")
    assert rc == 0 and "signals_osc.png" in out


def test_cli_text_in_numbers_exits_non_zero(tmp_path, capsys):
    run = run_folder(tmp_path, HEADER + "0,1,2\n0.001,hello,2\n0.002,3,4\n")
    rc, out = cli(capsys, "plot", run)
    assert rc == 1 and "results.csv:3:" in out and "'hello'" in out


def test_parquet_time_is_checked_too(tmp_path):
    pa = pytest.importorskip("pyarrow")
    import pyarrow.parquet as pq
    run = tmp_path / "run"
    run.mkdir()
    pq.write_table(pa.table({"time": [0.0, 0.2, 0.1], "osc.x": [1.0, 2.0, 3.0]}), run / "results.parquet")
    with pytest.raises(ValueError, match=r"results.parquet: row 3: time runs backwards \(0.1 after 0.2 on row 2"):
        RunDirectory(run).columns()
    pq.write_table(pa.table({"time": ["a", "b"], "osc.x": [1.0, 2.0]}), run / "results.parquet")
    with pytest.raises(ValueError, match="'time' column holds string, expected numbers"):
        RunDirectory(run).columns()


def test_a_warning_quoting_a_crafted_summary_cannot_drive_the_terminal(tmp_path):
    """The note on a run that ended without a final summary quotes summary.json's started_at; a
    crafted one holding ESC[2J cleared the terminal. Every warning the CLI prints now shows such
    characters escaped."""
    d = run_folder(tmp_path, HEADER + rows())
    (d / "summary.json").write_text('{"scenario": "x", "status": "running", "pid": 5, '
                                    '"started_at": "\\u001b[2Jboom"}')
    (d / ".rotorcosim.lock").write_text("")
    import subprocess
    import sys
    r = subprocess.run([sys.executable, "-m", "orchestrator", "plot", str(d)], capture_output=True, text=True,
                       timeout=120)    # in a process of its own: pytest records warnings instead of printing them
    rc, text = r.returncode, r.stdout + r.stderr
    assert rc == 0 and "\x1b" not in text, text
    assert "started \\x1b[2Jboom) ended without a final summary" in text, text
