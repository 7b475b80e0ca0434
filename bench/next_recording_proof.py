"""Does the recording the diagnosis asks for settle the answer?  (The loop of ``szdyn.diagnose.design``.)

Usage::

    python bench/next_recording_proof.py --case DIR --diagnosis OUT --work WORK [--diagnose-args="..."]

``DIR`` holds synthetic recordings (``DIR/data/manifest.toml`` and their CSVs) and the truth
that made them (``DIR/truth.json``, or ``DIR/data/truth.json``); ``OUT`` is a finished diagnosis
of them (``OUT/diagnosis.json``) whose ``next_recording`` recommends a protocol. The script
records that protocol from the *same truth* the way the generator records (RK4 at the truth's
step, a random initial wheel phase, the truth's sensor model; ``szdyn.synth.record_truth``, on a
random stream of its own), adds it to a copy of the recordings as one more *fit* recording (the
held-out ones are unchanged, so the held-out figures before and after compare), runs
``python -m szdyn.run diagnose`` on the copy as a user would, and writes ``WORK/proof.json`` and
``WORK/proof.md``: the answer, the effect parameter against the truth and the held-out error,
without and with the new recording.

The truth is read here only to play the rig; the diagnosis never sees it.
"""
from __future__ import annotations

import argparse
import json
import shlex
import shutil
import subprocess
import sys
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT / "src"))
sys.path.insert(0, str(ROOT / "bench"))

from szdyn.io import atomic_write_text, write_json  # noqa: E402
from szdyn.params import ParameterSet  # noqa: E402
from szdyn.sensors import SensorModel  # noqa: E402
from szdyn.synth import _fmt_load, record_truth  # noqa: E402
from szdyn.diagnose.design import PROTOCOLS  # noqa: E402
from diagnosis_grid import param_error, truth_primary  # noqa: E402

#: Random stream of the new recording (``record_truth``'s ``stream``): far from the generator's
#: own (one per recording of its grid, from 0), so its phase and noise are independent of theirs.
STREAM = 1000


def _truth(case: Path) -> dict:
    for p in (case / "truth.json", case / "data" / "truth.json"):
        if p.is_file():
            return json.loads(p.read_text())
    raise SystemExit(f"next_recording_proof: no truth.json in {case} or {case / 'data'}")


def add_recording(case: Path, diagnosis: dict, work: Path, protocol: str | None = None,
                  load_kg: float | None = None) -> dict:
    """Copy ``case/data`` to ``work/data`` and record the recommended protocol into it from the
    truth (or the row of the ranking at ``protocol`` and ``load_kg``); return what was recorded."""
    nr = diagnosis.get("next_recording") or {}
    rec = nr.get("recommended")
    if not rec:
        raise SystemExit("next_recording_proof: the diagnosis recommends no recording "
                         f"({nr.get('why_not') or 'no next_recording section'})")
    if protocol is not None:
        rows = [r for r in nr["protocols"] if r["protocol"] == protocol
                and (load_kg is None or abs(r["load_kg"] - load_kg) < 1e-9)]
        if not rows:
            raise SystemExit(f"next_recording_proof: no row {protocol} at {load_kg} kg in the ranking")
        rec = rows[0]
    proto = next(p for p in PROTOCOLS if p.id == rec["protocol"])
    truth = _truth(case)
    data = work / "data"
    if data.exists():
        shutil.rmtree(data)
    shutil.copytree(case / "data", data, ignore=shutil.ignore_patterns("truth.json"))
    params = ParameterSet.from_dict(truth["truth_parameters"]).replace(m_b=rec["load_kg"])
    sensor = SensorModel(**truth["sensor"])
    name = f"next_{proto.id}_load{_fmt_load(rec['load_kg'])}kg.csv"    # 0.5 kg -> load0p5kg, as the generator
    q_w0, r, _ = record_truth(params, proto.drive(nr["scale_speed"]), proto.duration, sensor, data / name,
                              seed=int(truth["seed"]), stream=STREAM, dt=truth["integrator"]["dt"],
                              save_dt=truth["integrator"]["save_dt"])
    man = data / "manifest.toml"
    man.write_text(man.read_text().rstrip("\n") + "\n\n[[recording]]\n"
                   f"file = {json.dumps(name)}\nload_kg = {float(rec['load_kg'])!r}\n"
                   f"n_circles = {int(truth['n_circles'])}\n"
                   f"note = {json.dumps('protocol ' + proto.id + ' (the next recording asked for)')}\n")
    return {"file": name, "protocol": proto.id, "load_kg": rec["load_kg"], "scale_speed": nr["scale_speed"],
            "recommended": rec["protocol"] == nr["recommended"]["protocol"]
            and rec["load_kg"] == nr["recommended"]["load_kg"],
            "duration_s": proto.duration, "rows": int(r.t.size), "q_w0": q_w0,
            "predicted_separation": rec["separation"]}


