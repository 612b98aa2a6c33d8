"""Metrics, order fit, checks, baseline and report files of ``rotorcosim compare``.

Definitions (also in ``docs/compare.md``). For a signal with reference values
``r_k`` on the reference output grid ``t_k`` (k = 0..N) and a variant ``v``
linearly interpolated onto that grid (exact when the grids coincide, which
:mod:`orchestrator.compare` arranges), with the scale ``S`` (given per signal,
else the peak ``max_k |r_k|`` of the reference):

* ``max`` = ``max_k |v_k - r_k| / S``
* ``rms`` = ``sqrt(mean_k (v_k - r_k)^2) / S``
* ``end`` = ``|v_N - r_N| / S``

The error of a variant is the worst over its signals. A derived quantity (a
number from ``summary.json``, e.g. the whirl-onset speed of
``orchestrator.results.whirl``) has the error ``|d_v - d_r| / S`` with ``S`` given or
``|d_r|``; when the key is null in both runs (e.g. no whirl onset in either)
the error is 0, when it is missing or null in only one it is infinite. A variant
that ends before the reference or produces non-finite values has infinite error.
"""

from __future__ import annotations

import json
import math
import os
import platform
import stat
from dataclasses import dataclass, field
from datetime import datetime, timezone
from pathlib import Path
from typing import Any, Mapping

import numpy as np

from orchestrator.results.run_directory import RunDirectory

METRICS = ("max", "rms", "end")
BASELINE_VERSION = 1


@dataclass
class RunData:
    """The files of one run, read back."""

    ok: bool
    message: str
    t: np.ndarray = field(default_factory=lambda: np.zeros(0))
    outputs: dict[str, np.ndarray] = field(default_factory=dict)
    summary: dict[str, Any] = field(default_factory=dict)
    wall_time_s: float = math.nan
    macro_steps: int | None = None
    fmu_calls: int | None = None


def read_run(run_dir: Path, job: Mapping[str, Any]) -> RunData:
    """Read ``results.csv`` and ``summary.json`` of a run (files of the public contract)."""
    run_dir = Path(run_dir)
    wall = job.get("wall_time_s", math.nan)
    if job.get("error"):
        return RunData(ok=False, message=job["error"], wall_time_s=wall)
    run = RunDirectory(run_dir)
    try:
        summary = run.summary()
    except (OSError, ValueError) as exc:
        return RunData(ok=False, message=f"no readable summary.json in {run_dir}: {exc}", wall_time_s=wall)
    try:
        cols = run.columns()
        t = cols.pop("time")
    except (OSError, ValueError, KeyError) as exc:
        return RunData(ok=False, message=f"no readable results.csv in {run_dir}: {exc}",
                       summary=summary, wall_time_s=wall)
    calls = summary.get("fmu_calls") or {}
    n_calls = sum(int(n) for per in calls.values() if isinstance(per, dict)
                  for n in per.values() if isinstance(n, (int, float)))
    status = summary.get("status", "failed")
    return RunData(ok=status == "finished", message=str(summary.get("message", "")),
                   t=t, outputs=cols,
                   summary=summary, wall_time_s=float(summary.get("wall_time_s", wall)),
                   macro_steps=summary.get("macro_steps"), fmu_calls=n_calls if calls else None)


def signal_errors(t_ref: np.ndarray, r: np.ndarray, t: np.ndarray, v: np.ndarray,
                  scale: float) -> dict[str, float]:
    """``max``, ``rms``, ``end`` errors of ``v(t)`` against ``r(t_ref)``, divided by ``scale``."""
    t_ref, r, t, v = (np.asarray(a, dtype=float) for a in (t_ref, r, t, v))
    if t.size == 0 or t[-1] < t_ref[-1] - 1e-9 * max(1.0, abs(t_ref[-1])) or t[0] > t_ref[0] + 1e-12:
        return {m: math.inf for m in METRICS}
    vi = np.interp(t_ref, t, v)
    d = np.abs(vi - r)
    if not np.all(np.isfinite(d)):
        return {m: math.inf for m in METRICS}
    return {"max": float(d.max() / scale), "rms": float(np.sqrt(np.mean(d * d)) / scale),
            "end": float(d[-1] / scale)}


