"""A rigid body in a convex table: any ``Body`` in any ``Table``, one scene for the engine and the analyses.

State layout (float64, shape ``(6,)``)::

    [x, y, alpha, vx, vy, omega]

``(x, y)`` is the body's centre of mass (length), ``alpha`` its orientation
(radians; wrapped into ``[-pi, pi)`` after each collision), ``(vx, vy)`` and
``omega`` their rates. A contact point fixed in the body at ``b`` sits at
``c + R(alpha) b``.

Contacts. The body's ``K`` contacts with each of the table's ``P`` walls are
the scene's gaps, numbered wall by wall: gap ``g = i K + k`` is contact ``k``
on wall ``i`` (``gap_names`` names them, ``gap_codes`` gives each its contact
code in ``Orbit.contact``: ``3 + g``; ``0`` none, ``2`` several at once).

The collision map. A body that turns has transcendental gaps: the first
contact is found by the certified safe-step search
(``jaxbill._engine.first_root``) from the walls' bounds; one that never turns
(infinite inertia) or a point moves its contacts on straight lines, and where
every wall has a closed-form exit time the scene compiles no search at all.
The impulse is the one mass-metric reflection (``jaxbill._scenes.impulse``).
"""

from __future__ import annotations

import dataclasses
import functools
import inspect
from typing import Any, ClassVar

import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np
from jaxtyping import ArrayLike

from jaxbill._engine.first_root import RootBounds, first_smallest, select
from jaxbill._engine.step import components, computed_once, cos_sin, stacked, wrapped_angle
from jaxbill._engine.validation import (
    is_concrete,
    motion_is_representable,
    on_wall_not_inwards,
    real_parameter,
    require_x64,
)
from jaxbill._scenes import body_sections, impulse
from jaxbill._scenes.bodies.base import Body
from jaxbill._scenes.protocols import (
    NO_CONTACT,
    SEVERAL_CONTACTS,
    WALL_TOLERANCE,
    RigidBodyColumn,
    SectionChart,
    chosen_section,
    component,
)
from jaxbill._scenes.shell_sampling import table_shell_candidates
from jaxbill._scenes.tables.base import Motion, Table

# The contact code of gap g (0 and 2 are taken: no contact, several at once).
FIRST_GAP_CODE = 3
# The contact code of a collision through a hole: the orbit left the table there.
ESCAPE_CODE = -1

# Orbits per vectorised lane of a batch on a CPU for a closed form (a search branches: one orbit after another).
CLOSED_FORM_LANES = 256


def _contact_name(contact: str, wall: str) -> str:
    return f"{contact} on {wall}"


def _scalar_fields(module) -> list:
    """``(name, value)`` of a body's or table's fields that are numbers (not static, no tuple of corners)."""
    out = []
    for field in dataclasses.fields(module):
        value = getattr(module, field.name)
        if field.metadata.get("static", False) or not isinstance(value, (jax.Array, np.ndarray, float, int)):
            continue
        out.append((field.name, value))
    return out


def _scalar(name: str, value) -> float:
    array = np.asarray(value)
    if array.ndim != 0:
        raise ValueError(f"{name}: one scene, not a batch: its parameters are scalars (shape {array.shape})")
    return float(array)


def _hole_intervals(holes, body: Body, table: Table) -> tuple[tuple[float, float], ...]:
    """``holes`` as sorted ``(s_low, s_high)`` float pairs, or ValueError naming what is wrong (the perimeter is
    checked by ``BodyInTable._check_holes`` once the table's parameters are concrete)."""
    if holes is None:
        return ()
    try:
        pairs = [tuple(hole) for hole in holes]
    except TypeError:
        raise ValueError(f"holes must be a sequence of (s_low, s_high) pairs; got {holes!r}") from None
    if not pairs:
        return ()
    intervals = []
    for pair in pairs:
        if len(pair) != 2:
            raise ValueError(f"holes must be a sequence of (s_low, s_high) pairs; got the entry {pair!r}")
        low, high = (float(real_parameter("holes", value)) for value in pair)
        if not (np.isfinite(low) and np.isfinite(high) and 0.0 <= low < high):
            raise ValueError(
                f"holes: each hole (s_low, s_high) must have 0 <= s_low < s_high <= the perimeter, "
                f"both finite; got ({low}, {high})"
            )
        intervals.append((low, high))
    if body.kind != "point":
        raise ValueError(
            f"holes: only a point (jb.PointBody) leaves a table through a hole; a {type(body).__name__} has "
            "extent, and which of its points in a hole would let it out is not defined"
        )
    if "birkhoff" not in table.section_names:
        raise ValueError(
            f"holes: {table.name} ({type(table).__name__}) has no Birkhoff section, so no arc length along a "
            "bounded boundary to place a hole on"
        )
    intervals.sort()
    for (low, high), (next_low, next_high) in zip(intervals, intervals[1:]):
        if next_low < high:
            raise ValueError(f"holes: the holes ({low}, {high}) and ({next_low}, {next_high}) overlap")
    return tuple(intervals)


