"""The diagnosis (issue 5): library, transforms, rule, and a small end-to-end proof.

The end-to-end cases are a small version of ``bench/diagnosis_grid.py`` (DIAGNOSIS.md): four
1 s recordings (N_c = 100, loads 0.5 and 1 kg, ramps to +-pi rad/s), three candidates, one
refit. A concealed viscous drag must be named, its parameter recovered and the held-out error
cut; null recordings must give "none".
"""
from __future__ import annotations

import json
import math
import signal
import subprocess
import sys
import time
from argparse import Namespace
from dataclasses import dataclass, replace
from pathlib import Path

import numpy as np
import pytest

from szdyn.diagnose.candidates import CALIBRATED, CANDIDATES, VISCOUS_PROBE_FRACTIONS, primary_std
from szdyn.diagnose.diagnosis import Diagnosis
from szdyn.diagnose.fit_pass import probe_additions
from szdyn.diagnose.engine import apply_sensor_transform, model_speed
from szdyn.diagnose.fit import Hypothesis, fit_hypothesis, jacobian, linear_step
from szdyn.diagnose.locate import FEATURES
from szdyn.diagnose.selection import (Decision, SelectionRule, close_rivals, decide, nominate, rivals, screen,
                                     settled)
from szdyn.diagnose.split import choose_heldout, exchange_pairs, exchanged, with_heldout
from szdyn.params import param_names
from szdyn.errors import UserInputError
from szdyn.run import main as run_main
from szdyn.synth import EFFECTS, RampSpec, synthesize

ROOT = Path(__file__).resolve().parents[1]

START = {"k_c": 0.05, "b_c": 7.5e-3, "k_imp": 4e12, "mu_s": 0.3, "mu_k": 0.25}


# ----------------------------------------------------------------------------- library
def test_library_covers_every_concealed_effect():
    assert set(EFFECTS) <= set(CANDIDATES)


@pytest.mark.parametrize("cid", list(CANDIDATES))
def test_candidate_at_zero_is_the_base_model(cid):
    c = CANDIDATES[cid]
    zeros = {p.name: (p.start if p.start is not None else 0.0) for p in c.params}
    zeros = {k: (0.0 if k != "v_st" else v) for k, v in zeros.items()}
    mc, sc = c.apply(zeros)
    assert mc == {} and sc == {}


@pytest.mark.parametrize("cid", [c for c in CANDIDATES if CANDIDATES[c].kind == "model"])
def test_candidate_sets_only_model_parameters(cid):
    c = CANDIDATES[cid]
    vals = {p.name: 0.5 * p.hi if p.hi > 0 else 0.5 * p.lo for p in c.params}
    mc, sc = c.apply(vals)
    assert mc and sc == {}
    assert set(mc) <= set(param_names())


def test_position_periodic_coordinates_round_trip():
    # a_rev sin(q + phi) == a_s sin(q) + a_c cos(q)
    c = CANDIDATES["position_periodic"]
    mc, _ = c.apply({"a_rev_s": 0.03, "a_rev_c": -0.04})
    q = np.linspace(0, 7, 50)
    lhs = mc["a_rev"] * np.sin(q + mc["phi_rev"])
    assert np.allclose(lhs, 0.03 * np.sin(q) - 0.04 * np.cos(q))
    assert mc["a_rev"] == pytest.approx(0.05)


def test_primary_std_by_the_delta_method():
    per = CANDIDATES["position_periodic"]
    v, sd = {"a_rev_s": 0.03, "a_rev_c": 0.04}, {"a_rev_s": 0.001, "a_rev_c": 0.001}
    # a_rev = hypot: gradient (0.6, 0.8)
    assert primary_std(per, v, sd) == pytest.approx(0.001, rel=1e-6)
    assert primary_std(per, v, sd, corr=[[1.0, 1.0], [1.0, 1.0]]) == pytest.approx(0.0014, rel=1e-6)
    assert primary_std(per, v, sd, corr=[[1.0, -1.0], [-1.0, 1.0]]) == pytest.approx(0.0002, rel=1e-5)
    # k_drive = 1 / compliance
    comp = CANDIDATES["drive_compliance"]
    assert primary_std(comp, {"drive_compliance": 0.5}, {"drive_compliance": 0.01}) == pytest.approx(0.04, rel=1e-6)
    assert math.isnan(primary_std(comp, {"drive_compliance": 0.5}, {}))


def test_hypothesis_start_and_constraint():
    h = Hypothesis(START, CANDIDATES["slider_viscous"])
    v = h.values(h.x_start())
    for k, val in START.items():
        assert v[k] == pytest.approx(val)
    assert v["c_visc"] == 0.0
    lo, hi = h.bounds()
    # mu_s >= mu_k at every corner of the box (fitted through the excess dmu_s > 0)
    for x in (lo, hi):
        vv = h.values(x)
        assert vv["mu_s"] > vv["mu_k"] > 0
    mc, sc = h.point(h.x_start())
    assert sc == {} and set(mc) == set(START)
    assert len(h.params) == len(CALIBRATED) + 1


# ----------------------------------------------------------------------------- transforms
def test_sensor_transform_scale_and_delay_are_exact_on_a_ramp():
    t = np.arange(0, 2, 1e-3)
    theta = 0.5 * 3.0 * t ** 2
    s = apply_sensor_transform(t, theta, {"encoder_scale_b": 1.02, "encoder_delay_b": 0.01})
    k = t > 0.02
    assert np.allclose(s[k], 1.02 * 0.5 * 3.0 * (t[k] - 0.01) ** 2, atol=2e-6)
    assert apply_sensor_transform(t, theta, {}) is theta


def test_model_speed_differentiates_a_ramp_exactly():
    t = np.arange(0, 2, 1e-3)
    tf = np.linspace(0.2, 1.8, 9)
    v = model_speed(t, 0.5 * 3.0 * t ** 2, tf)
    assert np.allclose(v, 3.0 * tf, rtol=1e-9, atol=1e-9)


def test_traction_runs_are_integrated_to_convergence():
    """Roller-contact friction (mu_t > 0) is stiff: Heun at 0.1 ms quietly loses a large part of
    it. The fit's run must agree with RK4 at 10 us (another integrator, converged) instead."""
    from szdyn.defaults import default_parameters
    from szdyn.drive import RampHold
    from szdyn.diagnose.engine import SIM_DT, _simulate
    from szdyn.simulate import simulate

    p0 = default_parameters()
    drive, T, mu = RampHold(a=3.14, t_ramp=1.0, t_hold=0.5), 1.5, 0.3
    p, x0 = p0.replace(mu_t=mu), p0.initial_state(None)

    def qb(params, **kw):
        q = simulate(params, drive, T, x0=x0, save_dt=SIM_DT, **kw).outputs["q_b"]
        return q - q[0]

    ref = qb(p, method="rk4", dt=1e-5)
    effect = np.abs(ref - qb(p0, method="rk4", dt=1e-5)).max()
    _, fit_run, _ = _simulate((p0.to_dict(), drive, 0.0, T, {"mu_t": mu}, False))
    heun_err = np.abs(qb(p, method="heun", dt=1e-4) - ref).max()
    assert effect > 0.1                                    # rad: the effect is there to lose
    assert heun_err > 0.2 * effect                         # the test tells a converged run apart
    assert np.abs(fit_run - ref).max() < 0.02 * effect


def test_a_drive_stiffer_than_the_features_resolve_is_rigid():
    """A compliance fitted at (or clipped to) ~0 must not become k_drive ~ 1e9: stiff, and slow."""
    from szdyn.diagnose.candidates import RIGID_COMPLIANCE, _compliance

    assert _compliance({"drive_compliance": 2e-9}) == ({}, {})
    assert _compliance({"drive_compliance": 0.5 * RIGID_COMPLIANCE}) == ({}, {})
    mc, _ = _compliance({"drive_compliance": RIGID_COMPLIANCE})
    assert mc == {"drive_mode": 2.0, "k_drive": pytest.approx(1.0 / RIGID_COMPLIANCE)}


def test_a_run_over_its_step_budget_fails_instead_of_stalling(monkeypatch):
    """dopri5 runs in a fit are capped (steps per simulated second): over it, the run fails."""
    from szdyn.defaults import default_parameters
    from szdyn.drive import RampHold
    from szdyn.diagnose import engine

    p0 = default_parameters()
    task = (p0.to_dict(), RampHold(a=3.14, t_ramp=0.3, t_hold=0.0), 0.0, 0.3, {"mu_t": 0.3}, False)
    assert engine._simulate(task) is not None
    monkeypatch.setattr(engine, "DOPRI5_MAX_STEPS_PER_S", 100.0)
    assert engine._simulate(task) is None


def test_heun_halves_its_step_only_where_the_arm_damper_makes_the_full_step_diverge():
    """Just past the threshold Heun at the fit's step does diverge, so the half step loses no
    run that worked; the half-step run agrees with dopri5; at the default damping the step is
    the full one, close below the threshold a failed full step is retried at the half step, and
    past the half step's limit too the run goes to dopri5."""
    from szdyn.defaults import default_parameters
    from szdyn.drive import RampHold
    from szdyn.diagnose import engine
    from szdyn.errors import SimulationError
    from szdyn.simulate import simulate

    p0 = default_parameters()
    # the damping whose free-arm mode z = -HEUN_DT b_c / (m_c d^2) is 2 % past Heun's -2
    b_lim = engine._ARM_MODE_MARGIN * engine.HEUN_STABILITY_LIMIT * p0["m_c"] * p0["d"] ** 2 / engine.HEUN_DT
    assert 0.0115 < b_lim < 0.012                           # N*m*s/rad, 1.57x the thesis's b_c
    steps = lambda p: [(kw["method"], kw.get("dt")) for kw in engine.integrators(p)]   # noqa: E731
    assert steps(p0) == [("heun", engine.HEUN_DT), ("dopri5", None)]
    assert steps(p0.replace(b_c=0.9 * b_lim)) == [("heun", engine.HEUN_DT), ("heun", 0.5 * engine.HEUN_DT),
                                                 ("dopri5", None)]
    p = p0.replace(b_c=1.01 * b_lim)
    assert steps(p) == [("heun", 0.5 * engine.HEUN_DT), ("dopri5", None)]
    assert steps(p0.replace(b_c=2.02 * b_lim)) == [("dopri5", None)]
    drive, T = RampHold(a=3.14, t_ramp=0.5, t_hold=0.5), 1.0
    with pytest.raises(SimulationError):
        simulate(p, drive, T, method="heun", dt=engine.HEUN_DT, save_dt=engine.SIM_DT)
    t, qb, _ = engine._simulate((p0.to_dict(), drive, 0.0, T, {"b_c": 1.01 * b_lim}, False))
    ref = simulate(p, drive, T, x0=p.initial_state(None), save_dt=engine.SIM_DT, **engine._DOPRI5).outputs["q_b"]
    t_feat = np.arange(0.1, 0.9, 0.05)
    diff = model_speed(t, qb, t_feat) - model_speed(t, ref - ref[0], t_feat)
    assert np.abs(diff).max() < 5e-5                       # rad/s (measured 9e-6; noise floors ~1e-2)


# ----------------------------------------------------------------------------- rule
def test_rule_says_none_at_the_noise_floor_and_picks_an_explaining_candidate():
    rule = SelectionRule()
    assert not rule.mismatch(b=0.006, floor=0.005)
    assert rule.mismatch(b=0.05, floor=0.005)
    good = rule.assess(b=0.05, c=0.006, floor=0.005, h0=0.06, hc=0.008, n_fit=400, k=1)
    assert good["eligible"] and good["explained"] > 0.95
    # fits better but does not generalise to held-out data
    overfit = rule.assess(b=0.05, c=0.006, floor=0.005, h0=0.06, hc=0.058, n_fit=400, k=1)
    assert not overfit["eligible"]
    # the median of the held-out recordings improves, all of them together get worse (null seed
    # 22: one recording 42 % better, the other 19 % worse): not eligible
    assert good["eligible"] and rule.assess(b=0.05, c=0.006, floor=0.005, h0=0.06, hc=0.008,
                                            hc_all=0.008, n_fit=400, k=1)["eligible"]
    split = rule.assess(b=0.05, c=0.006, floor=0.005, h0=0.06, hc=0.008, hc_all=0.061, n_fit=400, k=1)
    assert not split["eligible"] and not split["generalises"]
    # explains a little: rejected even though the information criterion improves
    weak = rule.assess(b=0.05, c=0.045, floor=0.005, h0=0.06, hc=0.04, n_fit=400, k=1)
    assert weak["dbic"] > rule.min_dbic and not weak["eligible"]
    # a rival 1 % worse in RSS over 400 samples (200 effective: 2.0 < 10) cannot be told apart;
    # one 20 % worse (36.5) can
    assert rule.indistinguishable(rss_selected=1.0, rss_other=1.01, n_fit=400)
    assert not rule.indistinguishable(rss_selected=1.0, rss_other=1.2, n_fit=400)


def _refit(c, b=0.05, floor=0.005, eligible=True, held=0.01, n=400):
    """An assessed refit at fit RMSE ``c`` as :func:`decide` reads it."""
    return {"eligible": eligible, "explained": (b * b - c * c) / (b * b - floor * floor),
            "heldout_rmse": held, "rmse_fit": c, "rss_fit": c * c * n, "n_fit": n}


def test_decide_names_only_an_effect_that_reaches_the_floor():
    rule = SelectionRule()
    floor = 0.005
    # nothing missing: none, whatever the refits say
    assert decide(rule, {"a": _refit(0.006)}, mismatch=False, floor=floor).verdict == "none"
    # the eligible candidate with the largest explained share is selected; a rival 1 % worse in
    # RSS is indistinguishable, an ineligible one is not
    dec = decide(rule, {"a": _refit(0.006), "b": _refit(0.006 * 1.005), "c": _refit(0.0055, eligible=False)},
                 mismatch=True, floor=floor)
    assert (dec.verdict, dec.selected, dec.indistinguishable, dec.partial) == ("selected", ["a"], ["b"], [])
    # out-of-sample slider_stribeck seed 13: calibrated 28x the floor, encoder_scale eligible
    # (explains 71 %) but leaving 15x: partial, the mismatch stays unexplained
    b = 27.8 * floor
    partial = _refit(15.0 * floor, b=b)
    assert partial["explained"] > rule.min_explained
    dec = decide(rule, {"encoder_scale": partial, "slider_viscous": _refit(b, b=b, eligible=False)},
                 mismatch=True, floor=floor)
    assert (dec.verdict, dec.selected, dec.partial) == ("unexplained", [], ["encoder_scale"])
    # the limit is max_remaining floors, inclusive; a partial rival does not stop a complete one
    at = _refit(rule.max_remaining * floor, b=b)
    dec = decide(rule, {"p": partial, "q": at}, mismatch=True, floor=floor)
    assert (dec.verdict, dec.selected, dec.partial) == ("selected", ["q"], ["p"])
    # out-of-sample load_lift seed 14: the fit stays 21x the floor (a recording near the cliff)
    # but the held-out recordings go from 185x to 1.9x: explained; not when the held-out
    # recordings were within the limit already (they then show nothing), nor without them
    lift = _refit(21.4 * floor, b=b, held=1.9 * floor)
    dec = decide(rule, {"load_lift": lift}, mismatch=True, floor=floor, heldout_before=185 * floor)
    assert (dec.verdict, dec.selected, dec.partial) == ("selected", ["load_lift"], [])
    for h0 in (4.0 * floor, None, math.nan):
        dec = decide(rule, {"load_lift": lift}, mismatch=True, floor=floor, heldout_before=h0)
        assert (dec.verdict, dec.partial) == ("unexplained", ["load_lift"])
    # no candidate at all: unexplained, nothing partial
    assert decide(rule, {}, mismatch=True, floor=floor) == Decision("unexplained")


