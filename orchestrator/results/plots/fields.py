"""``fields_<name>.png``: pressure [bar] and fluid fraction over (phi [deg], z [mm]) of each field file, cavity outlined."""

from __future__ import annotations

from pathlib import Path

import numpy as np

from orchestrator.results.plots.common import PlotContext, safe_name


def draw(ctx: PlotContext) -> None:
    files = ctx.field_files
    want = ctx.spec.get("fields") if ctx.spec else None
    if want and ctx.run_dir is not None and not (ctx.run_dir / f"{want}_fields.npz").is_file():
        ctx.skipped.append(f"fields of '{want}': {ctx.run_dir / (str(want) + '_fields.npz')} not "
                            "found; set the bearing's fields_file parameter to "
                            f"\"{{out_dir}}/{want}_fields.npz\"")
    for f in files:
        try:
            field_plot(ctx, f)
        except (KeyError, ValueError, OSError) as exc:
            ctx.skipped.append(f"fields {f.name}: {exc}; expected arrays phi (n_phi,), z (n_z,), "
                                "p, theta (n_z, n_phi)")

def field_plot(ctx: PlotContext, path: Path) -> None:
    from matplotlib.figure import Figure
    with np.load(path) as d:
        phi, zz, p = np.asarray(d["phi"]), np.asarray(d["z"]), np.asarray(d["p"])
        theta = np.asarray(d["theta"]) if "theta" in d else None
    if p.shape != (zz.size, phi.size):
        raise ValueError(f"p has shape {p.shape}, expected (n_z, n_phi) = ({zz.size}, {phi.size})")
    n = 2 if theta is not None else 1
    fig = Figure(figsize=(7, 3.3 * n), layout="constrained")
    axes = fig.subplots(n, 1, squeeze=False)[:, 0]
    P_, Z_ = np.degrees(phi), zz * 1e3
    cp = axes[0].contourf(P_, Z_, p / 1e5, levels=30, cmap="viridis")
    fig.colorbar(cp, ax=axes[0], label="pressure p [bar]")
    axes[0].set_title(f"{ctx.name}: {path.stem}  (p_max {p.max() / 1e5:.4g} bar, "
                      f"p_min {p.min() / 1e5:.4g} bar)", fontsize=10)
    if theta is not None:
        cav = theta < 1.0 - 1e-3
        ct = axes[1].contourf(P_, Z_, theta, levels=np.linspace(min(theta.min(), 0.999), 1.0, 21),
                              cmap="cividis")
        fig.colorbar(ct, ax=axes[1], label=r"fluid fraction $\vartheta$ [-]")
        if cav.any() and not cav.all():
            for ax in axes:
                ax.contour(P_, Z_, cav.astype(float), levels=[0.5], colors="r", linewidths=1.0)
                ax.contourf(P_, Z_, cav.astype(float), levels=[0.5, 1.5], colors="none", hatches=["//"])
            axes[1].set_title(r"fluid fraction; cavity ($\vartheta$ < 1) hatched, red outline",
                              fontsize=10)
    for ax in axes:
        ax.set_xlabel(r"circumferential angle $\varphi$ [deg]")
        ax.set_ylabel("axial position z [mm]")
    ctx.save(fig, f"fields_{safe_name(path.stem.removesuffix('_fields'))}.png")
