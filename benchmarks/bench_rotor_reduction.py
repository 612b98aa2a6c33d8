"""Accuracy and cost of the turbocharger's Craig-Bampton reduction vs the full FE model.

Run:  cd /work/main && OPENBLAS_NUM_THREADS=1 nice -n 10 .venv/bin/python benchmarks/bench_rotor_reduction.py
Prints: damped natural frequencies on linear supports (k = 2e7 N/m, c = 300 N s/m per
bearing) at 0 and 105 Hz, the max relative error of the bearing-station unbalance
response over 5..105 Hz, n_dof, omega_max and internal sub-steps per 2e-5 s step.
"""

import numpy as np

from rotor_fmu.turbocharger import TurbochargerParams, TurbochargerRotor

KB, CB = 2.0e7, 300.0


def freqs(r, Om):
    M, C, K = r.system_matrices(Om)
    n = M.shape[0]
    A = np.block([[np.zeros((n, n)), np.eye(n)], [-np.linalg.solve(M, K), -np.linalg.solve(M, C)]])
    lam = np.linalg.eigvals(A)
    return np.sort(np.abs(lam.imag[lam.imag > 1e-6])) / (2 * np.pi)


def resp(r, Om):
    M, C, K = r.system_matrices(Om)
    f = np.zeros(r.n_dof, complex)
    for ix, iy, me, ph in r.unbalances:
        f[ix] += me * Om**2 * np.exp(1j * ph)
        f[iy] += -1j * me * Om**2 * np.exp(1j * ph)
    X = np.linalg.solve(K - Om**2 * M + 1j * Om * C, f)
    return X[r.bearing_dofs[:, 0]]


def main():
    models = {"full": TurbochargerRotor(TurbochargerParams(reduce=False))}
    for nm in (1, 2, 4, 8):
        models[f"CB{nm}"] = TurbochargerRotor(TurbochargerParams(n_modes=nm))
    for r in models.values():
        r.add_linear_supports(KB, CB)
    for Om in (0.0, 2 * np.pi * 105):
        print(f"damped natural frequencies [Hz] at {Om / 2 / np.pi:.0f} Hz spin (first 8):")
        ref = freqs(models["full"], Om)[:8]
        print(f"  {'full':6s} " + " ".join(f"{x:8.2f}" for x in ref))
        for name, r in models.items():
            if name != "full":
                w = freqs(r, Om)[:8]
                print(f"  {name:6s} " + " ".join(f"{x:8.2f}" for x in w)
                      + f"   max rel err {np.max(np.abs(w / ref - 1)):.1e}")
    print("bearing-station unbalance response, max |X_red - X_full| / max |X_full| over 5..105 Hz:")
    for name, r in models.items():
        if name == "full":
            continue
        e = max(np.max(np.abs(resp(r, 2 * np.pi * f) - resp(models["full"], 2 * np.pi * f)))
                / np.max(np.abs(resp(models["full"], 2 * np.pi * f))) for f in np.linspace(5, 105, 41))
        print(f"  {name:6s} {e:.1e}")
    print(f"{'model':6s} {'n_dof':>5s} {'f_max [Hz]':>11s} {'n_sub(2e-5)':>11s}")
    for name, r in models.items():
        print(f"{name:6s} {r.n_dof:5d} {r.omega_max / 2 / np.pi:11.0f} {r.n_substeps(2e-5):11d}")


if __name__ == "__main__":
    main()