def _lookup(summary: Mapping[str, Any], key: str):
    cur: Any = summary
    for part in key.split("."):
        if not isinstance(cur, Mapping) or part not in cur:
            return None
        cur = cur[part]
    return cur if isinstance(cur, (int, float)) and not isinstance(cur, bool) else None


def derived_values(derived: Mapping[str, Mapping[str, Any]], summary: Mapping[str, Any]) -> dict[str, Any]:
    """Value of every derived quantity (``compare.derived``: name -> {key: dotted summary
    key}) in a run's summary.json; None where it is missing or not a number."""
    return {d: _lookup(summary, x["key"]) for d, x in derived.items()}


def _present(summary: Mapping[str, Any], key: str) -> bool:
    cur: Any = summary
    for part in key.split("."):
        if not isinstance(cur, Mapping) or part not in cur:
            return False
        cur = cur[part]
    return True


def derived_error(ref_summary, summary, key: str, scale: float | None) -> float:
    """Relative error of the number at dotted ``key`` in summary.json (inf when missing)."""
    r, v = _lookup(ref_summary, key), _lookup(summary, key)
    if r is None and v is None and _present(ref_summary, key) and _present(summary, key):
        return 0.0          # both null: e.g. no whirl onset in either run, they agree
    if r is None or v is None or not math.isfinite(v):
        return math.inf
    s = scale if scale else abs(r)
    return abs(v - r) / s if s > 0 else (0.0 if v == r else math.inf)


def fit_order(h, e) -> tuple[float, float, int]:
    """Observed order of ``e ~ C h^p``: (least-squares slope of log e vs log h over all
    finite positive points, slope of the two finest points, number of points)."""
    pts = sorted((float(a), float(b)) for a, b in zip(h, e) if a > 0 and 0 < b < math.inf)
    if len(pts) < 2 or len({a for a, _ in pts}) < 2:
        return math.nan, math.nan, len(pts)
    lh, le = np.log([a for a, _ in pts]), np.log([b for _, b in pts])
    p = float(np.polyfit(lh, le, 1)[0])
    p_fine = float((le[1] - le[0]) / (lh[1] - lh[0]))
    return p, p_fine, len(pts)


# --------------------------------------------------------------------------- checks

def load_baseline(path: Path) -> dict[str, Any]:
    """The stored baseline, checked (:class:`orchestrator.untrusted.InputError` if missing or
    not a baseline: a missing file must not silently switch the regression gate off)."""
    from orchestrator.untrusted import InputError, load_json

    path = Path(path)
    if not path.exists():
        raise InputError(f"{path}: the baseline file named by 'compare.baseline' does not exist, so the regression "
                         "gate cannot run; create it with `rotorcosim compare FILE --update-baseline` (and commit "
                         "it), or remove 'compare.baseline'")
    doc = load_json(path, what="baseline file", fix="fix 'compare.baseline' or rewrite the file with "
                    "`rotorcosim compare FILE --update-baseline`")
    variants = doc.get("variants") if isinstance(doc, dict) else None
    problem = None
    if not isinstance(variants, dict):
        problem = "has no 'variants' mapping"
    else:
        def number(x, whole: bool = False) -> bool:
            # a finite number >= 0 (a whole one for FMU calls): a text or list ended the comparison, after
            # every run, in "internal error: TypeError"; nan switched the check off, a negative one failed it
            kinds = (int,) if whole else (int, float)
            return isinstance(x, kinds) and not isinstance(x, bool) and math.isfinite(x) and x >= 0
        for name, v in variants.items():
            errors = v.get("errors", {}) if isinstance(v, dict) else None
            if (not isinstance(errors, dict) or not all(x is None or number(x) for x in errors.values())
                    or not (v.get("fmu_calls") is None or number(v["fmu_calls"], whole=True))
                    or not isinstance(v.get("stable", False), bool)):
                problem = (f"has a malformed entry for variant {name!r} (expected {{stable: true or false, errors: "
                           "{metric: number >= 0 or null}, fmu_calls: whole number >= 0}, got "
                           f"{json.dumps(v, default=str)[:200]})")
                break
    if problem:
        raise InputError(f"{path}: the baseline file {problem}; it was not written by `rotorcosim compare "
                         "--update-baseline`: fix 'compare.baseline' or rewrite the file with --update-baseline")
    return doc


