"""Physics checks of the whole model through the runtime: conservation laws and limiting cases."""
from __future__ import annotations

import math

import numpy as np
import pytest

from szdyn.defaults import default_parameters
from szdyn.drive import Ramp, RampHold, Torque
from szdyn.integrators import integrate
from szdyn_generated import spiral_zipper as sz

NC = 16  # a multiple of the 8 rollers keeps the start symmetric; small for speed


def _free(**changes):
    """Torque-driven (free) wheel with zero motor torque: nothing does work from outside."""
    params = default_parameters(n_circles=NC).replace(drive_mode=1, **changes)
    return params, params.to_array(), Torque(t=[0.0], torque=[0.0]).to_array()


def _spinning_state(params, rng, u_w=3.0):
    x = params.initial_state()
    n = NC + 2
    x[2:n] += rng.uniform(-0.05, 0.05, NC)  # arms deflected
    x[n] = u_w
    x[n + 1] = 0.5
    x[n + 2:2 * n] = x[n + 1] + rng.uniform(-1, 1, NC)
    return x


def _energies(traj, p):
    return np.array([sz.energy(x, p) for x in traj.x])


@pytest.mark.parametrize("contact", ["off", "conservative"])
def test_energy_conserved_without_dissipation(contact):
    """b_c = 0, no slider friction; contacts either out of reach or purely elastic (b_imp = 0)."""
    rng = np.random.default_rng(1)
    base = default_parameters(n_circles=NC)
    reach = {"off": dict(R_w=base.values["R_w"] - 1e-3), "conservative": dict(b_imp=0.0)}[contact]
    params, p, drive = _free(b_c=0.0, mu_s=0.0, mu_k=0.0, **reach)
    x0 = _spinning_state(params, rng)
    traj = integrate(x0, p, drive, 1.0, method="rk4", dt=2e-6, save_dt=1e-3)
    E = _energies(traj, p)
    drift = np.abs(E - E[0]).max() / E[0]
    assert drift < 1e-6, drift
    if contact == "conservative":
        contacts = [sz.contact_count(t, x, p, drive) for t, x in zip(traj.t, traj.x)]
        assert max(contacts) > 0  # the elastic contact force was really exercised
        assert np.ptp(traj.x[:, NC + 2]) > 0.1  # and exchanged momentum with the wheel


def test_energy_never_increases_with_damping():
    rng = np.random.default_rng(2)
    params, p, drive = _free()  # default damping, impact damping and slider friction
    x0 = _spinning_state(params, rng)
    traj = integrate(x0, p, drive, 0.5, method="dopri5", rtol=1e-9, atol=1e-12, save_dt=1e-4)
    E = _energies(traj, p)
    increase = np.diff(E).max() / E[0]
    assert increase < 1e-9, increase
    assert E[-1] < 0.9 * E[0]  # and it really dissipates


def test_angular_momentum_of_band_and_circles_is_conserved_by_internal_forces():
    """Without slider friction or contact, arm springs and dampers are internal: the total
    angular momentum of band + circles about the tube axis is constant."""
    rng = np.random.default_rng(3)
    base = default_parameters(n_circles=NC)
    # A light band (I_B ~ the circles' inertia) so that the exchange is large.
    params, p, drive = _free(mu_s=0.0, mu_k=0.0, R_w=base.values["R_w"] - 1e-3, I_B=2e-5)
    x0 = _spinning_state(params, rng)
    traj = integrate(x0, p, drive, 0.2, method="dopri5", rtol=1e-10, atol=1e-12, save_dt=1e-3)
    n = NC + 2

    def momentum(x):
        M, _ = sz.mass_matrix_forcing(0.0, x, p, drive)
        return (M[1:, 1:] @ x[n + 1:2 * n]).sum()  # sum of generalized momenta conjugate to q_b, q_i

    H = np.array([momentum(x) for x in traj.x])
    assert np.abs(H - H[0]).max() < 1e-8 * np.abs(H).max()
    # ...while the band speed itself changes (the test is not trivially static).
    assert np.ptp(traj.x[:, n + 1]) > 1e-2


def test_prescribed_drive_overrides_the_wheel_state():
    """With a prescribed drive the wheel's angle and speed come from the profile, not from the
    state's copy (which carries integration error at the profile's kinks): perturbing that
    copy changes nothing, and the wheel rows of dx/dt are the profile's speed and acceleration."""
    rng = np.random.default_rng(4)
    params = default_parameters(n_circles=NC).replace(drive_mode=0)
    p = params.to_array()
    drive = RampHold(a=0.5 * math.pi, t_ramp=0.4, t_hold=0.2)
    x = _spinning_state(params, rng)
    arr = drive.to_array(angle0=x[0])
    n = NC + 2
    for t in (0.0, 0.1, 0.39, 0.4, 0.55):
        out1, out2 = np.empty_like(x), np.empty_like(x)
        sz.rhs(t, x, p, arr, out1)
        y = x.copy()
        y[0] += 0.3
        y[n] -= 1.0
        sz.rhs(t, y, p, arr, out2)
        np.testing.assert_array_equal(out1, out2)
        angle, speed, accel = drive.evaluate(t, angle0=x[0])
        assert out1[0] == pytest.approx(speed, abs=1e-15) and out1[n] == pytest.approx(accel, abs=1e-15)


