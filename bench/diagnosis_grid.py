"""Proof of the diagnosis on concealed effects: synth grid -> diagnose -> score -> DIAGNOSIS.md.

Usage::

    python bench/diagnosis_grid.py --work grid-work --out DIAGNOSIS.md [--seeds 11] [--null-seeds 21,22,23]

For each effect of :data:`szdyn.synth.EFFECTS` and each seed (amplitude drawn from the effect's
realistic range), and for null cases (no effect), the generator writes recordings
(``synth --loads 0.5,1 --dt 5e-5``: RK4 at 50 us, 10 us with roller-contact friction; the fit
uses Heun at 100 us / dopri5), the
diagnosis runs on them as a user would (``python -m szdyn.run diagnose``; it never reads
``truth.json``), and the result is scored against ``truth.json``. Resumable: finished cases are
kept in ``--work``.

``--runs-from WORK`` diagnoses again, with other ``--diagnose-args`` (by default none), the
cases another grid run finished with ``--diagnose-args=--keep-runs``: each case's recordings and
kept model runs are copied into ``--work``, so every run the new options share with the old
path is read back (the checkpoint's fingerprint is of the recordings and the code, not the
options) and only the rest are made. Its seconds are not costs and are not written. Run it with
the code that made the runs (``PYTHONPATH`` to that tree's ``src``): runs of other code are set
aside by ``diagnose`` and all made anew, which the grid says after the case.
"""
from __future__ import annotations

import argparse
import json
import math
import shutil
import subprocess
import sys
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT / "src"))

from szdyn.io import atomic_write_text, write_json  # noqa: E402
from szdyn.diagnose.design import MIN_SEPARATION  # noqa: E402
from szdyn.synth import EFFECTS  # noqa: E402
from szdyn.diagnose.candidates import CANDIDATES, primary_std  # noqa: E402
from szdyn.diagnose.checkpoint import CHECKPOINT_DIR  # noqa: E402


#: The primary parameter's value without the effect, where it is not 0. The error is relative to
#: the effect, the primary's deviation from this value: encoder_scale's primary is the gain
#: 1 + A, and relative to the gain a scale error A = 0.02 fitted as 0.03 would be 1 % off, not 50 %.
NEUTRAL = {"encoder_scale": 1.0}


def param_error(effect: str, truth: float, fitted: float) -> float | None:
    """Relative error of the effect's fitted primary parameter against the truth's, measured from
    the value without the effect (:data:`NEUTRAL`, else 0); None for a truth at that value."""
    n = NEUTRAL.get(effect, 0.0)
    return None if truth == n else abs((fitted - n) / (truth - n) - 1.0)


def truth_primary(truth: dict, cid: str):
    """The truth value of the effect's primary parameter (as the diagnosis reports it)."""
    prim = CANDIDATES[cid].primary
    src = {**truth.get("effect_parameters", {}), **truth.get("effect_sensor", {})}
    return src.get(prim)


def ramp_dicts(ramps: str | None) -> list:
    """The profiles ``synth --ramps ramps`` writes (as in its truth.json); None: its defaults."""
    from szdyn.synth import DEFAULT_RAMPS, _ramps

    return [r.to_dict() for r in (DEFAULT_RAMPS if ramps is None else _ramps(ramps))]


def describe_ramps(ramps: str | None) -> str:
    if ramps is None:
        return "ramps to +pi, +2 pi, -pi rad/s"
    return "the profiles " + ", ".join(
        f"{r['name']} (to {r['omega_hold']:.3g} rad/s in {r['t_ramp']:g} s, held {r['t_hold']:g} s"
        + (f", stopped in {r['t_stop']:g} s)" if r.get("t_stop") else ")") for r in ramp_dicts(ramps))


