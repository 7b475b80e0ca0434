"""Measured (or synthetic) encoder recordings of the Spiral Zipper, and features to compare.

File format
-----------
A plain CSV file with one header row. Column names (case-sensitive, surrounding blanks
ignored):

========== ======== ========= ==================================================
column     unit     required  meaning
========== ======== ========= ==================================================
``t``      s        yes       sample time, strictly increasing (see duplicates)
``theta_w`` rad     yes       wheel (or motor) encoder angle, cumulative
``theta_b`` rad     yes       band encoder angle, cumulative
``omega_ref`` rad/s no        wheel speed set-point
``current`` A       no        motor current
========== ======== ========= ==================================================

Other columns are accepted, ignored and listed in :attr:`Recording.extra_columns`. Blank
lines and lines whose first non-blank character is ``#`` are skipped (logger comments).
The file is parsed with :mod:`csv` (values go through :func:`float` only, never ``eval``).

What is accepted and what is rejected
--------------------------------------
Real logs are noisy, quantized to encoder counts, unevenly sampled and may miss rows; all
of that is accepted as is (no data are altered). Broken input raises :class:`RecordingError`
(a :class:`~szdyn.errors.UserInputError`) whose message names the file, the line (1-based,
as an editor shows it) and the column, e.g.::

    ramp1.csv, line 17, column 'theta_b': expected a number, got 'abc'
    ramp1.csv, line 17, column 't': time goes backwards (0.52 s after 0.53 s on line 16)
    ramp1.csv, line 1: missing required column 'theta_b' (found: t, theta_w)
    ramp1.csv: empty file (no data rows)

Rejected: unreadable or non-UTF-8 file, no header, missing required column (with a hint when
the file uses another delimiter than the comma), repeated column name, a row with too few or too
many fields, an empty cell, a non-number (a decimal number as loggers write it: no ``1_000``, no
hex), NaN or infinity, time going backwards, fewer than two data rows, and two things no working
logger writes: a time step longer than both 10 s and 1000 median sample intervals (a mistyped
time or a logger restart; :data:`GAP_FACTOR`, :data:`GAP_MIN_S`), and an angle step implying
more than 10^4 rad/s over the step or the median interval, whichever is longer (a corrupted
value or an encoder glitch; :data:`MAX_SPEED`). Also rejected: angles in degrees, told by a travel
about 180/pi times one it cannot exceed (the band's over the wheel's, the wheel's over the one
``omega_ref`` commands; :data:`DEGREE_RATIO`). Not told: every column in degrees (``omega_ref`` in
deg/s too), both angles in degrees without ``omega_ref``, a wheel alone in degrees (it looks like
a slipping band) or a set-point alone in deg/s (it looks like a stalled drive).

Duplicate timestamps (decision): a row that repeats the previous row *exactly* (same ``t``
and same values in every used column) is a logger re-send; it is dropped and a note is kept
in :attr:`Recording.notes`. A repeated ``t`` with different values is rejected as "time not
increasing", because no order of the two samples can be trusted.

Derived signals
---------------
:func:`speeds` differentiates the quantized angles by local polynomial least squares
(Savitzky-Golay, :func:`scipy.signal.savgol_filter` with ``deriv=1``) on a uniform grid to
which the angles are first linearly interpolated (:func:`resample_uniform`). Angles, not
speeds, are interpolated, so dropped rows and jitter cost only resolution, not bias.

The impact model's fine-scale bumps (a roller hitting a circle) are not reproducible sample by
sample between model and test rig. :func:`features` therefore computes quantities that are:

* ``rel_speed``: relative speed ``omega_w - omega_b`` smoothed over ``window_s`` (default
  0.1 s, several impacts), on a uniform grid;
* ``slip_per_rev``: slip ``Delta theta_w - Delta theta_b`` (rad) accumulated over each complete
  revolution of the wheel angle, with the revolution's mean wheel speed;
* ``slip_vs_speed``: relative speed and slip ratio averaged in bins of (smoothed) wheel speed;
* ``stroke``: column extension ``P_B (theta_b - theta_b0) / (2 pi)`` and stroke lost to slip
  ``P_B ((theta_w - theta_w0) - (theta_b - theta_b0)) / (2 pi)`` (m), needing the band pitch.

:func:`compare_features` reduces two feature sets (measured and simulated) to named scalar
discrepancies, each with a sentence saying what was compared.
"""
from __future__ import annotations

import csv
import math
import re
from dataclasses import dataclass, field
from pathlib import Path
from typing import Mapping

import numpy as np

from szdyn.errors import UserInputError

__all__ = [
    "REQUIRED_COLUMNS", "OPTIONAL_COLUMNS", "COLUMN_UNITS", "RecordingError", "Recording",
    "read_recording", "resample_uniform", "speeds", "smoothed_current", "relative_speed", "slip_per_revolution",
    "slip_vs_speed", "stroke", "features", "compare_features", "speed_noise_std",
]

