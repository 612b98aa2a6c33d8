"""Scenario loader (``orchestrator.scenario.load_scenario``): valid files, every
bad-input case of issue 2 that belongs to loading, and ``--set`` overrides.

The helpers ``scenario_dir`` / ``write_md_only_fmu`` are also used by
tests/test_cli.py.
"""

from __future__ import annotations

import re
import shutil
import zipfile
from pathlib import Path

import pytest

from orchestrator.errors import CosimError, ScenarioError
from orchestrator.scenario import load_scenario, validate_scenario

DATA = Path(__file__).parent / "data" / "scenarios"

# An FMU that only carries a model description (enough for loading and
# validation): Integer and Boolean inputs/outputs, which none of the pythonfmu
# test FMUs has.
MIXED_MD = """<?xml version="1.0" encoding="UTF-8"?>
<fmiModelDescription fmiVersion="2.0" modelName="Mixed" guid="{0f6a1c2e-0000-4000-8000-000000000001}"
    generationTool="rotorcosim tests" variableNamingConvention="flat">
  <CoSimulation modelIdentifier="Mixed" canHandleVariableCommunicationStepSize="true"/>
  <ModelVariables>
    <ScalarVariable name="count" valueReference="0" causality="output" variability="discrete" initial="exact">
      <Integer start="0"/></ScalarVariable>
    <ScalarVariable name="enable" valueReference="1" causality="input" variability="discrete">
      <Boolean start="false"/></ScalarVariable>
    <ScalarVariable name="u" valueReference="2" causality="input" variability="continuous">
      <Real start="0"/></ScalarVariable>
    <ScalarVariable name="y" valueReference="3" causality="output" variability="continuous" initial="exact">
      <Real start="0"/></ScalarVariable>
  </ModelVariables>
  <ModelStructure><Outputs><Unknown index="1"/><Unknown index="4"/></Outputs></ModelStructure>
</fmiModelDescription>
"""


def write_md_only_fmu(path: Path, xml: str = MIXED_MD) -> Path:
    with zipfile.ZipFile(path, "w") as zf:
        zf.writestr("modelDescription.xml", xml)
    return path


def scenario_dir(tmp_path: Path, test_fmus: dict[str, Path]) -> Path:
    """Copy tests/data/scenarios/*.yaml to ``tmp_path`` with the test FMUs in ``fmus/``."""
    for src in DATA.glob("*.yaml"):
        shutil.copy(src, tmp_path / src.name)
    (tmp_path / "fmus").mkdir(exist_ok=True)
    for name in ("LeftMass", "RightMass", "Gain", "Params"):
        shutil.copy(test_fmus[name], tmp_path / "fmus" / f"{name}.fmu")
    write_md_only_fmu(tmp_path / "fmus" / "Mixed.fmu")
    return tmp_path


@pytest.fixture
def sdir(tmp_path, test_fmus) -> Path:
    return scenario_dir(tmp_path, test_fmus)


def problems_of(path, overrides=(), **kw) -> list[str]:
    with pytest.raises(ScenarioError) as info:
        load_scenario(path, overrides, **kw)
    assert info.value.problems, "a ScenarioError must list its problems"
    # one message lists them all
    for p in info.value.problems:
        assert p in str(info.value)
    return info.value.problems


def write(d: Path, text: str, name: str = "s.yaml") -> Path:
    p = d / name
    p.write_text(text)
    return p


def line_of(path: Path, needle: str) -> int:
    for i, line in enumerate(path.read_text().splitlines(), 1):
        if needle in line:
            return i
    raise AssertionError(f"{needle!r} not in {path}")


# ------------------------------------------------------------------ valid files
def test_valid_scenario_values_and_defaults(sdir):
    sc = load_scenario(sdir / "two_mass.yaml")
    assert sc.name == "two-mass-oscillator"
    assert sc.version == 1 and sc.start_time == 0.0 and sc.stop_time == 0.02
    assert [f.name for f in sc.fmus] == ["left", "right"]
    # paths are relative to the YAML file and come back absolute
    assert sc.fmu("left").path == (sdir / "fmus" / "LeftMass.fmu").resolve()
    assert sc.fmu("left").path.is_absolute()
    # 1e-3 (no dot) is a number, not YAML 1.1's string
    assert sc.coupling.macro_step == pytest.approx(1e-3)
    assert sc.fmu("left").parameters == {"m1": 1.0, "x1_0": 1e-3}
    assert sc.fmu("right").substeps == 4 and sc.fmu("left").substeps is None
    assert sc.fmu("left").line == line_of(sdir / "two_mass.yaml", "left:")
    assert [(c.src, c.dst) for c in sc.connections] == [
        ("left.x1", "right.x1"), ("left.v1", "right.v1"), ("right.F", "left.F")]
    assert sc.connections[2].src_instance == "right" and sc.connections[2].dst_variable == "F"
    assert sc.coupling.scheme == "gauss-seidel"
    assert sc.coupling.sequence == ("left", "right")       # default: order of `fmus`
    assert (sc.coupling.extrapolation_order, sc.coupling.interpolation_order, sc.coupling.substeps) == (1, 1, 1)
    assert sc.output.signals == ("left.x1", "right.F") and sc.output.interval == pytest.approx(1e-3)
    assert sc.source == (sdir / "two_mass.yaml").resolve()
    assert validate_scenario(sdir / "two_mass.yaml") == []


