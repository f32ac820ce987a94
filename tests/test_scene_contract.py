"""The contract every scene keeps: one set of checks, run over every scene of ``scene_catalogue.py``.

Each scene, hand-built or composed from a body and a table, goes through the
drivers, the Pallas kernels, the tangent maps, the energy-shell sampler, its
section chart (what the explorer seeds, reads and draws) and bad input. Each
test asserts a property that holds independently of the code under test:
bitwise agreement between two calls of one program, agreement between
independent drivers, energy conservation, the flow direction in the kernel of
the collision map's Jacobian, a chart's points inverting its own starts, the
chart's reachable edge, and the library's stated errors for bad starts.
"""

from __future__ import annotations

import functools
import inspect

import jax
import jax.numpy as jnp
import numpy as np
import pytest

import jaxbill as jb
from jaxbill._check.checker import flight_for
from jaxbill._engine import lanes as _lanes
from jaxbill._engine import pallas as _pallas
from jaxbill._explorer import section_chart
from jaxbill._scenes import protocols as _protocols
from scene_catalogue import NAMES, SCENES, start_states

R = jb.Result


@functools.cache
def _starts(name: str) -> np.ndarray:
    """Eight valid starts of scene ``name`` (``scene_catalogue.start_states``), drawn when a test first asks."""
    return start_states(SCENES[name], 8, seed=3)


def _chart(scene):
    """The explorer's chart of ``scene``, or None where the explorer refuses it (and then says why)."""
    try:
        return section_chart(scene)
    except TypeError as refused:
        assert str(refused).startswith("scene: ") and "section" in str(refused)
        return None


CHARTED = [name for name in NAMES if SCENES[name].sections and _chart(SCENES[name]) is not None]


def test_the_catalogue_holds_every_public_scene_body_table_and_piece():
    """A public scene class, body, table or wall piece the catalogue leaves out would escape the contract."""
    public = [getattr(jb, name) for name in jb.__all__]
    composed = [scene for scene in SCENES.values() if isinstance(scene, jb.BodyInTable)]
    held = {type(scene) for scene in SCENES.values()}
    held |= {type(scene.body) for scene in composed} | {type(scene.table) for scene in composed}
    held |= {type(piece) for scene in composed for piece in scene.table.pieces}
    kinds = (jb.Body, jb.Table, jb.Piece)
    expected = {
        value
        for value in public
        if inspect.isclass(value)
        and not inspect.isabstract(value)
        and (issubclass(value, kinds) or hasattr(value, "contact_codes"))
    }
    assert expected - held == set(), sorted(c.__name__ for c in expected - held)


@pytest.mark.parametrize("name", NAMES)
def test_every_scene_answers_the_capability_protocols(name):
    """What the analyses ask of a scene, it answers: its periodic symmetry, the checker's flight, and where
    it has sections, the area-preserving one among them, the explorer's chart, and a clear error for a
    section it does not have."""
    scene = SCENES[name]
    assert scene.periodic_symmetry in _protocols.PERIODIC_SYMMETRIES
    assert isinstance(flight_for(scene, scene.checker_flight()), _protocols.CheckerFlight)
    if scene.sections:
        assert scene.area_preserving_section in scene.sections
        assert name not in CHARTED or isinstance(section_chart(scene), _protocols.SectionChart)
        with pytest.raises(ValueError, match="name must be one of"):
            scene.section(jnp.zeros((1, scene.state_size)), jnp.ones(1, jnp.int32), name="no such section")


def _close(a, b):
    """Equal to rounding: vectorised arithmetic and the kernel may round a last bit differently, which a
    chaotic orbit then grows over a few collisions (the catalogue's lengths and speeds are of order one)."""
    return np.all(np.abs(np.asarray(a) - np.asarray(b)) <= 1e-10 * (1.0 + np.abs(np.asarray(b))))


