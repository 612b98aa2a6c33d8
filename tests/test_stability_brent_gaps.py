"""A speed inside a crossing's bracket that fails at one of Brent's steps (no static equilibrium or
periodic orbit there, a floating ring's operating point that fails from the warm start, eigenvalues
not computed: a StabilityError) leaves that crossing unrefined, kept as its bracket, and the search
goes on with the later crossings (orchestrator/stability/search.py ``_search``). Before, it stopped
the whole search there ("stopped by an error", every later crossing unrefined, a rest command).
A ``continued`` function (the film model's ``max_re_continued``, --film mc floating rings) tries
that speed once more first; an error other than StabilityError (a bug, a stop request) still stops
the search (tests/test_stability_stop.py).

Plain functions for the search (as tests/test_stability_left_out.py), and the command on the paper
rotor in short films with its film's max_re (with --unbalance: its periodic orbit) made to fail inside
the threshold's bracket.
"""

from __future__ import annotations

import json
import math

import numpy as np
import pytest

from hostile_builders import cli
from orchestrator.stability.search import _search
from orchestrator.stability.system import StabilityError
from tests.test_stability_stop import JEFFCOTT_HS, SHORT_THRESHOLD_HZ

ROOTS_HZ = (250.0, 400.0)                   # unstable from 250 Hz, stable again from 400 Hz
WS = 2 * math.pi * np.geomspace(100.0, 800.0, 20)
NEAR_HZ = 0.5                               # the speeds within this of 250 Hz fail (Brent's last steps)


def _result():
    return {"speed_range_hz": [100.0, 800.0], "crossings": [], "crossings_bracketed": [], "notes": []}


def _value(w):
    r = 2 * math.pi * np.array(ROOTS_HZ)
    return float(np.cbrt(-np.prod((w - r) / r))), 0.45 * w         # steep at the roots: Brent takes steps


def _failing_near(root_hz, exc=StabilityError, calls=None):
    """max_re of the two crossings, raising ``exc`` at the speeds within NEAR_HZ of ``root_hz``
    (none of them a scan speed); each call's speed [Hz] appended to ``calls``."""
    def max_re(w):
        if calls is not None:
            calls.append(w / (2 * math.pi))
        if abs(w / (2 * math.pi) - root_hz) < NEAR_HZ:
            raise exc(f"no static equilibrium of 'b' at {w / (2 * math.pi):.6g} Hz (made to fail here); raise the "
                      "lower end of --speeds")
        return _value(w)
    return max_re


def _cell(root_hz):
    hz = WS / (2 * math.pi)
    k1 = int(np.searchsorted(hz, root_hz))
    return hz[k1 - 1], hz[k1]


def test_a_failed_brent_step_keeps_the_crossing_as_its_bracket_and_the_search_goes_on():
    calls: list = []
    result = _result()
    found = _search(_failing_near(250.0, calls=calls), WS, result)
    assert found.stop is None and found.at is None
    assert result["status"] == "threshold_bracketed" and "threshold_hz" not in result
    a, b = result["threshold_between_hz"]
    lo, hi = _cell(250.0)
    assert lo <= a < 250.0 < b <= hi and (a, b) != (lo, hi)        # narrowed by Brent's steps before the failure
    assert result["threshold_bracket_width_hz"] == pytest.approx(b - a)
    [c] = result["crossings_bracketed"]
    failed = [f for f in calls if abs(f - 250.0) < NEAR_HZ]
    assert len(failed) == 1                                        # tried once (no continuation), then given up
    assert c["between_hz"] == [a, b] and c["becomes"] == "unstable" and c["failed_at_hz"] == pytest.approx(failed[0])
    assert c["not_refined"].startswith(f"Brent's step at {failed[0]:.6g} Hz failed: no static equilibrium of 'b'")
    assert "raise the lower end of --speeds" not in c["not_refined"]     # not the fix inside a bracket
    # the later crossing is refined as without the failure
    [later] = result["crossings"]
    assert later["becomes"] == "stable" and later["speed_hz"] == pytest.approx(400.0, rel=1e-9)
    note = next(n for n in result["notes"] if n.startswith("the crossing between"))
    assert note.startswith(f"the crossing between {lo:.4g} and {hi:.4g} Hz (it becomes unstable) is not refined: "
                           f"{c['not_refined']}"), note
    # the later crossing failing instead: the threshold is refined, the later one kept as a bracket
    result = _result()
    found = _search(_failing_near(400.0), WS, result)
    assert found.stop is None and result["status"] == "threshold"
    assert result["threshold_hz"] == pytest.approx(250.0, rel=1e-9)
    [c] = result["crossings_bracketed"]
    assert c["becomes"] == "stable" and c["between_hz"][0] < 400.0 < c["between_hz"][1] and "not_refined" in c


