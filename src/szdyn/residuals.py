"""Residual analysis in the style of Ljung (System Identification, 2nd ed., sec. 16.6).

A residual ``r(t)`` (measured minus simulated, e.g. of the smoothed relative speed) is
analysed on a **uniform** grid (:func:`uniform_residual`), because correlation and spectra
assume equally spaced samples. A residual of *smoothed* signals must first be thinned to the
smoothing window (:func:`thin`), otherwise the smoothing alone makes it non-white. What is
offered:

* **Whiteness**: :func:`autocorrelation` with the 99 % band ``+- z_{0.995} / sqrt(N)`` and
  :func:`whiteness_test` with the Ljung-Box statistic
  ``Q = N (N + 2) sum_{k=1}^{M} rho_k^2 / (N - k)``, compared with ``chi2(M - n_params)``.
* **Cross-correlation** with an input or state (:func:`cross_correlation`): the signal is
  prewhitened by a least-squares AR model and the residual filtered by the same filter (Box &
  Jenkins), so the band ``+- z / sqrt(N)`` and the statistic ``N sum rho_ru(k)^2 ~
  chi2(2M + 1)`` are valid although states are strongly autocorrelated.
* **Where** (:func:`localise`): residual statistics per regime segment (ramp up/down, hold,
  rest, from ``omega_ref`` or the wheel speed), direction, wheel-speed bin, band-angle phase bin
  (once per revolution and per tooth), and fixed time windows; a ranked list of
  :class:`Segment` ``{kind, regime, t0, t1, score, ...}``. :func:`phase_profile` tests
  whether the residual depends on an angle's phase.
* **Frequency** (:func:`spectral_peaks`): Welch spectrum (:func:`scipy.signal.welch`),
  background by a running median, peaks where the spectrum exceeds the background by the
  ``chi2`` quantile of the Welch estimate (Bonferroni over frequency bins), and
  :func:`match_orders` to name them (e.g. "1.00 x band revolution").

All functions take NumPy arrays; units are those of the inputs (time in s, frequency in Hz,
angles in rad).
"""
from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from scipy import signal, stats

from szdyn.errors import UserInputError

__all__ = [
    "uniform_residual", "thin", "autocorrelation", "ljung_box", "WhitenessResult", "whiteness_test",
    "CrossCorrelationResult", "cross_correlation", "Segment", "regime_labels",
    "direction_labels", "speed_bin_labels", "phase_bin_labels", "time_window_labels",
    "segment_stats", "localise", "phase_profile", "Peak", "welch_dof", "spectral_peaks",
    "match_orders",
]


def _as_1d(name, x):
    x = np.asarray(x, dtype=float)
    if x.ndim != 1:
        raise UserInputError(f"'{name}' must be one-dimensional, got shape {x.shape}")
    if not np.all(np.isfinite(x)):
        raise UserInputError(f"'{name}' contains NaN or infinity")
    return x


def uniform_residual(t, r, dt: float | None = None):
    """Resample a residual onto a uniform grid by linear interpolation.

    Parameters
    ----------
    t : array_like, shape (n,)
        Strictly increasing times (s), possibly uneven.
    r : array_like, shape (n,)
        Residual values.
    dt : float, optional
        Grid step (s); default the median interval.

    Returns
    -------
    tu : ndarray, shape (m,)
    ru : ndarray, shape (m,)
    """
    t = _as_1d("t", t)
    r = _as_1d("r", r)
    if t.shape != r.shape or t.size < 2 or np.any(np.diff(t) <= 0):
        raise UserInputError("t and r must have the same length >= 2 and t must increase")
    dt = float(np.median(np.diff(t))) if dt is None else float(dt)
    m = int(math.floor((t[-1] - t[0]) / dt + 1e-9)) + 1
    tu = t[0] + dt * np.arange(m)
    return tu, np.interp(tu, t, r)


