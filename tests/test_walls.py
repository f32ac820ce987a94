"""The stick between two flat walls (2D and 3D): invariants, symmetries, limits and bad input.

Expected values come from conservation laws, closed forms derived by hand in
the tests, the 2D <-> 3D embedding, time reversal and dense sampling of the
closed-form flight written here in numpy. The mpmath reference comparison is
in ``test_walls_reference.py``.
"""

from __future__ import annotations

import jax
import jax.numpy as jnp
import numpy as np
import pytest

import jaxbill as jb

EPS = np.finfo(np.float64).eps


def embed(state2d: np.ndarray) -> np.ndarray:
    """The 2D state ``[x, z, th, vx, vz, om]`` as a 3D state in the x-z plane."""
    x, z, th, vx, vz, om = np.moveaxis(np.asarray(state2d, dtype=np.float64), -1, 0)
    zero = np.zeros_like(x)
    return np.stack([x, zero, z, np.sin(th), zero, np.cos(th), vx, zero, vz, zero, om, zero], axis=-1)


def random_3d_state(rng, h, ell, speed=1.0):
    u = rng.normal(size=3)
    u /= np.linalg.norm(u)
    w = rng.normal(size=3) * speed / ell
    w -= (w @ u) * u
    z = rng.uniform(ell * abs(u[2]), h - ell * abs(u[2]))
    return np.array([0.0, 0.0, z, *u, *(rng.normal(size=3) * speed), *w])


def heights_2d(h, ell, state, ts):
    """End heights along the closed-form 2D flight from ``state``, shape ``(len(ts), 2)``."""
    theta = state[2] + state[5] * ts
    z = state[1] + state[4] * ts
    return np.stack([z + ell * np.cos(theta), z - ell * np.cos(theta)], axis=-1)


def heights_3d(ell, state, ts):
    """End heights along the closed-form 3D flight (Rodrigues rotation about w)."""
    u, w = state[3:6], state[9:12]
    spin = np.linalg.norm(w)
    axis_cross = np.cross(w / spin, u) if spin > 0 else np.zeros(3)
    uz = u[2] * np.cos(spin * ts) + axis_cross[2] * np.sin(spin * ts)
    z = state[2] + state[8] * ts
    return np.stack([z + ell * uz, z - ell * uz], axis=-1)


SCENES_2D = {
    "generic": (3.0, 1.0, None, [0.2, 1.5, 0.3, 0.1, 0.7, 1.1]),
    "cannot-turn-over": (1.5, 1.0, None, [0.0, 0.75, 1.2, 0.0, 0.3, 2.0]),
    "light": (3.0, 1.0, 0.01, [0.0, 1.5, 0.4, 0.0, 0.9, 0.2]),
    "heavy": (2.5, 1.0, 20.0, [0.0, 1.2, -0.4, 0.3, -0.6, 0.5]),
    "fast-spin": (3.0, 1.0, None, [0.0, 1.5, 0.0, 0.0, 1e-3, 1.0]),
}


@pytest.fixture(scope="module", params=list(SCENES_2D))
def run_2d(request):
    h, ell, inertia, state0 = SCENES_2D[request.param]
    scene = jb.StickBetweenWalls2D(h, ell, inertia=inertia)
    orb = jb.orbit(scene, jnp.asarray(state0), 3000)
    return scene, np.asarray(state0), orb


def test_2d_energy_and_horizontal_momentum_are_conserved(run_2d):
    scene, state0, orb = run_2d
    e0 = float(jb.energy(scene, state0))
    drift = np.abs(np.asarray(jb.energy(scene, orb.state)) - e0) / e0
    # Rounding growth: a few ulps per collision, as a random walk over 3000.
    assert drift.max() < 100 * EPS * np.sqrt(3000)
    assert np.all(np.asarray(orb.state[:, 3]) == state0[3])


def test_2d_no_collision_is_missed(run_2d):
    """Dense sampling of every flight: no end goes through a wall between collisions."""
    scene, state0, orb = run_2d
    h, ell = float(scene.h), float(scene.ell)
    states = np.vstack([state0, np.asarray(orb.state)])
    times = np.concatenate([[0.0], np.asarray(orb.t)])
    worst = np.inf
    for s, dt in zip(states[:400], np.diff(times)[:400]):
        heights = heights_2d(h, ell, s, np.linspace(0.0, dt, 200))
        worst = min(worst, heights.min(), (h - heights).min())
    assert worst > -1e-12 * h


