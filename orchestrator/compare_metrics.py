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
``orchestrator.analysis``) has the error ``|d_v - d_r| / S`` with ``S`` given or
``|d_r|``; when the key is null in both runs (e.g. no whirl onset in either)
the error is 0, when it is missing or null in only one it is infinite. A variant
that ends before the reference or produces non-finite values has infinite error.
"""

from __future__ import annotations

import csv
import json
import math
import platform
from dataclasses import dataclass, field
from datetime import datetime, timezone
from pathlib import Path
from typing import Any, Mapping

import numpy as np

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
    try:
        summary = json.loads((run_dir / "summary.json").read_text())
    except (OSError, ValueError) as exc:
        return RunData(ok=False, message=f"no readable summary.json in {run_dir}: {exc}", wall_time_s=wall)
    try:
        with open(run_dir / "results.csv", newline="") as f:
            rows = list(csv.reader(f))
        header, body = rows[0], [r for r in rows[1:] if len(r) == len(rows[0])]
        data = np.array([[float(x) for x in r] for r in body], dtype=float).reshape(-1, len(header))
    except (OSError, ValueError, IndexError) as exc:
        return RunData(ok=False, message=f"no readable results.csv in {run_dir}: {exc}",
                       summary=summary, wall_time_s=wall)
    calls = summary.get("fmu_calls") or {}
    n_calls = sum(int(n) for per in calls.values() if isinstance(per, dict)
                  for n in per.values() if isinstance(n, (int, float)))
    status = summary.get("status", "failed")
    return RunData(ok=status == "finished", message=str(summary.get("message", "")),
                   t=data[:, 0], outputs={h: data[:, i] for i, h in enumerate(header) if i},
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
        for name, v in variants.items():
            errors = v.get("errors", {}) if isinstance(v, dict) else None
            if not isinstance(errors, dict) or not all(
                    x is None or (isinstance(x, (int, float)) and not isinstance(x, bool)) for x in errors.values()):
                problem = f"has a malformed entry for variant {name!r} (expected {{stable: bool, errors: {{metric: number}}}})"
                break
    if problem:
        raise InputError(f"{path}: the baseline file {problem}; it was not written by `rotorcosim compare "
                         "--update-baseline`: fix 'compare.baseline' or rewrite the file with --update-baseline")
    return doc


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
                                 f"{chk['errors'][m]:.3g} >= the smallest tolerance in use "
                                 f"{small:.3g}; tighten the reference")
        if chk["ok"]:   # a derived quantity with a tolerance: its own change below its smallest one
            for d, tol in (chk.get("derived_tolerances") or {}).items():
                val = chk["errors"].get(d, math.inf)
                if not val < tol:
                    fails.append(f"reference: halving its tolerance/step changes '{d}' by {val:.3g} "
                                 f">= the smallest tolerance on it {tol:.3g}; tighten the reference")
    for v in report.variants:
        for m, tol in v["tolerance"].items():
            val = v["errors"].get(m, math.inf)
            if not val <= tol:
                msg = v["message"] if len(v["message"]) <= 160 else v["message"][:157] + "..."
                why = "" if v["stable"] else f" (unstable, run {v['status']}: {msg or 'error >= 100 %'})"
                fails.append(f"variant '{v['name']}': {m} error {val:.3g} exceeds tolerance {tol:.3g}{why}")
    for o in report.orders:
        if o["expected"] is not None and not abs(o["order"] - o["expected"]) <= spec.order_tolerance:
            fails.append(f"family '{o['family']}': observed order {o['order']:.2f} of the "
                         f"{o['metric']} error differs from the expected {o['expected']:g} by more "
                         f"than {spec.order_tolerance:g}")
    if baseline:
        base_vars = baseline.get("variants", {})
        m_, f_ = spec.regression_margin, spec.regression_floor
        for v in report.variants:
            b = base_vars.get(v["name"])
            if b is None:
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
    return fails


def write_baseline(report, spec, path: Path) -> None:
    """Store errors and stability of every variant (not timings, they are machine-dependent)."""
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    doc = {"version": BASELINE_VERSION, "compare": spec.name,
           "created": datetime.now(timezone.utc).isoformat(timespec="seconds"),
           "machine": platform.platform(),
           "variants": {v["name"]: {"stable": v["stable"],
                                    "errors": {m: (x if math.isfinite(x) else None)
                                               for m, x in v["errors"].items()}}
                        for v in report.variants}}
    path.write_text(json.dumps(doc, indent=1, sort_keys=True) + "\n")


# --------------------------------------------------------------------------- report

def _fmt(x, spec="{:.3g}") -> str:
    if x is None:
        return "-"
    if isinstance(x, float) and math.isnan(x):
        return "n/a"
    if isinstance(x, float) and math.isinf(x):
        return "inf"
    return spec.format(x)


def _clean(obj):
    if isinstance(obj, float) and not math.isfinite(obj):
        return None if math.isnan(obj) else ("inf" if obj > 0 else "-inf")
    if isinstance(obj, dict):
        return {k: _clean(v) for k, v in obj.items()}
    if isinstance(obj, (list, tuple)):
        return [_clean(v) for v in obj]
    return obj


def write_report(report, spec, out_dir: Path, failures: list[str]) -> list[Path]:
    """Write report.md, report.json and error_vs_cost.png into ``out_dir``."""
    out_dir = Path(out_dir)
    cols = list(spec.metrics) + list(spec.derived)
    lines = [f"# Comparison `{spec.name}`", ""]
    if spec.source:
        lines += [f"File: `{spec.source}`; base scenario `{spec.base.name}`, "
                  f"t = {spec.base.start_time:g} .. {spec.base.stop_time:g} s, output interval "
                  f"{_fmt(spec.output_interval, '{:g}')} s.", ""]
    ref = report.reference
    if ref.get("window"):
        lines += [f"Errors are measured over t = {ref['window'][0]:g} .. {ref['window'][1]:g} s only "
                  "(`compare.window`).", ""]
    values = ", ".join(f"{d} = {_fmt(x, '{:.6g}')}" for d, x in (ref.get("derived") or {}).items())
    lines += [f"Reference: `{ref['changes']}` ({_fmt(ref['wall_time_s'], '{:.2f}')} s wall"
              + (f"; {values}" if values else "") + "). "
              "Errors are relative to the scale of each signal (peak of the reference unless "
              "given), worst over the signals: " + ", ".join(
                  f"`{s}` (scale {_fmt(v, '{:.3g}')})" for s, v in ref["scales"].items()) + ".", ""]
    if "check" in ref:
        c = ref["check"]
        dtol = c.get("derived_tolerances") or {}
        chk_values = ", ".join(f"{d} = {_fmt(x, '{:.6g}')}" for d, x in (c.get("derived") or {}).items())
        lines += [f"Reference convergence check (`{c['changes']}`): change " + ", ".join(
            f"{m} {_fmt(c['errors'].get(m))}" for m in list(spec.metrics) + list(spec.derived)) +
            f"; smallest tolerance in use {_fmt(c['smallest_tolerance'])}" +
            "".join(f", on {d} {t:g}" for d, t in dtol.items()) +
            (f" (check run: {chk_values})" if chk_values else "") + ".", ""]
    head = (["variant", "scheme", "ext", "int", "h [s]"] + [f"{c} err" for c in cols] +
            ["wall [s]", "macro steps", "FMU calls", "stable", "tolerance", "check"])
    lines += ["| " + " | ".join(head) + " |", "|" + "---|" * len(head)]
    failed_names = {f.split("'")[1] for f in failures if f.startswith("variant '")}
    for v in report.variants:
        tol = ", ".join(f"{k} {t:g}" for k, t in v["tolerance"].items()) or "-"
        row = ([v["name"], v["scheme"], str(v["extrapolation_order"]), str(v["interpolation_order"]),
                f"{v['macro_step']:g}"] + [_fmt(v["errors"].get(c)) for c in cols] +
               [_fmt(v["wall_time_s"], "{:.2f}"), _fmt(v["macro_steps"], "{}"),
                _fmt(v["fmu_calls"], "{}"), "yes" if v["stable"] else "NO", tol,
                "FAIL" if v["name"] in failed_names else "ok"])
        lines.append("| " + " | ".join(row) + " |")
    if spec.derived:   # the derived numbers themselves (the table above has their errors)
        lines += ["", "Derived values (`" + "`, `".join(d["key"] for d in spec.derived.values()) + "`):",
                  "", "| run | " + " | ".join(spec.derived) + " |", "|---|" + "---|" * len(spec.derived)]
        rows = [("reference", ref.get("derived") or {})]
        if "check" in ref:
            rows.append(("reference-check", ref["check"].get("derived") or {}))
        rows += [(v["name"], v.get("derived") or {}) for v in report.variants]
        for name, vals in rows:
            lines.append(f"| {name} | " + " | ".join(_fmt(vals.get(d), "{:.6g}") for d in spec.derived) + " |")
    if report.orders:
        lines += ["", f"Observed order of convergence of the `{spec.order_metric}` error over the "
                  "macro step (least-squares slope over the stable points; slope of the two "
                  "finest steps):", "", "| family | order (fit) | order (finest pair) | points | expected |",
                  "|---|---|---|---|---|"]
        for o in report.orders:
            lines.append(f"| {o['family']} | {_fmt(o['order'], '{:.2f}')} | "
                         f"{_fmt(o['order_finest'], '{:.2f}')} | {o['points']} | "
                         f"{_fmt(o['expected'], '{:g}')} |")
    lines += ["", "## Result", ""]
    lines += [f"- FAIL {f}" for f in failures] or ["All checks passed."]
    lines += ["", f"Total wall time {report.wall_time_s:.1f} s."]
    paths = [out_dir / "report.md", out_dir / "report.json"]
    paths[0].write_text("\n".join(lines) + "\n")
    doc = {"name": report.name, "reference": report.reference, "variants": report.variants,
           "orders": report.orders, "failures": failures, "wall_time_s": report.wall_time_s,
           "passed": not failures}
    paths[1].write_text(json.dumps(_clean(doc), indent=1) + "\n")
    png = _plot(report, spec, out_dir / "error_vs_cost.png")
    return paths + ([png] if png else [])


def _plot(report, spec, path: Path) -> Path | None:
    try:
        import matplotlib
        matplotlib.use("Agg")
        import matplotlib.pyplot as plt
    except ImportError:
        return None
    m = spec.order_metric
    fig, axes = plt.subplots(1, 2, figsize=(10, 4), constrained_layout=True)
    for fam in dict.fromkeys(v["family"] for v in report.variants):
        pts = sorted((v["wall_time_s"], v["macro_steps"] or math.nan, v["errors"].get(m, math.inf))
                     for v in report.variants if v["family"] == fam and v["stable"])
        if not pts:
            continue
        w, n, e = zip(*pts)
        axes[0].loglog(w, e, "o-", label=fam)
        axes[1].loglog(n, e, "o-", label=fam)
    for ax, xl in zip(axes, ("wall time [s]", "macro steps")):
        ax.set_xlabel(xl)
        ax.set_ylabel(f"{m} error (relative)")
        ax.grid(True, which="both", alpha=0.3)
    axes[0].legend(fontsize=7)
    fig.suptitle(f"{spec.name}: error vs cost (stable variants)")
    fig.savefig(path, dpi=110)
    plt.close(fig)
    return path
