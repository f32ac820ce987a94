"""jaxbill.check: the diffrax spiral-column integration agrees with jb.orbit.

Agreement is asserted collision by collision up to the chaos horizon (where
jb.orbit from a 1e-12-perturbed start departs by more than TOL): contacts equal
and every scaled deviation (time in R/V, position in R, angle, velocity in V,
spin in V/sqrt(I/M)) below TOL. The checker must certify every collision it
returns; a step too large to rule out a hidden graze must be flagged.
"""

from __future__ import annotations

import math

import jax.numpy as jnp
import numpy as np
import pytest

import jaxbill as jb
from jaxbill._check.checker import check, flight_for

TOL = 1e-8
LOCAL_TOL = 1e-9  # one flight from the same state: only the checker's own error
N = 100

CASES = {
    # name: (R, ell, inertia, state0)
    "paper-ell1.9": (2.0, 1.9, None, [0.05, 0.02, 0.4, 0.8, 0.5, 0.6]),
    "paper-ell1.0": (2.0, 1.0, None, [0.3, -0.2, 1.1, -0.6, 0.7, 0.4]),
    "inertia/100": (2.0, 1.9, 1.9**2 / 100, [0.02, -0.03, 0.7, 0.5, 0.9, 2.0]),
    "fast-spin": (2.0, 1.0, None, [0.2, 0.1, -0.3, 0.4, -0.3, 25.0]),
    "lens": (2.0, 1.5, math.inf, [0.1, 0.05, 0.3, 0.7, 0.4, 0.0]),
    "circle": (2.0, 0.0, None, [0.1, 0.2, 0.3, 1.0, 0.4, 0.7]),
}


@pytest.mark.parametrize("name", list(CASES))
def test_agrees_with_orbit_up_to_chaos_horizon(name):
    R, ell, inertia, state0 = CASES[name]
    scene = jb.StickInCircle(R=R, ell=ell, inertia=inertia)
    result = check(scene, jnp.array(state0), N, tol=TOL)
    report = result.report
    print(report)
    assert report.trusted, str(report)
    assert report.n_checked == N
    assert report.n_compared >= 5, str(report)  # the comparison is not vacuous
    assert report.first_contact_mismatch is None, str(report)
    assert report.first_deviation is None, str(report)
    # One collision at a time, over all N (no chaos horizon): much tighter.
    assert report.local_first_mismatch is None, str(report)
    assert report.local_max_time < LOCAL_TOL and report.local_max_state < LOCAL_TOL, str(report)
    assert report.agree
    # The checker's own energy is conserved along its sequence.
    e0 = float(scene.energy(jnp.array(state0)))
    e = np.asarray(scene.energy(jnp.asarray(result.state)))
    assert np.max(np.abs(e - e0)) <= 1e-12 * e0


def test_reflection_in_scaled_coordinates_is_the_impulse_law():
    """With z = sqrt(I/M) alpha the metric is Euclidean: specular reflection
    about grad W_k reproduces the rigid-body impulse (checked against kick)."""
    R, ell, mass, inertia = 2.0, 1.3, 0.7, 0.05
    scene = jb.StickInCircle(R=R, ell=ell, mass=mass, inertia=inertia)
    s = math.sqrt(inertia / mass)
    column = flight_for(scene, scene.checker_flight())
    alpha, phi = 0.8, 2.1  # end P1 on the wall at polar angle phi
    u = np.array([math.cos(alpha), math.sin(alpha)])
    c = R * np.array([math.cos(phi), math.sin(phi)]) - ell * u
    state = jnp.array([c[0], c[1], alpha, 0.4, -0.9, 1.7])
    y = jnp.array([c[0], c[1], s * alpha, 0.4, -0.9, s * 1.7])
    y_after = column.reflect(jnp.array(0), y)
    expected = jnp.stack(scene.kick(tuple(state), 1.0, (jnp.cos(state[2]), jnp.sin(state[2]))))
    got = np.array([*y_after[:2], y_after[2] / s, *y_after[3:5], y_after[5] / s])
    np.testing.assert_allclose(got, np.asarray(expected), rtol=1e-13, atol=1e-13)


def _grazing_state(R=2.0, ell=1.0, excess=1e-5):
    """End P1 sweeps a circle of radius ell about a nearly fixed centre and pokes
    out of the wall by ``excess`` (in length) for a short moment near t = pi/2."""
    cx = R - ell + excess
    return jnp.array([cx, 0.0, math.pi / 2, 0.0, 1e-4, -1.0])


def test_grazing_collision_found_with_default_steps():
    scene = jb.StickInCircle(R=2.0, ell=1.0)
    result = check(scene, _grazing_state(), 1, tol=TOL)
    assert result.report.trusted, str(result.report)
    assert result.contact[0] == 1
    assert result.report.agree, str(result.report)


def test_too_large_step_is_flagged_not_misreported():
    scene = jb.StickInCircle(R=2.0, ell=1.0)
    result = check(scene, _grazing_state(), 1, dtmax=5.0)
    report = result.report
    assert not report.trusted
    assert report.flags[0].kind == "graze" and report.flags[0].index == 0, str(report)
    assert report.n_checked == 0 and result.t.shape == (0,)  # nothing uncertified is returned
    assert "FLAG" in str(report)


def test_batch_input_is_not_implemented():
    scene = jb.StickInCircle(R=2.0, ell=1.0)
    with pytest.raises(NotImplementedError):
        check(scene, jnp.zeros((2, 6)), 3)


def test_other_end_hitting_within_the_first_step_after_a_bounce():
    """Lens near a corner: P2 bounces, P1 hits 0.0025 later, inside the first
    solver step of the new flight, while P2's wall function starts at zero."""
    scene = jb.StickInCircle(R=2.0, ell=1.5, inertia=math.inf)
    state0 = jnp.array(
        [0.017720005343110773, 0.37639746740062185, -0.7172319232442583, 1.2822321449371856, 0.9374222901685278, 0.0]
    )
    result = check(scene, state0, 3, tol=TOL)
    assert result.report.trusted and result.report.agree, str(result.report)
    assert result.contact.tolist() == [-1, 1, -1]
    assert result.t[1] - result.t[0] < 0.003


def test_running_out_of_steps_is_flagged():
    scene = jb.StickInCircle(R=2.0, ell=1.9)
    result = check(scene, jnp.array(CASES["paper-ell1.9"][3]), 5, chunk_steps=64, max_steps=100)
    assert result.report.flags and result.report.flags[0].kind == "max_steps", str(result.report)
    assert result.report.n_checked == result.report.flags[0].index


def test_check_starts_from_a_state_just_after_a_collision():
    """The chaos-horizon perturbations must not push the end on the wall through it."""
    scene = jb.StickInCircle(R=2.0, ell=1.9)
    after = jb.orbit(scene, jnp.array([0.03, -0.02, 0.4, 0.6, 0.25, 0.3]), 1).state[0]
    result = jb.check(scene, after, 5)
    assert result.report.agree
    assert result.report.n_checked == 5
