"""Equations of motion by Kane's method, as small kernels plus a full-system oracle.

The system's mass matrix is an arrowhead: the band row/column couples to every circle, the
circles do not couple to each other and the wheel couples to the rest only through contact
forces. So the equations are a sum of three kinds of contribution, each derived once with
``KanesMethod`` on a three-speed system ``u = [u_w, u_b, u_i]``:

* ``core``: wheel and band inertia, motor torque ``T_m``, the band torque ``tau_b`` of the
  band's load laws (slider friction, ...) and the torque pair ``tau_wb`` (on the band; its
  reaction on the wheel) of a lumped wheel-band friction law (the counter-models);
* ``circle``: one generic circle (hinge offset ``alpha``) with its arm spring-damper;
* ``contact``: one generic roller (offset ``beta``) touching that circle, with symbolic normal
  and tangential forces ``f_n`` and ``f_t`` supplied by a force law.

Kernels are rewritten in the rotation-invariant angles ``phi = q_i - q_b`` and
``rho = q_w + beta - q_b - alpha`` (their cosines and sines become inputs), so one kernel
serves every circle and roller and the derivation cost does not depend on ``N_c``.
``full_system`` derives the whole model with every circle and roller unrolled; tests use it
to prove that the assembled kernels are exact.
"""
from __future__ import annotations

from dataclasses import dataclass
from functools import lru_cache

import sympy as sm
import sympy.physics.mechanics as me

from . import kinematics as kin
from .force_laws import (ArmSpringDamper, BandEffects, ContactTraction, HuntCrossleyImpact, SliderFriction,
                         TractionCoulomb, TractionLuGre, tt as t_sym, z as z_lugre)
from .symbols import P, alpha, beta, circle_coordinates, phi, q_b, q_w, rho, t, u_b, u_w

f_n, f_t, T_m, tau_b, tau_wb = sm.symbols("f_n f_t T_m tau_b tau_wb", real=True)
c_phi, s_phi, c_rho, s_rho = sm.symbols("c_phi s_phi c_rho s_rho", real=True)
# Plain-symbol stand-ins for the speeds inside emitted kernels.
U_W, U_B, U_I = sm.symbols("u_w u_b u_i", real=True)


@dataclass(frozen=True)
class Kernel:
    """Emitted scalar function: ordered inputs, named outputs (expressions in inputs and P)."""

    name: str
    args: tuple[sm.Symbol, ...]
    outputs: tuple[tuple[str, sm.Expr], ...]
    doc: str


def _kane_on(mech: kin.Mechanism, q, u, bodies, loads):
    kd = [qi.diff(t) - ui for qi, ui in zip(q, u)]
    km = me.KanesMethod(mech.N, q_ind=q, u_ind=u, kd_eqs=kd)
    km.kanes_equations(bodies, loads)
    return km.mass_matrix, km.forcing


def _reduce(expr: sm.Expr, q_i, u_i) -> sm.Expr:
    """Rewrite in phi, rho and their cos/sin, with plain speed symbols; check q_b cancels."""
    e = me.msubs(expr, {q_i: q_b + phi, q_w: q_b + alpha - beta + rho})
    e = e.xreplace({u_w: U_W, u_b: U_B, u_i: U_I})
    e = e.xreplace({sm.cos(phi): c_phi, sm.sin(phi): s_phi, sm.cos(rho): c_rho, sm.sin(rho): s_rho})
    bad = e.atoms(sm.Function) | ({q_b, q_w, q_i, alpha, beta} & e.free_symbols)
    bad = {b for b in bad if not isinstance(b, (sm.Max, sm.Min))}
    if bad:
        raise RuntimeError(f"kernel still depends on {sorted(map(str, bad))}: not rotation invariant")
    return e


def _generic(relative: bool = True):
    mech = kin.mechanism()
    q_i, u_i = circle_coordinates("i")
    circle = kin.add_circle(mech, q_i, u_i, alpha, "i", relative=relative)
    roller = kin.add_roller(mech, beta, "j", seen_from=circle if relative else None)
    return mech, circle, roller, q_i, u_i


def core_loads(mech: kin.Mechanism, motor, band, pair):
    """Motor torque on the wheel, band load torque, and a friction torque pair wheel -> band."""
    return [(mech.W, (motor - pair) * mech.N.z), (mech.B, (band + pair) * mech.N.z)]


