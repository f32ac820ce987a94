"""The small-stick law's tools (``jaxbill.studies.small_stick``): the reduced kick map, the kick against
the engine, and the common-window ensemble estimator on cases with known answers."""

from __future__ import annotations

import math

import numpy as np
import pytest

import jaxbill as jb
from jaxbill.studies import small_stick as ss


@pytest.mark.parametrize("K", [1e-2, 1e-3])
def test_reduced_map_exponent_matches_small_kick_theory(K):
    # sqrt(2K/pi) comes from <|cos|> = 2/pi in d^2 dx/dn^2 = K g'(x) dx, not from the simulation.
    n = int(40 / math.sqrt(K))
    lam, err = ss.reduced_map_lyapunov(K, n, n_orbits=128, seed=1)
    assert lam == pytest.approx(float(ss.reduced_map_exponent(K)), rel=0.05)
    assert err < 0.02 * lam


def test_reduced_map_with_opposite_twist_is_not_hyperbolic():
    # K < 0: trace 2 - |K| |cos x| < 2, the elliptic side; the exponent is far below sqrt(2|K|/pi).
    K = 1e-2
    lam, _ = ss.reduced_map_lyapunov(-K, int(40 / math.sqrt(K)), n_orbits=64, seed=2)
    assert lam < 0.3 * float(ss.reduced_map_exponent(K))


def test_sawtooth_profile():
    psi = np.array([-0.3, 0.3, np.pi / 2 - 1e-9, np.pi / 2 + 1e-9, np.pi - 0.3])
    g, gp = ss.sawtooth_kick(psi)
    np.testing.assert_allclose(g, [-math.sin(0.3), math.sin(0.3), 1.0, -1.0, -math.sin(0.3)], atol=1e-8)
    assert np.all(gp >= 0)


def _at_wall(scene, psi, ell, v0=0.8, gap=1e-6):
    """A stick near the wall point (R, 0) or (a, 0), at angle psi to the normal (x axis), moving outwards."""
    wall = float(scene.R) if hasattr(scene, "R") else float(scene.a)
    x = wall - ell * abs(math.cos(psi)) - gap
    return np.array([x, 0.0, psi, v0, 0.0, 0.0])


@pytest.mark.parametrize(
    "make",
    [
        lambda ell: jb.StickInCircle(R=2.0, ell=ell, mass=1.0, inertia=1.0),
        lambda ell: jb.StickInEllipse(a=2.0, b=1.4, ell=ell, mass=1.0, inertia=1.0),
    ],
)
def test_spin_kick_switches_sign_where_the_stick_is_parallel_to_the_wall(make):
    ell, v0 = 1e-3, 0.8
    scene = make(ell)
    kicks = []
    for psi in (math.pi / 2 - 0.2, math.pi / 2 - 0.02, math.pi / 2 + 0.02, math.pi / 2 + 0.2, 0.4, -0.4):
        new, _, contact = jb.collide(scene, _at_wall(scene, psi, ell, v0))
        expected = 2.0 * ell * v0 * ss.sawtooth_kick(psi)[0]  # 2 M ell v_n g(psi) / I, first order in ell
        kicks.append(float(new[5]))
        assert float(new[5]) == pytest.approx(float(expected), rel=5e-3)
        assert int(contact) == (1 if math.cos(psi) > 0 else -1)  # the nearer end hits
    assert kicks[1] > 0 > kicks[2]  # the jump at psi = pi/2


def test_point_in_a_circle_has_zero_exponent():
    scene = jb.StickInCircle(R=2.0, ell=0.0)
    states, w = jb.sample_energy_shell(scene, 32, energy=0.5, seed=3)
    T = 400.0
    r = ss.ensemble_lyapunov(scene, states, T, weights=w)
    # linear growth of the tangent vector: Lambda(T) - Lambda(T/2) <= log 2 (+ a little), over T/2
    assert abs(r.per_time) < 2.0 * math.log(2.0) / (T / 2)
    assert r.failed == 0
    assert np.all(r.collisions[:, -1] >= r.collisions[:, 0])


def test_ensemble_estimate_matches_the_reduced_map_in_the_circle():
    # Two independent routes: the engine's tangent maps in a common window, and the closed-form twist of the
    # (psi, omega) map; orbits with negative twist must come out regular, the others chaotic.
    ell = 1e-3
    scene = jb.StickInCircle(R=2.0, ell=ell, mass=1.0, inertia=1.0)
    states, w = jb.sample_energy_shell(scene, 64, energy=0.5, seed=4)
    predicted, _, each, regular = ss.circle_reduced_exponents(states, ell, R=2.0)
    r = ss.ensemble_lyapunov(scene, states, 40.0 / predicted, weights=w)
    assert r.per_time == pytest.approx(predicted, rel=0.1)
    assert abs(r.per_time - predicted) < 4 * r.per_time_err + 0.02 * predicted
    j0 = r.log_stretch.shape[1] // 2 - 1
    measured = (r.log_stretch[:, -1] - r.log_stretch[:, j0]) / (r.window[1] - r.window[0])
    chaotic = ~regular & (each > 0.5 * predicted)
    ratio = measured[chaotic] / each[chaotic]
    assert np.median(np.abs(ratio - 1)) < 0.05  # orbit by orbit; a few drift in omega within the window
    assert np.mean(np.abs(ratio - 1) < 0.25) > 0.9
    if regular.any():
        assert np.max(measured[regular]) < 0.3 * predicted


def test_point_billiard_flux_in_a_circle():
    h, rate = ss.point_billiard_flux(2.0, 2.0, n_orbits=4000, n_collisions=5)
    np.testing.assert_allclose(h, 1 / 4.0, rtol=1e-9)  # sin(phi) / (2 R sin(phi)) for every chord
    assert rate == pytest.approx(2.0 / (math.pi * 2.0), rel=0.06)  # P / (pi A), Santalo
    assert ss.visit_rate(2.0, 2.0) == pytest.approx((math.pi / 4) / math.pi, rel=1e-12)


def test_power_law_fit_recovers_its_exponent():
    ell = np.geomspace(1e-6, 1e-1, 8)
    lam = 1.7 * ell**0.5
    p, p_err, c, _, _ = ss.fit_power_law(ell, lam, 0.01 * lam)
    assert p == pytest.approx(0.5, abs=1e-9) and c == pytest.approx(1.7, rel=1e-9)
