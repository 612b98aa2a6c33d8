"""Per-signal tolerances and the interface-Jacobian error estimate of the error-controlled step.

Per-signal ``atol`` (``coupling.step_control.atol`` as a mapping)
----------------------------------------------------------------
A signal is a coupling input, named ``consumer.input`` (the history's column, the name
``summary.json`` ``step_control.limiting_signals`` uses: ``rotor.Fx_1``, not the producer's
``bearing1.Fx``). Each key is such a name or a glob pattern (:func:`fnmatch.fnmatchcase`). A
signal takes the value of the key equal to its name, else of the first pattern in file order
that matches it, else its default. ``.inf`` leaves the signal out of the error norm.

Default from the FMUs' ``nominal`` (:func:`signal_nominals`)
-----------------------------------------------------------
A signal no key names (or every signal, when ``atol`` is not given) gets ``rtol * nominal``
when the FMUs declare a ``nominal`` for it (FMI 2.0, sec. 2.2.7: the nominal value of a
variable, for scaling): a change of rtol times the signal's typical size is within
tolerance, also where the signal passes zero, the rule of model-exchange importers for state
tolerances (OpenModelica, Dymola: atol_i = rtol * nominal_i). The nominal is the producer's
output's, times |gain| of the connection; where the output declares none, the consumer input's.
A signal without a nominal gets 1e-8 when ``atol`` is a mapping that does not name it; when
``atol`` is not given at all it gets ``max(1e-8, rtol * s)`` instead, s the largest |y| of the
signal at accepted step ends so far and at the start of the attempt (:func:`running_scale_mask`
selects them, ``ErrorControlled.error`` applies it): a signal that passes through zero is held
to rtol times the size it has had, not to 1e-8 in its own units (a practically relative test
whose step followed every zero crossing: two crane-fmu oscillators in a loop, rtol 1e-3, took
18 092 steps with 1e-8 and 5 136 with the running scale, error against a fine reference
1.3e-4 and 3.8e-4 of the amplitude). An explicit number ``atol: 1.0e-6`` applies to every
signal as before (nominals and running scale unused).

One scale for a force vector (:func:`force_vectors`)
----------------------------------------------------
The components ``U.Fx_i``, ``U.Fy_i`` of an interface-Jacobian force (below) that both take the
running scale share it: s is the largest length |(Fx, Fy)| so far, and an attempt's atol uses at
least the length at its start. A defect is judged against the force the rotor integrates, not
against one component's size: with a scale per component the first 60 ms of the free-to-air
run-up from rest (a journal on its shell, 29 N along y, a few newtons along x) held its x defects
15 times tighter than its y defects, and the error test changed with the turn of the frame
(docs/coupling.md, "One scale for a force vector").

Interface-Jacobian estimate
---------------------------
With interface-Jacobian coupling (docs/stiff-coupling.md; Kuebler & Schiehlen 2000;
Sicklinger et al. 2014; Schweizer & Lu 2015) the consumer of a force ``F_a,i`` (a = x, y at
station i) also receives the film coefficients ``k_ab,i = -dF_a/db``, ``c_ab,i = -dF_a/dv_b``
and applies over the step [T, T + H]

    F_used(t) = P_a(t) - sum_b k_ab (b(t) - b(T)) - sum_b c_ab (v_b(t) - v_b(T)),

where P is the order-k prediction and b, v_b its own outputs ``b_i``, ``vb_i`` (b = x, y).
The explicit predictor/corrector indicator (Busch & Schweizer, PAMM 10 (2010); Meyer, Kraft
& Schweizer, J. Comput. Nonlinear Dyn. 16 (2021) 041002) compares the input a subsystem
was *fed* with the coupling variable it turned out to be. Here the rotor was effectively fed
``F_used``, so the defect it integrated is

    d_a = F_a(T + H) - F_used(T + H)
        = F_a(T + H) - P_a(T + H) + sum_b k_ab(T) db + c_ab(T) dv_b,

db = b(T + H) - b(T). For a force linear in (b, v_b) with constant coefficients and k = 0
the defect is exactly 0 (the rotor integrated the exact force), for F = -k x - a x^2 it is
-a dx^2: the second-order remainder of the linearisation (plus the change of F through
quantities not linearised, e.g. the speed, and the change of k, c over the step), where the
raw prediction error F(T + H) - P(T + H) is first order in dx and overstates the error the
rotor saw by dx / (remainder). This module replaces the raw prediction of such a force by
``P - k db - c dv`` (the coefficients at T, what the rotor holds with k = 0); the
coefficients' own signals leave the norm (their effect on the rotor is in d). The
displacements db are the rotor's outputs as the history holds them (the connection
``rotor.x_i -> bearing.x``: gain and offset undone).
"""

from __future__ import annotations

import fnmatch
import math
import re
from collections.abc import Sequence

import numpy as np

DEFAULT_ATOL = 1.0e-8
FORCE_RE = re.compile(r"^F([xy])_(\w+)$")


