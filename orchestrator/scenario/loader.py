"""Loading a scenario: read the sections, check them against the FMUs (building is not loading).

:func:`load_scenario` raises one :class:`orchestrator.errors.ScenarioError` listing every
problem with ``file:line``; :func:`validate_scenario` returns them as lines.
"""

from __future__ import annotations

import os
from pathlib import Path
from typing import Sequence

import yaml

from orchestrator.errors import ScenarioError, path_arg
from orchestrator.scenario.checks import FmuChecks
from orchestrator.scenario.limits import check_overrides
from orchestrator.scenario.model import Scenario
from orchestrator.scenario.nodes import GENERATED, YamlLoader, line_order
from orchestrator.scenario.sections import Draft, SectionReader


class ScenarioLoader(FmuChecks, SectionReader):
    """One loading pass over one file: :meth:`read_sections`, optionally :meth:`build`, :meth:`check`."""

    def build(self, draft: Draft) -> None:
        """Let :func:`orchestrator.fmi.build.ensure_fmus` build our own FMUs when missing or stale."""
        from orchestrator.fmi import build
        try:
            build.ensure_fmus(draft.scenario())
        except Exception as exc:                        # reported with the scenario's other problems
            self.problems.append(f"{self.display}: building the scenario's FMUs failed ({type(exc).__name__}: "
                                 f"{exc}); run `rotorcosim build-fmus --force` to see the details")

    def check(self, draft: Draft) -> Scenario | None:
        """Check ``draft`` against its FMUs; the scenario, or None when any problem was found."""
        params = self.check_draft(draft)
        if self.problems:
            return None
        return draft.scenario(params)


def load_scenario(path: str | Path, overrides: Sequence[str] = (), *, build_fmus: bool = False) -> Scenario:
    """Load and validate a scenario file (format version 1).

    Parameters
    ----------
    path : the YAML file; FMU paths in it are relative to its folder.
    overrides : ``"key.path=value"`` strings (the CLI's ``--set``), applied before
        validation; the value is read as YAML (``5e-5``, ``true``, ``[a, b]``).
        Examples: ``coupling.macro_step=5e-5``, ``fmus.bearing1.parameters.n_phi=60``,
        ``connections.0.gain=2``. Unknown paths are errors.
    build_fmus : loading reads and checks only (default): a scenario whose own FMU
        (``fmu: NAME``) is not built yet is refused with the command that builds it.
        ``True``: when the scenario is otherwise valid, first let
        :func:`orchestrator.fmi.build.ensure_fmus` build or rebuild our own FMUs that are
        missing or stale (``rotorcosim run``/``validate`` do; :func:`orchestrator.run`
        rebuilds stale ones before it runs). Building is a step between reading and
        checking, not part of loading.

    The scenario's ``inputs`` are the files loading read (the YAML, an SSP and its .ssd/.ssv
    files, every FMU; :mod:`orchestrator.read_log`) and the existing files its String
    parameters name (:func:`named_files`: not those the FMU writes): what ``sweep --resume`` compares.

    Raises
    ------
    ScenarioError
        listing every problem found, each as ``file:line: what is wrong (got X); fix``.
    """
    from dataclasses import replace

    from orchestrator import read_log
    check_overrides(overrides)
    given = path_arg(path, "load_scenario(path)", "load_scenario('scenarios/quickstart.yaml')")
    with read_log.recording() as reads:     # every file read below is an input of the scenario
        path = from_ssp(given)
        try:
            loader = ScenarioLoader(Path(path), overrides)
            draft = loader.read_sections()
            if build_fmus and draft is not None and not loader.problems and draft.complete:
                loader.build(draft)
            scenario = loader.check(draft) if draft is not None else None
        finally:
            GENERATED.pop(str(path), None)        # its origins are in the messages and parameter origins now
        if loader.problems or scenario is None:
            raise ScenarioError(sorted(loader.problems, key=line_order) or [f"{given}: invalid scenario"])
        for *_, named in named_files(scenario, getattr(loader, "mds", {})):
            reads.add(named)
    scenario = replace(scenario, inputs=tuple(reads.files))
    if path != given:         # made from an SSP: summary.json names the user's file, not the generated one
        scenario = replace(scenario, source=given.resolve(), extracted=Path(path).parent.resolve())
    return scenario


#: String parameters our FMUs write a file to, not read one from (the bearing's film fields at
#: fmi2Terminate): an existing file there is an earlier run's output, neither an input of the run nor
#: a file export-ssp carries (it would set the parameter to the extracted copy, and the run from the
#: archive would write its fields into the temporary folder, removed when the command ends)
WRITTEN_FILE_PARAMETERS = ("fields_file",)


