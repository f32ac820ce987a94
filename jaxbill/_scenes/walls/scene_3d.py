"""A stick between two flat walls in space.

State layout (float64, shape ``(12,)``)::

    [x, y, z, ux, uy, uz, vx, vy, vz, wx, wy, wz]

``c = (x, y, z)`` is the centre (``z`` the height above the floor), ``u`` the
unit vector from the centre to end P1, ``v`` the centre's velocity and ``w`` the
angular velocity, perpendicular to ``u`` (a thin stick has no spin about its
own axis). The ends are ``P1 = c + ell u`` and ``P2 = c - ell u``. Orientation
is a vector, not polar angles, so nothing breaks when the stick is vertical.

Free flight: ``c`` moves straight; ``u`` turns uniformly about ``w``,
``u(t) = u cos(|w| t) + (w x u) sin(|w| t) / |w|``; ``w`` is constant. The
walls are ``z = 0`` and ``z = h``, contact codes as for
``StickBetweenWalls2D``. The impulses are vertical, so the energy, the
horizontal momentum and the vertical angular momentum ``L_z = M (x vy - y vx)
+ I wz`` are conserved. In the reduced ``(ell theta, z)`` picture the flights
are curved by the potential ``L_z^2 / (2 M ell^2 sin^2 theta)``.

A stick moving in the ``x``-``z`` plane, ``[x, 0, z, sin th, 0, cos th, vx,
0, vz, 0, omega, 0]``, is the 2D scene's ``[x, z, th, vx, vz, omega]``.
"""

from __future__ import annotations

from typing import ClassVar

import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np
from jaxtyping import ArrayLike

from jaxbill._engine.step import components, stacked
from jaxbill._engine.validation import require_x64
from jaxbill._scenes.protocols import ReducedWalls, SectionChart, chosen_section, component
from jaxbill._scenes.walls import engine as walls
from jaxbill._scenes.walls.charts import WALLS_3D_CHART
from jaxbill._scenes.walls.sections import floor_state, reduced_wall_section

# Tolerance on |u| = 1 and w . u = 0 in a given state (relative).
UNIT_TOLERANCE = 1e-10


