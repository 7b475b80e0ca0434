"""bench/diagnosis_cost.py's scoring of the one-load cost configuration (no diagnosis is run)."""
import pytest

from cases import load_bench


def _bench():
    return load_bench("diagnosis_cost")


def _case(effect, selected, **kw):
    return {"effect": effect, "seed": 39, "seconds": 500.0, "selected": selected,
            "verdict": "selected" if selected else "none", "heldout_before": 0.08,
            "heldout_after": 0.008, "model_runs": 700, **kw}


def test_score_names_errors_and_gains():
    mod = _bench()
    r = mod.score(_case("slider_viscous", ["slider_viscous"], truth_param=0.004, fitted_param=0.0042,
                        noise_floor=0.004))
    assert r["correct"] and r["param_error"] == pytest.approx(0.05)
    assert r["heldout_ratio"] == pytest.approx(10.0) and r["heldout_over_floor"] == pytest.approx(20.0)
    # a wrong name: no parameter error; the floor taken from the diagnosis when the result lacks it
    r = mod.score(_case("slider_viscous", ["encoder_scale"], truth_param=0.004, fitted_param=None), 0.008)
    assert not r["correct"] and "param_error" not in r and r["heldout_over_floor"] == pytest.approx(10.0)
    # encoder_scale: the error of the scale error, not of the gain
    r = mod.score(_case("encoder_scale", ["encoder_scale"], truth_param=1.02, fitted_param=1.021))
    assert r["param_error"] == pytest.approx(0.05)
    assert "heldout_over_floor" not in r
    # a null case is right when nothing is named, whatever the verdict
    assert mod.score(_case("none", [], verdict="unexplained"))["correct"]
    assert not mod.score(_case("none", ["load_lift"]))["correct"]


def test_summary_counts_and_marks_wrong_answers():
    mod = _bench()
    rows = [mod.score(_case("none", [])),
            mod.score(_case("slider_viscous", ["encoder_scale"])),
            mod.score(_case("load_lift", ["load_lift"], truth_param=0.04, fitted_param=0.038))]
    md = mod.summary_md(rows, 39)
    assert "Named: 1/2; null cases with no effect named: 1/1." in md
    assert "| slider_viscous | - | **`encoder_scale`** |" in md
    assert "| load_lift | - | `load_lift` | 5.0 % |" in md


def test_unknown_effect_is_refused(capsys):
    mod = _bench()
    with pytest.raises(SystemExit):
        mod.main(["--work", "x", "--effect", "slider_viscus,none"])
    assert "unknown effect(s) slider_viscus" in capsys.readouterr().err


def test_summary_header_names_the_effects_run_and_the_options():
    """The header says which effects ran (in their order) and with which diagnose options;
    "every effect" only when none and all of them ran."""
    mod = _bench()
    two = [mod.score(_case("slider_viscous", ["slider_viscous"])), mod.score(_case("none", []))]
    md = mod.summary_md(two, 41)
    assert md.startswith("# The issue's cost configuration, slider_viscous, none (seed 41)\n")
    assert "`python bench/diagnosis_cost.py --work DIR --seed 41 --effect slider_viscous,none`" in md
    assert "the CLI defaults" in md
    steps = [mod.score(_case("load_lift", ["load_lift"], diagnose_args="--phase-steps 2"))]
    md = mod.summary_md(steps, 31)
    assert "--effect load_lift --diagnose-args '--phase-steps 2'`" in md and "the CLI defaults" not in md
    every = [mod.score(_case(e, [e] if e != "none" else [])) for e in ["none", *mod.EFFECTS]]
    assert mod.summary_md(every, 40).startswith("# The issue's cost configuration, every effect (seed 40)")


