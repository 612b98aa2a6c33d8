"""A threshold search that ended before its end (``rotorcosim stability`` stopped by Ctrl-C,
SIGTERM, or an error at one speed): why and where it stopped (:class:`Stop`, the result's
``stopped``), and the words the command says about it (:func:`scan_table`, :func:`stop_message`).

The project's rule: a computation that fails or is stopped halfway keeps everything it computed
and says why it stopped. The search (:func:`orchestrator.stability.search._search`) checks the
stop request (:class:`orchestrator.coupling.lifecycle.StopRequests`) before each speed it
evaluates, in the scan over the range and in Brent's refinement of a crossing: the first Ctrl-C
or SIGTERM lets the speed being computed finish and stops before the next one, a second one
abandons that speed at once; an error at one speed other than "no static equilibrium there"
(a StabilityError, which leaves a speed of the scan out, and leaves a crossing at whose Brent step
it was raised unrefined, as its bracket with ``not_refined``, the search going on: no stop) stops
it there. Nothing is computed after a stop: a
sign change between two speeds done is kept as its bracket (``crossings_bracketed``; the
threshold's is ``threshold_between_hz`` with its width, status ``threshold_bracketed``), and
``stopped.rest`` is the ``--speeds LO:HI --scan N`` that computes what is left.
"""

from __future__ import annotations

import logging
import math
import signal
import sys
from dataclasses import dataclass
from typing import Callable

from orchestrator.errors import CosimError

log = logging.getLogger(__name__)

#: exit status of a stopped search by its cause (as `rotorcosim run` and `sweep`: 128 + the signal)
EXIT_CODES = {"SIGINT": 130, "SIGTERM": 143}


class SpeedStopped(Exception):
    """Raised in place of evaluating a speed once a stop was requested (from the search's own
    code, so that Brent's refinement, which calls back into it, ends there too)."""

    def __init__(self, omega: float):
        super().__init__(f"stop requested before {omega / (2 * math.pi):.4g} Hz")
        self.omega = omega


@dataclass
class Stop:
    """Why and where a threshold search stopped before its end (the result's ``stopped``,
    :meth:`as_dict`)."""

    by: str                         # "SIGINT", "SIGTERM" (a stop signal) or "error" (an error at one speed)
    phase: str                      # "scan" (the grid over the range), "continuation" (the speeds it left
    #                                 out, from their neighbours), "refine" (Brent on a crossing's bracket)
    #                                 or "threshold" (the bearings' eccentricities at the threshold)
    at_hz: float | None             # the speed being computed (an error, a second signal) or next (a first signal)
    reason: str                     # what stopped it, in words
    done: int = 0                   # speeds of the scan evaluated (speeds without equilibrium included)
    planned: int = 0                # speeds of the scan
    rest: tuple[float, float, int] | None = None    # (LO, HI [Hz], N): --speeds LO:HI --scan N gives what is left
    rest_crossings: int | None = None   # a stopped refinement: the crossings not refined that the rest refines

    @property
    def exit_code(self) -> int:
        return EXIT_CODES.get(self.by, 1)

    @property
    def rest_args(self) -> str | None:
        if self.rest is None:
            return None
        lo, hi, n = self.rest
        return f"--speeds {lo:.10g}:{hi:.10g} --scan {n}"

    def as_dict(self) -> dict:
        return {"by": self.by, "phase": self.phase, "at_speed_hz": self.at_hz, "reason": self.reason,
                "speeds_done": self.done, "speeds_planned": self.planned, "exit_code": self.exit_code,
                "rest": None if self.rest is None else {"speeds_hz": [self.rest[0], self.rest[1]],
                                                        "scan": self.rest[2], "args": self.rest_args,
                                                        "crossings": self.rest_crossings}}


def stop_of(exc: BaseException, signum: int | None, omega: float | None, phase: str) -> Stop:
    """The :class:`Stop` of ``exc`` raised while computing speed ``omega`` [rad/s] in ``phase``:
    a stop request (:class:`SpeedStopped`, or the second signal's KeyboardInterrupt) is named by
    ``signum`` (the first signal), anything else is an error at that speed (its traceback logged
    at debug level: ``--debug`` shows it)."""
    at = None if omega is None else float(omega) / (2 * math.pi)
    if isinstance(exc, (SpeedStopped, KeyboardInterrupt)):
        name = signal.Signals(signum or getattr(exc, "signum", None) or signal.SIGINT).name
        return Stop(name, phase, at, "interrupted (Ctrl-C)" if name == "SIGINT" else f"terminated by signal {name}")
    log.debug("the stability search stopped at %s Hz (%s)", at, phase, exc_info=exc)
    text = str(exc) if isinstance(exc, CosimError) else f"{type(exc).__name__}: {exc}"
    return Stop("error", phase, at, text)


