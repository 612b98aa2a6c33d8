"""YAML node reading for scenario files: anchors, merge keys, YAML 1.2 numbers, typed values.

:class:`NodeReader` reads values off PyYAML nodes (keeping their line numbers) and
collects every problem as ``file:line: what is wrong (got X); fix`` in ``problems``.
"""

from __future__ import annotations

import copy
import difflib
import math
import re
from typing import Any

import yaml

from fmu_common.safe_yaml import SafeLoader
from orchestrator.errors import ScenarioError

MAP_TAG, SEQ_TAG, STR_TAG = "tag:yaml.org,2002:map", "tag:yaml.org,2002:seq", "tag:yaml.org,2002:str"
# YAML 1.1 (PyYAML) reads 1e-4 as a string; scenarios use such numbers all the time.
FLOAT_RE = re.compile(r"""^(?:[-+]?(?:[0-9][0-9_]*)\.[0-9_]*(?:[eE][-+]?[0-9]+)?
    |[-+]?[0-9][0-9_]*[eE][-+]?[0-9]+
    |[-+]?\.[0-9_]+(?:[eE][-+]?[0-9]+)?
    |[-+]?\.(?:inf|Inf|INF)|\.(?:nan|NaN|NAN))$""", re.X)



def yaml_float(text: str) -> float:
    """The number of a text that :data:`FLOAT_RE` matches, YAML's ``.inf``, ``-.inf`` and ``.nan``
    included (Python's float() refuses those: a quoted ``".nan"`` ended in an internal error)."""
    t = text.strip().replace("_", "")
    low = t.lower()
    if low in (".inf", "+.inf", "-.inf"):
        return -math.inf if low.startswith("-") else math.inf
    if low == ".nan":
        return math.nan
    return float(t)


#: the longest text a message quotes as what came (``got``): a file that is not YAML (an XML
#: system structure) reads as one string and was quoted whole, 1.4 kB for crane-fmu's OSP file
GOT_CHARS = 80


class YamlLoader(SafeLoader):
    """Safe YAML loader that also reads ``1e-4`` as a float (YAML 1.2 style); a value its tag
    cannot read (``!!int zz``, the date ``2001-13-45``) is a ``yaml.YAMLError`` with its line
    (:mod:`fmu_common.safe_yaml`), not an internal error."""


YamlLoader.add_implicit_resolver("tag:yaml.org,2002:float", FLOAT_RE, list("-+0123456789."))


MAX_RANKED = 2000                  # candidates compared in full for a "closest first" list


def ranked(name: str, candidates, limit: int = 15) -> str:
    """``candidates`` closest to ``name`` first, as one readable string.

    Above MAX_RANKED candidates only those sharing the first letter (else the first
    MAX_RANKED) are compared, so a bad name in an FMU of 200k variables stays cheap."""
    candidates = list(candidates)
    total = len(candidates)
    if total > MAX_RANKED:
        near = [c for c in candidates if c[:1].lower() == name[:1].lower()]
        candidates = (near if near else candidates)[:MAX_RANKED]
    order = sorted(candidates, key=lambda c: (
        -difflib.SequenceMatcher(None, name.lower(), c.lower()).ratio(), c))
    text = ", ".join(order[:limit])
    if total > limit:
        text += f", ... ({total - limit} more)"
    return text or "(none)"


def did_you_mean(name: str, candidates) -> str:
    close = difflib.get_close_matches(name, list(candidates), n=1, cutoff=0.5)
    return f"did you mean '{close[0]}'? " if close else ""


def article(word: str) -> str:
    return f"an {word}" if word[:1].lower() in "aeiou" else f"a {word}"


#: scenario files generated from an SSP (orchestrator.scenario.loader.from_ssp): generated file
#: -> (what to call it, {line of the generated file: where that value came from}), so that a
#: problem names the .ssp (and the value's place in it) or the user's YAML file and line, not
#: the generated file, which is gone when the process ends
GENERATED: dict[str, tuple[str, dict[int, str]]] = {}


