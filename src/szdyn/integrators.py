"""Explicit Runge-Kutta integrators: methods as data (Butcher tableaux) plus one compiled kernel.

A method is a :class:`Tableau` (like scipy's ``RK45.A/B/C/E`` or nbkode); the whole time loop
runs in one of two ``numba.njit(cache=True)`` kernels:

* :func:`_fixed_kernel` - any explicit tableau with a fixed step ``dt`` (the thesis uses Heun's
  method, the "modified Euler" method, with a fixed step);
* :func:`_adaptive_kernel` - embedded tableaux (DOPRI5) with error control.

Why the model RHS is a module-level global and not an argument: Numba does not cache a jitted
function that receives another jitted function as an argument (it recompiles in every process),
so the kernels call ``szdyn_generated.spiral_zipper.rhs`` directly. One consequence is handled at
the bottom of this module: Numba only checks *this* file's timestamp when it loads a cached
kernel, so the cache stamp is extended with the generated module's stamp; otherwise regenerating
the model would silently keep running the old, cached RHS.

:func:`integrate` is the public entry point. It runs the kernel in ~50 compiled chunks so that a
``progress(fraction)`` callback can be called between chunks at negligible cost.
"""
from __future__ import annotations

import math
import os
from dataclasses import dataclass
from typing import Callable, Sequence

import numpy as np
from numba import njit

import szdyn_generated.spiral_zipper as _model
from szdyn_generated.spiral_zipper import N_AUX, state_size
from szdyn_generated.spiral_zipper import rhs as _rhs

from .errors import SimulationError

__all__ = ["Tableau", "HEUN", "RK4", "DOPRI5", "TABLEAUX", "Trajectory", "integrate", "steps_per_save",
           "check_sampling", "MIN_SAVED_INTERVALS", "MAX_OUTPUT_BYTES", "MAX_FIXED_STEPS"]

# Kernel status codes.
OK = 0
NONFINITE = 1  # a stage derivative or the new state contained NaN/inf
H_UNDERFLOW = 2  # adaptive step size fell below 1e-14*|t| + 1e-300
MAX_STEPS = 3  # adaptive: max_steps attempted steps used up

_N_CHUNKS = 50  # compiled calls per integrate(); ~10 us overhead each, gives 2 % progress steps


# =============================================================================== tableaux
@dataclass(frozen=True, eq=False)
class Tableau:
    """Butcher tableau of an explicit Runge-Kutta method.

    Parameters
    ----------
    name : str
        Registry name, e.g. ``"rk4"``.
    order : int
        Classical order p of the propagated solution (global error O(dt^p)).
    A : array_like, shape (s, s)
        Stage coefficients, strictly lower triangular (explicit method).
    b : array_like, shape (s,)
        Weights of the propagated solution, ``sum(b) == 1``.
    c : array_like, shape (s,)
        Stage times as fractions of the step, ``c_i == sum_j A_ij``.
    b_err : array_like, shape (s,), optional
        Error weights ``b - b_hat`` of an embedded method of order ``order - 1``; the local error
        estimate is ``h * sum_i b_err_i k_i``. Required for adaptive stepping.
    fsal : bool
        First-same-as-last: the last stage is evaluated at the new state (``A[-1] == b``,
        ``c[-1] == 1``), so it is reused as the first stage of the next step.
    """

    name: str
    order: int
    A: np.ndarray
    b: np.ndarray
    c: np.ndarray
    b_err: np.ndarray | None = None
    fsal: bool = False

    def __post_init__(self):
        A = np.array(self.A, dtype=float)
        b = np.array(self.b, dtype=float)
        c = np.array(self.c, dtype=float)
        s = b.size
        if A.shape != (s, s) or c.shape != (s,) or b.ndim != 1:
            raise ValueError(f"Tableau {self.name}: need A (s, s), b (s,), c (s,); got "
                             f"{A.shape}, {b.shape}, {c.shape}")
        if np.any(np.triu(A) != 0):
            raise ValueError(f"Tableau {self.name}: A must be strictly lower triangular")
        if not np.allclose(A.sum(axis=1), c, rtol=0, atol=1e-14):
            raise ValueError(f"Tableau {self.name}: c must equal the row sums of A")
        if abs(b.sum() - 1.0) > 1e-14:
            raise ValueError(f"Tableau {self.name}: sum(b) must be 1, got {b.sum()!r}")
        arrays = {"A": A, "b": b, "c": c}
        if self.b_err is not None:
            e = np.array(self.b_err, dtype=float)
            if e.shape != (s,) or abs(e.sum()) > 1e-14:
                raise ValueError(f"Tableau {self.name}: b_err must have shape ({s},) and sum 0")
            arrays["b_err"] = e
        if self.fsal and not (c[-1] == 1.0 and b[-1] == 0.0 and np.all(A[-1] == b)):
            raise ValueError(f"Tableau {self.name}: fsal needs A[-1] == b, b[-1] == 0, c[-1] == 1")
        for key, arr in arrays.items():
            arr.flags.writeable = False
            object.__setattr__(self, key, arr)

    @property
    def stages(self) -> int:
        """Number of stages s (RHS evaluations per step; one fewer when FSAL)."""
        return self.b.size

    @property
    def adaptive(self) -> bool:
        """True if the tableau has an embedded error estimate."""
        return self.b_err is not None


