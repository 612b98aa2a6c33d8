"""The comparison's report: report.md (tables), report.json and error_vs_cost.png.

Reads only the :class:`~orchestrator.compare.runner.CompareReport` and the spec; the
JSON goes through the one sanitiser (:func:`orchestrator.results.jsonsafe.plain`,
NaN -> null, +-inf -> "inf"/"-inf", docs/compare.md).
"""

from __future__ import annotations

import json
import math
from pathlib import Path

from orchestrator.compare.metrics import REFERENCE_FLOOR_FACTOR, cheapest_within_tolerance
from orchestrator.results.jsonsafe import plain
from orchestrator.results.safe_write import save_figure, write_report_file


def _fmt(x, spec="{:.3g}") -> str:
    if x is None:
        return "-"
    if isinstance(x, float) and math.isnan(x):
        return "n/a"
    if isinstance(x, float) and math.isinf(x):
        return "inf"
    return spec.format(x)


def write_report(report, spec, out_dir: Path, failures: list[str]) -> list[Path]:
    """Write report.md, report.json and error_vs_cost.png into ``out_dir``.

    Length: the sections of report.md in the order they appear in it."""
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
            f"; smallest tolerance or goal in use {_fmt(c['smallest_tolerance'])}" +
            "".join(f", on {d} {t:g}" for d, t in dtol.items()) +
            (f" (check run: {chk_values})" if chk_values else "") + ".", ""]
    head = (["variant", "scheme", "ext", "int", "h [s]"] + [f"{c} err" for c in cols] +
            ["wall [s]", "macro steps", "FMU calls", "stable", "tolerance", "check"])
    goals = any(v.get("goal") for v in report.variants)
    if goals:
        head[-1:-1] = ["goal", "meets goal"]
    defects = any(v.get("coupling_defect") is not None for v in report.variants)
    if defects:      # after "FMU calls": the reference-free indicator (docs/coupling.md, "Coupling defect")
        head[head.index("FMU calls") + 1:head.index("FMU calls") + 1] = ["max defect / F", "median defect / F"]
    lines += ["| " + " | ".join(head) + " |", "|" + "---|" * len(head)]
    failed_names = {f.split("'")[1] for f in failures if f.startswith("variant '")}
    for v in report.variants:
        tol = ", ".join(f"{k} {t:g}" for k, t in v["tolerance"].items()) or "-"
        row = ([v["name"], v["scheme"], str(v["extrapolation_order"]), str(v["interpolation_order"]),
                f"{v['macro_step']:g}"] + [_fmt(v["errors"].get(c)) for c in cols] +
               [_fmt(v["wall_time_s"], "{:.2f}"), _fmt(v["macro_steps"], "{}"),
                _fmt(v["fmu_calls"], "{}"), "yes" if v["stable"] else "NO", tol,
                "FAIL" if v["name"] in failed_names else "ok"])
        if goals:
            met = v.get("meets_goal")
            row[-1:-1] = [", ".join(f"{k} {t:g}" for k, t in (v.get("goal") or {}).items()) or "-",
                          "-" if met is None else ("yes" if met else "no")]
        if defects:
            cd = v.get("coupling_defect") or {}
            i = head.index("max defect / F")
            row[i:i] = [_fmt(cd.get("max")), _fmt(cd.get("median"))]
        lines.append("| " + " | ".join(row) + " |")
    lines += ["", _cheapest_line(report, failures)]
    if defects:
        lines += ["", "`max defect / F`, `median defect / F`: the largest and the median coupling defect of the "
                  "run (at a step's end, the force a film returned minus the force the rotor integrated, or a "
                  "`coupling.defect_signals` input's value minus what its consumer was fed) over its typical "
                  "size, the largest over the signals (summary.json `coupling_defect`; constant steps): "
                  "indicators that need no reference; the median follows the order in the macro step, the "
                  "largest also shows a start-up or a jump that no step removes (docs/coupling.md, "
                  "\"Coupling defect\")."]
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
        lines += _floor_notes(report, spec)
    capped = list(dict.fromkeys(v["family"] for v in report.variants if v.get("order_capped_at")))
    if capped:
        lines += ["", "**Order capped by `interpolation_order`** in " + ", ".join(f"`{f}`" for f in capped) +
                  ": Gauss-Seidel inputs from FMUs stepped earlier in the sequence get a polynomial of degree "
                  "q < k through their new values, so these couplings are of order q + 1 at most whatever k is; "
                  "compare them with `interpolation_order` = `extrapolation_order` (docs/coupling.md) before "
                  "concluding that Gauss-Seidel is less accurate than Jacobi."]
    forward = [v["name"] for v in report.variants if v.get("forward_only")]
    if forward:
        lines += ["", f"Error-controlled step adapting **forward only** in {', '.join(f'`{n}`' for n in forward)}: "
                  "an FMU cannot save its state (canGetAndSetFMUstate false), so no step was rejected and "
                  "redone; each step follows the error of the one before, and the error reached is not held "
                  "to `rtol`/`atol` step by step (docs/coupling.md, \"Error-controlled macro step\")."]
    lines += ["", "## Result", ""]
    lines += [f"- FAIL {f}" for f in failures] or ["All checks passed."]
    lines += ["", f"Total wall time {report.wall_time_s:.1f} s."]
    paths = [out_dir / "report.md", out_dir / "report.json"]
    write_report_file(paths[0], "\n".join(lines) + "\n")
    best = cheapest_within_tolerance(report, failures)
    doc = {"name": report.name, "reference": report.reference, "variants": report.variants,
           "orders": report.orders, "failures": failures, "wall_time_s": report.wall_time_s,
           "cheapest_within_tolerance": best["name"] if best else None, "passed": not failures}
    write_report_file(paths[1], json.dumps(plain(doc, "null-nan"), indent=1) + "\n")
    png = _plot(report, spec, out_dir / "error_vs_cost.png")
    return paths + ([png] if png else [])


