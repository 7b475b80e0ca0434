"""One simulation run: parameters + drive profile + integrator -> trajectory and outputs."""
from __future__ import annotations

from dataclasses import dataclass, field
from functools import cached_property

import numpy as np

from szdyn_generated import spiral_zipper as model

from .integrators import Trajectory, integrate
from .io import write_csv
from .params import ParameterSet

#: Below this wheel speed (rad/s) the slip ratio is reported as 0: it is undefined at rest.
SLIP_RATIO_MIN_SPEED = 1e-6

OUTPUT_UNITS = {
    "t": "s", "q_w": "rad", "q_b": "rad", "u_w": "rad/s", "u_b": "rad/s",
    "rel_speed": "rad/s", "slip_ratio": "1", "stroke": "m", "stroke_lost": "m",
    "contacts": "1", "wheel_reaction_torque": "N*m",
}


@dataclass
class Run:
    """A finished simulation.

    Attributes
    ----------
    params : ParameterSet
    drive : profile object from :mod:`szdyn.drive`
    trajectory : Trajectory
        ``t`` shape (n,), ``x`` shape (n, 2 N_c + 4).
    outputs : dict of str -> ndarray, shape (n,)
        Computed on first access (a caller that reads only the state, like the diagnosis's
        thousand runs, does not pay the per-sample contact outputs: 7 % of a 10 s Heun run).
        ``t`` (s), ``q_w``, ``q_b`` (rad), ``u_w``, ``u_b`` (rad/s), ``rel_speed = u_w - u_b``
        (rad/s), ``slip_ratio = (u_w - u_b)/u_w`` (0 while |u_w| < 1e-6 rad/s), ``stroke`` =
        P_B q_b / (2 pi) (m, eqs 1-5), ``stroke_lost`` = P_B (q_w - q_b)/(2 pi) (m, the stroke
        the slip has cost), ``contacts`` (roller-circle pairs in contact) and
        ``wheel_reaction_torque`` (N m, contact torque on the wheel; the motor must supply its
        negative on top of I_W times the wheel's acceleration).
    """

    params: ParameterSet
    drive: object
    trajectory: Trajectory
    #: the flat parameter and drive arrays the run was integrated with (for the outputs)
    p: np.ndarray = field(repr=False)
    drive_array: np.ndarray = field(repr=False)

    @cached_property
    def outputs(self) -> dict:
        return compute_outputs(self.params, self.drive, self.trajectory, self.p, self.drive_array)

    def to_csv(self, path) -> None:
        """Write the outputs as CSV (atomically); units are in ``OUTPUT_UNITS``."""
        write_csv(path, self.outputs)


def compute_outputs(params: ParameterSet, drive, traj: Trajectory, p: np.ndarray, drive_arr: np.ndarray) -> dict:
    nc = params.n_circles
    n = nc + 2
    t = traj.t
    x = traj.x
    if params["drive_mode"] == 0:
        # The prescribed motion is exact; the state's copy of it carries integration error.
        q_w, u_w, _ = drive.evaluate(t, angle0=float(x[0, 0]))
    else:
        q_w, u_w = x[:, 0], x[:, n]
    q_b, u_b = x[:, 1], x[:, n + 1]
    rel = u_w - u_b
    moving = np.abs(u_w) >= SLIP_RATIO_MIN_SPEED
    slip = np.where(moving, rel / np.where(moving, u_w, 1.0), 0.0)
    geom = params.geometry
    counts, torque = model.per_sample_outputs(t, np.ascontiguousarray(x), p, drive_arr)
    return {
        "t": t, "q_w": q_w, "q_b": q_b, "u_w": u_w, "u_b": u_b, "rel_speed": rel,
        "slip_ratio": slip, "stroke": geom.stroke(q_b - q_b[0]),
        "stroke_lost": geom.stroke((q_w - q_w[0]) - (q_b - q_b[0])),
        "contacts": counts, "wheel_reaction_torque": torque,
    }


def simulate(params: ParameterSet, drive, t_end: float, *, method: str = "rk4", dt: float = 1e-5,
             save_dt: float = 1e-3, rtol: float = 1e-6, atol: float = 1e-9, x0=None,
             progress=None, **integrate_kwargs) -> Run:
    """Simulate the Spiral Zipper from rest (or ``x0``) to ``t_end`` seconds.

    Parameters
    ----------
    params : ParameterSet
        Model parameters (SI). ``drive_mode`` follows the drive profile (speed profile: 0,
        torque: 1), except that a speed profile with ``drive_mode = 2`` in ``params`` prescribes
        the motor, coupled to the wheel by the compliant drive (k_drive, c_drive).
    drive : Ramp, RampHold, Trapezoid, Sampled or Torque
        Wheel drive profile (:mod:`szdyn.drive`).
    t_end : float
        End time in s.
    method : {"heun", "rk4", "dopri5"}
        Fixed-step Heun (the thesis's modified Euler) or RK4 with step ``dt`` (s), or adaptive
        Dormand-Prince 5(4) with tolerances ``rtol``/``atol``.
    save_dt : float
        Output sampling interval in s.
    x0 : ndarray, shape (2 N_c + 4,), optional
        Initial state; default ``params.initial_state()`` (rest, rollers between circles).
    progress : callable(float), optional
        Called with the completed fraction between compiled chunks.
    """
    mode = drive.drive_mode
    if mode == 0 and params["drive_mode"] == 2:
        mode = 2  # a speed profile prescribes the motor, which drives the wheel through a compliance
    params = params.replace(drive_mode=mode)
    p = params.to_array()
    x0 = params.initial_state() if x0 is None else np.asarray(x0, dtype=float)
    drive_arr = drive.to_array(angle0=float(x0[0]))
    traj = integrate(x0, p, drive_arr, t_end, method=method, dt=dt, save_dt=save_dt, rtol=rtol,
                     atol=atol, progress=progress, state_names=model.state_names(params.n_circles),
                     **integrate_kwargs)
    return Run(params, drive, traj, p, drive_arr)
