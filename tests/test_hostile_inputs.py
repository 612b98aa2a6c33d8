"""Catalogue of hostile input files (issue 19), part 1: scenario YAML, FMU archives and
model descriptions, special files, numeric limits.

Every case builds its hostile file here, runs the CLI verb a user would run and checks
the message names the file (and line or field), and that no "internal error" or
traceback appears (``hostile_builders.cli``). Memory and time bounds are checked by
counts (bytes read, nodes constructed, extractions), never by wall-clock time.
"""

from __future__ import annotations

import os
import zipfile

import pytest
import yaml

from hostile_builders import bomb, cli, corrupt_member, md_scenario, md_xml, write_fmu
from orchestrator.fmi import archive as fmu_archive
from orchestrator.errors import CosimError, ScenarioError
from orchestrator.scenario import load_scenario

needs_fifo = pytest.mark.skipif(not hasattr(os, "mkfifo"), reason="needs FIFOs")
needs_dev_zero = pytest.mark.skipif(not os.path.exists("/dev/zero"), reason="needs /dev/zero")


@pytest.fixture
def constructed(monkeypatch):
    """Count the YAML values the constructor builds (the memory a bomb would take)."""
    counts = {"n": 0}
    real = yaml.constructor.BaseConstructor.construct_object

    def counting(self, node, deep=False):
        counts["n"] += 1
        return real(self, node, deep)
    monkeypatch.setattr(yaml.constructor.BaseConstructor, "construct_object", counting)
    return counts


# --------------------------------------------------------------------------- YAML
def test_alias_bomb_in_coupling_options_fails_validate(tmp_path, capsys, constructed):
    s = md_scenario(tmp_path, coupling="  options:\n" + bomb(9))
    rc, out = cli(capsys, "validate", s)
    assert rc == 1
    assert f"{s}:" in out and "expands to more than 200000 values through aliases" in out
    assert constructed["n"] < 1000


def test_merge_key_bomb_stays_bounded(tmp_path, capsys, constructed):
    lines = ["    m0: &m0 {a: 1, b: 2}"] + [f"    m{i}: &m{i} {{<<: [*m{i - 1}, *m{i - 1}], k{i}: 1}}"
                                            for i in range(1, 40)]
    s = md_scenario(tmp_path, coupling="  options:\n" + "\n".join(lines) + "\n")
    rc, out = cli(capsys, "validate", s)
    assert constructed["n"] < 100_000
    assert rc in (0, 1)


def test_nesting_50000_deep(tmp_path, capsys):
    s = md_scenario(tmp_path, extra="analysis: " + "[" * 50_000 + "]" * 50_000 + "\n")
    rc, out = cli(capsys, "validate", s)
    assert rc == 1 and f"{s}:7:" in out and "nested more than 64 levels" in out


def test_integer_of_400_digits(tmp_path, capsys):
    s = md_scenario(tmp_path, top="start_time: " + "1" * 400 + "\n")
    rc, out = cli(capsys, "validate", s)
    assert rc == 1 and f"{s}:3:" in out and "the limit is 40 digits" in out


def test_recursive_alias(tmp_path, capsys):
    s = md_scenario(tmp_path, coupling="  options: &o {a: [*o]}\n")
    rc, out = cli(capsys, "validate", s)
    assert rc == 1 and "recursive alias" in out


def test_scenario_not_utf8(tmp_path, capsys):
    s = md_scenario(tmp_path)
    s.write_bytes(s.read_bytes() + b"description: caf\xe9\n")
    rc, out = cli(capsys, "validate", s)
    assert rc == 1 and f"{s}:7:" in out and "not UTF-8" in out and "save it as UTF-8" in out


@needs_dev_zero
@pytest.mark.parametrize("verb", ["validate", "run"])
def test_dev_zero_as_scenario(tmp_path, capsys, verb):
    rc, out = cli(capsys, verb, "/dev/zero")
    assert rc == 1 and "/dev/zero" in out and "character device, expected a regular file" in out


