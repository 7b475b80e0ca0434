"""Section 3: RHS evaluation at N_c = 100, N_r = 8 against the SymPy-user baseline
(unrolled KanesMethod -> lambdify(cse=True) -> numpy.linalg.solve)."""
from __future__ import annotations

import time
import warnings

import numpy as np
import szdyn_generated.spiral_zipper as sz

from _common import best_of, fit_loglog, fmt_time, log, table
from _model import T_EVAL, setup, time_rhs_compiled, time_rhs_python

N_TARGET = 100
N_ROLLERS = 8
BUDGET_S = 120.0  # largest baseline derivation (+ lambdify) we are willing to wait for


def _baseline(nc: int, nr: int):
    import sympy as sm

    from derive.force_laws import tt as t_sym
    from derive.kernels import T_m, full_system
    from derive.symbols import P, PARAM_NAMES

    t0 = time.perf_counter()
    fs = full_system(nc, nr)
    t_derive = time.perf_counter() - t0
    t0 = time.perf_counter()
    # the model's loads may depend on time (friction_drift): time is an argument of the baseline too
    f = sm.lambdify((fs.q, fs.u, [P[n] for n in PARAM_NAMES], T_m, t_sym), (fs.mass_matrix, fs.forcing),
                    modules=[{"ImmutableDenseMatrix": np.array}, "math"], cse=True)
    t_lambdify = time.perf_counter() - t0

    ps, p, x, drive = setup(nc)
    assert int(ps["n_rollers"]) == nr
    n = nc + 2
    # With few circles the default wheel offset leaves every roller clear of the circles: turn
    # the wheel to the first angle with a contact so that check and timing include contact forces.
    q_w0 = x[0]
    for dq in np.linspace(0.0, 2 * np.pi / nr, 721):
        x[0] = q_w0 + dq
        if sz.contact_count(T_EVAL, x, p, drive) > 0:
            break
    q, u = x[:n].copy(), x[n:2 * n].copy()
    T = float(sz.drive_eval(drive, T_EVAL)[1])

    def evaluate():
        return f(q, u, p, T, T_EVAL)

    def evaluate_solve():
        M, F = f(q, u, p, T, T_EVAL)
        return np.linalg.solve(M, F)

    with warnings.catch_warnings():
        warnings.simplefilter("ignore", RuntimeWarning)
        du_ref = np.asarray(evaluate_solve(), float).ravel()
        out = np.empty_like(x)
        sz.rhs(T_EVAL, x, p, drive, out)
        err = float(np.max(np.abs(out[n:2 * n] - du_ref)) / np.max(np.abs(du_ref)))
        if not err <= 1e-8:
            raise AssertionError(f"baseline and generated RHS disagree at N_c={nc}: rel err {err:.2e}")
        t_eval = best_of(evaluate, repeat=5, number=max(1, int(2000 / n)))
        t_total = best_of(evaluate_solve, repeat=5, number=max(1, int(2000 / n)))
    return {"nc": nc, "derive_s": t_derive, "lambdify_s": t_lambdify, "eval_s": t_eval,
            "call_s": t_total, "rel_err": err, "contacts": int(sz.contact_count(T_EVAL, x, p, drive)),
            "gen_compiled_s": time_rhs_compiled(p, x, drive), "gen_python_s": time_rhs_python(p, x, drive)}


def _solve_only(nc: int) -> float:
    """numpy.linalg.solve on the real dense (N_c+2)^2 mass matrix (measured, not extrapolated)."""
    _, p, x, drive = setup(nc)
    M, F = sz.mass_matrix_forcing(T_EVAL, x, p, drive)
    return best_of(lambda: np.linalg.solve(M, F), repeat=5, number=200)


def _array_build(nc: int) -> float:
    """``numpy.array`` of an (N_c+2)^2 nested list of Python floats: what the lambdified function
    does to return M, whatever its expressions cost (a measured floor for the quadratic term)."""
    _, p, x, drive = setup(nc)
    M, _ = sz.mass_matrix_forcing(T_EVAL, x, p, drive)
    rows = M.tolist()
    return best_of(lambda: np.array(rows), repeat=5, number=50)


def run(quick: bool) -> dict:
    ps, p, x, drive = setup(N_TARGET)
    log(f"3/6 generated rhs at N_c={N_TARGET}")
    gen = {"compiled_s": time_rhs_compiled(p, x, drive, min_time=0.5),
           "python_s": time_rhs_python(p, x, drive, min_time=0.5),
           "contacts": int(sz.contact_count(T_EVAL, x, p, drive)),
           "solve_dense_s": _solve_only(N_TARGET), "array_build_s": _array_build(N_TARGET)}
    base = []
    sizes = [1, 2, 4] if quick else [2, 4, 8]
    for nc in sizes:
        log(f"3/6 baseline: full_system({nc}, {N_ROLLERS}) + lambdify(cse=True)")
        base.append(_baseline(nc, N_ROLLERS))
    if not quick:
        # One more, the largest N_c whose predicted derivation + lambdify fits the budget.
        cost = [b["derive_s"] + b["lambdify_s"] for b in base]
        k, a = fit_loglog([b["nc"] for b in base], cost)
        fits = [nc for nc in (12, 16, 20, 25, 32, 50) if np.exp(a) * nc**k <= BUDGET_S]
        if fits:
            log(f"3/6 baseline: full_system({fits[-1]}, {N_ROLLERS}) (predicted "
                f"{np.exp(a) * fits[-1]**k:.0f} s) + lambdify(cse=True)")
            base.append(_baseline(fits[-1], N_ROLLERS))
    return {"gen": gen, "base": base, "quick": quick}


