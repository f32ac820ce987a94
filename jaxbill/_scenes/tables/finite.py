"""Finite walls: a segment of a line and an arc of a circle, the boundary of a table that is a union of parts.

A table that is not an intersection (Bunimovich's mushroom: a half-disc on a
rectangle) has a boundary made of pieces that each end somewhere: the cap's
arc, the flat parts of its rim either side of the stem, the stem's sides and
foot. A point inside such a table leaves it, along a straight line, at its
first crossing of any of these pieces from inside to outside, so each piece
gives the first time the line crosses *the piece itself* outwards
(``exit_time``), ``inf`` if it crosses the piece's line or circle only outside
the piece's ends; the scene takes the smallest, as for any table.

Why each piece's end is padded. Where two pieces meet (a corner of the table,
convex or re-entrant), a line through the corner crosses both at the same
instant, and the two crossing points are computed separately: each may round
to just beyond its piece's end, and the point would escape through the corner.
So a crossing counts when it lies within ``pad`` (a length, of the order of
``WALL_TOLERANCE`` times the table's size) beyond either end: a line that passes
a corner closer than that is treated as hitting it, and the corner rule
resolves both impulses.

The gap. A piece's gap is its line's or circle's gap where the point projects
onto the piece itself, more than ``pad`` from its ends (within the segment,
within the arc's angles), and otherwise the distance to its nearer end (times
``scale``): zero only on the piece, and never negative in a table whose parts
meet as the mushroom's do. The margin matters at a re-entrant corner: a point
on the stem's side, through it by rounding, projects onto the end of the rim
beside it, on the rim's outer side; with the line's gap it would count as
through the rim. The gradient and the impulse normal are the line's or circle's.
Whether a point is in the table is the table's ``clearance`` (a union's: the
largest over its parts), not the sign of these gaps.

Only a point particle moves in such a table (``jb.BodyInTable`` refuses other
bodies: a side of a body could catch a re-entrant corner between its contacts).
"""

from __future__ import annotations

import math
from typing import ClassVar

import jax
import jax.numpy as jnp
import numpy as np

from jaxbill._scenes.tables.base import KICK_NORMAL_SQUARED, Motion, Piece
from jaxbill._scenes.tables.flat import StraightWallBounds


