"""Properties of ``StickInEllipse`` that need no reference orbit.

Independent checks written from the physics: dense sampling of the ends along
every flight (nothing missed, nothing through the wall), invariants (energy;
the focal-momentum product of a point; the angular momentum about the centre
*not* conserved unless ``a = b``), time reversal, batching, derivatives against
finite differences, the search's bounds (quiet region, curvature) against
sampling, and the validation of parameters and states.
"""

from __future__ import annotations

import math

import numpy as np
import pytest

jax = pytest.importorskip("jax")
jb = pytest.importorskip("jaxbill")
import jax.numpy as jnp  # noqa: E402

from jaxbill._scenes.tables.ellipse import EllipseWall as EllipseTable  # noqa: E402

SCENES = {
    "rotor_ratio_2": dict(a=2.0, b=1.0, ell=0.6),
    "rotor_b_major": dict(a=1.2, b=2.4, ell=0.9, inertia=0.3),
    "rotor_longer_than_minor": dict(a=3.0, b=1.0, ell=1.6, inertia=4.0),
    "static_ratio_1.5": dict(a=3.0, b=2.0, ell=1.2, inertia=float("inf")),
    "point_ratio_3": dict(a=3.0, b=1.0, ell=0.0),
}


def _np_gaps(a, b, ell, state, t):
    """Gaps ``1 - x^2/a^2 - y^2/b^2`` of both ends (numpy, from the physics), shape ``(len(t), 2)``."""
    x, y, al, vx, vy, w = state
    phi = al + w * t
    out = []
    for k in (1.0, -1.0):
        px = x + vx * t + k * ell * np.cos(phi)
        py = y + vy * t + k * ell * np.sin(phi)
        out.append(1.0 - (px / a) ** 2 - (py / b) ** 2)
    return np.stack(out, axis=-1)


def _start(params):
    """A valid start for each scene: centre near the middle, the stick along the major axis."""
    a, b = params["a"], params["b"]
    alpha = 0.1 if a >= b else math.pi / 2 + 0.1
    omega = 0.0 if params.get("inertia") == float("inf") else 1.7
    return np.array([0.1 * a, -0.05 * b, alpha, 0.8, 0.55, omega])


@pytest.mark.parametrize("name", list(SCENES))
def test_dense_sampling_finds_no_missed_collision(name):
    params = SCENES[name]
    scene = jb.StickInEllipse(**params)
    state0 = _start(params)
    orb = jb.orbit(scene, jnp.asarray(state0), 150)
    t = np.concatenate([[0.0], np.asarray(orb.t)])
    states = np.concatenate([state0[None], np.asarray(orb.state)])
    contacts = np.asarray(orb.contact)
    assert np.all(np.isfinite(t)) and np.all(contacts != 0)
    a, b, ell = params["a"], params["b"], params["ell"]
    for j in range(150):
        dt = t[j + 1] - t[j]
        samples = np.linspace(0.0, dt, max(400, int(60 * abs(states[j, 5]) * dt)))
        gaps = _np_gaps(a, b, ell, states[j], samples)
        assert np.all(gaps[1:-1] > -1e-13), f"flight {j}: an end outside the wall before the collision"
        # At the collision the touching end is on the wall (both at a corner).
        at_contact = gaps[-1]
        touching = [0, 1] if contacts[j] == 2 else [0 if contacts[j] == 1 else 1]
        assert np.all(np.abs(at_contact[touching]) < 1e-13), (j, at_contact)


def test_fast_spin_and_near_grazing_starts_are_not_missed():
    """Fast spin (ell omega / |v| = 60) in a 3:1 ellipse: every flight sampled densely."""
    scene = jb.StickInEllipse(3.0, 1.0, 0.5)
    state0 = np.array([0.2, 0.1, 0.3, 0.5, 0.2, 60.0])
    orb = jb.orbit(scene, jnp.asarray(state0), 40)
    t = np.concatenate([[0.0], np.asarray(orb.t)])
    states = np.concatenate([state0[None], np.asarray(orb.state)])
    for j in range(40):
        samples = np.linspace(0.0, t[j + 1] - t[j], 20000)
        assert np.all(_np_gaps(3.0, 1.0, 0.5, states[j], samples)[1:-1] > -1e-13), j


