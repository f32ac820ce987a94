"""Periodic and relative periodic orbits of the collision map, by Levenberg-Marquardt.

Reduced section coordinates
---------------------------
Just after a collision one end touches the wall, so a state on the section
(states just after a collision) is fixed by the polar angle ``phi`` of the
contact point and, in the frame rotated by ``-phi``:

* ``beta = phi - alpha_k``: the angle between the stick, pointing from the
  centre to the touching end (``alpha_k = alpha`` for P1, ``alpha + pi`` for
  P2: the two ends are identical point masses, so the label of the touching end
  is not a coordinate), and the radius to the contact point; ``|beta| <=
  arccos(ell / R)`` (the same ``beta`` as in ``jaxbill.reduced_section``);
* ``w = (w_r, w_t)``: the centre's velocity in the rotated frame (radial and
  tangential components at the contact point);
* ``omega``: the spin.

The whole system is symmetric under rotations about the origin (the rotation
acts on the centre, on ``alpha`` and on the velocity), so the collision map
commutes with rotations and the reduced map ``z -> z'`` on
``z = (beta, w_r, w_t, omega)`` does not depend on ``phi``. A fixed point of the
``p``-th iterate of the reduced map is a *relative periodic orbit*: after ``p``
collisions the state is the first one rotated by ``theta = phi_p - phi_0``
(and possibly with the ends exchanged). ``theta = 0`` (mod 2 pi) is a periodic
orbit proper. The reduced coordinates are ``(beta, w_r, w_t, omega)`` for a
spinning stick, ``(beta, w_r, w_t)`` for the static lens (``omega = 0``) and
``(w_r, w_t)`` for the circle billiard (``ell = 0``: no ``beta``).

For the static lens the stick angle ``alpha`` is a constant, so
``theta = alpha_p - alpha_0`` is forced to be 0 or ``pi``; ``pi`` is the lens's
own point symmetry ``c -> -c``.

Equations solved
----------------
Unknowns: the reduced coordinates of the first section point (velocities in
units of ``sqrt(2E/M)``, the spin in units of ``sqrt(2E/I)``). Residuals:
``z_p - z_0`` (``beta`` wrapped), the energy ``E - E0`` (the reduced map
commutes with a rescaling of all velocities, so the energy must be pinned),
for a spinning stick the angular momentum ``L - L0`` (it labels a one-parameter
family), and, when the rotation is prescribed, ``theta - theta0`` (wrapped).
The system is solved in the least-squares sense by optimistix's
Levenberg-Marquardt with autodiff Jacobians; at a solution the residual is zero
to rounding.

Stability
---------
The monodromy matrix is the Jacobian of the reduced ``p``-map at the fixed
point. It maps the level set ``{E = E0, L = L0}`` to itself; restricted to its
tangent space (2-dimensional for the spinning stick and the lens) it is a
symplectic ``2 x 2`` matrix with multipliers ``mu, 1/mu``. The trivial
multipliers, all equal to 1, have been removed: the flow direction (not in
the section), the rotation angle (quotiented out by the reduced coordinates),
the energy and the angular momentum (pinned). For the circle billiard
(``ell = 0``) the level set is a point, the incidence angle is invariant and the
orbit's neighbours shear: the multipliers are reported as ``(1, 1)``, parabolic.

Labels, from the trace ``tr = mu + 1/mu``: elliptic (``|tr| < 2``: linearly
stable), parabolic (``|tr| = 2`` to ``parabolic_tol``), hyperbolic
(``tr > 2``) and inverse hyperbolic (``tr < -2``: hyperbolic with reflection).

Sticks between walls
--------------------
``find_periodic_orbit`` and ``find_periodic_orbits`` also take
``StickBetweenWalls2D`` and ``StickBetweenWalls3D``: there an orbit is periodic
in the dynamical coordinates (the horizontal motion drifts freely; in 3D up to
a rotation of the stick about the vertical). Their section coordinates,
residuals and multipliers are described in ``jaxbill._scenes.walls.periodic``.

Scenes with no symmetry
-----------------------
Which of these solvers runs is the scene's answer to ``periodic_symmetry``
(``jaxbill._scenes.protocols.HasPeriodicSymmetry``), never its type: ``"rotation"``
(the reduced coordinates above), ``"translation"`` (the walls) or ``"none"``
(``StickInEllipse``). With nothing to divide out, the unknowns are the
dynamical components of the state just after the first collision, and the
residuals ``map^p(s) - s`` (angles wrapped), ``E - E0`` and the gap of the end
that touches at ``s`` (it stays on the section); see ``_PlainProblem``. Its
multipliers are those of ``map^p`` on the tangent space of ``{E = E0, g_k =
0}``: 2 for a point or a stick that never turns, 4 for a turning stick (the
ellipse conserves no angular momentum).

Derivatives
-----------
The solve is made differentiable with respect to the scene's leaves (and the
target energy and angular momentum) by the implicit function theorem: the
solution ``zeta*`` is refined by one Gauss-Newton step
``zeta* - J^+ F(zeta*; scene)`` with the Jacobian ``J`` held constant, whose
derivative is ``-J^+ dF/dscene``, never a derivative of the iterations.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from typing import Any, cast

import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np
import optimistix as optx
from jaxtyping import Array, ArrayLike, Bool, Complex, Float, Int

from jaxbill._engine.collision import check_eagerly, collide_unchecked
from jaxbill._engine.validation import MAX_STORED_COUNT, check_count, require_x64
from jaxbill._scenes.circle.scene import StickInCircle  # the rotation solver is its (periodic_symmetry "rotation")
from jaxbill._scenes.protocols import (
    NO_CONTACT,
    PERIODIC_SYMMETRIES,
    SEVERAL_CONTACTS,
    HasAngularMomentum,
    Scene,
    has_angular_momentum,
)
from jaxbill._scenes.walls import periodic as walls_orbits
from jaxbill._scenes.walls.periodic import wrap_angle as _wrap

ELLIPTIC, PARABOLIC, HYPERBOLIC, INVERSE_HYPERBOLIC = 0, 1, 2, 3
STABILITY_LABELS = ("elliptic", "parabolic", "hyperbolic", "inverse hyperbolic")

_TWO_PI = 2.0 * math.pi

# A solution with a flight shorter than this (in units of R / speed) slides
# along the wall (a grazing limit) and is not reported as converged.
_MIN_FLIGHT = 1e-6


def _rotate(vec, angle):
    c, s = jnp.cos(angle), jnp.sin(angle)
    return jnp.stack([c * vec[0] - s * vec[1], s * vec[0] + c * vec[1]])


def reduced_size(scene: StickInCircle) -> int:
    """Number of reduced section coordinates: 4 (a turning stick), 3 (one that never turns), 2 (a point)."""
    return 2 + int(not scene.body_is_point) + int(scene.body_turns)


def _full_z(scene, z):
    """``(beta, w_r, w_t, omega)`` from the reduced coordinates of any body."""
    if scene.body_turns:
        return z
    if not scene.body_is_point:
        return jnp.concatenate([z, jnp.zeros((1,), z.dtype)])
    return jnp.concatenate([jnp.zeros((1,), z.dtype), z, jnp.zeros((1,), z.dtype)])


def _short_z(scene, z4):
    if scene.body_turns:
        return z4
    return z4[1:3] if scene.body_is_point else z4[:3]


def reduced_state(scene: StickInCircle, z: jax.Array, phi: ArrayLike = 0.0) -> jax.Array:
    """The state just after a collision of end P1 at polar angle ``phi``, from reduced coordinates ``z``."""
    beta, w_r, w_t, omega = _full_z(scene, jnp.asarray(z, jnp.float64))
    alpha = phi - beta
    normal = jnp.stack([jnp.cos(phi), jnp.sin(phi)])
    axis = jnp.stack([jnp.cos(alpha), jnp.sin(alpha)])
    centre = scene.R * normal - scene.ell * axis
    v = _rotate(jnp.stack([w_r, w_t]), phi)
    return jnp.stack([centre[0], centre[1], _wrap(alpha), v[0], v[1], omega])


def reduced_coordinates(scene: StickInCircle, state: jax.Array, contact: jax.Array):
    """Reduced coordinates ``z`` and contact angle ``phi`` of a state just after a collision.

    ``contact`` is the code returned by ``collide`` (+1 or -1; for a corner, 2,
    the end nearer the wall is taken).
    """
    gaps = scene.gaps(state)
    end = jnp.where(contact == 2, jnp.where(gaps[0] <= gaps[1], 1.0, -1.0), jnp.sign(contact))
    alpha = state[2]
    axis = jnp.stack([jnp.cos(alpha), jnp.sin(alpha)])
    p = state[0:2] + end * scene.ell * axis
    phi = jnp.arctan2(p[1], p[0])
    beta = _wrap(phi - alpha - jnp.where(end < 0, jnp.pi, 0.0))
    w = _rotate(state[3:5], -phi)
    z4 = jnp.stack([beta, w[0], w[1], state[5]])
    return _short_z(scene, z4), phi


def _iterate(scene, z, p):
    """``p`` collisions from the section point ``z`` (at ``phi = 0``)."""

    def step(carry, _):
        state, t = carry
        new_state, dt, contact = collide_unchecked(scene, state)
        return (new_state, t + dt), (new_state, contact, dt)

    s0 = reduced_state(scene, z, 0.0)
    (_, period), (states, contacts, flights) = jax.lax.scan(step, (s0, jnp.zeros(())), None, length=p)
    z_p, phi_p = reduced_coordinates(scene, states[-1], contacts[-1])
    return z_p, phi_p, period, s0, states, contacts, flights


class _Problem(eqx.Module):
    """Residual of the periodic-orbit equations in scaled unknowns ``zeta``."""

    scene: Any
    energy: jax.Array
    angular_momentum: jax.Array
    rotation: jax.Array
    p: int = eqx.field(static=True)
    pin_l: bool = eqx.field(static=True)
    pin_rotation: bool = eqx.field(static=True)

    def scales(self):
        speed = jnp.sqrt(2.0 * self.energy / self.scene.mass)
        if self.scene.body_turns:
            spin = jnp.sqrt(2.0 * self.energy / self.scene.inertia)
            return jnp.stack([jnp.ones(()), speed, speed, spin])
        if not self.scene.body_is_point:
            return jnp.stack([jnp.ones(()), speed, speed])
        return jnp.stack([speed, speed])

    def momentum_scale(self):
        scene = self.scene
        inertia = scene.inertia if scene.body_turns else 0.0
        return jnp.sqrt(2.0 * self.energy * (scene.mass * scene.R**2 + inertia))

    def z(self, zeta):
        return zeta * self.scales()

    def zeta(self, z):
        return z / self.scales()

    def __call__(self, zeta, _=None):
        z = self.z(zeta)
        z_p, phi_p, _, s0, _, _, _ = _iterate(self.scene, z, self.p)
        return self.residual_from(z, z_p, phi_p, s0)

    def residual_from(self, z, z_p, phi_p, s0):
        scene = self.scene
        diff = (z_p - z) / self.scales()
        if not scene.body_is_point:
            diff = diff.at[0].set(_wrap(z_p[0] - z[0]))
        parts = [diff, ((scene.energy(s0) - self.energy) / self.energy)[None]]
        if self.pin_l:
            parts.append(((scene.angular_momentum(s0) - self.angular_momentum) / self.momentum_scale())[None])
        if self.pin_rotation:
            parts.append(_wrap(phi_p - self.rotation)[None])
        return jnp.concatenate(parts)


class PeriodicOrbit(eqx.Module):
    """A (relative) periodic orbit of the collision map.

    For a batch every field has a leading batch axis.

    Attributes (``S = scene.state_size``):
        state: ``(S,)`` the state just after the orbit's first collision.
        states: ``(p, S)`` the states just after each of its ``p`` collisions;
            ``states[-1]`` is ``state`` rotated by ``rotation`` about the origin
            (with the ends possibly exchanged, ``alpha -> alpha + pi``).
            Between walls: shifted horizontally by ``(vx, vy) * period`` and,
            in 3D, with ``u`` and ``w`` turned by ``rotation`` about the vertical.
        contacts: ``(p,)`` contact codes of those collisions.
        points: ``(p, K)`` the reduced section coordinates of the ``p`` section
            points (``points[0]`` is the fixed point solved for; see the module
            docstring for the coordinates). Between walls: ``(theta, z, vz,
            omega)`` in 2D, ``(u_z, z, vz, (w x u)_z, w_z)`` in 3D.
        period: ``()`` the orbit's period in time (sum of the ``p`` flight times).
        rotation: ``()`` the rotation ``theta`` in ``[-pi, pi)`` after ``p``
            collisions (0 for a periodic orbit proper; always 0 in 2D).
        residual: ``()`` max-norm of the scaled residual (0 to rounding at a solution).
        multipliers: ``(2,)`` complex, the nontrivial monodromy multipliers
            ``mu, 1/mu`` (trivial ones removed: see the module docstring).
        trace: ``()`` ``mu + 1/mu``.
        stability: ``()`` int, index into ``STABILITY_LABELS``.
        converged: ``()`` bool: ``residual <= tol`` and no flight shorter than
            ``1e-6 R / speed`` (sliding along the wall, the grazing limit,
            solves the equations trivially and is rejected); between walls
            also ``1e-6 h / speed``, and every contact a single one.
        energy, angular_momentum: ``()`` of the orbit (``angular_momentum``
            is NaN for ``StickBetweenWalls2D``, which conserves none).
        monodromy: ``(K', K')`` the Jacobian of the reduced ``p``-map at the
            fixed point, trivial directions included (the stick in a circle: in
            the reduced coordinates; between walls: in the section coordinates
            of ``jaxbill._scenes.walls.periodic``).
        p: number of collisions in one period (static).
    """

    state: Float[Array, "*B S"]
    states: Float[Array, "*B p S"]
    contacts: Int[Array, "*B p"]
    points: Float[Array, "*B p K"]
    period: Float[Array, "*B"]
    rotation: Float[Array, "*B"]
    residual: Float[Array, "*B"]
    multipliers: Complex[Array, "*B M"]
    trace: Float[Array, "*B"]
    stability: Int[Array, "*B"]
    converged: Bool[Array, "*B"]
    energy: Float[Array, "*B"]
    angular_momentum: Float[Array, "*B"]
    monodromy: Float[Array, "*B k k"]
    p: int = eqx.field(static=True)

    @property
    def label(self) -> str:
        """The stability label (``"elliptic"``, ...) of an unbatched orbit."""
        return STABILITY_LABELS[int(self.stability)]


def _monodromy(scene, z, jac_top, parabolic_tol):
    """Nontrivial multipliers from the Jacobian of the reduced ``p``-map at the fixed point ``z``."""
    if scene.body_is_point:
        one = jnp.ones((), jnp.complex128)
        multipliers = jnp.stack([one, one])
        trace = jnp.asarray(2.0)
    else:
        # Tangent space of the level set {E = E0 (, L = L0)}: null space of the
        # constraint gradients (the map preserves it at a fixed point).
        def invariants(z_):
            s = reduced_state(scene, z_, 0.0)
            out = [scene.energy(s)]
            if scene.body_turns:
                out.append(scene.angular_momentum(s))
            return jnp.stack(out)

        grads = jax.jacfwd(invariants)(z)
        m = grads.shape[0]
        _, _, vt = jnp.linalg.svd(grads, full_matrices=True)
        basis = vt[m:].T  # (k, 2), orthonormal
        reduced = basis.T @ jac_top @ basis
        multipliers = jnp.linalg.eigvals(reduced)
        trace = jnp.trace(reduced)
    return multipliers, trace, _stability(trace, parabolic_tol)


def _stability(trace, parabolic_tol):
    """Index into ``STABILITY_LABELS`` from the trace ``mu + 1/mu``."""
    stability = jnp.where(
        jnp.abs(jnp.abs(trace) - 2.0) <= parabolic_tol,
        PARABOLIC,
        jnp.where(jnp.abs(trace) < 2.0, ELLIPTIC, jnp.where(trace > 0, HYPERBOLIC, INVERSE_HYPERBOLIC)),
    )
    return stability.astype(jnp.int32)


def _solve(problem: _Problem | walls_orbits.WallsProblem | _PlainProblem, zeta0, max_steps):
    """Levenberg-Marquardt with the problem's parameters held constant, differentiable by the IFT.

    Returns the solution (differentiable in the problem's parameters by the
    implicit function theorem) and the residual's Jacobian there.
    """
    frozen = jax.lax.stop_gradient(problem)
    solver = optx.LevenbergMarquardt(rtol=1e-14, atol=1e-14)
    sol = optx.least_squares(frozen, solver, zeta0, max_steps=max_steps, throw=False)
    zeta = jax.lax.stop_gradient(sol.value)
    jac = jax.lax.stop_gradient(jax.jacfwd(frozen)(zeta))
    # Implicit function theorem: a Gauss-Newton step zeta - J^+ F(zeta; parameters)
    # with J held constant has the derivative -J^+ dF/dparameters. Its value is
    # left out (F = 0 at a solution; where the solve failed, the step could only
    # make things worse).
    r = problem(zeta)
    step = jnp.linalg.pinv(jac) @ (r - jax.lax.stop_gradient(r))
    return zeta - step, jac


def _periodic_orbit(
    scene,
    guess,
    p,
    energy,
    angular_momentum,
    rotation,
    pin_l,
    pin_rotation,
    max_steps,
    tol,
    parabolic_tol,
    frame_phi=None,
    zeta0=None,
):
    problem = _Problem(scene, energy, angular_momentum, rotation, p, pin_l, pin_rotation)
    if zeta0 is None:
        start, _, contact = collide_unchecked(scene, guess)
        z0, frame_phi = reduced_coordinates(scene, start, contact)
        zeta0 = jax.lax.stop_gradient(problem.zeta(z0))
    zeta, jac = _solve(problem, zeta0, max_steps)
    z = problem.z(zeta)
    z_p, phi_p, period, s0, states, contacts, flights = _iterate(scene, z, p)
    # Sliding along the wall (grazing, flight times -> 0) solves the equations
    # trivially; it is not an orbit.
    speed = jnp.sqrt(2.0 * energy / scene.mass)
    grazing = jnp.min(flights) <= _MIN_FLIGHT * scene.R / speed
    residual = jnp.max(jnp.abs(jax.lax.stop_gradient(problem.residual_from(z, z_p, phi_p, s0))))
    # Jacobian of the reduced p-map in z: the top block of the residual's
    # Jacobian is S^-1 (Dz_p S - S) in the scaled unknowns (S = diag(scales)).
    k = reduced_size(scene)
    scales = jax.lax.stop_gradient(problem.scales())
    jac_top = scales[:, None] * (jac[:k] + jnp.eye(k)) / scales[None, :]
    multipliers, trace, stability = _monodromy(
        jax.lax.stop_gradient(scene), jax.lax.stop_gradient(z), jac_top, parabolic_tol
    )
    points = jax.vmap(lambda s, c: reduced_coordinates(scene, s, c)[0])(
        jnp.concatenate([s0[None], states[:-1]]), jnp.concatenate([jnp.ones((1,), contacts.dtype), contacts[:-1]])
    )
    # Back into the frame of the guess: rotate by its first contact angle.
    frame_phi = jax.lax.stop_gradient(frame_phi)

    def rot_state(s):
        c = _rotate(s[0:2], frame_phi)
        v = _rotate(s[3:5], frame_phi)
        return jnp.stack([c[0], c[1], _wrap(s[2] + frame_phi), v[0], v[1], s[5]])

    return PeriodicOrbit(
        state=rot_state(s0),
        states=jax.vmap(rot_state)(states),
        contacts=contacts,
        points=points,
        period=period,
        rotation=_wrap(phi_p),
        residual=residual,
        multipliers=multipliers,
        trace=trace,
        stability=stability,
        converged=(residual <= tol) & ~grazing,
        energy=scene.energy(s0),
        angular_momentum=scene.angular_momentum(s0),
        monodromy=jac_top,
        p=p,
    ), frame_phi


def _angular_momentum_or_nan(scene: Scene, state: jax.Array) -> jax.Array:
    """The scene's angular momentum of ``state``, NaN for a scene without one (the 2D walls)."""
    if not has_angular_momentum(scene):
        return jnp.full((), jnp.nan)
    return cast(HasAngularMomentum, scene).angular_momentum(state)