class Segment(StraightWallBounds, Piece):
    """The segment from ``(x0, y0)`` to ``(x1, y1)`` with the table on its left: a finite flat wall.

    Fields (lengths): the ends, ``scale`` (the gap's unit per length), ``unit``
    (the table's gap unit) and ``pad`` (how far beyond an end a crossing still
    counts). The gap is ``scale`` times the distance from the segment's line
    where the point projects onto the segment more than ``pad`` from its ends,
    else ``scale`` times the distance to the nearer end; ``grad g = -scale n``, ``n`` the unit outward normal (to
    the right of the direction from the first end to the second).
    """

    x0: jax.Array | float
    y0: jax.Array | float
    x1: jax.Array | float
    y1: jax.Array | float
    scale: jax.Array | float
    unit: jax.Array | float
    pad: jax.Array | float

    straight_exit: ClassVar[bool] = True

    @property
    def _frame(self):
        """``(ex, ey, nx, ny, length)``: the unit direction from the first end, the outward normal, the length."""
        dx, dy = self.x1 - self.x0, self.y1 - self.y0
        length = jnp.sqrt(dx * dx + dy * dy)
        ex, ey = dx / length, dy / length
        return ex, ey, ey, -ex, length

    def gap(self, x, y):
        ex, ey, nx, ny, length = self._frame
        qx, qy = x - self.x0, y - self.y0
        along = qx * ex + qy * ey
        line = -(qx * nx + qy * ny)
        rx, ry = x - self.x1, y - self.y1
        ends = jnp.sqrt(jnp.minimum(qx * qx + qy * qy, rx * rx + ry * ry))
        inner = (along >= self.pad) & (along <= length - self.pad)
        return self.scale * jnp.where(inner, line, ends)

    def gradient(self, x, y):
        _, _, nx, ny, _ = self._frame
        return -self.scale * nx, -self.scale * ny

    def exit_time(self, px, py, vx, vy):
        """First ``t >= 0`` at which ``P + v t`` crosses the segment outwards (``inf``: never).

        A point through the line by less than ``pad`` and moving outwards
        crosses at once (0), if it lies on the segment; one farther beyond the
        line is elsewhere in the table (the line extends past the segment) and
        its crossing is in the past.
        """
        ex, ey, nx, ny, length = self._frame
        qx, qy = px - self.x0, py - self.y0
        room = -(qx * nx + qy * ny)
        closing = vx * nx + vy * ny
        leaving = (closing > 0.0) & (room >= -self.pad)
        t = jnp.maximum(room, 0.0) / jnp.where(leaving, closing, 1.0)
        along = (qx + vx * t) * ex + (qy + vy * t) * ey
        on_piece = (along >= -self.pad) & (along <= length + self.pad)
        return jnp.where(leaving & on_piece, t, jnp.inf)

    def impulse_normal(self, x, y):
        _, _, nx, ny, _ = self._frame
        factor = np.sqrt(KICK_NORMAL_SQUARED)
        return factor * nx, factor * ny

    def plane(self):
        _, _, nx, ny, _ = self._frame
        return nx, ny, nx * self.x0 + ny * self.y0, self.scale

    def boundary_coordinate(self, x, y):
        ex, ey, _, _, _ = self._frame
        return (x - self.x0) * ex + (y - self.y0) * ey

    def tangent(self, x, y):
        ex, ey, _, _, _ = self._frame
        return ex + jnp.zeros_like(x), ey + jnp.zeros_like(x)

    @property
    def length(self):
        return self._frame[4]

    def point_at(self, s):
        ex, ey, _, _, _ = self._frame
        return self.x0 + s * ex, self.y0 + s * ey


def _cos_sin(angle) -> tuple:
    """``(cos, sin)`` of an angle: Python numbers for a Python number (a table's fixed angles, which a Pallas
    kernel must not see as constant arrays), JAX arrays otherwise."""
    if isinstance(angle, (int, float)):
        return math.cos(angle), math.sin(angle)
    return jnp.cos(angle), jnp.sin(angle)


