"""Tests of szdyn.drive against the generated drive_eval and against numerical integration."""
from __future__ import annotations

import numpy as np
import pytest
from scipy.integrate import cumulative_trapezoid

from szdyn.drive import (DRIVE_MODES, Ramp, RampHold, Sampled, Torque, Trapezoid,
                         array_to_knots, knots_to_array)
from szdyn_generated.spiral_zipper import drive_eval

_rng = np.random.default_rng(12345)
_T = np.sort(_rng.uniform(0.0, 3.0, 40))

PROFILES = [
    Ramp(a=20.0, t_end=1.5),
    Ramp(a=-3.0, t_end=0.2),
    RampHold(a=10.0, t_ramp=0.5, t_hold=1.0),
    RampHold(a=10.0, t_ramp=0.5, t_hold=0.0),
    Trapezoid(a=40.0, omega_max=20.0, t_hold=0.3),
    Trapezoid(a=40.0, omega_max=20.0, t_hold=0.0, a_down=10.0),
    Sampled(t=_T, omega=np.sin(3 * _T) * 10),
    Sampled(t=[0.3], omega=[7.0]),
    Torque(t=[0.0, 0.1, 0.4], torque=[0.0, 2e-3, -1e-3]),
]
IDS = [f"{type(pr).__name__}{i}" for i, pr in enumerate(PROFILES)]


@pytest.mark.parametrize("profile", PROFILES, ids=IDS)
def test_knots_array_round_trip(profile):
    t_k, v_k = profile.knots()
    drive = profile.to_array(angle0=0.25)
    K = t_k.size
    assert drive.shape == (1 + 3 * K,) and drive.dtype == np.float64 and drive[0] == K
    t2, v2, c2 = array_to_knots(drive)
    np.testing.assert_array_equal(t2, t_k)
    np.testing.assert_array_equal(v2, v_k)
    assert c2[0] == 0.25
    np.testing.assert_array_equal(knots_to_array(t2, v2, angle0=c2[0]), drive)
    assert np.all(np.diff(t_k) > 0)
    assert profile.drive_mode == DRIVE_MODES[profile.mode]


def test_profile_knots():
    np.testing.assert_allclose(np.column_stack(Ramp(2.0, 3.0).knots()), [[0, 0], [3, 6]])
    np.testing.assert_allclose(np.column_stack(RampHold(2.0, 3.0, 1.0).knots()),
                               [[0, 0], [3, 6], [4, 6]])
    np.testing.assert_allclose(np.column_stack(Trapezoid(2.0, 6.0, 1.0, a_down=3.0).knots()),
                               [[0, 0], [3, 6], [4, 6], [6, 0]])
    # a hold that rounding makes zero long is no hold (it once divided by zero, with a warning)
    for hold in (1e-300, 1e-17):
        np.testing.assert_array_equal(np.column_stack(RampHold(2.0, 3.0, hold).knots()), [[0, 0], [3, 6]])
        np.testing.assert_array_equal(np.column_stack(Trapezoid(2.0, 6.0, hold).knots()), [[0, 0], [3, 6], [6, 0]])
    assert Ramp(2.0, 3.0).mode == "speed" and Torque([0.0], [1.0]).mode == "torque"
    assert Torque([0.0], [1.0]).drive_mode == 1 and Sampled([0.0], [1.0]).drive_mode == 0


@pytest.mark.parametrize("profile", PROFILES, ids=IDS)
def test_drive_eval_matches_evaluate(profile):
    """Compiled drive_eval == NumPy reference at random times (also outside the knots), at the
    interior knots and at the last knot."""
    t_k, _ = profile.knots()
    lo, hi = t_k[0] - 0.5, t_k[-1] + 0.5
    ts = np.concatenate((_rng.uniform(lo, hi, 300), [lo, hi], t_k[1:]))
    drive = profile.to_array(angle0=-1.3)
    ref = np.array(profile.evaluate(ts, angle0=-1.3))
    got = np.array([drive_eval(drive, t) for t in ts]).T
    np.testing.assert_allclose(got, ref, rtol=1e-12, atol=1e-12)
    # scalar in -> floats out
    a, v, acc = profile.evaluate(float(ts[0]), angle0=-1.3)
    assert all(isinstance(z, float) for z in (a, v, acc))


def test_drive_eval_right_continuous_at_t0():
    """At t == t_0 the acceleration is the first segment's slope: an integration starting at the
    first knot (the thesis ramp starts at t = 0) must see it in its first stage, else the
    state's u_w is off by ~b_1*dt*a for the whole run."""
    drive = Ramp(a=20.0, t_end=1.0).to_array()
    assert drive_eval(drive, 0.0) == Ramp(a=20.0, t_end=1.0).evaluate(0.0) == (0.0, 0.0, 20.0)


