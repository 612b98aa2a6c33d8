"""The coupling defect of interface-Jacobian forces on a constant step (orchestrator/coupling/defect.py):
known answers on a linear film, the episode summary, the bounded memory, and the real FMUs'
contact phase from rest."""

from __future__ import annotations

import dataclasses
import json
import logging
import math
from pathlib import Path

import numpy as np
import pytest

from orchestrator.coupling import defect as defect_mod
from orchestrator.coupling.defect import DefectMonitor
from orchestrator.coupling.execution import MasterAlgorithm
from orchestrator.coupling.signals import History
from orchestrator.scenario import ConnectionSpec, OutputSpec, load_scenario
from test_master_adaptive_scales import CF, KF, IJJournal, film, ij_scenario

ROOT = Path(__file__).resolve().parents[1]
H = 1e-4
# the from-rest scenarios ship the contact phase error-controlled (step_control.until); these tests are
# about the constant step there
CONSTANT = "coupling.step_control={type: constant}"


def scenario(k=0, control=None, sequence=("rotor", "bearing"), scheme="gauss-seidel"):
    sc = ij_scenario(control)
    return dataclasses.replace(
        sc, stop_time=0.02, coupling=dataclasses.replace(sc.coupling, sequence=sequence, macro_step=H,
                                                         extrapolation_order=k, scheme=scheme),
        output=OutputSpec(interval=H, signals=("rotor.x_1", "rotor.y_1", "rotor.vx_1", "rotor.vy_1",
                                               "bearing.Fx", "bearing.Fy")))


def run(bearing, **kw):
    res = MasterAlgorithm(scenario(**kw), subsystems={"rotor": IJJournal(), "bearing": bearing}).run()
    assert res.success, res.message
    return res


def test_jacobi_counts_the_kinematics_the_film_was_fed():
    """Jacobi (k = 0): the film computes F(T+H) at the held kinematics r(T), not at r(T+H) where the rotor
    went; the coefficients it returns carry the difference, -K (r(T+H) - r(T)) - C (v(T+H) - v(T)).
    On a linear film with its own coefficients the remaining defect is then Jacobi's lag alone: the rotor
    integrated the force of r(T - H), so d = F(r(T)) - F(r(T - H)) = the recorded force's change over
    the step (without the kinematics term it would be that plus K dr + C dv)."""
    res = run(film(), scheme="jacobi")
    j = res.stats["coupling_defect"]["journals"]["rotor.F_1"]
    o = res.outputs
    d = np.hypot(*np.diff(np.stack([o["bearing.Fx"], o["bearing.Fy"]], 1), axis=0).T)
    assert j["max_defect"] == pytest.approx(d.max(), rel=1e-5)
    assert j["median_defect"] == pytest.approx(np.median(d), rel=1e-5)
    assert j["t_max_defect"] == pytest.approx(res.t[1 + int(np.argmax(d))], abs=1e-12)


def test_exact_coefficients_leave_no_defect():
    """A linear film whose coefficients are its own: the rotor integrates the exact force (k = 0), d = 0."""
    res = run(film())
    st = res.stats["coupling_defect"]
    j = st["journals"]["rotor.F_1"]
    assert st["steps"] == 200 and j["steps_over"] == 0 and j["episodes"] == []
    assert j["max_defect"] < 1e-9 * j["typical"]
    assert j["typical"] > 1.0                   # the journal does move the film (F ~ 200 N at the start)


@pytest.mark.parametrize("half", ["k", "c"])
def test_wrong_coefficients_give_the_known_defect(half):
    """The film reports half its stiffness (or damping): per step d = -(KF/2) dr (or -(CF/2) dv), computed
    here from the recorded journal motion; the monitor's largest |d|, its time and the typical |F| match."""
    bearing = film(k_reported=KF / 2) if half == "k" else film(c_reported=CF / 2)
    res = run(bearing)
    o = res.outputs
    q = np.stack([o["rotor.x_1"], o["rotor.y_1"]], 1) if half == "k" else np.stack([o["rotor.vx_1"],
                                                                                     o["rotor.vy_1"]], 1)
    coef = KF / 2 if half == "k" else CF / 2
    d = coef * np.hypot(*np.diff(q, axis=0).T)
    f = np.hypot(o["bearing.Fx"], o["bearing.Fy"])[1:]
    j = res.stats["coupling_defect"]["journals"]["rotor.F_1"]
    assert j["max_defect"] == pytest.approx(d.max(), rel=1e-5)
    assert j["t_max_defect"] == pytest.approx(res.t[1 + int(np.argmax(d))], abs=1e-12)
    assert j["typical"] == pytest.approx(np.median(f), rel=1e-5)
    assert j["median_defect"] == pytest.approx(np.median(d), rel=1e-5)


