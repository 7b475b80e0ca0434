"""What the recordings can see: the smallest effect amplitude that would have been flagged.

A verdict of ``none`` says that nothing *significant* is missing; how significant an effect
must be depends on the recordings (an effect that acts only at low band speed is weighed by
the time the recordings spend there, a load-dependent one by the loads recorded). At the
calibrated point the screening already has each candidate's linear columns ``J_c`` (model speed per unit of the
effect's amplitude) and the base coefficients' ``J_b``. The part of ``J_c`` that the base
coefficients cannot absorb, ``(I - P_b) J_c`` with ``P_b`` the projector onto the columns of
``J_b``, is what a concealed effect of amplitude ``a`` leaves in the fit residual after
calibration. The mismatch test flags a calibrated fit above ``min_excess`` noise floors; with
the noise adding in quadrature, that needs an effect residual of RMS
``floor sqrt(min_excess^2 - 1)``, hence

    a_min = floor sqrt(min_excess^2 - 1) sqrt(n) / sigma((I - P_b) J_c)

for ``n`` compared samples, with the smallest singular value for an effect of several
amplitude coordinates (its least visible direction, e.g. the worst phase of a once-per-rev
torque) and the largest for its most visible one. It is a linear estimate from "off": an
effect whose slope from "off" is zero where the model sticks gets ``inf`` (not seen in the
linearisation), and the nonlinear fit may still see it. The estimate is optimistic where the
base model absorbs an effect nonlinearly: on slider_stribeck seed 14 it flags mu_st from 0.008,
yet the base model refitted from another start hides the truth's 0.116 down to 1.28 floors,
its static friction taking the peak (docs/DIAGNOSIS-DESIGN.md). The base model's own mismatch
also raises the practical threshold: calibrated null cases of the benchmark grid end at
0.9-1.5 floors.
"""
from __future__ import annotations

import math

import numpy as np

__all__ = ["detectable_amplitude"]


def detectable_amplitude(J_base, J_effect, floor: float, *, min_excess: float = 1.3,
                         rtol: float = 1e-10) -> tuple:
    """Smallest amplitudes of one effect that the mismatch test would flag (linearised).

    Parameters
    ----------
    J_base : ndarray, shape (n, p)
        Model-speed sensitivities to the base coefficients (rad/s per fit unit).
    J_effect : ndarray, shape (n, k)
        Sensitivities to the effect's amplitude coordinates (rad/s per unit of amplitude).
    floor : float
        Noise floor, RMS (rad/s).
    min_excess : float
        The mismatch threshold, in noise floors (``SelectionRule.min_excess``, > 1).
    rtol : float
        Singular values below ``rtol`` times the largest count as zero (rank of ``J_base``).

    Returns
    -------
    worst, best : float
        Amplitude along the effect's least and most visible directions, in its fit units;
        ``inf`` where the base coefficients absorb the effect entirely (or it has no slope).
    """
    J_base = np.asarray(J_base, dtype=float)
    J_effect = np.asarray(J_effect, dtype=float)
    if J_effect.ndim != 2 or J_effect.shape[1] == 0 or J_effect.shape[0] != J_base.shape[0]:
        raise ValueError(f"detectable_amplitude: J_effect must be (n, k>0) with n = {J_base.shape[0]}, "
                         f"got {J_effect.shape}")
    if not min_excess > 1.0:
        raise ValueError(f"detectable_amplitude: min_excess must be > 1, got {min_excess}")
    n = J_effect.shape[0]
    if J_base.size:
        U, s, _ = np.linalg.svd(J_base, full_matrices=False)
        U = U[:, s > rtol * max(float(s[0]), 1e-300)]
        J_perp = J_effect - U @ (U.T @ J_effect)
    else:
        J_perp = J_effect
    sv = np.linalg.svd(J_perp, compute_uv=False)
    need = floor * math.sqrt(min_excess ** 2 - 1.0) * math.sqrt(n)
    # a column that only differs from the base's span by rounding has no visible part
    scale = max(float(np.linalg.norm(J_effect, 2)), 1e-300)
    vis = [v if v > 1e-9 * scale else 0.0 for v in (float(sv.min()), float(sv.max()))]
    return tuple(need / v if v > 0.0 else math.inf for v in vis)
