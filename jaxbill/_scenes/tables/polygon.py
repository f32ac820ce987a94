"""A convex polygon: the intersection of the half-planes of its sides.

Side ``j`` runs from corner ``j`` to corner ``j + 1`` (anticlockwise); its gap
is the distance of a point from the side's line (``jaxbill._scenes.tables.flat``),
in units of the polygon's size (its largest corner distance from the origin).
A point in a corner touches two sides at once: the impulses of both apply, in
the order of the engine's corner rule.
"""

from __future__ import annotations

import functools
from typing import ClassVar

import jax
import jax.numpy as jnp
import numpy as np

from jaxbill._engine.validation import check_parameter, is_concrete, real_parameter
from jaxbill._scenes import polygon_geometry as geometry
from jaxbill._scenes.tables.base import Table
from jaxbill._scenes.tables.flat import wall_through


class Polygon(Table):
    """The convex polygon with the given corners.

    Args:
        vertices: ``(n, 2)`` corners in anticlockwise order (length), ``n >= 3``,
            a strictly convex polygon (``Polygon.regular`` builds a regular one).

    The corners are leaves (differentiable); their number is static. Wall
    ``j`` (named ``side j+1``) runs from corner ``j`` to corner ``j + 1``
    (mod ``n``); its gap is the distance from that side's line (length), and
    the gap unit (``gap_scale``) the largest distance of a corner from the origin.
    """

    xs: tuple
    ys: tuple

    name: ClassVar[str] = "the polygon"

    def __init__(self, vertices):
        if is_concrete(vertices):
            vertices = geometry.checked_vertices("vertices", vertices)
        self.xs = tuple(jnp.asarray(vertices[j][0], dtype=jnp.float64) for j in range(len(vertices)))
        self.ys = tuple(jnp.asarray(vertices[j][1], dtype=jnp.float64) for j in range(len(vertices)))

    @classmethod
    def regular(cls, n: int, circumradius) -> Polygon:
        """The regular ``n``-gon with its corners at ``circumradius`` (cos(2 pi j / n), sin(2 pi j / n))."""
        r = real_parameter("circumradius", circumradius)
        check_parameter("circumradius", r, np.isfinite(r) & (r > 0), "> 0 and finite")
        return cls(geometry.regular(n, float(r)))

    @property
    def vertices(self) -> jax.Array:
        """The corners ``(n, 2)``."""
        return jnp.stack([jnp.stack(self.xs), jnp.stack(self.ys)], axis=-1)

    def check(self) -> None:
        geometry.checked_vertices("vertices", np.asarray(self.vertices))

    def parameters_are_valid(self):
        ok = jnp.array(True)
        for j in range(len(self.xs)):
            k = (j + 1) % len(self.xs)
            m = (j + 2) % len(self.xs)
            turn = (self.xs[k] - self.xs[j]) * (self.ys[m] - self.ys[k]) - (self.ys[k] - self.ys[j]) * (
                self.xs[m] - self.xs[k]
            )
            ok &= jnp.isfinite(self.xs[j]) & jnp.isfinite(self.ys[j]) & (turn > 0.0)
        return ok

    @property
    def size(self):
        # A fold, not a stack: a Pallas (Triton) kernel stacks two arrays at most.
        return jnp.sqrt(functools.reduce(jnp.maximum, [x * x + y * y for x, y in zip(self.xs, self.ys)]))

    @property
    def pieces(self):
        n, unit = len(self.xs), self.size
        return tuple(
            wall_through(self.xs[j], self.ys[j], self.xs[(j + 1) % n], self.ys[(j + 1) % n], unit) for j in range(n)
        )

    @property
    def piece_names(self):
        return tuple(f"side {j + 1}" for j in range(len(self.xs)))

    @property
    def extent(self):
        xs, ys = jnp.stack(self.xs), jnp.stack(self.ys)
        return jnp.min(xs), jnp.max(xs), jnp.min(ys), jnp.max(ys)

    @property
    def diameter(self):
        return jnp.asarray(geometry.diameter(np.asarray(self.vertices)))

    @property
    def width(self):
        return jnp.asarray(geometry.width(np.asarray(self.vertices)))
