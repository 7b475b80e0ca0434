"""Model runs saved while a diagnosis runs, so that an interrupted one resumes where it stopped.

A diagnosis is a deterministic function of its recordings, options and model runs: the same
command, given the runs it had already made, takes the same path and asks for them again. So
the checkpoint holds *model runs* only (band angle and motor torque of one simulation of one
recording at one parameter point, the cache of :class:`~szdyn.diagnose.engine.FeatureModel`),
not the diagnosis's state. Rerun, the diagnosis finds them in its cache and spends time only on
the runs it had not made. The runs do not depend on the diagnosis's options, so a rerun with
other options (``--phase-steps``, ``--candidates`` ...) reuses them too.

Layout of ``DIR`` (``--out DIR/checkpoint``)::

    fingerprint.json     what the runs are valid for (recordings and code, see fingerprint())
    runs-00000.npz       one batch of runs each (written atomically, no pickle)
    runs-00001.npz ...

A checkpoint whose fingerprint differs (other recordings, another version of the code) is not
used: it is moved aside to ``DIR-previous`` (replacing an older one there), so that a mistake
such as a changed manifest line does not delete hours of runs, and the command says so. After a
diagnosis that finishes, the command removes the checkpoint unless told to keep it
(``--keep-runs``).
"""
from __future__ import annotations

import hashlib
import io
import json
import shutil
import zipfile
from pathlib import Path

import numpy as np

from ..errors import UserInputError
from ..io import atomic_write_bytes, atomic_write_text
from .data import SIM_DT

__all__ = ["CHECKPOINT_DIR", "RunCheckpoint", "fingerprint"]

#: Subdirectory of the diagnosis's ``--out`` that the command keeps the runs in.
CHECKPOINT_DIR = "checkpoint"
#: Version of the file layout (in the fingerprint: a new layout discards old checkpoints).
LAYOUT = 1


def _code_files() -> list:
    """The source files whose change can change a model run: the runtime package and the
    generated model (numba and numpy versions go into the fingerprint separately)."""
    import szdyn
    import szdyn_generated

    files = []
    for pkg in (szdyn, szdyn_generated):
        root = Path(pkg.__file__).resolve().parent
        files += sorted(root.rglob("*.py"))
    return files


def fingerprint(recordings) -> str:
    """SHA-256 of what a model run depends on, as hex.

    Parameters
    ----------
    recordings : list of Prepared
        Each recording's name, parameters, measured drive (time and wheel speed) and interval.
        Not its role (runs are shared by fit and held-out use), nor whether it asks for the motor
        torque: a saved run without the torque does not answer a recording that asks for it
        (``FeatureModel._has``), and is made again.

    Notes
    -----
    Also hashed: the bytes of every ``.py`` file of ``szdyn`` and ``szdyn_generated`` and the
    numpy and numba versions, so a checkpoint never outlives a change of the code that made it.
    """
    import numba

    h = hashlib.sha256()
    h.update(f"layout {LAYOUT} numpy {np.__version__} numba {numba.__version__}\n".encode())
    for f in _code_files():
        h.update(f.name.encode())
        h.update(f.read_bytes())
    for r in sorted(recordings, key=lambda r: r.name):
        h.update(json.dumps([r.name, r.params.to_dict(), float(r.t0), float(r.t1)], sort_keys=True).encode())
        h.update(np.ascontiguousarray(r.drive.t, dtype=float).tobytes())
        h.update(np.ascontiguousarray(r.drive.omega, dtype=float).tobytes())
    return h.hexdigest()


def _from_grid(grid) -> np.ndarray:
    """The save times ``t0 + dt k`` with the last one ``t_end`` (``grid = [t0, dt, n, t_end]``),
    computed as the integrator computes them (:func:`szdyn.integrators.integrate`)."""
    t0, dt, n, t_end = (float(g) for g in grid)
    t = t0 + dt * np.arange(int(n))
    t[-1] = t_end
    return t


def _grid_of(t: np.ndarray):
    """``[t0, dt, n, t_end]`` if :func:`_from_grid` gives ``t`` back bit for bit (the model runs'
    save grid, :data:`~szdyn.diagnose.data.SIM_DT`), else None (then ``t`` is stored whole)."""
    if t.ndim != 1 or t.size < 2:
        return None
    grid = np.array([t[0], SIM_DT, t.size, t[-1]])
    return grid if np.array_equal(_from_grid(grid), t) else None


def _encode_key(key) -> list:
    name, changes = key
    # floats go through JSON exactly (repr round-trips), so a loaded key equals the one asked for
    return [name, [[k, v] for k, v in changes]]


def _decode_key(obj) -> tuple:
    name, changes = obj
    return name, tuple((str(k), float(v)) for k, v in changes)


