"""Scenario ``thesis-fig10``: the thesis's three ramps under each wheel-band contact model,
checked against the thesis's findings (``szdyn.criteria``), with the stroke the slip costs.

Layout of the output directory::

    OUT/thesis-fig10/
        params.json                   parameter set used (contact_model set per model below)
        <model>/ramp_0.1pi.csv ...    one CSV per run (columns: szdyn.simulate.OUTPUT_UNITS)
        thesis-fig10.png              wheel, band, relative speed; one column per model
        thesis-fig10.json             criteria with measured values and pass/fail, stroke error
"""
from __future__ import annotations

import concurrent.futures as cf
import multiprocessing as mp
import os
import sys
import time
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from .criteria import evaluate_fig10
from .io import write_json
from .params import ParameterSet
from .processes import exit_with_parent
from .scenarios import thesis_fig10
from .simulate import OUTPUT_UNITS

CONTACT_MODELS = {"impact": 0, "coulomb": 1, "lugre": 2}
CRITERIA_LABELS = {
    "slip_at_constant_speed": "(a) slip at constant speed",
    "set_by_wheel_speed": "(b) set by wheel speed",
    "no_drop_after_ramp": "(c) no drop after ramp",
    "rises_with_wheel_speed": "(d) rises with wheel speed",
}


@dataclass(frozen=True)
class Integration:
    """Integrator settings shared by every run of a scenario."""

    method: str = "dopri5"
    dt: float = 1e-5
    rtol: float = 1e-5
    atol: float = 1e-8
    save_dt: float = 1e-3

    def describe(self) -> dict:
        if self.method == "dopri5":
            return {"method": self.method, "rtol": self.rtol, "atol": self.atol, "save_dt_s": self.save_dt}
        return {"method": self.method, "dt_s": self.dt, "save_dt_s": self.save_dt}


def _one_run(params_dict, model, spec, integ: Integration, csv_path):
    """Worker: simulate one (model, ramp) and write its CSV; returns a small summary."""
    from .simulate import simulate

    params = ParameterSet.from_dict(params_dict).replace(contact_model=CONTACT_MODELS[model])
    t0 = time.perf_counter()
    run = simulate(params, spec.drive, spec.t_end, method=integ.method, dt=integ.dt,
                   save_dt=integ.save_dt, rtol=integ.rtol, atol=integ.atol)
    run.to_csv(csv_path)
    return {"wall_time_s": time.perf_counter() - t0, "steps": int(run.trajectory.n_steps),
            "rejected_steps": int(run.trajectory.n_rejected)}


def stroke_error(outputs: dict, t_ramp: float, pitch: float) -> dict:
    """Stroke lost to slip during the hold (after the ramp): mm/s and mm per metre extended.

    ``pitch`` is the band helix pitch P_B (m): one band revolution extends the column by P_B.
    """
    t, q_w, q_b = outputs["t"], outputs["q_w"], outputs["q_b"]
    hold = t >= t_ramp
    th, dw, db = t[hold], q_w[hold] - q_w[hold][0], q_b[hold] - q_b[hold][0]
    duration = th[-1] - th[0]
    lost = pitch * (dw[-1] - db[-1]) / (2 * np.pi)        # m
    extended = pitch * db[-1] / (2 * np.pi)               # m
    return {
        "hold_wheel_speed_rad_s": float(np.mean(outputs["u_w"][hold])),
        "lost_mm_per_s": float(1e3 * lost / duration) if duration > 0 else 0.0,
        "lost_mm_per_m_extension": float(1e3 * lost / extended) if extended > 1e-9 else None,
        "note": None if extended > 1e-9 else "band did not extend during the hold",
    }


def run_fig10(params: ParameterSet, out: Path, *, models=tuple(CONTACT_MODELS), integ=Integration(),
              omega_hold: float = np.pi, t_hold: float = 3.0, workers: int | None = None,
              progress=True) -> dict:
    """Run the scenario for each contact model, write CSV/PNG/JSON into ``out``; return the JSON."""
    from .plots import fig10_grid

    specs = thesis_fig10(omega_hold=omega_hold, t_hold=t_hold)
    out.mkdir(parents=True, exist_ok=True)
    params.to_json(out / "params.json")
    jobs = [(m, s) for m in models for s in specs]
    for m in models:
        (out / m).mkdir(exist_ok=True)
    workers = workers or min(len(jobs), os.cpu_count() or 1)
    stats = {}
    t0 = time.perf_counter()
    # spawn: numba-compiled code and fork do not mix; workers load the on-disk compile cache.
    # Workers take Ctrl-C with the parent (a run is long) and end with it when it is killed.
    with cf.ProcessPoolExecutor(max_workers=workers, mp_context=mp.get_context("spawn"),
                                initializer=exit_with_parent) as pool:
        futs = {pool.submit(_one_run, params.to_dict(), m, s, integ, out / m / f"{s.name}.csv"): (m, s.name)
                for m, s in jobs}
        for k, fut in enumerate(cf.as_completed(futs), 1):
            stats[futs[fut]] = fut.result()
            if progress:
                m, name = futs[fut]
                el = time.perf_counter() - t0
                print(f"thesis-fig10: {k}/{len(jobs)} runs done ({m} {name}), {el:.0f} s elapsed, "
                      f"ETA {el / k * (len(jobs) - k):.0f} s", file=sys.stderr, flush=True)
    result = {"scenario": "thesis-fig10", "omega_hold_rad_s": omega_hold, "t_hold_s": t_hold,
              "integration": integ.describe(), "n_circles": params.n_circles,
              "parameters_file": "params.json", "csv_units": OUTPUT_UNITS, "models": {}}
    panels = {}
    for m in models:
        outputs = {s.name: read_outputs(out / m / f"{s.name}.csv") for s in specs}
        t_ramps = {s.name: s.t_ramp for s in specs}
        crit = evaluate_fig10(outputs, t_ramps)
        result["models"][m] = {
            "contact_model": CONTACT_MODELS[m],
            "criteria": crit,
            "all_passed": crit["all_passed"],
            "stroke_error": {s.name: stroke_error(outputs[s.name], s.t_ramp, params.geometry.pitch) for s in specs},
            "runs": [{"name": s.name, "label": s.label, "csv": f"{m}/{s.name}.csv", "t_ramp_s": s.t_ramp,
                      "t_end_s": s.t_end, **{k: round(v, 3) if isinstance(v, float) else v
                                             for k, v in stats[(m, s.name)].items()}} for s in specs],
        }
        panels[m] = [(s.label, outputs[s.name]) for s in specs]
    fig10_grid(panels, result, out / "thesis-fig10.png")
    write_json(out / "thesis-fig10.json", result)
    return result


def read_outputs(path) -> dict[str, np.ndarray]:
    """Read a run CSV back into columns (float arrays)."""
    with open(path) as fh:
        names = fh.readline().strip().split(",")
    data = np.loadtxt(path, delimiter=",", skiprows=1, ndmin=2)
    return {n: data[:, k] for k, n in enumerate(names)}
