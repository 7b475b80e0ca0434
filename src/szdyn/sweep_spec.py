"""Sweep specification: a TOML file -> a validated, canonical spec -> the list of cases.

The TOML file (read with :mod:`tomllib`; nothing in it is evaluated) has these tables; every
key is checked, and an unknown key is an error naming the table and suggesting the nearest
valid name. See ``examples/sweep_example.toml``.

``description`` (top level, optional string)

``[base]`` the base scenario
    ``t_end`` (s, required), ``n_circles`` (default 100).
    ``[base.params]`` parameter overrides by name (``PARAM_NAMES`` of the generated model, SI;
    ``drive_mode`` is set by the drive kind). ``[base.drive]`` ``kind`` = ``"ramp"`` (``a``,
    ``t_end``), ``"ramp_hold"`` (``a``, ``t_ramp``, ``t_hold``), ``"trapezoid"`` (``a``,
    ``omega_max``, ``t_hold``, optional ``a_down``), ``"sampled"`` (``t``, ``omega`` lists) or
    ``"torque"`` (``t``, ``torque`` lists), with the arguments of :mod:`szdyn.drive`.
    ``[base.integrator]`` ``method`` (``"dopri5"``, ``"rk4"``, ``"heun"``; default dopri5),
    ``dt`` (1e-5 s), ``rtol`` (1e-5), ``atol`` (1e-8), ``save_dt`` (1e-3 s), ``max_steps`` (1e8).

``[axes]`` a grid (Cartesian product, first axis varies slowest)
    ``name = [v1, v2, ...]`` or ``name = {start = .., stop = .., num = .., scale = "linear"|"log"}``.
    Names: a parameter name, ``n_circles``, ``t_end``, ``drive.<arg>`` (a numeric argument of
    the base drive kind; written ``drive.a = [...]`` or ``"drive.a" = [...]``) or
    ``integrator.<dt|rtol|atol|save_dt>``.

``[sampling]`` random or Latin-hypercube samples
    ``method = "lhs"|"random"``, ``n`` (samples), ``seed`` (default 0) and ``[sampling.ranges]``
    ``name = [low, high]`` or ``{low = .., high = .., scale = "linear"|"log"}`` (same names as
    axes). Integer-valued parameters are rounded. With both ``[axes]`` and ``[sampling]`` every
    grid point gets the same ``n`` samples.

``[metrics]`` summary metrics to keep (default: :data:`szdyn.metrics.DEFAULT_METRICS`)
    ``name = {kind = .., of = .., over = .., t_from = .., t_to = .., description = ..}``
    (see :mod:`szdyn.metrics`); ``include_defaults = true`` adds the default metrics.

The canonical spec (all defaults filled in, the base parameter set fully resolved, the list of
case inputs) is plain JSON data; its SHA-256 identifies the sweep, so a different spec cannot
be resumed into the same output directory. Case ids are the positions in the case list, which
depends only on the spec.
"""
from __future__ import annotations

import difflib
import hashlib
import itertools
import json
import math
import numbers
import tomllib
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from .errors import ParameterError, UserInputError
from .metrics import DEFAULT_METRICS, KINDS, RATIO_KINDS, Metric

__all__ = ["SpecError", "SweepSpec", "load_spec", "parse_spec", "DRIVE_KINDS", "FORMAT",
           "VERSION", "MAX_CASES", "spec_diff"]

FORMAT = "szdyn-sweep-spec"
VERSION = 1
MAX_CASES = 1_000_000

#: kind -> (class name in szdyn.drive, required args, optional args, list-valued args)
DRIVE_KINDS = {
    "ramp": ("Ramp", ("a", "t_end"), (), ()),
    "ramp_hold": ("RampHold", ("a", "t_ramp", "t_hold"), (), ()),
    "trapezoid": ("Trapezoid", ("a", "omega_max", "t_hold"), ("a_down",), ()),
    "sampled": ("Sampled", ("t", "omega"), (), ("t", "omega")),
    "torque": ("Torque", ("t", "torque"), (), ("t", "torque")),
}
METHODS = ("dopri5", "rk4", "heun")
INTEGRATOR_DEFAULTS = {"method": "dopri5", "dt": 1e-5, "rtol": 1e-5, "atol": 1e-8,
                       "save_dt": 1e-3, "max_steps": 10**8}
SWEEPABLE_INTEGRATOR = ("dt", "rtol", "atol", "save_dt")
SAMPLING_METHODS = ("lhs", "random")

