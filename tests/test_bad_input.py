"""Bad input: a ValueError naming the parameter and its valid range (eager
calls), NaN-poisoned output (inside ``jax.jit``), and the clean no-collision
result for a flight that never reaches the wall."""

from __future__ import annotations

import math

import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np
import pytest

import jaxbill as jb

NAN, INF = float("nan"), float("inf")
GOOD = np.array([0.1, -0.2, 0.3, 0.7, 0.4, 0.5])  # valid for R = 2, ell = 1
N = 3  # every orbit here has this length; jitted functions are built once (compile per scene kind)
jit_collide = jax.jit(jb.collide)
jit_orbit = jax.jit(jb.orbit, static_argnums=2)


def rotor():
    return jb.StickInCircle(R=2.0, ell=1.0)


def lens():
    return jb.StickInCircle(R=2.0, ell=1.0, inertia=INF)


def circle():
    return jb.StickInCircle(R=2.0, ell=0.0)


# ---------------------------------------------------------------------------
# scene parameters
# ---------------------------------------------------------------------------
@pytest.mark.parametrize(
    "kwargs, match",
    [
        (dict(R=0.0, ell=0.0), r"R must be > 0"),
        (dict(R=-1.0, ell=0.0), r"R must be > 0"),
        (dict(R=NAN, ell=1.0), r"R must be finite"),
        (dict(R=INF, ell=1.0), r"R must be finite"),
        (dict(R=-INF, ell=1.0), r"R must be finite"),
        (dict(R=2.0, ell=-0.1), r"ell must be >= 0"),
        (dict(R=2.0, ell=2.0), r"ell must be < R"),
        (dict(R=2.0, ell=3.0), r"ell must be < R"),
        (dict(R=2.0, ell=NAN), r"ell must be finite"),
        (dict(R=2.0, ell=1.0, mass=0.0), r"mass must be > 0"),
        (dict(R=2.0, ell=1.0, mass=-2.0), r"mass must be > 0"),
        (dict(R=2.0, ell=1.0, mass=NAN), r"mass must be finite"),
        (dict(R=2.0, ell=1.0, mass=INF), r"mass must be finite"),
        (dict(R=2.0, ell=1.0, inertia=0.0), r"inertia must be > 0"),
        (dict(R=2.0, ell=1.0, inertia=-1.0), r"inertia must be > 0"),
        (dict(R=2.0, ell=1.0, inertia=-INF), r"inertia must be > 0"),
        (dict(R=2.0, ell=1.0, inertia=NAN), r"inertia must be a number or inf, not NaN"),
        (dict(R=2.0, ell=jnp.array([0.5, 2.5])), r"ell must be < R"),
        (dict(R=jnp.array([2.0, -2.0]), ell=0.0), r"R must be > 0"),
    ],
)
def test_bad_scene_parameters_raise(kwargs, match):
    with pytest.raises(ValueError, match=match):
        jb.StickInCircle(**kwargs)


def _with(scene, name, value):
    return eqx.tree_at(lambda s: getattr(s, name), scene, jnp.asarray(value, dtype=jnp.float64))


@pytest.mark.parametrize(
    "name, value, match",
    [
        ("R", -3.0, r"R must be > 0"),
        ("ell", 2.5, r"ell must be < R"),
        ("mass", -1.0, r"mass must be > 0"),
        ("inertia", NAN, r"inertia must be a number or inf, not NaN"),
    ],
)
@pytest.mark.parametrize("call", ["collide", "orbit"])
def test_collide_and_orbit_reject_bad_parameters_of_a_modified_scene(name, value, match, call):
    """A scene whose leaves were changed after construction (``eqx.tree_at``, or
    an optimiser step ``eqx.apply_updates`` on a differentiable parameter) is
    concrete input too: collide/orbit must name the bad parameter, not return
    NaN silently or blame the state."""
    scene = _with(rotor(), name, value)
    with pytest.raises(ValueError, match=match):
        if call == "collide":
            jb.collide(scene, GOOD)
        else:
            jb.orbit(scene, GOOD, N)


