# ----------------------------------------------------------------------------
# szdyn generated code (assembly) -- DO NOT EDIT.
# Source: derive/codegen.py (run as `python -m derive`), SymPy 1.14.0.
# Regenerate with `make derive`; tests check that this file is reproduced byte for byte.
# State order: x = [q_w, q_b, q_1 .. q_Nc, u_w, u_b, u_1 .. u_Nc, z_lugre]  (rad, rad/s, m)
# Parameter order (p): I_W, I_B, m_c, R_bo, d, t_c, R_w, t_r, n_rollers, k_c, b_c, k_imp, b_imp, n_imp, impact_clamp, mu_s, mu_k, gamma, m_b, g, drive_mode, contact_model, F_nw, mu_ws, mu_wk, v_ws, v_weps, sigma0, sigma1, sigma2, c_visc, mu_st, v_st, fric_asym, tau_lift, a_rev, phi_rev, a_tooth, phi_tooth, n_teeth, k_drift, mu_t, v_teps, k_drive, c_drive
# ----------------------------------------------------------------------------
"""Spiral Zipper right-hand side: assembly of the generated kernels.

State vector: x = [q_w, q_b, q_1 .. q_Nc, u_w, u_b, u_1 .. u_Nc, z_lugre]  (rad, rad/s, m);
N_c = (len(x) - N_AUX)//2 - 2.
Parameter vector p: float64 array in the order of ``PARAM_NAMES``; see ``PARAM_DOCS``.
Drive array (see docs/CONTRACT.md): [K, t_0..t_{K-1}, v_0..v_{K-1}, c_0..c_{K-1}].
Imports only math, numpy and numba.
"""
import math

import numba as nb
import numpy as np

from .kernels import (circle_energy, circle_kernel, contact_distance_sq, contact_kernel,
                      core_energy, core_kernel, impact_normal_force, impact_potential,
                      lugre_force, lugre_z_dot, slider_torque, traction_coulomb_force,
                      band_effects_torque, traction_tangential_force, drive_compliance_torque)

KERNELS_SHA256 = "f2b03de6916768d90ad907df0e7cad4600883f2f5211d855772ce1ae3673f6ac"

