"""FloatingRingBearing FMU (bearing_fmu/floating_ring_bearing.py) through the real FMU.

Built once per module with :func:`orchestrator.fmi.build.build_fmus`; run with FMPy directly
(variables, state round trip, agreement with the plain-Python model) and in the shipped
Jeffcott scenario where it replaces the two JournalBearing FMUs (through the master).
"""

from __future__ import annotations

import math
from dataclasses import replace
from pathlib import Path

import numpy as np
import pytest

from test_fmus import open_slave   # tests/ is on sys.path: works under `pytest` and `python -m pytest`

pytestmark = pytest.mark.integration

REPO = Path(__file__).resolve().parents[1]
SCENARIO = REPO / "scenarios" / "jeffcott_runup_floating_ring_half_sommerfeld.yaml"

FILM = ("R", "B", "psi", "eta0", "n_phi", "n_z", "cavitation", "axial_bc", "theta_transport", "groove_width",
        "groove_angle", "cav_width")


@pytest.fixture(scope="module")
def fmu(tmp_path_factory) -> Path:
    from orchestrator.fmi.build import build_fmus
    return build_fmus(tmp_path_factory.mktemp("fmus"), force=True, names=["FloatingRingBearing"])[0]


def test_variables_are_the_issue_names(fmu):
    from fmpy import read_model_description
    md = read_model_description(fmu)
    by = {}
    for v in md.modelVariables:
        by.setdefault(v.causality, set()).add(v.name)
    assert by["input"] == {"x", "y", "vx", "vy", "omega"}
    need_out = {"Fx", "Fy", "eps", "omega_ring", "x_ring", "y_ring", "eps_outer", "T_journal", "P_loss"}
    need_out |= {f"{k}{i}{j}" for k in "kc" for i in "xy" for j in "xy"}
    assert need_out <= by["output"]
    need_par = {f"{n}_{s}" for n in FILM for s in ("inner", "outer")} | {"m_ring", "J_ring", "floating"}
    assert need_par <= by["parameter"]
    units = {v.name: v.unit for v in md.modelVariables}
    assert (units["T_journal"], units["P_loss"], units["omega_ring"]) == ("N.m", "W", "rad/s")


def _setup(slave, vr, params, inputs):
    for name, value in params.items():
        if isinstance(value, int):
            slave.setInteger([vr[name]], [value])
        else:
            slave.setReal([vr[name]], [float(value)])
    slave.setupExperiment(startTime=0.0)
    slave.enterInitializationMode()
    slave.setReal([vr[n] for n in ("x", "y", "vx", "vy", "omega")], list(inputs))
    slave.exitInitializationMode()


OUT = ("Fx", "Fy", "eps", "omega_ring", "x_ring", "y_ring", "eps_outer", "T_journal", "P_loss",
       "kxx", "kxy", "cyx", "cyy")
OMEGA = 2 * math.pi * 100.0
JOURNAL = (1.7450588e-5, -1.7598543e-5, 0.0, 0.0, OMEGA)
PARAMS = dict(cavitation_inner=1, cavitation_outer=1, n_phi_inner=24, n_z_inner=8, n_phi_outer=24,
              n_z_outer=8, linearize=1, floating=1)


