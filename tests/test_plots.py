"""plot_run on synthetic run directories: files are real, non-trivial PNGs; gaps give messages."""

from __future__ import annotations

import json
import math
import warnings

import numpy as np
import pytest

from orchestrator.results.whirl import analyze_run
from orchestrator.errors import CosimError
from orchestrator.results.plots import infer_spec, plot_run
from test_analysis import C, SPEC, whirl_vanishing, write_run

PNG_MAGIC = b"\x89PNG\r\n\x1a\n"


def fields_npz(path, n_phi=24, n_z=12, bad_shape=False):
    phi = np.linspace(0, 2 * np.pi, n_phi, endpoint=False)
    z = np.linspace(0, 0.032, n_z)
    P, Z = np.meshgrid(phi, z)
    p = 1e5 + 30e5 * np.clip(np.sin(P - np.pi / 2), 0, None) ** 2 * np.sin(np.pi * Z / 0.032)
    theta = np.where(P > 1.2 * np.pi, 0.7, 1.0)
    if bad_shape:
        p = p.T
    np.savez(path, phi=phi, z=z, p=p, theta=theta, h=1 - 0.7 * np.cos(P - np.pi), t=0.1)


def check_png(path):
    import matplotlib.image as mpimg
    data = path.read_bytes()
    assert data[:8] == PNG_MAGIC, f"{path} is not a PNG"
    assert len(data) > 10_000, f"{path} is only {len(data)} bytes"
    img = mpimg.imread(path)
    assert img.shape[0] > 200 and img.shape[1] > 200
    assert img[..., :3].std() > 0.05, f"{path} is (nearly) blank"


@pytest.fixture(scope="module")
def run_dir(tmp_path_factory):
    d = tmp_path_factory.mktemp("run")
    write_run(d, whirl_vanishing(), step=4)
    res = analyze_run(d, {**SPEC, "fields": "bearing1"})
    (d / "summary.json").write_text(json.dumps({"scenario": "synthetic_run_up", "status": "finished",
                                                "analysis": res}))
    fields_npz(d / "bearing1_fields.npz")
    return d


def test_full_run_dir(run_dir):
    with warnings.catch_warnings():
        warnings.simplefilter("error")          # nothing may be skipped here
        files = plot_run(run_dir)
    names = sorted(f.name for f in files)
    assert names == ["eccentricity.png", "fields_bearing1.png", "orbit_bearing1.png",
                     "waterfall_bearing1.png"]
    for f in files:
        assert f.parent == run_dir / "plots"
        check_png(f)


def test_inferred_signals_without_summary(tmp_path):
    write_run(tmp_path, whirl_vanishing(), step=4)
    spec = infer_spec({"time": 0, "rotor.x_1": 0, "rotor.y_1": 0, "rotor.omega": 0, "bearing1.eps": 0})
    assert spec == {"speed": "rotor.omega",
                    "journals": {"journal1": {"x": "rotor.x_1", "y": "rotor.y_1", "eps": "bearing1.eps"}}}
    files = plot_run(tmp_path)
    assert sorted(f.name for f in files) == ["eccentricity.png", "orbit_journal1.png",
                                             "waterfall_journal1.png"]


def test_spec_from_scenario_file(tmp_path):
    write_run(tmp_path, whirl_vanishing(), step=4)
    sc = tmp_path / "sc.yaml"
    sc.write_text("analysis:\n  speed: rotor.omega\n  journals:\n"
                  f"    left: {{x: rotor.x_1, y: rotor.y_1, clearance: {C}}}\n")
    (tmp_path / "summary.json").write_text(json.dumps({"scenario": "s", "scenario_file": str(sc)}))
    names = sorted(f.name for f in plot_run(tmp_path))
    assert names == ["eccentricity.png", "orbit_left.png", "waterfall_left.png"]


def test_missing_signal_is_a_clear_warning(tmp_path):
    write_run(tmp_path, whirl_vanishing(), step=4)
    spec = {"speed": "rotor.omega",
            "journals": {"b1": {"x": "rotor.x_9", "y": "rotor.y_1", "eps": "bearing1.eps",
                                "clearance": C}}}
    (tmp_path / "summary.json").write_text(json.dumps({"scenario": "s", "analysis": {"spec": spec}}))
    with pytest.warns(UserWarning) as rec:
        files = plot_run(tmp_path)
    msgs = " ".join(str(w.message) for w in rec)
    assert "results.csv has no column 'rotor.x_9'" in msgs
    assert "orbit of 'b1'" in msgs and "waterfall of 'b1'" in msgs
    assert [f.name for f in files] == ["eccentricity.png"]     # eps still plotted


