"""The commands' argument parser: argparse with the project's two conventions for a mistake.

* A mistake is one line, ``szdyn: error: COMMAND: what was wrong`` (a :class:`UserInputError`
  that :func:`szdyn.run.main` prints), not argparse's usage block followed by its message.
* A negative number in e-notation (``--dt -1e-4``) is a value, so the option's own check says
  what it expects; argparse's own pattern (Python 3.11, as installed here) took ``-1e-4`` for an
  unknown option and said only "expected one argument".
"""
from __future__ import annotations

import argparse
import re

from szdyn.errors import UserInputError

__all__ = ["Parser", "directory"]


def directory(text: str) -> "Path":
    """argparse type of an output directory: a path, but not an empty string, which ``Path``
    reads as the current directory (``--out ""``, or ``--out "$OUT"`` with OUT unset)."""
    from pathlib import Path

    if not text.strip():
        raise argparse.ArgumentTypeError("expected a directory, got an empty string (use . for the "
                                         "current directory)")
    return Path(text)


class Parser(argparse.ArgumentParser):
    """:class:`argparse.ArgumentParser` whose errors raise :class:`UserInputError`.

    Parameters
    ----------
    command : str
        The command's name, put before each message (``synth: argument --dt: ...``).
    **kwargs
        As for :class:`argparse.ArgumentParser`.
    """

    def __init__(self, command: str, **kwargs):
        super().__init__(**kwargs)
        self.command = command
        # any "-" followed by a digit or ".digit" (3.11's own pattern, set per parser in
        # __init__, matched only plain decimals such as -3 or -0.5). No command has an option
        # that starts with a digit, so nothing else is read as a value.
        self._negative_number_matcher = re.compile(r"^-\.?\d")

    def error(self, message):
        raise UserInputError(f"{self.command}: {message} (see {self.prog} --help)")
