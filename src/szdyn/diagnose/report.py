"""Write a fitted :class:`~szdyn.diagnose.diagnosis.Diagnosis`: JSON, Markdown, PNGs, parameters.

Files in ``out`` (written into a staging directory and moved in together at the end,
``diagnosis.json`` last, so that an interrupted run leaves the previous set whole):

* ``diagnosis.json`` — machine-readable result (schema of issue 5, plus details);
* ``report.md`` — what was compared, where the mismatch is, which effect, its parameters with
  uncertainty, its expression, the fit before/after, units;
* ``params.json`` — the updated model (:meth:`szdyn.params.ParameterSet.to_json`; load with
  ``python -m szdyn.run --params``);
* ``residual_time.png``, ``residual_features.png``, ``candidates.png``, ``heldout_fit.png``;
  ``torque_fit.png`` when the motor torque was compared (recordings with a current column).

The JSON dict (:mod:`.report_json`) and the figures (:mod:`.report_plots`) have modules of
their own; this one writes the Markdown and stages every file.
"""
from __future__ import annotations

import math

from ..io import atomic_write_text, staged_output, write_json
from .amplitude import AMPLITUDE_GRID
from .candidates import CANDIDATES
from .data import FEATURE_DT
from .starts import AMPLITUDE_MULTIPLES, AMPLITUDE_PROBES
from .phase import IDENTIFIED_SHARE, PHASE_UNCERTAINTY
# the JSON dict and the figures have their own modules; these names stay importable from here
from .report_json import COMPARED, UNITS, _clean, _f, _status, _to_json, to_json, updated_parameters
from .report_plots import _plots

__all__ = ["OUTPUT_FILES", "REPORT_TITLE", "write_report", "to_json", "updated_parameters"]

#: First line of every report.md (also how ``diagnose`` tells its own --out from someone else's).
REPORT_TITLE = "# szdyn diagnosis"
#: Every file :func:`write_report` may write; one a run does not write is removed from ``out``.
OUTPUT_FILES = ("params.json", "report.md", "diagnosis.json", "residual_time.png", "residual_features.png",
                "candidates.png", "heldout_fit.png", "torque_fit.png", "next_recording.png")


_WEIGHTED = ("**Weighted**: each recording's residual is multiplied by the common floor over its own "
             "floor, so that recordings whose impact bumps do not reproduce (they flip between "
             "tracking and slipping with the wheel phase) count less and reproducible ones more: {}. "
             "The base model was calibrated again with these weights, and every fit and held-out "
             "RMSE below (calibration, candidates, before and after, per recording) is in these "
             "weighted units: rad/s at the common floor, so that a correct model is near 1x the floor "
             "on every recording. The location section and the plots show the unweighted residual.")


def _force_scale_md(res) -> str:
    """One sentence on the force-scale secant of ``res`` (:mod:`.force_scale`)."""
    fs = res.extra.get("force_scale")
    if fs is None:
        return "They were not corrected along the force scale."
    if not fs["corrected"]:
        return f"They were not corrected along the force scale: {fs['reason']}."
    return ("The Jacobian they come from was corrected along the force scale (every force coefficient "
            f"and torque-like parameter scaled together): {100 * fs['step']:g} % of scale changes the "
            f"fit residual (the compared speed, and the weighted motor torque where compared) by "
            f"{_f(fs['measured'])} rad/s RMS in model runs, where the fit's Jacobian predicted "
            f"{_f(fs['predicted'])} (two runs per fit recording; the optimum is unchanged).")


def _nominated_md(d) -> str:
    n = d.nominated_
    head = (f"On the fit recordings the calibrated residual follows `{n['feature']}` most "
            f"(R^2 {n['r2']:.2f}; nomination threshold {d.nominate_r2}).")
    if n.get("phase_ladder"):
        head = (", ".join(f"`{k}`" for k in n["phase_ladder"]) + " refitted because this pass takes "
                "phase-profiled steps: its effect shifts the wheel's phase, which the phases estimated at "
                "the base absorb, so it is tried at amplitudes on a ladder, each with its own phases, "
                "whatever the screenings (made at the base's phases) say. " + head)
    if n["added"]:
        return head + " Refitted for that too, whatever their linear screening: " + \
            ", ".join(f"`{k}`" for k in n["added"]) + "."
    if n["ids"]:
        return head + " Its candidates (" + ", ".join(f"`{k}`" for k in n["ids"]) + ") were shortlisted anyway."
    if not d.mismatch_:
        return head + " Nothing significant is missing, so nothing was nominated."
    return head + " No candidate was nominated by it."


def _probing_md(d) -> str:
    if not d.probing_:
        return "No probe screening (nothing significant is missing, or it was switched off)."
    top = d.probing_[0]
    fr = " and ".join(f"{f:g}" for f in AMPLITUDE_PROBES)
    own = [q["id"] for q in d.probing_ if q.get("own_probes")]
    added = [k for k in dict.fromkeys(q["id"] for q in d.probing_ if q.get("added")) if k not in d.not_refitted_]
    spared = "".join(f" Not refitted: `{k}`, added by the probe screening after `{v['by']}` had explained "
                     f"{v['explained']:.1%} of the mismatch's excess within {d.rule.rival_floor:g} noise floors."
                     for k, v in d.not_refitted_.items())
    return (f"Probe screening (each candidate switched on at {fr} of its bounds, base coefficients "
            "as calibrated or corrected linearly; model runs"
            + (f"; {', '.join(f'`{k}`' for k in own)} at {'its' if len(own) == 1 else 'their'} own "
               "probes, moved out of the calibrated base coefficients and continued by one Jacobian, "
               "judged apart from the others" if own else "")
            + "): best " + ", ".join(f"`{q['id']}`{' (own probes)' if q.get('own_probes') else ''} "
                                     f"{_f(q['rmse_probe'])}" for q in d.probing_[:3])
            + f" rad/s against the calibrated base's {_f(top['rmse_base'])}"
            + (f"; refitted for it: {', '.join(f'`{k}`' for k in added)}." if added else ".") + spared
            + "".join(f" `{k}` was refitted with all its starts although `{v}` already fitted within "
                      f"{d.rule.rival_floor:g} noise floors: a sensor term does not settle a physical effect "
                      "that the calibration absorbed (it can imitate one)."
                      for k, v in d.sensor_not_settling_.items()))


