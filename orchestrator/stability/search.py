"""The linear stability threshold of a scenario (``rotorcosim stability``): the search over speeds
and the result.

What it computes (docs/analysis.md, "Linear stability threshold"): the lowest speed at which an
eigenvalue of the rotor's linear model with speed-dependent linear film coefficients at its
bearing stations crosses into the right half plane (a geometric scan of the whole range, then
Brent on every sign change of the largest real part, the first upwards with the bracket and
tolerances of :func:`rotor_fmu.stability.threshold_speed`; Lund 1974, J. Eng. Ind. 96:509; Childs
1993, "Turbomachinery Rotordynamics", sec. 3.6), the whirl frequency ratio of the crossing mode,
and each bearing's static eccentricity there. The coefficients are taken at the static
equilibrium of each journal under its static load (:mod:`orchestrator.stability.system`), with
the film model the ``film`` argument names (:mod:`orchestrator.stability.films`).
"""

from __future__ import annotations

import contextlib
import math
import sys
import time
from dataclasses import dataclass
from typing import Any

import numpy as np

from orchestrator.scenario.analysis_clearance import BEARING_MODEL
from orchestrator.stability.films import _NUMERIC, film_model
from orchestrator.stability.partial import SpeedStopped, Stop, _pair, bracket, stop_of, widened
from orchestrator.stability.system import (Bearing, EigenvaluesFailed, StabilityError, System, _static_loads,
                                          build_system)

FILMS = ("short", "hs", "mc")
MAX_SPEED_HZ = 1e7         # highest --speeds HI (600 million rpm: beyond any rotor; 2 pi HI must not overflow)
MC_SCAN = 80            # speeds of the default scan with --film mc (about 0.5 s each at 40 x 40): as the others


def _notes(system: System, film: str, ring_spin: bool, weight: np.ndarray, extra: np.ndarray) -> list[str]:
    """The result's notes on its inputs: each --load with the sum it makes, what the linear model
    leaves out of each bearing (its own mass-conserving film, the ring spin, grooves and feed
    pressure in the short-bearing closed form) and the short bearing's B/D."""
    names = [b.instance for b in system.bearings]
    total = weight + extra
    fmt = lambda v: f"({v[0] + 0.0:.4g}, {v[1] + 0.0:.4g}) N"        # noqa: E731 (+ 0.0: no "-0")
    notes = [f"bearing '{n}': static load {fmt(total[k])} = the rotor's weight share {fmt(weight[k])} plus --load "
             f"{fmt(extra[k])}" for k, n in enumerate(names) if extra[k].any()]
    for b in (x for x in system.bearings if x.kind == "floating_ring"):
        mc = [side for side in ("inner", "outer") if getattr(b.params, side).cavitation == 1]
        if mc and film != "mc":
            notes.append(f"bearing '{b.instance}': its {' and '.join(mc)} film is mass-conserving (cavitation = 1); "
                         "its coefficients here are those of the half-Sommerfeld film")
        if not ring_spin:                       # every ring floats (a semi-floating one is refused)
            notes.append(f"bearing '{b.instance}': full floating ring, spin held at its steady value in the "
                         "linear model" + (" (with --film hs, --ring-spin adds its perturbation)" if film == "mc"
                                           else " (--ring-spin adds its perturbation)"))
    for b in (x for x in system.bearings if x.kind == "journal"):
        if b.params.cavitation == 1 and film != "mc":
            notes.append(f"bearing '{b.instance}' is mass-conserving (cavitation = 1): its coefficients here are "
                         "those of the half-Sommerfeld film (the HS linearisation), not of its own film; "
                         "--film mc linearises its own film with its cavity dynamics")
        if film == "short" and (b.params.groove_width > 0 or b.params.p_feed != b.params.p0):
            notes.append(f"bearing '{b.instance}': the short-bearing closed form has no groove and no feed "
                         "pressure (use --film hs for the film with them)")
    if film == "short":
        notes.append("short-bearing theory is a bound for B/D not small (B/D of "
                     + ", ".join(f"'{b.instance}' {b.params.B / (2 * b.params.R):.2f}" for b in system.bearings)
                     + ")")
    return notes


@dataclass
class Searched:
    """What :func:`_search` found: the threshold speed ``at`` [rad/s] (None without one, or when
    it was stopped before locating it) and, for a search that stopped before its end (a stop
    signal, an error at one speed), ``stop`` (:class:`orchestrator.stability.partial.Stop`; None
    for a whole search). The rest is in the result dict it filled."""

    at: float | None
    stop: Stop | None = None


