"""Fits taken further than one ``least_squares`` run: a stalled fit restarted from its linear
step, phase-profiled steps, the named effect polished with its own phases or profiled along the
force scale, and which of two fits of one candidate is kept (:class:`FitRefinements`, a part of
:class:`~.diagnosis.Diagnosis`).

The impact bumps ripple the fit cost, and the wheel phases estimated at one point bias a fit made
at them; these refinements leave a valley a single fit stops in, each adopted only when it fits
better (and, for a later fit of a candidate, when the held-out recordings do not choose the
earlier one: :meth:`FitRefinements._keeps_earlier`).
"""
from __future__ import annotations

import math
from contextlib import contextmanager

from .fit import FIT_TOL, Hypothesis, fit_hypothesis, gauss_newton_step, linear_step
from .fit_pass import phases_on
from .force_scale import SCALE_PROFILE_FACTORS, profile_along_force_scale
from .phase import estimate_phases, identified_phases

__all__ = ["FitRefinements", "PHASE_STEP_FRACTIONS"]

#: Fractions of the linearised step tried by a phase-profiled step (:meth:`FitRefinements._phase_step`);
#: beyond 1 because at fixed phases the fit's own steps were cut short.
PHASE_STEP_FRACTIONS = (0.25, 0.5, 1.0, 2.0)


