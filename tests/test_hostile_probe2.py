"""Second hostile-input probe (after tests/test_hostile_small.py and the other catalogues):
one test per finding, each failing on the code before its fix."""

from __future__ import annotations

import logging

import numpy as np
import pytest

from orchestrator.results import writer as results_writer
from orchestrator.results.run_directory import read_results
from orchestrator.results.writer import ResultsWriter, read_back


def test_string_values_with_line_breaks_or_megabytes_stay_one_readable_line(tmp_path, caplog):
    """An FMU's String output with a line break made results.csv rows span several lines (which
    `rotorcosim plot` then refused as a damaged file), and one of 3 MB made the run end in
    "internal error: field larger than field limit" when it read its rows back (summary.json
    left at "running"). Now each row is one line: line breaks written as \\n, values cut at
    MAX_STRING_CHARS, one warning per column each."""
    path = tmp_path / "results.csv"
    w = ResultsWriter(path, ["a.y", "a.s", "a.t"], ["Real", "String", "String"])
    w.open()
    big = "A" * 3_000_000
    with caplog.at_level(logging.WARNING, logger="orchestrator.results.writer"):
        for k in range(3):
            w.write(0.001 * k, [float(k), 'line1\nline2,"q"\r\n', big])
    w.close()
    text = path.read_text()
    assert text.count("\n") == 4                       # header + 3 rows, one line each
    assert max(len(line) for line in text.splitlines()) < 2 * results_writer.MAX_STRING_CHARS
    msgs = [r.getMessage() for r in caplog.records]
    assert sum("line break" in m and "'a.s'" in m for m in msgs) == 1, msgs
    assert sum("3000000 characters" in m and "'a.t'" in m for m in msgs) == 1, msgs
    data = read_results(path)                          # the reader of plot/compare reads it
    assert np.allclose(data["a.y"], [0, 1, 2])
    t, out = read_back(path, ["a.y", "a.s", "a.t"], ["Real", "String", "String"])
    assert out["a.s"][0] == 'line1\\nline2,"q"\\r\\n'
    assert out["a.t"][0].startswith("AAAA") and out["a.t"][0].endswith(f"...[{3_000_000 - 4096} characters cut]")


def _cli_subprocess(tmp_path, env_extra: dict, *args) -> tuple[int, str]:
    """The CLI in a fresh interpreter (module constants read the environment at import)."""
    import os
    import subprocess
    import sys
    from pathlib import Path
    root = Path(__file__).resolve().parents[1]
    env = {**os.environ, **env_extra, "PYTHONPATH": str(root)}
    p = subprocess.run([sys.executable, "-m", "orchestrator", *map(str, args)], cwd=tmp_path, env=env,
                       capture_output=True, text=True, timeout=120)
    return p.returncode, p.stdout + p.stderr


def test_garbage_in_a_numeric_environment_variable_is_named_not_an_internal_error(tmp_path):
    """ROTORCOSIM_WORKER_SPIN=abc made every command end in "internal error: ValueError: could not
    convert string to float" (the module reads it at import); -1 or nan were taken silently.
    ROTORCOSIM_SWEEP_RUNS_PER_PROCESS likewise (0 or -3 gave a fresh process for every run)."""
    from hostile_builders import md_scenario
    s = md_scenario(tmp_path)
    rc, text = _cli_subprocess(tmp_path, {"ROTORCOSIM_WORKER_SPIN": "0"}, "validate", s, "--no-build")
    assert "ROTORCOSIM_WORKER_SPIN" not in text and "internal error" not in text, text
    for value in ("abc", "-1", "nan"):
        rc, text = _cli_subprocess(tmp_path, {"ROTORCOSIM_WORKER_SPIN": value}, "validate", s, "--no-build")
        assert rc == 1 and "internal error" not in text and "Traceback" not in text, text
        assert f"ROTORCOSIM_WORKER_SPIN='{value}': expected a number from 0 to 1" in text, text
        assert "unset it for the default 0.002" in text, text


