"""Scenario sections of the coupling beyond explicit: ``coupling.iteration`` and ``coupling.step_control``.

Read by the section reader (scenario/sections.py) (``load_iteration`` / ``load_step_control`` take the
loader, whose ``mapping``/``number``/``integer``/``value``/``err`` report problems
with file and line). Format (docs/scenario-format.md)::

    coupling:
      scheme: iterative
      iteration: {max_iterations: 20, tol: 1.0e-8, acceleration: iqn-ils}   # none | aitken | iqn-ils
      # hold_jacobian: true (default) keeps interface-Jacobian coefficients out of the iteration
      step_control: {type: error, rtol: 1.0e-4, atol: 1.0e-8, min_step: 1.0e-6, max_step: 1.0e-2}
      # atol per signal: a mapping from coupling signals (the consumer's input, "instance.input")
      # or glob patterns of them to atol; .inf leaves a signal out of the estimate
      step_control: {type: error, atol: {"rotor.F*": 0.1, "bearing*.*": .inf, "*": 1.0e-8}}
      # error control from start_time to 0.06 s (on the output grid), then constant macro_step steps
      step_control: {type: error, rtol: 0.1, until: 0.06}
"""

from __future__ import annotations

import fnmatch
import logging
import math
from dataclasses import dataclass
from typing import Mapping

import yaml

from orchestrator.scenario.limits import MIN_MACRO_STEP, step_slack
from orchestrator.scenario.nodes import did_you_mean
from orchestrator.scenario.model import (
    ACCELERATIONS, ERROR_MEASURES, STEP_CONTROL_TYPES, CouplingSpec, IterationSpec, StepControlSpec)

ITERATION_KEYS = ("max_iterations", "tol", "acceleration", "hold_jacobian")
STEP_CONTROL_KEYS = ("type", "rtol", "atol", "min_step", "max_step", "interface_jacobian", "measure", "until")
ATOL_NODES = "_step_control_atol_nodes"     # loader attribute: pattern -> YAML node (check_atol_patterns)
MAX_ITERATIONS_LIMIT = 1000
log = logging.getLogger(__name__)


def load_iteration(ld, node) -> IterationSpec | None:
    section = ld.mapping(node, "coupling.iteration", ITERATION_KEYS,
                         fix="write e.g. 'iteration: {max_iterations: 20, tol: 1.0e-8, acceleration: iqn-ils}'")
    if section is None:
        return None
    kw: dict = {}
    ok = True
    if "max_iterations" in section:
        v = ld.integer(section["max_iterations"][1], "coupling.iteration.max_iterations", 1, MAX_ITERATIONS_LIMIT,
                       "give the most passes per macro step, e.g. 20")
        ok &= v is not None
        kw["max_iterations"] = v
    if "tol" in section:
        v = ld.number(section["tol"][1], "coupling.iteration.tol", positive=True,
                      fix="give the tolerance relative to each signal's scale, e.g. 1.0e-8")
        ok &= v is not None
        kw["tol"] = v
    if "acceleration" in section:
        n = section["acceleration"][1]
        v = ld.value(n) if isinstance(n, yaml.ScalarNode) else None
        if v not in ACCELERATIONS:
            ld.err(n, f"'coupling.iteration.acceleration' must be one of {list(ACCELERATIONS)} (got {ld.got(n)}); "
                      "iqn-ils converges on stiff couplings, none and aitken may not")
            ok = False
        kw["acceleration"] = v
    if "hold_jacobian" in section:
        n = section["hold_jacobian"][1]
        v = ld.value(n) if isinstance(n, yaml.ScalarNode) else None
        if not isinstance(v, bool):
            ld.err(n, f"'coupling.iteration.hold_jacobian' must be true or false (got {ld.got(n)}); true (default) "
                      "holds the interface-Jacobian coefficients (k.., c.. inputs) at their first iterate during a "
                      "step's passes, false iterates them with the other signals")
            ok = False
        kw["hold_jacobian"] = v
    return IterationSpec(**kw) if ok else None


