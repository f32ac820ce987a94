"""Sinai's billiard: a square with a disc at its centre, the first billiard proved ergodic and mixing.

The table is the square ``|x|, |y| <= side/2`` less the open disc ``|P| < r``:
the intersection of four half-planes and the outside of a disc
(``jaxbill._scenes.tables.obstacles.DiscObstacle``). Not convex: only a point
moves in it. Every straight flight ends at a closed-form time, so a point in
it compiles no root search. Its gaps are lengths (the distance to a side; about
the distance to the disc near it), in units of ``side``.

Mean free path (Santalo): a point billiard's flights between collisions,
averaged over the collision map's invariant measure, have the mean length
``pi A / P`` for a table of area ``A`` and perimeter ``P``: here
``pi (side^2 - pi r^2) / (4 side + 2 pi r)`` (``mean_free_path``).
"""

from __future__ import annotations

from typing import ClassVar

import jax
import jax.numpy as jnp
import numpy as np

from jaxbill._engine.validation import check_parameter, is_concrete, real_parameter
from jaxbill._scenes.tables.base import Table
from jaxbill._scenes.tables.flat import wall_through
from jaxbill._scenes.tables.obstacles import DiscObstacle


class Sinai(Table):
    """Sinai's billiard: the square ``|x|, |y| <= side/2`` with the disc ``|P| < radius`` taken out.

    Args:
        radius: the disc's radius, ``0 < radius < side/2`` (length).
        side: the square's side, ``> 0`` (length; default 1, the unit square).

    Five walls, in the order of the contact codes (``3 + i``): the bottom, right,
    top and left sides, then the disc (a dispersing wall; its arc length runs
    clockwise). Only ``jb.PointBody`` moves in it.
    """

    side: jax.Array  # first: the unit of length (the explorer keeps it fixed)
    radius: jax.Array

    name: ClassVar[str] = "Sinai's billiard"

    def __init__(self, radius, side=1.0):
        self.radius, self.side = (jnp.asarray(v, dtype=jnp.float64) for v in (radius, side))
        if is_concrete(self.radius) and is_concrete(self.side):
            self.check()

    def check(self) -> None:
        side = real_parameter("side", self.side)
        check_parameter("side", side, np.isfinite(side) & (side > 0), "> 0 and finite (the square's side)")
        r = real_parameter("radius", self.radius)
        check_parameter("radius", r, (r > 0) & (r < side / 2), f"> 0 and < side/2 = {side / 2} (the disc fits)")

    def parameters_are_valid(self):
        return (self.side > 0) & jnp.isfinite(self.side) & (self.radius > 0) & (self.radius < 0.5 * self.side)

    @property
    def pieces(self):
        h = 0.5 * self.side
        corners = ((-h, -h), (h, -h), (h, h), (-h, h))
        sides = tuple(wall_through(*corners[j], *corners[(j + 1) % 4], self.side) for j in range(4))
        zero = 0.0 * self.radius  # from a parameter: a Pallas kernel lowers no operation on a constant
        return (*sides, DiscObstacle((zero, zero), self.radius))

    @property
    def corners(self):
        """The square's four corners (the disc meets no side)."""
        return ((0, 1), (1, 2), (2, 3), (3, 0))

    @property
    def piece_names(self):
        return ("the bottom side", "the right side", "the top side", "the left side", "the disc")

    @property
    def area(self) -> jax.Array:
        """``side^2 - pi r^2`` (area)."""
        return self.side**2 - jnp.pi * self.radius**2

    @property
    def mean_free_path(self) -> jax.Array:
        """Santalo's ``pi A / P``: the mean flight between collisions under the collision map's invariant
        measure (length)."""
        return jnp.pi * self.area / (4.0 * self.side + 2.0 * jnp.pi * self.radius)

    @property
    def size(self):
        return self.side

    @property
    def extent(self):
        h = 0.5 * self.side
        return -h, h, -h, h
