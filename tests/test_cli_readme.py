"""The README's two opening commands, .ci/run and pyproject.toml agree."""

from __future__ import annotations

import re
import shlex
import subprocess
import tomllib
from pathlib import Path

REPO = Path(__file__).resolve().parents[1]


def readme_block() -> list[str]:
    text = (REPO / "README.md").read_text()
    m = re.search(r"^```sh\n(.*?)^```", text, re.S | re.M)
    assert m, "README.md must contain a ```sh block with the two commands"
    # the block opens the README: only the title comes before it
    before = text[:m.start()].strip().splitlines()
    assert before == ["# rotorcosim"], before
    return [line for line in m.group(1).splitlines() if line.strip()]


def ci(option: str) -> str:
    proc = subprocess.run(["bash", str(REPO / ".ci" / "run"), option], capture_output=True, text=True,
                          timeout=30, check=True)
    return proc.stdout.strip()


def test_readme_opens_with_install_run_and_test_commands():
    lines = readme_block()
    assert len(lines) == 2
    run_line, test_line = lines
    assert run_line.startswith("python3 -m venv .venv && ") and test_line.startswith("python3 -m venv .venv && ")
    assert ".venv/bin/pip install -e . && " in run_line
    assert run_line.endswith(".venv/bin/rotorcosim run scenarios/quickstart.yaml")
    assert ".venv/bin/pip install -e '.[test]'" in test_line and test_line.endswith("-m pytest -q")
    for line in lines:                   # well-formed shell
        shlex.split(line)


def test_ci_runs_exactly_the_readme_commands():
    run_line, test_line = readme_block()
    assert ci("--print-test-command") == test_line
    assert ci("--print-run-command") == run_line
    script = (REPO / ".ci" / "run").read_text()
    assert script.startswith("#!/usr/bin/env bash") and "set -euo pipefail" in script
    assert "rc -eq 5" in script          # pytest's "no tests collected" is a failure


def test_pyproject_entry_points_and_extras():
    meta = tomllib.loads((REPO / "pyproject.toml").read_text())
    project = meta["project"]
    assert project["name"] == "rotorcosim" and project["requires-python"] == ">=3.11"
    assert project["scripts"]["rotorcosim"] == "orchestrator.cli:console_main"
    assert any(d.startswith("pytest") for d in project["optional-dependencies"]["test"])
    deps = {re.split(r"[<>=!~ \[]", d)[0].lower() for d in project["dependencies"]}
    assert {"numpy", "scipy", "fmpy", "pythonfmu", "pyyaml"} <= deps
    packages = set(meta["tool"]["setuptools"]["packages"])
    assert {p.split(".")[0] for p in packages} == {"orchestrator", "bearing_fmu", "rotor_fmu", "fmu_common",
                                                   "rotorcosim_scenarios"}
    # the shipped scenarios are the package rotorcosim_scenarios (issue 13: `rotorcosim run quickstart`)
    assert meta["tool"]["setuptools"]["package-dir"]["rotorcosim_scenarios"] == "scenarios"
    assert "*.yaml" in meta["tool"]["setuptools"]["package-data"]["rotorcosim_scenarios"]
    # every package folder of the orchestrator is shipped (the wheel would miss an unlisted one)
    on_disk = {".".join(d.relative_to(REPO).parts) for d in (REPO / "orchestrator").rglob("*")
               if d.is_dir() and (d / "__init__.py").is_file()}
    assert on_disk <= packages, on_disk - packages


def test_readme_links_exist_or_are_owned():
    text = (REPO / "README.md").read_text()
    links = re.findall(r"\]\(([^)#]+)\)", text)
    assert "docs/scenario-format.md" in links
    assert (REPO / "docs" / "scenario-format.md").is_file()


def test_readme_run_scenario_is_shipped_and_valid():
    """README line 1 runs a shipped scenario: it must exist and validate (our FMUs are built if needed)."""
    from orchestrator.scenario import validate_scenario
    run_line = readme_block()[0]
    scenario = REPO / run_line.split(" run ", 1)[1].split()[0]
    assert scenario.is_file(), f"README line 1 runs {scenario}, which is not in the repository"
    assert validate_scenario(scenario) == []
