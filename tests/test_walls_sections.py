"""Sections and the billiard picture of the stick between two flat walls.

Expected values are worked out here by other routes than the code under test:

* section coordinates of hand-built states, as the angular momentum about the
  touching end and as the paper's ``T . V / |V|`` with ``T = (1, db/dtheta)``;
  3D states built from polar angles and their rates with ``w = u x du/dt``;
* jaxbill's impulse against the specular reflection of ``(theta_dot,
  eta_dot)``, ``eta = z / kappa``, about the normal of the paper's walls
  ``b(theta) = (ell/kappa)|cos theta|`` and ``t(theta) = (h - ell|cos
  theta|)/kappa`` (normals from numerical derivatives of ``b`` and ``t``), and
  against the paper's closed form for ``Delta eta_dot``;
* area preservation: the Jacobian determinant of the floor-to-floor map, by
  ``jax.jacfwd`` through ``jb.collide``, is 1 in ``(theta, p)`` and not 1 in
  two tempting alternatives; an ergodic orbit's ``theta`` histogram matches the
  projection ``|T(theta)|`` of the uniform measure;
* the 3D stick with ``L_z = 0`` in a vertical plane against the 2D scene.
"""

from __future__ import annotations

import math

import jax
import jax.numpy as jnp
import numpy as np
import pytest

import jaxbill as jb
from jaxbill._scenes.walls.sections import (
    flight_paths,
    floor_section,
    floor_section_bound,
    floor_seed_points,
    floor_seeds,
    floor_state,
    reduced_wall_section,
    theta_z_path,
    wall_twin_distances,
    wall_twin_states,
)

H, ELL = 3.0, 1.0


def embed(state2d) -> np.ndarray:
    """2D ``[x, z, th, vx, vz, om]`` as a 3D state in the ``x``-``z`` plane."""
    x, z, th, vx, vz, om = np.moveaxis(np.asarray(state2d, dtype=np.float64), -1, 0)
    zero = np.zeros_like(x)
    return np.stack([x, zero, z, np.sin(th), zero, np.cos(th), vx, zero, vz, zero, om, zero], axis=-1)


def rotate_about_z(state3d, angle) -> np.ndarray:
    """Turn a 3D state (positions and every vector) about the vertical axis."""
    c, s = math.cos(angle), math.sin(angle)
    rot = np.array([[c, -s, 0.0], [s, c, 0.0], [0.0, 0.0, 1.0]])
    parts = np.asarray(state3d, dtype=np.float64).reshape(-1, 4, 3) @ rot.T
    return parts.reshape(np.shape(state3d))


def polar_state(theta, phi, theta_dot, phi_dot, z, vz, ell, lower_on_floor=True, vxy=(0.0, 0.0)):
    """A 3D state from polar angles and their rates: ``u`` on the sphere, ``w = u x du/dt``."""
    u = np.array([math.sin(theta) * math.cos(phi), math.sin(theta) * math.sin(phi), math.cos(theta)])
    e_theta = np.array([math.cos(theta) * math.cos(phi), math.cos(theta) * math.sin(phi), -math.sin(theta)])
    e_phi = np.array([-math.sin(phi), math.cos(phi), 0.0])
    du = theta_dot * e_theta + math.sin(theta) * phi_dot * e_phi
    w = np.cross(u, du)
    return np.concatenate([[0.3, -0.2, z], u, [vxy[0], vxy[1], vz], w])


# -- section coordinates of hand-built states -----------------------------------


def test_floor_section_hand_worked():
    mass, inertia = 2.0, 0.5  # kappa = 0.5
    scene = jb.StickBetweenWalls2D(H, ELL, mass=mass, inertia=inertia)
    kappa = math.sqrt(inertia / mass)
    cases = [  # theta, vz, omega, touching end, its contact code
        (0.3, 0.4, -0.7, -1),
        (-2.5, -0.2, 0.9, +1),
        (2.0, 0.6, 0.1, +1),
    ]
    for theta, vz, omega, end in cases:
        assert end * math.cos(theta) < 0  # the lower end
        z = ELL * abs(math.cos(theta))
        state = np.array([0.7, z, theta, 0.9, vz, omega])  # vx = 0.9 must not matter
        got = np.asarray(floor_section(scene, state, end))
        # Route 1: angular momentum about the touching end P_e = c + e ell (sin, cos), horizontal motion
        # removed; in the theta sense (from +z towards +x) r x v = r_z v_x - r_x v_z.
        r = -end * ELL * np.array([math.sin(theta), math.cos(theta)])  # centre minus P_e, (x, z)
        about_end = inertia * omega + mass * (r[1] * 0.0 - r[0] * vz)
        e_int = 0.5 * mass * vz**2 + 0.5 * inertia * omega**2
        expected_p = about_end / math.sqrt(2 * inertia * e_int)
        # Route 2: the paper's T . V / |V|, T = (1, db/dtheta), b = (ell/kappa)|cos theta|, V = (omega, vz/kappa).
        slope = -(ELL / kappa) * math.sin(theta) * math.copysign(1.0, math.cos(theta))
        v = np.array([omega, vz / kappa])
        paper_p = (v[0] + slope * v[1]) / np.linalg.norm(v)
        assert expected_p == pytest.approx(paper_p, abs=1e-14)
        assert got[0] == pytest.approx(theta % math.pi, abs=1e-15)
        assert got[1] == pytest.approx(expected_p, abs=1e-14)


