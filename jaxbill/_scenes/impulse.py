"""The impulse at a contact: one mass-metric reflection for every body and table, and the rule for several at once.

In the configuration ``q = (x, y, alpha)`` with the mass matrix
``diag(M, M, I)``, the gap of a contact at the offset ``r`` from the centre,
against a wall of outward normal ``N`` there, has the gradient
``-(N, s)`` (times a positive factor), with the lever ``s = N . r_alpha``
(``r_alpha = dr/dalpha``; ``r x N`` for a body turning anticlockwise). The
frictionless elastic impulse is the reflection about it in the metric
``M^-1``: with ``v_n = v . N + omega s`` (``> 0`` approaching) and
``w = 2 v_n / (|N|^2 + (M/I) s^2)``,

    v' = v - w N,        omega' = omega - w (M/I) s.

Any positive multiple of ``N`` gives the same impulse, and the energy is
conserved exactly for whatever ``N`` rounding produced (the walls scale it so
that ``|N|^2`` sits near ``pi/2``: see ``jaxbill._scenes.tables.base``). In
the form above the mass enters only through the one ratio ``M/I`` (0 for a
point or a body that never turns): a rounded ``1/M`` applied twice biased the
energy.

Several contacts at once (a corner: two corners of a polygon landing flat, a
point in a corner of two sides, both ends of a stick on the wall): the contacts
within ``CORNER_ULPS`` ulps of the gap's unit of the wall and approaching it
are resolved one after another, the fastest-approaching first, each of the
others in the order of their approach speeds before the event, and only if it
still approaches when its turn comes (at most ``MAX_SIMULTANEOUS`` of them: a
further one that still approaches takes its impulse in the next collision, at
``dt = 0``). An ill-posed event gets a deterministic answer, reported as the
contact code ``SEVERAL_CONTACTS``; for two contacts it is: the faster one,
then the other if it still approaches.
"""

from __future__ import annotations

import functools

import jax.numpy as jnp

from jaxbill._engine.first_root import select
from jaxbill._engine.step import rarely, where
from jaxbill._scenes.protocols import SEVERAL_CONTACTS

# A second contact within this many ulps of the gap's unit touches at the same instant.
CORNER_ULPS = 64.0
# At most this many contacts take their impulse in one event (two corners of a square landing flat in a
# corner of the table); any other that still approaches takes it in the next collision, at dt = 0. The
# pass is unrolled: every turn scans every contact, so its size, not the number of gaps, must stay small.
MAX_SIMULTANEOUS = 3


def reflect(state: tuple, lever, normal: tuple, mass_ratio) -> tuple:
    """The elastic frictionless impulse of a contact with lever ``s`` against the outward ``normal`` (components)."""
    x, y, alpha, vx, vy, omega = state
    nx, ny = normal
    v_n = vx * nx + vy * ny + omega * lever
    change = 2.0 * v_n / (nx * nx + ny * ny + mass_ratio * (lever * lever))
    return x, y, alpha, vx - change * nx, vy - change * ny, omega - (change * mass_ratio) * lever


def approach_speed(state: tuple, lever, normal: tuple):
    """The contact's normal speed ``(v . N + omega s) / |N|``: ``> 0`` approaching the wall."""
    _, _, _, vx, vy, omega = state
    nx, ny = normal
    return (vx * nx + vy * ny + omega * lever) / jnp.sqrt(nx * nx + ny * ny)


def several_at_once(gaps: tuple, closings: tuple, index, gap_scale):
    """Whether any contact other than ``index`` is on its wall (within ``CORNER_ULPS``) and approaching it."""
    limit = CORNER_ULPS * jnp.finfo(jnp.float64).eps * gap_scale
    several = jnp.zeros(jnp.shape(index), bool)
    for k, (gap, closing) in enumerate(zip(gaps, closings)):
        several = several | ((index != k) & (gap <= limit) & (closing > 0.0))
    return several