@pytest.mark.filterwarnings("ignore:plot .*skipped")
def test_nothing_to_plot_raises_cosim_error(tmp_path):
    with pytest.raises(CosimError, match="not a directory"):
        plot_run(tmp_path / "nope")
    with pytest.raises(CosimError, match="results.csv not found"):
        plot_run(tmp_path)


def test_fields_only_and_bad_fields(tmp_path):
    fields_npz(tmp_path / "b_fields.npz")
    with pytest.warns(UserWarning) as rec:
        files = plot_run(tmp_path)
    assert "results.csv not found" in str(rec[0].message)
    assert [f.name for f in files] == ["fields_b.png"]
    check_png(files[0])
    fields_npz(tmp_path / "b_fields.npz", bad_shape=True)
    with pytest.warns(UserWarning) as rec, pytest.raises(CosimError, match=r"expected \(n_z, n_phi\)"):
        plot_run(tmp_path)
    assert any("p has shape (24, 12)" in str(w.message) for w in rec)


def test_constant_speed_run(tmp_path):
    t = np.arange(0, 0.5, 1e-4)
    om = np.full(t.size, 2 * math.pi * 100.0)
    z = -0.5j * C + 0.05 * C * np.exp(1j * om * t)
    with (tmp_path / "results.csv").open("w") as fh:
        fh.write("time,rotor.x_1,rotor.y_1,rotor.omega\n")
        np.savetxt(fh, np.column_stack([t, z.real, z.imag, om]), delimiter=",")
    spec = {"speed": "rotor.omega", "journals": {"j": {"x": "rotor.x_1", "y": "rotor.y_1", "clearance": C}}}
    (tmp_path / "summary.json").write_text(json.dumps({"scenario": "s", "analysis": analyze_run(tmp_path, spec)}))
    files = plot_run(tmp_path)
    assert sorted(f.name for f in files) == ["eccentricity.png", "orbit_j.png", "waterfall_j.png"]
    for f in files:
        check_png(f)


if __name__ == "__main__":
    # Regenerate the example images of docs/analysis.md from synthetic data:
    #   python tests/test_plots.py docs/img
    import shutil
    import sys
    import tempfile
    from pathlib import Path

    import orchestrator.results.plots as plots

    dest = Path(sys.argv[1] if len(sys.argv) > 1 else "docs/img")
    dest.mkdir(parents=True, exist_ok=True)
    plots.DPI = 72
    with tempfile.TemporaryDirectory() as tmp:
        d = Path(tmp)
        write_run(d, whirl_vanishing(), step=4)
        res = analyze_run(d, SPEC)
        (d / "summary.json").write_text(json.dumps({"scenario": "synthetic whirl (test data)",
                                                    "analysis": res}))
        fields_npz(d / "bearing1_fields.npz", n_phi=40, n_z=40)
        for f in plot_run(d):
            shutil.copy(f, dest / f"synthetic_{f.name}")
            print(dest / f"synthetic_{f.name}")


def test_in_memory_result_gives_the_same_figures(run_dir, tmp_path):
    """plot_result draws from a CoSimResult (here the run folder read back), no folder needed."""
    from orchestrator import CoSimResult
    from orchestrator.results.plots import plot_result
    res = CoSimResult.load(run_dir)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        files = plot_result(res, tmp_path / "mem", name="synthetic_run_up")
    assert sorted(f.name for f in files) == ["eccentricity.png", "orbit_bearing1.png", "waterfall_bearing1.png"]
    for f in files:
        assert f.parent == tmp_path / "mem"
        check_png(f)


