"""The next recording to take (``szdyn.diagnose.design``): contenders, separations, outputs."""
from __future__ import annotations

import json
import math
from types import SimpleNamespace

import numpy as np
import pytest

from szdyn.diagnose.candidates import CANDIDATES
from szdyn.diagnose.data import prepare
from szdyn.diagnose.design import BREAKAWAY_SHARE, MIN_SEPARATION, PROTOCOLS, NextRecording, Protocol
from szdyn.diagnose.engine import model_speed
from szdyn.diagnose.fit import Hypothesis
from szdyn.manifest import read_manifest
from szdyn.synth import QUICK_RAMPS, synthesize

#: Short protocols (N_c 16 runs of a few seconds) with the library's shapes.
SHORT = (
    Protocol("slow", "slow ramp", "low speed", (0.0, 3.0), (0.0, 0.5)),
    Protocol("hold", "quick start, long hold", "time", (0.0, 0.25, 3.0), (0.0, 0.5, 0.5)),
    Protocol("fast", "fast start", "transients", (0.0, 0.1, 1.0), (0.0, 1.0, 1.0)),
)
FLOOR = 0.01


@pytest.fixture(scope="module")
def recs(tmp_path_factory):
    data = tmp_path_factory.mktemp("design")
    synthesize(data, "none", None, seed=2, loads_kg=(0.5, 1.0), ramps=QUICK_RAMPS, dt=5e-5, verbose=False)
    return prepare(read_manifest(data / "manifest.toml"))


def _start(recs):
    p = recs[0].params
    return {k: p[k] for k in ("k_c", "b_c", "k_imp", "mu_s", "mu_k")}


def _fit(hyp, **values):
    """A FitResult stand-in at the hypothesis's start with the candidate's values set."""
    x = hyp.x_start()
    for j, par in enumerate(hyp.params[hyp.n_base:], hyp.n_base):
        x[j] = values.get(par.name, x[j])
    return SimpleNamespace(hypothesis=hyp, x=x)


def _diagnosis(recs, answer, rivals, verdict="selected", selected=("a",)):
    """A fitted-diagnosis stand-in: ``answer`` a fit result, ``rivals`` {id: (fit result, explained)}."""
    return SimpleNamespace(recordings_=recs, floor_=FLOOR, verdict_=verdict, selected_=list(selected),
                           final_=answer, workers=1,
                           refits_={k: {"result": r, "explained": e} for k, (r, e) in rivals.items()})


def test_library_protocols_start_at_rest_and_stay_within_the_recorded_speed():
    for p in PROTOCOLS:
        assert p.t[0] == 0.0 and p.w[0] == 0.0 and np.all(np.diff(p.t) > 0), p.id
        assert max(abs(w) for w in p.w) <= 1.0, p.id
        d = p.drive(2.0)
        assert d.omega.max() <= 2.0 + 1e-12 and p.duration == p.t[-1]
    assert len({p.id for p in PROTOCOLS}) == len(PROTOCOLS)


def test_contenders_are_the_answer_then_the_rivals_explaining_enough_best_first(recs):
    s = _start(recs)
    base = _fit(Hypothesis(s))
    r = {k: _fit(Hypothesis(s, CANDIDATES[k])) for k in ("encoder_scale", "friction_drift", "slider_viscous", "load_lift")}
    d = _diagnosis(recs, base, {"encoder_scale": (r["encoder_scale"], 0.3), "friction_drift": (r["friction_drift"], 0.9),
                                "slider_viscous": (r["slider_viscous"], 0.5), "load_lift": (r["load_lift"], 0.1)},
                   verdict="unexplained", selected=())
    cont = NextRecording(max_rivals=2)._contenders(d)
    assert [c for c, _ in cont] == ["calibrated base", "friction_drift", "slider_viscous"]
    # the selected effect is the answer, never its own rival
    d.selected_, d.verdict_ = ["friction_drift"], "selected"
    assert [c for c, _ in NextRecording(max_rivals=3)._contenders(d)] == \
        ["friction_drift", "slider_viscous", "encoder_scale"]


