"""The paper's run-up as the paper ran it (issue 16): scenarios/jeffcott_runup_*_from_rest.yaml
start at t = 0 / 0 Hz with the journals at rest on the shell, carried by the asperity contact;
and the quickstart starts below its film's threshold so that its onset is measured.

Results of the full runs: docs/runups.md ("From rest").
"""

from __future__ import annotations

import math
from dataclasses import replace
from pathlib import Path

import numpy as np
import pytest

pytestmark = pytest.mark.integration

SCENARIOS = Path(__file__).resolve().parents[1] / "scenarios"
MODELS = ("half_sommerfeld", "free_to_air", "oil_bath")


@pytest.fixture(scope="module")
def pairs():
    from orchestrator import load_scenario
    return {m: (load_scenario(SCENARIOS / f"jeffcott_runup_{m}_from_rest.yaml"),
                load_scenario(SCENARIOS / f"jeffcott_runup_{m}.yaml")) for m in MODELS}


@pytest.mark.parametrize("model", MODELS)
def test_from_rest_is_the_shipped_runup_started_at_rest(pairs, model):
    rest, shipped = pairs[model]
    assert rest.name == f"jeffcott_runup_{model}_from_rest"
    assert (rest.start_time, rest.stop_time) == (0.0, shipped.stop_time)
    r_rot, s_rot = rest.fmu("rotor").parameters, shipped.fmu("rotor").parameters
    assert r_rot["journal_x0"] == 0.0
    assert {k: v for k, v in r_rot.items() if not k.startswith("journal_")} == \
        {k: v for k, v in s_rot.items() if not k.startswith("journal_")}
    for b in ("bearing1", "bearing2"):
        r_b, s_b = dict(rest.fmu(b).parameters), shipped.fmu(b).parameters
        assert r_b.pop("contact") == 1
        assert r_b == s_b
    assert [(c.src, c.dst, c.gain, c.offset) for c in rest.connections] == \
        [(c.src, c.dst, c.gain, c.offset) for c in shipped.connections]
    assert rest.coupling.macro_step == shipped.coupling.macro_step


@pytest.mark.parametrize("model", MODELS)
def test_from_rest_journals_rest_where_the_contact_carries_the_weight(pairs, model):
    """journal_y0 is where the Greenwood-Tripp force of each bearing carries half the
    rotor weight (6 kg, g = 9.81): the start is at rest, not a drop onto the shell."""
    from bearing_fmu.contact import normal_force
    rest, _ = pairs[model]
    rot, brg = rest.fmu("rotor").parameters, rest.fmu("bearing1").parameters
    c = brg["psi"] * brg["R"]
    e = -rot["journal_y0"]
    load = 0.5 * 9.81 * (rot["m_disc"] + 2 * rot["m_journal"])
    fn = normal_force(e, c=c, R=brg["R"], B=brg["B"], sigma=0.3e-6, KE=2.0e7)
    assert fn == pytest.approx(load, rel=0.01)
    assert 0.98 < e / c < 1.0


@pytest.mark.slow
@pytest.mark.parametrize("model", ["half_sommerfeld", "free_to_air"])
def test_from_rest_start_lifts_off(pairs, model, tmp_path):
    """The first 45 ms: the contact carries the journals at t = 0, the film takes the load over
    as the speed rises (contact force below 60 % by 25 ms, below 0.1 % by 45 ms: lifted off at ~14-16 Hz),
    and the journal is carried by the film alone, at its weight share.

    The contact phase is checked by these milestones, not by the force at one early instant: with
    the mass-conserving film and the shipped 0.1 ms macro step the force during contact has spikes
    (up to ~90x the load in the first 10 ms: docs/runups.md, "From rest", "The contact phase"),
    and the contact force at 6 ms depends on the solver's details (0.96 x its start on main
    e5d5eed, 0.83 x before dad0350, which this test's first version pinned as < 0.95 x). These
    milestones hold for the free-to-air film at macro steps of 0.1 ms and 10 us and with the
    error-controlled step alike (contact force below 15 N from 25 ms, lifted off between 32 and
    40 ms; the smallest eps over 40-50 ms 0.8529 / 0.8531 / 0.8531)."""
    from orchestrator import run
    rest, _ = pairs[model]
    sc = replace(rest, stop_time=45e-3)
    res = run(sc, out_dir=tmp_path, progress=False)
    assert res.success, res.message
    fc = np.asarray(res.outputs["bearing1.F_contact"])
    fy = np.asarray(res.outputs["bearing1.Fy"])
    eps = np.asarray(res.outputs["bearing1.eps"])
    t = np.linspace(0.0, sc.stop_time, len(fc))
    assert fc[0] == pytest.approx(29.43, rel=0.02)
    assert np.all(fc[t >= 25e-3] < 0.6 * fc[0])      # the film carries most of it by ~10 Hz
    assert fc[-1] < 1e-3 * fc[0]                     # lifted off (0.8 mN HS, 8 uN free to air left)
    assert fy[-1] == pytest.approx(29.43, rel=0.02)  # the film alone carries the weight share
    assert np.all(np.isfinite(fy)) and np.all(eps < 1.0 + 1e-6)
    assert eps[-1] < 0.95 < eps[0]


@pytest.mark.slow
def test_quickstart_onset_is_measured(tmp_path):
    """The quickstart starts below its threshold (~225 Hz, 200 Hz at start): the onset it
    prints is a measured crossing, after the start and above the growth-rate threshold,
    with no warnings."""
    import json
    from orchestrator import load_scenario, run
    sc = load_scenario(SCENARIOS / "quickstart.yaml")
    res = run(sc, out_dir=tmp_path, progress=False)
    assert res.success, res.message
    a = json.loads((tmp_path / "summary.json").read_text())["analysis"]
    j = a["journals"]["bearing1"]
    assert j["whirl"] and not j["onset"]["present_at_start"]
    assert not j["warnings"]
    assert j["threshold_speed_hz"] < j["onset_speed_hz"] < 280.0
    assert 200.0 < j["threshold_speed_hz"] < 240.0          # linear stability: ~225 Hz
    assert math.isfinite(j["max_eps"]) and j["max_eps"] > 0.3


def test_contact_phase_does_not_oscillate_on_held_coefficients(pairs, tmp_path):
    """The free-to-air run from rest, its error-controlled contact phase (0-60 ms, rtol 0.05).
    With the film coefficients held while the journal moved less than 1 % of c (before 988bf48), a
    journal on its shell (gap 0.015 c) moved 2/3 of its gap on stale coefficients, the
    interface-Jacobian step oscillated (bearing force alternating by +-10-20 N about the 29 N load
    from one 2-3 us step to the next) and the phase took 1 417-3 292 steps with 252-342 rejected
    (five runs at rtol 0.05 +- 1e-6). With the hold in units of the gap c (1 - eps) the same five runs
    took 866-966 steps with 76-108 rejected (docs/runups.md, "The contact phase"). The bounds lie
    between; the count is path-dependent, so a count near a bound is not by itself a failure of the
    fix: compare the runs of that section."""
    import json
    from orchestrator import run
    rest, _ = pairs["free_to_air"]
    sc = replace(rest, stop_time=0.06)
    res = run(sc, out_dir=tmp_path, progress=False)
    assert res.success, res.message
    ctl = json.loads((tmp_path / "summary.json").read_text())["step_control"]
    assert ctl["accepted_steps"] < 1200, ctl
    assert ctl["rejected_steps"] < 200, ctl
