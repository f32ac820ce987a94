"""What a body answers: its mass, its inertia, and how it touches a table's walls.

A planar rigid body's state is ``[x, y, alpha, vx, vy, omega]``: its centre of
mass ``c = (x, y)``, its orientation ``alpha`` and their velocities. Its free
flight is the same for every body (a straight line and a uniform turn); its
kinetic energy is ``M |v|^2 / 2 + I omega^2 / 2``. What differs is where it
touches a wall:

* a body with **contact points fixed in its frame** (``VertexBody``: a point, a
  dumbbell, a rigid polygon) touches at those points ``P_k = c + r_k``, with
  ``r_k = R(alpha) b_k``; each gap is the wall's gap at ``P_k``, for every kind
  of wall (a convex body in a convex table touches only at its vertices);
* a **smooth convex body** (the elliptic coin) touches a flat wall at the point
  of its rim farthest along the wall's normal: its gap is the wall's offset less
  the body's support function.

Every contact's impulse is the same mass-metric reflection
(``jaxbill._scenes.impulse``): it needs the contact's offset from the centre
and the wall's outward normal there.
"""

from __future__ import annotations

import abc

import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np

from jaxbill._engine.validation import check_parameter, real_parameter
from jaxbill._scenes.tables.base import Motion, Piece, along_path

# What ``kind`` says: the body is a point (its spin is a free rotor, never kicked),
# never turns (infinite inertia: its orientation is a constant of the orbit), or turns.
KINDS = ("point", "static", "rotor")


def checked_mass_and_inertia(mass, inertia, point: bool = False):
    """Concrete ``mass`` and ``inertia`` as float64 arrays, and the kind ("static" for ``inertia = inf``).

    ValueError naming the parameter and its range otherwise. For a point the
    inertia only weighs its free spin in the energy (0 allowed).
    """
    mass = real_parameter("mass", mass)
    check_parameter("mass", mass, np.isfinite(mass) & (mass > 0), "> 0 and finite")
    inertia = real_parameter("inertia", inertia)
    check_parameter("inertia", inertia, ~np.isnan(inertia), "a number or inf, not NaN")
    if point:
        check_parameter("inertia", inertia, inertia >= 0, ">= 0 (a point's spin is a free rotor)")
        return mass, inertia, "point"
    check_parameter("inertia", inertia, inertia > 0, "> 0 (or inf for a body that never turns)")
    static = bool(np.all(np.isinf(inertia)))
    if not static and np.any(np.isinf(inertia)):
        raise ValueError("inertia must be all finite or all inf within one batch of scenes")
    return mass, inertia, "static" if static else "rotor"