def test_nothing_is_ranked_after_none_or_without_a_rival(recs):
    s = _start(recs)
    base = _fit(Hypothesis(s))
    nr = NextRecording(SHORT).fit(_diagnosis(recs, base, {}, verdict="none", selected=()))
    assert nr.why_not_.startswith("nothing is missing") and nr.table_ == [] and nr.n_runs_ == 0
    weak = _fit(Hypothesis(s, CANDIDATES["load_lift"]), tau_lift=0.01)
    nr = NextRecording(SHORT).fit(_diagnosis(recs, base, {"load_lift": (weak, 0.1)}, verdict="unexplained", selected=()))
    assert "no refitted rival" in nr.why_not_ and nr.recommended_ is None and nr.n_runs_ == 0
    js = json.loads(json.dumps(nr.to_dict()))
    assert js["why_not"] == nr.why_not_ and js["protocols"] == []
    assert "Not ranked" in "\n".join(nr.to_markdown())


def test_a_band_encoder_scale_separates_by_exactly_its_share_of_the_band_speed(recs):
    """Reference: the sensor scale multiplies the model's smoothed band speed, so the separation
    of a contender with ``encoder_scale`` e from the same model without it is ``|e| rms(speed) /
    floor``, computed here from a run of the protocol made apart."""
    from szdyn.simulate import simulate

    s = _start(recs)
    e = 0.02
    d = _diagnosis(recs, _fit(Hypothesis(s)), {"encoder_scale": (_fit(Hypothesis(s, CANDIDATES["encoder_scale"]),
                                                                        encoder_scale=e), 0.8)},
                   verdict="unexplained", selected=())
    nr = NextRecording(SHORT[:1]).fit(d)
    assert nr.contenders_ == ["calibrated base", "encoder_scale"]
    assert nr.loads_ == [0.5, 1.0] and nr.scale_ == pytest.approx(max(np.abs(r.omega_w).max() for r in recs))
    pair = "calibrated base vs encoder_scale"
    assert nr.on_recordings_[pair] > 0
    for row in nr.table_:
        p = recs[0].params.replace(m_b=row["load_kg"], **{k: s[k] for k in s})
        run = simulate(p, SHORT[0].drive(nr.scale_), SHORT[0].duration, method="heun", dt=1e-4, save_dt=1e-3,
                       x0=p.initial_state())
        qb = run.trajectory.x[:, 1]
        t_feat = np.arange(0.05, SHORT[0].duration - 0.05 + 1e-9, 0.05)
        ref = e * math.sqrt(np.mean(model_speed(run.trajectory.t, qb - qb[0], t_feat) ** 2)) / FLOOR
        assert row["separation"][pair] == pytest.approx(ref, rel=1e-6)
    best = nr.table_[0]
    assert nr.recommended_ == {**best, "description": SHORT[0].description, "reveals": SHORT[0].reveals,
                               "sufficient": best["min_separation"] >= MIN_SEPARATION and not best["breakaway"]}


