"""The next recording to take: a wheel-speed protocol that tells the diagnosis's contenders apart.

When the recordings leave the answer open (rival effects that each explain much of the mismatch,
or "unexplained" with candidates that explain part of it), more of the same recordings will not
decide it: the contenders were fitted to them and agree there by construction. Two models that
agree on ramps from rest can differ elsewhere, where their physics differs: friction that falls
*over time* (``friction_drift``) and friction that falls *with speed* (``slider_stribeck``) agree
on a ramp from rest, but only the second comes back when the band stops and starts again.

:class:`NextRecording` runs every contender (the answer's updated model and the refitted rivals,
each with its own fitted coefficients) on a small library of wheel-speed protocols at the
recordings' lightest and heaviest loads, and ranks the protocols by how far apart the contenders'
smoothed band speeds are, in noise floors (the diagnosis's own floor): the protocol to record
next. The same figure on the recordings already taken says how much the new one adds. Nothing
here changes the diagnosis's answer.

The protocols are scaled to the largest wheel speed recorded, so they stay within the speeds
the model was fitted on (a protocol at speeds never recorded would separate the contenders by
extrapolation, which no one should trust).
"""
from __future__ import annotations

import itertools
import math
import time
from dataclasses import dataclass

import numpy as np

from ..drive import Sampled
from .data import FEATURE_DT, Prepared, feature_grid
from .engine import FeatureModel, rms

__all__ = ["PROTOCOLS", "Protocol", "NextRecording", "BREAKAWAY_SHARE", "MIN_SEPARATION", "MIN_SHARE", "MAX_RIVALS"]

#: A refitted rival is a contender when it explains at least this share of the mismatch (the
#: selection rule's own scale, ``explained``; a rival explaining less is not an answer the
#: recordings leave open).
MIN_SHARE = 0.25
#: At most this many rivals besides the answer (each costs one run per protocol and load).
MAX_RIVALS = 2
#: Noise floors of separation for a protocol to settle the answer: were one contender true, the
#: other would miss the new recording by about this many floors, the selection rule's
#: ``rival_floor`` (a model within 1.3 floors fits; impact bumps that differ between the
#: contenders' coefficients alone give about one floor).
MIN_SEPARATION = 2.0
#: A contender's band is *held at rest* where its speed is below this share of the wheel's while
#: the wheel runs faster than :data:`HELD_WHEEL` of the scale speed (the wheel slips over a band
#: that has not broken away).
HELD_SHARE = 0.05
HELD_WHEEL = 0.1
#: Share of the time the wheel runs during which a contender's band is held at rest, from which a
#: protocol counts as a *break-away* protocol, ranked after the others: there the contenders
#: differ mostly by whether and when the band breaks away, a cliff in the coefficients that a fit
#: does not cross (docs/DIAGNOSIS-DESIGN.md, "The next recording to take": on slider_stribeck
#: 45 a slow ramp at 1 kg, a contender's band held all of it, separated the contenders by 120
#: floors and left the diagnosis unable to fit it; a stop and restart, held 13 %, named the
#: effect. Built on that one case).
BREAKAWAY_SHARE = 0.5


@dataclass(frozen=True)
class Protocol:
    """A wheel-speed profile, piecewise linear, in units of the largest recorded wheel speed.

    Attributes
    ----------
    id : str
    description : str
        What the wheel does.
    reveals : str
        Which physics it separates, and why.
    t : tuple of float
        Knot times (s), from 0, increasing.
    w : tuple of float
        Wheel speed at the knots, as a fraction of the scale speed (signed).
    """

    id: str
    description: str
    reveals: str
    t: tuple
    w: tuple

    def drive(self, scale: float) -> Sampled:
        """The wheel speed (rad/s) for a scale speed ``scale`` (rad/s)."""
        return Sampled(t=np.array(self.t, dtype=float), omega=scale * np.array(self.w, dtype=float))

    @property
    def duration(self) -> float:
        return float(self.t[-1])


