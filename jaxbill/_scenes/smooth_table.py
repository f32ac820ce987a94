"""Tables bounded by a smooth convex curve ``F(P) = 0``, and what a first-root search needs of them.

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

``K``: ``|D c|^2 = sum_i d_i^2 c_i^2 <= d_max c^T D c``. For a body whose
contact points come in opposite pairs ``+-r`` (the stick), the mean of the
pair's gaps is ``ab - c^T D c - r^T D r``; until the first contact both gaps
are ``>= -delta ab`` (``delta`` covers an end that starts on the wall by
rounding), so ``c^T D c <= ab (1 + delta) - rho^2 d_min`` and
``K = sqrt(d_max (ab (1 + delta) - rho^2 d_min))`` (``sqrt(R^2 - ell^2)``
for the circle). The bound ``|grad g| = 2 |D P| <= 2 max(a, b)`` on the
table is what a body without such pairs would use instead, through the
centre being inside the table.

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

import equinox as eqx
import jax
import jax.numpy as jnp

# Relative slack ``delta`` in the bound on ``c^T D c``: an end may start this far
# (relative to ``ab``) through the wall by rounding (``WALL_TOLERANCE`` is 1e-12).
_REACH_SLACK = 1e-10


class EllipseTable(eqx.Module):
    """The table ``x^2/a^2 + y^2/b^2 <= 1``; leaves ``a, b`` (lengths, ``> 0``), of shape ``()``.

    Built on the fly from a scene's leaves, so that it is traced, vmapped and
    differentiated with them.
    """

    a: jax.Array
    b: jax.Array

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

    def gap_at(self, x, y):
        """``ab - P^T D P`` at ``P = (x, y)`` (scalars or equal-shaped arrays); ``>= 0`` inside."""
        p, q = self.metric
        return self.a * self.b - (p * (x * x) + q * (y * y))

    def normal_at(self, x, y):
        """Outward normal ``N = D P = -grad g / 2`` at ``P = (x, y)`` (not unit): ``(Nx, Ny)``."""
        p, q = self.metric
        return p * x, q * y

    def gap(self, points: jax.Array) -> jax.Array:
        """``gap_at`` of points ``(..., 2)``, shape ``(...)``."""
        return self.gap_at(points[..., 0], points[..., 1])

    def normal(self, points: jax.Array) -> jax.Array:
        """``normal_at`` of points ``(..., 2)``, shape ``(..., 2)``."""
        return jnp.stack(self.normal_at(points[..., 0], points[..., 1]), axis=-1)

    def reach(self, pair_radius: jax.Array) -> jax.Array:
        """``K >= |D c|`` until the first contact of a body with contact pairs ``+-r``, ``|r| = pair_radius``."""
        d_min, d_max = self.metric_bounds
        inner = self.gap_scale * (1.0 + _REACH_SLACK) - pair_radius**2 * d_min
        return jnp.sqrt(d_max * jnp.maximum(inner, 0.0))

    def curvature_bounds(self, vx, vy, omega, radius, reach):
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

    def quiet_interval(self, cx, cy, vx, vy, radius: jax.Array):
        """``(t_in, t_out)``: the times the centre ``c + v t`` (``t >= 0``) is inside the quiet ellipse.

        Empty (``t_in >= t_out``, both ``inf``) when the line misses it or the
        quiet ellipse is empty.
        """
        sx, sy = self.quiet_semi_axes(radius)
        empty = (sx <= 0.0) | (sy <= 0.0)
        sx, sy = jnp.where(empty, 1.0, sx), jnp.where(empty, 1.0, sy)
        # In units of the semi-axes the quiet ellipse is the unit disc.
        t_in, t_out = _unit_disc_crossing(cx / sx, cy / sy, vx / sx, vy / sy)
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
        g0 = self.gap_at(px, py)
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
