"""Parameter sweeps (``szdyn.sweep``): spec validation, resume after interruption, failed
cases, determinism across worker counts and executors (process pool, Dask)."""
from __future__ import annotations

import csv
import json
import os
import signal
import subprocess
import sys
import textwrap
import time
from pathlib import Path

import numpy as np
import pytest

from szdyn.errors import UserInputError
from szdyn.sweep import load_series, run_sweep, sweep_command
from szdyn.sweep_spec import SpecError, load_spec, parse_spec

ROOT = Path(__file__).resolve().parents[1]

BASE = """
description = "test sweep"
[base]
t_end = 0.2
n_circles = 16
[base.drive]
kind = "ramp_hold"
a = 10.0
t_ramp = 0.1
t_hold = 0.1
[base.integrator]
method = "dopri5"
rtol = 1e-5
atol = 1e-8
"""
AXES = """
[axes]
k_c = [0.01, 0.05]
"drive.a" = [5.0, 10.0]
"""
METRICS = """
[metrics]
slip_hold = { kind = "mean", of = "rel_speed", t_from = "drive.t_ramp" }
speed_ratio = { kind = "ratio_of_means", of = "u_b", over = "u_w", t_from = 0.1, t_to = 0.2 }
stroke_lost_end = { kind = "final", of = "stroke_lost" }
stroke_lost_per_m = { kind = "final_ratio", of = "stroke_lost", over = "stroke" }
max_contacts = { kind = "max", of = "contacts" }
mean_torque = { kind = "mean", of = "wheel_reaction_torque" }
max_abs_torque = { kind = "max_abs", of = "wheel_reaction_torque" }
"""


def write_spec(tmp_path, text, name="spec.toml") -> Path:
    p = tmp_path / name
    p.write_text(textwrap.dedent(text))
    return p


def read_table(out) -> list[dict]:
    with open(Path(out) / "cases.csv", newline="") as fh:
        return list(csv.DictReader(fh))


# --------------------------------------------------------------------------- end to end
def test_tiny_sweep_end_to_end(tmp_path):
    spec = write_spec(tmp_path, BASE + AXES + METRICS)
    out = tmp_path / "out"
    assert sweep_command([str(spec), "--out", str(out), "--workers", "1", "--quiet"]) == 0
    rows = read_table(out)
    assert [int(r["case_id"]) for r in rows] == [0, 1, 2, 3]
    assert all(r["status"] == "ok" for r in rows)
    # grid order: first axis slowest
    assert [(float(r["k_c"]), float(r["drive.a"])) for r in rows] == [
        (0.01, 5.0), (0.01, 10.0), (0.05, 5.0), (0.05, 10.0)]
    cols = {c["name"]: c for c in json.loads((out / "columns.json").read_text())["columns"]}
    assert set(cols) == set(rows[0])
    assert cols["k_c"]["unit"] == "N*m/rad" and cols["drive.a"]["unit"] == "rad/s^2"
    assert cols["slip_hold"]["unit"] == "rad/s" and cols["speed_ratio"]["unit"] == "1"
    assert cols["stroke_lost_end"]["unit"] == "m" and cols["max_abs_torque"]["unit"] == "N*m"
    # the time series are the runs: metrics recomputed from the .npz files agree
    for r in rows:
        s = load_series(out, int(r["case_id"]))
        assert set(s) >= {"t", "u_w", "u_b", "rel_speed", "stroke_lost", "contacts"}
        assert s["t"][-1] == pytest.approx(0.2)
        hold = s["t"] >= 0.1 - 1e-12
        assert float(r["slip_hold"]) == pytest.approx(s["rel_speed"][hold].mean(), rel=1e-12)
        assert float(r["speed_ratio"]) == pytest.approx(
            s["u_b"][hold].mean() / s["u_w"][hold].mean(), rel=1e-12)
        assert float(r["stroke_lost_end"]) == s["stroke_lost"][-1]
        assert float(r["max_abs_torque"]) == np.abs(s["wheel_reaction_torque"]).max()
        assert int(r["n_steps"]) > 0
    # the faster ramp slips more during the hold (sanity of the inputs reaching the model)
    assert (out / "metrics.png").stat().st_size > 10_000
    meta = json.loads((out / "spec.json").read_text())
    assert len(meta["hash"]) == 64 and meta["n_cases"] == 4
    summary = json.loads((out / "summary.json").read_text())
    assert summary["counts"] == {"ok": 4} and summary["complete"]
    # a re-run computes nothing and rewrites an identical table
    before = (out / "cases.csv").read_bytes()
    res = run_sweep(spec, out, workers=1, progress=False, plot=False)
    assert res.n_computed == 0 and res.n_skipped == 4
    assert (out / "cases.csv").read_bytes() == before


