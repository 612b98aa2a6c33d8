"""Our FMUs declare the ranges of their parameters (modelDescription.xml min/max), so a bad
value in a scenario is refused when the scenario is loaded, with its file and line, before
anything is instantiated or allocated; the film grid is bounded; what FMI 2.0 cannot declare
(String choices, relations between parameters) is refused by the FMU in its parameter names."""

from __future__ import annotations

import zipfile

import pytest

from fmu_common.slave import POSITIVE
from hostile_builders import cli
from orchestrator.errors import ScenarioError
from orchestrator.fmi.build import FMU_DIR
from orchestrator.fmi.model_description import parse_model_description
from orchestrator.scenario import load_scenario

SCENARIO = """\
name: bounds
start_time: 0.5
stop_time: 0.502
fmus:
  rotor:
    fmu: JeffcottRotor
    parameters: {{f_max: 800.0, t_ramp: {t_ramp}}}
  bearing1:
    fmu: JournalBearing
    parameters:
      {bearing}
connections:
  - {{from: rotor.x_1, to: bearing1.x}}
  - {{from: bearing1.Fx, to: rotor.Fx_1}}
coupling: {{scheme: gauss-seidel, macro_step: 1.0e-4}}
"""
# the loader's words for a film grid of more cells than MAX_FILM_CELLS
GRID_LIMIT = "more than the 262144 a film grid may have (MAX_FILM_CELLS, bearing_fmu/limits.py)"
GOOD = "{R: 4.9e-3, B: 7.84e-3, psi: 2.8e-3, eta0: 0.012, n_phi: 24, n_z: 12, cavitation: 0}"


def scenario(tmp_path, bearing=GOOD, t_ramp="2.0"):
    p = tmp_path / "s.yaml"
    p.write_text(SCENARIO.format(bearing=bearing, t_ramp=t_ramp))
    return p


def variables(name):
    with zipfile.ZipFile(FMU_DIR / f"{name}.fmu") as z:
        return parse_model_description(z.read("modelDescription.xml")).variables


def test_our_fmus_declare_parameter_ranges():
    from bearing_fmu import journal_bearing, model
    jb = variables("JournalBearing")
    assert (jb["n_phi"].min, jb["n_phi"].max) == (8, model.MAX_N_PHI)
    assert (jb["n_z"].min, jb["n_z"].max) == (2, model.MAX_N_Z)
    assert (journal_bearing.MAX_N_PHI, journal_bearing.MAX_N_Z) == (model.MAX_N_PHI, model.MAX_N_Z)
    assert (jb["cavitation"].min, jb["cavitation"].max) == (0, 1)
    assert (jb["psi"].min, jb["psi"].max) == (model.PSI_MIN, model.PSI_MAX) == (journal_bearing.PSI_MIN,
                                                                                journal_bearing.PSI_MAX)
    assert jb["R"].min > 0 and jb["solver_h_min"].min > 0 and jb["contact_h_limit"].min == -6.0
    for name, var in jb.items():                       # every default inside its declared range
        if var.causality == "parameter" and var.min is not None:
            assert var.min <= var.start <= (var.max if var.max is not None else var.start), name
    fr = variables("FloatingRingBearing")
    assert (fr["n_phi_inner"].max, fr["n_z_outer"].max) == (model.MAX_N_PHI, model.MAX_N_Z)
    rotor = variables("JeffcottRotor")
    assert rotor["t_ramp"].min == 0.0 and rotor["m_disc"].min > 0
    assert variables("TurbochargerRotor")["t_ramp"].min == 0.0


def test_the_largest_grids_we_use_are_inside_the_bounds():
    from bearing_fmu.model import MAX_FILM_CELLS, BearingParams
    for n_phi, n_z in ((1536, 40), (40, 320), (160, 160), (360, 120)):
        assert n_phi * n_z <= MAX_FILM_CELLS / 4
        BearingParams(n_phi=n_phi, n_z=n_z)


@pytest.mark.parametrize("n_phi, n_z, words", [
    (10**9, 12, ["n_phi must be an integer in [8, 8192]"]),
    (24, 10**6, ["n_z must be an integer in [2, 2048]"]),
    (4000, 2000, ["4000 x 2000 = 8000000", "at most 262144 cells", "coarser grid"]),
])
def test_bearing_params_refuse_a_huge_film_before_allocating(n_phi, n_z, words):
    from bearing_fmu.model import BearingParams
    with pytest.raises(ValueError) as exc:
        BearingParams(n_phi=n_phi, n_z=n_z)
    for w in words:
        assert w in str(exc.value)


