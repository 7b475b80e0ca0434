"""Cost of the issue's diagnosis case: three 10 s recordings on 2 cores (issue 5, "Cost").

Usage::

    python bench/diagnosis_cost.py --work DIR [--effect load_lift] [--seed 31] [--diagnose-args "--phase-steps 2"]

Writes three 10 s recordings at one load (1 kg; ramps to +pi, +2 pi and -pi rad/s, each held to
10 s) with one concealed effect, runs ``python -m szdyn.run diagnose`` on them as a user would
(CLI defaults, no ``[split]``: one recording is held out) and prints the wall time, the verdict,
the effect parameter against the truth and the held-out RMSE before and after, also written to
``DIR/cost.json``. Run it on an otherwise idle machine: the time is the measurement.
"""
from __future__ import annotations

import argparse
import json
import math
import subprocess
import sys
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT / "src"))

from szdyn.io import write_json  # noqa: E402
from szdyn.synth import RampSpec, synthesize  # noqa: E402
from szdyn.diagnose.candidates import CANDIDATES  # noqa: E402

#: Three 10 s recordings: the grid's ramps (``szdyn.synth.DEFAULT_RAMPS``), each held longer.
RAMPS = (RampSpec("up_pi", 0.5 * math.pi, 2.0, 8.0),
         RampSpec("up_2pi", math.pi, 2.0, 8.0),
         RampSpec("down_pi", -0.4 * math.pi, 2.5, 7.5))


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--work", type=Path, required=True)
    ap.add_argument("--effect", default="load_lift")
    ap.add_argument("--seed", type=int, default=31)
    ap.add_argument("--diagnose-args", default="", help="extra diagnose options (default: none, the CLI defaults)")
    args = ap.parse_args(argv)
    data, out = args.work / "data", args.work / "diagnosis"
    if not (data / "truth.json").is_file():
        synthesize(data, args.effect, seed=args.seed, loads_kg=(1.0,), ramps=RAMPS, dt=5e-5, verbose=False)
    # the split is the diagnosis's own choice (no [split] in the manifest): drop the generator's
    man = data / "manifest.toml"
    text = man.read_text()
    if "[split]" in text:
        lines = text.splitlines()
        k = lines.index("[split]")
        man.write_text("\n".join(lines[:k] + lines[k + 2:]) + "\n")
    t = time.perf_counter()
    subprocess.run([sys.executable, "-m", "szdyn.run", "diagnose", str(man), "--out", str(out),
                    *args.diagnose_args.split()], check=True)
    seconds = time.perf_counter() - t
    truth = json.loads((data / "truth.json").read_text())
    d = json.loads((out / "diagnosis.json").read_text())
    res = {"effect": args.effect, "seed": args.seed, "seconds": round(seconds, 1), "selected": d["selected"],
           "verdict": d["verdict"], "heldout_before": d["fit"]["before"]["heldout_rmse"],
           "heldout_after": d["fit"]["after"]["heldout_rmse"], "model_runs": d["cost"]["model_runs"],
           "diagnose_args": args.diagnose_args}
    if args.effect != "none":
        prim = CANDIDATES[args.effect].primary
        tv = {**truth["effect_parameters"], **truth["effect_sensor"]}.get(prim)
        e = next((x for x in d["effects"] if x["id"] == args.effect and x.get("primary")), None)
        res.update({"truth_param": tv, "fitted_param": e["primary"]["value"] if e else None})
    write_json(args.work / "cost.json", res)
    print(json.dumps(res, indent=1))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
