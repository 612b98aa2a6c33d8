"""Tests of ``rotorcosim compare`` with a fake runner (no master needed).

The fake runner writes the result files of the public contract for a made-up
"co-simulation" whose error is known in closed form:
``x(t) = cos t + K h^p sin 3t`` with ``p = 1 + extrapolation_order`` (``p + 1``
for Gauss-Seidel), and a blow-up when ``h`` exceeds ``H_UNSTABLE``. The
reference (``scheme: monolithic``) is ``cos t`` plus ``rtol * sin t``.
"""

from __future__ import annotations

import json
import math
from pathlib import Path

import numpy as np
import pytest

from orchestrator.compare import (CompareSpecError, apply_changes, expand_variants, load_compare, main_compare,
                                  parse_compare, run_comparison)
from orchestrator.compare.metrics import check_report, fit_order, signal_errors
from orchestrator.scenario import (ConnectionSpec, CouplingSpec, FmuSpec, OutputSpec, Scenario)

K = 0.1
H_UNSTABLE = 0.3


def fake_order(scheme: str, ext: int) -> int:
    return 1 + ext + (1 if scheme == "gauss-seidel" else 0)


def fake_runner(scenario: Scenario, out_dir: Path) -> None:
    out_dir.mkdir(parents=True, exist_ok=True)
    c = scenario.coupling
    t = np.arange(0.0, scenario.stop_time + 1e-12, scenario.output.interval)
    if c.scheme == "monolithic":
        x = np.cos(t) + c.options.get("rtol", 1e-8) * np.sin(t)
        steps = 0
    else:
        h, p = c.macro_step, fake_order(c.scheme, c.extrapolation_order)
        x = np.cos(t) + K * h ** p * np.sin(3 * t)
        if h > H_UNSTABLE:
            x = x * np.exp(3 * t)
        steps = int(round(scenario.stop_time / h))
    y = 2.0 * np.sin(t) if c.scheme == "monolithic" else 2.0 * np.sin(t) + 0.5 * (x - np.cos(t))
    with open(out_dir / "results.csv", "w") as f:
        f.write("time,left.x1,left.v1\n")
        for row in zip(t, x, y):
            f.write(",".join(repr(float(v)) for v in row) + "\n")
    summary = {"scenario": scenario.name, "status": "finished", "message": "",
               "macro_steps": steps, "wall_time_s": 0.01,
               "fmu_calls": {"left": {"doStep": steps}, "right": {"doStep": steps}},
               "analysis": {"journals": {"b1": {"onset": {"speed_hz": 100.0 * (1 + float(x[-1] - np.cos(t[-1])))}}}}}
    (out_dir / "summary.json").write_text(json.dumps(summary))


def base_scenario(tmp_path=Path("/nonexistent")) -> Scenario:
    return Scenario(name="fake", stop_time=4.0,
                    fmus=(FmuSpec(name="left", path=tmp_path / "L.fmu"),
                          FmuSpec(name="right", path=tmp_path / "R.fmu")),
                    connections=(ConnectionSpec(src="left.x1", dst="right.x1"),),
                    coupling=CouplingSpec(scheme="jacobi", macro_step=0.1),
                    output=OutputSpec(interval=0.1))


SECTION = {
    "signals": ["left.x1", "left.v1"],
    "reference": {"scheme": "monolithic", "set": {"coupling.options.rtol": 1e-9}},
    "variants": [{"scheme": ["jacobi", "gauss-seidel"], "extrapolation_order": [0, 1],
                  "macro_step": [0.2, 0.1, 0.05]}],
    "output_interval": 0.2,
}


# --------------------------------------------------------------------------- spec

def test_variant_expansion_is_cartesian_with_unique_names_and_families():
    base = base_scenario()
    vs = expand_variants({"scheme": ["jacobi", "gauss-seidel"], "extrapolation_order": [0, 1, 2],
                          "macro_step": [1e-3, 5e-4], "tolerance": {"rms": 0.01}}, base, {}, {"rms"})
    assert len(vs) == 12
    assert len({v.name for v in vs}) == 12
    assert len({v.family for v in vs}) == 6
    v = vs[0]
    assert v.name == "jac-e0i0-h0.001" and v.family == "jac-e0i0"
    assert v.changes == {"coupling.scheme": "jacobi", "coupling.extrapolation_order": 0,
                         "coupling.macro_step": 1e-3}
    assert v.tolerance == {"rms": 0.01}
    sc = apply_changes(base, v.changes)
    assert (sc.coupling.scheme, sc.coupling.macro_step) == ("jacobi", 1e-3)
    # a scalar sequence is one value, not an axis of the product
    vs = expand_variants({"sequence": ["right", "left"], "macro_step": [0.1, 0.2]}, base, {}, set())
    assert len(vs) == 2 and apply_changes(base, vs[0].changes).coupling.sequence == ("right", "left")


