"""The coin: a rigid elliptic disc, touching flat walls with the point of its rim farthest along their normal.

The disc has semi-axis ``a`` along its own x axis and ``b`` along its y axis;
at orientation ``alpha`` (``u = (cos alpha, sin alpha)``, ``w = (-sin alpha,
cos alpha)``) its extent along a unit vector ``n`` is the support function

    h = sqrt(a^2 (n . u)^2 + b^2 (n . w)^2),

reached at the rim point ``c + r``, ``r = (a^2 (n . u) u + b^2 (n . w) w) / h``.
Against the flat wall ``n . P <= d`` (``n`` outward) the gap is the wall's gap
at that point, ``s (d - n . c - h)``: it is the one contact of the disc with
that wall, and it moves along the rim as the disc turns.

Derivatives along a flight. The wall's gap at the rim point changes as that
of a point fixed in the disc (the first derivative of a maximum is the
derivative at the maximiser): ``g' = -s n . (v + omega r_alpha)``. The second
is not a fixed point's: with ``psi`` the normal's angle in the disc's frame,
``h_psi_psi = rho_c - h``, ``rho_c = a^2 b^2 / h^3`` the rim's radius of
curvature at the contact, so ``g'' = s omega^2 (h - rho_c)``. Over all
orientations (``A = max(a, b)``, ``B = min(a, b)``): ``h - rho_c`` lies in
``[B - A^2/B, A - B^2/A]``, and ``|h'''| <= (3 A^2/B^2 + 1) (A^2 - B^2) / (2 B)``
(``|h_psi| <= (A^2 - B^2) / (2 B)``).
"""

from __future__ import annotations

import math

import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np

from jaxbill._engine.validation import broadcast_parameters, is_concrete
from jaxbill._scenes.bodies.base import Body, checked_mass_and_inertia, scalar_leaf
from jaxbill._scenes.bodies.point import checked_length
from jaxbill._scenes.tables.base import Motion, Piece, along_path


class EllipseBody(Body):
    """A rigid elliptic disc (a coin seen edge-on is its limit ``b -> 0``) touching flat walls.

    Args:
        a: semi-axis along the body's x axis, ``> 0`` (length).
        b: semi-axis along its y axis, ``> 0``; ``a = b`` is a round disc.
        mass: ``M > 0`` (default 1).
        inertia: moment of inertia about the centre, ``> 0``; ``None`` means the
            uniform disc's ``M (a^2 + b^2) / 4``; ``float('inf')``: never turns.

    Only tables of flat walls (``jb.Strip``, ``jb.Polygon``) can hold it: its
    contact with a curved wall is not a support point.
    """

    a: jax.Array
    b: jax.Array
    mass: jax.Array
    inertia: jax.Array
    kind: str = eqx.field(static=True)

    def __init__(self, a, b, mass=1.0, inertia=None):
        if inertia is None:
            inertia = mass * (a * a + b * b) / 4.0
        if all(is_concrete(v) for v in (a, b, mass, inertia)):
            a = checked_length("a", a, "the semi-axis along the body's x axis")
            b = checked_length("b", b, "the semi-axis along the body's y axis")
            broadcast_parameters(a=a, b=b, mass=mass, inertia=inertia)
            mass, inertia, kind = checked_mass_and_inertia(mass, inertia)
        else:
            kind = "static" if isinstance(inertia, float) and math.isinf(inertia) else "rotor"
        self.a, self.b, self.mass, self.inertia = (scalar_leaf(v) for v in (a, b, mass, inertia))
        self.kind = kind

    @property
    def contact_names(self):
        return ("the rim",)

    def check(self) -> None:
        checked_length("a", self.a, "the semi-axis along the body's x axis")
        checked_length("b", self.b, "the semi-axis along the body's y axis")
        checked_mass_and_inertia(self.mass, self.inertia)

    def parameters_are_valid(self):
        ok = (self.a > 0) & (self.b > 0) & jnp.isfinite(self.a) & jnp.isfinite(self.b)
        ok &= (self.mass > 0) & jnp.isfinite(self.mass)
        if self.kind == "rotor":
            ok &= (self.inertia > 0) & jnp.isfinite(self.inertia)
        return ok

    @property
    def radius(self):
        return jnp.maximum(self.a, self.b)

    @property
    def width(self):
        return 2.0 * jnp.minimum(self.a, self.b)

    def offsets(self, cos, sin):
        # Not points: the orientation itself, from which each wall's contact follows.
        return cos, sin

    @property
    def turn_symmetry(self) -> int:
        return 2

    def outline(self, alpha) -> np.ndarray:
        turn = np.linspace(0.0, 2.0 * np.pi, 121)
        a, b, c, s = float(self.a), float(self.b), float(np.cos(alpha)), float(np.sin(alpha))
        x, y = a * np.cos(turn), b * np.sin(turn)
        return np.stack([c * x - s * y, s * x + c * y], axis=-1)

    def orientation_for(self, direction):
        """The orientation that puts the disc's own x axis (semi-axis ``a``) along ``direction``."""
        return direction

    def supports(self, piece: Piece) -> bool:
        return piece.flat

    def _support(self, piece: Piece, cx, cy, orientation):
        """``(px, py, rx, ry, h)``: the rim point farthest along the wall's normal, its offset, the extent."""
        cos, sin = orientation
        nx, ny, _, _ = piece.plane()
        along, across = nx * cos + ny * sin, ny * cos - nx * sin
        pa, pb = self.a * self.a * along, self.b * self.b * across
        h = jnp.sqrt(pa * along + pb * across)
        rx, ry = (pa * cos - pb * sin) / h, (pa * sin + pb * cos) / h
        return cx + rx, cy + ry, rx, ry, h

    def contact_points(self, piece: Piece, cx, cy, offsets):
        px, py, rx, ry, _ = self._support(piece, cx, cy, offsets)
        return ((px, py, rx, ry),)

    def gaps_along(self, piece: Piece, cx, cy, vx, vy, omega, offsets, curvatures: bool):
        px, py, rx, ry, h = self._support(piece, cx, cy, offsets)
        tx, ty = self.turn_vector(rx, ry)
        gap, slope = along_path(piece, px, py, vx + omega * tx, vy + omega * ty)
        if not curvatures:
            return ((gap, slope),)
        *_, scale = piece.plane()
        rim_curvature_radius = (self.a * self.b) ** 2 / (h * h * h)
        return ((gap, slope, scale * (omega * omega) * (h - rim_curvature_radius)),)

    def bounds_jerk(self, piece: Piece) -> bool:
        return True

    def _extremes(self):
        return jnp.maximum(self.a, self.b), jnp.minimum(self.a, self.b)

    def flight_bounds(self, piece: Piece, motion: Motion):
        *_, scale = piece.plane()
        major, minor = self._extremes()
        spin2 = motion.omega * motion.omega
        lower = scale * spin2 * (major * major / minor - minor)
        upper = scale * spin2 * (major - minor * minor / major)
        jerk_factor = (3.0 * major * major / (minor * minor) + 1.0) * (major * major - minor * minor) / (2.0 * minor)
        return lower, upper, scale * jnp.abs(motion.omega) * spin2 * jerk_factor
