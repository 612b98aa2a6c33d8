"""The map of a sweep folder (``rotorcosim plot DIR`` when DIR holds sweep.csv).

For every collected value: over one parameter a line with markers (runs without a value
marked with a red x at the bottom of the axes); over two parameters a heat map of the
value with the numbers printed in the cells and runs without a value drawn as a hatched
cell labelled with their status. A run that stopped early (``failed``: a run-up whose
journal reached the shell after the whirl set in, the usual end of a half-Sommerfeld run
through whip) but has a value - its summary holds the analysis of the rows it computed,
e.g. the onset - is drawn with its value and marked (hollow marker / its status under the
number): its onset and threshold are as valid as those of a finished run, a maximum is the
maximum up to its stop. With more parameters the map is over the first two, which must
then identify each run (the others derived from them, as in a zip sweep that also sets a
seed or a clearance per point); when the first parameter alone identifies each run (a zip
sweep along one parameter with derived columns such as seeds) the plot is a line over it.
An axis of a parameter that sets an FMU's switch shows the names that FMU declares for the
values (``half-Sommerfeld (0)``), which the sweep recorded in sweep.json; other axes show numbers.
PNGs go to ``DIR/plots/sweep_<value>.png``. matplotlib's object API with the Agg canvas.
"""

from __future__ import annotations

import math
import re
import warnings
from pathlib import Path

from orchestrator.errors import CosimError, path_arg
from orchestrator.results.safe_write import figure_folder, save_figure
from orchestrator.sweep.table import read_table
from orchestrator.sweep.units import MAX_UNIT_CHARS

__all__ = ["plot_sweep", "is_sweep_dir"]

DPI = 110
MAX_LABELLED_CELLS = 400      # heat maps with more cells get no numbers in them and a fixed size
MAX_MAP_CELLS = 250_000       # a larger grid of the first two parameters is drawn as points, one per run
MAX_TICKS = 30                # tick labels per axis (every k-th value beyond)
_VALUE_KEY = re.compile(r"-?(0|[1-9][0-9]{0,9})")    # a value of a switch as sweep.json writes it


def is_sweep_dir(path: str | Path) -> bool:
    return (Path(path) / "sweep.csv").is_file()


def _figure(size=(6.4, 4.4)):
    from matplotlib.backends.backend_agg import FigureCanvasAgg
    from matplotlib.figure import Figure
    fig = Figure(figsize=size, dpi=DPI)
    FigureCanvasAgg(fig)
    return fig


def _fmt(v) -> str:
    if v is None or (isinstance(v, float) and not math.isfinite(v)):
        return ""
    if isinstance(v, float):
        return f"{v:.4g}"
    return str(v)


def _line(rows, p: str, col: str, path: Path, label: dict, title: str, names: dict) -> None:
    fig = _figure()
    ax = fig.add_subplot()
    xs = sorted({r[p] for r in rows}, key=_order)
    at = None
    if any(isinstance(v, str) for v in xs):       # texts (or texts and numbers): one place per value, in order
        at = {v: k for k, v in enumerate(xs)}
        rows = [{**r, p: at[r[p]]} for r in rows]
    valued = sorted(((r[p], r[col], r["status"]) for r in rows if r[col] is not None), key=lambda t: _order(t[0]))
    pts = [(x, y) for x, y, _ in valued]
    early = [(x, y) for x, y, st in valued if st != "finished"]
    if at is not None:
        ax.set_xticks(*_ticks(xs))
    elif names.get(p):                            # a switch: its values by name
        ax.set_xticks(xs, [_tick_text(v, names[p]) for v in xs])
    if pts:
        ax.plot([x for x, _ in pts], [y for _, y in pts], "o-", color="C0", label=f"{col}")
    if early:
        ax.plot([x for x, _ in early], [y for _, y in early], "o", ms=11, mfc="none", mec="C3", mew=1.5,
                label="run stopped early (" + ", ".join(sorted({st for _, _, st in valued if st != "finished"}))
                + "): value up to its stop")
    bad = [r[p] for r in rows if r[col] is None]
    if bad:
        y0 = min((y for _, y in pts), default=0.0)
        ax.plot(bad, [y0] * len(bad), "x", color="C3", ms=9, mew=2,
                label="no value (" + ", ".join(sorted({r["status"] for r in rows if r[col] is None})) + ")")
    ax.set_xlabel(label[p])
    ax.set_ylabel(label[col])
    ax.set_title(title + ("" if pts else " (no run computed a value)"), fontsize=10)
    ax.grid(True, alpha=0.3)
    ax.legend(fontsize=8)
    fig.tight_layout()
    save_figure(fig, path)