REQUIRED_COLUMNS = ("t", "theta_w", "theta_b")
OPTIONAL_COLUMNS = ("omega_ref", "current")
COLUMN_UNITS = {"t": "s", "theta_w": "rad", "theta_b": "rad", "omega_ref": "rad/s",
                "current": "A"}


class RecordingError(UserInputError):
    """A recording file is broken.

    The message starts with the file name, then the line and column where known. The parts
    are also available as attributes ``path`` (str or None), ``line`` (int or None, 1-based)
    and ``column`` (str or None).
    """

    def __init__(self, message, *, path=None, line=None, column=None):
        where = []
        if path is not None:
            where.append(Path(path).name)
        if line is not None:
            where.append(f"line {line}")
        if column is not None:
            where.append(f"column '{column}'")
        full = (", ".join(where) + ": " + message) if where else message
        super().__init__(full)
        self.path = None if path is None else str(path)
        self.line = line
        self.column = column
        self.reason = message


@dataclass
class Recording:
    """One recording: time, wheel and band encoder angles, optional set-point and current.

    Attributes
    ----------
    name : str
        Short name (the file name for a file).
    t : ndarray, shape (n,)
        Sample times in s, strictly increasing, n >= 2; sampling may be uneven.
    theta_w : ndarray, shape (n,)
        Wheel (or motor) encoder angle in rad, cumulative (not wrapped).
    theta_b : ndarray, shape (n,)
        Band encoder angle in rad, cumulative.
    omega_ref : ndarray, shape (n,), or None
        Wheel speed set-point in rad/s.
    current : ndarray, shape (n,), or None
        Motor current in A.
    conditions : dict
        Experimental conditions (e.g. ``load_kg``, ``n_circles``, ``note``), usually from the
        manifest (:mod:`szdyn.manifest`).
    source : Path or None
        File the recording was read from.
    extra_columns : tuple of str
        Columns present in the file but not used.
    notes : list of str
        What the reader did that the user should know (dropped duplicate rows, ...).
    meta : dict
        Free provenance (e.g. the sensor model and seed of a synthetic recording).
    """

    name: str
    t: np.ndarray
    theta_w: np.ndarray
    theta_b: np.ndarray
    omega_ref: np.ndarray | None = None
    current: np.ndarray | None = None
    conditions: dict = field(default_factory=dict)
    source: Path | None = None
    extra_columns: tuple = ()
    notes: list = field(default_factory=list)
    meta: dict = field(default_factory=dict)

    def __post_init__(self):
        self.t = np.asarray(self.t, dtype=float)
        n = self.t.shape[0]
        for nm in ("theta_w", "theta_b", "omega_ref", "current"):
            v = getattr(self, nm)
            if v is None:
                continue
            v = np.asarray(v, dtype=float)
            if v.shape != (n,):
                raise RecordingError(f"column '{nm}' has shape {v.shape}, expected ({n},)",
                                     path=self.source)
            setattr(self, nm, v)
        if self.t.ndim != 1 or n < 2:
            raise RecordingError(f"need at least 2 samples, got {n}", path=self.source)
        if not np.all(np.diff(self.t) > 0):
            raise RecordingError("time is not strictly increasing", path=self.source)

    def __len__(self) -> int:
        return int(self.t.shape[0])

    @property
    def duration(self) -> float:
        """``t[-1] - t[0]`` in s."""
        return float(self.t[-1] - self.t[0])

    def columns(self) -> dict:
        """The data as ``{column name: ndarray (n,)}``, optional columns only when present."""
        out = {"t": self.t, "theta_w": self.theta_w, "theta_b": self.theta_b}
        if self.omega_ref is not None:
            out["omega_ref"] = self.omega_ref
        if self.current is not None:
            out["current"] = self.current
        return out

    def sampling(self, gap_factor: float = 3.0) -> dict:
        """Sampling statistics.

        Returns
        -------
        dict
            ``median_dt``, ``min_dt``, ``max_dt`` (s), ``rate_hz`` (1/median_dt), ``n_gaps``
            (intervals longer than ``gap_factor * median_dt``) and ``gap_time`` (s, their total
            length).
        """
        dt = np.diff(self.t)
        med = float(np.median(dt))
        gaps = dt > gap_factor * med
        return {"median_dt": med, "min_dt": float(dt.min()), "max_dt": float(dt.max()),
                "rate_hz": 1.0 / med, "n_gaps": int(gaps.sum()), "gap_time": float(dt[gaps].sum())}