def traction_torque(model: int, slip_speed, z_sym):
    """Torque on the band (N m) of counter-model ``model`` (1 Coulomb, 2 LuGre)."""
    r_c = P["R_w"] + P["t_r"]
    if model == 1:
        return r_c * TractionCoulomb().force(slip_speed)
    return r_c * TractionLuGre().force(slip_speed, z_sym)


def arm_loads(c: kin.Circle, mech: kin.Mechanism):
    """Spring-damper torque pair between arm ``c.arm`` and the band (hinge frame)."""
    law = ArmSpringDamper()
    torque = law.torque_on_arm(c.q - q_b, c.u - u_b)
    return [(c.arm, torque * mech.N.z), (c.hinge_frame, -torque * mech.N.z)]


def contact_loads(mech: kin.Mechanism, c: kin.Circle, rl: kin.Roller, fn, ft):
    """Contact force on the circle and its reaction on the wheel at the roller surface point."""
    g = kin.contact_geometry(mech, c, rl)
    F = fn * g.n + ft * g.tang
    return g, [(c.P, F), (g.contact_point, -F)]


@lru_cache(maxsize=None)
def kernels() -> tuple[Kernel, ...]:
    """Derive the core, circle and contact kernels (independent of N_c and N_r)."""
    mech, circle, roller, q_i, u_i = _generic()
    q = [q_w, q_b, q_i]
    u = [u_w, u_b, u_i]

    # Core: wheel and band rigid bodies spinning about n3 through the fixed point O.
    wheel = me.RigidBody("wheel", mech.O, mech.W, sm.S.One, (me.inertia(mech.W, 0, 0, P["I_W"]), mech.O))
    band = me.RigidBody("band", mech.O, mech.B, sm.S.One, (me.inertia(mech.B, 0, 0, P["I_B"]), mech.O))
    M, F = _kane_on(mech, q, u, [wheel, band], core_loads(mech, T_m, tau_b, tau_wb))
    core = Kernel(
        "core_kernel", (T_m, tau_b, tau_wb),
        (("M_ww", _reduce(M[0, 0], q_i, u_i)), ("M_bb", _reduce(M[1, 1], q_i, u_i)),
         ("F_w", _reduce(F[0], q_i, u_i)), ("F_b", _reduce(F[1], q_i, u_i))),
        "Wheel and band inertia (kg m^2) and generalized forces (N m) of motor torque T_m, band\n"
        "torque tau_b and wheel-band friction torque pair tau_wb (on the band; reaction on the wheel).",
    )
    for (r, s) in [(0, 1), (1, 0), (0, 2), (2, 0), (1, 2), (2, 1), (2, 2)]:
        assert M[r, s] == 0

    # One generic circle with its arm spring-damper.
    M, F = _kane_on(mech, q, u, [circle.particle], arm_loads(circle, mech))
    assert all(M[0, k] == 0 and M[k, 0] == 0 for k in range(3)) and F[0] == 0
    circ = Kernel(
        "circle_kernel", (phi, c_phi, s_phi, U_B, U_I),
        (("M_bb", _reduce(M[1, 1], q_i, u_i)), ("M_bi", _reduce(M[1, 2], q_i, u_i)),
         ("M_ii", _reduce(M[2, 2], q_i, u_i)),
         ("F_b", _reduce(F[1], q_i, u_i)), ("F_i", _reduce(F[2], q_i, u_i))),
        "Contribution of one circle: band/circle mass-matrix entries (kg m^2) and forcing (N m)\n"
        "(velocity terms and arm spring-damper) for arm angle phi = q_i - q_b (rad).",
    )

    # One roller-circle contact with symbolic normal/tangential force magnitudes.
    geo, loads = contact_loads(mech, circle, roller, f_n, f_t)
    M, F = _kane_on(mech, q, u, [], loads)
    assert M == sm.zeros(3, 3)
    red = lambda e: _reduce(e, q_i, u_i)  # noqa: E731
    dist = red(geo.dist)
    contact = Kernel(
        "contact_kernel", (c_rho, s_rho, c_phi, s_phi, U_W, U_B, U_I),
        (("dist", dist), ("delta_dot", red(geo.delta_dot)), ("v_slide", red(geo.v_slide)))
        + tuple((f"Gn_{k}", red(F[n].diff(f_n))) for n, k in enumerate("wbi"))
        + tuple((f"Gt_{k}", red(F[n].diff(f_t))) for n, k in enumerate("wbi")),
        "Roller-circle contact seen from the circle's hinge frame: centre distance (m), overlap\n"
        "rate (m/s), sliding speed along z x n (m/s) and the generalized forces per newton of\n"
        "normal (Gn_*) and tangential (Gt_*) force on rows w, b, i (m).",
    )
    dist_sq = dist**2
    dist_only = Kernel("contact_distance_sq", (c_rho, s_rho, c_phi, s_phi), (("dist_sq", dist_sq),),
                       "Squared distance (m^2) between a roller centre and a circle centre (cheap pre-check).")
    return (core, circ, contact, dist_only)


