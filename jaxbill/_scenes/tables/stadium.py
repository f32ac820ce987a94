"""The Bunimovich stadium: the points within ``radius`` of a segment, two half-discs joined by flat sides.

The wall is one smooth piece, ``g = r^2 - dist(P, S)^2`` (area), ``S`` the
segment from ``(-L, 0)`` to ``(L, 0)``: with ``q = P - foot(P)``,
``q = (x - clip(x, -L, L), y)``, ``grad g = -2 q`` and ``Hess g = -2 diag([|x| > L], 1)``.
The gap is once continuously differentiable (its curvature jumps where the
flat sides meet the half-discs), so the search uses bounds on ``g''`` alone:
``Hess g`` lies between ``-2`` and ``0`` and ``|grad g| = 2 |q| <= 2 r``
inside (``jaxbill._scenes.tables.base.generic_curvature_bounds``). The quiet
region is the stadium of radius ``r - rho`` about the same segment.
"""

from __future__ import annotations

from typing import ClassVar

import jax
import jax.numpy as jnp
import numpy as np

from jaxbill._engine.validation import check_parameter, real_parameter
from jaxbill._scenes.tables.base import (
    KICK_NORMAL_SQUARED,
    Motion,
    Piece,
    Table,
    band_crossing,
    disc_crossing,
    generic_curvature_bounds,
)


def _crossings(px, py, vx, vy, half_length, radius) -> list:
    """The times ``(t_in, t_out)`` (``t >= 0``) the point ``p + v t`` spends in each convex part of the stadium
    of ``radius`` about the segment: the two discs and the rectangle."""
    left = disc_crossing(px + half_length, py, vx, vy, radius)
    right = disc_crossing(px - half_length, py, vx, vy, radius)
    x_in, x_out = band_crossing(px, vx, -half_length, half_length)
    y_in, y_out = band_crossing(py, vy, -radius, radius)
    return [left, right, (jnp.maximum(x_in, y_in), jnp.minimum(x_out, y_out))]