def test_extrapolated_force_counts_its_prediction():
    """k = 1: the rotor integrates P - K dr - C dv with P the linear extrapolation of F, which counts the
    film's change twice (signal_scales.py); d = F(T+H) - P(T+H) + K dr + C dv = -(F(T) - F(T-H)) here."""
    res = run(film(), k=1)
    o = res.outputs
    F = np.stack([o["bearing.Fx"], o["bearing.Fy"]], 1)
    d = np.hypot(*np.diff(F, axis=0).T)[1:]                   # from the second step on (the first holds)
    j = res.stats["coupling_defect"]["journals"]["rotor.F_1"]
    assert j["max_defect"] == pytest.approx(d.max(), rel=1e-5)


def test_not_monitored_where_it_would_not_be_the_rotors_defect():
    """The error-controlled step and the iterative scheme have their own estimates; a force the rotor
    receives interpolated (the bearing steps first) has none: no coupling_defect in the statistics."""
    from orchestrator.scenario.model import StepControlSpec
    res = run(film(), control=StepControlSpec(type="error", rtol=1e-2))
    assert "coupling_defect" not in res.stats
    res = run(film(), sequence=("bearing", "rotor"))
    assert "coupling_defect" not in res.stats
    res = run(film(), scheme="iterative")
    assert "coupling_defect" not in res.stats and res.stats["iterations"]
    assert "coupling_defect" in run(film(), scheme="jacobi").stats


# --- the monitor alone: episodes, note, bounded memory ---------------------------------------------
NAMES = ["rotor.Fx_1", "rotor.Fy_1"] + [f"rotor.{c}{a}{b}_1" for c in "kc" for a in "xy" for b in "xy"] + \
        ["bearing.x", "bearing.y", "bearing.vx", "bearing.vy"]
CONNS = [ConnectionSpec(src=f"rotor.{a}_1", dst=f"bearing.{a}") for a in ("x", "y", "vx", "vy")]


def feed(mon, forces, t0=0.0, h=1e-3):
    """Levels with coefficients and motion 0, so d = F(T+H) - F(T); ``forces``: Fy per level."""
    hist = History(depth=4)
    hist.allocate([len(NAMES)])
    hist.store[0, 1] = forces[0]
    hist.start(t0)
    for n, f in enumerate(forces[1:], start=1):
        mon.before(hist, t0 + (n - 1) * h, t0 + n * h)
        hist.times[0] = t0 + n * h
        hist.store[0] = hist.store[1]
        hist.store[0, 1] = f
        hist.commit()
        mon.after(hist, t0 + n * h)


def test_episodes_and_note():
    mon = DefectMonitor(NAMES, NAMES[:10], CONNS, k=0, unit_of=lambda name: "N")
    forces = np.full(101, 30.0)
    forces[[20, 22]] = 100.0          # |d| = 70 at steps 20, 21, 22, 23: one episode (gap <= 10)
    forces[70] = 75.0                 # |d| = 45 at 70, 71: another one
    feed(mon, forces)
    j = mon.statistics()["journals"]["rotor.F_1"]
    assert j["typical"] == 30.0 and j["steps_over"] == 6 and j["episode_count"] == 2
    assert [(e["steps"], e["max_defect"]) for e in j["episodes"]] == [(4, 70.0), (2, 45.0)]
    assert (j["first_flagged"], j["last_flagged"]) == (0.020, 0.071)
    assert j["episodes"][0]["t_start"] == pytest.approx(0.020) and j["episodes"][0]["t_end"] == pytest.approx(0.023)
    note = mon.note()
    assert "rotor.F_1: 6 steps in 2 episodes between t=0.02 and 0.071 s" in note
    assert "largest 70 N against a typical size of 30 N" in note and "half the coupling.macro_step" in note
    with_h = DefectMonitor(NAMES, NAMES[:10], CONNS, k=0, macro_step=1e-3)
    feed(with_h, forces)
    assert "(--set coupling.macro_step=0.0005 --set stop_time=0.091)" in with_h.note()
    quiet = DefectMonitor(NAMES, NAMES[:10], CONNS, k=0)
    feed(quiet, 30.0 + np.sin(np.arange(50)))
    assert quiet.note() is None and quiet.statistics()["journals"]["rotor.F_1"]["steps_over"] == 0


