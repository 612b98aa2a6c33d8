"""Validation of the run-up analysis on synthetic journal motions with known answers.

Tolerances are derived from the method, not tuned: a window of ``window_revs``
revolutions is attributed to its centre, so a change at ``t0`` is seen within
half a window span around ``t0`` plus one hop (frame spacing), plus the time
the synthetic amplitude needs to reach the detection level. Ratios must be
within half an order bin (``0.5 / window_revs``).

``python tests/test_analysis.py`` prints the validation table of docs/analysis.md.
"""

from __future__ import annotations

import json
import math
import warnings

import numpy as np
import pytest

from orchestrator.results.run_directory import read_results
from orchestrator.results.whirl import (WhirlParams, analyze_journal, analyze_run, dominant_ratio,
                                        growth_rate, growth_threshold, order_spectra, revolutions, waterfall)

C = 1.0e-5            # clearance [m]
P = WhirlParams()     # defaults under test
F_END, T_END, FS = 800.0, 2.0, 20_000.0   # ramp 0 -> 800 Hz in 2 s (paper, sec. 3.2), 20 kHz output
A_RAMP = F_END / T_END                     # [Hz/s]


def ramp():
    t = np.arange(0.0, T_END, 1.0 / FS)
    f = A_RAMP * t
    theta = math.pi * A_RAMP * t**2        # 2 pi * integral of f
    return t, 2 * math.pi * f, theta


def t_of_rev(r):
    """Inverse of r(t) = a t^2 / 2 for the ramp."""
    return np.sqrt(2.0 * np.maximum(r, 0.0) / A_RAMP)


def tol_window(t0, p=P):
    """Half window span (larger side) + one hop for a window centred at t0 on the ramp."""
    r0 = 0.5 * A_RAMP * t0**2
    t_lo, t_hi = t_of_rev(r0 - p.window_revs / 2), t_of_rev(r0 + p.window_revs / 2)
    half = max(t_hi - t0, t0 - t_lo)
    hop = t_of_rev(r0) - t_of_rev(r0 - p.hop_revs)
    return half + hop


def base_motion(theta, t, sync=0.15, noise=0.0, seed=0):
    """Static equilibrium drifting with speed + unbalance orbit through a 'critical' at 300 Hz."""
    f = A_RAMP * t
    static = C * (-0.6 + 0.4 * t / T_END) * 1j + 0.1 * C * t / T_END
    amp = sync * C / np.sqrt((1 - (f / 300.0) ** 2) ** 2 + 0.3**2) * 0.3   # peak = sync * C
    z = static + amp * np.exp(1j * theta)
    if noise:
        rng = np.random.default_rng(seed)
        z = z + noise * C * (rng.standard_normal(t.size) + 1j * rng.standard_normal(t.size))
    return z


def gate(t, t0, t1=None, tau=0.005):
    """0 before t0, rises as 1 - exp(-(t-t0)/tau); after t1 decays as exp(-(t-t1)/tau)."""
    g = np.where(t > t0, 1.0 - np.exp(-np.clip(t - t0, 0, None) / tau), 0.0)
    if t1 is not None:
        g = np.where(t > t1, g * np.exp(-np.clip(t - t1, 0, None) / tau), g)
    return g


def rise_time(level, amp, tau=0.005):
    """Time for amp * (1 - exp(-s/tau)) to reach level."""
    return -tau * math.log(1.0 - level / amp)


def run_case(z, t, omega):
    return analyze_journal(t, z.real, z.imag, omega, C, params=P)


# ------------------------------------------------------------------ cases (also the doc table)

CASES = {}


def case(fn):
    CASES[fn.__name__] = fn
    return fn


@case
def whirl_clean():
    t, om, th = ramp()
    t0, a = 0.8, 0.4
    z = base_motion(th, t) + a * C * gate(t, t0) * np.exp(1j * 0.45 * th)
    return dict(z=z, t=t, om=om, onset=t0, ratio=0.45,
                tol_on=tol_window(t0) + rise_time(P.threshold * C, a * C))


@case
def whirl_noise():
    d = whirl_clean()
    rng = np.random.default_rng(1)
    sigma = P.threshold    # noise std per axis = the detection threshold
    d["z"] = d["z"] + sigma * C * (rng.standard_normal(d["t"].size) + 1j * rng.standard_normal(d["t"].size))
    return d


