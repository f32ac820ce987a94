"""jaxbill against the plain numba loop of the same method (``numba_baseline.py``), on CPU.

Run:  python benchmarks/bench_vs_numba.py [--quick] [--rounds N] [--cpu-devices D]
                                           [--orbit-collisions N] [--batch B] [--batch-collisions N]

Prints a markdown report, everything measured in this one process, R = 2,
float64, default inertia ``I = M ell^2``:

1. one orbit of ``--orbit-collisions`` collisions (default 2e5), every state
   recorded: ``jb.orbit(scene, state0, n)`` against numba ``orbit``, for the
   rotor at ell = 1.9 and 1.0, the lens at ell = 1.5, the circle and the stick
   between walls (h = 3, ell = 1);
2. a batch of ``--batch`` orbits (default 4096) of ``--batch-collisions``
   collisions (default 200), final states only, on one core:
   ``jb.run(scene, states, n)`` on one JAX device and ``jb.orbit`` (batched,
   which records every state) against numba ``run_batch``;
3. the same batch on two cores: ``jb.run`` over two JAX devices against numba
   ``run_batch_parallel`` (``prange``) with two threads, and each one's
   speed-up from one core to two;
4. root steps per collision: numba's, and jaxbill's from the same states
   (jaxbill's sharper steps, ``numba_baseline``'s docstring).

On CPU the JAX devices are the host's cores split by
``XLA_FLAGS=--xla_force_host_platform_device_count=D`` (``--cpu-devices``, or
the environment variable ``JAXBILL_BENCH_CPU_DEVICES``; default 2), set here
before JAX starts. Timings are medians over ``--rounds`` rounds in which the
two implementations alternate (A, B, A, B, ...), after a warm-up call of each
that compiles. "cores used" is process CPU time over wall time during the
timed calls. numba's parallel loop runs on OpenMP threads, which by default
spin for a while after each loop, on the cores the next contender needs (one
``jb.run`` call on two devices took 11.7 ms after numba's parallel loop, 7.8 ms
after its serial one): the benchmark sets ``OMP_WAIT_POLICY=PASSIVE`` (unless
set), which left numba's own two-thread time unchanged (15.1 ms and 15.0 ms).
The ratio column is jaxbill's time over numba's (above 1: numba is faster).
Nothing here asserts on timings; on a shared machine, read the load averages
printed before and after.
"""

from __future__ import annotations

import argparse
import os
import platform
import sys
import time

HERE = os.path.dirname(os.path.abspath(__file__))


def parse_arguments(argv=None):
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--quick", action="store_true", help="small sizes: about a minute in all")
    parser.add_argument("--rounds", type=int, default=None, help="timed rounds per row (default 7, quick 3)")
    parser.add_argument(
        "--cpu-devices",
        type=int,
        default=int(os.environ.get("JAXBILL_BENCH_CPU_DEVICES", "2")),
        help="JAX CPU devices to split the host into (default 2, or $JAXBILL_BENCH_CPU_DEVICES)",
    )
    parser.add_argument(
        "--orbit-collisions", type=int, default=None, help="collisions of the single orbit (2e5; quick 2e4)"
    )
    parser.add_argument("--batch", type=int, default=None, help="orbits in the batch (4096; quick 1024)")
    parser.add_argument(
        "--batch-collisions", type=int, default=None, help="collisions per batched orbit (200; quick 100)"
    )
    args = parser.parse_args(argv)
    defaults = (3, 20_000, 1024, 100) if args.quick else (7, 200_000, 4096, 200)
    for name, value in zip(("rounds", "orbit_collisions", "batch", "batch_collisions"), defaults):
        if getattr(args, name) is None:
            setattr(args, name, value)
    return args


ARGS = parse_arguments() if __name__ == "__main__" else None
if ARGS is not None and ARGS.cpu_devices > 1:
    flags = [
        f for f in os.environ.get("XLA_FLAGS", "").split() if not f.startswith("--xla_force_host_platform_device_count")
    ]
    os.environ["XLA_FLAGS"] = " ".join(flags + [f"--xla_force_host_platform_device_count={ARGS.cpu_devices}"])

# Read by libgomp when numba first starts its OpenMP threads (see the docstring).
os.environ.setdefault("OMP_WAIT_POLICY", "PASSIVE")

import jax  # noqa: E402
import jax.numpy as jnp  # noqa: E402
import numba  # noqa: E402
import numpy as np  # noqa: E402

import jaxbill as jb  # noqa: E402

sys.path.insert(0, HERE)
import numba_baseline as baseline  # noqa: E402
from interleaved import interleaved, load_average  # noqa: E402

# label -> params (numba_baseline layout); the orbit table runs all, the batch tables BATCH_SCENES.
SCENES = {
    "rotor ell=1.9": baseline.circle_params(2.0, 1.9),
    "rotor ell=1.0": baseline.circle_params(2.0, 1.0),
    "lens ell=1.5": baseline.circle_params(2.0, 1.5, inertia=float("inf")),
    "circle": baseline.circle_params(2.0, 0.0),
    "walls h=3 ell=1": baseline.walls_params(3.0, 1.0),
}
QUICK_BATCH_SCENES = ("rotor ell=1.9", "lens ell=1.5")


def rate(collisions, seconds):
    return f"{collisions / seconds:.3g}"


