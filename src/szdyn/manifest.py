"""Manifest of recordings: which files, under which conditions, with which model overrides.

A manifest is a TOML file (read with :mod:`tomllib` only)::

    # experiments.toml
    [model]                 # optional: parameter overrides for every recording (SI)
    mu_k = 0.25
    n_rollers = 8

    [motor]                 # optional: for recordings with a `current` column
    torque_constant = 0.05  # torque at the wheel per ampere (N m/A): motor constant x gear ratio

    [split]                 # optional: recordings held out of calibration
    heldout = ["ramp3.csv"] # file names as written in [[recording]], or a fraction:
    # heldout = 0.25        #   round(0.25 * n) recordings (at least one), numpy seed `seed`
    # seed = 0

    [[recording]]
    file = "ramp1.csv"      # relative to the manifest's directory
    load_kg = 1.0           # -> model m_b (kg)
    n_circles = 100         # -> model N_c
    note = "first ramp, fresh band"
    # torque_constant = 0.05  # overrides [motor] for this recording (N m/A)

Known keys of a ``[[recording]]``: ``file`` (required; two names of one file are refused),
``load_kg`` (number > 0, sets the model's ``m_b``; ``[model] m_b`` is refused when every
recording has one), ``n_circles`` (positive integer), ``note`` (text), ``torque_constant``
(number > 0, N m/A; with the recording's ``current`` column it gives the measured motor torque,
which the diagnosis compares with the model's). Unknown keys anywhere are errors with a
did-you-mean suggestion; ``[model]`` names are checked against
``szdyn_generated.spiral_zipper.PARAM_NAMES`` and values must be real numbers (not booleans,
not strings), and the overrides with each recording's conditions must make a valid parameter
set (checked when read, so the message names the table). ``[split] heldout`` must hold out at
least one recording and not all; ``[split] seed`` is refused unless ``heldout`` is a fraction,
the only split it draws. A UTF-8 byte-order mark is accepted. Errors are
:class:`ManifestError` (a :class:`~szdyn.errors.UserInputError`) naming the manifest file and
the table/key, e.g.
``experiments.toml, [[recording]] 2 ('ramp2.csv'): unknown key 'load_k' (did you mean
'load_kg'?)``.
"""
from __future__ import annotations

import difflib
import math
import numbers
import tomllib
from dataclasses import dataclass, field, replace
from pathlib import Path

import numpy as np

from szdyn.defaults import MAX_N_CIRCLES
from szdyn.errors import UserInputError, brief

__all__ = ["ManifestError", "ManifestEntry", "Manifest", "read_manifest", "RECORDING_KEYS"]

#: key -> meaning, for a [[recording]] table
RECORDING_KEYS = {
    "file": "recording CSV, relative to the manifest",
    "load_kg": "load carried by the column (kg); sets the model's m_b",
    "n_circles": "number of small circles N_c of the model",
    "note": "free text",
    "torque_constant": "torque at the wheel per ampere of the current column (N m/A); overrides [motor]",
}
TOP_KEYS = ("recording", "model", "split", "motor")
MOTOR_KEYS = ("torque_constant",)
SPLIT_KEYS = ("heldout", "seed")


class ManifestError(UserInputError):
    """A manifest is broken; the message names the file and the table/key."""


def _suggest(name: str, valid) -> str:
    close = difflib.get_close_matches(name, list(valid), n=1, cutoff=0.5)
    return f" (did you mean '{close[0]}'?)" if close else ""


def _is_real(v) -> bool:
    if not isinstance(v, numbers.Real) or isinstance(v, bool):
        return False
    try:
        return math.isfinite(float(v))
    except OverflowError:       # a TOML integer beyond a float's range
        return False


def _table(data: dict, name: str, keys, nm: str) -> dict:
    """The manifest's table ``[name]``, checked to be a table of known ``keys`` only."""
    tbl = data[name]
    if not isinstance(tbl, dict):
        raise ManifestError(f"{nm}: '{name}' must be a table ([{name}])")
    for key in tbl:
        if key not in keys:
            raise ManifestError(f"{nm}, [{name}]: unknown key '{key}'{_suggest(key, keys)}; "
                                f"known: {', '.join(keys)}")
    return tbl