PARAM_NAMES = (
    "I_W",
    "I_B",
    "m_c",
    "R_bo",
    "d",
    "t_c",
    "R_w",
    "t_r",
    "n_rollers",
    "k_c",
    "b_c",
    "k_imp",
    "b_imp",
    "n_imp",
    "impact_clamp",
    "mu_s",
    "mu_k",
    "gamma",
    "m_b",
    "g",
    "drive_mode",
    "contact_model",
    "F_nw",
    "mu_ws",
    "mu_wk",
    "v_ws",
    "v_weps",
    "sigma0",
    "sigma1",
    "sigma2",
    "c_visc",
    "mu_st",
    "v_st",
    "fric_asym",
    "tau_lift",
    "a_rev",
    "phi_rev",
    "a_tooth",
    "phi_tooth",
    "n_teeth",
    "k_drift",
    "mu_t",
    "v_teps",
    "k_drive",
    "c_drive",
)
PARAM_INDEX = {name: i for i, name in enumerate(PARAM_NAMES)}
#: name -> (SI unit, meaning)
PARAM_DOCS = {
    "I_W": ("kg*m^2", "wheel (with rollers) inertia about the tube axis n3"),
    "I_B": ("kg*m^2", "band tube inertia about n3 (J_B in the thesis)"),
    "m_c": ("kg", "mass of one small circle (particle at the arm tip)"),
    "R_bo": ("m", "band inner radius: radius of the arm hinges Q_i"),
    "d": ("m", "arm length from hinge Q_i to circle centre P_i"),
    "t_c": ("m", "radius of a small circle"),
    "R_w": ("m", "radius of the roller centres on the wheel"),
    "t_r": ("m", "roller radius"),
    "n_rollers": ("1", "number of rollers N_r (integer stored as float)"),
    "k_c": ("N*m/rad", "torsional stiffness of each arm"),
    "b_c": ("N*m*s/rad", "torsional damping of each arm"),
    "k_imp": ("N/m^n", "impact stiffness in F = delta^n (k_imp + b_imp delta_dot)"),
    "b_imp": ("N*s/m^(n+1)", "impact damping in F = delta^n (k_imp + b_imp delta_dot)"),
    "n_imp": ("1", "impact exponent n (thesis: 3)"),
    "impact_clamp": ("1", "1: clamp the impact force at 0 (no attraction); 0: thesis formula as printed"),
    "mu_s": ("1", "slider static (peak) friction coefficient"),
    "mu_k": ("1", "slider kinetic friction coefficient"),
    "gamma": ("rad/s", "slider static band: band speed below which friction is regularised"),
    "m_b": ("kg", "mass whose weight loads the slider (normal force m_b g)"),
    "g": ("m/s^2", "gravitational acceleration"),
    "drive_mode": ("1", "0: prescribed wheel motion (drive array is speed); 1: motor torque; 2: prescribed motor motion through a compliant drive (k_drive, c_drive)"),
    "contact_model": ("1", "wheel-band transmission: 0 impacts (thesis), 1 Coulomb friction, 2 LuGre friction"),
    "F_nw": ("N", "friction counter-models: total normal force of the rollers on the band"),
    "mu_ws": ("1", "friction counter-models: static (breakaway) coefficient, roller on band"),
    "mu_wk": ("1", "friction counter-models: Coulomb (kinetic) coefficient, roller on band"),
    "v_ws": ("m/s", "friction counter-models: Stribeck sliding speed"),
    "v_weps": ("m/s", "Coulomb counter-model: regularisation speed of sign(v) ~ tanh(v/v_weps)"),
    "sigma0": ("N/m", "LuGre bristle stiffness"),
    "sigma1": ("N*s/m", "LuGre bristle damping"),
    "sigma2": ("N*s/m", "LuGre viscous friction"),
    "c_visc": ("N*m*s/rad", "slider_viscous: viscous torque -c_visc u_b on the band"),
    "mu_st": ("1", "slider_stribeck: extra friction coefficient at low band speed"),
    "v_st": ("rad/s", "slider_stribeck: band speed over which the extra friction decays"),
    "fric_asym": ("1", "friction_asymmetry: slider friction scaled by (1 + fric_asym sign(u_b))"),
    "tau_lift": ("N*m", "load_lift: constant torque of the payload weight through the helix lead, m g P_B/(2 pi)"),
    "a_rev": ("N*m", "position_periodic: torque amplitude once per band revolution"),
    "phi_rev": ("rad", "position_periodic: phase of the once-per-revolution torque"),
    "a_tooth": ("N*m", "position_periodic: torque amplitude once per tooth pitch"),
    "phi_tooth": ("rad", "position_periodic: phase of the per-tooth torque"),
    "n_teeth": ("1", "position_periodic: teeth per wrap N (per-tooth period 2 pi / N in q_b)"),
    "k_drift": ("1/s", "friction_drift: slider friction scaled by (1 + k_drift t)"),
    "mu_t": ("1", "wheel_band_traction: tangential friction coefficient at the roller contacts"),
    "v_teps": ("m/s", "wheel_band_traction: regularisation speed of sign(v) ~ tanh(v/v_teps)"),
    "k_drive": ("N*m/rad", "drive_compliance: torsional stiffness between motor and wheel (drive_mode 2)"),
    "c_drive": ("N*m*s/rad", "drive_compliance: torsional damping between motor and wheel (drive_mode 2)"),
}
#: name -> admissible values, checked by szdyn.params.validate
PARAM_BOUNDS = {
    "I_W": "> 0",
    "I_B": "> 0",
    "m_c": "> 0",
    "R_bo": "> 0",
    "d": "> 0",
    "t_c": "> 0",
    "R_w": "> 0",
    "t_r": "> 0",
    "n_rollers": "positive integer",
    "k_c": ">= 0",
    "b_c": ">= 0",
    "k_imp": ">= 0",
    "b_imp": ">= 0",
    "n_imp": "> 0",
    "impact_clamp": "one of 0,1",
    "mu_s": ">= 0",
    "mu_k": ">= 0",
    "gamma": "> 0",
    "m_b": ">= 0",
    "g": "> 0",
    "drive_mode": "one of 0,1,2",
    "contact_model": "one of 0,1,2",
    "F_nw": ">= 0",
    "mu_ws": ">= 0",
    "mu_wk": ">= 0",
    "v_ws": "> 0",
    "v_weps": "> 0",
    "sigma0": "> 0",
    "sigma1": ">= 0",
    "sigma2": ">= 0",
    "c_visc": ">= 0",
    "mu_st": ">= 0",
    "v_st": "> 0",
    "fric_asym": "real",
    "tau_lift": "real",
    "a_rev": ">= 0",
    "phi_rev": "real",
    "a_tooth": ">= 0",
    "phi_tooth": "real",
    "n_teeth": "positive integer",
    "k_drift": "real",
    "mu_t": ">= 0",
    "v_teps": "> 0",
    "k_drive": ">= 0",
    "c_drive": ">= 0",
}

