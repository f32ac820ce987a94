"""Periodic orbits of a scene with no symmetry to divide out (``periodic_symmetry = "none"``: ``StickInEllipse``).

With nothing to divide out, the unknowns are the dynamical components of the
state just after the first collision, and the
residuals ``map^p(s) - s`` (angles wrapped), ``E - E0`` and the gap of the end
that touches at ``s`` (it stays on the section); see ``_PlainProblem``. Its
multipliers are those of ``map^p`` on the tangent space of ``{E = E0, g_k =
0}``: 2 for a point or a stick that never turns, 4 for a turning stick (the
ellipse conserves no angular momentum).
"""

from __future__ import annotations

from typing import Any

import equinox as eqx
import jax
import jax.numpy as jnp

from jaxbill._analysis.periodic_orbit import (
    ELLIPTIC,
    HYPERBOLIC,
    MIN_FLIGHT,
    PeriodicOrbit,
    angular_momentum_or_nan,
    solve_least_squares,
    stability_index,
)
from jaxbill._engine.collision import collide_unchecked
from jaxbill._scenes.protocols import NO_CONTACT, SEVERAL_CONTACTS
from jaxbill._scenes.walls.periodic import wrap_angle as _wrap


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


def plain_periodic_orbit(
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
    zeta, _ = solve_least_squares(problem, jnp.zeros(k), max_steps)
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
        stability = stability_index(trace, parabolic_tol)
    else:
        largest = jnp.max(jnp.abs(multipliers))
        stability = jnp.where(largest > 1.0 + parabolic_tol, HYPERBOLIC, ELLIPTIC).astype(jnp.int32)
    speed = jnp.sqrt(2.0 * energy / scene.mass)
    grazing = jnp.min(flights) <= MIN_FLIGHT * scene.length_scale / speed
    single = jnp.all((contacts != NO_CONTACT) & (contacts != SEVERAL_CONTACTS))
    single &= (first_contact != NO_CONTACT) & (first_contact != SEVERAL_CONTACTS) & (contacts[-1] == first_contact)
    all_states = jnp.concatenate([s0[None], states[:-1]])
    all_contacts = jnp.concatenate([first_contact[None], contacts[:-1]])
    momentum = angular_momentum_or_nan(scene, s0)
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


def plain_targets(scene, guess, e, angular_momentum, rotation):
    if angular_momentum is not None:
        raise ValueError(
            f"angular_momentum cannot be pinned for {type(scene).__name__}: no angular momentum is conserved"
        )
    if rotation is not None and float(rotation) != 0.0:
        raise ValueError(f"rotation must be None or 0 for {type(scene).__name__}: it has no rotation symmetry")
    return e, jnp.zeros(()), jnp.zeros(()), jnp.asarray(False), jnp.asarray(False)
