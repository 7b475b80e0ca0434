"""The thesis's findings (Lee 2021, ch. 4-5, Fig. 9/10) as computable pass/fail criteria.

The thesis states, for wheel-speed ramps ``omega = a t`` with ``a = 0.1 pi, 0.2 pi, 0.5 pi``
rad/s^2 (scenario ``thesis-fig10``: each ramp up to the same speed, then a hold):

(a) the band slips at constant wheel speed (not only while accelerating);
(b) the relative angular velocity is set by the wheel speed, hardly by the acceleration;
(c) the relative velocity does not decrease when the acceleration stops;
(d) the relative velocity rises with the wheel speed ("the change of the relative angular
    velocity in accordance with the angular velocity of the friction wheel").

:func:`evaluate_fig10` turns each statement into a number and a threshold. It is a pure function
of the columns ``t``, ``u_w``, ``u_b`` of each run (the CSV columns written by
:meth:`szdyn.simulate.Run.to_csv`) and of each run's ramp duration, so the verdict can be
recomputed from CSV files.

Smoothing (a choice). The impact model makes ``u_w - u_b`` bumpy: every time the rollers pass a
circle the band gets a kick. Pointwise comparisons ((b) matched wheel speeds and (d) rank
correlation) use a *centred moving average over a time window* (default 0.5 s: several
circle-passing periods at the relative speeds of interest, yet short against the 2-10 s ramps;
near the ends of the record the window shrinks to the available samples, so there is no
padding). Interval means ((a) hold mean, (c) last second of the ramp vs first second of the
hold) are computed from the raw samples: a mean over 1 s is itself a low-pass filter, and
smoothing first would leak ramp samples into the hold interval and vice versa. (c) compares the
hold mean with a straight-line fit of the last second of the ramp evaluated at its end, not with
the plain mean over that second (which lags whenever the relative speed rises with wheel speed).

Undefined quantities (too few samples, a zero denominator, a constant series) never produce
NaN: the criterion fails, its ``value`` is ``None`` and ``detail["reason"]`` says why.
"""
from __future__ import annotations

import math

import numpy as np

__all__ = [
    "DEFAULT_WINDOW", "moving_average", "classify_regime", "evaluate_fig10",
    "CRITERIA",
]

#: Default width (s) of the centred moving-average window.
DEFAULT_WINDOW = 0.5

#: Criterion keys of :func:`evaluate_fig10`, in the order (a)-(d).
CRITERIA = ("slip_at_constant_speed", "set_by_wheel_speed", "no_drop_after_ramp",
            "rises_with_wheel_speed")

_REQUIRED = ("t", "u_w", "u_b")


# --------------------------------------------------------------------------- helpers
def moving_average(t, x, window=DEFAULT_WINDOW):
    """Centred moving average of ``x`` over a time window.

    Parameters
    ----------
    t : array_like, shape (n,)
        Sample times in s, non-decreasing.
    x : array_like, shape (n,)
        Signal.
    window : float, optional
        Full window width in s (> 0). Sample ``i`` is replaced by the plain mean of all samples
        with ``|t_j - t_i| <= window / 2``; near the ends the window shrinks to what exists
        (no padding, no phase shift). For the uniform sampling of the simulator this is the
        usual boxcar filter.

    Returns
    -------
    numpy.ndarray, shape (n,)
        Smoothed signal (float64).

    Raises
    ------
    ValueError
        If ``window`` is not positive and finite, or ``t`` and ``x`` differ in length.
    """
    t = np.asarray(t, dtype=float).reshape(-1)
    x = np.asarray(x, dtype=float).reshape(-1)
    if t.size != x.size:
        raise ValueError(f"moving_average: t and x must have the same length, "
                         f"got {t.size} and {x.size}")
    if not (np.isfinite(window) and window > 0):
        raise ValueError(f"moving_average: window must be > 0 s, got {window!r}")
    if t.size == 0:
        return x.copy()
    cs = np.concatenate(([0.0], np.cumsum(x)))
    # tolerance so that round-off in t (e.g. np.arange) does not make the window lopsided
    eps = 1e-9 * (window + float(np.max(np.abs(t))))
    lo = np.searchsorted(t, t - 0.5 * window - eps, side="left")
    hi = np.searchsorted(t, t + 0.5 * window + eps, side="right")
    return (cs[hi] - cs[lo]) / (hi - lo)