def cheapest_text(best: dict) -> str:
    """``name (N FMU calls, W s; max 0.01 <= 0.05)``: the cheapest variant within its tolerance."""
    limits = {**best["tolerance"]}
    for m, t in (best.get("goal") or {}).items():
        limits[m] = min(t, limits.get(m, t))
    errs = ", ".join(f"{m} {_fmt(best['errors'].get(m))} <= {t:g}" for m, t in limits.items())
    return (f"{best['name']} ({_fmt(best['fmu_calls'], '{}')} FMU calls, {_fmt(best['wall_time_s'], '{:.2f}')} s; "
            f"{errs})")


def _cheapest_line(report, failures) -> str:
    best = cheapest_within_tolerance(report, failures)
    if best is not None:
        return ("**Cheapest variant within its tolerance** (stable, within its `tolerance` and `goal`, no failed "
                f"check; fewest FMU calls, then the smallest error for its limit): `{cheapest_text(best)}`.")
    if any(f.startswith("reference:") for f in failures):
        return ("No variant is named as good enough: the reference failed its convergence check (see Result), "
                "so the errors are not to be trusted; tighten the reference first.")
    if not any(v["tolerance"] or v.get("goal") for v in report.variants):
        return ("No variant has a tolerance or a goal, so none is named as good enough: give `goal: {max: ...}` "
                "(the accuracy you need; a variant outside it is not a failure) or `tolerance: {max: ...}` (the "
                "same, and a variant outside it fails the comparison) to the comparison or to its variant groups.")
    return ("**No variant is within its tolerance** and goal (or every one that is failed another check): try "
            "smaller macro steps or other schemes.")


def _floor_notes(report, spec) -> list[str]:
    """Lines saying which families' orders rest on errors within the reference's accuracy."""
    near = [o for o in report.orders if o.get("near_reference")]
    if not near:
        return []
    change = report.reference["check"]["errors"][spec.order_metric]
    out = ["", f"**At the reference's accuracy:** the reference changes by {_fmt(change)} ({spec.order_metric}) "
           f"when its step or tolerance is halved, so errors below {REFERENCE_FLOOR_FACTOR:g}x that "
           f"({_fmt(REFERENCE_FLOOR_FACTOR * change)}) are not resolved by it, and an order fitted through them "
           "is not the scheme's. Tighten the reference (a finer macro step or a higher-order scheme; for an "
           "FMU with its own solver, its tolerance) or compare coarser steps. Points affected:", ""]
    for o in near:
        out.append(f"- `{o['family']}`: h = {', '.join(f'{h:g}' for h in o['near_reference'])} s")
    return out


def cost_points(report, metric: str) -> dict[str, list[tuple]]:
    """Per family, ``(macro step, wall time [s], FMU calls, error)`` of its stable variants from the
    coarsest macro step to the finest: the points of error_vs_cost.png, each family's line drawn
    along its step refinement.

    The cost is the FMU calls of the run (report.md's column, what the baseline checks), not the
    macro steps: a variant with 16 sub-steps makes 16 doSteps per FMU and macro step, and an
    iterated or error-controlled step repeats them, which a count of macro steps hides (the
    16-sub-step family of compare/two_mass.yaml looked the cheapest for its error by macro steps and
    is not by calls). The points were ordered by wall time, a noisy measure at these run lengths,
    so the lines zig-zagged between steps."""
    out: dict[str, list[tuple]] = {}
    for fam in dict.fromkeys(v["family"] for v in report.variants):
        pts = [(v["macro_step"], v["wall_time_s"], v["fmu_calls"] or math.nan, v["errors"].get(metric, math.inf))
               for v in report.variants if v["family"] == fam and v["stable"]]
        if pts:
            out[fam] = sorted(pts, key=lambda p: -p[0])
    return out


def _plot(report, spec, path: Path) -> Path | None:
    try:
        import matplotlib
        matplotlib.use("Agg")
        import matplotlib.pyplot as plt
    except ImportError:
        return None
    m = spec.order_metric
    fig, axes = plt.subplots(1, 2, figsize=(10, 4), constrained_layout=True)
    for fam, pts in cost_points(report, m).items():
        _, w, n, e = zip(*pts)
        axes[0].loglog(w, e, "o-", label=fam)
        axes[1].loglog(n, e, "o-", label=fam)
    for ax, xl in zip(axes, ("wall time [s]", "FMU calls (all instances; sub-steps and iterations included)")):
        ax.set_xlabel(xl)
        ax.set_ylabel(f"{m} error (relative)")
        ax.grid(True, which="both", alpha=0.3)
    axes[0].legend(fontsize=7)
    fig.suptitle(f"{spec.name}: error vs cost (stable variants)")
    save_figure(fig, path, dpi=110)
    plt.close(fig)
    return path
