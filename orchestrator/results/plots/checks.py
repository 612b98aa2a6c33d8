"""Checks of what a run folder says about its analysis, before the plots use it.

A run folder may come from anyone: summary.json's analysis spec and result are kept
only in the parts that have the expected shape (journals a mapping of mappings,
clearances positive numbers, onset/vanish events with numeric times and speeds);
what is dropped is said in the plot's skip messages.
"""

from __future__ import annotations

from typing import Any, Mapping

import numpy as np


def _finite(x) -> bool:
    return isinstance(x, (int, float)) and not isinstance(x, bool) and bool(np.isfinite(x))


def checked_spec(spec: Mapping) -> tuple[dict, list[str]]:
    """The analysis spec with only well-formed parts kept, and what was dropped."""
    out: dict[str, Any] = {}
    problems = []
    for key in ("speed",):
        if spec.get(key) is not None:
            if isinstance(spec[key], str):
                out[key] = spec[key]
            else:
                problems.append(f"'{key}' is not a signal name (got {type(spec[key]).__name__})")
    if isinstance(spec.get("whirl"), Mapping):
        out["whirl"] = dict(spec["whirl"])
    if isinstance(spec.get("fields"), list) and all(isinstance(f, str) for f in spec["fields"]):
        out["fields"] = list(spec["fields"])
    journals = spec.get("journals")
    if journals is not None and not isinstance(journals, Mapping):
        problems.append(f"'journals' must be a mapping name -> {{x, y, eps, clearance}} (got "
                        f"{type(journals).__name__})")
        journals = {}
    out["journals"] = {}
    for name, js in (journals or {}).items():
        if not isinstance(js, Mapping):
            problems.append(f"journal '{name}' must be a mapping (got {type(js).__name__})")
            continue
        clean = {k: js[k] for k in ("x", "y", "eps") if isinstance(js.get(k), str)}
        c = js.get("clearance")
        if c is not None:
            if _finite(c) and c > 0:
                clean["clearance"] = float(c)
            else:
                problems.append(f"the clearance of journal '{name}' must be a positive number in m (got {c!r})")
        out["journals"][str(name)] = clean
    return out, problems


def _event_ok(ev) -> bool:
    return ev is None or (isinstance(ev, Mapping) and _finite(ev.get("time_s")) and _finite(ev.get("speed_hz")))


def checked_result(ana) -> tuple[dict | None, str | None]:
    """summary.json's analysis result if every part the plots read is well-formed (else None
    and the reason; None, None when there is none)."""
    if not isinstance(ana, Mapping) or "journals" not in ana:
        return None, None
    if not isinstance(ana["journals"], Mapping):
        return None, f"'journals' is {type(ana['journals']).__name__}, expected a mapping"
    for name, jr in ana["journals"].items():
        if not isinstance(jr, Mapping):
            return None, f"journal '{name}' is {type(jr).__name__}, expected a mapping"
        if not (_event_ok(jr.get("onset")) and _event_ok(jr.get("vanish"))):
            return None, f"the onset/vanish of journal '{name}' lack numeric time_s and speed_hz"
        if jr.get("clearance") is not None and not (_finite(jr["clearance"]) and jr["clearance"] > 0):
            return None, f"the clearance of journal '{name}' is not a positive number"
        if jr.get("time_resolution_s") is not None and not _finite(jr["time_resolution_s"]):
            return None, f"the time_resolution_s of journal '{name}' is not a number"
        eps = jr.get("episodes")
        if jr.get("onset") is not None and not (
                isinstance(eps, list) and eps and isinstance(eps[0], Mapping) and _finite(eps[0].get("onset_time_s"))
                and (eps[0].get("vanish_time_s") is None or _finite(eps[0]["vanish_time_s"]))):
            return None, f"the whirl episodes of journal '{name}' are malformed"
    return dict(ana), None
