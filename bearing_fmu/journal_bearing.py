"""JournalBearing: FMI 2.0 co-simulation slave of one hydrodynamic journal bearing.

A thin PythonFMU wrapper (the builder needs a class that derives *directly*
from ``Fmi2Slave``, and the FMU's C loader finds it with the regular expression
``^class (\\w+)\\(\\s*Fmi2Slave\\s*\\)\\s*:``) around
:class:`bearing_fmu.model.BearingModel`. All physics lives in the model; this
module only maps FMI variables to it. Variables, units and capabilities are
documented in ``docs/fmus.md``.

Life cycle
----------
``__init__`` only registers variables (the builder instantiates this class to
write ``modelDescription.xml``): no grid, no numba compilation. Parameters and
inputs may be set before and during initialization. The model is built and
initialized with the current parameter and input values when the importer first
asks for an output in initialization mode or, at the latest, in
``exit_initialization_mode``. ``do_step`` advances the film over the
communication step with the inputs held constant (zero-order hold: PythonFMU
does not implement ``fmi2SetRealInputDerivatives``).

FMU state
---------
PythonFMU's default ``fmi2GetFMUstate`` only collects registered scalar
variables, which would lose the pressure field and the integrator history.
``_get_fmu_state``/``_set_fmu_state`` are overridden here to deep-copy the
model's ``get_state()`` (arrays included) together with the FMI-visible
scalars, so a restore is exact. States serialize with ``pickle``.

Where the code comes from
-------------------------
``orchestrator/fmi/build.py`` bundles the ``bearing_fmu`` package sources into the
FMU's ``resources/`` folder, which the PythonFMU loader puts first on
``sys.path``; the FMU needs numpy, scipy and numba in the importing Python, not
an installed rotorcosim. (If a process has already imported ``bearing_fmu``,
Python reuses that module.)
"""

from __future__ import annotations

import dataclasses
import json
import logging
import math
import os
import shutil
import sys
from pathlib import Path
from typing import Any
from xml.etree.ElementTree import Element

from pythonfmu import Fmi2Causality, Fmi2Slave, Fmi2Variability, Integer, String
from pythonfmu.enums import Fmi2Initial, Fmi2Status
from pythonfmu.variables import Boolean

from fmu_common.slave import (
    RealU, check_shipped_layout, check_step_start, fast_get_real, fast_set_real, exit_initialization_mode, finish_model_description,
    get_slave_state, guard_callbacks, input_setter, journal_kinematics, output_getter, param_setter,
    refresh_coefficients, set_slave_state,
    POSITIVE, scalar_default, setup_experiment, shipped_parameters, state_from_bytes, state_to_bytes, value_getter)

log = logging.getLogger(__name__)

# ----------------------------------------------------------------------------
# Variable tables: name -> (default, unit, description)
# ----------------------------------------------------------------------------
DEFAULT_R = 0.02

