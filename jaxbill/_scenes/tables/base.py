"""What a table answers: a convex region, the intersection of smooth pieces ``g_i(P) >= 0``.

A **piece** is one smooth wall: a function ``g(P)`` of a point ``P = (x, y)``,
``>= 0`` on the table's side and ``0`` on the wall (a disc, an ellipse, a
half-plane, a capsule, a user's function). A **table** is the intersection of
its pieces. A body touches the table at contact points; the engine's
certified first-root search (``jaxbill._engine.first_root``) asks each piece:

* its **gap**, **gradient** and **Hessian form** ``d^T Hess g d`` at a point:
  along a path ``P(t)`` the gap's time derivatives are
  ``g' = grad g . P'`` and ``g'' = P'^T Hess g P' + grad g . P''``;
* **bounds on ``g''``** (and, where it can, ``|g'''|``) along the free flight of
  a body (``Motion``), from bounds on its Hessian and gradient over the table;
* a **quiet interval**: the times the body's centre stays where no contact
  point (all within ``Motion.radius`` of the centre) can reach the wall, so the
  search may jump over them;
* where a straight flight's gap is a polynomial, a **closed-form exit time**
  (a body that never turns, a point), so that no root search is compiled;
* the **impulse normal** at a contact: the outward normal, any positive
  multiple (the impulse is the one mass-metric reflection about it).

Units. Every piece of one table shares the table's gap unit (``gap_scale``):
a point at a small distance ``delta`` outside a wall has a gap of about
``-delta`` times a length of the table's size (``R^2 - |P|^2`` for a disc is
``-2 R delta``). ``WALL_TOLERANCE`` and the corner test are relative to it.
"""

from __future__ import annotations

import abc
import functools
from typing import Any, ClassVar, NamedTuple

import equinox as eqx
import jax
import jax.numpy as jnp

# An impulse's normal is scaled so that its squared norm sits near this value: mid-binade,
# with a reciprocal of no short binary period (see ``jaxbill._scenes.impulse.reflect``).
KICK_NORMAL_SQUARED = 1.5707963267948966  # pi / 2


class Motion(NamedTuple):
    """A body's free flight from one collision to the next, as the pieces' bounds need it (fixed along it).

    Attributes:
        cx, cy: the centre of mass at the start of the flight (length).
        vx, vy: its velocity (length / time).
        omega: the spin (radians / time; 0 for a body that never turns).
        radius: the largest distance of a contact point from the centre (length; 0 for a point).
        inner_radius2: ``sum_k w_k |b_k|^2`` for weights ``w_k >= 0``, ``sum w_k = 1``,
            ``sum w_k b_k = 0`` over the contact points ``b_k`` (area; 0 when the body
            gives none): the weighted mean of the contact gaps of a quadratic piece then
            bounds how far the centre can go before the first contact.
    """

    cx: jax.Array
    cy: jax.Array
    vx: jax.Array
    vy: jax.Array
    omega: jax.Array
    radius: jax.Array
    inner_radius2: jax.Array


