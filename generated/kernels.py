# ----------------------------------------------------------------------------
# szdyn generated code (kernels) -- DO NOT EDIT.
# Source: derive/codegen.py (run as `python -m derive`), SymPy 1.14.0.
# Regenerate with `make derive`; tests check that this file is reproduced byte for byte.
# State order: x = [q_w, q_b, q_1 .. q_Nc, u_w, u_b, u_1 .. u_Nc, z_lugre]  (rad, rad/s, m)
# Parameter order (p): I_W, I_B, m_c, R_bo, d, t_c, R_w, t_r, n_rollers, k_c, b_c, k_imp, b_imp, n_imp, impact_clamp, mu_s, mu_k, gamma, m_b, g, drive_mode, contact_model, F_nw, mu_ws, mu_wk, v_ws, v_weps, sigma0, sigma1, sigma2, c_visc, mu_st, v_st, fric_asym, tau_lift, a_rev, phi_rev, a_tooth, phi_tooth, n_teeth, k_drift, mu_t, v_teps, k_drive, c_drive
# ----------------------------------------------------------------------------
"""Scalar kernels of the Spiral Zipper model, derived with sympy KanesMethod.

One generic circle, one generic roller-circle contact, wheel/band core, force laws and
energies. The assembly in ``spiral_zipper.py`` loops over circles and contacts.
"""
import math

import numba as nb


@nb.njit(cache=True)
def fpow(x, n):
    """x**n, by multiplication for n = 1, 2, 3, 4 (equal to within rounding, much faster than pow)."""
    if n == 3.0:
        return x * x * x
    if n == 2.0:
        return x * x
    if n == 4.0:
        x2 = x * x
        return x2 * x2
    if n == 1.0:
        return x
    return x ** n


@nb.njit(cache=True)
def core_kernel(T_m, tau_b, tau_wb, p):
    """Wheel and band inertia (kg m^2) and generalized forces (N m) of motor torque T_m, band
    torque tau_b and wheel-band friction torque pair tau_wb (on the band; reaction on the wheel)."""
    I_B = p[1]
    I_W = p[0]
    M_ww = I_W
    M_bb = I_B
    F_w = T_m - tau_wb
    F_b = tau_b + tau_wb
    return M_ww, M_bb, F_w, F_b


@nb.njit(cache=True)
def circle_kernel(phi, c_phi, s_phi, u_b, u_i, p):
    """Contribution of one circle: band/circle mass-matrix entries (kg m^2) and forcing (N m)
    (velocity terms and arm spring-damper) for arm angle phi = q_i - q_b (rad)."""
    R_bo = p[3]
    b_c = p[10]
    d = p[4]
    k_c = p[9]
    m_c = p[2]
    x0 = R_bo*d*m_c
    x1 = b_c*(-u_b + u_i) + k_c*phi
    M_bb = R_bo**2*m_c
    M_bi = -c_phi*x0
    M_ii = d**2*m_c
    F_b = -s_phi*u_i**2*x0 + x1
    F_i = R_bo*d*m_c*s_phi*u_b**2 - x1
    return M_bb, M_bi, M_ii, F_b, F_i


@nb.njit(cache=True)
def contact_kernel(c_rho, s_rho, c_phi, s_phi, u_w, u_b, u_i, p):
    """Roller-circle contact seen from the circle's hinge frame: centre distance (m), overlap
    rate (m/s), sliding speed along z x n (m/s) and the generalized forces per newton of
    normal (Gn_*) and tangential (Gt_*) force on rows w, b, i (m)."""
    R_bo = p[3]
    R_w = p[6]
    d = p[4]
    t_r = p[7]
    x0 = R_w*s_rho
    x1 = d*s_phi
    x2 = -x0 - x1
    x3 = x2**2
    x4 = R_w*c_rho
    x5 = c_phi*d
    x6 = R_bo - x4 - x5
    x7 = x6**2
    x8 = x3 + x7
    x9 = math.sqrt(x8)
    x10 = 1/x9
    x11 = t_r/x8
    x12 = x11*x3
    x13 = x10*x2
    x14 = x10*x6
    x15 = c_rho*x14 + s_rho*x13
    x16 = d*(c_phi*x14 + s_phi*x13)
    dist = x9
    delta_dot = x10*(-x2*(R_bo*u_b - u_i*x5 - u_w*x4) - x6*(u_i*x1 + u_w*x0))
    v_slide = -R_w*u_w*x15 - u_i*x16 - u_w*x12 + x10*x6*(R_bo*u_b - t_r*u_w*x14)
    Gn_w = R_w*(-c_rho*x13 + s_rho*x10*x6)
    Gn_b = R_bo*x13
    Gn_i = -d*(c_phi*x13 - s_phi*x14)
    Gt_w = -R_w*x15 - x11*x7 - x12
    Gt_b = R_bo*x14
    Gt_i = -x16
    return dist, delta_dot, v_slide, Gn_w, Gn_b, Gn_i, Gt_w, Gt_b, Gt_i