def test_floor_section_other_contacts():
    scene = jb.StickBetweenWalls2D(H, ELL)
    state = np.array([0.0, 1.2, 0.4, 0.0, 0.3, 0.2])
    for code in (3, -3, 0):
        assert np.all(np.isnan(np.asarray(floor_section(scene, state, code))))
    # A flat landing (both ends on the floor, contact 2): the mean tangent (1, 0), p = I omega / sqrt(2 I E').
    flat = np.array([0.0, 0.0, math.pi / 2, 0.0, 0.5, -0.3])
    got = np.asarray(floor_section(scene, flat, 2))
    assert got[0] == pytest.approx(math.pi / 2, abs=1e-15)
    assert got[1] == pytest.approx(-0.3 / math.sqrt(0.5**2 + 0.3**2), abs=1e-14)
    # A flat stick on the ceiling (contact 2) is not a floor collision.
    assert np.all(np.isnan(np.asarray(floor_section(scene, np.array([0.0, H, math.pi / 2, 0, -0.5, 0.1]), 2))))
    # A stick spanning the walls (2 ell > h), one end on each: the floor end's tangent.
    narrow = jb.StickBetweenWalls2D(1.5, 1.0)
    theta = math.acos(0.75)
    span = np.array([0.0, 0.75, theta, 0.0, 0.2, 0.4])
    got = np.asarray(floor_section(narrow, span, 2))
    e_int = 0.5 * 0.2**2 + 0.5 * 0.4**2
    assert got[1] == pytest.approx((0.4 - math.sin(theta) * 0.2) / math.sqrt(2 * e_int), abs=1e-14)


def test_floor_section_mirror_symmetry():
    """x -> -x (theta -> -theta, omega -> -omega, vx -> -vx) maps (theta, p) to (pi - theta, -p) mod pi."""
    scene = jb.StickBetweenWalls2D(H, ELL)
    rng = np.random.default_rng(3)
    for _ in range(5):
        theta = rng.uniform(-math.pi, math.pi)
        end = -1 if math.cos(theta) > 0 else 1
        state = np.array([0.1, ELL * abs(math.cos(theta)), theta, 0.2, rng.uniform(0.1, 1), rng.normal()])
        mirror = state * np.array([-1, 1, -1, -1, 1, -1])
        a = np.asarray(floor_section(scene, state, end))
        b = np.asarray(floor_section(scene, mirror, end))
        assert (a[0] + b[0]) % math.pi == pytest.approx(0.0, abs=1e-12) or (a[0] + b[0]) == pytest.approx(math.pi)
        assert b[1] == pytest.approx(-a[1], abs=1e-14)