class Piece(eqx.Module):
    """One smooth wall of a table: ``g(P) >= 0`` on the table's side (an abstract ``equinox.Module``).

    Subclasses give the abstract methods; the class attributes say which of the
    optional answers they have. Coordinates come as scalars or equal-shaped
    arrays (one value per orbit), never stacked: the same code runs under
    ``vmap`` and inside a Pallas kernel.
    """

    # The exit time of a point on a straight line is a closed form (``exit_time``).
    straight_exit: ClassVar[bool] = False
    # A flat wall ``n . P <= d`` (``plane``): what a smooth body's support function needs.
    flat: ClassVar[bool] = False
    # ``jerk_bound`` bounds the third time derivative (the search's sharper steps need it).
    bounds_jerk: ClassVar[bool] = False
    # The search compares the gap's own curvature with the bounds at every step (bounds that were
    # estimated, not derived): an orbit where they fail is poisoned with NaN.
    checks_curvature: ClassVar[bool] = False
    # A dispersing wall (the outside of an obstacle, convex towards the table): the table is not convex,
    # and a body's sides could touch the wall between its contact points, which the scene does not model.
    dispersing: ClassVar[bool] = False
    # A periodic wall of a cell: crossing it continues the flight into the neighbouring cell (no impulse,
    # the identity on the state and its tangent), and it is no part of the boundary a section runs along.
    periodic: ClassVar[bool] = False

    @abc.abstractmethod
    def gap(self, x, y):
        """``g(P)``: ``>= 0`` inside, ``0`` on the wall, in the table's gap unit."""

    @abc.abstractmethod
    def gradient(self, x, y) -> tuple:
        """``grad g`` at ``P``: ``(gx, gy)``; it points into the table."""

    @abc.abstractmethod
    def hessian_form(self, x, y, dx, dy):
        """``d^T Hess g(P) d`` for the direction ``d = (dx, dy)``."""

    @property
    @abc.abstractmethod
    def gap_scale(self) -> jax.Array:
        """The unit of the gap (area for the curved pieces, ``R^2``; length for flat walls between two)."""

    @abc.abstractmethod
    def curvature_bounds(self, motion: Motion) -> tuple:
        """``(lower_curv, upper_curv)``: ``-lower_curv <= g'' <= upper_curv`` for every contact point of the
        body along its flight until its first contact (the point inside the table, within ``motion.radius``
        of the centre)."""

    def jerk_bound(self, motion: Motion):
        """A bound on ``|g'''|`` along the flight (``None``: the search uses the curvature bounds alone)."""
        return None

    def quiet_interval(self, motion: Motion) -> tuple:
        """``(t_in, t_out)``: times at which no point within ``motion.radius`` of the centre can touch this wall
        (empty, ``t_in >= t_out``, by default)."""
        never = jnp.full(jnp.shape(motion.cx), jnp.inf)
        return never, never

    def along_flight(self, cx, cy, rx, ry, vx, vy, tx, ty, omega, curvature: bool) -> tuple:
        """The gap of the contact point ``c + r`` of a body moving at ``(v, omega)`` and its time derivatives:
        ``(g, g')``, or ``(g, g', g'')`` with ``curvature``. ``t = dr/dalpha`` (the contact moves at
        ``v + omega t`` and accelerates at ``-omega^2 r``)."""
        px, py, ex, ey = cx + rx, cy + ry, vx + omega * tx, vy + omega * ty
        if not curvature:
            return along_path(self, px, py, ex, ey)
        spin2 = omega * omega
        return along_path(self, px, py, ex, ey, -spin2 * rx, -spin2 * ry)

    def exit_time(self, px, py, vx, vy):
        """First ``t >= 0`` at which the point ``P + v t`` reaches the wall moving outwards (``inf``: never).

        Only for ``straight_exit`` pieces. A point on the wall moving inwards gets
        the next crossing, never ``t = 0``; one on or outside it moving outwards gets 0.
        """
        raise NotImplementedError(f"{type(self).__name__} has no closed-form exit time")

    def impulse_normal(self, x, y) -> tuple:
        """The outward normal at a contact point, unnormalised; the default is ``-grad g`` scaled to a squared
        norm of ``KICK_NORMAL_SQUARED`` (any positive multiple gives the same impulse)."""
        gx, gy = self.gradient(x, y)
        scale = -jnp.sqrt(KICK_NORMAL_SQUARED / (gx * gx + gy * gy))
        return scale * gx, scale * gy

    def plane(self) -> tuple:
        """``(nx, ny, d)`` of a flat wall ``n . P <= d`` (``n`` the unit outward normal); only for ``flat``."""
        raise NotImplementedError(f"{type(self).__name__} is not a flat wall")

    def boundary_coordinate(self, x, y):
        """The arc length (length) along this wall of a point on it, from the wall's own origin."""
        raise NotImplementedError(f"{type(self).__name__} has no arc-length coordinate")

    @property
    def length(self) -> jax.Array:
        """The length of this wall's part of the table's boundary (``inf`` for an unbounded wall)."""
        raise NotImplementedError(f"{type(self).__name__} has no arc length")

    def point_at(self, s) -> tuple:
        """The point ``(x, y)`` of the wall at arc length ``s`` from its origin (the inverse of
        ``boundary_coordinate``)."""
        raise NotImplementedError(f"{type(self).__name__} has no arc-length coordinate")

    def tangent(self, x, y) -> tuple:
        """The unit tangent at a point of the wall, pointing the way the arc length grows
        (anticlockwise around the table)."""
        gx, gy = self.gradient(x, y)
        norm = jnp.sqrt(gx * gx + gy * gy)
        # grad g points inwards; a quarter turn clockwise of it runs anticlockwise along the wall.
        return gy / norm, -gx / norm


def along_path(piece: Piece, px, py, ex, ey, ax=None, ay=None) -> tuple:
    """A piece's gap and its time derivatives along a path through ``P`` with velocity ``e`` and acceleration
    ``a``: ``(g, g')``, or ``(g, g', g'')`` when ``a`` is given."""
    gx, gy = piece.gradient(px, py)
    gap, slope = piece.gap(px, py), gx * ex + gy * ey
    if ax is None:
        return gap, slope
    return gap, slope, piece.hessian_form(px, py, ex, ey) + (gx * ax + gy * ay)


