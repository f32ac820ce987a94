r"""Tangent maps, Lyapunov spectra and periodic orbits of the sticks between walls.

Reference values come from finite differences, symmetries, conservation laws,
the 2D <-> 3D embedding and the closed form below, never from jaxbill itself.

The vertical bounce, derived by hand
------------------------------------
The stick stands vertical (``theta = 0``, ``omega = 0``) and its centre moves
up and down with speed ``V``: P1 hits the ceiling with the centre at ``h -
ell``, P2 the floor with the centre at ``ell``; each flight takes ``T = (h - 2
ell) / V`` and one period (floor, then ceiling) ``2 T``.

Linearise in ``(theta, omega)``. The contact heights ``z +- ell cos theta``
change only at second order in ``theta``, so the flight time and ``(z, vz)``
decouple at first order. A flight is ``theta' = theta + T omega``. At the
ceiling (end P1, ``e = +1``) the lever is ``s = dz_1/dtheta = -ell sin theta ~
-ell theta`` and the impulse ``J = -2 (vz + s omega) / (1/M + s^2/I) ~ -2 M V``,
so ``omega' = omega + s J / I = omega + c theta`` with ``c = 2 M V ell / I``.
At the floor (end P2, ``e = -1``, ``vz = -V``): ``s ~ +ell theta``, ``J ~ +2 M
V``, the same ``omega' = omega + c theta``. (The wall pushes the tilted end
further over: both kicks defocus.) So one flight and one kick is

    B = [[1, 0], [c, 1]] @ [[1, T], [0, 1]],     tr B = 2 + c T = 2 + 2 M ell (h - 2 ell) / I,

independent of ``V``, and the period (two bounces) has the monodromy ``B^2``
with ``tr B^2 = (tr B)^2 - 2``. ``tr B > 2`` whenever ``h > 2 ell``: the
vertical bounce is **always hyperbolic** (never stable); only ``I -> inf``
(a stick that cannot turn) makes it parabolic. In the billiard picture
``(theta, eta = z/kappa)``, ``I = M kappa^2``, both walls bulge into the
table at ``theta = 0`` with radius of curvature ``kappa / ell``, a distance
``(h - 2 ell)/kappa`` apart: two dispersing mirrors, whose two-bounce orbit has
``tr = 2 + 2 L / rho`` per bounce, the same formula.

Its Lyapunov exponents follow: per bounce the multiplier ``mu_b = (tr B +
sqrt(tr B^2 - 4)) / 2``, so ``lambda = log(mu_b) / T`` per unit time. In 2D the
flow spectrum along it is ``{lambda, 0, 0, -lambda}``; in 3D the tilts in the
``x``-``z`` and ``y``-``z`` planes are two copies of the same block (rotation
about the vertical leaves the orbit fixed): ``{lambda, lambda, 0, 0, -lambda,
-lambda}``, and the 3D period-2 monodromy has the eigenvalues ``mu, mu, 1/mu,
1/mu`` and 1 (the energy direction).
"""

from __future__ import annotations

import math

import jax
import jax.numpy as jnp
import numpy as np
import pytest

import jaxbill as jb
from jaxbill._engine.collision import collide_unchecked
from jaxbill._engine.tangent import dynamical_frame, tangent_map

FD_STEP = 1e-6
FD_RTOL = 1e-6
N = 10000

_map_jit = jax.jit(lambda sc, s: collide_unchecked(sc, s)[:2])
_frame_jit = jax.jit(dynamical_frame)


@jax.jit
def _maps(scene, s):
    """``(new_state, DP, D phi, DP by reverse mode, f(s), f(s'))`` in one compilation."""
    new, _, _, dp = tangent_map(scene, s)
    dphi = tangent_map(scene, s, flow=True)[3]
    dp_rev = tangent_map(scene, s, mode="reverse")[3]
    return new, dp, dphi, dp_rev, jb.phase_velocity(scene, s), jb.phase_velocity(scene, new)


