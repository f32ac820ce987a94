"""check_walls: the reduced (z, psi) equations integrated with diffrax agree with jb.orbit.

The checker integrates the reduced equations of the 3D stick between two walls
(centrifugal potential L_spin^2 / (2 I sin^2 psi), curved flights), finds
contacts with a diffrax Event and reflects in mass-weighted coordinates; it
never uses jaxbill's flight, root search or impulse formula. Agreement is
asserted two ways: the whole orbit up to the chaos horizon (where jb.orbit
started from perturbations of the checker's own one-collision error departs by
more than the tolerance; these orbits are strongly chaotic, so the horizon is
short except on the regular orbit), and one collision at a time over all N
collisions (the checker restarted from each of jaxbill's states: no chaos).
"""

from __future__ import annotations

import math

import diffrax
import jax.numpy as jnp
import numpy as np
import pytest

import jaxbill as jb
from jaxbill._check import walls as wc
from jaxbill._check.walls import check_walls

N = 60
TOL = 1e-6  # whole-orbit comparison (and the chaos horizon's threshold)
LOCAL_TOL = 1e-10  # one flight from jaxbill's own state: the checker's error only


def _state3(c, u, v, w):
    """A valid 3D state: u normalised, w made perpendicular to u."""
    u = np.asarray(u, float) / np.linalg.norm(u)
    w = np.asarray(w, float)
    w = w - (w @ u) * u
    return np.concatenate([c, u, v, w])


def _xz(x, z, th, vx, vz, om):
    """The 2D state [x, z, th, vx, vz, om] embedded in the x-z plane.

    The embedding is the one in ``StickBetweenWalls3D``'s docstring.
    """
    return np.array([x, 0.0, z, math.sin(th), 0.0, math.cos(th), vx, 0.0, vz, 0.0, om, 0.0])


_TILT = 0.05  # near-vertical case: u starts 0.05 rad from +z
CASES = {
    # name: (scene, state0, least number of whole-orbit collisions compared)
    "2d": (jb.StickBetweenWalls2D(h=3.0, ell=1.0), np.array([0.1, 1.5, 0.3, 0.2, 0.7, 0.9]), 10),
    "3d-xz-plane": (jb.StickBetweenWalls3D(h=3.0, ell=1.0), _xz(0.1, 1.5, 0.3, 0.2, 0.7, 0.9), 10),
    "3d-curved": (
        jb.StickBetweenWalls3D(h=3.0, ell=1.0),
        _state3([0.1, 0.2, 1.5], [0.3, 0.4, 0.8], [0.2, -0.1, 0.7], [0.5, -0.6, 0.4]),
        5,
    ),
    # sin(psi_min) = |w_z|/|w| = 1e-3: the stick passes 1e-3 rad from vertical every half turn.
    "near-vertical": (
        jb.StickBetweenWalls3D(h=3.0, ell=1.0),
        _state3(
            [0.0, 0.0, 1.5],
            [math.sin(_TILT), 0.0, math.cos(_TILT)],
            [0.1, 0.0, 0.6],
            [-0.02 * math.cos(_TILT), 1.0, 0.02 * math.sin(_TILT)],
        ),
        5,
    ),
    # I = M ell^2 / 100: spins up to ~15 rad per flight, passing 0.035 rad from vertical.
    "light": (
        jb.StickBetweenWalls3D(h=3.0, ell=1.0, mass=0.2, inertia=0.002),
        _state3([0.1, 0.2, 1.5], [0.3, 0.4, 0.8], [0.2, -0.1, 0.7], [0.5, -0.6, 0.4]),
        5,
    ),
    "2ell>h": (
        jb.StickBetweenWalls3D(h=1.5, ell=1.0),
        _state3([0.1, 0.2, 0.75], [0.8, 0.3, 0.2], [0.2, -0.1, 0.7], [0.3, -0.6, 0.4]),
        10,
    ),
    # |w| ell / |v| ~ 40: thousands of solver steps per orbit, tens of radians per flight.
    "fast-spin": (
        jb.StickBetweenWalls3D(h=3.0, ell=1.0),
        _state3([0.1, 0.2, 1.5], [0.3, 0.4, 0.8], [0.2, -0.1, 0.7], [15.0, -20.0, 8.0]),
        5,
    ),
}
# A nearly horizontal stick spinning about z: curved flights (L_spin != 0) on a
# regular orbit, so the whole orbit is compared, all N collisions, at 1e-8.
REGULAR = (
    jb.StickBetweenWalls3D(h=3.0, ell=1.0),
    _state3([0.0, 0.0, 1.5], [math.cos(0.05), 0.0, math.sin(0.05)], [0.1, 0.05, 0.5], [0.0, 0.0, 1.0]),
)


def _invariants(scene, states):
    states = jnp.asarray(states)
    e = np.asarray(scene.energy(states))
    if isinstance(scene, jb.StickBetweenWalls3D):
        other = np.asarray(scene.angular_momentum(states))
    else:
        other = np.asarray(states[..., 3])  # vx
    return e, other


