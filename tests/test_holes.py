"""Holes in a table's boundary and a user's stopping condition: an orbit that ends stays where it ended.

References, none read back from the library:

* a point in a circle: every chord subtends the same angle, so the contact
  points march round by ``pi - 2 theta`` (``theta`` the angle of incidence)
  and each flight lasts ``2 R cos theta``; the first contact point in a hole,
  its time and its arrival state are computed here by hand;
* Kac's lemma for an ergodic billiard: started on a hole with the invariant
  measure of the collision map restricted to it (``s`` uniform on the hole,
  ``p = sin`` of the angle uniform in ``[-1, 1]``), an orbit returns to the
  hole after ``P / w`` boundary collisions on average and after a time
  ``pi A / w`` (the phase volume ``2 pi A`` over the hole's flux ``2 w``), for
  unit speed, exactly and for any hole, where ``A`` is the table's area, ``P``
  its perimeter and ``w`` the hole's length. The hexagonal Lorentz gas with a
  finite horizon is uniformly hyperbolic, so the return times have an
  exponential tail and their sample's error bar is the usual ``std / sqrt(N)``
  (Sinai's square and the stadium have corridors and bouncing balls whose long
  sojourns leave the variance of the return time barely finite);
* the drivers against one another, and bad input against its messages.
"""

from __future__ import annotations

import numpy as np
import pytest

import jaxbill as jb

R = jb.Result
DRIVERS = ("serial", "lockstep", "lanes", "pallas")


def circle_start(radius, phi0, theta):
    """The state just after a collision at polar angle ``phi0``, leaving at ``theta`` from the inward normal,
    anticlockwise, at unit speed."""
    inward = -np.array([np.cos(phi0), np.sin(phi0)])
    along = np.array([-np.sin(phi0), np.cos(phi0)])
    v = np.cos(theta) * inward + np.sin(theta) * along
    return np.array([radius * np.cos(phi0), radius * np.sin(phi0), 0.0, v[0], v[1], 0.0])


def circle_escape(radius, phi0, theta, holes):
    """By hand: the number ``k`` of the first collision in a hole, its time and the state arriving there."""
    step = np.pi - 2.0 * theta
    v0 = circle_start(radius, phi0, theta)[3:5]
    for k in range(1, 10_000):
        phi = phi0 + k * step
        s = radius * np.mod(phi, 2.0 * np.pi)
        if any(low <= s <= high for low, high in holes):
            turn = (k - 1) * step  # each reflection in a circle turns the velocity by the chord's angle
            vx = np.cos(turn) * v0[0] - np.sin(turn) * v0[1]
            vy = np.sin(turn) * v0[0] + np.cos(turn) * v0[1]
            arrival = np.array([radius * np.cos(phi), radius * np.sin(phi), 0.0, vx, vy, 0.0])
            return k, k * 2.0 * radius * np.cos(theta), arrival
    raise AssertionError("no hole is ever hit")


CIRCLE_CASES = {
    # (R, phi0, theta, holes): contact points kept well away from the holes' ends
    "six chords": (1.0, 0.3, 0.4, [(1.7, 1.9)]),
    "two holes, the second hit": (2.0, 1.0, 1.1, [(0.5, 0.6), (9.0, 9.4)]),
    "a hole across s = 0": (1.5, 2.0, 0.2, [(0.0, 0.3), (2 * np.pi * 1.5 - 0.4, 2 * np.pi * 1.5)]),
}


@pytest.mark.parametrize("name", list(CIRCLE_CASES))
def test_the_escape_in_a_circle_is_the_chords_closed_form(name):
    radius, phi0, theta, holes = CIRCLE_CASES[name]
    k, exit_time, arrival = circle_escape(radius, phi0, theta, holes)
    scene = jb.BodyInTable(jb.PointBody(), jb.Circle(radius), holes=holes)
    n = k + 3
    orbit = jb.orbit(scene, circle_start(radius, phi0, theta), n)
    t, contact, state = np.asarray(orbit.t), np.asarray(orbit.contact), np.asarray(orbit.state)
    assert int(orbit.result) == R.ESCAPED
    np.testing.assert_array_equal(contact, [3] * (k - 1) + [-1] + [0] * (n - k))
    np.testing.assert_allclose(t[k - 1 :], exit_time, rtol=1e-13)
    np.testing.assert_array_equal(t[k:], t[k - 1])  # the time stays the exit time, exactly
    np.testing.assert_allclose(state[k - 1], arrival, atol=1e-12)
    np.testing.assert_array_equal(state[k:], np.broadcast_to(state[k - 1], (n - k, 6)))
    run = jb.run(scene, circle_start(radius, phi0, theta), n)
    codes = list(run.contact_codes)
    assert run.contact_counts[codes.index(3)] == k - 1 and run.contact_counts[codes.index(-1)] == 1
    assert int(run.result) == R.ESCAPED and run.time == t[k - 1]


