"""bench/optimum_vs_truth.py places the truth in each candidate's own fit coordinates.

truth.json names the model's parameters (k_drive, a_rev and phi_rev, encoder_scale_b, ...),
while some candidates are fitted in other coordinates (a compliance, a sine and cosine part, a
scale offset). Round trip: the synthesised effect, mapped to the candidate's coordinates and
back through the candidate's own model changes, is the effect synth put into the truth. And it
compares on the diagnosis's own fit recordings, not the manifest's roles.
"""

from dataclasses import dataclass

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


@dataclass(frozen=True)
class _Rec:
    name: str
    role: str = "fit"


def test_fit_recordings_are_the_diagnosis_split():
    """The cost configuration's manifest gives no roles (all ``fit``): the fit recordings the
    truth is compared on must be the diagnosis's, or the held-out one is counted among them (as
    an analysis of load_lift 91 did: 90.1 floors on all three against the diagnosis's 91.5)."""
    recs = [_Rec("up_pi"), _Rec("up_2pi"), _Rec("down_pi")]
    out = _bench().diagnosis_roles(recs, {"split": {"heldout": ["up_pi"]}})
    assert [(r.name, r.role) for r in out] == [("up_2pi", "fit"), ("down_pi", "fit"),
                                               ("up_pi", "heldout")]


def test_fit_recordings_follow_an_exchanged_split():
    recs = [_Rec("a"), _Rec("b", "heldout"), _Rec("c")]
    out = _bench().diagnosis_roles(recs, {"split": {"heldout": ["c"]}})
    assert {r.name: r.role for r in out} == {"a": "fit", "b": "fit", "c": "heldout"}
    # an older diagnosis.json without the split keeps the manifest's roles
    assert _bench().diagnosis_roles(recs, {}) == recs


def test_a_split_naming_an_unknown_recording_is_refused():
    with pytest.raises(ValueError, match="does not list"):
        _bench().diagnosis_roles([_Rec("a")], {"split": {"heldout": ["zz"]}})


@dataclass(frozen=True)
class _PRec:
    params: dict


def _truth(effect, seed=5):
    """truth.json of a case: the base coefficients 10 % off, ``effect`` concealed."""
    _, model_changes, sensor_changes = effect_changes(effect, seed=seed)
    perturbed = {k: {"value": v * 1.1} for k, v in {**START, "b_imp": 0.5}.items()}
    return {"effect": effect, "effect_parameters": model_changes, "effect_sensor": sensor_changes,
            "perturbed": perturbed}


def _diagnosis(named, values, refits=None):
    """diagnosis.json of a case that named ``named`` (None: none) with final ``values``;
    ``refits``: {effect: the refit's values} of the effects refitted."""
    effects = [{"id": k, "refitted": True, "values": v} for k, v in (refits or {}).items()]
    return {"selected": [named] if named else [], "final": {"values": values}, "effects": effects}


@pytest.mark.parametrize("concealed, named, named_value, named_changes",
                         [("encoder_scale", "slider_viscous", {"c_visc": 0.01}, {"c_visc": 0.01}),
                          ("slider_viscous", "encoder_scale", {"encoder_scale": -0.02},
                           {"encoder_scale_b": 0.98})])
def test_a_wrong_name_also_compares_the_truth_with_its_own_effect(concealed, named, named_value,
                                                                   named_changes):
    """The named hypothesis has no term for the concealed effect, so the truth is also placed in
    the concealed effect's own hypothesis: its base, its effect's model and sensor changes, and
    nothing of the named effect."""
    truth = _truth(concealed)
    name, points = _bench().points_of(_diagnosis(named, {**START, **named_value}), truth, [_PRec(START)])
    assert name == named
    mc, sc = points["truth, its effect"]
    assert {k: mc[k] for k in START} == pytest.approx({k: 1.1 * v for k, v in START.items()}, rel=1e-12)
    assert {k: v for k, v in mc.items() if k not in START} == pytest.approx(truth["effect_parameters"], rel=1e-12)
    assert sc == pytest.approx(truth["effect_sensor"], rel=1e-12)
    # the line stays in the named hypothesis: the truth's base with the named effect's final value
    named_mc, named_sc = points["truth"]
    assert {k: v for k, v in {**named_mc, **named_sc}.items() if k not in START} == pytest.approx(
        named_changes, rel=1e-12)


