"""What the analyses ask of a scene, beyond the engine's ``Scene`` (``jaxbill._engine.interface``,
re-exported here with the contact codes every scene shares).

A scene is an ``equinox.Module``: its physical parameters are differentiable
leaves and its *kind* (which closed forms apply) is static, so that each scene
compiles only the code it needs.

The analyses ask through one small protocol per capability, never through
the scene's type: ``HasSection`` (section coordinates, the area-preserving
one named, and the explorer's ``SectionChart``), ``HasCheckerFlight`` (the
flight the diffrax checker integrates, or the ``RigidBodyColumn`` it builds one from), ``HasPeriodicSymmetry`` (what
periodic-orbit search divides out) and ``SamplesStates`` (valid starts on an
energy shell). A scene provides those it can; ``docs/how-to/new-scene.md``
says how to write one.
"""

from __future__ import annotations

import dataclasses
from collections.abc import Callable
from typing import Any, ClassVar, Protocol, cast, runtime_checkable

import jax
import numpy as np
from jaxtyping import Array, ArrayLike, Float

from jaxbill._engine.interface import NO_CONTACT, SEVERAL_CONTACTS, Scene
from jaxbill._engine.validation import WALL_TOLERANCE, as_states

__all__ = [
    "NO_CONTACT",
    "SEVERAL_CONTACTS",
    "WALL_TOLERANCE",
    "Scene",
    "HasSection",
    "HasCheckerFlight",
    "CheckerFlight",
    "RigidBodyColumn",
    "StickColumn",
    "ReducedWalls",
    "HasPeriodicSymmetry",
    "HasAngularMomentum",
    "has_angular_momentum",
    "PERIODIC_SYMMETRIES",
    "SamplesStates",
    "SectionChart",
]


# ---------------------------------------------------------------------------
# What the analyses ask: one small protocol per capability
# ---------------------------------------------------------------------------
# The analyses (sections, the explorer, the diffrax checker, periodic-orbit
# search, sampling) never test a scene's type: each asks the scene one of the
# questions below. A scene answers those it can, as its own methods; an
# analysis that needs a capability the scene lacks says so by name (an
# ``AttributeError`` turned into a ``TypeError`` naming the capability).


@dataclasses.dataclass(frozen=True)
class SectionChart:
    """How the explorer reads, seeds and draws one kind of scene's area-preserving section.

    Every function takes the scene first; ``invariants`` is a dict of the
    quantities the section holds fixed (its keys are those of
    ``invariant_symbols``). Section points are ``(x, y)`` pairs: ``x`` across
    the panel, ``y`` up.

    Attributes:
        title: the section's name, for the panel's title.
        axis_labels: ``(x label, y label)`` with units.
        invariant_symbols: the printed symbol of each invariant, keyed by
            the keyword ``explore`` accepts for it (e.g. ``{"energy": "E"}``).
        default_invariants: ``scene -> dict``: the invariants when
            ``explore`` is given none.
        x_range: ``scene -> (low, high)``: the span of ``x``.
        edge: ``(scene, x (m,), invariants) -> (m, 2)``: the lowest and
            highest reachable ``y`` at each ``x`` (NaN where none).
        start: ``(scene, x (...), y (...), invariants) -> (states (..., S),
            contacts (...))``: the state just after a collision at the
            section point and its contact code; NaN states where
            ``(x, y)`` is not reachable.
        seeds: ``(scene, count, invariants) -> (states (count, S), contacts
            (count,))``: starts spread evenly (in the section's area) over it.
        points: ``(scene, states (..., S), contacts (...)) -> (..., 2)``: the
            section point of each collision, NaN for collisions off the
            section. Traceable: the explorer compiles it.
        draw_configuration: ``(ax, scene, state0 (S,), orbit, color) ->
            None``: the orbit (an ``Orbit`` of one orbit) in configuration
            space, on a cleared ``Axes``.
    """

    title: str
    axis_labels: tuple[str, str]
    invariant_symbols: dict[str, str]
    default_invariants: Callable[[Any], dict[str, float]]
    x_range: Callable[[Any], tuple[float, float]]
    edge: Callable[..., np.ndarray]
    start: Callable[..., tuple[Any, Any]]
    seeds: Callable[..., tuple[Any, Any]]
    points: Callable[..., Any]
    draw_configuration: Callable[..., None]


