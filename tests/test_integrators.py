"""Tests of szdyn.integrators: convergence orders, adaptive accuracy, hand-computed steps,
non-finite handling and argument validation.

Model-specific setup lives only in conftest.smooth_case; everything else is built by name.
"""
from __future__ import annotations

import math

import numpy as np
import pytest
from scipy.integrate import solve_ivp

from szdyn.drive import Ramp
from szdyn.errors import SimulationError
from szdyn.integrators import DOPRI5, HEUN, RK4, TABLEAUX, Tableau, Trajectory, integrate
from szdyn_generated.spiral_zipper import N_AUX
from szdyn_generated.spiral_zipper import PARAM_INDEX, rhs


def _f(p, drive):
    def f(t, x):
        out = np.empty_like(x)
        rhs(t, x, p, drive, out)
        return out
    return f


@pytest.fixture(scope="module")
def reference(smooth_case):
    """Reference solution at t = 0, 0.05, ..., t_end (DOP853, rtol 1e-12): shape (21, n)."""
    x0, p, drive, t_end = smooth_case
    t_eval = np.linspace(0.0, t_end, 21)
    sol = solve_ivp(_f(p, drive), (0.0, t_end), x0, method="DOP853", rtol=1e-12, atol=1e-14,
                    t_eval=t_eval)
    assert sol.success
    return t_eval, sol.y.T


# ------------------------------------------------------------------------------- tableaux
@pytest.mark.parametrize("tab", [HEUN, RK4, DOPRI5])
def test_tableau_order_conditions(tab):
    """Butcher order conditions up to order min(p, 4): sum b = 1, b.c = 1/2, b.c^2 = 1/3, ..."""
    A, b, c = tab.A, tab.b, tab.c
    assert b.sum() == pytest.approx(1.0, abs=1e-15)
    assert b @ c == pytest.approx(1 / 2, abs=1e-15)
    if tab.order >= 3:
        assert b @ c**2 == pytest.approx(1 / 3, abs=1e-15)
        assert b @ A @ c == pytest.approx(1 / 6, abs=1e-15)
    if tab.order >= 4:
        assert b @ c**3 == pytest.approx(1 / 4, abs=1e-15)
        assert b @ (c * (A @ c)) == pytest.approx(1 / 8, abs=1e-15)
        assert b @ A @ c**2 == pytest.approx(1 / 12, abs=1e-15)
        assert b @ A @ A @ c == pytest.approx(1 / 24, abs=1e-15)
    if tab.b_err is not None:
        assert tab.b_err.sum() == pytest.approx(0.0, abs=1e-15)


def test_tableau_rejects_implicit():
    with pytest.raises(ValueError, match="lower triangular"):
        Tableau("bad", 1, A=[[1.0]], b=[1.0], c=[1.0])


def test_registry():
    assert TABLEAUX == {"heun": HEUN, "rk4": RK4, "dopri5": DOPRI5}
    assert DOPRI5.fsal and DOPRI5.adaptive and not RK4.adaptive


# ------------------------------------------------------------------------------- convergence
# dt ranges measured to be in the asymptotic regime of smooth_case (local slopes within 0.05
# of the order) and with errors >= 1e-10, far above the reference's ~4e-13.
ORDER_CASES = [
    ("heun", 2, 5e-3),
    ("rk4", 4, 1.25e-2),
    ("dopri5", 5, 2.5e-2),  # embedded tableau run through the fixed-step kernel
]


@pytest.mark.parametrize("method, order, dt_max", ORDER_CASES)
def test_convergence_order(smooth_case, reference, method, order, dt_max):
    x0, p, drive, t_end = smooth_case
    x_ref = reference[1][-1]
    dts = dt_max / 2.0 ** np.arange(4)
    errs = []
    for dt in dts:
        traj = integrate(x0, p, drive, t_end, method=method, dt=dt, save_dt=t_end,
                         adaptive=False)
        assert traj.t[-1] == t_end
        errs.append(np.max(np.abs(traj.x[-1] - x_ref)))
    slope = np.polyfit(np.log(dts), np.log(errs), 1)[0]  # least squares: log err vs log dt
    assert abs(slope - order) < 0.3, (method, slope, errs)


# ------------------------------------------------------------------------------- adaptive
def test_adaptive_meets_tolerance_and_saves_exactly(smooth_case, reference):
    x0, p, drive, t_end = smooth_case
    t_ref, x_ref = reference
    scale = np.abs(x_ref).max(axis=0)  # per-component magnitude (components cross zero)
    steps = []
    for rtol in (1e-4, 1e-6, 1e-8):
        atol = rtol * 1e-3
        traj = integrate(x0, p, drive, t_end, method="dopri5", save_dt=0.05, rtol=rtol,
                         atol=atol)
        assert traj.method == "dopri5"
        np.testing.assert_array_equal(traj.t, t_ref)  # save times hit exactly
        err = np.abs(traj.x - x_ref) / (atol + rtol * scale)
        assert err.max() < 10.0, (rtol, err.max())
        steps.append(traj.n_steps)
    assert steps[0] < steps[1] < steps[2], steps