class _NoStop:
    requested = False
    signum = None


def _search(max_re, ws: np.ndarray, result: dict, xtol: float = 1e-9, *, stop=None, bar=None,
            without: str = "static equilibrium", continued=None) -> Searched:
    """Fill ``result`` (its ``crossings``, ``crossings_bracketed``, ``status``, the threshold's
    entries, ``notes``) from ``max_re(omega) -> (largest real part, |Im| there)`` at the speeds
    ``ws`` [rad/s] and between them. ``stop``: a :class:`orchestrator.coupling.lifecycle.StopRequests`
    looked at before each speed (scan and refinement; :mod:`orchestrator.stability.partial`);
    ``bar``: a progress bar (tqdm's calls) advanced by each speed of the scan; ``without``: what a
    speed left out (``max_re`` raised :class:`StabilityError`) lacks, in the notes (one raising
    :class:`EigenvaluesFailed` has it, but not its eigenvalues: a note of its own). ``continued``:
    ``max_re`` by continuation from the speeds done (the film model's ``max_re_continued``, which
    leaves the warm start of the next ``max_re`` as it was): after the scan, each speed left out is
    computed so, outwards from the speeds done (:func:`_continue_left_out`), before any crossing is
    refined; and a step of Brent's where ``max_re`` raised StabilityError is tried once more with it.

    A StabilityError at a step of Brent's (no static equilibrium, no periodic orbit, eigenvalues not
    computed there; ``continued`` failing too) leaves that crossing unrefined, not the search: it is
    kept in ``crossings_bracketed`` as the narrowest bracket of the speeds done
    (:func:`orchestrator.stability.partial.bracket`) with ``not_refined`` (why, naming the speed)
    and ``failed_at_hz``, a note names it, and the later crossings are refined; when it is the first
    sign change the status is ``threshold_bracketed`` (``threshold_between_hz``), with no stop. Any
    other error there, and a stop request, stop the search (:class:`Searched` ``stop``)."""
    from rotor_fmu.stability import refine_crossing
    # the whole range on a geometric grid, then Brent on every sign change of the largest real part
    # between neighbouring speeds (rotor_fmu.stability.refine_crossing, as threshold_speed refines
    # its bracket: the same number): the first one upwards is the threshold, a later one downwards is
    # where the system is stable again (a run-up's whirl "vanish" has its linear counterpart there).
    # A speed without a static equilibrium (a load a film cannot carry there inside its clearance,
    # e.g. a floating ring's outer film at low speed) is left out, and no crossing is sought across it:
    # a sign change across such speeds is named (status "threshold_not_located" when it is the first).
    # A stop (signal, error) ends it where it is: nothing more is computed, the sign changes between
    # speeds done are kept as brackets (partial.py). A step of Brent's without an equilibrium (orbit,
    # eigenvalues) is no stop: that crossing is kept as its bracket, with why, and the search goes on.
    requests = stop if stop is not None else _NoStop
    # a second signal abandons the speed being computed (StopRequests.abandoning), and only that: one
    # landing between two speeds (the progress bar, the bookkeeping after the scan, a stop's own
    # handling) is held, and the next check of requests.requested stops there; it raised
    # KeyboardInterrupt out of the search, which ended with a bare "interrupted" and no table
    abandoning = getattr(requests, "abandoning", None) or contextlib.nullcontext
    evals: dict[float, tuple] = {}           # every speed evaluated -> max_re's answer (brackets; Brent's known)
    current: list = [None]                   # the speed being evaluated

    def guarded(fn):
        """fn(w) as one speed of the search: the stop checked first, a second signal abandoning
        only it, its largest real part kept for the brackets."""
        def at(w):
            current[0] = w
            if requests.requested:
                raise SpeedStopped(w)
            with abandoning():
                v = fn(w)
            evals[float(w)] = v
            return v
        return at
    checked = guarded(max_re)

    vals: list[float | None] = []
    failed: list[tuple[float, StabilityError]] = []
    halt: Stop | None = None
    for w in ws:
        try:
            vals.append(checked(w)[0])
        except StabilityError as exc:
            vals.append(None)
            failed.append((w, exc))
        except (Exception, KeyboardInterrupt) as exc:     # a stop request, or an error at this speed
            halt = stop_of(exc, requests.signum, w, "scan")
            break
        if bar is not None:
            bar.update(1)
    done = len(vals)
    again = None if continued is None else guarded(continued)
    if again is not None and failed and halt is None:
        halt, retried = _continue_left_out(again, ws, vals, failed, result, requests.signum)
        # the note's reason: that of the first speed the continuation failed at (it names both tries)
        failed.sort(key=lambda f: (f[0] not in retried, f[0]))
    ok = [k for k, v in enumerate(vals) if v is not None]
    if not ok and halt is None:
        raise failed[0][1]
    uncomputed = {float(w) for w, e in failed if isinstance(e, EigenvaluesFailed)}
    for key, lacks, these in (("speeds_without_equilibrium_hz", f"no {without}",
                               [f for f in failed if float(f[0]) not in uncomputed]),
                              ("speeds_without_eigenvalues_hz", "eigenvalues not computed",
                               [f for f in failed if float(f[0]) in uncomputed])):
        if these:
            hz = sorted(w / (2 * math.pi) for w, _ in these)
            where = ", ".join(f"{f:.4g}" for f in hz[:6]) + (" ..." if len(these) > 6 else "")
            result["notes"].append(f"{lacks} at {len(these)} of the {done} speeds searched ({where} Hz), "
                                   f"left out: {these[0][1]}".replace("; raise the lower end of --speeds", ""))
            result[key] = hz
    unlocated = None          # the first sign change, when it lies across speeds without equilibrium
    brackets = result["crossings_bracketed"]
    cells: list[tuple[int, int]] = []          # the scan's neighbours (k0, k1) of each bracket

    def step(w):
        """One of Brent's speeds: a StabilityError there tried once more by continuation (``again``)."""
        try:
            return checked(w)
        except StabilityError:
            if again is None:
                raise
        return again(w)
    for k0, k1 in zip(ok, ok[1:]):
        if (vals[k0] < 0.0) == (vals[k1] < 0.0):
            continue
        becomes = "unstable" if vals[k0] < 0.0 else "stable"
        if k1 == k0 + 1:
            gave_up = None              # (the speed, the StabilityError) where Brent could not go on
            if halt is None:
                if bar is not None:
                    bar.set_postfix_str(f"refining the crossing between {ws[k0] / (2 * math.pi):.4g} and "
                                        f"{ws[k1] / (2 * math.pi):.4g} Hz")
                try:
                    # the scan's answer at the lower end is taken as it is; the upper end is computed
                    # again, which puts the warm start of a film model that holds one (--film mc: each
                    # film's state, the root the eigenvalue search starts from) next to the crossing,
                    # where Brent goes next, not at the scan's last speed
                    wc, nu = refine_crossing(step, ws[k0], ws[k1], xtol, known={ws[k0]: evals[float(ws[k0])]})
                except StabilityError as exc:      # no equilibrium (orbit, eigenvalues) at a step: this crossing only
                    gave_up = (current[0], exc)
                except (Exception, KeyboardInterrupt) as exc:     # a stop request, or an error at a step
                    halt = stop_of(exc, requests.signum, current[0], "refine")
                else:
                    result["crossings"].append({"speed_hz": wc / (2 * math.pi), "whirl_hz": nu / (2 * math.pi),
                                                "becomes": becomes})
                    continue
            a, b = (x / (2 * math.pi) for x in bracket({w: v[0] for w, v in evals.items()}, ws[k0], ws[k1]))
            brackets.append({"between_hz": [a, b], "width_hz": b - a, "becomes": becomes})
            cells.append((k0, k1))
            if gave_up is not None:
                _not_refined(result, brackets[-1], ws[k0], ws[k1], *gave_up, continued is not None)
            continue
        between = [ws[k0] / (2 * math.pi), ws[k1] / (2 * math.pi)]
        gap = {float(w) in uncomputed for w in ws[k0 + 1:k1]}
        across = ("without a " + without if gap == {False} else "whose eigenvalues were not computed"
                  if gap == {True} else f"without a {without} or whose eigenvalues were not computed")
        result["notes"].append(f"the largest real part changes sign between {between[0]:.4g} and "
                               f"{between[1]:.4g} Hz (it becomes {becomes}), across speeds {across}: that "
                               "crossing is not located")
        if unlocated is None and not result["crossings"] and not brackets:
            unlocated = between
    vals = [vals[k] for k in ok]
    at = None
    # the first sign change: a crossing, or a bracket not refined (before it: Brent failed there)
    crossings = result["crossings"]
    bracketed_first = brackets and not (crossings and crossings[0]["speed_hz"] < brackets[0]["between_hz"][0])
    if not vals:                       # stopped before a speed with an equilibrium was done
        status = "incomplete"
    elif vals[0] >= 0.0:
        status = "unstable_at_lower_bound"
    elif unlocated is not None:        # stable below, unstable above, speeds without equilibrium between
        status = "threshold_not_located"
        result["threshold_between_hz"] = unlocated
    elif crossings and not bracketed_first:
        first = crossings[0]
        status, at = "threshold", 2 * math.pi * first["speed_hz"]
        result.update(threshold_hz=first["speed_hz"], whirl_hz=first["whirl_hz"],
                      whirl_ratio=first["whirl_hz"] / first["speed_hz"])
    elif brackets:                     # its bracket not refined: stopped before, or Brent failed in it
        status = "threshold_bracketed"
        result.update(threshold_between_hz=brackets[0]["between_hz"],
                      threshold_bracket_width_hz=brackets[0]["width_hz"])
    elif halt is not None:             # stable in the speeds done
        status = "incomplete"
    else:
        status = "stable"
    result["status"] = status
    if halt is not None:
        halt.done, halt.planned = done, len(ws)
        lo, hi = result.get("speed_range_hz") or (ws[0] / (2 * math.pi), ws[-1] / (2 * math.pi))
        if halt.phase == "continuation":    # the continuation needs the speeds done: the whole scan again
            halt.rest = (lo, hi, len(ws))
        elif halt.phase == "scan":       # from the last speed done (rounded down): a crossing just after it is found
            last = math.floor(ws[done - 1] / (2 * math.pi) * 1e3) / 1e3 if done else lo
            halt.rest = (lo, hi, len(ws)) if done == 0 else (max(last, lo), hi, len(ws) - done + 1)
        else:   # the crossing it was refining and the later ones (those before it Brent gave up on are not
            # the rest's: pasted back they would fail the same way; their notes say why)
            pending = [k for k, c in enumerate(brackets) if "not_refined" not in c]
            if len(pending) == 1:      # the crossing it was refining, the last one: its bracket
                halt.rest = (*widened(*brackets[pending[0]]["between_hz"]), 2)
                halt.rest_crossings = 1
            elif pending:              # that one and the later ones: the scan's grid from the first to the last
                # (the same speeds, so the same sign changes; Brent's bracket of the first is not kept: a grid
                # starting there would move the later speeds, and two close crossings could fall in one cell)
                k0, k1 = cells[pending[0]][0], cells[pending[-1]][1]
                halt.rest = (*widened(ws[k0] / (2 * math.pi), ws[k1] / (2 * math.pi)), k1 - k0 + 1)
                halt.rest_crossings = len(pending)
    return Searched(at, halt)