def generic_curvature_bounds(motion: Motion, hessian_low, hessian_high, gradient_bound) -> tuple:
    """``(lower_curv, upper_curv)`` from bounds on the piece's Hessian eigenvalues ``[low, high]`` and on
    ``|grad g|`` over the table.

    A contact point at the offset ``r`` from the centre moves with
    ``P' = v + omega r_alpha`` (``|P'| <= |v| + |omega| rho``) and
    ``P'' = -omega^2 r`` (``|P''| = omega^2 |r| <= omega^2 rho``), so
    ``g'' = P'^T H P' + grad g . P''`` lies in
    ``[min(low, 0) |P'|^2 - G omega^2 rho, max(high, 0) |P'|^2 + G omega^2 rho]``.
    """
    speed = jnp.sqrt(motion.vx * motion.vx + motion.vy * motion.vy) + jnp.abs(motion.omega) * motion.radius
    turn = gradient_bound * motion.omega * motion.omega * motion.radius
    return jnp.maximum(-hessian_low, 0.0) * speed * speed + turn, jnp.maximum(hessian_high, 0.0) * speed * speed + turn


def disc_crossing(px, py, vx, vy, radius):
    """``(t_in, t_out)``: the times ``t >= 0`` with ``|p + v t| < radius`` (both ``inf`` when there are none)."""
    speed2 = vx * vx + vy * vy
    b = px * vx + py * vy
    excess = px * px + py * py - radius * radius
    disc = b * b - speed2 * excess
    root = jnp.sqrt(jnp.maximum(disc, 0.0))
    # The two roots of speed2 t^2 + 2 b t + excess = 0, each without cancellation.
    q = -(b + jnp.where(b < 0.0, -root, root))
    safe_q = jnp.where(q == 0.0, 1.0, q)
    t1, t2 = q / jnp.where(speed2 > 0.0, speed2, 1.0), excess / safe_q
    t_in, t_out = jnp.minimum(t1, t2), jnp.maximum(t1, t2)
    crosses = (speed2 > 0.0) & (disc > 0.0) & (t_out > 0.0) & (q != 0.0) & (radius > 0.0)
    inside_for_ever = (speed2 == 0.0) & (excess < 0.0)
    t_in = jnp.where(crosses, jnp.maximum(t_in, 0.0), jnp.where(inside_for_ever, 0.0, jnp.inf))
    t_out = jnp.where(crosses, t_out, jnp.inf)
    return t_in, t_out


def band_crossing(p, v, low, high):
    """``(t_in, t_out)``: the times ``t >= 0`` with ``low < p + v t < high`` (empty, ``t_in >= t_out``, if none)."""
    safe_v = jnp.where(v == 0.0, 1.0, v)
    t_low, t_high = (low - p) / safe_v, (high - p) / safe_v
    t_in = jnp.maximum(jnp.minimum(t_low, t_high), 0.0)
    t_out = jnp.maximum(t_low, t_high)
    inside_now = (p > low) & (p < high)
    t_in = jnp.where(v == 0.0, jnp.where(inside_now, 0.0, jnp.inf), t_in)
    t_out = jnp.where(v == 0.0, jnp.where(inside_now, jnp.inf, -jnp.inf), t_out)
    no_band = low >= high
    return jnp.where(no_band, jnp.inf, t_in), jnp.where(no_band, -jnp.inf, t_out)


