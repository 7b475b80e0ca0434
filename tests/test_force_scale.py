"""The force-scale secant (szdyn.diagnose.force_scale): the direction along which every force
scales, and the reported standard deviations from a Jacobian corrected along it by runs."""
import math

import numpy as np
import pytest

from szdyn.diagnose.candidates import CANDIDATES, RIGID_COMPLIANCE
from szdyn.diagnose.engine import FeatureModel
from szdyn.diagnose.fit import FitResult, Hypothesis, _uncertainty, fit_hypothesis
from szdyn.diagnose.force_scale import (FORCE_SCALE_STEP, HELDOUT_SCALE_POINTS, force_scale_direction,
                                        force_scale_secant, heldout_along_force_scale,
                                        profile_along_force_scale)

START = {"k_c": 0.05, "b_c": 0.0075, "k_imp": 4e12, "mu_s": 0.3, "mu_k": 0.25}


def test_every_force_scaled_candidate_has_a_parameter_that_scales():
    for c in CANDIDATES.values():
        assert c.force_scaled == any(p.force_power != 0.0 for p in c.params), c.id


def test_direction_in_fit_coordinates():
    # the base's log coordinates move by 1 per unit log scale; a torque amplitude by its value,
    # a compliance by minus its value, a shape parameter and a sensor term not at all
    h = Hypothesis(START, CANDIDATES["slider_stribeck"])
    x = np.array([0.1, -0.2, 0.0, 0.05, 0.3, 0.08, 0.7])
    assert force_scale_direction(h, x).tolist() == [1, 1, 1, 1, 1, 0.08, 0.0]
    h = Hypothesis(START, CANDIDATES["drive_compliance"])
    assert force_scale_direction(h, np.r_[np.zeros(5), 0.4])[-1] == pytest.approx(-0.4)
    h = Hypothesis(START, CANDIDATES["encoder_delay"])
    assert force_scale_direction(h, np.r_[np.zeros(5), 0.01])[-1] == 0.0
    # moving along it scales every force and the torque alike
    h = Hypothesis(START, CANDIDATES["load_lift"])
    x = np.r_[np.zeros(5), 0.05]
    lam = 1.0001          # d x / d log(lam): exact for the log coordinates, first order for tau_lift
    v0, v1 = h.values(x), h.values(x + math.log(lam) * force_scale_direction(h, x))
    for k in ("k_c", "b_c", "k_imp", "mu_s", "mu_k", "tau_lift"):
        assert v1[k] / v0[k] == pytest.approx(lam, rel=1e-8), k


class LinearModel:
    """``residuals`` like FeatureModel's for a model speed linear in the fit coordinates,
    ``speed = A x`` (``hyp`` maps ``x`` to a point; the model recovers ``x`` from it)."""

    def __init__(self, hyp, A, y, failed=False):
        self.hyp, self.A, self.y, self.failed = hyp, A, y, failed

    def any_failed(self, points, which):
        return self.failed

    def _x(self, point):
        mc, _ = point
        v = dict(mc)
        x = [math.log(v[k] / self.hyp._start_log[k]) for k in ("k_c", "b_c", "k_imp", "mu_k")]
        x.append(math.log((v["mu_s"] - v["mu_k"]) / self.hyp._start_log["dmu_s"]))
        x.append(v["tau_lift"])
        return np.array(x)

    def residuals(self, points, which):
        return np.array([self.y - self.A @ self._x(pt) for pt in points])


def _fit_result(h, x, J, y, A):
    r = y - A @ x
    std, corr = _uncertainty(h, x, J, float(r @ r), r.size)
    return FitResult(hypothesis=h, x=x, values=h.values(x), std=std, corr=corr, rss_fit=float(r @ r),
                     n_fit=r.size, rmse_fit=math.sqrt(r @ r / r.size), nfev=1, J=J)


def _setup(seed=0, n=60):
    rng = np.random.default_rng(seed)
    h = Hypothesis(START, CANDIDATES["load_lift"])
    x = np.r_[0.02, -0.01, 0.03, 0.01, -0.02, 0.06]
    s = force_scale_direction(h, x)
    # a model that the force scale changes only slightly (1e-3 of a typical column): the columns
    # cancel along s
    A = rng.standard_normal((n, 6))
    A -= np.outer(A @ s, s) / (s @ s) * (1 - 1e-3)
    y = A @ x + 0.01 * rng.standard_normal(n)
    return h, x, s, A, y, rng