def test_fmu_matches_the_model_and_restores_its_state(fmu):
    """Three steps of the mass-conserving ring bearing through the FMU equal the
    plain-Python model bit for bit; get/set FMU state replays a step exactly."""
    from bearing_fmu.floating_ring import FloatingRing, RingParams
    from bearing_fmu.model import BearingParams
    with open_slave(fmu) as (slave, vr):
        _setup(slave, vr, PARAMS, JOURNAL)
        got = []
        for k in range(3):
            slave.doStep(k * 1e-4, 1e-4)
            got.append(slave.getReal([vr[n] for n in OUT]))
        state = slave.getFMUstate()
        slave.doStep(3e-4, 1e-4)
        after = slave.getReal([vr[n] for n in OUT])
        slave.setFMUstate(state)
        slave.doStep(3e-4, 1e-4)
        assert slave.getReal([vr[n] for n in OUT]) == after
        slave.freeFMUstate(state)
    films = {s: BearingParams(R=r, B=7.84e-3, psi=psi, eta0=0.012, n_phi=24, n_z=8, cavitation=1)
             for s, r, psi in (("inner", 4.9e-3, 2.8e-3), ("outer", 7.84e-3, 3.5e-3))}
    m = FloatingRing(RingParams(**films, m_ring=7.3e-3, J_ring=3.1e-7))
    m.initialize(*JOURNAL, ring="equilibrium")
    for k in range(3):
        m.step(1e-4, *JOURNAL)
        K, C = m.linearization()
        ref = [m.outputs[n] for n in OUT[:9]] + [K[0, 0], K[0, 1], C[1, 0], C[1, 1]]
        assert got[k] == pytest.approx(ref, rel=1e-12, abs=1e-30)


@pytest.mark.parametrize("name, value", [("theta_transport", 1), ("cav_width", 100.0)])
def test_film_options_reach_their_film(fmu, name, value):
    """``<name>_inner`` / ``<name>_outer`` through the FMU give the model with that option in that
    film only (theta_transport 1: the limited second-order theta transport; cav_width: the smooth
    theta(p) step), and not the model without it."""
    from bearing_fmu.floating_ring import FloatingRing, RingParams
    from bearing_fmu.model import BearingParams
    journal = (2.2e-5, -1.0e-5, 2e-3, -1e-3, OMEGA)      # off the equilibrium: the films move
    sides = (("inner", 4.9e-3, 2.8e-3), ("outer", 7.84e-3, 3.5e-3))

    def model(option_in=None):
        films = {s: BearingParams(R=r, B=7.84e-3, psi=psi, eta0=0.012, n_phi=24, n_z=8, cavitation=1,
                                  axial_bc=1, groove_width=0.3, **({name: value} if s == option_in else {}))
                 for s, r, psi in sides}
        m = FloatingRing(RingParams(**films, m_ring=7.3e-3, J_ring=3.1e-7))
        m.initialize(*journal, ring="equilibrium")
        for _ in range(3):
            m.step(1e-4, *journal)
        return [m.outputs[n] for n in OUT[:9]]

    without = model()
    for side, *_ in sides:
        params = dict(PARAMS, axial_bc_inner=1, axial_bc_outer=1, groove_width_inner=0.3,
                      groove_width_outer=0.3, **{f"{name}_{side}": value})
        with open_slave(fmu) as (slave, vr):
            _setup(slave, vr, params, journal)
            for k in range(3):
                slave.doStep(k * 1e-4, 1e-4)
            got = slave.getReal([vr[n] for n in OUT[:9]])
        assert got == pytest.approx(model(side), rel=1e-12, abs=1e-30)
        assert got != pytest.approx(without, rel=1e-9, abs=1e-30)


def test_journal_outside_the_clearance_is_a_discard(fmu):
    with open_slave(fmu) as (slave, vr):
        _setup(slave, vr, PARAMS, JOURNAL)
        slave.doStep(0.0, 1e-4)
        before = slave.getReal([vr[n] for n in OUT])
        slave.setReal([vr["y"]], [-1e-4])          # 7 inner clearances: through the ring
        with pytest.raises(Exception, match=r"status 2 \(discard\)"):
            slave.doStep(1e-4, 1e-4)
        assert slave.getReal([vr[n] for n in OUT]) == before