# --------------------------------------------------------------------------- reader
#: a decimal number as loggers write it. Python's float() also takes '1_0' (as 10) and digits of
#: other scripts ('١٢'), which no logger writes: a cell like that is a typo, not a value
_NUMBER = re.compile(r"[+-]?(\d+\.?\d*|\.\d+)([eE][+-]?\d+)?", re.ASCII)
_NON_FINITE = re.compile(r"[+-]?(nan|inf|infinity)", re.IGNORECASE)
#: largest angular speed a recording may imply between two samples (rad/s), about 95,000 rpm:
#: an order above any motor of such a rig (the thesis's wheel turns at a few rad/s). A larger
#: jump is a corrupted value or an encoder glitch, which would wreck every fit downstream
MAX_SPEED = 1e4
#: a time step longer than both this many median sample intervals and GAP_MIN_S is refused: a
#: mistyped time or a logger restart (the model would be run over the whole gap); dropped rows
#: make gaps of a few intervals, and a logger that writes only on change a standstill of a few
#: seconds, both accepted
GAP_FACTOR = 1000.0
GAP_MIN_S = 10.0
#: ratios of two travels that say "degrees where radians were meant" (180/pi = 57.3, with room
#: for slip and tracking error): checked only for a travel over one it cannot exceed, and only
#: when both travels exceed UNITS_MIN_TRAVEL (rad), so that encoder noise cannot trigger it
DEGREE_RATIO = (20.0, 110.0)
UNITS_MIN_TRAVEL = 0.5
_TRAVEL = {"theta_w": "theta_w's travel", "theta_b": "theta_b's travel",
           "omega_ref": "the travel omega_ref commands"}
_DELIMITERS = {";": "semicolon", "\t": "tab", "|": "vertical bar"}


def _parse_number(text: str, path, line: int, column: str) -> float:
    s = text.strip()
    if s == "":
        raise RecordingError("empty cell (expected a number)", path=path, line=line, column=column)
    if _NON_FINITE.fullmatch(s):
        raise RecordingError(f"non-finite value {s!r} (NaN or infinity)", path=path, line=line,
                             column=column)
    if not _NUMBER.fullmatch(s):
        raise RecordingError(f"expected a number, got {s!r}", path=path, line=line,
                             column=column)
    v = float(s)
    if not math.isfinite(v):
        raise RecordingError(f"non-finite value {s!r} (NaN or infinity)", path=path, line=line,
                             column=column)
    return v


def read_recording(path, conditions: Mapping | None = None, *, name: str | None = None) -> Recording:
    """Read a recording CSV file (format in the module docstring).

    Parameters
    ----------
    path : str or Path
        CSV file with a header row and columns ``t, theta_w, theta_b`` (+ optional
        ``omega_ref``, ``current``, + ignored extras).
    conditions : mapping, optional
        Experimental conditions to attach (copied into :attr:`Recording.conditions`).
    name : str, optional
        Name of the recording; default the file name.

    Returns
    -------
    Recording

    Raises
    ------
    RecordingError
        Naming the file, line and column of the first problem found.
    """
    path = Path(path)
    try:
        fh = open(path, "r", encoding="utf-8-sig", newline="")
    except FileNotFoundError:
        raise RecordingError("file not found", path=path) from None
    except OSError as exc:
        raise RecordingError(f"cannot open file ({exc.strerror})", path=path) from None
    try:
        with fh:
            return _read(fh, path, conditions, name)
    except UnicodeDecodeError as exc:
        raise RecordingError(f"not a UTF-8 text file ({exc.reason} at byte {exc.start})",
                             path=path) from None


