"""`export-ssp` carries the files String parameters name, and the SSP round trip is complete.

* A file a String parameter names (the turbocharger's ``rotor_file``) travels in the archive as
  ``resources/files/<instance>/<name>``; the SSD's value is that member and the annotation's
  ``files`` says so. The archive copied alone into an empty folder validates and runs there to the
  very numbers of the original scenario (before, export only warned that it did not carry the file,
  and the archive did not run anywhere else). No shipped scenario names a rotor file, so the
  shipped turbocharger scenarios are exported with ``--set fmus.rotor.parameters.rotor_file=...``;
  the rotor file used is the bundled one with a larger compressor unbalance, so a run that fell back
  to the bundled rotor would differ.
* Reading it back, the member is untrusted: under ``resources/``, no ``..``, not absolute, no link,
  a regular file of bounded size, and the SSD's value must be the member; each refusal names the
  archive and the member. A file too large to carry keeps its value and export-ssp says so.
* The annotation's ``compare`` section, written into every archive but never read (``compare
  x.ssp`` was refused), is what ``rotorcosim compare x.ssp`` now runs, baseline included.

libcosim with such an archive: tests/test_interop.py.
"""

from __future__ import annotations

import os
import shutil
import warnings
import zipfile
from pathlib import Path

import numpy as np
import pytest

from hostile_builders import cli

REPO = Path(__file__).resolve().parents[1]
TURBO_HS = "turbocharger_runup_half_sommerfeld"
MEMBER = "resources/files/rotor/my_rotor.yaml"
SHORT = "stop_time=2.01"                  # 100 macro steps of 0.1 ms from t = 2 s


def _my_rotor(folder: Path) -> Path:
    """The bundled rotor file with twice the compressor unbalance (another rotor than the default)."""
    text = (REPO / "rotor_fmu" / "data" / "turbocharger.yaml").read_text()
    old = "{name: comp, z: 0.010, mass: 1.6500, Ip: 2.7844e-3, Id: 1.6706e-3, unbalance: 1.5e-6"
    assert old in text
    f = folder / "my_rotor.yaml"
    f.write_text(text.replace(old, old.replace("unbalance: 1.5e-6", "unbalance: 3.0e-6")))
    return f


@pytest.fixture(scope="module")
def turbo_ssp(tmp_path_factory) -> Path:
    """The shipped HS turbocharger run-up, its rotor file relative ('my_rotor.yaml' in the working
    directory), exported to ``src/t.ssp``."""
    from orchestrator.scenario import load_scenario
    from orchestrator.scenario.ssp import export_ssp
    from orchestrator.shipped import resolve
    src = tmp_path_factory.mktemp("src")
    _my_rotor(src)
    cwd = os.getcwd()
    os.chdir(src)
    try:
        sc = load_scenario(resolve(TURBO_HS), ["fmus.rotor.parameters.rotor_file=my_rotor.yaml"], build_fmus=True)
        with warnings.catch_warnings(record=True) as caught:
            warnings.simplefilter("always")
            ssp = export_ssp(sc, src / "t.ssp")
    finally:
        os.chdir(cwd)
    assert not [w for w in caught if "does not carry" in str(w.message)], [str(w.message) for w in caught]
    return ssp


def _copy_alone(ssp: Path, folder: Path) -> Path:
    folder.mkdir()
    return Path(shutil.copy(ssp, folder / ssp.name))


def _tampered(ssp: Path, out: Path, ssd=lambda t: t, members: dict | None = None) -> Path:
    """A copy of ``ssp`` whose SSD text is ``ssd(text)`` and whose members ``members`` (name ->
    bytes, None: left out) are replaced or added."""
    members = dict(members or {})
    with zipfile.ZipFile(ssp) as zin, zipfile.ZipFile(out, "w") as zout:
        for item in zin.infolist():
            data = zin.read(item)
            if item.filename == "SystemStructure.ssd":
                data = ssd(data.decode()).encode()
            if item.filename in members:
                data = members.pop(item.filename)
                if data is None:
                    continue
            zout.writestr(item, data)
        for name, data in members.items():
            if data is not None:
                zout.writestr(name, data)
    return out


