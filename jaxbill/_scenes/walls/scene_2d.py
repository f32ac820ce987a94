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

from typing import ClassVar

import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np
from jaxtyping import ArrayLike

from jaxbill._check.walls import ReducedWallsFlight
from jaxbill._engine.step import components, cos_sin, stacked, wrapped_angle
from jaxbill._engine.validation import require_x64
from jaxbill._scenes.protocols import SectionChart, chosen_section, component
from jaxbill._scenes.walls import engine as walls
from jaxbill._scenes.walls.charts import WALLS_2D_CHART
from jaxbill._scenes.walls.sections import floor_section, floor_state


class StickBetweenWalls2D(walls.WallsEngine, eqx.Module):
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

    h: jax.Array
    ell: jax.Array
    mass: jax.Array
    inertia: jax.Array
    kind: str = eqx.field(static=True)

    state_size: ClassVar[int] = 6
    state_layout: ClassVar[str] = "[x, z, theta, vx, vz, omega]"
    gap_names: ClassVar[tuple[str, ...]] = walls.GAP_NAMES
    wall_name: ClassVar[str] = "the walls"

    def __init__(self, h: ArrayLike, ell: ArrayLike, mass: ArrayLike = 1.0, inertia: ArrayLike | None = None):
        require_x64()  # float32 leaves would void every accuracy claim
        self.h, self.ell, self.mass, self.inertia, self.kind = walls.scene_leaves(h, ell, mass, inertia)

    def check(self) -> None:
        """Raise ValueError if the (possibly replaced) parameters are invalid or change ``kind``."""
        walls.check_scene(self)

    # -- engine interface (jaxbill._scenes.protocols) --------------------------------------

    @property
    def batch_chunk(self) -> int:
        return walls.batch_chunk(self.kind)

    @property
    def gap_scale(self) -> jax.Array:
        return self.h

    def check_state_values(self, state: np.ndarray) -> None:
        walls.check_batch_of_states(self, state)
        if self.kind == "static" and np.any(state[..., 5] != 0):
            raise ValueError("omega must be 0 for a stick that never turns (inertia = inf)")

    def is_valid(self, state: jax.Array) -> jax.Array:
        ok = walls.parameters_are_valid(self.h, self.ell, self.mass, self.inertia, self.kind)
        ok &= jnp.all(jnp.isfinite(state)) & self.motion_is_representable(state) & walls.state_is_inside(self, state)
        if self.kind == "static":
            ok &= state[5] == 0.0
        return ok

    def motion_is_representable(self, state) -> jax.Array:
        """Traceable: the velocities' squares and the energy are ordinary float64 numbers."""
        return walls.motion_is_representable(self, state[..., 3:5], state[..., 5] ** 2, state)

    def orbit_constants(self, state0: tuple) -> None:
        return None

    # -- the engine's questions (see jaxbill._engine.step) -------------------------------
    # States are components (x, z, theta, vx, vz, omega); results are tuples.

    def moved(self, state: tuple, t) -> tuple:
        """The free flight of the components for time ``t``."""
        return self._flight(state, t)

    def end_gaps(self, state: tuple) -> tuple:
        """``(z1, z2, h - z1, h - z2)`` of the components."""
        return self.end_gaps_and_speeds(state)[0]

    def end_approach_speeds(self, state: tuple) -> tuple:
        """The rates at which the four gaps close (> 0: that end approaches that wall)."""
        return self.end_gaps_and_speeds(state)[1]

    def end_gaps_and_speeds(self, state: tuple) -> tuple:
        """``(end_gaps, end_approach_speeds)`` from one cosine and sine of ``theta``."""
        cos, sin = cos_sin(state[2])
        return (
            walls.end_gaps(state[1], self.ell * cos, self.h),
            walls.end_gaps_closing(state[4], -self.ell * sin * state[5], 1.0),
        )

    def _flight(self, state: tuple, t) -> tuple:
        x, z, theta, vx, vz, omega = state
        if self.kind == "rotor":
            theta = wrapped_angle(theta + omega * t)
        return x + vx * t, z + vz * t, theta, vx, vz, omega

    # -- geometry and flight -------------------------------------------------------

    def vertical_profile(self, state):
        """``(z0, vz, A, D, W^2, ell, h)`` of ``jaxbill._scenes.walls.engine``: ``a = cos theta``."""
        theta, omega = state[2], state[5]
        cos, sin = cos_sin(theta)
        return (state[1], state[4], cos, -omega * sin, omega * omega, self.ell, self.h)

    def end_points(self, state: jax.Array) -> jax.Array:
        """Ends ``[P1, P2]`` as ``(x, z)``, shape ``(..., 2, 2)``."""
        c = state[..., 0:2]
        arm = self.ell[..., None] * jnp.stack([jnp.sin(state[..., 2]), jnp.cos(state[..., 2])], axis=-1)
        return jnp.stack([c + arm, c - arm], axis=-2)

    def gaps(self, state: jax.Array) -> jax.Array:
        """``[z1, z2, h - z1, h - z2]``, shape ``(..., 4)``, >= 0 inside (length units)."""
        return jnp.stack(self.end_gaps(components(state)), axis=-1)

    def approach_speeds(self, state: jax.Array) -> jax.Array:
        """Rate at which each gap closes, shape ``(..., 4)`` (> 0: the end approaches that wall)."""
        return jnp.stack(self.end_approach_speeds(components(state)), axis=-1)

    def flight(self, state: jax.Array, t: jax.Array) -> jax.Array:
        """Free flight for time ``t``; ``theta`` is wrapped into ``[-pi, pi)``."""
        return stacked(self._flight(components(state), t))

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

    # -- invariants -------------------------------------------------------------------

    def energy(self, state: jax.Array) -> jax.Array:
        """``M (vx^2 + vz^2)/2 + I omega^2/2`` (a stick that never turns drops the spin term)."""
        vx, vz, omega = (component(state, i) for i in (3, 4, 5))
        e = 0.5 * self.mass * (vx**2 + vz**2)
        if self.kind == "static":
            return e
        return e + 0.5 * self.inertia * omega**2

    # == analysis (tangent maps, Lyapunov spectra, periodic orbits: jaxbill._engine.tangent) ======
    # Added for the analysis modules; the engine above does not use these.

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
    symplectic_flow: ClassVar[bool] = True  # HasSymplecticFlow: elastic and Hamiltonian

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
        """The explorer's chart of the floor section."""
        return WALLS_2D_CHART

    def checker_flight(self) -> ReducedWallsFlight:
        """The reduced ``(z, psi)`` flight of ``jaxbill._check.walls`` (``HasCheckerFlight``)."""
        return ReducedWallsFlight(planar=True)

    # == end of analysis block ============================================================