def test_memory_is_bounded_and_keeps_the_largest_defect(monkeypatch):
    monkeypatch.setattr(defect_mod, "MAX_KEPT", 64)
    mon = DefectMonitor(NAMES, NAMES[:10], CONNS, k=0)
    forces = 30.0 + 0.1 * np.sin(np.arange(1001))
    forces[777] = 500.0
    feed(mon, forces)
    st = mon.statistics()
    j = st["journals"]["rotor.F_1"]
    assert mon._n < 64 and st["steps"] == 1000 and st["steps_per_row"] >= 16
    jumps = np.abs(np.diff(forces))                           # d = F(T+H) - F(T): into and out of the spike
    assert j["max_defect"] == pytest.approx(jumps.max(), rel=1e-6)
    assert j["t_max_defect"] == pytest.approx(1e-3 * (1 + np.argmax(jumps)))
    assert j["typical"] == pytest.approx(30.0, abs=0.1)


def test_no_interface_jacobian_forces_no_monitor():
    assert not DefectMonitor(NAMES[:2] + NAMES[10:], NAMES[:2], CONNS, k=0)


# --- the real FMUs: the mass-conserving film's contact phase from rest --------------------------------
@pytest.mark.parametrize("name, flagged", [("jeffcott_runup_free_to_air_from_rest", True),
                                           ("jeffcott_runup_half_sommerfeld_from_rest", False)])
def test_contact_phase_from_rest(tmp_path, caplog, name, flagged):
    """docs/coupling.md 'Coupling defect': at the shipped 0.1 ms step the mass-conserving film's contact
    phase has film-force spikes of kN on a 29 N load that the rotor never integrated; the monitor flags
    them (where it flags, the recorded film force is far from the typical one) and warns; the
    half-Sommerfeld film's contact phase has none."""
    from orchestrator import run as run_scenario
    sc = load_scenario(ROOT / "scenarios" / f"{name}.yaml", ["stop_time=0.01", "coupling.defect_retries=0",
                                                         CONSTANT])
    with caplog.at_level(logging.WARNING, logger="orchestrator.coupling.execution"):
        res = run_scenario(sc, out_dir=tmp_path, progress=False)
    assert res.success, res.message
    summary = json.loads((tmp_path / "summary.json").read_text())["coupling_defect"]
    assert summary["steps"] == 100 and set(summary["journals"]) == {"rotor.F_1", "rotor.F_2"}
    warned = [r.getMessage() for r in caplog.records if r.getMessage().startswith("coupling defect")]
    for jname, j in summary["journals"].items():
        assert j["unit"] == "N" and 20 < j["typical"] < 100, j  # about the weight share, 29.4 N (median)
        if not flagged:
            assert j["steps_over"] == 0 and j["max_defect"] < 0.5 * j["typical"]
            continue
        assert j["steps_over"] >= 5 and j["max_defect"] > 10 * j["typical"]
        i = int(np.argmin(np.abs(res.t - j["t_max_defect"])))
        F = math.hypot(res.outputs[f"bearing{jname[-1]}.Fx"][i], res.outputs[f"bearing{jname[-1]}.Fy"][i])
        assert F > 10 * j["typical"]                  # the spike is in the recorded film force
    assert bool(warned) == flagged


