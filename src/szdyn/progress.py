"""Minimal progress reporting on stderr (a bar on a terminal, a line per 10 % otherwise)."""
from __future__ import annotations

import sys
import time


class Progress:
    """Callable ``progress(fraction)`` for :func:`szdyn.integrators.integrate`."""

    def __init__(self, label: str, stream=None, enabled: bool = True):
        self.label = label
        self.stream = stream or sys.stderr
        self.enabled = enabled
        self.tty = hasattr(self.stream, "isatty") and self.stream.isatty()
        self.t0 = time.perf_counter()
        self._last_decile = -1

    def __call__(self, fraction: float) -> None:
        if not self.enabled:
            return
        elapsed = time.perf_counter() - self.t0
        eta = elapsed * (1 - fraction) / fraction if fraction > 0 else float("nan")
        msg = f"{self.label}: {100 * fraction:5.1f}%  {elapsed:6.1f} s elapsed"
        if fraction > 0 and fraction < 1:
            msg += f", ETA {eta:5.1f} s"
        if self.tty:
            self.stream.write("\r" + msg + ("\n" if fraction >= 1 else ""))
            self.stream.flush()
        else:
            decile = int(fraction * 10 + 1e-9)
            if decile > self._last_decile:
                self._last_decile = decile
                print(msg, file=self.stream, flush=True)
