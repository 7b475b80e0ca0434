"""bench/next_recording_proof.py records the asked-for protocol from the same truth as the rig
would and adds it to a copy of the recordings as one more fit recording."""

import json

import numpy as np
import pytest

from szdyn.diagnose.data import prepare
from szdyn.diagnose.design import PROTOCOLS
from szdyn.manifest import read_manifest
from szdyn.synth import QUICK_RAMPS, synthesize

from cases import load_bench


def test_the_asked_for_protocol_is_recorded_from_the_truth_as_a_fit_recording(tmp_path):
    bench = load_bench("next_recording_proof")
    case = tmp_path / "case"
    synthesize(case / "data", "friction_drift", 0.2, seed=4, loads_kg=(0.5, 1.0), ramps=QUICK_RAMPS,
               n_circles=16, dt=5e-5, verbose=False)
    (case / "data" / "truth.json").rename(case / "truth.json")
    proto = next(p for p in PROTOCOLS if p.id == "fast_start")
    row = {"protocol": proto.id, "load_kg": 1.0, "separation": {"a vs b": 3.0}, "min_separation": 3.0}
    diag = {"next_recording": {"scale_speed": 2.0, "recommended": row, "protocols": [row]}}
    added = bench.add_recording(case, diag, tmp_path / "work")
    assert added["file"] == "next_fast_start_load1kg.csv" and added["recommended"]
    data = tmp_path / "work" / "data"
    assert not (data / "truth.json").exists()      # the copy the diagnosis reads has no answer
    man = read_manifest(data / "manifest.toml")
    recs = {r.name: r for r in prepare(man)}
    new = recs[added["file"]]
    held = json.loads((case / "truth.json").read_text())
    assert new.role == "fit" and len(recs) == len(held["recordings"]) + 1
    assert [r.name for r in recs.values() if r.role != "fit"] == \
        [r["file"] for r in held["recordings"] if r["heldout"]]
    assert new.load_kg == 1.0 and new.t1 >= proto.duration - 0.01
    # the wheel follows the protocol at its scale
    w = np.interp(new.t_feat, [0.0, 0.25, 4.25], [0.0, 2.0, 2.0])
    assert np.max(np.abs(new.omega_w - w)[new.t_feat > 0.3]) < 0.05
    # its own random stream: a wheel phase of its own, and the same recording when made again
    assert all(abs(added["q_w0"] - r["q_w0"]) > 1e-9 for r in held["recordings"])
    again = bench.add_recording(case, diag, tmp_path / "again")
    assert (tmp_path / "again" / "data" / again["file"]).read_bytes() == (data / added["file"]).read_bytes()
    # a row that is not in the ranking is refused
    with pytest.raises(SystemExit, match="no row"):
        bench.add_recording(case, diag, tmp_path / "w2", "long_hold", 1.0)