# --- rotorcosim plot marks the episodes in eccentricity.png -------------------------------------------
def _crimson_pixels(path) -> int:
    import matplotlib.image as mpimg
    img = mpimg.imread(path)[..., :3]
    r, g, b = img[..., 0], img[..., 1], img[..., 2]
    return int(np.sum((r - g > 0.3) & (np.abs(b - g) < 0.17)))      # crimson (0.86, 0.08, 0.24), also half on white


def test_plot_marks_the_episodes(tmp_path):
    from orchestrator.results.plots import plot_run
    from test_analysis import SPEC, whirl_vanishing, write_run
    counts = {}
    for case in ("none", "episodes", "tampered"):
        d = tmp_path / case
        d.mkdir()
        write_run(d, whirl_vanishing(), step=4)
        summary = {"scenario": "synthetic_run_up", "status": "finished", "analysis": {"spec": SPEC}}
        ep = [{"t_start": 0.4, "t_end": 0.45, "steps": 30, "max_defect": 900.0, "t_max_defect": 0.42},
              {"t_start": 0.9, "t_end": 0.9, "steps": 1, "max_defect": 60.0, "t_max_defect": 0.9}]
        if case == "tampered":
            ep = [{"t_start": "x"}, 5, {"t_start": 0.5, "t_end": 0.4, "t_max_defect": 0.45}] + ep[:1]
        if case != "none":
            summary["coupling_defect"] = {"journals": {"rotor.F_1": {"episode_count": 2, "episodes": ep}}}
        (d / "summary.json").write_text(json.dumps(summary))
        if case == "tampered":
            with pytest.warns(UserWarning, match="3 coupling_defect entries in summary.json are not of the form"):
                files = plot_run(d)
        else:
            files = plot_run(d)
        ecc = next(f for f in files if f.name == "eccentricity.png")
        counts[case] = _crimson_pixels(ecc)
    assert counts["none"] == 0
    assert counts["episodes"] > 40 and 20 < counts["tampered"] < counts["episodes"], counts   # the valid one drawn
    from orchestrator.results.plots.eccentricity import defect_episodes
    eps, n, problem = defect_episodes({"coupling_defect": {"journals": {"a": {"episode_count": 7, "episodes": [
        {"t_start": 1.0, "t_end": 2.0, "t_max_defect": 1.5}, {"t_start": 1.0, "t_end": 2.0, "t_max_defect": 3.0},
        {"t_start": float("nan"), "t_end": 2.0, "t_max_defect": 1.5}, "x"]}}}})
    assert eps == [(1.0, 2.0, 1.5)] and n == 7 and problem.startswith("3 coupling_defect entries")
    assert defect_episodes({"coupling_defect": []})[2].startswith("summary.json coupling_defect has no")
    assert defect_episodes({}) == ([], 0, None)


def test_defect_limit_key(tmp_path):
    """coupling.defect_limit: the multiple of the typical force above which a step is flagged (.inf: never);
    anything else is refused naming the key and the fix."""
    from orchestrator.errors import ScenarioError
    base = ROOT / "scenarios" / "jeffcott_runup_free_to_air_from_rest.yaml"
    assert load_scenario(base).coupling.defect_limit == 1.0
    assert load_scenario(base, ["coupling.defect_limit=50"]).coupling.defect_limit == 50.0
    assert load_scenario(base, ["coupling.defect_limit=.inf"]).coupling.defect_limit == math.inf
    for bad in ("-1", "0", "abc", "[1]"):
        with pytest.raises(ScenarioError, match=r"coupling.defect_limit.*(positive|finite number).*\.inf for never"):
            load_scenario(base, [f"coupling.defect_limit={bad}"])
    mon = DefectMonitor(NAMES, NAMES[:10], CONNS, k=0, limit=3.0)
    forces = np.full(30, 30.0)
    forces[10] = 100.0                # |d| = 70 at steps 10 and 11: below 3 x 30
    forces[20] = 130.0                # |d| = 100 at steps 20 and 21: above
    feed(mon, forces)
    st = mon.statistics()
    assert st["limit"] == 3.0 and st["journals"]["rotor.F_1"]["steps_over"] == 2
    assert "by more than 3x the signal's typical size (coupling.defect_limit)" in mon.note()
    off = DefectMonitor(NAMES, NAMES[:10], CONNS, k=0, limit=math.inf)
    feed(off, forces)
    assert off.note() is None and off.statistics()["journals"]["rotor.F_1"]["max_defect"] == 100.0


