"""Tangent maps of the collision map and of the flow, by automatic differentiation.

Two linearisations of one collision are useful, both ``(S, S)`` matrices
(``S = scene.state_size``: 6 for ``StickInCircle`` and
``StickBetweenWalls2D``, 12 for ``StickBetweenWalls3D``) acting on
perturbations of the state:

* The **collision (section) map** ``P: s -> s'`` sends a state to the state just
  after its next collision. Its Jacobian ``DP`` includes how the collision time
  ``t(s)`` depends on ``s``. A perturbation along the flow ``f(s)`` (the
  scene's ``phase_velocity``: ``[vx, vy, omega, 0, 0, 0]`` for the stick in a
  circle) only moves the start along the same flight, so ``DP f(s) = 0``: ``DP``
  maps into the tangent space of the section (states with an end on a wall).
* The **flow** tangent compares the two orbits at a *fixed time*, the reference
  orbit's collision time. A perturbed orbit that hits the wall ``dt`` earlier
  has already flown ``-dt`` away from its own collision, so
  ``D phi = DP - f(s') (grad t)^T``. It maps ``f(s)`` to ``f(s')`` (the
  time-shift direction stays neutral) and is the linearisation of the flow from
  just after one collision to just after the next: the product of these matrices
  along an orbit is the flow's Jacobian over the elapsed time. For a point
  particle this is the Dellago-Posch-Hoover tangent map; here it holds for any
  scene because it is computed, not derived.

Both come from JAX autodiff of ``collide``. Collision times found by a root
search are differentiated implicitly (``dt = -dg/g'`` at the root, a custom JVP
rule), never through the search; closed-form collision times are
differentiated directly. Wrapped angles (``alpha``, ``theta``) have derivative 1.

The tangent directions that carry the dynamics
------------------------------------------------
Lyapunov spectra and finite-time exponents follow only the directions that
carry the dynamics, given by the scene (``dynamical_frame``):

* ``StickInCircle``: all six coordinates for a spinning stick; ``(x, y, vx,
  vy)`` for the static lens (``alpha`` is a constant parameter and ``omega =
  0``) and for the circle billiard (the spin is a free rotor decoupled from
  the centre's motion).
* ``StickBetweenWalls2D``: ``(z, theta, vz, omega)``; the horizontal motion
  ``(x, vx)`` is free and decoupled. ``(z, vz)`` for a stick that never turns.
* ``StickBetweenWalls3D``: the state has the constraints ``|u| = 1`` and
  ``w . u = 0``, and ``(x, y, vx, vy)`` decouple, so the dynamical tangent
  space at a state is 6-dimensional (``dz``, ``dvz``, ``du`` perpendicular to
  ``u``, and ``dw`` with ``u . dw = -w . du``): a frame of 6 orthonormal
  columns in the 12 coordinates, which moves with the state. ``(z, vz)`` for a
  stick that never turns.

The first two are coordinate subspaces (``scene.dynamical_indices``); the
third is not. In every case the dynamical directions' images depend only on
the dynamical directions (the decoupled coordinates never feed back), so
restricting the tangent maps to them loses nothing.
"""

from __future__ import annotations

from typing import Any, NamedTuple, Protocol, cast

import jax
import jax.numpy as jnp
from jaxtyping import Array, ArrayLike, Float, Int

from jaxbill._engine.collision import collide_unchecked
from jaxbill._engine.interface import Scene
from jaxbill._engine.step import advance_components, components, orbit_constants, stacked
from jaxbill._engine.validation import check_state_static, check_unbatched_scene, require_x64


class _Flows(Scene, Protocol):
    """What the flow's tangent asks of a scene beyond ``Scene``: its free-flight vector field."""

    def phase_velocity(self, state: jax.Array) -> jax.Array: ...


class _MovingFrame(Scene, Protocol):
    """A scene whose dynamical directions move with the state (``StickBetweenWalls3D``).

    A scene whose directions are fixed state coordinates names them in
    ``dynamical_indices`` instead.
    """

    @property
    def dynamical_size(self) -> int: ...

    def dynamical_frame(self, state: jax.Array) -> jax.Array: ...