def test_env_number_bounds(monkeypatch):
    from orchestrator.errors import CosimError
    from orchestrator.untrusted import SettingError, env_number
    kw = dict(minimum=1, maximum=100, integer=True)
    monkeypatch.delenv("RC_PROBE", raising=False)
    assert env_number("RC_PROBE", 50, **kw) == 50
    monkeypatch.setenv("RC_PROBE", " 7 ")
    assert env_number("RC_PROBE", 50, **kw) == 7
    for bad in ("0", "-3", "1e3", "x", "101"):
        monkeypatch.setenv("RC_PROBE", bad)
        try:
            env_number("RC_PROBE", 50, **kw)
        except SettingError as e:
            assert isinstance(e, CosimError) and "expected an integer from 1 to 100" in str(e), e
        else:
            raise AssertionError(f"{bad!r} accepted")


def test_stage_handoff_garbage_is_a_user_error(monkeypatch):
    """ROTORCOSIM_STAGE_HANDOFF=xyz raised a plain ValueError, which the CLI reports as an internal error."""
    from orchestrator.cli import _describe
    from orchestrator.coupling.threads import StageThreads
    monkeypatch.setenv("ROTORCOSIM_STAGE_HANDOFF", "xyz")
    try:
        StageThreads(1)
    except Exception as e:      # noqa: BLE001 - the kind is what is tested
        text = _describe(e)
    else:
        raise AssertionError("xyz accepted")
    assert text.startswith("error: ") and "ROTORCOSIM_STAGE_HANDOFF must be one of" in text, text


def test_a_shared_library_that_does_not_load_is_reported_and_the_folder_kept(tmp_path, monkeypatch, capsys):
    """binaries/linux64/M.so that is no shared library: fmpy changed into the extraction's
    binaries folder to load it and stayed there, so a relative --out then pointed into it: the
    run ended in "error: out/summary.json.tmp: No such file or directory", the load failure was
    never shown and summary.json stayed at "running"."""
    import json
    import os
    from hostile_builders import cli, scenario_text, write_fmu
    write_fmu(tmp_path / "m.fmu", members=[("binaries/linux64/M.so", b"this is not an ELF file\n")])
    (tmp_path / "s.yaml").write_text(scenario_text())
    monkeypatch.chdir(tmp_path)
    rc, text = cli(capsys, "run", "s.yaml", "--out", "out", "--no-progress")
    assert rc == 1
    assert "cannot load the FMU's shared library" in text and "summary.json.tmp" not in text, text
    assert os.getcwd() == str(tmp_path)
    summary = json.loads((tmp_path / "out" / "summary.json").read_text())
    assert summary["status"] == "failed" and "cannot load the FMU's shared library" in summary["message"], summary


def test_the_summary_of_an_interrupted_run_says_why_once(test_fmus, tmp_path, monkeypatch):
    """summary.json of a run stopped by Ctrl-C said "interrupted by the user at t=0.03 s;
    interrupted by the user at t=0.03 s", and of one stopped by SIGTERM "terminated by signal
    SIGTERM at t=...; interrupted by the user at t=..." (the master's own note appended)."""
    import json
    import signal

    import pytest
    from test_master_fmus import chain

    from orchestrator import run
    with pytest.raises(KeyboardInterrupt):
        run(chain(test_fmus, "gauss-seidel", mode=4, t_fail=0.025, H=0.01, T=0.1), out_dir=tmp_path / "int",
            progress=False)
    s = json.loads((tmp_path / "int" / "summary.json").read_text())
    assert s["message"] == "interrupted by the user at t=0.03 s", s["message"]

    real_kill = __import__("os").kill          # the FMU's SIGINT sent as SIGTERM instead
    monkeypatch.setattr("os.kill", lambda pid, sig: real_kill(pid, signal.SIGTERM if sig == signal.SIGINT else sig))
    with pytest.raises(BaseException):
        run(chain(test_fmus, "gauss-seidel", mode=4, t_fail=0.025, H=0.01, T=0.1), out_dir=tmp_path / "term",
            progress=False)
    s = json.loads((tmp_path / "term" / "summary.json").read_text())
    assert s["message"] == "terminated by signal SIGTERM at t=0.03 s", s["message"]