def test_point_conserves_the_focal_momentum_product_over_1e5_collisions():
    """ell = 0: the elliptic billiard's second integral, L1 L2 about the foci, stays at rounding level."""
    scene = jb.StickInEllipse(2.0, 1.2, 0.0)
    state0 = jnp.asarray([0.3, 0.1, 0.0, 0.6, 0.8, 0.0])
    orb = jb.orbit(scene, state0, 100_000)
    product = np.asarray(scene.focal_momentum_product(orb.state))
    start = float(scene.focal_momentum_product(state0))
    scale = 1.0 * 2.0**2 * 1.0  # (M a |v|)^2 with |v| = 1
    drift = np.max(np.abs(product - start)) / scale
    assert drift < 2e-12, drift  # measured 2e-13: a random walk of ~5e-16 per collision
    # It is the integral, not a constant by accident: the angular momentum about
    # the centre and about each focus vary along the same orbit.
    assert np.ptp(np.asarray(scene.angular_momentum(orb.state[:100]))) > 0.1


def test_angular_momentum_about_the_centre_changes_unless_a_equals_b():
    state0 = jnp.asarray([0.1, 0.2, 0.3, 0.7, -0.4, 1.3])
    unequal = jb.StickInEllipse(2.2, 2.0, 1.0)
    lz = np.asarray(unequal.angular_momentum(jb.orbit(unequal, state0, 50).state))
    assert np.ptp(lz) > 0.05
    equal = jb.StickInEllipse(2.0, 2.0, 1.0)
    lz = np.asarray(equal.angular_momentum(jb.orbit(equal, state0, 50).state))
    assert np.ptp(lz) < 1e-13


@pytest.mark.parametrize("name", ["rotor_ratio_2", "rotor_longer_than_minor", "static_ratio_1.5"])
def test_energy_is_conserved(name):
    params = SCENES[name]
    scene = jb.StickInEllipse(**params)
    state0 = jnp.asarray(_start(params))
    energies = np.asarray(scene.energy(jb.orbit(scene, state0, 2000).state))
    e0 = float(scene.energy(state0))
    # Each impulse is elastic to rounding (a few ulps); over 2000 collisions
    # the errors add as a random walk (~sqrt(2000) * 4e-16 = 2e-14), not as a drift.
    assert np.max(np.abs(np.diff(energies))) / e0 < 4e-15
    assert np.max(np.abs(energies - e0)) / e0 < 1e-13


def test_time_reversal_retraces():
    scene = jb.StickInEllipse(2.5, 1.5, 0.8)
    state0 = np.array([0.2, -0.1, 0.4, 0.6, 0.5, 1.1])
    n = 8
    orb = jb.orbit(scene, jnp.asarray(state0), n)
    t, s, k = np.asarray(orb.t), np.asarray(orb.state), np.asarray(orb.contact)
    half = 0.5 * (t[n - 1] - t[n - 2])
    mid = np.asarray(scene.flight(jnp.asarray(s[n - 2]), half))
    reversed_mid = np.concatenate([mid[:3], -mid[3:]])
    back = jb.orbit(scene, jnp.asarray(reversed_mid), n - 1)
    bt, bk = np.asarray(back.t), np.asarray(back.contact)
    t_mid = t[n - 2] + half
    np.testing.assert_array_equal(bk, k[n - 2 :: -1])
    np.testing.assert_allclose(t_mid - bt, t[n - 2 :: -1], rtol=0, atol=1e-11)
    home = np.asarray(scene.flight(back.state[n - 2], t_mid - bt[n - 2]))
    np.testing.assert_allclose(home[:2], state0[:2], atol=1e-11)
    np.testing.assert_allclose(home[3:], -state0[3:], atol=1e-11)