def test_the_archive_carries_the_rotor_file_and_names_it(turbo_ssp):
    with zipfile.ZipFile(turbo_ssp) as zf:
        names = zf.namelist()
        ssd = zf.read("SystemStructure.ssd").decode()
        carried = zf.read(MEMBER)
    assert MEMBER in names
    assert carried == (turbo_ssp.parent / "my_rotor.yaml").read_bytes()
    assert f'<ssv:Parameter name="rotor_file"><ssv:String value="{MEMBER}" />' in ssd
    assert f"files:\n  rotor:\n    rotor_file: {MEMBER}\n" in ssd


@pytest.mark.integration
def test_the_archive_alone_in_an_empty_folder_runs_to_the_original_numbers(turbo_ssp, tmp_path, capsys,
                                                                             monkeypatch):
    """`export-ssp` of the shipped turbocharger run-up naming its own rotor file, the .ssp copied
    alone into an empty folder: `validate` and `run` there, identical results.csv to the original."""
    src = tmp_path / "src"
    src.mkdir()
    _my_rotor(src)
    monkeypatch.chdir(src)
    rotor = "fmus.rotor.parameters.rotor_file=my_rotor.yaml"
    rc, text = cli(capsys, "export-ssp", TURBO_HS, src / "t.ssp", "--set", rotor)
    assert rc == 0 and "does not carry" not in text, text
    rc, text = cli(capsys, "run", TURBO_HS, "--set", rotor, "--set", SHORT, "--out", tmp_path / "original")
    assert rc == 0, text
    alone = _copy_alone(src / "t.ssp", tmp_path / "alone")
    monkeypatch.chdir(alone.parent)
    rc, text = cli(capsys, "validate", "t.ssp")
    assert rc == 0 and "t.ssp: valid" in text, text
    rc, text = cli(capsys, "run", "t.ssp", "--set", SHORT, "--out", tmp_path / "from_ssp")
    assert rc == 0, text
    assert sorted(os.listdir(alone.parent)) == ["t.ssp"]          # nothing extracted beside it
    original = (tmp_path / "original" / "results.csv").read_bytes()
    assert (tmp_path / "from_ssp" / "results.csv").read_bytes() == original
    # the carried rotor is the one used: the bundled rotor (half the compressor unbalance) runs otherwise
    rc, text = cli(capsys, "run", TURBO_HS, "--set", SHORT, "--out", tmp_path / "bundled")
    assert rc == 0, text
    import pandas as pd
    a, b = (pd.read_csv(tmp_path / d / "results.csv") for d in ("original", "bundled"))
    assert np.abs(a["rotor.x_comp"] - b["rotor.x_comp"]).max() > 1e-8      # 2e-7 m of 3.8e-6 m


SHIPPED_TURBO = sorted(p.stem for p in (REPO / "scenarios").glob("turbocharger_*.yaml"))


@pytest.mark.parametrize("name", SHIPPED_TURBO)
def test_every_shipped_turbocharger_scenario_loads_back_with_its_rotor_file(name, tmp_path, monkeypatch):
    """Each shipped turbocharger scenario, given a rotor file, loads back from its archive alone in
    an empty folder with every parameter as before and rotor_file the extracted copy of the file."""
    import orchestrator
    from orchestrator.scenario.ssp import export_ssp
    from orchestrator.shipped import resolve
    assert len(SHIPPED_TURBO) >= 4
    mine = _my_rotor(tmp_path)
    monkeypatch.chdir(tmp_path)
    sc = orchestrator.load_scenario(resolve(name), ["fmus.rotor.parameters.rotor_file=my_rotor.yaml"],
                                    build_fmus=True)
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        ssp = export_ssp(sc, tmp_path / "x.ssp")
    assert not [w for w in caught if "does not carry" in str(w.message)]
    monkeypatch.chdir(_copy_alone(ssp, tmp_path / "alone").parent)
    back = orchestrator.load_scenario("x.ssp")
    rotor = Path(back.fmu("rotor").parameters["rotor_file"])
    assert rotor.is_absolute() and rotor.parts[-4:] == ("resources", "files", "rotor", "my_rotor.yaml")
    assert rotor.read_bytes() == mine.read_bytes()
    for f in sc.fmus:
        want = {k: v for k, v in f.parameters.items() if k != "rotor_file"}
        assert {k: v for k, v in back.fmu(f.name).parameters.items() if k != "rotor_file"} == want, f.name
    assert (back.coupling, back.output, back.analysis) == (sc.coupling, sc.output, sc.analysis)


