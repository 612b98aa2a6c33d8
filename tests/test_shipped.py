"""Our FMUs by name (`fmu: NAME`) and the scenarios shipped inside the package."""

from __future__ import annotations

from pathlib import Path

import pytest

from orchestrator.fmi import build
from orchestrator.cli import main
from orchestrator.errors import ScenarioError
from orchestrator.scenario import load_scenario
from orchestrator.shipped import resolve, shipped


def test_scenarios_lists_every_shipped_file(capsys):
    assert main(["scenarios"]) == 0
    out = capsys.readouterr().out
    names = set(shipped())
    assert "quickstart" in names and len(names) >= 14
    assert all(any(line.startswith(n + " ") for line in out.splitlines()) for n in names)


def test_a_shipped_scenario_runs_by_name():
    assert resolve("quickstart") == shipped()["quickstart"]
    assert resolve("quickstart.yaml") == shipped()["quickstart"]
    assert resolve("no_such_scenario") == Path("no_such_scenario")     # the loader says it is missing


def test_shipped_scenarios_name_our_fmus_without_paths():
    for path in shipped().values():
        text = path.read_text()
        assert "../fmus/" not in text, path
        assert "fmu: J" in text or "fmu: T" in text, path


@pytest.mark.integration
def test_init_copies_scenarios_that_load_anywhere(tmp_path, capsys):
    assert main(["init", str(tmp_path / "mine")]) == 0
    # the command it suggests is the quick start, not the first file by name (a long run-up)
    assert f"run it with `rotorcosim run {tmp_path / 'mine'}/quickstart.yaml` (a few seconds" in capsys.readouterr().out
    copied = sorted(p.name for p in (tmp_path / "mine").glob("*.yaml"))
    assert copied == sorted(p.name for p in shipped().values())
    sc = load_scenario(tmp_path / "mine" / "quickstart.yaml", build_fmus=True)
    assert sc.fmu("rotor").path == build.fmu_location("JeffcottRotor")
    capsys.readouterr()
    assert main(["init", str(tmp_path / "mine")]) == 1             # refuses to overwrite
    assert f"{len(copied)} scenario file(s) exist already" in capsys.readouterr().err


def test_fmu_key_errors(tmp_path):
    p = tmp_path / "s.yaml"
    p.write_text("name: s\nstop_time: 1\nfmus:\n  a: {fmu: JournalBaering}\n  b: {fmu: JournalBearing, path: x.fmu}\n"
                 "  c: {parameters: {}}\n")
    with pytest.raises(ScenarioError) as info:
        load_scenario(p, build_fmus=False)
    text = str(info.value)
    assert "'fmus.a.fmu' names our FMUs by name, one of JournalBearing, FloatingRingBearing, JeffcottRotor, TurbochargerRotor " \
           "(got 'JournalBaering'); did you mean 'JournalBearing'?" in text
    assert "'fmus.b' needs exactly one of 'path' (an FMU file) and 'fmu'" in text and "(got both)" in text
    assert "(got neither)" in text


def test_installed_package_builds_into_the_user_cache(tmp_path, monkeypatch):
    monkeypatch.setattr(build, "in_checkout", lambda: False)
    monkeypatch.setenv("ROTORCOSIM_CACHE", str(tmp_path / "cache"))
    loc = build.fmu_location("JournalBearing")
    digest = build.source_hash(build.RECIPES["JournalBearing"])
    assert loc == tmp_path / "cache" / "fmus" / digest[:16] / "JournalBearing.fmu"
    monkeypatch.delenv("ROTORCOSIM_CACHE")
    import platformdirs
    assert str(build.cache_dir()).startswith(platformdirs.user_cache_dir("rotorcosim"))
    site = Path(build.__file__).resolve().parents[1]
    assert site not in build.cache_dir().parents and Path.cwd() not in build.cache_dir().parents