def test_minimal_scenario_defaults(sdir):
    p = write(sdir, "name: m\nstop_time: 1\nfmus:\n  g: {path: fmus/Gain.fmu}\n")
    sc = load_scenario(p)
    assert sc.stop_time == 1.0 and isinstance(sc.stop_time, float)
    assert sc.connections == () and sc.output.signals is None and sc.output.interval is None
    assert sc.coupling.sequence == ("g",) and sc.analysis is None and sc.compare is None


def test_parameter_values_take_the_fmu_type(sdir):
    p = write(sdir, "name: p\nstop_time: 1\nfmus:\n  p: {path: fmus/Params.fmu, parameters: "
                    "{a: 2, n: 3, flag: true, out_file: '{out_dir}/x.txt'}}\n")
    params = load_scenario(p).fmu("p").parameters
    assert params == {"a": 2.0, "n": 3, "flag": True, "out_file": "{out_dir}/x.txt"}
    assert type(params["a"]) is float and type(params["n"]) is int


def test_analysis_and_compare_pass_through(sdir):
    p = write(sdir, "name: a\nstop_time: 1\nfmus:\n  left: {path: fmus/LeftMass.fmu}\n"
                    "analysis:\n  speed: left.v1\n  journals:\n    b1: {x: left.x1, y: left.v1, eps: left.x1, "
                    "clearance: 1.0e-5}\ncompare:\n  variants: [{macro_step: 1e-4}]\n")
    sc = load_scenario(p)
    assert sc.analysis["journals"]["b1"]["clearance"] == 1e-5
    assert sc.compare == {"variants": [{"macro_step": 1e-4}]}


# ------------------------------------------------------------------ bad input (issue 2 item 5)
def test_malformed_yaml_names_file_line_and_column(sdir):
    problems = problems_of(sdir / "malformed.yaml")
    assert len(problems) == 1
    m = re.match(r"^(.*malformed\.yaml):(\d+):(\d+): malformed YAML: ", problems[0])
    assert m, problems[0]
    # the flow mapping opened on line 4 is never closed: the parser stops at line 5
    assert int(m.group(2)) in (4, 5)
    assert "fix the syntax" in problems[0]


def test_an_unquoted_array_element_in_a_flow_mapping_says_to_quote_it(sdir):
    """`parameters: {x[0]: 1.0}` (crane-fmu's HarmonicOscillator6D has x[0..5]) is a YAML error whose
    parser message ("expected ',' or '}', but got '['") does not say that the name needs quotes."""
    p = write(sdir, "name: a\nstop_time: 1\nfmus:\n  osc: {path: fmus/LeftMass.fmu, parameters: {x[0]: 1.0}}\n")
    problems = problems_of(p)
    assert len(problems) == 1 and ":4:" in problems[0]
    assert 'needs quotes inside { } or [ ]: {"x[0]": 1.0}' in problems[0], problems[0]
    # other syntax errors keep the general hint
    p = write(sdir, "name: a\nstop_time: 1\nfmus:\n  osc: {path: fmus/LeftMass.fmu\n")
    assert "needs quotes" not in problems_of(p)[0] and "a closing bracket" in problems_of(p)[0]


def test_unknown_keys_suggest_the_closest_valid_key(sdir):
    path = sdir / "unknown_keys.yaml"
    problems = problems_of(path)
    text = "\n".join(problems)
    assert f"unknown_keys.yaml:{line_of(path, 'stop_tme')}: unknown key 'stop_tme'" in text
    assert "did you mean 'stop_time'?" in text
    assert (f":{line_of(path, 'parameter:')}: unknown key 'parameter' in 'fmus.left'; "
            "did you mean 'parameters'?") in text
    assert (f":{line_of(path, 'macro_stepp')}: unknown key 'macro_stepp' in 'coupling'; "
            "did you mean 'macro_step'?") in text
    # and the misspelt required key is also reported as missing
    assert any("missing the required key 'stop_time'" in p for p in problems)


def test_missing_fmu_gives_the_resolved_path(sdir):
    path = sdir / "missing_fmu.yaml"
    problems = problems_of(path)
    assert len(problems) == 1
    resolved = (sdir / "fmus" / "NoSuchMass.fmu").resolve()
    assert problems[0].startswith(f"{path}:{line_of(path, 'NoSuchMass')}: FMU file of 'right' not found: {resolved}")
    assert "rotorcosim build-fmus" in problems[0]


def test_nonexistent_variable_lists_valid_names_closest_first(sdir):
    path = sdir / "bad_variable.yaml"
    problems = problems_of(path)
    assert len(problems) == 2
    first, second = problems
    assert first.startswith(f"{path}:{line_of(path, 'left.x,')}: ")
    assert "'left' has no variable 'x'" in first
    assert first.endswith("outputs of 'left' (closest first): x1, v1")
    assert second.startswith(f"{path}:{line_of(path, 'left.Force')}: ")
    assert "'left' has no variable 'Force'; inputs of 'left' (closest first): F" in second


