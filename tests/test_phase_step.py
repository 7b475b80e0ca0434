"""The phase-profiled step of the base calibration (Diagnosis._phase_step), on a stand-in model.

The stand-in has what null 32 showed: each recording's impact bumps follow the wheel phase and
shift with a coefficient (here k_c), and the rest of the residual fixes that coefficient. At the
phases estimated at the calibration every step of k_c towards the truth misaligns the bumps and
fits worse; with the phases estimated at the trial point itself it fits at the truth.
"""
import dataclasses
import math

import numpy as np
import pytest

from szdyn.diagnose.candidates import CANDIDATES
from szdyn.diagnose.diagnosis import Diagnosis
from szdyn.diagnose.fit import FitResult, Hypothesis
from szdyn.diagnose.phase import estimate_phases
from szdyn.diagnose.report import _status

START = {"k_c": 0.05, "b_c": 0.0075, "k_imp": 4e12, "mu_s": 0.3, "mu_k": 0.25}
N_CIRCLES = 100
PITCH = 2 * math.pi / N_CIRCLES
K_TRUE = 0.056                      # N m/rad, 12 % above the start
SHIFT = 0.37 * PITCH / 0.006        # wheel angle the bumps move per N m/rad of k_c
TRUE_PHASE = (0.21 * PITCH, 0.63 * PITCH)
BUMP = 0.1                          # rad/s: bump amplitude
SMOOTH = 0.5                        # rad/s per relative error of k_c: the smooth part


class _Params:
    n_circles = N_CIRCLES

    def default_wheel_offset(self):
        return 0.0


class _Rec:
    params = _Params()


class BumpShift:
    """``residuals(points, which)`` like FeatureModel's: per recording 10 samples of bumps
    (amplitude BUMP, aligned where ``q_w0 - SHIFT k_c`` is the recording's phase) and 10 of a
    smooth part ``SMOOTH (k_c - K_TRUE) / K_TRUE``."""

    def __init__(self):
        self.recordings = [_Rec(), _Rec()]
        self.phases = {}

    def _one(self, i, mc):
        q = mc.get("q_w0", self.phases.get(i, 0.0))
        k = mc["k_c"]
        ph = TRUE_PHASE[i] + SHIFT * (k - K_TRUE)
        bumps = BUMP * np.sin(math.pi * (q - ph) / PITCH) * np.ones(10)
        return np.concatenate([bumps, np.full(10, SMOOTH * (k - K_TRUE) / K_TRUE)])

    def residuals(self, points, which):
        return np.array([np.concatenate([self._one(i, mc) for i in which]) for mc, _ in points])


def _calibrated(model, h):
    """The calibration as the diagnosis leaves it: at the start, phases estimated there, and a
    Jacobian that sees the smooth part only (a finite difference across the rippled bumps)."""
    x = h.x_start()
    est = estimate_phases(model, h.point(x), [0, 1])
    model.phases = {i: e.q_w0 for i, e in est.items()}
    r = model.residuals([h.point(x)], [0, 1])[0]
    J = np.zeros((r.size, x.size))
    for blk in (0, 1):                              # d speed / d log k_c of the smooth part
        J[20 * blk + 10:20 * blk + 20, 0] = -SMOOTH * START["k_c"] / K_TRUE
    rss = float(r @ r)
    res = FitResult(hypothesis=h, x=x, values=h.values(x), std={}, corr=np.eye(x.size), rss_fit=rss,
                    n_fit=r.size, rmse_fit=math.sqrt(rss / r.size), nfev=1, J=J, status="converged",
                    extra={"njac": 1})
    return res, est