def test_2d_contacts_are_on_the_wall_they_name(run_2d):
    scene, _, orb = run_2d
    gaps = np.asarray(scene.gaps(orb.state))
    contact = np.asarray(orb.contact)
    column = {1: 0, -1: 1, 3: 2, -3: 3}
    for code, index in column.items():
        hit = contact == code
        assert np.all(np.abs(gaps[hit, index]) < 1e-12 * float(scene.h))
    assert np.all(gaps > -1e-12 * float(scene.h))


def test_2d_stick_too_long_to_turn_over_never_does():
    """With ``2 ell > h`` the stick can never be vertical: ``sin theta`` keeps its sign."""
    h, ell = 1.5, 1.0
    scene = jb.StickBetweenWalls2D(h, ell)
    orb = jb.orbit(scene, jnp.array([0.0, 0.75, 1.2, 0.0, 0.3, 2.0]), 2000)
    theta = np.asarray(orb.state[:, 2])
    assert np.all(np.sin(theta) > 0)
    assert np.all(np.abs(np.cos(theta)) <= h / (2 * ell) + 1e-12)


@pytest.mark.parametrize("scene_cls", [jb.StickBetweenWalls2D, jb.StickBetweenWalls3D])
def test_time_reversal_retraces_the_orbit(scene_cls):
    """Reversing the velocities mid-flight retraces the collisions in reverse order."""
    h, ell, n = 3.0, 1.0, 8
    scene = scene_cls(h, ell)
    state2d = np.array([0.0, 1.4, 0.6, 0.2, 0.8, 0.9])
    if scene_cls is jb.StickBetweenWalls2D:
        state0, position, velocity = state2d, [0, 1, 2], [3, 4, 5]
    else:
        state0 = embed(state2d)
        state0[[7, 9, 11]] = [0.1, 0.05, 0.0]  # out of the plane: L_z != 0
        state0[9:12] -= (state0[9:12] @ state0[3:6]) * state0[3:6]
        position, velocity = list(range(6)), list(range(6, 12))
    forward = jb.orbit(scene, jnp.asarray(state0), n)
    states, flights = np.asarray(forward.state), np.diff(np.asarray(forward.t))
    middle = np.asarray(scene.flight(jnp.asarray(states[n - 2]), flights[-1] / 2)).copy()
    middle[velocity] *= -1
    backward = jb.orbit(scene, jnp.asarray(middle), n - 1)
    back_states = np.asarray(backward.state)
    back_flights = np.diff(np.concatenate([[0.0], np.asarray(backward.t)]))
    assert back_flights[0] == pytest.approx(flights[-1] / 2, abs=1e-12)
    assert np.allclose(back_flights[1:], flights[: n - 2][::-1], rtol=0, atol=1e-10)
    for j in range(n - 1):
        # Where collision n-2-j happened, with the velocities it had before it.
        gap = back_states[j][position] - states[n - 2 - j][position]
        if scene_cls is jb.StickBetweenWalls2D:
            gap[2] = np.remainder(gap[2] + np.pi, 2 * np.pi) - np.pi
        assert np.abs(gap).max() < 1e-10
        if j < n - 2:
            assert np.allclose(back_states[j][velocity], -states[n - 3 - j][velocity], rtol=0, atol=1e-10)


def test_3d_in_the_xz_plane_is_the_2d_scene_collision_by_collision():
    """Every collision of a 2D orbit, restarted in 3D, gives the same next collision."""
    h, ell = 3.0, 1.0
    s2, s3 = jb.StickBetweenWalls2D(h, ell), jb.StickBetweenWalls3D(h, ell)
    orb2 = jb.orbit(s2, jnp.array([0.2, 1.5, 0.3, 0.1, 0.7, 1.1]), 300)
    starts = np.asarray(orb2.state[:-1])
    new3, dt3, contact3 = jax.vmap(jb.collide, in_axes=(None, 0))(s3, jnp.asarray(embed(starts)))
    assert np.array_equal(np.asarray(contact3), np.asarray(orb2.contact[1:]))
    assert np.allclose(np.asarray(dt3), np.diff(np.asarray(orb2.t)), rtol=0, atol=1e-12)
    assert np.allclose(np.asarray(new3), embed(np.asarray(orb2.state[1:])), rtol=0, atol=1e-12)