def test_jit_and_vmap_over_states_and_over_scenes():
    scene = jb.StickInEllipse(2.0, 1.0, 0.6)
    rng = np.random.default_rng(3)
    states = np.stack([_start(SCENES["rotor_ratio_2"]) + rng.uniform(-0.05, 0.05, 6) for _ in range(5)])
    single = [jb.collide(scene, jnp.asarray(s)) for s in states]
    batched = jax.jit(jax.vmap(jb.collide, in_axes=(None, 0)))(scene, jnp.asarray(states))
    for i, (s, dt, k) in enumerate(single):
        np.testing.assert_allclose(batched[0][i], s, rtol=1e-14, atol=1e-15)
        np.testing.assert_allclose(batched[1][i], dt, rtol=1e-14, atol=1e-15)
        assert int(batched[2][i]) == int(k)
    # A batch of scenes (a, b, ell of shape (3,)), one state each.
    a, b, ell = np.array([2.0, 2.2, 1.5]), np.array([1.0, 1.4, 2.0]), np.array([0.6, 0.5, 0.7])
    scenes = jb.StickInEllipse(a, b, ell)
    orbits = jax.vmap(jb.orbit, in_axes=(0, 0, None))(scenes, jnp.asarray(states[:3]), 5)
    for i in range(3):
        one = jb.orbit(jb.StickInEllipse(a[i], b[i], ell[i]), jnp.asarray(states[i]), 5)
        np.testing.assert_allclose(orbits.state[i], one.state, rtol=1e-13, atol=1e-14)
        np.testing.assert_array_equal(orbits.contact[i], one.contact)


@pytest.mark.parametrize("name", ["rotor_ratio_2", "static_ratio_1.5", "point_ratio_3"])
def test_derivative_of_the_collision_map_matches_finite_differences(name):
    params = SCENES[name]
    scene = jb.StickInEllipse(**params)
    state = jnp.asarray(_start(params))
    new_state = lambda s: jb.collide(scene, s)[0]  # noqa: E731
    jacobian = np.asarray(jax.jacfwd(new_state)(state))
    columns = [0, 1, 3, 4] + ([2, 5] if scene.kind == "rotor" else [])
    h = 1e-6
    for col in columns:
        step = np.zeros(6)
        step[col] = h
        fd = (np.asarray(new_state(state + step)) - np.asarray(new_state(state - step))) / (2 * h)
        np.testing.assert_allclose(jacobian[:, col], fd, rtol=1e-6, atol=2e-7, err_msg=f"column {col}")


def test_derivative_with_respect_to_the_semi_axes():
    state = jnp.asarray(_start(SCENES["rotor_ratio_2"]))

    def new_state(axes):
        return jb.collide(jb.StickInEllipse(axes[0], axes[1], 0.6), state)[0]

    axes = jnp.asarray([2.0, 1.0])
    jacobian = np.asarray(jax.jacfwd(new_state)(axes))
    h = 1e-6
    for col in range(2):
        step = np.zeros(2)
        step[col] = h
        fd = (np.asarray(new_state(axes + step)) - np.asarray(new_state(axes - step))) / (2 * h)
        np.testing.assert_allclose(jacobian[:, col], fd, rtol=1e-6, atol=2e-7)


def test_collision_map_annihilates_the_flow_direction():
    """``DP f(s) = 0``: moving the start along its own flight changes nothing after the collision."""
    scene = jb.StickInEllipse(2.0, 1.0, 0.6)
    state = jnp.asarray(_start(SCENES["rotor_ratio_2"]))
    _, _, _, jacobian = jb.tangent_map(scene, state)
    assert np.max(np.abs(np.asarray(jacobian @ scene.phase_velocity(state)))) < 1e-10


