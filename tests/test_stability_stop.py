"""`rotorcosim stability` stopped halfway keeps what it computed and says why it stopped.

Ctrl-C (SIGINT) or SIGTERM during the scan kept none of the speeds done: SIGINT ended the command
with "interrupted" (exit 130) and nothing else, SIGTERM killed it without a word (exit -15), and an
error at one speed (other than "no static equilibrium there") lost the whole scan. Now the scan
stops after the speed being computed (a second signal: at once), the command prints the table of
the speeds done, writes --json (``complete`` false, ``stopped``: by what, where, how much, and the
``--speeds``/``--scan`` of the rest) and --plot, says how to get the rest, and exits 130 / 143 / 1.
A refinement stopped halfway keeps its bracket as the answer, with its width.

The scans are made slow deterministically, never by time: the film's ``max_re`` is wrapped so that
it raises the signal itself at speed N (in this process), or, in a subprocess, announces speed N and
waits until the test has sent the signal (no wall-clock assertion anywhere).
"""

from __future__ import annotations

import json
import math
import os
import signal
import subprocess
import sys
import time
from pathlib import Path
from types import SimpleNamespace

import numpy as np
import pytest

REPO = Path(__file__).resolve().parents[1]
JEFFCOTT_HS = REPO / "scenarios" / "jeffcott_runup_half_sommerfeld.yaml"
SHORT_THRESHOLD_HZ = 262.14       # the paper rotor in short films (test_stability_cli.py: 262.14, stable again 575.04)

posix_only = pytest.mark.skipif(os.name != "posix", reason="POSIX signals")


# ----------------------------------------------------------------------------- the search alone
class _Requests:
    """A stop request raised by hand after ``after`` evaluations (what StopRequests sets on a signal)."""

    def __init__(self, after: int | None, signum=signal.SIGINT):
        self.after, self.calls, self.signum, self.requested = after, 0, None, False
        self._signum = signum

    def count(self):
        self.calls += 1
        if self.after is not None and self.calls >= self.after:
            self.requested, self.signum = True, self._signum


def _linear(requests, w_c=2 * math.pi * 300.0, fail_at=None):
    """max_re crossing zero upwards at w_c (and never again), counting its calls in ``requests``;
    a RuntimeError at call ``fail_at``."""
    def max_re(w):
        if fail_at is not None and requests.calls + 1 == fail_at:
            raise RuntimeError("ARPACK did not converge (made to fail here)")
        requests.count()
        return float(np.cbrt((w - w_c) / w_c)), 0.45 * w        # steep at w_c: Brent takes its steps
    return max_re


def _result():
    return {"speed_range_hz": [100.0, 800.0], "crossings": [], "crossings_bracketed": [], "notes": []}


def test_the_search_stopped_during_the_scan_keeps_the_speeds_done_and_names_the_rest():
    from orchestrator.stability.search import _search
    ws = np.geomspace(2 * math.pi * 100.0, 2 * math.pi * 800.0, 40)
    req = _Requests(after=12)
    result = _result()
    found = _search(_linear(req), ws, result, stop=req)
    assert found.at is None and found.stop is not None
    s = found.stop
    assert (s.by, s.phase, s.done, s.planned, s.exit_code) == ("SIGINT", "scan", 12, 40, 130)
    assert s.at_hz == pytest.approx(ws[12] / (2 * math.pi))        # the next speed, not computed
    lo, hi, n = s.rest                                              # from the last speed done: its grid again
    assert lo == pytest.approx(ws[11] / (2 * math.pi), abs=1e-3) and lo <= ws[11] / (2 * math.pi)
    assert hi == 800.0 and n == 40 - 12 + 1
    assert np.allclose(np.geomspace(lo, hi, n), ws[11:] / (2 * math.pi), rtol=1e-5)
    assert result["status"] == "incomplete" and not result["crossings"] and not result["crossings_bracketed"]