def test_profiled_step_reaches_the_truth_the_held_phases_hide():
    model, h = BumpShift(), Hypothesis(START)
    res, est = _calibrated(model, h)
    # the held phases hide it: at the truth's k_c they misalign the bumps
    z = h.coordinates({**START, "k_c": K_TRUE})
    r = model.residuals([h.point(z)], [0, 1])[0]
    assert r @ r > 2 * res.rss_fit
    held = dict(model.phases)
    out = Diagnosis(phase_steps=2)._phase_step(model, h, res, [0, 1], est)
    assert out is not res and out.extra["phase_steps"] >= 1
    assert out.values["k_c"] == pytest.approx(K_TRUE, rel=0.01)
    assert out.rmse_fit < 0.1 * res.rmse_fit
    assert model.phases == held      # the caller decides whose phases the model holds
    fit_phases = out.extra["fit_phases"]
    for i in (0, 1):    # the phases that fit the new point, kept with the result
        assert abs(((fit_phases[i] - TRUE_PHASE[i]) / PITCH + 0.5) % 1.0 - 0.5) < 1 / 32
        assert est[i].q_w0 == fit_phases[i]
    # run with them, the result's own fit is reproduced; with the held ones it is not
    with Diagnosis._fit_phases(model, out):
        r = model.residuals([h.point(out.x)], [0, 1])[0]
    assert math.sqrt(r @ r / r.size) == pytest.approx(out.rmse_fit)
    assert model.phases == held
    r = model.residuals([h.point(out.x)], [0, 1])[0]
    assert math.sqrt(r @ r / r.size) > 2 * out.rmse_fit


def test_profiled_step_of_a_candidate_refit_keeps_its_record():
    """A candidate's refit gets the same step (the effect's column is flat here): the base
    coefficients reach the truth, the refit's own record (start, restart) is kept."""
    model, h0 = BumpShift(), Hypothesis(START)
    res0, _ = _calibrated(model, h0)
    h = Hypothesis(START, CANDIDATES["slider_viscous"])
    x = np.concatenate([res0.x, h.x_start()[h.n_base:]])
    J = np.zeros((res0.J.shape[0], x.size))
    J[:, :h.n_base] = res0.J
    res = FitResult(hypothesis=h, x=x, values=h.values(x), std={}, corr=np.eye(x.size), rss_fit=res0.rss_fit,
                    n_fit=res0.n_fit, rmse_fit=res0.rmse_fit, nfev=1, J=J, status="converged",
                    extra={"njac": 3, "start": "linear step"})
    out = Diagnosis(phase_steps=1)._phase_step(model, h, res, [0, 1], what="refit of slider_viscous",
                                               max_jac=2)
    assert out.hypothesis is h and out.extra["phase_steps"] == 1
    assert out.extra["start"] == "linear step" and out.extra["njac"] > 3
    assert out.values["k_c"] == pytest.approx(K_TRUE, rel=0.01)
    assert set(out.extra["fit_phases"]) == {0, 1}


def test_no_step_when_off_or_nothing_better():
    model, h = BumpShift(), Hypothesis(START)
    res, est = _calibrated(model, h)
    before = dict(model.phases)
    assert Diagnosis(phase_steps=0)._phase_step(model, h, res, [0, 1], est) is res
    assert model.phases == before
    # at the truth already: no step fits clearly better, phases untouched
    res_t, est_t = _calibrated(model, Hypothesis({**START, "k_c": K_TRUE}))
    before = dict(model.phases)
    assert Diagnosis(phase_steps=2)._phase_step(model, res_t.hypothesis, res_t, [0, 1], est_t) is res_t
    assert model.phases == before


@pytest.mark.parametrize("bad", [-1, 1.5, True, "2"])
def test_phase_steps_must_be_a_count(bad):
    with pytest.raises(ValueError, match="phase_steps"):
        Diagnosis(phase_steps=bad)


C_TRUE = 0.35                       # rad/(N m): the stand-in's drive compliance
WIND = 0.3 * PITCH / C_TRUE         # wheel angle the bumps move per unit compliance and unit torque
TORQUE = np.linspace(0.5, 1.5, 10)  # relative drive torque at the bump samples


