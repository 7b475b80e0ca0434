"""Recordings prepared for the diagnosis: drive, feature grid and measured feature.

What is compared
----------------
The impact model's fine-scale bumps are not reproducible sample by sample, so the diagnosis
compares the **smoothed band speed** ``omega_b`` (Savitzky-Golay derivative of ``theta_b``,
degree 2, window ``window_s`` = 0.1 s, which averages the impact bumps and keeps ramps of
~1 s), sampled every ``feature_dt`` = 0.05 s. Both sides share the measured wheel motion (the
model is driven by it), so this is the smoothed relative speed ``omega_w - omega_b`` up to the
common term ``omega_w``. Slip per revolution and stroke are reported before and after
(:func:`szdyn.compare.compare`), not fitted: they integrate the same signal.

When a recording has a ``current`` column and the manifest gives its torque constant, the
**smoothed motor torque** ``K_t * current`` (same filter, value instead of derivative) is
compared too, with the model's (:func:`szdyn.sensors.motor_torque`). The band speed
alone fixes the slider's forces only relative to each other (a friction and a load torque
both a third too large slip alike); the torque fixes their size.
"""
from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np

from ..drive import Sampled
from ..errors import UserInputError
from ..params import ParameterSet
from ..recordings import Recording, smoothed_current, speeds

__all__ = ["Prepared", "prepare", "WINDOW_S", "FEATURE_DT", "SIM_DT"]

#: smoothing window of the compared speeds (s)
WINDOW_S = 0.1
#: feature sampling step (s): half the window, so neighbouring samples overlap by half
FEATURE_DT = 0.05
#: output step of the model runs (s) on which the model's feature is computed
SIM_DT = 1e-3
#: longest recording the diagnosis takes (s). Every model run simulates each recording whole and
#: a diagnosis makes hundreds of runs, so an hour-long log would take days; no ramp test of the
#: actuator lasts that long, while a time column in ms from a logger at 10 kHz or more (which
#: passes the sampling check as a 10 Hz log) looks 1000 times longer than it is
MAX_DURATION_S = 3600.0


@dataclass
class Prepared:
    """One recording, ready for repeated comparison with the model.

    Attributes
    ----------
    name : str
    role : {"fit", "heldout"}
    params : ParameterSet
        Model parameters of this recording (defaults + manifest ``[model]`` + its conditions).
    drive : Sampled
        Measured wheel (or motor) speed, rad/s, on the recording's uniform grid.
    t0, t1 : float
        Time span simulated (s).
    t_feat : ndarray, shape (m,)
        Feature grid (s).
    y : ndarray, shape (m,)
        Measured smoothed band speed at ``t_feat`` (rad/s).
    omega_w : ndarray, shape (m,)
        Measured smoothed wheel speed at ``t_feat`` (rad/s).
    theta_b : ndarray, shape (m,)
        Measured band angle at ``t_feat`` (rad).
    rec : Recording
    tau : ndarray, shape (m,), or None
        Measured smoothed motor torque at ``t_feat`` (N m): ``torque_constant`` times the
        smoothed ``current``; None without a current column or a torque constant.
    torque_constant : float or None
        N m/A, from the manifest.
    """

    name: str
    role: str
    params: ParameterSet
    drive: Sampled
    t0: float
    t1: float
    t_feat: np.ndarray
    y: np.ndarray
    omega_w: np.ndarray
    theta_b: np.ndarray
    rec: Recording
    conditions: dict = field(default_factory=dict)
    tau: np.ndarray | None = None
    torque_constant: float | None = None

    @property
    def load_kg(self) -> float:
        return float(self.conditions.get("load_kg", math.nan))


def feature_grid(t0: float, t1: float, window_s: float = WINDOW_S, dt: float = FEATURE_DT):
    """Feature instants: every ``dt`` from half a window after the start to half before the end."""
    a, b = t0 + 0.5 * window_s, t1 - 0.5 * window_s
    n = int(math.floor((b - a) / dt + 1e-9)) + 1
    return a + dt * np.arange(max(n, 0))


