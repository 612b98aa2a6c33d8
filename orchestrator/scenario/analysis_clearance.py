"""The run-up analysis's clearance against the bearing it analyses.

Every amplitude of the whirl analysis (the onset threshold of 5 % of the clearance, the
growth-rate band, ``max_subsync_rel``, the orbit plots) is relative to
``analysis.journals.<name>.clearance``. The scenario gives that number separately from the
bearing's ``R`` and ``psi``, so a scenario copied from a shipped one and given other bearings
(or a sweep over ``psi`` that does not also set the clearance) analysed every run with the
shipped clearance: the run was right, its onset speed silently wrong. This check finds the
bearing of each journal - our ``JournalBearing`` whose input ``x`` is connected from the
journal's ``x`` signal, else the instance of its ``eps`` signal - and

* when ``clearance`` is given, requires it to be ``psi R`` within ``CLEARANCE_RTOL``;
* when it is left out, fills in ``psi R`` (instead of estimating it from ``eps`` after the run).

Third-party bearings and our floating-ring bearing (whose journal moves in two clearances) are
not checked: there the clearance stays the user's choice.
"""

from __future__ import annotations

import math

import yaml

CLEARANCE_RTOL = 0.01      # written clearances are rounded (1.372e-5 for 2.8e-3 x 4.9e-3 m)
BEARING_MODEL = "JournalBearing"


def _child(node, key: str):
    """The value node of ``key`` in a mapping node (None when absent or not a mapping)."""
    if not isinstance(node, yaml.MappingNode):
        return None
    for k, v in node.value:
        if isinstance(k, yaml.ScalarNode) and k.value == key:
            return v
    return None


def _bearing_of(journal: dict, connections: list, caps: dict) -> tuple[str, str] | None:
    """(instance, how it was found) of the JournalBearing a journal's signals belong to."""
    x = journal.get("x")
    for c in connections:
        to = c.get("to") or ""
        inst, _, var = to.partition(".")
        if (c.get("from") == x and var == "x" and inst in caps and caps[inst].model_name == BEARING_MODEL
                and c.get("gain", 1.0) == 1.0 and c.get("offset", 0.0) == 0.0):
            return inst, f"its input x is connected from {x}"
    eps = journal.get("eps")
    if isinstance(eps, str) and "." in eps:
        inst = eps.partition(".")[0]
        if inst in caps and caps[inst].model_name == BEARING_MODEL:
            return inst, f"the journal's eps signal is {eps}"
    return None


def parameter_value(inst: str, name: str, params: dict, mds: dict):
    """A Real parameter's value as the run will have it: the scenario's, else the FMU's start."""
    v = params.get(inst, {}).get(name)
    if v is None:
        var = mds.get(inst, {}).get(name)
        v = None if var is None else var.start
    return float(v) if isinstance(v, (int, float)) and not isinstance(v, bool) else None


def check_analysis_clearance(loader, draft, params: dict) -> None:
    """Check (or fill in) each journal's clearance against its JournalBearing's ``psi R``;
    problems go to ``loader.err`` at the line of the clearance (or of the journal)."""
    analysis = draft.kw.get("analysis")
    journals = analysis.get("journals") if isinstance(analysis, dict) else None
    if not isinstance(journals, dict):
        return
    jnodes = _child(draft.analysis_node, "journals")
    for jname, journal in journals.items():
        if not isinstance(journal, dict):
            continue
        found = _bearing_of(journal, draft.connections, loader.fmu_caps)
        if found is None:
            continue
        inst, how = found
        raw = next((f.get("parameters") for f in draft.fmus if f.get("name") == inst), None)
        if isinstance(raw, dict) and any(n in raw and n not in params.get(inst, {}) for n in ("R", "psi")):
            continue               # refused by the parameter checks (e.g. outside its range): not the FMU's start
        R, psi = parameter_value(inst, "R", params, loader.mds), parameter_value(inst, "psi", params, loader.mds)
        if R is None or psi is None or not (R > 0 and psi > 0):
            continue                                   # the parameter checks report bad values
        c = psi * R
        given = journal.get("clearance")
        jnode = _child(jnodes, jname)
        if not c > 0.0:     # R = 5e-324 is in the FMU's range (0, inf), psi R underflows: was ZeroDivisionError
            loader.err(_child(jnode, "clearance") or jnode or draft.analysis_node,
                       f"'analysis.journals.{jname}' analyses '{inst}', whose radial clearance c = psi R = {psi:g} x "
                       f"{R:g} m is 0 in floating point; the analysis divides by it: give '{inst}' a journal radius "
                       "R in m (e.g. 0.02 for 20 mm)")
            continue
        if given is None:
            journal["clearance"] = c                   # before the run: not estimated from eps after it
            continue
        if isinstance(given, bool) or not isinstance(given, (int, float)) or not given > 0:
            continue                                   # check_analysis reports it
        if not math.isclose(given, c, rel_tol=CLEARANCE_RTOL):
            if not getattr(loader, "analysis_used", True):
                journal["clearance"] = c               # e.g. `stability`: no analysis is run with it
                continue
            node = _child(jnode, "clearance") or jnode or draft.analysis_node
            sets = _overrides_of(inst, getattr(loader, "overrides", ()))
            hint = (f"; {' and '.join(sets)} changed it: add --set analysis.journals.{jname}.clearance={c:.6g}"
                    if sets else "")
            loader.err(node, f"'analysis.journals.{jname}.clearance' is {given:g} m, but the bearing it "
                             f"analyses, '{inst}' ({how}), has the radial clearance c = psi R = {psi:g} x "
                             f"{R:g} m = {c:.6g} m ({given / c:.3g} times that); the whirl threshold and "
                             "every amplitude of the analysis are relative to this number, so the onset "
                             f"would be wrong; write clearance: {c:.6g}, or leave 'clearance' out and it is "
                             f"taken from '{inst}' (a sweep over psi or R then needs no clearance column)" + hint)


def _overrides_of(inst: str, overrides) -> list[str]:
    """The ``--set fmus.<inst>.parameters.psi=...`` / ``R`` overrides among ``overrides``, as written."""
    found = []
    for text in overrides:
        key, sep, value = str(text).partition("=")
        if sep and key.strip() in (f"fmus.{inst}.parameters.psi", f"fmus.{inst}.parameters.R"):
            found.append(f"--set {key.strip()}={value.strip()}")
    return found
