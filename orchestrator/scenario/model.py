"""Scenario format (version 1): the frozen dataclasses and the format's limits.

The dataclasses are the contract between the loader, the master, the CLI,
``compare`` and ``plot``: extend them, never rename fields.
"""

from __future__ import annotations

import re

from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, Mapping

SCENARIO_VERSION = 1
SCHEMES = ("gauss-seidel", "jacobi", "iterative", "monolithic")
ACCELERATIONS = ("none", "aitken", "iqn-ils")       # coupling.iteration.acceleration
STEP_CONTROL_TYPES = ("constant", "error")          # coupling.step_control.type
ERROR_MEASURES = ("value", "impulse")       # coupling.step_control.measure (coupling/adaptive.py)
MAX_ORDER = 3                     # highest extrapolation/interpolation order of the coupling signals
MAX_DISCARD_RETRIES = 30          # coupling.discard_retries: smallest retried step H / 2^30

# the keys of each section, and the schema --set overrides navigate by
TOP_KEYS = ("name", "version", "description", "start_time", "stop_time", "fmus",
            "connections", "coupling", "output", "analysis", "compare")
FMU_KEYS = ("path", "fmu", "parameters", "substeps", "isolation")
ISOLATION = ("none", "process")   # fmus.<name>.isolation, coupling.isolation
CONNECTION_KEYS = ("from", "to", "gain", "offset")
COUPLING_KEYS = ("scheme", "sequence", "macro_step", "extrapolation_order",
                 "interpolation_order", "substeps", "discard_retries", "isolation", "parallel", "call_timeout",
                 "pin_workers", "options", "iteration", "step_control", "defect_limit", "defect_signals",
                 "defect_retries")
OUTPUT_KEYS = ("interval", "signals", "format")
OUTPUT_FORMATS = ("csv", "parquet")
ANALYSIS_KEYS = ("speed", "journals", "fields", "whirl")   # analysis (docs/analysis.md)
JOURNAL_KEYS = ("x", "y", "eps", "clearance")             # analysis.journals.<name>
# override navigation: (schema, key) -> schema of the child; (schema) -> default
CHILD_SCHEMA = {
    ("top", "fmus"): "instances", ("top", "connections"): "connections",
    ("top", "coupling"): "coupling", ("top", "output"): "output", ("top", "analysis"): "free",
    ("top", "compare"): "free", ("fmu", "parameters"): "params", ("coupling", "options"): "free",
    ("coupling", "iteration"): "free", ("coupling", "step_control"): "free",
    "instances": "fmu", "connections": "connection", "free": "free",
}
SECTION_KEYS = {"top": TOP_KEYS, "fmu": FMU_KEYS, "connection": CONNECTION_KEYS,
                 "coupling": COUPLING_KEYS, "output": OUTPUT_KEYS}

_MAP, _SEQ, _STR = "tag:yaml.org,2002:map", "tag:yaml.org,2002:seq", "tag:yaml.org,2002:str"


class SetOrigin(str):
    """The origin ``--set k=v`` of a value an override gave (``rotorcosim ... --set``,
    ``load_scenario(overrides=...)``): the caller's own value, not the scenario file's. export-ssp
    carries the file such a value names wherever it lies; a file named by the scenario file itself
    only from the scenario's folder (:func:`orchestrator.scenario.ssp.export_ssp`). A ``str``, so
    every message that shows an origin is unchanged; the type, not the text, tells them apart (a
    scenario file may be called ``--set x.yaml``)."""

    __slots__ = ()


@dataclass(frozen=True, kw_only=True)
class FmuSpec:
    """One FMU instance of the scenario (``fmus:`` entry)."""

    name: str                                # instance name, e.g. "bearing1"
    path: Path                               # absolute, resolved relative to the YAML file
    parameters: Mapping[str, Any] = field(default_factory=dict)   # name -> value (float/int/bool/str)
    substeps: int | None = None              # per-FMU override of coupling.substeps
    line: int | None = None                  # line of the entry in the YAML file
    isolation: str | None = None             # "process" | "none"; None -> coupling.isolation
    # name -> "file:line" or "--set ..." (a SetOrigin: the caller's value, not the file's)
    parameter_origins: Mapping[str, str] = field(default_factory=dict)

    def origins_named_in(self, text: str, limit: int = 4) -> list[tuple[str, str]]:
        """Where the scenario sets the parameters that ``text`` (an FMU's message) names.

        ``(name, "file:line")`` (or ``"--set ..."``) for each parameter of this instance that the text names,
        in the order the text names them, at most ``limit``: quoted (``'p_feed'``) or, for
        names of two or more characters, as a whole word (``p0``). The FMU checks its
        parameters itself (relations such as ``p_feed >= p0``), so this is how its
        refusal is traced back to the scenario's lines."""
        found = []
        for pname, origin in self.parameter_origins.items():
            pat = re.escape(pname)
            quoted = re.search(rf"['\"`]{pat}['\"`]", text)
            word = len(pname) > 1 and re.search(rf"(?<![\w.\[\]]){pat}(?![\w\[])", text)
            hit = quoted or word
            if hit:
                found.append((hit.start(), pname, origin))
        return [(n, o) for _, n, o in sorted(found)[:limit]]


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
class IterationSpec:
    """``coupling.iteration`` section (used by ``scheme: iterative``, orchestrator/coupling/iterative.py)."""

    max_iterations: int = 20                 # passes per macro step, >= 1
    tol: float = 1.0e-8                      # relative to each signal's scale
    acceleration: str = "iqn-ils"            # one of ACCELERATIONS
    hold_jacobian: bool = True               # interface-Jacobian coefficients held during a step's passes

    def __post_init__(self):
        if self.acceleration not in ACCELERATIONS:
            raise ValueError(f"coupling.iteration.acceleration must be one of {list(ACCELERATIONS)} "
                             f"(got {self.acceleration!r})")