def test_an_orbit_that_escapes_after_the_last_collision_asked_for_finishes():
    radius, phi0, theta, holes = CIRCLE_CASES["six chords"]
    k, _, _ = circle_escape(radius, phi0, theta, holes)
    scene = jb.BodyInTable(jb.PointBody(), jb.Circle(radius), holes=holes)
    orbit = jb.orbit(scene, circle_start(radius, phi0, theta), k - 1)
    assert int(orbit.result) == R.FINISHED and np.all(np.asarray(orbit.contact) == 3)


def test_a_resumed_run_stays_escaped_at_the_exit_time():
    radius, phi0, theta, holes = CIRCLE_CASES["six chords"]
    k, exit_time, arrival = circle_escape(radius, phi0, theta, holes)
    scene = jb.BodyInTable(jb.PointBody(), jb.Circle(radius), holes=holes)
    start = circle_start(radius, phi0, theta)
    first = jb.run(scene, start, k + 1)
    rest = jb.run(scene, start, k + 20, resume=first.checkpoint)
    assert int(rest.result) == R.ESCAPED
    assert rest.time == first.time and abs(rest.time - exit_time) < 1e-13 * exit_time
    np.testing.assert_array_equal(rest.final_state, first.final_state)
    np.testing.assert_allclose(rest.final_state, arrival, atol=1e-12)


def _every_collision(scene, state, contact):
    return True


@pytest.mark.parametrize("driver", ["serial", "lanes"])
def test_a_section_records_the_exit_and_nothing_after_it(driver):
    radius, phi0, theta, holes = CIRCLE_CASES["six chords"]
    k, exit_time, arrival = circle_escape(radius, phi0, theta, holes)
    scene = jb.BodyInTable(jb.PointBody(), jb.Circle(radius), holes=holes)
    starts = np.stack([circle_start(radius, phi0, theta)] * 2)
    run = jb.run(scene, starts, k + 5, record=jb.Section(where=_every_collision), driver=driver)
    assert run.section is not None
    for orbit in (0, 1):
        mine = run.section.orbit == orbit
        np.testing.assert_array_equal(run.section.collision[mine], np.arange(1, k + 1))
        np.testing.assert_allclose(run.section.point[mine][-1], arrival, atol=1e-12)
        assert abs(run.section.t[mine][-1] - exit_time) < 1e-13 * exit_time


# ---------------------------------------------------------------------------
# Kac's lemma: the mean return time to a hole of an ergodic billiard
# ---------------------------------------------------------------------------
def test_mean_escape_from_a_hole_is_kacs_return_time():
    table = jb.LorentzGas(0.45, 1.0)  # hexagonal, finite horizon
    assert table.finite_horizon
    perimeter, area = float(table.boundary_length), float(table.area)
    width = perimeter / 20.0
    scene = jb.BodyInTable(jb.PointBody(), table, holes=[(0.0, width)])
    rng = np.random.default_rng(2)
    count = 20_000
    on_hole = np.stack([rng.uniform(0.0, width, count), rng.uniform(-1.0, 1.0, count)], axis=-1)
    states = np.asarray(scene.section_state(on_hole, energy=0.5))  # unit speed, leaving the hole inwards
    assert np.all(np.isfinite(states))
    disc = 3  # the disc is wall 0; the cell's sides (crossed, never hit) follow
    # Most orbits are back within 200 collisions (crossings included); those still out run on from their states.
    first = jb.run(scene, states, 200)
    time, bounces = first.time.copy(), first.contact_counts[:, list(first.contact_codes).index(disc)].copy()
    out = first.result != R.ESCAPED
    assert np.all(first.result[out] == R.FINISHED) and out.mean() < 0.05
    second = jb.run(scene, first.final_state[out], 2000)
    assert np.all(second.result == R.ESCAPED)
    time[out] += second.time
    bounces[out] += second.contact_counts[:, list(second.contact_codes).index(disc)]
    collisions = bounces + 1  # the return into the hole is a collision with the boundary too
    mean_time, time_error = time.mean(), time.std() / np.sqrt(count)
    mean_collisions, collision_error = collisions.mean(), collisions.std() / np.sqrt(count)
    assert abs(mean_time - np.pi * area / width) < 4.0 * time_error
    assert abs(mean_collisions - perimeter / width) < 4.0 * collision_error
    assert time_error < 0.02 * mean_time  # the test can fail: the error bar is a small share of the mean


