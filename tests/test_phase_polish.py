"""The named effect's phase-profiled polish (Diagnosis._polish), on the stand-in of
tests/test_phase_step.py whose bumps move with a drive compliance times a varying torque.

The situation of drive_compliance seed 48: the compliance was named, but fitted at the wheel
phases estimated at the rigid base, which take in part of its shift, so the value ends short of
the truth (the drive too stiff). With each trial point's own phases it reaches the truth.
"""
import dataclasses
import math
from types import SimpleNamespace

import pytest

from szdyn.diagnose.diagnosis import POLISH_PHASE_STEPS, Diagnosis
from szdyn.diagnose.phase import estimate_phases
from szdyn.diagnose.report import _polish_md, _status
from szdyn.run import main as run_main

from test_phase_step import C_TRUE, WindUp, _rigid_refit

C_NAMED = 0.2       # rad/(N m): the named value, fitted at the base's phases (truth C_TRUE = 0.35)


def _named(model, cand="drive_compliance", value=C_NAMED, extra=None):
    """A named refit as the diagnosis leaves it: the phases estimated at the rigid calibration,
    the effect at ``value``, and a Jacobian that sees the effect's column flat."""
    return _rigid_refit(model, cand, value=value, extra=extra)


def test_the_polish_takes_a_named_compliance_to_the_truth():
    model = WindUp()
    h, res = _named(model)
    assert res.values["drive_compliance"] == pytest.approx(C_NAMED)
    held = dict(model.phases)
    d = Diagnosis()
    assert d.phase_polish == POLISH_PHASE_STEPS > 0
    out = d._polish(model, res, [0, 1])
    assert out is not res and out.hypothesis is h
    assert out.values["drive_compliance"] == pytest.approx(C_TRUE, rel=0.1)
    assert out.rmse_fit < 0.5 * res.rmse_fit
    assert model.phases == held         # the caller decides whose phases the model holds
    p = d.polish_
    assert p["candidate"] == "drive_compliance" and 1 <= p["steps"] <= POLISH_PHASE_STEPS
    assert out.extra["phase_steps"] == p["steps"] and set(out.extra["fit_phases"]) == {0, 1}
    # the candidates table's status line names the option its steps came from
    assert f"{p['steps']} phase-profiled step(s) (--phase-polish)" in _status(out)
    assert "(--phase-steps)" not in _status(out) and "phase_flag" not in res.extra
    assert p["before"] == {"values": {"drive_compliance": pytest.approx(C_NAMED)}, "rmse_fit": res.rmse_fit}
    assert p["after"]["values"]["drive_compliance"] == out.values["drive_compliance"]
    assert p["units"] == {"drive_compliance": "rad/(N*m)"}
    text = " ".join(_polish_md(SimpleNamespace(polish_=p)))
    assert "Polished with its own wheel phases" in text and "drive_compliance 0.2 -> " in text


def test_no_polish_off_without_a_ladder_or_after_steps_of_its_own():
    model = WindUp()
    _, res = _named(model)
    d = Diagnosis(phase_polish=0)
    assert d._polish(model, res, [0, 1]) is res
    assert getattr(d, "polish_", None) is None
    # a refit that already took phase-profiled steps (a second look) was fitted with its own phases
    _, stepped = _named(model, extra={"phase_steps": 1})
    d = Diagnosis()
    assert d._polish(model, stepped, [0, 1]) is stepped and getattr(d, "polish_", None) is None
    # an effect that does not move the wheel against the motor: no polish
    _, drag = _named(model, cand="slider_viscous", value=0.001)
    assert Diagnosis()._polish(model, drag, [0, 1]) is drag


def test_a_compliance_fitted_with_its_own_phases_stays():
    """At the truth, with the phases estimated there: no step fits clearly better, the values
    stand and the report says so."""
    model = WindUp()
    _, res = _named(model, value=C_TRUE)
    model.phases = {i: e.q_w0 for i, e in estimate_phases(model, res.hypothesis.point(res.x), [0, 1]).items()}
    r = model.residuals([res.hypothesis.point(res.x)], [0, 1])[0]
    res = dataclasses.replace(res, rss_fit=float(r @ r), rmse_fit=math.sqrt(r @ r / r.size))
    assert res.rmse_fit < 0.01
    d = Diagnosis()
    assert d._polish(model, res, [0, 1]) is res
    assert d.polish_["steps"] == 0 and d.polish_["after"] == d.polish_["before"]
    text = " ".join(_polish_md(d))
    assert "the values stand" in text and "->" not in text


@pytest.mark.parametrize("bad", [-1, 1.5, True, "2"])
def test_a_bad_phase_polish_is_refused(bad):
    with pytest.raises(ValueError, match="phase_polish must be an integer >= 0"):
        Diagnosis(phase_polish=bad)


def test_a_negative_phase_polish_is_a_clear_command_line_error(tmp_path, capsys):
    rc = run_main(["diagnose", str(tmp_path / "missing.toml"), "--out", str(tmp_path / "o"), "--phase-polish", "-1"])
    assert rc != 0
    err = capsys.readouterr().err
    assert "--phase-polish must be >= 0, got -1" in err and "Traceback" not in err
    assert not (tmp_path / "o").exists()
