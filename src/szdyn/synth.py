"""Synthetic test-rig recordings from a richer truth model (issue 5): ``python -m szdyn.run synth``.

What is generated
-----------------
For one seed the generator builds a *truth model* and logs it the way the rig would:

1. **Perturbed coefficients.** The thesis's "arbitrarily chosen" or probe coefficients ``k_c,
   b_c, k_imp, b_imp, mu_k`` are each multiplied by a seeded lognormal factor
   ``exp(perturb * z)``, ``z ~ N(0, 1)`` clipped to +-3. ``mu_s`` is perturbed through its excess
   over ``mu_k``: ``mu_s' = mu_k' + (mu_s - mu_k) exp(perturb * z)``, so that ``mu_s' >= mu_k'``
   always holds (the model requires it).
2. **One concealed effect** from :data:`EFFECTS` (or ``"none"``) at an amplitude given by the
   caller or drawn (seeded) from the effect's *realistic range* (below).
3. **Several loads and ramps.** Each load (kg) sets ``m_b``; each ramp is a wheel-speed
   ramp-and-hold (:class:`szdyn.drive.RampHold`) of ~4.5-5 s. The default ramps reach +pi,
   +2 pi and -pi rad/s (a negative ramp so that ``friction_asymmetry`` is observable; two
   held speeds so that a viscous term is separable from Coulomb friction). ``--ramps`` sets
   other profiles, each optionally ending in a stop (a deceleration to rest), to mimic a rig's
   own protocol.
4. **Initial wheel phase.** Each recording starts from rest with the wheel at a seeded random
   angle within one circle pitch (``q_w0 = default_wheel_offset() + U(0, 2 pi / N_c)``,
   recorded in ``truth.json``), as on a rig: the wheel stops wherever it stops. A fit model
   starts at the default offset, so the impact bumps of a recording are not reproducible sample
   by sample (a common phase would let a fit match them, another inverse crime).
5. **Integration** with classic RK4 at a fixed step ``dt = 2e-5 s`` (default), i.e. another
   integrator and a finer step than the fit's (Heun at 0.1 ms, or adaptive ``dopri5``), so that
   a fit of the recordings is not an "inverse crime". With roller-contact friction
   (``mu_t > 0``) the step is at most ``TRACTION_DT = 1e-5 s``: coarser RK4 steps do not
   resolve its ``tanh(v / v_teps)`` (measured, mu_t 0.28, v_teps 10 mm/s: 0.04 rad off dopri5
   after 2 s at 20-50 us, converged at 10 us).
6. **Sensor model** (:class:`szdyn.sensors.SensorModel`, defaults: 4096/2048 counts/rev,
   0.2 count noise, 500 Hz logger with +-100 us jitter, 0.2 % dropped rows, 1 us stamps),
   seeded per recording. ``theta_w`` is the *motor-side* encoder: with ``drive_compliance``
   it reads the motor angle (the prescribed profile), not the wheel behind the compliance;
   without it motor and wheel coincide.

Outputs in ``out_dir``: one CSV per (load, ramp) (format of :mod:`szdyn.recordings`),
``manifest.toml`` (``[[recording]]`` with ``load_kg`` and ``n_circles``; ``[split] heldout``
naming about a third of the recordings: one per load on a seeded "diagonal" of the load x
ramp grid, unless that leaves a load and travel direction without a fit recording or a held-out
one outside the fitted loads and speeds and another choice does not; ``[motor]
torque_constant`` when the current is logged) and ``truth.json``.

``truth.json`` is the hidden answer (effect id, amplitude, its parameter or sensor changes,
the perturbed coefficients and factors, seed, integrator, sensor settings, ramps). **It is for
scoring only: a diagnosis must never read it** (it reads ``manifest.toml`` and the CSVs).

Realistic amplitude ranges
--------------------------
Reference quantities (nominal defaults, not the perturbed truth): slider kinetic torque
``tau_k = R_bo g m_ref mu_k`` with ``m_ref = 1 kg`` (0.0736 N m), reference held wheel speed
``omega_ref = pi rad/s`` (the thesis's hold speed), band pitch ``P_B`` (41.7 mm).

=================== ===================== ================== =================================
effect              amplitude means       range (drawn)      parameters set
=================== ===================== ================== =================================
slider_viscous      viscous torque at     0.1 - 0.4          ``c_visc = A tau_k / omega_ref``
                    omega_ref / tau_k
slider_stribeck     extra low-speed       0.2 - 0.6          ``mu_st = A mu_k``, ``v_st``
                    friction / mu_k                          log-uniform 0.2-1.0 rad/s (drawn)
friction_asymmetry  relative friction     +-(0.1 - 0.3)      ``fric_asym = A``
                    difference by sign    (random sign)
load_lift           payload lifted (kg)   0.3 - 1.5          ``tau_lift = A g P_B / (2 pi)``
                                                             (same payload in every recording)
position_periodic   once-per-rev torque   0.1 - 0.3          ``a_rev = A tau_k``, ``phi_rev``
                    amplitude / tau_k                        ~ U(0, 2 pi) (drawn)
friction_drift      relative friction     +-(0.1 - 0.3)      ``k_drift = A / T_max``
                    change over the       (random sign)      (T_max: longest recording; the
                    longest recording                        model's time restarts per run)
wheel_band_traction mu_t                  0.1 - 0.5          ``mu_t = A``
drive_compliance    wind-up (deg) under   1 - 5              ``drive_mode = 2``,
                    tau_k                                    ``k_drive = tau_k / radians(A)``
encoder_scale       band-encoder scale    +-(0.005 - 0.03)   sensor ``encoder_scale_b = 1 + A``
                    error                 (random sign)
encoder_delay       band-encoder delay    0.002 - 0.020      sensor ``encoder_delay_b = A``
                    (s)
=================== ===================== ================== =================================

An amplitude of exactly 0 switches the effect off (no parameter or sensor change), so the
recordings equal those of ``"none"`` with the same seed bit for bit. Amplitudes outside the
realistic range are accepted (for benchmark sweeps) with a note on stderr, even with ``--quiet``.

Random streams are separate per purpose (``numpy.random.default_rng([seed, k])``: perturbation,
effect draws, split, and one per recording for the sensor), so the effect never shifts the
noise of another recording, and the output is a deterministic function of the arguments.
"""
from __future__ import annotations

