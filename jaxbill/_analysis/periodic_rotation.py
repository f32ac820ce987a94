"""Relative periodic orbits of the rotation-symmetric scene (a stick in a circle) in reduced coordinates.

The reduced section coordinates, the equations, the monodromy, the solver and
the continuation along a scene parameter.

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
The labels from the trace, and the derivatives by the implicit function
theorem, are those of ``jaxbill._analysis.periodic_orbit``.
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import Any

import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np
from jaxtyping import ArrayLike

from jaxbill._analysis.periodic_orbit import (
    MIN_FLIGHT,
    PeriodicOrbit,
    periodic_symmetry_of,
    solve_least_squares,
    stability_index,
)
from jaxbill._engine.collision import collide_unchecked
from jaxbill._engine.validation import require_x64
from jaxbill._scenes.circle.scene import StickInCircle  # the scene of periodic_symmetry "rotation"
from jaxbill._scenes.walls.periodic import wrap_angle as _wrap


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
    return multipliers, trace, stability_index(trace, parabolic_tol)


def rotation_periodic_orbit(
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
    zeta, jac = solve_least_squares(problem, zeta0, max_steps)
    z = problem.z(zeta)
    z_p, phi_p, period, s0, states, contacts, flights = _iterate(scene, z, p)
    # Sliding along the wall (grazing, flight times -> 0) solves the equations
    # trivially; it is not an orbit.
    speed = jnp.sqrt(2.0 * energy / scene.mass)
    grazing = jnp.min(flights) <= MIN_FLIGHT * scene.R / speed
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


def rotation_targets(scene, guess, e, angular_momentum, rotation):
    """The pinned angular momentum and rotation, and which of them are pinned, from the user's choice."""
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
    if periodic_symmetry_of(scene) != "rotation":
        raise TypeError(
            f"continue_periodic_orbit follows relative periodic orbits of a rotation-symmetric scene "
            f"(StickInCircle); got {type(scene).__name__} (periodic_symmetry = {periodic_symmetry_of(scene)!r})"
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
    orbit, _ = rotation_periodic_orbit(
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