def load_step_control(ld, node) -> StepControlSpec | None:
    section = ld.mapping(node, "coupling.step_control", STEP_CONTROL_KEYS,
                         fix="write e.g. 'step_control: {type: error, rtol: 1.0e-4, atol: 1.0e-8}'")
    if section is None:
        return None
    kw: dict = {}
    ok = True
    if "type" not in section:
        ld.err(node, f"'coupling.step_control' is missing the required key 'type'; add 'type: error' (or one of "
                     f"{list(STEP_CONTROL_TYPES)})")
        ok = False
    else:
        n = section["type"][1]
        v = ld.value(n) if isinstance(n, yaml.ScalarNode) else None
        if v not in STEP_CONTROL_TYPES:
            ld.err(n, f"'coupling.step_control.type' must be one of {list(STEP_CONTROL_TYPES)} (got {ld.got(n)}); "
                      "use error for an error-controlled macro step")
            ok = False
        kw["type"] = v
    if "atol" in section and isinstance(section["atol"][1], yaml.MappingNode):
        v = load_atol_mapping(ld, section["atol"][1])
        ok &= v is not None
        kw["atol"] = v
    if "measure" in section:
        n = section["measure"][1]
        v = ld.value(n) if isinstance(n, yaml.ScalarNode) else None
        if v not in ERROR_MEASURES:
            ld.err(n, f"'coupling.step_control.measure' must be one of {list(ERROR_MEASURES)} (got {ld.got(n)}); "
                      "value (default) takes the signals' defect as is, impulse weighs it by the step over the output interval")
            ok = False
        kw["measure"] = v
    if "interface_jacobian" in section:
        n = section["interface_jacobian"][1]
        v = ld.value(n) if isinstance(n, yaml.ScalarNode) else None
        if not isinstance(v, bool):
            ld.err(n, f"'coupling.step_control.interface_jacobian' must be true or false (got {ld.got(n)}); true "
                      "(default) estimates the error of the force an interface-Jacobian rotor applied")
            ok = False
        kw["interface_jacobian"] = v
    for key, fix in (("rtol", "e.g. 1.0e-4"), ("atol", "in the signals' units, e.g. 1.0e-8, or a mapping "
                                                        "{signal or pattern: atol}"),
                     ("min_step", "in seconds, e.g. 1.0e-7"), ("max_step", "in seconds, e.g. 1.0e-3")):
        if key == "atol" and "atol" in kw:
            continue
        if key in section:
            v = ld.number(section[key][1], f"coupling.step_control.{key}", positive=True, fix=f"give a number {fix}")
            if v is not None and key in ("min_step", "max_step") and v < MIN_MACRO_STEP:
                ld.err(section[key][1], f"'coupling.step_control.{key}' {v!r} s is below the smallest macro step, "
                                        f"{MIN_MACRO_STEP:g} s (1 fs); give a number {fix}")
                v = None
            ok &= v is not None
            kw[key] = v
    n = section["until"][1] if "until" in section else None
    if isinstance(n, yaml.ScalarNode) and ld.value(n) is None:
        kw["until"] = None           # until: null (--set coupling.step_control.until=null): to the end
    elif n is not None:
        v = ld.number(n, "coupling.step_control.until",
                      fix="give the time in seconds up to which the step is error-controlled, e.g. 0.06")
        if v is not None and kw.get("type") == "constant":
            ld.err(n, f"'coupling.step_control.until' ({v!r}) is for type error: the macro step is error-controlled "
                      "up to 'until' and constant (macro_step) after it; with type constant every step is "
                      "macro_step already: set type: error or remove until")
            v = None
        ok &= v is not None
        kw["until"] = v
    if ok and kw.get("min_step") is not None and kw.get("max_step") is not None and kw["min_step"] > kw["max_step"]:
        ld.err(section["min_step"][1], f"'coupling.step_control.min_step' ({kw['min_step']!r}) must not exceed "
                                       f"max_step ({kw['max_step']!r}); swap or change them")
        ok = False
    return StepControlSpec(**kw) if ok else None


