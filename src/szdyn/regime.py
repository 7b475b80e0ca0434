"""Regime map: where the impact model sticks, slips partially or slips fully.

model-notes section 5: the thesis's behaviour lives in a narrow band of roller interference
(``R_w + t_r + t_c - (R_bo - d)``). The map sweeps interference against a second parameter
(``b_c``, ``k_c`` or the slider load ``m_b``), drives each case up a ramp to a held wheel speed,
and classifies the hold by its mean band and wheel speeds (:func:`szdyn.criteria.classify_regime`:
stick if the relative speed is below 2 % of the wheel speed, full slip if the band turns at less
than 20 % of it, partial slip otherwise). It runs on the sweep engine, so it is parallel and
resumable, and writes ``regime_map.csv``/``.json``/``.png`` beside the sweep's own files.
"""
from __future__ import annotations

import csv
import io
import math
from pathlib import Path

from .criteria import classify_regime
from .errors import UserInputError
from .io import atomic_write_text, write_json
from .params import ParameterSet

#: Second axes offered by the CLI: name -> (values as factors of the default, log scale?)
SECOND_AXES = {"b_c": (0.1, 0.3, 1.0, 3.0), "k_c": (0.1, 0.3, 1.0, 3.0), "m_b": (0.25, 0.5, 1.0, 2.0, 4.0)}
REGIMES = ("stick", "partial_slip", "full_slip", "undefined", "failed")


def regime_spec(params: ParameterSet, interference_mm, second: str, second_values, *, omega_hold=math.pi,
                a=0.5 * math.pi, t_hold=2.0, hold_skip=0.5, method="dopri5", rtol=1e-5) -> dict:
    """The sweep spec (as a TOML-like dict) of a regime map around ``params``."""
    v = params.values
    offset = v["R_bo"] - v["d"] - v["t_c"] - v["t_r"]  # R_w = offset + interference
    t_ramp = omega_hold / a
    base_params = {k: float(x) for k, x in v.items() if k not in ("drive_mode",)}
    return {
        "description": f"regime map: interference x {second} (hold at {omega_hold:.4g} rad/s)",
        "base": {
            "t_end": t_ramp + t_hold, "n_circles": params.n_circles, "params": base_params,
            "drive": {"kind": "ramp_hold", "a": a, "t_ramp": t_ramp, "t_hold": t_hold},
            "integrator": {"method": method, "rtol": rtol, "atol": 1e-8, "save_dt": 1e-3},
        },
        "axes": {"R_w": [round(offset + 1e-3 * i, 12) for i in interference_mm],
                 second: [float(s) for s in second_values]},
        "metrics": {
            "hold_wheel": {"kind": "mean", "of": "u_w", "t_from": t_ramp + hold_skip},
            "hold_band": {"kind": "mean", "of": "u_b", "t_from": t_ramp + hold_skip},
            "hold_slip": {"kind": "mean", "of": "rel_speed", "t_from": t_ramp + hold_skip},
        },
    }


def classify_table(table_csv, params: ParameterSet, second: str) -> list[dict]:
    """Read the sweep's ``cases.csv`` and classify each case."""
    offset = params["R_bo"] - params["d"] - params["t_c"] - params["t_r"]
    rows = []
    with open(table_csv, newline="") as fh:
        for r in csv.DictReader(fh):
            status = r.get("status", "ok")
            wheel, band = _num(r.get("hold_wheel")), _num(r.get("hold_band"))
            regime = classify_regime(wheel, band) if status == "ok" else "failed"
            rows.append({"case_id": int(r["case_id"]), "interference_mm": round(1e3 * (float(r["R_w"]) - offset), 6),
                         second: float(r[second]), "hold_wheel_rad_s": wheel, "hold_band_rad_s": band,
                         "band_over_wheel": band / wheel if wheel and math.isfinite(band) else float("nan"),
                         "regime": regime, "status": status})
    return rows


def _num(s):
    try:
        return float(s)
    except (TypeError, ValueError):
        return float("nan")


