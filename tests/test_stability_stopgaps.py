"""`rotorcosim stability` stopped where its stop handling had gaps (tests/test_stability_stop.py tests
the stops it already handled; the same deterministic timing: signals raised at a chosen call, or
sent from outside once the subprocess says it is there, never by wall-clock time).

* A signal before the first speed (loading the scenario, setting up the linear model): SIGTERM
  killed the command without a word (no handler yet), Ctrl-C ended in a bare "interrupted"; now
  one line says it stopped before any speed was computed, nothing to keep, exit 130/143, and no
  --json/--plot file is written.
* A second signal that landed between two handlers or outside a speed's computation (the stop's
  own handling, the bookkeeping after the scan, between the search and its output) ended in
  "interrupted" without the table of the speeds done (SIGTERM between the search and its output:
  killed without a word); now it is held there and the search stops as after the first, with its
  table, --json and the --speeds of the rest.
* A refinement stopped with later crossings not refined suggested the --speeds of the crossing it
  was refining only; now the rest covers all of them, and pasted back it finds them.
"""

from __future__ import annotations

import json
import math
import os
import signal

import numpy as np
import pytest

from hostile_builders import cli
from tests.test_stability_stop import (JEFFCOTT_HS, _Requests, _result, _signal_at, safety_net,  # noqa: F401
                                      signal_first, signalled_command)

posix_only = pytest.mark.skipif(os.name != "posix", reason="POSIX signals")
SIGNALS = pytest.mark.parametrize("signum", [signal.SIGINT, signal.SIGTERM], ids=["SIGINT", "SIGTERM"])


def _head(signum) -> str:
    return "interrupted" if signum == signal.SIGINT else "terminated by signal SIGTERM"


# ----------------------------------------------------------------------------- before the first speed
_WAIT_IN_LOAD = """
import os, sys, time
from pathlib import Path
import orchestrator.scenario as scenario
ready, go = Path(sys.argv[1]), Path(sys.argv[2])
load = scenario.load_scenario
def waiting(*a, **kw):              # loading the scenario: say so, and wait until the test has sent its signal
    ready.write_text("loading")
    deadline = time.monotonic() + 300
    while not go.exists() and time.monotonic() < deadline:
        time.sleep(0.01)
    return load(*a, **kw)
scenario.load_scenario = waiting
sys.argv = ["rotorcosim"] + sys.argv[3:]
from orchestrator.cli import console_main
console_main()
"""


@posix_only
@SIGNALS
def test_a_signal_while_the_scenario_is_loaded_says_nothing_was_computed(tmp_path, signum):
    """SIGTERM while the scenario was being loaded killed the command (exit -15, not a word);
    Ctrl-C ended in "interrupted" alone."""
    out, png, ready, go = tmp_path / "r.json", tmp_path / "r.png", tmp_path / "ready", tmp_path / "go"
    proc, text, err = signalled_command(tmp_path, [_WAIT_IN_LOAD, str(ready), str(go), "stability", str(JEFFCOTT_HS),
                                                   "--film", "short", "--speeds", "100:800", "--json", str(out),
                                                   "--plot", str(png)], ready, go, signum)
    assert proc.returncode == 128 + signum, (proc.returncode, err)
    lines = [line for line in err.splitlines() if line.strip()]
    assert lines == [f"{_head(signum)} while loading the scenario: stopped before any speed was computed, nothing to "
                     f"keep (--json {out} and --plot {png} not written)"], err
    assert text == ""
    assert sorted(p.name for p in tmp_path.iterdir()) == ["go", "ready"]        # no report, no figure, no temp file


