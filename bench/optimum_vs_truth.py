"""Where a diagnosis ended against where the truth is: fit cost at both and on the line between.

Usage::

    python bench/optimum_vs_truth.py CASE_DIR [CASE_DIR ...]

``CASE_DIR`` is a case of ``bench/diagnosis_grid.py`` (``data/`` with ``truth.json``,
``diagnosis/diagnosis.json``). The hypothesis compared is the selected effect's; for a case
that named none, the concealed effect's (the calibrated base, its effect off, against the
truth), or the base model alone for a null case. Prints the RMSE of the compared band speed
(rad/s) of the diagnosis's final model and of the truth (its perturbed coefficients and effect
parameters; b_imp, which is not fitted, at the truth's and at the default) on the fit
recordings (the diagnosis's own split, ``split.heldout`` in diagnosis.json, not the manifest's
roles), on the straight line between the two in fit coordinates (a quarter, half, three
quarters), and per recording, three ways:

* ``default_phase``: every run from the default wheel offset;
* ``diagnosis_phases``: the fit recordings' wheel phases the diagnosis estimated at the
  calibrated base (where it did; ``wheel_phase`` in diagnosis.json);
* ``own_phases``: each point with the phases estimated at itself (:mod:`szdyn.diagnose.phase`).

For a case that named a wrong effect, one more point, ``truth, its effect``: the truth with its
concealed effect (in that effect's own hypothesis; the points above are in the named one, where
the concealed effect has no term). Off the line, which stays in the named hypothesis. A truth
that fits the fit recordings better with its effect than the named answer does is a fit that
stopped short of the right name; one that fits worse is recordings that favour the wrong name.
Where the diagnosis refitted the concealed effect, its refit too (``its effect, refitted`` for a
wrong name, ``its refit`` for a case that named none; from ``values`` in diagnosis.json, which
older files lack): a refit that fits worse than the truth in the same hypothesis stopped short.

A truth that fits the fit recordings better is a stalled fit; a barrier on the line with both
ends alike is two valleys the fit recordings cannot tell apart (docs/DIAGNOSIS-DESIGN.md,
"Splits that keep every load and direction"); a truth that fits well only with its own phases
is a valley the diagnosis's phases hide (docs/DIAGNOSIS-DESIGN.md, "The truth's narrow basin").
This reads the answer: it is an analysis tool, never part of a diagnosis.

``--scale F1,F2,...`` adds the final model with every force scaled together by each factor
(``final xF``: every parameter times F to its ``force_power``, k_imp included; a sensor term
stays), measured the same three ways: whether the truth's valley lies along the force scale from where
the diagnosis ended (on null 89 it did not: docs/DIAGNOSIS-DESIGN.md, "Null 89's unexplained,
traced").
"""
from __future__ import annotations

import argparse
import json
import math
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT / "src"))

from szdyn.diagnose.candidates import CANDIDATES  # noqa: E402
from szdyn.diagnose.data import prepare  # noqa: E402
from szdyn.diagnose.engine import FeatureModel, rms  # noqa: E402
from szdyn.diagnose.fit import Hypothesis  # noqa: E402
from szdyn.diagnose.phase import estimate_phases, identified_phases  # noqa: E402
from szdyn.diagnose.split import with_heldout  # noqa: E402
from szdyn.manifest import read_manifest  # noqa: E402

BASE = ("k_c", "b_c", "k_imp", "mu_s", "mu_k")
LINE = (0.25, 0.5, 0.75)
#: the points also measured on each recording (the line's points only on the fit recordings)
PER_RECORDING = ("final", "truth", "truth, its effect", "its refit", "its effect, refitted")


