"""Validated parameter sets for the Spiral Zipper model.

A :class:`ParameterSet` holds one value for every name in the generated module's
``PARAM_NAMES`` (the flat parameter vector ``p`` of docs/CONTRACT.md), the structural circle
count ``N_c`` (which sets the state length, not part of ``p``) and the band geometry used to
turn band rotation into stroke. All values are SI. Default values live only in
:mod:`szdyn.defaults`.

The generated module is imported lazily (inside functions) so that this module imports without
it; positions in ``p`` are never hard-coded, only ``PARAM_NAMES`` order is used.
"""
from __future__ import annotations

import difflib
import json
import math
import numbers
import warnings
from dataclasses import dataclass
from pathlib import Path
from types import MappingProxyType
from typing import Mapping

import numpy as np

from .io import write_json

from szdyn.defaults import MAX_N_CIRCLES, MAX_N_ROLLERS
from szdyn.errors import ParameterError, brief
from szdyn.geometry import BandGeometry

__all__ = ["ParameterSet", "param_names", "param_index", "validate"]

_FORMAT = "szdyn-parameters"
_VERSION = 1

# Bound kinds (strings shared with derive/symbols.py, exported as PARAM_BOUNDS).
POSITIVE = "> 0"  # strictly positive real
NONNEG = ">= 0"  # non-negative real
POSINT = "positive integer"
CHOICE = "one of "  # prefix: "one of 0,1,2"
REAL = "real"  # any finite value (signed effect parameters)


def _bounds() -> dict[str, tuple[str, str]]:
    """name -> (unit, bound kind), from the generated module (one source: derive/symbols.py)."""
    from szdyn_generated.spiral_zipper import PARAM_BOUNDS, PARAM_DOCS

    return {name: (PARAM_DOCS[name][0], PARAM_BOUNDS[name]) for name in PARAM_BOUNDS}


def param_names() -> tuple[str, ...]:
    """Names of the flat parameter vector, in order, from the generated module.

    Returns
    -------
    tuple of str
        ``szdyn_generated.spiral_zipper.PARAM_NAMES``.

    Raises
    ------
    ImportError
        If the generated module is not importable (there is deliberately no fallback list:
        the generated module is the single source of the order).
    """
    try:
        from szdyn_generated.spiral_zipper import PARAM_NAMES
    except ImportError as exc:
        raise ImportError(
            "szdyn_generated.spiral_zipper is not importable (generate it with the derive step "
            f"and install the package): {exc}") from exc
    return tuple(PARAM_NAMES)


def param_index() -> Mapping[str, int]:
    """``PARAM_INDEX`` of the generated module: name -> position in ``p``."""
    from szdyn_generated.spiral_zipper import PARAM_INDEX
    return PARAM_INDEX


def suggest(name: str, valid) -> str:
    """Return ``" (did you mean 'x'?)"`` for the closest valid name, or ``""``."""
    valid = list(valid)
    lower = {v.lower(): v for v in valid}
    if name.lower() in lower:
        return f" (did you mean '{lower[name.lower()]}'?)"
    close = difflib.get_close_matches(name, valid, n=1, cutoff=0.5)
    return f" (did you mean '{close[0]}'?)" if close else ""


def _unknown(key: str, valid, what: str = "parameter") -> ParameterError:
    valid = list(valid)
    return ParameterError(f"unknown {what} '{key}'{suggest(key, valid)}; valid names: "
                          + ", ".join(valid))


def _fmt(value) -> str:
    return repr(float(value)) if isinstance(value, float) else repr(value)


def _as_real(name: str, value) -> float:
    # (a JSON true is a Python bool, which is an int: refused, not read as 1)
    if isinstance(value, numbers.Real) and not isinstance(value, bool):
        try:
            return float(value)
        except OverflowError:   # a JSON integer beyond a float's range
            raise ParameterError(f"parameter '{name}' must be a finite number, got an integer too "
                                 "large for a float") from None
    raise ParameterError(f"parameter '{name}' must be a real number, got {value!r}")


