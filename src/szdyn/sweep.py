"""Parameter sweeps: ``python -m szdyn.run sweep SPEC.toml --out DIR``.

A sweep runs one simulation per case of a spec (:mod:`szdyn.sweep_spec`: a base scenario plus
grid axes and/or random / Latin-hypercube samples over parameters, drive and integrator
settings) in parallel, and keeps summary metrics (:mod:`szdyn.metrics`) and the time series.

Execution: all cores by default, in worker processes started with the ``spawn`` context (Numba
and ``fork`` do not mix); ``--workers 1`` runs in this process. With ``--dask`` (a local Dask
cluster) or ``--scheduler ADDRESS`` (an existing one; every worker needs szdyn installed) the
same cases run on Dask distributed, an optional extra (``pip install 'szdyn[dask]'``).
Only this process writes files.

Output directory ``DIR``:

``spec.json``
    Canonical spec, its SHA-256 and the case list. A different spec for the same DIR is refused.
``spec.toml``
    Copy of the spec file as first given (for reference).
``cases/NNNNN.json``
    One per finished case (``NNNNN`` = case id, 5+ digits): inputs, status (``ok``,
    ``failed`` = the simulation diverged, ``invalid`` = the parameter combination is not
    physical, ``error`` = unexpected exception), error message, metrics, step counts, wall time.
``cases/NNNNN.npz``
    Time series of an ``ok`` case, NumPy's standard ``.npz`` (a zip of ``.npy`` arrays; read with
    ``numpy.load(path)``, no pickle): one float64 array per output of
    :func:`szdyn.simulate.simulate` (``t, q_w, q_b, u_w, u_b, rel_speed, slip_ratio, stroke,
    stroke_lost, contacts, wheel_reaction_torque``), units in ``columns.json``.
``cases.csv``
    One row per case, sorted by case id: ``case_id, status, <swept inputs>, <metrics>,
    n_steps, n_rejected, error``; an empty cell is "not defined" (failed case, empty window,
    zero denominator); ``pending`` rows are cases not yet run. Depends only on the spec (not on
    the worker count or the executor).
``columns.json``
    Unit and meaning of every column of ``cases.csv`` and of the ``.npz`` arrays.
``summary.json``
    Counts, wall time, throughput, workers (this invocation).
``metrics.png``
    Each metric over the first axis (lines: values of the second axis), or a scatter over the
    first variable (colour: the second) when the spec has ``[sampling]``.
``.lock``
    Advisory lock held while a sweep runs here (a second concurrent run is refused).

Safe to interrupt: every case's files are written atomically (temp file + rename) when it
finishes, the ``.json`` last, so a re-run of the same command skips finished cases (``ok``,
``failed``, ``invalid``; ``error`` cases are retried) and assembles the table from the files.
"""
from __future__ import annotations

import argparse
import csv
import io
import json
import math
import os
import sys
import time
from dataclasses import dataclass, field
from itertools import islice
from pathlib import Path

import numpy as np

from .cli import Parser, directory
from .errors import ParameterError, SimulationError, UserInputError, interrupted
from .io import atomic_write_bytes, atomic_write_text, make_output_dir, write_json
from .metrics import Metric, evaluate_metrics, metric_unit
from .processes import MAX_WORKERS, worker_init
from .sweep_spec import SweepSpec, build_drive, load_spec, spec_diff

__all__ = ["run_sweep", "run_case", "sweep_command", "SweepResult", "assemble", "load_spec"]

SPEC_FILE = "spec.json"
CASES_DIR = "cases"
TABLE_FILE = "cases.csv"
DONE_STATUSES = ("ok", "failed", "invalid")  # not recomputed on a re-run
DASK_HINT = "pip install 'szdyn[dask]' (or: pip install 'dask[distributed]')"