def test_the_continuation_tries_a_failed_brent_step_once_more():
    """With ``continued`` (--film mc floating rings: max_re_continued) a step that failed is computed
    again by it; where that succeeds Brent goes on, where it fails too the crossing is a bracket with
    the continuation's reason."""
    again: list = []

    def continued(w):
        again.append(w / (2 * math.pi))
        return _value(w)
    result = _result()
    found = _search(_failing_near(250.0), WS, result, continued=continued)
    assert found.stop is None and result["status"] == "threshold"
    assert result["threshold_hz"] == pytest.approx(250.0, rel=1e-9)
    assert again and all(abs(f - 250.0) < NEAR_HZ for f in again)      # only the steps that failed
    assert not result["crossings_bracketed"] and [c["becomes"] for c in result["crossings"]] == ["unstable", "stable"]

    def continued_fails(w):
        again.append(w / (2 * math.pi))
        raise StabilityError(f"no operating point at {w / (2 * math.pi):.6g} Hz (continuation failed)")
    again.clear()
    result = _result()
    found = _search(_failing_near(250.0), WS, result, continued=continued_fails)
    assert found.stop is None and result["status"] == "threshold_bracketed" and len(again) == 1
    [c] = result["crossings_bracketed"]
    assert c["not_refined"] == (f"Brent's step at {again[0]:.6g} Hz failed (also by continuation from the speeds "
                                f"done): no operating point at {again[0]:.6g} Hz (continuation failed)")
    assert [x["speed_hz"] for x in result["crossings"]] == pytest.approx([400.0], rel=1e-9)


def test_an_error_other_than_stability_error_in_brent_still_stops_the_search():
    """A RuntimeError at a Brent step of the second crossing stops there (phase refine, exit 1, the
    rest that crossing's bracket), after the first crossing was kept as a bracket for its failure:
    the rest does not include it (pasted back it would fail the same way)."""
    from orchestrator.stability.partial import stop_message

    def max_re(w):
        f = w / (2 * math.pi)
        if abs(f - 250.0) < NEAR_HZ:
            raise StabilityError(f"no static equilibrium at {f:.6g} Hz")
        if abs(f - 400.0) < NEAR_HZ:
            raise RuntimeError("ARPACK did not converge (made to fail here)")
        return _value(w)
    result = _result()
    found = _search(max_re, WS, result)
    s = found.stop
    assert s is not None and (s.by, s.phase, s.exit_code) == ("error", "refine", 1)
    assert abs(s.at_hz - 400.0) < NEAR_HZ and s.reason == "RuntimeError: ARPACK did not converge (made to fail here)"
    first, second = result["crossings_bracketed"]
    assert "not_refined" in first and "not_refined" not in second        # stopped there, not given up
    assert result["status"] == "threshold_bracketed" and result["threshold_between_hz"] == first["between_hz"]
    assert s.rest_crossings == 1
    lo, hi, n = s.rest
    assert n == 2 and lo <= second["between_hz"][0] and hi >= second["between_hz"][1] and lo > 300.0
    result["stopped"] = s.as_dict()
    text = stop_message(result)
    assert "not refined: Brent's step at" in text and "for the crossing it was refining run" in text, text