def test_a_scene_checked_once_still_catches_every_later_change():
    """Scenes that passed their check are not checked again (``validation.check_scene``): a scene made
    from a checked one by ``eqx.tree_at`` is checked afresh, a scene with a mutable numpy leaf at
    every call, and the record of a checked scene goes with the scene."""
    import gc

    from jaxbill._engine import validation

    scene = rotor()
    jb.orbit(scene, GOOD, N)
    assert id(scene) in validation._CHECKED_SCENES
    with pytest.raises(ValueError, match=r"ell must be < R"):
        jb.orbit(_with(scene, "ell", 2.5), GOOD, N)

    ell = np.array(1.0)
    mutable = eqx.tree_at(lambda s: s.ell, scene, ell)
    jb.orbit(mutable, GOOD, N)
    ell[...] = 2.5  # in place: the same scene object now holds a bad parameter
    with pytest.raises(ValueError, match=r"ell must be < R"):
        jb.orbit(mutable, GOOD, N)

    key = id(scene)
    del scene
    gc.collect()
    assert key not in validation._CHECKED_SCENES


# ---------------------------------------------------------------------------
# bad states (eager): jb.collide and jb.orbit
# ---------------------------------------------------------------------------
def _outside_state():
    s = GOOD.copy()
    s[0] = 1.5  # P1 at about 2.45 > R
    return s


def _on_wall_outwards(moving_in):
    # stick along x, P1 = (2, 0) on the wall; end velocity +-x
    s = np.array([1.0, 0.0, 0.0, 0.5 if not moving_in else -0.5, 0.3, 0.0])
    return s


BAD_STATES = [
    ("nan", lambda: np.array([NAN, 0, 0, 1, 0, 0.0]), rotor, r"state must be finite"),
    ("nan-omega", lambda: np.array([0, 0, 0, 1, 0, NAN]), rotor, r"state must be finite"),
    ("inf-v", lambda: np.array([0, 0, 0, INF, 0, 0.0]), rotor, r"state must be finite"),
    ("inf-alpha", lambda: np.array([0, 0, -INF, 1, 0, 0.0]), lens, r"state must be finite"),
    ("shape5", lambda: np.zeros(5), rotor, r"state must have shape \(6,\) or \(B, 6\)"),
    ("shape3d", lambda: np.zeros((2, 2, 6)), rotor, r"state must have shape \(6,\) or \(B, 6\)"),
    ("shape-scalar", lambda: np.float64(1.0), rotor, r"state must have shape \(6,\) or \(B, 6\)"),
    ("outside", _outside_state, rotor, r"end P1 outside the circle"),
    ("outside-P2", lambda: -_outside_state() * np.array([1, 1, -1, 1, 1, 1]), rotor, r"end P2 outside the circle"),
    ("outside-lens", lambda: _outside_state() * np.array([1, 1, 1, 1, 1, 0]), lens, r"outside the circle"),
    ("centre-outside", lambda: np.array([2.5, 0, 0, 1, 0, 0.0]), circle, r"outside the circle"),
    ("on-wall-outwards", lambda: _on_wall_outwards(False), rotor, r"on the circle without moving inwards"),
    ("on-wall-outwards-lens", lambda: _on_wall_outwards(False), lens, r"on the circle without moving inwards"),
    ("spin-lens", lambda: np.array([0, 0, 0, 1, 0, 0.1]), lens, r"omega must be 0 for the static lens"),
]


@pytest.mark.parametrize("case", BAD_STATES, ids=[c[0] for c in BAD_STATES])
@pytest.mark.parametrize("call", ["collide", "orbit"])
def test_bad_state_raises(case, call):
    _, make_state, make_scene, match = case
    scene, state = make_scene(), make_state()
    with pytest.raises(ValueError, match=match):
        if call == "collide":
            jb.collide(scene, state)
        else:
            jb.orbit(scene, state, N)


def test_bad_state_in_a_batch_raises():
    states = np.stack([GOOD, _outside_state(), GOOD])
    with pytest.raises(ValueError, match=r"end P1 outside the circle"):
        jb.orbit(rotor(), states, N)


