"""Diagnosis (issue 5): calibrate the model to recordings, locate the mismatch, name the missing
effect from a library of derived terms, refit, and report. Entry points:
``python -m szdyn.run diagnose MANIFEST.toml --out DIR`` and :class:`Diagnosis`.
"""
from .diagnosis import Diagnosis
from .selection import SelectionRule

__all__ = ["Diagnosis", "SelectionRule"]
