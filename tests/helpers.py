"""Shared helpers for the jaxbill tests: valid random scenes and states, and an
independent numpy description of the physics (written from physics.md, not
from jaxbill) to check jaxbill's output against.

Sampling a valid state: both ends strictly inside the circle. In the stick's
own frame (``a`` along ``u``, ``b`` along ``u_perp``) the centre ``c = a u + b u_perp``
puts both ends inside iff ``(|a| + ell)^2 + b^2 < R^2``; we draw ``b`` in
``(-sqrt(R^2 - ell^2), +sqrt(R^2 - ell^2))`` and then ``a`` in
``(-(sqrt(R^2 - b^2) - ell), +...)``, both shrunk by ``INSIDE`` < 1, so every
draw is valid even for ``ell / R = 0.9999`` (where rejection sampling in the
disc would almost never succeed).
"""

from __future__ import annotations

import math
import os
import sys

import numpy as np

_HERE = os.path.dirname(os.path.abspath(__file__))
if _HERE not in sys.path:
    sys.path.insert(0, _HERE)

INSIDE = 0.98  # fraction of the admissible extent used for the centre
TWO_PI = 2.0 * math.pi


# ---------------------------------------------------------------------------
# scenes
# ---------------------------------------------------------------------------
def kind_of(ell: float, inertia) -> str:
    if ell == 0.0:
        return "circle"
    if inertia is not None and math.isinf(inertia):
        return "lens"
    return "rotor"


def resolved_inertia(mass: float, ell: float, inertia) -> float:
    """The moment of inertia physics.md prescribes (default ``M ell^2``)."""
    if inertia is None:
        return mass * ell * ell
    return float(inertia)


def make_scene(R=2.0, ell=1.0, mass=1.0, inertia=None):
    import jaxbill as jb

    return jb.StickInCircle(R=R, ell=ell, mass=mass, inertia=inertia)


# ---------------------------------------------------------------------------
# states
# ---------------------------------------------------------------------------
def state_from_unit(R, ell, kind, u, speed=1.0, max_spin=3.0):
    """A valid interior state from six numbers ``u`` in ``[0, 1]``.

    ``max_spin`` bounds ``|omega|`` in units of ``speed / R`` (turns per flight
    across the circle are about ``max_spin / pi``). The lens gets ``omega = 0``.
    """
    u = [min(max(float(x), 0.0), 1.0) for x in u]
    alpha = TWO_PI * u[0] - math.pi
    b_max = math.sqrt(R * R - ell * ell)
    b = (2.0 * u[1] - 1.0) * INSIDE * b_max
    a_max = math.sqrt(R * R - b * b) - ell
    a = (2.0 * u[2] - 1.0) * INSIDE * a_max
    ca, sa = math.cos(alpha), math.sin(alpha)
    x = a * ca - b * sa
    y = a * sa + b * ca
    heading = TWO_PI * u[3]
    vx, vy = speed * math.cos(heading), speed * math.sin(heading)
    omega = 0.0 if kind == "lens" else (2.0 * u[4] - 1.0) * max_spin * speed / R
    return np.array([x, y, alpha, vx, vy, omega], dtype=np.float64)


def random_state(rng, R, ell, kind, speed=None, max_spin=3.0):
    if speed is None:
        speed = float(rng.uniform(0.3, 3.0))
    return state_from_unit(R, ell, kind, rng.uniform(0.0, 1.0, size=6), speed, max_spin)


def random_states(rng, B, R, ell, kind, **kw):
    return np.stack([random_state(rng, R, ell, kind, **kw) for _ in range(B)])


# ---------------------------------------------------------------------------
# hypothesis strategies
# ---------------------------------------------------------------------------
def scene_params():
    """``(R, ell, mass, inertia)`` over the valid range: ``R`` in ``[0.5, 5]``,
    ``ell / R`` in ``[1e-6, 0.9999]`` (log-uniform or uniform) or exactly 0, ``mass`` in
    ``[0.1, 10]``, ``inertia`` from ``mass ell^2 1e-4`` through the default
    (``None``) to ``inf``."""
    from hypothesis import strategies as st

    @st.composite
    def params(draw):
        R = draw(st.floats(0.5, 5.0))
        kind = draw(st.sampled_from(["circle", "lens", "rotor-default", "rotor-scaled"]))
        if kind == "circle":
            ell = 0.0
        elif draw(st.booleans()):  # log-uniform: short sticks down to 1e-6 R
            ell = R * 10.0 ** draw(st.floats(-6.0, math.log10(0.9999)))
        else:  # uniform: long sticks (the paper's range) up to 0.9999 R
            ell = R * draw(st.floats(1e-6, 0.9999))
        mass = 10.0 ** draw(st.floats(-1.0, 1.0))
        if kind in ("circle", "rotor-default"):
            inertia = None
        elif kind == "lens":
            inertia = float("inf")
        else:
            inertia = mass * ell * ell * 10.0 ** draw(st.floats(-4.0, 2.0))
        return R, ell, mass, inertia

    return params()


