"""Result codes: each orbit says why it stopped or what went wrong first, the same in every driver.

Every code is provoked from its cause, never read back from the code itself: a
NaN start under ``jit`` (``INVALID_START``), a body at rest or gliding along a
strip (``NO_WALL``: its contact time is infinite, which its arrays show too),
a root search allowed one step (``ROOT_STEPS_EXHAUSTED``), a NaN put into a
checkpoint's state halfway through a run (``NON_FINITE``), and a user's convex
table given a Hessian bound a thousand times too small (``BOUND_VIOLATED``).
Beside them: empty batches and ``n = 0`` give empty results everywhere.
"""

from __future__ import annotations

import dataclasses

import jax
import jax.numpy as jnp
import numpy as np
import pytest

import jaxbill as jb
from helpers import random_states
from jaxbill._engine import lanes as _lanes
from jaxbill._engine import step as _step

R = jb.Result
INF = float("inf")
DRIVERS = ("serial", "lockstep", "lanes", "pallas")


def rotor():
    return jb.StickInCircle(R=2.0, ell=1.9)


def lens():
    return jb.StickInCircle(R=2.0, ell=1.5, inertia=INF)


def starts(scene, count, seed=3):
    return np.asarray(random_states(np.random.default_rng(seed), count, 2.0, float(scene.ell), scene.kind))


def test_every_code_is_documented_and_distinct():
    names = [member.name for member in R]
    assert len({int(member) for member in R}) == len(names) == 8
    assert int(R.FINISHED) == 0
    doc = R.__doc__ or ""
    assert all(f"``{name}`` ({int(R[name])})" in doc for name in names)


# ---------------------------------------------------------------------------
# FINISHED and INVALID_START
# ---------------------------------------------------------------------------
@pytest.mark.parametrize("driver", ["serial", "lockstep", "lanes"])
def test_a_bad_start_inside_jit_is_an_invalid_start(driver):
    """Under ``jit`` the value checks cannot raise: the NaN start is poisoned and says so, its neighbours finish."""
    scene = rotor()
    states = starts(scene, 5)
    states[2, 0] = np.nan
    orbit = jax.jit(lambda s: jb.orbit(scene, s, 6, driver=driver))(jnp.asarray(states))
    expected = [R.FINISHED, R.FINISHED, R.INVALID_START, R.FINISHED, R.FINISHED]
    np.testing.assert_array_equal(np.asarray(orbit.result), expected)
    assert np.all(np.isnan(np.asarray(orbit.t[2]))) and np.all(np.asarray(orbit.contact[2]) == 0)
    assert np.all(np.isfinite(np.asarray(orbit.t)[[0, 1, 3, 4]]))


def test_tangent_results_say_invalid_start_under_jit():
    scene = lens()
    states = starts(scene, 3)
    states[1, 3] = np.inf
    bad = jnp.asarray(states)
    expected = [R.FINISHED, R.INVALID_START, R.FINISHED]
    spectrum = jax.jit(lambda s: jb.lyapunov_spectrum(scene, s, 4, n_history=2))(bad)
    indicator = jax.jit(lambda s: jb.fli(scene, s, 4, n_history=2))(bad)
    mean = jax.jit(lambda s: jb.megno(scene, s, 4, n_history=2))(bad)
    finite_time = jax.jit(lambda s: jb.finite_time_lyapunov(scene, s, 4))(bad)
    for result in (spectrum.result, indicator.result, mean.result, finite_time.result):
        np.testing.assert_array_equal(np.asarray(result), expected)
    assert np.all(np.isnan(np.asarray(spectrum.exponents[1]))) and np.isnan(float(finite_time.per_time[1]))


# ---------------------------------------------------------------------------
# NO_WALL: a flight that never ends
# ---------------------------------------------------------------------------
AT_REST = {
    # A static stick at rest in the middle of a circle: the closed-form contact time is infinite.
    "lens at rest": (lens(), [0.1, -0.2, 0.3, 0.0, 0.0, 0.0], [0.434, -0.323, -1.554, 0.991, -0.131, 0.0]),
    # A stick between walls gliding parallel to them without spin: its searched gaps never change.
    "walls, gliding": (
        jb.StickBetweenWalls2D(h=3.0, ell=1.0),
        [0.0, 1.5, 0.3, 1.0, 0.0, 0.0],
        [0.0, 1.5, 0.3, 0.4, 0.9, 1.1],
    ),
}


