"""Third hostile-input probe (after tests/test_hostile_probe2.py and the other catalogues): FMUs
misbehaving at run time (native C test FMU MisbehavingBearing, faults 9-13), the Python API from
scripts, full disks and odd output paths. One test per finding, each failing on the code before
its fix."""

from __future__ import annotations

import zipfile

from hostile_builders import cli, md_scenario, write_fmu


def test_export_ssp_never_replaces_a_file_that_is_not_an_ssp(tmp_path, capsys):
    """`rotorcosim export-ssp s.yaml s.yaml` (a slip of the keyboard) replaced the scenario itself
    with the zip archive, exit 0; so did any other existing file (an FMU, results). Now an existing
    OUT is replaced only when it is an SSP archive (or empty); anything else is refused, named,
    with a new name to give, and left as it was."""
    scenario = md_scenario(tmp_path)
    text_before = scenario.read_bytes()
    rc, text = cli(capsys, "export-ssp", scenario, scenario)
    assert rc == 1, text
    assert f"{scenario}: exists and is not an SSP archive (it holds text, e.g. a scenario)" in text
    assert f"e.g. {scenario.with_suffix('.ssp')}" in text
    assert scenario.read_bytes() == text_before

    fmu = tmp_path / "m.fmu"
    fmu_before = fmu.read_bytes()
    rc, text = cli(capsys, "export-ssp", scenario, fmu)
    assert rc == 1 and "it is an FMU without SystemStructure.ssd" in text, text
    assert fmu.read_bytes() == fmu_before

    other = write_fmu(tmp_path / "other.ssp", md=False, members=[("a.txt", "x")])
    rc, text = cli(capsys, "export-ssp", scenario, other)
    assert rc == 1 and "it is a zip archive without SystemStructure.ssd" in text, text
    assert f"e.g. {tmp_path / 'other-new.ssp'}" in text

    # an earlier export and an empty file are replaced
    for name in ("x.ssp", "empty.ssp"):
        (tmp_path / name).write_bytes(b"")
        rc, text = cli(capsys, "export-ssp", scenario, tmp_path / name)
        assert rc == 0, text
        rc, text = cli(capsys, "export-ssp", scenario, tmp_path / name)
        assert rc == 0, text
        assert "SystemStructure.ssd" in zipfile.ZipFile(tmp_path / name).namelist()
