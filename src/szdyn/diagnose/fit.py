"""Fitting one hypothesis (base coefficients, optionally + one candidate) to recordings.

The fit is ``scipy.optimize.least_squares`` (trust-region reflective, bounds) on the residual
``measured - model`` smoothed band speed (rad/s) of the fit recordings, with a forward-difference
Jacobian whose columns run as one parallel batch (:class:`~szdyn.diagnose.engine.FeatureModel`).

Uncertainty: ``cov = s^2 (J^T J)^-1 * c`` at the optimum, ``s^2 = RSS / (n - p)``, inflated by
``c = WINDOW_S / FEATURE_DT`` (= 2) because neighbouring feature samples share half their
smoothing window and are not independent. Standard deviations of log-fitted coefficients are
converted to their own units by the delta method (``sigma_value = value * sigma_log``). What the
diagnosis reports for its calibrated and final models is recomputed from this Jacobian corrected
along the force scale by model runs (:mod:`.force_scale`).
"""
from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np
from scipy.optimize import least_squares

from .candidates import CALIBRATED, Candidate, FitParam
from .data import FEATURE_DT, WINDOW_S
from .engine import FeatureModel

__all__ = ["Hypothesis", "FitResult", "fit_hypothesis", "jacobian", "linear_step", "CORRELATION_INFLATION", "FIT_TOL"]

CORRELATION_INFLATION = WINDOW_S / FEATURE_DT

#: Relative ``ftol``/``xtol`` of every nonlinear fit of the diagnosis: tighter than a typical
#: 1e-3 so that the Jacobian budgets, not a small step on the rough (impact-bump) cost, end the
#: fits. Not a cure for stalls: the friction_drift seed-11 refit reported convergence after 2 Jacobians at
#: 0.030 rad/s with 1e-3 and with 1e-4 alike; the second start fixed that case.
FIT_TOL = 1e-4


class Hypothesis:
    """Maps fit coordinates ``x`` to model and sensor changes.

    Parameters
    ----------
    start : dict
        Base coefficient values to start from (``k_c, b_c, k_imp, mu_s, mu_k``, SI).
    candidate : Candidate, optional
        The effect switched on (None: the base model).

    Notes
    -----
    Base coefficients are ``x_j = log(value_j / start_j)`` (``mu_s`` through ``dmu_s = mu_s -
    mu_k``); candidate parameters are in their own units, 0 = off unless ``FitParam.start``.
    """

    def __init__(self, start: dict, candidate: Candidate | None = None):
        self.start = dict(start)
        self.candidate = candidate
        self._start_log = {"k_c": start["k_c"], "b_c": start["b_c"], "k_imp": start["k_imp"],
                           "mu_k": start["mu_k"], "dmu_s": start["mu_s"] - start["mu_k"]}
        self.params: tuple[FitParam, ...] = CALIBRATED + (candidate.params if candidate else ())
        self.n_base = len(CALIBRATED)

    @property
    def id(self) -> str:
        return self.candidate.id if self.candidate else "none"

    @property
    def names(self) -> tuple:
        return tuple(p.name for p in self.params)

    def x_start(self) -> np.ndarray:
        x = [0.0] * self.n_base
        x += [(p.start if p.start is not None else 0.0) for p in self.params[self.n_base:]]
        return np.array(x, dtype=float)

    def bounds(self):
        lo = [math.log(p.lo) if p.log else p.lo for p in self.params]
        hi = [math.log(p.hi) if p.log else p.hi for p in self.params]
        return np.array(lo), np.array(hi)

    def inside(self, x) -> np.ndarray:
        """``x`` clipped to just inside the bounds (``least_squares`` wants a strictly feasible start)."""
        lo, hi = self.bounds()
        span = hi - lo
        return np.clip(np.asarray(x, dtype=float), lo + 1e-9 * span, hi - 1e-9 * span)

    def steps(self) -> np.ndarray:
        """Finite-difference steps / scales in fit coordinates."""
        return np.array([p.probe for p in self.params])

    def values(self, x) -> dict:
        """Named values in their own units: base coefficients (incl. ``mu_s``) + candidate's."""
        v = {}
        for p, xi in zip(self.params[:self.n_base], x):
            v[p.name] = self._start_log[p.name] * math.exp(float(xi))
        v["mu_s"] = v["mu_k"] + v.pop("dmu_s")
        for p, xi in zip(self.params[self.n_base:], x[self.n_base:]):
            v[p.name] = float(xi)
        return v

    def coordinates(self, values: dict) -> np.ndarray:
        """Fit coordinates of named values (the inverse of :meth:`values`; not clipped)."""
        v = dict(values)
        v["dmu_s"] = v["mu_s"] - v["mu_k"]
        x = [math.log(v[p.name] / self._start_log[p.name]) if v[p.name] > 0 else -math.inf
             for p in self.params[:self.n_base]]
        x += [float(v[p.name]) for p in self.params[self.n_base:]]
        return np.array(x, dtype=float)

    def point(self, x) -> tuple[dict, dict]:
        """``(model_changes, sensor_changes)`` at ``x``."""
        v = self.values(x)
        mc = {k: v[k] for k in ("k_c", "b_c", "k_imp", "mu_s", "mu_k")}
        sc = {}
        if self.candidate is not None:
            cv = {p.name: v[p.name] for p in self.candidate.params}
            m2, s2 = self.candidate.apply(cv)
            mc.update(m2)
            sc.update(s2)
        return mc, sc

    def amplitude_indices(self) -> list:
        """Indices (fit coordinates) of the candidate's amplitude parameters: every candidate
        parameter but the shape ones (:attr:`.candidates.FitParam.screen_at`)."""
        return [j for j in range(self.n_base, len(self.params)) if not self.params[j].screen_at]

    def candidate_values(self, x) -> dict:
        if self.candidate is None:
            return {}
        v = self.values(x)
        return {p.name: v[p.name] for p in self.candidate.params}


