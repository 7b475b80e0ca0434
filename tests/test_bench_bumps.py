"""bench/bump_sensitivity.py: the model points it compares a recording with, and its errors on
a directory that is not a grid case."""

import math

import pytest

from cases import load_bench

TRUTH = {"k_c": 0.05, "b_c": 0.0075, "k_imp": 4e12, "b_imp": 2e13, "mu_s": 0.3, "mu_k": 0.25,
         "mu_st": 0.06, "v_st": 0.2}
PITCH = 2.0 * math.pi / 100


def test_points_move_one_thing_each_from_the_truth():
    bench = load_bench("bump_sensitivity")
    pts = bench._points(TRUTH, 0.04, PITCH, None, "a.csv")
    base = pts["truth"]
    assert base == {**TRUTH, "q_w0": 0.04}
    for label, name, factor in (("k_c x1.01", "k_c", 1.01), ("mu_k x1.01", "mu_k", 1.01)):
        moved = {k for k in base if pts[label][k] != base[k]}
        assert moved == {name}
        assert pts[label][name] == pytest.approx(base[name] * factor, rel=1e-12)
    phase = pts["phase +0.03125 pitch"]
    assert {k for k in base if phase[k] != base[k]} == {"q_w0"}
    assert phase["q_w0"] - 0.04 == pytest.approx(PITCH / 32, rel=1e-12)
    assert not any(k.startswith("calibrated") for k in pts)


def test_points_take_the_diagnosis_calibration_and_its_phase():
    bench = load_bench("bump_sensitivity")
    cal = {"k_c": 0.048, "b_c": 0.007, "k_imp": 3.8e12, "mu_s": 0.4, "mu_k": 0.29}
    diag = {"calibrated": cal, "wheel_phase": {"recordings": {"a.csv": {"q_w0": 0.06}}}}
    pts = bench._points(TRUTH, 0.04, PITCH, diag, "a.csv")
    assert pts["calibrated, truth phase"] == {**cal, "q_w0": 0.04}
    assert pts["calibrated, estimated phase"] == {**cal, "q_w0": 0.06}
    # a recording whose phase the diagnosis did not estimate: the truth phase only
    pts = bench._points(TRUTH, 0.04, PITCH, diag, "b.csv")
    assert "calibrated, estimated phase" not in pts and "calibrated, truth phase" in pts


def test_a_directory_that_is_not_a_grid_case_is_named(tmp_path):
    bench = load_bench("bump_sensitivity")
    with pytest.raises(SystemExit) as exc:
        bench.main([str(tmp_path), "load0p5kg"])
    assert str(tmp_path) in str(exc.value) and "truth.json" in str(exc.value)


def _measured(*changes):
    return {"recordings": [{"change": {"k_c x1.01": {"rms": r, "slow_rms": s}}} for r, s in changes]}


def test_a_seeds_sensitivity_is_the_fast_part_of_its_worst_run():
    regime = load_bench("bump_regime")
    assert regime.sensitivity(_measured((0.05, 0.03), (0.02, 0.0))) == pytest.approx(0.04, rel=1e-12)
    # a change all slow (a slip threshold) is not bumping
    assert regime.sensitivity(_measured((0.13, 0.13))) == 0.0


def test_the_tally_splits_named_cases_by_kind_and_period():
    regime = load_bench("bump_regime")
    cases = [{"effect": "slider_stribeck", "seed": 20, "correct": False},
             {"effect": "slider_stribeck", "seed": 30, "correct": True},
             {"effect": "slider_stribeck", "seed": 31, "correct": False},
             {"effect": "encoder_delay", "seed": 31, "correct": True},
             {"effect": "none", "seed": 70, "correct": True},          # nulls are not counted
             {"effect": "encoder_delay", "seed": 99, "correct": True}]  # no measurement: left out
    per, total = regime.tally(cases, {20: 0.05, 30: 0.0002, 31: 0.03})
    assert per["slider_stribeck/late"] == {"bumping_named": 0, "bumping_cases": 1,
                                           "calm_named": 1, "calm_cases": 1}
    assert per["slider_stribeck/early"]["bumping_cases"] == 1
    assert total["late"] == {"bumping_named": 1, "bumping_cases": 2, "calm_named": 1, "calm_cases": 1}
    assert sum(t["bumping_cases"] + t["calm_cases"] for t in total.values()) == 4


def test_a_seed_in_the_earlier_output_is_not_measured_again(tmp_path, monkeypatch):
    """The work directory of an earlier run may be gone: its seeds keep their values from --out,
    and only a new seed (or one whose measurement --work holds) is measured."""
    import json

    regime = load_bench("bump_regime")
    cases = [{"effect": "slider_stribeck", "seed": s, "correct": s == 30} for s in (20, 30, 40)]
    monkeypatch.setattr(regime.oos_summary, "record", lambda: None)
    monkeypatch.setattr(regime.oos_summary, "load", lambda _: cases)
    measured = []

    def measure(work, seed):
        measured.append(seed)
        return _measured((0.05, 0.03))

    monkeypatch.setattr(regime, "measure", measure)
    out, work = tmp_path / "bump.json", tmp_path / "work"
    out.write_text(json.dumps({"fast_kc_rad_s": {"20": 0.02, "40": 0.0001}}))
    work.mkdir()
    (work / "ne40.json").write_text("{}")       # measured in this work dir: measured again
    assert regime.main(["--work", str(work), "--out", str(out)]) == 0
    assert measured == [30, 40]
    got = json.loads(out.read_text())
    assert got["fast_kc_rad_s"] == {"20": 0.02, "30": pytest.approx(0.04), "40": pytest.approx(0.04)}
    assert got["total"]["late"] == {"bumping_named": 1, "bumping_cases": 2, "calm_named": 0, "calm_cases": 0}