import argparse
import difflib
import json
import math
import re
import sys
import time
from dataclasses import dataclass
from pathlib import Path
from collections.abc import Callable

import numpy as np

from szdyn.cli import Parser, directory
from szdyn.defaults import MAX_N_CIRCLES
from szdyn.errors import SimulationError, UserInputError
from szdyn.heldout import least_hiding, split_features
from szdyn.integrators import check_sampling, steps_per_save
from szdyn.io import atomic_write_text, staged_output, write_json

__all__ = ["Effect", "EFFECTS", "EFFECT_IDS", "RampSpec", "DEFAULT_RAMPS", "QUICK_RAMPS",
           "PERTURBED", "SynthError", "synthesize", "synth_command", "effect_changes",
           "perturbed_coefficients", "record_truth"]

#: Thesis/probe coefficients perturbed in the truth model.
PERTURBED = ("k_c", "b_c", "k_imp", "b_imp", "mu_s", "mu_k")
#: Reference load (kg) and held wheel speed (rad/s) that define the relative amplitudes.
REF_LOAD_KG = 1.0
REF_SPEED = math.pi
#: Largest RK4 step (s) of a truth with roller-contact friction (mu_t > 0); see note 5 above.
TRACTION_DT = 1e-5
#: the truth's sampling by the command (s): well below the logger's 2 ms period, a multiple of --dt
SAVE_DT = 1e-4
#: largest coefficient perturbation (lognormal sigma; the draws are clipped at 3 sigma): at 1 a
#: coefficient may already come out e^3 = 20 times its nominal value
MAX_PERTURB = 1.0

#: a ramp's name, as it goes into its recording's file name (load1kg_NAME.csv)
_RAMP_NAME = re.compile(r"[A-Za-z0-9_-]{1,40}")

# random-stream ids (numpy.random.default_rng([seed, id]))
_S_PERTURB, _S_EFFECT, _S_SPLIT, _S_SENSOR, _S_PHASE = 1, 2, 3, 100, 200


class SynthError(UserInputError):
    """A mistake in the generator's arguments (unknown effect, bad amplitude, ...)."""


# --------------------------------------------------------------------------- ramps
@dataclass(frozen=True)
class RampSpec:
    """A ramp-and-hold wheel-speed profile: ``omega = a t`` up to ``t_ramp``, then held; with
    ``t_stop > 0`` the wheel is then brought to rest at a constant rate over ``t_stop``.

    Attributes
    ----------
    name : str
        Used in the file name (letters, digits, ``_``, ``-``).
    a : float
        Acceleration (rad/s^2), any sign; ``a < 0`` runs the band backwards.
    t_ramp, t_hold : float
        Ramp and hold durations (s).
    t_stop : float
        Duration of the deceleration to rest after the hold (s); 0 (default): the recording
        ends in the hold, as the default ramps do. A stop crosses the low speeds again, slowing
        down, where a run from rest only crosses them speeding up.
    """

    name: str
    a: float
    t_ramp: float
    t_hold: float
    t_stop: float = 0.0

    @property
    def t_end(self) -> float:
        return self.t_ramp + self.t_hold + self.t_stop

    @property
    def omega_hold(self) -> float:
        return self.a * self.t_ramp

    def drive(self):
        from szdyn.drive import RampHold, Sampled, _distinct_times

        if self.t_stop == 0.0:
            return RampHold(a=self.a, t_ramp=self.t_ramp, t_hold=self.t_hold)
        w = self.omega_hold
        # piecewise linear between the knots (Sampled interpolates them), at rest afterwards; a
        # hold that rounding makes zero long is no hold, a stop in no time is refused. Only the
        # stop can take no time with a change of speed (t_ramp > 0 keeps the first two knots
        # apart), so the message names t_stop; the callers name the profile
        t, v = _distinct_times(np.array([0.0, self.t_ramp, self.t_ramp + self.t_hold, self.t_end]),
                               np.array([0.0, w, w, 0.0]), "t_stop")
        return Sampled(t=t, omega=v)

    def to_dict(self) -> dict:
        d = {"name": self.name, "a": self.a, "t_ramp": self.t_ramp, "t_hold": self.t_hold}
        if self.t_stop:    # (absent for the default ramps: their truth.json is as before)
            d["t_stop"] = self.t_stop
        return {**d, "omega_hold": self.omega_hold, "t_end": self.t_end}


DEFAULT_RAMPS = (
    RampSpec("up_pi", 0.5 * math.pi, 2.0, 3.0),     # thesis 0.5 pi rad/s^2 to pi rad/s, 5 s
    RampSpec("up_2pi", math.pi, 2.0, 2.5),          # to 2 pi rad/s, 4.5 s
    RampSpec("down_pi", -0.4 * math.pi, 2.5, 2.5),  # to -pi rad/s, 5 s
)
QUICK_RAMPS = (
    RampSpec("up", 2.0 * math.pi, 0.25, 0.25),
    RampSpec("down", -2.0 * math.pi, 0.25, 0.25),
)
QUICK_N_CIRCLES = 16