def energy_kernels() -> tuple[Kernel, ...]:
    """Kinetic and potential energy of the core and of one circle (for conservation tests)."""
    mech, circle, roller, q_i, u_i = _generic()
    wheel_T = P["I_W"] * U_W**2 / 2
    band_T = P["I_B"] * U_B**2 / 2
    T_i = circle.particle.kinetic_energy(mech.N)
    V_i = ArmSpringDamper().potential(q_i - q_b)
    core = Kernel("core_energy", (U_W, U_B), (("E", wheel_T + band_T),),
                  "Kinetic energy (J) of wheel and band.")
    circ = Kernel("circle_energy", (phi, c_phi, s_phi, U_B, U_I),
                  (("E", _reduce(T_i + V_i, q_i, u_i)),),
                  "Kinetic energy of one circle plus its arm spring energy (J).")
    return (core, circ)


@dataclass
class FullSystem:
    """The whole model with every circle and roller unrolled (the oracle for small N_c)."""

    q: list
    u: list
    mass_matrix: sm.Matrix
    forcing: sm.Matrix
    n_circles: int
    n_rollers: int


def full_system(n_circles: int, n_rollers: int, contact_model: int = 0) -> FullSystem:
    """Derive the complete model with one ``KanesMethod`` call (all loads in place).

    Frames are oriented from N (absolute angles), unlike the kernels. The motor torque is the
    symbol ``T_m``; the slider friction, the candidate band effects (time symbol ``t``) and
    the contact laws enter with their full expressions: impacts with tangential traction at
    every roller-circle pair (``contact_model = 0``) or the lumped Coulomb (1) or LuGre (2,
    bristle deflection symbol ``z``) wheel-band friction.
    """
    mech = kin.mechanism()
    impact = HuntCrossleyImpact()
    slider = SliderFriction()
    q, u = [q_w, q_b], [u_w, u_b]
    circles = []
    for i in range(n_circles):
        qi, ui = circle_coordinates(i + 1)
        q.append(qi)
        u.append(ui)
        circles.append(kin.add_circle(mech, qi, ui, 2 * sm.pi * i / n_circles, f"{i + 1}", relative=False))
    rollers = [kin.add_roller(mech, 2 * sm.pi * j / n_rollers, f"r{j}") for j in range(n_rollers)]
    bodies = [
        me.RigidBody("wheel", mech.O, mech.W, sm.S.One, (me.inertia(mech.W, 0, 0, P["I_W"]), mech.O)),
        me.RigidBody("band", mech.O, mech.B, sm.S.One, (me.inertia(mech.B, 0, 0, P["I_B"]), mech.O)),
    ] + [c.particle for c in circles]
    pair = 0 if contact_model == 0 else traction_torque(contact_model, (P["R_w"] + P["t_r"]) * (u_w - u_b), z_lugre)
    band_torque = slider.torque(u_b) + BandEffects().torque(u_b, q_b, t_sym, slider.torque(u_b))
    loads = core_loads(mech, T_m, band_torque, pair)
    for c in circles:
        loads += arm_loads(c, mech)
        for rl in (rollers if contact_model == 0 else []):
            g = kin.contact_geometry(mech, c, rl)
            fn = sm.Piecewise((impact.normal_force(g.delta, g.delta_dot), g.delta > 0), (0, True))
            _, cl = contact_loads(mech, c, rl, fn, ContactTraction().force(fn, g.v_slide))
            loads += cl
    M, F = _kane_on(mech, q, u, bodies, loads)
    return FullSystem(q, u, M, F, n_circles, n_rollers)
