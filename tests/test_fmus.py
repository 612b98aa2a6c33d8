"""Integration tests of our own FMUs (JournalBearing, JeffcottRotor, TurbochargerRotor).

The FMUs are built once per session (``built_fmus``) with
:func:`orchestrator.fmi.build.build_fmus` into a temporary folder and loaded with
FMPy. Every instance is freed explicitly (PythonFMU instances left to the
garbage collector have aborted processes at exit).
"""

from __future__ import annotations

import json
import math
import zipfile
from contextlib import contextmanager
from pathlib import Path

import numpy as np
import pytest

pytestmark = pytest.mark.integration

NAMES = ("JournalBearing", "JeffcottRotor", "TurbochargerRotor")
PSI, R_TEST = 2.8e-3, 0.02


def _available(name: str) -> bool:
    """Whether the model that FMU ``name`` wraps is in this checkout (it is bundled from here)."""
    from orchestrator.fmi.build import REPO
    module = {"JournalBearing": "bearing_fmu/model.py", "JeffcottRotor": "rotor_fmu/jeffcott.py",
              "TurbochargerRotor": "rotor_fmu/turbocharger.py"}[name]
    return (REPO / module).is_file()


@pytest.fixture(scope="session")
def built_fmus(tmp_path_factory) -> dict[str, Path]:
    from orchestrator.fmi.build import build_fmus
    out = tmp_path_factory.mktemp("fmus")
    names = [n for n in NAMES if _available(n)]
    return {p.stem: p for p in build_fmus(out, force=True, names=names)}


def _fmu(built_fmus, name):
    if name not in built_fmus:
        pytest.skip(f"model of {name} not available yet")
    return built_fmus[name]


@contextmanager
def open_slave(path: Path, instance: str = "inst"):
    """Instantiate a co-simulation slave with FMPy; yields (slave, {name: valueReference})."""
    from fmpy import extract, read_model_description
    from fmpy.fmi2 import FMU2Slave

    md = read_model_description(path)
    unzipdir = extract(path)
    slave = FMU2Slave(guid=md.guid, unzipDirectory=unzipdir,
                      modelIdentifier=md.coSimulation.modelIdentifier, instanceName=instance)
    slave.instantiate()
    ok = False
    try:
        yield slave, {v.name: v.valueReference for v in md.modelVariables}
        ok = True
    finally:
        if ok:          # after an FMI error/fatal status only fmi2FreeInstance is allowed
            slave.terminate()
        slave.freeInstance()
        import shutil
        shutil.rmtree(unzipdir, ignore_errors=True)


# --------------------------------------------------------------------------- all
@pytest.mark.parametrize("name", NAMES)
def test_validate_fmu_no_problems(built_fmus, name):
    from fmpy.validation import validate_fmu
    assert validate_fmu(str(_fmu(built_fmus, name))) == []


@pytest.mark.parametrize("name", NAMES)
def test_capabilities_are_the_real_ones(built_fmus, name):
    from fmpy import read_model_description
    cs = read_model_description(_fmu(built_fmus, name)).coSimulation
    assert cs.canGetAndSetFMUstate and cs.canSerializeFMUstate
    assert cs.canHandleVariableCommunicationStepSize
    assert not cs.canInterpolateInputs          # PythonFMU has no fmi2SetRealInputDerivatives
    assert cs.maxOutputDerivativeOrder in (None, 0)


@pytest.mark.parametrize("name", NAMES)
def test_fmu_carries_its_code_and_build_record(built_fmus, name):
    path = _fmu(built_fmus, name)
    stamp = json.loads(path.with_suffix(".stamp").read_text())
    with zipfile.ZipFile(path) as zf:
        inside = json.loads(zf.read("resources/rotorcosim_build.json"))
        names = zf.namelist()
    assert inside["source_sha256"] == stamp["source_sha256"]
    pkg = "bearing_fmu" if name == "JournalBearing" else "rotor_fmu"
    assert f"resources/{pkg}/__init__.py" in names          # model code travels with the FMU
    assert not any("__pycache__" in n for n in names)


