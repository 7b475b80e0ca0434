"""Sensor/logger model: quantization, jitter, drops, effects, determinism, CSV round trip."""
from __future__ import annotations

import math

import numpy as np
import pytest

from szdyn.recordings import read_recording
from szdyn.sensors import EFFECTS, SensorError, SensorModel, apply_sensor, write_recording


def _truth(t_end=4.0, a=2.0, slip=0.1, h=1e-4):
    """Analytic truth: wheel ramp ``q_w = a t^2 / 2``, band at a constant slip ratio."""
    t = np.arange(0.0, t_end + h / 2, h)
    q_w = 0.5 * a * t ** 2
    return t, q_w, (1 - slip) * q_w


def test_quantization_step_and_error_bound():
    t, qw, qb = _truth()
    s = SensorModel(noise_counts_w=0.0, noise_counts_b=0.0)
    rec = apply_sensor(t, qw, qb, s, 0)
    for theta, step in ((rec.theta_w, s.step_w), (rec.theta_b, s.step_b)):
        counts = theta / step
        np.testing.assert_allclose(counts, np.round(counts), atol=1e-6)
        assert np.all(np.isin(np.diff(np.round(counts)), np.arange(0, 200)))
    latch = rec.meta["t_latch"]
    err_w = rec.theta_w - np.interp(latch, t, qw)
    err_b = rec.theta_b - np.interp(latch, t, qb)
    assert err_w.max() - err_w.min() <= s.step_w * (1 + 1e-9)
    assert err_b.max() - err_b.min() <= s.step_b * (1 + 1e-9)
    assert abs(rec.theta_w[0]) <= s.step_w * (1 + 1e-9)
    # with noise the values are still whole counts, and the spread grows only by the noise
    rec_n = apply_sensor(t, qw, qb, SensorModel(noise_counts_w=0.5), 0)
    c = rec_n.theta_w / SensorModel().step_w
    np.testing.assert_allclose(c, np.round(c), atol=1e-6)


def test_jitter_bounds_timestamps_and_drop_rate():
    t, qw, qb = _truth(t_end=40.0, h=1e-3)
    s = SensorModel(sample_period=2e-3, jitter=3e-4, drop_rate=0.05, timestamp_resolution=1e-6)
    rec = apply_sensor(t, qw, qb, s, 42)
    latch = rec.meta["t_latch"]
    n_nom = rec.meta["n_nominal"]
    nominal = np.round((latch - t[0]) / s.sample_period) * s.sample_period
    dev = latch - nominal
    assert np.all(np.abs(dev) <= s.jitter + 1e-12)
    assert dev.std() == pytest.approx(s.jitter / math.sqrt(3), rel=0.05)   # uniform +-jitter
    assert np.all(np.abs(rec.t - latch) <= s.timestamp_resolution / 2 + 1e-12)
    np.testing.assert_allclose(rec.t / 1e-6, np.round(rec.t / 1e-6), atol=1e-6)
    assert np.all(np.diff(rec.t) >= s.sample_period - 2 * s.jitter - s.timestamp_resolution)
    drop = 1 - len(rec) / n_nom
    sd = math.sqrt(0.05 * 0.95 / n_nom)
    assert abs(drop - 0.05) < 4 * sd
    assert rec.meta["n_dropped"] == n_nom - len(rec)


def test_log_delay_shifts_time_stamps_only():
    t, qw, qb = _truth()
    a = apply_sensor(t, qw, qb, SensorModel(), 5)
    b = apply_sensor(t, qw, qb, SensorModel(log_delay=0.004), 5)
    np.testing.assert_allclose(b.t - a.t, 0.004, atol=1.01e-6)
    np.testing.assert_array_equal(a.theta_w, b.theta_w)


def test_determinism_by_seed():
    t, qw, qb = _truth()
    a = apply_sensor(t, qw, qb, SensorModel(), 123)
    b = apply_sensor(t, qw, qb, SensorModel(), np.random.default_rng(123))
    c = apply_sensor(t, qw, qb, SensorModel(), 124)
    for k in ("t", "theta_w", "theta_b"):
        np.testing.assert_array_equal(getattr(a, k), getattr(b, k))
    assert len(a) != len(c) or not np.array_equal(a.t, c.t)