# --------------------------------------------------------------------------- one case (worker)
def run_case(task: dict) -> dict:
    """Run one case. Top-level and dependency-light so process and Dask workers can call it.

    Returns a dict with ``case_id, status, error, inputs, metrics, n_steps, n_rejected,
    wall_time_s, t_fail`` and ``series`` (dict of float64 arrays, or None unless ``ok``).
    """
    from .params import ParameterSet
    from .simulate import simulate

    t0 = time.perf_counter()
    inputs = task["inputs"]
    rec = {"case_id": task["case_id"], "status": "ok", "error": "", "inputs": inputs,
           "metrics": {m["name"]: None for m in task["metrics"]}, "n_steps": None,
           "n_rejected": None, "wall_time_s": None, "t_fail": None, "series": None}
    try:
        params = ParameterSet.from_dict(task["base_params"])
        pchanges = {k: v for k, v in inputs.items() if "." not in k and k != "t_end"}
        drive_d = dict(task["drive"])
        drive_d.update({k[6:]: v for k, v in inputs.items() if k.startswith("drive.")})
        integ = dict(task["integrator"])
        integ.update({k[11:]: v for k, v in inputs.items() if k.startswith("integrator.")})
        t_end = float(inputs.get("t_end", task["t_end"]))
        params = params.replace(**pchanges) if pchanges else params
        drive = build_drive(drive_d)
    except (ParameterError, ValueError, TypeError) as exc:
        rec.update(status="invalid", error=_one_line(exc),
                   wall_time_s=time.perf_counter() - t0)
        return rec
    try:
        run = simulate(params, drive, t_end, method=integ["method"], dt=integ["dt"],
                       rtol=integ["rtol"], atol=integ["atol"], save_dt=integ["save_dt"],
                       max_steps=integ["max_steps"])
    except SimulationError as exc:
        rec.update(status="failed", error=_one_line(exc), t_fail=_float_or_none(exc.t),
                   wall_time_s=time.perf_counter() - t0)
        return rec
    except Exception as exc:  # noqa: BLE001 - recorded, retried on a re-run
        if interrupted(exc):   # Ctrl-C inside compiled code stops the sweep, as Ctrl-C does
            raise
        rec.update(status="error", error=f"{type(exc).__name__}: {_one_line(exc)}",
                   wall_time_s=time.perf_counter() - t0)
        return rec
    settings = {"t_end": t_end, **{f"drive.{k}": v for k, v in drive_d.items() if k != "kind"}}
    try:
        metrics = [Metric.from_dict(m) for m in task["metrics"]]
        rec["metrics"] = evaluate_metrics(metrics, run.outputs, settings)
    except Exception as exc:  # noqa: BLE001 - recorded, retried on a re-run
        rec.update(status="error", error=f"metrics: {type(exc).__name__}: {_one_line(exc)}",
                   wall_time_s=time.perf_counter() - t0)
        return rec
    rec["series"] = {k: np.ascontiguousarray(v, dtype=np.float64) for k, v in run.outputs.items()}
    rec["n_steps"] = int(run.trajectory.n_steps)
    rec["n_rejected"] = int(run.trajectory.n_rejected)
    rec["wall_time_s"] = time.perf_counter() - t0
    return rec


def _one_line(exc) -> str:
    return " ".join(str(exc).split())


def _float_or_none(v):
    try:
        v = float(v)
    except (TypeError, ValueError):
        return None
    return v if math.isfinite(v) else None


# --------------------------------------------------------------------------- case files
def case_stem(case_id: int) -> str:
    return f"{case_id:05d}"


def write_case(out: Path, rec: dict) -> None:
    """Write one finished case: the ``.npz`` (if any) first, then the ``.json`` marker."""
    cdir = out / CASES_DIR
    stem = case_stem(rec["case_id"])
    meta = {k: v for k, v in rec.items() if k != "series"}
    if rec.get("series") is not None:
        buf = io.BytesIO()
        np.savez_compressed(buf, **rec["series"])
        atomic_write_bytes(cdir / f"{stem}.npz", buf.getvalue())
        meta["series_file"] = f"{stem}.npz"
    else:
        meta["series_file"] = None
    if meta.get("wall_time_s") is not None:
        meta["wall_time_s"] = round(meta["wall_time_s"], 6)
    write_json(cdir / f"{stem}.json", meta)


def read_case(out: Path, case_id: int):
    """The record of a finished case, or None if absent, unreadable or incomplete."""
    cdir = out / CASES_DIR
    stem = case_stem(case_id)
    try:
        meta = json.loads((cdir / f"{stem}.json").read_text(encoding="utf-8"))
    except (OSError, ValueError):
        return None
    if not isinstance(meta, dict) or meta.get("case_id") != case_id:
        return None
    if meta.get("status") == "ok" and not (cdir / f"{stem}.npz").is_file():
        return None
    return meta


