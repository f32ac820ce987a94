"""Conservation of energy and of the total angular momentum about the origin.

Physics (physics.md): the wall force is a frictionless impulse along the
radius ``n = P_k / R`` through the contact point, so it does no net work on an
elastic bounce (energy ``E = M|v|^2/2 + I omega^2/2`` is conserved) and exerts
no torque about the origin (``L = M (x vy - y vx) + I omega`` is conserved).
Between collisions both are trivially constant. The static lens (``I = inf``)
conserves ``E`` only (the infinitely heavy stick absorbs the torque); the
circle billiard (``ell = 0``) conserves ``E`` and the orbital ``L``.

Tolerances: each collision is a handful of float64 operations, so a change
above ``1e-13`` (~500 ulps) in one collision is not rounding. Over ``1e5``
collisions, even a drift growing *linearly* at half an ulp per collision stays
near ``1e-11``; ``1e-10`` allows that and still catches any systematic error
of the impulse law (a wrong ``s_k`` or ``J`` changes ``E`` by O(1) per bounce).

Reference values: ``E0``, ``L0`` of the initial state; ``jb.energy`` and
``jb.angular_momentum`` are first checked against the formulas written out
here, so that a wrong (e.g. constant) invariant cannot make the test vacuous.
"""

from __future__ import annotations

import math

import jax.numpy as jnp
import numpy as np
import pytest

import jaxbill as jb
from helpers import kind_of, make_scene, random_state, random_states, resolved_inertia

R = 2.0
N_LONG = 100_000  # one compile per scene kind: every long orbit has this length
PER_COLLISION = 1e-13
LONG_RUN = 1e-10
INF = float("inf")


def angular_momentum_scale(R, mass, inertia, energy):
    """The largest ``|L|`` any state of energy ``E`` can have inside the circle.

    ``|M c x v| <= M R |v| <= R sqrt(2 M E)`` and ``|I omega| <= sqrt(2 I E)``.
    Why this scale and not ``|L|``: an orbit may have ``L`` near 0 (any state
    with the stick spinning against its orbital motion), where ``dL/|L|`` is
    rounding divided by ~0 and meaningless. Why it cannot hide a drift: it is a
    constant fixed by the conserved ``E`` (it does not grow with the run or
    with the error), it is attained by some states (``|L|`` really spans
    ``[0, scale]``), and both terms of ``L`` are bounded by it, so the
    rounding error of computing ``L`` is ~1 ulp of it: anything larger
    relative to it is a real change of ``L``.
    """
    spin = 0.0 if math.isinf(inertia) else math.sqrt(2.0 * inertia * energy)
    return R * math.sqrt(2.0 * mass * energy) + spin


def _check_orbit(scene, mass, inertia, kind, state0, states, check_L=True):
    states = np.asarray(states)
    assert states.shape == (N_LONG, 6)
    assert np.all(np.isfinite(states)), "orbit left the finite values"
    s0 = np.asarray(state0, dtype=np.float64)
    E = np.concatenate([[float(jb.energy(scene, s0))], np.asarray(jb.energy(scene, states))])
    E0 = E[0]
    assert E0 > 0
    step = np.abs(np.diff(E)) / E0
    total = np.abs(E - E0) / E0
    k = int(np.argmax(step))
    assert step[k] < PER_COLLISION, f"energy jumped by {step[k]:.3g} (relative) at collision {k}"
    k = int(np.argmax(total))
    assert total[k] < LONG_RUN, f"energy drifted by {total[k]:.3g} (relative) by collision {k}"
    if check_L:
        L = np.concatenate([[float(jb.angular_momentum(scene, s0))], np.asarray(jb.angular_momentum(scene, states))])
        scale = angular_momentum_scale(R, mass, inertia if kind == "rotor" else 0.0, E0)
        step = np.abs(np.diff(L)) / scale
        total = np.abs(L - L[0]) / scale
        k = int(np.argmax(step))
        assert step[k] < PER_COLLISION, f"L jumped by {step[k]:.3g} (of its scale) at collision {k}"
        k = int(np.argmax(total))
        assert total[k] < LONG_RUN, f"L drifted by {total[k]:.3g} (of its scale) by collision {k}"


