"""The run-up analysis's clearance is the clearance of the bearing it analyses.

Every amplitude of the whirl analysis is relative to ``analysis.journals.<j>.clearance``, which
the scenario gave separately from the bearings' ``R`` and ``psi``: a scenario copied from a
shipped one and given other bearings (or a sweep over psi without a clearance column) was
analysed with the old clearance and printed a wrong onset speed without any warning. It is now
compared with ``psi R`` of the JournalBearing the journal's x signal is connected to where the
analysis is planned (``check_analysis_clearance``, after loading: run, validate, sweep planning,
compare, export-ssp; orchestrator/scenario/analysis_clearance.py), at the line the loader recorded;
the loader fills it in when it is left out.
"""

from __future__ import annotations

from pathlib import Path

import pytest

from orchestrator import load_scenario
from orchestrator.errors import ScenarioError
from orchestrator.scenario.analysis_clearance import check_analysis_clearance

pytestmark = pytest.mark.integration

QUICKSTART = Path(__file__).resolve().parents[1] / "scenarios" / "quickstart.yaml"
R, PSI = 4.9e-3, 2.8e-3               # quickstart's bearings


def _problems(path, overrides) -> list[str]:
    """The loader's problems, or, for a scenario that loads, the analysis clearance check's."""
    with pytest.raises(ScenarioError) as info:
        check_analysis_clearance(load_scenario(path, overrides, build_fmus=True))
    return info.value.problems


def _line(path: Path, needle: str) -> int:
    return next(i for i, t in enumerate(path.read_text().splitlines(), 1) if needle in t)


def test_shipped_clearance_matches_the_bearings():
    sc = load_scenario(QUICKSTART, build_fmus=True)
    for j in ("bearing1", "bearing2"):
        assert sc.analysis["journals"][j]["clearance"] == 1.372e-5     # as written, psi R to 4 digits


def test_other_bearing_clearance_is_an_error_at_the_clearance_line():
    """psi of bearing1 changed to 2.0e-3 (c = 9.8 um) without the analysis's 13.72 um."""
    probs = _problems(QUICKSTART, ["fmus.bearing1.parameters.psi=2.0e-3"])
    assert len(probs) == 1, probs
    msg = probs[0]
    line = _line(QUICKSTART, "bearing1: {x: rotor.x_1")
    assert msg.startswith(f"{QUICKSTART}:{line}: 'analysis.journals.bearing1.clearance' is 1.372e-05 m"), msg
    assert "'bearing1' (its input x is connected from rotor.x_1)" in msg
    assert f"c = psi R = 0.002 x {R:g} m = {2.0e-3 * R:.6g} m" in msg
    assert f"write clearance: {2.0e-3 * R:.6g}" in msg and "leave 'clearance' out" in msg


def test_the_clearance_is_checked_where_the_analysis_is_planned_not_when_loading(tmp_path):
    """Loading does not know its consumer (`stability` runs no analysis); orchestrator.run() refuses
    the scenario before its folder is made, with the line the loader recorded."""
    from orchestrator import run
    sc = load_scenario(QUICKSTART, ["fmus.bearing1.parameters.psi=2.0e-3"], build_fmus=True)
    line = _line(QUICKSTART, "bearing1: {x: rotor.x_1")
    assert sc.analysis_origins["analysis.journals.bearing1.clearance"] == f"{QUICKSTART}:{line}"
    with pytest.raises(ScenarioError) as info:
        run(sc, out_dir=tmp_path / "run")
    (msg,) = info.value.problems
    assert msg.startswith(f"{QUICKSTART}:{line}: 'analysis.journals.bearing1.clearance' is 1.372e-05 m"), msg
    assert msg.endswith("; --set fmus.bearing1.parameters.psi=2.0e-3 changed it: add --set "
                        f"analysis.journals.bearing1.clearance={2.0e-3 * R:.6g}"), msg
    assert not (tmp_path / "run").exists()


def test_radius_in_millimetres_is_caught_by_the_clearance():
    """R = 4.9 (mm meant, m read): c = psi R = 13.7 mm, 1000 times the analysis's clearance; since
    tests/test_hostile_probe9b.py R is also outside the bearing's declared range [1e-4, 2] m."""
    probs = _problems(QUICKSTART, ["fmus.bearing2.parameters.R=4.9"])
    # (not also a clearance problem computed from the FMU's default R, as the refused value was dropped)
    assert len(probs) == 1 and "outside its declared range [0.0001, 2.0]" in probs[0], probs
    probs = _problems(QUICKSTART, ["fmus.bearing2.parameters.R=1.96"])    # a mm value inside the range
    assert len(probs) == 1 and "'analysis.journals.bearing2.clearance'" in probs[0], probs
    assert "(0.0025 times that)" in probs[0], probs


def test_rounding_within_one_percent_is_accepted():
    c = PSI * R
    for given in (c * 1.009, c * 0.991):
        sc = load_scenario(QUICKSTART, [f"analysis.journals.bearing1.clearance={given!r}"], build_fmus=True)
        assert sc.analysis["journals"]["bearing1"]["clearance"] == given
    assert _problems(QUICKSTART, [f"analysis.journals.bearing1.clearance={c * 1.02!r}"])


def test_a_left_out_clearance_is_taken_from_the_bearing(tmp_path):
    """Before: no clearance in the scenario; the analysis estimated one from eps after the run."""
    text = QUICKSTART.read_text().replace(", clearance: 1.372e-5}", "}")
    assert text.count("clearance") < QUICKSTART.read_text().count("clearance")
    p = tmp_path / "quickstart.yaml"
    p.write_text(text)
    sc = load_scenario(p, ["fmus.bearing2.parameters.psi=3.0e-3"], build_fmus=True)
    assert sc.analysis["journals"]["bearing1"]["clearance"] == pytest.approx(PSI * R, rel=1e-12)
    assert sc.analysis["journals"]["bearing2"]["clearance"] == pytest.approx(3.0e-3 * R, rel=1e-12)


# ---------------------------------------------------------------- the output resolves the top speed
def test_a_top_speed_the_output_cannot_resolve_is_named_at_load_with_the_rpm_hint(caplog):
    """f_max is in Hz. Written in rpm (48000 for the quickstart's 800 Hz) the run-up reaches a
    speed where output.interval gives under 8 samples per revolution; before, only summary.json
    said so after the run (and the analysis still printed an onset)."""
    import logging

    from orchestrator.scenario import checks
    checks._WARNED.clear()
    with caplog.at_level(logging.WARNING, logger="orchestrator.scenario.checks"):
        load_scenario(QUICKSTART, build_fmus=True)
        assert not [r for r in caplog.records if "samples per revolution" in r.getMessage()]
        load_scenario(QUICKSTART, ["fmus.rotor.parameters.f_max=48000"], build_fmus=True)
    (msg,) = [r.getMessage() for r in caplog.records if "samples per revolution" in r.getMessage()]
    sc = load_scenario(QUICKSTART, build_fmus=True)
    t_ramp = sc.fmu("rotor").parameters["t_ramp"]
    f_top = 48000 * min(sc.stop_time, t_ramp) / t_ramp
    dt = sc.output.interval or sc.coupling.macro_step
    assert msg.startswith("--set fmus.rotor.parameters.f_max=48000: 'rotor' runs up to "
                          f"{f_top:g} Hz ({f_top * 60:.4g} rpm)")
    assert f"records {1 / (dt * f_top):.2g} samples per revolution there" in msg
    assert "48000 rpm would be f_max: 800" in msg