@pytest.mark.parametrize("bearing, t_ramp, line, words", [
    (GOOD.replace("n_phi: 24", "n_phi: 1000000000"), "2.0", 11, ["bearing1.n_phi", "1000000000", "[8, 8192]"]),
    (GOOD.replace("n_z: 12", "n_z: 4000"), "2.0", 11, ["bearing1.n_z", "[2, 2048]"]),
    (GOOD.replace("n_phi: 24", "n_phi: 0"), "2.0", 11, ["bearing1.n_phi", "= 0"]),
    (GOOD.replace("psi: 2.8e-3", "psi: -2.8e-3"), "2.0", 11, ["bearing1.psi", "-0.0028"]),
    (GOOD.replace("R: 4.9e-3", "R: 0"), "2.0", 11, ["bearing1.R", "0.0"]),
    (GOOD.replace("cavitation: 0", "cavitation: 9"), "2.0", 11, ["bearing1.cavitation", "[0, 1]"]),
    (GOOD, "-2", 7, ["rotor.t_ramp", "-2"]),
])
def test_scenario_values_outside_the_declared_range_are_refused_at_load(tmp_path, bearing, t_ramp, line, words):
    path = scenario(tmp_path, bearing, t_ramp)
    with pytest.raises(ScenarioError) as exc:
        load_scenario(path)
    msg = str(exc.value)
    assert f"s.yaml:{line}:" in msg and "outside its declared range" in msg, msg
    for w in words:
        assert w in msg, msg


def test_validate_cli_refuses_a_large_grid_without_instantiating(tmp_path, capsys):
    # just above the bound (a film the old code could still afford: 9000 x 12 cells)
    path = scenario(tmp_path, GOOD.replace("n_phi: 24", "n_phi: 9000"))
    rc, out = cli(capsys, "validate", path, "--no-build")
    assert rc == 1 and "s.yaml:11:" in out and "[8, 8192]" in out
    assert "initialization failed" not in out and "MemoryError" not in out


def test_fmu_messages_use_the_fmu_parameter_names():
    from bearing_fmu.journal_bearing import fmu_parameter_message
    assert fmu_parameter_message("  BearingParams.h_min must be h_min <= h_init <= h_max (got 2.0)") == \
        "parameter 'solver_h_min' must be solver_h_min <= solver_h_init <= solver_h_max (got 2.0)"
    assert fmu_parameter_message("  BearingParams.psi must be a positive finite number (got 0.0)") == \
        "parameter 'psi' must be a positive finite number (got 0.0)"
    assert fmu_parameter_message("BearingParams: the film grid n_phi x n_z must ...") == \
        "the film grid n_phi x n_z must ..."


def test_string_choices_are_refused_at_load(tmp_path):
    """FMI 2.0 cannot declare the values of a String: our FMUs declare them in a rotorcosim tool
    annotation of the variable, and the scenario check reads it (file:line, before instantiating)."""
    assert variables("JournalBearing")["linear_solver"].choices == ("band", "lapack", "splu")
    assert variables("FloatingRingBearing")["ring_init"].choices == ("equilibrium", "given")
    bad = GOOD.replace("cavitation: 0", "cavitation: 0, linear_solver: magic, init: /etc/passwd")
    with pytest.raises(ScenarioError) as exc:
        load_scenario(scenario(tmp_path, bad))
    msg = str(exc.value)
    assert "s.yaml:11: parameter 'bearing1.linear_solver' must be one of 'band', 'lapack', 'splu'" in msg
    assert "got 'magic'" in msg and "got '/etc/passwd'" in msg


