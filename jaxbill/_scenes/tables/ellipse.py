"""The ellipse: the table ``x^2/a^2 + y^2/b^2 <= 1``, one wall, and the bounds its first-root search needs.

A planar rigid body touches such a table at a few contact points, fixed in the
body frame (the stick: its two ends). Every table answers the same questions:

* the **gap** of a point, ``g(P) >= 0`` inside, a positive multiple of ``-F``;
* the **outward normal** ``N(P) = -grad g(P) / 2`` (not normalised), along
  which every impulse acts: the impulse is the one mass-metric reflection
  about ``grad g`` at the contact, whatever the table;
* **bounds on the second derivative** of ``g`` along a free flight of the body,
  from bounds on the Hessian of ``g`` and on ``|grad g|`` over the region the
  contacts can reach (``jaxbill._engine.first_root`` needs them to step safely);
* a **quiet region**: centre positions from which no contact point at distance
  ``<= rho`` from the centre can touch the wall, so that a search may jump
  over the part of a flight that stays in it;
* a **closed-form exit time** of a point moving on a straight line (a body that
  does not turn, or a point particle), where the gap is a quadratic in ``t``.

The ellipse ``x^2/a^2 + y^2/b^2 <= 1`` (semi-axis ``a`` along x, ``b`` along
y, either may be the larger; the circle is ``a = b = R``) is the one table
here. Its gap is scaled so that the circle's gap is ``R^2 - |P|^2``::

    g(P) = a b (1 - x^2/a^2 - y^2/b^2) = a b - P^T D P,   D = diag(b/a, a/b),

so ``grad g = -2 D P``, ``N = D P`` and ``Hess g = -2 D``: constant, with
eigenvalues ``-2 d_max <= -2 d_min`` where ``d_min = min(a, b)/max(a, b)`` and
``d_max = 1/d_min``. Scaling ``P`` by ``D^(1/2)`` turns the table into the disc
of radius ``sqrt(ab)``: that is why a straight flight has a quadratic gap.

Bounds along a flight (derivation)
----------------------------------
A contact point at the offset ``r(t)`` from the centre, ``|r| = rho`` fixed,
turning at the spin ``omega`` (``r' = omega J r``, ``r'' = -omega^2 r``, ``J``
the quarter turn), on a body whose centre moves as ``c(t) = c + v t``::

    g(t) = ab - c^T D c - 2 c^T D r - r^T D r

    g'' = -2 v^T D v - 2 (c^T D r)'' - (r^T D r)''
    (c^T D r)'' = 2 omega v^T D J r - omega^2 c^T D r,
                 |.| <= 2 |omega| |D v| rho + omega^2 |D c| rho
    r^T D r = rho^2 ((p + q)/2 + (p - q)/2 cos 2 phi),   D = diag(p, q),
                 |(r^T D r)''| = |2 omega^2 rho^2 (p - q) cos 2 phi| <= 2 omega^2 rho^2 |p - q|

so ``-2 v^T D v - w <= g'' <= -2 v^T D v + w`` with the *wobble*
``w = 2 rho (2 |omega| |D v| + omega^2 K) + 2 omega^2 rho^2 |p - q|``, where
``K >= |D c(t)|`` for every ``t`` up to the first contact. (``v^T D v`` is the
second derivative of ``-c^T D c / 2`` exactly: the bound keeps it, as the
circle's does.) For a = b this is the circle's bound exactly.

``K``: ``|D c|^2 = sum_i d_i^2 c_i^2 <= d_max c^T D c``. For weights
``w_k >= 0`` (sum 1) that put the centre of mass at the barycentre of the
contact points (``sum w_k r_k = 0``; for the stick, ``1/2`` each), the
weighted mean of the gaps is ``ab - c^T D c - sum w_k r_k^T D r_k``; until
the first contact every gap is ``>= -delta ab`` (``delta`` covers an end that
starts on the wall by rounding), so
``c^T D c <= ab (1 + delta) - d_min sum w_k |r_k|^2`` and
``K = sqrt(d_max (ab (1 + delta) - d_min inner_radius2))``
(``inner_radius2 = sum w_k |r_k|^2``: ``ell^2`` for the stick, 0 for a body
that gives no such weights, whose centre is then only known to be inside).

The quiet region (derivation)
-----------------------------
Every contact point is within ``rho`` of the centre, so none can touch while
the disc of radius ``rho`` about the centre lies inside the table. For convex
sets, ``E' + disc(rho) ⊂ E`` iff ``h_E'(n) + rho <= h_E(n)`` for every unit
``n``, ``h`` the support function; for the ellipse with minor semi-axis ``m``
and major ``M`` (any orientation of the axes), with ``w = n_major^2``,
``h_E(n)^2 = f(w)^2 = m^2 + (M^2 - m^2) w``. Take ``E'`` concentric, with
the axes of ``E``: ``h_E'^2 = L(w)`` is affine in ``w``, and the condition
reads ``L(w) <= (f(w) - rho)^2 = m^2 + rho^2 + (M^2 - m^2) w - 2 rho f(w)``
(for ``rho < m``, ``f - rho > 0``). ``f`` is concave (the square root of an
affine function), so the right side is convex and lies above its tangent at
``w = 0``; taking ``L`` to be that tangent gives the semi-axes

    minor: m - rho,    major: sqrt((m - rho) (M^2 - m rho) / m).

The ellipse with semi-axes ``(a - rho, b - rho)`` is *not* safe unless
``a = b``: its ``L`` is ``(f - rho)^2 - 2 rho (m + (M - m) w - f)``, and
``f(w) > m + (M - m) w`` (strict concavity) for ``0 < w < 1``: near the
ends of the major axis, where the wall's radius of curvature ``m^2 / M`` is
below ``rho``, a disc about its rim pokes out. For ``rho >= m`` no disc of
radius ``rho`` fits and the quiet region is empty.
"""