def load_series(out, case_id: int) -> dict:
    """Time series of a finished ``ok`` case as a dict of arrays (``numpy.load``, no pickle)."""
    with np.load(Path(out) / CASES_DIR / f"{case_stem(case_id)}.npz", allow_pickle=False) as z:
        return {k: z[k] for k in z.files}


# --------------------------------------------------------------------------- output directory
class _DirLock:
    """Exclusive advisory lock on DIR/.lock (POSIX); refuses a second sweep on the same DIR."""

    def __init__(self, out: Path):
        self.path = out / ".lock"
        self.fh = None

    def __enter__(self):
        try:
            import fcntl
        except ImportError:  # pragma: no cover - not POSIX: no lock
            return self
        self.fh = open(self.path, "a+")
        try:
            fcntl.flock(self.fh, fcntl.LOCK_EX | fcntl.LOCK_NB)
        except OSError:
            self.fh.close()
            self.fh = None
            raise UserInputError(f"--out {self.path.parent}: another sweep is running in this "
                                 "directory (it holds .lock); wait for it or use another --out")
        return self

    def __exit__(self, *exc):
        if self.fh is not None:
            self.fh.close()


def model_fingerprint() -> str:
    """SHA-256 of the generated model sources (``szdyn_generated/*.py``), to notice a
    regenerated model between an interrupted sweep and its resumption."""
    import hashlib

    import szdyn_generated

    h = hashlib.sha256()
    for f in sorted(Path(szdyn_generated.__file__).parent.glob("*.py")):
        h.update(f.name.encode() + b"\0" + f.read_bytes() + b"\0")
    return h.hexdigest()


def _prepare_dir(out: Path, spec: SweepSpec) -> bool:
    """Create DIR/spec.json, or check that the existing one is the same spec.

    Returns True if the generated model changed since the sweep in DIR was started (a
    warning: finished cases were computed with the old model).
    """
    sp = out / SPEC_FILE
    fingerprint = model_fingerprint()
    if sp.is_file():
        try:
            old = json.loads(sp.read_text(encoding="utf-8"))
            old_hash = old["hash"]
        except (OSError, ValueError, KeyError, TypeError):
            raise UserInputError(f"--out {out}: {sp} is unreadable; it is not a sweep "
                                 "directory of this szdyn (use another --out)") from None
        if old_hash != spec.hash:
            where = spec_diff(old.get("spec", {}), spec.canonical)
            raise UserInputError(
                f"--out {out} holds results of a different sweep spec (hash {old_hash[:12]} "
                f"there, {spec.hash[:12]} now; differs in: {', '.join(where) or 'content'}); "
                "use another --out, or delete the directory to start again")
        return old.get("model_fingerprint") not in (None, fingerprint)
    stray = [p.name for p in out.iterdir() if p.name not in (".lock", CASES_DIR)] \
        if out.is_dir() else []
    cdir = out / CASES_DIR
    if cdir.is_dir():
        stray += [f"{CASES_DIR}/{p.name}" for p in cdir.iterdir() if not p.name.endswith(".tmp")]
    if stray:
        raise UserInputError(f"--out {out} exists and is not a sweep directory (no {SPEC_FILE}; "
                             f"contains {stray[0]}); use another --out")
    out.mkdir(parents=True, exist_ok=True)
    if spec.text:
        atomic_write_text(out / "spec.toml", spec.text)
    write_json(sp, {"format": "szdyn-sweep", "version": 1, "hash": spec.hash,
                    "source": spec.source, "n_cases": len(spec.cases),
                    "model_fingerprint": fingerprint, "spec": spec.canonical})
    return False


def _clean_tmp(out: Path) -> None:
    """Remove temp files left by a killed run (we hold the lock, so none are in use)."""
    for d in (out, out / CASES_DIR):
        if d.is_dir():
            for p in d.glob(".*.tmp"):
                try:
                    p.unlink()
                except OSError:
                    pass


# --------------------------------------------------------------------------- executors
def _iter_serial(tasks):
    for t in tasks:
        yield run_case(t)