def test_a_crossing_in_the_speeds_done_is_kept_as_the_threshold_bracket_not_refined():
    from orchestrator.stability.search import _search
    ws = np.geomspace(2 * math.pi * 100.0, 2 * math.pi * 800.0, 40)
    req = _Requests(after=30, signum=signal.SIGTERM)           # 30 speeds: up to ~490 Hz, past 300 Hz
    result = _result()
    found = _search(_linear(req), ws, result, stop=req)
    assert req.calls == 30                                      # nothing computed after the stop (no Brent)
    assert found.stop.by == "SIGTERM" and found.stop.exit_code == 143 and found.at is None
    assert result["status"] == "threshold_bracketed" and "threshold_hz" not in result
    a, b = result["threshold_between_hz"]
    assert a < 300.0 < b and b / a == pytest.approx(8.0 ** (1 / 39))   # neighbouring speeds of the scan
    assert result["threshold_bracket_width_hz"] == pytest.approx(b - a)
    assert result["crossings_bracketed"] == [{"between_hz": [a, b], "width_hz": b - a, "becomes": "unstable"}]


def test_a_refinement_stopped_halfway_keeps_brents_bracket_with_its_width():
    from orchestrator.stability.search import _search
    ws = np.geomspace(2 * math.pi * 100.0, 2 * math.pi * 800.0, 40)
    whole = _result()
    assert _search(_linear(_Requests(None)), ws, whole).stop is None
    assert whole["status"] == "threshold" and whole["threshold_hz"] == pytest.approx(300.0)
    req = _Requests(after=40 + 6)                               # the scan, then 6 of Brent's evaluations
    result = _result()
    found = _search(_linear(req), ws, result, stop=req)
    assert req.calls == 46 and found.at is None
    assert found.stop.phase == "refine" and found.stop.done == found.stop.planned == 40
    assert result["status"] == "threshold_bracketed" and "threshold_hz" not in result and not result["crossings"]
    a, b = result["threshold_between_hz"]
    scan_a = max(w for w in ws / (2 * math.pi) if w < 300.0)
    assert a <= 300.0 <= b and b - a < 0.5 * (scan_a * 8.0 ** (1 / 39) - scan_a)   # narrower than the scan's
    lo, hi, n = found.stop.rest
    assert lo <= a and hi >= b and n == 2 and hi - lo < b - a + 2.1e-6


def test_an_error_at_one_speed_stops_the_scan_there():
    from orchestrator.stability.search import _search
    ws = np.geomspace(2 * math.pi * 100.0, 2 * math.pi * 800.0, 40)
    req = _Requests(None)
    result = _result()
    found = _search(_linear(req, fail_at=8), ws, result, stop=req)
    s = found.stop
    assert (s.by, s.phase, s.done, s.exit_code) == ("error", "scan", 7, 1)
    assert s.at_hz == pytest.approx(ws[7] / (2 * math.pi))
    assert s.reason == "RuntimeError: ARPACK did not converge (made to fail here)"
    assert result["status"] == "incomplete"
    # the rest starts at the last speed done, so it computes the failing one again: the message says so
    from orchestrator.stability.partial import stop_message
    result["stopped"] = s.as_dict()
    text = stop_message(result)
    assert text.startswith(f"error: the scan stopped at {s.at_hz:.4g} Hz after 7 of its 40 speeds: RuntimeError")
    assert f"{s.rest_args} (in place of its --speeds and --scan) once the cause is mended: it computes " \
           f"{s.at_hz:.4g} Hz again" in text, text


# ----------------------------------------------------------------------------- stability() in this process
def _scenario():
    from orchestrator.scenario import load_scenario
    return load_scenario(str(JEFFCOTT_HS), [], build_fmus=True)


class _Unhandled(Exception):
    pass


@pytest.fixture
def safety_net():
    """Handlers of SIGINT and SIGTERM that fail the test (not the test run: a SIGTERM or SIGINT the
    code under test did not take would end pytest) while it signals itself; the previous ones after."""
    def fail(signum, frame):
        raise _Unhandled(f"{signal.Signals(signum).name} reached the test's own handler")
    previous = {s: signal.signal(s, fail) for s in (signal.SIGINT, signal.SIGTERM)}
    yield
    for s, h in previous.items():
        signal.signal(s, h)


