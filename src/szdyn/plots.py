"""Figures (PNG). Matplotlib is imported lazily with the Agg backend (no display needed)."""
from __future__ import annotations

import io
from pathlib import Path

from .io import atomic_write_bytes


def _pyplot():
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    return plt


def save_png(fig, path, dpi: int = 120) -> Path:
    """Save ``fig`` as PNG atomically (never a half-written image) and close it."""
    buf = io.BytesIO()
    fig.savefig(buf, format="png", dpi=dpi)
    _pyplot().close(fig)
    return atomic_write_bytes(path, buf.getvalue())


def fig10_grid(panels, result, path) -> Path:
    """Fig. 10 for several contact models: rows = ramps, columns = models; each column's
    title says which of the thesis criteria (a)-(d) the model meets."""
    plt = _pyplot()
    models = list(panels)
    nrow = len(next(iter(panels.values())))
    fig, axes = plt.subplots(nrow, len(models), figsize=(5.2 * len(models), 2.6 * nrow), squeeze=False,
                             sharey="row")
    for c, m in enumerate(models):
        crit = result["models"][m]["criteria"]
        marks = " ".join(f"({k}){'+' if crit[name]['passed'] else '-'}"
                         for k, name in zip("abcd", ("slip_at_constant_speed", "set_by_wheel_speed",
                                                      "no_drop_after_ramp", "rises_with_wheel_speed")))
        for r, (label, o) in enumerate(panels[m]):
            ax = axes[r, c]
            ax.plot(o["t"], o["u_w"], label="wheel $u_w$", lw=1.2)
            ax.plot(o["t"], o["u_b"], label="band $u_b$", lw=0.7)
            ax.plot(o["t"], o["rel_speed"], label="relative $u_w-u_b$", lw=0.7)
            ax.grid(alpha=0.3)
            if r == 0:
                ax.set_title(f"{m}: {marks}", fontsize=10)
            if c == 0:
                ax.set_ylabel(f"{label}\nrad/s", fontsize=9)
            if r == nrow - 1:
                ax.set_xlabel("time (s)")
    axes[0, 0].legend(loc="upper left", fontsize=7)
    fig.suptitle("thesis-fig10: criteria (a) slip at constant speed, (b) set by wheel speed, "
                 "(c) no drop after ramp, (d) rises with wheel speed (+ met, - not met)", fontsize=9)
    fig.tight_layout()
    return save_png(fig, path)