def _read(fh, path, conditions, name) -> Recording:
    reader = csv.reader(fh)
    header = None
    header_line = None
    index = {}
    used = []
    rows = []          # list of (line, values tuple in `used` order)
    notes = []
    dropped = 0
    first_drop = None
    for rec in reader:
        line = reader.line_num
        if not rec or all(c.strip() == "" for c in rec):
            continue
        if rec[0].lstrip().startswith("#"):
            continue
        if header is None:
            if any("\x00" in c for c in rec):
                # UTF-16 without a byte-order mark decodes as UTF-8 with a NUL after each character
                raise RecordingError("NUL bytes in the header: a UTF-16 (or binary) file? szdyn reads "
                                     "UTF-8 text, save the file as UTF-8", path=path, line=line)
            header = [c.strip() for c in rec]
            header_line = line
            seen = {}
            for i, c in enumerate(header):
                if c == "":
                    raise RecordingError(f"empty column name in header (field {i + 1})",
                                         path=path, line=line)
                if c in seen:
                    raise RecordingError(f"column '{c}' appears twice in the header "
                                         f"(fields {seen[c] + 1} and {i + 1})", path=path, line=line)
                seen[c] = i
            for req in REQUIRED_COLUMNS:
                if req not in seen:
                    found = [name for d, name in _DELIMITERS.items() if d in header[0]]
                    hint = (f"; the header is one field holding {found[0]}s: szdyn reads "
                            "comma-separated values, save the file with commas"
                            if len(header) == 1 and found else "")
                    raise RecordingError(f"missing required column '{req}' (found: "
                                         + ", ".join(header) + ")" + hint, path=path, line=line)
            used = [c for c in REQUIRED_COLUMNS + OPTIONAL_COLUMNS if c in seen]
            index = {c: seen[c] for c in used}
            continue
        if len(rec) != len(header):
            if len(rec) < len(header):
                col = header[len(rec)]
                raise RecordingError(f"row has {len(rec)} fields, header has {len(header)} "
                                     f"(missing value)", path=path, line=line, column=col)
            raise RecordingError(f"row has {len(rec)} fields, header has {len(header)} "
                                 f"(extra value {rec[len(header)].strip()!r})", path=path, line=line)
        vals = tuple(_parse_number(rec[index[c]], path, line, c) for c in used)
        if rows:
            pline, prev = rows[-1]
            if vals[0] < prev[0]:
                raise RecordingError(f"time goes backwards ({vals[0]:g} s after {prev[0]:g} s on "
                                     f"line {pline})", path=path, line=line, column="t")
            if vals[0] == prev[0]:
                if vals == prev:
                    dropped += 1
                    first_drop = first_drop or line
                    continue
                raise RecordingError(f"time not increasing (t = {vals[0]:g} s repeats line {pline} "
                                     "with different values)", path=path, line=line, column="t")
        rows.append((line, vals))
    if header is None or not rows:
        raise RecordingError("empty file (no data rows)", path=path)
    if len(rows) < 2:
        raise RecordingError(f"only one data row (line {rows[0][0]}); need at least 2",
                             path=path)
    if dropped:
        notes.append(f"dropped {dropped} exact duplicate row(s), the first on line {first_drop}")
    data = np.array([v for _, v in rows], dtype=float)
    cols = {c: data[:, i] for i, c in enumerate(used)}
    _check_plausible(cols, [ln for ln, _ in rows], path)
    _check_units(cols, path)
    extra = tuple(c for c in header if c not in used)
    if extra:
        notes.append("ignored column(s): " + ", ".join(extra))
    return Recording(name=name or path.name, t=cols["t"], theta_w=cols["theta_w"],
                     theta_b=cols["theta_b"], omega_ref=cols.get("omega_ref"),
                     current=cols.get("current"), conditions=dict(conditions or {}),
                     source=path, extra_columns=extra, notes=notes,
                     meta={"header_line": header_line})


def _check_plausible(cols: dict, lines: list, path) -> None:
    """Refuse time gaps and angle jumps no logger of a working rig writes (see GAP_FACTOR and
    MAX_SPEED): each is a typo or a glitch at a line the message names."""
    dt = np.diff(cols["t"])
    med = float(np.median(dt))
    lim = max(GAP_MIN_S, GAP_FACTOR * med)
    k = int(np.argmax(dt))
    if dt[k] > lim:
        raise RecordingError(
            f"time jumps by {dt[k]:.6g} s (from {cols['t'][k]:.6g} s on line {lines[k]} to "
            f"{cols['t'][k + 1]:.6g} s), {_ratio(dt[k] / med)} times the median sample interval "
            f"{med:.3g} s: a mistyped time or a logger restart? Fix the time, or split the "
            "recording there", path=path, line=lines[k + 1], column="t")
    for c in ("theta_w", "theta_b"):
        with np.errstate(over="ignore"):
            # over at least the median interval: two rows a few microseconds apart (timestamp
            # jitter) would make one count look like a huge speed
            speed = np.abs(np.diff(cols[c])) / np.maximum(dt, med)
        k = int(np.argmax(speed))
        if not speed[k] <= MAX_SPEED:
            raise RecordingError(
                f"angle jumps by {cols[c][k + 1] - cols[c][k]:.6g} rad in {dt[k]:.3g} s (from line "
                f"{lines[k]}), {speed[k]:.3g} rad/s over the step or the median interval, more "
                f"than {MAX_SPEED:g} rad/s: a corrupted value or an encoder glitch?", path=path,
                line=lines[k + 1], column=c)
    if "omega_ref" in cols:
        k = int(np.argmax(np.abs(cols["omega_ref"])))
        if abs(cols["omega_ref"][k]) > MAX_SPEED:
            raise RecordingError(f"speed set-point {cols['omega_ref'][k]:.6g} rad/s is beyond "
                                 f"{MAX_SPEED:g} rad/s: a corrupted value, or not in rad/s?",
                                 path=path, line=lines[k], column="omega_ref")


def _ratio(r: float) -> str:
    """A large ratio for a message: whole below a million, else 3 significant digits (a mistyped
    time of 1e300 s is not worth 300 digits)."""
    return f"{r:.0f}" if r < 1e6 else f"{r:.3g}"


