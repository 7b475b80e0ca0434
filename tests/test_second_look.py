"""The second look (Diagnosis.fit, ``second_look``): a pass that would answer "unexplained" with
its calibrated base within the phase gate runs again with phase-profiled steps, and that pass is
the answer.

Null 32 (out of sample) said "unexplained" with its calibration at 3.2x the floor while the truth,
with its own wheel phases, fits at 0.9x; with two phase-profiled steps the base reached 1.0x and
the answer was "none" (docs/DIAGNOSIS-DESIGN.md). A pass whose calibration stopped beyond the
gate but whose ablation's base fits within it gets the same second look, calibrated from that base
(null 41). The pass logic is tested here with a stand-in for the pass itself (a real pass costs
minutes); the report paragraph with it.
"""
from types import SimpleNamespace

import numpy as np
import pytest

from szdyn.diagnose.diagnosis import SECOND_LOOK_STEPS, Diagnosis
from szdyn.diagnose.report import _second_look_md
from szdyn.run import main as run_main


class Passes(Diagnosis):
    """A Diagnosis whose passes are scripted: each call of ``_fit_pass`` takes the next outcome
    (verdict, calibrated RMSE over the floor, whether the wheel phases were estimated) and records
    the phase-profiled steps it was run with and whether it was weighted."""

    def __init__(self, outcomes, **kw):
        super().__init__(**kw)
        self.outcomes = list(outcomes)
        self.steps_seen, self.weighted_seen, self.starts_seen = [], [], []

    def _fit_pass(self, recs, weighted=False):
        # an optional fourth item, the ablation: (its fit over the floor, adopted), the
        # calibration before it having been at 4.3x; an adopted ablation becomes the pass's
        # calibrated base, as in Diagnosis._fit_pass
        verdict, ratio, estimated, *ablation = self.outcomes.pop(0)
        self.steps_seen.append(self._steps)
        self.weighted_seen.append(weighted)
        self.starts_seen.append(None if self._base_start is None else list(self._base_start))
        self.verdict_, self.selected_ = verdict, (["encoder_delay"] if verdict == "selected" else [])
        self.floor_, self.floor_spread_, self.weighted_ = 0.01, 1.5, weighted
        self.calibrated_ = SimpleNamespace(rmse_fit=0.01 * ratio, x=np.array([len(self.steps_seen), 7.0]))
        self.phase_ = {"estimated": estimated}
        self.ablation_ = None
        if ablation:
            (ab_ratio, adopted), = ablation
            self.ablation_ = {"candidate": "encoder_scale", "rmse_fit": 0.01 * ab_ratio,
                              "calibrated_rmse_fit": 0.043, "adopted": adopted}
        self.heldout_beyond_floor_ = {}
        self.timings_ = {"refit": 100.0}
        self.n_runs_, self.n_failed_, self.recordings_ = 500, 1, recs


def test_unexplained_within_the_phase_gate_is_looked_at_again_with_steps():
    d = Passes([("unexplained", 2.4, True), ("none", 1.0, True)]).fit([])
    assert d.steps_seen == [0, SECOND_LOOK_STEPS] == [0, 2]
    assert d.verdict_ == "none" and d.selected_ == []                 # the second look is the answer
    assert d.second_look_ == {"weighted": False, "verdict": "unexplained", "selected": [],
                              "calibrated_fit_over_floor": pytest.approx(2.4), "seconds": 100.0,
                              "model_runs": 500, "failed_runs": 1, "steps": 2, "start": "calibration"}
    assert d.timings_ == {"before_second_look": 100.0, "refit": 100.0}
    assert (d.n_runs_, d.n_failed_) == (1000, 2)
    assert d._steps == 0                                                # the next fit starts without
    assert d.starts_seen == [None, None]                                # from the calibration's own start
    md = "\n".join(_second_look_md(d))
    assert md.startswith("**Second look.** A first pass said unexplained: its calibrated base was 2.40x the floor (its wheel phases estimated")
    assert "2 phase-profiled step(s)" in md and "First pass: 100 s, 500 model runs." in md
    # whatever the second look says is the answer: here it names an effect
    d = Passes([("unexplained", 1.6, True), ("selected", 1.1, True)], second_look=3).fit([])
    assert d.steps_seen == [0, 3] and d.verdict_ == "selected" and d.selected_ == ["encoder_delay"]
    assert d.second_look_["steps"] == 3


