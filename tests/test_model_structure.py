"""``<ModelStructure>`` of a model description (FMI 2.0 sec. 2.2.8): what is refused, what is
accepted as real FMUs write it, and what ``rotorcosim info`` shows of it.

The FMUs here carry only a model description (``hostile_builders.write_fmu``), except our own
(``fmus/``), pythonfmu's (``test_fmus``) and the PythonFMU FMUs of the ``crane-fmu`` wheel
(fetched from PyPI at test time; skipped offline).
"""

from __future__ import annotations

import logging
import re
import time
import warnings
from pathlib import Path

import pytest

import third_party
from hostile_builders import VARS, cli, md_xml, write_fmu
from orchestrator.errors import FmuError
from orchestrator.fmi import model_description
from orchestrator.fmi.archive import read_model_description

# VARS: 1 u (input), 2 y (output), 3 k (parameter)
STATE = ('<ScalarVariable name="x" valueReference="3" causality="local"><Real start="0"/></ScalarVariable>'
         '<ScalarVariable name="der(x)" valueReference="4" causality="local"><Real derivative="4"/></ScalarVariable>')
Y2 = '<ScalarVariable name="y2" valueReference="5" causality="output"><Real/></ScalarVariable>'


def ms(outputs: str = '<Unknown index="2"/>', extra: str = "") -> str:
    return f"<ModelStructure><Outputs>{outputs}</Outputs>{extra}</ModelStructure>"


def fmu_with(tmp_path: Path, structure: str, variables: str = VARS) -> Path:
    return write_fmu(tmp_path / "m.fmu", md_xml(variables=variables, structure=structure))


@pytest.fixture
def no_warnings(caplog):
    """Fails the test if reading logs a warning or issues a Python warning."""
    caplog.set_level(logging.DEBUG)
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        yield
    assert not [r for r in caplog.records if r.levelno >= logging.WARNING], caplog.text


# --------------------------------------------------------------------------- refused
REFUSED = [
    # index
    (ms('<Unknown index="0"/>'), VARS, "ModelStructure/Outputs: Unknown index 0 is outside 1..3"),
    (ms('<Unknown index="4"/>'), VARS, "ModelStructure/Outputs: Unknown index 4 is outside 1..3"),
    (ms('<Unknown index="99999999999"/>'), VARS,
     "ModelStructure/Outputs: Unknown index '99999999999' is not a positive integer"),
    (ms('<Unknown index="two"/>'), VARS, "ModelStructure/Outputs: Unknown index 'two' is not a positive integer"),
    (ms('<Unknown index="-2"/>'), VARS, "ModelStructure/Outputs: Unknown index '-2' is not a positive integer"),
    (ms('<Unknown index="2.0"/>'), VARS, "ModelStructure/Outputs: Unknown index '2.0' is not a positive integer"),
    (ms('<Unknown/>'), VARS, "ModelStructure/Outputs: an Unknown has no index attribute"),
    (ms(extra='<InitialUnknowns><Unknown index="7"/></InitialUnknowns>'), VARS,
     "ModelStructure/InitialUnknowns: Unknown index 7 is outside 1..3"),
    # Outputs against the causalities
    (ms('<Unknown index="1"/><Unknown index="2"/>'), VARS,
     "ModelStructure/Outputs: Unknown index 1 is variable 'u' of causality 'input'; every Outputs entry must be "
     "a variable of causality 'output'"),
    (ms('<Unknown index="2"/><Unknown index="2"/>'), VARS,
     "ModelStructure/Outputs: Unknown index 2 ('y') is listed twice"),
    (ms('<Unknown index="2"/>'), VARS + Y2, "ModelStructure/Outputs does not list the output 'y2' (index 4); it must "
                                            "have one Unknown per variable of causality 'output'"),
    # Derivatives
    (ms(extra='<Derivatives><Unknown index="3"/></Derivatives>'), VARS,
     "ModelStructure/Derivatives: Unknown index 3 is variable 'k', which is no state derivative (expected a Real "
     "with a derivative attribute)"),
    (ms(), VARS + '<ScalarVariable name="d" valueReference="3"><Real derivative="x"/></ScalarVariable>',
     "variable 'd': derivative 'x' is not a ScalarVariable index (a positive integer)"),
    (ms(), VARS + '<ScalarVariable name="d" valueReference="3"><Real derivative="9"/></ScalarVariable>',
     "variable 'd': derivative 9 is outside 1..4"),
    # dependencies
    (ms('<Unknown index="2" dependencies="1 x"/>'), VARS,
     "ModelStructure/Outputs: Unknown index 2 ('y'): dependencies entry 'x' is not a ScalarVariable index"),
    (ms('<Unknown index="2" dependencies="1,3"/>'), VARS,
     "Unknown index 2 ('y'): dependencies entry '1,3' is not a ScalarVariable index"),
    (ms('<Unknown index="2" dependencies="0"/>'), VARS, "Unknown index 2 ('y'): dependencies entry 0 is outside 1..3"),
    (ms('<Unknown index="2" dependencies="1 7"/>'), VARS,
     "Unknown index 2 ('y'): dependencies entry 7 is outside 1..3"),
    (ms('<Unknown index="2" dependencies="1 3 1"/>'), VARS, "Unknown index 2 ('y'): dependencies lists index 1 twice"),
    (ms(extra='<InitialUnknowns><Unknown index="2" dependencies="3 4"/></InitialUnknowns>'), VARS,
     "ModelStructure/InitialUnknowns: Unknown index 2 ('y'): dependencies entry 4 is outside 1..3"),
    # dependenciesKind
    (ms('<Unknown index="2" dependencies="1" dependenciesKind="dependent constant"/>'), VARS,
     "Unknown index 2 ('y'): dependenciesKind has 2 entries, dependencies 1; they must have the same number"),
    (ms('<Unknown index="2" dependencies="1 3" dependenciesKind="dependent"/>'), VARS,
     "Unknown index 2 ('y'): dependenciesKind has 1 entries, dependencies 2"),
    (ms('<Unknown index="2" dependencies="1" dependenciesKind="linear"/>'), VARS,
     "Unknown index 2 ('y'): dependenciesKind entry 'linear' is not one of dependent, constant, fixed, tunable, "
     "discrete"),
    (ms('<Unknown index="2" dependenciesKind="dependent"/>'), VARS,
     "Unknown index 2 ('y'): has a dependenciesKind but no dependencies"),
    # the lists themselves
    (ms(extra='<Outputs><Unknown index="2"/></Outputs>'), VARS, "<ModelStructure> has more than one <Outputs> element"),
]


