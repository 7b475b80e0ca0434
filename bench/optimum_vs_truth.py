"""Where a diagnosis ended against where the truth is: fit cost at both and on the line between.

Usage::

    python bench/optimum_vs_truth.py CASE_DIR [CASE_DIR ...]

``CASE_DIR`` is a case of ``bench/diagnosis_grid.py`` (``data/`` with ``truth.json``,
``diagnosis/diagnosis.json``) whose verdict names an effect. Prints the RMSE of the compared
band speed (rad/s) of the selected effect's final model and of the truth (its perturbed
coefficients and effect parameters; b_imp, which is not fitted, at the truth's and at the
default), on the fit recordings, on the straight line between the two in fit coordinates (a
quarter, half, three quarters), and per recording. A truth that fits the fit recordings better
is a stalled fit; a barrier on the line with both ends alike is two valleys the fit recordings
cannot tell apart (docs/DIAGNOSIS-DESIGN.md, "Splits that keep every load and direction").
This reads the answer: it is an analysis tool, never part of a diagnosis.
"""
from __future__ import annotations

import json
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT / "src"))

from szdyn.diagnose.candidates import CANDIDATES  # noqa: E402
from szdyn.diagnose.data import prepare  # noqa: E402
from szdyn.diagnose.engine import FeatureModel, rms  # noqa: E402
from szdyn.diagnose.fit import Hypothesis  # noqa: E402
from szdyn.manifest import read_manifest  # noqa: E402

BASE = ("k_c", "b_c", "k_imp", "mu_s", "mu_k")


def compare(case: Path) -> dict:
    d = json.loads((case / "diagnosis" / "diagnosis.json").read_text())
    truth = json.loads((case / "data" / "truth.json").read_text())
    if not d["selected"]:
        raise SystemExit(f"{case}: the diagnosis named no effect ({d['verdict']})")
    recs = prepare(read_manifest(case / "data" / "manifest.toml"))
    hyp = Hypothesis({k: recs[0].params[k] for k in BASE}, CANDIDATES[d["selected"][0]])
    final = d["final"]["values"]
    tv = {k: v["value"] for k, v in truth["perturbed"].items()}
    eff = {**truth.get("effect_parameters", {}), **truth.get("effect_sensor", {})}
    at_truth = {**{k: tv[k] for k in BASE},
                **{p.name: eff.get(p.name, final[p.name]) for p in hyp.candidate.params}}
    x0, x1 = hyp.coordinates(final), hyp.coordinates(at_truth)
    mc, sc = hyp.point(x1)
    points = {"final": hyp.point(x0), "truth": (mc, sc), "truth, its b_imp": ({**mc, "b_imp": tv["b_imp"]}, sc)}
    points.update({f"line {a:g}": hyp.point(x0 + a * (x1 - x0)) for a in (0.25, 0.5, 0.75)})
    fit_idx = [i for i, r in enumerate(recs) if r.role == "fit"]
    with FeatureModel(recs, workers=2) as model:
        on_fit = dict(zip(points, (rms(r) for r in model.residuals(list(points.values()), fit_idx))))
        per = {recs[i].name: {"role": recs[i].role,
                              **{k: rms(model.residuals([points[k]], [i])[0]) for k in ("final", "truth")}}
               for i in range(len(recs))}
        every = {k: rms(model.residuals([points[k]], list(range(len(recs))))[0]) for k in ("final", "truth")}
    return {"case": case.name, "noise_floor": d["noise_floor"], "fit_recordings": on_fit,
            "all_recordings": every, "per_recording": per}


if __name__ == "__main__":   # the model runs use worker processes
    for arg in sys.argv[1:]:
        print(json.dumps(compare(Path(arg)), indent=1))