# --------------------------------------------------------------------------- effects
@dataclass(frozen=True)
class Effect:
    """One concealed effect of the library.

    Attributes
    ----------
    id : str
    kind : {"model", "sensor"}
        Model parameters or :class:`~szdyn.sensors.SensorModel` fields.
    amplitude : str
        What the amplitude ``A`` means (with unit).
    range : (float, float)
        Realistic magnitude range; a drawn amplitude is uniform in it.
    signed : bool
        A drawn amplitude gets a random sign; a given one may be negative.
    doc : str
        How ``A`` maps to parameters (see the module table).
    build : callable(A, ctx, rng) -> dict
        Parameter (kind "model") or sensor-field (kind "sensor") changes for ``A != 0``.
    """

    id: str
    kind: str
    amplitude: str
    range: tuple
    signed: bool
    doc: str
    build: Callable


def _ctx(n_circles: int, ramps) -> dict:
    from szdyn.defaults import default_parameters

    p = default_parameters(n_circles)
    tau_k = p["R_bo"] * p["g"] * REF_LOAD_KG * p["mu_k"]
    return {"tau_k": tau_k, "omega_ref": REF_SPEED, "pitch": p.geometry.pitch, "g": p["g"],
            "mu_k": p["mu_k"], "t_max": max(r.t_end for r in ramps)}


def _stribeck(A, c, rng):
    v_st = float(math.exp(rng.uniform(math.log(0.2), math.log(1.0))))
    return {"mu_st": A * c["mu_k"], "v_st": v_st}


def _periodic(A, c, rng):
    return {"a_rev": A * c["tau_k"], "phi_rev": float(rng.uniform(0.0, 2 * math.pi))}


EFFECTS: dict[str, Effect] = {e.id: e for e in (
    Effect("slider_viscous", "model", "viscous torque at pi rad/s as a fraction of tau_k",
           (0.1, 0.4), False, "c_visc = A tau_k / pi",
           lambda A, c, rng: {"c_visc": A * c["tau_k"] / c["omega_ref"]}),
    Effect("slider_stribeck", "model", "extra low-speed friction coefficient as a fraction of mu_k",
           (0.2, 0.6), False, "mu_st = A mu_k; v_st log-uniform in [0.2, 1] rad/s", _stribeck),
    Effect("friction_asymmetry", "model", "relative slider-friction difference between directions",
           (0.1, 0.3), True, "fric_asym = A",
           lambda A, c, rng: {"fric_asym": A}),
    Effect("load_lift", "model", "payload mass lifted by the column (kg)",
           (0.3, 1.5), False, "tau_lift = A g P_B / (2 pi)",
           lambda A, c, rng: {"tau_lift": A * c["g"] * c["pitch"] / (2 * math.pi)}),
    Effect("position_periodic", "model", "once-per-band-revolution torque as a fraction of tau_k",
           (0.1, 0.3), False, "a_rev = A tau_k; phi_rev uniform in [0, 2 pi)", _periodic),
    Effect("friction_drift", "model", "relative slider-friction change over the longest recording",
           (0.1, 0.3), True, "k_drift = A / T_max",
           lambda A, c, rng: {"k_drift": A / c["t_max"]}),
    Effect("wheel_band_traction", "model", "tangential friction coefficient mu_t at the rollers",
           (0.1, 0.5), False, "mu_t = A",
           lambda A, c, rng: {"mu_t": A}),
    Effect("drive_compliance", "model", "motor-wheel wind-up under tau_k (degrees)",
           (1.0, 5.0), False, "drive_mode = 2, k_drive = tau_k / radians(A)",
           lambda A, c, rng: {"drive_mode": 2.0, "k_drive": c["tau_k"] / math.radians(A)}),
    Effect("encoder_scale", "sensor", "relative scale error of the band encoder",
           (0.005, 0.03), True, "encoder_scale_b = 1 + A",
           lambda A, c, rng: {"encoder_scale_b": 1.0 + A}),
    Effect("encoder_delay", "sensor", "band-encoder delay (s)",
           (0.002, 0.020), False, "encoder_delay_b = A",
           lambda A, c, rng: {"encoder_delay_b": A}),
)}
#: all ids the generator accepts
EFFECT_IDS = ("none",) + tuple(EFFECTS)


def check_effect(effect: str) -> str:
    """Return ``effect`` if known, else raise :class:`SynthError` with a did-you-mean."""
    if effect in EFFECT_IDS:
        return effect
    close = difflib.get_close_matches(str(effect), EFFECT_IDS, n=1, cutoff=0.4)
    hint = f" (did you mean '{close[0]}'?)" if close else ""
    raise SynthError(f"unknown effect '{effect}'{hint}; known: {', '.join(EFFECT_IDS)}")


def effect_changes(effect: str, amplitude=None, *, seed: int = 0, n_circles: int = 100,
                   ramps=DEFAULT_RAMPS) -> tuple[float, dict, dict]:
    """The switch of one effect: ``(amplitude, model_changes, sensor_changes)``.

    ``amplitude=None`` draws it from the effect's realistic range (seeded); 0 gives no
    changes. Cheap (no simulation).
    """
    check_effect(effect)
    if effect == "none":
        if amplitude not in (None, 0, 0.0):
            raise SynthError("effect 'none' takes no amplitude")
        return 0.0, {}, {}
    e = EFFECTS[effect]
    rng = np.random.default_rng([seed, _S_EFFECT])
    if amplitude is None:
        A = float(rng.uniform(*e.range))
        if e.signed and rng.random() < 0.5:
            A = -A
    else:
        if isinstance(amplitude, bool) or not isinstance(amplitude, (int, float, np.floating, np.integer)):
            raise SynthError(f"amplitude of '{effect}' must be a number, got {amplitude!r}")
        A = float(amplitude)
        if not math.isfinite(A):
            raise SynthError(f"amplitude of '{effect}' must be finite, got {amplitude!r}")
        if A < 0 and not e.signed:
            raise SynthError(f"amplitude of '{effect}' must be >= 0 ({e.amplitude}), got {A:g}")
        if effect == "encoder_scale" and A <= -1:
            raise SynthError(f"amplitude of 'encoder_scale' must be > -1 (scale 1 + A > 0), got {A:g}")
    if A == 0.0:
        return 0.0, {}, {}
    changes = e.build(A, _ctx(n_circles, ramps), rng)
    changes = {k: float(v) for k, v in changes.items()}
    return (A, changes, {}) if e.kind == "model" else (A, {}, changes)