class BodyInTable(eqx.Module):
    """A rigid ``body`` bouncing elastically inside a convex ``table``.

    Args:
        body: a ``jb.PointBody``, ``jb.Dumbbell``, ``jb.PolygonBody``,
            ``jb.EllipseBody`` or any ``jb.Body``.
        table: a ``jb.Circle``, ``jb.Ellipse``, ``jb.Stadium``, ``jb.Polygon``,
            ``jb.Strip``, ``jb.ConvexTable`` or any ``jb.Table``.
        holes: parts of the boundary through which a point leaves the table:
            a sequence of arc-length intervals ``(s_low, s_high)`` on the
            Birkhoff section's coordinate ``s`` (anticlockwise round the
            table from its origin; see ``section``), with
            ``0 <= s_low < s_high <= perimeter`` and no two overlapping (a
            hole across ``s = 0`` is two holes, ``(s, perimeter)`` and
            ``(0, s')``). A collision whose contact point lies in a hole
            (ends included) ends the orbit: ``Result.ESCAPED``, the state as
            it arrived (before any impulse), the time of the exit, contact
            ``-1`` (``ESCAPE_CODE``); every later collision has contact ``0``
            and ``dt = 0``. Only for ``jb.PointBody`` in a bounded table.
        stop_when: ``stop_when(state) -> bool``, pure and traceable: the
            orbit ends (``Result.STOPPED``) just after the first collision
            whose state makes it true, and stays there (every later collision
            has contact ``0`` and ``dt = 0``). ``state`` is the tuple of the
            six components ``(x, y, alpha, vx, vy, omega)``, each a scalar or
            an array of orbits (index it, ``state[0]``, and compute
            elementwise: every driver, the GPU kernel included, calls it on
            components). A module-level function reuses compiled code across
            scenes; a fresh lambda compiles anew.

    Both are ``equinox.Module``s: their parameters are differentiable leaves,
    their kind (a point, a body that never turns) is static, so a scene
    compiles only what it needs.

    A state is float64 ``[x, y, alpha, vx, vy, omega]``, shape ``(6,)`` (or
    ``(..., 6)``): the centre of mass (length), the orientation (radians), and
    their rates. The body's ``K`` contacts with the table's ``P`` walls are the
    ``G = P K`` gaps ``g = i K + k`` (contact ``k`` on wall ``i``);
    ``Orbit.contact`` is ``3 + g`` (``gap_codes``), ``2`` for several at once,
    ``0`` for none.

    Raises:
        TypeError: for a body or table of another type.
        ValueError: for a body that cannot touch one of the table's walls (the
            coin touches flat walls only) or that cannot fit in the table;
            for ``holes`` that are not intervals of the boundary, overlap, or
            are given for a body other than a point or a table without a
            bounded boundary; for a ``stop_when`` that is not callable.
    """

    body: Body
    table: Table
    holes: tuple[tuple[float, float], ...] = eqx.field(static=True)
    stop_when: Any = eqx.field(static=True)

    state_size: ClassVar[int] = 6
    state_layout: ClassVar[str] = "[x, y, alpha, vx, vy, omega]"
    symplectic_flow: ClassVar[bool] = True  # elastic impulses, a Hamiltonian flight
    periodic_symmetry: ClassVar[str] = "none"  # a periodic orbit closes in every coordinate
    periodic_angles: ClassVar[tuple[int, ...]] = (2,)  # compared modulo 2 pi when an orbit closes
    never_turning: ClassVar[str] = "a body that never turns"  # what messages call the body of infinite inertia

    def __init__(self, body: Body, table: Table, holes=(), stop_when=None):
        require_x64()
        if not isinstance(body, Body):
            raise TypeError(f"body must be a jaxbill body (jb.PointBody, jb.Dumbbell, ...); got {type(body).__name__}")
        if not isinstance(table, Table):
            raise TypeError(f"table must be a jaxbill table (jb.Circle, jb.Stadium, ...); got {type(table).__name__}")
        if body.kind != "point" and not table.convex:
            raise ValueError(
                f"body: a {type(body).__name__} cannot move in {table.name} ({type(table).__name__}): the table is "
                "not convex (a dispersing wall or a re-entrant corner), and a side of the body could touch it "
                "between the body's contact points, which no contact of the scene watches; only jb.PointBody "
                "moves there"
            )
        for piece, name in zip(table.pieces, table.piece_names):
            if not body.supports(piece):
                raise ValueError(
                    f"body: a {type(body).__name__} cannot touch {name} ({type(piece).__name__}): "
                    "it touches flat walls only (jb.Strip, jb.Polygon)"
                )
        self.body, self.table = body, table
        self.holes = _hole_intervals(holes, body, table)
        if stop_when is not None and not callable(stop_when):
            raise ValueError(f"stop_when must be a function of a state's components, or None; got {stop_when!r}")
        self.stop_when = stop_when
        if all(is_concrete(leaf) for leaf in jax.tree_util.tree_leaves(self)):
            # The table's own parameters first: a circle of radius -1 is a bad R, not a body that cannot fit.
            self.table.check()
            self._check_fit()
            self._check_holes()

    # -- parameters ---------------------------------------------------------------------

    def _check_fit(self) -> None:
        """ValueError for a body that fits in the table in no position."""
        if np.any(np.asarray(self.body.diameter) >= np.asarray(self.table.diameter)):
            raise ValueError(
                f"body: its length {float(np.max(self.body.diameter)):.6g} is not below the longest chord of "
                f"{self.table.name}, {float(np.min(self.table.diameter)):.6g}: it fits nowhere"
            )
        if np.any(np.asarray(self.body.width) >= np.asarray(self.table.width)):
            raise ValueError(
                f"body: its smallest width {float(np.max(self.body.width)):.6g} is not below the width of "
                f"{self.table.name}, {float(np.min(self.table.width)):.6g}: it fits nowhere"
            )

    @property
    def parameters(self) -> dict[str, float]:
        """The scene's parameters by name, as floats (one scene, not a batch: ValueError otherwise).

        A scene with a constructor of its own (``jb.StickInCircle(R, ell, mass,
        inertia)``, ...) gives that constructor's parameters. A body in a table
        gives the table's scalar parameters (``cap_radius``, ...), then the
        body's (a point's none: its mass and spin do not change its orbits),
        a body's named ``body_<name>`` where the table has the name already.
        ``with_parameters`` takes them back.
        """
        names = self._constructor_names
        if names is not None:
            return {name: _scalar(name, getattr(self, name)) for name in names}
        return {name: _scalar(name, getattr(getattr(self, part), field)) for name, (part, field) in self._paths.items()}

    def with_parameters(self, **values) -> BodyInTable:
        """The same scene with the parameters ``values`` (names as ``parameters`` gives them) changed.

        Raises:
            ValueError: for an unknown name, or values the table's, the body's
                or the constructor's checks refuse (the body must still fit).
        """
        current = self.parameters
        unknown = set(values) - set(current)
        if unknown:
            known = ", ".join(current)
            raise ValueError(f"{sorted(unknown)[0]}: not a parameter of this scene (its parameters: {known})")
        if self._constructor_names is not None:
            return type(self)(**{**current, **values})
        scene = self
        for name, value in values.items():
            part, field = self._paths[name]
            scene = eqx.tree_at(
                lambda s, p=part, f=field: getattr(getattr(s, p), f), scene, jnp.asarray(value, dtype=jnp.float64)
            )
        scene.check()
        return scene

    @property
    def _paths(self) -> dict[str, tuple[str, str]]:
        """Static: each public parameter's ``(part, field)``: ``("table", "cap_radius")``, ``("body", "l1")``."""
        paths = {name: ("table", name) for name, _ in _scalar_fields(self.table)}
        if self.body.kind != "point":
            for name, _ in _scalar_fields(self.body):
                paths["body_" + name if name in paths else name] = ("body", name)
        return paths

    @property
    def _constructor_names(self) -> tuple[str, ...] | None:
        """Static: the parameter names of a subclass's own constructor (``None`` for ``BodyInTable(body, table)``)."""
        init = type(self).__init__
        if init is BodyInTable.__init__:
            return None
        # The numbers it is built from; a keyword-only argument (a static ``kind``) is a choice, not a parameter.
        parameters = inspect.signature(init).parameters.values()
        return tuple(p.name for p in parameters if p.name != "self" and p.kind is p.POSITIONAL_OR_KEYWORD)

    def check(self) -> None:
        """Raise ValueError if the (possibly replaced) parameters are invalid, the body cannot fit, or a hole
        runs past the end of the boundary."""
        self.body.check()
        self.table.check()
        self._check_fit()
        self._check_holes()

    def _check_holes(self) -> None:
        """ValueError for a hole that ends beyond the perimeter (the table's parameters concrete)."""
        if not self.holes:
            return
        perimeter = float(np.min(np.asarray(self.table.boundary_length)))
        for low, high in self.holes:
            if high > perimeter:
                raise ValueError(
                    f"holes: the hole ({low}, {high}) ends beyond the boundary of {self.table.name}, whose arc "
                    f"length s runs over [0, {perimeter:.17g}]"
                )

    @property
    def kind(self) -> str:
        """The body's kind: ``"point"``, ``"static"`` (never turns) or ``"rotor"`` (static)."""
        return self.body.kind

    @property
    def body_turns(self) -> bool:
        """Static: the body turns (finite inertia, not a point): its spin is a coordinate of the dynamics."""
        return self.body.kind == "rotor"

    @property
    def body_is_point(self) -> bool:
        """Static: the body is a point, with no orientation."""
        return self.body.kind == "point"

    @property
    def mass(self) -> jax.Array:
        return self.body.mass

    @property
    def inertia(self) -> jax.Array:
        return self.body.inertia

    @property
    def gap_names(self) -> tuple[str, ...]:
        """One name per gap, wall by wall: ``"corner 2 on the stadium"``."""
        return tuple(
            _contact_name(contact, wall) for wall in self.table.piece_names for contact in self.body.contact_names
        )

    @property
    def wall_name(self) -> str:
        return self.table.name

    @property
    def gap_codes(self) -> tuple[int, ...]:
        """The contact code of each gap (``Orbit.contact``), wall by wall: ``3 + g``."""
        return tuple(FIRST_GAP_CODE + g for g in range(len(self.table.pieces) * self.body.contact_count))

    @property
    def contact_codes(self) -> tuple[int, ...]:
        """Every contact code a collision can have: the exit through a hole (with holes), none, several at once,
        and one per gap."""
        several = (SEVERAL_CONTACTS,) if len(self._cornering) > 1 else ()
        escape = (ESCAPE_CODE,) if self.holes else ()
        return (*escape, NO_CONTACT, *several, *self.gap_codes)

    @property
    def escape_code(self) -> int | None:
        """Static: the contact code of a collision through a hole (``ESCAPE_CODE``), ``None`` without holes."""
        return ESCAPE_CODE if self.holes else None

    @property
    def stop_condition(self):
        """Static: ``stop_when``, the condition on a state's components that ends an orbit (or ``None``)."""
        return self.stop_when

    @property
    def batch_chunk(self) -> int:
        """A search runs orbit after orbit (it branches; each orbit is then bitwise the orbit alone), a
        closed form in vectorised lanes of 256."""
        return 1 if self.searches_for_roots else CLOSED_FORM_LANES

    @property
    def gap_scale(self) -> jax.Array:
        return self.table.gap_scale

    @property
    def conserves_angular_momentum(self) -> bool:
        """Static: the table's wall pushes towards the origin, so ``angular_momentum`` is conserved."""
        return self.table.conserves_angular_momentum

    @property
    def length_scale(self) -> jax.Array:
        """A length of the table's size (its radius, ``sqrt(ab)``, the strip's height)."""
        return self.table.size

    # -- validation -----------------------------------------------------------------------

    def check_state_values(self, state: np.ndarray) -> None:
        shapes = {np.shape(leaf) for leaf in jax.tree_util.tree_leaves(self)}
        batch = max((s[0] for s in shapes if s), default=None)
        if batch is not None and state.ndim == 2 and batch != state.shape[0]:
            raise ValueError(f"a batch of {batch} scenes needs a batch of {batch} states; got {state.shape[0]}")
        if self.body.kind == "static" and np.any(state[..., 5] != 0):
            raise ValueError(
                f"omega must be 0 for {self.never_turning} (inertia = inf): an infinitely heavy body cannot spin"
            )
        if not self.table.intersection_of_pieces and np.all(np.isfinite(state)):
            # A union's gaps do not say whether a point is inside it; its clearance does.
            outside = np.asarray(self.clearances(jnp.asarray(state))) < -WALL_TOLERANCE * float(self.gap_scale)
            for k, name in enumerate(self.body.contact_names):
                if np.any(outside[..., k]):
                    row = np.argmax(np.reshape(outside[..., k], (-1,)))
                    raise ValueError(
                        f"state puts {name} outside {self.table.name}; first offending state: "
                        f"{np.reshape(state, (-1, 6))[row].tolist()}"
                    )

    def is_valid(self, state: jax.Array) -> jax.Array:
        ok = self.body.parameters_are_valid() & self.table.parameters_are_valid()
        ok &= jnp.all(jnp.isfinite(state)) & self.motion_is_representable(state)
        gaps = self.gaps(state)
        if self.table.intersection_of_pieces:
            ok &= jnp.all(gaps >= -WALL_TOLERANCE * self.gap_scale)
        else:
            ok &= jnp.all(self.clearances(state) >= -WALL_TOLERANCE * self.gap_scale)
        # A contact on the wall that does not move inwards is refused eagerly; a
        # tangential one would stall the map (zero-length flights), so poison.
        ok &= ~on_wall_not_inwards(gaps, self.approach_speeds(state))
        if self.body.kind == "static":
            ok &= state[5] == 0.0
        return ok

    def motion_is_representable(self, state) -> jax.Array:
        """Traceable: ``|v|^2``, ``omega^2`` and the energy are ordinary float64 numbers."""
        return motion_is_representable(state[..., 3:5], state[..., 5] ** 2, self.energy(state), self.table.size)

    # -- the engine's questions (jaxbill._engine.step); states are components ---------------

    def orbit_constants(self, state0: tuple):
        """A body that never turns keeps its contacts' offsets for a whole orbit."""
        if self.body.kind != "static":
            return None
        return self.body.offsets(*cos_sin(state0[2]))

    @property
    def searches_for_roots(self) -> bool:
        """Static: a turning body's gaps are transcendental; a straight flight's are closed forms where every
        wall gives one."""
        if self.body.kind == "rotor":
            return True
        return not all(self.body.has_closed_form(piece) for piece in self.table.pieces)

    def _offsets(self, alpha, constants=None):
        """The body's contact offsets at ``alpha`` (``None`` for a point; the orbit's constants if it never turns)."""
        if self.body.kind == "point":
            return None
        if self.body.kind == "static" and constants is not None:
            return constants
        return self.body.offsets(*cos_sin(alpha))

    def _motion(self, state: tuple) -> Motion:
        x, y, _, vx, vy, omega = state
        if self.body.kind != "rotor":
            omega = jnp.zeros_like(omega)  # its contacts move on straight lines
        body = self.body
        return Motion(x, y, vx, vy, omega, body.radius + jnp.zeros_like(x), body.inner_radius2 + jnp.zeros_like(x))

    @property
    def _sharp(self) -> bool:
        """Static: every wall bounds the gaps' third derivative, so the search takes its sharper steps."""
        return self.body.kind == "rotor" and all(self.body.bounds_jerk(piece) for piece in self.table.pieces)

    def root_search(self, state: tuple):
        """``(profile, RootBounds)`` of the flight from ``state`` (the profile is the state itself)."""
        motion = self._motion(state)
        lower, upper, jerk = [], [], []
        quiet_in, quiet_out = jnp.zeros_like(state[0]), jnp.full_like(state[0], jnp.inf)
        for piece in self.table.pieces:
            low, high, third = self.body.flight_bounds(piece, motion)
            lower.append(low)
            upper.append(high)
            jerk.append(third)
            t_in, t_out = self.body.quiet_interval(piece, motion)
            quiet_in, quiet_out = jnp.maximum(quiet_in, t_in), jnp.minimum(quiet_out, t_out)
        # The quiet times of the table are those quiet for every wall: the intersection.
        empty = quiet_in >= quiet_out
        quiet_in, quiet_out = jnp.where(empty, jnp.inf, quiet_in), jnp.where(empty, jnp.inf, quiet_out)
        speed = jnp.sqrt(motion.vx * motion.vx + motion.vy * motion.vy)
        time_scale = 1.0 / (speed / self.table.size + jnp.abs(motion.omega))
        sharp = self._sharp
        profile = (state, lower, upper) if self.checks_curvature else state
        return profile, RootBounds(
            functools.reduce(jnp.maximum, lower),
            functools.reduce(jnp.maximum, upper),
            quiet_in,
            quiet_out,
            time_scale,
            functools.reduce(jnp.maximum, jerk) if sharp else None,
        )

    @property
    def checks_curvature(self) -> bool:
        """Static: some wall's bounds were estimated, so each root step checks the gaps' curvature against them
        (a step that breaks them is refused: the orbit's result is ``BOUND_VIOLATED``)."""
        return any(piece.checks_curvature for piece in self.table.pieces)

    def gaps_along_flight(self, profile, t: jax.Array):
        """Every gap and its first (and, for the sharper steps, second) time derivative after a flight of ``t``.

        Where a wall's bounds were estimated (``Piece.checks_curvature``), a gap
        whose curvature breaks them is NaN, and so is a gap found through its
        wall by more than rounding (a safe step never lands there: one did, so
        the bounds were too small where the search did not look): the search
        stops and the orbit is poisoned rather than continued past a root it
        may have stepped over.
        """
        if not self.checks_curvature:
            return self._gaps_along_flight(profile, t, self._sharp)
        state, lower, upper = profile
        gaps, slopes, curvatures = self._gaps_along_flight(state, t, True)
        lower_curv, upper_curv = functools.reduce(jnp.maximum, lower), functools.reduce(jnp.maximum, upper)
        slack = 1e-9 * (lower_curv + upper_curv)
        through = -WALL_TOLERANCE * self.gap_scale
        inside = tuple(
            (k >= -lower_curv - slack) & (k <= upper_curv + slack) & (g >= through) for g, k in zip(gaps, curvatures)
        )
        gaps = tuple(jnp.where(ok, g, jnp.nan) for g, ok in zip(gaps, inside))
        return (gaps, slopes, curvatures) if self._sharp else (gaps, slopes)

    def _gaps_along_flight(self, state: tuple, t: jax.Array, sharp: bool):
        x, y, alpha, vx, vy, omega = state
        if self.body.kind != "rotor":
            omega = jnp.zeros_like(omega)
        cx, cy = x + vx * t, y + vy * t
        offsets = self._offsets(alpha + omega * t)
        columns: list[list] = [[], [], []]
        for piece in self.table.pieces:
            for contact in self.body.gaps_along(piece, cx, cy, vx, vy, omega, offsets, sharp):
                for column, value in zip(columns, contact):
                    column.append(value)
        return tuple(tuple(column) for column in columns[: 3 if sharp else 2])

    def _origin(self, state: tuple):
        """The origin of the cell the flight from ``state`` runs in (``None`` but in a periodic table)."""
        x, y, _, vx, vy, _ = state
        return self.table.cell_origin(x, y, vx, vy)

    def _in_cell(self, state: tuple, origin) -> tuple:
        """``state`` with its position relative to the cell's ``origin`` (unchanged for ``None``)."""
        if origin is None:
            return state
        x, y, *rest = state
        return (x - origin[0], y - origin[1], *rest)

    def closed_form_contact(self, state: tuple, constants):
        """``(t, index)`` for a body whose contacts move on straight lines."""
        x, y, alpha, vx, vy, _ = self._in_cell(state, self._origin(state))
        offsets = self._offsets(alpha, constants)
        times = tuple(t for piece in self.table.pieces for t in self.body.exit_times(piece, x, y, vx, vy, offsets))
        return functools.reduce(jnp.minimum, times), first_smallest(times)

    def flight_components(self, state: tuple, t) -> tuple:
        """The free flight of the components for time ``t``; ``alpha`` wrapped into ``[-pi, pi)``.

        Wrapping keeps ``cos``/``sin`` of ``alpha`` exact to rounding however
        long the run: an unwrapped angle of ``1e7`` radians would carry ``1e-9``
        absolute error into every contact. A body that never turns keeps ``alpha``.
        """
        x, y, alpha, vx, vy, omega = state
        if self.body.kind != "static":
            alpha = wrapped_angle(alpha + omega * t)
        return x + vx * t, y + vy * t, alpha, vx, vy, omega

    def contacts(self, state: tuple, offsets, origin=None) -> tuple:
        """Per gap, at a contact: ``(gap, closing, lever, normal)``: its gap, a number with the sign of its
        approach speed, its lever ``N . r_alpha`` and its wall's outward normal ``N`` (components); in a
        periodic table, in the cell about ``origin``."""
        x, y, _, vx, vy, omega = self._in_cell(state, origin)
        gaps, closings, levers, normals = [], [], [], []
        for piece in self.table.pieces:
            for px, py, rx, ry in self.body.contact_points(piece, x, y, offsets):
                tx, ty = self.body.turn_vector(rx, ry)
                gx, gy = piece.gradient(px, py)
                nx, ny = piece.impulse_normal(px, py)
                gaps.append(piece.gap(px, py))
                closings.append(-(gx * (vx + omega * tx) + gy * (vy + omega * ty)))
                levers.append(nx * tx + ny * ty)
                normals.append((nx, ny))
        return tuple(gaps), tuple(closings), tuple(levers), tuple(normals)

    def collide_at(self, state: tuple, t: jax.Array, index: jax.Array, constants):
        """The flight to ``t`` and the impulse(s) of gap ``index``: ``(state, contact)``."""
        # The cell is the flight's, from its start: at the end, on a periodic wall, the moved state would
        # already belong to the next cell.
        origin = self._origin(state)
        moved = self.flight_components(state, t)
        offsets = self._offsets(moved[2], constants)
        kicked, contact = self.resolve(moved, index, offsets, origin)
        if not self.holes:
            return kicked, contact
        # A point's contact point is its centre; the arc length is that of the wall it touches.
        x, y = self._in_cell(moved, origin)[:2]
        escaped = self._in_a_hole(x, y, index)
        return tuple(jnp.where(escaped, a, b) for a, b in zip(moved, kicked)), jnp.where(
            escaped, jnp.int32(ESCAPE_CODE), contact
        )

    def _in_a_hole(self, x, y, index):
        """Whether the point ``(x, y)`` on wall ``index`` (a point's gap is its wall) lies in one of the holes.

        Elementwise and without gathers: the arc length of every wall is
        computed and the touched wall's chosen, so it runs in every driver.
        """
        table = self.table
        s = jnp.zeros_like(x)
        for i, piece in enumerate(table.pieces):
            if type(piece).periodic:
                continue  # a cell's side is crossed, never hit: no part of the boundary
            s = jnp.where(index == i, table.boundary_coordinate(i, x, y), s)
        s = jnp.mod(s, table.boundary_length)
        on_boundary = functools.reduce(
            jnp.logical_or, [index == i for i, piece in enumerate(table.pieces) if not type(piece).periodic]
        )
        inside = functools.reduce(jnp.logical_or, [(s >= low) & (s <= high) for low, high in self.holes])
        return on_boundary & inside

    def resolve(self, state: tuple, index, offsets, origin=None):
        """The impulse(s) at a contact in gap ``index`` of ``state`` (components) on the wall: ``(state, contact)``.

        A periodic wall (``Piece.periodic``) gives no impulse: the flight goes on
        into the next cell, and the state is unchanged. The corner rule
        (several contacts at once) runs over the walls that can meet another at
        a corner (``_cornering``); a contact with any other wall is one impulse.
        """
        # A lambda, not a bound method: a conditional hashes its function, a scene is not hashable.
        gaps, closings, levers, normals = computed_once(lambda s, o, c: self.contacts(s, o, c), state, offsets, origin)
        mass_ratio = self.body.mass_ratio
        count = self.body.contact_count
        crossings = tuple(type(piece).periodic for piece in self.table.pieces for _ in range(count))

        def kicker(gap_indices: tuple):
            """``kick(s, j)``, ``speed_of(s, j)`` and the contact speeds over the gaps ``gap_indices`` (``j`` traced,
            a position in that tuple)."""
            lever = tuple(levers[g] for g in gap_indices)
            normal_x, normal_y = tuple(normals[g][0] for g in gap_indices), tuple(normals[g][1] for g in gap_indices)
            passing = [j for j, g in enumerate(gap_indices) if crossings[g]]

            def kick(s, j):
                kicked = impulse.reflect(s, select(lever, j), (select(normal_x, j), select(normal_y, j)), mass_ratio)
                if not passing:
                    return kicked
                crossing = functools.reduce(jnp.logical_or, [j == p for p in passing])
                return tuple(jnp.where(crossing, a, b) for a, b in zip(s, kicked))

            def speed_of(s, j):
                return impulse.approach_speed(s, select(lever, j), (select(normal_x, j), select(normal_y, j)))

            def contact_speeds(s):
                speeds = tuple(impulse.approach_speed(s, levers[g], normals[g]) for g in gap_indices)
                return tuple(gaps[g] for g in gap_indices), tuple(closings[g] for g in gap_indices), speeds

            return kick, speed_of, contact_speeds

        every = tuple(range(len(gaps)))
        if self.body.kind == "point" and self.table.corners is not None:
            # A point in a table whose walls meet two at a time: each corner's two impulses, wall by wall.
            kick, _, contact_speeds = kicker(every)

            def kick_wall(s, i):
                kicked = impulse.reflect(s, levers[i], normals[i], mass_ratio)
                return s if crossings[i] else kicked

            def speed_of_wall(s, i):
                return impulse.approach_speed(s, levers[i], normals[i])

            return impulse.pairs_resolution(
                state,
                index,
                self.table.corners,
                contact_speeds(state),
                kick_wall,
                speed_of_wall,
                kick,
                self.gap_scale,
                self.gap_codes,
            )
        corners = self._cornering
        if corners == every:
            kick, speed_of, contact_speeds = kicker(every)
            return impulse.contact_resolution(
                contact_speeds, kick, speed_of, state, index, self.gap_scale, self.gap_codes
            )
        kick, _, _ = kicker(every)
        single = kick(state, index), select(tuple(jnp.int32(c) for c in self.gap_codes), index)
        if len(corners) < 2:
            return single
        # The corner rule over the walls that meet at corners, in their own numbering.
        in_corner = functools.reduce(jnp.logical_or, [index == g for g in corners])
        local = functools.reduce(
            jnp.add, [jnp.where(index == g, jnp.int32(j), jnp.int32(0)) for j, g in enumerate(corners)]
        )
        kick, speed_of, contact_speeds = kicker(corners)
        codes = tuple(self.gap_codes[g] for g in corners)
        cornered = impulse.contact_resolution(contact_speeds, kick, speed_of, state, local, self.gap_scale, codes)
        return tuple(jnp.where(in_corner, a, b) for a, b in zip(cornered[0], single[0])), jnp.where(
            in_corner, cornered[1], single[1]
        )

    @property
    def _cornering(self) -> tuple[int, ...]:
        """Static: the gaps whose walls can meet another wall at a corner.

        An obstacle (``Piece.dispersing``) lies strictly inside its table, and a
        periodic wall's crossing has no impulse to order: a contact with either
        is never part of several at once, and leaving them out keeps the corner
        rule's code (quadratic in the walls it covers) small.
        """
        count = self.body.contact_count
        return tuple(
            i * count + k
            for i, piece in enumerate(self.table.pieces)
            if not (type(piece).dispersing or type(piece).periodic)
            for k in range(count)
        )

    # -- states as arrays (the analyses, validation) --------------------------------------

    def flight(self, state: jax.Array, t: jax.Array) -> jax.Array:
        """Free flight of states ``(..., 6)`` for time ``t``; ``alpha`` wrapped into ``[-pi, pi)``."""
        return stacked(self.flight_components(components(jnp.asarray(state)), t))

    def _contact_table(self, state: jax.Array):
        parts = components(jnp.asarray(state))
        offsets = self._offsets(parts[2])
        return parts, self.contacts(parts, offsets, self._origin(parts))

    def gaps(self, state: jax.Array) -> jax.Array:
        """Every contact gap ``(..., G)``, wall by wall; ``>= 0`` inside (in a periodic table, in the cell the
        state's flight runs in)."""
        _, (gaps, *_) = self._contact_table(state)
        return jnp.stack(gaps, axis=-1)

    def clearances(self, state: jax.Array) -> jax.Array:
        """How far inside the table each contact is ``(..., K)`` (the gap unit, ``>= 0`` inside): its smallest gap
        for a table that is an intersection of walls, ``Table.clearance`` of its point for a union; for a
        periodic table, inside its central cell (the position unfolded)."""
        parts = components(jnp.asarray(state))
        offsets = self._offsets(parts[2])
        count = self.body.contact_count
        if self.table.intersection_of_pieces:
            gaps = self.contacts(parts, offsets)[0]
            per_contact: list[Any] = [functools.reduce(jnp.minimum, gaps[k::count]) for k in range(count)]
            return jnp.stack(per_contact, axis=-1)
        points = self.body.contact_points(self.table.pieces[0], parts[0], parts[1], offsets)
        values: list[Any] = [self.table.clearance(px, py) for px, py, _, _ in points]
        return jnp.stack(values, axis=-1)

    def approach_speeds(self, state: jax.Array) -> jax.Array:
        """The normal speed of each contact towards its wall ``(..., G)``; ``> 0`` approaching."""
        parts, (_, _, levers, normals) = self._contact_table(state)
        return jnp.stack([impulse.approach_speed(parts, s, n) for s, n in zip(levers, normals)], axis=-1)

    def contact_points(self, state: jax.Array) -> jax.Array:
        """The contact points ``(..., G, 2)``: for each gap, the point of the body that would touch that wall (in a
        periodic table, relative to the centre of the cell the state's flight runs in)."""
        parts = self._in_cell(components(jnp.asarray(state)), self._origin(components(jnp.asarray(state))))
        offsets = self._offsets(parts[2])
        points = [
            jnp.stack([px, py], axis=-1)
            for piece in self.table.pieces
            for px, py, _, _ in self.body.contact_points(piece, parts[0], parts[1], offsets)
        ]
        return jnp.stack(points, axis=-2)

    def contact_offsets_at(self, alpha) -> list:
        """Per wall, the list of the contacts' offsets ``(rx, ry)`` from the centre at orientation ``alpha``."""
        alpha = jnp.asarray(alpha, jnp.float64)
        offsets = self._offsets(alpha)
        zero = jnp.zeros_like(alpha)
        return [
            [(rx, ry) for _, _, rx, ry in self.body.contact_points(piece, zero, zero, offsets)]
            for piece in self.table.pieces
        ]

    def end_points(self, state: jax.Array) -> jax.Array:
        """The body's contact points ``(..., K, 2)`` on the first wall (a point body: its centre), unfolded."""
        parts = components(jnp.asarray(state))
        offsets = self._offsets(parts[2])
        points = self.body.contact_points(self.table.pieces[0], parts[0], parts[1], offsets)
        return jnp.stack([jnp.stack([px, py], axis=-1) for px, py, _, _ in points], axis=-2)

    # -- invariants -----------------------------------------------------------------------

    def energy(self, state) -> jax.Array:
        """``M |v|^2 / 2 + I omega^2 / 2`` of states ``(..., 6)`` (or components)."""
        return self.body.energy(*(component(state, i) for i in (3, 4, 5)))

    def angular_momentum(self, state: ArrayLike) -> jax.Array:
        """``M (x vy - y vx) + I omega`` about the origin, ``(...)``: conserved in a circle (the wall's force
        is radial); a body that never turns gives the orbital part only.

        Raises:
            TypeError: in a table without a centre (the strip between two walls: its walls exert torques about
                every point, and the momentum it conserves is ``M vx``).
        """
        if not self.table.has_centre:
            raise TypeError(
                f"{type(self).__name__} has no conserved angular momentum: its table has no centre to take it "
                "about (between two walls the conserved momentum is M vx)"
            )
        state = jnp.asarray(state)
        x, y, vx, vy, omega = (state[..., i] for i in (0, 1, 3, 4, 5))
        orbital = self.body.mass * (x * vy - y * vx)
        if self.body.kind == "static":
            return orbital
        return orbital + self.body.spin_term(omega, self.body.inertia * omega)

    # -- sections (jaxbill._scenes.body_sections) ----------------------------------------------

    @property
    def sections(self) -> tuple[str, ...]:
        """The sections of a body in this table: ``("birkhoff",)`` in a bounded table, ``("floor",)`` between two
        flat walls."""
        return self.table.section_names

    @property
    def area_preserving_section(self) -> str:
        """The section whose coordinates the collision map preserves area in (for a point, or a body at fixed
        invariants between walls); for a body in a bounded table the Birkhoff section is a projection."""
        names = self.table.section_names
        return names[0] if names else ""

    def section(self, states: jax.Array, contacts: jax.Array | None = None, name: str | None = None) -> jax.Array:
        """Section points ``(..., 2)`` of states ``(..., 6)`` at collisions (``HasSection``): ``"birkhoff"``,
        ``[s, p]`` the contact's arc length round the table and the centre's tangential momentum
        ``sqrt(M) v_t / sqrt(2E)``; ``"floor"``, ``[alpha, p]`` at collisions with the floor of a strip (see
        ``jaxbill._scenes.body_sections``). ``contacts`` (``Orbit.contact``) name the touching contact;
        without them, the contact nearest its wall."""
        return body_sections.SECTIONS[chosen_section(self, name)](self, states, contacts)

    def section_state(self, point: ArrayLike, energy=0.5, arm_angle=0.0, spin=0.0) -> jax.Array:
        """The state ``(..., 6)`` just after a collision at the area-preserving section's ``point`` ``(..., 2)``
        at energy ``E``: for the Birkhoff section, the first contact on the wall at ``s`` with the body at
        ``arm_angle`` (radians, from the outward normal to that contact's offset) and spin ``omega``; for the
        floor section, ``(alpha, p)`` at ``x = 0``, ``vx = 0``. NaN where none exists."""
        xy = jnp.asarray(point, dtype=jnp.float64)
        if self.area_preserving_section == "floor":
            return body_sections.floor_state(self, xy[..., 0], xy[..., 1], energy)
        return body_sections.birkhoff_state(self, xy[..., 0], xy[..., 1], energy, arm_angle, spin)

    @property
    def section_axis_labels(self) -> dict[str, tuple[str, str]]:
        """The axes of each section, for pictures: ``{name: (x label, y label)}``."""
        return {name: body_sections.CHARTS[name].axis_labels for name in self.sections}

    @property
    def section_chart(self) -> SectionChart:
        """How ``jb.explore`` seeds, reads and draws the area-preserving section."""
        if not self.sections:
            raise TypeError(f"scene: {self.table.name} ({type(self.table).__name__}) offers no section to explore")
        return body_sections.CHARTS[self.area_preserving_section]

    def sample_states(self, rng, count: int, energy: float, angular_momentum=None, margin: float = 1e-9):
        """``count`` tries at Liouville-distributed states of energy ``E`` (and ``L``, for a turning body in a
        circle) (``SamplesStates``): ``(states (k, 6), weights (k,))``, every gap above ``margin`` times its unit
        (``jb.sample_energy_shell`` loops over it)."""
        return table_shell_candidates(self, rng, count, energy, angular_momentum, margin)

    # -- the independent checker (jb.check) ---------------------------------------------------

    def checker_flight(self) -> RigidBodyColumn:
        """The geometry ``jb.check`` flies the body in (``HasCheckerFlight``): its gaps as walls of the column
        in ``(x, y, sqrt(I/M) alpha)``; the checker bounds their curvature and reflects about their gradients
        itself, never asking for this scene's bounds, collision times or impulses."""
        turning = self.kind == "rotor"
        scale = float(jnp.sqrt(self.inertia / self.mass)) if turning else 1.0
        return RigidBodyColumn(
            gaps=self.gaps,
            gap_codes=self.gap_codes,
            scale=scale,
            frozen=self.kind == "static",
            point=self.kind == "point",
            length=float(self.length_scale),
            gap_unit=float(self.gap_scale),
            extent=tuple(float(e) for e in self.table.extent),  # type: ignore[arg-type]
        )

    # -- derivatives (jaxbill._engine.tangent) ----------------------------------------------

    @property
    def dynamical_indices(self) -> tuple[int, ...]:
        """All six coordinates for a turning body; ``(x, y, vx, vy)`` for a point (a free spin) and for a body
        that never turns (``alpha`` a constant, ``omega = 0``)."""
        return (0, 1, 2, 3, 4, 5) if self.body.kind == "rotor" else (0, 1, 3, 4)

    def phase_velocity(self, state: jax.Array) -> jax.Array:
        """The flow's vector field during free flight, ``[vx, vy, omega, 0, 0, 0]``, shape ``(..., 6)``."""
        state = jnp.asarray(state)
        return jnp.concatenate([state[..., 3:6], jnp.zeros_like(state[..., 0:3])], axis=-1)
