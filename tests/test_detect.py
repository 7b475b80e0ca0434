"""The smallest flagged amplitude (szdyn.diagnose.detect) on constructed sensitivities."""
import math

import numpy as np
import pytest

from szdyn.diagnose.detect import detectable_amplitude

RNG = np.random.default_rng(3)
N, FLOOR = 400, 0.01
J_BASE = RNG.normal(size=(N, 3))


def _perp(v):
    q, _ = np.linalg.qr(J_BASE)
    return v - q @ (q.T @ v)


def test_an_effect_orthogonal_to_the_base_reaches_the_threshold_at_the_returned_amplitude():
    col = _perp(RNG.normal(size=N))[:, None]
    a, a_best = detectable_amplitude(J_BASE, col, FLOOR, min_excess=1.3)
    assert a == pytest.approx(a_best)
    # noise at the floor plus the effect's residual, in quadrature, is exactly 1.3 floors
    eff = a * col[:, 0]
    assert math.hypot(FLOOR, np.sqrt(np.mean(eff ** 2))) == pytest.approx(1.3 * FLOOR, rel=1e-9)


def test_the_part_the_base_coefficients_absorb_does_not_count():
    v = _perp(RNG.normal(size=N))
    absorbed = J_BASE @ np.array([2.0, -1.0, 0.5])
    a_mixed, _ = detectable_amplitude(J_BASE, (v + absorbed)[:, None], FLOOR)
    a_pure, _ = detectable_amplitude(J_BASE, v[:, None], FLOOR)
    assert a_mixed == pytest.approx(a_pure, rel=1e-9)
    # an effect the base coefficients reproduce entirely cannot be flagged
    assert detectable_amplitude(J_BASE, absorbed[:, None], FLOOR) == (math.inf, math.inf)
    assert detectable_amplitude(J_BASE, np.zeros((N, 1)), FLOOR) == (math.inf, math.inf)


def test_two_coordinates_give_the_least_and_most_visible_direction():
    u, w = _perp(RNG.normal(size=N)), _perp(RNG.normal(size=N))
    w = w - u * (u @ w) / (u @ u)          # orthogonal pair with norms |u| and |w|
    w *= 0.25 * np.linalg.norm(u) / np.linalg.norm(w)
    worst, best = detectable_amplitude(J_BASE, np.column_stack([u, w]), FLOOR)
    assert worst / best == pytest.approx(4.0, rel=1e-9)


def test_rank_deficient_base_and_no_base():
    col = RNG.normal(size=(N, 1))
    dup = np.column_stack([J_BASE, J_BASE[:, :1]])
    assert detectable_amplitude(dup, col, FLOOR)[0] == pytest.approx(detectable_amplitude(J_BASE, col, FLOOR)[0])
    a, _ = detectable_amplitude(np.zeros((N, 0)), col, FLOOR)
    assert a == pytest.approx(FLOOR * math.sqrt(0.69) * math.sqrt(N) / np.linalg.norm(col))


@pytest.mark.parametrize("kw, shape", [({}, (N - 1, 1)), ({}, (N, 0)), ({"min_excess": 1.0}, (N, 1))])
def test_bad_arguments_are_clear_errors(kw, shape):
    with pytest.raises(ValueError, match="detectable_amplitude"):
        detectable_amplitude(J_BASE, np.ones(shape), FLOOR, **kw)