TOP_KEYS = ("description", "base", "axes", "sampling", "metrics")
BASE_KEYS = ("t_end", "n_circles", "params", "drive", "integrator")
RANGE_KEYS = ("start", "stop", "num", "scale")
SAMPLE_RANGE_KEYS = ("low", "high", "scale")
SAMPLING_KEYS = ("method", "n", "seed", "ranges")
METRIC_KEYS = ("kind", "of", "over", "t_from", "t_to", "description")


class SpecError(UserInputError):
    """A mistake in a sweep spec; the message names the TOML table and key."""


def _suggest(name, valid) -> str:
    valid = list(valid)
    lower = {v.lower(): v for v in valid}
    if name.lower() in lower and lower[name.lower()] != name:
        return f" (did you mean '{lower[name.lower()]}'?)"
    close = difflib.get_close_matches(name, valid, n=1, cutoff=0.5)
    return f" (did you mean '{close[0]}'?)" if close else ""


def _unknown(section: str, key: str, valid, what="key") -> SpecError:
    valid = list(valid)
    return SpecError(f"[{section}] unknown {what} '{key}'{_suggest(key, valid)}; valid: "
                     + ", ".join(valid))


def _check_keys(section: str, table, valid) -> None:
    if not isinstance(table, dict):
        raise SpecError(f"[{section}] must be a table, got {_type(table)}")
    for key in table:
        if key not in valid:
            raise _unknown(section, key, valid)


def _type(v) -> str:
    return {bool: "a boolean", str: "a string", list: "an array", dict: "a table",
            int: "an integer", float: "a number"}.get(type(v), type(v).__name__)


def _integrator_value(key: str, where: str, v) -> float:
    """A step size or tolerance: > 0, and a relative tolerance below 1 (as ``--rtol``)."""
    v = _number(where, v, positive=True)
    if key == "rtol" and not v < 1:
        raise SpecError(f"{where} must be a relative tolerance below 1 (e.g. 1e-5), got {v!r}")
    return v


def _number(where: str, v, *, positive=False, nonnegative=False, integer=False) -> float:
    if isinstance(v, bool) or not isinstance(v, numbers.Real):
        raise SpecError(f"{where} must be a number, got {_type(v)} {v!r}")
    try:
        v = float(v)
    except OverflowError:       # a TOML integer beyond a float's range
        raise SpecError(f"{where} must be finite, got an integer too large for a float") from None
    if not math.isfinite(v):
        raise SpecError(f"{where} must be finite, got {v!r}")
    if positive and not v > 0:
        raise SpecError(f"{where} must be > 0, got {v!r}")
    if nonnegative and not v >= 0:
        raise SpecError(f"{where} must be >= 0, got {v!r}")
    if integer and v != int(v):
        raise SpecError(f"{where} must be a whole number, got {v!r}")
    return v


def _string(where: str, v, choices=None) -> str:
    if not isinstance(v, str):
        raise SpecError(f"{where} must be a string, got {_type(v)} {v!r}")
    if choices is not None and v not in choices:
        raise SpecError(f"{where} must be one of {', '.join(repr(c) for c in choices)}, got "
                        f"{v!r}{_suggest(v, choices)}")
    return v


def _canonical_json(obj) -> bytes:
    return json.dumps(obj, sort_keys=True, separators=(",", ":"), allow_nan=False).encode()


def spec_diff(a, b, prefix="", limit=6) -> list[str]:
    """Paths (``base.params.k_c``, ``cases[3]``...) where two canonical specs differ."""
    out: list[str] = []

    def walk(x, y, path):
        if len(out) >= limit:
            return
        if isinstance(x, dict) and isinstance(y, dict):
            for k in sorted(set(x) | set(y), key=str):
                walk(x.get(k, "<absent>"), y.get(k, "<absent>"), f"{path}.{k}" if path else str(k))
        elif isinstance(x, list) and isinstance(y, list) and len(x) == len(y):
            for i, (u, v) in enumerate(zip(x, y)):
                walk(u, v, f"{path}[{i}]")
        elif x != y:
            out.append(path or "<root>")

    walk(a, b, prefix)
    return out


