"""The bearing's ``fields_file`` is untrusted scenario text: the FMU writes a .npz there at
fmi2Terminate, so it must never destroy a file it did not write, never follow a link, and
refuse a bad target when the parameter is set (before the run), not after it."""

from __future__ import annotations

import os

import numpy as np
import pytest

from bearing_fmu.journal_bearing import fields_target, write_fields
from hostile_builders import cli
from orchestrator.shipped import resolve


def test_writes_new_files_and_replaces_earlier_npz(tmp_path):
    assert write_fields(str(tmp_path / "a"), x=np.arange(3)) == tmp_path / "a.npz"      # numpy's rule
    assert write_fields(str(tmp_path / "sub" / "b.npz"), x=np.arange(2)) == tmp_path / "sub" / "b.npz"
    write_fields(str(tmp_path / "a.npz"), x=np.arange(5))
    assert list(np.load(tmp_path / "a.npz")["x"]) == [0, 1, 2, 3, 4]
    assert sorted(p.name for p in tmp_path.iterdir()) == ["a.npz", "sub"]          # no .part left
    os.chmod(tmp_path / "a.npz", 0o600)
    write_fields(str(tmp_path / "a.npz"), x=np.arange(1))
    assert oct(os.stat(tmp_path / "a.npz").st_mode & 0o777) == oct(0o600)          # its mode kept
    (tmp_path / "empty.npz").write_bytes(b"")
    write_fields(str(tmp_path / "empty.npz"), x=np.arange(1))                        # an empty file may go


@pytest.mark.parametrize("kind, words", [
    ("text", "a file that is not a .npz archive"),
    ("link", "a symbolic link"),
    ("dangling", "a symbolic link"),
    ("folder", "a folder"),
    ("fifo", "not a regular file"),
])
def test_refuses_what_it_did_not_write(tmp_path, kind, words):
    victim = tmp_path / "victim.txt"
    victim.write_text("precious")
    target = tmp_path / "f.npz"
    if kind == "text":
        target.write_text("precious too")
    elif kind == "link":
        target.symlink_to(victim)
    elif kind == "dangling":
        target.symlink_to(tmp_path / "nowhere")
    elif kind == "folder":
        target.mkdir()
    else:
        os.mkfifo(target)
    with pytest.raises(ValueError) as exc:
        write_fields(str(tmp_path / "f"), x=np.arange(3))
    msg = str(exc.value)
    assert msg.startswith(f"fields_file '{target}' exists and is {words}; it is not overwritten"), msg
    assert victim.read_text() == "precious"
    assert not (tmp_path / "nowhere").exists()
    if kind == "text":
        assert target.read_text() == "precious too"
    assert not [p for p in tmp_path.iterdir() if p.name.endswith(".part")]
    with pytest.raises(ValueError):
        fields_target(str(target))


def test_a_bad_target_is_refused_before_the_run(tmp_path, capsys):
    victim = tmp_path / "victim.npz"
    victim.write_text("precious")
    rc, out = cli(capsys, "run", resolve("stationary_free_to_air"), "--out", tmp_path / "run", "--no-progress",
                  "--set", "stop_time=0.001", "--set", f"fmus.bearing.parameters.fields_file={victim}")
    assert rc == 1, out
    assert f"fields_file '{victim}' exists and is a file that is not a .npz archive" in out, out
    assert f"'bearing' gets fields_file from --set fmus.bearing.parameters.fields_file={victim}" in out, out
    assert "macro steps" not in out                                   # no step was taken
    assert victim.read_text() == "precious"
