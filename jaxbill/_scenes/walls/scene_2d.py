"""A stick between two flat walls in a vertical plane.

State layout (float64, shape ``(6,)``)::

    [x, z, theta, vx, vz, omega]

``(x, z)`` is the stick's centre (``z`` the height above the floor), ``theta``
the angle of end P1 from the upward vertical, turning towards ``+x``, and
``omega = dtheta/dt``. The ends are ``P1 = c + ell (sin theta, cos theta)``
and ``P2 = c - ell (sin theta, cos theta)``. The walls are ``z = 0`` and
``z = h``; there is no gravity. Contact codes: ``+1``/``-1`` end P1/P2 on the
floor, ``+3``/``-3`` on the ceiling, ``2`` both ends at once, ``0`` none.

With ``eta = z / kappa`` (``I = M kappa^2``) the point ``(theta, eta)`` flies
straight between the walls ``(ell/kappa)|cos theta|`` and ``(h - ell|cos
theta|)/kappa`` and reflects specularly; the walls have kinks where the stick
is horizontal. The horizontal motion is free and decoupled.
"""

from __future__ import annotations

from typing import ClassVar, cast

import jax
import jax.numpy as jnp
from jaxtyping import ArrayLike

from jaxbill._engine.step import cos_sin
from jaxbill._engine.validation import require_x64
from jaxbill._scenes.bodies.dumbbell import Dumbbell
from jaxbill._scenes.body_in_table import BodyInTable
from jaxbill._scenes.protocols import ReducedWalls, SectionChart, chosen_section
from jaxbill._scenes.tables.flat import Strip
from jaxbill._scenes.walls import engine as walls
from jaxbill._scenes.walls.charts import WALLS_2D_CHART
from jaxbill._scenes.walls.sections import floor_section, floor_state


class StickFromVertical(Dumbbell):
    """A symmetric stick whose angle ``theta`` is measured from the upward vertical, turning towards ``+x``:
    the ends at ``c +- ell (sin theta, cos theta)``."""

    def __init__(self, ell, mass, inertia, kind: str):
        super().__init__(ell, None, mass, inertia, kind=kind)

    def offsets(self, cos, sin):
        return (self.l1 * sin, self.l1 * cos), (-(self.l1 * sin), -(self.l1 * cos))

    def turn_vector(self, rx, ry):
        # d/dtheta (sin, cos) = (cos, -sin): a quarter turn clockwise.
        return ry, -rx