def test_options_beyond_their_range_are_refused_before_any_case(tmp_path):
    spec = write_spec(tmp_path, BASE)
    for argv, say in ((["--workers", "99999999999"], "--workers must be in 1..1024"),   # once an OverflowError
                      (["--out", str(tmp_path / ("x" * 300))], "--out: .*cannot create the output directory")):
        with pytest.raises(UserInputError, match=say):
            sweep_command([str(spec), "--out", str(tmp_path / "out"), "--quiet", *argv])
    with pytest.raises(UserInputError, match="--workers must be in 1..1024"):   # called as a library too
        run_sweep(spec, tmp_path / "out", workers=10 ** 11, progress=False)
    assert sorted(p.name for p in tmp_path.iterdir()) == [spec.name]


# --------------------------------------------------------------------------- spec errors
@pytest.mark.parametrize("extra, expect", [
    ("[axis]\nk_c = [1.0]\n", ["[top level]", "'axis'", "did you mean 'axes'"]),
    ("[axes]\nkc = [0.01, 0.02]\n", ["[axes]", "'kc'", "did you mean 'k_c'"]),
    ("[axes]\n\"drive.t_rmp\" = [0.1]\n", ["[axes]", "did you mean 'drive.t_ramp'"]),
    ("[axes]\nk_c = {start = 0.01, stop = 0.1, nm = 3}\n", ["[axes] 'k_c'", "did you mean 'num'"]),
    ("[axes]\nk_c = [0.01, -1.0]\n", ["[axes] 'k_c'", "k_c", ">= 0"]),
    ("[axes]\nk_c = [0.01, \"x\"]\n", ["[axes] 'k_c'", "must be a number"]),
    ("[sampling]\nmetod = \"lhs\"\n", ["[sampling]", "did you mean 'method'"]),
    ("[sampling]\nmethod = \"lhc\"\nn = 4\n[sampling.ranges]\nk_c = [0.01, 0.1]\n",
     ["[sampling] key 'method'", "did you mean 'lhs'"]),
    ("[metrics]\ns = { kind = \"maen\", of = \"rel_speed\" }\n", ["[metrics.s]", "did you mean 'mean'"]),
    ("[metrics]\ns = { kind = \"mean\", of = \"rel_sped\" }\n", ["[metrics.s]", "did you mean 'rel_speed'"]),
    ("[metrics]\ns = { kind = \"mean\", off = \"rel_speed\" }\n", ["[metrics.s]", "did you mean 'of'"]),
    # refused before the values are made (1e9 of them took 7.5 GB)
    ("[axes]\nk_c = {start = 0.01, stop = 0.05, num = 1000000000}\n", ["[axes] 'k_c'", "more than the limit"]),
    # refused before any case runs: each would give metrics from 2 samples
    ("[axes]\n\"integrator.save_dt\" = [0.001, 0.1]\n",
     ["case 1 (integrator.save_dt = 0.1)", "at least 10 are needed"]),
    ("[axes]\nt_end = [0.2, 100000.0]\n", ["case 1 (t_end = 100000.0)", "GiB of output"]),
    # a mistyped N_c: refused by the cap on it, naming the axis
    ("[axes]\nn_circles = [16, 100000000]\n", ["[axes] 'n_circles'", "at most 10000"]),
    # a relative tolerance of 1 or more is no tolerance (the CLI's --rtol refuses it too)
    ("[axes]\n\"integrator.rtol\" = [1e-5, 2.0]\n", ["[axes] 'integrator.rtol'", "below 1"]),
    ("[axes]\nk_c = [0.01, 1" + "0" * 400 + "]\n", ["[axes] 'k_c'", "integer too large for a float"]),
])
def test_unknown_keys_and_bad_values_name_the_key_and_suggest(tmp_path, extra, expect):
    spec = write_spec(tmp_path, BASE + extra)
    with pytest.raises(UserInputError) as exc:
        sweep_command([str(spec), "--out", str(tmp_path / "out"), "--quiet"])
    msg = str(exc.value)
    assert str(spec) in msg and len(msg.splitlines()) == 1
    for e in expect:
        assert e in msg, msg
    assert not (tmp_path / "out").exists()


