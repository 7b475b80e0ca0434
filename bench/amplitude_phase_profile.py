"""One effect switched on at the calibrated (or the updated) base, with held and with profiled wheel phases.

Usage::

    python bench/amplitude_phase_profile.py CASE_DIR EFFECT PARAM V1,V2,... [--heldout NAME,...]
                                            [--at final]

``CASE_DIR`` holds ``data/manifest.toml`` and ``diagnosis/diagnosis.json`` (a case of
``bench/diagnosis_grid.py`` or ``bench/diagnosis_cost.py``). The diagnosis's calibrated base
coefficients (``--at final``: those of its updated model) are taken as they are, the
candidate ``EFFECT`` is switched on with its parameter ``PARAM`` at each value (its other
parameters 0), and the fit recordings (all but ``--heldout``) are run twice: from the default
wheel offset, and with each recording's wheel phase estimated at that point
(:func:`szdyn.diagnose.phase.estimate_phases`, the phases profiled out). Prints the fit RMSE of
the compared band speed over the diagnosis's noise floor, both ways.

Where the profile with its own phases falls below the base and the one with held phases does
not, the phases estimated at the base hide the effect (docs/DIAGNOSIS-DESIGN.md, "A drive
compliance the wheel phases hide"). An analysis tool: it never reads ``truth.json``.
"""
from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT / "src"))
sys.path.insert(0, str(ROOT / "bench"))

from optimum_vs_truth import BASE  # noqa: E402
from szdyn.diagnose.candidates import CANDIDATES  # noqa: E402
from szdyn.diagnose.data import prepare  # noqa: E402
from szdyn.diagnose.engine import FeatureModel, rms  # noqa: E402
from szdyn.diagnose.fit import Hypothesis  # noqa: E402
from szdyn.diagnose.phase import estimate_phases, identified_phases  # noqa: E402
from szdyn.manifest import read_manifest  # noqa: E402


def profile(case: Path, effect: str, param: str, values, heldout: str | None = None,
            at: str = "calibrated") -> list:
    """Rows ``{"value", "held_phases", "own_phases"}``: fit RMSE / noise floor at each value,
    the base coefficients the diagnosis's ``at`` ("calibrated" or "final") ones."""
    d = json.loads((case / "diagnosis" / "diagnosis.json").read_text())
    base = d["calibrated"] if at == "calibrated" else {k: d["final"]["values"][k] for k in BASE}
    recs = prepare(read_manifest(case / "data" / "manifest.toml"))
    left_out = set(heldout.split(",")) if heldout else set()
    fit_idx = [i for i, r in enumerate(recs) if r.name not in left_out]
    cand = CANDIDATES[effect]
    if param not in {p.name for p in cand.params}:
        raise SystemExit(f"{effect} has no parameter {param!r}; it has {', '.join(p.name for p in cand.params)}")
    hyp = Hypothesis({k: recs[0].params[k] for k in BASE}, cand)
    floor, rows = d["noise_floor"], []
    with FeatureModel(recs, workers=2) as m:
        for v in values:
            vals = {**base, **{p.name: 0.0 for p in cand.params}, param: v}
            pt = hyp.point(hyp.coordinates(vals))
            held = dict(m.phases)
            r_held = rms(m.residuals([pt], fit_idx)[0])
            m.phases = {**held, **identified_phases(estimate_phases(m, pt, fit_idx))}
            r_own = rms(m.residuals([pt], fit_idx)[0])
            m.phases = held
            rows.append({"value": v, "held_phases": r_held / floor, "own_phases": r_own / floor})
            print(f"{param} = {v:g}: held phases {r_held / floor:.2f}, own phases {r_own / floor:.2f} "
                  "noise floors", flush=True)
    return rows


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("case", type=Path)
    ap.add_argument("effect", choices=sorted(CANDIDATES))
    ap.add_argument("param")
    ap.add_argument("values", help="comma-separated values of PARAM in its own unit")
    ap.add_argument("--heldout", help="recordings the diagnosis held out, comma-separated (left out of the fit "
                    "RMSE)")
    ap.add_argument("--at", choices=("calibrated", "final"), default="calibrated",
                    help="the base coefficients: the calibrated ones (default) or the updated model's")
    args = ap.parse_args(argv)
    profile(args.case, args.effect, args.param, [float(x) for x in args.values.split(",")], args.heldout,
            args.at)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