AUX_STATES = ('z_lugre',)
N_AUX = len(AUX_STATES)

_I_I_W = 0
_I_I_B = 1
_I_m_c = 2
_I_R_bo = 3
_I_d = 4
_I_t_c = 5
_I_R_w = 6
_I_t_r = 7
_I_n_rollers = 8
_I_k_c = 9
_I_b_c = 10
_I_k_imp = 11
_I_b_imp = 12
_I_n_imp = 13
_I_impact_clamp = 14
_I_mu_s = 15
_I_mu_k = 16
_I_gamma = 17
_I_m_b = 18
_I_g = 19
_I_drive_mode = 20
_I_contact_model = 21
_I_F_nw = 22
_I_mu_ws = 23
_I_mu_wk = 24
_I_v_ws = 25
_I_v_weps = 26
_I_sigma0 = 27
_I_sigma1 = 28
_I_sigma2 = 29
_I_c_visc = 30
_I_mu_st = 31
_I_v_st = 32
_I_fric_asym = 33
_I_tau_lift = 34
_I_a_rev = 35
_I_phi_rev = 36
_I_a_tooth = 37
_I_phi_tooth = 38
_I_n_teeth = 39
_I_k_drift = 40
_I_mu_t = 41
_I_v_teps = 42
_I_k_drive = 43
_I_c_drive = 44

TWO_PI = 2.0 * math.pi


@nb.njit(cache=True)
def n_circles_of(n_state):
    """N_c from the state length 2 (N_c + 2) + N_AUX."""
    return (n_state - N_AUX) // 2 - 2


@nb.njit(cache=True)
def drive_eval(drive, t):
    """Wheel drive at time t: (angle rad, speed rad/s, acceleration rad/s^2).

    With torque drive the 'speed' slot holds the motor torque (N m). Piecewise linear in the
    knots, held constant before the first and after the last knot; the angle is the exact
    integral of the speed.
    """
    K = int(drive[0])
    ts = drive[1:1 + K]
    vs = drive[1 + K:1 + 2 * K]
    cs = drive[1 + 2 * K:1 + 3 * K]
    if K == 1 or t < ts[0]:
        return cs[0] + vs[0] * (t - ts[0]), vs[0], 0.0
    if t >= ts[K - 1]:
        return cs[K - 1] + vs[K - 1] * (t - ts[K - 1]), vs[K - 1], 0.0
    lo = 0
    hi = K - 1
    while hi - lo > 1:  # bisection: sampled profiles may have many knots
        mid = (lo + hi) // 2
        if ts[mid] <= t:
            lo = mid
        else:
            hi = mid
    s = t - ts[lo]
    a = (vs[hi] - vs[lo]) / (ts[hi] - ts[lo])
    return cs[lo] + vs[lo] * s + 0.5 * a * s * s, vs[lo] + a * s, a


@nb.njit(cache=True)
def contact_window(p, n_circles, phi_max):
    """Number of consecutive hinges to test on each roller pass (all of them if N_c is small).

    A contact needs |roller centre - circle centre| < t_c + t_r. A circle centre lies at radius
    r >= R_bo - d (triangle inequality) and, for arm deflections |phi| <= phi_max < pi/2, within
    atan(d sin(phi_max) / (R_bo - d)) of its hinge's ray (else within asin(d / R_bo)). For two
    points at radii R_w and r >= R_w the distance grows with the angle between them, so by the
    law of cosines the roller can reach a circle centre only within
    acos((R_w^2 + r_min^2 - reach^2) / (2 R_w r_min)) of its own ray. The hinges are evenly
    spaced, so the candidates are the hinges within the sum of the two angles of the roller.
    """
    reach = p[_I_t_c] + p[_I_t_r]
    R_w = p[_I_R_w]
    d = p[_I_d]
    R_bo = p[_I_R_bo]
    r_min = R_bo - d
    if r_min >= R_w:
        c = (R_w * R_w + r_min * r_min - reach * reach) / (2.0 * R_w * r_min)
        reach_angle = math.acos(max(-1.0, min(1.0, c)))
    else:  # roller centres outside the ring of circles: the cruder bound D >= R_w sin(angle)
        reach_angle = math.asin(min(1.0, reach / R_w)) if reach < R_w else math.pi
    if phi_max < 0.5 * math.pi:
        offset = math.atan2(d * math.sin(phi_max), r_min)
    else:
        offset = math.asin(min(1.0, d / R_bo))
    half = int((reach_angle + offset) / (TWO_PI / n_circles)) + 1
    return min(2 * half + 1, n_circles)


