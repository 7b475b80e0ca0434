"""Section 6: where the time of one RHS goes, and a FLOP estimate from the generated source."""
from __future__ import annotations

import ast
import inspect
import math
from collections import Counter

import numba as nb
import numpy as np
import szdyn_generated.kernels as gk
import szdyn_generated.spiral_zipper as sz

from _common import fmt_time, log, table
from _model import T_EVAL, setup, time_compiled, time_rhs_compiled, window

N_C = 100
TWO_PI = 2.0 * math.pi
I_N_R, I_T_C, I_T_R = (sz.PARAM_INDEX[k] for k in ("n_rollers", "t_c", "t_r"))
# The assembly's cheap pre-check: squared distance in newer generated code, distance before.
_SQ = hasattr(gk, "contact_distance_sq")
_precheck = gk.contact_distance_sq if _SQ else gk.contact_distance
PRECHECK = "contact_distance_sq" if _SQ else "contact_distance"


# ------------------------------------------------------------------ isolated compiled loops
@nb.njit
def _circle_loop(nc, x, p, m_bi, m_ii, f, c_phi, s_phi, reps):
    """The assembly's circle loop: phi, |phi| max, cos, sin and circle_kernel for every circle."""
    n = nc + 2
    acc = 0.0
    for _ in range(reps):
        q_b = x[1]
        u_b = x[n + 1]
        M_bb = 0.0
        phi_max = 0.0
        for i in range(nc):
            phi = x[2 + i] - q_b
            phi_max = max(phi_max, abs(phi))
            c = math.cos(phi)
            s = math.sin(phi)
            c_phi[i] = c
            s_phi[i] = s
            dM_bb, M_bi, M_ii, dF_b, F_i = gk.circle_kernel(phi, c, s, u_b, x[n + 2 + i], p)
            M_bb += dM_bb + dF_b
            m_bi[i] = M_bi
            m_ii[i] = M_ii
            f[i] = F_i
        acc += M_bb + phi_max
    return acc


@nb.njit
def _circle_kernel_only(nc, x, c_phi, s_phi, p, reps):
    """circle_kernel N_c times with cos/sin precomputed (kernel arithmetic alone)."""
    n = nc + 2
    acc = 0.0
    for _ in range(reps):
        for i in range(nc):
            a, b, c, d, e = gk.circle_kernel(x[2 + i] - x[1], c_phi[i], s_phi[i], x[n + 1], x[n + 2 + i], p)
            acc += a + b + c + d + e
    return acc


@nb.njit
def _contact_search(nc, ncand, x, p, q_w, c_phi, s_phi, hit_cr, hit_sr, hit_i, reps):
    """Per roller: locate the window and test contact_distance on each candidate (as _assemble).
    Records the active pairs (cos rho, sin rho, circle) and returns their number."""
    nr = int(p[I_N_R] + 0.5)
    reach = p[I_T_C] + p[I_T_R]
    if _SQ:
        reach = reach * reach
    pitch = TWO_PI / nc
    cp = math.cos(pitch)
    sp = math.sin(pitch)
    nhit = 0
    for _ in range(reps):
        nhit = 0
        q_b = x[1]
        for j in range(nr):
            ang = q_w + TWO_PI * j / nr - q_b
            k = int(math.floor(ang / pitch + 0.5)) - (ncand - 1) // 2
            rho = ang - k * pitch
            cr = math.cos(rho)
            sr = math.sin(rho)
            for m in range(ncand):
                i = (k + m) % nc
                if _precheck(cr, sr, c_phi[i], s_phi[i], p) < reach:
                    hit_cr[nhit] = cr
                    hit_sr[nhit] = sr
                    hit_i[nhit] = i
                    nhit += 1
                cr, sr = cr * cp + sr * sp, sr * cp - cr * sp
    return nhit