@pytest.mark.parametrize("profile", PROFILES, ids=IDS)
def test_angle_is_integral_of_speed(profile):
    t_k, _ = profile.knots()
    # fine grid that contains the knots: the trapezoid rule is then exact for piecewise-linear v
    ts = np.union1d(np.linspace(t_k[0] - 0.3, t_k[-1] + 0.3, 4001), t_k)
    angle, speed, accel = profile.evaluate(ts, angle0=0.7)
    integral = cumulative_trapezoid(speed, ts, initial=0.0)
    i0 = np.searchsorted(ts, t_k[0])
    np.testing.assert_allclose(angle - angle[i0], integral - integral[i0], rtol=0,
                               atol=1e-10 * max(1.0, np.abs(integral).max()))
    assert angle[i0] == pytest.approx(0.7, abs=1e-15)
    # accel is the derivative of speed away from the knots
    # (skip the sub-microsecond intervals union1d creates next to knots: rounding dominates)
    ok = np.diff(ts) > 1e-6
    mid = 0.5 * (ts[1:] + ts[:-1])[ok]
    _, _, acc_mid = profile.evaluate(mid)
    np.testing.assert_allclose((np.diff(speed) / np.diff(ts))[ok], acc_mid, rtol=1e-6,
                               atol=1e-9 * max(1.0, np.abs(speed).max()))


@pytest.mark.parametrize("make, match", [
    (lambda: Ramp(a=1.0, t_end=0.0), r"Ramp: t_end must be > 0 s, got 0"),
    (lambda: Ramp(a=np.nan, t_end=1.0), r"Ramp: a must be finite"),
    (lambda: Ramp(a="fast", t_end=1.0), r"Ramp: a must be a real number"),
    (lambda: RampHold(a=1.0, t_ramp=-1, t_hold=1.0), r"RampHold: t_ramp must be > 0 s, got -1"),
    (lambda: RampHold(a=1.0, t_ramp=1.0, t_hold=-2.0), r"RampHold: t_hold must be >= 0 s"),
    (lambda: Trapezoid(a=0.0, omega_max=1.0, t_hold=0.0), r"Trapezoid: a must be > 0"),
    (lambda: Trapezoid(a=1.0, omega_max=-1.0, t_hold=0.0), r"Trapezoid: omega_max must be > 0"),
    (lambda: Trapezoid(a=1.0, omega_max=1.0, t_hold=0.0, a_down=-1), r"Trapezoid: a_down"),
    (lambda: Sampled(t=[], omega=[]), r"Sampled: t must have at least 1 sample"),
    (lambda: Sampled(t=[0, 1, 2], omega=[0, 1]), r"Sampled: t and omega must have the same "),
    (lambda: Sampled(t=[0, 1, 1], omega=[0, 1, 2]),
     r"Sampled: t must be strictly increasing.*index 2"),
    (lambda: Sampled(t=[0, np.inf], omega=[0, 1]), r"Sampled: t must be finite.*index 1"),
    (lambda: Sampled(t=[0, 1], omega=[0, np.nan]), r"Sampled: omega must be finite.*index 1"),
    (lambda: Sampled(t=[[0, 1]], omega=[[0, 1]]), r"Sampled: t and omega must be 1-D"),
    (lambda: Torque(t=[0, 2, 1], torque=[0, 1, 2]), r"Torque: t must be strictly increasing"),
    (lambda: Torque(t=[0, 1], torque=[0, np.nan]), r"Torque: torque must be finite"),
    (lambda: Ramp(1.0, 1.0).to_array(angle0=np.nan), r"Ramp: angle0 must be finite"),
    (lambda: array_to_knots([2.0, 0.0, 1.0]), r"drive"),
    # a ramp down that takes no time in floating point: a slope divided by zero before
    (lambda: Trapezoid(a=1e300, omega_max=3.0, t_hold=1.0),
     r"Trapezoid: the speed changes from 3 to 0 rad/s in no time at t = 1 s"),
])
def test_bad_inputs_name_the_argument(make, match):
    with pytest.raises(ValueError, match=match):
        make()


def test_sampled_is_immutable_copy():
    t = np.array([0.0, 1.0])
    s = Sampled(t=t, omega=[0.0, 2.0])
    t[1] = 5.0
    assert s.t[1] == 1.0
    with pytest.raises(ValueError):
        s.t[0] = 3.0