@nb.njit(cache=True)
def slip_speed(p, u_w, u_b):
    """Sliding speed (m/s) of the rollers on the band at the contact radius R_w + t_r."""
    return (p[_I_R_w] + p[_I_t_r]) * (u_w - u_b)


@nb.njit(cache=True)
def traction_torque(x, p, u_w):
    """Torque (N m) on the band of the lumped wheel-band friction counter-model (0 for impacts)."""
    model = int(p[_I_contact_model] + 0.5)
    if model == 0:
        return 0.0
    n = n_circles_of(x.shape[0]) + 2
    v = slip_speed(p, u_w, x[n + 1])
    if model == 1:
        return (p[_I_R_w] + p[_I_t_r]) * traction_coulomb_force(v, p)
    return (p[_I_R_w] + p[_I_t_r]) * lugre_force(v, x[2 * n], p)


@nb.njit(cache=True)
def _assemble(t, x, p, q_w, u_w, T_m, m_bi, m_ii, f, c_phi, s_phi, want_energy):
    """Arrowhead mass matrix and forcing of the whole system.

    Fills the band-circle coupling ``m_bi``, circle diagonal ``m_ii`` and circle forcing ``f``
    (each shape (N_c,)), and returns ``(M_ww, M_bb, F_w, F_b, n_contacts, V_contacts)``;
    ``V_contacts`` (elastic energy in the contacts) is only computed if ``want_energy``.
    The wheel's angle, speed and torque are arguments because a prescribed drive overrides
    the state.
    """
    nc = n_circles_of(x.shape[0])
    n = nc + 2
    q_b = x[1]
    u_b = x[n + 1]
    model = int(p[_I_contact_model] + 0.5)
    tau_slider = slider_torque(u_b, p)
    tau_b = tau_slider + band_effects_torque(t, q_b, u_b, tau_slider, p)
    M_ww, M_bb, F_w, F_b = core_kernel(T_m, tau_b, traction_torque(x, p, u_w), p)
    phi_max = 0.0
    for i in range(nc):
        phi = x[2 + i] - q_b
        phi_max = max(phi_max, abs(phi))
        c = math.cos(phi)
        s = math.sin(phi)
        c_phi[i] = c
        s_phi[i] = s
        dM_bb, M_bi, M_ii, dF_b, F_i = circle_kernel(phi, c, s, u_b, x[n + 2 + i], p)
        M_bb += dM_bb
        m_bi[i] = M_bi
        m_ii[i] = M_ii
        F_b += dF_b
        f[i] = F_i

    n_contacts = 0
    V_contacts = 0.0
    if model != 0:  # friction counter-models: no impacts
        return M_ww, M_bb, F_w, F_b, n_contacts, V_contacts
    nr = int(p[_I_n_rollers] + 0.5)
    reach = p[_I_t_c] + p[_I_t_r]
    reach_sq = reach * reach
    pitch = TWO_PI / nc
    ncand = contact_window(p, nc, phi_max)
    cp = math.cos(pitch)
    sp = math.sin(pitch)
    for j in range(nr):
        ang = q_w + TWO_PI * j / nr - q_b  # roller j's angle seen from the band
        k = int(math.floor(ang / pitch + 0.5)) - (ncand - 1) // 2
        rho = ang - k * pitch
        cr = math.cos(rho)
        sr = math.sin(rho)
        for m in range(ncand):
            i = (k + m) % nc
            if contact_distance_sq(cr, sr, c_phi[i], s_phi[i], p) < reach_sq:
                dist, delta_dot, v_slide, Gn_w, Gn_b, Gn_i, Gt_w, Gt_b, Gt_i = contact_kernel(
                    cr, sr, c_phi[i], s_phi[i], u_w, u_b, x[n + 2 + i], p)
                delta = reach - dist
                f_n = impact_normal_force(delta, delta_dot, p)
                F_w += f_n * Gn_w
                F_b += f_n * Gn_b
                f[i] += f_n * Gn_i
                if p[_I_mu_t] != 0.0:  # wheel_band_traction (candidate effect)
                    f_t = traction_tangential_force(f_n, v_slide, p)
                    F_w += f_t * Gt_w
                    F_b += f_t * Gt_b
                    f[i] += f_t * Gt_i
                n_contacts += 1
                if want_energy:
                    V_contacts += impact_potential(delta, p)
            # next hinge: rho -> rho - pitch, by rotation instead of new trig calls
            cr, sr = cr * cp + sr * sp, sr * cp - cr * sp
    return M_ww, M_bb, F_w, F_b, n_contacts, V_contacts


