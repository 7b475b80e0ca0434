"""The model's feature for a parameter vector: simulation (cached, parallel) + sensor transform.

A *hypothesis point* is a pair ``(model_changes, sensor_changes)`` applied on top of each
recording's own parameters. Every model run is independent (one recording, one parameter set),
so a batch of points (a finite-difference Jacobian, a screening) runs as one batch of tasks on a
process pool. Runs are cached by their parameters, so a sensor-only change costs no simulation.

Integrator: fixed-step Heun (the thesis's modified Euler) at 0.1 ms, which is smooth in the
parameters (no adaptive step pattern in finite differences) and ~1.6x faster than dopri5; a run
that diverges is repeated with adaptive dopri5 (rtol 1e-5). Where the arm damping puts the arm's
damper mode (rate b_c / (m_c d^2)) past Heun's stability limit at 0.1 ms, Heun runs at half the
step instead: the full step would diverge, and dopri5 there is stiffness-bound and 1.4-2.1x
slower than the half step (measured on the issue's cost case, b_c 0.012-0.0188 N*m*s/rad; the
two agree to 1e-6 rad/s in the smoothed band speed); close below that limit a full step that
diverges is retried at the half step before dopri5 (:func:`integrators`). Runs with
roller-contact friction (``mu_t > 0``, wheel_band_traction) go to dopri5 directly: its
``tanh(v / v_teps)`` is stiff at the contacts, and Heun at 0.1 ms does not diverge there but
quietly loses most of the effect (measured, mu_t 0.28, v_teps 1 mm/s: band angle after 2 s
3.059 rad, 3.057 rad without traction, 2.850 rad converged). The synthetic recordings are
integrated with RK4 (at 10 us when mu_t > 0), so the fit never uses the truth's integrator.

Recordings with a measured motor torque (``Prepared.tau``) also return the model's motor torque
from their runs (:func:`szdyn.sensors.motor_torque`, on the same ``SIM_DT`` grid: sampling the
impact-bumpy contact torque at 1 ms instead of 0.1 ms changed its smoothed value by 0.4-2.5e-5
N m, against bump floors of 1-3e-3 N m, measured on load_lift seed 19); its residual joins a
recording's band-speed residual when ``torque_weights`` holds the recording.
"""
from __future__ import annotations

import math
import os
from collections.abc import Sequence

import numpy as np
from scipy.signal import savgol_filter

from ..errors import SimulationError
from ..processes import worker_init
from .data import SIM_DT, WINDOW_S, Prepared

__all__ = ["FeatureModel", "apply_sensor_transform", "arm_damper_rate", "integrators", "model_speed",
           "model_torque"]

HEUN_DT = 1e-4
_HEUN = {"method": "heun", "dt": HEUN_DT}
_HEUN_HALF = {"method": "heun", "dt": 0.5 * HEUN_DT}
_DOPRI5 = {"method": "dopri5", "rtol": 1e-5, "atol": 1e-8}
#: Attempted dopri5 steps allowed per simulated second before a run counts as failed. A backstop
#: against a fit wandering into a stiff corner: one run must not stall a diagnosis (encoder_delay
#: seed 15 hung 47 min in a drive_compliance refit at k_drive ~ 5e8 N*m/rad, where dopri5 needs
#: ~6e5 steps per simulated second already at k_drive = 1e6). Measured need (2 s ramps to pi/4
#: and pi rad/s): 1.4e4-1.7e4 steps/s for wheel_band_traction at mu_t 0.3, 8.4e4-9.2e4 at mu_t 2 (the
#: fit's upper bound), 6e3 for the base model.
DOPRI5_MAX_STEPS_PER_S = 5e5


#: Heun's stability interval on the negative real axis: |1 + z + z^2/2| <= 1 for -2 <= z <= 0.
HEUN_STABILITY_LIMIT = 2.0
#: Margin on the arm damper's eigenvalue before Heun's full step is skipped: its magnitude is
#: b_c / (m_c d^2) less about k_c / b_c (2e-4 of it at the defaults), and the coupling to the
#: band only makes it larger (measured on the issue's cost case: Heun at 0.1 ms failed for every
#: one of 306 runs with b_c >= 0.01066 N*m*s/rad and ran every one with b_c <= 0.01016, where
#: 2 m_c d^2 / dt = 0.01152).
_ARM_MODE_MARGIN = 1.02
#: Fraction of that limit above which a failed full Heun step is retried at half the step
#: (b_c above ~0.0094 N*m*s/rad at the defaults; see :func:`integrators`).
_ARM_MODE_NEAR = 0.8


