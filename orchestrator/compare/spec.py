"""The comparison file of ``rotorcosim compare``: dataclasses, loading and validation.

``load_compare(path)`` reads a YAML with a ``compare:`` section (a scenario file with
its own section, or a standalone file naming the base scenario), validates every key
and raises one :class:`CompareSpecError` listing every problem with ``file:line``.
``expand_variants`` turns a variant group into variants (lists in coupling keys are a
cartesian product); ``apply_changes`` makes a variant's scenario from the base. The
format is documented in ``docs/compare.md``.

Length: the validation of every key of the compare format (docs/compare.md) in one place,
so that all problems of a file are collected in one pass; above ~400 lines for that reason.
"""

from __future__ import annotations

import dataclasses
import itertools
import logging
import math
import os
import stat
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, Callable, Mapping

import yaml

from orchestrator.compare.capabilities import check_run_capabilities
from orchestrator.compare.metrics import METRICS
from orchestrator.compare.run_scenarios import RunChanges, check_run_scenarios
from orchestrator.errors import ScenarioError
from orchestrator.scenario import SCHEMES, Scenario
from orchestrator.scenario.analysis_clearance import check_analysis_clearance
from orchestrator.scenario.limits import MAX_SUBSTEPS, limit_problems
from orchestrator.scenario.model import IterationSpec, StepControlSpec
from orchestrator.scenario.nodes import YamlLoader as ScenarioYamlLoader   # same YAML number rules
from orchestrator.untrusted import (InputError, check_name, construct_yaml, file_kind, format_template,
                                   name_problem, read_text, read_yaml_tree)

log = logging.getLogger(__name__)

__all__ = ["CompareSpecError", "CompareSpec", "VariantSpec", "ReferenceSpec", "load_compare",
           "parse_compare", "expand_variants", "apply_changes", "build_pythonfmu_sources"]

COUPLING_KEYS = ("scheme", "extrapolation_order", "interpolation_order", "macro_step", "substeps",
                 "sequence")
MAX_VARIANTS = 500             # variants of one comparison (each is a run)
MAX_WORKERS = 64               # parallel runs of one comparison
MAX_BUILD_SOURCES = 64         # PythonFMU sources built by compare.build_fmus
MAX_BUILD_SOURCE_BYTES = 2**20  # each of them
_ABBR = {"gauss-seidel": "gs", "jacobi": "jac", "iterative": "it", "monolithic": "mono"}
_VARIANT_KEYS = set(COUPLING_KEYS) | {"name", "family", "set", "tolerance", "goal", "expect_order"}
_TOP_KEYS = {"name", "scenario", "set", "output_interval", "workers", "reference", "signals",
             "derived", "metrics", "tolerance", "goal", "variants", "order_metric", "order_tolerance",
             "baseline", "regression_margin", "regression_floor", "build_fmus", "window"}


class CompareSpecError(ScenarioError):
    """A comparison file is invalid; ``problems`` lists every problem found."""

    def __init__(self, problems: list[str] | str):
        super().__init__(problems)
        self.args = ("invalid comparison:\n  " + "\n  ".join(self.problems),)


# --------------------------------------------------------------------------- spec

@dataclass(frozen=True, kw_only=True)
class VariantSpec:
    """One variant: the base scenario with ``changes`` (dotted keys) applied."""

    name: str
    family: str                                   # variants differing only in macro_step
    changes: Mapping[str, Any]                    # e.g. {"coupling.macro_step": 1e-3}
    tolerance: Mapping[str, float] = field(default_factory=dict)   # metric -> max allowed
    expect_order: float | None = None
    # metric -> the error the user needs: selects the cheapest variant within it, never fails a check
    goal: Mapping[str, float] = field(default_factory=dict)


@dataclass(frozen=True, kw_only=True)
class ReferenceSpec:
    """The reference: ``changes`` applied to the base (monolithic or fine co-simulation)."""

    changes: Mapping[str, Any]
    check: bool = True          # also run with halved tolerance/step and report the change

    @property
    def monolithic(self) -> bool:
        return self.changes.get("coupling.scheme") == "monolithic"

    def halved(self, base: Scenario) -> dict[str, Any]:
        """Changes of the convergence-check run: rtol/atol and the BDF2 step (monolithic) or
        the macro step halved. (The step only matters to the BDF2 integrator, which the
        mass-conserving film needs; Radau ignores it.)"""
        ch = dict(self.changes)
        if self.monolithic:
            from orchestrator.reference.monolithic import DEFAULT_ATOL, DEFAULT_RTOL, DEFAULT_STEP
            opts = dict(base.coupling.options)
            rtol = ch.get("coupling.options.rtol", opts.get("rtol", DEFAULT_RTOL))
            atol = ch.get("coupling.options.atol", opts.get("atol", DEFAULT_ATOL))
            step = ch.get("coupling.options.step", opts.get("step", DEFAULT_STEP))
            ch["coupling.options.rtol"] = float(rtol) / 2
            ch["coupling.options.atol"] = float(atol) / 2
            ch["coupling.options.step"] = float(step) / 2
        else:
            h = ch.get("coupling.macro_step", base.coupling.macro_step)
            ch["coupling.macro_step"] = float(h) / 2
        return ch