def load_atol_mapping(ld, node) -> tuple | None:
    """``atol: {signal or glob pattern: atol}`` -> ((pattern, atol), ...) in file order.

    A value may be ``.inf`` (the signal is left out of the estimate); the patterns are
    checked against the connections later (:func:`check_atol_patterns`)."""
    section = ld.mapping(node, "coupling.step_control.atol",
                         fix="write e.g. 'atol: {\"rotor.F*\": 0.1, \"*\": 1.0e-8}'")
    if section is None:
        return None
    if not section:
        ld.err(node, "'coupling.step_control.atol' is an empty mapping; give at least one "
                     "'signal: atol' entry, e.g. '\"*\": 1.0e-8', or a single number")
        return None
    out, ok, nodes = [], True, getattr(ld, ATOL_NODES, None) or {}
    for key, (knode, vnode) in section.items():
        v = ld.value(vnode) if isinstance(vnode, yaml.ScalarNode) else None
        if v == float("inf"):
            out.append((key, float("inf")))
        else:
            v = ld.number(vnode, f"coupling.step_control.atol.{key}", positive=True,
                          fix="give the absolute tolerance in the signal's unit, or .inf to leave it out")
            if v is None:
                ok = False
                continue
            out.append((key, v))
        nodes[key] = knode
    setattr(ld, ATOL_NODES, nodes)
    return tuple(out) if ok else None


def check_atol_patterns(ld, coupling: dict | None, connections: list) -> None:
    """Every key of a per-signal ``atol`` must name (or match) a coupling signal, i.e. a
    connection's consumer input ``instance.input``; the message suggests the closest name."""
    sc = (coupling or {}).get("step_control")
    if sc is None or not isinstance(sc.atol, tuple):
        return
    names = sorted({str(c["to"]) for c in connections if c.get("to")})
    nodes = getattr(ld, ATOL_NODES, {})
    for pat, _ in sc.atol:
        if not any(fnmatch.fnmatchcase(n, pat) for n in names):
            ld.err(nodes.get(pat), f"'coupling.step_control.atol' key '{pat}' matches no coupling signal; "
                                   f"{did_you_mean(pat, names)}keys name a connection's input ('instance.input') or a glob "
                                   f"pattern of them, which are "
                                   f"{', '.join(names[:12])}{' ...' if len(names) > 12 else ''}")


def _grid_slack(k: float, t0: float, t_stop: float, interval: float) -> float:
    """How far (in output intervals) a time ``k`` intervals from t0 may be off the grid by rounding."""
    return max(1e-9 * max(1.0, abs(k)), step_slack(t0, t_stop, interval))


def until_reaches_stop(until: float, t0: float, t_stop: float, interval: float) -> bool:
    """Is ``step_control.until`` at or after ``t_stop`` (to rounding)? Then the whole run is
    error-controlled: the loader accepts it (:func:`until_problem`) and the master builds no
    constant part (coupling/adaptive.py ``controller_from_spec``)."""
    k = (until - t0) / interval
    return k >= (t_stop - t0) / interval - _grid_slack(k, t0, t_stop, interval)