def test_stamp_and_staleness(tmp_path):
    """On a frozen copy of the sources (the repository may be edited while tests run)."""
    import shutil
    from orchestrator.fmi.build import REPO, FmuRecipe, build_one, is_stale, source_hash
    src = tmp_path / "src" / "rotor_fmu"
    shutil.copytree(REPO / "rotor_fmu", src, ignore=shutil.ignore_patterns("__pycache__"))
    recipe = FmuRecipe("JeffcottRotor", src / "jeffcott_rotor.py", (src,))
    fmu = build_one(recipe, tmp_path / "out")
    stamp = json.loads(fmu.with_suffix(".stamp").read_text())
    assert stamp["source_sha256"] == source_hash(recipe)
    assert not is_stale(fmu, recipe)
    (src / "drive.py").write_text((src / "drive.py").read_text() + "\n# edited\n")
    assert is_stale(fmu, recipe)                              # a source edit makes it stale
    build_one(recipe, tmp_path / "out")
    assert not is_stale(fmu, recipe)
    fmu.with_suffix(".stamp").unlink()
    assert is_stale(fmu, recipe)                              # no stamp: rebuild
    fmu.unlink()
    assert is_stale(fmu, recipe)


def test_variable_names_of_the_contract(built_fmus):
    from fmpy import read_model_description
    want = {
        "JournalBearing": {
            "parameter": {"R", "B", "psi", "eta0", "p0", "p_feed", "groove_width", "groove_angle",
                          "n_phi", "n_z", "cavitation", "axial_bc", "fields_file"},
            "input": {"x", "y", "vx", "vy", "omega"},
            "output": {"Fx", "Fy", "eps", "p_max", "p_min", "h_min", "torque", "q_feed", "q_side"}},
        "JeffcottRotor": {
            "parameter": {"f_max", "t_ramp", "d_external"},
            "input": {"Fx_1", "Fy_1", "Fx_2", "Fy_2"},
            "output": {"x_1", "y_1", "vx_1", "vy_1", "x_2", "y_2", "vx_2", "vy_2", "omega"}},
    }
    want["TurbochargerRotor"] = {**want["JeffcottRotor"], "parameter": {"f_max", "t_ramp", "rotor_file"}}
    checked = 0
    for name, groups in want.items():
        if name not in built_fmus:
            continue
        md = read_model_description(built_fmus[name])
        for causality, names in groups.items():
            have = {v.name for v in md.modelVariables if v.causality == causality}
            assert names <= have, (name, causality, names - have)
        for v in md.modelVariables:
            if v.causality == "parameter":
                assert v.variability in ("fixed", "tunable") and v.initial in (None, "exact")
        checked += 1
    assert checked >= 1


# ------------------------------------------------------------------- bearing
def _bearing_setup(slave, vr, *, cavitation, eps=0.5, f=100.0, n=16, axial_bc=0, fields_file=""):
    c = PSI * R_TEST
    slave.setupExperiment(startTime=0.0)
    slave.enterInitializationMode()
    slave.setReal([vr["R"], vr["B"], vr["psi"]], [R_TEST, 1.6 * R_TEST, PSI])
    slave.setInteger([vr["n_phi"], vr["n_z"], vr["cavitation"], vr["axial_bc"]], [n, n, cavitation, axial_bc])
    if axial_bc == 1:
        slave.setReal([vr["groove_width"], vr["groove_angle"]], [math.radians(15.0), 0.0])
    if fields_file:
        slave.setString([vr["fields_file"]], [fields_file])
    slave.setReal([vr["x"], vr["y"], vr["omega"]], [0.0, -eps * c, 2 * math.pi * f])
    slave.exitInitializationMode()