def test_a_spec_saved_with_a_byte_order_mark_is_read(tmp_path):
    plain = load_spec(write_spec(tmp_path, BASE))
    bom = tmp_path / "bom.toml"
    bom.write_bytes(b"\xef\xbb\xbf" + textwrap.dedent(BASE).encode())
    assert load_spec(bom).hash == plain.hash


@pytest.mark.parametrize("old, new, expect", [
    ("k_c = 0.05", "kc = 0.05", "[base.params] unknown parameter 'kc' (did you mean 'k_c'?)"),
    ("k_c = 0.05", "drive_mode = 1", "[base.params] key 'drive_mode' is set by [base.drive] kind"),
    ("t_ramp = 0.1", "t_rampe = 0.1",
     "[base.drive] unknown key 't_rampe' for kind 'ramp_hold' (did you mean 't_ramp'?)"),
    ("t_ramp = 0.1", "t_ramp = -0.1", "[base.drive]: RampHold: t_ramp must be > 0"),
    ('kind = "ramp_hold"', 'kind = "ramphold"', "did you mean 'ramp_hold'"),
    ('method = "dopri5"', 'method = "dopri"', "did you mean 'dopri5'"),
    ("rtol = 1e-5", "rtl = 1e-5", "[base.integrator] unknown key 'rtl' (did you mean 'rtol'?)"),
    ("rtol = 1e-5", "rtol = 2.0", "[base.integrator] key 'rtol' must be a relative tolerance below 1"),
    ("n_circles = 16", "n_circle = 16", "[base] unknown key 'n_circle' (did you mean 'n_circles'?)"),
    ("t_end = 0.2", "t_end = \"1 s\"", "[base] key 't_end' must be a number"),
    # every case would fail, and be retried, at the first step
    ('method = "dopri5"', 'method = "rk4"\ndt = 3e-4',
     "[base]: save_dt=0.001 must be a multiple of dt=0.0003 (within 1e-9 relative); see [base.integrator]"),
])
def test_base_errors(tmp_path, old, new, expect):
    text = BASE + "[base.params]\nk_c = 0.05\n"
    load_spec(write_spec(tmp_path, text, name="ok.toml"))  # the unchanged spec is valid
    assert old in text
    with pytest.raises(SpecError) as exc:
        load_spec(write_spec(tmp_path, text.replace(old, new)))
    assert expect in str(exc.value)


def test_not_toml_and_missing_file(tmp_path):
    with pytest.raises(SpecError, match="not valid TOML"):
        load_spec(write_spec(tmp_path, "[base\nt_end = 1"))
    with pytest.raises(SpecError, match="cannot read"):
        load_spec(tmp_path / "nope.toml")