@nb.njit(cache=True)
def _wheel(t, x, p, drive):
    """Wheel (angle, speed, acceleration, motor torque) from the drive or the state.

    drive_mode 0: the drive prescribes the wheel's motion; 1: the drive is the motor torque;
    2: the drive prescribes the motor's motion and a compliant drive (k_drive, c_drive)
    carries the torque to the wheel, whose motion is then a state like the band's.
    """
    n = n_circles_of(x.shape[0]) + 2
    mode = int(p[_I_drive_mode] + 0.5)
    if mode == 0:
        q_w, u_w, acc_w = drive_eval(drive, t)
        return q_w, u_w, acc_w, 0.0
    if mode == 1:
        _, T_m, _ = drive_eval(drive, t)
        return x[0], x[n], 0.0, T_m
    motor_angle, motor_speed, _ = drive_eval(drive, t)
    return x[0], x[n], 0.0, drive_compliance_torque(motor_angle, motor_speed, x[0], x[n], p)


@nb.njit(cache=True)
def rhs(t, x, p, drive, out):
    """Time derivative of the state: writes dx/dt (shape (2 N_c + 4 + N_AUX,)) into ``out``.

    Solves the arrowhead mass matrix in O(N_c) by the Schur complement on the band row:
    the wheel row is decoupled, each circle row couples only to the band.
    """
    nc = n_circles_of(x.shape[0])
    n = nc + 2
    work = np.empty(5 * nc)
    m_bi = work[0:nc]
    m_ii = work[nc:2 * nc]
    f = work[2 * nc:3 * nc]
    q_w, u_w, acc_w, T_m = _wheel(t, x, p, drive)
    M_ww, M_bb, F_w, F_b, _, _ = _assemble(t, x, p, q_w, u_w, T_m, m_bi, m_ii, f,
                                           work[3 * nc:4 * nc], work[4 * nc:5 * nc], False)
    for k in range(n):
        out[k] = x[n + k]
    out[0] = u_w
    if int(p[_I_contact_model] + 0.5) == 2:
        out[2 * n] = lugre_z_dot(slip_speed(p, u_w, x[n + 1]), x[2 * n], p)
    else:
        out[2 * n] = 0.0
    if p[_I_drive_mode] < 0.5:
        out[n] = acc_w  # the motor supplies whatever torque the prescribed motion needs
    else:
        out[n] = F_w / M_ww
    S = M_bb
    r = F_b
    for i in range(nc):
        w = m_bi[i] / m_ii[i]
        S -= w * m_bi[i]
        r -= w * f[i]
    du_b = r / S
    out[n + 1] = du_b
    for i in range(nc):
        out[n + 2 + i] = (f[i] - m_bi[i] * du_b) / m_ii[i]


@nb.njit(cache=True)
def mass_matrix_forcing(t, x, p, drive):
    """Dense mass matrix (n, n) and forcing (n,), n = N_c + 2, as assembled (for checks).

    Rows are [w, b, 1..N_c]; M @ du = F. The wheel row is the free wheel's equation even
    when the drive prescribes its motion.
    """
    nc = n_circles_of(x.shape[0])
    n = nc + 2
    work = np.empty(5 * nc)
    q_w, u_w, acc_w, T_m = _wheel(t, x, p, drive)
    M_ww, M_bb, F_w, F_b, _, _ = _assemble(t, x, p, q_w, u_w, T_m, work[0:nc], work[nc:2 * nc],
                                           work[2 * nc:3 * nc], work[3 * nc:4 * nc], work[4 * nc:], False)
    M = np.zeros((n, n))
    F = np.zeros(n)
    M[0, 0] = M_ww
    M[1, 1] = M_bb
    F[0] = F_w
    F[1] = F_b
    for i in range(nc):
        M[1, 2 + i] = work[i]
        M[2 + i, 1] = work[i]
        M[2 + i, 2 + i] = work[nc + i]
        F[2 + i] = work[2 * nc + i]
    return M, F


