"""Sensor and logger model: simulated truth -> realistic recording.

A test rig does not see ``q_w(t), q_b(t)``; it sees what two incremental encoders and a
microcontroller logger make of them. :class:`SensorModel` reproduces that chain, in this order,
for each channel ``c`` in (wheel ``w``, band ``b``):

1. **Logger sampling.** Nominal instants ``t_n = t_0 + n T`` (``sample_period`` ``T``); the
   encoders are latched at ``t_n + j_n`` with loop jitter ``j_n ~ U(-jitter, +jitter)``; each row
   is lost with probability ``drop_rate`` (serial buffer overruns); the row is time-stamped
   ``t_n + j_n + log_delay``, rounded to ``timestamp_resolution`` (``micros()``).
2. **Encoder timing and scale (effects).** The channel reads the truth at
   ``t_latch - encoder_delay_c`` and multiplied by ``encoder_scale_c`` (a wrong counts-per-rev
   or gear/roll-radius assumption). These are the *effects* the diagnosis must find; only the
   band channel relative to the wheel matters for slip, so the effect names map to the band
   channel (:data:`EFFECTS`).
3. **Noise.** Gaussian, ``noise_counts_c`` counts standard deviation, added *before*
   quantization (it makes counts flicker at edges, as mechanical vibration and edge jitter do).
4. **Quantization.** ``counts = floor(angle / step + phase)``, ``step = 2 pi / cpr_c``, with an
   unknown zero phase ``phase ~ U(0, 1)`` per channel; the recorded angle is ``counts * step``
   and starts within one count of 0.

Optionally the speed set-point ``omega_ref`` (exact, from the drive profile at the latch time)
and the motor current ``current = tau_motor / torque_constant + noise`` are logged.

Defaults and their provenance (:data:`PROVENANCE`): wheel/motor encoder 4096 counts/rev
(1024-line optical encoder with 4x quadrature decoding; typical hobby/industrial encoders give
1024-4096 CPR), band encoder 2048 counts/rev (512-line), 0.2 count noise; logging at 500 Hz
(Arduino Due serial logging typically runs at 100-1000 Hz) with +-100 us loop jitter, 0.2 %
dropped rows, 1 us timestamps; no effects (scales 1, delays 0).

All randomness comes from one :class:`numpy.random.Generator`: the same seed gives the same
recording.
"""
from __future__ import annotations

import math
from dataclasses import asdict, dataclass, replace
from pathlib import Path

import numpy as np

from szdyn.errors import UserInputError
from szdyn.io import atomic_write_text
from szdyn.recordings import Recording

__all__ = ["SensorModel", "SensorError", "PROVENANCE", "EFFECTS", "apply_sensor", "motor_torque", "record_run",
           "truth_recording", "write_recording"]

#: diagnosis effect name -> SensorModel field it sets
EFFECTS = {"encoder_scale": "encoder_scale_b", "encoder_delay": "encoder_delay_b"}

#: field -> where the default comes from
PROVENANCE = {
    "cpr_w": "1024-line optical encoder on the wheel/motor shaft read in 4x quadrature; "
             "common encoders give 1024-4096 counts/rev",
    "cpr_b": "512-line band encoder (measuring wheel on the band) in 4x quadrature",
    "noise_counts_w": "edge jitter / vibration; a fraction of a count (assumed)",
    "noise_counts_b": "as noise_counts_w (assumed)",
    "sample_period": "500 Hz: Arduino Due logging over USB serial typically runs at 100-1000 Hz",
    "jitter": "+-100 us loop jitter from interrupts and blocking serial writes (assumed)",
    "drop_rate": "0.2 % rows lost to serial buffer overruns (assumed)",
    "log_delay": "0: timestamp taken when the encoders are latched",
    "timestamp_resolution": "1 us: Arduino micros()",
    "encoder_scale_w": "1: no scale error (effect off)",
    "encoder_scale_b": "1: no scale error (effect 'encoder_scale' off)",
    "encoder_delay_w": "0 s (effect off)",
    "encoder_delay_b": "0 s (effect 'encoder_delay' off)",
    "torque_constant": "None: no current column; e.g. 0.05 N m/A for a small geared DC motor",
    "current_noise": "0.01 A, ADC + shunt noise (assumed)",
}


class SensorError(UserInputError):
    """An invalid sensor-model setting (the message names the field)."""


