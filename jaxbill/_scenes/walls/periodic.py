r"""Periodic orbits of the sticks between walls (``find_periodic_orbit`` for ``StickBetweenWalls2D/3D``).

What "periodic" means here
--------------------------
The horizontal motion of the centre is free and decoupled (``x``, and in 3D
``y``, drift at the constant ``vx``, ``vy``), so an orbit is periodic when the
*dynamical* coordinates return: ``(z, theta, vz, omega)`` in 2D; ``(z, u, vz,
w)`` in 3D, there up to a rotation ``psi`` of the stick about the vertical
(the walls are invariant under rotations about ``z``, which act on ``u`` and
``w`` alone and commute with the collision map): a *relative periodic orbit*,
as for the stick in a circle. After ``p`` collisions the state is the first one
shifted horizontally by ``(vx, vy) * period`` and, in 3D, with ``u`` and ``w``
turned by ``psi`` about the vertical. The two ends are not exchanged
(``theta -> theta + pi`` is not divided out).

Section coordinates
-------------------
The section is "just after a collision", with the contact (which end, which
wall) of the guess's first collision, found by carrying the guess to it. On it
the height follows from the orientation (``z = wall - e ell cos theta`` in 2D,
``z = wall - e ell u_z`` in 3D, ``e = +1`` for P1, ``-1`` for P2), and the
horizontal ``(x, y, vx, vy)`` are held at the guess's values. Unknowns:

* 2D: ``xi = (theta, vz, omega)`` (``(vz,)`` for a stick that never turns);
* 3D: ``xi = (a1, a2, vz, b1, b2)`` in a chart around the guess's section
  point ``(u_b, w_b)``: ``u = (u_b + a1 t1 + a2 t2) / |.|`` and ``w`` the
  projection of ``b1 t1 + b2 t2`` perpendicular to ``u``, with ``(t1, t2)`` an
  orthonormal basis perpendicular to ``u_b`` (so the chart is smooth at a
  vertical stick, where polar angles are not), plus the rotation ``psi``
  (``(vz,)`` for a stick that never turns).

Residuals (each scaled to order 1): the dynamical coordinates after ``p``
collisions, turned back by ``-psi`` in 3D, minus those at the start (``theta``
wrapped); the energy ``E - E0`` (the map commutes with a rescaling of all
velocities, so the energy must be pinned); in 3D the angular momentum ``L_z -
L0`` when pinned, and ``psi - psi0`` when the rotation is prescribed. Solved by
optimistix's Levenberg-Marquardt, differentiable in the scene's leaves by the
implicit function theorem (as in ``jaxbill._analysis.periodic_orbit``).

Stability
---------
``monodromy`` is the Jacobian of the ``p``-map (turned back by ``-psi``) in the
section coordinates ``xi`` at the fixed point. On the tangent space of the
energy level set (the null space of ``grad E``) it is symplectic:

* 2D: a ``2 x 2`` matrix with multipliers ``mu, 1/mu``;
* 3D: ``4 x 4``, with two trivial multipliers 1 (the rotation about the
  vertical and the conserved ``L_z``) and the nontrivial pair ``mu, 1/mu``,
  reported as ``mu`` = the eigenvalue farthest from 1 and its inverse. (For an
  orbit that the rotation leaves fixed, the vertical bounce, the trivial pair
  is replaced by a second copy of ``mu, 1/mu``: the 2D pair in the ``x``-``z``
  and in the ``y``-``z`` plane.)

A stick that never turns has a 0-dimensional level set: multipliers ``(1,
1)``, parabolic. Labels from ``tr = mu + 1/mu`` as in ``jaxbill._analysis.periodic_orbit``.
"""

from __future__ import annotations

from typing import TYPE_CHECKING, TypeGuard

import equinox as eqx
import jax
import jax.numpy as jnp

from jaxbill._engine.collision import collide_unchecked
from jaxbill._scenes.walls import engine as walls