def test_a_stribeck_peak_holds_the_band_back_and_a_falling_friction_lets_it_run_faster(recs):
    """Physics of the predictions: on a start and hold, a Stribeck peak holds the band at rest
    at 1 kg and holds it back during the start at 0.5 kg, a friction falling over time makes it
    faster throughout the hold; and the table is ranked with break-away rows last."""
    s = _start(recs)
    base = _fit(Hypothesis(s))
    strib = _fit(Hypothesis(s, CANDIDATES["slider_stribeck"]), mu_st=0.15, v_st=0.1)
    drift = _fit(Hypothesis(s, CANDIDATES["friction_drift"]), k_drift=-0.1)
    d = _diagnosis(recs, base, {"slider_stribeck": (strib, 0.9), "friction_drift": (drift, 0.8)},
                   verdict="unexplained", selected=())
    nr = NextRecording(SHORT).fit(d)
    assert nr.scale_ == pytest.approx(0.5 * math.pi, rel=0.05)     # the quick ramps' 2 pi rad/s^2 for 0.25 s
    assert nr.n_runs_ == 3 * (len(recs) + len(SHORT) * 2)
    # ranked: break-away rows last, each group by its smallest separation
    key = [(r["breakaway"], -r["min_separation"]) for r in nr.table_]
    assert key == sorted(key)
    # at 1 kg the Stribeck peak holds the slipping band at rest through the hold: that row
    # separates most, and is ranked after every row that breaks away from rest
    row = {(r["protocol"], r["load_kg"]): r for r in nr.table_}
    held = row[("hold", 1.0)]
    assert held["breakaway"] and held["held_at_rest_s"] >= 2.5 and held["held_share"] >= BREAKAWAY_SHARE
    assert row[("hold", 1.0)]["min_separation"] == max(r["min_separation"] for r in nr.table_)
    assert not nr.table_[0]["breakaway"] and nr.recommended_["protocol"] == nr.table_[0]["protocol"]
    assert "Break-away rows" in "\n".join(nr.to_markdown())
    p = NextRecording(SHORT[1:2]).fit(d).predictions_     # the start and hold at 0.5 kg
    # the peak holds the band back during the 0.25 s start (it catches up after breaking away)
    start = p["t"] < 0.25
    assert (p["calibrated base"] - p["slider_stribeck"])[start].max() > 5 * FLOOR
    faster = p["friction_drift"] - p["calibrated base"]
    third = len(faster) // 3
    assert faster[third:].min() > 0


def test_the_section_the_plot_and_the_json_of_a_ranking(recs, tmp_path):
    s = _start(recs)
    d = _diagnosis(recs, _fit(Hypothesis(s, CANDIDATES["friction_drift"]), k_drift=-0.05),
                   {"slider_stribeck": (_fit(Hypothesis(s, CANDIDATES["slider_stribeck"]), mu_st=0.1), 0.5)},
                   selected=("friction_drift",))
    nr = NextRecording(SHORT[:2]).fit(d)
    md = "\n".join(nr.to_markdown())
    assert nr.recommended_["sufficient"] and "**Record next:" in md and "friction_drift vs slider_stribeck" in md
    assert md.count("\n| ") == 1 + len(nr.table_)     # header + one row per protocol and load
    assert nr.plot(tmp_path / "n.png") and (tmp_path / "n.png").stat().st_size > 0
    js = json.loads(json.dumps(nr.to_dict()))
    assert js["recommended"]["protocol"] in {"slow", "hold"} and len(js["library"]) == 2
    # a ranking whose best protocol separates too little says so instead of asking for it
    nr.recommended_["sufficient"] = False
    md = "\n".join(nr.to_markdown())
    assert "**Record next:" not in md and "No protocol of the library separates" in md


def test_a_failed_protocol_run_gives_nan_separations_and_no_band_held_at_rest(recs, monkeypatch):
    """A run that fails comes back all zeros (``FeatureModel``): its pairs are NaN, its row ranks
    after the finite ones, and its zeros are not read as a band held at rest."""
    import szdyn.diagnose.design as design

    class FailingLast(design.FeatureModel):
        def speeds(self, points, idx):
            out = super().speeds(points, idx)
            out[-1][-1] = np.zeros_like(out[-1][-1])    # the last contender on the last protocol row
            return out

    monkeypatch.setattr(design, "FeatureModel", FailingLast)
    s = _start(recs)
    d = _diagnosis(recs, _fit(Hypothesis(s)), {"encoder_scale": (_fit(Hypothesis(s, CANDIDATES["encoder_scale"]),
                                                                        encoder_scale=0.05), 0.8)},
                   verdict="unexplained", selected=())
    nr = NextRecording(SHORT[2:]).fit(d)                 # the fast start at 0.5 and 1 kg
    failed = nr.table_[-1]
    assert failed["load_kg"] == 1.0 and math.isnan(failed["min_separation"])
    assert failed["held_at_rest_s"] == 0.0 and not failed["breakaway"]
    assert math.isfinite(nr.table_[0]["min_separation"]) and nr.recommended_["load_kg"] == 0.5
