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

Optionally (``Diagnosis(coefficient_floor=step)``, ``--coefficient-floor``; off by default) the
bump part also counts the coefficients' uncertainty (:func:`coefficient_noise`): a light band
can keep bumping so that a model 1 % off in k_c or mu_k misses its bumps by 4-10 sensor floors
although its mean speed is right (docs/DIAGNOSIS-DESIGN.md, "Seed 64's 0.5 kg runs"), while the
phase's 1/32 pitch assumes coefficients exact enough to reproduce them. Measured on seed 64 (and
two cases of seed 61): at a step of 1 % it named one effect fewer, at 0.2 % the same ones; it
names no miss, since those are effects whose signal is at the floor (docs/DIAGNOSIS-DESIGN.md,
"A floor that counts the coefficients").

The smoothed motor torque (recordings with a current column) has a floor of its own, in N m,
made the same two ways (:func:`torque_sensor_noise`, :func:`torque_bump_noise`).

The common floor takes the median of the fit recordings' bump parts with each load counting
once (:func:`load_median`). The bumps depend on the load (on the benchmark's truths 0.5 kg
gave 0.013-0.039 rad/s and 1 kg 0.001-0.005), so a plain median over recordings moved to the
majority load's value as soon as one load had an extra recording.
"""
from __future__ import annotations

import math
from collections import Counter
from fractions import Fraction

import numpy as np
from scipy.ndimage import uniform_filter1d

from ..recordings import Recording, smoothed_current, speeds
from .data import Prepared, WINDOW_S
from .phase import PHASE_UNCERTAINTY

__all__ = ["sensor_noise", "bump_noise", "coefficient_noise", "fast_rms", "torque_sensor_noise", "torque_bump_noise",
           "load_median", "MAX_COEFFICIENT_STEP"]

#: window (s) of the running mean that parts a slow change of the model's speed, which a fit
#: sees and corrects, from a change in its bumps, which it cannot (:func:`coefficient_noise`)
SLOW_S = 0.5
#: the coefficients :func:`coefficient_noise` moves, each group by one factor: the contact
#: stiffness, and the slider friction with its static part (so that mu_s >= mu_k still holds)
COEFFICIENT_MOVES = (("k_c",), ("mu_k", "mu_s"))
#: largest relative step :func:`coefficient_noise` takes (``--coefficient-floor``); beyond it the
#: change is no longer a small uncertainty but another model
MAX_COEFFICIENT_STEP = 0.5


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


def fast_rms(change, dt: float, slow_s: float = SLOW_S) -> float:
    """RMS of ``change`` (shape (m,), uniform step ``dt`` s) beyond its running mean over ``slow_s``
    seconds (the ends padded with their nearest value)."""
    n = max(1, int(round(slow_s / dt)))
    return float(np.sqrt(np.mean((change - uniform_filter1d(change, n, mode="nearest")) ** 2)))


def coefficient_noise(model, i: int, base_changes: dict, step: float) -> float:
    """Bump part that a model ``step`` (relative) off in its coefficients leaves on recording
    ``i`` (rad/s).

    The model's smoothed band speed at ``base_changes`` and with each group of
    :data:`COEFFICIENT_MOVES` multiplied by ``1 + step`` (two more runs, at the recording's
    estimated phase): the fast part (:func:`fast_rms`) of each change, combined as an RMS. Only
    the fast part counts: a slow change is a mean speed the fit sees and corrects. No ``sqrt(2)``
    as in :func:`bump_noise`: the change is itself the error a model that far off makes.
    """
    r = model.recordings[i]
    points = [base_changes]
    for names in COEFFICIENT_MOVES:
        points.append({**base_changes, **{n: (1.0 + step) * base_changes.get(n, r.params[n]) for n in names}})
    base, *moved = (row[0] for row in model.speeds([(mc, {}) for mc in points], [i]))
    # (the feature grid is uniform; one compared instant has no fast part to speak of)
    dt = float(np.median(np.diff(r.t_feat))) if r.t_feat.size > 1 else SLOW_S
    return math.sqrt(float(np.mean([fast_rms(v - base, dt) ** 2 for v in moved])))


def torque_sensor_noise(p: Prepared, window_s: float = WINDOW_S) -> float:
    """Sensor noise of the smoothed motor torque of one recording (N m), from its even and odd
    rows as in :func:`sensor_noise`; the recording must have ``tau``."""
    return p.torque_constant * _half_difference(p, lambda sub: smoothed_current(sub, window_s))


def torque_bump_noise(model, i: int, base_changes: dict) -> float:
    """Unreproducible part of the model's smoothed motor torque for recording ``i`` (N m): the
    same two runs as :func:`bump_noise` (cached)."""
    return _shifted_pair(model, i, base_changes, model.torques)


def load_median(values, loads) -> float:
    """Median of per-recording values in which each load counts once.

    Each value is weighted by one over the number of values at its load, and the weighted
    median is taken with the plain median's convention (where the cumulative weight reaches
    exactly half, the mean of the two values either side). With the same number of values at
    every load this is ``np.median(values)`` exactly; adding recordings at one load only moves
    it within that load's share.

    Parameters
    ----------
    values : sequence of float, shape (n,)
        One value per recording (e.g. its impact-bump noise, rad/s).
    loads : sequence of float, shape (n,)
        Each recording's load (kg); NaN loads (not given) form one group.

    Returns
    -------
    float
    """
    values = [float(v) for v in values]
    if len(values) != len(loads) or not values:
        raise ValueError(f"load_median needs one load per value and at least one value "
                         f"(got {len(values)} values, {len(loads)} loads)")
    keys = [float(x) if math.isfinite(x) else None for x in loads]
    count = Counter(keys)
    # exact weights: the tie at exactly half must be recognised as the plain median does
    half = Fraction(len(count), 2)
    order = sorted(range(len(values)), key=values.__getitem__)
    cum = Fraction(0)
    for pos, j in enumerate(order):
        cum += Fraction(1, count[keys[j]])
        if cum == half:
            return (values[j] + values[order[pos + 1]]) / 2.0
        if cum > half:
            return values[j]
    raise AssertionError("unreachable: the weights sum to the number of loads")