def _not_refined(result: dict, entry: dict, w0: float, w1: float, w: float, exc: StabilityError,
                 retried: bool) -> None:
    """A crossing between the scan's speeds ``w0`` and ``w1`` [rad/s] that Brent could not refine,
    ``exc`` raised at its step ``w`` (tried once more by continuation when ``retried``): its bracket
    ``entry`` (in ``crossings_bracketed``) gets why (``not_refined``) and that speed (``failed_at_hz``),
    and the notes a line naming both."""
    why = str(exc).replace("; raise the lower end of --speeds", "")      # the scan's fix, not one inside a bracket
    also = " (also by continuation from the speeds done)" if retried else ""
    entry.update(not_refined=f"Brent's step at {w / (2 * math.pi):.6g} Hz failed{also}: {why}",
                 failed_at_hz=w / (2 * math.pi))
    a, b = entry["between_hz"]
    how = "" if (a, b) == (w0 / (2 * math.pi), w1 / (2 * math.pi)) else " (narrowed by Brent's speeds before it)"
    result["notes"].append(f"the crossing between {w0 / (2 * math.pi):.4g} and {w1 / (2 * math.pi):.4g} Hz (it "
                           f"becomes {entry['becomes']}) is not refined: {entry['not_refined']}; kept as its bracket"
                           + (f", {_pair(a, b)} Hz{how}" if how else ""))