def test_an_exact_jacobian_is_left_as_it_is():
    h, x, s, A, y, _ = _setup()
    res = _fit_result(h, x, A, y, A)
    out = force_scale_secant(LinearModel(h, A, y), h, res, [0])
    assert out.extra["force_scale"]["corrected"]
    m, p = out.extra["force_scale"]["measured"], out.extra["force_scale"]["predicted"]
    assert m == pytest.approx(p, rel=1e-6)
    for k in res.std:
        assert out.std[k] == pytest.approx(res.std[k], rel=1e-6), k
    assert out.x is res.x and out.rss_fit == res.rss_fit and out.J is res.J   # the fit is untouched


def test_a_jacobian_that_breaks_the_valley_gets_it_back():
    # the fit's Jacobian off by 3 % per column (as the impact bumps leave it): it sees the scale
    # as well determined; the runs along s restore the valley, and the torque's std grows to
    # that of the exact Jacobian
    h, x, s, A, y, rng = _setup()
    J = A * (1 + 0.03 * rng.standard_normal(A.shape))
    exact = _fit_result(h, x, A, y, A)
    res = _fit_result(h, x, J, y, A)
    assert res.std["tau_lift"] < 0.1 * exact.std["tau_lift"]          # measured 0.05x
    out = force_scale_secant(LinearModel(h, A, y), h, res, [0])
    fs = out.extra["force_scale"]
    assert fs["predicted"] > 10 * fs["measured"]
    assert fs["measured"] == pytest.approx(FORCE_SCALE_STEP * math.sqrt(np.mean((A @ s) ** 2)), rel=1e-6)
    assert out.std["tau_lift"] == pytest.approx(exact.std["tau_lift"], rel=2e-3)     # measured 1e-3


def test_a_failed_run_leaves_the_std_and_says_so():
    h, x, s, A, y, rng = _setup()
    J = A * (1 + 0.03 * rng.standard_normal(A.shape))
    res = _fit_result(h, x, J, y, A)
    out = force_scale_secant(LinearModel(h, A, y, failed=True), h, res, [0])
    assert out.std == res.std
    assert out.extra["force_scale"]["corrected"] is False
    assert "failed" in out.extra["force_scale"]["reason"]


def test_a_failed_run_found_in_the_cache_counts_as_failed():
    # loaded from a checkpoint, a failed run is a cached None: n_failed_ does not see it
    class Rec:
        name, tau = "a.csv", None

    m = FeatureModel([Rec()], workers=1, cache={("a.csv", (("mu_k", 0.2),)): None})
    assert m.any_failed([({"mu_k": 0.2}, {})], [0]) and m.n_failed_ == 0 and m.n_runs_ == 0


class Flat:
    """A model whose residual does not move (only the guards are under test)."""

    def residuals(self, points, which):
        return np.zeros((len(points), 10))

    def any_failed(self, points, which):
        return False


def test_a_drive_scaled_past_the_rigid_limit_is_not_corrected():
    h = Hypothesis(START, CANDIDATES["drive_compliance"])
    x = np.r_[np.zeros(5), 1.02 * RIGID_COMPLIANCE]          # 5 % less compliance is rigid
    J = np.ones((10, 6))
    res = _fit_result(h, x, J, np.zeros(10), np.zeros((10, 6)))
    out = force_scale_secant(Flat(), h, res, [0])
    assert out.extra["force_scale"]["corrected"] is False and out.std == res.std
    assert "another model" in out.extra["force_scale"]["reason"]
    x[-1] = 1.2 * RIGID_COMPLIANCE                             # +-5 % stays compliant
    res = _fit_result(h, x, J, np.zeros(10), np.zeros((10, 6)))
    assert force_scale_secant(Flat(), h, res, [0]).extra["force_scale"]["corrected"]