def _detectable_md(d, js) -> list:
    """What these recordings can see: each candidate's smallest flagged amplitude (linearised)."""
    rows = [e for e in js["effects"] if e.get("detectable")]
    if not rows:
        return []
    L = ["### What these recordings can see", "",
         f"The smallest amplitude of each effect that would lift the calibrated fit above the mismatch "
         f"threshold ({d.rule.min_excess:g} noise floors) if nothing else were off: the part of its "
         "linear sensitivity that the base coefficients cannot absorb, at the calibrated point "
         "(`szdyn.diagnose.detect`). Smaller effects may be present and not flagged; the base model's "
         "own mismatch makes the practical threshold higher. `inf` (null in diagnosis.json): no linear trace from \"off\" "
         "(e.g. where the model sticks); the nonlinear refits may still see it. It is a local "
         "estimate: the base model refitted from another start can absorb more of an effect.", "",
         "| effect | amplitude | unit | smallest flagged (least visible direction) | most visible direction | at |",
         "|---|---|---|---|---|---|"]
    for e in sorted(rows, key=lambda e: e["id"]):
        for t in e["detectable"]:
            at = ", ".join(f"{k} = {_f(v)}" for k, v in t["at"].items()) or "-"
            worst, most = ("inf" if t[k] is None or math.isinf(t[k]) else _f(t[k])
                           for k in ("amplitude", "amplitude_most_visible"))
            L.append(f"| {e['id']} | {', '.join(t['parameters'])} | {t['unit']} | {worst} | {most} | {at} |")
    return L


def _segments_md(segments) -> list:
    """Markdown table rows of mismatch segments (``locate`` output)."""
    return (["| recording | t0 (s) | t1 (s) | regime | score (RMS / floor) |", "|---|---|---|---|---|"]
            + [f"| {m['recording']} | {m['t0']:.2f} | {m['t1']:.2f} | {m['regime']} | {m['score']:.1f} |"
               for m in segments])


def _heldout_scale_md(d) -> list:
    """What the missed held-out recordings do along the force scale (``heldout_scale_``)."""
    hs = d.heldout_scale_
    if not hs:
        return []
    f = hs["factors"]
    L = [f"**The missed held-out recordings along the force scale.** The {'updated' if d.selected_ else 'calibrated'} "
         f"model run again with every force scaled together by x{f[0]:.3f} to x{f[-1]:.3f} "
         f"(+-1 reported std of mu_k, {hs['sigma']:.1%}, in {len(f)} steps; "
         "`szdyn.diagnose.force_scale.heldout_along_force_scale`):"]
    for k, e in hs["recordings"].items():
        tried = ", ".join("failed" if r is None else f"{r:.1f}" for r in e["over_floor"])
        if e["reproduced"]:
            said, why = (f"reproduced at x{e['at_factor']:.3f} ({e['min']:.2f}x the floor)",
                         " Within the fitted uncertainty the model does reproduce it: the miss is the "
                         "force scale's uncertainty on a recording that depends on it sharply, not "
                         "evidence of something missing.")
        else:
            said, why = (f"nowhere within {d.rule.min_excess:g}x the floor (best {e['min']:.1f}x, at "
                         f"x{e['at_factor']:.3f})", " Not the force scale's uncertainty alone.")
        L.append(f"- `{k}`: {said}; RMSE / floor at the steps {tried}; {e['max']:.1f}x at worst.{why}")
    return L + [""]


def _all_reproduced_along_scale(d, names) -> bool:
    """Whether every recording of ``names`` was reproduced along the force scale (``heldout_scale_``)."""
    hs = d.heldout_scale_
    return bool(hs) and all(hs["recordings"].get(k, {}).get("reproduced", False) for k in names)


