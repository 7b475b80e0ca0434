"""The restart of a pass from the base its ablation found (Diagnosis._pass, ``restart``).

slider_stribeck seed 22 (out of sample): the calibration stopped at 0.697 rad/s, 74x the floor,
while the base model alone, refitted from a candidate's coefficients, reached 0.040; the
screening had been made at the stuck calibration and slider_stribeck was never refitted. The pass
logic is tested here with a stand-in for the pass itself (a real stuck calibration costs minutes);
the report paragraph with it. Off by default (``Diagnosis(restart=True)``, ``diagnose --restart``).
"""
from types import SimpleNamespace

import numpy as np
import pytest

from szdyn.diagnose.diagnosis import RESTART_RATIO, Diagnosis
from szdyn.diagnose.report import _restart_md


class Passes(Diagnosis):
    """A Diagnosis whose passes are scripted: each call of ``_fit_pass`` takes the next outcome
    (verdict, calibrated RMSE, ablation RMSE or None) and records where it started."""

    def __init__(self, outcomes, **kw):
        super().__init__(**kw)
        self.outcomes = list(outcomes)
        self.starts = []

    def _fit_pass(self, recs, weighted=False):
        verdict, cal_rmse, alt_rmse = self.outcomes.pop(0)
        self.starts.append(None if self._base_start is None else self._base_start.copy())
        x_cal = np.full(5, float(len(self.starts)))       # the pass's own calibration
        self.verdict_, self.selected_ = verdict, (["slider_stribeck"] if verdict == "selected" else [])
        self.weighted_, self.floor_ = weighted, 0.01
        self.ablation_ = None if alt_rmse is None else {
            "candidate": "encoder_scale", "rmse_fit": alt_rmse, "calibrated_rmse_fit": cal_rmse,
            "adopted": alt_rmse < cal_rmse}
        # after an adopted ablation, the calibration is the base it found (as in _fit_pass)
        rmse = cal_rmse if alt_rmse is None else min(cal_rmse, alt_rmse)
        self.calibrated_ = SimpleNamespace(x=x_cal + 10.0 if alt_rmse is not None else x_cal, rmse_fit=rmse)
        self.timings_ = {"refit": 100.0}
        self.n_runs_, self.n_failed_ = 1000, 0


def run(outcomes, **kw):
    d = Passes(outcomes, **{"restart": True, **kw})
    d._pass([], weighted=False)
    return d


def test_a_pass_stuck_in_a_base_valley_runs_again_from_the_ablations_base():
    d = run([("unexplained", 0.697, 0.0404), ("selected", 0.04, None)])
    assert d.starts[0] is None
    np.testing.assert_array_equal(d.starts[1], np.full(5, 11.0))   # the first pass's ablation base
    assert d.verdict_ == "selected"                                # the second pass is the answer
    assert d.restart_["verdict"] == "unexplained"
    assert d.restart_["ablation"]["calibrated_rmse_fit"] == 0.697
    assert d.timings_["restart_first"] == 100.0 and d.n_runs_ == 2000
    md = "\n".join(_restart_md(d))
    assert "0.697 rad/s" in md and "`encoder_scale`" in md and "0.0404 rad/s" in md


@pytest.mark.parametrize("outcome, kw", [
    (("unexplained", 0.697, None), {}),                                  # no ablation
    (("unexplained", 0.697, 0.697 / RESTART_RATIO * 1.01), {}),          # not far enough
    (("selected", 0.697, 0.0404), {}),                                   # something was named
    (("unexplained", 0.697, 0.0404), {"restart": False}),                # switched off (the default)
    (("none", 0.011, 0.0109), {}),                                       # a small ablation (null 22)
])
def test_no_restart_without_a_far_better_base_or_when_named(outcome, kw):
    d = run([outcome, ("selected", 0.04, None)], **kw)
    assert len(d.starts) == 1 and d.restart_ is None
    assert _restart_md(d) == []


def test_every_later_pass_starts_from_the_better_base():
    # the restarted pass names nothing either: its answer stands, and a later pass (the split
    # exchanged, the weighting) calibrates from the same base
    d = run([("unexplained", 0.697, 0.0404), ("unexplained", 0.0404, None)])
    assert d.verdict_ == "unexplained" and d.restart_ is not None
    d.outcomes = [("none", 0.012, None)]
    d._pass([], weighted=True)
    np.testing.assert_array_equal(d.starts[2], np.full(5, 11.0))
    assert d.restart_ is None
