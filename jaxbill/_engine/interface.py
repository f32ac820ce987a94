"""The interface the collision engine calls: the ``Scene`` protocol and the contact codes every scene shares.

The engine owns it: its drivers, tangent maps and validation are written against
these methods alone, and a scene (``jaxbill._scenes``) implements them. What the
analyses ask of a scene beyond them (sections, the checker's flight, sampling)
is in ``jaxbill._scenes.protocols``.
"""

from __future__ import annotations

from typing import Any, ClassVar, Protocol

import jax

# Contact codes shared by every scene (``Orbit.contact``). Scenes add their own
# nonzero codes for which end touched which wall.
NO_CONTACT = 0  # the flight never reaches a wall: dt = inf, state unchanged
SEVERAL_CONTACTS = 2  # two or more contacts resolved in one event (a corner or kink)


class Scene(Protocol):
    """The interface of a scene (a structural type: scenes do not inherit from it).

    Optional, outside the protocol: ``contact_codes``, every contact code the
    scene's collisions can have (``NO_CONTACT`` included). ``jb.run`` counts
    those one by one and any other code in its last bin
    (``jaxbill._engine.chunks.tallied_codes``); without it, all of ``-4..4``,
    which costs the closed forms' batches up to a fifth of their speed. And
    ``checks_curvature`` (static, default ``False``): the scene checks the
    bounds of its root search along the way and refuses a step that breaks
    them by a NaN gap with a finite slope, which an orbit's result then
    reports as ``BOUND_VIOLATED`` (``jaxbill._engine.first_root.REFUSED``).
    Two ways to end an orbit for good (``jaxbill._engine.step.stops_orbits``;
    the drivers then hold it, ``jaxbill._engine.chunks.Bookkeeping.held``):
    ``escape_code`` (static, default ``None``), the contact code
    ``collide_at`` gives a collision through a hole, with the state as it
    arrived (``ESCAPED``); and ``stop_condition`` (static, default ``None``),
    a function of a state's components just after a collision that ends the
    orbit there when true (``STOPPED``).
    """

    state_size: ClassVar[int]  # length of the state vector
    state_layout: ClassVar[str]  # e.g. "[x, y, alpha, vx, vy, omega]", for messages
    gap_names: ClassVar[tuple[str, ...]]  # one name per contact gap, for messages
    wall_name: ClassVar[str]  # "the circle", "the walls"

    @property
    def batch_chunk(self) -> int:
        """Orbits per vectorised lane of a batch on a CPU; 1: one orbit after another (no ``vmap``).

        A vmapped root search waits for its slowest lane, a narrow lane leaves
        the vector units idle: the best width is measured per scene
        (``benchmarks/bench_drivers.py``; ``jaxbill._engine.drivers.choose_driver``).
        """
        ...

    @property
    def gap_scale(self) -> jax.Array:
        """The unit of the gaps, for ``WALL_TOLERANCE``."""
        ...

    def check(self) -> None:
        """Raise ValueError for invalid concrete parameters."""
        ...

    def check_state_values(self, state) -> None:
        """Scene-specific eager checks of a finite float64 numpy state ``(..., state_size)``."""
        ...

    def is_valid(self, state: jax.Array) -> jax.Array:
        """Traceable: parameters and ``state`` are a valid start (for NaN poisoning).

        The traceable twin of the eager checks: finite, motion representable,
        no end through a wall by more than ``WALL_TOLERANCE``, none on a wall
        (gap ``<= 0``) without moving away from it.
        """
        ...

    def motion_is_representable(self, state: jax.Array) -> jax.Array:
        """Traceable ``(...)``: the velocities' squares and the energy are ordinary float64 numbers."""
        ...

    def orbit_constants(self, state0: tuple) -> Any:
        """Quantities fixed along an orbit from ``state0`` (its components; a pytree, or None)."""
        ...

    # How a collision is computed (see jaxbill._engine.step): a scene whose gaps are
    # transcendental in time answers root_search and gaps_along_flight, one
    # whose gaps are polynomials answers closed_form_contact; both collide_at.
    # These take a state as its components (a tuple of S scalars, or of
    # equal-shaped arrays, one element per orbit) and return tuples, so that
    # they run inside a Pallas kernel too. Their arguments are positional
    # (``/``): each scene names them for what they are to it.

    @property
    def searches_for_roots(self) -> bool:
        """Static: the contact time needs the safe-step root search (else a closed form)."""
        ...

    def root_search(self, state: tuple, /) -> tuple[Any, Any]:
        """``(profile, RootBounds)``: what the gaps depend on along the flight, and the search's bounds."""
        ...

    def gaps_along_flight(self, profile: Any, t: jax.Array, /) -> tuple:
        """``(gaps, slopes)``, two K-tuples: the gaps and their time derivatives after a flight of ``t``;
        or ``(gaps, slopes, curvatures)`` with their second derivatives too, when ``root_search``'s
        ``RootBounds`` give ``jerk`` (a bound on the third): the search then takes sharper steps."""
        ...

    def closed_form_contact(self, state: tuple, constants: Any, /) -> tuple[jax.Array, jax.Array]:
        """``(t, index)``: the contact time (``inf``: never) and which gap closes."""
        ...

    def collide_at(self, state: tuple, t: jax.Array, index: jax.Array, constants: Any, /) -> tuple[tuple, jax.Array]:
        """``(state, contact)``: the flight to ``t`` and the impulse(s) of the contact in gap ``index``
        (the new state as components)."""
        ...

    def gaps(self, state: jax.Array) -> jax.Array:
        """Contact gaps ``(..., K)``, >= 0 inside."""
        ...

    def approach_speeds(self, state: jax.Array) -> jax.Array:
        """Rate at which each gap closes ``(..., K)``, > 0 when approaching its wall."""
        ...

    def energy(self, state: jax.Array) -> jax.Array:
        """Kinetic energy ``(...)``."""
        ...

    def end_points(self, state: jax.Array, /) -> jax.Array:
        """Positions of the ends ``[P1, P2]``, shape ``(..., 2, D)`` (``D`` = 2 or 3)."""
        ...
