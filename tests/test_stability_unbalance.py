"""`rotorcosim stability --unbalance`: the threshold of the rotor WITH its unbalance, the Floquet
growth rate along its synchronous periodic orbit (orchestrator/stability/floquet.py; docs/analysis.md
"Stability with the unbalance (Floquet)").

Independent checks: without unbalance the orbit is the static equilibrium and the Floquet threshold
must be the linear eigenvalue threshold (a different computation: a product of matrix exponentials
over a revolution, not eigenvalues); the turbocharger's threshold with its unbalance against the one
docs/runups.md section 4 found with docs/scripts/turbocharger_unbalance_floquet.py along a run's
orbit (53.38-53.39 Hz) and the growth rate of its constant-speed run at 57 Hz (+4.0 1/s).
Small scans, coarse ranges: 5-15 s in all (warm numba cache)."""

from __future__ import annotations

import json
import math
from pathlib import Path

import pytest

from hostile_builders import run_verb

from orchestrator import load_scenario
from orchestrator.stability import StabilityError, stability

REPO = Path(__file__).resolve().parents[1]
JEFFCOTT_HS = REPO / "scenarios" / "jeffcott_runup_half_sommerfeld.yaml"
TURBO_HS = REPO / "scenarios" / "turbocharger_runup_half_sommerfeld.yaml"
NO_UNBALANCE = "fmus.rotor.parameters.unbalance=0"
LINEAR_KEYS = {"scenario", "file", "rotor", "film", "method", "speed_range_hz", "complete", "stopped",
               "threshold_hz", "whirl_hz", "whirl_ratio", "crossings", "crossings_bracketed", "bearings", "notes",
               "status", "scan"}


@pytest.mark.parametrize("film, speeds", [("hs", (250.0, 262.0)), ("short", (255.0, 270.0))])
def test_without_unbalance_the_floquet_threshold_is_the_linear_one(film, speeds):
    scenario = load_scenario(JEFFCOTT_HS, [NO_UNBALANCE])
    r = stability(scenario, film=film, speeds=speeds, n_scan=2, unbalance=True, progress=False)
    lin = stability(scenario, film=film, speeds=speeds, n_scan=2, progress=False)
    assert r["status"] == lin["status"] == "threshold"
    assert r["threshold_hz"] == pytest.approx(lin["threshold_hz"], abs=2e-3)        # Brent to 1e-3 Hz
    assert r["linear"]["threshold_hz"] == lin["threshold_hz"]
    assert r["whirl_ratio"] == pytest.approx(lin["whirl_ratio"], abs=1e-4)
    for a, b in zip(r["scan"][:1] + r["scan"][-1:], lin["scan"][:1] + lin["scan"][-1:]):   # the scan's two ends
        assert a["speed_hz"] == b["speed_hz"]
        assert a["max_re_per_s"] == pytest.approx(b["max_re_per_s"], abs=1e-6 * abs(b["max_re_per_s"]) + 1e-6)
    orbit = r["floquet"]["orbit_at_threshold"]["bearing1"]
    assert orbit["amplitude_x_c"] < 1e-9 and orbit["amplitude_y_c"] < 1e-9
    assert any("has no unbalance" in n for n in r["notes"])


