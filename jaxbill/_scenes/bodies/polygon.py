"""A rigid convex polygon: its corners are its contact points.

A convex body in a convex table touches the wall only with its corners (a side
lying flat on a flat wall touches with both of its corners at once: a
simultaneous contact). The corners are given in the body's frame and stored
relative to the centre of mass: the centroid of the uniform lamina
(``inertia="lamina"``, the default) or the mean of the corners (equal point
masses at them, ``inertia="vertices"``).
"""

from __future__ import annotations

import functools

import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np

from jaxbill._engine.validation import check_parameter, is_concrete, real_parameter
from jaxbill._scenes import polygon_geometry as geometry
from jaxbill._scenes.bodies.base import Body, checked_mass_and_inertia, scalar_leaf

MASS_DISTRIBUTIONS = ("lamina", "vertices")


class PolygonBody(Body):
    """A rigid convex polygon of mass ``M``, touching walls with its corners.

    Args:
        vertices: ``(n, 2)`` corners in anticlockwise order (length), ``n >= 3``, a
            strictly convex polygon; shifted so that the centre of mass is the origin
            of the body's frame (``alpha = 0``: the corners as given, about it).
        mass: ``M > 0`` (default 1).
        inertia: ``"lamina"`` (default: a uniform plate), ``"vertices"`` (equal point
            masses ``M/n`` at the corners), a number ``> 0`` (with the lamina's
            centre of mass), or ``float('inf')`` (never turns; ``omega`` must be 0).

    The corners are leaves (differentiable); their number is static. Contact
    ``k`` is corner ``k + 1`` in the order given (``contact_names``).
    """

    xs: tuple
    ys: tuple
    mass: jax.Array
    inertia: jax.Array
    kind: str = eqx.field(static=True)
    # The corners' mean is the centre of mass: equal weights on the corners then have it as barycentre.
    balanced: bool = eqx.field(static=True)
    # n for a regular n-gon (it looks the same after a turn by 2 pi / n), else 1.
    symmetry: int = eqx.field(static=True)

    def __init__(self, vertices, mass=1.0, inertia="lamina"):
        v = geometry.checked_vertices("vertices", vertices)
        distribution = inertia if isinstance(inertia, str) else "lamina"
        if distribution not in MASS_DISTRIBUTIONS:
            raise ValueError(f"inertia must be one of {MASS_DISTRIBUTIONS} or a number > 0; got {inertia!r}")
        area, centroid = geometry.area_and_centroid(v)
        centre = centroid if distribution == "lamina" else v.mean(axis=0)
        corners = v - centre
        if is_concrete(mass):
            mass = real_parameter("mass", mass)
            check_parameter("mass", mass, np.isfinite(mass) & (mass > 0), "> 0 and finite")
        if isinstance(inertia, str):
            per_mass = (
                geometry.lamina_polar_moment(corners) / area
                if inertia == "lamina"
                else float(np.mean(np.sum(corners**2, axis=1)))
            )
            inertia = mass * per_mass
        if is_concrete(mass) and is_concrete(inertia):
            mass, inertia, kind = checked_mass_and_inertia(mass, inertia)
        else:
            kind = "rotor"
        self.xs = tuple(scalar_leaf(x) for x in corners[:, 0])
        self.ys = tuple(scalar_leaf(y) for y in corners[:, 1])
        self.mass, self.inertia = scalar_leaf(mass), scalar_leaf(inertia)
        self.kind = kind
        scale = float(np.max(np.hypot(corners[:, 0], corners[:, 1])))
        self.balanced = bool(np.max(np.abs(corners.mean(axis=0))) <= 1e-13 * scale)
        radii = np.hypot(corners[:, 0], corners[:, 1])
        sides = np.hypot(*(np.roll(corners, -1, axis=0) - corners).T)
        regular = np.ptp(radii) <= 1e-12 * scale and np.ptp(sides) <= 1e-12 * scale
        self.symmetry = len(corners) if regular else 1

    @classmethod
    def regular(cls, n: int, radius, mass=1.0, inertia="lamina") -> PolygonBody:
        """The regular ``n``-gon with corners at distance ``radius`` from its centre, a corner on the x axis."""
        r = real_parameter("radius", radius)
        check_parameter("radius", r, np.isfinite(r) & (r > 0), "> 0 and finite")
        return cls(geometry.regular(n, float(r)), mass, inertia)

    @property
    def contact_names(self):
        return tuple(f"corner {k + 1}" for k in range(len(self.xs)))

    @property
    def vertices(self) -> jax.Array:
        """The corners ``(n, 2)`` in the body's frame, about the centre of mass (length)."""
        return jnp.stack([jnp.stack(self.xs), jnp.stack(self.ys)], axis=-1)

    def check(self) -> None:
        geometry.checked_vertices("vertices", np.asarray(self.vertices))
        checked_mass_and_inertia(self.mass, self.inertia)

    def parameters_are_valid(self):
        ok = (self.mass > 0) & jnp.isfinite(self.mass)
        for x, y in zip(self.xs, self.ys):
            ok &= jnp.isfinite(x) & jnp.isfinite(y)
        if self.kind == "rotor":
            ok &= (self.inertia > 0) & jnp.isfinite(self.inertia)
        return ok

    @property
    def radius(self):
        # A fold, not a stack: a Pallas (Triton) kernel stacks two arrays at most.
        return jnp.sqrt(functools.reduce(jnp.maximum, [x * x + y * y for x, y in zip(self.xs, self.ys)]))

    @property
    def inner_radius2(self):
        if not self.balanced:
            return jnp.zeros_like(self.mass)
        return sum(x * x + y * y for x, y in zip(self.xs, self.ys)) / len(self.xs)

    @property
    def diameter(self):
        return jnp.asarray(geometry.diameter(np.asarray(self.vertices)))

    @property
    def width(self):
        return jnp.asarray(geometry.width(np.asarray(self.vertices)))

    @property
    def turn_symmetry(self) -> int:
        return self.symmetry

    def offsets(self, cos, sin):
        return tuple((x * cos - y * sin, x * sin + y * cos) for x, y in zip(self.xs, self.ys))