def test_name_template_and_parameter_changes():
    base = base_scenario()
    vs = expand_variants({"name": "{scheme}-k{extrapolation_order}-{macro_step:g}",
                          "extrapolation_order": [1], "macro_step": [0.1, 0.2],
                          "set": {"right.kc": 5.0}}, base, {}, set())
    assert [v.name for v in vs] == ["jacobi-k1-0.1", "jacobi-k1-0.2"]
    assert vs[0].family == "jacobi-k1-"
    assert apply_changes(base, vs[0].changes).fmu("right").parameters == {"kc": 5.0}
    with pytest.raises(KeyError, match="unknown coupling field"):
        apply_changes(base, {"coupling.macrostep": 1.0})


def test_invalid_section_lists_every_problem():
    bad = dict(SECTION, metrics=["max", "l2"], colour="red",
               variants=[{"scheme": "jacobi", "macro_step": [0.1, -1.0], "tolerance": {"rsm": 0.1}}],
               output_interval=0.15)
    with pytest.raises(CompareSpecError) as exc:
        parse_compare(bad, base_scenario())
    text = str(exc.value)
    for needle in ("'compare.colour' is not a known key", "'compare.metrics' must be a list",
                   "macro_step' must be a positive number", "'rsm'"):
        assert needle in text, text


def test_output_interval_must_be_a_multiple_of_every_macro_step():
    with pytest.raises(CompareSpecError, match="not a multiple of the macro step"):
        parse_compare(dict(SECTION, output_interval=0.15), base_scenario())


# --------------------------------------------------------------------------- metrics

def test_signal_errors_on_synthetic_signals_with_known_errors():
    t = np.linspace(0.0, 1.0, 101)
    r = 2.0 * np.sin(2 * np.pi * t)                      # peak 2
    e = signal_errors(t, r, t, r + 0.02, scale=2.0)      # constant offset 0.02 -> 1 %
    assert e["max"] == pytest.approx(0.01) and e["rms"] == pytest.approx(0.01)
    assert e["end"] == pytest.approx(0.01)
    bump = np.where(t < 0.5, 0.0, 0.04)                  # 51 of 101 points off by 2 %
    e = signal_errors(t, r, t, r + bump, scale=2.0)
    assert e["max"] == pytest.approx(0.02)
    assert e["rms"] == pytest.approx(0.02 * math.sqrt(51 / 101))
    # a coarser variant grid whose points coincide with every 2nd reference point:
    # linear interpolation of a linear error is exact
    tc = t[::2]
    e = signal_errors(t, r, tc, 2.0 * np.sin(2 * np.pi * tc) + 0.1 * tc, scale=2.0)
    assert e["end"] == pytest.approx(0.05)
    # a run that stops early or produces NaN has an infinite error
    assert signal_errors(t, r, t[:50], r[:50], 2.0)["max"] == math.inf
    v = r.copy()
    v[10] = np.nan
    assert signal_errors(t, r, t, v, 2.0)["rms"] == math.inf


def test_order_fit_recovers_known_orders():
    h = np.array([0.1, 0.05, 0.025, 0.0125])
    p, p_fine, n = fit_order(h, 3.0 * h ** 2)
    assert (p, p_fine, n) == (pytest.approx(2.0), pytest.approx(2.0), 4)
    p, p_fine, _ = fit_order(h, 0.1 * h + 7 * h ** 2)    # asymptotically first order
    assert 1.0 < p_fine < p < 2.0                         # the finest pair is nearer the asymptote
    assert math.isnan(fit_order([0.1], [0.01])[0])
    assert fit_order(h, [0.1, math.inf, 0.02, 0.01])[2] == 3   # an unstable point is dropped


# --------------------------------------------------------------------------- running

def test_run_comparison_measures_errors_orders_and_stability():
    sec = dict(SECTION, variants=[{"scheme": ["jacobi", "gauss-seidel"], "extrapolation_order": [0, 1],
                                   "macro_step": [0.4, 0.2, 0.1, 0.05]}], output_interval=0.4)
    spec = parse_compare(sec, base_scenario())
    import tempfile
    with tempfile.TemporaryDirectory() as d:
        rep = run_comparison(spec, d, runner=fake_runner, workers=1)
    by = {v["name"]: v for v in rep.variants}
    assert not by["jac-e0i0-h0.4"]["stable"]                 # past H_UNSTABLE
    assert by["jac-e0i0-h0.1"]["stable"]
    assert by["jac-e0i0-h0.1"]["macro_steps"] == 40 and by["jac-e0i0-h0.1"]["fmu_calls"] == 80
    for o in rep.orders:
        scheme = "gauss-seidel" if o["family"].startswith("gs") else "jacobi"
        ext = int(o["family"].split("-e")[1][0])
        assert o["order"] == pytest.approx(fake_order(scheme, ext), abs=0.05), o
        assert o["points"] == 3
    # max error of x at h = 0.1 for Jacobi e0: K h sin(3t) / peak(cos) on the output grid
    t = np.arange(0, 4.0 + 1e-12, 0.4)
    expect = np.max(np.abs(K * 0.1 * np.sin(3 * t)))
    assert by["jac-e0i0-h0.1"]["signal_errors"]["left.x1"]["max"] == pytest.approx(expect, rel=1e-6)
    assert rep.reference["check"]["errors"]["max"] < 1e-8


