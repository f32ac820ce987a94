"""An independent check of ``jb.orbit``: the spiral-column billiard integrated with diffrax.

A planar body's state ``[x, y, alpha, vx, vy, omega]`` is a point ``(x, y, z)``,
``z = sqrt(I/M) alpha``, with velocity ``(vx, vy, vz)``, ``vz = sqrt(I/M) omega``.
The kinetic energy is ``M |(vx, vy, vz)|^2 / 2``: in these coordinates the
metric is Euclidean, so the elastic impulse is a specular reflection. Between
collisions the point flies straight; here that flight is *integrated* as the
ODE ``d(x, y, z)/dt = v, dv/dt = 0`` with a diffrax solver, not evaluated in
closed form. The wall is the column ``W_g >= 0`` of every gap ``g``, where
``W_g`` is the scene's own gap as a function of position: for the stick
(``ColumnFlight``, which ``StickInCircle`` and ``StickInEllipse`` hand out as
their ``checker_flight``) one per end ``k = +1, -1``,

    StickInCircle:   W_k(x, y, z) = R^2 - |P_k|^2,
    StickInEllipse:  W_k(x, y, z) = a b - P_k^T D P_k,   D = diag(b/a, a/b),

with ``P_k = c + k ell u(z / sqrt(I/M))``: one smooth sheet per end (their
intersection is the column's crease); for any body in any fixed table
(``BodyColumnFlight``, built from the ``RigidBodyColumn`` a ``jb.BodyInTable``
describes) one per contact and wall. A ``diffrax.Event`` on ``min_g W_g``
with an ``optimistix.Newton`` root finder stops the solve at the wall; the
velocity is reflected about ``N = grad W_g`` of the touching gap
(``jax.grad``), and a new solve starts from there.

Nothing here uses jaxbill's collision times, impulse law or root-search
bounds. What diffrax cannot promise is checked after every solve, step by
step: an even number of sign changes of ``W_g`` inside one solver step is
invisible to the event, and so is a root that is not the first one in the
step. Along a straight flight ``|W_g''| <= K``: for the stick
``K = 2 d_max ((|v| + ell |omega|)^2 + (|c|_max + ell) ell omega^2)``
(``d_max`` bounds the table's ``D``: 1 for the circle, ``max(a, b)/min(a, b)``
for the ellipse); for any body ``K = 2 Lambda_g |V|^2``, ``Lambda_g`` the
largest curvature of ``W_g`` in ``(x, y, z)``, sampled by the checker itself
(``BodyColumnFlight`` says why that suffices, and checks it at every step).
From ``K`` and the values and slopes of ``W_g`` at each step's ends a
certified lower bound of ``W_g`` over the step follows. A step whose bound is
not positive (except at the event itself) is *flagged*: the checker stops
there and says so instead of returning a sequence that might have skipped a
collision. The default ``dtmax`` keeps such flags rare: it is chosen so that a
hidden excursion could be at most ``graze_tol`` times the gap's unit (``R^2``,
``ab``) deep.

Accuracy. The flight is summed step by step, so the checker's own error grows
with the number of steps and with the angle turned: about ``ulp(alpha)`` per
step in ``alpha`` (``z`` is wrapped to one period at each solve to keep that
small). For ordinary orbits one flight agrees with ``jb.collide`` to 1e-12 or
better; for a short, fast-spinning stick (``ell / R = 1e-3``, thousands of
radians per flight) only to about 1e-8 (checked against the mpmath reference:
there the error is the checker's).
"""

from __future__ import annotations

import abc
import dataclasses
import inspect
import math
import time
from collections.abc import Callable
from typing import Any, ClassVar

import diffrax
import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np
from jaxtyping import ArrayLike, Real

from jaxbill._check.events import gaps_at_step_ends, solve_to_event
from jaxbill._check.report import (
    CheckFlag,
    CheckReport,
    CheckResult,
    certified_positive,
    comparison_report,
    first_index,
    wrap_angle,
)
from jaxbill._check.walls import ReducedWallsFlight
from jaxbill._engine.collision import collide as _collide
from jaxbill._engine.collision import orbit as _orbit
from jaxbill._engine.validation import MAX_STORED_COUNT, check_count
from jaxbill._scenes.protocols import ReducedWalls, RigidBodyColumn, Scene, StickColumn

__all__ = ["check", "CheckResult", "CheckReport", "CheckFlag", "ColumnFlight", "BodyColumnFlight"]

_FLAG_NAMES = {
    1: "graze",  # a wall not certified positive inside a step: a collision may hide there
    2: "max_steps",  # the solve hit max_steps before any event
    3: "root_find",  # the event's root finder failed
    4: "not_approaching",  # the contact at the event is not moving into the wall
    5: "corner",  # two gaps at the wall at once (jb.orbit reports contact 2)
    6: "curvature",  # a wall bends more at a step's end than the bound that certifies the steps
}


