"""How well speed recordings fix the model's force scale: the compared feature with every force
coefficient (and the concealed effect's torque-like parameter) scaled by a common factor.

Usage::

    python bench/force_scale.py CASE [CASE ...]

``CASE`` is a case directory of ``bench/diagnosis_grid.py`` (``data/`` with the recordings and
``truth.json``, ``diagnosis/diagnosis.json`` for the noise floor). For each factor the script
prints the RMS change of the model's smoothed band speed against the truth model's, per
recording and over all, in rad/s and in noise floors. Reads the answer (truth.json): an analysis
of the benchmark, not a diagnosis. Results: docs/DIAGNOSIS-DESIGN.md, "The force scale".
"""
from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT / "src"))

from szdyn.diagnose.candidates import CANDIDATES  # noqa: E402
from szdyn.diagnose.data import prepare  # noqa: E402
from szdyn.diagnose.engine import FeatureModel, rms  # noqa: E402
from szdyn.manifest import read_manifest  # noqa: E402

#: every force coefficient of the base model (b_imp too, although the diagnosis does not fit it)
FORCE = ("k_c", "b_c", "k_imp", "b_imp", "mu_s", "mu_k")
#: effect parameters that scale with the forces (the primaries of Candidate.force_scaled)
SCALED = {c.primary for c in CANDIDATES.values() if c.force_scaled}
FACTORS = (0.8, 1.25, 1.5)


def point(truth: dict, lam: float) -> tuple:
    """The truth model's changes with the force scale multiplied by ``lam``."""
    ch = {k: truth["perturbed"][k]["value"] * lam for k in FORCE}
    for k, v in truth.get("effect_parameters", {}).items():
        ch[k] = v * lam if k in SCALED else v
    return ch, {}


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("cases", type=Path, nargs="+")
    args = ap.parse_args(argv)
    for case in args.cases:
        recs = prepare(read_manifest(case / "data" / "manifest.toml"))
        truth = json.loads((case / "data" / "truth.json").read_text())
        floor = json.loads((case / "diagnosis" / "diagnosis.json").read_text())["noise_floor"]
        idx = list(range(len(recs)))
        with FeatureModel(recs, workers=1) as m:
            S = m.speeds([point(truth, 1.0)] + [point(truth, f) for f in FACTORS], idx)
        print(f"{case}: noise floor {floor:.4g} rad/s")
        print("  recordings - truth model: " + ", ".join(f"{rms(recs[i].y - S[0][i]):.4f}" for i in idx))
        for f, s in zip(FACTORS, S[1:]):
            tot = rms(np.concatenate([s[i] - S[0][i] for i in idx]))
            print(f"  forces x{f:g} - truth model: " + ", ".join(f"{rms(s[i] - S[0][i]):.4f}" for i in idx)
                  + f"; all {tot:.4f} rad/s = {tot / floor:.2f} floors")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