@needs_fifo
@pytest.mark.parametrize("verb", ["validate", "info"])
def test_fifo_does_not_hang(tmp_path, capsys, verb):
    fifo = tmp_path / "pipe"
    os.mkfifo(fifo)
    rc, out = cli(capsys, verb, fifo)
    assert rc == 1 and str(fifo) in out and "named pipe (FIFO)" in out


def test_huge_scenario_file(tmp_path, capsys, monkeypatch):
    from orchestrator import untrusted
    monkeypatch.setattr(untrusted, "MAX_TEXT_BYTES", 10_000)
    s = md_scenario(tmp_path, extra="description: '" + "x" * 20_000 + "'\n")
    rc, out = cli(capsys, "validate", s)
    assert rc == 1 and "larger than 10000 bytes (the limit)" in out


# --------------------------------------------------------------------------- numeric limits
@pytest.mark.parametrize("top, coupling, step, words", [
    ("", "", "1.0e-3", None),
    ("stop_time: 1.0e300\n", "", "1.0e-3", "too small for the time 1e+300 s"),    # 1e-300: below 1 fs, refused first
    ("stop_time: 1.0e5\n", "", "1.0e-4", "1e+09 macro steps (the limit is 1e+08)"),
    ("stop_time: 1.0e5\n", "", None, "1e+09 macro steps (the limit is 1e+08)"),     # the default step
    ("", "  substeps: 1.0e9\n", "1.0e-3", "'coupling.substeps' must be between 1 and 10000"),
    ("start_time: 1.0e16\nstop_time: 1.00000001e16\n", "", "1.0", "too small for the time"),
    ("stop_time: 1.0e3\n", "", "1.0e-5", "rows of results (the limit is 1e+07)"),
])
def test_step_count_limits(tmp_path, capsys, top, coupling, step, words):
    text = md_scenario(tmp_path).read_text()
    if top:
        text = text.replace("stop_time: 0.01\n", top)
    text = text.replace("  macro_step: 1.0e-3\n", (f"  macro_step: {step}\n" if step else "  scheme: jacobi\n")
                        + coupling)
    s = tmp_path / "s.yaml"
    s.write_text(text)
    rc, out = cli(capsys, "validate", s)
    if words is None:           # within every limit (validate may still miss the FMU's binary)
        assert "(the limit is" not in out and "too small" not in out, out
    else:
        assert rc == 1 and f"{s}:" in out and words in out, out


def test_fmu_substeps_limit(tmp_path, capsys):
    s = md_scenario(tmp_path)
    s.write_text(s.read_text().replace("{path: m.fmu}", "{path: m.fmu, substeps: 1000000000}"))
    rc, out = cli(capsys, "validate", s)
    assert rc == 1 and "'fmus.a.substeps' must be between 1 and" in out


def test_output_row_limit(tmp_path, capsys):
    s = md_scenario(tmp_path, extra="output: {interval: 1.0e-10}\n")
    s.write_text(s.read_text().replace("1.0e-3", "1.0e-10"))
    rc, out = cli(capsys, "validate", s)
    assert rc == 1 and "1e+08 rows of results (the limit is 1e+07)" in out


# --------------------------------------------------------------------------- model description
@pytest.mark.parametrize("variables, words", [
    ('<ScalarVariable name="z" valueReference="4294967296" causality="output"><Real/></ScalarVariable>',
     "valueReference 4294967296 of variable 'z' is outside 0..4294967295"),
    ('<ScalarVariable name="z" valueReference="-1" causality="output"><Real/></ScalarVariable>',
     "valueReference -1 of variable 'z' is outside 0..4294967295"),
    ('<ScalarVariable name="z" valueReference="1" causality="evil"><Real/></ScalarVariable>',
     "causality 'evil' of variable 'z' is not an FMI 2.0 causality"),
    ('<ScalarVariable name="z" valueReference="1" variability="sometimes"><Real/></ScalarVariable>',
     "variability 'sometimes' of variable 'z' is not an FMI 2.0 variability"),
    ('<ScalarVariable name="z" valueReference="' + "9" * 5000 + '"><Real/></ScalarVariable>',
     "outside 0..4294967295"),
])
def test_model_description_fields(tmp_path, capsys, variables, words):
    p = write_fmu(tmp_path / "m.fmu", md_xml(variables=variables))
    rc, out = cli(capsys, "info", p)
    assert rc == 1 and str(p) in out and words in out and "re-export" in out, out