def _orbit(t: float, c: float) -> list[float]:
    """Journal on a small circular orbit (40 Hz, radius 0.05 C) around eps = 0.5 below the centre."""
    w, a = 2 * math.pi * 40.0, 0.05 * c
    return [a * math.cos(w * t), -0.5 * c + a * math.sin(w * t), -a * w * math.sin(w * t), a * w * math.cos(w * t)]


def test_bearing_theta_transport_parameter(built_fmus):
    """Integer parameter ``theta_transport`` (default 0): 1 switches the mass-conserving film
    to the limited second-order Couette transport of theta (BearingParams.theta_transport)."""
    from fmpy import read_model_description
    path = _fmu(built_fmus, "JournalBearing")
    md = read_model_description(path)
    v = {x.name: x for x in md.modelVariables}["theta_transport"]
    assert v.type == "Integer" and v.causality == "parameter" and int(v.start) == 0
    c = PSI * R_TEST
    res = {}
    for tt in (None, 0, 1):
        with open_slave(path) as (s, vr):
            s.setupExperiment(startTime=0.0)
            s.enterInitializationMode()
            s.setReal([vr["R"], vr["B"], vr["psi"]], [R_TEST, 1.6 * R_TEST, PSI])
            s.setInteger([vr["n_phi"], vr["n_z"], vr["cavitation"]], [16, 16, 1])
            if tt is not None:
                s.setInteger([vr["theta_transport"]], [tt])
            s.setReal([vr[n] for n in ("x", "y", "vx", "vy", "omega")],
                      _orbit(0.0, c) + [2 * math.pi * 100.0])
            s.exitInitializationMode()
            for k in range(3):
                s.setReal([vr[n] for n in ("x", "y", "vx", "vy")], _orbit((k + 1) * 2e-5, c))
                s.doStep(k * 2e-5, 2e-5)
            res[tt] = s.getReal([vr["Fx"], vr["Fy"]])
    assert res[None] == res[0]
    assert res[1] != res[0] and np.allclose(res[1], res[0], rtol=0.05)


def test_bearing_contact_parameters_and_output(built_fmus):
    """``contact`` (Integer, default 0), ``sigma_rough`` [m], ``contact_KE`` [Pa],
    ``mu_contact`` and the output ``F_contact`` [N]: near the shell the FMU's force is the
    film's plus bearing_fmu.contact.contact_force, and F_contact its normal part
    (tests/test_bearing_contact.py checks the model to round-off)."""
    from fmpy import read_model_description
    from bearing_fmu.contact import contact_force
    path = _fmu(built_fmus, "JournalBearing")
    md = read_model_description(path)
    var = {x.name: x for x in md.modelVariables}
    assert var["contact"].type == "Integer" and int(var["contact"].start) == 0
    for name, unit in (("sigma_rough", "m"), ("contact_KE", "Pa"), ("mu_contact", "1")):
        assert var[name].causality == "parameter" and var[name].unit == unit
    assert var["F_contact"].causality == "output" and var["F_contact"].unit == "N"
    c = PSI * R_TEST
    kin = [0.1 * c, -0.99 * c, 0.0, 0.0, 2 * math.pi * 100.0]
    res = {}
    for contact in (0, 1):
        with open_slave(path) as (s, vr):
            s.setupExperiment(startTime=0.0)
            s.enterInitializationMode()
            s.setReal([vr["R"], vr["B"], vr["psi"]], [R_TEST, 1.6 * R_TEST, PSI])
            s.setInteger([vr["n_phi"], vr["n_z"], vr["cavitation"], vr["contact"]], [16, 16, 0, contact])
            s.setReal([vr[n] for n in ("x", "y", "vx", "vy", "omega")], kin)
            s.exitInitializationMode()
            s.doStep(0.0, 1e-5)
            res[contact] = s.getReal([vr["Fx"], vr["Fy"], vr["F_contact"], vr["torque"]])
    fx, fy, fn, _ = contact_force(*kin, c=c, R=R_TEST, B=1.6 * R_TEST, sigma=0.3e-6, KE=2.0e7, mu=0.1)
    assert res[0][2] == 0.0 and res[1][2] == pytest.approx(fn, rel=1e-12) and fn > 0.1
    # the film itself sees the expected gap of the roughness with contact (a small change here)
    assert res[1][0] == pytest.approx(res[0][0] + fx, rel=1e-2)
    assert res[1][1] == pytest.approx(res[0][1] + fy, rel=1e-2)