def test_effects_scale_and_delay():
    t, qw, qb = _truth(t_end=4.0, a=2.0)
    base = SensorModel(noise_counts_w=0.0, noise_counts_b=0.0)
    ref = apply_sensor(t, qw, qb, base, 1)
    sc = apply_sensor(t, qw, qb, base.with_effects(encoder_scale=1.02), 1)
    assert sc.theta_b[-1] / ref.theta_b[-1] == pytest.approx(1.02, rel=1e-3)
    np.testing.assert_array_equal(sc.theta_w, ref.theta_w)
    tau = 0.01
    de = apply_sensor(t, qw, qb, base.with_effects(encoder_delay=tau), 1)
    latch = de.meta["t_latch"]
    # theta_b(t) ~ q_b(t - tau) - q_b(-tau): lag = omega_b * tau (omega_b = 0.9 a t)
    lag = np.interp(latch, t, qb) - de.theta_b
    k = latch > 1.0
    expected = 0.9 * 2.0 * latch[k] * tau - 0.5 * 0.9 * 2.0 * tau ** 2
    assert np.max(np.abs(lag[k] - expected)) < 2 * base.step_b
    assert set(EFFECTS) == {"encoder_scale", "encoder_delay"}
    with pytest.raises(SensorError, match="unknown sensor effect 'encoder_gain'"):
        base.with_effects(encoder_gain=1.0)


def test_current_and_set_point_columns():
    t, qw, qb = _truth()
    s = SensorModel(torque_constant=0.05, current_noise=0.0)
    rec = apply_sensor(t, qw, qb, s, 0, omega_ref=lambda tt: 2.0 * tt,
                       motor_torque=np.full(t.shape, 0.01))
    np.testing.assert_allclose(rec.current, 0.2)
    np.testing.assert_allclose(rec.omega_ref, 2.0 * rec.meta["t_latch"])


def test_write_read_round_trip(tmp_path):
    t, qw, qb = _truth()
    rec = apply_sensor(t, qw, qb, SensorModel(torque_constant=0.05), 9,
                       omega_ref=lambda tt: 2.0 * tt, motor_torque=np.full(t.shape, 0.01))
    p = write_recording(tmp_path / "syn.csv", rec)
    back = read_recording(p)
    for k in ("t", "theta_w", "theta_b", "omega_ref", "current"):
        np.testing.assert_allclose(getattr(back, k), getattr(rec, k), rtol=1e-11, atol=1e-12)
    assert not list(tmp_path.glob(".*.tmp"))


@pytest.mark.parametrize("kw,field", [
    ({"cpr_w": 0}, "cpr_w"), ({"cpr_b": 10.5}, "cpr_b"), ({"sample_period": 0.0}, "sample_period"),
    ({"jitter": 0.0011}, "jitter"), ({"drop_rate": 1.0}, "drop_rate"),
    ({"encoder_scale_b": -1.0}, "encoder_scale_b"), ({"encoder_delay_b": float("nan")}, "encoder_delay_b"),
    ({"noise_counts_w": -0.1}, "noise_counts_w"), ({"torque_constant": 0.0}, "torque_constant"),
])
def test_invalid_settings_name_the_field(kw, field):
    with pytest.raises(SensorError, match=f"'{field}'"):
        SensorModel(**kw)


def test_record_run_from_simulation():
    from szdyn.defaults import default_parameters
    from szdyn.drive import RampHold
    from szdyn.sensors import record_run
    from szdyn.simulate import simulate

    run = simulate(default_parameters(16).replace(m_b=0.1), RampHold(a=2 * math.pi, t_ramp=0.3,
                   t_hold=0.2), 0.5, method="dopri5", save_dt=2e-4)
    rec = record_run(run, SensorModel(torque_constant=0.05), 3, name="r.csv",
                     conditions={"load_kg": 0.1})
    assert rec.omega_ref is not None and rec.current is not None
    assert rec.conditions == {"load_kg": 0.1}
    assert abs(rec.theta_b[-1] - (run.outputs["q_b"][-1] - run.outputs["q_b"][0])) < 0.05


def test_motor_torque_of_the_compliant_drive_is_what_turns_the_wheel():
    """drive_mode 2: the torque in the compliance equals I_W * dw_w/dt - wheel_reaction_torque
    (the wheel's own balance), smoothed like the diagnosis compares it."""
    from szdyn.defaults import default_parameters
    from szdyn.diagnose.engine import model_torque
    from szdyn.drive import RampHold
    from szdyn.sensors import motor_torque
    from szdyn.simulate import simulate

    p = default_parameters().replace(drive_mode=2.0, k_drive=20.0, c_drive=0.01)
    run = simulate(p, RampHold(a=6.0, t_ramp=0.5, t_hold=0.3), 0.8, method="rk4", dt=2e-5, save_dt=1e-4)
    o = run.outputs
    u_w = run.trajectory.x[:, p.n_circles + 2]
    balance = p["I_W"] * np.gradient(u_w, o["t"]) - o["wheel_reaction_torque"]
    tf = np.arange(0.1, 0.7, 0.05)
    spring, wheel = (model_torque(o["t"], y, tf) for y in (motor_torque(run), balance))
    assert np.abs(spring).max() > 0.02                         # N m: the band is being pushed
    # measured 2e-9 N m; I_W times the motor's (not the wheel's) acceleration, the speed drive's
    # formula, is 2.9e-6 N m off: small against the torque floor (~3e-3), but not the torque
    assert np.abs(spring - wheel).max() < 1e-5 * np.abs(spring).max()