def unit_six():
    from hypothesis import strategies as st

    return st.lists(st.floats(0.0, 1.0), min_size=6, max_size=6)


# ---------------------------------------------------------------------------
# independent physics (numpy)
# ---------------------------------------------------------------------------
def np_end_points(ell, state, dtype=np.float64):
    """``[P1, P2]`` (P1 = c + ell u, contact +1), shape ``(..., 2, 2)``."""
    s = np.asarray(state, dtype=dtype)
    c = s[..., 0:2]
    u = np.stack([np.cos(s[..., 2]), np.sin(s[..., 2])], axis=-1)
    return np.stack([c + ell * u, c - ell * u], axis=-2)


def np_flight(state, t, dtype=np.float64):
    """Free flight (alpha not wrapped); ``t`` may be an array (leading axis)."""
    s = np.asarray(state, dtype=dtype)
    t = np.asarray(t, dtype=dtype)[..., None]
    out = np.broadcast_to(s, t.shape[:-1] + (6,)).copy()
    out[..., 0] = s[0] + s[3] * t[..., 0]
    out[..., 1] = s[1] + s[4] * t[..., 0]
    out[..., 2] = s[2] + s[5] * t[..., 0]
    return out


def np_normal_speed(ell, state, end):
    """Normal velocity ``v . n + omega s_k`` of end ``end`` (+1/-1) along ``n = P/|P|``
    (positive: moving outwards, towards the wall)."""
    x, y, a, vx, vy, w = (float(v) for v in state)
    ux, uy = math.cos(a), math.sin(a)
    px, py = x + end * ell * ux, y + end * ell * uy
    wx, wy = vx - end * ell * w * uy, vy + end * ell * w * ux  # end velocity
    r = math.hypot(px, py)
    return (px * wx + py * wy) / r


def np_energy(mass, inertia, kind, state):
    s = np.asarray(state, dtype=np.float64)
    e = 0.5 * mass * (s[..., 3] ** 2 + s[..., 4] ** 2)
    if kind != "lens":
        e = e + 0.5 * inertia * s[..., 5] ** 2
    return e


def angle_diff(a, b):
    """``a - b`` reduced to ``[-pi, pi)``."""
    return np.remainder(np.asarray(a) - np.asarray(b) + np.pi, TWO_PI) - np.pi


def config_error(s1, s2, R):
    """Largest of ``|dx|/R``, ``|dy|/R`` and ``|d alpha mod 2 pi|`` (radians)."""
    s1, s2 = np.asarray(s1), np.asarray(s2)
    return np.maximum(
        np.max(np.abs(s1[..., 0:2] - s2[..., 0:2]), axis=-1) / R,
        np.abs(angle_diff(s1[..., 2], s2[..., 2])),
    )


def rotate_state(state, theta):
    """Rotate a state by ``theta`` about the origin: centre and velocity turn, alpha + theta."""
    s = np.asarray(state, dtype=np.float64)
    c, sn = math.cos(theta), math.sin(theta)
    out = s.copy()
    out[..., 0] = c * s[..., 0] - sn * s[..., 1]
    out[..., 1] = sn * s[..., 0] + c * s[..., 1]
    out[..., 3] = c * s[..., 3] - sn * s[..., 4]
    out[..., 4] = sn * s[..., 3] + c * s[..., 4]
    out[..., 2] = s[..., 2] + theta
    return out


def mirror_state(state):
    """Reflection y -> -y: ``(x, -y, -alpha, vx, -vy, -omega)`` (exact in floating point)."""
    s = np.array(state, dtype=np.float64)
    s[..., 1] *= -1.0
    s[..., 2] *= -1.0
    s[..., 4] *= -1.0
    s[..., 5] *= -1.0
    return s
