"""results.csv / results.parquet writer: quoting, types, time from the step index, streaming."""

from __future__ import annotations

import csv
import tracemalloc

import numpy as np
import pytest

from orchestrator.results.writer import ResultsWriter, TimeGrid


def test_time_grid_prints_as_written():
    g = TimeGrid(0.0, 0.1)
    assert [repr(g.time(n)) for n in range(4)] == ["0.0", "0.1", "0.2", "0.3"]
    assert 0.1 * 3 != 0.3 and g.time(3) == 0.3          # t += h / n*h noise is gone
    g = TimeGrid(0.25, 1e-4)
    assert repr(g.time(7)) == "0.2507"
    assert g.time(123456) == pytest.approx(0.25 + 12.3456, abs=1e-12) and repr(g.time(123456)) == "12.5956"
    # the end of a shortened last step is the stop time as written
    g = TimeGrid(0.0, 0.3, t_stop=1.0, n_stop=4)
    assert g.time(3) == 0.9 and g.time(4) == 1.0
    # no short decimal form: no rounding (H = 1/3)
    g = TimeGrid(0.0, 1 / 3)
    assert g.digits is None and g.time(3) == 3 * (1 / 3)


def test_quoted_header_keeps_structured_names_in_one_column(tmp_path):
    cols = ["m[1,2]", "a.b", 'q"x']
    w = ResultsWriter(tmp_path / "results.csv", cols)
    w.open()
    w.write(0.0, [1.0, 2.0, 3.0])
    w.write(0.5, [4.0, 5.0, 6.0])
    w.close()
    rows = list(csv.reader(open(tmp_path / "results.csv")))
    assert rows[0] == ["time", *cols]
    assert all(len(r) == 4 for r in rows)
    assert rows[2] == ["0.5", "4.0", "5.0", "6.0"]


def test_no_signals_gives_time_only(tmp_path):
    w = ResultsWriter(tmp_path / "results.csv", [])
    w.open()
    w.write(0.0, [])
    w.write(0.1, [])
    w.close()
    assert (tmp_path / "results.csv").read_text() == "time\n0.0\n0.1\n"


def test_types_are_written_as_their_type(tmp_path):
    w = ResultsWriter(tmp_path / "results.csv", ["r", "i", "b", "s", "e"], ["Real", "Integer", "Boolean", "String", "Enumeration"])
    w.open()
    w.write(0.0, [0.5, 3, True, "a,b", 2])
    w.write(1.0, [np.float64(1.5), np.int32(-4), False, "", 1])
    w.close()
    rows = list(csv.reader(open(tmp_path / "results.csv")))
    assert rows[1] == ["0.0", "0.5", "3", "1", "a,b", "2"]
    assert rows[2] == ["1.0", "1.5", "-4", "0", "", "1"]


def test_rows_reach_the_file_before_close(tmp_path):
    w = ResultsWriter(tmp_path / "results.csv", ["x"], flush_interval=0.0)
    w.open()
    w.write(0.0, [1.0])
    assert (tmp_path / "results.csv").read_text() == "time,x\n0.0,1.0\n"
    w.close()


def test_memory_is_flat_in_rows(tmp_path):
    w = ResultsWriter(tmp_path / "results.csv", [f"s{i}" for i in range(8)])
    w.open()
    row = [0.1 * i for i in range(8)]
    g = TimeGrid(0.0, 1e-4)
    for n in range(2000):
        w.write(g.time(n), row)
    tracemalloc.start()
    base = tracemalloc.get_traced_memory()[0]
    for n in range(2000, 60000):
        w.write(g.time(n), row)
    grown = tracemalloc.get_traced_memory()[0] - base
    tracemalloc.stop()
    w.close()
    assert grown < 200_000, f"writer memory grew by {grown} bytes over 58000 rows"
    assert sum(1 for _ in open(tmp_path / "results.csv")) == 60001


def test_parquet_same_columns(tmp_path):
    pq = pytest.importorskip("pyarrow.parquet")
    w = ResultsWriter(tmp_path / "results.parquet", ["m[1,2]", "i", "b", "s"], ["Real", "Integer", "Boolean", "String"],
                      format="parquet", parquet_rows=2)
    w.open()
    for n in range(5):
        w.write(0.1 * n, [n * 0.5, n, n % 2 == 0, f"s{n}"])
    w.close()
    t = pq.read_table(tmp_path / "results.parquet")
    assert t.column_names == ["time", "m[1,2]", "i", "b", "s"]
    assert t.column("i").to_pylist() == [0, 1, 2, 3, 4]
    assert t.column("b").to_pylist() == [True, False, True, False, True]
    assert t.column("s").to_pylist()[-1] == "s4"


def test_bad_arguments_are_reported(tmp_path):
    with pytest.raises(ValueError, match="output.format"):
        ResultsWriter(tmp_path / "results.csv", ["x"], format="xlsx")
    with pytest.raises(ValueError, match="'time'"):
        ResultsWriter(tmp_path / "results.csv", ["time"])