def _split_md(d) -> list:
    """Report paragraphs on the split: conditions only held-out recordings have, and an exchanged
    split (the pass that is the answer, or the one that was not)."""
    L = []
    for c in d.hidden_conditions_:
        load = "an unknown load" if c["load_kg"] is None else f"{c['load_kg']:g} kg"
        one = len(c["recordings"]) == 1
        verb = {"forward": "run{} forward", "backward": "run{} backward",
                "standing": "stand{} still"}[c["travel"]].format("s" if one else "")
        L += ["**The split hides a condition.** Only held-out "
              + ", ".join(f"`{k}`" for k in c["recordings"])
              + f" {verb} at {load}: the fit never sees that condition, so an effect that shows "
              "mostly there (friction that depends on the direction, the payload's weight) can be "
              "missed or mis-sized, and the held-out error is the only sign of it. To let the fit "
              "see it, hold out another recording instead (manifest `[split]`), or record a second "
              "run of that condition, and run again.", ""]
    if d.first_split_:
        f1 = d.first_split_
        named = f1.get("selected")
        said = (f"named {', '.join(named)}, but its updated model missed held-out " if named else
                f"said {f1['verdict']}: the calibrated base reproduced the fit recordings "
                f"({f1['calibrated_fit_over_floor']:.2f}x the floor) but missed held-out ")
        which = "The second look's pass" if f1.get("after_second_look") else "A first pass"
        L += [f"**Split exchanged.** {which} with " + ", ".join(f"`{k}`" for k in f1["heldout"])
              + f" held out {said}"
              + ", ".join(f"`{k}` ({f1['heldout_beyond_floor'][k]:.1f}x)" for k in f1["exchanged"])
              + " by more than " + f"{d.rule.max_remaining:g}x the floor, so the split may have hidden "
              "the mismatch. This diagnosis is the second pass, with "
              + ", ".join(f"`{k}` fitted and `{v}` held out instead" for k, v in f1["exchanged"].items())
              + f" (the fit recording most like it: same travel direction, then nearest speed, then "
              f"nearest load). {'That' if f1.get('after_second_look') else 'First'} pass: "
              f"{f1['seconds']:.0f} s, {f1['model_runs']} model runs.", ""]
    if d.unused_split_:
        u = d.unused_split_
        tried = ("**Split exchange tried.** The updated model misses held-out "
                 + ", ".join(f"`{k}` ({d.heldout_beyond_floor_[k]:.1f}x the floor)" for k in u["exchanged"])
                 + (". After the second look, a pass with " if u.get("after_second_look") else ". A second pass with ")
                 + ", ".join(f"`{k}` fitted and `{v}` held out" for k, v in u["exchanged"].items()))
        if u.get("worse_on"):
            L += [tried + f" named {', '.join(u['selected'])} too, but its model missed "
                  + ", ".join(f"`{k}` ({w:.1f}x its floor, against {f:.1f}x here)" for k, (f, w) in u["worse_on"].items())
                  + ", held out in both passes: the exchange hid more from the fit than it showed, so the "
                  f"answer of this split stands (second pass: {u['seconds']:.0f} s, {u['model_runs']} model runs).", ""]
        else:
            L += [tried + f" said {u['verdict']} (calibrated base {u['calibrated_fit_over_floor']:.2f}x the floor; "
                  f"{u['seconds']:.0f} s, {u['model_runs']} model runs), so the effect named here stands; "
                  + ("the updated model reproduced that recording with its forces scaled within their "
                     "uncertainty (above), so it depends sharply on the force scale."
                     if _all_reproduced_along_scale(d, u["exchanged"]) else
                     "that recording is either less reproducible than the floor says or shows something this "
                     "model does not have."), ""]
    return L


def _staged_md(d) -> list:
    """Report paragraph on the staged calibration (``staged_``), when it ran."""
    g = d.staged_
    if not g:
        return []
    what = (f"It fitted {g['ratio']:g}x better or more, so it was adopted: the calibration on all of them "
            "at once had stopped where the lighter loads' recordings flip between tracking and slipping "
            "(a plateau cut by cliffs), and everything below starts from the staged one."
            if g["adopted"] else
            f"Not adopted: it is taken only when it fits {g['ratio']:g}x better (a calibration that had "
            "stopped), and the calibration on all of them at once is the one used below.")
    return [f"**Staged calibration.** The base was also calibrated in two stages from the nominal "
            f"coefficients: on the {g['load_kg']:g} kg fit recording(s) first ({', '.join(f'`{n}`' for n in g['recordings'])}; "
            f"{_f(g['first_rmse_fit'])} rad/s on them), then on all fit recordings from there: "
            f"{_f(g['rmse_fit'])} rad/s, against {_f(g['calibrated_rmse_fit'])} rad/s from the nominal start. "
            + what, ""]


def _restart_md(d) -> list:
    """Report paragraph on a pass run again from the base its ablation found (``restart_``)."""
    if not d.restart_:
        return []
    r, ab = d.restart_, d.restart_["ablation"]
    return [f"**Calibration restarted.** A first pass calibrated the base at {ab['calibrated_rmse_fit']:.4g} "
            f"rad/s and said {r['verdict']}; its ablation refitted the base alone from `{ab['candidate']}`'s "
            f"coefficients to {ab['rmse_fit']:.4g} rad/s. The calibration had stopped in a valley of the base "
            "model itself, where the screening and the refits' starts were made, so this diagnosis is a second "
            f"pass with the calibration started at that base. First pass: {r['seconds']:.0f} s, "
            f"{r['model_runs']} model runs.", ""]


def _second_look_md(d) -> list:
    """Report paragraph on a pass run again with phase-profiled steps (``second_look_``; it only
    follows a first pass that said unexplained)."""
    if not d.second_look_:
        return []
    f = d.second_look_
    cost = f"First pass: {f['seconds']:.0f} s, {f['model_runs']} model runs."
    if (d.first_split_ or {}).get("after_second_look"):
        # that pass then missed a held-out recording, and the exchanged split's pass answers
        cost = "Its split was then exchanged (below). " + cost
    if f["start"] == "ablation":
        a = f["ablation"]
        return [f"**Second look.** A first pass said unexplained: its calibration stopped at "
                f"{a['calibrated_fit_over_floor']:.2f}x the floor, beyond the phase gate, but the base model "
                f"alone, refitted from `{a['candidate']}`'s coefficients (the ablation), fitted at "
                f"{a['fit_over_floor']:.2f}x, within it. The calibration had stopped in a valley of the base "
                "model itself, so before answering unexplained the pass ran again calibrated from that base, "
                f"with the wheel phases estimated and {f['steps']} phase-profiled step(s) (each trial point "
                f"judged with the phases estimated at it); this diagnosis is that pass. {cost}", ""]
    return [f"**Second look.** A first pass said unexplained: its calibrated base was "
            f"{f['calibrated_fit_over_floor']:.2f}x the floor (its wheel phases estimated: within the phase "
            "gate, which is judged with the bumps of a quarter-pitch shift), and no candidate explained the "
            "rest. Within the gate the calibration can stop in the valley of other wheel phases, so before "
            f"answering unexplained the pass ran again with {f['steps']} phase-profiled step(s) (each trial "
            f"point judged with the phases estimated at it); this diagnosis is that pass. {cost}", ""]