def copy_kept_runs(source: Path, case: Path) -> None:
    """Copy a finished case's recordings and kept model runs (``source``, a case directory of a
    grid run with ``--keep-runs``) into ``case``, unless it already holds them."""
    kept = source / "diagnosis" / CHECKPOINT_DIR
    if not (source / "data" / "truth.json").is_file() or not (kept / "fingerprint.json").is_file():
        raise SystemExit(f"--runs-from: {source} has no recordings (data/truth.json) or no kept model "
                         f"runs (diagnosis/{CHECKPOINT_DIR}/fingerprint.json); run that grid with "
                         "--diagnose-args=--keep-runs")
    if not (case / "data" / "truth.json").is_file():
        shutil.rmtree(case / "data", ignore_errors=True)    # an unfinished copy
        shutil.copytree(source / "data", case / "data")
    if not (case / "diagnosis" / CHECKPOINT_DIR).is_dir():
        shutil.copytree(kept, case / "diagnosis" / CHECKPOINT_DIR)


def synthesize(data: Path, effect: str, seed: int, more=()) -> None:
    """The grid's recordings of one case: ``synth`` into ``data`` (loads 0.5 and 1 kg, RK4 at
    50 us), ``more`` its further options (``--ramps``, ``--current``)."""
    # --overwrite: the work directory is the grid's own; a set without truth.json is unfinished
    subprocess.run([sys.executable, "-m", "szdyn.run", "synth", "--out", str(data), "--effect", effect,
                    "--seed", str(seed), "--loads", "0.5,1", "--dt", "5e-5", "--quiet", "--overwrite",
                    *more], check=True)


