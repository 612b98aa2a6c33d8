"""``waterfall_<journal>.png``: frequency of the forward journal motion against rotor speed, colour = amplitude / clearance."""

from __future__ import annotations

import math

import numpy as np

from orchestrator.results.plots.common import PlotContext, edges, plain, safe_name
from orchestrator.results.whirl import WhirlParams, too_many_bins, waterfall


def draw(ctx: PlotContext, jn: str) -> None:
    from matplotlib.colors import LogNorm
    from matplotlib.figure import Figure
    j = ctx.journal(jn)
    if j["x"] is None or j["y"] is None or j["omega"] is None:
        ctx.skipped.append(f"waterfall of '{jn}': needs x, y and the speed signal "
                            f"('{ctx.spec.get('speed')}')")
        return
    params = WhirlParams()
    try:
        params = WhirlParams.from_mapping(ctx.spec.get("whirl"))
    except (ValueError, TypeError) as exc:
        ctx.skipped.append(f"custom whirl parameters for the waterfall ({exc}); defaults used")
    why = too_many_bins(j["t"], j["omega"], params.samples_per_rev)
    if why:
        ctx.skipped.append(f"waterfall of '{jn}': {why.replace('; whirl not analysed', '')}")
        return
    wf = waterfall(j["t"], j["x"] + 1j * j["y"], j["omega"], params)
    if wf["t"].size < 2:
        ctx.skipped.append(f"waterfall of '{jn}': fewer than {params.window_revs + params.hop_revs} "
                            "revolutions in the run")
        return
    c = j["c"]
    scale, unit = (1.0 / c, "amplitude / clearance [-]") if c else (1e6, r"amplitude [$\mu$m]")
    keep = (wf["orders"] >= 0) & (wf["orders"] <= 2.5)
    orders, amp = wf["orders"][keep], wf["amplitude"][:, keep] * scale
    sp = wf["speed_hz"]
    drawn = amp[np.isfinite(amp) & (amp > 0)]
    top = float(drawn.max()) if drawn.size else 1.0
    if not top * 3e-3 >= np.finfo(float).tiny or not np.isfinite(top):
        # the colour scale spans 3e-3 * top to top on a log axis; below the smallest normal float
        # (a clearance of 1e308 m in a crafted summary.json) matplotlib's colour bar raised
        # "Invalid vmin or vmax" and `plot` ended in an internal error
        ctx.skipped.append(f"waterfall of '{jn}': its largest {unit.split(' [')[0]} is {top:.3g}, too small for a "
                           f"logarithmic colour scale (clearance {c!r} m; check the journal's clearance in the "
                           "analysis spec of summary.json or the scenario)")
        return
    norm = LogNorm(vmin=top * 3e-3, vmax=top)
    shown = np.ma.masked_less(amp, top * 3e-3)          # below the colour range: white
    o_edges = edges(orders)
    fig = Figure(figsize=(8, 5.5), layout="constrained")
    ax = fig.subplots()
    ramp = np.ptp(sp) > 0.01 * max(np.max(np.abs(sp)), 1e-30)
    if ramp:
        S, O = np.meshgrid(edges(sp), o_edges, indexing="ij")
        m = ax.pcolormesh(S, S * O, shown, shading="flat", norm=norm, cmap="magma_r")
        f = np.array([0.0, np.max(sp)])
        ax.plot(f, f, "k--", lw=0.8, label="1x")
        ax.plot(f, 0.5 * f, "k:", lw=0.8, label="0.5x")
        ax.set_xlabel("rotor speed [Hz]")
        ax.set_ylabel("frequency of forward journal motion [Hz]")
        se = edges(sp)
        ax.set_xlim(max(0.0, float(np.min(se))), float(np.max(se)))   # the speeds the run covered
        ax.set_ylim(0, 1.5 * np.max(sp))
        th = (j["res"] or {}).get("threshold_speed_hz")
        if isinstance(th, (int, float)) and math.isfinite(th):
            snr = (j["res"] or {}).get("threshold_snr")
            weak = ", unreliable" if isinstance(snr, (int, float)) and snr < 3 else ""
            ax.axvline(th, color="C1", ls=":", lw=1.2,
                       label=f"instability threshold {th:.4g} Hz (growth rate > 0{weak})")
        ev = (j["res"] or {}).get("onset")
        if ev:
            ax.axvline(ev["speed_hz"], color="C0", ls="--", lw=1.0,
                       label=f"whirl onset {ev['speed_hz']:.4g} Hz")
        ev = (j["res"] or {}).get("vanish")
        if ev:
            ax.axvline(ev["speed_hz"], color="C2", ls="--", lw=1.0,
                       label=f"whirl vanishes {ev['speed_hz']:.4g} Hz")
    else:   # constant speed: spectrum over time, frequency in orders
        m = ax.pcolormesh(edges(wf["t"]), o_edges, shown.T, shading="flat", norm=norm, cmap="magma_r")
        ax.axhline(1.0, color="k", ls="--", lw=0.8, label="1x")
        ax.axhline(0.5, color="k", ls=":", lw=0.8, label="0.5x")
        ax.set_xlabel("time [s]")
        ax.set_ylabel("order (frequency / rotor speed) [-]")
    fig.colorbar(m, ax=ax, label=unit)
    ax.legend(fontsize=8, loc="upper left")
    ax.set_title(f"{plain(ctx.name)}: waterfall of journal '{plain(jn)}' "
                 f"({params.window_revs}-revolution windows)")
    ctx.save(fig, f"waterfall_{safe_name(jn)}.png")