def _walls_periodic_orbit(
    scene, guess, p, energy, angular_momentum, rotation, pin_l, pin_rotation, max_steps, tol, parabolic_tol
):
    """``find_periodic_orbit`` for the sticks between walls (see ``jaxbill._scenes.walls.periodic``)."""
    problem, first_contact = walls_orbits.make_problem(
        scene, guess, p, energy, angular_momentum, rotation, pin_l, pin_rotation
    )
    xi0 = problem.start()
    if problem.has_rotation:
        xi0 = xi0.at[-1].set(walls_orbits.initial_rotation(problem))
    zeta, _ = _solve(problem, jax.lax.stop_gradient(problem.zeta(xi0)), max_steps)
    xi = problem.z(zeta)
    s0, states, contacts, flights = problem.iterate(xi)
    residual = jnp.max(jnp.abs(jax.lax.stop_gradient(problem.residual_from(xi, s0, states[-1]))))
    monodromy, multipliers, trace = walls_orbits.monodromy(jax.lax.stop_gradient(problem), jax.lax.stop_gradient(xi))
    single = jnp.all((contacts != NO_CONTACT) & (contacts != SEVERAL_CONTACTS))
    single &= (first_contact != NO_CONTACT) & (first_contact != SEVERAL_CONTACTS)
    converged = (residual <= tol) & ~walls_orbits.flights_too_short(problem, flights) & single
    points = walls_orbits.section_points(scene, jnp.concatenate([s0[None], states[:-1]]))
    rotation_found = _wrap(xi[-1]) if problem.has_rotation else jnp.zeros(())
    momentum = _angular_momentum_or_nan(scene, s0)
    return PeriodicOrbit(
        state=s0,
        states=states,
        contacts=contacts,
        points=points,
        period=jnp.sum(flights),
        rotation=rotation_found,
        residual=residual,
        multipliers=multipliers,
        trace=trace,
        stability=_stability(trace, parabolic_tol),
        converged=converged,
        energy=scene.energy(s0),
        angular_momentum=momentum,
        monodromy=monodromy,
        p=p,
    ), jnp.zeros(())


