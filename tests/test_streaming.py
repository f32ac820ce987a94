"""``jb.run``: long runs in chunks, recording only what is asked, resumable bit for bit.

Every record is checked against ``jb.orbit`` on the same input: states, times and
contacts bitwise (the chunked run executes the same per-collision code), section
projections to rounding (they are computed inside the compiled chunk, where XLA
may contract multiply-adds differently than in an eager call).
"""

from __future__ import annotations

import os
import tracemalloc

import numpy as np
import pytest

import jaxbill as jb
from helpers import random_states
from jaxbill import Section, run
from jaxbill._runs import streaming as _streaming

INF = float("inf")
N = 120  # collisions per orbit in most tests
CHUNK = 37  # deliberately not a divisor of N or of `every`


def rotor():
    return jb.StickInCircle(R=2.0, ell=1.5)


def lens():
    return jb.StickInCircle(R=2.0, ell=1.5, inertia=INF)


def circle():
    return jb.StickInCircle(R=2.0, ell=0.0)


def states_for(scene, count, seed=1):
    return np.asarray(random_states(np.random.default_rng(seed), count, 2.0, float(scene.ell), scene.kind))


@pytest.fixture(scope="module")
def expected_single():
    """``{kind: (scene, state0, jb.orbit(...))}``, computed once for the module."""
    out = {}
    for make_scene in (rotor, lens, circle):
        scene = make_scene()
        state0 = states_for(scene, 1)[0]
        out[scene.kind] = scene, state0, jb.orbit(scene, state0, N)
    return out


@pytest.fixture(scope="module")
def expected_batch():
    """``{kind: (scene, states0, jb.orbit(...))}`` for a batch of one full lane and a
    few more orbits: at least one full lane, so that jb.orbit runs the same
    vectorised program as jb.run (see jaxbill._engine.sharding), and not a multiple of it."""
    out = {}
    for make_scene in (rotor, lens):
        scene = make_scene()
        states0 = states_for(scene, scene.batch_chunk + 3)
        out[scene.kind] = scene, states0, jb.orbit(scene, states0, N)
    return out


# Module-level filters, so that each compiles once for the whole module.
def hits_end_p1(scene, state, contact):
    return contact == 1


def centre_right_of_axis(scene, state, contact):
    return state[0] > 0.0


def position(scene, state):
    return state[:2]