def _signal_at(monkeypatch, n: int, signums):
    """The short film's max_re raises ``signums`` (one after the other) at its n-th speed."""
    import orchestrator.stability as st
    max_re = st._ShortFilm.max_re
    calls = [0]

    def wrapped(self, w):
        calls[0] += 1
        if calls[0] == n:
            for s in signums:
                os.kill(os.getpid(), s)
                time.sleep(0)            # the handler runs here, before the next signal is sent
        return max_re(self, w)
    monkeypatch.setattr(st._ShortFilm, "max_re", wrapped)
    return calls


@posix_only
@pytest.mark.parametrize("signum", [signal.SIGINT, signal.SIGTERM], ids=["SIGINT", "SIGTERM"])
def test_a_signal_stops_the_scan_after_the_speed_being_computed(monkeypatch, signum, safety_net):
    from orchestrator.stability import stability
    scenario = _scenario()
    before = {s: signal.getsignal(s) for s in (signal.SIGINT, signal.SIGTERM)}
    calls = _signal_at(monkeypatch, 10, [signum])
    r = stability(scenario, film="short", speeds=(100.0, 800.0), n_scan=80)
    assert {s: signal.getsignal(s) for s in before} == before          # the handlers are back
    assert calls[0] == 10 and len(r["scan"]) == 10                      # that speed finished, none after it
    assert r["complete"] is False and r["status"] == "incomplete"
    st = r["stopped"]
    assert st["by"] == signum.name and st["phase"] == "scan" and st["speeds_done"] == 10
    assert st["exit_code"] == 128 + signum
    assert st["rest"]["scan"] == 71 and st["rest"]["speeds_hz"][1] == 800.0
    assert st["rest"]["args"].startswith("--speeds ") and st["rest"]["args"].endswith(":800 --scan 71")
    assert all(b["eps_at_threshold"] is None for b in r["bearings"].values())
    json.dumps(r)                                                        # JSON-ready


@posix_only
def test_a_second_signal_abandons_the_speed_being_computed(monkeypatch, safety_net):
    from orchestrator.stability import stability
    calls = _signal_at(monkeypatch, 10, [signal.SIGINT, signal.SIGINT])
    r = stability(_scenario(), film="short", speeds=(100.0, 800.0), n_scan=80)
    assert calls[0] == 10 and len(r["scan"]) == 9 and r["stopped"]["speeds_done"] == 9
    assert r["stopped"]["at_speed_hz"] == pytest.approx(100.0 * 8.0 ** (9 / 79))


# ----------------------------------------------------------------------------- the command, signalled from outside
_WAITING = """
import os, sys, time
from pathlib import Path
import orchestrator.stability.films as films
ready, go, n = Path(sys.argv[1]), Path(sys.argv[2]), int(sys.argv[3])
max_re, calls = films._ShortFilm.max_re, [0]
def wrapped(self, w):               # at speed n: say so, and wait until the test has sent its signal
    calls[0] += 1
    if calls[0] == n:
        ready.write_text("at speed %d" % n)
        deadline = time.monotonic() + 300
        while not go.exists() and time.monotonic() < deadline:
            time.sleep(0.01)
    return max_re(self, w)
films._ShortFilm.max_re = wrapped
sys.argv = ["rotorcosim"] + sys.argv[4:]
from orchestrator.cli import console_main
console_main()
"""


def signal_first(monkeypatch, module, name: str, signum, *, once: bool = False) -> None:
    """``module.name`` replaced by a function that sends this process ``signum`` (handled before
    it goes on), then calls the real one; ``once``: only on its first call."""
    real, sent = getattr(module, name), [False]

    def signalled(*a, **kw):
        if not (once and sent[0]):
            sent[0] = True
            os.kill(os.getpid(), signum)
            time.sleep(0)
        return real(*a, **kw)
    monkeypatch.setattr(module, name, signalled)