def _check_units(cols: dict, path) -> None:
    """Refuse angles logged in degrees where the columns say rad.

    Two travels over the whole recording (max - min) cannot exceed their partner's by far: the
    band's the wheel's (the band encoder counts wheel-equivalent radians, and a friction drive
    cannot make the band outrun the wheel: slip only makes it lag), and the wheel's the travel
    its set-point commands (the integral of ``omega_ref``). A ratio near 180/pi
    (:data:`DEGREE_RATIO`) is a unit mistake, not physics: the fit would run on speeds 57 times
    too large. The other direction is physics as often as a mistake (a stalled or saturated drive
    lags its set-point, a slipping band its wheel), so it is left alone; so a set-point in deg/s,
    a wheel alone in degrees without ``omega_ref``, or every column in degrees pass unnoticed.
    """
    travel = {c: float(np.ptp(cols[c])) for c in ("theta_w", "theta_b")}
    if "omega_ref" in cols:
        w = cols["omega_ref"]
        commanded = np.cumsum(0.5 * (w[1:] + w[:-1]) * np.diff(cols["t"]))
        travel["omega_ref"] = float(np.ptp(np.append(commanded, 0.0)))
    # (column, the column whose travel it cannot exceed, why, what to check)
    pairs = [("theta_b", "theta_w", "the band cannot outrun the wheel that drives it", "is theta_b in degrees?"),
             ("theta_w", "omega_ref", "a drive does not outrun its set-point",
              "are the angles in degrees, or is theta_w read before a gearbox (the model needs the wheel's angle)?")]
    lo, hi = DEGREE_RATIO
    for col, other, why, ask in pairs:
        if col not in travel or other not in travel or min(travel[col], travel[other]) < UNITS_MIN_TRAVEL:
            continue
        ratio = travel[col] / travel[other]
        if lo <= ratio <= hi:
            raise RecordingError(
                f"{_TRAVEL[col]} ({travel[col]:.4g} rad) is {ratio:.1f} times {_TRAVEL[other]} "
                f"({travel[other]:.4g} rad), but {why}: {ask} Angles must be in rad and "
                "omega_ref in rad/s", path=path, column=col)


# --------------------------------------------------------------------------- derived signals
def resample_uniform(rec: Recording, dt: float | None = None, *, gap_factor: float = 3.0):
    """Linearly interpolate the recording onto a uniform time grid.

    Parameters
    ----------
    rec : Recording
    dt : float, optional
        Grid step in s; default the median sample interval of ``rec``.
    gap_factor : float
        Sample intervals longer than ``gap_factor * median_dt`` are gaps; grid points inside
        them are marked invalid.

    Returns
    -------
    t : ndarray, shape (m,)
        Uniform grid from ``rec.t[0]`` to at most ``rec.t[-1]`` (s).
    cols : dict of str -> ndarray, shape (m,)
        ``theta_w``, ``theta_b`` (rad) and, when present, ``omega_ref`` (rad/s), ``current``
        (A), linearly interpolated.
    valid : ndarray of bool, shape (m,)
        False for grid points inside a gap.
    """
    med = float(np.median(np.diff(rec.t)))
    dt = med if dt is None else float(dt)
    if not (dt > 0 and math.isfinite(dt)):
        raise UserInputError(f"resample step dt must be > 0 s, got {dt!r}")
    m = int(math.floor(rec.duration / dt + 1e-9)) + 1
    t = rec.t[0] + dt * np.arange(m)
    cols = {k: np.interp(t, rec.t, v) for k, v in rec.columns().items() if k != "t"}
    dts = np.diff(rec.t)
    k = np.clip(np.searchsorted(rec.t, t, side="right") - 1, 0, len(dts) - 1)
    valid = dts[k] <= gap_factor * med
    return t, cols, valid


def _savgol_window(window_s: float, dt: float, order: int) -> int:
    n = int(round(window_s / dt))
    n += (n + 1) % 2          # odd
    return max(n, order + 2 + (order + 2 + 1) % 2)


def speeds(rec: Recording, window_s: float = 0.05, *, order: int = 2, dt: float | None = None):
    """Wheel and band speeds by local polynomial differentiation (Savitzky-Golay).

    Method: the cumulative angles are linearly interpolated onto a uniform grid of step ``dt``
    (:func:`resample_uniform`), then a polynomial of degree ``order`` is fitted by least
    squares in a centred window of ``window_s`` seconds around each grid point and its
    derivative taken (:func:`scipy.signal.savgol_filter`, ``deriv=1``, ``mode="interp"``
    which fits the first/last window at the ends). For quantized angles the window should span
    several counts of motion; see :func:`speed_noise_std` for the resulting noise.

    Parameters
    ----------
    rec : Recording
    window_s : float
        Fit window in s (rounded to an odd number of grid points, at least ``order + 2``).
    order : int
        Polynomial degree (2 keeps ramps unbiased; the derivative at the centre of a degree-2
        fit equals the degree-1 slope).
    dt : float, optional
        Grid step in s; default the median sample interval.

    Returns
    -------
    t : ndarray, shape (m,)
        Uniform grid (s).
    omega_w, omega_b : ndarray, shape (m,)
        Wheel and band angular speed (rad/s).
    """
    t, (ww, wb) = _savgol_columns(rec, ("theta_w", "theta_b"), window_s, order, dt, 1, "speed")
    return t, ww, wb