def test_adaptive_hmax_and_max_steps(smooth_case):
    x0, p, drive, t_end = smooth_case
    traj = integrate(x0, p, drive, t_end, method="dopri5", save_dt=t_end, hmax=1e-2)
    assert traj.n_steps >= 100
    with pytest.raises(SimulationError, match="max_steps=5"):
        integrate(x0, p, drive, t_end, method="dopri5", save_dt=t_end, max_steps=5)


# ------------------------------------------------------------------------------- one step
def _hand_step(method, x, p, drive, t, h):
    f = _f(p, drive)
    if method == "heun":
        k1 = f(t, x)
        k2 = f(t + h, x + h * k1)
        return x + h * (0.5 * k1 + 0.5 * k2)
    k1 = f(t, x)
    k2 = f(t + h / 2, x + h / 2 * k1)
    k3 = f(t + h / 2, x + h / 2 * k2)
    k4 = f(t + h, x + h * k3)
    return x + h * (k1 / 6 + k2 / 3 + k3 / 3 + k4 / 6)


@pytest.mark.parametrize("method", ["heun", "rk4"])
def test_one_step_matches_hand_computation(smooth_case, method):
    x0, p, drive, _ = smooth_case
    t0, h = 0.1, 0.01
    traj = integrate(x0, p, drive, t0 + h, method=method, dt=h, save_dt=h, t0=t0)
    assert traj.x.shape == (2, x0.size) and traj.n_steps == 1
    np.testing.assert_array_equal(traj.x[0], x0)
    expected = _hand_step(method, x0, p, drive, t0, h)
    np.testing.assert_allclose(traj.x[1], expected, rtol=1e-14, atol=1e-15)


def test_final_partial_step_and_save_grid(smooth_case):
    x0, p, drive, _ = smooth_case
    traj = integrate(x0, p, drive, 0.0105, method="rk4", dt=1e-3, save_dt=2e-3)
    np.testing.assert_allclose(traj.t, [0, 0.002, 0.004, 0.006, 0.008, 0.010, 0.0105],
                               rtol=0, atol=1e-15)
    assert traj.n_steps == 11
    short = integrate(x0, p, drive, 0.010, method="rk4", dt=1e-3, save_dt=2e-3)
    np.testing.assert_array_equal(traj.x[:6], short.x)  # same steps up to t = 0.01
    last = _hand_step("rk4", short.x[-1], p, drive, 0.010, 0.0005)
    np.testing.assert_allclose(traj.x[-1], last, rtol=1e-13, atol=1e-14)


def test_progress_is_reported(smooth_case):
    x0, p, drive, t_end = smooth_case
    for kw in (dict(method="rk4", dt=1e-3), dict(method="dopri5")):
        seen = []
        integrate(x0, p, drive, t_end, save_dt=1e-2, progress=seen.append, **kw)
        assert 10 <= len(seen) <= 60
        assert np.all(np.diff(seen) > 0) and seen[-1] == pytest.approx(1.0)


# ------------------------------------------------------------------------------- non-finite
def _drive_with_nan_after(t_nan):
    """Wheel speed that is NaN from t_nan on: knots (0, 1), (t_nan, 1), (t_nan + 1, NaN)."""
    return np.array([3.0, 0.0, t_nan, t_nan + 1.0, 1.0, 1.0, np.nan, 0.0, t_nan, np.nan])


@pytest.mark.parametrize("method", ["heun", "rk4", "dopri5"])
def test_nonfinite_reports_when_and_which(smooth_case, method):
    x0, p, _, _ = smooth_case
    names = [f"s{k}" for k in range(x0.size)]
    names[0] = "q_w"
    with pytest.raises(SimulationError) as info:
        integrate(x0, p, _drive_with_nan_after(0.5), 1.0, method=method, dt=1e-3, save_dt=1e-2,
                  state_names=names)
    err = info.value
    msg = str(err)
    assert "q_w" in msg and err.variable.startswith("q_w")  # dq_w/dt = drive speed = NaN
    assert err.t == pytest.approx(0.5, abs=1e-3)
    assert "t = 0.5" in msg or "t = 0.49" in msg
    assert ("smaller step" in msg) if method != "dopri5" else ("tighter tolerance" in msg)
    part = err.trajectory
    assert isinstance(part, Trajectory) and np.all(np.isfinite(part.x))
    assert part.t[-1] <= 0.5 and part.t[-1] > 0.48
    assert part.x.shape == (part.t.size, x0.size)


@pytest.mark.parametrize("method", ["rk4", "dopri5"])
def test_nan_parameter_reported_at_t0_without_names(smooth_case, method):
    x0, p, drive, t_end = smooth_case
    p = p.copy()
    p[PARAM_INDEX["k_c"]] = np.nan
    with pytest.raises(SimulationError, match=r"x\[\d+\].*t = 0 s.*initial state") as info:
        integrate(x0, p, drive, t_end, method=method, dt=1e-3)
    assert info.value.t == 0.0 and info.value.variable.startswith("x[")
    assert info.value.trajectory.t.size == 1  # only the initial sample


