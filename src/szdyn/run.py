"""``python -m szdyn.run``: run scenarios of the Spiral Zipper model.

Without a command it runs the thesis scenario (``thesis-fig10``) on the built-in defaults and
writes one CSV per run, a Fig. 10-style PNG, the parameters used and a JSON summary.
"""
from __future__ import annotations

import argparse
import json
import math
import sys
import time
from pathlib import Path

from .errors import ParameterError, SimulationError, UserInputError
from .io import write_json

METHODS = ("rk4", "heun", "dopri5")
CONTACT_MODELS = {"impact": 0, "coulomb": 1, "lugre": 2}


def _parse_set(items) -> dict[str, float]:
    """Parse ``--set NAME=VALUE`` (float literals only; nothing is evaluated)."""
    out = {}
    for item in items or ():
        name, sep, value = item.partition("=")
        if not sep or not name.strip():
            raise UserInputError(f"--set expects NAME=VALUE, got {item!r}")
        try:
            out[name.strip()] = float(value)
        except ValueError:
            raise UserInputError(f"--set {name.strip()}: expected a number, got {value!r}") from None
    return out


def _positive_float(text: str) -> float:
    try:
        v = float(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"expected a number, got {text!r}") from None
    if not (math.isfinite(v) and v > 0):
        raise argparse.ArgumentTypeError(f"expected a positive finite number, got {text!r}")
    return v


def _positive_int(text: str) -> int:
    try:
        v = int(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"expected a whole number, got {text!r}") from None
    if v <= 0:
        raise argparse.ArgumentTypeError(f"expected a positive whole number, got {text!r}")
    return v


def build_parser() -> argparse.ArgumentParser:
    from .scenarios import SCENARIOS

    ap = argparse.ArgumentParser(
        prog="python -m szdyn.run",
        description="Simulate the Spiral Zipper (impact-friction model of Lee 2021). "
                    "Writes CSV per run, a PNG like the thesis's Fig. 10, params.json and summary.json.",
    )
    ap.add_argument("--scenario", default="thesis-fig10", choices=sorted(SCENARIOS),
                    help="scenario to run (default: %(default)s)")
    ap.add_argument("--out", type=Path, default=Path("results"), help="output directory (default: %(default)s)")
    ap.add_argument("--params", type=Path, help="parameter JSON file (as written to OUT/params.json); default: built-in defaults")
    ap.add_argument("--set", action="append", metavar="NAME=VALUE", help="override one parameter (SI units); repeatable")
    ap.add_argument("--n-circles", type=_positive_int, help="number of small circles N_c (default: from the parameter set)")
    ap.add_argument("--contact", choices=tuple(CONTACT_MODELS), default=None,
                    help="wheel-band transmission: impact (thesis), coulomb or lugre friction counter-models "
                         "(default: the parameter set's contact_model)")
    ap.add_argument("--method", choices=METHODS, default="dopri5",
                    help="integrator: heun (thesis's modified Euler), rk4 (fixed step), dopri5 (adaptive); default %(default)s")
    ap.add_argument("--dt", type=_positive_float, default=1e-5, help="fixed step for heun/rk4 in s (default %(default)s)")
    ap.add_argument("--rtol", type=_positive_float, default=1e-5, help="dopri5 relative tolerance (default %(default)s)")
    ap.add_argument("--atol", type=_positive_float, default=1e-8, help="dopri5 absolute tolerance (default %(default)s)")
    ap.add_argument("--save-dt", type=_positive_float, default=1e-3, help="output sampling interval in s (default %(default)s)")
    ap.add_argument("--omega-hold", type=_positive_float, default=math.pi,
                    help="wheel speed at the end of each ramp, rad/s (default pi)")
    ap.add_argument("--t-hold", type=_positive_float, default=3.0, help="hold duration after each ramp, s (default %(default)s)")
    ap.add_argument("--quiet", action="store_true", help="no progress output")
    return ap


def load_parameters(args):
    from .defaults import default_parameters
    from .params import ParameterSet

    if args.params is not None:
        if not args.params.is_file():
            raise UserInputError(f"--params: no such file: {args.params}")
        params = ParameterSet.from_json(args.params)
    else:
        params = default_parameters()
    changes = _parse_set(args.set)
    if args.n_circles is not None:
        changes["n_circles"] = args.n_circles
    if args.contact is not None:
        changes["contact_model"] = CONTACT_MODELS[args.contact]
    return params.replace(**changes) if changes else params


def simulate_command(argv) -> int:
    from .plots import fig10
    from .progress import Progress
    from .scenarios import SCENARIOS
    from .simulate import OUTPUT_UNITS, simulate

    args = build_parser().parse_args(argv)
    params = load_parameters(args)
    runs = SCENARIOS[args.scenario](omega_hold=args.omega_hold, t_hold=args.t_hold)
    out = args.out / args.scenario
    out.mkdir(parents=True, exist_ok=True)
    params.to_json(out / "params.json")
    summary = {"scenario": args.scenario, "method": args.method,
               "dt": args.dt if args.method != "dopri5" else None,
               "rtol": args.rtol if args.method == "dopri5" else None,
               "atol": args.atol if args.method == "dopri5" else None,
               "n_circles": params.n_circles, "csv_units": OUTPUT_UNITS, "runs": []}
    plotted = []
    for spec in runs:
        t0 = time.perf_counter()
        run = simulate(params, spec.drive, spec.t_end, method=args.method, dt=args.dt, save_dt=args.save_dt,
                       rtol=args.rtol, atol=args.atol, progress=Progress(spec.name, enabled=not args.quiet))
        wall = time.perf_counter() - t0
        csv = out / f"{spec.name}.csv"
        run.to_csv(csv)
        o = run.outputs
        hold = o["t"] >= spec.t_ramp
        summary["runs"].append({
            "name": spec.name, "label": spec.label, "csv": csv.name, "t_end_s": spec.t_end,
            "t_ramp_s": spec.t_ramp, "wall_time_s": round(wall, 3), "steps": int(run.trajectory.n_steps),
            "rejected_steps": int(run.trajectory.n_rejected),
            "hold_mean_wheel_speed_rad_s": float(o["u_w"][hold].mean()),
            "hold_mean_band_speed_rad_s": float(o["u_b"][hold].mean()),
            "hold_mean_rel_speed_rad_s": float(o["rel_speed"][hold].mean()),
            "stroke_lost_at_end_mm": float(1e3 * o["stroke_lost"][-1]),
            "mean_contacts": float(o["contacts"].mean()),
        })
        plotted.append((spec.label, o))
        if not args.quiet:
            print(f"{spec.name}: {spec.t_end:.1f} s simulated in {wall:.1f} s -> {csv}", file=sys.stderr)
    png = fig10(plotted, out / f"{args.scenario}.png")
    write_json(out / "summary.json", summary)
    print(f"wrote {png} and {len(runs)} CSV files in {out}")
    return 0


COMMANDS = {"simulate": simulate_command}


def main(argv=None) -> int:
    argv = list(sys.argv[1:] if argv is None else argv)
    command = "simulate"
    if argv and argv[0] in COMMANDS:
        command = argv.pop(0)
    try:
        return COMMANDS[command](argv)
    except (UserInputError, ParameterError) as exc:
        print(f"szdyn: error: {exc}", file=sys.stderr)
        return 2
    except SimulationError as exc:
        print(f"szdyn: simulation failed: {exc}", file=sys.stderr)
        return 1
    except KeyboardInterrupt:
        print("szdyn: interrupted", file=sys.stderr)
        return 130


if __name__ == "__main__":
    raise SystemExit(main())