def _npz_bomb(path, shape=(20000, 20000)):
    """A field file whose 'p' declares ``shape`` in its header but holds only a few bytes."""
    import io
    import zipfile
    hdr = io.BytesIO()
    np.lib.format.write_array_header_1_0(hdr, {"descr": "<f8", "fortran_order": False, "shape": shape})
    with zipfile.ZipFile(path, "w") as zf:
        for key, n in (("phi", shape[1]), ("z", shape[0])):
            b = io.BytesIO()
            np.save(b, np.linspace(0, 1, n))
            zf.writestr(f"{key}.npy", b.getvalue())
        zf.writestr("p.npy", hdr.getvalue() + bytes(64))


def test_hostile_field_files_are_skipped_with_a_reason(tmp_path):
    """`rotorcosim plot` of a folder whose <bearing>_fields.npz is a FIFO blocked for ever; one whose
    p declares 20000 x 20000 values (a few KB on disk) ended in "internal error: MemoryError"
    (numpy allocates what the header says), and arrays of the wrong shape, empty or of text in
    "internal error: TypeError". Now each is skipped with a warning that says what is wrong."""
    import os
    import threading
    import warnings

    from orchestrator.errors import CosimError
    from orchestrator.results.plots import plot_run
    cases = {
        "bomb": _npz_bomb,
        "shape": lambda p: np.savez(p, phi=np.zeros((2, 3)), z=np.zeros(2), p=np.zeros((2, 6))),
        "empty": lambda p: np.savez(p, phi=np.zeros(0), z=np.zeros(0), p=np.zeros((0, 0))),
        "text": lambda p: np.savez(p, phi=np.array(["a", "b"]), z=np.zeros(1), p=np.zeros((1, 2))),
        "fifo": lambda p: os.mkfifo(p),
    }
    expected = {"bomb": "declares shape (20000, 20000)", "shape": "'phi' has shape (2, 3)",
                "empty": "'phi' has shape (0,)", "text": "holds <U1 values, expected numbers",
                "fifo": "is a named pipe (FIFO)"}
    for name, make in cases.items():
        run = tmp_path / name
        run.mkdir()
        make(run / "b_fields.npz")
        result: dict = {}

        def plot(run=run, result=result):
            with warnings.catch_warnings(record=True) as rec:
                warnings.simplefilter("always")
                try:
                    plot_run(run)
                except CosimError as exc:       # nothing left to draw: fine
                    result["error"] = str(exc)
                except BaseException as exc:    # noqa: BLE001 - the old MemoryError / TypeError
                    result["crash"] = repr(exc)
            result["warnings"] = [str(w.message) for w in rec]

        th = threading.Thread(target=plot, daemon=True)
        th.start()
        th.join(60)
        if th.is_alive() and name == "fifo":    # unblock the old reader before failing
            with open(run / "b_fields.npz", "wb"):
                pass
            th.join(10)
            raise AssertionError("plot blocked on a FIFO named *_fields.npz")
        assert "crash" not in result, (name, result)
        assert any(expected[name] in w for w in result["warnings"]), (name, result)


SSD = """<?xml version="1.0" encoding="UTF-8"?>
<ssd:SystemStructureDescription xmlns:ssd="http://ssp-standard.org/SSP1/SystemStructureDescription"
  xmlns:ssc="http://ssp-standard.org/SSP1/SystemStructureCommon"
  xmlns:ssv="http://ssp-standard.org/SSP1/SystemStructureParameterValues" version="1.0" name="probe">
<ssd:System name="sys"><ssd:Elements>{elements}</ssd:Elements>
<ssd:Connections>{connections}</ssd:Connections></ssd:System>{experiment}
</ssd:SystemStructureDescription>
"""
COMP = '<ssd:Component name="{name}" source="m.fmu"/>'


