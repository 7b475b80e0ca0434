"""szdyn.heldout: the split that hides least from the fit (generator and diagnosis share it)."""
from __future__ import annotations

import math

from szdyn.heldout import EXHAUSTIVE, SplitCost, least_hiding, split_cost, split_features

PI = math.pi


def _f(load, direction, speed):
    return split_features(load, direction, speed)


def test_features_normalise_unknown_load_and_negative_zero():
    f = _f(math.nan, -0.0, math.nan)
    assert f.load_key is None and math.copysign(1, f.direction) == 1 and f.speed == 0.0
    assert _f(1.0000000001, 1, PI).load_key == 1.0


def test_cost_counts_lost_pairs_extrapolation_and_lost_margins():
    feats = [_f(0.5, 1, PI), _f(0.5, -1, PI), _f(1.0, 1, PI), _f(1.0, -1, PI), _f(1.5, 1, PI), _f(1.5, -1, PI)]
    # the heaviest backward run: its pair is lost and 1.5 kg lies beyond the fitted backward loads
    assert split_cost(feats, [5]) == SplitCost(1, 1, 0, -3)
    # both runs at 1 kg: two pairs and the load lost, but each lies between fitted loads
    assert split_cost(feats, [2, 3]) == SplitCost(2, 0, 1, -4)
    # every backward run: its direction is lost, and no fit recording runs that way
    assert split_cost(feats, [1, 3, 5]).outside == 3 and split_cost(feats, [1, 3, 5]).lost_margins == 1


def test_first_choice_stands_unless_another_hides_less():
    # (0, 1) hides nothing; a more varied set must not displace it
    feats = [_f(0.5, 1, PI), _f(0.5, 1, PI), _f(1.0, 1, PI), _f(1.0, 1, 2 * PI), _f(0.5, 1, 2 * PI)]
    assert least_hiding(feats, 2) == (0, 1)
    # the first choice holds out the only backward run at 0.5 kg: replaced by a forward run
    # that has a twin condition among the fit ones
    feats = [_f(0.5, -1, PI), _f(0.5, 1, PI), _f(0.5, 1, 2 * PI), _f(1.0, 1, PI), _f(1.0, -1, PI)]
    assert least_hiding(feats, 1) == (1,)
    # at most all but one; none of nothing
    assert least_hiding(feats[:2], 5) == (0,) and least_hiding(feats[:1], 1) == () == least_hiding(feats, 0)


def test_many_recordings_are_improved_from_the_first_choice_by_exchanges():
    # 3 loads x (forward slow, forward fast, backward) x 4 repeats, the backward runs first:
    # too many sets to compare one by one, and the first choice would hold out 12 backward runs
    feats = [_f(load, d, w) for d, w in ((-1, PI), (1, PI), (1, 2 * PI)) for load in (0.5, 1.0, 1.5) * 4]
    assert math.comb(len(feats), 12) > EXHAUSTIVE
    assert split_cost(feats, range(12)).lost_pairs == 3
    held = least_hiding(feats, 12)
    assert len(held) == 12 and split_cost(feats, held)[:3] == (0, 0, 0)