def jacobian(model: FeatureModel, hyp: Hypothesis, x, which, f0=None, cols=None):
    """Forward-difference Jacobian of the *model speed* (not the residual), one parallel batch.

    Returns
    -------
    J : ndarray, shape (n, len(cols))
        ``d model_speed / d x_j`` (rad/s per fit unit).
    f0 : ndarray, shape (n,)
        Residual at ``x``.
    """
    x = np.asarray(x, dtype=float)
    cols = range(len(x)) if cols is None else cols
    lo, hi = hyp.bounds()
    h = hyp.steps()
    pts, hs = [hyp.point(x)], []
    for j in cols:
        xj = x.copy()
        step = h[j] if x[j] + h[j] <= hi[j] else -h[j]   # stay inside the bounds
        xj[j] += step
        hs.append(step)
        pts.append(hyp.point(xj))
    R = model.residuals(pts, which)
    f0 = R[0]
    # residual = y - speed: d speed / dx = -(d residual / dx)
    J = np.column_stack([-(R[k + 1] - f0) / hs[k] for k in range(len(hs))]) if hs else np.zeros((f0.size, 0))
    return J, f0


@dataclass
class FitResult:
    """Result of :func:`fit_hypothesis`.

    Attributes
    ----------
    hypothesis : Hypothesis
    x : ndarray, shape (p,)
        Optimum in fit coordinates.
    values : dict
        Named values (own units).
    std : dict
        Standard deviations (own units; NaN where ``J^T J`` is singular).
    corr : ndarray, shape (p, p)
        Correlation matrix of the fit coordinates.
    rss_fit : float
        Residual sum of squares on the fit recordings ((rad/s)^2).
    n_fit : int
        Feature samples in the fit recordings.
    rmse_fit : float
        rad/s.
    nfev : int
        Residual evaluations.
    J : ndarray
        Jacobian of the model speed at the optimum (fit recordings).
    """

    hypothesis: Hypothesis
    x: np.ndarray
    values: dict
    std: dict
    corr: np.ndarray
    rss_fit: float
    n_fit: int
    rmse_fit: float
    nfev: int
    J: np.ndarray
    status: str = ""
    extra: dict = field(default_factory=dict)

    @property
    def budget_hit(self) -> bool:
        """Whether the fit was stopped by its Jacobian budget rather than converging."""
        return self.status.startswith("stopped after")