def thin(t, r, step_s: float):
    """Resample a residual of *smoothed* signals at the smoothing window, for the tests here.

    Ljung's whiteness and spectral tests assume that, under a correct model, the residual is
    white. A residual of Savitzky-Golay speeds over ``window_s`` is not (neighbouring grid
    points share most of their window) but its samples ``window_s`` apart come from disjoint
    windows and are independent. Use ``step_s = window_s`` before :func:`whiteness_test`,
    :func:`cross_correlation` or :func:`spectral_peaks` on such a residual.

    Parameters
    ----------
    t, r : array_like, shape (n,)
        Time (s) and residual.
    step_s : float
        New uniform step (s).

    Returns
    -------
    tu, ru : ndarray, shape (m,)
    """
    return uniform_residual(t, r, step_s)


def _acf(x, max_lag):
    x = x - x.mean()
    n = x.size
    c0 = float(np.dot(x, x)) / n
    if c0 == 0.0:
        return np.r_[1.0, np.zeros(max_lag)]
    # FFT-based biased autocovariance
    nfft = 1 << (2 * n - 1).bit_length()
    f = np.fft.rfft(x, nfft)
    c = np.fft.irfft(f * np.conj(f), nfft)[: max_lag + 1] / n
    rho = c / c[0]
    rho[0] = 1.0
    return rho


def autocorrelation(r, max_lag: int = 25, alpha: float = 0.01):
    """Sample autocorrelation of a uniformly sampled residual.

    Parameters
    ----------
    r : array_like, shape (N,)
    max_lag : int
        Largest lag ``M`` (samples), ``1 <= M < N``.
    alpha : float
        Two-sided level of the band (0.01: 99 % band).

    Returns
    -------
    lags : ndarray of int, shape (M + 1,)
        0..M.
    acf : ndarray, shape (M + 1,)
        ``rho_k`` (biased estimator, ``rho_0 = 1``).
    band : float
        ``z_{1 - alpha/2} / sqrt(N)``: for white noise each ``rho_k`` (k >= 1) lies inside
        ``+- band`` with probability ``1 - alpha``.
    """
    r = _as_1d("r", r)
    max_lag = int(max_lag)
    if not 1 <= max_lag < r.size:
        raise UserInputError(f"max_lag must be in [1, {r.size - 1}], got {max_lag}")
    acf = _acf(r, max_lag)
    return np.arange(max_lag + 1), acf, float(stats.norm.ppf(1 - alpha / 2) / math.sqrt(r.size))


def ljung_box(r, max_lag: int = 25, n_params: int = 0):
    """Ljung-Box portmanteau statistic.

    ``Q = N (N + 2) sum_{k=1}^{M} rho_k^2 / (N - k)``, asymptotically ``chi2(M - n_params)``
    for white residuals.

    Parameters
    ----------
    r : array_like, shape (N,)
    max_lag : int
        ``M``.
    n_params : int
        Number of parameters estimated from the data the residual comes from (reduces the
        degrees of freedom; 0 for a pure validation residual).

    Returns
    -------
    q : float
    dof : int
    p_value : float
        ``P(chi2(dof) >= q)``.
    """
    r = _as_1d("r", r)
    _, acf, _ = autocorrelation(r, max_lag)
    n = r.size
    k = np.arange(1, max_lag + 1)
    q = float(n * (n + 2) * np.sum(acf[1:] ** 2 / (n - k)))
    dof = max_lag - int(n_params)
    if dof < 1:
        raise UserInputError(f"max_lag ({max_lag}) must exceed n_params ({n_params})")
    return q, dof, float(stats.chi2.sf(q, dof))


@dataclass
class WhitenessResult:
    """Result of :func:`whiteness_test`.

    Attributes
    ----------
    q, dof, p_value : float, int, float
        Ljung-Box statistic, degrees of freedom and p-value.
    alpha : float
        Test level.
    white : bool
        ``p_value >= alpha`` (no evidence against whiteness).
    lags, acf : ndarray, shape (M + 1,)
    band : float
        ``+-`` band of the autocorrelation at level ``alpha``.
    n_outside : int
        Lags ``k >= 1`` with ``|rho_k| > band``.
    worst_lag : int
        Lag ``k >= 1`` of the largest ``|rho_k|``.
    """

    q: float
    dof: int
    p_value: float
    alpha: float
    white: bool
    lags: np.ndarray
    acf: np.ndarray
    band: float
    n_outside: int
    worst_lag: int


