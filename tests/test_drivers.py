"""The batch drivers, serial, lockstep and the lane state machine, run the same collision map.

All are built from the scene's own pieces (``jaxbill._engine.step``); the lane state
machine takes the root steps of many orbits in one loop, none waiting for
another. From identical states they must find the same contacts, in the same
number of root steps, with states and times equal to rounding; and the state
machine must handle what a batch throws at it: poisoned lanes, padding, lanes
that run out of steps, ``n = 0``, records every ``k`` collisions and sections.
These deep checks run over the hand-built scenes of ``scene_catalogue.py``;
every scene of the catalogue, compositions included, also keeps the contract of
``test_scene_contract.py`` (drivers, kernels, tangents, charts, bad input).
"""

import jax
import jax.numpy as jnp
import numpy as np
import pytest

import jaxbill as jb
from jaxbill._engine import collision as _collision
from jaxbill._engine import lanes as _lanes
from jaxbill._engine import step as _step
from jaxbill._engine.first_root import first_root
from scene_catalogue import hand_built as scenes
from scene_catalogue import start_states

INF = float("inf")
N = 40


@pytest.fixture(scope="module", params=list(scenes()))
def case(request):
    scene = scenes()[request.param]
    return request.param, scene, start_states(scene, scene.batch_chunk + 5)


def _one_collision_each(scene, states, driver):
    orbit = jb.orbit(scene, states, 1, driver=driver)
    return np.asarray(orbit.t[:, 0]), np.asarray(orbit.contact[:, 0]), np.asarray(orbit.state[:, 0])


def test_one_collision_agrees_between_drivers(case):
    """One collision from identical states: same contacts, states and times to rounding."""
    _, scene, states = case
    t_lock, contact_lock, state_lock = _one_collision_each(scene, states, "lockstep")
    t_lanes, contact_lanes, state_lanes = _one_collision_each(scene, states, "lanes")
    np.testing.assert_array_equal(contact_lanes, contact_lock)
    np.testing.assert_allclose(t_lanes, t_lock, rtol=1e-13, atol=0)
    scale = np.max(np.abs(state_lock), axis=1, keepdims=True)
    assert np.max(np.abs(state_lanes - state_lock) / scale) < 1e-13


def test_collision_by_collision_from_identical_states(case):
    """Each collision of the lane driver's orbit, restarted by the lockstep map from
    the lane driver's own previous state, agrees to rounding with the same contact:
    the comparison chaos cannot spoil."""
    _, scene, states = case
    orbit = jb.orbit(scene, states, N, driver="lanes")
    before = np.concatenate([states[:, None], np.asarray(orbit.state[:, :-1])], axis=1).reshape(-1, scene.state_size)
    t_lanes = np.diff(np.concatenate([np.zeros((states.shape[0], 1)), np.asarray(orbit.t)], axis=1), axis=1).ravel()
    t_lock, contact_lock, state_lock = _one_collision_each(scene, before, "lockstep")
    np.testing.assert_array_equal(np.asarray(orbit.contact).ravel(), contact_lock)
    np.testing.assert_allclose(t_lanes, t_lock, rtol=1e-12 * N, atol=1e-13)
    after = np.asarray(orbit.state).reshape(-1, scene.state_size)
    scale = np.max(np.abs(state_lock), axis=1, keepdims=True)
    assert np.max(np.abs(after - state_lock) / scale) < 1e-12


