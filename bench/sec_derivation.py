"""Section 1: derivation time (kernel derivation vs the unrolled KanesMethod oracle)."""
from __future__ import annotations

import json
import os
import subprocess
import sys
import tempfile
import time

from _common import ROOT, fit_loglog, fmt_time, log, table

WORKER = os.path.join(os.path.dirname(os.path.abspath(__file__)), "_worker.py")


def run_worker(args, env=None, timeout=900):
    """Run ``_worker.py args`` in a fresh interpreter; returns (parsed JSON, wall seconds)."""
    t0 = time.perf_counter()
    r = subprocess.run([sys.executable, WORKER, *map(str, args)], cwd=ROOT, env=env,
                       capture_output=True, text=True, timeout=timeout)
    wall = time.perf_counter() - t0
    if r.returncode != 0:
        raise RuntimeError(f"worker {args} failed:\n{r.stderr[-2000:]}")
    return json.loads(r.stdout.strip().splitlines()[-1]), wall


def run(quick: bool) -> dict:
    log("1/6 derivation: python -m derive")
    with tempfile.TemporaryDirectory(prefix="szdyn-bench-derive-") as tmp:
        t0 = time.perf_counter()
        r = subprocess.run([sys.executable, "-m", "derive", "--out", tmp], cwd=ROOT,
                           capture_output=True, text=True, timeout=900)
        t_cli = time.perf_counter() - t0
        if r.returncode != 0:
            raise RuntimeError(f"python -m derive failed:\n{r.stderr[-2000:]}")
        files = sorted(os.listdir(tmp))
    kern, _ = run_worker(["kernels"])
    full = []
    for nc in (1, 2, 3, 4):
        log(f"1/6 derivation: full_system({nc}, n_rollers=2)")
        res, _ = run_worker(["full", nc, 2])
        full.append((nc, res))
    return {"cli_s": t_cli, "files": files, "kernels": kern, "full": full}


def report(res: dict) -> str:
    k = res["kernels"]
    rows = [[nc, fmt_time(k["derive_s"]), fmt_time(r["derive_s"]), f"{r['derive_s'] / k['derive_s']:.1f}x",
             r["n_ops"]] for nc, r in res["full"]]
    slope, _ = fit_loglog([nc for nc, _ in res["full"]], [r["derive_s"] for _, r in res["full"]])
    return "\n".join([
        "## 1. Derivation time",
        "",
        f"`python -m derive --out <tmpdir>` (subprocess, wall, including interpreter start and SymPy "
        f"import; writes {', '.join(res['files'])}): **{fmt_time(res['cli_s'])}**.",
        "",
        f"Kernel derivation `derive.kernels.kernels()` alone (fresh interpreter, after a "
        f"{fmt_time(k['import_s'])} import): **{fmt_time(k['derive_s'])}**, independent of N_c and N_r "
        "(one generic circle and one generic roller-circle contact).",
        "",
        "Unrolled oracle `derive.kernels.full_system(N_c, n_rollers=2)` (one `KanesMethod` on the whole "
        "system; each N_c in a fresh interpreter, import excluded):",
        "",
        table(["N_c", "kernels() (any N_c)", "full_system(N_c, 2)", "full / kernels", "count_ops(forcing)"], rows),
        "",
        f"Fitted growth of the unrolled derivation: time ∝ N_c^{slope:.2f} over N_c = 1..4 (N_r = 2); "
        "the N_r = 8 baseline in section 3 grows further with the number of roller-circle pairs. "
        "(N_c = 3 is slower than N_c = 4 in every run: hinge angles 2 pi i / 3 bring sqrt(3) "
        "constants into the unrolled expressions, while multiples of pi/2 give 0 and ±1.)",
    ])