def named_files(scenario: Scenario, variables: dict, *, special: bool = False) -> list[tuple[str, str, Path]]:
    """``(instance, parameter, path)`` of each existing regular file the scenario's String
    parameters name (a rotor file; ``variables``: instance -> {name: model variable}): the FMU
    reads them when the run starts, so they are inputs of the run as much as the YAML is, and an
    exported SSP carries them (by the rule of :func:`orchestrator.scenario.ssp._named_files`). A
    path is resolved as the FMU resolves it (relative to the working directory); ``{out_dir}``
    paths are the run's own outputs and are left out, and so are the files the FMU writes
    (:data:`WRITTEN_FILE_PARAMETERS`). ``special``: also those naming a folder, FIFO, device or
    socket (export-ssp says it does not carry them; never opened here, only ``stat``-ed); without
    it a folder is no file: never listed."""
    from orchestrator.untrusted import OUT_DIR_FIELD
    found = []
    for spec in scenario.fmus:
        for name, value in spec.parameters.items():
            var = variables.get(spec.name, {}).get(name)
            if var is None or var.type != "String" or not isinstance(value, str) or not value.strip() \
                    or OUT_DIR_FIELD in value or name in WRITTEN_FILE_PARAMETERS:
                continue
            try:
                candidate = Path(value).expanduser()
                if candidate.is_file() or special and candidate.exists():
                    found.append((spec.name, name, candidate))
            except (OSError, ValueError, RuntimeError):  # a name too long, a NUL: not a file
                continue
    return found


def from_ssp(path: Path) -> Path:
    """An ``.ssp``/``.ssd`` file, or a YAML scenario with ``ssp: FILE``, as a generated YAML scenario.

    The SSP is read by :func:`orchestrator.ssp.scenario_from_ssp` (an archive is extracted into a
    temporary folder that lives until the process exits); a YAML scenario's own keys then add to or
    override it: ``fmus.<instance>`` entries are merged key by key (so ``parameters`` can be added),
    ``connections`` are appended, every other key replaces the SSP's. The generated file is written
    next to the extracted SSP and loaded as any scenario (problems name that file).
    """
    import atexit
    import shutil
    import tempfile

    from orchestrator.scenario.ssp import scenario_from_ssp
    overlay: dict = {}
    overlay_lines: dict[tuple, int] = {}
    ssp = path
    if path.suffix.lower() in (".yaml", ".yml") and path.is_file():
        try:              # bounded like every scenario read (size, UTF-8, depth, aliases)
            from orchestrator.scenario.nodes import YamlLoader
            from orchestrator.untrusted import InputError, compose_yaml, construct_yaml, read_text
            root = compose_yaml(read_text(path, what="scenario file"), display=str(path), loader_cls=YamlLoader)
            doc = None if root is None else construct_yaml(root, display=str(path), loader_cls=YamlLoader)
        except (InputError, yaml.YAMLError):
            return path                                  # the loader reports it with line numbers
        if not isinstance(doc, dict) or "ssp" not in doc:
            return path
        if not isinstance(doc["ssp"], str):
            raise ScenarioError(f"{path}: 'ssp' must name an .ssp or .ssd file (got {doc['ssp']!r})")
        ssp = (path.parent / doc.pop("ssp")).resolve()
        overlay = doc
        overlay_lines = _key_lines(root)             # where the user's values are, for the problems
    elif path.suffix.lower() not in (".ssp", ".ssd"):
        return path
    if not ssp.is_file():
        raise ScenarioError(f"{path}: SSP file {ssp} not found; check the path")
    work = Path(tempfile.mkdtemp(prefix="rotorcosim-ssp-"))
    atexit.register(shutil.rmtree, work, True)
    from orchestrator import read_log
    read_log.made_here(work)                  # extracted and generated here: the SSP itself is the input
    doc = scenario_from_ssp(ssp, work / "ssp")
    for key, value in overlay.items():
        if key == "fmus" and isinstance(value, dict):
            for inst, entry in value.items():
                base = doc["fmus"].get(inst, {})
                merged = {**base, **(entry or {})}
                if isinstance(base.get("parameters"), dict) and isinstance((entry or {}).get("parameters"), dict):
                    merged["parameters"] = {**base["parameters"], **entry["parameters"]}
                if "path" in (entry or {}):
                    merged["path"] = str((path.parent / entry["path"]).resolve())
                doc["fmus"][inst] = merged
        elif key == "connections" and isinstance(value, list):
            doc["connections"] = doc.get("connections", []) + value
        elif key == "coupling" and isinstance(value, dict) and isinstance(doc.get("coupling"), dict):
            doc["coupling"] = {**doc["coupling"], **value}
        else:
            doc[key] = value
    out = work / f"{ssp.stem}.yaml"
    text = f"# generated from {ssp} by rotorcosim\n" + yaml.safe_dump(doc, sort_keys=False)
    out.write_text(text)
    n_ssp_connections = len(doc.get("connections", [])) - len(overlay.get("connections", []) or []) \
        if isinstance(overlay.get("connections"), list) else len(doc.get("connections", []))
    # a String parameter set to a file the archive carries names the member, not the temporary folder
    extracted = str((work / "ssp").resolve()) + os.sep
    carried = {("fmus", inst, "parameters", name): value[len(extracted):]
               for inst, entry in doc["fmus"].items() if isinstance(entry, dict)
               for name, value in (entry.get("parameters") or {}).items()
               if isinstance(value, str) and value.startswith(extracted)}
    GENERATED[str(out)] = (str(ssp), _origins(text, ssp, path, overlay_lines, n_ssp_connections, carried))
    return out