@pytest.mark.parametrize("name", list(AT_REST))
def test_a_flight_that_never_reaches_a_wall(name):
    """``dt = inf`` from the first collision on, the state as it was: ``NO_WALL``, and the same from
    ``jb.run`` in every driver and from the tangent results."""
    scene, state, moving = AT_REST[name]
    state = np.asarray(state)
    orbit = jb.orbit(scene, state, 3)
    assert int(orbit.result) == R.NO_WALL
    assert np.all(np.isinf(np.asarray(orbit.t))) and np.all(np.asarray(orbit.contact) == 0)
    np.testing.assert_array_equal(np.asarray(orbit.state), np.broadcast_to(state, (3, scene.state_size)))
    batch = np.stack([state, np.asarray(moving)])
    for driver in DRIVERS:
        run = jb.run(scene, batch, 3, driver=driver)
        np.testing.assert_array_equal(run.result, [R.NO_WALL, R.FINISHED], err_msg=driver)
        np.testing.assert_array_equal(run.final_state[0], state, err_msg=driver)
    assert int(jb.lyapunov_spectrum(scene, state, 2, n_history=1).result) == R.NO_WALL


# ---------------------------------------------------------------------------
# ROOT_STEPS_EXHAUSTED
# ---------------------------------------------------------------------------
@pytest.fixture
def one_root_step(monkeypatch):
    """Root searches of one step: programs compiled before (or with it) are forgotten on both sides."""
    jax.clear_caches()
    monkeypatch.setattr(_step, "MAX_ROOT_STEPS", 1)
    monkeypatch.setattr(_lanes, "MAX_ROOT_STEPS", 1)
    yield
    monkeypatch.undo()
    jax.clear_caches()


def test_a_search_out_of_steps_is_reported_and_stays_reported(one_root_step):
    """The first collision's search proves nothing in one step: NaN from there on, and the code names the
    first failure, not the non-finite states that follow it."""
    scene = rotor()
    states = starts(scene, 4)
    single = jb.orbit(scene, states[0], 5)
    assert int(single.result) == R.ROOT_STEPS_EXHAUSTED and np.all(np.isnan(np.asarray(single.t)))
    for driver in ("serial", "lockstep", "lanes"):
        orbit = jax.jit(lambda s, driver=driver: jb.orbit(scene, s, 5, driver=driver))(jnp.asarray(states))
        np.testing.assert_array_equal(np.asarray(orbit.result), [R.ROOT_STEPS_EXHAUSTED] * 4, err_msg=driver)
    for driver in DRIVERS:
        run = jb.run(scene, states, 5, driver=driver)
        np.testing.assert_array_equal(run.result, [R.ROOT_STEPS_EXHAUSTED] * 4, err_msg=driver)
        assert np.all(np.isnan(run.final_state)), driver
    indicator = jb.fli(scene, states, 3, n_history=1)
    np.testing.assert_array_equal(np.asarray(indicator.result), [R.ROOT_STEPS_EXHAUSTED] * 4)


# ---------------------------------------------------------------------------
# NON_FINITE: a NaN injected mid-run
# ---------------------------------------------------------------------------
@pytest.mark.parametrize("driver", DRIVERS)
@pytest.mark.parametrize("make_scene", [lens, rotor], ids=["closed form", "searched"])
def test_a_nan_injected_mid_run_is_non_finite(driver, make_scene):
    """A run stopped after 10 collisions resumes from a checkpoint whose orbit 1 has turned NaN: that orbit
    reports ``NON_FINITE`` (and NaN), the others finish bitwise as if nothing had happened."""
    scene = make_scene()
    states = starts(scene, 3)
    whole = jb.run(scene, states, 20, driver=driver)
    first = jb.run(scene, states, 10, driver=driver)
    assert np.all(first.checkpoint.result == R.FINISHED)
    damaged_state = first.checkpoint.state.copy()
    damaged_state[1, 0] = np.nan
    damaged = dataclasses.replace(first.checkpoint, state=damaged_state)
    rest = jb.run(scene, states, 20, driver=driver, resume=damaged)
    np.testing.assert_array_equal(rest.result, [R.FINISHED, R.NON_FINITE, R.FINISHED])
    assert np.all(np.isnan(rest.final_state[1])) and np.isnan(rest.time[1])
    np.testing.assert_array_equal(rest.final_state[[0, 2]], whole.final_state[[0, 2]])
    np.testing.assert_array_equal(rest.checkpoint.result, rest.result)


def test_result_codes_survive_a_checkpoint_file(tmp_path):
    """A run directory's checkpoint keeps the codes: resuming continues them."""
    scene, state, moving = AT_REST["lens at rest"]
    batch = np.stack([np.asarray(state), np.asarray(moving)])
    jb.run(scene, batch, 4, out=tmp_path / "run")
    saved = jb.Checkpoint.load(tmp_path / "run")
    np.testing.assert_array_equal(saved.result, [R.NO_WALL, R.FINISHED])
    resumed = jb.run(scene, batch, 8, out=tmp_path / "run", resume=True)
    np.testing.assert_array_equal(resumed.result, [R.NO_WALL, R.FINISHED])


