"""Emit the Numba modules of ``generated/`` from the symbolic kernels.

Output is deterministic: kernels are emitted in a fixed order, parameters are unpacked in
sorted order, and common subexpressions come from ``sympy.cse`` on a fixed expression list.
"""
from __future__ import annotations

from pathlib import Path

import sympy as sm
from sympy.printing.pycode import PythonCodePrinter

from .force_laws import LAWS
from .kernels import energy_kernels, kernels
import hashlib

from .symbols import AUX_STATES, PARAMETERS, PARAM_NAMES

STATE_ORDER = "x = [q_w, q_b, q_1 .. q_Nc, u_w, u_b, u_1 .. u_Nc, " + ", ".join(AUX_STATES) + "]  (rad, rad/s, m)"


class _Printer(PythonCodePrinter):
    """Python printer for scalar Numba code (``math`` functions, no numpy)."""

    def _print_sign(self, e):
        a = self._print(e.args[0])
        return f"(0.0 if {a} == 0 else math.copysign(1.0, {a}))"

    def _print_Rational(self, e):
        return f"{float(e.p)}/{float(e.q)}"

    def _print_Pow(self, e, rational=False):
        # A parameter exponent (the impact law's n) would call the slow generic pow on every
        # contact; `fpow` multiplies for the common integer values and falls back to pow.
        if e.exp.is_Symbol:
            return f"fpow({self._print(e.base)}, {self._print(e.exp)})"
        return super()._print_Pow(e, rational=rational)


def _header(kind: str) -> str:
    params = ", ".join(PARAM_NAMES)
    return (
        "# " + "-" * 76 + "\n"
        f"# szdyn generated code ({kind}) -- DO NOT EDIT.\n"
        f"# Source: derive/codegen.py (run as `python -m derive`), SymPy {sm.__version__}.\n"
        "# Regenerate with `make derive`; tests check that this file is reproduced byte for byte.\n"
        f"# State order: {STATE_ORDER}\n"
        f"# Parameter order (p): {params}\n"
        "# " + "-" * 76 + "\n"
    )


def _param_lines(exprs, printer) -> list[str]:
    names = sorted({s.name for e in exprs for s in e.free_symbols} & set(PARAM_NAMES))
    return [f"    {n} = p[{PARAM_NAMES.index(n)}]" for n in names]


def _function(name: str, args, outputs: list[tuple[str, sm.Expr]], doc: str) -> str:
    printer = _Printer({"standard": "python3", "fully_qualified_modules": True})
    exprs = [e for _, e in outputs]
    subs, reduced = sm.cse(exprs, symbols=sm.numbered_symbols("x"), order="canonical")
    lines = ["@nb.njit(cache=True)", f"def {name}({', '.join(str(a) for a in args)}, p):"]
    lines.append('    """' + doc.replace("\n", "\n    ") + '"""')
    lines += _param_lines(exprs, printer)
    for s, e in subs:
        lines.append(f"    {s} = {printer.doprint(e)}")
    for (out, _), e in zip(outputs, reduced):
        lines.append(f"    {out} = {printer.doprint(e)}")
    lines.append(f"    return {', '.join(o for o, _ in outputs)}")
    return "\n".join(lines) + "\n"


def kernels_module() -> str:
    parts = [_header("kernels"),
             '"""Scalar kernels of the Spiral Zipper model, derived with sympy KanesMethod.\n\n'
             "One generic circle, one generic roller-circle contact, wheel/band core, force laws and\n"
             "energies. The assembly in ``spiral_zipper.py`` loops over circles and contacts.\n"
             '"""\n',
             "import math\n\nimport numba as nb\n\n\n"
             "@nb.njit(cache=True)\n"
             "def fpow(x, n):\n"
             '    """x**n, by multiplication for n = 1, 2, 3, 4 (equal to within rounding, much faster than pow)."""\n'
             "    if n == 3.0:\n        return x * x * x\n"
             "    if n == 2.0:\n        return x * x\n"
             "    if n == 4.0:\n        x2 = x * x\n        return x2 * x2\n"
             "    if n == 1.0:\n        return x\n"
             "    return x ** n\n"]
    for k in kernels() + energy_kernels():
        parts.append("\n\n" + _function(k.name, k.args, list(k.outputs), k.doc))
    for law in LAWS:
        for fn in law.functions():
            parts.append("\n\n" + _function(fn.name, fn.args, [("value", fn.expr)], fn.doc))
    return "".join(parts)


