"""Periodic and relative periodic orbits of the collision map, by Levenberg-Marquardt: the entry points.

Which solver runs is the scene's answer to ``periodic_symmetry``
(``jaxbill._scenes.protocols.HasPeriodicSymmetry``), never its type:
``"rotation"`` (``StickInCircle``: reduced coordinates, rotation divided out;
``jaxbill._analysis.periodic_rotation``), ``"translation"`` (the sticks between
walls; ``jaxbill._analysis.periodic_walls``) or ``"none"`` (``StickInEllipse``;
``jaxbill._analysis.periodic_plain``). The result, the stability labels and the
differentiable solve they share are in ``jaxbill._analysis.periodic_orbit``.
"""

from __future__ import annotations

import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np
from jaxtyping import ArrayLike, Float

from jaxbill._analysis.periodic_orbit import PeriodicOrbit, periodic_symmetry_of
from jaxbill._analysis.periodic_plain import plain_periodic_orbit, plain_targets
from jaxbill._analysis.periodic_rotation import rotation_periodic_orbit, rotation_targets
from jaxbill._analysis.periodic_walls import walls_periodic_orbit, walls_targets
from jaxbill._engine.collision import check_eagerly
from jaxbill._engine.validation import MAX_STORED_COUNT, check_count
from jaxbill._scenes.protocols import HasAngularMomentum, Scene


def _check_period(period) -> int:
    return check_count("period", period, 1, "collisions", MAX_STORED_COUNT)


def _targets(scene, guess, energy, angular_momentum, rotation):
    e = scene.energy(guess) if energy is None else jnp.asarray(energy, jnp.float64)
    return _TARGETS[periodic_symmetry_of(scene)](scene, guess, e, angular_momentum, rotation)


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
    see ``jaxbill._analysis.periodic_rotation``). The orbit is returned in the frame of the guess:
    its first section point is the solution rotated to the polar angle of the
    guess's own first contact.

    A scene with no symmetry (``periodic_symmetry = "none"``: ``StickInEllipse``):
    periodic in every dynamical coordinate; ``angular_momentum`` and a
    nonzero ``rotation`` are refused (see ``jaxbill._analysis.periodic_plain``).

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
    solve = _SOLVERS[periodic_symmetry_of(scene)]

    def one(g, e_, l_):
        return solve(scene, g, p, e_, l_, theta, pin_l, pin_rotation, max_steps, tol, parabolic_tol)

    if guess.ndim == 1:
        return one(guess, e, l0)
    return jax.vmap(one)(guess, e, l0)


# One solver (and one reading of the pinned targets) per symmetry, not per scene.
_SOLVERS = {"rotation": rotation_periodic_orbit, "translation": walls_periodic_orbit, "none": plain_periodic_orbit}
_TARGETS = {"rotation": rotation_targets, "translation": walls_targets, "none": plain_targets}


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