def test_a_missed_recording_is_run_along_the_scale_within_the_std_of_mu_k():
    # the linear model: at every step the residual is y - A (x + a sigma s), its RMS known
    h, x, s, A, y, rng = _setup()
    res = _fit_result(h, x, A, y, A)
    sigma = res.std["mu_k"] / res.values["mu_k"]
    out = heldout_along_force_scale(LinearModel(h, A, y), h, res, [3])
    assert out["sigma"] == pytest.approx(sigma) and out["points"] == list(HELDOUT_SCALE_POINTS)
    assert out["factors"] == pytest.approx([math.exp(a * sigma) for a in HELDOUT_SCALE_POINTS])
    want = [math.sqrt(np.mean((y - A @ (x + a * sigma * s)) ** 2)) for a in HELDOUT_SCALE_POINTS]
    assert list(out["rmse"]) == [3] and out["rmse"][3] == pytest.approx(want, rel=1e-9)
    # the steps move every force by the factor, the torque-like lift with them
    v0 = h.values(x)
    v1 = h.values(x + sigma * s)
    assert v1["mu_k"] / v0["mu_k"] == pytest.approx(out["factors"][-1])
    assert v1["k_c"] / v0["k_c"] == pytest.approx(out["factors"][-1])


def test_a_failed_run_along_the_scale_is_none_and_an_unknown_std_scans_nothing():
    h, x, s, A, y, rng = _setup()
    res = _fit_result(h, x, A, y, A)
    out = heldout_along_force_scale(LinearModel(h, A, y, failed=True), h, res, [0, 1])
    assert out["rmse"] == {0: [None] * len(HELDOUT_SCALE_POINTS), 1: [None] * len(HELDOUT_SCALE_POINTS)}
    res.std["mu_k"] = math.nan
    assert heldout_along_force_scale(LinearModel(h, A, y), h, res, [0]) is None


def test_steps_past_the_rigid_drive_are_skipped_along_the_held_out_scan():
    h = Hypothesis(START, CANDIDATES["drive_compliance"])
    x = np.r_[np.zeros(5), 1.02 * RIGID_COMPLIANCE]
    J = np.ones((10, 6))
    res = _fit_result(h, x, J, np.zeros(10), np.zeros((10, 6)))
    res.std["mu_k"] = 0.1 * res.values["mu_k"]          # -10 %: 2 % less compliance is rigid
    out = heldout_along_force_scale(Flat(), h, res, [0])
    # only the steps that scale the compliance down past the rigid limit are skipped (a linear
    # coordinate: d c / d log(lam) = -c)
    a = np.asarray(HELDOUT_SCALE_POINTS)
    assert [r is None for r in out["rmse"][0]] == list(1.02 * (1.0 - a * 0.1) < 1.0)
    assert any(r is None for r in out["rmse"][0]) and any(r == 0.0 for r in out["rmse"][0])


class Rippled(LinearModel):
    """A model blind to the force scale but for a ripple along it (the impact bumps): valleys
    a period ``P`` apart in log scale, the deepest at ``t = 0`` (``t``: the mean of the base's log
    coordinates), and a transverse part ``A u`` that the fit determines well."""

    P, RIPPLE, PULL = 0.6, 1.0, 0.05

    def residuals(self, points, which):
        out = []
        for pt in points:
            x = self._x(pt)
            t = float(np.mean(x[:5]))
            u = x - t * np.r_[1.0, 1.0, 1.0, 1.0, 1.0, 0.0]
            out.append(np.r_[self.y - self.A @ u, self.RIPPLE * (1 - math.cos(2 * math.pi * t / self.P)),
                             self.PULL * t])
        return np.array(out)


def _rippled(t0, seed=0):
    """The rippled model and a fit of it started ``t0`` along the scale (load_lift's hypothesis)."""
    rng = np.random.default_rng(seed)
    h = Hypothesis(START, CANDIDATES["load_lift"])
    A = rng.standard_normal((40, 6))
    model = Rippled(h, A, np.zeros(40))
    res = fit_hypothesis(model, h, [0], x0=np.r_[np.full(5, t0), 0.01], max_jac=8, tol=1e-8)
    return h, model, res