def perturbed_coefficients(perturb: float, seed: int, n_circles: int = 100) -> tuple[dict, dict]:
    """Perturbed ``PERTURBED`` coefficients and their factors (see the module docstring)."""
    from szdyn.defaults import default_parameters

    p = default_parameters(n_circles)
    rng = np.random.default_rng([seed, _S_PERTURB])
    z = np.clip(rng.standard_normal(len(PERTURBED)), -3.0, 3.0)
    f = {n: float(math.exp(perturb * zi)) for n, zi in zip(PERTURBED, z)}
    vals = {n: p[n] * f[n] for n in ("k_c", "b_c", "k_imp", "b_imp", "mu_k")}
    vals["mu_s"] = vals["mu_k"] + (p["mu_s"] - p["mu_k"]) * f["mu_s"]
    return {n: vals[n] for n in PERTURBED}, f


def _ramp_problem(r) -> str | None:
    """What is wrong with a profile (checked by :func:`synthesize` and ``--ramps``), or None."""
    if not (isinstance(r.name, str) and _RAMP_NAME.fullmatch(r.name)):
        # the name goes into a file name: no path separators, nothing a file system refuses
        return "the name: use 1-40 letters, digits, '_' or '-' (it names the recording files)"
    if not (math.isfinite(r.a) and r.a != 0):
        return f"a must be a finite, non-zero acceleration (rad/s^2; negative runs the band backwards), got {r.a!r}"
    for field in ("t_ramp", "t_hold", "t_stop"):
        v = getattr(r, field)
        if not (math.isfinite(v) and (v > 0 if field == "t_ramp" else v >= 0)):
            return f"{field} must be {'> 0' if field == 't_ramp' else '>= 0'} s, got {v!r}"
    try:
        r.drive()
    except ValueError as exc:   # times that rounding makes equal (a stop of 1e-300 s)
        return str(exc)
    return None


# --------------------------------------------------------------------------- generator
def _fmt_load(x: float) -> str:
    return f"{x:g}".replace(".", "p")


def _heldout(loads, ramps, seed: int) -> list[tuple[int, int]]:
    """About a third of the (load, ramp) grid, held out without hiding a condition from the fit.

    The seeded first choice is one recording per load on a diagonal; it stands unless another
    set keeps more (load, direction) pairs among the fit recordings or leaves fewer held-out
    recordings outside the loads and speeds fitted in their direction
    (:func:`szdyn.heldout.least_hiding`). On the grid's design (two loads x two forward ramps and
    one backward) the diagonal alone held out a backward run on 16 of seeds 11-31, the 1 kg one
    on 13 of them; friction_asymmetry 18 was fitted without the one run that showed it.
    """
    n_loads, n_ramps = len(loads), len(ramps)
    n = n_loads * n_ramps
    if n < 2:
        return []
    k = max(1, int(round(n / 3)))
    rng = np.random.default_rng([seed, _S_SPLIT])
    off = int(rng.integers(n_ramps))
    diag = [(i, (i + off) % n_ramps) for i in range(n_loads)]
    rest = [(i, j) for i in range(n_loads) for j in range(n_ramps) if (i, j) not in diag]
    rest = [rest[m] for m in rng.permutation(len(rest))]
    order = diag + rest
    feats = [split_features(loads[i], float(np.sign(ramps[j].omega_hold)), abs(ramps[j].omega_hold))
             for i, j in order]
    return sorted(order[m] for m in least_hiding(feats, k))


def _say(verbose, msg):
    if verbose:
        print(f"synth: {msg}", file=sys.stderr, flush=True)


