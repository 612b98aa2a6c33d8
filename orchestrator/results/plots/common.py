"""What every figure of :mod:`orchestrator.results.plots` shares: the :class:`PlotContext`
(the loaded signals, the analysis spec and result, where PNGs go, what was skipped) and
drawing helpers. A context comes from a run folder (:meth:`PlotContext.from_run_dir`, read
through :class:`~orchestrator.results.run_directory.RunDirectory`) or from an in-memory
:class:`~orchestrator.results.result.CoSimResult` (:meth:`PlotContext.from_result`).
"""

from __future__ import annotations

import logging
import os
import re
from pathlib import Path
from typing import Any, Mapping

import numpy as np

from orchestrator.errors import CosimError
from orchestrator.results.plots.checks import checked_result, checked_spec
from orchestrator.results.run_directory import RunDirectory
from orchestrator.results.safe_write import figure_folder, save_figure
from orchestrator.untrusted import InputError, load_yaml, read_text

logger = logging.getLogger("orchestrator.results.plots")

DPI = 110
ORBIT_REVS = 20          # revolutions shown per orbit window
MAX_ORBIT_POINTS = 1500  # orbit points per window (decimated above)
MAX_TRACE_POINTS = 4000  # above: min/max envelope per bin (looks the same, draws fast)


class PlotContext:
    """The data of one plotting call and its bookkeeping (``written``, ``skipped``).

    ``cols``: ``{"time": t, "inst.var": array}``; ``spec``: the analysis spec (journals,
    speed, whirl, fields); ``result``: the analysis result (``summary.json``'s ``analysis``);
    ``field_files``: film field files to draw; ``out``: the folder the PNGs go to.
    """

    def __init__(self, *, name: str, out: Path, cols: Mapping[str, np.ndarray] | None = None,
                 summary: Mapping[str, Any] | None = None, run_dir: Path | None = None):
        self.name = name
        self.out = Path(out)
        self.run_dir = run_dir
        self.cols: dict[str, np.ndarray] = dict(cols or {})
        self.summary: dict[str, Any] = dict(summary or {})
        self.spec: dict[str, Any] = {}
        self.result: dict[str, Any] = {}
        self.field_files: list[Path] = []
        self.written: list[Path] = []
        self.skipped: list[str] = []
        self.notes: list[str] = []           # about the run itself (e.g. it ended without a summary)

    @classmethod
    def from_run_dir(cls, run_dir: Path) -> "PlotContext":
        """The context of a finished (or failed) run folder; PNGs go to ``run_dir/plots``."""
        run = RunDirectory(run_dir)
        skipped = []
        summary: dict = {}
        if run.has_summary():
            try:
                summary = run.summary()
            except (OSError, ValueError, InputError) as exc:
                skipped.append(f"{run.summary_json.name} ({exc}); using results.csv only")
        ctx = cls(name=str(summary.get("scenario") or Path(run_dir).name), out=Path(run_dir) / "plots",
                  summary=summary, run_dir=Path(run_dir))
        ctx.skipped += skipped
        ctx.notes += _unfinished(summary, Path(run_dir))
        if run.has_results():
            try:           # there but unreadable (a FIFO, text in a number column, ...): no plot is right
                ctx.cols = run.columns()
            except (OSError, ValueError) as exc:
                raise CosimError(f"{exc}") from None
            ctx.drop_nonfinite_rows(run.results_file.name)
        else:
            ctx.skipped.append(f"time histories: {run.results_file} not found (the run wrote no results)")
        ctx.field_files = run.field_files()
        return ctx

    def drop_nonfinite_rows(self, fname: str) -> None:
        """Leave out the rows in which every numeric signal is NaN or infinite (a diverged run or
        an edited file would draw nothing there but numpy warnings), naming their lines."""
        numeric = [v for k, v in self.cols.items() if k != "time" and v.dtype.kind == "f"
                   and not np.all(np.isnan(v))]           # an all-NaN column is a String signal
        if not numeric or not self.cols.get("time", np.empty(0)).size:
            return
        empty = ~np.any(np.isfinite(np.column_stack(numeric)), axis=1)
        if not empty.any():
            return
        rows = np.flatnonzero(empty)
        self.skipped.append(f"{fname} {line_ranges(rows + 2)} ({rows.size} of {empty.size} rows): every signal "
                            "is NaN or infinite there (the run diverged, or the file was edited); those rows are "
                            "left out of the figures")
        self.cols = {k: v[~empty] for k, v in self.cols.items()}

    @classmethod
    def from_result(cls, res, out_dir: Path, *, name: str = "run",
                    spec: Mapping[str, Any] | None = None) -> "PlotContext":
        """The context of an in-memory result (``res.t``, ``res.outputs``, ``res.analysis``)."""
        summary: dict[str, Any] = {"scenario": name}
        if res.analysis is not None:
            summary["analysis"] = dict(res.analysis)
        if spec is not None:
            summary.setdefault("analysis", {})["spec"] = dict(spec)
        return cls(name=name, out=Path(out_dir), cols={"time": np.asarray(res.t), **res.outputs},
                   summary=summary)

    def load_spec(self) -> tuple[dict, str]:
        """The analysis spec: summary.json's, the scenario file's, or inferred from the columns
        (a run folder may come from anyone: bounded reads, every part checked)."""
        ana = self.summary.get("analysis")
        if isinstance(ana, Mapping) and isinstance(ana.get("spec"), Mapping):
            return self._checked_spec(ana["spec"], "summary.json")
        sf = self.summary.get("scenario_file")
        if isinstance(sf, str) and sf:
            try:          # the scenario named by summary.json: bounded reader, bounded YAML
                from orchestrator.scenario.nodes import YamlLoader      # the scenario's number rules
                doc = load_yaml(read_text(sf, what="scenario file"), display=sf, loader_cls=YamlLoader)
                if isinstance(doc, Mapping) and isinstance(doc.get("analysis"), Mapping):
                    return self._checked_spec(doc["analysis"], sf)
            except InputError as exc:
                self.skipped.append(f"the analysis section of the scenario named in summary.json ({exc})")
            except Exception as exc:  # noqa: BLE001 - yaml syntax errors: the inferred spec is used
                logger.info("cannot parse %s: %s", sf, exc)
        return infer_spec(self.cols), "inferred from results.csv column names"

    def _checked_spec(self, spec: Mapping, src: str) -> tuple[dict, str]:
        spec, problems = checked_spec(spec)
        self.skipped.extend(f"{p} in the analysis spec ({src})" for p in problems)
        return spec, src

    def load_analysis(self) -> None:
        """The whirl markers: summary.json's analysis, else analyse the run folder now."""
        result, problem = checked_result(self.summary.get("analysis"))
        if problem:
            self.skipped.append(f"the analysis in summary.json ({problem}); recomputed from results.csv")
        if result is not None:
            self.result = result
        elif self.spec.get("speed") and self.run_dir is not None:
            from orchestrator.results.whirl import analyze_run
            self.result = analyze_run(self.run_dir, self.spec)
        if "error" in self.result:
            self.skipped.append(f"whirl markers: {self.result['error']}")

    def signal(self, name: Any, what: str) -> np.ndarray | None:
        if isinstance(name, str) and name in self.cols:
            why = span_problem(self.cols[name])
            if why:
                self.skipped.append(f"{what}: results.csv column '{name}' {why}; not drawn")
                return None
            return self.cols[name]
        self.skipped.append(f"{what}: results.csv has no column '{name}'; columns: "
                            f"{sorted(self.cols)[:10]}; fix the analysis spec or output.signals")
        return None

    def journal(self, jn: str) -> dict:
        """Signals of one journal: t, x, y, eps, c, omega (None when missing)."""
        js = self.spec["journals"][jn] or {}
        jr = (self.result.get("journals") or {}).get(jn) or {}
        c = js.get("clearance") or jr.get("clearance")
        return {"t": self.cols["time"],
                "x": self.signal(js.get("x"), f"journal '{jn}' x") if js.get("x") else None,
                "y": self.signal(js.get("y"), f"journal '{jn}' y") if js.get("y") else None,
                "eps": self.signal(js.get("eps"), f"journal '{jn}' eps") if js.get("eps") else None,
                "c": float(c) if c else None,
                "omega": self.cols.get(self.spec.get("speed")) if self.spec.get("speed") else None,
                "res": jr}

    def save(self, fig, fname: str) -> None:
        figure_folder(self.out)
        path = self.out / fname
        save_figure(fig, path, dpi=DPI)
        self.written.append(path)