@nb.njit(cache=True)
def contact_distance_sq(c_rho, s_rho, c_phi, s_phi, p):
    """Squared distance (m^2) between a roller centre and a circle centre (cheap pre-check)."""
    R_bo = p[3]
    R_w = p[6]
    d = p[4]
    dist_sq = (-R_w*s_rho - d*s_phi)**2 + (R_bo - R_w*c_rho - c_phi*d)**2
    return dist_sq


@nb.njit(cache=True)
def core_energy(u_w, u_b, p):
    """Kinetic energy (J) of wheel and band."""
    I_B = p[1]
    I_W = p[0]
    E = (1.0/2.0)*I_B*u_b**2 + (1.0/2.0)*I_W*u_w**2
    return E


@nb.njit(cache=True)
def circle_energy(phi, c_phi, s_phi, u_b, u_i, p):
    """Kinetic energy of one circle plus its arm spring energy (J)."""
    R_bo = p[3]
    d = p[4]
    k_c = p[9]
    m_c = p[2]
    E = (1.0/2.0)*k_c*phi**2 + (1.0/2.0)*m_c*(R_bo**2*u_b**2 - 2*R_bo*c_phi*d*u_b*u_i + d**2*u_i**2)
    return E


@nb.njit(cache=True)
def impact_normal_force(delta, delta_dot, p):
    """Normal force (N) on the circle along roller->circle; delta (m) > 0, delta_dot (m/s)."""
    b_imp = p[12]
    impact_clamp = p[14]
    k_imp = p[11]
    n_imp = p[13]
    x0 = fpow(delta, n_imp)*(b_imp*delta_dot + k_imp)
    value = ((max(0, x0)) if (impact_clamp > 1.0/2.0) else (x0))
    return value


@nb.njit(cache=True)
def impact_potential(delta, p):
    """Elastic energy (J) stored in one contact at overlap delta (m)."""
    k_imp = p[11]
    n_imp = p[13]
    x0 = n_imp + 1
    value = fpow(delta, x0)*k_imp/x0
    return value


@nb.njit(cache=True)
def slider_mu(speed, p):
    """Slider friction coefficient (1) at band speed `speed` (rad/s)."""
    gamma = p[17]
    mu_k = p[16]
    mu_s = p[15]
    x0 = abs(speed)
    x1 = 1/gamma
    value = ((mu_s*x0*x1) if (gamma >= x0) else (mu_s - x1*(-gamma + x0)*(-2*mu_k + 2*mu_s)) if (x0 <= (3.0/2.0)*gamma) else (mu_k))*(0.0 if speed == 0 else math.copysign(1.0, speed))
    return value


@nb.njit(cache=True)
def slider_torque(speed, p):
    """Slider friction torque (N m) on the band about n3 at band speed `speed` (rad/s)."""
    R_bo = p[3]
    g = p[19]
    gamma = p[17]
    m_b = p[18]
    mu_k = p[16]
    mu_s = p[15]
    x0 = abs(speed)
    x1 = 1/gamma
    value = -R_bo*g*m_b*((mu_s*x0*x1) if (gamma >= x0) else (mu_s - x1*(-gamma + x0)*(-2*mu_k + 2*mu_s)) if (x0 <= (3.0/2.0)*gamma) else (mu_k))*(0.0 if speed == 0 else math.copysign(1.0, speed))
    return value


@nb.njit(cache=True)
def traction_coulomb_force(slip, p):
    """Friction force (N) on the band along its motion at sliding speed slip (m/s)."""
    F_nw = p[22]
    mu_wk = p[24]
    mu_ws = p[23]
    v_weps = p[26]
    v_ws = p[25]
    value = F_nw*(mu_wk + (-mu_wk + mu_ws)*math.exp(-slip**2/v_ws**2))*math.tanh(slip/v_weps)
    return value


@nb.njit(cache=True)
def lugre_z_dot(slip, z, p):
    """Bristle deflection rate (m/s)."""
    F_nw = p[22]
    mu_wk = p[24]
    mu_ws = p[23]
    sigma0 = p[27]
    v_ws = p[25]
    value = slip - sigma0*z*abs(slip)/(F_nw*(mu_wk + (-mu_wk + mu_ws)*math.exp(-slip**2/v_ws**2)))
    return value