@pytest.mark.parametrize("driver", ["serial", None])
@pytest.mark.parametrize("devices", [1, 2])
def test_a_batch_is_bitwise_each_orbit_run_alone(case, driver, devices):
    """The serial driver and each scene's default give each orbit of a batch, on one device or two, bit
    for bit what the orbit gives alone."""
    name, scene, states = case
    if devices > len(jax.devices()):
        pytest.skip("one device")
    some = states[:: max(1, states.shape[0] // 5)]
    batch = jb.orbit_sharded(scene, some, N, devices=jax.devices()[:devices], driver=driver)
    for i, state0 in enumerate(some):
        alone = jb.orbit(scene, state0, N)
        np.testing.assert_array_equal(np.asarray(batch.state[i]), np.asarray(alone.state), err_msg=name)
        np.testing.assert_array_equal(np.asarray(batch.t[i]), np.asarray(alone.t), err_msg=name)
        np.testing.assert_array_equal(np.asarray(batch.contact[i]), np.asarray(alone.contact), err_msg=name)


def test_a_lockstep_lane_at_a_corner_gets_both_impulses():
    """In a lockstep lane the rare second impulse is computed only when some lane needs it: the lane that
    hits a corner gets it, exactly as alone, and its neighbours are untouched.

    A horizontal static stick flying straight up from the middle reaches the wall with both ends at once
    (its gaps are equal by symmetry, bit for bit); the first reflection leaves the other end approaching
    (``1 - 2 (n_y^2 - n_x^2) > 0`` at ``n = (1.5, sqrt(1.75)) / 2``), so both impulses apply: contact 2.
    """
    scene = jb.StickInCircle(R=2.0, ell=1.5, inertia=INF)
    states = start_states(scene, 7)
    states[3] = [0.0, 0.0, 0.0, 0.0, 1.0, 0.0]
    batch = jb.orbit(scene, states, 3, driver="lockstep")
    assert int(batch.contact[3, 0]) == 2 and np.all(np.abs(np.asarray(batch.contact)[np.arange(7) != 3, 0]) == 1)
    for i, state0 in enumerate(states):
        alone = jb.orbit(scene, state0, 3)
        np.testing.assert_array_equal(np.asarray(batch.state[i]), np.asarray(alone.state))
    energy = np.asarray(scene.energy(jnp.asarray(batch.state[3])))
    np.testing.assert_allclose(energy, 0.5, rtol=1e-15)
    run = jb.run(scene, states, 3, driver="lockstep")
    counts = dict(zip(_lanes.CONTACT_CODES, run.contact_counts[3], strict=False))
    assert counts[2] == 1


class _LensCountingTwoCodes(jb.StickInCircle):
    """A lens that lists only contacts 0 and 1: every other code must land in the last bin."""

    @property
    def contact_codes(self):
        return (0, 1)


@pytest.mark.parametrize("driver", ["serial", "lockstep", "lanes", "pallas"])
def test_contact_counts_of_codes_a_scene_does_not_list_go_to_the_last_bin(driver):
    scene = _LensCountingTwoCodes(R=2.0, ell=1.5, inertia=INF)
    states = start_states(scene, 7)
    contacts = np.asarray(jb.orbit(scene, states, 30, driver="lockstep").contact)
    assert {-1, 1} <= set(np.unique(contacts))  # both ends touch: code -1 is not listed
    run = jb.run(scene, states, 30, driver=driver)
    code = {c: k for k, c in enumerate(_lanes.CONTACT_CODES)}
    np.testing.assert_array_equal(run.contact_counts[:, code[1]], np.sum(contacts == 1, axis=1))
    np.testing.assert_array_equal(run.contact_counts[:, code[0]], np.sum(contacts == 0, axis=1))
    np.testing.assert_array_equal(run.contact_counts[:, -1], np.sum((contacts != 0) & (contacts != 1), axis=1))
    assert np.all(np.delete(run.contact_counts, [code[0], code[1], -1], axis=1) == 0)


def _lane_root_steps(scene, state):
    lane = _step.begin_flight(scene, state, scene.orbit_constants(state))
    lane = jax.lax.while_loop(
        lambda l: ~l.found & (l.steps < _step.MAX_ROOT_STEPS), lambda l: _step.search_step(scene, l), lane
    )
    return lane.t, lane.index, lane.steps


def test_same_root_steps_as_the_whole_collision_search():
    """The state machine's search takes exactly the steps of ``first_root`` and ends at the same root."""
    for name, scene in scenes().items():
        if not scene.searches_for_roots:
            continue
        states = jnp.asarray(start_states(scene, 32))
        t, index, steps = jax.vmap(lambda s: _lane_root_steps(scene, s))(states)

        def whole(s):
            profile, bounds = scene.root_search(s)
            return first_root(lambda tt: scene.gaps_along_flight(profile, tt), bounds, _step.MAX_ROOT_STEPS)

        t_ref, index_ref, steps_ref, ok = jax.vmap(whole)(states)
        assert bool(jnp.all(ok)), name
        np.testing.assert_array_equal(np.asarray(steps), np.asarray(steps_ref), err_msg=name)
        np.testing.assert_array_equal(np.asarray(index), np.asarray(index_ref), err_msg=name)
        np.testing.assert_allclose(np.asarray(t), np.asarray(t_ref), rtol=4e-15, err_msg=name)
        assert float(jnp.mean(steps)) > 1.0, name  # the search really iterated


def test_run_records_agree_between_drivers(case):
    """States every k collisions, run statistics and final states, in chunks that do not divide n."""
    name, scene, states = case
    runs = {d: jb.run(scene, states, N, record="states", every=3, chunk=17, driver=d) for d in ("lockstep", "lanes")}
    lock, lanes_run = runs["lockstep"], runs["lanes"]
    assert lanes_run.state.shape == lock.state.shape == (states.shape[0], N // 3, scene.state_size)
    np.testing.assert_array_equal(lanes_run.contact_counts.sum(axis=1), N)
    # Chaos amplifies rounding differences (by up to 10x a collision for the
    # walls): compare the first record, collision 3, across drivers ...
    np.testing.assert_array_equal(lanes_run.contact[:, 0], lock.contact[:, 0])
    np.testing.assert_allclose(lanes_run.t[:, 0], lock.t[:, 0], rtol=1e-12)
    assert np.all(lanes_run.max_energy_error < 1e-13), name


def test_a_resumed_run_is_bitwise_the_whole_run_with_the_lane_driver():
    """A checkpoint resumes bit for bit with the driver that wrote it: every chunk,
    the resumed ones too, is the same compiled program."""
    scene = jb.StickInCircle(R=2.0, ell=1.9)
    states = start_states(scene, scene.batch_chunk + 3)
    whole = jb.run(scene, states, N, record="states", every=2, chunk=10, driver="lanes")
    first = jb.run(scene, states, 20, record="states", every=2, chunk=10, driver="lanes")
    rest = jb.run(scene, states, N, record="states", every=2, chunk=10, driver="lanes", resume=first.checkpoint)
    np.testing.assert_array_equal(np.concatenate([first.state, rest.state], axis=1), whole.state)
    np.testing.assert_array_equal(rest.final_state, whole.final_state)
    np.testing.assert_array_equal(rest.contact_counts, whole.contact_counts)


def test_section_records_with_the_lane_driver():
    scene = jb.StickInCircle(R=2.0, ell=1.5, inertia=INF)
    states = start_states(scene, 10)
    section = jb.Section(where=_hits_p1, capacity=4)
    lanes_run = jb.run(scene, states, N, record=section, driver="lanes")
    orbit = jb.orbit(scene, states, N, driver="lanes")
    for i in range(states.shape[0]):
        kept = np.asarray(orbit.contact[i]) == 1
        of_orbit = lanes_run.section.orbit == i
        np.testing.assert_array_equal(lanes_run.section.point[of_orbit], np.asarray(orbit.state[i])[kept])
        np.testing.assert_array_equal(lanes_run.section.collision[of_orbit], np.flatnonzero(kept) + 1)


def _hits_p1(scene, state, contact):
    return contact == 1


def test_poisoned_lanes_and_zero_collisions():
    """A NaN lane inside jit poisons only its own orbit and cannot stall the others; n = 0 is empty."""
    scene = jb.StickInCircle(R=2.0, ell=1.9)
    states = start_states(scene, 5)
    bad = states.copy()
    bad[2, 0] = np.nan
    orbit = jax.jit(lambda s: jb.orbit(scene, s, N, driver="lanes"))(jnp.asarray(bad))
    good = jb.orbit(scene, states, N, driver="lanes")
    assert np.all(np.isnan(np.asarray(orbit.state[2]))) and np.all(np.asarray(orbit.contact[2]) == 0)
    keep = [0, 1, 3, 4]
    np.testing.assert_allclose(np.asarray(orbit.t[keep, :5]), np.asarray(good.t[keep, :5]), rtol=1e-12)
    empty = jb.orbit(scene, states, 0, driver="lanes")
    assert empty.state.shape == (5, 0, 6) and empty.t.shape == (5, 0)


def test_a_lane_out_of_root_steps_is_poisoned_not_hung(monkeypatch):
    """A search that hits the step bound proves nothing: that collision is NaN, contact 0, as for ``collide``."""
    scene = jb.StickInCircle(R=2.0, ell=1.9)
    states = jnp.asarray(start_states(scene, 4))
    monkeypatch.setattr(_step, "MAX_ROOT_STEPS", 1)
    monkeypatch.setattr(_lanes, "MAX_ROOT_STEPS", 1)
    orbit = jax.jit(lambda s: _collision._orbit_batch(scene, s, 3, "lanes"))(states)
    assert np.all(np.isnan(np.asarray(orbit.t))) and np.all(np.asarray(orbit.contact) == 0)
    assert np.all(np.isnan(np.asarray(orbit.state)))


def test_unknown_driver_is_refused():
    scene = jb.StickInCircle(R=2.0, ell=1.9)
    with pytest.raises(ValueError, match="driver"):
        jb.orbit(scene, start_states(scene, 2), 3, driver="gpu")


# ---------------------------------------------------------------------------
# the Pallas kernel (interpret mode on the CPU; lowered for CUDA)
# ---------------------------------------------------------------------------
from jaxbill._engine import pallas as _pallas  # noqa: E402


@pytest.mark.parametrize("name", list(scenes()))
def test_pallas_kernel_matches_the_xla_state_machine_collision_by_collision(name):
    """From identical states, one collision at a time: the kernel's states, times and
    contacts equal the XLA driver's to rounding."""
    scene = scenes()[name]
    states = jnp.asarray(start_states(scene, 32, seed=11))
    # Compiled once, outside the loop: a new lambda each time compiled both programs again.
    kernel_step = jax.jit(lambda s, c: _pallas.pallas_final(scene, s, c, 1, interpret=True))
    xla_step = jax.jit(lambda s, c: _lanes.run_block(_lanes.Plan("final"), scene, s, c, 0, 1))
    for _ in range(3):
        carry = _lanes.fresh_carry(scene, states)
        kernel = kernel_step(states, carry)
        xla, _ = xla_step(states, carry)
        np.testing.assert_array_equal(np.asarray(kernel.contact_counts), np.asarray(xla.contact_counts))
        np.testing.assert_allclose(np.asarray(kernel.time), np.asarray(xla.time), rtol=1e-14)
        scale = np.max(np.abs(np.asarray(xla.state)), axis=1, keepdims=True)
        assert np.max(np.abs(np.asarray(kernel.state) - np.asarray(xla.state)) / scale) < 1e-14
        states = xla.state


@pytest.mark.parametrize(
    "name, corner",
    [
        ("rotor 1.9", [0.0, 0.0, 0.0, 0.0, 1.0, 0.0]),
        ("lens", [0.0, 0.0, 0.0, 0.0, 1.0, 0.0]),
        ("walls 2D", [0.0, 1.5, np.pi / 2, 0.2, 1.0, 0.0]),
    ],
)
def test_pallas_rare_side_computed_by_block_changes_no_bit(name, corner):
    """The kernel computes a corner's impulse (``rarely``'s rare side) only in blocks where some lane
    needs it. A block with one lane flying square at the wall (both ends land at once: contact 2)
    among 31 ordinary lanes, and a block of ordinary lanes only, end bitwise as when every lane
    computes both sides and selects."""
    scene = scenes()[name]
    ordinary = np.array(start_states(scene, 64, seed=13))
    ordinary[5] = corner
    states = jnp.asarray(ordinary)
    results = [
        jax.jit(
            lambda s, by_block=by_block: _pallas.pallas_final(
                scene, s, _lanes.fresh_carry(scene, s), 6, interpret=True, rare_by_block=by_block
            )
        )(states)
        for by_block in (True, False)
    ]
    several = np.asarray(results[0].contact_counts)[:, _lanes.CONTACT_CODES.index(2)]
    assert several[5] >= 1 and np.all(several[32:] == 0)  # the rare side ran in the first block only
    for by_block, selected in zip(*results, strict=True):
        np.testing.assert_array_equal(np.asarray(by_block), np.asarray(selected))


@pytest.mark.parametrize("name", ["rotor 1.9", "walls 2D"])
def test_pallas_through_run_pads_to_whole_blocks_on_one_device(name):
    """On one device (a single GPU) ``jb.run(driver="pallas")`` pads the batch to
    whole kernel blocks, whatever the scene's lane width (16 for the rotor, 1 for
    the walls): a padding to lane widths once made the kernel refuse 37 orbits."""
    scene = scenes()[name]
    states = start_states(scene, 37)  # not a multiple of the block
    one = jax.devices()[:1]
    kernel = jb.run(scene, states, 12, driver="pallas", devices=one)
    xla = jb.run(scene, states, 12, driver="lanes", devices=one)
    np.testing.assert_array_equal(kernel.contact_counts, xla.contact_counts)
    np.testing.assert_allclose(kernel.final_state, xla.final_state, rtol=1e-10, atol=1e-12)


def test_pallas_through_run_with_padding_poison_and_zero_collisions():
    """``jb.run(driver="pallas")`` pads the batch to whole blocks, keeps a NaN lane
    from stalling the others, and does nothing for n = 0."""
    scene = jb.StickInCircle(R=2.0, ell=1.9)
    states = start_states(scene, 37)  # not a multiple of the block
    kernel = jb.run(scene, states, 12, driver="pallas")
    xla = jb.run(scene, states, 12, driver="lanes")
    np.testing.assert_array_equal(kernel.contact_counts, xla.contact_counts)
    np.testing.assert_allclose(kernel.final_state, xla.final_state, rtol=1e-10, atol=1e-12)
    assert np.all(kernel.max_energy_error < 1e-13)
    zero = jb.run(scene, states, 0, driver="pallas")
    np.testing.assert_array_equal(zero.final_state, states)

    carry = _lanes.fresh_carry(scene, jnp.asarray(states[:32]))
    poisoned = carry._replace(state=carry.state.at[3, 0].set(jnp.nan))
    out = jax.jit(lambda s, c: _pallas.pallas_final(scene, s, c, 5, interpret=True))(jnp.asarray(states[:32]), poisoned)
    others = np.arange(32) != 3
    assert np.all(np.isnan(np.asarray(out.state[3]))) and np.all(np.isfinite(np.asarray(out.state[others])))
    assert np.all(np.asarray(out.contact_counts).sum(axis=1) == 5)


def test_pallas_lane_out_of_root_steps_is_poisoned(monkeypatch):
    scene = jb.StickInCircle(R=2.0, ell=1.9)
    states = jnp.asarray(start_states(scene, 32))
    monkeypatch.setattr(_step, "MAX_ROOT_STEPS", 1)
    out = jax.jit(lambda s: _pallas.pallas_final(scene, s, _lanes.fresh_carry(scene, s), 2, interpret=True))(states)
    assert np.all(np.isnan(np.asarray(out.time)))
    code_zero = _lanes.CONTACT_CODES.index(0)
    assert np.all(np.asarray(out.contact_counts)[:, code_zero] >= 1)  # the unproven collision: contact 0


def _fli_starting_vectors(scene, states):
    from jaxbill._analysis.indicators import _initial_vector
    from jaxbill._engine.tangent import to_state_space

    return jax.vmap(lambda s: to_state_space(scene, s, _initial_vector(scene, s, None, "collision")[:, None])[:, 0])(
        jnp.asarray(states)
    )


@pytest.mark.parametrize("name", ["rotor 1.0", "lens", "walls 2D", "ellipse", "ellipse point"])
def test_pallas_kernel_carries_the_tangent_as_jb_fli(name):
    """The FLI of the tangent vector carried inside the kernel equals ``jb.fli`` (autodiff
    tangent maps of the collision map) from the same starting vectors."""
    scene = scenes()[name]
    states = jnp.asarray(start_states(scene, 32, seed=5))
    n = 12
    fli, log_norm, final = jax.jit(lambda s, w: _pallas.pallas_fli(scene, s, w, n, interpret=True))(
        states, _fli_starting_vectors(scene, states)
    )
    expected = jb.fli(scene, states, n)
    np.testing.assert_allclose(np.asarray(fli), np.asarray(expected.value), rtol=1e-9, atol=1e-9)
    np.testing.assert_allclose(np.asarray(log_norm), np.asarray(expected.log_norm), rtol=1e-9, atol=1e-9)
    assert float(jnp.max(fli)) > 1.0  # the vectors really stretched


def test_fli_map_through_the_kernel_equals_the_autodiff_map():
    scene = jb.StickInCircle(R=2.0, ell=1.5, inertia=INF)
    grid = start_states(scene, 40, seed=9).reshape(5, 8, 6)
    grid[0, 0, 0] = np.nan  # an unreachable pixel stays NaN on both paths
    kernel = jb.fli_map(scene, grid, 15, driver="pallas")
    autodiff = jb.fli_map(scene, grid, 15, driver="autodiff")
    assert kernel.shape == (5, 8) and np.isnan(kernel[0, 0]) and np.isnan(autodiff[0, 0])
    np.testing.assert_allclose(kernel, autodiff, rtol=1e-9, atol=1e-9)
    with pytest.raises(ValueError, match="driver"):
        jb.fli_map(scene, grid, 15, per="time", driver="pallas")