if TYPE_CHECKING:  # the scenes import the engine this module is part of
    from jaxbill._scenes.walls.scene_2d import StickBetweenWalls2D
    from jaxbill._scenes.walls.scene_3d import StickBetweenWalls3D

_TWO_PI = 2.0 * jnp.pi

# A solution with a flight shorter than this (in units of h / speed) slides
# along a wall (the grazing limit) and is not reported as converged.
_MIN_FLIGHT = 1e-6


def wrap_angle(angle):
    """Into ``[-pi, pi)`` (also used by the periodic-orbit solvers of ``jaxbill._analysis``)."""
    return jnp.remainder(angle + jnp.pi, _TWO_PI) - jnp.pi


def _turn_about_z(vec, angle):
    c, s = jnp.cos(angle), jnp.sin(angle)
    return jnp.stack([c * vec[0] - s * vec[1], s * vec[0] + c * vec[1], vec[2]])


def is_3d(scene: StickBetweenWalls2D | StickBetweenWalls3D) -> TypeGuard[StickBetweenWalls3D]:
    return scene.state_size == 12


def section_size(scene) -> int:
    """Number of section coordinates ``xi`` (without the 3D rotation ``psi``)."""
    if scene.kind == "static":
        return 1
    return 5 if is_3d(scene) else 3


def gap_of_contact(contact):
    """Gap index 0..3 of a single contact code (+1, -1, +3, -3); 0 for others (flagged elsewhere)."""
    return jnp.where(
        contact == walls.FLOOR, 0, jnp.where(contact == -walls.FLOOR, 1, jnp.where(contact == walls.CEILING, 2, 3))
    ).astype(jnp.int32)


def _dynamical_coordinates(scene, state):
    """``(z, theta, vz, omega)`` (2D) or ``(z, u, vz, w)`` (3D)."""
    if is_3d(scene):
        return jnp.concatenate([state[2:6], state[8:12]])
    return state[jnp.asarray([1, 2, 4, 5])]


def section_points(scene, states):
    """Rotation-invariant description of section states ``(..., S)``.

    2D: ``(theta, z, vz, omega)``; 3D: ``(u_z, z, vz, (w x u)_z, w_z)``, the
    vertical component of the stick's direction and of its rate of change.
    """
    if is_3d(scene):
        u, w = states[..., 3:6], states[..., 9:12]
        rate = w[..., 0] * u[..., 1] - w[..., 1] * u[..., 0]
        return jnp.stack([u[..., 2], states[..., 2], states[..., 8], rate, w[..., 2]], axis=-1)
    return jnp.stack([states[..., 2], states[..., 1], states[..., 4], states[..., 5]], axis=-1)