@dataclass(frozen=True, kw_only=True)
class StepControlSpec:
    """``coupling.step_control``: ``type: constant`` (the default, macro_step throughout) or
    ``type: error`` (error-controlled macro step, orchestrator/coupling/adaptive.py; ``macro_step``
    is the first step). ``min_step``/``max_step`` None: macro_step / 1000 and the output interval.
    ``until`` (type error only): the step is error-controlled from start_time up to ``until`` [s]
    (a time on the output grid), then constant ``macro_step`` steps to stop_time (None: error
    control to the end)."""

    type: str = "constant"                   # one of STEP_CONTROL_TYPES
    rtol: float = 1.0e-4
    atol: float | tuple | None = None        # in the signals' units, or ((pattern, atol), ...) per signal;
                                             # None: rtol * the FMUs' nominal where declared, else 1e-8
    interface_jacobian: bool = True          # estimate the force an interface-Jacobian rotor applied
    measure: str = "value"                   # one of ERROR_MEASURES: the defect as is, or times H / output interval
    min_step: float | None = None            # [s]
    max_step: float | None = None            # [s]
    until: float | None = None               # [s] error control up to here, then constant steps

    def __post_init__(self):
        if isinstance(self.atol, Mapping):   # e.g. from a compare file's `set:` or Python: keep file order
            object.__setattr__(self, "atol", tuple((str(k), float(v)) for k, v in self.atol.items()))


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
    isolation: str = "none"                  # default of fmus.<name>.isolation: "process" | "none"
    parallel: bool | str = True              # step the FMUs of a stage concurrently: True (workers),
    #                                          False, or "threads" (also in-process FMUs, each in a thread)
    call_timeout: float | None = None        # [s] longest wait for an isolated FMU's answer; None: no limit
    pin_workers: bool = False                # each worker process on a CPU of its own (round robin)
    options: Mapping[str, Any] = field(default_factory=dict)  # scheme-specific extras (e.g. monolithic rtol)
    iteration: IterationSpec = field(default_factory=IterationSpec)         # scheme: iterative
    step_control: StepControlSpec = field(default_factory=StepControlSpec)  # constant or error-controlled
    # constant steps: warn when an interface-Jacobian force's defect exceeds this x its typical force
    # (orchestrator/coupling/defect.py); .inf: never (the statistics are still written)
    defect_limit: float = 1.0
    # constant steps: also monitor these coupling inputs' prediction error (names or patterns of
    # consumer inputs, e.g. "b.u*"; orchestrator/coupling/defect.py); () -> interface-Jacobian forces only
    defect_signals: tuple[str, ...] = ()
    # constant steps: a (sub-)step whose defect exceeds defect_limit x the typical force is redone from
    # the saved states in halves, up to this many halvings (0: only reported)
    defect_retries: int = 0


@dataclass(frozen=True, kw_only=True)
class OutputSpec:
    """``output:`` section."""

    interval: float | None = None            # [s]; None -> macro_step
    signals: tuple[str, ...] | None = None   # None -> every connected or FMU output
    format: str = "csv"                      # "csv" (results.csv) | "parquet" (results.parquet, needs pyarrow)


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
    defaults: Mapping[str, str] = field(default_factory=dict)  # values taken from the FMUs' DefaultExperiment
    # where the analysis section's keys are written: dotted key ("analysis.journals.bearing1.clearance") ->
    # "file:line" or "--set ...", for the checks of the analysis where it is planned (analysis_clearance.py)
    analysis_origins: Mapping[str, str] = field(default_factory=dict, compare=False)
    # the files loading read (the YAML, an SSP and its .ssd/.ssv, every FMU) and the existing files
    # String parameters name (a rotor file): absolute paths, for sweep --resume (orchestrator.read_log)
    inputs: tuple[str, ...] = field(default=(), compare=False)
    # a scenario read from an SSP (``source`` the .ssp/.ssd, or the YAML naming it): the temporary folder
    # the archive was extracted into and its scenario generated in (the files it carries are there)
    extracted: Path | None = field(default=None, compare=False)

    def fmu(self, name: str) -> FmuSpec:
        for f in self.fmus:
            if f.name == name:
                return f
        raise KeyError(name)