class NodeReader:
    """Typed reading of YAML nodes of one file; problems go to ``self.problems``."""

    def __init__(self, path, display: str):
        self.path = path
        self.display = display
        self.line_origins: dict[int, str] = {}
        if str(path) in GENERATED:
            self.display, self.line_origins = GENERATED[str(path)]
        self.problems: list[str] = []
        self.origins: dict[int, str] = {}     # id(node) -> "--set k=v" for override nodes
        self.ctor = YamlLoader("")

    # -- helpers -----------------------------------------------------------
    def loc(self, node) -> str:
        if node is None:
            return f"{self.display}:1"
        if id(node) in self.origins:
            return self.origins[id(node)]
        mark = getattr(node, "start_mark", None)
        if self.line_origins:               # generated from an SSP: where the value came from
            return self.line_origins.get(mark.line + 1, self.display) if mark is not None else self.display
        return f"{self.display}:{mark.line + 1}" if mark is not None else self.display

    def err(self, node, text: str) -> None:
        self.problems.append(f"{self.loc(node)}: {text}")

    def key_origins(self, node, key: str) -> dict[str, str]:
        """Where ``key`` (whose value is ``node``) and every key under it are written: dotted key ->
        place as :meth:`loc` gives it (``file:line``, ``--set k=v``, the origin in an SSP), for the
        checks made after loading (:attr:`Scenario.analysis_origins`)."""
        found = {key: self.loc(node)}
        if isinstance(node, yaml.MappingNode):
            for k, v in node.value:
                if isinstance(k, yaml.ScalarNode):
                    found.update(self.key_origins(v, f"{key}.{k.value}"))
        return found

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
        if isinstance(v, str) and len(v) > GOT_CHARS:    # a whole file read as one string: its start
            return f"{v[:GOT_CHARS]!r}... ({len(v)} characters), {kind}"
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
            raw = self.value(knode)
            if raw is None or isinstance(raw, bool):   # ~, null, yes/no, on/off, true/false
                self.err(knode, f"keys of '{where}' must be names (got {knode.value!r}, which YAML reads as "
                                f"{raw!r}); write a plain name, in quotes if it must be {knode.value!r}")
                continue
            key = str(raw)
            if key in out:
                self.err(knode, f"key '{key}' appears twice in '{where}' (first on line "
                                f"{out[key][0].start_mark.line + 1}); keep one of them")
            if keys is not None and key not in keys:
                self.err(knode, f"unknown key '{key}' in '{where}'; {did_you_mean(key, keys)}"
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
        if isinstance(v, str) and FLOAT_RE.match(v.strip()):
            v = yaml_float(v)
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

    def mark(self, node, origin: str) -> None:
        self.origins[id(node)] = origin
        if isinstance(node, yaml.MappingNode):
            for k, v in node.value:
                self.mark(k, origin)
                self.mark(v, origin)
        elif isinstance(node, yaml.SequenceNode):
            for v in node.value:
                self.mark(v, origin)


def flatten_merges(ctor, node, seen: set) -> None:
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
            flatten_merges(ctor, v, seen)
    elif isinstance(node, yaml.SequenceNode):
        for v in node.value:
            flatten_merges(ctor, v, seen)


def unshared(node):
    """A shallow copy of a collection node (YAML aliases share nodes), scalars as they are."""
    if isinstance(node, (yaml.MappingNode, yaml.SequenceNode)):
        node = copy.copy(node)
        node.value = list(node.value)
    return node


def line_order(problem: str) -> tuple[int, int]:
    """Sort key: ``--set`` problems first, then by line number in the file."""
    if problem.startswith("--set"):
        return (0, 0)
    m = re.match(r"^.*?:(\d+)(?::\d+)?: ", problem)
    return (1, int(m.group(1)) if m else 0)