@pytest.mark.parametrize("structure, variables, words", REFUSED, ids=[f"r{i}" for i in range(len(REFUSED))])
def test_an_inconsistent_model_structure_is_refused(tmp_path, capsys, structure, variables, words):
    fmu = fmu_with(tmp_path, structure, variables)
    rc, out = cli(capsys, "info", fmu)
    assert rc == 1 and f"{fmu}: " in out and words in out and "re-export the FMU" in out, out
    with pytest.raises(FmuError, match="re-export the FMU"):
        read_model_description(fmu)


def test_validate_names_the_fmu_whose_model_structure_is_refused(tmp_path, capsys):
    fmu_with(tmp_path, ms('<Unknown index="5"/>'))
    (tmp_path / "s.yaml").write_text("name: s\nstop_time: 0.01\nfmus:\n  a: {path: m.fmu}\n"
                                     "coupling:\n  macro_step: 1.0e-3\n")
    rc, out = cli(capsys, "validate", tmp_path / "s.yaml")
    assert rc == 1 and "FMU of 'a' cannot be used" in out and "Unknown index 5 is outside 1..3" in out, out


def test_the_number_of_dependencies_is_bounded(tmp_path, monkeypatch):
    monkeypatch.setattr(model_description, "MAX_DEPENDENCIES", 3)
    fmu = fmu_with(tmp_path, ms('<Unknown index="2" dependencies="1 3"/>',
                                '<InitialUnknowns><Unknown index="2" dependencies="1 3"/></InitialUnknowns>'))
    with pytest.raises(FmuError, match=r"<ModelStructure> declares more than 3 dependencies; raise "
                                       r"orchestrator.fmi.model_description.MAX_DEPENDENCIES"):
        read_model_description(fmu)


def test_huge_attributes_and_lists_are_refused_in_linear_time(tmp_path):
    """A million-entry dependencies or dependenciesKind, 300 000 Unknowns: refused (or counted)
    at the first wrong entry, one token at a time, without a list of the attribute's words.
    The check adds well under a second to the XML parse (measured: 0.0, 0.2 and 0.0 s beside
    0.06, 0.16 and about 1 s of XML)."""
    from orchestrator.untrusted import parse_xml
    n = 10**6
    cases = [
        (ms(f'<Unknown index="2" dependencies="{"1 " * n}"/>'), "dependencies lists index 1 twice"),
        (ms(f'<Unknown index="2" dependencies="1" dependenciesKind="{"dependent " * n}"/>'),
         f"dependenciesKind has {n} entries, dependencies 1"),
        (ms('<Unknown index="2"/>' * (3 * 10**5)), "Unknown index 2 ('y') is listed twice"),
    ]
    for structure, words in cases:
        xml = md_xml(structure=structure).encode()
        t0 = time.perf_counter()
        parse_xml(xml, display="m", what="modelDescription.xml")
        t1 = time.perf_counter()
        with pytest.raises(FmuError, match=re.escape(words)):
            model_description.parse_model_description(xml)
        assert (time.perf_counter() - t1) - (t1 - t0) < 2.0, words