def test_choices_annotation_of_any_fmu():
    from orchestrator.fmi.values import check_value
    xml = b"""<?xml version="1.0" encoding="UTF-8"?>
<fmiModelDescription fmiVersion="2.0" modelName="m" guid="g">
  <CoSimulation modelIdentifier="m"/>
  <ModelVariables>
    <ScalarVariable name="mode" valueReference="0" causality="parameter" variability="fixed">
      <String start="a"/>
      <Annotations><Tool name="other"><Choices><Choice value="zzz"/></Choices></Tool>
        <Tool name="rotorcosim"><Choices><Choice value="a"/><Choice value="b"/></Choices></Tool></Annotations>
    </ScalarVariable>
    <ScalarVariable name="free" valueReference="1" causality="parameter" variability="fixed">
      <String start="x"/>
    </ScalarVariable>
  </ModelVariables>
</fmiModelDescription>"""
    md = parse_model_description(xml)
    mode, free = md.variables["mode"], md.variables["free"]
    assert mode.choices == ("a", "b") and free.choices == ()
    assert check_value(mode, "b", "m.mode") == ("b", None)
    value, problem = check_value(mode, "c", "m.mode")
    assert value is None and "'m.mode' must be one of 'a', 'b'" in problem and "got 'c'" in problem
    assert check_value(free, "anything", "m.free") == ("anything", None)


def test_relations_are_refused_in_fmu_terms(tmp_path, capsys):
    """A rule across parameters (no declared range can say it): the FMU refuses it when the
    model is made (validate initializes the FMUs), in its own parameter names."""
    bad = GOOD.replace("cavitation: 0", "cavitation: 0, solver_h_min: 2.0")
    rc, out = cli(capsys, "validate", scenario(tmp_path, bad))
    assert rc == 1
    assert "invalid parameters of the JournalBearing FMU instance 'bearing1'" in out
    assert "parameter 'solver_h_min' must be solver_h_min <= solver_h_init <= solver_h_max (got 2.0)" in out
    assert "BearingParams." not in out and "set them in the scenario" in out


def test_floating_ring_films_are_named_by_side(capsys):
    from orchestrator.shipped import resolve
    path = resolve("jeffcott_runup_floating_ring_free_to_air")
    rc, out = cli(capsys, "validate", path, "--set", "fmus.bearing1.parameters.n_phi_inner=4000",
                  "--set", "fmus.bearing1.parameters.n_z_inner=100")
    assert rc == 1            # the grid's cells: at load (test_a_floating_ring_film_grid_above_the_cell_limit_...)
    assert "fmus.bearing1.parameters.n_phi_inner x n_z_inner = 4000 x 100 = 400000 film cells" in out, out
    rc, out = cli(capsys, "validate", path, "--set", "fmus.bearing1.parameters.cav_width_outer=2e5")
    assert rc == 1
    assert "parameter 'cav_width_outer' must be below p0" in out and "BearingParams." not in out


def test_relations_name_the_scenario_lines_of_the_parameters(tmp_path, capsys):
    """The FMU checks the relations between its parameters itself; the master traces its
    refusal back to where the scenario sets the parameters the message names."""
    bad = GOOD.replace("cavitation: 0", "cavitation: 1, axial_bc: 1, p0: 1.0e5,\n      p_feed: 0.5e5, "
                                        "groove_width: 0.26")
    path = scenario(tmp_path, bad)
    rc, out = cli(capsys, "validate", path)
    assert rc == 1 and "parameter 'p_feed' must be >= p0" in out, out
    assert f"'bearing1' gets p_feed from {path}:12 and p0 from {path}:11" in out, out
    rc, out = cli(capsys, "validate", scenario(tmp_path), "--set", "fmus.bearing1.parameters.n_phi=8192",
                  "--set", "fmus.bearing1.parameters.n_z=2048")
    assert rc == 1 and GRID_LIMIT in out, out         # the grid's cells: at load, where each factor comes from
    assert (f"{path.parent / 's.yaml'}:8: fmus.bearing1.parameters.n_phi x n_z = 8192 x 2048 = 16777216 film cells"
            in out), out
    assert ("; n_phi from --set fmus.bearing1.parameters.n_phi=8192; n_z from "
            "--set fmus.bearing1.parameters.n_z=2048;") in out, out


def test_floating_ring_grid_limit_names_the_parameters_of_the_side(capsys):
    from orchestrator.shipped import resolve
    rc, out = cli(capsys, "validate", resolve("jeffcott_runup_floating_ring_free_to_air"),
                  "--set", "fmus.bearing1.parameters.n_phi_outer=8192")
    assert rc == 1 and ("jeffcott_runup_floating_ring_free_to_air.yaml:30: fmus.bearing1.parameters.n_phi_outer x "
                        "n_z_outer = 8192 x 40 = 327680 film cells") in out, out
    assert "; n_phi_outer from --set fmus.bearing1.parameters.n_phi_outer=8192;" in out, out