def _coefficient_floor_md(d) -> str:
    """Sentence on the bump part's coefficient share (``--coefficient-floor``), empty when off."""
    step = d.floor_parts_.get("coefficient_step")
    if not step:
        return ""
    return (f"The bumps count what a model {step:.3g} off (relative) in k_c or in the slider friction misses "
            "of them (`--coefficient-floor`), in quadrature with the wheel phase's share; per recording (phase, "
            "coefficients, rad/s): " + "; ".join(f"`{k}` {_f(v['bump_phase'], '.3g')}, "
                                                 f"{_f(v['bump_coefficients'], '.3g')}"
                                                 for k, v in d.floor_per_recording_.items()) + ". ")


def _scale_profile_md(d) -> list:
    """Report paragraph on the named effect's profile along the force scale (``scale_profile_``)."""
    p = d.scale_profile_
    if not p:
        return []
    runs = ", ".join(f"x{f:g} " + ("skipped" if r is None else _f(r))
                     for f, r in zip(p["factors"], p["rmse_fit"]))
    head = (f"**Profiled along the force scale.** Speed recordings fix the common scale of every force "
            f"only weakly, and the fit's valley along it is rippled, so `{p['candidate']}`'s fit was "
            f"started again with every force scaled ({runs} rad/s; the fit {_f(p['rmse_before'])}). ")
    if p["chosen"] is not None:
        vals = ", ".join(f"{k} {_f(p['before']['values'][k], '.4g')} -> {_f(v, '.4g')} {p['units'][k]}"
                         for k, v in p["after"]["values"].items())
        return [head + f"The start at x{p['chosen']:g} fitted clearly better and was taken: every force "
                f"x{p['after']['force']:.3f}, {vals}; fit RMSE {_f(p['before']['rmse_fit'])} -> "
                f"{_f(p['after']['rmse_fit'])} rad/s. The answer is unchanged; the values, the updated "
                "model and the after figures are the profiled ones.", ""]
    if p["kept_by_heldout"]:
        return [head + "A start fitted clearly better but held out worse, both within the close rivals' "
                "floors: the held-out recordings kept the fit (see its status line).", ""]
    return [head + "None fitted clearly better: the values stand.", ""]


def _polish_md(d) -> list:
    """Report paragraph on the named effect's phase-profiled polish (``polish_``), when tried."""
    p = d.polish_
    if not p:
        return []
    vals = ", ".join(f"{k} {_f(p['before']['values'][k], '.4g')}" + (
        f" -> {_f(v, '.4g')}" if p["steps"] else "") + f" {p['units'][k]}" for k, v in p["after"]["values"].items())
    head = (f"**Polished with its own wheel phases.** `{p['candidate']}` moves the wheel's angle against "
            "the measured motor angle, and its refit was fitted at the fit recordings' wheel phases "
            "estimated at the calibrated base, which lacks it (those phases take in part of the effect). ")
    if p["steps"]:
        return [head + f"{p['steps']} phase-profiled step(s), each trial point judged with the phases "
                f"estimated at it, moved it: {vals}; fit RMSE {_f(p['before']['rmse_fit'])} -> "
                f"{_f(p['after']['rmse_fit'])} rad/s. The answer is unchanged; the values, the updated "
                "model and the after figures are the polished ones.", ""]
    return [head + f"No phase-profiled step fitted clearly better ({vals}; fit RMSE "
            f"{_f(p['before']['rmse_fit'])} rad/s): the values stand.", ""]


def _heavy_look_md(d) -> list:
    """Report paragraph on the look at the heaviest load alone (``heavy_look_``), when it ran or
    could not."""
    g = d.heavy_look_
    if not g:
        return []
    if g.get("failed"):
        return [f"**Heaviest load alone: the look failed** ({g['why']}); the answer is that of the "
                "recordings together, unexplained.", ""]
    if not g["ran"]:
        return [f"**Heaviest load alone: not looked at** ({g['why']}).", ""]
    if not g["adopted"]:
        said = g["verdict"] + (f" ({', '.join('`' + k + '`' for k in g['selected'])}, but leaving the fit "
                               f"{g['fit_over_floor']:.2f}x the floor, where this fallback asks for "
                               f"{d.rule.rival_floor:g}x or less)" if g["selected"] else "")
        text = (f"**Heaviest load alone.** Nothing explained the mismatch on every recording, so the "
                f"diagnosis ran once more on the {g['load_kg']:g} kg recordings alone "
                f"({', '.join('`' + k + '`' for k in g['recordings'])}); it said {said}, and the answer "
                f"stays unexplained ({g['seconds']:.0f} s, {g['model_runs']} model runs).")
        if heaviest_said_none(d):
            text += (" So the heaviest load's recordings need no added effect, and the mismatch comes from "
                     "the lighter loads' recordings or from fitting every load with one set of coefficients. "
                     "A calibration can stop short there with nothing missing: the base reproduces the "
                     "lighter loads only in a narrow valley of its coefficients, each recording with wheel "
                     "phases of its own (szdyn's null 89, nothing "
                     "concealed: its true coefficients fit at 1.0x the floor, the calibration ended at 1.5x "
                     "and said unexplained; docs/DIAGNOSIS-DESIGN.md, \"Null 89's unexplained, traced\"). "
                     "On its own, then, this answer does not show that physics is missing.")
        return [text, ""]
    e = g["every_recording"]
    said = e["verdict"] + (f" ({', '.join(e['selected'])})" if e["selected"] else "")
    look = e.get("second_look")
    L = [f"**Heaviest load alone.** On every recording the diagnosis said {said}"
         + (f" (also after a second look with {look['steps']} phase-profiled step(s))" if look else "")
         + f"; the calibrated base was {e['calibrated_fit_over_floor']:.2f}x the floor. Lighter loads ride the "
         "impact regime, where the fit flips between tracking and slipping as the coefficients move and a "
         "missing effect hides behind that; so the diagnosis ran once more on the "
         f"{g['load_kg']:g} kg recordings alone, with their roles, and **everything above and below is that "
         f"pass**: it names {', '.join('`' + k + '`' for k in g['selected'])}. The passes on every recording "
         f"took {e['seconds']:.0f} s and {e['model_runs']} model runs. The recordings it left out, each model "
         "from its own estimated wheel phases (rad/s; x the floor of this pass):", "",
         "| recording | role | load (kg) | calibrated base | updated model |", "|---|---|---|---|---|"]
    for k, v in g["other_recordings"].items():
        L.append(f"| {k} | {v['role']} | {v['load_kg']:g} | {_f(v['calibrated'])} ({v['calibrated_over_floor']:.1f}x) "
                 f"| {_f(v['updated'])} ({v['updated_over_floor']:.1f}x) |")
    L += ["", "Where the updated model leaves these many floors off, the model does not reproduce the lighter "
          "load's regime with one set of coefficients; the effect is named from the load where it does.", ""]
    return L