@pytest.mark.parametrize("name", NAMES)
def test_drivers_agree_and_run_is_orbit_bit_for_bit(name):
    """Serial, lockstep, the lane state machine and the Pallas kernel (interpret mode) take the same
    collisions; ``jb.run`` and ``jb.orbit``, one program twice, agree bit for bit; every contact code is
    one the scene declares, every orbit finishes, and every collision keeps the energy (elastic impulse)."""
    scene, states = SCENES[name], _starts(name)
    reference = jb.orbit(scene, states, 8, driver="serial")
    assert np.all(np.isfinite(np.asarray(reference.t)))
    np.testing.assert_array_equal(np.asarray(reference.result), R.FINISHED)
    start_energy = np.asarray(jb.energy(scene, states))[:, None]
    np.testing.assert_allclose(np.asarray(jb.energy(scene, reference.state)) / start_energy, 1.0, rtol=1e-13)
    lanes = jb.orbit(scene, states, 8, driver="lanes")
    for driver, other in (("lockstep", jb.orbit(scene, states, 8, driver="lockstep")), ("lanes", lanes)):
        np.testing.assert_array_equal(np.asarray(other.contact), np.asarray(reference.contact), err_msg=driver)
        assert _close(other.state, reference.state), driver
    serial = jb.run(scene, states, 8, driver="serial")
    np.testing.assert_array_equal(serial.final_state, np.asarray(reference.state[:, -1]))
    np.testing.assert_array_equal(serial.time, np.asarray(reference.t[:, -1]))
    kernel = jb.run(scene, states, 8, driver="pallas")
    assert _close(kernel.final_state, lanes.state[:, -1])
    codes = set(np.unique(np.asarray(reference.contact)).tolist())
    assert codes <= set(scene.contact_codes), codes


@pytest.mark.parametrize("name", NAMES)
def test_pallas_kernels_lower_for_cuda(name):
    """The plain kernel and the tangent kernel compile for a GPU without one: lowered for CUDA, each is a
    Triton call (a scene whose dynamical directions are not state coordinates is refused by the tangent
    kernel, by name)."""
    scene = SCENES[name]
    states = jnp.zeros((64, scene.state_size))
    final = (
        jax.jit(lambda s, c: _pallas.pallas_final(scene, s, c, 10))
        .trace(states, _lanes.fresh_carry(scene, states))
        .lower(lowering_platforms=("cuda",))
    )
    assert "triton" in final.as_text().lower()
    tangent = jax.jit(lambda s, w: _pallas.pallas_fli(scene, s, w, 10))
    if not hasattr(scene, "dynamical_indices"):  # its tangent lives in a frame the kernel does not carry
        with pytest.raises(ValueError, match="use jb.fli"):
            tangent.trace(states, states)
        return
    assert "triton" in tangent.trace(states, states).lower(lowering_platforms=("cuda",)).as_text().lower()


@pytest.mark.parametrize("name", NAMES)
def test_the_collision_map_annihilates_the_flow_direction(name):
    """``DP f(s) = 0``: moving the start along its own flight changes nothing after the collision; the
    flow's tangent map takes ``f(s)`` to ``f(s')``."""
    scene = SCENES[name]
    state = jnp.asarray(_starts(name)[0])
    new_state, _, _, section_jacobian = jb.tangent_map(scene, state)
    f = jb.phase_velocity(scene, state)
    assert float(jnp.max(jnp.abs(section_jacobian @ f))) < 1e-9 * float(jnp.max(jnp.abs(section_jacobian)))
    *_, flow_jacobian = jb.tangent_map(scene, state, flow=True)
    np.testing.assert_allclose(
        np.asarray(flow_jacobian @ f), np.asarray(jb.phase_velocity(scene, new_state)), atol=1e-9
    )


@pytest.mark.parametrize("name", NAMES)
def test_the_sampler_draws_valid_states_on_the_shell_or_says_it_has_none(name):
    scene = SCENES[name]
    if not hasattr(scene, "sample_states"):
        with pytest.raises(TypeError, match="sample_states"):
            jb.sample_energy_shell(scene, 4)
        return
    states, weights = jb.sample_energy_shell(scene, 40, seed=2)
    np.testing.assert_allclose(np.asarray(jb.energy(scene, states)), 0.5, rtol=1e-14)
    assert np.all(np.asarray(scene.gaps(states)) > 0.0) and np.all(np.asarray(weights) > 0)
    if not scene.body_turns:
        assert np.all(np.asarray(states)[:, 5] == 0.0)