#: Heun's method (explicit trapezoid, "modified Euler"), order 2: the thesis's integrator.
HEUN = Tableau("heun", 2, A=[[0.0, 0.0], [1.0, 0.0]], b=[0.5, 0.5], c=[0.0, 1.0])

#: Classic fourth-order Runge-Kutta.
RK4 = Tableau("rk4", 4,
              A=[[0.0, 0.0, 0.0, 0.0], [0.5, 0.0, 0.0, 0.0], [0.0, 0.5, 0.0, 0.0],
                 [0.0, 0.0, 1.0, 0.0]],
              b=[1 / 6, 1 / 3, 1 / 3, 1 / 6], c=[0.0, 0.5, 0.5, 1.0])


def _dopri5():
    A = np.zeros((7, 7))
    A[1, :1] = [1 / 5]
    A[2, :2] = [3 / 40, 9 / 40]
    A[3, :3] = [44 / 45, -56 / 15, 32 / 9]
    A[4, :4] = [19372 / 6561, -25360 / 2187, 64448 / 6561, -212 / 729]
    A[5, :5] = [9017 / 3168, -355 / 33, 46732 / 5247, 49 / 176, -5103 / 18656]
    A[6, :6] = [35 / 384, 0.0, 500 / 1113, 125 / 192, -2187 / 6784, 11 / 84]
    b = A[6].copy()
    b_hat = np.array([5179 / 57600, 0.0, 7571 / 16695, 393 / 640, -92097 / 339200,
                      187 / 2100, 1 / 40])
    c = [0.0, 1 / 5, 3 / 10, 4 / 5, 8 / 9, 1.0, 1.0]
    return Tableau("dopri5", 5, A=A, b=b, c=c, b_err=b - b_hat, fsal=True)


#: Dormand-Prince 5(4) with embedded 4th-order error estimate, FSAL (as scipy's RK45).
DOPRI5 = _dopri5()

#: Registry of the built-in methods by name.
TABLEAUX = {"heun": HEUN, "rk4": RK4, "dopri5": DOPRI5}


# =============================================================================== kernels
@njit(cache=True)
def _first_nonfinite(v):
    """Index of the first NaN/inf in v, or -1. The sum trick keeps the common case branch-free."""
    acc = 0.0
    for j in range(v.shape[0]):
        acc += v[j] * 0.0  # inf*0 and nan*0 are nan
    if acc == 0.0:
        return -1
    for j in range(v.shape[0]):
        if not math.isfinite(v[j]):
            return j
    return -1


@njit(cache=True)
def _stage_state(A, st, x, K, h, xs):
    """xs = x + h * sum_m A[st, m] K[m]; summed per component so that for FSAL tableaux the
    last stage state is bit-identical to the propagated solution."""
    n = x.shape[0]
    for j in range(n):
        acc = 0.0
        for m in range(st):
            acc += A[st, m] * K[m, j]
        xs[j] = x[j] + h * acc


@njit(cache=True)
def _eval_stages(A, c, x, K, xs, t, h, p, drive, have_k0):
    """Evaluate the stage derivatives of one explicit RK step into K (stage 0 is skipped when
    FSAL already holds it). Returns ``(stage, var, t_stage)`` of the first non-finite derivative,
    or ``(-1, -1, t)``."""
    for st in range(A.shape[0]):
        if st == 0 and have_k0:
            continue
        _stage_state(A, st, x, K, h, xs)
        ts = t + c[st] * h
        _rhs(ts, xs, p, drive, K[st])
        bad = _first_nonfinite(K[st])
        if bad >= 0:
            return st, bad, ts
    return -1, -1, t