def test_input_connected_twice(sdir):
    path = sdir / "input_twice.yaml"
    problems = problems_of(path)
    assert len(problems) == 1
    first, second = line_of(path, "left.x1, to: right.x1"), line_of(path, "left.v1, to: right.x1")
    assert problems[0].startswith(f"{path}:{second}: input 'right.x1' is connected twice (also on line {first})")


def test_type_mismatch(sdir):
    path = sdir / "type_mismatch.yaml"
    problems = problems_of(path)
    assert len(problems) == 2
    assert problems[0].startswith(f"{path}:{line_of(path, 'mixed.count')}: type mismatch: 'mixed.count' is "
                                  "Integer but 'left.F' is Real")
    assert "'left.x1' is Real but 'mixed.enable' is Boolean" in problems[1]


def test_non_positive_steps(sdir):
    path = sdir / "nonpositive_step.yaml"
    problems = problems_of(path)
    assert len(problems) == 2
    assert problems[0].startswith(f"{path}:{line_of(path, 'macro_step')}: 'coupling.macro_step' must be "
                                  "positive (got 0.0)")
    assert problems[1].startswith(f"{path}:{line_of(path, 'interval')}: 'output.interval' must be positive")


def test_every_problem_is_reported_at_once(sdir):
    p = write(sdir, """name: many
start_time: 1.0
stop_time: 0.5
fmus:
  left:  {path: fmus/LeftMass.fmu, parameters: {m: 1.0, x1_0: true, x1: 3}}
  right: {path: fmus/RightMass.fmu, substeps: 0}
  g: {path: fmus/Gain.fmu}
connections:
  - {from: left.v1, to: g.k}
  - {from: foo.y, to: left.F}
  - {from: left.F, to: right.x1}
coupling:
  scheme: gauss_seidel
  sequence: [left, right, left]
  extrapolation_order: 4
  interpolation_order: -1
output:
  signals: [left.x1, g.yy]
""")
    problems = problems_of(p)
    expected = [
        (3, "'stop_time' must be greater than start_time (1.0) (got 0.5)"),
        (5, "'left' has no parameter 'm'; parameters of 'left' (closest first): m1"),
        (5, "parameter 'left.x1_0' is Real (got True, a boolean)"),
        (5, "'left.x1' is a continuous output, not a parameter"),
        (6, "'fmus.right.substeps' must be between 1 and 10000 (got 0)"),
        (9, "'g.k' is a parameter, but the 'to' side of a connection must be an input; inputs of 'g': u"),
        (10, "names the instance 'foo', which is not in 'fmus'"),
        (11, "'left.F' is an input, but the 'from' side of a connection must be an output"),
        (13, "'coupling.scheme' must be one of ['gauss-seidel', 'jacobi', 'iterative', 'monolithic'] (got 'gauss_seidel', "
             "a string); did you mean 'gauss-seidel'?"),
        (14, "'coupling.sequence' must list every instance exactly once (left listed more than once; missing g)"),
        (15, "'coupling.extrapolation_order' must be between 0 and 3 (got 4)"),
        (16, "'coupling.interpolation_order' must be between 0 and 3 (got -1)"),
        (18, "'g' has no variable 'yy'; variables of 'g' (closest first): y"),
    ]
    for line, text in expected:
        assert any(q.startswith(f"{p}:{line}: ") and text in q for q in problems), (line, text, problems)
    assert len(problems) == len(expected)
    # sorted by line
    lines = [int(re.match(r".*?:(\d+): ", q).group(1)) for q in problems]
    assert lines == sorted(lines)


