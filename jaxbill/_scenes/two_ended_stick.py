"""What every planar stick scene shares: its direction, its free flight, and the contact of its two ends.

A stick's ends are ``P1 = c + ell u`` (gap index 0, contact ``+1``) and
``P2 = c - ell u`` (index 1, contact ``-1``), ``u = (cos alpha, sin alpha)``.
The scenes (``StickInCircle``, ``StickInEllipse``) differ in their table, hence
in their gaps, approach speeds and impulse; these functions take those as
arguments; their impulse is one and the same reflection (``reflect``), about
their own wall normal. States are components ``(x, y, alpha, vx, vy, omega)``.
"""

from __future__ import annotations

import math
from collections.abc import Callable

import jax.numpy as jnp

from jaxbill._engine.first_root import select
from jaxbill._engine.step import computed_once, cos_sin, rarely, where, wrapped_angle
from jaxbill._scenes.protocols import NO_CONTACT, SEVERAL_CONTACTS

END_SIGNS = (1.0, -1.0)  # gap index 0 -> end P1 (+1), index 1 -> end P2 (-1)


def contact_codes(point: bool) -> tuple[int, ...]:
    """A scene's ``contact_codes``: none (0), end P1 or P2 (1, -1), both at once (2); a point only 1 and 0."""
    return (NO_CONTACT, 1) if point else (-1, NO_CONTACT, 1, SEVERAL_CONTACTS)


# A second end within this many ulps of the gap scale of the wall at a contact
# touches it at the same instant (a corner): both impulses are applied in one event.
CORNER_ULPS = 64.0

# An impulse's normal is scaled so that its squared norm sits near this value (see
# ``StickInCircle.kick``): mid-binade, with a reciprocal of no short binary period.
KICK_NORMAL_SQUARED = math.pi / 2


def direction(point: bool, alpha):
    """``(cos alpha, sin alpha)``; ``(1, 0)`` for a point (``ell = 0``), which never needs it."""
    if point:
        return jnp.ones_like(alpha), jnp.zeros_like(alpha)
    return cos_sin(alpha)


def flight(turns: bool, state: tuple, t) -> tuple:
    """Free flight of the components for time ``t``; ``alpha`` wrapped into ``[-pi, pi)``.

    Wrapping keeps ``cos``/``sin`` of ``alpha`` exact to rounding however long
    the run: an unwrapped angle of ``1e7`` radians would carry ``1e-9``
    absolute error into every contact. A stick that never turns keeps ``alpha``.
    """
    x, y, alpha, vx, vy, omega = state
    if turns:
        alpha = wrapped_angle(alpha + omega * t)
    return x + vx * t, y + vy * t, alpha, vx, vy, omega


def end_motion(state: tuple, u: tuple, arm) -> tuple:
    """The end ``P = c + arm u`` (``arm = +-ell``) and its velocity ``dP/dt = v + arm omega (-uy, ux)``:
    ``(px, py, ex, ey)``."""
    x, y, _, vx, vy, omega = state
    ux, uy = u
    return x + arm * ux, y + arm * uy, vx - arm * omega * uy, vy + arm * omega * ux


def spin_term(point: bool, omega, term):
    """``term`` (``I omega^2 / 2`` or ``I omega``); for a point 0 where ``omega = 0`` (``I = inf``: not NaN)."""
    return jnp.where(omega == 0.0, 0.0, term) if point else term


def resolve_two_ends(
    kick: Callable, end_gap_and_closing: Callable, end_speeds: Callable, state: tuple, index, u: tuple, gap_scale
):
    """The impulse at end ``index`` (0: P1, 1: P2) touching the wall, and a simultaneous second contact.

    The scene's ``kick(state, end_sign, u)``; ``end_gap_and_closing(state, u,
    end_sign)``: one end's gap and a number with the sign of its approach
    speed (the speed times a positive factor: no square root, no division);
    ``end_speeds(state, u)``: both ends' approach speeds (a 2-tuple). If the
    other end is on the wall too (within ``CORNER_ULPS`` ulps of
    ``gap_scale``) and approaching, the faster-approaching end is kicked first
    and the other after it if it still approaches: a deterministic rule for an
    ill-posed event, reported as contact 2. Returns ``(state, contact)``.

    Only the other end is examined unless it is at a corner: its approach
    speed's sign costs a few products, where both ends' normalised speeds cost
    two square roots and two divisions per collision (XLA:CPU computes
    ``a / sqrt(b)`` as ``a * rsqrt(b)``, which it does not vectorise: a lockstep
    batch of lenses spent a third of its time there).
    """
    other = 1 - index
    # A lambda, not the scene's bound method: a conditional hashes its function, a scene is not hashable.
    gap_other, closing_other = computed_once(
        lambda s, d, sign: end_gap_and_closing(s, d, sign), state, u, select(END_SIGNS, other)
    )
    corner = (gap_other <= CORNER_ULPS * jnp.finfo(jnp.float64).eps * gap_scale) & (closing_other > 0.0)

    def one_end(state):
        return kick(state, select(END_SIGNS, index), u), jnp.where(index == 0, jnp.int32(1), jnp.int32(-1))

    def both_ends(state):
        speeds = end_speeds(state, u)
        first = jnp.where(select(speeds, other) > select(speeds, index), other, index)
        second = 1 - first
        kicked = kick(state, select(END_SIGNS, first), u)
        still_approaching = select(end_speeds(kicked, u), second) > 0.0
        kicked = where(still_approaching, kick(kicked, select(END_SIGNS, second), u), kicked)
        return kicked, jnp.int32(SEVERAL_CONTACTS) + jnp.zeros_like(index)

    return rarely(corner, both_ends, one_end, state)


def reflect(state: tuple, arm, u: tuple, normal: tuple, mass_ratio) -> tuple:
    """The elastic frictionless impulse at the contact point ``c + arm u``: a mass-metric reflection.

    ``normal = (nx, ny)`` is the wall's outward normal at the contact,
    unnormalised (any positive multiple gives the same impulse; the scenes
    scale it so that ``|N|^2`` sits near ``KICK_NORMAL_SQUARED``);
    ``mass_ratio = M / I`` (0 where the spin is never kicked). With
    ``s = arm (u x N)``, ``v_n = v . N + omega s`` and
    ``w = 2 v_n / (|N|^2 + (M/I) s^2)``: ``v' = v - w N``,
    ``omega' = omega - w (M/I) s``. The energy is conserved exactly for
    whatever ``N`` rounding produced. Every table's impulse is this one: the
    circle's and the ellipse's differ only in ``N``.
    """
    x, y, alpha, vx, vy, omega = state
    ux, uy = u
    nx, ny = normal
    s = arm * (ux * ny - uy * nx)
    v_n = vx * nx + vy * ny + omega * s
    change = 2.0 * v_n / (nx * nx + ny * ny + mass_ratio * (s * s))
    return x, y, alpha, vx - change * nx, vy - change * ny, omega - (change * mass_ratio) * s
