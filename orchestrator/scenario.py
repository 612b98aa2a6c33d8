"""Scenario format (version 1): frozen dataclasses and the YAML loader.

The dataclasses below are the contract between the loader, the master, the
CLI, ``compare`` and ``plot``: extend them, never rename fields.

Loading (``load_scenario``) validates everything and raises one
:class:`orchestrator.errors.ScenarioError` listing every problem with
``file:line``.
"""

from __future__ import annotations

import copy
import difflib
import functools
import logging
import math
import re
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, Mapping, Sequence

import yaml

from orchestrator.coupling.iterative import IterationSpec
from orchestrator.coupling.sections import StepControlSpec, check_capabilities, load_iteration, load_step_control
from orchestrator.errors import CosimError, ScenarioError

log = logging.getLogger(__name__)

SCENARIO_VERSION = 1
SCHEMES = ("gauss-seidel", "jacobi", "iterative", "monolithic")


@dataclass(frozen=True, kw_only=True)
class FmuSpec:
    """One FMU instance of the scenario (``fmus:`` entry)."""

    name: str                                # instance name, e.g. "bearing1"
    path: Path                               # absolute, resolved relative to the YAML file
    parameters: Mapping[str, Any] = field(default_factory=dict)   # name -> value (float/int/bool/str)
    substeps: int | None = None              # per-FMU override of coupling.substeps
    line: int | None = None                  # line of the entry in the YAML file


@dataclass(frozen=True, kw_only=True)
class ConnectionSpec:
    """``connections:`` entry: value(to) = gain * value(from) + offset."""

    src: str                                 # "instance.variable"
    dst: str                                 # "instance.variable"
    gain: float = 1.0
    offset: float = 0.0
    line: int | None = None

    @property
    def src_instance(self) -> str:
        return self.src.split(".", 1)[0]

    @property
    def src_variable(self) -> str:
        return self.src.split(".", 1)[1]

    @property
    def dst_instance(self) -> str:
        return self.dst.split(".", 1)[0]

    @property
    def dst_variable(self) -> str:
        return self.dst.split(".", 1)[1]


@dataclass(frozen=True, kw_only=True)
class CouplingSpec:
    """``coupling:`` section."""

    scheme: str = "gauss-seidel"             # one of SCHEMES
    sequence: tuple[str, ...] = ()           # Gauss-Seidel order; () -> order of `fmus`
    macro_step: float = 1e-4                 # [s]
    extrapolation_order: int = 0             # 0..3
    interpolation_order: int = 0             # 0..3
    substeps: int = 1                        # >= 1
    discard_retries: int = 0                 # 0..30: halvings of a macro step an FMU discards (0: stop)
    iteration: IterationSpec = field(default_factory=IterationSpec)         # scheme: iterative
    step_control: StepControlSpec = field(default_factory=StepControlSpec)  # constant or error-controlled
    options: Mapping[str, Any] = field(default_factory=dict)  # scheme-specific extras (e.g. monolithic rtol)


@dataclass(frozen=True, kw_only=True)
class OutputSpec:
    """``output:`` section."""

    interval: float | None = None            # [s]; None -> macro_step
    signals: tuple[str, ...] | None = None   # None -> every connected or FMU output


@dataclass(frozen=True, kw_only=True)
class Scenario:
    """A validated scenario."""

    name: str
    stop_time: float
    fmus: tuple[FmuSpec, ...]
    connections: tuple[ConnectionSpec, ...] = ()
    coupling: CouplingSpec = field(default_factory=CouplingSpec)
    output: OutputSpec = field(default_factory=OutputSpec)
    start_time: float = 0.0
    version: int = SCENARIO_VERSION
    description: str = ""
    source: Path | None = None               # the YAML file, if loaded from one
    analysis: Mapping[str, Any] | None = None  # optional run-up analysis section (see docs/scenario-format.md)
    compare: Mapping[str, Any] | None = None   # optional compare section (see docs/compare.md)

    def fmu(self, name: str) -> FmuSpec:
        for f in self.fmus:
            if f.name == name:
                return f
        raise KeyError(name)


