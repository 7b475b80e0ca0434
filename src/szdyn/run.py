"""``python -m szdyn.run [COMMAND]``: run the Spiral Zipper model.

Commands: ``simulate`` (the default: scenario ``thesis-fig10`` on the built-in defaults, one CSV
per run, a Fig. 10-style PNG, params.json and thesis-fig10.json), ``sweep SPEC.toml`` (parameter
sweeps, parallel and resumable), ``regime`` (regime map) and ``synth`` (synthetic recordings
with a concealed effect, for proving the diagnosis) and ``diagnose MANIFEST.toml`` (calibrate to
recordings, locate the mismatch, name the missing effect, refit). ``COMMAND --help`` for each.
"""
from __future__ import annotations

import argparse
import math
import sys
import textwrap
import warnings
from pathlib import Path

from .cli import Parser, directory
from .errors import ParameterError, SimulationError, UserInputError, interrupted

METHODS = ("rk4", "heun", "dopri5")
CONTACT_MODELS = ("impact", "coulomb", "lugre")


def _parse_set(items) -> dict[str, float]:
    """Parse ``--set NAME=VALUE`` (float literals only; nothing is evaluated)."""
    out = {}
    for item in items or ():
        name, sep, value = item.partition("=")
        if not sep or not name.strip():
            raise UserInputError(f"--set expects NAME=VALUE, got {item!r}")
        name = name.strip()
        if name == "geometry":
            raise UserInputError("--set geometry: the band geometry is a table, not a number; give it in a "
                                 "--params file (key 'geometry')")
        try:
            v = float(value)
        except ValueError:
            raise UserInputError(f"--set {name}: expected a number, got {value!r}") from None
        if not math.isfinite(v):
            raise UserInputError(f"--set {name}: expected a finite number, got {value!r}")
        if name in out and out[name] != v:
            raise UserInputError(f"--set {name} is given twice ({out[name]:g} and {v:g}); give it once")
        out[name] = v
    return out


def _positive_float(text: str) -> float:
    try:
        v = float(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"expected a number, got {text!r}") from None
    if not (math.isfinite(v) and v > 0):
        raise argparse.ArgumentTypeError(f"expected a positive finite number, got {text!r}")
    return v


def _tolerance(text: str) -> float:
    v = _positive_float(text)
    if not v < 1:
        raise argparse.ArgumentTypeError(f"expected a relative tolerance below 1 (e.g. 1e-5), got {text!r}")
    return v


def _positive_int(text: str) -> int:
    try:
        v = int(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"expected a whole number, got {text!r}") from None
    if v <= 0:
        raise argparse.ArgumentTypeError(f"expected a positive whole number, got {text!r}")
    return v


def _workers(text: str) -> int:
    from .processes import MAX_WORKERS

    v = _positive_int(text)
    if v > MAX_WORKERS:
        raise argparse.ArgumentTypeError(f"expected at most {MAX_WORKERS} processes, got {text!r}")
    return v


def add_parameter_options(ap: argparse.ArgumentParser) -> None:
    """``--params``, ``--set`` and ``--n-circles``, shared by the commands (see load_parameters)."""
    ap.add_argument("--params", type=Path, help="parameter JSON file (as simulate writes to OUT/thesis-fig10/params.json "
                    "and diagnose to its --out DIR/params.json); default: built-in defaults")
    ap.add_argument("--set", action="append", metavar="NAME=VALUE", help="override one parameter (SI units); repeatable")
    ap.add_argument("--n-circles", type=_positive_int, help="number of small circles N_c (default: from the parameter set)")


#: The step options' defaults, and the methods that use each.
STEP_DEFAULTS = {"dt": 1e-5, "rtol": 1e-5, "atol": 1e-8}
_STEP_METHODS = {"dt": ("heun", "rk4"), "rtol": ("dopri5",), "atol": ("dopri5",)}


def resolve_step_options(args) -> None:
    """Fill ``args.dt``, ``rtol``, ``atol`` with their defaults where not given, and warn about
    one given that ``args.method`` does not use (``--dt`` with dopri5 would otherwise be ignored
    without a word)."""
    unused = [f"--{k}" for k, used_by in _STEP_METHODS.items()
              if getattr(args, k) is not None and args.method not in used_by]
    if unused:
        warnings.warn(f"{' and '.join(unused)} not used by --method {args.method} (--dt is for heun and rk4, "
                      "--rtol and --atol for dopri5)", stacklevel=2)
    for k, v in STEP_DEFAULTS.items():
        if getattr(args, k) is None:
            setattr(args, k, v)


