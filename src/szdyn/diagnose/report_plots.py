"""The diagnosis's figures: residuals against time and features, candidate scores, fits.

Split from :mod:`.report`, which calls :func:`_plots` into its staging directory with the
effects list of the JSON dict it has built.
"""
from __future__ import annotations

import math
from pathlib import Path

import numpy as np

from ..plots import _pyplot, save_png
from .locate import feature_table


def _plots(d, out: Path, effects):
    """Every PNG of a fitted diagnosis ``d`` into ``out``; ``effects`` is diagnosis.json's
    ``effects`` list (ranked, with scores), which the caller has already built."""
    plt = _pyplot()
    recs = d.recordings_
    n = len(recs)
    ncol = min(3, n)
    nrow = math.ceil(n / ncol)
    fig, axes = plt.subplots(nrow, ncol, figsize=(4.2 * ncol, 2.6 * nrow), squeeze=False, sharey=True)
    for k, r in enumerate(recs):
        ax = axes[k // ncol][k % ncol]
        ax.plot(r.t_feat, r.y - d.base_speed_[k], lw=1, label="calibrated base")
        if d.selected_:
            ax.plot(r.t_feat, r.y - d.final_speed_[k], lw=1, label="updated")
        ax.axhspan(-d.floor_, d.floor_, color="0.85", lw=0)
        ax.set_title(f"{r.name} ({r.role})", fontsize=8)
        ax.set_xlabel("t (s)")
    axes[0][0].set_ylabel("residual omega_b (rad/s)")
    axes[0][0].legend(fontsize=7)
    for k in range(n, nrow * ncol):
        axes[k // ncol][k % ncol].axis("off")
    fig.tight_layout()
    save_png(fig, out / "residual_time.png")

    ft = feature_table(recs, [d.base_speed_[k] for k in range(n)])
    r_all = np.concatenate([r.y - d.base_speed_[k] for k, r in enumerate(recs)])
    fig, axes = plt.subplots(1, 4, figsize=(15, 3.2), sharey=True)
    for ax, (name, lab) in zip(axes, (("band_speed", "band speed (rad/s)"), ("band_accel", "band accel. (rad/s^2)"),
                                      ("time", "time in recording (s)"), ("sin_band_angle", "sin(band angle)"))):
        ax.scatter(ft[name], r_all, s=3, c=ft["load"], cmap="viridis")
        ax.set_xlabel(lab)
    axes[0].set_ylabel("residual omega_b (rad/s)")
    fig.suptitle("calibrated base model: residual against physical features (colour: load)", fontsize=9)
    fig.tight_layout()
    save_png(fig, out / "residual_features.png")

    fig, ax = plt.subplots(figsize=(7, 3.2))
    ids = [e["id"] for e in effects]
    ax.barh(ids, [e["score"] for e in effects], color=["C3" if e["selected"] else "C0" for e in effects])
    ax.axvline(d.rule.min_explained, color="k", ls="--", lw=0.8)
    ax.set_xlabel("share of the excess residual energy explained")
    ax.invert_yaxis()
    fig.tight_layout()
    save_png(fig, out / "candidates.png")

    held = [k for k, r in enumerate(recs) if r.role != "fit"] or list(range(n))
    _fit_panels(plt, d, held, lambda r: r.y, d.base_speed_, d.final_speed_, "measured",
                "omega_b (rad/s)", 2.4, out / "heldout_fit.png")
    tq = [k for k, r in enumerate(recs) if d.base_torque_.get(k) is not None]
    if tq:
        _fit_panels(plt, d, tq, lambda r: r.tau, d.base_torque_, d.final_torque_, "measured (K_t * current)",
                    "motor torque (N m)", 2.2, out / "torque_fit.png")



def _fit_panels(plt, d, idx, measured, before, after, label, ylabel, height, path):
    """One panel per recording ``idx``: measured, the calibrated base and (if an effect was
    selected) the updated model, against time."""
    fig, axes = plt.subplots(len(idx), 1, figsize=(7, height * len(idx)), squeeze=False)
    for ax, k in zip(axes[:, 0], idx):
        r = d.recordings_[k]
        ax.plot(r.t_feat, measured(r), "k", lw=1.2, label=label)
        ax.plot(r.t_feat, before[k], lw=1, label="before (calibrated base)")
        if d.selected_:
            ax.plot(r.t_feat, after[k], lw=1, ls="--", label=f"after (+ {d.selected_[0]})")
        ax.set_title(f"{r.name} ({r.role})", fontsize=8)
        ax.set_ylabel(ylabel)
    axes[-1, 0].set_xlabel("t (s)")
    axes[0, 0].legend(fontsize=7)
    fig.tight_layout()
    save_png(fig, path)
