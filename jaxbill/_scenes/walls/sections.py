"""Sections and pictures of the stick between two flat walls.

Every ``jax.numpy`` function here is pure (``jit``, ``vmap`` and ``grad``
work) and takes states as ``jb.orbit`` returns them (just after each impulse)
with their contact codes. The twin-orbit chaos test at the end is plain NumPy
on finished orbits, like ``jaxbill._analysis.section_measures``.

The billiard picture (Chatterjee and Jackson, "What's the Stick?")
==================================================================

With ``I = M kappa^2`` (``kappa`` the radius of gyration: ``kappa = ell`` for
the default ``I = M ell^2``) and ``eta = z / kappa``, the energy of the
vertical motion and the turning is ``E' = (I / 2) (theta_dot^2 +
eta_dot^2)``: a point ``(theta, eta)`` moving freely in a Euclidean plane at
the fixed speed ``|V| = sqrt(2 E' / I)``. An end touches the floor when
``eta = b(theta) = (ell/kappa)|cos theta|`` and the ceiling when ``eta =
t(theta) = (h - ell|cos theta|)/kappa`` (``floor_wall``, ``ceiling_wall``),
and every impulse reflects ``(theta_dot, eta_dot)`` specularly about the
wall (``tests/test_walls_sections.py`` checks jaxbill's impulse law against
that reflection). The walls have kinks where the stick is horizontal
(``theta = pi/2 mod pi``); for ``I = M ell^2`` the floor's kink is a right
angle. The horizontal motion of the centre is free and decoupled, and is left
out: ``E'`` is the energy without ``M vx^2 / 2`` (``M (vx^2 + vy^2)/2`` in 3D).
Plotted in lengths, the plane is ``(kappa theta, z)``: the paper's ``(ell
theta, z)`` for ``I = M ell^2`` (for another inertia, ``(ell theta, z)`` is
not a plane in which the reflection is specular; ``(kappa theta, z)`` is).

The floor section (2D)
======================

``floor_section`` gives, at every collision with the floor, the pair

* ``theta mod pi`` in ``[0, pi)``: ``theta`` and ``theta + pi`` are the same
  stick with its ends relabelled. The floor's kink (the stick flat) is at
  ``pi/2``;
* ``p = (I omega + M vz dz/dtheta) / sqrt(2 I E')``, where ``z(theta) =
  ell|cos theta|`` is the centre's height when an end rests on the floor,
  so ``dz/dtheta = e ell sin(theta)`` for end ``e`` (``+1`` P1, ``-1`` P2) on
  the floor. In the paper's variables ``p = T . V / |V|`` with ``V =
  (theta_dot, eta_dot)`` and ``T = (1, db/dtheta)`` the paper's (unnormalised)
  tangent of the floor, ``T = (1, -(ell/kappa) sin theta)`` for ``cos theta >
  0``. Physically, ``p sqrt(2 I E')`` is the angular momentum of the stick
  about the touching end in the frame that moves with the centre's
  horizontal velocity.

Why this ``p``. The impulse is normal to the wall in the ``(theta, eta)``
plane, so ``T . V`` is unchanged by it (the paper's tangential condition
``T . Delta v = 0``): ``p`` is the same just before and just after a
bounce. And ``(theta, p)`` is area-preserving: a billiard's boundary map
preserves the canonical form restricted to the wall, ``sum_i dp_i ^ dq_i``
with ``q = (theta, eta(theta))`` on the wall, which is ``d(p_theta + p_eta
db/dtheta) ^ dtheta = I |V| dp ^ dtheta``; ``I |V|`` is constant. Two
tempting alternatives are not: the plain ``theta_dot / |V|`` (it drops the
``p_eta db/dtheta`` part) and the Birkhoff sine ``T . V / (|T| |V|)`` paired
with ``theta`` (it is conjugate to the arc length ``s = int |T| dtheta``, not
to ``theta``). The tests compute the Jacobian of the floor-to-floor map in
all three: determinant 1 (to 1e-9) for ``(theta, p)`` only. Equal areas of
the ``(theta mod pi, p)`` plane therefore hold equal phase-space volume at
fixed ``E'`` and the share of seeds that are chaotic estimates the chaotic
share of the section. The reachable region is ``|p| <= |T| =
sqrt(1 + (ell/kappa)^2 sin^2 theta)`` (``floor_section_bound``); for ``2 ell
> h`` only ``|cos theta| <= h / (2 ell)`` has a floor at all.

A contact ``2`` (several contacts in one event) counts as a floor
collision when an end is on the floor: one end on the floor and the other on
the ceiling uses the floor end; both ends on the floor (a flat landing, the
kink) uses the mean of the two one-sided tangents, ``T = (1, 0)``, so ``p =
I omega / sqrt(2 I E')`` there. Other collisions give NaN, so the output keeps
the input's shape; plotting skips NaN.

Mirror symmetry: ``x -> -x`` maps ``(theta, p)`` to ``(pi - theta, -p)``
(``mod pi``), so every 2D section is point-symmetric about ``(pi/2, 0)``.

The reduced section (3D)
========================

The impulses are vertical, so ``I w_z`` (and the orbital part of ``L_z``, and
so ``L_z``) is conserved. With ``theta`` the polar angle of ``u`` from the
vertical (computed as ``atan2(|u_perp|, u_z)``, in ``[0, pi]``, stable at the
poles; no azimuth is needed), the reduced system is the billiard in ``(kappa
theta, z)`` with the same walls and the potential ``(I w_z)^2 / (2 I
sin^2 theta)``: curved flights (``theta_z_path``). ``reduced_wall_section``
gives ``(theta, p)`` at floor collisions with the same ``p`` (``theta_dot =
-(w x u)_z / sin theta`` is the polar rate); the same argument makes it
area-preserving at fixed ``E'`` and ``I w_z``, now with ``|p| <= |T| sqrt(1 -
U(theta)/E')``. Relabelling the ends (``u -> -u``) maps ``(theta, p)`` to
``(pi - theta, -p)``. A 2D state embedded in the ``x``-``z`` plane (``L_z =
0``) has polar angle ``|theta_2D|``: its 3D point equals its 2D point for
``sin theta_2D >= 0`` and is the mirror image ``(pi - theta, -p)`` of it
otherwise.
"""