def widened(a_hz: float, b_hz: float) -> tuple[float, float]:
    """A bracket [a, b] [Hz] rounded outwards to 1e-6 Hz (so that it prints exactly as ``--speeds``)."""
    return math.floor(a_hz * 1e6) / 1e6 or a_hz, math.ceil(b_hz * 1e6) / 1e6


def bracket(evals: dict[float, float], w0: float, w1: float) -> tuple[float, float]:
    """The narrowest sign change of the largest real part among the speeds evaluated in [w0, w1]
    [rad/s] (``evals``: speed -> largest real part; the scan's ends and Brent's steps): the first
    one upwards in speed, [w0, w1] itself when no step between them was evaluated."""
    pts = sorted((w, v) for w, v in evals.items() if w0 <= w <= w1)
    for (wa, va), (wb, vb) in zip(pts, pts[1:]):
        if (va < 0.0) != (vb < 0.0):
            return wa, wb
    return w0, w1


def _pair(a: float, b: float, sep: str = " and ") -> str:
    """'a and b' with the digits that tell them apart (a bracket Brent narrowed to 1e-7 Hz)."""
    digits = 6 if b <= a or a <= 0.0 else min(15, max(6, math.ceil(math.log10(b / (b - a))) + 2))
    return f"{a:.{digits}g}{sep}{b:.{digits}g}"


def speed_range(lo: float, hi: float, sep: str = " - ") -> str:
    """The speed range [Hz] as the command prints it, with the digits that tell its ends apart: the
    ``--speeds 262.144607:262.144608`` a stopped refinement gives read "262.145 - 262.145 Hz"."""
    return _pair(lo, hi, sep)


def scan_table(result: dict) -> str:
    """The speeds a stopped search evaluated, one line each: largest real part, logarithmic
    decrement and frequency of the least-damped mode (``result["scan"]``), and the speeds without
    a static equilibrium or without eigenvalues."""
    rows = [(s["speed_hz"], f"{s['max_re_per_s']:14.6g} "
             + (f"{s['log_decrement']:14.5g}" if s["log_decrement"] is not None else f"{'-':>14}")
             + f" {s['whirl_hz']:11.3f}") for s in result.get("scan") or []]
    lacks = "no periodic orbit" if result.get("unbalance") else "no static equilibrium"     # --unbalance: Floquet rate
    rows += [(f, f"{'':1}{lacks}") for f in result.get("speeds_without_equilibrium_hz") or []]
    rows += [(f, f"{'':1}eigenvalues not computed") for f in result.get("speeds_without_eigenvalues_hz") or []]
    stop = result.get("stopped") or {}
    done, planned = stop.get("speeds_done"), stop.get("speeds_planned")
    head = (f"speeds done: {done} of the scan's {planned}" if stop.get("phase") == "scan" else
            f"speeds done: the scan's {planned}") + (" and Brent's steps" if len(rows) > (done or 0) else "")
    lines = [f"{head} (the least-damped mode at each):",
             f"{'speed [Hz]':>12} {'max Re [1/s]':>14} {'log decrement':>14} {'whirl [Hz]':>11}"]
    lines += [f"{f:12.4f} {text}" for f, text in sorted(rows)]
    return "\n".join(lines)