# ---------------------------------------------------------------------------
# Loader (format version 1). Everything below builds the dataclasses above from
# a YAML file, collecting every problem before raising one ScenarioError.
# ---------------------------------------------------------------------------

TOP_KEYS = ("name", "version", "description", "start_time", "stop_time", "fmus",
            "connections", "coupling", "output", "analysis", "compare")
FMU_KEYS = ("path", "parameters", "substeps")
CONNECTION_KEYS = ("from", "to", "gain", "offset")
COUPLING_KEYS = ("scheme", "sequence", "macro_step", "extrapolation_order",
                 "interpolation_order", "substeps", "discard_retries", "options", "iteration", "step_control")
OUTPUT_KEYS = ("interval", "signals")
MAX_ORDER = 3
MAX_DISCARD_RETRIES = 30          # smallest retried step H / 2^30 (orchestrator.master has the same limit)
# override navigation: (schema, key) -> schema of the child; (schema) -> default
_CHILD_SCHEMA = {
    ("top", "fmus"): "instances", ("top", "connections"): "connections",
    ("top", "coupling"): "coupling", ("top", "output"): "output", ("top", "analysis"): "free",
    ("top", "compare"): "free", ("fmu", "parameters"): "params", ("coupling", "options"): "free",
    ("coupling", "iteration"): "free", ("coupling", "step_control"): "free",
    "instances": "fmu", "connections": "connection", "free": "free",
}
_SECTION_KEYS = {"top": TOP_KEYS, "fmu": FMU_KEYS, "connection": CONNECTION_KEYS,
                 "coupling": COUPLING_KEYS, "output": OUTPUT_KEYS}

_MAP, _SEQ, _STR = "tag:yaml.org,2002:map", "tag:yaml.org,2002:seq", "tag:yaml.org,2002:str"
_INSTANCE_RE = re.compile(r"^[A-Za-z_][A-Za-z0-9_-]*$")
# YAML 1.1 (PyYAML) reads 1e-4 as a string; scenarios use such numbers all the time.
_FLOAT_RE = re.compile(r"""^(?:[-+]?(?:[0-9][0-9_]*)\.[0-9_]*(?:[eE][-+]?[0-9]+)?
    |[-+]?[0-9][0-9_]*[eE][-+]?[0-9]+
    |[-+]?\.[0-9_]+(?:[eE][-+]?[0-9]+)?
    |[-+]?\.(?:inf|Inf|INF)|\.(?:nan|NaN|NAN))$""", re.X)


class _YamlLoader(yaml.SafeLoader):
    """Safe YAML loader that also reads ``1e-4`` as a float (YAML 1.2 style)."""


_YamlLoader.add_implicit_resolver("tag:yaml.org,2002:float", _FLOAT_RE, list("-+0123456789."))


def read_model_description(path: str | Path):
    """The FMU's checked model description (:class:`orchestrator.fmu_archive.ModelDescription`).

    The archive is treated as untrusted (see :mod:`orchestrator.fmu_archive`);
    raises :class:`orchestrator.errors.FmuError`. Cached per file path, size and
    modification time.
    """
    path = Path(path)
    try:
        st = path.stat()
    except OSError:
        st = None
    if st is None:
        from orchestrator.fmu_archive import read_model_description as read
        return read(path)                            # raises FmuError naming the missing file
    return _read_md_cached(str(path), st.st_mtime_ns, st.st_size)


@functools.lru_cache(maxsize=64)
def _read_md_cached(path: str, mtime_ns: int, size: int):
    from orchestrator.fmu_archive import read_model_description as read
    return read(path)


def _ranked(name: str, candidates, limit: int = 15) -> str:
    """``candidates`` closest to ``name`` first, as one readable string."""
    ranked = sorted(candidates, key=lambda c: (
        -difflib.SequenceMatcher(None, name.lower(), c.lower()).ratio(), c))
    text = ", ".join(ranked[:limit])
    if len(ranked) > limit:
        text += f", ... ({len(ranked) - limit} more)"
    return text or "(none)"


