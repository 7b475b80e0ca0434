"""``python -m szdyn.run``: a real (small) run, and one-line errors for bad input."""
from __future__ import annotations

import json
import subprocess
import sys

import pytest

from szdyn.criteria import evaluate_fig10
from szdyn.params import ParameterSet
from szdyn.run import main
from szdyn.simulate import OUTPUT_UNITS
from szdyn.thesis import read_outputs, stroke_error

SMALL = ["--n-circles", "16", "--omega-hold", "0.6", "--t-hold", "1.2", "--quiet", "--workers", "2"]


def test_small_thesis_run_json_is_recomputed_from_the_csvs(tmp_path):
    assert main(["--out", str(tmp_path), "--contact", "impact"] + SMALL) == 0
    out = tmp_path / "thesis-fig10"
    result = json.loads((out / "thesis-fig10.json").read_text())
    assert (out / "thesis-fig10.png").stat().st_size > 10_000
    model = result["models"]["impact"]
    assert [r["name"] for r in model["runs"]] == ["ramp_0.1pi", "ramp_0.2pi", "ramp_0.5pi"]
    outputs = {r["name"]: read_outputs(out / r["csv"]) for r in model["runs"]}
    for r in model["runs"]:
        assert set(outputs[r["name"]]) == set(OUTPUT_UNITS)
        assert outputs[r["name"]]["t"][-1] == pytest.approx(r["t_end_s"])
    recomputed = evaluate_fig10(outputs, {r["name"]: r["t_ramp_s"] for r in model["runs"]})
    assert json.loads(json.dumps(recomputed)) == model["criteria"]
    params = ParameterSet.from_json(out / "params.json")
    for r in model["runs"]:
        assert stroke_error(outputs[r["name"]], r["t_ramp_s"], params.geometry.pitch) == model["stroke_error"][r["name"]]
    # parameters round-trip: the written file reproduces the run
    assert main(["--out", str(tmp_path / "again"), "--params", str(out / "params.json"), "--contact", "impact"] + SMALL) == 0
    again = json.loads((tmp_path / "again" / "thesis-fig10" / "thesis-fig10.json").read_text())
    assert again["models"]["impact"]["criteria"] == model["criteria"]


def test_counter_model_run(tmp_path):
    assert main(["--out", str(tmp_path), "--contact", "lugre"] + SMALL) == 0
    result = json.loads((tmp_path / "thesis-fig10" / "thesis-fig10.json").read_text())
    assert list(result["models"]) == ["lugre"]


@pytest.mark.parametrize("argv, expect", [
    (["--set", "m_c=-1"], "m_c"),
    (["--set", "mc=0.01"], "did you mean"),
    (["--set", "k_c=abc"], "expected a number"),
    (["--set", "k_c"], "NAME=VALUE"),
    (["--set", "k_c=nan"], "k_c"),
    (["--set", "__import__('os')=1"], "unknown"),
    (["--params", "does-not-exist.json"], "does-not-exist.json"),
])
def test_bad_input_is_a_one_line_error(argv, expect, capsys, tmp_path):
    code = main(["--out", str(tmp_path)] + SMALL + argv)
    err = capsys.readouterr().err.strip()
    assert code == 2
    assert expect.lower() in err.lower()
    assert "Traceback" not in err and len(err.splitlines()) == 1


@pytest.mark.parametrize("argv", [["--dt", "0"], ["--method", "euler"], ["--n-circles", "-3"], ["--rtol", "nan"]])
def test_bad_options_are_rejected_by_the_parser(argv, capsys):
    with pytest.raises(SystemExit) as exc:
        main(argv)
    assert exc.value.code == 2
    err = capsys.readouterr().err
    assert "error:" in err and "Traceback" not in err


def test_bad_params_file_names_the_file(tmp_path, capsys):
    bad = tmp_path / "p.json"
    bad.write_text('{"values": {"m_c": "heavy"}}')
    assert main(["--out", str(tmp_path), "--params", str(bad)] + SMALL) == 2
    err = capsys.readouterr().err
    assert "p.json" in err and "Traceback" not in err