def _short_failing_inside_the_threshold_bracket(monkeypatch, scan_hz):
    """The short film's max_re raising a StabilityError at every speed from 255 to 270 Hz that is
    not one of the scan's (Brent's steps on the threshold's bracket, 262.14 Hz)."""
    import orchestrator.stability as st
    real = st._ShortFilm.max_re

    def max_re(self, w):
        f = w / (2 * math.pi)
        if 255.0 < f < 270.0 and not np.isclose(scan_hz, f, rtol=1e-12, atol=0.0).any():
            raise StabilityError(f"the short-bearing film has no static equilibrium at {f:.6g} Hz (made to fail "
                                 "here)")
        return real(self, w)
    monkeypatch.setattr(st._ShortFilm, "max_re", max_re)


def test_the_command_names_the_unrefined_threshold_bracket_why_and_the_fix(capsys, monkeypatch, tmp_path):
    from orchestrator.stability.partial import speed_range
    scan_hz = np.geomspace(100.0, 800.0, 8)
    _short_failing_inside_the_threshold_bracket(monkeypatch, scan_hz)
    out, png = tmp_path / "r.json", tmp_path / "r.png"
    rc, text = cli(capsys, "stability", JEFFCOTT_HS, "--film", "short", "--speeds", "100:800", "--scan", "8",
                   "--json", out, "--plot", png)
    assert rc == 1, text
    r = json.loads(out.read_text())
    assert r["complete"] is True and r["stopped"] is None and r["status"] == "threshold_bracketed"
    a, b = r["threshold_between_hz"]
    assert a < SHORT_THRESHOLD_HZ < b and [c["becomes"] for c in r["crossings"]] == ["stable"]
    why = r["crossings_bracketed"][0]["not_refined"]
    assert why.startswith("Brent's step at ") and "made to fail here" in why
    assert "stopped by an error" not in text and "while refining" not in text
    between = speed_range(a, b, " and ")
    assert f"threshold speed: not refined, between {between} Hz" in text, text
    assert "then stable from 575.04 Hz on" in text, text
    err = text.split("error: ", 1)[1]
    assert err.startswith(f"the system becomes unstable between {between} Hz, but that crossing is not "
                          f"refined: {why}"), err
    lo, hi = math.floor(a * 1e6) / 1e6, math.ceil(b * 1e6) / 1e6
    assert f"--speeds {lo:.10g}:{hi:.10g} --scan 8" in err, err
    assert png.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"


def test_the_command_with_unbalance_names_the_unrefined_threshold_bracket(capsys, monkeypatch, tmp_path):
    """--unbalance: no periodic orbit at a step of Brent's (NoPeriodicOrbit) inside the threshold's
    bracket (the paper rotor in short films with its unbalance: 261.95 Hz)."""
    from orchestrator.stability import floquet
    scan_hz = np.geomspace(250.0, 275.0, 3)
    real = floquet.FloquetFilms.max_re

    def max_re(self, w):
        f = w / (2 * math.pi)
        if 255.0 < f < 270.0 and not np.isclose(scan_hz, f, rtol=1e-12, atol=0.0).any():
            self.failures[float(w)] = "made to fail here"
            raise floquet.NoPeriodicOrbit(f"no synchronous periodic orbit at {f:.6g} Hz: made to fail here")
        return real(self, w)
    monkeypatch.setattr(floquet.FloquetFilms, "max_re", max_re)
    out = tmp_path / "r.json"
    rc, text = cli(capsys, "stability", JEFFCOTT_HS, "--film", "short", "--unbalance", "--speeds", "250:275",
                   "--scan", "3", "--json", out)
    assert rc == 1, text
    r = json.loads(out.read_text())
    assert r["stopped"] is None and r["status"] == "threshold_bracketed" and r["complete"] is True
    a, b = r["threshold_between_hz"]
    assert a < 261.95 < b
    assert "threshold speed with the unbalance: not refined, between" in text, text
    assert "linear threshold (static equilibrium, no unbalance): 262.14 Hz" in text, text
    assert "error: the system with its unbalance becomes unstable between" in text, text
    assert "no synchronous periodic orbit at" in text.split("error: ", 1)[1] and "--scan 8" in text, text