PROTOCOLS = (
    Protocol("stop_and_restart", "ramp to half speed, hold, ramp to rest, rest 1 s, start again",
             "friction that depends on band speed returns at every stop and start; friction that "
             "depends on time does not",
             (0.0, 2.0, 4.0, 6.0, 7.0, 9.0, 11.0), (0.0, 0.5, 0.5, 0.0, 0.0, 0.5, 0.5)),
    Protocol("slow_ramp", "ramp from rest to half speed over 10 s",
             "whether and when the band breaks away from rest as the wheel speeds up slowly: "
             "static and low-speed friction against the traction, without the inertia of a start",
             (0.0, 10.0), (0.0, 0.5)),
    Protocol("long_hold", "ramp to half speed in 2 s, hold 13 s",
             "constant speed for long: friction changing with time, free of speed effects",
             (0.0, 2.0, 15.0), (0.0, 0.5, 0.5)),
    Protocol("reversal", "ramp to half speed, hold, reverse through rest to minus half speed, hold",
             "both directions in one recording, passing through rest: direction-dependent "
             "friction, constant load torques",
             (0.0, 2.0, 4.0, 6.0, 8.0), (0.0, 0.5, 0.5, -0.5, -0.5)),
    Protocol("speed_steps", "steps of a quarter, half and full speed, 2 s each",
             "slip at three held speeds: speed-proportional drag against Coulomb friction",
             (0.0, 1.0, 3.0, 4.0, 6.0, 7.0, 9.0), (0.0, 0.25, 0.25, 0.5, 0.5, 1.0, 1.0)),
    Protocol("fast_start", "ramp to full speed in 0.25 s, hold 4 s",
             "a sharp transient: drive compliance, encoder delay, traction in transients",
             (0.0, 0.25, 4.25), (0.0, 1.0, 1.0)),
)


def _pair_key(a: str, b: str) -> str:
    return f"{a} vs {b}"