def _order(v):
    """Sort key of parameter values: numbers (and booleans) first, then texts."""
    return (isinstance(v, str), v if isinstance(v, str) else float(v), str(v))


def _ticks(values, names: dict | None = None) -> tuple[list[int], list[str]]:
    """Tick positions and labels, at most :data:`MAX_TICKS` of them (every k-th value);
    ``names``: value -> name of a switch axis (:func:`_value_names`)."""
    step = max(1, math.ceil(len(values) / MAX_TICKS))
    at = list(range(0, len(values), step))
    return at, [_tick_text(values[k], names) for k in at]


def _tick_text(v, names: dict | None) -> str:
    if names and _as_int(v) in names:
        return f"{names[_as_int(v)]} ({_fmt(v)})"
    return _fmt(v)


def _as_int(v):
    if isinstance(v, bool) or not isinstance(v, (int, float)) or not math.isfinite(v) or v != int(v):
        return None
    return int(v)


def _value_names(entry: dict, values) -> dict | None:
    """{value: name} of a parameter of sweep.json whose entry carries the names its FMU declares
    for the values of the switch it sets (``"value_names": {"0": "half-Sommerfeld", ...}``,
    written by the sweep: :func:`orchestrator.sweep.units.sweep_labels`), when every value the
    runs have is named; else None (the axis keeps the numbers). sweep.json may come from anyone:
    the names are checked by the rules of the FMU's declaration
    (:func:`orchestrator.fmi.model_description.checked_value_names`) and any problem gives none."""
    from orchestrator.fmi.model_description import MAX_VALUE_NAMES, checked_value_names
    raw = entry.get("value_names")
    if not isinstance(raw, dict) or len(raw) > MAX_VALUE_NAMES:
        return None
    pairs = []
    for key, name in raw.items():
        if not isinstance(key, str) or not _VALUE_KEY.fullmatch(key):
            return None
        pairs.append((int(key), name))
    names = checked_value_names(pairs, least=1)
    if not names or not all(_as_int(v) in names for v in values):
        return None
    return names


def _heat(rows, p: str, q: str, col: str, path: Path, label: dict, title: str, names: dict) -> None:
    import numpy as np
    xs = sorted({r[p] for r in rows}, key=_order)
    ys = sorted({r[q] for r in rows}, key=_order)
    xi = {v: j for j, v in enumerate(xs)}
    yi = {v: i for i, v in enumerate(ys)}
    if len(xs) * len(ys) > MAX_MAP_CELLS:         # sparse (a random draw of a large grid): points
        _scatter(rows, p, q, col, xs, ys, xi, yi, path, label, title, names)
        return
    z = np.full((len(ys), len(xs)), np.nan)
    status = {}
    for r in rows:
        i, j = yi[r[q]], xi[r[p]]
        status[(i, j)] = r["status"]
        if r[col] is not None:                     # a run that stopped early keeps what it computed
            z[i, j] = r[col]
    # a cell per value pair with its number printed in it up to MAX_LABELLED_CELLS cells; a larger
    # map (up to plan.MAX_RUNS runs) is drawn at a bounded size, unfinished runs as red crosses
    labelled = len(xs) * len(ys) <= MAX_LABELLED_CELLS
    if labelled:
        size = (1.6 + 1.15 * len(xs), 1.4 + 0.75 * len(ys)) if len(xs) > 4 else (6.4, 4.6)
    else:
        size = (10.0, 8.0)
    fig = _figure(size)
    ax = fig.add_subplot()
    finite = z[np.isfinite(z)]
    cmap, norm = _colours(finite)
    im = ax.imshow(z, origin="lower", aspect="auto", cmap=cmap, norm=norm)
    if finite.size:                               # a colour bar of no values showed a made-up -0.1..0.1
        _colour_bar(fig, ax, im, label[col], finite)
    else:
        title += " (no run computed a value)"
    mid = 0.5 * (finite.min() + finite.max()) if finite.size else 0.0
    if labelled:
        for (i, j), st in status.items():
            if np.isfinite(z[i, j]):
                ax.text(j, i, _fmt(float(z[i, j])) + ("" if st == "finished" else f"\n({st})"), ha="center",
                        va="center", fontsize=8, color="black" if z[i, j] > mid else "white")
            else:
                ax.add_patch(_hatch(j, i))
                ax.text(j, i, st if st != "finished" else "no value", ha="center", va="center", fontsize=8,
                        color="C3", fontweight="bold", bbox={"facecolor": "white", "edgecolor": "none", "pad": 1.5})
    else:
        bad = [(j, i) for (i, j) in status if not np.isfinite(z[i, j])]
        early = [(j, i) for (i, j), st in status.items() if np.isfinite(z[i, j]) and st != "finished"]
        if bad:
            ax.plot([j for j, _ in bad], [i for _, i in bad], "x", color="C3", ms=4, mew=1, label="no value")
        if early:
            ax.plot([j for j, _ in early], [i for _, i in early], "o", ms=4, mfc="none", mec="C3", mew=1,
                    label="run stopped early: value up to its stop")
        if bad or early:
            ax.legend(fontsize=8, loc="upper right")
    _finish_map(fig, ax, label[p], label[q], xs, ys, title, path, names.get(p), names.get(q))


