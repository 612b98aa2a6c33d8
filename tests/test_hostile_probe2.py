"""Second hostile-input probe (after tests/test_hostile_small.py and the other catalogues):
one test per finding, each failing on the code before its fix."""

from __future__ import annotations

import logging

import numpy as np

from orchestrator.results import writer as results_writer
from orchestrator.results.run_directory import read_results
from orchestrator.results.writer import ResultsWriter, read_back


def test_string_values_with_line_breaks_or_megabytes_stay_one_readable_line(tmp_path, caplog):
    """An FMU's String output with a line break made results.csv rows span several lines (which
    `rotorcosim plot` then refused as a damaged file), and one of 3 MB made the run end in
    "internal error: field larger than field limit" when it read its rows back (summary.json
    left at "running"). Now each row is one line: line breaks written as \\n, values cut at
    MAX_STRING_CHARS, one warning per column each."""
    path = tmp_path / "results.csv"
    w = ResultsWriter(path, ["a.y", "a.s", "a.t"], ["Real", "String", "String"])
    w.open()
    big = "A" * 3_000_000
    with caplog.at_level(logging.WARNING, logger="orchestrator.results.writer"):
        for k in range(3):
            w.write(0.001 * k, [float(k), 'line1\nline2,"q"\r\n', big])
    w.close()
    text = path.read_text()
    assert text.count("\n") == 4                       # header + 3 rows, one line each
    assert max(len(line) for line in text.splitlines()) < 2 * results_writer.MAX_STRING_CHARS
    msgs = [r.getMessage() for r in caplog.records]
    assert sum("line break" in m and "'a.s'" in m for m in msgs) == 1, msgs
    assert sum("3000000 characters" in m and "'a.t'" in m for m in msgs) == 1, msgs
    data = read_results(path)                          # the reader of plot/compare reads it
    assert np.allclose(data["a.y"], [0, 1, 2])
    t, out = read_back(path, ["a.y", "a.s", "a.t"], ["Real", "String", "String"])
    assert out["a.s"][0] == 'line1\\nline2,"q"\\r\\n'
    assert out["a.t"][0].startswith("AAAA") and out["a.t"][0].endswith(f"...[{3_000_000 - 4096} characters cut]")
