"""Shared helpers of the benchmark sections: progress, timing, machine description."""
from __future__ import annotations

import datetime as _dt
import math
import os
import platform
import sys
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]


def log(msg: str) -> None:
    """Progress line on stderr (the report goes to a file)."""
    print(f"[bench {time.strftime('%H:%M:%S')}] {msg}", file=sys.stderr, flush=True)


def best_of(fn, repeat: int = 5, number: int = 1) -> float:
    """Smallest wall time of ``repeat`` runs of ``number`` calls of ``fn()``, per call (s)."""
    best = math.inf
    for _ in range(repeat):
        t0 = time.perf_counter()
        for _ in range(number):
            fn()
        best = min(best, (time.perf_counter() - t0) / number)
    return best


def autorange(fn, min_time: float = 0.2) -> int:
    """Number of calls of ``fn()`` that take at least ``min_time`` s (powers of 2)."""
    n = 1
    while True:
        t0 = time.perf_counter()
        for _ in range(n):
            fn()
        if time.perf_counter() - t0 >= min_time or n >= 1 << 24:
            return n
        n *= 2


def fit_loglog(xs, ys) -> tuple[float, float]:
    """Least-squares ``log y = a + b log x``; returns ``(b, a)``."""
    import numpy as np

    lx, ly = np.log(np.asarray(xs, float)), np.log(np.asarray(ys, float))
    b, a = np.polyfit(lx, ly, 1)
    return float(b), float(a)


def fmt_time(s: float) -> str:
    """Human-readable duration."""
    if s is None or not math.isfinite(s):
        return "n/a"
    if s >= 100:
        return f"{s:.0f} s"
    if s >= 1:
        return f"{s:.2f} s"
    if s >= 1e-3:
        return f"{s * 1e3:.3g} ms"
    if s >= 1e-6:
        return f"{s * 1e6:.3g} µs"
    return f"{s * 1e9:.3g} ns"


def table(header, rows) -> str:
    """Markdown table."""
    out = ["| " + " | ".join(header) + " |", "|" + "|".join("---" for _ in header) + "|"]
    out += ["| " + " | ".join(str(c) for c in r) + " |" for r in rows]
    return "\n".join(out)


def _cpu_model() -> str:
    try:
        with open("/proc/cpuinfo") as fh:
            for line in fh:
                if line.lower().startswith("model name"):
                    return line.split(":", 1)[1].strip()
    except OSError:
        pass
    return platform.processor() or "unknown"


def model_info() -> dict:
    """What was benchmarked: git commit, hash of the generated code, key default parameters."""
    import hashlib
    import subprocess

    try:
        head = subprocess.run(["git", "rev-parse", "--short", "HEAD"], cwd=ROOT, capture_output=True,
                              text=True, timeout=10).stdout.strip()
        dirty = subprocess.run(["git", "status", "--porcelain", "--untracked-files=no"], cwd=ROOT,
                               capture_output=True, text=True, timeout=10).stdout.strip()
        head = (head or "unknown") + (" (with uncommitted changes)" if dirty else "")
    except (OSError, subprocess.SubprocessError):
        head = "unknown"
    h = hashlib.sha256()
    for name in ("kernels.py", "spiral_zipper.py"):
        try:
            h.update((ROOT / "generated" / name).read_bytes())
        except OSError:
            pass
    info = {"git HEAD": head, "generated/ sha256": h.hexdigest()[:12]}
    try:
        from szdyn.defaults import default_parameters

        ps = default_parameters(100)
        keys = [k for k in ("R_bo", "d", "t_c", "R_w", "t_r", "n_rollers", "contact_model") if k in ps.values]
        info["defaults (N_c = 100)"] = ", ".join(f"{k}={ps[k]:g}" for k in keys) + \
            f", interference={ps.interference * 1e3:.3g} mm"
    except Exception as exc:  # the report still says what it could not read
        info["defaults (N_c = 100)"] = f"unavailable ({exc})"
    return info


def machine() -> dict:
    """CPU model, cores, versions and date."""
    import numba
    import numpy
    import sympy

    try:
        affinity = len(os.sched_getaffinity(0))
    except AttributeError:
        affinity = os.cpu_count()
    return {
        "date": _dt.datetime.now().astimezone().strftime("%Y-%m-%d %H:%M %Z"),
        "cpu": _cpu_model(),
        "cores": f"{os.cpu_count()} logical ({affinity} usable)",
        "os": f"{platform.system()} {platform.release()}",
        "python": platform.python_version(),
        "numpy": numpy.__version__,
        "numba": numba.__version__,
        "sympy": sympy.__version__,
    }