def test_close_rivals_are_parted_by_the_heldout_recordings():
    rule = SelectionRule()
    f, b, h0 = 0.01508, 0.03376, 0.0505

    def r(c, held, eligible=True):
        return _refit(c, b=b, floor=f, held=held, eligible=eligible)

    # encoder_scale seed 27: the drag explains more (1.50 against 1.65 floors), the scale holds
    # out 3.1x better: both within rival_floor (2) floors, so the held-out recordings decide
    sv, es = r(0.02265, 0.02001), r(0.02490, 0.00648)
    assert sv["explained"] > es["explained"]
    dec = decide(rule, {"slider_viscous": sv, "encoder_scale": es}, mismatch=True, floor=f, heldout_before=h0)
    assert (dec.verdict, dec.selected, dec.passed_over) == ("selected", ["encoder_scale"], "slider_viscous")
    assert dec.indistinguishable == ["slider_viscous"]
    # the margin is rule.rival_heldout (2x), inclusive
    at = r(0.02490, 0.02001 / rule.rival_heldout)
    assert decide(rule, {"sv": sv, "es": at}, mismatch=True, floor=f, heldout_before=h0).selected == ["es"]
    short = r(0.02490, 0.02001 / rule.rival_heldout * (1 + 1e-9))
    dec = decide(rule, {"sv": sv, "es": short}, mismatch=True, floor=f, heldout_before=h0)
    assert (dec.selected, dec.passed_over) == (["sv"], None)
    # the rival beyond rival_floor floors (the fit parts them), or the one explaining most beyond it
    # (then every rival is): the explained share decides, however the held-out recordings look
    far = r(rule.rival_floor * f * (1 + 1e-9), 0.001)
    assert decide(rule, {"sv": sv, "es": far}, mismatch=True, floor=f, heldout_before=h0).selected == ["sv"]
    lead_far, rival_far = r(2.5 * f, 0.02), r(2.6 * f, 0.001)
    assert decide(rule, {"a": lead_far, "b": rival_far}, mismatch=True, floor=f, heldout_before=h0).selected == ["a"]
    # an ineligible rival, or no held-out recordings (NaN): no say
    dec = decide(rule, {"sv": sv, "es": r(0.02490, 0.00648, eligible=False)}, mismatch=True, floor=f,
                 heldout_before=h0)
    assert dec.selected == ["sv"]
    nan = {"sv": {**sv, "heldout_rmse": math.nan}, "es": {**es, "heldout_rmse": math.nan}}
    assert decide(rule, nan, mismatch=True, floor=f).selected == ["sv"]
    # a close rival without a held-out score does not hide one with it
    dec = decide(rule, {"sv": sv, "n": {**es, "heldout_rmse": math.nan}, "es": es}, mismatch=True, floor=f,
                 heldout_before=h0)
    assert (dec.selected, dec.passed_over) == (["es"], "sv")
    # of several close rivals, the best held-out; the verdict never changes (no new discovery)
    third = r(0.0290, 0.005)
    dec = decide(rule, {"sv": sv, "es": es, "x": third}, mismatch=True, floor=f, heldout_before=h0)
    assert (dec.selected, dec.passed_over) == (["x"], "sv")
    assert decide(rule, {"sv": sv, "es": es}, mismatch=False, floor=f).verdict == "none"
    # friction_asymmetry seed 27: load_lift close too (1.80 floors), but friction_asymmetry both
    # explains most and holds out best: unchanged
    fa, ll = _refit(0.01039, b=0.2047, floor=0.0101, held=0.02704), _refit(0.01821, b=0.2047, floor=0.0101, held=0.26302)
    dec = decide(rule, {"friction_asymmetry": fa, "load_lift": ll}, mismatch=True, floor=0.0101, heldout_before=0.3959)
    assert (dec.selected, dec.passed_over) == (["friction_asymmetry"], None)


def test_rivals_are_the_next_screened_candidates_when_the_winner_leaves_the_fit_off():
    rule, ranking = SelectionRule(), ["encoder_scale", "wheel_band_traction", "slider_viscous", "load_lift", "x"]
    refitted = {"encoder_scale": {}, "wheel_band_traction": {}}
    # slider_viscous seed 15: encoder_scale selected at 4.7 floors, the drag ranked third
    assert rivals(rule, ["encoder_scale"], 4.7e-2, 1e-2, ranking, refitted, 2) == ["slider_viscous", "load_lift"]
    assert rivals(rule, ["encoder_scale"], 4.7e-2, 1e-2, ranking, refitted, 1) == ["slider_viscous"]
    # within rule.rival_floor (2) floors, nothing selected, or switched off: no rivals
    assert rivals(rule, ["encoder_scale"], 2.0e-2, 1e-2, ranking, refitted, 2) == []
    assert rivals(rule, [], math.nan, 1e-2, ranking, refitted, 2) == []
    assert rivals(rule, ["encoder_scale"], 4.7e-2, 1e-2, ranking, refitted, 0) == []


def test_a_candidate_within_the_rival_floor_settles_the_further_starts_of_the_others():
    rule, floor = SelectionRule(), 1e-2
    # load_lift seed 24: load_lift at 1.8 floors, then wheel_band_traction's first start at 18 %:
    # its second and fourth starts took ~1650 s
    lead = {"eligible": True, "rmse_fit": 1.8e-2}
    refits = {"friction_asymmetry": {"eligible": True, "rmse_fit": 7.6e-2},   # partial
              "load_lift": lead}
    assert settled(rule, refits, floor, exclude="wheel_band_traction") == "load_lift"
    assert settled(rule, refits, floor, exclude="load_lift") is None   # not its own
    # the boundary is rule.rival_floor, as for rivals
    assert settled(rule, {"load_lift": {**lead, "rmse_fit": rule.rival_floor * floor}}, floor) == "load_lift"
    assert settled(rule, {"load_lift": {**lead, "rmse_fit": rule.rival_floor * floor * (1 + 1e-9)}}, floor) is None
    # not eligible (e.g. it does not generalise): settles nothing
    assert settled(rule, {"load_lift": {**lead, "eligible": False}}, floor) is None
    # a rule whose rival floor lies beyond max_remaining: only a candidate that explains the mismatch
    wide = SelectionRule(rival_floor=6.0)
    assert settled(wide, {"load_lift": {**lead, "rmse_fit": 5.5 * floor}}, floor) is None
    assert settled(wide, {"load_lift": {**lead, "rmse_fit": 4.9 * floor}}, floor) == "load_lift"


def test_close_rivals_are_the_eligible_candidates_within_the_rival_floor_when_two_or_more():
    rule, floor = SelectionRule(), 0.02309
    # encoder_scale seed 30 (out of sample): the drag continued to 1.20 floors, the scale stopped
    # by its budget at 1.28; both are to be finished before the rule compares them
    refits = {"slider_viscous": {"eligible": True, "rmse_fit": 0.02771},
              "encoder_scale": {"eligible": True, "rmse_fit": 0.0296},
              "friction_drift": {"eligible": True, "rmse_fit": 0.0700},     # beyond 2 floors
              "load_lift": {"eligible": False, "rmse_fit": 0.0250}}         # not eligible
    assert close_rivals(rule, refits, floor) == ["slider_viscous", "encoder_scale"]
    # one alone within the floor has no rival
    assert close_rivals(rule, {k: refits[k] for k in ("slider_viscous", "friction_drift")}, floor) == []
    assert close_rivals(rule, {}, floor) == []
    # the boundary is rule.rival_floor, as for settled()
    edge = {"a": {"eligible": True, "rmse_fit": rule.rival_floor * floor},
            "b": {"eligible": True, "rmse_fit": floor}}
    assert close_rivals(rule, edge, floor) == ["a", "b"]
    edge["a"]["rmse_fit"] *= 1 + 1e-9
    assert close_rivals(rule, edge, floor) == []


def test_linear_screening_recovers_a_linear_effect():
    rng = np.random.default_rng(0)
    Jb = rng.standard_normal((200, 3))
    Jc = rng.standard_normal((200, 1))
    r0 = Jb @ np.array([0.1, -0.2, 0.05]) + 0.3 * Jc[:, 0] + 1e-6 * rng.standard_normal(200)
    dx, rss = screen(r0, Jb, Jc, -np.ones(4), np.ones(4))
    assert np.allclose(dx, [0.1, -0.2, 0.05, 0.3], atol=1e-5)
    assert rss < 1e-8
    # a bound that forbids the needed sign leaves the residual of that column
    dx2, rss2 = screen(r0, Jb, Jc, np.r_[-np.ones(3), 0.0], np.r_[np.ones(3), 0.0])
    assert rss2 > 1.0


class _CurvedModel:
    """Stand-in for FeatureModel: a residual that is nonlinear in the log coefficients, zero at
    TARGET, so that one Jacobian cannot reach the optimum."""

    TARGET = {"k_c": 0.07, "b_c": 5e-3, "k_imp": 6e12, "mu_s": 0.36, "mu_k": 0.2}

    def residuals(self, points, which):
        out = []
        for mc, _ in points:
            z = np.array([math.log(mc[k] / self.TARGET[k]) for k in sorted(self.TARGET)])
            r = z + 0.8 * z ** 3
            out.append(np.concatenate([r * w for w in (1.0, 0.5, 2.0)] * len(which)))
        return out


def test_fit_stopped_by_its_budget_can_be_continued_to_the_optimum():
    model, h = _CurvedModel(), Hypothesis(START)
    first = fit_hypothesis(model, h, [0], max_jac=1)
    assert first.budget_hit and first.extra["njac"] <= 2
    # one more Jacobian must improve on where the first stopped: a restart from the start
    # would retrace the first fit exactly
    one = fit_hypothesis(model, h, [0], max_jac=1, previous=first)
    assert one.rss_fit < first.rss_fit
    more = fit_hypothesis(model, h, [0], max_jac=30, previous=first)
    assert not more.budget_hit, more.status
    assert more.extra["continued"] and more.extra["njac"] > first.extra["njac"]
    assert more.rss_fit < 1e-3 * first.rss_fit
    for k, v in _CurvedModel.TARGET.items():
        assert more.values[k] == pytest.approx(v, rel=1e-3), k


class _LinearModel(_CurvedModel):
    """A residual linear in the fit coordinates (log coefficients, ``dmu_s`` as ``mu_s - mu_k``),
    zero at TARGET: one Gauss-Newton step from anywhere is exact."""

    M = np.random.default_rng(3).normal(size=(15, 5))

    def residuals(self, points, which):
        t = self.TARGET
        out = []
        for mc, _ in points:
            z = [math.log(mc[k] / t[k]) for k in ("k_c", "b_c", "k_imp", "mu_k")]
            z.append(math.log((mc["mu_s"] - mc["mu_k"]) / (t["mu_s"] - t["mu_k"])))
            out.append(np.concatenate([self.M @ np.array(z)] * len(which)))
        return out


class _NoisyCurvedModel(_CurvedModel):
    """The curved stand-in plus a residual no coefficient changes (the noise of a recording)."""

    NOISE = np.random.default_rng(4).normal(scale=0.05, size=30)

    def residuals(self, points, which):
        return [np.append(r, self.NOISE) for r in super().residuals(points, which)]


def test_linear_step_is_the_gauss_newton_step_tried_with_model_runs():
    model, h = _LinearModel(), Hypothesis(START)
    first = fit_hypothesis(model, h, [0], max_jac=1)   # one Jacobian: not yet at TARGET
    # the step from the (exact) Jacobian lands on TARGET; of the tried fractions 1 is the best
    x, rss, step = linear_step(model, h, first, [0])
    assert rss < 1e-16 * first.rss_fit and step == "the full step"
    for k, v in _LinearModel.TARGET.items():
        assert h.values(x)[k] == pytest.approx(v, rel=1e-6), k
    # only half of it: a quarter of the residual energy (the residual is linear)
    x, rss, step = linear_step(model, h, first, [0], fractions=(0.5,))
    assert rss == pytest.approx(0.25 * first.rss_fit, rel=1e-6) and step == "0.5 x the full step"


class _RippledDelayModel(_LinearModel):
    """A band-encoder delay (residual linear in it, zero at DELAY, s; a sensor change, so no
    model run depends on it) on a base whose cost is rippled like the impacts': linear with its
    optimum half a ripple period (the finite-difference probe) from TARGET, plus a ripple that is
    zero at TARGET and at whole periods. A forward-difference Jacobian at TARGET sees no ripple."""

    DELAY = 0.012
    A = np.random.default_rng(5).normal(size=15)
    PERIOD = np.array([p.probe for p in CALIBRATED])
    Z_OPT = 0.5 * PERIOD

    def residuals(self, points, which):
        t = self.TARGET
        out = []
        for mc, sc in points:
            z = np.array([math.log(mc[k] / t[k]) for k in ("k_c", "b_c", "k_imp", "mu_k")]
                         + [math.log((mc["mu_s"] - mc["mu_k"]) / (t["mu_s"] - t["mu_k"]))])
            ripple = np.sqrt(1.0 - np.cos(2 * math.pi * z / self.PERIOD))
            delay = 100.0 * self.A * (sc.get("encoder_delay_b", 0.0) - self.DELAY)
            out.append(np.concatenate([self.M @ (z - self.Z_OPT), ripple, delay] * len(which)))
        return out


def test_linear_step_also_tries_the_candidates_own_step_with_the_base_held():
    # a fit stalled in a ripple of the base's cost with the delay short of its optimum
    # (encoder_delay seed 32): the full step, led by the base's smooth part, lands on the ripple
    # and fits worse; the delay's own step, the base held, removes the delay's part of the residual
    model = _RippledDelayModel()
    h = Hypothesis(_LinearModel.TARGET, CANDIDATES["encoder_delay"])
    x0 = h.coordinates({**_LinearModel.TARGET, "encoder_delay": 0.0097})
    J, f0 = jacobian(model, h, x0, [0])
    some_fit = fit_hypothesis(model, h, [0], x0=x0, max_jac=1)
    stalled = replace(some_fit, x=x0, J=J, rss_fit=float(f0 @ f0))
    base_part = float(np.sum(f0[:-15] ** 2))   # what the delay cannot fit
    _, rss_full, _ = linear_step(model, h, stalled, [0], own=False)
    x, rss, step = linear_step(model, h, stalled, [0])
    assert step == "the candidate's own step"
    assert rss_full > stalled.rss_fit   # the full step alone: worse than where the fit stalled
    assert rss == pytest.approx(base_part, rel=1e-9) and rss < 0.5 * stalled.rss_fit
    assert h.values(x)["encoder_delay"] == pytest.approx(_RippledDelayModel.DELAY, rel=1e-9)
    assert np.array_equal(x[:h.n_base], x0[:h.n_base])   # the base held
    # the base model has no own step: the same as the full step alone
    hb = Hypothesis(START)
    first = fit_hypothesis(_LinearModel(), hb, [0], max_jac=1)
    assert np.array_equal(linear_step(_LinearModel(), hb, first, [0])[0],
                          linear_step(_LinearModel(), hb, first, [0], own=False)[0])


def test_a_stalled_calibration_is_restarted_from_its_linear_step_and_a_finished_one_is_kept():
    model, h = _CurvedModel(), Hypothesis(START)
    d = Diagnosis(unstall=2)
    d.floor_ = 1e-3
    stalled = fit_hypothesis(model, h, [0], max_jac=1)   # stands in for a fit that stopped early
    cal = d._unstall(model, h, stalled, [0])
    assert cal is not stalled and 1 <= cal.extra["unstalled"] <= 2
    assert cal.extra["njac"] > stalled.extra["njac"] and cal.rss_fit < 1e-3 * stalled.rss_fit
    # at the optimum the linear step fits no better: the calibration is kept as it is (with a
    # residual the coefficients cannot fit, as in real recordings: an exact zero would make any
    # round-off change look significant to a scale-free criterion)
    noisy = _NoisyCurvedModel()
    done = fit_hypothesis(noisy, h, [0], max_jac=30)
    assert not done.budget_hit
    assert d._unstall(noisy, h, done, [0]) is done
    # unstall=0: never tried
    assert Diagnosis(unstall=0)._unstall(model, h, stalled, [0]) is stalled


def test_a_stalled_refit_is_restarted_within_its_own_budget_and_keeps_its_start():
    model, h = _CurvedModel(), Hypothesis(START)
    d = Diagnosis(unstall=2)
    d.floor_ = 1e-3
    stalled = fit_hypothesis(model, h, [0], max_jac=1)
    stalled.extra.update(start="linear step", restart="the uncalibrated coefficients (second start)")
    res = d._unstall(model, h, stalled, [0], what="refit of a candidate", max_jac=1)
    assert res is not stalled and res.rss_fit < stalled.rss_fit
    assert res.extra["start"] == "linear step"
    assert res.extra["restart"] == "the uncalibrated coefficients (second start)"
    # each new fit is held to the refit's budget (1 Jacobian, plus the one at its end point)
    assert res.extra["njac"] <= stalled.extra["njac"] + 2 * res.extra["unstalled"]
    # the report says which step each restart started from (the curved stand-in's base has no
    # own step: the full one or a fraction of it)
    from szdyn.diagnose.report import _status
    steps = res.extra["unstall_steps"]
    assert len(steps) == res.extra["unstalled"] and all(s.endswith("the full step") for s in steps)
    assert f"restarted {res.extra['unstalled']}x from its linear step (a stall; {steps[0]}" in _status(res)


class _WantsNegativeTraction(_CurvedModel):
    """The curved stand-in plus a residual that a negative mu_t would reduce (the real model
    rejects mu_t < 0)."""

    def residuals(self, points, which):
        for mc, _ in points:
            if mc.get("mu_t", 0.0) < 0:
                raise ValueError(f"mu_t = {mc['mu_t']} < 0")
        base = super().residuals(points, which)
        return [np.append(r, 1.0 + mc.get("mu_t", 0.0)) for r, (mc, _) in zip(base, points)]


def test_screened_starts_stay_inside_the_bounds():
    # the bounded linear step lands on mu_t's lower bound 0, which screen() widens by 1e-12;
    # a start of mu_t = -1e-12 stopped a grid case with a ParameterError
    d = Diagnosis(candidates=["wheel_band_traction"])
    x0 = Hypothesis(START).x_start()
    (scr,) = d._screen(_WantsNegativeTraction(), START, x0, [0], 0.01)
    lo, hi = Hypothesis(START, CANDIDATES["wheel_band_traction"]).bounds()
    x = np.array(scr["x_start"])
    assert np.all(x >= lo) and np.all(x <= hi), x
    assert x[-1] == 0.0   # mu_t at its bound: the step wanted it negative


def test_every_signature_names_a_located_feature():
    # a misspelt feature would never be nominated, silently
    for c in CANDIDATES.values():
        assert c.signature and set(c.signature) <= set(FEATURES), c.id


