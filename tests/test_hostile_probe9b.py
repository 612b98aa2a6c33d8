"""Leftovers of the ninth probe (tests/test_hostile_probe9.py): the bearing FMUs' physical parameters
get declared ranges as the rotor FMUs' have, results.parquet gets the row bound of results.csv, and
`stability --plot` no longer writes a PNG over a file named without a suffix. One test per finding,
each failing on the code before its fix."""

from __future__ import annotations

from pathlib import Path

import pytest

from hostile_builders import cli

REPO = Path(__file__).resolve().parents[1]
JEFFCOTT_HS = REPO / "scenarios" / "jeffcott_runup_half_sommerfeld.yaml"


def test_parquet_results_row_bound(tmp_path, monkeypatch):
    # results.csv stops at MAX_OUTPUT_ROWS + 2 rows; results.parquet was read whole, whatever its size
    pa = pytest.importorskip("pyarrow")
    import pyarrow.parquet as pq

    from orchestrator.results.run_directory import read_results_parquet
    from orchestrator.scenario import limits
    monkeypatch.setattr(limits, "MAX_OUTPUT_ROWS", 1000)
    path = tmp_path / "results.parquet"
    pq.write_table(pa.table({"time": [i * 1e-3 for i in range(1003)], "a.y": [1.0] * 1003}), path)
    with pytest.raises(ValueError) as exc:
        read_results_parquet(path)
    msg = str(exc.value)
    assert msg.startswith(f"{path}: 1003 rows, more than 1002"), msg
    assert "orchestrator.scenario.limits.MAX_OUTPUT_ROWS" in msg
    pq.write_table(pa.table({"time": [i * 1e-3 for i in range(1002)], "a.y": [1.0] * 1002}), path)
    assert len(read_results_parquet(path)["time"]) == 1002
    path.write_bytes(b"PAR1 not closed")       # the message of a killed run's file is kept
    with pytest.raises(ValueError, match="no footer"):
        read_results_parquet(path)


def test_stability_plot_without_suffix_refused(capsys, tmp_path):
    # `--plot notes` wrote a PNG over the file 'notes' (a name without a suffix was taken as PNG)
    notes = tmp_path / "notes"
    notes.write_text("my notes\n")
    with pytest.raises(SystemExit) as exc:
        cli(capsys, "stability", JEFFCOTT_HS, "--plot", notes)
    text = capsys.readouterr().err
    assert exc.value.code == 2 and "no suffix" in text and "--plot notes.png" in text, text
    assert notes.read_text() == "my notes\n"


def test_stability_plot_over_other_file_refused(capsys, tmp_path):
    # `--plot x.png` naming a file that is no PNG (and the scenario itself) is refused before the computation
    other = tmp_path / "readme.png"
    other.write_text("not a figure\n")
    rc, text = cli(capsys, "stability", JEFFCOTT_HS, "--plot", other)
    assert rc == 1 and f"{other}: exists and is not a figure" in text and "give a new name" in text, text
    assert other.read_text() == "not a figure\n"
    svg = tmp_path / "s.svg"
    svg.write_text("%PDF-1.4 not svg")
    rc, text = cli(capsys, "stability", JEFFCOTT_HS, "--plot", svg)
    assert rc == 1 and "not a .svg figure" in text, text
