"""The library of named candidate effects ("missing physics") and the calibrated coefficients.

Each :class:`Candidate` is a term that the base model can be extended with. Model-side terms are
load terms derived symbolically in ``derive/force_laws.py`` (``BandEffects``,
``ContactTraction``, ``DriveCompliance``) and already present, switched off, in the generated
RHS; a candidate only says which parameters switch it on, how to fit them and how to write them
down. Sensor-side terms (:mod:`szdyn.sensors`) act on the measured band angle and need no
re-simulation.

The library is data, apart from the selection method (:mod:`szdyn.diagnose.selection`), in the
style of pysindy's feature libraries: add a candidate here and the diagnosis screens it.

Fit coordinates
---------------
Every fitted quantity is a :class:`FitParam` with a *probe* step: the size of change that a
linear screening uses as a finite-difference step, and the scale given to
``scipy.optimize.least_squares`` (``x_scale``). Coefficients of the base model are fitted in
log space (``log=True``: positive, relative changes); effect parameters in linear space from 0
("off"), so that the base model is the candidate at zero.
"""
from __future__ import annotations

import math
from dataclasses import dataclass
from collections.abc import Callable

import numpy as np

__all__ = ["FitParam", "Candidate", "CANDIDATES", "CALIBRATED", "FIXED_UNIDENTIFIED",
           "candidate_ids", "primary_std"]


@dataclass(frozen=True)
class FitParam:
    """One fitted scalar.

    Attributes
    ----------
    name : str
        Name in the fit (a model parameter name, or a derived coordinate such as ``a_rev_s``).
    unit : str
    lo, hi : float
        Bounds in the parameter's own units; for ``log`` parameters, factors of the start value.
    probe : float
        Screening step and least-squares scale (own units; for ``log`` parameters a relative
        step, e.g. 0.1 = 10 %).
    log : bool
        Fit ``log(value)`` (positive coefficients).
    start : float or None
        Start value; ``None``: the base model's value (coefficients) or 0 (effects).
    screen_at : tuple of float
        For a *shape* parameter (one that changes nothing while the effect's amplitude is 0,
        such as a Stribeck speed): the values at which the linear screening tries the
        amplitude columns; the best becomes the refit's start. Empty: screened at ``start``.
    force_power : float
        How the value scales with the model's force scale (every force coefficient multiplied
        by ``lam``): as ``lam ** force_power``. 1 for a torque, a torque per speed or a friction
        coefficient (the slider's normal load is fixed), -1 for a compliance, 0 for ratios,
        shapes and sensor terms. Defines :func:`.force_scale.force_scale_direction`.
    """

    name: str
    unit: str
    lo: float
    hi: float
    probe: float
    log: bool = False
    start: float | None = None
    screen_at: tuple = ()
    force_power: float = 0.0