def _outwards(vals: list) -> list[list[int]]:
    """The speeds left out (``vals[k] is None``) as walks, each starting next to a speed done and
    going away from it: a run of them below the first speed done downwards, above the last one
    upwards, a run between two speeds done from both of its ends, alternately (two walks, interleaved
    by :func:`_continue_left_out`)."""
    walks: list[list[int]] = []
    k = 0
    while k < len(vals):
        if vals[k] is not None:
            k += 1
            continue
        j = k
        while j + 1 < len(vals) and vals[j + 1] is None:
            j += 1
        below, above = k > 0, j + 1 < len(vals)       # a speed done next to the run, below / above it
        run = list(range(k, j + 1))
        if below and above:
            half = (len(run) + 1) // 2
            walks += [run[:half], run[half:][::-1]]
        elif above:
            walks.append(run[::-1])
        elif below:
            walks.append(run)
        k = j + 1
    return walks


def _continue_left_out(again, ws, vals: list, failed: list, result: dict, signum) -> tuple[Stop | None, list]:
    """The speeds the scan left out (``failed``: (omega, StabilityError)) computed by ``again``
    (continuation from the speeds done): walk by walk (:func:`_outwards`), each speed from its
    neighbour done; a walk ends at its first speed that fails again (its error replaces the scan's;
    a ring's operating point names both tries), the speeds beyond it are not tried (a continuation
    from further away through the speed that failed). ``vals`` and ``failed`` are updated in place;
    the speeds so computed are listed in ``result["continued_speeds_hz"]`` (the scan's reason for
    each in ``continued_scan_reasons``) and a note. Returns (the :class:`Stop` of a stop (a signal,
    an error other than StabilityError; phase ``"continuation"``) or None, the speeds [rad/s] where
    the continuation failed)."""
    walks = [w for w in _outwards(vals) if w]
    errors = {float(w): e for w, e in failed}      # each speed's reason (the scan's, then the continuation's)
    reached: list[float] = []
    retried: list = []                 # speeds where the continuation failed too
    untried = 0
    halt = None
    while walks and halt is None:
        nxt = []
        for walk in walks:             # one speed of each walk in turn (a gap's two ends alternately)
            k = walk[0]
            try:
                vals[k] = again(ws[k])[0]
            except StabilityError as exc:
                errors[float(ws[k])] = exc
                retried.append(ws[k])
                untried += len(walk) - 1
                continue
            except (Exception, KeyboardInterrupt) as exc:     # a stop request, or an error at this speed
                halt = stop_of(exc, signum, ws[k], "continuation")
                break
            reached.append(float(ws[k]))
            if walk[1:]:
                nxt.append(walk[1:])
        walks = nxt
    failed[:] = [(w, errors[float(w)]) for w, _ in failed if float(w) not in reached]
    if reached:
        hz = sorted(w / (2 * math.pi) for w in reached)
        result["continued_speeds_hz"] = hz
        result["continued_scan_reasons"] = [str(errors[w]) for w in sorted(reached)]
        where = ", ".join(f"{f:.4g}" for f in hz[:6]) + (" ..." if len(hz) > 6 else "")
        result["notes"].append(f"{_speeds(len(hz))} the scan left out ({where} Hz) computed again by continuation "
                               f"in the speed from their neighbours done (the scan's reason at {hz[0]:.4g} Hz: "
                               f"{errors[min(reached)]})".replace("; raise the lower end of --speeds", ""))
    if untried:
        result["notes"].append(f"{_speeds(untried)} the scan left out not tried again by continuation: a speed between "
                               "them and the speeds done failed it")
    return halt, retried