# -- scenes with no continuous symmetry (periodic_symmetry == "none") -------------------


class _PlainProblem(eqx.Module):
    """``map^p(s) = s`` in every dynamical coordinate of the state ``s`` just after a collision.

    Unknowns ``zeta``: the dynamical components (``scene.dynamical_indices``)
    of ``s`` relative to the start ``s_1``, in units of the table's length
    ``length_scale`` (the first half of the state, ``q``) and of the speed
    ``sqrt(2 E0 / M)`` (the second half, ``qdot``); the others are held.
    Residuals: ``map^p(s) - s`` on the dynamical components (angles,
    ``scene.periodic_angles``, wrapped), ``E(s)/E0 - 1`` and the gap of the
    end that touched at ``s_1`` in units of ``gap_scale`` (keeps ``s`` on the
    section).
    """

    scene: Any
    start: jax.Array
    energy: jax.Array
    contact_index: jax.Array
    p: int = eqx.field(static=True)

    def scales(self) -> jax.Array:
        half = self.scene.state_size // 2
        length = self.scene.length_scale
        speed = jnp.sqrt(2.0 * self.energy / self.scene.mass)
        full = jnp.concatenate([jnp.full((half,), length), jnp.full((half,), speed)])
        return full[jnp.asarray(self.scene.dynamical_indices)]

    def state(self, zeta) -> jax.Array:
        indices = jnp.asarray(self.scene.dynamical_indices)
        return self.start.at[indices].add(zeta * self.scales())

    def iterate(self, s0):
        def step(s, _):
            after, dt, contact = collide_unchecked(self.scene, s)
            return after, (after, dt, contact)

        _, (states, flights, contacts) = jax.lax.scan(step, s0, None, length=self.p)
        return states, flights, contacts

    def residual_from(self, s0, s_p) -> jax.Array:
        indices = jnp.asarray(self.scene.dynamical_indices)
        difference = s_p - s0
        angles = jnp.asarray(getattr(self.scene, "periodic_angles", ()), dtype=jnp.int32)
        if angles.size:
            difference = difference.at[angles].set(_wrap(difference[angles]))
        gap = jnp.take(self.scene.gaps(s0), self.contact_index) / self.scene.gap_scale
        return jnp.concatenate(
            [
                difference[indices] / self.scales(),
                jnp.stack([self.scene.energy(s0) / self.energy - 1.0, gap]),
            ]
        )

    def __call__(self, zeta, _=None):
        s0 = self.state(zeta)
        states, _, _ = self.iterate(s0)
        return self.residual_from(s0, states[-1])