@dataclass(frozen=True, kw_only=True)
class CompareSpec:
    """A validated comparison (see ``docs/compare.md`` for the YAML keys)."""

    name: str
    base: Scenario
    variants: tuple[VariantSpec, ...]
    reference: ReferenceSpec
    signals: Mapping[str, float | None]           # signal -> error scale (None: peak of reference)
    derived: Mapping[str, Mapping[str, Any]] = field(default_factory=dict)  # name -> {key, scale}
    metrics: tuple[str, ...] = METRICS
    order_metric: str = "rms"
    order_tolerance: float = 0.3
    baseline: Path | None = None
    regression_margin: float = 0.10
    regression_floor: float = 1e-6
    workers: int | None = None
    output_interval: float | None = None
    window: tuple[float, float] | None = None    # metrics over t_from <= t <= t_to only
    source: Path | None = None
    reference_models: tuple[Path, ...] = ()      # files registering monolithic adapters (build_fmus.from)

    def scenario(self, changes: Mapping[str, Any]) -> Scenario:
        """The base scenario with the common output grid and ``changes`` applied."""
        ch = {}
        if self.output_interval is not None:
            ch["output.interval"] = self.output_interval
        ch.update(changes)
        return apply_changes(self.base, ch)

    def smallest_tolerance(self) -> float | None:
        """The smallest tolerance or goal on a signal metric: the reference's own change (its
        convergence check) must stay below it, else its errors cannot tell a variant within it
        from one outside."""
        tols = [v for var in self.variants for lim in (var.tolerance, var.goal) for k, v in lim.items()
                if k in self.metrics]
        return min(tols) if tols else None

    def derived_tolerances(self) -> dict[str, float]:
        """Derived quantity -> the smallest tolerance or goal any variant has on it (only those with
        one): the reference's own change in that quantity must stay below it."""
        out: dict[str, float] = {}
        for var in self.variants:
            for lim in (var.tolerance, var.goal):
                for k, v in lim.items():
                    if k in self.derived:
                        out[k] = min(v, out.get(k, math.inf))
        return out


class _LineLoader(ScenarioYamlLoader):
    """The scenario loader's YAML flavour (``1e-4`` is a float), recording the line of every
    mapping key (``mapping.lines[key]``)."""


class _LineDict(dict):
    lines: dict


def _construct_mapping(loader, node, deep=False):
    d = _LineDict(loader.construct_mapping(node, deep=True))
    d.lines = {loader.construct_object(k): k.start_mark.line + 1 for k, _ in node.value}
    return d


_LineLoader.add_constructor(yaml.resolver.BaseResolver.DEFAULT_MAPPING_TAG, _construct_mapping)


def _group_at(sec, key: str) -> tuple:
    """``(mapping, key)`` whose line ``bad`` should give for ``key``: for ``variants[i]`` the
    group's first key (its line), else the top-level key."""
    groups = sec.get("variants")
    if key.startswith("variants[") and isinstance(groups, list):
        i = int(key[len("variants["):].split("]")[0])
        if i < len(groups) and isinstance(groups[i], dict) and groups[i]:
            return groups[i], next(iter(groups[i]))
    return sec, None


def _line(mapping, key) -> str:
    ln = getattr(mapping, "lines", {}).get(key)
    return f":{ln}" if ln else ""


def load_compare(path: str | os.PathLike) -> CompareSpec:
    """Load a comparison file: a YAML with a ``compare:`` section.

    Either a standalone file whose ``compare.scenario`` names the base scenario
    (relative to the file), or a scenario file that carries its own ``compare:``
    section (the scenario is then the base).
    """
    from orchestrator.scenario import load_scenario   # the frontend's validating loader

    path = Path(path).resolve()
    if path.suffix.lower() == ".fmu":      # no scenario is an FMU: it is named by one (fmus.<instance>.path)
        # was "the comparison file is not UTF-8 text (byte 0xb4 ...)"
        raise CompareSpecError(f"{path}: is an FMU, not a comparison file; compare reads a YAML file with a "
                               "'compare:' section: write a scenario whose 'fmus.<instance>.path: "
                               f"{path.name}' names it, and a comparison file whose 'compare.scenario' names "
                               "that scenario and whose compare section lists the reference and the variants "
                               "(docs/compare.md)")
    if path.suffix.lower() in (".ssp", ".ssd"):
        return _load_compare_ssp(path, load_scenario)
    try:
        root = read_yaml_tree(path, what="comparison file", loader_cls=_LineLoader)
        doc = None if root is None else construct_yaml(root, display=str(path), loader_cls=_LineLoader)
    except InputError as exc:
        raise CompareSpecError(str(exc)) from None
    except yaml.YAMLError as exc:                   # e.g. an unknown !!tag or an unhashable key
        problem = getattr(exc, "problem", None) or exc
        mark = getattr(exc, "problem_mark", None)
        where = f"{path}:{mark.line + 1}" if mark is not None else f"{path}"
        raise CompareSpecError(f"{where}: cannot read the comparison file ({problem}); write plain numbers, "
                               "texts, lists and mappings") from None
    if not isinstance(doc, dict) or not isinstance(doc.get("compare"), dict):
        raise CompareSpecError(f"{path}: expected a mapping with a 'compare:' section "
                               "(see docs/compare.md)")
    sec = doc["compare"]
    reference_models: tuple[Path, ...] = ()
    if "build_fmus" in sec:     # e.g. the orchestrator's test FMUs, before the loader reads them
        b = sec["build_fmus"]
        if not isinstance(b, dict) or set(b) != {"from", "to"}:
            raise CompareSpecError(f"{path}{_line(sec, 'build_fmus')}: 'compare.build_fmus' must be "
                                   "{from: DIR_OF_PYTHONFMU_SOURCES, to: FMU_DIR} (relative to this file)")
        build_pythonfmu_sources(path.parent / str(b["from"]), path.parent / str(b["to"]))
        models = (path.parent / str(b["from"]) / REFERENCE_MODELS).resolve()
        if models.is_file():
            from orchestrator.reference.models import load_model_file
            load_model_file(models)
            reference_models = (models,)
    if "fmus" in doc:
        if "scenario" in sec:
            raise CompareSpecError(f"{path}{_line(sec, 'scenario')}: 'compare.scenario' must not be "
                                   "given in a scenario file (the file itself is the base)")
        base = load_scenario(path, build_fmus=True)     # a comparison runs: building is its step
    else:
        if "scenario" not in sec:
            raise CompareSpecError(f"{path}{_line(doc, 'compare')}: 'compare.scenario' is required "
                                   "(path of the base scenario, relative to this file)")
        if not isinstance(sec["scenario"], str) or not sec["scenario"].strip():
            raise CompareSpecError(f"{path}{_line(sec, 'scenario')}: 'compare.scenario' must be the path of the "
                                   f"base scenario, relative to this file (got {sec['scenario']!r})")
        base = load_scenario((path.parent / sec["scenario"]).resolve(), build_fmus=True)
    check_analysis_clearance(base)                    # its runs analyse their run-ups
    spec = parse_compare(sec, base, source=path)
    return dataclasses.replace(spec, reference_models=reference_models) if reference_models else spec


