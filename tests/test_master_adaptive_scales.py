"""Per-signal atol and the interface-Jacobian error estimate of the error-controlled step
(orchestrator/coupling/signal_scales.py), with known answers."""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import pytest
from scipy.linalg import expm

from orchestrator.coupling.error_control import scaled_error_norm
from orchestrator.coupling.execution import MasterAlgorithm
from orchestrator.coupling.signal_scales import atol_vector, corrected_prediction, jacobian_groups
from orchestrator.errors import ScenarioError
from orchestrator.scenario import ConnectionSpec, CouplingSpec, FmuSpec, OutputSpec, Scenario, load_scenario
from orchestrator.scenario.model import StepControlSpec
from test_master import LinearFake

ROOT = Path(__file__).resolve().parents[1]
SEEDED = ROOT / "scenarios" / "jeffcott_runup_half_sommerfeld_seeded.yaml"


def test_atol_vector_exact_name_then_first_pattern_then_default():
    names = ["rotor.Fx_1", "rotor.Fy_1", "bearing1.x", "rotor.kxx_1"]
    np.testing.assert_array_equal(atol_vector(1e-3, names), [1e-3] * 4)
    v = atol_vector((("rotor.F*", 0.5), ("rotor.Fy_1", 2.0), ("bearing*", math.inf), ("bearing1.x", 3.0)), names)
    # Fx_1: the first pattern; Fy_1 and bearing1.x: their exact name beats any pattern; kxx_1
    # matches nothing: the default
    np.testing.assert_array_equal(v, [0.5, 2.0, 3.0, 1e-8])
    # a producer's name (bearing1.Fx feeds rotor.Fx_1) is not a signal name
    np.testing.assert_array_equal(atol_vector((("bearing1.*", math.inf),), names), [1e-8, 1e-8, math.inf, 1e-8])


def test_infinite_atol_leaves_a_signal_out_of_the_mean():
    pred, act, prev = np.zeros(3), np.array([1.0, 1.0, 100.0]), np.zeros(3)
    err, worst = scaled_error_norm(pred, act, prev, rtol=0.0, atol=np.array([1.0, 1.0, math.inf]))
    assert err == pytest.approx(1.0) and worst in (0, 1)
    err, _ = scaled_error_norm(pred, np.array([1.0, np.nan, 0.0]), prev, rtol=0.0,
                               atol=np.array([1.0, math.inf, 1.0]))
    assert err == math.inf                                   # a NaN is never hidden by atol = inf


def test_jacobian_groups_of_the_seeded_runup():
    sc = load_scenario(SEEDED)
    names = [c.dst for c in sc.connections]
    groups = jacobian_groups(names, sc.connections)
    assert sorted(names[j] for j, _ in groups) == ["rotor.Fx_1", "rotor.Fx_2", "rotor.Fy_1", "rotor.Fy_2"]
    j, terms = next(g for g in groups if names[g[0]] == "rotor.Fy_2")
    assert [(names[k], names[u]) for k, u, _ in terms] == [
        ("rotor.kyx_2", "bearing2.x"), ("rotor.kyy_2", "bearing2.y"),
        ("rotor.cyx_2", "bearing2.vx"), ("rotor.cyy_2", "bearing2.vy")]


def test_corrected_prediction_known_answers():
    """Columns: F, k, x (gain 2 from the rotor's output). A force linear in x with the
    coefficient k = -dF/dx has defect 0; F = -k x - a x^2 has defect -a dx^2."""
    k, a, x0, x1 = 300.0, 5.0e4, 1.0e-3, 1.4e-3
    groups = [(0, [(1, 2, 0.5)])]
    for force, defect in ((lambda x: -k * x, 0.0), (lambda x: -k * x - a * x * x, -a * (x1 - x0) ** 2)):
        kx = k + 2 * a * x0 if defect else k                  # -dF/dx at x0
        prev = np.array([force(x0), kx, 2 * x0])
        new = np.array([force(x1), kx, 2 * x1])
        pred = prev.copy()                                    # hold (k = 0)
        used = corrected_prediction(pred, new, prev, groups)
        assert new[0] - used[0] == pytest.approx(defect, rel=1e-9, abs=1e-15)
        assert abs(new[0] - pred[0]) > 10 * abs(defect) + 1e-3    # the raw prediction error is first order