def test_3d_whole_orbit_follows_2d_within_its_chaos_horizon():
    h, ell = 3.0, 1.0
    state2d = np.array([0.2, 1.5, 0.3, 0.1, 0.7, 1.1])
    orb2 = jb.orbit(jb.StickBetweenWalls2D(h, ell), jnp.asarray(state2d), 8)
    orb3 = jb.orbit(jb.StickBetweenWalls3D(h, ell), jnp.asarray(embed(state2d)), 8)
    assert np.array_equal(np.asarray(orb2.contact), np.asarray(orb3.contact))
    assert np.allclose(np.asarray(orb3.state), embed(np.asarray(orb2.state)), rtol=0, atol=1e-10)


@pytest.mark.parametrize("seed", [0, 1, 2])
def test_3d_invariants_and_no_missed_collision(seed):
    h, ell = 3.0, 1.0
    scene = jb.StickBetweenWalls3D(h, ell)
    state0 = random_3d_state(np.random.default_rng(seed), h, ell)
    orb = jb.orbit(scene, jnp.asarray(state0), 2000)
    states = np.asarray(orb.state)
    e0 = float(jb.energy(scene, state0))
    assert np.abs(np.asarray(jb.energy(scene, states)) / e0 - 1).max() < 100 * EPS * np.sqrt(2000)
    # L_z: the orbital part is a difference of products of |x| ~ |v| t; its
    # rounding grows with the distance travelled.
    lz = np.asarray(jb.angular_momentum(scene, states))
    scale = np.abs(states[:, 0:2]).max() * np.abs(states[:, 6:8]).max() + abs(float(scene.inertia) * states[0, 11])
    assert np.abs(lz - float(jb.angular_momentum(scene, state0))).max() < 100 * EPS * scale
    assert np.all(states[:, 6:8] == state0[6:8])
    assert np.abs(np.linalg.norm(states[:, 3:6], axis=1) - 1).max() < 10 * EPS
    assert np.abs(np.sum(states[:, 3:6] * states[:, 9:12], axis=1)).max() < 100 * EPS
    times = np.concatenate([[0.0], np.asarray(orb.t)])
    all_states = np.vstack([state0, states])
    worst = np.inf
    for s, dt in zip(all_states[:300], np.diff(times)[:300]):
        heights = heights_3d(ell, s, np.linspace(0.0, dt, 200))
        worst = min(worst, heights.min(), (h - heights).min())
    assert worst > -1e-12 * h


def test_3d_nearly_vertical_stick_has_no_polar_singularity():
    """A stick through the vertical (where polar angles break) bounces like the 2D one."""
    h, ell = 3.0, 1.0
    tilt = 1e-9
    state2d = np.array([0.0, 1.5, tilt, 0.0, 0.5, 0.3])
    orb2 = jb.orbit(jb.StickBetweenWalls2D(h, ell), jnp.asarray(state2d), 6)
    orb3 = jb.orbit(jb.StickBetweenWalls3D(h, ell), jnp.asarray(embed(state2d)), 6)
    assert np.all(np.isfinite(np.asarray(orb3.state)))
    assert np.array_equal(np.asarray(orb2.contact), np.asarray(orb3.contact))
    assert np.allclose(np.asarray(orb3.state), embed(np.asarray(orb2.state)), atol=1e-10)


@pytest.mark.parametrize("scene_cls", [jb.StickBetweenWalls2D, jb.StickBetweenWalls3D])
def test_vertical_bounce_without_turning(scene_cls):
    """theta = 0, omega = 0: the stick bounces straight up and down, flights (h - 2 ell) / |vz|."""
    h, ell, vz, z0 = 3.0, 1.0, 0.7, 1.2
    scene = scene_cls(h, ell)
    state2d = np.array([0.0, z0, 0.0, 0.0, vz, 0.0])
    state0 = state2d if scene_cls is jb.StickBetweenWalls2D else embed(state2d)
    orb = jb.orbit(scene, jnp.asarray(state0), 6)
    first = (h - ell - z0) / vz
    expected_t = first + np.arange(6) * (h - 2 * ell) / vz
    assert np.allclose(np.asarray(orb.t), expected_t, rtol=0, atol=1e-14)
    assert list(np.asarray(orb.contact)) == [3, -1, 3, -1, 3, -1]
    vz_index = 4 if scene_cls is jb.StickBetweenWalls2D else 8
    assert np.allclose(np.asarray(orb.state[:, vz_index]), vz * np.array([-1, 1, -1, 1, -1, 1]), atol=1e-15)