def test_reduced_wall_section_hand_worked():
    mass, inertia = 1.5, 0.6
    scene = jb.StickBetweenWalls3D(H, ELL, mass=mass, inertia=inertia)
    for theta, phi, theta_dot, phi_dot, vz in [(0.7, 1.1, 0.4, -0.9, 0.5), (2.2, -2.0, -0.3, 0.6, 0.2)]:
        lower = -1 if math.cos(theta) > 0 else 1
        state = polar_state(theta, phi, theta_dot, phi_dot, ELL * abs(math.cos(theta)), vz, ELL, vxy=(0.3, -0.8))
        got = np.asarray(reduced_wall_section(scene, state, lower))
        e_int = 0.5 * mass * vz**2 + 0.5 * inertia * (theta_dot**2 + math.sin(theta) ** 2 * phi_dot**2)
        # z = -e ell cos(theta) on the floor, dz/dtheta = e ell sin(theta)
        expected = (inertia * theta_dot + mass * vz * lower * ELL * math.sin(theta)) / math.sqrt(2 * inertia * e_int)
        assert got[0] == pytest.approx(theta, abs=1e-14)
        assert got[1] == pytest.approx(expected, abs=1e-14)
        # The same stick with its ends relabelled (u -> -u, w unchanged): (pi - theta, -p).
        swapped = state.copy()
        swapped[3:6] *= -1
        other = np.asarray(reduced_wall_section(scene, swapped, -lower))
        assert other[0] == pytest.approx(math.pi - theta, abs=1e-14)
        assert other[1] == pytest.approx(-expected, abs=1e-14)
        # Turning the whole picture about the vertical changes nothing.
        turned = np.asarray(reduced_wall_section(scene, rotate_about_z(state, 0.83), lower))
        np.testing.assert_allclose(turned, got, rtol=0, atol=1e-14)


def test_polar_angle_is_accurate_at_the_vertical():
    scene = jb.StickBetweenWalls3D(H, ELL)
    tiny = 1e-12
    state = polar_state(tiny, 0.4, 0.3, 0.0, ELL * math.cos(tiny), 0.5, ELL)
    got = np.asarray(reduced_wall_section(scene, state, -1))
    assert got[0] == pytest.approx(tiny, rel=1e-9)  # arccos(u_z) would give ~1e-8 here
    e_int = 0.5 * 0.5**2 + 0.5 * 0.3**2
    assert got[1] == pytest.approx((0.3 - math.sin(tiny) * 0.5) / math.sqrt(2 * e_int), abs=1e-12)


# -- the inverse, the bounds and the seeds --------------------------------------------


@pytest.mark.parametrize("inertia", [None, 0.3])
def test_floor_state_inverts_the_sections(inertia):
    energy = 0.8
    theta = np.array([0.2, 1.0, 1.5, 2.3, 3.0])
    p = np.array([0.5, -1.1, 0.1, 0.9, -0.4])
    scene2 = jb.StickBetweenWalls2D(H, ELL, inertia=inertia)
    states = np.asarray(floor_state(scene2, theta, p, energy))
    lower = np.where(np.cos(theta) > 0, -1, 1)
    np.testing.assert_allclose(np.asarray(floor_section(scene2, states, lower)), np.stack([theta, p], 1), atol=1e-14)
    i2 = float(scene2.inertia)
    np.testing.assert_allclose(0.5 * states[:, 4] ** 2 + 0.5 * i2 * states[:, 5] ** 2, energy, rtol=1e-14)
    gaps = np.asarray(scene2.gaps(states))
    assert np.all(np.min(gaps[:, :2], axis=1) == 0.0) and np.all(gaps > -1e-15)
    # moving away from the floor: the touching end rises
    index = np.where(lower == 1, 0, 1)
    assert np.all(np.asarray(scene2.approach_speeds(states))[np.arange(5), index] < 0)

    scene3 = jb.StickBetweenWalls3D(H, ELL, inertia=inertia)
    spin = 0.5
    p3 = 0.5 * p
    states3 = np.asarray(floor_state(scene3, theta, p3, energy, spin))
    ok = np.isfinite(states3[:, 0])
    bound = np.asarray(floor_section_bound(scene3, theta, energy, spin))
    assert np.array_equal(ok, np.abs(p3) <= bound)
    got = np.asarray(reduced_wall_section(scene3, states3, lower))
    np.testing.assert_allclose(got[ok], np.stack([theta, p3], 1)[ok], atol=1e-14)
    i3 = float(scene3.inertia)
    np.testing.assert_allclose(i3 * states3[ok, 11], spin, rtol=1e-14)
    np.testing.assert_allclose(np.linalg.norm(states3[ok, 3:6], axis=1), 1.0, rtol=1e-15)
    assert np.all(np.abs(np.sum(states3[ok, 3:6] * states3[ok, 9:12], axis=1)) < 1e-15)
    e3 = 0.5 * states3[ok, 8] ** 2 + 0.5 * i3 * np.sum(states3[ok, 9:12] ** 2, axis=1)
    np.testing.assert_allclose(e3, energy, rtol=1e-14)


