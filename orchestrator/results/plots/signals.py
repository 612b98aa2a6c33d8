"""Time histories of the recorded signals of any run (``rotorcosim plot DIR [--signals ...]``).

One figure per FMU instance, ``plots/signals_<instance>.png``, with one panel per
signal over time. Integer and Boolean signals (whole numbers in results.csv) are
drawn as steps held over the macro step, as the master holds them; String columns
cannot be drawn and are skipped with a note. ``signals`` picks columns by name or
pattern (``*`` = any characters, see :mod:`orchestrator.names`: ``osc.x[*]``,
``bearing1.*``), default every column. Panels per figure are capped at
:data:`MAX_PANELS`; more signals of one instance go to ``signals_<instance>_2.png``
and so on, and at most :data:`MAX_FIGURES` figures are drawn (a note names how many signals
were left out and how to pick them with ``--signals``).
"""

from __future__ import annotations

import math
import re
from pathlib import Path
from typing import Any, Mapping, Sequence

import numpy as np

from orchestrator.results.plots.common import plain, span_problem
from orchestrator.results.safe_write import save_figure

MAX_PANELS = 8
MAX_FIGURES = 100        # signal figures of one plot (800 panels); a folder of 20 000 columns took hours
MAX_POINTS = 20000       # points per trace above which the trace is decimated by striding
DPI = 110
MAX_UNIT_CHARS = 40      # a longer "unit" in summary.json is not used as a label


def pick(columns: Sequence[str], patterns: Sequence[str] | None) -> tuple[list[str], list[str]]:
    """Columns matching any pattern (a name, or ``*`` wildcards), and the patterns that matched none."""
    from orchestrator.names import match
    if not patterns:
        return list(columns), []
    chosen, unmatched = [], []
    for pat in patterns:
        hits = match(pat, columns)
        if not hits:
            unmatched.append(pat)
        chosen += [c for c in hits if c not in chosen]
    return chosen, unmatched


def _safe(name: str) -> str:
    return re.sub(r"[^A-Za-z0-9_.-]+", "_", name) or "signals"