def synthesize(out_dir, effect: str = "none", amplitude=None, seed: int = 0,
               loads_kg=(0.5, 1.0, 1.5), ramps=DEFAULT_RAMPS, perturb: float = 0.1,
               n_circles: int = 100, *, dt: float = 2e-5, save_dt: float = 1e-4,
               sensor=None, torque_constant=None, verbose: bool = True) -> dict:
    """Write synthetic recordings, ``manifest.toml`` and ``truth.json`` to ``out_dir``.

    Parameters
    ----------
    out_dir : str or Path
        Created if missing. The files are written into a staging directory inside it and
        moved in at the end (recordings, then ``manifest.toml``, then ``truth.json``),
        replacing files of the same names: a run that fails while simulating writes none.
    effect : str
        An id of :data:`EFFECTS` or ``"none"``.
    amplitude : float, optional
        Effect amplitude (meaning per effect, see the module table); default: drawn from the
        realistic range with ``seed``. 0 switches the effect off.
    seed : int
        Seeds everything (perturbation, effect draws, split, sensor noise).
    loads_kg : sequence of float
        Loads (kg, > 0), each sets ``m_b``.
    ramps : sequence of RampSpec or (name, a, t_ramp, t_hold)
        Wheel-speed profiles; default :data:`DEFAULT_RAMPS`.
    perturb : float
        Lognormal sigma of the coefficient perturbation (>= 0; 0 = thesis coefficients).
    n_circles : int
        ``N_c`` of the truth model (also written to the manifest).
    dt, save_dt : float
        RK4 step and truth sampling (s); ``save_dt`` should be well below the logger period.
        With ``mu_t > 0`` the step is reduced to at most ``TRACTION_DT`` (a divisor of ``save_dt``).
    sensor : SensorModel, optional
        Base sensor settings (default :class:`~szdyn.sensors.SensorModel` defaults).
    torque_constant : float, optional
        If given (N m/A), a ``current`` column is logged.
    verbose : bool
        Progress on stderr.

    Returns
    -------
    dict
        The content written to ``truth.json``.

    Raises
    ------
    SynthError
        For bad arguments (unknown effect with a suggestion, bad amplitude/loads/ramps).
    szdyn.errors.SimulationError
        If the truth integration fails (try a smaller ``dt``).
    """
    from szdyn.defaults import default_parameters
    from szdyn.sensors import SensorModel

    check_effect(effect)
    if isinstance(seed, bool) or not isinstance(seed, (int, np.integer)) or seed < 0:
        raise SynthError(f"seed must be a non-negative integer, got {seed!r}")
    seed = int(seed)
    if (isinstance(n_circles, bool) or not isinstance(n_circles, (int, np.integer))
            or not 1 <= n_circles <= MAX_N_CIRCLES):
        raise SynthError(f"n_circles must be a positive integer up to {MAX_N_CIRCLES}, got {n_circles!r}")
    n_circles = int(n_circles)
    loads = [float(x) for x in loads_kg]
    if not loads or not all(math.isfinite(x) and x > 0 for x in loads):
        raise SynthError(f"loads must be positive numbers (kg), got {list(loads_kg)!r}")
    named = {}
    for x in loads:
        named.setdefault(_fmt_load(x), []).append(x)
    same = next((xs for xs in named.values() if len(xs) > 1), None)
    if same:
        # the load names the files (load1kg_up.csv): two loads of one name would overwrite
        raise SynthError(f"loads must be distinct in their first 6 significant digits (they name the "
                         f"files): {', '.join(map(repr, same))} would all write load{_fmt_load(same[0])}kg_*.csv")
    ramps = tuple(r if isinstance(r, RampSpec) else RampSpec(*r) for r in ramps)
    if not ramps or len({r.name for r in ramps}) != len(ramps):
        raise SynthError("ramps must be a non-empty sequence with distinct names")
    for r in ramps:
        problem = _ramp_problem(r)
        if problem:
            raise SynthError(f"ramp {r.name!r}: {problem}")
    if not (math.isfinite(perturb) and 0 <= perturb <= MAX_PERTURB):
        raise SynthError(f"perturb (the coefficients' lognormal sigma) must be in [0, {MAX_PERTURB:g}], got "
                         f"{perturb!r}")
    if not (dt > 0 and save_dt >= dt):
        raise SynthError(f"need 0 < dt <= save_dt, got dt={dt!r}, save_dt={save_dt!r}")

    A, model_changes, sensor_changes = effect_changes(effect, amplitude, seed=seed,
                                                      n_circles=n_circles, ramps=ramps)
    if effect != "none" and amplitude is not None and A != 0:
        lo, hi = EFFECTS[effect].range
        if not lo <= abs(A) <= hi:
            # said even when quiet: the recordings are of an effect no real machine shows
            _say(True, f"note: amplitude {A:g} of '{effect}' is outside its realistic range "
                       f"{lo:g}-{hi:g} ({EFFECTS[effect].amplitude})")
    coeffs, factors = perturbed_coefficients(perturb, seed, n_circles)
    base = default_parameters(n_circles).replace(**coeffs, **model_changes)
    sensor = SensorModel() if sensor is None else sensor
    if torque_constant is not None:
        from dataclasses import replace as dc_replace
        sensor = dc_replace(sensor, torque_constant=float(torque_constant))
    if sensor_changes:
        sensor = _with_fields(sensor, sensor_changes)
    if save_dt > sensor.sample_period / 4:
        raise SynthError(f"save_dt {save_dt:g} s must be <= a quarter of the logger period "
                         f"{sensor.sample_period:g} s")

    if base["mu_t"] > 0 and dt > TRACTION_DT:
        # the largest divisor of save_dt within TRACTION_DT (the integrator saves every k steps)
        dt_new = save_dt / math.ceil(save_dt / TRACTION_DT - 1e-9)
        _say(verbose, f"note: rk4 dt {dt:g} s -> {dt_new:g} s: roller-contact friction (mu_t > 0) "
                      f"needs <= {TRACTION_DT:g} s to converge")
        dt = dt_new
    try:
        check_sampling("rk4", dt, save_dt, max(r.t_end for r in ramps))
    except ValueError as exc:   # a dt that does not divide save_dt, or hours of steps
        raise SynthError(f"the truth's RK4 step: {exc}") from None

    out = Path(out_dir)
    if out.exists() and not out.is_dir():
        raise SynthError(f"output directory {out} is a file")
    # everything is written into a staging directory and moved in at the end: a run that fails
    # while simulating (an unphysical truth, Ctrl-C) writes none of its files, so old and new
    # recordings are not mixed; the manifest, then truth.json last: a reader that checks for
    # truth.json (the grid) sees a complete set
    with staged_output(out, last=("manifest.toml", "truth.json")) as stage:
        truth = _synthesize_into(stage, out, effect, amplitude, A, seed, loads, ramps, perturb,
                                 n_circles, dt, save_dt, base, coeffs, factors, model_changes,
                                 sensor_changes, sensor, verbose)
    return truth


