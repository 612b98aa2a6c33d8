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
