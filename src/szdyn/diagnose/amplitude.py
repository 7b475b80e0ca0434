"""Searching an effect's amplitude along its whole range, the base coefficients held fixed.

Why: near the full-slip cliff the fit cost in an effect's amplitude is a narrow valley beside a
cliff. Out-of-sample load_lift seed 20 (payload 1.29 kg, truth tau_lift 0.084 N m): at the
uncalibrated coefficients the RMSE over its six recordings was 0.21 rad/s at tau_lift 0.08, 0.052 at
0.09 and 1.48 at 0.10 N m (the band stalls). A gradient fit started beside that valley ends in
another one; the refit of load_lift ended at tau_lift 0.178 N m, 0.48 rad/s (28x the noise
floor), and a friction asymmetry pinned at its bound was named instead. A scan over the range
finds the valley and a bounded Brent search (``scipy.optimize.minimize_scalar``) its bottom;
the gradient fit then starts there.

This is the refit's fourth start (:class:`.diagnosis.Diagnosis`, step 4), tried only while a
candidate's refits leave more than ``max_remaining`` noise floors: the first refit's amplitude
was paired with calibrated coefficients that had compensated for the effect, so it need not
suit the uncalibrated ones. Only then, because a start that fits better need not end better
(docs/DIAGNOSIS-DESIGN.md: a better second start made friction_asymmetry seed 11 end worse), and
the fourth start is adopted only if its refit ends better.
"""
from __future__ import annotations

import numpy as np
from scipy.optimize import minimize_scalar

from .engine import FeatureModel
from .fit import Hypothesis

__all__ = ["AMPLITUDE_GRID", "REFINE_EVALS", "amplitude_search"]

#: Points of the scan over each amplitude's range (bounds included). 17 puts points at 0.25 and
#: 0.5 of a symmetric or one-sided range, the probes of the refit's other starts.
AMPLITUDE_GRID = 17

#: Model evaluations (each one run per fit recording) of the bounded Brent search in the
#: bracket around the scan's best point.
REFINE_EVALS = 10


def amplitude_search(model: FeatureModel, hyp: Hypothesis, x, which, *,
                     n_grid: int = AMPLITUDE_GRID, refine: int = REFINE_EVALS):
    """Best values of the effect's amplitude parameters at fixed base coefficients.

    Each amplitude parameter (:meth:`.fit.Hypothesis.amplitude_indices`) in turn, the others at
    their current best: a scan of ``n_grid`` points over its bounds (one parallel batch), then a
    bounded Brent search of at most ``refine`` evaluations between the neighbours of the best
    point. ``x`` itself is kept if nothing fits better.

    Parameters
    ----------
    model : FeatureModel
    hyp : Hypothesis
        With a candidate (the base model has no amplitude: ``x`` is returned).
    x : ndarray, shape (p,)
        Start in ``hyp``'s fit coordinates; its base coefficients are not changed.
    which : sequence of int
        Recordings fitted.
    n_grid : int
        Scan points per amplitude parameter (at least 3).
    refine : int
        Evaluations of the Brent search per parameter, at most (0: scan only; scipy's bounded
        search makes at least 2, so 1 acts as 2).

    Returns
    -------
    x : ndarray, shape (p,)
        The best point evaluated (fit coordinates, inside the bounds).
    rss : float
        Its residual sum of squares on ``which`` ((rad/s)^2).
    n_eval : int
        Points evaluated (each one model run per recording in ``which``).
    """
    if n_grid < 3:
        raise ValueError(f"n_grid must be at least 3, got {n_grid}")
    x = hyp.inside(x)
    r = model.residuals([hyp.point(x)], which)[0]
    best = [float(r @ r), x]     # updated in place by the scan and the Brent search's cost
    n_eval = 1
    lo, hi = hyp.bounds()
    for j in hyp.amplitude_indices():

        def at(v, j=j):
            y = best[1].copy()
            y[j] = v
            return hyp.inside(y)

        grid = np.linspace(lo[j], hi[j], n_grid)
        pts = [at(v) for v in grid]
        rss = [float(q @ q) for q in model.residuals([hyp.point(p) for p in pts], which)]
        n_eval += len(pts)
        k = int(np.argmin(rss))
        if rss[k] < best[0]:
            best[:] = [rss[k], pts[k]]
        # the bracket: the scan's neighbours of the best value so far (a grid point or the start)
        centre = best[1][j]
        step = grid[1] - grid[0]
        a, b = max(lo[j], centre - step), min(hi[j], centre + step)
        if refine <= 0 or not b > a:
            continue
        count = [0]

        def cost(v, j=j):
            p = at(v, j)
            q = model.residuals([hyp.point(p)], which)[0]
            count[0] += 1
            s = float(q @ q)
            if s < best[0]:
                best[:] = [s, p]
            return s

        minimize_scalar(cost, bounds=(a, b), method="bounded",
                        options={"xatol": hyp.params[j].probe / 10.0, "maxiter": refine})
        n_eval += count[0]
    return best[1], best[0], n_eval
