"""The assembled kernels are the model: checked against a full KanesMethod derivation
(every circle and roller unrolled), an independent Lagrange derivation, and the symbolic
kernels themselves (pydy-style oracle). Also: ``make derive`` is reproducible byte for byte."""
from __future__ import annotations

import filecmp
from pathlib import Path

import numpy as np
import pytest
import sympy as sm
import sympy.physics.mechanics as me

from cases import EFFECTS_OFF, constant_drive, param_vector, random_params, random_state
from derive.codegen import generate
from derive.force_laws import SliderFriction
from derive.force_laws import tt as T_SYM
from derive.force_laws import z as Z_LUGRE
from derive.kernels import T_m, energy_kernels, full_system, kernels
from derive.symbols import P, PARAM_NAMES, circle_coordinates, q_b, q_w, t
from szdyn_generated import kernels as gk
from szdyn_generated import spiral_zipper as sz

ROOT = Path(__file__).resolve().parents[1]
PSYMS = [P[n] for n in PARAM_NAMES]


def _lambdify_full(fs):
    q, u = fs.q, fs.u
    # "math" evaluates Piecewise lazily (numpy would evaluate both branches).
    return sm.lambdify((q, u, PSYMS, T_m, Z_LUGRE, T_SYM), (fs.mass_matrix, fs.forcing),
                       modules=[{"ImmutableDenseMatrix": np.array}, "math"], cse=True)


# lambdify's CSE hoists delta**n_imp out of the contact Piecewise, so it is also evaluated
# (and discarded) for negative overlaps with fractional n_imp: a harmless NaN warning.
@pytest.mark.filterwarnings("ignore:invalid value encountered in scalar power")
@pytest.mark.parametrize("n_circles, n_rollers, contact_model",
                         [(1, 1, 0), (1, 2, 0), (2, 1, 0), (2, 2, 0), (3, 1, 0), (3, 2, 0), (2, 2, 1), (3, 2, 2)])
def test_assembly_equals_full_kane(n_circles, n_rollers, contact_model):
    fs = full_system(n_circles, n_rollers, contact_model)
    f = _lambdify_full(fs)
    rng = np.random.default_rng(100 * n_circles + n_rollers)
    n = n_circles + 2
    contacts = 0
    for trial in range(40):
        v = random_params(rng, interference=rng.uniform(0.2e-3, 1.5e-3), contact_model=contact_model)
        v["n_rollers"] = n_rollers
        p = param_vector(**v)
        x = random_state(rng, n_circles, v["gamma"])
        if trial % 4:  # put a roller near some circle so that contacts are exercised
            x[0] = x[1] + 2 * np.pi * rng.integers(n_circles) / n_circles + rng.normal(0, 0.04)
        T = rng.uniform(-0.5, 0.5)
        t = rng.uniform(0, 10)
        M_ref, F_ref = f(x[:n], x[n:2 * n], p, T, x[2 * n], t)
        M, F = sz.mass_matrix_forcing(t, x, p, constant_drive(T))
        np.testing.assert_allclose(M, np.asarray(M_ref, float), rtol=1e-10, atol=1e-14)
        scale = np.abs(np.asarray(F_ref, float)).max()
        np.testing.assert_allclose(F, np.asarray(F_ref, float).ravel(), rtol=1e-10, atol=1e-10 * scale)
        contacts += sz.contact_count(0.0, x, p, constant_drive(T))
    # The comparison must exercise the contact force, not only the smooth part.
    if contact_model == 0:
        assert contacts >= 20, f"only {contacts} contacts sampled"
    else:
        assert contacts == 0  # friction counter-models have no impacts