def plot_regime_map(rows, second: str, default_point, path) -> Path:
    """Categorical map: interference (mm) on x, the second parameter on y (log), colour = regime,
    text = band/wheel speed ratio in percent; the default parameter set is marked."""
    from .plots import _pyplot, save_png

    plt = _pyplot()
    colors = {"stick": "#4c72b0", "partial_slip": "#55a868", "full_slip": "#c44e52",
              "undefined": "#999999", "failed": "#000000"}
    xs = sorted({r["interference_mm"] for r in rows})
    ys = sorted({r[second] for r in rows})
    fig, ax = plt.subplots(figsize=(2.6 + 0.75 * len(xs), 1.6 + 0.6 * len(ys)))
    for r in rows:
        i, j = xs.index(r["interference_mm"]), ys.index(r[second])
        ax.add_patch(plt.Rectangle((i - 0.5, j - 0.5), 1, 1, color=colors[r["regime"]], alpha=0.85))
        ratio = r["band_over_wheel"]
        ax.text(i, j, "" if not math.isfinite(ratio) else f"{100 * ratio:.0f}", ha="center", va="center",
                fontsize=7, color="white")
    dx, dy = default_point
    if dx in xs and dy in ys:
        ax.plot(xs.index(dx), ys.index(dy), marker="o", ms=22, mfc="none", mec="gold", mew=2.5)
    ax.set_xticks(range(len(xs)), [f"{x:.3g}" for x in xs], rotation=45)
    ax.set_yticks(range(len(ys)), [f"{y:.3g}" for y in ys])
    ax.set_xlim(-0.5, len(xs) - 0.5)
    ax.set_ylim(-0.5, len(ys) - 0.5)
    ax.set_xlabel("roller interference R_w + t_r + t_c - (R_bo - d) (mm)")
    from szdyn_generated.spiral_zipper import PARAM_DOCS

    ax.set_ylabel(f"{second} ({PARAM_DOCS[second][0]})")
    handles = [plt.Rectangle((0, 0), 1, 1, color=colors[k]) for k in ("stick", "partial_slip", "full_slip")]
    ax.legend(handles, ["stick", "partial slip", "full slip"], loc="upper left", fontsize=8,
              bbox_to_anchor=(1.01, 1.0))
    ax.set_title("numbers: band/wheel speed in the hold (%); ring: defaults", fontsize=8)
    fig.tight_layout()
    return save_png(fig, path)


def _check_sampling(spec: dict, params: ParameterSet) -> None:
    """The map's runs against the sampling limits, in the command's terms (the sweep spec would
    say it in tables of a spec the user never wrote)."""
    from szdyn_generated.spiral_zipper import state_size

    from .integrators import check_sampling

    base = spec["base"]
    drive, integ = base["drive"], base["integrator"]
    try:
        check_sampling(integ["method"], 1.0, integ["save_dt"], base["t_end"], n_states=state_size(params.n_circles))
    except ValueError as exc:
        raise UserInputError(f"the regime map's runs ramp at {drive['a']:g} rad/s^2 to --omega-hold "
                             f"{drive['a'] * drive['t_ramp']:g} rad/s and hold {drive['t_hold']:g} s "
                             f"({base['t_end']:g} s): {exc}") from None


def run_regime_map(params: ParameterSet, out: Path, *, second="b_c", interference_mm=None, factors=None,
                   workers=None, progress=True, **spec_kw) -> dict:
    """Run (or resume) the regime map sweep into ``out``; write the map's CSV, JSON and PNG."""
    from .sweep import csv_cell, run_sweep
    from .sweep_spec import SpecError, parse_spec

    if second not in SECOND_AXES:
        raise ValueError(f"second axis must be one of {sorted(SECOND_AXES)}, got {second!r}")
    default_i = round(1e3 * params.interference, 6)
    if interference_mm is None:
        interference_mm = sorted({round(default_i + k * 0.02, 9) for k in range(-4, 5)})
    factors = SECOND_AXES[second] if factors is None else factors
    if params[second] == 0:
        raise UserInputError(f"the regime map sweeps {second} as factors {', '.join(map(str, factors))} of its "
                             f"value, which is 0 here (--set or --params): every case would be the same; "
                             "give it a nonzero value or choose another --second")
    second_values = sorted({float(params[second] * f) for f in factors})
    spec_dict = regime_spec(params, interference_mm, second, second_values, **spec_kw)
    _check_sampling(spec_dict, params)
    try:
        spec = parse_spec(spec_dict)
    except SpecError as exc:
        # the spec is the map's own, built around the given parameters: say which of them put
        # a case out of bounds, not a table the user never wrote
        raise UserInputError(
            f"the regime map around R_w = {params['R_w']:g} m, {second} = {params[second]:g} sweeps "
            f"the interference over {min(interference_mm):g}..{max(interference_mm):g} mm and {second} "
            f"over {min(second_values):g}..{max(second_values):g}; a case is out of bounds: {exc}") from None
    result = run_sweep(spec, out, workers=workers, progress=progress, plot=False)
    rows = classify_table(result.table, params, second)
    cols = ["case_id", "interference_mm", second, "hold_wheel_rad_s", "hold_band_rad_s", "band_over_wheel",
            "regime", "status"]
    # a failed or undefined case has no speeds: an empty cell (as in the sweep's cases.csv), so
    # that one diverged case does not stop the map from being written
    buf = io.StringIO()
    w = csv.writer(buf, lineterminator="\n")
    w.writerow(cols)
    w.writerows([csv_cell(r[c]) for c in cols] for r in rows)
    atomic_write_text(out / "regime_map.csv", buf.getvalue())
    counts = {k: sum(r["regime"] == k for r in rows) for k in REGIMES}
    summary = {
        "second_axis": second, "default": {"interference_mm": default_i, second: float(params[second])},
        "classification": {"stick": "hold rel. speed < 2 % of wheel speed",
                           "full_slip": "hold band speed < 20 % of wheel speed", "partial_slip": "otherwise"},
        "counts": counts,
        "cases": [{k: (None if isinstance(v, float) and not math.isfinite(v) else v) for k, v in r.items()}
                  for r in rows],
    }
    write_json(out / "regime_map.json", summary)
    plot_regime_map(rows, second, (default_i, float(params[second])), out / "regime_map.png")
    return summary