@dataclass(frozen=True)
class SensorModel:
    """Encoders + microcontroller logger (see the module docstring for the chain).

    Parameters
    ----------
    cpr_w, cpr_b : int
        Counts per revolution of the wheel/motor and band encoders (after quadrature).
    noise_counts_w, noise_counts_b : float
        Gaussian angle noise before quantization, standard deviation in counts (>= 0).
    sample_period : float
        Nominal logger period ``T`` (s, > 0).
    jitter : float
        Half-width of the uniform latch-time jitter (s), ``0 <= jitter < T / 2`` so rows stay
        in order.
    drop_rate : float
        Probability that a row is lost, in ``[0, 1)``.
    log_delay : float
        Time stamp minus latch time (s, >= 0), common to all channels.
    timestamp_resolution : float
        Time stamps are rounded to this (s, >= 0; 0 = exact), must be < ``T / 4``.
    encoder_scale_w, encoder_scale_b : float
        Multiplicative scale of each channel (> 0). ``encoder_scale_b`` is effect
        ``encoder_scale``.
    encoder_delay_w, encoder_delay_b : float
        Channel delay (s, >= 0): the value logged at latch time ``t`` is the truth at
        ``t - delay``. ``encoder_delay_b`` is effect ``encoder_delay``.
    torque_constant : float or None
        Motor torque constant (N m/A); ``None`` logs no current.
    current_noise : float
        Gaussian current noise (A, >= 0).
    """

    cpr_w: int = 4096
    cpr_b: int = 2048
    noise_counts_w: float = 0.2
    noise_counts_b: float = 0.2
    sample_period: float = 0.002
    jitter: float = 1e-4
    drop_rate: float = 0.002
    log_delay: float = 0.0
    timestamp_resolution: float = 1e-6
    encoder_scale_w: float = 1.0
    encoder_scale_b: float = 1.0
    encoder_delay_w: float = 0.0
    encoder_delay_b: float = 0.0
    torque_constant: float | None = None
    current_noise: float = 0.01

    def __post_init__(self):
        def real(name, lo=None, lo_open=False, hi=None):
            v = getattr(self, name)
            if isinstance(v, bool) or not isinstance(v, (int, float, np.floating, np.integer)) \
                    or not math.isfinite(float(v)):
                raise SensorError(f"sensor '{name}' must be a finite number, got {v!r}")
            v = float(v)
            if lo is not None and (v <= lo if lo_open else v < lo):
                raise SensorError(f"sensor '{name}' must be {'>' if lo_open else '>='} {lo}, got {v!r}")
            if hi is not None and v >= hi:
                raise SensorError(f"sensor '{name}' must be < {hi:g}, got {v!r}")
            object.__setattr__(self, name, v)

        for name in ("cpr_w", "cpr_b"):
            v = getattr(self, name)
            if isinstance(v, bool) or not isinstance(v, (int, np.integer)) or v < 1:
                raise SensorError(f"sensor '{name}' must be a positive integer (counts/rev), got {v!r}")
            object.__setattr__(self, name, int(v))
        real("sample_period", 0.0, lo_open=True)
        real("noise_counts_w", 0.0)
        real("noise_counts_b", 0.0)
        real("jitter", 0.0, hi=self.sample_period / 2)
        real("drop_rate", 0.0, hi=1.0)
        real("log_delay", 0.0)
        real("timestamp_resolution", 0.0, hi=self.sample_period / 4)
        if self.sample_period - 2 * self.jitter <= self.timestamp_resolution:
            raise SensorError("sensor 'jitter' too large: sample_period - 2 jitter must exceed "
                              "timestamp_resolution so that time stamps stay increasing")
        real("encoder_scale_w", 0.0, lo_open=True)
        real("encoder_scale_b", 0.0, lo_open=True)
        real("encoder_delay_w", 0.0)
        real("encoder_delay_b", 0.0)
        real("current_noise", 0.0)
        if self.torque_constant is not None:
            real("torque_constant", 0.0, lo_open=True)

    @property
    def step_w(self) -> float:
        """Wheel encoder quantization step ``2 pi / cpr_w`` (rad)."""
        return 2 * math.pi / self.cpr_w

    @property
    def step_b(self) -> float:
        """Band encoder quantization step ``2 pi / cpr_b`` (rad)."""
        return 2 * math.pi / self.cpr_b

    def with_effects(self, **effects) -> "SensorModel":
        """Copy with diagnosis effects set, e.g. ``with_effects(encoder_scale=1.01)``.

        Raises
        ------
        SensorError
            For a name not in :data:`EFFECTS`.
        """
        changes = {}
        for k, v in effects.items():
            if k not in EFFECTS:
                raise SensorError(f"unknown sensor effect '{k}'; known: {', '.join(EFFECTS)}")
            changes[EFFECTS[k]] = v
        return replace(self, **changes)

    def to_dict(self) -> dict:
        """All fields as a JSON-ready dict."""
        return asdict(self)