@njit(cache=True)
def _fixed_kernel(A, b, c, fsal, x, K, xs, xn, have_k0, t0, dt, t_end, i_start, i_stop, n_steps,
                  save_every, out, p, drive):
    """Fixed-step explicit RK over global step indices ``i_start <= i < i_stop``.

    Step i goes from ``t0 + i*dt`` to ``t0 + (i+1)*dt`` (times from the index, so no round-off
    drift); the last step (``i == n_steps - 1``) ends exactly at ``t_end`` and may be shorter.
    After step i the state is stored in ``out[(i+1)//save_every]`` when ``(i+1) % save_every == 0``
    and always in ``out[-1]`` after the last step. ``x`` (shape (n,)) is advanced in place; ``K``
    (shape (s, n)), ``xs``, ``xn`` are work buffers owned by the caller so that the FSAL stage
    survives between chunks.

    Returns ``(status, i, t_ok, t_bad, var, have_k0)``: on NONFINITE, step ``i`` failed, ``x`` is
    the last finite state (at ``t_ok``), ``t_bad`` is the stage time at which a derivative (or the
    new state) of variable ``var`` was first non-finite.
    """
    s = b.shape[0]
    n = x.shape[0]
    t = t0 + i_start * dt
    for i in range(i_start, i_stop):
        t = t0 + i * dt
        t_next = t_end if i + 1 == n_steps else t0 + (i + 1) * dt
        h = t_next - t
        _, bad, ts = _eval_stages(A, c, x, K, xs, t, h, p, drive, have_k0)
        if bad >= 0:
            return NONFINITE, i, t, ts, bad, have_k0
        if fsal:
            for j in range(n):  # last stage was evaluated exactly at the new state
                xn[j] = xs[j]
        else:
            for j in range(n):
                acc = 0.0
                for m in range(s):
                    acc += b[m] * K[m, j]
                xn[j] = x[j] + h * acc
        bad = _first_nonfinite(xn)
        if bad >= 0:
            return NONFINITE, i, t, t_next, bad, have_k0
        for j in range(n):
            x[j] = xn[j]
        if fsal:
            for j in range(n):
                K[0, j] = K[s - 1, j]
            have_k0 = True
        if (i + 1) % save_every == 0:
            out[(i + 1) // save_every, :] = x
        elif i + 1 == n_steps:
            out[out.shape[0] - 1, :] = x
        t = t_next
    return OK, i_stop, t, t, -1, have_k0


@njit(cache=True)
def _adaptive_kernel(A, b, c, e, fsal, expo, x, K, xs, xn, t, h, errold, last_rejected, have_k0,
                     t_save, k_next, k_stop, out, rtol, atol, hmax, steps_left, p, drive):
    """Adaptive embedded RK from time ``t`` until ``out[k_stop - 1]`` has been stored.

    Steps are clipped so that every save time ``t_save[k]`` is hit exactly (``out[k]`` is the
    state there). Error norm: rms over components of ``err_j / (atol + rtol*max(|x_j|,
    |xnew_j|))`` with ``err = h * sum_i e_i k_i``; a step is accepted if the norm is <= 1.
    Step-size control: PI controller (Hairer's DOPRI5 "Lund stabilisation", beta = 0.2*expo)
    with safety 0.9 and factor clamps [0.2, 5]; no growth directly after a rejection.

    A non-finite stage in a trial step is treated as a rejection (factor 0.2), because a too
    large trial step of a stiff contact model can overflow even though smaller steps are fine;
    if the derivative at the accepted state itself is non-finite, or h underflows after such
    rejections, the kernel stops with NONFINITE and reports the variable.

    Returns ``(status, t, h, errold, last_rejected, have_k0, k_next, n_acc, n_rej, t_bad, var)``;
    controller state is returned so that the next chunk continues seamlessly.
    """
    s = b.shape[0]
    n = x.shape[0]
    beta = 0.2 * expo
    alpha = expo - 0.75 * beta
    n_acc = 0
    n_rej = 0
    var = -1
    t_bad = t
    while k_next < k_stop:
        if n_acc + n_rej >= steps_left:
            return (MAX_STEPS, t, h, errold, last_rejected, have_k0, k_next, n_acc, n_rej,
                    t_bad, var)
        target = t_save[k_next]
        h_wanted = min(h, hmax)
        hit = t + h_wanted >= target
        h_step = target - t if hit else h_wanted
        if h_step < 1e-14 * abs(t) + 1e-300:
            status = NONFINITE if var >= 0 else H_UNDERFLOW
            return status, t, h_step, errold, last_rejected, have_k0, k_next, n_acc, n_rej, \
                t_bad, var
        # ---- stages
        st_bad, bad, ts = _eval_stages(A, c, x, K, xs, t, h_step, p, drive, have_k0)
        if bad >= 0:
            t_bad = ts
            var = bad
            if st_bad == 0:  # derivative at the accepted state itself: no step size helps
                return (NONFINITE, t, h_step, errold, last_rejected, have_k0, k_next, n_acc,
                        n_rej, t_bad, var)
            h = 0.2 * h_step
            n_rej += 1
            last_rejected = True
            continue
        # ---- propagated solution and error norm
        err2 = 0.0
        for j in range(n):
            acc = 0.0
            ee = 0.0
            for m in range(s):
                acc += b[m] * K[m, j]
                ee += e[m] * K[m, j]
            xn[j] = x[j] + h_step * acc
            sc = atol + rtol * max(abs(x[j]), abs(xn[j]))
            r = h_step * ee / sc
            err2 += r * r
        err = math.sqrt(err2 / n)
        if not math.isfinite(err):  # overflow in the new state: same as a non-finite stage
            var = _first_nonfinite(xn)
            t_bad = t + h_step
            h = 0.2 * h_step
            n_rej += 1
            last_rejected = True
            continue
        if err <= 1.0:
            if err == 0.0:
                fac = 5.0
            else:
                fac = 0.9 * err ** (-alpha) * errold ** beta
                fac = min(5.0, max(0.2, fac))
            if last_rejected:
                fac = min(fac, 1.0)
            h_new = h_step * fac
            if hit:
                # a clipped step says little about the natural step size: keep the old proposal
                h_new = max(h_new, h_wanted)
                t = target
            else:
                t = t + h_step
            for j in range(n):
                x[j] = xn[j]
            if fsal:
                for j in range(n):
                    K[0, j] = K[s - 1, j]
                have_k0 = True
            errold = max(err, 1e-4)
            last_rejected = False
            var = -1
            n_acc += 1
            if hit:
                out[k_next, :] = x
                k_next += 1
            h = h_new
        else:
            h = h_step * max(0.2, 0.9 * err ** (-expo))
            n_rej += 1
            last_rejected = True
    return OK, t, h, errold, last_rejected, have_k0, k_next, n_acc, n_rej, t_bad, var


# =============================================================================== public API
@dataclass(frozen=True, eq=False)
class Trajectory:
    """Result of :func:`integrate`.

    Attributes
    ----------
    t : ndarray, shape (n_save,)
        Save times in s (``t0, t0 + save_dt, ...``, and ``t_end``).
    x : ndarray, shape (n_save, n_state)
        State at ``t`` in the contract layout (rad, rad/s).
    method : str
        Name of the tableau used (with ``"(fixed)"`` appended for an embedded tableau run with
        fixed steps).
    n_steps : int
        Accepted steps.
    n_rejected : int
        Rejected steps (always 0 for fixed-step methods).
    """

    t: np.ndarray
    x: np.ndarray
    method: str
    n_steps: int
    n_rejected: int


def _resolve_method(method) -> Tableau:
    if isinstance(method, Tableau):
        return method
    try:
        return TABLEAUX[str(method).lower()]
    except KeyError:
        raise ValueError(f"integrate: unknown method {method!r}; valid methods are "
                         f"{', '.join(repr(k) for k in TABLEAUX)}") from None


def _positive(name, value):
    try:
        v = float(value)
    except (TypeError, ValueError):
        raise ValueError(f"integrate: {name} must be a positive number, got {value!r}") from None
    if not (v > 0 and math.isfinite(v)) and not (name == "hmax" and v == math.inf):
        raise ValueError(f"integrate: {name} must be a finite number > 0, got {value!r}")
    return v


def _as_vector(name, value):
    # always a fresh, writable, C-contiguous float64 copy: a read-only or strided array would be
    # a new Numba signature, i.e. a multi-second compile and another cache entry
    arr = np.array(value, dtype=np.float64, order="C", copy=True)
    if arr.ndim != 1:
        raise ValueError(f"integrate: {name} must be 1-D, got shape {arr.shape}")
    return arr


def _initial_step(tab, t0, x0, p, drive, rtol, atol, span, hmax):
    """Hairer-Norsett-Wanner / scipy ``select_initial_step`` heuristic (two RHS calls)."""
    f0 = np.empty_like(x0)
    _rhs(t0, x0, p, drive, f0)
    if not np.all(np.isfinite(f0)):
        return min(1e-6, span, hmax)  # let the kernel find and report the non-finite derivative
    scale = atol + np.abs(x0) * rtol
    d0 = np.sqrt(np.mean((x0 / scale) ** 2))
    d1 = np.sqrt(np.mean((f0 / scale) ** 2))
    h0 = 1e-6 if d0 < 1e-5 or d1 < 1e-5 else 0.01 * d0 / d1
    h0 = min(h0, span)
    x1 = x0 + h0 * f0
    f1 = np.empty_like(x0)
    _rhs(t0 + h0, x1, p, drive, f1)
    d2 = np.sqrt(np.mean(((f1 - f0) / scale) ** 2)) / h0
    if not math.isfinite(d2):
        return min(h0, hmax)
    if d1 <= 1e-15 and d2 <= 1e-15:
        h1 = max(1e-6, h0 * 1e-3)
    else:
        h1 = (0.01 / max(d1, d2)) ** (1.0 / (tab.order))
    return min(100 * h0, h1, span, hmax)


#: fewest saved intervals a run of the command-line tools may have (``check_sampling``): with
#: fewer, the output is a few points, not a trajectory, and the metrics and criteria computed on
#: it would be numbers without meaning
MIN_SAVED_INTERVALS = 10
#: largest saved output of one run (bytes: rows x states x 8) the command-line tools start: a
#: mistyped duration, speed or N_c would otherwise end, minutes later, in a failed allocation
#: (the thesis's runs save 13 MB at N_c = 100)
MAX_OUTPUT_BYTES = 2 * 2**30
#: most fixed steps of one run the command-line tools start: at N_c = 100 an RK4 step costs ~8 us
#: (four ~2 us right-hand sides, BENCHMARKS.md), so 1e9 steps are over two hours a run; a
#: mistyped ``dt`` (1e-9 s over a 13 s thesis run is 1.3e10 steps, a day) would run unheard, and
#: one of 1e-300 would not even compile
MAX_FIXED_STEPS = 10**9


def steps_per_save(dt: float, save_dt: float) -> int:
    """Fixed steps per saved row, ``save_dt / dt``; ValueError unless it is a whole number
    (within 1e-9 relative): the fixed-step kernel saves every k-th step."""
    k = int(round(save_dt / dt))
    if k < 1 or abs(k * dt - save_dt) > 1e-9 * save_dt:
        raise ValueError(f"save_dt={save_dt!r} must be a multiple of dt={dt!r} (within 1e-9 relative)")
    return k


def check_sampling(method: str, dt: float, save_dt: float, duration: float,
                   n_states: int | None = None) -> None:
    """Refuse sampling settings a run cannot honour, before any run starts.

    Parameters
    ----------
    method : str
        A key of :data:`TABLEAUX`; ``dt`` matters only for a fixed-step one.
    dt, save_dt, duration : float
        Fixed step, output interval and simulated time (s).
    n_states : int, optional
        Length of the state vector (:func:`state_size`); with it, the saved output is held to
        :data:`MAX_OUTPUT_BYTES`.

    Raises
    ------
    ValueError
        ``save_dt`` not a whole multiple of ``dt`` or more than :data:`MAX_FIXED_STEPS` steps
        (fixed step), the run shorter than
        :data:`MIN_SAVED_INTERVALS` output intervals, or its output larger than
        :data:`MAX_OUTPUT_BYTES`. The message names ``dt``/``save_dt``; callers put it in their
        own terms (an option, a spec key).
    """
    if not _resolve_method(method).adaptive:
        if duration / dt > MAX_FIXED_STEPS:
            raise ValueError(f"dt={dt!r} s makes {duration / dt:.3g} fixed steps over the {duration:g} s run, "
                             f"more than {MAX_FIXED_STEPS:.0e} (hours of work a run): take a larger dt")
        steps_per_save(dt, save_dt)
    if duration / save_dt < MIN_SAVED_INTERVALS * (1 - 1e-9):   # (0.7 s at 0.07 s is 10, not 9.99...)
        raise ValueError(f"save_dt={save_dt!r} s gives {duration / save_dt:.3g} saved intervals over the "
                         f"{duration:g} s run; at least {MIN_SAVED_INTERVALS} are needed (make save_dt "
                         f"at most {duration / MIN_SAVED_INTERVALS:g} s)")
    if n_states is not None:
        size = (math.floor(duration / save_dt) + 2) * n_states * 8
        if size > MAX_OUTPUT_BYTES:
            raise ValueError(f"a {duration:g} s run saved every {save_dt:g} s with {n_states} states would "
                             f"hold {size / 2**30:.3g} GiB of output, more than the limit of "
                             f"{MAX_OUTPUT_BYTES / 2**30:g} GiB (a shorter run, a larger save_dt or fewer "
                             "circles)")


def integrate(x0, p, drive, t_end, method="rk4", dt=1e-4, save_dt=1e-3, rtol=1e-6, atol=1e-9,
              h0=None, hmax=math.inf, max_steps=10**8, t0=0.0,
              progress: Callable[[float], object] | None = None,
              state_names: Sequence[str] | None = None, adaptive: bool | None = None):
    """Integrate the generated Spiral Zipper model from ``t0`` to ``t_end``.

    Parameters
    ----------
    x0 : array_like, shape (n_state,)
        Initial state in the contract layout ``[q_w, q_b, q_1..q_Nc, u_w, u_b, u_1..u_Nc]``
        (rad, rad/s); must be finite.
    p : array_like, shape (len(PARAM_NAMES),)
        Parameter vector ordered as ``szdyn_generated.spiral_zipper.PARAM_NAMES``.
    drive : array_like, shape (1 + 3K,)
        Drive array (see :mod:`szdyn.drive`).
    t_end : float
        Final time in s, ``> t0``. Always stored as the last sample.
    method : str or Tableau
        ``"heun"`` (thesis), ``"rk4"`` or ``"dopri5"``, or any :class:`Tableau`.
    dt : float
        Fixed step in s (fixed-step methods only).
    save_dt : float
        Output interval in s; for fixed steps a multiple of ``dt`` (1e-9 relative).
    rtol, atol : float
        Relative and absolute tolerances of the adaptive method (absolute in rad, rad/s).
    h0 : float, optional
        First adaptive step in s; default from the Hairer-Norsett-Wanner heuristic.
    hmax : float
        Largest adaptive step in s.
    max_steps : int
        Limit on attempted adaptive steps (accepted + rejected).
    t0 : float
        Initial time in s.
    progress : callable, optional
        Called as ``progress(fraction)`` with ``0 < fraction <= 1`` between compiled chunks
        (about 50 per run).
    state_names : sequence of str, optional
        Names of the state variables, used in error messages.
    adaptive : bool, optional
        Force fixed (False) or adaptive (True) stepping; default: adaptive iff the tableau has
        an embedded error estimate (so ``"dopri5"`` is adaptive).

    Returns
    -------
    Trajectory
        ``t`` shape (n_save,), ``x`` shape (n_save, n_state).

    Raises
    ------
    ValueError
        Invalid arguments (unknown method, non-finite ``x0``, ``save_dt`` not a multiple of ``dt``).
    SimulationError
        The state or its derivative became non-finite, the adaptive step size underflowed, or
        ``max_steps`` was exhausted. The message says when, which variable and what to try; the
        exception's ``trajectory`` holds the samples computed before the failure.
    """
    tab = _resolve_method(method)
    use_adaptive = tab.adaptive if adaptive is None else bool(adaptive)
    if use_adaptive and not tab.adaptive:
        raise ValueError(f"integrate: method {tab.name!r} has no embedded error estimate; "
                         f"adaptive stepping needs one of "
                         f"{', '.join(repr(k) for k, v in TABLEAUX.items() if v.adaptive)}")
    x0 = _as_vector("x0", x0)
    p = _as_vector("p", p)
    drive = _as_vector("drive", drive)
    n = x0.size
    if n < state_size(1) or (n - N_AUX) % 2:
        raise ValueError(f"integrate: x0 must have length 2*(N_c + 2) + {N_AUX} with N_c >= 1, got {n}")
    bad = np.flatnonzero(~np.isfinite(x0))
    if bad.size:
        raise ValueError(f"integrate: x0 must be finite, got {x0[bad[0]]} in "
                         f"{_var_name(bad[0], state_names)}")
    if p.size != len(_model.PARAM_NAMES):
        raise ValueError(f"integrate: p must have {len(_model.PARAM_NAMES)} entries "
                         f"(PARAM_NAMES), got {p.size}")
    K = int(drive[0]) if drive.size else 0
    if drive.size < 4 or K < 1 or drive.size != 1 + 3 * K:
        raise ValueError(f"integrate: drive must be [K, t_k.., v_k.., c_k..] of length 1 + 3K, "
                         f"got length {drive.size}")
    if state_names is not None and len(state_names) != n:
        raise ValueError(f"integrate: state_names has {len(state_names)} names for {n} states")
    t0 = float(t0)
    t_end = float(t_end)
    if not (math.isfinite(t0) and math.isfinite(t_end) and t_end > t0):
        raise ValueError(f"integrate: need finite t_end > t0, got t0={t0!r}, t_end={t_end!r}")
    save_dt = _positive("save_dt", save_dt)
    span = t_end - t0

    # save grid t0 + k*save_dt (k from the index, no drift) plus t_end if it is off the grid
    n_full = int(math.floor(span / save_dt * (1 + 1e-12)))
    t_save = t0 + save_dt * np.arange(n_full + 1)
    remainder = t_end - t_save[-1]  # in (-tiny, save_dt)
    appended = n_full == 0 or remainder > 1e-9 * save_dt
    if appended:
        t_save = np.append(t_save, t_end)
    else:
        t_save[-1] = t_end
    out = np.empty((t_save.size, n))
    out[0] = x0

    s = tab.stages
    Kbuf = np.zeros((s, n))
    xs = np.empty(n)
    xn = np.empty(n)
    x = x0.copy()
    name = tab.name if use_adaptive or not tab.adaptive else tab.name + "(fixed)"

    if not use_adaptive:
        dt = _positive("dt", dt)
        try:
            save_every = steps_per_save(dt, save_dt)
        except ValueError as exc:
            raise ValueError(f"integrate: {exc}") from None
        # step count from the save grid (not from span/dt) so that the last save row is always
        # written: whole save intervals, plus ceil(remainder/dt) steps if t_end is off the grid
        n_steps = n_full * save_every
        if appended:
            n_steps += max(1, int(math.ceil(remainder / dt * (1 - 1e-9))))
        # chunk boundaries on multiples of save_every so that saves never straddle chunks
        n_blocks = -(-n_steps // save_every)
        bounds = sorted({min(n_steps, int(round(f)) * save_every)
                         for f in np.linspace(0, n_blocks, min(_N_CHUNKS, n_blocks) + 1)})
        have_k0 = False
        for i0, i1 in zip(bounds[:-1], bounds[1:]):
            status, i_fail, t_ok, t_bad, var, have_k0 = _fixed_kernel(
                tab.A, tab.b, tab.c, tab.fsal, x, Kbuf, xs, xn, have_k0, t0, dt, t_end, i0, i1,
                n_steps, save_every, out, p, drive)
            if status != OK:
                # rows 0 .. i_fail//save_every were written before step i_fail failed
                _raise(status, tab, False, t_ok, t_bad, var, state_names, dt, rtol, atol,
                       t_save, out, i_fail // save_every + 1, x, name, i_fail, 0)
            if progress is not None:
                progress(i1 / n_steps)
        return Trajectory(t_save, out, name, n_steps, 0)

    rtol = _positive("rtol", rtol)
    atol = _positive("atol", atol)
    hmax = _positive("hmax", hmax)
    max_steps = int(max_steps)
    if max_steps < 1:
        raise ValueError(f"integrate: max_steps must be >= 1, got {max_steps}")
    h = _initial_step(tab, t0, x, p, drive, rtol, atol, span, hmax) if h0 is None \
        else min(_positive("h0", h0), hmax)
    expo = 1.0 / tab.order  # embedded estimate of order p-1: error ~ h^p
    t, errold, last_rej, have_k0 = t0, 1e-4, False, False
    k_next, n_acc, n_rej = 1, 0, 0
    n_save = t_save.size
    stops = sorted({int(round(f)) for f in np.linspace(1, n_save, min(_N_CHUNKS, n_save - 1) + 1)})
    for k_stop in stops[1:]:
        (status, t, h, errold, last_rej, have_k0, k_next, na, nr, t_bad, var) = _adaptive_kernel(
            tab.A, tab.b, tab.c, tab.b_err, tab.fsal, expo, x, Kbuf, xs, xn, t, h, errold,
            last_rej, have_k0, t_save, k_next, k_stop, out, rtol, atol, hmax,
            max_steps - n_acc - n_rej, p, drive)
        n_acc += na
        n_rej += nr
        if status != OK:
            _raise(status, tab, True, t, t_bad, var, state_names, h, rtol, atol, t_save, out,
                   k_next, x, name, n_acc, n_rej, max_steps=max_steps)
        if progress is not None:
            progress((t - t0) / span)
    return Trajectory(t_save, out, name, n_acc, n_rej)


def _var_name(k, state_names):
    k = int(k)
    if state_names is not None and 0 <= k < len(state_names):
        return f"{state_names[k]} (x[{k}])"
    return f"x[{k}]"


def _raise(status, tab, adaptive, t_ok, t_bad, var, state_names, h, rtol, atol, t_save, out,
           n_saved, x, name, n_acc, n_rej, max_steps=None):
    """Build and raise a SimulationError saying when, which variable and what to try."""
    # partial trajectory: the saved samples plus the last finite state
    t_part = np.append(t_save[:n_saved], t_ok) if t_ok > t_save[n_saved - 1] else t_save[:n_saved]
    x_part = np.vstack([out[:n_saved], x[None, :]]) if t_part.size > n_saved else out[:n_saved]
    traj = Trajectory(t_part.copy(), x_part.copy(), name, n_acc, n_rej)
    what = _var_name(var, state_names) if var >= 0 else None
    if status == NONFINITE:
        msg = f"non-finite value (NaN/inf) in the time derivative of {what} at t = {t_bad:.9g} s"
        if f"{t_ok:.9g}" != f"{t_bad:.9g}":
            msg += f" (last finite state at t = {t_ok:.9g} s)"
        msg += ". "
        if t_ok == t_save[0] and t_bad == t_ok:
            # the derivative of the given initial state is already non-finite: not a step issue
            msg += "This happens at the initial state, so no step size can help: "
        elif adaptive:
            msg += (f"Try a tighter tolerance (rtol={rtol:g} -> {rtol / 100:g}; `--rtol` on the "
                    f"command line) or a smaller hmax (Python only), and ")
        else:
            msg += (f"Try a smaller step (dt={h:g} s -> dt={h / 4:g} s; `--dt` on the command "
                    f"line) or the adaptive method='dopri5' (`--method dopri5`), and ")
        msg += "check p, x0 and the drive for NaN/inf or unphysical values."
    elif status == H_UNDERFLOW:
        msg = (f"step size underflow (h = {h:.3g} s) at t = {t_ok:.9g} s with rtol={rtol:g}, "
               f"atol={atol:g}: the solution is (nearly) singular or discontinuous there. Try a "
               f"looser atol (`--atol`), check the parameters (contact stiffness, impact clamp), or "
               f"use a fixed-step method='heun'/'rk4' with small dt (`--method heun --dt ...`) to "
               f"see what happens.")
    else:
        msg = (f"max_steps={max_steps} exhausted at t = {t_ok:.9g} s ({n_acc} accepted, {n_rej} "
               f"rejected, last h = {h:.3g} s). Try a larger max_steps (Python only) or a looser "
               f"rtol (`--rtol`); if h is tiny the problem may be stiff.")
    raise SimulationError(f"Simulation failed ({name}): " + msg, t=t_bad if var >= 0 else t_ok,
                          variable=what, trajectory=traj)


# =============================================================================== cache stamp
def _extend_cache_stamps():
    """Make cached kernels depend on the generated model file as well as on this file.

    Numba validates a cache entry only against the (mtime, size) of the file defining the
    jitted function; callees from other modules are compiled in but not tracked. Without this,
    regenerating ``generated/*.py`` would keep loading kernels with the old RHS compiled in
    (verified with numba 0.68). Uses Numba internals
    (``Dispatcher._cache._cache_file._source_stamp``); if they change, caching still works but
    the stamp is not extended.
    """
    try:
        # every module of the generated package (rhs calls into kernels.py as well)
        folder = os.path.dirname(os.path.abspath(_model.__file__))
        extra = tuple(sorted((e.name, e.stat().st_mtime_ns, e.stat().st_size)
                             for e in os.scandir(folder) if e.name.endswith(".py")))
    except (OSError, TypeError, AttributeError):
        return
    for disp in (_fixed_kernel, _adaptive_kernel):
        cache_file = getattr(getattr(disp, "_cache", None), "_cache_file", None)
        stamp = getattr(cache_file, "_source_stamp", None)
        if stamp is not None:
            cache_file._source_stamp = (stamp, extra)


_extend_cache_stamps()
