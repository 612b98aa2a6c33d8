"""The sweep file (format 1): dataclasses, reading and checking.

``load_sweep(path)`` reads a sweep YAML file (docs/sweeps.md), checks every key the way
the scenario loader checks scenario keys (the same YAML flavour, node helpers and
``file:line: what is wrong (got X); fix`` messages, every problem at once, did-you-mean
for unknown keys) and returns a frozen :class:`SweepSpec`. The runs themselves are made
by :mod:`orchestrator.sweep.plan`.
"""

from __future__ import annotations

import math
import re
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import yaml

from orchestrator.errors import ScenarioError
# The scenario loader's YAML reading (``1e-4`` is a float, marks on every node) and its node
# helpers (mapping/number/integer/string with file:line messages): one reader for both formats.
from orchestrator.scenario.nodes import NodeReader, YamlLoader, did_you_mean
from orchestrator.untrusted import InputError, read_yaml_tree

__all__ = ["SweepError", "Parameter", "SweepSpec", "load_sweep", "SWEEP_VERSION", "MODES", "RESERVED_COLUMNS"]

SWEEP_VERSION = 1
TOP_KEYS = ("sweep", "scenario", "set", "parameters", "mode", "samples", "seed", "collect")
PARAMETER_KEYS = ("name", "set", "values", "linspace", "logspace")
MODES = ("grid", "zip", "random")
RESERVED_COLUMNS = ("run_id", "status", "message", "wall_time_s", "run_dir")
_NAME_RE = re.compile(r"^[A-Za-z_][A-Za-z0-9_]*$")
_PATH_RE = re.compile(r"^[^.\s=]+(\.[^.\s=]+)*$")


class SweepError(ScenarioError):
    """A sweep file (or a scenario one of its runs makes) is invalid; ``problems`` lists them all."""

    def __init__(self, problems: list[str] | str):
        super().__init__(problems)
        n = len(self.problems)
        head = "invalid sweep" if n == 1 else f"invalid sweep ({n} problems)"
        self.args = (head + ":\n  " + "\n  ".join(self.problems),)


@dataclass(frozen=True, kw_only=True)
class Parameter:
    """One swept parameter: its column ``name``, the scenario paths it sets, its values."""

    name: str
    paths: tuple[str, ...]
    values: tuple[Any, ...]
    line: int | None = None                      # line of the entry in the sweep file


@dataclass(frozen=True, kw_only=True)
class SweepSpec:
    """A checked sweep file (see docs/sweeps.md for every key)."""

    source: Path
    scenario: Path                               # resolved scenario file
    common: tuple[tuple[str, Any], ...] = ()     # the 'set' overrides of every run, in file order
    parameters: tuple[Parameter, ...] = ()
    mode: str = "grid"
    samples: int | None = None
    seed: int = 0
    collect: tuple[tuple[str, str], ...] = ()    # column -> dotted path in summary.json
    lines: dict = field(default_factory=dict, compare=False)   # override path -> sweep file line