def _torque_constant(v, label: str) -> float:
    if not _is_real(v) or v <= 0:
        raise ManifestError(f"{label}: 'torque_constant' must be a number > 0 (N m/A), got {brief(v)}")
    return float(v)


@dataclass(frozen=True)
class ManifestEntry:
    """One ``[[recording]]`` of a manifest.

    Attributes
    ----------
    file : Path
        Absolute (resolved against the manifest's directory) path of the CSV.
    name : str
        The file as written in the manifest (used by ``[split] heldout``).
    conditions : dict
        ``load_kg`` (float), ``n_circles`` (int), ``note`` (str), only those given.
    torque_constant : float or None
        Torque at the wheel per ampere of the recording's ``current`` column (N m/A): its own
        ``torque_constant``, else ``[motor] torque_constant``, else None (current not used).
    """

    file: Path
    name: str
    conditions: dict
    torque_constant: float | None = None

    def model_changes(self) -> dict:
        """Parameter changes implied by the conditions, for ``ParameterSet.replace``.

        Returns
        -------
        dict
            ``m_b`` from ``load_kg`` and ``n_circles`` when given.
        """
        out = {}
        if "load_kg" in self.conditions:
            out["m_b"] = float(self.conditions["load_kg"])
        if "n_circles" in self.conditions:
            out["n_circles"] = int(self.conditions["n_circles"])
        return out

    def read(self):
        """Read the recording (:func:`szdyn.recordings.read_recording`) with these conditions."""
        from szdyn.recordings import read_recording

        return read_recording(self.file, self.conditions, name=self.name)


@dataclass(frozen=True)
class Manifest:
    """A parsed manifest.

    Attributes
    ----------
    path : Path
        The manifest file.
    entries : tuple of ManifestEntry
        In file order.
    model : dict of str -> float
        ``[model]`` parameter overrides (SI), validated names.
    heldout : tuple of str
        Names (as in ``ManifestEntry.name``) of the held-out recordings.
    """

    path: Path
    entries: tuple
    model: dict = field(default_factory=dict)
    heldout: tuple = ()

    def training(self) -> tuple:
        """Entries not held out (for calibration)."""
        return tuple(e for e in self.entries if e.name not in self.heldout)

    def validation(self) -> tuple:
        """Held-out entries (for validation)."""
        return tuple(e for e in self.entries if e.name in self.heldout)

    def parameters(self, entry: ManifestEntry, base=None):
        """Model parameters for one recording: ``base`` + ``[model]`` + the entry's conditions.

        Parameters
        ----------
        entry : ManifestEntry
        base : ParameterSet, optional
            Default :func:`szdyn.defaults.default_parameters` (with the entry's ``n_circles``
            when given).

        Returns
        -------
        ParameterSet

        Raises
        ------
        ParameterError
            If the combination is invalid (message names the parameter).
        """
        from szdyn.defaults import default_parameters

        changes = entry.model_changes()
        if base is None:
            base = (default_parameters(changes["n_circles"]) if "n_circles" in changes
                    else default_parameters())
        return base.replace(**{**self.model, **changes})


