"""Run-up analysis: whirl onset and vanishing, eccentricity maxima, whirl ratio.

Method (details, parameters and the synthetic validation: ``docs/analysis.md``)
-------------------------------------------------------------------------------
The journal motion of each bearing is the complex displacement ``z = x + i y``
(x horizontal, y vertical up, the journal spins counter-clockwise, so forward
whirl has positive frequency). It is analysed in the *order domain*:

1. Shaft revolutions ``r(t) = (1/2 pi) * integral of omega dt`` (trapezoid).
2. ``z`` is re-sampled on a uniform grid of ``samples_per_rev`` points per
   revolution by *averaging* the piecewise-linear ``z(r)`` over each angle bin
   (a box-car anti-alias filter: noise and fast content are not folded back).
3. Sliding windows of ``window_revs`` (an integer) revolutions, hop
   ``hop_revs``: linear detrend fitted with the window's weights (removes the static
   equilibrium position and its slow drift with speed without taking part of the
   whirl, :func:`detrend_windowed`), periodic Hann window, FFT normalised by ``sum(w)``.
   The bins are orders (multiples of the rotor speed), spacing
   ``1/window_revs``; a forward circular orbit of radius ``A`` gives a peak of
   ``A``. Because a window spans an integer number of revolutions, the
   synchronous (1x, unbalance) component sits exactly on a bin and leaks only
   into its two neighbours, even while the speed ramps.
4. Per window: ``sub`` = forward amplitude in the sub-synchronous order band
   ``band`` (band power / equivalent noise bandwidth, so the estimate does not
   depend on where the peak falls between bins); ``sync`` = the same for the
   1x bin and its neighbours; ``ratio`` = the order of the largest forward
   sub-synchronous peak, refined by a log-parabolic fit over three bins. The
   window is attributed to the time at its centre angle.
5. Whirl episodes by hysteresis on ``sub / clearance``: an episode starts where
   it rises above ``threshold`` and stays above ``off_fraction * threshold``
   for ``persist_revs`` revolutions (or to the end of the data); it ends
   (whirl vanishes) where it falls below ``off_fraction * threshold`` and does
   not come back above ``threshold`` within ``persist_revs``. Crossing times are
   interpolated linearly between window centres.

The onset is therefore "the sub-synchronous orbit reaches ``threshold`` times
the clearance", with a time uncertainty of about half a window
(``window_revs / (2 f_rot)``), reported as ``time_resolution_s``.

6. Instability threshold (:func:`growth_threshold`): the growth rate
   ``sigma = d ln(a) / dt`` is the least-squares slope of the log
   amplitude ``a`` in the order band ``growth_band`` over sliding fits of ``growth_fit_revs``
   revolutions of frames, each value belonging to the mean time of the frames of its fit
   (about the frame's own time where the fit is centred on it; later / earlier within half a
   fit of the start / end of the data, where the fit is one-sided). Before the first onset (or
   to the end of the data when there is none), the threshold is where ``sigma`` last changes
   sign from <= 0 to > 0 and stays positive, with the amplitude growing by at least
   ``growth_min_factor`` from there; interpolated linearly between the times of the two
   growth rates. For a
   linear(ised) rotor whose least-damped forward mode has the real part
   ``sigma(t)``, this is where that mode crosses into the right half plane:
   unlike the onset it does not depend on how small the seed of the whirl is.

Public functions work on numpy arrays; :func:`analyze_run` reads a run
directory and never raises (it returns ``{"error": ...}``).

Length: one pipeline (order resampling, spectra, episode detection, growth-rate threshold,
per-journal result) whose steps share WhirlParams and are tested as a whole (tests/test_analysis.py);
splitting it would scatter one algorithm over files, so it stays above ~400 lines.
"""

from __future__ import annotations

import logging
import math
import warnings
from dataclasses import asdict, dataclass, fields, replace
from pathlib import Path
from typing import Any, Mapping

import numpy as np

from orchestrator.results.jsonsafe import plain
from orchestrator.results.run_directory import RunDirectory
from orchestrator.scenario.analysis_sampling import MIN_SAMPLES_PER_REV

logger = logging.getLogger(__name__)

TWO_PI = 2.0 * math.pi
HANN_ENBW = 1.5          # equivalent noise bandwidth of the periodic Hann window [bins]
#: most angle bins one orbit is resampled into (16.8 M: 256 MiB of complex bins; a 100 000 rpm
#: rotor recorded for a minute at 32 samples per revolution needs 3.2 M). A speed signal that
#: would need more (a speed in rpm or deg/s given as rad/s, a value of 1e300 in a tampered
#: results file) is not analysed: :func:`too_many_bins` says why
MAX_ORDER_BINS = 1 << 24