from __future__ import annotations

from typing import ClassVar

import jax
import jax.numpy as jnp
import numpy as np

from jaxbill._engine.validation import check_parameter, real_parameter
from jaxbill._scenes.tables.base import KICK_NORMAL_SQUARED, Motion, Piece, Table

# Relative slack ``delta`` in the bound on ``c^T D c``: an end may start this far
# (relative to ``ab``) through the wall by rounding (``WALL_TOLERANCE`` is 1e-12).
_REACH_SLACK = 1e-10

# Gauss-Legendre nodes and weights on [-1, 1] for the arc length quadrature.
_NODES, _WEIGHTS = np.polynomial.legendre.leggauss(64)
# Newton steps inverting s(t) (quadratic convergence from the linear guess).
_NEWTON_STEPS = 8


class EllipseWall(Piece):
    """The wall ``x^2/a^2 + y^2/b^2 = 1``; leaves ``a, b`` (lengths, ``> 0``), of shape ``()``.

    The gap is ``a b - P^T D P`` (area), ``D = diag(b/a, a/b)``: the circle's
    ``R^2 - |P|^2`` for ``a = b = R``.
    """

    a: jax.Array
    b: jax.Array

    straight_exit: ClassVar[bool] = True

    @property
    def gap_scale(self) -> jax.Array:
        """``a b``, the unit of the gap (``R^2`` for the circle)."""
        return self.a * self.b

    @property
    def metric(self) -> tuple[jax.Array, jax.Array]:
        """``(p, q) = (b/a, a/b)``: ``D = diag(p, q)``, ``g = ab - P^T D P``."""
        return self.b / self.a, self.a / self.b

    @property
    def metric_bounds(self) -> tuple[jax.Array, jax.Array]:
        """``(d_min, d_max)``, the eigenvalues of ``D`` (``Hess g = -2 D``)."""
        p, q = self.metric
        return jnp.minimum(p, q), jnp.maximum(p, q)

    def gap(self, x, y):
        p, q = self.metric
        return self.a * self.b - (p * (x * x) + q * (y * y))

    def gradient(self, x, y):
        p, q = self.metric
        return -2.0 * (p * x), -2.0 * (q * y)

    def hessian_form(self, x, y, dx, dy):
        p, q = self.metric
        return -2.0 * (p * (dx * dx) + q * (dy * dy))

    def gap_at(self, x, y):
        """``ab - P^T D P`` at ``P = (x, y)`` (scalars or equal-shaped arrays); ``>= 0`` inside."""
        return self.gap(x, y)

    def normal_at(self, x, y):
        """Outward normal ``N = D P = -grad g / 2`` at ``P = (x, y)`` (not unit): ``(Nx, Ny)``."""
        p, q = self.metric
        return p * x, q * y

    def reach(self, inner_radius2: jax.Array) -> jax.Array:
        """``K >= |D c|`` until the first contact of a body whose contact points' ``inner_radius2`` is given
        (``ell^2`` for a stick)."""
        d_min, d_max = self.metric_bounds
        inner = self.gap_scale * (1.0 + _REACH_SLACK) - inner_radius2 * d_min
        return jnp.sqrt(d_max * jnp.maximum(inner, 0.0))

    def wobble_bounds(self, vx, vy, omega, radius, reach):
        """``(lower_curv, upper_curv)``: ``-lower_curv <= g'' <= upper_curv`` for every contact point.

        ``(vx, vy)`` the centre's velocity, ``omega`` the spin, ``radius`` the
        largest distance of a contact point from the centre, ``reach`` a bound
        on ``|D c(t)|`` (``reach``). See the module docstring.
        """
        p, q = self.metric
        dvx, dvy = p * vx, q * vy
        straight = 2.0 * (vx * dvx + vy * dvy)  # 2 v^T D v
        spin = jnp.abs(omega)
        wobble = 2.0 * radius * (2.0 * spin * jnp.sqrt(dvx * dvx + dvy * dvy) + spin * spin * reach)
        wobble = wobble + 2.0 * (spin * radius) ** 2 * jnp.abs(p - q)
        return straight + wobble, wobble - straight

    def curvature_bounds(self, motion: Motion):
        p, q = self.metric
        start = jnp.sqrt((p * motion.cx) ** 2 + (q * motion.cy) ** 2)
        reach = jnp.maximum(self.reach(motion.inner_radius2), start)
        return self.wobble_bounds(motion.vx, motion.vy, motion.omega, motion.radius, reach)

    def quiet_semi_axes(self, radius: jax.Array) -> tuple[jax.Array, jax.Array]:
        """Semi-axes ``(along x, along y)`` of the quiet ellipse for contact points within ``radius``.

        A centre strictly inside it keeps every such point strictly inside the
        table (module docstring). Both are 0 (empty) when ``radius >= min(a, b)``.
        """
        minor, major = jnp.minimum(self.a, self.b), jnp.maximum(self.a, self.b)
        room = jnp.maximum(minor - radius, 0.0)
        along_minor = room
        along_major = jnp.sqrt(room * (major * major - minor * radius) / minor)
        x_major = self.a >= self.b
        return jnp.where(x_major, along_major, along_minor), jnp.where(x_major, along_minor, along_major)

    def quiet_interval(self, motion: Motion):
        """``(t_in, t_out)``: the times the centre ``c + v t`` (``t >= 0``) is inside the quiet ellipse.

        Empty (``t_in >= t_out``, both ``inf``) when the line misses it or the
        quiet ellipse is empty.
        """
        sx, sy = self.quiet_semi_axes(motion.radius)
        empty = (sx <= 0.0) | (sy <= 0.0)
        sx, sy = jnp.where(empty, 1.0, sx), jnp.where(empty, 1.0, sy)
        # In units of the semi-axes the quiet ellipse is the unit disc.
        t_in, t_out = _unit_disc_crossing(motion.cx / sx, motion.cy / sy, motion.vx / sx, motion.vy / sy)
        return jnp.where(empty, jnp.inf, t_in), jnp.where(empty, jnp.inf, t_out)

    def exit_time(self, px, py, vx, vy) -> jax.Array:
        """First ``t >= 0`` at which ``P + v t`` reaches the wall moving outwards.

        The gap along the line is ``g(t) = g0 - 2 h t - s t^2`` with
        ``g0 = g(P)``, ``h = P^T D v``, ``s = v^T D v``. A point on the wall
        moving inwards (``h <= 0``) gets the far root, never ``t = 0``; one on
        or through it moving outwards gets 0; a point at rest ``inf``.
        """
        p, q = self.metric
        speed2 = p * vx * vx + q * vy * vy
        h = p * px * vx + q * py * vy
        g0 = self.gap(px, py)
        disc = h * h + speed2 * g0
        root = jnp.sqrt(jnp.maximum(disc, 0.0))
        # The positive root of s t^2 + 2 h t - g0 = 0 in the form without
        # cancellation on each side of h = 0. Through the wall by rounding with
        # a line that misses the table (disc < 0): the chord of the tangent
        # line, -2h/s, so that the kick is not taken at the chord's midpoint
        # (a zero kick, and flights of length zero after it).
        inward = jnp.where(disc < 0.0, -2.0 * h / speed2, (root - h) / speed2)
        outward = g0 / (h + root)
        t = jnp.where(h <= 0.0, inward, outward)
        return jnp.where(speed2 > 0.0, jnp.maximum(t, 0.0), jnp.inf)

    def impulse_normal(self, x, y):
        # ``D P`` scaled so that ``|N|^2`` sits near pi/2 (see ``DiscWall.impulse_normal``).
        p, q = self.metric
        scale = np.sqrt(KICK_NORMAL_SQUARED) / jnp.sqrt(self.gap_scale)
        return (scale * p) * x, (scale * q) * y

    def speed_along(self, t):
        """``|P'(t)| = sqrt(a^2 sin^2 t + b^2 cos^2 t)``: arc length per unit of the parameter angle ``t``."""
        return jnp.sqrt((self.a * jnp.sin(t)) ** 2 + (self.b * jnp.cos(t)) ** 2)

    def _arc_within_quarter(self, r: jax.Array) -> jax.Array:
        """``int_0^r |P'(tau)| dtau`` for ``0 <= r <= pi/2`` by 64-point Gauss-Legendre quadrature.

        The integrand's nearest complex singularity is at ``Im tau = artanh(min/max)``
        of the axes; over a quarter turn (half-width ``pi/4``) the rule's error
        falls like ``rho^-128`` with ``rho = d/(pi/4) + sqrt(1 + (d/(pi/4))^2)``:
        below rounding for axis ratios up to about 10 (1e-16 at 10, still 1e-13 at 20).
        """
        half = 0.5 * r[..., None]
        taus = half * (1.0 + jnp.asarray(_NODES))
        return jnp.sum(jnp.asarray(_WEIGHTS) * self.speed_along(taus), axis=-1) * half[..., 0]

    def arc_length(self, t) -> jax.Array:
        """Arc length ``s(t)`` (length) from ``(a, 0)`` anticlockwise to the parameter angle ``t`` (radians).

        Summed by quarter turns: ``|P'|`` has period ``pi`` and is symmetric about
        ``pi/2``, so ``s(t) = k Q + s_k(r)``, ``t = k pi/2 + r``, ``Q`` the quarter
        arc and ``s_k(r) = s(r)`` for even ``k``, ``Q - s(pi/2 - r)`` for odd ``k``.
        """
        t = jnp.asarray(t, dtype=jnp.float64)
        quarter_turn = 0.5 * jnp.pi
        k = jnp.floor(t / quarter_turn)
        r = jnp.clip(t - k * quarter_turn, 0.0, quarter_turn)
        quarter = self._arc_within_quarter(jnp.full_like(t, quarter_turn))
        odd = jnp.remainder(k, 2.0) == 1.0
        part = jnp.where(odd, quarter - self._arc_within_quarter(quarter_turn - r), self._arc_within_quarter(r))
        return k * quarter + part

    @property
    def length(self) -> jax.Array:
        """The perimeter ``4 a E(1 - b^2/a^2)`` (length)."""
        return self.arc_length(2.0 * jnp.pi)

    def parameter_at(self, s) -> jax.Array:
        """The inverse of ``arc_length`` on ``[0, length)``: the parameter angle ``t`` with ``s(t) = s`` (Newton)."""
        s = jnp.asarray(s, dtype=jnp.float64)
        t = 2.0 * jnp.pi * s / self.length
        for _ in range(_NEWTON_STEPS):
            t = t - (self.arc_length(t) - s) / self.speed_along(t)
        return t

    def point_at(self, s):
        t = self.parameter_at(s)
        return self.a * jnp.cos(t), self.b * jnp.sin(t)

    def boundary_coordinate(self, x, y):
        """The arc length from ``(a, 0)`` anticlockwise to the point (on the wall)."""
        return self.arc_length(jnp.remainder(jnp.arctan2(y / self.b, x / self.a), 2.0 * jnp.pi))

    def tangent(self, x, y):
        t = jnp.arctan2(y / self.b, x / self.a)
        speed = self.speed_along(t)
        return -self.a * jnp.sin(t) / speed, self.b * jnp.cos(t) / speed


