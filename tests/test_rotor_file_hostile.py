"""A rotor file is untrusted input (a scenario names it in the TurbochargerRotor's
``rotor_file``): its size, its YAML expansion, its lists and the beam elements it asks for
are bounded, and every malformed part is named (before: /dev/zero ran out of memory, a tiny
``max_element_length`` or a huge ``n_elements`` never finished, a list of materials or a
number of discs raised AttributeError/TypeError)."""

from __future__ import annotations

import os

import pytest

from rotor_fmu import rotor_file
from rotor_fmu.rotor_file import MAX_ELEMENTS, RotorFileError, load_rotor_file

GOOD = (rotor_file.DATA_DIR / "turbocharger.yaml").read_text()


def write(tmp_path, text: str, name="r.yaml"):
    p = tmp_path / name
    p.write_text(text)
    return p


def refused(path, *words):
    with pytest.raises(RotorFileError) as exc:
        load_rotor_file(path)
    msg = str(exc.value)
    assert msg.startswith(f"invalid rotor file {path}:"), msg
    for w in words:
        assert w in msg, msg
    return msg


def test_the_shipped_rotor_still_loads(tmp_path):
    assert len(load_rotor_file().elements) == 33
    assert len(load_rotor_file(write(tmp_path, GOOD)).elements) == 33


@pytest.mark.parametrize("old, new, words", [
    ("max_element_length: 0.006", "max_element_length: 1.0e-9",
     [f"more than {MAX_ELEMENTS} beam elements", "'shaft.max_element_length' (now 1e-09 m)"]),
    ("max_element_length: 0.006", "max_element_length: 0.006\n  sections_x: 1",
     ["unknown key 'sections_x'"]),
    ("sections:\n", "sections:\n    - {length: 0.01, d_outer: 0.01, material: steel, n_elements: 100000000}\n",
     [f"'shaft.sections[0].n_elements' must be a whole number from 1 to {MAX_ELEMENTS} (got 100000000)"]),
    ("sections:\n", "sections:\n    - {length: 0.01, d_outer: 0.01, material: steel, n_elements: abc}\n",
     ["'shaft.sections[0].n_elements' must be a whole number", "(got 'abc')"]),
    ("sections:\n", "sections:\n    - {length: 0.01, d_outer: 0.01, material: steel, n_elements: 2.5}\n",
     ["(got 2.5)"]),
    ("n_modes: 4", "n_modes: lots", ["'reduction.n_modes' must be a whole number from 0 to", "(got 'lots')"]),
    ("n_modes: 4", "n_modes: 1000000000", ["(got 1000000000)"]),
    ("reduction: {n_modes: 4}", "reduction: [4]", ["'reduction' must be a mapping"]),
    ("materials:\n  steel:", "materials:\n  - steel:", ["'materials' must be a mapping of names to entries (got list)"]),
    ("\ndiscs:", "\ndiscs: 5\nunused:", ["'discs' must be a list of mappings (got int)"]),
    ("\nbearings:", "\nbearings: {a: 1}\nunused:", ["'bearings' must be a list of mappings (got dict)"]),
])
def test_malformed_parts_are_named(tmp_path, old, new, words):
    assert old in GOOD
    refused(write(tmp_path, GOOD.replace(old, new, 1)), *words)


def test_a_long_section_list_is_refused(tmp_path):
    sections = "".join("    - {length: 0.0001, d_outer: 0.01, material: steel}\n" for _ in range(1001))
    text = GOOD.replace("  sections:\n", "  sections:\n" + sections, 1)
    refused(write(tmp_path, text), "'shaft.sections' has", "more than 1000")


def test_an_alias_bomb_is_counted_not_expanded(tmp_path):
    lines = ["a0: &a0 [x, x, x, x, x, x, x, x, x, x]"]
    lines += [f"a{i}: &a{i} [{', '.join([f'*a{i - 1}'] * 10)}]" for i in range(1, 9)]
    refused(write(tmp_path, "\n".join(lines) + "\n"), "more than 100000 values with its aliases expanded")
    # a few aliases (a material used twice) are fine
    ok = GOOD.replace("steel: {E: 2.1e11, nu: 0.3, rho: 7850.0}",
                      "steel: &st {E: 2.1e11, nu: 0.3, rho: 7850.0}\n  steel2: *st")
    assert "&st" in ok and len(load_rotor_file(write(tmp_path, ok, "ok.yaml")).elements) == 33


def test_deep_nesting_and_big_or_odd_files(tmp_path):
    refused(write(tmp_path, "[" * 200_000), "nested too deeply")
    big = tmp_path / "big.yaml"
    big.write_bytes(b"# " + b"x" * (rotor_file.MAX_FILE_BYTES + 10))
    refused(big, "more than a rotor file may have")
    bad = tmp_path / "bad.yaml"
    bad.write_bytes(b"name: \xff\xfe\n")
    refused(bad, "not UTF-8")
    refused(tmp_path, "is a folder")
    fifo = tmp_path / "fifo.yaml"
    os.mkfifo(fifo)
    refused(fifo, "not a regular file")
    refused("/dev/zero", "not a regular file")


def test_the_fmu_names_its_parameter_and_the_scenario_line(capsys):
    from hostile_builders import cli
    from orchestrator.shipped import resolve
    rc, out = cli(capsys, "validate", resolve("turbocharger_runup_half_sommerfeld"),
                  "--set", "fmus.rotor.parameters.rotor_file=/dev/zero")
    assert rc == 1
    assert "invalid rotor file /dev/zero (parameter 'rotor_file')" in out and "not a regular file" in out, out
    assert "'rotor' gets rotor_file from --set fmus.rotor.parameters.rotor_file=/dev/zero" in out, out