def _quantize(angle, step, noise_counts, rng):
    phase = rng.random()
    x = angle / step + phase
    if noise_counts > 0:
        x = x + rng.normal(0.0, noise_counts, size=x.shape)
    counts = np.floor(x)
    return counts * step


def apply_sensor(t, q_w, q_b, sensor: SensorModel | None = None, rng=None, *, omega_ref=None,
                 motor_torque=None, name: str = "synthetic", conditions: dict | None = None,
                 t_start: float | None = None, t_stop: float | None = None) -> Recording:
    """Turn a finely sampled truth into a logged recording.

    Parameters
    ----------
    t : array_like, shape (n,)
        Truth times (s), increasing; the step should be well below ``sensor.sample_period``
        (a note is added to the recording otherwise: the angles are linearly interpolated).
    q_w, q_b : array_like, shape (n,)
        True wheel and band angles (rad).
    sensor : SensorModel, optional
        Default ``SensorModel()``.
    rng : numpy.random.Generator or int or None
        Source of all randomness (an int is used as a seed).
    omega_ref : callable, optional
        ``omega_ref(t_latch) -> ndarray`` speed set-point (rad/s), logged exactly.
    motor_torque : array_like, shape (n,), optional
        Motor torque on the truth grid (N m); logged as current if
        ``sensor.torque_constant`` is set.
    name : str
        Recording name.
    conditions : dict, optional
        Conditions to attach.
    t_start, t_stop : float, optional
        Logging window (s); default the truth's span.

    Returns
    -------
    Recording
        Columns ``t, theta_w, theta_b`` (+ ``omega_ref``, ``current``); ``meta`` holds the
        sensor settings, the latch times (``meta['t_latch']``, shape (m,)) and the seed state.
    """
    sensor = SensorModel() if sensor is None else sensor
    rng = np.random.default_rng(rng)
    t = np.asarray(t, float)
    q_w = np.asarray(q_w, float)
    q_b = np.asarray(q_b, float)
    t0 = t[0] if t_start is None else float(t_start)
    t1 = t[-1] if t_stop is None else float(t_stop)
    T = sensor.sample_period
    n = int(math.floor((t1 - t0 - sensor.jitter) / T + 1e-9)) + 1
    nominal = t0 + T * np.arange(n)
    jit = rng.uniform(-sensor.jitter, sensor.jitter, size=n) if sensor.jitter > 0 else np.zeros(n)
    jit[0] = abs(jit[0])                     # do not latch before the truth starts
    latch = nominal + jit
    keep = rng.random(n) >= sensor.drop_rate
    latch = latch[keep]
    stamp = latch + sensor.log_delay
    if sensor.timestamp_resolution > 0:
        r = sensor.timestamp_resolution
        stamp = np.round(stamp / r) * r
    th_w0 = float(np.interp(t0 - sensor.encoder_delay_w, t, q_w))
    th_b0 = float(np.interp(t0 - sensor.encoder_delay_b, t, q_b))
    ang_w = sensor.encoder_scale_w * (np.interp(latch - sensor.encoder_delay_w, t, q_w) - th_w0)
    ang_b = sensor.encoder_scale_b * (np.interp(latch - sensor.encoder_delay_b, t, q_b) - th_b0)
    theta_w = _quantize(ang_w, sensor.step_w, sensor.noise_counts_w, rng)
    theta_b = _quantize(ang_b, sensor.step_b, sensor.noise_counts_b, rng)
    notes = []
    h = float(np.median(np.diff(t)))
    if h > T / 2:
        notes.append(f"truth step {h:g} s is coarse against the logger period {T:g} s; "
                     "angles were linearly interpolated")
    ref = None if omega_ref is None else np.asarray(omega_ref(latch), float)
    cur = None
    if sensor.torque_constant is not None and motor_torque is not None:
        cur = np.interp(latch, t, np.asarray(motor_torque, float)) / sensor.torque_constant
        if sensor.current_noise > 0:
            cur = cur + rng.normal(0.0, sensor.current_noise, size=cur.shape)
    return Recording(name=name, t=stamp, theta_w=theta_w, theta_b=theta_b, omega_ref=ref,
                     current=cur, conditions=dict(conditions or {}), notes=notes,
                     meta={"sensor": sensor.to_dict(), "t_latch": latch,
                           "n_nominal": n, "n_dropped": int(n - keep.sum())})


