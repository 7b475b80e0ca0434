"""The diagnosis as data: ``diagnosis.json``'s dict, its units, and the updated parameter set.

Split from :mod:`.report` (which writes the files and the Markdown) so that the schema has one
home: :func:`to_json` is what a program reads, the report what a person reads.
"""
from __future__ import annotations

import math

import numpy as np

from .candidates import CANDIDATES, FIXED_UNIDENTIFIED, primary_std
from .data import FEATURE_DT, WINDOW_S

__all__ = ["COMPARED", "UNITS", "to_json", "updated_parameters"]

COMPARED = (f"smoothed band speed omega_b (Savitzky-Golay derivative of theta_b, degree 2, window "
            f"{WINDOW_S:g} s) every {FEATURE_DT:g} s, measured minus model, with the model driven by "
            f"the measured wheel speed (so equal to the smoothed relative speed omega_w - omega_b "
            f"up to the shared omega_w); slip per revolution and stroke integrate the same signal")


UNITS = {"rmse": "rad/s", "heldout_rmse": "rad/s", "noise_floor": "rad/s", "t0": "s", "t1": "s",
         "score (mismatch)": "segment RMS / noise floor (1)",
         "ratio (heldout_beyond_floor)": "held-out RMSE of the final model / noise floor (1)",
         "heldout_force_scale": "sigma: reported std of mu_k relative to mu_k (1); points: steps along the "
                                "force scale in sigma (1); factors: every force's factor (1); over_floor, "
                                "min, max: held-out RMSE / noise floor (1); at_factor: the factor of min (1)",
         "score (effect)": "share of the calibrated model's excess residual energy over the noise floor "
                           "that the effect explains (1; linearised for candidates not refitted)",
         "per_mu_k (effect primary)": "the effect parameter's own unit (mu_k is 1)",
         "weights": "common noise floor / the recording's own (1); when weighted, every fit and "
                    "held-out RMSE is of the weighted residual (rad/s at the common floor)",
         "motor_torque": "floor, heldout_rmse and per_recording in N m; torque_constant N m/A; weight "
                         "rad/s per N m (the speed floor over the torque floor): when used, every fit and "
                         "held-out RMSE counts the torque residual times it, in rad/s at the speed floor",
         "uncertainty": "step: half-width of the secant in log force scale (1); predicted, measured: RMS "
                        "change of the fit residual (the compared speed, and the weighted motor torque where "
                        "compared) for that step, by the fit's Jacobian and by model runs (rad/s, weighted as "
                        "the fit)",
         "std (effects)": "own units; calibrated_std, final.std and the selected effect's std come from the "
                          "Jacobian corrected along the force scale (see uncertainty), the other effects' "
                          "std are local (uncorrected)",
         "polish": "values: the named effect's parameters in the units listed with them; rmse_fit: the fit "
                   "recordings' RMSE before and after the phase-profiled steps (rad/s, weighted as the fit)",
         "scale_profile": "factors: every force's factor at each start (1); rmse_fit, rmse_before: the fit "
                          "recordings' RMSE of each start's fit and of the fit before (rad/s, weighted as the "
                          "fit; null: skipped); chosen: the factor whose fit was taken (null: none); "
                          "before/after: values (units listed with them), force (mu_k after over before, 1), "
                          "rmse_fit (rad/s)",
         "values (effect)": "the refit's base coefficients (units as calibrated) and the candidate's fit "
                            "parameters (as fit_coordinates)",
         "kept_over (effect)": "later fits of the candidate that fitted better but held out rival_heldout "
                               "times worse, both within rival_floor noise floors: fit (which one), "
                               "rmse_fit and heldout_rmse (rad/s, weighted as the fit)",
         "k_c": "N*m/rad", "b_c": "N*m*s/rad", "k_imp": "N/m^n", "b_imp": "N*s/m^(n+1)", "mu_s": "1", "mu_k": "1"}


def _f(x, fmt=".4g"):
    return "nan" if x is None or (isinstance(x, float) and not math.isfinite(x)) else format(x, fmt)


def updated_parameters(d):
    """The updated :class:`~szdyn.params.ParameterSet` (defaults + manifest + calibration + effect).

    The recording-specific load ``m_b`` is that of the first fit recording's defaults (the
    parameter file describes the machine; set ``m_b`` per run).
    """
    from ..defaults import default_parameters

    rec0 = d.recordings_[0]
    base = default_parameters(rec0.params.n_circles)
    # manifest [model] overrides other than the load
    over = {k: rec0.params[k] for k in rec0.params.values if rec0.params[k] != base[k] and k != "m_b"}
    mc, _ = d.final_.hypothesis.point(d.final_.x)
    return base.replace(**{**over, **mc})