def test_section_bound_and_seeds():
    narrow = jb.StickBetweenWalls2D(1.5, 1.0)  # 2 ell > h: a floor only where |cos theta| <= 3/4
    theta = np.array([0.1, 0.5, 1.0, 1.5])
    bound = np.asarray(floor_section_bound(narrow, theta, 0.5))
    fits = 2 * np.abs(np.cos(theta)) <= 1.5
    assert np.array_equal(np.isfinite(bound), fits)
    np.testing.assert_allclose(bound[fits], np.sqrt(1 + np.sin(theta[fits]) ** 2), rtol=1e-15)
    seeds = np.asarray(floor_seeds(narrow, 50))
    assert seeds.shape == (50, 6) and np.all(np.isfinite(seeds))
    assert np.all(2 * np.abs(np.cos(seeds[:, 2])) <= 1.5)
    th, p = floor_seed_points(narrow, 50)
    np.testing.assert_allclose(seeds[:, 2], th, rtol=0, atol=0)
    assert np.all(np.abs(p) < np.sqrt(1 + np.sin(th) ** 2))
    # every seed is a valid start: inside the room, the touching end leaving the floor
    assert np.all(np.asarray(jax.vmap(narrow.is_valid)(jnp.asarray(seeds))))
    assert np.all(np.asarray(narrow.approach_speeds(seeds))[:, :2].min(axis=1) < 0)
    # 3D: spin keeps the stick off the vertical: 1 - spin^2 / (2 I E' sin^2) >= 0
    scene3 = jb.StickBetweenWalls3D(H, ELL)
    th3, _ = floor_seed_points(scene3, 40, 0.5, 0.6)
    assert np.all(np.sin(th3) ** 2 >= 0.36)


# -- the billiard picture: specular reflection in (theta, eta) ------------------------


def _wall_normal(fn, theta, step=1e-6):
    """Unit normal of the curve eta = fn(theta), by a central difference, pointing up (+eta)."""
    slope = (fn(theta + step) - fn(theta - step)) / (2 * step)
    normal = np.array([-slope, 1.0])
    return normal / np.linalg.norm(normal)


@pytest.mark.parametrize("inertia", [None, 0.3, 4.0])
@pytest.mark.parametrize("wall", ["floor", "ceiling"])
def test_impulse_is_a_specular_reflection_in_theta_eta(inertia, wall):
    scene = jb.StickBetweenWalls2D(H, ELL, inertia=inertia)
    kappa = math.sqrt(float(scene.inertia) / float(scene.mass))
    b = lambda th: (ELL / kappa) * np.abs(np.cos(th))  # noqa: E731  the paper's walls
    t = lambda th: (H - ELL * np.abs(np.cos(th))) / kappa  # noqa: E731
    rng = np.random.default_rng(11)
    for _ in range(6):
        theta = rng.uniform(-math.pi, math.pi)
        if abs(math.cos(theta)) < 0.05:
            continue  # away from the kinks
        on_floor = wall == "floor"
        eta = b(theta) if on_floor else t(theta)
        n = _wall_normal(b if on_floor else t, theta) * (1 if on_floor else -1)  # into the room
        # an incoming velocity in the (theta, eta) plane: V . n < 0
        v = rng.normal(size=2)
        if v @ n > 0:
            v -= 2 * (v @ n) * n
        v_reflected = v - 2 * (v @ n) * n
        omega, vz = v[0], kappa * v[1]
        tau = 1e-3
        start = np.array([0.2, kappa * eta - vz * tau, theta - omega * tau, 0.1, vz, omega])
        new, dt, contact = jb.collide(scene, jnp.asarray(start))
        assert float(dt) == pytest.approx(tau, rel=1e-9)
        assert abs(int(contact)) == (1 if on_floor else 3)
        after = np.array([float(new[5]), float(new[4]) / kappa])
        np.testing.assert_allclose(after, v_reflected, rtol=0, atol=1e-9)
        if on_floor and math.cos(theta) > 0:
            # the paper's closed form:
            # Delta eta_dot = -2 (eta_dot + (ell/kappa) theta_dot sin) / (1 + (ell/kappa)^2 sin^2)
            k = ELL / kappa * math.sin(theta)
            d_eta = -2 * (v[1] + k * v[0]) / (1 + k * k)
            np.testing.assert_allclose(after - v, [k * d_eta, d_eta], rtol=0, atol=1e-12)