def run_case(work: Path, effect: str, seed: int, diag_args, current: float | None = None,
             runs_from: Path | None = None, ramps: str | None = None) -> dict:
    case = work / f"{effect}-{seed}"
    data, out = case / "data", case / "diagnosis"
    replay = runs_from is not None and not (out / "diagnosis.json").is_file()
    if replay:
        copy_kept_runs(runs_from / case.name, case)
    if not (data / "truth.json").is_file():
        more = ([] if current is None else ["--current", repr(current)]) + ([] if ramps is None else ["--ramps", ramps])
        synthesize(data, effect, seed, more)
    if ("[motor]" in (data / "manifest.toml").read_text()) != (current is not None):
        # a work directory holds recordings with or without the current, not both
        raise SystemExit(f"{data}: recordings {'without' if current is not None else 'with'} a current "
                         f"column, but --current is {'given' if current is not None else 'not given'}; "
                         "use another --work")
    made = json.loads((data / "truth.json").read_text())["ramps"]
    if made != ramp_dicts(ramps):
        # nor recordings of two protocols
        raise SystemExit(f"{data}: recordings of the profiles {[r['name'] for r in made]}, not those of "
                         f"--ramps {ramps or '(default)'}; use another --work")
    if not (out / "diagnosis.json").is_file():
        t = time.perf_counter()
        subprocess.run([sys.executable, "-m", "szdyn.run", "diagnose", str(data / "manifest.toml"),
                        "--out", str(out), "--quiet", *diag_args], check=True)
        if replay:
            # the runs read back were made by another path: this time is not the diagnosis's cost
            (case / "seconds.txt").unlink(missing_ok=True)
            if (out / f"{CHECKPOINT_DIR}-previous").exists():
                # the kept runs were of other code or recordings: diagnose set them aside and made
                # every run anew, so this is no replay of the other grid's path
                print(f"{case}: the kept model runs of {runs_from / case.name} were not valid for this "
                      f"code (moved to {out / (CHECKPOINT_DIR + '-previous')}); every run was made anew",
                      file=sys.stderr, flush=True)
        else:
            (case / "seconds.txt").write_text(f"{time.perf_counter() - t:.1f}\n")
    truth = json.loads((data / "truth.json").read_text())
    d = json.loads((out / "diagnosis.json").read_text())
    sel = d["selected"]
    res = {"effect": effect, "seed": seed, "amplitude": truth.get("amplitude"), "selected": sel,
           "verdict": d.get("verdict"),
           "correct": (sel == [] if effect == "none" else sel == [effect]),
           "heldout_before": d["fit"]["before"]["heldout_rmse"],
           "heldout_after": d["fit"]["after"]["heldout_rmse"],
           "seconds": float((case / "seconds.txt").read_text()) if (case / "seconds.txt").is_file() else None}
    look = d.get("heavy_look") or {}
    if look.get("ran"):
        # what the heaviest load alone said (an "unexplained" whose heaviest load said "none" has
        # the report's caution that it may be the calibration's; docs/DIAGNOSIS-DESIGN.md,
        # "Null 89's unexplained, traced")
        res["heavy_look"] = look.get("verdict")
    nr = d.get("next_recording")
    if nr is not None:
        # the next-recording step (szdyn.diagnose.design): whom it would tell apart, and with what;
        # a miss it can decide is one whose concealed effect is among the contenders
        rec = nr.get("recommended")
        res["next_contenders"] = nr.get("contenders") or []
        res["next_protocol"] = f"{rec['protocol']} at {rec['load_kg']:g} kg" if rec else None
        res["next_separation"] = rec["min_separation"] if rec else None
        res["next_sufficient"] = bool(rec and rec.get("sufficient"))
    if res["heldout_before"] and res["heldout_after"]:
        res["heldout_ratio"] = res["heldout_before"] / res["heldout_after"]
    if res["heldout_before"] and d.get("noise_floor"):
        # about the most any model can cut the held-out error by: one at the noise floor (the
        # truth's held-out RMSE is about the floor); well below 3, the goal's 3x is out of reach
        res["heldout_over_floor"] = res["heldout_before"] / d["noise_floor"]
    if effect != "none":
        tv = truth_primary(truth, effect)
        e = next((x for x in d["effects"] if x["id"] == effect and x.get("primary")), None)
        res["truth_param"] = tv
        res["fitted_param"] = e["primary"]["value"] if e else None
        perr = param_error(effect, tv, e["primary"]["value"]) \
            if tv is not None and e and e["primary"]["value"] is not None and math.isfinite(tv) else None
        if perr is not None:
            res["param_error"] = perr
            if CANDIDATES[effect].force_scaled and res["correct"]:
                # the scale-free form (Candidate.force_scaled): relative to mu_k, the refit's
                # against the truth's (the final model is the selected refit)
                mu_t, mu_f = truth["perturbed"]["mu_k"]["value"], d["final"]["values"]["mu_k"]
                res["param_error_per_mu_k"] = abs((e["primary"]["value"] / mu_f) / (tv / mu_t) - 1.0)
            # how far off in its own reported standard deviations (older diagnosis.json files have
            # no primary std: then from the coordinates' std, uncorrelated, exact for one parameter)
            sd = e["primary"].get("std")
            if sd is None:
                sd = primary_std(CANDIDATES[effect], e["fit_coordinates"], e["std"])
            res["param_std"] = sd
            if sd and math.isfinite(sd):
                res["param_z"] = abs(e["primary"]["value"] - tv) / sd
    return res


def _fmt(x, f=".3g"):
    return "-" if x is None else format(x, f)


def next_recording_rows(results) -> list[str]:
    """Summary rows for the next-recording step, when the diagnoses ran it (none before 3fc9059)."""
    ran = [r for r in results if "next_contenders" in r]
    if not ran:
        return []
    eff = [r for r in ran if r["effect"] != "none"]
    miss = [r for r in eff if not r["correct"]]
    asked = [r for r in ran if r["next_sufficient"]]
    return [f"| next recording asked for (sufficient: contenders >= {MIN_SEPARATION:g} floors apart on it, no break-away) | {len(asked)}/{len(ran)} cases | |",
            f"| ... misses for which one is asked for with the concealed effect among the contenders (it could decide them) | "
            f"{sum(r['next_sufficient'] and r['effect'] in r['next_contenders'] for r in miss)}/{len(miss)} | |",
            f"| ... null cases where one was asked for | {sum(r['next_sufficient'] for r in ran if r['effect'] == 'none')}"
            f"/{len(ran) - len(eff)} | 0 |"]


