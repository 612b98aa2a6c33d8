"""Unit tests of orchestrator.untrusted (bounded reading of files from others) and
orchestrator.fmi.extraction (run folders, shared extraction, stale cleanup)."""

from __future__ import annotations

import json
import os
import sys
import time

import pytest
import yaml

from orchestrator import untrusted
from orchestrator.fmi import extraction
from orchestrator.untrusted import InputError


# --------------------------------------------------------------------------- files
def test_read_text_regular_file(tmp_path):
    p = tmp_path / "a.yaml"
    p.write_bytes("\ufeffname: x\n".encode())
    assert untrusted.read_text(p, what="scenario") == "name: x\n"


def test_read_bytes_limit_reads_at_most_limit_plus_one(tmp_path, monkeypatch):
    p = tmp_path / "big.yaml"
    p.write_bytes(b"a" * 5000)
    reads = []
    real_open = untrusted.open_regular

    def counting_open(path, what="file"):
        f = real_open(path, what=what)
        orig = f.read
        f.read = lambda n=-1: (reads.append(n), orig(n))[1]
        return f
    monkeypatch.setattr(untrusted, "open_regular", counting_open)
    with pytest.raises(InputError, match=r"larger than 1000 bytes \(the limit\)"):
        untrusted.read_bytes(p, what="scenario", limit=1000)
    assert sum(n for n in reads if n > 0) <= 1001


@pytest.mark.skipif(not os.path.exists("/dev/zero"), reason="needs /dev/zero")
def test_device_refused_without_reading():
    with pytest.raises(InputError, match="character device, expected a regular file"):
        untrusted.read_bytes("/dev/zero", what="scenario")


@pytest.mark.skipif(not hasattr(os, "mkfifo"), reason="needs FIFOs")
def test_fifo_refused_without_blocking(tmp_path):
    fifo = tmp_path / "pipe.yaml"
    os.mkfifo(fifo)
    with pytest.raises(InputError, match=r"named pipe \(FIFO\)"):
        untrusted.read_text(fifo, what="scenario")     # returns at once: the test timeout guards a hang


def test_directory_and_missing(tmp_path):
    with pytest.raises(InputError, match="is a directory|a directory, expected"):
        untrusted.read_text(tmp_path, what="scenario")
    with pytest.raises(InputError, match="scenario not found"):
        untrusted.read_text(tmp_path / "nope.yaml", what="scenario")


def test_non_utf8_names_line_and_column(tmp_path):
    p = tmp_path / "latin1.yaml"
    p.write_bytes(b"name: a\ndescription: caf\xe9\n")
    with pytest.raises(InputError, match=r"latin1.yaml:2:17: the scenario is not UTF-8 text \(byte 0xe9"):
        untrusted.read_text(p, what="scenario")


def test_load_json_deep_nesting_and_garbage(tmp_path):
    p = tmp_path / "summary.json"
    p.write_text("[" * 200_000)
    with pytest.raises(InputError, match="not valid JSON|nested too deeply"):
        untrusted.load_json(p, what="summary.json")
    p.write_text('{"a": 1')
    with pytest.raises(InputError, match="not valid JSON"):
        untrusted.load_json(p, what="summary.json")


# --------------------------------------------------------------------------- YAML
def _bomb(levels: int, width: int = 10) -> str:
    lines = ["a0: &a0 [x, x, x, x, x, x, x, x, x, x]"]
    for i in range(1, levels):
        lines.append(f"a{i}: &a{i} [{', '.join([f'*a{i - 1}'] * width)}]")
    return "\n".join(lines) + "\n"


def test_alias_bomb_refused_in_linear_time():
    text = _bomb(9)                          # 10^9 leaves, under 1 KB
    assert len(text) < 1024
    with pytest.raises(InputError, match=r"<s>:\d+: the YAML expands to more than 200000 values"):
        untrusted.compose_yaml(text, display="<s>")


