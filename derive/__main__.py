"""``python -m derive --out generated``: regenerate the Numba model code."""
from __future__ import annotations

import argparse
import time
from pathlib import Path

from .codegen import generate


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(prog="python -m derive", description=__doc__)
    ap.add_argument("--out", type=Path, default=Path("generated"), help="output directory (default: generated)")
    args = ap.parse_args(argv)
    t0 = time.perf_counter()
    for path in generate(args.out):
        print(f"wrote {path}")
    print(f"derivation and code generation took {time.perf_counter() - t0:.1f} s")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