class HasSection(Protocol):
    """A scene with Poincaré-section coordinates at its collisions (sections, figures, the explorer).

    ``sections`` names every section the scene offers; ``area_preserving_section``
    is the one whose coordinates the collision map preserves area in (at the
    invariants it holds fixed): "fraction covered" and island counts mean
    something there only. ``section_chart`` is what ``jb.explore`` draws.
    Optional: ``section_axis_labels``, ``{name: (x label, y label)}`` for each of
    ``sections``, which ``plotting.draw_section(..., scene=scene)`` puts on its axes.
    """

    sections: ClassVar[tuple[str, ...]]
    area_preserving_section: ClassVar[str]

    def section(self, states: jax.Array, contacts: jax.Array | None = None, name: str | None = None) -> jax.Array:
        """Section points ``(..., 2)`` of states ``(..., S)`` just after collisions (``contacts (...)``
        their codes, for scenes that need them); ``name`` one of ``sections`` (default: the
        area-preserving one). Traceable."""
        ...

    # ``*args: Any, **invariants: Any`` stands for "the scene's own invariant keywords":
    # each scene names those its section holds fixed (energy=, spin=, ...).
    def section_state(self, point: ArrayLike, *args: Any, **invariants: Any) -> jax.Array:
        """The state ``(..., S)`` just after a collision at the area-preserving section's
        ``point (..., 2)`` with the given invariants (NaN where unreachable)."""
        ...

    @property
    def section_chart(self) -> SectionChart:
        """How ``jb.explore`` seeds, reads and draws the area-preserving section."""
        ...


@runtime_checkable
class CheckerFlight(Protocol):
    """The free flight an independent checker integrates, built by the scene for one orbit.

    ``check`` integrates ``n`` collisions from ``state0`` with diffrax (never
    with jaxbill's collision times or impulse law) and compares them with
    ``jb.orbit``; the options are those of ``jb.check``, each checker taking
    the ones it knows. The library's scenes hand the checker a geometry instead
    (``RigidBodyColumn``, ``StickColumn``, ``ReducedWalls``) and it builds the
    flight itself.
    """

    def check(self, scene: Any, state0: np.ndarray, n: int, **options) -> Any:
        """A ``CheckResult`` of ``n`` collisions from ``state0`` (shape ``(S,)``)."""
        ...


@dataclasses.dataclass(frozen=True)
class RigidBodyColumn:
    """What the checker needs to fly a planar rigid body in a fixed table itself: geometry, never dynamics.

    A scene whose state is ``[x, y, alpha, vx, vy, omega]`` and whose walls do
    not move can hand ``jb.check`` this description instead of a flight of its
    own: the checker then flies the point ``(x, y, z = scale alpha)`` straight
    inside the column ``W_g(x, y, z) >= 0`` that ``gaps`` bound, reflects it
    about ``grad W_g`` and bounds ``W_g''`` itself
    (``jaxbill._check.checker.BodyColumnFlight``). Nothing here is a
    collision time, an impulse or a curvature bound of the scene's own.

    Attributes:
        gaps: the scene's gaps of a state, ``(6,) -> (G,)``, read at zero velocity (geometry only).
        gap_codes: the ``Orbit.contact`` code of each gap.
        scale: ``sqrt(I/M)`` for a body that turns, 1 otherwise (length).
        frozen: the body never turns (infinite inertia): the impulse has no turning part.
        point: the gaps do not depend on ``alpha`` (a point: its spin is a free rotor).
        length: the unit of length of the comparison (the table's size).
        gap_unit: the gaps' unit (``WALL_TOLERANCE`` and the corner test are relative to it).
        extent: ``(x_low, x_high, y_low, y_high)``, a box that holds the table (infinite along an
            unbounded direction).
    """

    gaps: Callable[[jax.Array], jax.Array]
    gap_codes: tuple[int, ...]
    scale: float
    frozen: bool
    point: bool
    length: float
    gap_unit: float
    extent: tuple[float, float, float, float]