@pytest.mark.parametrize("text, want", [
    ("parameter 'p_feed' must be >= p0 (got 1)", [("p_feed", "f:2"), ("p0", "f:1")]),
    ("n_z and n_phi", [("n_z", "f:4"), ("n_phi", "f:3")]),
    ("the gap R/B is odd", []),                       # one-letter names only when quoted
    ("'R' must be positive", [("R", "f:5")]),
    ("p_feed_outer must be set; xp0 and p0x differ", []),   # whole words only
    ("a.p0 and p0[1]", []),
])
def test_origins_named_in(text, want):
    from orchestrator.scenario.model import FmuSpec
    spec = FmuSpec(name="b", path=tmp_path_free(), parameter_origins={
        "p0": "f:1", "p_feed": "f:2", "n_phi": "f:3", "n_z": "f:4", "R": "f:5"})
    assert spec.origins_named_in(text) == want
    assert len(FmuSpec(name="b", path=tmp_path_free(), parameter_origins={
        f"q{i}": f"f:{i}" for i in range(9)}).origins_named_in(" ".join(f"q{i}" for i in range(9)))) == 4


def tmp_path_free():
    from pathlib import Path
    return Path("/nonexistent/b.fmu")


@pytest.mark.parametrize("n_phi, n_z, groove, theta_transport", [
    (512, 512, 0.26, 0), (512, 512, 0.0, 0), (513, 511, 0.26, 0), (8192, 32, 0.0, 0), (8192, 32, 0.26, 1),
    (128, 2048, 0.0, 0), (128, 2048, 0.26, 1), (40, 40, 0.26, 0), (8, 3, 0.26, 1), (9, 7, 0.0, 1)])
def test_film_band_is_the_grid_band_or_more(n_phi, n_z, groove, theta_transport):
    # film_memory_estimate's band width from the sizes alone (no grid built): the band the
    # ordering finds, on the grids of benchmarks/bench_film_memory.py exactly
    import math

    from bearing_fmu.grid import make_grid
    from bearing_fmu.model import film_band
    g = make_grid(n_phi, n_z, groove, math.pi / 2, half=n_z % 2 == 0, wide=theta_transport == 1)
    n, bw = film_band(n_phi, n_z, 1, groove, math.pi / 2, theta_transport)
    assert n == g.n and bw >= g.bw
    if n_phi * n_z >= 2**16:
        assert bw == g.bw


def test_a_film_larger_than_the_available_memory_is_refused(monkeypatch):
    import bearing_fmu.model as model
    from bearing_fmu.journal_bearing import fmu_parameter_message

    def small():
        return 2**29
    monkeypatch.setattr(model, "available_memory", small)
    with pytest.raises(ValueError) as exc:
        model.BearingParams(n_phi=512, n_z=512, groove_width=0.26)
    msg = str(exc.value)
    for w in ("n_phi x n_z = 512 x 512 needs about 0.9 GiB", "131072 unknowns x 769 band rows",
              "(0.5 GiB, MemAvailable)", "use a coarser grid"):
        assert w in msg, msg
    assert fmu_parameter_message(msg.splitlines()[1]).startswith("the film grid n_phi x n_z = 512 x 512 needs")
    model.BearingParams(n_phi=512, n_z=512, cavitation=0)      # half-Sommerfeld: 64 MiB

    def unread():
        raise AssertionError("a small film must not read the available memory")
    monkeypatch.setattr(model, "available_memory", unread)
    model.BearingParams(n_phi=1536, n_z=40)
    model.BearingParams(n_phi=160, n_z=160)


def test_the_available_memory_is_read():
    from bearing_fmu.model import available_memory
    assert available_memory() > 2**26


@pytest.mark.parametrize("psi, words", [
    ("1.5", ["bearing1.psi' = 1.5", "outside its declared range [0.0001, 0.1]", "C/R",
             "radial clearance C over journal radius R", "typically 1e-3 to 3e-3", "per mille",
             "1.5 per mille is psi = 1.5e-3"]),
    ("1.5e-5", ["bearing1.psi' = 1.5e-05", "a clearance in m is not psi"]),   # a clearance in metres
])
def test_psi_out_of_range_says_what_psi_is(tmp_path, psi, words):
    """Before 2026-12-06 psi = 1.5 (meant: 1.5 per mille) got "outside its declared range (0, 0.1]"
    without saying what psi is, and a clearance in metres (1.5e-5) was accepted (psi > 0)."""
    with pytest.raises(ScenarioError) as exc:
        load_scenario(scenario(tmp_path, GOOD.replace("psi: 2.8e-3", f"psi: {psi}")))
    msg = str(exc.value)
    for w in words:
        assert w in msg, msg


