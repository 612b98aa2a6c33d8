"""Section parsing of a scenario file: from YAML nodes to the parts of a :class:`Scenario`.

:class:`SectionReader` reads every section into a :class:`Draft` (problems collected,
nothing raised for a bad value); checks against the FMUs are :mod:`.checks`.

Length: one reader method per section of the documented format (docs/scenario-format.md),
sharing the node helpers and the problem list so that every problem of a file is reported in
one pass; above ~400 lines for that reason (the coupling sub-sections live in
:mod:`.coupling_sections`).
"""

from __future__ import annotations

import importlib.util
import logging
import re
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import yaml

from orchestrator.errors import ScenarioError
from orchestrator.scenario.coupling_sections import load_iteration, load_step_control
from orchestrator.scenario.model import (
    CONNECTION_KEYS, COUPLING_KEYS, FMU_KEYS, ISOLATION, MAX_DISCARD_RETRIES, MAX_ORDER, OUTPUT_FORMATS, OUTPUT_KEYS,
    SCENARIO_VERSION,
    SCHEMES, TOP_KEYS, ConnectionSpec, CouplingSpec, FmuSpec, OutputSpec, Scenario)
from orchestrator.scenario.nodes import NodeReader, YamlLoader, did_you_mean, flatten_merges
from orchestrator.scenario.limits import (MAX_FMU_INSTANCES, MAX_MACRO_STEPS, MAX_OUTPUT_ROWS, MAX_SUBSTEPS,
                                          MIN_MACRO_STEP, MIN_RELATIVE_STEP)
from orchestrator.scenario.overrides import apply_override
from orchestrator.untrusted import InputError, check_yaml_tree, name_problem, out_dir_escape, read_yaml_tree

log = logging.getLogger("orchestrator.scenario")

INSTANCE_RE = re.compile(r"^[A-Za-z_][A-Za-z0-9_-]*$")
MAX_INSTANCE_NAME = 100     # characters, as untrusted.check_name allows for names that become paths
FROM_FMUS = object()        # stop_time not written: taken from the FMUs' DefaultExperiment (checks.apply_defaults)


def our_fmus() -> list[str]:
    """The names of our FMUs (``fmu: NAME``)."""
    from orchestrator.fmi.build import RECIPES
    return list(RECIPES)


@dataclass
class Draft:
    """The parsed sections of a scenario before the checks against its FMUs.

    ``fmus`` / ``connections`` are dicts that keep their YAML nodes (for messages);
    ``complete`` says whether every required value could be read.
    """

    kw: dict
    fmus: list
    connections: list
    coupling: dict | None
    interval: float | None
    signals: list | None
    analysis_node: Any = None
    coupling_node: Any = None
    output_format: str = "csv"

    @property
    def complete(self) -> bool:
        return None not in self.kw.values() and self.coupling is not None      # FROM_FMUS counts as given

    def scenario(self, params: dict | None = None) -> Scenario:
        """The :class:`Scenario` of these sections; ``params``: checked parameters per instance
        (None: the values as written, for building the FMUs before they are read)."""
        fmus = self.fmus
        if params is None:
            params = {f["name"]: {k: v for k, (v, _) in f["parameters"].items()} for f in fmus}
        return Scenario(
            fmus=tuple(FmuSpec(name=f["name"], path=f["path"], parameters=params[f["name"]],
                               substeps=f["substeps"], line=f["line"], isolation=f["isolation"],
                               parameter_origins=dict(f.get("origins", {}))) for f in fmus),
            connections=tuple(ConnectionSpec(src=c["from"], dst=c["to"], gain=c["gain"], offset=c["offset"],
                                             line=c["line"]) for c in self.connections),
            coupling=CouplingSpec(**self.coupling),
            output=OutputSpec(interval=self.interval, signals=self.signals and tuple(s for s, _ in self.signals),
                              format=self.output_format),
            **self.kw)