@pytest.mark.parametrize("scene_cls", [jb.StickBetweenWalls2D, jb.StickBetweenWalls3D])
def test_flat_landing_is_one_double_contact(scene_cls):
    """A horizontal stick landing flat: both ends at once (a kink), vz reverses, no spin results."""
    h, ell, z0, vz = 3.0, 1.0, 1.0, -0.5
    scene = scene_cls(h, ell)
    state2d = np.array([0.0, z0, np.pi / 2, 0.0, vz, 0.0])
    state0 = state2d if scene_cls is jb.StickBetweenWalls2D else embed(state2d)
    new, dt, contact = jb.collide(scene, jnp.asarray(state0))
    assert int(contact) == 2
    assert float(dt) == pytest.approx(z0 / -vz, abs=1e-14)
    new2d = np.asarray(new) if scene_cls is jb.StickBetweenWalls2D else np.asarray(new)[[0, 2, 4, 6, 8, 10]]
    assert new2d[4] == pytest.approx(-vz, abs=1e-14)
    assert new2d[5] == pytest.approx(0.0, abs=1e-14)


@pytest.mark.parametrize("scene_cls", [jb.StickBetweenWalls2D, jb.StickBetweenWalls3D])
def test_stick_that_never_turns_bounces_in_closed_form(scene_cls):
    h, ell, theta, z0, vz = 3.0, 1.0, 0.4, 1.5, 0.8
    scene = scene_cls(h, ell, inertia=float("inf"))
    assert scene.kind == "static"
    state2d = np.array([0.0, z0, theta, 0.3, vz, 0.0])
    state0 = state2d if scene_cls is jb.StickBetweenWalls2D else embed(state2d)
    orb = jb.orbit(scene, jnp.asarray(state0), 5)
    reach = ell * np.cos(theta)
    first = (h - reach - z0) / vz
    assert np.allclose(np.asarray(orb.t), first + np.arange(5) * (h - 2 * reach) / vz, atol=1e-14)
    assert list(np.asarray(orb.contact)) == [3, -1, 3, -1, 3]


def test_batch_equals_single_runs_and_vmap_over_scenes():
    """Agreement to rounding; chaos (about 4x per collision here) limits how far."""
    h, ell = 3.0, 1.0
    rng = np.random.default_rng(5)
    states = np.stack([random_3d_state(rng, h, ell) for _ in range(5)])
    scene = jb.StickBetweenWalls3D(h, ell)
    batch = jb.orbit(scene, jnp.asarray(states), 20)
    for i in range(5):
        single = jb.orbit(scene, jnp.asarray(states[i]), 20)
        assert np.array_equal(np.asarray(single.contact), np.asarray(batch.contact[i]))
        assert np.allclose(np.asarray(single.state[:5]), np.asarray(batch.state[i, :5]), rtol=0, atol=1e-12)
    hs = np.array([3.0, 3.5, 4.0])
    scenes = jb.StickBetweenWalls2D(hs, ell)
    state = jnp.array([0.0, 1.5, 0.3, 0.0, 0.7, 1.1])
    swept = jax.vmap(lambda sc: jb.orbit(sc, state, 10))(scenes)
    for i, h_i in enumerate(hs):
        one = jb.orbit(jb.StickBetweenWalls2D(h_i, ell), state, 10)
        assert np.allclose(np.asarray(one.t[:5]), np.asarray(swept.t[i, :5]), rtol=0, atol=1e-12)


@pytest.mark.parametrize("scene_cls", [jb.StickBetweenWalls2D, jb.StickBetweenWalls3D])
def test_collision_derivatives_match_finite_differences(scene_cls):
    """Implicit differentiation of the contact time, against central differences."""
    h, ell = 3.0, 1.0
    scene = scene_cls(h, ell)
    state2d = np.array([0.0, 1.5, 0.3, 0.0, 0.7, 1.1])
    state0 = state2d if scene_cls is jb.StickBetweenWalls2D else embed(state2d)
    orb = jb.orbit(scene, jnp.asarray(state0), 4)
    # Mid-flight, so that perturbed states stay inside the walls.
    state0 = scene.flight(orb.state[2], (orb.t[3] - orb.t[2]) / 2)
    jac = np.asarray(jax.jacfwd(lambda s: jb.collide(scene, s)[0])(state0))
    jac_dt = np.asarray(jax.jacfwd(lambda s: jb.collide(scene, s)[1])(state0))
    step = 1e-6
    free = [1, 2, 4, 5] if scene_cls is jb.StickBetweenWalls2D else [2, 8, 10]
    for j in free:
        e = np.zeros(scene.state_size)
        e[j] = step
        plus, dt_plus, _ = jb.collide(scene, state0 + e)
        minus, dt_minus, _ = jb.collide(scene, state0 - e)
        assert np.allclose((np.asarray(plus) - np.asarray(minus)) / (2 * step), jac[:, j], atol=1e-6)
        assert (float(dt_plus) - float(dt_minus)) / (2 * step) == pytest.approx(jac_dt[j], abs=1e-6)


