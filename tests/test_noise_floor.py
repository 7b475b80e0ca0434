"""The common noise floor's bump part: a median in which each load counts once, and the
coefficients' share of it (``coefficient_floor``)."""
from __future__ import annotations

import math

import numpy as np
import pytest

from szdyn.diagnose.noise import coefficient_noise, fast_rms, load_median


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


# ----------------------------------------------------------------------------- coefficients
def test_fast_rms_drops_a_mean_speed_change_and_keeps_the_bumps():
    dt = 0.005
    t = np.arange(0.0, 3.0, dt)
    bumps = 0.02 * np.sin(2 * np.pi * 20.0 * t)      # 20 Hz: ten periods in the 0.5 s window
    assert fast_rms(np.full_like(t, 0.05), dt) == pytest.approx(0.0, abs=1e-15)
    assert fast_rms(0.05 + bumps, dt) == pytest.approx(0.02 / math.sqrt(2), rel=0.02)
    # a slow drift keeps a little at the ends only (where the running mean is one-sided)
    drift = 0.1 * t
    assert fast_rms(drift, dt) < 0.05 * float(np.sqrt(np.mean(drift ** 2)))


class _FakeModel:
    """Speeds of one recording: bumps that move with k_c, a mean speed that moves with mu_k."""

    def __init__(self):
        from types import SimpleNamespace

        self.t = np.arange(0.0, 3.0, 0.005)
        self.recordings = [SimpleNamespace(t_feat=self.t, params={"k_c": 0.05, "mu_k": 0.25, "mu_s": 0.3})]
        self.asked = []

    def speeds(self, points, which):
        assert list(which) == [0]
        out = []
        for mc, sc in points:
            self.asked.append(dict(mc))
            kc, mk = mc.get("k_c", 0.05), mc.get("mu_k", 0.25)
            v = 2.0 - 10.0 * (mk - 0.25) + 2.0 * (kc - 0.05) * np.sin(2 * np.pi * 20.0 * self.t)
            out.append([v])
        return out


def test_coefficient_noise_moves_each_group_by_the_step_and_counts_the_fast_part():
    m = _FakeModel()
    base = {"k_c": 0.06, "q_w0": 0.1}
    c = coefficient_noise(m, 0, base, 0.01)
    # the base, k_c x1.01 (from the base's own value), mu_k and mu_s x1.01 (from the nominal)
    assert m.asked[0] == base
    assert m.asked[1] == {"k_c": pytest.approx(0.0606), "q_w0": 0.1}
    assert m.asked[2] == {"k_c": 0.06, "q_w0": 0.1, "mu_k": pytest.approx(0.2525), "mu_s": pytest.approx(0.303)}
    # k_c's change: bumps of amplitude 2 * 0.0006; mu's: a mean speed shift, no fast part
    assert c == pytest.approx(math.sqrt(((2 * 0.0006 / math.sqrt(2)) ** 2 + 0.0) / 2), rel=0.02)


@pytest.mark.parametrize("bad", [-0.01, 0.51, math.nan, True, "0.01"])
def test_coefficient_floor_out_of_range_is_refused(bad):
    from szdyn.diagnose.diagnosis import Diagnosis

    with pytest.raises(ValueError, match="coefficient_floor"):
        Diagnosis(coefficient_floor=bad)


def test_the_diagnosis_floor_adds_the_coefficients_in_quadrature(monkeypatch):
    from types import SimpleNamespace

    from szdyn.diagnose import diagnosis as dg

    recs = [SimpleNamespace(name=f"r{i}", load_kg=x) for i, x in enumerate([0.5, 1.0, 0.5])]
    coef = [0.03, 0.0004, 0.02]
    monkeypatch.setattr(dg, "sensor_noise", lambda p: 0.005)
    monkeypatch.setattr(dg, "bump_noise", lambda model, i, mc: 0.004)
    steps = []

    def fake_coefficient_noise(model, i, mc, step):
        steps.append(step)
        return coef[i]
    monkeypatch.setattr(dg, "coefficient_noise", fake_coefficient_noise)
    off = dg.Diagnosis()
    off._noise_floor(None, recs, [0, 1], [0, 1, 2], {})
    assert steps == [] and set(off.floor_per_recording_["r0"]) == {"sensor", "bump"}
    assert "coefficient_step" not in off.floor_parts_
    on = dg.Diagnosis(coefficient_floor=0.01)
    own = on._noise_floor(None, recs, [0, 1], [0, 1, 2], {})
    assert steps == [0.01] * 3
    assert on.floor_per_recording_["r2"] == pytest.approx(
        {"sensor": 0.005, "bump": math.hypot(0.004, 0.02), "bump_phase": 0.004, "bump_coefficients": 0.02})
    # each load once: the median of the 0.5 kg and the 1 kg fit recordings' combined bumps
    assert on.floor_parts_ == pytest.approx({"sensor": 0.005, "coefficient_step": 0.01,
                                              "bump": (math.hypot(0.004, 0.03) + math.hypot(0.004, 0.0004)) / 2})
    assert on.floor_ > off.floor_ and own[2] == pytest.approx(math.hypot(0.005, math.hypot(0.004, 0.02)))