# ---------------------------------------------------------------------------
# Every driver ends an orbit at the same collision
# ---------------------------------------------------------------------------
def _stop_in_the_upper_half(state):
    return state[1] > 0.3


def sinai_starts(scene, count, seed=5):
    rng = np.random.default_rng(seed)
    perimeter = float(scene.table.boundary_length)
    points = np.stack([rng.uniform(0.0, perimeter, count), rng.uniform(-0.9, 0.9, count)], axis=-1)
    return np.asarray(scene.section_state(points))


# holes on the right side and on the disc (its arc length runs clockwise, after the four sides of length 1)
SINAI_HOLES = [(1.2, 1.8), (4.3, 4.8)]


def sinai_with_holes_and_a_condition(count=40, n=12):
    """The closed Sinai table, the same table with ``SINAI_HOLES`` and the stopping condition, ``count`` starts,
    and, from the closed table's orbits of ``n`` collisions: the closed orbits, and per start the index of the
    first collision in a hole and of the first that meets the condition (``n``: none)."""
    plain = jb.BodyInTable(jb.PointBody(), jb.Sinai(0.25))
    scene = jb.BodyInTable(jb.PointBody(), jb.Sinai(0.25), holes=SINAI_HOLES, stop_when=_stop_in_the_upper_half)
    states = sinai_starts(scene, count)
    closed = jb.orbit(plain, states, n)
    s = np.asarray(plain.section(closed.state, closed.contact))[..., 0]
    in_hole = np.any([(s >= low) & (s <= high) for low, high in SINAI_HOLES], axis=0)
    condition = np.asarray(closed.state)[..., 1] > 0.3
    first_hole = np.where(in_hole.any(-1), np.argmax(in_hole, -1), n)
    first_stop = np.where(condition.any(-1), np.argmax(condition, -1), n)
    return plain, scene, states, closed, first_hole, first_stop


def test_every_driver_ends_the_same_orbits_at_the_same_collision():
    """Each orbit ends where the same orbit in the closed table first hits a hole (its Birkhoff ``s``) or first
    satisfies the condition, whichever comes first, with the same code, time and counts in every driver."""
    n = 12
    _, scene, states, closed, first_hole, first_stop = sinai_with_holes_and_a_condition(n=n)
    escapes = first_hole <= first_stop  # a hole is checked before the condition
    last = np.minimum(first_hole, first_stop)
    expected = np.where(last == n, R.FINISHED, np.where(escapes, R.ESCAPED, R.STOPPED))
    assert np.sum(expected == R.ESCAPED) >= 5 and np.sum(expected == R.STOPPED) >= 5  # both ways happen
    closed_t = np.asarray(closed.t)
    end_time = closed_t[np.arange(len(states)), np.minimum(last, n - 1)]

    orbit = jb.orbit(scene, states, n)
    np.testing.assert_array_equal(np.asarray(orbit.result), expected)
    counts_by_driver = {}
    for driver in (None, *DRIVERS):
        run = jb.run(scene, states, n, driver=driver)
        np.testing.assert_array_equal(run.result, expected, err_msg=str(driver))
        np.testing.assert_allclose(run.time, end_time, rtol=1e-12, err_msg=str(driver))
        counts_by_driver[driver] = run.contact_counts
        codes = list(run.contact_codes)
        # Contacts with a wall: every collision but those with none (held, after the end) and the exit.
        walls = run.collisions - run.contact_counts[:, codes.index(0)] - run.contact_counts[:, codes.index(-1)]
        np.testing.assert_array_equal(walls, np.where(escapes, last, np.minimum(last + 1, n)), err_msg=str(driver))
        np.testing.assert_array_equal(run.contact_counts[:, codes.index(-1)], expected == R.ESCAPED)
    for driver, counts in counts_by_driver.items():
        np.testing.assert_array_equal(counts, counts_by_driver["serial"], err_msg=str(driver))
    lanes = jb.orbit(scene, states, n, driver="lanes")
    np.testing.assert_array_equal(np.asarray(lanes.contact), np.asarray(orbit.contact))