class WallsProblem(eqx.Module):
    """Residual of the periodic-orbit equations in scaled unknowns ``zeta``."""

    scene: StickBetweenWalls2D | StickBetweenWalls3D
    base: jax.Array  # (S,) the guess's first section point
    gap: jax.Array  # () int32, the gap touched at the section
    tangent: jax.Array  # (3, 2) orthonormal basis perpendicular to the base's u (3D); unused in 2D
    energy: jax.Array
    angular_momentum: jax.Array
    rotation: jax.Array
    pin_l: jax.Array  # () bool: pin L_z (3D, turning stick)
    pin_rotation: jax.Array  # () bool: pin psi (3D, turning stick)
    p: int = eqx.field(static=True)

    @property
    def has_rotation(self) -> bool:
        return is_3d(self.scene) and self.scene.kind == "rotor"

    def vertical_energy(self):
        """The energy less the horizontal motion's (held at the base's ``vx, vy``)."""
        v = self.base[6:8] if is_3d(self.scene) else self.base[3:4]
        return self.energy - 0.5 * self.scene.mass * jnp.sum(v * v)

    def scales(self):
        scene = self.scene
        e = self.vertical_energy()
        speed = jnp.sqrt(2.0 * e / scene.mass)
        one = jnp.ones(())
        if scene.kind == "static":
            return speed[None]
        spin = jnp.sqrt(2.0 * e / scene.inertia)
        if is_3d(scene):
            return jnp.stack([one, one, speed, spin, spin, one])
        return jnp.stack([one, speed, spin])

    def z(self, zeta):
        return zeta * self.scales()

    def zeta(self, xi):
        return xi / self.scales()

    def section_state(self, xi):
        """The state on the section from the section coordinates ``xi`` (``psi`` ignored)."""
        scene, base = self.scene, self.base
        end = jnp.asarray(walls.END_SIGNS)[self.gap]
        wall = jnp.where(self.gap >= 2, scene.h, 0.0)
        if is_3d(scene):
            if scene.kind == "static":
                u, vz, w = base[3:6], xi[0], base[9:12]
            else:
                raw = base[3:6] + self.tangent @ xi[0:2]
                u = raw / jnp.linalg.norm(raw)
                w = self.tangent @ xi[3:5]
                w = w - (w @ u) * u
                vz = xi[2]
            z = wall - end * scene.ell * u[2]
            return jnp.concatenate([base[0:2], z[None], u, base[6:8], vz[None], w])
        if scene.kind == "static":
            theta, vz, omega = base[2], xi[0], jnp.zeros(())
        else:
            theta, vz, omega = wrap_angle(xi[0]), xi[1], xi[2]
        z = wall - end * scene.ell * jnp.cos(theta)
        return jnp.stack([base[0], z, theta, base[3], vz, omega])

    def start(self):
        """Section coordinates (with ``psi``) of the base point."""
        base = self.base
        if self.scene.kind == "static":
            return base[8:9] if is_3d(self.scene) else base[4:5]
        if is_3d(self.scene):
            b = self.tangent.T @ base[9:12]
            return jnp.concatenate([jnp.zeros(2), base[8:9], b, jnp.zeros(1)])
        return base[jnp.asarray([2, 4, 5])]

    def turned_back(self, state, psi):
        """``state`` with ``u`` and ``w`` turned by ``-psi`` about the vertical."""
        if not self.has_rotation:
            return state
        u, w = _turn_about_z(state[3:6], -psi), _turn_about_z(state[9:12], -psi)
        return jnp.concatenate([state[0:3], u, state[6:9], w])

    def iterate(self, xi):
        """``(s0, states, contacts, flights)`` of ``p`` collisions from the section point ``xi``."""

        def step(state, _):
            new_state, dt, contact = collide_unchecked(self.scene, state)
            return new_state, (new_state, contact, dt)

        s0 = self.section_state(xi)
        _, (states, contacts, flights) = jax.lax.scan(step, s0, None, length=self.p)
        return s0, states, contacts, flights

    def __call__(self, zeta, _=None):
        xi = self.z(zeta)
        s0, states, _, _ = self.iterate(xi)
        return self.residual_from(xi, s0, states[-1])

    def residual_from(self, xi, s0, s_p):
        scene = self.scene
        scales = self.scales()
        psi = xi[-1] if self.has_rotation else jnp.zeros(())
        d0 = _dynamical_coordinates(scene, s0)
        dp = _dynamical_coordinates(scene, self.turned_back(s_p, psi))
        diff = dp - d0
        if is_3d(scene):
            speed, spin = jnp.sqrt(2.0 * self.vertical_energy() / scene.mass), scales[-3]
            unit = jnp.concatenate([scene.h[None], jnp.ones(3), speed[None], jnp.full(3, spin)])
            if scene.kind == "static":
                unit = unit.at[4:].set(1.0)
        else:
            speed = jnp.sqrt(2.0 * self.vertical_energy() / scene.mass)
            spin = scales[-1] if scene.kind == "rotor" else jnp.ones(())
            unit = jnp.stack([scene.h, jnp.ones(()), speed, spin])
            diff = diff.at[1].set(wrap_angle(diff[1]))
        parts = [diff / unit, ((scene.energy(s0) - self.energy) / self.vertical_energy())[None]]
        if is_3d(scene) and self.has_rotation:
            # The pins are traced flags (one compilation for every choice): an
            # unpinned equation is a zero row, which least squares ignores.
            momentum = scene.inertia * scales[-3]
            l_residual = (scene.angular_momentum(s0) - self.angular_momentum) / momentum
            parts.append(jnp.where(self.pin_l, l_residual, 0.0)[None])
            parts.append(jnp.where(self.pin_rotation, wrap_angle(psi - self.rotation), 0.0)[None])
        return jnp.concatenate(parts)


