"""``jb.run(..., out=D)`` under ordinary faults: two writers, a full disk, a stop signal, a damaged file.

The promise under test is that nothing is lost: after each fault the run
directory's checkpoint is intact, ``resume=True`` gives bitwise the
uninterrupted run, and the error says which file or directory is at fault and
what to do. Where a process must die or race another, the run happens in a
subprocess (with a timeout, so a failure cannot hang the suite); elsewhere the
fault is sent or injected in this process.
"""

from __future__ import annotations

import errno
import json
import os
import shutil
import signal
import subprocess
import sys
import textwrap
import threading
import time

import numpy as np
import pytest

import jaxbill as jb
from helpers import random_states
from jaxbill import Section, run
from jaxbill._runs import files as _run_files
from jaxbill._runs import guard as _run_guard
from jaxbill._runs import streaming as _streaming

HERE = os.path.dirname(os.path.abspath(__file__))
TIMEOUT_S = 180
N = 120
CHUNK = 37  # not a divisor of N: the last chunk is shorter


def scene():
    """The issue's scene: a long rotor in a circle."""
    return jb.StickInCircle(R=2.0, ell=1.9)


def state_for(seed: int) -> np.ndarray:
    return np.asarray(random_states(np.random.default_rng(seed), 1, 2.0, 1.9, scene().kind))[0]


# Module-level section functions, so that each compiles once for the module.
def every_collision(scene, state, contact):
    return contact == contact


def position(scene, state):
    return state[:2]


def _environment() -> dict:
    env = dict(os.environ)
    env["JAX_PLATFORMS"] = "cpu"
    return env


def _start(script: str, *args) -> subprocess.Popen:
    return subprocess.Popen(
        [sys.executable, "-c", textwrap.dedent(script), HERE, *map(str, args)],
        env=_environment(),
        stdout=subprocess.PIPE,
        stderr=subprocess.PIPE,
        text=True,
    )


def _finish(process: subprocess.Popen) -> tuple[str, str]:
    try:
        return process.communicate(timeout=TIMEOUT_S)
    finally:
        if process.poll() is None:
            process.kill()
            process.communicate()


# np.load of an .npy gives an array, which has no context manager: read both kinds alike.
def _load_all(path):
    loaded = np.load(path)
    if isinstance(loaded, np.ndarray):
        return {"": loaded}
    with loaded:
        return {key: loaded[key] for key in loaded.files}


def _assert_same_directories(directory, reference) -> None:
    names = sorted(os.listdir(reference))
    assert sorted(os.listdir(directory)) == names
    for name in names:
        mine, theirs = _load_all(directory / name), _load_all(reference / name)
        assert mine.keys() == theirs.keys(), name
        for key in theirs:
            np.testing.assert_array_equal(mine[key], theirs[key], err_msg=f"{name} {key}")


# ---------------------------------------------------------------------------
# 1. one writer per directory
# ---------------------------------------------------------------------------
# every=2, chunk=CHUNK as in the tests below: one compilation serves them all.
RACE_N, RACE_EVERY, RACE_CHUNK = 1000, 2, CHUNK

_RACER = """
    import json, os, sys, time
    tests, out, seed, me, other = sys.argv[1], sys.argv[2], int(sys.argv[3]), sys.argv[4], sys.argv[5]
    sys.path.insert(0, tests)
    import jaxbill as jb
    from jaxbill._runs import streaming as _streaming
    from test_run_faults import RACE_CHUNK, RACE_EVERY, RACE_N, scene, state_for

    original = _streaming._ProgressBar.update

    def hold_the_directory(self, done):
        # After the first chunk (the lock held, the code compiled), wait for the
        # other process to have tried: the race is then decided whatever the timing.
        deadline = time.monotonic() + 60
        while not os.path.exists(other) and time.monotonic() < deadline:
            time.sleep(0.02)
        _streaming._ProgressBar.update = original

    _streaming._ProgressBar.update = hold_the_directory
    try:
        jb.run(scene(), state_for(seed), RACE_N, record="states", every=RACE_EVERY, chunk=RACE_CHUNK, out=out)
        result = {"error": None, "pid": os.getpid()}
    except ValueError as error:
        result = {"error": str(error), "pid": os.getpid()}
    finally:
        open(me, "w").close()
    print(json.dumps(result))
"""