def heaviest_said_none(d) -> bool:
    """Whether the look at the heaviest load alone (``d.heavy_look_``) ran and said "none": the
    heaviest load's recordings need nothing the library holds, and the answer stays unexplained."""
    return (d.heavy_look_ or {}).get("verdict") == "none"


def _phase_md(d) -> list:
    """Paragraph on the recordings' initial wheel phases: estimated, or why not."""
    lead = ("**Wheel phase.** Neither encoder measures where the rollers start relative to the band's "
            "circles, and the impact bumps and the breakaway follow it. ")
    if not d.fit_phase:
        return [lead + "Every run started from the default offset (`--no-phase`); the floor counts the "
                "bumps of a quarter-pitch shift.", ""]
    if not d.phases_:
        return [lead + f"The calibrated base fitted {d.phase_['base_over_floor']:.2f}x the floor (with "
                "the bumps of a quarter-pitch shift), beyond "
                f"{d.phase_['gate']:g}x: a mismatch that large would bias a phase scan, so every run "
                "started from the default offset and the floor counts the quarter-pitch bumps.", ""]
    ok = [k for k, v in d.phases_.items() if v["identified"]]
    return [lead + "So each recording's initial "
            "wheel angle was estimated at the first calibration (a scan over one circle pitch, refined to "
            "1/64 pitch; `szdyn.diagnose.phase`), the calibrated base being "
            f"{d.phase_['base_over_floor']:.2f}x the floor with quarter-pitch bumps (within "
            f"{d.phase_['gate']:g}x). It counts as identified where "
            "the scan's median squared RMSE exceeds the best phase's by at least "
            f"{IDENTIFIED_SHARE:g} of the model's own squared change over the scan (the recording's "
            "bumps then follow the model's): " + ", ".join(
                f"`{k}` {v['phase_pitch']:.3f} pitch (RMSE {_f(v['rmse'], '.3g')} against a median "
                f"{_f(v['median_rmse'], '.3g')}, model change {_f(v['model_spread'], '.3g')} rad/s"
                + ("" if v["identified"] else ", not identified: default offset") + ")"
                for k, v in d.phases_.items())
            + (f". Then {d.phase_['steps']} phase-profiled step(s) of the base "
               "(`--phase-steps`) estimated them again at the point each step went to; these are the "
               "phases of the last" if d.phase_.get("steps") else "")
            + _candidate_phase_md(d)
            + f". On the {len(ok)} identified, the floor's bump part is the phase's uncertainty "
            f"({PHASE_UNCERTAINTY:g} pitch) instead of a quarter pitch."
            + _heldout_phase_md(d), ""]


def _candidate_phase_md(d) -> str:
    """The sentence on the candidates' refits that took phase-profiled steps of their own."""
    own = {k: v["result"].extra["phase_steps"] for k, v in d.refits_.items()
           if v["result"].extra.get("phase_steps")}
    if not own:
        return ""
    return ("; refits with phase-profiled steps of their own, each fitted and judged with the phases of "
            "its last step: " + ", ".join(f"`{k}` ({n})" for k, n in own.items()))


def _heldout_phase_md(d) -> str:
    """The sentence on the held-out recordings' phases, estimated again per model."""
    held = d.phase_.get("heldout")
    if not held:
        return ""
    return (" The held-out recordings' phases were estimated again for each model judged on them (the "
            "calibrated base and every refitted candidate), since a phase estimated at a model that lacks "
            "an effect is biased against the model that has it: an initial state estimated on the "
            "validation data, as output-error identification does. The final model's: " + ", ".join(
                f"`{k}` " + (f"{v['phase_pitch']:.3f} pitch" if v["identified"] else "not identified (default offset)")
                for k, v in held.items()) + ".")


def _torque_md(d) -> list:
    """The motor-torque paragraph of "What was compared" (recordings with a current column)."""
    t = d.torque_
    if t is None:
        return []
    if not t["used"]:
        return ["Motor current: only held-out recordings (" + ", ".join(f"`{k}`" for k in t["recordings"])
                + ") have a current column and a torque constant, so the motor torque was not compared "
                "(it must be among the fit recordings to take part in the fit).", ""]
    kts = sorted(set(t["torque_constant"].values()))
    b, a = t.get("before", {}), t.get("after", {})
    return [f"**Motor torque** ({len(t['recordings'])} recordings with a `current` column; torque constant "
            + ", ".join(f"{k:g}" for k in kts) + " N m/A from the manifest): the smoothed measured torque "
            "`K_t * current` (same filter, value instead of derivative) against the model's "
            "`I_W * d(omega_w)/dt - wheel_reaction_torque`, every "
            f"{FEATURE_DT:g} s. Its floor {_f(t['floor'], '.3g')} N m = sqrt(sensor "
            f"{_f(t['floor_parts']['sensor'], '.3g')}^2 + impact bumps {_f(t['floor_parts']['bump'], '.3g')}^2), "
            f"made like the speed's. Its residual enters every fit times {_f(t['weight'], '.3g')} rad/s per "
            "N m (the speed floor over the torque floor), so that a correct model is near the floor in "
            "both; every fit and held-out RMSE below is of speed and weighted torque together (rad/s at "
            "the speed floor). The speed fixes the slider's forces mostly relative to one another; "
            "the torque fixes their size. Torque alone, held-out RMSE: "
            f"{_f(b.get('heldout_rmse'), '.3g')} N m before, {_f(a.get('heldout_rmse'), '.3g')} N m after "
            "(per recording, before/after: "
            + "; ".join(f"`{k}` {_f(v, '.3g')}/{_f(a.get('per_recording', {}).get(k), '.3g')}"
                        for k, v in b.get("per_recording", {}).items())
            + " N m). Plot: `torque_fit.png`.", ""]