class SectionReader(NodeReader):
    """One pass over one scenario file's sections; problems go to ``self.problems``."""

    def __init__(self, path: Path, overrides):
        super().__init__(Path(path), str(path))
        self.overrides = list(overrides)
        self.instances: list[str] = []         # every instance name written under 'fmus'
        self.fmu_specs: list[dict] = []        # parsed 'fmus' entries
        self.output_format = "csv"

    # -- the pass ----------------------------------------------------------
    def read_sections(self) -> Draft | None:
        """Read the file, apply the overrides and parse every section (no FMU is opened)."""
        root = self._read_tree()
        for text in self.overrides:
            apply_override(self, root, text)
        element = _xml_root(root)
        if element:
            fix = {"SystemStructureDescription": "it is an SSD: give it the extension .ssd and it is read as one",
                   "fmiModelDescription": "it is an FMU's model description: name the .fmu under 'fmus' of a YAML "
                                          "scenario (rotorcosim info X.fmu lists its variables)",
                   "OspSystemStructure": "an OSP system structure is not read: write its simulators as 'fmus' and "
                                         "its connections as 'connections' of a YAML scenario"}.get(
                element.split(":")[-1], "write the system as a YAML scenario")
            self.err(root, f"is an XML file (root element <{element}>), not a scenario: rotorcosim reads YAML "
                           "scenarios (docs/scenario-format.md) and SSP 1.0 system structures as an .ssp archive or "
                           f"an .ssd file (\"Scenarios from SSP\" there); {fix}")
            return None
        top = self.mapping(root, "top level", TOP_KEYS, ("name", "fmus"),
                           fix="a scenario is a mapping with at least 'name' and 'fmus'")
        if top is None:
            return None
        get = lambda key: top[key][1] if key in top else None      # noqa: E731
        kw = self._top_scalars(top, get)
        start, stop = kw["start_time"], kw["stop_time"]
        fmus = self.load_fmus(get("fmus")) if "fmus" in top else []
        self.fmu_specs = fmus
        names = [f["name"] for f in fmus]
        given_stop = None if stop is FROM_FMUS else stop
        coupling = self.load_coupling(get("coupling"), names, start, given_stop)
        self.default_isolation = (coupling or {}).get("isolation") or "none"
        interval, signals = self.load_output(get("output"), given_stop, start)
        self.check_rows(get("output"), interval, coupling, start, given_stop)
        connections = self.load_connections(get("connections"))
        for key in ("analysis", "compare"):
            if key in top:
                if not isinstance(get(key), yaml.MappingNode):
                    self.err(get(key), f"'{key}' must be a mapping (got {self.got(get(key))}); see "
                                       f"docs/{'analysis' if key == 'analysis' else 'compare'}.md")
                else:
                    kw[key] = self.value(get(key))

        self.top_keys = set(top)
        self.root_node = root
        return Draft(kw=kw, fmus=fmus, connections=connections, coupling=coupling, interval=interval,
                     signals=signals, analysis_node=get("analysis") if "analysis" in top else None,
                     coupling_node=get("coupling"),
                     output_format=self.output_format)

    def _read_tree(self):
        """The file's YAML node tree, bounded (regular file, size, UTF-8, depth, alias
        expansion), merge keys flattened and bounded again."""
        try:
            root = read_yaml_tree(self.path, what="scenario file", loader_cls=YamlLoader)
        except InputError as exc:
            raise ScenarioError(str(exc)) from None
        if root is None:
            raise ScenarioError(f"{self.display}:1: expected a scenario (a mapping with at least "
                                "'name', 'stop_time' and 'fmus'), got an empty file; see docs/scenario-format.md")
        try:
            flatten_merges(self.ctor, root, set())
        except yaml.MarkedYAMLError as exc:
            mark = exc.problem_mark or exc.context_mark
            raise ScenarioError(f"{self.display}:{mark.line + 1 if mark else 1}: {exc.problem}; '<<' merges "
                                "mappings only (write '<<: *anchor' or '<<: [*a, *b]')") from None
        try:
            check_yaml_tree(root, display=self.display)      # the merged tree, bounded again
        except InputError as exc:
            raise ScenarioError(str(exc)) from None
        return root

    def _top_scalars(self, top, get) -> dict[str, Any]:
        """``name``, ``version``, ``description``, ``start_time``, ``stop_time`` (``FROM_FMUS``
        when not given: the FMUs' DefaultExperiment, checks.py)."""
        kw: dict[str, Any] = {"source": self.path.resolve()}
        if "name" in top:
            name = self.string(get("name"), "name", "give the scenario a name such as 'two-mass-oscillator'")
            if name is not None and name_problem(name) is not None:     # the one check of names that become paths
                self.err(get("name"), f"'name' is used as a folder name (runs/<name>), but {name_problem(name)}; "
                                      "rename it with letters, digits, '-', '_' and '.'")
                name = None
            kw["name"] = name
        if "version" in top:
            v = self.integer(get("version"), "version", 1, None, "write 'version: 1' or remove it")
            if v is not None and v != SCENARIO_VERSION:
                self.err(get("version"), f"scenario format version {v} is not supported by this rotorcosim "
                                         f"(it reads version {SCENARIO_VERSION}); upgrade rotorcosim or convert "
                                         "the file (docs/scenario-format.md)")
            kw["version"] = SCENARIO_VERSION
        if "description" in top:
            d = self.value(get("description")) if isinstance(get("description"), yaml.ScalarNode) else None
            if not isinstance(d, str):
                self.err(get("description"), f"'description' must be a text (got {self.got(get('description'))});"
                                             " quote it")
            else:
                kw["description"] = d
        start = self.number(get("start_time"), "start_time") if "start_time" in top else 0.0
        kw["start_time"] = start
        stop = FROM_FMUS if "stop_time" not in top else None
        if "stop_time" in top:
            stop = self.number(get("stop_time"), "stop_time", fix="write the end time in seconds, e.g. 0.5")
            if stop is not None and start is not None and stop <= start:
                self.err(get("stop_time"), f"'stop_time' must be greater than start_time ({start!r}) (got "
                                           f"{stop!r}); set a later stop time")
                stop = None
        kw["stop_time"] = stop
        return kw

    # -- sections ----------------------------------------------------------
    def load_fmus(self, node) -> list[dict]:
        section = self.mapping(node, "fmus", fix="write 'fmus:' followed by 'instance: {path: X.fmu}' lines")
        if section is None:
            return []
        self.instances = list(section)
        if not section:
            self.err(node, "'fmus' must list at least one FMU instance (got none); add 'name: {path: X.fmu}'")
        if len(section) > MAX_FMU_INSTANCES:
            self.err(node, f"'fmus' lists {len(section)} FMU instances, more than {MAX_FMU_INSTANCES} (each is an FMU "
                           "loaded, instantiated and stepped; orchestrator.scenario.limits.MAX_FMU_INSTANCES); "
                           "split the system into scenarios of fewer instances")
            return []
        out = []
        for name, (knode, vnode) in section.items():
            if not INSTANCE_RE.match(name):
                self.err(knode, f"instance name must start with a letter or '_' and contain only letters, digits, "
                                f"'_' and '-' (got {name!r}); rename it (signals are written 'instance.variable')")
                continue
            if len(name) > MAX_INSTANCE_NAME:    # it names the worker's folder (isolation: process) and files
                self.err(knode, f"instance name is {len(name)} characters long (got {name[:20]!r}...), more than "
                                f"{MAX_INSTANCE_NAME}; give it a shorter name")
                continue
            entry = self.mapping(vnode, f"fmus.{name}", FMU_KEYS, (),
                                 fix=f"write '{name}: {{path: X.fmu}}' or '{name}: {{fmu: JournalBearing}}'")
            if entry is None:
                continue
            if ("path" in entry) == ("fmu" in entry):
                self.err(vnode, f"'fmus.{name}' needs exactly one of 'path' (an FMU file) and 'fmu' (one of ours by "
                                f"name: {', '.join(our_fmus())}) (got {'both' if 'path' in entry else 'neither'}); "
                                f"write '{name}: {{path: X.fmu}}' or '{name}: {{fmu: JournalBearing}}'")
            spec = {"name": name, "line": knode.start_mark.line + 1 if knode.start_mark else None,
                    "node": knode, "path": None, "parameters": {}, "origins": {}, "substeps": None,
                    "isolation": None}
            if "path" in entry:
                p = self.string(entry["path"][1], f"fmus.{name}.path", "give the FMU file, relative to this file")
                if p is not None and (any(ord(ch) < 32 for ch in p) or len(p) > 4096):
                    self.err(entry["path"][1], f"'fmus.{name}.path' must be a file path without control characters "
                                               f"and at most 4096 characters (got {p[:60]!r}); fix the path")
                elif p is not None:
                    spec["path"] = (self.path.parent / Path(p).expanduser()).resolve()
                    spec["path_node"] = entry["path"][1]
            elif "fmu" in entry:
                key = self.string(entry["fmu"][1], f"fmus.{name}.fmu", f"name one of ours: {', '.join(our_fmus())}")
                if key is not None and key not in our_fmus():
                    self.err(entry["fmu"][1], f"'fmus.{name}.fmu' names our FMUs by name, one of "
                                              f"{', '.join(our_fmus())} (got {key!r}); "
                                              f"{did_you_mean(key, our_fmus())}for another FMU write 'path: X.fmu'")
                elif key is not None:
                    from orchestrator.fmi.build import fmu_location
                    spec["path"] = fmu_location(key)
                    spec["path_node"] = entry["fmu"][1]
                    spec["ours"] = key
            if "substeps" in entry:
                spec["substeps"] = self.integer(entry["substeps"][1], f"fmus.{name}.substeps", 1, MAX_SUBSTEPS,
                                                "use a whole number of sub-steps per macro step")
            if "isolation" in entry:
                spec["isolation"] = self.isolation(entry["isolation"][1], f"fmus.{name}.isolation")
            if "parameters" in entry:
                pmap = self.mapping(entry["parameters"][1], f"fmus.{name}.parameters",
                                    fix="write 'parameters: {name: value, ...}'")
                for pname, (_, pv) in (pmap or {}).items():
                    if not isinstance(pv, yaml.ScalarNode) or self.value(pv) is None:
                        self.err(pv, f"parameter '{name}.{pname}' must be a single value (number, true/false or "
                                     f"text) (got {self.got(pv)}); write one value")
                    else:
                        spec["parameters"][pname] = (self.value(pv), pv)
                        spec["origins"][pname] = self.loc(pv)
                        why = out_dir_escape(self.value(pv))
                        if why:
                            self.err(pv, f"parameter '{name}.{pname}' is a path in the run folder, but {why}")
            out.append(spec)
        return out

    def load_coupling(self, node, names: list[str], start, stop) -> dict | None:
        c: dict[str, Any] = {"sequence": tuple(names)}
        section = {} if node is None else self.mapping(node, "coupling", COUPLING_KEYS)
        if section is None:
            return None
        ok = True
        if "scheme" in section:
            s = self.value(section["scheme"][1]) if isinstance(section["scheme"][1], yaml.ScalarNode) else None
            if s not in SCHEMES:
                self.err(section["scheme"][1], f"'coupling.scheme' must be one of {list(SCHEMES)} (got "
                                               f"{self.got(section['scheme'][1])}); "
                                               f"{did_you_mean(str(s), SCHEMES) or 'pick one of them'}".rstrip())
                ok = False
            else:
                c["scheme"] = s
        if "sequence" in section:
            order = self.load_sequence(section["sequence"][1], names)
            ok &= order is not None
            if order is not None:
                c["sequence"] = order
        step_ok, h = self.load_macro_step(node, section, start, stop)
        ok &= step_ok
        if "macro_step" in section:
            c["macro_step"] = h
        for key in ("extrapolation_order", "interpolation_order"):
            if key in section:
                v = self.integer(section[key][1], f"coupling.{key}", 0, MAX_ORDER,
                                 "use 0 (hold), 1 (linear), 2 (quadratic) or 3 (cubic)")
                ok &= v is not None
                c[key] = v
        if "substeps" in section:
            v = self.integer(section["substeps"][1], "coupling.substeps", 1, MAX_SUBSTEPS,
                             "use a whole number of sub-steps per macro step (a larger one: a smaller macro_step)")
            ok &= v is not None
            c["substeps"] = v
        if "discard_retries" in section:
            v = self.integer(section["discard_retries"][1], "coupling.discard_retries", 0, MAX_DISCARD_RETRIES,
                             "use 0 (stop the run when an FMU returns fmi2Discard) or the number of times a "
                             "discarded macro step may be halved, e.g. 3 (smallest step macro_step / 2^3)")
            ok &= v is not None
            c["discard_retries"] = v
            if v and c.get("scheme") == "monolithic":
                log.warning("%s: coupling.discard_retries = %d is ignored by the monolithic scheme (one "
                            "integrator with its own step-size control, no macro steps to retry)",
                            self.loc(section["discard_retries"][1]), v)
        ok &= self.load_worker_keys(section, c)
        for key, load in (("iteration", load_iteration), ("step_control", load_step_control)):
            if key in section:
                v = load(self, section[key][1])
                ok &= v is not None
                c[key] = v
        if "options" in section:
            if not isinstance(section["options"][1], yaml.MappingNode):
                self.err(section["options"][1], f"'coupling.options' must be a mapping (got "
                                                f"{self.got(section['options'][1])}); write 'options: {{key: value}}'")
                ok = False
            else:
                c["options"] = self.value(section["options"][1])
        return c if ok else None

    def load_sequence(self, node, names: list[str]) -> tuple[str, ...] | None:
        """``coupling.sequence``: every instance exactly once (None: problem reported)."""
        if not names:           # 'fmus' refused (reported): every entry read "not an instance (instances: )"
            return None
        seq = self.strings(node, "coupling.sequence", "list every instance once")
        if seq is None:
            return None
        order = [s for s, _ in seq]
        problems = []
        for s, _ in seq:
            if s not in names:
                problems.append(f"'{s}' is not an instance ({did_you_mean(s, names)}instances: "
                                f"{', '.join(names)})")
        dup = sorted({s for s in order if order.count(s) > 1})
        missing = [s for s in names if s not in order]
        if dup:
            problems.append(f"{', '.join(dup)} listed more than once")
        if missing:
            problems.append(f"missing {', '.join(missing)}")
        if problems:
            self.err(node, "'coupling.sequence' must list every instance exactly once "
                           f"({'; '.join(problems)}); e.g. [{', '.join(names)}]")
            return None
        return tuple(order)

    def load_macro_step(self, node, section, start, stop) -> tuple[bool, float | None]:
        """``coupling.macro_step`` checked against the run's length and step count; without
        the key, the default step is checked. Returns (no problem reported, the checked step
        or None)."""
        if "macro_step" in section:
            h = self.number(section["macro_step"][1], "coupling.macro_step", positive=True,
                            fix="give the communication step in seconds, e.g. 1.0e-4")
            if h is not None and start is not None and stop is not None and h > _span(start, stop):
                self.err(section["macro_step"][1], f"'coupling.macro_step' must not exceed stop_time - start_time "
                                                   f"({stop - start!r}) (got {h!r}); use a smaller step")
                h = None
            if h is not None and start is not None and stop is not None:
                h = self.check_step_count(section["macro_step"][1], h, start, stop)
            return h is not None, h
        if start is not None and stop is not None:        # the default step must fit too
            return self.check_step_count(node, CouplingSpec.macro_step, start, stop) is not None, None
        return True, None

    def check_step_count(self, node, h: float, start: float, stop: float) -> float | None:
        """``h`` if the run's macro steps stay within MAX_MACRO_STEPS and the time grid
        resolves them (MIN_RELATIVE_STEP), else None (problem reported)."""
        scale = max(abs(start), abs(stop))
        if h < MIN_RELATIVE_STEP * scale:
            self.err(node, f"'coupling.macro_step' {h!r} is too small for the time {scale:g} s: t = start_time + n * "
                           f"macro_step cannot resolve it (the limit is macro_step >= {MIN_RELATIVE_STEP:g} * "
                           "max(|start_time|, |stop_time|)); use a larger step or shift the times towards 0")
            return None
        if h < MIN_MACRO_STEP:
            self.err(node, f"'coupling.macro_step' {h!r} s is below the smallest macro step, {MIN_MACRO_STEP:g} s "
                           "(1 fs; the master's input weights take 1/macro_step to the third power); use a "
                           "larger step, or express the times in a larger unit")
            return None
        n = (stop - start) / h
        if n > MAX_MACRO_STEPS:
            self.err(node, f"(stop_time - start_time) / macro_step = {n:.3g} macro steps (the limit is "
                           f"{MAX_MACRO_STEPS:.0e}); use a larger macro_step or a shorter run")
            return None
        return h

    def check_rows(self, node, interval, coupling, start, stop) -> None:
        """results.csv (and the in-memory result) get at most MAX_OUTPUT_ROWS rows."""
        every = interval or (coupling or {}).get("macro_step")
        if every and start is not None and stop is not None and (stop - start) / every > MAX_OUTPUT_ROWS:
            self.err(node, f"the run writes (stop_time - start_time) / output.interval = {(stop - start) / every:.3g} "
                           f"rows of results (the limit is {MAX_OUTPUT_ROWS:.0e}); set a larger 'output.interval' "
                           "(rows are written every interval, by default every macro step)")

    def isolation(self, node, what: str) -> str | None:
        v = self.value(node) if isinstance(node, yaml.ScalarNode) else None
        if v not in ISOLATION:
            self.err(node, f"'{what}' must be one of {list(ISOLATION)} (got {self.got(node)}); use 'process' to "
                           "run the FMU in a worker process of its own (docs/coupling.md), 'none' to load it into "
                           "the master")
            return None
        return v

    def load_worker_keys(self, section: dict, c: dict) -> bool:
        """coupling.isolation, .parallel, .call_timeout, .pin_workers (FMUs in worker processes)."""
        ok = True
        if "isolation" in section:
            v = self.isolation(section["isolation"][1], "coupling.isolation")
            ok &= v is not None
            c["isolation"] = v
        for key, meaning in (("parallel", "true steps the isolated FMUs of a stage at the same time, 'threads' "
                                          "also those in the master's process (each in a thread)"),
                             ("pin_workers", "true keeps each worker process on a CPU of its own")):
            if key in section:
                node = section[key][1]
                v = self.value(node) if isinstance(node, yaml.ScalarNode) else None
                if key == "parallel" and v == "threads":
                    pass
                elif not isinstance(v, bool):
                    allowed = "true, false or threads" if key == "parallel" else "true or false"
                    self.err(node, f"'coupling.{key}' must be {allowed} (got {self.got(node)}); {meaning}")
                    ok = False
                c[key] = v
        if "call_timeout" in section:
            v = self.number(section["call_timeout"][1], "coupling.call_timeout", positive=True,
                            fix="give the longest time in seconds an isolated FMU may take for one call, e.g. 60")
            ok &= v is not None
            c["call_timeout"] = v
        if "defect_signals" in section:
            v = self.strings(section["defect_signals"][1], "coupling.defect_signals",
                             "list coupling inputs (a connection's 'to' name) or patterns, "
                             "e.g. [\"b.u\", \"rotor.F*\"]")
            ok &= v is not None
            c["defect_signals"] = tuple(s for s, _ in v or ())
        if "defect_retries" in section:
            v = self.integer(section["defect_retries"][1], "coupling.defect_retries", 0, MAX_DISCARD_RETRIES,
                             "use 0 (only report the coupling defect) or the number of times a macro step whose "
                             "defect is over coupling.defect_limit may be halved, e.g. 4 (smallest step "
                             "macro_step / 2^4)")
            ok &= v is not None
            c["defect_retries"] = v
        if "defect_limit" in section:
            node = section["defect_limit"][1]
            v = self.value(node) if isinstance(node, yaml.ScalarNode) else None
            if isinstance(v, float) and v == float("inf"):
                c["defect_limit"] = v
            else:
                v = self.number(node, "coupling.defect_limit", positive=True,
                                fix="give the defect, as a multiple of a journal's typical force, above which a "
                                    "step is flagged, e.g. 1.0 (the default), or .inf for never")
                ok &= v is not None
                c["defect_limit"] = v
        return ok

    def load_output(self, node, stop, start):
        if node is None:
            return None, None
        section = self.mapping(node, "output", OUTPUT_KEYS)
        if section is None:
            return None, None
        interval = signals = None
        if "format" in section:
            fnode = section["format"][1]
            fmt = self.string(fnode, "output.format", "write 'csv' or 'parquet'")
            if fmt is not None and fmt not in OUTPUT_FORMATS:
                self.err(fnode, f"'output.format' must be one of {list(OUTPUT_FORMATS)} (got {fmt!r}); write 'csv' "
                                "or 'parquet'")
            elif fmt == "parquet" and importlib.util.find_spec("pyarrow") is None:
                self.err(fnode, "'output.format: parquet' needs pyarrow, which is not installed; "
                                "`pip install pyarrow` (or 'rotorcosim[parquet]') or write 'output.format: csv'")
            elif fmt is not None:
                self.output_format = fmt
        if "interval" in section:
            interval = self.number(section["interval"][1], "output.interval", positive=True,
                                   fix="give the output interval in seconds, e.g. 1.0e-3")
            if interval is not None and stop is not None and start is not None and interval > _span(start, stop):
                self.err(section["interval"][1], f"'output.interval' must not exceed stop_time - start_time "
                                                 f"({stop - start!r}) (got {interval!r}); use a smaller interval")
        if "signals" in section:
            signals = self.strings(section["signals"][1], "output.signals",
                                   "list signals as 'instance.variable'")
            seen = set()
            for s, n in signals or ():
                if s in seen:
                    self.err(n, f"'output.signals' lists '{s}' twice; remove the duplicate")
                seen.add(s)
        return interval, signals

    def load_connections(self, node) -> list[dict]:
        if node is None:
            return []
        if not isinstance(node, yaml.SequenceNode):
            self.err(node, f"'connections' must be a list (got {self.got(node)}); write "
                           "'- {from: a.y, to: b.u}' lines")
            return []
        out = []
        for i, item in enumerate(node.value):
            where = f"connections[{i}]"
            if isinstance(item, yaml.ScalarNode) and isinstance(self.value(item), str) and "->" in item.value:
                c = self.arrow_connection(item, where)     # the one-line form "a.y -> b.u"
                if c is not None:
                    out.append(c)
                continue
            entry = self.mapping(item, where, CONNECTION_KEYS, ("from", "to"),
                                 fix="write '- {from: instance.output, to: instance.input}'")
            if entry is None:
                continue
            c = {"line": item.start_mark.line + 1 if item.start_mark else None, "node": item,
                 "gain": 1.0, "offset": 0.0}
            for key in ("from", "to"):
                if key in entry:
                    s = self.string(entry[key][1], f"{where}.{key}", "write 'instance.variable'")
                    if s is not None and "." not in s:
                        self.err(entry[key][1], f"'{where}.{key}' must be 'instance.variable' (got {s!r}); "
                                                "add the instance name and a dot")
                        s = None
                    c[key], c[key + "_node"] = s, entry[key][1]
            for key in ("gain", "offset"):
                if key in entry:
                    c[key] = self.number(entry[key][1], f"{where}.{key}")
                    c[key + "_node"] = entry[key][1]
            out.append(c)
        return out

    def arrow_connection(self, item, where: str) -> dict | None:
        """``"drv.f[0] -> osc.f[0]"``: a connection without gain/offset written as one string."""
        parts = [p.strip() for p in str(self.value(item)).split("->")]
        if len(parts) != 2 or not all("." in p and " " not in p for p in parts):
            self.err(item, f"'{where}' {item.value!r} is not 'instance.output -> instance.input'; write one "
                           "arrow between two 'instance.variable' names (or a mapping {from: ..., to: ...})")
            return None
        return {"line": item.start_mark.line + 1 if item.start_mark else None, "node": item, "gain": 1.0,
                "offset": 0.0, "from": parts[0], "from_node": item, "to": parts[1], "to_node": item}


def _xml_root(node) -> str | None:
    """The root element's name when the file read as YAML is one XML text (``<?xml ...`` or
    ``<Name ...``), else None."""
    if not isinstance(node, yaml.ScalarNode) or not isinstance(node.value, str):
        return None
    m = re.match(r"\s*(?:<\?xml[^>]*\?>\s*)?(?:<!--.*?-->\s*)*<([A-Za-z_][\w.:-]*)", node.value, re.S)
    return m.group(1) if m else None


def _span(start: float, stop: float) -> float:
    """``stop - start`` with the rounding of the subtraction allowed for: 0.5002 - 0.5 is
    0.00019999999999997797, and a macro step or output interval of 2e-4 was refused as longer
    than the run (the master takes time from the step index and compares with a tolerance)."""
    return (stop - start) * (1 + 1e-9)
