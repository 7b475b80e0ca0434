"""Replay kept grid diagnoses from their saved model runs, to show a change to the diagnosis's
orchestration leaves every answer as it was.

Usage::

    python bench/replay_grid.py --work /path/gw65 [--work /path/gw66 ...] --out REPLAY_DIR \
        [--src OTHER_CHECKOUT/src] [--against OTHER_REPLAY_DIR]

A grid run with ``--diagnose-args=--keep-runs`` (``bench/diagnosis_grid.py``) keeps each case's
model runs in ``CASE/diagnosis/checkpoint``. A diagnosis is a deterministic function of its
recordings, options and model runs (``szdyn.diagnose.checkpoint``), so run again with those runs
it takes the same path in seconds, without simulating. This script copies each case's runs to
``REPLAY_DIR/CASE/diagnosis`` and runs the diagnosis there with this checkout's szdyn, or the
one ``--src`` names, with the command's default options (as the grid runs it; a case kept with
other ``--diagnose-args`` would take another path) and ``--no-next-recording`` (that ranking
runs new designs, not saved ones). Its log goes to ``REPLAY_DIR/CASE/replay.log``.

The checkpoint's fingerprint hashes every ``.py`` file of szdyn, so any code change would
discard the runs; the replay accepts the stored fingerprint instead. That is valid only when the
change leaves the model runs themselves alone (``engine``, ``integrators``, ``generated/``...).
A run the replayed code asks for that the saved ones do not hold is simulated afresh: a path the
grid did not take. Such a replay is counted as differing, whatever its outputs.

``--against`` compares each case's ``diagnosis.json``, ``report.md`` and log with another
replay (e.g. of the commit before the change, replayed the same way): equal apart from times and
run counts (:func:`json_differences`, :func:`text_differences`); the log, which names every
refit, start, continuation and ablation in order, shows a changed path even where the answer is
the same. Compare replay with replay, not with the grid's own output: that one ranked the next
recording and counted its model runs.
Writes ``REPLAY_DIR/replay.json`` (per case: exit code, seconds, model runs, differences) and
prints a line per case; exit code 1 if any case failed or differs.
"""
from __future__ import annotations

import argparse
import json
import re
import shutil
import subprocess
import sys
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT / "src"))

#: diagnosis.json keys whose values are measured, not decided: wall times and run counts. (Of
#: ``cost``, the steps its ``seconds`` lists are compared: they say which branches ran.)
VOLATILE_KEYS = frozenset({"cost", "timings", "model_runs", "seconds"})

#: report.md and log pieces that are times or run counts: the cost line, "First pass: 611 s, 2166
#: model runs", "took 48 s and 322 model runs", the log's clock "diagnose [  12.3 s]", and its
#: progress lines "diagnose [...] 25 model runs"
_TEXT_VOLATILE = (re.compile(r"^Cost: .*$", re.M), re.compile(r"\d+(\.\d+)? s(,| and) \d+ model runs"),
                  re.compile(r"^diagnose \[\s*[\d.]+ s\] \d+ model runs$", re.M),
                  re.compile(r"^diagnose \[\s*[\d.]+ s\]", re.M))


def json_differences(a, b, path: str = "") -> list:
    """Paths at which two diagnosis.json trees differ, ignoring :data:`VOLATILE_KEYS` (NaN equals
    NaN). Each entry is ``"path: a != b"``."""
    if isinstance(a, dict) and isinstance(b, dict):
        out = []
        for k in sorted(set(a) | set(b)):
            if k == "cost" and not path and isinstance(a.get(k), dict) and isinstance(b.get(k), dict):
                steps = [list(c["seconds"]) if isinstance(c.get("seconds"), dict) else [] for c in (a[k], b[k])]
                if steps[0] != steps[1]:
                    out.append(f"/cost/seconds: steps {steps[0]} != {steps[1]}")
                continue
            if k in VOLATILE_KEYS:
                continue
            if k not in a or k not in b:
                out.append(f"{path}/{k}: only in {'the second' if k not in a else 'the first'}")
            else:
                out += json_differences(a[k], b[k], f"{path}/{k}")
        return out
    if isinstance(a, list) and isinstance(b, list):
        if len(a) != len(b):
            return [f"{path}: {len(a)} items != {len(b)}"]
        return [d for i, (x, y) in enumerate(zip(a, b)) for d in json_differences(x, y, f"{path}[{i}]")]
    if type(a) is not type(b) or (a != b and not (a != a and b != b)):
        return [f"{path}: {a!r:.60} != {b!r:.60}"]
    return []


def text_differences(a: str, b: str) -> list:
    """Line numbers (1-based) at which two report.md texts (or two logs) differ once times and
    run counts are blanked; a different line count is one entry."""
    for pat in _TEXT_VOLATILE:
        a, b = pat.sub("#", a), pat.sub("#", b)
    la, lb = a.splitlines(), b.splitlines()
    out = [i + 1 for i, (x, y) in enumerate(zip(la, lb)) if x != y]
    return out + ([f"{len(la)} lines != {len(lb)}"] if len(la) != len(lb) else [])


def cases(works) -> list:
    """The kept cases under the ``--work`` directories: those with a diagnosis.json and runs."""
    out = []
    for w in works:
        for c in sorted(Path(w).iterdir()):
            if (c / "diagnosis" / "diagnosis.json").is_file() and (c / "diagnosis" / "checkpoint").is_dir():
                out.append(c)
    return out