from __future__ import annotations

import jax
import jax.numpy as jnp
import numpy as np
from jaxtyping import Array, ArrayLike, Float, Int

from jaxbill._engine.collision import orbit as _orbit
from jaxbill._engine.step import cos_sin
from jaxbill._engine.validation import MAX_STORED_COUNT, as_states, check_count, require_x64
from jaxbill._scenes.circle.sections import halton

# Floor gaps below this many units of h count as "on the floor" in a contact 2.
_ON_WALL = 1e-9


def _check_turning(scene) -> None:
    if scene.kind != "rotor":
        raise ValueError("the (theta, eta) picture needs a stick that turns (finite inertia)")


def _is_3d(scene) -> bool:
    return scene.state_size == 12


def gyration_radius(scene) -> jax.Array:
    """``kappa = sqrt(I / M)``, the radius of gyration (``ell`` for the default inertia)."""
    return jnp.sqrt(scene.inertia / scene.mass)


def floor_wall(scene, theta) -> jax.Array:
    """The paper's floor ``b(theta) = (ell/kappa)|cos theta|`` in ``eta = z/kappa`` units."""
    return scene.ell / gyration_radius(scene) * jnp.abs(jnp.cos(theta))


def ceiling_wall(scene, theta) -> jax.Array:
    """The paper's ceiling ``t(theta) = (h - ell|cos theta|)/kappa`` (below ``b``: no room there)."""
    return (scene.h - scene.ell * jnp.abs(jnp.cos(theta))) / gyration_radius(scene)


def polar_angle(u: jax.Array) -> jax.Array:
    """Angle of the unit vectors ``u`` (``(..., 3)``) from the upward vertical, in ``[0, pi]``.

    ``atan2(|u_perp|, u_z)``: accurate at the poles, where ``arccos(u_z)`` is not.
    """
    return jnp.arctan2(jnp.hypot(u[..., 0], u[..., 1]), u[..., 2])