def test_replaces_journal_bearings_in_the_jeffcott_scenario(tmp_path):
    """The shipped scenario (two FloatingRingBearing FMUs on the Jeffcott rotor, coupled with
    their series coefficients), 5 ms from the static equilibrium at 100 Hz: the journals stay
    at their equilibrium to within 0.05 c_i, each bearing carries the static load 29.43 N on
    average, the rings spin at a fraction of the journal speed and lose power."""
    from orchestrator import load_scenario, run
    sc = load_scenario(SCENARIO)
    sc = replace(sc, stop_time=sc.start_time + 5e-3)
    res = run(sc, out_dir=tmp_path, progress=False)
    assert res.success, res.message
    out = {k: np.asarray(v) for k, v in res.outputs.items()}
    c_i = 1.372e-5
    for b, j in (("bearing1", "1"), ("bearing2", "2")):
        dx = out[f"rotor.x_{j}"] - 1.7450588e-5
        dy = out[f"rotor.y_{j}"] + 1.7598543e-5
        assert np.max(np.hypot(dx, dy)) < 0.05 * c_i
        ratio = out[f"{b}.omega_ring"] / out["rotor.omega"]
        assert np.all((ratio > 0.15) & (ratio < 0.4))
        assert np.all(out[f"{b}.P_loss"] > 0)
    assert np.mean(out["bearing1.Fy"]) == pytest.approx(29.43, rel=0.03)


def _check_turbocharger_start(tmp_path, scenario, load_rel):
    """Run 5 ms of a floating-ring turbocharger scenario from its start (30 Hz) and check each
    journal stays within 0.05 c_i of the floating-ring static equilibrium it starts at, each
    inner film carries its station's static load within ``load_rel`` and each ring keeps its
    torque-balance speed ratio; returns the outputs."""
    from orchestrator import load_scenario, run
    sc = load_scenario(REPO / "scenarios" / scenario)
    sc = replace(sc, stop_time=sc.start_time + 5e-3)
    res = run(sc, out_dir=tmp_path, progress=False)
    assert res.success, res.message
    out = {k: np.asarray(v) for k, v in res.outputs.items()}
    c_i = 1.372e-5
    starts = {"1": (1.14787e-5, -5.6143e-6), "2": (1.44178e-5, -3.37010e-5)}
    for b, j, load, ratio in (("bearing1", "1", 1.4886, 0.30), ("bearing2", "2", 57.372, 0.12)):
        x0, y0 = starts[j]
        assert np.max(np.hypot(out[f"rotor.x_{j}"] - x0, out[f"rotor.y_{j}"] - y0)) < 0.05 * c_i
        assert np.mean(out[f"{b}.Fy"]) == pytest.approx(load, rel=load_rel)
        assert np.mean(out[f"{b}.omega_ring"] / out["rotor.omega"]) == pytest.approx(ratio, abs=0.02)
    return out


def test_turbocharger_in_floating_rings_starts_at_its_equilibrium(tmp_path):
    """scenarios/turbocharger_runup_floating_ring_half_sommerfeld.yaml, 5 ms from t = 2 s (30 Hz):
    each journal stays within 0.05 c_i of the floating-ring static equilibrium it starts at
    (rotor_fmu.floating_ring_stability.operating_point), each inner film carries its station's
    static load (1.49 N, 57.37 N; rotor_fmu.stability.static_bearing_loads) and each ring keeps
    its torque-balance speed ratio (0.30 and 0.12)."""
    _check_turbocharger_start(tmp_path, "turbocharger_runup_floating_ring_half_sommerfeld.yaml",
                              load_rel=0.05)


def test_turbocharger_in_mass_conserving_floating_rings_starts_near_its_equilibrium(tmp_path):
    """scenarios/turbocharger_runup_floating_ring_free_to_air.yaml (mass-conserving films free to
    air, grooves, stationary initial films, started at the half-Sommerfeld equilibria; 160 x 40
    second-order films), 5 ms from t = 2 s (30 Hz): each journal stays within 0.05 c_i of its start
    (measured 0.031 / 0.037 c_i), each inner film carries its station's static load within 10 %
    while the mass-conserving films settle (measured 1.40 N of 1.49 N, 58.2 N of 57.37 N; with the
    earlier 40 x 40 first-order films 1.41 N and 58.2 N, and over 2.05-2.1 s 1.50 N and 57.39 N),
    the rings keep their torque-balance speed ratios (measured 0.304, 0.118) and the heavily loaded
    turbine-side ring stays inside its clearance (outer eps 0.969)."""
    out = _check_turbocharger_start(tmp_path, "turbocharger_runup_floating_ring_free_to_air.yaml",
                                    load_rel=0.10)
    for b in ("bearing1", "bearing2"):
        assert np.all(out[f"{b}.eps_outer"] < 0.99)


