"""The units of a sweep's axes and collected values, and the names of a switch's values, for
the map's labels (``sweep.json``).

A parameter that sets an FMU parameter (``fmus.<instance>.parameters.<name>``) takes the unit
the FMU's modelDescription gives that variable (``psi`` -> ``1``, ``eta0`` -> ``Pa.s``); the
scenario's own times and clearances are in s and m. A collected value takes the unit the
summary.json path implies (``..._hz`` -> Hz, ``max_eps`` -> relative to c, ``end_time`` -> s)
or, for ``output.final.<instance>.<variable>``, that variable's unit. Anything else has no unit
(the label is the name alone). Best effort: a unit that cannot be found is left out, never an error.

A parameter that sets an Integer switch (or an Enumeration) of an FMU takes the names the FMU
declares for its values (:func:`orchestrator.fmi.model_description.value_names`: for our
bearing's ``cavitation`` ``{0: "half-Sommerfeld", 1: "mass-conserving"}``), so that the map's
axis reads ``half-Sommerfeld (0)``; every path of the parameter must give the same names. An
FMU that declares none (or a malformed list) gives none: its axis keeps the numbers.
"""

from __future__ import annotations

import re

__all__ = ["sweep_units", "sweep_labels", "MAX_UNIT_CHARS"]

MAX_UNIT_CHARS = 24                   # a longer unit text in sweep.json is not drawn
_SCENARIO_UNITS = {"stop_time": "s", "start_time": "s", "coupling.macro_step": "s", "output.interval": "s"}
_FMU_PARAMETER = re.compile(r"fmus\.([^.]+)\.parameters\.(.+)")
_SUMMARY_UNITS = [(re.compile(r"(^|\.)end_time$"), "s"), (re.compile(r"_hz$"), "Hz"),
                  (re.compile(r"(^|\.)(max_eps|eps\w*|dominant_ratio|max_subsync_rel)$"), "1"),
                  (re.compile(r"(^|\.)clearance$"), "m")]


def _variable(scenario, instance: str, name: str):
    """The Variable ``name`` of the FMU of ``instance`` (its modelDescription), or None."""
    from orchestrator.fmi.archive import cached_model_description
    for f in scenario.fmus:
        if f.name == instance:
            return cached_model_description(f.path).variables.get(name)
    return None


def _variable_unit(scenario, instance: str, name: str) -> str | None:
    var = _variable(scenario, instance, name)
    return (var.unit or None) if var is not None else None


def _path_value_names(scenario, path: str) -> dict[int, str]:
    from orchestrator.fmi.model_description import value_names
    m = _FMU_PARAMETER.fullmatch(path)
    var = _variable(scenario, m.group(1), m.group(2)) if m else None
    return value_names(var) if var is not None else {}


def _path_unit(scenario, path: str) -> str | None:
    if path in _SCENARIO_UNITS:
        return _SCENARIO_UNITS[path]
    m = _FMU_PARAMETER.fullmatch(path)
    if m:
        return _variable_unit(scenario, m.group(1), m.group(2))
    if re.fullmatch(r"analysis\.journals\.[^.]+\.clearance", path):
        return "m"
    return None


def _collect_unit(scenario, path: str) -> str | None:
    m = re.fullmatch(r"output\.final\.([^.]+)\.(.+)", path)
    if m:
        return _variable_unit(scenario, m.group(1), re.sub(r"\[\d+\]$", "", m.group(2)))
    for pattern, unit in _SUMMARY_UNITS:
        if pattern.search(path):
            return unit
    return None


def sweep_units(spec, overrides) -> tuple[dict[str, str], dict[str, str]]:
    """``({parameter: unit}, {collected column: unit})`` of ``spec`` (:func:`sweep_labels`)."""
    params, collect, _ = sweep_labels(spec, overrides)
    return params, collect


def sweep_labels(spec, overrides) -> tuple[dict[str, str], dict[str, str], dict[str, dict[int, str]]]:
    """``({parameter: unit}, {collected column: unit}, {parameter: {value: name}})`` of ``spec``,
    with the scenario loaded with one run's ``overrides`` (its FMUs' modelDescriptions); only
    the units and names found, and nothing when the scenario cannot be loaded now."""
    from orchestrator import load_scenario
    try:
        scenario = load_scenario(spec.scenario, list(overrides), build_fmus=False)
    except Exception:                         # noqa: BLE001 - labels only; the runs report their own problems
        return {}, {}, {}
    params, collect, names = {}, {}, {}
    for p in spec.parameters:
        try:
            found = {_path_unit(scenario, path) for path in p.paths}
        except Exception:                     # noqa: BLE001 - an unreadable modelDescription: no unit
            found = {None}
        if len(found) == 1 and None not in found:
            params[p.name] = found.pop()
        try:
            named = [_path_value_names(scenario, path) for path in p.paths]
        except Exception:                     # noqa: BLE001 - an unreadable modelDescription: no names
            named = [{}]
        if named and named[0] and all(n == named[0] for n in named):
            names[p.name] = named[0]
    for name, path in spec.collect:
        try:
            unit = _collect_unit(scenario, path)
        except Exception:                     # noqa: BLE001
            continue
        if unit:
            collect[name] = unit
    return params, collect, names