def record_truth(params, drive, t_end: float, sensor, path, *, seed: int, stream: int, dt: float,
                 save_dt: float, final=None):
    """Run the truth on one wheel-speed profile and log it as the rig would (one CSV).

    Parameters
    ----------
    params : ParameterSet
        The truth's parameters, its load (``m_b``) set.
    drive : szdyn.drive profile
        Wheel (motor, with ``drive_mode`` 2) speed; its largest ``|speed|`` bounds the checks.
    t_end : float
        Duration (s).
    sensor : SensorModel
    path : Path
        The CSV to write; its name is the recording's.
    seed, stream : int
        The initial wheel phase (``U(0, pitch)`` past the default offset) and the sensor's noise
        come from ``default_rng([seed, _S_PHASE + stream])`` and ``[seed, _S_SENSOR + stream]``:
        a recording of its own needs a stream of its own.
    dt, save_dt : float
        RK4 step and output step (s).
    final : path-like, optional
        Directory named in error messages (default: ``path``'s).

    Returns
    -------
    q_w0 : float
        Initial wheel angle (rad).
    rec : Recording
        As written.
    outputs : dict
        The run's outputs (``t``, ``q_w``, ``q_b``, ``u_b``, ...).
    """
    from szdyn.sensors import apply_sensor, motor_torque, write_recording
    from szdyn.simulate import simulate

    path = Path(path)
    fname, final = path.name, (path.parent if final is None else final)
    load = params["m_b"]
    n_circles = params.n_circles
    pitch = 2 * math.pi / n_circles
    q_w0 = params.default_wheel_offset() + float(np.random.default_rng([seed, _S_PHASE + stream]).uniform(0, pitch))
    try:
        run = simulate(params, drive, t_end, method="rk4", dt=dt, save_dt=save_dt,
                       x0=params.initial_state(q_w0))
    except SimulationError as exc:
        raise SimulationError(f"truth of {fname} failed: {exc} (for synth: try a smaller --dt than "
                              f"{dt:g} s, or check the load {load:g} kg and the effect's amplitude); "
                              f"nothing was written to {final}", t=exc.t, variable=exc.variable) from exc
    o = run.outputs
    x = run.trajectory.x
    n = n_circles + 2
    w_max = float(np.abs(drive.knots()[1]).max())
    if params["drive_mode"] == 2 and not np.abs(x[:, n]).max() <= 10 * w_max + 10:
        raise SimulationError(
            f"truth of {fname} is unphysical: the wheel behind the compliant drive reaches "
            f"{np.abs(x[:, n]).max():.3g} rad/s for a motor at {w_max:.3g} rad/s "
            f"(k_drive {params['k_drive']:.3g} N m/rad, c_drive {params['c_drive']:.3g} "
            f"N m s/rad); check drive_mode 2 in the model", t=None, variable="u_w")
    if not np.abs(o["u_b"]).max() <= 10 * w_max + 10:
        raise SimulationError(f"truth of {fname} is unphysical: band speed reaches "
                              f"{np.abs(o['u_b']).max():.3g} rad/s (try a smaller --dt, or check "
                              f"the load {load:g} kg and the effect's amplitude); nothing was written to "
                              f"{final}", t=None, variable="u_b")
    # motor-side encoder: with the compliant drive, the prescribed motor angle
    q_enc = drive.evaluate(o["t"], angle0=float(x[0, 0]))[0] if params["drive_mode"] == 2 else o["q_w"]
    torque = motor_torque(run)
    cond = {"load_kg": load, "n_circles": n_circles}
    rec = apply_sensor(o["t"], q_enc, o["q_b"], sensor, np.random.default_rng([seed, _S_SENSOR + stream]),
                       omega_ref=lambda tt, d=drive: d.evaluate(tt)[1], motor_torque=torque,
                       name=fname, conditions=cond)
    write_recording(path, rec)
    return q_w0, rec, o