class _StraightColumn(eqx.Module):
    """What every column flight shares: the point ``(x, y, z = scale alpha)`` flies straight in the column
    ``W_g(x, y, z) >= 0`` of the scene's gaps and is reflected about ``grad W_g`` at a wall.

    In ``(x, y, z)`` with ``z = sqrt(I/M) alpha`` the kinetic energy is
    ``M |(vx, vy, vz)|^2 / 2``: the metric is Euclidean, so the elastic,
    frictionless impulse at a contact is the specular reflection about the
    gradient of that contact's gap. A subclass says what the walls are and how
    much they can bend along a straight flight (``curvature_bound``).
    """

    scale: eqx.AbstractVar[jax.Array]
    length: eqx.AbstractVar[jax.Array]
    frozen: eqx.AbstractVar[bool]

    # Whether ``_segment`` compares each wall's own curvature at every step's ends with the bound
    # (a bound that was sampled, not derived, is checked where the flight goes).
    guards_curvature: ClassVar[bool] = False

    @abc.abstractmethod
    def walls(self, pos: jax.Array) -> jax.Array:
        """Every gap ``W_g`` at the position ``pos = (x, y, z)``, shape ``(G,)``."""

    @abc.abstractmethod
    def curvature_bound(self, y0: jax.Array, y1: jax.Array) -> jax.Array:
        """A bound on ``|W_g''|`` over the straight flight from ``y0`` to ``y1``: one for every gap, or ``(G,)``."""

    @abc.abstractmethod
    def default_step(self, y: jax.Array, graze_tol: float) -> float:
        """The solver's largest step for the flight from ``y`` that hides no excursion deeper than
        ``graze_tol`` gap units."""

    @property
    @abc.abstractmethod
    def gap_unit(self) -> jax.Array:
        """The gaps' unit (the event's and the corner test's scale)."""

    @property
    @abc.abstractmethod
    def gap_codes(self) -> tuple[int, ...]:
        """The ``Orbit.contact`` code of each gap."""

    @property
    @abc.abstractmethod
    def turning(self) -> bool:
        """The walls depend on ``z`` and the impulse turns the body (spins compare in ``V / scale``)."""

    def prepared(self, state0: np.ndarray):
        """The flight ready for the orbit from ``state0`` (a flight that needs nothing of it: itself)."""
        del state0
        return self

    def _state(self, pos: jax.Array) -> jax.Array:
        zero = jnp.zeros((), pos.dtype)
        return jnp.stack([pos[0], pos[1], pos[2] / self.scale, zero, zero, zero])

    def walls_and_slopes(self, y: jax.Array):
        """``W_g`` and ``dW_g/dt`` along the flight (a JVP along the velocity)."""
        return jax.jvp(self.walls, (y[0:3],), (y[3:6],))

    def curvatures(self, y: jax.Array) -> jax.Array:
        """``d^2 W_g / dt^2`` along the flight at ``y`` (a JVP of the JVP along the velocity)."""
        velocity = y[3:6]

        def slopes(pos):
            return jax.jvp(self.walls, (pos,), (velocity,))[1]

        return jax.jvp(slopes, (y[0:3],), (velocity,))[1]

    def reflect(self, k_index: jax.Array, y: jax.Array) -> jax.Array:
        """Specular reflection of the velocity about ``grad W_k`` (Euclidean metric)."""
        normal = jax.grad(lambda pos: self.walls(pos)[k_index])(y[0:3])
        if self.frozen:  # the infinitely heavy body takes the z part of the impulse
            normal = normal.at[2].set(0.0)
        v = y[3:6]
        v = v - 2.0 * (v @ normal) / (normal @ normal) * normal
        return jnp.concatenate([y[0:3], v])

    def check(self, scene, state0, n: int, **options) -> CheckResult:
        """``jb.check`` for this flight (see ``check`` for the options; those not given keep its defaults)."""
        return _check_column(self, scene, state0, n, **{**_DEFAULT_OPTIONS, **options})


