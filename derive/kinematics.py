"""Frames, points and bodies of the Spiral Zipper (model-notes section 1).

Two constructions share this file:

* the *kernel* construction (one wheel, band, one generic circle with symbolic hinge offset
  ``alpha``, one generic roller with symbolic offset ``beta``), oriented relative to the circle's
  hinge frame so that every scalar depends only on the rotation-invariant angles
  ``phi = q_i - q_b`` and ``rho = q_w + beta - q_b - alpha``;
* the *full* construction (``N_c`` circles, ``N_r`` rollers, all frames oriented from the
  inertial frame), which tests use as the oracle for the assembled kernels.
"""
from __future__ import annotations

from dataclasses import dataclass, field

import sympy as sm
import sympy.physics.mechanics as me

from .symbols import P, q_b, q_w, u_b, u_w


@dataclass
class Circle:
    """Kinematics of circle ``i``: hinge ``Q`` on the band, arm frame ``A``, centre ``P``."""

    q: sm.Function
    u: sm.Function
    offset: sm.Expr
    hinge_frame: me.ReferenceFrame
    arm: me.ReferenceFrame
    Q: me.Point
    P: me.Point
    particle: me.Particle


@dataclass
class Roller:
    """Kinematics of roller ``j``: centre ``C`` fixed in the wheel, frame ``F`` along O->C."""

    offset: sm.Expr
    frame: me.ReferenceFrame
    centre: me.Point


@dataclass
class Mechanism:
    """Inertial frame, tube-axis origin, wheel and band frames."""

    N: me.ReferenceFrame
    O: me.Point
    W: me.ReferenceFrame
    B: me.ReferenceFrame
    circles: list[Circle] = field(default_factory=list)
    rollers: list[Roller] = field(default_factory=list)


def mechanism() -> Mechanism:
    """Wheel W and band B, both rotating about the tube axis n3 through O."""
    N = me.ReferenceFrame("N")
    O = me.Point("O")
    O.set_vel(N, 0)
    W = N.orientnew("W", "Axis", (q_w, N.z))
    W.set_ang_vel(N, u_w * N.z)
    B = N.orientnew("B", "Axis", (q_b, N.z))
    B.set_ang_vel(N, u_b * N.z)
    return Mechanism(N=N, O=O, W=W, B=B)


def add_circle(m: Mechanism, q, u, offset, tag: str, relative: bool) -> Circle:
    """Attach a small circle on a massless arm hinged at radius R_bo, angle q_b + offset.

    ``relative=True`` orients the arm from the hinge frame (angle ``q - q_b``) so that
    expressions come out in the arm's relative angle; ``False`` orients it from N (absolute).
    """
    N, O = m.N, m.O
    H = N.orientnew(f"H{tag}", "Axis", (q_b + offset, N.z))  # hinge frame: x along O->Q_i
    H.set_ang_vel(N, u_b * N.z)
    if relative:
        A = H.orientnew(f"A{tag}", "Axis", (q - q_b, H.z))
    else:
        A = N.orientnew(f"A{tag}", "Axis", (q + offset, N.z))
    A.set_ang_vel(N, u * N.z)
    Q = O.locatenew(f"Q{tag}", P["R_bo"] * H.x)
    Q.v2pt_theory(O, N, H)
    # At rest (q = q_b) the arm points inward: P_i = Q_i - d * a_x.
    Pt = Q.locatenew(f"P{tag}", -P["d"] * A.x)
    Pt.v2pt_theory(Q, N, A)
    c = Circle(q, u, offset, H, A, Q, Pt, me.Particle(f"circle{tag}", Pt, P["m_c"]))
    m.circles.append(c)
    return c


def add_roller(m: Mechanism, offset, tag: str, seen_from: Circle | None = None) -> Roller:
    """Attach a roller centre at radius R_w, angle q_w + offset, fixed in the wheel.

    With ``seen_from`` (the generic circle of a kernel) the roller frame is oriented from that
    circle's hinge frame by ``q_w + offset - (q_b + alpha)``, so scalars depend on that
    difference only; otherwise it is oriented from N.
    """
    N, O = m.N, m.O
    if seen_from is not None:
        H = seen_from.hinge_frame
        F = H.orientnew(f"F{tag}", "Axis", (q_w + offset - q_b - seen_from.offset, H.z))
    else:
        F = N.orientnew(f"F{tag}", "Axis", (q_w + offset, N.z))
    F.set_ang_vel(N, u_w * N.z)
    C = O.locatenew(f"C{tag}", P["R_w"] * F.x)
    C.v2pt_theory(O, N, F)
    r = Roller(offset, F, C)
    m.rollers.append(r)
    return r


@dataclass
class ContactGeometry:
    """Roller-circle contact: normal ``n`` (roller -> circle), tangent ``tang = z x n``,
    overlap ``delta`` (> 0 in contact), its rate, the sliding speed and the contact point on the
    roller surface (moving with the wheel)."""

    r: me.Vector
    dist: sm.Expr
    n: me.Vector
    tang: me.Vector
    delta: sm.Expr
    delta_dot: sm.Expr
    v_slide: sm.Expr
    contact_point: me.Point


def contact_geometry(m: Mechanism, c: Circle, rl: Roller) -> ContactGeometry:
    """Kinematics of the contact between roller ``rl`` and circle ``c`` (eqs 34-35)."""
    N, O, W = m.N, m.O, m.W
    r = c.P.pos_from(rl.centre)
    frame = c.hinge_frame
    rx = r.dot(frame.x)
    ry = r.dot(frame.y)
    dist = sm.sqrt(rx**2 + ry**2)
    n = (rx * frame.x + ry * frame.y) / dist
    tang = N.z.cross(n)
    delta = P["t_c"] + P["t_r"] - dist
    v_rel = c.P.vel(N) - rl.centre.vel(N)
    # d|r|/dt = r . v_rel / |r|, and delta_dot = -d|r|/dt.
    delta_dot = -(rx * v_rel.dot(frame.x) + ry * v_rel.dot(frame.y)) / dist
    # Contact point on the roller surface along the line of centres, as a point of the wheel.
    Cp = rl.centre.locatenew("Cp", P["t_r"] * n)
    Cp.set_vel(N, W.ang_vel_in(N).cross(Cp.pos_from(O)))
    v_slide = (c.P.vel(N) - Cp.vel(N)).dot(tang)
    return ContactGeometry(r, dist, n, tang, delta, delta_dot, v_slide, Cp)
