"""Symbolic derivation of the Spiral Zipper model (imports SymPy; never imported at run time).

Run ``python -m derive --out generated`` (or ``make derive``) to regenerate ``generated/``.
"""
