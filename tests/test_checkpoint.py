"""Model runs saved on disk so that an interrupted diagnosis resumes (``szdyn.diagnose.checkpoint``).

The end-to-end proof (interrupt a diagnosis, rerun it, get the same answer from fewer runs) is in
``tests/test_diagnose.py``, which has the recordings.
"""
from __future__ import annotations

import json
from types import SimpleNamespace

import numpy as np
import pytest

from szdyn.diagnose.checkpoint import RunCheckpoint, fingerprint
from szdyn.diagnose.data import SIM_DT
from szdyn.errors import UserInputError


def _run(n, seed, torque=True, t0=0.0, t_end=None):
    rng = np.random.default_rng(seed)
    t = t0 + SIM_DT * np.arange(n)          # the integrator's save grid: t0 + k dt, last t_end
    if t_end is not None:
        t[-1] = t_end
    return t, np.cumsum(rng.normal(size=n)), (rng.normal(size=n) if torque else None)


def _runs():
    # keys as FeatureModel makes them: (recording name, sorted (parameter, float) pairs); floats
    # that print long must come back bit for bit, or a resumed diagnosis would miss its cache
    return {
        ("up.csv", (("k_c", 0.1 + 0.2), ("mu_k", 0.25))): _run(50, 1),
        ("up.csv", (("mu_k", 1 / 3), ("q_w0", 0.012345678901234567))): _run(40, 2, torque=False),
        ("down.csv", ()): _run(30, 3, t0=0.123, t_end=0.123 + 29.5 * SIM_DT),
        # times off the grid are stored as they are
        ("down.csv", (("mu_s", 0.3),)): (np.array([0.0, 0.3, 0.31]), np.zeros(3), None),
        ("down.csv", (("b_c", 1e-300),)): None,                  # a run that failed
    }


def _same(a, b):
    assert a.keys() == b.keys()
    for k in a:
        if a[k] is None or b[k] is None:
            assert a[k] is None and b[k] is None, k
            continue
        assert len(a[k]) == len(b[k]) == 3, k
        for x, y in zip(a[k], b[k]):
            assert (x is None and y is None) or np.array_equal(x, y), k


def test_saved_runs_load_back_exactly_batch_after_batch(tmp_path):
    runs = _runs()
    items = list(runs.items())
    ck = RunCheckpoint(tmp_path / "ck", "abc")
    assert ck.load() == {} and ck.discarded_ is None and not (tmp_path / "ck").exists()
    ck.save(dict(items[:2]))
    ck.save({})                                                   # nothing new: no file
    ck.save(dict(items[2:]))
    assert sorted(p.name for p in (tmp_path / "ck").iterdir()) == ["fingerprint.json", "runs-00000.npz",
                                                                   "runs-00001.npz"]
    again = RunCheckpoint(tmp_path / "ck", "abc")
    loaded = again.load()
    _same(loaded, runs)
    assert len(loaded) == 5 and again.discarded_ is None
    # a resumed diagnosis adds its batches after the loaded ones
    again.save({("down.csv", (("mu_k", 0.3),)): _run(10, 4)})
    assert (tmp_path / "ck" / "runs-00002.npz").is_file()
    assert len(RunCheckpoint(tmp_path / "ck", "abc").load()) == 6
    # no pickle: every array loads with allow_pickle=False (load() itself uses it)
    with np.load(tmp_path / "ck" / "runs-00000.npz", allow_pickle=False) as z:
        assert json.loads(str(z["keys"]))[0][0] == "up.csv"
    # the save grid is kept as its rule, other times whole; a failed run as its key only
    with np.load(tmp_path / "ck" / "runs-00001.npz", allow_pickle=False) as z:
        assert {"tgrid_0", "t_1"} <= set(z.files) and not {"t_0", "tgrid_1", "qb_2"} & set(z.files)


def test_runs_of_other_recordings_or_code_are_moved_aside_and_said(tmp_path):
    ck = RunCheckpoint(tmp_path / "ck", "old")
    ck.save(dict(list(_runs().items())[:1]))
    said = []
    other = RunCheckpoint(tmp_path / "ck", "new", warn=said.append)
    assert other.load() == {}
    assert said == [other.discarded_] and "other recordings, or of another version" in said[0]
    # not deleted: a mistake (a changed manifest line) must not cost the runs; renamed back,
    # they serve what they were made for
    assert not (tmp_path / "ck").exists() and str(tmp_path / "ck-previous") in said[0]
    (tmp_path / "ck-previous").rename(tmp_path / "ck")
    assert len(RunCheckpoint(tmp_path / "ck", "old").load()) == 1
    # runs without a fingerprint are not trusted either
    (tmp_path / "ck2").mkdir()
    (tmp_path / "ck2" / "runs-00000.npz").write_bytes(b"")
    lone = RunCheckpoint(tmp_path / "ck2", "new")
    assert lone.load() == {} and "no fingerprint.json" in lone.discarded_
    assert (tmp_path / "ck2-previous" / "runs-00000.npz").is_file()


