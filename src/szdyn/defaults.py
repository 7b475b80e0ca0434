"""THE one place for default values of the Spiral Zipper model, each with its provenance.

Every parameter of the flat vector ``p`` (``PARAM_NAMES`` of the generated module), the
structural circle count ``N_c`` and the band geometry has exactly one :class:`Default` record
here: value (SI), unit, description and a one-line provenance saying where the number comes
from. "thesis" is Lee, MSc thesis, Hanyang University 2021 (``seed/spiral-zipper-thesis.txt``);
"model-notes" is ``shared/model-notes.md``; "probe" is the quick independent probe recorded in
model-notes section 5. Where a value is a choice, the provenance says "chosen so that ...".
These are starting values; they will be retuned (regime map), so do not read them as measured.

Unit interpretation (model-notes section 4): the thesis works in N, mm, s. Its
``k_c = 50 N*mm/rad`` is 0.05 N*m/rad and ``b_c = 7.5 N*mm*s/rad`` is 7.5e-3 N*m*s/rad. Its
``k_imp = 4000`` and ``b_imp = 20`` are printed with the units of k_c/b_c, which is impossible
for the force law ``F = delta**3 (k_imp + b_imp delta_dot)``; read consistently in N, mm, s they
are 4000 N/mm^3 = 4e12 N/m^3 and 20 N*s/mm^4 = 2e13 N*s/m^4, which are the probe's SI values.
"""
from __future__ import annotations

import math
from dataclasses import dataclass

__all__ = [
    "Default", "PARAMETER_DEFAULTS", "GEOMETRY_DEFAULTS", "N_CIRCLES_DEFAULT", "DEFAULT_N_CIRCLES",
    "MAX_N_CIRCLES",
    "MAX_N_ROLLERS",
    "ALL_DEFAULTS", "PARAMETER_DOCS", "default_values", "default_geometry", "default_parameters",
    "omni_wheel_inertia_estimate",
]


@dataclass(frozen=True)
class Default:
    """One default value with its unit, meaning and provenance.

    Attributes
    ----------
    name : str
        Parameter name (as in ``PARAM_NAMES``, or a geometry field / ``n_circles``).
    value : float
        Default value in SI units (integers stored as int for structural counts).
    unit : str
        SI unit of ``value`` ("1" for dimensionless).
    description : str
        What the parameter is.
    provenance : str
        One line: where the value comes from, or "chosen so that ..." if it is a choice.
    """

    name: str
    value: float
    unit: str
    description: str
    provenance: str


# ---------------------------------------------------------------------------------------------
# Probe geometry (model-notes section 5), SI metres.
_R_BO = 30e-3
_D_ARM = 12e-3
_T_C = 1e-3
_T_R = 6e-3
_INTERFERENCE = 0.19e-3
_R_W = round(_R_BO - _D_ARM - _T_C - _T_R + _INTERFERENCE, 9)  # = 11.19 mm (rounding: clean JSON)


def omni_wheel_inertia_estimate(r_w: float = _R_W, t_r: float = _T_R) -> dict:
    """Estimate the inertia of a small 3D-printed omni wheel with 8 rubber rollers.

    Assumptions (chosen, not measured): each roller a rubber cylinder of radius ``t_r``,
    length 10 mm, density 1150 kg/m^3 (polyurethane/silicone), on a steel pin (2 mm diameter,
    14 mm long, 7850 kg/m^3), centred at radius ``r_w``; hub a printed ABS disc of radius
    16 mm, thickness 12 mm, 1050 kg/m^3 at 60 % effective infill. The motor rotor reflected
    through the gearbox is NOT included (it matters only for torque drive, drive_mode = 1).

    Parameters
    ----------
    r_w : float
        Radius of the roller centres (m).
    t_r : float
        Roller radius (m).

    Returns
    -------
    dict
        ``{"rollers": ..., "rollers_own": ..., "hub": ..., "total": ...}`` in kg*m^2 about n3.
    """
    n_r, length, rho_rubber = 8, 10e-3, 1150.0
    m_roller = rho_rubber * math.pi * t_r ** 2 * length
    m_pin = 7850.0 * math.pi * (1e-3) ** 2 * 14e-3
    rollers = n_r * (m_roller + m_pin) * r_w ** 2
    # each roller's own inertia about an axis parallel to n3 through its centre (axis tangential)
    rollers_own = n_r * m_roller * (3 * t_r ** 2 + length ** 2) / 12.0
    r_hub, h_hub = 16e-3, 12e-3
    m_hub = 1050.0 * 0.6 * math.pi * r_hub ** 2 * h_hub
    hub = 0.5 * m_hub * r_hub ** 2
    return {"rollers": rollers, "rollers_own": rollers_own, "hub": hub,
            "total": rollers + rollers_own + hub}


