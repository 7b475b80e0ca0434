"""Benchmark inputs (state, parameters, drive) and compiled timing loops around the generated code."""
from __future__ import annotations

import time

import numba as nb
import numpy as np
import szdyn_generated.spiral_zipper as sz

from szdyn.defaults import default_parameters
from szdyn.drive import Ramp

T_EVAL = 1.0  # s, time at which the RHS is evaluated (inside the ramp)


def setup(n_circles: int, *, torque: bool = True, seed: int = 0):
    """(ParameterSet, p, x, drive) at N_c circles: default parameters (N_r = 8), the initial
    state slightly perturbed, and a ramp drive. ``torque=True`` sets ``drive_mode=1``."""
    ps = default_parameters(n_circles)
    if torque:
        ps = ps.replace(drive_mode=1)
    p = ps.to_array()
    rng = np.random.default_rng(seed)
    x = ps.initial_state()
    n = n_circles + 2
    x[:n] += rng.normal(0.0, 1e-4, n)  # rad
    x[n:2 * n] += rng.normal(0.0, 1e-2, n)  # rad/s (any auxiliary states after 2 n are left alone)
    drive = np.ascontiguousarray(Ramp(0.05, 2.0).to_array(), dtype=np.float64)  # torque 0.05 t N m
    return ps, p, x, drive


def window(p, n_circles, x):
    """``contact_window`` at state ``x`` (its signature gained the largest arm angle ``phi_max``)."""
    import inspect

    nargs = len(inspect.signature(sz.contact_window.py_func).parameters)
    if nargs == 2:
        return int(sz.contact_window(p, n_circles))
    q_b = x[1]
    phi_max = float(np.max(np.abs(x[2:2 + n_circles] - q_b)))
    return int(sz.contact_window(p, n_circles, phi_max))


@nb.njit
def rhs_loop(x, p, drive, out, n_calls):
    """``n_calls`` RHS evaluations in compiled code (the result is accumulated so none is dead)."""
    acc = 0.0
    for k in range(n_calls):
        sz.rhs(1.0 + 1e-12 * k, x, p, drive, out)
        acc += out[out.shape[0] - 1]
    return acc


def time_compiled(fn, *args, min_time=0.2, repeat=5):
    """Per-iteration time (s) of a compiled loop ``fn(*args, n)``, best of ``repeat``."""
    fn(*args, 1)  # compile / warm up
    n = 1
    while True:
        t0 = time.perf_counter()
        fn(*args, n)
        dt = time.perf_counter() - t0
        if dt >= min_time / repeat or n >= 1 << 26:
            break
        n *= 2
    best = dt / n
    for _ in range(repeat - 1):
        t0 = time.perf_counter()
        fn(*args, n)
        best = min(best, (time.perf_counter() - t0) / n)
    return best


def time_rhs_compiled(p, x, drive, min_time=0.2):
    out = np.empty_like(x)
    return time_compiled(rhs_loop, x, p, drive, out, min_time=min_time)


def time_rhs_python(p, x, drive, min_time=0.2, repeat=5):
    """Per-call time (s) of ``rhs`` called from a Python loop (dispatch overhead included)."""
    out = np.empty_like(x)
    rhs = sz.rhs
    rhs(T_EVAL, x, p, drive, out)
    n = 1
    while True:
        t0 = time.perf_counter()
        for _ in range(n):
            rhs(T_EVAL, x, p, drive, out)
        dt = time.perf_counter() - t0
        if dt >= min_time / repeat:
            break
        n *= 2
    best = dt / n
    for _ in range(repeat - 1):
        t0 = time.perf_counter()
        for _ in range(n):
            rhs(T_EVAL, x, p, drive, out)
        best = min(best, (time.perf_counter() - t0) / n)
    return best
