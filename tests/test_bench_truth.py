"""bench/optimum_vs_truth.py places the truth in each candidate's own fit coordinates.

truth.json names the model's parameters (k_drive, a_rev and phi_rev, encoder_scale_b, ...),
while some candidates are fitted in other coordinates (a compliance, a sine and cosine part, a
scale offset). Round trip: the synthesised effect, mapped to the candidate's coordinates and
back through the candidate's own model changes, is the effect synth put into the truth.
"""

import pytest

from szdyn.diagnose.candidates import CANDIDATES
from szdyn.diagnose.fit import Hypothesis
from szdyn.synth import EFFECTS, effect_changes

from cases import load_bench

START = {"k_c": 0.05, "b_c": 0.0075, "k_imp": 4e12, "mu_s": 0.3, "mu_k": 0.25}


def _bench():
    return load_bench("optimum_vs_truth")


@pytest.mark.parametrize("effect", sorted(EFFECTS))
@pytest.mark.parametrize("seed", [3, 21])
def test_truth_coordinates_round_trip(effect, seed):
    _, model_changes, sensor_changes = effect_changes(effect, seed=seed)
    truth = {"effect": effect, "effect_parameters": model_changes, "effect_sensor": sensor_changes}
    coords = _bench().truth_coordinates(effect, truth)
    hyp = Hypothesis(START, CANDIDATES[effect])
    assert set(coords) == {p.name for p in hyp.candidate.params}
    mc, sc = hyp.point(hyp.coordinates({**START, **coords}))
    got = {**{k: v for k, v in mc.items() if k not in START}, **sc}
    assert got.keys() == {**model_changes, **sensor_changes}.keys()
    for k, v in {**model_changes, **sensor_changes}.items():
        assert got[k] == pytest.approx(v, rel=1e-12, abs=1e-15), k