def classify_regime(mean_wheel, mean_band, stick_tol=0.02, full_slip_ratio=0.2):
    """Regime of a hold at constant wheel speed from mean wheel and band speeds.

    Parameters
    ----------
    mean_wheel, mean_band : float
        Mean wheel and band angular velocities over the hold (rad/s).
    stick_tol : float, optional
        Relative speed below ``stick_tol * mean_wheel`` is "stick" (default 2 %).
    full_slip_ratio : float, optional
        Band speed below ``full_slip_ratio * mean_wheel`` is "full_slip" (default 20 %).

    Returns
    -------
    str
        ``"stick"``, ``"full_slip"``, ``"partial_slip"`` or ``"undefined"`` (wheel at rest or
        non-finite input).
    """
    if not (math.isfinite(mean_wheel) and math.isfinite(mean_band)) or mean_wheel <= 0:
        return "undefined"
    if mean_wheel - mean_band < stick_tol * mean_wheel:
        return "stick"
    if mean_band < full_slip_ratio * mean_wheel:
        return "full_slip"
    return "partial_slip"


def _f(x):
    """JSON-ready float, or None if not finite."""
    x = float(x)
    return x if math.isfinite(x) else None


def _result(passed, value, threshold, detail):
    if value is None or not math.isfinite(value):
        value, passed = None, False
    return {"passed": bool(passed), "value": None if value is None else float(value),
            "threshold": float(threshold), "detail": detail}


def _mean(x, mask):
    n = int(np.count_nonzero(mask))
    return (float(np.mean(x[mask])) if n else None), n


def _check_inputs(outputs_by_run, t_ramp_by_run):
    if not outputs_by_run:
        raise ValueError("evaluate_fig10: outputs_by_run is empty")
    if set(outputs_by_run) != set(t_ramp_by_run):
        raise ValueError("evaluate_fig10: outputs_by_run and t_ramp_by_run must have the same "
                         f"run names, got {sorted(outputs_by_run)} and {sorted(t_ramp_by_run)}")
    runs = {}
    for name, out in outputs_by_run.items():
        missing = [c for c in _REQUIRED if c not in out]
        if missing:
            raise ValueError(f"evaluate_fig10: run '{name}' lacks column(s) {missing}")
        cols = [np.asarray(out[c], dtype=float).reshape(-1) for c in _REQUIRED]
        if len({c.size for c in cols}) != 1:
            raise ValueError(f"evaluate_fig10: run '{name}': t, u_w, u_b differ in length")
        t, uw, ub = cols
        if np.any(np.diff(t) < 0):
            raise ValueError(f"evaluate_fig10: run '{name}': t must be non-decreasing")
        t_ramp = float(t_ramp_by_run[name])
        if not (math.isfinite(t_ramp) and t_ramp > 0):
            raise ValueError(f"evaluate_fig10: run '{name}': t_ramp must be > 0 s, "
                             f"got {t_ramp!r}")
        # non-finite samples (a failed run) are dropped; criteria then see fewer samples
        ok = np.isfinite(t) & np.isfinite(uw) & np.isfinite(ub)
        runs[name] = (t[ok], uw[ok], ub[ok], t_ramp, int(np.count_nonzero(~ok)))
    return runs


# --------------------------------------------------------------------------- criteria
def _crit_a(runs, hold_skip, stick_tol, band_min, min_samples):
    per_run, reasons = {}, []
    slips, bands = [], []
    for name, (t, uw, ub, t_ramp, _) in runs.items():
        m = t >= t_ramp + hold_skip
        mw, n = _mean(uw, m)
        mb, _ = _mean(ub, m)
        d = {"t_from": t_ramp + hold_skip, "t_to": _f(t[-1]) if t.size else None, "samples": n}
        if n < min_samples:
            reasons.append(f"{name}: only {n} hold samples after t_ramp + {hold_skip} s")
        elif not mw > 0:
            reasons.append(f"{name}: mean wheel speed over the hold is {mw:g} rad/s (not > 0)")
        else:
            slip, band = (mw - mb) / mw, mb / mw
            slips.append(slip)
            bands.append(band)
            d.update(mean_wheel=mw, mean_band=mb, mean_rel=mw - mb, rel_over_wheel=slip,
                     band_over_wheel=band, regime=classify_regime(mw, mb, stick_tol, band_min))
        per_run[name] = d
    detail = {"runs": per_run, "band_over_wheel_threshold": band_min, "hold_skip_s": hold_skip,
              "note": "value = smallest (mean rel. speed / mean wheel speed) over the runs' "
                      "holds; passes if value > threshold AND every band/wheel ratio > "
                      "band_over_wheel_threshold"}
    if reasons or not slips:
        detail["reason"] = "; ".join(reasons) or "no runs"
        return _result(False, None, stick_tol, detail)
    detail["min_band_over_wheel"] = min(bands)
    passed = min(slips) > stick_tol and min(bands) > band_min
    return _result(passed, min(slips), stick_tol, detail)