REAL_PARAMETERS: dict[str, tuple[float, str, str]] = {
    "R": (DEFAULT_R, "m", "journal (bearing) radius R [m] (e.g. 0.02 for 20 mm)"),
    "B": (1.6 * DEFAULT_R, "m", "axial bearing width B [m] (e.g. 0.032 for 32 mm)"),
    "psi": (2.8e-3, "1", "relative radial clearance psi = C/R, radial clearance C over journal radius R [-], "
                         "typically 1e-3 to 3e-3 (1 to 3 per mille); a value in per mille is 1000 times too "
                         "large (1.5 per mille is psi = 1.5e-3), a clearance in m is not psi (C = 15 um at "
                         "R = 10 mm is psi = 1.5e-3)"),
    "eta0": (0.012, "Pa.s", "dynamic viscosity of the pure lubricant eta0 [Pa s] (e.g. 0.012 for 12 mPa s = 12 cP)"),
    "p0": (1.0e5, "Pa", "ambient pressure p0 [Pa]"),
    "p_feed": (1.0e5, "Pa", "feed pressure in the axial groove p_feed [Pa]"),
    "groove_width": (0.0, "rad", "opening angle of the axial feed groove [rad] (0: no groove)"),
    "groove_angle": (math.pi / 2, "rad", "groove centre, from +x counter-clockwise [rad]"),
    "sigma_rough": (0.3e-6, "m", "composite RMS surface roughness of journal and shell [m] (asperity contact, contact = 1)"),
    "contact_KE": (2.0e7, "Pa", "Greenwood-Tripp factor K E' of the asperity contact pressure [Pa] (contact = 1)"),
    "mu_contact": (0.1, "1", "boundary friction coefficient of the asperity contact [-] (contact = 1)"),
    "contact_h_limit": (-1.0, "1", "smallest nominal gap h/sigma_rough a step may reach; deeper: fmi2Discard "
                                   "(retry with smaller steps: coupling.discard_retries) (contact = 1)"),
}
INTEGER_PARAMETERS: dict[str, tuple[int, str]] = {
    "n_phi": (40, "number of grid cells in the circumferential direction [-]"),
    "n_z": (40, "number of grid cells in the axial direction [-]"),
    # a switch's description ends with the names of its values, "(0 = NAME, 1 = NAME)": rotorcosim
    # reads them for plot axes (orchestrator.fmi.model_description.value_names, docs/fmus.md)
    "cavitation": (1, "cavitation model: the quasi-static half-Sommerfeld film or the transient mass-conserving "
                      "two-phase film (0 = half-Sommerfeld, 1 = mass-conserving)"),
    "axial_bc": (0, "axial boundary condition: oil bath is Dirichlet p0, free to air a Neumann penalty "
                    "(0 = oil bath, 1 = free to air)"),
    "theta_transport": (0, "Couette transport of the fluid fraction of the mass-conserving film: first-order "
                           "upwind or limited second order MUSCL (0 = upwind, 1 = MUSCL)"),
    "contact": (0, "asperity contact of journal and shell: none, or Greenwood-Tripp contact with boundary "
                   "friction added to the film force, bearing_fmu/contact.py (0 = no contact, 1 = asperity contact)"),
}
INPUTS: dict[str, tuple[str, str]] = journal_kinematics()
OUTPUTS: dict[str, tuple[str, str]] = {
    "Fx": ("N", "film force on the journal, x [N] (plus the asperity contact force when contact = 1)"),
    "Fy": ("N", "film force on the journal, y [N] (plus the asperity contact force when contact = 1)"),
    "eps": ("1", "relative eccentricity |e|/C [-]"),
    "attitude": ("rad", "attitude angle: from the load line (direction of -F) to the eccentricity vector, counter-clockwise positive [rad]"),
    "p_max": ("Pa", "maximum film pressure [Pa]"),
    "p_min": ("Pa", "minimum film pressure [Pa]"),
    "h_min": ("m", "minimum film thickness [m]"),
    "torque": ("N.m", "friction torque of the film on the journal about +z [N m]"),
    "q_feed": ("m3/s", "volume inflow through the feed groove [m^3/s]"),
    "q_side": ("m3/s", "volume outflow through both axial edges [m^3/s]"),
    "F_contact": ("N", "normal asperity contact force of journal and shell [N] (0 unless contact = 1)"),
}
# Interface-Jacobian coupling (docs/stiff-coupling.md, bearing_fmu/linearize.py): film
# coefficients K = -dF/dr, C = -dF/dv at the current state, computed when the Integer
# parameter ``linearize`` is 1 (default 0: plain coupling pays nothing).
LINEARIZATION_OUTPUTS: dict[str, tuple[str, str]] = {
    f"{kind}{i}{j}": (unit, f"film {what} -dF{i}/d{var}{j} [{unit}] (interface-Jacobian coupling)")
    for kind, unit, what, var in (("k", "N/m", "stiffness", ""), ("c", "N.s/m", "damping", "v"))
    for i in "xy" for j in "xy"}
# Declared ranges of the parameters (modelDescription.xml min/max, inclusive; FMI 2.0 sec.
# 2.2.7), so that an importer refuses a bad value when it loads a scenario, with its file and
# line, instead of the model failing in initialization. BearingParams checks the same and the
# relations between parameters (p_feed >= p0, h_min <= h_init <= h_max, the film's cells).
# The film grid is bounded: a film of n_phi x n_z cells takes memory and time in proportion
# (n_phi: 10^9 took 23 GB before failing); the largest grids we use are 1536 x 40 (issue 16
# phi refinement), 40 x 320 (its axial one) and 160 x 160. The ranges live in bearing_fmu.limits,
# shared with BearingParams (model.py itself is not imported here: the FMU loads its code in
# __init__, see use_stable_code_copy).
from bearing_fmu.limits import (B_RANGE, CONTACT_KE_MAX, ETA0_RANGE, MAX_N_PHI, MAX_N_Z, MU_CONTACT_MAX,  # noqa: E402
                                PRESSURE_MAX, PSI_MAX, PSI_MIN, R_RANGE, SIGMA_ROUGH_MAX)
