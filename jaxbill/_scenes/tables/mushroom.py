"""Bunimovich's mushroom: a semicircular cap on a rectangular stem, a table that is a union of two convex parts.

The cap is the half-disc ``|P| <= R``, ``y >= 0``; the stem the rectangle
``|x| <= w/2``, ``-h <= y <= 0`` under its middle. The boundary, anticlockwise
from ``(R, 0)``, is six finite walls (``jaxbill._scenes.tables.finite``): the
cap's arc, the flat rim left of the stem, the stem's left side, its foot, its
right side, and the flat rim right of the stem. The corners where the stem
meets the rim are re-entrant: the table is not convex, and only a point moves in
it.

Its phase space is sharply divided (L. A. Bunimovich, Chaos 11, 802 (2001)): a
point in the cap whose angular momentum about the cap's centre exceeds ``w/2``
in size (speed 1) keeps it for ever, a chord of the full disc whose caustic
misses the stem's mouth (reflections off the flat rim mirror the half-disc into
the disc), so it never enters the stem: a regular region of whispering-gallery
orbits; every other orbit is chaotic.

Membership (``clearance``): a point is in the table when it is in one part, the
cap or the stem; the stem's part is taken up to ``y = sqrt(R^2 - w^2/4)`` (its
top lies inside the cap), so that a point in the mouth is inside a part by a
margin. Gaps are lengths (the distance to a wall near it), in units of ``R``.
"""

from __future__ import annotations

from typing import ClassVar

import jax
import jax.numpy as jnp
import numpy as np

from jaxbill._engine.validation import WALL_TOLERANCE, check_parameter, is_concrete, real_parameter
from jaxbill._scenes.tables.base import Table
from jaxbill._scenes.tables.finite import Arc, Segment


class Mushroom(Table):
    """Bunimovich's mushroom: a half-disc cap of radius ``cap_radius`` on a centred stem.

    Args:
        cap_radius: the cap's radius ``R > 0`` (length); the cap is ``|P| <= R``, ``y >= 0``.
        stem_width: the stem's width ``w``, ``0 < w < 2 R`` (length); the stem is ``|x| <= w/2``.
        stem_height: the stem's height ``h > 0`` (length); the stem is ``-h <= y <= 0``.

    Six walls, in the order of the contact codes (``3 + i``): the arc, the rim
    left of the stem, the stem's left side, its foot, its right side, the rim
    right of the stem. A point in the cap with angular momentum ``|x vy - y vx|
    > w/2`` (speed 1) never enters the stem (a regular region); every other
    orbit is chaotic. Only ``jb.PointBody`` moves in it.
    """

    cap_radius: jax.Array
    stem_width: jax.Array
    stem_height: jax.Array

    name: ClassVar[str] = "the mushroom"
    intersection_of_pieces: ClassVar[bool] = False

    def __init__(self, cap_radius, stem_width, stem_height):
        self.cap_radius, self.stem_width, self.stem_height = (
            jnp.asarray(v, dtype=jnp.float64) for v in (cap_radius, stem_width, stem_height)
        )
        if all(is_concrete(v) for v in (self.cap_radius, self.stem_width, self.stem_height)):
            self.check()

    def check(self) -> None:
        R = real_parameter("cap_radius", self.cap_radius)
        check_parameter("cap_radius", R, np.isfinite(R) & (R > 0), "> 0 and finite (the cap's radius)")
        w = real_parameter("stem_width", self.stem_width)
        check_parameter(
            "stem_width", w, np.isfinite(w) & (w > 0) & (w < 2 * R), f"> 0 and < 2 cap_radius = {2 * R} (the stem fits)"
        )
        h = real_parameter("stem_height", self.stem_height)
        check_parameter("stem_height", h, np.isfinite(h) & (h > 0), "> 0 and finite (the stem's height)")

    def parameters_are_valid(self):
        R, w, h = self.cap_radius, self.stem_width, self.stem_height
        return (R > 0) & jnp.isfinite(R) & (w > 0) & (w < 2.0 * R) & (h > 0) & jnp.isfinite(h)

    @property
    def pieces(self):
        R, h = self.cap_radius, self.stem_height
        a = 0.5 * self.stem_width
        pad = WALL_TOLERANCE * R
        zero = 0.0 * R  # built from a parameter: a Pallas kernel lowers no operation on a constant

        def side(x0, y0, x1, y1):
            return Segment(x0, y0, x1, y1, 1.0, R, pad)

        return (
            Arc(zero, zero, R, 0.0, np.pi, 1.0, R, pad),
            side(-R, zero, -a, zero),
            side(-a, zero, -a, -h),
            side(-a, -h, a, -h),
            side(a, -h, a, zero),
            side(a, zero, R, zero),
        )

    @property
    def corners(self):
        """Each wall meets the next, round the table: four convex corners and the two re-entrant ones where the
        stem meets the rim."""
        return tuple((i, (i + 1) % 6) for i in range(6))

    @property
    def piece_names(self):
        return (
            "the cap's arc",
            "the rim left of the stem",
            "the stem's left side",
            "the stem's foot",
            "the stem's right side",
            "the rim right of the stem",
        )

    def clearance(self, x, y):
        """The larger of the point's margins in the cap and in the stem (lengths; ``>= 0`` inside)."""
        R, h = self.cap_radius, self.stem_height
        a = 0.5 * self.stem_width
        cap = jnp.minimum(0.5 * (R * R - (x * x + y * y)) / R, y)
        top = jnp.sqrt(R * R - a * a)
        stem = jnp.minimum(jnp.minimum(a - jnp.abs(x), y + h), top - y)
        return jnp.maximum(cap, stem)

    @property
    def regular_angular_momentum(self) -> jax.Array:
        """``w / 2``: an orbit in the cap with ``|L| > w/2`` per unit speed is regular (length)."""
        return 0.5 * self.stem_width

    @property
    def area(self) -> jax.Array:
        """``pi R^2 / 2 + w h`` (area)."""
        return 0.5 * jnp.pi * self.cap_radius**2 + self.stem_width * self.stem_height

    @property
    def size(self):
        return jnp.maximum(self.cap_radius, self.stem_height)

    @property
    def extent(self):
        R = self.cap_radius
        return -R, R, -self.stem_height, R

    @property
    def diameter(self):
        return 2.0 * self.cap_radius + self.stem_height

    @property
    def width(self):
        return self.stem_width