@dataclasses.dataclass(frozen=True)
class StickColumn:
    """The column a stick's point ``(x, y, z = scale alpha)`` flies straight in, its walls the scene's own gaps
    (``StickInCircle``, ``StickInEllipse``): ``jb.check`` reflects the point about their gradients and bounds
    their curvature from ``hessian_bound`` (``jaxbill._check.checker.ColumnFlight``).

    Attributes:
        scale: ``sqrt(I/M)`` for a turning stick, 1 otherwise (length).
        length: the unit of length of the comparison (``R``; ``max(a, b)``).
        reach: a bound on ``|c|``, the centre's distance from the origin, inside the table.
        hessian_bound: ``d_max``: the gaps' Hessian in the contact point is ``-2 D`` with ``|D| <= d_max``.
        frozen: the stick never turns (infinite inertia).
        single_sheet: both ends are one point (``ell = 0``): no crease, no corner.
    """

    scale: Any
    length: Any
    reach: Any
    hessian_bound: Any
    frozen: bool
    single_sheet: bool


@dataclasses.dataclass(frozen=True)
class ReducedWalls:
    """The sticks between two flat walls: ``jb.check`` integrates their reduced ``(z, psi)`` billiard with its
    centrifugal potential (``jaxbill._check.walls``). ``planar``: the 2D scene, else the 3D one."""

    planar: bool


class HasCheckerFlight(Protocol):
    """A scene that ``jb.check`` can verify: it says what flight the checker integrates."""

    def checker_flight(self) -> CheckerFlight | RigidBodyColumn | StickColumn | ReducedWalls:
        """The ``CheckerFlight`` of this (unbatched, concrete) scene, or the geometry (``RigidBodyColumn``,
        ``StickColumn``, ``ReducedWalls``) the checker builds its flight from."""
        ...


# The symmetries periodic-orbit search can divide out (``HasPeriodicSymmetry``):
# "rotation" about the origin (the circle), "translation" along the walls (the
# horizontal drift of the sticks between walls; in 3D also the turn about the
# vertical), and "none" (the ellipse: the orbit must close in every coordinate).
PERIODIC_SYMMETRIES = ("rotation", "translation", "none")


class HasPeriodicSymmetry(Protocol):
    """A scene ``find_periodic_orbit`` can search: the symmetry its solver divides out.

    ``periodic_symmetry`` is one of ``PERIODIC_SYMMETRIES``; ``body_turns`` and
    ``body_is_point`` say which coordinates its orbits have (a spin, an orientation);
    ``jaxbill._analysis.periodic`` keeps one solver per symmetry (not per scene). The
    solver for "none" asks the scene only for its collision map, energy, gaps
    and ``section`` (the ``HasSection`` points it reports).
    """

    periodic_symmetry: ClassVar[str]

    @property
    def body_turns(self) -> bool:
        """Static: the body turns (its spin a coordinate; an angular momentum to pin where it is conserved)."""
        ...

    @property
    def body_is_point(self) -> bool:
        """Static: the body is a point, with no orientation among the coordinates."""
        ...


class HasSymplecticFlow(Protocol):
    """A scene whose flow is symplectic: a Hamiltonian flight and elastic collisions.

    Its Lyapunov exponents then come in pairs ``lambda, -lambda`` (the pairing
    rule; exponents do not depend on the coordinates, so it holds in the
    dynamical frame the analyses use), so ``lyapunov_spectrum`` (by default, or
    with ``paired=True``) can carry half the tangent vectors and give the lower
    half of the spectrum as the negatives of the upper. Every scene jaxbill ships sets
    ``symplectic_flow = True``; a scene with losses (a coefficient of
    restitution below one) must not.
    """

    symplectic_flow: ClassVar[bool]