@pytest.mark.parametrize("cavitation", [0, 1])
def test_bearing_state_round_trip_is_exact(built_fmus, cavitation):
    """step / save / step / restore / step: identical outputs; the journal moves, so a
    transient film (pressure field, integrator history) not restored would show."""
    path = _fmu(built_fmus, "JournalBearing")
    c = PSI * R_TEST
    outs = ["Fx", "Fy", "p_max", "p_min", "eps", "q_side"]
    kin = [vr_name for vr_name in ("x", "y", "vx", "vy")]
    with open_slave(path) as (s, vr):
        s.setupExperiment(startTime=0.0)
        s.enterInitializationMode()
        s.setReal([vr["R"], vr["B"], vr["psi"]], [R_TEST, 1.6 * R_TEST, PSI])
        s.setInteger([vr["n_phi"], vr["n_z"], vr["cavitation"]], [16, 16, cavitation])
        s.setReal([vr[n] for n in kin] + [vr["omega"]], _orbit(0.0, c) + [2 * math.pi * 100.0])
        s.exitInitializationMode()
        ovr, kvr = [vr[n] for n in outs], [vr[n] for n in kin]
        h = 2e-5

        def advance(k0, k1):
            rows = []
            for k in range(k0, k1):
                s.setReal(kvr, _orbit((k + 1) * h, c))     # kinematics at the end of the step, held
                s.doStep(k * h, h)
                rows.append(s.getReal(ovr))
            return np.array(rows)

        advance(0, 5)
        state = s.getFMUstate()
        first = advance(5, 15)
        blob = s.serializeFMUstate(state)
        s.setFMUstate(state)
        second = advance(5, 15)
        assert np.array_equal(first, second)
        assert np.ptp(first[:, 1]) > 0                     # the outputs did change over the steps
        state2 = s.deSerializeFMUstate(blob)
        s.setFMUstate(state2)
        third = advance(5, 15)
        assert np.array_equal(first, third)
        s.freeFMUstate(state)
        s.freeFMUstate(state2)


@pytest.mark.parametrize("cavitation", [0, 1])
def test_bearing_force_points_back_to_centre(built_fmus, cavitation):
    path = _fmu(built_fmus, "JournalBearing")
    with open_slave(path) as (s, vr):
        _bearing_setup(s, vr, cavitation=cavitation, eps=0.5, n=20)
        for k in range(3):
            s.doStep(k * 1e-4, 1e-4)
        fx, fy, eps, p_max, p_min, h_min = s.getReal(
            [vr[n] for n in ("Fx", "Fy", "eps", "p_max", "p_min", "h_min")])
    # journal below the centre (y = -0.5 C): the film pushes it back up, with an attitude
    # angle below 90 degrees (Fy dominant, Fx from the rotation, counter-clockwise)
    assert fy > 0 and fy > 0.3 * math.hypot(fx, fy)
    assert eps == pytest.approx(0.5, rel=1e-9)
    assert h_min == pytest.approx(0.5 * PSI * R_TEST, rel=0.05)
    assert p_max > 1e5 > p_min - 1e-6 * p_max or cavitation == 0 and p_min >= 1e5 - 1.0


def test_bearing_writes_fields_file_at_terminate(built_fmus, tmp_path):
    path = _fmu(built_fmus, "JournalBearing")
    target = tmp_path / "sub" / "bearing1_fields.npz"
    with open_slave(path) as (s, vr):
        _bearing_setup(s, vr, cavitation=1, n=12, fields_file=str(target))
        s.doStep(0.0, 1e-4)
        assert not target.exists()                           # written at fmi2Terminate
    data = np.load(target)                                   # open_slave terminated the instance
    assert {"phi", "z", "p", "theta", "h", "t"} <= set(data.files)
    assert data["p"].shape == (data["z"].size, data["phi"].size) == (12, 12)
    assert float(data["t"]) == pytest.approx(1e-4)