@pytest.mark.parametrize("spin", [0.0, 0.45])
def test_3d_impulse_reflects_theta_eta_and_keeps_phi_dot(spin):
    """The paper's 3D result: with Delta phi_dot = 0, (theta_dot, z_dot/kappa) reflects off the same walls."""
    scene = jb.StickBetweenWalls3D(H, ELL, inertia=0.5)
    kappa = math.sqrt(0.5)
    b = lambda th: (ELL / kappa) * np.abs(np.cos(th))  # noqa: E731
    rng = np.random.default_rng(5)
    for theta in (0.6, 1.2, 2.4):
        n = _wall_normal(b, theta)
        v = rng.normal(size=2)
        if v @ n > 0:
            v -= 2 * (v @ n) * n
        phi_dot = spin / (0.5 * math.sin(theta) ** 2)
        contact_state = polar_state(theta, 0.3, v[0], phi_dot, ELL * abs(math.cos(theta)), kappa * v[1], ELL)
        tau = 1e-4
        start = np.asarray(jb.StickBetweenWalls3D(H, ELL, inertia=0.5).flight(jnp.asarray(contact_state), -tau))
        new, dt, contact = jb.collide(scene, jnp.asarray(start))
        assert float(dt) == pytest.approx(tau, rel=1e-8)
        new = np.asarray(new)
        u, w = new[3:6], new[9:12]
        polar = math.atan2(math.hypot(u[0], u[1]), u[2])
        assert polar == pytest.approx(theta, abs=1e-12)
        theta_dot = -(w[0] * u[1] - w[1] * u[0]) / math.hypot(u[0], u[1])
        reflected = v - 2 * (v @ n) * n
        np.testing.assert_allclose([theta_dot, new[8] / kappa], reflected, rtol=0, atol=1e-9)
        assert 0.5 * w[2] == pytest.approx(spin, abs=1e-13)  # I w_z = I sin^2 phi_dot: unchanged


def test_flat_landing_in_the_right_angled_kink_reverses_the_velocity():
    """For I = M ell^2 the floor's kink at theta = pi/2 is a right angle: a point entering it leaves with -V."""
    scene = jb.StickBetweenWalls2D(H, ELL)
    omega, vz, tau = 0.3, -0.8, 0.5  # |vz| > ell |omega|: inside the wedge, both ends land at t = tau
    start = np.array([0.0, -vz * tau, math.pi / 2 - omega * tau, 0.0, vz, omega])
    new, dt, contact = jb.collide(scene, jnp.asarray(start))
    assert int(contact) == 2
    assert float(dt) == pytest.approx(tau, rel=1e-12)
    np.testing.assert_allclose(np.asarray(new)[[4, 5]], [-vz, -omega], rtol=0, atol=1e-12)
    got = np.asarray(floor_section(scene, new, contact))
    assert got[0] == pytest.approx(math.pi / 2, abs=1e-12)
    assert got[1] == pytest.approx(-omega / math.hypot(omega, vz), abs=1e-12)


# -- area preservation ---------------------------------------------------------------


def _collisions_to_next_floor(scene, state):
    contacts = np.asarray(jb.orbit(scene, jnp.asarray(state), 40).contact)
    k = int(np.argmax(np.isin(contacts, (1, -1)))) + 1
    assert contacts[k - 1] in (1, -1) and 2 not in contacts[:k]
    return k


@jax.jit
def _floor_map_jacobian(scene, x, k, energy, spin):
    """Jacobian and value of (theta, p) -> (theta', p'), k collisions later (the k-th on the floor)."""
    section = reduced_wall_section if scene.state_size == 12 else floor_section

    def f(x):
        if scene.state_size == 12:
            state = floor_state(scene, x[0], x[1], energy, spin)
        else:
            state = floor_state(scene, x[0], x[1], energy)

        def step(_, carry):
            state, _, contact = jb.collide(scene, carry[0])
            return state, contact

        state, contact = jax.lax.fori_loop(0, k, step, (state, jnp.int32(0)))
        y = section(scene, state, contact)
        return y, y

    return jax.jacfwd(f, has_aux=True)(x)


def _check_map(scene, x0, energy, spin=0.0):
    """Jacobian and image of the floor-to-floor map at x0, the image checked against the orbit."""
    state0 = np.asarray(floor_state(scene, x0[0], x0[1], energy, spin) if spin else floor_state(scene, *x0, energy))
    k = _collisions_to_next_floor(scene, state0)
    jac, y = _floor_map_jacobian(scene, jnp.asarray(x0), k, energy, spin)
    orb = jb.orbit(scene, state0, 40)
    section = reduced_wall_section if scene.state_size == 12 else floor_section
    np.testing.assert_allclose(
        np.asarray(y), np.asarray(section(scene, orb.state[k - 1], orb.contact[k - 1])), rtol=0, atol=1e-12
    )
    return np.asarray(jac), np.asarray(y), state0