def whiteness_test(r, max_lag: int = 25, alpha: float = 0.01, n_params: int = 0) -> WhitenessResult:
    """Test a uniformly sampled residual for whiteness (Ljung-Box + 99 % ACF band).

    Parameters
    ----------
    r : array_like, shape (N,)
    max_lag : int
        ``M`` (samples); Ljung suggests 20-25 or about N/4 for short records.
    alpha : float
        Level for both the test and the band.
    n_params : int
        See :func:`ljung_box`.

    Returns
    -------
    WhitenessResult
    """
    lags, acf, band = autocorrelation(r, max_lag, alpha)
    q, dof, p = ljung_box(r, max_lag, n_params)
    out = np.abs(acf[1:]) > band
    return WhitenessResult(q=q, dof=dof, p_value=p, alpha=alpha, white=p >= alpha, lags=lags,
                           acf=acf, band=band, n_outside=int(out.sum()),
                           worst_lag=int(1 + np.argmax(np.abs(acf[1:]))))


def _ar_prewhitener(u, order):
    """Least-squares AR(order) coefficients ``a`` so that ``A(q) u = u - sum a_k u(t-k)`` is ~white."""
    u = u - u.mean()
    n = u.size
    if order < 1 or n <= 4 * order:
        return np.zeros(0)
    X = np.column_stack([u[order - k: n - k] for k in range(1, order + 1)])
    y = u[order:]
    a, *_ = np.linalg.lstsq(X, y, rcond=None)
    return a


@dataclass
class CrossCorrelationResult:
    """Result of :func:`cross_correlation`.

    Attributes
    ----------
    lags : ndarray of int, shape (2M + 1,)
        ``-M..M``; positive lag ``k`` correlates ``r(t)`` with ``u(t - k)`` (the signal leads).
    ccf : ndarray, shape (2M + 1,)
        Normalised cross-correlation of the (prewhitened) pair.
    band : float
        ``z_{1 - alpha/2} / sqrt(N)``.
    stat, dof, p_value : float, int, float
        ``N sum_k ccf_k^2`` and its ``chi2(2M + 1)`` p-value.
    independent : bool
        ``p_value >= alpha``.
    worst_lag : int
        Lag of the largest ``|ccf|``.
    ar_order : int
        Order of the prewhitening AR filter used (0 = none).
    """

    lags: np.ndarray
    ccf: np.ndarray
    band: float
    stat: float
    dof: int
    p_value: float
    independent: bool
    worst_lag: int
    ar_order: int


def cross_correlation(r, u, max_lag: int = 25, alpha: float = 0.01,
                      prewhiten_order: int = 10) -> CrossCorrelationResult:
    """Cross-correlation of a residual with an input or state, with confidence band.

    Parameters
    ----------
    r : array_like, shape (N,)
        Residual, uniformly sampled.
    u : array_like, shape (N,)
        Input or state on the same grid (e.g. ``omega_ref``, wheel speed, band phase
        ``sin(theta_b)``).
    max_lag : int
        ``M`` (samples).
    alpha : float
        Level.
    prewhiten_order : int
        Order of the least-squares AR filter fitted to ``u`` and applied to both series
        (0 disables it; then the band is valid only if ``u`` or ``r`` is white).

    Returns
    -------
    CrossCorrelationResult
    """
    r = _as_1d("r", r)
    u = _as_1d("u", u)
    if r.shape != u.shape:
        raise UserInputError(f"r and u must have the same length, got {r.size} and {u.size}")
    a = _ar_prewhitener(u, int(prewhiten_order))
    if a.size:
        filt = np.r_[1.0, -a]
        uf = signal.lfilter(filt, [1.0], u - u.mean())[a.size:]
        rf = signal.lfilter(filt, [1.0], r - r.mean())[a.size:]
    else:
        uf, rf = u - u.mean(), r - r.mean()
    n = uf.size
    max_lag = int(max_lag)
    if not 1 <= max_lag < n:
        raise UserInputError(f"max_lag must be in [1, {n - 1}], got {max_lag}")
    su, sr = float(np.std(uf)), float(np.std(rf))
    lags = np.arange(-max_lag, max_lag + 1)
    if su == 0.0 or sr == 0.0:
        ccf = np.zeros(lags.size)
    else:
        full = signal.correlate(rf - rf.mean(), uf - uf.mean(), mode="full", method="fft")
        mid = n - 1
        ccf = full[mid - max_lag: mid + max_lag + 1] / (n * su * sr)
    band = float(stats.norm.ppf(1 - alpha / 2) / math.sqrt(n))
    stat = float(n * np.sum(ccf ** 2))
    dof = 2 * max_lag + 1
    p = float(stats.chi2.sf(stat, dof))
    return CrossCorrelationResult(lags=lags, ccf=ccf, band=band, stat=stat, dof=dof, p_value=p,
                                  independent=p >= alpha, worst_lag=int(lags[np.argmax(np.abs(ccf))]),
                                  ar_order=int(a.size))


