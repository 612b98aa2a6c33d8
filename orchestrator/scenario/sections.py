"""Section parsing of a scenario file: from YAML nodes to the parts of a :class:`Scenario`.

:class:`SectionReader` reads every section into a :class:`Draft` (problems collected,
nothing raised for a bad value); checks against the FMUs are :mod:`.checks`.
"""

from __future__ import annotations

import logging
import re
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import yaml

from orchestrator.errors import ScenarioError
from orchestrator.scenario.coupling_sections import load_iteration, load_step_control
from orchestrator.scenario.model import (
    CONNECTION_KEYS, COUPLING_KEYS, FMU_KEYS, MAX_DISCARD_RETRIES, MAX_ORDER, OUTPUT_KEYS, SCENARIO_VERSION,
    SCHEMES, TOP_KEYS, ConnectionSpec, CouplingSpec, FmuSpec, OutputSpec, Scenario)
from orchestrator.scenario.nodes import NodeReader, YamlLoader, did_you_mean, flatten_merges
from orchestrator.scenario.overrides import apply_override

log = logging.getLogger("orchestrator.scenario")

INSTANCE_RE = re.compile(r"^[A-Za-z_][A-Za-z0-9_-]*$")


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

    @property
    def complete(self) -> bool:
        return None not in self.kw.values() and self.coupling is not None

    def scenario(self, params: dict | None = None) -> Scenario:
        """The :class:`Scenario` of these sections; ``params``: checked parameters per instance
        (None: the values as written, for building the FMUs before they are read)."""
        fmus = self.fmus
        if params is None:
            params = {f["name"]: {k: v for k, (v, _) in f["parameters"].items()} for f in fmus}
        return Scenario(
            fmus=tuple(FmuSpec(name=f["name"], path=f["path"], parameters=params[f["name"]],
                               substeps=f["substeps"], line=f["line"]) for f in fmus),
            connections=tuple(ConnectionSpec(src=c["from"], dst=c["to"], gain=c["gain"], offset=c["offset"],
                                             line=c["line"]) for c in self.connections),
            coupling=CouplingSpec(**self.coupling),
            output=OutputSpec(interval=self.interval, signals=self.signals and tuple(s for s, _ in self.signals)),
            **self.kw)