def test_start_up_steps_of_order_two_are_not_monitored():
    """k = 2 iterates the first step from saved states (no prediction integrated): left out and counted."""
    st = run(film(), k=2).stats["coupling_defect"]
    assert st["steps_not_monitored"] == 1 and st["steps"] == 199


def test_run_prints_one_line_on_the_defect():
    from orchestrator.cli.run import _defect_line
    cd = {"journals": {"rotor.F_1": {"unit": "N", "typical": 29.6, "max_defect": 2608.0, "t_max_defect": 0.0037,
                                     "steps_over": 44},
                       "rotor.F_2": {"unit": "N", "typical": 29.6, "max_defect": 100.0, "t_max_defect": 0.01,
                                     "steps_over": 3}}}
    assert _defect_line(cd) == ("coupling defect: largest 2608 N (88.1x the typical 29.6 N, rotor.F_1, t = 0.0037 s); "
                                "47 step(s) flagged, see the warning above")
    cd["journals"] = {"rotor.F_1": {"typical": 30.0, "max_defect": 0.96, "t_max_defect": 0.5, "steps_over": 0}}
    assert _defect_line(cd).endswith("(0.032x the typical 30, rotor.F_1, t = 0.5 s); no step flagged")
    assert _defect_line(None) is None and _defect_line({"journals": {"a": {"typical": 0}}}) is None


# --- coupling.defect_signals: any coupling input's prediction error (third-party FMUs) ---------------
def test_defect_signals_of_any_coupling():
    """Two masses coupled Jacobi with hold (k = 0): the consumer integrated y(T) over the step, the signal
    ended at y(T+H); d = y(T+H) - y(T) per step, from the recorded outputs, for a force and a position."""
    from test_master import two_mass_fakes, two_mass_scenario
    sc = two_mass_scenario("jacobi", 0.01, 0)
    sc = dataclasses.replace(sc, coupling=dataclasses.replace(sc.coupling, defect_signals=("left.F", "right.x*")),
                             output=OutputSpec(signals=("left.x1", "right.F")))
    res = MasterAlgorithm(sc, subsystems=two_mass_fakes()).run()
    assert res.success, res.message
    st = res.stats["coupling_defect"]
    assert set(st["journals"]) == {"left.F", "right.x1"} and st["steps"] == 50
    for name, col in (("left.F", "right.F"), ("right.x1", "left.x1")):
        y = res.outputs[col]
        d = np.abs(np.diff(y))
        j = st["journals"][name]
        assert j["max_defect"] == pytest.approx(d.max(), rel=1e-5)
        assert j["median_defect"] == pytest.approx(np.median(d), rel=1e-5)
        assert j["typical"] == pytest.approx(np.median(np.abs(y[1:])), rel=1e-5)


@pytest.mark.parametrize("signals, says", [
    (("right.z",), "'right.z' matches no coupling input that its consumer receives extrapolated"),
    (("right.x1",), "'right.x1' matches no coupling input"),          # Gauss-Seidel: interpolated
])
def test_defect_signals_that_match_nothing_are_refused(signals, says):
    from orchestrator.errors import ScenarioError
    from test_master import two_mass_fakes, two_mass_scenario
    sc = two_mass_scenario("gauss-seidel", 0.01, 0)
    sc = dataclasses.replace(sc, coupling=dataclasses.replace(sc.coupling, defect_signals=signals))
    with pytest.raises(ScenarioError, match=says):
        MasterAlgorithm(sc, subsystems=two_mass_fakes()).run()


def test_defect_signals_naming_the_monitored_forces_add_nothing():
    """A pattern that matches the interface-Jacobian forces (or their coefficients) is not refused: they
    are monitored per journal already; the kinematics the bearings receive are interpolated here."""
    sc = scenario()
    sc = dataclasses.replace(sc, coupling=dataclasses.replace(sc.coupling, defect_signals=("rotor.F*", "rotor.k*")))
    res = MasterAlgorithm(sc, subsystems={"rotor": IJJournal(), "bearing": film()}).run()
    assert res.success and list(res.stats["coupling_defect"]["journals"]) == ["rotor.F_1"]