class FitRefinements:
    """The fit refinements of :class:`~.diagnosis.Diagnosis` (a base class of it: the methods
    read its options, ``rule`` and ``floor_``, and write ``polish_`` and ``scale_profile_``)."""

    def _phase_step(self, model, h: Hypothesis, res, fit_idx, est: dict | None = None, *,
                    what: str = "calibration", max_jac: int | None = None):
        """Phase-profiled Gauss-Newton steps of a fit (the base calibration, or a candidate's
        refit), at most ``phase_steps`` (``second_look`` in the second look).

        The wheel phases are nuisance parameters of every run, estimated once at the first
        calibration. A fit with them held cannot leave its valley: a step of the coefficients
        moves the impact bumps, so at the old phases every longer step fits worse, while at the
        phases that fit the new point it may fit much better. Here the full linearised step from
        the fit's end is tried at :data:`PHASE_STEP_FRACTIONS` of its length, each trial point
        with the fit recordings' phases estimated at itself (the phases profiled out, as in
        variable projection); the best, if clearly better (``rule.min_dbic``), becomes the new
        start with its phases, and the fit continues from there. Measured on null 32 (the
        calibration at 3.2x the floor, the truth at 0.9x with its own phases): one step to
        0.0063 rad/s, the next 0.0060 (1.0x the floor); docs/DIAGNOSIS-DESIGN.md.

        Parameters
        ----------
        res : FitResult
            The fit (of ``h`` on ``fit_idx``, with the phases ``model.phases`` holds now).
        est : dict, optional
            Recording index -> :class:`.phase.PhaseEstimate`; updated in place for the fit
            recordings whose phases are re-estimated (the base's record).
        what : str
            The fit's name in the log.
        max_jac : int, optional
            Jacobians of each continued fit (default ``2 max_jac``, the calibration's budget).

        Returns
        -------
        FitResult
            ``res`` when no step fits clearly better, else the last fit, whose
            ``extra["fit_phases"]`` (recording index -> initial wheel angle, rad) holds the fit
            recordings' phases it was fitted with. ``model.phases`` is left as it was: the
            caller decides whose phases it holds (:meth:`_fit_phases`).
        """
        max_jac = 2 * self.max_jac if max_jac is None else max_jac
        entry = dict(model.phases)
        ladder = h.candidate.phase_ladder if h.candidate is not None else ()
        try:
            for k in range(self._steps):
                d = gauss_newton_step(model, h, res, fit_idx)
                trials = [(f"{a:g} of the linear step", h.inside(res.x + a * d)) for a in PHASE_STEP_FRACTIONS]
                if ladder and k == 0:
                    # the effect's own ladder: the linear step is taken at held phases, where an
                    # effect that is itself a shift of the wheel's phase cannot lower the cost
                    name = h.candidate.params[0].name
                    trials += [(f"{name} = {v:.3g}", h.inside(h.coordinates({**h.values(res.x), name: v})))
                               for v in ladder]
                saved, best = dict(model.phases), None
                for label, z in trials:
                    e = estimate_phases(model, h.point(z), fit_idx)
                    model.phases = {**saved, **identified_phases(e)}
                    r = model.residuals([h.point(z)], fit_idx)[0]
                    if best is None or r @ r < best[0]:
                        best = (float(r @ r), label, z, e)
                    model.phases = saved
                rss, label, z, e = best
                if self.rule.indistinguishable(rss_selected=rss, rss_other=res.rss_fit, n_fit=res.n_fit):
                    break   # (also when it fits worse)
                self.log(f"  {what}: phase-profiled step {k + 1} ({label}, phases estimated "
                         f"there): {math.sqrt(rss / res.n_fit):.4g} rad/s (was {res.rmse_fit:.4g}); fitting on from there")
                model.phases = {**saved, **identified_phases(e)}
                if est is not None:
                    est.update({i: q for i, q in e.items() if q.identified})
                nxt = fit_hypothesis(model, h, fit_idx, x0=z, max_jac=max_jac, tol=FIT_TOL)
                nxt.extra.update({**{k2: v for k2, v in res.extra.items() if k2 not in nxt.extra},
                                  "njac": nxt.extra["njac"] + res.extra["njac"], "phase_steps": k + 1,
                                  "fit_phases": phases_on(model, fit_idx)})
                self.log(f"  {what}: fit RMSE {nxt.rmse_fit:.4g} rad/s")
                res = nxt
        finally:
            model.phases = entry
        return res

    def _keeps_earlier(self, cid: str, res, heldout: float, later: str) -> bool:
        """Whether candidate ``cid``'s fit in ``refits_`` is kept over ``res``, a later fit of it
        that fits better (a further start, a restart from its linear or phase-profiled step, a
        continuation), by :meth:`~.selection.SelectionRule.heldout_decides`: the fit cannot
        part them (both within ``rule.rival_floor`` noise floors) and the held-out recordings
        can (the earlier holds out ``rule.rival_heldout`` times better or more).

        friction_asymmetry seed 49, out of sample: the second start fitted at 1.11 noise floors
        against the first's 1.34 and held out at 0.119 rad/s against 0.0093 (0.143 before), the
        effect exact either way; adopted, it left the held-out gain at 1.2x.

        Parameters
        ----------
        cid : str
            Candidate id.
        res : FitResult
            The later fit.
        heldout : float
            Its RMSE on all held-out recordings (rad/s; NaN without held-out recordings).
        later : str
            What the later fit is, for the log and the report ("the second start", ...).

        Returns
        -------
        bool
            True when the earlier fit is kept; it then records ``res`` in its
            ``extra["kept_over"]`` (the report's status line says the held-out recordings chose).
        """
        prev = self.refits_.get(cid)
        if prev is None or not self.rule.heldout_decides(
                fit_chosen=prev["result"].rmse_fit, heldout_chosen=prev["heldout_rmse"],
                fit_other=res.rmse_fit, heldout_other=heldout, floor=self.floor_):
            return False
        self.log(f"  {cid}: kept the earlier fit over {later}: fit RMSE {res.rmse_fit:.4g} against "
                 f"{prev['result'].rmse_fit:.4g} (both within {self.rule.rival_floor:g} noise floors), "
                 f"held-out {heldout:.4g} against {prev['heldout_rmse']:.4g} rad/s")
        prev["result"].extra.setdefault("kept_over", []).append(
            {"fit": later, "rmse_fit": float(res.rmse_fit), "heldout_rmse": float(heldout)})
        return True

    def _polish(self, model, res, fit_idx):
        """Phase-profiled steps of the named effect's refit ``res`` (see ``phase_polish``).

        Only for a candidate with a phase ladder (:attr:`~.candidates.Candidate.phase_ladder`)
        whose refit took no phase-profiled step of its own: its value was fitted at the fit
        recordings' phases estimated at the calibrated base, which a wheel-phase shift like a
        drive compliance's biases (towards a stiffer drive). At most ``phase_polish`` steps of
        :meth:`_phase_step`, with the ladder in the first; ``model.phases`` must hold the phases
        ``res`` was fitted with, and is left so.

        Returns
        -------
        FitResult
            ``res`` where no polish applies or no step fitted clearly better, else the polished
            fit (its ``extra["fit_phases"]`` the fit recordings' phases it was fitted with).
            Sets ``polish_`` where a polish was tried.
        """
        cand = res.hypothesis.candidate
        if self.phase_polish == 0 or cand is None or not cand.phase_ladder or res.extra.get("phase_steps"):
            return res
        self.log(f"polishing the named {cand.id} with phase-profiled steps (its value was fitted at "
                 "the wheel phases estimated without it)")
        steps, self._steps = self._steps, self.phase_polish
        try:
            out = self._phase_step(model, res.hypothesis, res, fit_idx, what=f"polish of {cand.id}",
                                   max_jac=self.max_jac)
        finally:
            self._steps = steps
        if out is not res:
            out.extra["phase_flag"] = "--phase-polish"  # the status line names where its steps came from
        names = [p.name for p in cand.params]

        def record(r):
            return {"values": {k: float(r.values[k]) for k in names}, "rmse_fit": float(r.rmse_fit)}

        self.polish_ = {"candidate": cand.id, "steps": int(out.extra.get("phase_steps", 0)) if out is not res else 0,
                        "units": {p.name: p.unit for p in cand.params}, "before": record(res), "after": record(out)}
        return out

    def _scale_profile(self, model, res, fit_idx):
        """The named effect's fit ``res`` started again along the force scale (see
        ``scale_profile`` and :func:`~.force_scale.profile_along_force_scale`).

        ``model.phases`` must hold the phases ``res`` was fitted with; each fit of the profile
        runs with them, and is left so.

        Returns
        -------
        FitResult
            The profile's best fit (its ``extra["fit_phases"]`` those of ``res``), or ``res``
            when none fits clearly better (the information criterion's margin,
            ``rule.indistinguishable``). Sets ``scale_profile_``; the caller judges the new fit
            on the held-out recordings and may keep ``res`` (``kept_by_heldout``).
        """
        cand = res.hypothesis.candidate
        if not self.scale_profile or cand is None:
            return res
        self.log(f"profiling the named {cand.id} along the force scale (every force x"
                 + ", x".join(f"{f:g}" for f in SCALE_PROFILE_FACTORS) + ")")
        best, rec = profile_along_force_scale(model, res.hypothesis, res, fit_idx, factors=SCALE_PROFILE_FACTORS,
                                              tol=FIT_TOL)
        if best is not res and self.rule.indistinguishable(rss_selected=best.rss_fit, rss_other=res.rss_fit,
                                                           n_fit=res.n_fit):
            best, rec["chosen"] = res, None    # better, but not clearly
        if best is not res:
            best.extra["fit_phases"] = dict(res.extra.get("fit_phases", {}))
            # the status line says which phase-profiled steps moved the phases it was fitted with
            best.extra.update({k: res.extra[k] for k in ("phase_steps", "phase_flag") if k in res.extra})
        names = [p.name for p in cand.params]

        def record(r):
            return {"values": {k: float(r.values[k]) for k in names}, "rmse_fit": float(r.rmse_fit),
                    "force": float(r.values["mu_k"] / res.values["mu_k"])}

        self.scale_profile_ = {"candidate": cand.id, **rec, "kept_by_heldout": False,
                               "units": {p.name: p.unit for p in cand.params},
                               "before": record(res), "after": record(best)}
        self.log("  " + ", ".join(f"x{f:g}: " + ("skipped" if r is None else f"{r:.4g}")
                                  for f, r in zip(rec["factors"], rec["rmse_fit"]))
                 + f" rad/s (the fit {res.rmse_fit:.4g})")
        return best

    @staticmethod
    @contextmanager
    def _fit_phases(model, res):
        """Run the model with the fit recordings' phases ``res`` was fitted with (its
        ``extra["fit_phases"]``, set by :meth:`_phase_step` and by :meth:`~.fit_pass.FitPass.assess`); the other
        recordings' phases as they are. Restores ``model.phases`` on exit."""
        saved = dict(model.phases)
        model.phases = {**saved, **res.extra.get("fit_phases", {})}
        try:
            yield
        finally:
            model.phases = saved

    def _unstall(self, model, h: Hypothesis, res, fit_idx, what: str = "calibration", max_jac: int | None = None):
        """Fit again from a fit's linear step while that step fits clearly better (at most
        ``unstall`` times; see the class docstring).

        Parameters
        ----------
        res : FitResult
            The fit (of ``h`` on ``fit_idx``) to check.
        what : str
            Its name in the log ("calibration", or "refit of <candidate id>").
        max_jac : int, optional
            Jacobians of each new fit (default ``2 max_jac``, the calibration's budget).

        Returns
        -------
        FitResult
            ``res`` itself when its linear step does not fit clearly better, else the last new
            fit, whose ``extra`` keeps ``res``'s start and restart and counts all Jacobians.
        """
        max_jac = 2 * self.max_jac if max_jac is None else max_jac
        for k in range(self.unstall):
            x, rss, step = linear_step(model, h, res, fit_idx)
            if self.rule.indistinguishable(rss_selected=rss, rss_other=res.rss_fit, n_fit=res.n_fit):
                break   # (also when the step fits worse)
            self.log(f"  the {what} stalled: its linear step ({step}) fits at {math.sqrt(rss / res.n_fit):.4g} "
                     f"rad/s (ended at {res.rmse_fit:.4g}); fitting again from there")
            nxt = fit_hypothesis(model, h, fit_idx, x0=x, max_jac=max_jac, tol=FIT_TOL)
            nxt.extra.update(njac=nxt.extra["njac"] + res.extra["njac"], unstalled=k + 1,
                             unstall_steps=[*res.extra.get("unstall_steps", []), step],
                             continued=res.extra.get("continued", False),
                             start=res.extra.get("start"), restart=res.extra.get("restart"))
            self.log(f"  {what}: fit RMSE {nxt.rmse_fit:.4g} rad/s ({nxt.rmse_fit / self.floor_:.2f}x the floor)")
            res = nxt
        return res
