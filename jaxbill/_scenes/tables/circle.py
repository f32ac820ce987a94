"""The circle: the table ``|P| <= R``, one wall, the gap ``R^2 - |P|^2``.

Bounds along a flight (derivation). A contact point ``P = c + r``, ``|r| <= rho``
turning at ``omega`` (``r'' = -omega^2 r``), on a centre ``c + v t``::

    g = R^2 - |c|^2 - 2 c . r - |r|^2,     g'' = -2 |v|^2 - 2 (c . r)'',
    (c . r)'' = 2 v . r' + c . r'',   |(c . r)''| <= 2 |v| |omega| rho + omega^2 rho |c|,
    g''' = -2 (3 v . r'' + c . r'''),  |g'''| <= 2 rho omega^2 (3 |v| + |omega| |c|).

``|c(t)|`` until the first contact: the weighted mean of the contact gaps with
weights ``w_k`` that put the centre of mass at their barycentre is
``R^2 - |c|^2 - sum w_k |r_k|^2 >= 0`` while every gap is, so
``|c| <= sqrt(R^2 - inner_radius2)`` (``sqrt(R^2 - ell^2)`` for a stick), or
the start's ``|c|`` if larger (an end that starts on the wall by rounding).
The quiet region is the disc of radius ``R - rho``: no contact point can reach
the wall while the centre is inside it.
"""

from __future__ import annotations

from typing import ClassVar

import jax
import jax.numpy as jnp
import numpy as np

from jaxbill._engine.validation import check_parameter, real_parameter
from jaxbill._scenes.tables.base import KICK_NORMAL_SQUARED, Motion, Piece, Table, disc_crossing


class DiscWall(Piece):
    """The wall of the disc ``|P| <= radius`` about the origin: ``g = radius^2 - |P|^2`` (area)."""

    radius: jax.Array

    straight_exit: ClassVar[bool] = True
    bounds_jerk: ClassVar[bool] = True

    def gap(self, x, y):
        return self.radius**2 - (x * x + y * y)

    def gradient(self, x, y):
        return -2.0 * x, -2.0 * y

    def hessian_form(self, x, y, dx, dy):
        return -2.0 * (dx * dx + dy * dy)

    @property
    def gap_scale(self):
        return self.radius**2

    def along_flight(self, cx, cy, rx, ry, vx, vy, tx, ty, omega, curvature: bool):
        # |c + r|^2 = |c|^2 + 2 c . r + |r|^2 term by term: forming c + r first would keep a short
        # offset only to the rounding of c (a stick of half-length 1e-6 in a circle of radius 2 to
        # 1e-10 of its own length). r . t = 0 for a rigid turn.
        cross = cx * rx + cy * ry
        gap = (self.radius**2 - (rx * rx + ry * ry) - (cx * cx + cy * cy)) - 2.0 * cross
        slope = -2.0 * (cx * vx + cy * vy) - 2.0 * ((vx * rx + vy * ry) + omega * (cx * tx + cy * ty))
        if not curvature:
            return gap, slope
        curve = -2.0 * (vx * vx + vy * vy) - 2.0 * omega * (2.0 * (vx * tx + vy * ty) - omega * cross)
        return gap, slope, curve

    def _centre_reach(self, motion: Motion):
        """A bound on ``|c(t)|`` until the first contact (module docstring)."""
        start = jnp.sqrt(motion.cx * motion.cx + motion.cy * motion.cy)
        return jnp.maximum(jnp.sqrt(jnp.maximum(self.radius**2 - motion.inner_radius2, 0.0)), start)

    def curvature_bounds(self, motion: Motion):
        speed = jnp.sqrt(motion.vx * motion.vx + motion.vy * motion.vy)
        spin = jnp.abs(motion.omega)
        wobble = 2.0 * motion.radius * (2.0 * spin * speed + spin * spin * self._centre_reach(motion))
        return 2.0 * speed * speed + wobble, wobble - 2.0 * speed * speed

    def jerk_bound(self, motion: Motion):
        speed = jnp.sqrt(motion.vx * motion.vx + motion.vy * motion.vy)
        spin = jnp.abs(motion.omega)
        return 2.0 * motion.radius * (spin * spin * (3.0 * speed + spin * self._centre_reach(motion)))

    def quiet_interval(self, motion: Motion):
        return disc_crossing(motion.cx, motion.cy, motion.vx, motion.vy, self.radius - motion.radius)

    def exit_time(self, px, py, vx, vy):
        speed2 = vx * vx + vy * vy
        b = px * vx + py * vy
        gap = self.radius * self.radius - (px * px + py * py)
        disc = b * b + speed2 * gap
        root = jnp.sqrt(jnp.maximum(disc, 0.0))
        # Cancellation-free forms of the larger root of speed2 t^2 + 2 b t - gap = 0.
        # A point outside by rounding (gap < 0) whose line misses the disc
        # (disc < 0: a grazing chord shorter than rounding) takes the chord of
        # the tangent line through it, as if on the rim: ``-2 b / speed2``. The
        # clamped root would give the chord's midpoint, where the kick is zero and
        # every later flight has length 0.
        # Each form is a quotient: the numerator and denominator are chosen, then
        # divided once (the chosen quotient, to the bit, at a third of the divisions).
        inward = jnp.where(disc < 0.0, -2.0 * b, root - b)
        outward = b > 0.0
        t = jnp.where(outward, gap, inward) / jnp.where(outward, b + root, speed2)
        return jnp.where(speed2 > 0.0, jnp.maximum(t, 0.0), jnp.inf)

    def impulse_normal(self, x, y):
        # |N|^2 near pi/2 rather than near R^2: at a contact |P|^2 = R^2 to a few
        # ulps, and when that is a power of two (R = 2) the impulse's quotient
        # would round alike whatever those ulps are, biasing the energy by about
        # 0.2 ulp per collision (the same sign each time).
        scale = np.sqrt(KICK_NORMAL_SQUARED) / self.radius
        return scale * x, scale * y

    def boundary_coordinate(self, x, y):
        """``R phi``, ``phi`` the polar angle of the point in ``[0, 2 pi)``, from ``(R, 0)`` anticlockwise."""
        return self.radius * jnp.mod(jnp.arctan2(y, x), 2.0 * jnp.pi)

    def tangent(self, x, y):
        norm = jnp.sqrt(x * x + y * y)
        return -y / norm, x / norm

    @property
    def length(self):
        return 2.0 * jnp.pi * self.radius

    def point_at(self, s):
        return self.radius * jnp.cos(s / self.radius), self.radius * jnp.sin(s / self.radius)


class Circle(Table):
    """The circle of radius ``R`` about the origin, ``|P| <= R``: one wall, the gap ``R^2 - |P|^2`` (area).

    Args:
        R: the radius, ``R > 0`` (length).
    """

    R: jax.Array

    name: ClassVar[str] = "the circle"
    conserves_angular_momentum: ClassVar[bool] = True

    def __init__(self, R):
        self.R = jnp.asarray(R, dtype=jnp.float64)

    def check(self) -> None:
        R = real_parameter("R", self.R)
        check_parameter("R", R, np.isfinite(R) & (R > 0), "> 0 and finite")

    def parameters_are_valid(self):
        return (self.R > 0) & jnp.isfinite(self.R)

    @property
    def pieces(self):
        return (DiscWall(self.R),)

    @property
    def piece_names(self):
        return ("the circle",)

    @property
    def size(self):
        return self.R

    @property
    def extent(self):
        return -self.R, self.R, -self.R, self.R

    @property
    def diameter(self):
        return 2.0 * self.R

    @property
    def width(self):
        return 2.0 * self.R
