"""Every scenario in scenarios/ loads (FMUs, connections, parameters checked by the
loader) and states the paper's case; short slices of the cheap ones run.

Loading builds our FMUs into the repository's fmus/ folder when they are missing or
stale (orchestrator.fmi.build.ensure_fmus), as `rotorcosim run` does on a fresh clone.
"""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import pytest

pytestmark = pytest.mark.integration

SCENARIOS = Path(__file__).resolve().parents[1] / "scenarios"
FILES = sorted(SCENARIOS.glob("*.yaml"))
EXPECTED = {
    "stationary_oil_bath", "stationary_free_to_air", "jeffcott_runup_half_sommerfeld",
    "jeffcott_runup_oil_bath", "jeffcott_runup_free_to_air", "turbocharger_runup_half_sommerfeld",
    "turbocharger_runup_oil_bath", "turbocharger_runup_free_to_air", "quickstart",
}
CAVITATION = {"half_sommerfeld": (0, 0), "oil_bath": (1, 0), "free_to_air": (1, 1)}


def test_all_paper_scenarios_are_shipped():
    assert EXPECTED <= {f.stem for f in FILES}


@pytest.fixture(scope="module")
def loaded():
    from orchestrator import load_scenario
    return {f.stem: load_scenario(f) for f in FILES}


@pytest.mark.parametrize("path", FILES, ids=[f.stem for f in FILES])
def test_scenario_loads(loaded, path):
    sc = loaded[path.stem]
    assert sc.name == path.stem
    assert sc.stop_time > sc.start_time
    for spec in sc.fmus:
        assert spec.path.is_file(), spec.path


@pytest.mark.parametrize("name", sorted(n for n in EXPECTED if "runup" in n))
def test_runups_are_the_papers(loaded, name):
    sc = loaded[name]
    rotor = sc.fmu("rotor").parameters
    if name.startswith("jeffcott"):
        assert (rotor["f_max"], rotor["t_ramp"], rotor["d_external"]) == (800.0, 2.0, 500.0)
        assert rotor["m_disc"] + 2 * rotor["m_journal"] == pytest.approx(6.0)
    else:
        assert (rotor["f_max"], rotor["t_ramp"]) == (105.0, 7.0)
    assert sc.stop_time == rotor["t_ramp"]
    kind = name.split("_runup_")[1]
    for b in ("bearing1", "bearing2"):
        p = sc.fmu(b).parameters
        assert (p["cavitation"], p["axial_bc"]) == CAVITATION[kind]
        assert p["B"] == pytest.approx(1.6 * p["R"]) and p["psi"] == 2.8e-3 and p["eta0"] == 0.012
        assert (p["n_phi"], p["n_z"]) == (40, 40) and p["p0"] == p["p_feed"] == 1.0e5
        if kind == "free_to_air":      # feed groove at the top of the shell, 15 deg
            assert p["groove_width"] == pytest.approx(math.radians(15.0))
            assert p["groove_angle"] == pytest.approx(math.pi / 2)
        clearance = sc.analysis["journals"][b]["clearance"]
        assert clearance == pytest.approx(p["psi"] * p["R"], rel=1e-3)
    assert sc.analysis["speed"] == "rotor.omega"


@pytest.mark.parametrize("name", ["stationary_oil_bath", "stationary_free_to_air"])
def test_stationary_cases_are_the_papers(loaded, name):
    p = loaded[name].fmu("bearing").parameters
    c = p["psi"] * p["R"]
    assert math.hypot(p["x"], p["y"]) / c == pytest.approx(0.7, rel=1e-3)
    assert p["x"] < 0 and p["y"] == 0.0                      # minimum gap at phi = pi
    assert p["omega"] == pytest.approx(2 * math.pi * 100.0)
    assert p["fields_file"] == "{out_dir}/bearing_fields.npz"
    assert p["axial_bc"] == (1 if "free_to_air" in name else 0)


def test_stationary_free_to_air_slice_runs_and_writes_fields(loaded, tmp_path):
    from dataclasses import replace
    from orchestrator import run
    sc = replace(loaded["stationary_free_to_air"], stop_time=3e-4)
    res = run(sc, out_dir=tmp_path, progress=False)
    assert res.success, res.message
    fields = np.load(tmp_path / "bearing_fields.npz")
    p, theta = fields["p"], fields["theta"]
    assert p.shape == (40, 40) and p.max() > 10 * 1e5          # a loaded film (MPa peak)
    assert theta.min() < 0.9                                   # and a cavity
    fy = np.asarray(res.outputs["bearing.Fy"])
    assert np.ptp(fy) <= 1e-6 * np.max(np.abs(fy))             # steady film stays steady


def test_quickstart_slice_runs(loaded, tmp_path):
    from dataclasses import replace
    from orchestrator import run
    sc = loaded["quickstart"]
    sc = replace(sc, stop_time=sc.start_time + 2e-3)
    res = run(sc, out_dir=tmp_path, progress=False)
    assert res.success, res.message
    y1 = np.asarray(res.outputs["rotor.y_1"])
    assert y1[-1] < 0.0                                         # the journals start to sink
    assert np.all(np.asarray(res.outputs["bearing1.eps"]) < 1.0)