def internal_energy(scene, states: jax.Array) -> jax.Array:
    """``E' = M vz^2/2 + I |omega|^2/2``: the energy without the free horizontal motion."""
    if _is_3d(scene):
        w = states[..., 9:12]
        return 0.5 * scene.mass * states[..., 8] ** 2 + 0.5 * scene.inertia * jnp.sum(w * w, axis=-1)
    return 0.5 * scene.mass * states[..., 4] ** 2 + 0.5 * scene.inertia * states[..., 5] ** 2


def internal_energy_np(scene, states) -> np.ndarray:
    """``internal_energy`` in NumPy, for finished results (no JAX dispatch or compilation)."""
    states = np.asarray(states, dtype=np.float64)
    mass, inertia = float(np.asarray(scene.mass)), float(np.asarray(scene.inertia))
    if _is_3d(scene):
        return 0.5 * mass * states[..., 8] ** 2 + 0.5 * inertia * np.sum(states[..., 9:12] ** 2, axis=-1)
    return 0.5 * mass * states[..., 4] ** 2 + 0.5 * inertia * states[..., 5] ** 2


def spin_momentum(scene, states: jax.Array) -> jax.Array:
    """``I w_z`` of 3D states: the spin part of ``L_z``, conserved on its own (the reduced problem's ``L_z``)."""
    return scene.inertia * states[..., 11]


def _floor_end(scene, contacts: ArrayLike, heights: jax.Array):
    """Sign ``e`` of the end on the floor (``0.0`` at a flat landing) and whether it is a floor collision.

    ``heights`` are the two end heights ``[z_1, z_2]`` (the floor gaps).
    """
    contacts = jnp.asarray(contacts)
    tol = _ON_WALL * scene.h
    on1, on2 = jnp.abs(heights[..., 0]) <= tol, jnp.abs(heights[..., 1]) <= tol
    several = contacts == 2
    end = jnp.where(contacts == 1, 1.0, jnp.where(contacts == -1, -1.0, 0.0))
    end = jnp.where(several & on1 & ~on2, 1.0, jnp.where(several & on2 & ~on1, -1.0, end))
    floor = (contacts == 1) | (contacts == -1) | (several & (on1 | on2))
    return end, floor


@jax.jit
def floor_section(
    scene, states: Float[ArrayLike, "*batch S"], contacts: Int[ArrayLike, "*batch"]
) -> Float[Array, "*batch 2"]:
    """The 2D floor section ``[theta mod pi, p]`` (see the module docstring); NaN off the floor.

    Args:
        scene: a ``StickBetweenWalls2D`` with finite inertia.
        states: ``(..., 6)`` states at collisions, e.g. ``jb.orbit(...).state``.
        contacts: ``(...)`` their contact codes (``jb.orbit(...).contact``).

    Returns:
        ``(..., 2)``: ``theta mod pi`` in ``[0, pi)`` and ``p = (I omega + M e
        ell sin(theta) vz) / sqrt(2 I E')``, ``e`` the sign of the end on the
        floor, ``E'`` the energy without ``M vx^2/2``. Area-preserving for the
        floor-to-floor map; ``|p| <= floor_section_bound(scene, theta)``.
    """
    _check_turning(scene)
    if _is_3d(scene):
        raise ValueError("floor_section is for StickBetweenWalls2D; use reduced_wall_section in 3D")
    states = as_states(scene, states)
    theta, vz, omega = states[..., 2], states[..., 4], states[..., 5]
    heights = scene.gaps(states)[..., :2]
    end, floor = _floor_end(scene, contacts, heights)
    angular = scene.inertia * omega + scene.mass * end * scene.ell * jnp.sin(theta) * vz
    p = angular / jnp.sqrt(2.0 * scene.inertia * internal_energy(scene, states))
    point = jnp.stack([jnp.remainder(theta, jnp.pi), p], axis=-1)
    return jnp.where(floor[..., None], point, jnp.nan)