def _iter_pool(tasks, workers: int, context: str = "spawn"):
    import multiprocessing as mp
    from concurrent.futures import FIRST_COMPLETED, ProcessPoolExecutor, wait
    from concurrent.futures.process import BrokenProcessPool

    ctx = mp.get_context(context)
    if context == "forkserver":
        ctx.set_forkserver_preload(["szdyn.simulate"])
    pool = ProcessPoolExecutor(max_workers=workers, mp_context=ctx, initializer=worker_init)
    clean = False
    try:
        it = iter(tasks)
        ids = {}

        def submit(t):
            ids[pool.submit(run_case, t)] = t["case_id"]

        for t in islice(it, 2 * workers):
            submit(t)
        while ids:
            done, _ = wait(list(ids), return_when=FIRST_COMPLETED)
            for f in sorted(done, key=ids.get):
                cid = ids.pop(f)
                nxt = next(it, None)
                if nxt is not None:
                    submit(nxt)
                try:
                    rec = f.result()
                except BrokenProcessPool:
                    raise SimulationError(
                        f"a worker process died (running case {cid} or one of "
                        f"{sorted(ids)}); finished cases are saved, re-run to resume "
                        "(try --workers 1 to see the failing case)") from None
                except Exception as exc:  # noqa: BLE001 - recorded, retried on a re-run
                    rec = {"case_id": cid, "status": "error", "series": None,
                           "error": f"{type(exc).__name__}: {_one_line(exc)}"}
                yield rec
        clean = True
    finally:
        if not clean:
            _terminate_pool(pool)
        pool.shutdown(wait=clean, cancel_futures=True)


def _terminate_pool(pool) -> None:
    """Stop our own worker processes now (interrupt or early stop): running cases are lost,
    finished ones are already on disk."""
    procs = getattr(pool, "_processes", None) or {}
    for p in list(procs.values()):
        try:
            p.terminate()
        except Exception:  # noqa: BLE001
            pass
    for p in list(procs.values()):
        try:
            p.join(timeout=5)
        except Exception:  # noqa: BLE001
            pass


def _iter_dask(tasks, client, spec_hash: str):
    from distributed import as_completed

    try:
        nthreads = max(1, sum(client.nthreads().values()))
    except Exception:  # noqa: BLE001
        nthreads = 1
    it = iter(tasks)

    def submit(t):
        return client.submit(run_case, t, key=f"szdyn-sweep-{spec_hash[:16]}-{t['case_id']}",
                             pure=False)

    first = [submit(t) for t in islice(it, 2 * nthreads)]
    ac = as_completed(first)
    live = set(first)
    try:
        for f in ac:
            live.discard(f)
            nxt = next(it, None)
            if nxt is not None:
                g = submit(nxt)
                live.add(g)
                ac.add(g)
            try:
                rec = f.result()
            except Exception as exc:  # noqa: BLE001 - e.g. KilledWorker: retried on a re-run
                cid = int(str(f.key).rsplit("-", 1)[-1])
                rec = {"case_id": cid, "status": "error", "series": None,
                       "error": f"{type(exc).__name__}: {_one_line(exc)}"}
            yield rec
    finally:
        for g in live:
            g.cancel()


def _dask_client(scheduler: str | None, workers: int):
    """Client to ``scheduler`` or to a new LocalCluster; returns ``(client, cluster)``."""
    try:
        import distributed
    except ImportError:
        raise UserInputError(f"--dask/--scheduler need the optional dependency Dask "
                             f"distributed, which is not installed: {DASK_HINT}") from None
    if scheduler:
        try:
            return distributed.Client(scheduler, timeout="15s"), None
        except (OSError, TimeoutError, ValueError) as exc:
            raise UserInputError(f"--scheduler {scheduler}: cannot connect: {exc}") from None
    cluster = distributed.LocalCluster(n_workers=workers, threads_per_worker=1, processes=True,
                                       dashboard_address=None)
    return distributed.Client(cluster), cluster


