"""Residual tests: nominal false-alarm rates on noise, detection of periodic disturbances,
cross-correlation with inputs, and localisation by regime and band phase."""
from __future__ import annotations

import math

import numpy as np
from scipy.signal import lfilter, savgol_filter

from szdyn.residuals import (autocorrelation, cross_correlation, localise, ljung_box,
                             match_orders, phase_profile, regime_labels, spectral_peaks, thin,
                             uniform_residual, whiteness_test)

FS = 500.0
N = 2000
SEEDS = 300


def _rate(hits):
    return float(np.mean(hits))


def test_whiteness_false_positive_rate_is_nominal():
    hits = [whiteness_test(np.random.default_rng(s).normal(size=N), 20).p_value < 0.01
            for s in range(SEEDS)]
    # nominal 1 %; binomial sd over 300 seeds ~0.6 %
    assert _rate(hits) <= 0.035


def test_spectral_false_positive_rate_on_white_and_coloured_noise():
    white, coloured = [], []
    for s in range(SEEDS):
        e = np.random.default_rng(s).normal(size=N)
        white.append(bool(spectral_peaks(e, FS)[0]))
        coloured.append(bool(spectral_peaks(lfilter([1.0], [1.0, -0.9], e), FS)[0]))
    assert _rate(white) <= 0.035 and _rate(coloured) <= 0.035


def test_smoothed_residual_is_white_after_thinning():
    t = np.arange(20 * N) / FS
    hits = []
    for s in range(100):
        r = savgol_filter(np.random.default_rng(s).normal(size=t.size), 51, 2)
        _, rt = thin(t, r, 51 / FS)
        hits.append(whiteness_test(rt, 20).p_value < 0.01)
    assert _rate(hits) <= 0.05
    # unthinned, the smoothing alone fails the test
    assert whiteness_test(r, 20).p_value < 1e-6


def test_periodic_disturbance_is_detected_and_named():
    rng = np.random.default_rng(0)
    t = np.arange(4 * N) / FS
    band_rate = 1.6                                  # band revolutions per second
    theta_b = 2 * math.pi * band_rate * t
    r = rng.normal(size=t.size) + 0.5 * np.sin(theta_b + 0.3)
    w = whiteness_test(r, 25)
    assert not w.white and w.p_value < 1e-6 and w.n_outside > 0
    peaks, f, psd, floor = spectral_peaks(r, FS)
    assert peaks, "no peak found"
    df = f[1] - f[0]
    assert abs(peaks[0].freq - band_rate) <= df
    names = match_orders(peaks[0].freq, {"band revolution": band_rate,
                                         "wheel revolution": 2.3}, tol=df / band_rate)
    assert names and names[0][:2] == ("band revolution", 1)
    prof = phase_profile(theta_b, r, 2 * math.pi, 12)
    assert prof["p_value"] < 1e-6
    assert 0.35 < prof["amplitude"] < 0.65
    segs = localise(t, r, theta_b=theta_b, n_phase_bins=12)
    assert segs[0].kind == "phase_rev"


def test_phase_profile_false_positive_rate():
    t = np.arange(N) / FS
    theta_b = 2 * math.pi * 1.3 * t
    hits = [phase_profile(theta_b, np.random.default_rng(s).normal(size=N))["p_value"] < 0.01
            for s in range(SEEDS)]
    assert _rate(hits) <= 0.035


def test_cross_correlation_detects_lagged_dependence_and_not_independence():
    rng = np.random.default_rng(1)
    u = lfilter([1.0], [1.0, -0.95], rng.normal(size=N))          # strongly coloured state
    r = 0.3 * np.roll(u, 3) + lfilter([1.0], [1.0, -0.8], rng.normal(size=N))
    cc = cross_correlation(r, u, 20)
    assert not cc.independent and cc.worst_lag == 3
    hits = []
    for s in range(SEEDS):
        g = np.random.default_rng(10_000 + s)
        u = lfilter([1.0], [1.0, -0.95], g.normal(size=N))
        r = lfilter([1.0], [1.0, -0.8], g.normal(size=N))
        hits.append(cross_correlation(r, u, 20).p_value < 0.01)
    assert _rate(hits) <= 0.035


def test_localise_ranks_the_hold_phase_and_regime_labels():
    t = np.arange(0, 3.0, 1 / FS)
    omega_ref = np.interp(t, [0, 1.0, 2.0, 3.0], [0, 6.0, 6.0, 0.0])
    lab = regime_labels(t, omega_ref)
    assert lab[int(0.5 * FS)] == "ramp_up" and lab[int(1.5 * FS)] == "hold"
    assert lab[int(2.5 * FS)] == "ramp_down"
    rng = np.random.default_rng(2)
    r = 0.1 * rng.normal(size=t.size) + np.where(lab == "hold", 0.5, 0.0)
    segs = localise(t, r, omega=omega_ref)
    top = [s for s in segs if s.kind == "regime"][0]
    assert top.regime == "hold" and abs(top.t0 - 1.0) < 0.05 and abs(top.t1 - 2.0) < 0.05
    assert segs[0].score > 2 and top.z > 5
    d = top.to_dict()
    assert {"kind", "regime", "t0", "t1", "score"} <= set(d)


def test_basic_helpers():
    t = np.cumsum(np.random.default_rng(3).uniform(1e-3, 3e-3, 500))
    tu, ru = uniform_residual(t, np.sin(t))
    assert np.allclose(np.diff(tu), np.diff(tu)[0])
    lags, acf, band = autocorrelation(ru, 10)
    assert acf[0] == 1.0 and lags[-1] == 10 and 0 < band < 1
    q, dof, p = ljung_box(ru, 10, n_params=2)
    assert dof == 8 and p < 1e-6
