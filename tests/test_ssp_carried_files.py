"""`export-ssp` carries a file a String parameter names only from the scenario's own folder.

A scenario file is untrusted: one from someone else could set a String parameter (our rotor's
``rotor_file``, a third-party FMU's ``label``) to ``~/.ssh/id_rsa``, ``/etc/passwd`` or
``../../secret.txt``, and the user's ``export-ssp`` packed that file into the SSP they then share.
Now a file the scenario file names is carried only when it is a regular file whose real path (links
resolved) lies in the scenario's folder (for a scenario read from an SSP also the folder it was
extracted to) or in a ``--carry-files-from`` folder; a FIFO, device or socket is never opened. Any
other is not carried, and export-ssp warns as it does for a file too large to carry. A value given
with ``--set`` is the user's own: its file is carried wherever it lies (tests/test_ssp_files.py).
"""

from __future__ import annotations

import json
import os
import signal
import warnings
import zipfile
from contextlib import contextmanager
from pathlib import Path

import pytest

from hostile_builders import cli
from test_ssp_files import MEMBER, _copy_alone, _my_rotor, _tampered

REPO = Path(__file__).resolve().parents[1]
SHIPPED = REPO / "scenarios" / "turbocharger_runup_half_sommerfeld.yaml"
SECRET = b"-----BEGIN OPENSSH PRIVATE KEY-----\nnot really\n"
KEY = "fmus.rotor.parameters.rotor_file"


def _scenario(folder: Path, rotor_file: str) -> Path:
    """The shipped HS turbocharger run-up written to ``folder/s.yaml``, its rotor naming ``rotor_file``."""
    text = SHIPPED.read_text()
    old = "parameters: {f_max: 105.0,"
    assert old in text
    folder.mkdir(parents=True, exist_ok=True)
    out = folder / "s.yaml"
    out.write_text(text.replace(old, f"parameters: {{rotor_file: {json.dumps(rotor_file)}, f_max: 105.0,"))
    return out


def _export(scenario, out: Path, **kw) -> tuple[Path, list[str]]:
    """export_ssp's archive and its 'does not carry' warnings."""
    from orchestrator.scenario.ssp import export_ssp
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        ssp = export_ssp(scenario, out, **kw)
    return ssp, [str(w.message) for w in caught if "does not carry" in str(w.message)]


def _carried(ssp: Path) -> dict[str, bytes]:
    with zipfile.ZipFile(ssp) as zf:
        return {n: zf.read(n) for n in zf.namelist() if n.startswith("resources/files/")}


@contextmanager
def _no_hang(seconds: int = 60):
    """Fail instead of hanging (an open() of a FIFO blocks until a writer comes)."""
    def stuck(*_):
        raise TimeoutError(f"still running after {seconds} s: a FIFO was opened")
    old = signal.signal(signal.SIGALRM, stuck)
    signal.alarm(seconds)
    try:
        yield
    finally:
        signal.alarm(0)
        signal.signal(signal.SIGALRM, old)


@pytest.mark.parametrize("how", ["absolute", "relative ..", "through a link in the folder", "home"])
def test_a_file_outside_the_scenarios_folder_is_not_carried_and_said(tmp_path, monkeypatch, how):
    """Before, each of these was packed into the archive without a word."""
    import orchestrator
    outside = tmp_path / "outside"
    outside.mkdir()
    secret = outside / "secret.txt"
    secret.write_bytes(SECRET)
    folder = tmp_path / "from_someone" / "scenario"
    folder.mkdir(parents=True)
    monkeypatch.chdir(folder)
    if how == "absolute":
        value = str(secret)
    elif how == "relative ..":
        value = "../../outside/secret.txt"
    elif how == "through a link in the folder":
        (folder / "rotor.yaml").symlink_to(secret)
        value = "rotor.yaml"
    else:
        home = tmp_path / "home"
        (home / ".ssh").mkdir(parents=True)
        (home / ".ssh" / "id_rsa").write_bytes(SECRET)
        monkeypatch.setenv("HOME", str(home))
        value = "~/.ssh/id_rsa"
    sc = orchestrator.load_scenario(_scenario(folder, value), build_fmus=True)
    ssp, said = _export(sc, tmp_path / "shared.ssp")
    assert _carried(ssp) == {}
    with zipfile.ZipFile(ssp) as zf:
        assert not any(SECRET in zf.read(n) for n in zf.namelist())
    assert len(said) == 1, said
    relative = "" if how in ("absolute", "home") else " (relative)"
    real = (tmp_path / "home" / ".ssh" / "id_rsa") if how == "home" else secret
    assert f"export-ssp: {KEY} = {value!r}{relative} names a file the SSP does not carry (" in said[0], said
    assert f"{real.resolve()} is outside the scenario's folder {folder.resolve()}" in said[0], said
    assert f"the value is set at {folder / 's.yaml'}:24" in said[0], said
    assert f"copy the file next to the scenario (into {folder.resolve()}) and set {KEY} to that copy, or give " \
           f"--carry-files-from {real.resolve().parent}" in said[0], said
    if how == "through a link in the folder":
        assert f"its real path {secret.resolve()} is outside" in said[0], said
    # the value stays as written (the path, not the file)
    with zipfile.ZipFile(ssp) as zf:
        assert f'<ssv:String value="{value}" />' in zf.read("SystemStructure.ssd").decode()