def dynamical_indices(scene: Scene) -> tuple[int, ...]:
    """Indices of the state coordinates that carry the dynamics of ``scene``.

    ``StickInCircle``: ``(0, 1, 2, 3, 4, 5)`` for a spinning stick (``kind ==
    "rotor"``); ``(0, 1, 3, 4)`` = ``(x, y, vx, vy)`` for the static lens and
    the circle billiard. The subspace ``d alpha = d omega = 0`` is invariant
    under both tangent maps in those two cases, so restricting to these rows
    and columns loses nothing. ``StickBetweenWalls2D``: ``(1, 2, 4, 5)`` =
    ``(z, theta, vz, omega)`` (``(1, 4)`` for a stick that never turns).

    Raises:
        TypeError: for a scene whose dynamical directions are not coordinate
            axes (``StickBetweenWalls3D``: use ``dynamical_frame``).
    """
    indices = getattr(scene, "dynamical_indices", None)
    if indices is None:
        raise TypeError(
            f"{type(scene).__name__}'s dynamical directions depend on the state and are not coordinate axes: "
            "use jaxbill.dynamical_frame(scene, state)"
        )
    return tuple(indices)


def dynamical_size(scene: Scene) -> int:
    """Number ``k`` of tangent directions that carry the dynamics (the length of a flow spectrum)."""
    indices = getattr(scene, "dynamical_indices", None)
    return len(indices) if indices is not None else int(cast(_MovingFrame, scene).dynamical_size)


def dynamical_frame(scene: Scene, state: Float[ArrayLike, " S"]) -> Float[Array, "S k"]:
    """Orthonormal columns spanning the dynamical tangent directions at ``state``: ``(S, k)``.

    The coordinate axes of ``dynamical_indices`` for ``StickInCircle`` and
    ``StickBetweenWalls2D`` (the same at every state); for
    ``StickBetweenWalls3D`` a frame that moves with the state (see its
    ``dynamical_frame``). ``state`` has shape ``(S,)``.
    """
    state = jnp.asarray(state, jnp.float64)
    indices = getattr(scene, "dynamical_indices", None)
    if indices is not None:
        return jnp.eye(scene.state_size, dtype=state.dtype)[:, list(indices)]
    return cast(_MovingFrame, scene).dynamical_frame(state)


def to_state_space(scene: Scene, state: jax.Array, coefficients: jax.Array) -> jax.Array:
    """Tangent vectors ``(S, m)`` at ``state`` from their coordinates ``(k, m)`` in the dynamical frame."""
    indices = getattr(scene, "dynamical_indices", None)
    if indices is not None:
        # Rows by static position, not a scatter: XLA:CPU runs a vmapped scatter
        # or gather as a loop of its own, which cost more than a lens collision.
        row_of = {index: row for row, index in enumerate(indices)}
        zero = jnp.zeros(coefficients.shape[1:], coefficients.dtype)
        return jnp.stack([coefficients[row_of[i]] if i in row_of else zero for i in range(scene.state_size)])
    return cast(_MovingFrame, scene).dynamical_frame(state) @ coefficients


def to_dynamical(scene: Scene, state: jax.Array, vectors: jax.Array) -> jax.Array:
    """Coordinates ``(k, m)`` in the dynamical frame at ``state`` of tangent vectors ``(S, m)``.

    An orthogonal projection: components along the decoupled coordinates (and,
    in 3D, rounding across the constraints ``|u| = 1``, ``w . u = 0``) are dropped.
    """
    indices = getattr(scene, "dynamical_indices", None)
    if indices is not None:
        return jnp.stack([vectors[i] for i in indices])  # static rows (see to_state_space)
    return cast(_MovingFrame, scene).dynamical_frame(state).T @ vectors


def phase_velocity(
    scene_or_state: Scene | Float[ArrayLike, "*batch 6"], state: Float[ArrayLike, "*batch S"] | None = None
) -> Float[Array, "*batch S"]:
    """The flow's vector field ``f(s)`` during free flight: ``phase_velocity(scene, state)``.

    ``StickInCircle``: ``[vx, vy, omega, 0, 0, 0]``; ``StickBetweenWalls2D``:
    ``[vx, vz, omega, 0, 0, 0]``; ``StickBetweenWalls3D``: ``[v, w x u, 0, 0]``.
    Shape ``(..., S)``.

    The one-argument form ``phase_velocity(state)`` (kept from earlier
    versions) takes a planar state of length 6, for which both planar scenes
    have the same field ``[v, omega, 0, 0, 0]``.
    """
    if state is None:
        state = jnp.asarray(scene_or_state)
        if state.shape[-1] != 6:
            raise ValueError(
                f"phase_velocity(state) takes a planar state of length 6; got shape {state.shape}: "
                "use phase_velocity(scene, state)"
            )
        zeros = jnp.zeros_like(state[..., 0:3])
        return jnp.concatenate([state[..., 3:6], zeros], axis=-1)
    return cast(_Flows, scene_or_state).phase_velocity(jnp.asarray(state))