@pytest.fixture
def compare_files(tmp_path, test_fmus):
    """A two-mass scenario (real test FMUs, so the loader can check it) and a comparison file."""
    (tmp_path / "two_mass.yaml").write_text(f"""
name: two-mass
stop_time: 4.0
fmus:
  left: {{path: {test_fmus['LeftMass']}}}
  right: {{path: {test_fmus['RightMass']}}}
connections:
  - {{from: left.x1, to: right.x1}}
  - {{from: left.v1, to: right.v1}}
  - {{from: right.F, to: left.F}}
coupling: {{scheme: jacobi, macro_step: 0.1}}
output: {{interval: 0.2}}
""")

    def write(extra: str, tol: str = "{rms: 0.05, max: 0.1}", baseline: bool = False) -> Path:
        # a named baseline must exist (a missing one fails the comparison), so only when asked
        p = tmp_path / "cmp.yaml"
        p.write_text(f"""
compare:
  scenario: two_mass.yaml
  signals: [left.x1, left.v1]
  reference: {{scheme: monolithic}}
  tolerance: {tol}
  {"baseline: baselines/cmp.json" if baseline else ""}
  variants:
    - {{scheme: [jacobi, gauss-seidel], extrapolation_order: [0, 1], macro_step: [0.2, 0.1, 0.05]}}
{extra}""")
        return p
    return write


def test_clean_run_passes_and_writes_report(compare_files, tmp_path, capsys):
    path = compare_files("")
    rc = main_compare(path, out_dir=tmp_path / "out", runner=fake_runner, workers=2)
    assert rc == 0, capsys.readouterr()
    md = (tmp_path / "out" / "report.md").read_text()
    assert "jac-e0i0-h0.2" in md and "order (fit)" in md and "All checks passed." in md
    doc = json.loads((tmp_path / "out" / "report.json").read_text())
    assert doc["passed"] and len(doc["variants"]) == 12
    assert (tmp_path / "out" / "error_vs_cost.png").stat().st_size > 1000


def test_too_tight_tolerance_fails_naming_variant_and_metric(compare_files, tmp_path, capsys):
    path = compare_files("    - {scheme: jacobi, macro_step: 0.2, name: coarse, tolerance: {max: 0.001}}")
    rc = main_compare(path, out_dir=tmp_path / "out", runner=fake_runner, workers=1)
    err = capsys.readouterr().err
    assert rc == 1
    assert "variant 'coarse': max error" in err and "exceeds tolerance 0.001" in err
    assert err.count("FAIL") == 1                      # the others are within their tolerance
    assert "FAIL variant 'coarse'" in (tmp_path / "out" / "report.md").read_text()


def test_unstable_variant_fails_naming_variant(compare_files, tmp_path, capsys):
    path = compare_files("    - {scheme: jacobi, macro_step: 0.4, name: too-coarse}")
    rc = main_compare(path, out_dir=tmp_path / "out", runner=fake_runner, workers=1)
    err = capsys.readouterr().err
    assert rc == 1
    assert "variant 'too-coarse': rms error" in err and "unstable" in err


def test_expected_order_is_checked(compare_files, tmp_path, capsys):
    path = compare_files("    - {scheme: jacobi, extrapolation_order: 1, macro_step: [0.2, 0.1, 0.05], "
                         "name: 'j1-{macro_step:g}', expect_order: 1}")
    assert main_compare(path, out_dir=tmp_path / "out", runner=fake_runner, workers=1) == 1
    err = capsys.readouterr().err
    assert "family 'j1-': observed order 2.00" in err and "expected 1" in err