def test_simulated_wheel_follows_the_profile():
    from szdyn.simulate import simulate

    params = default_parameters(n_circles=NC)
    drive = RampHold(a=0.5 * math.pi, t_ramp=0.4, t_hold=0.2)
    run = simulate(params, drive, 0.6, method="rk4", dt=1e-5)
    angle, speed, _ = drive.evaluate(run.outputs["t"], angle0=params.initial_state()[0])
    np.testing.assert_array_equal(run.outputs["u_w"], speed)
    np.testing.assert_array_equal(run.outputs["q_w"], angle)
    # the state's shadow copy stays within O(a dt) of the profile
    assert np.abs(run.trajectory.x[:, NC + 2] - speed).max() < 0.5 * math.pi * 1e-5


def test_slider_friction_decelerates_a_free_band_at_the_kinetic_rate():
    """No contact, arms at rest and moving with the band: a rigid band sliding faster than
    1.5 gamma decelerates at R_bo mu_k m_b g / (I_B + N_c m_c (R_bo - d)^2)."""
    base = default_parameters(n_circles=NC)
    params, p, drive = _free(R_w=base.values["R_w"] - 1e-3, k_c=50.0)  # stiff arms: near rigid
    v = params.values
    x0 = params.initial_state()
    n = NC + 2
    x0[n + 1:2 * n] = 2.0
    traj = integrate(x0, p, drive, 0.01, method="dopri5", rtol=1e-10, atol=1e-12, save_dt=1e-3)
    assert traj.x[-1, n + 1] > 1.5 * v["gamma"]  # still in the kinetic branch
    decel = -(traj.x[-1, n + 1] - traj.x[0, n + 1]) / 0.01
    inertia = v["I_B"] + NC * v["m_c"] * (v["R_bo"] - v["d"]) ** 2
    expected = v["R_bo"] * v["mu_k"] * v["m_b"] * v["g"] / inertia
    assert decel == pytest.approx(expected, rel=1e-3)


def test_no_contact_means_band_does_not_move():
    """Rollers out of reach: a prescribed wheel cannot move the band (transmission is by
    impacts only in this model)."""
    base = default_parameters(n_circles=NC)
    params = base.replace(R_w=base.values["R_w"] - 1e-3, drive_mode=0)
    drive = Ramp(a=math.pi, t_end=0.3).to_array(angle0=params.initial_state()[0])
    traj = integrate(params.initial_state(), params.to_array(), drive, 0.3, method="rk4", dt=1e-5, save_dt=1e-3)
    assert np.abs(traj.x[:, NC + 3]).max() == 0.0


def test_compliant_drive_is_the_torque_drive_with_the_coupling_torque():
    """drive_mode 2: the drive prescribes the motor; the wheel feels k_drive (motor - wheel angle)
    + c_drive (motor - wheel speed) as its motor torque, nothing else changes."""
    rng = np.random.default_rng(9)
    params = default_parameters(n_circles=NC)
    x = _spinning_state(params, rng)
    n = NC + 2
    motor = RampHold(a=2.0, t_ramp=1.0, t_hold=1.0)
    arr = motor.to_array(angle0=0.1)
    for t in (0.0, 0.3, 1.5):
        angle, speed, _ = motor.evaluate(t, angle0=0.1)
        v = params.values
        torque = v["k_drive"] * (angle - x[0]) + v["c_drive"] * (speed - x[n])
        out2, out1 = np.empty_like(x), np.empty_like(x)
        sz.rhs(t, x, params.replace(drive_mode=2).to_array(), arr, out2)
        sz.rhs(t, x, params.replace(drive_mode=1).to_array(), Torque(t=[0.0], torque=[torque]).to_array(), out1)
        np.testing.assert_allclose(out2, out1, rtol=1e-12, atol=1e-12)
        assert out2[0] == x[n]  # the wheel angle is a state: its rate is the state's speed


def test_stiff_compliant_drive_follows_the_motor():
    from szdyn.simulate import simulate

    params = default_parameters(n_circles=NC).replace(drive_mode=2, k_drive=50.0, c_drive=0.05)
    run = simulate(params, RampHold(a=2.0, t_ramp=0.3, t_hold=0.2), 0.5, method="dopri5", rtol=1e-8, atol=1e-10)
    motor_angle, motor_speed, _ = RampHold(a=2.0, t_ramp=0.3, t_hold=0.2).evaluate(run.outputs["t"])
    assert run.params["drive_mode"] == 2
    wind_up = run.outputs["q_w"] - params.initial_state()[0] - motor_angle
    assert np.abs(wind_up).max() < 2e-3  # rad: the coupling winds up a little under the load
    assert np.abs(wind_up).max() > 0  # ...but it does (the wheel is a state, not the profile)