def arm_damper_rate(p) -> float:
    """Decay rate (1/s) of a free arm's damper mode, ``b_c / (m_c d^2)``, the mode that limits
    Heun's step when the arm damping is high (``p``: a ParameterSet or mapping, SI)."""
    return p["b_c"] / (p["m_c"] * p["d"] ** 2)


def integrators(p) -> tuple:
    """Integrator settings to try in turn for a run with parameters ``p`` (see the module notes).

    Heun's step is ``HEUN_DT``, or half of it where the arm damper's mode lies beyond Heun's
    stability limit at ``HEUN_DT`` (b_c above ~0.0118 N*m*s/rad at the defaults), where the
    full step must diverge. Close below that limit (``_ARM_MODE_NEAR``) the contacts push the
    mode across it (the full step failed from b_c ~0.0103-0.0107 on grid and cost recordings),
    so a failed full step is retried at the half step before dopri5. Beyond the limit at the
    half step too, dopri5 directly.
    """
    if p["mu_t"] > 0:
        return (_DOPRI5,)
    z = HEUN_DT * arm_damper_rate(p) / (_ARM_MODE_MARGIN * HEUN_STABILITY_LIMIT)
    if z <= _ARM_MODE_NEAR:
        return (_HEUN, _DOPRI5)
    if z <= 1.0:
        return (_HEUN, _HEUN_HALF, _DOPRI5)
    if z <= 2.0:
        return (_HEUN_HALF, _DOPRI5)
    return (_DOPRI5,)


def _key(changes: dict) -> tuple:
    return tuple(sorted((k, float(v)) for k, v in changes.items()))


def _simulate(task):
    """Worker: one model run -> ``(t, theta_b, tau)`` on the ``SIM_DT`` grid, or None if it failed.

    ``theta_b``: band angle from rest (rad); ``tau``: the motor torque (N m,
    :func:`szdyn.sensors.motor_torque`) if the task asks for it, else None (the per-sample
    contact outputs cost ~7 % of a run).
    """
    params, drive, t0, t1, changes, want_torque = task
    from ..params import ParameterSet
    from ..sensors import motor_torque
    from ..simulate import simulate

    changes = dict(changes)
    q_w0 = changes.pop("q_w0", None)      # initial wheel angle (rad), not a model parameter
    p = ParameterSet.from_dict(params)   # a dict travels to the worker (ParameterSet holds a mappingproxy)
    p = p.replace(**changes) if changes else p
    x0 = p.initial_state(q_w0)
    for kw in integrators(p):
        if kw["method"] == "dopri5":
            kw = {**kw, "max_steps": int(DOPRI5_MAX_STEPS_PER_S * max(t1 - t0, 1.0))}
        try:
            run = simulate(p, drive, t1, t0=t0, x0=x0, save_dt=SIM_DT, **kw)
        except SimulationError:
            continue
        qb = run.trajectory.x[:, 1]   # the band angle (rad)
        if np.all(np.isfinite(qb)) and np.abs(np.diff(qb)).max(initial=0.0) < 1.0:
            tau = motor_torque(run) if want_torque else None
            if tau is not None and not np.all(np.isfinite(tau)):
                continue
            return run.trajectory.t, qb - qb[0], tau
    return None


def apply_sensor_transform(t, theta_b, sensor: dict):
    """Band angle as the band encoder would report it (scale and delay; see :mod:`szdyn.sensors`).

    Parameters
    ----------
    t, theta_b : ndarray, shape (n,)
        Time (s) and band angle (rad) from rest at ``t[0]``.
    sensor : dict
        ``encoder_scale_b`` (1), ``encoder_delay_b`` (s); missing means no error.
    """
    scale = float(sensor.get("encoder_scale_b", 1.0))
    delay = float(sensor.get("encoder_delay_b", 0.0))
    out = theta_b
    if delay != 0.0:
        out = np.interp(t - delay, t, theta_b, left=theta_b[0])
    return scale * out if scale != 1.0 else out


