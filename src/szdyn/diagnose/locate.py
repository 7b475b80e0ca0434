"""Where the calibrated model misses: time, regime, frequency, and what the residual follows.

Residual ``r = measured - model`` smoothed band speed (rad/s) on each recording's feature grid
(20 Hz). For each recording (:mod:`szdyn.residuals`, in the style of Ljung):

* **time and regime**: :func:`~szdyn.residuals.localise` segments (ramp up/down, hold,
  direction, wheel-speed bins, band-phase bins, time windows), scored by their RMS over the
  noise floor;
* **whiteness**: Ljung-Box on the residual thinned to one sample per smoothing window (a
  smoothed residual is never white at its own sampling);
* **cross-correlation** with the wheel speed (the input), prewhitened;
* **frequency**: spectral peaks below the smoothing cut-off, named as orders of the band and
  wheel revolution rates.

Across recordings, the residual is regressed on one physical feature at a time (band speed, its
sign, its acceleration, time, load, sin/cos of the band angle); the share of the residual's
energy each explains (R^2) says what the mismatch follows.
"""
from __future__ import annotations

import math

import numpy as np

from .. import residuals as R
from .data import FEATURE_DT, WINDOW_S

__all__ = ["locate", "follows", "feature_table", "FEATURES"]

#: Physical features the residual is compared with: name -> (unit, what it stands for).
FEATURES = {
    "band_speed": ("rad/s", "viscous drag, encoder scale"),
    "direction": ("1", "direction-dependent friction, a constant torque"),
    "band_accel": ("rad/s^2", "delays, compliance, inertia"),
    "time": ("s", "drift within a recording"),
    "load": ("kg", "load-dependent traction or lift"),
    "sin_band_angle": ("1", "once-per-revolution torque"),
    "cos_band_angle": ("1", "once-per-revolution torque"),
    "low_speed": ("1", "Stribeck friction: exp(-(omega_b / 0.5 rad/s)^2)"),
}


def feature_table(recs, speeds):
    """Per-sample physical features over all recordings (dict of name -> ndarray)."""
    cols = {k: [] for k in FEATURES}
    for p, v in zip(recs, speeds):
        acc = np.gradient(p.y, p.t_feat)
        cols["band_speed"].append(p.y)
        cols["direction"].append(np.sign(p.omega_w))
        cols["band_accel"].append(acc)
        cols["time"].append(p.t_feat - p.t0)
        cols["load"].append(np.full(p.y.shape, p.load_kg if math.isfinite(p.load_kg) else 0.0))
        cols["sin_band_angle"].append(np.sin(p.theta_b))
        cols["cos_band_angle"].append(np.cos(p.theta_b))
        cols["low_speed"].append(np.exp(-(p.y / 0.5) ** 2) * np.sign(p.omega_w))
    return {k: np.concatenate(v) for k, v in cols.items()}


def _r2(x, r):
    x = x - x.mean()
    sxx = float(x @ x)
    if sxx <= 0:
        return 0.0
    b = float(x @ (r - r.mean())) / sxx
    rr = r - r.mean()
    return float((b * b * sxx) / max(float(rr @ rr), 1e-300))


def locate(recs, speeds, *, floor: float, top: int = 8) -> dict:
    """Localise the residual of model speeds ``speeds`` against prepared recordings ``recs``.

    Parameters
    ----------
    recs : list of Prepared
    speeds : list of ndarray
        Model band speed at each recording's ``t_feat`` (rad/s).
    floor : float
        Noise floor (rad/s) used to score segments.
    top : int
        Segments kept in ``mismatch``.

    Returns
    -------
    dict
        ``recordings``: per recording RMSE, ratio to the floor, Ljung-Box, cross-correlation
        with the wheel speed, spectral peaks; ``mismatch``: segments ``{recording, t0, t1,
        regime, kind, score, mean}`` ranked by ``score = segment RMS / floor``; ``follows``:
        R^2 of the residual against each physical feature, largest first.
    """
    per, segs = [], []
    thin = max(1, int(round(WINDOW_S / FEATURE_DT)))
    for p, v in zip(recs, speeds):
        r = p.y - v
        rm = float(np.sqrt(np.mean(r * r)))
        item = {"recording": p.name, "role": p.role, "load_kg": p.load_kg, "rmse": rm,
                "ratio_to_floor": rm / floor if floor > 0 else math.inf}
        rt = r[::thin]
        if rt.size > 12:
            w = R.whiteness_test(rt, max_lag=min(20, rt.size // 4))
            item["whiteness"] = {"q": w.q, "dof": w.dof, "p_value": w.p_value, "white": w.white}
            try:
                c = R.cross_correlation(rt, p.omega_w[::thin], max_lag=min(10, rt.size // 6),
                                        prewhiten_order=min(5, rt.size // 10))
                item["xcorr_wheel_speed"] = {"p_value": c.p_value, "independent": c.independent,
                                             "worst_lag_s": c.worst_lag * thin * FEATURE_DT}
            except Exception as exc:  # too short or degenerate input: report, do not fail
                item["xcorr_wheel_speed"] = {"error": str(exc)}
        fs = 1.0 / FEATURE_DT
        peaks = []
        if r.size >= 64:
            try:
                found = R.spectral_peaks(r, fs, fmax=0.4 / WINDOW_S)[0]
            except Exception:
                found = []
            refs = {"band revolution": float(np.mean(np.abs(p.y))) / (2 * math.pi),
                    "wheel revolution": float(np.mean(np.abs(p.omega_w))) / (2 * math.pi)}
            for pk in found:
                peaks.append({"freq_hz": pk.freq, "ratio": pk.ratio, "p_value": pk.p_value,
                              "orders": [f"{o} x {n}" for n, o, _ in R.match_orders(pk.freq, refs)]})
        item["peaks"] = peaks
        per.append(item)
        for s in R.localise(p.t_feat, r, omega=p.omega_w, theta_b=p.theta_b, min_samples=4):
            segs.append({"recording": p.name, "t0": s.t0, "t1": s.t1, "regime": s.regime,
                         "kind": s.kind, "score": s.rms / floor if floor > 0 else math.inf,
                         "mean": s.mean, "rms": s.rms, "n": s.n})
    # rank contiguous segments (time-localised) first by how far above the floor they are
    segs.sort(key=lambda s: -s["score"])
    contiguous = [s for s in segs if s["kind"] in ("regime", "direction", "time")]
    return {"recordings": per, "mismatch": contiguous[:top], "segments_all": segs[:4 * top],
            "follows": follows(recs, speeds)}


def follows(recs, speeds) -> list:
    """R^2 of the residual against each physical feature (one at a time), largest first.

    Parameters
    ----------
    recs : list of Prepared
    speeds : list of ndarray
        Model band speed at each recording's ``t_feat`` (rad/s).

    Returns
    -------
    list of dict
        ``{feature, unit, suggests, r2}``, sorted by ``r2`` (share of the residual's energy about
        its mean that a straight-line fit on the feature explains, 0..1).
    """
    r_all = np.concatenate([p.y - v for p, v in zip(recs, speeds)])
    ft = feature_table(recs, speeds)
    return sorted(({"feature": k, "unit": FEATURES[k][0], "suggests": FEATURES[k][1],
                    "r2": _r2(ft[k], r_all)} for k in FEATURES), key=lambda d: -d["r2"])
