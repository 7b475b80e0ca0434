"""Exchanging fit and held-out recordings when the split hid the mismatch.

Held-out recordings judge; they never choose what is fitted. But a fixed split can put the
only recording that shows an effect on the held-out side: out-of-sample friction_asymmetry
seed 14 held out the one run that was both backward and heavily loaded. The calibrated base
reproduced the four fit recordings (1.13x the noise floor), so the answer was "none", while
that held-out run was 18x the floor. A user would move it among the fit recordings and run
again; :func:`exchange_pairs` says which fit recording goes the other way, so that the held-out
set keeps its size, hides no more from the fit than it must (every load and travel direction
keeps a fit recording where the recordings allow), and covers the same kind of run (same travel
direction and speed, another load, where that hides nothing). On that case the second pass
named friction_asymmetry with fric_asym 1.8 % off the truth.

When the manifest names no held-out recordings, :func:`choose_heldout` picks them so that the
split does not hide a condition in the first place (:mod:`szdyn.heldout`): every (load, travel
direction) pair keeps a fit recording where the recordings allow, and a held-out recording
sits inside the loads and speeds fitted in its direction (the model interpolates to it).
"""
from __future__ import annotations

import math

import numpy as np

from ..heldout import least_hiding, lost_pairs, split_features

__all__ = ["choose_heldout", "hidden_conditions", "with_heldout", "exchange_pairs", "exchanged"]


def _direction(rec) -> float:
    """Travel direction of a prepared recording: sign of its mean measured wheel speed."""
    return float(np.sign(np.mean(rec.omega_w)))


def _speed(rec) -> float:
    """Typical drive speed of a prepared recording: its RMS measured wheel speed (rad/s)."""
    return float(np.sqrt(np.mean(np.square(rec.omega_w))))


def exchange_pairs(recs, missed) -> dict:
    """Which fit recording to hold out in exchange for each held-out one in ``missed``.

    Parameters
    ----------
    recs : list of Prepared
    missed : iterable of str
        Names of held-out recordings to move among the fit recordings, worst first.

    Returns
    -------
    dict of str -> str
        Held-out name -> fit name. The partner is, first, one whose holding out leaves the
        fewest (load, travel direction) pairs without a fit recording (as the split itself is
        chosen, :func:`choose_heldout`), then the fit recording most like the held-out one: same
        travel direction, then nearest RMS wheel speed (relative), then nearest load; each fit
        recording is used once, and at least one stays a fit recording. Held-out recordings
        without a partner stay held out.

    Notes
    -----
    Without the first criterion the partner of a run of the grid's design was the run of the
    same speed at the other load, whose other forward run was already held out: the exchanged
    split hid that load's forward travel from the fit. load_lift seed 20 was then named
    ``friction_asymmetry`` (a lift and a direction-dependent friction coincide on the two
    held-out forward 1 kg runs), and load_lift seed 63 in another protocol (4 of 6 runs fitted,
    the 1 kg forward ones stalled) was named with tau_lift 88 % off.
    """
    by_name = {r.name: r for r in recs}
    index = {r.name: i for i, r in enumerate(recs)}
    feats = [_features(r) for r in recs]
    held = {r.name for r in recs if r.role != "fit"}
    free = [r for r in recs if r.role == "fit"]
    pairs = {}
    for name in missed:
        if len(free) < 2:
            break
        h = by_name[name]
        s = max(_speed(h), 1e-9)

        def unlike(r):
            dl = abs(r.load_kg - h.load_kg)
            hidden = lost_pairs(feats, [index[k] for k in (held - {name}) | {r.name}])
            return (len(hidden), _direction(r) != _direction(h), round(abs(_speed(r) - s) / s, 2),
                    dl if math.isfinite(dl) else math.inf)
        p = min(free, key=unlike)
        pairs[name] = p.name
        held = (held - {name}) | {p.name}
        free.remove(p)
    return pairs


def exchanged(recs, pairs) -> list:
    """Copies of ``recs`` with the roles of each pair swapped, fit recordings first."""
    held = {r.name for r in recs if r.role != "fit"}
    return with_heldout(recs, (held - set(pairs)) | set(pairs.values()))


def _features(rec):
    return split_features(rec.load_kg, _direction(rec), _speed(rec))


def choose_heldout(recs) -> tuple:
    """Held-out recordings when the manifest has no ``[split]``.

    As many as every third recording from the second would give (none of a single recording,
    1 of 2-4, 2 of 5-7, ...), chosen by :func:`szdyn.heldout.least_hiding` with the manifest's
    order as preference: every (load, direction) pair keeps a fit recording where the
    recordings allow, then the held-out ones lie within the loads and speeds fitted in their
    direction, then every load and direction keeps a fit recording. Holding out the only
    backward run at the heaviest load, say, would leave the fit blind to anything that shows
    only there (out-of-sample friction_asymmetry seeds 14 and 18).

    Parameters
    ----------
    recs : list of Prepared
        In manifest order; reads ``name``, ``load_kg`` and ``omega_w`` (direction: sign of the
        mean wheel speed; speed: its RMS).

    Returns
    -------
    tuple of str
        Names of the held-out recordings, in manifest order.
    """
    best = least_hiding([_features(r) for r in recs], len(range(1, len(recs), 3)))
    return tuple(recs[i].name for i in best)


def with_heldout(recs, names) -> list:
    """Copies of ``recs`` with exactly ``names`` held out, fit recordings first."""
    from dataclasses import replace

    names = set(names)
    out = [replace(r, role="heldout" if r.name in names else "fit") for r in recs]
    out.sort(key=lambda r: r.role != "fit")
    return out


def hidden_conditions(recs) -> list:
    """The (load, direction) conditions that only held-out recordings have.

    The fit cannot see what shows only there (friction asymmetry at the heavier load, say);
    the report says so, since the held-out error is then the only sign of it.

    Parameters
    ----------
    recs : list of Prepared
        With their roles.

    Returns
    -------
    list of dict
        ``load_kg`` (None when the manifest gives none), ``direction`` (+1/-1 sign of the mean
        wheel speed, 0 standing), ``travel`` ("forward", "backward", "standing") and
        ``recordings`` (names), in recording order.
    """
    held = [i for i, r in enumerate(recs) if r.role != "fit"]
    travel = {1.0: "forward", -1.0: "backward", 0.0: "standing"}
    return [{"load_kg": load, "direction": d, "travel": travel[d], "recordings": [recs[i].name for i in idx]}
            for (load, d), idx in lost_pairs([_features(r) for r in recs], held).items()]