class WindUp(BumpShift):
    """As :class:`BumpShift` (k_c at the start is the truth), but the bumps also move with a
    drive compliance ``c`` times the drive torque, which varies over each recording: a phase
    estimate absorbs the mean shift of any ``c``, only the right one aligns every sample."""

    def _one(self, i, mc):
        q = mc.get("q_w0", self.phases.get(i, 0.0))
        c = 1.0 / mc["k_drive"] if mc.get("drive_mode") == 2.0 else 0.0
        ph = TRUE_PHASE[i] + WIND * (c - C_TRUE) * TORQUE
        smooth = np.full(10, SMOOTH * (mc["k_c"] - START["k_c"]) / START["k_c"])
        return np.concatenate([BUMP * np.sin(math.pi * (q - ph) / PITCH), smooth])


def _rigid_refit(model, cand, value=None, extra=None):
    """A candidate's refit as the diagnosis leaves it at a rigid calibration: the base's phases,
    the effect off (or its first parameter at ``value``), and an effect column the Jacobian sees
    flat (the held phases hide it)."""
    res0, est = _calibrated(model, Hypothesis(START))
    h = Hypothesis(START, CANDIDATES[cand])
    x = np.concatenate([res0.x, np.zeros(len(h.params) - h.n_base)])
    if value is not None:
        x = h.coordinates({**h.values(x), CANDIDATES[cand].params[0].name: value})
    r = model.residuals([h.point(x)], [0, 1])[0]
    J = np.zeros((r.size, x.size))
    J[:, :h.n_base] = res0.J
    rss = float(r @ r)
    return h, FitResult(hypothesis=h, x=x, values=h.values(x), std={}, corr=np.eye(x.size), rss_fit=rss,
                        n_fit=r.size, rmse_fit=math.sqrt(rss / r.size), nfev=1, J=J, status="converged",
                        extra={"njac": 3, **(extra or {})})


def test_a_phase_ladder_finds_a_compliance_the_held_phases_hide():
    model = WindUp()
    h, res = _rigid_refit(model, "drive_compliance")
    assert CANDIDATES["drive_compliance"].phase_ladder
    # held phases hide it: the true compliance fits worse than the rigid drive at them
    r = model.residuals([h.point(h.coordinates({**h.values(res.x), "drive_compliance": C_TRUE}))], [0, 1])[0]
    assert r @ r > res.rss_fit
    held = dict(model.phases)
    out = Diagnosis(phase_steps=2)._phase_step(model, h, res, [0, 1], what="refit of drive_compliance",
                                               max_jac=2)
    assert out is not res and out.extra["phase_steps"] >= 1
    assert f"{out.extra['phase_steps']} phase-profiled step(s) (--phase-steps)" in _status(out)
    # within the ladder's spacing (a factor 1.6) of the truth at least, and the fit far better
    assert out.values["drive_compliance"] == pytest.approx(C_TRUE, rel=0.1)
    assert out.rmse_fit < 0.3 * res.rmse_fit
    assert model.phases == held


def test_without_its_ladder_the_compliance_is_not_found():
    """The same recordings and the same candidate with its ladder taken away: the linear step,
    whose effect column the Jacobian sees flat, has nothing to move, and no step is taken."""
    model = WindUp()
    h, res = _rigid_refit(model, "drive_compliance")
    h = Hypothesis(START, dataclasses.replace(CANDIDATES["drive_compliance"], phase_ladder=()))
    res = dataclasses.replace(res, hypothesis=h)
    assert Diagnosis(phase_steps=2)._phase_step(model, h, res, [0, 1], max_jac=2) is res


def test_a_phase_ladder_needs_a_single_parameter():
    with pytest.raises(ValueError, match="single parameter"):
        dataclasses.replace(CANDIDATES["position_periodic"], phase_ladder=(0.1,))


def test_the_report_says_why_a_ladder_candidate_was_refitted():
    from types import SimpleNamespace

    from szdyn.diagnose.report import _nominated_md
    n = {"feature": "band_accel", "r2": 0.1, "ids": [], "added": []}
    d = SimpleNamespace(nominated_={**n, "phase_ladder": ["drive_compliance"]}, nominate_r2=0.3, mismatch_=True)
    assert _nominated_md(d).startswith("`drive_compliance` refitted because this pass takes phase-profiled steps")
    d.nominated_ = {**n, "phase_ladder": []}
    assert "phase-profiled" not in _nominated_md(d)