POS = POSITIVE
PARAMETER_RANGES: dict[str, tuple[Any, Any]] = {
    "R": R_RANGE, "B": B_RANGE, "psi": (PSI_MIN, PSI_MAX), "eta0": ETA0_RANGE, "p0": (0.0, PRESSURE_MAX),
    "p_feed": (0.0, PRESSURE_MAX), "groove_width": (0.0, 2 * math.pi), "sigma_rough": (POS, SIGMA_ROUGH_MAX),
    "contact_KE": (0.0, CONTACT_KE_MAX), "mu_contact": (0.0, MU_CONTACT_MAX), "contact_h_limit": (-6.0, 0.0),
    "n_phi": (8, MAX_N_PHI), "n_z": (2, MAX_N_Z), "cavitation": (0, 1), "axial_bc": (0, 1),
    "theta_transport": (0, 1), "contact": (0, 1),
    "cav_width": (POS, None), "cav_smoothing": (POS, None), "penalty_a": (0.0, None), "penalty_b": (POS, None),
    "penalty_smoothing": (POS, None), "theta_atol": (POS, None), "newton_atol": (POS, None),
    "newton_max_iter": (2, None), "krylov_tol": (POS, 1.0), "krylov_refactor": (0, None),
    "solver_h_init": (POS, None), "solver_h_min": (POS, None), "solver_h_max": (POS, None),
}
# String parameters and their values: FMI 2.0 cannot declare them, so they go into a rotorcosim
# annotation of the variable (fmu_common.slave.declare_choices; checked at load by rotorcosim) and
# are checked again when the model is made
STRING_CHOICES: dict[str, tuple[str, ...]] = {"linear_solver": ("band", "lapack", "splu"),
                                              "init": ("flooded", "stationary")}

# Model parameters whose names collide with FMU variables: FMU name -> model field.
RENAMED = {"solver_h_init": "h_init", "solver_h_min": "h_min", "solver_h_max": "h_max"}
_FMU_NAME = {v: k for k, v in RENAMED.items()}

# Outputs the model must provide (issue 5 contract); the others default to 0.
REQUIRED_OUTPUTS = ("Fx", "Fy", "eps", "p_max", "p_min", "h_min")

UNITS = {
    "m": dict(m="1"), "m/s": dict(m="1", s="-1"), "rad": dict(rad="1"),
    "rad/s": dict(rad="1", s="-1"), "Pa": dict(kg="1", m="-1", s="-2"),
    "Pa.s": dict(kg="1", m="-1", s="-1"), "N": dict(kg="1", m="1", s="-2"),
    "N.m": dict(kg="1", m="2", s="-2"), "m3/s": dict(m="3", s="-1"), "1": {},
    "N/m": dict(kg="1", s="-2"), "N.s/m": dict(kg="1", s="-1"),
}


def fmu_parameter_message(line: str) -> str:
    """A line of BearingParams' ValueError (``  BearingParams.h_init must be ...``) in the FMU's
    parameter names (``parameter 'solver_h_init' must be ...``)."""
    text = line.strip()
    if text.startswith("BearingParams: "):
        return text[len("BearingParams: "):]
    if text.startswith("BearingParams."):
        field, _, rest = text[len("BearingParams."):].partition(" ")
        for model_name, fmu_name in _FMU_NAME.items():      # h_min <= h_init <= h_max
            rest = rest.replace(f"{model_name} <=", f"{fmu_name} <=").replace(f"<= {model_name}", f"<= {fmu_name}")
        return f"parameter '{_FMU_NAME.get(field, field)}' {rest}"
    return text


def _tree_digest(folder: Path) -> str:
    """sha256 over the relative names and contents of the files under ``folder``
    (``__pycache__`` excluded: numba and Python write there)."""
    import hashlib
    h = hashlib.sha256()
    for f in sorted(p for p in folder.rglob("*") if p.is_file() and "__pycache__" not in p.parts):
        h.update(f.relative_to(folder).as_posix().encode() + b"\0" + f.read_bytes() + b"\0")
    return h.hexdigest()