def _map_with_time(scene: Scene, state: jax.Array):
    new_state, dt, _ = collide_unchecked(scene, state)
    return new_state, dt


def _map_with_contact(scene: Scene, state: jax.Array, constants: Any = None):
    # The map itself, unchecked: push_forward carries states the map produced
    # (its callers check the start once, as jb.orbit does). Checking each one
    # as a start would poison the rare states the map leaves mid-corner (an
    # end still approaching its wall, resolved by a collision with dt = 0).
    if constants is None:
        constants = orbit_constants(scene, state)
    collision = advance_components(scene, components(state), constants)
    return (stacked(collision.state), collision.dt), (collision.contact, collision.status)


class PushedFrame(NamedTuple):
    """One collision of a state and of a frame of tangent vectors (``pushed_frame``).

    Attributes:
        state: ``(S,)`` the state just after the collision.
        dt: ``()`` its flight time.
        contact: ``()`` its contact code.
        status: ``()`` int32, its ``jaxbill._engine.results.Result``.
        frame: the pushed frame, as it was given (state vectors ``(S, k)`` or
            dynamical coordinates ``(k, m)``).
    """

    state: jax.Array
    dt: jax.Array
    contact: jax.Array
    status: jax.Array
    frame: jax.Array


def push_forward(scene: Scene, state: jax.Array, vectors: jax.Array, *, flow: bool, constants: Any = None):
    """Apply one collision to ``state`` and its tangent map to ``vectors``.

    Args:
        scene: any scene.
        state: shape ``(S,)``, from the map itself or a start already checked
            (``scene.is_valid``): it is not checked here.
        vectors: tangent vectors as columns, shape ``(S, k)``.
        flow: ``True`` for the fixed-time flow tangent, ``False`` for the
            Jacobian of the collision map (see the module docstring).
        constants: ``orbit_constants(scene, state0)``, what the scene holds
            fixed along the orbit, from its first state (the static lens's
            direction: its cosine and sine are then neither recomputed nor
            differentiated at every collision); ``None``: computed from
            ``state`` and differentiated with it.

    Returns:
        ``(new_state, dt, contact, new_vectors)`` with ``new_vectors`` of shape
        ``(S, k)``. The collision is linearised once (the root search runs
        once) and the linear map applied to the ``k`` vectors.
    """
    pushed = _pushed_vectors(scene, state, vectors, flow, constants)
    return pushed.state, pushed.dt, pushed.contact, pushed.frame


def _pushed_vectors(scene: Scene, state: jax.Array, vectors: jax.Array, flow: bool, constants: Any) -> PushedFrame:
    """``push_forward`` with the collision's status."""
    (new_state, dt), linear, (contact, status) = jax.linearize(
        lambda s: _map_with_contact(scene, s, constants), state, has_aux=True
    )

    def push(v):
        ds, dtime = linear(v)
        if flow:
            ds = ds - cast(_Flows, scene).phase_velocity(new_state) * dtime
        return ds

    new_vectors = jax.vmap(push, in_axes=1, out_axes=1)(vectors)
    return PushedFrame(new_state, dt, contact, status, new_vectors)


def push_frame(scene: Scene, state: jax.Array, coefficients: jax.Array, *, flow: bool, constants: Any = None):
    """``push_forward`` of a frame given by its coordinates ``(k, m)`` in the dynamical directions
    (``to_state_space``), returned the same way at the new state (``to_dynamical``).

    Returns ``(new_state, dt, contact, new_coefficients)``, ``new_coefficients``
    of shape ``(k, m)``. Where the dynamical directions are coordinate axes,
    only those coordinates are differentiated: the others (the static lens's
    and the circle's ``alpha`` and ``omega``) get no tangent at all, where
    zero tangents would be carried through every operation of the collision
    (a spectrum of the circle billiard or the static lens runs faster for it;
    the same values to the bit, since those zeros only ever added zero).
    """
    pushed = pushed_frame(scene, state, coefficients, flow=flow, constants=constants)
    return pushed.state, pushed.dt, pushed.contact, pushed.frame


