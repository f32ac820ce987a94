"""The analyses on ``StickInEllipse``: the checker, periodic orbits, sections, sampling, the plug-in protocols.

References are independent of the code under test: the point's period-2
orbits along the axes have closed-form periods and, as a two-mirror optical
resonator, closed-form monodromy traces ``2 (2 g^2 - 1)`` with
``g = 1 - d / rho`` (``d`` the orbit's length, ``rho`` the wall's radius of
curvature at its ends); the short stick along the major axis bounces like a
point in a segment shortened by ``ell`` at each end; the perimeter comes
from mpmath's complete elliptic integral; an ``a = b`` ellipse is the circle.
"""

from __future__ import annotations

import math

import numpy as np
import pytest

jax = pytest.importorskip("jax")
jb = pytest.importorskip("jaxbill")
import jax.numpy as jnp  # noqa: E402

from jaxbill._check.checker import flight_for  # noqa: E402
from jaxbill._scenes.ellipse.sections import arc_length, ellipse_length  # noqa: E402

A, B = 2.0, 1.3


@pytest.mark.parametrize(
    "parameters, state0",
    [
        (dict(a=A, b=B, ell=0.6), [0.1, 0.2, 0.3, 0.7, -0.4, 0.9]),
        (dict(a=A, b=B, ell=0.6, inertia=float("inf")), [0.1, 0.2, 0.3, 0.7, -0.4, 0.0]),
        (dict(a=A, b=B, ell=0.0), [0.1, 0.2, 0.0, 0.7, -0.4, 0.0]),
        (dict(a=1.0, b=2.5, ell=1.2, inertia=0.2), [0.0, 0.3, 1.4, 0.3, 0.8, -2.0]),
    ],
    ids=["rotor", "static", "point", "rotor_long_b_major"],
)
def test_checker_agrees_with_orbit(parameters, state0):
    """The diffrax column flight certifies every collision and agrees with ``jb.orbit`` to its tolerance."""
    scene = jb.StickInEllipse(**parameters)
    result = jb.check(scene, jnp.asarray(state0), 15)
    report = result.report
    assert report.n_checked == 15 and not report.flags, str(report)
    assert report.agree, str(report)
    assert report.local_max_time < 1e-9 and report.local_max_state < 1e-9, str(report)


def test_checker_reflection_is_the_impulse_law():
    """Specular reflection about the gradient of the gap in ``(x, y, sqrt(I/M) alpha)`` is ``kick``."""
    scene = jb.StickInEllipse(a=A, b=B, ell=0.7, mass=0.8, inertia=0.09)
    flight = flight_for(scene, scene.checker_flight())
    scale = math.sqrt(0.09 / 0.8)
    t_contact, alpha = 2.2, 0.4  # end P1 on the wall at parameter angle t_contact
    point = np.array([A * math.cos(t_contact), B * math.sin(t_contact)])
    centre = point - 0.7 * np.array([math.cos(alpha), math.sin(alpha)])
    state = jnp.array([*centre, alpha, 0.3, -0.8, 1.1])
    y = jnp.array([*centre, scale * alpha, 0.3, -0.8, scale * 1.1])
    after = flight.reflect(jnp.array(0), y)
    expected = scene.kick(tuple(state), 1.0, (math.cos(alpha), math.sin(alpha)))
    got = [*after[:2], after[2] / scale, *after[3:5], after[5] / scale]
    np.testing.assert_allclose(got[3:], np.asarray(expected[3:]), rtol=1e-13, atol=1e-13)


def _resonator_trace(length, radius):
    g = 1.0 - length / radius
    return 2.0 * (2.0 * g * g - 1.0)


@pytest.mark.parametrize("axis", ["minor", "major"])
def test_point_period_two_orbits_along_the_axes(axis):
    """Bouncing along an axis: period ``4 semi-axis / |v|``, back to its start, trace of a two-mirror resonator."""
    scene = jb.StickInEllipse(a=A, b=B, ell=0.0)
    if axis == "minor":
        guess, semi, other = [0.01, 0.0, 0.0, 0.02, 1.0, 0.0], B, A
    else:
        guess, semi, other = [0.0, 0.01, 0.0, 1.0, 0.02, 0.0], A, B
    found = jb.find_periodic_orbit(scene, jnp.asarray(guess), 2)
    assert bool(found.converged), found
    speed = math.sqrt(2.0 * float(found.energy))
    assert float(found.period) == pytest.approx(4.0 * semi / speed, rel=1e-12)
    np.testing.assert_allclose(found.states[-1], found.state, rtol=0, atol=1e-12)
    # Radius of curvature at the end of this axis: other^2 / semi... of the *other* semi-axis's square over this one.
    radius = other**2 / semi
    assert float(found.trace) == pytest.approx(_resonator_trace(2.0 * semi, radius), rel=1e-9)
    assert found.label == ("elliptic" if axis == "minor" else "hyperbolic")