def _refits_md(d) -> str:
    """How the shortlisted candidates were refitted: the starts each refit may get, as ``d``
    (a fitted :class:`~szdyn.diagnose.diagnosis.Diagnosis`: ``shortlist``, ``rivals``, ``rule``
    and ``amplitude_starts`` are read) configured them."""
    fifth = ("a fifth from the calibrated coefficients with the effect's amplitude at "
             + " and ".join(f"x{m:g}" for m in AMPLITUDE_MULTIPLES)
             + " of where the best refit left it, when that refit explains part of the mismatch but less "
             f"than {d.rule.min_explained:.0%} and still leaves a mismatch; ") if d.amplitude_starts else ""
    return ("Screened linearly at the calibrated point, the best "
            f"{d.shortlist} refitted nonlinearly (base coefficients refitted too; a second start from the "
            f"uncalibrated coefficients when the first refit is not at the floor, a third with the effect "
            f"at an amplitude probe when it still explains too little, a fourth with the effect's amplitude "
            f"searched over its range at the uncalibrated coefficients ({AMPLITUDE_GRID}-point scan, then a "
            f"bounded Brent search) when the refits still leave more than {d.rule.max_remaining:g}x the floor; "
            + fifth + f"the next {d.rivals} of the screening "
            f"too when the provisional winner left the fit above {d.rule.rival_floor:g}x the floor).")


def failed_md(names, selected) -> str:
    """The warning for recordings on which the final model's own run failed (markdown)."""
    which = "updated" if selected else "calibrated"
    return (f"**The {which} model's run failed on** " + ", ".join(f"`{k}`" for k in names)
            + " with every integrator it tries (dopri5 the last): its band speed there is taken as zero, a "
            "band at rest, so its figures for these recordings are no fit. Their conditions (load_kg, "
            "speeds) or the parameters may lie beyond what the model can integrate.")


