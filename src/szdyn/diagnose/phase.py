"""The wheel's initial phase: a per-recording initial condition the encoders do not measure.

Where the rollers first meet the band's circles depends on the wheel's angle at rest relative to
the circles, within one circle pitch (``2 pi / N_c``). Neither encoder reports it: both start
from zero. The impact bumps and the instant the band breaks away follow from it, so a model run
from the default offset misses a recording by the bumps of a wrong phase, which the noise floor
used to absorb as "unreproducible" (:func:`.noise.bump_noise`).

Measured on null 31 (docs/DIAGNOSIS-DESIGN.md, "The wheel's phase is estimated"): at the true
coefficients the smoothed band speed misses the six recordings by a median 0.008-0.012 rad/s
over a pitch of phases, and by 0.0054-0.0060 rad/s at the best phase of a 16-point scan, which
is the sensor noise (0.0041-0.0059); the best phase is the true one to 1/64 pitch, modulo the
half pitch by which this wheel (8 rollers, 100 circles) is symmetric; the same at the calibrated
coefficients. The phase is therefore estimated per recording, like an initial state in output-
error identification, on every recording, where the calibrated base is near the floor
(:data:`PHASE_GATE`). A held-out recording's phase is estimated again for each model judged on
it (the base and every refitted candidate): a phase estimated at a model that lacks an effect
is biased against the model that has it (encoder_delay seed 19: up to 0.12 pitch off).
"""
from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from .engine import rms

__all__ = ["PhaseEstimate", "estimate_phases", "identified_phases", "pitch_angle", "N_SCAN", "PHASE_UNCERTAINTY",
           "IDENTIFIED_SHARE", "PHASE_GATE"]

#: Phases scanned per circle pitch (then refined twice by halving the step around the best).
N_SCAN = 16
#: Uncertainty of the estimate in circle pitches, the shift :func:`.noise.bump_noise` uses for
#: an estimated phase: the scan resolves 1/64 pitch, but its RMSE is flat to a few per cent
#: within +-1/32 pitch of the minimum (null 31), so the phase is not known better than that.
PHASE_UNCERTAINTY = 1.0 / 32.0
#: The phase counts as identified where the scan's median squared RMSE exceeds its best by at
#: least this share of the model's own median squared change over the scan (the model at each
#: scanned phase against the model at the best): the recording's bumps then follow the model's.
#: Where no phase of the model reproduces them, the scan is flat against the model's change, and
#: the recording keeps the default offset and the quarter-pitch bump floor. (A missing effect
#: does not flatten it: it adds about the same to every phase.)
IDENTIFIED_SHARE = 0.25
#: The phases are estimated only where the calibrated base fits within this multiple of the
#: noise floor with quarter-pitch bumps. Farther off, a missing effect dominates the residual
#: and the scan aligns the model's bumps with it instead of with the recording's: on the test
#: suite's concealed viscous drag (base 12.5x) the phases estimated there left the named drag at
#: 2.4x the floor and 0.0142 rad/s held out, against 0.88x and 0.0073 without them. Cases that
#: far off are named without the phase; it matters near the floor, where it lowers the floor.
PHASE_GATE = 3.0


@dataclass(frozen=True)
class PhaseEstimate:
    """The initial wheel angle that fits one recording best.

    Attributes
    ----------
    q_w0 : float
        Initial wheel angle (rad).
    phase : float
        The same as a fraction of a circle pitch past the default offset, in [0, 1).
    rmse : float
        Residual RMS at ``q_w0`` (the model's residual units: rad/s, weighted as the model is).
    median_rmse : float
        Median residual RMS over the scan (its squares' median, square-rooted).
    model_spread : float
        How much the model itself changes over the scan: the median over the scanned phases of
        the RMS of (model at that phase - model at the best), same units.
    identified : bool
        ``median_rmse^2 - rmse^2 >= IDENTIFIED_SHARE * model_spread^2``.
    """

    q_w0: float
    phase: float
    rmse: float
    median_rmse: float
    model_spread: float
    identified: bool

    def to_dict(self) -> dict:
        return {"q_w0": self.q_w0, "phase_pitch": self.phase, "rmse": self.rmse,
                "median_rmse": self.median_rmse, "model_spread": self.model_spread,
                "identified": self.identified}


def pitch_angle(p) -> float:
    """One circle pitch as a wheel angle (rad): the period of the initial phase."""
    return 2.0 * math.pi / p.n_circles


def identified_phases(est: dict) -> dict:
    """Recording index -> initial wheel angle (rad) of the identified estimates of ``est``
    (index -> :class:`PhaseEstimate`): what ``FeatureModel.phases`` takes."""
    return {i: e.q_w0 for i, e in est.items() if e.identified}


def estimate_phases(model, base_changes: dict, which, *, n_scan: int = N_SCAN,
                    refine: int = 2) -> dict:
    """Estimate each recording's initial wheel angle at the model point ``base_changes``.

    Parameters
    ----------
    model : FeatureModel
    base_changes : dict or tuple of (dict, dict)
        Model parameter changes of the point (no ``q_w0``), or a whole point
        ``(model changes, sensor changes)`` (e.g. a candidate's with an encoder delay).
    which : sequence of int
        Recording indices.
    n_scan : int
        Phases scanned over one circle pitch.
    refine : int
        Halvings of the step around the best phase (each two runs per recording).

    Returns
    -------
    dict
        Recording index -> :class:`PhaseEstimate`.
    """
    out = {}
    for i in which:
        p = model.recordings[i].params
        off, pitch = p.default_wheel_offset(), pitch_angle(p)
        fracs = [k / n_scan for k in range(n_scan)]
        res = _residuals_at(model, i, base_changes, off, pitch, fracs)
        err = [rms(r) for r in res]
        k = int(np.argmin(err))
        best, best_err, best_res = fracs[k], err[k], res[k]
        step = 1.0 / n_scan
        for _ in range(refine):
            step /= 2.0
            near = [best - step, best + step]
            for f, r in zip(near, _residuals_at(model, i, base_changes, off, pitch, near)):
                if rms(r) < best_err:
                    best, best_err, best_res = f, rms(r), r
        median2 = float(np.median(np.square(err)))
        # the residuals differ by the model's change between phases (the data cancel)
        spread2 = float(np.median([rms(r - best_res) ** 2 for r in res]))
        frac = best % 1.0
        out[i] = PhaseEstimate(q_w0=off + frac * pitch, phase=frac, rmse=best_err,
                               median_rmse=math.sqrt(median2), model_spread=math.sqrt(spread2),
                               identified=bool(median2 - best_err ** 2 >= IDENTIFIED_SHARE * spread2
                                               and spread2 > 0.0))
    return out


def _residuals_at(model, i, base_changes, off, pitch, fracs) -> list:
    """Residuals of recording ``i`` with the wheel started ``fracs`` pitches past ``off`` (one
    batch of runs)."""
    mc, sc = base_changes if isinstance(base_changes, tuple) else (base_changes, {})
    pts = [({**mc, "q_w0": off + (f % 1.0) * pitch}, sc) for f in fracs]
    return list(model.residuals(pts, [i]))
