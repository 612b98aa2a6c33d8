"""First-order model adapters of the monolithic reference (:mod:`orchestrator.reference.monolithic`).

An adapter wraps one FMU instance's *plain-Python* model (never the FMU) as

* ``initial_state() -> ndarray`` (may be empty),
* ``rhs(t, s, u) -> ds/dt`` with ``u`` the dict of the FMU's inputs,
* ``outputs(t, s, u) -> dict`` of the FMU's outputs at state ``s``,
* ``feedthrough``: True when outputs depend on inputs.

Adapters with ``implicit = True`` (the mass-conserving bearing) have an internal discrete
state advanced by the BDF2 integrator of :mod:`orchestrator.reference.monolithic`: ``start(u, step,
tol)``, ``trial(h, u)`` (one film step from the committed state), ``commit(h, u)``;
bearing adapters give ``fd_steps(u)`` (difference steps of their inputs) for the
integrator's Newton matrix.

``MODELS`` maps the FMU's ``modelName`` to a factory (ours here; others, such as the
tests' two-mass oscillator, are added with :func:`register_model`)
``(instance, model_description, parameters, *, start_time) -> adapter``; parameters are the
FMU's start values overridden by the scenario's ``parameters``. A parameter the
Python model does not know raises, so the reference never silently differs from
the FMU it stands for.
"""

from __future__ import annotations

import dataclasses
import math
import re
from typing import Any, Callable, Mapping

import numpy as np

__all__ = ["ModelAdapter", "MODELS", "register_model", "load_model_file"]


class ModelAdapter:
    """Base class: the rules of an adapter are in the module docstring."""

    input_names: tuple[str, ...] = ()
    output_names: tuple[str, ...] = ()
    feedthrough: bool = False
    n_states: int = 0
    implicit: bool = False       # internal discrete state advanced by the BDF2 integrator's steps

    def __init__(self, instance: str, md, params: Mapping[str, Any], *, start_time: float = 0.0):
        self.instance = instance
        self.params = _parameters(md, params)
        self.input_defaults = {n: float(md.variables[n].start or 0.0) for n in self.input_names
                               if n in md.variables}
        missing = [n for n in self.input_names + self.output_names if n not in md.variables]
        if missing:
            raise KeyError(f"model '{md.model_name}' lacks the variables {missing} the monolithic "
                           "adapter expects; rebuild the FMU (rotorcosim build-fmus --force)")

    def initial_state(self) -> np.ndarray:
        return np.zeros(0)

    def rhs(self, t: float, s: np.ndarray, u: Mapping[str, float]) -> np.ndarray:
        return np.zeros(0)

    def outputs(self, t: float, s: np.ndarray, u: Mapping[str, float], *, full: bool = True) -> dict[str, float]:
        """Outputs at (t, s, u); ``full=False`` (inside the right-hand side) may leave outputs that
        are expensive and feed nothing physical as NaN (so a misuse fails loudly)."""
        raise NotImplementedError


def _parameters(md, overrides: Mapping[str, Any]) -> dict[str, Any]:
    out = {n: v.start for n, v in md.variables.items()
           if v.causality == "parameter" and v.start is not None}
    unknown = [k for k in overrides if k not in out and k not in md.variables]
    if unknown:
        raise KeyError(f"parameters {unknown} are not variables of model '{md.model_name}'")
    out.update(overrides)
    return out


def _dataclass_kwargs(cls, params: Mapping[str, Any], ignore=()) -> dict[str, Any]:
    names = {f.name for f in dataclasses.fields(cls)}
    unknown = sorted(k for k in params if k not in names and k not in ignore)
    if unknown:
        raise ValueError(f"FMU parameters {unknown} have no counterpart in {cls.__name__}; the "
                         "monolithic reference would silently ignore them")
    return {k: v for k, v in params.items() if k in names}


# --------------------------------------------------------------------------- rotor and bearing

# FMU parameters without a BearingParams field: the fields file (not written by the reference)
# and the initial film of the mass-conserving model (half-Sommerfeld ignores it), and
# `linearize` (film coefficient outputs for interface-Jacobian coupling; the reference
# couples monolithically and leaves those outputs 0).
_BEARING_FMU_ONLY = ("fields_file", "init", "linearize", "linearize_tol")
# Rotor FMU parameters without a JeffcottParams field: the ring masses of the ring-interface
# step (rotor_fmu/ring_interface.py), like the kxx_i inputs a device of the co-simulation step
# that does not change the physical system.
_ROTOR_FMU_ONLY = ("m_ring_1", "m_ring_2")