class ColumnFlight(_StraightColumn):
    """The straight flight of a planar stick's point ``(x, y, z = scale alpha)`` in the column its gaps bound.

    What a scene whose state is ``[x, y, alpha, vx, vy, omega]`` and whose
    table is fixed and convex (``StickInCircle``, ``StickInEllipse``) hands the
    checker (``HasCheckerFlight``): in ``(x, y, z)`` with ``z = sqrt(I/M) alpha``
    the metric is Euclidean, so a collision is a specular reflection about the
    gradient of the touching end's gap, and between collisions the point flies
    straight. The walls are the scene's own gaps as functions of position
    (``scene.gaps`` at zero velocity): geometry only, never its collision
    times or impulse law.

    Attributes:
        scene: the scene (one, unbatched); only ``gaps``, ``gap_codes`` and ``gap_scale`` are used.
        scale: ``sqrt(I/M)`` for a turning stick, 1 otherwise (``z = alpha``), length.
        length: the unit of length of the comparison (``R``; ``max(a, b)``).
        reach: a bound on ``|c|``, the centre's distance from the origin, inside the table.
        hessian_bound: ``d_max``: the gaps' Hessian in the contact point is
            ``-2 D`` with ``|D| <= d_max`` (1 for the circle).
        frozen: the stick never turns (infinite inertia): the impulse's z part is dropped.
        single_sheet: both ends are one point (``ell = 0``): no crease, no corner.
    """

    scene: Any
    scale: jax.Array
    length: jax.Array
    reach: jax.Array
    hessian_bound: jax.Array
    frozen: bool = eqx.field(static=True)
    single_sheet: bool = eqx.field(static=True)

    @property
    def ell(self) -> jax.Array:
        return self.scene.ell

    @property
    def gap_unit(self) -> jax.Array:
        return self.scene.gap_scale

    @property
    def gap_codes(self) -> tuple[int, ...]:
        return tuple(self.scene.gap_codes)

    @property
    def turning(self) -> bool:
        return not (self.frozen or self.single_sheet)

    def wall(self, k: float, pos: jax.Array) -> jax.Array:
        """The gap of end ``k`` (+1: P1, -1: P2) at position ``pos = (x, y, z)``."""
        return self.walls(pos)[0 if k > 0 else 1]

    def walls(self, pos: jax.Array) -> jax.Array:
        return self.scene.gaps(self._state(pos))

    def curvature_bound(self, y0: jax.Array, y1: jax.Array) -> jax.Array:
        """Bound on ``|W_k''|`` over the straight flight from ``y0`` to ``y1``.

        ``W = g(P)``, ``P = c + k ell u``: ``W'' = P'^T Hess g P' + grad g . P''``
        with ``|Hess g| <= 2 d_max``, ``|grad g| = 2 |D P| <= 2 d_max |P|``,
        ``|P'| <= |v| + ell |omega|`` and ``|P''| = ell omega^2``.
        """
        speed = jnp.linalg.norm(y0[3:5])
        spin = jnp.abs(y0[5] / self.scale)
        centre = jnp.maximum(jnp.linalg.norm(y0[0:2]), jnp.linalg.norm(y1[0:2]))
        return 2.0 * self.hessian_bound * ((speed + self.ell * spin) ** 2 + (centre + self.ell) * self.ell * spin**2)

    def default_step(self, y: jax.Array, graze_tol: float) -> float:
        # ``curvature_bound`` for the whole flight: the centre stays within ``reach`` inside the table.
        ell, scale = float(self.ell), float(self.scale)
        reach = max(float(self.reach), float(jnp.linalg.norm(y[0:2])))
        v, w = float(jnp.linalg.norm(y[3:5])), abs(float(y[5])) / scale
        K = 2.0 * float(self.hessian_bound) * ((v + ell * w) ** 2 + (reach + ell) * ell * w * w)
        return math.sqrt(8.0 * graze_tol * float(self.gap_unit) / K) if K > 0 else 1.0


# The sampled bound on the walls' Hessian is taken this many times over (``BodyColumnFlight``).
CURVATURE_SAFETY = 2.0
# Samples of the table's box along each axis, and of one turn of the body.
_BOX_SAMPLES = 17
_TURN_SAMPLES = 128
# Sampled configurations count where no gap is below ``-_SAMPLED_SHELL`` gap units: the table and a
# shell round it (a step that hides an excursion goes a little outside).
_SAMPLED_SHELL = 0.5
# Configurations per compiled batch of the sampling.
_SAMPLE_BATCH = 4096