def _speeds(n: int) -> str:
    return f"{n} speed" + ("" if n == 1 else "s")


def log_decrement(re: float, im: float) -> float | None:
    """-2 pi Re / |Im| of an eigenvalue, None for a real one (no oscillation)."""
    return None if im == 0.0 else -2.0 * math.pi * re / abs(im)


def later_crossings(result: dict) -> list[dict]:
    """The crossings of a :func:`stability` result other than the threshold: after the first one
    when that is the threshold (status ``"threshold"``), else all of them (already unstable at the
    lower end: the first crossing is where it becomes stable)."""
    crossings = result.get("crossings") or []
    return crossings[1:] if result.get("status") == "threshold" else list(crossings)


def stability(scenario, *, film: str = "hs", speeds: tuple[float, float] | None = None, n_scan: int | None = None,
              ring_spin: bool = False, loads: dict[str, tuple[float, float]] | None = None,
              mc_solver: str = "counted", progress: bool | None = None, requests=None, unbalance: bool = False,
              n_per_rev: int | None = None) -> dict:
    """The threshold result (a JSON-ready dict) of a loaded scenario: the search of the module doc,
    for the scenarios of :mod:`orchestrator.stability.system`, with the films of
    :mod:`orchestrator.stability.films`.

    ``loads``: bearing instance -> static force (Fx, Fy) [N] the rotor puts on that bearing in
    addition to its share of the rotor's weight (``--load``: a gear or belt force, a magnetic pull,
    a horizontal rotor's load with g = 0), in the convention of
    :func:`rotor_fmu.stability.static_bearing_loads` (down is -y). ``n_scan``: speeds of the scan
    (default 80, :data:`MC_SCAN` with ``film="mc"``, whose crossings are refined to 0.01 Hz instead
    of 1e-9 rad/s). ``mc_solver`` (``film="mc"``): ``"counted"`` (sparse, its least-damped eigenvalue
    counted, :func:`rotor_fmu.film_system.rightmost`) or ``"dense"`` (all eigenvalues by QZ, the
    reference: the same roots, ~30 x slower at 40 x 40). ``progress``: a progress bar of the scan on
    stderr (tqdm): None (default) when stderr is a terminal and the scan lasts more than a few
    seconds, True always (after those seconds), False never. ``unbalance``: the threshold of the
    rotor WITH its unbalance (``--unbalance``): at each speed its synchronous periodic orbit and the
    Floquet growth rate along it in place of the largest real part (:mod:`orchestrator.stability.floquet`,
    ``n_per_rev`` steps per revolution, default :data:`~orchestrator.stability.floquet.N_PER_REV`);
    the result then also has ``unbalance``, ``floquet`` and ``linear`` (the threshold without it).

    Ctrl-C or SIGTERM (in the main thread; :class:`orchestrator.coupling.lifecycle.StopRequests`)
    stops the search after the speed being computed (a second one at once), and an error at one
    speed (other than a :class:`StabilityError`: no static equilibrium, periodic orbit or
    eigenvalues there, which leaves a speed of the scan out, and a crossing whose Brent step raised
    it unrefined, as its bracket with ``not_refined``, the search going on) stops it at that speed:
    the result then holds what was done, ``complete`` False and ``stopped`` (why, where, and the
    ``--speeds``/``--scan`` of the rest; :mod:`orchestrator.stability.partial`), and nothing is
    computed after the stop.
    Before the first speed (the system and its films being set up) a signal stops at once: the
    :class:`orchestrator.coupling.lifecycle.RunStopped` (a KeyboardInterrupt) raised there leaves
    this function, as nothing was computed to keep. ``requests``: the caller's StopRequests, entered
    with ``at_once=True`` (``rotorcosim stability``'s, which sees the command from loading the
    scenario to its last line of output, so that no signal lands between two handlers); None:
    one of its own for the call."""
    if requests is None:
        from orchestrator.coupling.lifecycle import StopRequests
        with StopRequests(at_once=True) as own:
            return stability(scenario, film=film, speeds=speeds, n_scan=n_scan, ring_spin=ring_spin, loads=loads,
                             mc_solver=mc_solver, progress=progress, requests=own, unbalance=unbalance,
                             n_per_rev=n_per_rev)
    if film not in FILMS:
        raise StabilityError(f"--film must be one of {', '.join(FILMS)} (got {film!r})")
    system = build_system(scenario)
    lo, hi = speeds if speeds is not None else (0.1 * system.f_max, system.f_max)
    if speeds is None and not (0.0 < lo < hi and math.isfinite(hi)):
        raise StabilityError(f"the default speed range 0.1 f_max : f_max is {lo:g}:{hi:g} Hz, but the rotor "
                             f"'{system.rotor_instance}' has f_max = {system.f_max:g} Hz (no ramp to take the range "
                             "from); give the range: --speeds LO:HI in Hz, e.g. --speeds 50:800")
    if not (0.0 < lo < hi <= MAX_SPEED_HZ):
        raise StabilityError(f"--speeds: need 0 < LO < HI <= {MAX_SPEED_HZ:g} in Hz (got {lo:g}:{hi:g}); speeds "
                             "in Hz, e.g. --speeds 50:800")
    if system.rings and film == "mc" and ring_spin:
        raise StabilityError("--film mc --ring-spin: with the mass-conserving films the ring spin is held at its "
                             "steady value (the torque's sensitivity to the films' cavity states is not linearised); "
                             "use --film mc without --ring-spin, or --film hs --ring-spin for the half-Sommerfeld "
                             "films with the spin perturbation")
    if system.rings and film == "short":
        raise StabilityError("--film short: the short-bearing closed form has no floating ring; the floating-ring "
                             "bearings of this scenario are linearized with their half-Sommerfeld films (--film hs)")
    if unbalance and system.rings:
        raise StabilityError("--unbalance: the periodic orbit under the unbalance is computed for plain "
                             f"{BEARING_MODEL}s (--film hs or short), not for floating-ring bearings; leave "
                             "--unbalance out for this scenario's linear threshold")
    if unbalance and film == "mc":
        raise StabilityError("--unbalance --film mc: the periodic orbit under the unbalance needs each film's "
                             "nonlinear force at any journal motion, which the mass-conserving film has only with its "
                             "cavity's history (a run); --unbalance supports --film hs (each bearing's own "
                             "half-Sommerfeld film, also for a mass-conserving bearing's geometry) and --film short; "
                             "use --unbalance --film hs, or --film mc without --unbalance")
    if n_per_rev is not None and not unbalance:
        raise StabilityError("n_per_rev: steps per revolution of the periodic orbit, only with unbalance=True")
    if ring_spin and not system.rings:
        raise StabilityError("--ring-spin: the scenario has no floating-ring bearings (its stations carry "
                             f"{BEARING_MODEL}s); leave --ring-spin out")
    fixed = [b.instance for b in system.bearings if b.kind == "floating_ring" and not b.params.floating]
    if fixed:           # its outer film at rest: bearing_fmu.floating_ring_statics finds no equilibrium at any speed
        raise StabilityError(f"the ring of '{fixed[0]}' is semi-floating (floating = 0): its outer film does not "
                             "spin and carries no static load in the quasi-static (half-Sommerfeld) film, so "
                             "`stability` has no operating point to linearize at, at any speed; it takes floating "
                             "rings (floating = 1) only")
    if n_scan is None:
        n_scan = MC_SCAN if film == "mc" else 80
    with _progress_bar(n_scan, progress) as bar:
        return _threshold(scenario, system, film=film, lo=lo, hi=hi, n_scan=n_scan, ring_spin=ring_spin, loads=loads,
                          mc_solver=mc_solver, requests=requests, bar=bar, unbalance=unbalance, n_per_rev=n_per_rev)