def _check_n_circles(n_circles) -> int:
    ok = (not isinstance(n_circles, bool) and isinstance(n_circles, numbers.Real)
          and (isinstance(n_circles, int) or math.isfinite(float(n_circles)))
          and n_circles == int(n_circles) and int(n_circles) > 0)
    if not ok:
        raise ParameterError(f"parameter 'n_circles' (N_c) must be a positive integer, "
                             f"got {brief(n_circles)}")
    if int(n_circles) > MAX_N_CIRCLES:
        raise ParameterError(f"parameter 'n_circles' (N_c) must be at most {MAX_N_CIRCLES} (the thesis uses "
                             f"100; a run's memory and time grow with N_c), got {brief(n_circles)}")
    return int(n_circles)


def validate(values: Mapping[str, float], n_circles: int, names=None) -> dict[str, float]:
    """Check a full set of parameter values; return them as a new dict of floats.

    Parameters
    ----------
    values : mapping of str to float
        One value per name in ``names`` (SI units and bounds: ``PARAM_DOCS`` and
        ``PARAM_BOUNDS`` of the generated module).
    n_circles : int
        ``N_c``, number of small circles (positive integer).
    names : sequence of str, optional
        Expected names; defaults to :func:`param_names`.

    Returns
    -------
    dict of str to float
        The values in ``names`` order, converted to float.

    Raises
    ------
    ParameterError
        Naming the parameter (and its unit and value) on the first problem found: unknown or
        missing name, non-real or non-finite value, bound violated (positive masses, inertias,
        lengths, ``n_imp``, ``gamma``, ``g``; non-negative stiffness, damping, friction
        coefficients and ``m_b``; ``n_rollers`` and ``N_c`` positive integers, at most
        ``MAX_N_ROLLERS`` and ``MAX_N_CIRCLES``; ``impact_clamp``
        and ``drive_mode`` in {0, 1}), ``mu_k > mu_s``, or geometric inconsistency
        (``d < R_bo``, ``R_w + t_r < R_bo``, ``t_c < d`` are required).
    """
    names = tuple(param_names() if names is None else names)
    bounds = _bounds()
    for key in values:
        if key not in names:
            raise _unknown(key, names)
    out: dict[str, float] = {}
    for name in names:
        if name not in values:
            raise ParameterError(f"missing value for parameter '{name}'")
        unit, kind = bounds[name]
        v = _as_real(name, values[name])
        u = "" if unit == "1" else f" {unit}"
        if not math.isfinite(v):
            raise ParameterError(f"parameter '{name}' must be finite, got {v!r}")
        if kind == POSITIVE and not v > 0.0:
            raise ParameterError(f"parameter '{name}' must be > 0{u}, got {_fmt(v)}")
        if kind == NONNEG and not v >= 0.0:
            raise ParameterError(f"parameter '{name}' must be >= 0{u}, got {_fmt(v)}")
        if kind == POSINT and not (v > 0.0 and v == int(v)):
            raise ParameterError(f"parameter '{name}' must be a positive integer, got {_fmt(v)}")
        if kind not in (POSITIVE, NONNEG, POSINT, REAL) and not kind.startswith(CHOICE):
            raise RuntimeError(f"parameter '{name}' has an unknown bound kind {kind!r} in derive/symbols.py")
        if kind.startswith(CHOICE) and v not in {float(c) for c in kind[len(CHOICE):].split(",")}:
            raise ParameterError(f"parameter '{name}' must be {kind}, got {_fmt(v)}")
        out[name] = v
    _check_n_circles(n_circles)

    def has(*ns):
        return all(n in out for n in ns)

    if has("n_rollers") and out["n_rollers"] > MAX_N_ROLLERS:
        raise ParameterError(f"parameter 'n_rollers' (N_r) must be at most {MAX_N_ROLLERS} (the thesis's "
                             f"wheel has 8; a run's time grows with N_r), got {_fmt(out['n_rollers'])}")
    if has("mu_s", "mu_k") and out["mu_k"] > out["mu_s"]:
        raise ParameterError(f"parameter 'mu_k' must be <= mu_s = {out['mu_s']!r}, "
                             f"got {out['mu_k']!r}")
    if has("d", "R_bo") and not out["d"] < out["R_bo"]:
        raise ParameterError(f"parameter 'd' (arm length) must be < R_bo = {out['R_bo']!r} m, "
                             f"got {out['d']!r}")
    if has("R_w", "t_r", "R_bo") and not out["R_w"] + out["t_r"] < out["R_bo"]:
        raise ParameterError(
            f"parameter 'R_w' + t_r must be < R_bo = {out['R_bo']!r} m (rollers must fit inside "
            f"the band), got R_w = {out['R_w']!r}, t_r = {out['t_r']!r}")
    if has("contact_model", "F_nw") and out["contact_model"] != 0 and not out["F_nw"] > 0:
        raise ParameterError("parameter 'F_nw' must be > 0 N when contact_model is 1 or 2 "
                             f"(friction counter-models), got {_fmt(out['F_nw'])}")
    if has("mu_ws", "mu_wk") and out["mu_wk"] > out["mu_ws"]:
        raise ParameterError(f"parameter 'mu_wk' must be <= mu_ws = {out['mu_ws']!r}, got {out['mu_wk']!r}")
    if has("t_c", "d") and not out["t_c"] < out["d"]:
        raise ParameterError(f"parameter 't_c' (circle radius) must be < d = {out['d']!r} m, "
                             f"got {out['t_c']!r}")
    return out


