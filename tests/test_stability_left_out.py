"""The stability search's bookkeeping with plain functions (no films): Brent takes the scan's
answers instead of computing them again, and speeds left out because their eigenvalues could not be
computed are named apart from speeds without a static equilibrium (orchestrator/stability/search.py)."""
from __future__ import annotations

import collections
import json
import math

import numpy as np
import pytest

from orchestrator.stability.search import _search
from orchestrator.stability.system import EigenvaluesFailed, StabilityError
from rotor_fmu.stability import first_crossing, refine_crossing

W_CROSS = 2 * math.pi * 300.0           # the fake system becomes unstable here [rad/s]


def _counting(calls: collections.Counter, left_out: dict | None = None):
    """max_re of a system unstable above 300 Hz, counting its calls per speed; ``left_out``: speed
    index -> the exception it raises (indices into the search's speeds)."""
    def max_re(w):
        calls[float(w)] += 1
        exc = (left_out or {}).get(float(w))
        if exc is not None:
            raise exc
        return (w - W_CROSS) * 1e-3, 0.45 * w
    return max_re


def test_brent_computes_no_speed_twice_and_takes_the_known_ends():
    calls: collections.Counter = collections.Counter()
    f = _counting(calls)
    w0, w1 = 2 * math.pi * 250.0, 2 * math.pi * 350.0
    wc, nu = refine_crossing(f, w0, w1, known={w0: f(w0), w1: f(w1)})
    assert wc == pytest.approx(W_CROSS, rel=1e-11) and nu == pytest.approx(0.45 * wc)
    assert calls[w0] == 1 and calls[w1] == 1          # the two calls above, none by Brent
    assert max(calls.values()) == 1                    # and no speed computed twice (its root's |Im| included)
    calls.clear()
    assert first_crossing(f, np.geomspace(2 * math.pi * 100, 2 * math.pi * 800, 9))[0] == pytest.approx(W_CROSS)
    assert max(calls.values()) == 1


def test_the_search_takes_the_scans_answer_at_the_lower_end_of_a_bracket():
    """The lower end's answer comes from the scan; the upper end is computed again (it puts a film's
    warm start next to the crossing), Brent's own speeds once each."""
    ws = 2 * math.pi * np.geomspace(100.0, 800.0, 9)
    calls: collections.Counter = collections.Counter()
    result = {"speed_range_hz": [100.0, 800.0], "crossings": [], "crossings_bracketed": [], "notes": []}
    _search(_counting(calls), ws, result)
    assert result["status"] == "threshold" and result["threshold_hz"] == pytest.approx(300.0, rel=1e-9)
    k1 = int(np.searchsorted(ws, W_CROSS))
    assert calls[float(ws[k1 - 1])] == 1 and calls[float(ws[k1])] == 2
    assert all(n == 1 for w, n in calls.items() if w not in (float(ws[k1 - 1]), float(ws[k1])))


def test_speeds_without_eigenvalues_are_named_apart_from_speeds_without_equilibrium():
    ws = 2 * math.pi * np.geomspace(100.0, 800.0, 20)
    k1 = int(np.searchsorted(ws, W_CROSS))
    left_out = {float(ws[0]): StabilityError("no static equilibrium of 'b' at 100 Hz (an overload)"),
                float(ws[k1 - 1]): EigenvaluesFailed(f"at {ws[k1 - 1] / (2 * math.pi):.4g} Hz the count disagreed"),
                float(ws[k1]): EigenvaluesFailed("the count disagreed again")}
    result = {"speed_range_hz": [100.0, 800.0], "crossings": [], "crossings_bracketed": [], "notes": []}
    _search(_counting(collections.Counter(), left_out), ws, result)
    assert result["speeds_without_equilibrium_hz"] == pytest.approx([100.0])
    assert result["speeds_without_eigenvalues_hz"] == pytest.approx(ws[[k1 - 1, k1]] / (2 * math.pi))
    assert any(n.startswith("no static equilibrium at 1 of the 20 speeds searched (100 Hz), left out: no static "
                            "equilibrium of 'b'") for n in result["notes"])
    assert any(n.startswith("eigenvalues not computed at 2 of the 20 speeds searched") and "count disagreed" in n
               for n in result["notes"])
    # the sign change lies across the two speeds without eigenvalues: not located, and said so
    assert result["status"] == "threshold_not_located"
    assert any("across speeds whose eigenvalues were not computed: that crossing is not located" in n
               for n in result["notes"])


def _short_without_eigenvalues(monkeypatch, lo_hz, hi_hz):
    """The short film's max_re raising EigenvaluesFailed at every speed in (lo_hz, hi_hz)."""
    import orchestrator.stability as st
    real = st._ShortFilm.max_re

    def max_re(self, w):
        f = w / (2 * math.pi)
        if lo_hz < f < hi_hz:
            raise EigenvaluesFailed(f"at {f:.4g} Hz the count disagreed (made to fail here)")
        return real(self, w)
    monkeypatch.setattr(st._ShortFilm, "max_re", max_re)


def test_the_command_names_a_crossing_across_speeds_without_eigenvalues(capsys, monkeypatch, tmp_path):
    """The paper rotor in short films (threshold 262.14 Hz) with no eigenvalues from 230 to 300 Hz:
    the threshold is not located, and the message says the speeds were left out, not that they have
    no static equilibrium."""
    from hostile_builders import cli
    from tests.test_stability_stop import JEFFCOTT_HS
    _short_without_eigenvalues(monkeypatch, 230.0, 300.0)
    out = tmp_path / "r.json"
    rc, text = cli(capsys, "stability", JEFFCOTT_HS, "--film", "short", "--speeds", "100:800", "--scan", "30",
                   "--json", out)
    assert rc == 1, text
    r = json.loads(out.read_text())
    assert r["status"] == "threshold_not_located" and "speeds_without_equilibrium_hz" not in r
    assert all(230.0 < f < 300.0 for f in r["speeds_without_eigenvalues_hz"]) and r["speeds_without_eigenvalues_hz"]
    err = text.split("error: ", 1)[1]
    assert "across speeds left out (where a film has no static equilibrium, or whose eigenvalues were not " \
           "computed" in err, err
    assert "note: eigenvalues not computed at" in text, text


def test_the_command_names_the_lowest_speed_computed_when_eigenvalues_failed_below(capsys, monkeypatch, tmp_path):
    """No eigenvalues below 265 Hz, and the system already unstable at the first speed computed above
    (the short-film threshold is 262.14 Hz): the command names that speed as the lowest computed, not
    as the lowest with a static equilibrium."""
    from hostile_builders import cli
    from tests.test_stability_stop import JEFFCOTT_HS
    _short_without_eigenvalues(monkeypatch, 0.0, 265.0)
    rc, text = cli(capsys, "stability", JEFFCOTT_HS, "--film", "short", "--speeds", "240:400", "--scan", "8")
    assert rc == 1, text
    assert "error: already unstable at the lowest speed computed (" in text, text
    assert "lowest speed with a static equilibrium" not in text, text