def _polar_rate(states: jax.Array):
    """Polar angle ``theta`` of ``u``, ``sin theta`` and the polar rate ``theta_dot`` of 3D states."""
    u, w = states[..., 3:6], states[..., 9:12]
    sin = jnp.hypot(u[..., 0], u[..., 1])
    theta = jnp.arctan2(sin, u[..., 2])
    # d(u_z)/dt = (w x u)_z = -sin(theta) theta_dot
    rise = w[..., 0] * u[..., 1] - w[..., 1] * u[..., 0]
    vertical = sin == 0.0
    # Exactly vertical: the polar angle grows at the rate |w| (it cannot decrease below 0).
    rate = jnp.where(vertical, jnp.sqrt(jnp.sum(w * w, axis=-1)), -rise / jnp.where(vertical, 1.0, sin))
    return theta, sin, rate


@jax.jit
def reduced_wall_section(
    scene, states: Float[ArrayLike, "*batch 12"], contacts: Int[ArrayLike, "*batch"]
) -> Float[Array, "*batch 2"]:
    """The 3D reduced section ``[theta, p]`` at floor collisions (see the module docstring); NaN elsewhere.

    ``theta = atan2(|u_perp|, u_z)`` in ``[0, pi]`` is the polar angle of
    ``u``, ``p = (I theta_dot + M e ell sin(theta) vz) / sqrt(2 I E')`` as in
    2D. Area-preserving at fixed ``E'`` and ``I w_z``.

    Args:
        scene: a ``StickBetweenWalls3D`` with finite inertia.
        states: ``(..., 12)`` states at collisions.
        contacts: ``(...)`` their contact codes.
    """
    _check_turning(scene)
    if not _is_3d(scene):
        raise ValueError("reduced_wall_section is for StickBetweenWalls3D; use floor_section in 2D")
    states = as_states(scene, states)
    theta, sin, rate = _polar_rate(states)
    heights = scene.gaps(states)[..., :2]
    end, floor = _floor_end(scene, contacts, heights)
    angular = scene.inertia * rate + scene.mass * end * scene.ell * sin * states[..., 8]
    p = angular / jnp.sqrt(2.0 * scene.inertia * internal_energy(scene, states))
    point = jnp.stack([theta, p], axis=-1)
    return jnp.where(floor[..., None], point, jnp.nan)


def _potential(scene, sin, spin):
    """``U = spin^2 / (2 I sin^2 theta)`` (0 for ``spin = 0``, even at the poles)."""
    sin2 = jnp.where(sin == 0.0, 1.0, sin * sin)
    return jnp.where(spin == 0.0, 0.0, jnp.where(sin == 0.0, jnp.inf, spin * spin / (2.0 * scene.inertia * sin2)))


@jax.jit
def floor_section_bound(
    scene, theta: Float[ArrayLike, "*batch"], energy: ArrayLike = 0.5, spin: ArrayLike = 0.0
) -> Float[Array, "*batch"]:
    """Largest ``|p|`` of the floor section at ``theta``: ``sqrt(1 + (ell/kappa)^2 sin^2 theta) sqrt(1 - U/E')``.

    ``U = spin^2 / (2 I sin^2 theta)`` with ``spin = I w_z`` (3D; 0 in 2D) and
    ``energy = E'``. NaN where nothing is reachable: no floor there (``2 ell
    |cos theta| > h``: the stick would not fit) or ``U > E'``.
    """
    theta = jnp.asarray(theta, dtype=jnp.float64)
    sin = jnp.sin(theta)
    slope = scene.ell / gyration_radius(scene) * sin
    potential = _potential(scene, sin, spin)
    room = 1.0 - potential / energy
    fits = 2.0 * scene.ell * jnp.abs(jnp.cos(theta)) <= scene.h
    bound = jnp.sqrt(1.0 + slope**2) * jnp.sqrt(jnp.where(room >= 0.0, room, jnp.nan))
    return jnp.where(fits, bound, jnp.nan)