class JournalBearingAdapter(ModelAdapter):
    """bearing_fmu.model.BearingModel, half-Sommerfeld only (quasi-static, no state)."""

    input_names = ("x", "y", "vx", "vy", "omega")
    feedthrough = True

    def __init__(self, instance, md, params, *, start_time=0.0):
        super().__init__(instance, md, params, start_time=start_time)
        from bearing_fmu import journal_bearing as slave
        from bearing_fmu.model import BearingParams, BearingModel
        renamed = getattr(slave, "RENAMED", {})          # FMU name -> BearingParams field
        params = {renamed.get(k, k): v for k, v in self.params.items()}
        kw = _dataclass_kwargs(BearingParams, params, ignore=_BEARING_FMU_ONLY)
        if int(kw.get("cavitation", 1)) != 0:
            raise ValueError("JournalBearingAdapter is the half-Sommerfeld adapter; the "
                             "mass-conserving film (cavitation = 1) is MassConservingBearingAdapter")
        self.model = BearingModel(BearingParams(**kw))
        u = self.input_defaults
        self.model.initialize(u["x"], u["y"], u["vx"], u["vy"], u["omega"])
        self.output_names = tuple(n for n, v in md.variables.items() if v.causality == "output")
        # film coefficients kxx..cyy for interface-Jacobian coupling (FMU parameter linearize)
        self.coeff_names = tuple(n for n in self.output_names if re.fullmatch(r"[kc][xy][xy]", n))
        self.linearize = int(self.params.get("linearize", 0)) != 0
        plain = [n for n in self.output_names if n not in self.coeff_names]
        missing = [n for n in plain if n not in self.model.outputs]
        if missing:
            raise KeyError(f"the bearing model computes no {missing} (has {sorted(self.model.outputs)})")

    def fd_steps(self, u):
        return _fd_steps(self.model.c, u)

    def outputs(self, t, s, u, *, full=True):
        # quasi-static: step() only evaluates the film at the given kinematics (cavitation = 0)
        self.model.step(1e-6, u["x"], u["y"], u["vx"], u["vy"], u["omega"])
        out = {n: float(v) for n, v in self.model.outputs.items() if n in self.output_names}
        if self.coeff_names:
            if full and self.linearize:
                from bearing_fmu.linearize import linearization
                K, C = linearization(self.model)
                for m, kind in ((K, "k"), (C, "c")):
                    for a, i in enumerate("xy"):
                        for b, j in enumerate("xy"):
                            out[f"{kind}{i}{j}"] = float(m[a, b])
            else:   # as the FMU with linearize = 0 outputs 0; NaN inside the rhs (unused there)
                out.update({n: (0.0 if not self.linearize else math.nan) for n in self.coeff_names})
        return out


def _coefficient_outputs(model, names, linearize, full) -> dict[str, float]:
    """Film coefficients kxx..cyy as the FMU outputs them (``linearize``), NaN inside the rhs."""
    if not names:
        return {}
    if full and linearize:
        from bearing_fmu.linearize import linearization
        K, C = linearization(model)
        out = {}
        for m, kind in ((K, "k"), (C, "c")):
            for a, i in enumerate("xy"):
                for b, j in enumerate("xy"):
                    out[f"{kind}{i}{j}"] = float(m[a, b])
        return out
    return {n: (0.0 if not linearize else math.nan) for n in names}


def _fd_steps(c: float, u: Mapping[str, float]) -> dict[str, float]:
    """Finite-difference steps of the bearing inputs (as bearing_fmu.linearize): 1e-5 of the
    clearance for x, y and of max(c |omega|, |v|, c / 1 ms) for vx, vy. omega is a function
    of time only in our rotor models and is not differenced."""
    dv = 1e-5 * max(c * abs(u["omega"]), abs(u["vx"]), abs(u["vy"]), c / 1e-3)
    return {"x": 1e-5 * c, "y": 1e-5 * c, "vx": dv, "vy": dv}