def _smoothed_at(t, y, t_feat, window_s: float, deriv: int):
    """Savitzky-Golay (degree 2, ``window_s``, value or first derivative) of a model output on
    its uniform grid ``t``, at the feature instants: the filter the recordings go through."""
    h = float(t[1] - t[0])
    n = int(round(window_s / h))
    n += (n + 1) % 2
    return np.interp(t_feat, t, savgol_filter(y, n, 2, deriv=deriv, delta=h, mode="interp"))


def model_speed(t, theta_b, t_feat, window_s: float = WINDOW_S):
    """Smoothed band speed of a model run at the feature instants (same filter as the data)."""
    return _smoothed_at(t, theta_b, t_feat, window_s, 1)


def model_torque(t, tau, t_feat, window_s: float = WINDOW_S):
    """Smoothed motor torque of a model run at the feature instants (same filter as the
    measured current, :func:`szdyn.recordings.smoothed_current`), N m."""
    return _smoothed_at(t, tau, t_feat, window_s, 0)


class FeatureModel:
    """Evaluate the model's smoothed band speed (and motor torque, where measured) on prepared
    recordings.

    Parameters
    ----------
    recordings : list of Prepared
    workers : int, optional
        Processes (default: CPU count, at most 8); 1 runs in this process.
    progress : callable(int), optional
        Called with the number of model runs finished, after each one (for a progress bar).
    cache : dict, optional
        Runs to share with other models of the same recordings (keyed by recording name and
        parameter changes, so a model with the roles or order of the recordings changed reuses
        them); default: a cache of its own.
    on_runs : callable(dict), optional
        Called with each batch of new runs (``{key: run}``, as added to the cache), also with
        the part finished when a batch is interrupted: how a
        :class:`~szdyn.diagnose.checkpoint.RunCheckpoint` saves them.

    Attributes
    ----------
    n_runs_ : int
        Model runs done (cache misses).
    n_failed_ : int
        Runs that failed with both integrators (their feature is replaced by zeros, i.e. a band
        at rest, which the fit treats as a very poor point).
    """

    def __init__(self, recordings: Sequence[Prepared], workers: int | None = None, progress=None,
                 cache: dict | None = None, on_runs=None):
        self.recordings = list(recordings)
        self._index = {r.name: i for i, r in enumerate(self.recordings)}   # cache keys are names
        self.workers = max(1, min(8, os.cpu_count() or 1) if workers is None else int(workers))
        self.progress = progress
        self._cache: dict = {} if cache is None else cache
        self.on_runs = on_runs
        self._pool = None
        self.n_runs_ = 0
        self.n_failed_ = 0
        #: residual weight per recording index (default 1; see ``Diagnosis(weighting=...)``)
        self.weights = {}
        #: weight (s^-1 rad / (N m)) of the motor-torque residual per recording index; a
        #: recording not in it (default: all) contributes its band speed only
        self.torque_weights = {}
        #: initial wheel angle ``q_w0`` (rad) per recording index, estimated from the recording
        #: (:mod:`.phase`); a recording not in it, or a point that sets ``q_w0`` itself, starts
        #: from the default offset
        self.phases = {}

    # -- pool ------------------------------------------------------------------------------
    def _executor(self):
        if self._pool is None and self.workers > 1:
            import multiprocessing as mp
            from concurrent.futures import ProcessPoolExecutor

            self._pool = ProcessPoolExecutor(self.workers, mp_context=mp.get_context("spawn"),
                                             initializer=worker_init)
        return self._pool

    def close(self):
        if self._pool is not None:
            self._pool.shutdown(cancel_futures=True)
            self._pool = None

    def __enter__(self):
        return self

    def __exit__(self, *exc):
        self.close()

    # -- runs ------------------------------------------------------------------------------
    def _has(self, key) -> bool:
        """Whether the cache answers ``key``: a run shared from a model that did not ask for the
        torque does not answer a recording with a measured one."""
        if key not in self._cache:
            return False
        res = self._cache[key]
        return res is None or res[2] is not None or self.recordings[self._index[key[0]]].tau is None

    def _run_all(self, keys):
        todo = [k for k in dict.fromkeys(keys) if not self._has(k)]
        if not todo:
            return
        tasks = []
        for name, ck in todo:
            r = self.recordings[self._index[name]]
            tasks.append((r.params.to_dict(), r.drive, r.t0, r.t1, dict(ck), r.tau is not None))
        pool = self._executor()
        futs = {}
        if pool is None:
            results = map(_simulate, tasks)
        else:
            # longest first keeps both workers busy to the end
            order = sorted(range(len(tasks)), key=lambda j: -(tasks[j][3] - tasks[j][2]))
            futs = {j: pool.submit(_simulate, tasks[j]) for j in order}
            results = (futs[j].result() for j in range(len(tasks)))
        new = {}

        def add(k, res):
            self._cache[k] = new[k] = res
            self.n_runs_ += 1
            if res is None:
                self.n_failed_ += 1
            if self.progress is not None:
                self.progress(1)
        try:
            for k, res in zip(todo, results):
                add(k, res)
        finally:
            # interrupted: the runs that finished out of the reading order count too (they were
            # handed out longest first), so that a resumed diagnosis need not make them again
            for j, fut in futs.items():
                if todo[j] not in new and fut.done() and not fut.cancelled() and fut.exception() is None:
                    add(todo[j], fut.result())
            if new and self.on_runs is not None:
                self.on_runs(new)

    def speeds(self, points, which: Sequence[int]):
        """Model band speeds for several hypothesis points.

        Parameters
        ----------
        points : list of (dict, dict)
            ``(model_changes, sensor_changes)`` per point.
        which : sequence of int
            Indices of the recordings to evaluate.

        Returns
        -------
        list (per point) of list (per recording) of ndarray, shape (m_i,)
            Smoothed band speed (rad/s) at each recording's ``t_feat``.
        """
        out = []
        for (_, sc), row in zip(points, self._runs_for(points, which)):
            out.append([np.zeros_like(r.y) if res is None else
                        model_speed(res[0], apply_sensor_transform(res[0], res[1], sc), r.t_feat)
                        for r, res in row])
        return out

    def torques(self, points, which: Sequence[int]):
        """Model motor torques (N m) at each recording's ``t_feat``, like :meth:`speeds`;
        None for a recording without a measured torque (``Prepared.tau``).

        The sensor changes of a point do not act on the torque (they are encoder errors).
        """
        return [[None if r.tau is None else np.zeros_like(r.tau) if res is None else
                 model_torque(res[0], res[2], r.t_feat) for r, res in row]
                for row in self._runs_for(points, which)]

    def _run_key(self, i: int, mc: dict) -> tuple:
        """Cache key of recording ``i`` at model changes ``mc``, its wheel phase included."""
        if i in self.phases and "q_w0" not in mc:
            mc = {**mc, "q_w0": self.phases[i]}
        return self.recordings[i].name, _key(mc)

    def _runs_for(self, points, which):
        """Per point, ``(recording, run)`` for each of ``which`` after running what the cache
        lacks; a run is ``(t, theta_b, tau)`` or None if it failed."""
        keys = [[self._run_key(i, mc) for i in which] for mc, _ in points]
        self._run_all([k for row in keys for k in row])
        return [[(self.recordings[i], self._cache[k]) for i, k in zip(which, row)] for row in keys]

    def any_failed(self, points, which: Sequence[int]) -> bool:
        """Whether a run of ``points`` on ``which`` failed, made now or found in the cache (a
        failed run loaded from a checkpoint counts too, which ``n_failed_`` does not)."""
        return any(res is None for row in self._runs_for(points, which) for _, res in row)

    def residuals(self, points, which: Sequence[int]):
        """Residuals per point, concatenated over ``which``: per recording, measured minus model
        band speed (rad/s) times its weight in ``weights`` (default 1), then, if the recording
        is in ``torque_weights``, measured minus model motor torque (N m) times that weight.

        Returns
        -------
        ndarray, shape (n_points, sum of the blocks' lengths)
        """
        sp = self.speeds(points, which)
        tq_idx = [i for i in which if i in self.torque_weights and self.recordings[i].tau is not None]
        tq = self.torques(points, tq_idx) if tq_idx else [[] for _ in points]
        out = []
        for row_s, row_t in zip(sp, tq):
            blocks = []
            tq_of = dict(zip(tq_idx, row_t))
            for i, v in zip(which, row_s):
                r = self.recordings[i]
                blocks.append(self.weights.get(i, 1.0) * (r.y - v))
                if i in tq_of:
                    blocks.append(self.torque_weights[i] * (r.tau - tq_of[i]))
            out.append(np.concatenate(blocks))
        return np.array(out)


def rms(x) -> float:
    x = np.asarray(x, dtype=float)
    return float(math.sqrt(np.mean(x * x))) if x.size else float("nan")
