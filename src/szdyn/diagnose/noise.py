"""The noise floor: how close a correct model can come to a recording in the compared feature.

Two parts, both estimated without knowing the truth:

* **Sensor noise** of the measured smoothed band speed: the recording is split into its even
  and odd rows, two independent samplings of the same motion; the speed of each half is
  computed with the same filter and ``sigma_sensor = std(v_even - v_odd) / 2`` (each half has
  twice the variance of the whole, the difference four times).
* **Unreproducible impact bumps**: the model itself run twice with the wheel's initial offset
  shifted by a quarter of a circle pitch; the bumps' phase changes but not the physics, so
  ``sigma_bump = rms(v_1 - v_2) / sqrt(2)``. Where the recording's phase was estimated
  (:mod:`.phase`), the shift is the estimate's uncertainty instead (1/32 pitch): what remains
  unreproducible is the phase's uncertainty.

``floor = sqrt(sigma_sensor^2 + sigma_bump^2)`` (rad/s) is the RMSE a correct model would
reach; the diagnosis calls a mismatch significant only above it.

The smoothed motor torque (recordings with a current column) has a floor of its own, in N m,
made the same two ways (:func:`torque_sensor_noise`, :func:`torque_bump_noise`).
"""
from __future__ import annotations

import math

import numpy as np

from ..recordings import Recording, smoothed_current, speeds
from .data import Prepared, WINDOW_S
from .phase import PHASE_UNCERTAINTY

__all__ = ["sensor_noise", "bump_noise", "torque_sensor_noise", "torque_bump_noise"]


def _half_difference(p: Prepared, smoothed) -> float:
    """``std(f_even - f_odd) / 2`` at ``p.t_feat``, where ``smoothed(sub) -> (t, f)`` is the
    smoothed feature of a sub-recording of the even or the odd rows."""
    rec = p.rec
    halves = []
    for k in (0, 1):
        sub = Recording(name=rec.name, t=rec.t[k::2], theta_w=rec.theta_w[k::2],
                        theta_b=rec.theta_b[k::2],
                        current=None if rec.current is None else rec.current[k::2], conditions=rec.conditions)
        t, f = smoothed(sub)
        halves.append(np.interp(p.t_feat, t, f))
    return float(np.std(halves[0] - halves[1]) / 2.0)


def _shifted_pair(model, i: int, base_changes: dict, feature) -> float:
    """``rms(f_1 - f_2) / sqrt(2)`` of a model feature (``model.speeds`` or ``model.torques``)
    of recording ``i`` at ``base_changes`` and with the wheel shifted by a quarter pitch."""
    r = model.recordings[i]
    pitch = 2.0 * math.pi / r.params.n_circles
    if i in model.phases:
        # the phase was estimated (:mod:`.phase`): what is left is its uncertainty
        off = model.phases[i] + PHASE_UNCERTAINTY * pitch
    else:
        # a quarter of a circle pitch: half a pitch would land on the symmetric configuration
        off = r.params.default_wheel_offset() + 0.25 * pitch
    a, b = (feature([(mc, {})], [i])[0][0] for mc in (base_changes, {**base_changes, "q_w0": off}))
    return float(np.sqrt(np.mean((a - b) ** 2)) / math.sqrt(2.0))


def sensor_noise(p: Prepared, window_s: float = WINDOW_S) -> float:
    """Sensor noise of the smoothed band speed of one recording (rad/s)."""
    return _half_difference(p, lambda sub: speeds(sub, window_s)[::2])


def bump_noise(model, i: int, base_changes: dict) -> float:
    """Unreproducible part of the model's smoothed band speed for recording ``i`` (rad/s)."""
    return _shifted_pair(model, i, base_changes, model.speeds)


def torque_sensor_noise(p: Prepared, window_s: float = WINDOW_S) -> float:
    """Sensor noise of the smoothed motor torque of one recording (N m), from its even and odd
    rows as in :func:`sensor_noise`; the recording must have ``tau``."""
    return p.torque_constant * _half_difference(p, lambda sub: smoothed_current(sub, window_s))


def torque_bump_noise(model, i: int, base_changes: dict) -> float:
    """Unreproducible part of the model's smoothed motor torque for recording ``i`` (N m): the
    same two runs as :func:`bump_noise` (cached)."""
    return _shifted_pair(model, i, base_changes, model.torques)
