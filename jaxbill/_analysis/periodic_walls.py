"""Periodic orbits of the sticks between walls (translation symmetry): the solver around their section map.

``find_periodic_orbit`` and ``find_periodic_orbits`` take
``StickBetweenWalls2D`` and ``StickBetweenWalls3D``: there an orbit is periodic
in the dynamical coordinates (the horizontal motion drifts freely; in 3D up to
a rotation of the stick about the vertical). Their section coordinates,
residuals and multipliers are described in ``jaxbill._scenes.walls.periodic``.
"""

from __future__ import annotations

import jax
import jax.numpy as jnp

from jaxbill._analysis.periodic_orbit import (
    PeriodicOrbit,
    angular_momentum_or_nan,
    solve_least_squares,
    stability_index,
)
from jaxbill._scenes.protocols import NO_CONTACT, SEVERAL_CONTACTS
from jaxbill._scenes.walls import periodic as walls_orbits
from jaxbill._scenes.walls.periodic import wrap_angle as _wrap


def walls_periodic_orbit(
    scene, guess, p, energy, angular_momentum, rotation, pin_l, pin_rotation, max_steps, tol, parabolic_tol
):
    """``find_periodic_orbit`` for the sticks between walls (see ``jaxbill._scenes.walls.periodic``)."""
    problem, first_contact = walls_orbits.make_problem(
        scene, guess, p, energy, angular_momentum, rotation, pin_l, pin_rotation
    )
    xi0 = problem.start()
    if problem.has_rotation:
        xi0 = xi0.at[-1].set(walls_orbits.initial_rotation(problem))
    zeta, _ = solve_least_squares(problem, jax.lax.stop_gradient(problem.zeta(xi0)), max_steps)
    xi = problem.z(zeta)
    s0, states, contacts, flights = problem.iterate(xi)
    residual = jnp.max(jnp.abs(jax.lax.stop_gradient(problem.residual_from(xi, s0, states[-1]))))
    monodromy, multipliers, trace = walls_orbits.monodromy(jax.lax.stop_gradient(problem), jax.lax.stop_gradient(xi))
    single = jnp.all((contacts != NO_CONTACT) & (contacts != SEVERAL_CONTACTS))
    single &= (first_contact != NO_CONTACT) & (first_contact != SEVERAL_CONTACTS)
    converged = (residual <= tol) & ~walls_orbits.flights_too_short(problem, flights) & single
    points = walls_orbits.section_points(scene, jnp.concatenate([s0[None], states[:-1]]))
    rotation_found = _wrap(xi[-1]) if problem.has_rotation else jnp.zeros(())
    momentum = angular_momentum_or_nan(scene, s0)
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
        stability=stability_index(trace, parabolic_tol),
        converged=converged,
        energy=scene.energy(s0),
        angular_momentum=momentum,
        monodromy=monodromy,
        p=p,
    ), jnp.zeros(())


def walls_targets(scene, guess, e, angular_momentum, rotation):
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