_I_W = float(f"{omni_wheel_inertia_estimate()['total']:.2g}")  # 5.3e-6 kg*m^2

PARAMETER_DEFAULTS: tuple[Default, ...] = (
    Default("I_W", _I_W, "kg*m^2", "wheel (with rollers) inertia about the tube axis n3",
            "estimate for a printed omni wheel: 8 rollers (1.6 g each incl. steel pin) at R_w "
            "~4.3e-6 + roller spin axes ~0.2e-6 + ABS hub ~0.8e-6 (omni_wheel_inertia_estimate); "
            "excludes reflected motor rotor; irrelevant for drive_mode 0"),
    Default("I_B", 1e-3, "kg*m^2", "band tube inertia about n3 (J_B in the thesis)",
            "probe (model-notes s.5); chosen so that the band + turntable is of order a 1 kg "
            "ring of 30 mm radius (0.9e-3); thesis does not give it"),
    Default("m_c", 4e-3, "kg", "mass of one small circle (particle at the arm tip)",
            "probe (model-notes s.5); chosen, thesis does not give it (100 circles = 0.4 kg "
            "of band)"),
    Default("R_bo", _R_BO, "m", "band inner radius: radius of the arm hinges Q_i",
            "probe (model-notes s.5); within the public 60-130 mm tube-diameter range"),
    Default("d", _D_ARM, "m", "arm length from hinge Q_i to circle centre P_i",
            "chosen, see regime map: 12 mm widens the partial-slip band (0.16-0.22 mm vs 5 mm's ~0.01 mm) and keeps Heun at 0.1 ms stable"),
    Default("t_c", _T_C, "m", "radius of a small circle",
            "probe (model-notes s.5); chosen, thesis does not give it"),
    Default("R_w", _R_W, "m", "radius of the roller centres on the wheel",
            "chosen so that interference R_w + t_r + t_c - (R_bo - d) = 0.19 mm, the centre of the "
            "0.18-0.20 mm window meeting thesis criteria (a)-(d), see regime map"),
    Default("t_r", _T_R, "m", "roller radius",
            "probe (model-notes s.5); chosen, thesis does not give it"),
    Default("n_rollers", 8.0, "1", "number of rollers N_r on the wheel (integer stored as float)",
            "thesis ch.2 s.2: the friction wheel has eight bushings and eight rubber rollers"),
    Default("k_c", 0.05, "N*m/rad", "torsional stiffness of each arm",
            "thesis ch.4: k_c = 50 N*mm/rad ('arbitrarily chosen') = 0.05 N*m/rad"),
    Default("b_c", 7.5e-3, "N*m*s/rad", "torsional damping of each arm",
            "thesis ch.4: b_c = 7.5 N*mm*s/rad ('arbitrarily chosen') = 7.5e-3 N*m*s/rad"),
    Default("k_imp", 4e12, "N/m^n", "impact stiffness in F = delta^n (k_imp + b_imp delta_dot)",
            "thesis ch.4: k_imp = 4000, printed as N*mm/rad (impossible for delta^3); read in "
            "the thesis's N-mm-s units as 4000 N/mm^3 = 4e12 N/m^3 (= probe value)"),
    Default("b_imp", 2e13, "N*s/m^(n+1)",
            "impact damping in F = delta^n (k_imp + b_imp delta_dot)",
            "thesis ch.4: b_imp = 20, printed as N*mm*s/rad (impossible); read in N-mm-s units "
            "as 20 N*s/mm^4 = 2e13 N*s/m^4 (= probe value)"),
    Default("n_imp", 3.0, "1", "impact exponent n",
            "thesis eqs 34-35: n = 3"),
    Default("impact_clamp", 1.0, "1",
            "1: clamp the impact force at 0 (no attraction); 0: thesis formula as printed",
            "chosen so that contact never pulls (model-notes s.2: the printed law can turn "
            "attractive while separating fast)"),
    Default("mu_s", 0.3, "1", "slider static (peak) friction coefficient",
            "probe (model-notes s.5); chosen, below the ABS-on-ABS literature 0.5-0.6; retune"),
    Default("mu_k", 0.25, "1", "slider kinetic friction coefficient",
            "probe (model-notes s.5); chosen, below the ABS-on-ABS literature 0.35-0.5; retune"),
    Default("gamma", 0.01, "rad/s",
            "slider static band: band speed below which friction is regularised",
            "probe (model-notes s.5); chosen so that the band is small against the 0.3-30 rad/s "
            "speeds of interest"),
    Default("m_b", 1.0, "kg", "mass whose weight loads the slider (normal force m_b g)",
            "thesis ch.4 s.1: 1 kg of balance weights on the plate in the experiments"),
    Default("g", 9.80665, "m/s^2", "gravitational acceleration",
            "standard gravity (3rd CGPM 1901)"),
    Default("drive_mode", 0.0, "1",
            "0: prescribed wheel motion (drive array is speed); 1: motor torque; 2: prescribed motor motion through a compliant drive (k_drive, c_drive)",
            "thesis ch.4 s.2: simulations prescribed the wheel speed ramp omega = a t"),
    # Counter-models of issue 3 (thesis ch.5: "Coulomb's model or LuGre friction").
    Default("contact_model", 0.0, "1",
            "wheel-band transmission: 0 impacts (thesis), 1 Coulomb friction, 2 LuGre friction",
            "thesis ch.3: the impact-involved model is the thesis's; 1 and 2 are its ch.5 counter-models"),
    Default("F_nw", 10.0, "N", "friction counter-models: total normal force of the rollers on the band",
            "chosen so that the traction limit (R_w+t_r) mu_wk F_nw = 0.19 N m is ~2.6x the slider's kinetic torque"),
    Default("mu_ws", 0.9, "1", "friction counter-models: static (breakaway) coefficient, roller on band",
            "rubber on ABS, above ABS-on-ABS 0.5-0.6 (model-notes s.4: 'rubber on ABS higher'); a choice"),
    Default("mu_wk", 0.8, "1", "friction counter-models: Coulomb (kinetic) coefficient, roller on band",
            "rubber on ABS, above ABS-on-ABS 0.35-0.5 (model-notes s.4); a choice"),
    Default("v_ws", 0.01, "m/s", "friction counter-models: Stribeck sliding speed",
            "Canudas de Wit et al. 1995 (IEEE TAC 40(3)) use v_s = 0.001-0.01 m/s; upper value"),
    Default("v_weps", 1e-4, "m/s", "Coulomb counter-model: regularisation speed of sign(v) ~ tanh(v/v_weps)",
            "chosen 100x below v_ws so that the regularised law is Coulomb at every slip of interest"),
    Default("sigma0", 1e5, "N/m", "LuGre bristle stiffness",
            "Canudas de Wit et al. 1995, example values sigma0 = 1e5 N/m"),
    Default("sigma1", 316.0, "N*s/m", "LuGre bristle damping",
            "Canudas de Wit et al. 1995, sigma1 = sqrt(1e5) = 316 N s/m"),
    Default("sigma2", 0.4, "N*s/m", "LuGre viscous friction",
            "Canudas de Wit et al. 1995, sigma2 = 0.4 N s/m"),
    # Candidate effects of issue 5: off (0) in the thesis's model; the diagnosis fits them.
    Default("c_visc", 0.0, "N*m*s/rad", "slider_viscous: viscous torque -c_visc u_b on the band",
            "off: not in the thesis's model (candidate effect for diagnosis)"),
    Default("mu_st", 0.0, "1", "slider_stribeck: extra friction coefficient at low band speed",
            "off: not in the thesis's model (candidate effect for diagnosis)"),
    Default("v_st", 0.5, "rad/s", "slider_stribeck: band speed over which the extra friction decays",
            "chosen: a few percent of the held wheel speed range; used only when mu_st > 0"),
    Default("fric_asym", 0.0, "1", "friction_asymmetry: slider friction scaled by (1 + fric_asym sign(u_b))",
            "off: not in the thesis's model (candidate effect for diagnosis)"),
    Default("tau_lift", 0.0, "N*m", "load_lift: constant torque of the payload weight through the helix lead, m g P_B/(2 pi)",
            "off: the thesis's rig carried its weights on a guided plate (no lift); 1 kg gives 0.065 N m at P_B = 41.7 mm"),
    Default("a_rev", 0.0, "N*m", "position_periodic: torque amplitude once per band revolution",
            "off: not in the thesis's model (candidate effect for diagnosis)"),
    Default("phi_rev", 0.0, "rad", "position_periodic: phase of the once-per-revolution torque",
            "used only when a_rev > 0"),
    Default("a_tooth", 0.0, "N*m", "position_periodic: torque amplitude once per tooth pitch",
            "off: not in the thesis's model (candidate effect for diagnosis)"),
    Default("phi_tooth", 0.0, "rad", "position_periodic: phase of the per-tooth torque",
            "used only when a_tooth > 0"),
    Default("n_teeth", 24.0, "1", "position_periodic: teeth per wrap N (per-tooth period 2 pi / N in q_b)",
            "same as the band geometry's teeth_per_wrap (chosen, see GEOMETRY_DEFAULTS)"),
    Default("k_drift", 0.0, "1/s", "friction_drift: slider friction scaled by (1 + k_drift t)",
            "off: not in the thesis's model (candidate effect for diagnosis)"),
    Default("mu_t", 0.0, "1", "wheel_band_traction: tangential friction coefficient at the roller contacts",
            "off: the thesis's central claim is transmission by normal impacts only (model-notes s.2)"),
    Default("v_teps", 1e-2, "m/s", "wheel_band_traction: regularisation speed of sign(v) ~ tanh(v/v_teps)",
            "chosen: a third of the roller surface speed (~0.03 m/s at pi rad/s), the smallest that integrates "
            "well; measured (mu_t 0.28, 2 s): at 1 mm/s RK4 needs 10 us to come within 0.012 rad of dopri5 "
            "and dopri5 takes 4.2 s, at 10 mm/s 0.6 s; used only when mu_t > 0"),
    Default("k_drive", 20.0, "N*m/rad", "drive_compliance: torsional stiffness between motor and wheel (drive_mode 2)",
            "chosen: a stiff printed coupling (a 10 mm steel shaft 50 mm long is ~4e3 N m/rad); used only in drive_mode 2"),
    Default("c_drive", 0.01, "N*m*s/rad", "drive_compliance: torsional damping between motor and wheel (drive_mode 2)",
            "chosen: light damping of the coupling; used only in drive_mode 2"),
)

