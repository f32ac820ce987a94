"""Batches split over several devices give bitwise the results of one device.

The two-device checks run in a subprocess started with
``XLA_FLAGS=--xla_force_host_platform_device_count=2`` (the flag must be set
before JAX starts), so this machine's CPU appears as two JAX devices.
"""

from __future__ import annotations

import json
import os
import subprocess
import sys
import textwrap

import numpy as np
import pytest

import jaxbill as jb
from helpers import random_states
from jaxbill import run
from jaxbill._engine.collision import orbit_sharded
from jaxbill._engine.sharding import orbit_mesh, pad_batch, padded_batch_size

HERE = os.path.dirname(os.path.abspath(__file__))
# The sizes of tests/test_streaming.py, so that in one pytest session the
# compiled programs are shared.
N = 120
CHUNK = 37


def _states(kind, ell, count, seed=3):
    return np.asarray(random_states(np.random.default_rng(seed), count, 2.0, ell, kind))


def test_an_orbit_does_not_depend_on_the_batch_around_it():
    """jb.run pads every batch to whole lanes of scene.batch_chunk orbits, so an
    orbit runs in the same vectorised program whether its batch holds 3 orbits
    or 70 (jb.orbit narrows the program for a batch under one lane, and on CPU
    that can change the last bit)."""
    scene = jb.StickInCircle(R=2.0, ell=1.5, inertia=float("inf"))
    states0 = _states("lens", 1.5, scene.batch_chunk + 3)
    small = run(scene, states0[:3], N, record="states", chunk=CHUNK)
    large = run(scene, states0, N, record="states", chunk=CHUNK)
    np.testing.assert_array_equal(small.state, large.state[:3])
    np.testing.assert_array_equal(small.t, large.t[:3])


def test_orbit_sharded_on_one_device_equals_orbit():
    scene = jb.StickInCircle(R=2.0, ell=1.5, inertia=float("inf"))
    states0 = _states("lens", 1.5, scene.batch_chunk + 3)
    expected = jb.orbit(scene, states0, N)
    result = orbit_sharded(scene, states0, N, devices=orbit_mesh().devices.ravel()[:1])
    np.testing.assert_array_equal(np.asarray(result.state), np.asarray(expected.state))
    np.testing.assert_array_equal(np.asarray(result.t), np.asarray(expected.t))


def test_padding_and_mesh_arguments():
    mesh = orbit_mesh()
    assert mesh.axis_names == ("orbits",) and mesh.size == len(mesh.devices.ravel())
    assert padded_batch_size(1, 64, mesh) == 64 * mesh.size
    assert padded_batch_size(64 * mesh.size + 1, 64, mesh) == 2 * 64 * mesh.size
    padded = pad_batch(np.arange(6.0).reshape(3, 2), 5)
    np.testing.assert_array_equal(padded[3:], [[0.0, 1.0], [0.0, 1.0]])
    with pytest.raises(ValueError, match="devices must be"):
        orbit_mesh([])
    with pytest.raises(ValueError, match="devices must be"):
        orbit_mesh(["cpu:0"])
    with pytest.raises(ValueError, match="batch of shape"):
        orbit_sharded(jb.StickInCircle(R=2.0, ell=1.0), np.zeros(6), 3)


_TWO_DEVICES = textwrap.dedent(
    """
    import json, sys
    import numpy as np
    import jax
    sys.path.insert(0, sys.argv[1])
    import jaxbill as jb
    from jaxbill import orbit_mesh, orbit_sharded
    from jaxbill import run
    from helpers import random_states

    N = int(sys.argv[2])
    out = {"devices": len(jax.devices())}
    one = jax.devices()[:1]
    for kind, ell, inertia in (("rotor", 1.5, None), ("lens", 1.5, float("inf"))):
        scene = jb.StickInCircle(R=2.0, ell=ell, inertia=inertia)
        # One lane and a few more orbits: the two devices get unequal real work.
        states0 = np.asarray(random_states(np.random.default_rng(5), scene.batch_chunk + 3, 2.0, ell, kind))
        expected = jb.orbit(scene, states0, N)
        two = orbit_sharded(scene, states0, N)
        run_two = run(scene, states0, N, record="states", chunk=23)
        run_one = run(scene, states0, N, record="states", chunk=23, devices=one)
        out[kind] = {
            "orbit_sharded == orbit": bool(np.array_equal(np.asarray(two.state), np.asarray(expected.state))
                                           and np.array_equal(np.asarray(two.t), np.asarray(expected.t))),
            "run: 2 devices == orbit": bool(np.array_equal(run_two.state, np.asarray(expected.state))),
            "run: 2 devices == 1 device": bool(np.array_equal(run_two.state, run_one.state)
                                               and np.array_equal(run_two.t, run_one.t)
                                               and np.array_equal(run_two.contact_counts, run_one.contact_counts)),
        }
        if kind == "lens":
            # A batch smaller than one lane: padded to one lane per device.
            small_two = run(scene, states0[:5], N, record="states", chunk=23)
            small_one = run(scene, states0[:5], N, record="states", chunk=23, devices=one)
            out[kind]["small batch: 2 devices == 1 device"] = bool(np.array_equal(small_two.state, small_one.state))
    print("RESULT" + json.dumps(out))
    """
)


def test_two_host_devices_give_bitwise_the_results_of_one():
    env = dict(os.environ)
    env["XLA_FLAGS"] = (env.get("XLA_FLAGS", "") + " --xla_force_host_platform_device_count=2").strip()
    env["JAX_PLATFORMS"] = "cpu"
    proc = subprocess.run(
        [sys.executable, "-c", _TWO_DEVICES, HERE, "40"], env=env, capture_output=True, text=True, timeout=300
    )
    assert proc.returncode == 0, proc.stderr[-3000:]
    line = next(ln for ln in proc.stdout.splitlines() if ln.startswith("RESULT"))
    out = json.loads(line[len("RESULT") :])
    assert out["devices"] == 2
    for kind in ("rotor", "lens"):
        failed = [check for check, ok in out[kind].items() if not ok]
        assert not failed, f"{kind}: {failed}"
