"""``eccentricity.png``: eccentricity of every journal over time and over rotor speed, whirl onset / vanishing marked."""

from __future__ import annotations

import numpy as np

from orchestrator.results.plots.common import PlotContext, plain, trace
from orchestrator.results.whirl import TWO_PI


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