def _plain_periodic_orbit(
    scene, guess, p, energy, angular_momentum, rotation, pin_l, pin_rotation, max_steps, tol, parabolic_tol
):
    """``find_periodic_orbit`` for a scene with no symmetry to divide out (``periodic_symmetry = "none"``).

    Multipliers: the Jacobian ``J`` of ``map^p`` in the dynamical coordinates
    maps the tangent space ``T`` of ``{E = E0, g_k = 0}`` (the energy shell on
    the section) to itself at the fixed point; ``multipliers`` are the
    eigenvalues of ``J`` restricted to ``T`` (``N^T J N``, ``N`` an orthonormal
    basis of ``T``): 2 for a point or a stick that never turns, 4 for a
    turning stick. ``trace`` is their sum; the label comes from it when there
    are two, else from the largest ``|mu|`` (hyperbolic above ``1 +
    parabolic_tol``, elliptic otherwise).
    """
    del angular_momentum, rotation, pin_l, pin_rotation  # nothing is conserved but E; no rotation
    start, _, first_contact = collide_unchecked(scene, guess)
    # The gap of the contact that touched (the scene's contact code of each gap, ``gap_codes``).
    contact_index = jnp.zeros((), jnp.int32)
    for gap, code in enumerate(scene.gap_codes):
        contact_index = jnp.where(first_contact == code, jnp.int32(gap), contact_index)
    problem = _PlainProblem(scene, start, energy, contact_index, p)
    k = len(scene.dynamical_indices)
    zeta, _ = _solve(problem, jnp.zeros(k), max_steps)
    s0 = problem.state(zeta)
    states, flights, contacts = problem.iterate(s0)
    residual = jnp.max(jnp.abs(jax.lax.stop_gradient(problem.residual_from(s0, states[-1]))))
    indices = jnp.asarray(scene.dynamical_indices)

    def p_map(q):
        after, _, _ = problem.iterate(s0.at[indices].set(q))
        return after[-1][indices]

    frozen_s0 = jax.lax.stop_gradient(s0)
    jac = jax.jacfwd(p_map)(frozen_s0[indices])

    def constraints(q):
        s = frozen_s0.at[indices].set(q)
        return jnp.stack([scene.energy(s), jnp.take(scene.gaps(s), contact_index)])

    grads = jax.jacfwd(constraints)(frozen_s0[indices])
    _, _, vt = jnp.linalg.svd(grads, full_matrices=True)
    basis = vt[2:].T  # (k, k - 2): orthonormal basis of T
    restricted = basis.T @ jac @ basis
    multipliers = jnp.linalg.eigvals(restricted).astype(jnp.complex128)
    trace = jnp.real(jnp.trace(restricted))
    if k - 2 == 2:
        stability = _stability(trace, parabolic_tol)
    else:
        largest = jnp.max(jnp.abs(multipliers))
        stability = jnp.where(largest > 1.0 + parabolic_tol, HYPERBOLIC, ELLIPTIC).astype(jnp.int32)
    speed = jnp.sqrt(2.0 * energy / scene.mass)
    grazing = jnp.min(flights) <= _MIN_FLIGHT * scene.length_scale / speed
    single = jnp.all((contacts != NO_CONTACT) & (contacts != SEVERAL_CONTACTS))
    single &= (first_contact != NO_CONTACT) & (first_contact != SEVERAL_CONTACTS) & (contacts[-1] == first_contact)
    all_states = jnp.concatenate([s0[None], states[:-1]])
    all_contacts = jnp.concatenate([first_contact[None], contacts[:-1]])
    momentum = _angular_momentum_or_nan(scene, s0)
    return PeriodicOrbit(
        state=s0,
        states=states,
        contacts=contacts,
        points=scene.section(all_states, all_contacts),
        period=jnp.sum(flights),
        rotation=jnp.zeros(()),
        residual=residual,
        multipliers=multipliers,
        trace=trace,
        stability=stability,
        converged=(residual <= tol) & ~grazing & single,
        energy=scene.energy(s0),
        angular_momentum=momentum,
        monodromy=jac,
        p=p,
    ), jnp.zeros(())