class BodyColumnFlight(_StraightColumn):
    """The straight flight of any planar rigid body in a fixed table, in the column its ``G`` gaps bound.

    Built by ``jb.check`` from the scene's ``RigidBodyColumn``: the point
    ``(x, y, z = scale alpha)`` flies straight while every gap
    ``W_g(x, y, z)`` (the scene's ``gaps`` at zero velocity) is positive; at
    the first zero of ``min_g W_g`` it is reflected about ``grad W_g`` of the
    touching gap (``jax.grad``). A body that never turns (``frozen``) keeps
    ``z``; a point's gaps do not depend on ``z`` at all.

    The curvature bound. Along a straight flight ``q(t) = q + V t`` every gap
    has ``W_g'' = V^T H_g(q) V``, ``H_g`` the Hessian of ``W_g`` in ``q``
    (``(x, y)`` only for a point or a body that never turns), so
    ``|W_g''| <= Lambda_g |V|^2`` with ``Lambda_g`` the largest ``|eigenvalue|``
    of ``H_g`` over the configurations the flight can reach. This needs no
    formula of the scene's: it covers a body whose contact slides on its rim
    (the coin: ``W = d - n . c - h(alpha)``, ``W'' = -h''(alpha) omega^2``)
    as well as fixed contact points (``W = g(c + R(alpha) b)``). ``Lambda_g``
    is sampled (``jax.hessian`` of the gaps) on a grid: ``_BOX_SAMPLES`` along
    each axis of the table's box (a window of ``+-2 length`` round the start
    along an unbounded axis, the table taken to repeat itself along it, as
    the strip does) times ``_TURN_SAMPLES`` orientations over one turn (only
    the orbit's own one for a body that never turns), keeping the
    configurations within a shell round the table (``_SAMPLED_SHELL`` gap
    units, or more, below), and the start's own; the bound used is ``CURVATURE_SAFETY`` times the largest
    sample. Why that is enough (the grid's maximum is within a factor 2 of
    the supremum):

    * in the centre: the discs, ellipses and half-planes are quadratic in the
      contact point, the stadium piecewise so (its curvature jumps where the
      flat sides meet the half-discs; both regions are wide and sampled), so
      for fixed ``alpha`` every entry of ``H_g`` is affine in the centre on
      each region (``Hess g`` constant, ``grad g`` affine), and the largest
      ``|eigenvalue|`` of an affine matrix, a convex function, peaks at a
      grid cell's corners, all kept: the shell is widened to the gaps'
      largest slope times a cell's diagonal where that is more;
    * in ``alpha``, for a body with fixed contact points: each ``v^T H_g v``
      (``v`` a unit vector) is a trigonometric polynomial of degree 2 on each
      region, whose slope is at most twice its largest value (Bernstein), so
      the supremum exceeds the largest of ``_TURN_SAMPLES = 128`` equispaced
      samples by at most ``2 pi / 128``, 5 percent;
    * for the coin ``H_g`` depends on ``alpha`` alone, through
      ``h'' = rho_c - h``, whose slope is at most
      ``(3 A^2/B^2 + 1)(A^2 - B^2)/(2B)`` (``A, B`` the larger and smaller
      semi-axis): within half a sample spacing that changes ``h''`` by less
      than half of its largest value ``A^2/B - B`` for axis ratios ``A/B``
      up to 3.5; a flatter coin, and a user's ``jb.ConvexTable``, get an
      estimate.

    What a sampled bound cannot promise is guarded where the flight goes: at
    both ends of every solver step each ``|W_g''|`` is compared with the
    bound, and a step where it is exceeded is flagged (``curvature``), never
    certified.

    Attributes:
        gaps: the scene's gaps of a state (``RigidBodyColumn.gaps``).
        scale: ``sqrt(I/M)`` for a body that turns, 1 otherwise.
        length: the unit of length of the comparison (the table's size).
        wall_unit: the gaps' unit (``gap_unit``).
        extent: a box that holds the table, ``(x_low, x_high, y_low, y_high)``.
        hessian_bounds: ``Lambda_g`` per gap, ``(G,)`` (``None`` until ``prepared`` samples it).
        safety: the factor on ``Lambda_g`` (``CURVATURE_SAFETY``).
        wall_codes: the ``Orbit.contact`` code of each gap (``gap_codes``).
        frozen, point: as ``RigidBodyColumn``.
    """

    gaps: Callable[[jax.Array], jax.Array]
    scale: jax.Array
    length: jax.Array
    wall_unit: jax.Array
    extent: tuple[float, float, float, float] = eqx.field(static=True)
    wall_codes: tuple[int, ...] = eqx.field(static=True)
    frozen: bool = eqx.field(static=True)
    point: bool = eqx.field(static=True)
    hessian_bounds: jax.Array | None = None
    safety: float = CURVATURE_SAFETY

    guards_curvature: ClassVar[bool] = True

    @classmethod
    def of(cls, column: RigidBodyColumn) -> BodyColumnFlight:
        """The flight of a scene's ``RigidBodyColumn`` (its curvature bound still to sample: ``prepared``)."""
        return cls(
            gaps=column.gaps,
            scale=jnp.asarray(column.scale, jnp.float64),
            length=jnp.asarray(column.length, jnp.float64),
            wall_unit=jnp.asarray(column.gap_unit, jnp.float64),
            extent=tuple(float(e) for e in column.extent),  # type: ignore[arg-type]
            wall_codes=tuple(int(c) for c in column.gap_codes),
            frozen=bool(column.frozen),
            point=bool(column.point),
        )

    @property
    def gap_unit(self) -> jax.Array:
        return self.wall_unit

    @property
    def gap_codes(self) -> tuple[int, ...]:
        return self.wall_codes

    @property
    def turning(self) -> bool:
        return not (self.frozen or self.point)

    def walls(self, pos: jax.Array) -> jax.Array:
        return self.gaps(self._state(pos))

    def _squared_speed(self, y: jax.Array) -> jax.Array:
        """``|V|^2`` over the coordinates the walls depend on."""
        return y[3] ** 2 + y[4] ** 2 + (y[5] ** 2 if self.turning else 0.0)

    def curvature_bound(self, y0: jax.Array, y1: jax.Array) -> jax.Array:
        """``safety Lambda_g |V|^2`` for every gap, ``(G,)``: ``W_g'' = V^T H_g V`` along a straight flight."""
        del y1  # the bound holds over the whole table
        assert self.hessian_bounds is not None, "BodyColumnFlight.prepared samples the bound first"
        return self.safety * self.hessian_bounds * self._squared_speed(y0)

    def default_step(self, y: jax.Array, graze_tol: float) -> float:
        K = float(jnp.max(self.curvature_bound(y, y)))
        if K > 0:
            return math.sqrt(8.0 * graze_tol * float(self.gap_unit) / K)
        # Flat walls and a body that never turns: the gaps are linear in time, nothing hides in a step.
        speed = math.sqrt(float(self._squared_speed(y)))
        return float(self.length) / speed if speed > 0 else 1.0

    def prepared(self, state0: np.ndarray) -> BodyColumnFlight:
        """The flight with its curvature bound sampled for the orbit from ``state0`` (itself if it has one)."""
        if self.hessian_bounds is not None:
            return self
        configurations, cell = self._configurations(state0)
        parts = []
        for start in range(0, len(configurations), _SAMPLE_BATCH):
            batch = configurations[start : start + _SAMPLE_BATCH]
            padded = np.concatenate([batch, np.repeat(batch[-1:], _SAMPLE_BATCH - len(batch), axis=0)])
            parts.append([np.asarray(a)[: len(batch)] for a in _wall_shapes(self, jnp.asarray(padded))])
        norm, slope, low = (np.concatenate(a) for a in zip(*parts))
        # The shell holds every corner of a grid cell that reaches into the table: a gap changes by at most
        # its slope times the cell's diagonal across it (the slope sampled too, so taken 1.5 times over).
        unit = float(self.gap_unit)
        near = low >= -_SAMPLED_SHELL * unit
        shell = max(_SAMPLED_SHELL * unit, 1.5 * cell * float(np.max(slope[near], initial=0.0)))
        inside = low >= -shell
        inside[-1] = True  # the start itself
        sampled = norm[inside]
        if not np.all(np.isfinite(sampled)):
            where = configurations[np.flatnonzero(inside)[np.flatnonzero(~np.isfinite(sampled).all(axis=1))[0]]]
            raise ValueError(
                f"scene: its gaps' Hessian is not finite at (x, y, z) = {where.tolist()}: "
                "the checker cannot bound how the walls bend"
            )
        return dataclasses.replace(self, hessian_bounds=jnp.asarray(sampled.max(axis=0)))

    def _configurations(self, state0: np.ndarray) -> tuple[np.ndarray, float]:
        """The sampled positions ``(N, 3)`` in ``(x, y, z)``, the last one the start's, and the diagonal of a
        grid cell in ``(x, y)``."""
        x_low, x_high, y_low, y_high = self.extent
        window = 2.0 * float(self.length)
        if not (math.isfinite(x_low) and math.isfinite(x_high)):
            x_low, x_high = state0[0] - window, state0[0] + window
        if not (math.isfinite(y_low) and math.isfinite(y_high)):
            y_low, y_high = state0[1] - window, state0[1] + window
        xs = np.linspace(x_low, x_high, _BOX_SAMPLES)
        ys = np.linspace(y_low, y_high, _BOX_SAMPLES)
        scale = float(self.scale)
        if self.turning:
            zs = scale * np.linspace(-np.pi, np.pi, _TURN_SAMPLES, endpoint=False)
        else:  # one orientation: the orbit's own (a point's walls do not depend on it)
            zs = np.array([scale * state0[2]])
        grid = np.stack(np.meshgrid(xs, ys, zs, indexing="ij"), axis=-1).reshape(-1, 3)
        start = np.array([state0[0], state0[1], scale * state0[2]])
        cell = math.hypot(xs[1] - xs[0], ys[1] - ys[0])
        return np.concatenate([grid, start[None]]), cell