@pytest.mark.parametrize("name", list(CASES))
def test_agrees_with_orbit(name):
    scene, state0, min_compared = CASES[name]
    result = check_walls(scene, state0, N, tol=TOL)
    report = result.report
    print(name, report, sep="\n")
    assert report.trusted, str(report)
    assert report.n_checked == N
    # Whole orbit, up to the chaos horizon.
    assert report.n_compared >= min_compared, str(report)
    assert report.first_contact_mismatch is None and report.first_deviation is None, str(report)
    # One collision at a time, all N.
    assert report.local_first_mismatch is None, str(report)
    assert report.local_max_time < LOCAL_TOL and report.local_max_state < LOCAL_TOL, str(report)
    assert report.agree
    # The checker's own orbit conserves E (to its tolerance) and L_z (exactly: a constant of the ODE).
    e0, l0 = _invariants(scene, state0)
    e, l = _invariants(scene, result.state)
    assert np.max(np.abs(e - e0)) <= 1e-9 * e0
    assert np.max(np.abs(l - l0)) <= 1e-13 * float(scene.mass * scene.h) * math.sqrt(2 * e0 / float(scene.mass))
    # The orbit really exercises both walls with both ends.
    assert set(np.unique(result.contact).tolist()) == {-3, -1, 1, 3}


def test_regular_orbit_agrees_over_all_collisions():
    scene, state0 = REGULAR
    result = check_walls(scene, state0, N, tol=1e-8)
    report = result.report
    print(report)
    assert report.trusted and report.agree, str(report)
    assert report.n_compared == N, str(report)
    assert max(report.max_time, report.max_position, report.max_angle, report.max_velocity, report.max_spin) < 1e-9
    assert abs(float(state0[11])) > 0.5  # L_spin = I w_z != 0: curved flights


def _settings(**kw):
    base = dict(
        solver=diffrax.Dopri8(),
        rtol=1e-12,
        atol=1e-14,
        root_tol=1e-12,
        chunk_steps=1024,
        max_steps=2**20,
        corner_tol=1e-12,
        graze_tol=1e-6,
        coarse_turn=0.5,
        pole_tol=1e-5,
    )
    base.update(kw)
    return wc._Settings(**base)


def test_the_potential_is_what_curves_the_flight():
    """The same flight without the L_spin^2 / (2 I sin^2 psi) term misses jaxbill's
    collision by far more than the checker's error: the comparison sees the curvature."""
    scene, state0, _ = CASES["3d-curved"]
    params = (3.0, 1.0, 1.0, 1.0, False)
    y, vxy, spin, sin_min = wc._from_3d(state0, 1.0, False)
    assert abs(spin) > 0.1
    _, dt_ref, _ = jb.collide(scene, jnp.asarray(state0))
    dt_with = wc._flight(params, y, vxy, spin, sin_min, _settings())[0]
    dt_without = wc._flight(params, y, vxy, 0.0, 1.0, _settings())[0]
    assert abs(dt_with - float(dt_ref)) < 1e-10
    assert abs(dt_without - float(dt_ref)) > 1e-3


@pytest.mark.parametrize("gap", [0, 1, 2, 3])
def test_mass_weighted_reflection_is_the_impulse_law(gap):
    """Reflection about grad g in Q = (sqrt(M) z, sqrt(I) psi) equals the rigid-body
    impulse of scene.kick, L_spin and phi' untouched."""
    h, ell, mass, inertia = 3.0, 1.0, 0.7, 0.3
    scene = jb.StickBetweenWalls3D(h=h, ell=ell, mass=mass, inertia=inertia)
    e = 1.0 if gap in (0, 2) else -1.0  # P1 or P2
    floor = gap < 2
    u = np.array([0.3, -0.5, 0.6 * (-e if floor else e)])  # the end points at its wall
    u /= np.linalg.norm(u)
    c = np.array([0.2, 0.1, (0.0 if floor else h) - e * ell * u[2]])  # and touches it
    state = _state3(c, u, [0.3, -0.2, 0.4], [0.9, 0.4, -0.7])
    assert abs(float(scene.gaps(jnp.asarray(state))[gap])) < 1e-15
    y, vxy, spin, _ = wc._from_3d(state, inertia, False)
    core = wc._Reduced(
        h=jnp.asarray(h),
        ell=jnp.asarray(ell),
        mass=jnp.asarray(mass),
        inertia=jnp.asarray(inertia),
        spin=jnp.asarray(spin),
        vxy=jnp.asarray(vxy),
        frozen=False,
    )
    reflected = wc._to_3d(np.asarray(core.reflect(jnp.asarray(gap), jnp.asarray(y))), vxy, spin, inertia)
    expected = np.asarray(scene.kick(jnp.asarray(state), gap))
    np.testing.assert_allclose(reflected, expected, rtol=0, atol=1e-14)


