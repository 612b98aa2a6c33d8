"""coupling.parallel: threads (orchestrator/coupling/threads.py): the members of a stage
loaded into the master step at the same time, each in a thread, with the same results.

The pool itself: jobs really run at the same time (a barrier only two concurrent jobs
pass), failures come back in order after every job has finished. End to end: the shipped free-to-air Jeffcott run-up on a coarse film
grid (a few macro steps), sequential against threads: results.csv byte for byte, and the
bearing stage counted as stepped in threads.
"""

from __future__ import annotations

import threading
from pathlib import Path

import pytest

from orchestrator.coupling.threads import StageThreads, in_worker_thread

ROOT = Path(__file__).resolve().parents[1]


def test_jobs_run_at_the_same_time_and_failures_come_back_in_order():
    pool = StageThreads(2)
    barrier = threading.Barrier(3, timeout=30)      # passed only if all three wait together
    where = {}

    def job(k, fail=None):
        def f():
            where[k] = in_worker_thread()
            barrier.wait()
            if fail:
                raise fail
        return f

    boom = ValueError("second member failed")
    errors = pool.run([job(0), job(1, boom), job(2)])
    assert errors == [None, boom, None]
    assert where == {0: False, 1: True, 2: True}       # the first member in the caller's thread
    stop = KeyboardInterrupt()
    errors = pool.run([job(0, stop), job(1), job(2)])   # Ctrl-C in the caller's own member
    assert errors[0] is stop and errors[1:] == [None, None]
    assert pool.runs == 2
    pool.close()


def test_hand_offs_that_outlast_the_watch_go_to_sleep_and_still_arrive():
    """A job longer than the watch (handoff.SPIN_TURNS, ~2 ms) puts the master to sleep, a gap
    between stages longer than it puts the stage thread to sleep: both are woken by the other
    side, every job runs once, and close() ends the threads."""
    import time
    pool = StageThreads(1)
    ran = []

    def slow():
        time.sleep(0.05)
        ran.append("slow")

    assert pool.run([lambda: ran.append("first"), slow]) == [None, None]
    time.sleep(0.05)                                   # the stage thread falls asleep
    w = pool._workers[0]
    assert w.asleep
    boom = RuntimeError("late failure")

    def fails():
        raise boom
    assert pool.run([lambda: ran.append("again"), fails]) == [None, boom]
    assert ran == ["first", "slow", "again"] and pool.runs == 2
    pool.close()
    assert not w.thread.is_alive()


def test_more_stage_threads_than_cores_sleep_instead_of_watching(monkeypatch):
    import orchestrator.coupling.threads as threads
    monkeypatch.setattr(threads, "usable_cores", lambda: 2)
    wide, narrow = StageThreads(2), StageThreads(1)
    try:
        assert wide.turns == 0 and narrow.turns == threads.SPIN_TURNS
        ran = []
        jobs = [lambda k=k: ran.append(k) for k in range(3)]
        assert wide.run(jobs) == [None, None, None] and sorted(ran) == [0, 1, 2]
    finally:
        wide.close()
        narrow.close()


def _scenario(tmp_path, parallel, name="jeffcott_runup_free_to_air", stop=0.2504):
    from orchestrator import load_scenario

    sets = [f"stop_time={stop}", f"coupling.parallel={parallel}"]
    for b in ("bearing1", "bearing2"):
        sets += [f"fmus.{b}.parameters.n_phi=16", f"fmus.{b}.parameters.n_z=8"]
    return load_scenario(ROOT / "scenarios" / f"{name}.yaml", sets)


@pytest.mark.integration
def test_two_film_bearings_step_in_threads_with_the_same_results(tmp_path):
    from orchestrator import run
    from orchestrator.coupling.execution import MasterAlgorithm

    out = {}
    for parallel in ("true", "threads"):
        d = tmp_path / parallel
        res = run(_scenario(tmp_path, parallel), out_dir=d, progress=False)
        assert res.success, res.message
        out[parallel] = ((d / "results.csv").read_bytes(), res.stats)
    assert out["threads"][0] == out["true"][0]
    assert "threaded_stage_steps" not in out["true"][1]
    # 4 macro steps, each with the stage [bearing1, bearing2] stepped in threads
    assert out["threads"][1]["threaded_stage_steps"] == out["threads"][1]["macro_steps"] == 4
    import json
    summary = json.loads((tmp_path / "threads" / "summary.json").read_text())
    assert summary["threaded_stage_steps"] == 4
    m = MasterAlgorithm(_scenario(tmp_path, "threads"), out_dir=tmp_path / "plan")
    m.setup()
    try:
        flags = {tuple(u.name for u in members): threaded for _, members, _, threaded in m.stepper.stages}
        assert flags == {("rotor",): False, ("bearing1", "bearing2"): True}
    finally:
        m.terminate()


@pytest.mark.integration
def test_the_run_from_rest_with_contact_and_retries_is_the_same_in_threads(tmp_path):
    """From rest on the shell (asperity contact on, coupling.discard_retries: 4, so the
    master saves the FMU states every macro step): the shipped configuration, 30 steps."""
    from orchestrator import run

    got = {}
    for parallel in ("false", "threads"):
        d = tmp_path / parallel
        res = run(_scenario(tmp_path, parallel, "jeffcott_runup_free_to_air_from_rest", 0.003),
                  out_dir=d, progress=False)
        assert res.success, res.message
        got[parallel] = ((d / "results.csv").read_bytes(), res.stats["retried_steps"],
                         res.stats["rejected_steps"])
    assert got["threads"] == got["false"]
    assert len(got["false"][0]) > 3000