@nb.njit(cache=True)
def lugre_force(slip, z, p):
    """LuGre friction force (N) on the band at sliding speed slip (m/s), deflection z (m)."""
    F_nw = p[22]
    mu_wk = p[24]
    mu_ws = p[23]
    sigma0 = p[27]
    sigma1 = p[28]
    sigma2 = p[29]
    v_ws = p[25]
    x0 = sigma0*z
    value = sigma1*(slip - x0*abs(slip)/(F_nw*(mu_wk + (-mu_wk + mu_ws)*math.exp(-slip**2/v_ws**2)))) + sigma2*slip + x0
    return value


@nb.njit(cache=True)
def effect_slider_viscous(t, q_b, speed, tau_slider, p):
    """Band torque (N m) of candidate effect slider_viscous."""
    c_visc = p[30]
    value = -c_visc*speed
    return value


@nb.njit(cache=True)
def effect_slider_stribeck(t, q_b, speed, tau_slider, p):
    """Band torque (N m) of candidate effect slider_stribeck."""
    R_bo = p[3]
    g = p[19]
    gamma = p[17]
    m_b = p[18]
    mu_st = p[31]
    v_st = p[32]
    value = -R_bo*g*m_b*mu_st*math.exp(-speed**2/v_st**2)*max(-1, min(1, speed/gamma))
    return value


@nb.njit(cache=True)
def effect_friction_asymmetry(t, q_b, speed, tau_slider, p):
    """Band torque (N m) of candidate effect friction_asymmetry."""
    fric_asym = p[33]
    value = fric_asym*tau_slider*(0.0 if speed == 0 else math.copysign(1.0, speed))
    return value


@nb.njit(cache=True)
def effect_load_lift(t, q_b, speed, tau_slider, p):
    """Band torque (N m) of candidate effect load_lift."""
    tau_lift = p[34]
    value = -tau_lift
    return value


@nb.njit(cache=True)
def effect_position_periodic(t, q_b, speed, tau_slider, p):
    """Band torque (N m) of candidate effect position_periodic."""
    a_rev = p[35]
    a_tooth = p[37]
    n_teeth = p[39]
    phi_rev = p[36]
    phi_tooth = p[38]
    value = -a_rev*math.sin(phi_rev + q_b) - a_tooth*math.sin(n_teeth*q_b + phi_tooth)
    return value


@nb.njit(cache=True)
def effect_friction_drift(t, q_b, speed, tau_slider, p):
    """Band torque (N m) of candidate effect friction_drift."""
    k_drift = p[40]
    value = k_drift*t*tau_slider
    return value


@nb.njit(cache=True)
def band_effects_torque(t, q_b, speed, tau_slider, p):
    """Sum of the candidate effects' band torques (N m); 0 with their parameters at 0."""
    R_bo = p[3]
    a_rev = p[35]
    a_tooth = p[37]
    c_visc = p[30]
    fric_asym = p[33]
    g = p[19]
    gamma = p[17]
    k_drift = p[40]
    m_b = p[18]
    mu_st = p[31]
    n_teeth = p[39]
    phi_rev = p[36]
    phi_tooth = p[38]
    tau_lift = p[34]
    v_st = p[32]
    value = -R_bo*g*m_b*mu_st*math.exp(-speed**2/v_st**2)*max(-1, min(1, speed/gamma)) - a_rev*math.sin(phi_rev + q_b) - a_tooth*math.sin(n_teeth*q_b + phi_tooth) - c_visc*speed + fric_asym*tau_slider*(0.0 if speed == 0 else math.copysign(1.0, speed)) + k_drift*t*tau_slider - tau_lift
    return value


@nb.njit(cache=True)
def traction_tangential_force(f_n, slip, p):
    """Tangential force (N) on the circle along z x n at normal force f_n (N) and sliding speed slip (m/s)."""
    mu_t = p[41]
    v_teps = p[42]
    value = -f_n*mu_t*math.tanh(slip/v_teps)
    return value


@nb.njit(cache=True)
def drive_compliance_torque(motor_angle, motor_speed, q_w, u_w, p):
    """Torque (N m) on the wheel from the compliant drive at motor angle/speed and wheel angle/speed."""
    c_drive = p[44]
    k_drive = p[43]
    value = c_drive*(motor_speed - u_w) + k_drive*(motor_angle - q_w)
    return value