@pytest.mark.parametrize("text, needle", [
    ("", "got an empty file"),
    ("- a\n- b\n", "'top level' must be a mapping (got a list)"),
    ("name: x\n", "missing the required key 'stop_time'"),
    ("name: x\nstop_time: 1\nfmus: {}\n", "'fmus' must list at least one FMU instance"),
    ("name: x\nstop_time: soon\nfmus:\n  g: {path: fmus/Gain.fmu}\n",
     "'stop_time' must be a finite number (got 'soon'"),
    ("name: x\nstop_time: .nan\nfmus:\n  g: {path: fmus/Gain.fmu}\n", "'stop_time' must be a finite number"),
    ("name: x\nversion: 2\nstop_time: 1\nfmus:\n  g: {path: fmus/Gain.fmu}\n", "version 2 is not supported"),
    ("name: a/b\nstop_time: 1\nfmus:\n  g: {path: fmus/Gain.fmu}\n", "'name' is used as a folder name"),
    ("name: x\nstop_time: 1\nfmus:\n  g.1: {path: fmus/Gain.fmu}\n", "instance name must start with a letter"),
    ("name: x\nstop_time: 1\nfmus:\n  g: fmus/Gain.fmu\n", "'fmus.g' must be a mapping (got 'fmus/Gain.fmu'"),
    ("name: x\nstop_time: 1\nfmus:\n  g: {path: fmus/Gain.fmu}\n  g: {path: fmus/Gain.fmu}\n",
     "key 'g' appears twice in 'fmus' (first on line 4)"),
    ("name: x\nstop_time: 1\nfmus:\n  g: {path: fmus/Gain.fmu}\ncoupling: {macro_step: 2}\n",
     "'coupling.macro_step' must not exceed stop_time - start_time"),
    ("name: x\nstop_time: 1\nfmus:\n  g: {path: fmus/Gain.fmu}\ncoupling: {substeps: 0}\n",
     "'coupling.substeps' must be between 1 and 10000 (got 0)"),
    ("name: x\nstop_time: 1\nfmus:\n  g: {path: fmus/Gain.fmu}\ncoupling: {extrapolation_order: 1.5}\n",
     "'coupling.extrapolation_order' must be an integer (got 1.5"),
    ("name: x\nstop_time: 1\nfmus:\n  g: {path: fmus/Gain.fmu}\nconnections: {from: g.y, to: g.u}\n",
     "'connections' must be a list (got a mapping)"),
    ("name: x\nstop_time: 1\nfmus:\n  g: {path: fmus/Gain.fmu}\nconnections:\n  - {from: g.y}\n",
     "'connections[0]' is missing the required key 'to'"),
    ("name: x\nstop_time: 1\nfmus:\n  g: {path: fmus/Gain.fmu}\nconnections:\n  - {from: y, to: g.u}\n",
     "'connections[0].from' must be 'instance.variable' (got 'y')"),
    ("name: x\nstop_time: 1\nfmus:\n  g: {path: fmus/Gain.fmu}\noutput: {signals: [g.y, g.y]}\n",
     "'output.signals' lists 'g.y' twice"),
    ("name: x\nstop_time: 1\nfmus:\n  g: {path: fmus/Gain.fmu}\nanalysis: [g.y]\n", "'analysis' must be a mapping"),
    ("name: x\nstop_time: 1\nfmus:\n  g: {path: fmus/Gain.fmu}\nanalysis: {speed: g.omega}\n",
     "'analysis.speed': 'g' has no variable 'omega'"),
    ("name: x\nstop_time: 1\nfmus:\n  g: {path: fmus/Gain.fmu}\noutput: {signals: [g.u]}\nanalysis: {speed: g.y}\n",
     "'analysis.speed' is 'g.y', which is not recorded (not in output.signals)"),
    # the analysis section is checked as the run-up analysis will read it (docs/analysis.md)
    ("name: x\nstop_time: 1\nfmus:\n  g: {path: fmus/Gain.fmu}\noutput: {signals: [g.u, g.y]}\nanalysis: {speed: g.y, journals: {b1: {x: g.u, y: g.y}}, extra: 1}\n",
     "unknown key 'extra' in 'analysis'; valid keys: speed, journals, fields, whirl"),
    ("name: x\nstop_time: 1\nfmus:\n  g: {path: fmus/Gain.fmu}\noutput: {signals: [g.u, g.y]}\nanalysis: {journals: {b1: {x: g.u, y: g.y, clearance: 1.0e-5}}}\n",
     "'analysis' is missing the required key 'speed'"),
    ("name: x\nstop_time: 1\nfmus:\n  g: {path: fmus/Gain.fmu}\noutput: {signals: [g.u, g.y]}\nanalysis: {speed: g.y, journals: {}}\n", "'analysis.journals' is empty; name at least one journal"),
    ("name: x\nstop_time: 1\nfmus:\n  g: {path: fmus/Gain.fmu}\noutput: {signals: [g.u, g.y]}\nanalysis: {speed: g.y, journals: {b1: {x: g.u, y: g.y}}}\n",
     "'analysis.journals.b1' needs 'clearance' [m] (or an 'eps' signal to estimate it from)"),
    ("name: x\nstop_time: 1\nfmus:\n  g: {path: fmus/Gain.fmu}\noutput: {signals: [g.u, g.y]}\nanalysis: {speed: g.y, journals: {b1: {x: g.u, clearance: 1.0e-5}}}\n",
     "'analysis.journals.b1' is missing the required key 'y'"),
    ("name: x\nstop_time: 1\nfmus:\n  g: {path: fmus/Gain.fmu}\noutput: {signals: [g.u, g.y]}\nanalysis: {speed: g.y, journals: {b1: {x: g.u, y: g.y, clearance: -1}}}\n",
     "'analysis.journals.b1.clearance' must be positive (got -1"),
    ("name: x\nstop_time: 1\nfmus:\n  g: {path: fmus/Gain.fmu}\noutput: {signals: [g.u, g.y]}\nanalysis: {speed: g.y, journals: {b1: {x: g.u, y: g.y, clearance: 1.0e-5}}, fields: [g]}\n", "'analysis.fields' must be a non-empty text (got a list)"),
    ("name: x\nstop_time: 1\nfmus:\n  g: {path: fmus/Gain.fmu}\noutput: {signals: [g.u, g.y]}\nanalysis: {speed: g.y, journals: {b1: {x: g.u, y: g.y, clearance: 1.0e-5}}, whirl: {window_rev: 8}}\n", "unknown key 'window_rev' in 'analysis.whirl'; did you mean 'window_revs'?"),
    ("name: x\nstop_time: 1\nfmus:\n  g: {path: fmus/Gain.fmu}\noutput: {signals: [g.u, g.y]}\nanalysis: {speed: g.y, journals: {b1: {x: g.u, y: g.y, clearance: 1.0e-5}}, whirl: {band: 0.5}}\n", "'analysis.whirl.band' must be a list of two orders [low, high] (got 0.5"),
    ("name: x\nstop_time: 1\nfmus:\n  g: {path: fmus/Gain.fmu}\noutput: {signals: [g.u, g.y]}\nanalysis: {speed: g.y, journals: {b1: {x: g.u, y: g.y, clearance: 1.0e-5}}, whirl: {hop_revs: often}}\n", "'analysis.whirl.hop_revs' must be a finite number (got 'often'"),
    ("name: x\nstop_time: 1\nfmus:\n  g: {path: fmus/Gain.fmu}\noutput: {signals: [g.u, g.y]}\nanalysis: {speed: g.y, journals: {b1: {x: g.u, y: g.y, clearance: 1.0e-5}}, whirl: {band: [0.9, 0.1], threshold: -1}}\n",
     "band must satisfy 0 < low < high < 1 (got (0.9, 0.1)); threshold must be > 0 (got -1.0)"),
])
def test_structural_problems(sdir, text, needle):
    problems = problems_of(write(sdir, text))
    assert any(needle in p for p in problems), problems
    assert all(re.match(rf"^{re.escape(str(sdir / 's.yaml'))}:\d+(:\d+)?: ", p) for p in problems), problems