@contextlib.contextmanager
def _progress_bar(n_scan: int, progress: bool | None):
    """A tqdm bar of the scan's speeds on stderr, as `rotorcosim run`'s (coupling/observers.py
    Progress): with ``progress`` None only when stderr is a terminal, and shown once the scan has
    lasted 2 s; None when off."""
    if progress is None:
        progress = bool(getattr(sys.stderr, "isatty", lambda: False)())
    if not progress:
        yield None
        return
    from tqdm import tqdm
    bar = tqdm(total=n_scan, unit="speed", desc="stability scan", file=sys.stderr, dynamic_ncols=True,
               mininterval=0.5, delay=2.0)
    try:
        yield bar
    finally:
        bar.close()


def _threshold(scenario, system: System, *, film: str, lo: float, hi: float, n_scan: int, ring_spin: bool,
               loads, mc_solver: str, requests, bar, unbalance: bool = False, n_per_rev: int | None = None) -> dict:
    """The search of :func:`stability` on its checked arguments (``requests``: the stop requests
    looked at before each speed; ``bar``: the progress bar or None)."""
    weight, extra, total = _static_loads(system, loads)
    fn = film_model(system, film, total, ring_spin=ring_spin, mc_solver=mc_solver)
    notes = _notes(system, film, ring_spin, weight, extra)
    seen: dict[float, tuple[float, float]] = {}
    fq = None
    if unbalance:
        from orchestrator.stability.floquet import N_PER_REV, FloquetFilms
        fq = FloquetFilms(system, film, fn, extra, n_per_rev=n_per_rev or N_PER_REV)
        if not fq.has_unbalance:
            notes.append(f"the rotor '{system.rotor_instance}' has no unbalance: its periodic orbit is the static "
                         "equilibrium and the Floquet growth rate the linear threshold's largest real part")
    model = fq if fq is not None else fn

    def recorded(fn):
        """fn(w) (the model's max_re, or its continuation) with every speed evaluated kept for
        result["scan"] and --plot, and a numeric failure of the rotor's own matrices (an absurd mass,
        a speed far off) named as eigenvalues not computed there."""
        def at(w):
            try:
                v = fn(w)
            except _NUMERIC as exc:
                raise EigenvaluesFailed(f"the eigenvalues of the rotor '{system.rotor_instance}' in its bearings "
                                        f"cannot be computed at {w / (2 * math.pi):.4g} Hz: "
                                        f"{exc or type(exc).__name__}; check the rotor's and the bearings' "
                                        "parameters, or give a --speeds LO:HI nearer the rotor's running speeds") \
                    from exc
            seen[float(w)] = v
            return v
        return at
    max_re = recorded(model.max_re)

    w_lo, w_hi = 2 * math.pi * lo, 2 * math.pi * hi
    result: dict[str, Any] = {
        "scenario": scenario.name, "file": str(scenario.source) if scenario.source else None,
        "rotor": {"instance": system.rotor_instance, "model": system.rotor_model},
        "film": film, "method": fn.method, "speed_range_hz": [lo, hi], "complete": True, "stopped": None,
        "threshold_hz": None, "whirl_hz": None, "whirl_ratio": None, "crossings": [], "crossings_bracketed": [],
        "bearings": {}, "notes": notes,
    }
    # from the first speed on a signal stops after the speed being computed (a second one abandons it)
    requests.phase("this speed")
    requests.abandon = False
    if fq is not None:                   # the linear threshold beside it (cheap), then the Floquet search
        from orchestrator.stability.floquet import linear_beside
        result["linear"] = linear_beside(fn, np.geomspace(w_lo, w_hi, n_scan), requests)
        t_search = time.perf_counter()
    continued = getattr(model, "max_re_continued", None)
    searched = _search(max_re, np.geomspace(w_lo, w_hi, n_scan), result,
                       xtol=(2 * math.pi * 0.01 if film == "mc" else 2 * math.pi * 1e-3 if fq is not None else 1e-9),
                       stop=requests, bar=bar, without="static equilibrium" if fq is None else
                       "synchronous periodic orbit (or static equilibrium)",
                       continued=None if continued is None else recorded(continued))
    at, stop = searched.at, searched.stop
    if film == "mc" and fn.dense_speeds:
        notes.append(f"at {len(fn.dense_speeds)} of the {len(seen)} speeds evaluated the argument-principle count "
                     "disagreed with the eigenvalues the Arnoldi runs found: there all were computed densely")
    result["scan"] = [{"speed_hz": w / (2 * math.pi), "max_re_per_s": re, "whirl_hz": im / (2 * math.pi),
                       "log_decrement": log_decrement(re, im)} for w, (re, im) in sorted(seen.items())]
    if fq is not None:
        from orchestrator.stability.floquet import floquet_entries
        floquet_entries(fq, result, seen, at if stop is None else None, time.perf_counter() - t_search)
    none = [None] * len(system.bearings)
    eps, points = none, none
    if at is not None and stop is None:         # nothing is computed after a stop
        try:
            if requests.requested:
                raise SpeedStopped(at)
            with requests.abandoning():        # a second signal abandons this computation only
                eps = fn.eccentricities(at)
                shares = fn.contact_share(at) if film == "hs" and not system.rings else ()
                points = fn.points(at) if system.rings else none
            for b, share in zip(system.bearings, shares):
                if share > 1e-3:
                    notes.append(f"bearing '{b.instance}': asperity contact carries {share:.1%} of its static "
                                 "load at the threshold (its coefficients are included, bearing_fmu/contact.py)")
        except (Exception, KeyboardInterrupt) as exc:     # a stop request, or an error there
            eps, points = none, none
            stop = stop_of(exc, requests.signum, at, "threshold")
            stop.done = stop.planned = n_scan
    if stop is not None:
        result.update(complete=False, stopped=stop.as_dict())
    for b, e, ld, pt in zip(system.bearings, eps, total, points):
        result["bearings"][b.instance] = _bearing_entry(b, film, ld, e, pt, at)
    return result


