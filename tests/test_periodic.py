r"""Periodic orbits by Levenberg-Marquardt on the section map (jaxbill._analysis.periodic and its solvers).

The diameter orbit, derived by hand
-----------------------------------
The stick lies along a diameter (the x axis), its centre moves along the axis
with speed ``V``, ``omega = 0``: the ends hit the wall head-on in turn, at
``x = +-a`` for the centre, ``a = R - ell``; the flight between hits takes
``T = 2a / V`` and one period (2 collisions) ``4a / V``.

Linearise in the transverse variables ``xi = (y, alpha, vy, omega)`` (the energy
direction ``vx`` decouples at first order, and so does the collision time).
At a hit of end P1 (centre at ``x = a``, ``vx: V -> -V``), with ``n = P1/R``,
``n_y = (y + ell alpha) / R``, ``s = ell (u x n) = ell (n_y - alpha)
= ell (y - a alpha) / R``, ``J = 2 M V`` to first order:

    vy' = vy - (2V/R) (y + ell alpha),      omega' = omega - c (y - a alpha),
    c = 2 M V ell / (I R).

The hit of P2 at ``x = -a`` is the same law conjugated by the half-turn
``(y, vy) -> (-y, -vy)``. So the period-2 monodromy is ``B^2`` with
``B = K D F``: the flight ``F`` (``y += T vy``, ``alpha += T omega``), the flip
``D = diag(-1, 1, -1, 1)`` and the kick ``K`` above. Directly,

    tr B = 4a/R + 4 M ell a^2 / (I R).

``B`` has the eigenvalue 1 twice: the rotation about the origin,
``r = (a, 1, -V, 0)`` with ``B r = r``, and the conserved angular momentum,
the left eigenvector ``(M V, 0, M a, I)`` (``det B = 1``). The remaining pair
``mu, 1/mu`` has ``mu + 1/mu = tr B - 2``, and the period-2 multipliers
``mu^2, mu^-2`` have the trace

    tr_2 = (4a/R + 4 M ell a^2/(I R) - 2)^2 - 2.

For ``I = inf`` (the lens) this is the textbook two-bounce orbit between two
focusing mirrors of radius ``R`` a distance ``L = 2a`` apart: one bounce has
``tr = 2 - 2L/R``, and ``(2 - 4a/R)^2 - 2`` agrees. Examples (``R = 2``, ``M = 1``,
``I = ell^2``): ``ell = 1.5``: ``mu + 1/mu = -0.667``, elliptic;
``ell = 0.5``: ``+10``, hyperbolic; ``ell = 1``: ``+2``, parabolic.
"""

from __future__ import annotations

import math

import jax.numpy as jnp
import numpy as np
import pytest

import jaxbill as jb
from jaxbill._analysis.periodic import find_periodic_orbit, find_periodic_orbits
from jaxbill._analysis.periodic_rotation import continue_periodic_orbit, reduced_state

PERTURBED_DIAMETER_GUESS = [0.01, 0.02, 0.01, 1.0, 0.003, 0.002]


def diameter_trace(R, ell, inertia, mass=1.0):
    a = R - ell
    half = 4 * a / R + (0.0 if math.isinf(inertia) else 4 * mass * ell * a * a / (inertia * R)) - 2
    return half * half - 2


