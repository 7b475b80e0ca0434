"""Recording reader (good and broken files), manifest, and comparison features."""
from __future__ import annotations

import math

import numpy as np
import pytest

from szdyn.errors import UserInputError
from szdyn.manifest import ManifestError, read_manifest
from szdyn.recordings import (RecordingError, Recording, compare_features, features,
                              read_recording, slip_per_revolution, slip_vs_speed, speeds, stroke)

GOOD = "t,theta_w,theta_b\n0.0,0.0,0.0\n0.01,0.1,0.09\n0.02,0.2,0.18\n0.035,0.35,0.3\n"


def _write(tmp_path, text, name="ramp1.csv"):
    p = tmp_path / name
    p.write_text(text, encoding="utf-8")
    return p


# --------------------------------------------------------------------------- good input
def test_reads_good_file_with_extras_comments_bom_and_uneven_sampling(tmp_path):
    text = ("\ufeff# logger v1.2\n t , theta_w,theta_b,omega_ref,current,temp\n\n"
            "0.0,0,0,0,0.1,20\n0.010,0.1,0.09,1,0.2,20\n# pause\n0.013,0.13,0.12,1,0.2,21\n"
            "0.050,0.5,0.45,1,0.2,21\n")
    rec = read_recording(_write(tmp_path, text), {"load_kg": 1.0})
    assert rec.name == "ramp1.csv" and len(rec) == 4
    np.testing.assert_allclose(rec.t, [0, 0.01, 0.013, 0.05])
    np.testing.assert_allclose(rec.theta_b, [0, 0.09, 0.12, 0.45])
    assert rec.omega_ref is not None and rec.current is not None
    assert rec.extra_columns == ("temp",)
    assert any("temp" in n for n in rec.notes)
    assert rec.conditions == {"load_kg": 1.0}
    assert rec.sampling()["n_gaps"] == 1


def test_exact_duplicate_rows_are_dropped_with_a_note(tmp_path):
    text = "t,theta_w,theta_b\n0,0,0\n0.01,0.1,0.1\n0.01,0.1,0.1\n0.02,0.2,0.2\n"
    rec = read_recording(_write(tmp_path, text))
    assert len(rec) == 3
    assert any("duplicate" in n and "line 4" in n for n in rec.notes)


# --------------------------------------------------------------------------- broken input
BROKEN = [
    ("t,theta_w,theta_b\n0,0,0\n0.1,0.1,abc\n", 3, "theta_b", "expected a number, got 'abc'"),
    ("t,theta_w,theta_b\n0,0,0\n0.1,nan,0.1\n", 3, "theta_w", "non-finite"),
    ("t,theta_w,theta_b\n0,0,0\n0.1,0.1,-inf\n", 3, "theta_b", "non-finite"),
    ("t,theta_w,theta_b\n0,0,0\n0.53,0.1,0.1\n0.52,0.2,0.2\n", 4, "t",
     "time goes backwards (0.52 s after 0.53 s on line 3)"),
    ("t,theta_w,theta_b\n0,0,0\n0.1,0.1,0.1\n0.1,0.2,0.2\n", 4, "t", "time not increasing"),
    ("t,theta_w,theta_b\n0,0,0\n0.1,0.1\n", 3, "theta_b", "missing value"),
    ("t,theta_w,theta_b\n0,0,0\n0.1,,0.1\n", 3, "theta_w", "empty cell"),
    ("t,theta_w\n0,0\n0.1,0.1\n", 1, None, "missing required column 'theta_b' (found: t, theta_w)"),
    ("t,theta_w,theta_b,t\n0,0,0,0\n", 1, None, "appears twice"),
    ("t,theta_w,theta_b\n0,0,0\n0.1,0.1,0.1,7\n", 3, None, "extra value"),
    # float() reads these as 10 and 12; no logger writes them
    ("t,theta_w,theta_b\n0,0,0\n0.1,1_0,0.1\n", 3, "theta_w", "expected a number, got '1_0'"),
    ("t,theta_w,theta_b\n0,0,0\n0.1,0.1,\u0661\u0662\n", 3, "theta_b", "expected a number"),
    ("t;theta_w;theta_b\n0;0;0\n", 1, None, "one field holding semicolons"),
    ("t\ttheta_w\ttheta_b\n0\t0\t0\n", 1, None, "one field holding tabs"),
    # a mistyped time (1 ms sampling, then 1000 s): the model would be run over the gap
    ("t,theta_w,theta_b\n0,0,0\n0.001,0,0\n0.002,0,0\n1000,0,0\n", 5, "t",
     "time jumps by 999.998 s (from 0.002 s on line 4 to 1000 s)"),
    # 10 s sampling, then 10001 s: over GAP_MIN_S, and 1000 median intervals exactly is not over
    ("t,theta_w,theta_b\n0,0,0\n10,0,0\n20,0,0\n10020.5,0,0\n", 5, "t", "1000 times the median"),
    ("t,theta_w,theta_b\n0,0,0\n10,0,0\n20,0,0\n1e300,0,0\n", 5, "t", "1e+299 times the median"),
    # a corrupted angle: 1e300 rad in 1 ms
    ("t,theta_w,theta_b\n0,0,0\n0.001,0,0\n0.002,0,1e300\n", 4, "theta_b", "angle jumps by 1e+300 rad"),
    ("t,theta_w,theta_b,omega_ref\n0,0,0,0\n0.001,0,0,3e7\n", 3, "omega_ref", "speed set-point 3e+07"),
]


