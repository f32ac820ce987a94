"""Dispersing walls: the outside of a disc and of an ellipse, obstacles a point particle bounces off.

A table with an obstacle in it (Sinai's billiard, the Lorentz gas) is still the
intersection of its pieces, but no longer convex: the obstacle's wall curves
towards the table. Its gap is positive *outside* the obstacle, and along a
straight flight its second derivative is positive (``g'' = d^T Hess g d`` with
a positive definite Hessian): the wall disperses, neighbouring rays diverge after
a bounce, which is the source of the chaos of these billiards.

Only a point particle may move among obstacles (``Piece.dispersing``; the scene
refuses any other body): a body that touches walls at its contact points would
need contacts anywhere along its sides against a wall that bulges into it.

For a point on a straight line the gap is a quadratic in time, so each
obstacle gives its first-entry time in closed form (``exit_time``, the time the
point leaves the table through it), and a point among obstacles compiles no root
search. Units: the gap is ``scale`` times a length (near the wall, ``scale``
times the distance to it), so that the obstacle shares its table's gap unit.
"""

from __future__ import annotations

from typing import ClassVar

import jax
import jax.numpy as jnp
import numpy as np

from jaxbill._engine.validation import check_parameter, is_concrete, real_parameter
from jaxbill._scenes.tables.base import KICK_NORMAL_SQUARED, Motion, Piece, Table
from jaxbill._scenes.tables.ellipse import EllipseWall


def entry_time(excess, speed2, along):
    """First ``t >= 0`` at which a point enters a quadric obstacle: ``excess + 2 along t + speed2 t^2`` reaches 0
    while decreasing (``excess`` the start's gap, > 0 outside; ``along`` half its slope, ``speed2 > 0``).

    A point outside moving towards the obstacle enters at the near root
    ``excess / (-along + sqrt(along^2 - speed2 excess))`` (the cancellation-free
    form: ``-along > 0`` there); one on or inside it by rounding that moves in
    enters at once (0); one moving away, or whose line misses it, never (``inf``).
    """
    disc = along * along - speed2 * excess
    approaching = (along < 0.0) & (disc >= 0.0) & (speed2 > 0.0)
    root = jnp.sqrt(jnp.maximum(disc, 0.0))
    t = excess / jnp.where(approaching, root - along, 1.0)
    return jnp.where(approaching, jnp.maximum(t, 0.0), jnp.inf)


class DiscObstacle(Piece):
    """The outside of the disc of ``radius`` about ``(cx, cy)``: a dispersing wall.

    Args:
        centre: ``(cx, cy)``, the disc's centre (length).
        radius: ``r > 0`` (length).
        scale: the gap's unit per length (default 1: the gap is about the distance to the wall).

    The gap is ``scale (|P - c|^2 - r^2) / (2 r)``, ``>= 0`` outside the disc,
    about ``scale`` times the distance near it; ``grad g = scale (P - c) / r``
    points away from the disc (into the table), ``Hess g = (scale / r) I``:
    along a point's straight flight ``g'' = scale |v|^2 / r > 0``. The arc
    length runs clockwise round the disc, so that the table is on its left, as
    for every wall.
    """

    cx: jax.Array
    cy: jax.Array
    radius: jax.Array
    scale: jax.Array | float

    straight_exit: ClassVar[bool] = True
    bounds_jerk: ClassVar[bool] = True
    dispersing: ClassVar[bool] = True

    def __init__(self, centre, radius, scale=1.0):
        cx, cy = centre
        self.cx, self.cy, self.radius = (jnp.asarray(v, dtype=jnp.float64) for v in (cx, cy, radius))
        self.scale = scale

    def check(self) -> None:
        """ValueError for a radius that is not positive and finite, or a centre that is not finite."""
        r = real_parameter("radius", self.radius)
        check_parameter("radius", r, np.isfinite(r) & (r > 0), "> 0 and finite (the obstacle's radius)")
        for name, value in (("centre", self.cx), ("centre", self.cy)):
            v = real_parameter(name, value)
            check_parameter(name, v, np.isfinite(v), "finite (the obstacle's centre)")

    def parameters_are_valid(self):
        """Traceable twin of ``check``."""
        return (self.radius > 0) & jnp.isfinite(self.radius) & jnp.isfinite(self.cx) & jnp.isfinite(self.cy)

    def gap(self, x, y):
        qx, qy = x - self.cx, y - self.cy
        return (self.scale * 0.5) * ((qx * qx + qy * qy) - self.radius * self.radius) / self.radius

    def gradient(self, x, y):
        factor = self.scale / self.radius
        return factor * (x - self.cx), factor * (y - self.cy)

    def hessian_form(self, x, y, dx, dy):
        return (self.scale / self.radius) * (dx * dx + dy * dy)

    @property
    def gap_scale(self):
        return self.scale * self.radius

    def curvature_bounds(self, motion: Motion):
        # A point (the only body among obstacles) flies straight: g'' = scale |v|^2 / r exactly, so
        # -lower_curv = upper_curv = that (a negative lower_curv: the gap curves upwards).
        speed2 = motion.vx * motion.vx + motion.vy * motion.vy
        curve = self.scale * speed2 / self.radius
        return -curve, curve

    def jerk_bound(self, motion: Motion):
        return jnp.zeros_like(motion.vx)

    def exit_time(self, px, py, vx, vy):
        """First ``t >= 0`` at which the point ``P + v t`` enters the disc (leaves the table through it)."""
        qx, qy = px - self.cx, py - self.cy
        excess = (qx * qx + qy * qy) - self.radius * self.radius
        return entry_time(excess, vx * vx + vy * vy, qx * vx + qy * vy)

    def impulse_normal(self, x, y):
        # Into the disc (out of the table), |N|^2 = pi/2 on the wall (see ``DiscWall.impulse_normal``).
        factor = -np.sqrt(KICK_NORMAL_SQUARED) / self.radius
        return factor * (x - self.cx), factor * (y - self.cy)

    def boundary_coordinate(self, x, y):
        """``r phi``, ``phi`` the clockwise angle from the disc's rightmost point, in ``[0, 2 pi)``."""
        return self.radius * jnp.mod(-jnp.arctan2(y - self.cy, x - self.cx), 2.0 * jnp.pi)

    def tangent(self, x, y):
        qx, qy = x - self.cx, y - self.cy
        norm = jnp.sqrt(qx * qx + qy * qy)
        return qy / norm, -qx / norm

    @property
    def length(self):
        return 2.0 * jnp.pi * self.radius

    def point_at(self, s):
        angle = -s / self.radius
        return self.cx + self.radius * jnp.cos(angle), self.cy + self.radius * jnp.sin(angle)

    def scaled(self, scale) -> DiscObstacle:
        """The same obstacle with the gap unit ``scale`` per length (a table sets its own unit)."""
        return DiscObstacle((self.cx, self.cy), self.radius, scale)