def _plain_targets(scene, guess, e, angular_momentum, rotation):
    if angular_momentum is not None:
        raise ValueError(
            f"angular_momentum cannot be pinned for {type(scene).__name__}: no angular momentum is conserved"
        )
    if rotation is not None and float(rotation) != 0.0:
        raise ValueError(f"rotation must be None or 0 for {type(scene).__name__}: it has no rotation symmetry")
    return e, jnp.zeros(()), jnp.zeros(()), jnp.asarray(False), jnp.asarray(False)


def _check_period(period) -> int:
    return check_count("period", period, 1, "collisions", MAX_STORED_COUNT)


def _symmetry(scene) -> str:
    """The symmetry ``scene`` says its periodic orbits divide out (``HasPeriodicSymmetry``)."""
    symmetry = getattr(scene, "periodic_symmetry", None)
    if symmetry not in PERIODIC_SYMMETRIES:
        raise TypeError(
            f"scene: {type(scene).__name__} has no periodic_symmetry (one of {PERIODIC_SYMMETRIES}; "
            "the HasPeriodicSymmetry protocol of jaxbill._scenes.protocols): find_periodic_orbit cannot search it"
        )
    return symmetry


def _targets(scene, guess, energy, angular_momentum, rotation):
    e = scene.energy(guess) if energy is None else jnp.asarray(energy, jnp.float64)
    symmetry = _symmetry(scene)
    if symmetry != "rotation":
        return _TARGETS[symmetry](scene, guess, e, angular_momentum, rotation)
    pin_rotation = rotation is not None
    if scene.body_turns:
        pin_l = (angular_momentum is not None) or not pin_rotation
    else:
        if angular_momentum is not None:
            raise ValueError(
                "angular_momentum can be pinned only for a spinning stick: it is not conserved "
                "for the static lens, and fixed by the incidence angle in the circle"
            )
        pin_l = False
    l0 = (
        (scene.angular_momentum(guess) if angular_momentum is None else jnp.asarray(angular_momentum, jnp.float64))
        if pin_l
        else jnp.zeros(())
    )
    theta = jnp.asarray(0.0 if rotation is None else rotation, jnp.float64)
    return e, l0, theta, pin_l, pin_rotation


