"""The amplitude search of a refit's fourth start (szdyn.diagnose.amplitude), on a stand-in model.

The stand-in's cost in ``tau_lift`` has the shape measured on out-of-sample load_lift seed 20 at
the uncalibrated coefficients: a slow descent, a valley about 0.01 N m wide, and a cliff just
beyond it (the band stalls). A gradient start beside the valley cannot see it.
"""
import numpy as np
import pytest

from szdyn.diagnose.amplitude import AMPLITUDE_GRID, REFINE_EVALS, amplitude_search
from szdyn.diagnose.diagnosis import Diagnosis
from szdyn.diagnose.candidates import CANDIDATES
from szdyn.diagnose.fit import Hypothesis, fit_hypothesis

START = {"k_c": 0.05, "b_c": 0.0075, "k_imp": 4e12, "mu_s": 0.3, "mu_k": 0.25}
CENTRE = 0.0893      # N m: not on the scan's grid (spacing 0.0375 N m over -0.3..0.3)


class CliffValley:
    """``residuals(points, which)`` like :class:`szdyn.diagnose.engine.FeatureModel`'s, with a
    cost that depends only on one model change; counts the points asked for."""

    def __init__(self, name="tau_lift", centre=CENTRE, width=0.004):
        self.name, self.centre, self.width = name, centre, width
        self.points = 0
        self.seen_base = set()

    def cost(self, v):
        r = min(abs(v - self.centre) / self.width, 5.0)
        return r + (50.0 if v > self.centre + 2.5 * self.width else 0.0)

    def residuals(self, points, which):
        self.points += len(points)
        out = []
        for mc, _ in points:
            self.seen_base.add(tuple(round(mc[k], 12) for k in ("k_c", "b_c", "k_imp", "mu_s", "mu_k")))
            out.append(np.full(10 * len(which), self.cost(mc.get(self.name, 0.0))))
        return np.array(out)


def _x(hyp, **values):
    x = hyp.x_start()
    for k, v in values.items():
        x[hyp.names.index(k)] = v
    return x


def test_finds_a_narrow_valley_beside_a_cliff_from_far_away():
    hyp = Hypothesis(START, CANDIDATES["load_lift"])
    model = CliffValley()
    x0 = _x(hyp, tau_lift=0.178)       # where load_lift seed 20's first refit ended
    x, rss, n = amplitude_search(model, hyp, x0, [0, 1])
    tau = hyp.candidate_values(x)["tau_lift"]
    assert abs(tau - CENTRE) < 0.002, tau          # xatol is probe / 10 = 0.002 N m
    np.testing.assert_array_equal(x[:hyp.n_base], x0[:hyp.n_base])   # base coefficients held
    assert model.seen_base == {tuple(round(START[k], 12) for k in ("k_c", "b_c", "k_imp", "mu_s", "mu_k"))}
    assert rss == pytest.approx(20 * model.cost(tau) ** 2)
    assert n == model.points
    assert AMPLITUDE_GRID + 1 < n <= AMPLITUDE_GRID + 1 + REFINE_EVALS   # start + scan + the Brent budget


def test_refinement_improves_on_the_scan():
    hyp = Hypothesis(START, CANDIDATES["load_lift"])
    x0 = _x(hyp, tau_lift=-0.2)
    _, rss_scan, n_scan = amplitude_search(CliffValley(), hyp, x0, [0], refine=0)
    _, rss, _ = amplitude_search(CliffValley(), hyp, x0, [0])
    assert n_scan == AMPLITUDE_GRID + 1
    assert rss < 0.1 * rss_scan


def test_keeps_the_start_when_nothing_fits_better():
    hyp = Hypothesis(START, CANDIDATES["load_lift"])
    x0 = _x(hyp, tau_lift=CENTRE)
    x, rss, _ = amplitude_search(CliffValley(), hyp, x0, [0])
    np.testing.assert_array_equal(x, hyp.inside(x0))
    assert rss == 0.0


