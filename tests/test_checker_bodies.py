"""jb.check on bodies in tables: the diffrax column flight of any planar body agrees with jb.orbit.

The checker flies the point ``(x, y, sqrt(I/M) alpha)`` straight in the column
the scene's gaps bound, reflects it about the touching gap's gradient and
bounds the gaps' curvature itself (``BodyColumnFlight``); it never uses the
scene's collision times, impulses or root-search bounds. Agreement is asserted
up to the chaos horizon (contacts equal, scaled deviations below ``TOL``) and
one collision at a time over all of them. References independent of the code:
the impulse law written out by hand, the closed-form Hessians of the walls,
energy conservation. A wrong impulse and a too-small curvature bound must be
reported, not passed.
"""

from __future__ import annotations

import math

import equinox as eqx
import jax.numpy as jnp
import numpy as np
import pytest

import jaxbill as jb
from jaxbill._check.checker import CURVATURE_SAFETY, BodyColumnFlight

TOL = 1e-8
LOCAL_TOL = 1e-9  # one flight from the same state: only the checker's own error
N = 12

CASES = {
    # name: (scene, state0 [x, y, alpha, vx, vy, omega])
    "triangle-in-stadium": (
        jb.BodyInTable(jb.PolygonBody.regular(3, 0.4), jb.Stadium(1.0, 1.0)),
        [0.1, 0.05, 0.3, 0.8, 0.45, 1.3],
    ),
    "dumbbell-1:3-in-ellipse": (
        jb.BodyInTable(jb.Dumbbell.from_masses(1.0, 3.0, 1.0), jb.Ellipse(2.0, 1.3)),
        [0.1, 0.05, 0.3, 0.7, -0.4, 0.9],
    ),
    "point-in-pentagon": (
        jb.BodyInTable(jb.PointBody(), jb.Polygon.regular(5, 2.0)),
        [0.1, 0.2, 0.0, 0.7, -0.4, 0.0],
    ),
    "square-in-circle": (
        jb.BodyInTable(jb.PolygonBody.regular(4, 0.6), jb.Circle(2.0)),
        [0.1, -0.2, 0.2, -0.5, 0.8, 1.1],
    ),
    "coin-between-walls": (
        jb.BodyInTable(jb.EllipseBody(0.5, 0.2), jb.Strip(1.5)),
        [0.0, 0.7, 0.4, 0.6, 0.8, 1.7],
    ),
}


@pytest.mark.parametrize("name", list(CASES))
def test_agrees_with_orbit_up_to_chaos_horizon(name):
    scene, state0 = CASES[name]
    result = jb.check(scene, jnp.array(state0), N, tol=TOL)
    report = result.report
    print(report)
    assert report.trusted, str(report)
    assert report.n_checked == N
    assert report.n_compared >= 4, str(report)  # the comparison is not vacuous
    assert report.first_contact_mismatch is None, str(report)
    assert report.first_deviation is None, str(report)
    assert report.local_first_mismatch is None, str(report)
    assert report.local_max_time < LOCAL_TOL and report.local_max_state < LOCAL_TOL, str(report)
    assert report.agree
    assert set(result.contact.tolist()) <= set(scene.gap_codes)  # one gap at a time, in the scene's codes
    # The checker's own energy is conserved along its sequence.
    e0 = float(scene.energy(jnp.array(state0)))
    e = np.asarray(scene.energy(jnp.asarray(result.state)))
    assert np.max(np.abs(e - e0)) <= 1e-12 * e0


def test_a_body_that_never_turns():
    """Infinite inertia: the impulse's turning part is dropped and alpha stays the start's."""
    scene = jb.BodyInTable(jb.PolygonBody.regular(4, 0.6, inertia=math.inf), jb.Circle(2.0))
    state0 = jnp.array([0.1, -0.2, 0.2, -0.5, 0.8, 0.0])
    result = jb.check(scene, state0, N, tol=TOL)
    assert result.report.trusted and result.report.agree, str(result.report)
    np.testing.assert_array_equal(result.state[:, 2], 0.2)
    np.testing.assert_array_equal(result.state[:, 5], 0.0)


def _flight(scene, state0):
    return BodyColumnFlight.of(scene.checker_flight()).prepared(np.asarray(state0, np.float64))


@pytest.mark.parametrize(
    "scene, exact",
    [
        # R^2 - |P|^2: Hess = -2 I.
        (jb.BodyInTable(jb.PointBody(), jb.Circle(2.0)), 2.0),
        # ab - P^T D P, D = diag(b/a, a/b): Hess = -2 D.
        (jb.BodyInTable(jb.PointBody(), jb.Ellipse(2.0, 1.3)), 2.0 * 2.0 / 1.3),
        # d - n . c - h(alpha): W'' = -h'' omega^2, |h''| <= A^2/B - B, in z = sqrt(I/M) alpha.
        (jb.BodyInTable(jb.EllipseBody(0.5, 0.2), jb.Strip(1.5)), (0.5**2 / 0.2 - 0.2) / ((0.5**2 + 0.2**2) / 4)),
    ],
    ids=["point-circle", "point-ellipse", "coin-strip"],
)
def test_sampled_curvature_bound_meets_the_closed_form(scene, exact):
    """The sampled largest Hessian of the walls is the closed form's (the grid hits the maxima), so the bound
    used, ``CURVATURE_SAFETY`` times it, holds with room to spare."""
    flight = _flight(scene, [0.1, 0.3, 0.0, 0.0, 0.0, 0.0])
    bounds = np.asarray(flight.hessian_bounds)
    np.testing.assert_allclose(bounds, exact, rtol=1e-12)
    assert CURVATURE_SAFETY * bounds.min() >= exact