# --------------------------------------------------------------------------- localisation
@dataclass
class Segment:
    """Residual statistics of one regime segment.

    Attributes
    ----------
    kind : str
        Family of the segmentation: ``regime``, ``direction``, ``speed``, ``phase_rev``,
        ``phase_tooth``, ``time`` (or a user key).
    regime : str
        Label within the family, e.g. ``ramp_up``, ``speed 1.0-2.0 rad/s``, ``phase 3/12``.
    t0, t1 : float
        First and last sample time (s). Contiguous families (regime, direction, time) give
        one segment per run of equal labels; the others pool all samples of a label.
    n : int
        Samples.
    mean, rms : float
        Mean and root-mean-square residual in the segment.
    score : float
        ``rms^2 / mean(r^2)``: share of residual energy per sample relative to the whole record
        (1 = average, > 1 = the mismatch concentrates here). Segments are ranked by it.
    z : float
        Mean divided by its standard error, the error computed from the record's variance with
        an AR(1) effective sample size ``n (1 - rho_1) / (1 + rho_1)``.
    """

    kind: str
    regime: str
    t0: float
    t1: float
    n: int
    mean: float
    rms: float
    score: float
    z: float

    def to_dict(self) -> dict:
        return dict(self.__dict__)


def regime_labels(t, omega, *, speed_tol: float | None = None, accel_tol: float | None = None):
    """Label each sample ``rest``, ``ramp_up``, ``ramp_down`` or ``hold``.

    Parameters
    ----------
    t : array_like, shape (n,)
        Times (s).
    omega : array_like, shape (n,)
        Speed set-point ``omega_ref`` (preferred, exact) or smoothed wheel speed (rad/s).
    speed_tol : float, optional
        ``|omega|`` below this is ``rest``; default 2 % of ``max |omega|``.
    accel_tol : float, optional
        ``|d|omega|/dt|`` below this is ``hold``; default 5 % of its maximum (rad/s^2).

    Returns
    -------
    ndarray of str, shape (n,)
        ``ramp_up``/``ramp_down`` refer to the speed magnitude.
    """
    t = _as_1d("t", t)
    w = _as_1d("omega", omega)
    mag = np.abs(w)
    acc = np.gradient(mag, t)
    speed_tol = 0.02 * float(mag.max()) if speed_tol is None else float(speed_tol)
    accel_tol = 0.05 * float(np.abs(acc).max()) if accel_tol is None else float(accel_tol)
    lab = np.full(t.shape, "hold", dtype=object)
    lab[acc > accel_tol] = "ramp_up"
    lab[acc < -accel_tol] = "ramp_down"
    lab[(mag <= speed_tol) & (np.abs(acc) <= accel_tol)] = "rest"
    return lab.astype(str)


def direction_labels(omega, *, speed_tol: float | None = None):
    """``forward`` (omega > tol), ``reverse`` (omega < -tol) or ``stopped``; shape (n,)."""
    w = _as_1d("omega", omega)
    tol = 0.02 * float(np.abs(w).max()) if speed_tol is None else float(speed_tol)
    return np.where(w > tol, "forward", np.where(w < -tol, "reverse", "stopped"))


