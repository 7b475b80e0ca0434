"""Figures (PNG). Matplotlib is imported lazily with the Agg backend (no display needed)."""
from __future__ import annotations

from pathlib import Path


def _pyplot():
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    return plt


def fig10(runs, path) -> Path:
    """Thesis Fig. 10 style: wheel, band and relative angular speed against time, one panel
    per run. ``runs`` is a list of ``(label, outputs)`` with the :class:`szdyn.simulate.Run`
    output columns."""
    plt = _pyplot()
    fig, axes = plt.subplots(len(runs), 1, figsize=(8, 2.8 * len(runs)), squeeze=False)
    for ax, (label, o) in zip(axes[:, 0], runs):
        ax.plot(o["t"], o["u_w"], label="wheel $u_w$", lw=1.2)
        ax.plot(o["t"], o["u_b"], label="band $u_b$", lw=0.8)
        ax.plot(o["t"], o["rel_speed"], label="relative $u_w - u_b$", lw=0.8)
        ax.set_title(label)
        ax.set_ylabel("angular speed (rad/s)")
        ax.grid(alpha=0.3)
    axes[-1, 0].set_xlabel("time (s)")
    axes[0, 0].legend(loc="upper left", fontsize=8)
    fig.tight_layout()
    path = Path(path)
    tmp = path.with_name(f".{path.name}.tmp.png")
    fig.savefig(tmp, dpi=120)
    plt.close(fig)
    tmp.replace(path)  # atomic: never a half-written PNG
    return path
