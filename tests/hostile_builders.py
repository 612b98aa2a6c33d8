"""Builders of hostile input files for the catalogue (tests/test_hostile_*.py).

Everything is built in the test's temporary folder; nothing large is committed.
"""

from __future__ import annotations

import shutil
import zipfile
from pathlib import Path

from orchestrator.cli import main

VARS = ('<ScalarVariable name="u" valueReference="0" causality="input"><Real start="0"/></ScalarVariable>'
        '<ScalarVariable name="y" valueReference="1" causality="output"><Real/></ScalarVariable>'
        '<ScalarVariable name="k" valueReference="2" causality="parameter" variability="fixed">'
        '<Real start="1"/></ScalarVariable>')


def md_xml(*, version: str = "2.0", variables: str = VARS, doctype: str = "", encoding: str = "UTF-8",
           structure: str = "") -> str:
    """A model description; ``structure``: the ``<ModelStructure>`` element (none by default)."""
    return (f'<?xml version="1.0" encoding="{encoding}"?>\n{doctype}'
            f'<fmiModelDescription fmiVersion="{version}" modelName="M" guid="{{1}}">'
            '<CoSimulation modelIdentifier="M"/>'
            f'<ModelVariables>{variables}</ModelVariables>{structure}</fmiModelDescription>\n')


def write_fmu(path: Path, md: bytes | str | None = None, members=(), *,
              compression=zipfile.ZIP_DEFLATED) -> Path:
    """An FMU-like zip: ``modelDescription.xml`` (``md``, default a small valid one) and ``members``."""
    md = md_xml() if md is None else md
    with zipfile.ZipFile(path, "w", compression=compression) as zf:
        if md is not False:
            zf.writestr("modelDescription.xml", md.encode() if isinstance(md, str) else md)
        for name, data in members:
            zf.writestr(name, data)
    return path


def corrupt_member(path: Path, member: str) -> None:
    """Flip one byte of ``member``'s stored data (its CRC then fails, as after a broken download)."""
    with zipfile.ZipFile(path) as zf:
        info = zf.getinfo(member)
    raw = bytearray(path.read_bytes())
    name_len = int.from_bytes(raw[info.header_offset + 26:info.header_offset + 28], "little")
    extra_len = int.from_bytes(raw[info.header_offset + 28:info.header_offset + 30], "little")
    start = info.header_offset + 30 + name_len + extra_len
    raw[start + info.compress_size // 2] ^= 0xFF
    path.write_bytes(bytes(raw))


def scenario_text(fmu: str = "m.fmu", *, extra: str = "", coupling: str = "", top: str = "") -> str:
    return (f"name: hostile\nstop_time: 0.01\n{top}fmus:\n  a: {{path: {fmu}}}\n"
            f"coupling:\n  macro_step: 1.0e-3\n{coupling}{extra}")


def md_scenario(tmp: Path, **kw) -> Path:
    """A scenario over a model-description-only FMU (enough for validate)."""
    write_fmu(tmp / "m.fmu")
    p = tmp / "s.yaml"
    p.write_text(scenario_text(**kw))
    return p


def two_mass_dir(tmp: Path, test_fmus) -> Path:
    shutil.copy(Path(__file__).parent / "data" / "scenarios" / "two_mass.yaml", tmp / "two_mass.yaml")
    (tmp / "fmus").mkdir(exist_ok=True)
    for name in ("LeftMass", "RightMass"):
        shutil.copy(test_fmus[name], tmp / "fmus" / f"{name}.fmu")
    return tmp


def cli(capsys, *args) -> tuple[int, str]:
    """Run the CLI in-process; return (exit code, stdout + stderr) after the catalogue's common
    checks: no traceback, no 'internal error' (that text is reserved for bugs)."""
    rc = main([str(a) for a in args])
    cap = capsys.readouterr()
    text = cap.out + cap.err
    assert "internal error" not in text, text
    assert "Traceback" not in text, text
    return rc, text


def bomb(levels: int = 9, width: int = 10, indent: str = "    ") -> str:
    """A YAML alias bomb (10^levels leaves in under 1 KB), as lines of a mapping at ``indent``."""
    lines = [f"{indent}a0: &a0 [x, x, x, x, x, x, x, x, x, x]"]
    for i in range(1, levels):
        lines.append(f"{indent}a{i}: &a{i} [{', '.join([f'*a{i - 1}'] * width)}]")
    return "\n".join(lines) + "\n"


def tampered_quickstart_ssp(tmp_path: Path, edit, quiet: bool = True) -> Path:
    """The shipped quickstart exported to ``tmp_path/q.ssp`` and a copy ``tmp_path/bad.ssp`` whose
    SystemStructure.ssd text is ``edit(text)``; returns the copy (``quiet``: export-ssp's warnings
    ignored, else left to the caller)."""
    import warnings
    import zipfile

    import orchestrator
    from orchestrator.scenario.ssp import export_ssp
    from orchestrator.shipped import resolve
    with warnings.catch_warnings():
        if quiet:
            warnings.simplefilter("ignore")          # libcosim's Jacobi note
        good = export_ssp(orchestrator.load_scenario(resolve("quickstart")), tmp_path / "q.ssp")
    bad = tmp_path / "bad.ssp"
    with zipfile.ZipFile(good) as zin, zipfile.ZipFile(bad, "w") as zout:
        for item in zin.infolist():
            data = zin.read(item)
            if item.filename == "SystemStructure.ssd":
                data = edit(data.decode()).encode()
            zout.writestr(item, data)
    return bad


def run_verb(capsys, verb: str, *args) -> tuple[int, str, str]:
    """``rotorcosim VERB ARGS...`` in this process: (exit code, stdout, stderr)."""
    code = main([verb, *map(str, args)])
    out = capsys.readouterr()
    return code, out.out, out.err