def one_after_another(state: tuple, index, touching: tuple, speeds: tuple, kick, speed_of) -> tuple:
    """Kick the touching contacts one after another: contact ``index`` first unless another is faster, then
    each in the order of ``speeds`` (their approach speeds before the event, the first of equals first), if it
    still approaches (``speed_of(state, k)``) when its turn comes.

    ``touching``: per contact, whether it takes part; ``kick(state, k)``: the impulse of contact ``k`` (traced).
    """
    count = len(touching)
    waiting = tuple(t | (index == k) for k, t in enumerate(touching))
    for turn in range(min(count, MAX_SIMULTANEOUS)):
        if turn == 0:
            found, best, best_speed = jnp.ones(jnp.shape(index), bool), index, select(speeds, index)
        else:
            found = jnp.zeros(jnp.shape(index), bool)
            best, best_speed = jnp.zeros(jnp.shape(index), jnp.int32), jnp.zeros(jnp.shape(index))
        for k in range(count):
            faster = waiting[k] & (~found | (speeds[k] > best_speed))
            best_speed = jnp.where(faster, speeds[k], best_speed)
            best = jnp.where(faster, jnp.int32(k), best)
            found = found | faster
        go = found & (speed_of(state, best) > 0.0) if turn else found
        state = where(go, kick(state, best), state)
        waiting = tuple(w & (best != k) for k, w in enumerate(waiting))
    return state


def contact_resolution(contacts, kick, speed_of, state: tuple, index, gap_scale, codes: tuple):
    """``(state, contact code)`` after the impulse(s) of a collision in contact ``index``.

    ``contacts(state) -> (gaps, closings, speeds)``: per contact, its gap, a
    number of the sign of its approach speed, and its approach speed; ``kick(state, k)``
    and ``speed_of(state, k)`` for a traced contact ``k``. A single contact
    (the usual case) costs one impulse; the rare simultaneous ones are computed
    only where they happen (``rarely``).
    """
    if len(codes) == 1:
        return kick(state, index), jnp.full(jnp.shape(index), codes[0], jnp.int32)
    gaps, closings, speeds = contacts(state)
    several = several_at_once(gaps, closings, index, gap_scale)
    code = select(tuple(jnp.int32(c) for c in codes), index)

    def one(s):
        return kick(s, index), code

    def all_of_them(s):
        limit = CORNER_ULPS * jnp.finfo(jnp.float64).eps * gap_scale
        touching = tuple((g <= limit) & (c > 0.0) for g, c in zip(gaps, closings))
        kicked = one_after_another(s, index, touching, speeds, kick, speed_of)
        return kicked, jnp.int32(SEVERAL_CONTACTS) + jnp.zeros_like(index)

    return rarely(several, all_of_them, one, state)


def pairs_resolution(
    state: tuple, index, pairs: tuple, contacts: tuple, kick_wall, speed_of_wall, kick, gap_scale, codes
):
    """``(state, contact code)`` of a point particle's collision in wall ``index`` of a table whose walls meet two
    at a time, at the corners ``pairs`` (static ``(i, j)`` of wall indices): the corner rule of
    ``contact_resolution`` for the only events a point can have there, one wall or two at once.

    ``contacts = (gaps, closings, speeds)`` per wall; ``kick_wall(s, i)`` and
    ``speed_of_wall(s, i)`` for a static wall ``i``, ``kick(s, index)`` for the
    traced one. At a corner the two impulses apply one after the other, the
    touched wall's first unless the other approaches faster, the second only
    if it still approaches: the general rule's order for two contacts. Each
    corner's impulses take a few flops with no selection among the walls, where
    the general rule orders every wall against every other (its code, and its
    compile time, grow with the square of the walls).
    """
    gaps, closings, speeds = contacts
    limit = CORNER_ULPS * jnp.finfo(jnp.float64).eps * gap_scale
    events = []
    for i, j in pairs:
        for touched, other in ((i, j), (j, i)):
            events.append(((index == touched) & (gaps[other] <= limit) & (closings[other] > 0.0), touched, other))
    several = functools.reduce(jnp.logical_or, [condition for condition, _, _ in events])
    code = select(tuple(jnp.int32(c) for c in codes), index)

    def one(s):
        return kick(s, index), code

    def at_corners(s):
        out = kick(s, index)
        for condition, touched, other in events:
            orders = []
            for first, second in ((touched, other), (other, touched)):
                kicked = kick_wall(s, first)
                again = kick_wall(kicked, second)
                orders.append(where(speed_of_wall(kicked, second) > 0.0, again, kicked))
            other_first = speeds[other] > speeds[touched]
            out = where(condition, where(other_first, orders[1], orders[0]), out)
        return out, jnp.where(several, jnp.int32(SEVERAL_CONTACTS), code)

    return rarely(several, at_corners, one, state)