def test_gaps_and_speeds_a_logger_writes_are_accepted(tmp_path):
    """The plausibility limits leave real logs alone: a 5 s standstill of a 1 kHz logger that
    writes only on change (5000 intervals, but under GAP_MIN_S), 10 s sampling with a 9.9 ks gap
    (under 1000 intervals), and a motor encoder at 800 rad/s whose row 50 is stamped 1 us after
    row 49 with a whole interval's motion (0.8 rad in 1 us: 8e5 rad/s over the step alone)."""
    t = np.concatenate([np.arange(0, 1, 1e-3), np.arange(6, 6.5, 1e-3)])
    text = "t,theta_w,theta_b\n" + "".join(f"{v:.6f},{3 * v:.6f},{2.9 * v:.6f}\n" for v in t)
    assert len(read_recording(_write(tmp_path, text))) == t.size
    text = "t,theta_w,theta_b\n0,0,0\n10,0,0\n20,0,0\n9900,0,0\n"
    assert len(read_recording(_write(tmp_path, text))) == 4
    t = np.arange(0, 0.1, 1e-3)
    stamp = t.copy()
    stamp[50] = t[49] + 1e-6
    text = "t,theta_w,theta_b\n" + "".join(f"{s:.6f},{800 * v:.6f},0\n" for s, v in zip(stamp, t))
    assert len(read_recording(_write(tmp_path, text))) == t.size


def _ramp(band=lambda w: 0.9 * w, wheel=lambda w: w, ref=lambda v: v):
    """A 2 s ramp to 3 rad/s and back as a logger writes it: wheel angle, band angle and
    set-point (rad, rad/s), each passed through the given function (a unit mistake)."""
    t = np.arange(0, 2, 2e-3)
    v = 3.0 * np.minimum(t, 2 - t)
    th = np.concatenate([[0.0], np.cumsum(0.5 * (v[1:] + v[:-1]) * np.diff(t))])
    return "t,theta_w,theta_b,omega_ref\n" + "".join(
        f"{a:.4f},{wheel(b):.6f},{band(b):.6f},{ref(c):.6f}\n" for a, b, c in zip(t, th, v))