def test_a_finished_case_run_with_other_options_is_refused(tmp_path):
    """Resuming with other --diagnose-args would mix two settings in one summary: refused, naming
    the case's file and both option strings; nothing is run and nothing is overwritten."""
    import json

    mod = _bench()
    for eff in ("none", "load_lift"):
        (tmp_path / eff).mkdir()
        (tmp_path / eff / "cost.json").write_text(json.dumps(
            _case(eff, [], noise_floor=0.005, diagnose_args="--phase-steps 2")))
    with pytest.raises(SystemExit) as exc:
        mod.main(["--work", str(tmp_path), "--effect", "none,load_lift"])
    msg = str(exc.value)
    assert str(tmp_path / "none" / "cost.json") in msg and "'--phase-steps 2'" in msg and "not ''" in msg
    assert not (tmp_path / "cost-summary.md").exists()
    assert mod.main(["--work", str(tmp_path), "--effect", "none,load_lift",
                     "--diagnose-args", "--phase-steps 2"]) == 0
    assert "--diagnose-args '--phase-steps 2'" in (tmp_path / "cost-summary.md").read_text()


def test_amplitude_factor_sets_the_top_of_the_range_times_f():
    """``--amplitude-factor F``: F times the top of the effect's realistic range, a seeded sign
    only for the signed effects, the same on every call; the summary says the factor and shows
    each case's amplitude."""
    mod = _bench()
    for eff, e in mod.EFFECTS.items():
        a = mod.amplitude_at(eff, 1.5, 92)
        assert abs(a) == pytest.approx(1.5 * e.range[1])
        assert a > 0 or e.signed
        assert mod.amplitude_at(eff, 1.5, 92) == a
    signs = {mod.amplitude_at("friction_asymmetry", 1.0, s) > 0 for s in range(20)}
    assert signs == {True, False}
    rows = [mod.score(_case("load_lift", ["load_lift"], amplitude=2.25, amplitude_factor=1.5))]
    md = mod.summary_md(rows, 92)
    assert md.startswith("# The issue's cost configuration, load_lift (seed 92, amplitudes at 1.5x "
                         "the top of the range)")
    assert "--effect load_lift --amplitude-factor 1.5`" in md and "| load_lift | 2.25 |" in md


def test_a_bad_factor_or_a_case_run_at_another_factor_is_refused(tmp_path, capsys):
    import json

    mod = _bench()
    with pytest.raises(SystemExit):
        mod.main(["--work", str(tmp_path), "--effect", "none", "--amplitude-factor", "0"])
    assert "--amplitude-factor must be a finite number > 0, got 0" in capsys.readouterr().err
    for eff in ("none", "load_lift"):
        (tmp_path / eff).mkdir()
        (tmp_path / eff / "cost.json").write_text(json.dumps(
            _case(eff, [], noise_floor=0.005, amplitude_factor=1.5)))
    with pytest.raises(SystemExit) as exc:
        mod.main(["--work", str(tmp_path), "--effect", "none,load_lift"])
    assert str(tmp_path / "none" / "cost.json") in str(exc.value) and "1.5" in str(exc.value)
    assert not (tmp_path / "cost-summary.md").exists()
    assert mod.main(["--work", str(tmp_path), "--effect", "none,load_lift",
                     "--amplitude-factor", "1.5"]) == 0


def test_recordings_made_for_another_case_are_refused(tmp_path):
    """A work directory whose recordings were made for another amplitude (or effect, or seed) is
    refused before anything runs, naming its truth.json; nothing is overwritten."""
    import json

    mod = _bench()
    data = tmp_path / "data"
    data.mkdir()
    truth = {"effect": "load_lift", "seed": 92, "amplitude": 0.7, "amplitude_drawn": True}
    (data / "truth.json").write_text(json.dumps(truth))
    with pytest.raises(SystemExit) as exc:
        mod.run_case(tmp_path, "load_lift", 92, "", amplitude_factor=1.5)
    assert str(data / "truth.json") in str(exc.value) and "amplitude 2.25" in str(exc.value)
    for eff, seed in (("slider_viscous", 92), ("load_lift", 93)):
        with pytest.raises(SystemExit):
            mod.run_case(tmp_path, eff, seed, "")
    assert json.loads((data / "truth.json").read_text()) == truth