# --------------------------------------------------------------------------- progress
class CaseProgress:
    """``cases done / total, failed, rate, ETA`` on stderr (bar on a terminal, else lines)."""

    def __init__(self, total: int, skipped: int, stream=None, enabled: bool = True):
        self.total, self.skipped = total, skipped
        self.todo = total - skipped
        self.stream = stream or sys.stderr
        self.enabled = enabled and self.todo > 0
        self.tty = hasattr(self.stream, "isatty") and self.stream.isatty()
        self.t0 = time.perf_counter()
        self.done = 0
        self.bad = 0
        self._last = -1.0

    def update(self, status: str) -> None:
        self.done += 1
        self.bad += status != "ok"
        if not self.enabled:
            return
        el = time.perf_counter() - self.t0
        rate = self.done / el if el > 0 else float("nan")
        eta = (self.todo - self.done) / rate if rate > 0 else float("nan")
        frac = self.done / self.todo
        width = 24
        bar = "#" * int(width * frac) + "-" * (width - int(width * frac))
        msg = (f"sweep [{bar}] {self.skipped + self.done}/{self.total} cases"
               + (f" ({self.skipped} done before)" if self.skipped else "")
               + (f", {self.bad} not ok" if self.bad else "")
               + f", {rate:.2f} cases/s, {el:.1f} s elapsed")
        if self.done < self.todo:
            msg += f", ETA {eta:.1f} s"
        if self.tty:
            self.stream.write("\r" + msg + ("\n" if self.done >= self.todo else ""))
            self.stream.flush()
        elif frac >= self._last + 0.1 or self.done == self.todo:
            self._last = frac
            print(msg, file=self.stream, flush=True)


# --------------------------------------------------------------------------- sweep
@dataclass
class SweepResult:
    out: Path
    n_cases: int
    n_computed: int
    n_skipped: int
    counts: dict = field(default_factory=dict)
    wall_time_s: float = 0.0
    complete: bool = True
    table: Path | None = None
    plot: Path | None = None

    @property
    def cases_per_s(self) -> float:
        return self.n_computed / self.wall_time_s if self.wall_time_s > 0 else float("nan")


def run_sweep(spec, out, *, workers: int | None = None, dask_client=None,
              scheduler: str | None = None, use_dask: bool = False, max_cases: int | None = None,
              progress: bool = True, plot: bool = True, on_case_done=None,
              context: str = "spawn") -> SweepResult:
    """Run (or resume) a sweep and assemble its table.

    Parameters
    ----------
    spec : SweepSpec or path of a TOML spec
    out : path
        Output directory (see the module docstring for its layout).
    workers : int, optional
        Worker processes (default: all cores, at most the number of cases to run); 1 runs the
        cases in this process.
    dask_client : distributed.Client, optional
        Run on this Dask client (``scheduler``/``use_dask`` make one).
    max_cases : int, optional
        Compute at most this many new cases, then stop (resume later with a re-run).
    on_case_done : callable(record), optional
        Called after each newly finished case has been written.
    context : {"spawn", "forkserver"}
        Multiprocessing start method of the process pool (never ``fork``: Numba). As with any
        ``spawn`` pool, a script that calls this with ``workers > 1`` needs the
        ``if __name__ == "__main__":`` guard.

    Returns
    -------
    SweepResult
        Counts by status, cases computed now / skipped (done before), wall time, paths.
    """
    if not isinstance(spec, SweepSpec):
        spec = load_spec(spec)
    out = Path(out)
    if workers is not None and not 1 <= workers <= MAX_WORKERS:
        raise UserInputError(f"--workers must be in 1..{MAX_WORKERS}, got {workers}")
    if max_cases is not None and max_cases < 0:
        raise UserInputError(f"--max-cases must be >= 0, got {max_cases}")
    try:
        make_output_dir(out)
    except UserInputError as exc:
        raise UserInputError(f"--out: {exc}") from None
    t_start = time.perf_counter()
    with _DirLock(out):
        model_changed = _prepare_dir(out, spec)
        if model_changed:
            print(f"szdyn: warning: the generated model (szdyn_generated) changed since the sweep "
                  f"in {out} was started; cases finished before were computed with the old "
                  "model (delete the directory to recompute all)", file=sys.stderr, flush=True)
        _clean_tmp(out)
        (out / CASES_DIR).mkdir(exist_ok=True)
        todo = [cid for cid in range(len(spec.cases))
                if (r := read_case(out, cid)) is None or r.get("status") not in DONE_STATUSES]
        skipped = len(spec.cases) - len(todo)
        if max_cases is not None:
            todo = todo[:max_cases]
        n_workers = workers or _cpu_count()
        n_workers = max(1, min(n_workers, len(todo) or 1))
        tasks = (spec.task(cid) for cid in todo)
        cluster = client = None
        executor = "serial"
        if dask_client is not None or scheduler or use_dask:
            executor = "dask"
            client = dask_client
            if client is None and todo:
                client, cluster = _dask_client(scheduler, n_workers)
            results = _iter_dask(tasks, client, spec.hash) if todo else iter(())
        elif n_workers > 1:
            executor = f"processes ({context})"
            results = _iter_pool(tasks, n_workers, context)
        else:
            results = _iter_serial(tasks)
        prog = CaseProgress(len(spec.cases), skipped, enabled=progress)
        computed = 0
        try:
            for rec in results:
                write_case(out, rec)
                computed += 1
                prog.update(rec["status"])
                if on_case_done is not None:
                    on_case_done(rec)
        except KeyboardInterrupt:
            if progress:
                print(f"\nsweep interrupted: {skipped + computed} of {len(spec.cases)} cases are "
                      f"saved in {out / CASES_DIR}; re-run the same command to continue",
                      file=sys.stderr, flush=True)
            raise
        finally:
            close = getattr(results, "close", None)
            if close is not None:
                close()
            if cluster is not None:
                client.close()
                cluster.close()
        sweep_wall = time.perf_counter() - t_start
        table, png, counts = assemble(out, spec, plot=plot)
        n_pending = counts.get("pending", 0)
        summary = {"n_cases": len(spec.cases), "counts": counts, "computed_now": computed,
                   "skipped_done_before": skipped, "complete": n_pending == 0,
                   "executor": executor, "workers": n_workers if executor != "dask" else None,
                   "wall_time_s": round(sweep_wall, 3),
                   "cases_per_s": round(computed / sweep_wall, 4) if sweep_wall > 0 else None,
                   "spec_hash": spec.hash, "model_changed_since_start": model_changed}
        write_json(out / "summary.json", summary)
    return SweepResult(out=out, n_cases=len(spec.cases), n_computed=computed, n_skipped=skipped,
                       counts=counts, wall_time_s=sweep_wall, complete=n_pending == 0,
                       table=table, plot=png)