def _next_cell(r) -> str:
    if "next_contenders" not in r:
        return "-"
    if r["next_protocol"] is None:
        return "not ranked"
    who = " vs ".join(r["next_contenders"])
    return (f"{r['next_protocol']}, {r['next_separation']:.1f} floors ({who})"
            + ("" if r["next_sufficient"] else ", not sufficient"))


def write_md(results, path: Path, args):
    eff = [r for r in results if r["effect"] != "none"]
    null = [r for r in results if r["effect"] == "none"]
    named = sum(r["correct"] for r in eff)
    fd = sum(not r["correct"] for r in null)
    alarms = sum(r["verdict"] != "none" for r in null)
    perr = [r["param_error"] for r in eff if r["correct"] and r.get("param_error") is not None]
    gained = [r for r in eff if r["correct"] and r.get("heldout_ratio")]
    ratios = [r["heldout_ratio"] for r in gained]
    reach = [r["heldout_ratio"] for r in gained if r.get("heldout_over_floor", 0.0) >= 3.0]
    zs = [r["param_z"] for r in eff if r["correct"] and r.get("param_z") is not None]
    prel = [r["param_error_per_mu_k"] for r in eff if r["correct"] and r.get("param_error_per_mu_k") is not None]
    pabs = [r["param_error"] for r in eff if r["correct"] and r.get("param_error_per_mu_k") is not None]
    secs = [r["seconds"] for r in results if r.get("seconds")]
    L = ["# Diagnosis on concealed effects (issue 5)", "",
         "Generated by `python bench/diagnosis_grid.py` " + " ".join(sys.argv[1:]) + ".", ""]
    if args.preface is not None and args.preface.is_file():
        # where the tool stands over every grid run so far (hand-written, kept across re-runs)
        L += [args.preface.read_text().rstrip(), "", "## This grid", ""]
    L += [f"Each case: `synth` writes {2 * len(ramp_dicts(args.ramps))} recordings (loads 0.5 and 1 kg x "
          f"{describe_ramps(args.ramps)}; "
         "N_c = 100; coefficients perturbed by a seeded lognormal, sigma 0.1; each recording from its "
         "own random wheel phase; RK4 at 50 us, 10 us for wheel_band_traction; 4096/2048 "
         "count encoders with noise, a 500 Hz logger with jitter and dropped rows), "
         f"{max(1, round(2 * len(ramp_dicts(args.ramps)) / 3))} of them held out; "
         "`diagnose` runs as a user would (it never reads `truth.json`); the result is scored against "
         "`truth.json`. Amplitudes are drawn from each effect's realistic range (`szdyn.synth`).", "",
         "## Summary", "",
         "| measure | result | goal |", "|---|---|---|",
         f"| concealed effect named correctly | {named}/{len(eff)} ({100 * named / max(len(eff), 1):.0f} %) | >= 90 % |",
         f"| false discoveries on null cases (an effect selected) | {fd}/{len(null)} | 0 |",
         f"| null cases where a mismatch was flagged but left unexplained | {alarms - fd}/{len(null)} | |",
         f"| `unexplained` answers whose heaviest load alone said none (effect cases; nulls) | "
         f"{sum(r['verdict'] == 'unexplained' and r.get('heavy_look') == 'none' for r in eff)}/"
         f"{sum(r['verdict'] == 'unexplained' for r in eff)}; "
         f"{sum(r['verdict'] == 'unexplained' and r.get('heavy_look') == 'none' for r in null)}/"
         f"{sum(r['verdict'] == 'unexplained' for r in null)} | |",
         f"| effect-parameter error (correctly named) | median {_fmt(_median(perr), '.1%')}, "
         f"{sum(p <= 0.15 for p in perr)}/{len(perr)} within 15 % | within 15 % |",
         f"| held-out RMSE reduction (correctly named) | median {_fmt(_median(ratios), '.1f')}x, "
         f"{sum(x >= 3 for x in ratios)}/{len(ratios)} >= 3x | >= 3x |",
         f"| ... where 3x can be reached (held-out error before >= 3 noise floors) | "
         f"{sum(x >= 3 for x in reach)}/{len(reach)} >= 3x | |",
         f"| the same for the {len(prel)} torque-like ones (c_visc, mu_st, tau_lift, a_rev, k_drive) | "
         f"median {_fmt(_median(pabs), '.1%')}, {sum(p <= 0.15 for p in pabs)}/{len(pabs)} within 15 % | |",
         f"| ... relative to the kinetic friction (parameter / mu_k, refit's against truth's) | "
         f"median {_fmt(_median(prel), '.1%')}, {sum(p <= 0.15 for p in prel)}/{len(prel)} within 15 % | |",
         f"| effect-parameter error in its reported std (correctly named) | median {_fmt(_median(zs), '.1f')}, "
         f"{sum(z <= 2 for z in zs)}/{len(zs)} within 2 std | (honest std: most within 2) |",
         f"| wall time per diagnosis (6 recordings, 2 cores) | median {_fmt(_median(secs), '.0f')} s | |",
         *next_recording_rows(results),
         "", "## Cases", "",
         "| effect | seed | amplitude | selected | correct | parameter truth | fitted | error | error of parameter / mu_k | error/std | held-out before -> after (rad/s) | ratio | before / floor | s | next recording |",
         "|---|---|---|---|---|---|---|---|---|---|---|---|---|---|---|"]
    for r in results:
        L.append(f"| {r['effect']} | {r['seed']} | {_fmt(r['amplitude'])} | {', '.join(r['selected']) or r['verdict']} | "
                 f"{'yes' if r['correct'] else '**no**'} | {_fmt(r.get('truth_param'))} | {_fmt(r.get('fitted_param'))} | "
                 f"{_fmt(r.get('param_error'), '.1%')} | {_fmt(r.get('param_error_per_mu_k'), '.1%')} | {_fmt(r.get('param_z'), '.1f')} | {_fmt(r['heldout_before'], '.4f')} -> {_fmt(r['heldout_after'], '.4f')} | "
                 f"{_fmt(r.get('heldout_ratio'), '.1f')} | {_fmt(r.get('heldout_over_floor'), '.1f')} | "
                 f"{_fmt(r.get('seconds'), '.0f')} | {_next_cell(r)} |")
    raw = args.json.resolve()
    raw = raw.relative_to(ROOT) if raw.is_relative_to(ROOT) else raw
    L += ["", "For a missed case, \"fitted\" and \"error\" are those of the concealed effect's refit when "
          "it was refitted but not selected; the summary counts correctly named cases only. "
          "\"before / floor\": the held-out error before over the noise floor, about the most any model "
          "can cut it by (not exactly: a held-out recording can reproduce better than the fit ones' floor).",
          "",
          f"Raw results: `{raw}`.", ""]
    if args.reading is not None and args.reading.is_file():
        # the human reading of the results lives in its own file, so that a re-run cannot erase it
        L += [args.reading.read_text().rstrip(), ""]
    atomic_write_text(path, "\n".join(L))