@case
def whirl_under_large_sync():
    t, om, th = ramp()
    t0, a = 0.7, 0.15
    z = base_motion(th, t, sync=0.6) + a * C * gate(t, t0) * np.exp(1j * 0.45 * th)
    return dict(z=z, t=t, om=om, onset=t0, ratio=0.45,
                tol_on=tol_window(t0) + rise_time(P.threshold * C, a * C))


@case
def whirl_exponential_growth():
    # linear instability: amplitude 1e-4 c * exp(s (t - 0.5)), saturating at 0.5 c
    t, om, th = ramp()
    s = 40.0
    amp = np.minimum(1e-4 * np.exp(s * (t - 0.5)), 0.5)
    z = base_motion(th, t) + amp * C * np.exp(1j * 0.45 * th)
    t_true = 0.5 + math.log(P.threshold / 1e-4) / s     # amplitude reaches the threshold
    return dict(z=z, t=t, om=om, onset=t_true, ratio=0.45, tol_on=tol_window(t_true))


@case
def whirl_vanishing():
    t, om, th = ramp()
    t0, t1, a = 0.6, 1.4, 0.3       # 240 Hz -> 560 Hz, like the paper's figure 8
    z = base_motion(th, t) + a * C * gate(t, t0, t1) * np.exp(1j * 0.45 * th)
    fall = 0.005 * math.log(a / (P.threshold * P.off_fraction))
    return dict(z=z, t=t, om=om, onset=t0, ratio=0.45, vanish=t1,
                tol_on=tol_window(t0) + rise_time(P.threshold * C, a * C),
                tol_off=tol_window(t1) + fall)


@case
def whip_locked():
    # whip locked at 150 Hz from t = 1 s (400 Hz, ratio 0.375) to the end (800 Hz, 0.1875)
    t, om, th = ramp()
    t0, a, fw = 1.0, 0.3, 150.0
    z = base_motion(th, t) + a * C * gate(t, t0) * np.exp(1j * 2 * math.pi * fw * t)
    return dict(z=z, t=t, om=om, onset=t0, whip_hz=fw,
                tol_on=tol_window(t0) + rise_time(P.threshold * C, a * C))


@case
def unbalance_only():
    t, om, th = ramp()
    return dict(z=base_motion(th, t, sync=0.9, noise=P.threshold), t=t, om=om, onset=None)


def check_onset(d, r):
    if d["onset"] is None:
        assert not r["whirl"], f"false whirl onset reported: {r['onset']}"
        assert r["max_subsync_rel"] < P.threshold
        return
    assert r["whirl"], f"no onset found; max sub-synchronous amplitude {r.get('max_subsync_rel')}"
    t_on = r["onset"]["time_s"]
    assert abs(t_on - d["onset"]) <= d["tol_on"], (t_on, d["onset"], d["tol_on"])
    assert r["onset"]["speed_hz"] == pytest.approx(A_RAMP * t_on, rel=1e-3)
    assert len(r["episodes"]) == 1, r["episodes"]


@pytest.mark.parametrize("name", sorted(CASES))
def test_onset_detection(name):
    d = CASES[name]()
    r = run_case(d["z"], d["t"], d["om"])
    check_onset(d, r)
    if "ratio" in d:
        assert abs(r["dominant_ratio"] - d["ratio"]) <= 0.5 / P.window_revs
        assert abs(r["episodes"][0]["ratio_at_onset"] - d["ratio"]) <= 0.5 / P.window_revs
    if "vanish" in d:
        assert r["vanish"] is not None, "whirl did not vanish"
        assert abs(r["vanish"]["time_s"] - d["vanish"]) <= d["tol_off"]
    elif d["onset"] is not None:
        assert r["vanish"] is None, r["vanish"]


def test_whip_ratio_follows_locked_frequency():
    d = whip_locked()
    s = order_spectra(d["t"], d["z"], d["om"], P)
    ratio = dominant_ratio(s)
    sub = s.subsync_amplitude() / C
    w = sub >= P.threshold
    assert w.sum() > 10
    expect = d["whip_hz"] / s.speed_hz[w]
    # chirp: the order of a fixed frequency changes across the window
    spread = d["whip_hz"] / (A_RAMP * s.t_start[w]) - d["whip_hz"] / (A_RAMP * s.t_end[w])
    err = np.abs(ratio[w] - expect)
    assert np.all(err <= 0.5 / P.window_revs + 0.5 * spread), err.max()
    # the ratio falls as the speed rises (whip locked onto a natural frequency)
    assert np.all(np.diff(ratio[w][2:]) < 0.5 / P.window_revs)
    r = run_case(d["z"], d["t"], d["om"])
    lo, hi = r["ratio_range"]
    assert lo == pytest.approx(d["whip_hz"] / F_END, abs=1.0 / P.window_revs)
    assert hi >= 0.33