def build_parser() -> argparse.ArgumentParser:
    from .scenarios import SCENARIOS

    ap = Parser(
        "simulate",
        prog="python -m szdyn.run",
        # filled here: the raw formatter, which keeps the commands' list in columns, does not wrap
        description=textwrap.fill(
            "Simulate the Spiral Zipper (impact-friction model of Lee 2021) and its friction "
            "counter-models. Writes a CSV per run, a PNG like the thesis's Fig. 10, params.json and "
            "thesis-fig10.json (the thesis's findings as criteria, measured, with pass/fail).", 79),
        epilog="commands (python -m szdyn.run COMMAND --help for each):\n"
               + "\n".join(f"  {name:9s} {text}" for name, text in COMMAND_HELP.items()),
        formatter_class=argparse.RawDescriptionHelpFormatter,
    )
    ap.add_argument("--scenario", default="thesis-fig10", choices=sorted(SCENARIOS),
                    help="scenario to run (default: %(default)s)")
    ap.add_argument("--out", type=directory, default=Path("results"),
                    help="output directory; the files go into OUT/SCENARIO/ (default: %(default)s)")
    add_parameter_options(ap)
    ap.add_argument("--contact", choices=tuple(CONTACT_MODELS), default=None,
                    help="wheel-band transmission to run: impact (thesis), coulomb or lugre friction "
                         "counter-models (default: all three)")
    ap.add_argument("--workers", type=_workers, default=None,
                    help="parallel processes (default: one per core)")
    ap.add_argument("--method", choices=METHODS, default="dopri5",
                    help="integrator: heun (thesis's modified Euler), rk4 (fixed step), dopri5 (adaptive); default %(default)s")
    # (default None: resolve_step_options tells an option given for another method from a default)
    ap.add_argument("--dt", type=_positive_float, help=f"fixed step for heun/rk4 in s (default {STEP_DEFAULTS['dt']})")
    ap.add_argument("--rtol", type=_tolerance, help=f"dopri5 relative tolerance (default {STEP_DEFAULTS['rtol']})")
    ap.add_argument("--atol", type=_positive_float, help=f"dopri5 absolute tolerance (default {STEP_DEFAULTS['atol']})")
    ap.add_argument("--save-dt", type=_positive_float, default=1e-3, help="output sampling interval in s (default %(default)s)")
    ap.add_argument("--omega-hold", type=_positive_float, default=math.pi,
                    help="wheel speed at the end of each ramp, rad/s (default pi)")
    ap.add_argument("--t-hold", type=_positive_float, default=3.0,
                    help="hold duration after each ramp, s (default %(default)s); criterion (a) reads the hold "
                         "from 0.5 s after the ramp")
    ap.add_argument("--quiet", action="store_true", help="no progress output")
    return ap


def load_parameters(args):
    from .defaults import default_parameters
    from .params import ParameterSet

    if args.params is not None:
        try:
            is_dir, is_file = args.params.is_dir(), args.params.is_file()
        except OSError as exc:      # a name the system refuses (too long)
            raise UserInputError(f"--params: not a usable path ({exc})") from None
        if is_dir:
            raise UserInputError(f"--params: {args.params} is a directory; give the parameter JSON file "
                                 "(e.g. OUT/thesis-fig10/params.json)")
        if not is_file:
            raise UserInputError(f"--params: no such file: {args.params}")
        params = ParameterSet.from_json(args.params)
    else:
        params = default_parameters()
    changes = _parse_set(args.set)
    if args.n_circles is not None:
        if changes.get("n_circles", args.n_circles) != args.n_circles:
            raise UserInputError(f"--n-circles {args.n_circles} and --set n_circles={changes['n_circles']:g} "
                                 "disagree; give one")
        changes["n_circles"] = args.n_circles
    return params.replace(**changes) if changes else params


def _check_run_sampling(args, params, specs) -> None:
    """The integrator options against every run of the scenario (before any run starts)."""
    from szdyn_generated.spiral_zipper import state_size

    from .integrators import check_sampling

    for spec in specs:
        try:
            check_sampling(args.method, args.dt, args.save_dt, spec.t_end, n_states=state_size(params.n_circles))
        except ValueError as exc:
            raise UserInputError(f"run {spec.name} ({spec.t_end:g} s with --omega-hold {args.omega_hold:g} "
                                 f"--t-hold {args.t_hold:g}, --method {args.method}): "
                                 + str(exc).replace("save_dt=", "--save-dt ").replace("dt=", "--dt ")
                                 .replace("save_dt", "--save-dt")) from None


def simulate_command(argv) -> int:
    from .io import staged_output
    from .scenarios import SCENARIOS
    from .thesis import CRITERIA_LABELS, Integration, run_fig10

    args = build_parser().parse_args(argv)
    resolve_step_options(args)
    params = load_parameters(args)
    if "contact_model" in _parse_set(args.set):
        raise UserInputError("--set contact_model: the transmission is chosen with --contact "
                             f"({', '.join(CONTACT_MODELS)}), not as a parameter")
    models = [args.contact] if args.contact else list(CONTACT_MODELS)
    integ = Integration(args.method, args.dt, args.rtol, args.atol, args.save_dt)
    out = args.out / args.scenario
    _check_run_sampling(args, params, SCENARIOS[args.scenario](omega_hold=args.omega_hold, t_hold=args.t_hold))
    # written elsewhere and moved into OUT only when every run succeeded: an interrupted or failed
    # run leaves the previous results as they were, not a mix of old and new files
    with staged_output(out, last=("thesis-fig10.json",)) as stage:
        result = run_fig10(params, stage, models=models, integ=integ, omega_hold=args.omega_hold,
                           t_hold=args.t_hold, workers=args.workers, progress=not args.quiet)
    for m, r in result["models"].items():
        marks = ", ".join(f"{CRITERIA_LABELS[k]} {_verdict(r['criteria'][k])}" for k in CRITERIA_LABELS)
        print(f"{m}: {marks}")
    print(f"wrote {out / 'thesis-fig10.png'}, {out / 'thesis-fig10.json'} and per-run CSVs in {out}")
    return 0