def spiral_zipper_module(kernels_text: str) -> str:
    index_lines = "\n".join(f"_I_{p.name} = {i}" for i, p in enumerate(PARAMETERS))
    names = ",\n".join(f'    "{p.name}"' for p in PARAMETERS)
    units = ",\n".join(f'    "{p.name}": ("{p.unit}", "{p.doc}")' for p in PARAMETERS)
    bounds = ",\n".join(f'    "{p.name}": "{p.bound}"' for p in PARAMETERS)
    # Numba's cache is keyed on this file's own stamp, not on the kernels it calls: carrying the
    # kernels' hash here makes any kernel change change this file too (new cache entries).
    digest = hashlib.sha256(kernels_text.encode()).hexdigest()
    template = (Path(__file__).with_name("assembly_template.py")).read_text()
    body = template.split("# --- template begins ---\n", 1)[1]
    return (
        _header("assembly")
        + '"""Spiral Zipper right-hand side: assembly of the generated kernels.\n\n'
        f"State vector: {STATE_ORDER};\nN_c = (len(x) - N_AUX)//2 - 2.\n"
        "Parameter vector p: float64 array in the order of ``PARAM_NAMES``; see ``PARAM_DOCS``.\n"
        "Drive array (see docs/CONTRACT.md): [K, t_0..t_{K-1}, v_0..v_{K-1}, c_0..c_{K-1}].\n"
        "Imports only math, numpy and numba.\n"
        '"""\n'
        "import math\n\nimport numba as nb\nimport numpy as np\n\n"
        "from .kernels import (circle_energy, circle_kernel, contact_distance_sq, contact_kernel,\n"
        "                      core_energy, core_kernel, impact_normal_force, impact_potential,\n"
        "                      lugre_force, lugre_z_dot, slider_torque, traction_coulomb_force,\n"
        "                      band_effects_torque, traction_tangential_force, drive_compliance_torque)\n\n"
        f"KERNELS_SHA256 = \"{digest}\"\n\n"
        f"PARAM_NAMES = (\n{names},\n)\n"
        "PARAM_INDEX = {name: i for i, name in enumerate(PARAM_NAMES)}\n"
        "#: name -> (SI unit, meaning)\n"
        f"PARAM_DOCS = {{\n{units},\n}}\n"
        "#: name -> admissible values, checked by szdyn.params.validate\n"
        f"PARAM_BOUNDS = {{\n{bounds},\n}}\n\n"
        f"AUX_STATES = {AUX_STATES!r}\n"
        "N_AUX = len(AUX_STATES)\n\n"
        f"{index_lines}\n"
        + body
    )


INIT = '''"""Generated Spiral Zipper model code (numpy + numba only; no SymPy).

``spiral_zipper`` holds the right-hand side ``rhs(t, x, p, drive, out)``, the parameter order
``PARAM_NAMES`` and helpers; ``kernels`` holds the per-circle and per-contact kernels.
"""
'''


def generate(out_dir: Path) -> list[Path]:
    """Write all generated files into ``out_dir``; return their paths."""
    out_dir.mkdir(parents=True, exist_ok=True)
    kernels_text = kernels_module()
    files = {
        "__init__.py": _header("package") + INIT,
        "kernels.py": kernels_text,
        "spiral_zipper.py": spiral_zipper_module(kernels_text),
    }
    written = []
    for name, text in files.items():
        path = out_dir / name
        tmp = path.with_suffix(".tmp")
        tmp.write_text(text)
        tmp.replace(path)
        written.append(path)
    return written