def test_backward_whirl_is_not_forward_subsync():
    t, om, th = ramp()
    z = base_motion(th, t) + 0.4 * C * gate(t, 0.8) * np.exp(-1j * 0.45 * th)
    r = run_case(z, t, om)
    assert not r["whirl"]
    assert r["max_subsync_rel"] < P.threshold


@pytest.mark.parametrize("order", [0.3, 0.45, 0.5 + 1 / 32])
def test_amplitude_calibration_forward_circle(order):
    # constant speed 100 Hz; Hann energy outside the band is < 0.1 %, box-car averaging
    # attenuates order <1 by < 0.1 % at 32 samples/rev -> 1 %
    t = np.arange(0, 1.0, 1 / 10_000)
    om = np.full(t.size, 2 * math.pi * 100)
    z = 0.2 * C * np.exp(1j * order * om * t) + 0.1 * C * np.exp(1j * om * t)
    s = order_spectra(t, z, om, P)
    assert np.allclose(s.subsync_amplitude(), 0.2 * C, rtol=0.01)
    assert np.allclose(s.sync_amplitude(), 0.1 * C, rtol=0.01)
    assert np.allclose(dominant_ratio(s), order, atol=0.5 / P.window_revs)


def test_revolutions_and_waterfall_shapes():
    t, om, th = ramp()
    assert revolutions(t, om)[-1] == pytest.approx(th[-1] / (2 * math.pi), rel=1e-6)
    wf = waterfall(t, base_motion(th, t), om)
    assert wf["amplitude"].shape == (wf["t"].size, P.window_revs * P.samples_per_rev)
    assert np.all(np.diff(wf["orders"]) > 0)
    j1 = np.argmin(np.abs(wf["orders"] - 1.0))
    k = np.argmin(np.abs(wf["speed_hz"] - 300.0))          # critical: sync peak = 0.15 c
    assert wf["amplitude"][k, j1] == pytest.approx(0.15 * C, rel=0.05)


def test_too_short_data_does_not_raise():
    t = np.linspace(0, 0.01, 50)
    om = np.full(t.size, 2 * math.pi * 100)       # 1 revolution
    r = analyze_journal(t, 0 * t, 0 * t, om, C)
    assert r["whirl"] is False and "too little rotation" in r["warnings"][0]
    r = analyze_journal(t[:1], t[:1], t[:1], om[:1], C)
    assert r["whirl"] is False


@pytest.mark.parametrize("case, expect", [
    ("zero_speed", "no positive finite value"),
    ("negative_speed", "no positive finite value"),
    ("nan_speed", "no positive finite value"),
    ("nan_xy", "0 finite value"),
    ("diverged", "NaN/inf in 1000 of 2001 samples (first at t = 0.5"),
])
def test_odd_data_warns_and_gives_strict_json(tmp_path, case, expect):
    t = np.linspace(0, 1, 2001)
    om = np.full(t.size, 2 * math.pi * 100.0)
    x = 1e-6 * np.cos(2 * math.pi * 100.0 * t)
    if case == "zero_speed":
        om = 0 * om
    elif case == "negative_speed":
        om = -om
    elif case == "nan_speed":
        om = np.nan * om
    elif case == "nan_xy":
        x = np.nan * x
    elif case == "diverged":
        x = np.where(t > 0.5, np.inf, x)
    with (tmp_path / "results.csv").open("w") as fh:
        fh.write("time,rotor.x_1,rotor.y_1,rotor.omega\n")
        np.savetxt(fh, np.column_stack([t, x, x, om]), delimiter=",")
    spec = {"speed": "rotor.omega", "journals": {"j": {"x": "rotor.x_1", "y": "rotor.y_1", "clearance": C}}}
    with warnings.catch_warnings():
        warnings.simplefilter("error")          # no numpy RuntimeWarning may escape
        res = analyze_run(tmp_path, spec)
    json.dumps(res, allow_nan=False)
    j = res["journals"]["j"]
    assert j["whirl"] is False
    assert any(expect in w for w in j["warnings"]), j["warnings"]


