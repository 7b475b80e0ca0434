"""Process lifetime: pool workers that end with their parent, and SIGTERM taken as Ctrl-C.

Why
---
A worker of a ``spawn`` process pool (:class:`concurrent.futures.ProcessPoolExecutor`) waits on
its task queue, and holds both ends of that queue's pipe: when the parent dies without shutting
the pool down (``kill``, a batch scheduler's stop, the out-of-memory killer), the worker never
reads end-of-file and stays, with its ~280 MB, until someone kills it. Measured before this
module (a diagnosis with ``--workers 2``, its parent sent SIGTERM): both workers and the
resource tracker were still there, idle, a minute later, and the runs of the batch in flight
were not saved. Two remedies, one per side:

* :func:`worker_init` (each pool's initializer) starts a thread that waits on the parent's
  sentinel (a pipe the parent alone keeps open, :func:`multiprocessing.parent_process`) and ends
  the worker when it closes, whatever killed the parent, ``kill -9`` included.
* :func:`sigterm_as_interrupt` (around a command in :func:`szdyn.run.main`) raises
  :class:`~szdyn.errors.Terminated`, a :class:`KeyboardInterrupt`, on SIGTERM, so that the
  command stops as on Ctrl-C: finished runs saved, pools shut down, partial results discarded,
  and a message saying how to resume.
"""
from __future__ import annotations

import os
import signal
import threading
from contextlib import contextmanager

from .errors import Terminated

__all__ = ["MAX_WORKERS", "worker_init", "exit_with_parent", "sigterm_as_interrupt"]

#: most worker processes a command starts (``--workers``): a guard, not a tuning; each one loads
#: numba and the compiled model, and a mistyped 99999999999 ended in an OverflowError traceback
MAX_WORKERS = 1024


def exit_with_parent() -> bool:
    """In a process started by :mod:`multiprocessing`: end it (``os._exit(1)``) as soon as its
    parent is gone. Returns False (and does nothing) in a process that has no such parent."""
    import multiprocessing as mp

    parent = mp.parent_process()
    if parent is None:
        return False

    def watch():
        parent.join()       # returns when the parent's end of the sentinel pipe closes
        os._exit(1)         # a worker has nothing to save: its results went to the parent

    threading.Thread(target=watch, name="szdyn-exit-with-parent", daemon=True).start()
    return True


def worker_init() -> None:
    """Initializer of szdyn's process-pool workers: Ctrl-C is left to the parent (which stops
    the pool), the worker ends with its parent, and the model is imported once (numba and the
    generated code) rather than in the first task."""
    signal.signal(signal.SIGINT, signal.SIG_IGN)
    exit_with_parent()
    from . import simulate  # noqa: F401


class _Received:
    """Whether SIGTERM arrived while :func:`sigterm_as_interrupt` was active."""

    received = False


@contextmanager
def sigterm_as_interrupt():
    """Within the block, SIGTERM raises :class:`~szdyn.errors.Terminated` in the main thread.

    Yields an object whose ``received`` attribute says whether it came (a command may turn the
    exception into a plain :class:`KeyboardInterrupt`). Outside the main thread, where Python
    cannot set a signal handler, it changes nothing. The previous handler is restored on exit.
    """
    state = _Received()
    if threading.current_thread() is not threading.main_thread():
        yield state
        return

    def handler(signum, frame):
        state.received = True
        raise Terminated("terminated (SIGTERM)")

    previous = signal.signal(signal.SIGTERM, handler)
    try:
        yield state
    finally:
        signal.signal(signal.SIGTERM, previous)