class StickBetweenWalls3D(walls.WallsEngine):
    """A stick of half-length ``ell`` bouncing between the planes ``z = 0`` and ``z = h``.

    Args:
        h: distance between the walls, ``h > 0`` (``2 ell > h`` is allowed).
        ell: half-length of the stick, ``ell > 0``.
        mass: total mass ``M > 0`` (default 1).
        inertia: moment of inertia about any axis through the centre
            perpendicular to the stick, ``I > 0``; ``None`` means
            ``mass * ell**2``; ``float('inf')`` is a stick that never turns
            (``w`` must be 0).

    The leaves are differentiable; ``kind`` (``"rotor"`` or ``"static"``) is
    static, as for ``StickBetweenWalls2D``.
    """

    h: jax.Array
    ell: jax.Array
    mass: jax.Array
    inertia: jax.Array
    kind: str = eqx.field(static=True)

    state_size: ClassVar[int] = 12
    state_layout: ClassVar[str] = "[x, y, z, ux, uy, uz, vx, vy, vz, wx, wy, wz]"
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
    def body_turns(self) -> bool:
        """Static: the stick turns (finite inertia): its spin is a coordinate of the dynamics."""
        return self.kind == "rotor"

    @property
    def body_is_point(self) -> bool:
        """Static: never; a stick has an orientation."""
        return False

    @property
    def batch_chunk(self) -> int:
        return walls.batch_chunk(self.kind)

    @property
    def gap_scale(self) -> jax.Array:
        return self.h

    def check_state_values(self, state: np.ndarray) -> None:
        walls.check_batch_of_states(self, state)
        u, w = state[..., 3:6], state[..., 9:12]
        norm = np.linalg.norm(u, axis=-1)
        if np.any(np.abs(norm - 1.0) > UNIT_TOLERANCE):
            raise ValueError(
                f"u = state[3:6] must be a unit vector (to {UNIT_TOLERANCE:g}); got |u| = {norm.ravel()[:4].tolist()}"
            )
        along = np.abs(np.sum(u * w, axis=-1))
        if np.any(along > UNIT_TOLERANCE * np.maximum(np.linalg.norm(w, axis=-1), 1.0)):
            raise ValueError(
                "w = state[9:12] must be perpendicular to u (a thin stick has no spin about its axis); "
                f"got w . u = {along.ravel()[:4].tolist()}"
            )
        if self.kind == "static" and np.any(w != 0):
            raise ValueError("w must be 0 for a stick that never turns (inertia = inf)")

    def is_valid(self, state: jax.Array) -> jax.Array:
        ok = walls.parameters_are_valid(self.h, self.ell, self.mass, self.inertia, self.kind)
        ok &= jnp.all(jnp.isfinite(state)) & self.motion_is_representable(state) & walls.state_is_inside(self, state)
        u, w = state[3:6], state[9:12]
        ok &= jnp.abs(jnp.linalg.norm(u) - 1.0) <= UNIT_TOLERANCE
        ok &= jnp.abs(u @ w) <= UNIT_TOLERANCE * jnp.maximum(jnp.linalg.norm(w), 1.0)
        if self.kind == "static":
            ok &= jnp.all(w == 0.0)
        return ok

    def motion_is_representable(self, state) -> jax.Array:
        """Traceable: the velocities' squares and the energy are ordinary float64 numbers."""
        return walls.motion_is_representable(self, state[..., 6:9], jnp.sum(state[..., 9:12] ** 2, axis=-1), state)

    def orbit_constants(self, state0: tuple) -> None:
        return None

    # -- the engine's questions (see jaxbill._engine.step) -------------------------------
    # States are components (x, y, z, ux, uy, uz, vx, vy, vz, wx, wy, wz);
    # results are tuples.

    def moved(self, state: tuple, t) -> tuple:
        """The free flight of the components for time ``t``, ``u`` and ``w`` renormalised."""
        return self._renormalised(self._flight(state, t))

    def end_gaps(self, state: tuple) -> tuple:
        """``(z1, z2, h - z1, h - z2)`` of the components."""
        return walls.end_gaps(state[2], self.ell * state[5], self.h)

    def end_approach_speeds(self, state: tuple) -> tuple:
        """The rates at which the four gaps close (> 0: that end approaches that wall)."""
        _, _, _, ux, uy, _, _, _, vz, wx, wy, _ = state
        return walls.end_gaps_closing(vz, self.ell * (wx * uy - wy * ux), 1.0)

    def _flight(self, state: tuple, t) -> tuple:
        """``c + v t``, ``u`` turned about ``w`` by ``|w| t``."""
        x, y, z, ux, uy, uz, vx, vy, vz, wx, wy, wz = state
        if self.kind == "rotor":
            cos, sinc = walls.turn(wx * wx + wy * wy + wz * wz, t)
            ux, uy, uz = (
                ux * cos + (wy * uz - wz * uy) * sinc,
                uy * cos + (wz * ux - wx * uz) * sinc,
                uz * cos + (wx * uy - wy * ux) * sinc,
            )
        return x + vx * t, y + vy * t, z + vz * t, ux, uy, uz, vx, vy, vz, wx, wy, wz

    def _renormalised(self, state: tuple) -> tuple:
        """``u`` back to unit length and ``w`` back perpendicular to it.

        Rounding in the flight moves both by ulps per collision; left alone that
        would drift without bound over a long run.
        """
        if self.kind == "static":
            return state
        x, y, z, ux, uy, uz, vx, vy, vz, wx, wy, wz = state
        norm = jnp.sqrt(ux * ux + uy * uy + uz * uz)
        ux, uy, uz = ux / norm, uy / norm, uz / norm
        along = wx * ux + wy * uy + wz * uz
        return x, y, z, ux, uy, uz, vx, vy, vz, wx - along * ux, wy - along * uy, wz - along * uz

    # -- geometry and flight -------------------------------------------------------

    def vertical_profile(self, state):
        """``(z0, vz, A, D, W^2, ell, h)`` of ``jaxbill._scenes.walls.engine``: ``a = uz``."""
        _, _, z, ux, uy, uz, _, _, vz, wx, wy, wz = state
        return (z, vz, uz, wx * uy - wy * ux, wx * wx + wy * wy + wz * wz, self.ell, self.h)

    def end_points(self, state: jax.Array) -> jax.Array:
        """Ends ``[P1, P2]``, shape ``(..., 2, 3)``."""
        c = state[..., 0:3]
        arm = self.ell[..., None] * state[..., 3:6]
        return jnp.stack([c + arm, c - arm], axis=-2)

    def gaps(self, state: jax.Array) -> jax.Array:
        """``[z1, z2, h - z1, h - z2]``, shape ``(..., 4)``, >= 0 inside (length units)."""
        return jnp.stack(self.end_gaps(components(state)), axis=-1)

    def approach_speeds(self, state: jax.Array) -> jax.Array:
        """Rate at which each gap closes, shape ``(..., 4)`` (> 0: the end approaches that wall)."""
        return jnp.stack(self.end_approach_speeds(components(state)), axis=-1)

    def flight(self, state: jax.Array, t: jax.Array) -> jax.Array:
        """Free flight for time ``t``: ``c + v t``, ``u`` turned about ``w`` by ``|w| t``."""
        return stacked(self._flight(components(state), t))

    def kick(self, state: tuple, gap: jax.Array) -> tuple:
        """Elastic frictionless impulse of the wall touched in gap ``gap`` (0..3), on components.

        The impulse ``J zhat`` acts at ``r = e_k ell u``. The end's vertical
        velocity ``vz + (w x r)_z`` reverses:
        ``J = -2 (vz + (w x r)_z) / (1/M + |r x zhat|^2 / I)``,
        ``v' = v + (J/M) zhat``, ``w' = w + (J/I) (r x zhat)``.
        """
        x, y, z, ux, uy, uz, vx, vy, vz, wx, wy, wz = state
        arm = walls.end_sign(gap) * self.ell
        lever_x, lever_y = arm * uy, -arm * ux  # r x zhat (its z component is 0)
        inv_mass = 1.0 / self.mass
        inv_inertia = 1.0 / self.inertia if self.kind == "rotor" else jnp.zeros_like(self.inertia)
        end_rise = vz + arm * (wx * uy - wy * ux)
        impulse = -2.0 * end_rise / (inv_mass + (lever_x * lever_x + lever_y * lever_y) * inv_inertia)
        spin_kick = impulse * inv_inertia
        return (
            x,
            y,
            z,
            ux,
            uy,
            uz,
            vx,
            vy,
            vz + impulse * inv_mass,
            wx + spin_kick * lever_x,
            wy + spin_kick * lever_y,
            wz,
        )

    # -- invariants -------------------------------------------------------------------

    def energy(self, state: jax.Array) -> jax.Array:
        """``M |v|^2/2 + I |w|^2/2`` (a stick that never turns drops the spin term)."""
        vx, vy, vz, wx, wy, wz = (component(state, i) for i in range(6, 12))
        e = 0.5 * self.mass * (vx**2 + vy**2 + vz**2)
        if self.kind == "static":
            return e
        return e + 0.5 * self.inertia * (wx**2 + wy**2 + wz**2)

    def angular_momentum(self, state: jax.Array) -> jax.Array:
        """The conserved vertical angular momentum ``L_z = M (x vy - y vx) + I wz``."""
        x, y, vx, vy = state[..., 0], state[..., 1], state[..., 6], state[..., 7]
        orbital = self.mass * (x * vy - y * vx)
        if self.kind == "static":
            return orbital
        return orbital + self.inertia * state[..., 11]

    # == analysis (tangent maps, Lyapunov spectra, periodic orbits: jaxbill._engine.tangent) ======
    # Added for the analysis modules; the engine above does not use these.

    @property
    def dynamical_size(self) -> int:
        """Dimension of the dynamical tangent space (``dynamical_frame``): 6, or 2 for a stick that never turns."""
        return 6 if self.kind == "rotor" else 2

    def phase_velocity(self, state: jax.Array) -> jax.Array:
        """The flow's vector field during free flight, ``[v, w x u, 0, 0]``, shape ``(..., 12)``."""
        state = jnp.asarray(state)
        u, v, w = state[..., 3:6], state[..., 6:9], state[..., 9:12]
        zeros = jnp.zeros_like(v)
        return jnp.concatenate([v, jnp.cross(w, u), zeros, zeros], axis=-1)

    def dynamical_frame(self, state: jax.Array) -> jax.Array:
        """Orthonormal columns spanning the tangent directions that carry the dynamics at ``state``.

        Shape ``(12, 6)`` (``(12, 2)`` for a stick that never turns). The
        horizontal motion ``(x, y, vx, vy)`` decouples, as in 2D. The rest,
        ``(z, u, vz, w)``, lives on the manifold ``|u| = 1``, ``w . u = 0``;
        a perturbation ``(du, dw)`` stays on it to first order when
        ``u . du = 0`` and ``w . du + u . dw = 0``. With ``dz`` and ``dvz`` that
        leaves 6 directions: ``e_z``, ``e_vz`` and an orthonormal basis of the
        null space of the ``2 x 6`` constraint matrix ``[[u, 0], [w, u]]`` in
        the ``(du, dw)`` coordinates (4 directions: ``du`` perpendicular to
        ``u``, and ``dw`` perpendicular to ``u`` corrected by ``-(w . du) u``).
        The columns are orthonormal in the 12 state coordinates; which basis
        of that space is chosen does not matter to a QR (only the span does).
        A stick that never turns has ``u`` fixed and ``w = 0``: ``(e_z, e_vz)``.
        """
        state = jnp.asarray(state)
        eye = jnp.eye(12, dtype=state.dtype)
        vertical = eye[:, [2, 8]]
        if self.kind == "static":
            return vertical
        u, w = state[3:6], state[9:12]
        zero = jnp.zeros_like(u)
        constraints = jnp.stack([jnp.concatenate([u, zero]), jnp.concatenate([w, u])])
        _, _, vt = jnp.linalg.svd(constraints, full_matrices=True)
        basis = jax.lax.stop_gradient(vt[2:].T)  # (6, 4) in (du, dw)
        turning = jnp.zeros((12, 4), state.dtype).at[3:6].set(basis[0:3]).at[9:12].set(basis[3:6])
        return jnp.concatenate([vertical, turning], axis=1)

    # -- what the analyses ask (jaxbill._scenes.protocols's capability protocols) ---------------------

    sections: ClassVar[tuple[str, ...]] = ("reduced floor",)
    area_preserving_section: ClassVar[str] = "reduced floor"
    # The horizontal drift divides out (and, for a turning stick, the turn about the vertical).
    periodic_symmetry: ClassVar[str] = "translation"
    symplectic_flow: ClassVar[bool] = True  # HasSymplecticFlow: elastic and Hamiltonian

    def section(self, states: jax.Array, contacts: jax.Array | None = None, name: str | None = None) -> jax.Array:
        """Section points ``(..., 2)`` at floor collisions, NaN elsewhere (``HasSection``; ``jb.reduced_wall_section``).

        ``contacts`` ``(...)``, the collisions' contact codes, are needed: they say which wall was hit.
        """
        chosen_section(self, name)
        if contacts is None:
            raise ValueError("contacts: the reduced floor section needs the collisions' contact codes (Orbit.contact)")
        return reduced_wall_section(self, states, contacts)

    def section_state(self, point: ArrayLike, energy=0.5, spin=0.0) -> jax.Array:
        """The state just after a floor collision at ``point = (theta, p)``, shape ``(..., 2)``, at the
        energy ``E'`` of the dynamical part and the spin ``I w_z`` (``jb.floor_state``)."""
        xy = jnp.asarray(point, dtype=jnp.float64)
        return floor_state(self, xy[..., 0], xy[..., 1], energy, spin)

    @property
    def section_chart(self) -> SectionChart:
        """The explorer's chart of the reduced floor section."""
        return WALLS_3D_CHART

    def checker_flight(self) -> ReducedWalls:
        """The reduced ``(z, psi)`` flight of ``jaxbill._check.walls`` (``HasCheckerFlight``)."""
        return ReducedWalls(planar=False)

    # == end of analysis block ============================================================