def speed_bin_labels(omega, bins=5, *, unit: str = "rad/s"):
    """Label samples by bins of ``|omega|``.

    Parameters
    ----------
    omega : array_like, shape (n,)
    bins : int or array_like
        Number of equal-width bins over ``[0, max |omega|]`` or explicit edges.

    Returns
    -------
    ndarray of str, shape (n,)
        e.g. ``speed 1.26-1.88 rad/s``.
    """
    w = np.abs(_as_1d("omega", omega))
    edges = (np.linspace(0.0, float(w.max()) * (1 + 1e-9) + 1e-300, int(bins) + 1)
             if np.ndim(bins) == 0 else np.asarray(bins, float))
    idx = np.clip(np.digitize(w, edges) - 1, 0, edges.size - 2)
    names = np.array([f"speed {edges[i]:.3g}-{edges[i + 1]:.3g} {unit}"
                      for i in range(edges.size - 1)])
    return names[idx]


def phase_bin_labels(angle, period: float = 2 * math.pi, n_bins: int = 12, *, prefix="phase"):
    """Label samples by the phase of an angle within a period.

    Parameters
    ----------
    angle : array_like, shape (n,)
        Cumulative angle (rad), e.g. ``theta_b``.
    period : float
        ``2 pi`` for once per revolution, ``2 pi / teeth_per_wrap`` per tooth pitch (rad).
    n_bins : int

    Returns
    -------
    ndarray of str, shape (n,)
        ``f"{prefix} {k}/{n_bins}"`` for bin ``k`` (0-based) of ``angle mod period``.
    """
    a = _as_1d("angle", angle)
    k = np.floor(np.mod(a, period) / period * n_bins).astype(int) % n_bins
    names = np.array([f"{prefix} {i}/{n_bins}" for i in range(n_bins)])
    return names[k]


def time_window_labels(t, n_windows: int = 10):
    """Split ``[t0, t1]`` into ``n_windows`` equal windows; labels ``t a-b s``, shape (n,)."""
    t = _as_1d("t", t)
    edges = np.linspace(t[0], t[-1], int(n_windows) + 1)
    idx = np.clip(np.digitize(t, edges) - 1, 0, n_windows - 1)
    names = np.array([f"t {edges[i]:.3g}-{edges[i + 1]:.3g} s" for i in range(n_windows)])
    return names[idx]


def _rho1(r):
    r = r - r.mean()
    d = float(np.dot(r, r))
    return 0.0 if d == 0 else float(np.dot(r[1:], r[:-1]) / d)


def segment_stats(t, r, labels, kind: str, *, contiguous: bool = True,
                  min_samples: int = 10) -> list:
    """Residual statistics per label (see :class:`Segment`).

    Parameters
    ----------
    t, r : array_like, shape (n,)
        Uniform time grid (s) and residual.
    labels : array_like of str, shape (n,)
    kind : str
        Family name stored in each segment.
    contiguous : bool
        One segment per run of equal labels (True) or one per label value (False).
    min_samples : int
        Segments with fewer samples are left out.

    Returns
    -------
    list of Segment
        Unsorted.
    """
    t = _as_1d("t", t)
    r = _as_1d("r", r)
    labels = np.asarray(labels)
    ms_all = float(np.mean(r ** 2))
    var = float(np.var(r))
    rho = min(max(_rho1(r), -0.99), 0.99)
    eff = (1 - rho) / (1 + rho)
    groups = []
    if contiguous:
        change = np.flatnonzero(labels[1:] != labels[:-1]) + 1
        starts = np.r_[0, change]
        ends = np.r_[change, labels.size]
        groups = [(str(labels[s]), np.arange(s, e)) for s, e in zip(starts, ends)]
    else:
        for lab in dict.fromkeys(labels.tolist()):
            groups.append((str(lab), np.flatnonzero(labels == lab)))
    out = []
    for lab, idx in groups:
        if idx.size < min_samples:
            continue
        seg = r[idx]
        m = float(seg.mean())
        ms = float(np.mean(seg ** 2))
        se = math.sqrt(var / max(idx.size * eff, 1.0)) if var > 0 else float("inf")
        out.append(Segment(kind=kind, regime=lab, t0=float(t[idx[0]]), t1=float(t[idx[-1]]),
                           n=int(idx.size), mean=m, rms=math.sqrt(ms),
                           score=ms / ms_all if ms_all > 0 else 0.0,
                           z=m / se if se > 0 else 0.0))
    return out