# --------------------------------------------------------------------------- accepted
ACCEPTED = [
    "",                                                                     # no ModelStructure (hand-written FMUs)
    "<ModelStructure/>",
    "<ModelStructure><Outputs/></ModelStructure>",                          # declared as unknown
    ms(),                                                                   # pythonfmu: no dependencies nor
                                                                            # InitialUnknowns
    ms('<Unknown index=" 2 " dependencies=" 3   1 "/>'),                    # spaces; unsorted; a parameter (no Known)
    ms('<Unknown index="+2" dependencies="" dependenciesKind=""/>'),        # OpenModelica: both empty
    ms('<Unknown index="2" dependenciesKind=""/>'),                         # an empty kind list without dependencies
    ms('<Unknown index="2" dependencies="1" dependenciesKind="fixed"/>'),
    ms(extra='<InitialUnknowns><Unknown index="3"/></InitialUnknowns>'),    # incomplete / not what FMI asks: accepted
    ms(extra='<DiscreteStates><Unknown index="99"/></DiscreteStates>'),     # old OpenModelica element: ignored
    ms('<Unknown index="2"/><Other index="x"/>'),                           # other children: ignored
]


@pytest.mark.parametrize("structure", ACCEPTED, ids=[f"a{i}" for i in range(len(ACCEPTED))])
def test_what_real_fmus_write_is_accepted_without_a_warning(tmp_path, capsys, no_warnings, structure):
    rc, out = cli(capsys, "info", fmu_with(tmp_path, structure))
    assert rc == 0, out


def test_derivatives_of_states_are_read(tmp_path, no_warnings):
    md = read_model_description(fmu_with(tmp_path, ms(extra='<Derivatives><Unknown index="5" dependencies="4"/>'
                                                            '</Derivatives>'), VARS + STATE))
    assert md.variables["der(x)"].derivative == 4 and md.variables["x"].derivative is None
    (d,) = md.model_structure.derivatives
    assert (d.index, d.name, d.dependencies, d.dependencies_kind) == (5, "der(x)", (4,), None)


@pytest.mark.parametrize("split_chars", [2**20, 0], ids=["split", "token_by_token"])
def test_the_structure_is_kept_on_the_model_description(tmp_path, monkeypatch, no_warnings, split_chars):
    monkeypatch.setattr(model_description, "_SPLIT_CHARS", split_chars)     # both ways of reading an attribute
    md = read_model_description(fmu_with(tmp_path, ms(
        '<Unknown index="2" dependencies="+1" dependenciesKind="constant"/><Unknown index="4" dependencies=""/>',
        '<InitialUnknowns><Unknown index="2" dependencies="3"/></InitialUnknowns>'), VARS + Y2))
    s = md.model_structure
    assert [(u.name, u.dependencies, u.dependencies_kind) for u in s.outputs] == [("y", (1,), ("constant",)),
                                                                                 ("y2", (), None)]
    assert [(u.index, u.dependencies) for u in s.initial_unknowns] == [(2, (3,))] and s.derivatives == ()
    assert md.direct_feedthrough() == {"y": ("u",), "y2": ()}
    md = read_model_description(fmu_with(tmp_path, ""))
    assert md.direct_feedthrough() == {"y": None} and md.model_structure.outputs == ()


# --------------------------------------------------------------------------- info
def _feedthrough(out: str) -> list[str]:
    lines = out.split("variables (")[0].splitlines()
    start = next(i for i, ln in enumerate(lines) if ln.startswith("direct feedthrough"))
    return lines[start:]


