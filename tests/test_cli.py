"""``python -m szdyn.run``: a real (small) run, and one-line errors for bad input."""
from __future__ import annotations

import json
import subprocess
import sys
import warnings

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
    (["--set", "k_c=nan"], "--set k_c: expected a finite number"),
    (["--set", "__import__('os')=1"], "unknown"),
    (["--params", "does-not-exist.json"], "does-not-exist.json"),
    (["--params", "p" * 300 + ".json"], "--params: not a usable path"),
    # checked before any run starts (these were tracebacks, silent garbage or minutes of waiting)
    (["--method", "rk4", "--dt", "3e-4"], "--save-dt 0.001 must be a multiple of --dt 0.0003"),
    (["--save-dt", "1"], "at least 10 are needed"),
    (["--n-circles", "100000000"], "at most 10000"),
    (["--omega-hold", "1e6"], "GiB of output"),
    (["--set", "contact_model=2"], "--contact"),
    (["--set", "k_c=1", "--set", "k_c=2"], "given twice"),
    (["--set", "n_circles=8"], "disagree"),
    (["--set", "geometry=1"], "--params file"),
    # once a traceback (OverflowError, numba TypingError, OSError) or hours of waiting
    (["--workers", "99999999999"], "expected at most 1024 processes"),
    (["--method", "rk4", "--dt", "1e-9"], "fixed steps over the"),
    (["--method", "heun", "--dt", "1e-300"], "fixed steps over the"),
    (["--set", "n_rollers=1e9"], "at most 1000"),
    (["--out", "/tmp/" + "x" * 300], "cannot create the output directory (file name too long)"),
    (["--out", ""], "--out: expected a directory, got an empty string"),   # once the current directory
])
def test_bad_input_is_a_one_line_error(argv, expect, capsys, tmp_path):
    code = main(["--out", str(tmp_path)] + SMALL + argv)
    err = capsys.readouterr().err.strip()
    assert code == 2
    assert expect.lower() in err.lower()
    assert "Traceback" not in err and len(err.splitlines()) == 1


@pytest.mark.parametrize("argv", [["--dt", "0"], ["--method", "euler"], ["--n-circles", "-3"], ["--rtol", "nan"],
                                  ["--rtol", "5"], ["--dt", "-1e-4"], ["regime", "--omega-hold", "nan"],
                                  ["sweep", "x.toml", "--bogus"]])
def test_bad_options_are_rejected_by_the_parser_in_one_line(argv, capsys):
    assert main(argv) == 2
    err = capsys.readouterr().err.strip()
    assert err.startswith("szdyn: error: ") and "--help" in err
    assert len(err.splitlines()) == 1 and "Traceback" not in err
    # a negative value in e-notation reaches the option's own check (argparse's own pattern took it
    # for an option and said "expected one argument")
    assert "expected one argument" not in err
    assert next(a for a in argv if a.startswith("--")) in err        # the offending option, named


def test_a_step_option_the_method_does_not_use_is_said_and_defaults_fill_the_rest():
    from argparse import Namespace

    from szdyn.run import STEP_DEFAULTS, resolve_step_options

    args = Namespace(method="dopri5", dt=1e-4, rtol=None, atol=None)
    with pytest.warns(UserWarning, match="--dt not used by --method dopri5"):
        resolve_step_options(args)
    assert (args.dt, args.rtol, args.atol) == (1e-4, STEP_DEFAULTS["rtol"], STEP_DEFAULTS["atol"])
    with pytest.warns(UserWarning, match="--rtol and --atol not used by --method heun"):
        resolve_step_options(Namespace(method="heun", dt=None, rtol=1e-6, atol=1e-9))
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        resolve_step_options(Namespace(method="rk4", dt=1e-4, rtol=None, atol=None))


@pytest.mark.parametrize("content, expect", [
    (b'{"values": {"m_c": "heavy"}}', "must be a real number"),
    (b'{"values": {"m_c": true}}', "must be a real number, got True"),   # not read as 1 kg
    (b'{"values": {"k_c": 1.0, "k_c": 2.0}}', "key 'k_c' appears twice"),
    (b"\x89PNG\r\n\x1a\n\xff\xfe", "not UTF-8"),
])
def test_bad_params_file_names_the_file(tmp_path, capsys, content, expect):
    bad = tmp_path / "p.json"
    bad.write_bytes(content)
    assert main(["--out", str(tmp_path), "--params", str(bad)] + SMALL) == 2
    err = capsys.readouterr().err
    assert "p.json" in err and expect in err and "Traceback" not in err
    assert main(["--out", str(tmp_path), "--params", str(tmp_path)] + SMALL) == 2
    assert "is a directory" in capsys.readouterr().err


