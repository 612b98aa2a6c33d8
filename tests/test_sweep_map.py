"""What the stability map of a sweep shows (orchestrator/sweep/plot.py), on the sweep I ran
for a pump rotor: psi 1.0 ... 2.5 per mille, each point with its own seed (zip), half-Sommerfeld
run-ups whose journals reach the shell some time after the whirl onset (status failed, onset
and threshold in their summary).

Before: the map was a 4 x 4 heat map over psi x journal_x0 with only its diagonal filled, and the
three failed runs were hatched cells without their onsets: of four onsets one was shown.
"""

from __future__ import annotations

import json
from pathlib import Path

from orchestrator.sweep import plot as sweep_plot

META = {"sweep": 1, "source": "pump_psi_map.yaml", "scenario": "pump_hs_map.yaml", "mode": "zip",
        "parameters": [{"name": "psi", "set": ["fmus.bearing1.parameters.psi"]},
                       {"name": "journal_x0", "set": ["fmus.rotor.parameters.journal_x0"]}],
        "collect": {"onset_hz": "analysis.journals.bearing1.onset_speed_hz"}}
HEADER = "run_id,psi,journal_x0,onset_hz,status,message,wall_time_s,run_dir\n"
PUMP = [("r1", 1.0e-3, 4.266e-07, 355.46, "finished"), ("r2", 1.5e-3, 9.695e-07, 305.16, "failed"),
        ("r3", 2.0e-3, 1.9e-06, 270.11, "failed"), ("r4", 2.5e-3, 3.322e-06, 249.76, "failed")]


def _folder(tmp_path: Path, rows, meta=META, header=HEADER) -> Path:
    """A sweep folder: ``rows`` are (run id, swept values..., collected value or None, status)."""
    d = tmp_path / "sw"
    d.mkdir()
    text = header + "".join(f"{i},{','.join(map(str, vals))},{'' if v is None else v},{st},"
                            f"{'' if st == 'finished' else 'journal touches the shell'},1.0,runs/{i}\n"
                            for i, *vals, v, st in rows)
    (d / "sweep.csv").write_text(text)
    (d / "sweep.json").write_text(json.dumps(meta))
    return d


def test_a_zip_sweep_along_one_parameter_is_a_line_with_every_onset(tmp_path, figures):
    sweep_plot.plot_sweep(_folder(tmp_path, PUMP))
    (fig,) = figures
    (ax,) = [a for a in fig.axes if a.get_xlabel()]
    assert not ax.images, "a heat map over psi x journal_x0 (only its diagonal filled)"
    assert ax.get_xlabel() == "psi"
    main = next(line for line in ax.lines if line.get_label() == "onset_hz")
    assert list(main.get_xdata()) == [r[1] for r in PUMP]
    assert list(main.get_ydata()) == [r[3] for r in PUMP]         # the failed runs' onsets included
    early = next(line for line in ax.lines if line.get_label().startswith("run stopped early (failed)"))
    assert list(early.get_xdata()) == [r[1] for r in PUMP if r[4] == "failed"]
    assert not any(line.get_label().startswith("no value") for line in ax.lines)


def test_runs_without_a_value_stay_marked_as_such(tmp_path, figures):
    rows = PUMP[:3] + [("r4", 2.5e-3, 3.322e-06, None, "crashed")]
    sweep_plot.plot_sweep(_folder(tmp_path, rows))
    ax = [a for a in figures[0].axes if a.get_xlabel()][0]
    bad = next(line for line in ax.lines if line.get_label().startswith("no value"))
    assert list(bad.get_xdata()) == [2.5e-3] and "crashed" in bad.get_label()


def test_heat_map_cells_of_runs_that_stopped_early_show_their_value(tmp_path, figures):
    grid = [("r1", 1.0e-3, 1.0, 355.46, "finished"), ("r2", 1.0e-3, 2.0, 340.0, "failed"),
            ("r3", 2.0e-3, 1.0, 270.11, "failed"), ("r4", 2.0e-3, 2.0, None, "cancelled")]
    meta = dict(META, mode="grid")
    sweep_plot.plot_sweep(_folder(tmp_path, grid, meta))
    ax = [a for a in figures[0].axes if a.images][0]
    texts = sorted(t.get_text() for t in ax.texts)
    assert texts == ["270.1\n(failed)", "340\n(failed)", "355.5", "cancelled"]