def test_nomination_follows_the_leading_feature_only_above_its_threshold():
    lib = list(CANDIDATES.values())
    fol = [{"feature": "direction", "r2": 0.8}, {"feature": "band_speed", "r2": 0.6}]
    assert nominate(fol, lib, min_r2=0.3) == ["friction_asymmetry", "load_lift"]
    assert nominate(fol, lib, min_r2=0.9) == []
    # the second feature does not nominate, however high
    assert "slider_viscous" not in nominate(fol, lib, min_r2=0.3)
    assert nominate([{"feature": "time", "r2": 0.5}], lib, min_r2=0.3) == ["friction_drift"]
    assert nominate([{"feature": "time", "r2": float("nan")}], lib, min_r2=0.3) == []
    assert nominate([], lib, min_r2=0.0) == []


def test_amplitude_starts_switch_the_effect_on_at_fractions_of_its_bounds():
    xb = np.full(len(CALIBRATED), 0.03)
    h = Hypothesis(START, CANDIDATES["friction_asymmetry"])
    starts = Diagnosis._starts(h, xb, h.x_start())
    assert sorted(x[-1] for x in starts) == pytest.approx([-0.35, -0.175, 0.175, 0.35])
    assert all(np.array_equal(x[:h.n_base], xb) for x in starts)
    # no probe at a zero bound (that is "off"); v_st-like shape parameters are not probed
    h = Hypothesis(START, CANDIDATES["slider_viscous"])
    assert [x[-1] for x in Diagnosis._starts(h, xb, h.x_start())] == pytest.approx([0.025, 0.05])
    speed = np.linspace(-2.0, 6.0, 81)
    for cid in CANDIDATES:
        h = Hypothesis(START, CANDIDATES[cid])
        lo, hi = h.bounds()
        for x in Diagnosis._starts(h, xb, h.x_start(), speed):
            assert np.all(x >= lo) and np.all(x <= hi), cid


def test_stribeck_probes_move_the_peak_out_of_the_calibrated_friction():
    xb = np.full(len(CALIBRATED), 0.03)
    h = Hypothesis(START, CANDIDATES["slider_stribeck"])
    x_lin = np.r_[xb, 0.01, 0.3]
    with pytest.raises(ValueError, match="band speed"):
        Diagnosis._starts(h, xb, x_lin)
    speed = np.r_[np.full(50, 0.2), np.full(50, 3.0)]          # rad/s, half slow, half fast
    cal = h.values(np.r_[xb, 0.0, 0.5])
    starts = Diagnosis._starts(h, xb, x_lin, speed)
    assert len(starts) == 8
    for x in starts:
        v = h.values(x)
        assert v["mu_st"] / cal["mu_k"] == pytest.approx(0.25) or v["mu_st"] / cal["mu_k"] == pytest.approx(0.5)
        w = np.mean(np.exp(-(speed / v["v_st"]) ** 2))
        # the mean sliding friction over the recorded speeds is the calibrated one ...
        assert v["mu_k"] + v["mu_st"] * w == pytest.approx(cal["mu_k"], rel=1e-9)
        # ... and the friction at rest too, unless that would put mu_s under mu_k (then the
        # static excess is the smallest the fit allows)
        if cal["mu_s"] - v["mu_st"] > v["mu_k"] + 0.2 * (START["mu_s"] - START["mu_k"]):
            assert v["mu_s"] + v["mu_st"] == pytest.approx(cal["mu_s"], rel=1e-9)
        else:
            assert v["mu_s"] - v["mu_k"] == pytest.approx(0.2 * (START["mu_s"] - START["mu_k"]), rel=1e-6)
        # the coefficients the friction does not touch stay as calibrated
        assert all(v[k] == pytest.approx(cal[k]) for k in ("k_c", "b_c", "k_imp"))
    assert sorted({round(h.values(x)["v_st"], 6) for x in starts}) == [0.1, 0.3, 1.0, 2.5]


def test_viscous_probes_move_the_drag_out_of_the_calibrated_kinetic_friction():
    xb = np.full(len(CALIBRATED), 0.03)
    h = Hypothesis(START, CANDIDATES["slider_viscous"])
    x_lin = np.r_[xb, 0.0]
    speed = np.r_[np.full(60, 3.0), np.full(40, -6.0)]            # rad/s, both directions
    scale = np.r_[np.full(30, 0.5), np.full(70, 1.0)] * 0.02 * 9.80665   # R_bo m_b g (N m), two loads
    with pytest.raises(ValueError, match="band speed"):
        Diagnosis._own_starts(h, xb, x_lin)
    cal = h.values(x_lin)
    starts = Diagnosis._own_starts(h, xb, x_lin, speed, scale)
    assert len(starts) == len(VISCOUS_PROBE_FRACTIONS)
    fractions = []
    lo, hi = h.bounds()
    for x in starts:
        v = h.values(x)
        # the mean sliding torque over the moving samples is the calibrated one: the drag takes
        # over what mu_k gives up
        calibrated = np.mean(scale * cal["mu_k"])
        assert np.mean(scale * v["mu_k"] + v["c_visc"] * np.abs(speed)) == pytest.approx(calibrated, rel=1e-9)
        fractions.append(1.0 - v["mu_k"] / cal["mu_k"])
        # the friction at rest is kept (here the static excess stays inside its bound at every
        # fraction, so no clipping moves it)
        assert math.log((cal["mu_s"] - v["mu_k"]) / (START["mu_s"] - START["mu_k"])) < hi[4]
        assert v["mu_s"] == pytest.approx(cal["mu_s"], rel=1e-9)
        assert all(v[k] == pytest.approx(cal[k]) for k in ("k_c", "b_c", "k_imp"))
    assert fractions == pytest.approx(list(VISCOUS_PROBE_FRACTIONS))
    # besides its own probes, it keeps the bound-fraction ones (the refit's third and fourth starts)
    assert [x[-1] for x in Diagnosis._starts(h, xb, x_lin, speed, scale)] == pytest.approx([0.025, 0.05])
    # without a moving sample there is nothing to trade
    assert Diagnosis._own_starts(h, xb, x_lin, speed[:0], scale[:0]) == []


class _ViscousDrag:
    """Stand-in for FeatureModel: the residual is the truth's sliding torque minus the model's at
    the recorded band speeds (truth: mu_k 0.20 plus a drag c_visc 0.004 N m s/rad), and each of
    two loads sticks (a residual of 10) once the model's torque at its top speed exceeds the
    truth's there by more than 0.02 N m."""

    speed = np.r_[np.linspace(0.5, 3.2, 50), np.linspace(0.5, 6.3, 50)]
    scale = np.r_[np.full(50, 0.5), np.full(50, 1.0)] * 0.02 * 9.80665

    def torque(self, mc):
        return self.scale * mc["mu_k"] + mc.get("c_visc", 0.0) * self.speed

    def residuals(self, points, which):
        truth = self.torque({"mu_k": 0.20, "c_visc": 0.004})
        out = []
        for mc, _ in points:
            m = self.torque(mc)
            stick = [10.0 * (m[k] - truth[k] > 0.02) for k in (49, 99)]
            out.append(np.r_[truth - m, stick])
        return out


def test_viscous_probes_leave_the_calibrated_valley_where_a_drag_on_top_sticks():
    model, d = _ViscousDrag(), Diagnosis(candidates=["slider_viscous"])
    d._moving_speed, d._moving_slider_scale = model.speed, model.scale
    base = Hypothesis(START)
    truth = model.torque({"mu_k": 0.20, "c_visc": 0.004})
    # the calibrated base: mu_k carries the mean of the drag (least squares on the torques)
    mu_cal = float(truth @ model.scale / (model.scale @ model.scale))
    cal = base.coordinates({**START, "mu_k": mu_cal})
    (r0,) = model.residuals([base.point(cal)], [0])
    h = Hypothesis(START, CANDIDATES["slider_viscous"])
    probes = d._probe(model, h, cal, np.r_[cal, 0.0], [0], own=True)
    assert len(probes) == len(VISCOUS_PROBE_FRACTIONS)
    assert all(k == "effect probe moved out of the calibrated base" for k, _, _ in probes)
    name, x, rss = min(probes, key=lambda t: t[2])
    assert rss < 0.5 * float(r0 @ r0)
    # the same drag added on top of the calibrated friction sticks the band and fits worse
    (r_top,) = model.residuals([h.point(np.r_[cal, x[-1]])], [0])
    assert float(r_top @ r_top) > float(r0 @ r0)
    # its bound-fraction probes (kept besides) lie on top of the calibration and stick
    d._J_base = np.zeros((r0.size, len(CALIBRATED)))    # no linear base correction
    generic = d._probe(model, h, cal, np.r_[cal, 0.0], [0], own=False)
    assert [k for k, _, _ in generic[:2]] == ["calibrated + effect amplitude probe"] * 2
    assert all(r > float(r0 @ r0) for _, _, r in generic)
    assert d._probe(model, h, cal, np.r_[cal, 0.0], [0])[0][0] == "calibrated + effect amplitude probe"


class _StickingBackward:
    """Stand-in for FeatureModel: a forward run whose residual is log(friction) (truth 0.2) and a
    backward run that sticks (no residual change) until the friction exceeds 0.28 (truth 0.3:
    a miss of 0.2 at any friction below). Truth: mu_k 0.25, fric_asym -0.2."""

    def residuals(self, points, which):
        out = []
        for mc, _ in points:
            a = mc.get("fric_asym", 0.0)
            stick = lambda f: 10.0 * max(f - 0.28, 0.0)   # noqa: E731
            fwd = math.log(0.2 / (mc["mu_k"] * (1 + a)))
            bwd = stick(0.3) - stick(mc["mu_k"] * (1 - a))
            out.append(np.array([fwd, bwd] + [math.log(mc[k] / START[k]) for k in ("k_c", "b_c", "k_imp")]))
        return out


def test_probe_with_base_correction_finds_an_effect_the_linearisation_cannot():
    model, d = _StickingBackward(), Diagnosis(candidates=["friction_asymmetry"])
    xb = Hypothesis(START).x_start()
    xb[3] = math.log(0.2 / START["mu_k"])    # calibrated on the forward run: mu_k = 0.2
    _, r0 = jacobian(model, Hypothesis(START), xb, [0])
    assert r0[1] == pytest.approx(0.2) and abs(r0[0]) < 1e-12
    # linearly the asymmetry is a copy of the mu_k column on the forward run, and nothing on the
    # stuck backward one: the screening finds no gain at all
    (scr,) = d._screen(model, START, xb, [0], 0.01)
    assert scr["rmse_linear"] == pytest.approx(math.sqrt(float(r0 @ r0) / r0.size), rel=1e-6)
    # ... and the detectable amplitude says so: no linear trace beyond what mu_k absorbs
    assert scr["detectable"] == [{"parameters": ["fric_asym"], "unit": "1", "amplitude": math.inf,
                                  "amplitude_most_visible": math.inf, "at": {}}]
    h = Hypothesis(START, CANDIDATES["friction_asymmetry"])
    probes = d._probe(model, h, xb, np.array(scr["x_start"]), [0])
    kinds = [k for k, _, _ in probes]
    assert kinds.count("calibrated + effect amplitude probe") == 4 == len(probes) // 2
    name, x, rss = min(probes, key=lambda t: t[2])
    # switched on alone, the asymmetry spoils the forward run; with mu_k raised to compensate
    # (the linear base correction) it frees the backward run
    assert name == "effect amplitude probe + linear base correction"
    assert x[-1] == pytest.approx(-0.175) and h.values(x)["mu_k"] > 0.2
    assert rss < 0.6 * float(r0 @ r0)
    assert all(r > float(r0 @ r0) for k, _, r in probes if k == "calibrated + effect amplitude probe")


class _StribeckCurve:
    """Stand-in for FeatureModel: the residual is the truth's sliding friction minus the model's at
    the recorded band speeds (truth: mu_k 0.22 plus a Stribeck peak 0.1 at v_st 0.5 rad/s),
    and a start that sticks when the friction at rest (mu_s + mu_st) exceeds 0.42."""

    speed = np.r_[np.linspace(0.05, 1.0, 40), np.linspace(1.0, 6.0, 60)]

    @staticmethod
    def mu(mc, u):
        return mc["mu_k"] + mc.get("mu_st", 0.0) * np.exp(-(u / mc.get("v_st", 1.0)) ** 2)

    def residuals(self, points, which):
        truth = self.mu({"mu_k": 0.22, "mu_st": 0.1, "v_st": 0.5}, self.speed)
        return [np.r_[truth - self.mu(mc, self.speed),
                      10.0 * max(mc["mu_s"] + mc.get("mu_st", 0.0) - 0.42, 0.0)] for mc, _ in points]


def test_stribeck_probes_leave_the_calibrated_valley_where_a_peak_on_top_sticks():
    model, d = _StribeckCurve(), Diagnosis(candidates=["slider_stribeck"])
    d._moving_speed = model.speed
    base = Hypothesis(START)
    # the calibrated base: mu_k carries the mean friction, mu_s the static peak at 0.40
    truth = model.mu({"mu_k": 0.22, "mu_st": 0.1, "v_st": 0.5}, model.speed)
    cal = base.coordinates({**START, "mu_k": float(np.mean(truth)), "mu_s": 0.40})
    (r0,) = model.residuals([base.point(cal)], [0])
    h = Hypothesis(START, CANDIDATES["slider_stribeck"])
    probes = d._probe(model, h, cal, np.r_[cal, 0.0, 0.5], [0])
    assert len(probes) == 8 and all(k == "effect probe moved out of the calibrated base" for k, _, _ in probes)
    name, x, rss = min(probes, key=lambda t: t[2])
    assert rss < 0.5 * float(r0 @ r0)
    # the same peak added on top of the calibrated friction sticks the band and fits worse
    on_top = np.r_[cal, x[-2:]]
    (r_top,) = model.residuals([h.point(on_top)], [0])
    assert float(r_top @ r_top) > float(r0 @ r0)


def test_probe_screening_gives_own_probes_a_slot_apart_from_the_best_generic_probe():
    rule = SelectionRule()
    n_fit, rss_base = 2000, 2000.0          # calibrated base: 1 rad/s RMS over 2000 samples

    def entries(*rows):
        return [{"id": i, "rmse_probe": r, "own_probes": own} for i, r, own in rows]

    # one slot for the best generic probe (B, though it also beats the base, stays out); the
    # own-probe candidates are judged apart, even when they rank below both, and need only fit
    # better than the base (T, 0.9995 rad/s: n_eff ln ratio = 1 < 10, within the criterion's
    # margin, is added); a generic probe within the margin (G) is not, nor an own one that ties (U)
    probing = entries(("A", 0.5, False), ("B", 0.6, False), ("S", 0.7, True), ("T", 0.9995, True),
                      ("U", 1.0, True))
    added = probe_additions(probing, ["C"], rule, rss_base=rss_base, n_fit=n_fit)
    assert [q["id"] for q in added] == ["A", "S", "T"]
    assert [q.get("added", False) for q in probing] == [True, False, True, True, False]
    probing = entries(("G", 0.9995, False), ("S", 0.9995, True))
    assert [q["id"] for q in probe_additions(probing, [], rule, rss_base=rss_base, n_fit=n_fit)] == ["S"]
    # the own-probe candidate leading the ranking does not take the generic slot either
    probing = entries(("S", 0.3, True), ("A", 0.5, False))
    assert {q["id"] for q in probe_additions(probing, [], rule, rss_base=rss_base, n_fit=n_fit)} == {"S", "A"}
    # a candidate with both kinds of entry (own probes besides the generic ones) is added once
    probing = entries(("V", 0.5, False), ("V", 0.6, True), ("S", 0.7, True))
    assert [q["id"] for q in probe_additions(probing, [], rule, rss_base=rss_base, n_fit=n_fit)] == ["V", "S"]
    # already shortlisted: not added twice, and the generic slot does not pass to the runner-up
    probing = entries(("A", 0.5, False), ("B", 0.6, False), ("S", 0.7, True))
    assert probe_additions(probing, ["A", "S"], rule, rss_base=rss_base, n_fit=n_fit) == []
    assert not any(q.get("added") for q in probing)
    # a probe fitting worse than the calibrated base is never added
    probing = entries(("A", 1.2, False), ("S", 1.5, True))
    assert probe_additions(probing, [], rule, rss_base=rss_base, n_fit=n_fit) == []


def test_probe_start_switches_on_an_effect_the_refits_left_off():
    # the refits stayed with the asymmetry off; from the uncalibrated coefficients "off" still
    # misses the stuck backward run, so the best amplitude probe there is the third start
    model, d = _StickingBackward(), Diagnosis(candidates=["friction_asymmetry"])
    h = Hypothesis(START, CANDIDATES["friction_asymmetry"])
    x_nom = h.x_start()
    x = d._probe_start(model, h, x_nom, [0])
    assert np.array_equal(x[:h.n_base], x_nom[:h.n_base]) and x[-1] == pytest.approx(-0.175)
    (r_off,), (r_x,) = model.residuals([h.point(x_nom)], [0]), model.residuals([h.point(x)], [0])
    assert r_x @ r_x < 0.1 * (r_off @ r_off)
    # an effect already switched on that fits better than every probe: no third start
    x_on = h.x_start()
    x_on[-1] = -0.2
    assert d._probe_start(model, h, x_on, [0]) is None