def test_a_criterion_without_a_value_is_not_met_with_its_reason():
    from szdyn.run import _verdict

    assert _verdict({"passed": True, "value": 0.2, "detail": {}}) == "met"
    assert _verdict({"passed": False, "value": 0.01, "detail": {}}) == "NOT met"
    short = {"passed": False, "value": None, "detail": {"reason": "ramp_0.1pi: only 0 hold samples"}}
    assert _verdict(short) == "NOT met (no value: ramp_0.1pi: only 0 hold samples)"


def test_out_that_is_a_file_is_refused(tmp_path, capsys):
    (tmp_path / "f").write_text("mine")
    for out in (tmp_path / "f", tmp_path / "f" / "sub"):
        assert main(["--out", str(out)] + SMALL) == 2
        assert f"{tmp_path / 'f'} is a file" in capsys.readouterr().err
    assert (tmp_path / "f").read_text() == "mine"


def test_a_failed_run_leaves_the_earlier_results_as_they_were(tmp_path, monkeypatch, capsys):
    """simulate writes into a staging directory and moves the set in only when every run is done:
    a run that fails (or is interrupted) part-way neither loses nor mixes the earlier files."""
    import szdyn.thesis as thesis

    fast = ["--n-circles", "4", "--omega-hold", "1", "--t-hold", "0.6", "--contact", "coulomb", "--quiet",
            "--workers", "1"]
    assert main(["--out", str(tmp_path)] + fast) == 0
    out = tmp_path / "thesis-fig10"
    before = {p.relative_to(out): p.read_bytes() for p in out.rglob("*") if p.is_file()}

    def failing(params, stage, **kw):   # writes part of its set, then fails
        params.to_json(stage / "params.json")
        (stage / "coulomb").mkdir()
        (stage / "coulomb" / "ramp_0.1pi.csv").write_text("t\n0\n")
        raise KeyboardInterrupt

    monkeypatch.setattr(thesis, "run_fig10", failing)
    assert main(["--out", str(tmp_path), "--set", "k_c=0.06"] + fast) == 130
    after = {p.relative_to(out): p.read_bytes() for p in out.rglob("*") if p.is_file()}
    assert after == before
    assert not [p for p in out.iterdir() if p.name.startswith(".partial-")]


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


def test_regime_map_with_an_invalid_case_is_still_written(tmp_path, capsys):
    """A case out of the parameter bounds (rollers beyond the band) is 'failed' with empty speed
    cells; it used to stop the map's CSV (non-finite values refused) after every run was made."""
    import csv

    from szdyn.defaults import default_parameters
    from szdyn.regime import run_regime_map

    params = default_parameters(n_circles=16)
    beyond = 1e3 * (params["d"] + params["t_c"]) + 1.0   # R_w + t_r > R_bo: an invalid combination
    kw = dict(second="b_c", interference_mm=[0.19, beyond], factors=(1.0,), workers=1, progress=False,
              omega_hold=2.0, a=20.0, t_hold=0.3, hold_skip=0.1)
    s = run_regime_map(params, tmp_path, **kw)
    assert s["counts"]["failed"] == 1 and sum(s["counts"].values()) == 2
    with open(tmp_path / "regime_map.csv", newline="") as fh:
        rows = list(csv.DictReader(fh))
    bad = next(r for r in rows if r["regime"] == "failed")
    assert bad["hold_wheel_rad_s"] == bad["hold_band_rad_s"] == bad["band_over_wheel"] == ""
    assert bad["status"] != "ok" and (tmp_path / "regime_map.png").is_file()
    # a second axis at 0 would make every factor the same case; bounds are said in the map's terms
    assert main(["regime", "--set", "b_c=0", "--out", str(tmp_path / "z"), "--quiet"]) == 2
    assert "which is 0 here" in capsys.readouterr().err
    assert main(["regime", "--set", "R_w=5e-5", "--out", str(tmp_path / "w"), "--quiet"]) == 2
    err = capsys.readouterr().err
    assert "the regime map around R_w = 5e-05 m" in err and "Traceback" not in err


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