def single_orbits(args):
    print(f"## One orbit of {args.orbit_collisions} collisions, every state recorded")
    print()
    print(
        "| scene | jb.orbit s | numba orbit s | ratio jaxbill/numba | jb.orbit coll/s | numba coll/s "
        "| cores used (jb, numba) | root steps / collision (numba, jaxbill) |"
    )
    print("|---|---|---|---|---|---|---|---|")
    n = args.orbit_collisions
    for label, params in SCENES.items():
        scene = baseline.jaxbill_scene(params)
        state0 = baseline.random_states(params, 1, seed=7)[0]
        device_state0 = jnp.asarray(state0)
        numba_orbits = []  # the last call's (t, contact, states, root_steps)

        def run_jaxbill():
            jax.block_until_ready(jb.orbit(scene, device_state0, n))

        def run_numba():
            numba_orbits[:] = [baseline.orbit(params, state0, n)]

        times = interleaved({"jaxbill": run_jaxbill, "numba": run_numba}, args.rounds)
        (t_jb, c_jb), (t_nb, c_nb) = ((times[name].median, times[name].cores) for name in ("jaxbill", "numba"))
        # Both counted from the same states, those of numba's orbit's first collisions.
        counted = min(n, 20_000)
        _, _, numba_states, numba_steps = numba_orbits[0]
        before = np.concatenate([state0[None], numba_states[: counted - 1]])
        jaxbill_steps = baseline.jaxbill_root_steps(params, before)
        print(
            f"| {label} | {t_jb:.3f} | {t_nb:.3f} | {t_jb / t_nb:.2f} | {rate(n, t_jb)} | {rate(n, t_nb)} "
            f"| {c_jb:.1f}, {c_nb:.1f} | {np.mean(numba_steps[:counted]):.2f}, {np.mean(jaxbill_steps):.2f} |"
        )
    print()


def batches(args, scenes):
    devices = jax.devices()
    two = len(devices) >= 2
    batch, n = args.batch, args.batch_collisions
    collisions = batch * n
    print(f"## A batch of {batch} orbits x {n} collisions, final states")
    print()
    print(
        "One core: `jb.run` on one JAX device, `jb.orbit` (batched; records every state) and numba `run_batch`. "
        "Two cores: `jb.run` over two JAX devices and numba `run_batch_parallel` with two threads. "
        "Times in seconds (collisions/s in brackets); ratios are jaxbill's time over numba's."
    )
    print()
    print(
        "| scene | jb.run 1 core | jb.orbit 1 core | numba 1 core | ratio jb.run/numba | ratio jb.orbit/numba "
        "| jb.run 2 cores | numba 2 cores | ratio 2 cores | speed-up 1 -> 2 cores (jb.run, numba) "
        "| cores used (jb.run 1/2, numba 1/2) | numba root steps / collision |"
    )
    print("|---|---|---|---|---|---|---|---|---|---|---|---|")
    for label in scenes:
        params = SCENES[label]
        scene = baseline.jaxbill_scene(params)
        states0 = baseline.random_states(params, batch, seed=11)
        steps = []

        def run_numba():
            steps.append(baseline.run_batch(params, states0, n)[3])

        contenders = {
            "run1": lambda: jb.run(scene, states0, n, devices=devices[:1], progress=False),
            "orbit1": lambda: jax.block_until_ready(jb.orbit_sharded(scene, states0, n, devices=devices[:1])),
            "numba1": run_numba,
        }
        if two:
            contenders["run2"] = lambda: jb.run(scene, states0, n, devices=devices[:2], progress=False)
            contenders["numba2"] = lambda: baseline.run_batch_parallel(params, states0, n, threads=2)
        times = {name: (t.median, t.cores) for name, t in interleaved(contenders, args.rounds).items()}
        numba.set_num_threads(numba.config.NUMBA_NUM_THREADS)

        def cell(name):
            return f"{times[name][0]:.3f} ({rate(collisions, times[name][0])})" if name in times else "n/a"

        def ratio(a, b):
            return f"{times[a][0] / times[b][0]:.2f}" if a in times and b in times else "n/a"

        def cores(name):
            return f"{times[name][1]:.1f}" if name in times else "n/a"

        speedups = (
            f"{times['run1'][0] / times['run2'][0]:.2f}, {times['numba1'][0] / times['numba2'][0]:.2f}"
            if two
            else "n/a"
        )
        print(
            f"| {label} | {cell('run1')} | {cell('orbit1')} | {cell('numba1')} | {ratio('run1', 'numba1')} "
            f"| {ratio('orbit1', 'numba1')} | {cell('run2')} | {cell('numba2')} | {ratio('run2', 'numba2')} "
            f"| {speedups} | {cores('run1')}/{cores('run2')}, {cores('numba1')}/{cores('numba2')} "
            f"| {steps[-1].sum() / collisions:.2f} |"
        )
    print()


def main(args):
    started = time.perf_counter()
    print("# jaxbill vs a plain numba loop of the same method")
    print()
    print(
        f"- python {platform.python_version()}, jax {jax.__version__} ({jax.default_backend()}), "
        f"numba {numba.__version__} ({numba.config.NUMBA_NUM_THREADS} threads), numpy {np.__version__}"
    )
    print(
        f"- machine: {platform.machine()}, {os.cpu_count()} logical CPUs; "
        f"len(jax.devices()) = {len(jax.devices())} (XLA_FLAGS={os.environ.get('XLA_FLAGS', '')!r})"
    )
    print(
        f"- sizes: orbit {args.orbit_collisions} collisions; batch {args.batch} x {args.batch_collisions}; "
        f"{args.rounds} interleaved rounds, medians; R = 2, float64, I = M ell^2"
    )
    print(f"- load average at start: {load_average()}")
    print()
    single_orbits(args)
    batches(args, QUICK_BATCH_SCENES if args.quick else tuple(SCENES))
    print(f"- load average at end: {load_average()}; total {time.perf_counter() - started:.0f} s")


if __name__ == "__main__":
    main(ARGS)