@dataclass
class _Rec:
    """What the split exchange reads of a prepared recording."""
    name: str
    role: str
    load_kg: float
    omega_w: np.ndarray


def _runs():
    up, down, fast = np.full(5, math.pi), np.full(5, -math.pi), np.full(5, 2 * math.pi)
    return [_Rec("a_up", "fit", 0.5, up), _Rec("a_down", "fit", 0.5, down), _Rec("b_up", "fit", 1.0, up),
            _Rec("b_fast", "fit", 1.0, fast), _Rec("a_fast", "heldout", 0.5, fast),
            _Rec("b_down", "heldout", 1.0, down)]


def test_exchange_pairs_hold_out_a_run_of_the_same_kind_without_hiding_a_condition():
    recs = _runs()
    # the only backward run at 1 kg goes into the fit; holding out a_down instead would hide the
    # backward travel at 0.5 kg, a_up the forward one there (a_fast is held out): b_up, the
    # nearest speed among those that hide nothing
    assert exchange_pairs(recs, ["b_down"]) == {"b_down": "b_up"}
    # same direction and speed, other load, where that hides nothing more than the split did
    # (b_down's backward 1 kg stays hidden until it is exchanged itself)
    assert exchange_pairs(recs, ["a_fast", "b_down"]) == {"a_fast": "b_fast", "b_down": "a_up"}
    new = exchanged(recs, {"b_down": "a_down"})
    assert [(r.name, r.role) for r in new] == [("a_up", "fit"), ("b_up", "fit"), ("b_fast", "fit"),
                                               ("b_down", "fit"), ("a_down", "heldout"), ("a_fast", "heldout")]
    # a fit recording is used once, and one always stays fitted
    two = [recs[0], recs[1], recs[4], recs[5]]
    assert exchange_pairs(two, ["a_fast", "b_down"]) == {"a_fast": "a_up"}
    # the grid's design, one forward run per load held out: the run of the same speed at the
    # other load (1_up) would leave no forward 1 kg run in the fit (load_lift seed 20, named
    # friction_asymmetry so): the other forward run at the same load goes instead
    grid = _grid([(0.5, "up"), (0.5, "fast"), (0.5, "down"), (1, "up"), (1, "fast"), (1, "down")])
    grid = with_heldout(grid, ["0.5_up", "1_fast"])
    assert exchange_pairs(grid, ["0.5_up"]) == {"0.5_up": "0.5_fast"}
    assert exchange_pairs(grid, ["1_fast"]) == {"1_fast": "1_up"}


def _grid(spec):
    """Recordings ``load_kind`` in this order; kinds: up (pi rad/s), fast (2 pi), down (-pi)."""
    w = {"up": math.pi, "fast": 2 * math.pi, "down": -math.pi}
    return [_Rec(f"{load:g}_{kind}", "fit", load, np.full(5, w[kind])) for load, kind in spec]


def test_choose_heldout_keeps_every_load_direction_pair_it_can_among_the_fit_recordings():
    # as many as every third from the second: none of one, 1 of 2-4, 2 of 5-7, 3 of 8-10
    for n, k in [(1, 0), (2, 1), (4, 1), (5, 2), (7, 2), (8, 3), (10, 3)]:
        assert len(choose_heldout(_grid([(0.5 * (i + 1), "up") for i in range(n)]))) == k
    # the order every-third-from-the-second would hold out 0.5_down (the only backward run at
    # 0.5 kg) and 1_fast: one forward run per load instead, one slow and one fast
    recs = _grid([(0.5, "up"), (0.5, "down"), (0.5, "fast"), (1, "up"), (1, "down"), (1, "fast")])
    assert choose_heldout(recs) == ("0.5_up", "1_fast")
    # three loads, one run each way (no split keeps every pair): the heaviest backward run stays
    # fitted (out-of-sample friction_asymmetry 14 held it out); both held-out runs lie between
    # fitted loads, though that leaves 1 kg without a fit recording
    recs = _grid([(load, kind) for load in (0.5, 1.0, 1.5) for kind in ("up", "down")])
    held = choose_heldout(recs)
    assert held == ("1_up", "1_down")
    assert "1.5_down" not in choose_heldout(recs[::-1])
    # many recordings (one at a time): still no (load, direction) left without a fit recording
    recs = _grid([(load, kind) for load in (0.5, 1.0, 1.5) for kind in ("up", "down", "fast")] * 4)
    for i, r in enumerate(recs):
        r.name = f"{r.name}_{i}"
    held = set(choose_heldout(recs))
    assert len(held) == 12
    cells = lambda rs: {(r.load_kg, np.sign(r.omega_w[0])) for r in rs}   # noqa: E731
    assert cells(r for r in recs if r.name not in held) == cells(recs)
    # roles follow the choice, fit recordings first
    assert [(r.name, r.role) for r in with_heldout(recs[:3], ["0.5_up_0"])] == [
        ("0.5_down_1", "fit"), ("0.5_fast_2", "fit"), ("0.5_up_0", "heldout")]


class _ScriptedDiagnosis(Diagnosis):
    """A Diagnosis whose passes return scripted answers: (verdict, held-out ratios[, spread of the
    recordings' own floors]) per pass."""

    def __init__(self, script, **kw):
        kw.setdefault("heavy_look", False)   # (tests/test_heavy_look.py)
        super().__init__(**kw)
        self.script, self.seen, self.weighted_seen = list(script), [], []

    def _fit_pass(self, recs, weighted=False):
        self.seen.append({r.name for r in recs if r.role != "fit"})
        self.weighted_seen.append(weighted)
        verdict, self.heldout_beyond_floor_, *spread = self.script.pop(0)
        verdict, _, named = verdict.partition(":")   # "selected:<effect>" names another than the drag
        self.verdict_, self.selected_ = verdict, ([named or "slider_viscous"] if verdict == "selected" else [])
        self.floor_spread_, self.weighted_ = (spread or [1.5])[0], weighted
        self.floor_, self.calibrated_ = 0.01, Namespace(rmse_fit=0.011)
        self.phase_ = {"estimated": False}   # beyond the phase gate: no second look (tests/test_second_look.py)
        self.timings_, self.n_runs_, self.n_failed_, self.recordings_ = {"calibrate": 1.0}, 10, 0, recs


def test_fit_exchanges_the_split_only_when_a_heldout_recording_shows_what_the_fit_ones_hide():
    # "none" with a held-out run far beyond the floor: a second pass with it fitted answers
    d = _ScriptedDiagnosis([("none", {"b_down": 18.0, "a_fast": 2.0}), ("selected", {})]).fit(_runs())
    assert d.seen == [{"a_fast", "b_down"}, {"a_fast", "b_up"}]
    assert d.verdict_ == "selected" and d.first_split_["exchanged"] == {"b_down": "b_up"}
    assert d.first_split_["verdict"] == "none" and d.n_runs_ == 20 and d.timings_["first_split"] == 1.0
    # a named effect whose model misses a held-out run: the second pass, naming one, is the answer
    d = _ScriptedDiagnosis([("selected", {"b_down": 26.6}), ("selected", {})]).fit(_runs())
    assert d.seen == [{"a_fast", "b_down"}, {"a_fast", "b_up"}] and d.unused_split_ is None
    assert d.first_split_["verdict"] == "selected" and d.first_split_["selected"] == ["slider_viscous"]
    # ... naming none, it is only a record: the first answer stands, with its own state
    d = _ScriptedDiagnosis([("selected", {"b_down": 26.6}), ("unexplained", {})]).fit(_runs())
    assert len(d.seen) == 2 and d.first_split_ is None
    assert d.verdict_ == "selected" and d.heldout_beyond_floor_ == {"b_down": 26.6}
    assert {r.name for r in d.recordings_ if r.role != "fit"} == {"a_fast", "b_down"}
    assert d.unused_split_["verdict"] == "unexplained" and d.unused_split_["exchanged"] == {"b_down": "b_up"}
    assert d.n_runs_ == 20 and d.timings_["unused_split"] == 1.0
    # ... naming one whose model misses a run both passes held out, which the first reproduced:
    # the exchange hid more than it showed, and the first answer stands with its own state
    d = _ScriptedDiagnosis([("selected", {"b_down": 5.4, "a_fast": 3.0}),
                            ("selected", {"b_up": 2.2, "a_fast": 55.9})]).fit(_runs())
    assert len(d.seen) == 2 and d.first_split_ is None and d.verdict_ == "selected"
    assert d.heldout_beyond_floor_ == {"b_down": 5.4, "a_fast": 3.0}
    assert {r.name for r in d.recordings_ if r.role != "fit"} == {"a_fast", "b_down"}
    assert d.unused_split_["worse_on"] == {"a_fast": (3.0, 55.9)}
    assert d.unused_split_["heldout_beyond_floor"] == {"b_up": 2.2, "a_fast": 55.9}
    assert d.n_runs_ == 20 and d.timings_["unused_split"] == 1.0
    # the shared run only worse within max_remaining, or already beyond it in the first pass, or
    # a run only the second pass held out: the second pass is the answer
    for second in ({"b_up": 2.2, "a_fast": 4.9}, {"b_up": 9.0, "a_fast": 3.0}):
        d = _ScriptedDiagnosis([("selected", {"b_down": 5.4, "a_fast": 3.0}), ("selected", second)]).fit(_runs())
        assert d.first_split_["exchanged"] == {"b_down": "b_up"} and d.unused_split_ is None
        assert d.heldout_beyond_floor_ == second
    d = _ScriptedDiagnosis([("selected", {"b_down": 26.6, "a_fast": 6.0}),
                            ("selected", {"a_fast": 30.0, "b_up": 1.0})]).fit(_runs())
    assert d.first_split_ is not None and d.unused_split_ is None
    # ... and so is one naming another effect, however it holds out
    d = _ScriptedDiagnosis([("selected", {"b_down": 5.4, "a_fast": 3.0}),
                            ("selected:load_lift", {"b_up": 2.2, "a_fast": 55.9})]).fit(_runs())
    assert d.selected_ == ["load_lift"] and d.first_split_["selected"] == ["slider_viscous"]
    assert d.unused_split_ is None
    # within max_remaining floors, after "unexplained", or switched off: one pass
    for script, kw in [([("none", {"b_down": 4.9})], {}), ([("unexplained", {"b_down": 18.0})], {}),
                       ([("selected", {"b_down": 4.9})], {}),
                       ([("none", {"b_down": 18.0})], {"exchange_split": False})]:
        d = _ScriptedDiagnosis(script, **kw).fit(_runs())
        assert len(d.seen) == 1 and d.first_split_ is None and d.unused_split_ is None


class _LookedAgain(_ScriptedDiagnosis):
    """Scripted passes whose wheel phases were estimated (within the phase gate), so that an
    "unexplained" is looked at again; records the phase-profiled steps of each pass."""

    def _fit_pass(self, recs, weighted=False):
        super()._fit_pass(recs, weighted)
        self.phase_ = {"estimated": True}
        self.steps_seen = getattr(self, "steps_seen", []) + [self._steps]


def test_the_second_looks_answer_faces_the_split_exchange_once():
    from szdyn.diagnose.report import _second_look_md, _split_md

    # unexplained, then "none" on the second look with a held-out run far off (slider_stribeck
    # seed 71): the split is exchanged, that pass with the second look's steps, and it answers
    d = _LookedAgain([("unexplained", {}), ("none", {"b_down": 18.0}), ("selected", {})]).fit(_runs())
    assert d.seen == [{"a_fast", "b_down"}, {"a_fast", "b_down"}, {"a_fast", "b_up"}]
    assert d.steps_seen == [0, 2, 2] and d._steps == 0
    assert d.verdict_ == "selected" and d.second_look_["verdict"] == "unexplained"
    assert d.first_split_["verdict"] == "none" and d.first_split_["after_second_look"] is True
    assert d.first_split_["exchanged"] == {"b_down": "b_up"}
    assert {r.name for r in d.recordings_ if r.role != "fit"} == {"a_fast", "b_up"}
    assert d.n_runs_ == 30 and list(d.timings_)[:2] == ["before_second_look", "first_split"]
    d.rule, d.hidden_conditions_ = SelectionRule(), []
    assert "Its split was then exchanged (below)." in "\n".join(_second_look_md(d))
    assert _split_md(d)[0].startswith("**Split exchanged.** The second look's pass with `a_fast`, `b_down` held out said none")
    assert "That pass: 1 s, 10 model runs." in _split_md(d)[0]
    # a named effect there whose exchanged pass names none: the second look's answer stands
    d = _LookedAgain([("unexplained", {}), ("selected", {"b_down": 26.6}), ("unexplained", {})]).fit(_runs())
    assert d.verdict_ == "selected" and d.first_split_ is None and d.unused_split_["after_second_look"]
    assert {r.name for r in d.recordings_ if r.role != "fit"} == {"a_fast", "b_down"}
    # a split exchanged already (the first pass said none, its exchanged pass unexplained): the
    # second look's answer is final, whatever it holds out
    d = _LookedAgain([("none", {"b_down": 18.0}), ("unexplained", {}), ("none", {"a_fast": 30.0})]).fit(_runs())
    assert len(d.seen) == 3 and d.verdict_ == "none" and "after_second_look" not in d.first_split_
    # within max_remaining floors, or the exchange switched off: no exchange after the look
    for script, kw in [([("unexplained", {}), ("none", {"b_down": 4.9})], {}),
                       ([("unexplained", {}), ("none", {"b_down": 18.0})], {"exchange_split": False})]:
        d = _LookedAgain(script, **kw).fit(_runs())
        assert len(d.seen) == 2 and d.first_split_ is None and d.unused_split_ is None


def test_report_says_which_pass_of_an_exchanged_split_is_the_answer():
    from szdyn.diagnose.report import _split_md

    first = {"heldout": ["a_fast", "b_down"], "verdict": "selected", "selected": ["friction_asymmetry"],
             "calibrated_fit_over_floor": 7.0, "heldout_beyond_floor": {"b_down": 26.6},
             "exchanged": {"b_down": "a_down"}, "seconds": 598.0, "model_runs": 1574, "failed_runs": 0}
    d = Namespace(first_split_=first, unused_split_=None, rule=SelectionRule(), heldout_beyond_floor_={},
                  hidden_conditions_=[])
    (text, _) = _split_md(d)
    assert text.startswith("**Split exchanged.**") and "named friction_asymmetry, but its updated model" in text
    assert "`b_down` (26.6x)" in text and "`b_down` fitted and `a_down` held out instead" in text
    d.first_split_ = {**first, "verdict": "none", "selected": []}
    assert "said none: the calibrated base reproduced the fit recordings (7.00x the floor)" in _split_md(d)[0]
    # the second pass named nothing: the first answer stands, and the report says what the second said
    d = Namespace(first_split_=None, rule=SelectionRule(), heldout_beyond_floor_={"b_down": 26.6}, heldout_scale_=None,
                  hidden_conditions_=[], unused_split_={"verdict": "unexplained", "selected": [], "calibrated_fit_over_floor": 3.2,
                                 "seconds": 700.0, "model_runs": 1800, "failed_runs": 0,
                                 "exchanged": {"b_down": "a_down"}})
    (text, _) = _split_md(d)
    assert text.startswith("**Split exchange tried.**") and "`b_down` (26.6x the floor)" in text
    assert "said unexplained" in text and "the effect named here stands" in text
    # the second pass named one too, but missed a run both held out: the report says which
    d.unused_split_ = {**d.unused_split_, "verdict": "selected", "selected": ["slider_stribeck"],
                       "worse_on": {"a_fast": (3.0, 55.9)}}
    (text, _) = _split_md(d)
    assert text.startswith("**Split exchange tried.**") and "named slider_stribeck too" in text
    assert "`a_fast` (55.9x its floor, against 3.0x here), held out in both passes" in text
    assert "the answer of this split stands (second pass: 700 s, 1800 model runs)" in text
    assert _split_md(Namespace(first_split_=None, unused_split_=None, hidden_conditions_=[])) == []