def test_two_processes_racing_for_one_directory(tmp_path):
    """Two runs into one directory, started 0.3 s apart: exactly one is refused at
    once with the lock's error, and the directory holds the other's run, bitwise."""
    out = tmp_path / "run"
    flags = [tmp_path / "done_0", tmp_path / "done_1"]
    first = _start(_RACER, out, 1, flags[0], flags[1])
    time.sleep(0.3)
    second = _start(_RACER, out, 2, flags[1], flags[0])
    results = []
    for process in (first, second):
        stdout, stderr = _finish(process)
        assert process.returncode == 0, stderr[-3000:]
        results.append(json.loads(stdout.strip().splitlines()[-1]))
    refused = [i for i, result in enumerate(results) if result["error"] is not None]
    assert len(refused) == 1, results
    loser, winner = refused[0], 1 - refused[0]
    message = results[loser]["error"]
    assert f"{out} is in use by another jb.run" in message
    assert f"pid {results[winner]['pid']}" in message

    solo = run(scene(), state_for(winner + 1), RACE_N, record="states", every=RACE_EVERY, chunk=RACE_CHUNK)
    for name, expected in (("t", solo.t), ("contact", solo.contact), ("state", solo.state)):
        np.testing.assert_array_equal(np.load(out / f"{name}.npy"), expected, err_msg=name)
    checkpoint = jb.Checkpoint.load(out / "checkpoint.npz")
    assert checkpoint.collisions == RACE_N
    np.testing.assert_array_equal(checkpoint.state, solo.final_state)
    assert sorted(os.listdir(out)) == ["checkpoint.npz", "contact.npy", "state.npy", "t.npy"]  # lock file gone