def _uncertainty(hyp, x, J, rss, n):
    p = J.shape[1]
    s2 = rss / max(n - p, 1)
    JTJ = J.T @ J
    try:
        cov = np.linalg.pinv(JTJ, rcond=1e-10) * s2 * CORRELATION_INFLATION
    except np.linalg.LinAlgError:
        cov = np.full((p, p), np.nan)
    sd = np.sqrt(np.clip(np.diag(cov), 0.0, None))
    with np.errstate(invalid="ignore", divide="ignore"):
        corr = cov / np.outer(sd, sd)
    v = hyp.values(x)
    std = {}
    for k, par in enumerate(hyp.params):
        if par.log:
            base = v["mu_s"] - v["mu_k"] if par.name == "dmu_s" else v[par.name]
            std[par.name] = base * sd[k]
        else:
            std[par.name] = float(sd[k])
    # mu_s = mu_k + dmu_s: combine (delta method, with the covariance of the two log coordinates)
    i_k, i_d = hyp.names.index("mu_k"), hyp.names.index("dmu_s")
    g = np.zeros(p)
    g[i_k] = v["mu_k"]
    g[i_d] = v["mu_s"] - v["mu_k"]
    std["mu_s"] = float(math.sqrt(max(g @ cov @ g, 0.0)))
    return std, corr


def fit_hypothesis(model: FeatureModel, hyp: Hypothesis, which, *, x0=None, max_jac: int = 8,
                   tol: float = 1e-3, previous: FitResult | None = None) -> FitResult:
    """Least-squares fit of ``hyp`` on the recordings ``which``.

    Parameters
    ----------
    model : FeatureModel
    hyp : Hypothesis
    which : sequence of int
        Recordings fitted.
    x0 : ndarray, optional
        Start (default ``hyp.x_start()``), clipped into the bounds.
    max_jac : int
        At most this many Jacobians (each ``p + 1`` model evaluations per recording).
    tol : float
        ``ftol`` and ``xtol`` of the trust-region iteration (relative).
    previous : FitResult, optional
        Continue this fit (of the same hypothesis) from its optimum with another ``max_jac``
        Jacobians; the result counts the Jacobians of both.
    """
    if previous is not None:
        x0 = previous.x
    lo, hi = hyp.bounds()
    x0 = hyp.inside(hyp.x_start() if x0 is None else x0)
    memo = {}

    def fun(x):
        k = tuple(np.round(x, 14))
        if k not in memo:
            memo[k] = model.residuals([hyp.point(x)], which)[0]
        return memo[k]

    jmemo = {}

    class _Budget(Exception):
        pass

    def jac(x):
        # least_squares has no budget on Jacobians (max_nfev counts residuals): stop it here
        if len(jmemo) >= max_jac:
            raise _Budget
        J, f0 = jacobian(model, hyp, x, which)
        k = tuple(np.round(x, 14))
        memo[k], jmemo[k] = f0, J
        return -J   # d residual / dx

    try:
        res = least_squares(fun, x0, jac=jac, bounds=(lo, hi), x_scale=hyp.steps(), method="trf",
                            ftol=tol, xtol=tol, gtol=1e-8, max_nfev=max_jac * 3)
        x, nfev, status = res.x, int(res.nfev), str(res.message)
    except _Budget:
        # the best point evaluated so far
        kbest = min(memo, key=lambda k: float(memo[k] @ memo[k]))
        x, nfev, status = np.array(kbest), len(memo), f"stopped after {max_jac} Jacobians"
    f = fun(x)
    k = tuple(np.round(x, 14))
    J = jmemo[k] if k in jmemo else jacobian(model, hyp, x, which)[0]
    rss = float(f @ f)
    std, corr = _uncertainty(hyp, x, J, rss, f.size)
    return FitResult(hypothesis=hyp, x=x, values=hyp.values(x), std=std, corr=corr, rss_fit=rss,
                     n_fit=int(f.size), rmse_fit=math.sqrt(rss / f.size), nfev=nfev, J=J,
                     status=status,
                     extra={"njac": len(jmemo) + (k not in jmemo) + (previous.extra["njac"] if previous else 0),
                            "continued": previous is not None,
                            "restart": previous.extra.get("restart") if previous else None})


