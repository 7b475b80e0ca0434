"""bench/diagnosis_grid.py scores the next-recording step from each diagnosis.json: what it asked
for, and whether a missed case's concealed effect was among the contenders it would tell apart."""

import json
from pathlib import Path

import pytest

from cases import load_bench


def _case(work, effect, seed, selected, next_recording, ramps=None, **extra):
    case = work / f"{effect}-{seed}"
    (case / "data").mkdir(parents=True)
    (case / "diagnosis").mkdir()
    made = load_bench("diagnosis_grid").ramp_dicts(ramps)
    (case / "data" / "truth.json").write_text(json.dumps({"amplitude": None, "ramps": made}))
    (case / "data" / "manifest.toml").write_text('[[recording]]\nfile = "a.csv"\nload_kg = 1.0\n')
    d = {"selected": selected, "verdict": selected[0] if selected else "none", "effects": [],
         "fit": {"before": {"heldout_rmse": 0.03}, "after": {"heldout_rmse": 0.01}}, "noise_floor": 0.01}
    if next_recording is not None:
        d["next_recording"] = next_recording
    d.update(extra)
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


def test_the_grid_diagnoses_again_from_another_grids_kept_runs(tmp_path, monkeypatch):
    """``--runs-from``: each case the other grid finished is diagnosed again here, with these
    options, from its recordings and kept model runs; its seconds are not written (not a cost);
    a case not finished there is skipped, and one without kept runs is refused by name."""
    grid = load_bench("diagnosis_grid")
    src, work = tmp_path / "src", tmp_path / "work"
    _case(src, "slider_stribeck", 3, ["friction_drift"], None)
    kept = src / "slider_stribeck-3" / "diagnosis" / "checkpoint"
    kept.mkdir()
    (kept / "fingerprint.json").write_text('"abc"')
    (kept / "runs-00000.npz").write_bytes(b"runs")
    calls = []

    def diagnose(cmd, check):
        # stands in for `szdyn.run diagnose`: the kept runs must be in place before it starts
        out = Path(cmd[cmd.index("--out") + 1])
        assert (out / "checkpoint" / "runs-00000.npz").read_bytes() == b"runs"
        assert (out.parent / "data" / "truth.json").is_file()
        calls.append(cmd)
        d = json.loads((src / "slider_stribeck-3" / "diagnosis" / "diagnosis.json").read_text())
        (out / "diagnosis.json").write_text(json.dumps({**d, "selected": ["slider_stribeck"]}))

    monkeypatch.setattr(grid.subprocess, "run", diagnose)
    monkeypatch.setattr(grid, "truth_primary", lambda truth, effect: None)
    md, js = tmp_path / "grid.md", tmp_path / "grid.json"
    assert grid.main(["--work", str(work), "--runs-from", str(src), "--seeds", "3", "--null-seeds", "",
                      "--effects", "slider_stribeck,load_lift", "--out", str(md), "--json", str(js),
                      "--reading", "/dev/null", "--diagnose-args=--keep-runs"]) == 0
    assert len(calls) == 1 and calls[0][-1] == "--keep-runs"
    rows = json.loads(js.read_text())
    assert [(r["effect"], r["selected"], r["correct"], r["seconds"]) for r in rows] == \
        [("slider_stribeck", ["slider_stribeck"], True, None)]
    assert not (work / "slider_stribeck-3" / "seconds.txt").exists() and not (work / "load_lift-3").exists()
    # finished here: scored again without running, the source's answer untouched
    assert grid.run_case(work, "slider_stribeck", 3, [], runs_from=src)["selected"] == ["slider_stribeck"]
    assert len(calls) == 1
    # a finished case whose runs were not kept cannot be replayed: the message says what to do
    _case(src, "load_lift", 3, ["load_lift"], None)
    with pytest.raises(SystemExit, match="load_lift-3.*--keep-runs"):
        grid.run_case(work, "load_lift", 3, [], runs_from=src)


def test_the_grid_keeps_one_protocol_per_work_directory(tmp_path, capsys):
    """``--ramps`` (synth's profiles): recordings of another protocol in ``--work`` are refused,
    a bad profile before any case runs, and the report says which profiles were recorded."""
    grid = load_bench("diagnosis_grid")
    stops = "up:1.5708:2:2:1.5,down:-1.2566:2.5:2:2"
    _case(tmp_path, "none", 1, [], None, ramps=stops)
    with pytest.raises(SystemExit, match=r"profiles \['up', 'down'\], not those of --ramps \(default\)"):
        grid.run_case(tmp_path, "none", 1, [])
    assert grid.run_case(tmp_path, "none", 1, [], ramps=stops)["correct"]
    assert grid.describe_ramps(stops) == ("the profiles up (to 3.14 rad/s in 2 s, held 2 s, stopped in 1.5 s), "
                                          "down (to -3.14 rad/s in 2.5 s, held 2 s, stopped in 2 s)")
    with pytest.raises(SystemExit):
        grid.main(["--work", str(tmp_path), "--ramps", "up:1:1", "--score-only"])
    assert "--ramps: entry 1 'up:1:1': expected NAME:A:T_RAMP:T_HOLD" in capsys.readouterr().err
    md, js = tmp_path / "grid.md", tmp_path / "grid.json"
    assert grid.main(["--work", str(tmp_path), "--ramps", stops, "--score-only", "--seeds", "",
                      "--null-seeds", "1", "--out", str(md), "--json", str(js), "--reading", "/dev/null"]) == 0
    assert "Each case: `synth` writes 4 recordings (loads 0.5 and 1 kg x the profiles up (to 3.14" in md.read_text()
    assert "1 of them held out" in md.read_text()


def test_the_grid_counts_unexplained_answers_whose_heaviest_load_said_none(tmp_path):
    """The report's caution (the mismatch may be the calibration's) stands on the heaviest load
    alone saying none: the grid records what that look said and counts it per kind of case."""
    grid = load_bench("diagnosis_grid")
    grid.truth_primary = lambda truth, effect: None
    said = lambda v: {"ran": True, "verdict": v, "selected": [], "adopted": False}   # noqa: E731
    _case(tmp_path, "none", 1, [], None, verdict="unexplained", heavy_look=said("none"))
    _case(tmp_path, "none", 2, [], None, verdict="unexplained", heavy_look={"ran": False, "why": "one load"})
    _case(tmp_path, "none", 3, [], None)
    _case(tmp_path, "load_lift", 4, [], None, verdict="unexplained", heavy_look=said("unexplained"))
    _case(tmp_path, "load_lift", 5, [], None, verdict="unexplained", heavy_look=said("none"))
    _case(tmp_path, "load_lift", 6, [], None, verdict="unexplained", heavy_look=said("none"))
    rows = {(r["effect"], r["seed"]): r for r in
            [grid.run_case(tmp_path, "none", s, []) for s in (1, 2, 3)]
            + [grid.run_case(tmp_path, "load_lift", s, []) for s in (4, 5, 6)]}
    assert rows["none", 1]["heavy_look"] == "none" and rows["load_lift", 4]["heavy_look"] == "unexplained"
    assert "heavy_look" not in rows["none", 2] and "heavy_look" not in rows["none", 3]
    md, js = tmp_path / "grid.md", tmp_path / "grid.json"
    assert grid.main(["--work", str(tmp_path), "--score-only", "--seeds", "4,5,6", "--effects", "load_lift",
                      "--null-seeds", "1,2,3", "--out", str(md), "--json", str(js), "--reading", "/dev/null"]) == 0
    assert "| `unexplained` answers whose heaviest load alone said none (effect cases; nulls) | 2/3; 1/2 | |" \
        in md.read_text()