# --------------------------------------------------------------------------- hand-off mode
def _drive(chooser, cost, steps, first=0):
    """Tick ``chooser`` over the stage steps ``first`` ... ``first + steps - 1``, whose cost
    ``cost(k, watching)`` depends on the mode the chooser gave (the clock goes on from the last
    call on the same chooser); returns the modes."""
    t = getattr(chooser, "_test_clock", 0.0)
    modes = []
    for k in range(first, first + steps):
        m = chooser.tick(t)
        modes.append(m)
        t += cost(k, m)
    chooser._test_clock = t
    return modes


def test_hand_offs_sleep_when_watching_costs_more():
    """With every core busy, watching makes a step cost 2.5x (measured: another busy process
    beside the oil-bath run-up on 2 cores, BENCHMARKS.md session 18): the chooser sleeps,
    except in the probe windows that check it again."""
    from orchestrator.coupling.threads import HandoffChooser
    c = HandoffChooser(window=8, min_hold=2, max_hold=16)
    modes = _drive(c, lambda k, w: 2.5 if w else 1.0, 4000)
    assert not any(c.choices) and len(c.choices) >= 5
    assert sum(modes[1000:]) / 3000 < 0.15          # probes only


def test_hand_offs_watch_on_a_quiet_machine_and_follow_a_change_of_load():
    """Quiet: watching is the cheaper (sleeping costs the wake-ups), so it is kept. When
    another process starts at step 2000, the next windows cost more than the held one before,
    a probe follows at once and the chooser sleeps from then on."""
    from orchestrator.coupling.threads import HandoffChooser
    c = HandoffChooser(window=8, min_hold=2, max_hold=64)

    def cost(k, watching):
        if k < 2000:
            return 1.0 if watching else 1.1
        return 2.5 if watching else 1.2
    modes = _drive(c, cost, 2000)
    assert sum(modes[200:]) / 1800 > 0.85 and c.choices[-1]
    n = len(c.choices)
    modes += _drive(c, cost, 40, first=2000)         # 5 windows after the change
    assert c.choices[n:] and not c.choices[-1]
    modes += _drive(c, cost, 1960, first=2040)
    assert sum(modes[2100:]) / 1900 < 0.15


def test_the_probe_alternates_its_order_and_the_hold_grows_while_the_choice_stays():
    from orchestrator.coupling.threads import HandoffChooser
    c = HandoffChooser(window=4, min_hold=2, max_hold=8)
    modes = _drive(c, lambda k, w: 1.0 if w else 1.1, 400)
    windows = [modes[i] for i in range(0, 400, 4)]
    assert windows[:2] == [True, False]             # first probe: watching, then sleeping
    assert c.hold == 8 and all(c.choices)
    # the second probe starts with sleeping: windows 2, 3 hold, then the probe (False, True)
    assert windows[2:4] == [True, True] and windows[4:6] == [False, True]


def test_pool_switches_the_stage_threads_mode_and_jobs_still_run(monkeypatch):
    """The pool applies the chooser's mode to its stage threads between stage steps; jobs run
    once each in either mode, and the counts say how many steps watched."""
    import orchestrator.coupling.threads as threads
    monkeypatch.setattr(threads, "usable_cores", lambda: 4)
    pool = StageThreads(1, handoff="auto")
    pool._chooser = threads.HandoffChooser(window=3, min_hold=1, max_hold=1)
    try:
        ran = []
        seen = []
        for k in range(30):
            assert pool.run([lambda k=k: ran.append(k), lambda k=k: ran.append(-k - 1)]) == [None, None]
            seen.append((pool.turns, pool._workers[0].turns))
        assert sorted(ran) == sorted([k for k in range(30)] + [-k - 1 for k in range(30)])
        assert {t for t, _ in seen} == {0, threads.SPIN_TURNS}       # both modes were used
        assert all(t == w for t, w in seen)                          # the thread follows the pool
        assert pool.runs == 30 and 0 < pool.watched < 30
        assert pool.watched == sum(t > 0 for t, _ in seen)
    finally:
        pool.close()


def test_fixed_hand_off_modes_and_a_bad_setting(monkeypatch):
    import orchestrator.coupling.threads as threads
    monkeypatch.setattr(threads, "usable_cores", lambda: 4)
    for mode, turns in (("watch", threads.SPIN_TURNS), ("sleep", 0)):
        monkeypatch.setenv("ROTORCOSIM_STAGE_HANDOFF", mode)
        pool = StageThreads(1)
        try:
            for _ in range(300):
                pool.run([lambda: None, lambda: None])
            assert pool.turns == turns and pool._chooser is None
            assert pool.watched == (300 if turns else 0)
        finally:
            pool.close()
    monkeypatch.setenv("ROTORCOSIM_STAGE_HANDOFF", "spin")
    with pytest.raises(ValueError, match="ROTORCOSIM_STAGE_HANDOFF must be one of .*'auto'.*got 'spin'"):
        StageThreads(1)