class _SweepReader(NodeReader):
    """The scenario loader's node helpers applied to a sweep file."""

    def __init__(self, path: Path):
        super().__init__(Path(path), str(path))

    def compose(self):
        """The sweep file's node tree, read with the bounded reader and YAML composer that
        every input file goes through (orchestrator/untrusted.py: size, regular file, UTF-8,
        nesting and alias bounds)."""
        try:
            root = read_yaml_tree(self.path, what="sweep file", loader_cls=YamlLoader)
        except InputError as exc:
            raise SweepError(str(exc)) from None
        if root is None:
            raise SweepError(f"{self.display}:1: expected a sweep (a mapping with 'sweep: 1', 'scenario' and "
                             "'parameters'), got an empty file; see docs/sweeps.md")
        return root

    def line(self, node) -> int | None:
        mark = getattr(node, "start_mark", None)
        return mark.line + 1 if mark is not None else None

    def scalar(self, node, what: str):
        """A plain value for an override: number, text or boolean (lists/mappings too for 'set')."""
        v = self.value(node)
        if isinstance(v, str) and re.fullmatch(r"[-+]?(\d+\.?\d*|\.\d+)[eE][-+]?\d+", v.strip()):
            v = float(v)
        if v is None or (isinstance(v, float) and not math.isfinite(v)):
            self.err(node, f"'{what}' must be a finite number, a text or a boolean (got {self.got(node)}); "
                           "write a value such as 2.8e-3")
            return None
        return v

    def load(self) -> SweepSpec | None:
        top = self.mapping(self.compose(), "sweep file", TOP_KEYS, ("sweep", "scenario", "parameters"),
                           fix="a sweep file is a mapping with 'sweep: 1', 'scenario' and 'parameters'")
        if top is None:
            return None
        get = lambda key: top[key][1] if key in top else None      # noqa: E731
        if "sweep" in top:
            self.integer(get("sweep"), "sweep", SWEEP_VERSION, SWEEP_VERSION,
                         f"this rotorcosim reads sweep format {SWEEP_VERSION}: write 'sweep: {SWEEP_VERSION}'")
        scenario = self.scenario_path(get("scenario")) if "scenario" in top else None
        lines: dict[str, int | None] = {}
        common = self.common(get("set"), lines) if "set" in top else ()
        params = self.parameters(get("parameters"), lines) if "parameters" in top else ()
        mode = "grid"
        if "mode" in top:
            m = self.string(get("mode"), "mode", f"write one of {', '.join(MODES)}")
            if m is not None and m not in MODES:
                self.err(get("mode"), f"'mode' must be one of {list(MODES)} (got {m!r}); "
                                      f"{did_you_mean(m, MODES)}grid: every combination, zip: the i-th "
                                      "value of every parameter together, random: 'samples' runs of the grid")
            elif m is not None:
                mode = m
        samples, seed = self.random_keys(top, mode)
        collect = self.collect(get("collect"), {p.name for p in params}) if "collect" in top else ()
        if mode != "zip":
            for p in params:
                if len(set(map(_same_as, p.values))) != len(p.values):
                    self.problems.append(f"{self.display}:{p.line}: the values of parameter '{p.name}' repeat "
                                         f"(got {list(p.values)}); in mode {mode!r} every value makes its own "
                                         "runs: remove the repetition")
        if mode == "zip" and params:
            counts = {p.name: len(p.values) for p in params}
            if len(set(counts.values())) > 1:
                self.err(get("parameters"), f"mode 'zip' runs the i-th value of every parameter together, so "
                                            f"all need as many values (got {counts}); give them equal "
                                            "counts or use mode: grid")
        if self.problems or scenario is None:
            return None
        return SweepSpec(source=self.path.resolve(), scenario=scenario, common=common, parameters=params,
                         mode=mode, samples=samples, seed=seed, collect=collect, lines=lines)

    def scenario_path(self, node) -> Path | None:
        s = self.string(node, "scenario", "give the scenario file, relative to this sweep file")
        if s is None:
            return None
        path = (self.path.resolve().parent / s).resolve()
        if not path.is_file():
            self.err(node, f"'scenario' names {s!r}, which is not a file ({path}); give the scenario YAML "
                           "file relative to the sweep file's folder")
            return None
        return path

    def override_path(self, node, what: str) -> str | None:
        s = self.string(node, what, "write a dotted scenario key such as fmus.bearing1.parameters.psi")
        if s is not None and not _PATH_RE.match(s):
            self.err(node, f"'{what}' must be a dotted scenario key without spaces or '=' (got {s!r}); "
                           "e.g. fmus.bearing1.parameters.psi")
            return None
        return s

    def common(self, node, lines) -> tuple:
        section = self.mapping(node, "set", None, fix="write scenario keys and values, e.g. set: {stop_time: 1.6}")
        out = []
        for key, (knode, vnode) in (section or {}).items():
            path = self.override_path(knode, "set key")
            value = self.value(vnode) if not isinstance(vnode, yaml.ScalarNode) else self.scalar(vnode, key)
            if path is not None and value is not None:
                out.append((path, value))
                lines[path] = self.line(knode)
        return tuple(out)

    def parameters(self, node, lines) -> tuple[Parameter, ...]:
        if not isinstance(node, yaml.SequenceNode) or not node.value:
            self.err(node, f"'parameters' must be a non-empty list (got {self.got(node)}); write entries "
                           "'- {name: psi, set: [fmus.bearing1.parameters.psi], values: [2.4e-3, 2.8e-3]}'")
            return ()
        out, seen = [], {}
        for i, item in enumerate(node.value):
            p = self.parameter(item, f"parameters[{i}]", lines)
            if p is None:
                continue
            if p.name in seen:
                self.err(item, f"parameter name '{p.name}' appears twice (first on line {seen[p.name]}); "
                               "names are sweep.csv columns: rename one")
                continue
            for path in p.paths:
                owner = next((q.name for q in out if path in q.paths), None)
                if owner is not None:
                    self.err(item, f"'{path}' is set by parameter '{owner}' too; set each scenario key from "
                                   "one parameter only")
            seen[p.name] = p.line
            out.append(p)
        return tuple(out)

    def parameter(self, node, where: str, lines) -> Parameter | None:
        sec = self.mapping(node, where, PARAMETER_KEYS, ("name", "set"))
        if sec is None:
            return None
        name = self.column_name(sec["name"][1], f"{where}.name") if "name" in sec else None
        paths = []
        if "set" in sec:
            snode = sec["set"][1]
            items = snode.value if isinstance(snode, yaml.SequenceNode) else [snode]
            if not items:
                self.err(snode, f"'{where}.set' is empty; give at least one scenario key")
            for it in items:
                path = self.override_path(it, f"{where}.set")
                if path is not None:
                    paths.append(path)
                    lines[path] = self.line(it)
        given = [k for k in ("values", "linspace", "logspace") if k in sec]
        if len(given) != 1:
            self.err(node, f"'{where}' needs exactly one of 'values', 'linspace', 'logspace' (got "
                           f"{given or 'none'}); e.g. values: [2.4e-3, 2.8e-3] or linspace: [0.008, 0.016, 3]")
            return None
        values = self.values(sec[given[0]][1], f"{where}.{given[0]}", given[0])
        if name is None or not paths or values is None:
            return None
        return Parameter(name=name, paths=tuple(paths), values=values, line=self.line(node))

    def column_name(self, node, what: str) -> str | None:
        s = self.string(node, what, "name the parameter, e.g. psi")
        if s is not None and (not _NAME_RE.match(s) or s in RESERVED_COLUMNS):
            self.err(node, f"'{what}' becomes a sweep.csv column: a name of letters, digits and '_' that is "
                           f"not one of {list(RESERVED_COLUMNS)} (got {s!r}); rename it")
            return None
        return s

    def values(self, node, what: str, kind: str) -> tuple | None:
        if kind == "values":
            if not isinstance(node, yaml.SequenceNode) or not node.value:
                self.err(node, f"'{what}' must be a non-empty list (got {self.got(node)}); e.g. [2.4e-3, 2.8e-3]")
                return None
            vals = [self.scalar(it, f"{what} entry") if isinstance(it, yaml.ScalarNode) else
                    self.err(it, f"'{what}' entries must be single values (got {self.got(it)})") for it in node.value]
            return None if any(v is None for v in vals) else tuple(vals)
        fix = f"write {kind}: [first, last, count], e.g. [0.008, 0.016, 3]"
        if not isinstance(node, yaml.SequenceNode) or len(node.value) != 3:
            self.err(node, f"'{what}' must be a list [first, last, count] (got {self.got(node)}); {fix}")
            return None
        a = self.number(node.value[0], f"{what}[0]", positive=kind == "logspace", fix=fix)
        b = self.number(node.value[1], f"{what}[1]", positive=kind == "logspace", fix=fix)
        n = self.integer(node.value[2], f"{what}[2]", 1, 10000, "the count of values, e.g. 3")
        if a is None or b is None or n is None:
            return None
        if n == 1:
            return (a,)
        if kind == "linspace":          # a (1 - t) + b t: no overflow (b - a of -1e308 and 1e308 is inf)
            return tuple(a * (1 - i / (n - 1)) + b * (i / (n - 1)) for i in range(n))
        return tuple(math.exp(math.log(a) + (math.log(b) - math.log(a)) * i / (n - 1)) for i in range(n))

    def random_keys(self, top, mode: str) -> tuple[int | None, int]:
        samples, seed = None, 0
        for key in ("samples", "seed"):
            if key in top and mode != "random":
                self.err(top[key][0], f"'{key}' belongs to mode: random (the mode is {mode!r}); remove it or "
                                      "write mode: random")
        if mode != "random":
            return None, 0
        if "samples" not in top:
            self.err(top.get("mode", (None, None))[1], "mode 'random' needs 'samples' (how many runs to draw "
                                                       "from the grid); add e.g. 'samples: 20'")
        else:
            samples = self.integer(top["samples"][1], "samples", 1, None, "the number of runs to draw, e.g. 20")
        if "seed" in top:
            seed = self.integer(top["seed"][1], "seed", 0, None, "a non-negative integer, e.g. 1") or 0
        return samples, seed

    def collect(self, node, param_names: set) -> tuple:
        section = self.mapping(node, "collect", None, fix="write column: summary.json path lines, e.g. "
                                                         "onset_hz: analysis.journals.bearing1.onset_speed_hz")
        out = []
        for key, (knode, vnode) in (section or {}).items():
            name = self.column_name(knode, f"collect.{key}")
            if name is not None and name in param_names:
                self.err(knode, f"'collect.{key}' is also a parameter name; sweep.csv columns must differ: "
                                "rename one")
                continue
            path = self.override_path(vnode, f"collect.{key}")
            if name is not None and path is not None:
                out.append((name, path))
        return tuple(out)


def _same_as(value) -> tuple:
    """What a parameter value is to a scenario: 1, 1.0 and "1.0" are the same Real (the scenario
    reads a number in a text as the number; ``values: [1, 1.0]`` made two runs of one value)."""
    from orchestrator.scenario.nodes import FLOAT_RE, yaml_float
    if isinstance(value, bool):
        return ("bool", value)
    if isinstance(value, (int, float)):
        return ("number", float(value))
    if isinstance(value, str) and FLOAT_RE.match(value.strip()):      # as checks.convert reads a Real
        return ("number", yaml_float(value))
    return ("text", value)


def load_sweep(path: str | Path) -> SweepSpec:
    """Read and check a sweep file; raises :class:`SweepError` listing every problem.

    Only the sweep file itself is checked here; :func:`orchestrator.sweep.plan.plan_sweep`
    then loads and validates the scenario of every run.
    """
    reader = _SweepReader(Path(path))
    try:
        spec = reader.load()
    except SweepError:
        raise
    except ScenarioError as exc:             # the shared value reader refuses a node (e.g. an unknown !!tag)
        raise SweepError(exc.problems) from None
    if reader.problems or spec is None:
        raise SweepError(reader.problems or [f"{path}: invalid sweep file"])
    return spec
