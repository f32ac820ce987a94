"""What the certified search assumes of every body and table holds along sampled flights.

The first-root search (``jaxbill._engine.first_root``) is safe only if the
scene's bounds are true: ``-lower_curv <= g'' <= upper_curv`` and
``|g'''| <= jerk`` for every gap along the flight up to its first contact, and
no gap vanishes inside the quiet interval. Here the gaps along each flight are
sampled densely and differentiated by autodiff of ``scene.gaps`` (the gaps as
functions of position, not the search's own formulas), for every kind of
table and body; the closed-form exit times are checked against the sampled
first sign change of the gaps.
"""

from __future__ import annotations

import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np
import pytest

import jaxbill as jb
from jaxbill._engine.first_root import with_curvatures
from jaxbill._engine.step import components

TRIANGLE = [(0.0, 0.0), (0.6, 0.0), (0.15, 0.4)]
PENTAGON = [(1.1, -0.2), (0.7, 0.85), (-0.45, 0.95), (-1.05, 0.05), (-0.2, -0.95)]
SAMPLES = 600


def _squircle(x, y):
    return x**4 + y**4 - 1.0


TURNING = {
    "triangle in stadium": jb.BodyInTable(jb.PolygonBody(TRIANGLE), jb.Stadium(1.0, 0.8)),
    "dumbbell 1:3 in ellipse": jb.BodyInTable(jb.Dumbbell.from_masses(1.0, 3.0, 0.8), jb.Ellipse(2.0, 1.2)),
    "square in circle": jb.BodyInTable(jb.PolygonBody.regular(4, 0.3), jb.Circle(1.0)),
    "triangle in pentagon": jb.BodyInTable(jb.PolygonBody(TRIANGLE), jb.Polygon(PENTAGON)),
    "coin between walls": jb.BodyInTable(jb.EllipseBody(0.4, 0.2), jb.Strip(1.0)),
    "fast coin between walls": jb.BodyInTable(jb.EllipseBody(0.45, 0.1, inertia=0.005), jb.Strip(1.0)),
    "dumbbell in a user's table": jb.BodyInTable(jb.Dumbbell(0.3), jb.ConvexTable(_squircle, (-1.2, 1.2, -1.2, 1.2))),
}

STRAIGHT = {
    "point in stadium": jb.BodyInTable(jb.PointBody(), jb.Stadium(1.0, 0.5)),
    "point in pentagon": jb.BodyInTable(jb.PointBody(), jb.Polygon(PENTAGON)),
    "static triangle in stadium": jb.BodyInTable(jb.PolygonBody(TRIANGLE, inertia=float("inf")), jb.Stadium(1.0, 0.8)),
    "static coin between walls": jb.BodyInTable(jb.EllipseBody(0.4, 0.2, inertia=float("inf")), jb.Strip(1.0)),
}


def _flights(scene, count=12, seed=0):
    """Starts just after a collision (the hard case: a gap at zero) and the flight to the next one."""
    states = jb.sample_energy_shell(scene, count, seed=seed)[0]
    orbit = jb.orbit(scene, states, 3)
    starts = np.asarray(orbit.state[:, 1])
    flights = np.asarray(orbit.t[:, 2] - orbit.t[:, 1])
    return starts, flights


def _gap_derivatives(scene, state, times):
    """Every gap and its first three time derivatives along the free flight, by autodiff of ``scene.gaps``."""

    def gaps_at(t):
        return scene.gaps(scene.flight(state, t))

    first = jax.jacfwd(gaps_at)
    second = jax.jacfwd(first)
    third = jax.jacfwd(second)
    return tuple(jax.vmap(f)(times) for f in (gaps_at, first, second, third))


# Compiled once per scene and reused for every flight (eager autodiff of every flight took most of this file's
# time): the sampled derivatives and the search's own bounds and profile.
_sampled_derivatives = eqx.filter_jit(
    lambda scene, state, flight, samples: _gap_derivatives(scene, state, jnp.linspace(0.0, flight, samples))
)
_search = eqx.filter_jit(lambda scene, state: scene.root_search(components(state)))
_gaps_between = eqx.filter_jit(
    lambda scene, state, t_in, t_out, samples: jax.vmap(lambda t: scene.gaps(scene.flight(state, t)))(
        jnp.linspace(t_in, t_out, samples)
    )
)


