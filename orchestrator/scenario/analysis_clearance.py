"""The run-up analysis's clearance against the bearing it analyses.

Every amplitude of the whirl analysis (the onset threshold of 5 % of the clearance, the
growth-rate band, ``max_subsync_rel``, the orbit plots) is relative to
``analysis.journals.<name>.clearance``. The scenario gives that number separately from the
bearing's ``R`` and ``psi``, so a scenario copied from a shipped one and given other bearings
(or a sweep over ``psi`` that does not also set the clearance) analysed every run with the
shipped clearance: the run was right, its onset speed silently wrong. The bearing of each
journal is our ``JournalBearing`` whose input ``x`` is connected from the journal's ``x``
signal, else the instance of its ``eps`` signal. Two steps, at two depths:

* loading (:func:`complete_analysis_clearance`, for every consumer): a left-out ``clearance`` is
  filled in as ``psi R`` (instead of estimated from ``eps`` after the run);
* planning the analysis (:func:`check_analysis_clearance`: ``run``, ``validate``, a sweep's
  planning, ``compare``, ``export-ssp``; not ``stability``, which does not use it): a given
  ``clearance`` must be ``psi R`` within ``CLEARANCE_RTOL``. Its message names the place the
  loader recorded (:attr:`Scenario.analysis_origins`) and the ``--set`` of ``psi`` or ``R`` that
  changed the bearing (:attr:`FmuSpec.parameter_origins`).

Third-party bearings and our floating-ring bearing (whose journal moves in two clearances) are
not checked: there the clearance stays the user's choice.
"""

from __future__ import annotations

import math
from typing import Callable, Iterable, Mapping

import yaml

from orchestrator.errors import CosimError, ScenarioError

CLEARANCE_RTOL = 0.01      # written clearances are rounded (1.372e-5 for 2.8e-3 x 4.9e-3 m)
BEARING_MODEL = "JournalBearing"


def _bearing_of(journal: dict, links: Iterable[tuple], model_of: Callable[[str], str | None]) -> tuple[str, str] | None:
    """(instance, how it was found) of the JournalBearing a journal's signals belong to; ``links``:
    the connections as ``(from, to, gain, offset)``, ``model_of``: an instance's model name."""
    x = journal.get("x")
    for src, to, gain, offset in links:
        inst, _, var = (to or "").partition(".")
        if src == x and var == "x" and gain == 1.0 and offset == 0.0 and model_of(inst) == BEARING_MODEL:
            return inst, f"its input x is connected from {x}"
    eps = journal.get("eps")
    if isinstance(eps, str) and "." in eps:
        inst = eps.partition(".")[0]
        if model_of(inst) == BEARING_MODEL:
            return inst, f"the journal's eps signal is {eps}"
    return None


def parameter_value(inst: str, name: str, params: dict, mds: dict):
    """A Real parameter's value as the run will have it: the scenario's, else the FMU's start."""
    v = params.get(inst, {}).get(name)
    if v is None:
        var = mds.get(inst, {}).get(name)
        v = None if var is None else var.start
    return float(v) if isinstance(v, (int, float)) and not isinstance(v, bool) else None


def complete_analysis_clearance(loader, draft, params: dict) -> None:
    """Fill in each left-out journal clearance as its JournalBearing's ``psi R`` (a clearance
    that is 0 in floating point goes to ``loader.err``); a given one is checked where the
    analysis is planned (:func:`check_analysis_clearance`)."""
    analysis = draft.kw.get("analysis")
    journals = analysis.get("journals") if isinstance(analysis, dict) else None
    if not isinstance(journals, dict):
        return
    links = [(c.get("from"), c.get("to"), c.get("gain", 1.0), c.get("offset", 0.0)) for c in draft.connections]
    caps = loader.fmu_caps
    jnodes = _child(draft.analysis_node, "journals")
    for jname, journal in journals.items():
        if not isinstance(journal, dict):
            continue
        found = _bearing_of(journal, links, lambda i: caps[i].model_name if i in caps else None)
        if found is None:
            continue
        inst = found[0]
        raw = next((f.get("parameters") for f in draft.fmus if f.get("name") == inst), None)
        if isinstance(raw, dict) and any(n in raw and n not in params.get(inst, {}) for n in ("R", "psi")):
            continue               # refused by the parameter checks (e.g. outside its range): not the FMU's start
        R, psi = parameter_value(inst, "R", params, loader.mds), parameter_value(inst, "psi", params, loader.mds)
        if R is None or psi is None or not (R > 0 and psi > 0):
            continue                                   # the parameter checks report bad values
        c = psi * R
        jnode = _child(jnodes, jname)
        if not c > 0.0:     # R = 5e-324 is in the FMU's range (0, inf), psi R underflows: was ZeroDivisionError
            loader.err(_child(jnode, "clearance") or jnode or draft.analysis_node,
                       f"'analysis.journals.{jname}' analyses '{inst}', whose radial clearance c = psi R = {psi:g} x "
                       f"{R:g} m is 0 in floating point; the analysis divides by it: give '{inst}' a journal radius "
                       "R in m (e.g. 0.02 for 20 mm)")
            continue
        if journal.get("clearance") is None:
            journal["clearance"] = c                   # before the run: not estimated from eps after it