@pytest.mark.parametrize("mistake,column,msg", [
    ({"band": lambda w: math.degrees(0.9 * w)}, "theta_b", "is theta_b in degrees?"),
    # heavy slip: the band at half the wheel's speed, in degrees, travels 28.6x the wheel
    ({"band": lambda w: math.degrees(0.5 * w)}, "theta_b", "28.6 times theta_w's travel"),
    ({"band": math.degrees, "wheel": math.degrees}, "theta_w", "are the angles in degrees, or is theta_w read before"),
])
def test_angles_in_degrees_are_refused_naming_the_column(tmp_path, mistake, column, msg):
    with pytest.raises(RecordingError) as ei:
        read_recording(_write(tmp_path, _ramp(**mistake)))
    assert ei.value.column == column and msg in str(ei.value), str(ei.value)
    assert "Angles must be in rad and omega_ref in rad/s" in str(ei.value)


def test_slip_stalls_and_small_moves_pass_the_units_check(tmp_path):
    """The check leaves physics alone: a band at a tenth of the wheel (heavy slip), a wheel at a
    fortieth of its set-point (a stalled drive: the ratio of degrees, the other way round), a
    wheel in revolutions (6.3x, not 57x: the diagnosis's fit shows that one), and degrees over a
    wheel travel of 0.1 rad, under the 0.5 rad the check needs."""
    for kw in ({"band": lambda w: 0.1 * w}, {"band": lambda w: w / 40, "wheel": lambda w: w / 40},
               {"wheel": lambda w: w / (2 * math.pi), "band": lambda w: 0.9 * w / (2 * math.pi)}):
        assert len(read_recording(_write(tmp_path, _ramp(**kw)))) == 1000
    tiny = _ramp(band=lambda w: math.degrees(w) * 0.1 / 3, wheel=lambda w: w * 0.1 / 3,
                 ref=lambda v: v * 0.1 / 3)
    assert len(read_recording(_write(tmp_path, tiny))) == 1000


@pytest.mark.parametrize("text,line,column,msg", BROKEN)
def test_broken_file_names_file_line_and_column(tmp_path, text, line, column, msg):
    with pytest.raises(RecordingError) as ei:
        read_recording(_write(tmp_path, text))
    s = str(ei.value)
    assert s.startswith("ramp1.csv, ")
    assert f"line {line}" in s and ei.value.line == line
    if column:
        assert f"column '{column}'" in s and ei.value.column == column
    assert msg in s
    assert isinstance(ei.value, UserInputError)


def test_a_utf16_file_without_a_byte_order_mark_is_named_as_such(tmp_path):
    """Read as UTF-8, each character comes with a NUL: it once said the 't' column was missing."""
    p = tmp_path / "ramp1.csv"
    p.write_bytes("t,theta_w,theta_b\n0,0,0\n0.1,1,1\n".encode("utf-16-le"))
    with pytest.raises(RecordingError, match=r"^ramp1.csv, line 1: NUL bytes in the header: a UTF-16 "):
        read_recording(p)


@pytest.mark.parametrize("text", ["", "\n\n", "t,theta_w,theta_b\n", "# only a comment\n"])
def test_empty_file(tmp_path, text):
    with pytest.raises(RecordingError, match=r"ramp1\.csv: empty file \(no data rows\)"):
        read_recording(_write(tmp_path, text))


def test_single_row_and_missing_file(tmp_path):
    with pytest.raises(RecordingError, match="only one data row"):
        read_recording(_write(tmp_path, "t,theta_w,theta_b\n0,0,0\n"))
    with pytest.raises(RecordingError, match="nope.csv: file not found"):
        read_recording(tmp_path / "nope.csv")


def test_random_corruptions_are_located(tmp_path):
    """Property test: one corrupted cell anywhere in a valid file is reported at its place."""
    rng = np.random.default_rng(7)
    bad_tokens = ["abc", "nan", "NaN", "inf", "", "1.2.3", "0x10", "--1", "1e", "None"]
    cols = ["t", "theta_w", "theta_b", "omega_ref"]
    for trial in range(60):
        n = int(rng.integers(3, 40))
        t = np.cumsum(rng.uniform(1e-3, 3e-3, n))
        data = np.column_stack([t, np.cumsum(rng.normal(size=n)), np.cumsum(rng.normal(size=n)),
                                rng.normal(size=n)])
        rows = [[f"{v:.6g}" for v in row] for row in data]
        i, j = int(rng.integers(n)), int(rng.integers(4))
        tok = bad_tokens[int(rng.integers(len(bad_tokens)))]
        rows[i][j] = tok
        text = ",".join(cols) + "\n" + "\n".join(",".join(r) for r in rows) + "\n"
        with pytest.raises(RecordingError) as ei:
            read_recording(_write(tmp_path, text, f"c{trial}.csv"))
        assert ei.value.line == i + 2, (tok, str(ei.value))
        assert ei.value.column == cols[j], (tok, str(ei.value))
        assert str(ei.value).startswith(f"c{trial}.csv, line {i + 2}, column '{cols[j]}'")