def test_geometric_parameters_out_of_range_give_their_units(tmp_path):
    """A range error says what the parameter is, with its unit (from the FMU's description)."""
    for old, bad, words in (("R: 4.9e-3", "R: 0", ["bearing1.R' = 0.0", "radius R [m]", "20 mm"]),
                            ("B: 7.84e-3", "B: -7.84", ["width B [m]", "32 mm"]),
                            ("eta0: 0.012", "eta0: -12", ["eta0 [Pa s]", "12 mPa s"])):
        with pytest.raises(ScenarioError) as exc:
            load_scenario(scenario(tmp_path, GOOD.replace(old, bad)))
        for w in words:
            assert w in str(exc.value), str(exc.value)


def test_bearing_params_psi_message_in_per_mille():
    """The model's own check (BearingParams, also the FMU's check in another importer)."""
    from bearing_fmu.journal_bearing import fmu_parameter_message
    from bearing_fmu.model import BearingParams
    for psi, shown in ((1.5, "1500 per mille"), (1.5e-5, "0.015 per mille")):
        with pytest.raises(ValueError) as exc:
            BearingParams(psi=psi)
        msg = fmu_parameter_message(str(exc.value).splitlines()[1])
        assert msg.startswith("parameter 'psi' must be the relative radial clearance C/R"), msg
        assert shown in msg and "1.5 per mille is psi = 1.5e-3" in msg and "C / R" in msg, msg
    with pytest.raises(ValueError, match=r"BearingParams.R must be a positive finite number \[m\], the journal radius"):
        BearingParams(R=0.0)


def _outside(lo, hi, integer):
    """Values just outside a declared [lo, hi] (None: open); POSITIVE as lo is "> 0", tested elsewhere."""
    out = []
    if lo is not None and lo != POSITIVE:
        out.append(lo - 1 if integer or lo <= 0 else lo / 10)
    if hi is not None:
        out.append(hi + 1 if integer or hi <= 0 else hi * 10)
    return out


def test_bearing_params_refuse_every_value_the_fmu_declares_out_of_range():
    """The Python API (BearingParams) and the FMU's declaration accept the same range of every
    parameter: R = 25 (mm meant) was refused by a scenario's loader but built a 25 m journal through
    BearingParams (stop 44, leftover of probe 9b)."""
    import dataclasses

    from bearing_fmu import journal_bearing as jb
    from bearing_fmu.model import BearingParams
    fields = {f.name for f in dataclasses.fields(BearingParams)}
    base = {"axial_bc": 1}                       # free to air: no oil-bath warning
    checked = 0
    for fmu_name, (lo, hi) in jb.PARAMETER_RANGES.items():
        name = jb.RENAMED.get(fmu_name, fmu_name)
        assert name in fields, fmu_name
        integer = fmu_name in jb.INTEGER_PARAMETERS or isinstance(getattr(BearingParams(**base), name), int)
        for v in _outside(lo, hi, integer):
            v = int(v) if integer else float(v)
            with pytest.raises(ValueError, match=rf"BearingParams\.{name} must"):
                BearingParams(**{**base, name: v})
            checked += 1
    assert checked >= 30, checked


# ----------------------------------------------------------------------------- the film grid's cells at load
# n_phi and n_z each inside its declared range, their product above MAX_FILM_CELLS: found only when the
# FMU started ("initialization failed: FMU instance 'bearing1': fmi2GetReal returned fatal: ... ValueError
# in the FMU's getReal: ... the film grid n_phi x n_z must have at most 262144 cells"), after the other
# FMUs were instantiated, without the scenario's line. Now the loader refuses it with its line.


