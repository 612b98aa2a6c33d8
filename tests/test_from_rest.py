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
    """The first 6 ms: the contact carries the journals at t = 0 and the film starts to
    take the load over as the speed rises (contact force falls, the film's grows)."""
    from orchestrator import run
    rest, _ = pairs[model]
    sc = replace(rest, stop_time=6e-3)
    res = run(sc, out_dir=tmp_path, progress=False)
    assert res.success, res.message
    fc = np.asarray(res.outputs["bearing1.F_contact"])
    fy = np.asarray(res.outputs["bearing1.Fy"])
    eps = np.asarray(res.outputs["bearing1.eps"])
    assert fc[0] == pytest.approx(29.43, rel=0.02)
    assert fc[-1] < 0.95 * fc[0]                    # the film carries part of it now
    assert np.all(np.isfinite(fy)) and np.all(eps < 1.0 + 1e-6)
    assert eps[-1] < eps[0]


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