N_CIRCLES_DEFAULT = Default(
    "n_circles", 100, "1", "number of small circles N_c (structural; sets state length)",
    "thesis ch.4 s.2: N_d = 100 ('arbitrarily chosen'); note 100 is not a multiple of 8 rollers")
DEFAULT_N_CIRCLES: int = int(N_CIRCLES_DEFAULT.value)
#: Largest N_c accepted anywhere (a guard, not physics): 100x the thesis's. A run's state, memory
#: and time grow with N_c; a mistyped 1e8 would otherwise take gigabytes before any message.
MAX_N_CIRCLES: int = 10_000
#: Largest N_r accepted (a guard, not physics): the thesis's wheel has 8. Each step searches every
#: roller's contacts, so a run's time grows with N_r; a mistyped 1e9 would run for hours unheard.
MAX_N_ROLLERS: int = 1_000

GEOMETRY_DEFAULTS: tuple[Default, ...] = (
    Default("band_height", 45.72e-3, "m", "band height H_B including teeth",
            "public Spiral Zipper band figure of 1.8 in = 45.72 mm (model-notes s.4)"),
    Default("tooth_height", 5e-3, "m", "tooth height H_T",
            "chosen so that teeth are ~11 % of the band height; thesis gives no number"),
    Default("diameter", 2 * _R_BO, "m", "band (tube) diameter D",
            "chosen as 2 R_bo = 60 mm (band thickness neglected) to match the probe's R_bo"),
    Default("teeth_per_wrap", 24, "1", "number of teeth N in one wrap",
            "chosen so that the tooth pitch P_T = S_B/N is ~8 mm; thesis gives no number"),
)