class SectionReader(NodeReader):
    """One pass over one scenario file's sections; problems go to ``self.problems``."""

    def __init__(self, path: Path, overrides):
        super().__init__(Path(path), str(path))
        self.overrides = list(overrides)
        self.instances: list[str] = []         # every instance name written under 'fmus'
        self.fmu_specs: list[dict] = []        # parsed 'fmus' entries

    # -- the pass ----------------------------------------------------------
    def read_sections(self) -> Draft | None:
        """Read the file, apply the overrides and parse every section (no FMU is opened)."""
        try:
            text = self.path.read_text(encoding="utf-8")
        except OSError as exc:
            raise ScenarioError(f"{self.display}: cannot read the scenario file ({exc.strerror or exc}); "
                                "check the path") from None
        except UnicodeDecodeError as exc:
            raise ScenarioError(f"{self.display}: the scenario file is not UTF-8 text ({exc.reason} at "
                                f"byte {exc.start}); save it as UTF-8") from None
        try:
            root = yaml.compose(text, Loader=YamlLoader)
        except yaml.MarkedYAMLError as exc:
            mark = exc.problem_mark or exc.context_mark
            where = f"{self.display}:{mark.line + 1}:{mark.column + 1}" if mark else self.display
            context = f" {exc.context}" if exc.context else ""
            raise ScenarioError(f"{where}: malformed YAML: {exc.problem}{context}; fix the syntax there "
                                "(indentation, a missing ':' or a closing bracket)") from None
        except yaml.YAMLError as exc:
            raise ScenarioError(f"{self.display}: malformed YAML ({exc}); fix the syntax") from None
        if root is None:
            raise ScenarioError(f"{self.display}:1: expected a scenario (a mapping with at least "
                                "'name', 'stop_time' and 'fmus'), got an empty file; see docs/scenario-format.md")
        try:
            flatten_merges(self.ctor, root, set())
        except yaml.MarkedYAMLError as exc:
            mark = exc.problem_mark or exc.context_mark
            raise ScenarioError(f"{self.display}:{mark.line + 1 if mark else 1}: {exc.problem}; '<<' merges "
                                "mappings only (write '<<: *anchor' or '<<: [*a, *b]')") from None
        for text in self.overrides:
            apply_override(self, root, text)
        top = self.mapping(root, "top level", TOP_KEYS, ("name", "stop_time", "fmus"),
                           fix="a scenario is a mapping with at least 'name', 'stop_time' and 'fmus'")
        if top is None:
            return None
        get = lambda key: top[key][1] if key in top else None      # noqa: E731

        kw: dict[str, Any] = {"source": self.path.resolve()}
        if "name" in top:
            name = self.string(get("name"), "name", "give the scenario a name such as 'two-mass-oscillator'")
            if name is not None and (re.search(r"[/\\\x00-\x1f]", name) or name.startswith(".")):
                self.err(get("name"), f"'name' is used as a folder name (runs/<name>) and must not contain "
                                      f"'/', '\\' or control characters nor start with '.' (got {name!r}); rename it")
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
        stop = None
        if "stop_time" in top:
            stop = self.number(get("stop_time"), "stop_time", fix="write the end time in seconds, e.g. 0.5")
            if stop is not None and start is not None and stop <= start:
                self.err(get("stop_time"), f"'stop_time' must be greater than start_time ({start!r}) (got "
                                           f"{stop!r}); set a later stop time")
                stop = None
        kw["stop_time"] = stop
        fmus = self.load_fmus(get("fmus")) if "fmus" in top else []
        self.fmu_specs = fmus
        names = [f["name"] for f in fmus]
        coupling = self.load_coupling(get("coupling"), names, start, stop)
        interval, signals = self.load_output(get("output"), stop, start)
        connections = self.load_connections(get("connections"))
        for key in ("analysis", "compare"):
            if key in top:
                if not isinstance(get(key), yaml.MappingNode):
                    self.err(get(key), f"'{key}' must be a mapping (got {self.got(get(key))}); see "
                                       f"docs/{'analysis' if key == 'analysis' else 'compare'}.md")
                else:
                    kw[key] = self.value(get(key))

        return Draft(kw=kw, fmus=fmus, connections=connections, coupling=coupling, interval=interval,
                     signals=signals, analysis_node=get("analysis") if "analysis" in top else None,
                     coupling_node=get("coupling"))

    # -- sections ----------------------------------------------------------
    def load_fmus(self, node) -> list[dict]:
        section = self.mapping(node, "fmus", fix="write 'fmus:' followed by 'instance: {path: X.fmu}' lines")
        if section is None:
            return []
        self.instances = list(section)
        if not section:
            self.err(node, "'fmus' must list at least one FMU instance (got none); add 'name: {path: X.fmu}'")
        out = []
        for name, (knode, vnode) in section.items():
            if not INSTANCE_RE.match(name):
                self.err(knode, f"instance name must start with a letter or '_' and contain only letters, digits, "
                                f"'_' and '-' (got {name!r}); rename it (signals are written 'instance.variable')")
                continue
            entry = self.mapping(vnode, f"fmus.{name}", FMU_KEYS, ("path",),
                                 fix=f"write '{name}: {{path: X.fmu}}'")
            if entry is None:
                continue
            spec = {"name": name, "line": knode.start_mark.line + 1 if knode.start_mark else None,
                    "node": knode, "path": None, "parameters": {}, "substeps": None}
            if "path" in entry:
                p = self.string(entry["path"][1], f"fmus.{name}.path", "give the FMU file, relative to this file")
                if p is not None:
                    spec["path"] = (self.path.parent / Path(p).expanduser()).resolve()
                    spec["path_node"] = entry["path"][1]
            if "substeps" in entry:
                spec["substeps"] = self.integer(entry["substeps"][1], f"fmus.{name}.substeps", 1, None,
                                                "use a whole number of sub-steps >= 1")
            if "parameters" in entry:
                pmap = self.mapping(entry["parameters"][1], f"fmus.{name}.parameters",
                                    fix="write 'parameters: {name: value, ...}'")
                for pname, (_, pv) in (pmap or {}).items():
                    if not isinstance(pv, yaml.ScalarNode) or self.value(pv) is None:
                        self.err(pv, f"parameter '{name}.{pname}' must be a single value (number, true/false or "
                                     f"text) (got {self.got(pv)}); write one value")
                    else:
                        spec["parameters"][pname] = (self.value(pv), pv)
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
            seq = self.strings(section["sequence"][1], "coupling.sequence", "list every instance once")
            if seq is None:
                ok = False
            else:
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
                    self.err(section["sequence"][1], "'coupling.sequence' must list every instance exactly once "
                                                     f"({'; '.join(problems)}); e.g. [{', '.join(names)}]")
                    ok = False
                else:
                    c["sequence"] = tuple(order)
        if "macro_step" in section:
            h = self.number(section["macro_step"][1], "coupling.macro_step", positive=True,
                            fix="give the communication step in seconds, e.g. 1.0e-4")
            if h is not None and start is not None and stop is not None and h > stop - start:
                self.err(section["macro_step"][1], f"'coupling.macro_step' must not exceed stop_time - start_time "
                                                   f"({stop - start!r}) (got {h!r}); use a smaller step")
                h = None
            ok &= h is not None
            c["macro_step"] = h
        for key in ("extrapolation_order", "interpolation_order"):
            if key in section:
                v = self.integer(section[key][1], f"coupling.{key}", 0, MAX_ORDER,
                                 "use 0 (hold), 1 (linear), 2 (quadratic) or 3 (cubic)")
                ok &= v is not None
                c[key] = v
        if "substeps" in section:
            v = self.integer(section["substeps"][1], "coupling.substeps", 1, None,
                             "use a whole number of sub-steps >= 1")
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

    def load_output(self, node, stop, start):
        if node is None:
            return None, None
        section = self.mapping(node, "output", OUTPUT_KEYS)
        if section is None:
            return None, None
        interval = signals = None
        if "interval" in section:
            interval = self.number(section["interval"][1], "output.interval", positive=True,
                                   fix="give the output interval in seconds, e.g. 1.0e-3")
            if interval is not None and stop is not None and start is not None and interval > stop - start:
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