def localise(t, r, *, omega=None, theta_b=None, teeth_per_wrap: int | None = None,
             n_phase_bins: int = 12, n_speed_bins: int = 5, n_time_windows: int = 10,
             extra: dict | None = None, min_samples: int = 10) -> list:
    """Rank regime segments by how much of the residual they hold.

    Parameters
    ----------
    t, r : array_like, shape (n,)
        Uniform time grid (s) and residual.
    omega : array_like, shape (n,), optional
        ``omega_ref`` or smoothed wheel speed (rad/s): enables the ``regime`` (ramp up/down,
        hold, rest), ``direction`` and ``speed`` families.
    theta_b : array_like, shape (n,), optional
        Band angle (rad): enables ``phase_rev`` (once per band revolution) and, with
        ``teeth_per_wrap``, ``phase_tooth`` (per tooth pitch ``2 pi / teeth_per_wrap``).
    n_phase_bins, n_speed_bins, n_time_windows : int
    extra : dict of str -> (labels array (n,), contiguous bool), optional
        Further families (e.g. load, recording).
    min_samples : int

    Returns
    -------
    list of Segment
        Sorted by decreasing ``score`` (ties by ``|z|``).
    """
    t = _as_1d("t", t)
    r = _as_1d("r", r)
    fams = [("time", time_window_labels(t, n_time_windows), True)]
    if omega is not None:
        fams += [("regime", regime_labels(t, omega), True),
                 ("direction", direction_labels(omega), True),
                 ("speed", speed_bin_labels(omega, n_speed_bins), False)]
    if theta_b is not None:
        fams.append(("phase_rev", phase_bin_labels(theta_b, 2 * math.pi, n_phase_bins,
                                                   prefix="band phase"), False))
        if teeth_per_wrap:
            fams.append(("phase_tooth", phase_bin_labels(theta_b, 2 * math.pi / teeth_per_wrap,
                                                         n_phase_bins, prefix="tooth phase"), False))
    for k, (lab, contig) in (extra or {}).items():
        fams.append((k, np.asarray(lab), bool(contig)))
    segs = []
    for kind, lab, contig in fams:
        segs += segment_stats(t, r, lab, kind, contiguous=contig, min_samples=min_samples)
    segs.sort(key=lambda s: (-s.score, -abs(s.z)))
    return segs


def phase_profile(angle, r, period: float = 2 * math.pi, n_bins: int = 12) -> dict:
    """Mean residual per phase bin of an angle, and a test of "no phase dependence".

    Parameters
    ----------
    angle : array_like, shape (n,)
        Cumulative angle (rad).
    r : array_like, shape (n,)
        Uniformly sampled residual.
    period : float
        Phase period (rad).
    n_bins : int

    Returns
    -------
    dict
        ``center`` (rad, shape (B,)), ``mean``, ``stderr``, ``count`` (shape (B,)),
        ``stat`` = ``sum ((mean_i - grand mean) / stderr_i)^2`` over filled bins, ``dof`` =
        filled bins - 1, ``p_value`` from ``chi2(dof)``, ``amplitude`` = half the range of the
        bin means. Standard errors use the AR(1) effective sample size (see :class:`Segment`).
    """
    a = _as_1d("angle", angle)
    r = _as_1d("r", r)
    k = np.floor(np.mod(a, period) / period * n_bins).astype(int) % n_bins
    rho = min(max(_rho1(r), -0.99), 0.99)
    eff = (1 - rho) / (1 + rho)
    var = float(np.var(r))
    count = np.bincount(k, minlength=n_bins)
    sums = np.bincount(k, weights=r, minlength=n_bins)
    mean = np.where(count > 0, sums / np.maximum(count, 1), np.nan)
    se = np.where(count > 0, np.sqrt(var / np.maximum(count * eff, 1.0)), np.nan)
    ok = count > 0
    grand = float(np.sum(sums) / np.sum(count))
    stat = float(np.sum(((mean[ok] - grand) / se[ok]) ** 2)) if var > 0 else 0.0
    dof = int(ok.sum()) - 1
    return {"center": (np.arange(n_bins) + 0.5) * period / n_bins, "mean": mean, "stderr": se,
            "count": count, "stat": stat, "dof": dof,
            "p_value": float(stats.chi2.sf(stat, dof)) if dof > 0 else 1.0,
            "amplitude": float(0.5 * (np.nanmax(mean) - np.nanmin(mean)))}