def _ramp_part(t, uw, rel_s, t_ramp):
    m = t <= t_ramp
    return uw[m], rel_s[m]


def _crit_b(runs, smoothed, grid_fractions, tol):
    reasons = []
    omega_end = {}
    curves = {}
    for name, (t, uw, ub, t_ramp, _) in runs.items():
        w, r = _ramp_part(t, uw, smoothed[name], t_ramp)
        if w.size < 2:
            reasons.append(f"{name}: fewer than 2 ramp samples")
            continue
        order = np.argsort(w, kind="stable")
        w, r = w[order], r[order]
        keep = np.concatenate(([True], np.diff(w) > 0))
        w, r = w[keep], r[keep]
        if w.size < 2:
            reasons.append(f"{name}: wheel speed does not vary over the ramp")
            continue
        curves[name] = (w, r)
        omega_end[name] = float(w[-1])
    detail = {"grid_fractions": [float(g) for g in grid_fractions]}
    if reasons or not curves:
        detail["reason"] = "; ".join(reasons) or "no runs"
        return _result(False, None, tol, detail)
    w_ref = min(omega_end.values())
    if not w_ref > 0:
        detail["reason"] = f"largest common ramp wheel speed is {w_ref:g} rad/s (not > 0)"
        return _result(False, None, tol, detail)
    grid = np.asarray(grid_fractions, dtype=float) * w_ref
    lo_common = max(float(w[0]) for w, _ in curves.values())
    if grid[0] < lo_common:
        detail["reason"] = (f"grid starts at {grid[0]:g} rad/s below a ramp's first wheel speed "
                            f"{lo_common:g} rad/s")
        return _result(False, None, tol, detail)
    vals = np.array([np.interp(grid, w, r) for w, r in curves.values()])
    mean = vals.mean(axis=0)
    span = vals.max(axis=0) - vals.min(axis=0)
    detail.update(omega_ref=w_ref, grid_omega=grid.tolist(),
                  rel_by_run={n: v.tolist() for n, v in zip(curves, vals)},
                  mean_rel=mean.tolist(),
                  note="spread = (max - min) / |mean| of the runs' smoothed rel. speeds at each "
                       "grid wheel speed (fractions of the smallest final ramp speed); value = "
                       "worst spread")
    if np.any(np.abs(mean) <= 1e-12):
        bad = grid[np.abs(mean) <= 1e-12]
        detail["reason"] = f"mean relative speed is 0 at wheel speed(s) {bad.tolist()} rad/s"
        return _result(False, None, tol, detail)
    spread = span / np.abs(mean)
    k = int(np.argmax(spread))
    detail.update(spread=spread.tolist(), worst_at_omega=float(grid[k]))
    return _result(spread[k] <= tol, float(spread[k]), tol, detail)