def _load_compare_ssp(path: Path, load_scenario) -> CompareSpec:
    """``compare x.ssp``: the comparison an SSP from ``export-ssp`` carries in its
    ``org.rotorcosim.scenario`` annotation (the ``compare`` section of the scenario it was exported
    from), with the SSP as its base, as a scenario file with a ``compare:`` section. Paths in it are
    relative to the SSP's folder (``baseline``). Before, the section was written into every archive
    but never read: `compare x.ssp` was refused. An annotation is untrusted: ``build_fmus`` (Python
    sources built and imported) and ``scenario`` (the SSP is the base) are refused."""
    from orchestrator.scenario.ssp_annotation import baseline_outside
    base = load_scenario(path, build_fmus=True)       # a comparison runs: building is its step
    check_analysis_clearance(base)                    # its runs analyse their run-ups
    sec = base.compare
    where = f"{path} (its org.rotorcosim.scenario annotation)"
    if not sec:
        raise CompareSpecError(f"{path}: the SSP carries no 'compare' section (export-ssp writes the one of the "
                               "scenario it exports; this one had none): write a comparison file whose "
                               f"'compare.scenario: {path.name}' names it and whose compare section lists the "
                               "reference and the variants (docs/compare.md)")
    problems = []
    if "build_fmus" in sec:
        problems.append(f"{where}: 'compare.build_fmus' is not taken from an SSP (it builds and imports the Python "
                        "sources it names, outside the archive): remove it, or compare with a comparison file "
                        f"whose 'compare.scenario: {path.name}' names the SSP")
    if "scenario" in sec:
        problems.append(f"{where}: 'compare.scenario' must not be given in an SSP's annotation (the SSP itself is the "
                        "base); remove it")
    baseline = sec.get("baseline")
    if isinstance(baseline, str) and baseline_outside(baseline):
        # --update-baseline writes it: an archive from elsewhere must not name a file outside its folder
        problems.append(f"{where}: 'compare.baseline' = {baseline!r:.200} is not a path inside the SSP's folder "
                        "(relative, no '..', no backslash or drive letter), and `compare --update-baseline` writes "
                        "that file: give a path such as baselines/NAME.json, or compare with a comparison file whose "
                        f"'compare.scenario: {path.name}' names the SSP")
    if problems:
        raise CompareSpecError(problems)
    return parse_compare(dict(sec), base, source=path)


REFERENCE_MODELS = "_reference_models.py"   # in compare.build_fmus.from: register(register_model)


def build_pythonfmu_sources(src_dir: Path, dest: Path) -> list[Path]:
    """Build every PythonFMU source ``src_dir/*.py`` (not ``_*.py``) into ``dest`` when its FMU
    is missing or older than the source; return the FMU paths.

    For comparison files whose FMUs are built from sources, such as the two-mass
    oscillator of ``tests/fmus_src`` (built with ``canGetAndSetFMUstate`` so the
    master may save and restore them, as ``tests/conftest.py`` does).
    """
    import re
    src_dir, dest = Path(src_dir).resolve(), Path(dest).resolve()
    if not src_dir.is_dir():
        raise CompareSpecError(f"compare.build_fmus.from: {src_dir} is not a folder; name the folder of the "
                               "PythonFMU sources (relative to the comparison file)")
    sources = sorted(p for p in src_dir.glob("*.py") if not p.name.startswith("_"))
    if not sources:
        raise CompareSpecError(f"compare.build_fmus.from: no PythonFMU sources (*.py) in {src_dir}")
    if len(sources) > MAX_BUILD_SOURCES:
        raise CompareSpecError(f"compare.build_fmus.from: {len(sources)} sources in {src_dir} (the limit is "
                               f"{MAX_BUILD_SOURCES}, each is an FMU build); point it at a folder of test FMUs")
    if dest.is_file() or Path(dest).is_symlink():
        raise CompareSpecError(f"compare.build_fmus.to: {dest} is a file or a link, expected a folder for the FMUs")
    dest.mkdir(parents=True, exist_ok=True)
    out = []
    for src in sources:
        try:            # a regular file of bounded size (no FIFO or device behind a *.py name)
            text = read_text(src, what="PythonFMU source", limit=MAX_BUILD_SOURCE_BYTES)
        except InputError as exc:
            raise CompareSpecError(f"compare.build_fmus.from: {exc}") from None
        m = re.search(r"^class (\w+)\(\s*Fmi2Slave\s*\)\s*:", text, re.M)
        if m is None:
            continue
        fmu = dest / f"{m.group(1)}.fmu"
        if not fmu.exists() or fmu.stat().st_mtime < src.stat().st_mtime:
            from pythonfmu.builder import FmuBuilder
            log.info("compare: building %s from %s", fmu, src)
            fmu = Path(FmuBuilder.build_FMU(src, dest=dest, canGetAndSetFMUstate=True))
        out.append(fmu)
    return out