# --------------------------------------------------------------------------- spectrum
@dataclass
class Peak:
    """A spectral peak of the residual.

    Attributes
    ----------
    freq : float
        Frequency (Hz) of the largest bin of the peak.
    power : float
        PSD there (residual unit^2 / Hz).
    floor : float
        Background PSD (running median, bias-corrected to a mean).
    ratio : float
        ``power / floor``.
    p_value : float
        Single-bin probability of a ratio this large from the background alone
        (``chi2(dof)/dof``); compare with ``alpha / n_bins``.
    """

    freq: float
    power: float
    floor: float
    ratio: float
    p_value: float


def welch_dof(n: int, nperseg: int, noverlap: int, window: str = "hann") -> float:
    """Equivalent chi-square degrees of freedom of a Welch PSD estimate.

    ``nu = 2 K / (1 + 2 sum_{j>=1} (1 - j/K) c_j)`` with ``K`` segments and ``c_j`` the squared
    normalised overlap correlation of the window at shift ``j (nperseg - noverlap)``
    (Welch 1967; Percival & Walden 1993, eq. 292b).
    """
    step = nperseg - noverlap
    k = (n - noverlap) // step
    w = signal.get_window(window, nperseg)
    s2 = float(np.sum(w ** 2))
    tot = 0.0
    for j in range(1, k):
        sh = j * step
        if sh >= nperseg:
            break
        tot += (1 - j / k) * (float(np.sum(w[:-sh] * w[sh:])) / s2) ** 2
    return 2.0 * k / (1.0 + 2.0 * tot)