@dataclass(frozen=True)
class Candidate:
    """A named effect the base model may have left out.

    Attributes
    ----------
    id : str
        Effect id (as in the issue and :data:`szdyn.synth.EFFECTS`).
    kind : {"model", "sensor"}
    params : tuple of FitParam
        What is fitted when the candidate is switched on.
    apply : callable(dict) -> (dict, dict)
        Fitted values -> (model-parameter changes, sensor changes). ``{}`` sensor changes for
        model-side terms. Must return the base model (no changes) when every value is 0.
    primary : str
        The model/sensor quantity reported as "the effect parameter".
    primary_of : callable(dict) -> float
        Fitted values -> value of ``primary``.
    expression : str
        The term as it enters the model (units in the report).
    explains : str
        The signature this term produces (what it would explain in the residuals).
    signature : tuple of str
        Physical features of :data:`szdyn.diagnose.locate.FEATURES` that the residual of a model
        missing this term follows. When the calibrated model's residual follows one of them more
        than any other, the candidate is refitted whatever its linear screening says
        (:func:`~szdyn.diagnose.selection.nominate`).
    force_scaled : bool
        ``primary`` is a torque, a torque per speed or per angle, or a friction coefficient:
        it scales with the model's force scale, which speed recordings fix only weakly (every
        force coefficient and the effect scaled together by 1.25 changed the compared feature by
        0.4 to 2.8 noise floors on four grid cases, docs/DIAGNOSIS-DESIGN.md, "The force scale").
        Such a parameter is better determined relative to the kinetic friction
        (``primary / mu_k``) and is reported so as well.
    probes : callable(dict, ndarray, ndarray) -> list of (dict, dict), optional
        For an effect that the calibrated base coefficients absorb wholesale: ``probes(base,
        speed, slider_scale)`` with ``base`` the calibrated coefficients (``k_c, b_c, k_imp,
        mu_s, mu_k``), ``speed`` the measured band speed (rad/s) of the fit recordings' moving
        samples and ``slider_scale`` the slider friction torque per unit friction coefficient
        at each of them (``R_bo m_b g``, N m; ``m_b`` is the recording's load), returns starts
        ``(effect values, base values)``: the effect switched on at physical amplitudes together
        with the base change that takes the same amount back out of what the calibration
        fitted. The best is continued by one Jacobian in the probe screening, judged apart from
        the other candidates' probes, and (when the probe screening runs) offered to the
        candidate's refit as a start.
    probes_only : bool
        With ``probes``: they replace the bound-fraction probes of
        :meth:`~szdyn.diagnose.starts.RefitStarts._starts` and the fourth start (default,
        slider_stribeck). False: they are tried besides them (slider_viscous, whose fourth
        start named it on seed 20).
    phase_ladder : tuple of float
        Values of the candidate's single parameter tried, each with the fit recordings' wheel
        phases estimated at it, by a phase-profiled step of its refit
        (:meth:`~szdyn.diagnose.refine.FitRefinements._phase_step`), and the reason it is
        refitted in every pass with such steps. For an effect that moves the wheel's angle
        against the measured motor angle: the phases estimated at a base model without it
        absorb that shift, and at them the effect cannot lower the cost (drive_compliance seed
        90, docs/DIAGNOSIS-DESIGN.md, "A drive compliance the wheel phases hide"). Empty: none.
    """

    id: str
    kind: str
    params: tuple
    apply: Callable
    primary: str
    primary_of: Callable
    expression: str
    explains: str
    signature: tuple = ()
    force_scaled: bool = False
    probes: Callable | None = None
    probes_only: bool = True
    phase_ladder: tuple = ()

    def __post_init__(self):
        # the ladder sets the candidate's one parameter (FitRefinements._phase_step)
        if self.phase_ladder and len(self.params) != 1:
            raise ValueError(f"candidate {self.id}: a phase ladder needs a single parameter, "
                             f"it has {len(self.params)}")

    @property
    def own_probes_replace(self) -> bool:
        """Its own ``probes`` replace the bound-fraction probes and the fourth start."""
        return self.probes is not None and self.probes_only


def _lin(name):
    # 0 is "off": return no change at all, so the point is the base model's run (cache hit)
    return lambda v: ({name: v[name]} if v[name] != 0.0 else {}, {})


def _sensor(field, offset=0.0):
    return lambda v: ({}, {field: offset + v[next(iter(v))]} if v[next(iter(v))] != 0.0 else {})


def _periodic(v):
    a_s, a_c = v["a_rev_s"], v["a_rev_c"]
    a = math.hypot(a_s, a_c)
    if a == 0.0:
        return {}, {}
    # a sin(q_b + phi) = a cos(phi) sin(q_b) + a sin(phi) cos(q_b)
    return {"a_rev": a, "phi_rev": math.atan2(a_c, a_s) % (2 * math.pi)}, {}


#: Drive compliance (rad/(N*m)) below which the drive is modelled rigid. Under the reference
#: friction torque tau_k = 0.074 N*m it winds up 0.04 deg, half of a 4096-count encoder's count,
#: and resonates at ~690 Hz (wheel inertia 5.3e-6 kg*m^2), above a 500 Hz logger's Nyquist
#: frequency: the features cannot tell it from rigid. Stiffer drives only cost time: the fit's
#: start clipped to its bound (compliance 2e-9, k_drive 5e8 N*m/rad) made every run crawl.
RIGID_COMPLIANCE = 0.01