def test_unstable_step_blows_up_with_advice(smooth_case):
    x0, p, drive, _ = smooth_case
    with pytest.raises(SimulationError, match=r"smaller step \(dt=0\.5 s") as info:
        integrate(x0, p, drive, 2000.0, method="heun", dt=0.5, save_dt=0.5)
    assert 0 < info.value.t < 2000.0


# ------------------------------------------------------------------------------- validation
@pytest.mark.parametrize("kwargs, match", [
    (dict(method="euler"), r"unknown method 'euler'.*'heun', 'rk4', 'dopri5'"),
    (dict(dt=-1e-3), "dt must be a finite number > 0"),
    (dict(dt=3e-4, save_dt=1e-3), "save_dt=0.001 must be a multiple of dt=0.0003"),
    (dict(t_end=0.0), "t_end > t0"),
    (dict(save_dt=0.0), "save_dt"),
    (dict(method="dopri5", rtol=-1.0), "rtol"),
    (dict(method="rk4", adaptive=True), "no embedded error estimate"),
    (dict(state_names=["a"]), "state_names"),
])
def test_bad_arguments(smooth_case, kwargs, match):
    x0, p, drive, t_end = smooth_case
    args = dict(x0=x0, p=p, drive=drive, t_end=t_end)
    args.update(kwargs)
    with pytest.raises(ValueError, match=match):
        integrate(**args)


def test_bad_vectors(smooth_case):
    x0, p, drive, t_end = smooth_case
    bad = x0.copy()
    bad[3] = math.inf
    with pytest.raises(ValueError, match=r"x0 must be finite.*x\[3\]"):
        integrate(bad, p, drive, t_end)
    with pytest.raises(ValueError, match="p must have"):
        integrate(x0, p[:-1], drive, t_end)
    with pytest.raises(ValueError, match="drive"):
        integrate(x0, p, drive[:-1], t_end)


@pytest.mark.parametrize("method", ["heun", "rk4", "dopri5"])
def test_prescribed_ramp_from_t0_is_exact(smooth_case, method):
    """A ramp starting at t0 = 0 (thesis drive): the state's wheel angle and speed are
    polynomials of degree <= 2 in t, so every method reproduces the drive to round-off, provided
    the drive acceleration is right-continuous at the first knot."""
    x0, p, _, _ = smooth_case
    ramp = Ramp(a=20.0, t_end=2.0)
    x0 = x0.copy()
    n = (x0.size - N_AUX) // 2
    x0[0], x0[n] = 0.3, 0.0
    traj = integrate(x0, p, ramp.to_array(angle0=0.3), 0.5, method=method, dt=1e-3,
                     save_dt=1e-2)
    angle, speed, _ = ramp.evaluate(traj.t, angle0=0.3)
    np.testing.assert_allclose(traj.x[:, 0], angle, rtol=0, atol=1e-12)
    np.testing.assert_allclose(traj.x[:, n], speed, rtol=0, atol=1e-12)


def test_check_sampling_limits_and_its_boundaries():
    from szdyn.integrators import MAX_OUTPUT_BYTES, check_sampling

    check_sampling("rk4", 1e-5, 1e-3, 1.0)
    with pytest.raises(ValueError, match="save_dt=0.001 must be a multiple of dt=0.0003"):
        check_sampling("rk4", 3e-4, 1e-3, 1.0)
    check_sampling("dopri5", 3e-4, 1e-3, 1.0)   # dt is not used by the adaptive method
    # exactly 10 intervals pass though 0.7 / 0.07 is 9.999999999999998 in floating point
    check_sampling("dopri5", 1e-5, 0.07, 0.7)
    with pytest.raises(ValueError, match="gives 9.9 saved intervals"):
        check_sampling("dopri5", 1e-5, 0.1, 0.99)
    # the output limit: rows x states x 8 bytes
    rows = MAX_OUTPUT_BYTES // (8 * 205) - 2
    check_sampling("dopri5", 1e-5, 1e-3, (rows - 1) * 1e-3, n_states=205)
    with pytest.raises(ValueError, match="GiB of output"):
        check_sampling("dopri5", 1e-5, 1e-3, (rows + 2) * 1e-3, n_states=205)
    # the fixed-step limit: 1e9 steps pass, 1.1e9 do not; dopri5 has
    # its own step budget, and dt=1e-300 (which would not compile) is refused by the same rule
    check_sampling("rk4", 1e-6, 1e-3, 1000.0)
    with pytest.raises(ValueError, match=r"dt=1e-06 s makes 1.1e\+09 fixed steps over the 1100 s run, more "
                                         r"than 1e\+09 \(hours of work a run\)"):
        check_sampling("rk4", 1e-6, 1e-3, 1100.0)
    check_sampling("dopri5", 1e-9, 1e-3, 1100.0)
    with pytest.raises(ValueError, match="fixed steps"):
        check_sampling("heun", 1e-300, 1e-3, 1.0)
