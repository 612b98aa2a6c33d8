"""TurbochargerRotor: FMI 2.0 co-simulation slave of the flexible turbocharger rotor (paper section 3.3).

A thin PythonFMU wrapper around :class:`rotor_fmu.turbocharger.TurbochargerRotor`
(Timoshenko shaft with gyroscopics, rigid compressor and turbine wheels,
Craig-Bampton reduction). The slave machinery is shared with the Jeffcott
FMU (:mod:`rotor_fmu.jeffcott_rotor`, see its docstring for why it is shared by
assigning functions rather than by inheritance).

Variables (see ``docs/fmus.md``)
--------------------------------
* parameters: the scalar fields of :class:`rotor_fmu.turbocharger.TurbochargerParams`
  (``f_max`` [Hz], ``t_ramp`` [s], ``g``, ``journal_x0``/``journal_y0``, ``reduce``, ``shear``,
  ...), String ``rotor_file`` (empty: the bundled ``rotor_fmu/data/turbocharger.yaml``;
  otherwise a path, absolute or relative to the importer's working directory; the
  file must define exactly two bearing stations) and Integer ``n_modes``
  (0: the rotor file's value);
* inputs ``Fx_1, Fy_1`` (compressor-side bearing), ``Fx_2, Fy_2`` (turbine side) [N];
* outputs ``x_i, y_i, vx_i, vy_i``, ``omega``, ``angle``, ``alpha`` and the wheel centres
  ``x_comp, y_comp, vx_comp, vy_comp, x_turb, y_turb, vx_turb, vy_turb`` (the disc names
  of the default rotor file; a rotor file with other disc names leaves these NaN), and
  ``x_disc<k>, y_disc<k>, vx_disc<k>, vy_disc<k>`` for the k-th disc of any rotor file
  (k = 1 ... ``N_DISC_OUTPUTS``; NaN beyond the file's discs): the motion of your own
  machine's discs (an e-machine core, a pump impeller) whatever they are called.
"""

from __future__ import annotations

import math
from pathlib import Path
from typing import Any

from pythonfmu import Fmi2Slave

from rotor_fmu import jeffcott_rotor as _slave

WHEELS = ("comp", "turb")
#: discs of any rotor file output by their place in the file: x_disc1 ... vy_disc<N>
N_DISC_OUTPUTS = 4


def _fields():
    from rotor_fmu.turbocharger import TurbochargerParams
    fields = _slave.scalar_fields(TurbochargerParams)
    fields.append(("rotor_file", "", str))
    fields.append(("n_modes", 0, int))
    return fields


def _model(params: dict[str, Any], t0: float):
    from rotor_fmu.turbocharger import TurbochargerParams, TurbochargerRotor as Model
    kw = dict(params)
    kw["rotor_file"] = kw.get("rotor_file") or None
    kw["n_modes"] = kw.get("n_modes") or None
    return Model(TurbochargerParams(**kw, t0=t0))


def _copy_outputs(self) -> None:
    out = self._model.outputs
    for name in self._output_names():
        self._values[name] = float(out.get(name, math.nan))
    for name in _slave.rotor_output_names(self)[:11]:      # station kinematics and speed: required
        if name not in out:
            raise KeyError(f"turbocharger model lacks output {name!r}")


@_slave.guard_callbacks
class TurbochargerRotor(Fmi2Slave):
    """Flexible turbocharger rotor with two journal bearings between the wheels."""

    author = "rotorcosim"
    description = ("Flexible turbocharger rotor (Timoshenko shaft with gyroscopics, rigid compressor and "
                   "turbine wheels, Craig-Bampton reduced), two journal bearings, kinematic speed ramp "
                   "(paper section 3.3)")
    version = "0.1.0"

    __init__ = _slave.rotor_init
    to_xml = _slave.rotor_to_xml
    setup_experiment = _slave.rotor_setup_experiment
    exit_initialization_mode = _slave.rotor_exit_initialization_mode
    do_step = _slave.rotor_do_step
    get_real = _slave.fast_get_real
    set_real = _slave.fast_set_real
    _get_fmu_state = _slave.rotor_get_fmu_state
    _set_fmu_state = _slave.rotor_set_fmu_state
    _fmu_state_to_bytes = staticmethod(_slave.state_to_bytes)
    _fmu_state_from_bytes = staticmethod(_slave.state_from_bytes)
    _output_names = _slave.rotor_output_names
    _ensure_model = _slave.rotor_ensure_model
    _copy_outputs = _copy_outputs
    _forces = _slave.rotor_forces

    @staticmethod
    def _parameter_fields():
        return _fields()

    @staticmethod
    def _extra_output_names() -> list[str]:
        wheels = list(WHEELS) + [f"disc{k}" for k in range(1, N_DISC_OUTPUTS + 1)]
        return [f"{c}_{w}" for w in wheels for c in ("x", "y", "vx", "vy")]

    def _make_model(self, params: dict[str, Any], t0: float):
        # the default rotor file from THIS instance's resources: a rotor_fmu imported by an earlier
        # instance in the same process points its DATA_DIR into that instance's extracted folder,
        # deleted when its run ended (two turbocharger runs in one process failed on the second)
        if not params.get("rotor_file") and self.resources:
            bundled = Path(self.resources) / "rotor_fmu" / "data" / "turbocharger.yaml"
            if bundled.is_file():
                params = {**params, "rotor_file": str(bundled)}
        from rotor_fmu.rotor_file import RotorFileError
        try:
            return _model(params, t0)
        except RotorFileError as exc:          # named as the FMU's parameter (the master traces it)
            raise RotorFileError(f"{exc.source} (parameter 'rotor_file')", exc.problems) from None