# --------------------------------------------------------------------------- the spec object
@dataclass
class SweepSpec:
    """A validated sweep spec.

    Attributes
    ----------
    canonical : dict
        JSON-ready canonical form (what the hash covers).
    hash : str
        SHA-256 hex digest of the canonical JSON.
    cases : list of dict
        Per case id (list position), the swept inputs: variable name -> value.
    variables : list of str
        Names of the swept variables, axes first (grid order), then sampled ones.
    metrics : list of Metric
    """

    canonical: dict
    hash: str
    cases: list
    variables: list
    metrics: list
    source: str = ""
    text: str = field(default="", repr=False)

    @property
    def axes(self) -> list:
        return self.canonical["axes"]

    @property
    def sampling(self):
        return self.canonical["sampling"]

    def case_settings(self, inputs: dict) -> dict:
        """Resolved settings of one case: ``t_end``, ``drive.<arg>``, ``integrator.<key>``."""
        base = self.canonical["base"]
        s = {"t_end": base["t_end"]}
        s.update({f"drive.{k}": v for k, v in base["drive"].items() if k != "kind"})
        s.update({f"integrator.{k}": v for k, v in base["integrator"].items()})
        s.update({k: v for k, v in inputs.items() if k == "t_end" or "." in k})
        return s

    def task(self, case_id: int) -> dict:
        """Everything a worker needs to run one case (plain, picklable data)."""
        base = self.canonical["base"]
        return {"case_id": case_id, "base_params": base["params"], "drive": base["drive"],
                "t_end": base["t_end"], "integrator": base["integrator"],
                "inputs": dict(self.cases[case_id]),
                "metrics": [m.to_dict() for m in self.metrics]}


def load_spec(path) -> SweepSpec:
    """Read and validate a sweep spec TOML file (errors are :class:`SpecError`)."""
    path = Path(path)
    try:
        raw = path.read_bytes()
    except OSError as exc:
        raise SpecError(f"{path}: cannot read sweep spec: {exc.strerror or exc}") from None
    try:
        # a byte-order mark (editors on Windows) is accepted, as in a manifest
        text = raw.removeprefix(b"\xef\xbb\xbf").decode("utf-8")
        data = tomllib.loads(text)
    except (UnicodeDecodeError, tomllib.TOMLDecodeError) as exc:
        raise SpecError(f"{path}: not valid TOML: {exc}") from None
    try:
        spec = parse_spec(data)
    except SpecError as exc:
        raise SpecError(f"{path}: {exc}") from None
    spec.source = str(path)
    spec.text = text
    return spec