class NextRecording:
    """Rank wheel-speed protocols by how well they would tell the diagnosis's contenders apart.

    Parameters
    ----------
    protocols : sequence of Protocol, optional
        Default :data:`PROTOCOLS`.
    min_share : float
        A refitted rival is a contender when it explains at least this share (default
        :data:`MIN_SHARE`).
    max_rivals : int
        Rivals besides the answer (default :data:`MAX_RIVALS`).
    workers : int, optional
        Processes for the model runs (default: the diagnosis's).
    log : callable(str), optional

    Attributes (after :meth:`fit`)
    ------------------------------
    contenders_ : list of str
        The answer first (its selected effect, or ``"calibrated base"``), then the rivals.
    why_not_ : str or None
        Why nothing was ranked (no rival, "none"); None when :attr:`table_` is filled.
    scale_ : float
        Largest recorded wheel speed (rad/s), the protocols' scale.
    loads_ : list of float
        Loads (kg) the protocols are run at.
    floor_ : float
        The diagnosis's noise floor (rad/s).
    on_recordings_ : dict of str -> float
        Per pair of contenders (``"a vs b"``): RMS difference of their smoothed band speeds over
        the recordings already taken, in noise floors.
    table_ : list of dict
        Per protocol and load: ``protocol``, ``load_kg``, ``separation`` (per pair, in noise
        floors), ``min_separation`` (over the pairs), ``held_at_rest_s`` (the most time any
        one contender's band is held at rest, s; :data:`HELD_SHARE`), ``held_share`` (that over the
        time the wheel runs) and ``breakaway`` (the share reaches :data:`BREAKAWAY_SHARE`);
        break-away rows last, each group by ``min_separation``, largest first.
    recommended_ : dict or None
        The first row of :attr:`table_`, with the protocol's ``description`` and ``reveals`` and
        ``sufficient``: its ``min_separation`` reaches :data:`MIN_SEPARATION` and it is no
        break-away row (else no protocol of the library would settle the answer, and the report
        says so). None when no row is finite.
    predictions_ : dict
        For that row: ``t`` (s), ``omega_w`` (rad/s) and per contender its smoothed band speed
        (rad/s), for the plot.
    n_runs_ : int
        Model runs made.
    seconds_ : float
        Wall-clock time of :meth:`fit` (s; 0 when nothing was ranked).
    """

    def __init__(self, protocols=None, *, min_share: float = MIN_SHARE, max_rivals: int = MAX_RIVALS,
                 workers: int | None = None, log=None):
        self.protocols = tuple(PROTOCOLS if protocols is None else protocols)
        self.min_share = min_share
        self.max_rivals = max_rivals
        self.workers = workers
        self.log = log or (lambda msg: None)

    # -- who is compared --------------------------------------------------------------------
    def _contenders(self, d) -> list:
        """``(label, (model_changes, sensor_changes))``: the answer's model, then the rivals."""
        answer = d.selected_[0] if d.selected_ else "calibrated base"
        out = [(answer, d.final_.hypothesis.point(d.final_.x))]
        rivals = sorted((k for k in d.refits_ if k not in d.selected_
                         and d.refits_[k]["explained"] >= self.min_share),
                        key=lambda k: -d.refits_[k]["explained"])
        for k in rivals[:self.max_rivals]:
            res = d.refits_[k]["result"]
            out.append((k, res.hypothesis.point(res.x)))
        return out

    # -- runs --------------------------------------------------------------------------------
    def _protocol_recordings(self, recs) -> list:
        """One :class:`.data.Prepared` per protocol and load, from the recordings' parameters
        (the recording nearest in load, with its load set): measured parts are zeros."""
        out = []
        for proto, load in itertools.product(self.protocols, self.loads_):
            tmpl = min(recs, key=lambda r: (abs(r.load_kg - load) if math.isfinite(r.load_kg) else math.inf))
            drive = proto.drive(self.scale_)
            tf = feature_grid(0.0, proto.duration)
            out.append(Prepared(name=f"next:{proto.id}@{load:g}", role="protocol",
                                params=tmpl.params.replace(m_b=load), drive=drive, t0=0.0,
                                t1=proto.duration, t_feat=tf, y=np.zeros_like(tf),
                                omega_w=np.interp(tf, drive.t, drive.omega), theta_b=np.zeros_like(tf),
                                rec=None, conditions={"load_kg": load}))
        return out

    def fit(self, d) -> "NextRecording":
        """Rank the protocols for a fitted :class:`~.diagnosis.Diagnosis` ``d``."""
        t_start = time.perf_counter()
        recs = d.recordings_
        self.seconds_ = 0.0
        self.floor_ = float(d.floor_)
        self.scale_ = max(float(np.max(np.abs(r.omega_w))) for r in recs)
        loads = sorted({r.load_kg for r in recs if math.isfinite(r.load_kg)})
        self.loads_ = sorted({loads[0], loads[-1]}) if loads else [float(recs[0].params["m_b"])]
        self.contenders_, self.table_, self.on_recordings_ = [], [], {}
        self.recommended_, self.predictions_, self.n_runs_ = None, {}, 0
        if d.verdict_ == "none":
            self.why_not_ = "nothing is missing: no contenders to tell apart"
            return self
        cont = self._contenders(d)
        self.contenders_ = [c for c, _ in cont]
        if len(cont) < 2:
            self.why_not_ = (f"no refitted rival explains {self.min_share:.0%} of the mismatch or more: "
                             "the recordings leave no second answer open")
            return self
        self.why_not_ = None
        points = [p for _, p in cont]
        pairs = list(itertools.combinations(range(len(cont)), 2))
        self.log(f"next recording: {len(self.protocols)} protocols x {len(self.loads_)} loads for "
                 f"{', '.join(self.contenders_)}")
        workers = self.workers if self.workers is not None else getattr(d, "workers", None)
        precs = self._protocol_recordings(recs)
        # one batch on one pool: the recordings already taken (from the default wheel phase, like
        # the protocols) and the protocols
        n = len(recs)
        with FeatureModel(list(recs) + precs, workers=workers) as fm:
            both = fm.speeds(points, range(n + len(precs)))
            self.n_runs_ = fm.n_runs_
        for i, j in pairs:
            diff = np.concatenate([a - b for a, b in zip(both[i][:n], both[j][:n])])
            self.on_recordings_[_pair_key(self.contenders_[i], self.contenders_[j])] = rms(diff) / self.floor_
        sp = [row[n:] for row in both]
        ran = [[bool(np.any(v[k])) for k in range(len(precs))] for v in sp]   # a failed run is all zeros
        failed = sum(not x for r in ran for x in r)
        rows = []
        for k, pr in enumerate(precs):
            proto = self.protocols[k // len(self.loads_)]
            sep = {_pair_key(self.contenders_[i], self.contenders_[j]):
                   rms(sp[i][k] - sp[j][k]) / self.floor_ if ran[i][k] and ran[j][k] else math.nan
                   for i, j in pairs}
            vals = [v for v in sep.values() if math.isfinite(v)]
            moving = np.abs(pr.omega_w) > HELD_WHEEL * self.scale_
            # a failed run's zeros are no band held at rest
            held = max((int(np.sum(moving & (np.abs(v[k]) < HELD_SHARE * np.abs(pr.omega_w))))
                        for i, v in enumerate(sp) if ran[i][k]), default=0)
            share = held / max(int(np.sum(moving)), 1)
            rows.append({"protocol": proto.id, "load_kg": pr.load_kg, "separation": sep,
                         "min_separation": min(vals) if len(vals) == len(sep) else math.nan,
                         "held_at_rest_s": held * FEATURE_DT, "held_share": share,
                         "breakaway": share >= BREAKAWAY_SHARE})
        order = sorted(range(len(rows)), key=lambda k: (
            rows[k]["breakaway"],
            -rows[k]["min_separation"] if math.isfinite(rows[k]["min_separation"]) else math.inf))
        if failed:
            self.log(f"next recording: {failed} protocol run(s) failed; their rows are NaN")
        self.table_ = [rows[k] for k in order]
        k = order[0]
        best = rows[k]
        if math.isfinite(best["min_separation"]):
            proto = self.protocols[k // len(self.loads_)]
            self.recommended_ = {**best, "description": proto.description, "reveals": proto.reveals,
                                 "sufficient": best["min_separation"] >= MIN_SEPARATION and not best["breakaway"]}
            pr = precs[k]
            self.predictions_ = {"t": pr.t_feat, "omega_w": pr.omega_w,
                                 **{c: sp[i][k] for i, c in enumerate(self.contenders_)}}
        self.seconds_ = time.perf_counter() - t_start
        return self

    # -- outputs -----------------------------------------------------------------------------
    def to_dict(self) -> dict:
        """The machine-readable record (``diagnosis.json``'s ``next_recording``)."""
        return {"contenders": self.contenders_, "why_not": self.why_not_,
                "scale_speed": self.scale_, "loads_kg": self.loads_, "noise_floor": self.floor_,
                "on_recordings": self.on_recordings_, "protocols": self.table_,
                "recommended": self.recommended_, "model_runs": self.n_runs_, "seconds": self.seconds_,
                "library": [{"id": p.id, "description": p.description, "reveals": p.reveals,
                             "t": list(p.t), "omega_w_over_scale": list(p.w)} for p in self.protocols]}

    def to_markdown(self) -> list:
        """Lines of the report's section."""
        L = ["## The next recording to take", ""]
        if self.why_not_ is not None:
            return L + [f"Not ranked: {self.why_not_}.", ""]
        pairs = list(self.on_recordings_)
        L += ["Contenders: " + ", ".join(f"`{c}`" for c in self.contenders_)
              + " (the answer first, then the refitted rivals explaining at least "
              f"{self.min_share:.0%} of the mismatch, each with its own fitted coefficients). Each "
              "was run on the wheel-speed protocols below (scaled to the largest recorded wheel "
              f"speed, {self.scale_:.3g} rad/s; at "
              + ", ".join(f"{x:g}" for x in self.loads_) + " kg), from the default wheel phase. "
              "Separation: RMS difference of the two models' smoothed band speeds over the protocol, "
              f"in noise floors ({self.floor_:.3g} rad/s). It is a prediction of the fitted models, "
              f"not a measurement ({self.n_runs_} model runs, {self.seconds_:.0f} s).", "",
              "On the recordings already taken: "
              + "; ".join(f"{p} {self.on_recordings_[p]:.2f}" for p in pairs) + " floors.", ""]
        if self.recommended_ is not None:
            r = self.recommended_
            what = (f"**Record next: `{r['protocol']}` at {r['load_kg']:g} kg**" if r["sufficient"] else
                    "**Every protocol of the library holds a contender's band at rest** (break-away, "
                    f"below); the best is `{r['protocol']}` at {r['load_kg']:g} kg" if r["breakaway"] else
                    f"**No protocol of the library separates every pair by {MIN_SEPARATION:g} noise floors** "
                    f"(were one contender true, the other would still fit a new recording about as well); "
                    f"the best is `{r['protocol']}` at {r['load_kg']:g} kg")
            L += [what + f" ({r['description']}; {r['reveals']}): separation "
                  + "; ".join(f"{p} {r['separation'][p]:.2f}" for p in pairs)
                  + " floors. See next_recording.png.", ""]
        L += ["| protocol | load (kg) | " + " | ".join(pairs) + " | band held at rest (s, share) |",
              "|---|---|" + "---|" * len(pairs) + "---|"]
        for r in self.table_:
            L.append(f"| {r['protocol']} | {r['load_kg']:g} | "
                     + " | ".join(f"{r['separation'][p]:.2f}" for p in pairs)
                     + f" | {r['held_at_rest_s']:.2f} ({r['held_share']:.0%})"
                     + f"{', break-away' if r['breakaway'] else ''} |")
        if any(r["breakaway"] for r in self.table_):
            L += ["", f"Break-away rows (a contender's band held at rest for {BREAKAWAY_SHARE:.0%} or more of "
                  "the time the wheel runs) come last whatever their separation: there the contenders "
                  "differ mostly by whether and when the band breaks away, a cliff the fit does not cross."]
        return L + [""]

    def plot(self, path) -> bool:
        """The contenders' predicted band speeds on the recommended protocol (PNG); False when
        there is nothing to plot."""
        if not self.predictions_:
            return False
        from ..plots import _pyplot, save_png

        plt = _pyplot()
        p = self.predictions_
        fig, (ax, bx) = plt.subplots(2, 1, figsize=(7, 5), sharex=True)
        ax.plot(p["t"], p["omega_w"], "k", lw=0.8, label="wheel (protocol)")
        for c in self.contenders_:
            ax.plot(p["t"], p[c], lw=1, label=c)
        ax.set_ylabel("speed (rad/s)")
        ax.legend(fontsize=7)
        ref = p[self.contenders_[0]]
        for c in self.contenders_[1:]:
            bx.plot(p["t"], p[c] - ref, lw=1, label=f"{c} - {self.contenders_[0]}")
        bx.axhspan(-self.floor_, self.floor_, color="0.85", lw=0, label="noise floor")
        bx.set_xlabel("t (s)")
        bx.set_ylabel("difference (rad/s)")
        bx.legend(fontsize=7)
        r = self.recommended_
        fig.suptitle(f"{'next recording' if r['sufficient'] else 'best protocol (not sufficient)'}: "
                     f"{r['protocol']} at {r['load_kg']:g} kg", fontsize=9)
        fig.tight_layout()
        save_png(fig, path)
        return True