@jax.jit
def _next_contact(scene, s):
    """Flight time, contact, and the gaps and approach speeds just before the contact."""
    _, dt, contact = collide_unchecked(scene, s)
    pre = scene.flight(s, jnp.where(jnp.isfinite(dt), dt, 0.0))
    return dt, contact, scene.gaps(s), scene.gaps(pre), scene.approach_speeds(pre)


def embed(state2d) -> np.ndarray:
    """The 2D state ``[x, z, th, vx, vz, om]`` as a 3D state in the x-z plane.

    The embedding is the one in ``StickBetweenWalls3D``'s docstring.
    """
    x, z, th, vx, vz, om = np.asarray(state2d, dtype=np.float64)
    return np.array([x, 0.0, z, np.sin(th), 0.0, np.cos(th), vx, 0.0, vz, 0.0, om, 0.0])


def embed_tangent(theta) -> np.ndarray:
    """Jacobian ``(12, 6)`` of ``embed`` at angle ``theta``."""
    d = np.zeros((12, 6))
    d[0, 0] = d[2, 1] = d[6, 3] = d[8, 4] = d[10, 5] = 1.0
    d[3, 2], d[5, 2] = np.cos(theta), -np.sin(theta)
    return d


def retract(state):
    """Back onto ``|u| = 1``, ``w . u = 0`` (second order for a tangent perturbation)."""
    s = np.array(state, dtype=np.float64)
    if s.shape[0] == 12:
        s[3:6] /= np.linalg.norm(s[3:6])
        s[9:12] -= (s[9:12] @ s[3:6]) * s[3:6]
    return s


def random_state(scene, rng):
    h, ell = float(scene.h), float(scene.ell)
    speed_dir = rng.normal(size=3 if scene.state_size == 12 else 2)
    v = speed_dir / np.linalg.norm(speed_dir)
    if scene.state_size == 6:
        th = rng.uniform(-np.pi, np.pi)
        reach = ell * abs(np.cos(th))
        z = rng.uniform(reach + 0.02 * h, h - reach - 0.02 * h)
        return np.array([0.1, z, th, v[0], v[1], rng.uniform(-1, 1) * 0.6 / ell])
    u = rng.normal(size=3)
    u /= np.linalg.norm(u)
    w = rng.normal(size=3) * 0.6 / ell
    w -= (w @ u) * u
    reach = ell * abs(u[2])
    z = rng.uniform(reach + 0.02 * h, h - reach - 0.02 * h)
    return np.array([0.1, -0.2, z, *u, *v, *w])


def well_conditioned_states(scene, count, seed):
    """Random states whose next contact is a single, clearly non-grazing one: the
    touching end approaches at >= 0.2 of ``|vz| + ell |spin|``, the other end stays
    >= 0.05 h from both walls, and the flight lasts >= 0.05 h / speed."""
    rng = np.random.default_rng(seed)
    h, ell = float(scene.h), float(scene.ell)
    out = []
    while len(out) < count:
        s = random_state(scene, rng)
        dt, contact, gaps_now, gaps, speeds = (np.asarray(a) for a in _next_contact(scene, jnp.asarray(s)))
        dt, contact = float(dt), int(contact)
        if gaps_now.min() < 0.01 * h or contact not in (1, -1, 3, -3) or dt < 0.05 * h:
            continue
        gap = {1: 0, -1: 1, 3: 2, -3: 3}[contact]
        spin = np.linalg.norm(s[9:12]) if s.shape[0] == 12 else abs(s[5])
        vz = s[8] if s.shape[0] == 12 else s[4]
        if speeds[gap] < 0.2 * (abs(vz) + ell * spin):
            continue
        other = 1 - gap % 2
        if min(gaps[other], gaps[other + 2]) < 0.05 * h:
            continue
        out.append(s)
    return out