def test_turbocharger_threshold_with_its_unbalance(capsys, tmp_path):
    # measured 2026-12-07: 53.21 Hz (the run's orbit, docs/runups.md: 53.38-53.39 Hz), mu -1.0000,
    # compressor-side orbit 0.0099 x 0.0120 c; linear 56.59 Hz
    out = tmp_path / "r.json"
    png = tmp_path / "r.png"
    code, text, err = run_verb(capsys, "stability", TURBO_HS, "--unbalance", "--speeds", "52:57", "--scan", "3",
                               "--json", out, "--plot", png)
    assert code == 0, err
    assert png.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
    r = json.loads(out.read_text())
    assert r["unbalance"] is True and LINEAR_KEYS <= set(r)
    assert 53.0 < r["threshold_hz"] < 53.45
    assert r["whirl_ratio"] == pytest.approx(0.5, abs=1e-6)
    mu = r["floquet"]["threshold_multiplier"]
    assert mu[1] == 0.0 and mu[0] == pytest.approx(-1.0, abs=1e-3)
    assert "parametric resonance" in r["floquet"]["multiplier_kind"]
    b1 = r["floquet"]["orbit_at_threshold"]["bearing1"]
    assert 0.008 < b1["amplitude_x_c"] < 0.012 and 0.010 < b1["amplitude_y_c"] < 0.014
    assert r["linear"]["threshold_hz"] == pytest.approx(56.594, abs=0.01)
    assert r["floquet"]["below_linear_hz"] == pytest.approx(r["linear"]["threshold_hz"] - r["threshold_hz"])
    assert r["floquet"]["speeds_without_orbit"] == [] and r["floquet"]["seconds_per_speed"] > 0
    assert all("floquet_multiplier" in s and set(s["orbit_amplitude_c"]) == {"bearing1", "bearing2"}
               for s in r["scan"])
    assert "threshold speed with the unbalance: 53.2" in text and "linear threshold" in text and "56.59" in text


def test_turbocharger_growth_rate_at_57_hz_as_its_constant_speed_run():
    # the constant-speed run at 57 Hz grows at +4.0 1/s (docs/runups.md section 4), the eigenvalue +0.20
    from orchestrator.stability.films import film_model
    from orchestrator.stability.floquet import FloquetFilms
    from orchestrator.stability.system import _static_loads, build_system
    system = build_system(load_scenario(TURBO_HS))
    _, extra, total = _static_loads(system, None)
    fq = FloquetFilms(system, "hs", film_model(system, "hs", total), extra, n_per_rev=32)
    rate, whirl = fq.max_re(2 * math.pi * 57.0)
    assert 3.8 < rate < 4.2
    assert whirl == pytest.approx(math.pi * 57.0, rel=1e-9)        # half speed


def test_without_unbalance_option_the_result_has_only_the_linear_keys(capsys, tmp_path):
    a, b = tmp_path / "a.json", tmp_path / "b.json"
    args = (JEFFCOTT_HS, "--film", "short", "--speeds", "255:270", "--scan", "2", "--set", NO_UNBALANCE)
    assert run_verb(capsys, "stability", *args, "--json", a)[0] == 0
    assert run_verb(capsys, "stability", *args, "--unbalance", "--json", b)[0] == 0
    ra, rb = json.loads(a.read_text()), json.loads(b.read_text())
    assert set(ra) == LINEAR_KEYS
    assert set(rb) == LINEAR_KEYS | {"unbalance", "floquet", "linear"}
    assert {k: v for k, v in ra.items() if k not in ("scan", "method", "notes", "threshold_hz", "whirl_hz",
                                                      "whirl_ratio", "crossings", "bearings")} == \
        {k: v for k, v in rb.items() if k in LINEAR_KEYS - {"scan", "method", "notes", "threshold_hz", "whirl_hz",
                                                            "whirl_ratio", "crossings", "bearings"}}


def test_mass_conserving_film_and_floating_rings_are_refused():
    mc = load_scenario(REPO / "scenarios" / "jeffcott_runup_free_to_air.yaml")
    with pytest.raises(StabilityError, match=r"--unbalance --film mc.*use --unbalance --film hs"):
        stability(mc, film="mc", unbalance=True, n_scan=2, progress=False)
    ring = load_scenario(REPO / "scenarios" / "jeffcott_runup_floating_ring_half_sommerfeld.yaml")
    with pytest.raises(StabilityError, match="not for floating-ring bearings"):
        stability(ring, film="hs", unbalance=True, n_scan=2, progress=False)


def test_per_rev_needs_unbalance(capsys):
    code, _, err = run_verb(capsys, "stability", JEFFCOTT_HS, "--per-rev", "32", "--scan", "2")
    assert code != 0 and "--per-rev 32" in err and "needs --unbalance" in err