@pytest.mark.parametrize("given", ["in the scenario file", "with --set"])
def test_a_fifo_in_the_scenarios_folder_is_not_opened_and_said(tmp_path, monkeypatch, given):
    """A FIFO is no file to carry: never opened (an open() blocks until a writer comes), said.
    Before, it was left out without a word. The regular-file rule holds for a --set value too."""
    import orchestrator
    folder = tmp_path / "scenario"
    folder.mkdir()
    fifo = folder / "rotor.yaml"
    os.mkfifo(fifo)
    monkeypatch.chdir(folder)
    opened = []
    real_open = os.open

    def watched(path, *a, **kw):
        if Path(path).name == "rotor.yaml":
            opened.append(path)
        return real_open(path, *a, **kw)
    if given == "with --set":
        sc = orchestrator.load_scenario(_scenario(folder, ""), [f"{KEY}=rotor.yaml"], build_fmus=True)
    else:
        sc = orchestrator.load_scenario(_scenario(folder, "rotor.yaml"), build_fmus=True)
    monkeypatch.setattr(os, "open", watched)
    with _no_hang():
        ssp, said = _export(sc, tmp_path / "x.ssp")
    monkeypatch.setattr(os, "open", real_open)
    assert opened == []
    assert _carried(ssp) == {}
    assert len(said) == 1, said
    assert f"{KEY} = 'rotor.yaml' (relative) names a file the SSP does not carry (it is a named pipe (FIFO), " \
           "not a regular file, and export-ssp opens no pipes, devices or sockets): the SSD keeps the value as " \
           f"written; to carry its content, save it as a regular file next to the scenario (in {folder.resolve()}) " \
           f"and set {KEY} to that file" in said[0], said


def test_the_rotor_file_next_to_the_scenario_is_carried_and_runs_a_copy_one_folder_up_is_not(
        tmp_path, monkeypatch):
    """The shipped-style case is unchanged: the rotor file beside the scenario travels in the
    archive, and the archive alone in an empty folder runs to the scenario's numbers. The same file
    one folder up is outside: not carried (before, it was)."""
    import orchestrator
    folder = tmp_path / "scenario"
    folder.mkdir()
    mine = _my_rotor(folder)
    monkeypatch.chdir(folder)
    short = ["stop_time=2.002"]                               # 20 macro steps of 0.1 ms
    sc = orchestrator.load_scenario(_scenario(folder, "my_rotor.yaml"), build_fmus=True)
    ssp, said = _export(sc, tmp_path / "t.ssp")
    assert said == [] and _carried(ssp) == {MEMBER: mine.read_bytes()}
    res = orchestrator.run(orchestrator.load_scenario(folder / "s.yaml", short), out_dir=tmp_path / "yaml",
                           progress=False)
    assert res.success
    alone = _copy_alone(ssp, tmp_path / "alone")
    monkeypatch.chdir(alone.parent)
    back = orchestrator.load_scenario("t.ssp", short)
    assert Path(back.fmu("rotor").parameters["rotor_file"]).read_bytes() == mine.read_bytes()
    res = orchestrator.run(back, out_dir=tmp_path / "ssp", progress=False)
    assert res.success
    assert (tmp_path / "ssp" / "results.csv").read_bytes() == (tmp_path / "yaml" / "results.csv").read_bytes()
    # read from the archive, exported again: the carried file is in its extraction folder, carried again
    again, said = _export(back, tmp_path / "again.ssp")
    assert said == [] and _carried(again) == {MEMBER: mine.read_bytes()}
    # one folder up: outside the scenario's folder
    monkeypatch.chdir(folder)
    sc = orchestrator.load_scenario(_scenario(folder, "../up.yaml"), build_fmus=True)
    (tmp_path / "up.yaml").write_bytes(mine.read_bytes())
    ssp, said = _export(sc, tmp_path / "up.ssp")
    assert _carried(ssp) == {} and len(said) == 1 and "is outside the scenario's folder" in said[0], said