def test_changed_spec_is_refused(tmp_path):
    spec = write_spec(tmp_path, BASE + AXES)
    out = tmp_path / "out"
    run_sweep(spec, out, workers=1, progress=False, plot=False, max_cases=1)
    # cosmetic changes (comments, 0.2 vs 2e-1, key order inside a table) are the same spec
    write_spec(tmp_path, "# a comment\n" + BASE.replace("t_end = 0.2", "t_end = 2e-1")
               .replace("rtol = 1e-5\natol = 1e-8", "atol = 1e-8\nrtol = 0.00001") + AXES,
               name="same.toml")
    res = run_sweep(tmp_path / "same.toml", out, workers=1, progress=False, plot=False)
    assert res.n_skipped == 1 and res.n_computed == 3
    changed = write_spec(tmp_path, BASE + AXES.replace("0.05", "0.06"), name="changed.toml")
    with pytest.raises(UserInputError) as exc:
        sweep_command([str(changed), "--out", str(out), "--quiet"])
    msg = str(exc.value)
    assert "different sweep spec" in msg and "axes[0].values[1]" in msg
    # a directory that is not a sweep directory is refused too
    (tmp_path / "other").mkdir()
    (tmp_path / "other" / "notes.txt").write_text("mine")
    with pytest.raises(UserInputError, match="not a sweep directory"):
        run_sweep(spec, tmp_path / "other", workers=1, progress=False)


# --------------------------------------------------------------------------- interruption
def test_interrupted_sweep_resumes_without_recomputing(tmp_path):
    spec = write_spec(tmp_path, BASE + AXES + METRICS)
    ref = tmp_path / "ref"
    run_sweep(spec, ref, workers=1, progress=False, plot=False)

    out = tmp_path / "out"
    res = run_sweep(spec, out, workers=1, progress=False, plot=False, max_cases=2)
    assert (res.n_computed, res.complete) == (2, False)
    assert [r["status"] for r in read_table(out)] == ["ok", "ok", "pending", "pending"]
    done = sorted((out / "cases").iterdir())
    mtimes = {p.name: p.stat().st_mtime_ns for p in done}
    assert len(mtimes) == 4  # 2 cases x (.json + .npz)

    seen = []
    res = run_sweep(spec, out, workers=1, progress=False, plot=False,
                    on_case_done=lambda rec: seen.append(rec["case_id"]))
    assert seen == [2, 3] and res.n_computed == 2 and res.n_skipped == 2 and res.complete
    assert {p: (out / "cases" / p).stat().st_mtime_ns for p in mtimes} == mtimes
    assert (out / "cases.csv").read_bytes() == (ref / "cases.csv").read_bytes()


def test_kill_9_then_rerun_loses_nothing(tmp_path):
    """A real ``kill -9`` of a sweep process between cases: the re-run skips what was written."""
    spec = write_spec(tmp_path, BASE + """
[axes]
k_c = [0.01, 0.02, 0.03, 0.04, 0.05, 0.06]
""")
    out = tmp_path / "out"
    code = ("import sys, time; from szdyn.sweep import run_sweep; "
            f"run_sweep({str(spec)!r}, {str(out)!r}, workers=1, progress=False, plot=False, "
            "on_case_done=lambda r: time.sleep(0.4))")
    proc = subprocess.Popen([sys.executable, "-c", code], cwd=ROOT)
    try:
        deadline = time.monotonic() + 120
        while time.monotonic() < deadline:
            if len(list((out / "cases").glob("*.json"))) >= 2:
                break
            assert proc.poll() is None, "sweep subprocess ended early"
            time.sleep(0.02)
        os.kill(proc.pid, signal.SIGKILL)
    finally:
        proc.wait(timeout=30)
    assert proc.returncode == -signal.SIGKILL
    written = sorted((out / "cases").glob("*.json"))
    assert 2 <= len(written) < 6
    mtimes = {p.name: p.stat().st_mtime_ns for p in written}

    res = run_sweep(spec, out, workers=1, progress=False, plot=False)
    assert res.n_skipped == len(written) and res.n_computed == 6 - len(written)
    assert {p: (out / "cases" / p).stat().st_mtime_ns for p in mtimes} == mtimes
    assert not list(out.rglob(".*.tmp"))
    ref = tmp_path / "ref"
    run_sweep(spec, ref, workers=1, progress=False, plot=False)
    assert (out / "cases.csv").read_bytes() == (ref / "cases.csv").read_bytes()