@pytest.mark.parametrize(
    "ell,inertia,label",
    [
        (1.5, float("inf"), "elliptic"),
        (1.5, None, "elliptic"),
        (1.9, None, "elliptic"),
        (1.1, None, "elliptic"),
        (0.5, None, "hyperbolic"),
        (1.9, 1.9**2 / 100, "elliptic"),
        (1.9, 1.9**2 / 200, "elliptic"),
    ],
)
def test_diameter_orbit_from_perturbed_guess(ell, inertia, label):
    R = 2.0
    scene = jb.StickInCircle(R=R, ell=ell, inertia=inertia)
    guess = np.array(PERTURBED_DIAMETER_GUESS)
    if scene.kind == "lens":
        guess[5] = 0.0
        orbit = find_periodic_orbit(scene, guess, 2)
    else:
        orbit = find_periodic_orbit(scene, guess, 2, angular_momentum=0.0)
    assert bool(orbit.converged) and float(orbit.residual) < 1e-12
    s = np.asarray(orbit.state)
    u = np.array([np.cos(s[2]), np.sin(s[2])])
    # Along a diameter, moving along its own axis, not spinning.
    assert abs(s[0] * u[1] - s[1] * u[0]) < 1e-12
    assert abs(s[3] * u[1] - s[4] * u[0]) < 1e-12
    assert abs(s[5]) < 1e-12
    # Period 2 proper: back to the first state after two collisions.
    np.testing.assert_allclose(np.asarray(orbit.states[-1]), s, atol=1e-12)
    assert abs(float(orbit.rotation)) < 1e-12
    speed = math.sqrt(2 * float(orbit.energy))
    np.testing.assert_allclose(float(orbit.period), 4 * (R - ell) / speed, rtol=1e-13)
    expected = diameter_trace(R, ell, float(scene.inertia))
    np.testing.assert_allclose(float(orbit.trace), expected, rtol=1e-9, atol=1e-9)
    mu = np.asarray(orbit.multipliers)
    np.testing.assert_allclose(mu[0] * mu[1], 1.0, atol=1e-9)
    np.testing.assert_allclose(np.sort(np.real(mu + 1 / mu)), [expected, expected], rtol=1e-9, atol=1e-9)
    assert orbit.label == label


def test_diameter_half_period_is_relative_periodic_with_rotation_pi():
    """One collision returns the state rotated by pi (ends exchanged): trace = tr B - 2."""
    R, ell = 2.0, 1.5
    scene = jb.StickInCircle(R=R, ell=ell, inertia=float("inf"))
    guess = np.array(PERTURBED_DIAMETER_GUESS)
    guess[5] = 0.0
    orbit = find_periodic_orbit(scene, guess, 1)
    assert bool(orbit.converged)
    np.testing.assert_allclose(abs(float(orbit.rotation)), math.pi, atol=1e-12)
    # For the lens B = -A (the flip), so tr B - 2 = -(2 - 4a/R).
    np.testing.assert_allclose(float(orbit.trace), -(2 - 4 * (R - ell) / R), atol=1e-9)


def _circle_guesses(count, seed, R=2.0):
    rng = np.random.default_rng(seed)
    r = R * np.sqrt(rng.uniform(0, 0.9, count))
    phi = rng.uniform(-np.pi, np.pi, count)
    th = rng.uniform(-np.pi, np.pi, count)
    return np.column_stack([r * np.cos(phi), r * np.sin(phi), np.zeros(count), np.cos(th), np.sin(th), np.zeros(count)])


def test_circle_polygon_orbits_from_random_guesses_are_distinct_and_exact():
    """Period 5 in the circle: the pentagon and the pentagram, each in both senses.

    Rotation number q/5 (q = 1..4) means each chord subtends 2 pi q / 5, the
    incidence angle (from the inward normal) is chi = pi/2 - pi q/5, chords have
    length 2 R cos(chi) and the period is 5 * 2 R cos(chi) / V.
    """
    R, p = 2.0, 5
    scene = jb.StickInCircle(R=R, ell=0.0)
    guesses = _circle_guesses(24, seed=3)
    orbits = find_periodic_orbits(scene, guesses, p, rotation=0.0, energy=0.5)
    speed = 1.0
    chis = []
    for orbit in orbits:
        assert float(orbit.residual) < 1e-12 and orbit.label == "parabolic"
        w_r, w_t = np.asarray(orbit.points[0])
        chi = math.atan2(w_t, -w_r)
        chis.append(chi)
        q = round(p * (math.pi / 2 - chi) / math.pi)
        assert 1 <= q <= 4
        np.testing.assert_allclose(chi, math.pi / 2 - math.pi * q / p, atol=1e-12)
        np.testing.assert_allclose(float(orbit.period), p * 2 * R * math.cos(chi) / speed, rtol=1e-12)
        # Vertices: consecutive contact points advance by 2 pi q / 5 on the circle.
        contacts = np.asarray(orbit.states)[:, :2]
        np.testing.assert_allclose(np.linalg.norm(contacts, axis=1), R, rtol=1e-13)
        angles = np.arctan2(contacts[:, 1], contacts[:, 0])
        steps = np.diff(np.concatenate([[math.atan2(orbit.state[1], orbit.state[0])], angles]))
        np.testing.assert_allclose(np.mod(steps - 2 * math.pi * q / p + math.pi, 2 * math.pi) - math.pi, 0, atol=1e-11)
    # All four rotation numbers found once each: duplicates (24 guesses) removed.
    assert sorted(round(p * (math.pi / 2 - c) / math.pi) for c in chis) == [1, 2, 3, 4]