def test_help_and_no_traceback_in_a_real_process(tmp_path):
    r = subprocess.run([sys.executable, "-m", "szdyn.run", "--help"], capture_output=True, text=True)
    assert r.returncode == 0 and "--scenario" in r.stdout
    r = subprocess.run([sys.executable, "-m", "szdyn.run", "--out", str(tmp_path), "--set", "d=-0.001"],
                       capture_output=True, text=True)
    assert r.returncode == 2 and "Traceback" not in r.stderr and "'d'" in r.stderr


def test_regime_map_small(tmp_path):
    """A 2 x 2 regime map end to end; re-running resumes (nothing recomputed)."""
    from szdyn.defaults import default_parameters
    from szdyn.regime import run_regime_map

    params = default_parameters(n_circles=16)
    kw = dict(second="b_c", interference_mm=[-0.5, 0.19], factors=(1.0, 3.0), workers=1, progress=False,
              omega_hold=2.0, a=20.0, t_hold=0.3, hold_skip=0.1)
    s = run_regime_map(params, tmp_path, **kw)
    assert sum(s["counts"].values()) == 4
    # rollers 0.5 mm out of reach cannot move the band: full slip, band at rest
    far = [c for c in s["cases"] if c["interference_mm"] < 0]
    assert {c["regime"] for c in far} == {"full_slip"} and all(c["hold_band_rad_s"] == 0 for c in far)
    assert (tmp_path / "regime_map.png").stat().st_size > 5_000
    case_files = sorted((tmp_path / "cases").glob("*.json"))
    assert len(case_files) == 4
    stamps = [f.stat().st_mtime_ns for f in case_files]
    assert run_regime_map(params, tmp_path, **kw)["cases"] == s["cases"]
    assert [f.stat().st_mtime_ns for f in case_files] == stamps  # resumed: no case recomputed


def test_sweep_and_regime_commands_are_registered(capsys):
    for cmd in ("sweep", "regime", "synth"):
        with pytest.raises(SystemExit) as exc:
            main([cmd, "--help"])
        assert exc.value.code == 0


def test_a_mistyped_command_is_named_and_help_lists_the_commands(capsys):
    assert main(["diagnos", "m.toml", "--out", "d"]) == 2
    err = capsys.readouterr().err
    assert "unknown command 'diagnos' (did you mean 'diagnose'?)" in err and "Traceback" not in err
    with pytest.raises(SystemExit):
        main(["--help"])
    out = capsys.readouterr().out
    assert all(f"  {cmd} " in out for cmd in ("simulate", "sweep", "regime", "synth", "diagnose"))


def test_ctrl_c_inside_a_compiled_function_counts_as_an_interrupt():
    """CPython raises SystemError ('returned a result with an exception set') with the
    KeyboardInterrupt as its cause when Ctrl-C lands as a Numba function returns."""
    from szdyn.errors import interrupted

    try:
        try:
            raise KeyboardInterrupt
        except KeyboardInterrupt as ki:
            raise SystemError("CPUDispatcher(...) returned a result with an exception set") from ki
    except SystemError as exc:
        assert interrupted(exc)
    assert interrupted(KeyboardInterrupt())
    assert not interrupted(SystemError("a real one")) and not interrupted(ValueError())


def test_main_reports_ctrl_c_in_compiled_code_as_an_interrupt(monkeypatch, capsys):
    import szdyn.run as run

    def ctrl_c_in_numba(argv):
        try:
            raise KeyboardInterrupt
        except KeyboardInterrupt as ki:
            raise SystemError("CPUDispatcher(...) returned a result with an exception set") from ki

    monkeypatch.setitem(run.COMMANDS, "simulate", ctrl_c_in_numba)
    assert main([]) == 130
    assert capsys.readouterr().err == "szdyn: interrupted\n"
    monkeypatch.setitem(run.COMMANDS, "simulate", lambda argv: (_ for _ in ()).throw(SystemError("bug")))
    with pytest.raises(SystemError, match="bug"):
        main([])