@pytest.mark.parametrize("version", ["2.9-evil", "2", "2.0x", "20"])
def test_fmi_version_exact(tmp_path, capsys, version):
    p = write_fmu(tmp_path / "m.fmu", md_xml(version=version))
    rc, out = cli(capsys, "info", p)
    assert rc == 1 and f"fmiVersion {version!r}" in out and "FMI 2.0" in out


def test_utf16_doctype_entity_bomb(tmp_path, capsys):
    ents = '<!DOCTYPE r [<!ENTITY a "' + "a" * 100 + '">' + "".join(
        f'<!ENTITY {c} "{("&" + p + ";") * 10}">' for p, c in zip("abcdef", "bcdefg")) + "]>\n"
    xml = md_xml(doctype=ents, encoding="UTF-16").replace('modelName="M"', 'modelName="&g;"')
    data = xml.encode("utf-16")
    assert b"<!doctype" not in data.lower() and len(data) < 20_000
    p = write_fmu(tmp_path / "m.fmu", data)
    rc, out = cli(capsys, "info", p)
    assert rc == 1 and str(p) in out and "contains a DOCTYPE" in out


def test_bad_crc_in_model_description(tmp_path, capsys):
    p = write_fmu(tmp_path / "m.fmu", compression=zipfile.ZIP_STORED)
    corrupt_member(p, "modelDescription.xml")
    rc, out = cli(capsys, "info", p)
    assert rc == 1 and str(p) in out and "corrupt" in out and "download" in out


def test_bad_crc_in_extracted_member(tmp_path):
    p = write_fmu(tmp_path / "m.fmu", members=[("binaries/linux64/M.so", b"\x7fELF" + b"x" * 5000)],
                  compression=zipfile.ZIP_STORED)
    corrupt_member(p, "binaries/linux64/M.so")
    with pytest.raises(CosimError, match="corrupt"):
        fmu_archive.safe_extract(p, tmp_path / "x")


def test_directory_named_model_description(tmp_path, capsys):
    p = write_fmu(tmp_path / "m.fmu", md=False, members=[("modelDescription.xml/", b""),
                                                           ("modelDescription.xml/a", b"x")])
    rc, out = cli(capsys, "info", p)
    assert rc == 1 and str(p) in out and "modelDescription.xml" in out and "not a file" in out


@needs_dev_zero
def test_dev_zero_as_fmu(tmp_path, capsys):
    rc, out = cli(capsys, "info", "/dev/zero")
    assert rc == 1 and "character device, expected a regular file" in out
    s = md_scenario(tmp_path)
    s.write_text(s.read_text().replace("m.fmu", "/dev/zero"))
    rc, out = cli(capsys, "validate", s)
    assert rc == 1 and "character device" in out


def test_archive_ratio_over_many_small_members(tmp_path, monkeypatch):
    """Each member below the per-member ratio check, the archive as a whole a bomb."""
    monkeypatch.setattr(fmu_archive, "ARCHIVE_RATIO_MIN_BYTES", 2**20)
    zeros = bytes(256 * 1024)
    p = write_fmu(tmp_path / "m.fmu", members=[(f"resources/r{i}.bin", zeros) for i in range(40)])
    assert p.stat().st_size < 50_000
    with pytest.raises(CosimError, match="compression ratio .* the whole archive"):
        fmu_archive.check_archive(p)
    assert not (tmp_path / "x").exists()
    with pytest.raises(CosimError):
        fmu_archive.safe_extract(p, tmp_path / "x")
    assert not any((tmp_path / "x").rglob("*.bin")) if (tmp_path / "x").exists() else True


