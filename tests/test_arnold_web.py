"""The Arnold-web analysis (``jaxbill.studies.arnold_web``): starts, frequencies, resonances, ridges, spreads.

Every expected value here comes from a closed form, a hand count or a second
route through other code (the autodiff Jacobian of the collision map), never
from a previous run of the functions under test.
"""

from __future__ import annotations

import math

import jax
import jax.numpy as jnp
import numpy as np
import pytest

import jaxbill as jb
from jaxbill.studies import arnold_web as aw

R, ELL, E = 2.0, 1.9, 0.5


@pytest.fixture(scope="module")
def circle():
    return aw.circle_scene(R, ELL)


def test_L_is_conserved_in_the_circle_and_not_in_the_ellipse(circle):
    start = aw.web_starts(circle, 0.3, 0.8, E)
    assert float(jb.angular_momentum(circle, start)) == pytest.approx(0.8, abs=1e-12)
    spreads = {}
    for eps in (0.0, 1e-2):
        scene = aw.ellipse_scene(R, ELL, eps)
        # the same start is valid in every ellipse of the family (jb.orbit refuses invalid starts)
        orb = jb.orbit(scene, start, 2000)
        L = np.asarray(jb.angular_momentum(scene, orb.state))
        spreads[eps] = np.max(np.abs(L - 0.8))
    assert spreads[0.0] < 1e-11
    assert spreads[1e-2] > 1e-3


def test_ellipse_with_equal_axes_is_the_circle(circle):
    start = aw.web_starts(circle, np.array([-0.4, 0.2]), np.array([0.5, -1.0]), E)
    a = jb.orbit(circle, start, 200).state
    b = jb.orbit(aw.ellipse_scene(R, ELL, 0.0), start, 200).state
    np.testing.assert_allclose(np.asarray(a), np.asarray(b), atol=1e-9)


def test_web_starts_sit_on_the_line_with_contact_on_the_x_axis(circle):
    p = np.array([-0.5, 0.0, 0.6])
    L = np.array([1.0, -0.3, 0.2])
    st = aw.web_starts(circle, p, L, E)
    sp = np.asarray(jb.reduced_section(circle, st))
    np.testing.assert_allclose(sp[:, 0], aw.centre_line_s(circle), atol=1e-12)
    np.testing.assert_allclose(sp[:, 1], p, atol=1e-12)
    np.testing.assert_allclose(np.asarray(jb.angular_momentum(circle, st)), L, atol=1e-12)
    # the touching end P1 at (R, 0)
    ends = st[:, :2] + ELL * np.stack([np.cos(st[:, 2]), np.sin(st[:, 2])], axis=-1)
    np.testing.assert_allclose(ends, [[R, 0.0]] * 3, atol=1e-12)
    # unreachable points are NaN
    assert np.isnan(aw.web_starts(circle, 0.99, 1.9, E)).all()


def test_weighted_birkhoff_mean_converges_fast_on_a_quasi_periodic_signal():
    # f = cos(2 pi theta_j), theta_j = 0.1 + j * golden: its mean over the circle is exactly 0
    golden = (math.sqrt(5.0) - 1.0) / 2.0
    f = np.cos(2.0 * np.pi * (0.1 + golden * np.arange(2000)))
    assert abs(aw.weighted_birkhoff_mean(f)) < 1e-12
    assert abs(f.mean()) > 1e-5  # the plain mean converges as 1/N only


@pytest.mark.parametrize("p", [-0.6, 0.1, 0.45])
def test_point_in_a_circle_frequencies_match_the_chord_angle(p):
    # A point reflecting with sin(chi) = p advances by the central angle pi - 2 chi per
    # collision and flies for the chord 2 R cos(chi) at speed v; a free spin omega turns
    # by omega 2 R cos(chi) / v meanwhile.
    scene = jb.StickInCircle(R=R, ell=0.0, inertia=1.0)
    speed, omega = 1.3, 0.37
    phi0 = 0.4
    n_hat = np.array([np.cos(phi0), np.sin(phi0)])
    t_hat = np.array([-np.sin(phi0), np.cos(phi0)])
    v = speed * (p * t_hat - math.sqrt(1.0 - p * p) * n_hat)
    start = np.array([R * n_hat[0], R * n_hat[1], 0.0, v[0], v[1], omega])
    orb = jb.orbit(scene, start, 1500)
    f = aw.frequencies_from_orbit(scene, start, np.asarray(orb.state))
    chi = math.asin(p)
    assert f.nu1 == pytest.approx((math.pi - 2.0 * chi) / (2.0 * math.pi), abs=1e-10)
    assert f.nu2 == pytest.approx(omega * 2.0 * R * math.cos(chi) / speed / (2.0 * math.pi), abs=1e-10)


