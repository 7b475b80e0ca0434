"""Force laws as swappable symbolic objects, separate from the kinematics.

Each law maps a few kinematic scalars (overlap and its rate, a speed) to a force or torque.
The kinematic kernels are derived with *symbols* standing for these outputs
(``f_n``, ``f_t``, ``tau_b``, ``T_m``), so a law can be exchanged without re-deriving the
kinematics. Each law also emits its own small Numba function (see ``codegen``).
"""
from __future__ import annotations

from dataclasses import dataclass

import sympy as sm

from .symbols import P

delta, delta_dot, speed = sm.symbols("delta delta_dot speed", real=True)


@dataclass(frozen=True)
class LawFunction:
    """One emitted scalar function ``name(*args, p) -> expr`` with a docstring."""

    name: str
    args: tuple[sm.Symbol, ...]
    expr: sm.Expr
    doc: str


class HuntCrossleyImpact:
    """Nonlinear viscoelastic normal force of eqs 34-35, ``delta^n (k_imp + b_imp delta_dot)``.

    With ``impact_clamp = 1`` the force is clamped at zero: the printed formula turns
    attractive while the bodies separate fast, which a contact cannot do (model-notes 2).
    """

    name = "impact"

    def normal_force(self, d=delta, dd=delta_dot) -> sm.Expr:
        raw = d ** P["n_imp"] * (P["k_imp"] + P["b_imp"] * dd)
        return sm.Piecewise((sm.Max(raw, 0), P["impact_clamp"] > sm.Rational(1, 2)), (raw, True))

    def potential(self, d=delta) -> sm.Expr:
        """Elastic energy stored at overlap ``d`` (J): the integral of the stiffness part."""
        n = P["n_imp"]
        return P["k_imp"] * d ** (n + 1) / (n + 1)

    def functions(self) -> list[LawFunction]:
        return [
            LawFunction("impact_normal_force", (delta, delta_dot), self.normal_force(),
                        "Normal force (N) on the circle along roller->circle; delta (m) > 0, delta_dot (m/s)."),
            LawFunction("impact_potential", (delta,), self.potential(),
                        "Elastic energy (J) stored in one contact at overlap delta (m)."),
        ]


class SliderFriction:
    """Slider friction on the band, eqs 38-39 as corrected in model-notes section 2.

    ``mu(u)`` rises linearly to ``mu_s`` inside the static band ``gamma``, falls to ``mu_k``
    by ``1.5 gamma`` and stays there; the torque on the band is ``-R_bo mu(u_b) m_b g``.
    """

    name = "slider_coulomb"

    def mu(self, u=speed) -> sm.Expr:
        mu_s, mu_k, gamma = P["mu_s"], P["mu_k"], P["gamma"]
        a = sm.Abs(u)
        mag = sm.Piecewise(
            (mu_s * a / gamma, a <= gamma),
            (mu_s - 2 * (mu_s - mu_k) * (a - gamma) / gamma, a <= sm.Rational(3, 2) * gamma),
            (mu_k, True),
        )
        return sm.sign(u) * mag

    def torque(self, u=speed) -> sm.Expr:
        return -P["R_bo"] * self.mu(u) * P["m_b"] * P["g"]

    def functions(self) -> list[LawFunction]:
        return [
            LawFunction("slider_mu", (speed,), self.mu(),
                        "Slider friction coefficient (1) at band speed `speed` (rad/s)."),
            LawFunction("slider_torque", (speed,), self.torque(),
                        "Slider friction torque (N m) on the band about n3 at band speed `speed` (rad/s)."),
        ]


class ArmSpringDamper:
    """Torsional spring-damper between each arm and the band, eqs 36-37 (corrected).

    ``V = k_c phi^2 / 2`` and ``D = b_c phi_dot^2 / 2`` with ``phi = q_i - q_b``; the torque on
    the arm is ``-(k_c phi + b_c phi_dot)`` and the reaction acts on the band.
    """

    name = "arm_spring_damper"

    def torque_on_arm(self, phi, phi_dot) -> sm.Expr:
        return -(P["k_c"] * phi + P["b_c"] * phi_dot)

    def potential(self, phi) -> sm.Expr:
        return P["k_c"] * phi**2 / 2



def _stribeck(v):
    """Friction coefficient magnitude with Stribeck peak: mu_wk + (mu_ws - mu_wk) exp(-(v/v_ws)^2)."""
    return P["mu_wk"] + (P["mu_ws"] - P["mu_wk"]) * sm.exp(-((v / P["v_ws"]) ** 2))


slip, z = sm.symbols("slip z", real=True)


class TractionCoulomb:
    """Counter-model: the rollers drive the band by sliding friction, Coulomb with Stribeck peak.

    ``F = F_nw mu(v) tanh(v / v_weps)`` along the sliding velocity ``v = r_c (u_w - u_b)``,
    ``r_c = R_w + t_r``; the tanh regularises sign(v) (``v_weps`` small) so that the law has
    a stick regime an explicit integrator can resolve.
    """

    name = "traction_coulomb"

    def force(self, v=slip) -> sm.Expr:
        return P["F_nw"] * _stribeck(v) * sm.tanh(v / P["v_weps"])

    def functions(self) -> list[LawFunction]:
        return [LawFunction("traction_coulomb_force", (slip,), self.force(),
                            "Friction force (N) on the band along its motion at sliding speed slip (m/s).")]