def test_shape_parameters_and_the_base_model_are_left_alone():
    # slider_stribeck is the library's only candidate with a shape parameter; the diagnosis
    # never searches it (it has its own probes), but the search must leave v_st alone anyway
    hyp = Hypothesis(START, CANDIDATES["slider_stribeck"])
    model = CliffValley(name="mu_st", centre=0.4, width=0.02)
    x0 = _x(hyp, mu_st=1.2, v_st=0.7)
    x, _, _ = amplitude_search(model, hyp, x0, [0])
    v = hyp.candidate_values(x)
    assert v["v_st"] == pytest.approx(0.7)         # a shape parameter: not searched
    assert abs(v["mu_st"] - 0.4) < 0.01
    base = Hypothesis(START)
    xb, _, n = amplitude_search(CliffValley(), base, base.x_start(), [0])
    assert n == 1
    np.testing.assert_array_equal(xb, base.inside(base.x_start()))


def test_too_few_scan_points_is_an_error():
    hyp = Hypothesis(START, CANDIDATES["load_lift"])
    with pytest.raises(ValueError, match="n_grid"):
        amplitude_search(CliffValley(), hyp, hyp.x_start(), [0], n_grid=2)


def test_fourth_start_only_where_the_refits_leave_the_mismatch_unexplained():
    model = CliffValley()
    d = Diagnosis(candidates=["load_lift"])
    h = Hypothesis(START, CANDIDATES["load_lift"])
    x_far = _x(h, tau_lift=0.178)                  # beyond the cliff: a flat cost, no gradient
    best = fit_hypothesis(model, h, [0], x0=x_far, max_jac=2)
    assert best.rmse_fit > 50.0
    d.floor_ = 1.0                                 # the refit leaves 55 floors: searched
    res = d._amplitude_start(model, h, best, x_far, [0])
    assert res is not None and res.rmse_fit < 0.5
    assert abs(res.values["tau_lift"] - CENTRE) < 0.002
    d.floor_ = 20.0                                # within max_remaining (5) floors: not tried
    assert d._amplitude_start(model, h, best, x_far, [0]) is None
    d.floor_ = 1.0                                 # a candidate with its own probes: not tried
    hs = Hypothesis(START, CANDIDATES["slider_stribeck"])
    best_s = fit_hypothesis(CliffValley(name="mu_st", centre=0.4, width=0.02), hs, [0],
                            x0=_x(hs, mu_st=1.4), max_jac=1)
    assert best_s.rmse_fit > 5.0
    assert d._amplitude_start(model, hs, best_s, _x(hs, mu_st=1.4), [0]) is None
    # ... unless they are tried besides the bound-fraction probes (slider_viscous): searched
    hv = Hypothesis(START, CANDIDATES["slider_viscous"])
    valley = CliffValley(name="c_visc", centre=0.03, width=0.004)
    best_v = fit_hypothesis(valley, hv, [0], x0=_x(hv, c_visc=0.09), max_jac=1)
    assert best_v.rmse_fit > 5.0
    res_v = d._amplitude_start(valley, hv, best_v, _x(hv, c_visc=0.09), [0])
    assert res_v is not None and abs(res_v.values["c_visc"] - 0.03) < 0.004


class TwoValleys:
    """A cost in the band encoder's delay with a shallow valley where a refit stops and a deeper
    one a factor away (out-of-sample encoder_delay seed 53: the refit stopped at 3.3 ms, and a
    start at 1.5-2x ended near the truth's 5.5 ms); the base coefficients do not matter."""

    SHALLOW, DEEP = 0.010, 0.030    # s

    def cost(self, v):
        return (1.0 - 0.4 * np.exp(-((v - self.SHALLOW) / 0.004) ** 2)
                - 0.9 * np.exp(-((v - self.DEEP) / 0.008) ** 2))

    def residuals(self, points, which):
        out = []
        for _, sc in points:
            out.append(np.full(10 * len(which), self.cost(sc.get("encoder_delay_b", 0.0))))
        return np.array(out)


