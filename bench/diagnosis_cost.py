"""Cost of the issue's diagnosis case: three 10 s recordings on 2 cores (issue 5, "Cost").

Usage::

    python bench/diagnosis_cost.py --work DIR [--effect load_lift] [--seed 31] [--diagnose-args "--phase-steps 2"]
    python bench/diagnosis_cost.py --work DIR --effect all --seed 39   # every effect and none
    python bench/diagnosis_cost.py --work DIR --effect all --seed 92 --amplitude-factor 1.5

Writes three 10 s recordings at one load (1 kg; ramps to +pi, +2 pi and -pi rad/s, each held to
10 s) with one concealed effect, runs ``python -m szdyn.run diagnose`` on them as a user would
(CLI defaults, no ``[split]``: one recording is held out) and prints the wall time, the verdict,
the effect parameter against the truth and the held-out RMSE before and after, also written to
``DIR/cost.json``. Run it on an otherwise idle machine: the time is the measurement.

With several effects (``--effect a,b`` or ``all``: ``none`` and every effect of
``szdyn.synth.EFFECTS``) each runs in ``DIR/EFFECT`` in turn, one already finished (its
``cost.json``) is kept, and ``DIR/cost-summary.md`` with a JSON twin scores them: the answer
against the concealed effect, the parameter error (``diagnosis_grid.param_error``), the held-out
gain and the held-out error before in noise floors, model runs and seconds. This is the issue's
configuration, on one load; the grids (``diagnosis_grid.py``) have two.

``--amplitude-factor F`` conceals each effect at F times the top of its realistic range
(``szdyn.synth.EFFECTS[...].range``) instead of a drawn amplitude, with a seeded random sign for
the signed effects: a test of amplitudes the generator never draws (F > 1) or of the detection
limit (F < 1). The factor is recorded in each ``cost.json`` and a summary takes one factor.
"""
from __future__ import annotations

import argparse
import json
import math
import shlex
import subprocess
import sys
import time
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT / "src"))

sys.path.insert(0, str(ROOT / "bench"))

from szdyn.io import atomic_write_text, write_json  # noqa: E402
from szdyn.synth import EFFECTS, RampSpec, synthesize  # noqa: E402
from szdyn.diagnose.candidates import CANDIDATES  # noqa: E402
from diagnosis_grid import param_error  # noqa: E402

#: Three 10 s recordings: the grid's ramps (``szdyn.synth.DEFAULT_RAMPS``), each held longer.
RAMPS = (RampSpec("up_pi", 0.5 * math.pi, 2.0, 8.0),
         RampSpec("up_2pi", math.pi, 2.0, 8.0),
         RampSpec("down_pi", -0.4 * math.pi, 2.5, 7.5))


def amplitude_at(effect: str, factor: float, seed: int) -> float:
    """``factor`` times the top of ``effect``'s realistic range, negative for a signed effect when
    a draw seeded by ``seed`` and the effect's place in the library says so."""
    e = EFFECTS[effect]
    rng = np.random.default_rng([seed, list(EFFECTS).index(effect)])
    sign = -1.0 if e.signed and rng.random() < 0.5 else 1.0
    return sign * factor * e.range[1]