def _no_duplicate_keys(pairs) -> dict:
    """``json.loads`` hook: a key given twice in one object is refused (json would keep the
    last silently, and which of two values the user meant is unknowable)."""
    out = {}
    for key, value in pairs:
        if key in out:
            raise ParameterError(f"key '{key}' appears twice in one object")
        out[key] = value
    return out


@dataclass(frozen=True, eq=False)
class ParameterSet:
    """A validated, immutable set of model parameters.

    Parameters
    ----------
    values : mapping of str to float
        One value for every name in ``PARAM_NAMES`` of the generated module (SI units;
        integer-valued entries such as ``n_rollers`` are stored as floats). Stored read-only.
    n_circles : int
        ``N_c``, number of small circles; structural (sets the state length
        ``2 * (N_c + 2)``), not part of the parameter vector.
    geometry : BandGeometry
        Band geometry, used to convert band rotation and slip to stroke.

    Raises
    ------
    ParameterError
        On construction, if any value is invalid (see :func:`validate`).

    Examples
    --------
    >>> from szdyn.defaults import default_parameters
    >>> ps = default_parameters().replace(b_c=7.5e-4)
    >>> p = ps.to_array()   # float64, PARAM_NAMES order
    """

    values: Mapping[str, float]
    n_circles: int
    geometry: BandGeometry

    def __post_init__(self) -> None:
        if not isinstance(self.geometry, BandGeometry):
            raise ParameterError(f"'geometry' must be a BandGeometry, got {self.geometry!r}")
        checked = validate(self.values, self.n_circles)
        object.__setattr__(self, "values", MappingProxyType(checked))
        object.__setattr__(self, "n_circles", _check_n_circles(self.n_circles))

    # --- access ---------------------------------------------------------------------------
    def __getitem__(self, name: str) -> float:
        try:
            return self.values[name]
        except KeyError:
            raise _unknown(name, self.values) from None

    def __eq__(self, other) -> bool:
        if not isinstance(other, ParameterSet):
            return NotImplemented
        return (dict(self.values) == dict(other.values) and self.n_circles == other.n_circles
                and self.geometry == other.geometry)

    def __hash__(self) -> int:
        return hash((tuple(self.values.items()), self.n_circles, self.geometry))

    def __repr__(self) -> str:
        vals = ", ".join(f"{k}={v!r}" for k, v in self.values.items())
        return f"ParameterSet(n_circles={self.n_circles}, geometry={self.geometry!r}, {vals})"

    @property
    def interference(self) -> float:
        """How far the rollers reach into the ring of circles (m).

        ``R_w + t_r + t_c - (R_bo - d)``: positive when a roller centred on a circle (circle at
        rest) overlaps it. The model's behaviour is very sensitive to this (model-notes s. 5).
        """
        v = self.values
        return v["R_w"] + v["t_r"] + v["t_c"] - (v["R_bo"] - v["d"])

    @property
    def state_size(self) -> int:
        """Length of the state vector, ``2 * (N_c + 2) + N_AUX``."""
        from szdyn_generated.spiral_zipper import state_size

        return state_size(self.n_circles)

    def to_array(self) -> np.ndarray:
        """Parameter vector ``p``.

        Returns
        -------
        numpy.ndarray, shape (len(PARAM_NAMES),), float64
            Values in the generated module's ``PARAM_NAMES`` order. Convert once per run.
        """
        names = param_names()
        return np.array([self.values[n] for n in names], dtype=np.float64)

    def replace(self, **changes) -> "ParameterSet":
        """Return a new validated set with some values changed.

        Parameters
        ----------
        **changes
            Parameter names with new values (SI), and/or ``n_circles=`` and ``geometry=``.

        Raises
        ------
        ParameterError
            For an unknown name (suggesting the nearest valid one) or an invalid result.
        """
        values = dict(self.values)
        n_circles = changes.pop("n_circles", self.n_circles)
        geometry = changes.pop("geometry", self.geometry)
        for key, val in changes.items():
            if key not in values:
                raise _unknown(key, list(values) + ["n_circles", "geometry"])
            values[key] = val
        return ParameterSet(values=values, n_circles=n_circles, geometry=geometry)

    def default_wheel_offset(self) -> float:
        """Initial wheel angle that keeps every roller as far as possible from a circle (rad).

        Roller ``j`` sits at ``q_w + 2 pi j / N_r`` and circle ``i`` at ``2 pi (i-1) / N_c``.
        In units of the circle pitch the rollers' fractional offsets are multiples of
        ``1/m`` with ``m = N_r / gcd(N_c, N_r)``, so the best common offset is half of
        ``1/m`` pitch: ``q_w0 = pi / (N_c m)``. When ``N_c`` is a multiple of ``N_r``
        (``m = 1``) this is half a circle pitch, ``pi / N_c``, and every roller is midway
        between two circles; otherwise (e.g. thesis ``N_c = 100``, ``N_r = 8``: ``m = 2``) the
        rollers alternate a quarter pitch either side of a circle, which is as far as possible.
        """
        nr = int(self.values["n_rollers"])
        m = nr // math.gcd(self.n_circles, nr)
        return math.pi / (self.n_circles * m)

    def initial_state(self, q_w0: float | None = None) -> np.ndarray:
        """Initial state ``x0`` per docs/CONTRACT.md: everything at rest.

        Parameters
        ----------
        q_w0 : float, optional
            Initial wheel angle (rad). Default :meth:`default_wheel_offset` (half a circle
            pitch, ``pi / N_c``, when ``N_c`` is a multiple of ``n_rollers``), so the rollers
            start between circles rather than centred on one (model-notes section 5).

        Returns
        -------
        numpy.ndarray, shape (2 * (N_c + 2) + N_AUX,), float64
            ``[q_w, q_b, q_1..q_Nc, u_w, u_b, u_1..u_Nc, z_lugre]`` with ``q_w = q_w0``, all
            other angles 0 rad, all speeds 0 rad/s and auxiliary states 0.
        """
        if q_w0 is None:
            q_w0 = self.default_wheel_offset()
        q_w0 = _as_real("q_w0", q_w0)
        if not math.isfinite(q_w0):
            raise ParameterError(f"parameter 'q_w0' must be finite, got {q_w0!r}")
        x0 = np.zeros(self.state_size, dtype=np.float64)
        x0[0] = q_w0
        return x0

    # --- serialisation --------------------------------------------------------------------
    def to_dict(self) -> dict:
        """Plain, JSON-ready dict: format tag, version, ``n_circles``, geometry, values."""
        return {"format": _FORMAT, "version": _VERSION, "n_circles": self.n_circles,
                "geometry": self.geometry.to_dict(), "values": dict(self.values)}

    @classmethod
    def from_dict(cls, data: Mapping, *, missing: str = "defaults", source: str | None = None) -> "ParameterSet":
        """Build a validated set from :meth:`to_dict` output.

        Parameters
        ----------
        data : mapping
            Keys ``values`` (required), ``n_circles``, ``geometry`` (default from
            :mod:`szdyn.defaults` when absent), and optional ``format``/``version``.
        missing : {"defaults", "error"}
            What to do with names of ``PARAM_NAMES`` absent from ``values`` (e.g. parameters
            appended after the file was written): take them from :mod:`szdyn.defaults` with a
            warning naming them, or raise.
        source : str, optional
            Where ``data`` came from (a file name), for the warning.

        Raises
        ------
        ParameterError
            Naming the offending key.
        """
        from szdyn import defaults

        if not isinstance(data, Mapping):
            raise ParameterError(f"parameter data must be a mapping, got {type(data).__name__}")
        top = ("format", "version", "n_circles", "geometry", "values")
        for key in data:
            if key not in top:
                raise _unknown(key, top, what="top-level key")
        if "format" in data and data["format"] != _FORMAT:
            raise ParameterError(f"key 'format' must be {_FORMAT!r}, got {data['format']!r}")
        if "version" in data and data["version"] != _VERSION:
            raise ParameterError(f"key 'version': unsupported version {data['version']!r} "
                                 f"(this szdyn reads version {_VERSION})")
        if "values" not in data or not isinstance(data["values"], Mapping):
            raise ParameterError("key 'values' (name -> value mapping) is missing or not a mapping")
        names = param_names()
        values = dict(data["values"])
        for key in values:
            if key not in names:
                raise _unknown(key, names)
        absent = [n for n in names if n not in values]
        if absent:
            if missing == "error":
                raise ParameterError("missing value for parameter " +
                                     ", ".join(f"'{n}'" for n in absent))
            if missing != "defaults":
                raise ValueError(f"missing must be 'defaults' or 'error', got {missing!r}")
            dflt = defaults.default_values()
            for n in absent:
                if n not in dflt:
                    raise ParameterError(f"missing value for parameter '{n}' and no default")
                values[n] = dflt[n]
            warnings.warn((f"{source}: " if source else "") + "parameters not given, taken from "
                          "szdyn.defaults: " + ", ".join(absent), stacklevel=2)
        if "geometry" not in data:
            geometry = defaults.default_geometry()
        else:
            geo = data["geometry"]
            if not isinstance(geo, Mapping):
                # (a JSON null too: leaving the key out is how the default geometry is asked for)
                raise ParameterError("key 'geometry' must be a mapping of band_height, tooth_height, "
                                     "diameter and teeth_per_wrap (leave it out for the default "
                                     f"geometry), got {'null' if geo is None else type(geo).__name__}")
            fields = ("band_height", "tooth_height", "diameter", "teeth_per_wrap")
            for key in geo:
                if key not in fields:
                    raise _unknown(key, fields, what="geometry key")
            for key in fields:
                if key not in geo:
                    raise ParameterError(f"geometry key '{key}' is missing")
            geometry = BandGeometry(**{k: geo[k] for k in fields})
        n_circles = data.get("n_circles", defaults.DEFAULT_N_CIRCLES)
        return cls(values=values, n_circles=n_circles, geometry=geometry)

    def to_json(self, path) -> None:
        """Write :meth:`to_dict` as JSON, atomically (temp file in the same dir + os.replace).

        Parameters
        ----------
        path : str or os.PathLike
            Destination file; either the old content or the complete new content is there
            afterwards, never a partial file.
        """
        write_json(path, self.to_dict())

    @classmethod
    def from_json(cls, path, *, missing: str = "defaults") -> "ParameterSet":
        """Read a file written by :meth:`to_json`.

        Raises
        ------
        OSError
            If the file cannot be read.
        ParameterError
            If the content is not valid JSON or not a valid parameter set; the message starts
            with the file name and names the key.
        """
        path = Path(path)
        try:
            text = path.read_bytes().decode("utf-8")
        except UnicodeDecodeError:
            raise ParameterError(f"{path}: not UTF-8 text (a parameter JSON file was expected)") from None
        try:
            data = json.loads(text, object_pairs_hook=_no_duplicate_keys)
        except json.JSONDecodeError as exc:
            raise ParameterError(f"{path}: not valid JSON: {exc}") from exc
        except ParameterError as exc:
            raise ParameterError(f"{path}: {exc}") from None
        try:
            return cls.from_dict(data, missing=missing, source=path.name)
        except ParameterError as exc:
            raise ParameterError(f"{path}: {exc}") from exc