def _impulse(state, r, normal, mass, inertia):
    """The frictionless elastic impulse written out: ``J = 2 v_n / (1/M + s^2/I)``, ``s = r x N``."""
    v, omega = np.array(state[3:5]), state[5]
    s = r[0] * normal[1] - r[1] * normal[0]
    v_n = v @ normal + omega * s
    J = 2.0 * v_n / (1.0 / mass + s * s / inertia)
    return np.array([*state[:3], *(v - J / mass * normal), omega - J / inertia * s])


def _reflected(flight, state, gap):
    scale = float(flight.scale)
    y = jnp.array([state[0], state[1], scale * state[2], state[3], state[4], scale * state[5]])
    after = np.asarray(flight.reflect(jnp.array(gap), y))
    return np.array([*after[:2], after[2] / scale, *after[3:5], after[5] / scale])


def test_reflection_is_the_impulse_law_for_a_polygon():
    """A vertex of a square on the circle: the reflection about grad W in ``(x, y, sqrt(I/M) alpha)``."""
    mass, inertia, R = 0.7, 0.09, 2.0
    scene = jb.BodyInTable(jb.PolygonBody.regular(4, 0.6, mass=mass, inertia=inertia), jb.Circle(R))
    alpha, phi = 0.3, 2.1  # vertex 0 (at angle alpha from the centre) on the wall at polar angle phi
    r = 0.6 * np.array([math.cos(alpha), math.sin(alpha)])
    centre = R * np.array([math.cos(phi), math.sin(phi)]) - r
    state = np.array([*centre, alpha, 0.4, -0.9, 1.7])
    expected = _impulse(state, r, (centre + r) / R, mass, inertia)
    got = _reflected(BodyColumnFlight.of(scene.checker_flight()), state, 0)
    np.testing.assert_allclose(got, expected, rtol=1e-13, atol=1e-13)


def test_reflection_is_the_impulse_law_for_the_coin():
    """The coin on the floor touches at its rim point farthest down, which slides as it turns."""
    a, b, mass, inertia = 0.5, 0.2, 0.8, 0.03
    scene = jb.BodyInTable(jb.EllipseBody(a, b, mass=mass, inertia=inertia), jb.Strip(1.5))
    alpha = 0.7
    n = np.array([0.0, -1.0])  # the floor's outward normal
    u, w = np.array([math.cos(alpha), math.sin(alpha)]), np.array([-math.sin(alpha), math.cos(alpha)])
    h = math.sqrt(a * a * (n @ u) ** 2 + b * b * (n @ w) ** 2)
    r = (a * a * (n @ u) * u + b * b * (n @ w) * w) / h
    state = np.array([0.3, h, alpha, 0.4, -0.9, 1.7])  # the rim touches y = 0
    expected = _impulse(state, r, n, mass, inertia)
    got = _reflected(BodyColumnFlight.of(scene.checker_flight()), state, 0)  # gap 0: the floor
    np.testing.assert_allclose(got, expected, rtol=1e-13, atol=1e-13)


def test_a_wrong_impulse_is_reported():
    """jb.orbit on a scene whose impulses use a moment of inertia 10 percent off the body the checker flies (the
    same walls, so the same flights): the comparison fails from the first collision on."""
    scene, state0 = CASES["square-in-circle"]
    flight = _flight(scene, state0)
    wrong = eqx.tree_at(lambda s: s.body.inertia, scene, scene.body.inertia * 1.1)
    report = flight.check(wrong, np.asarray(state0), N).report
    assert report.trusted, str(report)  # the checker's own flight is sound
    assert not report.agree
    assert report.local_first_mismatch == 0, str(report)
    assert report.local_max_time < LOCAL_TOL, str(report)  # the flight is right, the kick is not


def _grazing_state(R=2.0, rho=0.6, excess=1e-5):
    """A square turning about a nearly fixed centre: its vertices sweep a circle of radius rho that pokes out of
    the wall by ``excess`` (in length) for a short moment each quarter turn, first near t = pi/4."""
    return jnp.array([R - rho + excess, 0.0, math.pi / 4, 0.0, 1e-4, -1.0])


GRAZING_SCENE = CASES["square-in-circle"][0]


# N collisions everywhere below: the same compiled orbit as the square's comparison above.
def test_grazing_vertex_found_with_default_steps():
    result = jb.check(GRAZING_SCENE, _grazing_state(), N, tol=TOL)
    assert result.report.trusted and result.report.agree, str(result.report)
    assert abs(result.t[0] - math.pi / 4) < 0.01


def test_too_large_step_is_flagged_not_misreported():
    result = jb.check(GRAZING_SCENE, _grazing_state(), N, dtmax=5.0)
    report = result.report
    assert not report.trusted
    assert report.flags[0].kind == "graze" and report.flags[0].index == 0, str(report)
    assert report.n_checked == 0 and result.t.shape == (0,)  # nothing uncertified is returned


def test_too_small_curvature_bound_is_flagged():
    """A curvature bound 1000 times too small would certify a step that hides the graze: the walls' own
    curvature at the steps' ends exposes it."""
    state0 = _grazing_state()
    honest = _flight(GRAZING_SCENE, state0)
    weak = eqx.tree_at(lambda f: f.hessian_bounds, honest, honest.hessian_bounds * 1e-3)
    result = weak.check(GRAZING_SCENE, np.asarray(state0), N, dtmax=5.0)
    report = result.report
    assert not report.trusted
    assert report.flags[0].kind == "curvature" and report.flags[0].index == 0, str(report)
    assert report.n_checked == 0
