"""Named scenarios: sets of runs (drive profile + duration) that ``python -m szdyn.run`` knows."""
from __future__ import annotations

import math
from dataclasses import dataclass

from .drive import RampHold


@dataclass(frozen=True)
class RunSpec:
    """One run of a scenario: a name (file stem), a drive profile and its duration (s)."""

    name: str
    label: str
    drive: object
    t_end: float
    t_ramp: float


#: Thesis Fig. 10 accelerations (rad/s^2).
THESIS_ACCELERATIONS = (0.1 * math.pi, 0.2 * math.pi, 0.5 * math.pi)


def thesis_fig10(omega_hold: float = math.pi, t_hold: float = 3.0) -> list[RunSpec]:
    """The thesis's three wheel-speed ramps omega = a t (a = 0.1, 0.2, 0.5 pi rad/s^2), each up
    to the same speed ``omega_hold`` (rad/s) and then held for ``t_hold`` s, so that the runs
    can be compared at matched wheel speeds and during the hold."""
    runs = []
    for k, a in zip((1, 2, 5), THESIS_ACCELERATIONS):
        t_ramp = omega_hold / a
        runs.append(RunSpec(f"ramp_0.{k}pi", f"omega = 0.{k} pi t", RampHold(a=a, t_ramp=t_ramp, t_hold=t_hold),
                            t_ramp + t_hold, t_ramp))
    return runs


SCENARIOS = {"thesis-fig10": thesis_fig10}