@posix_only
@SIGNALS
@pytest.mark.usefixtures("safety_net")
def test_a_signal_while_the_linear_model_is_set_up_says_nothing_was_computed(tmp_path, capsys, monkeypatch, signum):
    """A signal in stability()'s setup (build_system, before the first speed) reached no handler of
    the command: SIGTERM killed it, Ctrl-C ended in "interrupted"."""
    import orchestrator.stability.search as search
    signal_first(monkeypatch, search, "build_system", signum)
    monkeypatch.setattr(search, "film_model", lambda *a, **kw: pytest.fail("set up after the signal"))
    before = {s: signal.getsignal(s) for s in (signal.SIGINT, signal.SIGTERM)}
    out, png = tmp_path / "r.json", tmp_path / "r.png"
    rc, text = cli(capsys, "stability", JEFFCOTT_HS, "--film", "short", "--json", out, "--plot", png)
    assert rc == 128 + signum, text
    assert text.strip() == (f"{_head(signum)} while setting up the linear model of the rotor in its bearings: stopped "
                            f"before any speed was computed, nothing to keep (--json {out} and --plot {png} not "
                            "written)"), text
    assert not out.exists() and not png.exists()
    assert {s: signal.getsignal(s) for s in before} == before


@posix_only
@pytest.mark.usefixtures("safety_net")
def test_stability_called_from_python_stops_at_once_before_the_first_speed(monkeypatch):
    """The Python API: a SIGTERM while stability() set up its system reached the caller's handler
    (by default: killed); now it raises RunStopped (a KeyboardInterrupt, exit code 143) out of
    stability(), and the caller's handlers are back."""
    import orchestrator.stability.search as search
    from orchestrator.coupling.lifecycle import RunStopped
    from tests.test_stability_stop import _scenario
    signal_first(monkeypatch, search, "build_system", signal.SIGTERM)
    before = {s: signal.getsignal(s) for s in (signal.SIGINT, signal.SIGTERM)}
    with pytest.raises(RunStopped) as exc:
        search.stability(_scenario(), film="short", speeds=(100.0, 800.0), n_scan=8)
    assert exc.value.exit_code == 143
    assert {s: signal.getsignal(s) for s in before} == before


# ----------------------------------------------------------------------------- a second signal in a gap
def _second_signal_in(monkeypatch, gap: str, signum) -> None:
    """Send ``signum`` once, from inside ``gap``: the stop's own handling (stop_of), the bookkeeping
    after the search (the table's log decrements), or between the search and its output."""
    import orchestrator.stability.partial as partial
    import orchestrator.stability.search as search
    module, name = {"stop": (search, "stop_of"), "bookkeeping": (search, "log_decrement"),
                    "before-output": (partial, "written_holding_signals")}[gap]
    signal_first(monkeypatch, module, name, signum, once=True)


@posix_only
@SIGNALS
@pytest.mark.parametrize("gap", ["stop", "bookkeeping", "before-output"])
@pytest.mark.usefixtures("safety_net")
def test_a_second_signal_between_the_speeds_stops_with_the_table_of_what_was_done(tmp_path, capsys, monkeypatch,
                                                                                 signum, gap):
    """The first signal during speed 10 of the scan, the second in a gap where no speed is being
    computed: it raised KeyboardInterrupt out of the search ("interrupted" or "terminated by
    signal SIGTERM" alone: no table, no --json, no --speeds of the rest), or, between the search
    and its output, reached no handler of the command (SIGTERM: killed without a word)."""
    calls = _signal_at(monkeypatch, 10, [signum])
    _second_signal_in(monkeypatch, gap, signum)
    out = tmp_path / "r.json"
    rc, text = cli(capsys, "stability", JEFFCOTT_HS, "--film", "short", "--speeds", "100:800", "--json", out)
    assert rc == 128 + signum and calls[0] == 10, text
    assert "speeds done: 10 of the scan's 80" in text, text
    r = json.loads(out.read_text())
    assert r["complete"] is False and r["stopped"]["speeds_done"] == 10 and len(r["scan"]) == 10
    assert r["stopped"]["by"] == signum.name
    assert f"{_head(signum)}: the scan stopped at" in text and "after 10 of its 80 speeds" in text, text
    assert f"for the rest of the range run the same command with {r['stopped']['rest']['args']}" in text, text