def test_a_batch_error_names_its_first_offending_state():
    """The message quotes the first offending row of a batch, not row 0 or a later offender
    (the checks reduce on the device and bring back only its index)."""
    first, later = _outside_state(), _outside_state() * np.array([1, 0.5, 1, 1, 1, 1])
    states = np.stack([GOOD, GOOD, first, GOOD, later])
    with pytest.raises(ValueError, match=r"end P1 outside the circle") as raised:
        jb.run(rotor(), states, N, progress=False)
    assert str(first.tolist()) in str(raised.value) and str(later.tolist()) not in str(raised.value)
    slow = GOOD * np.array([1, 1, 1, 1e-170, 1e-170, 0])  # |v|^2 underflows: no flight time
    with pytest.raises(ValueError, match=r"squares that float64 represents") as raised:
        jb.run(rotor(), np.stack([GOOD, slow, GOOD]), N, progress=False)
    assert str(slow.tolist()) in str(raised.value)


def test_end_on_wall_moving_inwards_is_accepted():
    """The mirror case of 'on the wall moving outwards': the state just after a
    collision, which must be a valid start."""
    s = _on_wall_outwards(True)
    new, dt, contact = jb.collide(rotor(), s)
    assert int(contact) != 0 and float(dt) > 0.0 and np.all(np.isfinite(np.asarray(new)))


@pytest.mark.parametrize(
    "n, match",
    [
        (-1, r"n must be a non-negative integer"),
        (2.5, r"n must be a non-negative integer"),
        (3.0, r"n must be a non-negative integer"),
        ("3", r"n must be a non-negative integer"),
        (None, r"n must be a non-negative integer"),
    ],
)
def test_bad_orbit_length_raises(n, match):
    with pytest.raises(ValueError, match=match):
        jb.orbit(rotor(), GOOD, n)


def test_orbit_length_zero_and_numpy_integer():
    orb = jb.orbit(rotor(), GOOD, 0)
    assert orb.t.shape == (0,) and orb.state.shape == (0, 6) and orb.contact.shape == (0,)
    orb = jb.orbit(rotor(), GOOD, np.int64(N))
    assert orb.t.shape == (N,)


# ---------------------------------------------------------------------------
# NaN poisoning inside jit
# ---------------------------------------------------------------------------
def _assert_poisoned(new, dt, contact):
    assert np.all(np.isnan(np.asarray(new))), new
    assert np.all(np.isnan(np.asarray(dt))), dt
    assert np.all(np.asarray(contact) == 0), contact


POISON_CASES = [
    ("nan", rotor, np.array([NAN, 0, 0, 1, 0, 0.0])),
    ("inf", rotor, np.array([0, 0, 0, 1, INF, 0.0])),
    ("outside", rotor, _outside_state()),
    ("outside-lens", lens, _outside_state() * np.array([1, 1, 1, 1, 1, 0])),
    ("centre-outside", circle, np.array([2.5, 0, 0, 1, 0, 0.0])),
    ("spin-lens", lens, np.array([0, 0, 0, 1, 0, 0.1])),
    ("nan-circle", circle, np.array([0, 0, 0, NAN, 0, 0.0])),
]


@pytest.mark.parametrize("case", POISON_CASES, ids=[c[0] for c in POISON_CASES])
def test_invalid_state_inside_jit_is_poisoned(case):
    _, make_scene, state = case
    scene = make_scene()
    _assert_poisoned(*jit_collide(scene, jnp.asarray(state)))
    orb = jit_orbit(scene, jnp.asarray(state), N)
    _assert_poisoned(orb.state, orb.t, orb.contact)


def test_invalid_state_in_a_vmapped_batch_poisons_only_its_row():
    states = jnp.asarray(np.stack([GOOD, _outside_state(), GOOD]))
    new, dt, contact = jax.vmap(jb.collide, in_axes=(None, 0))(rotor(), states)
    _assert_poisoned(new[1], dt[1], contact[1])
    for i in (0, 2):
        assert np.all(np.isfinite(np.asarray(new[i]))) and np.isfinite(float(dt[i])) and int(contact[i]) != 0


@jax.jit
def _collide_traced(R, ell, mass, inertia, s):
    return jb.collide(jb.StickInCircle(R=R, ell=ell, mass=mass, inertia=inertia), s)