def test_independent_lagrange_derivation():
    """Model-notes' energy T_i = m_c/2 (R^2 u_b^2 + d^2 u_i^2 - 2 R d u_b u_i cos(q_b - q_i)),
    V_i = k_c (q_i - q_b)^2 / 2, with LagrangesMethod and hand-written generalized forces."""
    nc = 2
    qs = [q_w, q_b] + [circle_coordinates(i + 1)[0] for i in range(nc)]
    qd = [qi.diff(t) for qi in qs]
    R, d, m, k, b = P["R_bo"], P["d"], P["m_c"], P["k_c"], P["b_c"]
    T = P["I_W"] * qd[0] ** 2 / 2 + P["I_B"] * qd[1] ** 2 / 2
    V = 0
    Q = [T_m, SliderFriction().torque(qd[1])] + [0] * nc
    for i in range(nc):
        qi, ui = qs[2 + i], qd[2 + i]
        T += m / 2 * (R**2 * qd[1] ** 2 + d**2 * ui**2 - 2 * R * d * qd[1] * ui * sm.cos(q_b - qi))
        V += k * (qi - q_b) ** 2 / 2
        Q[2 + i] += -b * (ui - qd[1])
        Q[1] += b * (ui - qd[1])
    lm = me.LagrangesMethod(T - V, qs)
    lm.form_lagranges_equations()
    # The non-conservative generalized forces are written by hand above: add them.
    M_sym = lm.mass_matrix
    F_sym = lm.forcing + sm.Matrix(Q)
    us = sm.symbols(f"v0:{nc + 2}")
    subs = dict(zip(qd, us))
    fn = sm.lambdify((qs, us, PSYMS, T_m), (me.msubs(M_sym, subs), me.msubs(F_sym, subs)), modules="numpy")
    rng = np.random.default_rng(7)
    for _ in range(20):
        v = random_params(rng, interference=-2e-3)  # no contact: it is not in this derivation
        v.update(EFFECTS_OFF, n_rollers=3)  # nor are the candidate effects
        p = param_vector(**v)
        x = random_state(rng, nc, v["gamma"])
        Tq = rng.uniform(-1, 1)
        M_ref, F_ref = fn(x[: nc + 2], x[nc + 2:2 * (nc + 2)], p, Tq)
        M, F = sz.mass_matrix_forcing(0.0, x, p, constant_drive(Tq))
        assert sz.contact_count(0.0, x, p, constant_drive(Tq)) == 0
        np.testing.assert_allclose(M, np.asarray(M_ref, float), rtol=1e-12, atol=1e-15)
        np.testing.assert_allclose(F, np.asarray(F_ref, float).ravel(), rtol=1e-10, atol=1e-12)


def _inputs(rng, names):
    vals = []
    for a in names:
        if a.startswith(("c_", "s_")):
            vals.append(None)
        else:
            vals.append(rng.uniform(-2, 2))
    return vals


@pytest.mark.parametrize("kernel", kernels() + energy_kernels(), ids=lambda k: k.name)
def test_generated_kernel_equals_symbolic(kernel):
    rng = np.random.default_rng(11)
    fn = sm.lambdify((kernel.args, PSYMS), [e for _, e in kernel.outputs], modules="math")
    gen = getattr(gk, kernel.name)
    for _ in range(50):
        v = random_params(rng)
        v["n_rollers"] = 8
        p = param_vector(**v)
        args = []
        angles = {"phi": rng.uniform(-0.5, 0.5), "rho": rng.uniform(-0.5, 0.5)}
        for a in kernel.args:
            name = str(a)
            if name in ("c_phi", "s_phi", "c_rho", "s_rho"):
                ang = angles[name[2:]]
                args.append(np.cos(ang) if name[0] == "c" else np.sin(ang))
            elif name in angles:
                args.append(angles[name])
            else:
                args.append(rng.uniform(-2, 2))
        ref = fn(args, p)
        got = gen(*args, p)
        got = got if isinstance(got, tuple) else (got,)
        np.testing.assert_allclose(got, ref, rtol=1e-12, atol=1e-300)


def _law_functions():
    from derive.force_laws import LAWS

    return [f for law in LAWS for f in law.functions()]


