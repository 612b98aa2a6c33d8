"""Plots of a run (``rotorcosim plot DIR``): PNGs in ``DIR/plots/``, one module per figure.

What is drawn, when the data exist (see ``docs/analysis.md``):

* ``eccentricity.png``: eccentricity of every journal over time and over rotor
  speed, whirl onset / vanishing marked;
* ``orbit_<journal>.png``: journal orbits (x/c, y/c) with the clearance circle in
  three windows (before the onset, in the whirl, at the end), coloured by time;
* ``waterfall_<journal>.png``: run-up waterfall, frequency of the forward journal
  motion against rotor speed, colour = amplitude / clearance, 1x and 0.5x lines;
* ``fields_<name>.png``: pressure [bar] and fluid fraction over (phi [deg], z [mm])
  for every ``*_fields.npz`` (stationary runs), cavity (theta < 1) outlined; a
  half-Sommerfeld film: the pressure alone, its ruptured region (p = p0) outlined;
* ``signals_<instance>.png``: the recorded signals over time, one figure per
  instance, for a run without journals (any FMUs) or the ``signals`` picked
  (:mod:`orchestrator.results.plots.signals`).

The signals come from ``summary.json`` (the ``analysis.spec`` written by
:func:`orchestrator.results.whirl.analyze_run`), else the ``analysis:`` section of the
scenario file named in ``summary.json``, else they are inferred from the column
names (``<inst>.omega``, ``<inst>.x_<i>``/``<inst>.y_<i>``, ``<inst>.eps``).
Whatever cannot be drawn is skipped with a ``UserWarning`` that says why.
Uses matplotlib's object API with the Agg canvas (no pyplot, no display).
"""

from __future__ import annotations

import warnings
from pathlib import Path

import numpy as np

from orchestrator.errors import CosimError, path_arg
from orchestrator.results.plots import eccentricity, fields, orbit, waterfall
from orchestrator.results.plots.common import PlotContext, infer_spec, logger
from orchestrator.results.plots.signals import pick, plot_signals

__all__ = ["plot_run", "plot_result", "draw_all", "infer_spec", "PlotContext"]

#: journals drawn by one plot (an orbit and a waterfall each, and a line of the eccentricity
#: figure); the rest are named in a note. A summary.json listing 2000 journals (or a results.csv
#: of 2000 x_i/y_i column pairs) kept `plot` drawing 4000 figures (still at it after 5 minutes)
MAX_JOURNALS = 50


def plot_run(run_dir: str | Path, signals: list[str] | None = None) -> list[Path]:
    """Write the plots of a run into ``run_dir/plots/``; return the written files.

    A run without journals (any third-party system) gets the time histories of its
    recorded signals; ``signals`` (names or ``*`` patterns) picks which, and draws
    them also for a run with journals.

    Skips (with a ``UserWarning`` naming file, signal and fix) what the run's
    files do not support. Raises :class:`CosimError` when ``run_dir`` is not a
    directory or nothing at all could be plotted.
    """
    run_dir = path_arg(run_dir, "plot_run(run_dir)", "plot_run('runs/quickstart')")
    if not run_dir.is_dir():
        raise CosimError(f"{run_dir}: not a directory; give the output directory of a run "
                         "(the one holding results.csv and summary.json)")
    ctx = PlotContext.from_run_dir(run_dir)
    if signals:                      # a pattern that matches nothing is a typo: say so before drawing
        names = [c for c in ctx.cols if c != "time"]
        unmatched = pick(names, signals)[1]
        if unmatched:
            shown = ", ".join(names[:12]) + (", ..." if len(names) > 12 else "") if names else "none"
            raise CosimError(f"{run_dir}: --signals {' '.join(repr(p) for p in unmatched)}: no recorded signal "
                             f"matches (recorded in results.csv: {shown}); give column names of results.csv or "
                             "'*' patterns such as 'rotor.*'")
    return _finish(draw_all(ctx, signals=signals), run_dir)


def plot_result(res, out_dir: str | Path, *, name: str = "run", spec=None) -> list[Path]:
    """The same figures of an in-memory :class:`~orchestrator.results.result.CoSimResult`
    (``spec``: the analysis spec; default ``res.analysis["spec"]`` or inferred), into ``out_dir``."""
    return _finish(draw_all(PlotContext.from_result(res, Path(out_dir), name=name, spec=spec)), Path(out_dir))


def _finish(ctx: PlotContext, where: Path) -> list[Path]:
    for msg in ctx.notes:
        warnings.warn(f"plot {where}: {msg}", UserWarning, stacklevel=3)
    for msg in dict.fromkeys(ctx.skipped):     # each reason once, in order
        warnings.warn(f"plot {where}: skipped {msg}", UserWarning, stacklevel=3)
    if not ctx.written:
        raise CosimError(f"{where}: nothing to plot: " + "; ".join(ctx.skipped))
    return ctx.written


def draw_all(ctx: PlotContext, signals: list[str] | None = None) -> PlotContext:
    """Every figure the context's data support (the rest is listed in ``ctx.skipped``).

    NaN and infinite samples leave gaps; numpy's RuntimeWarnings about them are not passed on
    (the rows without any finite value are named by :meth:`PlotContext.drop_nonfinite_rows`)."""
    with np.errstate(all="ignore"), warnings.catch_warnings():
        warnings.simplefilter("ignore", RuntimeWarning)
        return _draw_all(ctx, signals)


def _draw_all(ctx: PlotContext, signals: list[str] | None) -> PlotContext:
    if ctx.cols.get("time", np.empty(0)).size >= 2:
        ctx.spec, src = ctx.load_spec()
        journals = ctx.spec.get("journals") or {}
        if len(journals) > MAX_JOURNALS:
            ctx.notes.append(f"{len(journals)} journals in the analysis spec ({src}); the first {MAX_JOURNALS} "
                             f"are drawn, the other {len(journals) - MAX_JOURNALS} are not "
                             "(orchestrator.results.plots.MAX_JOURNALS)")
            ctx.spec = {**ctx.spec, "journals": dict(list(journals.items())[:MAX_JOURNALS])}
        logger.info("plot signals from %s: %s", src, ctx.spec)
        if not ctx.spec.get("journals") or signals:
            output = ctx.summary.get("output")
            files, notes = plot_signals(ctx.cols, ctx.out, ctx.name, signals,
                                        units=output.get("units") if isinstance(output, dict) else None)
            ctx.written += files
            ctx.skipped += notes
        if not ctx.spec.get("journals"):
            logger.info("journal plots: no journals in the analysis spec (%s); drew the recorded signals", src)
        else:
            ctx.load_analysis()
            eccentricity.draw(ctx)
            for jn in ctx.spec["journals"]:
                orbit.draw(ctx, jn)
                waterfall.draw(ctx, jn)
    elif "time" in ctx.cols:
        ctx.skipped.append(f"time histories: results.csv has {ctx.cols['time'].size} row(s) with a finite "
                           "signal, need 2 (did the run stop before its second output row?)")
    fields.draw(ctx)
    return ctx