@pytest.mark.parametrize(
    "R, ell, mass, inertia",
    [
        (-2.0, 1.0, 1.0, 1.0),
        (2.0, 2.5, 1.0, 1.0),
        (2.0, 1.0, -1.0, 1.0),
        (2.0, 1.0, 1.0, -1.0),
        (NAN, 1.0, 1.0, 1.0),
        (2.0, 1.0, 1.0, NAN),
        (INF, 1.0, 1.0, 1.0),
    ],
)
def test_invalid_traced_parameters_are_poisoned(R, ell, mass, inertia):
    """A scene built inside jit from traced values cannot be checked eagerly."""

    _assert_poisoned(*_collide_traced(R, ell, mass, inertia, jnp.asarray(np.array([0.1, -0.2, 0.3, 0.7, 0.4, 0.5]))))
    # the same function with valid values is not poisoned (so the poison is
    # caused by the bad value, not by tracing)
    new, dt, contact = _collide_traced(2.0, 1.0, 1.0, 1.0, jnp.asarray(GOOD))
    assert np.all(np.isfinite(np.asarray(new))) and np.isfinite(float(dt)) and int(contact) != 0


# ---------------------------------------------------------------------------
# a flight that never reaches the wall
# ---------------------------------------------------------------------------
NEVER = [
    ("rotor-still", rotor, [0.1, 0.2, 10.0, 0.0, 0.0, 0.0]),
    ("rotor-spinning", rotor, [0.1, 0.2, 10.0, 0.0, 0.0, 5.0]),  # |c| + ell < R: spins freely
    ("rotor-fast-spin", rotor, [-0.3, 0.4, -2.0, 0.0, 0.0, -1e4]),
    ("lens", lens, [0.1, 0.2, 3.0, 0.0, 0.0, 0.0]),
    ("circle", circle, [0.1, 0.2, 3.0, 0.0, 0.0, 0.0]),
    ("circle-spinning", circle, [0.1, 0.2, 3.0, 0.0, 0.0, 2.0]),
]


@pytest.mark.parametrize("case", NEVER, ids=[c[0] for c in NEVER])
def test_flight_that_never_reaches_the_wall(case):
    _, make_scene, state = case
    scene, state = make_scene(), np.asarray(state)
    R, ell = float(scene.R), float(scene.ell)
    assert math.hypot(state[0], state[1]) + ell < R  # the construction: no end can ever touch
    for fn in (jb.collide, jit_collide):
        new, dt, contact = fn(scene, jnp.asarray(state))
        new = np.asarray(new)
        assert float(dt) == INF and int(contact) == 0
        assert np.all(np.isfinite(new))
        np.testing.assert_array_equal(new[[0, 1, 3, 4, 5]], state[[0, 1, 3, 4, 5]])
        wrapped = math.remainder(new[2] - state[2], 2 * math.pi)
        assert abs(wrapped) <= 1e-15 * max(1.0, abs(state[2]))
    orb = jb.orbit(scene, jnp.asarray(state), N)
    assert np.all(np.asarray(orb.t) == INF)
    assert np.all(np.asarray(orb.contact) == 0)
    assert np.all(np.isfinite(np.asarray(orb.state)))
    np.testing.assert_array_equal(
        np.asarray(orb.state)[:, [0, 1, 3, 4, 5]], np.broadcast_to(state[[0, 1, 3, 4, 5]], (N, 5))
    )


def test_batch_with_an_orbit_that_never_collides():
    """In a batch, an orbit that never collides gives t = inf and contact 0 in its
    row only; the other rows are ordinary orbits."""
    states = jnp.asarray(np.stack([GOOD, np.array([0.1, 0.2, 1.0, 0.0, 0.0, 3.0])]))
    orb = jb.orbit(rotor(), states, N)
    assert np.all(np.isfinite(np.asarray(orb.t[0]))) and np.all(np.asarray(orb.contact[0]) != 0)
    assert np.all(np.asarray(orb.t[1]) == INF) and np.all(np.asarray(orb.contact[1]) == 0)
    assert np.all(np.isfinite(np.asarray(orb.state)))