def test_a_missed_heldout_recording_along_the_force_scale_is_recorded_and_reported():
    from szdyn.diagnose.diagnosis import Diagnosis
    from szdyn.diagnose.report import _heldout_scale_md, _split_md

    recs = [Namespace(name="a_up"), Namespace(name="b_fast"), Namespace(name="c_down")]
    d = Namespace(floor_=0.01, rule=SelectionRule(), heldout_beyond_floor_={"b_fast": 7.9, "c_down": 4.0},
                  selected_=["encoder_scale"])
    scan = {"sigma": 0.049, "points": [-1.0, -0.5, 0.5, 1.0], "factors": [0.952, 0.976, 1.025, 1.050],
            "rmse": {1: [0.0795, 0.0073, 0.076, 0.144], 2: [0.041, None, 0.039, 0.042]}}
    rec = Diagnosis._scale_record(d, scan, recs)
    b, c = rec["recordings"]["b_fast"], rec["recordings"]["c_down"]
    assert b["over_floor"] == pytest.approx([7.95, 0.73, 7.6, 14.4])
    assert b["min"] == pytest.approx(0.73) and b["at_factor"] == 0.976 and b["max"] == pytest.approx(14.4)
    assert b["reproduced"]                        # 0.73 floors is within the rule's 1.3
    # a failed step is None and left out; the final model itself (x1, 4.0 floors) counts
    assert c["over_floor"][1] is None and c["min"] == pytest.approx(3.9) and c["at_factor"] == 1.025
    assert c["max"] == pytest.approx(4.2) and not c["reproduced"]
    d.heldout_scale_ = rec
    text = "\n".join(_heldout_scale_md(d))
    assert "x0.952 to x1.050 (+-1 reported std of mu_k, 4.9%, in 4 steps" in text
    assert "`b_fast`: reproduced at x0.976 (0.73x the floor)" in text and "14.4x at worst" in text
    assert "14.4x at worst. Within the fitted uncertainty the model does reproduce it" in text
    assert "`c_down`: nowhere within 1.3x the floor (best 3.9x, at x1.025)" in text
    assert "4.2x at worst. Not the force scale's uncertainty alone." in text
    assert "8.0, 0.7, 7.6, 14.4" in text and "4.1, failed, 3.9, 4.2" in text
    # the exchange the first answer survived says which of the two it was
    d.first_split_, d.hidden_conditions_ = None, []
    d.unused_split_ = {"verdict": "unexplained", "selected": [], "calibrated_fit_over_floor": 4.6, "seconds": 257.0,
                       "model_runs": 1848, "failed_runs": 0, "exchanged": {"b_fast": "a_up"}}
    assert "reproduced that recording with its forces scaled within their uncertainty" in _split_md(d)[0]
    d.unused_split_["exchanged"] = {"c_down": "a_up"}
    assert "either less reproducible than the floor says" in _split_md(d)[0]
    d.heldout_scale_ = None
    assert _heldout_scale_md(d) == [] and "either less reproducible" in _split_md(d)[0]


def test_split_that_holds_out_the_only_run_of_a_condition_is_reported():
    from szdyn.diagnose.report import _split_md
    from szdyn.diagnose.split import hidden_conditions

    # b_down is the only backward run at 1 kg; a_fast has a fitted twin condition (a_up)
    hidden = hidden_conditions(_runs())
    assert hidden == [{"load_kg": 1.0, "direction": -1.0, "travel": "backward", "recordings": ["b_down"]}]
    (text, _) = _split_md(Namespace(first_split_=None, unused_split_=None, hidden_conditions_=hidden))
    assert text.startswith("**The split hides a condition.** Only held-out `b_down` runs backward at 1 kg")
    # exchanged so that it is fitted: nothing hidden
    assert hidden_conditions(exchanged(_runs(), {"b_down": "a_down"})) == [
        {"load_kg": 0.5, "direction": -1.0, "travel": "backward", "recordings": ["a_down"]}]
    assert hidden_conditions(with_heldout(_runs(), ["a_fast", "b_up"])) == []


def test_fit_weights_the_recordings_only_when_nothing_is_named_and_their_floors_differ():
    from szdyn.diagnose.diagnosis import FLOOR_SPREAD

    wide = FLOOR_SPREAD + 1
    # nothing named under a common floor that misdescribes the recordings: the weighted pass names
    # an effect, and it is the answer; the unweighted one is kept as the other pass
    d = _ScriptedDiagnosis([("none", {}, wide), ("selected", {})]).fit(_runs())
    assert d.weighted_seen == [False, True] and d.seen[0] == d.seen[1]
    assert d.verdict_ == "selected" and d.weighted_ and d.weighting_["weighted"]
    assert d.weighting_["other_pass"]["verdict"] == "none" and not d.weighting_["other_pass"]["weighted"]
    assert d.n_runs_ == 20 and d.timings_["unweighted_pass"] == 1.0
    # the weighted pass names nothing either: the unweighted answer stands, with its own state
    d = _ScriptedDiagnosis([("unexplained", {}, wide), ("none", {}, 1.0)]).fit(_runs())
    assert d.weighted_seen == [False, True]
    assert d.verdict_ == "unexplained" and not d.weighted_ and d.floor_spread_ == wide
    assert d.weighting_ == {"mode": "fallback", "spread": wide, "threshold": FLOOR_SPREAD, "weighted": False,
                            "other_pass": {"weighted": True, "verdict": "none", "selected": [],
                                           "calibrated_fit_over_floor": pytest.approx(1.1),
                                           "seconds": 1.0, "model_runs": 10, "failed_runs": 0}}
    assert d.n_runs_ == 20 and d.timings_["weighted_pass"] == 1.0
    # a named effect, floors within the spread, weighting off: one unweighted pass; always: weighted
    for script, kw in [([("selected", {}, wide)], {}), ([("none", {}, FLOOR_SPREAD)], {}),
                       ([("none", {}, wide)], {"weighting": "off"})]:
        d = _ScriptedDiagnosis(script, **kw).fit(_runs())
        assert d.weighted_seen == [False] and d.weighting_["other_pass"] is None
    # after a split exchange, the weighted pass keeps the exchanged roles (and the exchange record)
    d = _ScriptedDiagnosis([("none", {"b_down": 18.0}, wide), ("none", {}, wide), ("selected", {})]).fit(_runs())
    assert d.weighted_seen == [False, False, True] and d.seen[2] == d.seen[1] == {"a_fast", "b_up"}
    assert d.verdict_ == "selected" and d.first_split_["exchanged"] == {"b_down": "b_up"}
    d = _ScriptedDiagnosis([("none", {}, wide)], weighting="always").fit(_runs())
    assert d.weighted_seen == [True] and d.weighting_["weighted"]
    with pytest.raises(ValueError, match="weighting"):
        _ScriptedDiagnosis([], weighting="sometimes").fit(_runs())


# ----------------------------------------------------------------------------- command errors
def test_diagnose_missing_manifest_is_a_clear_error(tmp_path, capsys):
    rc = run_main(["diagnose", str(tmp_path / "nope.toml"), "--out", str(tmp_path / "o")])
    assert rc == 2
    err = capsys.readouterr().err
    assert "nope.toml" in err and "Traceback" not in err


def test_diagnose_unknown_candidate_is_a_clear_error(tmp_path, capsys):
    m = tmp_path / "m.toml"
    m.write_text("")
    rc = run_main(["diagnose", str(m), "--out", str(tmp_path / "o"), "--candidates", "slider_viscus"])
    assert rc == 2
    assert "slider_viscus" in capsys.readouterr().err


@pytest.mark.parametrize("value", ["-0.1", "2", "nan"])
def test_diagnose_nomination_threshold_outside_0_1_is_a_clear_error(tmp_path, capsys, value):
    m = tmp_path / "m.toml"
    m.write_text("")
    rc = run_main(["diagnose", str(m), "--out", str(tmp_path / "o"), "--nominate-r2", value])
    assert rc == 2
    err = capsys.readouterr().err
    assert "--nominate-r2" in err and "Traceback" not in err


@pytest.mark.parametrize("flag, value", [("--polish-jac", "-1"), ("--rivals", "-1"), ("--unstall", "-1"),
                                         ("--phase-steps", "-1"), ("--workers", "99999999999"),
                                         ("--coefficient-floor", "-0.01"), ("--coefficient-floor", "nan"),
                                         ("--coefficient-floor", "0.6")])
def test_diagnose_option_out_of_range_is_a_clear_error(tmp_path, capsys, flag, value):
    m = tmp_path / "m.toml"
    m.write_text("")
    rc = run_main(["diagnose", str(m), "--out", str(tmp_path / "o"), flag, value])
    assert rc == 2
    err = capsys.readouterr().err
    assert flag in err and "Traceback" not in err


# ----------------------------------------------------------------------------- end to end
RAMPS = (RampSpec("up", 2 * math.pi, 0.5, 0.5), RampSpec("down", -2 * math.pi, 0.5, 0.5))
SMALL = ["--candidates", "slider_viscous,load_lift,encoder_scale", "--shortlist", "1", "--max-jac", "3",
         "--quiet"]


def _synth_and_diagnose(tmp_path_factory, effect, amplitude, **synth_kw):
    base = tmp_path_factory.mktemp(effect)
    data, out = base / "data", base / "out"
    synthesize(data, effect, amplitude, seed=5, loads_kg=(0.5, 1.0), ramps=RAMPS, dt=5e-5, verbose=False,
               **synth_kw)
    # the diagnosis must not read the answer: hide it
    truth = json.loads((data / "truth.json").read_text())
    (data / "truth.json").rename(base / "truth.json")
    assert run_main(["diagnose", str(data / "manifest.toml"), "--out", str(out), *SMALL]) == 0
    return truth, json.loads((out / "diagnosis.json").read_text()), out


@pytest.fixture(scope="module")
def viscous(tmp_path_factory):
    return _synth_and_diagnose(tmp_path_factory, "slider_viscous", 0.4)


@pytest.fixture(scope="module")
def null(tmp_path_factory):
    return _synth_and_diagnose(tmp_path_factory, "none", None)


def test_concealed_viscous_drag_is_named_recovered_and_improves_heldout(viscous):
    truth, d, out = viscous
    assert d["selected"] == ["slider_viscous"]
    e = next(x for x in d["effects"] if x["selected"])
    c_true = truth["effect_parameters"]["c_visc"]
    assert e["primary"]["name"] == "c_visc"
    assert abs(e["primary"]["value"] / c_true - 1) < 0.3    # measured 6.2 % (seed 5)
    assert d["fit"]["before"]["heldout_rmse"] / d["fit"]["after"]["heldout_rmse"] > 3
    # outputs a user looks at, and the updated parameters load and carry the effect
    for f in ("report.md", "params.json", "residual_time.png", "residual_features.png",
              "candidates.png", "heldout_fit.png"):
        assert (out / f).stat().st_size > 0
    from szdyn.params import ParameterSet
    p = ParameterSet.from_json(out / "params.json")
    assert p["c_visc"] == pytest.approx(e["primary"]["value"])
    assert p["k_c"] == pytest.approx(d["final"]["values"]["k_c"])
    assert "slider_viscous" in (out / "report.md").read_text()
    assert (out / "report.md").read_text().count("was corrected along the force scale") == 2   # base, effect


def test_diagnosis_json_schema(viscous):
    truth, d, _ = viscous
    assert set(d) >= {"selected", "effects", "mismatch", "calibrated", "fit"}
    # two loads: the staged calibration ran (the 1 kg fit recordings first) and says what it did
    g = d["staged_calibration"]
    assert g["load_kg"] == 1.0 and g["recordings"] and all("1kg" in n for n in g["recordings"])
    assert 0 < g["first_rmse_fit"] and 0 < g["rmse_fit"] and g["ratio"] == 2.0
    assert g["adopted"] == (g["rmse_fit"] * 2.0 <= g["calibrated_rmse_fit"])
    for e in d["effects"]:
        assert set(e) >= {"id", "score", "selected", "parameters", "expression", "explains"}
    for m in d["mismatch"]:
        assert set(m) >= {"recording", "t0", "t1", "regime", "score"}
    assert set(d["calibrated"]) == {"k_c", "b_c", "k_imp", "mu_s", "mu_k"}
    assert d["fit"]["before"]["heldout_rmse"] > 0 and d["fit"]["after"]["heldout_rmse"] > 0
    assert d["final_failed_on"] == []   # every run of the updated model went through
    # what the reader needs to judge the fits: how each ended, and rivals that fit as well
    assert d["calibration_status"].split(" after ")[0] in ("converged", "stopped by its budget")
    refitted = [e for e in d["effects"] if e["refitted"]]
    assert refitted and all(" Jacobians" in e["fit_status"] for e in refitted)
    # each refit's whole point, so that it can be run again: its base and its own parameters
    for e in refitted:
        assert set(e["values"]) == set(d["calibrated"]) | set(e["fit_coordinates"])
        assert {k: e["values"][k] for k in e["fit_coordinates"]} == e["fit_coordinates"]
    assert isinstance(d["indistinguishable"], list) and not set(d["indistinguishable"]) & set(d["selected"])
    # the selected effect reaches the floor's neighbourhood; eligible ones that do not are partial
    assert all(e["explains_mismatch"] for e in d["effects"] if e["selected"])
    assert {p["id"] for p in d["partial"]} == {e["id"] for e in d["effects"]
                                              if e.get("eligible") and not e["explains_mismatch"]}
    # what the fit residual follows, and which candidates that put on the shortlist
    nom = d["nominated"]
    assert nom["feature"] in FEATURES and 0.0 <= nom["r2"] <= 1.0 and set(nom["added"]) <= set(nom["ids"])
    assert all(e["refitted"] for e in d["effects"] if e["id"] in nom["ids"])
    assert all(e["refitted"] for e in d["effects"] if e["id"] in d["rivals"])
    # what the recordings can see: every screened effect's smallest flagged amplitude; the
    # concealed drag, flagged and named, was larger than its own
    for e in d["effects"]:
        assert e["detectable"]
        for t in e["detectable"]:
            assert t["parameters"] and t["unit"] and (t["amplitude"] is None or t["amplitude"] > 0)
    [vis] = next(e for e in d["effects"] if e["id"] == "slider_viscous")["detectable"]
    assert vis["parameters"] == ["c_visc"] and 0 < vis["amplitude"] < truth["effect_parameters"]["c_visc"]
    # the ablation (base model alone from the selected candidate's coefficients) ran and, the
    # drag being real, did not fit as well
    assert d["ablation"]["candidate"] == "slider_viscous" and not d["ablation"]["adopted"]
    assert d["restart"] is None            # (off by default)
    assert d["heavy_look"] is None         # (only after "unexplained")
    assert d["scale_profile"] is None      # (off by default)
    # the effect parameter comes with its (local) standard deviation, from the Jacobian corrected
    # along the force scale by runs (.force_scale), the same in the effect's entry and the final
    sel = next(e for e in d["effects"] if e["selected"])
    assert sel["primary"]["std"] == pytest.approx(sel["std"]["c_visc"])
    assert sel["std"]["c_visc"] == pytest.approx(d["final"]["std"]["c_visc"])
    for k in ("calibrated", "final"):
        fs = d["uncertainty"][k]
        assert fs["corrected"] and fs["step"] == 0.05 and fs["measured"] > 0 and fs["predicted"] > 0, k
    # a torque-like effect parameter is also given relative to the refit's kinetic friction
    assert sel["primary"]["per_mu_k"] == pytest.approx(sel["primary"]["value"] / d["final"]["values"]["mu_k"])
    assert all("per_mu_k" not in e.get("primary", {}) for e in d["effects"] if e["id"] == "encoder_scale")
    # the floor is assembled from the fit recordings' own parts (RMS of sensor, median of bumps
    # with each load counting once: here one fit recording at 0.5 kg and two at 1 kg, so the
    # plain median with the 0.5 kg one counted twice)
    per = d["noise_floor_per_recording"]
    assert set(per) == {r["recording"] for r in d["location"]["recordings"]}
    fit = {r["name"]: r["load_kg"] for r in d["recordings"] if r["role"] == "fit"}
    assert sorted(fit.values()) == [0.5, 1.0, 1.0] and set(fit) == set(per) - set(d["split"]["heldout"])
    s = math.sqrt(np.mean([per[k]["sensor"] ** 2 for k in fit]))
    bumps = [per[k]["bump"] for k, x in fit.items() for _ in range(2 if x == 0.5 else 1)]
    assert d["noise_floor"] == pytest.approx(math.hypot(s, float(np.median(bumps))))
    own = [math.hypot(v["sensor"], v["bump"]) for v in per.values()]
    assert d["weighting"]["spread"] == pytest.approx(max(own) / min(own))
    assert d["weights"] == {r["recording"]: 1.0 for r in d["location"]["recordings"]}   # unweighted
    # held-out recordings the final model misses beyond the floor are listed, and only those
    after = d["fit"]["after"]["per_recording"]
    beyond = {b["recording"]: b["ratio"] for b in d["heldout_beyond_floor"]}
    for name, rmse in after.items():
        ratio = rmse / d["noise_floor"]
        assert (name in beyond) == (ratio > d["rule"]["min_excess"]), name
        assert beyond.get(name, ratio) == pytest.approx(ratio)
    # and run again along the force scale, within the reported std of mu_k
    hs = d["heldout_force_scale"]
    assert (hs is None) == (not beyond)
    if hs is not None:
        assert set(hs["recordings"]) == set(beyond) and len(hs["factors"]) == len(hs["points"])
        for name, e in hs["recordings"].items():
            assert e["min"] <= beyond[name] <= e["max"] and len(e["over_floor"]) == len(hs["points"])


def test_null_recordings_give_none(null):
    truth, d, out = null
    assert truth["effect"] == "none"
    assert d["selected"] == [] and d["verdict"] == "none"
    assert d["fit"]["after"]["heldout_rmse"] == d["fit"]["before"]["heldout_rmse"]
    assert "Verdict: none" in (out / "report.md").read_text()
    # nothing named: the final model is the calibrated base, its std corrected once
    assert d["uncertainty"]["final"] == d["uncertainty"]["calibrated"] and d["uncertainty"]["final"]["corrected"]
    assert d["final"]["std"]["mu_k"] == pytest.approx(d["calibrated_std"]["mu_k"])