@dataclass(frozen=True, kw_only=True)
class WhirlParams:
    """Parameters of the whirl detection (scenario key ``analysis.whirl``).

    window_revs : int
        Window length in shaft revolutions; order resolution ``1/window_revs``.
    hop_revs : int
        Hop between windows [revolutions].
    samples_per_rev : int
        Order-domain samples per revolution (orders up to ``samples_per_rev/2``).
    band : (float, float)
        Forward sub-synchronous order band [x rotor speed].
    threshold : float
        Sub-synchronous amplitude, relative to the clearance, that starts a whirl episode.
    off_fraction : float
        The episode ends below ``off_fraction * threshold`` (hysteresis).
    persist_revs : float
        The state change must persist this many revolutions.
    growth_fit_revs : float
        Span of the least-squares fit of ln(sub) against time that gives the growth
        rate (threshold estimate, :func:`growth_threshold`) [revolutions].
    growth_min_factor : float
        The sub-synchronous amplitude must grow by at least this factor after the
        sign change of the growth rate for a threshold to be reported.
    growth_band : (float, float)
        Order band of the amplitude whose growth rate gives the threshold: narrower
        than ``band`` so that the leakage of the static drift (order 0) and of the
        unbalance response (order 1) stays out of it near the threshold, where the
        growing mode is smallest.
    """

    window_revs: int = 16
    hop_revs: int = 2
    samples_per_rev: int = 32
    band: tuple[float, float] = (0.15, 0.85)
    threshold: float = 0.05
    off_fraction: float = 0.5
    persist_revs: float = 16.0
    growth_fit_revs: float = 16.0
    growth_min_factor: float = 10.0
    growth_band: tuple[float, float] = (0.25, 0.75)

    def check(self) -> list[str]:
        """Problems with these values (empty when valid)."""
        p = []
        if int(self.window_revs) != self.window_revs or self.window_revs < 4:
            p.append(f"window_revs must be an integer >= 4 (got {self.window_revs})")
        if int(self.hop_revs) != self.hop_revs or self.hop_revs < 1:
            p.append(f"hop_revs must be an integer >= 1 (got {self.hop_revs})")
        if int(self.samples_per_rev) != self.samples_per_rev or self.samples_per_rev < 8:
            p.append(f"samples_per_rev must be an integer >= 8 (got {self.samples_per_rev})")
        lo, hi = self.band
        if not 0.0 < lo < hi < 1.0:
            p.append(f"band must satisfy 0 < low < high < 1 (got {self.band})")
        elif self.window_revs >= 4 and (lo * self.window_revs < 2 or (1 - hi) * self.window_revs < 2):
            p.append(f"band {self.band} must stay 2 bins (2/window_revs = {2 / self.window_revs:g}) "
                     "away from orders 0 and 1; widen window_revs or narrow band")
        if not self.threshold > 0:
            p.append(f"threshold must be > 0 (got {self.threshold})")
        if not 0.0 < self.off_fraction <= 1.0:
            p.append(f"off_fraction must be in (0, 1] (got {self.off_fraction})")
        if not self.persist_revs >= 0:
            p.append(f"persist_revs must be >= 0 (got {self.persist_revs})")
        if not self.growth_fit_revs >= 2 * self.hop_revs:
            p.append(f"growth_fit_revs must be >= 2 hop_revs = {2 * self.hop_revs} "
                     f"(got {self.growth_fit_revs})")
        glo, ghi = self.growth_band
        if not 0.0 < glo < ghi < 1.0:
            p.append(f"growth_band must satisfy 0 < low < high < 1 (got {self.growth_band})")
        if not self.growth_min_factor > 1:
            p.append(f"growth_min_factor must be > 1 (got {self.growth_min_factor})")
        return p

    @classmethod
    def from_mapping(cls, m: Mapping[str, Any] | None) -> "WhirlParams":
        """Build from the scenario's ``analysis.whirl`` mapping; ValueError lists problems."""
        if not m:
            return cls()
        known = {f.name for f in fields(cls)}
        unknown = sorted(set(m) - known)
        if unknown:
            raise ValueError(f"analysis.whirl: unknown key(s) {unknown}; valid keys: {sorted(known)}")
        kw = dict(m)
        for key in ("band", "growth_band"):
            if key in kw:
                kw[key] = tuple(float(v) for v in kw[key])
        out = replace(cls(), **kw)
        problems = out.check()
        if problems:
            raise ValueError("analysis.whirl: " + "; ".join(problems))
        return out


# ----------------------------------------------------------------------------- order domain

def revolutions(t: np.ndarray, omega: np.ndarray) -> np.ndarray:
    """Shaft revolutions ``integral(omega dt) / 2 pi`` (trapezoid), starting at 0."""
    t = np.asarray(t, float)
    omega = np.asarray(omega, float)
    r = np.zeros_like(t)
    if t.size > 1:
        r[1:] = np.cumsum(0.5 * (omega[1:] + omega[:-1]) * np.diff(t)) / TWO_PI
    return r