@eqx.filter_jit
def _wall_shapes(flight: BodyColumnFlight, positions: jax.Array):
    """Per position ``(N, 3)``: the largest ``|eigenvalue|`` of each wall's Hessian ``(N, G)`` (in ``(x, y)``
    only where the walls do not depend on ``z`` or ``z`` never moves), the walls' largest slope in the centre
    ``(N,)`` and the smallest gap ``(N,)``."""

    def one(pos):
        hessian = jax.hessian(flight.walls)(pos)
        if not flight.turning:
            hessian = hessian[:, :2, :2]
        slopes = jnp.linalg.norm(jax.jacfwd(flight.walls)(pos)[:, :2], axis=-1)
        return jnp.max(jnp.abs(jnp.linalg.eigvalsh(hessian)), axis=-1), jnp.max(slopes), jnp.min(flight.walls(pos))

    return jax.vmap(one)(positions)


def _vector_field(t, y, args):
    return jnp.concatenate([y[3:6], jnp.zeros(3, y.dtype)])


@eqx.filter_jit
def _segment(column: _StraightColumn, y0, dtmax, solver, rtol, atol, root_tol, max_steps, corner_tol):
    """Integrate from ``y0`` to the next wall event (at most ``max_steps`` steps);
    certify the steps; reflect.

    Returns ``(t_event, y_after, contact_index, flag, flag_time, n_steps)``;
    flag 2 (out of steps, no event) returns the last state, unreflected.
    """

    def cond_fn(t, y, args, **kwargs):
        # At the start one wall is at zero (the end that just bounced), and
        # diffrax only sees a crossing from a positive value: start from +1 so
        # that the *other* end reaching the wall within the first step is seen.
        value = jnp.min(column.walls(y[0:3])) / column.gap_unit  # O(1), so root_tol is relative
        return jnp.where(t <= 0.0, 1.0, value)

    flight = solve_to_event(
        _vector_field,
        y0,
        t1=jnp.inf,
        dt0=dtmax,
        dtmax=dtmax,
        solver=solver,
        rtol=rtol,
        atol=atol,
        root_tol=root_tol,
        max_steps=max_steps,
        conditions=cond_fn,
    )
    ts, valid, n_steps, last = flight.ts, flight.valid, flight.n_steps, flight.last
    t_start, y_start, t_end, y_end = flight.t_start, flight.y_start, flight.t_end, flight.y_end
    t_event, y_event = ts[last], flight.ys[last]
    f0, p0, f1, p1 = gaps_at_step_ends(column.walls_and_slopes, flight, corner_tol * column.gap_unit)
    K = jax.vmap(column.curvature_bound)(y_start, y_end)
    K = K.reshape(K.shape[0], -1)  # one bound for every gap, or one per gap

    w_event, slope_event = column.walls_and_slopes(y_event)
    gap_index = jnp.arange(w_event.shape[0])
    k_index = jnp.argmin(w_event)
    event_ok = flight.result == diffrax.RESULTS.event_occurred
    is_last = (jnp.arange(ts.shape[0]) == last) & event_ok
    # The event itself is a root of the contacting wall: certify up to it only.
    at_event = is_last[:, None] & (gap_index[None, :] == k_index)
    f1 = jnp.where(at_event, jnp.maximum(f1, 0.0), f1)
    ok = certified_positive(f0, p0, f1, p1, (t_end - t_start)[:, None], K)
    bad = valid[:, None] & ~ok
    if column.guards_curvature:
        # A bound that was sampled is checked wherever the flight goes: at both ends of every step.
        bent = (jnp.abs(jax.vmap(column.curvatures)(y_start)) > K) | (jnp.abs(jax.vmap(column.curvatures)(y_end)) > K)
        bent = valid & jnp.any(bent, axis=1)
    else:
        bent = jnp.zeros_like(valid)
    bad_step = jnp.where(jnp.any(bent), jnp.argmax(bent), jnp.argmax(jnp.any(bad, axis=1)))

    flag = jnp.where(jnp.any(bent), 6, jnp.where(jnp.any(bad), 1, 0))
    flag = jnp.where((flag == 0) & (flight.result == diffrax.RESULTS.max_steps_reached), 2, flag)
    flag = jnp.where((flag == 0) & ~event_ok, 3, flag)
    flag = jnp.where((flag == 0) & (slope_event[k_index] >= 0.0), 4, flag)
    if w_event.shape[0] > 1:  # another gap at the wall too: a corner (a crease of the column)
        other = jnp.min(jnp.where(gap_index == k_index, jnp.inf, w_event))
        flag = jnp.where((flag == 0) & (other <= corner_tol * column.gap_unit), 5, flag)
    flag_time = jnp.where((flag == 1) | (flag == 6), t_start[bad_step], t_event)

    # A chunk that ran out of steps without an event hands back its last state unreflected.
    y_after = jnp.where(event_ok, column.reflect(k_index, y_event), y_event)
    return t_event, y_after, k_index, flag, flag_time, n_steps