# ---------------------------------------------------------------------------
# BOUND_VIOLATED: a user's table with too small a Hessian bound
# ---------------------------------------------------------------------------
def _ellipse_function(x, y):
    return x * x / 4.0 + y * y / 2.0 - 1.0


def _convex_scene(hessian_bound):
    # Hess F = diag(1/2, 1): a bound of 1.5 (the estimate's margin) holds, 1e-3 does not.
    table = jb.ConvexTable(_ellipse_function, (-2.5, 2.5, -1.6, 1.6), hessian_bound=hessian_bound)
    return jb.BodyInTable(jb.PointBody(), table)


def test_a_hessian_bound_too_small_is_a_bound_violated():
    """The search checks the gap's curvature ``-v^T Hess F v`` against the bound at every step: a bound
    far below the true Hessian stops it at the first step, and the code says so, not merely NaN."""
    state = np.array([0.1, 0.2, 0.0, 0.6, 0.5, 0.0])
    sound = jb.orbit(_convex_scene(1.5), state, 4)
    assert int(sound.result) == R.FINISHED and np.all(np.isfinite(np.asarray(sound.t)))
    broken = _convex_scene(1e-3)
    orbit = jb.orbit(broken, state, 4)
    assert int(orbit.result) == R.BOUND_VIOLATED and np.all(np.isnan(np.asarray(orbit.t)))
    batch = np.stack([state, state * 0.5])
    for driver in ("serial", "lockstep", "lanes"):
        np.testing.assert_array_equal(
            jb.run(broken, batch, 4, driver=driver).result, [R.BOUND_VIOLATED] * 2, err_msg=driver
        )
    assert int(jb.fli(broken, state, 2, n_history=1).result) == R.BOUND_VIOLATED


# ---------------------------------------------------------------------------
# empty batches and n = 0
# ---------------------------------------------------------------------------
def test_an_empty_batch_gives_empty_results_everywhere():
    scene = lens()
    empty = np.zeros((0, scene.state_size))
    orbit = jb.orbit(scene, empty, 5)
    assert orbit.t.shape == (0, 5) and orbit.state.shape == (0, 5, 6) and orbit.result.shape == (0,)
    run = jb.run(scene, empty, 5)
    assert run.final_state.shape == (0, 6) and run.result.shape == (0,)
    spectrum = jb.lyapunov_spectrum(scene, empty, 4, n_history=2)
    assert spectrum.exponents.shape == (0, 4) and spectrum.result.shape == (0,)
    indicator = jb.fli(scene, empty, 4, n_history=2)
    assert indicator.value.shape == (0,) and indicator.result.shape == (0,)
    assert jb.megno(scene, empty, 4, n_history=2).result.shape == (0,)
    assert jb.finite_time_lyapunov(scene, empty, 4).result.shape == (0,)
    assert jb.fli_map(scene, empty, 4).shape == (0,)
    assert jb.fli_map(scene, np.zeros((3, 0, 6)), 4).shape == (3, 0)


@pytest.mark.parametrize("driver", DRIVERS)
def test_zero_collisions_finish_at_the_start(driver):
    scene = rotor()
    states = starts(scene, 3)
    orbit = jb.orbit(scene, states, 0, driver=driver)
    assert orbit.t.shape == (3, 0) and np.all(np.asarray(orbit.result) == R.FINISHED)
    run = jb.run(scene, states, 0, driver=driver)
    np.testing.assert_array_equal(run.final_state, states)
    np.testing.assert_array_equal(run.result, [R.FINISHED] * 3)
    assert int(jb.orbit(scene, states[0], 0).result) == R.FINISHED


def test_the_first_collisions_of_an_orbit_are_a_shorter_orbit_with_its_code():
    """``Orbit.first(k)`` of an orbit (and of a batch) is the orbit run for ``k`` collisions, bit for bit, with
    the result code it carries: for one orbit a scalar, for a batch one per orbit."""
    scene = jb.StickInCircle(R=1.0, ell=0.6)
    states = random_states(np.random.default_rng(5), 3, 1.0, 0.6, "rotor")
    for start in (states[0], states):
        short, long = jb.orbit(scene, start, 7), jb.orbit(scene, start, 30).first(7)
        for name in ("t", "contact", "state", "result"):
            np.testing.assert_array_equal(np.asarray(getattr(long, name)), np.asarray(getattr(short, name)))