def test_one_file_named_twice_is_carried_once_and_names_are_made_portable(tmp_path, monkeypatch):
    """Two String parameters naming one file share its member; a file name with spaces or other
    characters becomes a portable member name."""
    from orchestrator.scenario.ssp import _member_name
    assert _member_name("rotor", "my rotor (v2).yaml", {}) == "resources/files/rotor/my_rotor__v2_.yaml"
    assert _member_name("rotor", ".hidden", {}) == "resources/files/rotor/hidden"
    taken = {"resources/files/rotor/r.yaml": b""}
    assert _member_name("rotor", "r.yaml", taken) == "resources/files/rotor/r_2.yaml"
    import dataclasses

    import orchestrator
    from orchestrator.scenario.ssp import _named_files
    from orchestrator.shipped import resolve
    _my_rotor(tmp_path)
    monkeypatch.chdir(tmp_path)
    sc = orchestrator.load_scenario(resolve(TURBO_HS), ["fmus.rotor.parameters.rotor_file=my_rotor.yaml"],
                                    build_fmus=True)
    absolute = str(tmp_path / "my_rotor.yaml")
    twin = dataclasses.replace(sc.fmu("rotor"), name="rotor2",
                               parameters={**sc.fmu("rotor").parameters, "rotor_file": absolute})
    values, blobs = _named_files(dataclasses.replace(sc, fmus=(*sc.fmus, twin)))
    assert values == {("rotor", "rotor_file"): MEMBER, ("rotor2", "rotor_file"): MEMBER}
    assert list(blobs) == [MEMBER]


def test_member_names_differ_on_a_file_system_that_ignores_case():
    """Members that differ only in case (files R.yaml and r.yaml, or instances Rotor and rotor) are
    one file when the archive is extracted on Windows or macOS: one parameter read the other's file.
    Names Windows cannot create (a trailing dot, a device name) are changed too."""
    from orchestrator.scenario.ssp import _member_name
    assert _member_name("rotor", "r.yaml", {"resources/files/rotor/R.yaml": b""}) == "resources/files/rotor/r_2.yaml"
    assert _member_name("Rotor", "x.yaml", {"resources/files/rotor/x.yaml": b""}) == "resources/files/Rotor/x_2.yaml"
    assert _member_name("rotor", "rotor.", {}) == "resources/files/rotor/rotor"
    assert _member_name("rotor", "con.yaml", {}) == "resources/files/rotor/_con.yaml"
    assert _member_name("rotor", "console.yaml", {}) == "resources/files/rotor/console.yaml"


def test_a_file_the_fmu_writes_is_not_carried(tmp_path, monkeypatch):
    """The bearing's fields_file is written at fmi2Terminate; with a relative path it exists after a
    first run. export-ssp carried that earlier output and set the parameter to the member, so the
    run from the archive wrote its film fields into the temporary folder, removed when it ended."""
    import numpy as np

    import orchestrator
    from orchestrator.scenario.ssp import export_ssp
    from orchestrator.shipped import resolve
    monkeypatch.chdir(tmp_path)
    np.savez("fields.npz", phi=np.zeros(3))                 # an earlier run's output
    sc = orchestrator.load_scenario(resolve("quickstart"), ["fmus.bearing1.parameters.fields_file=fields.npz"],
                                    build_fmus=True)
    assert not [f for f in sc.inputs if Path(f).name == "fields.npz"]       # nor an input of the run
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        out = export_ssp(sc, tmp_path / "q.ssp")
    assert not [w for w in caught if "fields_file" in str(w.message)], [str(w.message) for w in caught]
    with zipfile.ZipFile(out) as zf:
        assert not [n for n in zf.namelist() if n.startswith("resources/files/")]
    assert orchestrator.load_scenario(out).fmu("bearing1").parameters["fields_file"] == "fields.npz"


def test_a_file_too_large_to_carry_keeps_its_value_and_is_said(turbo_ssp, tmp_path, monkeypatch):
    import orchestrator
    from orchestrator.scenario import ssp as ssp_mod
    from orchestrator.shipped import resolve
    monkeypatch.chdir(turbo_ssp.parent)
    sc = orchestrator.load_scenario(resolve(TURBO_HS), ["fmus.rotor.parameters.rotor_file=my_rotor.yaml"],
                                    build_fmus=True)
    monkeypatch.setattr(ssp_mod, "MAX_NAMED_FILE_BYTES", 1000)
    with pytest.warns(UserWarning) as caught:
        out = ssp_mod.export_ssp(sc, tmp_path / "big.ssp")
    said = [str(w.message) for w in caught if "does not carry" in str(w.message)]
    assert len(said) == 1, [str(w.message) for w in caught]
    assert "fmus.rotor.parameters.rotor_file = 'my_rotor.yaml' (relative) names a file the SSP does not carry" \
        in said[0] and "(it has 4825 bytes, more than export-ssp carries (1000, " in said[0], said
    with zipfile.ZipFile(out) as zf:
        assert not [n for n in zf.namelist() if n.startswith("resources/files/")]
        ssd = zf.read("SystemStructure.ssd").decode()
    assert '<ssv:String value="my_rotor.yaml" />' in ssd and "files:" not in ssd