def test_turbocharger_runups_start_at_the_journal_equilibria(loaded, tmp_path):
    """The turbocharger run-ups start each journal at its own HS static equilibrium
    (bearing1 eps 0.083, bearing2 eps 0.803 at 30 Hz; journal_dx0_2/dy0_2 shift station 2):
    over the first 5 ms of the HS run-up neither journal moves by more than 1 % of the
    clearance (from a common start position they would move by tens of %)."""
    from dataclasses import replace
    from orchestrator import run
    for name in ("turbocharger_runup_oil_bath", "turbocharger_runup_free_to_air"):
        assert loaded[name].fmu("rotor").parameters == loaded["turbocharger_runup_half_sommerfeld"].fmu("rotor").parameters
        assert loaded[name].start_time == loaded["turbocharger_runup_half_sommerfeld"].start_time
    sc = loaded["turbocharger_runup_half_sommerfeld"]
    sc = replace(sc, stop_time=sc.start_time + 5e-3)
    res = run(sc, out_dir=tmp_path, progress=False)
    assert res.success, res.message
    c = sc.analysis["journals"]["bearing1"]["clearance"]
    for j, eps0 in ((1, 0.083), (2, 0.803)):
        x, y = (np.asarray(res.outputs[f"rotor.{k}_{j}"]) for k in "xy")
        assert math.hypot(x[0], y[0]) / c == pytest.approx(eps0, abs=2e-3)
        assert np.max(np.hypot(x - x[0], y - y[0])) < 0.01 * c


def _half_unit(v: float) -> float:
    """Half a unit in the last digit of ``v`` as the scenario writes it (the shortest repr of the
    float read from YAML gives those digits; a written trailing zero is lost, which only widens it)."""
    mant, _, exp = repr(float(v)).lower().partition("e")
    return 0.5 * 10.0 ** ((int(exp) if exp else 0) - len(mant.partition(".")[2]))


# scenario -> the start's offset of station 1 from its static equilibrium, in +x [c]; the other
# variants of each run-up (free to air, oil bath) start where its half-Sommerfeld scenario does
STATIC_STARTS = {"jeffcott_runup_half_sommerfeld": 0.0, "turbocharger_runup_half_sommerfeld": 0.0,
                 "jeffcott_runup_half_sommerfeld_seeded": 0.02, "turbocharger_runup_half_sommerfeld_seeded": 0.02,
                 "quickstart": 0.04}


@pytest.mark.parametrize("name", sorted(STATIC_STARTS))
def test_runups_start_at_todays_static_equilibrium(loaded, name):
    """The starts written as static equilibria (docs/runups.md, docs/rotor-models.md) are those of
    today's film: each journal's half-Sommerfeld equilibrium under its static load on the scenario's
    own film at the start speed (bearing_fmu.linearize.hs_static_equilibrium, what
    docs/turbocharger_threshold.py --equilibrium-hz and docs/paper_cases_radius.py print), plus the
    seed, to the digits written. Until 2026-12-07 the turbocharger scenarios started bearing 2 at the
    equilibrium of the force quadrature before 39f4995, 1.9e-9 m (1.4e-4 c, 19 half-units of the
    last digit) away."""
    from bearing_fmu.linearize import hs_static_equilibrium
    from bearing_fmu.model import BearingModel
    from orchestrator.stability import build_system
    from rotor_fmu.stability import static_bearing_loads
    sc = loaded[name]
    p = sc.fmu("rotor").parameters
    omega = 2 * math.pi * p["f_max"] * min(sc.start_time, p["t_ramp"]) / p["t_ramp"]
    x1, y1 = p["journal_x0"], p["journal_y0"]
    starts = [(x1, y1, _half_unit(x1), _half_unit(y1))]
    seeded = [STATIC_STARTS[name], 0.0]
    if "journal_dx0_2" in p:          # turbocharger: station 2 = station 1 + (dx0_2, dy0_2), at its equilibrium
        dx, dy = p["journal_dx0_2"], p["journal_dy0_2"]
        starts.append((x1 + dx, y1 + dy, _half_unit(x1) + _half_unit(dx), _half_unit(y1) + _half_unit(dy)))
    else:                             # Jeffcott: both journals at (journal_x0, journal_y0), both seeded
        starts.append(starts[0])
        seeded[1] = seeded[0]
    system = build_system(sc)
    for j, (b, load, (x, y, tol_x, tol_y)) in enumerate(zip(system.bearings, static_bearing_loads(system.rotor),
                                                            starts)):
        m = BearingModel(b.params)
        m.initialize(0.0, -0.5 * m.c, 0.0, 0.0, 1.0)
        q = hs_static_equilibrium(m, -np.asarray(load, float), omega)
        q = q + np.array([seeded[j] * m.c, 0.0])
        assert abs(x - q[0]) <= tol_x + 1e-13 and abs(y - q[1]) <= tol_y + 1e-13, (b.instance, (x, y), q.tolist())
    for variant in ("free_to_air", "oil_bath"):     # the seeded variants start off their own films' equilibria
        other = name.replace("half_sommerfeld", variant)
        if other != name and other in loaded and not name.endswith("_seeded"):
            assert loaded[other].start_time == sc.start_time
            for k in ("journal_x0", "journal_y0", "journal_dx0_2", "journal_dy0_2"):
                assert loaded[other].fmu("rotor").parameters.get(k) == p.get(k), (other, k)