def until_problem(spec, t0: float, t_stop: float, interval: float) -> str | None:
    """Why ``coupling.step_control.until`` (``spec.until``; None: not set) cannot be the time at which
    the error-controlled step hands over to constant steps, or None.

    It must lie after ``t0`` (start_time) and, when before ``t_stop`` (stop_time), on the output grid
    ``t0 + k * interval`` (``interval``: output.interval, or macro_step when that is not given): the
    constant steps after it are ``until + n * macro_step`` and write a row every ``interval`` from
    ``until``, which are the output times only when ``until`` is one. At or after ``t_stop`` it is
    allowed: the whole run is error-controlled (a run shortened with ``--set stop_time=...`` keeps
    working). The message names the nearest valid values. The one rule for the loader
    (:func:`check_until`, at the key's line) and ``rotorcosim compare``
    (orchestrator/compare/capabilities.py, per variant)."""
    until = getattr(spec, "until", None)
    if until is None:
        return None
    if getattr(spec, "type", "error") != "error":
        return (f"'coupling.step_control.until' ({until!r}) is for type error: the macro step is error-controlled "
                "up to 'until' and constant (macro_step) after it; set type: error or remove until")
    if not (isinstance(until, (int, float)) and not isinstance(until, bool) and math.isfinite(until)):
        return f"'coupling.step_control.until' must be a time in seconds (got {until!r}); e.g. 0.06"
    if not (t_stop > t0 and interval and interval > 0):
        return None                              # the times themselves are reported
    if until_reaches_stop(until, t0, t_stop, interval):
        return None                              # at or after stop_time: error-controlled to the end
    k = (until - t0) / interval
    n_out = (t_stop - t0) / interval                         # output intervals in the run
    slack = _grid_slack(k, t0, t_stop, interval)
    j = round(k)
    on_grid = abs(k - j) <= slack
    last_j = math.ceil(n_out - slack) - 1                   # the last output time before stop_time
    if last_j < 1 and until > t0:
        return (f"'coupling.step_control.until' ({until!r}) must be an output time after start_time ({t0!r}) and "
                f"before stop_time ({t_stop!r}), but the run is one output interval ({interval!r} s) long; remove "
                "until (the whole run is error-controlled) or write rows more often (output.interval)")
    if not (t0 < until < t_stop) or (on_grid and not 0 < j <= last_j):
        near = t0 + max(1, 1 if until <= t0 + 0.5 * interval else last_j) * interval
        return (f"'coupling.step_control.until' must lie after start_time ({t0!r}) (got {until!r}); give the time "
                f"up to which the step is error-controlled, an output time in "
                f"{t0 + interval:.12g}..{t0 + max(1, last_j) * interval:.12g}, e.g. {near:.12g} (at or after "
                f"stop_time ({t_stop!r}) the whole run is error-controlled)")
    if not on_grid:
        near = [t0 + i * interval for i in (math.floor(k), math.ceil(k)) if 0 < i <= last_j]
        return (f"'coupling.step_control.until' ({until!r}) is not on the output grid start_time + k * "
                f"output.interval ({t0!r} + k * {interval!r}): the constant steps after it write a row every "
                f"output interval from 'until', which would miss the grid; use "
                + " or ".join(f"{t:.12g}" for t in near))
    return None


def check_until(ld, node, coupling: dict | None, t0, t_stop, interval) -> None:
    """:func:`until_problem` of the loader's coupling mapping, reported at the line of ``until``
    (``node``: the coupling section's node)."""
    sc = (coupling or {}).get("step_control")
    if sc is None or getattr(sc, "until", None) is None or not isinstance(t0, float) or not isinstance(t_stop, float):
        return
    why = until_problem(sc, t0, t_stop, interval or coupling.get("macro_step") or CouplingSpec.macro_step)
    if why:
        at, then = value_place(ld, node, ("step_control", "until"), ("step_control",))
        ld.err(at, why + then)


def _entry(node, keys: tuple[str, ...]):
    """(key node, value node) of the value at ``keys`` under the mapping ``node``, or None."""
    key_node = None
    for key in keys:
        if not isinstance(node, yaml.MappingNode):
            return None
        found = next(((k, v) for k, v in node.value if isinstance(k, yaml.ScalarNode) and k.value == key), None)
        if found is None:
            return None
        key_node, node = found
    return key_node, node


