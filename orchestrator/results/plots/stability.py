"""``rotorcosim stability --plot OUT``: the least-damped mode of the linear model over speed.

Two panels over the rotor speed [Hz], from the speeds the threshold search evaluated (the scan
and Brent's steps, ``result["scan"]``): the logarithmic decrement of the least-damped eigenvalue,
``delta = -2 pi Re(lambda) / |Im(lambda)|`` (positive: the mode decays; the threshold is where it
crosses 0; API 684's measure of a stability margin), and its frequency against 0.5 x speed (a
film whirl sits just below it). The threshold and its whirl frequency are marked, so is every
other crossing (stable again, or, already unstable at the lower end, stable from there), and
speeds without a static equilibrium (grey crosses). The figure of a search that was stopped
(``result["stopped"]``: Ctrl-C, SIGTERM, an error at one speed) draws the speeds done, its
unrefined crossings as their brackets (shaded), and says where it stopped; a crossing Brent could
not refine (no equilibrium, orbit or eigenvalues at one of its speeds) is shaded as its bracket
too, the speed that failed a red cross. With ``--unbalance``
(``result["unbalance"]``) the same panels from the largest Floquet multiplier (decrement
``-2 pi ln|mu| / |arg mu|``, frequency ``|arg mu| f``) and the linear threshold marked beside.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

from orchestrator.results.safe_write import save_figure

DPI = 110


def draw(result: dict, path: Path | str) -> Path:
    """Write the figure of a :func:`orchestrator.stability.stability` result to ``path``."""
    from matplotlib.figure import Figure
    scan = result.get("scan") or []
    f = np.array([s["speed_hz"] for s in scan], dtype=float)
    fw = np.array([s["whirl_hz"] for s in scan], dtype=float)
    dec = np.array([np.nan if s["log_decrement"] is None else s["log_decrement"] for s in scan], dtype=float)
    fig = Figure(figsize=(8, 6.2), layout="constrained")
    ax1, ax2 = fig.subplots(2, 1, sharex=True)
    floquet = bool(result.get("unbalance"))         # --unbalance: the largest Floquet multiplier's rate, |arg mu| f
    ax1.plot(f, dec, "o-", ms=3, lw=1.2, color="C0",
             label="largest Floquet multiplier (orbit under the unbalance)" if floquet else "least-damped mode")
    ax1.axhline(0.0, color="k", lw=0.8)
    ax1.set_ylabel("logarithmic decrement [-]")
    ax2.plot(f, fw, "o-", ms=3, lw=1.2, color="C0", label="its frequency")
    if f.size:
        lim = np.array([f.min(), f.max()])
        ax2.plot(lim, 0.5 * lim, ":", color="0.4", lw=1.0, label="0.5 x speed")
    th = result.get("threshold_hz")
    if th is not None:
        lab = (f"threshold {th:.2f} Hz, whirl {result['whirl_hz']:.2f} Hz "
               f"({result['whirl_ratio']:.3f} x speed)")
        for ax in (ax1, ax2):
            ax.axvline(th, color="C3", ls="--", lw=1.2, label=lab if ax is ax1 else None)
        ax2.plot([th], [result["whirl_hz"]], "s", color="C3", ms=6)
    lin = (result.get("linear") or {}).get("threshold_hz") if floquet else None
    if lin is not None:
        for ax in (ax1, ax2):
            ax.axvline(lin, color="0.4", ls="--", lw=1.0, label=f"linear threshold {lin:.2f} Hz (no unbalance)"
                       if ax is ax1 else None)
    from orchestrator.stability import later_crossings
    for c in later_crossings(result):
        lab = f"{c['becomes']} from {c['speed_hz']:.2f} Hz"
        for ax in (ax1, ax2):
            ax.axvline(c["speed_hz"], color="C2" if c["becomes"] == "stable" else "C3", ls=":", lw=1.2,
                       label=lab if ax is ax1 else None)
    # the unrefined crossings: a stopped search's, and those where a step of Brent's failed
    for k, c in enumerate(result.get("crossings_bracketed") or []):
        a, b = c["between_hz"]
        why = f": Brent failed at {c['failed_at_hz']:.5g} Hz" if c.get("failed_at_hz") is not None else ""
        lab = f"{c['becomes']} from between {a:.5g} and {b:.5g} Hz (not refined{why})"
        for ax in (ax1, ax2):
            ax.axvspan(a, b, color="C3" if c["becomes"] == "unstable" else "C2", alpha=0.25,
                       label=lab if ax is ax1 and k < 3 else None)
    failed = [c["failed_at_hz"] for c in result.get("crossings_bracketed") or [] if c.get("failed_at_hz") is not None]
    if failed:           # no value there: on the zero line and at 0.5 x speed, as the speeds left out
        for ax in (ax1, ax2):
            ax.plot(failed, np.zeros(len(failed)) if ax is ax1 else 0.5 * np.asarray(failed), "x", color="C3", ms=6,
                    mew=1.5, label="Brent's step failed (see the notes)" if ax is ax1 else None)
    for key, marker, what in (("speeds_without_equilibrium_hz", "x",
                               "no periodic orbit" if floquet else "no static equilibrium"),
                              ("speeds_without_eigenvalues_hz", "+", "eigenvalues not computed")):
        bad = result.get(key) or []
        if bad:
            for ax in (ax1, ax2):
                ax.plot(bad, np.zeros(len(bad)) if ax is ax1 else 0.5 * np.asarray(bad), marker, color="0.5",
                        ms=4, label=what if ax is ax1 else None)
    stop = result.get("stopped")
    if stop:
        where = f" at {stop['at_speed_hz']:.4g} Hz" if stop.get("at_speed_hz") is not None else ""
        why = {"SIGINT": "interrupted", "SIGTERM": "terminated (SIGTERM)"}.get(stop["by"], "stopped by an error")
        ax1.set_title(f"incomplete: {why}{where} ({stop['phase']}, {stop['speeds_done']} of "
                      f"{stop['speeds_planned']} speeds of the scan done)", fontsize=9)
    elif result.get("status") == "threshold_bracketed":     # not stopped: a step of Brent's failed in its bracket
        a, b = result["threshold_between_hz"]
        ax1.set_title(f"threshold not refined: between {a:.5g} and {b:.5g} Hz (a step of Brent's failed there)",
                      fontsize=9)
    elif result.get("status") == "stable":
        ax1.set_title("no crossing in the range: stable there", fontsize=9)
    elif result.get("status") == "unstable_at_lower_bound":
        ax1.set_title("unstable already at the lower end of the range", fontsize=9)
    elif result.get("status") == "threshold_not_located":
        a, b = result["threshold_between_hz"]
        ax1.set_title(f"unstable from between {a:.4g} and {b:.4g} Hz (no static equilibrium there)", fontsize=9)
    fin = dec[np.isfinite(dec)]
    if fin.size and np.ptp(fin) > 0:      # keep the zero line and the crossing in view
        lo, hi = min(fin.min(), 0.0), max(fin.max(), 0.0)
        pad = 0.05 * (hi - lo)
        ax1.set_ylim(lo - pad, hi + pad)
    ax2.set_xlabel("rotor speed [Hz]")
    ax2.set_ylabel("whirl frequency [Hz]")
    for ax in (ax1, ax2):
        ax.grid(True, lw=0.4, alpha=0.6)
        ax.legend(fontsize=8, loc="best")
    film = {"hs": "half-Sommerfeld films", "short": "short-bearing closed form"}.get(result.get("film"),
                                                                                    result.get("film"))
    from orchestrator.results.plots.common import plain
    what = "stability with the unbalance (Floquet)" if floquet else "linear stability"
    fig.suptitle(f"{plain(result.get('scenario'))}: {what} ({film})", fontsize=10)
    return save_figure(fig, path, dpi=DPI)