class MassConservingBearingAdapter(ModelAdapter):
    """bearing_fmu.model.BearingModel with ``cavitation = 1`` (mass-conserving film).

    The film has its own state (the universal variable u per cell: pressure in the full
    film, fluid fraction theta in the cavity), advanced by the *reference's* BDF steps:
    the adapter is ``implicit`` and is only usable by the BDF2 integrator of
    :mod:`orchestrator.reference.monolithic` (not by ``solve_ivp``). Per integrator step of size h:

    * ``trial(h, u)``: restore the film state at t_n, take ONE film step of size h with
      the journal kinematics ``u`` (the end-of-step kinematics x, y, vx, vy, omega at
      t_{n+1}) through the public ``BearingModel.step``, return the outputs at t_{n+1};
      memoized per (h, u) within the step;
    * ``commit(h, u)``: keep the film state of the converged ``u`` as the new t_n state.

    The film is built with its own error control disabled (``theta_atol = 1e30``),
    ``h_init = h_max = h`` and ``h_min = h / 1000``, so that ``BearingModel.step(h)`` is
    exactly one BDF step (BDF1 for the first, variable-coefficient BDF2 after it: the
    same formula and step sequence as the reference's rotor step), never a sub-stepped
    one; the film Newton is exact (``krylov_refactor = 0``) with ``newton_atol =
    newton_rtol = tol``. A film step that would need sub-steps or fails raises
    :class:`bearing_fmu.model.StepFailed`. The film keeps its own time ``t`` from 0;
    its equations do not depend on absolute time.
    """

    input_names = ("x", "y", "vx", "vy", "omega")
    feedthrough = True
    implicit = True

    def __init__(self, instance, md, params, *, start_time=0.0):
        super().__init__(instance, md, params, start_time=start_time)
        from bearing_fmu import journal_bearing as slave
        from bearing_fmu.model import BearingParams
        renamed = getattr(slave, "RENAMED", {})
        params = {renamed.get(k, k): v for k, v in self.params.items()}
        self._kw = _dataclass_kwargs(BearingParams, params, ignore=_BEARING_FMU_ONLY)
        self._kw["cavitation"] = 1
        self.init = str(self.params.get("init", "flooded"))
        if self.init not in ("flooded", "stationary"):
            raise ValueError(f"parameter 'init' must be 'flooded' or 'stationary' (got {self.init!r})")
        BearingParams(**self._kw)            # validate now (bad parameters fail before running)
        self.output_names = tuple(n for n, v in md.variables.items() if v.causality == "output")
        self.coeff_names = tuple(n for n in self.output_names if re.fullmatch(r"[kc][xy][xy]", n))
        self.linearize = int(self.params.get("linearize", 0)) != 0
        self.model = None
        self.film_steps = 0                  # film steps taken (trials included)

    def start(self, u: Mapping[str, float], *, step: float, tol: float) -> None:
        """Build the film for reference steps of size ``step`` and Newton tolerance ``tol``
        and initialise it at the inputs ``u`` (t0), as the FMU does at exit_initialization_mode."""
        from bearing_fmu.model import BearingParams, BearingModel
        kw = dict(self._kw, theta_atol=1e30, h_init=float(step), h_max=float(step),
                  h_min=1e-3 * float(step), krylov_refactor=0, newton_atol=float(tol),
                  newton_rtol=float(tol), newton_max_iter=max(int(self._kw.get("newton_max_iter", 30)), 50))
        self.model = BearingModel(BearingParams(**kw))
        plain = [n for n in self.output_names if n not in self.coeff_names]
        self.model.initialize(*(float(u[n]) for n in self.input_names), init=self.init)
        missing = [n for n in plain if n not in self.model.outputs]
        if missing:
            raise KeyError(f"the bearing model computes no {missing} (has {sorted(self.model.outputs)})")
        self._saved = self.model.get_state()
        self._out = self._plain()
        self._held = None                   # key of the trial whose state the model holds
        self._cache: dict[tuple, dict[str, float]] = {}
        self.c = self.model.c

    def _plain(self) -> dict[str, float]:
        return {n: float(v) for n, v in self.model.outputs.items() if n in self.output_names}

    def trial(self, h: float, u: Mapping[str, float]) -> dict[str, float]:
        from bearing_fmu.model import StepFailed
        key = (float(h),) + tuple(float(u[n]) for n in self.input_names)
        out = self._cache.get(key)
        if out is not None:
            return out
        m = self.model
        m.set_state(self._saved)
        n0, r0 = m.stats["steps"], m.stats["rejected"]
        self._held = None
        m.step(key[0], *key[1:])
        self.film_steps += 1
        if m.stats["steps"] != n0 + 1 or m.stats["rejected"] != r0:
            raise StepFailed(f"{self.instance}: the film took {m.stats['steps'] - n0} steps "
                             f"({m.stats['rejected'] - r0} rejected) for one reference step of "
                             f"{h:g} s; reduce coupling.options.step")
        self._held = key
        out = self._plain()
        out.update({n: 0.0 for n in self.coeff_names})
        if len(self._cache) > 64:
            self._cache.clear()
        self._cache[key] = out
        return out

    def commit(self, h: float, u: Mapping[str, float]) -> None:
        key = (float(h),) + tuple(float(u[n]) for n in self.input_names)
        if self._held != key:
            self._cache.pop(key, None)
            self.trial(h, u)
        self._saved = self.model.get_state()
        self._out = self._plain()
        self._cache.clear()

    def fd_steps(self, u: Mapping[str, float]) -> dict[str, float]:
        return _fd_steps(self.c, u)

    def outputs(self, t, s, u, *, full=True):
        """Outputs of the committed film state (t_n); coefficients as the FMU outputs them."""
        out = dict(self._out)
        if self.coeff_names:
            if full and self.linearize and self._held is not None:
                self.model.set_state(self._saved)
                self._held = None
            out.update(_coefficient_outputs(self.model, self.coeff_names, self.linearize, full))
        return out