# ---------------------------------------------------------------------------
# records against jb.orbit
# ---------------------------------------------------------------------------
@pytest.mark.parametrize("kind", ["rotor", "lens", "circle"])
def test_single_orbit_states_equal_orbit_bitwise(expected_single, kind):
    scene, state0, expected = expected_single[kind]
    result = run(scene, state0, N, record="states", chunk=CHUNK)
    assert result.chunks == -(-N // CHUNK)
    np.testing.assert_array_equal(result.t, np.asarray(expected.t))
    np.testing.assert_array_equal(result.contact, np.asarray(expected.contact))
    np.testing.assert_array_equal(result.state, np.asarray(expected.state))
    np.testing.assert_array_equal(result.final_state, np.asarray(expected.state[-1]))
    assert float(result.time) == float(expected.t[-1])
    assert result.collisions == N and result.orbit_index is None


@pytest.mark.parametrize("kind", ["rotor", "lens"])
def test_batch_states_equal_orbit_bitwise(expected_batch, kind):
    scene, states0, expected = expected_batch[kind]
    result = run(scene, states0, N, record="states", chunk=CHUNK)
    assert result.state.shape == (states0.shape[0], N, scene.state_size)
    np.testing.assert_array_equal(result.t, np.asarray(expected.t))
    np.testing.assert_array_equal(result.contact, np.asarray(expected.contact))
    np.testing.assert_array_equal(result.state, np.asarray(expected.state))
    np.testing.assert_array_equal(result.orbit_index, np.arange(states0.shape[0]))


def test_every_kth_collision_and_chunk_size_do_not_matter(expected_single):
    scene, state0, expected = expected_single["lens"]
    every = 7
    for chunk in (5, CHUNK):
        result = run(scene, state0, N, record="states", every=every, chunk=chunk)
        # collisions numbered 7, 14, ...: indices 6, 13, ...
        np.testing.assert_array_equal(result.state, np.asarray(expected.state)[every - 1 :: every])
        np.testing.assert_array_equal(result.t, np.asarray(expected.t)[every - 1 :: every])


def test_any_scene_any_state_size():
    """The stick between walls in 3D: 12 numbers per state, contact codes +-1, +-3."""
    scene = jb.StickBetweenWalls3D(h=2.0, ell=0.5)
    tilt = 0.7
    state0 = np.array([0.0, 0.0, 1.0, np.sin(tilt), 0.0, np.cos(tilt), 0.3, 0.1, 0.8, 0.0, 0.9, 0.0])
    expected = jb.orbit(scene, state0, N)
    result = run(scene, state0, N, record="states", chunk=CHUNK)
    np.testing.assert_array_equal(result.state, np.asarray(expected.state))
    assert result.state.shape == (N, 12)
    contacts = np.asarray(expected.contact)
    assert set(np.unique(contacts)) == {-3, -1, 1, 3}
    for i, code in enumerate(result.contact_codes):
        assert result.contact_counts[i] == np.sum(contacts == code)


def test_final_record_keeps_statistics_only(expected_batch):
    scene, states0, expected = expected_batch["rotor"]
    result = run(scene, states0, N, chunk=CHUNK)
    assert result.t is None and result.state is None and result.section is None
    np.testing.assert_array_equal(result.final_state, np.asarray(expected.state[:, -1]))
    np.testing.assert_array_equal(result.time, np.asarray(expected.t[:, -1]))
    # Counts per contact code, orbit by orbit.
    contacts = np.asarray(expected.contact)
    for i, code in enumerate(result.contact_codes):
        np.testing.assert_array_equal(result.contact_counts[:, i], np.sum(contacts == code, axis=1))
    assert np.all(result.contact_counts.sum(axis=1) == N)
    assert np.all(result.contact_counts[:, -1] == 0)  # no code outside the counted ones
    # Energy drift: the largest over all collisions, relative to E0.
    energy0 = np.asarray(jb.energy(scene, states0))
    energies = np.asarray(jb.energy(scene, expected.state))
    drift = np.max(np.abs(energies - energy0[:, None]), axis=1) / energy0
    np.testing.assert_allclose(result.max_energy_error, drift, rtol=0, atol=8 * np.finfo(float).eps)
    assert np.all(result.max_energy_error < 1e-12)


# ---------------------------------------------------------------------------
# sections
# ---------------------------------------------------------------------------
def _expected_section(scene, orbit, where_contact):
    keep = np.asarray(orbit.contact) == where_contact
    points = np.asarray(jb.birkhoff_section(scene, orbit.state))[keep]
    return keep, points


def test_section_single_orbit(expected_single):
    scene, state0, expected = expected_single["lens"]
    result = run(scene, state0, N, record=Section(hits_end_p1, jb.birkhoff_section), chunk=CHUNK)
    keep = np.asarray(expected.contact) == 1
    assert 0 < keep.sum() < N
    np.testing.assert_array_equal(result.section.collision, np.nonzero(keep)[0] + 1)
    np.testing.assert_array_equal(result.section.t, np.asarray(expected.t)[keep])
    points = np.asarray(jb.birkhoff_section(scene, expected.state))[keep]
    np.testing.assert_allclose(result.section.point, points, rtol=0, atol=1e-13)
    assert result.section.orbit is None


def test_section_overflow_reruns_the_chunk_and_loses_nothing(expected_batch):
    scene, states0, expected = expected_batch["lens"]
    section = Section(centre_right_of_axis, position, capacity=2)
    result = run(scene, states0, N, record=section, chunk=CHUNK)
    assert result.section_reruns >= 1  # 2 points per 37 collisions cannot hold them
    for i in range(0, states0.shape[0], 16):
        mine = result.section.orbit == i
        keep = np.asarray(expected.state[i, :, 0]) > 0.0
        np.testing.assert_array_equal(result.section.collision[mine], np.nonzero(keep)[0] + 1)
        # The projection is a plain copy: no rounding, so bitwise.
        np.testing.assert_array_equal(result.section.point[mine], np.asarray(expected.state[i, :, :2])[keep])
    assert result.section.point.shape[0] == int(np.sum(np.asarray(expected.state[..., 0]) > 0.0))


# ---------------------------------------------------------------------------
# files and resume
# ---------------------------------------------------------------------------
def test_states_written_to_a_run_directory(tmp_path, expected_single):
    scene, state0, expected = expected_single["lens"]
    result = run(scene, state0, N, record="states", every=3, chunk=CHUNK, out=tmp_path / "run")
    on_disk = np.load(tmp_path / "run" / "state.npy", mmap_mode="r")
    np.testing.assert_array_equal(on_disk, np.asarray(expected.state)[2::3])
    np.testing.assert_array_equal(result.state, on_disk)
    saved = _streaming.Checkpoint.load(tmp_path / "run" / "checkpoint.npz")
    assert saved.collisions == N
    np.testing.assert_array_equal(saved.state, result.final_state)
    with pytest.raises(ValueError, match="already holds a run"):
        run(scene, state0, N, record="states", every=3, out=tmp_path / "run")


class _Interrupted(Exception):
    pass


@pytest.mark.parametrize("record", ["states", "section", "final"])
def test_a_killed_run_resumes_bit_for_bit(tmp_path, monkeypatch, record):
    """Stop a run inside its third chunk (after its records went to disk, before
    its checkpoint), resume it, and compare every file with an uninterrupted run."""
    scene = lens()
    states0 = states_for(scene, 3)
    spec = {"states": "states", "final": "final", "section": Section(hits_end_p1, position)}[record]
    kwargs = dict(record=spec, chunk=CHUNK, every=2 if record == "states" else 1)
    whole = run(scene, states0, N, out=tmp_path / "whole", **kwargs)

    monkeypatch.setattr(_streaming, "CHECKPOINT_INTERVAL_S", 0.0)
    calls = {"count": 0}
    original = _streaming._ProgressBar.update

    def update_then_die(self, done):
        calls["count"] += 1
        if calls["count"] == 3:
            raise _Interrupted
        original(self, done)

    monkeypatch.setattr(_streaming._ProgressBar, "update", update_then_die)
    with pytest.raises(_Interrupted):
        run(scene, states0, N, out=tmp_path / "killed", **kwargs)
    monkeypatch.setattr(_streaming._ProgressBar, "update", original)
    assert _streaming.Checkpoint.load(tmp_path / "killed" / "checkpoint.npz").collisions == 2 * CHUNK

    resumed = run(scene, states0, N, out=tmp_path / "killed", resume=True, **kwargs)
    assert resumed.chunks == -(-(N - 2 * CHUNK) // CHUNK)
    names = sorted(os.listdir(tmp_path / "whole"))
    assert names == sorted(os.listdir(tmp_path / "killed"))
    for name in names:
        whole_file, killed_file = np.load(tmp_path / "whole" / name), np.load(tmp_path / "killed" / name)
        if name.endswith(".npz"):
            assert whole_file.files == killed_file.files
            for key in whole_file.files:
                np.testing.assert_array_equal(whole_file[key], killed_file[key], err_msg=f"{name}: {key}")
        else:
            np.testing.assert_array_equal(whole_file, killed_file, err_msg=name)
    np.testing.assert_array_equal(resumed.final_state, whole.final_state)
    np.testing.assert_array_equal(resumed.contact_counts, whole.contact_counts)
    np.testing.assert_array_equal(resumed.max_energy_error, whole.max_energy_error)


def test_resume_from_a_checkpoint_in_memory_and_extend(expected_single):
    scene, state0, expected = expected_single["lens"]
    first = run(scene, state0, 50, record="states", every=4)
    rest = run(scene, state0, N, record="states", every=4, resume=first.checkpoint)
    np.testing.assert_array_equal(np.concatenate([first.state, rest.state]), np.asarray(expected.state)[3::4])
    assert rest.collisions == N and float(rest.time) == float(expected.t[-1])
    np.testing.assert_array_equal(rest.contact_counts.sum(), N)
    with pytest.raises(ValueError, match="other initial states"):
        run(scene, state0 * 0.5, N, resume=first.checkpoint)
    with pytest.raises(ValueError, match="another scene"):
        run(jb.StickInCircle(R=2.0, ell=1.4, inertia=INF), state0, N, resume=first.checkpoint)
    with pytest.raises(ValueError, match="beyond n"):
        run(scene, state0, 10, resume=first.checkpoint)


# ---------------------------------------------------------------------------
# bounded memory
# ---------------------------------------------------------------------------
def test_a_million_collisions_with_final_record_keep_host_memory_tiny():
    scene = lens()
    state0 = states_for(scene, 1)[0]
    n = 1_000_000
    run(scene, state0, 1000, chunk=1 << 17)  # compile outside the measurement
    tracemalloc.start()
    result = run(scene, state0, n, chunk=1 << 17)
    _, peak = tracemalloc.get_traced_memory()
    tracemalloc.stop()
    assert result.collisions == n and result.chunks == 8
    assert result.final_state.shape == (scene.state_size,) and result.t is None
    assert np.isfinite(result.time) and result.time > 0
    assert result.contact_counts.sum() == n
    # Recording the states would take n * 8 * (S + 2) = 64 MB; the run keeps a few kB.
    assert peak < 1_000_000, f"host allocations peaked at {peak} bytes"


@pytest.mark.parametrize("seconds, chunks", [(0.0, 21), (float("inf"), 3)])
def test_a_final_run_of_short_calls_grows_its_chunk_fourfold(monkeypatch, seconds, chunks):
    """Default chunk of 4 collisions per orbit and 84 in all: with every call counted as short
    (``SECONDS_PER_CHUNK`` infinite) the chunks are 4, 16 and 64; with none, 21 of 4. Either way the
    final states and statistics are bitwise those of a run in one chunk."""
    scene = lens()
    states0 = states_for(scene, 5)
    lanes = _streaming._Engine(scene, states0, None).lanes
    monkeypatch.setattr(_streaming, "COLLISIONS_PER_CHUNK", 4 * lanes)
    monkeypatch.setattr(_streaming, "SECONDS_PER_CHUNK", seconds)
    result = run(scene, states0, 84)
    whole = run(scene, states0, 84, chunk=84)
    assert result.chunks == chunks and whole.chunks == 1
    for field in ("final_state", "time", "max_energy_error", "contact_counts"):
        assert np.array_equal(getattr(result, field), getattr(whole, field))
    recorded = run(scene, states0, 84, record="states")  # records: the chunk stays as it is
    assert recorded.chunks == 21


def test_default_chunk_bounds_the_records_of_a_chunk():
    lanes, every, row_bytes = 1 << 20, 1, 8 * 8
    chunk = _streaming._default_chunk("states", lanes, every, row_bytes)
    assert lanes * chunk * row_bytes <= _streaming.RECORD_BYTES_PER_CHUNK
    assert chunk >= 1
    assert _streaming._default_chunk("final", 1, 1, 0) == _streaming.COLLISIONS_PER_CHUNK


# ---------------------------------------------------------------------------
# bad input
# ---------------------------------------------------------------------------
@pytest.mark.parametrize(
    "kwargs, match",
    [
        (dict(record="everything"), "record must be"),
        (dict(record="states", every=0), "every must be a positive integer"),
        (dict(record="final", every=3), "every applies to record='states' only"),
        (dict(chunk=0), "chunk must be a positive integer"),
        (dict(chunk=2.5), "chunk must be a positive integer"),
        (dict(out=3), "out must be a directory path"),
        (dict(resume=True), "resume=True continues the run in out"),
        (dict(resume=42), "resume must be"),
        (dict(progress="yes"), "progress must be"),
        (dict(record=Section(hits_end_p1, capacity=0)), "capacity must be a positive integer"),
        (dict(record=Section("not a function")), "must be functions"),
    ],
)
def test_bad_arguments_raise(kwargs, match):
    scene = lens()
    with pytest.raises(ValueError, match=match):
        run(scene, states_for(scene, 1)[0], 10, **kwargs)


def test_bad_states_and_counts_raise_as_in_orbit(tmp_path):
    scene = rotor()
    good = states_for(scene, 1)[0]
    with pytest.raises(ValueError, match="n must be a non-negative integer"):
        run(scene, good, -1)
    with pytest.raises(ValueError, match="finite"):
        run(scene, np.where(np.arange(6) == 0, np.nan, good), 10)
    with pytest.raises(ValueError, match="shape"):
        run(scene, good[:5], 10)
    (tmp_path / "a_file").write_text("")
    with pytest.raises(ValueError, match="is a file"):
        run(scene, good, 10, out=tmp_path / "a_file")


def test_section_functions_of_wrong_shape_raise():
    scene = lens()
    with pytest.raises(ValueError, match="one bool per state"):
        run(scene, states_for(scene, 1)[0], 10, record=Section(lambda scene, s, c: s > 0))
    with pytest.raises(ValueError, match="vector"):
        run(scene, states_for(scene, 1)[0], 10, record=Section(hits_end_p1, lambda scene, s: s[0]))


def test_zero_collisions_returns_the_start():
    scene = lens()
    state0 = states_for(scene, 1)[0]
    result = run(scene, state0, 0, record="states")
    assert result.chunks == 0 and result.state.shape == (0, scene.state_size)
    np.testing.assert_array_equal(result.final_state, state0)
    assert float(result.time) == 0.0


@pytest.mark.parametrize("record", ["final", "states", "section"])
def test_an_empty_batch_returns_an_empty_run(tmp_path, record):
    """As ``jb.orbit`` returns empty results for ``(0, S)`` states, ``jb.run`` returns a run of no orbits."""
    scene = rotor()
    spec = Section(hits_end_p1, position) if record == "section" else record
    empty = np.zeros((0, scene.state_size))
    orbit = jb.orbit(scene, empty, N)
    for out in (None, tmp_path / record):
        result = run(scene, empty, N, record=spec, out=out)
        assert result.final_state.shape == (0, scene.state_size) and result.time.shape == (0,)
        assert result.contact_counts.shape[0] == 0 and result.max_energy_error.shape == (0,)
        if record == "states":
            assert result.t.shape == orbit.t.shape == (0, N)
            assert result.state.shape == orbit.state.shape == (0, N, scene.state_size)
        if record == "section":
            assert result.section.point.shape == (0, 2)


def test_checkpoint_load_takes_a_run_directory(tmp_path, expected_single):
    scene, state0, _ = expected_single["lens"]
    result = run(scene, state0, N, out=tmp_path / "run")
    from_directory = jb.Checkpoint.load(tmp_path / "run")
    from_file = jb.Checkpoint.load(tmp_path / "run" / "checkpoint.npz")
    assert from_directory.collisions == from_file.collisions == N
    np.testing.assert_array_equal(from_directory.state, result.final_state)
    (tmp_path / "empty").mkdir()
    with pytest.raises(FileNotFoundError, match="directory without a run's checkpoint.npz") as raised:
        jb.Checkpoint.load(tmp_path / "empty")
    assert raised.value.filename == str(tmp_path / "empty" / "checkpoint.npz")


def test_resume_into_the_run_directory_with_its_own_checkpoint(tmp_path, expected_single):
    """A run's own checkpoint (in memory, as a file or as its directory) continues it in its directory,
    as resume=True does; a checkpoint of another point of the run is refused, naming what to pass."""
    scene, state0, expected = expected_single["lens"]
    first = run(scene, state0, 50, out=tmp_path / "run")
    for own in (first.checkpoint, tmp_path / "run" / "checkpoint.npz", tmp_path / "run"):
        first.checkpoint.save(tmp_path / "run" / "checkpoint.npz")  # the run back at collision 50
        rest = run(scene, state0, 80, out=tmp_path / "run", resume=own)
        assert jb.Checkpoint.load(tmp_path / "run").collisions == rest.collisions == 80
        np.testing.assert_array_equal(rest.final_state, np.asarray(expected.state)[79])
    with pytest.raises(ValueError, match=r"not the checkpoint of the run in .* at collision 80.*pass resume=True"):
        run(scene, state0, N, out=tmp_path / "run", resume=first.checkpoint)