def parse_compare(sec: Mapping[str, Any], base: Scenario, *, source: Path | None = None) -> CompareSpec:
    """Validate a ``compare:`` mapping against ``base``; raise one CompareSpecError listing all problems.

    Every section is read by its own function below, each reporting through ``bad`` so
    that one pass collects every problem of the file."""
    where = str(source) if source else "<compare>"
    problems: list[str] = []

    def said(key, msg, m=sec, at=None) -> str:  # line of ``at`` (default ``key``) in ``m``, else of the top key
        line = _line(m, key if at is None else at) or _line(sec, key.split("[")[0].split(".")[0])
        return f"{where}{line}: 'compare.{key}' {msg}"

    def bad(key, msg, m=sec, at=None):
        problems.append(said(key, msg, m, at))

    for k in sec:
        if k not in _TOP_KEYS:
            bad(k, f"is not a known key; valid keys: {sorted(_TOP_KEYS)}")
    name = _name(sec, source, base, bad)
    common = _changes(_given(sec.get("set")), "set", bad)
    try:
        base = apply_changes(base, common)
    except (KeyError, ValueError, TypeError) as exc:
        bad("set", f"cannot be applied: {exc}")
    metrics = sec.get("metrics", list(METRICS))
    if not isinstance(metrics, list) or any(m not in METRICS for m in metrics):
        bad("metrics", f"must be a list drawn from {list(METRICS)} (got {metrics!r})")
        metrics = list(METRICS)
    signals = _signals(sec.get("signals"), bad, base)
    derived = _derived(_given(sec.get("derived")), bad)
    known = set(metrics) | set(derived)
    default_tol = _tolerance(_given(sec.get("tolerance")), known, "tolerance", bad)
    default_goal = _tolerance(_given(sec.get("goal")), known, "goal", bad)
    group_of: dict[str, int] = {}
    variants = _variants(sec, base, default_tol, known, bad, group_of, default_goal)
    reference = _reference(sec.get("reference") or {"scheme": "monolithic"}, bad)
    order_metric = sec.get("order_metric", "rms")
    if order_metric not in metrics:
        bad("order_metric", f"must be one of the metrics {metrics} (got {order_metric!r})")
    nums = _numbers(sec, bad)
    interval = _output_interval(sec.get("output_interval"), base, variants, bad)
    window = _window(sec.get("window"), base, bad)
    baseline = _baseline(sec.get("baseline"), source, bad)
    _check_signals(signals, base, bad)
    _check_reference_step(reference, base, variants, bad)
    if not problems:        # every run of the comparison within the loader's numeric limits
        _check_run_limits(base, reference, variants, interval, bad)
    if not problems:        # ... and one its FMUs can take (state saving, variable steps)
        check_run_capabilities(base, reference, variants, group_of,
                               lambda key, msg: bad(key, msg, *_group_at(sec, key)),
                               lambda key, msg: log.warning("%s", said(key, msg, *_group_at(sec, key))))
    # every run through the scenario loader's checks (a run reported above is left out: one message each)
    converted = check_run_scenarios(_source_file(base), base, _runs(sec, common, reference, variants, group_of,
                                                                      interval, problems), apply_changes, bad)
    if problems:
        raise CompareSpecError(problems)
    base, reference, variants = _as_checked(base, common, reference, variants, converted)
    return CompareSpec(name=name, base=base, variants=tuple(variants), reference=reference,
                       signals=signals, derived=derived, metrics=tuple(metrics),
                       order_metric=order_metric, order_tolerance=nums["order_tolerance"],
                       baseline=baseline, regression_margin=nums["regression_margin"],
                       regression_floor=nums["regression_floor"], workers=nums["workers"],
                       output_interval=interval, window=window, source=source)


def _name(sec, source, base, bad) -> str:
    if sec.get("name") is not None and not isinstance(sec["name"], str):
        bad("name", f"must be a text (got {sec['name']!r})")
    name = str(sec.get("name") or (source.stem if source else base.name))
    if name_problem(name) is not None:              # the default report folder is out/compare/<name>
        bad("name", f"becomes a folder name, but {name_problem(name)}; use letters, digits, '-', '_' and '.'")
    return name


def _derived(derived_sec, bad) -> dict[str, dict]:
    """``compare.derived``: name -> {key: dotted path into summary.json, scale}."""
    derived = {}
    if not isinstance(derived_sec, dict):
        bad("derived", f"must be a mapping name -> {{key, scale}} (got {type(derived_sec).__name__})")
        return derived
    for dname, d in derived_sec.items():
        if isinstance(d, dict) and d.get("scale") is not None and not _positive(d["scale"]):
            bad("derived", f"scale of '{dname}' must be a positive number (got {d['scale']!r})")
            continue
        if not isinstance(d, dict) or "key" not in d:
            bad("derived", f"entry '{dname}' must be a mapping with 'key' (a dotted path into "
                "summary.json, e.g. analysis.bearing1.onset_speed_hz)")
            continue
        derived[str(dname)] = {"key": str(d["key"]), "scale": d.get("scale")}
    return derived


def _variants(sec, base, default_tol, known, bad, group_of: dict[str, int],
              default_goal: Mapping[str, float] | None = None) -> list[VariantSpec]:
    """``compare.variants``: every group expanded, at most MAX_VARIANTS, names distinct;
    ``group_of`` gets each variant's group index (for the line of a later problem)."""
    variants: list[VariantSpec] = []
    groups = sec.get("variants")
    if not isinstance(groups, list) or not groups:
        bad("variants", "must be a non-empty list of variant groups")
        groups = []
    for i, g in enumerate(groups):
        group = expand_variants(g, base, default_tol, known, where=f"variants[{i}]",
                                bad=lambda k, msg, m=g, i=i: bad(f"variants[{i}].{k}", msg, m, k),
                                default_goal=default_goal)
        variants.extend(group)
        for v in group:
            group_of.setdefault(v.name, i)
    if len(variants) > MAX_VARIANTS:
        bad("variants", f"make {len(variants)} variants (the limit is {MAX_VARIANTS}, each is a run); use fewer")
        variants = variants[:MAX_VARIANTS]
    seen = set()
    for v in variants:
        if v.name in seen:
            bad("variants", f"produce the variant name '{v.name}' twice; give each group a "
                "distinct 'name' template such as '{scheme}-e{extrapolation_order}-h{macro_step:g}'")
        seen.add(v.name)
    return variants


def _reference(ref, bad) -> ReferenceSpec:
    """``compare.reference``: the monolithic reference or a fine co-simulation variant."""
    if not isinstance(ref, dict):
        bad("reference", "must be a mapping, e.g. {scheme: monolithic} or {macro_step: 1e-5}")
        ref = {"scheme": "monolithic"}
    ref_changes = _changes({f"coupling.{k}": v for k, v in ref.items() if k in COUPLING_KEYS}, "reference", bad)
    ref_changes.update(_changes(_given(ref.get("set")), "reference.set", bad))
    if not isinstance(ref.get("check", True), bool):
        bad("reference", f"'check' must be true or false (got {ref['check']!r})")
    for k in ref:
        if k not in set(COUPLING_KEYS) | {"set", "check"}:
            bad("reference", f"has unknown key '{k}'; valid: {sorted(set(COUPLING_KEYS) | {'set', 'check'})}")
    if ref_changes.get("coupling.scheme") != "monolithic" and "coupling.macro_step" not in ref_changes:
        bad("reference", "must be {scheme: monolithic, ...} or a co-simulation variant with a "
            "'macro_step' finer than every variant's")
    return ReferenceSpec(changes=ref_changes, check=bool(ref.get("check", True)))