def test_invalid_params_listed():
    with pytest.raises(ValueError, match="window_revs"):
        WhirlParams.from_mapping({"window_revs": 2})
    with pytest.raises(ValueError, match="unknown key"):
        WhirlParams.from_mapping({"windows": 2})
    with pytest.raises(ValueError, match="2 bins"):
        WhirlParams.from_mapping({"band": [0.05, 0.8]})


# ------------------------------------------------------------------ instability threshold (growth rate)

def growing_mode(f_th, a0, *, s_max=20.0, width=60.0, f_w=115.0, f0=140.0, sat=0.4, noise=0.0,
                 seed=3, sync=0.15):
    """Journal motion with a forward mode at a fixed f_w [Hz] (like the rotor-bearing whirl
    mode) that appears at f0 [Hz] with amplitude ``a0`` (x C) and has the growth rate
    ``s_max tanh((f - f_th) / width)`` [1/s] on the ramp: it decays, reaches its minimum
    at the threshold f_th and grows (saturating at ``sat`` C), on top of the base motion
    (drifting equilibrium + unbalance orbit); optional white noise [C per axis]."""
    t, om, th = ramp()
    f = A_RAMP * t
    sigma = s_max * np.tanh((f - f_th) / width)
    ln_a = np.concatenate([[0.0], np.cumsum(0.5 * (sigma[1:] + sigma[:-1]) * np.diff(t))])
    t0 = f0 / A_RAMP
    k0 = int(np.argmin(np.abs(t - t0)))
    amp = np.minimum(a0 * np.exp(ln_a - ln_a[k0]), sat) * gate(t, t0)
    z = base_motion(th, t, sync=sync, noise=noise, seed=seed) + amp * C * np.exp(2j * math.pi * f_w * t)
    return z, t, om


def test_threshold_at_growth_rate_zero_crossing_independent_of_seed():
    # same growth-rate curve, seeds 30x apart: the onsets differ a lot, the threshold does not.
    # (unbalance orbit 0.015 C: its leakage into the growth band, ~5e-6 C, stays below the
    # mode's minimum, 2e-5 C for the smaller seed; test_threshold_mode_under_floor_is_flagged
    # covers the other case)
    f_th = 256.0
    t_th = f_th / A_RAMP
    tol_hz = A_RAMP * tol_window(t_th)       # the window is attributed to its centre (derived, as above)
    res = []
    for a0 in (3e-2, 1e-3):
        z, t, om = growing_mode(f_th, a0, sync=0.015)
        r = run_case(z, t, om)
        assert r["whirl"]
        assert r["threshold_speed_hz"] == pytest.approx(f_th, abs=tol_hz), (a0, r["threshold_speed_hz"])
        assert r["threshold_time_s"] == pytest.approx(t_th, abs=tol_window(t_th))
        assert r["threshold_speed_hz"] < r["onset_speed_hz"]
        assert r["threshold_snr"] >= 3.0
        assert not [w for w in r["warnings"] if "threshold" in w], r["warnings"]
        res.append(r)
    # the onset is seed-dependent: about ln(30) / s_max of ramp time later for the smaller seed
    d_onset = res[1]["onset_speed_hz"] - res[0]["onset_speed_hz"]
    assert d_onset > 2 * tol_hz, d_onset
    assert abs(res[1]["threshold_speed_hz"] - res[0]["threshold_speed_hz"]) <= tol_hz


def test_threshold_other_speeds_and_noise():
    for f_th, a0 in ((200.0, 3e-3), (350.0, 3e-2)):
        z, t, om = growing_mode(f_th, a0, sync=0.015, noise=1e-5)     # floor below the mode
        r = run_case(z, t, om)
        t_th = f_th / A_RAMP
        assert r["threshold_speed_hz"] == pytest.approx(f_th, abs=A_RAMP * tol_window(t_th)), f_th


