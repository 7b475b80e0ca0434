"""``python -m szdyn.run diagnose MANIFEST.toml --out DIR``."""
from __future__ import annotations

import argparse
import sys
import time
from dataclasses import replace
from pathlib import Path

from ..cli import Parser, directory
from ..errors import UserInputError, interrupted
from ..io import make_output_dir
from ..processes import MAX_WORKERS

__all__ = ["diagnose_command"]


def _build_parser():
    from .candidates import CANDIDATES
    from .diagnosis import FLOOR_SPREAD, POLISH_PHASE_STEPS, SECOND_LOOK_STEPS, STAGED_RATIO

    ap = Parser("diagnose", prog="python -m szdyn.run diagnose",
                 description="Calibrate the model to recordings, locate the mismatch, name the missing "
                             "effect from a library, refit and report (report.md, diagnosis.json, PNGs, "
                             "params.json).")
    ap.add_argument("manifest", type=Path, help="manifest TOML listing the recordings and their conditions")
    ap.add_argument("--out", type=directory, required=True, help="output directory")
    ap.add_argument("--candidates", help="comma-separated effect ids to screen (default: all: "
                    + ", ".join(CANDIDATES) + ")")
    ap.add_argument("--shortlist", type=int, default=2, help="candidates refitted nonlinearly (default 2)")
    ap.add_argument("--nominate-r2", type=float, default=0.3,
                    help="also refit the candidates whose signature holds the feature the calibrated residual "
                    "follows most, when it explains at least this share (R^2, 0..1; default 0.3; 1.01: never)")
    ap.add_argument("--no-probe-screen", action="store_true",
                    help="do not evaluate every candidate switched on at finite amplitudes (the best of "
                    "them, if it beats the calibrated base, is refitted; so are slider_stribeck and "
                    "slider_viscous at their own probes, moved out of the calibrated static and kinetic "
                    "friction, if they fit better)")
    ap.add_argument("--rivals", type=int, default=2,
                    help="when the selected candidate leaves the fit above 2 noise floors, also refit this "
                    "many more of the linear screening (default 2; 0: never)")
    ap.add_argument("--no-exchange-split", action="store_true",
                    help="when the fit recordings show nothing but a held-out one is missed by more than "
                    "5 noise floors, do not run again with it fitted and a similar fit recording held out")
    ap.add_argument("--no-current", action="store_true",
                    help="compare the band speed only, even where recordings have a current column and the "
                    "manifest its torque constant (by default their motor torque is compared too)")
    ap.add_argument("--no-phase", action="store_true",
                    help="start every model run from the default wheel offset instead of estimating each "
                    "recording's initial wheel phase (the impact bumps then count in the noise floor)")
    ap.add_argument("--restart", action="store_true",
                    help="run a pass that named nothing again, calibrated from the base its ablation found, "
                         "when that fits at least 2x better than the calibration (default: off; measured on "
                         "one case, docs/DIAGNOSIS-DESIGN.md)")
    ap.add_argument("--phase-steps", type=int, default=0,
                    help="after the calibration with the wheel phases, at most this many Gauss-Newton steps of "
                    "the base model, and of each candidate's refit left above the threshold, whose trial points are "
                    "each judged with the phases estimated there (default 0: off; measured on few cases, "
                    "docs/DIAGNOSIS-DESIGN.md)")
    ap.add_argument("--second-look", type=int, default=SECOND_LOOK_STEPS,
                    help="before answering 'unexplained' with the calibrated base within the phase gate, run "
                    "that pass again with this many phase-profiled steps (as --phase-steps) and answer with it; "
                    "a calibration stopped beyond the gate whose ablation's base fits within it gets the same, "
                    f"calibrated from that base (default {SECOND_LOOK_STEPS}; 0: off)")
    ap.add_argument("--scale-profile", action="store_true",
                    help="after the decision, start the named effect's fit again with every force scaled "
                    "(x0.8-x1.25, 3 Jacobians each) and take the best where it fits clearly better; the answer "
                    "stands (off by default: on seed 52 it moved four parameters towards their truth and one "
                    "away, see docs/DIAGNOSIS-DESIGN.md, \"A profile along the force scale\")")
    ap.add_argument("--amplitude-starts", action=argparse.BooleanOptionalAction, default=True,
                    help="a fifth start for a refit that explains part of the mismatch but less than half: the "
                    "calibrated coefficients with the effect's amplitude x0.5 and x2 of where the refit left it "
                    "(on by default since seed 56, where it took a named effect's parameter from 41 %% to 6.5 %% "
                    "off; --no-amplitude-starts gives the earlier default; see "
                    "docs/DIAGNOSIS-DESIGN.md, \"Seed 56: the fifth start's first rescue out of sample, on by "
                    "default\")")
    ap.add_argument("--coefficient-floor", type=float, default=0.0, metavar="STEP",
                    help="also count in each recording's noise floor what a model STEP (relative, e.g. 0.01) "
                    "off in k_c or in the slider friction misses of its impact bumps (two more runs per "
                    "recording); a light band can keep bumping so that a model 1 %% off misses its bumps by "
                    "several floors (default 0: off; on seed 64 it named one effect fewer at 0.01 and the "
                    "same at 0.002, see docs/DIAGNOSIS-DESIGN.md, \"A floor that counts the coefficients\")")
    ap.add_argument("--phase-polish", type=int, default=POLISH_PHASE_STEPS,
                    help="when the named effect moves the wheel against the motor encoder (drive_compliance) "
                    "and its refit took no phase-profiled step, at most this many such steps of it after the "
                    "decision, since its value was fitted at wheel phases estimated without it; the answer "
                    f"stands (default {POLISH_PHASE_STEPS}; 0: off)")
    ap.add_argument("--no-staged", action="store_true",
                    help="calibrate the base on all fit recordings at once only; by default, where that leaves a "
                    "mismatch, it is also calibrated on the heaviest load's fit recordings first and then on "
                    f"all from there, and that is used when it fits at least {STAGED_RATIO:g}x better (a "
                    "calibration stopped on the lighter loads' plateau)")
    ap.add_argument("--no-heavy-look", action="store_true",
                    help="answer 'unexplained' when nothing explains the mismatch on every recording; by "
                    "default, where the recordings have two loads or more, the diagnosis then runs once more "
                    "on the heaviest load's recordings alone (it needs a fit and a held-out one there) and "
                    "answers with an effect named there that fits them within 2 noise floors, reporting how "
                    "the other recordings fare")
    ap.add_argument("--weighting", choices=("fallback", "always", "off"), default="fallback",
                    help="weight each recording's residual by the common noise floor over its own, so that "
                    "recordings whose impact bumps do not reproduce count less: 'fallback' (default) only in "
                    "a second pass when the first names no effect and the recordings' own floors differ "
                    f"by more than {FLOOR_SPREAD:g}x, 'always', or 'off'")
    ap.add_argument("--max-jac", type=int, default=4, help="Jacobians per nonlinear fit (default 4; calibration twice)")
    ap.add_argument("--polish-jac", type=int, help="Jacobians to continue a budget-stopped calibration, "
                    "leading candidate or close rival with (default twice --max-jac; 0: never)")
    ap.add_argument("--unstall", type=int, default=2,
                    help="when the calibration or a candidate's refit ends above the mismatch threshold, at "
                    "most this many times try its full linear step (for a refit also the candidate's own step, the "
                    "base held) and, when one fits clearly better (a stall), fit again from there (default 2; "
                    "0: never)")
    ap.add_argument("--keep-runs", action="store_true",
                    help="keep the model runs saved in DIR/checkpoint after the diagnosis finishes (by default "
                    "they are removed then; while it runs they let an interrupted diagnosis resume: re-run "
                    "the same command, with the same or other options)")
    ap.add_argument("--no-checkpoint", action="store_true",
                    help="do not save model runs to DIR/checkpoint (an interrupted diagnosis then starts afresh)")
    ap.add_argument("--no-next-recording", action="store_true",
                    help="do not rank wheel-speed protocols for the recording that would tell the answer from "
                    "its refitted rivals (by default, where a rival explains a quarter of the mismatch or more, "
                    "each contender is run on six protocols at the lightest and heaviest load: report.md "
                    "'The next recording to take', next_recording.png)")
    ap.add_argument("--workers", type=int, help="processes for model runs (default: CPU count)")
    ap.add_argument("--quiet", action="store_true", help="no progress on stderr")
    return ap