def test_defect_signals_key_is_checked():
    from orchestrator.errors import ScenarioError
    base = ROOT / "scenarios" / "quickstart.yaml"
    assert load_scenario(base, ["coupling.defect_signals=[rotor.F*, bearing1.x]"]).coupling.defect_signals == (
        "rotor.F*", "bearing1.x")
    with pytest.raises(ScenarioError, match=r"coupling.defect_signals' must be a list"):
        load_scenario(base, ["coupling.defect_signals=5"])


# --- coupling.defect_retries: steps whose defect is over the limit are redone in halves ----------------
def _closed_form(t):
    """The journal on the linear film with its true coefficients (KF, CF) and the spring K0, released
    from x = 1 mm at rest (test_master_adaptive_scales.py): the exact answer of every coupling."""
    from test_master_adaptive_scales import K0, M
    w = math.sqrt((K0 + KF) / M - (CF / (2 * M)) ** 2)
    return 1e-3 * np.exp(-CF / (2 * M) * t) * (np.cos(w * t) + CF / (2 * M * w) * np.sin(w * t))


def _run_retries(limit, n, **kw):
    sc = scenario(**kw)
    sc = dataclasses.replace(sc, coupling=dataclasses.replace(sc.coupling, defect_limit=limit, defect_retries=n))
    res = MasterAlgorithm(sc, subsystems={"rotor": IJJournal(), "bearing": film(c_reported=CF / 2)}).run()
    assert res.success, res.message
    return res


def test_defect_retries_redo_the_steps_over_the_limit_and_converge_to_the_exact_answer():
    """The film reports half its damping, so every step has the known defect (CF/2) |dv|. With
    defect_retries, a step (or piece) whose defect is over the limit is redone from the saved states in
    halves: the rows stay on the macro grid, the pieces' defects shrink with h (largest 1.22 -> 0.61 ->
    0.32 at 0 / 1 / 2 halvings, as |dv| does), and the journal moves closer to the closed-form motion
    than at the constant step (an independent reference: the film's true coefficients)."""
    base = _run_retries(0.002, 0)
    err0 = np.abs(base.outputs["rotor.x_1"] - _closed_form(base.t)).max()
    errs, retried = [], []
    for n in (1, 2, 8):
        res = _run_retries(0.002, n)
        np.testing.assert_array_equal(res.t, base.t)                 # rows on the macro grid
        st = res.stats
        assert st["coupling_defect"]["steps"] == 200                 # one row per macro step
        assert st["defect_retried_steps"] == st["retried_steps"] > 0
        retried.append(st["retried_steps"])
        errs.append(np.abs(res.outputs["rotor.x_1"] - _closed_form(res.t)).max())
    assert errs[0] < 0.8 * err0 and errs[1] < errs[0] and errs[2] <= errs[1]
    assert retried[0] <= retried[1] <= retried[2]
    # the largest merged (weighted) defect falls with the depth allowed
    assert _run_retries(0.002, 8).stats["coupling_defect"]["journals"]["rotor.F_1"]["max_defect"] < \
        0.5 * base.stats["coupling_defect"]["journals"]["rotor.F_1"]["max_defect"]


def test_defect_retries_off_or_nothing_over_changes_nothing():
    """defect_retries 0, or a limit no step reaches: bit for bit the constant-step run."""
    base = _run_retries(1.0, 0)
    for limit, n in ((1.0, 4), (0.002, 0)):
        res = _run_retries(limit, n)
        np.testing.assert_array_equal(res.outputs["rotor.x_1"], base.outputs["rotor.x_1"])
        assert res.stats.get("defect_retried_steps", 0) == 0