@pytest.mark.parametrize("case, needle", [
    ("escape", "'files.rotor.rotor_file' = 'resources/../../etc/passwd' is no file inside the package"),
    ("absolute", "'files.rotor.rotor_file' = '/etc/passwd' is no file inside the package"),
    ("outside resources", "'files.rotor.rotor_file' = 'SystemStructure.ssd' is no file inside the package"),
    ("missing", f"({MEMBER}): the file fmus.rotor.parameters.rotor_file names is not in the archive"),
    ("contradicts", f"'files.rotor.rotor_file' = '{MEMBER}' but the SSD sets rotor.rotor_file = 'other.yaml'"),
    ("folder", "(resources/files/rotor/dir.yaml): the file fmus.rotor.parameters.rotor_file names is a directory"),
    ("too large", f"({MEMBER}): the file fmus.rotor.parameters.rotor_file names has 4825 bytes, more than an SSP "
                  "may carry for a String parameter (1000, orchestrator.scenario.ssp.MAX_NAMED_FILE_BYTES)"),
    ("no component", "'files' names 'ghost', which is no component of the SSD"),
    ("not a mapping", "'files.rotor' must map parameter names to archive members"),
])
def test_a_carried_file_is_read_as_untrusted(turbo_ssp, tmp_path, monkeypatch, case, needle):
    import orchestrator
    from orchestrator.errors import ScenarioError
    from orchestrator.scenario import ssp as ssp_mod
    value = f'<ssv:String value="{MEMBER}" />'
    files = f"rotor_file: {MEMBER}"
    ssd, members = (lambda t: t), {}

    def both(new):          # the SSD's value and the annotation's member, as a tampered export would have
        return lambda t: t.replace(value, f'<ssv:String value="{new}" />').replace(files, f"rotor_file: {new}")
    if case == "escape":
        ssd = both("resources/../../etc/passwd")
    elif case == "absolute":
        ssd = both("/etc/passwd")
    elif case == "outside resources":
        ssd = both("SystemStructure.ssd")
    elif case == "missing":
        members = {MEMBER: None}
    elif case == "contradicts":
        ssd = lambda t: t.replace(value, '<ssv:String value="other.yaml" />')      # noqa: E731
    elif case == "folder":
        ssd, members = both("resources/files/rotor/dir.yaml"), {"resources/files/rotor/dir.yaml/x": b"x"}
    elif case == "too large":
        monkeypatch.setattr(ssp_mod, "MAX_NAMED_FILE_BYTES", 1000)
    elif case == "no component":
        ssd = lambda t: t.replace(f"files:\n  rotor:", "files:\n  ghost:")        # noqa: E731
    elif case == "not a mapping":
        ssd = lambda t: t.replace(files, "rotor_file: [1, 2]")                      # noqa: E731
    bad = _tampered(turbo_ssp, tmp_path / "bad.ssp", ssd, members)
    with pytest.raises(ScenarioError) as info:
        orchestrator.load_scenario(bad)
    text = str(info.value)
    assert needle in text and f"{bad}" in text, text
    assert "rotorcosim-ssp-" not in text, text           # the archive, never the temporary folder


@pytest.mark.skipif(os.name == "nt", reason="symbolic links")
def test_a_carried_file_that_is_a_link_is_refused_in_a_bare_ssd_folder(turbo_ssp, tmp_path):
    """An archive cannot hold a link (safe_extract refuses it), a folder with a bare .ssd can:
    the file the SSD names must be there itself, not a link to a file elsewhere."""
    import orchestrator
    from orchestrator.errors import ScenarioError
    folder = tmp_path / "unzipped"
    with zipfile.ZipFile(turbo_ssp) as zf:
        zf.extractall(folder)
    ssd = folder / "SystemStructure.ssd"
    back = orchestrator.load_scenario(ssd)            # the unzipped archive reads as its .ssd
    assert back.fmu("rotor").parameters["rotor_file"] == str((folder / MEMBER).resolve())
    (folder / MEMBER).unlink()
    secret = tmp_path / "secret.yaml"
    secret.write_text("x: 1\n")
    (folder / MEMBER).symlink_to(secret)
    with pytest.raises(ScenarioError) as info:
        orchestrator.load_scenario(ssd)
    text = str(info.value)
    assert f"{folder / MEMBER}: the file fmus.rotor.parameters.rotor_file names is a symbolic link" in text, text