#: a variant error below this many times the reference's own change (its convergence check, in the
#: order metric) is within the reference's accuracy: the reference's error, which is of the order of
#: that change, is then >= 10 % of the measured error, and an order fitted through it is not the
#: scheme's (a third-party FMU's internal solver tolerance sets such a floor for a co-simulation
#: reference; docs/compare.md, "Observed order")
REFERENCE_FLOOR_FACTOR = 10.0


def cheapest_within_tolerance(report, failures: list[str]) -> dict | None:
    """The answer to "which coupling is good enough at the least cost": among the stable variants
    that have a tolerance or a goal, no failed check and every error within their goal, the one
    with the fewest FMU calls (exact on every machine); at equal calls the one furthest within its
    tolerance and goal (largest error/limit the smallest), then wall time. None when no variant
    qualifies, or when the reference failed its convergence check (the errors are then not to be
    trusted)."""
    if any(f.startswith("reference:") for f in failures):
        return None                 # errors against a reference that is not converged name nothing
    failed = {f.split("'")[1] for f in failures if f.startswith("variant '")}
    ok = [v for v in report.variants if v["stable"] and (v["tolerance"] or v.get("goal"))
          and v["name"] not in failed and v.get("meets_goal") is not False]
    if not ok:
        return None

    def used(v) -> float:
        return max(v["errors"].get(m, math.inf) / t for lim in (v["tolerance"], v.get("goal") or {})
                   for m, t in lim.items())
    return min(ok, key=lambda v: (v["fmu_calls"] if isinstance(v.get("fmu_calls"), (int, float)) else math.inf,
                                  used(v), v.get("wall_time_s") or math.inf))


def check_report(report, spec, baseline: Mapping[str, Any] | None) -> list[str]:
    """Every failed check as one readable line naming the variant and the metric."""
    fails = []
    chk = report.reference.get("check")
    if chk is not None:
        small = chk.get("smallest_tolerance")
        if not chk["ok"]:
            fails.append(f"reference: the convergence-check run failed ({chk['message']})")
        elif small is not None:
            for m in spec.metrics:
                if chk["errors"][m] >= small:
                    fails.append(f"reference: halving its tolerance/step changes the '{m}' error by "
                                 f"{chk['errors'][m]:.3g} >= the smallest tolerance or goal in use "
                                 f"{small:.3g}; tighten the reference")
        if chk["ok"]:   # a derived quantity with a tolerance: its own change below its smallest one
            for d, tol in (chk.get("derived_tolerances") or {}).items():
                val = chk["errors"].get(d, math.inf)
                if not val < tol:
                    fails.append(f"reference: halving its tolerance/step changes '{d}' by {val:.3g} "
                                 f">= the smallest tolerance or goal on it {tol:.3g}; tighten the reference")
    for v in report.variants:
        for m, tol in v["tolerance"].items():
            val = v["errors"].get(m, math.inf)
            if not val <= tol:
                msg = v["message"] if len(v["message"]) <= 160 else v["message"][:157] + "..."
                why = "" if v["stable"] else f" (unstable, run {v['status']}: {msg or 'error >= 100 %'})"
                fails.append(f"variant '{v['name']}': {m} error {val:.3g} exceeds tolerance {tol:.3g}{why}")
    for o in report.orders:
        if o["expected"] is not None and not abs(o["order"] - o["expected"]) <= spec.order_tolerance:
            near = o.get("near_reference") or []
            why = (f" (the errors at h = {', '.join(f'{h:g}' for h in near)} s are within the reference's own "
                   "accuracy, see report.md: tighten the reference)" if near else "")
            fails.append(f"family '{o['family']}': observed order {o['order']:.2f} of the "
                         f"{o['metric']} error differs from the expected {o['expected']:g} by more "
                         f"than {spec.order_tolerance:g}{why}")
    if baseline:
        base_vars = baseline.get("variants", {})
        m_, f_ = spec.regression_margin, spec.regression_floor
        fix = ("the regression gate cannot check it: if the comparison file changed on purpose, rewrite the "
               "baseline with `rotorcosim compare FILE --update-baseline` and review its diff")
        ran = {v["name"] for v in report.variants}
        for name in sorted(set(base_vars) - ran):
            fails.append(f"variant '{name}': in the baseline but not run (renamed or removed from the comparison "
                         f"file?); {fix}")
        for v in report.variants:
            b = base_vars.get(v["name"])
            if b is None:
                fails.append(f"variant '{v['name']}': not in the baseline ({len(base_vars)} variants); {fix}")
                continue
            if b.get("stable") and not v["stable"]:
                fails.append(f"variant '{v['name']}': stable in the baseline, unstable now "
                             f"({v['message'] or 'error >= 100 %'})")
                continue
            for m, old in b.get("errors", {}).items():
                new = v["errors"].get(m)
                if new is None or old is None:
                    continue
                limit = old * (1 + m_) + f_
                if not new <= limit:
                    fails.append(f"variant '{v['name']}': {m} error {new:.4g} regressed vs baseline "
                                 f"{old:.4g} (allowed {limit:.4g} = baseline*(1+{m_:g}) + {f_:g})")
            old_calls, new_calls = b.get("fmu_calls"), v.get("fmu_calls")
            if old_calls and new_calls is not None and new_calls > old_calls * (1 + m_):
                fails.append(f"variant '{v['name']}': {new_calls} FMU calls regressed vs baseline {old_calls} "
                             f"(allowed {old_calls * (1 + m_):.0f} = baseline*(1+{m_:g}); the cost of a "
                             "variable or iterated step)")
    return fails