class Body(eqx.Module):
    """A planar rigid body (an abstract ``equinox.Module``): mass, inertia, and its contacts with a wall.

    ``kind`` (static) is ``"point"``, ``"static"`` (infinite inertia) or
    ``"rotor"``; a scene compiles only the code of its kind.

    A body with contact points fixed in its frame gives the fields ``mass``
    (``M > 0``), ``inertia`` (``I`` about the centre of mass, mass times length
    squared; ``inf`` for ``"static"``) and ``kind``, and the abstract members:
    ``contact_names`` (``K`` names), ``radius`` (length), ``offsets(cos, sin)``
    (the ``K`` offsets ``r_k = R(alpha) b_k``, lengths), ``check`` and
    ``parameters_are_valid``; ``inner_radius2`` (area), ``diameter`` and
    ``width`` (lengths) sharpen the search and the fit check. A smooth body
    (the coin) also replaces the contact methods (``contact_points``,
    ``gaps_along``, ``flight_bounds``, ``supports``).
    """

    mass: eqx.AbstractVar[jax.Array]
    inertia: eqx.AbstractVar[jax.Array]
    kind: eqx.AbstractVar[str]

    @property
    @abc.abstractmethod
    def contact_names(self) -> tuple[str, ...]:
        """One name per contact with a wall (messages, gap names): ``("end P1", "end P2")``."""

    @property
    def contact_count(self) -> int:
        """``K``, the contacts the body has with one wall (static)."""
        return len(self.contact_names)

    @abc.abstractmethod
    def check(self) -> None:
        """ValueError naming a parameter out of its range (concrete values)."""

    @abc.abstractmethod
    def parameters_are_valid(self) -> jax.Array:
        """Traceable twin of ``check`` (for NaN poisoning inside ``jit``)."""

    @property
    @abc.abstractmethod
    def radius(self) -> jax.Array:
        """The largest distance of a point of the body from its centre of mass (length)."""

    @property
    def inner_radius2(self) -> jax.Array:
        """``sum_k w_k |b_k|^2`` for weights that put the centre of mass at the contacts' barycentre
        (``jaxbill._scenes.tables.base.Motion``); 0 when the body gives none."""
        return jnp.zeros_like(self.mass)

    @property
    def diameter(self) -> jax.Array:
        """The body's largest extent (length): it fits in no table whose longest chord is shorter."""
        return 2.0 * self.radius

    @property
    def width(self) -> jax.Array:
        """The body's smallest width over all directions (length)."""
        return jnp.zeros_like(self.mass)

    @property
    def mass_ratio(self) -> jax.Array:
        """``M / I``: 0 where the spin is never kicked (a point, a body that never turns)."""
        if self.kind == "rotor":
            return self.mass / self.inertia
        return jnp.zeros_like(self.mass)

    def energy(self, vx, vy, omega):
        """``M |v|^2 / 2 + I omega^2 / 2`` (a body that never turns drops the spin term: ``omega = 0``)."""
        translation = 0.5 * self.mass * (vx**2 + vy**2)
        if self.kind == "static":
            return translation
        return translation + self.spin_term(omega, 0.5 * self.inertia * omega**2)

    def spin_term(self, omega, term):
        """``term`` (``I omega^2 / 2`` or ``I omega``); for a point 0 where ``omega = 0`` (``I = inf``: not NaN)."""
        return jnp.where(omega == 0.0, 0.0, term) if self.kind == "point" else term

    @abc.abstractmethod
    def offsets(self, cos, sin) -> tuple:
        """The contacts' offsets ``r_k`` from the centre at orientation ``alpha`` (``cos``, ``sin`` of it):
        a K-tuple of ``(rx, ry)``, or ``None`` for a point (no offset at all)."""

    def turn_vector(self, rx, ry) -> tuple:
        """``d r / d alpha`` of an offset ``r``: a quarter turn anticlockwise, ``(-ry, rx)``."""
        return -ry, rx

    def outline(self, alpha) -> np.ndarray:
        """The body's shape at orientation ``alpha``, relative to its centre: ``(m, 2)`` points to draw joined
        (its contact points, closed round a polygon)."""
        offsets = self.offsets(jnp.cos(alpha), jnp.sin(alpha))
        if offsets is None:
            return np.zeros((1, 2))
        points = np.array([[float(rx), float(ry)] for rx, ry in offsets])
        return np.concatenate([points, points[:1]]) if len(points) > 2 else points

    @property
    def turn_symmetry(self) -> int:
        """``n``: the body looks the same after a turn by ``2 pi / n`` (static; 1 when it has no such symmetry)."""
        return 1

    def orientation_for(self, direction):
        """The orientation ``alpha`` at which the first contact's offset from the centre points along the angle
        ``direction`` (radians)."""
        (bx, by), *_ = self.offsets(jnp.ones(()), jnp.zeros(()))
        sense = jnp.sign(self.turn_vector(jnp.ones(()), jnp.zeros(()))[1])
        return sense * (direction - jnp.arctan2(by, bx))

    def supports(self, piece: Piece) -> bool:
        """Whether the body can touch this kind of wall (every wall for a body with contact points)."""
        return True

    # -- contacts with one wall (a piece); the defaults are those of contact points fixed in the body ----

    def contact_points(self, piece: Piece, cx, cy, offsets) -> tuple:
        """Per contact with ``piece``: ``(px, py, rx, ry)``, the contact point and its offset from the centre."""
        if offsets is None:
            zero = jnp.zeros_like(cx)
            return ((cx, cy, zero, zero),)
        return tuple((cx + rx, cy + ry, rx, ry) for rx, ry in offsets)

    def gaps_along(self, piece: Piece, cx, cy, vx, vy, omega, offsets, curvatures: bool) -> tuple:
        """Per contact with ``piece``: ``(g, g')``, or ``(g, g', g'')`` with ``curvatures``, at the moment the
        centre is at ``c``, the orientation's offsets are ``offsets``, and the body moves at ``(v, omega)``."""
        if offsets is None:
            zero = jnp.zeros_like(cx)
            return (along_path(piece, cx, cy, vx, vy, *((zero, zero) if curvatures else ())),)
        out = []
        for rx, ry in offsets:
            tx, ty = self.turn_vector(rx, ry)
            out.append(piece.along_flight(cx, cy, rx, ry, vx, vy, tx, ty, omega, curvatures))
        return tuple(out)

    def flight_bounds(self, piece: Piece, motion: Motion) -> tuple:
        """``(lower_curv, upper_curv, jerk or None)`` of every contact gap with ``piece`` along the flight."""
        return (*piece.curvature_bounds(motion), piece.jerk_bound(motion))

    def bounds_jerk(self, piece: Piece) -> bool:
        """Static: ``flight_bounds`` bounds the third derivative too (the search's sharper steps)."""
        return piece.bounds_jerk

    def quiet_interval(self, piece: Piece, motion: Motion) -> tuple:
        """The times no contact can reach ``piece`` (the piece's own answer for points within ``radius``)."""
        return piece.quiet_interval(motion)

    def exit_times(self, piece: Piece, cx, cy, vx, vy, offsets) -> tuple:
        """Per contact with ``piece``: its closed-form contact time for a body that does not turn."""
        return tuple(piece.exit_time(px, py, vx, vy) for px, py, _, _ in self.contact_points(piece, cx, cy, offsets))

    def has_closed_form(self, piece: Piece) -> bool:
        """Static: a flight of a body that does not turn reaches ``piece`` at a closed-form time."""
        return piece.straight_exit


def scalar_leaf(value) -> jax.Array:
    """A parameter as a float64 JAX array (a differentiable leaf)."""
    return jnp.asarray(value, dtype=jnp.float64)
