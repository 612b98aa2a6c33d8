"""``eccentricity.png``: eccentricity of every journal over time and over rotor speed, whirl onset / vanishing
marked, and the episodes of a large coupling defect (``summary.json`` ``coupling_defect``,
orchestrator/coupling/defect.py) as ticks along the top with their spans shaded."""

from __future__ import annotations

import math
from collections.abc import Mapping

import numpy as np

from orchestrator.results.plots.common import PlotContext, plain, trace
from orchestrator.results.whirl import TWO_PI

MAX_MARKED = 1000          # defect episodes drawn (summary.json is untrusted: a tampered one may list millions)


def defect_episodes(summary) -> tuple[list[tuple[float, float, float]], int, str | None]:
    """``[(t_start, t_end, t_max_defect), ...]`` of ``summary["coupling_defect"]`` over every journal,
    the episodes counted there (``episode_count``; more than are listed when a journal had over 100),
    and a problem (or None). A field of another type is left out:
    the summary of a run folder may come from anyone."""
    cd = summary.get("coupling_defect") if isinstance(summary, Mapping) else None
    if cd is None:
        return [], 0, None
    journals = cd.get("journals") if isinstance(cd, Mapping) else None
    if not isinstance(journals, Mapping):
        return [], 0, "summary.json coupling_defect has no 'journals' mapping; its episodes are not marked"
    out, count, bad = [], 0, 0
    for j in list(journals.values())[:MAX_MARKED]:
        if not isinstance(j, Mapping):
            bad += 1
            continue
        n = j.get("episode_count")
        count += n if isinstance(n, int) and not isinstance(n, bool) and n >= 0 else 0
        eps = j.get("episodes")
        for e in (eps if isinstance(eps, list) else [])[:MAX_MARKED]:
            vals = [e.get(k) if isinstance(e, Mapping) else None for k in ("t_start", "t_end", "t_max_defect")]
            if all(isinstance(v, (int, float)) and not isinstance(v, bool) and math.isfinite(v) for v in vals) \
                    and vals[0] <= vals[2] <= vals[1]:
                out.append(tuple(float(v) for v in vals))
            else:
                bad += 1
    problem = (f"{bad} coupling_defect entries in summary.json are not of the form the run writes (t_start <= "
               "t_max_defect <= t_end, numbers); they are not marked") if bad else None
    return out[:MAX_MARKED], count, problem


def draw(ctx: PlotContext) -> None:
    from matplotlib.figure import Figure
    t = ctx.cols["time"]
    om = ctx.cols.get(ctx.spec.get("speed") or "")
    if ctx.spec.get("speed") and om is None:
        ctx.signal(ctx.spec.get("speed"), "speed axis")
    ramp = om is not None and np.ptp(om) > 0.01 * max(np.nanmax(np.abs(om)), 1e-30)
    fig = Figure(figsize=(8, 6.5 if ramp else 3.8), layout="constrained")
    axes = fig.subplots(2 if ramp else 1, 1, squeeze=False)[:, 0]
    n = 0
    for i, jn in enumerate(ctx.spec["journals"]):
        j = ctx.journal(jn)
        e, lab = j["eps"], jn
        if e is None and j["x"] is not None and j["y"] is not None and j["c"]:
            e, lab = np.hypot(j["x"], j["y"]) / j["c"], f"{jn} (|z|/c)"
        if e is None:
            ctx.skipped.append(f"eccentricity of '{jn}': neither an eps signal nor x, y and clearance")
            continue
        col = f"C{i}"
        trace(axes[0], t, e, col, lab)
        if ramp:
            trace(axes[1], om / TWO_PI, e, col, lab)
        for key, ls in (("onset", "--"), ("vanish", ":")):
            ev = j["res"].get(key)
            if ev:
                txt = f"{key} {jn}: {ev['time_s']:.3g} s, {ev['speed_hz']:.4g} Hz"
                axes[0].axvline(ev["time_s"], color=col, ls=ls, lw=1.2, label=txt)
                if ramp:
                    axes[1].axvline(ev["speed_hz"], color=col, ls=ls, lw=1.2)
        n += 1
    if not n:
        return
    _mark_defects(ctx, axes, t, om if ramp else None)
    axes[0].set_xlabel("time t [s]")
    axes[0].set_title(f"{plain(ctx.name)}: journal eccentricity")
    if ramp:
        axes[1].set_xlabel("rotor speed [Hz]")
    for ax in axes:
        ax.set_ylabel(r"eccentricity $\varepsilon$ [-]")
        ax.set_ylim(bottom=0)
        ax.grid(alpha=0.3)
    axes[0].legend(fontsize=7, loc="upper left")
    ctx.save(fig, "eccentricity.png")


def _mark_defects(ctx: PlotContext, axes, t: np.ndarray, om) -> None:
    """Ticks at the top of each panel where a coupling-defect episode had its largest defect, its span shaded."""
    episodes, count, problem = defect_episodes(ctx.summary)
    if problem:
        ctx.skipped.append(problem)
    if not episodes:
        return
    ep = np.array(episodes)
    panels = [(axes[0], ep)]
    if om is not None and len(axes) > 1 and t.size > 1 and np.all(np.diff(t) > 0):
        panels.append((axes[1], np.interp(ep, t, om / TWO_PI)))
    count = max(count, len(episodes))
    cd = ctx.summary.get("coupling_defect")
    lim = cd.get("limit") if isinstance(cd, Mapping) else None
    times = (f"{lim:g}x " if isinstance(lim, (int, float)) and not isinstance(lim, bool) and math.isfinite(lim)
             and lim != 1 else "")
    label = (f"coupling defect > {times}typical force: {count} episode{'s' if count != 1 else ''} (forces there may "
             "depend on the macro step; summary.json coupling_defect)")
    for k, (ax, x) in enumerate(panels):
        tr = ax.get_xaxis_transform()
        ax.vlines(x[:, 2], 0.94, 1.0, transform=tr, color="crimson", lw=1.0, label=label if k == 0 else None)
        for a, b in x[:, :2]:
            if b > a:
                ax.axvspan(a, b, color="crimson", alpha=0.12, lw=0)
