"""bench/replay_grid.py: what its comparison of two replays counts as a difference, and its
errors when there is nothing to replay."""

import math

from cases import load_bench

REPORT = """# szdyn diagnosis

**Second look.** A first pass said unexplained (...). First pass: 611 s, 2166 model runs.
The heaviest load alone took 48 s and 322 model runs.

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


def test_text_differences_blank_times_and_run_counts_only():
    bench = load_bench("replay_grid")
    replayed = REPORT.replace("611 s, 2166 model runs", "2 s, 0 model runs").replace(
        "48 s and 322 model runs", "1 s and 0 model runs").replace(
        "Cost: 854 s wall ({'calibrate': 0.17}), 2994", "Cost: 1 s wall ({'calibrate': 0.01}), 0")
    assert bench.text_differences(REPORT, replayed) == []
    assert bench.text_differences(REPORT, replayed.replace("0.05142", "0.05143")) == [6]
    assert bench.text_differences(REPORT, replayed + "one more line\n") == ["8 lines != 9"]
    # the log: its clock and progress lines are blanked, what it says is not
    log = ("diagnose [   0.3 s] calibrating\ndiagnose [ 120.0 s] 25 model runs\n"
           "diagnose [ 130.5 s] refitting base + load_lift\n")
    again = ("diagnose [   0.1 s] calibrating\ndiagnose [   0.2 s] 50 model runs\n"
             "diagnose [   0.9 s] refitting base + load_lift\n")
    assert bench.text_differences(log, again) == []
    assert bench.text_differences(log, again.replace("load_lift", "slider_viscous")) == [3]


def test_the_steps_a_pass_timed_are_compared_not_their_times():
    bench = load_bench("replay_grid")
    a = {"cost": {"seconds": {"calibrate": 10.0, "refit": 30.0}, "model_runs": 900}}
    b = {"cost": {"seconds": {"calibrate": 0.1, "refit": 0.3}, "model_runs": 0}}
    assert bench.json_differences(a, b) == []
    c = {"cost": {"seconds": {"calibrate": 0.1, "refit": 0.3, "rivals": 0.2}, "model_runs": 0}}
    assert bench.json_differences(a, c) == ["/cost/seconds: steps ['calibrate', 'refit'] != "
                                            "['calibrate', 'refit', 'rivals']"]


def test_nothing_to_replay_is_an_error_naming_the_directory(tmp_path, capsys):
    bench = load_bench("replay_grid")
    (tmp_path / "case-1" / "diagnosis").mkdir(parents=True)   # a case without kept runs
    assert bench.main(["--work", str(tmp_path), "--out", str(tmp_path / "out")]) == 2
    assert str(tmp_path) in capsys.readouterr().err
    assert bench.main(["--work", str(tmp_path), "--out", str(tmp_path / "out"), "--src", str(tmp_path)]) == 2
    assert "no szdyn/diagnose package" in capsys.readouterr().err