@pytest.mark.parametrize("h, inertia", [(3.0, None), (1.5, None), (2.5, 0.4)])
def test_floor_map_preserves_area_in_theta_p_only(h, inertia):
    scene = jb.StickBetweenWalls2D(h, ELL, inertia=inertia)
    kappa = math.sqrt(float(scene.inertia) / float(scene.mass))
    energy = 0.5
    theta, p = floor_seed_points(scene, 4, energy, offset=7)
    for x0 in zip(theta, p):
        jac, y, state0 = _check_map(scene, x0, energy)
        assert np.linalg.det(jac) == pytest.approx(1.0, abs=1e-9)

        # The same map in (theta, q = theta_dot/|V|) and in (theta, sigma = Birkhoff sine), by the chain rule
        # through the changes of coordinates: not area-preserving.
        def slope(th):
            return -(ELL / kappa) * jnp.sin(th) * jnp.sign(jnp.cos(th))

        rising = 1.0 if state0[4] > 0 else -1.0  # the sign of eta_dot at the start (a steep floor allows both)

        def p_of_q(x):  # (theta, q) -> (theta, p): V/|V| = (q, +-sqrt(1 - q^2)), p = T . V/|V|
            return jnp.stack([x[0], x[1] + slope(x[0]) * rising * jnp.sqrt(1 - x[1] ** 2)])

        def q_of_p(x):  # (theta, p) -> (theta, q): V/|V| = (p T + sqrt(|T|^2 - p^2) N) / |T|^2, N = (-slope, 1)
            t2 = 1 + slope(x[0]) ** 2
            return jnp.stack([x[0], (x[1] - jnp.sqrt(t2 - x[1] ** 2) * slope(x[0])) / t2])

        def sigma_of_p(x):
            return jnp.stack([x[0], x[1] / jnp.sqrt(1 + slope(x[0]) ** 2)])

        def p_of_sigma(x):
            return jnp.stack([x[0], x[1] * jnp.sqrt(1 + slope(x[0]) ** 2)])

        q0 = q_of_p(jnp.asarray(x0))
        np.testing.assert_allclose(np.asarray(p_of_q(q0)), x0, atol=1e-14)  # the charts are each other's inverses
        det_q = (
            np.linalg.det(np.asarray(jax.jacfwd(q_of_p)(jnp.asarray(y))))
            * np.linalg.det(jac)
            * np.linalg.det(np.asarray(jax.jacfwd(p_of_q)(q0)))
        )
        s0 = sigma_of_p(jnp.asarray(x0))
        det_sigma = (
            np.linalg.det(np.asarray(jax.jacfwd(sigma_of_p)(jnp.asarray(y))))
            * np.linalg.det(jac)
            * np.linalg.det(np.asarray(jax.jacfwd(p_of_sigma)(s0)))
        )
        # Birkhoff's sine goes with the arc length ds = |T| dtheta: the determinant is |T(theta)| / |T(theta')|
        t_ratio = math.sqrt(1 + float(slope(x0[0])) ** 2) / math.sqrt(1 + float(slope(y[0])) ** 2)
        assert det_sigma == pytest.approx(t_ratio, rel=1e-9)
        if abs(t_ratio - 1) > 1e-3:
            assert abs(det_sigma - 1) > 1e-4
        assert abs(det_q - 1) > 1e-4


def test_3d_reduced_map_preserves_area_at_fixed_spin():
    scene = jb.StickBetweenWalls3D(H, ELL)
    energy, spin = 0.5, 0.55
    theta, p = floor_seed_points(scene, 3, energy, spin, offset=5)
    for x0 in zip(theta, p):
        jac, _, _ = _check_map(scene, x0, energy, spin)
        assert np.linalg.det(jac) == pytest.approx(1.0, abs=1e-9)