def _report_md(d, js) -> str:
    L = [REPORT_TITLE, ""]
    v = d.verdict_
    if v == "none":
        L += ["**Verdict: none.** The calibrated base model reproduces the fit recordings to within the "
              f"noise floor (fit RMSE {_f(d.calibrated_.rmse_fit)} rad/s, floor {_f(d.floor_)} rad/s, "
              f"ratio {d.calibrated_.rmse_fit / d.floor_:.2f} <= {d.rule.min_excess}): nothing significant "
              "is missing from what they show.", ""]
    elif v == "selected":
        e = CANDIDATES[d.selected_[0]]
        L += [f"**Verdict: `{e.id}`.** {e.explains}.", "", f"Term: `{e.expression}`", ""]
        if d.passed_over_:
            L += [f"**Chosen by the held-out recordings.** `{d.passed_over_}` explained more of the fit "
                  f"recordings' excess, but both left them within {d.rule.rival_floor:g}x the noise floor, "
                  f"and `{e.id}` held out {d.rule.rival_heldout:g}x better or more (see the candidates "
                  "table). The held-out improvement below is then not an independent check.", ""]
        if d.indistinguishable_:
            L += ["**Not distinguishable from these recordings:** "
                  + ", ".join(f"`{k}`" for k in d.indistinguishable_)
                  + f" fit(s) within {d.rule.min_dbic:g} of the selected effect in the information "
                  "criterion. Recordings that separate them (other loads, both directions, slow "
                  "ramps) would decide; " + ("the held-out recordings chose." if d.passed_over_ else
                                             "the selected one explains the most."), ""]
    else:
        L += ["**Verdict: unexplained.** The calibrated model misses something significant "
              f"({d.calibrated_.rmse_fit / d.floor_:.1f}x the noise floor) but no candidate of the "
              "library passed the selection rule; see the candidates table."
              + (" The heaviest load alone needs nothing the library holds (\"Heaviest load alone\" below)."
                 if heaviest_said_none(d) else ""), ""]
        if js["partial"]:
            L += ["**Partly explained by** " + ", ".join(
                f"`{q['id']}` (explains {q['explained']:.0%} of the excess, but leaves the fit "
                f"{q['fit_rmse_over_floor']:.1f}x the floor)" for q in js["partial"])
                + f": eligible, but an effect is named only when its refit comes within "
                f"{d.rule.max_remaining:g}x the floor on the fit recordings or on held-out ones the "
                "calibrated model missed by more. Something else, or another form of it, is missing "
                "too; the calibration may also have settled in a wrong valley (the updated model is "
                "the calibrated base).", ""]
    if js["final_failed_on"]:
        L += [failed_md(js["final_failed_on"], d.selected_), ""]
    if d.heldout_beyond_floor_:
        L += ["**Held-out recordings not reproduced:** "
              + ", ".join(f"`{k}` ({r:.1f}x the floor)" for k, r in d.heldout_beyond_floor_.items())
              + f" with the {'updated' if d.selected_ else 'calibrated'} model. Held-out recordings only judge, "
              "so this does not change the verdict. Either they show what the fit recordings do not "
              "excite (another load, speed or direction: put such a recording among the fit ones, "
              "manifest `[split]`, and run again), or they are less reproducible than the floor "
              "estimate says (near the full-slip cliff: on szdyn's grid a 2 % change of mu_k "
              "decided between tracking and slipping on one such recording).", ""]
        L += _heldout_scale_md(d)
    L += (_split_md(d) + _restart_md(d) + _second_look_md(d) + _heavy_look_md(d) + _polish_md(d)
          + _scale_profile_md(d))
    o = d.weighting_["other_pass"]
    if o is not None:
        said = (f"{o['verdict']}" + (f" ({', '.join(o['selected'])})" if o["selected"] else "")
                + f", the calibrated base {o['calibrated_fit_over_floor']:.2f}x the floor in its units; "
                f"{o['seconds']:.0f} s, {o['model_runs']} model runs")
        if d.weighted_:
            L += [f"**Weighted pass.** The unweighted diagnosis named no effect (it said {said}), and the "
                  f"recordings' own noise floors differ {d.weighting_['spread']:.1f}x (more than "
                  f"{d.weighting_['threshold']:g}x): the common floor hid what the reproducible recordings show. This "
                  "diagnosis is the pass with each recording weighted by its own floor (see What was "
                  "compared).", ""]
        else:
            L += [f"**Weighted pass tried.** The recordings' own noise floors differ "
                  f"{d.weighting_['spread']:.1f}x (more than {d.weighting_['threshold']:g}x), so the diagnosis also ran "
                  f"with each recording weighted by its own floor; that pass named no effect either "
                  f"(it said {said}), and this unweighted answer stands.", ""]
    L += ["## What was compared", "", COMPARED + ".", "",
          "Recordings: " + ", ".join(f"`{r.name}` ({r.role}, {r.load_kg:g} kg)" for r in d.recordings_) + ".", "",
          f"Noise floor {_f(d.floor_)} rad/s = sqrt(sensor {_f(d.floor_parts_['sensor'])}^2 + "
          f"impact bumps {_f(d.floor_parts_['bump'])}^2) (see `szdyn.diagnose.noise`): the RMS of the "
          "fit recordings' sensor noise and the median of their bumps, each load counting once. Per recording (sensor, bumps, "
          "rad/s): " + "; ".join(f"`{k}` {_f(v['sensor'], '.3g')}, {_f(v['bump'], '.3g')}"
                                  for k, v in d.floor_per_recording_.items())
          + f"; their own floors differ {d.floor_spread_:.1f}x. " + _coefficient_floor_md(d) + (_WEIGHTED.format(
              ", ".join(f"`{k}` {w:.2f}" for k, w in d.weights_.items())) if d.weighted_ else
              "Where these differ a lot (recordings that flip between tracking and slipping with the "
              "wheel phase have large bumps), the common floor can hide an effect that the "
              "reproducible recordings show (`--weighting always` weights each recording by its own "
              "floor; by default that is tried when nothing is named and they differ by more than "
              f"{d.weighting_['threshold']:g}x)."), "",
          *_phase_md(d),
          *_torque_md(d),
          "## Calibration (base model, fit recordings)", "",
          "| coefficient | value | std | unit |", "|---|---|---|---|"]
    for k in ("k_c", "b_c", "k_imp", "mu_s", "mu_k"):
        L.append(f"| {k} | {_f(d.calibrated_.values[k])} | {_f(d.calibrated_.std.get(k))} | {UNITS[k]} |")
    L += ["", f"`b_imp` is not identifiable from these features (below the noise floor and collinear with "
          f"`b_c`, `k_imp`): kept at {_f(d.recordings_[0].params['b_imp'])} {UNITS['b_imp']}.",
          "Standard deviations are local (Jacobian) estimates, inflated x2 for the overlap of neighbouring "
          "samples. " + _force_scale_md(d.calibrated_) + " They measure the curvature of the valley the fit ended "
          "in, not how far that valley is from the truth: the fit cost is rippled by the impact bumps, and "
          "on szdyn's benchmark grid effect parameters were often several standard deviations off "
          "(docs/diagnosis-oos-summary.md, column \"error in std\", before this correction; "
          "docs/DIAGNOSIS-DESIGN.md, \"The reported standard deviations\", with it). Judge the fit, not "
          "the coefficients.", "",
          f"Fit RMSE {_f(d.calibrated_.rmse_fit)} rad/s ({d.calibrated_.rmse_fit / d.floor_:.2f}x the floor); "
          f"the fit {_status(d.calibrated_)}.", "",
          *_staged_md(d),
          "## Where the mismatch is (calibrated base model)", ""]
    held = [m for m in d.location_["mismatch"] if m["recording"] in d.heldout_beyond_floor_]
    if js["mismatch"]:
        L += _segments_md(js["mismatch"])
    elif held:
        # the calibrated base is at the floor on the fit recordings, not on these
        L += ["No segment of the fit recordings stands out. Segments of the held-out recordings "
              "that the calibrated model misses:", ""] + _segments_md(held)
    else:
        L.append("No segment stands out: the residual is at the noise floor.")
    L += ["", "Per recording (Ljung-Box on the residual thinned to one sample per window; "
          "cross-correlation with the wheel speed, prewhitened; spectral peaks):", "",
          "| recording | role | RMSE (rad/s) | / floor | white (p) | indep. of wheel speed (p) | peaks |",
          "|---|---|---|---|---|---|---|"]
    for r in d.location_["recordings"]:
        w = r.get("whiteness", {})
        c = r.get("xcorr_wheel_speed", {})
        pk = "; ".join(f"{p['freq_hz']:.2f} Hz" + (f" ({', '.join(p['orders'])})" if p["orders"] else "")
                       for p in r["peaks"]) or "-"
        L.append(f"| {r['recording']} | {r['role']} | {_f(r['rmse'])} | {r['ratio_to_floor']:.1f} | "
                 f"{w.get('white', '-')} ({_f(w.get('p_value'), '.2g')}) | {c.get('independent', '-')} "
                 f"({_f(c.get('p_value'), '.2g')}) | {pk} |")
    L += ["", "What the residual follows (R^2 of a one-feature linear fit over all recordings):", "",
          "| feature | R^2 | would suggest |", "|---|---|---|"]
    for f in d.location_["follows"]:
        L.append(f"| {f['feature']} ({f['unit']}) | {f['r2']:.3f} | {f['suggests']} |")
    L += ["", "Plots: `residual_time.png`, `residual_features.png`.", "",
          "## Candidate effects", "",
          _refits_md(d) + f" Rule: {d.rule}.", "",
          _nominated_md(d), "", _probing_md(d), "",
          *([f"Rivals refitted because the provisional winner left the fit above {d.rule.rival_floor:g}x "
             "the floor: " + ", ".join(f"`{k}`" for k in d.rivals_) + ".", ""] if d.rivals_ else []),
          "| effect | score | screen RMSE | refit RMSE | held-out RMSE | dBIC | eligible | selected | refit |",
          "|---|---|---|---|---|---|---|---|---|"]
    for e in js["effects"]:
        L.append(f"| {e['id']} | {e['score']:.2f} | {_f(e['screen_rmse'])} | {_f(e.get('fit_rmse'))} | "
                 f"{_f(e.get('heldout_rmse'))} | {_f(e.get('dbic'), '.1f')} | {e.get('eligible', '-')} | "
                 f"{'**yes**' if e['selected'] else ('partial' if e['id'] in d.partial_ else '')} | "
                 f"{e.get('fit_status', '-')} |")
    L += ["", "Plot: `candidates.png`.", "", *_detectable_md(d, js), ""]
    if d.selected_:
        e = next(x for x in js["effects"] if x["selected"])
        L += [f"## Selected: `{e['id']}`", "", f"Expression: `{e['expression']}`", "",
              "| parameter | value | std |", "|---|---|---|"]
        for k, val in e["fit_coordinates"].items():
            L.append(f"| {k} | {_f(val)} | {_f(e['std'].get(k))} |")
        L += ["", f"Model/sensor parameters set: `{e['parameters']}`; effect parameter "
              f"`{e['primary']['name']}` = {_f(e['primary']['value'])} (std {_f(e['primary']['std'])}; "
              "a local estimate like the coefficients', see the calibration section). "
              + _force_scale_md(d.final_), ""]
        if "per_mu_k" in e["primary"] and d.torque_ is not None and d.torque_["used"]:
            L += [f"`{e['primary']['name']}` / mu_k = {_f(e['primary']['per_mu_k'])}. The measured motor "
                  "torque took part in the fit, so the size of the torques is measured, not only their "
                  "ratio.", ""]
        elif "per_mu_k" in e["primary"]:
            pn = e["primary"]["name"]
            L += [f"`{pn}` / mu_k = {_f(e['primary']['per_mu_k'])}. Speed recordings fix the size of every "
                  "torque mainly relative to the others: scaling every force coefficient and the effect "
                  "together by 1.25 changed szdyn's compared feature by only 0.4 to 2.8 noise floors on "
                  f"four benchmark cases. If the calibrated mu_k is off by some factor, `{pn}` is likely "
                  "off by about the same factor; the ratio is the better-determined number.", ""]
    fb, fa = js["fit"]["before"], js["fit"]["after"]
    L += ["## Fit before and after", "", "| | fit RMSE (rad/s) | held-out RMSE (rad/s) |", "|---|---|---|",
          f"| before (calibrated base) | {_f(fb['fit_rmse'])} | {_f(fb['heldout_rmse'])} |",
          f"| after (updated model) | {_f(fa['fit_rmse'])} | {_f(fa['heldout_rmse'])} |", ""]
    if fb["per_recording"]:
        L += ["| held-out recording | before | after |", "|---|---|---|"]
        for k in fb["per_recording"]:
            L.append(f"| {k} | {_f(fb['per_recording'][k])} | {_f(fa['per_recording'].get(k))} |")
    L += ["", "Plot: `heldout_fit.png`. Updated parameters: `params.json` (`python -m szdyn.run --params "
          "params.json`)" + (f"; sensor corrections (not model parameters): `{js['final']['sensor']}`"
                             if js["final"]["sensor"] else "") + ".", "",
          "## Units", "", "Time s, angles rad, speeds rad/s, torques N m, SI throughout. " +
          "; ".join(f"{k}: {u}" for k, u in UNITS.items()) + ".", "",
          f"Cost: {sum(d.timings_.values()):.0f} s wall ({d.timings_}), {d.n_runs_} model runs"
          f" ({d.n_failed_} failed with both integrators)"
          + (f"; {d.resumed_runs_} more model runs were loaded from a checkpoint (an interrupted or kept "
             "earlier run; not counted here)"
             if d.resumed_runs_ else "") + ".", ""]
    return "\n".join(L)