def _savgol_columns(rec: Recording, names, window_s: float, order: int, dt, deriv: int, what: str):
    """Columns ``names`` of ``rec`` on a uniform grid, Savitzky-Golay filtered (value or
    derivative ``deriv``) over ``window_s``: the one filter of :func:`speeds` and
    :func:`smoothed_current`. Returns the grid and the filtered columns."""
    from scipy.signal import savgol_filter

    t, cols, _ = resample_uniform(rec, dt)
    h = float(t[1] - t[0])
    n = _savgol_window(window_s, h, order)
    if n > t.shape[0]:
        raise UserInputError(f"recording '{rec.name}' is too short ({rec.duration:g} s) for a "
                             f"{what} window of {window_s:g} s")
    return t, [savgol_filter(cols[k], n, order, deriv=deriv, delta=h, mode="interp") for k in names]


def smoothed_current(rec: Recording, window_s: float = 0.05, *, order: int = 2, dt: float | None = None):
    """The ``current`` column smoothed like the speeds of :func:`speeds` (same grid and window).

    A local polynomial of degree ``order`` over ``window_s`` seconds (Savitzky-Golay, value, not
    derivative), so that the measured motor torque and the model's are compared through the
    same filter as the band speeds.

    Parameters
    ----------
    rec : Recording
        Must have a ``current`` column.
    window_s, order, dt
        As in :func:`speeds`.

    Returns
    -------
    t : ndarray, shape (m,)
        Uniform grid (s).
    current : ndarray, shape (m,)
        Smoothed current (A).
    """
    if rec.current is None:
        raise UserInputError(f"recording '{rec.name}' has no 'current' column")
    t, (cur,) = _savgol_columns(rec, ("current",), window_s, order, dt, 0, "current smoothing")
    return t, cur


def speed_noise_std(angle_noise_std: float, dt: float, window_s: float) -> float:
    """Standard deviation of a Savitzky-Golay speed from white angle noise (rad/s).

    For a least-squares slope over ``N`` equally spaced points, ``var = sigma^2 * 12 /
    (N (N^2 - 1) dt^2)``. Quantization with step ``q`` acts roughly like white noise of
    ``sigma = q / sqrt(12)`` once the angle moves several counts per window.

    Parameters
    ----------
    angle_noise_std : float
        ``sigma`` in rad.
    dt : float
        Grid step in s.
    window_s : float
        Window in s.
    """
    n = _savgol_window(window_s, dt, 1)
    return float(angle_noise_std * math.sqrt(12.0 / (n * (n * n - 1.0))) / dt)


def relative_speed(rec: Recording, window_s: float = 0.1, *, dt: float | None = None):
    """Smoothed relative speed ``omega_w - omega_b`` (rad/s) on a uniform grid.

    Computed as the Savitzky-Golay derivative of ``theta_w - theta_b`` over ``window_s``
    (default 0.1 s: long enough to average the impact bumps, short against ramps of ~1 s).

    Returns
    -------
    t : ndarray, shape (m,)
    rel : ndarray, shape (m,)
    """
    t, ww, wb = speeds(rec, window_s, dt=dt)
    return t, ww - wb


def slip_per_revolution(t, theta_w, theta_b) -> dict:
    """Slip accumulated over each complete revolution of the wheel angle.

    A revolution ``k`` runs from the first time ``|theta_w - theta_w[0]|`` reaches ``2 pi k``
    to the first time it reaches ``2 pi (k + 1)`` (crossing times by linear interpolation on a
    running maximum, so noise and quantization flicker cannot create extra crossings). The
    direction is that of the net wheel motion.

    Parameters
    ----------
    t, theta_w, theta_b : array_like, shape (n,)
        Time (s, increasing) and cumulative angles (rad).

    Returns
    -------
    dict of ndarray, each shape (k,) (k = number of complete revolutions, may be 0)
        ``t0``, ``t1`` (s): revolution start and end; ``omega_w`` (rad/s): mean wheel speed
        ``2 pi / (t1 - t0)`` (signed); ``slip`` (rad): ``Delta theta_w - Delta theta_b`` over
        the revolution, signed so that positive means the band lags the wheel; ``slip_fraction``
        (1): ``slip / (2 pi)``.
    """
    t = np.asarray(t, float)
    tw = np.asarray(theta_w, float)
    tb = np.asarray(theta_b, float)
    s = 1.0 if tw[-1] >= tw[0] else -1.0
    a = np.maximum.accumulate(s * (tw - tw[0]))
    tb_rel = s * (tb - tb[0])
    k = int(math.floor(a[-1] / (2 * math.pi)))
    empty = {key: np.zeros(0) for key in ("t0", "t1", "omega_w", "slip", "slip_fraction")}
    if k < 1:
        return empty
    levels = 2 * math.pi * np.arange(k + 1)
    # first index where a >= level; interpolate between it and the previous sample
    idx = np.searchsorted(a, levels, side="left")
    tc = np.empty(k + 1)
    bc = np.empty(k + 1)
    for j, (i, lev) in enumerate(zip(idx, levels)):
        if i == 0:
            tc[j], bc[j] = t[0], tb_rel[0]
            continue
        a0, a1 = a[i - 1], a[i]
        f = 0.0 if a1 == a0 else (lev - a0) / (a1 - a0)
        tc[j] = t[i - 1] + f * (t[i] - t[i - 1])
        bc[j] = tb_rel[i - 1] + f * (tb_rel[i] - tb_rel[i - 1])
    slip = 2 * math.pi - np.diff(bc)
    t0, t1 = tc[:-1], tc[1:]
    return {"t0": t0, "t1": t1, "omega_w": s * 2 * math.pi / (t1 - t0), "slip": slip,
            "slip_fraction": slip / (2 * math.pi)}


