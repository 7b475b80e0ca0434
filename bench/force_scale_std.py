"""The effect parameter's error in its reported standard deviation, with and without the force-scale
secant (szdyn.diagnose.force_scale), on finished grid cases.

Usage::

    python bench/force_scale_std.py CASE [CASE ...] [--json OUT.json]

A CASE is a grid work directory ``EFFECT-SEED`` (``bench/diagnosis_grid.py --work``) with
``data/`` (recordings, manifest, truth.json) and ``diagnosis/diagnosis.json``. For a case whose
concealed effect was named, the final model is rebuilt from diagnosis.json (its values, weights
and the wheel phases it was fitted with), its forward-difference Jacobian is taken again as the
fit took it, and the primary's standard deviation is computed from it (``local``: what the
diagnosis reported before the secant; where diagnosis.json predates the secant, the rebuild is
checked against its reported std, ``rebuilt``: within 1e-6 relative, else a warning; measured
1.4e-8 at most on 27 cases) and after :func:`~szdyn.diagnose.force_scale.force_scale_secant` (``secant``). Both are then
compared with the primary's actual error against the truth. A benchmark of the benchmark, not a
diagnosis: it reads truth.json. Results: docs/DIAGNOSIS-DESIGN.md, "The reported standard
deviations".
"""
from __future__ import annotations

import argparse
import json
import math
import sys
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT / "src"))
sys.path.insert(0, str(ROOT / "bench"))

from szdyn.io import write_json  # noqa: E402
from szdyn.manifest import read_manifest  # noqa: E402
from szdyn.diagnose.candidates import CANDIDATES, primary_std  # noqa: E402
from szdyn.diagnose.data import prepare  # noqa: E402
from szdyn.diagnose.engine import FeatureModel  # noqa: E402
from szdyn.diagnose.fit import FitResult, Hypothesis, _uncertainty, jacobian  # noqa: E402
from szdyn.diagnose.force_scale import force_scale_secant  # noqa: E402
from diagnosis_grid import truth_primary  # noqa: E402


def _primary_std(res: FitResult, cand) -> float:
    h = res.hypothesis
    cv = h.candidate_values(res.x)
    return primary_std(cand, cv, res.std, res.corr[h.n_base:, h.n_base:])


def case_std(case: Path) -> dict:
    """The named effect's error and its standard deviation before and after the secant."""
    d = json.loads((case / "diagnosis" / "diagnosis.json").read_text())
    truth = json.loads((case / "data" / "truth.json").read_text())
    effect = case.name.rsplit("-", 1)[0]
    out = {"case": case.name, "effect": effect, "selected": d["selected"]}
    if d["selected"] != [effect]:
        return out
    if (d.get("motor_torque") or {}).get("used"):
        # the fit's residual had the weighted torque too; this rebuild compares the speed only
        return {**out, "skipped": "the motor torque was compared (not rebuilt here)"}
    roles = {r["name"]: r["role"] for r in d["recordings"]}
    # the recordings of the pass that answered (the heavy look's: one load's only)
    recs = [r for r in prepare(read_manifest(case / "data" / "manifest.toml")) if r.name in roles]
    for r in recs:
        r.role = roles[r.name]
    recs.sort(key=lambda p: p.role != "fit")      # fit recordings first, as the diagnosis orders them
    idx = {r.name: i for i, r in enumerate(recs)}
    fit_idx = [i for i, r in enumerate(recs) if r.role == "fit"]
    cand = CANDIDATES[effect]
    eff = next(e for e in d["effects"] if e["id"] == effect)
    h = Hypothesis(d["final"]["values"], cand)     # started at the final values: base coordinates 0
    x = np.array([0.0] * h.n_base + [eff["fit_coordinates"][p.name] for p in cand.params])
    with FeatureModel(recs, workers=1) as m:
        if d["weighting"].get("weighted"):
            m.weights = {idx[k]: v for k, v in d["weights"].items()}
        m.phases = {idx[k]: v for k, v in (d["wheel_phase"].get("final_fit") or {}).items()}
        J, f = jacobian(m, h, x, fit_idx)
        rss = float(f @ f)
        std, corr = _uncertainty(h, x, J, rss, f.size)
        res = FitResult(hypothesis=h, x=x, values=h.values(x), std=std, corr=corr, rss_fit=rss, n_fit=f.size,
                        rmse_fit=math.sqrt(rss / f.size), nfev=0, J=J)
        sec = force_scale_secant(m, h, res, fit_idx)
    tv = truth_primary(truth, effect)
    err = abs(eff["primary"]["value"] - tv)
    local, after = _primary_std(res, cand), _primary_std(sec, cand)
    reported = eff["primary"].get("std")
    # a diagnosis.json without "uncertainty" reported the local std: the rebuild must reproduce it
    rebuilt = abs(local / reported - 1.0) <= 1e-6 if "uncertainty" not in d and reported else None
    out.update({"truth": tv, "fitted": eff["primary"]["value"], "error": err,
                "reported_std": reported, "local_std": local, "rebuilt": rebuilt, "secant_std": after,
                "z_local": err / local, "z_secant": err / after, "force_scale": sec.extra.get("force_scale")})
    return out


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("cases", type=Path, nargs="+")
    ap.add_argument("--json", type=Path, help="write the results here (a list, one entry per case)")
    args = ap.parse_args(argv)
    rows = []
    for case in args.cases:
        r = case_std(case)
        rows.append(r)
        if r.get("rebuilt") is False:
            print(f"{r['case']}: WARNING the rebuilt local std {r['local_std']:.6g} is not the reported "
                  f"{r['reported_std']:.6g}: the model was not rebuilt as the diagnosis fitted it", flush=True)
        if "z_local" in r:
            fs = r["force_scale"]
            print(f"{r['case']:26s} error in std: local {r['z_local']:7.2f}  secant {r['z_secant']:7.2f}  "
                  f"(change for 5 % of scale: Jacobian {fs['predicted']:.4f}, runs {fs['measured']:.4f} rad/s)",
                  flush=True)
        else:
            print(f"{r['case']:26s} " + r.get("skipped", f"not named (selected {r['selected']})"), flush=True)
        if args.json:
            write_json(args.json, rows)
    z0 = [r["z_local"] for r in rows if "z_local" in r]
    z1 = [r["z_secant"] for r in rows if "z_secant" in r]
    if z0:
        print(f"{len(z0)} named: within 2 std {sum(z <= 2 for z in z0)} -> {sum(z <= 2 for z in z1)}; "
              f"median error in std {np.median(z0):.2f} -> {np.median(z1):.2f}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