def test_time_backwards_anywhere(tmp_path):
    rng = np.random.default_rng(3)
    for trial in range(30):
        n = int(rng.integers(3, 30))
        t = list(np.round(np.cumsum(rng.uniform(1e-3, 3e-3, n)), 6))
        i = int(rng.integers(1, n))
        t[i] = t[i - 1] - 1e-4
        text = "t,theta_w,theta_b\n" + "".join(f"{v},{k},{k}\n" for k, v in enumerate(t))
        with pytest.raises(RecordingError, match="time goes backwards") as ei:
            read_recording(_write(tmp_path, text))
        assert ei.value.line == i + 2 and ei.value.column == "t"


# --------------------------------------------------------------------------- manifest
def test_manifest_good(tmp_path):
    for f in ("ramp1.csv", "ramp2.csv", "ramp3.csv"):
        _write(tmp_path, GOOD, f)
    m = tmp_path / "exp.toml"
    m.write_text('[model]\nmu_k = 0.25\nn_rollers = 8\n[split]\nheldout = ["ramp3.csv"]\n'
                 '[[recording]]\nfile = "ramp1.csv"\nload_kg = 1.0\nn_circles = 16\nnote = "a"\n'
                 '[[recording]]\nfile = "ramp2.csv"\nload_kg = 0.5\n'
                 '[[recording]]\nfile = "ramp3.csv"\n')
    man = read_manifest(m)
    assert [e.name for e in man.training()] == ["ramp1.csv", "ramp2.csv"]
    assert [e.name for e in man.validation()] == ["ramp3.csv"]
    assert man.model == {"mu_k": 0.25, "n_rollers": 8.0}
    e = man.entries[0]
    ps = man.parameters(e)
    assert ps.n_circles == 16 and ps["m_b"] == 1.0 and ps["mu_k"] == 0.25
    rec = e.read()
    assert rec.conditions["load_kg"] == 1.0 and len(rec) == 4


def test_manifest_fraction_split_is_deterministic(tmp_path):
    names = [f"r{i}.csv" for i in range(8)]
    for f in names:
        _write(tmp_path, GOOD, f)
    body = "".join(f'[[recording]]\nfile = "{f}"\n' for f in names)
    m = tmp_path / "m.toml"
    m.write_text("[split]\nheldout = 0.25\nseed = 3\n" + body)
    a, b = read_manifest(m), read_manifest(m)
    assert len(a.heldout) == 2 and a.heldout == b.heldout


def test_manifest_torque_constant_from_motor_table_and_per_recording(tmp_path):
    """``[motor] torque_constant`` applies to every recording unless one gives its own."""
    for f in ("a.csv", "b.csv", "c.csv"):
        _write(tmp_path, GOOD, f)
    m = tmp_path / "m.toml"
    m.write_text('[motor]\ntorque_constant = 0.05\n[[recording]]\nfile = "a.csv"\n'
                 '[[recording]]\nfile = "b.csv"\ntorque_constant = 0.08\n')
    assert [e.torque_constant for e in read_manifest(m).entries] == [0.05, 0.08]
    m.write_text('[[recording]]\nfile = "a.csv"\n[[recording]]\nfile = "c.csv"\ntorque_constant = 2\n')
    assert [e.torque_constant for e in read_manifest(m).entries] == [None, 2.0]