@pytest.mark.parametrize("outcome, kw", [
    (("none", 1.1, True), {}),                          # nothing missing
    (("selected", 1.1, True), {}),                      # an effect named
    (("unexplained", 74.0, False), {}),                 # beyond the gate: phases not estimated
    (("unexplained", 4.3, False, (3.5, True)), {}),     # ... and the ablation's base beyond it too
    (("unexplained", 4.3, False, (1.9, False)), {}),    # ... or not adopted (it fitted worse)
    (("unexplained", 4.3, False, (1.9, True)), {"fit_phase": False}),   # no phases at all
    (("unexplained", 2.4, True), {"second_look": 0}),   # switched off
])
def test_no_second_look_unless_unexplained_within_the_gate(outcome, kw):
    d = Passes([outcome, ("none", 1.0, True)], **kw).fit([])
    assert d.steps_seen == [0] and d.second_look_ is None and d.verdict_ == outcome[0]
    assert _second_look_md(d) == []


def test_no_second_look_when_every_pass_already_takes_steps():
    d = Passes([("unexplained", 2.4, True), ("none", 1.0, True)], phase_steps=1).fit([])
    assert d.steps_seen == [1] and d.second_look_ is None and d.verdict_ == "unexplained"


def test_the_second_look_repeats_the_answering_pass_weighted_as_it_was():
    # weighting always: the pass that said "unexplained" was weighted, and so is its second look
    d = Passes([("unexplained", 2.4, True), ("unexplained", 1.9, True)], weighting="always").fit([])
    assert d.weighted_seen == [True, True] and d.steps_seen == [0, 2]
    assert d.verdict_ == "unexplained" and d.second_look_["weighted"]


@pytest.mark.parametrize("bad", [-1, 1.5, True, "2"])
def test_a_bad_second_look_is_refused(bad):
    with pytest.raises(ValueError, match="second_look must be an integer >= 0"):
        Diagnosis(second_look=bad)


def test_a_negative_second_look_is_a_clear_command_line_error(tmp_path, capsys):
    # refused before the manifest is read: no work is lost
    rc = run_main(["diagnose", str(tmp_path / "missing.toml"), "--out", str(tmp_path / "o"), "--second-look", "-1"])
    assert rc != 0
    err = capsys.readouterr().err
    assert "--second-look must be >= 0, got -1" in err and "Traceback" not in err
    assert not (tmp_path / "o").exists()


def test_unexplained_beyond_the_gate_is_looked_at_again_from_an_ablation_within_it():
    # null 41: the calibration stopped at 4.30x the floor (beyond the gate, so no phases), and the
    # base model alone refitted from encoder_scale's coefficients reached 1.88x
    d = Passes([("unexplained", 1.88, False, (1.88, True)), ("none", 1.0, True)]).fit([])
    assert d.steps_seen == [0, 2] and d.verdict_ == "none"
    assert d.starts_seen == [None, [1.0, 7.0]]          # calibrated from the first pass's base
    f = d.second_look_
    assert f["start"] == "ablation" and f["verdict"] == "unexplained" and f["steps"] == 2
    assert f["ablation"] == {"candidate": "encoder_scale", "fit_over_floor": pytest.approx(1.88),
                             "calibrated_fit_over_floor": pytest.approx(4.3)}
    md = "\n".join(_second_look_md(d))
    assert md.startswith("**Second look.** A first pass said unexplained: its calibration stopped at 4.30x the "
                         "floor, beyond the phase gate, but the base model alone, refitted from `encoder_scale`'s "
                         "coefficients (the ablation), fitted at 1.88x, within it.")
    assert "2 phase-profiled step(s)" in md and "First pass: 100 s, 500 model runs." in md
    # exactly at the gate counts as within it; the second look's answer stands whatever it is
    d = Passes([("unexplained", 3.0, False, (3.0, True)), ("unexplained", 2.5, True)]).fit([])
    assert d.steps_seen == [0, 2] and d.verdict_ == "unexplained" and d.second_look_["start"] == "ablation"