def check_baseline_target(path: Path, where: str = "'compare.baseline'") -> Path:
    """``path`` as the file ``--update-baseline`` will write, checked before any run: an existing
    regular file or a new name; its folder exists or can be made (the nearest existing
    ancestor is a folder). A directory, FIFO, device, socket or symbolic link at ``path`` is
    refused (:class:`orchestrator.untrusted.InputError`), so a long comparison never ends
    blocked on a pipe or failing to write. ``where`` names the file and field."""
    from orchestrator.untrusted import InputError, file_kind

    path = Path(path)
    expected = "--update-baseline writes a regular JSON file there"
    try:
        st = os.lstat(path)
    except (FileNotFoundError, NotADirectoryError):
        st = None
    if st is not None and stat.S_ISLNK(st.st_mode):
        raise InputError(f"{where}: {path} is a symbolic link (to {os.readlink(path)}); {expected} and does not write "
                         "through a link: name the real file in 'compare.baseline' or remove the link")
    if st is not None and not stat.S_ISREG(st.st_mode):
        raise InputError(f"{where}: {path} is {file_kind(st.st_mode)}; {expected}: name a new or existing regular file, "
                         "e.g. baselines/NAME.json")
    folder = path.parent
    while not folder.exists() and folder != folder.parent:
        folder = folder.parent
    if not folder.is_dir():
        raise InputError(f"{where}: {path} cannot be created: {folder} is not a folder; name a file in a folder")
    return path


def write_baseline(report, spec, path: Path) -> None:
    """Store errors, stability and FMU calls of every variant (not timings, they are
    machine-dependent; call counts are not). Written atomically and never through a link
    (:func:`orchestrator.results.safe_write.write_text_no_follow`); the folder is created."""
    from orchestrator.results.safe_write import write_text_no_follow

    path = check_baseline_target(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    doc = {"version": BASELINE_VERSION, "compare": spec.name,
           "created": datetime.now(timezone.utc).isoformat(timespec="seconds"),
           "machine": platform.platform(),
           "variants": {v["name"]: {"stable": v["stable"], "fmu_calls": v.get("fmu_calls"),
                                    "errors": {m: (x if math.isfinite(x) else None)
                                               for m, x in v["errors"].items()}}
                        for v in report.variants}}
    write_text_no_follow(path, json.dumps(doc, indent=1, sort_keys=True) + "\n")


# --------------------------------------------------------------------------- report