def directions(scene, s):
    """Tangent directions to test: the dynamical frame and the horizontal coordinates."""
    frame = np.asarray(_frame_jit(scene, jnp.asarray(s)))
    horizontal = [0, 3] if scene.state_size == 6 else [0, 1, 6, 7]
    return np.concatenate([frame, np.eye(scene.state_size)[:, horizontal]], axis=1)


def central_difference(scene, s, d):
    plus, t_plus = _map_jit(scene, jnp.asarray(retract(s + FD_STEP * d)))
    minus, t_minus = _map_jit(scene, jnp.asarray(retract(s - FD_STEP * d)))
    diff = np.asarray(plus) - np.asarray(minus)
    if scene.state_size == 6:
        diff[2] = (diff[2] + np.pi) % (2 * np.pi) - np.pi  # theta is wrapped
    return diff / (2 * FD_STEP), (float(t_plus) - float(t_minus)) / (2 * FD_STEP)


SCENE_2D = jb.StickBetweenWalls2D(3.0, 1.0)
SCENE_2D_WEIGHTED = jb.StickBetweenWalls2D(2.5, 1.0, mass=2.0, inertia=0.5)
SCENE_3D = jb.StickBetweenWalls3D(3.0, 1.0)


@pytest.mark.parametrize("scene", [SCENE_2D, SCENE_2D_WEIGHTED, SCENE_3D], ids=["2d", "2d-weighted", "3d"])
def test_tangent_maps_match_central_differences_and_reverse_mode(scene):
    for s in well_conditioned_states(scene, 3, seed=1):
        _, dp, dphi, dp_rev, _, f_new = (np.asarray(a) for a in _maps(scene, jnp.asarray(s)))
        np.testing.assert_allclose(dp_rev, dp, rtol=0, atol=1e-12 * np.abs(dp).max())
        for d in directions(scene, s).T:
            fd, fd_time = central_difference(scene, s, d)
            scale = np.abs(np.asarray(dp) @ d).max()
            assert np.abs(np.asarray(dp) @ d - fd).max() <= FD_RTOL * scale
            assert np.abs(np.asarray(dphi) @ d - (fd - f_new * fd_time)).max() <= FD_RTOL * scale


@pytest.mark.parametrize("scene", [SCENE_2D, SCENE_2D_WEIGHTED], ids=["2d", "2d-weighted"])
def test_2d_flow_tangent_is_symplectic_and_carries_the_flow(scene):
    """In ``(z, theta, M vz, I omega)`` the flow map is symplectic; ``DP f = 0``, ``D phi f = f'``."""
    idx = list(jb.dynamical_indices(scene))
    assert idx == [1, 2, 4, 5]
    weights = np.array([1.0, 1.0, float(scene.mass), float(scene.inertia)])
    omega = np.block([[np.zeros((2, 2)), np.eye(2)], [-np.eye(2), np.zeros((2, 2))]])
    for s in well_conditioned_states(scene, 3, seed=2):
        _, dp, dphi, _, f, f_new = (np.asarray(a) for a in _maps(scene, jnp.asarray(s)))
        np.testing.assert_allclose(f, [s[3], s[4], s[5], 0, 0, 0])
        scale = np.abs(dphi).max()
        assert np.abs(dp @ f).max() <= 1e-12 * scale
        assert np.abs(dphi @ f - f_new).max() <= 1e-12 * scale
        sub = dphi[np.ix_(idx, idx)]
        canonical = weights[:, None] * sub / weights[None, :]
        np.testing.assert_allclose(canonical.T @ omega @ canonical, omega, atol=1e-11 * scale**2)
        # x and vx decouple: no dynamical perturbation reaches them in the flow map.
        assert np.abs(dphi[np.ix_([0, 3], idx)]).max() <= 1e-12 * scale