def too_many_bins(t, omega, samples_per_rev: int) -> str | None:
    """Why the orbit cannot be resampled in angle (more than :data:`MAX_ORDER_BINS` bins), or None."""
    with np.errstate(all="ignore"):           # an overflow to inf revolutions is the answer here
        r = revolutions(t, np.where(np.isfinite(np.asarray(omega, float)), omega, 0.0))
        revs = float(np.nanmax(r, initial=0.0)) if r.size else 0.0
    bins = revs * int(samples_per_rev)
    if bins <= MAX_ORDER_BINS:
        return None
    top = float(np.nanmax(np.abs(np.asarray(omega, float)), initial=0.0))
    t = np.asarray(t, float)
    span = float(t[-1] - t[0]) if t.size else 0.0
    # the revolutions grow with the recorded time too: a tampered time column of 1e305 s, at a
    # plausible 280 Hz, was blamed on the speed's unit alone
    return (f"the speed signal gives {revs:.3g} revolutions over {span:.6g} s of recorded time ({bins:.3g} angle "
            f"bins of 1/{int(samples_per_rev)} revolution, at most {MAX_ORDER_BINS} are analysed; its largest "
            f"|value| is {top:.6g} rad/s = {top / TWO_PI:.6g} Hz): is the speed in rad/s? (rpm or deg/s read as "
            "rad/s give 9.5x or 57x too many) Is the time in s? whirl not analysed")


def order_resample(t: np.ndarray, z: np.ndarray, r: np.ndarray, samples_per_rev: int):
    """Average ``z`` over uniform angle bins of ``1/samples_per_rev`` revolution.

    ``z`` is taken piecewise linear in ``r`` between samples, and each bin value
    is its exact mean over the bin (box-car anti-alias filter). Samples where
    ``r`` does not increase (standstill, reverse rotation) are dropped.

    Returns ``(r_c, z_c, t_c)``: bin-centre revolutions, bin means, times at the
    bin centres. Empty arrays when fewer than two bins fit, or more than
    :data:`MAX_ORDER_BINS`.
    """
    t = np.asarray(t, float)
    z = np.asarray(z, complex)
    r = np.asarray(r, float)
    ok = np.isfinite(t) & np.isfinite(r) & np.isfinite(z)
    t, z, r = t[ok], z[ok], r[ok]
    if r.size:
        keep = np.ones(r.size, bool)
        keep[1:] = r[1:] > np.maximum.accumulate(r)[:-1]
        t, z, r = t[keep], z[keep], r[keep]
    empty = (np.empty(0), np.empty(0, complex), np.empty(0))
    if r.size < 2:
        return empty
    m = int(samples_per_rev)
    e0 = math.ceil(r[0] * m) / m
    span = (r[-1] - e0) * m
    if not span <= MAX_ORDER_BINS:     # too many to hold (too_many_bins says why); inf/NaN too
        return empty
    n_bins = int(math.floor(span + 1e-9))
    if n_bins < 2:
        return empty
    edges = e0 + np.arange(n_bins + 1) / m
    # exact integral of the piecewise-linear z(r) from r[0] to each edge
    dr = np.diff(r)
    cum = np.concatenate([[0.0], np.cumsum(0.5 * (z[1:] + z[:-1]) * dr)])
    i = np.clip(np.searchsorted(r, edges, side="right") - 1, 0, r.size - 2)
    s = edges - r[i]
    slope = (z[i + 1] - z[i]) / dr[i]
    integ = cum[i] + z[i] * s + 0.5 * slope * s * s
    z_c = np.diff(integ) * m
    r_c = 0.5 * (edges[1:] + edges[:-1])
    t_c = np.interp(r_c, r, t)
    return r_c, z_c, t_c


@dataclass(frozen=True)
class OrderSpectra:
    """Short-time order spectra of one journal (one row per window).

    ``X[k, j]`` is the complex amplitude at order ``orders[j]`` (positive =
    forward whirl) of window ``k``; a forward circular orbit of radius ``A`` at a
    bin gives ``|X| = A``. ``t``, ``speed_hz``: time and rotor speed at the
    window centre; ``t_start``, ``t_end``: time span of the window.
    """

    t: np.ndarray
    speed_hz: np.ndarray
    t_start: np.ndarray
    t_end: np.ndarray
    orders: np.ndarray
    X: np.ndarray
    params: WhirlParams

    @property
    def n_frames(self) -> int:
        return self.t.size

    def band_amplitude(self, lo: float, hi: float) -> np.ndarray:
        """Amplitude of the content in the order band [lo, hi] (band power / ENBW)."""
        sel = (self.orders >= lo - 1e-12) & (self.orders <= hi + 1e-12)
        return np.sqrt(np.sum(np.abs(self.X[:, sel]) ** 2, axis=1) / HANN_ENBW)

    def sync_amplitude(self) -> np.ndarray:
        """Forward synchronous (1x) amplitude: the 1x bin and its two neighbours."""
        d = 1.0 / self.params.window_revs
        return self.band_amplitude(1.0 - 1.5 * d, 1.0 + 1.5 * d)

    def subsync_amplitude(self) -> np.ndarray:
        """Forward sub-synchronous amplitude in ``params.band``."""
        return self.band_amplitude(*self.params.band)


def _hann(n: int) -> np.ndarray:
    """Periodic Hann window of ``n`` points."""
    return 0.5 - 0.5 * np.cos(TWO_PI * np.arange(n) / n)