@pytest.mark.parametrize("named", ["encoder_scale", None])
def test_a_right_name_or_none_adds_no_point(named):
    truth = _truth("encoder_scale")
    final = {**START, **({"encoder_scale": 0.0} if named else {})}
    name, points = _bench().points_of(_diagnosis(named, final), truth, [_PRec(START)])
    assert name == "encoder_scale"
    assert "truth, its effect" not in points
    null = {**_truth("slider_viscous"), "effect": "none"}
    assert "truth, its effect" not in _bench().points_of(_diagnosis(None, START), null, [_PRec(START)])[1]


REFIT_BASE = {"k_c": 0.06, "b_c": 0.008, "k_imp": 5e12, "mu_s": 0.35, "mu_k": 0.3}


@pytest.mark.parametrize("named", ["slider_viscous", None])
def test_the_diagnosis_refit_of_the_concealed_effect_is_a_point(named):
    """Where the diagnosis refitted the concealed effect without naming it, its refit (base and
    the effect's own parameters, ``values`` in diagnosis.json) is placed in the concealed
    effect's hypothesis, beside the truth."""
    truth = _truth("encoder_scale")
    refit = {**REFIT_BASE, "encoder_scale": -0.03}
    final = {**START, **({"c_visc": 0.01} if named else {})}
    _, points = _bench().points_of(_diagnosis(named, final, {"encoder_scale": refit}), truth, [_PRec(START)])
    label = "its effect, refitted" if named else "its refit"
    assert {"its effect, refitted", "its refit"} & set(points) == {label}
    mc, sc = points[label]
    assert {k: mc[k] for k in REFIT_BASE} == pytest.approx(REFIT_BASE, rel=1e-12)
    assert set(mc) == set(REFIT_BASE)       # a sensor effect: no model change of its own
    assert sc == pytest.approx(CANDIDATES["encoder_scale"].apply({"encoder_scale": -0.03})[1], rel=1e-12)


def test_no_refit_point_without_a_refit_of_the_concealed_effect():
    """Not refitted (or a diagnosis.json older than ``values``), or refitted and named: no point."""
    truth = _truth("encoder_scale")
    others = {"slider_viscous": {**REFIT_BASE, "c_visc": 0.01}}
    for d in (_diagnosis(None, START, others), _diagnosis("slider_viscous", {**START, "c_visc": 0.01}, others),
              {**_diagnosis(None, START), "effects": [{"id": "encoder_scale", "refitted": True}]},
              _diagnosis("encoder_scale", {**START, "encoder_scale": 0.0},
                         {"encoder_scale": {**REFIT_BASE, "encoder_scale": 0.0}})):
        points = _bench().points_of(d, truth, [_PRec(START)])[1]
        assert not {"its effect, refitted", "its refit"} & set(points)


@pytest.mark.parametrize("f", [0.8, 0.93, 1.25])
def test_scaled_points_scale_every_force(f):
    """``--scale``: every force coefficient and the drag's torque-like amplitude times ``f``;
    what is not a force (b_imp is not fitted) stays."""
    hyp = Hypothesis(START, CANDIDATES["slider_viscous"])
    x = hyp.coordinates({**START, "c_visc": 0.003})
    (label, (mc, _)), = _bench().scaled_points(hyp, x, [f]).items()
    assert label == f"final x{f:g}"
    for k, v in {**START, "c_visc": 0.003}.items():
        assert mc[k] == pytest.approx(f * v, rel=1e-9), k
    assert "b_imp" not in mc


def test_scaled_points_leave_a_sensor_term():
    hyp = Hypothesis(START, CANDIDATES["encoder_scale"])
    x = hyp.coordinates({**START, "encoder_scale": -0.05})
    (_, (mc, sc)), = _bench().scaled_points(hyp, x, [0.9]).items()
    assert mc["mu_k"] == pytest.approx(0.9 * START["mu_k"])
    assert sc["encoder_scale_b"] == pytest.approx(0.95)


@pytest.mark.parametrize("text", ["", "0.9,", "0.9;1.1", "0", "-1", "nan", "inf", "1e-400"])
def test_scale_option_refuses_what_is_not_a_factor(text):
    with pytest.raises(__import__("argparse").ArgumentTypeError, match="got"):
        _bench().parse_scale(text)


def test_scale_option_reads_factors():
    assert _bench().parse_scale("0.9,1.05") == (0.9, 1.05)