def _crit_c(runs, window_s, tol, min_samples):
    per_run, reasons, diffs = {}, [], []
    for name, (t, uw, ub, t_ramp, _) in runs.items():
        rel = uw - ub
        t0 = max(t_ramp - window_s, float(t[0]) if t.size else 0.0)
        m_ramp = (t >= t0) & (t <= t_ramp)
        before, nb_ = _mean(rel, m_ramp)
        after, na = _mean(rel, (t > t_ramp) & (t <= t_ramp + window_s))
        t_end = float(t[-1]) if t.size else t_ramp
        d = {"ramp_interval": [t0, t_ramp], "hold_interval": [t_ramp, min(t_ramp + window_s, t_end)],
             "samples_ramp": nb_, "samples_hold": na}
        # the hold's mean must cover the whole window: over a shorter one (a hold cut at 0.3 s,
        # say) it would measure another quantity than the criterion states (a ramp shorter than
        # the window is the whole ramp, and ramp_interval says so)
        spacing = float(np.median(np.diff(t))) if t.size > 1 else 0.0
        if t_end - t_ramp < window_s - spacing:
            reasons.append(f"{name}: the hold lasts {t_end - t_ramp:.3g} s, shorter than the {window_s:g} s "
                           "compared")
            per_run[name] = d
            continue
        if nb_ < min_samples or na < min_samples:
            reasons.append(f"{name}: too few samples ({nb_} ramp, {na} hold; need "
                           f"{min_samples})")
            per_run[name] = d
            continue
        tr = t[m_ramp]
        if np.ptp(tr) > 0:
            slope, icpt = np.polyfit(tr - t_ramp, rel[m_ramp], 1)
            end = float(icpt)
        else:
            slope, end = 0.0, before
        d.update(mean_rel_ramp_last=before, ramp_end_fit=end, ramp_slope=float(slope),
                 mean_rel_hold_first=after)
        if abs(end) > 1e-12:
            d["relative_change_vs_ramp_end_fit"] = (after - end) / abs(end)
        if abs(before) <= 1e-12:
            reasons.append(f"{name}: mean relative speed over the last second of the ramp is 0")
        else:
            change = (after - before) / abs(before)
            diffs.append(abs(change))
            d["relative_change"] = change
        per_run[name] = d
    detail = {"runs": per_run, "interval_s": window_s,
              "note": "value = largest |hold mean - ramp mean| / |ramp mean| over the runs (the "
                      "issue's definition): hold mean = mean raw rel. speed over the first "
                      "interval_s of the hold, ramp mean = over the last interval_s of the ramp. "
                      "When the rel. speed rises with wheel speed the ramp mean lags the value at "
                      "the ramp's end, so relative_change_vs_ramp_end_fit (a line fitted to the "
                      "last interval_s of the ramp, evaluated at its end) is reported too"}
    if reasons or not diffs:
        detail["reason"] = "; ".join(reasons) or "no runs"
        return _result(False, None, tol, detail)
    return _result(max(diffs) <= tol, max(diffs), tol, detail)


def _crit_d(runs, smoothed, threshold):
    from scipy.stats import spearmanr

    per_run, reasons, rhos = {}, [], []
    for name, (t, uw, ub, t_ramp, _) in runs.items():
        w, r = _ramp_part(t, uw, smoothed[name], t_ramp)
        d = {"samples": int(w.size)}
        if w.size < 3:
            reasons.append(f"{name}: fewer than 3 ramp samples")
        elif np.ptp(w) == 0 or np.ptp(r) == 0:
            reasons.append(f"{name}: wheel or relative speed constant over the ramp "
                           "(rank correlation undefined)")
        else:
            res = spearmanr(w, r)
            rho = float(res.statistic if hasattr(res, "statistic") else res[0])
            if not math.isfinite(rho):
                reasons.append(f"{name}: Spearman correlation undefined")
            else:
                rhos.append(rho)
                d["spearman_rho"] = rho
        per_run[name] = d
    detail = {"runs": per_run,
              "note": "value = smallest Spearman rank correlation between wheel speed and "
                      "smoothed rel. speed over the ramp (t <= t_ramp)"}
    if reasons or not rhos:
        detail["reason"] = "; ".join(reasons) or "no runs"
        return _result(False, None, threshold, detail)
    return _result(min(rhos) > threshold, min(rhos), threshold, detail)