def test_3d_tangent_map_in_the_plane_is_the_2d_one_and_stays_on_the_constraints():
    scene2, scene3 = SCENE_2D, SCENE_3D
    for s in well_conditioned_states(scene2, 3, seed=3):
        new2, _, j2, _, _, _ = (np.asarray(a) for a in _maps(scene2, jnp.asarray(s)))
        new3, _, j3, _, _, _ = (np.asarray(a) for a in _maps(scene3, jnp.asarray(embed(s))))
        np.testing.assert_allclose(new3, embed(new2), atol=1e-13)
        lhs = j3 @ embed_tangent(s[2])
        rhs = embed_tangent(float(new2[2])) @ j2
        np.testing.assert_allclose(lhs, rhs, atol=1e-11 * np.abs(rhs).max())
    for s in well_conditioned_states(scene3, 3, seed=4):
        new, _, j, _, f, _ = (np.asarray(a) for a in _maps(scene3, jnp.asarray(s)))
        np.testing.assert_allclose(f, np.concatenate([s[6:9], np.cross(s[9:12], s[3:6]), np.zeros(6)]))
        frame = np.asarray(_frame_jit(scene3, jnp.asarray(s)))
        np.testing.assert_allclose(frame.T @ frame, np.eye(6), atol=1e-14)
        images = np.asarray(j) @ frame
        u, w = np.asarray(new[3:6]), np.asarray(new[9:12])
        # Images stay tangent to |u| = 1, w . u = 0, and the frame at the new state spans them.
        assert np.abs(u @ images[3:6]).max() <= 1e-12 * np.abs(images).max()
        assert np.abs(w @ images[3:6] + u @ images[9:12]).max() <= 1e-12 * np.abs(images).max()
        new_frame = np.asarray(_frame_jit(scene3, jnp.asarray(new)))
        dyn = [2, 3, 4, 5, 8, 9, 10, 11]
        rest = images[dyn] - new_frame[dyn] @ (new_frame.T @ images)
        assert np.abs(rest).max() <= 1e-12 * np.abs(images).max()


def _tol(n, t):
    return 2.0 * np.log(n) / t


def _assert_paired_with_zeros(sp, zeros):
    for n, t, est in zip(np.asarray(sp.collisions), np.asarray(sp.times), np.asarray(sp.history)):
        tol = _tol(n, t)
        assert np.abs(est + est[::-1]).max() <= tol, (n, est)
        middle = est[1:-1]
        assert middle.size == zeros and np.abs(middle).max() <= tol, (n, middle, tol)


CHAOTIC_2D = [0.2, 1.5, 0.3, 0.1, 0.7, 1.1]


def _generic_3d_start():
    """A chaotic start out of every vertical plane."""
    u = np.array([0.3, 0.4, 0.866])
    u /= np.linalg.norm(u)
    w = np.array([0.5, -0.2, 0.1])
    w -= (w @ u) * u
    return np.array([0.1, -0.2, 1.5, *u, 0.1, 0.2, 0.7, *w])


@pytest.fixture(scope="module")
def chaotic_spectra():
    """Every vector carried (``paired=False``): the pairing and the zeros are measured."""
    s2 = jnp.asarray(CHAOTIC_2D)
    generic = _generic_3d_start()
    return (
        jb.lyapunov_spectrum(SCENE_2D, s2, N, n_history=5, paired=False),
        jb.lyapunov_spectrum(SCENE_3D, jnp.asarray(embed(CHAOTIC_2D)), N, n_history=5, paired=False),
        jb.lyapunov_spectrum(SCENE_3D, jnp.asarray(generic), N, n_history=5, paired=False),
        jb.lyapunov_spectrum(SCENE_3D, jnp.asarray(generic), N, n_history=5, per="collision", paired=False),
    )


def test_flow_spectra_pair_and_have_the_expected_zeros(chaotic_spectra):
    sp2, sp3_plane, sp3, _ = chaotic_spectra
    assert sp2.exponents.shape == (4,) and sp3.exponents.shape == (6,)
    _assert_paired_with_zeros(sp2, 2)  # time shift, energy
    _assert_paired_with_zeros(sp3_plane, 4)  # and L_z (w_z), rotation about the vertical
    _assert_paired_with_zeros(sp3, 4)
    lam2 = float(sp2.exponents[0])
    assert lam2 > 0.1 and float(sp3.exponents[0]) > 0.1
    # In the x-z plane the 3D orbit is the 2D one (the two part after a few
    # dozen collisions by rounding, so: the same exponent up to sampling error).
    np.testing.assert_allclose(float(sp3_plane.exponents[0]), lam2, rtol=0.05)