def test_signal_panels_are_labelled_with_the_fmus_units(tmp_path, monkeypatch):
    # found plotting the quickstart run: the panels said 'Fx', 'p_max', 'h_min' with no unit (N, Pa,
    # m), though our FMUs declare one for every variable; summary.json now records the recorded
    # columns' units (output.units) and plot labels the panels with them
    from orchestrator import load_scenario, run
    from orchestrator.results.plots import signals as sig
    from pathlib import Path
    quickstart = Path(__file__).resolve().parents[1] / "scenarios" / "quickstart.yaml"
    sc = load_scenario(quickstart, overrides=["stop_time=0.5004"], build_fmus=True)
    out = tmp_path / "run"
    run(sc, out_dir=out)
    units = json.loads((out / "summary.json").read_text())["output"]["units"]
    assert units["rotor.omega"] == "rad/s" and units["bearing1.Fx"] == "N" and units["bearing1.p_max"] == "Pa"
    assert units["bearing1.eps"] == "1" and list(units) == [c for c in units if c in sc.output.signals]
    figs = []
    monkeypatch.setattr(sig, "save_figure", lambda fig, path, dpi: figs.append(fig))
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", UserWarning)          # 3 rows: no journal figures
        plot_run(out, signals=["bearing1.*"])
    labels = [ax.get_ylabel() for ax in figs[0].axes]
    assert labels == ["eps [-]", "Fx [N]", "Fy [N]", "p_max [Pa]", "h_min [m]"]
    # a summary from elsewhere: units that are not short text are not used, '$' is no mathtext
    assert sig.unit_labels({"a.x": "m$^2$", "a.y": 3, "a.z": "x" * 41, "a.w": "N\n"}) == {"a.x": r"m\$^2\$"}
    assert sig.unit_labels(["m"]) == {}


def test_a_signal_constant_up_to_rounding_is_drawn_flat(tmp_path):
    """A stationary bearing's force varies by 1e-10 of itself (rounding); matplotlib filled the
    panel with that noise under an offset, so a constant looked like a wandering signal. Such a
    signal is now drawn flat around its value; a real variation is left to matplotlib."""
    import numpy as np
    from orchestrator.results.plots.signals import plot_signals, steady_limits
    rng = np.random.default_rng(1)
    flat = 26.2 * (1 + 1e-11 * rng.standard_normal(200))
    lo, hi = steady_limits(flat)
    assert lo < flat.min() and hi > flat.max() and hi - lo == pytest.approx(2 * 26.2e-3, rel=1e-6)
    assert steady_limits(np.zeros(5)) == (-1.0, 1.0)
    assert steady_limits(np.array([np.nan, np.nan])) is None
    assert steady_limits(26.2 + 1e-6 * np.sin(np.linspace(0, 6, 50))) is None
    files, notes = plot_signals({"time": np.linspace(0, 1, 200), "b.Fx": flat,
                                 "b.Fy": np.linspace(0, 1, 200)}, tmp_path, "t")
    assert [f.name for f in files] == ["signals_b.png"] and notes == []


def test_waterfall_spans_the_run_and_marks_the_threshold(tmp_path, monkeypatch):
    """My pump run-up starts at 150 Hz (on the ramp) and its analysis puts the instability
    threshold at 249 Hz, the onset at 326 Hz. Before, the waterfall's speed axis started at 0 Hz
    (40 % of it empty) and only the onset was marked, not where the rotor became unstable."""
    from orchestrator.results.plots import common
    d = whirl_vanishing()
    keep = d["t"] >= 0.4                                 # the run starts at 160 Hz
    write_run(tmp_path, {**d, **{k: d[k][keep] for k in ("t", "z", "om")}}, step=4)
    res = analyze_run(tmp_path, SPEC)
    res["journals"]["bearing1"].update(threshold_speed_hz=215.0, threshold_snr=4.0)
    (tmp_path / "summary.json").write_text(json.dumps({"scenario": "pump", "status": "finished",
                                                       "analysis": res}))
    figs = {}
    real = common.save_figure
    monkeypatch.setattr(common, "save_figure", lambda fig, path, **kw: (figs.__setitem__(path.name, fig),
                                                                        real(fig, path, **kw))[1])
    plot_run(tmp_path)
    ax = figs["waterfall_bearing1.png"].axes[0]
    lo, hi = ax.get_xlim()
    # the first cell's edge: half a window less half a hop (8 - 1 = 7 revolutions) after 160 Hz on
    # the 400 Hz/s ramp: 400 dt^2 / 2 + 160 dt = 7
    dt = (-160.0 + math.sqrt(160.0**2 + 2 * 400.0 * 7)) / 400.0
    assert lo == pytest.approx(160.0 + 400.0 * dt, abs=0.5) and hi > 790.0
    labels = [line.get_label() for line in ax.lines]
    assert "instability threshold 215 Hz (growth rate > 0)" in labels
    assert any(lab.startswith("whirl onset") for lab in labels)