def truth_coordinates(effect: str, truth: dict) -> dict:
    """The concealed effect's values in the candidate's own fit parameters (truth.json names the
    model's parameters; some candidates are fitted in other coordinates)."""
    src = {**truth.get("effect_parameters", {}), **truth.get("effect_sensor", {})}
    if effect == "drive_compliance":
        return {"drive_compliance": 1.0 / src["k_drive"]}
    if effect == "position_periodic":
        a, phi = src["a_rev"], src["phi_rev"]
        return {"a_rev_s": a * math.cos(phi), "a_rev_c": a * math.sin(phi)}
    if effect == "encoder_scale":
        return {"encoder_scale": src["encoder_scale_b"] - 1.0}
    if effect == "encoder_delay":
        return {"encoder_delay": src["encoder_delay_b"]}
    return {p.name: src[p.name] for p in CANDIDATES[effect].params}


def diagnosis_roles(recs, d: dict):
    """``recs`` with the roles of the diagnosis's final split (``split.heldout`` in
    diagnosis.json), fit recordings first.

    The manifest's roles are not the split: the cost configuration's manifest has none (every
    recording ``fit``; the diagnosis chooses which to hold out), and a diagnosis may exchange
    a generator's split. Comparing with the diagnosis's ``fit_rmse`` needs its own fit
    recordings. A diagnosis.json without ``split`` keeps the manifest's roles.
    """
    held = (d.get("split") or {}).get("heldout")
    if held is None:
        return list(recs)
    names = {r.name for r in recs}
    unknown = sorted(set(held) - names)
    if unknown:
        raise ValueError(f"diagnosis.json holds out {unknown}, which the manifest does not list "
                         f"(it lists {sorted(names)})")
    return with_heldout(recs, held)


def scaled_points(hyp: Hypothesis, x, factors) -> dict:
    """``{"final xF": point}``: the point ``x`` (fit coordinates of ``hyp``) with every force
    scaled by each factor ``F`` (> 0), exactly: each parameter by ``F`` to its
    :attr:`~szdyn.diagnose.candidates.FitParam.force_power` (the direction of
    :func:`szdyn.diagnose.force_scale.force_scale_direction`, whose linear coordinates it only
    follows to first order)."""
    out = {}
    for f in factors:
        if not (math.isfinite(f) and f > 0.0):
            raise ValueError(f"--scale: every factor must be a finite number > 0, got {f!r}")
        z = [xj + p.force_power * math.log(f) if p.log else xj * f ** p.force_power
             for p, xj in zip(hyp.params, x)]
        out[f"final x{f:g}"] = hyp.point(hyp.inside(z))
    return out


def points_of(d: dict, truth: dict, recs, scale=()) -> tuple:
    """The points compared: ``(hypothesis name, {label: (model_changes, sensor_changes)})``.

    ``d`` is diagnosis.json, ``truth`` truth.json, ``recs`` the prepared recordings (their
    nominal base parameters start the hypotheses). The hypothesis is the selected effect's; for
    a case that named none, the concealed effect's, or the base model for a null case.
    """
    effect = d["selected"][0] if d["selected"] else (None if truth["effect"] == "none" else truth["effect"])
    start = {k: recs[0].params[k] for k in BASE}
    hyp = Hypothesis(start, CANDIDATES[effect]) if effect else Hypothesis(start)
    # the final model; a candidate not selected is off in it (its amplitude 0)
    final = {**{p.name: 0.0 for p in (hyp.candidate.params if effect else ())}, **d["final"]["values"]}
    tv = {k: v["value"] for k, v in truth["perturbed"].items()}
    eff = truth_coordinates(effect, truth) if effect == truth["effect"] else {}
    at_truth = {**{k: tv[k] for k in BASE},
                **{p.name: eff.get(p.name, final[p.name]) for p in (hyp.candidate.params if effect else ())}}
    x0, x1 = hyp.coordinates(final), hyp.coordinates(at_truth)
    mc, sc = hyp.point(x1)
    points = {"final": hyp.point(x0), "truth": (mc, sc), "truth, its b_imp": ({**mc, "b_imp": tv["b_imp"]}, sc)}
    points.update({f"line {a:g}": hyp.point(x0 + a * (x1 - x0)) for a in LINE})
    points.update(scaled_points(hyp, x0, scale))
    if truth["effect"] not in ("none", effect):
        # a wrong name: "truth" above is the truth's base with the named effect's final
        # amplitude; the concealed effect has no term in the named hypothesis
        own = Hypothesis(start, CANDIDATES[truth["effect"]])
        points["truth, its effect"] = own.point(own.coordinates(
            {**{k: tv[k] for k in BASE}, **truth_coordinates(truth["effect"], truth)}))
        refit = refit_values(d, truth["effect"])
        if refit is not None:
            points["its effect, refitted"] = own.point(own.coordinates(refit))
    elif effect and not d["selected"]:
        # nothing named: the diagnosis's own refit of the concealed effect, where it made one
        refit = refit_values(d, effect)
        if refit is not None:
            points["its refit"] = hyp.point(hyp.coordinates(refit))
    return effect or "base", points