def span_problem(values) -> str | None:
    """Why a column cannot be drawn although it has numbers: its finite values span more than the
    largest float (matplotlib's ticks then fail with "arange: cannot compute length", which ended
    `rotorcosim plot` in an internal error); None when it can be drawn."""
    a = np.asarray(values)
    if a.dtype == object or a.size == 0:
        return None
    a = a.astype(float)
    finite = a[np.isfinite(a)]
    if finite.size == 0:
        return None
    lo, hi = float(finite.min()), float(finite.max())
    with np.errstate(over="ignore"):
        if np.isfinite(hi - lo):
            return None
    return (f"spans more than the largest floating-point number (from {lo:.4g} to {hi:.4g}; an FMU's 'no value' "
            "marker such as DBL_MAX?)")


def plain(text: Any) -> str:
    """``text`` as a figure draws it as written: each ``$`` escaped, so that no name from a run
    folder, a scenario or an FMU (a scenario named 'a$_$b', a variable 'x$_$') is parsed as
    matplotlib mathtext, which drew it wrong or raised ParseSyntaxException (an internal error of
    `rotorcosim plot` and `stability --plot`). Our own labels keep their mathtext."""
    return str(text).replace("$", r"\$")


def trace(ax, xv, yv, color, label) -> None:
    """Line plot; long dense signals as a min/max envelope over ``MAX_TRACE_POINTS/2`` bins."""
    label = plain(label)
    n = xv.size
    if n <= MAX_TRACE_POINTS or not np.all(np.diff(xv) >= 0):
        ax.plot(xv, yv, lw=0.7, color=color, label=label)
        return
    nb = MAX_TRACE_POINTS // 2
    edges = np.linspace(0, n, nb + 1).astype(int)
    yv = np.where(np.isfinite(yv), yv, np.nan)
    lo = np.fmin.reduceat(yv, edges[:-1])
    hi = np.fmax.reduceat(yv, edges[:-1])
    xc = xv[(edges[:-1] + edges[1:]) // 2]
    ax.fill_between(xc, lo, hi, color=color, lw=0.3, alpha=0.8, label=label + " (min-max envelope)")


def line_ranges(lines: np.ndarray, most: int = 5) -> str:
    """``line 4`` / ``lines 2-21, 30, ...`` for increasing line numbers (at most ``most`` ranges)."""
    lines = np.asarray(lines, int)
    cuts = np.flatnonzero(np.diff(lines) != 1) + 1
    parts = [f"{g[0]}-{g[-1]}" if g.size > 1 else f"{g[0]}" for g in np.split(lines, cuts)]
    text = ", ".join(parts[:most]) + (", ..." if len(parts) > most else "")
    return ("line " if lines.size == 1 else "lines ") + text


def edges(c: np.ndarray) -> np.ndarray:
    """Cell edges around increasing centres ``c`` (midpoints, ends extrapolated)."""
    c = np.asarray(c, float)
    if c.size == 1:
        return np.array([c[0] - 0.5, c[0] + 0.5])
    mid = 0.5 * (c[1:] + c[:-1])
    return np.concatenate([[2 * c[0] - mid[0]], mid, [2 * c[-1] - mid[-1]]])


def safe_name(name: str) -> str:
    return re.sub(r"[^A-Za-z0-9_.-]+", "_", str(name))


XY = re.compile(r"^(?P<inst>[^.]+)\.x_(?P<i>\d+)$")


def infer_spec(cols: Mapping[str, Any]) -> dict:
    """Guess an analysis spec from column names (``*.omega``, ``*.x_i``/``*.y_i``, ``*.eps``).

    Journal ``i`` gets the eps column of the instance whose name ends in ``i``,
    else the i-th eps column in header order. No clearance (estimated from eps
    by the analysis when both exist).
    """
    names = list(cols)
    speed = next((n for n in names if n.endswith(".omega")), None)
    eps_cols = [n for n in names if n.endswith(".eps")]
    journals = {}
    for k, n in enumerate(sorted((n for n in names if XY.match(n)), key=lambda s: int(XY.match(s)["i"]))):
        m = XY.match(n)
        yname = f"{m['inst']}.y_{m['i']}"
        if yname not in cols:
            continue
        e = next((c for c in eps_cols if re.search(rf"{m['i']}\.eps$", c)), None)
        if e is None and k < len(eps_cols):
            e = eps_cols[k]
        js = {"x": n, "y": yname}
        if e:
            js["eps"] = e
        journals[f"journal{m['i']}"] = js
    spec: dict[str, Any] = {"journals": journals}
    if speed:
        spec["speed"] = speed
    return spec


def _unfinished(summary: Mapping[str, Any], run_dir: Path) -> list[str]:
    """A note when summary.json still says "running": the run is going on (its rows so far are
    drawn), or its process is gone without a final summary (killed, or crashed with an FMU in
    its own process), which the figures alone would not tell."""
    if summary.get("status") != "running":
        return []
    from orchestrator.coupling.lifecycle import folder_in_use
    pid = summary.get("pid")
    who = f"the run (pid {pid}, started {summary.get('started_at')})" if isinstance(pid, int) else "the run"
    in_use = folder_in_use(run_dir)
    if in_use is None and _moved_aside(run_dir):
        in_use = False            # a later run took the folder's lock and moved this one here: it is gone
    if in_use:
        return [f"{who} is still going on: these are the rows it has written so far"]
    if in_use is False:
        from orchestrator.coupling.lifecycle import open_calls
        from orchestrator.fmi.call_record import describe_calls
        calls = open_calls(run_dir)
        where = (f"; it died in an FMI call that never returned: {describe_calls(calls)}" if calls else "")
        return [f"{who} ended without a final summary: it was killed, or it crashed (an FMU in the master's "
                "process that crashes takes the run down with it: give it isolation: process, "
                f"docs/coupling.md){where}; these are the rows it wrote before"]
    return []


def _moved_aside(run_dir: Path) -> bool:
    """Whether ``run_dir`` is the ``previous/`` folder of a run folder (one with a lock file): an
    earlier run's files, moved there by a later run that held the folder's lock."""
    from orchestrator.coupling.lifecycle import LOCK_NAME, PREVIOUS
    run_dir = Path(run_dir)
    return run_dir.name == PREVIOUS and os.path.lexists(run_dir.parent / LOCK_NAME)