def _key_lines(root) -> dict[tuple, int]:
    """{path of keys and list indices: line} of every value in a composed YAML tree (1-based);
    a node met again through an alias is not walked again (bounded by the tree's size)."""
    lines: dict[tuple, int] = {}
    seen: set[int] = set()
    stack = [((), root)]
    while stack:
        prefix, node = stack.pop()
        if id(node) in seen:
            continue
        seen.add(id(node))
        if isinstance(node, yaml.MappingNode):
            for k, v in node.value:
                if isinstance(k, yaml.ScalarNode):
                    lines.setdefault(prefix + (k.value,), k.start_mark.line + 1)
                    stack.append((prefix + (k.value,), v))
        elif isinstance(node, yaml.SequenceNode):
            for i, v in enumerate(node.value):
                lines.setdefault(prefix + (i,), v.start_mark.line + 1)
                stack.append((prefix + (i,), v))
    return lines


def _origins(text: str, ssp: Path, overlay_file: Path, user: dict[tuple, int],
             n_ssp_connections: int, carried: dict[tuple, str] | None = None) -> dict[int, str]:
    """{line of the generated scenario: origin} for :data:`nodes.GENERATED`: ``FILE:LINE`` of the
    user's YAML file ``overlay_file`` for a value it sets (``user``: its :func:`_key_lines`;
    ``fmus.<i>`` entries and ``coupling`` merged key by key, ``connections`` appended, other keys
    replaced: :func:`from_ssp`), else ``SSP [dotted.path]``, for a parameter set to a file the
    archive carries (``carried``: key path -> member) ``SSP [dotted.path] (its file MEMBER)``."""
    generated = _key_lines(yaml.compose(text, Loader=YamlLoader))
    out: dict[int, str] = {}
    for key_path, line in generated.items():
        mine = key_path
        if key_path[:1] == ("connections",) and len(key_path) > 1 and isinstance(key_path[1], int):
            mine = ("connections", key_path[1] - n_ssp_connections) + key_path[2:] \
                if key_path[1] >= n_ssp_connections else None
        elif key_path[:1] not in (("fmus",), ("coupling",)):
            # a replaced key: everything under it is the user's
            while mine and mine not in user:
                mine = mine[:-1]
        if mine and mine in user:
            at = f"{overlay_file}:{user[mine]}"
        else:
            dotted = ".".join(str(k) if isinstance(k, str) else f"[{k}]" for k in key_path).replace(".[", "[")
            at = f"{ssp} [{dotted}]" + (f" (its file {carried[key_path]})" if carried and key_path in carried else "")
        out.setdefault(line, at)
    return out


def validate_scenario(path: str | Path, overrides: Sequence[str] = (), *,
                      build_fmus: bool = True) -> list[str]:
    """Every problem of a scenario file as readable lines (empty: the scenario is valid).

    Validation is a step of a run, so unlike :func:`load_scenario` it first builds
    our own FMUs that are missing or stale (``build_fmus=False``: only check, and
    report a missing FMU with the command that builds it), and it checks what the run's
    analysis would refuse (:func:`check_analysis_clearance`).
    """
    from orchestrator.scenario.analysis_clearance import check_analysis_clearance
    path_arg(path, "validate_scenario(path)", "validate_scenario('scenarios/quickstart.yaml')")
    try:
        check_analysis_clearance(load_scenario(path, overrides, build_fmus=build_fmus))
    except ScenarioError as exc:
        return list(exc.problems)
    return []