class CapsuleWall(Piece):
    """The wall at distance ``radius`` from the segment ``(-half_length, 0)``-``(half_length, 0)``.

    Leaves ``half_length >= 0`` and ``radius > 0`` (lengths, shape ``()``).
    The gap is ``radius^2 - |q|^2`` (area), ``q = P - foot(P)`` the point's
    offset from its nearest point of the segment: ``grad g = -2 q`` and
    ``Hess g = -2 diag([|x| > half_length], 1)``, between ``-2`` and ``0``. The
    gap is once continuously differentiable (its curvature jumps where the flat
    sides meet the half-discs): it bounds ``g''``, not ``g'''``.
    """

    half_length: jax.Array
    radius: jax.Array

    straight_exit: ClassVar[bool] = True

    def _offset(self, x, y):
        """``q = P - foot(P)``: the point's offset from its nearest point of the segment."""
        return x - jnp.clip(x, -self.half_length, self.half_length), y

    def gap(self, x, y):
        qx, qy = self._offset(x, y)
        return self.radius**2 - (qx * qx + qy * qy)

    def gradient(self, x, y):
        qx, qy = self._offset(x, y)
        return -2.0 * qx, -2.0 * qy

    def hessian_form(self, x, y, dx, dy):
        beyond = jnp.abs(x) > self.half_length
        return -2.0 * (jnp.where(beyond, dx * dx, 0.0) + dy * dy)

    @property
    def gap_scale(self):
        return self.radius**2

    def curvature_bounds(self, motion: Motion):
        return generic_curvature_bounds(motion, -2.0, 0.0, 2.0 * self.radius)

    def quiet_interval(self, motion: Motion):
        room = self.radius - motion.radius
        parts = _crossings(motion.cx, motion.cy, motion.vx, motion.vy, self.half_length, room)
        # The quiet stadium is convex: the times in it are the union of the times in its parts.
        t_in, t_out = jnp.inf, -jnp.inf
        for part_in, part_out in parts:
            visited = part_in < part_out
            t_in = jnp.where(visited, jnp.minimum(t_in, part_in), t_in)
            t_out = jnp.where(visited, jnp.maximum(t_out, part_out), t_out)
        empty = (t_in >= t_out) | (room <= 0.0)
        return jnp.where(empty, jnp.inf, t_in), jnp.where(empty, jnp.inf, t_out)

    def exit_time(self, px, py, vx, vy):
        # The latest time the line is in any part is when it leaves the (convex) stadium; a point on
        # or through the wall moving outwards is in no part after t = 0: it leaves at once.
        t = jnp.zeros_like(px)
        for part_in, part_out in _crossings(px, py, vx, vy, self.half_length, self.radius):
            visited = (part_in < part_out) & jnp.isfinite(part_out)
            t = jnp.where(visited, jnp.maximum(t, part_out), t)
        moving = (vx != 0.0) | (vy != 0.0)
        return jnp.where(moving, t, jnp.inf)

    def impulse_normal(self, x, y):
        qx, qy = self._offset(x, y)
        scale = np.sqrt(KICK_NORMAL_SQUARED) / self.radius
        return scale * qx, scale * qy

    def boundary_coordinate(self, x, y):
        """Arc length anticlockwise from ``(L + r, 0)``: the right half-disc, the top side, the left half-disc,
        the bottom side."""
        L, r = self.half_length, self.radius
        quarter = 0.5 * jnp.pi * r
        right = r * jnp.mod(jnp.arctan2(y, x - L) + 0.5 * jnp.pi, 2.0 * jnp.pi) - quarter
        right = jnp.where(right < 0.0, right + 2.0 * jnp.pi * r + 4.0 * L, right)
        top = quarter + (L - x)
        left = quarter + 2.0 * L + r * (jnp.mod(jnp.arctan2(y, x + L), 2.0 * jnp.pi) - 0.5 * jnp.pi)
        bottom = 3.0 * quarter + 2.0 * L + (x + L)
        flat = jnp.where(y > 0.0, top, bottom)
        return jnp.where(x > L, right, jnp.where(x < -L, left, flat))

    @property
    def length(self):
        return 2.0 * jnp.pi * self.radius + 4.0 * self.half_length

    def point_at(self, s):
        L, r = self.half_length, self.radius
        quarter = 0.5 * jnp.pi * r
        # From the right end anticlockwise: a quarter of the right half-disc, the top side, the left
        # half-disc, the bottom side, the last quarter of the right half-disc.
        bounds = (quarter, quarter + 2.0 * L, 3.0 * quarter + 2.0 * L, 3.0 * quarter + 4.0 * L)
        right = (L + r * jnp.cos(s / r), r * jnp.sin(s / r))
        top = (L - (s - bounds[0]), r + 0.0 * s)
        turn = (s - bounds[1]) / r + 0.5 * jnp.pi
        left = (-L + r * jnp.cos(turn), r * jnp.sin(turn))
        bottom = (-L + (s - bounds[2]), -r + 0.0 * s)
        last = (s - bounds[3]) / r - 0.5 * jnp.pi
        lower_right = (L + r * jnp.cos(last), r * jnp.sin(last))
        parts = (right, top, left, bottom, lower_right)
        x, y = lower_right
        for limit, part in reversed(list(zip(bounds, parts[:4]))):
            x, y = jnp.where(s < limit, part[0], x), jnp.where(s < limit, part[1], y)
        return x, y


class Stadium(Table):
    """Bunimovich's stadium: two half-discs of radius ``radius`` joined by flat sides of length ``2 half_length``.

    Args:
        half_length: half the length of the flat sides, ``>= 0`` (length; 0: the circle).
        radius: the half-discs' radius, ``> 0`` (length).
    """

    half_length: jax.Array
    radius: jax.Array

    name: ClassVar[str] = "the stadium"

    def __init__(self, half_length, radius):
        self.half_length, self.radius = (jnp.asarray(v, dtype=jnp.float64) for v in (half_length, radius))

    def check(self) -> None:
        L = real_parameter("half_length", self.half_length)
        check_parameter("half_length", L, np.isfinite(L) & (L >= 0), ">= 0 and finite (half a flat side)")
        r = real_parameter("radius", self.radius)
        check_parameter("radius", r, np.isfinite(r) & (r > 0), "> 0 and finite (the half-discs' radius)")

    def parameters_are_valid(self):
        return (self.half_length >= 0) & jnp.isfinite(self.half_length) & (self.radius > 0) & jnp.isfinite(self.radius)

    @property
    def pieces(self):
        return (CapsuleWall(self.half_length, self.radius),)

    @property
    def piece_names(self):
        return ("the stadium",)

    @property
    def size(self):
        return self.half_length + self.radius

    @property
    def extent(self):
        reach = self.half_length + self.radius
        return -reach, reach, -self.radius, self.radius

    @property
    def diameter(self):
        return 2.0 * (self.half_length + self.radius)

    @property
    def width(self):
        return 2.0 * self.radius
