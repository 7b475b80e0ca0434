"""Helical band geometry of the Spiral Zipper (thesis eqs 1-5) and the stroke cost of slip.

The band is a toothed strip wound into a helix: each wrap around a tube of diameter ``D`` rises
by ``H_B - H_T`` (band height minus tooth height, the teeth of neighbouring wraps interlock).
Thesis eqs 1-5 (model-notes section 3)::

    beta_I = asin((H_B - H_T) / (pi D))        helix incline angle            (1)
    P_B    = (H_B - H_T) / cos(beta_I)         band helix pitch               (2)
    P_T    = S_B / N                           band tooth pitch               (3)
    H      = L_B / S_B * P_B                   column height for band length  (4)
    S_B    = sqrt(P_B**2 + (pi D)**2)          arc length of one wrap         (5)

One band revolution extends the column by one pitch ``P_B``, so a band rotation ``q_b`` (rad)
is a stroke ``P_B q_b / (2 pi)`` and a wheel-band slip ``Delta theta`` (rad) is a stroke error
``P_B Delta theta / (2 pi)``.

All lengths are SI metres, angles radians.
"""
from __future__ import annotations

import math
import numbers
from dataclasses import dataclass

import numpy as np

from szdyn.errors import ParameterError, brief

__all__ = ["BandGeometry"]


#: a sanity cap on the teeth per wrap: 10000 on the thesis's 6 cm tube is a 19 um pitch (it has 24)
MAX_TEETH_PER_WRAP = 10_000


def _check_length(name: str, value) -> float:
    """Return ``value`` as float, or raise ParameterError unless it is a finite positive number."""
    if isinstance(value, bool) or not isinstance(value, numbers.Real):
        raise ParameterError(f"band geometry '{name}' must be a real number in m, got {value!r}")
    try:
        value = float(value)
    except OverflowError:       # a JSON integer beyond a float's range
        raise ParameterError(f"band geometry '{name}' must be finite, got an integer too large for "
                             "a float") from None
    if not math.isfinite(value):
        raise ParameterError(f"band geometry '{name}' must be finite, got {value!r}")
    if value <= 0.0:
        raise ParameterError(f"band geometry '{name}' must be > 0 m, got {value!r}")
    return value


def _as_finite_array(name: str, value, unit: str) -> np.ndarray:
    arr = np.asarray(value, dtype=np.float64)
    if not np.all(np.isfinite(arr)):
        raise ParameterError(f"'{name}' must be finite ({unit}), got non-finite entries")
    return arr


