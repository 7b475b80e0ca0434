"""bench/replay_grid.py: what its comparison of two replays counts as a difference, and its
error when there is nothing to replay."""

import math

from cases import load_bench

REPORT = """# szdyn diagnosis

**Second look.** A first pass said unexplained (...). First pass: 611 s, 2166 model runs.

| k_c | 0.05142 | 8.444e-05 | N*m/rad |

Cost: 854 s wall ({'calibrate': 0.17}), 2994 model runs (0 failed with both integrators).
"""


def test_json_differences_ignore_times_and_run_counts_only():
    bench = load_bench("replay_grid")
    a = {"selected": ["slider_viscous"], "cost": {"seconds": 3.0}, "calibrated": {"k_c": 0.05, "mu_s": math.nan},
         "second_look": {"model_runs": 1548, "verdict": "none"}, "effects": [{"id": "x", "score": 0.5}]}
    same = {"selected": ["slider_viscous"], "cost": {"seconds": 9.0}, "calibrated": {"k_c": 0.05, "mu_s": math.nan},
            "second_look": {"model_runs": 0, "verdict": "none"}, "effects": [{"id": "x", "score": 0.5}]}
    assert bench.json_differences(a, same) == []
    moved = {**same, "calibrated": {"k_c": 0.0500001, "mu_s": math.nan}}
    assert bench.json_differences(a, moved) == ["/calibrated/k_c: 0.05 != 0.0500001"]
    assert bench.json_differences(a, {**same, "selected": []}) == ["/selected: 1 items != 0"]
    assert bench.json_differences(a, {**same, "effects": [{"id": "x", "score": 0.5, "new": 1}]}) \
        == ["/effects[0]/new: only in the second"]
    # a value that changes type (a figure become null) is a difference
    assert bench.json_differences({"v": 1.0}, {"v": None}) == ["/v: 1.0 != None"]
    second = {**same, "second_look": {"model_runs": 0, "verdict": "unexplained"}}
    assert bench.json_differences(a, second) == ["/second_look/verdict: 'none' != 'unexplained'"]


def test_report_differences_blank_the_cost_line_and_the_first_pass_time_only():
    bench = load_bench("replay_grid")
    replayed = REPORT.replace("611 s, 2166 model runs", "2 s, 0 model runs").replace(
        "Cost: 854 s wall ({'calibrate': 0.17}), 2994", "Cost: 1 s wall ({'calibrate': 0.01}), 0")
    assert bench.report_differences(REPORT, replayed) == []
    assert bench.report_differences(REPORT, replayed.replace("0.05142", "0.05143")) == [5]
    assert bench.report_differences(REPORT, replayed + "one more line\n") == ["7 lines != 8"]


def test_nothing_to_replay_is_an_error_naming_the_directory(tmp_path, capsys):
    bench = load_bench("replay_grid")
    (tmp_path / "case-1" / "diagnosis").mkdir(parents=True)   # a case without kept runs
    assert bench.main(["--work", str(tmp_path), "--out", str(tmp_path / "out")]) == 2
    assert str(tmp_path) in capsys.readouterr().err
    assert bench.main(["--work", str(tmp_path), "--out", str(tmp_path / "out"), "--src", str(tmp_path)]) == 2
    assert "no szdyn/diagnose package" in capsys.readouterr().err