def test_a_fit_stopped_in_a_ripple_of_the_scale_is_taken_to_the_deepest_valley():
    h, model, res = _rippled(0.6)
    t = float(np.mean(res.x[:5]))
    assert t == pytest.approx(0.6, abs=0.05)        # the fit stayed in the valley it started in
    best, rec = profile_along_force_scale(model, h, res, [0], factors=(0.55, 1.3), max_jac=8)
    assert rec["chosen"] == 0.55 and best is not res
    assert abs(float(np.mean(best.x[:5]))) < 0.02 and best.rss_fit < 0.01 * res.rss_fit
    assert rec["factors"] == [0.55, 1.3] and rec["rmse_before"] == res.rmse_fit
    assert rec["rmse_fit"][0] == best.rmse_fit and rec["rmse_fit"][1] > best.rmse_fit
    # every force moved together, by the start's factor and what the fit added (t: -0.6)
    assert best.values["mu_k"] / res.values["mu_k"] == pytest.approx(math.exp(-t), rel=0.05)
    assert best.extra["scale_factor"] == 0.55
    assert best.extra["njac"] > res.extra["njac"]       # its own Jacobians counted with the fit's


def test_a_fit_in_the_deepest_valley_is_kept_and_bad_factors_are_refused():
    h, model, res = _rippled(0.02)
    best, rec = profile_along_force_scale(model, h, res, [0], factors=(0.55, 1.82), max_jac=8)
    assert best is res and rec["chosen"] is None
    assert all(r > res.rmse_fit for r in rec["rmse_fit"])
    for bad in ((0.0,), (-1.0,), (math.nan,)):
        with pytest.raises(ValueError, match="factors"):
            profile_along_force_scale(model, h, res, [0], factors=bad)


def test_a_start_past_the_rigid_drive_is_skipped_in_the_profile():
    h = Hypothesis(START, CANDIDATES["drive_compliance"])
    x = np.r_[np.zeros(5), 1.1 * RIGID_COMPLIANCE]
    res = _fit_result(h, x, np.ones((10, 6)), np.zeros(10), np.zeros((10, 6)))
    res.extra["njac"] = 1
    # x0.8 of every force is 1.25x the compliance (kept); x1.25 is 0.8x, past the rigid limit
    best, rec = profile_along_force_scale(Flat(), h, res, [0], factors=(0.8, 1.25), max_jac=1)
    assert rec["rmse_fit"][1] is None and rec["rmse_fit"][0] == 0.0
    assert best is res      # (the flat model fits no better anywhere)


def test_the_diagnosis_takes_the_profile_only_where_it_fits_clearly_better(monkeypatch):
    import szdyn.diagnose.diagnosis as dg
    import szdyn.diagnose.refine as refine
    from types import SimpleNamespace
    from szdyn.diagnose.report import _scale_profile_md, _status

    monkeypatch.setattr(refine, "SCALE_PROFILE_FACTORS", (0.55, 1.3))
    h, model, res = _rippled(0.6)
    res.extra["fit_phases"] = {0: 0.25}
    assert dg.Diagnosis().scale_profile is False      # (off by default)
    d = dg.Diagnosis(scale_profile=True)
    out = d._scale_profile(model, res, [0])
    p = d.scale_profile_
    assert out is not res and p["chosen"] == 0.55 and out.extra["fit_phases"] == {0: 0.25}
    assert p["candidate"] == "load_lift" and p["units"] == {"tau_lift": "N*m"}
    assert p["before"]["rmse_fit"] == res.rmse_fit and p["after"]["rmse_fit"] == out.rmse_fit
    assert p["after"]["force"] == pytest.approx(out.values["mu_k"] / res.values["mu_k"])
    assert "every force x0.55 (force-scale profile)" in _status(out)
    text = " ".join(_scale_profile_md(SimpleNamespace(scale_profile_=p)))
    assert "The start at x0.55 fitted clearly better and was taken" in text
    # off: nothing tried
    d = dg.Diagnosis(scale_profile=False)
    assert d._scale_profile(model, res, [0]) is res and getattr(d, "scale_profile_", None) is None
    # a better fit within the information criterion's margin is not taken
    d = dg.Diagnosis(scale_profile=True)
    d.rule = SimpleNamespace(indistinguishable=lambda **kw: True)
    assert d._scale_profile(model, res, [0]) is res
    assert d.scale_profile_["chosen"] is None and d.scale_profile_["after"] == d.scale_profile_["before"]
    text = " ".join(_scale_profile_md(SimpleNamespace(scale_profile_=d.scale_profile_)))
    assert "None fitted clearly better" in text