def _private(path: Path) -> bool:
    """``path`` exists, is no symlink, belongs to this user and nobody else may write to it."""
    import stat
    try:
        st = path.lstat()
    except OSError:
        return False
    if stat.S_ISLNK(st.st_mode) or (hasattr(os, "getuid") and st.st_uid != os.getuid()):
        return False
    return not st.st_mode & (stat.S_IWGRP | stat.S_IWOTH)


def _cache_copy_ok(root: Path, base: Path, src: Path, package: str) -> bool:
    """Re-check a cached code copy on every use: the cache folders are private to this
    user (no one else could have planted code or numba cache files), and the copy has
    the same files as the FMU's bundled package."""
    for cache in [d for d in (base / package).rglob("__pycache__") if d.is_dir()]:
        if not _private(cache):                      # e.g. made under umask 002: its content is
            shutil.rmtree(cache, ignore_errors=True)  # not trusted, numba compiles once more
    dirs = [root, base] + [d for d in (base / package).rglob("*") if d.is_dir()] + [base / package]
    if not all(_private(d) for d in dirs):
        log.warning("the FMU code cache %s is not private to this user (owner or permissions); importing the "
                    "bundled code from the extracted FMU instead", base)
        return False
    return _tree_digest(base / package) == _tree_digest(src)


def use_stable_code_copy(resources: str | None, package: str = "bearing_fmu") -> Path | None:
    """Import ``package`` from a content-addressed copy instead of the extracted FMU.

    Every run extracts the FMU into a new temporary folder, which would defeat
    numba's on-disk cache (``cache=True`` stores compiled code next to the
    source and keys it by the source path): the film kernels would be
    recompiled on every run (5-10 s). So, once per source hash, the bundled
    package is copied to ``$ROTORCOSIM_FMU_CODE_CACHE`` (default
    ``$XDG_CACHE_HOME/rotorcosim/fmu-code`` or ``~/.cache/rotorcosim/fmu-code``)
    and that folder is put first on ``sys.path``. The copy is identical to the
    bundled sources (same hash as ``resources/rotorcosim_build.json``). Set
    ``ROTORCOSIM_FMU_CODE_CACHE=off`` to import from the extracted FMU instead.
    Nothing happens when ``package`` is already imported or the FMU has no
    build record (e.g. while the builder writes modelDescription.xml).
    """
    setting = os.environ.get("ROTORCOSIM_FMU_CODE_CACHE", "")
    if setting.lower() in ("off", "0", "no") or not resources or package in sys.modules:
        return None
    try:
        info = Path(resources) / "rotorcosim_build.json"
        src = Path(resources) / package
        if not info.is_file() or not src.is_dir():
            return None
        digest = json.loads(info.read_text())["source_sha256"][:20]
        root = Path(setting) if setting else (
            Path(os.environ.get("XDG_CACHE_HOME") or Path.home() / ".cache") / "rotorcosim" / "fmu-code")
        base = root / f"{package}-{digest}"
        if (base / ".complete").is_file() and not _cache_copy_ok(root, base, src, package):
            shutil.rmtree(base, ignore_errors=True)      # tampered or foreign: rebuilt below
            if base.exists():
                return None
        if not (base / ".complete").is_file():
            root.mkdir(mode=0o700, parents=True, exist_ok=True)
            tmp = root / f".{package}-{digest}.{os.getpid()}.tmp"
            shutil.rmtree(tmp, ignore_errors=True)
            shutil.copytree(src, tmp / package, ignore=shutil.ignore_patterns("__pycache__"))
            for d in [tmp, *(p for p in tmp.rglob("*") if p.is_dir())]:
                os.chmod(d, 0o700)                     # private: re-checked on every use
            (tmp / ".complete").write_text(digest + "\n")
            try:
                os.replace(tmp, base)          # atomic; fails if another process won the race
            except OSError:
                shutil.rmtree(tmp, ignore_errors=True)
            if not (base / ".complete").is_file() or not _cache_copy_ok(root, base, src, package):
                return None
            # keep the 5 newest copies of this package (one per source version)
            old = sorted(root.glob(f"{package}-*"), key=lambda d: d.stat().st_mtime, reverse=True)[5:]
            for d in old:
                shutil.rmtree(d, ignore_errors=True)
        sys.path.insert(0, str(base))
        return base
    except (OSError, ValueError, KeyError):    # read-only home, odd record: use the extracted copy
        return None


_STATE_ATTRS = {"fields_file": "fields_file"}     # saved with the FMU state besides the common part