def test_short_stick_along_the_major_axis_is_period_two():
    """Aligned with the major axis and moving along it, the stick's ends hit at ``(+-a, 0)`` with no lever:
    the centre bounces between ``+-(a - ell)``, period ``4 (a - ell) / |v|``."""
    ell = 0.6
    scene = jb.StickInEllipse(a=A, b=B, ell=ell)
    found = jb.find_periodic_orbit(scene, jnp.array([0.0, 0.001, 0.001, 1.0, 0.001, 0.001]), 2)
    assert bool(found.converged)
    speed = math.sqrt(2.0 * float(found.energy) / float(scene.mass))
    assert float(found.period) == pytest.approx(4.0 * (A - ell) / speed, rel=1e-12)
    np.testing.assert_allclose(found.states[-1], found.state, rtol=0, atol=1e-12)
    np.testing.assert_allclose(abs(float(found.state[0])), A - ell, rtol=0, atol=1e-12)
    np.testing.assert_allclose(np.asarray(found.state)[[1, 2, 4, 5]], 0.0, atol=1e-12)
    assert sorted(np.asarray(found.contacts).tolist()) == [-1, 1]
    # The energy-shell section of a turning stick has 4 dimensions: 4 nontrivial multipliers in reciprocal pairs.
    mu = np.sort(np.abs(np.asarray(found.multipliers)))
    assert mu.shape == (4,)
    np.testing.assert_allclose(mu[0] * mu[-1], 1.0, rtol=1e-8)


def test_ellipse_refuses_pinned_momentum_or_rotation():
    scene = jb.StickInEllipse(a=A, b=B, ell=0.0)
    guess = jnp.array([0.01, 0.0, 0.0, 0.02, 1.0, 0.0])
    with pytest.raises(ValueError, match="angular_momentum"):
        jb.find_periodic_orbit(scene, guess, 2, angular_momentum=0.1)
    with pytest.raises(ValueError, match="rotation"):
        jb.find_periodic_orbit(scene, guess, 2, rotation=0.5)


def test_perimeter_matches_the_complete_elliptic_integral():
    mpmath = pytest.importorskip("mpmath")
    mpmath.mp.dps = 30
    for a, b in ((A, B), (1.0, 3.0), (2.5, 2.5)):
        major, minor = max(a, b), min(a, b)
        expected = 4 * major * mpmath.ellipe(1 - (minor / major) ** 2)
        scene = jb.StickInEllipse(a=a, b=b, ell=0.0)
        assert float(ellipse_length(scene)) == pytest.approx(float(expected), rel=1e-14)
        # a quarter of the way round is the arc to (0, b)
        assert float(arc_length(scene, math.pi / 2)) == pytest.approx(float(expected) / 4, rel=1e-14)


def test_equal_axes_give_the_circle_sections():
    """``a = b = R``: the point's Birkhoff section is the circle's; a stick's ``p`` is the reduced section's."""
    R = 1.7
    point_orbit_start = jnp.array([0.2, -0.3, 0.0, 0.8, 0.5, 0.0])
    ellipse, circle = jb.StickInEllipse(a=R, b=R, ell=0.0), jb.StickInCircle(R=R, ell=0.0)
    states = jb.orbit(circle, point_orbit_start, 30).state
    np.testing.assert_allclose(ellipse.section(states), jb.birkhoff_section(circle, states), rtol=0, atol=1e-12)
    stick_start = jnp.array([0.2, -0.3, 0.4, 0.8, 0.5, 1.3])
    ellipse, circle = jb.StickInEllipse(a=R, b=R, ell=0.9), jb.StickInCircle(R=R, ell=0.9)
    orb = jb.orbit(circle, stick_start, 30)
    np.testing.assert_allclose(
        ellipse.section(orb.state, orb.contact)[:, 1], jb.reduced_section(circle, orb.state)[:, 1], rtol=0, atol=1e-12
    )