def _param_comp(kind, value, name="a"):
    return (f'<ssd:Component name="{name}" source="m.fmu"><ssd:ParameterBindings><ssd:ParameterBinding>'
            '<ssd:ParameterValues><ssv:ParameterSet version="1.0" name="p"><ssv:Parameters>'
            f'<ssv:Parameter name="k"><ssv:{kind} value="{value}"/></ssv:Parameter></ssv:Parameters>'
            '</ssv:ParameterSet></ssd:ParameterValues></ssd:ParameterBinding></ssd:ParameterBindings></ssd:Component>')


def test_ssp_values_that_are_not_of_their_type_and_twin_components(tmp_path, capsys):
    """An SSD with ssv:Real value="abc", ssv:Integer value="1.5", a LinearTransformation
    factor="abc" or DefaultExperiment startTime="x" ended in "internal error: ValueError";
    ssv:Boolean value="maybe" was read as false; two components of one name: the second silently
    replaced the first (and its parameters). Each is now a problem naming the SSD and the element."""
    import os

    from hostile_builders import cli, write_fmu
    write_fmu(tmp_path / "m.fmu")
    exp = '<ssd:DefaultExperiment startTime="0" stopTime="0.01"/>'
    two = COMP.format(name="a") + COMP.format(name="b")
    cases = {
        "real": (dict(elements=_param_comp("Real", "abc")), "ssv:Real value is 'abc', not a number"),
        "int": (dict(elements=_param_comp("Integer", "1.5")), "ssv:Integer value is '1.5', not an integer"),
        "bool": (dict(elements=_param_comp("Boolean", "maybe")), "ssv:Boolean value is 'maybe'"),
        "factor": (dict(elements=two, connections='<ssd:Connection startElement="a" startConnector="y" '
                        'endElement="b" endConnector="u"><ssc:LinearTransformation factor="abc"/></ssd:Connection>'),
                   "connection a.y -> b.u: LinearTransformation factor is 'abc', not a number"),
        "start": (dict(elements=COMP.format(name="a"), experiment='<ssd:DefaultExperiment startTime="x"/>'),
                  "DefaultExperiment startTime is 'x', not a number"),
        "twins": (dict(elements=_param_comp("Real", "2") + COMP.format(name="a")), "two components are called 'a'"),
    }
    os.mkfifo(tmp_path / "pipe.ssv")
    cases["fifo"] = (dict(elements='<ssd:Component name="a" source="m.fmu"><ssd:ParameterBindings>'
                          '<ssd:ParameterBinding source="pipe.ssv"/></ssd:ParameterBindings></ssd:Component>'),
                     "parameter values 'pipe.ssv' is a named pipe (FIFO)")
    for name, (parts, words) in cases.items():
        f = tmp_path / f"{name}.ssd"
        f.write_text(SSD.format(**{"connections": "", "experiment": exp, **parts}))
        rc, text = cli(capsys, "validate", f, "--no-build")
        assert rc == 1 and f"{f}: " in text and words in text, (name, text)


def test_an_fmu_log_message_cannot_drive_the_terminal():
    """An FMU's log message went to the terminal as it came: ESC [2J cleared the screen, ESC ]0;
    retitled the window, ESC [8m hid what followed, a bare CR overwrote the line with a fake
    'status: finished', U+202E showed the rest reversed. They are now shown escaped."""
    from orchestrator.fmi.subsystem import log_message_text
    raw = "\x1b[2J\x1b[Hbad k\rstatus: finished\x1b]0;owned\x07\x1b[8mhidden \u202eevil\x9b1m\ttab"
    text = log_message_text(raw)
    assert not any(c in text for c in "\x1b\x07\r\u202e\x9b"), repr(text)
    assert text == ("\\x1b[2J\\x1b[Hbad k / status: finished\\x1b]0;owned\\x07\\x1b[8mhidden \\u202eevil\\x9b1m\ttab")