def _damage(ck_dir, how):
    fp, batch = ck_dir / "fingerprint.json", ck_dir / "runs-00000.npz"
    if how == "cut batch":
        batch.write_bytes(batch.read_bytes()[:20])
        return batch
    if how in ("cut fingerprint", "null fingerprint"):
        fp.write_text('{"finger' if how == "cut fingerprint" else "null")
        return fp
    with np.load(batch, allow_pickle=False) as z:
        arrays = {k: z[k] for k in z.files}
    if how == "bad key":
        arrays["keys"] = np.array(json.dumps([["up.csv", 3]]))
    else:                                                 # a band angle shorter than its times
        arrays["qb_0"] = arrays["qb_0"][:-1]
    np.savez(batch, **arrays)
    return batch


@pytest.mark.parametrize("how", ["cut batch", "cut fingerprint", "null fingerprint", "bad key", "short run"])
def test_a_damaged_checkpoint_is_a_clear_error_naming_the_file(tmp_path, how):
    ck = RunCheckpoint(tmp_path / "ck", "abc")
    ck.save(dict(list(_runs().items())[:2]))
    bad = _damage(tmp_path / "ck", how)
    with pytest.raises(UserInputError, match=str(bad).replace(".", r"\.")):
        RunCheckpoint(tmp_path / "ck", "abc").load()


def _rec(name, omega=1.0, mu_k=0.25, role="fit", tau=None):
    params = SimpleNamespace(to_dict=lambda: {"mu_k": mu_k, "m_b": 1.0})
    t = np.linspace(0.0, 1.0, 11)
    return SimpleNamespace(name=name, role=role, params=params, t0=0.0, t1=1.0, tau=tau,
                           drive=SimpleNamespace(t=t, omega=omega * t))


def test_fingerprint_follows_what_a_run_depends_on_and_not_the_roles():
    base = fingerprint([_rec("a"), _rec("b")])
    assert fingerprint([_rec("b"), _rec("a", role="heldout")]) == base      # order and role: no
    assert fingerprint([_rec("a", omega=1.001), _rec("b")]) != base         # the measured drive
    assert fingerprint([_rec("a", mu_k=0.26), _rec("b")]) != base           # a manifest override
    # whether it asks for the torque: no (a saved run without it is made again, FeatureModel._has)
    assert fingerprint([_rec("a", tau=np.zeros(3)), _rec("b")]) == base
    assert fingerprint([_rec("a")]) != base                                 # another set


def test_a_checkpoint_that_cannot_be_written_warns_once_and_lets_the_diagnosis_go_on(tmp_path):
    (tmp_path / "ck").write_text("a file where the directory should be")
    said = []
    ck = RunCheckpoint(tmp_path / "ck", "abc", warn=said.append)
    items = list(_runs().items())
    ck.save(dict(items[:1]))                  # no exception: the diagnosis must not be lost
    ck.save(dict(items[1:2]))
    assert ck.error_ is not None and str(tmp_path / "ck") in ck.error_
    assert len(said) == 1 and "no longer saved" in said[0]


def test_an_interrupted_batch_keeps_every_run_that_finished(monkeypatch):
    """Ctrl-C while a batch runs on workers: the runs that finished are given to ``on_runs``,
    also those that finished before the one being read (runs are handed out longest first
    and read in order). A thread pool stands in for the process pool, so the patch acts."""
    import threading
    from concurrent.futures import ThreadPoolExecutor

    from szdyn.diagnose import engine

    durations = [0.5, 1.0, 2.0, 3.0, 4.0]   # read first, handed out last
    recs = [_rec(f"r{j}") for j in range(5)]
    for r, d in zip(recs, durations):
        r.t1 = d
    others_done = threading.Event()
    finished = []
    lock = threading.Lock()

    def simulate(task):
        if task[3] == 0.5:                   # the run read first
            assert others_done.wait(10)
            raise KeyboardInterrupt
        return np.arange(3.0), np.zeros(3), None

    def one_more_done(fut):
        # a done callback runs once its future is marked finished; setting the event inside
        # simulate (before it returns) raced with the interrupt, and the last run was missed
        with lock:
            finished.append(fut)
            if len(finished) == 4:
                others_done.set()

    class Pool(ThreadPoolExecutor):
        def submit(self, fn, *args, **kwargs):
            fut = super().submit(fn, *args, **kwargs)
            if args[0][3] != 0.5:
                fut.add_done_callback(one_more_done)
            return fut
    monkeypatch.setattr(engine, "_simulate", simulate)
    saved = []
    model = engine.FeatureModel(recs, workers=2, on_runs=saved.append)
    monkeypatch.setattr(model, "_executor", lambda: pool)
    with Pool(2) as pool:
        with pytest.raises(KeyboardInterrupt):
            model._run_all([(r.name, ()) for r in recs])
    assert len(saved) == 1 and sorted(k[0] for k in saved[0]) == ["r1", "r2", "r3", "r4"]
    assert model.n_runs_ == 4