class Arc(Piece):
    """An arc of the circle of ``radius`` about ``(cx, cy)``, the table inside it: a finite focusing wall.

    Fields: the centre and ``radius`` (lengths), ``start`` (the angle of its
    first end, radians) and ``span`` (its angle, anticlockwise, ``0 < span < 2
    pi``), ``scale``, ``unit`` and ``pad`` as ``Segment``'s. The gap is
    ``scale (r^2 - |P - c|^2) / (2 r)`` (about ``scale`` times the distance
    inside the circle) where the direction of ``P - c`` lies within the arc,
    else ``scale`` times the distance to the nearer end; ``Hess g = -(scale / r) I``.
    """

    cx: jax.Array | float
    cy: jax.Array | float
    radius: jax.Array
    start: jax.Array | float
    span: jax.Array | float
    scale: jax.Array | float
    unit: jax.Array | float
    pad: jax.Array | float

    straight_exit: ClassVar[bool] = True
    bounds_jerk: ClassVar[bool] = True

    @property
    def _middle(self):
        """``(mx, my, cos_half)``: the unit direction of the arc's midpoint from the centre, ``cos(span / 2)``."""
        mx, my = _cos_sin(self.start + 0.5 * self.span)
        return mx, my, _cos_sin(0.5 * self.span)[0]

    def _ends(self):
        r = self.radius
        (c0, s0), (c1, s1) = _cos_sin(self.start), _cos_sin(self.start + self.span)
        return (self.cx + r * c0, self.cy + r * s0), (self.cx + r * c1, self.cy + r * s1)

    def gap(self, x, y):
        qx, qy = x - self.cx, y - self.cy
        mx, my, cos_half = self._middle
        norm = jnp.sqrt(qx * qx + qy * qy)
        within = (qx * mx + qy * my) - norm * cos_half >= self.pad
        circle = 0.5 * (self.radius * self.radius - (qx * qx + qy * qy)) / self.radius
        (ax, ay), (bx, by) = self._ends()
        ends = jnp.sqrt(jnp.minimum((x - ax) ** 2 + (y - ay) ** 2, (x - bx) ** 2 + (y - by) ** 2))
        return self.scale * jnp.where(within, circle, ends)

    def gradient(self, x, y):
        factor = -self.scale / self.radius
        return factor * (x - self.cx), factor * (y - self.cy)

    def hessian_form(self, x, y, dx, dy):
        return -(self.scale / self.radius) * (dx * dx + dy * dy)

    @property
    def gap_scale(self):
        return self.unit

    def curvature_bounds(self, motion: Motion):
        # A point (the only body in a union) flies straight: g'' = -scale |v|^2 / r.
        curve = self.scale * (motion.vx * motion.vx + motion.vy * motion.vy) / self.radius
        return curve, -curve

    def jerk_bound(self, motion: Motion):
        return jnp.zeros_like(motion.vx)

    def exit_time(self, px, py, vx, vy):
        """First ``t >= 0`` at which ``P + v t`` crosses the arc outwards (leaves the circle on the arc).

        The circle's exit root, in ``DiscWall.exit_time``'s cancellation-free
        forms, for a point inside the circle or through it by less than ``pad``
        (a point on the rim moving outwards leaves at once); a point farther
        outside (a part of the table beyond the circle) crosses outwards only
        after it has entered, at the far root, if its line meets the circle
        ahead of it. The crossing counts when it lies on the arc (within ``pad``).
        """
        qx, qy = px - self.cx, py - self.cy
        r = self.radius
        speed2 = vx * vx + vy * vy
        b = qx * vx + qy * vy
        gap = r * r - (qx * qx + qy * qy)
        disc = b * b + speed2 * gap
        root = jnp.sqrt(jnp.maximum(disc, 0.0))
        near = gap >= -2.0 * r * self.pad
        inward = jnp.where(disc < 0.0, -2.0 * b, root - b)
        outward = b > 0.0
        t = jnp.where(outward, gap, inward) / jnp.where(outward, b + root, speed2)
        t = jnp.maximum(t, 0.0)
        # Far outside: only a line heading for the circle (b < 0) and meeting it crosses it outwards later.
        reached = near | ((b < 0.0) & (disc >= 0.0))
        hx, hy = qx + vx * t, qy + vy * t
        mx, my, cos_half = self._middle
        on_piece = hx * mx + hy * my >= r * cos_half - self.pad
        return jnp.where((speed2 > 0.0) & reached & on_piece, t, jnp.inf)

    def impulse_normal(self, x, y):
        factor = np.sqrt(KICK_NORMAL_SQUARED) / self.radius
        return factor * (x - self.cx), factor * (y - self.cy)

    def boundary_coordinate(self, x, y):
        """Arc length anticlockwise from the arc's first end."""
        angle = jnp.arctan2(y - self.cy, x - self.cx)
        return self.radius * jnp.mod(angle - self.start, 2.0 * jnp.pi)

    def tangent(self, x, y):
        qx, qy = x - self.cx, y - self.cy
        norm = jnp.sqrt(qx * qx + qy * qy)
        return -qy / norm, qx / norm

    @property
    def length(self):
        return self.radius * self.span

    def point_at(self, s):
        angle = self.start + s / self.radius
        return self.cx + self.radius * jnp.cos(angle), self.cy + self.radius * jnp.sin(angle)