def test_fifth_start_reaches_the_deeper_valley_a_factor_away_from_the_calibrated_coefficients():
    from szdyn.diagnose.fit import FIT_TOL
    from szdyn.diagnose.starts import AMPLITUDE_MULTIPLES

    h = Hypothesis(START, CANDIDATES["encoder_delay"])
    model = TwoValleys()
    best = fit_hypothesis(model, h, [0], x0=_x(h, encoder_delay=TwoValleys.SHALLOW), max_jac=4)
    assert best.values["encoder_delay"] == pytest.approx(TwoValleys.SHALLOW, abs=1e-3)   # stopped there
    x_cal = np.log([1.1, 0.9, 1.2, 1.0, 0.95])     # calibrated coefficients, not the refit's
    best.x[:h.n_base] = -x_cal
    d = Diagnosis(candidates=["encoder_delay"], amplitude_starts=True)
    res, f = d._multiple_starts(model, h, best, x_cal, [0])
    assert res.values["encoder_delay"] == pytest.approx(TwoValleys.DEEP, abs=2e-3)
    assert res.rss_fit < 0.5 * best.rss_fit
    # the best of the starts, each from its multiple of the refit's delay
    ends = {g: fit_hypothesis(TwoValleys(), h, [0], x0=np.r_[x_cal, g * TwoValleys.SHALLOW], max_jac=d.max_jac,
                              tol=FIT_TOL).rss_fit for g in AMPLITUDE_MULTIPLES}
    assert f in AMPLITUDE_MULTIPLES and res.rss_fit == pytest.approx(min(ends.values()))
    # started at the calibrated coefficients: the stand-in's cost ignores them, so the fit
    # never moved them from its start
    np.testing.assert_allclose(res.x[:h.n_base], x_cal)


def test_fifth_start_needs_an_amplitude_to_multiply_and_a_better_end():
    h = Hypothesis(START, CANDIDATES["encoder_delay"])
    model = TwoValleys()
    d = Diagnosis(candidates=["encoder_delay"], amplitude_starts=True)
    off = fit_hypothesis(model, h, [0], x0=_x(h, encoder_delay=0.0), max_jac=1)
    off.x[h.n_base:] = 0.0
    assert d._multiple_starts(model, h, off, np.zeros(5), [0]) is None       # no multiple of "off"
    deep = fit_hypothesis(model, h, [0], x0=_x(h, encoder_delay=TwoValleys.DEEP), max_jac=4)
    assert d._multiple_starts(model, h, deep, np.zeros(5), [0]) is None      # nothing ends better
    assert Diagnosis().amplitude_starts is True                               # (on by default)


@pytest.mark.parametrize("on, explained, floors, wanted", [
    (True, 0.39, 1.35, True),       # encoder_delay seed 53's refit
    (False, 0.39, 1.35, False),     # off
    (True, 0.0, 1.35, False),       # explains nothing: no effect to move
    (True, -0.2, 1.35, False),
    (True, 0.5, 1.35, False),       # explains enough: judged as it is
    (True, 0.39, 1.2, False),       # within the mismatch threshold (1.3 floors)
])
def test_fifth_start_only_for_a_refit_that_explains_part_of_a_remaining_mismatch(on, explained, floors, wanted):
    from types import SimpleNamespace

    d = Diagnosis(amplitude_starts=on)
    d.floor_ = 0.0073
    refit = {"explained": explained, "result": SimpleNamespace(rmse_fit=floors * d.floor_)}
    assert d._wants_fifth_start(refit) is wanted


@pytest.mark.parametrize("on", [True, False])
def test_the_report_says_whether_refits_get_the_fifth_start(on):
    """The report's account of the refits names the fifth start exactly when it was on."""
    from types import SimpleNamespace

    from szdyn.diagnose.report import _refits_md
    from szdyn.diagnose.selection import SelectionRule

    text = _refits_md(SimpleNamespace(shortlist=2, rivals=2, rule=SelectionRule(), amplitude_starts=on))
    assert text.startswith("Screened linearly") and text.endswith("the floor).")
    assert ("a fifth from the calibrated coefficients with the effect's amplitude at x0.5 and x2" in text) is on
    assert ("less than 50%" in text) is on