def _floor_velocity(scene, theta, p, energy, spin):
    """``(theta_dot, vz)`` leaving the floor at ``theta`` with section momentum ``p``; lower end sign."""
    kappa = gyration_radius(scene)
    end = jnp.where(jnp.cos(theta) >= 0.0, -1.0, 1.0)  # the lower end rests on the floor
    sin = jnp.sin(theta)
    slope = end * scene.ell * sin / kappa  # db/dtheta along the floor (eta units)
    potential = _potential(scene, sin, spin)
    kinetic = energy - potential
    speed = jnp.sqrt(2.0 * kinetic / scene.inertia)  # |(theta_dot, eta_dot)|
    along = p * jnp.sqrt(energy / kinetic)  # T . V / |V|
    t2 = 1.0 + slope**2
    normal = jnp.sqrt(jnp.where(t2 - along**2 >= 0.0, t2 - along**2, jnp.nan))
    # V/|V| = (along T + normal N) / |T|^2 with T = (1, slope), N = (-slope, 1) into the room.
    theta_dot = speed * (along - normal * slope) / t2
    eta_dot = speed * (along * slope + normal) / t2
    return theta_dot, kappa * eta_dot, end


def floor_state(
    scene,
    theta: Float[ArrayLike, "*#batch"],
    p: Float[ArrayLike, "*#batch"],
    energy: ArrayLike = 0.5,
    spin: ArrayLike = 0.0,
) -> Float[Array, "*batch S"]:
    """The state just after a floor collision at section point ``(theta, p)``: the inverse of the sections.

    The lower end rests on the floor, the centre at ``x = y = 0``, ``z =
    ell|cos theta|``, with no horizontal velocity, internal energy ``E' =
    energy`` and moving away from the floor.

    Args:
        scene: ``StickBetweenWalls2D`` (``theta`` in ``[0, pi)``; ``spin``
            must be 0) or ``StickBetweenWalls3D`` (``theta`` the polar angle,
            the stick in the ``x``-``z`` plane, ``w_z = spin / I``).
        theta, p: section coordinates (broadcast together).
        energy: ``E'``; spin: ``I w_z`` (3D).

    Returns:
        ``(..., 6)`` or ``(..., 12)`` states; NaN where ``(theta, p)`` is not
        reachable (``floor_section_bound``). ``floor_section`` /
        ``reduced_wall_section`` of the result (with the lower end's contact
        code) give back ``(theta mod pi, p)``.
    """
    _check_turning(scene)
    if not _is_3d(scene) and not (isinstance(spin, (int, float)) and spin == 0.0):
        raise ValueError("a 2D stick has no spin about the vertical: spin must be 0")
    return _floor_state(
        scene,
        jnp.asarray(theta, dtype=jnp.float64),
        jnp.asarray(p, dtype=jnp.float64),
        jnp.asarray(energy, dtype=jnp.float64),
        jnp.asarray(spin, dtype=jnp.float64),
    )


@jax.jit
def _floor_state(scene, theta, p, energy, spin):
    theta, p = jnp.broadcast_arrays(theta, p)
    theta_dot, vz, _ = _floor_velocity(scene, theta, p, energy, spin)
    # The scene's own cosine and sine: the lower end then lies on the floor to the bit.
    cos, sin = cos_sin(theta)
    z = scene.ell * jnp.abs(cos)
    zero = jnp.zeros_like(theta)
    ok = jnp.isfinite(floor_section_bound(scene, theta, energy, spin)) & jnp.isfinite(vz)
    if _is_3d(scene):
        u = jnp.stack([sin, zero, cos], axis=-1)
        # w = u x du/dt = theta_dot e_phi - sin(theta) phi_dot e_theta with e_phi = y,
        # e_theta = (cos, 0, -sin) and I sin^2(theta) phi_dot = spin.
        phi_rate_sin = jnp.where(spin == 0.0, 0.0, spin / (scene.inertia * jnp.where(sin == 0.0, 1.0, sin)))
        w = jnp.stack([-phi_rate_sin * cos, theta_dot, phi_rate_sin * sin], axis=-1)
        state = jnp.concatenate(
            [jnp.stack([zero, zero, z], axis=-1), u, jnp.stack([zero, zero, vz], axis=-1), w], axis=-1
        )
    else:
        state = jnp.stack([zero, z, theta, zero, vz, theta_dot], axis=-1)
    return jnp.where(ok[..., None], state, jnp.nan)