def test_unreadable_fmu_is_a_problem_with_file_and_line(sdir):
    (sdir / "fmus" / "Broken.fmu").write_text("not a zip")
    write_md_only_fmu(sdir / "fmus" / "ME.fmu", MIXED_MD.replace(
        '<CoSimulation modelIdentifier="Mixed" canHandleVariableCommunicationStepSize="true"/>',
        '<ModelExchange modelIdentifier="Mixed"/>'))
    p = write(sdir, "name: x\nstop_time: 1\nfmus:\n  b: {path: fmus/Broken.fmu}\n  me: {path: fmus/ME.fmu}\n"
                    "connections:\n  - {from: b.y, to: me.u}\n")
    problems = problems_of(p)
    assert len(problems) == 2, problems      # no follow-up errors for the connection of unreadable FMUs
    assert problems[0].startswith(f"{p}:4: FMU of 'b' cannot be used: ") and "not a valid zip" in problems[0]
    assert problems[1].startswith(f"{p}:5: FMU of 'me' cannot be used: ") and "CoSimulation" in problems[1]


def test_parameter_problems_list_valid_parameters(sdir):
    p = write(sdir, "name: x\nstop_time: 1\nfmus:\n  p: {path: fmus/Params.fmu, parameters: "
                    "{flagg: true, n: 2.5, a: yes, out_file: 3}}\n")
    text = "\n".join(problems_of(p))
    assert "'p' has no parameter 'flagg'; parameters of 'p' (closest first): flag," in text
    assert "parameter 'p.n' is Integer (got 2.5, a number)" in text
    assert "parameter 'p.a' is Real (got True, a boolean)" in text
    assert "parameter 'p.out_file' is String (got 3, an integer)" in text


def test_signals_of_every_type_are_coupled_and_recorded(sdir):
    write_md_only_fmu(sdir / "fmus" / "Mixed2.fmu")
    p = write(sdir, "name: x\nstop_time: 1\nfmus:\n  a: {path: fmus/Mixed.fmu}\n  b: {path: fmus/Mixed2.fmu}\n"
                    "connections:\n  - {from: a.y, to: b.u}\n  - {from: b.y, to: a.u, gain: 2}\n")
    assert load_scenario(p).connections[1].gain == 2.0      # Real with gain: fine
    md = MIXED_MD.replace('<Boolean start="false"/>', '<Integer start="0"/>')
    write_md_only_fmu(sdir / "fmus" / "Mixed3.fmu", md)
    p = write(sdir, "name: x\nstop_time: 1\nfmus:\n  a: {path: fmus/Mixed.fmu}\n  c: {path: fmus/Mixed3.fmu}\n"
                    "connections:\n  - {from: a.count, to: c.enable}\noutput: {signals: [a.y, a.count]}\n")
    sc = load_scenario(p)                                   # Integer -> Integer, Integer recorded: fine
    assert sc.output.signals == ("a.y", "a.count")
    # Integer -> Boolean: a type mismatch naming both ends; gain on a non-Real connection: refused
    p = write(sdir, "name: x\nstop_time: 1\nfmus:\n  a: {path: fmus/Mixed.fmu}\n  b: {path: fmus/Mixed2.fmu}\n"
                    "  c: {path: fmus/Mixed3.fmu}\n"
                    "connections:\n  - {from: a.count, to: b.enable}\n  - {from: a.count, to: c.enable, gain: 2}\n")
    problems = problems_of(p)
    assert len(problems) == 2, problems
    assert problems[0].startswith(f"{p}:8: type mismatch: 'a.count' is Integer but 'b.enable' is Boolean")
    assert problems[1].startswith(f"{p}:9: 'gain' of the connection 'a.count' -> 'c.enable': gain and offset "
                                  "apply to Real connections only (this one is Integer")


