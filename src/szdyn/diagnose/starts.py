"""Where a candidate's refit starts: the effect switched on at finite amplitudes (the probes),
and the further starts of a refit that missed (:class:`RefitStarts`, a part of
:class:`~.diagnosis.Diagnosis`).

A gradient fit started with an effect "off" never switches it on where the calibrated model
sticks or slips fully (the effect's slope is zero there), and the refit's cost is rippled by the
impact bumps in the effect's amplitude and the base coefficients together. So the pass
(:mod:`.fit_pass`) tries, besides the linear step: the bound-fraction probes and a candidate's
own probes (:meth:`RefitStarts._starts`, evaluated by :meth:`RefitStarts._probe`), the third start
(:meth:`RefitStarts._probe_start`), the fourth (:meth:`RefitStarts._amplitude_start`) and the fifth
(:meth:`RefitStarts._multiple_starts`).
"""
from __future__ import annotations

import numpy as np

from .amplitude import amplitude_search
from .fit import FIT_TOL, Hypothesis, fit_hypothesis
from .selection import screen

__all__ = ["AMPLITUDE_MULTIPLES", "AMPLITUDE_PROBES", "RefitStarts"]

#: Multiples of the amplitude a refit left its effect at, from which the fifth start
#: (``Diagnosis(amplitude_starts=True)``, :meth:`RefitStarts._multiple_starts`) fits again at the
#: calibrated coefficients. The refit's cost is rippled in the effect's amplitude and the base
#: coefficients together, so a start a factor away can end in a deeper valley than the one the
#: refit stopped in: encoder_delay seed 53 (truth 5.46 ms; in sample for this start) stopped at 3.31 ms,
#: explaining 39 %; from x1.5 and x2 it ended at 4.87 and 4.77 ms, explaining 60 % and 61 %
#: (x0.5: 1.65 ms, 28 %), and with the start the diagnosis named it (4.77 ms).
AMPLITUDE_MULTIPLES = (0.5, 2.0)

#: Fractions of an effect amplitude's bound at which the probe screening and every refit try the
#: effect switched on (see :meth:`RefitStarts._starts`).
AMPLITUDE_PROBES = (0.25, 0.5)