@guard_callbacks
class JournalBearing(Fmi2Slave):
    """Hydrodynamic journal bearing (short/finite film on a (phi, z) grid).

    Parameters, inputs and outputs: see the tables at module level and
    ``docs/fmus.md``. Film force is the force of the oil film ON the journal.
    """

    author = "rotorcosim"
    description = ("Hydrodynamic journal bearing: Reynolds equation on the developed film, "
                   "half-Sommerfeld or mass-conserving two-phase cavitation, oil bath or free-to-air edges")
    version = "0.1.0"

    # PythonFMU's get_real/set_real without the per-variable isinstance of an ABC (fmu_common.slave)
    get_real = fast_get_real
    set_real = fast_set_real

    def __init__(self, **kwargs: Any):
        super().__init__(**kwargs)
        self.code_dir = use_stable_code_copy(self.resources)
        self._values: dict[str, Any] = {}
        self._extra_types: dict[str, type] = {}
        self._model = None
        self._initialized = False          # exit_initialization_mode done
        self._init_key = None              # (params, inputs) the model was initialized with
        self._time = 0.0
        self._start_time = 0.0
        self.fields_file = ""
        units: set[str] = set()

        par = dict(causality=Fmi2Causality.parameter, variability=Fmi2Variability.fixed)
        for name, (default, unit, desc) in REAL_PARAMETERS.items():
            self._values[name] = float(default)
            self._register_real(name, unit, desc, **par)
            units.add(unit)
        for name, (default, desc) in INTEGER_PARAMETERS.items():
            self._values[name] = int(default)
            self.register_variable(Integer(
                name, description=desc, getter=self._getter(name),
                setter=self._param_setter(name, int), **par))
        for name, default, kind in self._extra_model_parameters():
            self._values[name] = default
            self._extra_types[name] = kind
            desc = (f"bearing model parameter '{RENAMED.get(name, name)}' (see bearing_fmu.model.BearingParams; "
                    "SI units)")
            if kind is float:
                self._register_real(name, None, desc, **par)
            elif kind is bool:
                self.register_variable(Boolean(
                    name, description=desc, getter=self._getter(name),
                    setter=self._param_setter(name, bool), **par))
            elif kind is str:
                self.register_variable(String(
                    name, description=desc, getter=self._getter(name),
                    setter=self._param_setter(name, str), **par))
            else:
                self.register_variable(Integer(
                    name, description=desc, getter=self._getter(name),
                    setter=self._param_setter(name, int), **par))
        self._values["init"] = "flooded"
        self.register_variable(String(
            "init", description=(
                "initial film of the mass-conserving model: 'flooded' (theta = 1, a run-up from rest) "
                "or 'stationary' (steady film at the initial inputs); ignored by half-Sommerfeld"),
            getter=self._getter("init"), setter=self._param_setter("init", str), **par))
        self.register_variable(String(
            "fields_file", description=(
                "if not empty: at fmi2Terminate write numpy.savez(fields_file, phi, z, p, theta, h, t, cavitation, p0) "
                "(arrays of JournalBearing.fields(); '{out_dir}' is substituted by the rotorcosim master)"),
            getter=lambda: self.fields_file, setter=self._set_fields_file, **par))
        self._values["linearize"] = 0
        self.register_variable(Integer(
            "linearize", description=(
                "N >= 1: output the film coefficients kxx..cyy (interface-Jacobian coupling, "
                "docs/stiff-coupling.md), recomputed every N-th step and held in between "
                "(1: every step); 0: outputs 0, no extra cost"),
            getter=self._getter("linearize"), setter=self._param_setter("linearize", int), **par))

        for name, (unit, desc) in INPUTS.items():
            self._values[name] = 0.0
            self._register_real(name, unit, desc, causality=Fmi2Causality.input,
                                variability=Fmi2Variability.continuous)
            units.add(unit)
        for name, (unit, desc) in OUTPUTS.items():
            self._values[name] = 0.0
            self.register_variable(RealU(
                name, unit=unit, description=desc, causality=Fmi2Causality.output,
                variability=Fmi2Variability.continuous, initial=Fmi2Initial.calculated,
                getter=self._output_getter(name)))
            units.add(unit)
        for name, (unit, desc) in LINEARIZATION_OUTPUTS.items():
            self._values[name] = 0.0
            self.register_variable(RealU(
                name, unit=unit, description=desc, causality=Fmi2Causality.output,
                variability=Fmi2Variability.continuous, initial=Fmi2Initial.calculated,
                getter=self._output_getter(name)))
            units.add(unit)
        self.register_variable(RealU(
            "t_film", unit="s", description="film (model) time [s]",
            causality=Fmi2Causality.local, variability=Fmi2Variability.continuous,
            initial=Fmi2Initial.calculated, getter=lambda: self._time))
        self._values["linearize_tol"] = 0.0
        self._register_real("linearize_tol", "1", (
            "with linearize >= 1: a due refresh of kxx..cyy is skipped while the inputs stay "
            "within this distance of those of the last refresh (max of |dx|, |dy| / g, |dvx|, "
            "|dvy| / (g max(|omega|, 1000/s)), |domega| / max(|omega|, 1/s), g = C (1 - eps) the "
            "smallest gap there, at least 0.01 C); 0: no skipping"),
                            causality=Fmi2Causality.parameter, variability=Fmi2Variability.fixed)
        units.add("s")
        check_shipped_layout(self)
        UNITS.setdefault("s", dict(s="1"))
        self._units = units

    # -- registration helpers -------------------------------------------------
    def _register_real(self, name: str, unit: str | None, desc: str, **kw: Any) -> None:
        setter = (self._param_setter(name, float) if kw.get("causality") == Fmi2Causality.parameter
                  else self._input_setter(name))
        self.register_variable(RealU(name, unit=unit, description=desc,
                                      getter=self._getter(name), setter=setter, **kw))

    # variable accessors (fmu_common.slave): read and write self._values
    _getter = value_getter
    _output_getter = output_getter
    _param_setter = param_setter
    _input_setter = input_setter

    def _set_fields_file(self, value: str) -> None:
        if value and "{out_dir}" not in str(value):     # refused now, not after the run (write_fields)
            fields_target(str(value))
        self.fields_file = str(value)

    def to_xml(self, model_options: dict[str, str] = dict()) -> Element:  # noqa: B006 (PythonFMU's signature)
        return finish_model_description(super().to_xml(model_options), self._units, UNITS, PARAMETER_RANGES,
                                        STRING_CHOICES)

    def _extra_model_parameters(self) -> list[tuple[str, Any, type]]:
        """Fields of ``BearingParams`` beyond the issue-5 ones, with their defaults.

        At run time: the ones declared in the FMU's modelDescription.xml (see
        :func:`shipped_parameters`); while building: from ``BearingParams``.
        """
        shipped = shipped_parameters(self.resources)
        if shipped is not None:
            fixed = set(REAL_PARAMETERS) | set(INTEGER_PARAMETERS) | {"init", "fields_file", "linearize", "linearize_tol"}
            return [(n, v, k) for n, v, k in shipped if n not in fixed]
        try:
            from bearing_fmu.model import BearingParams
        except ImportError:
            return []
        known = set(REAL_PARAMETERS) | set(INTEGER_PARAMETERS)
        extra = []
        for f in dataclasses.fields(BearingParams):
            if f.name in known or f.name.startswith("_"):
                continue
            name = _FMU_NAME.get(f.name, f.name)
            if name in INPUTS or name in OUTPUTS or name in ("fields_file", "init", "t_film"):
                raise NameError(f"BearingParams.{f.name} collides with the FMU variable {name!r}; "
                                "add it to journal_bearing.RENAMED")
            found = scalar_default(f)
            if found is not None:
                extra.append((name, found[1], found[0]))
        return extra

    # -- model ----------------------------------------------------------------
    def _params(self) -> dict[str, Any]:
        """Keyword arguments of ``BearingParams`` (model field names)."""
        names = list(REAL_PARAMETERS) + list(INTEGER_PARAMETERS) + list(self._extra_types)
        return {RENAMED.get(n, n): self._values[n] for n in names}

    def _inputs(self) -> tuple[float, ...]:
        return tuple(self._values[n] for n in INPUTS)

    def _ensure_model(self) -> None:
        """Build and initialize the model for the current parameters and inputs."""
        key = (tuple(sorted(self._params().items())), self._inputs(), self._values["init"])
        if self._model is not None and key == self._init_key:
            return
        from bearing_fmu.model import BearingParams
        from bearing_fmu.model import BearingModel as Model
        problems = [f"parameter '{name}' must be one of {', '.join(map(repr, choices))} (got {self._values[name]!r})"
                    for name, choices in STRING_CHOICES.items()
                    if name in self._values and self._values[name] not in choices]
        try:
            params = BearingParams(**self._params())
        except ValueError as exc:       # the model's message in the FMU's parameter names
            problems += [m for m in map(fmu_parameter_message, str(exc).splitlines()[1:])
                         if not any(m.startswith(f"parameter '{name}' ") for name in STRING_CHOICES)]
        if problems:
            raise ValueError(f"invalid parameters of the JournalBearing FMU instance "
                             f"'{getattr(self, 'instance_name', '?')}': " + "; ".join(problems)
                             + "; set them in the scenario (fmus.<instance>.parameters)")
        model = Model(params)
        model.linearized = bool(self._values["linearize"])
        model.initialize(*self._inputs(), init=self._values["init"])
        self._model = model
        self._init_key = key
        self._copy_outputs()

    def _copy_outputs(self) -> None:
        out = self._model.outputs
        missing = [n for n in REQUIRED_OUTPUTS if n not in out]
        if missing:
            raise KeyError(f"bearing model outputs lack {missing}; it provides {sorted(out)}")
        for name in OUTPUTS:
            self._values[name] = float(out.get(name, 0.0))
        refresh_coefficients(self, self._linearization, self._coefficients_hold)

    def _linearization(self):
        """(K, C) of the model now; remembers the inputs they belong to (``linearize_tol``)."""
        from bearing_fmu.linearize import linearization
        self._values["_lin_at"] = self._inputs()
        return linearization(self._model)

    def _coefficients_hold(self) -> bool:
        """True while the inputs are within ``linearize_tol`` of those of the last refresh
        (:func:`coefficients_moved`); always False with linearize_tol = 0."""
        tol = float(self._values.get("linearize_tol", 0.0))
        at = self._values.get("_lin_at")
        if not tol > 0.0 or at is None:
            return False
        return coefficients_moved(at, self._inputs(), self._model.c) <= tol

    # -- FMI life cycle --------------------------------------------------------
    setup_experiment = setup_experiment
    exit_initialization_mode = exit_initialization_mode

    def do_step(self, current_time: float, step_size: float) -> bool:
        check_step_start(self, current_time, step_size)
        if step_size <= 0.0:
            raise ValueError(f"step_size must be > 0 (got {step_size!r})")
        try:
            # a step that raises leaves the model as it was (BearingModel.step)
            self._model.step(step_size, *self._inputs())
        except Exception as exc:  # the film could not be advanced: Discard, keep the state at t
            if not _is_numerical_failure(exc):
                raise
            self.log(f"bearing step t={current_time:.9g} dt={step_size:.3g} failed: {exc}",
                     Fmi2Status.discard)
            return False
        self._copy_outputs()
        self._time = current_time + step_size
        return True

    def terminate(self):
        if self.fields_file and self._model is not None:
            import numpy as np
            fields = self._model.fields()
            write_fields(self.fields_file, t=np.float64(self._time), **{k: np.asarray(v) for k, v in fields.items()})

    # -- FMU state --------------------------------------------------------------
    def _get_fmu_state(self) -> dict[str, Any]:
        return get_slave_state(self, _STATE_ATTRS)

    def _set_fmu_state(self, state: dict[str, Any]) -> None:
        set_slave_state(self, state, _STATE_ATTRS)

    _fmu_state_to_bytes = staticmethod(state_to_bytes)
    _fmu_state_from_bytes = staticmethod(state_from_bytes)


