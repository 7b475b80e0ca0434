"""Symbols of the Spiral Zipper model: coordinates, speeds and the flat parameter vector.

The order of ``PARAMETERS`` *is* the order of the runtime parameter array ``p``; the
generated module re-exports it as ``PARAM_NAMES``. New parameters are appended at the end so
that saved parameter files stay readable.
"""
from __future__ import annotations

from dataclasses import dataclass

import sympy as sm
import sympy.physics.mechanics as me


@dataclass(frozen=True)
class Param:
    """One entry of the flat parameter vector."""

    name: str
    unit: str
    doc: str
    bound: str  # validation: "> 0", ">= 0", "positive integer" or "one of 0,1,..."

    @property
    def symbol(self) -> sm.Symbol:
        return sm.Symbol(self.name, real=True)


PARAMETERS: tuple[Param, ...] = (
    Param("I_W", "kg*m^2", "wheel (with rollers) inertia about the tube axis n3", "> 0"),
    Param("I_B", "kg*m^2", "band tube inertia about n3 (J_B in the thesis)", "> 0"),
    Param("m_c", "kg", "mass of one small circle (particle at the arm tip)", "> 0"),
    Param("R_bo", "m", "band inner radius: radius of the arm hinges Q_i", "> 0"),
    Param("d", "m", "arm length from hinge Q_i to circle centre P_i", "> 0"),
    Param("t_c", "m", "radius of a small circle", "> 0"),
    Param("R_w", "m", "radius of the roller centres on the wheel", "> 0"),
    Param("t_r", "m", "roller radius", "> 0"),
    Param("n_rollers", "1", "number of rollers N_r (integer stored as float)", "positive integer"),
    Param("k_c", "N*m/rad", "torsional stiffness of each arm", ">= 0"),
    Param("b_c", "N*m*s/rad", "torsional damping of each arm", ">= 0"),
    Param("k_imp", "N/m^n", "impact stiffness in F = delta^n (k_imp + b_imp delta_dot)", ">= 0"),
    Param("b_imp", "N*s/m^(n+1)", "impact damping in F = delta^n (k_imp + b_imp delta_dot)", ">= 0"),
    Param("n_imp", "1", "impact exponent n (thesis: 3)", "> 0"),
    Param("impact_clamp", "1", "1: clamp the impact force at 0 (no attraction); 0: thesis formula as printed", "one of 0,1"),
    Param("mu_s", "1", "slider static (peak) friction coefficient", ">= 0"),
    Param("mu_k", "1", "slider kinetic friction coefficient", ">= 0"),
    Param("gamma", "rad/s", "slider static band: band speed below which friction is regularised", "> 0"),
    Param("m_b", "kg", "mass whose weight loads the slider (normal force m_b g)", ">= 0"),
    Param("g", "m/s^2", "gravitational acceleration", "> 0"),
    Param("drive_mode", "1", "0: prescribed wheel motion (drive array is speed); 1: motor torque; "
          "2: prescribed motor motion through a compliant drive (k_drive, c_drive)", "one of 0,1,2"),
    # Counter-models (issue 3): the wheel drives the band by tangential friction at the roller
    # contact radius r_c = R_w + t_r instead of by impacts.
    Param("contact_model", "1", "wheel-band transmission: 0 impacts (thesis), 1 Coulomb friction, 2 LuGre friction", "one of 0,1,2"),
    Param("F_nw", "N", "friction counter-models: total normal force of the rollers on the band", ">= 0"),
    Param("mu_ws", "1", "friction counter-models: static (breakaway) coefficient, roller on band", ">= 0"),
    Param("mu_wk", "1", "friction counter-models: Coulomb (kinetic) coefficient, roller on band", ">= 0"),
    Param("v_ws", "m/s", "friction counter-models: Stribeck sliding speed", "> 0"),
    Param("v_weps", "m/s", "Coulomb counter-model: regularisation speed of sign(v) ~ tanh(v/v_weps)", "> 0"),
    Param("sigma0", "N/m", "LuGre bristle stiffness", "> 0"),
    Param("sigma1", "N*s/m", "LuGre bristle damping", ">= 0"),
    Param("sigma2", "N*s/m", "LuGre viscous friction", ">= 0"),
    # Candidate effects the thesis's model leaves out (issue 5). Each is off at 0.
    Param("c_visc", "N*m*s/rad", "slider_viscous: viscous torque -c_visc u_b on the band", ">= 0"),
    Param("mu_st", "1", "slider_stribeck: extra friction coefficient at low band speed", ">= 0"),
    Param("v_st", "rad/s", "slider_stribeck: band speed over which the extra friction decays", "> 0"),
    Param("fric_asym", "1", "friction_asymmetry: slider friction scaled by (1 + fric_asym sign(u_b))", "real"),
    Param("tau_lift", "N*m", "load_lift: constant torque of the payload weight through the helix lead, m g P_B/(2 pi)", "real"),
    Param("a_rev", "N*m", "position_periodic: torque amplitude once per band revolution", ">= 0"),
    Param("phi_rev", "rad", "position_periodic: phase of the once-per-revolution torque", "real"),
    Param("a_tooth", "N*m", "position_periodic: torque amplitude once per tooth pitch", ">= 0"),
    Param("phi_tooth", "rad", "position_periodic: phase of the per-tooth torque", "real"),
    Param("n_teeth", "1", "position_periodic: teeth per wrap N (per-tooth period 2 pi / N in q_b)", "positive integer"),
    Param("k_drift", "1/s", "friction_drift: slider friction scaled by (1 + k_drift t)", "real"),
    Param("mu_t", "1", "wheel_band_traction: tangential friction coefficient at the roller contacts", ">= 0"),
    Param("v_teps", "m/s", "wheel_band_traction: regularisation speed of sign(v) ~ tanh(v/v_teps)", "> 0"),
    Param("k_drive", "N*m/rad", "drive_compliance: torsional stiffness between motor and wheel (drive_mode 2)", ">= 0"),
    Param("c_drive", "N*m*s/rad", "drive_compliance: torsional damping between motor and wheel (drive_mode 2)", ">= 0"),
)

#: Auxiliary states appended after the speeds: the LuGre bristle deflection z (m).
AUX_STATES: tuple[str, ...] = ("z_lugre",)

PARAM_NAMES: tuple[str, ...] = tuple(p.name for p in PARAMETERS)
P = {p.name: p.symbol for p in PARAMETERS}

t = me.dynamicsymbols._t

# Reduced, rotation-invariant quantities that the kernels are written in.
phi, rho = sm.symbols("phi rho", real=True)  # arm angle q_i - q_b; roller angle seen from Q_i
alpha, beta = sm.symbols("alpha beta", real=True)  # circle hinge offset on band; roller offset on wheel


def circle_coordinates(i: int | str):
    """Return ``(q_i, u_i)`` dynamic symbols of circle ``i``."""
    q = me.dynamicsymbols(f"q_{i}")
    u = me.dynamicsymbols(f"u_{i}")
    return q, u


q_w, q_b, u_w, u_b = me.dynamicsymbols("q_w q_b u_w u_b")
