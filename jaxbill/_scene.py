"""What the collision engine needs from a scene, and the contact codes every scene shares.

A scene is an ``equinox.Module``: its physical parameters are differentiable
leaves and its *kind* (which closed forms apply) is static, so that each scene
compiles only the code it needs. The orbit scan, batching, streaming, tangent
maps and Lyapunov spectra work on any object with the methods of ``Scene``.
"""

from __future__ import annotations

from typing import Any, ClassVar, Protocol

import jax
import jax.numpy as jnp

# Contact codes shared by every scene (``Orbit.contact``). Scenes add their own
# nonzero codes for which end touched which wall.
NO_CONTACT = 0  # the flight never reaches a wall: dt = inf, state unchanged
SEVERAL_CONTACTS = 2  # two or more contacts resolved in one event (a corner or kink)

# Relative tolerance on a contact gap (in units of ``Scene.gap_scale``): an end
# this far outside a wall is "through the wall"; this close to it, "on the wall".
WALL_TOLERANCE = 1e-12


class Scene(Protocol):
    """The interface of a scene (a structural type: scenes do not inherit from it)."""

    state_size: ClassVar[int]  # length of the state vector
    state_layout: ClassVar[str]  # e.g. "[x, y, alpha, vx, vy, omega]", for messages
    gap_names: ClassVar[tuple[str, ...]]  # one name per contact gap, for messages
    wall_name: ClassVar[str]  # "the circle", "the walls"

    @property
    def batch_chunk(self) -> int:
        """Lanes per chunk in a batched run (a vmapped loop waits for its slowest lane)."""

    @property
    def gap_scale(self) -> jax.Array:
        """The unit of the gaps, for ``WALL_TOLERANCE``."""

    def check(self) -> None:
        """Raise ValueError for invalid concrete parameters."""

    def check_state_values(self, state) -> None:
        """Scene-specific eager checks of a finite float64 numpy state ``(..., state_size)``."""

    def is_valid(self, state: jax.Array) -> jax.Array:
        """Traceable: parameters and ``state`` are a valid start (for NaN poisoning).

        The traceable twin of the eager checks: finite, motion representable,
        no end through a wall by more than ``WALL_TOLERANCE``, none on a wall
        (gap ``<= 0``) without moving away from it.
        """

    def motion_is_representable(self, state: jax.Array) -> jax.Array:
        """Traceable ``(...)``: the velocities' squares and the energy are ordinary float64 numbers."""

    def orbit_constants(self, state0: jax.Array) -> Any:
        """Quantities fixed along an orbit from ``state0`` (a pytree, or None)."""

    # How a collision is computed (see jaxbill._step): a scene whose gaps are
    # transcendental in time answers root_search and gaps_along_flight, one
    # whose gaps are polynomials answers closed_form_contact; both collide_at.

    @property
    def searches_for_roots(self) -> bool:
        """Static: the contact time needs the safe-step root search (else a closed form)."""

    def root_search(self, state: jax.Array) -> tuple[Any, Any]:
        """``(profile, RootBounds)``: what the gaps depend on along the flight, and the search's bounds."""

    def gaps_along_flight(self, profile: Any, t: jax.Array) -> tuple[jax.Array, jax.Array]:
        """``(gap, slope)``, each ``(K,)``: the gaps and their time derivatives after a flight of ``t``."""

    def closed_form_contact(self, state: jax.Array, constants: Any) -> tuple[jax.Array, jax.Array]:
        """``(t, index)``: the contact time (``inf``: never) and which gap closes."""

    def collide_at(self, state: jax.Array, t: jax.Array, index: jax.Array, constants: Any) -> tuple[jax.Array, jax.Array]:
        """``(state, contact)``: the flight to ``t`` and the impulse(s) of the contact in gap ``index``."""

    def gaps(self, state: jax.Array) -> jax.Array:
        """Contact gaps ``(..., K)``, >= 0 inside."""

    def approach_speeds(self, state: jax.Array) -> jax.Array:
        """Rate at which each gap closes ``(..., K)``, > 0 when approaching its wall."""

    def energy(self, state: jax.Array) -> jax.Array:
        """Kinetic energy ``(...)``."""


def component(state, i: int):
    """Component ``i`` of a state: ``state[..., i]`` of an array ``(..., S)``, ``state[i]`` of a tuple of components.

    Lets one formula (an energy, say) serve both the analyses, which hold
    states as arrays, and the engine's drivers, which hold them as components.
    """
    return state[i] if isinstance(state, tuple) else state[..., i]


def _states(scene: Scene, state) -> jax.Array:
    """``state`` as an array ``(..., S)``; ValueError for another last axis or a non-real dtype (static)."""
    from ._validation import as_states  # noqa: PLC0415 (_validation imports this module)

    return as_states(scene, state, "state")


def energy(scene: Scene, state: jax.Array) -> jax.Array:
    """Kinetic energy of ``state`` (shape ``(..., S)``) in ``scene``: translation plus rotation."""
    return scene.energy(_states(scene, state))


def angular_momentum(scene: Scene, state: jax.Array) -> jax.Array:
    """The scene's angular momentum (``StickInCircle``: about the origin; ``StickBetweenWalls3D``: ``L_z``).

    Raises:
        TypeError: for a scene without one (``StickBetweenWalls2D``: the walls
            exert torques; its conserved momentum is ``M vx``).
    """
    if not hasattr(scene, "angular_momentum"):
        raise TypeError(f"{type(scene).__name__} has no conserved angular momentum")
    return scene.angular_momentum(_states(scene, state))


def end_points(scene: Scene, state: jax.Array) -> jax.Array:
    """Positions of the ends ``[P1, P2]``, shape ``(..., 2, D)`` (``D`` = 2 or 3)."""
    return scene.end_points(_states(scene, state))
