"""Where `rotorcosim export-ssp SCENARIO OUT` may write (hostile output paths).

OUT must be an earlier SSP archive or an empty file (replaced atomically) or a new name in an
existing folder (any other existing file: tests/test_hostile_probe3.py).
A FIFO, a directory, a symbolic link or a missing folder is refused with one message
naming OUT, what it is and the fix (exit 1), and nothing is written: no stray ``.part``
file, no folder created, nothing written through a link. (Device nodes are refused by
the same check as the FIFO; they are not tested here so as not to touch /dev.)
"""

from __future__ import annotations

import os
import zipfile

import pytest

from hostile_builders import cli, md_scenario

needs_fifo = pytest.mark.skipif(not hasattr(os, "mkfifo"), reason="needs os.mkfifo")
needs_symlink = pytest.mark.skipif(os.name == "nt", reason="symbolic links")
EXPECTED = "expected a new or existing regular .ssp file"


@pytest.fixture
def scenario(tmp_path):
    """A scenario over a model-description-only FMU (export-ssp reads only the model description)."""
    src = tmp_path / "src"
    src.mkdir()
    return md_scenario(src, coupling="  scheme: jacobi\n")


def _leftovers(folder) -> list[str]:
    return sorted(p.name for p in folder.iterdir() if ".part" in p.name)


@needs_fifo
def test_fifo_is_refused_and_left_alone(tmp_path, capsys, scenario):
    out = tmp_path / "out.ssp"
    os.mkfifo(out)
    rc, text = cli(capsys, "export-ssp", scenario, out)
    assert rc == 1, text
    assert f"{out}: is a named pipe (FIFO); {EXPECTED}" in text
    assert os.path.exists(out) and not os.path.isfile(out)       # still the FIFO, not replaced
    assert _leftovers(tmp_path) == []


def test_directory_is_refused_without_a_stray_part_file(tmp_path, capsys, scenario):
    out = tmp_path / "outdir"
    out.mkdir()
    rc, text = cli(capsys, "export-ssp", scenario, out)
    assert rc == 1, text
    assert f"{out}: is a directory; {EXPECTED}" in text and str(out / "system.ssp") in text
    assert list(out.iterdir()) == [] and _leftovers(tmp_path) == []


def test_missing_folder_is_named_and_not_created(tmp_path, capsys, scenario):
    out = tmp_path / "no" / "such" / "x.ssp"
    rc, text = cli(capsys, "export-ssp", scenario, out)
    assert rc == 1, text
    assert f"the folder {out.parent} does not exist" in text and "mkdir -p" in text
    assert not (tmp_path / "no").exists()


def test_file_used_as_a_folder_is_refused(tmp_path, capsys, scenario):
    (tmp_path / "plain").write_text("x")
    rc, text = cli(capsys, "export-ssp", scenario, tmp_path / "plain" / "x.ssp")
    assert rc == 1 and f"the folder {tmp_path / 'plain'} is not a folder" in text, text
    assert (tmp_path / "plain").read_text() == "x"


@needs_symlink
def test_symlink_is_refused_and_its_target_untouched(tmp_path, capsys, scenario):
    victim = tmp_path / "victim.txt"
    victim.write_text("keep me")
    out = tmp_path / "link.ssp"
    out.symlink_to(victim)
    rc, text = cli(capsys, "export-ssp", scenario, out)
    assert rc == 1, text
    assert f"{out}: is a symbolic link" in text and "does not write through a link" in text
    assert out.is_symlink() and victim.read_text() == "keep me"
    assert _leftovers(tmp_path) == []


@needs_symlink
def test_link_planted_at_the_temporary_name_is_not_written_through(tmp_path, capsys, scenario):
    """The old code wrote OUT.part through whatever was there; the temporary file is now created
    exclusively under an unpredictable name."""
    victim = tmp_path / "victim.txt"
    victim.write_text("keep me")
    out = tmp_path / "x.ssp"
    (tmp_path / "x.ssp.part").symlink_to(victim)
    rc, text = cli(capsys, "export-ssp", scenario, out)
    assert rc == 0, text
    assert victim.read_text() == "keep me"
    assert zipfile.ZipFile(out).namelist()[0] == "SystemStructure.ssd"


def _old_ssp(out) -> bytes:
    with zipfile.ZipFile(out, "w") as zf:
        zf.writestr("SystemStructure.ssd", "<old/>")
    return out.read_bytes()


def test_regular_file_is_replaced_atomically(tmp_path, capsys, scenario):
    out = tmp_path / "x.ssp"
    _old_ssp(out)
    rc, text = cli(capsys, "export-ssp", scenario, out)
    assert rc == 0, text
    with zipfile.ZipFile(out) as zf:
        assert zf.namelist() == ["SystemStructure.ssd", "resources/m.fmu"]
    assert _leftovers(tmp_path) == []
    assert os.stat(out).st_mode & 0o777 == 0o644


def test_failed_write_leaves_the_old_file_and_no_part_file(tmp_path, capsys, scenario, monkeypatch):
    out = tmp_path / "x.ssp"
    old = _old_ssp(out)

    def broken(self, *args, **kwargs):
        raise OSError(28, "No space left on device")
    monkeypatch.setattr(zipfile.ZipFile, "write", broken)
    rc, text = cli(capsys, "export-ssp", scenario, out)
    assert rc == 1 and "No space left on device" in text, text
    assert out.read_bytes() == old and _leftovers(tmp_path) == []


def test_library_refuses_a_directory_before_writing(tmp_path, scenario):
    import orchestrator
    from orchestrator.errors import CosimError
    from orchestrator.scenario.ssp import export_ssp
    sc = orchestrator.load_scenario(scenario)
    with pytest.raises(CosimError, match="is a directory"):
        export_ssp(sc, tmp_path)
    assert _leftovers(tmp_path) == []