def test_alias_bomb_culprit_line():
    text = "ok: 1\n" + _bomb(7)                   # a5 (line 7) is the first to exceed 2e5
    with pytest.raises(InputError, match=r"^<s>:7: "):
        untrusted.compose_yaml(text, display="<s>")


def test_moderate_aliases_accepted_and_counted(monkeypatch):
    root = untrusted.compose_yaml(_bomb(4), display="<s>")     # 10^4 leaves: fine
    assert root is not None
    monkeypatch.setattr(untrusted, "MAX_YAML_NODES", 1000)
    with pytest.raises(InputError, match="more than 1000 values"):
        untrusted.compose_yaml(_bomb(4), display="<s>")


def test_deep_nesting_refused_before_recursion():
    text = "a: " + "[" * 50_000 + "]" * 50_000 + "\n"
    with pytest.raises(InputError, match=r"<s>:1: the YAML is nested more than 64 levels"):
        untrusted.compose_yaml(text, display="<s>")
    block = "".join("  " * i + f"k{i}:\n" for i in range(100)) + "  " * 100 + "v: 1\n"
    with pytest.raises(InputError, match="nested more than 64 levels"):
        untrusted.compose_yaml(block, display="<s>")


def test_deep_nesting_through_alias_chain():
    lines = ["a0: &a0 [1]"] + [f"a{i}: &a{i} [*a{i - 1}]" for i in range(1, 500)]
    with pytest.raises(InputError, match="nested more than 64 levels deep once its aliases are expanded"):
        untrusted.compose_yaml("\n".join(lines), display="<s>")


def test_recursive_alias_refused():
    with pytest.raises(InputError, match="recursive alias"):
        untrusted.compose_yaml("a: &x [1, *x]\n", display="<s>")


def test_long_integer_refused():
    with pytest.raises(InputError, match=r"<s>:2: an integer of 400 characters \(the limit is 40 digits\)"):
        untrusted.compose_yaml("a: 1\nb: " + "9" * 400 + "\n", display="<s>")


def test_resolvers_of_the_callers_loader_apply():
    from orchestrator.scenario.nodes import YamlLoader as _YamlLoader
    value = untrusted.load_yaml("h: 1e-4\nm: &m {a: 1}\nn: {<<: *m, b: 2}\n", display="<s>", loader_cls=_YamlLoader)
    assert value == {"h": 1e-4, "m": {"a": 1}, "n": {"a": 1, "b": 2}}
    assert isinstance(untrusted.compose_yaml("a: 1", display="<s>"), yaml.MappingNode)
    assert untrusted.compose_yaml("", display="<s>") is None


def test_syntax_errors_pass_through_for_the_caller():
    with pytest.raises(yaml.YAMLError):
        untrusted.compose_yaml("a: [1, 2\n", display="<s>")


# --------------------------------------------------------------------------- XML
_ENTITY_BOMB = ('<?xml version="1.0" encoding="{enc}"?>\n<!DOCTYPE r [<!ENTITY a "aaaaaaaaaa">'
                '<!ENTITY b "&a;&a;&a;&a;&a;&a;&a;&a;&a;&a;">]>\n<fmiModelDescription x="&b;"/>')


@pytest.mark.parametrize("enc", ["utf-8", "utf-16", "utf-16-le", "utf-16-be"])
def test_doctype_refused_after_decoding(enc):
    data = _ENTITY_BOMB.format(enc=enc.upper()).encode(enc)
    if enc == "utf-16":
        assert b"<!doctype" not in data.lower()          # what the byte search used to miss
    # without a BOM expat refuses the declared UTF-16-LE/BE outright: refused either way
    with pytest.raises(InputError, match="contains a DOCTYPE|cannot be decoded"):
        untrusted.parse_xml(data, display="m.fmu", what="modelDescription.xml")


def test_plain_xml_and_malformed():
    root = untrusted.parse_xml(b'<fmiModelDescription fmiVersion="2.0"><a/></fmiModelDescription>',
                               display="m.fmu")
    assert root.tag == "fmiModelDescription" and root[0].tag == "a"
    with pytest.raises(InputError, match="not well-formed XML"):
        untrusted.parse_xml(b"<a><b></a>", display="m.fmu")