def _synthesize_into(out, final, effect, amplitude, A, seed, loads, ramps, perturb, n_circles,
                     dt, save_dt, base, coeffs, factors, model_changes, sensor_changes, sensor,
                     verbose) -> dict:
    """The simulations and writes of :func:`synthesize`, into ``out`` (its staging directory;
    ``final`` is only named in messages)."""
    from szdyn.defaults import default_parameters

    held = set(_heldout(loads, ramps, seed))
    _say(verbose, f"effect {effect} (amplitude {A:g}), seed {seed}, N_c {n_circles}, "
                  f"{len(loads)} loads x {len(ramps)} ramps, rk4 dt {dt:g} s -> {final}")
    recs = []
    n_tot = len(loads) * len(ramps)
    wall0 = time.perf_counter()
    for i, load in enumerate(loads):
        params = base.replace(m_b=load)
        for j, ramp in enumerate(ramps):
            k = i * len(ramps) + j
            fname = f"load{_fmt_load(load)}kg_{ramp.name}.csv"
            t0 = time.perf_counter()
            q_w0, rec, o = record_truth(params, ramp.drive(), ramp.t_end, sensor, out / fname, seed=seed,
                                        stream=k, dt=dt, save_dt=save_dt, final=final)
            dq_w, dq_b = o["q_w"][-1] - o["q_w"][0], o["q_b"][-1] - o["q_b"][0]
            slip = (dq_w - dq_b) / dq_w if dq_w != 0 else 0.0
            recs.append({"file": fname, "load_kg": load, "ramp": ramp.name,
                         "heldout": (i, j) in held, "rows": int(rec.t.size), "q_w0": q_w0,
                         "dropped_rows": rec.meta["n_dropped"],
                         "truth_final": {"q_w": float(o["q_w"][-1]), "q_b": float(o["q_b"][-1]),
                                         "u_b": float(o["u_b"][-1]), "slip_fraction": float(slip)}})
            _say(verbose, f"[{k + 1}/{n_tot}] {fname}: {ramp.t_end:g} s simulated in "
                          f"{time.perf_counter() - t0:.1f} s, {rec.t.size} rows, "
                          f"band {o['q_b'][-1]:.2f} rad vs wheel {o['q_w'][-1]:.2f} rad")
            del o

    lines = ["# Synthetic Spiral Zipper recordings (python -m szdyn.run synth).",
             "# truth.json beside this file is the hidden answer for scoring only;",
             "# a diagnosis must not read it.", ""]
    if sensor.torque_constant is not None:
        lines += ["[motor]", f"torque_constant = {float(sensor.torque_constant)!r}  # N m/A, as logged", ""]
    heldnames = [r["file"] for r in recs if r["heldout"]]
    if heldnames:
        lines += ["[split]", "heldout = [" + ", ".join(json.dumps(h) for h in heldnames) + "]", ""]
    for r in recs:
        lines += ["[[recording]]", f"file = {json.dumps(r['file'])}", f"load_kg = {r['load_kg']!r}",
                  f"n_circles = {n_circles}", f"note = {json.dumps('ramp ' + r['ramp'])}", ""]
    atomic_write_text(out / "manifest.toml", "\n".join(lines))

    nominal = default_parameters(n_circles)
    truth = {
        "_note": "hidden answer for scoring only; the diagnosis must not read this file",
        "generator": "szdyn.synth",
        "effect": effect,
        "amplitude": A,
        "amplitude_meaning": None if effect == "none" else EFFECTS[effect].amplitude,
        "amplitude_range": None if effect == "none" else list(EFFECTS[effect].range),
        "amplitude_drawn": amplitude is None and effect != "none",
        "effect_parameters": model_changes,
        "effect_sensor": sensor_changes,
        "seed": seed,
        "perturb": perturb,
        "perturbed": {n: {"value": coeffs[n], "nominal": nominal[n], "factor": factors[n]}
                      for n in PERTURBED},
        "truth_parameters": base.to_dict(),
        "n_circles": n_circles,
        "integrator": {"method": "rk4", "dt": dt, "save_dt": save_dt},
        "sensor": sensor.to_dict(),
        "theta_w_encoder": "motor side (equals the wheel unless drive_compliance)",
        "loads_kg": loads,
        "ramps": [r.to_dict() for r in ramps],
        "reference": {"load_kg": REF_LOAD_KG, "speed_rad_s": REF_SPEED,
                      **{k: v for k, v in _ctx(n_circles, ramps).items() if k != "omega_ref"}},
        "recordings": recs,
    }
    write_json(out / "truth.json", truth)
    _say(verbose, f"wrote {len(recs)} recordings, manifest.toml, truth.json to {final} in "
                  f"{time.perf_counter() - wall0:.1f} s")
    return truth


def _with_fields(sensor, changes):
    from dataclasses import replace as dc_replace

    return dc_replace(sensor, **changes)


# --------------------------------------------------------------------------- CLI
def _loads(text: str):
    if any(not x.strip() for x in text.split(",")):
        raise argparse.ArgumentTypeError(f"expected comma-separated numbers (kg), got an empty entry in {text!r}")
    try:
        vals = [float(x) for x in text.split(",")]
    except ValueError:
        raise argparse.ArgumentTypeError(f"expected comma-separated numbers (kg), got {text!r}") from None
    if not vals or not all(math.isfinite(v) and v > 0 for v in vals):
        raise argparse.ArgumentTypeError(f"loads must be positive numbers (kg), got {text!r}")
    return vals


#: longest profile ``--ramps`` takes (s): a rig's runs last seconds; at the default 20 us step
#: this is already 3e7 RK4 steps per recording
MAX_RAMP_S = 600.0
_RAMP_FIELDS = ("a", "t_ramp", "t_hold", "t_stop")


def _ramps(text: str):
    """``--ramps``: ``NAME:A:T_RAMP:T_HOLD[:T_STOP]`` entries, comma-separated."""
    out = []
    for k, entry in enumerate(text.split(","), 1):
        parts = entry.strip().split(":")
        if not 4 <= len(parts) <= 5:
            raise argparse.ArgumentTypeError(
                f"entry {k} {entry.strip()!r}: expected NAME:A:T_RAMP:T_HOLD[:T_STOP] (A in rad/s^2, "
                f"times in s), e.g. up:1.5708:2:3 or stop:3.1416:1:2:1")
        name, nums = parts[0].strip(), {}
        for field, cell in zip(_RAMP_FIELDS, parts[1:]):
            try:
                nums[field] = float(cell)
            except ValueError:
                raise argparse.ArgumentTypeError(f"entry {k} ({name}): {field} {cell.strip()!r} is not a "
                                                 "number") from None
        r = RampSpec(name, **nums)
        problem = _ramp_problem(r)
        if problem:
            raise argparse.ArgumentTypeError(f"entry {k} ({name}): {problem}")
        if r.t_end > MAX_RAMP_S:
            raise argparse.ArgumentTypeError(f"entry {k} ({name}): lasts {r.t_end:g} s; at most "
                                             f"{MAX_RAMP_S:g} s per profile")
        if r.name in {o.name for o in out}:
            raise argparse.ArgumentTypeError(f"entry {k}: the name {name!r} is used twice (it names the "
                                             "recording files)")
        out.append(r)
    return tuple(out)