def test_carry_files_from_lets_a_folder_travel(tmp_path, monkeypatch, capsys):
    """`--carry-files-from DIR` (repeatable; export_ssp(carry_files_from=...)) adds a folder whose
    files the archive may carry; without it the same file is not carried and the warning names the
    option; a DIR that is no folder is refused before anything is written."""
    folder = tmp_path / "scenario"
    shared = tmp_path / "shared rotors"
    shared.mkdir()
    rotor = _my_rotor(shared)
    scen = _scenario(folder, str(rotor))
    monkeypatch.chdir(tmp_path)
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        rc, text = cli(capsys, "export-ssp", scen, tmp_path / "a.ssp")
    said = [str(w.message) for w in caught if "does not carry" in str(w.message)]
    assert rc == 0 and len(said) == 1 and f"--carry-files-from '{shared}'" in said[0], (text, said)
    assert _carried(tmp_path / "a.ssp") == {}
    rc, text = cli(capsys, "export-ssp", scen, tmp_path / "b.ssp", "--carry-files-from", tmp_path / "other",
                   "--carry-files-from", shared)
    assert rc != 0 and f"--carry-files-from {tmp_path / 'other'}: no such folder" in text, text
    assert not (tmp_path / "b.ssp").exists()
    (tmp_path / "other").mkdir()
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        rc, text = cli(capsys, "export-ssp", scen, tmp_path / "b.ssp", "--carry-files-from", tmp_path / "other",
                       "--carry-files-from", shared)
    assert rc == 0 and not [w for w in caught if "does not carry" in str(w.message)], text
    assert _carried(tmp_path / "b.ssp") == {MEMBER: rotor.read_bytes()}


def test_an_ssp_from_elsewhere_cannot_name_files_outside_its_extraction(tmp_path, monkeypatch):
    """Reading: the archive's ``files`` annotation cannot point the reader outside the extraction
    (already refused: '..', absolute; verified here), and a plain String value naming a file outside
    it is not carried when the scenario read from the SSP is exported again (before, it was)."""
    import orchestrator
    from orchestrator.errors import ScenarioError
    folder = tmp_path / "scenario"
    folder.mkdir()
    _my_rotor(folder)
    monkeypatch.chdir(folder)
    ssp, said = _export(orchestrator.load_scenario(_scenario(folder, "my_rotor.yaml"), build_fmus=True),
                        tmp_path / "t.ssp")
    assert said == []
    value = f'<ssv:String value="{MEMBER}" />'
    files = f"files:\n  rotor:\n    rotor_file: {MEMBER}\n"
    secret = tmp_path / "home" / "secret.txt"
    secret.parent.mkdir()
    secret.write_bytes(SECRET)
    elsewhere = tmp_path / "downloads"
    elsewhere.mkdir()
    # the annotation pointing outside: refused, nothing read or written outside the extraction
    for bad in ("resources/../../home/secret.txt", str(secret), f"resources/files/../../../{secret.name}"):
        hostile = _tampered(ssp, elsewhere / "h.ssp", lambda t: t.replace(value, f'<ssv:String value="{bad}" />')
                            .replace(files, f"files:\n  rotor:\n    rotor_file: {bad}\n"))
        with pytest.raises(ScenarioError) as info:
            orchestrator.load_scenario(hostile)
        assert "is no file inside the package" in str(info.value), info.value
        assert sorted(os.listdir(elsewhere)) == ["h.ssp"]
    # a plain value (no 'files' entry) naming a file outside: read as written, not carried on export
    hostile = _tampered(ssp, elsewhere / "h.ssp", lambda t: t.replace(value, f'<ssv:String value="{secret}" />')
                        .replace(files, ""))
    sc = orchestrator.load_scenario(hostile)
    assert sc.fmu("rotor").parameters["rotor_file"] == str(secret)
    again, said = _export(sc, tmp_path / "again.ssp")
    assert _carried(again) == {} and len(said) == 1, said
    assert sc.extracted is not None
    assert f"{secret} is outside the scenario's folder {elsewhere}; the folder its SSP was extracted to " \
           f"{sc.extracted}" in said[0], said
    assert f"the value is set at {hostile} [fmus.rotor.parameters.rotor_file]" in said[0], said


@pytest.mark.parametrize("how", ["relative", "absolute"])
def test_a_folder_a_string_parameter_names_is_said_not_carried(tmp_path, monkeypatch, how):
    """A String parameter naming a folder: export-ssp carries files, not folders, and says so with
    the parameter and the fix (before, the folder was left out without a word)."""
    import orchestrator
    folder = tmp_path / "scenario"
    (folder / "data").mkdir(parents=True)
    (folder / "data" / "inside.txt").write_bytes(SECRET)
    monkeypatch.chdir(folder)
    value = "data" if how == "relative" else str(folder / "data")
    sc = orchestrator.load_scenario(_scenario(folder, value), build_fmus=True)
    ssp, said = _export(sc, tmp_path / "x.ssp")
    assert _carried(ssp) == {}
    assert len(said) == 1, said
    assert f"{KEY} = {value!r}" in said[0] and "names a folder the SSP does not carry (export-ssp carries " \
           "files, not folders)" in said[0], said
    assert f"set {KEY} to that file (export-ssp then carries it)" in said[0], said
    with zipfile.ZipFile(ssp) as zf:
        assert all(SECRET not in zf.read(n) for n in zf.namelist())