def test_the_paired_3d_spectrum_agrees_with_the_full_one(chaotic_spectra):
    """The 3D stick's flow in its dynamical frame (u and w on their constraint manifold) pairs as
    its ``symplectic_flow`` says: three vectors and their partners agree with six vectors within the
    finite-time estimate of a zero exponent, at every checkpoint (a lost pair would miss by 2 lambda)."""
    _, _, full, _ = chaotic_spectra
    paired = jb.lyapunov_spectrum(SCENE_3D, jnp.asarray(_generic_3d_start()), N, n_history=5, paired=True)
    assert paired.exponents.shape == (6,)
    for n, t, a, b in zip(
        np.asarray(full.collisions), np.asarray(full.times), np.asarray(paired.history), np.asarray(full.history)
    ):
        assert np.abs(a - b).max() <= _tol(n, t), (n, a, b)


def test_3d_section_map_spectrum(chaotic_spectra):
    _, _, per_time, per_coll = chaotic_spectra
    lam = np.asarray(per_coll.exponents)
    assert lam.shape == (5,)
    assert np.abs(lam + lam[::-1]).max() <= 2 * np.log(N) / N and np.abs(lam[1:-1]).max() <= 2 * np.log(N) / N
    mean_flight = float(per_time.time) / N
    np.testing.assert_allclose(lam[0], float(per_time.exponents[0]) * mean_flight, rtol=1e-3)


def bounce_trace(h, ell, mass, inertia):
    """``tr B`` of one flight and one kick of the vertical bounce (module docstring)."""
    return 2.0 + 2.0 * mass * ell * (h - 2.0 * ell) / inertia


def test_vertical_bounce_lyapunov_exponents_match_the_closed_form():
    h, ell, speed = 3.0, 1.0, 1.3
    tr = bounce_trace(h, ell, 1.0, ell**2)
    lam = math.log((tr + math.sqrt(tr * tr - 4.0)) / 2.0) / ((h - 2 * ell) / speed)
    # Every vector carried: the negative exponents measured, not mirrored.
    sp2 = jb.lyapunov_spectrum(SCENE_2D, jnp.asarray([0.0, 1.5, 0.0, 0.2, speed, 0.0]), N, n_history=5, paired=False)
    state3 = embed([0.0, 1.5, 0.0, 0.2, speed, 0.0])
    sp3 = jb.lyapunov_spectrum(SCENE_3D, jnp.asarray(state3), N, n_history=5, paired=False)
    t2, t3 = float(sp2.time), float(sp3.time)
    np.testing.assert_allclose(np.asarray(sp2.exponents)[[0, 3]], [lam, -lam], rtol=1e-3)
    assert np.abs(np.asarray(sp2.exponents)[1:3]).max() <= _tol(N, t2)
    np.testing.assert_allclose(np.asarray(sp3.exponents)[[0, 1, 4, 5]], [lam, lam, -lam, -lam], rtol=1e-3)
    assert np.abs(np.asarray(sp3.exponents)[2:4]).max() <= _tol(N, t3)
    ftle = jb.finite_time_lyapunov(SCENE_2D, jnp.asarray([[0.0, 1.5, 0.0, 0.2, speed, 0.0]]), 2000)
    np.testing.assert_allclose(float(ftle.per_time[0]), lam, rtol=1e-2)


VERTICAL_CASES = [  # h, ell, mass, inertia: tr B^2 = 14, 26.4, 23, 2.41 (nearly parabolic)
    (3.0, 1.0, 1.0, None),
    (2.5, 1.0, 1.0, 0.3),
    (4.0, 0.5, 2.0, 2.0),
    (3.0, 1.0, 1.0, 20.0),
]