def stop_message(result: dict, *, kept: list[str] | tuple = ()) -> str:
    """What the command says on stderr about a stopped search (``result["stopped"]``): why and
    where it stopped, what it found in what was done, where that is (``kept``: the files written),
    and the ``--speeds LO:HI --scan N`` that gives the rest."""
    s = result["stopped"]
    head = {"SIGINT": "interrupted", "SIGTERM": "terminated by signal SIGTERM"}.get(s["by"], "error")
    at = "" if s["at_speed_hz"] is None else f" at {s['at_speed_hz']:.4g} Hz"
    why = f": {s['reason']}" if s["by"] == "error" else ""
    if s["phase"] == "scan":
        parts = [f"{head}: the scan stopped{at} after {s['speeds_done']} of its {s['speeds_planned']} speeds{why}"]
    elif s["phase"] == "refine":
        parts = [f"{head}: stopped{at} while refining a crossing, after the scan of all {s['speeds_planned']} "
                 f"speeds{why}"]
    elif s["phase"] == "continuation":
        parts = [f"{head}: stopped{at} while computing the speeds the scan left out by continuation from their "
                 f"neighbours, after the scan of all {s['speeds_planned']} speeds{why}"]
    else:
        parts = [f"{head}: the threshold is located, but the bearings' static eccentricities there were not "
                 f"computed{why}"]
    parts.append("the speeds done are kept: the table above" + "".join(f", {k}" for k in kept))
    status = result.get("status")
    if status == "threshold":
        parts.append(f"the threshold is {result['threshold_hz']:.2f} Hz (whirl {result['whirl_hz']:.2f} Hz)")
    elif status == "threshold_bracketed":
        a, b = result["threshold_between_hz"]
        lo, hi = widened(a, b)
        how = f"; `--speeds {lo:.10g}:{hi:.10g} --scan 2` refines it" if s["phase"] == "scan" else ""
        first = (result.get("crossings_bracketed") or [{}])[0]
        how = f": {first['not_refined']}" if first.get("not_refined") else how      # Brent gave up on it
        width = result["threshold_bracket_width_hz"]
        parts.append(f"the threshold lies between {_pair(a, b)} Hz ({width:.3g} Hz wide, not refined{how})")
    elif status == "unstable_at_lower_bound":
        parts.append(f"already unstable at the lower end of the range ({result['speed_range_hz'][0]:g} Hz): the "
                     "threshold is below it")
    elif status == "threshold_not_located":
        a, b = result["threshold_between_hz"]
        parts.append(f"it becomes unstable between {a:.4g} and {b:.4g} Hz, across speeds " +
                     ("left out (no static equilibrium, or eigenvalues not computed: see the notes)"
                      if result.get("speeds_without_eigenvalues_hz") else "without a static equilibrium"))
    elif status == "incomplete" and result.get("scan"):
        parts.append(f"no eigenvalue crosses into the right half plane up to {result['scan'][-1]['speed_hz']:.4g} Hz")
    for c in (result.get("crossings_bracketed") or [])[1 if status == "threshold_bracketed" else 0:]:
        why = f": {c['not_refined']}" if c.get("not_refined") else ""
        parts.append(f"then {c['becomes']} from between {_pair(*c['between_hz'])} Hz (not refined{why})")
    if s["rest"] is not None:
        n = s["rest"].get("crossings") or 1
        what = ("the rest of the range" if s["phase"] == "scan" else "the range (the continuation starts from the "
                "scan's speeds)" if s["phase"] == "continuation" else "the crossing it was refining" if n == 1 else
                f"the crossing it was refining and the {n - 1} after it (all {n} not refined: the scan's speeds "
                "from the first to the last)" if n > 2 else
                "the crossing it was refining and the one after it (both not refined: the scan's speeds from the "
                "first to the second)")
        again = (f" once the cause is mended: it computes {s['at_speed_hz']:.4g} Hz again, which fails the same way "
                 "until then" if s["by"] == "error" and s["at_speed_hz"] is not None else "")
        parts.append(f"for {what} run the same command with {s['rest']['args']} (in place of its --speeds and "
                     f"--scan){again}")
    return "; ".join(parts)


def written_holding_signals(write: Callable[[], int], result: dict, requests=None) -> int:
    """``write()`` (the command's output of ``result``: the table, --json, --plot, the stop
    message; returns the exit code) with Ctrl-C and SIGTERM held until it is done. After the
    search the handlers of :class:`orchestrator.coupling.lifecycle.StopRequests` were gone, so a
    second Ctrl-C pressed quickly (the first one stopped the scan) landed while the figure was
    drawn: no figure, no stop message, no ``--speeds`` of the rest, only "interrupted"; a second
    SIGTERM killed the process without a word. Now a signal there lets the output finish (the
    next one stops at once), and the exit code is the signal's (130, 143).

    ``requests``: the command's StopRequests, already entered (the search's: a signal between
    the search and its output is held by it, and counts here), which this puts into its writing
    phase; None: one of its own around ``write()``."""
    if requests is None:
        from orchestrator.coupling.lifecycle import StopRequests
        with StopRequests() as own:
            return written_holding_signals(write, result, own)
    requests.phase("writing what was computed")
    code = write()
    if requests.requested and not result.get("stopped"):
        name = signal.Signals(requests.signum).name
        print(f"{'interrupted' if name == 'SIGINT' else f'terminated by signal {name}'} while the result was "
              "written: the result above is complete", file=sys.stderr)
        return EXIT_CODES.get(name, 128 + int(requests.signum))
    return code