def test_baseline_update_and_regression(compare_files, tmp_path, capsys):
    path = compare_files("", baseline=True)
    out = tmp_path / "out"
    rc = main_compare(path, out_dir=out, update_baseline=True, runner=fake_runner, workers=1)
    assert rc == 0
    bfile = tmp_path / "baselines" / "cmp.json"
    base = json.loads(bfile.read_text())
    assert set(base["variants"]) == {v["name"] for v in json.loads((out / "report.json").read_text())["variants"]}
    assert main_compare(path, out_dir=out, runner=fake_runner, workers=1) == 0
    # floating-point noise across machines (relative 1e-9) is not a regression
    for v in base["variants"].values():
        v["errors"] = {m: x * (1 - 1e-9) for m, x in v["errors"].items()}
    bfile.write_text(json.dumps(base))
    assert main_compare(path, out_dir=out, runner=fake_runner, workers=1) == 0
    # a variant whose stored error was half the current one has regressed
    base["variants"]["gs-e1i0-h0.1"]["errors"]["rms"] /= 2
    bfile.write_text(json.dumps(base))
    capsys.readouterr()
    assert main_compare(path, out_dir=out, runner=fake_runner, workers=1) == 1
    err = capsys.readouterr().err
    assert "variant 'gs-e1i0-h0.1': rms error" in err and "regressed vs baseline" in err
    # --update-baseline accepts the new numbers
    assert main_compare(path, out_dir=out, update_baseline=True, runner=fake_runner, workers=1) == 0
    assert main_compare(path, out_dir=out, runner=fake_runner, workers=1) == 0


def test_invalid_file_exits_2(compare_files, tmp_path, capsys):
    path = compare_files("", tol="{rms: -1}")
    assert main_compare(path, out_dir=tmp_path / "out", runner=fake_runner) == 2
    assert "'rms' must be a positive number" in capsys.readouterr().err


def test_check_report_flags_an_inaccurate_reference():
    spec = parse_compare(dict(SECTION, tolerance={"rms": 1e-3}), base_scenario())

    class R:
        reference = {"check": {"ok": True, "message": "", "errors": {"max": 5e-3, "rms": 1e-4, "end": 0},
                               "smallest_tolerance": 1e-3}}
        variants, orders = [], []
    fails = check_report(R(), spec, None)
    assert len(fails) == 1 and "reference: halving" in fails[0] and "'max'" in fails[0]


def test_check_report_flags_a_cost_regression_against_the_baseline():
    """A baseline with FMU calls (written since session 4) fails a variant that needs more than
    (1 + regression_margin) x its calls; fewer calls, a baseline without them, or a run without
    a count pass."""
    spec = parse_compare(dict(SECTION), base_scenario())

    def rep(calls):
        class R:
            reference = {}
            orders = []
            variants = [{"name": "v", "stable": True, "errors": {"max": 1e-3}, "tolerance": {},
                         "message": "", "status": "finished", "fmu_calls": calls}]
        return R()
    base = {"variants": {"v": {"stable": True, "errors": {"max": 1e-3}, "fmu_calls": 1000}}}
    fails = check_report(rep(1101), spec, base)
    assert len(fails) == 1 and "1101 FMU calls regressed vs baseline 1000" in fails[0]
    assert check_report(rep(1100), spec, base) == [] and check_report(rep(500), spec, base) == []
    assert check_report(rep(None), spec, base) == []
    assert check_report(rep(5000), spec, {"variants": {"v": {"stable": True, "errors": {"max": 1e-3}}}}) == []


def test_derived_quantity_error_from_summary():
    """The fake onset speed is 100 Hz * (1 + end deviation of x): its relative error is
    |x_N - cos t_N|; a key missing in the runs gives an infinite error."""
    sec = dict(SECTION, derived={"onset": {"key": "analysis.journals.b1.onset.speed_hz"},
                                 "missing": {"key": "analysis.journals.b1.nothing"}},
               tolerance={"onset": 1.0})
    spec = parse_compare(sec, base_scenario())
    import tempfile
    with tempfile.TemporaryDirectory() as d:
        rep = run_comparison(spec, d, runner=fake_runner, workers=1)
    v = {v["name"]: v for v in rep.variants}["jac-e0i0-h0.1"]
    t_end = 4.0
    ref_end = 1e-9 * math.sin(t_end)                    # the reference's own deviation (rtol 1e-9)
    expect = abs(100 * (1 + K * 0.1 * math.sin(3 * t_end)) - 100 * (1 + ref_end)) / (100 * (1 + ref_end))
    assert v["errors"]["onset"] == pytest.approx(expect, rel=1e-6)
    assert v["errors"]["missing"] == math.inf
    assert check_report(rep, spec, None) == []


def test_window_restricts_metrics_and_scales():
    spec = parse_compare(dict(SECTION, window=[2.0, 4.0]), base_scenario())
    import tempfile
    with tempfile.TemporaryDirectory() as d:
        rep = run_comparison(spec, d, runner=fake_runner, workers=1)
    t = np.arange(0.0, 4.0 + 1e-12, 0.2)
    t = t[t >= 2.0 - 1e-9]
    expect = np.max(np.abs(K * 0.1 * np.sin(3 * t))) / np.max(np.abs(np.cos(t)))
    v = {v["name"]: v for v in rep.variants}["jac-e0i0-h0.1"]
    assert v["signal_errors"]["left.x1"]["max"] == pytest.approx(expect, rel=1e-6)
    assert rep.reference["window"] == [2.0, 4.0]
    with pytest.raises(CompareSpecError, match="'compare.window' must be"):
        parse_compare(dict(SECTION, window=[3.0, 1.0]), base_scenario())


