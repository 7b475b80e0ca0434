"""Wheel drive profiles.

Every profile is a piecewise-linear function given by knots ``(t_k, v_k)``; ``v`` is the wheel
speed in rad/s (``mode == "speed"``, model ``drive_mode = 0``) or the motor torque in N m
(``mode == "torque"``, ``drive_mode = 1``). Between knots ``v`` is linear, before the first and
after the last knot it is held constant. :meth:`to_array` packs the knots into the drive array of
docs/CONTRACT.md, ``[K, t_0..t_{K-1}, v_0..v_{K-1}, c_0..c_{K-1}]``, where ``c_k`` is the exact
(trapezoid) integral of ``v`` up to ``t_k`` plus ``angle0``, so the compiled ``drive_eval`` never
integrates anything at run time and the wheel angle is exactly the integral of its speed.

:meth:`evaluate` is a vectorised NumPy reference of the compiled ``drive_eval`` with the same
conventions (right-continuous acceleration: at an interior knot the slope of the following
segment is returned; at and after the last knot, and before the first, the acceleration is 0).
"""
from __future__ import annotations

from dataclasses import dataclass, field
from typing import ClassVar

import numpy as np

__all__ = ["DRIVE_MODES", "Ramp", "RampHold", "Trapezoid", "Sampled", "Torque",
           "knots_to_array", "array_to_knots", "evaluate_knots"]

#: Value of the model parameter ``drive_mode`` for each profile ``mode``.
DRIVE_MODES = {"speed": 0, "torque": 1}


# --------------------------------------------------------------------------- helpers
def _check_scalar(cls, name, value, *, positive=False, nonnegative=False, unit=""):
    """Return ``value`` as float or raise ValueError naming the class, argument and expectation."""
    try:
        v = float(value)
    except (TypeError, ValueError):
        raise ValueError(f"{cls}: {name} must be a real number{unit and f' ({unit})'}, "
                         f"got {value!r}") from None
    u = f" {unit}" if unit else ""
    if not np.isfinite(v):
        raise ValueError(f"{cls}: {name} must be finite, got {v:g}")
    if positive and not v > 0:
        raise ValueError(f"{cls}: {name} must be > 0{u}, got {v:g}")
    if nonnegative and not v >= 0:
        raise ValueError(f"{cls}: {name} must be >= 0{u}, got {v:g}")
    return v


def _check_series(cls, tname, t, vname, v):
    """Validate sampled knots; return read-only float64 copies ``(t, v)``."""
    try:
        t = np.array(t, dtype=float).reshape(-1) if np.ndim(t) <= 1 else None
        v = np.array(v, dtype=float).reshape(-1) if np.ndim(v) <= 1 else None
    except (TypeError, ValueError):
        raise ValueError(f"{cls}: {tname} and {vname} must be 1-D sequences of numbers") from None
    if t is None or v is None:
        raise ValueError(f"{cls}: {tname} and {vname} must be 1-D sequences of numbers")
    if t.size < 1:
        raise ValueError(f"{cls}: {tname} must have at least 1 sample, got 0")
    if t.size != v.size:
        raise ValueError(f"{cls}: {tname} and {vname} must have the same length, "
                         f"got {t.size} and {v.size}")
    bad = np.flatnonzero(~np.isfinite(t))
    if bad.size:
        raise ValueError(f"{cls}: {tname} must be finite, got {t[bad[0]]:g} at index {bad[0]}")
    bad = np.flatnonzero(~np.isfinite(v))
    if bad.size:
        raise ValueError(f"{cls}: {vname} must be finite, got {v[bad[0]]:g} at index {bad[0]}")
    bad = np.flatnonzero(np.diff(t) <= 0)
    if bad.size:
        i = bad[0] + 1
        raise ValueError(f"{cls}: {tname} must be strictly increasing, but {tname}[{i}] = "
                         f"{t[i]:g} <= {tname}[{i - 1}] = {t[i - 1]:g} (index {i})")
    t.flags.writeable = False
    v.flags.writeable = False
    return t, v


