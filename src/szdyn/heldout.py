"""Which recordings to hold out: a split that hides as little as it can from the fit.

Shared by the generator (:func:`szdyn.synth.synthesize` writes a ``[split]``) and the diagnosis
(:func:`szdyn.diagnose.split.choose_heldout`, when a manifest has none). Pure Python, so that
the generator does not load the diagnosis to use it.

A split hides a condition when only held-out recordings have it: out-of-sample
friction_asymmetry 14 and 18 held out the only backward run at 1 kg, where the asymmetry showed,
and the fit recordings could not see it (docs/DIAGNOSIS-DESIGN.md, "Splits that keep every load
and direction").
"""
from __future__ import annotations

import itertools
import math
from typing import NamedTuple

__all__ = ["SplitFeatures", "SplitCost", "split_features", "lost_pairs", "split_cost", "least_hiding"]

#: largest number of held-out sets :func:`least_hiding` compares one by one (beyond: swaps)
EXHAUSTIVE = 5000


class SplitFeatures(NamedTuple):
    """What :func:`split_cost` reads of one recording (see :func:`split_features`)."""

    load_key: float | None
    load_kg: float
    direction: float
    speed: float


class SplitCost(NamedTuple):
    """How much a split hides from the fit; compared in this order, lower is better."""

    #: (load, direction) pairs left without a fit recording
    lost_pairs: int
    #: held-out recordings outside the loads or speeds fitted in their direction (extrapolated)
    outside: int
    #: loads and directions left without a fit recording
    lost_margins: int
    #: minus the variety of the held-out set (distinct loads + directions + speed classes)
    neg_variety: int


def split_features(load_kg: float, direction: float, speed: float) -> SplitFeatures:
    """Features of one recording for :func:`split_cost`.

    Parameters
    ----------
    load_kg : float
        Payload (kg); NaN when unknown (the recording's load key is then None, else the load
        rounded to 1e-6 kg).
    direction : float
        Travel direction: +1 or -1 (0: standing; -0.0 is taken as 0).
    speed : float
        A typical drive speed (rad/s, >= 0; compared only within a direction).
    """
    x = float(load_kg)
    w = float(speed)
    return SplitFeatures(round(x, 6) if math.isfinite(x) else None, x, float(direction) + 0.0,
                         w if math.isfinite(w) else 0.0)


def _speed_class(w: float) -> int:
    """Speeds in classes 25 % wide (for the held-out set's variety)."""
    return round(math.log(max(w, 1e-9)) / math.log(1.25))


def lost_pairs(feats, held) -> dict:
    """The (load key, direction) pairs that only held-out recordings have.

    Parameters
    ----------
    feats : sequence of SplitFeatures
    held : iterable of int
        Indices of the held-out recordings.

    Returns
    -------
    dict of (float or None, float) -> list of int
        Each such pair with its held-out indices, in index order.
    """
    held = set(held)
    fit = {(f.load_key, f.direction) for i, f in enumerate(feats) if i not in held}
    out = {}
    for i in sorted(held):
        pair = (feats[i].load_key, feats[i].direction)
        if pair not in fit:
            out.setdefault(pair, []).append(i)
    return out


def split_cost(feats, held) -> SplitCost:
    """How much the split with held-out indices ``held`` hides from the fit.

    Parameters
    ----------
    feats : sequence of SplitFeatures
        One per recording.
    held : iterable of int
        Indices of the held-out recordings.

    Returns
    -------
    SplitCost
        A held-out recording is *outside* when no fit recording runs in its direction, when its
        load lies outside the fitted loads of that direction, or when its speed lies outside the
        fitted speeds of that direction (10 % slack).
    """
    held = set(held)
    fit = [f for i, f in enumerate(feats) if i not in held]
    out = [feats[i] for i in sorted(held)]
    outside = 0
    for f in out:
        same = [g for g in fit if g.direction == f.direction]
        loads = [g.load_kg for g in same if math.isfinite(g.load_kg)]
        if not same:
            outside += 1
        elif math.isfinite(f.load_kg) and loads and not min(loads) - 1e-9 <= f.load_kg <= max(loads) + 1e-9:
            outside += 1
        elif not 0.9 * min(g.speed for g in same) <= f.speed <= 1.1 * max(g.speed for g in same):
            outside += 1
    lost_margins = (len({f.load_key for f in out} - {f.load_key for f in fit})
                    + len({f.direction for f in out} - {f.direction for f in fit}))
    variety = (len({f.load_key for f in out}) + len({f.direction for f in out})
               + len({_speed_class(f.speed) for f in out}))
    return SplitCost(len(lost_pairs(feats, held)), outside, lost_margins, -variety)


def least_hiding(feats, k: int) -> tuple:
    """The ``k`` held-out indices that hide least, the caller's first choice where it can.

    The caller's first choice is ``0 .. k-1`` (order ``feats`` by preference). It stands unless
    another set has a lower :class:`SplitCost` in its first three parts (what is hidden or
    extrapolated); among those others, the more varied held-out set, then the earliest, wins.
    Every set is compared when there are at most :data:`EXHAUSTIVE`; beyond, the first choice
    is improved by exchanging one held-out recording at a time while that lowers the same key.

    Parameters
    ----------
    feats : sequence of SplitFeatures
    k : int
        How many to hold out (capped at ``len(feats) - 1``: one recording is always fitted).

    Returns
    -------
    tuple of int
        Sorted indices into ``feats`` (empty when ``k`` <= 0).
    """
    n = len(feats)
    k = min(k, n - 1)
    if k <= 0:
        return ()
    first = tuple(range(k))

    def key(h):
        c = split_cost(feats, h)
        return c[:3], h != first, c.neg_variety, h

    if math.comb(n, k) <= EXHAUSTIVE:
        return min(itertools.combinations(range(n), k), key=key)
    best, kb = first, key(first)
    improved = True
    while improved:
        improved = False
        for i in best:
            for j in range(n):
                if j in best:
                    continue
                h = tuple(sorted(set(best) - {i} | {j}))
                kh = key(h)
                if kh < kb:
                    best, kb, improved = h, kh, True
                    break
            if improved:
                break
    return best