def _cpu_count() -> int:
    try:
        return len(os.sched_getaffinity(0))
    except (AttributeError, OSError):
        return os.cpu_count() or 1


# --------------------------------------------------------------------------- table and plot
def csv_cell(v) -> str:
    """One CSV cell: empty for None and non-finite floats (no NaN text in a table), bools as 0/1."""
    if v is None:
        return ""
    if isinstance(v, bool):
        return str(int(v))
    if isinstance(v, float):
        return repr(v) if math.isfinite(v) else ""
    return str(v)


def assemble(out, spec: SweepSpec, *, plot: bool = True):
    """Build ``cases.csv``, ``columns.json`` (and ``metrics.png``) from the per-case files.

    Returns ``(table_path, png_path_or_None, counts_by_status)``.
    """
    from .simulate import OUTPUT_UNITS

    out = Path(out)
    metric_names = [m.name for m in spec.metrics]
    header = ["case_id", "status"] + spec.variables + metric_names + ["n_steps", "n_rejected",
                                                                      "error"]
    rows, counts = [], {}
    for cid, inputs in enumerate(spec.cases):
        rec = read_case(out, cid) or {"status": "pending", "metrics": {}, "error": ""}
        counts[rec["status"]] = counts.get(rec["status"], 0) + 1
        m = rec.get("metrics") or {}
        rows.append([cid, rec["status"]] + [inputs[v] for v in spec.variables]
                    + [m.get(k) for k in metric_names]
                    + [rec.get("n_steps"), rec.get("n_rejected"), rec.get("error", "")])
    buf = io.StringIO()
    w = csv.writer(buf, lineterminator="\n")
    w.writerow(header)
    for r in rows:
        w.writerow([csv_cell(v) for v in r])
    table = atomic_write_text(out / TABLE_FILE, buf.getvalue())
    write_json(out / "columns.json", _columns_doc(spec, OUTPUT_UNITS))
    png = None
    if plot and spec.metrics:
        png = plot_metrics(out / "metrics.png", spec, rows, header)
    return table, png, dict(sorted(counts.items()))


def _variable_unit(name: str) -> str:
    if name in ("t_end",) or name in ("drive.t_end", "drive.t_ramp", "drive.t_hold",
                                      "integrator.dt", "integrator.save_dt"):
        return "s"
    if name in ("drive.a", "drive.a_down"):
        return "rad/s^2"
    if name == "drive.omega_max":
        return "rad/s"
    if name in ("integrator.rtol", "n_circles"):
        return "1"
    if name == "integrator.atol":
        return "rad, rad/s"
    try:
        from szdyn_generated.spiral_zipper import PARAM_DOCS

        return PARAM_DOCS[name][0]
    except (ImportError, KeyError):
        return ""