def _unit_disc_crossing(px, py, wx, wy):
    """``(t_in, t_out)``: the times ``t >= 0`` with ``|p + w t| < 1`` (both ``inf`` if none)."""
    speed2 = wx * wx + wy * wy
    h = px * wx + py * wy
    excess = px * px + py * py - 1.0
    disc = h * h - speed2 * excess
    root = jnp.sqrt(jnp.maximum(disc, 0.0))
    # The two roots of speed2 t^2 + 2 h t + excess = 0, each without cancellation.
    big = -(h + jnp.where(h < 0.0, -root, root))
    safe_big = jnp.where(big == 0.0, 1.0, big)
    t1, t2 = big / jnp.where(speed2 > 0.0, speed2, 1.0), excess / safe_big
    t_in, t_out = jnp.minimum(t1, t2), jnp.maximum(t1, t2)
    crosses = (speed2 > 0.0) & (disc > 0.0) & (t_out > 0.0) & (big != 0.0)
    at_rest_inside = (speed2 == 0.0) & (excess < 0.0)
    t_in = jnp.where(crosses, jnp.maximum(t_in, 0.0), jnp.where(at_rest_inside, 0.0, jnp.inf))
    t_out = jnp.where(crosses, t_out, jnp.inf)
    return t_in, t_out