def check_analysis_clearance(scenario) -> None:
    """Refuse a scenario whose run-up analysis would measure a journal against another clearance
    than its JournalBearing's ``psi R``: :class:`ScenarioError` with one problem per journal, at the
    line of its clearance (or of the journal). For the callers that run the analysis, after loading."""
    from orchestrator.scenario.nodes import line_order
    problems = analysis_clearance_problems(scenario)
    if problems:
        raise ScenarioError(sorted(problems, key=line_order))


def analysis_clearance_problems(scenario) -> list[str]:
    """The problems :func:`check_analysis_clearance` raises, as ``place: text`` lines."""
    analysis = scenario.analysis                      # a Mapping when the scenario is made in Python
    journals = analysis.get("journals") if isinstance(analysis, Mapping) else None
    if not isinstance(journals, Mapping):
        return []
    specs = {f.name: f for f in scenario.fmus}
    mds: dict = {}

    def model_of(inst: str) -> str | None:
        if inst not in specs:
            return None
        if inst not in mds:
            from orchestrator.fmi.archive import cached_model_description
            try:
                mds[inst] = cached_model_description(specs[inst].path)
            except CosimError:                          # the run reports an unreadable FMU itself
                mds[inst] = None
        return getattr(mds[inst], "model_name", None)

    links = [(c.src, c.dst, c.gain, c.offset) for c in scenario.connections]
    origins = scenario.analysis_origins
    problems = []
    for jname, journal in journals.items():
        given = journal.get("clearance") if isinstance(journal, Mapping) else None
        if isinstance(given, bool) or not isinstance(given, (int, float)) or not given > 0:
            continue                                   # the loader reports it (or fills it in)
        found = _bearing_of(journal, links, model_of)
        if found is None:
            continue
        inst, how = found
        spec = specs[inst]
        variables = {inst: mds[inst].variables}
        R = parameter_value(inst, "R", {inst: spec.parameters}, variables)
        psi = parameter_value(inst, "psi", {inst: spec.parameters}, variables)
        if R is None or psi is None or not (R > 0 and psi > 0) or not psi * R > 0.0:
            continue                                   # the loader reports bad values
        c = psi * R
        if math.isclose(given, c, rel_tol=CLEARANCE_RTOL):
            continue
        key = f"analysis.journals.{jname}"
        place = (origins.get(f"{key}.clearance") or origins.get(key) or origins.get("analysis")
                 or str(scenario.source or scenario.name))
        sets = [o for n, o in spec.parameter_origins.items() if n in ("R", "psi") and o.startswith("--set ")]
        hint = (f"; {' and '.join(sets)} changed it: add --set analysis.journals.{jname}.clearance={c:.6g}"
                if sets else "")
        problems.append(f"{place}: 'analysis.journals.{jname}.clearance' is {given:g} m, but the bearing it "
                        f"analyses, '{inst}' ({how}), has the radial clearance c = psi R = {psi:g} x "
                        f"{R:g} m = {c:.6g} m ({given / c:.3g} times that); the whirl threshold and "
                        "every amplitude of the analysis are relative to this number, so the onset "
                        f"would be wrong; write clearance: {c:.6g}, or leave 'clearance' out and it is "
                        f"taken from '{inst}' (a sweep over psi or R then needs no clearance column)" + hint)
    return problems


def _child(node, key: str):
    """The value node of ``key`` in a mapping node (None when absent or not a mapping)."""
    if not isinstance(node, yaml.MappingNode):
        return None
    for k, v in node.value:
        if isinstance(k, yaml.ScalarNode) and k.value == key:
            return v
    return None