def _walls_targets(scene, guess, e, angular_momentum, rotation):
    turning_3d = walls_orbits.is_3d(scene) and scene.body_turns
    if turning_3d:
        pin_rotation = rotation is not None
        pin_l = (angular_momentum is not None) or not pin_rotation
    else:
        if angular_momentum is not None:
            raise ValueError(
                "angular_momentum can be pinned only for StickBetweenWalls3D with a turning stick: "
                "the 2D stick conserves no angular momentum"
            )
        if rotation is not None and float(rotation) != 0.0:
            raise ValueError(
                "rotation must be None or 0 here: only StickBetweenWalls3D with a turning stick has "
                "relative periodic orbits (turned about the vertical)"
            )
        pin_rotation = pin_l = False
    l0 = (
        (scene.angular_momentum(guess) if angular_momentum is None else jnp.asarray(angular_momentum, jnp.float64))
        if pin_l
        else jnp.zeros(())
    )
    theta = jnp.asarray(0.0 if rotation is None else rotation, jnp.float64)
    # Traced flags: every choice of pins shares one compilation.
    return e, l0, theta, jnp.asarray(pin_l), jnp.asarray(pin_rotation)


def find_periodic_orbit(
    scene: Scene,
    guess: Float[ArrayLike, " S"],
    period: int,
    *,
    energy: float | None = None,
    angular_momentum: float | None = None,
    rotation: float | None = None,
    tol: float = 1e-11,
    max_steps: int = 100,
    parabolic_tol: float = 1e-8,
) -> PeriodicOrbit:
    """A periodic (or relative periodic) orbit of ``period`` collisions near ``guess``.

    The guess is first carried to its next collision (onto the section);
    then Levenberg-Marquardt (optimistix) with autodiff Jacobians solves
    ``map^period(z) = z`` in reduced section coordinates (rotation divided out:
    see the module docstring). The orbit is returned in the frame of the guess:
    its first section point is the solution rotated to the polar angle of the
    guess's own first contact.

    A scene with no symmetry (``periodic_symmetry = "none"``: ``StickInEllipse``):
    periodic in every dynamical coordinate; ``angular_momentum`` and a
    nonzero ``rotation`` are refused (see the module docstring).

    Sticks between walls (``StickBetweenWalls2D``, ``StickBetweenWalls3D``):
    the same, with the section coordinates of ``jaxbill._scenes.walls.periodic``:
    periodic in the dynamical coordinates, the horizontal motion drifting
    freely at the guess's ``vx`` (``vy``); in 3D up to a rotation of the stick
    about the vertical. The contact of the guess's first collision (which end,
    which wall) is the orbit's first contact.

    Args:
        scene: any scene that answers ``periodic_symmetry`` (``StickInCircle``,
            ``StickInEllipse``, ``StickBetweenWalls2D``,
            ``StickBetweenWalls3D``; leaves may be traced: the result is
            differentiable in them by the implicit function theorem).
        guess: a state, shape ``(S,)`` (``S = scene.state_size``).
        period: number of collisions ``p`` (Python int, static).
        energy: energy of the orbit; default that of ``guess`` (between walls:
            the total energy, with the horizontal velocity held at the guess's).
        angular_momentum: (spinning stick in a circle, or
            ``StickBetweenWalls3D``: ``L_z``) angular momentum of the orbit.
            Default: that of ``guess`` when ``rotation`` is free, and not
            pinned when ``rotation`` is given (``L`` then follows from the
            rotation).
        rotation: ``None`` (default) for a relative periodic orbit, periodic up
            to the rotation it finds; a number ``theta`` to ask for
            ``map^p(state) = Rot(theta) state`` (``0.0``: periodic proper).
            ``StickBetweenWalls2D``: ``None`` or 0 only.
        tol: a solution counts as converged when the scaled residual's max-norm
            is ``<= tol``.
        max_steps: Levenberg-Marquardt step bound.
        parabolic_tol: ``|tr| = 2`` within this is labelled parabolic.

    Returns:
        ``PeriodicOrbit``; check ``converged`` (nothing raises when the solve
        fails). Works under ``jit``/``vmap`` (use ``find_periodic_orbits`` for
        a batch of guesses).
    """
    p = _check_period(period)
    check_eagerly(scene, guess, single=True)
    guess = jnp.asarray(guess, jnp.float64)
    e, l0, theta, pin_l, pin_rotation = _targets(scene, guess, energy, angular_momentum, rotation)
    orbit, _ = _find_jit(scene, guess, p, e, l0, theta, pin_l, pin_rotation, max_steps, tol, parabolic_tol)
    return orbit