# --- end to end: a journal on a linear film, interface-Jacobian coupling (known answer: exact) --
M, K0, KF, CF = 0.5, 4.0e3, 2.0e5, 60.0
IJ_IN = ["Fx_1", "Fy_1"] + [f"{c}{a}{b}_1" for c in "kc" for a in "xy" for b in "xy"]


class IJJournal(LinearFake):
    """A journal of mass M on a spring K0 that applies F_in - K (q - q(T)) - C (v - v(T)) over
    each step (the interface-Jacobian rotor, docs/stiff-coupling.md), integrated exactly."""

    def __init__(self):
        super().__init__("rotor", np.zeros((4, 4)), np.zeros((4, len(IJ_IN))), np.eye(4),
                         np.zeros((4, len(IJ_IN))), [1e-3, 0, 0, 0], IJ_IN, ["x_1", "y_1", "vx_1", "vy_1"],
                         interpolate=False)

    def do_step(self, t, h):
        self.calls["doStep"] += 1
        F, K, C = self.u[:2], self.u[2:6].reshape(2, 2), self.u[6:10].reshape(2, 2)
        q, v = self.x[:2], self.x[2:]
        A = np.zeros((5, 5))
        A[:2, 2:4] = np.eye(2)
        A[2:4, :2] = -(K0 * np.eye(2) + K) / M
        A[2:4, 2:4] = -C / M
        A[2:4, 4] = (F + K @ q + C @ v) / M
        self.x = (expm(A * h) @ np.concatenate([self.x, [1.0]]))[:4]


def film(k_reported=KF, c_reported=CF):
    """F = -KF q - CF v, and the coefficients kxx = kyy = k_reported, cxx = cyy = c_reported (a constant
    state 1; by default the film's own, KF and CF)."""
    C = np.zeros((10, 1))
    C[[2, 5], 0], C[[6, 9], 0] = k_reported, c_reported
    D = np.zeros((10, 4))
    D[0, 0], D[1, 1], D[0, 2], D[1, 3] = -KF, -KF, -CF, -CF
    return LinearFake("bearing", [[0.0]], np.zeros((1, 4)), C, D, [1.0], ["x", "y", "vx", "vy"],
                      ["Fx", "Fy", "kxx", "kxy", "kyx", "kyy", "cxx", "cxy", "cyx", "cyy"], interpolate=False)


def ij_scenario(control):
    conns = [ConnectionSpec(src=f"rotor.{a}_1", dst=f"bearing.{b}") for a, b in
             (("x", "x"), ("y", "y"), ("vx", "vx"), ("vy", "vy"))]
    conns += [ConnectionSpec(src=f"bearing.{n.removesuffix('_1')}", dst=f"rotor.{n}") for n in IJ_IN]
    return Scenario(name="ij-journal", stop_time=0.05,
                    fmus=(FmuSpec(name="rotor", path=Path("rotor")), FmuSpec(name="bearing", path=Path("bearing"))),
                    connections=tuple(conns),
                    coupling=CouplingSpec(scheme="gauss-seidel", sequence=("rotor", "bearing"), macro_step=1e-5,
                                          step_control=control),
                    output=OutputSpec(interval=2.5e-3, signals=("rotor.x_1", "bearing.Fx")))