MANIFEST_ERRORS = [
    ('[motor]\ntorque_constant = 0\n[[recording]]\nfile = "ramp1.csv"\n',
     "[motor]: 'torque_constant' must be a number > 0 (N m/A)"),
    ('[motor]\ntorque_const = 0.1\n[[recording]]\nfile = "ramp1.csv"\n',
     "unknown key 'torque_const' (did you mean 'torque_constant'?)"),
    ('[[recording]]\nfile = "ramp1.csv"\ntorque_constant = "0.05"\n',
     "[[recording]] 1 ('ramp1.csv'): 'torque_constant' must be a number > 0 (N m/A)"),
    ('motor = 0.05\n[[recording]]\nfile = "ramp1.csv"\n', "'motor' must be a table ([motor])"),
    ('[model]\ntorque_constant = 0.05\n[[recording]]\nfile = "ramp1.csv"\n',
     "torque constant goes in [motor]"),
    ('[[recording]]\nfile = "ramp1.csv"\nload_k = 1.0\n', "unknown key 'load_k' (did you mean 'load_kg'?)"),
    ('[[recording]]\nfile = "ramp1.csv"\nload_kg = "heavy"\n', "'load_kg' must be a number > 0"),
    ('[[recording]]\nfile = "ramp1.csv"\nn_circles = 1.5\n', "'n_circles' must be a positive integer"),
    ('[[recording]]\nfile = "ramp1.csv"\nn_circles = 100000000\n', "'n_circles' must be a positive integer up to 10000"),
    ('[[recording]]\nload_kg = 1.0\n', "missing key 'file'"),
    ('[[recording]]\nfile = "missing.csv"\n', "recording file not found"),
    ('[model]\nmu_kk = 0.3\n[[recording]]\nfile = "ramp1.csv"\n', "unknown parameter 'mu_kk' (did you mean 'mu_k'?)"),
    ('[model]\nmu_k = "0.3"\n[[recording]]\nfile = "ramp1.csv"\n', "parameter 'mu_k' must be a finite number"),
    ('[model]\nmu_k = true\n[[recording]]\nfile = "ramp1.csv"\n', "parameter 'mu_k' must be a finite number"),
    ('[modle]\nmu_k = 0.3\n[[recording]]\nfile = "ramp1.csv"\n', "unknown table or key 'modle' (did you mean 'model'?)"),
    ('[split]\nheldout = ["ramp9.csv"]\n[[recording]]\nfile = "ramp1.csv"\n', "heldout file 'ramp9.csv'"),
    ('[split]\nheldout = ["ramp1.csv"]\n[[recording]]\nfile = "ramp1.csv"\n', "every recording is held out"),
    ('[split]\nheld = 0.5\n[[recording]]\nfile = "ramp1.csv"\n', "unknown key 'held' (did you mean 'heldout'?)"),
    ('[split]\nheldout = 1.5\n[[recording]]\nfile = "ramp1.csv"\n', "fraction must be in [0, 1)"),
    ('[[recording]]\nfile = "ramp1.csv"\n[[recording]]\nfile = "ramp1.csv"\n', "listed twice"),
    ('[[recording]]\nfile = "ramp1.csv"\n[[recording]]\nfile = "./ramp1.csv"\n',
     "'./ramp1.csv' is the same file as 'ramp1.csv' ([[recording]] 1 and 2)"),
    ('[[recording]]\nfile = "."\n', "is a directory, expected a CSV file"),
    # names the system refuses, a device that is no file, a load beyond a float's range
    ('[[recording]]\nfile = "' + "x" * 300 + '.csv"\n', "'file' is not a usable path (["),
    ('[[recording]]\nfile = "a\\u0000.csv"\n', "'file' is not a usable path (embedded null byte)"),
    ('[[recording]]\nfile = "/dev/null"\n', "not a regular file: /dev/null"),
    ('[[recording]]\nfile = "ramp1.csv"\nload_kg = 1' + "0" * 400 + '\n',
     "'load_kg' must be a number > 0 (kg), got 100000... (an integer of 401 digits)"),
    ('[split]\nheldout = []\n[[recording]]\nfile = "ramp1.csv"\n', "holds out no recording"),
    ('[split]\nheldout = 0\n[[recording]]\nfile = "ramp1.csv"\n', "holds out no recording"),
    # a seed draws only a fractional heldout: beside a list, or alone, it would be silently ignored
    ('[split]\nseed = 3\n[[recording]]\nfile = "ramp1.csv"\n', "with no 'heldout' it would do nothing"),
    ('[split]\nheldout = ["ramp1.csv"]\nseed = 3\n[[recording]]\nfile = "ramp1.csv"\n',
     "with a list of files it would do nothing"),
    ('[model]\nm_b = 2.0\n[[recording]]\nfile = "ramp1.csv"\nload_kg = 1.0\n',
     "[model]: 'm_b' is the load, which 'load_kg' sets in every [[recording]]"),
    # values checked when read, naming the table (not at the recording's turn in a diagnosis)
    ('[model]\nmu_k = -0.3\n[[recording]]\nfile = "ramp1.csv"\n', "[model]: parameter 'mu_k' must be >= 0"),
    ('[model]\nn_rollers = 2.5\n[[recording]]\nfile = "ramp1.csv"\n', "[model]: parameter 'n_rollers'"),
    ('[model]\nmu_s = 0.1\nmu_k = 0.2\n[[recording]]\nfile = "ramp1.csv"\n', "[model]: parameter 'mu_k' must be <= mu_s"),
    ('[model]\nmu_k = \n', "invalid TOML"),
    ('', "no recordings"),
]


