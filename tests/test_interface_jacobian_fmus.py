"""Interface-Jacobian coupling through the real FMUs and the master
(benchmarks/stiff_coupling/*.yaml, docs/stiff-coupling.md): the Jeffcott rotor in two
half-Sommerfeld bearings at a 50 us macro step (~15x the explicit limit) runs with the
film coefficients connected and matches the monolithic reference; plain coupling at the
same step leaves the clearance within a few steps."""

from __future__ import annotations

from pathlib import Path

import numpy as np
from orchestrator import load_scenario, run

HERE = Path(__file__).resolve().parents[1] / "benchmarks" / "stiff_coupling"
SIG = ["rotor.x_1", "rotor.y_1", "rotor.x_2", "rotor.y_2"]
C = 2.8e-3 * 0.02
COMMON = ["start_time=1.0", "stop_time=1.002", "output.interval=1e-4",
          f"output.signals=[{','.join(SIG)}]"]


def _run(name, tmp_path, extra):
    sc = load_scenario(str(HERE / name), overrides=COMMON + extra)
    return run(sc, out_dir=tmp_path / name.replace(".yaml", "") / extra[-1].replace("=", "_"),
               progress=False)


def test_interface_jacobian_fmus_stable_and_accurate_at_50us(tmp_path):
    ref = _run("jeffcott_hs_plain.yaml", tmp_path, ["coupling.scheme=monolithic",
                                                     "coupling.options.rtol=1e-8",
                                                     "coupling.macro_step=1e-4"])
    assert ref.success, ref.message
    ij = _run("jeffcott_hs_ij.yaml", tmp_path, ["coupling.macro_step=5e-5"])
    assert ij.success, ij.message
    plain = _run("jeffcott_hs_plain.yaml", tmp_path, ["coupling.macro_step=5e-5"])
    assert not plain.success
    X = np.stack([ij.outputs[s] for s in SIG], axis=1)
    R = np.stack([ref.outputs[s] for s in SIG], axis=1)
    assert X.shape == R.shape
    motion = np.abs(R - R[0]).max()
    assert motion > 1e-3 * C                       # the journals really move
    assert np.abs(X - R).max() < 0.01 * motion     # 1 % of the motion
