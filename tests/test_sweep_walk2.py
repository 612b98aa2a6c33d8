"""Frictions of the second sweeps walkthrough (docs/sweeps.md): too-thin oil diagnosed as a
blow-up, stability refusing a psi --set for an analysis clearance it does not use, sweep
maps that show 0/1 for the cavitation model and a made-up colour range for a constant map."""

import math

import pytest

from bearing_fmu.model import BearingModel, BearingParams
from bearing_fmu.solver import StepFailed

R, B, PSI = 4.9e-3, 7.84e-3, 2.8e-3
C = PSI * R
W = 2 * math.pi * 220.0


def _bearing(eta0, linearized=False):
    b = BearingModel(BearingParams(R=R, B=B, psi=PSI, eta0=eta0, n_phi=24, n_z=8, cavitation=0))
    b.linearized = linearized
    b.initialize(0.0, -0.5 * C, 0.0, 0.0, W)
    b.step(1e-4, 0.0, -0.95 * C, 0.0, -0.03, W)
    return b


def test_too_thin_oil_is_named_as_the_oil_not_a_blow_up():
    """eta0 = 1e-7 Pa s: the journal falls into the shell. The message used to say 'the coupled
    simulation went unstable ... use linearize: 1'; it must name eta0 and the film's load capacity."""
    b = _bearing(1e-7, linearized=True)
    cap = b.load_capacity(W)
    assert 0.0 < cap < 0.1                          # 12 mPa s carries ~1e5 times more
    with pytest.raises(StepFailed) as info:
        b.step(1e-4, 0.0, -1.16 * C, 0.0, -0.03, W)
    msg = str(info.value)
    assert "cannot carry the load" in msg and "eta0 = 1e-07 Pa s is far below any oil" in msg
    assert f"load capacity at this viscosity and speed is about {cap:.3g} N" in msg
    assert "not a coupling instability" in msg and "0.012 for 12 mPa s" in msg
    assert "unstable before" not in msg and "linearize" not in msg
    with pytest.raises(StepFailed, match="cannot carry the load"):   # just past the shell, too
        b.step(1e-4, 0.0, -1.01 * C, 0.0, -0.03, W)


def test_a_blow_up_with_real_oil_stays_a_blow_up_and_gives_the_capacity():
    b = _bearing(0.012, linearized=True)
    with pytest.raises(StepFailed) as info:
        b.step(1e-4, 0.0, -1.16 * C, 0.0, -0.03, W)
    msg = str(info.value)
    assert "went unstable before this step" in msg
    assert "interface-Jacobian coupling is already on" in msg and "(linearize: 1)" not in msg
    assert f"about {b.load_capacity(W):.3g} N at eps = 0.95" in msg
    assert "not a coupling instability" not in msg
    b = _bearing(0.012, linearized=False)
    with pytest.raises(StepFailed, match=r"use interface-Jacobian coupling \(linearize: 1\)"):
        b.step(1e-4, 0.0, -1.16 * C, 0.0, -0.03, W)


def test_load_capacity_scales_with_viscosity_and_speed():
    thin, thick = _bearing(1e-6), _bearing(1e-2)
    assert thick.load_capacity(W) == pytest.approx(1e4 * thin.load_capacity(W), rel=1e-9)
    assert thick.load_capacity(2 * W) == pytest.approx(2 * thick.load_capacity(W), rel=1e-9)


# -- 2: the analysis clearance against a psi --set ----------------------------------------------

from pathlib import Path  # noqa: E402

from orchestrator.errors import ScenarioError  # noqa: E402

REPO = Path(__file__).resolve().parents[1]
SEEDED = REPO / "scenarios" / "jeffcott_runup_half_sommerfeld_seeded.yaml"
PSI_SETS = ["fmus.bearing1.parameters.psi=3.2e-3", "fmus.bearing2.parameters.psi=3.2e-3"]


def test_a_run_refused_for_the_clearance_gives_the_exact_set_to_add():
    from orchestrator import load_scenario
    from orchestrator.scenario.analysis_clearance import check_analysis_clearance
    with pytest.raises(ScenarioError) as info:
        check_analysis_clearance(load_scenario(SEEDED, PSI_SETS))     # what `run` checks after loading
    text = str(info.value)
    assert "--set fmus.bearing1.parameters.psi=3.2e-3 changed it: " \
           "add --set analysis.journals.bearing1.clearance=1.568e-05" in text
    assert "add --set analysis.journals.bearing2.clearance=1.568e-05" in text
    sc = load_scenario(SEEDED, PSI_SETS + ["analysis.journals.bearing1.clearance=1.568e-05",
                                           "analysis.journals.bearing2.clearance=1.568e-05"])
    check_analysis_clearance(sc)
    assert sc.analysis["journals"]["bearing1"]["clearance"] == pytest.approx(1.568e-5)