# ---------------------------------------------------------------------------
# comparison helpers
# ---------------------------------------------------------------------------
def _scaled_deviation(a, b, scales):
    """Per-collision scaled deviations ``(time, position, angle, velocity, spin)``, shape (m, 5)."""
    (ta, sa), (tb, sb) = a, b
    t_s, r_s, v_s, w_s = scales
    dang = np.remainder(sa[:, 2] - sb[:, 2] + np.pi, 2 * np.pi) - np.pi
    return np.stack(
        [
            np.abs(ta - tb) / t_s,
            np.max(np.abs(sa[:, 0:2] - sb[:, 0:2]), axis=1) / r_s,
            np.abs(dang),
            np.max(np.abs(sa[:, 3:5] - sb[:, 3:5]), axis=1) / v_s,
            np.abs(sa[:, 5] - sb[:, 5]) / w_s,
        ],
        axis=1,
    )


# ---------------------------------------------------------------------------
# the checker
# ---------------------------------------------------------------------------
def check(
    scene: Scene,
    state0: Real[ArrayLike, " S"],
    n: int,
    *,
    tol: float = 1e-8,
    graze_tol: float = 1e-6,
    dtmax: float | None = None,
    solver=None,
    rtol: float = 1e-10,
    atol: float = 1e-12,
    root_tol: float = 1e-12,
    chunk_steps: int = 2048,
    max_steps: int = 2**20,
    corner_tol: float = 1e-12,
    horizon_eps: float = 1e-12,
) -> CheckResult:
    """Integrate the first ``n`` collisions with diffrax and compare with ``jb.orbit``.

    Args:
        scene: a single (unbatched) scene that answers ``checker_flight``
            (``jaxbill._scenes.protocols.HasCheckerFlight``). A ``BodyInTable``
            describes its geometry (a ``RigidBodyColumn``), from which the
            checker builds a ``BodyColumnFlight`` (this module: any body, any
            fixed table); ``StickInCircle`` and ``StickInEllipse`` give a
            ``ColumnFlight`` (this module);
            ``StickBetweenWalls2D``/``3D`` a ``ReducedWallsFlight``
            (``jaxbill._check.walls``: the reduced ``(z, psi)`` flight with
            its centrifugal potential; it takes ``tol``, ``graze_tol``,
            ``max_steps``, ``corner_tol`` and ``solver``, the rest keep its
            defaults, and lengths are in units of ``h``).
        state0: the start, shape ``(S,)`` (``[x, y, alpha, vx, vy, omega]`` for the column flights).
        n: number of collisions.
        tol: scaled tolerance of the comparison (see ``CheckReport``) and of
            the chaos horizon.
        graze_tol: sets the default ``dtmax`` per flight: a wall excursion
            hidden inside one step is at most ``graze_tol`` gap units (``R^2``) deep. Any
            step that could hide one is flagged whatever ``dtmax`` is.
        dtmax: fixed largest solver step (time units) instead of the default.
        solver: a diffrax solver (default ``diffrax.Tsit5()``).
        rtol, atol: the PID controller's tolerances.
        root_tol: ``optimistix.Newton`` tolerances (on the event time and on
            ``W / R^2``); Newton converges quadratically, so the time it
            returns is far more accurate than this.
        chunk_steps: solver steps per diffrax solve (static: the size of the
            saved-steps buffer that is certified after each solve); a flight
            longer than that continues in a new solve from where it stopped.
        max_steps: solver steps allowed per flight, over all its solves.
        corner_tol: two gaps within ``corner_tol`` gap units (``R^2``) of the wall
            at an event is a corner hit, flagged (``jb.orbit`` merges it into contact 2).
        horizon_eps: relative size of the perturbations that set the chaos
            horizon: ``jb.orbit`` from ``state0`` perturbed in four fixed
            directions (scaled as in ``CheckReport``); the horizon is the first
            collision at which any of them departs from ``jb.orbit(state0)`` by
            more than ``tol`` or in its contact. Past it the two orbits are
            compared one collision at a time only (``local_*`` in the report).

    Returns:
        ``CheckResult``: the checker's certified collisions and a ``CheckReport``
        (``print`` it). The checker stops at the first collision it cannot
        certify and records a ``CheckFlag``; it never returns collisions past it.

    Raises:
        NotImplementedError: for a batched scene or ``state0``.
        TypeError: for a scene without ``checker_flight``.
        ValueError: for ``n`` not a positive integer (at most ``2**31 - 1``),
            a complex or non-numeric ``state0``, or an invalid ``state0`` (as
            ``jb.orbit``).
    """
    n = check_count("n", n, 1, "number of collisions", MAX_STORED_COUNT)
    dtype = np.asarray(state0).dtype
    if not (np.issubdtype(dtype, np.floating) or np.issubdtype(dtype, np.integer)):
        raise ValueError(f"state0 must be real numbers; got dtype {dtype}")
    flight_of = getattr(scene, "checker_flight", None)
    if flight_of is None:
        raise TypeError(
            f"scene: {type(scene).__name__} gives no checker_flight (the HasCheckerFlight protocol of "
            "jaxbill._scenes.protocols): jb.check cannot integrate it"
        )
    options = dict(
        tol=tol,
        graze_tol=graze_tol,
        dtmax=dtmax,
        solver=solver,
        rtol=rtol,
        atol=atol,
        root_tol=root_tol,
        chunk_steps=chunk_steps,
        max_steps=max_steps,
        corner_tol=corner_tol,
        horizon_eps=horizon_eps,
    )
    state0 = np.asarray(state0, dtype=np.float64)
    if any(np.ndim(leaf) for leaf in jax.tree_util.tree_leaves(scene)):
        raise NotImplementedError("jaxbill.check takes one scene, not a batch; loop over a batch")
    scene.check()
    return flight_for(scene, flight_of()).check(scene, state0, n, **options)