def value_place(ld, node, *paths: tuple[str, ...]) -> tuple:
    """Where a problem caused by the values at ``paths`` (key tuples under the mapping ``node``,
    in order of preference) is reported, and the text that follows the message: the first of
    those values that came from ``--set`` (or a sweep axis, which is one), followed by the
    scenario's own line of its key (``(the scenario's line: s.yaml:10)``, or of ``node`` when the
    file does not have the key: ``(the scenario: s.yaml:9)``); else the first of them in the file; else
    ``node`` itself.

    ``node`` alone was the place before: a sweep over ``coupling.scheme`` that included
    ``iterative`` for FMUs without state saving was reported at the scenario's ``coupling:``
    line, and a macro step off the grid of a fixed-step FMU at the scenario's first line,
    which the user need not change, not at the sweep's axis (orchestrator/sweep/plan.py
    places problems that start with ``--set path=``)."""
    origins = getattr(ld, "origins", {})
    found = [e for e in (_entry(node, p) for p in paths) if e is not None]
    for key_node, at in found:
        if id(at) in origins:
            for there, what in ((key_node, "the scenario's line"), (node, "the scenario")):
                if there is not None and id(there) not in origins and getattr(there, "start_mark", None) is not None:
                    return at, f" ({what}: {ld.loc(there)})"
            return at, ""
    return (found[0][1] if found else node), ""


@dataclass(frozen=True)
class CapabilityIssue:
    """One thing a coupling needs that its FMUs cannot do (:func:`capability_issues`)."""

    text: str                               # what the coupling needs, which FMUs lack it, the fix
    paths: tuple[tuple[str, ...], ...]      # coupling keys that cause it, in order of preference (value_place)
    warning: bool = False                   # True: the run goes on (the step adapts forward only)


def capability_issues(coupling: Mapping, mds: Mapping) -> list[CapabilityIssue]:
    """The FMU capability flags the chosen coupling needs (``coupling``: the loader's coupling
    mapping, ``scheme``/``step_control``/``discard_retries``/``defect_retries``; ``mds``: instance -> model
    description).

    ``scheme: iterative`` needs canGetAndSetFMUstate in every FMU (an error), and so does
    ``discard_retries`` > 0 (an error; with ``step_control: {type: error}`` and no ``until`` it is
    refused whatever the FMUs, as the master does: the error-controlled step has its own rejection;
    with ``until`` it acts on the constant steps after it), and so does ``defect_retries`` > 0 (also
    refused with the error-controlled step without ``until`` and with the iterative scheme);
    ``step_control: error`` needs canHandleVariableCommunicationStepSize (an error) and,
    to reject steps, canGetAndSetFMUstate (without it the step adapts forward only: a warning,
    which ``rotorcosim validate`` prints).

    The one set of these rules: the scenario loader (:func:`check_capabilities`, which places
    each at its line) and ``rotorcosim compare`` (orchestrator/compare/capabilities.py, per
    variant) both call it. Fixed-step FMUs' grid: ``completion.fixed_step_problem``.
    """
    out: list[CapabilityIssue] = []
    stateless = [n for n, md in mds.items() if not md.can_get_and_set_fmu_state]
    if coupling.get("scheme") == "iterative" and stateless:
        out.append(CapabilityIssue(
            f"'coupling.scheme: iterative' repeats every macro step from saved FMU states, but "
            f"{', '.join(map(repr, stateless))} cannot save them (canGetAndSetFMUstate is false); use "
            f"gauss-seidel or jacobi, or FMUs built with state support", (("scheme",),)))
    sc = coupling.get("step_control")
    # refused by the master when the run starts (coupling/adaptive.py, coupling/execution.py): a
    # sweep over discard_retries validated, then every such run failed with no line of the sweep
    for key, why in (("discard_retries", "the error-controlled step has its own rejection"),
                     ("defect_retries", "the error-controlled step rejects steps on its own estimate of the same "
                                        "defect")):
        n = coupling.get(key, 0) or 0
        if not n or coupling.get("scheme") == "monolithic":
            continue
        if sc is not None and sc.type == "error" and getattr(sc, "until", None) is None:
            # with until they act on the constant steps after it (coupling/adaptive.py, ErrorThenConstant)
            out.append(CapabilityIssue(
                f"coupling.step_control type error and coupling.{key} cannot be combined ({why}); set {key}: 0, "
                f"or give step_control.until (the time after which constant steps, with {key}, take over)",
                ((key,), ("step_control", "type"), ("step_control",))))
        elif key == "defect_retries" and coupling.get("scheme") == "iterative":
            out.append(CapabilityIssue(
                "coupling.defect_retries redoes the steps of gauss-seidel and jacobi whose coupling defect is over "
                "coupling.defect_limit; the iterative scheme iterates every step to its tolerance instead; set "
                "defect_retries: 0 or use scheme gauss-seidel", ((key,), ("scheme",))))
        elif stateless:
            out.append(CapabilityIssue(
                f"coupling.{key} = {n} needs every FMU to save and restore its state "
                f"(canGetAndSetFMUstate=\"true\"), but {', '.join(map(repr, stateless))} cannot (got "
                f"canGetAndSetFMUstate false); set coupling.{key}: 0 or use an FMU built with "
                "state support", ((key,),)))
    if sc is None or sc.type != "error":
        return out
    fixed = [n for n, md in mds.items() if not md.can_handle_variable_step]
    if fixed:
        out.append(CapabilityIssue(
            f"'coupling.step_control: {{type: error}}' varies the macro step, but "
            f"{', '.join(map(repr, fixed))} cannot take varying steps "
            f"(canHandleVariableCommunicationStepSize is false); use type: constant",
            (("step_control", "type"), ("step_control",))))
    elif stateless:
        out.append(CapabilityIssue(
            f"'coupling.step_control: {{type: error}}': {', '.join(map(repr, stateless))} cannot save "
            "and restore its state (canGetAndSetFMUstate is false), so no step can be rejected and "
            "redone: the macro step only adapts forward (the next step follows the error of the last)",
            (("step_control", "type"), ("step_control",)), warning=True))
    return out