def test_ergodic_orbit_has_the_uniform_measure_of_theta_p():
    """An orbit of the chaotic 2D stick visits theta with density |T(theta)| / int |T|, the projection of dtheta dp."""
    scene = jb.StickBetweenWalls2D(H, ELL)
    state, pieces = floor_seeds(scene, 1)[0], []
    for _ in range(200):  # 40000 collisions in runs of 200 (the length the other tests compile)
        orb = jb.orbit(scene, state, 200)
        pieces.append(np.asarray(floor_section(scene, orb.state, orb.contact)))
        state = orb.state[-1]
    pts = np.concatenate(pieces)
    pts = pts[np.isfinite(pts[:, 0])]
    assert len(pts) > 15_000
    edges = np.linspace(0, np.pi, 9)
    counts, _ = np.histogram(pts[:, 0], edges)
    fine = np.linspace(0, np.pi, 8001)
    weight = np.sqrt(1 + np.sin(fine) ** 2)
    expected = np.array(
        [
            np.trapezoid(weight[(fine >= a) & (fine <= b)], fine[(fine >= a) & (fine <= b)])
            for a, b in zip(edges[:-1], edges[1:])
        ]
    )
    expected /= expected.sum()
    np.testing.assert_allclose(counts / counts.sum(), expected, rtol=0.06)
    # and, at fixed theta, p is uniform: the mean of |p| / |T| is 1/2
    assert np.mean(np.abs(pts[:, 1]) / np.sqrt(1 + np.sin(pts[:, 0]) ** 2)) == pytest.approx(0.5, abs=0.015)


# -- 3D with L_z = 0 is the 2D scene -----------------------------------------------


@pytest.mark.parametrize("h", [3.0, 1.5])
def test_3d_section_at_zero_lz_equals_the_2d_section(h):
    s2, s3 = jb.StickBetweenWalls2D(h, ELL), jb.StickBetweenWalls3D(h, ELL)
    orb2 = jb.orbit(s2, floor_seeds(s2, 1)[0], 200)
    states2, contacts = np.asarray(orb2.state), np.asarray(orb2.contact)
    sec2 = np.asarray(floor_section(s2, states2, contacts))
    on_floor = np.isfinite(sec2[:, 0])
    assert 50 < on_floor.sum() < 150
    for angle in (0.0, 1.9):  # the x-z plane, and a vertical plane turned about z
        states3 = rotate_about_z(embed(states2), angle)
        sec3 = np.asarray(reduced_wall_section(s3, states3, contacts))
        assert np.array_equal(np.isfinite(sec3[:, 0]), on_floor)
        # the polar angle is |theta_2D|: equal for sin(theta) >= 0, mirrored (pi - theta, -p) otherwise
        mirrored = np.sin(states2[:, 2]) < 0
        expected = np.where(mirrored[:, None], np.stack([np.pi - sec2[:, 0], -sec2[:, 1]], 1), sec2)
        np.testing.assert_allclose(sec3[on_floor], expected[on_floor], rtol=0, atol=1e-12)
        if h < 2 * ELL:  # the stick cannot pass the vertical: no mirroring at all
            assert not mirrored.any()
        # collision by collision: the 3D map from each 2D state lands on the next 2D section point
        m = 60
        steps = [jb.collide(s3, jnp.asarray(state)) for state in states3[:m]]
        new3 = np.stack([np.asarray(step[0]) for step in steps])
        c3 = np.array([int(step[2]) for step in steps])
        assert np.array_equal(c3, contacts[1 : m + 1])
        sec3_next = np.asarray(reduced_wall_section(s3, new3, c3))
        np.testing.assert_allclose(
            sec3_next[on_floor[1 : m + 1]], expected[1 : m + 1][on_floor[1 : m + 1]], rtol=0, atol=1e-10
        )


# -- the reduced picture's flights ----------------------------------------------------


def test_theta_z_path_conserves_the_reduced_energy_with_the_lz_potential():
    """Along a 3D flight, (I/2) theta_dot^2 + (M/2) z_dot^2 + (I w_z)^2 / (2 I sin^2 theta) = E' (paper's eq. 20)."""
    scene = jb.StickBetweenWalls3D(H, ELL, mass=1.3, inertia=0.7)
    kappa = math.sqrt(0.7 / 1.3)
    state = polar_state(1.0, 0.2, 0.5, 1.4, 1.5, 0.3, ELL)
    spin = 0.7 * state[11]
    e_int = 0.5 * 1.3 * 0.3**2 + 0.5 * 0.7 * float(np.sum(state[9:12] ** 2))
    t = np.linspace(0.0, 2.0, 2001)
    path = np.asarray(theta_z_path(scene, state, t))
    theta = path[:, 0] / kappa
    theta_dot = np.gradient(theta, t, edge_order=2)
    z_dot = np.gradient(path[:, 1], t, edge_order=2)
    reduced = 0.5 * 0.7 * theta_dot**2 + 0.5 * 1.3 * z_dot**2 + spin**2 / (2 * 0.7 * np.sin(theta) ** 2)
    np.testing.assert_allclose(reduced[5:-5], e_int, rtol=1e-5)
    # curved: theta is not linear in time
    assert np.ptp(theta_dot) > 0.1
    # without spin about the vertical (L_z = 0) the same start flies straight in (kappa theta, z)
    flat = polar_state(1.0, 0.2, 0.5, 0.0, 1.5, 0.3, ELL)
    line = np.asarray(theta_z_path(scene, flat, np.linspace(0.0, 1.0, 50)))
    np.testing.assert_allclose(np.diff(line[:, 0]), kappa * 0.5 / 49, rtol=1e-12)
    np.testing.assert_allclose(np.diff(line[:, 1]), 0.3 / 49, rtol=1e-12)