@eqx.filter_jit
def _find_jit(scene, guess, p, e, l0, theta, pin_l, pin_rotation, max_steps, tol, parabolic_tol):
    solve = _SOLVERS[_symmetry(scene)]

    def one(g, e_, l_):
        return solve(scene, g, p, e_, l_, theta, pin_l, pin_rotation, max_steps, tol, parabolic_tol)

    if guess.ndim == 1:
        return one(guess, e, l0)
    return jax.vmap(one)(guess, e, l0)


# One solver (and one reading of the pinned targets) per symmetry, not per scene.
_SOLVERS = {"rotation": _periodic_orbit, "translation": _walls_periodic_orbit, "none": _plain_periodic_orbit}
_TARGETS = {"translation": _walls_targets, "none": _plain_targets}


def _same_orbit(a: PeriodicOrbit, b: PeriodicOrbit, atol: float) -> bool:
    """Whether ``b``'s first section point is one of ``a``'s (so the orbits coincide)."""
    pa, pb = np.asarray(a.points), np.asarray(b.points)
    d = np.abs(pa - pb[0][None, :])
    if d.shape[1] in (3, 4):  # beta is an angle
        d[:, 0] = np.abs((d[:, 0] + np.pi) % (2 * np.pi) - np.pi)
    return bool(np.any(np.max(d, axis=1) <= atol)) and abs(float(a.energy) - float(b.energy)) <= atol * abs(
        float(a.energy)
    )


def find_periodic_orbits(
    scene: Scene,
    guesses: Float[ArrayLike, "B S"],
    period: int,
    *,
    energy: float | None = None,
    angular_momentum: float | None = None,
    rotation: float | None = None,
    tol: float = 1e-11,
    max_steps: int = 100,
    parabolic_tol: float = 1e-8,
    distinct_atol: float = 1e-7,
) -> list[PeriodicOrbit]:
    """Search from many guesses; the distinct converged orbits, as a list.

    Args:
        guesses: shape ``(B, S)``; each is solved as in ``find_periodic_orbit``
            (vmapped, one compilation).
        energy, angular_momentum: pinned values shared by all guesses (default:
            each guess's own, as in ``find_periodic_orbit``). Pin the energy to
            compare orbits found from guesses of different energies.
        distinct_atol: two solutions are the same orbit when the first section
            point of one is within this (max-norm, reduced coordinates) of one
            of the section points of the other, that is, up to a cyclic shift
            along the orbit and a rotation about the origin.

    Returns:
        The distinct converged orbits (unbatched ``PeriodicOrbit`` each), in
        increasing order of period (time), then of trace.
    """
    p = _check_period(period)
    size = scene.state_size
    if np.ndim(guesses) != 2 or np.shape(guesses)[1] != size:
        raise ValueError(f"guesses must have shape (B, {size}); got {np.shape(guesses)}")
    check_eagerly(scene, guesses)
    guesses = jnp.asarray(guesses, jnp.float64)
    e, l0, theta, pin_l, pin_rotation = _targets(scene, guesses[0], energy, angular_momentum, rotation)
    b = guesses.shape[0]
    e = jnp.broadcast_to(e, (b,)) if energy is not None else scene.energy(guesses)
    if pin_l:
        assert isinstance(scene, HasAngularMomentum)  # _targets pins L only for a scene that has one
        l0 = jnp.broadcast_to(l0, (b,)) if angular_momentum is not None else scene.angular_momentum(guesses)
    else:
        l0 = jnp.zeros((b,))
    batch, _ = _find_jit(scene, guesses, p, e, l0, theta, pin_l, pin_rotation, max_steps, tol, parabolic_tol)
    batch = jax.device_get(batch)
    found: list[PeriodicOrbit] = []
    for i in np.flatnonzero(np.asarray(batch.converged)):
        orbit = jax.tree_util.tree_map(lambda x: x[i], batch)
        if not any(_same_orbit(o, orbit, distinct_atol) for o in found):
            found.append(orbit)
    found.sort(key=lambda o: (float(o.period), float(o.trace)))
    return found