def _colours(finite):
    """(colour map, norm) of a map's values: viridis over their range; one colour when every
    value is the same (matplotlib would spread it over a made-up value +- 0.1)."""
    from matplotlib.colors import ListedColormap, Normalize
    if finite.size and float(finite.min()) == float(finite.max()):
        v = float(finite[0])
        half = 0.5 * abs(v) if v != 0.0 and math.isfinite(0.5 * abs(v)) and v - 0.5 * abs(v) != v else 1.0
        from matplotlib import colormaps
        return ListedColormap([colormaps["viridis"](0.5)]), Normalize(v - half, v + half)
    return "viridis", None


def _colour_bar(fig, ax, mappable, label: str, finite) -> None:
    """The colour bar; for a map whose values are all the same, a one-colour bar with one tick,
    the value, and a label that says so."""
    if float(finite.min()) == float(finite.max()):
        v = float(finite[0])
        bar = fig.colorbar(mappable, ax=ax, label=f"{label}: {_fmt(v)} in every run")
        bar.set_ticks([v], labels=[_fmt(v)])
    else:
        fig.colorbar(mappable, ax=ax, label=label)


def _scatter(rows, p: str, q: str, col: str, xs, ys, xi, yi, path: Path, label: dict, title: str,
             names: dict) -> None:
    """The map of runs that cover a small part of a large grid: one coloured point per run with a
    value, a red cross per run without (memory per run, not per grid cell)."""
    fig = _figure((10.0, 8.0))
    ax = fig.add_subplot()
    good = [r for r in rows if r[col] is not None]
    bad = [r for r in rows if r[col] is None]
    early = [r for r in good if r["status"] != "finished"]
    if good:
        import numpy as np
        finite = np.array([r[col] for r in good], dtype=float)
        cmap, norm = _colours(finite)
        sc = ax.scatter([xi[r[p]] for r in good], [yi[r[q]] for r in good], c=finite, cmap=cmap, norm=norm, s=16)
        _colour_bar(fig, ax, sc, label[col], finite)
    if bad:
        ax.plot([xi[r[p]] for r in bad], [yi[r[q]] for r in bad], "x", color="C3", ms=5, mew=1, label="no value")
    if early:
        ax.plot([xi[r[p]] for r in early], [yi[r[q]] for r in early], "o", ms=7, mfc="none", mec="C3", mew=1,
                label="run stopped early: value up to its stop")
    if bad or early:
        ax.legend(fontsize=8, loc="upper right")
    _finish_map(fig, ax, label[p], label[q], xs, ys, f"{title} ({len(rows)} runs)"
                + ("" if good else " (no run computed a value)"), path, names.get(p), names.get(q))