def test_manifest_without_split_holds_out_what_choose_heldout_picks(null, monkeypatch, capsys):
    """No ``[split]``: the command prepares every recording, holds out :func:`choose_heldout`'s
    pick (from the recordings' loads, directions and speeds) and says so on stderr."""
    from szdyn.diagnose import diagnosis
    from szdyn.diagnose.data import prepare
    from szdyn.manifest import read_manifest

    _, _, out = null
    data = out.parent / "data"
    text = (data / "manifest.toml").read_text()
    split = text[text.index("[split]"):text.index("[[recording]]")]
    (data / "nosplit.toml").write_text(text.replace(split, ""))
    seen = []

    def stop(self, recs):
        seen.extend((r.name, r.role) for r in recs)
        raise UserInputError("stopped after the split")
    monkeypatch.setattr(diagnosis.Diagnosis, "fit", stop)
    assert run_main(["diagnose", str(data / "nosplit.toml"), "--out", str(out.parent / "nosplit")]) != 0
    held = choose_heldout(prepare(read_manifest(data / "nosplit.toml")))
    assert len(held) == 1 and [n for n, role in seen if role == "heldout"] == list(held)
    assert [role for _, role in seen] == ["fit"] * 3 + ["heldout"]
    assert f"no [split] in the manifest: holding out {held[0]}" in capsys.readouterr().err


def test_what_the_reader_left_out_is_said(null, monkeypatch, tmp_path, capsys):
    """A misspelt optional column is ignored and an exact duplicate row dropped by the reader;
    diagnose says both (even with --quiet), naming the recording."""
    import re

    from szdyn.diagnose import diagnosis
    _, _, out = null
    data = out.parent / "data"
    text = (data / "manifest.toml").read_text()
    names = re.findall(r'file = "([^"]+)"', text)
    for n in names:
        lines = (data / n).read_text().splitlines()
        if n == names[0]:
            lines = [lines[0] + ",omega_rf"] + [x + ",0" for x in lines[1:4]] + [lines[3] + ",0"] \
                + [x + ",0" for x in lines[4:]]
        (tmp_path / n).write_text("\n".join(lines) + "\n")
    (tmp_path / "m.toml").write_text(text)

    def stop(self, recs):
        raise UserInputError("stopped after reading")
    monkeypatch.setattr(diagnosis.Diagnosis, "fit", stop)
    assert run_main(["diagnose", str(tmp_path / "m.toml"), "--out", str(tmp_path / "o"), "--quiet"]) == 2
    err = capsys.readouterr().err
    assert f"diagnose: {names[0]}: dropped 1 exact duplicate row(s), the first on line 5" in err
    assert f"diagnose: {names[0]}: ignored column(s): omega_rf" in err
    assert not any(f"diagnose: {n}:" in err for n in names[1:])


def test_a_single_recording_is_diagnosed_without_a_heldout_one(null, tmp_path):
    """One recording and no [split]: nothing can be held out; the diagnosis still ends cleanly
    (it once wrote its files and then failed formatting the missing held-out error)."""
    _, _, out = null
    data = out.parent / "data"
    text = (data / "manifest.toml").read_text()
    first = text.index("[[recording]]")
    one = text[first:text.index("[[recording]]", first + 1)].replace('file = "', f'file = "{data}/')
    (tmp_path / "one.toml").write_text(one)
    assert run_main(["diagnose", str(tmp_path / "one.toml"), "--out", str(tmp_path / "o"), *SMALL]) == 0
    d = json.loads((tmp_path / "o" / "diagnosis.json").read_text())
    assert d["fit"]["before"]["heldout_rmse"] is None and d["fit"]["after"]["heldout_rmse"] is None
    assert d["verdict"] in ("none", "unexplained", "selected")


def test_an_out_holding_files_no_diagnosis_wrote_is_refused_before_the_fit(null, tmp_path, capsys):
    """--out the data folder, which holds the user's own params.json and report.md: refused before
    any run, and nothing there is touched."""
    _, _, out = null
    data = out.parent / "data"
    for f in data.glob("*.csv"):
        (tmp_path / f.name).write_bytes(f.read_bytes())
    (tmp_path / "m.toml").write_text((data / "manifest.toml").read_text())
    mine = {"params.json": '{"mine": 1}', "report.md": "my notes"}
    for k, v in mine.items():
        (tmp_path / k).write_text(v)
    assert run_main(["diagnose", str(tmp_path / "m.toml"), "--out", str(tmp_path), "--quiet"]) == 2
    err = capsys.readouterr().err
    assert ("holds params.json, report.md without a diagnosis.json beside them (not a diagnosis's output)"
            in err) and "Traceback" not in err
    assert all((tmp_path / k).read_text() == v for k, v in mine.items())
    assert not (tmp_path / "checkpoint").exists()


@pytest.mark.parametrize("left", ["diagnosis.json", "checkpoint", "report"])
def test_an_out_a_diagnosis_left_is_taken_again(null, tmp_path, monkeypatch, capsys, left):
    """A diagnosis's own --out (also one stopped while its files moved in, diagnosis.json not yet
    there: its checkpoint or its report's title tells) passes the check; the fit is stopped here."""
    from szdyn.diagnose import diagnosis

    _, _, out = null
    data = out.parent / "data"
    o = tmp_path / "o"
    o.mkdir()
    (o / "params.json").write_text("{}")
    if left == "diagnosis.json":
        (o / "diagnosis.json").write_text("{}")
    elif left == "checkpoint":
        (o / "checkpoint").mkdir()
    else:
        (o / "report.md").write_text("# szdyn diagnosis\n\n**Verdict: none.**\n")

    def stop(self, recs):
        raise UserInputError("stopped after the checks")
    monkeypatch.setattr(diagnosis.Diagnosis, "fit", stop)
    assert run_main(["diagnose", str(data / "manifest.toml"), "--out", str(o), "--quiet", "--no-checkpoint"]) == 2
    assert "stopped after the checks" in capsys.readouterr().err


def test_recordings_the_final_model_cannot_run_are_said(null, tmp_path, monkeypatch, capsys):
    """Every run at 1 kg fails (as one far beyond what the model integrates would): the diagnosis
    still ends, and diagnosis.json, the report and stderr name those recordings; before, only the
    cost line's count of failed runs showed it."""
    from szdyn.diagnose import engine

    _, _, out = null
    data = out.parent / "data"
    real = engine._simulate
    monkeypatch.setattr(engine, "_simulate", lambda task: None if task[0]["values"]["m_b"] == 1.0 else real(task))
    for f in data.glob("*.csv"):
        (tmp_path / f.name).write_bytes(f.read_bytes())
    (tmp_path / "m.toml").write_text((data / "manifest.toml").read_text())
    # one process: the patched worker runs in this one
    assert run_main(["diagnose", str(tmp_path / "m.toml"), "--out", str(tmp_path / "o"), *SMALL,
                     "--workers", "1", "--no-next-recording"]) == 0
    d = json.loads((tmp_path / "o" / "diagnosis.json").read_text())
    heavy = sorted(r["name"] for r in d["recordings"] if r["load_kg"] == 1.0)
    assert heavy and sorted(d["final_failed_on"]) == heavy and d["cost"]["failed_runs"] > 0
    which = "updated" if d["selected"] else "calibrated"
    assert f"**The {which} model's run failed on**" in (tmp_path / "o" / "report.md").read_text()
    err = capsys.readouterr().err
    assert f"diagnose: The {which} model's run failed on" in err and all(n in err for n in heavy)


def test_weighted_diagnosis_of_null_recordings_gives_none(null, tmp_path):
    """Every recording weighted by its own floor (``--weighting always``): the scores stay
    consistent (nothing selected: after == before), and the null recordings still give none."""
    _, _, out = null
    man = out.parent / "data" / "manifest.toml"
    assert run_main(["diagnose", str(man), "--out", str(tmp_path / "w"), "--weighting", "always", *SMALL]) == 0
    d = json.loads((tmp_path / "w" / "diagnosis.json").read_text())
    assert d["verdict"] == "none" and d["selected"] == []
    assert set(d["noise_floor_per_recording"]) == {r["recording"] for r in d["location"]["recordings"]}
    assert d["fit"]["after"]["heldout_rmse"] == pytest.approx(d["fit"]["before"]["heldout_rmse"])
    assert d["fit"]["after"]["per_recording"] == pytest.approx(d["fit"]["before"]["per_recording"])
    # each recording's weight is the common floor over its own (sensor and bumps in quadrature),
    # and the report says that its RMSEs are in these weighted units
    per = d["noise_floor_per_recording"]
    assert d["weights"] == pytest.approx({k: d["noise_floor"] / math.hypot(v["sensor"], v["bump"])
                                          for k, v in per.items()})
    assert "**Weighted**" in (tmp_path / "w" / "report.md").read_text()


def test_phase_profiled_steps_on_null_recordings_keep_none_and_are_reported(null, tmp_path):
    """``--phase-steps``: the base calibration may only get better (each step is kept only if it
    fits clearly better), the null still gives none, and the steps taken are reported."""
    _, d0, out = null
    man = out.parent / "data" / "manifest.toml"
    assert run_main(["diagnose", str(man), "--out", str(tmp_path / "p"), "--phase-steps", "1", *SMALL]) == 0
    d = json.loads((tmp_path / "p" / "diagnosis.json").read_text())
    assert d["verdict"] == "none" and d["selected"] == []
    assert d0["wheel_phase"]["estimated"] and "steps" not in d0["wheel_phase"]
    steps = d["wheel_phase"]["steps"]
    assert steps in (0, 1)
    if steps:   # a step is kept only where it fits clearly better
        assert d["fit"]["before"]["fit_rmse"] < d0["fit"]["before"]["fit_rmse"]
    else:
        assert d["fit"]["before"]["fit_rmse"] == pytest.approx(d0["fit"]["before"]["fit_rmse"])
    said = "phase-profiled step(s) of the base" in (tmp_path / "p" / "report.md").read_text()
    assert said == (steps == 1)


def test_fallback_weighted_pass_on_null_recordings_keeps_none(null, tmp_path, monkeypatch):
    """The default fallback, made to fire (any spread of the own floors): the weighted pass names
    nothing either, so the unweighted answer and its numbers stand, and both say so."""
    from szdyn.diagnose import diagnosis

    _, d0, out = null
    monkeypatch.setattr(diagnosis, "FLOOR_SPREAD", 0.0)
    man = out.parent / "data" / "manifest.toml"
    assert run_main(["diagnose", str(man), "--out", str(tmp_path / "f"), *SMALL]) == 0
    d = json.loads((tmp_path / "f" / "diagnosis.json").read_text())
    assert d["verdict"] == "none" and d["weighting"]["mode"] == "fallback" and not d["weighting"]["weighted"]
    other = d["weighting"]["other_pass"]
    assert other["weighted"] and other["verdict"] in ("none", "unexplained") and other["selected"] == []
    assert d["fit"] == d0["fit"] and set(d["weights"].values()) == {1.0}
    assert d["cost"]["seconds"]["weighted_pass"] == other["seconds"] > 0
    assert "**Weighted pass tried.**" in (tmp_path / "f" / "report.md").read_text()


def test_starts_skipped_for_a_settler_are_made_once_it_settles_nothing(viscous, tmp_path, monkeypatch):
    """A settler judged ineligible after the refits (ablation, held-out phases): the candidates it
    stopped get their further starts before the decision. Made to happen with a settler that
    settles each candidate's first look only."""
    from szdyn.diagnose import fit_pass

    _, d0, out = viscous
    asked = {}

    def first_look_only(rule, refits, floor, *, exclude=None):
        asked[exclude] = asked.get(exclude, 0) + 1
        return "phantom" if asked[exclude] == 1 else None

    monkeypatch.setattr(fit_pass, "settled", first_look_only)
    # (no probe addition spared: the small case's, encoder_scale, is the candidate that misses;
    # sparing is covered by the next tests)
    monkeypatch.setattr(fit_pass, "SETTLED_SKIPS_PROBED", math.inf)
    man = out.parent / "data" / "manifest.toml"
    assert run_main(["diagnose", str(man), "--out", str(tmp_path / "u"), *SMALL]) == 0
    d = json.loads((tmp_path / "u" / "diagnosis.json").read_text())
    missed = [e["id"] for e in d["effects"] if e["id"] in asked and asked[e["id"]] == 2]
    # (asked twice: once at its first start, once before the decision)
    assert missed, "no refitted candidate missed at its first start: nothing was skipped"
    assert "refit_unsettled" in d["cost"]["seconds"]
    report = (tmp_path / "u" / "report.md").read_text()
    assert "no further starts" not in report and "phantom" not in report
    assert d["selected"] == d0["selected"] == ["slider_viscous"]


def test_a_probe_addition_is_not_refitted_after_a_settler(viscous, tmp_path, monkeypatch):
    """The probe screening's additions come last on the shortlist; once a refitted candidate
    settles the answer explaining at least SETTLED_SKIPS_PROBED of the mismatch, they are not
    refitted, and the JSON and the report say which and why (the small case: the drag settles,
    encoder_scale's probe was added). The answer is the same as with the additions refitted
    (SETTLED_SKIPS_PROBED above any share), with fewer model runs."""
    from szdyn.diagnose import fit_pass

    _, d0, out = viscous
    added = list(dict.fromkeys(q["id"] for q in d0["probing"] if q.get("added")))
    assert added, "the small case's probe screening added nothing: nothing to test"
    assert d0["selected"] == ["slider_viscous"]
    assert set(d0["not_refitted"]) == set(added)
    for k in added:
        assert d0["not_refitted"][k]["by"] == "slider_viscous"
        assert d0["not_refitted"][k]["explained"] >= fit_pass.SETTLED_SKIPS_PROBED
    assert not any(e["refitted"] for e in d0["effects"] if e["id"] in added)
    report = (out / "report.md").read_text()
    for k in added:
        assert f"Not refitted: `{k}`, added by the probe screening after `slider_viscous`" in report

    monkeypatch.setattr(fit_pass, "SETTLED_SKIPS_PROBED", math.inf)
    man = out.parent / "data" / "manifest.toml"
    assert run_main(["diagnose", str(man), "--out", str(tmp_path / "all"), *SMALL]) == 0
    d = json.loads((tmp_path / "all" / "diagnosis.json").read_text())
    assert d["not_refitted"] == {} and all(e["refitted"] for e in d["effects"] if e["id"] in added)
    assert "Not refitted" not in (tmp_path / "all" / "report.md").read_text()
    assert d["selected"] == d0["selected"] and d["fit"] == d0["fit"]
    assert d0["cost"]["model_runs"] < d["cost"]["model_runs"]


def test_a_sensor_settler_does_not_spare_a_model_side_probe_addition(viscous, tmp_path, monkeypatch):
    """SENSOR_SETTLES_RESCUES False: a sensor candidate does not spare a model-side addition of
    the probe screening, nor skip its further starts. Made to happen in the small case (the drag
    settles, encoder_scale's probe is added) by swapping the two candidates' kinds: the drag
    then counts as a sensor term and encoder_scale as a model-side one, which is refitted with
    every start; the JSON and the report say why. With SENSOR_SETTLES_RESCUES True it is spared,
    as the real kinds have it."""
    from dataclasses import replace

    from szdyn.diagnose import diagnosis

    _, d0, out = viscous
    added = list(dict.fromkeys(q["id"] for q in d0["probing"] if q.get("added")))
    assert added == ["encoder_scale"], added
    assert d0["sensor_not_settling"] == {}     # the drag is model-side: it spares
    for cid, kind in (("slider_viscous", "sensor"), ("encoder_scale", "model")):
        monkeypatch.setitem(diagnosis.CANDIDATES, cid, replace(diagnosis.CANDIDATES[cid], kind=kind))
    man = out.parent / "data" / "manifest.toml"
    assert run_main(["diagnose", str(man), "--out", str(tmp_path / "s"), *SMALL]) == 0
    d = json.loads((tmp_path / "s" / "diagnosis.json").read_text())
    assert d["not_refitted"] == {} and d["sensor_not_settling"] == {"encoder_scale": "slider_viscous"}
    e = next(e for e in d["effects"] if e["id"] == "encoder_scale")
    assert e["refitted"] and "no further starts" not in (e["fit_status"] or "")
    assert ("`encoder_scale` was refitted with all its starts although `slider_viscous` already fitted"
            in (tmp_path / "s" / "report.md").read_text())
    assert d["selected"] == d0["selected"] == ["slider_viscous"]
    assert d["cost"]["model_runs"] > d0["cost"]["model_runs"]

    monkeypatch.setattr(diagnosis, "SENSOR_SETTLES_RESCUES", True)
    assert run_main(["diagnose", str(man), "--out", str(tmp_path / "t"), *SMALL]) == 0
    d = json.loads((tmp_path / "t" / "diagnosis.json").read_text())
    assert d["sensor_not_settling"] == {} and set(d["not_refitted"]) == {"encoder_scale"}
    assert d["not_refitted"]["encoder_scale"]["by"] == "slider_viscous"