def _bearing_entry(b: Bearing, film: str, load, eps, point, at: float | None) -> dict:
    """A bearing's part of the result: its static ``load`` (2,) [N], eccentricity ratio ``eps``
    at the threshold speed ``at`` [rad/s] (None without one), and for a floating ring its steady
    operating ``point`` there (a FloatingRing model, or None)."""
    entry = {"station": b.station, "kind": b.kind, "load_n": float(np.hypot(*load)),
             "load_vector_n": [float(load[0]), float(load[1])], "eps_at_threshold": eps}
    if b.kind == "floating_ring":       # eps, clearance, cavitation, grid: of the inner film
        inner, outer = b.params.inner, b.params.outer
        entry.update(clearance_m=inner.psi * inner.R, cavitation=int(inner.cavitation),
                     grid=[int(inner.n_phi), int(inner.n_z)],
                     eps_outer_at_threshold=None if point is None else float(point.outputs["eps_outer"]),
                     ring_speed_ratio_at_threshold=None if point is None else float(point.outputs["omega_ring"] / at),
                     clearance_outer_m=outer.psi * outer.R, cavitation_outer=int(outer.cavitation),
                     grid_outer=[int(outer.n_phi), int(outer.n_z)], m_ring_kg=float(b.params.m_ring),
                     floating=int(b.params.floating))
    else:
        entry.update(clearance_m=b.params.psi * b.params.R, cavitation=int(b.params.cavitation),
                     grid=[int(b.params.n_phi), int(b.params.n_z)] if film in ("hs", "mc") else None)
    return entry