def slip_vs_speed(t, omega_w, omega_b, bins=10, *, min_speed: float = 0.05) -> dict:
    """Relative speed and slip ratio averaged in bins of wheel speed.

    Parameters
    ----------
    t : array_like, shape (m,)
        Uniform time grid (s) of the speeds (used only for the time spent per bin).
    omega_w, omega_b : array_like, shape (m,)
        Smoothed wheel and band speeds (rad/s), e.g. from :func:`speeds`.
    bins : int or array_like
        Number of equal-width bins over ``[min_speed, max |omega_w|]`` or explicit edges of
        ``|omega_w|`` (rad/s).
    min_speed : float
        Samples with ``|omega_w| < min_speed`` (rad/s) are left out (slip ratio undefined).

    Returns
    -------
    dict of ndarray
        ``edges`` shape (B+1,) (rad/s, of ``|omega_w|``); each of shape (B,): ``center``,
        ``rel_speed`` (mean ``omega_w - omega_b``, rad/s), ``rel_speed_std``, ``slip_ratio``
        (mean ``(omega_w - omega_b)/omega_w``), ``slip_ratio_std``, ``count`` (samples),
        ``time`` (s). Empty bins hold NaN means and zero counts.
    """
    t = np.asarray(t, float)
    ww = np.asarray(omega_w, float)
    wb = np.asarray(omega_b, float)
    sp = np.abs(ww)
    ok = sp >= min_speed
    if np.ndim(bins) == 0:
        hi = float(sp[ok].max()) if ok.any() else min_speed * 2
        edges = np.linspace(min_speed, max(hi, min_speed * 1.0001) * (1 + 1e-12), int(bins) + 1)
    else:
        edges = np.asarray(bins, float)
    nb = edges.shape[0] - 1
    which = np.digitize(sp, edges) - 1
    rel = ww - wb
    ratio = np.where(ok, rel / np.where(ok, ww, 1.0), np.nan)
    dt = float(np.median(np.diff(t))) if t.shape[0] > 1 else 0.0
    out = {k: np.full(nb, np.nan) for k in ("rel_speed", "rel_speed_std", "slip_ratio",
                                             "slip_ratio_std")}
    count = np.zeros(nb, dtype=int)
    for b in range(nb):
        m = ok & (which == b)
        count[b] = int(m.sum())
        if count[b]:
            out["rel_speed"][b] = rel[m].mean()
            out["rel_speed_std"][b] = rel[m].std()
            out["slip_ratio"][b] = ratio[m].mean()
            out["slip_ratio_std"][b] = ratio[m].std()
    out.update(edges=edges, center=0.5 * (edges[1:] + edges[:-1]), count=count,
               time=count * dt)
    return out


def stroke(t, theta_w, theta_b, pitch: float):
    """Column extension and stroke lost to slip (thesis eqs 1-5).

    Parameters
    ----------
    t, theta_w, theta_b : array_like, shape (n,)
        Time (s) and cumulative angles (rad).
    pitch : float
        Band helix pitch ``P_B`` (m), e.g. ``params.geometry.pitch``.

    Returns
    -------
    t : ndarray, shape (n,)
    stroke : ndarray, shape (n,)
        ``P_B (theta_b - theta_b[0]) / (2 pi)`` (m).
    stroke_lost : ndarray, shape (n,)
        ``P_B ((theta_w - theta_w[0]) - (theta_b - theta_b[0])) / (2 pi)`` (m).
    """
    if not (isinstance(pitch, (int, float)) and math.isfinite(pitch) and pitch > 0):
        raise UserInputError(f"band pitch must be a finite number > 0 m, got {pitch!r}")
    tw = np.asarray(theta_w, float)
    tb = np.asarray(theta_b, float)
    c = pitch / (2 * math.pi)
    return np.asarray(t, float), c * (tb - tb[0]), c * ((tw - tw[0]) - (tb - tb[0]))