def _patch_headers(path, *, flag=None, method=None):
    """Set the general-purpose flag or the compression method of every member, in the local and
    the central headers (what an encrypting or a deflate64 zip tool writes)."""
    import struct
    import zipfile
    data = bytearray(path.read_bytes())
    with zipfile.ZipFile(path) as zf:
        offsets = [i.header_offset for i in zf.infolist()]
    for off in offsets:
        if flag is not None:
            struct.pack_into("<H", data, off + 6, flag)
        if method is not None:
            struct.pack_into("<H", data, off + 8, method)
    i = data.find(b"PK\x01\x02")
    while i != -1:
        if flag is not None:
            struct.pack_into("<H", data, i + 8, flag)
        if method is not None:
            struct.pack_into("<H", data, i + 10, method)
        i = data.find(b"PK\x01\x02", i + 4)
    path.write_bytes(bytes(data))


def test_encrypted_or_deflate64_fmu_is_refused_by_name(tmp_path, capsys):
    """`rotorcosim info` of an FMU zipped with a password (zip -e) or with deflate64 (method 9,
    Windows Explorer's choice for large files) ended in "internal error: RuntimeError: File
    <ZipInfo ...> is encrypted" / "NotImplementedError: That compression method is not
    supported"; run and validate showed the same Python text."""
    from hostile_builders import cli, scenario_text, write_fmu
    (tmp_path / "s.yaml").write_text(scenario_text())
    for kind, patch, words in (("encrypted", dict(flag=1), "is encrypted; FMUs are not encrypted"),
                               ("deflate64", dict(method=9), "is compressed with zip method 9")):
        fmu = write_fmu(tmp_path / "m.fmu")
        _patch_headers(fmu, **patch)
        rc, text = cli(capsys, "info", fmu)
        assert rc == 1 and "member 'modelDescription.xml' " + words in text, (kind, text)
        rc, text = cli(capsys, "validate", tmp_path / "s.yaml", "--no-build")
        assert rc == 1 and words in text and "RuntimeError" not in text and "NotImplementedError" not in text, text


def test_variable_names_with_line_breaks_or_invisible_characters_are_refused(tmp_path, capsys):
    """A variable called "y&#10;status: finished&#13;" was accepted: `rotorcosim info` printed a
    fake line, and recording it ("a.*") gave results.csv a header over two lines that `rotorcosim
    plot` then refused as damaged. Names with control or invisible characters are now refused
    when the model description is read, as instance and run names are."""
    from hostile_builders import VARS, cli, md_xml, write_fmu
    for bad, code in (("y&#10;status: finished&#13;", "U+000A"), ("y&#x202e;x", "U+202E"), ("y&#9;", "U+0009")):
        fmu = write_fmu(tmp_path / "m.fmu", md_xml(variables=VARS.replace('name="y"', f'name="{bad}"')))
        rc, text = cli(capsys, "info", fmu)
        assert rc == 1 and f"holds the control or invisible character {code}" in text, text
    fmu = write_fmu(tmp_path / "m.fmu", md_xml(variables=VARS.replace('name="y"', 'name="Über-y [m/s²] ω"')))
    rc, text = cli(capsys, "info", fmu)
    assert rc == 0, text


def test_instance_names_are_bounded(tmp_path, capsys):
    """An instance name of 300 letters was valid; with isolation: process the run then failed in
    "fmi2Instantiate returned exception: OSError in the worker: [Errno 36] File name too long"
    (the name becomes the worker's folder). Names are now at most 100 characters, like every
    name that becomes a path."""
    from hostile_builders import cli, write_fmu
    write_fmu(tmp_path / "m.fmu")
    for n, refused in ((101, True), (100, False)):
        name = "a" * n
        (tmp_path / "s.yaml").write_text(f"name: long\nstop_time: 0.01\nfmus:\n  {name}: {{path: m.fmu}}\n"
                                         "coupling:\n  macro_step: 1.0e-3\n  isolation: process\n")
        rc, text = cli(capsys, "validate", tmp_path / "s.yaml", "--no-build")
        assert rc == 1 and (f"s.yaml:4: instance name is {n} characters long" in text) == refused, text