@pytest.mark.parametrize("h,ell,mass,inertia", VERTICAL_CASES)
def test_2d_vertical_bounce_from_a_perturbed_guess(h, ell, mass, inertia):
    scene = jb.StickBetweenWalls2D(h, ell, mass=mass, inertia=inertia)
    guess = np.array([0.0, h / 2, 0.01, 0.2, 1.0, 0.01])
    orbit = jb.find_periodic_orbit(scene, guess, 2)
    assert bool(orbit.converged) and float(orbit.residual) < 1e-12
    s = np.asarray(orbit.state)
    assert abs(s[2]) < 1e-12 and abs(s[5]) < 1e-12
    assert sorted(np.asarray(orbit.contacts).tolist()) == [-1, 3]
    energy = float(jb.energy(scene, guess))
    speed = math.sqrt((2 * energy - mass * guess[3] ** 2) / mass)
    np.testing.assert_allclose(abs(s[4]), speed, rtol=1e-12)
    np.testing.assert_allclose(float(orbit.period), 2 * (h - 2 * ell) / speed, rtol=1e-12)
    # Back to the first state after two collisions, shifted by vx * period.
    back = np.asarray(orbit.states[-1]) - s
    np.testing.assert_allclose(back, [guess[3] * float(orbit.period), 0, 0, 0, 0, 0], atol=1e-12)
    tr = bounce_trace(h, ell, mass, float(scene.inertia))
    np.testing.assert_allclose(float(orbit.trace), tr * tr - 2, rtol=1e-9)
    mu = np.asarray(orbit.multipliers)
    np.testing.assert_allclose(mu[0] * mu[1], 1.0, rtol=1e-9)
    np.testing.assert_allclose(np.sum(mu).real, tr * tr - 2, rtol=1e-9)
    assert orbit.label == "hyperbolic" and np.isnan(float(orbit.angular_momentum))


def test_3d_vertical_bounce_has_the_2d_multipliers_twice():
    h, ell = 3.0, 1.0
    u = np.array([0.02, -0.015, 1.0])
    u /= np.linalg.norm(u)
    w = np.array([0.01, 0.03, 0.0])
    w -= (w @ u) * u
    guess = np.array([0.0, 0.0, 1.5, *u, 0.1, -0.05, 1.0, *w])
    orbit = jb.find_periodic_orbit(SCENE_3D, guess, 2, rotation=0.0, angular_momentum=0.0)
    assert bool(orbit.converged) and float(orbit.residual) < 1e-12
    s = np.asarray(orbit.state)
    assert np.abs(s[3:5]).max() < 1e-12 and np.abs(s[9:12]).max() < 1e-12
    tr = bounce_trace(h, ell, 1.0, 1.0) ** 2 - 2
    mu = (tr + math.sqrt(tr * tr - 4)) / 2
    eig = np.sort(np.linalg.eigvals(np.asarray(orbit.monodromy)).real)
    np.testing.assert_allclose(eig, [1 / mu, 1 / mu, 1.0, mu, mu], rtol=1e-9)
    np.testing.assert_allclose(float(orbit.trace), tr, rtol=1e-9)
    assert orbit.label == "hyperbolic"


def _turn(vec, angle):
    c, s = math.cos(angle), math.sin(angle)
    return np.array([c * vec[0] - s * vec[1], s * vec[0] + c * vec[1], vec[2]])