def test_flight_paths_join_the_collisions():
    scene = jb.StickBetweenWalls3D(H, ELL)
    state0 = np.asarray(floor_seeds(scene, 1, 0.5, 0.5))[0]
    orb = jb.orbit(scene, state0, 40)
    paths = flight_paths(scene, state0, orb, 30)
    assert paths.shape == (40, 30, 2)
    states = np.asarray(orb.state)
    ends = np.stack([np.arctan2(np.hypot(states[:, 3], states[:, 4]), states[:, 5]), states[:, 2]], 1)
    np.testing.assert_allclose(paths[:, -1], ends, atol=1e-10)
    np.testing.assert_allclose(paths[1:, 0], paths[:-1, -1], atol=1e-10)
    # every path point is inside the room: floor <= z <= ceiling at its theta
    reach = ELL * np.abs(np.cos(paths[..., 0]))
    assert np.all(paths[..., 1] >= reach - 1e-10) and np.all(paths[..., 1] <= H - reach + 1e-10)


def test_twins_keep_energy_and_spin_and_part_for_the_chaotic_2d_stick():
    scene3 = jb.StickBetweenWalls3D(H, ELL)
    s3 = np.asarray(floor_seeds(scene3, 3, 0.5, 0.4))
    t3 = wall_twin_states(scene3, s3, 1e-6)
    e = lambda s: 0.5 * s[:, 8] ** 2 + 0.5 * np.sum(s[:, 9:12] ** 2, axis=1)  # noqa: E731
    np.testing.assert_allclose(e(t3), e(s3), rtol=1e-14)
    np.testing.assert_allclose(t3[:, 11], s3[:, 11], rtol=1e-14)
    assert np.allclose(np.sum(t3[:, 3:6] * t3[:, 9:12], axis=1), 0.0, atol=1e-15)
    assert np.all(np.abs(t3[:, 8] - s3[:, 8]) > 1e-8)
    # a stick exactly vertical: the polar rate is |w|, and the twin keeps E' there too
    vertical = polar_state(0.0, 0.0, 0.4, 0.0, ELL, 0.3, ELL)
    twin = wall_twin_states(scene3, vertical, 1e-3)[0]
    assert e(twin[None])[0] == pytest.approx(e(vertical[None])[0], rel=1e-14)
    turn = math.atan2(0.3, 0.4) - math.atan2(twin[8], np.linalg.norm(twin[9:12]))
    assert turn == pytest.approx(-1e-3, rel=1e-9)
    # the 2D stick between walls is a dispersing billiard: every twin pair parts to order one
    scene2 = jb.StickBetweenWalls2D(H, ELL)
    s2 = np.asarray(floor_seeds(scene2, 8))
    runs = [np.asarray(jb.orbit(scene2, s, 200).state) for s in np.concatenate([s2, wall_twin_states(scene2, s2)])]
    d = wall_twin_distances(scene2, np.stack(runs[:8]), np.stack(runs[8:]), s2)
    assert d[:, 0].max() < 1e-9
    assert np.all(d[:, -30:].max(axis=1) > 0.1)


def test_bad_use_raises():
    still = jb.StickBetweenWalls2D(H, ELL, inertia=math.inf)
    with pytest.raises(ValueError, match="turns"):
        floor_section(still, np.zeros(6), 1)
    with pytest.raises(ValueError, match="spin must be 0"):
        floor_state(jb.StickBetweenWalls2D(H, ELL), 0.3, 0.1, 0.5, 0.2)
    with pytest.raises(ValueError, match="StickBetweenWalls3D"):
        reduced_wall_section(jb.StickBetweenWalls2D(H, ELL), np.zeros(6), 1)
    with pytest.raises(ValueError, match="StickBetweenWalls2D"):
        floor_section(jb.StickBetweenWalls3D(H, ELL), np.zeros(12), 1)