def spectral_peaks(r, fs: float, *, alpha: float = 0.01, nperseg: int | None = None,
                   fmin: float | None = None, fmax: float | None = None, floor_bins: int | None = None,
                   max_peaks: int = 5, prewhiten_order: int = 4):
    """Find frequencies at which the residual has more power than its background.

    Method: the residual is first prewhitened by a low-order least-squares AR filter
    (``prewhiten_order``, default 4: it flattens a smooth coloured background, which a
    running median cannot follow near steep edges, but is too short to notch a narrow line)
    -> Welch PSD (Hann window, 50 % overlap, ``nperseg`` default ``min(N, 2^k)`` near
    ``N/8``) -> background = running median over ``floor_bins`` bins divided by the median of
    ``chi2(nu)/nu`` (so it estimates the mean) -> a bin is significant if ``PSD / background``
    exceeds the ``1 - alpha/n_bins`` quantile of ``F(nu, nu_f)`` (``chi2(nu)/nu`` widened for
    the uncertainty of the background estimate; Bonferroni over bins: the family-wise
    false-alarm rate on white or smoothly coloured noise is at most about ``alpha``).
    Adjacent significant bins form one peak.

    Parameters
    ----------
    r : array_like, shape (N,)
        Uniformly sampled residual.
    fs : float
        Sampling rate (Hz).
    alpha : float
        Family-wise level.
    nperseg : int, optional
    fmin : float, optional
        Ignore frequencies below this (Hz); default two frequency bins (drift, DC).
    fmax : float, optional
        Ignore frequencies above this (Hz); default Nyquist. For a residual of *smoothed*
        signals (e.g. Savitzky-Golay speeds over ``window_s``) set ``fmax`` below the
        smoothing cut-off, about ``0.5 / window_s``: beyond it the spectrum falls steeply and
        the filter's stop-band ripple would be reported as peaks.
    floor_bins : int, optional
        Running-median width (odd); default about 1/4 of the bins, at least 9.
    max_peaks : int
    prewhiten_order : int
        Order of the AR prewhitening filter (0: analyse ``r`` as is).

    Returns
    -------
    peaks : list of Peak
        Sorted by decreasing ``ratio``, at most ``max_peaks``.
    f : ndarray, shape (F,)
        Frequencies (Hz).
    psd : ndarray, shape (F,)
        Welch PSD of the prewhitened residual (its powers are relative to the background).
    floor : ndarray, shape (F,)
        Background.
    """
    r = _as_1d("r", r)
    a = _ar_prewhitener(r, int(prewhiten_order))
    if a.size:
        r = signal.lfilter(np.r_[1.0, -a], [1.0], r - r.mean())[a.size:]
    n = r.size
    if nperseg is None:
        nperseg = int(2 ** max(5, round(math.log2(max(n / 8, 32)))))
    nperseg = min(int(nperseg), n)
    nover = nperseg // 2
    f, psd = signal.welch(r, fs=fs, window="hann", nperseg=nperseg, noverlap=nover,
                          detrend="constant")
    nu = welch_dof(n, nperseg, nover)
    nb = f.size
    if floor_bins is None:
        floor_bins = max(9, (nb // 4) | 1)
    floor_bins = int(floor_bins) | 1
    med = signal.medfilt(psd, floor_bins)
    # medfilt pads with zeros: recompute the edges with shrinking windows
    h = floor_bins // 2
    for i in list(range(min(h, nb))) + list(range(max(nb - h, 0), nb)):
        lo, hi = max(0, i - h), min(nb, i + h + 1)
        med[i] = np.median(psd[lo:hi])
    floor = med / (stats.chi2.median(nu) / nu)
    fmin = 2 * f[1] if fmin is None else float(fmin)
    use = f >= fmin
    if fmax is not None:
        use &= f <= float(fmax)
    n_test = int(use.sum())
    ratio = np.where(floor > 0, psd / np.where(floor > 0, floor, 1.0), 0.0)
    # The background itself is estimated (median of ~floor_bins correlated bins): treat the
    # ratio as F(nu, nu_f) with nu_f = nu * m_eff / (pi / 2) (variance of a sample median),
    # m_eff = floor_bins / 2 (neighbouring Hann bins are correlated).
    nu_f = nu * (floor_bins / 2.0) / (math.pi / 2.0)
    thr = stats.f.ppf(1 - alpha / max(n_test, 1), nu, nu_f)
    sig = use & (ratio > thr)
    peaks = []
    i = 0
    while i < nb:
        if sig[i]:
            j = i
            while j + 1 < nb and sig[j + 1]:
                j += 1
            k = i + int(np.argmax(ratio[i:j + 1]))
            peaks.append(Peak(freq=float(f[k]), power=float(psd[k]), floor=float(floor[k]),
                              ratio=float(ratio[k]),
                              p_value=float(stats.chi2.sf(ratio[k] * nu, nu))))
            i = j + 1
        else:
            i += 1
    peaks.sort(key=lambda p: -p.ratio)
    return peaks[:max_peaks], f, psd, floor


def match_orders(freq: float, references: dict, *, max_order: int = 10, tol: float = 0.05):
    """Name a frequency as a multiple of reference rates.

    Parameters
    ----------
    freq : float
        Hz.
    references : dict of str -> float
        e.g. ``{"band revolution": mean |omega_b| / (2 pi), "wheel revolution": ...,
        "tooth": teeth_per_wrap * band rate}`` (Hz).
    max_order : int
        Largest harmonic considered.
    tol : float
        Relative tolerance on ``freq / (order * rate)``.

    Returns
    -------
    list of (str, int, float)
        ``(reference name, harmonic order, relative error)``, best first; empty if none fits.
    """
    out = []
    for name, rate in references.items():
        if not rate or rate <= 0:
            continue
        order = int(round(freq / rate))
        if 1 <= order <= max_order:
            err = abs(freq / (order * rate) - 1.0)
            if err <= tol:
                out.append((name, order, err))
    out.sort(key=lambda x: (x[1], x[2]))
    return out