def _finish_map(fig, ax, p: str, q: str, xs, ys, title: str, path: Path, x_names=None, y_names=None) -> None:
    """Ticks (turned when many; a switch's values by name), axis labels ``p``, ``q`` and title
    of a map; saved."""
    ax.set_xticks(*_ticks(xs, x_names))
    ax.set_yticks(*_ticks(ys, y_names))
    if len(xs) > MAX_TICKS // 2:
        ax.tick_params(axis="x", labelrotation=60)
    ax.set_xlabel(p)
    ax.set_ylabel(q)
    ax.set_title(title, fontsize=10)
    fig.tight_layout()
    save_figure(fig, path)


def _hatch(j, i):
    from matplotlib.patches import Rectangle
    return Rectangle((j - 0.5, i - 0.5), 1, 1, fill=False, hatch="xx", edgecolor="0.7", lw=0)


def _unit_text(unit) -> str | None:
    """A unit of sweep.json as an axis label shows it ('1' as '-', 'Pa.s' as 'Pa s'); None when
    it is no short printable text (sweep.json may come from anyone)."""
    if not isinstance(unit, str) or not unit or len(unit) > MAX_UNIT_CHARS or not unit.isprintable():
        return None
    return "-" if unit == "1" else unit.replace(".", " ")


def _labels(meta: dict, params: list[str], values: list[str]) -> dict[str, str]:
    """Axis label per column: its name and, when sweep.json has it, its unit (``eta0 [Pa s]``)."""
    units = {e["name"]: e.get("unit") for e in meta["parameters"]}
    collect_units = meta.get("collect_units")
    if isinstance(collect_units, dict):
        units.update({k: v for k, v in collect_units.items() if k in values})
    label = {}
    for name in params + values:
        unit = _unit_text(units.get(name))
        label[name] = f"{name} [{unit}]" if unit else name
    return label


def plot_sweep(out_dir: str | Path) -> list[Path]:
    """Draw the map of every collected value of the sweep in ``out_dir``; return the PNGs."""
    out_dir = path_arg(out_dir, "plot_sweep(out_dir)", "plot_sweep('runs/sweep_x')")
    if not is_sweep_dir(out_dir):
        raise CosimError(f"{out_dir}: no sweep.csv here; give the --out folder of `rotorcosim sweep`")
    rows, meta = read_table(out_dir)              # bounded and checked: raises InputError naming file:line
    params = [p["name"] for p in meta["parameters"]]
    values = list(meta.get("collect", {}))
    if not rows:
        raise CosimError(f"{out_dir}/sweep.csv: no runs (only the header); rerun the sweep")
    if not values:
        raise CosimError(f"{out_dir}: the sweep collects no values, so there is no map to draw; add a 'collect:' "
                         "section to the sweep file and rerun it with --resume")
    if len(params) > 2 and len({(r[params[0]], r[params[1]]) for r in rows}) < len(rows):
        raise CosimError(f"{out_dir}: maps are drawn over the first two parameters ({params[0]}, {params[1]}), "
                         f"and in this sweep the other parameters vary on their own; read sweep.csv (or "
                         "sweep.parquet) with pandas for other views")
    figure_folder(out_dir / "plots")
    label = _labels(meta, params, values)
    scenario = meta.get("scenario")
    of = f" ({Path(scenario).stem[:60]})" if isinstance(scenario, str) and scenario else ""
    names = {e["name"]: _value_names(e, {r[e["name"]] for r in rows}) for e in meta["parameters"]}
    written = []
    import matplotlib
    # every text drawn as written: a unit ('$\Omega$'), scenario name or text value from sweep.json or
    # sweep.csv with two '$' was parsed as mathtext, and one it cannot parse made the map raise
    with matplotlib.rc_context({"text.parse_math": False}):
        for col in values:
            path = out_dir / "plots" / f"sweep_{col}.png"
            if (len(params) == 1 or len({r[params[1]] for r in rows}) == 1
                    or len({r[params[0]] for r in rows}) == len(rows)):     # the first alone identifies each run
                _line(rows, params[0], col, path, label, f"{col} over {params[0]}{of}", names)
            else:
                _heat(rows, params[0], params[1], col, path, label, f"{col} over {params[0]} and {params[1]}{of}",
                      names)
            written.append(path)
    return written