@nb.njit(cache=True)
def wheel_reaction_torque(t, x, p, drive):
    """Generalized force of the contacts (or friction) on the wheel row (N m): minus the torque
    the motor must add, beyond I_W times the wheel's acceleration, to hold a prescribed motion."""
    nc = n_circles_of(x.shape[0])
    work = np.empty(5 * nc)
    q_w, u_w, acc_w, T_m = _wheel(t, x, p, drive)
    M_ww, M_bb, F_w, F_b, _, _ = _assemble(t, x, p, q_w, u_w, 0.0, work[0:nc], work[nc:2 * nc],
                                           work[2 * nc:3 * nc], work[3 * nc:4 * nc], work[4 * nc:], False)
    return F_w


@nb.njit(cache=True)
def energy(x, p):
    """Total mechanical energy (J): kinetic + arm springs + elastic contact energy.

    Uses the wheel angle and speed from the state (meaningful for torque drive).
    """
    nc = n_circles_of(x.shape[0])
    n = nc + 2
    work = np.empty(5 * nc)
    _, _, _, _, _, V = _assemble(0.0, x, p, x[0], x[n], 0.0, work[0:nc], work[nc:2 * nc],
                                 work[2 * nc:3 * nc], work[3 * nc:4 * nc], work[4 * nc:], True)
    E = core_energy(x[n], x[n + 1], p) + V
    for i in range(nc):
        E += circle_energy(x[2 + i] - x[1], work[3 * nc + i], work[4 * nc + i], x[n + 1], x[n + 2 + i], p)
    return E


@nb.njit(cache=True)
def contact_count(t, x, p, drive):
    """Number of roller-circle pairs in contact at state x and time t."""
    nc = n_circles_of(x.shape[0])
    work = np.empty(5 * nc)
    q_w, u_w, acc_w, T_m = _wheel(t, x, p, drive)
    _, _, _, _, nct, _ = _assemble(t, x, p, q_w, u_w, T_m, work[0:nc], work[nc:2 * nc],
                                   work[2 * nc:3 * nc], work[3 * nc:4 * nc], work[4 * nc:], False)
    return nct


@nb.njit(cache=True)
def per_sample_outputs(t, xs, p, drive):
    """Contact count and contact torque on the wheel (N m) at each saved sample.

    ``t`` shape (n,), ``xs`` shape (n, len(x)); returns two arrays of shape (n,). Lives here,
    not in the runtime, so that its compiled code is rebuilt whenever the model is regenerated.
    """
    n = t.shape[0]
    counts = np.empty(n)
    torque = np.empty(n)
    for k in range(n):
        counts[k] = contact_count(t[k], xs[k], p, drive)
        torque[k] = wheel_reaction_torque(t[k], xs[k], p, drive)
    return counts, torque


def state_names(n_circles):
    """Names of the state entries, in order."""
    qs = ["q_w", "q_b"] + [f"q_{i}" for i in range(1, n_circles + 1)]
    return qs + ["u" + s[1:] for s in qs] + list(AUX_STATES)


def state_size(n_circles):
    """Length of the state vector for N_c circles."""
    return 2 * (n_circles + 2) + N_AUX


def make_ivp_fun(p, drive):
    """A ``scipy.integrate.solve_ivp``-compatible ``fun(t, y) -> dy/dt``.

    ``p`` (parameter vector in ``PARAM_NAMES`` order) and ``drive`` (drive array) are
    converted to float64 once here, not on every call.
    """
    p = np.ascontiguousarray(p, dtype=np.float64)
    drive = np.ascontiguousarray(drive, dtype=np.float64)
    if p.shape != (len(PARAM_NAMES),):
        raise ValueError(f"p must have shape ({len(PARAM_NAMES)},) in PARAM_NAMES order, got {p.shape}")

    def fun(t, y):
        y = np.ascontiguousarray(y, dtype=np.float64)
        out = np.empty_like(y)
        rhs(float(t), y, p, drive, out)
        return out

    return fun
