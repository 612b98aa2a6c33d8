"""``fields_<name>.png``: pressure [bar] and fluid fraction over (phi [deg], z [mm]) of each field file.

The cavity (theta < 1) is hatched and outlined on both panels.

A half-Sommerfeld film (the file's ``cavitation`` = 0) has no fluid fraction (theta is 1 by
definition): its figure is the pressure alone, with the ruptured region (pressure clipped to
``p0``) hatched and outlined, and says so in its title. A file without ``cavitation`` (written
before 2026-12-06, or by another tool) whose theta is 1 everywhere gets the pressure alone too,
as that panel would show nothing.
"""

from __future__ import annotations

import os
from pathlib import Path

import numpy as np

from orchestrator.results.plots.common import PlotContext, plain, safe_name


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


MAX_FIELD_FILE_BYTES = 256 * 2**20
"""bytes of one ``*_fields.npz`` file (our bearings write well below 10 MiB)"""
MAX_FIELD_VALUES = 2**20
"""values of one array in it (our bearings refuse films of more than 262 144 cells)"""
_FIELD_ARRAYS = ("phi", "z", "p", "theta")
_FIELD_SCALARS = ("cavitation", "p0")       # optional: the film model and the ambient pressure


def read_fields(path: Path) -> dict[str, np.ndarray]:
    """The arrays phi, z, p (and theta if present) of a field file, read as untrusted input: a
    regular file (no FIFO or device) of at most :data:`MAX_FIELD_FILE_BYTES`, each array a
    number array of at most :data:`MAX_FIELD_VALUES` values, as its header says (checked before
    numpy allocates it: a small file may declare an array of gigabytes), phi and z 1-D with at
    least 2 values and p, theta of shape (n_z, n_phi). ``ValueError`` saying what is wrong
    otherwise."""
    import zipfile

    from orchestrator.untrusted import InputError, open_regular
    try:
        fh = open_regular(path, what="field file")
    except InputError as exc:
        raise ValueError(str(exc)) from None
    with fh:
        size = os.fstat(fh.fileno()).st_size
        if size > MAX_FIELD_FILE_BYTES:
            raise ValueError(f"{size} bytes, more than the {MAX_FIELD_FILE_BYTES} a field file may have "
                             "(orchestrator.results.plots.fields.MAX_FIELD_FILE_BYTES)")
        try:
            zf = zipfile.ZipFile(fh)
        except zipfile.BadZipFile:
            raise ValueError("not a numpy .npz archive") from None
        with zf:
            names = set(zf.namelist())
            out = {}
            for key in _FIELD_ARRAYS:
                if f"{key}.npy" not in names:
                    if key == "theta":
                        continue
                    held = sorted(n.removesuffix(".npy") for n in names)[:10]
                    raise ValueError(f"no array '{key}' (it holds {held})")
                out[key] = _read_array(zf, key)
            for key in _FIELD_SCALARS:
                if f"{key}.npy" in names:
                    out[key] = _read_array(zf, key)
    for key in _FIELD_SCALARS:
        if key in out and (out[key].size != 1 or not np.isfinite(out[key]).all()):
            raise ValueError(f"'{key}' is {out[key].ravel()[:3]} of shape {out[key].shape}, expected one finite number")
    if "cavitation" in out and float(out["cavitation"]) not in (0.0, 1.0):
        raise ValueError(f"'cavitation' is {float(out['cavitation']):g}, expected 0 (half-Sommerfeld) or 1 "
                         "(mass-conserving)")
    phi, z, p = out["phi"], out["z"], out["p"]
    for key, a in (("phi", phi), ("z", z)):
        if a.ndim != 1 or a.size < 2:
            raise ValueError(f"'{key}' has shape {a.shape}, expected a 1-D array of at least 2 values")
    for key in ("p", "theta"):
        if key in out and out[key].shape != (z.size, phi.size):
            raise ValueError(f"{key} has shape {out[key].shape}, expected (n_z, n_phi) = ({z.size}, {phi.size})")
        if key in out and not np.isfinite(out[key]).all():
            raise ValueError(f"'{key}' holds NaN or infinite values (a diverged run?)")
    return out


def _read_array(zf, key: str) -> np.ndarray:
    with zf.open(f"{key}.npy") as f:
        try:
            version = np.lib.format.read_magic(f)
            shape, fortran, dtype = (np.lib.format.read_array_header_1_0(f) if version == (1, 0)
                                     else np.lib.format.read_array_header_2_0(f))
        except ValueError as exc:
            raise ValueError(f"'{key}' is not a numpy array ({exc})") from None
        count = int(np.prod(shape, dtype=object))
        if dtype.kind not in "biuf":
            raise ValueError(f"'{key}' holds {dtype} values, expected numbers")
        if count > MAX_FIELD_VALUES:
            raise ValueError(f"'{key}' declares shape {shape} ({count} values), more than the {MAX_FIELD_VALUES} "
                             "an array of a field file may have (orchestrator.results.plots.fields.MAX_FIELD_VALUES)")
        data = f.read(count * dtype.itemsize + 1)
    if len(data) != count * dtype.itemsize:
        raise ValueError(f"'{key}' declares {count} values of {dtype} but holds {len(data)} bytes")
    a = np.frombuffer(data, dtype=dtype).reshape(shape, order="F" if fortran else "C")
    return a.astype(float)

def field_plot(ctx: PlotContext, path: Path) -> None:
    from matplotlib.figure import Figure
    d = read_fields(path)
    phi, zz, p, theta = d["phi"], d["z"], d["p"], d.get("theta")
    model = int(d["cavitation"]) if "cavitation" in d else None
    hs = model == 0
    note = None
    if hs:
        theta = None
    elif model is None and theta is not None and np.all(theta == 1.0):
        theta, note = None, r"fluid fraction $\vartheta$ = 1 everywhere (full film or half-Sommerfeld): not drawn"
    n = 2 if theta is not None else 1
    fig = Figure(figsize=(7, 3.3 * n + (0.5 if note or hs else 0.0)), layout="constrained")
    axes = fig.subplots(n, 1, squeeze=False)[:, 0]
    P_, Z_ = np.degrees(phi), zz * 1e3
    cp = axes[0].contourf(P_, Z_, p / 1e5, levels=30, cmap="viridis")
    fig.colorbar(cp, ax=axes[0], label="pressure p [bar]")
    title = (f"{plain(ctx.name)}: {plain(path.stem)}  (p_max {p.max() / 1e5:.4g} bar, "
             f"p_min {p.min() / 1e5:.4g} bar)")
    if hs:
        p0 = float(d["p0"]) if "p0" in d else float(p.min())
        ruptured = p <= p0 + 1e-9 * max(float(np.max(np.abs(p))), 1.0)
        note = (r"half-Sommerfeld film: no fluid fraction ($\vartheta$ = 1 by definition)" "\n"
                + (f"hatched, red outline: ruptured, p clipped to p0 = {p0 / 1e5:.4g} bar "
                   f"({100 * ruptured.mean():.0f} % of the film)" if ruptured.any() else "no ruptured region"))
        if ruptured.any() and not ruptured.all():
            axes[0].contour(P_, Z_, ruptured.astype(float), levels=[0.5], colors="r", linewidths=1.0)
            axes[0].contourf(P_, Z_, ruptured.astype(float), levels=[0.5, 1.5], colors="none", hatches=["//"])
    axes[0].set_title(title + (f"\n{note}" if note else ""), fontsize=10)
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