def knots_to_array(t_k, v_k, angle0=0.0):
    """Pack knots into the contract drive array.

    Parameters
    ----------
    t_k : array_like, shape (K,)
        Knot times in s, strictly increasing, K >= 1.
    v_k : array_like, shape (K,)
        Knot values: wheel speed in rad/s or motor torque in N m.
    angle0 : float
        Integral of ``v`` at ``t_0`` (initial wheel angle in rad for speed profiles).

    Returns
    -------
    drive : ndarray, shape (1 + 3K,)
        ``[K, t_0..t_{K-1}, v_0..v_{K-1}, c_0..c_{K-1}]`` with
        ``c_{k+1} = c_k + (t_{k+1} - t_k)(v_k + v_{k+1})/2`` (exact for piecewise-linear ``v``).
    """
    t_k = np.asarray(t_k, dtype=float)
    v_k = np.asarray(v_k, dtype=float)
    K = t_k.size
    c_k = np.empty(K)
    c_k[0] = angle0
    # cumsum of trapezoids: exact integral of the piecewise-linear speed between knots
    c_k[1:] = angle0 + np.cumsum(np.diff(t_k) * 0.5 * (v_k[1:] + v_k[:-1]))
    return np.concatenate(([float(K)], t_k, v_k, c_k))


def array_to_knots(drive):
    """Inverse of :func:`knots_to_array`: return ``(t_k, v_k, c_k)``, each shape (K,).

    Raises ValueError if ``drive`` does not have the contract layout.
    """
    drive = np.asarray(drive, dtype=float)
    if drive.ndim != 1 or drive.size < 4:
        raise ValueError(f"drive: expected a 1-D array of length 1 + 3K (K >= 1), "
                         f"got shape {drive.shape}")
    K = int(drive[0])
    if K < 1 or K != drive[0] or drive.size != 1 + 3 * K:
        raise ValueError(f"drive: drive[0] = {drive[0]:g} must be K >= 1 with "
                         f"len(drive) = 1 + 3K, got len {drive.size}")
    return drive[1:1 + K].copy(), drive[1 + K:1 + 2 * K].copy(), drive[1 + 2 * K:].copy()


def evaluate_knots(t_k, v_k, c_k, t):
    """Vectorised reference of ``drive_eval``: ``(integral, value, slope)`` at times ``t``.

    Parameters
    ----------
    t_k, v_k, c_k : ndarray, shape (K,)
        Knot times (s), values and cumulative integrals as in the drive array.
    t : float or array_like
        Evaluation times in s, any shape; outside ``[t_0, t_{K-1}]`` the value is held.

    Returns
    -------
    angle, speed, accel : ndarray (shape of ``t``) or float
        rad, rad/s, rad/s^2 for speed profiles (for torque: integral, N m, N m/s).
    """
    t_k = np.asarray(t_k, dtype=float)
    v_k = np.asarray(v_k, dtype=float)
    c_k = np.asarray(c_k, dtype=float)
    t = np.asarray(t, dtype=float)
    K = t_k.size
    if K == 1:
        speed = np.full(t.shape, v_k[0])
        accel = np.zeros(t.shape)
        angle = c_k[0] + (t - t_k[0]) * v_k[0]
    else:
        # segment lo with t_k[lo] <= t < t_k[lo+1] (right-continuous, like drive_eval)
        lo = np.clip(np.searchsorted(t_k, t, side="right") - 1, 0, K - 2)
        slope = (v_k[lo + 1] - v_k[lo]) / (t_k[lo + 1] - t_k[lo])
        inside = (t >= t_k[0]) & (t < t_k[-1])  # right-continuous at t_0 too
        before = t < t_k[0]
        accel = np.where(inside, slope, 0.0)
        speed = np.where(inside, v_k[lo] + slope * (t - t_k[lo]),
                         np.where(before, v_k[0], v_k[-1]))
        angle = np.where(inside, c_k[lo] + 0.5 * (t - t_k[lo]) * (v_k[lo] + speed),
                         np.where(before, c_k[0] + (t - t_k[0]) * v_k[0],
                                  c_k[-1] + (t - t_k[-1]) * v_k[-1]))
    if t.ndim == 0:
        return float(angle), float(speed), float(accel)
    return angle, speed, accel