# -- bad input ------------------------------------------------------------------------


@pytest.mark.parametrize("scene_cls", [jb.StickBetweenWalls2D, jb.StickBetweenWalls3D])
@pytest.mark.parametrize(
    "kwargs,match",
    [
        (dict(h=0.0, ell=1.0), "h must be > 0"),
        (dict(h=-1.0, ell=1.0), "h must be > 0"),
        (dict(h=np.nan, ell=1.0), "h must be finite"),
        (dict(h=3.0, ell=0.0), "ell must be > 0"),
        (dict(h=3.0, ell=np.inf), "ell must be finite"),
        (dict(h=3.0, ell=1.0, mass=-1.0), "mass must be > 0"),
        (dict(h=3.0, ell=1.0, inertia=-1.0), "inertia must be > 0"),
        (dict(h=3.0, ell=1.0, inertia=np.nan), "inertia must be a number"),
    ],
)
def test_bad_parameters_raise(scene_cls, kwargs, match):
    with pytest.raises(ValueError, match=match):
        scene_cls(**kwargs)


BAD_2D = [
    ([0.0, 0.5, 0.0, 0.0, 1.0, 0.0], "end P2 \\(floor\\) outside the walls"),
    ([0.0, 2.5, 0.0, 0.0, 1.0, 0.0], "end P1 \\(ceiling\\) outside the walls"),
    ([0.0, 1.0, 0.0, 0.0, -1.0, 0.0], "on the walls without moving inwards"),
    ([0.0, 1.5, 0.0, 0.0, np.nan, 0.0], "finite"),
    ([0.0, 1.5, 0.0, 0.0, 1.0], "shape \\(6,\\)"),
]


@pytest.mark.parametrize("state,match", BAD_2D)
def test_bad_2d_states_raise(state, match):
    with pytest.raises(ValueError, match=match):
        jb.collide(jb.StickBetweenWalls2D(3.0, 1.0), jnp.asarray(state))


def test_bad_3d_states_raise():
    scene = jb.StickBetweenWalls3D(3.0, 1.0)
    good = embed(np.array([0.0, 1.5, 0.3, 0.0, 0.5, 1.0]))
    stretched = good.copy()
    stretched[3:6] *= 1.01
    with pytest.raises(ValueError, match="unit vector"):
        jb.collide(scene, jnp.asarray(stretched))
    axial = good.copy()
    axial[9:12] += 0.5 * good[3:6]
    with pytest.raises(ValueError, match="perpendicular to u"):
        jb.collide(scene, jnp.asarray(axial))
    with pytest.raises(ValueError, match="w must be 0"):
        jb.collide(jb.StickBetweenWalls3D(3.0, 1.0, inertia=np.inf), jnp.asarray(good))
    with pytest.raises(ValueError, match="omega must be 0"):
        jb.collide(jb.StickBetweenWalls2D(3.0, 1.0, inertia=np.inf), jnp.array([0.0, 1.5, 0.3, 0.0, 0.5, 1.0]))


def test_invalid_state_inside_jit_is_poisoned():
    scene = jb.StickBetweenWalls3D(3.0, 1.0)
    bad = embed(np.array([0.0, 1.5, 0.3, 0.0, 0.5, 1.0]))
    bad[3:6] *= 2.0
    new, dt, contact = jax.jit(jb.collide)(scene, jnp.asarray(bad))
    assert np.all(np.isnan(np.asarray(new))) and np.isnan(float(dt)) and int(contact) == 0


def test_2d_has_no_angular_momentum():
    with pytest.raises(TypeError, match="no conserved angular momentum"):
        jb.angular_momentum(jb.StickBetweenWalls2D(3.0, 1.0), jnp.zeros(6))