def test_reference_check_covers_derived_tolerances(tmp_path):
    """A tolerance on a derived quantity (e.g. 1 % on the whirl-onset speed) is 'in use':
    the reference's own change in that quantity under halving must stay below it. The fake
    reference's onset is 100 Hz * (1 + rtol sin 4): at rtol 0.1 halving moves it by 4.1 %."""
    sec = dict(SECTION, derived={"onset": {"key": "analysis.journals.b1.onset.speed_hz"}},
               reference={"scheme": "monolithic", "set": {"coupling.options.rtol": 0.1}})
    ref_on = 100 * (1 + 0.1 * math.sin(4.0))
    change = abs(100 * (1 + 0.05 * math.sin(4.0)) - ref_on) / ref_on
    spec = parse_compare(dict(sec, tolerance={"onset": 0.01}), base_scenario())
    assert spec.smallest_tolerance() is None and spec.derived_tolerances() == {"onset": 0.01}
    rep = run_comparison(spec, tmp_path / "a", runner=fake_runner, workers=1)
    assert rep.reference["check"]["errors"]["onset"] == pytest.approx(change, rel=1e-9)
    assert rep.reference["derived"]["onset"] == pytest.approx(ref_on)
    fails = [f for f in check_report(rep, spec, None) if f.startswith("reference:")]
    assert len(fails) == 1 and "changes 'onset' by 0.0409" in fails[0]
    # a looser tolerance on it: the reference is good enough
    spec = parse_compare(dict(sec, tolerance={"onset": 0.1}), base_scenario())
    rep = run_comparison(spec, tmp_path / "b", runner=fake_runner, workers=1)
    assert not [f for f in check_report(rep, spec, None) if f.startswith("reference:")]
    # the report gives the change and the derived values themselves
    from orchestrator.compare.report import write_report
    write_report(rep, spec, tmp_path / "b", [])
    md = (tmp_path / "b" / "report.md").read_text()
    assert f"onset {change:.3g}" in md and ", on onset 0.1" in md
    assert f"| reference | {ref_on:.6g} |" in md and "| jac-e0i0-h0.1 | " in md


def test_error_vs_cost_plots_fmu_calls_along_the_step_refinement(tmp_path, monkeypatch):
    # found with compare/two_mass.yaml: the right panel's cost was the macro steps, so the family
    # with 16 sub-steps (16 doSteps per FMU and macro step) looked the cheapest for its error, and
    # the points were joined in the order of their wall times, which zig-zagged between the steps
    from types import SimpleNamespace
    from orchestrator.compare import report as rep

    def variant(fam, h, wall, calls, err):
        return {"family": fam, "macro_step": h, "wall_time_s": wall, "macro_steps": int(round(0.5 / h)),
                "fmu_calls": calls, "errors": {"max": err}, "stable": True}
    variants = [variant("gs", 4e-3, 0.31, 786, 3e-2), variant("gs", 2e-3, 0.49, 1536, 1.4e-2),
                variant("gs", 1e-3, 0.28, 3036, 7e-3),                # the finest step ran fastest
                variant("gs-s16", 8e-3, 0.58, 4463, 3.3e-4), variant("gs-s16", 4e-3, 0.57, 8679, 4.4e-5),
                {**variant("gs-s16", 2e-3, 0.30, 17179, 5.7e-6), "stable": False}]
    figs = []
    monkeypatch.setattr(rep, "save_figure", lambda fig, path, dpi: figs.append(fig))
    rep._plot(SimpleNamespace(variants=variants), SimpleNamespace(order_metric="max", name="x"), tmp_path / "e.png")
    wall_ax, cost_ax = figs[0].axes
    assert cost_ax.get_xlabel().startswith("FMU calls")
    lines = {ln.get_label(): ln for ln in cost_ax.get_lines()}
    assert list(lines["gs"].get_xdata()) == [786, 1536, 3036]         # calls, coarse to fine
    assert list(lines["gs-s16"].get_xdata()) == [4463, 8679]           # unstable variants left out
    assert list(lines["gs"].get_ydata()) == [3e-2, 1.4e-2, 7e-3]
    walls = {ln.get_label(): list(ln.get_xdata()) for ln in wall_ax.get_lines()}
    assert walls["gs"] == [0.31, 0.49, 0.28]                           # joined by step, not by wall time