# ----------------------------------------------------------------------------- a refinement stopped: the rest
def _three_crossings(requests):
    """max_re crossing zero at 250 (up), 400 (down) and 600 Hz (up), counting its calls."""
    roots = 2 * math.pi * np.array([250.0, 400.0, 600.0])

    def max_re(w):
        requests.count()
        return float(np.prod((w - roots) / roots)), 0.45 * w
    return max_re


def test_a_refinement_stopped_before_later_crossings_gives_a_rest_that_finds_them_all():
    """Stopped while refining the first of three crossings, ``stopped.rest`` was that crossing's
    bracket (``--scan 2``): the two later ones, found by the scan and not refined, were not in it."""
    from orchestrator.stability.search import _search
    ws = np.geomspace(2 * math.pi * 100.0, 2 * math.pi * 800.0, 40)
    whole = _result()
    assert _search(_three_crossings(_Requests(None)), ws, whole).stop is None
    assert [c["becomes"] for c in whole["crossings"]] == ["unstable", "stable", "unstable"]
    req = _Requests(after=40 + 3)                               # the scan, then 3 of Brent's steps on the first
    result = _result()
    found = _search(_three_crossings(req), ws, result, stop=req)
    s = found.stop
    assert s.phase == "refine" and len(result["crossings_bracketed"]) == 3 and not result["crossings"]
    assert s.rest_crossings == 3 and s.as_dict()["rest"]["crossings"] == 3
    lo, hi, n = s.rest
    hz = ws / (2 * math.pi)
    k0, k1 = int(np.searchsorted(hz, 250.0)) - 1, int(np.searchsorted(hz, 600.0))
    assert n == k1 - k0 + 1 and np.allclose(np.geomspace(lo, hi, n), hz[k0:k1 + 1], rtol=1e-8)   # the scan's speeds
    # pasted back: the three crossings, as the whole search found them
    again = _result()
    assert _search(_three_crossings(_Requests(None)), 2 * math.pi * np.geomspace(lo, hi, n), again).stop is None
    assert [c["becomes"] for c in again["crossings"]] == ["unstable", "stable", "unstable"]
    assert [c["speed_hz"] for c in again["crossings"]] == pytest.approx([c["speed_hz"] for c in whole["crossings"]],
                                                                        abs=1e-6)


@posix_only
@pytest.mark.usefixtures("safety_net")
def test_the_command_stopped_while_refining_the_threshold_names_a_rest_with_the_later_crossing(tmp_path, capsys,
                                                                                             monkeypatch):
    """The paper rotor in short films becomes unstable at 262.14 Hz and stable again at 575.04 Hz;
    Ctrl-C while the first was refined suggested `--speeds` around the first only."""
    _signal_at(monkeypatch, 8 + 3, [signal.SIGINT])           # the scan's 8 speeds, then Brent's third step
    out = tmp_path / "r.json"
    rc, text = cli(capsys, "stability", JEFFCOTT_HS, "--film", "short", "--speeds", "100:800", "--scan", "8",
                   "--json", out)
    assert rc == 130, text
    r = json.loads(out.read_text())
    rest = r["stopped"]["rest"]
    assert r["stopped"]["phase"] == "refine" and len(r["crossings_bracketed"]) == 2 and rest["crossings"] == 2
    assert rest["speeds_hz"][0] < 262.14 and rest["speeds_hz"][1] > 575.04
    assert (f"for the crossing it was refining and the one after it (both not refined: the scan's speeds from the "
            f"first to the second) run the same command with {rest['args']}") in text, text
    monkeypatch.undo()                                           # pasted back, without the signal
    rc, text = cli(capsys, "stability", JEFFCOTT_HS, "--film", "short", *rest["args"].split())
    assert rc == 0, text
    assert "threshold speed: 262.14 Hz" in text and "then stable from 575.04 Hz on" in text, text