@pytest.mark.parametrize("text,msg", MANIFEST_ERRORS)
def test_manifest_errors(tmp_path, text, msg):
    _write(tmp_path, GOOD)
    m = tmp_path / "exp.toml"
    m.write_text(text)
    with pytest.raises(ManifestError) as ei:
        read_manifest(m)
    assert str(ei.value).startswith(str(m))   # the path as given (which of several manifests)
    assert msg in str(ei.value)
    assert isinstance(ei.value, UserInputError)


def test_manifest_with_a_byte_order_mark_and_m_b_for_the_recordings_without_a_load(tmp_path):
    _write(tmp_path, GOOD)
    _write(tmp_path, GOOD, "ramp2.csv")
    m = tmp_path / "exp.toml"
    m.write_bytes(b"\xef\xbb\xbf" + b'[model]\nm_b = 2.0\n[[recording]]\nfile = "ramp1.csv"\n'
                  b'[[recording]]\nfile = "ramp2.csv"\nload_kg = 1.0\n')
    man = read_manifest(m)
    assert man.model == {"m_b": 2.0}
    assert [man.parameters(e)["m_b"] for e in man.entries] == [2.0, 1.0]


def test_a_split_table_without_heldout_leaves_the_choice_to_szdyn(tmp_path):
    _write(tmp_path, GOOD)
    _write(tmp_path, GOOD, "ramp2.csv")
    m = tmp_path / "exp.toml"
    m.write_text('[split]\n[[recording]]\nfile = "ramp1.csv"\n[[recording]]\nfile = "ramp2.csv"\n')
    assert read_manifest(m).heldout == ()
    # a fraction of few recordings holds out at least one
    m.write_text('[split]\nheldout = 0.25\n[[recording]]\nfile = "ramp1.csv"\n'
                 '[[recording]]\nfile = "ramp2.csv"\n')
    assert len(read_manifest(m).heldout) == 1