def _build_parser() -> argparse.ArgumentParser:
    ap = Parser("synth", prog="python -m szdyn.run synth",
                 description="Write synthetic recordings (CSV + manifest.toml + truth.json) from a "
                             "perturbed truth model with one concealed effect.")
    ap.add_argument("--out", type=directory, required=True, help="output directory")
    ap.add_argument("--effect", default="none", help=f"concealed effect: {', '.join(EFFECT_IDS)}")
    ap.add_argument("--amplitude", type=float, help="effect amplitude (default: drawn from its realistic range)")
    ap.add_argument("--seed", type=int, default=0, help="random seed (default 0)")
    ap.add_argument("--loads", type=_loads, help="loads in kg, comma-separated (default 0.5,1,1.5)")
    ap.add_argument("--ramps", type=_ramps, metavar="NAME:A:T_RAMP:T_HOLD[:T_STOP],...",
                    help="wheel-speed profiles, one recording per load and profile: accelerate at A "
                         "rad/s^2 for T_RAMP s, hold T_HOLD s, then (T_STOP > 0) decelerate to rest in "
                         "T_STOP s; comma-separated, at most 600 s each (default, rounded: "
                         "up_pi:1.5708:2:3,up_2pi:3.1416:2:2.5,down_pi:-1.2566:2.5:2.5; with --quick "
                         "up:6.2832:0.25:0.25,down:-6.2832:0.25:0.25)")
    ap.add_argument("--n-circles", type=int, help="N_c of the truth model (default 100; 16 with --quick)")
    ap.add_argument("--perturb", type=float, default=0.1,
                    help="lognormal sigma of the coefficient perturbation, 0..1 (default 0.1)")
    ap.add_argument("--dt", type=float, default=2e-5,
                    help="RK4 step of the truth (s, default 2e-5; a divisor of 1e-4 s, or at most 5e-4 s)")
    ap.add_argument("--current", type=float, metavar="KT",
                    help="also log motor current with torque constant KT (N m/A, 1e-6..1e3)")
    ap.add_argument("--quick", action="store_true", help="N_c 16 and two 0.5 s ramps (for tests)")
    ap.add_argument("--list-effects", action="store_true", help="print the effect library and exit")
    ap.add_argument("--overwrite", action="store_true",
                    help="replace the files of the same names already in --out; other files "
                         "there are left (default: refuse when --out holds a CSV, manifest.toml "
                         "or truth.json)")
    ap.add_argument("--quiet", action="store_true", help="no progress on stderr")
    return ap


def _existing_outputs(out: Path) -> list:
    """Files in ``out`` that a synth run writes or that belong to another set of recordings."""
    if not out.is_dir():
        return []
    return sorted(p.name for p in out.iterdir()
                  if p.is_file() and (p.name in ("manifest.toml", "truth.json") or p.suffix == ".csv"))


def synth_command(argv) -> int:
    """``python -m szdyn.run synth ...``; returns the exit code (mistakes raise
    :class:`~szdyn.errors.UserInputError`: SynthError, or the parser's own)."""
    argv = list(argv)
    if "--list-effects" in argv:
        for e in EFFECTS.values():
            print(f"{e.id:20s} {e.kind:6s} A = {e.amplitude}; range {'+-' if e.signed else ''}"
                  f"{e.range[0]:g}-{e.range[1]:g}; {e.doc}")
        return 0
    args = _build_parser().parse_args(argv)
    check_effect(args.effect)
    if args.seed < 0:
        raise SynthError(f"synth: --seed must be >= 0, got {args.seed}")
    if args.n_circles is not None and not 1 <= args.n_circles <= MAX_N_CIRCLES:
        raise SynthError(f"synth: --n-circles must be a positive integer up to {MAX_N_CIRCLES} (the thesis "
                         f"uses 100), got {args.n_circles}")
    if args.amplitude is not None and not math.isfinite(args.amplitude):
        raise SynthError(f"synth: --amplitude must be finite, got {args.amplitude}")
    if not (math.isfinite(args.dt) and args.dt > 0):
        raise SynthError(f"synth: --dt must be > 0, got {args.dt}")
    if args.dt < SAVE_DT:
        try:
            steps_per_save(args.dt, SAVE_DT)
        except ValueError:
            raise SynthError(f"synth: --dt must divide the truth's {SAVE_DT:g} s sampling (e.g. 5e-5, 2.5e-5, "
                             f"2e-5, 1e-5), got {args.dt:g}") from None
    if args.current is not None and not (math.isfinite(args.current) and 1e-6 <= args.current <= 1e3):
        # a guard: motor torque constants are ~0.01-1 N m/A; 1e-310 made an infinite current column
        raise SynthError(f"synth: --current must be a torque constant in 1e-6..1e3 N m/A, got {args.current}")
    from szdyn.sensors import SensorModel

    period = SensorModel().sample_period
    if args.dt > period / 4:
        raise SynthError(f"synth: --dt must be <= {period / 4:g} s (a quarter of the logger's "
                         f"sample period {period:g} s), got {args.dt:g}")
    try:
        is_file = args.out.exists() and not args.out.is_dir()
    except OSError as exc:   # e.g. a name too long
        raise SynthError(f"synth: --out {args.out}: not a usable directory ({exc.strerror or exc})") from None
    if is_file:
        raise SynthError(f"synth: --out {args.out} is a file, expected a directory")
    clash = _existing_outputs(args.out)
    if clash and not args.overwrite:
        more = f" and {len(clash) - 4} more" if len(clash) > 4 else ""
        raise SynthError(f"synth: --out {args.out} already holds {', '.join(clash[:4])}{more}; "
                         "choose a new or empty directory, or pass --overwrite to replace them")
    kw = {}
    if args.quick:
        kw.update(ramps=QUICK_RAMPS, n_circles=QUICK_N_CIRCLES)
    if args.n_circles is not None:
        kw["n_circles"] = args.n_circles
    if args.loads is not None:
        kw["loads_kg"] = tuple(args.loads)
    if args.ramps is not None:
        kw["ramps"] = args.ramps
    synthesize(args.out, effect=args.effect, amplitude=args.amplitude, seed=args.seed,
               perturb=args.perturb, dt=args.dt, save_dt=max(SAVE_DT, args.dt),
               torque_constant=args.current, verbose=not args.quiet, **kw)
    return 0


if __name__ == "__main__":  # pragma: no cover
    try:
        sys.exit(synth_command(sys.argv[1:]))
    except UserInputError as exc:
        print(f"error: {exc}", file=sys.stderr)
        sys.exit(2)