@pytest.mark.parametrize("name", NAMES)
def test_the_section_chart_inverts_its_starts(name):
    """What the explorer does with a click: the chart's state at a reachable section point ``(x, y)`` is just
    after a collision (its contact touching), and the chart reads ``(x, y)`` back from it. A scene with no
    section says so by name."""
    scene = SCENES[name]
    if name not in CHARTED:
        with pytest.raises(TypeError, match="^scene: .*section"):
            jb.explore(scene)
        return
    chart = section_chart(scene)
    invariants = chart.default_invariants(scene)
    x_low, x_high = chart.x_range(scene)
    rng = np.random.default_rng(4)
    x = rng.uniform(x_low, x_high, 40)
    edge = np.asarray(chart.edge(scene, x, invariants))
    y = edge[:, 0] + (edge[:, 1] - edge[:, 0]) * rng.uniform(0.05, 0.95, 40)
    states, contacts = chart.start(scene, x, y, invariants)
    states = np.asarray(states)
    found = np.all(np.isfinite(states), axis=1)
    assert found.sum() >= 10, found.sum()
    points = np.asarray(chart.points(scene, jnp.asarray(states[found]), jnp.asarray(contacts)[found]))
    np.testing.assert_allclose(points, np.stack([x, y], axis=-1)[found], atol=1e-9)
    touching = np.min(np.abs(np.asarray(scene.gaps(states[found]))), axis=-1)
    assert np.all(touching <= 1e-12 * float(scene.gap_scale))


@pytest.mark.parametrize("name", CHARTED)
def test_the_section_charts_seeds_stay_within_its_edge(name):
    """The explorer's survey: the chart's seeds are valid starts, and every section point of their orbits
    lies between the chart's lowest and highest reachable ``y``."""
    scene = SCENES[name]
    chart = section_chart(scene)
    invariants = chart.default_invariants(scene)
    states, _ = chart.seeds(scene, 24, invariants)
    states = np.asarray(states)
    good = np.all(np.isfinite(states), axis=1)
    assert good.sum() >= 12
    orbit = jb.orbit(scene, states[good], 8)
    np.testing.assert_array_equal(np.asarray(orbit.result), R.FINISHED)
    points = np.asarray(chart.points(scene, orbit.state, orbit.contact)).reshape(-1, 2)
    points = points[np.all(np.isfinite(points), axis=1)]
    assert len(points) >= 40
    low, high = np.asarray(chart.edge(scene, points[:, 0], invariants)).T
    slack = 1e-9 * (np.abs(low) + np.abs(high) + 1.0)
    assert np.all(points[:, 1] <= high + slack) and np.all(points[:, 1] >= low - slack)


def _outside(scene, states):
    """The starts moved far away, or (in a periodic gas, where far away is another cell) onto the centre
    of the cell's disc: wherever the scene holds none of them valid."""
    position = slice(0, 3) if scene.state_size == 12 else slice(0, 2)
    for factor in (100.0, 0.0):
        moved = states.copy()
        moved[:, position] *= factor
        if not np.any(np.asarray(jax.vmap(scene.is_valid)(jnp.asarray(moved)))):
            return moved
    raise AssertionError("no outside start found")


@pytest.mark.parametrize("name", NAMES)
def test_bad_starts_are_refused_by_name_and_poisoned_under_jit(name):
    """Eagerly: a start outside the table, a non-finite one and a wrongly shaped one raise ``ValueError``
    naming ``state``. Under ``jit``, where nothing can raise, the non-finite start's orbit is NaN and says
    ``INVALID_START`` while its neighbours finish."""
    scene, states = SCENES[name], _starts(name)[:3]
    outside = _outside(scene, states)
    with pytest.raises(ValueError, match="^state .*outside"):
        jb.orbit(scene, outside, 2)
    broken = states.copy()
    broken[1, 0] = np.nan
    with pytest.raises(ValueError, match="^state must be finite"):
        jb.orbit(scene, broken, 2)
    with pytest.raises(ValueError, match="state"):
        jb.orbit(scene, states[:, :-1], 2)
    orbit = jax.jit(lambda s: jb.orbit(scene, s, 8))(jnp.asarray(broken))
    np.testing.assert_array_equal(np.asarray(orbit.result), [R.FINISHED, R.INVALID_START, R.FINISHED])
    assert np.all(np.isnan(np.asarray(orbit.t[1]))) and np.all(np.isfinite(np.asarray(orbit.t)[[0, 2]]))