#: Drive compliances (rad/(N*m)) tried with profiled wheel phases (``Candidate.phase_ladder``):
#: wind-ups of 0.6-6.3 deg under the reference friction torque tau_k = 0.074 N*m, log-spaced
#: (ratio 1.6; szdyn.synth draws 1-5 deg). On drive_compliance seed 90 (truth 0.346) the fit
#: with profiled phases improved over 0.1-0.45 (2.25 -> 1.32 noise floors at best), a window
#: that steps of 1.6 cannot jump.
COMPLIANCE_LADDER = tuple(math.radians(a) / 0.074 for a in (0.6, 1.0, 1.6, 2.5, 4.0, 6.3))


def _compliance(v):
    c = v["drive_compliance"]
    if c < RIGID_COMPLIANCE:
        return {}, {}
    return {"drive_mode": 2.0, "k_drive": 1.0 / c}, {}


def _stribeck(v):
    if v["mu_st"] == 0.0:
        return {}, {}
    return {"mu_st": v["mu_st"], "v_st": v["v_st"]}, {}


#: Stribeck peaks tried by the probes, as fractions of the calibrated kinetic friction: about the
#: defaults' own static excess (mu_s / mu_k = 1.2) and twice it. (szdyn.synth draws 0.2-0.6.)
STRIBECK_PROBE_FRACTIONS = (0.25, 0.5)
#: Stribeck speeds tried by the probes (rad/s): log-spaced over the fit bounds, as screened.
STRIBECK_PROBE_SPEEDS = (0.1, 0.3, 1.0, 2.5)


def _stribeck_probes(base, speed, slider_scale=None):
    """Stribeck peaks moved out of the calibrated slider friction (see ``Candidate.probes``).

    A base model calibrated on recordings with a low-speed friction peak raises ``mu_s`` and
    ``mu_k`` to carry it, and the peak added on top then sticks the band (slider_stribeck seed
    17: 87 and 92 noise floors on its two 1 kg fit recordings with mu_st 0.05-0.15 on top of a
    calibrated point, against 2.5 and 5.5 without). Each probe keeps the friction at rest
    (``mu_s - mu_st``; at least ``mu_k``) and the mean sliding friction over the recorded band
    speeds (``mu_k - mu_st <exp(-(u/v_st)^2)>``) as calibrated.
    """
    out = []
    for v_st in STRIBECK_PROBE_SPEEDS:
        w = float(np.mean(np.exp(-(np.asarray(speed) / v_st) ** 2))) if len(speed) else 0.0
        for f in STRIBECK_PROBE_FRACTIONS:
            a = f * base["mu_k"]
            mu_k = base["mu_k"] - a * w
            out.append(({"mu_st": a, "v_st": v_st},
                        {**base, "mu_k": mu_k, "mu_s": max(base["mu_s"] - a, mu_k)}))
    return out


#: Viscous drags tried by its probes, as the fraction of the calibrated mean sliding friction
#: torque that they take over: log-spaced, from a drag hardly above the noise to one carrying
#: nearly half the friction. On slider_viscous seed 34 (a drag of 12 % of the truth's mean
#: sliding torque, the calibration's mu_k 48 % high) the fit RMSE of such probes at the calibrated
#: coefficients was 6.8 noise floors at 0.1 and 0.2, 10.4 at 0.25 and 33 at 0.5, the base 17.2:
#: Stribeck's fractions (0.25, 0.5) alone missed the valley.
VISCOUS_PROBE_FRACTIONS = (0.05, 0.1, 0.2, 0.4)


def _viscous_probes(base, speed, slider_scale):
    """Viscous drags moved out of the calibrated kinetic friction (see ``Candidate.probes``).

    A base model calibrated on recordings with a speed-proportional drag raises ``mu_k`` to
    carry its mean, and the drag added on top then sticks the band (slider_viscous seed 34,
    missed out of sample: mu_k calibrated 0.422 against the truth's 0.285, its generic probes on
    top at 2.09 rad/s against the base's 0.117). Each probe hands a fraction ``f`` of the mean
    sliding friction torque over the moving samples to the drag and lowers ``mu_k`` by as much::

        c_visc <|u_b|> = f mu_k <R_bo m_b g>,   mu_k' = (1 - f) mu_k,

    so the mean sliding torque is the calibrated one. The friction at rest (``mu_s``) is kept (a
    drag is 0 there) where the fit's bounds allow: the caller clips every start to them, which
    can lower ``mu_s`` at the larger fractions (its excess over ``mu_k`` is bounded).
    """
    if slider_scale is None:
        raise ValueError("slider_viscous's probes need R_bo m_b g at the moving samples (slider_scale)")
    u = np.abs(np.asarray(speed, dtype=float))
    s = np.asarray(slider_scale, dtype=float)     # its shape is checked by the caller (_own_starts)
    if u.size == 0 or not np.mean(u) > 0.0:
        return []     # no moving sample: nothing to trade
    out = []
    for f in VISCOUS_PROBE_FRACTIONS:
        c = f * base["mu_k"] * float(np.mean(s)) / float(np.mean(u))
        out.append(({"c_visc": c}, {**base, "mu_k": (1.0 - f) * base["mu_k"]}))
    return out