def test_section_state_round_trips():
    scene = jb.StickInEllipse(a=A, b=B, ell=0.5)
    s = np.linspace(0.05, 0.95, 7) * float(ellipse_length(scene))
    p = np.linspace(-0.8, 0.9, 7)
    states = scene.section_state(jnp.stack([jnp.asarray(s), jnp.asarray(p)], axis=-1), energy=0.7)
    assert np.all(np.isfinite(states))
    np.testing.assert_allclose(scene.section(states, jnp.ones(7, jnp.int32)), np.stack([s, p], -1), atol=1e-12)
    np.testing.assert_allclose(scene.energy(states), 0.7, rtol=1e-13)
    np.testing.assert_allclose(scene.gaps(states)[:, 0], 0.0, atol=1e-12)


def test_birkhoff_section_of_the_point_preserves_area():
    """The collision map of the point, read in ``(s, p)``, has Jacobian determinant 1 (Birkhoff)."""
    scene = jb.StickInEllipse(a=A, b=B, ell=0.0)

    def section_map(point):
        state = scene.section_state(point)
        after, _, contact = jb.collide(scene, state)
        return scene.section(after, contact)

    for point in ([0.7, 0.3], [3.1, -0.6], [5.5, 0.05]):
        jac = jax.jacfwd(section_map)(jnp.asarray(point))
        assert float(jnp.linalg.det(jac)) == pytest.approx(1.0, abs=1e-11)


def test_sample_energy_shell_gives_valid_starts():
    scene = jb.StickInEllipse(a=A, b=B, ell=0.8)
    states, weights = jb.sample_energy_shell(scene, 64, energy=0.3, seed=2)
    assert states.shape == (64, 6) and np.all(weights == 1.0)
    np.testing.assert_allclose(scene.energy(jnp.asarray(states)), 0.3, rtol=1e-13)
    assert np.all(np.asarray(scene.gaps(jnp.asarray(states))) > 0)
    with pytest.raises(ValueError, match="angular_momentum"):
        jb.sample_energy_shell(scene, 4, angular_momentum=0.1)


SCENES = [
    jb.StickInCircle(R=2.0, ell=1.0),
    jb.StickInEllipse(a=A, b=B, ell=0.5),
    jb.StickBetweenWalls2D(h=3.0, ell=1.0),
    jb.StickBetweenWalls3D(h=3.0, ell=1.0),
]


def test_symmetries_are_the_scenes_own():
    assert [s.periodic_symmetry for s in SCENES] == ["rotation", "none", "translation", "translation"]


def test_a_spinning_sticks_spectrum_pairs_with_two_positive_exponents():
    """The stick in an ellipse has three degrees of freedom and, off the circle, no invariant but the
    energy: its flow's spectrum is ``{l1, l2, 0, 0, -l2, -l1}`` with ``l2 > 0`` (only the time shift
    and the energy give zeros). Every checkpoint pairs within ``2 log(n) / T``, the size of a
    finite-time estimate of a zero exponent: the flow is symplectic, as its ``symplectic_flow`` says,
    and ``paired=True`` (three vectors and their partners) agrees with the six-vector run as closely."""
    scene = jb.StickInEllipse(a=2.2, b=1.8, ell=0.9)
    start = jnp.array([0.2, -0.3, 0.4, 0.8, 0.5, 1.3])
    n = 4000
    full = jb.lyapunov_spectrum(scene, start, n, n_history=5, paired=False)
    paired = jb.lyapunov_spectrum(scene, start, n, n_history=5, paired=True)
    tolerance = 2 * np.log(np.asarray(full.collisions)) / np.asarray(full.times)
    history = np.asarray(full.history)
    assert np.all(np.max(np.abs(history + history[:, ::-1]), axis=1) <= tolerance)
    assert np.all(np.max(np.abs(history[:, 2:4]), axis=1) <= tolerance)
    assert history[-1, 1] > 0.1 and history[-1, 1] > 10 * tolerance[-1]
    assert np.all(np.max(np.abs(np.asarray(paired.history) - history), axis=1) <= tolerance)