def parse_spec(data: dict) -> SweepSpec:
    """Validate a parsed TOML document (dict) and build the canonical spec and case list."""
    from .defaults import default_parameters
    from .params import param_names, validate

    _check_keys("top level", data, TOP_KEYS)
    description = data.get("description", "")
    if not isinstance(description, str):
        raise SpecError(f"[top level] key 'description' must be a string, got {_type(description)}")
    if "base" not in data:
        raise SpecError("table [base] is missing (it needs at least t_end and [base.drive])")
    base_in = data["base"]
    _check_keys("base", base_in, BASE_KEYS)
    names = [n for n in param_names() if n != "drive_mode"]

    # --- base scenario ------------------------------------------------------------------
    if "t_end" not in base_in:
        raise SpecError("[base] key 't_end' (simulated time in s) is missing")
    t_end = _number("[base] key 't_end'", base_in["t_end"], positive=True)
    n_circles = None
    if "n_circles" in base_in:
        n_circles = int(_number("[base] key 'n_circles'", base_in["n_circles"], positive=True,
                                integer=True))
    params_in = base_in.get("params", {})
    if not isinstance(params_in, dict):
        raise SpecError(f"[base.params] must be a table, got {_type(params_in)}")
    overrides = {}
    for key, v in params_in.items():
        if key == "drive_mode":
            raise SpecError("[base.params] key 'drive_mode' is set by [base.drive] kind "
                            "(torque -> 1, otherwise 0); remove it")
        if key == "n_circles":
            raise SpecError("[base.params] key 'n_circles' belongs in [base] (n_circles = ...)")
        if key not in names:
            raise _unknown("base.params", key, names, what="parameter")
        overrides[key] = _number(f"[base.params] key '{key}'", v)
    try:
        ps = default_parameters(n_circles) if n_circles is not None else default_parameters()
        ps = ps.replace(**overrides)
    except ParameterError as exc:
        raise SpecError(f"[base.params] {exc}") from None

    drive_in = base_in.get("drive")
    if drive_in is None:
        raise SpecError("table [base.drive] is missing (kind = \"ramp_hold\", a = ..., ...)")
    if not isinstance(drive_in, dict):
        raise SpecError(f"[base.drive] must be a table, got {_type(drive_in)}")
    if "kind" not in drive_in:
        raise SpecError("[base.drive] key 'kind' is missing; one of " + ", ".join(DRIVE_KINDS))
    kind = _string("[base.drive] key 'kind'", drive_in["kind"], tuple(DRIVE_KINDS))
    _cls, req, opt, listy = DRIVE_KINDS[kind]
    for key in drive_in:
        if key != "kind" and key not in req + opt:
            raise SpecError(f"[base.drive] unknown key '{key}' for kind '{kind}'"
                            f"{_suggest(key, req + opt)}; valid: kind, " + ", ".join(req + opt))
    drive = {"kind": kind}
    for key in req:
        if key not in drive_in:
            raise SpecError(f"[base.drive] key '{key}' is missing (kind '{kind}' needs "
                            + ", ".join(req) + ")")
    for key in req + opt:
        if key not in drive_in:
            continue
        where = f"[base.drive] key '{key}'"
        if key in listy:
            v = drive_in[key]
            if not isinstance(v, list):
                raise SpecError(f"{where} must be an array of numbers, got {_type(v)}")
            drive[key] = [_number(f"{where}[{i}]", x) for i, x in enumerate(v)]
        else:
            drive[key] = _number(where, drive_in[key])
    _build_drive_checked(drive, "[base.drive]")

    integ_in = base_in.get("integrator", {})
    _check_keys("base.integrator", integ_in, tuple(INTEGRATOR_DEFAULTS))
    integrator = dict(INTEGRATOR_DEFAULTS)
    for key, v in integ_in.items():
        where = f"[base.integrator] key '{key}'"
        if key == "method":
            integrator[key] = _string(where, v, METHODS)
        elif key == "max_steps":
            integrator[key] = int(_number(where, v, positive=True, integer=True))
        else:
            integrator[key] = _integrator_value(key, where, v)

    base = {"t_end": t_end, "n_circles": ps.n_circles, "overrides": overrides,
            "params": ps.to_dict(), "drive": drive, "integrator": integrator}

    # --- variables ----------------------------------------------------------------------
    scalar_drive = [k for k in req + opt if k not in listy]
    valid_vars = (names + ["n_circles", "t_end"] + [f"drive.{k}" for k in scalar_drive]
                  + [f"integrator.{k}" for k in SWEEPABLE_INTEGRATOR])

    def check_var(section, name):
        if name not in valid_vars:
            if name.startswith("drive.") and name[6:] in ("kind",) + listy:
                raise SpecError(f"[{section}] '{name}' cannot be swept (only numeric arguments "
                                f"of drive kind '{kind}': {', '.join(scalar_drive)})")
            raise _unknown(section, name, valid_vars, what="name")

    def check_value(section, name, v):
        """Validate one value of a swept variable on the base case; return it canonical."""
        where = f"[{section}] '{name}'"
        if name in ("n_circles",) or _is_integer_param(name):
            v = _number(f"{where} value", v, integer=True)
        if name == "n_circles":
            v = int(v)
        try:
            if name in names:  # its own bound only; combinations are checked per case
                validate({name: v}, ps.n_circles, names=(name,))
            elif name == "n_circles":
                validate({}, v, names=())
            elif name == "t_end":
                _number(f"{where} value", v, positive=True)
            elif name.startswith("drive."):
                _build_drive_checked({**drive, name[6:]: v}, where)
            elif name.startswith("integrator."):
                _integrator_value(name[len("integrator."):], f"{where} value", v)
        except ParameterError as exc:
            raise SpecError(f"{where}: {exc}") from None
        return v

    axes_in = data.get("axes", {})
    if not isinstance(axes_in, dict):
        raise SpecError(f"[axes] must be a table, got {_type(axes_in)}")
    axes = []
    for name, spec in _flatten_vars(axes_in, RANGE_KEYS):
        check_var("axes", name)
        values, scale = _axis_values(name, spec)
        values = [check_value("axes", name, v) for v in values]
        if len(set(values)) != len(values):
            dup = next(v for v in values if values.count(v) > 1)
            raise SpecError(f"[axes] '{name}' has the value {dup!r} more than once")
        axes.append({"name": name, "values": values, "scale": scale})

    sampling = None
    if "sampling" in data:
        sampling = _parse_sampling(data["sampling"], check_var)
        for r in sampling["ranges"]:
            for v in (r["low"], r["high"]):
                check_value("sampling.ranges", r["name"], v)
            if r["name"] in [a["name"] for a in axes]:
                raise SpecError(f"[sampling.ranges] '{r['name']}' is already an axis in [axes]; "
                                "sweep each variable in one place only")

    metrics = _parse_metrics(data.get("metrics"), kind, scalar_drive)

    # --- cases --------------------------------------------------------------------------
    n_grid = math.prod(len(a["values"]) for a in axes)
    n_samp = sampling["n"] if sampling else 1
    if n_grid * n_samp > MAX_CASES:
        raise SpecError(f"[axes]/[sampling] give {n_grid * n_samp} cases, more than the limit "
                        f"{MAX_CASES}")
    samples = _draw_samples(sampling) if sampling else [{}]
    variables = [a["name"] for a in axes] + ([r["name"] for r in sampling["ranges"]]
                                             if sampling else [])
    for x in metrics:
        if x.name in variables:
            raise SpecError(f"[metrics] name '{x.name}' is also a swept variable; rename it")
    cases = []
    for point in itertools.product(*[a["values"] for a in axes]):
        g = dict(zip([a["name"] for a in axes], point))
        for s in samples:
            cases.append({**g, **s})
    _check_case_sampling(integrator, t_end, ps.n_circles, cases)

    canonical = {"format": FORMAT, "version": VERSION, "description": description,
                 "base": base, "axes": axes, "sampling": sampling,
                 "metrics": [m.to_dict() for m in metrics], "cases": cases}
    digest = hashlib.sha256(_canonical_json(canonical)).hexdigest()
    return SweepSpec(canonical=canonical, hash=digest, cases=cases, variables=variables,
                     metrics=list(metrics))


