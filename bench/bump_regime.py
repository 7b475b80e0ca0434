"""Which seeds' base truths keep the 0.5 kg band bumping, and how the diagnosis fared on each kind.

Usage::

    python bench/bump_regime.py [--work bump-regime-work] [--out docs/bump-regime-by-seed.json]

For each seed with figures of record (``bench/oos_summary.py``), synth writes the seed's
slider_stribeck recordings in the default protocol (as ``bench/diagnosis_grid.py`` does; every
effect of a seed shares its base coefficients), and ``bench/bump_sensitivity.py
--without-effect`` runs the seed's base truth on the 0.5 kg forward runs with k_c 1 % off. The
seed's *bump sensitivity* is the fast part of that change in the smoothed band speed (its RMS
beyond the 0.5 s running mean, in quadrature), the worse of the two runs, rad/s. A seed is
*bumping* above :data:`THRESHOLD` (the values fall in two groups far either side of it:
docs/DIAGNOSIS-DESIGN.md, "Seed 64's 0.5 kg runs"). The named cases of the seeds' figures of
record are then counted per effect and kind, early (seeds up to 27) and late. Resumable: the
recordings and each seed's measurement are kept in ``--work``, and a seed already in ``--out``
keeps its value there unless ``--work`` holds its measurement. This reads ``truth.json``: it is
an analysis of the benchmark, not part of a diagnosis.
"""
from __future__ import annotations

import argparse
import json
import math
import sys
from collections import defaultdict
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT / "src"))
sys.path.insert(0, str(ROOT / "bench"))

import bump_sensitivity  # noqa: E402
import diagnosis_grid  # noqa: E402
import oos_summary  # noqa: E402
from szdyn.io import write_json  # noqa: E402

#: rad/s; a seed's bump sensitivity above it is "bumping"
THRESHOLD = 0.01
#: the last seed of the early period (the code of seeds 13-27 named fewer effects)
EARLY_LAST = 27
RECORDINGS = ("load0p5kg_up_pi", "load0p5kg_up_2pi")


def sensitivity(measured: dict) -> float:
    """A seed's bump sensitivity (rad/s) from ``bump_sensitivity.py --json`` output: the largest
    fast part of the k_c x1.01 change over its recordings."""
    return max(math.sqrt(max(c["rms"] ** 2 - c["slow_rms"] ** 2, 0.0))
               for c in (r["change"][bump_sensitivity.KC_LABEL] for r in measured["recordings"]))


def tally(cases: list, bump: dict, threshold: float = THRESHOLD) -> tuple:
    """Named / cases per (effect, period) and per period, split by kind of base truth.

    Returns
    -------
    (dict, dict)
        ``"effect/period" -> counts`` and ``period -> counts``, each counts a dict with
        ``bumping_named``, ``bumping_cases``, ``calm_named``, ``calm_cases``.
    """
    def counts():
        return {"bumping_named": 0, "bumping_cases": 0, "calm_named": 0, "calm_cases": 0}
    per, total = defaultdict(counts), defaultdict(counts)
    for c in cases:
        if c["effect"] == "none" or c["seed"] not in bump:
            continue
        kind = "bumping" if bump[c["seed"]] > threshold else "calm"
        period = "early" if c["seed"] <= EARLY_LAST else "late"
        for t in (per[f"{c['effect']}/{period}"], total[period]):
            t[f"{kind}_cases"] += 1
            t[f"{kind}_named"] += bool(c["correct"])
    return dict(sorted(per.items())), dict(sorted(total.items()))


def measure(work: Path, seed: int) -> dict:
    """The seed's base-truth measurement, made once and kept in ``work``."""
    out = work / f"ne{seed}.json"
    if not out.is_file():
        case = work / f"slider_stribeck-{seed}"
        if not (case / "data" / "truth.json").is_file():
            diagnosis_grid.synthesize(case / "data", "slider_stribeck", seed)
        bump_sensitivity.main([str(case), *RECORDINGS, "--without-effect", "--json", str(out)])
    return json.loads(out.read_text())


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--work", type=Path, default=Path("bump-regime-work"))
    ap.add_argument("--out", type=Path, default=ROOT / "docs" / "bump-regime-by-seed.json")
    args = ap.parse_args(argv)
    args.work.mkdir(parents=True, exist_ok=True)
    cases = oos_summary.load(oos_summary.record())
    seeds = sorted({c["seed"] for c in cases if c["effect"] != "none"})
    # a seed measured in an earlier run keeps its value from --out (the measurement is
    # deterministic: the seed's synth recordings and one model run each), so that a new seed
    # costs its own measurement only, even where the earlier --work is gone
    earlier = {}
    if args.out.is_file():
        earlier = {int(s): float(v) for s, v in json.loads(args.out.read_text())["fast_kc_rad_s"].items()}
    bump = {}
    for k, s in enumerate(seeds, 1):
        kept = s in earlier and not (args.work / f"ne{s}.json").is_file()
        bump[s] = earlier[s] if kept else sensitivity(measure(args.work, s))
        print(f"[{k}/{len(seeds)}] seed {s}: {bump[s]:.4f} rad/s" + (f" (from {args.out})" if kept else ""),
              file=sys.stderr, flush=True)
    per, total = tally(cases, bump)
    write_json(args.out, {
        "what": "Per seed: the bump sensitivity of the seed's base truth (its perturbed coefficients, no "
                "concealed effect) on the default protocol's 0.5 kg forward runs: the fast part (RMS of the "
                "change minus its 0.5 s running mean, in quadrature) of the model's smoothed band speed when "
                "k_c moves 1 %, the worse of load0p5kg_up_pi and load0p5kg_up_2pi, rad/s (bench/bump_regime.py). "
                f"'bumping': above {THRESHOLD} rad/s. Tallies: named / cases of the seeds' figures of record "
                f"(bench/oos_summary.py), early = seeds 13-{EARLY_LAST}, late = {EARLY_LAST + 1} on.",
        "fast_kc_rad_s": {str(s): v for s, v in bump.items()},
        "bumping_threshold_rad_s": THRESHOLD,
        "tally": per,
        "total": total})
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