def test_a_speed_without_periodic_orbit_is_left_out_with_its_reason():
    # 100 g mm: at 126.8 Hz the unbalance orbit of the short film leaves the clearance
    scenario = load_scenario(JEFFCOTT_HS, ["fmus.rotor.parameters.unbalance=1e-4"])
    r = stability(scenario, film="short", speeds=(80.0, 126.8), n_scan=2, unbalance=True, progress=False)
    assert r["status"] == "stable" and len(r["scan"]) == 1
    assert r["speeds_without_equilibrium_hz"] == [pytest.approx(126.8)]
    (miss,) = r["floquet"]["speeds_without_orbit"]
    assert miss["speed_hz"] == pytest.approx(126.8) and "clearance" in miss["reason"]
    assert any(n.startswith("no synchronous periodic orbit (or static equilibrium) at 1 of the 2 speeds")
               for n in r["notes"])


def test_the_scripts_floquet_rate_along_the_computed_orbit_agrees():
    # docs/scripts/turbocharger_unbalance_floquet.py's monodromy (2 harmonics of the orbit, 48 midpoint
    # exponentials) on the periodic orbit computed here: measured +0.8258 against +0.8238 1/s at 54 Hz
    import sys

    import numpy as np
    sys.path.insert(0, str(REPO / "docs" / "scripts"))
    fl = pytest.importorskip("turbocharger_unbalance_floquet")
    from orchestrator.stability.floquet import FloquetFilms
    from orchestrator.stability.system import _static_loads
    fn, system = fl.linear_model(str(TURBO_HS))
    _, extra, _ = _static_loads(system, None)
    fq = FloquetFilms(system, "hs", fn, extra)
    w = 2 * math.pi * 54.0
    rate, _ = fq.max_re(w)
    kin = fq.orbits[w].kin[:-1]
    phi = 2 * math.pi * np.arange(len(kin)) / len(kin)
    B = np.array([np.ones_like(phi)] + [g(m * phi) for m in (1, 2) for g in (np.cos, np.sin)]).T
    orbits = []
    for j in range(2):
        cx, cy = (np.linalg.lstsq(B, kin[:, j, k], rcond=None)[0] for k in (0, 1))
        orbits.append((cx[0], cy[0], cx[1:], cy[1:]))
    theirs, mu = fl.floquet_rate(fn, system.rotor, orbits, w, 48)
    assert 0.7 < rate < 0.95
    assert theirs == pytest.approx(rate, abs=0.01)
    assert mu.imag == 0.0 and mu.real < -1.0


def test_a_load_in_place_of_the_weight_gives_the_same_orbit_and_threshold():
    # g = 0 and each bearing's weight share (m g / 2 = 29.43 N) as --load: the forces enter the orbit's
    # statics and dynamics as the weight does (measured: 261.95 Hz both, orbit 0.0081 x 0.0079 c)
    kw = dict(film="short", speeds=(255.0, 270.0), n_scan=2, unbalance=True, progress=False)
    a = stability(load_scenario(JEFFCOTT_HS), **kw)
    w = a["bearings"]["bearing1"]["load_vector_n"][1]
    b = stability(load_scenario(JEFFCOTT_HS, ["fmus.rotor.parameters.g=0"]),
                  loads={"bearing1": (0.0, w), "bearing2": (0.0, w)}, **kw)
    assert b["threshold_hz"] == pytest.approx(a["threshold_hz"], abs=2e-3)
    assert a["threshold_hz"] < a["linear"]["threshold_hz"] - 0.1         # measured -0.19 Hz
    oa, ob = a["floquet"]["orbit_at_threshold"]["bearing1"], b["floquet"]["orbit_at_threshold"]["bearing1"]
    assert ob["amplitude_x_c"] == pytest.approx(oa["amplitude_x_c"], rel=1e-3)
    assert ob["eps_max"] == pytest.approx(oa["eps_max"], rel=1e-3)