class EllipseObstacle(Piece):
    """The outside of the ellipse ``(x - cx)^2 / a^2 + (y - cy)^2 / b^2 <= 1``: a dispersing wall.

    Args:
        centre: ``(cx, cy)`` (length).
        a, b: the semi-axes along x and y, ``> 0`` (length).
        scale: the gap's unit per length (default 1).

    The gap is ``scale (sqrt(ab) / 2) (X^2/a^2 + Y^2/b^2 - 1)`` with
    ``(X, Y) = P - c`` (the disc's ``(|P - c|^2 - r^2) / (2 r)`` for
    ``a = b = r``), ``Hess g = scale sqrt(ab) diag(1/a^2, 1/b^2)``, positive
    definite. Along a straight line ``X^2/a^2 + Y^2/b^2`` is a quadratic in
    time: the entry time is the disc's formula in the coordinates scaled by the
    semi-axes. The arc length runs clockwise.
    """

    cx: jax.Array
    cy: jax.Array
    a: jax.Array
    b: jax.Array
    scale: jax.Array | float

    straight_exit: ClassVar[bool] = True
    bounds_jerk: ClassVar[bool] = True
    dispersing: ClassVar[bool] = True

    def __init__(self, centre, a, b, scale=1.0):
        cx, cy = centre
        self.cx, self.cy, self.a, self.b = (jnp.asarray(v, dtype=jnp.float64) for v in (cx, cy, a, b))
        self.scale = scale

    def check(self) -> None:
        """ValueError for a semi-axis that is not positive and finite, or a centre that is not finite."""
        for name, value in (("a", self.a), ("b", self.b)):
            v = real_parameter(name, value)
            check_parameter(name, v, np.isfinite(v) & (v > 0), "> 0 and finite (a semi-axis of the obstacle)")
        for value in (self.cx, self.cy):
            v = real_parameter("centre", value)
            check_parameter("centre", v, np.isfinite(v), "finite (the obstacle's centre)")

    def parameters_are_valid(self):
        """Traceable twin of ``check``."""
        ok = (self.a > 0) & (self.b > 0) & jnp.isfinite(self.a) & jnp.isfinite(self.b)
        return ok & jnp.isfinite(self.cx) & jnp.isfinite(self.cy)

    @property
    def _unit(self):
        return self.scale * 0.5 * jnp.sqrt(self.a * self.b)

    def gap(self, x, y):
        X, Y = (x - self.cx) / self.a, (y - self.cy) / self.b
        return self._unit * ((X * X + Y * Y) - 1.0)

    def gradient(self, x, y):
        factor = 2.0 * self._unit
        return factor * (x - self.cx) / (self.a * self.a), factor * (y - self.cy) / (self.b * self.b)

    def hessian_form(self, x, y, dx, dy):
        return 2.0 * self._unit * (dx * dx / (self.a * self.a) + dy * dy / (self.b * self.b))

    @property
    def gap_scale(self):
        return self.scale * jnp.sqrt(self.a * self.b)

    def curvature_bounds(self, motion: Motion):
        # A point's straight flight: g'' = 2 unit (vx^2/a^2 + vy^2/b^2), a constant.
        curve = 2.0 * self._unit * ((motion.vx / self.a) ** 2 + (motion.vy / self.b) ** 2)
        return -curve, curve

    def jerk_bound(self, motion: Motion):
        return jnp.zeros_like(motion.vx)

    def exit_time(self, px, py, vx, vy):
        """First ``t >= 0`` at which ``P + v t`` enters the ellipse (leaves the table through it)."""
        X, Y = (px - self.cx) / self.a, (py - self.cy) / self.b
        wx, wy = vx / self.a, vy / self.b
        return entry_time((X * X + Y * Y) - 1.0, wx * wx + wy * wy, X * wx + Y * wy)

    def impulse_normal(self, x, y):
        gx, gy = self.gradient(x, y)
        factor = -jnp.sqrt(KICK_NORMAL_SQUARED / (gx * gx + gy * gy))
        return factor * gx, factor * gy

    @property
    def _rim(self) -> EllipseWall:
        """The ellipse's own wall about its centre: its arc length (anticlockwise) by quadrature."""
        return EllipseWall(self.a, self.b)

    def boundary_coordinate(self, x, y):
        """Arc length clockwise from the rightmost point ``(cx + a, cy)``."""
        rim = self._rim
        anticlockwise = rim.boundary_coordinate(x - self.cx, y - self.cy)
        return jnp.mod(rim.length - anticlockwise, rim.length)

    def tangent(self, x, y):
        tx, ty = self._rim.tangent(x - self.cx, y - self.cy)
        return -tx, -ty

    @property
    def length(self):
        return self._rim.length

    def point_at(self, s):
        rim = self._rim
        px, py = rim.point_at(jnp.mod(rim.length - s, rim.length))
        return self.cx + px, self.cy + py

    def scaled(self, scale) -> EllipseObstacle:
        """The same obstacle with the gap unit ``scale`` per length."""
        return EllipseObstacle((self.cx, self.cy), self.a, self.b, scale)