@pytest.mark.parametrize("bearing, overrides, place, words", [
    (GOOD.replace("n_phi: 24", "n_phi: 8000").replace("n_z: 12", "n_z: 40"), [], 11,
     ["n_phi x n_z = 8000 x 40 = 320000 film cells", "n_phi <= 6553 at n_z = 40, or n_z <= 32 at n_phi = 8000"]),
    (GOOD.replace("n_phi: 24, n_z: 12", "n_phi: 8000"), [], 11,
     ["n_phi x n_z = 8000 x 40 = 320000 film cells", "; n_z = 40 is the FMU's default;"]),
    (GOOD.replace("n_phi: 24", "n_phi: 8000"), ["fmus.bearing1.parameters.n_z=200"], 11,
     ["n_phi x n_z = 8000 x 200 = 1600000", "; n_z from --set fmus.bearing1.parameters.n_z=200;"]),
    (GOOD, ["fmus.bearing1.parameters.n_phi=4096", "fmus.bearing1.parameters.n_z=100"], 8,
     ["n_phi x n_z = 4096 x 100 = 409600", "; n_phi from --set fmus.bearing1.parameters.n_phi=4096; n_z from "
      "--set fmus.bearing1.parameters.n_z=100;"]),
], ids=["both-written", "n_z-default", "n_z-set", "both-set"])
def test_a_journal_bearing_grid_above_the_cell_limit_is_refused_at_load_with_its_line(tmp_path, bearing, overrides,
                                                                                    place, words):
    _refused_grid(scenario(tmp_path, bearing), overrides, f"s.yaml:{place}: fmus.bearing1.parameters.n_phi x n_z = ",
                  words)


def _refused_grid(path, overrides, head, words):
    """load_scenario refuses the film grid with ``head``, the limit and every one of ``words``."""
    with pytest.raises(ScenarioError) as exc:
        load_scenario(path, overrides)
    msg = str(exc.value)
    assert head in msg and GRID_LIMIT in msg, msg
    for w in words:
        assert w in msg, msg


def test_a_grid_of_exactly_the_cell_limit_loads(tmp_path):
    from bearing_fmu.limits import MAX_FILM_CELLS
    assert 4096 * 64 == MAX_FILM_CELLS
    sc = load_scenario(scenario(tmp_path, GOOD.replace("n_phi: 24", "n_phi: 4096").replace("n_z: 12", "n_z: 64")))
    assert (sc.fmus[1].parameters["n_phi"], sc.fmus[1].parameters["n_z"]) == (4096, 64)


@pytest.mark.parametrize("side, overrides, place, words", [
    ("outer", [], 11, ["n_phi_outer x n_z_outer = 8000 x 40 = 320000", "; n_z_outer = 40 is the FMU's default;",
                       "n_phi_outer <= 6553 at n_z_outer = 40"]),
    ("inner", ["fmus.bearing1.parameters.n_z_inner=64"], 11,
     ["n_phi_inner x n_z_inner = 8000 x 64 = 512000", "; n_z_inner from --set fmus.bearing1.parameters.n_z_inner=64;"]),
], ids=["outer-n_z-default", "inner-n_z-set"])
def test_a_floating_ring_film_grid_above_the_cell_limit_is_refused_at_load_with_its_line(tmp_path, side, overrides,
                                                                                       place, words):
    text = SCENARIO.format(bearing=f"{{n_phi_{side}: 8000}}", t_ramp="2.0").replace("fmu: JournalBearing",
                                                                                  "fmu: FloatingRingBearing")
    path = tmp_path / "s.yaml"
    path.write_text(text)
    load_scenario(path, [f"fmus.bearing1.parameters.n_phi_{side}=4096"])         # 4096 x 40: loads
    _refused_grid(path, overrides, f"s.yaml:{place}: fmus.bearing1.parameters.n_phi_{side} x n_z_{side} = ", words)


@pytest.mark.parametrize("verb", ["validate", "run"])
def test_validate_and_run_refuse_a_grid_above_the_cell_limit_before_any_fmu_starts(tmp_path, capsys, verb):
    path = scenario(tmp_path, GOOD.replace("n_phi: 24", "n_phi: 8000").replace("n_z: 12", "n_z: 40"))
    extra = ["--out", tmp_path / "run"] if verb == "run" else []
    rc, out = cli(capsys, verb, path, *extra)
    assert rc == 1 and "s.yaml:11: fmus.bearing1.parameters.n_phi x n_z = 8000 x 40 = 320000 film cells" in out, out
    assert "initialization failed" not in out and "fmi2GetReal" not in out, out
