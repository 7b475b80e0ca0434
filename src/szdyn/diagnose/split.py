"""Exchanging fit and held-out recordings when the split hid the mismatch.

Held-out recordings judge; they never choose what is fitted. But a fixed split can put the
only recording that shows an effect on the held-out side: out-of-sample friction_asymmetry
seed 14 held out the one run that was both backward and heavily loaded. The calibrated base
reproduced the four fit recordings (1.13x the noise floor), so the answer was "none", while
that held-out run was 18x the floor. A user would move it among the fit recordings and run
again; :func:`exchange_pairs` says which fit recording goes the other way, so that the held-out
set keeps its size and covers the same kind of run (same travel direction and speed, another
load, where the recordings allow). On that case the second pass named friction_asymmetry with
fric_asym 1.8 % off the truth.

When the manifest names no held-out recordings, :func:`choose_heldout` picks them so that the
split does not hide a condition in the first place: every load and travel direction stays
among the fit recordings where the recordings allow, and a held-out recording sits inside the
loads and speeds the fit recordings span (the model interpolates to it).
"""
from __future__ import annotations

import itertools
import math

import numpy as np

__all__ = ["choose_heldout", "hidden_conditions", "least_hiding", "split_cost", "with_heldout",
           "exchange_pairs", "exchanged"]

#: largest number of held-out sets :func:`least_hiding` compares one by one (beyond: greedy)
_EXHAUSTIVE = 5000


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
        Held-out name -> fit name. The partner is the fit recording most like the held-out
        one: same travel direction first, then nearest RMS wheel speed (relative), then nearest
        load; each fit recording is used once, and at least one stays a fit recording.
        Held-out recordings without a partner stay held out.
    """
    by_name = {r.name: r for r in recs}
    free = [r for r in recs if r.role == "fit"]
    pairs = {}
    for name in missed:
        if len(free) < 2:
            break
        h = by_name[name]
        s = max(_speed(h), 1e-9)

        def unlike(r):
            dl = abs(r.load_kg - h.load_kg)
            return (_direction(r) != _direction(h), round(abs(_speed(r) - s) / s, 2),
                    dl if math.isfinite(dl) else math.inf)
        p = min(free, key=unlike)
        pairs[name] = p.name
        free.remove(p)
    return pairs


def exchanged(recs, pairs) -> list:
    """Copies of ``recs`` with the roles of each pair swapped, fit recordings first."""
    from dataclasses import replace

    swap = set(pairs) | set(pairs.values())
    out = [replace(r, role="heldout" if r.role == "fit" else "fit") if r.name in swap else r for r in recs]
    out.sort(key=lambda r: r.role != "fit")
    return out


def conditions(load_kg: float, direction: float, speed: float) -> tuple:
    """What :func:`split_cost` reads of one recording: ``(load key, load kg, direction, speed)``.

    ``load_kg`` NaN when unknown (the key is then None; otherwise the load rounded), direction
    +1/-1 (0: standing), speed a typical drive speed (rad/s; compared within a direction).
    """
    x = float(load_kg)
    return (round(x, 6) if math.isfinite(x) else None), x, float(direction), float(speed)


def _conditions(rec) -> tuple:
    return conditions(rec.load_kg, _direction(rec), _speed(rec))


def split_cost(cond, held) -> tuple:
    """How much the split with held-out indices ``held`` hides from the fit (lower is better).

    ``cond`` holds :func:`conditions` of every recording. In order: (load, direction) cells
    left without a fit recording; held-out recordings outside the loads or speeds that the fit
    recordings of their direction span (extrapolation, 10 % slack on speed); loads and
    directions left without a fit recording; and, negated, how varied the held-out set is
    (distinct loads + directions + speeds in 25 % classes).
    """
    held = set(held)
    fit = [c for i, c in enumerate(cond) if i not in held]
    out = [cond[i] for i in sorted(held)]
    lost_cells = len({c[0::2] for c in out} - {c[0::2] for c in fit})
    outside = 0
    for key, load, d, w in out:
        same = [c for c in fit if c[2] == d]
        loads = [c[1] for c in same if math.isfinite(c[1])]
        if not same:
            outside += 1
        elif math.isfinite(load) and loads and not min(loads) - 1e-9 <= load <= max(loads) + 1e-9:
            outside += 1
        elif not 0.9 * min(c[3] for c in same) <= w <= 1.1 * max(c[3] for c in same):
            outside += 1
    lost_margins = len({c[0] for c in out} - {c[0] for c in fit}) + len({c[2] for c in out} - {c[2] for c in fit})
    variety = (len({c[0] for c in out}) + len({c[2] for c in out})
               + len({round(math.log(max(c[3], 1e-9)) / math.log(1.25)) for c in out}))
    return lost_cells, outside, lost_margins, -variety


def choose_heldout(recs) -> tuple:
    """Held-out recordings when the manifest has no ``[split]``.

    As many as every third recording from the second would give (none of a single recording,
    1 of 2-4, 2 of 5-7, ...), chosen to keep the fit recordings covering the conditions:
    the set with the lowest :func:`split_cost` (:func:`least_hiding`), ties to the earliest in
    manifest order. Holding out the only backward run at the heaviest load, say, would leave
    the fit blind to anything that shows only there (out-of-sample friction_asymmetry seeds 14
    and 18).

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
    best = least_hiding([_conditions(r) for r in recs], len(range(1, len(recs), 3)))
    return tuple(recs[i].name for i in best)


def least_hiding(cond, k: int) -> tuple:
    """The ``k`` held-out indices with the lowest :func:`split_cost`, ties to the earliest.

    Every set is compared when there are at most ``_EXHAUSTIVE`` (5000), else they are added
    one at a time. The first set tried is ``0 .. k-1``, so a caller that orders ``cond`` by
    preference keeps its first choice unless another hides less.

    Returns
    -------
    tuple of int
        Sorted indices into ``cond`` (empty for ``k`` = 0).
    """
    n = len(cond)
    if k <= 0:
        return ()
    if math.comb(n, k) <= _EXHAUSTIVE:
        best = min(itertools.combinations(range(n), k), key=lambda h: (split_cost(cond, h), h))
    else:
        best = ()
        for _ in range(k):
            i = min((j for j in range(n) if j not in best), key=lambda j: (split_cost(cond, best + (j,)), j))
            best = best + (i,)
    return tuple(sorted(best))


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
    fit = {_conditions(r)[0::2] for r in recs if r.role == "fit"}
    out = {}
    for r in recs:
        cell = _conditions(r)[0::2]
        if r.role != "fit" and cell not in fit:
            out.setdefault(cell, []).append(r.name)
    travel = {1.0: "forward", -1.0: "backward", 0.0: "standing"}
    return [{"load_kg": load, "direction": d, "travel": travel[d], "recordings": names}
            for (load, d), names in out.items()]