def _baseline(baseline, source, bad) -> Path | None:
    """``compare.baseline`` relative to the file; its folder resolved, not the file itself (a link
    there stays a link, which --update-baseline refuses to write through). What is there must
    be a regular file (or nothing yet): a folder, FIFO or device is refused before any run."""
    if baseline is None:
        return None
    if not isinstance(baseline, str) or not baseline.strip():
        bad("baseline", f"must be a file name such as baselines/NAME.json (got {baseline!r})")
        return None
    path = (source.parent if source else Path.cwd()) / baseline
    path = path.parent.resolve() / path.name
    try:
        mode = os.stat(path).st_mode             # stat, not open: a FIFO does not block
    except OSError:                              # missing (reported when it is read) or unreadable
        return path
    if not stat.S_ISREG(mode):
        bad("baseline", f"names {path}, which is {file_kind(mode)}; the baseline is a regular JSON file (read by the "
            "regression gate, written by --update-baseline): name a file, e.g. baselines/NAME.json")
        return None
    return path


def _check_reference_step(reference: ReferenceSpec, base: Scenario, variants, bad) -> None:
    """A co-simulation reference's macro step must be finer than every variant's and divide it
    (docs/compare.md), so that it is the more accurate run and its rows fall on the common
    output grid (a multiple of every variant's step)."""
    if reference.monolithic or not variants:
        return
    h_ref = reference.changes.get("coupling.macro_step", base.coupling.macro_step)
    if not _positive(h_ref):
        return                                   # reported by _changes
    wrong = [v for v in variants if not (h_ref < _macro(v, base) and _multiple(_macro(v, base), h_ref))]
    if not wrong:
        return
    h, name = _macro(wrong[0], base), wrong[0].name
    why = (f"is not finer than the macro step {h:g} s of variant '{name}'" if h_ref >= h else
           f"does not divide the macro step {h:g} s of variant '{name}' ({h / h_ref:.6g} reference steps)")
    steps = sorted({_macro(v, base) for v in variants})
    fits = [steps[0] / k for k in (10, 2, 4, 5, 20, 100) if all(_multiple(x, steps[0] / k) for x in steps)]
    example = f"e.g. {fits[0]:g}" if fits else "a common divisor of them"
    bad("reference", f"macro_step {h_ref:g} s {why}; a co-simulation reference must be finer than every variant "
        f"and divide its step (docs/compare.md), so that its rows fall on the output grid: give it a macro_step "
        f"that divides every variant's ({', '.join(f'{x:g}' for x in steps)} s), {example}, or use "
        "'scheme: monolithic'")


def _check_signals(signals, base: Scenario, bad) -> None:
    """Every compared signal is ``instance.variable`` with an FMU instance of the base and,
    when its model description can be read, a variable the run records (``output.signals``,
    or by default every output), so that a typo fails here and not after the reference ran."""
    from orchestrator.errors import FmuError
    from orchestrator.fmi.archive import cached_model_description
    from orchestrator.scenario.nodes import article, ranked

    instances = {f.name: f for f in base.fmus}
    recorded = None if base.output.signals is None else set(base.output.signals)
    for s in signals:
        inst, dot, var = s.partition(".")
        if not dot or not var:
            bad("signals", f"entry {s!r} must be 'instance.variable', e.g. '{next(iter(instances), 'rotor')}.x_1'")
            continue
        if inst not in instances:
            bad("signals", f"entry {s!r} names the instance '{inst}', which is not an FMU of the base scenario; "
                f"instances: {', '.join(instances)}")
            continue
        if recorded is not None and s not in recorded:
            bad("signals", f"lists '{s}', which the base scenario does not output; add it to "
                f"'output.signals' (has {list(base.output.signals)})")
            continue
        try:
            md = cached_model_description(instances[inst].path)
        except (FmuError, OSError):
            continue                                 # the run reports an unreadable FMU
        if var in md.variables and md.variables[var].type == "String":
            # a text has no difference to measure: every run came out 'inf', reported as an
            # unstable variant and a reference to tighten
            bad("signals", f"entry {s!r} is a String variable, which has no numeric error to measure; compare "
                "Real, Integer, Boolean or Enumeration signals (a String can be recorded in 'output.signals' "
                "and read in each run's results.csv)")
            continue
        if recorded is not None:
            continue
        outputs = [v.name for v in md.outputs()]
        if var not in md.variables:
            bad("signals", f"entry {s!r}: '{inst}' has no variable '{var}'; outputs of '{inst}' (closest first): "
                f"{ranked(var, outputs)}")
        elif var not in outputs:
            bad("signals", f"entry {s!r}: '{var}' of '{inst}' is {article(md.variables[var].causality)}, "
                "and a run records only outputs unless 'output.signals' lists it; "
                f"add '{s}' to the scenario's 'output.signals' or compare an output of '{inst}' (closest first): "
                f"{ranked(var, outputs)}")


def _numbers(sec, bad) -> dict[str, Any]:
    """The order tolerance, the regression margin and floor, and ``workers``."""
    nums: dict[str, Any] = {}
    for key, default, what in (("order_tolerance", 0.3, "allowed |observed - expect_order|"),
                               ("regression_margin", 0.10, "relative growth allowed over the baseline"),
                               ("regression_floor", 1e-6, "absolute growth allowed over the baseline")):
        val = sec.get(key, default)
        if not _finite(val) or val < 0:     # nan would fail (or pass) every check; inf switches the check off
            bad(key, f"must be a finite number >= 0, the {what} (got {val!r}); write a number such as {default:g}, "
                "or leave the key out for the default")
            val = default
        nums[key] = float(val)
    workers = sec.get("workers")
    if workers is not None and (not isinstance(workers, int) or isinstance(workers, bool)
                                or not 1 <= workers <= MAX_WORKERS):
        bad("workers", f"must be an integer between 1 and {MAX_WORKERS} (got {workers!r})")
        workers = None
    nums["workers"] = workers
    return nums