def motor_torque(run) -> np.ndarray:
    """Torque the motor applies (N m) at the run's output instants, shape (n,).

    Speed drive: ``I_W * d(omega_w)/dt - wheel_reaction_torque`` (the torque that makes the
    wheel follow its profile against the contacts). Compliant drive (``drive_mode`` 2, a speed
    profile prescribing the motor): the torque in the compliance,
    ``k_drive (q_m - q_w) + c_drive (u_m - u_w)`` (the motor's own inertia is not modelled).
    Torque drive: the drive torque.
    """
    t = run.trajectory.t
    if run.drive.mode == "torque":
        return np.asarray(run.drive.evaluate(t)[1], float)
    if run.params["drive_mode"] == 2:
        from szdyn.drive import array_to_knots, evaluate_knots

        x = run.trajectory.x
        u_w = x[:, run.params.n_circles + 2]
        q_m, u_m, _ = evaluate_knots(*array_to_knots(run.drive_array), t)
        return run.params["k_drive"] * (q_m - x[:, 0]) + run.params["c_drive"] * (u_m - u_w)
    # only here the per-sample contact outputs are needed
    accel = np.asarray(run.drive.evaluate(t)[2], float)
    return run.params["I_W"] * accel - run.outputs["wheel_reaction_torque"]


def record_run(run, sensor: SensorModel | None = None, rng=None, *, name: str = "synthetic",
               conditions: dict | None = None) -> Recording:
    """Log a :class:`szdyn.simulate.Run` through the sensor model.

    The speed set-point is taken from the drive profile (speed drives only) and the motor
    torque ``I_W * accel - wheel_reaction_torque`` (speed drive) or the drive torque (torque
    drive) for the current. Simulate with ``save_dt`` several times finer than
    ``sensor.sample_period`` (e.g. 1e-4 s for a 2 ms logger).

    Parameters
    ----------
    run : szdyn.simulate.Run
    sensor, rng, name, conditions
        As in :func:`apply_sensor`.

    Returns
    -------
    Recording
    """
    o = run.outputs
    ref = None
    if run.drive.mode == "speed":
        def ref(tt):
            return run.drive.evaluate(tt)[1]
    return apply_sensor(o["t"], o["q_w"], o["q_b"], sensor, rng, omega_ref=ref,
                        motor_torque=motor_torque(run), name=name, conditions=conditions)


def truth_recording(run, *, name: str = "truth", conditions: dict | None = None) -> Recording:
    """The run's exact angles as a :class:`Recording` (no sensor), for feature comparison.

    Angles are taken relative to their initial values (as an encoder reads them). The
    set-point column is the drive speed for speed drives.
    """
    o = run.outputs
    ref = run.drive.evaluate(o["t"])[1] if run.drive.mode == "speed" else None
    return Recording(name=name, t=o["t"], theta_w=o["q_w"] - o["q_w"][0],
                     theta_b=o["q_b"] - o["q_b"][0], omega_ref=ref,
                     conditions=dict(conditions or {}), meta={"truth": True})


def write_recording(path, rec: Recording, *, digits: int = 12) -> Path:
    """Write a recording as CSV (atomically) in the format :func:`read_recording` reads.

    Parameters
    ----------
    path : str or Path
    rec : Recording
    digits : int
        Significant digits (default 12: 1 us at 1e5 s, sub-count angles over 1e4 rev).

    Returns
    -------
    Path
    """
    cols = rec.columns()
    names = list(cols)
    data = np.column_stack([cols[k] for k in names])
    if not np.all(np.isfinite(data)):
        raise ValueError(f"refusing to write non-finite values to {path}")
    fmt = f"{{:.{digits}g}}"
    lines = [",".join(names)]
    lines += [",".join(fmt.format(v) for v in row) for row in data]
    return atomic_write_text(path, "\n".join(lines) + "\n")