def read_manifest(path, *, check_files: bool = True) -> Manifest:
    """Read and validate a manifest TOML file.

    Parameters
    ----------
    path : str or Path
    check_files : bool
        Also check that every recording file exists (default True).

    Returns
    -------
    Manifest

    Raises
    ------
    ManifestError
        Naming the manifest file and the offending table/key (TOML syntax errors keep the
        line and column from :mod:`tomllib`).
    """
    path = Path(path)
    nm = str(path)   # as given: "manifest.toml" alone would not say which of several
    try:
        raw = path.read_bytes()
        # editors on Windows save UTF-8 with a byte-order mark; TOML does not allow one, the
        # recordings' reader accepts it, so the manifest does too
        data = tomllib.loads(raw.removeprefix(b"\xef\xbb\xbf").decode("utf-8"))
    except FileNotFoundError:
        raise ManifestError(f"{nm}: file not found") from None
    except IsADirectoryError:
        raise ManifestError(f"{nm}: is a directory, expected a TOML file") from None
    except tomllib.TOMLDecodeError as exc:
        raise ManifestError(f"{nm}: invalid TOML: {exc}") from None
    except UnicodeDecodeError as exc:
        raise ManifestError(f"{nm}: not a UTF-8 text file ({exc.reason})") from None
    except OSError as exc:
        raise ManifestError(f"{nm}: cannot read ({exc.strerror})") from None

    for key in data:
        if key not in TOP_KEYS:
            raise ManifestError(f"{nm}: unknown table or key '{key}'{_suggest(key, TOP_KEYS)}; "
                                f"known: {', '.join(TOP_KEYS)}")
    recs = data.get("recording")
    if recs is None:
        raise ManifestError(f"{nm}: no recordings (add [[recording]] tables with file = ...)")
    if not isinstance(recs, list) or not all(isinstance(r, dict) for r in recs):
        raise ManifestError(f"{nm}: 'recording' must be an array of tables ([[recording]])")
    if not recs:
        raise ManifestError(f"{nm}: no recordings (add [[recording]] tables with file = ...)")

    entries = []
    seen = {}
    base_dir = path.parent
    for i, r in enumerate(recs, start=1):
        label = f"{nm}, [[recording]] {i}"
        if "file" in r and isinstance(r["file"], str):
            label += f" ('{r['file']}')"
        for key in r:
            if key not in RECORDING_KEYS:
                raise ManifestError(f"{label}: unknown key '{key}'{_suggest(key, RECORDING_KEYS)}; "
                                    f"known: {', '.join(RECORDING_KEYS)}")
        if "file" not in r:
            raise ManifestError(f"{label}: missing key 'file'")
        f = r["file"]
        if not isinstance(f, str) or not f.strip():
            raise ManifestError(f"{label}: 'file' must be a non-empty string, got {f!r}")
        try:
            full = (base_dir / f).resolve()
            # asked here, so that a name the system refuses (too long, a NUL byte) is said once
            kind = None
            if check_files:
                kind = "directory" if full.is_dir() else "file" if full.is_file() else None
        except (OSError, ValueError) as exc:
            raise ManifestError(f"{label}: 'file' is not a usable path ({exc})") from None
        if full in seen:
            j, g = seen[full]
            same = f"file '{f}' is listed twice" if g == f else f"'{f}' is the same file as '{g}'"
            raise ManifestError(f"{label}: {same} ([[recording]] {j} and {i})")
        seen[full] = (i, f)
        cond = {}
        if "load_kg" in r:
            v = r["load_kg"]
            if not _is_real(v) or v <= 0:
                raise ManifestError(f"{label}: 'load_kg' must be a number > 0 (kg), got {brief(v)}")
            cond["load_kg"] = float(v)
        if "n_circles" in r:
            v = r["n_circles"]
            if isinstance(v, bool) or not isinstance(v, int) or not 0 < v <= MAX_N_CIRCLES:
                raise ManifestError(f"{label}: 'n_circles' must be a positive integer up to {MAX_N_CIRCLES} "
                                    f"(the thesis uses 100), got {brief(v)}")
            cond["n_circles"] = int(v)
        if "note" in r:
            if not isinstance(r["note"], str):
                raise ManifestError(f"{label}: 'note' must be a string, got {r['note']!r}")
            cond["note"] = r["note"]
        kt = None
        if "torque_constant" in r:
            kt = _torque_constant(r["torque_constant"], label)
        if check_files and kind == "directory":
            raise ManifestError(f"{label}: {full} is a directory, expected a CSV file")
        if check_files and kind is None:
            what = "not a regular file" if full.exists() else "recording file not found"
            raise ManifestError(f"{label}: {what}: {full}")
        entries.append(ManifestEntry(file=full, name=f, conditions=cond, torque_constant=kt))

    if "motor" in data:
        tbl = _table(data, "motor", MOTOR_KEYS, nm)
        if "torque_constant" in tbl:
            kt = _torque_constant(tbl["torque_constant"], f"{nm}, [motor]")
            entries = [e if e.torque_constant is not None else replace(e, torque_constant=kt)
                       for e in entries]

    model = {}
    if "model" in data:
        from szdyn_generated.spiral_zipper import PARAM_NAMES

        tbl = data["model"]
        if not isinstance(tbl, dict):
            raise ManifestError(f"{nm}: 'model' must be a table ([model])")
        for key, v in tbl.items():
            if key not in PARAM_NAMES:
                hint = _suggest(key, PARAM_NAMES)
                extra = (" (set load_kg or n_circles per [[recording]])"
                         if key in ("load_kg", "n_circles") else
                         " (the motor's torque constant goes in [motor])" if key == "torque_constant" else "")
                raise ManifestError(f"{nm}, [model]: unknown parameter '{key}'{hint}{extra}; "
                                    f"valid: {', '.join(PARAM_NAMES)}")
            if not _is_real(v):
                raise ManifestError(f"{nm}, [model]: parameter '{key}' must be a finite number, "
                                    f"got {brief(v)}")
            model[key] = float(v)
        if "m_b" in model and all("load_kg" in e.conditions for e in entries):
            # [model] m_b still sets the load of recordings without load_kg; beside a load_kg
            # in every one it would set nothing, silently
            raise ManifestError(f"{nm}, [model]: 'm_b' is the load, which 'load_kg' sets in every "
                                "[[recording]]; remove it, or set load_kg there")
    # the overrides, then each recording's conditions with them, checked now: a bad value found
    # later, at the recording's turn in a diagnosis, would name neither the file nor the table
    from szdyn.defaults import default_parameters
    from szdyn.errors import ParameterError

    try:
        default_parameters().replace(**model)
    except ParameterError as exc:
        raise ManifestError(f"{nm}, [model]: {exc}") from None
    for i, e in enumerate(entries, start=1):
        try:
            Manifest(path=path, entries=(), model=model).parameters(e)
        except ParameterError as exc:
            raise ManifestError(f"{nm}, [[recording]] {i} ('{e.name}'): {exc}") from None

    heldout = ()
    if "split" in data:
        tbl = _table(data, "split", SPLIT_KEYS, nm)
        h = tbl.get("heldout", [])
        seed = tbl.get("seed", 0)
        if isinstance(seed, bool) or not isinstance(seed, int) or seed < 0:
            raise ManifestError(f"{nm}, [split]: 'seed' must be a non-negative integer, got {brief(seed)}")
        if "seed" in tbl and ("heldout" not in tbl or isinstance(h, list)):
            # the seed draws the recordings a fraction holds out; anything else would ignore it
            what = "a list of files" if "heldout" in tbl else "no 'heldout'"
            raise ManifestError(f"{nm}, [split]: 'seed' only draws which recordings a fractional "
                                f"'heldout' holds out (e.g. heldout = 0.3); with {what} it would do "
                                "nothing: remove it")
        names = [e.name for e in entries]
        if isinstance(h, list):
            for x in h:
                if not isinstance(x, str):
                    raise ManifestError(f"{nm}, [split]: 'heldout' entries must be file names, got {x!r}")
                if x not in names:
                    raise ManifestError(f"{nm}, [split]: heldout file '{x}' is not a [[recording]]"
                                        f"{_suggest(x, names)}")
            heldout = tuple(dict.fromkeys(h))
        elif _is_real(h):
            if not 0 <= h < 1:
                raise ManifestError(f"{nm}, [split]: 'heldout' fraction must be in [0, 1), got {h!r}")
            # a fraction of a few recordings holds out at least one: 0.25 of 2 is one, not none
            k = max(1, int(round(h * len(names)))) if h > 0 else 0
            pick = np.random.default_rng(seed).choice(len(names), size=k, replace=False)
            heldout = tuple(names[j] for j in sorted(pick))
        else:
            raise ManifestError(f"{nm}, [split]: 'heldout' must be a list of file names or a "
                                f"fraction, got {h!r}")
        if "heldout" in tbl and not heldout:
            raise ManifestError(f"{nm}, [split]: 'heldout' = {h!r} holds out no recording; "
                                "calibration is judged on held-out recordings: name at least one, "
                                "or remove [split] to let szdyn choose")
        if len(heldout) == len(entries):
            raise ManifestError(f"{nm}, [split]: every recording is held out; nothing is left "
                                "for calibration")
    return Manifest(path=path.resolve(), entries=tuple(entries), model=model, heldout=heldout)