def _spun_up(state):
    return state[5] > 1.0


def test_a_turning_body_stops_where_its_orbit_first_meets_the_condition():
    """A body whose contact times are searched: the orbit in the scene without the condition says where it
    first holds; every driver stops there, keeping the state after that collision."""
    plain = jb.BodyInTable(jb.Dumbbell(0.5), jb.Circle(1.0))
    scene = jb.BodyInTable(jb.Dumbbell(0.5), jb.Circle(1.0), stop_when=_spun_up)
    rng = np.random.default_rng(3)
    points = np.stack([rng.uniform(0.0, 2.0 * np.pi, 16), rng.uniform(-0.8, 0.8, 16)], axis=-1)
    states = np.asarray(scene.section_state(points, arm_angle=0.3, spin=0.0))
    n = 10
    closed = jb.orbit(plain, states, n)
    spins = np.asarray(closed.state)[..., 5] > 1.0
    first = np.where(spins.any(-1), np.argmax(spins, -1), n)
    assert 3 <= np.sum(first < n) <= 13
    rows = np.arange(len(states))
    for driver in ("serial", "lockstep", "lanes"):
        orbit = jb.orbit(scene, states, n, driver=driver)
        np.testing.assert_array_equal(np.asarray(orbit.result), np.where(first < n, R.STOPPED, R.FINISHED))
        final = np.asarray(orbit.state)[:, -1]
        expected = np.asarray(closed.state)[rows, np.minimum(first, n - 1)]
        np.testing.assert_allclose(final, expected, rtol=1e-12, atol=1e-12, err_msg=driver)


def test_a_stopped_orbit_keeps_the_state_after_the_collision_that_stopped_it():
    """In a circle the contact points are known by hand: the orbit stops at the first with ``y > 0.9``."""
    radius, phi0, theta = 1.0, 0.3, 0.4
    step = np.pi - 2.0 * theta
    ys = radius * np.sin(phi0 + step * np.arange(1, 50))
    k = int(np.argmax(ys > 0.9)) + 1
    scene = jb.BodyInTable(jb.PointBody(), jb.Circle(radius), stop_when=_stop_above_09)
    orbit = jb.orbit(scene, circle_start(radius, phi0, theta), k + 2)
    assert int(orbit.result) == R.STOPPED
    np.testing.assert_array_equal(np.asarray(orbit.contact), [3] * k + [0, 0])
    np.testing.assert_allclose(np.asarray(orbit.t)[k - 1 :], k * 2.0 * radius * np.cos(theta), rtol=1e-13)
    state = np.asarray(orbit.state)
    assert state[k - 1, 1] > 0.9 and np.all(state[: k - 1, 1] <= 0.9)
    # after the impulse: the velocity points inwards
    assert state[k - 1, 0] * state[k - 1, 3] + state[k - 1, 1] * state[k - 1, 4] < 0
    np.testing.assert_array_equal(state[k:], np.broadcast_to(state[k - 1], (2, 6)))


def _stop_above_09(state):
    return state[1] > 0.9


# ---------------------------------------------------------------------------
# Bad input
# ---------------------------------------------------------------------------
@pytest.mark.parametrize(
    "holes, message",
    [
        ([(1.0, 7.0)], "ends beyond the boundary"),
        ([(-0.1, 0.5)], "0 <= s_low < s_high"),
        ([(0.5, 0.5)], "0 <= s_low < s_high"),
        ([(0.6, 0.5)], "0 <= s_low < s_high"),
        ([(0.1, float("nan"))], "finite"),
        ([(0.1, 0.5), (0.4, 0.9)], "overlap"),
        ([(0.1, 0.5, 0.7)], "pairs"),
        (0.5, "pairs"),
    ],
)
def test_bad_holes_are_refused_by_name(holes, message):
    with pytest.raises(ValueError, match="holes") as error:
        jb.BodyInTable(jb.PointBody(), jb.Circle(1.0), holes=holes)
    assert message in str(error.value)