ALL_DEFAULTS: tuple[Default, ...] = PARAMETER_DEFAULTS + (N_CIRCLES_DEFAULT,) + GEOMETRY_DEFAULTS

#: name -> (unit, description) for every parameter, n_circles and geometry field.
PARAMETER_DOCS: dict[str, tuple[str, str]] = {d.name: (d.unit, d.description)
                                              for d in ALL_DEFAULTS}


def default_values() -> dict[str, float]:
    """Default value of every parameter of the flat vector, name -> float (SI)."""
    return {d.name: float(d.value) for d in PARAMETER_DEFAULTS}


def default_geometry():
    """Default :class:`~szdyn.geometry.BandGeometry` (see ``GEOMETRY_DEFAULTS``)."""
    from szdyn.geometry import BandGeometry

    return BandGeometry(**{d.name: d.value for d in GEOMETRY_DEFAULTS})


def default_parameters(n_circles: int = DEFAULT_N_CIRCLES):
    """Default, validated :class:`~szdyn.params.ParameterSet`.

    Parameters
    ----------
    n_circles : int, optional
        ``N_c``, number of small circles (default 100, thesis).

    Returns
    -------
    ParameterSet
        All parameters from ``PARAMETER_DEFAULTS``, geometry from ``GEOMETRY_DEFAULTS``.

    Raises
    ------
    ParameterError
        If the generated module's ``PARAM_NAMES`` has a name without a default here.
    ImportError
        If the generated module is not importable.
    """
    from szdyn.errors import ParameterError
    from szdyn.params import ParameterSet, param_names

    values = default_values()
    names = param_names()
    lacking = [n for n in names if n not in values]
    if lacking:
        raise ParameterError("no default in szdyn.defaults for parameter(s) "
                             + ", ".join(f"'{n}'" for n in lacking))
    return ParameterSet(values={n: values[n] for n in names}, n_circles=n_circles,
                        geometry=default_geometry())