@pytest.mark.parametrize("L", [0.0, 0.7])
def test_small_torus_turns_at_the_linearised_rate_of_its_fixed_point(circle, L):
    # Second route: the elliptic fixed point of the folded reduced map (the stick bouncing
    # along a diameter), found by Newton with the Jacobian of jb.collide by autodiff;
    # the loops round it turn by arccos(tr J / 2) / (2 pi) per collision as their size -> 0.
    half = float(jb.wall_length(circle)) / 2.0

    def folded_map(x):
        state = jb.section_state(circle, x[0], x[1], E, L)
        sp = jb.reduced_section(circle, jb.collide(circle, state)[0])
        return jnp.array([jnp.remainder(sp[0], half), sp[1]])

    step, jacobian = jax.jit(folded_map), jax.jit(jax.jacfwd(folded_map))
    x = jnp.array([aw.centre_line_s(circle), 0.0])
    for _ in range(6):
        x = x - jnp.linalg.solve(jacobian(x) - jnp.eye(2), step(x) - x)
    jac = np.asarray(jacobian(x))
    assert np.linalg.det(jac) == pytest.approx(1.0, abs=1e-10)
    nu_lin = math.acos(np.trace(jac) / 2.0) / (2.0 * math.pi)
    start = np.asarray(jb.section_state(circle, x[0], x[1] + 1e-4, E, L))
    f = aw.frequencies_from_orbit(circle, start, np.asarray(jb.orbit(circle, start, 3000).state))
    assert f.spread < 1e-9
    assert min(abs(f.nu1 - nu_lin), abs(f.nu1 - (1.0 - nu_lin))) < 1e-8


def test_resonances_by_hand():
    # nu1 in [0.4, 0.45], nu2 in [-0.05, 0.05], k2 = 2:
    # k1 = 0: 2 nu2 in [-0.1, 0.1] holds 0; k1 = +-1: |nu1 + 2 nu2| in [0.3, 0.55] holds no integer;
    # k1 = +-2: 2 nu1 + 2 nu2 in [0.7, 1.0] holds 1.
    box = dict(nu1_range=(0.4, 0.45), nu2_range=(-0.05, 0.05))
    assert aw.resonances(3, (2,), **box) == [(0, 2, 0)]
    assert aw.resonances(4, (2,), **box) == [(0, 2, 0), (-2, 2, -1), (2, 2, 1)]
    # the harmonic (14, 2, 6) draws the line of (7, 1, 3): listed once, by the lower order
    lines = aw.resonances(16, (1, 2), nu1_range=(0.42, 0.44), nu2_range=(-0.01, 0.01))
    assert (7, 1, 3) in lines and (14, 2, 6) not in lines
    assert (7, 2, 3) in lines and (-7, 2, -3) in lines


def test_resonance_crossings_by_hand():
    # nu2 = 0.01 L + 0.003, nu1 = 3/7 + 0.02 p: (0, 2, 0) at L = -0.3; (7, 2, 3) where 0.14 p + 0.02 L + 0.006 = 0
    L = np.linspace(-1.0, 1.0, 41)
    p = np.linspace(-1.0, 1.0, 21)
    pp, ll = np.meshgrid(p, L)
    nu1 = 3.0 / 7.0 + 0.02 * pp
    nu2 = 0.01 * ll + 0.003
    rows = aw.resonance_crossings((0, 2, 0), L, nu1, nu2, axis=0)
    assert len(rows) == p.size
    for c in rows:
        np.testing.assert_allclose(c, [-0.3], atol=1e-12)
    cols = aw.resonance_crossings((7, 2, 3), p, nu1, nu2, axis=1)
    for Li, c in zip(L, cols):
        expect = -(0.02 * Li + 0.006) / 0.14
        np.testing.assert_allclose(c, [expect] if -1.0 <= expect <= 1.0 else [], atol=1e-12)


def test_ridges_and_offsets_on_a_synthetic_band():
    # a band round L = 0.2 with edges (Gaussian ridges of height 3) at 0.2 -+ 0.15
    L = np.linspace(-1.0, 1.0, 201)
    p = np.linspace(-1.0, 1.0, 5)
    ll = np.broadcast_to(L[:, None], (L.size, p.size))
    fli = 2.0 + 3.0 * (np.exp(-(((ll - 0.35) / 0.02) ** 2)) + np.exp(-(((ll - 0.05) / 0.02) ** 2)))
    ridges = aw.fli_ridges(fli, L, axis=0)
    for r in ridges:
        np.testing.assert_allclose(np.sort(r), [0.05, 0.35], atol=2e-3)
    off = aw.ridge_offsets(ridges, [[0.2]] * p.size, window=0.5)
    np.testing.assert_allclose(off.above, 0.15, atol=2e-3)
    np.testing.assert_allclose(off.below, -0.15, atol=2e-3)
    assert off.missed == 0
    assert aw.ridge_offsets(ridges, [[0.9]] * p.size, window=0.3).missed == p.size


def test_spread_against_time_uses_common_times():
    # two orbits with L = L0 + c t, recorded at different collision times; at a time T the
    # value is the last record at or before T.
    t = np.array([[1.0, 2.0, 3.0, 4.0], [0.5, 1.5, 3.5, 5.0]])
    c = np.array([0.1, -0.2])
    L0 = np.array([1.0, 2.0])
    L = L0[:, None] + c[:, None] * t
    times = np.array([2.0, 3.7])
    got = aw.values_at_times(t, L, times)
    np.testing.assert_allclose(got, [[1.2, 1.3], [1.7, 1.3]])
    msd, err = aw.spread_against_time(t, L, L0, times, n_sub=2)
    np.testing.assert_allclose(msd, [(0.2**2 + 0.3**2) / 2, (0.3**2 + 0.7**2) / 2])
    np.testing.assert_allclose(err, [abs(0.04 - 0.09) / 2, abs(0.09 - 0.49) / 2])


def test_power_law_fit_recovers_a_power_law():
    x = np.geomspace(1e-4, 1e-2, 5)
    A, g, sA, sg = aw.fit_power_law(x, 3.0 * x**1.7)
    assert A == pytest.approx(3.0, rel=1e-10) and g == pytest.approx(1.7, abs=1e-10)