def summary(truth: dict, d: dict) -> dict:
    sel = d["selected"]
    out = {"verdict": d["verdict"], "selected": sel,
           "heldout_before": d["fit"]["before"]["heldout_rmse"], "heldout_after": d["fit"]["after"]["heldout_rmse"],
           "noise_floor": d["noise_floor"], "seconds": sum(d["cost"]["seconds"].values()),
           "model_runs": d["cost"]["model_runs"]}
    if sel:
        e = next(x for x in d["effects"] if x["selected"])
        out["parameters"] = e["parameters"]
        if sel == [truth["effect"]]:
            prim = truth_primary(truth, sel[0])
            if prim is not None:
                out["parameter_error"] = param_error(sel[0], prim, e["primary"]["value"])
    return out


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--case", type=Path, required=True)
    ap.add_argument("--diagnosis", type=Path, required=True, help="directory of a finished diagnosis of the case")
    ap.add_argument("--work", type=Path, required=True)
    # (written --diagnose-args=--quiet: argparse reads a lone value starting with "-" as an option)
    ap.add_argument("--diagnose-args", default="", metavar="ARGS",
                    help='extra arguments for the diagnosis, one string, e.g. --diagnose-args="--quiet"')
    ap.add_argument("--protocol", help="record this row of the ranking instead of the recommended one")
    ap.add_argument("--load", type=float, help="with --protocol: its load (kg; default its best)")
    args = ap.parse_args(argv)
    args.work.mkdir(parents=True, exist_ok=True)
    before = json.loads((args.diagnosis / "diagnosis.json").read_text())
    truth = _truth(args.case)
    added = add_recording(args.case, before, args.work, args.protocol, args.load)
    print(f"recorded {added['file']} ({added['protocol']}, {added['load_kg']:g} kg) from the truth", file=sys.stderr)
    t0 = time.perf_counter()
    subprocess.run([sys.executable, "-m", "szdyn.run", "diagnose", str(args.work / "data" / "manifest.toml"),
                    "--out", str(args.work / "diagnosis"), *shlex.split(args.diagnose_args)], check=True)
    seconds = time.perf_counter() - t0
    after = json.loads((args.work / "diagnosis" / "diagnosis.json").read_text())
    res = {"case": str(args.case), "truth": {"effect": truth["effect"], "parameters": truth["effect_parameters"],
                                             "sensor": truth["effect_sensor"]},
           "added": added, "without": summary(truth, before), "with": summary(truth, after),
           "seconds_with": seconds}
    write_json(args.work / "proof.json", res)
    w, n = res["without"], res["with"]

    def row(label, s):
        pe = s.get("parameter_error")
        return (f"| {label} | {', '.join(s['selected']) or s['verdict']} | "
                + (f"{100 * pe:.1f} %" if pe is not None else "") + f" | {s['heldout_before']:.4g} -> "
                f"{s['heldout_after']:.4g} |")
    md = [f"# The next recording, recorded: {args.case}", "",
          f"Concealed: `{truth['effect']}` {truth['effect_parameters'] or truth['effect_sensor']}.", "",
          f"Added `{added['file']}` ({'the recommended row' if added['recommended'] else 'not the recommended row'}: "
          f"protocol `{added['protocol']}`, {added['load_kg']:g} kg, "
          f"{added['duration_s']:g} s at scale {added['scale_speed']:.3g} rad/s; predicted separation "
          + "; ".join(f"{k} {v:.2f}" for k, v in added["predicted_separation"].items()) + " floors).", "",
          "| recordings | answer | parameter error | held-out RMSE (rad/s) |", "|---|---|---|---|",
          row("as generated", w), row("with the next recording", n), "",
          f"Diagnosis with the new recording: {seconds:.0f} s.", ""]
    atomic_write_text(args.work / "proof.md", "\n".join(md))
    print("\n".join(md))
    return 0


if __name__ == "__main__":
    sys.exit(main())