def floor_seed_points(scene, count: int, energy=0.5, spin=0.0, *, offset: int = 1):
    """``count`` section points ``(theta, p)`` spread evenly (a Halton sequence) over the reachable floor section.

    ``theta`` in ``[0, pi)`` (bases 2 and 3 of the Halton sequence), kept
    where ``|p| < floor_section_bound(scene, theta, energy, spin)``. Returns
    two NumPy arrays ``(count,)``.
    """
    require_x64()
    count = check_count("count", count, 0, "number of seeds", MAX_STORED_COUNT)
    offset = check_count("offset", offset, 0, "first index of the Halton sequence", MAX_STORED_COUNT)
    top = float(np.sqrt(1.0 + float(scene.ell) ** 2 * float(scene.mass) / float(scene.inertia)))
    chosen_theta, chosen_p = [], []
    start = offset
    while len(chosen_theta) < count:
        index = np.arange(start, start + 4 * count + 16)
        start = int(index[-1]) + 1
        theta = halton(index, 2) * np.pi
        p = (2.0 * halton(index, 3) - 1.0) * top
        bound = np.asarray(floor_section_bound(scene, theta, energy, spin))
        keep = np.isfinite(bound) & (np.abs(p) < bound) & (np.abs(theta - 0.5 * np.pi) > 1e-9)
        chosen_theta.extend(theta[keep].tolist())
        chosen_p.extend(p[keep].tolist())
        if start > 10_000 * (count + 1):
            raise ValueError("no reachable floor-section points at this energy and spin")
    return np.asarray(chosen_theta[:count]), np.asarray(chosen_p[:count])


def floor_seeds(
    scene, count: int, energy: float = 0.5, spin: float = 0.0, *, offset: int = 1
) -> Float[Array, "count S"]:
    """``count`` start states spread evenly over the reachable floor section, at fixed ``E'`` (and spin).

    The points (``floor_seed_points``) are uniform in the area-preserving
    coordinates ``(theta, p)``, so the share of them whose orbits are chaotic
    estimates the chaotic share of the section at this ``E'`` (and, in 3D,
    ``I w_z = spin``). Deterministic. Returns ``(count, 6)`` or ``(count,
    12)`` states from ``floor_state``: each just after a bounce of its lower
    end on the floor, centre at ``x = y = 0``, no horizontal velocity.
    """
    theta, p = floor_seed_points(scene, count, energy, spin, offset=offset)
    return floor_state(scene, theta, p, energy, spin)


@jax.jit
def theta_z_path(
    scene, state: Float[ArrayLike, "*#batch S"], t: Float[ArrayLike, "*#batch"]
) -> Float[Array, "*batch 2"]:
    """Points ``[kappa theta, z]`` of the reduced billiard picture along the free flight from ``state``.

    Args:
        scene: ``StickBetweenWalls3D`` (``theta`` the polar angle of ``u``:
            the flights curve when ``w_z != 0``) or ``StickBetweenWalls2D``
            (``theta`` as it is, not wrapped: straight lines).
        state: one state ``(S,)`` (or a batch broadcast against ``t``).
        t: times after ``state`` (within its flight: no impulse is applied).

    Returns:
        ``(..., 2)`` with the shape of ``t``: ``kappa theta`` and ``z`` in
        length units (``kappa = ell`` for ``I = M ell^2``: the paper's
        ``(ell theta, z)``).
    """
    t = jnp.asarray(t, dtype=jnp.float64)
    state = jnp.asarray(state, dtype=jnp.float64)
    shape = jnp.broadcast_shapes(t.shape, state.shape[:-1])
    t = jnp.broadcast_to(t, shape)
    state = jnp.broadcast_to(state, shape + state.shape[-1:])
    kappa = gyration_radius(scene)
    if _is_3d(scene):
        moved = scene.flight(state, t)
        return jnp.stack([kappa * polar_angle(moved[..., 3:6]), moved[..., 2]], axis=-1)
    theta = state[..., 2] + state[..., 5] * t
    return jnp.stack([kappa * theta, state[..., 1] + state[..., 4] * t], axis=-1)


