"""Plots of a run directory (``rotorcosim plot DIR``): PNGs in ``DIR/plots/``.

What is drawn, when the data exist (see ``docs/analysis.md``):

* ``eccentricity.png``: eccentricity of every journal over time and over rotor
  speed, whirl onset / vanishing marked;
* ``orbit_<journal>.png``: journal orbits (x/c, y/c) with the clearance circle in
  three windows (before the onset, in the whirl, at the end), coloured by time;
* ``waterfall_<journal>.png``: run-up waterfall, frequency of the forward journal
  motion against rotor speed, colour = amplitude / clearance, 1x and 0.5x lines;
* ``fields_<name>.png``: pressure [bar] and fluid fraction over (phi [deg], z [mm])
  for every ``*_fields.npz`` (stationary runs), cavity (theta < 1) outlined.

The signals come from ``summary.json`` (the ``analysis.spec`` written by
:func:`orchestrator.analysis.analyze_run`), else the ``analysis:`` section of the
scenario file named in ``summary.json``, else they are inferred from the column
names (``<inst>.omega``, ``<inst>.x_<i>``/``<inst>.y_<i>``, ``<inst>.eps``).
Whatever cannot be drawn is skipped with a ``UserWarning`` that says why.
Uses matplotlib's object API with the Agg canvas (no pyplot, no display).
"""

from __future__ import annotations

import logging
import re
import warnings
from pathlib import Path
from typing import Any, Mapping

import numpy as np

from orchestrator.analysis import TWO_PI, WhirlParams, analyze_run, read_results, waterfall
from orchestrator.errors import CosimError
from orchestrator.untrusted import InputError, load_json, load_yaml, read_text

logger = logging.getLogger(__name__)

DPI = 110
ORBIT_REVS = 20          # revolutions shown per orbit window
MAX_ORBIT_POINTS = 1500  # orbit points per window (decimated above)
MAX_TRACE_POINTS = 4000  # above: min/max envelope per bin (looks the same, draws fast)


def plot_run(run_dir: str | Path) -> list[Path]:
    """Write the plots of a run into ``run_dir/plots/``; return the written files.

    Skips (with a ``UserWarning`` naming file, signal and fix) what the run's
    files do not support. Raises :class:`CosimError` when ``run_dir`` is not a
    directory or nothing at all could be plotted.
    """
    run_dir = Path(run_dir)
    if not run_dir.is_dir():
        raise CosimError(f"{run_dir}: not a directory; give the output directory of a run "
                         "(the one holding results.csv and summary.json)")
    ctx = _Context(run_dir)
    ctx.run()
    for msg in dict.fromkeys(ctx.skipped):     # each reason once, in order
        warnings.warn(f"plot {run_dir}: skipped {msg}", UserWarning, stacklevel=2)
    if not ctx.written:
        raise CosimError(f"{run_dir}: nothing to plot: " + "; ".join(ctx.skipped))
    return ctx.written


