"""How reproducible a synth recording's impact bumps are: at the truth, and 1 % away from it.

Usage::

    python bench/bump_sensitivity.py CASE_DIR RECORDING [RECORDING ...] [--json OUT.json]

``CASE_DIR`` is a diagnosis grid case (``bench/diagnosis_grid.py --work W``: ``W/EFFECT-SEED``)
with the synth recordings in ``data/`` (``truth.json``, ``manifest.toml``) and, optionally, the
diagnosis in ``diagnosis/``. This script reads ``truth.json``, which the diagnosis never does:
it is a check of the noise floor's assumption, not part of a diagnosis.

The diagnosis's noise floor (:mod:`szdyn.diagnose.noise`) takes a recording's unreproducible
bumps, once its wheel phase is estimated, as the spread from the phase's uncertainty alone
(1/32 of a circle pitch). This script measures, for each named recording, the RMSE (rad/s) of
the compared feature (smoothed band speed) against the model run

* at the truth (coefficients, concealed effect, wheel phase): what a correct model reaches;
* with ``k_c`` and with ``mu_k`` 1 % off the truth, at the truth phase: what a fit whose
  coefficients are right to 1 % reaches;
* with the phase 1/32 pitch off: the spread the floor assumes;
* when the diagnosis is there, at its calibrated coefficients with the truth phase and with the
  phase it estimated;

and, for the two 1 % changes, how much of the change in the model's speed is slow (its 0.5 s
running mean) and how it grows over the recording (RMS per 0.5 s). ``--without-effect`` makes
every model point without the concealed effect (the "truth" is then the base truth, which no
longer matches the recording where the effect shows): whether the bumps' sensitivity is the
effect's or the coefficients'.
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

from szdyn.diagnose.data import prepare  # noqa: E402
from szdyn.diagnose.engine import FeatureModel, rms  # noqa: E402
# the window that parts a slow change from the bumps, the same as the floor's coefficient share
from szdyn.diagnose.noise import SLOW_S  # noqa: E402
from szdyn.io import write_json  # noqa: E402
from szdyn.manifest import read_manifest  # noqa: E402

#: the phase uncertainty the floor assumes, in circle pitches (szdyn.diagnose.phase)
PHASE_STEP = 1.0 / 32.0
#: relative coefficient change
STEP = 0.01
#: labels of the two coefficient changes (keys of the JSON's ``rmse`` and ``change``)
KC_LABEL = f"k_c x{1 + STEP:g}"
MUK_LABEL = f"mu_k x{1 + STEP:g}"


def _points(truth: dict, q_true: float, pitch: float, diagnosis: dict | None, name: str) -> dict:
    base = {**truth, "q_w0": q_true}
    pts = {"truth": base,
           KC_LABEL: {**base, "k_c": truth["k_c"] * (1 + STEP)},
           MUK_LABEL: {**base, "mu_k": truth["mu_k"] * (1 + STEP)},
           f"phase +{PHASE_STEP:g} pitch": {**base, "q_w0": q_true + PHASE_STEP * pitch}}
    if diagnosis is not None:
        cal = dict(diagnosis["calibrated"])
        pts["calibrated, truth phase"] = {**cal, "q_w0": q_true}
        # the phases the diagnosis ended with, per recording (its report's wheel_phase)
        est = diagnosis.get("wheel_phase", {}).get("recordings") or {}
        if name in est and "q_w0" in est[name]:
            pts["calibrated, estimated phase"] = {**cal, "q_w0": est[name]["q_w0"]}
    return pts


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("case", type=Path, help="grid case directory (with data/truth.json)")
    ap.add_argument("recordings", nargs="+", help="recording names (or their beginnings)")
    ap.add_argument("--json", type=Path, default=None, help="write the measurements here")
    ap.add_argument("--without-effect", action="store_true",
                    help="leave the concealed effect out of the truth (do its bumps come from it?)")
    args = ap.parse_args(argv)
    data = args.case / "data"
    try:
        truth_doc = json.loads((data / "truth.json").read_text())
        manifest = read_manifest(data / "manifest.toml")
    except (OSError, ValueError) as exc:
        raise SystemExit(f"{args.case}: not a grid case with data/truth.json and data/manifest.toml ({exc})")
    dpath = args.case / "diagnosis" / "diagnosis.json"
    diagnosis = json.loads(dpath.read_text()) if dpath.is_file() else None
    truth = {k: v["value"] for k, v in truth_doc["perturbed"].items()}
    if not args.without_effect:
        truth.update(truth_doc.get("effect_parameters", {}))
    if truth_doc.get("effect_sensor") and not args.without_effect:
        raise SystemExit(f"{args.case}: a sensor effect ({truth_doc['effect']}); this check is of the model's bumps")
    q_true = {r["file"]: r["q_w0"] for r in truth_doc["recordings"]}
    recs = prepare(manifest)
    model = FeatureModel(recs, workers=1)
    out = []
    for want in args.recordings:
        hits = [j for j, r in enumerate(recs) if r.name.startswith(want)]
        if len(hits) != 1:
            raise SystemExit(f"{want}: matches {len(hits)} recordings of {[r.name for r in recs]}; expected one")
        i = hits[0]
        r = recs[i]
        pitch = 2.0 * math.pi / r.params.n_circles
        pts = _points(truth, q_true[r.name], pitch, diagnosis, r.name)
        speeds = {k: v[0] for k, v in zip(pts, model.speeds([(p, {}) for p in pts.values()], [i]))}
        row = {"recording": r.name, "rmse": {k: rms(r.y - v) for k, v in speeds.items()}, "change": {}}
        dt = float(np.median(np.diff(r.t_feat)))
        kern = np.ones(max(1, int(round(SLOW_S / dt))))
        kern /= kern.size
        edges = np.arange(r.t_feat[0], r.t_feat[-1], SLOW_S)
        for k in (KC_LABEL, MUK_LABEL):
            d = speeds[k] - speeds["truth"]
            row["change"][k] = {"rms": rms(d), "slow_rms": rms(np.convolve(d, kern, mode="same")),
                                "rms_per_window": [rms(d[(r.t_feat >= a) & (r.t_feat < a + SLOW_S)])
                                                   for a in edges]}
        out.append(row)
        print(f"{r.name}")
        for k, v in row["rmse"].items():
            print(f"  {k:28s} rmse {v:.4f} rad/s")
        for k, v in row["change"].items():
            print(f"  change with {k:14s} rms {v['rms']:.4f}, slow part {v['slow_rms']:.4f} rad/s; per "
                  f"{SLOW_S:g} s: {' '.join(f'{x:.3f}' for x in v['rms_per_window'])}")
    if args.json is not None:
        write_json(args.json, {"case": str(args.case), "without_effect": args.without_effect, "step": STEP,
                               "phase_step_pitch": PHASE_STEP, "slow_window_s": SLOW_S, "units": "rad/s",
                               "recordings": out})
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