def test_start_values_of_states_and_range_checks(sdir):
    md = MIXED_MD.replace('<Real start="0"/></ScalarVariable>\n  </ModelVariables>',
                          '<Real start="0" min="-1" max="1"/></ScalarVariable>\n  </ModelVariables>')
    write_md_only_fmu(sdir / "fmus" / "Ranged.fmu", md)
    ok = write(sdir, "name: x\nstop_time: 1\nfmus:\n  a: {path: fmus/Ranged.fmu, parameters: {y: 0.5, count: 3}}\n")
    assert dict(load_scenario(ok).fmu("a").parameters) == {"y": 0.5, "count": 3}   # initial="exact" outputs
    bad = write(sdir, "name: x\nstop_time: 1\nfmus:\n  a: {path: fmus/Ranged.fmu, parameters: "
                      "{y: 2.0, count: 3000000000, u: .nan}}\n")
    problems = problems_of(bad)
    assert len(problems) == 3, problems
    assert any("'a.y' = 2.0 is outside its declared range [-1.0, 1.0]" in q for q in problems)
    assert any("'a.count' is Integer, a 32-bit integer" in q and "3000000000" in q for q in problems)
    assert any("'a.u' is Real and must be finite (got nan)" in q for q in problems)


# ------------------------------------------------------------------ --set overrides
def test_overrides_change_values(sdir):
    sc = load_scenario(sdir / "two_mass.yaml", [
        "coupling.macro_step=5e-4", "stop_time=0.01", "fmus.left.parameters.k1=2",
        "connections.2.gain=3", "output.signals=[left.v1]", "coupling.scheme=jacobi",
        "fmus.right.path=fmus/RightMass.fmu", "coupling.options.note=hello"])
    assert sc.coupling.macro_step == 5e-4 and sc.stop_time == 0.01
    assert sc.fmu("left").parameters["k1"] == 2.0
    assert sc.connections[2].gain == 3.0
    assert sc.output.signals == ("left.v1",)
    assert sc.coupling.scheme == "jacobi"
    assert sc.coupling.options == {"note": "hello"}
    # the file itself is untouched
    assert load_scenario(sdir / "two_mass.yaml").coupling.macro_step == 1e-3


def test_override_creates_missing_sections(sdir):
    p = write(sdir, "name: m\nstop_time: 1\nfmus:\n  g: {path: fmus/Gain.fmu}\n")
    sc = load_scenario(p, ["output.interval=0.1", "coupling.extrapolation_order=2", "fmus.g.parameters.k=4"])
    assert sc.output.interval == 0.1 and sc.coupling.extrapolation_order == 2
    assert sc.fmu("g").parameters == {"k": 4.0}


@pytest.mark.parametrize("override, needle", [
    ("coupling.macro_stp=1e-4", "unknown key 'macro_stp' in 'coupling'; did you mean 'macro_step'?"),
    ("coupling.macro_step=-1e-4", "'coupling.macro_step' must be positive (got -0.0001)"),
    ("coupling.macro_step=0", "'coupling.macro_step' must be positive (got 0)"),
    ("stoptime=1", "unknown key 'stoptime' in 'top level'; did you mean 'stop_time'?"),
    ("fmus.lefty.path=x.fmu", "unknown instance 'lefty' in 'fmus'; did you mean 'left'?"),
    ("connections.7.gain=2", "'connections' has entries 0..2 (got '7')"),
    ("connections.0.gane=2", "unknown key 'gane' in 'connections.0'; did you mean 'gain'?"),
    ("stop_time.x=1", "'stop_time' is a single value, not a section"),
    ("macro_step", "expected KEY.PATH=VALUE (got 'macro_step')"),
    ("=3", "expected KEY.PATH=VALUE"),
    ("coupling.macro_step=[1, 2", "the value is not valid YAML"),
    ("fmus.left.parameters.mass=2", "'left' has no parameter 'mass'"),
    ("coupling.scheme=gauss_seidel", "did you mean 'gauss-seidel'?"),
])
def test_bad_overrides(sdir, override, needle):
    problems = problems_of(sdir / "two_mass.yaml", [override])
    assert len(problems) == 1, problems
    assert problems[0].startswith(f"--set {override}: "), problems[0]
    assert needle in problems[0], problems[0]


def test_scenario_error_is_a_cosim_error():
    assert issubclass(ScenarioError, CosimError)


def test_unreadable_scenario_file(tmp_path):
    with pytest.raises(ScenarioError, match=r"nope\.yaml: scenario file not found"):
        load_scenario(tmp_path / "nope.yaml")
    (tmp_path / "bin.yaml").write_bytes(b"\xff\xfe\x00")
    with pytest.raises(ScenarioError, match="not UTF-8"):
        load_scenario(tmp_path / "bin.yaml")


def test_fmu_instantiable_once_cannot_serve_two_instances(sdir):
    write_md_only_fmu(sdir / "fmus" / "Once.fmu", MIXED_MD.replace(
        'canHandleVariableCommunicationStepSize="true"',
        'canHandleVariableCommunicationStepSize="true" canBeInstantiatedOnlyOncePerProcess="true"'))
    p = write(sdir, "name: x\nstop_time: 1\nfmus:\n  a: {path: fmus/Once.fmu}\n  b: {path: fmus/Once.fmu}\n")
    problems = problems_of(p)
    assert len(problems) == 1 and problems[0].startswith(f"{p}:5: FMU Once.fmu declares "
                                                         "canBeInstantiatedOnlyOncePerProcess")
    # two instances of an ordinary FMU are fine
    p = write(sdir, "name: x\nstop_time: 1\nfmus:\n  a: {path: fmus/Mixed.fmu}\n  b: {path: fmus/Mixed.fmu}\n")
    assert [f.name for f in load_scenario(p).fmus] == ["a", "b"]