class StickBetweenWalls2D(BodyInTable):
    """A stick of half-length ``ell`` bouncing between a floor ``z = 0`` and a ceiling ``z = h``, in a plane.

    Args:
        h: distance between the walls, ``h > 0``. A stick with ``2 ell > h``
            cannot turn over; that is allowed.
        ell: half-length of the stick, ``ell > 0``.
        mass: total mass ``M > 0`` (default 1).
        inertia: moment of inertia about the centre, ``I > 0``; ``None`` means
            ``mass * ell**2`` (point masses ``M/2`` at the ends);
            ``float('inf')`` is a stick that never turns (``omega`` must be 0).

    Parameters may be arrays of one common shape ``(B,)`` for a batch of
    scenes. The leaves ``h, ell, mass, inertia`` are differentiable; ``kind``
    (``"rotor"`` or ``"static"``) is static: a stick that never turns has
    straight gaps and closed-form contact times, and never traces the root
    search.
    """

    state_size: ClassVar[int] = 6
    state_layout: ClassVar[str] = "[x, z, theta, vx, vz, omega]"
    gap_names: ClassVar[tuple[str, ...]] = walls.GAP_NAMES
    wall_name: ClassVar[str] = "the walls"
    never_turning: ClassVar[str] = "a stick that never turns"
    # P1/P2 on the floor (1, -1) and on the ceiling (3, -3), as the gaps come, wall by wall.
    gap_codes: ClassVar[tuple[int, ...]] = (walls.FLOOR, -walls.FLOOR, walls.CEILING, -walls.CEILING)
    contact_codes: ClassVar[tuple[int, ...]] = walls.CONTACT_CODES

    def __init__(self, h: ArrayLike, ell: ArrayLike, mass: ArrayLike = 1.0, inertia: ArrayLike | None = None):
        require_x64()  # float32 leaves would void every accuracy claim
        h, ell, mass, inertia, kind = walls.scene_leaves(h, ell, mass, inertia)
        super().__init__(StickFromVertical(ell, mass, inertia, kind), Strip(h))

    def check(self) -> None:
        """Raise ValueError if the (possibly replaced) parameters are invalid or change ``kind``."""
        walls.check_scene(self)

    @property
    def h(self) -> jax.Array:
        """The distance between the walls."""
        return cast(Strip, self.table).h

    @property
    def ell(self) -> jax.Array:
        """The stick's half-length."""
        return cast(Dumbbell, self.body).l1

    @property
    def batch_chunk(self) -> int:
        return walls.batch_chunk(self.kind)

    def motion_is_representable(self, state) -> jax.Array:
        """Traceable: the velocities' squares and the energy are ordinary float64 numbers."""
        return walls.motion_is_representable(self, state[..., 3:5], state[..., 5] ** 2, state)

    def end_points(self, state: jax.Array) -> jax.Array:
        """Ends ``[P1, P2]`` as ``(x, z)``, shape ``(..., 2, 2)``."""
        return self.contact_points(state)[..., :2, :]

    def kick(self, state: tuple, gap: jax.Array) -> tuple:
        """Elastic frictionless impulse of the wall touched in gap ``gap`` (0..3), on components.

        The impulse ``J`` is vertical. With the end's height ``z_k = z + e_k
        ell cos theta`` and ``s = dz_k/dtheta = -e_k ell sin theta``, the end's
        vertical velocity ``vz + s omega`` reverses:
        ``J = -2 (vz + s omega) / (1/M + s^2/I)``, ``vz' = vz + J/M``,
        ``omega' = omega + s J / I``. Energy is conserved exactly.
        """
        x, z, theta, vx, vz, omega = state
        lever = -walls.end_sign(gap) * self.ell * cos_sin(theta)[1]
        inv_mass = 1.0 / self.mass
        inv_inertia = 1.0 / self.inertia if self.kind == "rotor" else jnp.zeros_like(self.inertia)
        impulse = -2.0 * (vz + lever * omega) / (inv_mass + lever * lever * inv_inertia)
        return x, z, theta, vx, vz + impulse * inv_mass, omega + impulse * inv_inertia * lever

    @property
    def dynamical_indices(self) -> tuple[int, ...]:
        """State coordinates that carry the dynamics: ``(z, theta, vz, omega)`` = ``(1, 2, 4, 5)``.

        ``x`` and ``vx`` decouple: no contact time or impulse depends on them,
        and in the flow's tangent map they only carry ``dx' = dx + t dvx``. A
        stick that never turns keeps ``theta`` fixed and ``omega = 0``: then
        only ``(z, vz)`` = ``(1, 4)`` move.
        """
        if self.kind == "rotor":
            return (1, 2, 4, 5)
        return (1, 4)

    def phase_velocity(self, state: jax.Array) -> jax.Array:
        """The flow's vector field during free flight, ``[vx, vz, omega, 0, 0, 0]``, shape ``(..., 6)``."""
        state = jnp.asarray(state)
        return jnp.concatenate([state[..., 3:6], jnp.zeros_like(state[..., 0:3])], axis=-1)

    # -- what the analyses ask (jaxbill._scenes.protocols's capability protocols) ---------------------

    sections: ClassVar[tuple[str, ...]] = ("floor",)
    area_preserving_section: ClassVar[str] = "floor"
    # The horizontal drift divides out.
    periodic_symmetry: ClassVar[str] = "translation"

    def section(self, states: jax.Array, contacts: jax.Array | None = None, name: str | None = None) -> jax.Array:
        """Section points ``(..., 2)`` at floor collisions, NaN elsewhere (``HasSection``; ``jb.floor_section``).

        ``contacts`` ``(...)``, the collisions' contact codes, are needed: they say which wall was hit.
        """
        chosen_section(self, name)
        if contacts is None:
            raise ValueError("contacts: the floor section needs the collisions' contact codes (Orbit.contact)")
        return floor_section(self, states, contacts)

    def section_state(self, point: ArrayLike, energy=0.5, spin=0.0) -> jax.Array:
        """The state just after a floor collision at ``point = (theta, p)``, shape ``(..., 2)``, at the
        energy ``E'`` of the dynamical part (``spin`` must be 0) (``jb.floor_state``)."""
        xy = jnp.asarray(point, dtype=jnp.float64)
        return floor_state(self, xy[..., 0], xy[..., 1], energy, spin)

    @property
    def section_chart(self) -> SectionChart:
        """The explorer's chart of the floor section: ``(theta, p)`` of a stick that turns.

        Raises:
            TypeError: for a stick that never turns (``inertia = inf``): its angle never changes, so
                its floor section has nothing to explore in ``theta``.
        """
        if not self.body_turns:
            raise TypeError(
                "scene: a stick between walls that never turns (inertia = inf) has no floor section to "
                "explore: its angle theta never changes"
            )
        return WALLS_2D_CHART

    def checker_flight(self) -> ReducedWalls:
        """The reduced ``(z, psi)`` flight of ``jaxbill._check.walls`` (``HasCheckerFlight``)."""
        return ReducedWalls(planar=True)

    # == end of analysis block ============================================================
