"""The diagnosis as an estimator: ``Diagnosis(...).fit(recordings)`` (scikit-learn style).

Steps (each a module of its own):

1. calibrate the base model's coefficients on the fit recordings (:mod:`.fit`);
2. estimate the noise floor (:mod:`.noise`);
3. locate the mismatch in time, regime and frequency (:mod:`.locate`);
4. screen every candidate of the library linearly, refit the shortlist nonlinearly, and select
   with :class:`~.selection.SelectionRule` (held-out data + information criterion);
5. keep the refitted model of the selected effect as the updated model.
"""
from __future__ import annotations

import math
import time

import numpy as np

from .candidates import CANDIDATES, Candidate
from .engine import FeatureModel, rms
from .fit import Hypothesis, fit_hypothesis, jacobian
from .locate import locate
from .noise import bump_noise, sensor_noise
from .selection import SelectionRule, screen

__all__ = ["Diagnosis"]


class Diagnosis:
    """Calibrate, locate, name, refit.

    Parameters
    ----------
    candidates : sequence of str or Candidate, optional
        The library to screen (default: all of :data:`~.candidates.CANDIDATES`).
    rule : SelectionRule, optional
    shortlist : int
        Candidates refitted nonlinearly after the linear screening.
    max_jac : int
        Jacobians per nonlinear fit (calibration: twice this).
    workers : int, optional
        Processes for the model runs (default: CPU count).
    log : callable(str), optional
        Progress messages (e.g. ``print`` to stderr).
    progress : callable(int), optional
        Called with 1 after each model run.

    Attributes (after :meth:`fit`)
    ------------------------------
    calibrated_ : FitResult
        Base model fitted to the fit recordings.
    floor_ : float
        Noise floor of the compared feature (rad/s).
    floor_parts_ : dict
        ``sensor`` and ``bump`` parts (rad/s).
    mismatch_ : bool
        Whether the calibrated base model misses something significant.
    location_ : dict
        Output of :func:`.locate.locate` for the calibrated base model.
    screening_ : list of dict
        Per candidate: linearised fit RMSE, step.
    refits_ : dict of str -> dict
        Per refitted candidate: ``result`` (FitResult), ``heldout_rmse``, scores.
    selected_ : list of str
        Selected effect ids ([] for none or unexplained).
    verdict_ : str
        ``"none"``, ``"selected"`` or ``"unexplained"``.
    final_ : FitResult
        The updated model (the selected candidate's refit, else the calibrated base).
    heldout_ : dict
        ``before``/``after`` held-out RMSE (rad/s), overall and per recording.
    timings_ : dict
        Wall-clock seconds per step.
    """

    def __init__(self, candidates=None, rule: SelectionRule | None = None, *, shortlist: int = 3,
                 max_jac: int = 6, workers: int | None = None, log=None, progress=None):
        self.candidates = candidates
        self.rule = rule or SelectionRule()
        self.shortlist = shortlist
        self.max_jac = max_jac
        self.workers = workers
        self.log = log or (lambda msg: None)
        self.progress = progress

    def _library(self) -> list:
        if self.candidates is None:
            return list(CANDIDATES.values())
        return [c if isinstance(c, Candidate) else CANDIDATES[c] for c in self.candidates]

    def fit(self, recordings) -> "Diagnosis":
        """Run the diagnosis on prepared recordings (:func:`.data.prepare`).

        At least one recording must have role ``"fit"``; held-out ones (role ``"heldout"``)
        are never used to fit, only to select and to report.
        """
        recs = list(recordings)
        fit_idx = [i for i, r in enumerate(recs) if r.role == "fit"]
        held_idx = [i for i, r in enumerate(recs) if r.role != "fit"]
        if not fit_idx:
            raise ValueError("no fit recordings")
        all_idx = fit_idx + held_idx
        self.timings_ = {}
        clock = time.perf_counter()

        def lap(name):
            nonlocal clock
            now = time.perf_counter()
            self.timings_[name] = round(now - clock, 2)
            clock = now

        p0 = recs[fit_idx[0]].params
        start = {k: p0[k] for k in ("k_c", "b_c", "k_imp", "mu_s", "mu_k")}
        with FeatureModel(recs, workers=self.workers, progress=self.progress) as model:
            self.model_ = model
            # 1. calibrate
            self.log(f"calibrating k_c, b_c, k_imp, mu_s, mu_k on {len(fit_idx)} recording(s)")
            base_h = Hypothesis(start)
            cal = fit_hypothesis(model, base_h, fit_idx, max_jac=2 * self.max_jac)
            self.calibrated_ = cal
            self.log(f"calibrated: fit RMSE {cal.rmse_fit:.4g} rad/s after {cal.extra['njac']} Jacobians")
            lap("calibrate")

            # 2. noise floor
            base_mc, _ = base_h.point(cal.x)
            sens = [sensor_noise(recs[i]) for i in fit_idx]
            bump = [bump_noise(model, i, base_mc) for i in fit_idx]
            s_sens = math.sqrt(np.mean(np.square(sens)))
            # median: one recording whose start flips between stick and slip must not inflate the floor
            s_bump = float(np.median(bump))
            self.floor_ = math.hypot(s_sens, s_bump)
            self.floor_parts_ = {"sensor": s_sens, "bump": s_bump}
            self.mismatch_ = self.rule.mismatch(cal.rmse_fit, self.floor_)
            self.log(f"noise floor {self.floor_:.4g} rad/s (sensor {s_sens:.3g}, bumps {s_bump:.3g}); "
                     f"calibrated base is {cal.rmse_fit / self.floor_:.2f}x the floor")
            lap("noise_floor")

            # 3. locate (all recordings, calibrated base)
            sp = model.speeds([base_h.point(cal.x)], all_idx)[0]
            self.base_speed_ = dict(zip(all_idx, sp))
            self.location_ = locate([recs[i] for i in all_idx], sp, floor=self.floor_)
            h0 = rms(np.concatenate([recs[i].y - self.base_speed_[i] for i in held_idx])) if held_idx else math.nan
            h0_rec = {i: rms(recs[i].y - self.base_speed_[i]) for i in held_idx}
            lap("locate")

            # 4. screening (linear) on the fit recordings
            self.log(f"screening {len(self._library())} candidate effects")
            J_base, r0 = jacobian(model, base_h, cal.x, fit_idx)
            lo_b, hi_b = base_h.bounds()
            self.screening_ = []
            for cand in self._library():
                h = Hypothesis(start, cand)
                xc = np.concatenate([cal.x, h.x_start()[h.n_base:]])
                cols = list(range(h.n_base, len(xc)))
                Jc, _ = jacobian(model, h, xc, fit_idx, cols=cols)
                lo_h, hi_h = h.bounds()
                dlo = np.concatenate([lo_b - cal.x, lo_h[h.n_base:] - xc[h.n_base:]])
                dhi = np.concatenate([hi_b - cal.x, hi_h[h.n_base:] - xc[h.n_base:]])
                dx, rss = screen(r0, J_base, Jc, dlo, dhi)
                self.screening_.append({"id": cand.id, "rmse_linear": math.sqrt(rss / r0.size),
                                        "x_start": (xc + dx).tolist()})
            self.screening_.sort(key=lambda s: s["rmse_linear"])
            lap("screen")

            # 5. nonlinear refit of the shortlist
            self.refits_ = {}
            n_short = self.shortlist if self.mismatch_ else 0
            for s in self.screening_[:n_short]:
                cand = CANDIDATES[s["id"]] if s["id"] in CANDIDATES else next(
                    c for c in self._library() if c.id == s["id"])
                self.log(f"refitting base + {cand.id}")
                h = Hypothesis(start, cand)
                res = fit_hypothesis(model, h, fit_idx, x0=np.array(s["x_start"]), max_jac=self.max_jac)
                hc = rms(model.residuals([h.point(res.x)], held_idx)[0]) if held_idx else math.nan
                # held-out score: the median per-recording ratio, so that one recording flipped
                # across the full-slip cliff does not decide alone
                ratios = [rms(model.residuals([h.point(res.x)], [i])[0]) / max(h0_rec[i], 1e-12)
                          for i in held_idx]
                hc_med = h0 * float(np.median(ratios)) if held_idx else 1.0
                sc = self.rule.assess(b=cal.rmse_fit, c=res.rmse_fit, floor=self.floor_,
                                      h0=h0 if held_idx else 1.0, hc=hc_med,
                                      n_fit=res.n_fit, k=len(cand.params))
                self.refits_[cand.id] = {"result": res, "heldout_rmse": hc, **sc}
                self.log(f"  {cand.id}: fit RMSE {res.rmse_fit:.4g}, held-out {hc:.4g} rad/s, "
                         f"explains {sc['explained']:.0%}, dBIC {sc['dbic']:.1f}")
            lap("refit")

            # 6. decide
            eligible = [k for k, v in self.refits_.items() if v["eligible"]]
            if not self.mismatch_:
                self.verdict_, self.selected_ = "none", []
            elif eligible:
                best = max(eligible, key=lambda k: (self.refits_[k]["explained"], -self.refits_[k]["heldout_rmse"]))
                self.verdict_, self.selected_ = "selected", [best]
            else:
                self.verdict_, self.selected_ = "unexplained", []
            self.final_ = self.refits_[self.selected_[0]]["result"] if self.selected_ else cal
            fh = self.final_.hypothesis
            after = {}
            for i in held_idx:
                after[recs[i].name] = rms(model.residuals([fh.point(self.final_.x)], [i])[0])
            before = {recs[i].name: rms(recs[i].y - self.base_speed_[i]) for i in held_idx}
            ha = rms(model.residuals([fh.point(self.final_.x)], held_idx)[0]) if held_idx else math.nan
            self.heldout_ = {"before": {"heldout_rmse": h0, "per_recording": before},
                             "after": {"heldout_rmse": ha, "per_recording": after}}
            self.final_speed_ = dict(zip(all_idx, model.speeds([fh.point(self.final_.x)], all_idx)[0]))
            lap("decide")
            self.n_runs_ = model.n_runs_
            self.n_failed_ = model.n_failed_
        self.recordings_ = recs
        return self
