"""``orbit_<journal>.png``: journal orbits (x/c, y/c) with the clearance circle in three windows, coloured by time."""

from __future__ import annotations

import numpy as np

from orchestrator.results.plots.common import MAX_ORBIT_POINTS, ORBIT_REVS, PlotContext, plain, safe_name
from orchestrator.results.whirl import TWO_PI


def draw(ctx: PlotContext, jn: str) -> None:
    from matplotlib.collections import LineCollection
    from matplotlib.figure import Figure
    j = ctx.journal(jn)
    if j["x"] is None or j["y"] is None:
        ctx.skipped.append(f"orbit of '{jn}': x or y signal missing (see above)")
        return
    t, om, c, res = j["t"], j["omega"], j["c"], j["res"]
    scale, unit = (1.0 / c, "/c [-]") if c else (1e6, r" [$\mu$m]")
    x, y = j["x"] * scale, j["y"] * scale
    wins = orbit_windows(t, om, res)
    fig = Figure(figsize=(4.0 * len(wins), 4.4), layout="constrained")
    axes = fig.subplots(1, len(wins), squeeze=False)[0]
    for ax, (title, t0, t1) in zip(axes, wins):
        sel = np.nonzero((t >= t0) & (t <= t1))[0]
        sel = sel[::max(1, sel.size // MAX_ORBIT_POINTS)]
        pts = np.column_stack([x[sel], y[sel]])
        lc = LineCollection(np.stack([pts[:-1], pts[1:]], axis=1), cmap="viridis", lw=0.8)
        lc.set_array(t[sel][:-1])
        ax.add_collection(lc)
        if c:
            phi = np.linspace(0, TWO_PI, 361)
            ax.plot(np.cos(phi), np.sin(phi), "k-", lw=1.0, label="clearance")
            ax.set_xlim(-1.1, 1.1)
            ax.set_ylim(-1.1, 1.1)
            size = max(np.ptp(pts[:, 0]), np.ptp(pts[:, 1])) if len(pts) > 1 else 0.0
            if 0 < size < 0.15:      # small orbit: zoomed inset so its shape stays visible
                ins = ax.inset_axes([0.62, 0.58, 0.36, 0.36])
                lc2 = LineCollection(np.stack([pts[:-1], pts[1:]], axis=1), cmap="viridis", lw=0.8)
                lc2.set_array(t[sel][:-1])
                ins.add_collection(lc2)
                ins.autoscale()
                ins.set_aspect("equal", adjustable="datalim")
                ins.tick_params(labelsize=6)
                ins.set_xlabel(f"zoom, {size:.2g} c wide", fontsize=6, labelpad=1)
        else:
            ax.autoscale()
        ax.set_aspect("equal")
        ax.grid(alpha=0.3)
        sp = f", {np.interp(0.5 * (t0 + t1), t, om) / TWO_PI:.4g} Hz" if om is not None else ""
        ax.set_title(f"{title}\n{t0:.3g}-{t1:.3g} s{sp}", fontsize=9)
        ax.set_xlabel("x" + unit)
        ax.set_ylabel("y" + unit)
        fig.colorbar(lc, ax=ax, label="time [s]", shrink=0.7)
    fig.suptitle(f"{plain(ctx.name)}: orbit of journal '{plain(jn)}'")
    ctx.save(fig, f"orbit_{safe_name(jn)}.png")



def orbit_windows(t, omega, res) -> list[tuple[str, float, float]]:
    """Up to three (title, t0, t1) windows of ``ORBIT_REVS`` revolutions each."""
    t_end = float(t[-1])

    def span(t_center_or_end, end=False):
        f = abs(float(np.interp(t_center_or_end, t, omega))) / TWO_PI if omega is not None else 0.0
        d = ORBIT_REVS / f if f > 0 else 0.05 * (t_end - t[0])
        d = min(d, 0.2 * (t_end - t[0]))
        return (t_center_or_end - d, t_center_or_end) if end else (t_center_or_end - d / 2, t_center_or_end + d / 2)

    wins = []
    ons = res.get("onset") if res else None
    if ons:
        a, b = span(ons["time_s"] - (res.get("time_resolution_s") or 0.0), end=True)
        wins.append(("before whirl onset", a, b))
        ep = res["episodes"][0]
        t_mid = ep["onset_time_s"] + 0.5 * ((ep["vanish_time_s"] or t_end) - ep["onset_time_s"])
        a, b = span(t_mid)
        wins.append(("in whirl", a, b))
    else:
        a, b = span(t[0] + 0.5 * (t_end - t[0]))
        wins.append(("middle of the run", a, b))
    a, b = span(t_end, end=True)
    wins.append(("end of the run", a, b))
    return [(s, max(a, float(t[0])), min(b, t_end)) for s, a, b in wins]