def test_an_origin_of_the_carried_file_names_the_member_not_the_temporary_folder(turbo_ssp):
    from orchestrator.scenario import loader
    from orchestrator.scenario.nodes import GENERATED
    generated = loader.from_ssp(turbo_ssp)
    try:
        origins = GENERATED[str(generated)][1].values()
    finally:
        GENERATED.pop(str(generated), None)
    assert f"{turbo_ssp} [fmus.rotor.parameters.rotor_file] (its file {MEMBER})" in origins


# ------------------------------------------------------------------ compare x.ssp
_TWO_MASS = """name: tm
stop_time: 0.1
fmus:
  left: {{path: {left}, parameters: {{m1: 1.0, k1: 10.0, x1_0: 1.0}}}}
  right: {{path: {right}, parameters: {{m2: 1.0, k2: 1000.0, d2: 1.0, kc: 100.0, dc: 1.0}}}}
connections:
  - {{from: left.x1, to: right.x1}}
  - {{from: left.v1, to: right.v1}}
  - {{from: right.F, to: left.F}}
coupling: {{scheme: gauss-seidel, sequence: [left, right], macro_step: 1.0e-3}}
output: {{interval: 4.0e-3, signals: [left.x1, right.x2]}}
compare:
  signals: [left.x1, right.x2]
  reference: {{scheme: gauss-seidel, extrapolation_order: 1, interpolation_order: 1, macro_step: 2.5e-4}}
  variants:
    - {{scheme: [jacobi, gauss-seidel], extrapolation_order: 0, interpolation_order: 0,
       macro_step: [2.0e-3, 1.0e-3]}}
  tolerance: {{max: 0.5}}
  baseline: baselines/tm.json
  workers: 1
"""


@pytest.mark.integration
def test_compare_of_the_exported_ssp_runs_the_scenarios_comparison(test_fmus, tmp_path, capsys):
    """`compare x.ssp` runs the comparison the annotation carries (before: refused, the section
    written but never read): the same variants and errors as `compare s.yaml`, against the same
    baseline beside the archive; the baseline is really read (a tightened one fails)."""
    import json

    import orchestrator
    from orchestrator.compare import main_compare
    from orchestrator.scenario.ssp import export_ssp
    d = tmp_path / "cmp"
    d.mkdir()
    yml = d / "tm.yaml"
    yml.write_text(_TWO_MASS.format(left=test_fmus["LeftMass"], right=test_fmus["RightMass"]))
    assert main_compare(yml, out_dir=tmp_path / "out_yaml", update_baseline=True) == 0
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        ssp = export_ssp(orchestrator.load_scenario(yml), d / "tm.ssp")
    assert not [w for w in caught if "baseline" in str(w.message)], [str(w.message) for w in caught]
    capsys.readouterr()
    assert main_compare(ssp, out_dir=tmp_path / "out_ssp") == 0, capsys.readouterr().err
    yaml_report, ssp_report = (json.loads((tmp_path / o / "report.json").read_text())
                               for o in ("out_yaml", "out_ssp"))
    assert ssp_report["name"] == "tm" and ssp_report["passed"]
    errors = [{v["name"]: v["errors"] for v in r["variants"]} for r in (yaml_report, ssp_report)]
    assert errors[1] == errors[0] and len(errors[0]) == 4
    # the baseline beside the archive is the regression gate: tightened, the comparison fails
    base = json.loads((d / "baselines" / "tm.json").read_text())
    for v in base["variants"].values():
        v["errors"] = {k: (x / 100 if x else x) for k, x in v["errors"].items()}
    (d / "baselines" / "tm.json").write_text(json.dumps(base))
    capsys.readouterr()
    assert main_compare(ssp, out_dir=tmp_path / "out_tight") == 1
    assert "regressed vs baseline" in capsys.readouterr().err
    # elsewhere, export-ssp says where `compare` will look for the baseline, and compare names it missing
    elsewhere = tmp_path / "elsewhere"
    elsewhere.mkdir()
    with pytest.warns(UserWarning, match=r"compare.baseline 'baselines/tm.json' is read relative to the comparison "
                                         r"file: `rotorcosim compare .*elsewhere/tm.ssp` reads .*elsewhere/baselines/"
                                         r"tm.json, which does not exist"):
        moved = export_ssp(orchestrator.load_scenario(yml), elsewhere / "tm.ssp")
    capsys.readouterr()
    assert main_compare(moved, out_dir=tmp_path / "out_elsewhere") == 2
    assert "the baseline file named by 'compare.baseline' does not exist" in capsys.readouterr().err