def features(rec: Recording, pitch: float, *, window_s: float = 0.1, dt: float | None = None,
             speed_bins=None, min_speed: float = 0.05) -> dict:
    """All comparison features of one recording (see the module docstring).

    Parameters
    ----------
    rec : Recording
    pitch : float
        Band helix pitch ``P_B`` (m).
    window_s : float
        Smoothing window for speeds (s).
    dt : float, optional
        Uniform grid step (s); default the median sample interval.
    speed_bins : int or array_like, optional
        Bins of ``|omega_w|`` for :func:`slip_vs_speed`; default 10 equal bins.
    min_speed : float
        Minimum ``|omega_w|`` (rad/s) for the slip ratio.

    Returns
    -------
    dict
        ``t`` (m,) uniform grid, ``omega_w``, ``omega_b``, ``rel_speed`` (m,) rad/s;
        ``slip_per_rev`` (dict, see :func:`slip_per_revolution`); ``slip_vs_speed`` (dict, see
        :func:`slip_vs_speed`); ``stroke_t``, ``stroke``, ``stroke_lost`` (n,) at the
        recording's own samples (m); ``final_stroke``, ``final_stroke_lost`` (m).
    """
    t, ww, wb = speeds(rec, window_s, dt=dt)
    st_t, st, lost = stroke(rec.t, rec.theta_w, rec.theta_b, pitch)
    return {
        "t": t, "omega_w": ww, "omega_b": wb, "rel_speed": ww - wb,
        "slip_per_rev": slip_per_revolution(rec.t, rec.theta_w, rec.theta_b),
        "slip_vs_speed": slip_vs_speed(t, ww, wb, 10 if speed_bins is None else speed_bins,
                                       min_speed=min_speed),
        "stroke_t": st_t, "stroke": st, "stroke_lost": lost,
        "final_stroke": float(st[-1]), "final_stroke_lost": float(lost[-1]),
    }


def compare_features(measured: dict, simulated: dict) -> dict:
    """Scalar discrepancies between two feature sets from :func:`features`.

    Parameters
    ----------
    measured, simulated : dict
        Outputs of :func:`features` (for the simulated side, build a :class:`Recording` from
        the run, e.g. :func:`szdyn.sensors.truth_recording`, and use the same settings).

    Returns
    -------
    dict of str -> {"value": float, "unit": str, "compared": str}
        ``rel_speed_rms`` (rad/s), ``slip_per_rev_rms`` (rad), ``slip_ratio_vs_speed_rms`` (1),
        ``stroke_rms`` (m), ``final_stroke_lost_diff`` (m; measured minus simulated, at the
        last time both cover). A value
        is NaN when there is nothing to compare (e.g. no complete revolution).
    """
    out = {}
    tm, ts = measured["t"], simulated["t"]
    lo, hi = max(tm[0], ts[0]), min(tm[-1], ts[-1])
    m = (tm >= lo) & (tm <= hi)
    d = measured["rel_speed"][m] - np.interp(tm[m], ts, simulated["rel_speed"])
    out["rel_speed_rms"] = {
        "value": float(np.sqrt(np.mean(d ** 2))) if d.size else float("nan"), "unit": "rad/s",
        "compared": "RMS difference of the smoothed relative speed omega_w - omega_b on the "
                    "measured grid over the common time span"}
    a, b = measured["slip_per_rev"]["slip"], simulated["slip_per_rev"]["slip"]
    k = min(a.size, b.size)
    out["slip_per_rev_rms"] = {
        "value": float(np.sqrt(np.mean((a[:k] - b[:k]) ** 2))) if k else float("nan"),
        "unit": "rad",
        "compared": f"RMS difference of the slip per wheel revolution, revolution by revolution "
                    f"(first {k} revolutions)"}
    sa, sb = measured["slip_vs_speed"], simulated["slip_vs_speed"]
    if sa["edges"].shape == sb["edges"].shape and np.allclose(sa["edges"], sb["edges"]):
        dd = sa["slip_ratio"] - sb["slip_ratio"]
        ok = np.isfinite(dd)
        val = float(np.sqrt(np.mean(dd[ok] ** 2))) if ok.any() else float("nan")
        txt = "RMS difference of the mean slip ratio per wheel-speed bin (bins filled in both)"
    else:
        val = float("nan")
        txt = "not compared: the two feature sets use different speed bins (pass speed_bins)"
    out["slip_ratio_vs_speed_rms"] = {"value": val, "unit": "1", "compared": txt}
    tm2, ts2 = measured["stroke_t"], simulated["stroke_t"]
    m2 = (tm2 >= max(tm2[0], ts2[0])) & (tm2 <= min(tm2[-1], ts2[-1]))
    d2 = measured["stroke"][m2] - np.interp(tm2[m2], ts2, simulated["stroke"])
    out["stroke_rms"] = {
        "value": float(np.sqrt(np.mean(d2 ** 2))) if d2.size else float("nan"), "unit": "m",
        "compared": "RMS difference of the column extension P_B (theta_b - theta_b0)/(2 pi) at "
                    "the measured samples over the common time span"}
    t_end = min(tm2[-1], ts2[-1])
    out["final_stroke_lost_diff"] = {
        "value": float(np.interp(t_end, tm2, measured["stroke_lost"])
                       - np.interp(t_end, ts2, simulated["stroke_lost"])), "unit": "m",
        "compared": f"stroke lost to slip at the common end time t = {t_end:.6g} s (linear "
                    "interpolation), measured minus simulated"}
    return out