# --------------------------------------------------------------------------- helpers
def _check_case_sampling(integrator: dict, t_end: float, n_circles: int, cases: list) -> None:
    """Refuse, before any case runs, a save interval that is not a multiple of a fixed step,
    leaves a run with too few samples or makes its output too large
    (:func:`szdyn.integrators.check_sampling`): such a case would fail every time it is
    retried, give metrics from a handful of points, or end in a failed allocation."""
    from szdyn_generated.spiral_zipper import state_size

    from .integrators import check_sampling

    keys = ("integrator.dt", "integrator.save_dt", "t_end", "n_circles")
    swept = [k for k in keys if any(k in c for c in cases)]
    seen = set()
    for k, c in enumerate(cases):
        combo = (c.get("integrator.dt", integrator["dt"]), c.get("integrator.save_dt", integrator["save_dt"]),
                 c.get("t_end", t_end), c.get("n_circles", n_circles))
        if combo in seen:
            continue
        seen.add(combo)
        dt, save_dt, span, nc = combo
        try:
            check_sampling(integrator["method"], dt, save_dt, span, n_states=state_size(int(nc)))
        except ValueError as exc:
            where = (f"case {k} ({', '.join(f'{n} = {c[n]!r}' for n in swept if n in c)})" if swept
                     else "[base]")
            raise SpecError(f"{where}: {exc}; see [base.integrator] (method "
                            f"{integrator['method']!r}) and [base] t_end") from None


def _is_integer_param(name: str) -> bool:
    try:
        from szdyn_generated.spiral_zipper import PARAM_BOUNDS
    except ImportError:  # pragma: no cover
        return False
    kind = PARAM_BOUNDS.get(name, "")
    return kind == "positive integer" or kind.startswith("one of ")


def build_drive(drive: dict):
    """Drive profile object from a canonical drive dict ``{"kind": .., args..}``."""
    from . import drive as drive_mod

    cls_name, *_ = DRIVE_KINDS[drive["kind"]]
    return getattr(drive_mod, cls_name)(**{k: v for k, v in drive.items() if k != "kind"})


def _build_drive_checked(drive: dict, where: str):
    try:
        return build_drive(drive)
    except (ValueError, TypeError) as exc:
        raise SpecError(f"{where}: {exc}") from None


def _flatten_vars(table: dict, range_keys):
    """Yield ``(name, spec)`` from an [axes]-like table; ``drive = {a = [...]}`` -> ``drive.a``."""
    for key, v in table.items():
        if key in ("drive", "integrator") and isinstance(v, dict) and not (set(v) & set(range_keys)):
            for sub, w in v.items():
                yield f"{key}.{sub}", w
        else:
            yield key, v