def flight_paths(scene, state0, orbit, points_per_flight: int = 40) -> np.ndarray:
    """``theta_z_path`` sampled along every flight of one orbit: ``(n, points_per_flight, 2)`` (NumPy).

    Flight ``j`` runs from ``state0`` (``j = 0``) or ``orbit.state[j - 1]`` to
    collision ``j``. In 2D ``theta`` is unwrapped along the orbit.
    """
    states = np.asarray(orbit.state)
    start = np.asarray(state0, dtype=np.float64)
    starts = np.vstack([start[None], states[:-1]])
    dts = np.diff(np.concatenate([[0.0], np.asarray(orbit.t)]))
    if not _is_3d(scene):
        # unwrap: the angle at each start is state0's plus the exact turning omega dt so far
        turned = np.concatenate(
            [[start[2]], start[2] + np.cumsum(np.concatenate([[start[5]], states[:-1, 5]]) * dts)[:-1]]
        )
        starts = starts.copy()
        starts[:, 2] = turned
    frac = np.linspace(0.0, 1.0, points_per_flight)
    times = dts[:, None] * frac[None, :]
    return np.asarray(theta_z_path(scene, starts[:, None, :], times))


# -- regular or chaotic: twins ---------------------------------------------------


def wall_twin_states(scene, states0, delta: float = 1e-11) -> np.ndarray:
    """Twins for ``wall_twin_divergence``: the velocity ``(theta_dot, eta_dot)`` turned by ``delta`` rad.

    Same ``E'``, same horizontal motion, and in 3D the same ``I w_z`` (only
    the polar rate and ``vz`` change).
    """
    states0 = np.atleast_2d(np.asarray(states0, dtype=np.float64))
    kappa = float(np.asarray(gyration_radius(scene)))
    c, s = np.cos(delta), np.sin(delta)
    twins = states0.copy()
    if _is_3d(scene):
        u, w = states0[:, 3:6], states0[:, 9:12]
        sin = np.hypot(u[:, 0], u[:, 1])
        safe = np.where(sin > 0, sin, 1.0)
        e_phi = np.stack([-u[:, 1], u[:, 0], np.zeros_like(sin)], axis=1) / safe[:, None]
        # exactly vertical: the polar angle grows at the rate |w| (theta_dot = w . e with e = w / |w|)
        along_w = w / np.maximum(np.linalg.norm(w, axis=1), 1e-300)[:, None]
        e_phi = np.where((sin > 0)[:, None], e_phi, along_w)
        rate = np.sum(w * e_phi, axis=1)
        eta_dot = states0[:, 8] / kappa
        new_rate, new_eta = c * rate - s * eta_dot, s * rate + c * eta_dot
        twins[:, 9:12] = w + (new_rate - rate)[:, None] * e_phi
        twins[:, 8] = kappa * new_eta
    else:
        rate, eta_dot = states0[:, 5], states0[:, 4] / kappa
        twins[:, 5] = c * rate - s * eta_dot
        twins[:, 4] = kappa * (s * rate + c * eta_dot)
    return twins


