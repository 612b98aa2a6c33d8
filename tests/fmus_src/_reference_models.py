"""Monolithic-reference adapters of the two-mass oscillator (left_mass.py, right_mass.py).

Registered by tests/conftest.py for the tests and, through ``compare.build_fmus.from``,
by ``rotorcosim compare compare/two_mass.yaml`` (orchestrator.reference.models.load_model_file).
The leading ``_`` keeps it out of the PythonFMU sources this folder is built from.
"""

from __future__ import annotations

import math

import numpy as np

from orchestrator.reference.models import ModelAdapter


class LeftMassAdapter(ModelAdapter):
    """tests/fmus_src/left_mass.py: ``m1 x1'' = -k1 x1 + F``."""

    input_names = ("F",)
    output_names = ("x1", "v1")
    n_states = 2

    def initial_state(self):
        return np.array([self.params["x1_0"], self.params["v1_0"]], dtype=float)

    def rhs(self, t, s, u):
        p = self.params
        return np.array([s[1], (-p["k1"] * s[0] + u["F"]) / p["m1"]])

    def outputs(self, t, s, u, *, full=True):
        return {"x1": float(s[0]), "v1": float(s[1])}


class RightMassAdapter(ModelAdapter):
    """tests/fmus_src/right_mass.py: ``m2 x2'' = -k2 x2 - d2 v2 - F``, ``F = kc (x2-x1) + dc (v2-v1)``
    (``kc`` becomes ``kc_after`` from ``t_switch`` on)."""

    input_names = ("x1", "v1")
    output_names = ("F", "x2", "v2")
    feedthrough = True
    n_states = 2

    def initial_state(self):
        return np.array([self.params["x2_0"], self.params["v2_0"]], dtype=float)

    def _force(self, t, s, u):
        p = self.params
        kc = p.get("kc_after", p["kc"]) if t >= p.get("t_switch", math.inf) else p["kc"]
        return kc * (s[0] - u["x1"]) + p["dc"] * (s[1] - u["v1"])

    def rhs(self, t, s, u):
        p = self.params
        return np.array([s[1], (-p["k2"] * s[0] - p["d2"] * s[1] - self._force(t, s, u)) / p["m2"]])

    def outputs(self, t, s, u, *, full=True):
        return {"F": float(self._force(t, s, u)), "x2": float(s[0]), "v2": float(s[1])}


def register(register_model) -> None:
    register_model("LeftMass", LeftMassAdapter)
    register_model("RightMass", RightMassAdapter)