# --------------------------------------------------------------------------- failures
def test_diverging_case_is_recorded_as_failed_and_the_sweep_goes_on(tmp_path):
    # geometry pinned (0.17 mm interference) so that the test does not follow retuned defaults
    spec = write_spec(tmp_path, BASE.replace('method = "dopri5"', 'method = "heun"\ndt = 1e-3')
                      + '[base.params]\nd = 5e-3\nR_w = 0.01817\nt_c = 1e-3\nt_r = 6e-3\n'
                      + '[axes]\n"drive.a" = [3.0, 30.0]\nk_c = [0.05]\n')
    out = tmp_path / "out"
    res = run_sweep(spec, out, workers=1, progress=False)
    rows = read_table(out)
    assert [r["status"] for r in rows] == ["ok", "failed"] and res.counts == {"failed": 1, "ok": 1}
    assert "non-finite" in rows[1]["error"] and rows[1]["stroke_lost_end"] == ""
    meta = json.loads((out / "cases" / "00001.json").read_text())
    assert meta["status"] == "failed" and 0 < meta["t_fail"] < 0.2
    assert not (out / "cases" / "00001.npz").exists()
    # failed cases are finished: a re-run does not retry them
    assert run_sweep(spec, out, workers=1, progress=False, plot=False).n_computed == 0


def test_resume_after_model_change_warns(tmp_path, monkeypatch, capsys):
    import szdyn.sweep as sw

    spec = write_spec(tmp_path, BASE + AXES)
    out = tmp_path / "out"
    run_sweep(spec, out, workers=1, progress=False, plot=False, max_cases=1)
    monkeypatch.setattr(sw, "model_fingerprint", lambda: "0" * 64)
    run_sweep(spec, out, workers=1, progress=False, plot=False)
    assert "generated model (szdyn_generated) changed" in capsys.readouterr().err
    assert json.loads((out / "summary.json").read_text())["model_changed_since_start"] is True


def test_invalid_parameter_combination_is_recorded(tmp_path):
    # each value is valid alone against the base, but mu_k > mu_s in one combination
    spec = write_spec(tmp_path, BASE + "[axes]\nmu_s = [0.3, 0.5]\nmu_k = [0.25, 0.4]\n")
    out = tmp_path / "out"
    run_sweep(spec, out, workers=1, progress=False, plot=False)
    rows = read_table(out)
    assert [r["status"] for r in rows] == ["ok", "invalid", "ok", "ok"]
    assert "mu_k" in rows[1]["error"]


# --------------------------------------------------------------------------- sampling
def test_lhs_sampling_is_deterministic_and_in_range():
    import tomllib

    doc = tomllib.loads(BASE + """
[axes]
"drive.a" = [5.0, 10.0]
[sampling]
method = "lhs"
n = 6
seed = 7
[sampling.ranges]
k_c = { low = 0.01, high = 0.1, scale = "log" }
n_circles = [8, 24]
""")
    a, b = parse_spec(doc), parse_spec(doc)
    assert a.hash == b.hash and a.cases == b.cases and len(a.cases) == 12
    assert a.variables == ["drive.a", "k_c", "n_circles"]
    kc = [c["k_c"] for c in a.cases[:6]]
    assert all(0.01 <= v <= 0.1 for v in kc)
    assert all(isinstance(c["n_circles"], int) and 8 <= c["n_circles"] <= 24 for c in a.cases)
    # LHS: one sample per stratum of log k_c
    strata = sorted(int(6 * np.log(v / 0.01) / np.log(10)) for v in kc)
    assert strata == list(range(6))
    assert a.cases[6:] == [{**c, "drive.a": 10.0} for c in a.cases[:6]]
    doc["sampling"]["seed"] = 8
    assert parse_spec(doc).hash != a.hash


