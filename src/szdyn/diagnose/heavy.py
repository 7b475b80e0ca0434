"""The heaviest load alone: a last look before "unexplained".

The light-load recordings of szdyn's synthetic grid (0.5 kg against 1 kg) ride the impact regime:
as the coefficients move they flip between tracking and slipping, and their impact bumps move
with the wheel's phase, so their fit cost is a plateau cut by cliffs around a basin narrower than
the coefficients' own uncertainty (docs/DIAGNOSIS-DESIGN.md, "The truth's narrow basin"). The
heavier load's recordings are smooth in the coefficients. Where every recording together leaves
the mismatch unexplained, the diagnosis is run once more on the heaviest load's recordings only
(their own fit and held-out roles), and an effect named there that fits them within
``rule.rival_floor`` noise floors is the answer, with what it does on the other recordings
reported beside it (:func:`other_loads`).

Measured (docs/DIAGNOSIS-DESIGN.md, "The heaviest load alone"): friction_drift seed 24, which
every recording together left unexplained (the truth, each recording at its own wheel phase, fits
the four fit recordings at 0.0058 rad/s; the diagnosis ended at 0.043): the two 1 kg fit
recordings alone gave k_drift 0.5 % off the truth and the 1 kg held-out recording 0.0339 -> 0.0054
rad/s.
"""
from __future__ import annotations

import math

from .engine import FeatureModel, rms
from .phase import estimate_phases, identified_phases

__all__ = ["heaviest_load", "other_loads"]


def heaviest_load(recs):
    """The heaviest load and its recordings, if a look at them alone can be judged.

    Parameters
    ----------
    recs : list of Prepared
        The recordings with the roles of the answering pass.

    Returns
    -------
    (float, list of Prepared) or (None, str)
        The load (kg) and its recordings (roles kept); or None and why the look cannot run:
        fewer than two loads, a load unknown, or no fit or no held-out recording at the
        heaviest load (a held-out recording must judge what the look names).
    """
    loads = [r.load_kg for r in recs]
    if not all(isinstance(m, (int, float)) and math.isfinite(m) for m in loads):
        return None, "a recording's load is unknown"
    if len(set(loads)) < 2:
        return None, "the recordings have fewer than two loads"
    heavy = max(loads)
    sub = [r for r in recs if r.load_kg == heavy]
    if not any(r.role == "fit" for r in sub):
        return None, f"no fit recording at {heavy:g} kg"
    if all(r.role == "fit" for r in sub):
        return None, f"no held-out recording at {heavy:g} kg to judge it"
    return heavy, sub


def other_loads(recs, points: dict, *, floor: float, cache: dict, workers=None, progress=None,
                on_runs=None, phases: bool = True) -> tuple:
    """How models fitted on the heaviest load reproduce the other recordings.

    Each model runs every recording of ``recs`` from its best wheel phase (estimated at that
    model, :func:`.phase.estimate_phases`; the default offset where not identified, or with
    ``phases`` False).

    Parameters
    ----------
    recs : list of Prepared
        The recordings the look left out.
    points : dict of str -> (dict, dict)
        Model name -> hypothesis point ``(model changes, sensor changes)``.
    floor : float
        Noise floor the ratios are taken to (rad/s).
    cache : dict
        The diagnosis's shared run cache (keys are recording names).
    workers, progress, on_runs :
        As for :class:`.engine.FeatureModel`.
    phases : bool
        Estimate each model's wheel phases (True) or run every recording from the default offset
        (False: as the look's own pass did when it estimated none, with ``--no-phase`` or its
        base beyond the phase gate).

    Returns
    -------
    per_recording : dict
        Recording name -> ``{"role", "load_kg", <model name>: RMSE (rad/s), <model name>_over_floor}``.
    n_runs, n_failed : int
        Model runs made (not found in ``cache``) and of them failed.
    """
    out = {r.name: {"role": r.role, "load_kg": r.load_kg} for r in recs}
    idx = list(range(len(recs)))
    with FeatureModel(recs, workers=workers, progress=progress, cache=cache, on_runs=on_runs) as model:
        for name, pt in points.items():
            # (the scan sets each run's q_w0 itself: the phases of the previous model do not enter)
            model.phases = identified_phases(estimate_phases(model, pt, idx)) if phases else {}
            for i in idx:
                e = rms(model.residuals([pt], [i])[0])
                out[recs[i].name][name] = e
                out[recs[i].name][f"{name}_over_floor"] = e / floor if floor > 0 else math.inf
        return out, model.n_runs_, model.n_failed_
