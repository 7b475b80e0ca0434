"""Shared test inputs: random parameter vectors and states built by parameter *name*."""
from __future__ import annotations

import importlib.util
import math
from pathlib import Path

import numpy as np

from szdyn_generated.spiral_zipper import PARAM_NAMES, state_size


def param_vector(**values) -> np.ndarray:
    missing = set(PARAM_NAMES) - set(values)
    assert not missing, missing
    return np.array([float(values[n]) for n in PARAM_NAMES])


def random_params(rng: np.random.Generator, interference: float = 0.6e-3, drive_mode: int = 1,
                  clamp: int | None = None, contact_model: int = 0) -> dict:
    """Random but physical parameters; rollers reach ``interference`` (m) into the circles."""
    R_bo = rng.uniform(0.025, 0.04)
    d = rng.uniform(0.004, 0.008)
    t_c = rng.uniform(0.0008, 0.0015)
    t_r = rng.uniform(0.004, 0.007)
    v = dict(
        I_W=rng.uniform(1e-4, 1e-3), I_B=rng.uniform(5e-4, 2e-3), m_c=rng.uniform(1e-3, 5e-3),
        R_bo=R_bo, d=d, t_c=t_c, t_r=t_r, R_w=R_bo - d - t_c - t_r + interference,
        k_c=rng.uniform(0.01, 0.1), b_c=rng.uniform(1e-3, 1e-2),
        k_imp=rng.uniform(1e11, 1e12), b_imp=rng.uniform(1e11, 1e13), n_imp=rng.choice([1.5, 2.0, 3.0]),
        impact_clamp=rng.integers(0, 2) if clamp is None else clamp,
        mu_s=rng.uniform(0.3, 0.6), gamma=rng.uniform(0.005, 0.05), m_b=rng.uniform(0.5, 2.0),
        g=9.80665, drive_mode=drive_mode, contact_model=contact_model,
        F_nw=rng.uniform(1, 20), mu_ws=rng.uniform(0.6, 1.0), v_ws=rng.uniform(1e-3, 1e-2),
        v_weps=rng.uniform(1e-4, 1e-3), sigma0=rng.uniform(1e4, 1e5), sigma1=rng.uniform(10, 300),
        sigma2=rng.uniform(0, 1),
        # candidate effects, all switched on so that the oracle checks them
        c_visc=rng.uniform(0, 1e-3), mu_st=rng.uniform(0, 0.2), v_st=rng.uniform(0.1, 1.0),
        fric_asym=rng.uniform(-0.3, 0.3), tau_lift=rng.uniform(-0.1, 0.1), a_rev=rng.uniform(0, 0.05),
        phi_rev=rng.uniform(-3, 3), a_tooth=rng.uniform(0, 0.02), phi_tooth=rng.uniform(-3, 3),
        n_teeth=float(rng.integers(10, 30)), k_drift=rng.uniform(-0.05, 0.05), mu_t=rng.uniform(0, 1.0),
        v_teps=rng.uniform(1e-4, 1e-2), k_drive=rng.uniform(1, 50), c_drive=rng.uniform(0, 0.05),
    )
    v["mu_wk"] = v["mu_ws"] * rng.uniform(0.5, 1.0)
    v["mu_k"] = v["mu_s"] * rng.uniform(0.5, 1.0)
    return v


#: The candidate effects switched off (their zero values).
EFFECTS_OFF = dict(c_visc=0.0, mu_st=0.0, fric_asym=0.0, tau_lift=0.0, a_rev=0.0, a_tooth=0.0, k_drift=0.0, mu_t=0.0)


def random_state(rng: np.random.Generator, n_circles: int, gamma: float) -> np.ndarray:
    """Random state: arms deflected by up to ~0.3 rad, band speed in every friction branch."""
    n = n_circles + 2
    x = np.empty(state_size(n_circles))
    x[0] = rng.uniform(-math.pi, math.pi)
    x[1] = rng.uniform(-math.pi, math.pi)
    x[2:n] = x[1] + rng.uniform(-0.3, 0.3, n_circles)
    x[n:2 * n] = rng.uniform(-3, 3, n)
    x[2 * n:] = rng.uniform(-1e-5, 1e-5, x.size - 2 * n)  # LuGre bristle deflection (m)
    x[n + 1] = gamma * rng.choice([0.5, 1.2, 1.4, 3.0, -0.7, -1.3, -5.0])
    return x


def constant_drive(value: float) -> np.ndarray:
    """Drive array with one knot: constant speed (prescribed) or constant torque."""
    return np.array([1.0, 0.0, value, 0.0])


def load_bench(name: str):
    """The module ``bench/NAME.py`` (the benchmarks are scripts, not a package), loaded by path."""
    path = Path(__file__).resolve().parents[1] / "bench" / f"{name}.py"
    spec = importlib.util.spec_from_file_location(name, path)
    mod = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(mod)
    return mod