def test_own_fmus_are_built_before_they_are_read(sdir, test_fmus, monkeypatch):
    """Loading reads and checks only (issue 12); with ``build_fmus=True`` (what run and
    validate do) load_scenario hands the draft scenario to orchestrator.fmi.build.ensure_fmus
    first."""
    from orchestrator.fmi import build
    calls = []

    def fake_ensure(scenario):
        calls.append(scenario)
        shutil.copy(test_fmus["RightMass"], sdir / "fmus" / "NoSuchMass.fmu")   # "builds" the missing FMU
        return [sdir / "fmus" / "NoSuchMass.fmu"]
    monkeypatch.setattr(build, "ensure_fmus", fake_ensure)
    path = sdir / "missing_fmu.yaml"
    # only checking: not built, reported with the command that builds it
    assert any("rotorcosim build-fmus" in p for p in validate_scenario(path, build_fmus=False))
    assert calls == []
    # a scenario with other problems is not built either
    assert validate_scenario(path, ["stop_time=-1"]) and calls == []
    # loading does not build: refused with the command that builds it
    with pytest.raises(ScenarioError, match="rotorcosim build-fmus"):
        load_scenario(path)
    assert calls == []
    sc = load_scenario(path, build_fmus=True)
    assert len(calls) == 1 and calls[0].name == "missing-fmu"
    assert calls[0].fmu("right").path == (sdir / "fmus" / "NoSuchMass.fmu").resolve()
    assert sc.fmu("right").path.is_file()


def test_build_failure_is_a_scenario_problem(sdir, monkeypatch):
    from orchestrator.fmi import build

    def failing(scenario):
        raise RuntimeError("pythonfmu exploded")
    monkeypatch.setattr(build, "ensure_fmus", failing)
    problems = problems_of(sdir / "two_mass.yaml", build_fmus=True)
    assert problems == [f"{sdir / 'two_mass.yaml'}: building the scenario's FMUs failed (RuntimeError: pythonfmu "
                        "exploded); run `rotorcosim build-fmus --force` to see the details"]


def test_override_of_an_aliased_section_changes_only_that_path(sdir):
    p = write(sdir, "name: m\nstop_time: 1\nfmus:\n  g1: {path: fmus/Gain.fmu, parameters: &p {k: 2.0}}\n"
                    "  g2: {path: fmus/Gain.fmu, parameters: *p}\n")
    sc = load_scenario(p, ["fmus.g1.parameters.k=5"])
    assert sc.fmu("g1").parameters == {"k": 5.0}
    assert sc.fmu("g2").parameters == {"k": 2.0}
    problems = problems_of(p, ["fmus.g1.parameters.kk=5"])
    assert len(problems) == 1 and "'g1' has no parameter 'kk'" in problems[0]


def test_yaml_merge_keys_explicit_keys_win(sdir):
    p = write(sdir, "name: m\nstop_time: 1\nbase: &base {path: fmus/Gain.fmu, parameters: {k: 2.0}}\n"
                    "fmus:\n  g1: {<<: *base}\n  g2: {<<: *base, parameters: {k: 3.0}}\n")
    problems = problems_of(p)                  # 'base' is not a scenario key: say so
    assert len(problems) == 1 and "unknown key 'base'" in problems[0]
    p = write(sdir, "name: m\nstop_time: 1\nfmus:\n  g1: &base {path: fmus/Gain.fmu, parameters: {k: 2.0}}\n"
                    "  g2: {<<: *base, parameters: {k: 3.0}}\n")
    sc = load_scenario(p)
    assert sc.fmu("g1").parameters == {"k": 2.0} and sc.fmu("g2").parameters == {"k": 3.0}
    assert sc.fmu("g2").path == sc.fmu("g1").path


def test_unreadable_yaml_values_are_reported_with_their_line(sdir):
    p = write(sdir, "name: x\nstop_time: !!python/object:os.system ls\nfmus:\n  g: {path: fmus/Gain.fmu}\n")
    problems = problems_of(p)
    assert problems[-1].startswith(f"{p}:2: cannot read this value (could not determine a constructor")


OSP_XML = """<OspSystemStructure xmlns="http://opensimulationplatform.com/MSMI/OSPSystemStructure" version="0.1">
   <StartTime>0.0</StartTime>
   <BaseStepSize>0.01</BaseStepSize>
   <Simulators>
      <Simulator name="crane" source="MobileCraneStraight.fmu" stepSize="0.01"/>
      <Simulator name="osc" source="HarmonicOscillator6D.fmu" stepSize="0.01" />
   </Simulators>
</OspSystemStructure>"""