def test_a_spared_probe_addition_is_refitted_once_its_settler_settles_nothing(viscous, tmp_path, monkeypatch):
    """A settler that settles nothing by the decision (the ablation or the held-out phases judged
    it again): the probe addition it spared is refitted then (5f), by the settled rule again (one
    start when a candidate settles it then). Made to happen with ``settled`` answering None for
    the addition once: at its second look, the one in 5f."""
    from szdyn.diagnose import fit_pass

    _, d0, out = viscous
    added = {q["id"] for q in d0["probing"] if q.get("added")}
    asked = {}
    real = fit_pass.settled

    def first_look_only(rule, refits, floor, *, exclude=None):
        if exclude in added:
            asked[exclude] = asked.get(exclude, 0) + 1
            if asked[exclude] == 2:
                return None
        return real(rule, refits, floor, exclude=exclude)

    monkeypatch.setattr(fit_pass, "settled", first_look_only)
    man = out.parent / "data" / "manifest.toml"
    assert run_main(["diagnose", str(man), "--out", str(tmp_path / "f"), *SMALL]) == 0
    d = json.loads((tmp_path / "f" / "diagnosis.json").read_text())
    assert added and all(asked.get(k, 0) >= 2 for k in added), "no addition was asked again in 5f"
    assert d["not_refitted"] == {} and "refit_unsettled" in d["cost"]["seconds"]
    for e in d["effects"]:
        if e["id"] in added:    # refitted in 5f, its further starts settled by the drag
            assert e["refitted"] and "no further starts (slider_viscous" in e["fit_status"]
    assert "Not refitted" not in (tmp_path / "f" / "report.md").read_text()
    assert d["selected"] == d0["selected"] == ["slider_viscous"]


def test_a_choice_by_the_heldout_recordings_reaches_the_report_and_the_json(viscous, tmp_path, monkeypatch):
    """The close-rival branch end to end: when the rule passes over the candidate explaining most
    (``Decision.passed_over``), the diagnosis keeps the choice, the report says why and that its
    held-out gain is no independent check, and diagnosis.json names the one passed over. The
    small case has no close rivals, so the decision is scripted to have one; the rule itself is
    tested in ``test_close_rivals_are_parted_by_the_heldout_recordings``."""
    import dataclasses

    from szdyn.diagnose import fit_pass

    _, d0, out = viscous
    real, calls = fit_pass.decide, []

    def with_a_close_rival(*args, **kw):
        dec = real(*args, **kw)
        calls.append(dec.verdict)
        return dataclasses.replace(dec, passed_over="load_lift") if dec.verdict == "selected" else dec

    monkeypatch.setattr(fit_pass, "decide", with_a_close_rival)
    man = out.parent / "data" / "manifest.toml"
    assert run_main(["diagnose", str(man), "--out", str(tmp_path / "r"), *SMALL]) == 0
    assert "selected" in calls
    d = json.loads((tmp_path / "r" / "diagnosis.json").read_text())
    assert d["selected"] == d0["selected"] == ["slider_viscous"]
    assert d["passed_over"] == "load_lift" and d0["passed_over"] is None
    report = (tmp_path / "r" / "report.md").read_text()
    assert "**Chosen by the held-out recordings.** `load_lift` explained more" in report
    assert "not an independent check" in report
    assert "Chosen by the held-out recordings" not in (out / "report.md").read_text()


def test_scale_profile_on_request_is_recorded_and_reported(viscous, tmp_path):
    """``--scale-profile``: the named drag's fit started again with every force scaled after
    the decision; diagnosis.json and the report say what each start gave, and the answer stands."""
    _, d0, out = viscous
    man = out.parent / "data" / "manifest.toml"
    assert run_main(["diagnose", str(man), "--out", str(tmp_path / "p"), *SMALL, "--scale-profile"]) == 0
    d = json.loads((tmp_path / "p" / "diagnosis.json").read_text())
    assert d["selected"] == d0["selected"] == ["slider_viscous"]
    sp = d["scale_profile"]
    assert sp["candidate"] == "slider_viscous" and sp["factors"] == [0.8, 0.87, 0.93, 1.07, 1.15, 1.25]
    assert len(sp["rmse_fit"]) == 6 and all(r is None or r > 0 for r in sp["rmse_fit"])
    assert sp["rmse_before"] == pytest.approx(d0["fit"]["after"]["fit_rmse"])    # the same fit before
    if sp["chosen"] is None:
        assert sp["after"] == sp["before"] and d["final"]["values"] == pytest.approx(d0["final"]["values"])
    else:
        assert sp["after"]["rmse_fit"] < sp["rmse_before"] and sp["chosen"] in sp["factors"]
        assert d["final"]["values"]["c_visc"] == pytest.approx(sp["after"]["values"]["c_visc"])
        assert d["fit"]["after"]["fit_rmse"] == pytest.approx(sp["after"]["rmse_fit"])
    assert "**Profiled along the force scale.**" in (tmp_path / "p" / "report.md").read_text()
    assert "Profiled along the force scale" not in (out / "report.md").read_text()


@pytest.mark.parametrize("flag, on", [([], True), (["--amplitude-starts"], True), (["--no-amplitude-starts"], False)])
def test_amplitude_starts_reach_the_diagnosis_unless_turned_off(null, tmp_path, monkeypatch, flag, on):
    """The refits' fifth start (on by default since seed 56) is handed to the diagnosis, and
    ``--no-amplitude-starts`` turns it off."""
    from szdyn.diagnose import diagnosis

    _, _, out = null
    seen = []

    def stop(self, recs):
        seen.append(self.amplitude_starts)
        raise UserInputError("stopped before the diagnosis")
    monkeypatch.setattr(diagnosis.Diagnosis, "fit", stop)
    man = out.parent / "data" / "manifest.toml"
    assert run_main(["diagnose", str(man), "--out", str(tmp_path / "a"), "--quiet", *flag]) != 0
    assert seen == [on]


def test_models_sharing_a_cache_run_each_point_once_whatever_the_roles(null):
    """A second pass (weighted, or with the split exchanged) repeats runs of the first: with a
    shared cache they are not run again, and give the same speeds with the roles reordered."""
    from dataclasses import replace

    from szdyn.diagnose.data import prepare
    from szdyn.diagnose.engine import FeatureModel
    from szdyn.manifest import read_manifest

    _, _, out = null
    recs = prepare(read_manifest(out.parent / "data" / "manifest.toml"))[:2]
    point = [({"mu_k": 0.24}, {})]
    shared = {}
    with FeatureModel(recs, workers=1, cache=shared) as first:
        v1 = first.speeds(point, [0, 1])[0]
    assert first.n_runs_ == 2
    swapped = [replace(recs[1], role="heldout"), recs[0]]
    with FeatureModel(swapped, workers=1, cache=shared) as second:
        v2 = second.speeds(point, [1, 0])[0]
        assert second.n_runs_ == 0
        second.speeds([({"mu_k": 0.25}, {})], [0])
        assert second.n_runs_ == 1                        # a new point is run
    assert all(np.array_equal(a, b) for a, b in zip(v1, v2))
    with FeatureModel(recs, workers=1) as own:            # default: a cache of its own
        own.speeds(point, [0])
        assert own.n_runs_ == 1


# ----------------------------------------------------------------------------- motor current
KT = 0.05   # N m/A, the torque constant the synthetic recordings log their current with


@pytest.fixture(scope="module")
def lift_current(tmp_path_factory):
    """A concealed payload lift, with the motor current logged and its torque constant given."""
    return _synth_and_diagnose(tmp_path_factory, "load_lift", 1.0, torque_constant=KT)


def test_torque_sensor_noise_is_the_noise_of_the_smoothed_current():
    """The even/odd estimate of the smoothed torque's sensor noise matches the actual scatter of
    the smoothed current about the truth (white noise on a constant current)."""
    from szdyn.diagnose.data import prepare_one
    from szdyn.diagnose.noise import torque_sensor_noise
    from szdyn.defaults import default_parameters
    from szdyn.recordings import Recording

    rng = np.random.default_rng(3)
    t = 0.002 * np.arange(2500)
    th = 3.0 * t
    rec = Recording(name="r", t=t, theta_w=th, theta_b=th, current=0.8 + rng.normal(0.0, 0.02, t.size))
    p = prepare_one(rec, default_parameters(), "fit", torque_constant=KT)
    actual = float(np.std(p.tau - KT * 0.8))
    assert p.tau.shape == p.t_feat.shape and p.torque_constant == KT
    assert torque_sensor_noise(p) == pytest.approx(actual, rel=0.25)
    # without a torque constant the current is not turned into a torque
    assert prepare_one(rec, default_parameters(), "fit").tau is None


def test_a_recording_too_coarse_for_the_speed_window_is_refused():
    """A time column in ms read as s samples every 2 s: no speed can be estimated over 0.1 s. A
    10 Hz log (one sample a window) still passes, smoothed over a few samples."""
    from szdyn.diagnose.data import prepare_one
    from szdyn.defaults import default_parameters
    from szdyn.recordings import Recording

    t = 2.0 * np.arange(500)
    rec = Recording(name="ms.csv", t=t, theta_w=3e-3 * t, theta_b=3e-3 * t)
    with pytest.raises(UserInputError, match=r"'ms.csv' is sampled every 2 s .* in seconds\?"):
        prepare_one(rec, default_parameters(), "fit")
    ok = Recording(name="ok.csv", t=t / 20, theta_w=0.06 * t, theta_b=0.06 * t)
    assert prepare_one(ok, default_parameters(), "fit").y.size > 0
    coarse = Recording(name="c.csv", t=t / 10, theta_w=0.03 * t, theta_b=0.03 * t)   # 5 Hz
    with pytest.raises(UserInputError, match=r"every 0.2 s .*or less\.$"):
        prepare_one(coarse, default_parameters(), "fit")
    # shorter than one window (49 samples every 2.05 ms, 0.098 s): enough samples for the
    # recording's own filter, but no instant to compare at; refused before any model run
    ts = 2.05e-3 * np.arange(49)
    short = Recording(name="s.csv", t=ts, theta_w=3.0 * ts, theta_b=3.0 * ts)
    with pytest.raises(UserInputError, match=r"'s.csv' is too short \(0.0984 s\) for a speed window of 0.1 s"):
        prepare_one(short, default_parameters(), "fit")
    # a window long (0.1005 s), but its uniform grid at the median step (3 ms) ends at 0.099 s:
    # still no instant to compare at
    te = np.append(3e-3 * np.arange(34), 0.1005)
    edge = Recording(name="e.csv", t=te, theta_w=3.0 * te, theta_b=3.0 * te)
    with pytest.raises(UserInputError, match=r"'e.csv' is too short \(0.099 s\) for a speed window of 0.1 s"):
        prepare_one(edge, default_parameters(), "fit")
    # a 10 kHz log of 4 s with its time in ms: sampled every 0.1 "s", it passes the sampling
    # check but lasts 4000 "s"; refused before any model run. The same log in s passes.
    tk = 0.1 * np.arange(40_000)
    khz = Recording(name="k.csv", t=tk, theta_w=3e-3 * tk, theta_b=3e-3 * tk)
    with pytest.raises(UserInputError, match=r"'k.csv' lasts 4000 s, more than 3600 s: .* in seconds"):
        prepare_one(khz, default_parameters(), "fit")
    ins = Recording(name="k.csv", t=tk / 1000, theta_w=3e-3 * tk, theta_b=3e-3 * tk)
    assert prepare_one(ins, default_parameters(), "fit").y.size > 0


def test_candidates_that_name_none_are_refused(tmp_path, capsys):
    assert run_main(["diagnose", str(tmp_path / "m.toml"), "--out", str(tmp_path / "o"),
                     "--candidates", ","]) == 2
    assert "--candidates ',' names no candidate" in capsys.readouterr().err


def test_motor_torque_tells_the_force_scale_apart(lift_current):
    """Every force coefficient and the lift a quarter larger (``bench/force_scale.py``'s
    direction) slip almost alike (the band speed barely moves) but draw a quarter more motor
    torque: the model's torque at the truth is near the measured one, at the scaled point far
    from it; the residual carries the torque only when weighted."""
    from szdyn.diagnose.data import prepare
    from szdyn.diagnose.engine import FeatureModel, rms
    from szdyn.manifest import read_manifest

    truth, _, out = lift_current
    recs = prepare(read_manifest(out.parent / "data" / "manifest.toml"))
    assert all(r.tau is not None and r.torque_constant == KT for r in recs)
    v = truth["truth_parameters"]["values"]
    at_truth = {k: v[k] for k in ("k_c", "b_c", "k_imp", "b_imp", "mu_s", "mu_k", "tau_lift")}
    scaled = {k: 1.25 * x for k, x in at_truth.items()}
    which = [0, 1]
    with FeatureModel(recs, workers=1) as m:
        sp = m.speeds([(at_truth, {}), (scaled, {})], which)
        tq = m.torques([(at_truth, {}), (scaled, {})], which)
        err = [[rms(recs[i].y - a) for i, a in zip(which, row)] for row in sp]       # rad/s
        terr = [[rms(recs[i].tau - a) for i, a in zip(which, row)] for row in tq]    # N m
        assert min(terr[1]) > 5 * max(terr[0])
        assert max(err[1]) < 2 * max(err[0])        # the speed alone hardly tells
        n_speed = sum(recs[i].y.size for i in which)
        assert m.residuals([(at_truth, {})], which).shape == (1, n_speed)
        m.torque_weights = {0: 2.0}
        r = m.residuals([(at_truth, {})], which)[0]
        assert r.shape == (n_speed + recs[0].tau.size,)
        m0 = recs[0].y.size
        # per recording: its speed block, then its torque block (if weighted)
        assert np.allclose(r[:m0], recs[0].y - sp[0][0])
        assert np.allclose(r[m0:2 * m0], 2.0 * (recs[0].tau - tq[0][0]))
        assert np.allclose(r[2 * m0:], recs[1].y - sp[0][1])


def test_concealed_lift_with_current_is_sized_by_the_motor_torque(lift_current):
    truth, d, out = lift_current
    assert d["selected"] == ["load_lift"]
    e = next(x for x in d["effects"] if x["selected"])
    tau_true = truth["effect_parameters"]["tau_lift"]
    err = abs(e["primary"]["value"] / tau_true - 1)
    assert err < 0.15        # the goal; measured 2.1 % (4.5 % on the same recordings without current)
    assert d["cost"]["seconds"]["calibrate_torque"] > 0     # the base was calibrated with the torque
    t = d["motor_torque"]
    assert t["used"] and t["torque_constant"] == {r["name"]: KT for r in d["recordings"]}
    assert t["weight"] == pytest.approx(d["noise_floor"] / t["floor"])
    assert t["after"]["heldout_rmse"] < t["before"]["heldout_rmse"]
    assert (out / "torque_fit.png").stat().st_size > 0
    assert "**Motor torque**" in (out / "report.md").read_text()


def test_current_is_compared_unless_switched_off_and_an_unused_one_is_said(lift_current, monkeypatch, capsys):
    """The command hands the measured torque to the diagnosis; ``--no-current`` withholds it; a
    current column without a torque constant is named on stderr, not silently dropped."""
    from szdyn.diagnose import diagnosis

    _, _, out = lift_current
    data = out.parent / "data"
    seen = []

    def stop(self, recs):
        seen.append([r.tau is not None for r in recs])
        raise UserInputError("stopped before fitting")
    monkeypatch.setattr(diagnosis.Diagnosis, "fit", stop)
    man = str(data / "manifest.toml")
    assert run_main(["diagnose", man, "--out", str(out.parent / "x")]) != 0
    assert run_main(["diagnose", man, "--out", str(out.parent / "x"), "--no-current"]) != 0
    assert seen == [[True] * 4, [False] * 4]
    text = (data / "manifest.toml").read_text()
    motor = text[text.index("[motor]"):text.index("[split]")]
    (data / "nokt.toml").write_text(text.replace(motor, ""))
    capsys.readouterr()
    assert run_main(["diagnose", str(data / "nokt.toml"), "--out", str(out.parent / "x")]) != 0
    assert seen[-1] == [False] * 4
    assert "current column not used in" in capsys.readouterr().err


def test_a_recording_without_its_load_is_named_before_the_diagnosis(null, monkeypatch, capsys):
    """load_kg is optional in the manifest; a recording without it runs at the default load,
    and the command says so at the start (not only in the report's heavy-look line)."""
    from szdyn.diagnose import diagnosis

    def stop(self, recs):
        raise UserInputError("stopped before fitting")
    monkeypatch.setattr(diagnosis.Diagnosis, "fit", stop)
    data = null[2].parent / "data"
    text = (data / "manifest.toml").read_text()
    first = text.index("load_kg")
    (data / "noload.toml").write_text(text[:first] + text[text.index("\n", first) + 1:])
    capsys.readouterr()
    assert run_main(["diagnose", str(data / "noload.toml"), "--out", str(data.parent / "x"), "--quiet"]) != 0
    said = [line for line in capsys.readouterr().err.splitlines() if "no load_kg" in line]
    assert len(said) == 1 and "(m_b = 1 kg used): the load is the model's default" in said[0]
    # a [model] m_b is the load of such a recording, and is named as such
    (data / "noload.toml").write_text("[model]\nm_b = 2.5\n" + text[:first] + text[text.index("\n", first) + 1:])
    assert run_main(["diagnose", str(data / "noload.toml"), "--out", str(data.parent / "x"), "--quiet"]) != 0
    said = [line for line in capsys.readouterr().err.splitlines() if "no load_kg" in line]
    assert len(said) == 1 and "(m_b = 2.5 kg used): the load is [model] m_b" in said[0]
    assert run_main(["diagnose", str(data / "manifest.toml"), "--out", str(data.parent / "x"), "--quiet"]) != 0
    assert "no load_kg" not in capsys.readouterr().err