def signalled_command(cwd, script_args: list, ready: Path, go: Path, signum):
    """(process, stdout, stderr) of ``python -c script_args[0] script_args[1:]`` (the command with
    a waiting hook, in its own session) sent ``signum`` once it has written ``ready``, then let go
    on by writing ``go``; killed if it outlives the test."""
    env = dict(os.environ, PYTHONPATH=str(REPO) + os.pathsep + os.environ.get("PYTHONPATH", ""))
    proc = subprocess.Popen([sys.executable, "-c", *script_args], stdout=subprocess.PIPE, stderr=subprocess.PIPE,
                            text=True, env=env, cwd=cwd, start_new_session=True)
    try:
        deadline = time.monotonic() + 300
        while not ready.exists() and proc.poll() is None and time.monotonic() < deadline:
            time.sleep(0.01)
        assert ready.exists(), proc.communicate(timeout=60)
        os.kill(proc.pid, signum)             # delivered while the command waits for "go"
        go.write_text("")
        text, err = proc.communicate(timeout=300)
    finally:
        if proc.poll() is None:
            os.killpg(proc.pid, signal.SIGKILL)
            proc.wait()
    return proc, text, err


@posix_only
@pytest.mark.parametrize("signum, code", [(signal.SIGINT, 130), (signal.SIGTERM, 143)], ids=["SIGINT", "SIGTERM"])
def test_the_command_signalled_after_n_speeds_prints_and_writes_what_it_did(tmp_path, signum, code):
    out, png, ready, go = tmp_path / "r.json", tmp_path / "r.png", tmp_path / "ready", tmp_path / "go"
    n = 12
    proc, text, err = signalled_command(tmp_path, [_WAITING, str(ready), str(go), str(n), "stability", str(JEFFCOTT_HS),
                                                   "--film", "short", "--speeds", "100:800", "--json", str(out),
                                                   "--plot", str(png)], ready, go, signum)
    assert proc.returncode == code, err
    assert "Traceback" not in err and "Traceback" not in text, err
    assert f"speeds done: {n} of the scan's 80" in text
    table = text.split(f"speeds done: {n} of the scan's 80")[1].splitlines()[2:2 + n]
    assert [float(row.split()[0]) for row in table] == pytest.approx(list(np.geomspace(100.0, 800.0, 80)[:n]),
                                                                   abs=1e-4)
    r = json.loads(out.read_text())
    assert r["complete"] is False and r["status"] == "incomplete"
    assert r["stopped"]["by"] == signum.name and r["stopped"]["speeds_done"] == n and len(r["scan"]) == n
    assert r["stopped"]["at_speed_hz"] == pytest.approx(100.0 * 8.0 ** (n / 79))
    assert png.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
    head = "interrupted" if signum == signal.SIGINT else "terminated by signal SIGTERM"
    assert f"{head}: the scan stopped at" in err and f"after {n} of its 80 speeds" in err
    assert r["stopped"]["rest"]["args"] in err and r["stopped"]["rest"]["args"].endswith(f":800 --scan {80 - n + 1}")
    assert str(out) in err and str(png) in err


def test_the_message_of_a_stopped_refinement_names_the_bracket_and_how_to_refine_it():
    from orchestrator.stability.partial import Stop, scan_table, stop_message
    stop = Stop("SIGINT", "refine", 262.1446, "interrupted (Ctrl-C)", done=80, planned=80,
                rest=(262.144607, 262.144608, 2))
    r = {"status": "threshold_bracketed", "threshold_between_hz": [262.14460735, 262.14460745],
         "threshold_bracket_width_hz": 1e-7, "speed_range_hz": [80.0, 800.0], "stopped": stop.as_dict(),
         "crossings_bracketed": [{"between_hz": [262.14460735, 262.14460745], "width_hz": 1e-7,
                                  "becomes": "unstable"}],
         "scan": [{"speed_hz": 262.14460735, "max_re_per_s": -1e-6, "log_decrement": 5e-8, "whirl_hz": 117.5}]}
    text = stop_message(r, kept=["r.json"])
    assert text.startswith("interrupted: stopped at 262.1 Hz while refining a crossing")
    assert "between 262.14460735 and 262.14460745 Hz (1e-07 Hz wide, not refined)" in text
    assert "--speeds 262.144607:262.144608 --scan 2" in text and "r.json" in text
    assert "262.1446" in scan_table(r)
    assert SimpleNamespace(**stop.as_dict()).exit_code == 130