@pytest.mark.parametrize("scenario", ["turbocharger_runup_floating_ring_half_sommerfeld_seeded.yaml",
                                      "turbocharger_runup_floating_ring_free_to_air_seeded.yaml"])
def test_seeded_turbocharger_in_floating_rings_starts_at_its_seed(tmp_path, scenario):
    """The seeded credibility scenarios start on the ramp at the speed their start time gives
    (34 Hz, below the linear threshold 42.19 Hz) with the compressor-side journal 0.02 c_i in +x
    off its floating-ring static equilibrium there, the turbine-side journal and both rings at
    theirs and the rings at their torque-balance speeds, all recomputed here from
    rotor_fmu.floating_ring_stability.operating_point; over 5 ms the turbine-side journal stays
    within 0.05 c_i of its start and the seeded journal, with half-Sommerfeld films, moves back
    towards its equilibrium; the mass-conserving films start stationary at the HS equilibria and
    settle, which moves it further off at first, within 0.05 c_i (measured after 5 ms, mass-conserving
    160 x 40 second-order films of the scenario: seeded journal 0.033 c_i off, turbine-side journal
    at most 0.044 c_i; with 40 x 40 first-order films 0.026 and 0.036 c_i)."""
    from orchestrator import load_scenario, run
    from rotor_fmu.floating_ring_growth import turbocharger_floating_ring
    from rotor_fmu.floating_ring_stability import operating_point
    from rotor_fmu.stability import static_bearing_loads
    sc = load_scenario(REPO / "scenarios" / scenario)
    rp = sc.fmu("rotor").parameters
    omega = 2 * math.pi * rp["f_max"] * sc.start_time / rp["t_ramp"]
    assert omega / (2 * math.pi) == pytest.approx(34.0, abs=1e-4)
    rotor, rings = turbocharger_floating_ring()
    c_i = 1.372e-5
    ops = [operating_point(p, float(-ld[1]), omega) for p, ld in zip(rings, static_bearing_loads(rotor))]
    (x1, y1), (x2, y2) = (op._journal[:2] for op in ops)
    assert rp["journal_x0"] == pytest.approx(x1 + 0.02 * c_i, abs=1e-3 * c_i)
    assert rp["journal_y0"] == pytest.approx(y1, abs=1e-3 * c_i)
    assert rp["journal_x0"] + rp["journal_dx0_2"] == pytest.approx(x2, abs=1e-3 * c_i)
    assert rp["journal_y0"] + rp["journal_dy0_2"] == pytest.approx(y2, abs=1e-3 * c_i)
    for k, op in ((1, ops[0]), (2, ops[1])):
        bp = sc.fmu(f"bearing{k}").parameters
        assert bp["omega_ring0"] == pytest.approx(op.outputs["omega_ring"], rel=1e-4)
        assert bp["x_ring0"] == pytest.approx(op.outputs["x_ring"], abs=1e-3 * c_i)
        assert bp["y_ring0"] == pytest.approx(op.outputs["y_ring"], abs=1e-3 * c_i)
    res = run(replace(sc, stop_time=sc.start_time + 5e-3), out_dir=tmp_path, progress=False)
    assert res.success, res.message
    out = {k: np.asarray(v) for k, v in res.outputs.items()}
    d1 = np.hypot(out["rotor.x_1"] - x1, out["rotor.y_1"] - y1)
    assert d1[0] == pytest.approx(0.02 * c_i, rel=0.02)
    if "half_sommerfeld" in scenario:
        assert d1[-1] < d1[0]
    assert np.max(d1) < 0.05 * c_i
    assert np.max(np.hypot(out["rotor.x_2"] - x2, out["rotor.y_2"] - y2)) < 0.05 * c_i