def report(res: dict) -> str:
    gen, base = res["gen"], res["base"]
    ncs = [b["nc"] for b in base]
    k_eval, a_eval = fit_loglog(ncs, [b["eval_s"] for b in base])
    k_der, a_der = fit_loglog(ncs, [b["derive_s"] + b["lambdify_s"] for b in base])
    eval100 = float(np.exp(a_eval) * N_TARGET**k_eval)
    base100 = eval100 + gen["solve_dense_s"]
    der100 = float(np.exp(a_der) * N_TARGET**k_der)
    rows = [[b["nc"], b["contacts"], fmt_time(b["derive_s"]), fmt_time(b["lambdify_s"]), fmt_time(b["eval_s"]),
             fmt_time(b["call_s"]), fmt_time(b["gen_compiled_s"]), fmt_time(b["gen_python_s"]),
             f"{b['call_s'] / b['gen_compiled_s']:.0f}x", f"{b['call_s'] / b['gen_python_s']:.0f}x",
             f"{b['rel_err']:.1e}"] for b in base]
    rows.append([f"**{N_TARGET}** (extrapolated)", gen["contacts"], f"~{fmt_time(der100)} (derive+lambdify, fit)", "",
                 f"~{fmt_time(eval100)} (fit)", f"~{fmt_time(base100)}", fmt_time(gen["compiled_s"]),
                 fmt_time(gen["python_s"]), f"~{base100 / gen['compiled_s']:.0f}x",
                 f"~{base100 / gen['python_s']:.0f}x", "not checked"])
    return "\n".join([
        f"## 3. RHS evaluation (N_c = {N_TARGET}, N_r = {N_ROLLERS})",
        "",
        f"Generated `szdyn_generated.spiral_zipper.rhs` at N_c = {N_TARGET} (default parameters, "
        f"`drive_mode = 1` (torque), `initial_state()` perturbed by 1e-4 rad / 1e-2 rad/s, "
        f"`Ramp(0.05, 2).to_array()` evaluated at t = {T_EVAL} s; {gen['contacts']} roller-circle pairs in contact):",
        "",
        table(["call path", "time per call"], [
            ["compiled loop (njit function calling `rhs` N times)", f"**{fmt_time(gen['compiled_s'])}**"],
            ["Python loop (`rhs(t, x, p, drive, out)` per call, dispatch included)", f"**{fmt_time(gen['python_s'])}**"],
        ]),
        "",
        "Baseline a SymPy user would write: `full_system(N_c, 8)` (one `KanesMethod`, every circle and "
        "roller unrolled), `sympy.lambdify((q, u, params, T_m), (M, F), cse=True)` (`math` module, "
        "matrices as `numpy.array`), then `numpy.linalg.solve(M, F)` per call. Before timing, each baseline "
        "is checked against `rhs` (max relative difference of the accelerations, must be <= 1e-8). "
        f"Deriving it at N_c = {N_TARGET} is out of reach (fitted derive+lambdify time ∝ N_c^{k_der:.2f}, "
        f"~{fmt_time(der100)} at N_c = {N_TARGET}), so it was measured at N_c = {', '.join(map(str, ncs))} and "
        f"**its per-call time at N_c = {N_TARGET} is extrapolated**: lambdified evaluation fitted as ∝ N_c^{k_eval:.2f} "
        f"(log-log least squares over the measured N_c) plus `numpy.linalg.solve` of the real dense "
        f"{N_TARGET + 2}x{N_TARGET + 2} mass matrix, which *is* measured ({fmt_time(gen['solve_dense_s'])}).",
        "",
        table(["N_c", "contacts", "derive", "lambdify", "baseline eval (M, F)", "baseline eval + solve",
               "generated (compiled loop)", "generated (Python loop)", "ratio vs compiled", "ratio vs Python",
               "rel. diff of accelerations"], rows),
        "",
        "(Baseline states: as above but with the wheel turned to the first angle at which a roller touches a circle, so that contact forces are part of the check and of the timing.)",
        "",
        f"Sanity check of the extrapolation: building the {N_TARGET + 2}x{N_TARGET + 2} `numpy.array` that the "
        f"lambdified function returns as M costs {fmt_time(gen['array_build_s'])} by itself (measured), a term "
        "quadratic in N_c that the power-law fit over small N_c hardly sees, so the extrapolated baseline is "
        "more likely too low than too high (the ratio conservative).",
        "",
        f"**Ratio at N_c = {N_TARGET} (extrapolated baseline): ~{base100 / gen['compiled_s']:.0f}x "
        f"(compiled loop), ~{base100 / gen['python_s']:.0f}x (Python loop).**",
    ])
