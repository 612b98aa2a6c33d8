"""`rotorcosim stability --film mc`: the linear threshold with each mass-conserving film's own
linearisation, cavity (theta) dynamics included (orchestrator/stability.py ``_MCFilm``).

The film impedance itself is checked in tests/test_mc_impedance.py (against steady solves and the
transient film in the time domain); the command's sparse counted solver against the dense one in
tests/test_film_system.py. Here: the descriptor system's eigenvalues
(rotor_fmu.stability.film_system_eigenvalues) against the other formulation of the same
characteristic equation, det(s^2 M + s C + K + sum P^T Z(s) P) = 0 with Z(s) from
MCFilmLinear.impedance (a sparse LU per s); and the documented threshold of the oil-bath
Jeffcott rotor on its 40 x 40 films (slow), which the shipped run-up's growth-rate estimate
(181.48 Hz since the growth rates belong to their fits' centres, 2026-12-07; 181.84 Hz before)
confirms within 0.6 % (docs/analysis.md, "Linear threshold of the mass-conserving film").
"""

from __future__ import annotations

import json
import math
from pathlib import Path

import numpy as np
import pytest

from hostile_builders import run_verb

from orchestrator.cli import main

REPO = Path(__file__).resolve().parents[1]
BATH = REPO / "scenarios" / "jeffcott_runup_oil_bath.yaml"
SMALL = [f"fmus.{b}.parameters.{k}={v}" for b in ("bearing1", "bearing2") for k, v in (("n_phi", 16), ("n_z", 8))]


def _run(capsys, *args):
    return run_verb(capsys, "stability", *args)


def test_mc_threshold_is_a_root_of_the_impedance_determinant(capsys, tmp_path):
    from orchestrator.scenario import load_scenario
    from orchestrator.stability import _MCFilm, build_system
    from rotor_fmu.stability import film_system_eigenvalues, static_bearing_loads
    out = tmp_path / "r.json"
    sets = [a for s in SMALL for a in ("--set", s)]
    code, text, err = _run(capsys, BATH, "--film", "mc", "--speeds", "100:400", "--json", out, *sets)
    assert code == 0, err
    r = json.loads(out.read_text())
    assert r["film"] == "mc" and r["status"] == "threshold"
    assert "cavity (theta) dynamics" in r["method"]
    assert not any("HS linearisation" in n for n in r["notes"])
    # the same characteristic equation through Z(s): at the threshold the rightmost root s of the
    # descriptor system is on the imaginary axis (to the 0.01 Hz of the refinement) and makes the
    # impedance determinant singular
    system = build_system(load_scenario(str(BATH), SMALL, build_fmus=True))
    films = _MCFilm(system, static_bearing_loads(system.rotor))
    w = 2 * math.pi * r["threshold_hz"]
    lins = films._films(w)
    lam = film_system_eigenvalues(system.rotor, w, lins)
    s = lam[np.argmax(lam.real)]
    assert abs(s.real) < 0.05 and abs(abs(s.imag) / (2 * math.pi) - r["whirl_hz"]) < 1e-6 * r["whirl_hz"]
    M, C, K = system.rotor.system_matrices(w)

    def singular(s):            # smallest / largest singular value of the impedance matrix at s
        D = s * s * M + s * C + K.astype(complex)
        for lin, (ix, iy) in zip(lins, system.rotor.bearing_dofs):
            D[np.ix_([ix, iy], [ix, iy])] += lin.impedance(s)
        sv = np.linalg.svd(D, compute_uv=False)
        return sv[-1] / sv[0]
    assert singular(s) < 1e-7                           # a root of the determinant, to rounding
    assert singular(s + 0.01 * abs(s)) > 1e3 * singular(s)    # and nearby speeds are not
    # the cavity dynamics destabilise: well below the half-Sommerfeld linearisation of the same films
    code, _, err = _run(capsys, BATH, "--speeds", "100:400", "--json", tmp_path / "hs.json", *sets)
    assert code == 0, err
    assert r["threshold_hz"] < json.loads((tmp_path / "hs.json").read_text())["threshold_hz"] - 30.0


def test_mc_needs_mass_conserving_journal_bearings(capsys):
    code, _, err = _run(capsys, REPO / "scenarios" / "jeffcott_runup_half_sommerfeld.yaml", "--film", "mc")
    assert code == 1 and "'bearing1' is half-Sommerfeld (cavitation = 0): use --film hs" in err
    code, _, err = _run(capsys, REPO / "scenarios" / "turbocharger_runup_floating_ring_half_sommerfeld.yaml",
                        "--film", "mc")
    assert code == 1 and "floating-ring bearing 'bearing1' the inner and outer films are half-Sommerfeld" in err


def test_scan_option_is_checked(capsys):
    with pytest.raises(SystemExit) as e:
        main(["stability", str(BATH), "--scan", "1"])
    assert e.value.code == 2 and "from 2 to 2000" in capsys.readouterr().err


@pytest.mark.slow
def test_oil_bath_mc_threshold_40x40():
    """docs/analysis.md: 182.45 Hz, whirl ratio 0.485, eps 0.288 (docs/scripts/mc_linear_stability.py)."""
    from orchestrator.scenario import load_scenario
    from orchestrator.stability import stability
    r = stability(load_scenario(str(BATH), [], build_fmus=True), film="mc", speeds=(175.0, 200.0), n_scan=2)
    assert r["threshold_hz"] == pytest.approx(182.45, abs=0.02)
    # the independent reference: the shipped run-up's growth-rate threshold estimate (docs/runups.md)
    assert abs(r["threshold_hz"] / 181.48 - 1.0) < 0.01
    assert r["whirl_ratio"] == pytest.approx(0.485, abs=0.001)
    assert r["bearings"]["bearing1"]["eps_at_threshold"] == pytest.approx(0.288, abs=0.001)