# --------------------------------------------------------------------------- determinism
def test_same_table_with_1_and_2_worker_processes(tmp_path):
    spec = write_spec(tmp_path, BASE + AXES + METRICS)
    r1 = run_sweep(spec, tmp_path / "w1", workers=1, progress=False, plot=False)
    r2 = run_sweep(spec, tmp_path / "w2", workers=2, progress=False, plot=False)
    assert r1.n_computed == r2.n_computed == 4
    assert (tmp_path / "w1" / "cases.csv").read_bytes() == (tmp_path / "w2" / "cases.csv").read_bytes()
    s1, s2 = load_series(tmp_path / "w1", 3), load_series(tmp_path / "w2", 3)
    assert all(np.array_equal(s1[k], s2[k]) for k in s1)


# --------------------------------------------------------------------------- dask
def test_dask_local_cluster_gives_the_same_table(tmp_path):
    distributed = pytest.importorskip(
        "distributed", reason="Dask distributed not installed (optional extra szdyn[dask])")
    spec = write_spec(tmp_path, BASE + AXES + METRICS)
    run_sweep(spec, tmp_path / "serial", workers=1, progress=False, plot=False)
    with distributed.LocalCluster(n_workers=1, threads_per_worker=1, processes=False,
                                  dashboard_address=None) as cluster, \
            distributed.Client(cluster) as client:
        res = run_sweep(spec, tmp_path / "dask", dask_client=client, progress=False, plot=False)
    assert res.n_computed == 4
    assert (tmp_path / "dask" / "cases.csv").read_bytes() == \
        (tmp_path / "serial" / "cases.csv").read_bytes()


def test_dask_cli_path_with_worker_processes(tmp_path):
    pytest.importorskip("distributed", reason="Dask distributed not installed (optional extra szdyn[dask])")
    spec = write_spec(tmp_path, BASE + "[axes]\nk_c = [0.01, 0.05]\n")
    assert sweep_command([str(spec), "--out", str(tmp_path / "d"), "--dask", "--workers", "1",
                          "--quiet", "--no-plot"]) == 0
    assert [r["status"] for r in read_table(tmp_path / "d")] == ["ok", "ok"]
    assert json.loads((tmp_path / "d" / "summary.json").read_text())["executor"] == "dask"


def test_missing_dask_is_a_clear_error(tmp_path, monkeypatch):
    monkeypatch.setitem(sys.modules, "distributed", None)  # import distributed -> ImportError
    spec = write_spec(tmp_path, BASE)
    with pytest.raises(UserInputError, match=r"szdyn\[dask\]"):
        sweep_command([str(spec), "--out", str(tmp_path / "o"), "--dask", "--quiet"])


def test_example_spec_is_valid():
    spec = load_spec(ROOT / "examples" / "sweep_example.toml")
    assert len(spec.cases) == 9 and spec.variables == ["k_c", "drive.a"]


def test_registered_cli_gives_one_line_errors(tmp_path, capsys):
    from szdyn import run

    spec = write_spec(tmp_path, BASE + "[axes]\nkc = [0.01]\n")
    assert run.main(["sweep", str(spec), "--out", str(tmp_path / "o"), "--quiet"]) == 2
    err = capsys.readouterr().err.strip()
    assert "did you mean 'k_c'" in err and len(err.splitlines()) == 1 and "Traceback" not in err
    good = write_spec(tmp_path, BASE + "[axes]\nk_c = [0.01]\n", name="good.toml")
    assert run.main(["sweep", str(good), "--out", str(tmp_path / "g"), "--workers", "1",
                     "--quiet"]) == 0
    assert read_table(tmp_path / "g")[0]["status"] == "ok"