#: Base-model coefficients calibrated in every hypothesis (log space, +-60 % bounds). ``b_imp``
#: is not among them: in the smoothed features it is ~40x below the noise floor and collinear
#: with ``b_c`` and ``k_imp`` (docs/DIAGNOSIS-DESIGN.md), so it stays at its default and the
#: report says so.
#: ``mu_s`` is fitted through its excess over ``mu_k`` (``dmu_s = mu_s - mu_k > 0``) so that
#: the model's requirement ``mu_s >= mu_k`` holds at every trial point.
CALIBRATED = (
    FitParam("k_c", "N*m/rad", 0.4, 2.5, 0.1, log=True, force_power=1.0),
    FitParam("b_c", "N*m*s/rad", 0.4, 2.5, 0.1, log=True, force_power=1.0),
    FitParam("k_imp", "N/m^n", 0.4, 2.5, 0.1, log=True, force_power=1.0),
    FitParam("mu_k", "1", 0.4, 2.5, 0.05, log=True, force_power=1.0),
    FitParam("dmu_s", "1", 0.2, 5.0, 0.1, log=True, force_power=1.0),
)
#: Coefficients the issue names but the data cannot identify (kept at their defaults).
FIXED_UNIDENTIFIED = ("b_imp",)

CANDIDATES: dict[str, Candidate] = {c.id: c for c in (
    Candidate(
        "slider_viscous", "model",
        (FitParam("c_visc", "N*m*s/rad", 0.0, 0.1, 0.005, force_power=1.0),),
        _lin("c_visc"), "c_visc", lambda v: v["c_visc"],
        "tau_b += -c_visc * u_b",
        "band-speed-proportional drag: slip grows with held speed (2 pi vs pi) beyond Coulomb",
        signature=("band_speed",), force_scaled=True, probes=_viscous_probes, probes_only=False),
    Candidate(
        "slider_stribeck", "model",
        (FitParam("mu_st", "1", 0.0, 1.5, 0.1, force_power=1.0),
         FitParam("v_st", "rad/s", 0.05, 3.0, 0.2, start=0.5,
                                                      # log-spaced over the bounds: the column of
                                                      # mu_st depends strongly on v_st
                                                      screen_at=(0.1, 0.3, 1.0, 2.5))),
        _stribeck, "mu_st", lambda v: v["mu_st"],
        "tau_b += -R_bo m_b g mu_st exp(-(u_b/v_st)^2) sign(u_b)",
        "extra friction at low band speed: start-up lag and slow-speed slip, fading at speed",
        signature=("low_speed",), force_scaled=True, probes=_stribeck_probes),
    Candidate(
        "friction_asymmetry", "model",
        (FitParam("fric_asym", "1", -0.7, 0.7, 0.1),),
        _lin("fric_asym"), "fric_asym", lambda v: v["fric_asym"],
        "tau_b += fric_asym sign(u_b) * tau_slider  (friction scaled by 1 + fric_asym sign(u_b))",
        "slip differs between forward and backward runs by the same relative amount at every load",
        signature=("direction",)),
    Candidate(
        "load_lift", "model",
        (FitParam("tau_lift", "N*m", -0.3, 0.3, 0.02, force_power=1.0),),
        _lin("tau_lift"), "tau_lift", lambda v: v["tau_lift"],
        "tau_b += -tau_lift,  tau_lift = m_lift g P_B / (2 pi)",
        "a constant torque against extension: more slip extending, less retracting",
        signature=("direction", "load"), force_scaled=True),
    Candidate(
        "position_periodic", "model",
        (FitParam("a_rev_s", "N*m", -0.15, 0.15, 0.01, force_power=1.0),
         FitParam("a_rev_c", "N*m", -0.15, 0.15, 0.01, force_power=1.0)),
        _periodic, "a_rev", lambda v: math.hypot(v["a_rev_s"], v["a_rev_c"]),
        "tau_b += -a_rev sin(q_b + phi_rev)",
        "residual periodic in the band angle, once per band revolution",
        signature=("sin_band_angle", "cos_band_angle"), force_scaled=True),
    Candidate(
        "friction_drift", "model",
        (FitParam("k_drift", "1/s", -0.3, 0.3, 0.02),),
        _lin("k_drift"), "k_drift", lambda v: v["k_drift"],
        "tau_b += k_drift * t * tau_slider  (slider friction scaled by 1 + k_drift t)",
        "a residual trend within each recording (heating, wear)",
        signature=("time",)),
    Candidate(
        "wheel_band_traction", "model",
        (FitParam("mu_t", "1", 0.0, 2.0, 0.1),),
        _lin("mu_t"), "mu_t", lambda v: v["mu_t"],
        "F_t = -mu_t F_n tanh(v_t / v_teps) at every roller-circle contact (tangential rubber friction)",
        "extra traction growing with contact force: less slip at high load and in transients",
        signature=("load",)),
    Candidate(
        "drive_compliance", "model",
        (FitParam("drive_compliance", "rad/(N*m)", 0.0, 2.0, 0.1, force_power=-1.0),),
        _compliance, "k_drive", lambda v: (1.0 / v["drive_compliance"]
                                           if v["drive_compliance"] >= RIGID_COMPLIANCE else math.inf),
        "tau_w = k_drive (q_m - q_w) + c_drive (u_m - u_w),  q_m the measured motor angle",
        "wind-up between motor encoder and wheel: lag in ramps, oscillation after speed changes",
        signature=("band_accel",), force_scaled=True, phase_ladder=COMPLIANCE_LADDER),
    Candidate(
        "encoder_scale", "sensor",
        (FitParam("encoder_scale", "1", -0.2, 0.2, 0.01),),
        _sensor("encoder_scale_b", 1.0),
        "encoder_scale_b", lambda v: 1.0 + v["encoder_scale"],
        "theta_b,measured = (1 + encoder_scale) theta_b",
        "band speed off by a constant factor: residual proportional to band speed",
        signature=("band_speed",)),
    Candidate(
        "encoder_delay", "sensor",
        (FitParam("encoder_delay", "s", 0.0, 0.1, 0.005),),
        _sensor("encoder_delay_b"),
        "encoder_delay_b", lambda v: v["encoder_delay"],
        "theta_b,measured(t) = theta_b(t - encoder_delay)",
        "band lags the wheel by a constant time: residual proportional to band acceleration",
        signature=("band_accel",)),
)}