def test_defect_retries_key(tmp_path):
    """coupling.defect_retries: an integer 0..30; refused with the error-controlled step, the iterative
    scheme and FMUs that cannot save their state, each naming the key and the fix."""
    from orchestrator.errors import ScenarioError
    base = ROOT / "scenarios" / "jeffcott_runup_free_to_air.yaml"
    assert load_scenario(base).coupling.defect_retries == 0
    assert load_scenario(base, ["coupling.defect_retries=4"]).coupling.defect_retries == 4
    assert load_scenario(ROOT / "scenarios" / "jeffcott_runup_free_to_air_from_rest.yaml").coupling.defect_retries == 4
    for bad in ("-1", "31", "1.5", "abc", "true"):
        with pytest.raises(ScenarioError, match=r"coupling.defect_retries.*e\.g\. 4"):
            load_scenario(base, [f"coupling.defect_retries={bad}"])
    with pytest.raises(ScenarioError, match=r"step_control type error and coupling.defect_retries cannot be "
                                            r"combined.*set defect_retries: 0"):
        load_scenario(base, ["coupling.defect_retries=4", "coupling.step_control.type=error"])
    with pytest.raises(ScenarioError, match=r"defect_retries.*iterative.*set defect_retries: 0"):
        load_scenario(base, ["coupling.defect_retries=4", "coupling.scheme=iterative"])
    stateless = film(c_reported=CF / 2)
    stateless.can_get_set_state = False
    s = scenario()
    s = dataclasses.replace(s, coupling=dataclasses.replace(s.coupling, defect_retries=2))
    with pytest.raises(ScenarioError, match=r"coupling.defect_retries = 2 needs every FMU to save.*'bearing'.*"
                                            r"set coupling.defect_retries: 0"):
        MasterAlgorithm(s, subsystems={"rotor": IJJournal(), "bearing": stateless}).setup()


def test_defect_retries_count_what_the_smallest_step_did_not_resolve():
    """A limit no piece can meet (1e-5 x the typical force) with one halving: every macro step is redone
    in two halves, both still over the limit; the monitor counts them, the warning and the CLI line say
    so, and every macro step stays one row."""
    from orchestrator.cli.run import _defect_line
    res = _run_retries(1e-5, 1)
    cd = res.stats["coupling_defect"]
    assert cd["retries"] == {"halvings": 1, "retried_steps": 200, "unresolved_steps": 200}
    assert cd["steps"] == 200 and res.stats["retry_substeps"] == 400
    mon = DefectMonitor(NAMES, NAMES[:10], CONNS, k=0)
    note = mon.note(cd)
    assert "coupling.defect_retries redid 200 macro step(s) in halves down to macro_step / 2^1" in note
    assert "200 still had a piece over the limit there" in note
    assert _defect_line(cd).endswith("; 200 step(s) redone in halves (coupling.defect_retries), 200 still over "
                                     "the limit at the smallest")
    # a summary read back may come from anyone: a malformed retries entry is left out, not a traceback
    assert "redone" not in _defect_line({**cd, "retries": {"retried_steps": "x"}})


def test_contact_phase_from_rest_with_defect_retries(tmp_path):
    """docs/coupling.md 'Redoing the steps over the limit': the same first 10 ms of the mass-conserving
    run-up from rest, with and without defect_retries 4. Redoing the flagged steps in halves lowers the
    recorded force spikes (measured 2637 / 3017 N -> 249 / 836 N; the error-controlled step, which
    resolves the phase, keeps them below 60 N), and summary.json counts the redone steps."""
    from orchestrator import run as run_scenario
    peaks = {}
    for n in (0, 4):
        sc = load_scenario(ROOT / "scenarios" / "jeffcott_runup_free_to_air_from_rest.yaml",
                           ["stop_time=0.01", f"coupling.defect_retries={n}", CONSTANT])
        res = run_scenario(sc, out_dir=tmp_path / str(n), progress=False)
        assert res.success, res.message
        np.testing.assert_allclose(res.t, np.linspace(0.0, 0.01, 101), atol=1e-15)
        peaks[n] = max(np.hypot(res.outputs[f"bearing{i}.Fx"], res.outputs[f"bearing{i}.Fy"]).max() for i in (1, 2))
        cd = json.loads((tmp_path / str(n) / "summary.json").read_text())["coupling_defect"]
        assert cd["steps"] == 100
        if n:
            r = cd["retries"]
            assert r["halvings"] == 4 and 0 < r["unresolved_steps"] <= r["retried_steps"] <= 100
        else:
            assert "retries" not in cd
    assert peaks[0] > 1000.0 and peaks[4] < 0.5 * peaks[0]


