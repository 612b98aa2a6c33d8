"""Leftovers of the ninth probe (tests/test_hostile_probe9.py): the bearing FMUs' physical parameters
get declared ranges as the rotor FMUs' have, results.parquet gets the row bound of results.csv, and
`stability --plot` no longer writes a PNG over a file named without a suffix. One test per finding,
each failing on the code before its fix."""

from __future__ import annotations

from pathlib import Path

import pytest

from hostile_builders import cli
from tests.test_fmu_param_bounds import scenario, variables

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


# --------------------------------------------------------------------------- bearing parameter ranges
def bearing_block(R, B, eta0) -> str:
    """The bearing's parameters one per line (R on line 11 of test_fmu_param_bounds' scenario)."""
    return "\n      ".join(f"{k}: {v}" for k, v in dict(R=R, B=B, psi="2.8e-3", eta0=eta0, n_phi=24, n_z=12,
                                                          cavitation=0).items())


@pytest.mark.parametrize("field, value, line, rng", [
    ("R", "25", 11, "[0.0001, 2.0]"),          # R in mm: a 25 m journal
    ("B", "32", 12, "[0.0001, 4.0]"),          # B in mm
    ("eta0", "12", 14, "[1e-07, 10.0]"),       # eta0 in mPa s
    ("R", "1e-6", 11, "[0.0001, 2.0]"),
])
def test_bearing_values_in_a_wrong_unit_are_refused_at_load(tmp_path, field, value, line, rng):
    # R, B and eta0 had only a lower bound (> 0): R: 25 (meant: mm) ran as a 25 m journal
    from orchestrator.errors import ScenarioError
    from orchestrator.scenario import load_scenario
    values = {"R": "4.9e-3", "B": "7.84e-3", "eta0": "0.012", field: value}
    p = scenario(tmp_path, bearing_block(**values))
    with pytest.raises(ScenarioError) as exc:
        load_scenario(p)
    msg = str(exc.value)
    assert f"s.yaml:{line}" in msg and f"bearing1.{field}' = {float(value)!r}" in msg, msg
    assert f"outside its declared range {rng}" in msg and "give a value inside the range" in msg, msg
    load_scenario(scenario(tmp_path, bearing_block(**{**values, field: {"R": "0.5", "B": "1.0", "eta0": "1.0"}[field]})))                              # a ship's shaft, cold oil: inside


def test_bearing_fmus_declare_upper_bounds():
    jb = variables("JournalBearing")
    for name in ("R", "B", "eta0", "p0", "p_feed", "sigma_rough", "contact_KE", "mu_contact"):
        assert jb[name].max is not None and jb[name].min <= jb[name].start <= jb[name].max, name
    fr = variables("FloatingRingBearing")
    for name in ("R_inner", "R_outer", "B_inner", "eta0_outer", "p_feed_inner", "p0", "omega_ring0",
                 "x_ring0", "y_ring0"):
        assert fr[name].max is not None and fr[name].min <= fr[name].start <= fr[name].max, name
    assert (fr["x_ring0"].min, fr["x_ring0"].max) == (-1.0, 1.0)
    assert fr["omega_ring0"].min < 0 < fr["omega_ring0"].max        # < 0: the Petroff ratio


@pytest.mark.parametrize("value", ["B=1e6", "B=1e-12", "eta0=1e6"])
def test_stability_absurd_bearing_is_refused_at_load(capsys, value):
    # these reached the film solvers (tests/test_hostile_probe8.py): "eccentricity below 1e-12", the
    # film unable to carry the load, the HS solver dividing by zero
    rc, text = cli(capsys, "stability", JEFFCOTT_HS, "--film", "short", "--set", f"fmus.bearing1.parameters.{value}")
    name = value.split("=")[0]
    assert rc == 1 and f"--set fmus.bearing1.parameters.{value}: parameter 'bearing1.{name}'" in text, text
    assert "outside its declared range" in text and "linearly stable" not in text, text


@pytest.mark.parametrize("line, value", [("omega_ring0: 1317.84", "omega_ring0: 1.0e9"),
                                         ("omega_ring0: 1317.84", "x_ring0: 10.6, omega_ring0: 1317.84")])  # um
def test_floating_ring_start_values_are_bounded(tmp_path, line, value):
    from orchestrator.errors import ScenarioError
    from orchestrator.scenario import load_scenario
    src = (REPO / "scenarios" / "jeffcott_runup_floating_ring_half_sommerfeld_seeded.yaml").read_text()
    assert line in src, line
    p = tmp_path / "s.yaml"
    p.write_text(src.replace(line, value, 1))
    with pytest.raises(ScenarioError) as exc:
        load_scenario(p)
    msg = str(exc.value)
    lineno = src[:src.index(line)].count("\n") + 1
    assert f"s.yaml:{lineno}" in msg and "outside its declared range" in msg, msg