@runtime_checkable
class HasAngularMomentum(Protocol):
    """A scene with a conserved angular momentum (``StickInCircle`` about the origin, ``StickBetweenWalls3D``
    ``L_z``, ``StickInEllipse``'s only when it is a circle)."""

    def angular_momentum(self, state: jax.Array, /) -> jax.Array:
        """The angular momentum ``(...)`` of states ``(..., S)``."""
        ...


@runtime_checkable
class SamplesStates(Protocol):
    """A scene that can draw valid starts with the Liouville measure on an energy shell."""

    def sample_states(
        self,
        rng: np.random.Generator,
        count: int,
        energy: float,
        angular_momentum: float | None = None,
        margin: float = 1e-9,
    ) -> tuple[np.ndarray, np.ndarray]:
        """``count`` tries at valid states of energy ``energy`` (and ``angular_momentum``, where the
        scene conserves one; else it must be None), both ends inside by ``margin`` (relative):
        ``(states (k, S), weights (k,))``, ``k <= count``, Liouville-distributed on the shell once
        weighted (``jb.sample_energy_shell`` draws until it has enough)."""
        ...


def chosen_section(scene: Any, name: str | None) -> str:
    """``name``, or the scene's area-preserving section for ``None``; ValueError naming the choices otherwise."""
    name = str(scene.area_preserving_section) if name is None else name
    if name not in scene.sections:
        raise ValueError(f"name must be one of {scene.sections} for {type(scene).__name__}; got {name!r}")
    return name


def component(state, i: int):
    """Component ``i`` of a state: ``state[..., i]`` of an array ``(..., S)``, ``state[i]`` of a tuple of components.

    Lets one formula (an energy, say) serve both the analyses, which hold
    states as arrays, and the engine's drivers, which hold them as components.
    """
    return state[i] if isinstance(state, tuple) else state[..., i]


def _states(scene: Scene, state: ArrayLike) -> jax.Array:
    """``state`` as an array ``(..., S)``; ValueError for another last axis or a non-real dtype (static)."""
    return as_states(scene, state, "state")


def energy(scene: Scene, state: Float[ArrayLike, "*batch S"]) -> Float[Array, "*batch"]:
    """Kinetic energy of ``state`` (shape ``(..., S)``) in ``scene``: translation plus rotation."""
    return scene.energy(_states(scene, state))


def has_angular_momentum(scene) -> bool:
    """Whether ``scene`` has an angular momentum about an origin (a body in a table with a centre; the 3D
    walls' ``L_z``): a body between two walls in the plane has none."""
    table = getattr(scene, "table", None)
    return isinstance(scene, HasAngularMomentum) and getattr(table, "has_centre", True)


def angular_momentum(scene: Scene, state: Float[ArrayLike, "*batch S"]) -> Float[Array, "*batch"]:
    """The scene's angular momentum (``StickInCircle``: about the origin; ``StickBetweenWalls3D``: ``L_z``).

    Raises:
        TypeError: for a scene without one (``StickBetweenWalls2D``: the walls
            exert torques; its conserved momentum is ``M vx``).
    """
    if not has_angular_momentum(scene):
        raise TypeError(f"{type(scene).__name__} has no conserved angular momentum")
    return cast(HasAngularMomentum, scene).angular_momentum(_states(scene, state))


def end_points(scene: Scene, state: Float[ArrayLike, "*batch S"]) -> Float[Array, "*batch 2 D"]:
    """Positions of the ends ``[P1, P2]``, shape ``(..., 2, D)`` (``D`` = 2 or 3)."""
    return scene.end_points(_states(scene, state))