def detrend_windowed(segs: np.ndarray) -> np.ndarray:
    """Rows of ``segs`` less their linear trend, times the periodic Hann window.

    The trend (mean position and its drift, complex) is the least-squares line *weighted by the
    window*, so that the windowed residual has exactly zero mean and zero first moment. An
    unweighted fit (used before 2026-12-06) lets a sub-synchronous whirl that is not a whole number
    of cycles in the window leak into the fitted mean and slope: subtracting them put a spurious
    DC + ramp into every window after the whirl onset, which the window turned into a band at
    orders 0 and +-1/window_revs (0-50 Hz on the half-Sommerfeld run-up, about 4 % of the whirl
    amplitude). With the window's weights the whirl's share of the fit falls off as the window's
    side lobes (order 1/k^3), and a slow drift of the mean position is still removed.
    """
    n = segs.shape[-1]
    w = _hann(n)
    x = np.arange(n, dtype=float)
    x = x - np.dot(w, x) / w.sum()
    mean = (segs @ w)[..., None] / w.sum()
    slope = (segs @ (w * x))[..., None] / np.dot(w, x * x)
    return (segs - mean - slope * x) * w


def order_spectra(t, z, omega, params: WhirlParams | None = None) -> OrderSpectra:
    """Sliding-window order spectra of the complex displacement ``z(t)``.

    Parameters
    ----------
    t : (n,) times [s], increasing.
    z : (n,) complex journal displacement ``x + i y`` [m].
    omega : (n,) rotor speed [rad/s] (positive = counter-clockwise).
    params : WhirlParams, defaults when None.

    Too little data for one window gives zero frames (no exception).
    """
    p = params or WhirlParams()
    t = np.asarray(t, float)
    omega = np.asarray(omega, float)
    r = revolutions(t, np.where(np.isfinite(omega), omega, 0.0))
    r_c, z_c, t_c = order_resample(t, z, r, p.samples_per_rev)
    m = int(p.samples_per_rev)
    n = int(p.window_revs) * m
    hop = int(p.hop_revs) * m
    orders = np.fft.fftfreq(n, d=1.0 / m)
    if z_c.size < n:
        e = np.empty(0)
        return OrderSpectra(e, e, e, e, orders, np.empty((0, n), complex), p)
    segs = np.lib.stride_tricks.sliding_window_view(z_c, n)[::hop]
    starts = np.arange(segs.shape[0]) * hop
    X = np.fft.fft(detrend_windowed(segs), axis=1) / _hann(n).sum()
    r_mid = r_c[starts] + 0.5 * (n - 1) / m
    t_mid = np.interp(r_mid, r_c, t_c)
    sp = np.interp(t_mid, t, omega) / TWO_PI
    return OrderSpectra(t_mid, sp, t_c[starts], t_c[starts + n - 1], orders, X, p)


def dominant_ratio(spec: OrderSpectra, band: tuple[float, float] | None = None) -> np.ndarray:
    """Order (whirl frequency / rotor speed) of the largest forward peak in ``band``, per window.

    Log-parabolic interpolation over the peak bin and its neighbours; NaN for
    windows with no content.
    """
    lo, hi = band or spec.params.band
    if spec.n_frames == 0:
        return np.empty(0)
    idx = np.nonzero((spec.orders >= lo - 1e-12) & (spec.orders <= hi + 1e-12))[0]
    mag = np.abs(spec.X)
    k = idx[np.argmax(mag[:, idx], axis=1)]
    rows = np.arange(spec.n_frames)
    n = spec.orders.size
    tiny = 1e-300
    a = np.log(mag[rows, (k - 1) % n] + tiny)
    b = np.log(mag[rows, k] + tiny)
    c = np.log(mag[rows, (k + 1) % n] + tiny)
    den = a - 2 * b + c
    with np.errstate(invalid="ignore", divide="ignore"):
        delta = np.where(den < 0, 0.5 * (a - c) / den, 0.0)
    delta = np.clip(delta, -0.5, 0.5)
    ratio = spec.orders[k] + delta / spec.params.window_revs
    ratio[mag[rows, k] <= 0] = np.nan
    return ratio


def waterfall(t, z, omega, params: WhirlParams | None = None) -> dict:
    """Data for a run-up waterfall: amplitude vs order and rotor speed.

    Returns a dict with ``t`` (n_frames,) [s], ``speed_hz`` (n_frames,),
    ``orders`` (n_orders,) sorted from backward (negative) to forward, and
    ``amplitude`` (n_frames, n_orders) [same unit as z]. The frequency of a cell
    is ``orders[j] * speed_hz[k]`` [Hz].
    """
    s = order_spectra(t, z, omega, params)
    order = np.argsort(s.orders)
    return {"t": s.t, "speed_hz": s.speed_hz, "orders": s.orders[order],
            "amplitude": np.abs(s.X[:, order])}


# ----------------------------------------------------------------------------- detection

def _crossing(t, a, k, level):
    """Time where ``a`` crosses ``level`` between frames k-1 and k (linear)."""
    if k <= 0:
        return float(t[0])
    a0, a1 = a[k - 1], a[k]
    if not (np.isfinite(a0) and np.isfinite(a1)) or a1 == a0:
        return float(t[k])
    f = min(max((level - a0) / (a1 - a0), 0.0), 1.0)
    return float(t[k - 1] + f * (t[k] - t[k - 1]))