def _verdict(criterion: dict) -> str:
    """'met' or 'NOT met', as thesis-fig10.json says, with the reason when the runs left the
    criterion's measure undefined (a hold too short to read, a band that sticks)."""
    reason = (criterion.get("detail") or {}).get("reason")
    if criterion["passed"]:
        return "met"
    return f"NOT met (no value: {reason})" if criterion.get("value") is None and reason else "NOT met"


def regime_command(argv) -> int:
    from .regime import SECOND_AXES, run_regime_map

    ap = Parser(
        "regime",
        prog="python -m szdyn.run regime",
        description="Regime map: roller interference against a second parameter; each case ramps the wheel "
                    "to a held speed and is classified stick / partial slip / full slip. Parallel and resumable "
                    "(re-run the same command to continue); writes regime_map.png/.json/.csv into OUT.")
    ap.add_argument("--second", choices=sorted(SECOND_AXES), default="b_c",
                    help="second axis, swept as factors %s of its value in the parameter set (after --params "
                         "and --set; default axis: %%(default)s)" %
                         ", ".join(f"{k}: {v}" for k, v in SECOND_AXES.items()))
    ap.add_argument("--out", type=directory, default=None, help="output directory (default: results/regime-SECOND)")
    add_parameter_options(ap)
    ap.add_argument("--omega-hold", type=_positive_float, default=math.pi, help="held wheel speed, rad/s (default pi)")
    ap.add_argument("--workers", type=_workers, default=None, help="parallel processes (default: one per core)")
    ap.add_argument("--quiet", action="store_true", help="no progress output")
    args = ap.parse_args(argv)
    params = load_parameters(args)
    out = args.out or Path("results") / f"regime-{args.second}"
    summary = run_regime_map(params, out, second=args.second, workers=args.workers, progress=not args.quiet,
                             omega_hold=args.omega_hold)
    print(f"regime map ({summary['counts']}) written to {out / 'regime_map.png'}")
    return 0


def sweep_command(argv) -> int:
    from .sweep import sweep_command as run_sweep_command

    return run_sweep_command(argv)


def synth_command(argv) -> int:
    from .synth import synth_command as run_synth_command

    return run_synth_command(argv)


def diagnose_command(argv) -> int:
    from .diagnose.command import diagnose_command as run_diagnose_command

    return run_diagnose_command(argv)


COMMANDS = {"simulate": simulate_command, "sweep": sweep_command, "regime": regime_command,
            "synth": synth_command, "diagnose": diagnose_command}
COMMAND_HELP = {
    "simulate": "the default: a scenario on a parameter set (the options above)",
    "sweep": "SPEC.toml: parameter sweeps, parallel and resumable",
    "regime": "regime map (stick / partial slip / full slip)",
    "synth": "synthetic recordings with a concealed effect",
    "diagnose": "MANIFEST.toml --out DIR: calibrate, locate the mismatch, name the missing effect",
}


def _show_warning(message, category, filename, lineno, file=None, line=None) -> None:
    print(f"szdyn: warning: {message}", file=sys.stderr if file is None else file)


def main(argv=None) -> int:
    argv = list(sys.argv[1:] if argv is None else argv)
    command = "simulate"
    if argv and argv[0] in COMMANDS:
        command = argv.pop(0)
    elif argv and not argv[0].startswith("-"):
        # simulate takes no positional argument: a first word is a mistyped command
        from .params import suggest

        print(f"szdyn: error: unknown command '{argv[0]}'{suggest(argv[0], COMMANDS)}; commands: "
              f"{', '.join(COMMANDS)}",
              file=sys.stderr)
        return 2
    from .processes import sigterm_as_interrupt

    sigterm = None
    try:
        # SIGTERM (kill, a scheduler's stop) stops a command as Ctrl-C does: runs saved, pool
        # workers stopped, how to resume said
        with warnings.catch_warnings(), sigterm_as_interrupt() as sigterm:
            # a warning for the user (a parameter taken from the defaults ...) without the
            # source line Python's default format adds
            warnings.showwarning = _show_warning
            return COMMANDS[command](argv)
    except (UserInputError, ParameterError) as exc:
        print(f"szdyn: error: {exc}", file=sys.stderr)
        return 2
    except SimulationError as exc:
        print(f"szdyn: simulation failed: {exc}", file=sys.stderr)
        return 1
    except (KeyboardInterrupt, SystemError) as exc:
        if not interrupted(exc):
            raise
        if sigterm is not None and sigterm.received:
            print("szdyn: terminated (SIGTERM)", file=sys.stderr)
            return 143      # 128 + SIGTERM, as a shell reports a process it ended
        print("szdyn: interrupted", file=sys.stderr)
        return 130


if __name__ == "__main__":
    raise SystemExit(main())