def fields_target(name: str):
    """The path ``numpy.savez(name)`` writes (``.npz`` appended when missing) and its lstat (None
    when it does not exist yet); ValueError naming ``fields_file`` when it must not be replaced:
    an existing link, folder, device, or a file that is not a zip archive (an earlier .npz)."""
    import stat
    path = Path(name)
    if path.suffix != ".npz":
        path = path.with_name(path.name + ".npz")
    try:
        st = os.lstat(path)
    except FileNotFoundError:
        return path, None
    except OSError as exc:
        raise ValueError(f"fields_file {str(path)!r} cannot be checked ({exc}); choose another path") from None
    why = ("a symbolic link" if stat.S_ISLNK(st.st_mode) else "a folder" if stat.S_ISDIR(st.st_mode)
           else None if stat.S_ISREG(st.st_mode) else "not a regular file")
    if why is None and st.st_size:
        try:
            with open(path, "rb") as f:
                head = f.read(4)
        except OSError as exc:
            raise ValueError(f"fields_file {str(path)!r} cannot be read ({exc}); choose another path") from None
        if head != b"PK\x03\x04":
            why = "a file that is not a .npz archive"
    if why is not None:
        raise ValueError(f"fields_file {str(path)!r} exists and is {why}; it is not overwritten: "
                         "give the name of a new file or of an earlier fields file (e.g. '{out_dir}/fields.npz')")
    return path, st