def test_bearing_parameter_fixed_after_initialization(built_fmus):
    from fmpy.fmi1 import FMICallException
    path = _fmu(built_fmus, "JournalBearing")
    with open_slave(path) as (s, vr):
        _bearing_setup(s, vr, cavitation=0, n=8)
        s.setReal([vr["R"]], [R_TEST])                      # same value: accepted
        with pytest.raises(FMICallException):
            s.setReal([vr["R"]], [2 * R_TEST])


# --------------------------------------------------------------------- rotors
@pytest.mark.parametrize("name", ["JeffcottRotor", "TurbochargerRotor"])
def test_rotor_state_round_trip_and_gravity(built_fmus, name):
    path = _fmu(built_fmus, name)
    outs = ["x_1", "y_1", "vx_1", "vy_1", "x_2", "y_2", "vy_2", "omega"]
    with open_slave(path) as (s, vr):
        s.setupExperiment(startTime=0.0)
        s.enterInitializationMode()
        s.setReal([vr["f_max"], vr["t_ramp"]], [200.0, 1.0])
        s.exitInitializationMode()
        ovr = [vr[n] for n in outs]
        h, t = 1e-4, 0.0
        first = []
        for k in range(5):
            s.doStep(t, h)
            t += h
        state = s.getFMUstate()
        for k in range(10):
            s.setReal([vr["Fx_1"], vr["Fy_1"]], [1.0 * k, 2.0])
            s.doStep(t, h)
            t += h
            first.append(s.getReal(ovr))
        s.setFMUstate(state)
        t -= 10 * h
        second = []
        for k in range(10):
            s.setReal([vr["Fx_1"], vr["Fy_1"]], [1.0 * k, 2.0])
            s.doStep(t, h)
            t += h
            second.append(s.getReal(ovr))
        s.freeFMUstate(state)
    first, second = np.array(first), np.array(second)
    assert np.array_equal(first, second)
    assert first[-1, outs.index("vy_2")] < 0.0               # unsupported journal falls under gravity
    assert first[-1, outs.index("omega")] == pytest.approx(2 * math.pi * 200.0 * 15 * h, rel=1e-9)


def _coefficient_run(path, tol, steps, h, orbit, restore_at=None):
    """kxx..cyy after initialization and after each of ``steps`` steps of a half-Sommerfeld bearing FMU with
    linearize = 1 and ``linearize_tol = tol`` (None: not set), the journal on ``orbit(t)``;
    with ``restore_at = k``: the state saved after step k is restored at the end and the
    remaining steps repeated (second list)."""
    c = PSI * R_TEST
    names = [f"{k}{i}{j}" for k in "kc" for i in "xy" for j in "xy"]
    with open_slave(path) as (s, vr):
        s.setupExperiment(startTime=0.0)
        s.enterInitializationMode()
        s.setReal([vr["R"], vr["B"], vr["psi"]], [R_TEST, 1.6 * R_TEST, PSI])
        s.setInteger([vr["n_phi"], vr["n_z"], vr["cavitation"], vr["linearize"]], [16, 8, 0, 1])
        if tol is not None:
            s.setReal([vr["linearize_tol"]], [tol])
        s.setReal([vr[n] for n in ("x", "y", "vx", "vy", "omega")], orbit(0.0, c) + [2 * math.pi * 100.0])
        s.exitInitializationMode()
        kvr, cvr = [vr[n] for n in ("x", "y", "vx", "vy")], [vr[n] for n in names]

        def advance(k0, k1):
            rows = []
            for k in range(k0, k1):
                s.setReal(kvr, orbit((k + 1) * h, c))
                s.doStep(k * h, h)
                rows.append(s.getReal(cvr))
            return np.array(rows)

        first = np.vstack([[s.getReal(cvr)], advance(0, restore_at or steps)])   # row 0: initial
        if restore_at is None:
            return first, None
        state = s.getFMUstate()
        rest = advance(restore_at, steps)
        s.setFMUstate(state)
        again = advance(restore_at, steps)
        s.freeFMUstate(state)
        return np.vstack([first, rest]), again