def test_plot_of_parquet_strings_nested_columns_undotted_names_and_many_columns(tmp_path, capsys, monkeypatch):
    """`rotorcosim plot` ended in an internal error for a run with output.format: parquet and a
    String signal (ValueError: could not convert string to float: 'hello': no hostile input
    needed), a results.parquet with a list column (ValueError: setting an array element with a
    sequence) and a column name without '.' (IndexError); a folder of 20 000 columns drew
    20 000 figures (more than 2 minutes and counting). Now: text columns are skipped with the
    usual note, nested columns refused naming the column, undotted names drawn, and at most
    MAX_FIGURES figures with a note on the rest."""
    import pyarrow as pa
    import pyarrow.parquet as pq
    import pytest

    from hostile_builders import cli
    from orchestrator.results.plots import signals
    run = tmp_path / "strings"
    run.mkdir()
    pq.write_table(pa.table({"time": [0.0, 0.1, 0.2], "a.y": [0.0, 1.0, 2.0], "a.s": ["x", "y", "z"]}),
                   run / "results.parquet")
    with pytest.warns(UserWarning, match="'a.s' has no numeric values"):
        rc, text = cli(capsys, "plot", run)
    assert rc == 0 and (run / "plots" / "signals_a.png").is_file(), text

    run = tmp_path / "nested"
    run.mkdir()
    pq.write_table(pa.table({"time": [0.0, 0.1], "a.x": [[1.0], [2.0, 3.0]]}), run / "results.parquet")
    rc, text = cli(capsys, "plot", run)
    assert rc == 1 and "column 'a.x' holds list<" in text and "expected numbers or text" in text, text

    run = tmp_path / "wide"
    run.mkdir()
    (run / "results.csv").write_text("time," + ",".join(f"c{i}" for i in range(30)) + "\n"
                                     + "".join(f"{t}," + ",".join(["1.5"] * 30) + "\n" for t in (0, 1, 2)))
    monkeypatch.setattr(signals, "MAX_FIGURES", 3)
    with pytest.warns(UserWarning, match="27 more signals not drawn"):
        rc, text = cli(capsys, "plot", run)
    assert rc == 0 and sorted(p.name for p in (run / "plots").glob("signals_*.png")) == [
        "signals_c0.png", "signals_c1.png", "signals_c2.png"], text


def test_info_lists_a_few_aliases_of_each_variable(tmp_path, capsys):
    """`rotorcosim info` of an FMU whose 150 000 variables share one value reference listed every
    alias on every line: quadratic, "internal error: MemoryError" after 43 s and 3.8 GB (a 420 KB
    FMU). Each line now names at most 5 aliases and how many more there are."""
    from hostile_builders import cli, md_xml, write_fmu
    v = "".join(f'<ScalarVariable name="w{i}" valueReference="7" causality="local"><Real/></ScalarVariable>'
                for i in range(20))
    rc, text = cli(capsys, "info", write_fmu(tmp_path / "m.fmu", md_xml(variables=v)))
    assert rc == 0, text
    lines = [line for line in text.splitlines() if line.strip().startswith("w")]
    assert len(lines) == 20 and lines[0].endswith("[alias of w1, w2, w3, w4, w5 and 14 more]"), lines[0]
    assert lines[-1].endswith("[alias of w0, w1, w2, w3, w4 and 14 more]"), lines[-1]


def test_info_shows_an_fmus_texts_without_letting_them_drive_the_terminal(tmp_path, capsys):
    """`info` printed the model's and the variables' descriptions, units and start strings as
    they came: a C1 CSI (U+009B, which XML 1.0 allows; ESC it does not) or U+202E reached the
    terminal. They are shown escaped, as FMU log messages are."""
    from hostile_builders import cli, md_xml, write_fmu
    variables = ('<ScalarVariable name="u" valueReference="0" causality="input" description="in &#x9b;8m">'
                 '<Real start="0" unit="m&#x2066;"/></ScalarVariable>'
                 '<ScalarVariable name="s" valueReference="1" causality="parameter" variability="fixed">'
                 '<String start="a&#x202e;b"/></ScalarVariable>')
    xml = md_xml(variables=variables).replace('modelName="M"', 'modelName="M" description="d &#x9b;2J&#x202e;x"')
    xml = xml.replace('guid="{1}"', 'guid="{1}" generationTool="t&#x9b;1m"')
    rc, out = cli(capsys, "info", write_fmu(tmp_path / "m.fmu", xml))
    assert rc == 0, out
    assert not any(c in out for c in "\x9b\u202e\u2066"), repr(out)
    assert "description: d \\x9b2J\\u202ex" in out and "generated by: t\\x9b1m" in out, out
    assert "in \\x9b8m" in out and "m\\u2066" in out and "a\\u202eb" in out, out