# ---------------------------------------------------------------------------
# the root search's bounds, against sampling
# ---------------------------------------------------------------------------
@pytest.mark.parametrize("a,b,ell", [(3.0, 1.0, 0.5), (1.0, 2.5, 0.9), (2.0, 2.0, 1.0), (2.0, 1.5, 1.49)])
def test_quiet_ellipse_keeps_both_ends_inside(a, b, ell):
    table = EllipseTable(jnp.asarray(a), jnp.asarray(b))
    sx, sy = (float(v) for v in table.quiet_semi_axes(jnp.asarray(ell)))
    theta = np.linspace(0.0, 2 * np.pi, 721)
    phi = np.linspace(0.0, 2 * np.pi, 721)[:, None]
    cx, cy = sx * np.cos(theta), sy * np.sin(theta)
    for k in (1.0, -1.0):
        px, py = cx + k * ell * np.cos(phi), cy + k * ell * np.sin(phi)
        assert np.all((px / a) ** 2 + (py / b) ** 2 <= 1.0 + 1e-12)
    # Tight where the minor axis meets the wall: the quiet ellipse is no smaller than it must be there.
    # The stick centred at the end of the quiet ellipse's minor axis, lying along that axis, touches the wall.
    (cx, cy), (ux, uy) = ((0.0, sy), (0.0, 1.0)) if a >= b else ((sx, 0.0), (1.0, 0.0))
    assert min(sx, sy) == pytest.approx(min(a, b) - ell)
    assert ((cx + ell * ux) / a) ** 2 + ((cy + ell * uy) / b) ** 2 == pytest.approx(1.0, abs=1e-12)


def test_the_naive_quiet_ellipse_is_not_safe():
    """Semi-axes (a - ell, b - ell) let an end out near the major axis (why the module does not use them)."""
    a, b, ell = 3.0, 1.0, 0.5
    theta = np.linspace(-0.6, 0.6, 1201)
    cx, cy = (a - ell) * np.cos(theta), (b - ell) * np.sin(theta)
    phi = np.linspace(0.0, 2 * np.pi, 721)[:, None]
    px, py = cx + ell * np.cos(phi), cy + ell * np.sin(phi)
    assert np.max((px / a) ** 2 + (py / b) ** 2) > 1.0 + 1e-3


@pytest.mark.parametrize("name", ["rotor_ratio_2", "rotor_b_major", "rotor_longer_than_minor"])
def test_curvature_bounds_hold_along_flights(name):
    """Sampled ``g_k''`` (autodiff of the slope) stays within the search's bounds on every flight."""
    params = SCENES[name]
    scene = jb.StickInEllipse(**params)
    state0 = jnp.asarray(_start(params))
    states = jnp.concatenate([state0[None], jb.orbit(scene, state0, 30).state])

    @jax.jit
    @jax.vmap
    def margins(s):
        lower, upper, *_ = scene.root_search_setup(s)
        t, _, _ = scene.next_contact(s)
        second = jax.vmap(jax.jacfwd(lambda tt: scene.contact_gaps(s, tt)[1]))(t * jnp.linspace(0.0, 1.0, 400))
        return jnp.min(lower - (-second)) / lower, jnp.min(upper - second) / lower

    below, above = (np.asarray(m) for m in margins(states[:-1]))
    assert np.all(below >= -1e-12) and np.all(above >= -1e-12)


def test_engine_pieces_compose_to_the_collision():
    """root_search_setup, contact_gaps and resolve_contact give what collide gives, and the slope is d gap/dt."""
    from jaxbill._engine.first_root import RootBounds, first_root

    scene = jb.StickInEllipse(2.5, 1.5, 0.8)
    state = jnp.asarray([0.2, -0.1, 0.4, 0.6, 0.5, 1.1])
    gaps = lambda t: scene.contact_gaps(state, t)  # noqa: E731
    t, index, _, ok = first_root(gaps, RootBounds(*scene.root_search_setup(state)), 4096)
    new_state, contact = scene.resolve_contact(scene.flight(state, t), index)
    want_state, want_t, want_contact = jb.collide(scene, state)
    assert bool(ok) and float(t) == float(want_t) and int(contact) == int(want_contact)
    np.testing.assert_allclose(np.asarray(new_state), np.asarray(want_state), rtol=1e-15, atol=1e-15)
    for t_probe in (0.1, 0.7, float(t)):
        slope_ad = jax.jacfwd(lambda tt: gaps(tt)[0])(jnp.asarray(t_probe))
        np.testing.assert_allclose(slope_ad, gaps(t_probe)[1], rtol=1e-13, atol=1e-14)


