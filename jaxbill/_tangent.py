"""Tangent maps of the collision map and of the flow, by automatic differentiation.

Two linearisations of one collision are useful, both ``(6, 6)`` matrices acting
on perturbations of the state ``[x, y, alpha, vx, vy, omega]``:

* The **collision (section) map** ``P: s -> s'`` sends a state to the state just
  after its next collision. Its Jacobian ``DP`` includes how the collision time
  ``t(s)`` depends on ``s``. A perturbation along the flow,
  ``f(s) = [vx, vy, omega, 0, 0, 0]``, only moves the start along the same
  flight, so ``DP f(s) = 0``: ``DP`` has rank 5 and maps into the tangent space
  of the section (states with an end on the wall).
* The **flow** tangent compares the two orbits at a *fixed time*, the reference
  orbit's collision time. A perturbed orbit that hits the wall ``dt`` earlier
  has already flown ``-dt`` away from its own collision, so
  ``D phi = DP - f(s') (grad t)^T``. It maps ``f(s)`` to ``f(s')`` (the
  time-shift direction stays neutral) and is the linearisation of the flow from
  just after one collision to just after the next: the product of these matrices
  along an orbit is the flow's Jacobian over the elapsed time. For a point
  particle this is the Dellago-Posch-Hoover tangent map; here it holds for any
  scene because it is computed, not derived.

Both come from JAX autodiff of ``collide``. The collision time of a spinning
stick is differentiated implicitly (``dt = -dg/g'`` at the root, a custom JVP
rule on the root finder), never through the root search; the lens and circle
collision times are closed forms and are differentiated directly. ``alpha`` is
wrapped into ``[-pi, pi)`` on output; the wrap is a piecewise-constant shift and
its derivative is 1.

Coordinates that carry the dynamics (``dynamical_indices``): all six for a
spinning stick; ``(x, y, vx, vy)`` for the static lens (``alpha`` is a constant
parameter and ``omega = 0``) and for the circle billiard (the spin is a free
rotor decoupled from the centre's motion).
"""

from __future__ import annotations

import jax
import jax.numpy as jnp

from ._collision import _collide
from ._stick_in_circle import StickInCircle


def dynamical_indices(scene: StickInCircle) -> tuple[int, ...]:
    """Indices of the state coordinates that carry the dynamics of ``scene``.

    ``(0, 1, 2, 3, 4, 5)`` for a spinning stick (``kind == "rotor"``);
    ``(0, 1, 3, 4)`` = ``(x, y, vx, vy)`` for the static lens and the circle
    billiard. The subspace ``d alpha = d omega = 0`` is invariant under both
    tangent maps in those two cases, so restricting to these rows and columns
    loses nothing.
    """
    if scene.kind == "rotor":
        return (0, 1, 2, 3, 4, 5)
    return (0, 1, 3, 4)


def phase_velocity(state: jax.Array) -> jax.Array:
    """The flow's vector field ``f(s) = [vx, vy, omega, 0, 0, 0]`` during free flight."""
    state = jnp.asarray(state)
    zeros = jnp.zeros_like(state[..., 0:3])
    return jnp.concatenate([state[..., 3:6], zeros], axis=-1)


def _map_with_time(scene: StickInCircle, state: jax.Array):
    new_state, dt, _ = _collide(scene, state)
    return new_state, dt


def _map_with_contact(scene: StickInCircle, state: jax.Array):
    new_state, dt, contact = _collide(scene, state)
    return (new_state, dt), contact


def push_forward(scene: StickInCircle, state: jax.Array, vectors: jax.Array, *, flow: bool):
    """Apply one collision to ``state`` and its tangent map to ``vectors``.

    Args:
        scene: a ``StickInCircle``.
        state: shape ``(6,)``.
        vectors: tangent vectors as columns, shape ``(6, k)``.
        flow: ``True`` for the fixed-time flow tangent, ``False`` for the
            Jacobian of the collision map (see the module docstring).

    Returns:
        ``(new_state, dt, contact, new_vectors)`` with ``new_vectors`` of shape
        ``(6, k)``. The collision is linearised once (the root search runs
        once) and the linear map applied to the ``k`` vectors.
    """
    (new_state, dt), linear, contact = jax.linearize(
        lambda s: _map_with_contact(scene, s), state, has_aux=True
    )

    def push(v):
        ds, dtime = linear(v)
        if flow:
            ds = ds - phase_velocity(new_state) * dtime
        return ds

    new_vectors = jax.vmap(push, in_axes=1, out_axes=1)(vectors)
    return new_state, dt, contact, new_vectors


def tangent_map(scene: StickInCircle, state: jax.Array, *, flow: bool = False, mode: str = "forward"):
    """The Jacobian of one collision: ``(new_state, dt, contact, jacobian)``.

    Args:
        scene: a ``StickInCircle`` (its leaves may be traced).
        state: ``[x, y, alpha, vx, vy, omega]``, float64, shape ``(6,)``.
        flow: ``False`` (default): the Jacobian ``DP`` of the collision map
            ``state -> state just after the next collision``, including the
            dependence of the flight time on the state (rank 5: ``DP f = 0``).
            ``True``: the flow's tangent map from ``state`` to the state just
            after the next collision at the reference orbit's collision time,
            ``DP - f(s') (grad t)^T`` (Dellago-Posch-Hoover form, invertible,
            ``f(s) -> f(s')``).
        mode: ``"forward"`` (``jax.jacfwd``) or ``"reverse"`` (``jax.jacrev``);
            the results agree to rounding.

    Returns:
        ``new_state`` (6,), ``dt`` (), ``contact`` () int32 and the ``(6, 6)``
        Jacobian, rows = output coordinates, columns = input coordinates.
        Invalid input poisons everything with NaN (see ``collide``).

    Works under ``jit`` and ``vmap``. At a corner (contact ``2``) or a grazing
    contact the map is not differentiable and the result is meaningless.
    """
    if mode not in ("forward", "reverse"):
        raise ValueError(f"mode must be 'forward' or 'reverse'; got {mode!r}")
    state = jnp.asarray(state, dtype=jnp.float64)
    jac = jax.jacfwd if mode == "forward" else jax.jacrev
    new_state, dt, contact = _collide(scene, state)
    d_state, d_time = jac(lambda s: _map_with_time(scene, s))(state)
    if flow:
        d_state = d_state - jnp.outer(phase_velocity(new_state), d_time)
    return new_state, dt, contact, d_state