def refit_values(d: dict, effect: str) -> dict | None:
    """The diagnosis's refit of ``effect`` (base coefficients and the candidate's fit
    parameters, ``values`` of its entry in diagnosis.json), or None where it made none (or the
    file is older than that entry)."""
    e = next((x for x in d.get("effects", []) if x["id"] == effect), None)
    return e.get("values") if e is not None and e.get("refitted") else None


def compare(case: Path, scale=()) -> dict:
    d = json.loads((case / "diagnosis" / "diagnosis.json").read_text())
    truth = json.loads((case / "data" / "truth.json").read_text())
    recs = diagnosis_roles(prepare(read_manifest(case / "data" / "manifest.toml")), d)
    hypothesis, points = points_of(d, truth, recs, scale)
    fit_idx = [i for i, r in enumerate(recs) if r.role == "fit"]
    all_idx = list(range(len(recs)))
    diag_ph = {i: e["q_w0"] for i in all_idx
               for e in [d.get("wheel_phase", {}).get("recordings", {}).get(recs[i].name)]
               if e and e.get("identified")}
    out = {"case": case.name, "hypothesis": hypothesis, "verdict": d["verdict"],
           "noise_floor": d["noise_floor"]}
    with FeatureModel(recs, workers=2) as model:
        def measure(phases_of):
            """RMSEs of every point on the fit recordings, and per recording for the final model,
            the truth and the points off the line (PER_RECORDING)."""
            on_fit, per = {}, {recs[i].name: {"role": recs[i].role} for i in all_idx}
            for k, pt in points.items():
                model.phases = phases_of(pt)
                on_fit[k] = rms(model.residuals([pt], fit_idx)[0])
                if k in PER_RECORDING:
                    for i in all_idx:
                        per[recs[i].name][k] = rms(model.residuals([pt], [i])[0])
            return {"fit_recordings": on_fit, "per_recording": per}

        def own(pt):
            model.phases = {}
            return identified_phases(estimate_phases(model, pt, all_idx))

        out["default_phase"] = measure(lambda pt: {})
        if diag_ph:
            out["diagnosis_phases"] = measure(lambda pt: diag_ph)
        out["own_phases"] = measure(own)
    return out


def parse_scale(text: str) -> tuple:
    """``"0.9,1.1"`` -> ``(0.9, 1.1)``; a clear error for anything else."""
    try:
        out = tuple(float(v) for v in text.split(","))
    except ValueError:
        raise argparse.ArgumentTypeError(f"expected comma-separated numbers > 0 (e.g. 0.9,0.95), got {text!r}")
    if any(not (math.isfinite(f) and f > 0.0) for f in out):
        raise argparse.ArgumentTypeError(f"every factor must be a finite number > 0, got {text!r}")
    return out


if __name__ == "__main__":   # the model runs use worker processes
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("cases", nargs="+", type=Path, help="case directories of bench/diagnosis_grid.py")
    ap.add_argument("--scale", type=parse_scale, default=(),
                    help="also the final model with every force scaled by these factors (comma-separated)")
    args = ap.parse_args()
    for case in args.cases:
        print(json.dumps(compare(case, args.scale), indent=1))
