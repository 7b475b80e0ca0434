"""Simulating the model against a recording: the truth model reproduces its own (sensor-noisy)
recording far better than a wrong model does."""
from __future__ import annotations

import json

import numpy as np
import pytest

from szdyn.compare import compare, measured_drive
from szdyn.manifest import read_manifest
from szdyn.params import ParameterSet
from szdyn.recordings import read_recording
from szdyn.synth import RampSpec, synthesize


@pytest.fixture(scope="module")
def synthetic(tmp_path_factory):
    out = tmp_path_factory.mktemp("synth")
    # N_c = 48 (not the quick 16, at which the band hardly moves): a light load and one ramp
    # and hold, so that the band really slips partially and the comparison means something.
    synthesize(out, effect="none", seed=2, loads_kg=(0.5,), n_circles=48,
               ramps=(RampSpec("up", 2.0 * np.pi, 0.5, 0.5),), verbose=False)
    truth = json.loads((out / "truth.json").read_text())  # a test may read the answer
    manifest = read_manifest(out / "manifest.toml")
    entry = manifest.entries[0]
    rec = read_recording(entry.file, conditions=entry.conditions)
    params = manifest.parameters(entry, base=ParameterSet.from_dict(truth["truth_parameters"]))
    return rec, params, truth


def test_measured_drive_follows_the_wheel_encoder(synthetic):
    rec, _, _ = synthetic
    d = measured_drive(rec)
    angle = d.evaluate(rec.t, angle0=rec.theta_w[0])[0]
    assert np.abs(angle - rec.theta_w).max() < 0.02  # rad: integral of the smoothed speed


def test_truth_model_fits_its_recording_better_than_a_wrong_model(synthetic):
    rec, truth_params, truth = synthetic
    # the recording starts at its own wheel phase (synth draws it): start the models there, so
    # that the impact bumps line up as they do for the truth
    q_w0 = truth["recordings"][0]["q_w0"]
    good = compare(rec, truth_params, q_w0=q_w0)["metrics"]
    wrong = compare(rec, truth_params.replace(mu_k=truth_params["mu_k"] * 1.6,
                                              mu_s=truth_params["mu_s"] * 1.6), q_w0=q_w0)["metrics"]
    for key in ("rel_speed_rms", "slip_ratio_vs_speed_rms", "stroke_rms"):
        g, w = good[key]["value"], wrong[key]["value"]
        assert np.isfinite(g) and np.isfinite(w), key
        assert w > 3 * g, (key, g, w)
    # the truth model reproduces its own recording to about the sensor noise (~0.005 rad/s)
    assert good["rel_speed_rms"]["value"] < 0.02
