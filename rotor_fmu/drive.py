"""Kinematic speed drive of the rotor (paper section 2.1: the rotor is kinematically driven).

The spin speed is prescribed, never integrated: ``omega(t)``, ``angle(t)`` (its exact
integral) and ``alpha(t)`` (angular acceleration) are closed-form functions of time.

* :class:`RampProfile` - linear ramp ``f_start -> f_max`` over ``[0, t_ramp]``, then
  constant (the paper's 0 -> 800 Hz in 2 s and 0 -> 105 Hz in 7 s).
* :class:`TableProfile` - piecewise-linear speed table ``(t_i, f_i)`` (Hz), held
  constant outside the table; the angle is the exact piecewise-quadratic integral.

Units: t [s], frequencies f [Hz], omega [rad/s], angle [rad], alpha [rad/s^2].
Positive omega is counter-clockwise about +z (docs/dev/contracts.md).
"""

from __future__ import annotations

import math

import numpy as np

TWO_PI = 2.0 * math.pi


class RampProfile:
    """Linear speed ramp.

    ``f(t) = f_start + (f_max - f_start) * t / t_ramp`` for ``0 <= t <= t_ramp``,
    ``f_max`` after, ``f_start`` before 0.  ``t_ramp == 0`` gives constant ``f_max``.
    ``angle(0) = 0``.
    """

    def __init__(self, *, f_max: float, t_ramp: float, f_start: float = 0.0):
        if not (np.isfinite(f_max) and np.isfinite(t_ramp) and t_ramp >= 0.0):
            raise ValueError(
                f"RampProfile: expected finite f_max [Hz] and t_ramp >= 0 [s] "
                f"(got f_max={f_max!r}, t_ramp={t_ramp!r}); pass e.g. f_max=800.0, t_ramp=2.0")
        self.f_max = float(f_max)
        self.t_ramp = float(t_ramp)
        self.f_start = float(f_start) if t_ramp > 0.0 else float(f_max)
        self._w0 = TWO_PI * self.f_start
        self._w1 = TWO_PI * self.f_max
        self._a = (self._w1 - self._w0) / self.t_ramp if self.t_ramp > 0.0 else 0.0

    # All three accept a float (return a float) or an array of times (return an array).
    def omega(self, t):
        tc = np.clip(t, 0.0, self.t_ramp)
        return _out(self._w0 + self._a * tc, t)

    def alpha(self, t):
        ta = np.asarray(t, dtype=float)
        return _out(np.where((ta > 0.0) & (ta < self.t_ramp), self._a, 0.0), t)

    def angle(self, t):
        ta = np.asarray(t, dtype=float)
        tc = np.clip(ta, 0.0, self.t_ramp)
        ang = self._w0 * np.minimum(ta, self.t_ramp) + 0.5 * self._a * tc * tc
        ang = ang + self._w1 * np.maximum(ta - self.t_ramp, 0.0)
        return _out(ang, t)

    def table(self):
        """Piecewise-linear table (t, omega, angle at t) with constant extrapolation and
        angle(0) = 0, for the compiled stepping kernel."""
        if self.t_ramp > 0.0:
            t = np.array([0.0, self.t_ramp])
            w = np.array([self._w0, self._w1])
        else:
            t = np.array([0.0, 1.0])
            w = np.array([self._w1, self._w1])
        return t, w, np.array([self.angle(x) for x in t])

    def __repr__(self) -> str:
        return f"RampProfile(f_max={self.f_max}, t_ramp={self.t_ramp}, f_start={self.f_start})"


class TableProfile:
    """Piecewise-linear speed table ``t`` [s] (strictly increasing), ``f`` [Hz].

    Constant ``f[0]`` before ``t[0]`` and ``f[-1]`` after ``t[-1]``; ``angle(t[0]) = 0``
    is NOT assumed: ``angle(0) = 0`` and the angle is the exact integral from 0.
    """

    def __init__(self, *, t, f):
        t = np.asarray(t, dtype=float)
        f = np.asarray(f, dtype=float)
        if t.ndim != 1 or t.shape != f.shape or t.size < 2:
            raise ValueError(
                f"TableProfile: expected 1-D arrays t [s] and f [Hz] of equal length >= 2 "
                f"(got shapes {t.shape} and {f.shape}); pass t=[0, 2], f=[0, 800]")
        if not (np.all(np.isfinite(t)) and np.all(np.isfinite(f)) and np.all(np.diff(t) > 0)):
            raise ValueError(
                f"TableProfile: t must be finite and strictly increasing, f finite (got t={t}, f={f})")
        self.t_tab = t
        self.w_tab = TWO_PI * f
        self.slopes = np.diff(self.w_tab) / np.diff(t)
        # cumulative angle at the table points, measured from t = 0
        seg = 0.5 * (self.w_tab[1:] + self.w_tab[:-1]) * np.diff(t)
        self._cum = np.concatenate(([0.0], np.cumsum(seg)))
        self._offset = 0.0
        self._offset = self._raw_angle(0.0)

    def _raw_angle(self, t: float) -> float:
        """Exact integral of omega from t_tab[0] to t, minus the offset (angle(0) = 0)."""
        tt, w, cum = self.t_tab, self.w_tab, self._cum
        return self._raw_unshifted(t, tt, w, cum) - self._offset

    def _raw_unshifted(self, t, tt, w, cum):
        ta = np.asarray(t, dtype=float)
        i = np.clip(np.searchsorted(tt, ta, side="right") - 1, 0, tt.size - 2)
        dt = np.clip(ta, tt[0], tt[-1]) - tt[i]
        inside = cum[i] + w[i] * dt + 0.5 * self.slopes[i] * dt * dt
        return (inside + w[0] * np.minimum(ta - tt[0], 0.0)
                + w[-1] * np.maximum(ta - tt[-1], 0.0))

    def omega(self, t):
        return _out(np.interp(t, self.t_tab, self.w_tab), t)

    def alpha(self, t):
        tt = self.t_tab
        ta = np.asarray(t, dtype=float)
        i = np.clip(np.searchsorted(tt, ta, side="right") - 1, 0, tt.size - 2)
        return _out(np.where((ta > tt[0]) & (ta < tt[-1]), self.slopes[i], 0.0), t)

    def angle(self, t):
        return _out(self._raw_angle(t), t)

    def table(self):
        """Piecewise-linear table (t, omega, angle at t), see RampProfile.table."""
        return self.t_tab.copy(), self.w_tab.copy(), np.asarray(self.angle(self.t_tab))

    def __repr__(self) -> str:
        return f"TableProfile(t={self.t_tab.tolist()}, f={(self.w_tab / TWO_PI).tolist()})"


def _out(val, t):
    """float for scalar input, array for array input."""
    return float(val) if np.ndim(t) == 0 else np.asarray(val, dtype=float)


def make_profile(*, f_max: float, t_ramp: float, speed_table=None):
    """The profile a parameter set asks for: a table ``{"t": [...], "f": [...]}`` or
    ``((t...), (f...))`` if given, else the linear ramp."""
    if speed_table is None:
        return RampProfile(f_max=f_max, t_ramp=t_ramp)
    if isinstance(speed_table, dict):
        return TableProfile(t=speed_table["t"], f=speed_table["f"])
    t, f = speed_table
    return TableProfile(t=t, f=f)