@nb.njit
def _contact_kernels(nc, x, p, u_w, nhit, hit_cr, hit_sr, hit_i, c_phi, s_phi, reps):
    """contact_kernel + impact_normal_force for the active pairs (rhs skips the contact energy)."""
    n = nc + 2
    reach = p[I_T_C] + p[I_T_R]
    acc = 0.0
    for _ in range(reps):
        for h in range(nhit):
            i = hit_i[h]
            dist, dd, vs, gw, gb, gi, tw, tb, ti = gk.contact_kernel(
                hit_cr[h], hit_sr[h], c_phi[i], s_phi[i], u_w, x[n + 1], x[n + 2 + i], p)
            delta = reach - dist
            fn = gk.impact_normal_force(delta, dd, p)
            acc += fn * (gw + gb + gi)
    return acc


@nb.njit
def _solve(M_bb, F_b, m_bi, m_ii, f, out, reps):
    """The arrowhead solve of rhs: Schur complement on the band row and back substitution."""
    nc = m_bi.shape[0]
    acc = 0.0
    for _ in range(reps):
        S = M_bb
        r = F_b
        for i in range(nc):
            w = m_bi[i] / m_ii[i]
            S -= w * m_bi[i]
            r -= w * f[i]
        du_b = r / S
        for i in range(nc):
            out[i] = (f[i] - m_bi[i] * du_b) / m_ii[i]
        acc += du_b
    return acc


# ------------------------------------------------------------------ FLOP counting (AST)
_BINOPS = {ast.Add: "+", ast.Sub: "-", ast.Mult: "*", ast.Div: "/", ast.Pow: "**"}
_INT_OPS = (ast.Mod, ast.FloorDiv)


def _function_defs(module):
    tree = ast.parse(inspect.getsource(module))
    return {n.name: n for n in tree.body if isinstance(n, ast.FunctionDef)}


class _Counter(ast.NodeVisitor):
    """Floating-point operations of expressions (index arithmetic inside subscripts skipped)."""

    def __init__(self, mult, sink, calls, resolve):
        self.mult, self.sink, self.calls, self.resolve = mult, sink, calls, resolve

    def visit_Subscript(self, node):
        self.visit(node.value)  # not node.slice: integer index arithmetic

    def visit_BinOp(self, node):
        if type(node.op) in _BINOPS:
            self.sink[_BINOPS[type(node.op)]] += self.mult
        self.generic_visit(node)

    def visit_AugAssign(self, node):
        if type(node.op) in _BINOPS:
            self.sink[_BINOPS[type(node.op)]] += self.mult
        self.visit(node.value)

    def visit_UnaryOp(self, node):
        if isinstance(node.op, ast.USub) and not isinstance(node.operand, ast.Constant):
            self.sink["-"] += self.mult
        self.generic_visit(node)

    def visit_Call(self, node):
        fn = node.func
        if isinstance(fn, ast.Attribute) and isinstance(fn.value, ast.Name) and fn.value.id == "math":
            self.sink[f"math.{fn.attr}"] += self.mult
        elif isinstance(fn, ast.Attribute):
            return  # np.empty(...) etc.: allocation, not arithmetic
        elif isinstance(fn, ast.Name):
            if fn.id in ("range", "int", "float", "len", "min", "max", "abs"):
                pass
            else:
                self.calls[fn.id] += self.mult
                self.resolve(fn.id, self.mult)
        for a in node.args:
            self.visit(a)


def _static_test(test, env):
    """Value of a model-switch test such as ``model != 0`` or ``p[_I_drive_mode] < 0.5`` at the
    benchmarked parameters, or None if the test is not such a switch."""
    import operator

    if isinstance(test, ast.Name) and test.id in env and isinstance(env[test.id], bool):
        return env[test.id]  # flags such as want_energy (False inside rhs)
    if not (isinstance(test, ast.Compare) and len(test.ops) == 1
            and isinstance(test.comparators[0], ast.Constant)):
        return None
    left = ast.unparse(test.left)
    key = "contact_model" if ("contact_model" in left or left == "model") else (
        "drive_mode" if "drive_mode" in left else None)
    if key is None or key not in env:
        return None
    ops = {ast.Eq: operator.eq, ast.NotEq: operator.ne, ast.Lt: operator.lt, ast.LtE: operator.le,
           ast.Gt: operator.gt, ast.GtE: operator.ge}
    op = ops.get(type(test.ops[0]))
    return None if op is None else bool(op(env[key], test.comparators[0].value))


