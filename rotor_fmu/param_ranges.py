"""Accepted ranges of the rotor FMUs' parameters (JeffcottRotor, TurbochargerRotor).

One table for both places that check them: the FMUs declare them in modelDescription.xml
(``min``/``max``, so an importer refuses a value when it loads a scenario, with its file and
line) and :meth:`JeffcottParams.validate` / :meth:`TurbochargerParams.validate` check them when
the model is made (any importer). Wide enough for any machine from a micro turbine to a
turbogenerator; narrow enough that the model stays finite: ``k_shaft: 1e300`` made the linear
stability analysis report "already unstable" at any speed, ``max_phase_per_substep: 1e-300``
asked for 1e300 sub-steps per macro step. Plain Python: the FMUs import it while they are built.
"""

from __future__ import annotations

import math

#: name -> (lowest, highest or None, unit); inclusive, as FMI 2.0 min/max
RANGES: dict[str, tuple[float, float | None, str]] = {
    "m_disc": (1e-6, 1e6, "kg"),
    "m_journal": (1e-6, 1e6, "kg"),
    "k_shaft": (1.0, 1e13, "N/m"),
    "d_internal": (0.0, 1e9, "N s/m"),
    "d_external": (0.0, 1e9, "N s/m"),
    "unbalance": (0.0, 1e3, "kg m"),
    "unbalance_phase": (-2 * math.pi, 2 * math.pi, "rad"),
    "g": (0.0, 1e4, "m/s^2"),
    "f_max": (0.0, 1e5, "Hz"),
    "t_ramp": (0.0, 1e7, "s"),
    "journal_x0": (-1.0, 1.0, "m"),
    "journal_y0": (-1.0, 1.0, "m"),
    "journal_dx0_2": (-1.0, 1.0, "m"),
    "journal_dy0_2": (-1.0, 1.0, "m"),
    # sub-steps per macro step h: omega_max h / max_phase_per_substep (0.25 is a good value)
    "max_phase_per_substep": (1e-3, None, "rad"),
    "n_modes": (0, 500, ""),                     # rotor_file.MAX_MODES
}


def range_problems(params, cls_name: str) -> list[str]:
    """One line per field of ``params`` (a parameter dataclass) outside :data:`RANGES`."""
    problems = []
    for name, (lo, hi, unit) in RANGES.items():
        v = getattr(params, name, None)
        if v is None:
            continue
        try:            # a boolean is no number here (m_disc=True was a 1 kg disc)
            bad = isinstance(v, bool) or not (math.isfinite(v) and v >= lo and (hi is None or v <= hi))
        except TypeError:
            bad = True
        if bad:
            rng = f">= {lo:g}" + ("" if hi is None else f" and <= {hi:g}") + (f" {unit}" if unit else "")
            kind = "an integer " if isinstance(lo, int) else ""
            problems.append(f"{cls_name}.{name} must be {kind}{rng}{'' if kind else ' and finite'} (got {v!r})")
    return problems
