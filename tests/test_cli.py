"""``python -m szdyn.run``: a real (small) run, and one-line errors for bad input."""
from __future__ import annotations

import csv
import json
import subprocess
import sys

import pytest

from szdyn.run import main

SMALL = ["--n-circles", "16", "--omega-hold", "0.6", "--t-hold", "0.2", "--quiet"]


def test_small_thesis_run_writes_csv_png_json(tmp_path):
    assert main(["--out", str(tmp_path)] + SMALL) == 0
    out = tmp_path / "thesis-fig10"
    summary = json.loads((out / "summary.json").read_text())
    assert [r["name"] for r in summary["runs"]] == ["ramp_0.1pi", "ramp_0.2pi", "ramp_0.5pi"]
    assert (out / "thesis-fig10.png").stat().st_size > 10_000
    for r in summary["runs"]:
        with open(out / r["csv"]) as fh:
            rows = list(csv.DictReader(fh))
        assert set(summary["csv_units"]) == set(rows[0])
        assert float(rows[-1]["t"]) == pytest.approx(r["t_end_s"])
        # the CSV is the run: its hold mean equals the summary's
        hold = [float(x["u_b"]) for x in rows if float(x["t"]) >= r["t_ramp_s"]]
        assert sum(hold) / len(hold) == pytest.approx(r["hold_mean_band_speed_rad_s"], rel=1e-6)
    # parameters round-trip: the written file reproduces the run's parameter set
    assert main(["--out", str(tmp_path / "again"), "--params", str(out / "params.json")] + SMALL) == 0


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