def write_fields(name: str, **arrays) -> Path:
    """``numpy.savez(name, **arrays)`` that never destroys what it did not write; the path written.

    As numpy.savez, ``.npz`` is appended to a name without it, and missing folders are made.
    The file is written beside its target under a new temporary name (created exclusively,
    so with the mode ``open`` gives a new file) and renamed into place, so a reader never sees
    half a file (and a link made at the target after the check is replaced, not followed). An
    existing target is replaced only when it is a regular file that holds a zip archive (an
    earlier .npz; its mode is kept); anything else is refused (:func:`fields_target`): the
    parameter is untrusted scenario text, and ``/home/u/.bashrc`` must not be overwritten. The
    FMU checks the target when the parameter is set too, so a refusal comes before the run."""
    import secrets
    import stat

    import numpy as np
    path, st = fields_target(name)
    path.parent.mkdir(parents=True, exist_ok=True)
    tmp = path.with_name(f".{path.name}.{secrets.token_hex(6)}.part")
    fd = os.open(tmp, os.O_WRONLY | os.O_CREAT | os.O_EXCL | getattr(os, "O_NOFOLLOW", 0), 0o666)
    try:
        with os.fdopen(fd, "wb") as f:
            np.savez(f, **arrays)
        if st is not None:
            os.chmod(tmp, stat.S_IMODE(st.st_mode))
        os.replace(tmp, path)
    except BaseException:
        try:
            os.unlink(tmp)
        except OSError:
            pass
        raise
    return path