def evaluate_fig10(outputs_by_run, t_ramp_by_run, *, window=DEFAULT_WINDOW, hold_skip=0.5,
                   stick_tol=0.02, band_min=0.2, spread_tol=0.2, grid_fractions=None,
                   drop_interval=1.0, drop_tol=0.2, rho_min=0.0, min_samples=10):
    """Check the thesis's four findings on the runs of scenario ``thesis-fig10``.

    Parameters
    ----------
    outputs_by_run : dict of str -> dict of str -> array_like
        Per run name, at least the columns ``t`` (s), ``u_w`` and ``u_b`` (rad/s), all of the
        same length, ``t`` non-decreasing (e.g. ``Run.outputs`` or a CSV read back). Other
        columns are ignored; rows with a non-finite value are dropped.
    t_ramp_by_run : dict of str -> float
        Ramp duration (s) of each run (same keys): the wheel accelerates on ``[0, t_ramp]`` and
        is held at constant speed afterwards.
    window : float, optional
        Width (s) of the centred moving average applied to ``u_w - u_b`` for (b) and (d).
    hold_skip : float, optional
        (a): the first ``hold_skip`` s of each hold are excluded (transient), default 0.5 s.
    stick_tol : float, optional
        (a): the mean relative speed over the hold must exceed ``stick_tol`` times the mean
        wheel speed (default 0.02) ...
    band_min : float, optional
        ... and the mean band speed must exceed ``band_min`` times it (default 0.2).
    spread_tol : float, optional
        (b): allowed (max - min)/|mean| of the runs' smoothed relative speeds at matched wheel
        speed (default 0.2).
    grid_fractions : array_like, optional
        (b): wheel speeds compared, as fractions of the smallest final ramp speed over the runs;
        default 0.20, 0.25, ..., 1.00.
    drop_interval : float, optional
        (c): length (s) of the intervals before and after the end of the ramp (default 1 s).
    drop_tol : float, optional
        (c): allowed |change| of the relative speed from the end of the ramp to the first
        ``drop_interval`` s of the hold, relative to the ramp-end value (default 0.2).
    rho_min : float, optional
        (d): the Spearman correlation must exceed this (default 0: positive).
    min_samples : int, optional
        Fewer samples than this in an averaging interval make the quantity undefined.

    Returns
    -------
    dict
        JSON-ready. Keys ``CRITERIA`` (``slip_at_constant_speed``, ``set_by_wheel_speed``,
        ``no_drop_after_ramp``, ``rises_with_wheel_speed``), each
        ``{"passed": bool, "value": float or None, "threshold": float, "detail": dict}``
        (``value`` is None, and ``passed`` False, only if the quantity is undefined;
        ``detail["reason"]`` then says why), plus ``"smoothing"`` (what was used) and
        ``"all_passed"``. No NaN or infinity anywhere.

    Raises
    ------
    ValueError
        If the run names of the two dicts differ, a run lacks a column, columns differ in length,
        ``t`` decreases or a ``t_ramp`` is not positive.

    Notes
    -----
    (a) slip at constant speed: per run, mean over ``t >= t_ramp + hold_skip`` of ``u_w - u_b``
    and of ``u_b`` relative to the mean ``u_w``. (b) set by wheel speed: smoothed relative speed
    on the ramp, interpolated at a common wheel-speed grid. (c) no drop after the ramp: raw mean
    of ``u_w - u_b`` over ``(t_ramp, t_ramp + 1]`` against the value at ``t_ramp`` of a straight
    line fitted to ``u_w - u_b`` over ``[t_ramp - 1, t_ramp]`` (the plain mean over the last
    second of the ramp lags when the relative speed rises with the wheel speed; it is reported in
    the detail). (d) rises with
    wheel speed: Spearman rank correlation of ``u_w`` and smoothed ``u_w - u_b`` on the ramp.
    """
    runs = _check_inputs(outputs_by_run, t_ramp_by_run)
    if grid_fractions is None:
        grid_fractions = np.round(np.arange(0.20, 1.0001, 0.05), 2)
    smoothed = {n: moving_average(t, uw - ub, window) for n, (t, uw, ub, _, _) in runs.items()}
    result = {
        "slip_at_constant_speed": _crit_a(runs, hold_skip, stick_tol, band_min, min_samples),
        "set_by_wheel_speed": _crit_b(runs, smoothed, grid_fractions, spread_tol),
        "no_drop_after_ramp": _crit_c(runs, drop_interval, drop_tol, min_samples),
        "rises_with_wheel_speed": _crit_d(runs, smoothed, rho_min),
    }
    result["smoothing"] = {
        "kind": "centred moving average (boxcar) of u_w - u_b over a time window; the window "
                "shrinks to the available samples at the ends of the record",
        "window_s": float(window),
        "used_for": ["set_by_wheel_speed", "rises_with_wheel_speed"],
        "raw_interval_means_for": ["slip_at_constant_speed", "no_drop_after_ramp"],
        "dropped_nonfinite_rows": {n: r[4] for n, r in runs.items()},
    }
    result["all_passed"] = all(result[c]["passed"] for c in CRITERIA)
    return _sanitize(result)


def _sanitize(obj):
    """Recursively convert NumPy scalars/arrays to Python types; non-finite floats to None."""
    if isinstance(obj, dict):
        return {str(k): _sanitize(v) for k, v in obj.items()}
    if isinstance(obj, (list, tuple, np.ndarray)):
        return [_sanitize(v) for v in obj]
    if isinstance(obj, (bool, np.bool_)):
        return bool(obj)
    if isinstance(obj, (int, np.integer)):
        return int(obj)
    if isinstance(obj, (float, np.floating)):
        return _f(obj)
    return obj