def _output_interval(interval, base, variants, bad) -> float | None:
    """``compare.output_interval``, else the scenario's when it suits every variant, else the
    largest macro step; it must be a multiple of every variant's macro step."""
    if interval is not None and not _positive(interval):
        bad("output_interval", f"must be a positive number [s] (got {interval!r})")
        interval = None
    steps = [_macro(v, base) for v in variants]
    if interval is None and variants:   # the scenario's interval if it suits every variant
        interval = base.output.interval
        if interval is None or not all(_multiple(interval, h) for h in steps):
            interval = max(steps)
    if interval is not None:
        for v, h in zip(variants, steps):
            if not _multiple(interval, h):
                bad("output_interval", f"({interval:g} s) is not a multiple of the macro step "
                    f"{h:g} s of variant '{v.name}'; outputs would be interpolated, choose a common "
                    "multiple of every macro step")
                break
    return interval


def _window(window, base, bad) -> tuple[float, float] | None:
    """``compare.window``: [t_from, t_to] within the base scenario's run."""
    if window is None:
        return None
    ok = (isinstance(window, list) and len(window) == 2
          and all(isinstance(x, (int, float)) and not isinstance(x, bool) for x in window)
          and base.start_time <= window[0] < window[1] <= base.stop_time)
    if not ok:
        bad("window", f"must be [t_from, t_to] [s] with start_time <= t_from < t_to <= stop_time "
            f"({base.start_time:g}, {base.stop_time:g}) (got {window!r})")
        return None
    return (float(window[0]), float(window[1]))


def _check_run_limits(base, reference: ReferenceSpec, variants, interval, bad) -> None:
    """Every run of the comparison (reference and variants) within the loader's numeric limits."""
    runs = [("reference", reference.changes)] + [(f"variant '{v.name}'", v.changes) for v in variants]
    for label, ch in runs:
        try:
            found = limit_problems(apply_changes(base, dict(ch, **(
                {"output.interval": interval} if interval is not None else {}))))
        except (KeyError, ValueError, TypeError) as exc:
            found = [f"cannot be applied ({exc})"]
        for p in found[:1]:
            bad("variants" if label != "reference" else "reference", f"makes the {label} run invalid: {p}")


def _source_file(base: Scenario) -> Path | None:
    """The file the base scenario was loaded from (None: made in code)."""
    src = base.source
    return Path(src) if src is not None and Path(src).is_file() else None


def _runs(sec, common, reference: ReferenceSpec, variants, group_of, interval, problems) -> list[RunChanges]:
    """The reference (a co-simulation or monolithic one) and every variant as :class:`RunChanges`: the
    comparison's ``set``, the run's changes and the output grid, each with its place in the file."""
    shared: dict[str, tuple] = {k: ("set", _given(sec.get("set")), k) for k in common}
    # the output grid as written (the default one is the base's or the largest macro step: checked as those are)
    grid = {"output.interval": interval} if interval is not None and "output_interval" in sec else {}

    def run(who, home, changes, places):
        return RunChanges(who=who, changes={**common, **changes, **grid}, home=home, places={
            **shared, **places, **({"output.interval": ("output_interval", sec, "output_interval")} if grid else {})})

    out = []
    ref = sec.get("reference") if isinstance(sec.get("reference"), dict) else {}
    if not any("'compare.reference'" in p for p in problems):
        out.append(run("the reference", ("reference", sec, "reference"), reference.changes,
                       _places(ref, "reference", reference.changes)))
    groups = sec.get("variants") if isinstance(sec.get("variants"), list) else []
    for v in variants:
        if any(f"variant '{v.name}'" in p for p in problems):
            continue
        i = group_of.get(v.name, 0)
        g = groups[i] if i < len(groups) and isinstance(groups[i], dict) else {}
        out.append(run(f"variant '{v.name}'", (f"variants[{i}]", *_group_at(sec, f"variants[{i}]")), v.changes,
                       _places(g, f"variants[{i}]", v.changes)))
    return out


def _as_checked(base, common, reference: ReferenceSpec, variants, converted) -> tuple:
    """The base, reference and variants with the parameter values the loader converted
    (:func:`check_run_scenarios`): what each run is given is what was checked."""
    runs = [("the reference", reference.changes)] + [(f"variant '{v.name}'", v.changes) for v in variants]
    shared = {k: x for who, changes in runs for k, x in converted.get(who, {}).items()
              if k in common and k not in changes}           # the comparison's set, as no run overrides it
    if shared:
        base = apply_changes(base, shared)

    def own(who, changes):
        return {**changes, **{k: x for k, x in converted.get(who, {}).items() if k in changes}}
    reference = dataclasses.replace(reference, changes=own("the reference", reference.changes))
    variants = [dataclasses.replace(v, changes=own(f"variant '{v.name}'", v.changes)) for v in variants]
    return base, reference, variants


def _places(group, label: str, changes) -> dict[str, tuple]:
    """Where in ``group`` (a variant group or the reference) each of ``changes`` is written: its
    ``set`` entry, else its coupling key."""
    sets = _given(group.get("set"))
    out = {}
    for k in changes:
        if isinstance(sets, dict) and k in sets:
            out[k] = (f"{label}.set", sets, k)
        elif k.startswith("coupling.") and k[len("coupling."):] in group:
            out[k] = (f"{label}.{k[len('coupling.'):]}", group, k[len("coupling."):])
    return out


def _multiple(interval: float, h: float) -> bool:
    n = round(interval / h)
    return n >= 1 and math.isclose(interval / h, n, rel_tol=1e-9)


def _macro(v: VariantSpec, base: Scenario) -> float:
    return float(v.changes.get("coupling.macro_step", base.coupling.macro_step))