@pytest.mark.parametrize("ij", [True, False])
def test_interface_jacobian_estimate_on_a_linear_film(ij):
    """Interface-Jacobian Gauss-Seidel on a linear film is exact for any step, so the estimate
    with the correction is ~0 and the step grows to max_step (the output interval); the raw
    prediction error of F needs many more steps for nothing. Both are exact."""
    spec = StepControlSpec(type="error", rtol=1e-2, atol=(("bearing.*", math.inf), ("*", 1.0)),
                           interface_jacobian=ij)
    res = MasterAlgorithm(ij_scenario(spec), subsystems={"rotor": IJJournal(), "bearing": film()}).run()
    assert res.success, res.message
    w = math.sqrt((K0 + KF) / M - (CF / (2 * M)) ** 2)
    ref = 1e-3 * np.exp(-CF / (2 * M) * res.t) * (np.cos(w * res.t) + CF / (2 * M * w) * np.sin(w * res.t))
    assert np.abs(res.outputs["rotor.x_1"] - ref).max() < 1e-9 * 1e-3
    st = res.stats["step_control"]
    if ij:
        assert st["interface_jacobian"] == ["rotor.Fx_1", "rotor.Fy_1"]
        assert st["rejected_steps"] == 0 and st["accepted_steps"] <= 20 + 5   # 20 intervals, start-up growth
    else:
        assert st["interface_jacobian"] == [] and st["accepted_steps"] > 200


def _load(tmp_path, step_control: str):
    text = SEEDED.read_text().replace("  extrapolation_order: 0\n", f"  extrapolation_order: 0\n  step_control: {step_control}\n")
    p = tmp_path / "s.yaml"
    p.write_text(text)
    return p, load_scenario(p)


def test_loader_reads_an_atol_mapping(tmp_path):
    _, sc = _load(tmp_path, '{type: error, atol: {"rotor.F*": 0.3, "bearing*.*": .inf, rotor.kxx_1: 1.0}}')
    assert sc.coupling.step_control.atol == (("rotor.F*", 0.3), ("bearing*.*", math.inf), ("rotor.kxx_1", 1.0))
    assert sc.coupling.step_control.interface_jacobian is True


@pytest.mark.parametrize("sc, says", [
    ('{type: error, atol: {"rotor.Fz*": 0.3}}', ["key 'rotor.Fz*' matches no coupling signal", "did you mean"]),
    ('{type: error, atol: {rotor.Fx_1: -1}}', ["'coupling.step_control.atol.rotor.Fx_1' must be positive"]),
    ('{type: error, atol: {}}', ["empty mapping"]),
    ('{type: error, interface_jacobian: 2}', ["'coupling.step_control.interface_jacobian' must be true or false"]),
    ('{type: error, atl: 1}', ["unknown key 'atl'", "did you mean 'atol'"]),
])
def test_loader_names_the_line_and_the_fix(tmp_path, sc, says):
    with pytest.raises(ScenarioError) as ei:
        _load(tmp_path, sc)
    msg = str(ei.value)
    line = next(i for i, t in enumerate(_load.__globals__["SEEDED"].read_text().splitlines(), 1)
                if t.startswith("  extrapolation_order")) + 1
    assert f"s.yaml:{line}" in msg, msg
    for s in says:
        assert s in msg, msg


def test_atol_mapping_given_as_a_dict_keeps_its_order():
    """compare files' `set:` and the Python API give a dict; it becomes the same tuple."""
    spec = StepControlSpec(type="error", atol={"rotor.F*": 0.3, "bearing*.*": math.inf})
    assert spec.atol == (("rotor.F*", 0.3), ("bearing*.*", math.inf))
    np.testing.assert_array_equal(atol_vector(spec.atol, ["rotor.Fx_1", "bearing1.x"]), [0.3, math.inf])


def test_the_interface_jacobian_estimate_with_held_forces_is_of_order_two():
    """ij_order_of (adaptive.py): with k = 0 and only interface-Jacobian forces in the norm the PI
    controller uses p = 2 (the linearisation's remainder, measured 1.95 on the seeded run-up),
    p = 3 with measure impulse; with another signal in the norm, or k = 1, p stays k + 1."""
    import dataclasses
    from orchestrator.coupling.adaptive import controller_from_spec
    sc = load_scenario(SEEDED)
    names = [c.dst for c in sc.connections]
    only_forces = (("rotor.F*", 0.03), ("bearing*.*", math.inf))

    def order(k=0, atol=only_forces, measure="value"):
        c = dataclasses.replace(sc.coupling, extrapolation_order=k, step_control=StepControlSpec(
            type="error", rtol=1e-3, atol=atol, measure=measure))
        ctl = controller_from_spec(dataclasses.replace(sc, coupling=c))
        ctl.bind(names, sc.connections)
        return ctl.pi.p

    assert order() == 2
    assert order(measure="impulse") == 3
    assert order(atol=(("rotor.F*", 0.03),)) == 1          # the bearings' inputs count: raw order k + 1
    assert order(k=1) == 2