def test_run_extraction_budget(tmp_path, monkeypatch):
    from orchestrator.fmi import extraction
    a = write_fmu(tmp_path / "a.fmu", members=[("resources/r.bin", os.urandom(30_000))])
    b = write_fmu(tmp_path / "b.fmu", members=[("resources/r.bin", os.urandom(30_000))])
    pool = extraction.ExtractionPool(tmp_path / "run", budget=50_000)
    pool.extract(a)
    pool.extract(a)                                  # shared: no second extraction, no budget used
    assert pool.extractions == 1
    with pytest.raises(CosimError, match="run's extraction budget"):
        pool.extract(b)


def test_four_instances_share_one_extraction(tmp_path, test_fmus, monkeypatch):
    import orchestrator
    calls = []
    real = fmu_archive.safe_extract

    def counting(path, dest, **kw):
        calls.append(path)
        return real(path, dest, **kw)
    monkeypatch.setattr(fmu_archive, "safe_extract", counting)
    fmus = "".join(f"  g{i}: {{path: {test_fmus['Trivial']}}}\n" for i in range(4))
    s = tmp_path / "s.yaml"
    s.write_text(f"name: four\nstop_time: 0.003\nfmus:\n{fmus}coupling: {{macro_step: 1.0e-3}}\n")
    res = orchestrator.run(load_scenario(s), out_dir=tmp_path / "out", progress=False)
    assert res.success and len(calls) == 1


def test_scenario_error_is_a_scenario_error(tmp_path):
    s = md_scenario(tmp_path, coupling="  options:\n" + bomb(9))
    with pytest.raises(ScenarioError):
        load_scenario(s)


def test_parameter_checks_linear_in_fmu_variables(tmp_path, monkeypatch):
    """Setting P parameters of an FMU with V variables visits O(V) variables, not O(P*V)
    (200k variables used to take > 90 s)."""
    from orchestrator.scenario import checks as scenario_mod
    n_vars, n_params = 5000, 500
    extra = "".join(f'<ScalarVariable name="v{i}" valueReference="{i + 3}" causality="parameter" '
                    f'variability="fixed"><Real start="1"/></ScalarVariable>' for i in range(n_vars))
    from hostile_builders import VARS
    write_fmu(tmp_path / "m.fmu", md_xml(variables=VARS + extra))
    params = ", ".join(f"v{i}: 2.0" for i in range(n_params)) + ", nope: 1.0"
    (tmp_path / "s.yaml").write_text(f"name: big\nstop_time: 0.01\nfmus:\n  a: {{path: m.fmu, parameters: "
                                     f"{{{params}}}}}\ncoupling: {{macro_step: 1.0e-3}}\n")
    visits = {"n": 0}

    class CountingVar:                 # counts every look at a variable's causality
        def __init__(self, var):
            self._var = var

        def __getattr__(self, name):
            if name == "causality":
                visits["n"] += 1
            return getattr(self._var, name)
    real = scenario_mod.cached_model_description
    monkeypatch.setattr(scenario_mod, "cached_model_description", lambda p: type("MD", (), {
        "variables": {k: CountingVar(v) for k, v in real(p).variables.items()},
        "model_name": real(p).model_name,
        "can_be_instantiated_only_once_per_process": False, "default_experiment": {},
        "can_handle_variable_step": True, "can_get_and_set_fmu_state": True})())
    with pytest.raises(ScenarioError, match="'a' has no parameter 'nope'"):
        load_scenario(tmp_path / "s.yaml", build_fmus=False)
    assert visits["n"] <= 10 * (n_vars + 3), visits     # a few looks per variable; quadratic: 2.5M