def test_orders_through_errors_at_the_reference_accuracy_are_flagged(tmp_path):
    """A co-simulation reference of a third-party FMU (crane-fmu's HarmonicOscillator6D, Gauss-Seidel
    at 5 ms) changed by 5e-4 when halved, and Jacobi k = 2's errors (1e-3) sat on that floor: the
    report gave 'order 0.14' with no word that the reference cannot resolve it, and an
    expect_order: 3 failed as if the scheme were wrong. Here the fake reference is off by rtol."""
    sec = dict(SECTION, reference={"scheme": "monolithic", "set": {"coupling.options.rtol": 1e-3}},
               variants=[{"scheme": ["jacobi", "gauss-seidel"], "extrapolation_order": [0, 1],
                          "macro_step": [0.2, 0.1, 0.05]},
                         {"name": "g3-h{macro_step:g}", "scheme": "gauss-seidel", "extrapolation_order": 1,
                          "macro_step": [0.2, 0.1, 0.05], "expect_order": 1}])
    spec = parse_compare(sec, base_scenario())
    rep = run_comparison(spec, tmp_path / "loose", runner=fake_runner, workers=1)
    near = {o["family"]: o["near_reference"] for o in rep.orders}
    floor = 10 * rep.reference["check"]["errors"]["rms"]
    by = {v["name"]: v for v in rep.variants}
    assert by["gs-e1i0-h0.2"]["errors"]["rms"] < floor           # order 3: every point below the floor
    assert near["gs-e1i0"] == [0.2, 0.1, 0.05]
    assert by["jac-e0i0-h0.2"]["errors"]["rms"] > floor          # order 1: the coarse point resolved
    assert 0.2 not in near["jac-e0i0"]
    fails = check_report(rep, spec, None)
    order_fail = [f for f in fails if f.startswith("family 'g3'")]
    assert len(order_fail) == 1 and "within the reference's own accuracy" in order_fail[0], fails
    from orchestrator.compare.report import write_report
    write_report(rep, spec, tmp_path / "loose", fails)
    md = (tmp_path / "loose" / "report.md").read_text()
    assert "**At the reference's accuracy:**" in md and "- `gs-e1i0`: h = 0.2, 0.1, 0.05 s" in md
    # a reference accurate enough: nothing flagged, nothing said
    tight = parse_compare(dict(sec, reference={"scheme": "monolithic", "set": {"coupling.options.rtol": 1e-12}}),
                          base_scenario())
    rep = run_comparison(tight, tmp_path / "tight", runner=fake_runner, workers=1)
    assert all(o["near_reference"] == [] for o in rep.orders)
    fails = check_report(rep, tight, None)
    assert not any("reference's own accuracy" in f for f in fails)


def test_a_forward_only_error_controlled_variant_is_said_so_in_the_report(tmp_path):
    """An error-controlled step over FMUs that cannot save their state adapts forward only (no
    rejections); the run warned on stderr, the report did not say it, so its error read as one
    held to rtol."""
    def runner(scenario, out_dir):
        fake_runner(scenario, out_dir)
        if scenario.coupling.step_control.type == "error":
            s = json.loads((out_dir / "summary.json").read_text())
            s["step_control"] = {"type": "error", "can_reject": False, "rejected_steps": 0}
            (out_dir / "summary.json").write_text(json.dumps(s))
    sec = dict(SECTION, variants=[{"scheme": "gauss-seidel", "macro_step": 0.1},
                                  {"name": "gs-err", "scheme": "gauss-seidel", "macro_step": 0.1,
                                   "set": {"coupling.step_control.type": "error"}}])
    spec = parse_compare(sec, base_scenario())
    rep = run_comparison(spec, tmp_path, runner=runner, workers=1)
    assert [v["forward_only"] for v in rep.variants] == [False, True]
    from orchestrator.compare.report import write_report
    write_report(rep, spec, tmp_path, [])
    md = (tmp_path / "report.md").read_text()
    assert "adapting **forward only** in `gs-err`:" in md and "`gs-e0i0-h0.1`" not in md.split("forward only")[1]


