"""Subprocess worker: time one derivation or the cold/warm compile of the RHS.

Run as ``python bench/_worker.py <task> [args]``; prints one JSON line on stdout.
Tasks: ``kernels``, ``full N_C N_R``, ``compile N_C``.
"""
from __future__ import annotations

import json
import sys
import time
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))


def _kernels():
    t0 = time.perf_counter()
    import derive.kernels as dk  # noqa: F401  (sympy import is part of the cost; timed separately)
    t_import = time.perf_counter() - t0
    t0 = time.perf_counter()
    dk.kernels()
    return {"import_s": t_import, "derive_s": time.perf_counter() - t0}


def _full(nc: int, nr: int):
    t0 = time.perf_counter()
    import derive.kernels as dk
    t_import = time.perf_counter() - t0
    t0 = time.perf_counter()
    fs = dk.full_system(nc, nr)
    t = time.perf_counter() - t0
    return {"import_s": t_import, "derive_s": t, "n_ops": int(sum(sm_count(e) for e in fs.forcing))}


def sm_count(e):
    import sympy as sm

    return sm.count_ops(e, visual=False)


def _compile(nc: int):
    import os

    t0 = time.perf_counter()
    import szdyn_generated.spiral_zipper as sz
    t_import = time.perf_counter() - t0
    import numpy as np

    from szdyn.defaults import default_parameters
    from szdyn.drive import Ramp

    ps = default_parameters(nc)
    p = ps.to_array()
    x = ps.initial_state()
    drive = Ramp(0.5, 2.0).to_array()
    out = np.empty_like(x)
    t0 = time.perf_counter()
    sz.rhs(0.1, x, p, drive, out)
    t_first = time.perf_counter() - t0
    t0 = time.perf_counter()
    sz.rhs(0.1, x, p, drive, out)
    t_second = time.perf_counter() - t0
    cache = os.environ.get("NUMBA_CACHE_DIR", "")
    n_files = sum(len(f) for _, _, f in os.walk(cache)) if cache else -1
    return {"import_s": t_import, "first_call_s": t_first, "second_call_s": t_second,
            "cache_files": n_files, "finite": bool(np.isfinite(out).all())}


def main(argv):
    task = argv[0]
    if task == "kernels":
        res = _kernels()
    elif task == "full":
        res = _full(int(argv[1]), int(argv[2]))
    elif task == "compile":
        res = _compile(int(argv[1]))
    else:
        raise SystemExit(f"unknown task {task!r}")
    print(json.dumps(res))


if __name__ == "__main__":
    main(sys.argv[1:])