def test_holes_need_a_point_in_a_bounded_table():
    with pytest.raises(ValueError, match="holes: only a point"):
        jb.BodyInTable(jb.Dumbbell(0.5), jb.Circle(1.0), holes=[(0.1, 0.2)])
    with pytest.raises(ValueError, match="holes: .* no Birkhoff section"):
        jb.BodyInTable(jb.PointBody(), jb.Strip(1.0), holes=[(0.1, 0.2)])
    with pytest.raises(ValueError, match="stop_when"):
        jb.BodyInTable(jb.PointBody(), jb.Circle(1.0), stop_when=3.0)


def test_a_table_shrunk_under_its_holes_is_refused():
    scene = jb.BodyInTable(jb.PointBody(), jb.Circle(1.0), holes=[(5.0, 6.0)])
    with pytest.raises(ValueError, match="holes: the hole"):
        scene.with_parameters(R=0.5)
    touching = jb.BodyInTable(jb.PointBody(), jb.Circle(1.0), holes=[(0.1, 0.5), (0.5, 0.9)])
    assert touching.holes == ((0.1, 0.5), (0.5, 0.9))  # sharing an end is no overlap


def test_tangent_indicators_keep_the_values_of_an_orbits_last_reflection():
    """After an orbit ends, its FLI, MEGNO and Lyapunov exponents are those of the same orbit in the closed
    table after its last reflection: the collisions before a hole (the crossing is no reflection), or up to and
    including the one that met the stopping condition. The closed table's histories, one checkpoint per
    collision, give every truncation at once."""
    n = 12
    plain, scene, states, _, first_hole, first_stop = sinai_with_holes_and_a_condition(n=n)
    reflections = np.where(first_hole <= first_stop, first_hole, np.minimum(first_stop + 1, n))
    ended = reflections < n
    before_any = reflections == 0  # through a hole at the first collision
    assert np.sum(ended & ~before_any) >= 10 and 1 <= np.sum(before_any) <= 20
    rows, last = np.arange(len(states))[~before_any], reflections[~before_any] - 1

    fli_closed, fli_open = jb.fli(plain, states, n, n_history=n), jb.fli(scene, states, n)
    fli_value = np.asarray(fli_open.value)
    np.testing.assert_allclose(fli_value[~before_any], np.asarray(fli_closed.history)[rows, last], rtol=1e-12)
    np.testing.assert_allclose(np.asarray(fli_open.time)[~before_any], np.asarray(fli_closed.times)[rows, last])
    np.testing.assert_array_equal(fli_value[before_any], 0.0)  # the unit vector it started with
    megno_closed, megno_open = jb.megno(plain, states, n, n_history=n), jb.megno(scene, states, n)
    megno_value = np.asarray(megno_open.value)
    np.testing.assert_allclose(megno_value[~before_any], np.asarray(megno_closed.history)[rows, last], rtol=1e-12)
    np.testing.assert_array_equal(megno_value[before_any], 0.0)
    spectrum_closed = jb.lyapunov_spectrum(plain, states, n, per="collision", n_history=n)
    spectrum_open = jb.lyapunov_spectrum(scene, states, n, per="collision")
    exponents = np.asarray(spectrum_open.exponents)
    np.testing.assert_allclose(exponents[~before_any], np.asarray(spectrum_closed.history)[rows, last], rtol=1e-12)
    assert np.all(np.isnan(exponents[before_any]))  # no reflection: no rate
    np.testing.assert_array_equal(
        spectrum_open.result, np.where(ended, np.where(first_hole <= first_stop, R.ESCAPED, R.STOPPED), R.FINISHED)
    )
    # The kernel's tangent vector would run on through the hole: the map refuses it by name.
    with pytest.raises(ValueError, match="without holes or a stopping condition"):
        jb.fli_map(scene, states[:2], n, driver="pallas")
