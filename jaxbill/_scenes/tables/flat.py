"""Flat walls: the half-plane ``n . P <= d``, and the strip between two parallel walls.

A flat wall's gap ``s (d - n . P)`` is linear in the point: its Hessian is 0, so
along a flight ``g'' = -s n . P''`` and ``g''' = -s n . P'''``, with
``|P''| = omega^2 |r|`` and ``|P'''| = |omega|^3 |r|`` for a contact point at
the offset ``r`` from the centre: ``|g''| <= s omega^2 rho`` and
``|g'''| <= s |omega|^3 rho``. No point within ``rho`` of the centre can touch
the wall while ``n . c < d - rho``; a point on a straight line reaches it at
``(d - n . P) / (n . v)``.
"""

from __future__ import annotations

from typing import TYPE_CHECKING, ClassVar

import jax
import jax.numpy as jnp
import numpy as np

from jaxbill._engine.validation import check_parameter, real_parameter
from jaxbill._scenes.tables.base import KICK_NORMAL_SQUARED, Motion, Piece, Table, band_crossing


class StraightWallBounds:
    """What every straight wall answers alike (the module's docstring derives it): no curvature, so its bounds
    along a flight come from the contact point's turn about the centre alone. A mixin of methods only, beside
    ``Piece``: the wall's own fields ``scale`` (the gap's unit per length) and ``unit`` (the table's gap unit)
    stay where its constructor puts them."""

    if TYPE_CHECKING:
        scale: jax.Array | float
        unit: jax.Array | float

    bounds_jerk: ClassVar[bool] = True
    flat: ClassVar[bool] = True

    def hessian_form(self, x, y, dx, dy):
        return 0.0 * dx

    @property
    def gap_scale(self):
        return self.unit

    def curvature_bounds(self, motion: Motion):
        turn = self.scale * (motion.omega * motion.omega) * motion.radius
        return turn, turn

    def jerk_bound(self, motion: Motion):
        spin = jnp.abs(motion.omega)
        return self.scale * (spin * spin * spin) * motion.radius


class HalfPlane(StraightWallBounds, Piece):
    """The flat wall ``n . P <= d``: ``n = (nx, ny)`` its unit outward normal, ``(sx, sy)`` a point on it (the
    origin of its arc length, which runs along ``(-ny, nx)``); the gap is ``scale (d - n . P)``, in units of
    ``unit``."""

    nx: jax.Array | float
    ny: jax.Array | float
    d: jax.Array | float
    sx: jax.Array | float
    sy: jax.Array | float
    scale: jax.Array | float
    unit: jax.Array | float
    # The length of the side this wall is (``inf``: a whole line).
    side: jax.Array | float

    straight_exit: ClassVar[bool] = True

    def gap(self, x, y):
        return self.scale * (self.d - (self.nx * x + self.ny * y))

    def gradient(self, x, y):
        # Constants where the wall's parameters are: a Pallas kernel lowers no operation on a constant array.
        return -self.scale * self.nx, -self.scale * self.ny

    def quiet_interval(self, motion: Motion):
        along = self.nx * motion.cx + self.ny * motion.cy
        speed = self.nx * motion.vx + self.ny * motion.vy
        return band_crossing(along, speed, -jnp.inf, self.d - motion.radius)

    def exit_time(self, px, py, vx, vy):
        closing = self.nx * vx + self.ny * vy
        room = jnp.maximum(self.d - (self.nx * px + self.ny * py), 0.0)
        leaving = closing > 0.0
        return jnp.where(leaving, room / jnp.where(leaving, closing, 1.0), jnp.inf)

    def impulse_normal(self, x, y):
        scale = np.sqrt(KICK_NORMAL_SQUARED)
        return scale * self.nx, scale * self.ny

    def plane(self):
        return self.nx, self.ny, self.d, self.scale

    def boundary_coordinate(self, x, y):
        return (x - self.sx) * (-self.ny) + (y - self.sy) * self.nx

    def tangent(self, x, y):
        return -self.ny, self.nx

    @property
    def length(self):
        return self.side

    def point_at(self, s):
        return self.sx - s * self.ny, self.sy + s * self.nx


def wall_through(x0, y0, x1, y1, unit) -> HalfPlane:
    """The flat wall through ``(x0, y0)`` and ``(x1, y1)`` with the table on its left (anticlockwise order)."""
    ex, ey = x1 - x0, y1 - y0
    length = jnp.sqrt(ex * ex + ey * ey)
    nx, ny = ey / length, -ex / length
    return HalfPlane(nx, ny, nx * x0 + ny * y0, x0, y0, 1.0, unit, length)


class Strip(Table):
    """The strip between two flat walls, ``0 <= y <= h``: the floor ``y = 0`` and the ceiling ``y = h``.

    Args:
        h: the distance between the walls, ``h > 0`` (length).

    The gaps are distances (``y`` to the floor, ``h - y`` to the ceiling), in
    units of ``h``.
    """

    h: jax.Array

    name: ClassVar[str] = "the walls"
    section_names: ClassVar[tuple[str, ...]] = ("floor",)
    has_centre: ClassVar[bool] = False

    def __init__(self, h):
        self.h = jnp.asarray(h, dtype=jnp.float64)

    def check(self) -> None:
        h = real_parameter("h", self.h)
        check_parameter("h", h, np.isfinite(h) & (h > 0), "> 0 and finite (the distance between the walls)")

    def parameters_are_valid(self):
        return (self.h > 0) & jnp.isfinite(self.h)

    @property
    def pieces(self):
        # Python numbers, not arrays: inside a Pallas kernel an array built from them is a constant,
        # and Triton lowers no operation on one.
        floor = HalfPlane(0.0, -1.0, 0.0, 0.0, 0.0, 1.0, self.h, np.inf)
        ceiling = HalfPlane(0.0, 1.0, self.h, 0.0, self.h, 1.0, self.h, np.inf)
        return floor, ceiling

    @property
    def piece_names(self):
        return ("the floor", "the ceiling")

    @property
    def size(self):
        return self.h

    @property
    def extent(self):
        infinite = jnp.full_like(self.h, jnp.inf)
        return -infinite, infinite, jnp.zeros_like(self.h), self.h

    @property
    def width(self):
        return self.h