@pytest.mark.parametrize("name, text, needle", [
    # the OSP system structure that the crane-fmu wheel ships beside its FMUs
    ("CraneOnOscillatorSystemStructure.xml", OSP_XML,
     "is an XML file (root element <OspSystemStructure>), not a scenario: rotorcosim reads YAML scenarios"),
    ("modelDescription.xml", '<?xml version="1.0" encoding="UTF-8"?>\n<!-- made by hand -->\n'
     '<fmiModelDescription fmiVersion="2.0" modelName="M" guid="{x}">\n</fmiModelDescription>\n',
     "(root element <fmiModelDescription>), not a scenario: rotorcosim reads YAML scenarios"),
    ("system.xml", '<ssd:SystemStructureDescription xmlns:ssd="http://ssp-standard.org/SSP1/'
     'SystemStructureDescription" version="1.0" name="s"/>\n',
     "it is an SSD: give it the extension .ssd and it is read as one"),
])
def test_an_xml_file_is_named_as_such_not_quoted_whole(tmp_path, name, text, needle):
    """An XML file given as a scenario read as one YAML string, and the message quoted all of it
    (1.4 kB for crane-fmu's CraneOnOscillatorSystemStructure.xml) as "'top level' must be a mapping"."""
    p = tmp_path / name
    p.write_text(text)
    with pytest.raises(ScenarioError) as info:
        load_scenario(p)
    msg = str(info.value)
    assert f"{name}:1: " in msg and needle in msg
    assert "Simulator name" not in msg and "must be a mapping" not in msg


def test_a_long_text_that_came_is_quoted_by_its_start():
    p_text = "word " * 100          # YAML reads it without the last blank: 499 characters
    from orchestrator.scenario.nodes import GOT_CHARS
    import tempfile
    with tempfile.TemporaryDirectory() as d:
        p = Path(d) / "s.yaml"
        p.write_text(p_text)
        with pytest.raises(ScenarioError) as info:
            load_scenario(p)
    msg = str(info.value)
    assert f"'top level' must be a mapping (got {p_text[:GOT_CHARS]!r}... (499 characters), a string)" in msg


def test_gauss_seidel_with_interpolation_order_below_the_extrapolation_order_warns(test_fmus, tmp_path, caplog):
    """q < k under Gauss-Seidel caps the coupling's order at q + 1 for the inputs fed by FMUs
    stepped earlier (measured: k = 1, q = 0 order 1.01, q = 1 order 1.97, two crane-fmu
    oscillators in a loop); the scenario said nothing."""
    import logging
    from orchestrator.scenario import checks

    def load(coupling: str, name: str):
        p = tmp_path / f"{name}.yaml"
        p.write_text(f"name: {name}\nstop_time: 1.0\nfmus:\n  left: {{path: {test_fmus['LeftMass']}}}\n"
                     f"  right: {{path: {test_fmus['RightMass']}}}\nconnections:\n"
                     "  - {from: left.x1, to: right.x1}\n  - {from: left.v1, to: right.v1}\n"
                     f"  - {{from: right.F, to: left.F}}\ncoupling: {coupling}\n")
        checks._WARNED.clear()
        caplog.clear()
        with caplog.at_level(logging.WARNING):
            load_scenario(p)
        return [r.getMessage() for r in caplog.records if "interpolation_order" in r.getMessage()]

    said = load("{scheme: gauss-seidel, extrapolation_order: 1, macro_step: 0.01}", "q0")
    assert said == [f"{tmp_path / 'q0.yaml'}:10: 'coupling.interpolation_order' 0 with extrapolation_order 1 under "
                    "gauss-seidel: right.x1, right.v1 come from FMUs stepped earlier in the sequence and get a "
                    "degree-0 polynomial through the new values, so the coupling is of order 1 at most, not up to 2; "
                    "set interpolation_order: 1 (docs/coupling.md, \"One macro step\")"]
    assert "left.F" not in said[0]                       # fed by the later FMU: extrapolated
    said = load("{scheme: gauss-seidel, sequence: [right, left], extrapolation_order: 2, interpolation_order: 1, "
                "macro_step: 0.01}", "rev")
    assert len(said) == 1 and "left.F comes from an FMU stepped earlier" in said[0] and "not up to 3" in said[0]
    assert load("{scheme: gauss-seidel, extrapolation_order: 1, interpolation_order: 1, macro_step: 0.01}", "q1") == []
    assert load("{scheme: jacobi, extrapolation_order: 2, macro_step: 0.01}", "jac") == []
    assert load("{scheme: gauss-seidel, macro_step: 0.01}", "k0") == []


def test_arrays_of_different_sizes_are_refused_with_the_connections_to_write():
    """`drv.f -> osc.f` between a 3-element and a 6-element array (crane-fmu's DrivingForce and
    HarmonicOscillator6D) names the element connections to write instead of only 'one by one'."""
    from types import SimpleNamespace

    from orchestrator.scenario.completion import Completion
    errors = []
    stub = SimpleNamespace(mds={"drv": {f"f[{i}]": None for i in range(3)},
                                "osc": {f"f[{i}]": None for i in range(6)}},
                           err=lambda node, msg: errors.append(msg))
    out = Completion.expand_arrays(stub, [{"from": "drv.f", "to": "osc.f", "node": None}])
    assert out == [] and len(errors) == 1
    assert "index sets differ (0, 1, 2 vs 0, 1, 2, 3, 4, 5)" in errors[0]
    assert "'drv.f[0] -> osc.f[0]', 'drv.f[1] -> osc.f[1]', 'drv.f[2] -> osc.f[2]'" in errors[0]
    assert "\n" not in errors[0]                                  # one problem, one line