def test_stability_loads_a_psi_set_whatever_the_analysis_clearance(capsys):
    """The linear threshold does not use analysis.journals.*.clearance: `rotorcosim stability
    SEEDED --set ...psi=3.2e-3` was refused for it. Loading does not check the clearance (the
    callers that run the analysis do, check_analysis_clearance): the scenario loads as written."""
    from orchestrator import load_scenario
    from orchestrator.scenario.analysis_clearance import check_analysis_clearance
    sc = load_scenario(SEEDED, PSI_SETS)
    assert sc.analysis["journals"]["bearing1"]["clearance"] == pytest.approx(1.372e-5)   # as written
    with pytest.raises(ScenarioError, match="'analysis.journals.bearing1.clearance' is 1.372e-05 m"):
        check_analysis_clearance(sc)
    from hostile_builders import run_verb
    code, text, err = run_verb(capsys, "stability", SEEDED, "--set", PSI_SETS[0], "--set", PSI_SETS[1])
    assert code == 0, err
    assert "threshold speed:" in text and "clearance" not in err


@pytest.mark.parametrize("mode", ["grid", "zip"])
def test_a_sweep_over_psi_is_refused_at_its_own_psi_line(tmp_path, mode):
    from orchestrator.sweep import load_sweep
    from orchestrator.sweep.plan import plan_sweep
    from orchestrator.sweep.spec import SweepError
    (tmp_path / "sw.yaml").write_text(
        f"sweep: 1\nscenario: {SEEDED}\nmode: {mode}\nparameters:\n  - name: psi\n"
        "    set: [fmus.bearing1.parameters.psi, fmus.bearing2.parameters.psi]\n"
        "    values: [2.8e-3, 3.2e-3]\n")
    with pytest.raises(SweepError) as info:
        plan_sweep(load_sweep(tmp_path / "sw.yaml"), build_fmus=False)
    problems = info.value.problems
    assert len(problems) == 2
    first = problems[0]
    assert first.startswith(f"{tmp_path / 'sw.yaml'}:6: run psi=0.0032: ")
    assert f"{SEEDED}:89:" in first                 # the scenario's clearance line, too
    assert "the sweep's line 6 sets fmus.bearing1.parameters.psi" in first
    assert "analysis.journals.bearing1.clearance to each run's psi R (here 1.568e-05)" in first
    assert ("leave 'clearance' out" in first.split("the sweep's line")[1]) == (mode == "grid")
    assert "--set" not in first.split("the sweep's line")[1]


# -- 3: the sweep maps: switch names, a constant map ---------------------------------------------

from orchestrator.sweep import plot as sweep_plot  # noqa: E402
from tests.test_sweep_map import _folder  # noqa: E402


def _value_names(tmp_path, params, rows) -> dict:
    """The names of the swept values that a sweep over ``params`` of SEEDED records in sweep.json:
    those its bearing FMU declares (orchestrator.sweep.units.sweep_labels)."""
    from orchestrator.sweep import load_sweep
    from orchestrator.sweep.plan import expand
    from orchestrator.sweep.units import sweep_labels
    lines = "".join(f"  - {{name: {n}, set: [{', '.join(paths)}], values: {sorted({r[k] for r in rows})}}}\n"
                    for k, (n, paths) in enumerate(params.items()))
    (tmp_path / "sw.yaml").write_text(f"sweep: 1\nscenario: {SEEDED}\nparameters:\n{lines}")
    spec = load_sweep(tmp_path / "sw.yaml")
    return sweep_labels(spec, expand(spec)[0].overrides)[2]


def _sweep_folder(tmp_path, params, rows, value="max_eps"):
    """sweep.csv and sweep.json of a finished sweep over ``params`` (name -> set paths) of
    SEEDED, with the names of the values its FMU declares (before 2026-12-07 the plot took them
    from a table of our bearing's switches, matched by the parameter's name)."""
    names = _value_names(tmp_path, params, rows)
    meta = {"sweep": 1, "source": "s.yaml", "scenario": str(SEEDED), "mode": "grid",
            "parameters": [{"name": n, "set": paths, **({"value_names": {str(v): t for v, t in names[n].items()}}
                                                        if n in names else {})} for n, paths in params.items()],
            "collect": {value: f"analysis.journals.bearing1.{value}"}}
    head = ",".join(["run_id", *params, value, "status", "message", "wall_time_s", "run_dir"]) + "\n"
    return _folder(tmp_path, [(f"r{k}", *r, "finished") for k, r in enumerate(rows)], meta, head)