class JeffcottRotorAdapter(ModelAdapter):
    """rotor_fmu.jeffcott.JeffcottModel in its first-order form.

    Only the film forces ``Fx_i, Fy_i`` enter ``rhs``. The film-coefficient inputs of
    interface-Jacobian coupling (``kxx_i`` ... ``cyy_i``, and the ring-interface step's
    ``m_ring_i`` and ring inputs) are a device of the co-simulation step and do not change
    the physical system, which the monolithic integrator solves exactly; they are ignored here.
    """

    output_names = ()

    def __init__(self, instance, md, params, *, start_time=0.0):
        from rotor_fmu.jeffcott import JeffcottParams, JeffcottModel
        self.input_names = tuple(n for n, v in md.variables.items() if v.causality == "input")
        super().__init__(instance, md, params, start_time=start_time)
        kw = _dataclass_kwargs(JeffcottParams, self.params, ignore=_ROTOR_FMU_ONLY)
        kw["t0"] = start_time            # the FMU takes t0 from the experiment start time
        self.model = JeffcottModel(JeffcottParams(**kw))
        self.model.initialize()
        self.n_b = int(self.model.n_bearings)
        self.output_names = tuple(n for n, v in md.variables.items() if v.causality == "output")
        self._s0 = np.asarray(self.model.state_vector(), dtype=float).copy()
        self.n_states = self._s0.size

    def _forces(self, u) -> np.ndarray:
        return np.array([[u[f"Fx_{i + 1}"], u[f"Fy_{i + 1}"]] for i in range(self.n_b)], dtype=float)

    def initial_state(self):
        return self._s0.copy()

    def rhs(self, t, s, u):
        return np.asarray(self.model.rhs(t, s, self._forces(u)), dtype=float)

    def outputs(self, t, s, u, *, full=True):
        self.model.set_state({"t": float(t), "s": s})   # exact; recomputes every output
        out = self.model.outputs
        missing = [n for n in self.output_names if n not in out]
        if missing:
            raise KeyError(f"{self.instance}: the rotor model computes no {missing} "
                           f"(has {sorted(out)})")
        return {n: float(out[n]) for n in self.output_names}


def journal_bearing_adapter(instance, md, params, *, start_time=0.0) -> ModelAdapter:
    """``JournalBearing`` FMU: half-Sommerfeld (cavitation = 0) or mass-conserving (1) adapter."""
    p = _parameters(md, params)
    cav = int(p.get("cavitation", 1))
    cls = MassConservingBearingAdapter if cav == 1 else JournalBearingAdapter
    return cls(instance, md, params, start_time=start_time)


MODELS: dict[str, Callable[..., ModelAdapter]] = {
    "JournalBearing": journal_bearing_adapter,
    "JeffcottRotor": JeffcottRotorAdapter,
}


def register_model(model_name: str, factory: Callable[..., ModelAdapter]) -> None:
    """Make ``factory`` the adapter of FMUs whose ``modelName`` is ``model_name`` (e.g. the
    two-mass oscillator of the tests, registered by ``tests/fmus_src/_reference_models.py``)."""
    if not callable(factory):
        raise TypeError(f"register_model({model_name!r}, ...): the factory must be callable "
                        f"(got {type(factory).__name__})")
    MODELS[model_name] = factory


def load_model_file(path) -> None:
    """Import the Python file ``path`` and call its ``register(register_model)``: adapters that
    live beside their FMU sources (compare files name them through ``compare.build_fmus``)."""
    import importlib.util
    from pathlib import Path
    path = Path(path).resolve()
    spec = importlib.util.spec_from_file_location(f"rotorcosim_reference_models_{abs(hash(str(path)))}", path)
    if spec is None or spec.loader is None:
        raise ImportError(f"{path}: cannot import the reference model file")
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    register = getattr(module, "register", None)
    if not callable(register):
        raise ImportError(f"{path}: a reference model file must define register(register_model)")
    register(register_model)