def _axis_values(name: str, spec):
    where = f"[axes] '{name}'"
    if isinstance(spec, list):
        if not spec:
            raise SpecError(f"{where} is an empty array; give at least one value")
        return [_number(f"{where}[{i}]", v) for i, v in enumerate(spec)], "linear"
    if isinstance(spec, dict):
        for key in spec:
            if key not in RANGE_KEYS:
                raise SpecError(f"{where}: unknown key '{key}'{_suggest(key, RANGE_KEYS)}; "
                                "valid: " + ", ".join(RANGE_KEYS))
        for key in ("start", "stop", "num"):
            if key not in spec:
                raise SpecError(f"{where}: key '{key}' is missing (a range needs start, stop, num)")
        start = _number(f"{where} key 'start'", spec["start"])
        stop = _number(f"{where} key 'stop'", spec["stop"])
        num = int(_number(f"{where} key 'num'", spec["num"], positive=True, integer=True))
        if num > MAX_CASES:   # before the values are made: a typo of 1e9 would allocate 8 GB
            raise SpecError(f"{where}: num = {num} values, more than the limit of {MAX_CASES} cases")
        scale = _string(f"{where} key 'scale'", spec.get("scale", "linear"), ("linear", "log"))
        if scale == "log":
            if not (start > 0 and stop > 0):
                raise SpecError(f"{where}: scale 'log' needs start > 0 and stop > 0, got "
                                f"{start!r}, {stop!r}")
            values = np.geomspace(start, stop, num)
        else:
            values = np.linspace(start, stop, num)
        values = [float(v) for v in values]
        if num >= 1:  # exact end points (geomspace/linspace may round them)
            values[0] = start
            values[-1] = stop if num > 1 else start
        return values, scale
    raise SpecError(f"{where} must be an array of values or a table {{start, stop, num, scale}}, "
                    f"got {_type(spec)}")


def _parse_sampling(s, check_var) -> dict:
    _check_keys("sampling", s, SAMPLING_KEYS)
    if "method" not in s:
        raise SpecError("[sampling] key 'method' is missing; one of " + ", ".join(SAMPLING_METHODS))
    method = _string("[sampling] key 'method'", s["method"], SAMPLING_METHODS)
    if "n" not in s:
        raise SpecError("[sampling] key 'n' (number of samples) is missing")
    n = int(_number("[sampling] key 'n'", s["n"], positive=True, integer=True))
    seed = int(_number("[sampling] key 'seed'", s.get("seed", 0), nonnegative=True, integer=True))
    ranges_in = s.get("ranges")
    if not isinstance(ranges_in, dict) or not ranges_in:
        raise SpecError("[sampling.ranges] is missing or empty: give name = [low, high] for "
                        "each sampled variable")
    ranges = []
    for name, r in _flatten_vars(ranges_in, SAMPLE_RANGE_KEYS):
        check_var("sampling.ranges", name)
        where = f"[sampling.ranges] '{name}'"
        scale = "linear"
        if isinstance(r, list):
            if len(r) != 2:
                raise SpecError(f"{where} must be [low, high], got {len(r)} values")
            low, high = (_number(f"{where}[{i}]", v) for i, v in enumerate(r))
        elif isinstance(r, dict):
            for key in r:
                if key not in SAMPLE_RANGE_KEYS:
                    raise SpecError(f"{where}: unknown key '{key}'"
                                    f"{_suggest(key, SAMPLE_RANGE_KEYS)}; valid: "
                                    + ", ".join(SAMPLE_RANGE_KEYS))
            for key in ("low", "high"):
                if key not in r:
                    raise SpecError(f"{where}: key '{key}' is missing")
            low = _number(f"{where} key 'low'", r["low"])
            high = _number(f"{where} key 'high'", r["high"])
            scale = _string(f"{where} key 'scale'", r.get("scale", "linear"), ("linear", "log"))
        else:
            raise SpecError(f"{where} must be [low, high] or {{low, high, scale}}, got {_type(r)}")
        if not low < high:
            raise SpecError(f"{where}: low must be < high, got {low!r}, {high!r}")
        if scale == "log" and not low > 0:
            raise SpecError(f"{where}: scale 'log' needs low > 0, got {low!r}")
        ranges.append({"name": name, "low": low, "high": high, "scale": scale,
                       "integer": name == "n_circles" or _is_integer_param(name)})
    return {"method": method, "n": n, "seed": seed, "ranges": ranges}