def test_threshold_none_when_stable_or_growing_from_start():
    z, t, om = growing_mode(1000.0, 1e-2)                   # decays to the end
    r = run_case(z, t, om)
    assert r["threshold_speed_hz"] is None and r["threshold_time_s"] is None
    assert any("does not grow at the end" in w for w in r["warnings"]), r["warnings"]
    z, t, om = growing_mode(-100.0, 1e-6)                   # grows wherever it is in the band:
    keep = t >= 0.45                                        # data from 180 Hz (mode at order 0.64) on
    r = run_case(z[keep], t[keep], om[keep])
    assert r["threshold_speed_hz"] is None
    assert any("grows from the first analysable frame" in w for w in r["warnings"]), r["warnings"]
    r = run_case(base_motion(ramp()[2], ramp()[0], sync=0.9, noise=0.01), *ramp()[:2])
    assert r["threshold_speed_hz"] is None                  # noise only: no sustained growth


def test_threshold_mode_under_floor_is_flagged():
    # mode minimum 6e-5 C, at the leakage floor of the 0.15 C unbalance orbit (~5e-5 C)
    z, t, om = growing_mode(256.0, 3e-3)
    r = run_case(z, t, om)
    if r["threshold_speed_hz"] is not None:
        assert r["threshold_snr"] < 3.0
        assert any("unreliable" in w for w in r["warnings"]), r["warnings"]


def test_growth_rate_and_threshold_units():
    t = np.linspace(0.0, 1.0, 101)
    sig_true = 20.0 * (t - 0.4)                             # ln a = 10 (t - 0.4)^2
    a = 1e-3 * np.exp(10.0 * (t - 0.4) ** 2)
    sig = growth_rate(t, a, 9)
    inner = slice(4, -4)
    assert np.allclose(sig[inner], sig_true[inner], atol=1e-9)   # exact for a quadratic ln a (centred fit)
    t_th, why = growth_threshold(t, a, sig, t.size, 10.0)
    assert why is None and t_th == pytest.approx(0.4, abs=1e-9)
    t_th, why = growth_threshold(t, a, sig, t.size, 1e6)         # growth factor e^3.6 < 1e6
    assert t_th is None and "growth_min_factor" in why


def test_growth_rate_belongs_to_the_centre_of_its_fit():
    # within half a fit of either end the fit is one-sided: its slope is the growth rate at the
    # mean time of its frames, not at the frame's own time
    t = np.linspace(0.0, 1.0, 101)
    a = 1e-3 * np.exp(10.0 * (t - 0.0237) ** 2)             # sigma = 20 (t - 0.0237): zero at 0.0237
    sig, t_fit = growth_rate(t, a, 9, centres=True)
    assert np.allclose(sig, 20.0 * (t_fit - 0.0237), atol=1e-9)   # every value, the ends included
    assert np.allclose(t_fit[4:-4], t[4:-4])
    assert t_fit[0] == pytest.approx(0.02) and t_fit[-1] == pytest.approx(0.98)
    assert np.array_equal(sig, growth_rate(t, a, 9))
    t_th, why = growth_threshold(t, a, sig, t.size, 10.0, t_sigma=t_fit)
    assert why is None and t_th == pytest.approx(0.0237, abs=1e-9)
    t_th, _ = growth_threshold(t, a, sig, t.size, 10.0)       # the frames' own times: 0.0074
    assert t_th < 0.01


def test_threshold_near_the_start_of_the_data():
    # a run-up whose data start shortly below the threshold (a seeded scenario): the crossing
    # lies in the first frames, whose growth-rate fits are one-sided. Attributed to the fits'
    # centres it is the true one; attributed to the frames (as until this change) it was 5.6 Hz low
    # (250.4 Hz), within the window tolerance but biased, always towards the start.
    f_th = 256.0
    z, t, om = growing_mode(f_th, 3e-2, sync=0.015)
    keep = t >= 236.0 / A_RAMP                              # first frame centred at 249 Hz
    r = run_case(z[keep], t[keep], om[keep])
    s = order_spectra(t[keep], z[keep], om[keep], P)
    assert s.speed_hz[0] < f_th < s.speed_hz[4]             # inside the one-sided fits
    hop_hz = float(np.median(np.diff(s.speed_hz[:8])))
    assert r["threshold_speed_hz"] == pytest.approx(f_th, abs=hop_hz / 3), r["threshold_speed_hz"]
    assert r["threshold_snr"] >= 3.0


def test_invalid_growth_params_listed():
    with pytest.raises(ValueError, match="growth_band"):
        WhirlParams.from_mapping({"growth_band": [0.8, 0.3]})
    with pytest.raises(ValueError, match="growth_fit_revs"):
        WhirlParams.from_mapping({"growth_fit_revs": 1})
    with pytest.raises(ValueError, match="growth_min_factor"):
        WhirlParams.from_mapping({"growth_min_factor": 1.0})