def test_the_coupling_defect_is_a_column_of_the_report(tmp_path):
    """A variant whose summary.json has a coupling_defect (constant steps, interface-Jacobian forces) gets
    its largest and median defect over the typical force in report.md and report.json, the largest
    over the journals; a malformed entry is left out; no column when no variant has one."""
    from orchestrator.compare.report import write_report
    from orchestrator.compare.runner import _relative_defect

    def runner(scenario, out_dir):
        fake_runner(scenario, out_dir)
        if scenario.coupling.macro_step < 0.1:
            s = json.loads((out_dir / "summary.json").read_text())
            s["coupling_defect"] = {"journals": {
                "rotor.F_1": {"typical": 20.0, "max_defect": 4.0, "median_defect": 0.5},
                "rotor.F_2": {"typical": 10.0, "max_defect": 1.0, "median_defect": 0.4},
                "rotor.F_3": {"typical": "x", "max_defect": 1e9, "median_defect": 1e9}}}
            (out_dir / "summary.json").write_text(json.dumps(s))
    sec = dict(SECTION, variants=[{"scheme": "gauss-seidel", "macro_step": 0.1},
                                  {"scheme": "gauss-seidel", "macro_step": 0.05}])
    spec = parse_compare(sec, base_scenario())
    rep = run_comparison(spec, tmp_path, runner=runner, workers=1)
    assert [v["coupling_defect"] for v in rep.variants] == [None, {"max": 0.2, "median": 0.04}]
    write_report(rep, spec, tmp_path, [])
    md = (tmp_path / "report.md").read_text()
    head = next(line for line in md.splitlines() if line.startswith("| variant"))
    rows = [line for line in md.splitlines() if line.startswith("| gs-") and "-h0." in line]
    i = head.split(" | ").index("max defect / F")
    assert [r.split(" | ")[i:i + 2] for r in rows] == [["-", "-"], ["0.2", "0.04"]]
    assert json.loads((tmp_path / "report.json").read_text())["variants"][1]["coupling_defect"]["max"] == 0.2
    assert _relative_defect({"coupling_defect": {"journals": []}}) is None and _relative_defect(None) is None
    spec1 = parse_compare(dict(SECTION, variants=[{"scheme": "gauss-seidel", "macro_step": 0.1}]), base_scenario())
    write_report(run_comparison(spec1, tmp_path / "none", runner=fake_runner, workers=1), spec1, tmp_path / "none", [])
    assert "defect" not in (tmp_path / "none" / "report.md").read_text()


def test_the_cheapest_variant_within_its_tolerance_is_named(compare_files, tmp_path, capsys):
    """The question a comparison answers for a co-simulation engineer, "which coupling is good
    enough at the least cost", had no answer in the report: 18 rows to read. Now report.md,
    report.json and the command's output name the stable variant within its tolerance with the
    fewest FMU calls (at equal calls the one furthest within it)."""
    path = compare_files("")                 # tolerance {rms: 0.05, max: 0.1}: every stable variant passes
    assert main_compare(path, out_dir=tmp_path / "out", runner=fake_runner, workers=1) == 0
    out = capsys.readouterr().out
    # h = 0.2 is the fewest calls (40); among those Gauss-Seidel k = 1 has the smallest error (order 3)
    assert "cheapest within tolerance: gs-e1i0-h0.2 (40 FMU calls, " in out
    doc = json.loads((tmp_path / "out" / "report.json").read_text())
    assert doc["cheapest_within_tolerance"] == "gs-e1i0-h0.2"
    assert "**Cheapest variant within its tolerance**" in (tmp_path / "out" / "report.md").read_text()
    # a tolerance only the order-3 family meets at h = 0.2 .. 0.05: the coarsest of them
    path = compare_files("", tol="{max: 1.0e-3}")
    assert main_compare(path, out_dir=tmp_path / "o2", runner=fake_runner, workers=1) == 1
    assert json.loads((tmp_path / "o2" / "report.json").read_text())["cheapest_within_tolerance"] == "gs-e1i0-h0.2"
    # nothing within: said so; no tolerance at all: said what to give
    path = compare_files("", tol="{max: 1.0e-6}")      # gs-e1 at 0.05: 1.2e-5; the reference: 5e-9
    capsys.readouterr()
    assert main_compare(path, out_dir=tmp_path / "o3", runner=fake_runner, workers=1) == 1
    assert "**No variant is within its tolerance**" in (tmp_path / "o3" / "report.md").read_text()
    assert "cheapest within tolerance" not in capsys.readouterr().out
    path = compare_files("", tol="{}")
    assert main_compare(path, out_dir=tmp_path / "o4", runner=fake_runner, workers=1) == 0
    assert "No variant has a tolerance" in (tmp_path / "o4" / "report.md").read_text()
    assert json.loads((tmp_path / "o4" / "report.json").read_text())["cheapest_within_tolerance"] is None


