"""bench/diagnosis_grid.py scores the next-recording step from each diagnosis.json: what it asked
for, and whether a missed case's concealed effect was among the contenders it would tell apart."""

import json

from cases import load_bench


def _case(work, effect, seed, selected, next_recording):
    case = work / f"{effect}-{seed}"
    (case / "data").mkdir(parents=True)
    (case / "diagnosis").mkdir()
    (case / "data" / "truth.json").write_text(json.dumps({"amplitude": None}))
    (case / "data" / "manifest.toml").write_text('[[recording]]\nfile = "a.csv"\nload_kg = 1.0\n')
    d = {"selected": selected, "verdict": selected[0] if selected else "none", "effects": [],
         "fit": {"before": {"heldout_rmse": 0.03}, "after": {"heldout_rmse": 0.01}}, "noise_floor": 0.01}
    if next_recording is not None:
        d["next_recording"] = next_recording
    (case / "diagnosis" / "diagnosis.json").write_text(json.dumps(d))
    (case / "seconds.txt").write_text("12.0\n")


def _asked(protocol, load, sep, breakaway=False):
    return {"protocol": protocol, "load_kg": load, "min_separation": sep, "breakaway": breakaway,
            "sufficient": sep >= 2.0 and not breakaway}


def test_the_grid_scores_what_the_next_recording_would_decide(tmp_path):
    grid = load_bench("diagnosis_grid")
    _case(tmp_path, "none", 1, [], {"contenders": [], "why_not": "nothing is missing",
                                    "recommended": None})
    _case(tmp_path, "none", 2, [], None)             # a diagnosis from before the step: not counted
    _case(tmp_path, "slider_stribeck", 3, ["friction_drift"],
          {"contenders": ["friction_drift", "slider_stribeck"], "why_not": None,
           "recommended": _asked("stop_and_restart", 1.0, 10.1)})
    rows = [grid.run_case(tmp_path, "none", s, []) for s in (1, 2)]
    assert rows[0]["next_contenders"] == [] and rows[0]["next_protocol"] is None
    assert not rows[0]["next_sufficient"] and "next_contenders" not in rows[1]
    # a scored miss (its truth's parameter is not what this test is about)
    grid.truth_primary = lambda truth, effect: None
    miss = grid.run_case(tmp_path, "slider_stribeck", 3, [])
    assert not miss["correct"] and miss["next_protocol"] == "stop_and_restart at 1 kg"
    assert miss["next_sufficient"] and miss["next_separation"] == 10.1
    other = {**miss, "effect": "load_lift"}          # asked for, but between two other effects
    close = {**miss, "next_sufficient": False, "next_separation": 1.2}   # the truth's, not asked for
    out = grid.next_recording_rows(rows + [miss, other, close])
    assert out[0].startswith("| next recording asked for") and "| 2/4 cases |" in out[0]
    assert "| 1/3 |" in out[1]                        # only the first miss could be decided
    assert "| 0/1 | 0 |" in out[2]                    # the null that ran the step asked for nothing
    assert grid._next_cell(miss) == ("stop_and_restart at 1 kg, 10.1 floors "
                                     "(friction_drift vs slider_stribeck)")
    assert grid._next_cell(close).endswith(", not sufficient")
    assert grid._next_cell(rows[0]) == "not ranked" and grid._next_cell(rows[1]) == "-"
    assert grid.next_recording_rows(rows[1:]) == []
