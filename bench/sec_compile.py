"""Section 2: cold compile of the generated RHS with an empty Numba cache, then warm."""
from __future__ import annotations

import os
import shutil
import tempfile

from _common import fmt_time, log, table
from sec_derivation import run_worker


def run(quick: bool) -> dict:
    cache = tempfile.mkdtemp(prefix="szdyn-bench-numba-cache-")
    try:
        env = dict(os.environ, NUMBA_CACHE_DIR=cache)
        log("2/6 cold compile (empty NUMBA_CACHE_DIR)")
        cold, cold_wall = run_worker(["compile", 100], env=env)
        log("2/6 warm start (same cache dir)")
        warm, warm_wall = run_worker(["compile", 100], env=env)
    finally:
        shutil.rmtree(cache, ignore_errors=True)
    return {"cold": cold, "cold_wall": cold_wall, "warm": warm, "warm_wall": warm_wall}


def report(res: dict) -> str:
    c, w = res["cold"], res["warm"]
    rows = [
        ["cold (empty cache)", fmt_time(c["import_s"]), fmt_time(c["first_call_s"]), fmt_time(c["second_call_s"]),
         fmt_time(res["cold_wall"]), c["cache_files"]],
        ["warm (same cache dir)", fmt_time(w["import_s"]), fmt_time(w["first_call_s"]), fmt_time(w["second_call_s"]),
         fmt_time(res["warm_wall"]), w["cache_files"]],
    ]
    ratio = (c["import_s"] + c["first_call_s"]) / (w["import_s"] + w["first_call_s"])
    return "\n".join([
        "## 2. Cold compile",
        "",
        "A fresh interpreter with `NUMBA_CACHE_DIR=<new tmpdir>` imports `szdyn_generated.spiral_zipper` "
        "and calls `rhs` once (N_c = 100, default parameters); then the same with the now-populated cache.",
        "",
        table(["run", "import", "1st rhs call", "2nd rhs call", "process wall", "cache files after"], rows),
        "",
        f"Cold / warm (import + first call): **{ratio:.0f}x**.",
    ])