class RefitStarts:
    """The refit starts of :class:`~.diagnosis.Diagnosis` (a base class of it: the methods read
    its options, ``rule``, ``floor_`` and the fit recordings' moving band speed)."""

    @staticmethod
    def _starts(h: Hypothesis, x_base, x_lin, speed=None, slider_scale=None) -> list:
        """Refit starts with the effect switched on at finite amplitudes.

        Each amplitude parameter (not a shape parameter) is set, one at a time, to each of
        :data:`AMPLITUDE_PROBES` times each nonzero bound, the base coefficients at ``x_base``
        and the other effect parameters at the linear step ``x_lin``. Where the calibrated model
        sticks (or slips fully) on a recording, an effect's slope from "off" is zero there and a
        gradient method started at "off" never switches it on; from these points it can.
        A candidate whose own ``probes`` replace these (``own_probes_replace``; an effect the base
        coefficients absorb wholesale) gives its starts instead (:meth:`_own_starts`).

        Parameters
        ----------
        speed, slider_scale : ndarray, optional
            See :meth:`_own_starts`; required by a candidate with ``own_probes_replace``.

        Returns
        -------
        list of ndarray
            Points in ``h``'s fit coordinates.
        """
        if h.candidate is not None and h.candidate.own_probes_replace:
            return RefitStarts._own_starts(h, x_base, x_lin, speed, slider_scale)
        return RefitStarts._bound_starts(h, x_base, x_lin)

    @staticmethod
    def _bound_starts(h: Hypothesis, x_base, x_lin) -> list:
        """The bound-fraction probes of :meth:`_starts` (every candidate has them; list of
        ndarray in ``h``'s fit coordinates)."""
        lo, hi = h.bounds()
        out = []
        for j in h.amplitude_indices():
            for bound in (lo[j], hi[j]):
                for f in AMPLITUDE_PROBES:
                    if bound != 0.0:
                        x = np.concatenate([x_base, x_lin[h.n_base:]])
                        x[j] = f * bound
                        out.append(x)
        return out

    @staticmethod
    def _own_starts(h: Hypothesis, x_base, x_lin, speed=None, slider_scale=None) -> list:
        """The candidate's own probes (``Candidate.probes``): the effect moved out of the base
        coefficients at ``x_base`` (the other effect parameters at the linear step ``x_lin``).

        Parameters
        ----------
        speed : ndarray, shape (n,)
            Measured band speed (rad/s) of the fit recordings' moving samples.
        slider_scale : ndarray, shape (n,), optional
            ``R_bo m_b g`` (N m) at each of those samples (probes that trade a torque against a
            friction coefficient need it).

        Returns
        -------
        list of ndarray
            Points in ``h``'s fit coordinates (none for a candidate without probes).
        """
        if h.candidate is None or h.candidate.probes is None:
            return []
        if speed is None:
            raise ValueError(f"{h.candidate.id}'s probes need the measured band speed")
        if slider_scale is not None and np.shape(slider_scale) != np.shape(speed):
            raise ValueError(f"{h.candidate.id}'s probes: slider_scale has shape {np.shape(slider_scale)}, "
                             f"the band speed {np.shape(speed)}")
        base = h.values(np.concatenate([x_base, x_lin[h.n_base:]]))
        base = {k: base[k] for k in ("k_c", "b_c", "k_imp", "mu_s", "mu_k")}
        return [h.inside(h.coordinates({**b, **e})) for e, b in h.candidate.probes(base, speed, slider_scale)]

    def _probe(self, model, h: Hypothesis, x_base, x_lin, fit_idx, *, own: bool | None = None) -> list:
        """The amplitude probes of :meth:`_starts` as they are and with the base coefficients
        corrected linearly, evaluated on the fit recordings.

        The calibration compensated for the missing effect on the recordings where the effect is
        small; switching it on must undo that compensation (e.g. mu_k for an asymmetry), which
        the base Jacobian of the screening (``_J_base``) does to first order: bounded least
        squares of that point's residual on the base columns. (Not for the candidate's own
        ``probes``, which carry their base change.)

        Parameters
        ----------
        own : bool, optional
            True: the candidate's own probes (:meth:`_own_starts`); False: the bound-fraction
            ones (:meth:`_bound_starts`); None (default): those of :meth:`_starts`.

        Returns
        -------
        list of (str, ndarray, float)
            Name of the start, the point (fit coordinates), fit RSS ((rad/s)^2).
        """
        if own is None:
            own = h.candidate.own_probes_replace
        probes = self._own_starts(h, x_base, x_lin, self._moving_speed, self._moving_slider_scale) \
            if own else self._bound_starts(h, x_base, x_lin)
        if not probes:
            return []
        lo, hi = h.bounds()
        nb = h.n_base
        out, corrected = [], []
        for x, r in zip(probes, model.residuals([h.point(x) for x in probes], fit_idx)):
            out.append(("effect probe moved out of the calibrated base" if own
                        else "calibrated + effect amplitude probe", x, float(r @ r)))
            if own:
                continue
            dx, _ = screen(r, self._J_base, np.zeros((r.size, 0)), lo[:nb] - x[:nb], hi[:nb] - x[:nb])
            xc = x.copy()
            xc[:nb] = np.clip(x[:nb] + dx, lo[:nb], hi[:nb])
            corrected.append(xc)
        if not corrected:
            return out
        for x, r in zip(corrected, model.residuals([h.point(x) for x in corrected], fit_idx)):
            out.append(("effect amplitude probe + linear base correction", x, float(r @ r)))
        return out

    def _probe_start(self, model, h: Hypothesis, x_nom, fit_idx):
        """The best amplitude probe of :meth:`_starts` at the base coefficients of ``x_nom`` (the
        second start: uncalibrated coefficients, effect as the first refit left it), if it fits
        the fit recordings better than ``x_nom`` itself; else None.

        For a first refit that left the effect off: out-of-sample position_periodic seed 13
        (calibrated base 19x the floor, mu_k 29 % high) refitted to a_rev = 1e-4 N m from the
        calibrated and from the uncalibrated coefficients; from the best probe the refit reached
        the truth's a_rev (0.020 N m) within 2 %. A third start rather than a better second
        one, because the better start does not always end better (friction_asymmetry seed 11:
        0.0269 from the probe against 0.0181 rad/s as refitted).

        Returns
        -------
        ndarray or None
            Start in ``h``'s fit coordinates.
        """
        probes = self._starts(h, np.asarray(x_nom)[:h.n_base], x_nom, self._moving_speed,
                              self._moving_slider_scale)
        if not probes:
            return None
        R = model.residuals([h.point(x) for x in [x_nom] + probes], fit_idx)
        rss = [float(r @ r) for r in R]
        k = int(np.argmin(rss[1:]))
        return probes[k] if rss[1 + k] < rss[0] else None

    def _amplitude_start(self, model, h: Hypothesis, best, x_nom, fit_idx):
        """The fourth start of a refit: the effect's amplitude searched over its whole range at
        the base coefficients of ``x_nom`` (the uncalibrated ones), then refitted from there.

        Only while the best refit so far (``best``, a FitResult) leaves more than
        ``rule.max_remaining`` noise floors (it does not explain the mismatch), and not for a
        candidate whose own probes replace the others (``own_probes_replace``). Near the
        full-slip cliff the effect's valley at the uncalibrated coefficients can be narrow and far
        from where the refits ended (load_lift seed 20: 0.052 rad/s within 0.01 N m of tau_lift
        0.09, the refits at 0.178 N m and 28x the floor; :mod:`.amplitude`). The caller adopts
        it only if it ends better: a start that fits better need not end better
        (friction_asymmetry seed 11).

        Returns
        -------
        FitResult or None
            The refit from the searched start; None when not tried.
        """
        if h.candidate is None or h.candidate.own_probes_replace \
                or best.rmse_fit <= self.rule.max_remaining * self.floor_:
            return None
        x4, _, n_ev = amplitude_search(model, h, x_nom, fit_idx)
        self.log(f"  fourth start for {h.candidate.id}: uncalibrated coefficients, amplitude searched "
                 f"over its range ({n_ev} points): "
                 + ", ".join(f"{k} = {v:.4g}" for k, v in h.candidate_values(x4).items()))
        return fit_hypothesis(model, h, fit_idx, x0=x4, max_jac=self.max_jac, tol=FIT_TOL)

    def _wants_fifth_start(self, refit: dict) -> bool:
        """Whether a candidate's best refit so far (its ``refits_`` entry: ``result``, a
        FitResult, and ``explained``) gets the fifth start (:meth:`_multiple_starts`): with
        ``amplitude_starts``, where it explains part of the mismatch but less than
        ``rule.min_explained`` and still leaves a mismatch (``rule.mismatch``). An effect that
        explains nothing is not there to be moved; one that explains enough is judged as it is."""
        return bool(self.amplitude_starts and 0.0 < refit["explained"] < self.rule.min_explained
                    and self.rule.mismatch(refit["result"].rmse_fit, self.floor_))

    def _multiple_starts(self, model, h: Hypothesis, best, x_cal, fit_idx):
        """The fifth start of a refit (``amplitude_starts``): the calibrated coefficients with the
        effect's amplitude parameters at each of :data:`AMPLITUDE_MULTIPLES` times where the
        best refit so far left them (its shape parameters as it left them), each refitted.

        Parameters
        ----------
        best : FitResult
            The candidate's best refit so far; its amplitude must not be all zero (there is no
            multiple of "off").
        x_cal : ndarray, shape (n_base,)
            The calibrated coefficients (fit coordinates).

        Returns
        -------
        (FitResult, float) or None
            The refit that ends with the smallest residual sum of squares and its start's
            multiple; None when no start was made (nothing to multiply) or none ended better
            than ``best``.
        """
        amp = h.amplitude_indices()
        if not amp or not np.any(best.x[amp] != 0.0):
            return None
        out = None
        for f in AMPLITUDE_MULTIPLES:
            x0 = np.concatenate([np.asarray(x_cal, dtype=float), best.x[h.n_base:]])
            x0[amp] = f * best.x[amp]
            res = fit_hypothesis(model, h, fit_idx, x0=h.inside(x0), max_jac=self.max_jac, tol=FIT_TOL)
            self.log(f"  fifth start for {h.candidate.id}: calibrated coefficients, amplitude x{f:g} of the "
                     f"refit's: fit RMSE {res.rmse_fit:.4g} rad/s, "
                     + ", ".join(f"{k} = {v:.4g}" for k, v in h.candidate_values(res.x).items()))
            if res.rss_fit < (best.rss_fit if out is None else out[0].rss_fit):
                out = (res, f)
        return out
