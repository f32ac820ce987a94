"""Two processes on localhost under ``jax.distributed``, one CPU device each, split a
batch between them and get bitwise what one process gets.

Each process runs the same script: ``jax.distributed.initialize`` with a
coordinator on a free local port, then ``jb.run`` and ``orbit_sharded`` on the
full batch. The batch is split over the global mesh of both processes' devices;
each process computes and keeps its own orbits (``Run.orbit_index``) and writes
its own run directory (``out/process_<i>``). Every subprocess has a timeout, and
the coordinator's start-up has one, so a failure cannot hang the test suite.
"""

from __future__ import annotations

import os
import socket
import subprocess
import sys
import textwrap

import jax
import numpy as np

import jaxbill as jb
from helpers import random_states
from jaxbill import Checkpoint, run

HERE = os.path.dirname(os.path.abspath(__file__))
N = 40
TIMEOUT_S = 240
SEED = 11


def _batch(scene):
    # Two lanes and a few more orbits: both processes hold real orbits and padding.
    count = 2 * scene.batch_chunk + 5
    return np.asarray(random_states(np.random.default_rng(SEED), count, 2.0, float(scene.ell), scene.kind))


_WORKER = textwrap.dedent(
    """
    import sys
    import numpy as np
    import jax

    tests, port, process_id, out = sys.argv[1], int(sys.argv[2]), int(sys.argv[3]), sys.argv[4]
    jax.config.update("jax_num_cpu_devices", 1)
    jax.distributed.initialize(coordinator_address=f"localhost:{port}", num_processes=2,
                               process_id=process_id, initialization_timeout=60)
    sys.path.insert(0, tests)
    import jaxbill as jb
    from jax.experimental import multihost_utils
    from jaxbill import orbit_sharded
    from jaxbill import run
    from test_distributed import N, _batch

    assert jax.process_count() == 2 and len(jax.devices()) == 2 and len(jax.local_devices()) == 1
    scene = jb.StickInCircle(R=2.0, ell=1.5, inertia=float("inf"))
    states0 = _batch(scene)  # every process builds the same full batch
    result = run(scene, states0, N, record="states", chunk=17, out=out)
    orbits = orbit_sharded(scene, states0, N)
    everything = multihost_utils.process_allgather(orbits.state, tiled=True)
    np.savez(f"{out}/sharded_{process_id}.npz", state=everything, orbit_index=result.orbit_index)
    jax.distributed.shutdown()
    """
)


def _free_port() -> int:
    with socket.socket(socket.AF_INET, socket.SOCK_STREAM) as s:
        s.bind(("localhost", 0))
        return s.getsockname()[1]


def test_two_processes_split_a_batch_and_match_one_process(tmp_path):
    env = dict(os.environ)
    env["JAX_PLATFORMS"] = "cpu"
    # One device per process, whatever the parent was started with.
    env["XLA_FLAGS"] = " ".join(
        f for f in env.get("XLA_FLAGS", "").split() if not f.startswith("--xla_force_host_platform_device_count")
    )
    port = _free_port()
    out = tmp_path / "run"
    workers = [
        subprocess.Popen(
            [sys.executable, "-c", _WORKER, HERE, str(port), str(i), str(out)],
            env=env,
            stdout=subprocess.PIPE,
            stderr=subprocess.PIPE,
            text=True,
        )
        for i in range(2)
    ]
    logs = []
    try:
        for worker in workers:
            logs.append(worker.communicate(timeout=TIMEOUT_S))
    finally:
        for worker in workers:
            if worker.poll() is None:
                worker.kill()
                worker.communicate()
    for i, (worker, (_, stderr)) in enumerate(zip(workers, logs)):
        assert worker.returncode == 0, f"process {i} failed:\n{stderr[-3000:]}"

    scene = jb.StickInCircle(R=2.0, ell=1.5, inertia=float("inf"))
    states0 = _batch(scene)
    reference = run(scene, states0, N, record="states", chunk=17, devices=jax.devices()[:1])
    seen = []
    for i in range(2):
        directory = out / f"process_{i}"
        checkpoint = Checkpoint.load(directory / "checkpoint.npz")
        index = checkpoint.orbit_index
        assert 0 < index.size < states0.shape[0]  # each process ran a real share
        seen.append(index)
        np.testing.assert_array_equal(np.load(directory / "state.npy"), reference.state[index])
        np.testing.assert_array_equal(np.load(directory / "t.npy"), reference.t[index])
        np.testing.assert_array_equal(checkpoint.state, reference.final_state[index])
        np.testing.assert_array_equal(checkpoint.contact_counts, reference.contact_counts[index])
        with np.load(out / f"sharded_{i}.npz") as gathered:
            np.testing.assert_array_equal(gathered["state"], reference.state)
    # Together the processes ran every orbit exactly once.
    np.testing.assert_array_equal(np.sort(np.concatenate(seen)), np.arange(states0.shape[0]))