def test_a_locked_directory_refuses_a_run_and_a_resume_but_not_a_reader(tmp_path):
    out = tmp_path / "run"
    state0 = state_for(1)
    run(scene(), state0, N // 2, record="states", chunk=CHUNK, out=out)
    lock = _run_guard.DirectoryLock(out)
    lock.acquire()
    try:
        for kwargs in (dict(), dict(resume=True)):
            with pytest.raises(ValueError, match=f"is in use by another jb.run \\(pid {os.getpid()} on "):
                run(scene(), state0, N // 2, record="states", chunk=CHUNK, out=out, **kwargs)
        # Reading needs no lock.
        assert jb.Checkpoint.load(out / "checkpoint.npz").collisions == N // 2
        assert np.load(out / "state.npy").shape == (N // 2, 6)
    finally:
        lock.release()
    assert run(scene(), state0, N // 2, record="states", chunk=CHUNK, out=out, resume=True).collisions == N // 2


# ---------------------------------------------------------------------------
# 2. a full disk
# ---------------------------------------------------------------------------
_FILL_A_SMALL_DISK = """
    import json, sys
    tests, disk = sys.argv[1], sys.argv[2]
    sys.path.insert(0, tests)
    import jaxbill as jb
    from test_run_faults import every_collision, scene, state_for, DISK_SECTION, DISK_N, DISK_CHUNK

    result = {}
    try:  # 40000 states of 60 bytes: 2.4 MB, on a 2 MiB disk
        jb.run(scene(), state_for(1), 40000, record="states", out=f"{disk}/states")
    except OSError as error:
        result["states"] = [error.errno, str(error)]
    try:  # section files that grow by 64 bytes a collision until the disk is full
        jb.run(scene(), state_for(1), DISK_N, record=DISK_SECTION, chunk=DISK_CHUNK, out=f"{disk}/section")
    except OSError as error:
        result["section"] = [error.errno, str(error)]
    print(json.dumps(result))
"""
DISK_N, DISK_CHUNK = 60000, 5000
DISK_SECTION = Section(every_collision, capacity=DISK_CHUNK)


@pytest.fixture(autouse=True)
def python_handles_ctrl_c():
    """Ctrl-C as an interactive session has it (Python's KeyboardInterrupt handler): what the tests below
    assume, whatever an earlier test in the same worker process left installed."""
    before = signal.signal(signal.SIGINT, signal.default_int_handler)
    yield
    signal.signal(signal.SIGINT, before)


@pytest.fixture
def small_disk(tmp_path):
    """A 2 MiB tmpfs (root only, and only where mounting is allowed)."""
    if not hasattr(os, "geteuid") or os.geteuid() != 0 or shutil.which("mount") is None:
        pytest.skip(
            "mounting a small tmpfs needs root; test_a_refused_reservation_fails_before_the_first_collision and "
            "test_a_write_error_midway_keeps_the_checkpoint_and_resumes inject the same faults"
        )
    disk = tmp_path / "disk"
    disk.mkdir()
    mounted = subprocess.run(["mount", "-t", "tmpfs", "-o", "size=2m", "tmpfs", str(disk)], capture_output=True)
    if mounted.returncode != 0:
        pytest.skip(f"cannot mount a tmpfs here: {mounted.stderr.decode().strip()}")
    try:
        yield disk
    finally:
        subprocess.run(["umount", "-l", str(disk)], capture_output=True)


def test_a_full_disk_is_an_error_never_a_signal(small_disk):
    """On a real 2 MiB filesystem: records that cannot fit fail before the first
    collision, saying what they need; a run that fills the disk midway stops with
    a usable checkpoint, and once there is room it resumes to the uninterrupted run."""
    process = _start(_FILL_A_SMALL_DISK, small_disk)
    stdout, stderr = _finish(process)
    # SIGBUS (the old behaviour) would show as returncode -7.
    assert process.returncode == 0, f"returncode {process.returncode}:\n{stderr[-3000:]}"
    result = json.loads(stdout.strip().splitlines()[-1])

    code, message = result["states"]
    assert code == errno.ENOSPC
    assert f"{small_disk / 'states'} needs " in message and "are free there; nothing was run" in message
    needed = int(message.split(" needs ")[1].split(" bytes")[0])
    assert needed >= 40000 * 60
    assert not (small_disk / "states").exists()  # no files left behind, no checkpoint

    code, message = result["section"]
    assert code == errno.ENOSPC
    assert "resume=True" in message and "holds collision" in message
    checkpoint = jb.Checkpoint.load(small_disk / "section" / "checkpoint.npz")
    assert 0 < checkpoint.collisions < DISK_N and checkpoint.collisions % DISK_CHUNK == 0
    assert f"holds collision {checkpoint.collisions}," in message

    subprocess.run(["mount", "-o", "remount,size=16m", "tmpfs", str(small_disk)], check=True)
    resumed = run(
        scene(), state_for(1), DISK_N, record=DISK_SECTION, chunk=DISK_CHUNK, out=small_disk / "section", resume=True
    )
    whole = run(scene(), state_for(1), DISK_N, record=DISK_SECTION, chunk=DISK_CHUNK)
    for field in ("point", "t", "collision"):
        np.testing.assert_array_equal(getattr(resumed.section, field), getattr(whole.section, field), err_msg=field)
    np.testing.assert_array_equal(resumed.final_state, whole.final_state)


def test_too_little_space_fails_before_the_first_collision(tmp_path, monkeypatch):
    monkeypatch.setattr(_run_guard, "free_bytes", lambda directory: 1000)
    chunks = []
    monkeypatch.setattr(_streaming._ProgressBar, "update", lambda self, done: chunks.append(done))
    out = tmp_path / "run"
    with pytest.raises(OSError, match=f"{out} needs [0-9]+ bytes .* and 1000 bytes .* are free there") as caught:
        run(scene(), state_for(1), N, record="states", chunk=CHUNK, out=out)
    assert caught.value.errno == errno.ENOSPC
    assert chunks == [] and not out.exists()  # nothing run, nothing left


@pytest.mark.skipif(not hasattr(os, "posix_fallocate"), reason="no posix_fallocate here: nothing is reserved")
def test_a_refused_reservation_fails_before_the_first_collision(tmp_path, monkeypatch):
    """The free-space check passes but the filesystem refuses the records' blocks (``posix_fallocate``
    answers ENOSPC, as a quota, a thin volume or another writer filling the disk meanwhile may): the run
    fails before its first collision, saying what it needs and what is free, and leaves nothing behind."""
    asked = []

    def refuse(fd, offset, length):
        asked.append((offset, length))
        raise OSError(errno.ENOSPC, "No space left on device")

    monkeypatch.setattr(_run_guard.os, "posix_fallocate", refuse)
    chunks = []
    monkeypatch.setattr(_streaming._ProgressBar, "update", lambda self, done: chunks.append(done))
    out = tmp_path / "run"
    with pytest.raises(OSError, match=f"{out} needs [0-9]+ bytes .* are free there; nothing was run") as caught:
        run(scene(), state_for(1), N, record="states", chunk=CHUNK, out=out)
    assert caught.value.errno == errno.ENOSPC
    assert isinstance(caught.value.__cause__, OSError) and caught.value.__cause__.errno == errno.ENOSPC
    # The first record file's reservation is the call refused: its whole size, N times 8 bytes past the header.
    assert len(asked) == 1 and asked[0][0] == 0 and asked[0][1] > N * 8
    assert chunks == [] and not out.exists()  # nothing run, nothing left


@pytest.mark.parametrize("fault", ["section file", "checkpoint"])
def test_a_write_error_midway_keeps_the_checkpoint_and_resumes(tmp_path, monkeypatch, fault):
    """ENOSPC injected in the writer: the run stops with the checkpoint of its last
    complete chunk (or, if the checkpoint itself cannot be written, the one
    before), the message says from where it resumes, and it does, bitwise."""
    state0 = state_for(3)
    section = Section(every_collision, position, capacity=CHUNK)
    whole = run(scene(), state0, N, record=section, chunk=CHUNK, out=tmp_path / "whole")

    monkeypatch.setattr(_streaming, "CHECKPOINT_INTERVAL_S", 0.0)
    target = (_run_files.GrowingNpy, "append") if fault == "section file" else (_run_files.Checkpoint, "save")
    original = getattr(*target)
    calls = {"count": 0}

    def full_disk(self, *args):
        calls["count"] += 1
        # Section files: 3 appends a chunk, the 3rd chunk's first fails. Checkpoint:
        # the start, then one a chunk; the one after the 2nd chunk fails.
        if calls["count"] == (7 if fault == "section file" else 3):
            raise OSError(errno.ENOSPC, "No space left on device", str(tmp_path / "x.npy"))
        return original(self, *args)

    monkeypatch.setattr(*target, full_disk)
    killed = tmp_path / "killed"
    with pytest.raises(OSError) as caught:
        run(scene(), state0, N, record=section, chunk=CHUNK, out=killed)
    monkeypatch.setattr(*target, original)
    assert caught.value.errno == errno.ENOSPC
    saved = jb.Checkpoint.load(killed / "checkpoint.npz").collisions
    assert saved == (2 * CHUNK if fault == "section file" else CHUNK)
    message = str(caught.value)
    assert "No space left on device" in message and "x.npy" in message
    assert f"holds collision {saved}, with the records up to it" in message and "resume=True" in message
    assert not (killed / "checkpoint.npz.partial").exists()

    resumed = run(scene(), state0, N, record=section, chunk=CHUNK, out=killed, resume=True)
    _assert_same_directories(killed, tmp_path / "whole")
    np.testing.assert_array_equal(resumed.section.point, whole.section.point)


# ---------------------------------------------------------------------------
# 3. stop signals
# ---------------------------------------------------------------------------
SIGNAL_N, SIGNAL_EVERY, SIGNAL_CHUNK = 4000, 2, CHUNK

_STOPPED_BY_SIGTERM = """
    import os, sys, time
    tests, out, started = sys.argv[1], sys.argv[2], sys.argv[3]
    sys.path.insert(0, tests)
    import jaxbill as jb
    from jaxbill._runs import streaming as _streaming
    from test_run_faults import SIGNAL_CHUNK, SIGNAL_EVERY, SIGNAL_N, scene, state_for

    def slowly(self, done):
        open(started, "a").close()  # compiled, one chunk written: the parent may signal
        time.sleep(0.05)  # 109 chunks of 0.05 s: the signal arrives mid-run

    _streaming._ProgressBar.update = slowly
    jb.run(scene(), state_for(5), SIGNAL_N, record="states", every=SIGNAL_EVERY, chunk=SIGNAL_CHUNK, out=out)
    print("not stopped")
"""


def test_sigterm_mid_run_then_resume_is_the_uninterrupted_run(tmp_path):
    out, started = tmp_path / "stopped", tmp_path / "started"
    process = _start(_STOPPED_BY_SIGTERM, out, started)
    deadline = time.monotonic() + TIMEOUT_S
    while not started.exists() and process.poll() is None and time.monotonic() < deadline:
        time.sleep(0.02)
    process.send_signal(signal.SIGTERM)
    stdout, stderr = _finish(process)
    # 143 = 128 + SIGTERM from the uncaught RunInterrupted; -15 would be death by the signal.
    assert process.returncode == 143, f"returncode {process.returncode}:\n{stderr[-3000:]}"
    assert "not stopped" not in stdout
    saved = jb.Checkpoint.load(out / "checkpoint.npz").collisions
    assert 0 < saved < SIGNAL_N and saved % SIGNAL_CHUNK == 0
    assert f"stopped by SIGTERM after collision {saved} of {SIGNAL_N}" in stderr and "resume=True" in stderr
    assert sorted(os.listdir(out)) == ["checkpoint.npz", "contact.npy", "state.npy", "t.npy"]

    kwargs = dict(record="states", every=SIGNAL_EVERY, chunk=SIGNAL_CHUNK)
    resumed = run(scene(), state_for(5), SIGNAL_N, out=out, resume=True, **kwargs)
    assert resumed.chunks == -(-(SIGNAL_N - saved) // SIGNAL_CHUNK)
    run(scene(), state_for(5), SIGNAL_N, out=tmp_path / "whole", **kwargs)
    _assert_same_directories(out, tmp_path / "whole")


def _signal_after_chunk(monkeypatch, number, at=2):
    """Make the run send itself ``number`` when its ``at``-th chunk is done.

    ``signal.raise_signal`` delivers it to this thread and runs the Python handler before returning.
    ``os.kill`` of the own process may deliver it to any thread (XLA's, once a test has started
    them), and the main thread then runs the handler a moment later, after the chunk's check.
    """
    calls = {"count": 0}

    def update(self, done):
        calls["count"] += 1
        if calls["count"] == at:
            signal.raise_signal(number)

    monkeypatch.setattr(_streaming._ProgressBar, "update", update)
    return calls


def test_ctrl_c_checkpoints_and_raises_keyboard_interrupt(tmp_path, monkeypatch):
    state0, kwargs = state_for(4), dict(record="states", every=2, chunk=CHUNK)
    before = signal.getsignal(signal.SIGINT)
    calls = _signal_after_chunk(monkeypatch, signal.SIGINT)
    with pytest.raises(KeyboardInterrupt, match=f"stopped by SIGINT after collision {2 * CHUNK} of {N}"):
        run(scene(), state0, N, out=tmp_path / "stopped", **kwargs)
    assert calls["count"] == 2  # it stopped after the chunk in flight
    assert signal.getsignal(signal.SIGINT) is before
    assert jb.Checkpoint.load(tmp_path / "stopped" / "checkpoint.npz").collisions == 2 * CHUNK
    monkeypatch.undo()
    run(scene(), state0, N, out=tmp_path / "stopped", resume=True, **kwargs)
    run(scene(), state0, N, out=tmp_path / "whole", **kwargs)
    _assert_same_directories(tmp_path / "stopped", tmp_path / "whole")


def test_sigterm_is_catchable_and_a_users_handler_still_runs(tmp_path, monkeypatch):
    received = []

    def users_handler(number, frame):
        received.append(number)

    previous = signal.signal(signal.SIGTERM, users_handler)
    try:
        _signal_after_chunk(monkeypatch, signal.SIGTERM, at=1)
        with pytest.raises(jb.RunInterrupted) as caught:
            run(scene(), state_for(4), N, chunk=CHUNK, out=tmp_path / "stopped")
        assert received == [signal.SIGTERM]
        assert signal.getsignal(signal.SIGTERM) is users_handler
    finally:
        signal.signal(signal.SIGTERM, previous)
    error = caught.value
    assert isinstance(error, SystemExit) and not isinstance(error, Exception)
    assert error.code == 128 + signal.SIGTERM and error.collisions == CHUNK and error.out == tmp_path / "stopped"
    assert f"stopped by SIGTERM after collision {CHUNK} of {N}" in str(error)
    assert jb.Checkpoint.load(tmp_path / "stopped" / "checkpoint.npz").collisions == CHUNK


def test_a_signal_during_the_final_checkpoint_is_not_lost(tmp_path, monkeypatch):
    """After the last chunk's check no chunk boundary is left: the signal goes to the
    previous handler once the run is complete and its directory released."""
    original = _run_files.Checkpoint.save

    def save_then_ctrl_c(self, path):
        original(self, path)
        if self.collisions == N:
            signal.raise_signal(signal.SIGINT)

    monkeypatch.setattr(_run_files.Checkpoint, "save", save_then_ctrl_c)
    with pytest.raises(KeyboardInterrupt) as caught:
        run(scene(), state_for(4), N, chunk=CHUNK, out=tmp_path / "run")
    assert "stopped by" not in str(caught.value)  # the default handler's, not jb.run's
    assert jb.Checkpoint.load(tmp_path / "run" / "checkpoint.npz").collisions == N
    assert not (tmp_path / "run" / _run_guard.LOCK_NAME).exists()


def test_a_run_in_another_thread_installs_no_handlers(tmp_path):
    """Python lets only the main thread set handlers: elsewhere the run goes on without them."""
    before = signal.getsignal(signal.SIGTERM), signal.getsignal(signal.SIGINT)
    results = []

    def in_thread():
        results.append(run(scene(), state_for(4), N, chunk=CHUNK, out=tmp_path / "run"))

    worker = threading.Thread(target=in_thread)
    worker.start()
    worker.join(TIMEOUT_S)
    assert results and results[0].collisions == N
    assert (signal.getsignal(signal.SIGTERM), signal.getsignal(signal.SIGINT)) == before


# ---------------------------------------------------------------------------
# 4. damaged or foreign files
# ---------------------------------------------------------------------------
@pytest.fixture(scope="module")
def finished_run(tmp_path_factory):
    out = tmp_path_factory.mktemp("finished") / "run"
    run(scene(), state_for(6), N, record="states", chunk=CHUNK, out=out)
    return out


def _cut_in_half(path):
    data = path.read_bytes()
    path.write_bytes(data[: len(data) // 2])


def _wrong_header(path):
    data = bytearray(path.read_bytes())
    data[:6] = b"\x00JUNK!"
    path.write_bytes(bytes(data))


def _other_dtype(path):
    # The same length, a header that says float32 and twice the rows.
    record = np.load(path)
    np.save(path, np.zeros((2 * record.shape[0], *record.shape[1:]), np.float32))


def _newer_format(path):
    with np.load(path) as f:
        arrays = {key: f[key] for key in f.files}
    arrays["format_version"] = np.int64(99)
    with open(path, "wb") as f:
        np.savez(f, **arrays)


@pytest.mark.parametrize(
    "file, damage, match",
    [
        ("checkpoint.npz", _cut_in_half, "checkpoint.npz: not a readable checkpoint .* cut short or damaged"),
        ("checkpoint.npz", _newer_format, "checkpoint.npz: checkpoint format 99, this jaxbill reads format 1"),
        ("state.npy", _wrong_header, "state.npy: not a readable .npy file"),
        ("state.npy", _cut_in_half, "state.npy: [0-9]+ bytes, cut short"),
        ("t.npy", _other_dtype, "t.npy: holds float32"),
    ],
)
def test_a_damaged_file_is_named(tmp_path, finished_run, file, damage, match):
    out = tmp_path / "run"
    shutil.copytree(finished_run, out)
    damage(out / file)
    with pytest.raises(ValueError, match=match) as caught:
        run(scene(), state_for(6), N, record="states", chunk=CHUNK, out=out, resume=True)
    assert str(out / file) in str(caught.value)
    if file == "checkpoint.npz":
        with pytest.raises(ValueError, match=match):
            jb.Checkpoint.load(out / file)
    else:
        assert "resume=" in str(caught.value)  # says how to go on from the checkpoint


def test_a_directory_of_another_run_is_named(tmp_path, finished_run):
    out = tmp_path / "run"
    shutil.copytree(finished_run, out)
    with pytest.raises(ValueError, match=f"{out / 'checkpoint.npz'} belongs to a run of another scene"):
        run(jb.StickInCircle(R=2.0, ell=1.8), state_for(6), N, record="states", out=out, resume=True)
    with pytest.raises(ValueError, match="t.npy holds float64\\(120,\\), this run would write float64\\(240,\\)"):
        run(scene(), state_for(6), 2 * N, record="states", out=out, resume=True)
    with pytest.raises(ValueError, match=f"{out / 'checkpoint.npz'} belongs to a run from other initial states"):
        run(scene(), state_for(7), N, record="states", out=out, resume=True)


def test_a_section_file_shorter_than_its_checkpoint_is_named(tmp_path):
    out = tmp_path / "run"
    section = Section(every_collision, position, capacity=CHUNK)
    run(scene(), state_for(6), N, record=section, chunk=CHUNK, out=out)
    with open(out / "section_t.npy", "r+b") as f:
        f.truncate(os.path.getsize(out / "section_t.npy") - 8 * 10)
    with pytest.raises(ValueError, match="section_t.npy: holds 110 rows; the checkpoint counts 120"):
        run(scene(), state_for(6), N, record=section, chunk=CHUNK, out=out, resume=True)