def _too_short(name: str, duration: float, window_s: float) -> str:
    return (f"recording '{name}' is too short ({duration:.4g} s) for a speed window of {window_s:g} s: "
            "the diagnosis compares speeds smoothed over that window and needs at least one")


def prepare_one(rec: Recording, params: ParameterSet, role: str, *, window_s: float = WINDOW_S,
                feature_dt: float = FEATURE_DT, torque_constant: float | None = None) -> Prepared:
    """Prepare one recording (see :class:`Prepared`); ``torque_constant`` (N m/A) turns its
    ``current`` column, if any, into the measured motor torque ``tau``.

    Raises
    ------
    UserInputError
        If the recording is sampled too coarsely for the speed window (less than one sample in
        ``window_s``: a time column in ms read as s, for instance), lasts less than one
        window, or lasts more than :data:`MAX_DURATION_S`.
    """
    med = rec.sampling()["median_dt"]
    if med > window_s * (1 + 1e-9):   # one per window exactly passes, rounding aside
        # coarser logs (a 30 fps camera) are smoothed over a few samples instead; sparser ones
        # cannot show the speeds the diagnosis compares
        units = " Is the 't' column in seconds?" if med >= 0.5 else ""
        raise UserInputError(
            f"recording '{rec.name}' is sampled every {med:.3g} s (median): the diagnosis compares "
            f"speeds smoothed over {window_s:g} s and needs a sample every {window_s:g} s or "
            f"less.{units}")
    if rec.duration < window_s:
        raise UserInputError(_too_short(rec.name, rec.duration, window_s))
    if rec.duration > MAX_DURATION_S:
        raise UserInputError(
            f"recording '{rec.name}' lasts {rec.duration:.4g} s, more than {MAX_DURATION_S:g} s: every "
            "model run of the diagnosis simulates each recording whole, so this would take days. Is the "
            "'t' column in seconds (a log in ms looks 1000 times longer)? Otherwise split the log into "
            "runs of a few minutes, each a [[recording]] of the manifest")
    t, ww, wb = speeds(rec, window_s)
    drive = Sampled(t=t, omega=ww)
    t0, t1 = float(t[0]), float(t[-1])
    tf = feature_grid(t0, t1, window_s, feature_dt)
    if tf.size == 0:
        # (the resampled grid can end a little before the last sample): no compared instant lies
        # a half window from both ends, nor can a model run be filtered
        raise UserInputError(_too_short(rec.name, t1 - t0, window_s))
    tau = None
    if torque_constant is not None and rec.current is not None:
        tc, cur = smoothed_current(rec, window_s)
        tau = torque_constant * np.interp(tf, tc, cur)
    return Prepared(name=rec.name, role=role, params=params, drive=drive, t0=t0, t1=t1,
                    t_feat=tf, y=np.interp(tf, t, wb), omega_w=np.interp(tf, t, ww),
                    theta_b=np.interp(tf, rec.t, rec.theta_b - rec.theta_b[0]), rec=rec,
                    conditions=dict(rec.conditions), tau=tau,
                    torque_constant=None if tau is None else float(torque_constant))


def prepare(manifest, *, window_s: float = WINDOW_S, feature_dt: float = FEATURE_DT,
            base: ParameterSet | None = None) -> list:
    """Read and prepare every recording of a manifest (fit ones first, then held-out).

    Parameters
    ----------
    manifest : szdyn.manifest.Manifest
    base : ParameterSet, optional
        Starting parameters (default: built-in defaults); manifest overrides apply on top.

    Returns
    -------
    list of Prepared
    """
    out = []
    held = set(manifest.heldout)
    for e in manifest.entries:
        rec = e.read()
        out.append(prepare_one(rec, manifest.parameters(e, base), "heldout" if e.name in held else "fit",
                               window_s=window_s, feature_dt=feature_dt,
                               torque_constant=e.torque_constant))
    out.sort(key=lambda p: p.role != "fit")
    return out
