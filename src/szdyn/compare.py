"""Simulate the model against a recording, and compare the two (building block of issue 5).

The model is driven by the recording's own measured wheel motion, so that the comparison is
about the band (the transmission), not about how well a speed loop was modelled. With
``drive_mode = 2`` in the parameters (the drive_compliance hypothesis) the measured angle is the
motor's and it prescribes the motor, coupled to the wheel through ``k_drive``, ``c_drive``.
"""
from __future__ import annotations

import numpy as np

from .drive import Sampled
from .params import ParameterSet
from .recordings import Recording, compare_features, features, speeds


def measured_drive(rec: Recording, window_s: float = 0.05) -> Sampled:
    """Wheel (or motor) speed profile of a recording: Savitzky-Golay speed of ``theta_w``.

    Parameters
    ----------
    rec : Recording
    window_s : float
        Differentiation window in s (see :func:`szdyn.recordings.speeds`).

    Returns
    -------
    Sampled
        Piecewise-linear speed in rad/s on the recording's uniform grid.
    """
    t, omega_w, _ = speeds(rec, window_s)
    return Sampled(t=t, omega=omega_w)


def simulate_against(rec: Recording, params: ParameterSet, *, method: str = "dopri5",
                     rtol: float = 1e-5, atol: float = 1e-8, dt: float = 1e-4, save_dt: float = 1e-3,
                     window_s: float = 0.05, q_w0: float | None = None) -> Recording:
    """The model's counterpart of ``rec``: same wheel motion, same time span, band from the model.

    Parameters
    ----------
    rec : Recording
        Measured recording; the band starts at rest at ``rec.t[0]``.
    params : ParameterSet
        Model parameters (load already applied, e.g. by ``Manifest.parameters``).
    method, rtol, atol, dt, save_dt :
        Integrator settings (:func:`szdyn.simulate.simulate`).
    window_s : float
        Window of the wheel-speed differentiation (s).
    q_w0 : float, optional
        Initial wheel angle (rad); default the model's default offset. A rig's wheel starts at
        an unknown phase to the circles, so the impact bumps cannot be matched sample by sample;
        a synthetic recording's ``truth.json`` records its phase.

    Returns
    -------
    Recording
        ``t`` (s) on a ``save_dt`` grid; ``theta_w`` the simulated wheel angle, or the motor angle
        with the compliant drive (what the encoder measures); ``theta_b`` the band angle; both
        relative to their initial values, as an encoder reads them.
    """
    from .simulate import simulate

    drive = measured_drive(rec, window_s)
    t0, t1 = float(drive.t[0]), float(drive.t[-1])
    run = simulate(params, drive, t1, t0=t0, method=method, rtol=rtol, atol=atol, dt=dt, save_dt=save_dt,
                   x0=params.initial_state(q_w0))
    o = run.outputs
    if run.params["drive_mode"] == 2:
        theta_w = drive.evaluate(o["t"])[0]  # the encoder is on the motor
    else:
        theta_w = o["q_w"]
    return Recording(name=f"{rec.name} (model)", t=o["t"], theta_w=theta_w - theta_w[0],
                     theta_b=o["q_b"] - o["q_b"][0], conditions=dict(rec.conditions),
                     meta={"simulated": True, "method": method})


def compare(rec: Recording, params: ParameterSet, *, window_s: float = 0.1, **sim_kw) -> dict:
    """Simulate against ``rec`` and compare the features that are reproducible despite the
    impact model's bumps (:func:`szdyn.recordings.compare_features`), on the same grid step.

    Returns
    -------
    dict
        ``{"metrics": compare_features(...), "measured": features, "model": features}``.
    """
    sim = simulate_against(rec, params, **sim_kw)
    pitch = params.geometry.pitch
    dt = float(np.median(np.diff(rec.t)))
    # one set of wheel-speed bins for both sides, from the measured wheel speed
    _, omega_w, _ = speeds(rec, window_s, dt=dt)
    bins = np.linspace(0.0, float(np.abs(omega_w).max()) * (1 + 1e-9), 11)
    measured = features(rec, pitch, window_s=window_s, dt=dt, speed_bins=bins)
    model = features(sim, pitch, window_s=window_s, dt=dt, speed_bins=bins)
    return {"metrics": compare_features(measured, model), "measured": measured, "model": model}