def gauss_newton_step(model: FeatureModel, hyp: Hypothesis, res: FitResult, which) -> np.ndarray:
    """The full linearised (Gauss-Newton) step from the end of a fit, shape (p,), in fit
    coordinates: ``residual(x + d) ~ f0 - J d`` with the fit's Jacobian ``res.J`` (d model speed /
    dx) and its residual at ``res.x`` on ``which`` (cached: the fit evaluated it)."""
    f0 = model.residuals([hyp.point(res.x)], which)[0]
    return np.linalg.lstsq(res.J, f0, rcond=None)[0]


def linear_step(model: FeatureModel, hyp: Hypothesis, res: FitResult, which,
                fractions=(1.0, 0.5), own: bool = True) -> tuple[np.ndarray, float, str]:
    """The Gauss-Newton step from the end of a fit, tried with model runs (one parallel batch).

    A trust-region fit on the rippled (impact-bump) cost can report convergence (``xtol``)
    after rejected steps shrank its radius, while the full linearised step from its end point
    still lowers the actual cost: a stall, not a minimum (measured: encoder_scale seed 17, whose
    calibration ended after 2 Jacobians at 0.0742 rad/s; the full step gave 0.0618 rad/s).

    The ripple lives in the base coefficients (the impacts), so with ``own`` the step in the
    candidate's own coordinates alone, the base held where the fit ended, is tried too: the
    full step can fail on the base's part of it while the effect's part would not (measured:
    encoder_delay seed 32, whose refit "converged" at 9.71 ms and 0.00988 rad/s; the full step
    gave 0.01165 and its half 0.00985, the delay's own step 0.00892 at 12.55 ms, truth 14.35).
    For an encoder effect that step costs no model run (the runs at the base are cached).

    Parameters
    ----------
    model : FeatureModel
    hyp : Hypothesis
    res : FitResult
        A fit of ``hyp`` on ``which``; its Jacobian ``res.J`` is used.
    which : sequence of int
        Recordings.
    fractions : sequence of float
        Fractions of each step tried.
    own : bool
        Also try the step in the candidate's coordinates alone (no effect for the base model).

    Returns
    -------
    x : ndarray, shape (p,)
        The best of the tried points (clipped into the bounds), in fit coordinates.
    rss : float
        Its residual sum of squares ((rad/s)^2).
    label : str
        Which step it is, for the report: ``"the full step"`` or ``"the candidate's own step"``,
        with the fraction when it is not 1 (``"0.5 x the full step"``).
    """
    steps = [gauss_newton_step(model, hyp, res, which)]
    names = ["the full step"]
    nb = hyp.n_base
    if own and res.J.shape[1] > nb:
        f0 = model.residuals([hyp.point(res.x)], which)[0]   # (cached: the fit evaluated it)
        d = np.zeros_like(res.x)
        d[nb:] = np.linalg.lstsq(res.J[:, nb:], f0, rcond=None)[0]
        steps.append(d)
        names.append("the candidate's own step")
    xs = [hyp.inside(res.x + a * d) for d in steps for a in fractions]
    labels = [nm if a == 1.0 else f"{a:g} x {nm}" for nm in names for a in fractions]
    R = model.residuals([hyp.point(x) for x in xs], which)
    rss = [float(r @ r) for r in R]
    k = int(np.argmin(rss))
    return xs[k], rss[k], labels[k]