def _law_argument(name, rng, v):
    if name == "speed":  # band speed: every branch of the slider law, both directions
        return rng.choice([-1, 1]) * v["gamma"] * rng.uniform(0, 3)
    if name == "delta":
        return rng.uniform(0, 1e-3)
    if name == "z":
        return rng.uniform(-1e-4, 1e-4)
    if name == "tau_slider":
        return rng.uniform(-0.2, 0.2)
    if name == "f_n":
        return rng.uniform(0, 50)
    if name == "slip":
        return rng.uniform(-0.05, 0.05)
    return rng.uniform(-5, 5)  # t, q_b, delta_dot, angles and speeds of the drive


@pytest.mark.parametrize("fn", _law_functions(), ids=lambda f: f.name)
def test_generated_force_laws_equal_symbolic(fn):
    """Every emitted force law (including each candidate effect) equals its symbolic expression."""
    ref = sm.lambdify((fn.args, PSYMS), fn.expr, modules="math")
    gen = getattr(gk, fn.name)
    rng = np.random.default_rng(3)
    for _ in range(200):
        v = random_params(rng)
        v["n_rollers"] = 8
        p = param_vector(**v)
        a = [_law_argument(str(arg), rng, v) for arg in fn.args]
        assert gen(*a, p) == pytest.approx(ref(a, p), rel=1e-12, abs=1e-14)


def test_slider_law_is_continuous_and_odd():
    rng = np.random.default_rng(5)
    v = random_params(rng)
    v["n_rollers"] = 8
    p = param_vector(**v)
    g = v["gamma"]
    for edge in (g, 1.5 * g):
        lo, hi = gk.slider_mu(edge * (1 - 1e-9), p), gk.slider_mu(edge * (1 + 1e-9), p)
        assert abs(lo - hi) < 1e-6
    assert gk.slider_mu(g, p) == pytest.approx(v["mu_s"])
    assert gk.slider_mu(2 * g, p) == pytest.approx(v["mu_k"])
    assert gk.slider_mu(-2 * g, p) == pytest.approx(-v["mu_k"])
    assert gk.slider_mu(0.0, p) == 0.0


def test_regenerate_is_byte_identical(tmp_path):
    generate(tmp_path)
    for name in ("__init__.py", "kernels.py", "spiral_zipper.py"):
        assert filecmp.cmp(tmp_path / name, ROOT / "generated" / name, shallow=False), (
            f"generated/{name} is stale: run `make derive` and commit")


def test_generated_code_does_not_import_sympy():
    for path in (ROOT / "generated").glob("*.py"):
        text = path.read_text()
        assert "sympy" not in text.split('"""', 2)[-1].replace("SymPy", ""), path
        assert "DO NOT EDIT" in text and "make derive" in text


@pytest.mark.parametrize("n_circles", [1, 5, 16, 100])
def test_contact_window_finds_every_contact(n_circles):
    """The windowed contact search equals a brute-force test of every roller-circle pair, at
    random states (arm deflections up to pi) and geometries, including many contacts."""
    rng = np.random.default_rng(n_circles)
    found = 0
    for trial in range(300):
        v = random_params(rng, interference=rng.uniform(-0.5e-3, 3e-3))
        v["n_rollers"] = int(rng.integers(1, 9))
        if trial % 3 == 0:  # roller centres beyond the ring of circles
            v["R_w"] = v["R_bo"] - v["d"] + rng.uniform(0, 0.5) * v["d"]
            v["t_r"] = min(v["t_r"], 0.9 * (v["R_bo"] - v["R_w"]))
        p = param_vector(**v)
        x = random_state(rng, n_circles, v["gamma"])
        x[2:n_circles + 2] = x[1] + rng.uniform(-1, 1, n_circles) * rng.choice([0.02, 0.3, np.pi])
        brute = 0
        for j in range(v["n_rollers"]):
            for i in range(n_circles):
                rho = x[0] + 2 * np.pi * j / v["n_rollers"] - x[1] - 2 * np.pi * i / n_circles
                phi = x[2 + i] - x[1]
                dist_sq = gk.contact_distance_sq(np.cos(rho), np.sin(rho), np.cos(phi), np.sin(phi), p)
                brute += dist_sq < (v["t_c"] + v["t_r"]) ** 2
        assert sz.contact_count(0.0, x, p, constant_drive(0.0)) == brute
        found += brute
    assert found >= 20