# ---------------------------------------------------------------------------
# the invariants are the physical ones (so the conservation tests mean something)
# ---------------------------------------------------------------------------
@pytest.mark.parametrize("ell, mass, inertia", [(1.0, 1.0, None), (1.9, 2.5, 0.01), (1.5, 0.7, INF), (0.0, 1.3, None)])
def test_invariants_are_the_physical_formulas(ell, mass, inertia):
    scene = make_scene(R, ell, mass, inertia)
    kind = kind_of(ell, inertia)
    I = resolved_inertia(mass, ell, inertia)
    rng = np.random.default_rng(7)
    states = random_states(rng, 5, R, ell, kind)
    x, y, _, vx, vy, w = states.T
    E = 0.5 * mass * (vx**2 + vy**2) + (0.0 if kind == "lens" else 0.5 * I * w**2)
    L = mass * (x * vy - y * vx) + (0.0 if kind == "lens" else I * w)
    np.testing.assert_allclose(np.asarray(jb.energy(scene, states)), E, rtol=1e-15, atol=0)
    np.testing.assert_allclose(
        np.asarray(jb.angular_momentum(scene, states)), L, rtol=0, atol=1e-15 * np.max(np.abs(L))
    )


# ---------------------------------------------------------------------------
# single orbits
# ---------------------------------------------------------------------------
ROTOR_CASES = [
    # (ell, inertia factor: I = mass ell^2 / factor; None = default, seed)
    (0.5, None, 1),
    (0.5, None, 2),
    (1.0, None, 3),
    (1.0, None, 4),
    (1.9, None, 5),
    (1.9, None, 6),
    (1.0, 100.0, 7),
    (1.0, 200.0, 8),
    (1.9, 100.0, 9),
    (1.9, 200.0, 10),
]


@pytest.mark.parametrize("ell, factor, seed", ROTOR_CASES)
def test_rotor_conserves_energy_and_angular_momentum(ell, factor, seed):
    mass = 1.0
    inertia = None if factor is None else mass * ell**2 / factor
    scene = make_scene(R, ell, mass, inertia)
    state0 = random_state(np.random.default_rng(seed), R, ell, "rotor")
    orb = jb.orbit(scene, jnp.asarray(state0), N_LONG)
    assert np.all(np.asarray(orb.contact) != 0)
    _check_orbit(scene, mass, resolved_inertia(mass, ell, inertia), "rotor", state0, orb.state)


@pytest.mark.parametrize("ell, seed", [(1.0, 11), (1.5, 12), (1.9, 13)])
def test_static_lens_conserves_energy(ell, seed):
    scene = make_scene(R, ell, 1.0, INF)
    state0 = random_state(np.random.default_rng(seed), R, ell, "lens")
    orb = jb.orbit(scene, jnp.asarray(state0), N_LONG)
    assert np.all(np.asarray(orb.state)[:, 5] == 0.0), "the static lens started to spin"
    # L is not conserved here (the wall's torque goes into the infinitely heavy
    # stick); check that it does change, i.e. that the energy check is not on
    # a trivially frozen orbit.
    L = np.asarray(jb.angular_momentum(scene, orb.state))
    assert np.ptp(L) > 1e-3
    _check_orbit(scene, 1.0, INF, "lens", state0, orb.state, check_L=False)


@pytest.mark.parametrize("seed", [14, 15])
def test_circle_billiard_conserves_energy_and_orbital_angular_momentum(seed):
    scene = make_scene(R, 0.0, 1.0, None)
    state0 = random_state(np.random.default_rng(seed), R, 0.0, "circle")
    orb = jb.orbit(scene, jnp.asarray(state0), N_LONG)
    states = np.asarray(orb.state)
    # the spin decouples: it is never kicked
    assert np.all(states[:, 5] == state0[5])
    _check_orbit(scene, 1.0, 0.0, "circle", state0, states)


# ---------------------------------------------------------------------------
# batched orbits
# ---------------------------------------------------------------------------
@pytest.mark.parametrize("ell, inertia", [(1.0, None), (1.9, 1.9**2 / 200), (1.5, INF)])
def test_batched_orbits_conserve_invariants(ell, inertia):
    mass = 1.0
    scene = make_scene(R, ell, mass, inertia)
    kind = kind_of(ell, inertia)
    states0 = random_states(np.random.default_rng(16), 3, R, ell, kind)
    orb = jb.orbit(scene, jnp.asarray(states0), N_LONG)
    assert orb.state.shape == (3, N_LONG, 6)
    for b in range(3):
        _check_orbit(
            scene,
            mass,
            resolved_inertia(mass, ell, inertia),
            kind,
            states0[b],
            orb.state[b],
            check_L=(kind != "lens"),
        )