#: smallest gap (fraction of c) :func:`coefficients_moved` measures a distance in (eps >= 0.99)
GAP_FLOOR = 0.01


def coefficients_moved(at, now, c: float) -> float:
    """Distance of the inputs ``now`` = (x, y, vx, vy, omega) from ``at`` in the scale of the
    film coefficients: positions in units of the smallest gap at ``at``, g = c (1 - eps) (at
    least GAP_FLOOR c), velocities in units of g max(|omega|, 1000/s) (the gap's surface-speed
    scale; 1000/s at rest, as the linearization's t_ref = 1 ms), the speed relative to
    max(|omega|, 1/s); the maximum. The coefficients are smooth functions of these whose
    relative change is of the order of this distance (the short-bearing stiffness goes as
    (1 - eps)^-2, so its change over de is ~2 de / g), so holding them over a distance below
    ``linearize_tol`` changes them by about that fraction.

    Why the gap and not c: with c (before 2026-12-08) a hold of 0.01 let a journal at eps 0.985
    (on its shell, the run-ups from rest) move by 2/3 of its gap on coefficients of the start,
    through a contact stiffness that changes over the roughness (0.3 um = 0.022 c); the stale
    coefficients made the interface-Jacobian step oscillate, force alternating by +-10-20 N
    about a 29 N load from one 2-3 us step to the next; the error-controlled contact phase took
    1 417-3 292 steps (free to air, five runs at rtol 0.05 +- 1e-6), in units of the gap 866-966
    (docs/runups.md, "The contact phase")."""
    x0, y0, vx0, vy0, w0 = at
    x, y, vx, vy, w = now
    g = c * max(1.0 - math.hypot(x0, y0) / c, GAP_FLOOR)
    vs = g * max(abs(w), 1000.0)
    return max(abs(x - x0) / g, abs(y - y0) / g, abs(vx - vx0) / vs, abs(vy - vy0) / vs,
               abs(w - w0) / max(abs(w), 1.0))


def _is_numerical_failure(exc: Exception) -> bool:
    """True for 'cannot complete this step' failures (become fmi2Discard)."""
    if isinstance(exc, (FloatingPointError, ArithmeticError)):
        return True
    try:
        from bearing_fmu import model as _m
    except ImportError:
        return False
    kinds = tuple(getattr(_m, n) for n in ("StepFailed", "ConvergenceError")
                  if isinstance(getattr(_m, n, None), type))
    return bool(kinds) and isinstance(exc, kinds)