def _grazing_state(miss, ell=1.0, vz=0.05):
    """2D: a horizontal stick spinning at omega = 1 over the floor, rising slowly;
    end P1 reaches its lowest point ``miss`` above the floor (below it if < 0) near
    t = 1.52 and turns back. The first real contact is P1 on the ceiling near t = 23."""
    t_low = math.acos(vz / ell)
    z0 = ell * math.sqrt(1.0 - (vz / ell) ** 2) - vz * t_low + miss
    return np.array([0.0, z0, math.pi / 2, 0.1, vz, 1.0])


@pytest.mark.parametrize("three_d", [False, True])
def test_grazing_within_1e_9_is_flagged_not_misreported(three_d):
    s2 = _grazing_state(1e-9)
    scene = jb.StickBetweenWalls3D(h=3.0, ell=1.0) if three_d else jb.StickBetweenWalls2D(h=3.0, ell=1.0)
    state0 = _xz(*s2) if three_d else s2
    report = check_walls(scene, state0, N).report
    assert not report.trusted
    assert report.flags[0].kind == "graze" and report.flags[0].index == 0, str(report)
    assert report.n_checked == 0  # nothing uncertified is returned
    assert "FLAG" in str(report)
    # With steps fine enough to rule out a 1e-12 h excursion the miss is certified,
    # and the checker finds the real first contact, as jaxbill does.
    result = check_walls(scene, state0, N, graze_tol=1e-12, local="none")
    assert result.report.trusted and result.report.agree, str(result.report)
    assert result.contact[0] == 3 and int(result.orbit.contact[0]) == 3


def test_grazing_touch_is_found_with_fine_steps():
    """The same end dipping 1e-9 *into* the floor is a contact (P1 on the floor)."""
    scene = jb.StickBetweenWalls2D(h=3.0, ell=1.0)
    result = check_walls(scene, _grazing_state(-1e-9), N, graze_tol=1e-12, local="restart")
    assert result.report.trusted, str(result.report)
    assert result.contact[0] == 1 and int(result.orbit.contact[0]) == 1
    assert result.report.local_first_mismatch is None and result.report.local_max_time < LOCAL_TOL


def test_flat_landing_is_flagged_as_corner():
    scene = jb.StickBetweenWalls2D(h=3.0, ell=1.0)
    state0 = np.array([0.0, 1.5, math.pi / 2, 0.1, -1.0, 0.0])  # horizontal, no spin, falling
    result = check_walls(scene, state0, N, local="none")
    assert int(result.orbit.contact[0]) == 2  # jaxbill: both ends at once
    assert result.report.flags and result.report.flags[0].kind == "corner", str(result.report)
    assert result.report.n_checked == 0


def test_too_close_to_the_pole_is_flagged():
    scene = jb.StickBetweenWalls3D(h=3.0, ell=1.0)
    a = 2e-5  # sin(psi_min) = |w_z| / |w| = 1e-6
    state0 = _state3(
        [0.0, 0.0, 1.5],
        [math.sin(_TILT), 0.0, math.cos(_TILT)],
        [0.1, 0.0, 0.6],
        [-a * math.cos(_TILT), 1.0, a * math.sin(_TILT)],
    )
    report = check_walls(scene, state0, N, local="none").report
    assert report.flags and report.flags[0].kind == "pole" and report.n_checked == 0, str(report)


def test_a_flight_that_never_ends_is_flagged():
    """Spinning in place between the walls: jaxbill says no contact (dt = inf);
    the checker cannot prove that and says so."""
    scene = jb.StickBetweenWalls2D(h=3.0, ell=1.0)
    state0 = np.array([0.0, 1.5, 0.3, 0.2, 0.0, 2.0])
    result = check_walls(scene, state0, N, max_steps=2000)
    assert int(result.orbit.contact[0]) == 0 and math.isinf(float(result.orbit.t[0]))
    assert result.report.flags[0].kind == "max_steps" and result.report.n_checked == 0, str(result.report)


def test_bad_input():
    with pytest.raises(NotImplementedError):
        check_walls(jb.StickBetweenWalls2D(h=3.0, ell=1.0), np.zeros((2, 6)), 3)
    with pytest.raises(TypeError):
        check_walls(jb.StickInCircle(R=2.0, ell=1.0), np.zeros(6), 3)


def test_a_wrong_reference_is_caught(monkeypatch):
    """The comparison is not vacuous: jb.orbit's collision 10 made 1e-7 (in h/V) late
    is reported as a mismatch of that collision (and of the next flight)."""
    scene, state0, _ = CASES["3d-curved"]
    real = wc._orbit

    def late(scene_, s, n):
        o = real(scene_, s, n)
        if np.ndim(s) == 1:
            o = jb.Orbit(
                t=o.t.at[10].add(1e-7 * 3.0 / math.sqrt(2 * float(scene.energy(jnp.asarray(s))))),
                contact=o.contact,
                state=o.state,
                result=o.result,
            )
        return o

    monkeypatch.setattr(wc, "_orbit", late)
    report = check_walls(scene, state0, N, tol=1e-8).report
    assert report.trusted and not report.agree, str(report)
    assert report.local_first_mismatch == 10, str(report)
    assert 0.9e-7 < report.local_max_time < 1.1e-7, str(report)