def test_compare_of_an_ssp_refuses_build_fmus_and_names_a_missing_section(turbo_ssp, tmp_path, capsys):
    """export-ssp leaves compare.build_fmus out (it would build and import Python sources outside the
    archive); an annotation that has it anyway is refused by `compare x.ssp`, and an archive without a
    compare section says what compare reads instead."""
    rc, text = cli(capsys, "compare", turbo_ssp, "--out", tmp_path / "o1")
    assert rc == 2 and "the SSP carries no 'compare' section" in text and "compare.scenario: t.ssp" in text, text
    with zipfile.ZipFile(turbo_ssp) as zf:
        assert "compare:" not in zf.read("SystemStructure.ssd").decode()
    bad = _tampered(turbo_ssp, tmp_path / "bad.ssp", lambda t: t.replace(
        "\nfiles:\n", "\ncompare:\n  build_fmus: {from: ../src, to: fmus}\n  signals: [rotor.x_1]\nfiles:\n"))
    rc, text = cli(capsys, "compare", bad, "--out", tmp_path / "o2")
    assert rc == 2 and "'compare.build_fmus' is not taken from an SSP" in text, text


def test_export_leaves_build_fmus_out_of_the_annotation_and_says_so(tmp_path):
    import dataclasses

    import orchestrator
    from orchestrator.scenario.ssp import export_ssp
    from orchestrator.shipped import resolve
    sc = orchestrator.load_scenario(resolve("quickstart"), build_fmus=True)
    sc = dataclasses.replace(sc, compare={"build_fmus": {"from": "../tests/fmus_src", "to": "../out/test_fmus"},
                                          "signals": ["rotor.x_1"]})
    with pytest.warns(UserWarning, match=r"compare.build_fmus \(from '../tests/fmus_src'\) is not written into the "
                                         r"archive's annotation"):
        out = export_ssp(sc, tmp_path / "q.ssp")
    with zipfile.ZipFile(out) as zf:
        ssd = zf.read("SystemStructure.ssd").decode()
    assert "compare:\n  signals:\n  - rotor.x_1\n" in ssd and "build_fmus" not in ssd


@pytest.mark.parametrize("baseline", ["/tmp/evil.json", "../../evil.json", "baselines/../../evil.json",
                                      "..\\evil.json", "C:/evil.json"])
def test_compare_of_an_ssp_refuses_a_baseline_outside_its_folder(tmp_path, baseline):
    """`compare x.ssp --update-baseline` writes compare.baseline relative to the archive's folder; an
    archive from elsewhere naming an absolute path or one with '..' wrote that file (any regular file
    the user may write, e.g. ~/.bashrc, overwritten with the baseline's JSON)."""
    import dataclasses

    import orchestrator
    from orchestrator.compare import CompareSpecError, load_compare
    from orchestrator.scenario.ssp import export_ssp
    from orchestrator.shipped import resolve
    sc = orchestrator.load_scenario(resolve("quickstart"), build_fmus=True)
    sc = dataclasses.replace(sc, compare={"signals": ["rotor.x_1"], "baseline": baseline,
                                          "variants": [{"scheme": "jacobi", "macro_step": 1.0e-4}]})
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        out = export_ssp(sc, tmp_path / "q.ssp")
    said = [str(w.message) for w in caught if "compare.baseline" in str(w.message)]
    assert len(said) == 1 and f"compare.baseline {baseline!r} is outside the comparison file's folder, which " \
        f"`rotorcosim compare {out}` refuses" in said[0], said
    with pytest.raises(CompareSpecError) as info:
        load_compare(out)
    assert f"'compare.baseline' = {baseline!r} is not a path inside the SSP's folder" in str(info.value), info.value