def test_info_shows_which_inputs_each_output_depends_on(tmp_path, capsys):
    variables = (VARS + Y2 + '<ScalarVariable name="v" valueReference="6" causality="input"><Real start="0"/>'
                 '</ScalarVariable><ScalarVariable name="y3" valueReference="7" causality="output"><Real/>'
                 '</ScalarVariable><ScalarVariable name="x" valueReference="8" causality="local"><Real start="0"/>'
                 '</ScalarVariable>')
    # 1 u, 2 y, 3 k, 4 y2, 5 v, 6 y3, 7 x (a state: a Known, not an input)
    fmu = fmu_with(tmp_path, ms('<Unknown index="2" dependencies="1 5 7"/><Unknown index="4" dependencies="7"/>'
                                '<Unknown index="6"/>'), variables)
    rc, out = cli(capsys, "info", fmu)
    assert rc == 0, out
    assert _feedthrough(out) == [
        "direct feedthrough (ModelStructure/Outputs: output <- the inputs it depends on directly):",
        "  y <- u, v",
        "  no input: y2",
        "  not declared (may depend on every input): y3"]


@pytest.mark.parametrize("structure, line", [
    (ms('<Unknown index="2" dependencies=""/>'),
     "direct feedthrough: none (ModelStructure/Outputs: no output depends directly on an input)"),
    (ms(), "direct feedthrough: not declared (ModelStructure/Outputs gives no dependencies: an output may depend "
           "on every input)"),
    ("", "direct feedthrough: not declared (ModelStructure/Outputs gives no dependencies: an output may depend "
         "on every input)"),
])
def test_info_says_none_or_not_declared_in_one_line(tmp_path, capsys, structure, line):
    rc, out = cli(capsys, "info", fmu_with(tmp_path, structure))
    assert rc == 0 and _feedthrough(out) == [line], out


def test_info_of_an_fmu_without_inputs_says_so(tmp_path, capsys):
    rc, out = cli(capsys, "info", fmu_with(tmp_path, "", VARS.replace('causality="input"', 'causality="local"')))
    assert rc == 0 and _feedthrough(out) == ["direct feedthrough: none (the FMU has no inputs)"], out


def test_info_of_an_fmu_without_outputs_has_no_feedthrough_line(tmp_path, capsys):
    rc, out = cli(capsys, "info", fmu_with(tmp_path, "", VARS.replace('causality="output"', 'causality="local"')))
    assert rc == 0 and "direct feedthrough" not in out, out


# --------------------------------------------------------------------------- real FMUs
def _read_quietly(path: Path):
    md = read_model_description(path)
    outputs = {v.name for v in md.outputs()}
    assert {u.name for u in md.model_structure.outputs} == outputs
    return md


def test_our_fmus_load_unchanged_without_a_warning(no_warnings, capsys):
    from orchestrator.fmi.build import FMU_DIR, RECIPES
    for name in RECIPES:
        md = _read_quietly(FMU_DIR / f"{name}.fmu")
        # fmu_common.slave: outputs change only in fmi2DoStep; every output is an initial unknown
        assert set(md.direct_feedthrough().values()) == {()}, name
        assert [u.index for u in md.model_structure.initial_unknowns] == [u.index for u in md.model_structure.outputs]
        assert main_info(FMU_DIR / f"{name}.fmu", capsys)[0] == ("direct feedthrough: none (ModelStructure/Outputs: "
                                                                 "no output depends directly on an input)")


def main_info(path: Path, capsys) -> list[str]:
    from orchestrator.cli import main
    assert main(["info", str(path)]) == 0
    return _feedthrough(capsys.readouterr().out)


def test_pythonfmu_fmus_load_without_a_warning(test_fmus, no_warnings):
    for name, path in test_fmus.items():        # pythonfmu 0.7: Outputs without dependencies, no InitialUnknowns
        md = _read_quietly(path)
        assert set(md.direct_feedthrough().values()) <= {None} and md.model_structure.initial_unknowns == (), name


@pytest.fixture(scope="module")
def crane_fmus(tmp_path_factory) -> dict[str, Path]:
    """The FMUs of the crane-fmu 0.2.0 wheel (PythonFMU 0.6.9 and 0.7.0); reading their model
    descriptions needs neither component_model nor running them."""
    return third_party.crane_fmus(tmp_path_factory.mktemp("crane_md"))


def test_crane_fmu_fmus_load_without_a_warning(crane_fmus, no_warnings):
    assert {"DrivingForce", "HarmonicOscillator6D", "MobileCrane"} <= set(crane_fmus)
    for name, path in crane_fmus.items():
        md = _read_quietly(path)
        assert set(md.direct_feedthrough().values()) == {None}, name
    crane = _read_quietly(crane_fmus["MobileCrane"])        # it lists state derivatives: each is a derivative
    assert len(crane.model_structure.derivatives) == 22
    assert all(crane.variables[u.name].derivative for u in crane.model_structure.derivatives)