# ---------------------------------------------------------------------------
# validation
# ---------------------------------------------------------------------------
@pytest.mark.parametrize(
    "kwargs,message",
    [
        (dict(a=0.0, b=1.0, ell=0.5), "a must be > 0"),
        (dict(a=2.0, b=-1.0, ell=0.5), "b must be > 0"),
        (dict(a=2.0, b=float("nan"), ell=0.5), "b must be finite"),
        (dict(a=2.0, b=1.0, ell=2.0), r"ell must be < max\(a, b\)"),
        (dict(a=1.0, b=2.0, ell=2.5), r"ell must be < max\(a, b\)"),
        (dict(a=2.0, b=1.0, ell=-0.1), "ell must be >= 0"),
        (dict(a=2.0, b=1.0, ell=0.5, mass=0.0), "mass must be > 0"),
        (dict(a=2.0, b=1.0, ell=0.5, inertia=float("nan")), "inertia must be a number or inf"),
        (dict(a=2.0, b=1.0, ell=0.5, inertia=-1.0), "inertia must be > 0"),
        (dict(a="2", b=1.0, ell=0.5), "a must be a real number"),
        (dict(a=[2.0, 3.0], b=1.0, ell=[0.5, 0.0]), "ell must be all zero or all positive"),
    ],
)
def test_bad_parameters_raise(kwargs, message):
    with pytest.raises(ValueError, match=message):
        jb.StickInEllipse(**kwargs)


def test_bad_states_raise():
    scene = jb.StickInEllipse(3.0, 1.0, 1.6, inertia=4.0)
    with pytest.raises(ValueError, match="outside the ellipse"):
        jb.collide(scene, jnp.asarray([0.0, 0.0, 1.2, 0.5, 0.1, 0.0]))  # too long to stand across the minor axis
    with pytest.raises(ValueError, match="outside the ellipse"):
        jb.collide(scene, jnp.asarray([1.5, 0.0, 0.0, 0.5, 0.1, 0.0]))
    # End P1 exactly on the wall at (3, 0) moving outwards, then inwards (a valid start).
    with pytest.raises(ValueError, match="without moving inwards"):
        jb.collide(scene, jnp.asarray([1.4, 0.0, 0.0, 0.5, 0.0, 0.0]))
    jb.collide(scene, jnp.asarray([1.4, 0.0, 0.0, -0.5, 0.0, 0.0]))
    static = jb.StickInEllipse(3.0, 1.0, 0.5, inertia=float("inf"))
    with pytest.raises(ValueError, match="omega must be 0"):
        jb.collide(static, jnp.asarray([0.0, 0.0, 0.0, 0.5, 0.1, 0.2]))
    with pytest.raises(ValueError, match="shape"):
        jb.collide(static, jnp.zeros(5))


def test_invalid_input_inside_jit_poisons_with_nan():
    scene = jb.StickInEllipse(3.0, 1.0, 1.6, inertia=4.0)
    out = jax.jit(lambda s: jb.collide(scene, s))(jnp.asarray([0.0, 0.0, 1.2, 0.5, 0.1, 0.0]))
    assert np.all(np.isnan(np.asarray(out[0]))) and int(out[2]) == 0
    bad_scene = jax.jit(lambda ell, s: jb.collide(jb.StickInEllipse(3.0, 1.0, ell), s))
    out = bad_scene(jnp.asarray(3.5), jnp.asarray([0.0, 0.0, 0.0, 0.5, 0.1, 0.0]))
    assert np.all(np.isnan(np.asarray(out[0])))