class Ellipse(Table):
    """The ellipse ``x^2/a^2 + y^2/b^2 <= 1``: one wall, the gap ``a b - P^T D P`` (area), ``D = diag(b/a, a/b)``.

    Args:
        a: the semi-axis along x, ``a > 0`` (length).
        b: the semi-axis along y, ``b > 0``; either may be the larger.
    """

    a: jax.Array
    b: jax.Array

    name: ClassVar[str] = "the ellipse"

    def __init__(self, a, b):
        self.a, self.b = (jnp.asarray(v, dtype=jnp.float64) for v in (a, b))

    def check(self) -> None:
        for name, value, side in (("a", self.a, "x"), ("b", self.b, "y")):
            v = real_parameter(name, value)
            check_parameter(name, v, np.isfinite(v) & (v > 0), f"> 0 and finite (the semi-axis along {side})")

    def parameters_are_valid(self):
        return (self.a > 0) & (self.b > 0) & jnp.isfinite(self.a) & jnp.isfinite(self.b)

    @property
    def pieces(self):
        return (EllipseWall(self.a, self.b),)

    @property
    def piece_names(self):
        return ("the ellipse",)

    @property
    def size(self):
        return jnp.sqrt(self.a * self.b)

    @property
    def extent(self):
        return -self.a, self.a, -self.b, self.b

    @property
    def diameter(self):
        return 2.0 * jnp.maximum(self.a, self.b)

    @property
    def width(self):
        return 2.0 * jnp.minimum(self.a, self.b)