def test_a_goal_names_the_cheapest_good_enough_variant_without_failing_the_others(compare_files, tmp_path, capsys):
    """A co-simulation engineer choosing a coupling wants the cheapest variant within the accuracy
    they need; with `tolerance` every coarser variant was a `FAIL` line and the command exited 1,
    as if something were broken. `goal` selects the same variant and is no check: exit 0, the
    variants outside it marked "no" in report.md's "meets goal" column."""
    path = compare_files("  goal: {max: 1.0e-3}", tol="{}")
    assert main_compare(path, out_dir=tmp_path / "g", runner=fake_runner, workers=1) == 0
    cap = capsys.readouterr()
    assert "cheapest within tolerance: gs-e1i0-h0.2 (40 FMU calls, " in cap.out and "max " in cap.out
    assert "FAIL" not in cap.err and "compare: all checks passed" in cap.out
    doc = json.loads((tmp_path / "g" / "report.json").read_text())
    assert doc["cheapest_within_tolerance"] == "gs-e1i0-h0.2" and doc["passed"]
    met = {v["name"]: v["meets_goal"] for v in doc["variants"]}
    assert met["gs-e1i0-h0.2"] is True and met["jac-e0i0-h0.2"] is False
    md = (tmp_path / "g" / "report.md").read_text()
    assert "| goal | meets goal |" in md and "| max 0.001 | no |" in md
    # the reference must resolve the goal as it must a tolerance
    assert load_compare(path).smallest_tolerance() == 1.0e-3
    # a variant group's goal overrides the comparison's; a tolerance beside it still fails
    path = compare_files("    - {scheme: gauss-seidel, extrapolation_order: 1, macro_step: 0.4, goal: {max: 0.5}}",
                         tol="{max: 1.0e-6}")
    spec = load_compare(path)
    assert {v.name: dict(v.goal) for v in spec.variants}["gs-e1i0-h0.4"] == {"max": 0.5}
    # goal values are checked as tolerances are
    bad = compare_files("  goal: {max: .nan}", tol="{}")
    with pytest.raises(CompareSpecError, match="goal"):
        load_compare(bad)


def test_a_goal_finer_than_the_reference_resolves_fails_naming_the_goal(compare_files, tmp_path, capsys):
    """A goal the reference cannot resolve (its convergence check changes it by ~5e-9) fails the
    comparison as a tolerance does ("tighten the reference"), and names nothing; the message said
    "the smallest tolerance in use" of a comparison that has no tolerance."""
    path = compare_files("  goal: {max: 1.0e-10}", tol="{}")
    assert main_compare(path, out_dir=tmp_path / "g", runner=fake_runner, workers=1) == 1
    err = capsys.readouterr().err
    assert ">= the smallest tolerance or goal in use 1e-10; tighten the reference" in err, err
    doc = json.loads((tmp_path / "g" / "report.json").read_text())
    assert doc["cheapest_within_tolerance"] is None and not doc["passed"]


def test_a_missing_signals_list_is_answered_with_signals_to_write(compare_files):
    """A first comparison file often leaves `signals` out; the message now gives outputs the base
    scenario records to copy instead of only the type of the key."""
    path = compare_files("")
    path.write_text(path.read_text().replace("  signals: [left.x1, left.v1]\n", ""))
    with pytest.raises(CompareSpecError) as info:
        load_compare(path)
    msg = str(info.value)
    assert "'compare.signals' must be a non-empty list" in msg
    assert "e.g. signals: ['left.x1', 'left.v1'" in msg, msg


def test_no_variant_is_named_good_enough_against_a_reference_that_failed_its_check():
    from orchestrator.compare.metrics import cheapest_within_tolerance

    class R:
        variants = [{"name": "a", "stable": True, "tolerance": {"max": 0.1}, "errors": {"max": 0.01},
                     "fmu_calls": 10, "wall_time_s": 1.0}]
    assert cheapest_within_tolerance(R(), [])["name"] == "a"
    assert cheapest_within_tolerance(R(), ["reference: halving its tolerance/step changes the 'max' error by "
                                           "0.2 >= the smallest tolerance in use 0.1; tighten the reference"]) is None
    assert cheapest_within_tolerance(R(), ["variant 'a': max error 0.2 exceeds tolerance 0.1"]) is None


def test_gauss_seidel_families_whose_order_interpolation_order_caps_are_said(tmp_path):
    """Two crane-fmu oscillators in a loop: Gauss-Seidel k = 1 with the default q = 0 had order
    1.01 against Jacobi k = 1's 2.00 (and q = 1: 1.97), which read as "Jacobi is more accurate";
    the report now says that q caps those families' order at q + 1."""
    sec = dict(SECTION, variants=[{"scheme": ["jacobi", "gauss-seidel"], "extrapolation_order": [0, 1],
                                   "macro_step": [0.2, 0.1]},
                                  {"scheme": "gauss-seidel", "extrapolation_order": 1, "interpolation_order": 1,
                                   "macro_step": [0.2, 0.1]}])
    spec = parse_compare(sec, base_scenario())
    rep = run_comparison(spec, tmp_path, runner=fake_runner, workers=1)
    capped = {v["name"]: v["order_capped_at"] for v in rep.variants}
    assert capped["gs-e1i0-h0.2"] == capped["gs-e1i0-h0.1"] == 1
    assert capped["gs-e1i1-h0.2"] is None and capped["jac-e1i0-h0.2"] is None and capped["gs-e0i0-h0.2"] is None
    from orchestrator.compare.report import write_report
    write_report(rep, spec, tmp_path, [])
    md = (tmp_path / "report.md").read_text()
    assert "**Order capped by `interpolation_order`** in `gs-e1i0`:" in md
