"""Summary metrics of one simulation run, for parameter sweeps.

A metric reduces one output time series of :func:`szdyn.simulate.simulate` (``of``), optionally
divided by a second one (``over``), over a time window ``[t_from, t_to]`` (s, inclusive; default
the whole run) to one number. The window ends may be numbers or the name of a case setting
(``"t_end"`` or ``"drive.<arg>"``, e.g. ``"drive.t_ramp"`` for "from the end of the ramp"), so
a window can follow a swept drive setting.

Kinds (``unit`` is the unit of ``of``; ratios have unit ``unit(of)/unit(over)``):

=================  ===============================================================
``mean``           time average of the samples in the window (samples are equally spaced)
``mean_abs``       mean of ``|of|``
``rms``            root mean square
``std``            standard deviation
``min``/``max``    extreme sample
``max_abs``        largest ``|of|``
``final``          last sample in the window
``delta``          last minus first sample in the window
``ratio_of_means`` ``mean(of) / mean(over)`` (e.g. band/wheel speed ratio)
``final_ratio``    ``of / over`` at the last sample (e.g. stroke lost per metre of stroke)
=================  ===============================================================

A metric that is undefined for a case (empty window, zero denominator) is ``None`` (an empty
cell in the table), never NaN.
"""
from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

__all__ = ["KINDS", "RATIO_KINDS", "Metric", "DEFAULT_METRICS", "evaluate_metrics",
           "metric_unit"]

KINDS = ("mean", "mean_abs", "rms", "std", "min", "max", "max_abs", "final", "delta",
         "ratio_of_means", "final_ratio")
RATIO_KINDS = ("ratio_of_means", "final_ratio")


@dataclass(frozen=True)
class Metric:
    """One summary metric (see the module docstring).

    ``t_from``/``t_to`` are a float (s), a case-setting name (str) or None (start/end of run).
    """

    name: str
    kind: str
    of: str
    over: str | None = None
    t_from: float | str | None = None
    t_to: float | str | None = None
    description: str = ""

    def to_dict(self) -> dict:
        return {"name": self.name, "kind": self.kind, "of": self.of, "over": self.over,
                "t_from": self.t_from, "t_to": self.t_to, "description": self.description}

    @classmethod
    def from_dict(cls, d) -> "Metric":
        return cls(**d)


#: Used when a sweep spec has no ``[metrics]`` table.
DEFAULT_METRICS = (
    Metric("mean_rel_speed", "mean", "rel_speed",
           description="mean wheel-band relative (slip) speed over the run"),
    Metric("speed_ratio", "ratio_of_means", "u_b", "u_w",
           description="mean band speed / mean wheel speed over the run"),
    Metric("stroke_lost_end", "final", "stroke_lost",
           description="stroke lost to slip at the end of the run"),
    Metric("stroke_lost_per_stroke", "final_ratio", "stroke_lost", "stroke",
           description="stroke lost per metre of extension at the end of the run"),
    Metric("max_contacts", "max", "contacts",
           description="largest number of roller-circle contacts"),
    Metric("mean_contact_torque", "mean", "wheel_reaction_torque",
           description="mean contact torque on the wheel"),
    Metric("max_abs_wheel_torque", "max_abs", "wheel_reaction_torque",
           description="largest |contact torque on the wheel|"),
)


def metric_unit(metric: Metric, units: dict) -> str:
    """Unit string of ``metric`` given the output units (``szdyn.simulate.OUTPUT_UNITS``)."""
    u = units.get(metric.of, "")
    if metric.kind not in RATIO_KINDS:
        return u
    v = units.get(metric.over, "")
    if u == v:
        return "1"
    if v == "1":
        return u
    return f"{u}/({v})" if "/" in v or "*" in v else f"{u}/{v}"


def _resolve_time(value, settings: dict, default: float) -> float:
    if value is None:
        return default
    if isinstance(value, str):
        return float(settings[value])
    return float(value)


def _finite_or_none(v) -> float | None:
    v = float(v)
    return v if math.isfinite(v) else None


def evaluate_metrics(metrics, outputs: dict, settings: dict) -> dict:
    """Evaluate ``metrics`` on one run's ``outputs``.

    Parameters
    ----------
    metrics : sequence of Metric
    outputs : dict of str -> ndarray, shape (n,)
        ``Run.outputs`` (must contain ``t``).
    settings : dict
        Case settings that window ends may name (``t_end``, ``drive.<arg>``), numbers.

    Returns
    -------
    dict of str -> float or None
        Metric name -> value (None where undefined).
    """
    t = np.asarray(outputs["t"], dtype=float)
    t_last = float(t[-1]) if t.size else 0.0
    eps = 1e-9 * max(1.0, abs(t_last))
    out = {}
    for m in metrics:
        t0 = _resolve_time(m.t_from, settings, -math.inf)
        t1 = _resolve_time(m.t_to, settings, math.inf)
        sel = (t >= t0 - eps) & (t <= t1 + eps)
        if not np.any(sel):
            out[m.name] = None
            continue
        y = np.asarray(outputs[m.of], dtype=float)[sel]
        with np.errstate(divide="ignore", invalid="ignore"):
            if m.kind == "mean":
                v = y.mean()
            elif m.kind == "mean_abs":
                v = np.abs(y).mean()
            elif m.kind == "rms":
                v = math.sqrt(float(np.mean(y * y)))
            elif m.kind == "std":
                v = y.std()
            elif m.kind == "min":
                v = y.min()
            elif m.kind == "max":
                v = y.max()
            elif m.kind == "max_abs":
                v = np.abs(y).max()
            elif m.kind == "final":
                v = y[-1]
            elif m.kind == "delta":
                v = y[-1] - y[0]
            elif m.kind in RATIO_KINDS:
                z = np.asarray(outputs[m.over], dtype=float)[sel]
                num, den = (y.mean(), z.mean()) if m.kind == "ratio_of_means" else (y[-1], z[-1])
                v = num / den if den != 0.0 else math.nan
            else:  # validated when the spec is read
                raise ValueError(f"unknown metric kind {m.kind!r}")
        out[m.name] = _finite_or_none(v)
    return out