def test_bearing_linearize_tol_holds_coefficients_while_the_journal_stays(built_fmus):
    """``linearize_tol`` (Real, default 0): with linearize = 1 a due refresh of kxx..cyy is
    skipped while the inputs stay within the tolerance of the last refresh, in units of the
    gap c (1 - eps) (positions), the gap times omega (velocities) and omega. 0 and unset: every step, as before;
    a restored state repeats the held values."""
    from fmpy import read_model_description
    from bearing_fmu.journal_bearing import coefficients_moved
    path = _fmu(built_fmus, "JournalBearing")
    v = {x.name: x for x in read_model_description(path).modelVariables}["linearize_tol"]
    assert v.type == "Real" and v.causality == "parameter" and float(v.start) == 0.0
    c = PSI * R_TEST
    w = 2 * math.pi * 40.0

    def slow(t, c):        # 40 Hz orbit of radius 0.005 c: moves ~2.5e-5 c per 2e-5 s step
        a = 0.005 * c
        return [a * math.cos(w * t), -0.5 * c + a * math.sin(w * t), -a * w * math.sin(w * t),
                a * w * math.cos(w * t)]

    every, _ = _coefficient_run(path, None, 40, 2e-5, slow)
    zero, _ = _coefficient_run(path, 0.0, 40, 2e-5, slow)
    assert np.array_equal(every, zero)
    assert np.all(np.any(np.diff(every, axis=0) != 0, axis=1))    # refreshed every step
    held, again = _coefficient_run(path, 2e-4, 40, 2e-5, slow, restore_at=17)   # rows 0..40
    changed = np.flatnonzero(np.any(np.diff(held, axis=0) != 0, axis=1)) + 1
    assert 2 <= changed.size <= 20                                   # refreshed now and then
    assert np.array_equal(held[18:], again)                         # the state holds the anchor
    # each held row is the coefficient of an earlier step (the last refresh) and within the
    # tolerance's effect of the coefficient of its own step
    for k in range(held.shape[0]):
        assert any(np.array_equal(held[k], every[j]) for j in range(k + 1))
    assert np.allclose(held, every, rtol=5e-3, atol=0)
    # the distance: positions / c, velocities / (c omega), speed relative
    base = (0.0, 0.0, 0.0, 0.0, 100.0)
    assert coefficients_moved(base, (2e-3 * c, 0, 0, 0, 100.0), c) == pytest.approx(2e-3)
    assert coefficients_moved(base, (0, 0, 0, 3e-3 * c * 1000, 100.0), c) == pytest.approx(3e-3)
    assert coefficients_moved(base, (0, 0, 0, 0, 100.5), c) == pytest.approx(0.5 / 100.5)
    # ... in units of the gap at the anchor, c (1 - eps), at least 0.01 c: a journal near its
    # shell is held to a move of the tolerance times its gap, not times c
    near = (0.0, -0.9 * c, 0.0, 0.0, 100.0)
    assert coefficients_moved(near, (2e-3 * c, -0.9 * c, 0, 0, 100.0), c) == pytest.approx(2e-2)
    assert coefficients_moved(near, (0, -0.9 * c, 0, 3e-3 * c * 1000, 100.0), c) == pytest.approx(3e-2)
    shell = (0.0, -1.02 * c, 0.0, 0.0, 0.0)       # in the asperity layer: the floor
    assert coefficients_moved(shell, (1e-4 * c, -1.02 * c, 0, 0, 0.0), c) == pytest.approx(1e-2)