def flight_for(scene, description):
    """The flight the checker integrates for a scene's ``checker_flight()`` description (a geometry the
    scene states; the integrator is the checker's own)."""
    if isinstance(description, RigidBodyColumn):
        return BodyColumnFlight.of(description)
    if isinstance(description, StickColumn):
        return ColumnFlight(
            scene=scene, **{f.name: getattr(description, f.name) for f in dataclasses.fields(description)}
        )
    if isinstance(description, ReducedWalls):
        return ReducedWallsFlight(planar=description.planar)
    return description  # a flight of the scene's own (``CheckerFlight``)


# ``jb.check``'s defaults, for a flight's ``check`` called with some options only.
_DEFAULT_OPTIONS = {
    name: parameter.default
    for name, parameter in inspect.signature(check).parameters.items()
    if parameter.kind is inspect.Parameter.KEYWORD_ONLY
}


def _check_column(
    column: _StraightColumn,
    scene,
    state0: np.ndarray,
    n: int,
    *,
    tol,
    graze_tol,
    dtmax,
    solver,
    rtol,
    atol,
    root_tol,
    chunk_steps,
    max_steps,
    corner_tol,
    horizon_eps,
) -> CheckResult:
    """``check`` for a column flight: integrate flight by flight, certify each step, compare with ``jb.orbit``."""
    start = time.perf_counter()
    if state0.shape != (6,):
        raise NotImplementedError("jaxbill.check takes one scene and one state0 of shape (6,); loop over a batch")
    reference = _orbit(scene, state0, n)  # also validates state0 eagerly
    column = column.prepared(state0)
    length, mass = float(column.length), float(scene.mass)
    gap_unit, scale = float(column.gap_unit), float(column.scale)
    solver = diffrax.Tsit5() if solver is None else solver

    y = jnp.asarray(
        [state0[0], state0[1], scale * state0[2], state0[3], state0[4], scale * state0[5]], dtype=jnp.float64
    )
    if column.frozen:
        y = y.at[5].set(0.0)
    t_abs = 0.0
    times, contacts, states, flags = [], [], [], []
    total_steps = 0
    for i in range(n):
        step = column.default_step(y, graze_tol) if dtmax is None else float(dtmax)
        flight_t, flight_steps = 0.0, 0
        while True:
            # The column is periodic in z (period 2 pi sqrt(I/M)): keeping z small
            # keeps the integrator's rounding per step at ulp(z) small.
            if not column.frozen:  # a body that never turns keeps its alpha exactly, as jb.orbit does
                y = y.at[2].set(scale * wrap_angle(float(y[2]) / scale))
            t_ev, y_new, k_index, flag, flag_time, n_steps = _segment(
                column, y, jnp.asarray(step), solver, rtol, atol, root_tol, chunk_steps, corner_tol
            )
            flag, n_steps = int(flag), int(n_steps)
            total_steps += n_steps
            flight_steps += n_steps
            if flag == 2 and flight_steps < max_steps:  # out of steps, no event: go on
                flight_t += float(t_ev)
                y = y_new
                continue
            break
        flag_time = flight_t + float(flag_time)
        t_ev = flight_t + float(t_ev)
        if flag:
            kind = _FLAG_NAMES[flag]
            message = {
                "graze": f"a wall excursion could hide in the solver step from t = {t_abs + flag_time:.6g} "
                f"(dtmax {step:.3g}); collision {i} and later not certified",
                "max_steps": f"no wall event within max_steps = {max_steps} steps of {step:.3g} after t = {t_abs:.6g}",
                "root_find": f"event root finder failed near t = {t_abs + t_ev:.6g}",
                "not_approaching": f"the contact at the event at t = {t_abs + t_ev:.6g} is not moving into the wall",
                "corner": f"two gaps at the wall at once at t = {t_abs + t_ev:.6g} (a crease of the column)",
                "curvature": f"a wall bends more than its bound {float(jnp.max(column.curvature_bound(y, y))):.3g} "
                "allows in the "
                f"solver step from t = {t_abs + flag_time:.6g}; collision {i} and later not certified",
            }[kind]
            flags.append(CheckFlag(index=i, kind=kind, message=message))
            break
        t_abs += t_ev
        y = y_new
        if column.frozen:
            y = y.at[5].set(0.0)
        alpha = float(y[2]) / scale if column.frozen else wrap_angle(float(y[2]) / scale)
        times.append(t_abs)
        contacts.append(column.gap_codes[int(k_index)])
        states.append([float(y[0]), float(y[1]), alpha, float(y[3]), float(y[4]), float(y[5]) / scale])

    t = np.asarray(times, dtype=np.float64)
    contact = np.asarray(contacts, dtype=np.int32)
    state = np.asarray(states, dtype=np.float64).reshape(-1, 6)

    # Scales and the chaos horizon.
    V = math.sqrt(2.0 * float(scene.energy(jnp.asarray(state0))) / mass) or 1.0
    spin_scale = V / scale if column.turning else V / length
    scales = (length / V, length, V, spin_scale)
    ref_t, ref_c, ref_s = (np.asarray(a) for a in (reference.t, reference.contact, reference.state))
    # Several perturbation directions: one alone may lie along a weakly growing direction.
    directions = np.array(
        [
            [0.6, -0.8, 0.0, 0.3, -0.7, 0.0],
            [-0.2, 0.5, 0.7, -0.6, 0.1, 0.4],
            [0.9, 0.1, -0.3, 0.2, 0.8, -0.5],
            [-0.4, -0.3, 0.2, 0.9, 0.3, 0.8],
        ]
    )
    if column.frozen:
        directions[:, 5] = 0.0
    if float(jnp.min(scene.gaps(jnp.asarray(state0)))) <= 1e-9 * gap_unit:
        # A start on the wall (just after a collision): a moved end could be
        # pushed through it; perturbing the velocities alone keeps it valid.
        directions[:, 0:3] = 0.0
    bumps = horizon_eps * directions * np.array([length, length, 1.0, V, V, spin_scale])
    perturbed = _orbit(scene, state0 + bumps, n)
    departed = np.zeros(n, bool)
    for b in range(len(bumps)):
        mine = (np.asarray(perturbed.t[b]), np.asarray(perturbed.state[b]))
        pd = _scaled_deviation(mine, (ref_t, ref_s), scales)
        departed |= (np.asarray(perturbed.contact[b]) != ref_c) | np.any(pd > tol, axis=1)
    horizon = first_index(departed)
    horizon = n if horizon is None else horizon

    m = min(len(t), horizon)
    dev = _scaled_deviation((t[:m], state[:m]), (ref_t[:m], ref_s[:m]), scales)
    # One collision at a time: jb.collide from each checker state (chaos-free).
    starts = np.concatenate([state0[None], state[:-1]]) if len(t) else np.zeros((0, 6))
    if len(t):
        one_state, one_dt, one_contact = jax.vmap(_collide, in_axes=(None, 0))(scene, jnp.asarray(starts))
        t_prev = np.concatenate([[0.0], t[:-1]])
        local = _scaled_deviation((np.asarray(one_dt), np.asarray(one_state)), (t - t_prev, state), scales)
        local_bad = (np.asarray(one_contact) != contact) | np.any(local > tol, axis=1)
        local_max = local.max(axis=0)
    else:
        local_bad, local_max = np.zeros(0, bool), np.zeros(5)
    report = comparison_report(n, contact, ref_c, horizon, tol, dev, local_max, local_bad, flags, total_steps, start)
    return CheckResult(t=t, contact=contact, state=state, orbit=reference, report=report)