def run_case(work: Path, effect: str, seed: int, diagnose_args: str,
             amplitude_factor: float | None = None) -> dict:
    """Generate (once) and diagnose one case in ``work``; its result, also in ``work/cost.json``.
    ``amplitude_factor``: see :func:`amplitude_at` (default: the amplitude drawn by the seed)."""
    data, out = work / "data", work / "diagnosis"
    amp = None if amplitude_factor is None or effect == "none" else \
        amplitude_at(effect, amplitude_factor, seed)
    if not (data / "truth.json").is_file():
        synthesize(data, effect, amplitude=amp, seed=seed, loads_kg=(1.0,), ramps=RAMPS, dt=5e-5,
                   verbose=False)
    else:   # recordings made before: only if they are the ones asked for
        made = json.loads((data / "truth.json").read_text())
        same = made.get("effect") == effect and made.get("seed") == seed and (
            effect == "none" or (made.get("amplitude_drawn") if amp is None else made.get("amplitude") == amp))
        if not same:
            raise SystemExit(f"{data / 'truth.json'}: recordings of {made.get('effect')} (seed {made.get('seed')}, "
                             f"amplitude {made.get('amplitude')}, drawn: {made.get('amplitude_drawn')}), not the "
                             f"{effect} asked for (seed {seed}, amplitude {'drawn' if amp is None else amp}); "
                             "use another --work")
    # the split is the diagnosis's own choice (no [split] in the manifest): drop the generator's
    man = data / "manifest.toml"
    text = man.read_text()
    if "[split]" in text:
        lines = text.splitlines()
        k = lines.index("[split]")
        man.write_text("\n".join(lines[:k] + lines[k + 2:]) + "\n")
    t = time.perf_counter()
    subprocess.run([sys.executable, "-m", "szdyn.run", "diagnose", str(man), "--out", str(out),
                    *diagnose_args.split()], check=True)
    seconds = time.perf_counter() - t
    truth = json.loads((data / "truth.json").read_text())
    d = json.loads((out / "diagnosis.json").read_text())
    res = {"effect": effect, "seed": seed, "seconds": round(seconds, 1), "selected": d["selected"],
           "verdict": d["verdict"], "heldout_before": d["fit"]["before"]["heldout_rmse"],
           "heldout_after": d["fit"]["after"]["heldout_rmse"], "model_runs": d["cost"]["model_runs"],
           "noise_floor": d["noise_floor"], "diagnose_args": diagnose_args,
           "amplitude": truth.get("amplitude"), "amplitude_factor": amplitude_factor}
    if effect != "none":
        prim = CANDIDATES[effect].primary
        tv = {**truth["effect_parameters"], **truth["effect_sensor"]}.get(prim)
        e = next((x for x in d["effects"] if x["id"] == effect and x.get("primary")), None)
        res.update({"truth_param": tv, "fitted_param": e["primary"]["value"] if e else None})
    write_json(work / "cost.json", res)
    return res


def score(res: dict, noise_floor: float | None = None) -> dict:
    """One case's result with ``correct``, ``param_error`` (named cases), ``heldout_ratio`` and
    ``heldout_over_floor`` added; ``noise_floor`` (rad/s) where the result lacks it (a
    ``cost.json`` written before it was recorded)."""
    eff = res["effect"]
    floor = res.get("noise_floor", noise_floor)
    out = dict(res, noise_floor=floor,
               correct=(res["selected"] == [] if eff == "none" else res["selected"] == [eff]))
    if out["correct"] and eff != "none" and res.get("truth_param") is not None \
            and res.get("fitted_param") is not None:
        out["param_error"] = param_error(eff, res["truth_param"], res["fitted_param"])
    if res["heldout_before"] and res["heldout_after"]:
        out["heldout_ratio"] = res["heldout_before"] / res["heldout_after"]
    if res["heldout_before"] and floor:
        out["heldout_over_floor"] = res["heldout_before"] / floor
    return out