def kernel_ops() -> dict[str, Counter]:
    """Operation counts of each generated kernel (one call)."""
    res = {}
    for name, fd in _function_defs(gk).items():
        c = Counter()
        _Counter(1, c, Counter(), lambda *_: None).visit(fd)
        res[name] = c
    return res


def rhs_ops(env: dict) -> tuple[Counter, Counter]:
    """Operations of one ``rhs`` call: kernels times their call counts, plus the assembly's own
    arithmetic, with loop trip counts from ``env`` (nc, n, nr, ncand, n_active)."""
    kops = kernel_ops()
    asm = _function_defs(sz)
    total, calls = Counter(), Counter()

    def resolve(name, mult):
        if name in kops:
            for k, v in kops[name].items():
                total[k] += v * mult
        elif name in asm:
            walk(asm[name].body, mult)

    def walk(stmts, mult):
        """Count ``stmts``; returns True when a ``return`` was certainly reached."""
        for st in stmts:
            if isinstance(st, ast.For):
                it = st.iter
                trips = 1
                if isinstance(it, ast.Call) and getattr(it.func, "id", "") == "range" and len(it.args) == 1:
                    a = it.args[0]
                    trips = env.get(a.id, 1) if isinstance(a, ast.Name) else 1
                walk(st.body, mult * trips)
            elif isinstance(st, ast.If):
                _Counter(mult, total, calls, resolve).visit(st.test)
                known = _static_test(st.test, env)
                if known is not None:  # model switch (contact_model, drive_mode): one branch only
                    if walk(st.body if known else st.orelse, mult):
                        return True
                    continue
                gated = any(isinstance(n, ast.Call) and getattr(n.func, "id", "").startswith("contact_distance")
                            for n in ast.walk(st.test))
                walk(st.body, env["n_active"] if gated else mult)  # other branches: both counted
                walk(st.orelse, mult)
            elif isinstance(st, ast.While):
                _Counter(mult, total, calls, resolve).visit(st.test)
                walk(st.body, mult)
            elif isinstance(st, ast.Return):
                _Counter(mult, total, calls, resolve).visit(st)
                return True
            else:
                _Counter(mult, total, calls, resolve).visit(st)
        return False

    calls["rhs"] = 1
    walk(asm["rhs"].body, 1)
    return total, calls


# ------------------------------------------------------------------ section
def run(quick: bool) -> dict:
    log(f"6/6 breakdown at N_c={N_C}")
    ps, p, x, drive = setup(N_C)
    nc = N_C
    n = nc + 2
    mt = 0.1 if quick else 0.3
    m_bi, m_ii, f, c_phi, s_phi = (np.empty(nc) for _ in range(5))
    q_w, u_w = x[0], x[n]
    nr = int(ps["n_rollers"])
    ncand = window(p, nc, x)
    hit_cr, hit_sr = np.empty(nr * ncand), np.empty(nr * ncand)
    hit_i = np.empty(nr * ncand, dtype=np.int64)
    t = {}
    t["circle loop (cos, sin, circle_kernel) x N_c"] = time_compiled(_circle_loop, nc, x, p, m_bi, m_ii, f, c_phi, s_phi,
                                                                      min_time=mt)
    t_kernel_only = time_compiled(_circle_kernel_only, nc, x, c_phi, s_phi, p, min_time=mt)
    t[f"contact search ({PRECHECK}) x N_r x window"] = time_compiled(
        _contact_search, nc, ncand, x, p, q_w, c_phi, s_phi, hit_cr, hit_sr, hit_i, min_time=mt)
    nhit = int(_contact_search(nc, ncand, x, p, q_w, c_phi, s_phi, hit_cr, hit_sr, hit_i, 1))
    n_active = int(sz.contact_count(T_EVAL, x, p, drive))
    t["active contacts (contact_kernel + impact force) x contacts"] = time_compiled(
        _contact_kernels, nc, x, p, u_w, nhit, hit_cr, hit_sr, hit_i, c_phi, s_phi, min_time=mt)
    M, F = sz.mass_matrix_forcing(T_EVAL, x, p, drive)
    out = np.empty(nc)
    t["arrowhead solve (Schur complement)"] = time_compiled(
        _solve, M[1, 1], F[1], M[1, 2:].copy(), np.diag(M)[2:].copy(), F[2:].copy(), out, min_time=mt)
    t_rhs = time_rhs_compiled(p, x, drive, min_time=mt)

    env = {"nc": nc, "n": n, "nr": nr, "ncand": ncand, "n_active": n_active,
           "drive_mode": float(p[sz.PARAM_INDEX["drive_mode"]]), "want_energy": False}
    if "contact_model" in sz.PARAM_INDEX:
        env["contact_model"] = int(p[sz.PARAM_INDEX["contact_model"]] + 0.5)
    ops, calls = rhs_ops(env)
    return {"t": t, "t_kernel_only": t_kernel_only, "t_rhs": t_rhs, "nhit": nhit, "n_active": n_active,
            "env": env, "ops": dict(ops), "calls": dict(calls), "kernel_ops": {k: dict(v) for k, v in kernel_ops().items()}}