@pytest.mark.parametrize("argv", [
    ["run", "quickstart", "--out", "A", "--out", "B"],
    ["sweep", "s.yaml", "--workers", "2", "--workers", "3"],
    ["compare", "c.yaml", "--out", "A", "--out", "A"],
    ["plot", "run", "--signals", "a", "b", "--signals", "c"],
    ["build-fmus", "--out", "A", "--out", "B"],
])
def test_a_value_option_given_twice_is_refused_naming_both(argv, tmp_path, monkeypatch, capsys):
    """``run X --out A --out B`` wrote to B without a word (argparse keeps the last value): now a
    usage error (exit 2) naming the option and both values, before anything is read or written."""
    from orchestrator.cli import main
    monkeypatch.chdir(tmp_path)
    with pytest.raises(SystemExit) as exc:
        main(argv)
    err = capsys.readouterr().err
    flag = argv[-2]
    assert exc.value.code == 2 and f"argument {flag}: given twice (" in err and "give it once" in err, err
    assert list(tmp_path.iterdir()) == []


def test_ssp_problems_name_the_ssp_or_the_users_file_not_the_generated_one(tmp_path, capsys):
    """A scenario made from an SSP was checked as a generated YAML file in a temporary folder, and
    every problem named that file (`/tmp/rotorcosim-ssp-x/q.yaml:23: ...`), gone when the command
    ended. Now a value from the archive is named by the .ssp and its place
    (`q.ssp [fmus.bearing1.parameters.n_phi]`), and a value of the YAML file that names the SSP by
    that file's line."""
    from hostile_builders import cli, tampered_quickstart_ssp
    with pytest.warns(UserWarning, match="SSP has no coupling scheme"):
        bad = tampered_quickstart_ssp(tmp_path, lambda t: t.replace('name="n_phi"><ssv:Integer value="24"',
                                                                    'name="n_phi"><ssv:Integer value="3"', 1),
                                      quiet=False)
    good = tmp_path / "q.ssp"
    rc, text = cli(capsys, "validate", bad)
    assert rc == 1 and f"{bad} [fmus.bearing1.parameters.n_phi]: parameter 'bearing1.n_phi' = 3" in text, text
    assert "rotorcosim-ssp-" not in text, text
    over = tmp_path / "over.yaml"
    over.write_text("ssp: q.ssp\nstop_time: -1\nfmus:\n  bearing2:\n    parameters: {n_phi: 3}\n"
                    "connections:\n  - {from: rotor.x_1, to: bearing1.x}\n")
    rc, text = cli(capsys, "validate", over)
    assert rc == 1 and "rotorcosim-ssp-" not in text, text
    assert f"{over}:2: 'stop_time' must be greater than start_time" in text, text
    assert f"{over}:5: parameter 'bearing2.n_phi' = 3 is outside" in text, text
    assert (f"{over}:7: input 'bearing1.x' is connected twice (also {good.resolve()} [connections[0]])"
            in text), text
    # a run of it: summary.json names the user's file, not the generated one
    ok = tmp_path / "ok.yaml"
    ok.write_text("ssp: q.ssp\nstop_time: 0.501\n")
    rc, text = cli(capsys, "run", ok, "--out", tmp_path / "run", "--no-progress")
    import json
    assert rc == 0 and json.loads((tmp_path / "run" / "summary.json").read_text())["scenario_file"] == str(ok), text