def make_problem(scene, guess, p, energy, angular_momentum, rotation, pin_l, pin_rotation):
    """The problem around the guess's first collision, and that collision's contact code."""
    start, _, contact = collide_unchecked(scene, guess)
    start = jax.lax.stop_gradient(start)
    gap = gap_of_contact(contact)
    if is_3d(scene):
        _, _, vt = jnp.linalg.svd(start[3:6][None, :], full_matrices=True)
        tangent = jax.lax.stop_gradient(vt[1:].T)
    else:
        tangent = jnp.zeros((3, 2))
    problem = WallsProblem(
        scene, start, gap, tangent, energy, angular_momentum, rotation, jnp.asarray(pin_l), jnp.asarray(pin_rotation), p
    )
    return problem, contact


def initial_rotation(problem: WallsProblem):
    """A first estimate of ``psi``: the turn about the vertical that best carries the start onto the ``p``-th point."""
    xi = problem.start()
    s0, states, _, _ = problem.iterate(xi)
    s_p = states[-1]
    spin = problem.scales()[-3]
    pairs = [(s0[3:5], s_p[3:5]), (s0[9:11] / spin, s_p[9:11] / spin)]
    cross = sum(a[0] * b[1] - a[1] * b[0] for a, b in pairs)
    dot = sum(a @ b for a, b in pairs)
    return jnp.where(problem.pin_rotation, problem.rotation, jnp.arctan2(cross, dot))


def monodromy(problem: WallsProblem, xi):
    """``(M, multipliers, trace)``: the Jacobian of the ``p``-map in ``xi`` and its nontrivial pair."""
    scene = problem.scene
    k = section_size(scene)
    psi = xi[-1] if problem.has_rotation else jnp.zeros(())
    point = xi[:k]

    def full(x):
        return jnp.concatenate([x, xi[k:]])

    def after(x):
        _, states, _, _ = problem.iterate(full(x))
        return _dynamical_coordinates(scene, problem.turned_back(states[-1], psi))

    def before(x):
        return _dynamical_coordinates(scene, problem.section_state(full(x)))

    a = jax.jacfwd(after)(point)
    c = jax.jacfwd(before)(point)
    m = jnp.linalg.pinv(c) @ a  # the p-map's images lie on the section: A = C M
    if k == 1:
        one = jnp.ones((), jnp.complex128)
        return m, jnp.stack([one, one]), jnp.asarray(2.0)
    grad = jax.grad(lambda x: scene.energy(problem.section_state(full(x))))(point)
    _, _, vt = jnp.linalg.svd(grad[None, :], full_matrices=True)
    basis = vt[1:].T  # (k, k - 1), orthonormal: the energy level set's tangent space
    reduced = basis.T @ m @ basis
    eig = jnp.linalg.eigvals(reduced)
    if reduced.shape[0] == 2:
        return m, eig, jnp.trace(reduced)
    mu = eig[jnp.argmax(jnp.abs(eig - 1.0))]
    multipliers = jnp.stack([mu, 1.0 / mu])
    return m, multipliers, jnp.real(mu + 1.0 / mu)


def flights_too_short(problem: WallsProblem, flights):
    speed = jnp.sqrt(2.0 * problem.vertical_energy() / problem.scene.mass)
    return jnp.min(flights) <= _MIN_FLIGHT * problem.scene.h / speed
