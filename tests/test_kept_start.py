"""Between fits of one candidate that the fit cannot part, the held-out recordings decide
(SelectionRule.heldout_decides, Diagnosis._keeps_earlier).

The numbers are friction_asymmetry seed 49's (out of sample): the first start fitted at 1.34
noise floors and held out at 0.0093 rad/s, the second start fitted at 1.11 floors and held out at
0.119 rad/s (0.143 before the refit), the effect parameter exact in both.
"""
import math
from types import SimpleNamespace

import pytest

from szdyn.diagnose.diagnosis import Diagnosis
from szdyn.diagnose.report import _status
from szdyn.diagnose.selection import SelectionRule

FLOOR = 0.008285                         # rad/s
FIRST = {"fit": 0.0111, "held": 0.009261}
SECOND = {"fit": 0.009162, "held": 0.1189}


def _kept(rule, earlier, later, floor=FLOOR):
    return rule.heldout_decides(fit_chosen=earlier["fit"], heldout_chosen=earlier["held"],
                                fit_other=later["fit"], heldout_other=later["held"], floor=floor)


def test_the_earlier_fit_is_kept_only_where_the_fit_cannot_part_them_and_the_held_out_can():
    rule = SelectionRule()
    assert _kept(rule, FIRST, SECOND)
    # the later one holding out less than rival_heldout (2) times worse: it replaces the earlier
    assert not _kept(rule, FIRST, {**SECOND, "held": 1.9 * FIRST["held"]})
    assert _kept(rule, FIRST, {**SECOND, "held": rule.rival_heldout * FIRST["held"]})
    # either fit beyond rival_floor (2) noise floors: the fit parts them, the better fit stays
    lim = rule.rival_floor * FLOOR
    assert _kept(rule, {**FIRST, "fit": lim}, SECOND)
    assert not _kept(rule, {**FIRST, "fit": lim * (1 + 1e-9)}, SECOND)
    assert not _kept(rule, FIRST, {**SECOND, "fit": lim * (1 + 1e-9)})
    # no held-out recordings (NaN): nothing to decide with
    assert not _kept(rule, {**FIRST, "held": math.nan}, SECOND)
    assert not _kept(rule, FIRST, {**SECOND, "held": math.nan})
    # the thresholds are the rule's
    assert not _kept(SelectionRule(rival_heldout=20.0), FIRST, SECOND)
    assert not _kept(SelectionRule(rival_floor=1.2), FIRST, SECOND)


def _fit(fit, njac=3):
    return SimpleNamespace(rmse_fit=fit, extra={"njac": njac}, budget_hit=False)


def test_a_diagnosis_keeps_the_first_start_and_says_why():
    d = Diagnosis()
    d.floor_ = FLOOR
    first = _fit(FIRST["fit"])
    d.refits_ = {"friction_asymmetry": {"result": first, "heldout_rmse": FIRST["held"]}}
    assert d._keeps_earlier("friction_asymmetry", _fit(SECOND["fit"]), SECOND["held"], "the second start")
    assert d.refits_["friction_asymmetry"]["result"] is first
    assert first.extra["kept_over"] == [{"fit": "the second start", "rmse_fit": SECOND["fit"],
                                         "heldout_rmse": SECOND["held"]}]
    assert ("kept over later fits that fitted better but held out worse (by the close rivals' test), "
            "the held-out recordings choosing: the second start (fit 0.009162, held-out 0.1189 rad/s)") in _status(first)
    # a later fit that also holds out well replaces it (the caller assesses it): not kept, no record
    assert not d._keeps_earlier("friction_asymmetry", _fit(SECOND["fit"]), 0.01, "its continued fit")
    assert len(first.extra["kept_over"]) == 1
    # each later fit kept over is listed
    assert d._keeps_earlier("friction_asymmetry", _fit(0.01021), 0.1154, "its continued fit")
    assert _status(first).endswith("the second start (fit 0.009162, held-out 0.1189 rad/s), "
                                   "its continued fit (fit 0.01021, held-out 0.1154 rad/s)")
    # a candidate without an earlier fit: nothing to keep
    assert not d._keeps_earlier("load_lift", _fit(SECOND["fit"]), SECOND["held"], "the second start")


def test_the_status_line_without_a_kept_over_fit_is_unchanged():
    assert "kept over" not in _status(_fit(FIRST["fit"]))
    assert _status(_fit(FIRST["fit"])) == "converged after 3 Jacobians"


@pytest.mark.parametrize("later", ["the second start", "the third start", "the fourth start",
                                   "its restart from the linear step", "its phase-profiled steps",
                                   "its continued fit"])
def test_every_later_fit_is_named_in_the_log(later):
    lines = []
    d = Diagnosis(log=lines.append)
    d.floor_ = FLOOR
    d.refits_ = {"c": {"result": _fit(FIRST["fit"]), "heldout_rmse": FIRST["held"]}}
    assert d._keeps_earlier("c", _fit(SECOND["fit"]), SECOND["held"], later)
    assert any(f"kept the earlier fit over {later}" in s for s in lines)