def candidate_ids() -> tuple:
    """All candidate ids, in library order."""
    return tuple(CANDIDATES)


def primary_std(cand: Candidate, values: dict, std: dict, corr=None) -> float:
    """Standard deviation of the candidate's primary quantity (delta method).

    Parameters
    ----------
    cand : Candidate
    values, std : dict
        The candidate's fitted coordinates and their standard deviations (own units).
    corr : ndarray, shape (k, k), optional
        Correlation of those coordinates, in ``cand.params`` order (default: uncorrelated, exact
        for one-parameter candidates).

    Returns
    -------
    float
        NaN where a standard deviation is unknown or the primary is not finite.
    """
    names = [p.name for p in cand.params]
    sd = [std.get(n, math.nan) for n in names]
    c = [[1.0 if i == j else (0.0 if corr is None else float(corr[i][j])) for j in range(len(names))]
         for i in range(len(names))]
    grad = []
    for p in cand.params:
        # central difference of the primary (e.g. 1/compliance, hypot of the periodic pair)
        h = 1e-6 * max(abs(values[p.name]), p.probe)
        up, dn = dict(values), dict(values)
        up[p.name] += h
        dn[p.name] -= h
        grad.append((cand.primary_of(up) - cand.primary_of(dn)) / (2 * h))
    var = sum(grad[i] * c[i][j] * sd[i] * sd[j] * grad[j] for i in range(len(names)) for j in range(len(names)))
    return math.sqrt(var) if math.isfinite(var) and var >= 0 else math.nan