class TractionLuGre:
    """Counter-model: LuGre dynamic friction between rollers and band (Canudas de Wit 1995).

    ``dz/dt = v - sigma0 |v| z / g(v)``, ``g(v) = F_nw mu(v)`` (N), and
    ``F = sigma0 z + sigma1 dz/dt + sigma2 v``; ``z`` (m) is the mean bristle deflection.
    """

    name = "traction_lugre"

    def z_dot(self, v=slip, zz=z) -> sm.Expr:
        return v - P["sigma0"] * sm.Abs(v) * zz / (P["F_nw"] * _stribeck(v))

    def force(self, v=slip, zz=z) -> sm.Expr:
        return P["sigma0"] * zz + P["sigma1"] * self.z_dot(v, zz) + P["sigma2"] * v

    def functions(self) -> list[LawFunction]:
        return [
            LawFunction("lugre_z_dot", (slip, z), self.z_dot(), "Bristle deflection rate (m/s)."),
            LawFunction("lugre_force", (slip, z), self.force(),
                        "LuGre friction force (N) on the band at sliding speed slip (m/s), deflection z (m)."),
        ]


tt, q, tau_s = sm.symbols("t q_b tau_slider", real=True)


class BandEffects:
    """Candidate effects that the thesis's model leaves out, as torques on the band (issue 5).

    Each is one named term with its own parameters and is off when they are 0; the sum is the
    extra band torque of the model. ``speed`` is the band speed u_b (rad/s), ``q`` its angle
    (rad), ``tt`` the time (s), ``slider`` the slider friction torque (N m) that the asymmetry
    and drift terms scale: an input, so that the slider law is evaluated once per RHS.
    """

    name = "band_effects"

    def terms(self, u=speed, qb=q, time=tt, slider=tau_s) -> dict:
        sat = sm.Max(-1, sm.Min(1, u / P["gamma"]))  # sign(u) regularised like the slider law
        return {
            "slider_viscous": -P["c_visc"] * u,
            "slider_stribeck": -P["R_bo"] * P["m_b"] * P["g"] * P["mu_st"] * sm.exp(-((u / P["v_st"]) ** 2)) * sat,
            "friction_asymmetry": P["fric_asym"] * sm.sign(u) * slider,
            "load_lift": -P["tau_lift"],
            "position_periodic": -P["a_rev"] * sm.sin(qb + P["phi_rev"])
                                 - P["a_tooth"] * sm.sin(P["n_teeth"] * qb + P["phi_tooth"]),
            "friction_drift": P["k_drift"] * time * slider,
        }

    def torque(self, u=speed, qb=q, time=tt, slider=tau_s) -> sm.Expr:
        return sum(self.terms(u, qb, time, slider).values())

    def functions(self) -> list[LawFunction]:
        out = [LawFunction(f"effect_{k}", (tt, q, speed, tau_s), v, f"Band torque (N m) of candidate effect {k}.")
               for k, v in self.terms().items()]
        out.append(LawFunction("band_effects_torque", (tt, q, speed, tau_s), self.torque(),
                               "Sum of the candidate effects' band torques (N m); 0 with their parameters at 0."))
        return out


class ContactTraction:
    """wheel_band_traction: tangential (rubber) friction at each roller-circle contact, which the
    thesis's model omits: ``f_t = -mu_t f_n tanh(v_slide / v_teps)`` on the circle along the
    contact tangent, opposing the circle's sliding relative to the roller surface."""

    name = "wheel_band_traction"

    def force(self, fn=sm.Symbol("f_n", real=True), v=slip) -> sm.Expr:
        return -P["mu_t"] * fn * sm.tanh(v / P["v_teps"])

    def functions(self) -> list[LawFunction]:
        fn = sm.Symbol("f_n", real=True)
        return [LawFunction("traction_tangential_force", (fn, slip), self.force(fn, slip),
                            "Tangential force (N) on the circle along z x n at normal force f_n (N) and sliding speed slip (m/s).")]


class DriveCompliance:
    """drive_compliance (drive_mode 2): the encoder measures the motor, whose motion is prescribed;
    a torsional spring-damper (k_drive, c_drive) carries the torque to the wheel."""

    name = "drive_compliance"

    def torque(self, motor_angle, motor_speed, q_w, u_w) -> sm.Expr:
        return P["k_drive"] * (motor_angle - q_w) + P["c_drive"] * (motor_speed - u_w)

    def functions(self) -> list[LawFunction]:
        a, w, qw, uw = sm.symbols("motor_angle motor_speed q_w u_w", real=True)
        return [LawFunction("drive_compliance_torque", (a, w, qw, uw), self.torque(a, w, qw, uw),
                            "Torque (N m) on the wheel from the compliant drive at motor angle/speed and wheel angle/speed.")]


LAWS = (HuntCrossleyImpact(), SliderFriction(), TractionCoulomb(), TractionLuGre(), BandEffects(),
        ContactTraction(), DriveCompliance())