class Table(eqx.Module):
    """A convex table: the intersection of its ``pieces`` (an abstract ``equinox.Module``).

    Subclasses hold their parameters as leaves and build ``pieces`` from them
    (a property, so that a traced or vmapped table builds traced pieces).
    They give ``pieces`` and ``piece_names`` (one name per piece, in the same
    order: wall ``i`` of the gap numbering), ``size`` (length) and ``extent``
    (four lengths), and where they can ``check``, ``parameters_are_valid``,
    ``diameter`` and ``width`` (lengths: a body that cannot fit is refused)
    and ``section_names``.
    """

    name: ClassVar[str] = "the table"
    # The wall's force always points at the origin (a circle about it): the angular momentum is conserved.
    conserves_angular_momentum: ClassVar[bool] = False
    # A table with a centre (a bounded one) takes angular momentum about its origin; the strip has none.
    has_centre: ClassVar[bool] = True
    # The table is the intersection of its pieces: a point is inside when every gap is >= 0. A union of
    # convex parts (the mushroom) sets False and gives ``clearance``; its pieces are finite walls.
    intersection_of_pieces: ClassVar[bool] = True

    @property
    @abc.abstractmethod
    def pieces(self) -> tuple[Piece, ...]:
        """The smooth walls whose intersection is the table, in the order of the contact codes."""

    @property
    @abc.abstractmethod
    def piece_names(self) -> tuple[str, ...]:
        """One name per piece, for messages (``("the circle",)``, ``("side 1", ...)``)."""

    @property
    @abc.abstractmethod
    def size(self) -> jax.Array:
        """A length of the table's size (the radius; ``sqrt(ab)``; the strip's height): the time scale of a
        flight is ``size / |v|``."""

    @property
    def gap_scale(self) -> jax.Array:
        """The gap unit every piece shares (``WALL_TOLERANCE`` is relative to it)."""
        return self.pieces[0].gap_scale

    @property
    @abc.abstractmethod
    def extent(self) -> tuple:
        """``(x_low, x_high, y_low, y_high)``: a box that holds the table (for sampling and plots; infinite
        along an unbounded direction)."""

    @property
    def convex(self) -> bool:
        """Static: the table is convex, an intersection of walls none of which disperses.

        Only a point particle moves in a table that is not (``jb.BodyInTable``
        refuses other bodies): a body touches a convex table only at its
        contact points, but a dispersing wall or a re-entrant corner could
        meet one of its sides between them.
        """
        return self.intersection_of_pieces and not any(type(piece).dispersing for piece in self.pieces)

    def clearance(self, x, y):
        """How far inside the table a point is, in the gap unit: ``>= 0`` inside, ``< 0`` outside.

        The default is the smallest of the pieces' gaps (an intersection). A
        union of convex parts gives the largest over its parts of each part's
        smallest gap. A periodic table answers for its central cell (the one
        about the origin), unfolded: the sampler draws starts there.
        """
        gaps: list[Any] = [piece.gap(x, y) for piece in self.pieces]
        return functools.reduce(jnp.minimum, gaps)

    @property
    def corners(self) -> tuple[tuple[int, int], ...] | None:
        """Static: the corners of the table, as pairs ``(i, j)`` of the walls that meet there, where every corner
        is two walls meeting at a point; ``None`` (the default) where the scene should not rely on it. A point
        particle's corner rule then runs over these pairs alone (``jaxbill._scenes.impulse.pairs_resolution``)."""
        return None

    def cell_origin(self, x, y, vx, vy):
        """The origin ``(ox, oy)`` of the cell a flight from ``(x, y)`` at ``(vx, vy)`` runs in, or ``None``.

        ``None`` (static) for every table but a periodic one: its state keeps
        the unfolded position, and the pieces see ``P - origin``, the position
        in the cell the flight starts in (on a boundary between cells, the one
        the velocity points into).
        """
        return None

    def cells_covering(self, x_low: float, x_high: float, y_low: float, y_high: float) -> list:
        """The origins ``(ox, oy)`` (floats) of the copies of the table a picture of the box shows: ``[(0, 0)]``;
        a periodic table, every cell that meets the box (its orbits unfold across the plane)."""
        return [(0.0, 0.0)]

    def check(self) -> None:
        """ValueError naming a parameter that is out of range (concrete values)."""

    def parameters_are_valid(self) -> jax.Array:
        """Traceable twin of ``check``."""
        return jnp.array(True)

    @property
    def diameter(self) -> jax.Array:
        """The longest chord (length; ``inf`` for an unbounded table): no body longer than it fits."""
        return jnp.asarray(jnp.inf)

    @property
    def width(self) -> jax.Array:
        """The smallest width over all directions (length): no body wider than it in every direction fits."""
        return jnp.asarray(jnp.inf)

    # The sections a body in this table has (``jaxbill._scenes.body_sections``): "birkhoff" for a
    # bounded table, "floor" for the strip between two walls.
    section_names: ClassVar[tuple[str, ...]] = ("birkhoff",)

    @property
    def boundary_length(self) -> jax.Array:
        """The perimeter (length): the sum of the walls' lengths."""
        return sum((piece.length for piece in self.pieces[1:]), self.pieces[0].length)

    def boundary_offset(self, piece: int) -> jax.Array:
        """Arc length from the table's boundary origin to the start of piece ``piece`` (static index)."""
        pieces = self.pieces
        return sum((p.length for p in pieces[:piece]), jnp.zeros_like(pieces[0].gap_scale))

    def boundary_coordinate(self, piece: int, x, y):
        """The arc length, anticlockwise round the table from its origin, of a point on wall ``piece``."""
        return self.boundary_offset(piece) + self.pieces[piece].boundary_coordinate(x, y)

    def boundary_point(self, s) -> tuple:
        """``(x, y, piece)``: the boundary point at arc length ``s`` (any real: taken modulo the perimeter) and
        the index of its wall (int32)."""
        s = jnp.mod(s, self.boundary_length)
        x = y = jnp.zeros_like(s)
        index = jnp.zeros(jnp.shape(s), jnp.int32)
        for i, piece in enumerate(self.pieces):
            if type(piece).periodic:
                continue  # no part of the boundary: a cell's side, crossed and never hit
            start = self.boundary_offset(i)
            here = s >= start
            px, py = piece.point_at(jnp.where(here, s - start, 0.0))
            x, y = jnp.where(here, px, x), jnp.where(here, py, y)
            index = jnp.where(here, jnp.int32(i), index)
        return x, y, index