def pushed_frame(
    scene: Scene, state: jax.Array, coefficients: jax.Array, *, flow: bool, constants: Any = None
) -> PushedFrame:
    """``push_frame`` with the collision's status (a ``PushedFrame``), for the analyses' result codes."""
    indices = getattr(scene, "dynamical_indices", None)
    if indices is None:
        vectors = to_state_space(scene, state, coefficients)
        pushed = _pushed_vectors(scene, state, vectors, flow, constants)
        return pushed._replace(frame=to_dynamical(scene, pushed.state, pushed.frame))
    parts = components(state)

    def map_of_dynamical(dynamical):
        given = dict(zip(indices, dynamical, strict=True))
        start = tuple(given.get(i, part) for i, part in enumerate(parts))
        orbit = scene.orbit_constants(start) if constants is None else constants
        collision = advance_components(scene, start, orbit)
        return (collision.state, collision.dt), (collision.contact, collision.status)

    primals = tuple(parts[i] for i in indices)

    def projected(new_state, d_parts, d_time):
        if flow:
            velocity = cast(_Flows, scene).phase_velocity(new_state)
            return jnp.stack([d_parts[i] - velocity[i] * d_time for i in indices])
        return jnp.stack([d_parts[i] for i in indices])

    if coefficients.shape[-1] == 1:
        # One vector (FLI, MEGNO): a plain forward derivative. ``linearize`` would split every conditional of
        # the collision into a primal and a linear one and copy the residuals between them, which costs more
        # than the one vector's arithmetic; it pays where several vectors share the primal (the spectra).
        column = tuple(coefficients[row, 0] for row in range(len(indices)))
        (new_parts, dt), (d_parts, d_time), (contact, status) = jax.jvp(
            map_of_dynamical, (primals,), (column,), has_aux=True
        )
        new_state = stacked(new_parts)
        return PushedFrame(new_state, dt, contact, status, projected(new_state, d_parts, d_time)[:, None])
    (new_parts, dt), linear, (contact, status) = jax.linearize(map_of_dynamical, primals, has_aux=True)
    new_state = stacked(new_parts)

    def push(column):
        d_parts, d_time = linear(tuple(column[row] for row in range(len(indices))))
        return projected(new_state, d_parts, d_time)

    return PushedFrame(new_state, dt, contact, status, jax.vmap(push, in_axes=1, out_axes=1)(coefficients))


def tangent_map(
    scene: Scene, state: Float[ArrayLike, " S"], *, flow: bool = False, mode: str = "forward"
) -> tuple[Float[Array, " S"], Float[Array, ""], Int[Array, ""], Float[Array, "S S"]]:
    """The Jacobian of one collision: ``(new_state, dt, contact, jacobian)``.

    Args:
        scene: any scene (``StickInCircle``, ``StickInEllipse``,
            ``StickBetweenWalls2D``, ``StickBetweenWalls3D``, ...; its leaves
            may be traced).
        state: float64, shape ``(S,)``, ``S = scene.state_size`` (the
            scene's ``state_layout``).
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
        Jacobian, rows = output coordinates, columns = input coordinates
        (``(S,)`` and ``(S, S)`` in general).
        Invalid input poisons everything with NaN (see ``collide``), the
        Jacobian included; a wrong shape or dtype of ``state`` or a batch of
        scenes (use ``jax.vmap``) raises ``ValueError``.

    Works under ``jit`` and ``vmap``. At a corner (contact ``2``) or a grazing
    contact the map is not differentiable and the result is meaningless.

    ``StickBetweenWalls3D``: the state's ``u`` and ``w`` are constrained
    (``|u| = 1``, ``w . u = 0``) and the map renormalises them, so the
    Jacobian has a zero singular value across each constraint; only its
    action on tangent vectors of the constraint manifold (``dynamical_frame``
    plus the horizontal coordinates) describes the dynamics.
    """
    if mode not in ("forward", "reverse"):
        raise ValueError(f"mode must be 'forward' or 'reverse'; got {mode!r}")
    require_x64()
    check_unbatched_scene(scene)
    check_state_static(scene, state, single=True)
    state = jnp.asarray(state, dtype=jnp.float64)
    jac = jax.jacfwd if mode == "forward" else jax.jacrev
    new_state, dt, contact = collide_unchecked(scene, state)
    d_state, d_time = jac(lambda s: _map_with_time(scene, s))(state)
    if flow:
        d_state = d_state - jnp.outer(cast(_Flows, scene).phase_velocity(new_state), d_time)
    # The map is poisoned where the input is invalid (or its search failed);
    # its derivative through jnp.where would be a plausible matrix of zeros.
    d_state = jnp.where(jnp.isnan(dt), jnp.nan, d_state)
    return new_state, dt, contact, d_state