def report(res: dict) -> str:
    t, t_rhs, env = res["t"], res["t_rhs"], res["env"]
    parts = sum(t.values())
    rows = [[k, fmt_time(v), f"{100 * v / t_rhs:.0f} %"] for k, v in t.items()]
    rows.append(["sum of the parts", fmt_time(parts), f"{100 * parts / t_rhs:.0f} %"])
    rows.append(["**whole `rhs`** (compiled loop)", f"**{fmt_time(t_rhs)}**", "100 %"])
    rows.append(["rest (allocation, drive, copies, loop overheads; by difference)", fmt_time(t_rhs - parts),
                 f"{100 * (t_rhs - parts) / t_rhs:.0f} %"])

    ko = res["kernel_ops"]
    used = ["core_kernel", "slider_torque", "circle_kernel", "contact_distance", "contact_distance_sq", "contact_kernel",
            "impact_normal_force", "impact_potential", "drive_eval"]
    calls = res["calls"]
    krows = []
    for name in used:
        c = ko.get(name)
        if c is None:
            continue
        nops = sum(c.values())
        krows.append([f"`{name}`", " ".join(f"{k}:{v}" for k, v in sorted(c.items())), nops,
                      f"{calls.get(name, 0):g}", f"{nops * calls.get(name, 0):,.0f}"])
    ops = res["ops"]
    total = sum(ops.values())
    kernel_total = sum(sum(ko[nm].values()) * calls.get(nm, 0) for nm in ko)
    transc = sum(v for k, v in ops.items() if k.startswith("math.") or k == "**")
    return "\n".join([
        f"## 6. Where time goes (N_c = {N_C}, N_r = {env['nr']}, default state)",
        "",
        "Generated kernels timed in isolation, each in a compiled loop that mirrors the assembly "
        f"(`_assemble`/`rhs`) at the section-3 state: window = {env['ncand']} candidates per roller "
        f"(`contact_window` at this state; the window-size computation itself is in the rest), {res['n_active']} active pairs (`contact_count`; the search found {res['nhit']}).",
        "",
        table(["part", "time per RHS", "share of rhs"], rows),
        "",
        f"`circle_kernel` alone (cos/sin precomputed) x N_c: {fmt_time(res['t_kernel_only'])}, so the two "
        "trig calls per circle are most of the circle loop.",
        "",
        "**FLOP estimate.** Operations (+ - * / **, unary minus, `math.*` calls; `abs`/`max`/`min` and "
        "integer index arithmetic not counted) parsed from the generated source with `ast`, times the "
        "number of calls per RHS at this state:",
        "",
        table(["kernel", "ops per call", "total", "calls per RHS", "ops per RHS"], krows),
        "",
        f"Whole RHS including the assembly's own arithmetic (loops of `_assemble` and `rhs` weighted by "
        f"their trip counts): **~{total:,.0f} operations** ({kernel_total:,.0f} in kernels), of which "
        f"{transc:,.0f} are `math.*` calls or powers (each worth several to tens of flops). "
        f"Breakdown: {', '.join(f'{k} {v:,.0f}' for k, v in sorted(ops.items(), key=lambda kv: -kv[1]))}. "
        f"At {fmt_time(t_rhs)} per call that is ~{total / t_rhs / 1e9:.2f} G operations/s "
        f"(~{total / env['nc']:.0f} operations per circle).",
    ])