def atol_vector(atol, names: list[str], *, rtol: float = 0.0,
                nominals: Sequence[float | None] | None = None) -> np.ndarray:
    """atol per column ``names`` (module docstring): a number for all, ((key, atol), ...), or
    None (not given). A signal no key names gets ``rtol * nominals[j]`` if that is given, else
    DEFAULT_ATOL."""
    if atol is not None and not isinstance(atol, (tuple, list)):
        return np.full(len(names), float(atol))
    nominals = nominals if nominals is not None else [None] * len(names)
    pairs = tuple(atol or ())
    table = dict(pairs)
    out = np.empty(len(names))
    for j, name in enumerate(names):
        nom = nominals[j]
        default = rtol * nom if (nom is not None and rtol > 0) else DEFAULT_ATOL
        if name in table:
            out[j] = table[name]
            continue
        out[j] = next((v for pat, v in pairs if fnmatch.fnmatchcase(name, pat)), default)
    return out


def running_scale_mask(atol, n: int, nominals: Sequence[float | None] | None = None) -> np.ndarray:
    """Which of ``n`` signals take ``atol = rtol * running scale`` (module docstring): all whose FMUs
    declare no nominal, when ``atol`` is not given at all (None); none when it is (a number or a
    mapping keep their meaning, 1e-8 included)."""
    if atol is not None:
        return np.zeros(n, dtype=bool)
    nominals = nominals if nominals is not None else [None] * n
    return np.array([nominals[j] is None for j in range(n)], dtype=bool)


def signal_nominals(names: list[str], connections, variable) -> list[float | None]:
    """The nominal of every column ``names`` (module docstring): ``variable(instance, name)``
    gives an FMU's :class:`~orchestrator.fmi.model_description.Variable` (or None); the producer
    output's ``nominal`` times |gain|, else the consumer input's, else None."""
    src = {}
    for c in connections:
        src.setdefault(c.dst, c)
    out: list[float | None] = []
    for name in names:
        nom = None
        c = src.get(name)
        if c is not None:
            inst, _, var = c.src.partition(".")
            v = variable(inst, var)
            if v is not None and v.nominal is not None and c.gain != 0:
                nom = abs(float(v.nominal) * float(c.gain))
        if nom is None:
            inst, _, var = name.partition(".")
            v = variable(inst, var)
            nom = None if v is None or v.nominal is None else abs(float(v.nominal))
        out.append(nom if nom is not None and math.isfinite(nom) and nom > 0 else None)
    return out


def jacobian_groups(names: list[str], connections) -> list[tuple[int, list[tuple[int, int, float]]]]:
    """The interface-Jacobian forces among the columns ``names``.

    Returns ``[(force column, [(coefficient column, kinematics column, 1 / gain), ...]), ...]``:
    a force input ``U.Fa_i`` counts when every ``U.kab_i``, ``U.cab_i`` (b = x, y) is a column
    and U's outputs ``b_i``, ``vb_i`` reach some column through a connection with gain != 0.
    """
    col = {n: j for j, n in enumerate(names)}
    via: dict[str, tuple[int, float, float]] = {}      # producer output -> (column, gain, offset)
    for c in connections:
        if c.dst in col and c.gain != 0 and c.src not in via:
            via[c.src] = (col[c.dst], float(c.gain), float(c.offset))
    groups = []
    for name, j in col.items():
        inst, _, var = name.rpartition(".")
        m = FORCE_RE.match(var)
        if not m:
            continue
        a, i = m.groups()
        terms = []
        for kind, kin in (("k", "{b}_{i}"), ("c", "v{b}_{i}")):
            for b in "xy":
                kc = col.get(f"{inst}.{kind}{a}{b}_{i}")
                u = via.get(f"{inst}.{kin.format(b=b, i=i)}")
                if kc is None or u is None:
                    break
                terms.append((kc, u[0], 1.0 / u[1]))
        if len(terms) == 4:
            groups.append((j, terms))
    return groups


def force_vectors(names: list[str], forces: Sequence[int], running: np.ndarray) -> np.ndarray:
    """The interface-Jacobian force vectors among the columns ``names`` (module docstring, "One
    scale for a force vector"): ``[[x columns], [y columns]]``, one pair ``U.Fx_i``, ``U.Fy_i``
    per consumer U and station i where both are in ``forces`` (columns of
    :func:`jacobian_groups`) and both take the running scale (``running``)."""
    col = {names[j]: j for j in forces if running[j]}
    pairs = []
    for name, jx in col.items():
        inst, _, var = name.rpartition(".")
        m = FORCE_RE.match(var)
        if m and m.group(1) == "x":
            jy = col.get(f"{inst}.Fy_{m.group(2)}")
            if jy is not None:
                pairs.append((jx, jy))
    return np.array(pairs, dtype=np.intp).reshape(-1, 2).T


def corrected_prediction(pred: np.ndarray, new: np.ndarray, prev: np.ndarray, groups) -> np.ndarray:
    """``pred`` with every interface-Jacobian force replaced by what the rotor applied at the
    step end: P - sum k (b(T+H) - b(T)) - sum c (v(T+H) - v(T)) (module docstring)."""
    out = pred.copy()
    for j, terms in groups:
        s = 0.0
        for kc, uc, inv_gain in terms:
            s += prev[kc] * (new[uc] - prev[uc]) * inv_gain
        out[j] -= s
    return out