def _field_axes(tmp_path, name, **extra):
    """The drawn panels (axes with a colour bar's partner excluded) and their titles of one
    field file written as the bearing FMU writes it, with ``extra`` arrays (None: left out)."""
    from orchestrator.results.plots.common import PlotContext
    from orchestrator.results.plots.fields import field_plot
    phi = np.linspace(0, 2 * np.pi, 24, endpoint=False)
    z = np.linspace(0, 0.032, 12)
    P, Z = np.meshgrid(phi, z)
    p = 1e5 + 30e5 * np.clip(np.sin(P - np.pi / 2), 0, None) ** 2 * np.sin(np.pi * Z / 0.032)
    arrays = dict(phi=phi, z=z, p=p, theta=np.ones_like(p), h=1 - 0.7 * np.cos(P - np.pi), t=0.1)
    arrays.update({k: v for k, v in extra.items() if v is not None})
    for k in [k for k, v in extra.items() if v is None]:
        arrays.pop(k, None)
    path = tmp_path / f"{name}_fields.npz"
    np.savez(path, **arrays)
    drawn = []

    class Ctx(PlotContext):
        def save(self, fig, fname):
            drawn.append(fig)
            super().save(fig, fname)

    field_plot(Ctx(name="run", out=tmp_path / "plots"), path)
    check_png(tmp_path / "plots" / f"fields_{name}.png")
    fig, = drawn
    panels = [ax for ax in fig.axes if ax.get_label() != "<colorbar>"]
    return panels, " ".join(ax.get_title() for ax in panels), p


def test_half_sommerfeld_fields_show_pressure_and_the_ruptured_region_not_theta(tmp_path):
    """A half-Sommerfeld film has no fluid fraction: theta is 1 by definition. Before 2026-12-06 its
    figure had a second panel of that constant theta (a yellow rectangle, colour bar 0.999-1);
    now the bearing writes its film model (cavitation, p0) into the fields file and the figure
    is the pressure alone, the ruptured region (p clipped to p0) hatched, and says so."""
    panels, titles, p = _field_axes(tmp_path, "hs", cavitation=np.int64(0), p0=np.float64(1e5))
    assert len(panels) == 1, titles
    assert "half-Sommerfeld" in titles and "ruptured, p clipped to p0 = 1 bar" in titles, titles
    assert f"({100 * np.mean(p <= 1e5 + 1e-9 * p.max()):.0f} % of the film)" in titles
    # the mass-conserving film keeps its fluid-fraction panel, even when it is full
    panels, titles, _ = _field_axes(tmp_path, "mc", cavitation=np.int64(1), p0=np.float64(1e5),
                                    theta=np.where(np.arange(24) > 14, 0.7, 1.0) * np.ones((12, 1)))
    assert len(panels) == 2 and "fluid fraction" in titles and "half-Sommerfeld" not in titles
    # a file of before (no film model) with theta 1 everywhere: that panel would show nothing
    panels, titles, _ = _field_axes(tmp_path, "old", cavitation=None, p0=None)
    assert len(panels) == 1 and "= 1 everywhere" in titles, titles
    with pytest.raises(ValueError, match="expected 0 .half-Sommerfeld. or 1"):
        _field_axes(tmp_path, "bad", cavitation=np.int64(7))


def test_the_bearing_writes_its_film_model_into_the_fields(tmp_path):
    from bearing_fmu.model import BearingModel, BearingParams
    b = BearingModel(BearingParams(R=4.9e-3, B=7.84e-3, psi=2.8e-3, n_phi=24, n_z=12, cavitation=0))
    b.initialize(4e-6, -6e-6, 0.0, 0.0, 2 * math.pi * 100.0)
    f = b.fields()
    assert int(f["cavitation"]) == 0 and float(f["p0"]) == 1e5
    assert np.all(f["theta"] == 1.0) and np.isclose(f["p"].min(), 1e5) and f["p"].max() > 1e5