def summary_md(rows: list, seed: int) -> str:
    """The cases of one seed as a markdown table (``rows``: :func:`score`'s, in the order run,
    all with the same ``diagnose_args`` and ``amplitude_factor``)."""
    def f(x, fmt):
        return "-" if x is None else format(x, fmt)

    eff = [r for r in rows if r["effect"] != "none"]
    nulls = [r for r in rows if r["effect"] == "none"]
    run = [r["effect"] for r in rows]
    diagnose_args = rows[0].get("diagnose_args", "") if rows else ""
    which = "every effect" if set(run) == {"none", *EFFECTS} else ", ".join(run)
    factor = rows[0].get("amplitude_factor") if rows else None
    extra = f" --diagnose-args {shlex.quote(diagnose_args)}" if diagnose_args else ""
    if factor is not None:
        extra += f" --amplitude-factor {factor:g}"
    amp = ("each effect drawn by the seed in its realistic range" if factor is None else
           f"each effect at {factor:g} times the top of its realistic range (column amplitude, "
           "in the units of `szdyn.synth`'s table)")
    L = [f"# The issue's cost configuration, {which} (seed {seed}"
         f"{'' if factor is None else f', amplitudes at {factor:g}x the top of the range'})", "",
         f"Generated by `python bench/diagnosis_cost.py --work DIR --seed {seed} --effect "
         f"{','.join(run)}{extra}`: three 10 s recordings at one load (1 kg; ramps to +pi, +2 pi "
         f"and -pi rad/s), {amp}, one held out by the diagnosis's own split, "
         f"{'diagnose ' + diagnose_args if diagnose_args else 'the CLI defaults'}. Seconds are "
         "wall time on 2 cores (comparable only on an idle machine).", "",
         f"Named: {sum(r['correct'] for r in eff)}/{len(eff)}; null cases with no effect named: "
         f"{sum(r['correct'] for r in nulls)}/{len(nulls)}.", "",
         "| concealed | amplitude | answer | parameter error | held-out before -> after (rad/s) | gain "
         "| before, noise floors | model runs | seconds |", "|---|---|---|---|---|---|---|---|---|"]
    for r in rows:
        ans = ", ".join(f"`{k}`" for k in r["selected"]) or r["verdict"]
        if not r["correct"]:
            ans = f"**{ans}**"
        L.append(f"| {r['effect']} | {f(r.get('amplitude'), '.4g')} | {ans} | {f(r.get('param_error'), '.1%').replace('%', ' %')} "
                 f"| {r['heldout_before']:.4g} -> {r['heldout_after']:.4g} | {f(r.get('heldout_ratio'), '.1f')}x "
                 f"| {f(r.get('heldout_over_floor'), '.1f')} | {r['model_runs']} | {r['seconds']:.0f} |")
    return "\n".join(L) + "\n"


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--work", type=Path, required=True)
    ap.add_argument("--effect", default="load_lift",
                    help="an effect id or none, several comma-separated, or all (none and every effect)")
    ap.add_argument("--seed", type=int, default=31)
    ap.add_argument("--diagnose-args", default="", help="extra diagnose options (default: none, the CLI defaults)")
    ap.add_argument("--amplitude-factor", type=float, default=None, metavar="F",
                    help="conceal each effect at F times the top of its realistic range "
                         "(default: the amplitude drawn by the seed)")
    args = ap.parse_args(argv)
    if args.amplitude_factor is not None and not (math.isfinite(args.amplitude_factor)
                                                  and args.amplitude_factor > 0):
        ap.error(f"--amplitude-factor must be a finite number > 0, got {args.amplitude_factor:g}")
    effects = ["none", *EFFECTS] if args.effect == "all" else [e.strip() for e in args.effect.split(",")]
    bad = [e for e in effects if e != "none" and e not in EFFECTS]
    if bad:
        ap.error(f"unknown effect(s) {', '.join(bad)}; known: none, {', '.join(EFFECTS)}, all")
    if len(effects) == 1:
        print(json.dumps(run_case(args.work, effects[0], args.seed, args.diagnose_args,
                                  args.amplitude_factor), indent=1))
        return 0
    rows = []
    for eff in effects:
        work = args.work / eff
        done = work / "cost.json"
        res = json.loads(done.read_text()) if done.is_file() else \
            run_case(work, eff, args.seed, args.diagnose_args, args.amplitude_factor)
        if res.get("diagnose_args", "") != args.diagnose_args:    # one summary, one set of options
            raise SystemExit(f"{done}: this case ran with --diagnose-args {res.get('diagnose_args', '')!r}, "
                             f"not {args.diagnose_args!r}; give those options again, or another --work")
        if res.get("amplitude_factor") != args.amplitude_factor:
            raise SystemExit(f"{done}: this case ran with --amplitude-factor {res.get('amplitude_factor')}, "
                             f"not {args.amplitude_factor}; give that factor again, or another --work")
        truth = work / "data" / "truth.json"
        if "amplitude" not in res and truth.is_file():   # a cost.json from before it was recorded
            res["amplitude"] = json.loads(truth.read_text()).get("amplitude")
        floor = None
        diag = work / "diagnosis" / "diagnosis.json"
        if "noise_floor" not in res and diag.is_file():   # a cost.json from before it was recorded
            floor = json.loads(diag.read_text())["noise_floor"]
        rows.append(score(res, floor))
        print(f"{eff}: {', '.join(res['selected']) or res['verdict']} ({res['seconds']:.0f} s)", flush=True)
    md = summary_md(rows, args.seed)
    write_json(args.work / "cost-summary.json", {"seed": args.seed, "diagnose_args": args.diagnose_args, "cases": rows})
    atomic_write_text(args.work / "cost-summary.md", md)
    print(md)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