def _clean(x):
    """JSON-ready copy: numpy scalars/arrays to Python, NaN/inf to None (JSON has neither)."""
    if isinstance(x, dict):
        return {str(k): _clean(v) for k, v in x.items()}
    if isinstance(x, (list, tuple)):
        return [_clean(v) for v in x]
    if isinstance(x, np.ndarray):
        return _clean(x.tolist())
    if isinstance(x, (bool, np.bool_)):
        return bool(x)
    if isinstance(x, (int, np.integer)):
        return int(x)
    if isinstance(x, (float, np.floating)):
        return float(x) if math.isfinite(x) else None
    return x


def _status(res) -> str:
    """How a nonlinear fit ended, for the reader (converged or stopped by its budget)."""
    ex = res.extra
    parts = []
    if ex.get("start"):
        parts.append(f"started from the {ex['start']}")
    if ex.get("restart"):
        parts.append(f"restarted from {ex['restart']}")
    if ex.get("ablation_of"):
        parts.append(f"refitted from {ex['ablation_of']}'s coefficients (ablation)")
    if ex.get("continued"):
        parts.append("continued once")
    if ex.get("unstalled"):
        # which step (the full one or the candidate's own) each restart started from
        steps = f"; {', then '.join(ex['unstall_steps'])}" if ex.get("unstall_steps") else ""
        parts.append(f"restarted {ex['unstalled']}x from its linear step (a stall{steps})")
    if ex.get("scale_factor"):
        parts.append(f"started again with every force x{ex['scale_factor']:g} (force-scale profile)")
    if ex.get("phase_steps"):
        parts.append(f"{ex['phase_steps']} phase-profiled step(s) ({ex.get('phase_flag', '--phase-steps')})")
    if ex.get("kept_over"):
        # the held-out recordings chose between fits the fit could not part: not an independent check
        later = ", ".join(f"{k['fit']} (fit {_f(k['rmse_fit'])}, held-out {_f(k['heldout_rmse'])} rad/s)"
                          for k in ex["kept_over"])
        parts.append("kept over later fits that fitted better but held out worse (by the close rivals' test), "
                     "the held-out recordings choosing: " + later)
    if ex.get("settled_by"):
        parts.append(f"no further starts ({ex['settled_by']} already explained the mismatch)")
    how = "stopped by its budget" if res.budget_hit else "converged"
    return f"{how} after {ex['njac']} Jacobians" + "".join(", " + p for p in parts)


def to_json(d) -> dict:
    """The diagnosis as a JSON-ready dict (NaN, e.g. no held-out recording, becomes null)."""
    return _clean(_to_json(d))


