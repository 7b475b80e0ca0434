"""Process lifetime (``szdyn.processes``): pool workers end with their parent, SIGTERM is Ctrl-C.

The end-to-end case (a diagnosis sent SIGTERM saves its runs, says how to resume and leaves no
worker behind) is in tests/test_diagnose.py.
"""
from __future__ import annotations

import os
import signal
import subprocess
import sys
import textwrap
import time
from pathlib import Path

import pytest

from szdyn.errors import Terminated, interrupted
from szdyn.processes import sigterm_as_interrupt

ROOT = Path(__file__).resolve().parents[1]


def alive(pid: int) -> bool:
    """The process exists and is not a zombie (a dead child its new parent has not reaped)."""
    try:
        os.kill(pid, 0)
    except ProcessLookupError:
        return False
    try:
        stat = Path(f"/proc/{pid}/stat").read_text()
    except FileNotFoundError:
        return False
    except OSError:         # no /proc: os.kill said it exists
        return True
    return stat.rsplit(")", 1)[1].split()[0] != "Z"


def children(pid: int) -> list[int]:
    """Processes whose parent is ``pid`` (from /proc)."""
    out = []
    for d in Path("/proc").iterdir():
        if d.name.isdigit():
            try:
                if int((d / "stat").read_text().rsplit(")", 1)[1].split()[1]) == pid:
                    out.append(int(d.name))
            except (OSError, IndexError, ValueError):
                pass
    return out


POOL = textwrap.dedent("""
    import os, sys, time
    import multiprocessing as mp
    from concurrent.futures import ProcessPoolExecutor
    from szdyn.processes import worker_init

    def pid(_):
        time.sleep(0.3)
        return os.getpid()

    if __name__ == "__main__":
        init = worker_init if sys.argv[1] == "worker_init" else None
        pool = ProcessPoolExecutor(2, mp_context=mp.get_context("spawn"), initializer=init)
        pids = set()
        while len(pids) < 2:
            pids |= set(pool.map(pid, range(4)))
        print(*sorted(pids), flush=True)
        time.sleep(600)
""")


@pytest.mark.skipif(not Path("/proc/self/stat").exists(), reason="needs /proc")
@pytest.mark.parametrize("init", ["worker_init", "none"])
def test_pool_workers_end_with_a_killed_parent(tmp_path, init):
    """``kill -9`` of the parent: workers started with :func:`worker_init` end within seconds;
    without it (the control) they stay, blocked on their task queue, as measured before."""
    script = tmp_path / "pool.py"
    script.write_text(POOL)
    proc = subprocess.Popen([sys.executable, str(script), init], cwd=ROOT, stdout=subprocess.PIPE,
                            text=True)
    try:
        workers = [int(p) for p in proc.stdout.readline().split()]
        assert len(workers) == 2 and all(alive(p) for p in workers)
    finally:
        proc.kill()
        proc.wait(timeout=30)
    try:
        deadline = time.monotonic() + (30 if init == "worker_init" else 3)
        while time.monotonic() < deadline and any(alive(p) for p in workers):
            time.sleep(0.1)
        assert [alive(p) for p in workers] == [init == "none"] * 2
    finally:
        for p in workers:
            if alive(p):
                os.kill(p, signal.SIGKILL)


def test_sigterm_raises_terminated_and_the_handler_is_restored():
    before = signal.getsignal(signal.SIGTERM)
    with pytest.raises(Terminated) as exc:
        with sigterm_as_interrupt() as state:
            assert not state.received
            os.kill(os.getpid(), signal.SIGTERM)
            time.sleep(5)       # the handler runs between bytecodes: the sleep is cut short
    assert state.received and interrupted(exc.value)     # handled as Ctrl-C is
    assert signal.getsignal(signal.SIGTERM) is before