# --------------------------------------------------------------------------- features
def test_features_on_analytic_recording():
    """Constant slip ratio 10 % on a ramp: every feature has a closed form."""
    a, s = 4 * math.pi, 0.1
    t = np.arange(0, 2.0, 1e-3)
    tw = 0.5 * a * t ** 2
    rec = Recording("x", t, tw, (1 - s) * tw)
    tt, ww, wb = speeds(rec, 0.05)
    np.testing.assert_allclose(ww, a * tt, atol=1e-9)
    np.testing.assert_allclose(wb, (1 - s) * a * tt, atol=1e-9)
    spr = slip_per_revolution(rec.t, rec.theta_w, rec.theta_b)
    assert spr["slip"].size == int(tw[-1] / (2 * math.pi))
    np.testing.assert_allclose(spr["slip"], 2 * math.pi * s, rtol=1e-6)
    svs = slip_vs_speed(tt, ww, wb, 5)
    np.testing.assert_allclose(svs["slip_ratio"], s, rtol=1e-6)
    _, st, lost = stroke(rec.t, rec.theta_w, rec.theta_b, 0.04)
    np.testing.assert_allclose(lost[-1], 0.04 * s * tw[-1] / (2 * math.pi))
    # reversed direction: same slip magnitudes, positive = band lags
    rev = slip_per_revolution(t, -tw, -(1 - s) * tw)
    np.testing.assert_allclose(rev["slip"], spr["slip"])
    assert np.all(rev["omega_w"] < 0)


@pytest.fixture(scope="module")
def sim_run():
    from szdyn.defaults import default_parameters
    from szdyn.drive import RampHold
    from szdyn.simulate import simulate

    params = default_parameters(16).replace(m_b=0.3)
    return simulate(params, RampHold(a=4 * math.pi, t_ramp=0.75, t_hold=0.75), 1.5,
                    method="dopri5", save_dt=2e-4)


def test_features_on_simulated_recording(sim_run):
    from szdyn.sensors import SensorModel, record_run, truth_recording

    o = sim_run.outputs
    pitch = sim_run.params.geometry.pitch
    truth = truth_recording(sim_run)
    ft = features(truth, pitch)
    # stroke equals the simulator's own output
    np.testing.assert_allclose(ft["stroke"], o["stroke"], atol=1e-12)
    np.testing.assert_allclose(ft["stroke_lost"], o["stroke_lost"], atol=1e-12)
    # smoothed speeds carry the band's motion: their integral is the band angle travelled
    tt = ft["t"]
    k = (tt > 0.2) & (tt < 1.3)
    dq = np.interp(tt[k][-1], o["t"], o["q_b"]) - np.interp(tt[k][0], o["t"], o["q_b"])
    integral = np.trapezoid(ft["omega_b"][k], tt[k])
    assert abs(integral - dq) < 0.02 * abs(dq) + 0.01
    # slip per revolution is the angle difference at the revolution crossings
    spr = ft["slip_per_rev"]
    assert spr["slip"].size >= 1
    qw, qb = o["q_w"] - o["q_w"][0], o["q_b"] - o["q_b"][0]
    exp = [(np.interp(t1, o["t"], qw) - np.interp(t0, o["t"], qw))
           - (np.interp(t1, o["t"], qb) - np.interp(t0, o["t"], qb))
           for t0, t1 in zip(spr["t0"], spr["t1"])]
    np.testing.assert_allclose(spr["slip"], exp, atol=1e-6)
    # a realistic recording of the same run: features agree to sensor accuracy
    rec = record_run(sim_run, SensorModel(), 11)
    fm = features(rec, pitch, speed_bins=ft["slip_vs_speed"]["edges"])
    cmp = compare_features(fm, ft)
    assert cmp["slip_per_rev_rms"]["value"] < 0.02            # ~ a few encoder counts
    assert cmp["rel_speed_rms"]["value"] < 0.1
    assert abs(cmp["final_stroke_lost_diff"]["value"]) < 1e-4
    assert all(isinstance(v["compared"], str) and v["compared"] for v in cmp.values())
    # the band-encoder delay effect (apparent stroke lag omega_b * tau) stands out
    fd = features(record_run(sim_run, SensorModel().with_effects(encoder_delay=0.02), 11), pitch,
                  speed_bins=ft["slip_vs_speed"]["edges"])
    assert compare_features(fd, ft)["stroke_rms"]["value"] > 3 * cmp["stroke_rms"]["value"]


def test_speed_window_too_long():
    rec = Recording("short", np.arange(5) * 1e-3, np.zeros(5), np.zeros(5))
    with pytest.raises(UserInputError, match="too short"):
        speeds(rec, 0.5)