def _to_json(d) -> dict:
    cal = d.calibrated_
    b = cal.rmse_fit
    effects = []
    screened = {s["id"]: s for s in d.screening_}
    for cid, cand in CANDIDATES.items():
        if cid not in screened and cid not in d.refits_:
            continue
        s = screened.get(cid, {})
        lin = s.get("rmse_linear", math.nan)
        excess = max(b * b - d.floor_ ** 2, 1e-30)
        item = {"id": cid, "kind": cand.kind, "selected": cid in d.selected_,
                "expression": cand.expression, "explains": cand.explains,
                "screen_rmse": lin, "refitted": cid in d.refits_,
                "nominated": cid in d.nominated_["ids"], "detectable": s.get("detectable", [])}
        if cid in d.refits_:
            r = d.refits_[cid]
            res = r["result"]
            cv = res.hypothesis.candidate_values(res.x)
            mc, sc = cand.apply(cv)
            item.update({"score": r["explained"], "parameters": {**mc, **sc},
                         "fit_coordinates": cv,
                         # the refit's whole point (base coefficients too), so that it can be run
                         # again: the candidate's own parameters alone leave its base unknown
                         "values": dict(res.values),
                         "std": {k: res.std.get(k, math.nan) for k in cv},
                         "primary": {"name": cand.primary, "value": cand.primary_of(cv),
                                     "std": primary_std(cand, cv, res.std,
                                                        res.corr[res.hypothesis.n_base:, res.hypothesis.n_base:])},
                         "fit_rmse": res.rmse_fit, "heldout_rmse": r["heldout_rmse"],
                         "phase_steps": res.extra.get("phase_steps", 0),
                         "kept_over": res.extra.get("kept_over", []),
                         "dbic": r["dbic"], "heldout_gain": r["heldout_gain"], "eligible": r["eligible"],
                         "explains_mismatch": d.rule.explains_mismatch(
                             res.rmse_fit, d.floor_, h0=d.heldout_["before"]["heldout_rmse"], hc=r["heldout_rmse"]),
                         "fit_status": _status(res)})
            if cand.force_scaled:
                # what speed recordings determine (see Candidate.force_scaled)
                item["primary"]["per_mu_k"] = item["primary"]["value"] / res.values["mu_k"]
        else:
            item.update({"score": float(np.clip((b * b - lin * lin) / excess, 0, 1)) if d.mismatch_ else 0.0,
                         "parameters": {}})
        effects.append(item)
    effects.sort(key=lambda e: -e["score"])
    mism = [{"recording": s["recording"], "t0": s["t0"], "t1": s["t1"], "regime": s["regime"],
             "kind": s["kind"], "score": s["score"]} for s in d.location_["mismatch"]] if d.mismatch_ else []
    fin = d.final_
    sensor = {}
    if fin.hypothesis.candidate is not None:
        _, sensor = fin.hypothesis.point(fin.x)
    return {
        "selected": list(d.selected_),
        "verdict": d.verdict_,
        "indistinguishable": list(d.indistinguishable_),
        "passed_over": d.passed_over_,
        "partial": [{"id": k, "explained": d.refits_[k]["explained"],
                     "fit_rmse_over_floor": d.refits_[k]["result"].rmse_fit / d.floor_} for k in d.partial_],
        "effects": effects,
        "mismatch": mism,
        "calibrated": {k: cal.values[k] for k in ("k_c", "b_c", "k_imp", "mu_s", "mu_k")},
        "calibrated_std": {k: cal.std.get(k, math.nan) for k in ("k_c", "b_c", "k_imp", "mu_s", "mu_k")},
        "calibration_status": _status(cal),
        "staged_calibration": d.staged_,
        "ablation": d.ablation_,
        "restart": d.restart_,
        "second_look": d.second_look_,
        "heavy_look": d.heavy_look_,
        "polish": d.polish_,
        "scale_profile": d.scale_profile_,
        "not_identified": {k: d.recordings_[0].params[k] for k in FIXED_UNIDENTIFIED},
        "final": {"values": fin.values, "std": fin.std, "sensor": sensor},
        "uncertainty": {"calibrated": cal.extra.get("force_scale"), "final": fin.extra.get("force_scale")},
        "fit": {"before": {"heldout_rmse": d.heldout_["before"]["heldout_rmse"],
                           "fit_rmse": cal.rmse_fit,
                           "per_recording": d.heldout_["before"]["per_recording"]},
                "after": {"heldout_rmse": d.heldout_["after"]["heldout_rmse"],
                          "fit_rmse": fin.rmse_fit,
                          "per_recording": d.heldout_["after"]["per_recording"]}},
        "heldout_beyond_floor": [{"recording": k, "ratio": v} for k, v in d.heldout_beyond_floor_.items()],
        "heldout_force_scale": d.heldout_scale_,
        "split": {"heldout": [r.name for r in d.recordings_ if r.role != "fit"], "first": d.first_split_,
                  "unused": d.unused_split_, "hidden": d.hidden_conditions_},
        "wheel_phase": {**d.phase_, "recordings": d.phases_},
        "noise_floor": d.floor_, "noise_floor_parts": d.floor_parts_,
        "noise_floor_per_recording": d.floor_per_recording_,
        "weights": d.weights_,
        "weighting": d.weighting_,
        "motor_torque": d.torque_,
        "mismatch_significant": bool(d.mismatch_),
        "rule": d.rule.__dict__,
        "location": {"recordings": d.location_["recordings"], "follows": d.location_["follows"]},
        "nominated": d.nominated_,
        "rivals": list(d.rivals_),
        "probing": d.probing_,
        "not_refitted": d.not_refitted_,
        "sensor_not_settling": d.sensor_not_settling_,
        "recordings": [{"name": r.name, "role": r.role, "load_kg": r.load_kg,
                        "t0": r.t0, "t1": r.t1, "samples": len(r.rec)} for r in d.recordings_],
        "compared": COMPARED,
        "units": UNITS,
        # recordings on which the final model's own run failed (its band speed taken as zero)
        "final_failed_on": list(getattr(d, "final_failed_", [])),
        "cost": {"seconds": d.timings_, "model_runs": d.n_runs_, "failed_runs": d.n_failed_,
                 # runs loaded from a checkpoint of an earlier run, interrupted or kept (not in
                 # model_runs or seconds)
                 "resumed_runs": d.resumed_runs_},
    }