# --------------------------------------------------------------------------- base class
class _Profile:
    """Shared behaviour; subclasses define :meth:`knots` and the class attribute ``mode``."""

    mode: ClassVar[str] = "speed"

    @property
    def drive_mode(self) -> int:
        """Value for the model parameter ``drive_mode`` (0 speed, 1 torque)."""
        return DRIVE_MODES[self.mode]

    def knots(self):
        """Return ``(t_k, v_k)``, float64 arrays of shape (K,): times in s and values."""
        raise NotImplementedError

    def to_array(self, angle0=0.0):
        """Contract drive array, shape (1 + 3K,); ``angle0`` is the wheel angle (rad) at t_0."""
        angle0 = _check_scalar(type(self).__name__, "angle0", angle0, unit="rad")
        return knots_to_array(*self.knots(), angle0=angle0)

    def evaluate(self, t, angle0=0.0):
        """``(angle, speed, accel)`` at times ``t`` (s); NumPy reference of ``drive_eval``."""
        return evaluate_knots(*array_to_knots(self.to_array(angle0)), t)


# --------------------------------------------------------------------------- profiles
@dataclass(frozen=True)
class Ramp(_Profile):
    """Thesis ramp: wheel speed ``omega = a t`` for ``0 <= t <= t_end``, held afterwards.

    Parameters
    ----------
    a : float
        Angular acceleration of the wheel in rad/s^2 (any sign).
    t_end : float
        Duration of the ramp in s (> 0).
    """

    a: float
    t_end: float

    def __post_init__(self):
        object.__setattr__(self, "a", _check_scalar("Ramp", "a", self.a, unit="rad/s^2"))
        object.__setattr__(self, "t_end", _check_scalar("Ramp", "t_end", self.t_end,
                                                        positive=True, unit="s"))

    def knots(self):
        return np.array([0.0, self.t_end]), np.array([0.0, self.a * self.t_end])


@dataclass(frozen=True)
class RampHold(_Profile):
    """Ramp ``omega = a t`` up to ``t_ramp``, then constant speed ``a t_ramp`` for ``t_hold``.

    Parameters
    ----------
    a : float
        Angular acceleration in rad/s^2 (any sign).
    t_ramp : float
        Ramp duration in s (> 0).
    t_hold : float
        Hold duration in s (>= 0). The speed is held after the last knot anyway; the hold knot
        only marks the intended end of the manoeuvre.
    """

    a: float
    t_ramp: float
    t_hold: float

    def __post_init__(self):
        object.__setattr__(self, "a", _check_scalar("RampHold", "a", self.a, unit="rad/s^2"))
        object.__setattr__(self, "t_ramp", _check_scalar("RampHold", "t_ramp", self.t_ramp,
                                                         positive=True, unit="s"))
        object.__setattr__(self, "t_hold", _check_scalar("RampHold", "t_hold", self.t_hold,
                                                         nonnegative=True, unit="s"))
        self.knots()   # refused when built, not at the first run

    def knots(self):
        w = self.a * self.t_ramp
        if self.t_hold == 0.0:
            return np.array([0.0, self.t_ramp]), np.array([0.0, w])
        return _distinct_times(np.array([0.0, self.t_ramp, self.t_ramp + self.t_hold]), np.array([0.0, w, w]),
                               "RampHold")


def _distinct_times(t, v, cls: str):
    """Knots ``(t, v)`` without a hold that rounding made zero long (1e-300 s after a 1 s ramp):
    two knots at one time with one speed are one knot. Two at one time with two speeds (a ramp so
    steep that it takes no time in floating point) would divide by zero in the slope: refused."""
    same = np.diff(t) <= 0
    jumps = np.flatnonzero(same & (np.diff(v) != 0))
    if jumps.size:
        i = int(jumps[0])
        raise ValueError(f"{cls}: the speed changes from {v[i]:g} to {v[i + 1]:g} rad/s in no time at "
                         f"t = {t[i]:g} s (an acceleration too large for the profile's times)")
    keep = np.append(~same, True)
    return t[keep], v[keep]