@pytest.mark.parametrize("path, words", [
    ('"a\\0b.fmu"', "without control characters"),
    ("a" * 5000 + ".fmu", "at most 4096 characters"),
    ("a" * 300 + ".fmu", "cannot be used"),              # longer than a file name may be
])
def test_fmu_path_values(tmp_path, capsys, path, words):
    s = md_scenario(tmp_path)
    s.write_text(s.read_text().replace("{path: m.fmu}", f"{{path: {path}}}"))
    rc, out = cli(capsys, "validate", s)
    assert rc == 1 and f"{s}:4:" in out and words in out and "fmus.a.path" in out, out


def test_duplicate_anchor_message_reads_in_order(tmp_path, capsys):
    s = md_scenario(tmp_path, extra="x: &a 1\ny: &a 2\n")
    rc, out = cli(capsys, "validate", s)
    assert rc == 1 and "found duplicate anchor 'a'; first occurrence (line 7), second occurrence" in out


def test_ssp_utf16_doctype_and_special_file(tmp_path, capsys):
    """The SSP reader (scenario from an .ssd/.ssp) follows the same rules as the FMU reader."""
    ssd = tmp_path / "SystemStructure.ssd"
    xml = ('<?xml version="1.0" encoding="UTF-16"?>\n<!DOCTYPE r [<!ENTITY a "aaaa">]>\n'
           '<ssd:SystemStructureDescription xmlns:ssd="http://ssp-standard.org/SSP1/SystemStructureDescription" '
           'name="&a;" version="1.0"/>\n')
    ssd.write_bytes(xml.encode("utf-16"))
    rc, out = cli(capsys, "validate", ssd)
    assert rc == 1 and "contains a DOCTYPE" in out
    bomb_ssp = tmp_path / "b.ssp"
    write_fmu(bomb_ssp, md=False, members=[("SystemStructure.ssd", b"<x/>"), ("resources/../../evil", b"x")])
    rc, out = cli(capsys, "validate", bomb_ssp)
    assert rc == 1 and "'..'" in out and not (tmp_path.parent / "evil").exists()


def test_compare_build_fmus_reads_only_bounded_regular_sources(tmp_path, monkeypatch):
    """compare.build_fmus names a folder of PythonFMU sources: a FIFO or an oversized file
    behind a *.py name is refused with the file named (not read until memory or time runs out),
    and so are too many sources and a link or file where the FMU folder should be."""
    from orchestrator.compare import spec as cspec
    src = tmp_path / "src"
    src.mkdir()
    os.mkfifo(src / "fifo.py")
    with pytest.raises(cspec.CompareSpecError, match="fifo.py"):
        cspec.build_pythonfmu_sources(src, tmp_path / "out")
    (src / "fifo.py").unlink()
    (src / "big.py").write_bytes(b"#" * (cspec.MAX_BUILD_SOURCE_BYTES + 1))
    with pytest.raises(cspec.CompareSpecError, match="big.py"):
        cspec.build_pythonfmu_sources(src, tmp_path / "out")
    (src / "big.py").write_text("x = 1\n")
    monkeypatch.setattr(cspec, "MAX_BUILD_SOURCES", 0)
    with pytest.raises(cspec.CompareSpecError, match="the limit is 0"):
        cspec.build_pythonfmu_sources(src, tmp_path / "out")
    monkeypatch.undo()
    (tmp_path / "file").write_text("")
    with pytest.raises(cspec.CompareSpecError, match="is a file or a link"):
        cspec.build_pythonfmu_sources(src, tmp_path / "file")
    with pytest.raises(cspec.CompareSpecError, match="is not a folder"):
        cspec.build_pythonfmu_sources(tmp_path / "nowhere", tmp_path / "out")
    assert cspec.build_pythonfmu_sources(src, tmp_path / "out") == []     # no Fmi2Slave class: nothing built