class RunCheckpoint:
    """Model runs of a diagnosis on disk (see the module notes).

    Parameters
    ----------
    directory : path
        Where the runs are kept (created when the first batch is saved).
    fingerprint : str
        What the runs are valid for (:func:`fingerprint` of the recordings).
    warn : callable(str), optional
        Told when a checkpoint is not used (``discarded_``), and once when a batch cannot be
        written (disk full, permissions): the diagnosis then goes on without saving, rather
        than losing what it has done.

    Attributes
    ----------
    discarded_ : str or None
        Why an existing checkpoint was not used, and where it went (None: there was none, or
        it was used).
    error_ : str or None
        Why saving stopped (None: every batch was saved).
    """

    def __init__(self, directory, fingerprint: str, warn=None):
        self.directory = Path(directory)
        self.fingerprint = fingerprint
        self.warn = warn
        self.discarded_ = None
        self.error_ = None
        self._next = 0

    def _batches(self) -> list:
        return sorted(self.directory.glob("runs-*.npz"))

    def load(self) -> dict:
        """The saved runs, ``{(recording name, changes): (t, theta_b, tau or None) or None}``.

        A checkpoint made for other recordings or code is removed (``discarded_`` says why) and
        an empty dict returned. A batch or fingerprint that cannot be read (batches are written
        atomically, so only damage or another program can cut one short) raises
        :class:`~szdyn.errors.UserInputError` naming the file.
        """
        runs = {}
        stamp = self.directory / "fingerprint.json"
        if not stamp.is_file():
            if self._batches():
                self._discard("it has runs but no fingerprint.json")
            return runs
        try:
            saved = json.loads(stamp.read_text())
            if not isinstance(saved, dict):
                raise ValueError("not a JSON object")
        except (OSError, ValueError) as exc:
            raise UserInputError(f"{stamp}: unreadable checkpoint fingerprint ({exc}); remove "
                                 f"{self.directory} to start afresh") from None
        if saved.get("fingerprint") != self.fingerprint:
            self._discard("its runs are of other recordings, or of another version of szdyn, its generated "
                          "model, numpy or numba")
            return runs
        for f in self._batches():
            try:
                with np.load(f, allow_pickle=False) as z:
                    keys = json.loads(str(z["keys"]))
                    for j, key in enumerate(keys):
                        if f"qb_{j}" not in z:
                            runs[_decode_key(key)] = None          # a failed run
                            continue
                        t = z[f"t_{j}"] if f"t_{j}" in z else _from_grid(z[f"tgrid_{j}"])
                        qb = z[f"qb_{j}"]
                        tau = z[f"tau_{j}"] if f"tau_{j}" in z else None
                        if qb.shape != t.shape or (tau is not None and tau.shape != t.shape):
                            raise ValueError(f"run {j}: times, band angle and torque differ in length")
                        runs[_decode_key(key)] = (t, qb, tau)
                self._next = max(self._next, int(f.stem.split("-")[1]) + 1)
            except (OSError, ValueError, KeyError, TypeError, IndexError, EOFError, zipfile.BadZipFile) as exc:
                raise UserInputError(f"{f}: unreadable checkpoint batch ({exc}); remove {self.directory} "
                                     "to start afresh") from None
        return runs

    def save(self, runs: dict) -> None:
        """Add one batch of runs (the same mapping as :meth:`load` returns); atomic per batch.

        An ``OSError`` while writing stops the saving (``error_``, ``warn``) instead of the
        diagnosis."""
        if not runs or self.error_ is not None:
            return
        try:
            self._save(runs)
        except OSError as exc:
            self.error_ = f"{self.directory}: {exc.strerror or exc}"
            if self.warn is not None:
                self.warn(f"model runs no longer saved ({self.error_}); the diagnosis goes on, but an "
                          "interruption now loses the runs made from here")

    def _save(self, runs: dict) -> None:
        if not (self.directory / "fingerprint.json").is_file():
            atomic_write_text(self.directory / "fingerprint.json",
                              json.dumps({"fingerprint": self.fingerprint, "layout": LAYOUT}) + "\n")
        arrays = {"keys": np.array(json.dumps([_encode_key(k) for k in runs]))}
        for j, res in enumerate(runs.values()):
            if res is None:
                continue
            t, qb, tau = res
            grid = _grid_of(np.asarray(t))
            if grid is None:
                arrays[f"t_{j}"] = np.asarray(t)
            else:
                arrays[f"tgrid_{j}"] = grid
            arrays[f"qb_{j}"] = np.asarray(qb)
            if tau is not None:
                arrays[f"tau_{j}"] = np.asarray(tau)
        buf = io.BytesIO()
        # not compressed: a band angle's low bytes are noise (zlib saved 9 % of a 10 s run's at
        # ~100x the time); the save grid is stored as its rule, which halves the size
        np.savez(buf, **arrays)
        atomic_write_bytes(self.directory / f"runs-{self._next:05d}.npz", buf.getvalue())
        self._next += 1

    def _discard(self, why: str) -> None:
        aside = self.directory.with_name(self.directory.name + "-previous")
        shutil.rmtree(aside, ignore_errors=True)
        try:
            self.directory.rename(aside)
            where = f"moved to {aside} (delete it, or rename it back to use it with what it was made for)"
        except OSError as exc:
            self.clear()
            where = f"removed (it could not be moved aside: {exc.strerror or exc})"
        self.discarded_ = f"checkpoint {self.directory} not used: {why}; {where}"
        if self.warn is not None:
            self.warn(self.discarded_)

    def clear(self) -> None:
        """Remove the checkpoint directory and everything in it."""
        shutil.rmtree(self.directory, ignore_errors=True)
        self._next = 0