def detect_episodes(t, amp, on: float, off: float, persist: int) -> list[tuple[float, float | None, int, int]]:
    """Hysteresis episodes of ``amp``: ``[(t_on, t_off or None, k_on, k_off or n)]``.

    Starts where ``amp >= on`` and stays ``>= off`` for ``persist`` frames (or to
    the end); ends where ``amp < off`` and stays ``< on`` for ``persist`` frames
    (or to the end). NaN counts as below.
    """
    a = np.nan_to_num(np.asarray(amp, float), nan=-np.inf)
    n = a.size
    out = []
    k, k_on, t_on, active = 0, 0, 0.0, False
    persist = max(int(persist), 1)
    while k < n:
        if not active and a[k] >= on and np.all(a[k:k + persist] >= off):
            active, k_on = True, k
            t_on = _crossing(t, a, k, on)
        elif active and a[k] < off and np.all(a[k:k + persist] < on):
            out.append((t_on, _crossing(t, a, k, off), k_on, k))
            active = False
        k += 1
    if active:
        out.append((t_on, None, k_on, n))
    return out


def growth_rate(t, amp, fit_frames: int, *, centres: bool = False):
    """Growth rate ``d ln(amp) / dt`` [1/s] per frame: least-squares slope of ``ln(amp)``
    against ``t`` over the ``fit_frames`` frames centred on each frame (odd count;
    shortened at the ends, NaN where fewer than 3 finite positive frames fit).

    A fit measures the growth rate at the mean time of the frames it uses (exactly, for a
    growth rate that varies linearly in time), which is about frame ``k``'s own time only where
    the fit is centred on it (frames equally spaced in revolutions are not quite equally spaced in
    time on a ramp): within ``fit_frames // 2`` frames of either end of the data (and next
    to frames without a finite positive amplitude) it is shortened to one side, and its slope is
    that of a later (earlier) time. With ``centres=True`` the function returns ``(sigma,
    t_fit)``, ``t_fit[k]`` the mean time of frame ``k``'s fit, the time each value belongs to;
    :func:`growth_threshold` places the zero crossing with it."""
    t = np.asarray(t, float)
    with np.errstate(divide="ignore", invalid="ignore"):
        la = np.log(np.asarray(amp, float))
    ok = np.isfinite(la) & np.isfinite(t)
    half = max(int(fit_frames) // 2, 1)
    sig = np.full(t.size, np.nan)
    t_fit = np.full(t.size, np.nan)
    for k in range(t.size):
        sl = slice(max(k - half, 0), min(k + half + 1, t.size))
        m = ok[sl]
        if np.count_nonzero(m) < 3:
            continue
        tt, yy = t[sl][m], la[sl][m]
        tc = tt - tt.mean()
        den = float(np.sum(tc * tc))
        if den > 0:
            sig[k] = float(np.sum(tc * (yy - yy.mean())) / den)
            t_fit[k] = float(tt.mean())
    return (sig, t_fit) if centres else sig


def growth_threshold(t, amp, sigma, k_end: int, min_factor: float, *, t_sigma=None):
    """Instability threshold from the growth rate (module doc, step 6).

    Among frames ``0 .. k_end - 1`` (``k_end``: first frame of the first whirl
    episode, or the number of frames), find the last frame ``k`` with
    ``sigma[k] <= 0``; every later finite ``sigma`` up to ``k_end`` must be > 0 and
    ``amp`` must grow by ``min_factor`` from frame ``k`` to its maximum after it
    (whirl included; else the sign change is noise). Returns ``(t_threshold, reason)``:
    the crossing time interpolated linearly between the times of ``sigma[k]`` and
    ``sigma[k + 1]``, or None and why not. ``t_sigma``: the time each ``sigma`` value
    belongs to (the mean time of its fit, ``growth_rate(..., centres=True)``); default ``t``,
    right only where every fit is centred on its frame.
    """
    t = np.asarray(t, float)
    ts = t if t_sigma is None else np.asarray(t_sigma, float)
    sigma = np.asarray(sigma, float)
    amp = np.asarray(amp, float)
    k_end = min(int(k_end), t.size)
    idx = np.nonzero(np.isfinite(sigma[:k_end]))[0]
    if idx.size < 2:
        return None, "too few frames before the onset to fit a growth rate"
    neg = idx[sigma[idx] <= 0.0]
    if neg.size == 0:
        return None, ("the sub-synchronous amplitude grows from the first analysable frame "
                      f"(t = {t[idx[0]]:.4g} s): the threshold lies before it")
    k = int(neg[-1])
    later = idx[idx > k]
    if later.size == 0:
        return None, "the sub-synchronous amplitude does not grow at the end of the data (no threshold)"
    k1 = int(later[0])
    a0 = amp[k]
    a_max = float(np.nanmax(amp[k:]))      # significance: growth after the crossing, onset included
    if not (a0 > 0 and a_max >= min_factor * a0):
        return None, (f"the sub-synchronous amplitude grows only by {a_max / a0 if a0 > 0 else float('nan'):.3g}"
                      f" (< growth_min_factor = {min_factor:g}) after the last sign change of its "
                      "growth rate: no threshold")
    s0, s1 = sigma[k], sigma[k1]
    f = 0.0 if s1 == s0 else min(max(-s0 / (s1 - s0), 0.0), 1.0)
    return float(ts[k] + f * (ts[k1] - ts[k])), None


def analyze_journal(t, x, y, omega, clearance: float, *, eps=None,
                    params: WhirlParams | None = None) -> dict:
    """Whirl analysis of one journal (arrays in SI units); JSON-ready dict.

    Keys: ``whirl`` (bool), ``onset`` / ``vanish`` (``{"time_s", "speed_hz"}``
    of the first episode, or None), ``episodes`` (list), ``dominant_ratio``
    (median over whirl windows), ``ratio_range``, ``max_eps`` with
    ``max_eps_time_s`` / ``max_eps_speed_hz``, ``max_subsync_rel`` /
    ``max_sync_rel`` (amplitudes / clearance), ``time_resolution_s``
    (half the window duration at the onset, or the median), ``warnings``.
    """
    with np.errstate(all="ignore"), warnings.catch_warnings():
        warnings.simplefilter("ignore", RuntimeWarning)     # NaN/inf of a diverged run
        return _analyze_journal(t, x, y, omega, clearance, eps=eps, params=params)


def _analyze_journal(t, x, y, omega, clearance, *, eps, params) -> dict:
    p = params or WhirlParams()
    t = np.asarray(t, float)
    x, y, omega = (np.asarray(v, float) for v in (x, y, omega))
    warn: list[str] = []
    res: dict[str, Any] = {"whirl": False, "onset": None, "vanish": None,
                           "onset_time_s": None, "onset_speed_hz": None,      # flat copies for
                           "vanish_time_s": None, "vanish_speed_hz": None,    # dotted look-ups (compare)
                           "threshold_time_s": None, "threshold_speed_hz": None,  # growth rate crosses 0
                           "threshold_snr": None,
                           "episodes": [], "dominant_ratio": None, "ratio_range": None, "warnings": warn}
    _max_eps(res, t, x, y, omega, clearance, eps)
    _sampling_check(warn, t, omega)
    z = x + 1j * y
    if not _analysable(warn, t, z, omega):
        return res
    why = too_many_bins(t, omega, p.samples_per_rev)
    if why:
        warn.append(why)
        return res
    s = order_spectra(t, z, omega, p)
    if s.n_frames == 0:
        revs = float(np.nanmax(revolutions(t, np.nan_to_num(omega)))) if t.size else 0.0
        warn.append(f"too little rotation for one analysis window: need {p.window_revs} revolutions, "
                    f"got {revs:.3g}; whirl not analysed")
        return res
    sub = s.subsync_amplitude() / clearance
    ratio = dominant_ratio(s)
    res["max_subsync_rel"] = float(np.nanmax(sub))
    res["max_sync_rel"] = float(np.nanmax(s.sync_amplitude() / clearance))
    half = 0.5 * (s.t_end - s.t_start)
    res["time_resolution_s"] = float(np.median(half))
    eps_list = detect_episodes(s.t, sub, p.threshold, p.threshold * p.off_fraction,
                               math.ceil(p.persist_revs / p.hop_revs))
    spd = lambda tt: float(np.interp(tt, t, omega) / TWO_PI)  # noqa: E731
    all_whirl = _episodes(res, s, sub, ratio, eps_list, p, spd)
    _threshold(res, s, eps_list, p, clearance, spd)
    if eps_list:
        _first_episode(res, s, ratio, all_whirl, half[eps_list[0][2]])
    return res


def _max_eps(res, t, x, y, omega, clearance, eps) -> None:
    """The eccentricity maximum: of the ``eps`` signal, else of hypot(x, y) / clearance."""
    if eps is not None:
        e, src = np.asarray(eps, float), "signal"
    else:
        e, src = np.hypot(x, y) / clearance, "hypot(x, y) / clearance"
    fin = np.isfinite(e)
    if fin.any():
        i = int(np.nanargmax(np.where(fin, e, -np.inf)))
        res.update(max_eps=float(e[i]), max_eps_time_s=float(t[i]),
                   max_eps_speed_hz=float(omega[i] / TWO_PI), eps_source=src)


def _sampling_check(warn, t, omega) -> None:
    """Warn when the output has fewer than MIN_SAMPLES_PER_REV (8) samples per revolution at the
    top speed (the limit the scenario loader warns about before the run, analysis_sampling.py)."""
    if t.size > 1:
        f_max = float(np.nanmax(np.abs(omega))) / TWO_PI
        dt = float(np.median(np.diff(t)))
        if f_max > 0 and dt > 0 and 1.0 / (dt * f_max) < MIN_SAMPLES_PER_REV:
            warn.append(f"output interval {dt:g} s gives {1.0 / (dt * f_max):.1f} samples per revolution "
                        f"at {f_max:.4g} Hz (< {MIN_SAMPLES_PER_REV}): amplitudes are low-passed; use "
                        f"output.interval <= {1.0 / (MIN_SAMPLES_PER_REV * f_max):.3g} s")


def _analysable(warn, t, z, omega) -> bool:
    """False (with the reason in ``warn``) when the orbit cannot be analysed at all."""
    n_fin = int(np.count_nonzero(np.isfinite(z)))
    if n_fin < 2:
        warn.append(f"x/y have {n_fin} finite value(s) of {z.size}; whirl not analysed")
        return False
    if t.size and np.nanmax(omega, initial=-np.inf) <= 0:
        warn.append("rotor speed has no positive finite value (the convention is omega > 0, "
                    "counter-clockwise); whirl not analysed")
        return False
    if n_fin < z.size:
        bad = ~np.isfinite(z)
        warn.append(f"x/y are NaN/inf in {int(bad.sum())} of {z.size} samples (first at t = "
                    f"{t[np.argmax(bad)]:.6g} s; diverged run?); analysed the finite samples")
    return True


def _episodes(res, s, sub, ratio, eps_list, p, spd) -> np.ndarray:
    """One ``res["episodes"]`` entry per whirl episode; the frames in whirl (bool array)."""
    all_whirl = np.zeros(s.n_frames, bool)
    for t_on, t_off, k0, k1 in eps_list:
        in_w = np.zeros(s.n_frames, bool)
        in_w[k0:k1] = True
        in_w &= sub >= p.threshold
        all_whirl |= in_w
        r_w = ratio[in_w]
        res["episodes"].append({
            "onset_time_s": t_on, "onset_speed_hz": spd(t_on),
            "vanish_time_s": t_off, "vanish_speed_hz": None if t_off is None else spd(t_off),
            "present_at_start": k0 == 0,
            "dominant_ratio": float(np.nanmedian(r_w)) if r_w.size else None,
            "ratio_at_onset": float(ratio[k0]),
            "max_subsync_rel": float(np.nanmax(sub[k0:k1])),
        })
    return all_whirl


def _threshold(res, s, eps_list, p, clearance, spd) -> None:
    """The instability threshold: where the growth rate of the sub-synchronous amplitude
    turns positive (before the first episode), with how clearly the mode stands out there."""
    warn = res["warnings"]
    fit_frames = 2 * max(int(round(p.growth_fit_revs / p.hop_revs / 2)), 1) + 1
    gsub = s.band_amplitude(*p.growth_band) / clearance
    sigma, t_fit = growth_rate(s.t, gsub, fit_frames, centres=True)
    k_end = eps_list[0][2] if eps_list else s.n_frames
    t_th, why = growth_threshold(s.t, gsub, sigma, k_end, p.growth_min_factor, t_sigma=t_fit)
    if t_th is None:
        warn.append(f"threshold_speed_hz not estimated: {why}")
        return
    res["threshold_time_s"], res["threshold_speed_hz"] = t_th, spd(t_th)
    # how clearly the growing mode stands out at the crossing: the largest band bin over the
    # largest band bin outside its main lobe (+-1 bin). The growth rate is that of the whole
    # band's amplitude, so anything else in the band as large as the mode (the unbalance
    # response's leakage near a critical, a broadband numerical floor) moves the zero crossing
    # (typically late, docs/analysis.md). Until 2026-12-06 this was the largest over the median
    # bin, which relied on a floor that the unweighted detrend put into every band bin
    # (detrend_windowed): without it, the median no longer sees a leakage at one band edge.
    kk = int(np.argmin(np.abs(s.t - t_th)))
    sel = (s.orders >= p.growth_band[0] - 1e-12) & (s.orders <= p.growth_band[1] + 1e-12)
    mags = np.abs(s.X[kk, sel])
    j = int(np.argmax(mags))
    rest = mags[np.abs(np.arange(mags.size) - j) > 1]
    top = float(np.max(rest)) if rest.size else 0.0
    res["threshold_snr"] = float(mags[j] / top) if top > 0 else None
    if res["threshold_snr"] is not None and res["threshold_snr"] < 3.0:
        warn.append(f"threshold_speed_hz {res['threshold_speed_hz']:.4g} Hz: the growing mode does not "
                    f"stand out in growth_band there (its peak / the largest other bin = "
                    f"{res['threshold_snr']:.2g} < 3): the zero crossing may be that of other content "
                    "(the unbalance response's leakage, a broadband floor) and is unreliable (typically "
                    "late, where the mode rises out of it)")


def _first_episode(res, s, ratio, all_whirl, resolution) -> None:
    """Onset (first episode), vanish (last episode) and the whirl ratio over all episodes."""
    first, last = res["episodes"][0], res["episodes"][-1]
    res["whirl"] = True
    res["onset"] = {"time_s": first["onset_time_s"], "speed_hz": first["onset_speed_hz"],
                    "present_at_start": first["present_at_start"]}
    res["time_resolution_s"] = float(resolution)
    res["onset_time_s"], res["onset_speed_hz"] = first["onset_time_s"], first["onset_speed_hz"]
    if last["vanish_time_s"] is not None:
        res["vanish"] = {"time_s": last["vanish_time_s"], "speed_hz": last["vanish_speed_hz"]}
        res["vanish_time_s"], res["vanish_speed_hz"] = last["vanish_time_s"], last["vanish_speed_hz"]
    r_all = ratio[all_whirl]
    res["dominant_ratio"] = float(np.nanmedian(r_all))
    res["ratio_range"] = [float(np.nanmin(r_all)), float(np.nanmax(r_all))]
    if first["present_at_start"]:
        res["warnings"].append("sub-synchronous motion already above threshold in the first window "
                               f"(t = {s.t[0]:.4g} s): the onset lies before it")


# ----------------------------------------------------------------------------- files

def _signal(cols: Mapping[str, np.ndarray], name: Any, what: str, csv_path: Path) -> np.ndarray:
    if not isinstance(name, str) or name not in cols:
        near = sorted(c for c in cols if isinstance(name, str) and c.split(".")[-1] == name.split(".")[-1])
        raise KeyError(f"{csv_path.name}: {what} signal '{name}' not found in the header; "
                       f"columns ending like it: {near or 'none'}; available: {sorted(cols)[:12]}"
                       f"{' ...' if len(cols) > 12 else ''}. Fix the scenario's analysis section "
                       "or add the signal to output.signals")
    return cols[name]


def analyze_run(out_dir: str | Path, spec: Mapping[str, Any]) -> dict:
    """Analyse a finished (or failed) run; never raises.

    ``spec`` is the scenario's ``analysis:`` mapping: ``speed`` (rad/s signal),
    ``journals`` ({name: {x, y, eps (optional), clearance [m] (optional)}}),
    optional ``fields`` and ``whirl`` (:class:`WhirlParams` keys). When a
    journal has no ``clearance`` it is estimated as ``median(|z| / eps)``.

    Returns ``{"method", "parameters", "spec", "speed_max_hz", "journals":
    {name: analyze_journal(...) or {"error": ...}}}`` or ``{"error": "..."}``.
    """
    try:
        return _analyze_run(Path(out_dir), spec)
    except Exception as exc:  # the contract: report, never raise
        logger.warning("analysis of %s failed", out_dir, exc_info=True)
        return {"error": f"{type(exc).__name__}: {exc}"}


def _analyze_run(out_dir: Path, spec: Mapping[str, Any]) -> dict:
    if not isinstance(spec, Mapping):
        return {"error": f"analysis spec must be a mapping (got {type(spec).__name__})"}
    run = RunDirectory(out_dir)
    csv_path = run.results_file
    if not csv_path.is_file():
        return {"error": f"{csv_path}: not found; the run wrote no results"}
    try:
        params = WhirlParams.from_mapping(spec.get("whirl"))
    except (ValueError, TypeError) as exc:
        return {"error": str(exc)}
    cols = run.columns()
    t = cols.get("time")
    if t is None:
        return {"error": f"{csv_path.name}: no 'time' column (header: {sorted(cols)[:8]})"}
    if t.size < 2:
        return {"error": f"{csv_path.name}: {t.size} data row(s); need at least 2 to analyse"}
    try:
        omega = _signal(cols, spec.get("speed"), "analysis.speed", csv_path)
    except KeyError as exc:
        return {"error": exc.args[0]}
    out: dict[str, Any] = {
        "method": "order-domain short-time spectra; see docs/analysis.md",
        "parameters": {k: (list(v) if isinstance(v, tuple) else v) for k, v in asdict(params).items()},
        "spec": plain(spec, "null"),
        "speed_max_hz": (float(np.max(omega[np.isfinite(omega)])) / TWO_PI
                         if np.isfinite(omega).any() else None),
        "journals": {},
    }
    journals = spec.get("journals") or {}
    if not isinstance(journals, Mapping) or not journals:
        out["error"] = "analysis.journals: expected a mapping {name: {x, y, eps, clearance}}, got none"
        return out
    for name, js in journals.items():
        try:
            out["journals"][str(name)] = _analyze_one(name, js, cols, t, omega, params, csv_path)
        except (KeyError, ValueError, TypeError) as exc:
            out["journals"][str(name)] = {"error": exc.args[0] if exc.args else repr(exc)}
    return plain(out, "null")      # strict JSON for summary.json: NaN/inf -> None


def _analyze_one(name, js, cols, t, omega, params, csv_path) -> dict:
    if not isinstance(js, Mapping):
        raise TypeError(f"analysis.journals.{name}: expected a mapping with x, y, eps, clearance")
    x = _signal(cols, js.get("x"), f"analysis.journals.{name}.x", csv_path)
    y = _signal(cols, js.get("y"), f"analysis.journals.{name}.y", csv_path)
    eps = _signal(cols, js["eps"], f"analysis.journals.{name}.eps", csv_path) if js.get("eps") else None
    c = js.get("clearance")
    note = None
    if c is None:
        if eps is None:
            raise ValueError(f"analysis.journals.{name}: needs 'clearance' [m] (or an 'eps' signal "
                             "to estimate it from)")
        ok = np.isfinite(eps) & (eps > 0.05)
        if not ok.any():
            raise ValueError(f"analysis.journals.{name}: no 'clearance' and eps never exceeds 0.05; "
                             "give clearance [m]")
        c = float(np.median(np.hypot(x, y)[ok] / eps[ok]))
        note = f"clearance not given: estimated {c:.4g} m from median(|z| / eps)"
    c = float(c)
    if not c > 0:
        raise ValueError(f"analysis.journals.{name}.clearance must be > 0 [m] (got {c})")
    r = analyze_journal(t, x, y, omega, c, eps=eps, params=params)
    r["clearance"] = c
    if note:
        r["warnings"].insert(0, note)
    return r
