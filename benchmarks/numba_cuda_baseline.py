"""The numba baseline as a CUDA kernel: one thread per orbit, the state in registers.

Run:  NUMBA_ENABLE_CUDASIM=1 python benchmarks/numba_cuda_baseline.py   (no GPU: the simulator)
      python benchmarks/numba_cuda_baseline.py [--orbits B] [--collisions N]   (on a GPU)

The per-collision code is ``numba_baseline.make_engine`` compiled with
``cuda.jit(device=True)``: the same method, line for line, as the CPU loop
(and as jaxbill). Each thread runs one orbit of ``n`` collisions and writes
its final state, final time, the collisions that reached a wall and its root
steps in all. Without a GPU, ``check_against_cpu`` runs a few orbits in
numba's CUDA simulator and compares them with ``numba_baseline.run_batch``.
"""

from __future__ import annotations

import argparse
import math
import os
import sys
import time

import numpy as np

# numba-cuda on the GPU machine still calls np.row_stack, which numpy 2.x removed.
# (The shim is the point, so NumPy's deprecation rule does not apply to it.)
if not hasattr(np, "row_stack"):
    np.row_stack = np.vstack  # noqa: NPY201

from numba import cuda

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
import numba_baseline as baseline

THREADS_PER_BLOCK = 128


@cuda.jit(device=True)
def _fmod(a, b):
    return math.fmod(a, b)


_device = baseline.make_engine(cuda.jit(device=True), _fmod)
_collide = _device.collide
_orbit_direction = _device.orbit_direction


@cuda.jit
def _batch_kernel(params, states0, n, final_states, final_times, collisions, root_steps):
    i = cuda.grid(1)
    if i >= states0.shape[0]:
        return
    kind, size, ell, mass, inertia = int(params[0]), params[1], params[2], params[3], params[4]
    x, y, a, vx, vy, om = states0[i, 0], states0[i, 1], states0[i, 2], states0[i, 3], states0[i, 4], states0[i, 5]
    ux, uy = _orbit_direction(kind, a)
    t = 0.0
    hits = 0
    steps_total = 0
    for _ in range(n):
        x, y, a, vx, vy, om, dt, contact, steps = _collide(kind, size, ell, mass, inertia, ux, uy, x, y, a, vx, vy, om)
        t = t + dt
        if contact != baseline.NO_CONTACT:
            hits += 1
        steps_total += steps
    final_states[i, 0] = x
    final_states[i, 1] = y
    final_states[i, 2] = a
    final_states[i, 3] = vx
    final_states[i, 4] = vy
    final_states[i, 5] = om
    final_times[i] = t
    collisions[i] = hits
    root_steps[i] = steps_total


def run_batch_cuda(params, states0, n, threads_per_block=THREADS_PER_BLOCK):
    """``numba_baseline.run_batch`` on the GPU: one thread per orbit.

    Args:
        params: ``(5,)`` float64 scene (``numba_baseline``); states0: ``(B, 6)``
            float64; n: collisions per orbit.

    Returns:
        ``(final_states (B, 6), final_times (B,), collisions (B,) int64,
        root_steps (B,) int64)`` as numpy arrays (copied back from the device).
    """
    batch = states0.shape[0]
    device_params = cuda.to_device(np.ascontiguousarray(params, dtype=np.float64))
    device_states = cuda.to_device(np.ascontiguousarray(states0, dtype=np.float64))
    final_states = cuda.device_array((batch, 6), np.float64)
    final_times = cuda.device_array(batch, np.float64)
    collisions = cuda.device_array(batch, np.int64)
    root_steps = cuda.device_array(batch, np.int64)
    blocks = (batch + threads_per_block - 1) // threads_per_block
    _batch_kernel[blocks, threads_per_block](
        device_params, device_states, n, final_states, final_times, collisions, root_steps
    )
    cuda.synchronize()
    return final_states.copy_to_host(), final_times.copy_to_host(), collisions.copy_to_host(), root_steps.copy_to_host()


def check_against_cpu(orbits=4, collisions=30, seed=3, show=True):
    """Final states of the CUDA kernel and of the CPU ``run_batch`` from the same states, for every scene.

    Returns ``{scene: (max relative state difference, same collision and root-step counts)}``.
    """
    results = {}
    for label, params in baseline.CHECK_SCENES.items():
        states0 = baseline.random_states(params, orbits, seed=seed)
        gpu = run_batch_cuda(params, states0, collisions, threads_per_block=min(THREADS_PER_BLOCK, orbits))
        cpu = baseline.run_batch(params, states0, collisions)
        diff = float(baseline.relative_difference(gpu[0], cpu[0]).max())
        same_counts = bool(np.array_equal(gpu[2], cpu[2]) and np.array_equal(gpu[3], cpu[3]))
        results[label] = (diff, same_counts)
        if show:
            print(f"| {label} | {diff:.1e} | {same_counts} | {cpu[3].sum() / max(cpu[2].sum(), 1):.2f} |")
    return results


def main(argv=None):
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--orbits", type=int, default=None, help="orbits for the timing (GPU only)")
    parser.add_argument("--collisions", type=int, default=200, help="collisions per orbit for the timing")
    args = parser.parse_args(argv)
    simulated = os.environ.get("NUMBA_ENABLE_CUDASIM") == "1"
    print(f"CUDA kernel vs CPU run_batch ({'simulator' if simulated else cuda.get_current_device().name})")
    print()
    print("| scene | max rel. final-state diff | same collision and root-step counts | root steps / collision |")
    print("|---|---|---|---|")
    results = check_against_cpu(orbits=4 if simulated else 256, collisions=30 if simulated else 200)
    ok = all(d < 1e-9 and same for d, same in results.values())
    if not simulated:
        orbits = args.orbits or 1 << 16
        print()
        print("| scene | orbits x collisions | seconds (median of 5) | collisions / s |")
        print("|---|---|---|---|")
        for label, params in baseline.CHECK_SCENES.items():
            states0 = baseline.random_states(params, orbits, seed=0)
            run_batch_cuda(params, states0[:256], 2)  # compile
            seconds = []
            for _ in range(5):
                started = time.perf_counter()
                run_batch_cuda(params, states0, args.collisions)
                seconds.append(time.perf_counter() - started)
            median = float(np.median(seconds))
            rate = orbits * args.collisions / median
            print(f"| {label} | {orbits} x {args.collisions} | {median:.3f} | {rate:.3g} |")
    return 0 if ok else 1


if __name__ == "__main__":
    sys.exit(main())