class _Context:
    """State of one ``plot_run`` call (files read once, list of skipped items)."""

    def __init__(self, run_dir: Path):
        self.run_dir = run_dir
        self.out = run_dir / "plots"
        self.written: list[Path] = []
        self.skipped: list[str] = []
        self.summary = self._load_summary()
        self.name = str(self.summary.get("scenario") or run_dir.name)
        self.cols: dict[str, np.ndarray] = {}
        self.spec: dict[str, Any] = {}
        self.result: dict[str, Any] = {}

    # ------------------------------------------------------------------ inputs
    def _load_summary(self) -> dict:
        """summary.json (bounded read); a run folder may come from anyone, so every part
        the plots use is checked here (:func:`_checked_spec`, :func:`_checked_result`)."""
        p = self.run_dir / "summary.json"
        if not p.exists():
            return {}
        try:
            summary = load_json(p, what="summary.json")
        except InputError as exc:
            self.skipped.append(f"{p.name} ({exc}); using results.csv only")
            return {}
        if not isinstance(summary, dict):
            self.skipped.append(f"{p.name} (expected a JSON object, got {type(summary).__name__}); using "
                                "results.csv only")
            return {}
        return summary

    def _load_spec(self) -> tuple[dict, str]:
        ana = self.summary.get("analysis")
        if isinstance(ana, Mapping) and isinstance(ana.get("spec"), Mapping):
            return self._checked_spec(ana["spec"], "summary.json")
        sf = self.summary.get("scenario_file")
        if isinstance(sf, str) and sf:
            try:          # the scenario named by summary.json: bounded reader, bounded YAML
                from orchestrator.scenario import _YamlLoader      # the scenario's number rules
                doc = load_yaml(read_text(sf, what="scenario file"), display=sf, loader_cls=_YamlLoader)
                if isinstance(doc, Mapping) and isinstance(doc.get("analysis"), Mapping):
                    return self._checked_spec(doc["analysis"], sf)
            except InputError as exc:
                self.skipped.append(f"the analysis section of the scenario named in summary.json ({exc})")
            except Exception as exc:  # noqa: BLE001 - yaml syntax errors: the inferred spec is used
                logger.info("cannot parse %s: %s", sf, exc)
        return infer_spec(self.cols), "inferred from results.csv column names"

    def _checked_spec(self, spec: Mapping, src: str) -> tuple[dict, str]:
        spec, problems = _checked_spec(spec)
        self.skipped.extend(f"{p} in the analysis spec ({src})" for p in problems)
        return spec, src

    def run(self) -> None:
        csv_path = self.run_dir / "results.csv"
        if csv_path.is_file():
            try:
                self.cols = read_results(csv_path)
            except (OSError, ValueError) as exc:
                self.skipped.append(f"time histories: {exc}")
        else:
            self.skipped.append(f"time histories: {csv_path} not found")
        if self.cols.get("time", np.empty(0)).size >= 2:
            self.spec, src = self._load_spec()
            logger.info("plot signals from %s: %s", src, self.spec)
            if not self.spec.get("journals"):
                self.skipped.append(
                    f"journal plots: no journals in the analysis spec ({src}) and no columns named "
                    "like '<inst>.x_1', '<inst>.y_1' in results.csv; add an 'analysis:' section "
                    "(docs/analysis.md)")
            else:
                self._analysis()
                self._eccentricity()
                for jn in self.spec["journals"]:
                    self._orbit(jn)
                    self._waterfall(jn)
        elif "time" in self.cols:
            self.skipped.append(f"time histories: results.csv has {self.cols['time'].size} row(s), need 2")
        self._fields()

    def _analysis(self) -> None:
        ana = self.summary.get("analysis")
        result, problem = _checked_result(ana)
        if problem:
            self.skipped.append(f"the analysis in summary.json ({problem}); recomputed from results.csv")
        if result is not None:
            self.result = result
        elif self.spec.get("speed"):
            self.result = analyze_run(self.run_dir, self.spec)
        if "error" in self.result:
            self.skipped.append(f"whirl markers: {self.result['error']}")

    def _sig(self, name: Any, what: str) -> np.ndarray | None:
        if isinstance(name, str) and name in self.cols:
            return self.cols[name]
        self.skipped.append(f"{what}: results.csv has no column '{name}'; columns: "
                            f"{sorted(self.cols)[:10]}; fix the analysis spec or output.signals")
        return None

    def _journal(self, jn: str) -> dict:
        """Signals of one journal: t, x, y, eps, c, omega (None when missing)."""
        js = self.spec["journals"][jn] or {}
        jr = (self.result.get("journals") or {}).get(jn) or {}
        c = js.get("clearance") or jr.get("clearance")
        return {"t": self.cols["time"],
                "x": self._sig(js.get("x"), f"journal '{jn}' x") if js.get("x") else None,
                "y": self._sig(js.get("y"), f"journal '{jn}' y") if js.get("y") else None,
                "eps": self._sig(js.get("eps"), f"journal '{jn}' eps") if js.get("eps") else None,
                "c": float(c) if c else None,
                "omega": self.cols.get(self.spec.get("speed")) if self.spec.get("speed") else None,
                "res": jr}

    def _save(self, fig, fname: str) -> None:
        self.out.mkdir(parents=True, exist_ok=True)
        path = self.out / fname
        fig.savefig(path, dpi=DPI)
        self.written.append(path)

    # ------------------------------------------------------------------ plots
    def _eccentricity(self) -> None:
        from matplotlib.figure import Figure
        t = self.cols["time"]
        om = self.cols.get(self.spec.get("speed") or "")
        if self.spec.get("speed") and om is None:
            self._sig(self.spec.get("speed"), "speed axis")
        ramp = om is not None and np.ptp(om) > 0.01 * max(np.nanmax(np.abs(om)), 1e-30)
        fig = Figure(figsize=(8, 6.5 if ramp else 3.8), layout="constrained")
        axes = fig.subplots(2 if ramp else 1, 1, squeeze=False)[:, 0]
        n = 0
        for i, jn in enumerate(self.spec["journals"]):
            j = self._journal(jn)
            e, lab = j["eps"], jn
            if e is None and j["x"] is not None and j["y"] is not None and j["c"]:
                e, lab = np.hypot(j["x"], j["y"]) / j["c"], f"{jn} (|z|/c)"
            if e is None:
                self.skipped.append(f"eccentricity of '{jn}': neither an eps signal nor x, y and clearance")
                continue
            col = f"C{i}"
            _trace(axes[0], t, e, col, lab)
            if ramp:
                _trace(axes[1], om / TWO_PI, e, col, lab)
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
        axes[0].set_title(f"{self.name}: journal eccentricity")
        if ramp:
            axes[1].set_xlabel("rotor speed [Hz]")
        for ax in axes:
            ax.set_ylabel(r"eccentricity $\varepsilon$ [-]")
            ax.set_ylim(bottom=0)
            ax.grid(alpha=0.3)
        axes[0].legend(fontsize=7, loc="upper left")
        self._save(fig, "eccentricity.png")

    def _orbit(self, jn: str) -> None:
        from matplotlib.collections import LineCollection
        from matplotlib.figure import Figure
        j = self._journal(jn)
        if j["x"] is None or j["y"] is None:
            self.skipped.append(f"orbit of '{jn}': x or y signal missing (see above)")
            return
        t, om, c, res = j["t"], j["omega"], j["c"], j["res"]
        scale, unit = (1.0 / c, "/c [-]") if c else (1e6, r" [$\mu$m]")
        x, y = j["x"] * scale, j["y"] * scale
        wins = _orbit_windows(t, om, res)
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
        fig.suptitle(f"{self.name}: orbit of journal '{jn}'")
        self._save(fig, f"orbit_{_safe(jn)}.png")

    def _waterfall(self, jn: str) -> None:
        from matplotlib.colors import LogNorm
        from matplotlib.figure import Figure
        j = self._journal(jn)
        if j["x"] is None or j["y"] is None or j["omega"] is None:
            self.skipped.append(f"waterfall of '{jn}': needs x, y and the speed signal "
                                f"('{self.spec.get('speed')}')")
            return
        params = WhirlParams()
        try:
            params = WhirlParams.from_mapping(self.spec.get("whirl"))
        except (ValueError, TypeError) as exc:
            self.skipped.append(f"custom whirl parameters for the waterfall ({exc}); defaults used")
        wf = waterfall(j["t"], j["x"] + 1j * j["y"], j["omega"], params)
        if wf["t"].size < 2:
            self.skipped.append(f"waterfall of '{jn}': fewer than {params.window_revs + params.hop_revs} "
                                "revolutions in the run")
            return
        c = j["c"]
        scale, unit = (1.0 / c, "amplitude / clearance [-]") if c else (1e6, r"amplitude [$\mu$m]")
        keep = (wf["orders"] >= 0) & (wf["orders"] <= 2.5)
        orders, amp = wf["orders"][keep], wf["amplitude"][:, keep] * scale
        sp = wf["speed_hz"]
        top = float(np.nanmax(amp)) if np.isfinite(amp).any() and np.nanmax(amp) > 0 else 1.0
        norm = LogNorm(vmin=top * 3e-3, vmax=top)
        shown = np.ma.masked_less(amp, top * 3e-3)          # below the colour range: white
        o_edges = _edges(orders)
        fig = Figure(figsize=(8, 5.5), layout="constrained")
        ax = fig.subplots()
        ramp = np.ptp(sp) > 0.01 * max(np.max(np.abs(sp)), 1e-30)
        if ramp:
            S, O = np.meshgrid(_edges(sp), o_edges, indexing="ij")
            m = ax.pcolormesh(S, S * O, shown, shading="flat", norm=norm, cmap="magma_r")
            f = np.array([0.0, np.max(sp)])
            ax.plot(f, f, "k--", lw=0.8, label="1x")
            ax.plot(f, 0.5 * f, "k:", lw=0.8, label="0.5x")
            ax.set_xlabel("rotor speed [Hz]")
            ax.set_ylabel("frequency of forward journal motion [Hz]")
            ax.set_xlim(0, np.max(sp))
            ax.set_ylim(0, 1.5 * np.max(sp))
            ev = (j["res"] or {}).get("onset")
            if ev:
                ax.axvline(ev["speed_hz"], color="C0", ls="--", lw=1.0,
                           label=f"whirl onset {ev['speed_hz']:.4g} Hz")
            ev = (j["res"] or {}).get("vanish")
            if ev:
                ax.axvline(ev["speed_hz"], color="C2", ls="--", lw=1.0,
                           label=f"whirl vanishes {ev['speed_hz']:.4g} Hz")
        else:   # constant speed: spectrum over time, frequency in orders
            m = ax.pcolormesh(_edges(wf["t"]), o_edges, shown.T, shading="flat", norm=norm, cmap="magma_r")
            ax.axhline(1.0, color="k", ls="--", lw=0.8, label="1x")
            ax.axhline(0.5, color="k", ls=":", lw=0.8, label="0.5x")
            ax.set_xlabel("time [s]")
            ax.set_ylabel("order (frequency / rotor speed) [-]")
        fig.colorbar(m, ax=ax, label=unit)
        ax.legend(fontsize=8, loc="upper left")
        ax.set_title(f"{self.name}: waterfall of journal '{jn}' "
                     f"({params.window_revs}-revolution windows)")
        self._save(fig, f"waterfall_{_safe(jn)}.png")

    def _fields(self) -> None:
        files = sorted(self.run_dir.glob("*_fields.npz"))
        want = self.spec.get("fields") if self.spec else None
        if want and not (self.run_dir / f"{want}_fields.npz").is_file():
            self.skipped.append(f"fields of '{want}': {self.run_dir / (str(want) + '_fields.npz')} not "
                                "found; set the bearing's fields_file parameter to "
                                f"\"{{out_dir}}/{want}_fields.npz\"")
        for f in files:
            try:
                self._field_plot(f)
            except (KeyError, ValueError, OSError) as exc:
                self.skipped.append(f"fields {f.name}: {exc}; expected arrays phi (n_phi,), z (n_z,), "
                                    "p, theta (n_z, n_phi)")

    def _field_plot(self, path: Path) -> None:
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
        axes[0].set_title(f"{self.name}: {path.stem}  (p_max {p.max() / 1e5:.4g} bar, "
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
        self._save(fig, f"fields_{_safe(path.stem.removesuffix('_fields'))}.png")


def _trace(ax, xv, yv, color, label) -> None:
    """Line plot; long dense signals as a min/max envelope over ``MAX_TRACE_POINTS/2`` bins."""
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


def _orbit_windows(t, omega, res) -> list[tuple[str, float, float]]:
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


def _finite(x) -> bool:
    return isinstance(x, (int, float)) and not isinstance(x, bool) and bool(np.isfinite(x))


def _checked_spec(spec: Mapping) -> tuple[dict, list[str]]:
    """The analysis spec with only well-formed parts kept, and what was dropped."""
    out: dict[str, Any] = {}
    problems = []
    for key in ("speed",):
        if spec.get(key) is not None:
            if isinstance(spec[key], str):
                out[key] = spec[key]
            else:
                problems.append(f"'{key}' is not a signal name (got {type(spec[key]).__name__})")
    if isinstance(spec.get("whirl"), Mapping):
        out["whirl"] = dict(spec["whirl"])
    if isinstance(spec.get("fields"), list) and all(isinstance(f, str) for f in spec["fields"]):
        out["fields"] = list(spec["fields"])
    journals = spec.get("journals")
    if journals is not None and not isinstance(journals, Mapping):
        problems.append(f"'journals' must be a mapping name -> {{x, y, eps, clearance}} (got "
                        f"{type(journals).__name__})")
        journals = {}
    out["journals"] = {}
    for name, js in (journals or {}).items():
        if not isinstance(js, Mapping):
            problems.append(f"journal '{name}' must be a mapping (got {type(js).__name__})")
            continue
        clean = {k: js[k] for k in ("x", "y", "eps") if isinstance(js.get(k), str)}
        c = js.get("clearance")
        if c is not None:
            if _finite(c) and c > 0:
                clean["clearance"] = float(c)
            else:
                problems.append(f"the clearance of journal '{name}' must be a positive number in m (got {c!r})")
        out["journals"][str(name)] = clean
    return out, problems


def _event_ok(ev) -> bool:
    return ev is None or (isinstance(ev, Mapping) and _finite(ev.get("time_s")) and _finite(ev.get("speed_hz")))


def _checked_result(ana) -> tuple[dict | None, str | None]:
    """summary.json's analysis result if every part the plots read is well-formed (else None
    and the reason; None, None when there is none)."""
    if not isinstance(ana, Mapping) or "journals" not in ana:
        return None, None
    if not isinstance(ana["journals"], Mapping):
        return None, f"'journals' is {type(ana['journals']).__name__}, expected a mapping"
    for name, jr in ana["journals"].items():
        if not isinstance(jr, Mapping):
            return None, f"journal '{name}' is {type(jr).__name__}, expected a mapping"
        if not (_event_ok(jr.get("onset")) and _event_ok(jr.get("vanish"))):
            return None, f"the onset/vanish of journal '{name}' lack numeric time_s and speed_hz"
        if jr.get("clearance") is not None and not (_finite(jr["clearance"]) and jr["clearance"] > 0):
            return None, f"the clearance of journal '{name}' is not a positive number"
        if jr.get("time_resolution_s") is not None and not _finite(jr["time_resolution_s"]):
            return None, f"the time_resolution_s of journal '{name}' is not a number"
        eps = jr.get("episodes")
        if jr.get("onset") is not None and not (
                isinstance(eps, list) and eps and isinstance(eps[0], Mapping) and _finite(eps[0].get("onset_time_s"))
                and (eps[0].get("vanish_time_s") is None or _finite(eps[0]["vanish_time_s"]))):
            return None, f"the whirl episodes of journal '{name}' are malformed"
    return dict(ana), None


_XY = re.compile(r"^(?P<inst>[^.]+)\.x_(?P<i>\d+)$")


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
    for k, n in enumerate(sorted((n for n in names if _XY.match(n)), key=lambda s: int(_XY.match(s)["i"]))):
        m = _XY.match(n)
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


def _edges(c: np.ndarray) -> np.ndarray:
    """Cell edges around increasing centres ``c`` (midpoints, ends extrapolated)."""
    c = np.asarray(c, float)
    if c.size == 1:
        return np.array([c[0] - 0.5, c[0] + 0.5])
    mid = 0.5 * (c[1:] + c[:-1])
    return np.concatenate([[2 * c[0] - mid[0]], mid, [2 * c[-1] - mid[-1]]])


def _safe(name: str) -> str:
    return re.sub(r"[^A-Za-z0-9_.-]+", "_", str(name))