def _did_you_mean(name: str, candidates) -> str:
    close = difflib.get_close_matches(name, list(candidates), n=1, cutoff=0.5)
    return f"did you mean '{close[0]}'? " if close else ""


def _a(word: str) -> str:
    return f"an {word}" if word[:1].lower() in "aeiou" else f"a {word}"


class _Loader:
    """One loading pass over one file; collects problems in ``self.problems``."""

    def __init__(self, path: Path, overrides, build_fmus: bool):
        self.path = Path(path)
        self.display = str(path)
        self.build_fmus = build_fmus
        self.overrides = list(overrides)
        self.problems: list[str] = []
        self.origins: dict[int, str] = {}     # id(node) -> "--set k=v" for override nodes
        self.ctor = _YamlLoader("")
        self.mds: dict[str, dict] = {}         # instance -> {variable name: fmpy variable} (readable FMUs)
        self.fmu_caps: dict = {}               # instance -> model description (capability flags)
        self.instances: list[str] = []         # every instance name written under 'fmus'
        self.fmu_specs: list[dict] = []        # parsed 'fmus' entries

    # -- helpers -----------------------------------------------------------
    def loc(self, node) -> str:
        if node is None:
            return f"{self.display}:1"
        if id(node) in self.origins:
            return self.origins[id(node)]
        mark = getattr(node, "start_mark", None)
        return f"{self.display}:{mark.line + 1}" if mark is not None else self.display

    def err(self, node, text: str) -> None:
        self.problems.append(f"{self.loc(node)}: {text}")

    def warn(self, node, text: str) -> None:
        log.warning("%s: %s", self.loc(node), text)

    def value(self, node):
        try:
            return self.ctor.construct_object(node, deep=True)
        except yaml.YAMLError as exc:                 # e.g. an unknown !!tag or an unhashable key
            problem = getattr(exc, "problem", None) or str(exc)
            raise ScenarioError(self.problems + [f"{self.loc(node)}: cannot read this value ({problem}); write a "
                                                 "plain number, text, list or mapping"]) from None

    def got(self, node) -> str:
        if isinstance(node, yaml.MappingNode):
            return "a mapping"
        if isinstance(node, yaml.SequenceNode):
            return "a list"
        v = self.value(node)
        kind = {bool: "a boolean", int: "an integer", float: "a number", str: "a string",
                type(None): "nothing"}.get(type(v), type(v).__name__)
        return f"{v!r}, {kind}" if v is not None else "nothing"

    def mapping(self, node, where: str, keys=None, required=(), fix="") -> dict | None:
        """{key: (key_node, value_node)} of a mapping node; unknown/missing keys reported."""
        if not isinstance(node, yaml.MappingNode):
            fix = fix or "write it as key: value lines"
            self.err(node, f"'{where}' must be a mapping (got {self.got(node)}); {fix}")
            return None
        out: dict = {}
        for knode, vnode in node.value:
            if not isinstance(knode, yaml.ScalarNode):
                self.err(knode, f"keys of '{where}' must be names (got {self.got(knode)}); write a plain name")
                continue
            key = str(self.value(knode))
            if key in out:
                self.err(knode, f"key '{key}' appears twice in '{where}' (first on line "
                                f"{out[key][0].start_mark.line + 1}); keep one of them")
            if keys is not None and key not in keys:
                self.err(knode, f"unknown key '{key}' in '{where}'; {_did_you_mean(key, keys)}"
                                f"valid keys: {', '.join(keys)}")
                continue
            out[key] = (knode, vnode)
        for key in required:
            if key not in out:
                owner = "the scenario" if where == "top level" else f"'{where}'"
                self.err(node, f"{owner} is missing the required key '{key}'; add '{key}: ...'")
        return out

    def number(self, node, what: str, *, positive=False, fix="") -> float | None:
        v = self.value(node) if isinstance(node, yaml.ScalarNode) else None
        if isinstance(v, str) and _FLOAT_RE.match(v.strip()):
            v = float(v.replace("_", ""))
        if isinstance(v, bool) or not isinstance(v, (int, float)) or not math.isfinite(v):
            fix = fix or "write a number such as 1.0e-4"
            self.err(node, f"'{what}' must be a finite number (got {self.got(node)}); {fix}")
            return None
        if positive and v <= 0:
            self.err(node, f"'{what}' must be positive (got {v!r}); {fix or 'use a value > 0'}")
            return None
        return float(v)

    def integer(self, node, what: str, lo: int, hi: int | None, fix: str) -> int | None:
        v = self.value(node) if isinstance(node, yaml.ScalarNode) else None
        if isinstance(v, float) and v.is_integer():
            v = int(v)
        if isinstance(v, bool) or not isinstance(v, int):
            self.err(node, f"'{what}' must be an integer (got {self.got(node)}); {fix}")
            return None
        if v < lo or (hi is not None and v > hi):
            rng = f"between {lo} and {hi}" if hi is not None else f">= {lo}"
            self.err(node, f"'{what}' must be {rng} (got {v}); {fix}")
            return None
        return v

    def string(self, node, what: str, fix: str) -> str | None:
        v = self.value(node) if isinstance(node, yaml.ScalarNode) else None
        if not isinstance(v, str) or not v.strip():
            self.err(node, f"'{what}' must be a non-empty text (got {self.got(node)}); {fix}")
            return None
        return v

    def strings(self, node, what: str, fix: str) -> list[tuple[str, Any]] | None:
        if not isinstance(node, yaml.SequenceNode):
            self.err(node, f"'{what}' must be a list (got {self.got(node)}); {fix}")
            return None
        out = []
        for item in node.value:
            s = self.string(item, f"{what} entry", fix)
            if s is not None:
                out.append((s, item))
        return out

    # -- overrides ---------------------------------------------------------
    def apply_override(self, root, text: str) -> None:
        """Apply one ``--set key.path=value`` to the node tree (before validation)."""
        origin = f"--set {text}"
        key, sep, raw = text.partition("=")
        key = key.strip()
        if not sep or not key:
            self.problems.append(f"{origin}: expected KEY.PATH=VALUE (got {text!r}); "
                                 "e.g. --set coupling.macro_step=5e-5")
            return
        try:
            vnode = yaml.compose(raw.strip(), Loader=_YamlLoader)
        except yaml.YAMLError as exc:
            self.problems.append(f"{origin}: the value is not valid YAML ({exc}); quote or fix it")
            return
        if vnode is None:
            vnode = yaml.ScalarNode("tag:yaml.org,2002:null", "")
        self._mark(vnode, origin)
        if not isinstance(root, yaml.MappingNode):
            return                                       # the file itself is broken (reported)
        node, schema, done, parts = root, "top", [], key.split(".")
        while parts:
            part = ".".join(parts) if schema == "params" else parts[0]   # names may hold dots
            parts = [] if schema == "params" else parts[1:]
            here = ".".join(done) or "top level"
            nxt = _CHILD_SCHEMA.get((schema, part), _CHILD_SCHEMA.get(schema, "leaf"))
            if parts and nxt == "leaf":
                self.problems.append(f"{origin}: '{'.'.join(done + [part])}' is a single value, not a section; "
                                     f"use --set {'.'.join(done + [part])}=VALUE")
                return
            if isinstance(node, yaml.SequenceNode):
                if not part.isdigit() or int(part) >= len(node.value):
                    self.problems.append(f"{origin}: '{here}' has entries 0..{len(node.value) - 1} (got "
                                         f"{part!r}); use an index, e.g. --set {here}.0.gain=2")
                    return
                if not parts:
                    node.value[int(part)] = vnode
                    return
                child = node.value[int(part)] = _unshared(node.value[int(part)])
            elif isinstance(node, yaml.MappingNode):
                entries = {str(self.value(k)): i for i, (k, _) in enumerate(node.value)
                           if isinstance(k, yaml.ScalarNode)}
                allowed = tuple(entries) if schema == "instances" else _SECTION_KEYS.get(schema)
                if allowed is not None and part not in allowed:
                    what = "instance" if schema == "instances" else "key"
                    self.problems.append(f"{origin}: unknown {what} '{part}' in '{here}'; "
                                         f"{_did_you_mean(part, allowed)}valid: {', '.join(allowed) or '(none)'}")
                    return
                if not parts:
                    if part in entries:
                        i = entries[part]
                        node.value[i] = (node.value[i][0], vnode)
                    else:
                        knode = yaml.ScalarNode(_STR, part)
                        self._mark(knode, origin)
                        node.value.append((knode, vnode))
                    return
                if part in entries:                      # copy: an alias (*anchor) must not change too
                    knode, child = node.value[entries[part]]
                    child = _unshared(child)
                    node.value[entries[part]] = (knode, child)
                else:                                    # a section not written in the file
                    knode, child = yaml.ScalarNode(_STR, part), yaml.MappingNode(_MAP, [])
                    self._mark(knode, origin)
                    self._mark(child, origin)
                    node.value.append((knode, child))
            else:
                self.problems.append(f"{origin}: '{here}' is a single value, not a section; "
                                     f"use --set {here}=VALUE")
                return
            node, schema, done = child, nxt, done + [part]

    def _mark(self, node, origin: str) -> None:
        self.origins[id(node)] = origin
        if isinstance(node, yaml.MappingNode):
            for k, v in node.value:
                self._mark(k, origin)
                self._mark(v, origin)
        elif isinstance(node, yaml.SequenceNode):
            for v in node.value:
                self._mark(v, origin)

    # -- the pass ----------------------------------------------------------
    def load(self) -> Scenario | None:
        try:
            text = self.path.read_text(encoding="utf-8")
        except OSError as exc:
            raise ScenarioError(f"{self.display}: cannot read the scenario file ({exc.strerror or exc}); "
                                "check the path") from None
        except UnicodeDecodeError as exc:
            raise ScenarioError(f"{self.display}: the scenario file is not UTF-8 text ({exc.reason} at "
                                f"byte {exc.start}); save it as UTF-8") from None
        try:
            root = yaml.compose(text, Loader=_YamlLoader)
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
            _flatten_merges(self.ctor, root, set())
        except yaml.MarkedYAMLError as exc:
            mark = exc.problem_mark or exc.context_mark
            raise ScenarioError(f"{self.display}:{mark.line + 1 if mark else 1}: {exc.problem}; '<<' merges "
                                "mappings only (write '<<: *anchor' or '<<: [*a, *b]')") from None
        for text in self.overrides:
            self.apply_override(root, text)
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

        # FMU files: build ours when missing/stale (only with a consistent scenario), then read them
        if self.build_fmus and not self.problems and None not in kw.values() and None not in (coupling,):
            self.ensure_fmus(kw, fmus, connections, coupling, interval, signals)
        for f in fmus:
            self.read_fmu(f)
        params = {f["name"]: self.check_parameters(f) for f in fmus}
        self.check_connections(connections)
        if len(self.fmu_caps) == len(fmus):
            check_capabilities(self, get("coupling"), coupling, self.fmu_caps)
        self.check_signals(signals, "output.signals")
        if "analysis" in top and isinstance(kw.get("analysis"), dict):
            self.check_analysis(get("analysis"), signals)
        if self.problems:
            return None
        return Scenario(
            fmus=tuple(FmuSpec(name=f["name"], path=f["path"], parameters=params[f["name"]],
                               substeps=f["substeps"], line=f["line"]) for f in fmus),
            connections=tuple(ConnectionSpec(src=c["from"], dst=c["to"], gain=c["gain"], offset=c["offset"],
                                             line=c["line"]) for c in connections),
            coupling=CouplingSpec(**coupling),
            output=OutputSpec(interval=interval, signals=signals and tuple(s for s, _ in signals)),
            **kw)

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
            if not _INSTANCE_RE.match(name):
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
                                               f"{_did_you_mean(str(s), SCHEMES) or 'pick one of them'}".rstrip())
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
                        problems.append(f"'{s}' is not an instance ({_did_you_mean(s, names)}instances: "
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

    # -- FMU checks ----------------------------------------------------------
    def ensure_fmus(self, kw, fmus, connections, coupling, interval, signals) -> None:
        """Let ``orchestrator.build.ensure_fmus`` build our own FMUs when missing or stale."""
        try:
            from orchestrator import build
        except ModuleNotFoundError as exc:
            if exc.name != "orchestrator.build":
                raise
            return
        draft = Scenario(
            fmus=tuple(FmuSpec(name=f["name"], path=f["path"], substeps=f["substeps"], line=f["line"],
                               parameters={k: v for k, (v, _) in f["parameters"].items()}) for f in fmus),
            connections=tuple(ConnectionSpec(src=c["from"], dst=c["to"], gain=c["gain"], offset=c["offset"],
                                             line=c["line"]) for c in connections),
            coupling=CouplingSpec(**coupling),
            output=OutputSpec(interval=interval, signals=signals and tuple(s for s, _ in signals)), **kw)
        try:
            build.ensure_fmus(draft)
        except Exception as exc:                        # reported with the scenario's other problems
            self.problems.append(f"{self.display}: building the scenario's FMUs failed ({type(exc).__name__}: "
                                 f"{exc}); run `rotorcosim build-fmus --force` to see the details")

    def read_fmu(self, f: dict) -> None:
        name, path = f["name"], f["path"]
        if path is None:
            return
        node = f["path_node"]
        if not path.exists():
            self.err(node, f"FMU file of '{name}' not found: {path} (paths are relative to the scenario's "
                           f"folder {self.path.parent.resolve()}); fix 'fmus.{name}.path', or build our FMUs "
                           "with `rotorcosim build-fmus`")
            return
        try:
            md = read_model_description(path)
        except CosimError as exc:                      # unreadable, unsafe, not FMI 2.0 CS
            self.err(node, f"FMU of '{name}' cannot be used: {exc}")
            return
        except Exception as exc:                        # an unexpected failure is still a problem of the file
            self.err(node, f"FMU of '{name}' cannot be read: {path}: {type(exc).__name__}: {exc}; check that it "
                           "is an FMI 2.0 co-simulation FMU (`rotorcosim info FILE` shows what it contains)")
            return
        self.mds[name] = dict(md.variables)
        self.fmu_caps[name] = md
        if md.can_be_instantiated_only_once_per_process:
            users = [g["name"] for g in self.fmu_specs if g["path"] == path]
            if len(users) > 1 and users[0] != name:
                self.err(node, f"FMU {path.name} declares canBeInstantiatedOnlyOncePerProcess, but instances "
                               f"{', '.join(users)} all use it; use it for one instance only")

    def check_parameters(self, f: dict) -> dict:
        name, out = f["name"], {}
        variables = self.mds.get(name)
        for pname, (value, node) in f["parameters"].items():
            if variables is None:
                out[pname] = value
                continue
            settable = [v.name for v in variables.values()
                        if v.causality in ("parameter", "input") and v.variability != "constant"]
            var = variables.get(pname)
            if var is None:
                self.err(node, f"'{name}' has no parameter '{pname}'; parameters of '{name}' (closest first): "
                               f"{_ranked(pname, settable)}")
                continue
            if pname not in settable:
                self.err(node, f"'{name}.{pname}' is {_a(var.variability)} {var.causality}, not a parameter; only "
                               f"parameters and inputs can be given values: {_ranked(pname, settable)}")
                continue
            conv = _convert(value, var.type)
            if conv is None:
                example = {"Real": "1.5", "Integer": "3", "Enumeration": "1", "Boolean": "true",
                           "String": '"text"'}.get(var.type, "a value")
                self.err(node, f"parameter '{name}.{pname}' is {var.type} (got {self.got(node)}); write a "
                               f"{var.type} value such as {example}")
                continue
            out[pname] = conv
        return out

    def check_connections(self, connections: list[dict]) -> None:
        fed: dict[str, int | None] = {}
        for c in connections:
            ends = {}
            for side, want in (("from", "output"), ("to", "input")):
                if c.get(side) is None:
                    continue
                var = self.variable(c[side], c[side + "_node"], f"'{side}' of a connection", want)
                if var is not None and var.causality != want:
                    names = [v.name for v in self.mds[c[side].split(".", 1)[0]].values() if v.causality == want]
                    self.err(c[side + "_node"], f"'{c[side]}' is {_a(var.causality)}, but the '{side}' side of a "
                                                f"connection must be an {want}; {want}s of "
                                                f"'{c[side].split('.', 1)[0]}': {_ranked(var.name, names)}")
                    var = None
                ends[side] = var
            if c.get("to") is not None:
                if c["to"] in fed:
                    self.err(c["to_node"], f"input '{c['to']}' is connected twice (also on line {fed[c['to']]}); "
                                           "an input takes exactly one source: remove one of the connections")
                fed.setdefault(c["to"], c["line"])
            src, dst = ends.get("from"), ends.get("to")
            if src is None or dst is None:
                continue
            if src.type != dst.type:
                self.err(c["node"], f"type mismatch: '{c['from']}' is {src.type} but '{c['to']}' is {dst.type}; "
                                    "connect variables of the same type (Real to Real)")
            elif src.type != "Real":
                self.err(c["node"], f"'{c['from']}' -> '{c['to']}' couples {src.type} variables, but the master "
                                    "couples (and extrapolates) Real signals only; connect Real variables")

    def variable(self, signal: str, node, what: str, want: str | None = None):
        """The model variable named by ``instance.variable`` or None (problem reported)."""
        inst, _, var = signal.partition(".")
        names = [f for f in self.instances]
        if inst not in names:
            self.err(node, f"{what} names the instance '{inst}', which is not in 'fmus' (got {signal!r}); "
                           f"{_did_you_mean(inst, names)}instances: {', '.join(names)}")
            return None
        variables = self.mds.get(inst)
        if variables is None:
            return None                                  # FMU unreadable: reported already
        if var not in variables:
            pool = [v.name for v in variables.values() if want is None or v.causality == want] \
                or list(variables)
            kind = f"{want}s" if want else "variables"
            self.err(node, f"{what}: '{inst}' has no variable '{var}'; {kind} of '{inst}' (closest first): "
                           f"{_ranked(var, pool)}")
            return None
        return variables[var]

    def check_signals(self, signals, what: str) -> None:
        for s, node in signals or ():
            if "." not in s:
                self.err(node, f"'{what}' entries must be 'instance.variable' (got {s!r}); add the instance name")
                continue
            var = self.variable(s, node, f"'{what}' entry {s!r}")
            if var is not None and var.type != "Real":
                self.err(node, f"'{what}' entry {s!r} is {_a(var.type)} variable; results.csv records Real "
                               "variables only: remove it")

    def check_analysis(self, node, signals) -> None:
        recorded = None if signals is None else {s for s, _ in signals}
        section = self.mapping(node, "analysis") or {}
        found = []
        if "speed" in section:
            found.append(("analysis.speed", section["speed"][1]))
        if "journals" in section:
            journals = self.mapping(section["journals"][1], "analysis.journals") or {}
            for jname, (_, jnode) in journals.items():
                entry = self.mapping(jnode, f"analysis.journals.{jname}") or {}
                for key in ("x", "y", "eps"):
                    if key in entry:
                        found.append((f"analysis.journals.{jname}.{key}", entry[key][1]))
        for what, vnode in found:
            s = self.string(vnode, what, "name a signal as 'instance.variable'")
            if s is None:
                continue
            if "." not in s:
                self.err(vnode, f"'{what}' must be 'instance.variable' (got {s!r}); add the instance name")
            elif self.variable(s, vnode, f"'{what}'") is not None and recorded is not None and s not in recorded:
                self.err(vnode, f"'{what}' is {s!r}, which is not recorded (not in output.signals); add it to "
                                "output.signals")


def _flatten_merges(ctor, node, seen: set) -> None:
    """Resolve YAML merge keys (``<<: *defaults``) in place; explicit keys win."""
    if id(node) in seen:
        return
    seen.add(id(node))
    if isinstance(node, yaml.MappingNode):
        if any(k.tag == "tag:yaml.org,2002:merge" for k, _ in node.value):
            ctor.flatten_mapping(node)               # merged pairs first, then the node's own
            last = {}
            for i, (k, _) in enumerate(node.value):
                last[(k.tag, k.value) if isinstance(k, yaml.ScalarNode) else id(k)] = i
            node.value = [kv for i, kv in enumerate(node.value) if last.get(
                (kv[0].tag, kv[0].value) if isinstance(kv[0], yaml.ScalarNode) else id(kv[0])) == i]
        for _, v in node.value:
            _flatten_merges(ctor, v, seen)
    elif isinstance(node, yaml.SequenceNode):
        for v in node.value:
            _flatten_merges(ctor, v, seen)


def _unshared(node):
    """A shallow copy of a collection node (YAML aliases share nodes), scalars as they are."""
    if isinstance(node, (yaml.MappingNode, yaml.SequenceNode)):
        node = copy.copy(node)
        node.value = list(node.value)
    return node


def _convert(value, fmi_type: str):
    """``value`` as the Python type of an FMI variable type, or None if it does not fit."""
    if fmi_type == "Real":
        if isinstance(value, str) and _FLOAT_RE.match(value.strip()):
            return float(value.replace("_", ""))
        return float(value) if isinstance(value, (int, float)) and not isinstance(value, bool) else None
    if fmi_type in ("Integer", "Enumeration"):
        if isinstance(value, float) and value.is_integer():
            value = int(value)
        return value if isinstance(value, int) and not isinstance(value, bool) else None
    if fmi_type == "Boolean":
        return value if isinstance(value, bool) else None
    if fmi_type == "String":
        return value if isinstance(value, str) else None
    return value


def load_scenario(path: str | Path, overrides: Sequence[str] = (), *, build_fmus: bool = True) -> Scenario:
    """Load and validate a scenario file (format version 1).

    Parameters
    ----------
    path : the YAML file; FMU paths in it are relative to its folder.
    overrides : ``"key.path=value"`` strings (the CLI's ``--set``), applied before
        validation; the value is read as YAML (``5e-5``, ``true``, ``[a, b]``).
        Examples: ``coupling.macro_step=5e-5``, ``fmus.bearing1.parameters.n_phi=60``,
        ``connections.0.gain=2``. Unknown paths are errors.
    build_fmus : when the scenario is otherwise valid, let ``orchestrator.build.ensure_fmus``
        build or rebuild our own FMUs (in the repository's ``fmus/``) that are
        missing or stale, before their model descriptions are read.

    Raises
    ------
    ScenarioError
        listing every problem found, each as ``file:line: what is wrong (got X); fix``.
    """
    loader = _Loader(Path(path), overrides, build_fmus)
    scenario = loader.load()
    if loader.problems or scenario is None:
        raise ScenarioError(sorted(loader.problems, key=_line_order) or [f"{path}: invalid scenario"])
    return scenario


def _line_order(problem: str) -> tuple[int, int]:
    """Sort key: ``--set`` problems first, then by line number in the file."""
    if problem.startswith("--set"):
        return (0, 0)
    m = re.match(r"^.*?:(\d+)(?::\d+)?: ", problem)
    return (1, int(m.group(1)) if m else 0)


def validate_scenario(path: str | Path, overrides: Sequence[str] = (), *,
                      build_fmus: bool = True) -> list[str]:
    """Every problem of a scenario file as readable lines (empty: the scenario is valid).

    Like :func:`load_scenario`, first builds our own FMUs that are missing or
    stale (``build_fmus=False``: only check, and report a missing FMU with the
    command that builds it).
    """
    try:
        load_scenario(path, overrides, build_fmus=build_fmus)
    except ScenarioError as exc:
        return list(exc.problems)
    return []