@dataclass(frozen=True)
class Trapezoid(_Profile):
    """Speed trapezoid: accelerate at ``a`` to ``omega_max``, hold ``t_hold``, decelerate to 0.

    Parameters
    ----------
    a : float
        Acceleration in rad/s^2 (> 0).
    omega_max : float
        Plateau speed in rad/s (> 0).
    t_hold : float
        Plateau duration in s (>= 0).
    a_down : float, optional
        Deceleration magnitude in rad/s^2 (> 0); defaults to ``a``.
    """

    a: float
    omega_max: float
    t_hold: float
    a_down: float | None = None

    def __post_init__(self):
        c = "Trapezoid"
        object.__setattr__(self, "a", _check_scalar(c, "a", self.a, positive=True,
                                                    unit="rad/s^2"))
        object.__setattr__(self, "omega_max", _check_scalar(c, "omega_max", self.omega_max,
                                                            positive=True, unit="rad/s"))
        object.__setattr__(self, "t_hold", _check_scalar(c, "t_hold", self.t_hold,
                                                         nonnegative=True, unit="s"))
        if self.a_down is not None:
            object.__setattr__(self, "a_down", _check_scalar(c, "a_down", self.a_down,
                                                             positive=True, unit="rad/s^2"))
        self.knots()   # refused when built (a ramp in no time), not at the first run

    def knots(self):
        a_down = self.a if self.a_down is None else self.a_down
        w = self.omega_max
        t1 = w / self.a
        t2 = t1 + self.t_hold
        t3 = t2 + w / a_down
        if self.t_hold == 0.0:
            return _distinct_times(np.array([0.0, t1, t3]), np.array([0.0, w, 0.0]), "Trapezoid")
        return _distinct_times(np.array([0.0, t1, t2, t3]), np.array([0.0, w, w, 0.0]), "Trapezoid")


@dataclass(frozen=True, eq=False)
class Sampled(_Profile):
    """Wheel speed from data, linearly interpolated, held outside the sampled range.

    Parameters
    ----------
    t : array_like, shape (K,)
        Sample times in s, finite and strictly increasing, K >= 1.
    omega : array_like, shape (K,)
        Wheel speed in rad/s at ``t``, finite.
    """

    t: np.ndarray = field(repr=False)
    omega: np.ndarray = field(repr=False)

    def __post_init__(self):
        t, v = _check_series("Sampled", "t", self.t, "omega", self.omega)
        object.__setattr__(self, "t", t)
        object.__setattr__(self, "omega", v)

    def __repr__(self):
        return f"Sampled(K={self.t.size}, t=[{self.t[0]:g}..{self.t[-1]:g}] s)"

    def knots(self):
        return self.t.copy(), self.omega.copy()


@dataclass(frozen=True, eq=False)
class Torque(_Profile):
    """Piecewise-linear motor torque (model ``drive_mode = 1``), held outside the knots.

    Parameters
    ----------
    t : array_like, shape (K,)
        Knot times in s, finite and strictly increasing, K >= 1.
    torque : array_like, shape (K,)
        Motor torque in N m at ``t``, finite.

    Notes
    -----
    The ``c`` entries of the drive array (unused by the model in torque mode) hold the torque
    integral, so ``evaluate`` returns ``(integral in N m s, torque in N m, dtorque/dt in N m/s)``.
    """

    t: np.ndarray = field(repr=False)
    torque: np.ndarray = field(repr=False)
    mode: ClassVar[str] = "torque"

    def __post_init__(self):
        t, v = _check_series("Torque", "t", self.t, "torque", self.torque)
        object.__setattr__(self, "t", t)
        object.__setattr__(self, "torque", v)

    def __repr__(self):
        return f"Torque(K={self.t.size}, t=[{self.t[0]:g}..{self.t[-1]:g}] s)"

    def knots(self):
        return self.t.copy(), self.torque.copy()