# ------------------------------------------------------------------ analyze_run on files

SPEC = {"speed": "rotor.omega",
        "journals": {"bearing1": {"x": "rotor.x_1", "y": "rotor.y_1", "eps": "bearing1.eps",
                                  "clearance": C}}}


def write_run(tmp_path, d, step=4, truncate=False):
    z = d["z"][::step]
    t, om = d["t"][::step], d["om"][::step]
    cols = np.column_stack([t, z.real, z.imag, om, np.abs(z) / C])
    path = tmp_path / "results.csv"
    with path.open("w") as fh:
        fh.write("time,rotor.x_1,rotor.y_1,rotor.omega,bearing1.eps\n")
        np.savetxt(fh, cols, delimiter=",", fmt="%.9e")
        if truncate:
            fh.write("2.0,1e-6,")
    return path


def test_analyze_run_on_results_csv(tmp_path):
    d = whirl_vanishing()
    write_run(tmp_path, d, truncate=True)   # 5 kHz output, last line cut off mid-row
    res = analyze_run(tmp_path, SPEC)
    assert "error" not in res, res
    json.dumps(res, allow_nan=False)        # goes into summary.json
    j = res["journals"]["bearing1"]
    assert abs(j["onset"]["time_s"] - d["onset"]) <= d["tol_on"]
    assert abs(j["vanish"]["time_s"] - d["vanish"]) <= d["tol_off"]
    assert (j["onset_speed_hz"], j["vanish_speed_hz"]) == (j["onset"]["speed_hz"], j["vanish"]["speed_hz"])
    assert j["eps_source"] == "signal"
    assert res["speed_max_hz"] == pytest.approx(F_END, rel=0.01)
    assert res["spec"]["journals"]["bearing1"]["x"] == "rotor.x_1"


def test_analyze_run_estimates_clearance_from_eps(tmp_path):
    write_run(tmp_path, whirl_clean())
    spec = {"speed": "rotor.omega",
            "journals": {"b": {"x": "rotor.x_1", "y": "rotor.y_1", "eps": "bearing1.eps"}}}
    j = analyze_run(tmp_path, spec)["journals"]["b"]
    assert j["clearance"] == pytest.approx(C, rel=1e-6)
    assert "estimated" in j["warnings"][0]


@pytest.mark.parametrize("content, match", [
    ("", "empty file"),
    ("time,rotor.x_1,rotor.y_1,rotor.omega,bearing1.eps\n", "0 data row"),
    ("time,rotor.x_1,rotor.y_1,rotor.omega,bearing1.eps\n0,0,0,0,0\n", "1 data row"),
])
def test_analyze_run_short_files_return_error(tmp_path, content, match):
    (tmp_path / "results.csv").write_text(content)
    res = analyze_run(tmp_path, SPEC)
    assert match in res["error"]


def test_analyze_run_errors_name_the_problem(tmp_path):
    assert "not found" in analyze_run(tmp_path, SPEC)["error"]          # no results.csv
    write_run(tmp_path, whirl_clean(), step=40)
    bad = {"speed": "rotor.omega", "journals": {"b": {"x": "rotor.x_9", "y": "rotor.y_1"}}}
    err = analyze_run(tmp_path, bad)["journals"]["b"]["error"]
    assert "results.csv" in err and "rotor.x_9" in err and "analysis.journals.b.x" in err
    assert "rotor.omg" in analyze_run(tmp_path, {**SPEC, "speed": "rotor.omg"})["error"]
    assert "unknown key" in analyze_run(tmp_path, {**SPEC, "whirl": {"treshold": 1}})["error"]
    assert "mapping" in analyze_run(tmp_path, ["x"])["error"]


def test_read_results_roundtrip(tmp_path):
    p = tmp_path / "results.csv"
    p.write_text("time,a.b\n0,1\n1,2\n")
    cols = read_results(p)
    assert list(cols) == ["time", "a.b"] and cols["a.b"].tolist() == [1.0, 2.0]