def write_report(d, out, next_recording=None) -> dict:
    """Write every output file of a fitted diagnosis into ``out``; return the JSON dict.

    ``next_recording``: a fitted :class:`~.design.NextRecording` (its section, its plot
    ``next_recording.png`` and ``diagnosis.json``'s ``next_recording``), or None (then null).
    """
    js = _to_json(d)
    js["next_recording"] = None if next_recording is None else next_recording.to_dict()
    # staged, then moved in together: an interruption part-way leaves the previous run's set
    # whole (a new params.json beside an old report would be taken for this run's answer)
    # torque_fit.png is written only with a measured current: an earlier run's must not stay
    with staged_output(out, last=("diagnosis.json",), owns=OUTPUT_FILES) as stage:
        updated_parameters(d).to_json(stage / "params.json")
        _plots(d, stage, js["effects"])
        md = _report_md(d, js)
        if next_recording is not None:
            # before the units and the cost, after the fit it would decide between
            head, sep, tail = md.partition("\n## Units\n")
            md = head + "\n" + "\n".join(next_recording.to_markdown()) + sep + tail
            next_recording.plot(stage / "next_recording.png")
        atomic_write_text(stage / "report.md", md)
        js = _clean(js)
        write_json(stage / "diagnosis.json", js)
    return js