CAV = {"cavitation": ["fmus.bearing1.parameters.cavitation", "fmus.bearing2.parameters.cavitation"],
       "eta0": ["fmus.bearing1.parameters.eta0", "fmus.bearing2.parameters.eta0"]}


def test_a_cavitation_axis_is_labelled_with_the_model_names(tmp_path, figures):
    rows = [(0, 0.008, 0.41), (1, 0.008, 0.52), (0, 0.012, 0.45), (1, 0.012, 0.60)]
    sweep_plot.plot_sweep(_sweep_folder(tmp_path, CAV, rows))
    ax = [a for a in figures[0].axes if a.images][0]
    assert [t.get_text() for t in ax.get_xticklabels()] == ["half-Sommerfeld (0)", "mass-conserving (1)"]
    assert [t.get_text() for t in ax.get_yticklabels()] == ["0.008", "0.012"]


def test_a_cavitation_line_is_labelled_with_the_model_names(tmp_path, figures):
    sweep_plot.plot_sweep(_sweep_folder(tmp_path, {"cavitation": CAV["cavitation"]}, [(0, 0.41), (1, 0.52)]))
    ax = [a for a in figures[0].axes if a.get_xlabel()][0]
    assert [t.get_text() for t in ax.get_xticklabels()] == ["half-Sommerfeld (0)", "mass-conserving (1)"]


def test_an_integer_axis_that_is_no_switch_keeps_its_numbers(tmp_path, figures):
    n_phi = {"n_phi": ["fmus.bearing1.parameters.n_phi"], "eta0": CAV["eta0"]}
    rows = [(40, 0.008, 0.41), (80, 0.008, 0.52), (40, 0.012, 0.45), (80, 0.012, 0.60)]
    sweep_plot.plot_sweep(_sweep_folder(tmp_path, n_phi, rows))
    ax = [a for a in figures[0].axes if a.images][0]
    assert [t.get_text() for t in ax.get_xticklabels()] == ["40", "80"]


def test_a_map_of_one_value_has_a_one_colour_bar_labelled_with_it(tmp_path, figures):
    """Every run 0.958: the colour bar showed 0.858 ... 1.058, a range no run has."""
    rows = [(0, 0.008, 0.958), (1, 0.008, 0.958), (0, 0.012, 0.958), (1, 0.012, 0.958)]
    sweep_plot.plot_sweep(_sweep_folder(tmp_path, CAV, rows))
    fig = figures[0]
    fig.canvas.draw()
    bar = [a for a in fig.axes if a.get_label() == "<colorbar>"][0]
    assert [t.get_text() for t in bar.get_yticklabels()] == ["0.958"]
    assert "0.958 in every run" in bar.get_ylabel()
    im = [a for a in fig.axes if a.images][0].images[0]
    assert im.cmap.N == 1                            # one colour, not a gradient over a made-up range


def test_a_map_of_different_values_keeps_its_gradient(tmp_path, figures):
    rows = [(0, 0.008, 0.41), (1, 0.008, 0.52), (0, 0.012, 0.45), (1, 0.012, 0.60)]
    sweep_plot.plot_sweep(_sweep_folder(tmp_path, CAV, rows))
    im = [a for a in figures[0].axes if a.images][0].images[0]
    assert im.cmap.N > 1 and im.norm.vmin == 0.41 and im.norm.vmax == 0.60


def test_a_run_with_too_thin_oil_says_so_and_gives_no_macro_step_advice(tmp_path, capsys):
    """The walkthrough's run: eta0 = 1e-7 on both bearings of the seeded run-up (linearize: 1)."""
    from hostile_builders import run_verb
    code, text, err = run_verb(capsys, "run", SEEDED, "--out", tmp_path / "thin", "--no-progress",
                               "--set", "fmus.bearing1.parameters.eta0=1e-7",
                               "--set", "fmus.bearing2.parameters.eta0=1e-7", "--set", "stop_time=0.551")
    assert code != 0
    assert "status: failed" in text
    assert "eta0 = 1e-07 Pa s is far below any oil" in err and "load capacity" in err
    assert "went unstable" not in err and "linearize: 1" not in err
    assert "a smaller coupling.macro_step or more substeps do not change" in err
    assert "also try a smaller coupling.macro_step" not in err