@pytest.mark.parametrize("scheme, k", [("gauss-seidel", 1), ("jacobi", 0), ("jacobi", 1)])
def test_defect_retries_with_other_schemes_and_orders(scheme, k):
    """The pieces extrapolate through the newest (uneven) history points, as discard retries do: with
    linear extrapolation, and under Jacobi (whose first piece keeps the lag of the previous macro step's
    feed, so it is counted as unresolved), the retried run is closer to the closed-form motion."""
    errs = []
    for n in (0, 6):
        sc = scenario(k=k, scheme=scheme)
        sc = dataclasses.replace(sc, coupling=dataclasses.replace(sc.coupling, defect_limit=0.002, defect_retries=n))
        res = MasterAlgorithm(sc, subsystems={"rotor": IJJournal(), "bearing": film(c_reported=CF / 2)}).run()
        assert res.success, res.message
        errs.append(np.abs(res.outputs["rotor.x_1"] - _closed_form(res.t)).max())
    assert errs[1] < 0.2 * errs[0]


@pytest.mark.parametrize("discard_retries", [0, 1])
def test_a_discard_inside_a_defect_retry(discard_retries):
    """A film that discards every step shorter than the macro step: inside a defect retry its discard
    ends the run as without retries (discard_retries 0: the FMU's own message) or after the discard
    halvings allowed (1: the halvings named); the rows computed before are kept."""
    from orchestrator.errors import FmuCallError

    class Picky(type(film())):
        def do_step(self, t, h):
            if h < 0.9 * H:
                raise FmuCallError("bearing", "fmi2DoStep", "discard", "step too short")
            super().do_step(t, h)

    bearing = film(c_reported=CF / 2)
    bearing.__class__ = Picky
    sc = scenario()
    sc = dataclasses.replace(sc, coupling=dataclasses.replace(sc.coupling, defect_limit=0.002, defect_retries=4,
                                                              discard_retries=discard_retries))
    res = MasterAlgorithm(sc, subsystems={"rotor": IJJournal(), "bearing": bearing}).run()
    assert not res.success and len(res.t) >= 1
    assert "fmi2DoStep returned discard" in res.message
    assert ("halving" in res.message) == bool(discard_retries)


def test_defect_retries_with_nothing_to_judge_warn_and_change_nothing(caplog):
    """A coupling with no interface-Jacobian forces and no defect_signals: defect_retries has nothing to
    judge; the run says so once and is the plain constant-step run, bit for bit; with defect_signals on
    the force it judges that input's prediction defect and redoes steps."""
    from test_master import global_error, two_mass_fakes, two_mass_scenario
    base = two_mass_scenario("jacobi", 1e-2, 0)
    plain = MasterAlgorithm(base, subsystems=two_mass_fakes()).run()
    sc = dataclasses.replace(base, coupling=dataclasses.replace(base.coupling, defect_retries=3))
    with caplog.at_level(logging.WARNING, logger="orchestrator.coupling.execution"):
        res = MasterAlgorithm(sc, subsystems=two_mass_fakes()).run()
    assert res.success and res.stats["retried_steps"] == 0
    np.testing.assert_array_equal(res.outputs["left.x1"], plain.outputs["left.x1"])
    assert any("coupling.defect_retries = 3 has nothing to judge" in r.getMessage() for r in caplog.records)
    sc = dataclasses.replace(base, coupling=dataclasses.replace(base.coupling, defect_retries=3, defect_limit=0.05,
                                                                defect_signals=("left.F",)))
    res = MasterAlgorithm(sc, subsystems=two_mass_fakes()).run()
    assert res.success and res.stats["defect_retried_steps"] > 0
    assert res.stats["coupling_defect"]["retries"]["halvings"] == 3
    assert global_error(res) < 0.5 * global_error(plain)          # against the exact two-mass motion (0.21 -> 0.08)