class _Pair:
    """A stepper stand-in for ``ErrorControlled.error``: the step's predicted and actual signals."""

    def __init__(self, pred, actual):
        self.pair = (np.asarray(pred, float), np.asarray(actual, float))
        self.history = None

    def error_signals(self):
        return self.pair


def test_a_force_vector_is_judged_by_its_length_in_any_frame():
    """The running-scale atol of an interface-Jacobian force's components is rtol x the vector's
    length (signal_scales.force_vectors), so the error test does not depend on how the frame
    is turned against the load. Known answer: a journal carrying 30 N along y with 0.3 N
    across it (a bearing at rest on its shell), the same defect of 0.5 N across the load,
    the frame turned by 0 ... 90 deg. The scale of each component is between rtol |F| and
    2 rtol |F| (atol plus the relative term), so the error may vary by 2x at most; with a
    scale per component (before) it was 31x larger in the frame where the defect lay along
    the 0.3 N component than where it lay along the 30 N one."""
    from orchestrator.coupling.adaptive import ErrorControlled
    from orchestrator.coupling.signal_scales import force_vectors

    conns = ij_scenario(None).connections
    names = [c.dst for c in conns]
    ctl = ErrorControlled(StepControlSpec(type="error", rtol=0.1), t0=0.0, t_stop=1.0, h0=1e-4,
                          interval=1e-3, order=1)
    ctl.bind(names, conns)
    jx, jy = names.index("rotor.Fx_1"), names.index("rotor.Fy_1")
    assert force_vectors(names, [jx, jy], np.ones(len(names), bool)).tolist() == [[jx], [jy]]
    errs = []
    for a in np.radians([0.0, 30.0, 60.0, 89.0, 90.0]):
        rot = np.array([[math.cos(a), -math.sin(a)], [math.sin(a), math.cos(a)]])
        prev = np.zeros(len(names))
        prev[[jx, jy]] = rot @ [0.3, 30.0]
        actual = prev.copy()
        actual[[jx, jy]] += rot @ [0.5, 0.0]              # the defect, across the load
        err, worst = ctl.error(_Pair(prev, actual), prev, prev)
        errs.append(err)
        assert worst in (jx, jy)
    assert max(errs) / min(errs) < 2.0, errs
    # the size of the answer at 0 deg: 0.5 N against atol rtol |F| plus rtol x 0.8 N (the component
    # after the defect), one signal of the mean over those in the norm
    n = int(np.count_nonzero(np.isfinite(ctl.atol)))
    assert errs[0] == pytest.approx(0.5 / (0.1 * math.hypot(0.3, 30.0) + 0.1 * 0.8) / math.sqrt(n), rel=1e-6)


def test_the_step_limited_by_an_interface_jacobian_force_is_controlled_at_its_order():
    """With first-order kinematics in the norm the controller's p is 1 (k + 1, hold); a step whose
    largest error is an interface-Jacobian force is decided at that force's order (2,
    ij_order_of), any other at p; with only the forces in the norm p is already 2."""
    from orchestrator.coupling.adaptive import ErrorControlled

    conns = ij_scenario(None).connections
    names = [c.dst for c in conns]
    ctl = ErrorControlled(StepControlSpec(type="error", rtol=0.1), t0=0.0, t_stop=1.0, h0=1e-4,
                          interval=1e-3, order=1, ij_order=2)
    ctl.bind(names, conns)
    assert ctl.pi.p == 1
    assert ctl._order_of(names.index("rotor.Fy_1")) == 2
    assert ctl._order_of(names.index("bearing.vx")) is None
    only = ErrorControlled(StepControlSpec(type="error", rtol=0.1, atol=(("bearing.*", math.inf),)), t0=0.0,
                           t_stop=1.0, h0=1e-4, interval=1e-3, order=1, ij_order=2)
    only.bind(names, conns)
    assert only.pi.p == 2 and only._order_of(names.index("rotor.Fy_1")) is None