# Points sampled round each obstacle's rim to check that it lies inside the table and clear of the others.
_RIM_SAMPLES = 256


class WithObstacles(Table):
    """A table with obstacles taken out: the intersection of its walls and the outsides of the obstacles.

    Args:
        table: the outer table (any ``jb.Table`` that is an intersection of
            walls: ``jb.Circle``, ``jb.Stadium``, ``jb.Polygon``, ...).
        obstacles: a sequence of ``jb.DiscObstacle`` and ``jb.EllipseObstacle``,
            each strictly inside the table and clear of the others (checked at
            256 points of each rim).

    The walls, in the order of the contact codes (``3 + i``): the table's, then
    the obstacles'. The obstacles' gaps are rescaled to the table's gap unit.
    Only ``jb.PointBody`` moves in it (the obstacles disperse).
    """

    table: Table
    obstacles: tuple

    name: ClassVar[str] = "the table with obstacles"

    def __init__(self, table: Table, obstacles):
        if not isinstance(table, Table) or not table.intersection_of_pieces:
            raise TypeError(f"table must be a jaxbill table that is an intersection of walls; got {table!r}")
        obstacles = tuple(obstacles)
        for obstacle in obstacles:
            if not isinstance(obstacle, (DiscObstacle, EllipseObstacle)):
                raise TypeError(
                    f"obstacles must be jb.DiscObstacle or jb.EllipseObstacle; got {type(obstacle).__name__}"
                )
        self.table, self.obstacles = table, obstacles
        if all(is_concrete(leaf) for leaf in jax.tree_util.tree_leaves(self)):
            self.check()

    def check(self) -> None:
        """ValueError for an obstacle out of range, outside the table or overlapping another."""
        self.table.check()
        for obstacle in self.obstacles:
            obstacle.check()
        pieces = self.pieces
        walls, rims = pieces[: len(self.table.pieces)], pieces[len(self.table.pieces) :]
        s = np.linspace(0.0, 1.0, _RIM_SAMPLES, endpoint=False)
        for i, rim in enumerate(rims):
            x, y = rim.point_at(jnp.asarray(s) * rim.length)
            for wall, name in zip(walls, self.table.piece_names):
                if np.any(np.asarray(wall.gap(x, y)) <= 0.0):
                    raise ValueError(
                        f"obstacles: obstacle {i + 1} reaches {name}: it must lie strictly inside the table"
                    )
            for j, other in enumerate(rims):
                if j != i and np.any(np.asarray(other.gap(x, y)) <= 0.0):
                    raise ValueError(f"obstacles: obstacles {i + 1} and {j + 1} overlap")

    def parameters_are_valid(self):
        ok = self.table.parameters_are_valid()
        for obstacle in self.obstacles:
            ok &= obstacle.parameters_are_valid()
        return ok

    @property
    def pieces(self):
        unit = self.table.gap_scale / self.table.size
        return (*self.table.pieces, *(obstacle.scaled(unit) for obstacle in self.obstacles))

    @property
    def piece_names(self):
        return (*self.table.piece_names, *(f"obstacle {i + 1}" for i in range(len(self.obstacles))))

    @property
    def size(self):
        return self.table.size

    @property
    def extent(self):
        return self.table.extent

    @property
    def section_names(self):  # type: ignore[override]
        return self.table.section_names