def _median(x):
    x = sorted(x)
    if not x:
        return None
    n = len(x)
    return x[n // 2] if n % 2 else 0.5 * (x[n // 2 - 1] + x[n // 2])


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--work", type=Path, default=Path("grid-work"))
    ap.add_argument("--out", type=Path, default=ROOT / "DIAGNOSIS.md")
    ap.add_argument("--json", type=Path, default=ROOT / "docs" / "diagnosis-grid.json")
    ap.add_argument("--reading", type=Path, default=ROOT / "docs" / "diagnosis-grid-reading.md",
                    help="hand-written reading of the results, appended to --out")
    ap.add_argument("--preface", type=Path, default=None,
                    help="hand-written summary over all grid runs, placed after the first line "
                         "(DIAGNOSIS.md: docs/diagnosis-standing.md)")
    ap.add_argument("--seeds", default="11,12")
    ap.add_argument("--null-seeds", default="21,22,23,24")
    ap.add_argument("--effects", default=",".join(EFFECTS))
    ap.add_argument("--diagnose-args", default="", help="extra diagnose options (default: none, the CLI defaults)")
    ap.add_argument("--score-only", action="store_true", help="only (re)score finished cases")
    ap.add_argument("--runs-from", type=Path, default=None, metavar="WORK",
                    help="another grid's --work, run with --diagnose-args=--keep-runs: diagnose each case it "
                         "finished again (here with --diagnose-args) from its recordings and kept model runs; "
                         "cases it has not finished are skipped; use the code that made the runs")
    ap.add_argument("--earlier", type=Path, default=None, metavar="JSON",
                    help="raw results (a --json file) of cases scored before, whose work directory is "
                         "gone: each case of this grid that --work has not finished is taken from it "
                         "as it was scored then (not checked against --diagnose-args or --current: say "
                         "in the reading what they were)")
    ap.add_argument("--ramps", default=None, metavar="NAME:A:T_RAMP:T_HOLD[:T_STOP],...",
                    help="the recordings' wheel-speed profiles (synth --ramps; default synth's three "
                         "ramp-and-holds): another protocol than the one the tool was developed on")
    ap.add_argument("--current", type=float, metavar="KT", default=None,
                    help="the recordings also log the motor current (synth --current KT, N m/A), and "
                         "the manifest gives KT: the diagnosis compares the motor torque too")
    args = ap.parse_args(argv)
    try:
        ramp_dicts(args.ramps)
    except argparse.ArgumentTypeError as exc:
        ap.error(f"--ramps: {exc}")
    seeds = [int(s) for s in args.seeds.split(",") if s]
    effect_cases = [(e, s) for s in seeds for e in args.effects.split(",") if e]
    null_cases = [("none", int(s)) for s in args.null_seeds.split(",") if s]
    # interleave nulls among the effects, so that a grid cut short still has both kinds
    cases, k = [], max(1, len(effect_cases) // max(len(null_cases), 1))
    while effect_cases or null_cases:
        cases += effect_cases[:k] + null_cases[:1]
        effect_cases, null_cases = effect_cases[k:], null_cases[1:]
    earlier = {}
    if args.earlier is not None:
        if args.earlier.resolve() == args.json.resolve():
            # --json is rewritten after every case: reading from it would lose what is not yet merged
            raise SystemExit(f"--earlier {args.earlier} is also --json; copy it elsewhere first")
        need = ("effect", "seed", "selected", "verdict", "correct", "heldout_before", "heldout_after")
        try:
            rows = json.loads(args.earlier.read_text())
            earlier = {(r["effect"], r["seed"]): r for r in rows}
            bad = [r for r in rows if any(k not in r for k in need)]
        except (OSError, ValueError, KeyError, TypeError) as exc:
            raise SystemExit(f"--earlier {args.earlier}: not a results file of this script ({exc})")
        if bad:
            raise SystemExit(f"--earlier {args.earlier}: a case lacks one of {', '.join(need)}: {bad[0]}")
    results = []
    for k, (e, s) in enumerate(cases, 1):
        if not (args.work / f"{e}-{s}" / "diagnosis" / "diagnosis.json").is_file():
            if (e, s) in earlier:
                print(f"[{k}/{len(cases)}] {e} seed {s}: as scored before ({args.earlier})",
                      file=sys.stderr, flush=True)
                results.append(earlier[(e, s)])
                write_json(args.json, results)
                write_md(results, args.out, args)
                continue
            if args.score_only:
                continue
            if args.runs_from is not None and not (args.runs_from / f"{e}-{s}" / "diagnosis" /
                                                   "diagnosis.json").is_file():
                print(f"[{k}/{len(cases)}] {e} seed {s}: not finished in {args.runs_from}, skipped",
                      file=sys.stderr, flush=True)
                continue
        print(f"[{k}/{len(cases)}] {e} seed {s}", file=sys.stderr, flush=True)
        results.append(run_case(args.work, e, s, args.diagnose_args.split(), args.current, args.runs_from,
                                args.ramps))
        write_json(args.json, results)
        write_md(results, args.out, args)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