# A period-2 relative periodic orbit of the spinning stick (R = 2, ell = 1.5,
# I = M ell^2) at E = 1/2, L = 0.3, found by a random search; (beta, w_r, w_t, omega).
ORBIT_L03 = [-0.64361, -0.75798, 0.53901, 0.2449]


def test_continuation_in_ell_is_second_order():
    """The predictor (IFT tangent, autodiff through the collisions) is O(d ell^2) accurate."""
    scene = jb.StickInCircle(R=2.0, ell=1.5)
    guess = reduced_state(scene, jnp.asarray(ORBIT_L03), 0.3)
    orbit = find_periodic_orbit(scene, guess, 2, energy=0.5, angular_momentum=0.3)
    assert bool(orbit.converged)
    path, predicted = continue_periodic_orbit(scene, orbit, "ell", [1.48, 1.46, 1.44], return_predictions=True)
    for o in path:
        assert bool(o.converged) and float(o.residual) < 1e-12
        np.testing.assert_allclose(float(o.energy), 0.5, rtol=1e-12)
        np.testing.assert_allclose(float(o.angular_momentum), 0.3, rtol=1e-12)
    half, predicted_half = continue_periodic_orbit(scene, orbit, "ell", [1.49], return_predictions=True)
    err_full = np.max(np.abs(np.asarray(predicted[0]) - np.asarray(path[0].points[0])))
    err_half = np.max(np.abs(np.asarray(predicted_half[0]) - np.asarray(half[0].points[0])))
    assert 3.0 < err_full / err_half < 5.0
    # Without the derivative the error would be first order.
    lag_full = np.max(np.abs(np.asarray(orbit.points[0]) - np.asarray(path[0].points[0])))
    lag_half = np.max(np.abs(np.asarray(orbit.points[0]) - np.asarray(half[0].points[0])))
    assert 1.5 < lag_full / lag_half < 2.5 and err_full < lag_full / 20
    # Stability changes smoothly along the family (towards period doubling at tr = -2).
    traces = [float(orbit.trace)] + [float(o.trace) for o in path]
    assert all(np.diff(traces) < 0) and traces[-1] > -2


def test_find_periodic_orbit_input_checks():
    scene = jb.StickInCircle(R=2.0, ell=1.5, inertia=float("inf"))
    with pytest.raises(ValueError, match="period"):
        find_periodic_orbit(scene, jnp.zeros(6), 0)
    with pytest.raises(ValueError, match="angular_momentum"):
        find_periodic_orbit(scene, jnp.asarray([0, 0, 0, 1.0, 0, 0]), 2, angular_momentum=0.0)
    with pytest.raises(ValueError, match="parameter"):
        continue_periodic_orbit(scene, None, "length", [1.0])


def test_scenes_say_whether_their_body_turns_or_is_a_point():
    """What periodic-orbit search and the pictures ask instead of a scene's kind: a stick of finite inertia
    turns, one of infinite inertia (the lens, a static stick between walls) does not, a point has no
    orientation at all."""
    inf = float("inf")
    declared = {
        "spinning stick": (jb.StickInCircle(2.0, 1.9), (True, False)),
        "lens": (jb.StickInCircle(2.0, 1.5, inertia=inf), (False, False)),
        "circle billiard": (jb.StickInCircle(2.0, 0.0), (False, True)),
        "stick in an ellipse": (jb.StickInEllipse(2.0, 1.4, 0.5), (True, False)),
        "walls 2D": (jb.StickBetweenWalls2D(3.0, 1.0), (True, False)),
        "static walls 2D": (jb.StickBetweenWalls2D(3.0, 1.0, inertia=inf), (False, False)),
        "walls 3D": (jb.StickBetweenWalls3D(3.0, 1.0), (True, False)),
        "static walls 3D": (jb.StickBetweenWalls3D(3.0, 1.0, inertia=inf), (False, False)),
        "point in a stadium": (jb.BodyInTable(jb.PointBody(), jb.Stadium(1.0, 1.0)), (False, True)),
    }
    for name, (scene, expected) in declared.items():
        assert (scene.body_turns, scene.body_is_point) == expected, name