@dataclass(frozen=True)
class BandGeometry:
    """Geometry of the helically wound Spiral Zipper band (thesis Fig. 3, eqs 1-5).

    Parameters
    ----------
    band_height : float
        ``H_B``, height of the band strip including its teeth (m), > 0.
    tooth_height : float
        ``H_T``, height of the teeth that interlock with the neighbouring wrap (m),
        ``0 < H_T < H_B``.
    diameter : float
        ``D``, band (tube) diameter (m), > 0, with ``H_B - H_T < pi D``.
    teeth_per_wrap : int
        ``N``, number of teeth in one wrap, positive integer up to :data:`MAX_TEETH_PER_WRAP`.

    Raises
    ------
    ParameterError
        Naming the offending field when a value is non-finite or non-positive (or
        ``teeth_per_wrap`` beyond its cap), when
        ``tooth_height >= band_height`` or when ``band_height - tooth_height >= pi * diameter``
        (no real helix angle).
    """

    band_height: float
    tooth_height: float
    diameter: float
    teeth_per_wrap: int

    def __post_init__(self) -> None:
        hb = _check_length("band_height", self.band_height)
        ht = _check_length("tooth_height", self.tooth_height)
        dd = _check_length("diameter", self.diameter)
        n = self.teeth_per_wrap
        # (an int is compared as one: a JSON integer may lie beyond a float's range)
        if isinstance(n, bool) or not isinstance(n, numbers.Real) \
                or not (isinstance(n, int) or math.isfinite(float(n))) or n != int(n) or int(n) <= 0:
            raise ParameterError(
                f"band geometry 'teeth_per_wrap' must be a positive integer, got {brief(n)}")
        if int(n) > MAX_TEETH_PER_WRAP:
            raise ParameterError(f"band geometry 'teeth_per_wrap' must be at most {MAX_TEETH_PER_WRAP} "
                                 f"(the thesis's band has 24), got {brief(n)}")
        if ht >= hb:
            raise ParameterError(
                f"band geometry 'tooth_height' must be < band_height = {hb!r} m "
                f"(the wrap rise H_B - H_T must be positive), got {ht!r}")
        if hb - ht >= math.pi * dd:
            raise ParameterError(
                f"band geometry 'diameter' too small: the wrap rise band_height - tooth_height = "
                f"{hb - ht!r} m must be < pi * diameter = {math.pi * dd!r} m for a helix "
                f"angle to exist (eq 1), got diameter = {dd!r}")
        object.__setattr__(self, "band_height", hb)
        object.__setattr__(self, "tooth_height", ht)
        object.__setattr__(self, "diameter", dd)
        object.__setattr__(self, "teeth_per_wrap", int(n))

    # --- eqs 1, 2, 5, 3 -------------------------------------------------------------------
    @property
    def rise(self) -> float:
        """Axial rise per wrap ``H_B - H_T`` (m)."""
        return self.band_height - self.tooth_height

    @property
    def helix_angle(self) -> float:
        """Helix incline angle ``beta_I = asin((H_B - H_T) / (pi D))`` (rad), eq 1."""
        return math.asin(self.rise / (math.pi * self.diameter))

    @property
    def pitch(self) -> float:
        """Band helix pitch ``P_B = (H_B - H_T) / cos(beta_I)`` (m), eq 2.

        This is the column extension per band revolution.
        """
        return self.rise / math.cos(self.helix_angle)

    @property
    def wrap_length(self) -> float:
        """Arc length of one wrap ``S_B = sqrt(P_B**2 + (pi D)**2)`` (m), eq 5."""
        return math.hypot(self.pitch, math.pi * self.diameter)

    @property
    def tooth_pitch(self) -> float:
        """Band tooth pitch ``P_T = S_B / N`` (m), eq 3."""
        return self.wrap_length / self.teeth_per_wrap

    # --- eq 4 and stroke ------------------------------------------------------------------
    def column_height(self, band_length):
        """Column height ``H = L_B / S_B * P_B`` for a wound band length (eq 4).

        Parameters
        ----------
        band_length : float or array_like, shape (...)
            ``L_B``, length of band wound into the column (m), finite and >= 0.

        Returns
        -------
        float or numpy.ndarray, shape (...)
            Column height ``H`` (m); a Python float for scalar input.

        Raises
        ------
        ParameterError
            If any band length is negative or non-finite.
        """
        lb = _as_finite_array("band_length", band_length, "m")
        if np.any(lb < 0.0):
            raise ParameterError(f"'band_length' must be >= 0 m, got min {float(lb.min())!r}")
        h = lb * (self.pitch / self.wrap_length)
        return float(h) if h.ndim == 0 else h

    def stroke(self, q_b):
        """Column extension produced by a band rotation: ``P_B * q_b / (2 pi)``.

        Parameters
        ----------
        q_b : float or array_like, shape (...)
            Band rotation about the tube axis (rad), measured from the reference at which the
            stroke is zero; may be negative (retraction).

        Returns
        -------
        float or numpy.ndarray, shape (...)
            Stroke (m); a Python float for scalar input. One revolution (``2 pi``) gives
            exactly ``pitch``.
        """
        q = _as_finite_array("q_b", q_b, "rad")
        s = q * (self.pitch / (2.0 * math.pi))
        return float(s) if s.ndim == 0 else s

    def stroke_error(self, delta_theta):
        """Stroke error caused by a wheel-band slip angle: ``P_B * delta_theta / (2 pi)``.

        Parameters
        ----------
        delta_theta : float or array_like, shape (...)
            Slip angle of the band relative to rolling without slip, i.e. the band rotation
            lost (rad). Sign is preserved.

        Returns
        -------
        float or numpy.ndarray, shape (...)
            Stroke error (m); a Python float for scalar input.
        """
        dq = _as_finite_array("delta_theta", delta_theta, "rad")
        e = dq * (self.pitch / (2.0 * math.pi))
        return float(e) if e.ndim == 0 else e

    def to_dict(self) -> dict:
        """Return the four defining fields as a plain dict (SI units)."""
        return {"band_height": self.band_height, "tooth_height": self.tooth_height,
                "diameter": self.diameter, "teeth_per_wrap": self.teeth_per_wrap}
