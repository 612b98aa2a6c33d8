"""FMU archives are untrusted input: unsafe zips are rejected with clear messages."""

from __future__ import annotations

import stat
import zipfile

import pytest

from orchestrator.fmi import archive as fmu_archive
from orchestrator.errors import FmuError
from orchestrator.fmi.archive import read_model_description, safe_extract

MD = b"""<?xml version="1.0" encoding="UTF-8"?>
<fmiModelDescription fmiVersion="2.0" modelName="M" guid="{123}">
  <CoSimulation modelIdentifier="M" canGetAndSetFMUstate="true"/>
  <ModelVariables>
    <ScalarVariable name="u" valueReference="0" causality="input"><Real start="0.5"/></ScalarVariable>
    <ScalarVariable name="y" valueReference="1" causality="output"><Real/></ScalarVariable>
  </ModelVariables>
</fmiModelDescription>
"""


def make_zip(path, members, md=MD):
    with zipfile.ZipFile(path, "w", compression=zipfile.ZIP_DEFLATED) as zf:
        if md is not None:
            zf.writestr("modelDescription.xml", md)
        for name, data in members:
            if isinstance(name, zipfile.ZipInfo):
                zf.writestr(name, data)
            else:
                zf.writestr(name, data)
    return path


def test_valid_archive_parses_and_extracts(tmp_path):
    p = make_zip(tmp_path / "ok.fmu", [("resources/a.txt", b"hi")])
    md = read_model_description(p)
    assert md.model_identifier == "M" and md.guid == "{123}"
    assert md.can_get_and_set_fmu_state and not md.can_interpolate_inputs
    assert md.variables["u"].start == 0.5 and md.variables["y"].causality == "output"
    d = safe_extract(p, tmp_path / "x")
    assert (d / "resources" / "a.txt").read_bytes() == b"hi"


def test_real_test_fmu_reads(test_fmus):
    md = read_model_description(test_fmus["RightMass"])
    assert [v.name for v in md.inputs()] == ["x1", "v1"]
    assert "F" in md.variables


@pytest.mark.parametrize("name, words", [
    ("../evil", "'..'"),
    ("resources/../../evil", "'..'"),
    ("/etc/evil", "absolute"),
    ("C:/evil", "drive letter"),
    ("resources\\..\\evil", "backslash"),
])
def test_rejects_unsafe_names(tmp_path, name, words):
    p = make_zip(tmp_path / "bad.fmu", [(name, b"x")])
    with pytest.raises(FmuError) as ei:
        read_model_description(p)
    msg = str(ei.value)
    assert str(p) in msg and words in msg and repr(name) in msg
    with pytest.raises(FmuError):
        safe_extract(p, tmp_path / "x")
    assert not (tmp_path / "evil").exists()


def test_rejects_symlink(tmp_path):
    info = zipfile.ZipInfo("resources/link")
    info.external_attr = (stat.S_IFLNK | 0o777) << 16
    p = make_zip(tmp_path / "link.fmu", [(info, b"/etc/passwd")])
    with pytest.raises(FmuError, match="symbolic link"):
        safe_extract(p, tmp_path / "x")


def test_rejects_oversized_member(tmp_path, monkeypatch):
    monkeypatch.setattr(fmu_archive, "MAX_MEMBER_BYTES", 1000)
    p = make_zip(tmp_path / "big.fmu", [("resources/big.bin", b"\x01" * 1001)])
    with pytest.raises(FmuError, match=r"resources/big.bin.*1001 bytes.*limit 1000.*MAX_MEMBER_BYTES"):
        read_model_description(p)


def test_rejects_oversized_total(tmp_path, monkeypatch):
    monkeypatch.setattr(fmu_archive, "MAX_TOTAL_BYTES", 2000)
    p = make_zip(tmp_path / "big.fmu", [(f"resources/{i}.bin", b"\x01" * 900) for i in range(3)])
    with pytest.raises(FmuError, match="more than 2000 bytes"):
        safe_extract(p, tmp_path / "x")


def test_rejects_zip_bomb_ratio(tmp_path, monkeypatch):
    monkeypatch.setattr(fmu_archive, "RATIO_CHECK_MIN_BYTES", 10_000)
    monkeypatch.setattr(fmu_archive, "MAX_COMPRESSION_RATIO", 50.0)
    p = make_zip(tmp_path / "bomb.fmu", [("resources/zeros.bin", bytes(1_000_000))])
    with pytest.raises(FmuError, match="compression ratio.*zip bomb"):
        read_model_description(p)


def test_rejects_doctype_entities(tmp_path):
    md = MD.replace(b'<?xml version="1.0" encoding="UTF-8"?>',
                    b'<?xml version="1.0"?><!DOCTYPE x [<!ENTITY e SYSTEM "file:///etc/passwd">]>')
    p = make_zip(tmp_path / "xxe.fmu", [], md=md)
    with pytest.raises(FmuError, match="DOCTYPE"):
        read_model_description(p)


def test_rejects_oversized_xml(tmp_path, monkeypatch):
    monkeypatch.setattr(fmu_archive, "MAX_XML_BYTES", 100)
    p = make_zip(tmp_path / "x.fmu", [])
    with pytest.raises(FmuError, match="larger than 100 bytes|limit 100"):
        read_model_description(p)


@pytest.mark.parametrize("md, words", [
    (None, "no modelDescription.xml"),
    (MD.replace(b'fmiVersion="2.0"', b'fmiVersion="3.0"'), "expected FMI 2.0"),
    (MD.replace(b'<CoSimulation modelIdentifier="M" canGetAndSetFMUstate="true"/>', b""), "CoSimulation"),
    (b"<fmiModelDescription", "not well-formed"),
])
def test_rejects_non_fmi2_cs(tmp_path, md, words):
    p = make_zip(tmp_path / "x.fmu", [("resources/a", b"a")], md=md)
    with pytest.raises(FmuError, match=words):
        read_model_description(p)


def test_missing_and_not_zip(tmp_path):
    with pytest.raises(FmuError, match="not found"):
        read_model_description(tmp_path / "nope.fmu")
    (tmp_path / "junk.fmu").write_bytes(b"not a zip")
    with pytest.raises(FmuError, match="not a valid zip"):
        read_model_description(tmp_path / "junk.fmu")