def test_3d_orbit_in_the_plane_and_a_relative_periodic_orbit():
    """A 2D period-2 orbit (found in 2D) is found again in 3D from a guess tilted out of
    the plane, with the same nontrivial pair and three multipliers 1 (energy, L_z,
    rotation); at L_z = 0.05 the family continues as a relative periodic orbit, whose
    return (``jb.orbit``) is the start turned by ``rotation`` about the vertical."""
    orbit2 = jb.find_periodic_orbit(SCENE_2D, np.array([0.0, 2.0, 0.892, 0.0, -0.789, 0.614]), 2)
    assert bool(orbit2.converged)
    mid = np.array(SCENE_3D.flight(jnp.asarray(embed(orbit2.state)), 0.3))
    mid[3:6] += [0.0, 0.02, 0.0]
    mid[9:12] += [0.01, 0.0, 0.02]
    guess = retract(mid)
    planar = jb.find_periodic_orbit(SCENE_3D, guess, 2, rotation=0.0, angular_momentum=0.0)
    assert bool(planar.converged) and float(planar.residual) < 1e-12
    np.testing.assert_allclose(float(planar.trace), float(orbit2.trace), rtol=1e-9)
    eig = np.sort(np.linalg.eigvals(np.asarray(planar.monodromy)).real)
    mu2 = np.sort(np.asarray(orbit2.multipliers).real)
    np.testing.assert_allclose(eig[[0, 4]], mu2, rtol=1e-8)
    np.testing.assert_allclose(eig[1:4], 1.0, atol=1e-5)

    relative = jb.find_periodic_orbit(SCENE_3D, guess, 2, angular_momentum=0.05)
    assert bool(relative.converged) and float(relative.residual) < 1e-12
    np.testing.assert_allclose(float(relative.angular_momentum), 0.05, rtol=1e-12)
    psi = float(relative.rotation)
    assert abs(psi) > 0.05
    s0 = np.asarray(relative.state)
    back = np.asarray(jb.orbit(SCENE_3D, jnp.asarray(s0), 2).state[-1])
    np.testing.assert_allclose(back[3:6], _turn(s0[3:6], psi), atol=1e-10)
    np.testing.assert_allclose(back[9:12], _turn(s0[9:12], psi), atol=1e-10)
    np.testing.assert_allclose(back[[2, 8]], s0[[2, 8]], atol=1e-10)
    # Symplectic: the nontrivial pair multiplies to 1 (not imposed by the solver).
    eig = np.linalg.eigvals(np.asarray(relative.monodromy))
    far = eig[np.argsort(np.abs(eig - 1.0))[-2:]]
    np.testing.assert_allclose(np.prod(far).real, 1.0, rtol=1e-8)
    assert np.sort(np.abs(eig - 1.0))[2] < 1e-5  # the three trivial ones


def test_walls_input_checks():
    with pytest.raises(ValueError, match="angular_momentum"):
        jb.find_periodic_orbit(SCENE_2D, jnp.asarray(CHAOTIC_2D), 2, angular_momentum=0.0)
    with pytest.raises(ValueError, match="rotation"):
        jb.find_periodic_orbit(SCENE_2D, jnp.asarray(CHAOTIC_2D), 2, rotation=0.5)
    with pytest.raises(TypeError, match="StickInCircle"):
        jb.continue_periodic_orbit(SCENE_2D, None, "ell", [1.0])
    with pytest.raises(TypeError, match="dynamical_frame"):
        jb.dynamical_indices(SCENE_3D)
    with pytest.raises(ValueError, match="scene"):
        jb.phase_velocity(jnp.zeros(12))
    with pytest.raises(TypeError, match="BodyInTable"):
        jb.sample_energy_shell(SCENE_3D, 4)


def test_2d_energy_shell_samples_lie_between_the_walls_at_the_energy():
    states, weights = jb.sample_energy_shell(SCENE_2D, 64, energy=0.7, seed=3)
    assert states.shape == (64, 6) and np.all(weights == 1.0)
    np.testing.assert_allclose(np.asarray(jb.energy(SCENE_2D, states)), 0.7, rtol=1e-13)
    assert np.all(np.asarray(SCENE_2D.gaps(jnp.asarray(states))) > 0.0)
    # The measure is uniform in the stick's angle: its mean direction is near zero (64 draws, 4 sigma).
    assert abs(np.mean(np.cos(states[:, 2]))) < 4.0 / np.sqrt(2 * 64)