# --------------------------------------------------------------------------- names
@pytest.mark.parametrize("name", ["gs-e0i0-h0.001", "two_mass", "ij-gs-e0-h1e-05", "A1"])
def test_good_names(name):
    assert untrusted.name_problem(name) is None


@pytest.mark.parametrize("name, why", [
    ("../../../../elsewhere/x", "'/'"), ("a\\b", "'\\\\'"), ("..", "starts with '.'"), (".hidden", "starts with"),
    ("", "non-empty"), ("a" * 101, "101 characters"), ("c:x", "':'"), ("nul", "reserved"), ("x\x00", "'\\x00'"),
    ("x.", "ends with"), (3, "non-empty text")])
def test_bad_names(name, why):
    problem = untrusted.name_problem(name)
    assert problem is not None and why in problem
    with pytest.raises(InputError, match="becomes a file or folder name"):
        untrusted.check_name(name, what="variant name")


def test_child_path(tmp_path):
    assert untrusted.child_path(tmp_path, "v1", what="variant") == tmp_path / "v1"
    with pytest.raises(InputError):
        untrusted.child_path(tmp_path, "../v1", what="variant")


# --------------------------------------------------------------------------- templates
def test_format_template_plain_fields():
    assert untrusted.format_template("gs-h{macro_step:g}-{scheme}", {"macro_step": 1e-4, "scheme": "x"},
                                     what="name") == "gs-h0.0001-x"


@pytest.mark.parametrize("tmpl, why", [
    ("{x.__class__}", "not a field"), ("{x[0]}", "not a field"), ("{}", "not a field"), ("{0}", "not a field"),
    ("{x!r}", "conversion"), ("{x:99999999}", "format spec"), ("{x:{x}}", "format spec"), ("{x", "not a valid"),
    ("{nope}", "not a field"), ("{x:.9999f}", "format spec")])
def test_format_template_refuses(tmpl, why):
    with pytest.raises(InputError, match=why):
        untrusted.format_template(tmpl, {"x": 1.5}, what="variant name")


def test_format_template_type_error_is_clear():
    with pytest.raises(InputError, match="cannot be formatted"):
        untrusted.format_template("{x:d}", {"x": 1.5}, what="variant name")


# --------------------------------------------------------------------------- run folders
def test_run_dir_has_owner_and_is_not_stale(tmp_path):
    d = extraction.make_run_dir(tmp_path)
    rec = json.loads((d / extraction.OWNER_FILE).read_text())
    assert rec["pid"] == os.getpid()
    assert extraction.clean_stale(tmp_path) == []
    assert d.is_dir()


@pytest.mark.skipif(sys.platform == "win32", reason="POSIX processes")
def test_stale_run_dir_of_dead_process_removed(tmp_path):
    import subprocess
    proc = subprocess.Popen([sys.executable, "-c", "pass"])
    proc.wait()
    dead = tmp_path / "rotorcosim-dead1234"
    dead.mkdir()
    (dead / "x.bin").write_bytes(b"0" * 100)
    (dead / extraction.OWNER_FILE).write_text(json.dumps({"pid": proc.pid, "start": "1", "host": os.uname().nodename}))
    legacy_old, legacy_new = tmp_path / "rotorcosim-abcdefgh", tmp_path / "rotorcosim-ijklmnop"
    legacy_old.mkdir()
    legacy_new.mkdir()
    old = time.time() - 2 * extraction.LEGACY_MAX_AGE_S
    os.utime(legacy_old, (old, old))
    other = tmp_path / "unrelated-dir"
    other.mkdir()
    removed = extraction.clean_stale(tmp_path)
    assert sorted(removed) == sorted([dead, legacy_old])
    assert legacy_new.is_dir() and other.is_dir() and not dead.exists()