def _is_diagnosis_report(path: Path) -> bool:
    """Whether ``path`` is a report.md a diagnosis wrote (its title line)."""
    from .report import REPORT_TITLE

    try:
        with open(path, encoding="utf-8", errors="replace") as f:
            return f.readline().rstrip("\n") == REPORT_TITLE
    except OSError:
        return False


def diagnose_command(argv) -> int:
    from ..manifest import read_manifest
    from .candidates import CANDIDATES
    from .data import prepare
    from .checkpoint import CHECKPOINT_DIR, RunCheckpoint, fingerprint
    from .diagnosis import Diagnosis
    from .report import OUTPUT_FILES, failed_md, write_report
    from .split import choose_heldout, with_heldout
    from .noise import MAX_COEFFICIENT_STEP

    args = _build_parser().parse_args(argv)
    if args.shortlist < 1:
        raise UserInputError(f"diagnose: --shortlist must be >= 1, got {args.shortlist}")
    if not 0.0 <= args.nominate_r2 <= 1.01:   # also refuses NaN
        raise UserInputError(f"diagnose: --nominate-r2 must be an R^2 in 0..1 (1.01: never), got {args.nominate_r2}")
    if args.rivals < 0:
        raise UserInputError(f"diagnose: --rivals must be >= 0, got {args.rivals}")
    if args.max_jac < 1:
        raise UserInputError(f"diagnose: --max-jac must be >= 1, got {args.max_jac}")
    if args.polish_jac is not None and args.polish_jac < 0:
        raise UserInputError(f"diagnose: --polish-jac must be >= 0, got {args.polish_jac}")
    if args.unstall < 0:
        raise UserInputError(f"diagnose: --unstall must be >= 0, got {args.unstall}")
    if args.phase_steps < 0:
        raise UserInputError(f"diagnose: --phase-steps must be >= 0, got {args.phase_steps}")
    if args.second_look < 0:
        raise UserInputError(f"diagnose: --second-look must be >= 0, got {args.second_look}")
    if args.phase_polish < 0:
        raise UserInputError(f"diagnose: --phase-polish must be >= 0, got {args.phase_polish}")
    if not 0.0 <= args.coefficient_floor <= MAX_COEFFICIENT_STEP:  # also refuses NaN
        raise UserInputError(f"diagnose: --coefficient-floor must be a relative step in 0..{MAX_COEFFICIENT_STEP:g} (0: off), "
                             f"got {args.coefficient_floor}")
    if args.workers is not None and not 1 <= args.workers <= MAX_WORKERS:
        raise UserInputError(f"diagnose: --workers must be in 1..{MAX_WORKERS}, got {args.workers}")
    cands = None
    if args.candidates is not None:
        cands = list(dict.fromkeys(c.strip() for c in args.candidates.split(",") if c.strip()))   # once each
        if not cands:
            raise UserInputError(f"diagnose: --candidates {args.candidates!r} names no candidate; "
                                 f"known: {', '.join(CANDIDATES)} (leave it out for all)")
        bad = [c for c in cands if c not in CANDIDATES]
        if bad:
            raise UserInputError(f"diagnose: unknown candidate(s) {bad}; known: {', '.join(CANDIDATES)}")
    t_start = time.perf_counter()

    def log(msg):
        if not args.quiet:
            print(f"diagnose [{time.perf_counter() - t_start:6.1f} s] {msg}", file=sys.stderr, flush=True)

    runs = [0]

    def progress(k):
        runs[0] += k
        if not args.quiet and runs[0] % 25 == 0:
            log(f"{runs[0]} model runs")

    man = read_manifest(args.manifest)
    recs = prepare(man)
    if args.no_current:
        recs = [replace(r, tau=None, torque_constant=None) for r in recs]
    # said even with --quiet: part of the input is not used (a misspelt optional column, rows
    # dropped by the reader)
    for r in recs:
        for note in r.rec.notes:
            print(f"diagnose: {r.name}: {note}", file=sys.stderr)
    unused = [r.name for r in recs if r.rec.current is not None and r.tau is None]
    if unused and not args.no_current:
        print(f"diagnose: current column not used in {', '.join(unused)}: no torque constant in the "
              "manifest ([motor] torque_constant = N m/A, or per [[recording]])", file=sys.stderr)
    with_current = {r.name for r in recs if r.rec.current is not None}
    lacking = [e.name for e in man.entries if e.torque_constant is not None and e.name not in with_current]
    if lacking:
        print(f"diagnose: torque constant given but no current column in {', '.join(lacking)}",
              file=sys.stderr)
    no_load = {}    # the load used -> recordings without load_kg
    for e in man.entries:
        if "load_kg" not in e.conditions:
            no_load.setdefault(man.parameters(e)["m_b"], []).append(e.name)
    if no_load:
        # said even with --quiet: the slider friction scales with the load, so a forgotten
        # load_kg changes every fitted friction coefficient
        src = "[model] m_b" if "m_b" in man.model else "the model's default"
        print("diagnose: no load_kg for " + "; ".join(f"{', '.join(names)} (m_b = {m:g} kg used)"
                                                       for m, names in no_load.items())
              + f": the load is {src} (set load_kg per [[recording]])", file=sys.stderr)
    if not man.heldout:
        held = choose_heldout(recs)
        recs = with_heldout(recs, held)
        if held:
            log(f"no [split] in the manifest: holding out {', '.join(held)} (every load-direction "
                "pair kept among the fit recordings where they allow)")
    log(f"{len(recs)} recording(s): {sum(r.role == 'fit' for r in recs)} fit, "
        f"{sum(r.role != 'fit' for r in recs)} held out")
    # before the diagnosis: an --out that cannot take the results would lose the whole diagnosis
    try:
        make_output_dir(args.out)
    except UserInputError as exc:
        raise UserInputError(f"diagnose: --out: {exc}") from None
    # the diagnosis replaces its own files (report.md, params.json, ...) in --out; files of those
    # names are someone else's (e.g. --out the data folder) unless a diagnosis left them: its
    # diagnosis.json, its checkpoint (a run stopped while its files moved in) or its report's title
    foreign = [f for f in OUTPUT_FILES if (args.out / f).exists()]
    if foreign and not ((args.out / "diagnosis.json").is_file() or (args.out / CHECKPOINT_DIR).is_dir()
                        or _is_diagnosis_report(args.out / "report.md")):
        raise UserInputError(f"diagnose: --out {args.out} holds {', '.join(foreign)} without a "
                             "diagnosis.json beside them (not a diagnosis's output); the diagnosis "
                             "would replace them: choose another --out, or move them away")
    checkpoint = None if args.no_checkpoint else RunCheckpoint(
        args.out / CHECKPOINT_DIR, fingerprint(recs), warn=lambda m: print(f"diagnose: {m}", file=sys.stderr))
    d = Diagnosis(cands, shortlist=args.shortlist, nominate_r2=args.nominate_r2,
                  probe_screen=not args.no_probe_screen, max_jac=args.max_jac,
                  polish_jac=args.polish_jac, rivals=args.rivals, exchange_split=not args.no_exchange_split,
                  weighting=args.weighting, unstall=args.unstall, fit_phase=not args.no_phase,
                  phase_steps=args.phase_steps, restart=args.restart,
                  second_look=args.second_look, phase_polish=args.phase_polish,
                  scale_profile=args.scale_profile, amplitude_starts=args.amplitude_starts,
                  coefficient_floor=args.coefficient_floor,
                  staged=not args.no_staged,
                  heavy_look=not args.no_heavy_look, checkpoint=checkpoint,
                  workers=args.workers, log=log, progress=progress)
    nxt = None
    try:
        d.fit(recs)
        if not args.no_next_recording:
            from .design import NextRecording

            try:
                nxt = NextRecording(workers=args.workers, log=log).fit(d)
            except Exception as exc:    # advice only: it must not cost the diagnosis's results
                print(f"diagnose: the next recording was not ranked ({type(exc).__name__}: {exc}); "
                      "the diagnosis is written without it", file=sys.stderr, flush=True)
    except (KeyboardInterrupt, SystemError) as exc:
        if not interrupted(exc):
            raise
        if checkpoint is not None and checkpoint.directory.is_dir():
            upto = "made so far" if checkpoint.error_ is None else "made up to the failure said above"
            print(f"diagnose interrupted: the model runs {upto} are saved in {checkpoint.directory}; "
                  "re-run the same command to resume", file=sys.stderr, flush=True)
        raise KeyboardInterrupt from None
    js = write_report(d, args.out, next_recording=nxt)
    if checkpoint is not None and not args.keep_runs:
        checkpoint.clear()
    sel = ", ".join(js["selected"]) or d.verdict_
    h0, h1 = js["fit"]["before"]["heldout_rmse"], js["fit"]["after"]["heldout_rmse"]
    # null (to_json's NaN) when no recording was held out, e.g. a single recording
    held = (f"held-out RMSE {h0:.4g} -> {h1:.4g} rad/s" if h0 is not None and h1 is not None
            else "no held-out recording")
    if js.get("final_failed_on"):
        # said even with --quiet: the figures for these recordings are no fit
        print("diagnose: " + failed_md(js["final_failed_on"], js["selected"]).replace("**", "").replace("`", ""),
              file=sys.stderr, flush=True)
    log(f"done: {sel}; {held}; wrote {args.out}/report.md")
    print(sel)
    return 0