def _finite(x) -> bool:
    return isinstance(x, (int, float)) and not isinstance(x, bool) and math.isfinite(x)


def _positive(x) -> bool:
    return _finite(x) and x > 0


def _change_problem(key: str, v) -> str | None:
    """Why value ``v`` cannot be given to the dotted key ``key`` (None: it can)."""
    num = isinstance(v, (int, float)) and not isinstance(v, bool) and math.isfinite(v)
    integer = isinstance(v, int) and not isinstance(v, bool)
    if key in ("stop_time", "start_time") and not num:
        return "a finite number [s]"
    if key in ("coupling.macro_step", "output.interval") and not (num and v > 0):
        return "a positive number [s]"
    if key in ("coupling.extrapolation_order", "coupling.interpolation_order") and not (integer and 0 <= v <= 3):
        return "an integer 0..3"
    if key == "coupling.substeps" and not (integer and 1 <= v <= MAX_SUBSTEPS):
        return f"an integer 1..{MAX_SUBSTEPS}"
    if key == "coupling.scheme" and v not in SCHEMES:
        return f"one of {list(SCHEMES)}"
    if key in ("coupling.sequence", "output.signals") and not (
            isinstance(v, list) and all(isinstance(x, str) for x in v)):
        return "a list of names"
    return None


def _given(value):
    """A mapping key's value, ``{}`` when it is left empty (``goal:``): a falsy value of another type
    (``goal: 0``, ``[]``, ``''``, ``false``) is checked as given, not taken for no entries (``x or {}``
    did, without a word)."""
    return {} if value is None else value


def _changes(m, key, bad) -> dict[str, Any]:
    if not isinstance(m, dict):
        bad(key, f"must be a mapping of dotted keys to values, e.g. {{stop_time: 0.1}} (got {m!r})")
        return {}
    out = {}
    for k, v in m.items():
        want = _change_problem(str(k), v)
        if want is not None:
            bad(key, f"gives '{k}' the value {v!r}; it must be {want}")
            continue
        out[str(k)] = v
    return out


def _signals(sig, bad, base: Scenario | None = None) -> dict[str, float | None]:
    if isinstance(sig, list) and sig and all(isinstance(s, str) for s in sig):
        return {s: None for s in sig}
    if isinstance(sig, dict) and sig:
        out = {}
        for s, opt in sig.items():
            scale = (opt or {}).get("scale") if isinstance(opt, dict) else opt
            if scale is not None and not _positive(scale):
                bad("signals", f"scale of '{s}' must be a positive finite number [signal unit] (got {scale!r}); "
                    "e.g. the clearance for a displacement, or leave it out for the reference's peak")
                scale = None
            out[str(s)] = None if scale is None else float(scale)
        return out
    example = _signal_example(base)
    bad("signals", "must be a non-empty list of 'instance.variable' names or a mapping "
        "name -> {scale: value}: the signals whose errors are measured" +
        (f", e.g. signals: [{', '.join(repr(x) for x in example)}]" if example else ""))
    return {}


def _signal_example(base: Scenario | None) -> list[str]:
    """Up to three numeric outputs the base scenario records, for the message of a missing
    ``compare.signals`` (a first comparison file often leaves it out)."""
    if base is None:
        return []
    if base.output.signals is not None:
        return list(base.output.signals)[:3]
    from orchestrator.errors import FmuError
    from orchestrator.fmi.archive import cached_model_description
    out: list[str] = []
    for f in base.fmus:
        try:
            md = cached_model_description(f.path)
        except (FmuError, OSError, AttributeError, TypeError):
            continue
        out += [f"{f.name}.{n}" for n, v in md.variables.items()
                if getattr(v, "causality", None) == "output" and getattr(v, "type", None) == "Real"]
        if len(out) >= 3:
            break
    return out[:3]


def _tolerance(tol, known, key, bad) -> dict[str, float]:
    if not isinstance(tol, dict):
        bad(key, f"must be a mapping metric -> relative error, e.g. {{rms: 0.01}} (got {tol!r})")
        return {}
    out = {}
    for k, v in tol.items():
        if k not in known:
            bad(key, f"names '{k}', which is neither a metric nor a derived quantity; "
                f"valid: {sorted(known)}")
        elif not _positive(v):     # nan fails every variant, inf checks nothing
            bad(key, f"value of '{k}' must be a positive number (got {v!r}), finite: the largest error "
                f"allowed, e.g. 0.01 (nan would fail every variant, inf check nothing); leave '{k}' out to not "
                "check it")
        else:
            out[k] = float(v)
    return out