def replay_one(src: Path, dst: Path) -> int:
    """Run the diagnosis of case ``src`` into ``dst/diagnosis`` from a copy of its saved runs
    (in this process: the stored fingerprint is accepted, see the module notes). The patch of
    ``checkpoint.fingerprint`` acts because the command imports it when it runs."""
    import szdyn.diagnose.checkpoint as checkpoint
    from szdyn.diagnose.command import diagnose_command

    if dst.exists():
        shutil.rmtree(dst)
    (dst / "diagnosis").mkdir(parents=True)
    runs = dst / "diagnosis" / checkpoint.CHECKPOINT_DIR
    # the runs only; the recordings, which the diagnosis only reads, are read where the grid
    # wrote them (diagnosis_grid.copy_kept_runs, for --runs-from, copies both)
    shutil.copytree(src / "diagnosis" / checkpoint.CHECKPOINT_DIR, runs)
    stored = json.loads((runs / "fingerprint.json").read_text())["fingerprint"]
    checkpoint.fingerprint = lambda recordings: stored
    return diagnose_command([str(src / "data" / "manifest.toml"), "--out", str(dst / "diagnosis"),
                             "--keep-runs", "--no-next-recording"])


def model_runs(diagnosis_json: Path):
    """The model runs the replay made (``cost.model_runs`` of its diagnosis.json), or None."""
    if not diagnosis_json.is_file():
        return None
    return json.loads(diagnosis_json.read_text()).get("cost", {}).get("model_runs")


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--work", action="append", type=Path, required=True, help="grid work directory (repeatable)")
    ap.add_argument("--out", type=Path, required=True, help="where the replays are written")
    ap.add_argument("--against", type=Path, help="another replay directory to compare with")
    ap.add_argument("--src", type=Path, help="the szdyn source tree to replay with (default: this checkout's src)")
    ap.add_argument("--one", nargs=2, type=Path, metavar=("CASE", "DEST"), help=argparse.SUPPRESS)
    args = ap.parse_args(argv)
    if args.src is not None:
        if not (args.src / "szdyn" / "diagnose").is_dir():
            print(f"replay_grid: --src {args.src}: no szdyn/diagnose package there", file=sys.stderr)
            return 2
        sys.path.insert(0, str(args.src.resolve()))
    if args.one:                      # (the child process of one replay)
        return replay_one(*args.one)
    todo = cases(args.work)
    if not todo:
        print(f"replay_grid: no kept cases (diagnosis.json and checkpoint/) under {args.work}", file=sys.stderr)
        return 2
    rows, bad = [], 0
    for k, c in enumerate(todo, 1):
        dst = args.out / c.name
        t = time.perf_counter()
        proc = subprocess.run([sys.executable, __file__, "--work", str(c.parent), "--out", str(args.out),
                               *(["--src", str(args.src)] if args.src else []), "--one", str(c), str(dst)],
                              capture_output=True, text=True)
        rc = proc.returncode
        dst.mkdir(parents=True, exist_ok=True)    # (a child that failed early made none)
        (dst / "replay.log").write_text(proc.stderr)
        row = {"case": c.name, "work": str(c.parent), "rc": rc, "seconds": round(time.perf_counter() - t, 1),
               "model_runs": model_runs(dst / "diagnosis" / "diagnosis.json")}
        if rc != 0:
            row["stderr_tail"] = proc.stderr.strip().splitlines()[-5:]
        if rc == 0 and row["model_runs"]:
            # the saved runs did not hold them: the replayed code took a path the grid did not
            row["differences"] = [f"made {row['model_runs']} model runs (a path the saved runs do not cover)"]
        if args.against is not None and rc == 0:
            other = args.against / c.name
            if not (other / "diagnosis" / "diagnosis.json").is_file():
                row.setdefault("differences", []).append("not in --against")
            else:
                row.setdefault("differences", []).extend(
                    json_differences(json.loads((other / "diagnosis" / "diagnosis.json").read_text()),
                                     json.loads((dst / "diagnosis" / "diagnosis.json").read_text()))
                    + [f"report.md line {n}" for n in text_differences(
                        (other / "diagnosis" / "report.md").read_text(),
                        (dst / "diagnosis" / "report.md").read_text())]
                    + ([f"replay.log line {n}" for n in text_differences(   # (each names its own directory)
                        (other / "replay.log").read_text().replace(str(other), "CASE"),
                        proc.stderr.replace(str(dst), "CASE"))]
                       if (other / "replay.log").is_file() else ["no replay.log in --against"]))
        bad += rc != 0 or bool(row.get("differences"))
        rows.append(row)
        diff = "" if "differences" not in row else f", {len(row['differences'])} difference(s)"
        print(f"[{k}/{len(todo)}] {c.parent.name}/{c.name}: rc {rc}, {row['seconds']} s, "
              f"{row['model_runs']} model runs{diff}", flush=True)
        for d in row.get("differences", [])[:5] + row.get("stderr_tail", []):
            print(f"    {d}")
    from szdyn.io import write_json
    write_json(args.out / "replay.json", {"against": None if args.against is None else str(args.against),
                                          "cases": rows})
    print(f"{len(rows) - bad} of {len(rows)} cases replayed" + (" identically" if args.against else "")
          + (f"; {bad} failed or differ" if bad else ""))
    return 1 if bad else 0


if __name__ == "__main__":
    raise SystemExit(main())