def _variable_doc(name: str) -> str:
    if name == "n_circles":
        return "number of small circles N_c"
    if name == "t_end":
        return "simulated time"
    if name.startswith("drive."):
        return f"drive profile argument '{name[6:]}'"
    if name.startswith("integrator."):
        return f"integrator setting '{name[11:]}'"
    try:
        from szdyn_generated.spiral_zipper import PARAM_DOCS

        return PARAM_DOCS[name][1]
    except (ImportError, KeyError, IndexError):
        return "model parameter"


def _columns_doc(spec: SweepSpec, units: dict) -> dict:
    cols = [{"name": "case_id", "kind": "id", "unit": "",
             "description": "case number (position in spec.json 'cases'); files cases/NNNNN.*"},
            {"name": "status", "kind": "status", "unit": "",
             "description": "ok | failed (simulation diverged) | invalid (parameter combination "
                            "rejected) | error (unexpected exception; retried on a re-run) | "
                            "pending (not run yet)"}]
    for v in spec.variables:
        cols.append({"name": v, "kind": "input", "unit": _variable_unit(v),
                     "description": _variable_doc(v)})
    for m in spec.metrics:
        win = ""
        if m.t_from is not None or m.t_to is not None:
            win = f" for t in [{m.t_from if m.t_from is not None else 0}, " \
                  f"{m.t_to if m.t_to is not None else 't_end'}]"
        what = f"{m.kind} of {m.of}" + (f" over {m.over}" if m.over else "") + win
        cols.append({"name": m.name, "kind": "metric", "unit": metric_unit(m, units),
                     "description": (m.description + "; " if m.description else "") + what,
                     "definition": m.to_dict()})
    cols += [{"name": "n_steps", "kind": "diagnostic", "unit": "1",
              "description": "integrator steps accepted"},
             {"name": "n_rejected", "kind": "diagnostic", "unit": "1",
              "description": "adaptive steps rejected"},
             {"name": "error", "kind": "status", "unit": "",
              "description": "error message of a case that is not ok"}]
    return {
        "format": "szdyn-sweep-table", "version": 1, "file": TABLE_FILE,
        "spec_hash": spec.hash,
        "missing_value": "empty cell: not defined (case not ok, empty window, zero denominator)",
        "columns": cols,
        "time_series": {
            "files": f"{CASES_DIR}/NNNNN.npz (NNNNN = case_id, zero-padded to 5 digits), only "
                     "for status ok",
            "format": "NumPy .npz (zip of .npy arrays): numpy.load(path) - no pickle; one "
                      "float64 array of shape (n_samples,) per output, sampled every save_dt",
            "arrays": dict(units),
        },
        "case_files": f"{CASES_DIR}/NNNNN.json: inputs, status, error, metrics, n_steps, "
                      "n_rejected, wall_time_s, t_fail (s, where a failed run stopped)",
    }