def continue_periodic_orbit(
    scene: StickInCircle,
    orbit: PeriodicOrbit,
    parameter: str,
    values: Sequence[float] | np.ndarray,
    *,
    rotation: float | None = None,
    tol: float = 1e-11,
    max_steps: int = 100,
    parabolic_tol: float = 1e-8,
    return_predictions: bool = False,
):
    """Continue a periodic orbit along a scene parameter (natural-parameter continuation).

    At each step the orbit's derivative with respect to the parameter, from the
    implicit function theorem (``dzeta/dq = -J^+ dF/dq``, autodiff through the
    collisions), predicts the orbit at the next value; Levenberg-Marquardt then
    corrects the prediction. The energy (and, for a spinning stick, the angular
    momentum) of ``orbit`` are kept fixed.

    Args:
        scene: the scene ``orbit`` belongs to.
        orbit: an unbatched ``PeriodicOrbit`` (e.g. from ``find_periodic_orbit``).
        parameter: ``"ell"``, ``"R"``, ``"mass"`` or ``"inertia"`` (the latter
            for a spinning stick only).
        values: the successive parameter values (small steps).
        rotation: as in ``find_periodic_orbit`` (``None``: free).
        return_predictions: also return the predictor's reduced coordinates
            for each value (to see the first-order prediction's accuracy).

    Returns:
        One ``PeriodicOrbit`` per value (check ``converged``), expressed in the
        frame where the first contact is at polar angle 0; with
        ``return_predictions``, the pair ``(orbits, predictions)``, the latter
        of shape ``(len(values), K)``.
    """
    require_x64()
    if _symmetry(scene) != "rotation":
        raise TypeError(
            f"continue_periodic_orbit follows relative periodic orbits of a rotation-symmetric scene "
            f"(StickInCircle); got {type(scene).__name__} (periodic_symmetry = {_symmetry(scene)!r})"
        )
    if parameter not in ("ell", "R", "mass", "inertia"):
        raise ValueError(f"parameter must be 'ell', 'R', 'mass' or 'inertia'; got {parameter!r}")
    if parameter == "inertia" and not scene.body_turns:
        raise ValueError("parameter 'inertia' can be continued only for a spinning stick (finite inertia)")
    p = orbit.p
    pin_rotation = rotation is not None
    pin_l = scene.body_turns and not pin_rotation
    theta = jnp.asarray(0.0 if rotation is None else rotation, jnp.float64)
    e = jnp.asarray(orbit.energy)
    l0 = jnp.asarray(orbit.angular_momentum) if pin_l else jnp.zeros(())
    results, predictions = [], []
    current_scene = scene
    z = jnp.asarray(orbit.points[0])
    for value in values:
        new_scene = _with_parameter(current_scene, parameter, value)
        z, predicted, out = _continue_step(
            current_scene, new_scene, z, p, e, l0, theta, pin_l, pin_rotation, parameter, max_steps, tol, parabolic_tol
        )
        results.append(out)
        predictions.append(predicted)
        current_scene = new_scene
    if return_predictions:
        return results, jnp.stack(predictions)
    return results


def _with_parameter(scene, parameter, value):
    """``scene`` with one parameter replaced, checked as the constructor checks it."""
    values = {name: float(getattr(scene, name)) for name in ("R", "ell", "mass", "inertia")}
    values[parameter] = float(value)
    checked = type(scene)(**values)  # raises ValueError out of range
    if (checked.body_turns, checked.body_is_point) != (scene.body_turns, scene.body_is_point):
        raise ValueError(f"{parameter} = {float(value)} changes the kind of scene ({scene.kind} -> {checked.kind})")
    return eqx.tree_at(lambda s: getattr(s, parameter), scene, jnp.asarray(value, jnp.float64))


@eqx.filter_jit
def _continue_step(
    old_scene, new_scene, z, p, e, l0, theta, pin_l, pin_rotation, parameter, max_steps, tol, parabolic_tol
):
    old = _Problem(old_scene, e, l0, theta, p, pin_l, pin_rotation)
    zeta = old.zeta(z)

    def residual_in_parameter(q):
        sc = eqx.tree_at(lambda s: getattr(s, parameter), old_scene, q)
        return _Problem(sc, e, l0, theta, p, pin_l, pin_rotation)(zeta)

    q0 = getattr(old_scene, parameter)
    dq = getattr(new_scene, parameter) - q0
    jac_z = jax.jacfwd(old)(zeta)
    jac_q = jax.jacfwd(residual_in_parameter)(q0)
    # Predictor: the tangent of the solution branch, -J^+ dF/dq, times the step.
    predicted = old.z(zeta - jnp.linalg.pinv(jac_z) @ (jac_q * dq))
    new = _Problem(new_scene, e, l0, theta, p, pin_l, pin_rotation)
    orbit, _ = _periodic_orbit(
        new_scene,
        None,
        p,
        e,
        l0,
        theta,
        pin_l,
        pin_rotation,
        max_steps,
        tol,
        parabolic_tol,
        frame_phi=jnp.zeros(()),
        zeta0=new.zeta(predicted),
    )
    return orbit.points[0], predicted, orbit