def check_capabilities(ld, node, coupling: dict, mds: dict) -> None:
    """:func:`capability_issues` of ``coupling`` reported by the loader ``ld``: an error at the
    line of the key that causes it (:func:`value_place`), a warning logged with that place."""
    if coupling is None:
        return
    for issue in capability_issues(coupling, mds):
        at, then = value_place(ld, node, *issue.paths)
        if issue.warning:
            log.warning("%s: %s%s", ld.loc(at), issue.text, then)
        else:
            ld.err(at, issue.text + then)


def interpolated_inputs(scheme: str, k: int, q: int, sequence, connections) -> list[str]:
    """The consumer inputs whose order ``interpolation_order`` q < ``extrapolation_order`` k
    limits (a Gauss-Seidel run, docs/coupling.md "One macro step"): the Real connections
    ``(from, to)`` ("instance.variable") from an FMU stepped earlier in ``sequence`` to one
    stepped later get the degree-q polynomial through their new values, so the coupling is of
    order q + 1 at most, not k + 1. [] when that does not apply.

    Found with two crane-fmu oscillators in a loop: Gauss-Seidel k = 1 and 2 with the default
    q = 0 gave order 1.07 and 1.08, worse than Jacobi k = 1 (order 2), which reads as "Jacobi
    is the better scheme"; with q = k Gauss-Seidel is the more accurate one (docs/coupling.md)."""
    if scheme != "gauss-seidel" or not k or q >= k:
        return []
    pos = {name: i for i, name in enumerate(sequence)}
    out = []
    for src, dst in connections:
        a, b = src.split(".", 1)[0], dst.split(".", 1)[0]
        if a in pos and b in pos and pos[a] < pos[b]:
            out.append(dst)
    return out


def interpolation_warning(k: int, q: int, inputs: list[str]) -> str:
    """The text of the loader's warning about :func:`interpolated_inputs`."""
    shown = ", ".join(inputs[:4]) + (f" and {len(inputs) - 4} more" if len(inputs) > 4 else "")
    verb = "comes from an FMU" if len(inputs) == 1 else "come from FMUs"
    return (f"'coupling.interpolation_order' {q} with extrapolation_order {k} under gauss-seidel: {shown} {verb} "
            f"stepped earlier in the sequence and get{'s' if len(inputs) == 1 else ''} a degree-{q} polynomial "
            f"through the new values, so the coupling is of order {q + 1} at most, not up to {k + 1}; set "
            f"interpolation_order: {k} (docs/coupling.md, \"One macro step\")")