def wall_twin_distances(scene, states, twin_states, states0) -> np.ndarray:
    """Distance between orbits and their twins at every collision, ``(B, n)``.

    ``|(z/h, stick direction, vz/(kappa|V|), omega/|V|)_twin - (...)|`` with
    ``|V| = sqrt(2 E'/I)`` of each start, the stick direction as ``theta``
    (2D, the difference wrapped into ``[-pi, pi)``) or ``u`` (3D, ``w`` for
    ``omega``). Collisions are compared by index: once the twins part, the
    distance is of order one whatever collision it compares.
    """
    first, second = np.asarray(states), np.asarray(twin_states)
    states0 = np.atleast_2d(np.asarray(states0, dtype=np.float64))
    h = float(np.max(np.asarray(scene.h)))
    kappa = float(np.asarray(gyration_radius(scene)))
    speed = np.sqrt(2.0 * internal_energy_np(scene, states0) / float(np.asarray(scene.inertia)))[:, None]
    if _is_3d(scene):
        parts = [
            (first[..., 2] - second[..., 2]) / h,
            *(first[..., k] - second[..., k] for k in (3, 4, 5)),
            (first[..., 8] - second[..., 8]) / (kappa * speed),
            *((first[..., k] - second[..., k]) / speed for k in (9, 10, 11)),
        ]
    else:
        turn = np.remainder(first[..., 2] - second[..., 2] + np.pi, 2.0 * np.pi) - np.pi
        parts = [
            (first[..., 1] - second[..., 1]) / h,
            turn,
            (first[..., 4] - second[..., 4]) / (kappa * speed),
            (first[..., 5] - second[..., 5]) / speed,
        ]
    return np.nan_to_num(np.sqrt(sum(part**2 for part in parts)), nan=np.inf)


def wall_divergence(scene, states, twin_states, states0) -> np.ndarray:
    """Largest ``wall_twin_distances`` over the last tenth of the collisions, ``(B,)``."""
    difference = wall_twin_distances(scene, states, twin_states, states0)
    n = difference.shape[-1]
    return np.max(difference[:, -max(1, n // 10) :], axis=1)


def separation_collisions(distances, level: float = 1e-4) -> np.ndarray:
    """Collisions until each twin pair is first ``level`` apart, ``(B,)`` floats (inf: never).

    With twins ``delta`` apart at the start, ``log(level / delta) / k``
    estimates the largest Lyapunov exponent per collision of a chaotic orbit.
    """
    distances = np.asarray(distances)
    apart = distances > level
    first = np.argmax(apart, axis=1).astype(np.float64) + 1.0
    return np.where(np.any(apart, axis=1), first, np.inf)


def orbits_with_twins(scene, states0, n: int, delta: float = 1e-11):
    """Run orbits and their twins in one batch: ``(orbit of the originals, divergence per orbit)``."""
    states0 = np.atleast_2d(np.asarray(states0, dtype=np.float64))
    orb, distances = orbits_with_twin_distances(scene, states0, n, delta)
    n = distances.shape[-1]
    return orb, np.max(distances[:, -max(1, n // 10) :], axis=1)


def orbits_with_twin_distances(scene, states0, n: int, delta: float = 1e-11):
    """Run sticks between walls beside their twins, in one batch: ``(orbits, distances)``.

    Each twin's velocity ``(theta_dot, eta_dot)`` is turned by ``delta`` radians
    (same energy, same horizontal motion). ``distances`` ``(B, n)``: orbit to twin
    at every collision, in ``(z/h, stick direction, vz/(kappa |V|), omega/|V|)``
    with ``|V| = sqrt(2 E'/I)``; their largest over the last tenth is
    ``wall_twin_divergence``, and ``separation_collisions`` reads when they part.
    """
    states0 = np.atleast_2d(np.asarray(states0, dtype=np.float64))
    both = _orbit(scene, np.concatenate([states0, wall_twin_states(scene, states0, delta)]), n)
    both = jax.device_get(both)  # an Orbit of numpy arrays
    count = len(states0)
    orb = jax.tree_util.tree_map(lambda a: a[:count], both)
    return orb, wall_twin_distances(scene, both.state[:count], both.state[count:], states0)


def wall_twin_divergence(
    scene, states0: Float[ArrayLike, "B S"] | Float[ArrayLike, " S"], n: int, delta: float = 1e-11
) -> Float[np.ndarray, " B"]:
    """How far each orbit and its twin (``wall_twin_states``) are apart after ``n`` collisions, ``(B,)``.

    ``~delta n`` (times the flight lengths) on a torus, order one for a
    chaotic orbit; ``> 1e-3`` (``_section_measures.CHAOTIC_DIVERGENCE``)
    counts as chaotic, as for the stick in a circle.
    """
    return orbits_with_twins(scene, states0, n, delta)[1]
