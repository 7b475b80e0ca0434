"""The common noise floor's bump part: a median in which each load counts once."""
from __future__ import annotations

import math

import numpy as np
import pytest

from szdyn.diagnose.noise import load_median


def _replicated_median(values, loads):
    """Independent oracle: repeat each value (lcm of the per-load counts) / (its load's count)
    times, so that every load has the same number of copies, and take the plain median."""
    keys = [x if math.isfinite(x) else "nan" for x in loads]
    count = {k: keys.count(k) for k in set(keys)}
    m = math.lcm(*count.values())
    return float(np.median(np.repeat(values, [m // count[k] for k in keys])))


def _draw(rng, n_loads, counts):
    loads = np.repeat(rng.choice([0.25, 0.5, 1.0, 2.0, math.nan], n_loads, replace=False), counts)
    # loads whose values sit apart by decades, as the benchmark's 0.5 and 1 kg bumps do
    values = rng.lognormal(mean=np.repeat(rng.normal(-4.0, 1.5, n_loads), counts), sigma=0.3)
    perm = rng.permutation(len(values))
    return values[perm], loads[perm]


def test_balanced_loads_give_the_plain_median_exactly():
    # what every benchmark case had (two fit recordings per load): the floor is unchanged
    rng = np.random.default_rng(0)
    for _ in range(300):
        n_loads, m = int(rng.integers(1, 5)), int(rng.integers(1, 5))
        v, loads = _draw(rng, n_loads, [m] * n_loads)
        assert load_median(v, loads) == float(np.median(v))


def test_unbalanced_loads_match_the_replicated_median():
    rng = np.random.default_rng(1)
    for _ in range(300):
        n_loads = int(rng.integers(1, 5))
        counts = rng.integers(1, 6, n_loads)
        v, loads = _draw(rng, n_loads, counts)
        assert load_median(v, loads) == pytest.approx(_replicated_median(v, loads), rel=1e-15)


def test_an_extra_recording_at_one_load_does_not_move_it_to_that_load():
    # seed 47's friction_asymmetry case with the slow ramp added at 1 kg (bump parts, rad/s):
    # the plain median went from between the loads to the 1 kg value
    half = [0.0318, 0.0312]
    one = [0.0018, 0.0023]
    both = half + one
    before = load_median(both, [0.5, 0.5, 1.0, 1.0])
    assert before == float(np.median(both)) == pytest.approx((0.0023 + 0.0312) / 2)
    extra = both + [0.0024]
    loads = [0.5, 0.5, 1.0, 1.0, 1.0]
    assert float(np.median(extra)) == 0.0024
    assert load_median(extra, loads) == pytest.approx((0.0024 + 0.0312) / 2)
    # and a copy of every recording at one load changes nothing
    assert load_median(half + one + one, [0.5, 0.5, 1.0, 1.0, 1.0, 1.0]) == before


def test_loads_not_given_form_one_group():
    v = [1.0, 2.0, 10.0, 11.0, 12.0]
    assert load_median(v, [0.5, 0.5] + [math.nan] * 3) == load_median(v, [0.5, 0.5, 2.0, 2.0, 2.0])
    assert load_median([3.0, 1.0, 2.0], [math.nan] * 3) == 2.0


@pytest.mark.parametrize("values, loads", [([], []), ([1.0, 2.0], [0.5])])
def test_bad_input_is_a_clear_error(values, loads):
    with pytest.raises(ValueError, match="one load per value"):
        load_median(values, loads)


def test_the_diagnosis_floor_counts_each_load_once(monkeypatch):
    # the wiring in Diagnosis._noise_floor, with each recording's parts given (no model runs):
    # seed 47's friction_asymmetry with the slow ramp added at 1 kg as a fifth fit recording
    from types import SimpleNamespace

    from szdyn.diagnose import diagnosis as dg

    loads = [0.5, 0.5, 1.0, 1.0, 1.0, 0.5, 1.0]        # five fit, then two held out
    bumps = [0.0318, 0.0312, 0.0018, 0.0023, 0.0024, 0.0291, 0.0027]
    recs = [SimpleNamespace(name=f"r{i}", load_kg=x, sensor=0.005, bump=b)
            for i, (x, b) in enumerate(zip(loads, bumps))]
    monkeypatch.setattr(dg, "sensor_noise", lambda p: p.sensor)
    monkeypatch.setattr(dg, "bump_noise", lambda model, i, mc: recs[i].bump)
    d = dg.Diagnosis()
    own = d._noise_floor(None, recs, [0, 1, 2, 3, 4], list(range(7)), {})
    assert d.floor_parts_["bump"] == pytest.approx((0.0024 + 0.0312) / 2)    # plain median: 0.0024
    assert d.floor_ == pytest.approx(math.hypot(0.005, (0.0024 + 0.0312) / 2))
    assert own[5] == pytest.approx(math.hypot(0.005, 0.0291)) and set(own) == set(range(7))