@pytest.mark.parametrize("name", list(TURNING))
def test_curvature_and_jerk_bounds_hold_along_flights(name):
    scene = TURNING[name]
    starts, flights = _flights(scene)
    for state, flight in zip(starts, flights):
        state = jnp.asarray(state)
        _, bounds = _search(scene, state)
        _, _, curvature, jerk = _sampled_derivatives(scene, state, jnp.asarray(flight), SAMPLES)
        curvature, jerk = np.asarray(curvature), np.asarray(jerk)
        slack = 1e-9 * (float(bounds.lower_curv) + float(bounds.upper_curv))
        assert np.all(curvature >= -float(bounds.lower_curv) - slack), (name, curvature.min(), bounds.lower_curv)
        assert np.all(curvature <= float(bounds.upper_curv) + slack), (name, curvature.max(), bounds.upper_curv)
        if bounds.jerk is not None:
            assert np.all(np.abs(jerk) <= float(bounds.jerk) * (1 + 1e-9) + slack), (name, np.abs(jerk).max())


@pytest.mark.parametrize("name", list(TURNING))
def test_the_scenes_own_curvatures_are_the_gaps_second_derivatives(name):
    """``gaps_along_flight``'s slopes and curvatures (the sharper steps) agree with autodiff of the gaps."""
    scene = TURNING[name]
    starts, flights = _flights(scene, count=4, seed=1)
    for state, flight in zip(starts, flights):
        state = jnp.asarray(state)
        profile, _ = _search(scene, state)
        times = jnp.linspace(0.0, flight, 40)
        gaps, slopes, curvature, _ = (
            np.asarray(v) for v in _sampled_derivatives(scene, state, jnp.asarray(flight), 40)
        )
        own = jax.vmap(lambda t: with_curvatures(scene.gaps_along_flight(profile, t)))(times)
        scale = float(scene.gap_scale)
        np.testing.assert_allclose(np.stack(own[0], -1), gaps, atol=1e-12 * scale)
        np.testing.assert_allclose(np.stack(own[1], -1), slopes, atol=1e-10 * scale * (1 + np.abs(slopes).max()))
        if own[2] is not None:
            np.testing.assert_allclose(np.stack(own[2], -1), curvature, rtol=1e-8, atol=1e-8 * np.abs(curvature).max())


@pytest.mark.parametrize("name", list(TURNING))
def test_no_contact_inside_the_quiet_interval(name):
    scene = TURNING[name]
    states = jb.sample_energy_shell(scene, 40, seed=2)[0]
    checked = 0
    for state in states:
        _, bounds = _search(scene, jnp.asarray(state))
        t_in, t_out = float(bounds.quiet_in), float(bounds.quiet_out)
        if not (t_in < t_out and np.isfinite(t_out)):
            continue
        checked += 1
        gaps = np.asarray(_gaps_between(scene, jnp.asarray(state), jnp.asarray(t_in), jnp.asarray(t_out), 200))
        assert np.all(gaps > 0.0), name
    if name not in ("coin between walls", "fast coin between walls", "dumbbell in a user's table"):
        assert checked >= 5, checked


@pytest.mark.parametrize("name", list(STRAIGHT))
def test_closed_form_contact_times_are_the_first_sign_change(name):
    """For contacts moving on straight lines the closed-form time is where a sampled gap first reaches zero,
    to the sampling's resolution, and no gap is negative before it."""
    scene = STRAIGHT[name]
    assert not scene.searches_for_roots
    starts, flights = _flights(scene, count=20, seed=3)
    for state, flight in zip(starts, flights):
        state = jnp.asarray(state)
        times = jnp.linspace(0.0, 1.5 * flight, 3001)
        gaps = np.asarray(_gaps_between(scene, state, jnp.asarray(0.0), jnp.asarray(1.5 * flight), 3001))
        inside = np.all(gaps >= -1e-12 * float(scene.gap_scale), axis=-1)
        first_out = np.argmin(inside) if not inside.all() else len(times)
        step = float(times[1])
        assert first_out < len(times), name
        assert abs(float(times[first_out]) - flight) <= 1.01 * step, (name, float(times[first_out]), flight)


def test_a_users_table_estimates_bounds_above_the_true_ones():
    """For the ellipse written as a user's function ``F = x^2/a^2 + y^2/b^2 - 1``, the largest ``|grad F|``
    over the table is ``2 / min(a, b)`` and the largest eigenvalue of ``Hess F`` is ``2 / min(a, b)^2``: the
    estimates (the grid's maxima times ``ESTIMATE_MARGIN``) lie above them, and not absurdly far."""
    a, b = 2.0, 0.7
    table = jb.ConvexTable(lambda x, y: (x / a) ** 2 + (y / b) ** 2 - 1.0, (-2.5, 2.5, -1.0, 1.0))
    true_gradient, true_hessian = 2.0 / min(a, b), 2.0 / min(a, b) ** 2
    assert true_gradient <= float(table.wall.gradient_bound) <= 2.0 * true_gradient
    assert true_hessian <= float(table.wall.hessian_bound) <= 2.0 * true_hessian