def expand_variants(group: Mapping[str, Any], base: Scenario, default_tol: Mapping[str, float],
                    known: set[str], *, where: str = "variants[0]",
                    bad: Callable[[str, str], None] | None = None,
                    default_goal: Mapping[str, float] | None = None) -> list[VariantSpec]:
    """Expand one variant group (lists in coupling keys -> cartesian product).

    Length: every key of a variant group is checked here, in one pass that collects all
    problems, then the product is formed and named."""
    problems = []
    if bad is None:
        def bad(k, msg):
            problems.append(f"{where}.{k} {msg}")
    if not isinstance(group, dict):
        bad("", f"must be a mapping of coupling keys {list(COUPLING_KEYS)} (got {group!r})")
        return []
    for k in group:
        if k not in _VARIANT_KEYS:
            bad(k, f"is not a variant key; valid: {sorted(_VARIANT_KEYS)}")
    axes = []
    for k in COUPLING_KEYS:
        if k in group:
            vals = group[k]
            if k == "sequence" or not isinstance(vals, list):
                vals = [vals]
            if not vals:
                bad(k, "is an empty list")
            wrong = [v for v in vals if _change_problem(f"coupling.{k}", v) is not None]
            if wrong:
                bad(k, f"must be {_change_problem(f'coupling.{k}', wrong[0])} (got {wrong[0]!r})")
                vals = []
            axes.append((k, vals))
    tol = dict(default_tol)
    tol.update(_tolerance(_given(group.get("tolerance")), known, "tolerance", bad))
    goal = dict(default_goal or {})
    goal.update(_tolerance(_given(group.get("goal")), known, "goal", bad))
    extra = _changes(_given(group.get("set")), "set", bad)
    expect = group.get("expect_order")
    if expect is not None and not _finite(expect):
        bad("expect_order", f"must be a finite number, the expected order of convergence (got {expect!r}); "
            "e.g. 1, or leave it out")
        expect = None
    count = math.prod(len(vals) for _, vals in axes)
    if count > MAX_VARIANTS:
        bad("", f"expands to {count} variants (the product of its lists; the limit is {MAX_VARIANTS}); split it "
            "into smaller groups or shorten the lists")
    out = []
    combos = itertools.product(*[vals for _, vals in axes]) if count <= MAX_VARIANTS else ()
    for combo in combos:
        values = dict(zip([k for k, _ in axes], combo))
        coupling = {k: values.get(k, getattr(base.coupling, k)) for k in COUPLING_KEYS}
        for k in ("extrapolation_order", "interpolation_order", "substeps"):
            if not isinstance(coupling[k], int) or coupling[k] < 0:
                bad(k, f"must be a non-negative integer (got {coupling[k]!r})")
        if not isinstance(coupling["macro_step"], (int, float)) or coupling["macro_step"] <= 0:
            bad("macro_step", f"must be a positive number [s] (got {coupling['macro_step']!r})")
            continue
        fields_ = dict(coupling, abbr=_ABBR.get(coupling["scheme"], coupling["scheme"]))
        default_name = "{abbr}-e{extrapolation_order}i{interpolation_order}"
        if coupling["substeps"] != 1:
            default_name += "-s{substeps}"
        default_name += "-h{macro_step:g}"
        try:     # names become folders (runs/<name>): plain fields only, then the one name check
            template = group.get("name", default_name)
            name = check_name(format_template(template, fields_, what="the name template"),
                              what=f"the variant name made from {template!r}")
            fam_tmpl = group.get("family") or str(template).replace(
                "-h{macro_step:g}", "").replace("{macro_step:g}", "").replace("{macro_step}", "")
            family = format_template(fam_tmpl, fields_, what="the family template")
        except InputError as exc:
            bad("name", f"is not usable: {exc}")
            continue
        changes = {f"coupling.{k}": v for k, v in values.items()}
        changes.update(extra)
        out.append(VariantSpec(name=name, family=family, changes=changes, tolerance=tol, goal=goal,
                               expect_order=None if expect is None else float(expect)))
    if problems:
        raise CompareSpecError(problems)
    return out


def apply_changes(scenario: Scenario, changes: Mapping[str, Any]) -> Scenario:
    """Return ``scenario`` with dotted-key changes applied.

    Keys: ``stop_time``, ``start_time``, ``coupling.<field>``, ``coupling.options.<k>``,
    ``coupling.iteration.<k>``, ``coupling.step_control.<k>``,
    ``output.interval``, ``output.signals``, ``<instance>.<parameter>`` (an FMU parameter).
    """
    sc = scenario
    for key, value in changes.items():
        parts = key.split(".")
        if key in ("stop_time", "start_time"):
            sc = dataclasses.replace(sc, **{key: float(value)})
        elif parts[0] == "coupling" and len(parts) == 3 and parts[1] == "options":
            opts = dict(sc.coupling.options)
            opts[parts[2]] = value
            sc = dataclasses.replace(sc, coupling=dataclasses.replace(sc.coupling, options=opts))
        elif parts[0] == "coupling" and len(parts) == 3 and parts[1] in ("iteration", "step_control"):
            sub = getattr(sc.coupling, parts[1])
            if parts[2] not in {f.name for f in dataclasses.fields(sub)}:
                raise KeyError(f"'{key}': unknown field of coupling.{parts[1]} (fields: "
                               f"{[f.name for f in dataclasses.fields(sub)]})")
            sub = dataclasses.replace(sub, **{parts[2]: value})
            sc = dataclasses.replace(sc, coupling=dataclasses.replace(sc.coupling, **{parts[1]: sub}))
        elif parts[0] == "coupling" and len(parts) == 2:
            if parts[1] not in {f.name for f in dataclasses.fields(sc.coupling)}:
                raise KeyError(f"'{key}': unknown coupling field")
            if parts[1] == "sequence":
                value = tuple(value)
            elif parts[1] in ("iteration", "step_control"):
                # a whole section, e.g. {type: constant} over a scenario's error control: a new spec
                # from the given keys (the others at their defaults), as a scenario file would give it
                cls = {"iteration": IterationSpec, "step_control": StepControlSpec}[parts[1]]
                names = [f.name for f in dataclasses.fields(cls)]
                if not isinstance(value, Mapping) or set(value) - set(names):
                    raise KeyError(f"'{key}': expected a mapping of {names} (got "
                                   f"{sorted(set(value) - set(names)) if isinstance(value, Mapping) else value!r})")
                try:
                    value = cls(**dict(value))
                except (TypeError, ValueError) as exc:
                    raise KeyError(f"'{key}': {exc}") from None
            sc = dataclasses.replace(sc, coupling=dataclasses.replace(sc.coupling, **{parts[1]: value}))
        elif parts[0] == "output" and len(parts) == 2 and parts[1] in ("interval", "signals"):
            if parts[1] == "signals" and value is not None:
                value = tuple(value)
            sc = dataclasses.replace(sc, output=dataclasses.replace(sc.output, **{parts[1]: value}))
        elif len(parts) == 2 and parts[0] in {f.name for f in sc.fmus}:
            fmus = tuple(dataclasses.replace(f, parameters={**f.parameters, parts[1]: value})
                         if f.name == parts[0] else f for f in sc.fmus)
            sc = dataclasses.replace(sc, fmus=fmus)
        else:
            raise KeyError(f"'{key}': expected stop_time, start_time, coupling.<field>, "
                           "coupling.options.<key>, output.interval, output.signals or "
                           f"<instance>.<parameter> with an instance in {[f.name for f in sc.fmus]}")
    return sc