def test_current_only_on_heldout_recordings_is_not_used_and_the_report_says_so():
    """The torque must be among the fit recordings to take part: otherwise it is left out (no
    weights), and the report says why."""
    from types import SimpleNamespace

    from szdyn.diagnose.report import _torque_md

    recs = [SimpleNamespace(name=f"r{k}", tau=None if k < 2 else np.zeros(3), torque_constant=KT,
                            role="fit" if k < 2 else "heldout") for k in range(3)]
    model = SimpleNamespace(torque_weights={})
    d = Diagnosis(log=lambda m: None)
    t = d._torque_floor(model, recs, [0, 1], [0, 1, 2], {})
    assert t == {"used": False, "recordings": ["r2"], "torque_constant": {"r2": KT}}
    assert model.torque_weights == {}
    assert "only held-out recordings" in _torque_md(SimpleNamespace(torque_=t))[0]
    assert _torque_md(SimpleNamespace(torque_=None)) == []


def test_a_shared_run_without_the_torque_is_run_again_for_a_recording_with_one(lift_current):
    """Runs shared from a model whose recording had no measured torque do not answer one that
    has: the run is repeated with the torque, not read as missing."""
    from dataclasses import replace

    from szdyn.diagnose.data import prepare
    from szdyn.diagnose.engine import FeatureModel
    from szdyn.manifest import read_manifest

    _, _, out = lift_current
    rec = prepare(read_manifest(out.parent / "data" / "manifest.toml"))[0]
    shared, point = {}, [({"mu_k": 0.26}, {})]
    with FeatureModel([replace(rec, tau=None)], workers=1, cache=shared) as first:
        first.speeds(point, [0])
    with FeatureModel([rec], workers=1, cache=shared) as second:
        [[tq]] = second.torques(point, [0])
        assert second.n_runs_ == 1 and tq is not None and np.all(np.isfinite(tq))
        second.speeds(point, [0])
        assert second.n_runs_ == 1


# ----------------------------------------------------------------------------- wheel phase
def _pitches_apart(q_a, q_b, n_circles) -> float:
    """Distance of two initial wheel angles (rad) in circle pitches, modulo the half pitch by
    which this wheel (8 rollers, 100 circles) is symmetric."""
    off = ((q_a - q_b) * n_circles / (2 * math.pi)) % 0.5
    return min(off, 0.5 - off)


def test_the_wheel_phase_is_recovered_from_each_recording(null):
    """At the true coefficients, the scan finds each recording's initial wheel angle (which the
    encoders do not measure) to the estimate's uncertainty, modulo the half pitch by which this
    wheel (8 rollers, 100 circles) is symmetric; there it fits clearly better than the scan's
    median, and the runs at the estimated phase are the runs the model then makes."""
    from szdyn.diagnose.data import prepare
    from szdyn.diagnose.engine import FeatureModel, rms
    from szdyn.diagnose.phase import IDENTIFIED_SHARE, PHASE_UNCERTAINTY, estimate_phases
    from szdyn.manifest import read_manifest

    truth, _, out = null
    recs = prepare(read_manifest(out.parent / "data" / "manifest.toml"))
    tv = truth["perturbed"]
    base = {k: tv[k]["value"] for k in ("k_c", "b_c", "k_imp", "b_imp", "mu_s", "mu_k")}
    q0 = {r["file"]: r["q_w0"] for r in truth["recordings"]}
    p = recs[0].params
    assert p.n_circles == 100 and p["n_rollers"] == 8
    with FeatureModel(recs, workers=1) as m:
        est = estimate_phases(m, base, range(len(recs)))
        for i, r in enumerate(recs):
            e = est[i]
            off = _pitches_apart(e.q_w0, q0[r.name], p.n_circles)
            assert off <= PHASE_UNCERTAINTY, (r.name, off)
            assert e.identified
            assert e.median_rmse ** 2 - e.rmse ** 2 >= IDENTIFIED_SHARE * e.model_spread ** 2 > 0
        # a whole point (model changes, sensor changes) scans the same runs
        n = m.n_runs_
        assert estimate_phases(m, (base, {}), [0])[0] == est[0] and m.n_runs_ == n
        m.phases = {i: e.q_w0 for i, e in est.items()}
        at = m.speeds([(base, {})], range(len(recs)))[0]
        assert m.n_runs_ == n                        # the scan's runs, reused
        assert all(rms(r.y - v) == pytest.approx(est[i].rmse) for i, (r, v) in enumerate(zip(recs, at)))


def test_null_diagnosis_estimates_the_phases_and_the_floor_loses_the_bumps(null):
    """The end-to-end null: every recording's phase is identified, the floor's bump part is the
    phase's uncertainty (well below the sensor part) and the report says so; the held-out
    recordings' phases, estimated again for the final model, are the truth's."""
    from szdyn.diagnose.phase import PHASE_UNCERTAINTY

    _, d, out = null
    assert d["wheel_phase"]["estimated"] and d["wheel_phase"]["base_over_floor"] <= d["wheel_phase"]["gate"]
    ph = d["wheel_phase"]["recordings"]
    assert set(ph) == set(d["noise_floor_per_recording"]) and all(v["identified"] for v in ph.values())
    assert d["noise_floor_parts"]["bump"] < 0.5 * d["noise_floor_parts"]["sensor"]
    assert d["cost"]["seconds"]["phase"] > 0 and d["cost"]["seconds"]["calibrate_phase"] > 0
    assert "**Wheel phase.**" in (out / "report.md").read_text()
    # the held-out recordings' phases, estimated again for the final model (here the base)
    truth = null[0]
    held = d["split"]["heldout"]
    assert held and set(d["wheel_phase"]["heldout"]) == set(held)
    q0 = {r["file"]: r["q_w0"] for r in truth["recordings"]}
    for k in held:
        v = d["wheel_phase"]["heldout"][k]
        assert v["identified"] and _pitches_apart(v["q_w0"], q0[k], 100) <= PHASE_UNCERTAINTY, (k, v)
    assert d["cost"]["seconds"]["heldout_phase"] > 0
    assert "estimated again for each model" in (out / "report.md").read_text()
    # the final model (the base here) runs the fit recordings with the base's phases
    assert d["wheel_phase"]["final_fit"] == {k: v["q_w0"] for k, v in ph.items() if k not in held}


@pytest.mark.parametrize("flag, attr, default", [
    ("--no-phase", "fit_phase", True),      # every run then starts from the default offset
    ("--restart", "restart", False),        # off unless asked
])
def test_a_switch_reaches_the_diagnosis(null, monkeypatch, flag, attr, default):
    from szdyn.diagnose import diagnosis

    _, _, out = null
    seen = []

    def stop(self, recs):
        seen.append(getattr(self, attr))
        raise UserInputError("stopped before fitting")
    monkeypatch.setattr(diagnosis.Diagnosis, "fit", stop)
    man = str(out.parent / "data" / "manifest.toml")
    assert run_main(["diagnose", man, "--out", str(out.parent / "x")]) != 0
    assert run_main(["diagnose", man, "--out", str(out.parent / "x"), flag]) != 0
    assert seen == [default, not default]


def test_an_interrupted_diagnosis_resumes_from_its_saved_runs_to_the_same_answer(null, tmp_path, monkeypatch,
                                                                                 capsys):
    """Ctrl-C after some model runs: they are saved in ``--out/checkpoint`` and the command says
    how to resume; the same command then loads them, makes only the runs it lacks and writes
    the same diagnosis as an uninterrupted run, and removes the checkpoint."""
    from szdyn.diagnose import engine

    _, d0, out = null
    man = str(out.parent / "data" / "manifest.toml")
    res = str(tmp_path / "r")
    real, calls = engine._simulate, [0]

    def interrupted(task):
        calls[0] += 1
        if calls[0] == 40:
            raise KeyboardInterrupt
        return real(task)
    # one worker: the runs are made in this process, where the patch acts
    monkeypatch.setattr(engine, "_simulate", interrupted)
    assert run_main(["diagnose", man, "--out", res, "--workers", "1", *SMALL]) == 130
    assert "re-run the same command to resume" in capsys.readouterr().err
    assert not (tmp_path / "r" / "diagnosis.json").exists()
    monkeypatch.setattr(engine, "_simulate", real)
    assert run_main(["diagnose", man, "--out", res, "--workers", "1", "--keep-runs", *SMALL]) == 0
    d = json.loads((tmp_path / "r" / "diagnosis.json").read_text())
    assert d["cost"]["resumed_runs"] == 39 and d0["cost"]["resumed_runs"] == 0
    assert d["cost"]["model_runs"] + 39 == d0["cost"]["model_runs"]
    for key in ("verdict", "selected", "calibrated", "fit", "effects", "noise_floor"):
        assert d[key] == d0[key], key
    assert "39 more model runs were loaded from a checkpoint" in (tmp_path / "r" / "report.md").read_text()
    # kept (--keep-runs): run again, every run is loaded and none made; then it is removed
    assert (tmp_path / "r" / "checkpoint" / "fingerprint.json").is_file()
    # ... first interrupted while its results are written: the earlier set stays whole
    from szdyn.diagnose import report

    def no_plots(*a):
        raise KeyboardInterrupt

    def files():   # (an atomic write makes a new inode even where the bytes come out equal)
        return {f: ((tmp_path / "r" / f).read_bytes(), (tmp_path / "r" / f).stat().st_ino)
                for f in ("params.json", "report.md", "diagnosis.json")}
    before = files()
    real_plots = report._plots
    monkeypatch.setattr(report, "_plots", no_plots)   # after params.json, before report.md
    assert run_main(["diagnose", man, "--out", res, "--keep-runs", *SMALL]) == 130
    monkeypatch.setattr(report, "_plots", real_plots)
    assert files() == before
    assert not list((tmp_path / "r").glob(".partial-*"))
    # a plot of an earlier run with a current column, which these recordings lack: removed
    (tmp_path / "r" / "torque_fit.png").write_bytes(b"an earlier run's")
    assert run_main(["diagnose", man, "--out", res, *SMALL]) == 0
    assert not (tmp_path / "r" / "torque_fit.png").exists()
    d = json.loads((tmp_path / "r" / "diagnosis.json").read_text())
    assert d["cost"]["model_runs"] == 0 and d["cost"]["resumed_runs"] == d0["cost"]["model_runs"]
    assert d["selected"] == d0["selected"] and d["fit"] == d0["fit"]
    assert not (tmp_path / "r" / "checkpoint").exists()


@pytest.mark.skipif(not Path("/proc/self/stat").exists(), reason="needs /proc")
def test_a_diagnosis_sent_sigterm_saves_its_runs_and_leaves_no_worker(null, tmp_path):
    """``kill`` (SIGTERM, as a batch scheduler stops a job) of a diagnosis on two workers: it
    stops as on Ctrl-C (runs saved, how to resume said, exit 143, no partial results) and its
    pool workers end too (before szdyn.processes they stayed, idle, holding their memory)."""
    from test_processes import alive, children

    _, _, out = null
    man = str(out.parent / "data" / "manifest.toml")
    res = tmp_path / "r"
    proc = subprocess.Popen([sys.executable, "-m", "szdyn.run", "diagnose", man, "--out", str(res),
                             "--workers", "2", *SMALL], cwd=ROOT, stderr=subprocess.PIPE, text=True)
    try:
        deadline = time.monotonic() + 300
        while time.monotonic() < deadline and not list((res / "checkpoint").glob("runs-*.npz")):
            assert proc.poll() is None, "the diagnosis ended before its first runs were saved"
            time.sleep(0.05)
        workers = children(proc.pid)
        proc.send_signal(signal.SIGTERM)
        _, err = proc.communicate(timeout=120)
    finally:
        if proc.poll() is None:
            proc.kill()
            proc.wait()
    assert proc.returncode == 143, err
    assert "re-run the same command to resume" in err and "terminated (SIGTERM)" in err
    assert "Traceback" not in err
    assert list((res / "checkpoint").glob("runs-*.npz")) and not (res / "diagnosis.json").exists()
    assert len(workers) >= 2        # the two pool workers (and multiprocessing's resource tracker)
    deadline = time.monotonic() + 30
    while time.monotonic() < deadline and any(alive(p) for p in workers):
        time.sleep(0.1)
    assert not [p for p in workers if alive(p)]


def test_diagnose_without_checkpoint_or_with_an_out_that_is_a_file(null, tmp_path, monkeypatch):
    """``--no-checkpoint`` gives the diagnosis none; an ``--out`` that is a file is refused
    before any run, and the file is left as it was."""
    from szdyn.diagnose import diagnosis

    _, _, out = null
    man = str(out.parent / "data" / "manifest.toml")
    seen = []

    def stop(self, recs):
        seen.append(self.checkpoint)
        raise UserInputError("stopped before fitting")
    monkeypatch.setattr(diagnosis.Diagnosis, "fit", stop)
    assert run_main(["diagnose", man, "--out", str(tmp_path / "a")]) != 0
    assert run_main(["diagnose", man, "--out", str(tmp_path / "b"), "--no-checkpoint"]) != 0
    assert seen[0].directory == tmp_path / "a" / "checkpoint" and seen[1] is None
    (tmp_path / "file").write_text("x")
    assert run_main(["diagnose", man, "--out", str(tmp_path / "file")]) == 2
    assert len(seen) == 2 and (tmp_path / "file").read_text() == "x"


def test_a_large_mismatch_leaves_the_phases_unestimated(viscous):
    """The concealed drag leaves the calibrated base far beyond the floor: a phase scan there
    would line the model's bumps up with the missing drag, so none is made and every run keeps
    the default offset (the report says why)."""
    from szdyn.diagnose.phase import PHASE_GATE

    _, d, out = viscous
    ph = d["wheel_phase"]
    assert ph["gate"] == PHASE_GATE and ph["base_over_floor"] > PHASE_GATE
    assert not ph["estimated"] and ph["recordings"] == {}
    assert "phase" not in d["cost"]["seconds"]
    assert f"beyond {PHASE_GATE:g}x" in (out / "report.md").read_text()


def test_the_next_recording_is_ranked_after_the_diagnosis_unless_switched_off(viscous, monkeypatch, capsys):
    """The CLI runs :class:`~szdyn.diagnose.design.NextRecording` on the fitted diagnosis and
    hands it to the report (the small viscous case has no refitted rival, so it says why not);
    ``--no-next-recording`` hands None."""
    from szdyn.diagnose import design, diagnosis, report

    _, d, out = viscous
    nr = d["next_recording"]
    assert nr["contenders"] == ["slider_viscous"] and nr["recommended"] is None
    assert "no refitted rival" in nr["why_not"] and nr["protocols"] == [] and nr["model_runs"] == 0
    assert "## The next recording to take" in (out / "report.md").read_text()
    assert not (out / "next_recording.png").exists()
    seen = []

    def fit(self, recs):
        self.verdict_ = "none"
        return self
    monkeypatch.setattr(diagnosis.Diagnosis, "fit", fit)
    monkeypatch.setattr(design.NextRecording, "fit", lambda self, d: seen.append("ranked") or self)
    monkeypatch.setattr(report, "write_report", lambda d, o, next_recording=None: seen.append(next_recording) or
                        {"selected": [], "fit": {"before": {"heldout_rmse": 1.0}, "after": {"heldout_rmse": 1.0}}})
    man = str(out.parent / "data" / "manifest.toml")
    assert run_main(["diagnose", man, "--out", str(out.parent / "y"), "--no-checkpoint"]) == 0
    assert seen[0] == "ranked" and isinstance(seen[1], design.NextRecording)
    assert run_main(["diagnose", man, "--out", str(out.parent / "y"), "--no-checkpoint", "--no-next-recording"]) == 0
    assert seen[2:] == [None]

    # a failure of the ranking (advice) costs nothing of the diagnosis: it is said, and the
    # results are written without it
    def broken(self, d):
        raise RuntimeError("no pool")
    monkeypatch.setattr(design.NextRecording, "fit", broken)
    assert run_main(["diagnose", man, "--out", str(out.parent / "y"), "--no-checkpoint"]) == 0
    assert seen[3:] == [None]
    assert "the next recording was not ranked (RuntimeError: no pool)" in capsys.readouterr().err


def test_coefficient_noise_on_model_runs(lift_current):
    """The coefficients' share of the floor on real model runs: nothing at a step of 0 (the
    same runs), something finite at 1 %."""
    from szdyn.diagnose.data import prepare
    from szdyn.diagnose.engine import FeatureModel
    from szdyn.diagnose.noise import coefficient_noise
    from szdyn.manifest import read_manifest

    truth, _, out = lift_current
    recs = prepare(read_manifest(out.parent / "data" / "manifest.toml"))
    v = truth["truth_parameters"]["values"]
    at_truth = {k: v[k] for k in ("k_c", "b_c", "k_imp", "b_imp", "mu_s", "mu_k", "tau_lift")}
    with FeatureModel(recs, workers=1) as m:
        assert coefficient_noise(m, 0, at_truth, 0.0) == 0.0
        c = coefficient_noise(m, 0, at_truth, 0.01)
    assert math.isfinite(c) and c > 0.0
