"""The safe-step search's sharper steps (``jaxbill._engine.first_root``), for the stick in a circle.

The sharper steps rest on two facts the scene supplies: each gap's second
derivative at the current time, and a bound on the third along the flight.
Both are checked here against automatic differentiation of the gaps. Then the
search with them must find the roots the search without them finds (each is
proven to the time resolution; a grazing root also to the gap's rounding over
its slope), in fewer steps.
"""

import jax
import jax.numpy as jnp
import numpy as np
import pytest

import jaxbill as jb
from helpers import random_states
from jaxbill._engine.first_root import first_root
from jaxbill._engine.step import MAX_ROOT_STEPS, components

EPS = float(np.finfo(np.float64).eps)
R = 2.0


def _starts(ell, count, seed, spin_scale=1.0):
    states = random_states(np.random.default_rng(seed), count, R, ell, "rotor")
    states[:, 5] *= spin_scale
    scene = jb.StickInCircle(R=R, ell=ell)
    # States just after a bounce as well as fresh ones: one end on the wall, leaving it.
    after = np.asarray(jb.orbit(scene, jnp.asarray(states), 3, driver="lockstep").state)
    return scene, np.concatenate([states, after.reshape(-1, 6)])


@pytest.mark.parametrize("ell", [1.9, 1.0, 0.05])
def test_curvatures_and_jerk_bound_are_the_gaps_derivatives(ell):
    """``gaps_along_flight``'s curvatures are d(slope)/dt, and ``RootBounds.jerk`` bounds d^3 gap/dt^3
    along the flight to the first contact (automatic differentiation of the gaps)."""
    scene, states = _starts(ell, 24, seed=3, spin_scale=3.0)

    def along_flight(state):
        profile, bounds = scene.root_search(components(state))
        t_root = first_root(lambda t: scene.gaps_along_flight(profile, t), bounds, MAX_ROOT_STEPS)[0]
        times = t_root * jnp.linspace(0.0, 1.0, 9)
        rows = []
        for k in range(2):

            def gap(t, k=k):
                return scene.gaps_along_flight(profile, t)[0][k]

            rows.append(
                (
                    jax.vmap(lambda t, k=k: scene.gaps_along_flight(profile, t)[2][k])(times),
                    jax.vmap(jax.grad(jax.grad(gap)))(times),
                    jax.vmap(jax.grad(jax.grad(jax.grad(gap))))(times),
                )
            )
        return rows, bounds.lower_curv, bounds.jerk

    rows, lower_curv, jerk = jax.jit(jax.vmap(along_flight))(jnp.asarray(states))
    for curvature, second, third in rows:
        scale = np.asarray(lower_curv)[:, None]
        assert np.all(np.abs(np.asarray(curvature) - np.asarray(second)) <= 1e-12 * scale)
        assert np.all(np.abs(np.asarray(third)) <= np.asarray(jerk)[:, None] * (1.0 + 1e-12))


@pytest.mark.parametrize("ell,spin_scale", [(1.9, 1.0), (1.0, 1.0), (1.0, 30.0), (0.05, 1.0)])
def test_sharper_steps_find_the_same_roots_in_fewer_steps(ell, spin_scale):
    """From the same states, the search with the gaps' curvatures and the one with the flight's bounds
    alone find the same gap and the same time, the first in fewer steps."""
    scene, states = _starts(ell, 64, seed=5, spin_scale=spin_scale)

    def search(state, sharper):
        profile, bounds = scene.root_search(components(state))
        if not sharper:
            bounds = bounds._replace(jerk=None)
        t, index, steps, ok = first_root(lambda t: scene.gaps_along_flight(profile, t), bounds, MAX_ROOT_STEPS)
        slope = jnp.where(index == 0, *scene.gaps_along_flight(profile, t)[1])
        return t, index, steps, ok, slope, bounds.time_scale

    runs = {
        sharper: [np.asarray(a) for a in jax.jit(jax.vmap(lambda s: search(s, sharper)))(jnp.asarray(states))]
        for sharper in (True, False)
    }
    t, index, steps, ok, slope, time_scale = runs[True]
    t_plain, index_plain, steps_plain, ok_plain, _, _ = runs[False]
    assert ok.all() and ok_plain.all()
    np.testing.assert_array_equal(index, index_plain)
    # Each root is proven to 4 ulps of max(t, time scale); the gap's own rounding
    # (ulps of R^2) moves a root by that over its slope, which grazing makes large.
    allowed = 8 * EPS * np.maximum(t, time_scale) + 100 * EPS * R * R / np.abs(slope)
    assert np.all(np.abs(t - t_plain) <= allowed), np.max(np.abs(t - t_plain) / allowed)
    assert steps.mean() < 0.9 * steps_plain.mean(), (steps.mean(), steps_plain.mean())