def _draw_samples(sampling) -> list[dict]:
    """Deterministic samples (depend only on the sampling spec)."""
    d = len(sampling["ranges"])
    n = sampling["n"]
    rng = np.random.default_rng(sampling["seed"])
    if sampling["method"] == "lhs":
        from scipy.stats import qmc

        u = qmc.LatinHypercube(d=d, rng=rng).random(n)
    else:
        u = rng.random((n, d))
    out = []
    for row in u:
        s = {}
        for r, x in zip(sampling["ranges"], row):
            if r["scale"] == "log":
                v = math.exp(math.log(r["low"]) + float(x) * (math.log(r["high"]) - math.log(r["low"])))
            else:
                v = r["low"] + float(x) * (r["high"] - r["low"])
            if r["integer"]:
                v = min(max(round(v), math.ceil(r["low"])), math.floor(r["high"]))
                v = int(v) if r["name"] == "n_circles" else float(v)
            s[r["name"]] = v
        out.append(s)
    return out


def _parse_metrics(m, drive_kind, scalar_drive) -> list[Metric]:
    from .simulate import OUTPUT_UNITS

    if m is None:
        return list(DEFAULT_METRICS)
    if not isinstance(m, dict):
        raise SpecError(f"[metrics] must be a table, got {_type(m)}")
    quantities = [q for q in OUTPUT_UNITS if q != "t"]
    refs = ["t_end"] + [f"drive.{k}" for k in scalar_drive]
    out = []
    include_defaults = False
    for name, d in m.items():
        if name == "include_defaults":
            if not isinstance(d, bool):
                raise SpecError(f"[metrics] key 'include_defaults' must be true or false, got {d!r}")
            include_defaults = d
            continue
        sec = f"metrics.{name}"
        if not isinstance(d, dict):
            raise SpecError(f"[metrics] '{name}' must be a table {{kind = .., of = ..}}, got "
                            f"{_type(d)}")
        _check_keys(sec, d, METRIC_KEYS)
        if not name.isidentifier():
            raise SpecError(f"[metrics] name '{name}' must be letters, digits and '_'")
        for key in ("kind", "of"):
            if key not in d:
                raise SpecError(f"[{sec}] key '{key}' is missing")
        kind = _string(f"[{sec}] key 'kind'", d["kind"], KINDS)
        of = _string(f"[{sec}] key 'of'", d["of"], quantities)
        over = None
        if kind in RATIO_KINDS:
            if "over" not in d:
                raise SpecError(f"[{sec}] key 'over' (denominator) is missing for kind '{kind}'")
            over = _string(f"[{sec}] key 'over'", d["over"], quantities)
        elif "over" in d:
            raise SpecError(f"[{sec}] key 'over' is only used by kinds "
                            + ", ".join(RATIO_KINDS))
        times = {}
        for key in ("t_from", "t_to"):
            v = d.get(key)
            if v is None:
                times[key] = None
            elif isinstance(v, str):
                if v not in refs:
                    raise SpecError(f"[{sec}] key '{key}': unknown setting '{v}'"
                                    f"{_suggest(v, refs)}; give seconds or one of "
                                    + ", ".join(refs))
                times[key] = v
            else:
                times[key] = _number(f"[{sec}] key '{key}'", v, nonnegative=True)
        if (isinstance(times["t_from"], float) and isinstance(times["t_to"], float)
                and not times["t_from"] < times["t_to"]):
            raise SpecError(f"[{sec}] t_from must be < t_to, got {times['t_from']!r}, "
                            f"{times['t_to']!r}")
        desc = d.get("description", "")
        if not isinstance(desc, str):
            raise SpecError(f"[{sec}] key 'description' must be a string")
        out.append(Metric(name, kind, of, over, times["t_from"], times["t_to"], desc))
    if include_defaults:
        mine = {x.name for x in out}
        out = [x for x in DEFAULT_METRICS if x.name not in mine] + out
    if not out:
        raise SpecError("[metrics] defines no metric")
    reserved = {"case_id", "status", "error", "n_steps", "n_rejected"}
    for x in out:
        if x.name in reserved:
            raise SpecError(f"[metrics] name '{x.name}' is reserved for a table column")
    return out