def plot_signals(cols: dict[str, np.ndarray], out_dir: Path, title: str,
                 patterns: Sequence[str] | None = None,
                 units: Mapping[str, Any] | None = None) -> tuple[list[Path], list[str]]:
    """Draw the signals of ``cols`` (``{"time": t, "inst.var": values}``) into ``out_dir``.

    ``units``: ``{column: unit}`` (summary.json's ``output.units``, from the FMUs' model
    descriptions); a panel is labelled ``var [unit]``, ``var`` alone without one.
    Returns ``(written files, notes on what was skipped)``.
    """
    units = unit_labels(units)
    from matplotlib.backends.backend_agg import FigureCanvasAgg
    from matplotlib.figure import Figure

    t = np.asarray(cols.get("time", np.empty(0)), dtype=float)
    names = [c for c in cols if c != "time"]
    chosen, unmatched = pick(names, patterns)
    notes = [f"--signals {p!r}: no recorded signal matches (recorded: {', '.join(names[:12])}"
             f"{', ...' if len(names) > 12 else ''})" for p in unmatched]
    if t.size < 2:
        return [], notes + [f"signal plots: {t.size} row(s) in results.csv, need 2"]
    groups: dict[str, list[str]] = {}
    for c in chosen:
        y = _numbers(cols[c])
        if y is None or np.all(np.isnan(y)):
            notes.append(f"signal plots: '{c}' has no numeric values (a String signal?); not drawn")
            continue
        why = span_problem(y)
        if why:
            notes.append(f"signal plots: '{c}' {why}; not drawn")
            continue
        groups.setdefault(c.split(".", 1)[0], []).append(c)      # a name without '.': its own group
    out_dir.mkdir(parents=True, exist_ok=True)
    stride = max(1, t.size // MAX_POINTS)
    written = []
    drawn = 0
    for inst, sigs in groups.items():
        for k in range(0, len(sigs), MAX_PANELS):
            if len(written) >= MAX_FIGURES:
                break
            part = sigs[k:k + MAX_PANELS]
            drawn += len(part)
            fig = Figure(figsize=(8, 1.6 + 1.7 * len(part)), layout="constrained")
            FigureCanvasAgg(fig)
            axes = fig.subplots(len(part), 1, sharex=True, squeeze=False)[:, 0]
            for ax, c in zip(axes, part):
                y = _numbers(cols[c])
                whole = bool(np.all(np.isnan(y) | (y == np.round(y))))
                steady = steady_limits(y)
                scale = steady_scale(steady)    # a huge steady signal is drawn divided by it
                ax.plot(t[::stride], y[::stride] / scale, lw=0.9, drawstyle="steps-post" if whole else "default")
                if steady is not None:          # rounding noise, not a signal: a flat line, plain ticks
                    ax.set_ylim(*(steady_limits(y / scale) if scale != 1.0 else steady))
                    ticks = steady_ticks(steady, y)
                    if ticks is not None:      # labelled here: matplotlib's formatter overflows there too
                        ax.set_yticks([v / scale for v in ticks], labels=[f"{v:.7g}" for v in ticks])
                    else:
                        ax.ticklabel_format(axis="y", useOffset=False)
                unit = units.get(c)
                ax.set_ylabel(plain(c.split(".", 1)[-1]) + (f" [{unit}]" if unit else ""), rotation=0, ha="right",
                              va="center")
                ax.grid(True, lw=0.3)
            axes[-1].set_xlabel("time [s]")
            fig.suptitle(f"{plain(title)}: {plain(inst)}")
            path = out_dir / f"signals_{_safe(inst)}{'' if k == 0 else f'_{k // MAX_PANELS + 1}'}.png"
            save_figure(fig, path, dpi=DPI)
            written.append(path)
    left = sum(len(sigs) for sigs in groups.values()) - drawn
    if left:
        notes.append(f"signal plots: {left} more signals not drawn (at most {MAX_FIGURES} figures of {MAX_PANELS} "
                     "panels; orchestrator.results.plots.signals.MAX_FIGURES); pick them with --signals PATTERN")
    return written, notes


#: a signal whose values differ by at most this fraction of their size is drawn as constant
STEADY_SPAN = 1e-9
#: the least half-height of a steady signal's axis (0.1 % of a value below 1e-297 is no normal float)
STEADY_MIN_PAD = 1e-300
#: from this magnitude on, a steady signal's tick is its value (matplotlib's tick finder overflows)
HUGE = 1e300
_FMAX = float(np.finfo(float).max)


def steady_limits(y: np.ndarray) -> tuple[float, float] | None:
    """y-limits for a signal that is constant up to rounding (its finite values within
    :data:`STEADY_SPAN` of their size): the value +- 0.1 %. Left to matplotlib, such a signal
    filled its panel with the rounding noise under an offset (a stationary bearing's Fx, which
    varies by 1e-10 of itself, looked like a wandering signal). None for any other signal.

    Any finite magnitude: the limits stay finite (clipped to the largest float, so a signal at
    1.8e308 sits at the top edge) and distinct (at least +- :data:`STEADY_MIN_PAD` around a
    value so small that 0.1 % of it is no normal number, e.g. 5e-324); matplotlib's warning
    "Attempting to set identical low and high ylims" and its ValueErrors ("Axis limits cannot be
    NaN or Inf") came from such values."""
    v = y[np.isfinite(y)]
    if v.size == 0:
        return None
    lo, hi = float(v.min()), float(v.max())
    size = max(abs(lo), abs(hi))
    with np.errstate(over="ignore"):
        if not hi - lo <= STEADY_SPAN * size:       # (hi - lo may overflow to inf)
            return None
    if size == 0:
        return -1.0, 1.0
    pad = max(1e-3 * size, STEADY_MIN_PAD)
    return max(lo - pad, -_FMAX), min(hi + pad, _FMAX)


def steady_scale(limits: tuple[float, float] | None) -> float:
    """What a steady signal of :data:`HUGE` magnitude or more is divided by to be drawn (a power
    of ten: its values then lie in [1, 10), its tick labelled with the true value): Agg drew an
    empty panel, without even its frame, for a line at 1e308. 1.0 for any other signal."""
    if limits is None:
        return 1.0
    size = max(abs(limits[0]), abs(limits[1]))
    return 10.0 ** math.floor(math.log10(size)) if size >= HUGE else 1.0


def steady_ticks(limits: tuple[float, float], y: np.ndarray) -> list[float] | None:
    """The y tick of a steady signal (its value, to be labelled by the caller) when matplotlib's
    own tick finder and formatter fail on its limits: a magnitude of :data:`HUGE` or more
    ("arange: cannot compute length" and an OverflowError ended plot at 1e308), or limits
    within 1e-290 of each other (a value of 5e-324); None otherwise (matplotlib's ticks)."""
    v = y[np.isfinite(y)]
    size = max(abs(limits[0]), abs(limits[1]))
    if v.size == 0 or (size < HUGE and limits[1] - limits[0] >= 1e-290):
        return None
    return [float(np.sort(v)[v.size // 2])]        # a value of the signal (a mean may overflow)


def unit_labels(units: Any) -> dict[str, str]:
    """The usable entries of ``units`` (read from a summary.json, which may come from anyone): text
    of at most :data:`MAX_UNIT_CHARS` printable characters; ``$`` escaped (no mathtext); ``1`` shown as ``-``."""
    if not isinstance(units, Mapping):
        return {}
    out = {}
    for col, unit in units.items():
        if isinstance(col, str) and isinstance(unit, str) and 0 < len(unit) <= MAX_UNIT_CHARS and unit.isprintable():
            out[col] = "-" if unit == "1" else unit.replace("$", r"\$")     # FMI's "1": dimensionless
    return out


def _numbers(column) -> np.ndarray | None:
    """A column as float64, or None for text (a String signal of results.parquet comes as
    an object array of str; results.csv gives NaN for it)."""
    a = np.asarray(column)
    return None if a.dtype == object else a.astype(float)