def validation_table():
    """Rows of the docs table: case, true onset, detected, tolerance, true / detected ratio."""
    rows = []
    for name, fn in CASES.items():
        d = fn()
        r = run_case(d["z"], d["t"], d["om"])
        on = r["onset"]["time_s"] if r["onset"] else None
        van = r["vanish"]["time_s"] if r["vanish"] else None
        rows.append((name, d["onset"], on, d.get("tol_on"), d.get("vanish"), van, d.get("tol_off"),
                     d.get("ratio", d.get("whip_hz") and f"{d['whip_hz']} Hz"), r["dominant_ratio"],
                     r["ratio_range"]))
    return rows


if __name__ == "__main__":
    def f(v):
        return "-" if v is None else (f"{v:.4f}" if isinstance(v, float) else str(v))
    print("| case | true onset [s] | detected [s] | tol [s] | true vanish [s] | detected [s] | tol [s] "
          "| true ratio | dominant ratio | ratio range |")
    print("|---|---|---|---|---|---|---|---|---|---|")
    for row in validation_table():
        rr = row[-1]
        print("| " + " | ".join([f(v) for v in row[:-1]]
                                + ["-" if rr is None else f"{rr[0]:.3f} - {rr[1]:.3f}"]) + " |")


def test_analyze_run_on_results_parquet(tmp_path):
    """output.format: parquet: the analysis (and RunDirectory) read results.parquet as the CSV."""
    pa = pytest.importorskip("pyarrow")
    import pyarrow.parquet as pq
    from orchestrator.results import RunDirectory
    d = whirl_vanishing()
    (tmp_path / "csv").mkdir()
    write_run(tmp_path / "csv", d)
    cols = RunDirectory(tmp_path / "csv").columns()
    (tmp_path / "pq").mkdir()
    pq.write_table(pa.table({k: v for k, v in cols.items()}), tmp_path / "pq" / "results.parquet")
    back = RunDirectory(tmp_path / "pq").columns()
    assert list(back) == list(cols) and all(np.array_equal(back[k], cols[k]) for k in cols)
    assert analyze_run(tmp_path / "pq", SPEC) == analyze_run(tmp_path / "csv", SPEC)
    (tmp_path / "bad").mkdir()
    (tmp_path / "bad" / "results.parquet").write_bytes(b"PAR1 not really")
    assert "not a readable Parquet file" in str(pytest.raises(ValueError, RunDirectory(tmp_path / "bad").columns).value)


def test_waterfall_has_no_low_band_below_the_whirl_line():
    """A drifting mean position plus a forward whirl at 0.43 x the rotor speed (6.88 bins: not a
    whole number of cycles per window, as a real whirl): the waterfall shows the whirl line and
    the 1x line and nothing at orders 0 .. whirl - 2 bins. Before 2026-12-06 the unweighted linear detrend took
    part of the whirl into each window's fitted mean and slope, and subtracting them put a band at
    orders 0 and +-1/16 (0-50 Hz on the half-Sommerfeld run-up) of 4 % of the whirl amplitude
    into every window after the onset; the drift alone was removed (the window-weighted fit of
    detrend_windowed takes less than 0.3 % of the whirl)."""
    t, om, theta = ramp()
    t_on = 0.8
    order_w = 0.43
    whirl = 0.3 * C * np.exp(1j * order_w * theta) * gate(t, t_on)
    drift = C * (-0.6j * (1.0 - np.exp(-t / 0.5)) + 0.4 * (t / T_END) ** 3)   # mean position moves
    sync = 0.02 * C * np.exp(1j * theta)
    for z, has_whirl in ((drift + sync, False), (whirl + drift + sync, True)):
        wf = waterfall(t, z, om)
        o, amp = wf["orders"], wf["amplitude"] / C
        d = 1.0 / P.window_revs
        after = wf["t"] > t_on + tol_window(t_on)
        assert after.sum() > 50
        for k in np.nonzero(after)[0]:
            row = amp[k]
            assert row[np.argmin(np.abs(o - 1.0))] == pytest.approx(0.02, rel=0.05)     # 1x in place
            if has_whirl:
                near = np.abs(o - order_w) <= 1.0 * d
                assert row[near].max() > 0.15, (k, row[near])                    # whirl in place
                assert o[near][np.argmax(row[near])] == pytest.approx(order_w, abs=0.5 * d + 1e-9)
            below = np.abs(o) < order_w - 2 * d     # 0 .. whirl line (its main lobe out), both ways
            assert row[below].max() < 0.003, (wf["speed_hz"][k], o[below][np.argmax(row[below])], row[below].max())
