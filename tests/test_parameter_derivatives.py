"""Derivatives with respect to the scene's parameters (R, ell, inertia) against finite differences.

* The final state and time of a short orbit (``jb.orbit``), by ``jax.jacfwd``
  over the scene (the rotor's collision times differentiate implicitly).
* The period (in time) of a periodic orbit, by ``jax.grad`` through
  ``find_periodic_orbit`` (implicit function theorem at the solution), against
  re-solving at perturbed parameters; for the diameter orbit also against the
  closed form ``T = 4 (R - ell) / V``.
"""

from __future__ import annotations

import math

import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np
import pytest

import jaxbill as jb
from jaxbill._analysis.periodic import find_periodic_orbit
from jaxbill._analysis.periodic_rotation import reduced_state

N_COLLISIONS = 6
REL = 1e-6

CASES = {
    "rotor": (dict(R=2.0, ell=1.0), [0.1, -0.2, 0.3, 0.6, 0.5, 0.7], ("R", "ell", "inertia")),
    "rotor_light": (
        dict(R=2.0, ell=1.9, inertia=1.9**2 / 100),
        [0.01, -0.02, 0.3, 0.6, 0.5, 0.7],
        ("R", "ell", "inertia"),
    ),
    "lens": (dict(R=2.0, ell=1.5, inertia=float("inf")), [0.1, -0.2, 0.3, 0.6, 0.5, 0.0], ("R", "ell")),
    "circle": (dict(R=2.0, ell=0.0), [0.1, -0.2, 0.3, 0.6, 0.5, 0.7], ("R",)),
}


def _replace(scene, name, value):
    return eqx.tree_at(lambda s: getattr(s, name), scene, jnp.asarray(value))


@jax.jit
def _final(scene, s0):
    orb = jb.orbit(scene, s0, N_COLLISIONS)
    return orb.state[-1], orb.t[-1]


@pytest.mark.parametrize("case", list(CASES))
def test_orbit_final_state_gradients_match_finite_differences(case):
    params, s0, names = CASES[case]
    scene = jb.StickInCircle(**params)
    s0 = jnp.asarray(s0)
    grads = jax.jit(jax.jacfwd(_final))(scene, s0)
    for name in names:
        value = float(getattr(scene, name))
        h = 1e-7 * value  # the map is strongly curved: FD truncation error ~ h^2
        plus = _final(_replace(scene, name, value + h), s0)
        minus = _final(_replace(scene, name, value - h), s0)
        for k in range(2):
            diff = np.atleast_1d(np.asarray(plus[k]) - np.asarray(minus[k]))
            if k == 0:
                diff[2] = (diff[2] + np.pi) % (2 * np.pi) - np.pi  # alpha is wrapped
            fd = diff / (2 * h)
            ad = np.asarray(getattr(grads[k], name))
            assert np.max(np.abs(ad - fd)) <= REL * max(np.max(np.abs(ad)), 1e-2), (name, k, ad, fd)


def _period(params, scene, guess, **kw):
    R, ell, inertia = params
    sc = eqx.tree_at(lambda s: (s.R, s.ell, s.inertia), scene, (R, ell, inertia))
    return find_periodic_orbit(sc, guess, 2, **kw).period


def test_diameter_period_gradient_closed_form():
    scene = jb.StickInCircle(R=2.0, ell=1.5)
    guess = jnp.asarray([0.01, 0.02, 0.01, 1.0, 0.003, 0.002])
    p0 = jnp.asarray([2.0, 1.5, 2.25])
    grad = np.asarray(jax.grad(_period)(p0, scene, guess, energy=0.5, angular_momentum=0.0))
    # T = 4 (R - ell) / V with V = sqrt(2E/M) = 1, independent of the inertia.
    np.testing.assert_allclose(grad, [4.0, -4.0, 0.0], atol=1e-9)


def test_periodic_orbit_period_gradient_matches_finite_differences():
    """A non-symmetric period-2 orbit of the spinning stick (E = 1/2, L = 0.3)."""
    scene = jb.StickInCircle(R=2.0, ell=1.5)
    guess = reduced_state(scene, jnp.asarray([-0.64361, -0.75798, 0.53901, 0.2449]), 0.3)
    kw = dict(energy=0.5, angular_momentum=0.3)
    orbit = find_periodic_orbit(scene, guess, 2, **kw)
    assert bool(orbit.converged)
    # Re-solves start on the orbit itself, mid-flight (inside the circle for all
    # the perturbed parameters).
    _, flight, _ = jb.collide(scene, orbit.state)
    start = scene.flight(orbit.state, 0.5 * flight)
    p0 = jnp.asarray([2.0, 1.5, 2.25])
    grad = np.asarray(jax.grad(_period)(p0, scene, start, **kw))
    for i in range(3):
        h = 1e-5 * float(p0[i])
        plus = _period(p0.at[i].add(h), scene, start, **kw)
        minus = _period(p0.at[i].add(-h), scene, start, **kw)
        fd = (float(plus) - float(minus)) / (2 * h)
        assert abs(grad[i] - fd) <= 1e-6 * max(abs(fd), 1e-2), (i, grad[i], fd)
    assert np.all(np.abs(grad) > 1e-3)  # all three parameters matter for this orbit
    assert math.isfinite(float(orbit.period))