def plot_metrics(path, spec: SweepSpec, rows, header) -> Path | None:
    """One panel per metric against the first swept variable (see module docstring)."""
    if not spec.variables:
        return None
    from .plots import _pyplot, save_png

    plt = _pyplot()

    idx = {h: i for i, h in enumerate(header)}
    ok = [r for r in rows if r[1] == "ok"]
    xname = spec.variables[0]
    scales = {a["name"]: a["scale"] for a in spec.axes}
    if spec.sampling:
        scales.update({r["name"]: r["scale"] for r in spec.sampling["ranges"]})
    sampled = spec.sampling is not None
    n = len(spec.metrics)
    ncol = min(3, n)
    nrow = math.ceil(n / ncol)
    fig, axs = plt.subplots(nrow, ncol, figsize=(4.6 * ncol, 3.4 * nrow), squeeze=False)
    for k, m in enumerate(spec.metrics):
        ax = axs[k // ncol][k % ncol]
        unit = metric_unit(m, _units())
        pts = [r for r in ok if r[idx[m.name]] is not None]
        if sampled:
            x = [r[idx[xname]] for r in pts]
            y = [r[idx[m.name]] for r in pts]
            if len(spec.variables) > 1 and pts:
                c = [r[idx[spec.variables[1]]] for r in pts]
                sc = ax.scatter(x, y, c=c, s=14)
                fig.colorbar(sc, ax=ax, label=spec.variables[1])
            else:
                ax.scatter(x, y, s=14)
        else:
            others = [v for v in spec.variables if v != xname]
            groups: dict = {}
            for r in pts:
                groups.setdefault(tuple(r[idx[v]] for v in others), []).append(r)
            for key, g in groups.items():
                g = sorted(g, key=lambda r: r[idx[xname]])
                label = (f"{others[0]} = {key[0]:.4g}" if others else None)
                if len(others) > 1:
                    label += " (+" + ", ".join(f"{o}={v:.3g}" for o, v in zip(others[1:], key[1:])) + ")"
                ax.plot([r[idx[xname]] for r in g], [r[idx[m.name]] for r in g], "o-", ms=3,
                        label=label)
            if others and 0 < len(groups) <= 8:
                ax.legend(fontsize=7)
        if scales.get(xname) == "log":
            ax.set_xscale("log")
        ax.set_xlabel(f"{xname} [{_variable_unit(xname)}]")
        ax.set_ylabel(f"[{unit}]")
        ax.set_title(m.name, fontsize=10)
        ax.grid(True, alpha=0.3)
    for k in range(n, nrow * ncol):
        axs[k // ncol][k % ncol].axis("off")
    failed = sum(1 for r in rows if r[1] not in ("ok", "pending"))
    fig.suptitle(f"{Path(spec.source).name or 'sweep'}: {len(ok)} ok"
                 + (f", {failed} not ok" if failed else ""), fontsize=11)
    fig.tight_layout()
    return save_png(fig, path, dpi=110)


def _units():
    from .simulate import OUTPUT_UNITS

    return OUTPUT_UNITS


# --------------------------------------------------------------------------- CLI
def build_parser() -> argparse.ArgumentParser:
    ap = Parser(
        "sweep",
        prog="python -m szdyn.run sweep",
        description="Run a parameter sweep described by a TOML spec (see "
                    "examples/sweep_example.toml). Writes cases.csv (+ columns.json), one .npz "
                    "time-series file per case, metrics.png. Re-run the same command to resume.")
    ap.add_argument("spec", type=Path, help="sweep spec (TOML)")
    ap.add_argument("--out", type=directory, help="output directory (default: results/<spec name>)")
    ap.add_argument("--workers", type=int, default=None,
                    help="parallel workers (default: all cores; 1 = in this process)")
    g = ap.add_mutually_exclusive_group()
    g.add_argument("--scheduler", metavar="ADDRESS",
                   help="run on an existing Dask distributed scheduler (e.g. tcp://host:8786)")
    g.add_argument("--dask", action="store_true", help="run on a local Dask cluster")
    ap.add_argument("--max-cases", type=int, default=None,
                    help="compute at most N new cases, then stop (re-run to continue)")
    ap.add_argument("--no-plot", action="store_true", help="do not draw metrics.png")
    ap.add_argument("--quiet", action="store_true", help="no progress output")
    return ap


def sweep_command(argv) -> int:
    """``python -m szdyn.run sweep SPEC.toml --out DIR [--workers N] [--scheduler ADDR | --dask]``.

    Raises UserInputError (incl. SpecError) for mistakes in the spec or the options.
    """
    args = build_parser().parse_args(argv)
    if args.workers is not None and not 1 <= args.workers <= MAX_WORKERS:
        raise UserInputError(f"--workers must be in 1..{MAX_WORKERS}, got {args.workers}")
    if args.max_cases is not None and args.max_cases < 0:
        raise UserInputError(f"--max-cases must be >= 0, got {args.max_cases}")
    spec = load_spec(args.spec)
    out = args.out if args.out is not None else Path("results") / args.spec.stem
    res = run_sweep(spec, out, workers=args.workers, scheduler=args.scheduler,
                    use_dask=args.dask, max_cases=args.max_cases, progress=not args.quiet,
                    plot=not args.no_plot)
    c = res.counts
    parts = ", ".join(f"{v} {k}" for k, v in c.items())
    rate = f", {res.cases_per_s:.2f} cases/s" if res.n_computed else ""
    print(f"{res.out / TABLE_FILE}: {res.n_cases} cases ({parts}); computed {res.n_computed} "
          f"in {res.wall_time_s:.1f} s{rate}, {res.n_skipped} done before"
          + ("" if res.complete else "; incomplete: re-run the same command to continue"))
    return 0
