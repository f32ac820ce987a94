"""Where a batch's speed-up from one core to two goes: ``jb.run`` over two JAX devices against numba's two threads.

Run:  python benchmarks/bench_two_cores.py [--quick] [--rounds N] [--batch B] [--collisions N ...]

Prints a markdown report, everything measured in this one process, R = 2,
float64, default inertia ``I = M ell^2``, for the rotor at ell = 1.9 and 1.0
and the stick between walls (h = 3, ell = 1), from the same seeded starts as
``bench_vs_numba.py``:

1. the speed-up from one core to two of ``jb.run`` (final states; one JAX
   device, then two) and of numba's ``run_batch`` / ``run_batch_parallel``
   (one thread, then two), at each ``--collisions`` per orbit (default 200,
   as ``bench_vs_numba.py``, and 2000): the median time of each, the cores
   each two-core call kept busy, and the spread of the calls (90th percentile
   over the median), which shows how much the machine's noise moves each;
2. the split's balance: each half of the batch (the orbits each of two
   devices gets) run alone on one device, as a share of the whole batch's
   time on that device; the whole over the slower half is the best speed-up
   that split allows.

Timings are medians over ``--rounds`` interleaved rounds (``interleaved.py``)
after a warm-up call of each contender that compiles. "cores used" is process
CPU time over wall time during the timed calls. The benchmark sets
``OMP_WAIT_POLICY=PASSIVE`` (unless set), as ``bench_vs_numba.py`` does, so
that numba's threads do not spin on the cores jaxbill needs next. It needs two
JAX CPU devices (jaxbill makes one per core; a machine of one core prints
why not and exits). Nothing here asserts on timings.
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
    parser.add_argument("--quick", action="store_true", help="200 collisions per orbit only, 3 rounds: under a minute")
    parser.add_argument("--rounds", type=int, default=None, help="timed rounds per row (default 7, quick 3)")
    parser.add_argument("--batch", type=int, default=4096, help="orbits in the batch (default 4096)")
    parser.add_argument(
        "--collisions", type=int, nargs="+", default=None, help="collisions per orbit, one table row each (200 2000)"
    )
    args = parser.parse_args(argv)
    if args.rounds is None:
        args.rounds = 3 if args.quick else 7
    if args.collisions is None:
        args.collisions = [200] if args.quick else [200, 2000]
    if args.batch < 2 or args.batch % 2:
        parser.error(f"--batch must be an even number of orbits, at least 2; got {args.batch}")
    return args


# Read by libgomp when numba first starts its OpenMP threads (see the docstring).
os.environ.setdefault("OMP_WAIT_POLICY", "PASSIVE")

import jax  # noqa: E402
import numba  # noqa: E402
import numpy as np  # noqa: E402

import jaxbill as jb  # noqa: E402

sys.path.insert(0, HERE)
import numba_baseline as baseline  # noqa: E402
from interleaved import Timing, interleaved, load_average  # noqa: E402

SCENES = {
    "rotor ell=1.9": baseline.circle_params(2.0, 1.9),
    "rotor ell=1.0": baseline.circle_params(2.0, 1.0),
    "walls h=3 ell=1": baseline.walls_params(3.0, 1.0),
}


def spread(timing: Timing) -> float:
    """The 90th percentile of a contender's calls over their median."""
    return float(np.percentile(timing.round_seconds, 90)) / timing.median


def speed_ups(args, devices) -> None:
    print(f"## One core to two: {args.batch} orbits, final states")
    print()
    print(
        "Times in seconds (medians); speed-up = one core's time over two cores'; spread = 90th percentile of "
        "the calls over their median."
    )
    print()
    print(
        "| scene | collisions / orbit | jb.run 1 core | jb.run 2 cores | speed-up jb.run | numba 1 thread "
        "| numba 2 threads | speed-up numba | cores used, 2 cores (jb.run, numba) "
        "| spread 1 core (jb.run, numba) | spread 2 cores (jb.run, numba) |"
    )
    print("|---|---|---|---|---|---|---|---|---|---|---|")
    for n in args.collisions:
        for label, params in SCENES.items():
            scene = baseline.jaxbill_scene(params)
            states0 = baseline.random_states(params, args.batch, seed=11)
            contenders = {
                "jb1": lambda: jb.run(scene, states0, n, devices=devices[:1], progress=False),
                "jb2": lambda: jb.run(scene, states0, n, devices=devices[:2], progress=False),
                "numba1": lambda: baseline.run_batch(params, states0, n),
                "numba2": lambda: baseline.run_batch_parallel(params, states0, n, threads=2),
            }
            t = interleaved(contenders, args.rounds)
            numba.set_num_threads(numba.config.NUMBA_NUM_THREADS)
            jb1, jb2, nb1, nb2 = (t[name] for name in ("jb1", "jb2", "numba1", "numba2"))
            print(
                f"| {label} | {n} | {jb1.median:.3f} | {jb2.median:.3f} | **{jb1.median / jb2.median:.2f}** "
                f"| {nb1.median:.3f} | {nb2.median:.3f} | {nb1.median / nb2.median:.2f} "
                f"| {jb2.cores:.2f}, {nb2.cores:.2f} | {spread(jb1):.2f}, {spread(nb1):.2f} "
                f"| {spread(jb2):.2f}, {spread(nb2):.2f} |",
                flush=True,
            )
    print()


def balance(args, devices) -> None:
    n = args.collisions[0]
    half = args.batch // 2
    print(f"## The split's balance: each device's half of {args.batch} orbits x {n} collisions, alone on one device")
    print()
    print("| scene | whole batch s | first half s | second half s | shares of the whole | whole / slower half |")
    print("|---|---|---|---|---|---|")
    for label, params in SCENES.items():
        scene = baseline.jaxbill_scene(params)
        states0 = baseline.random_states(params, args.batch, seed=11)
        contenders = {
            "whole": lambda: jb.run(scene, states0, n, devices=devices[:1], progress=False),
            "first": lambda: jb.run(scene, states0[:half], n, devices=devices[:1], progress=False),
            "second": lambda: jb.run(scene, states0[half:], n, devices=devices[:1], progress=False),
        }
        t = {name: timing.median for name, timing in interleaved(contenders, args.rounds).items()}
        print(
            f"| {label} | {t['whole']:.3f} | {t['first']:.3f} | {t['second']:.3f} "
            f"| {t['first'] / t['whole']:.3f}, {t['second'] / t['whole']:.3f} "
            f"| {t['whole'] / max(t['first'], t['second']):.2f} |",
            flush=True,
        )
    print()


def main(args) -> None:
    started = time.perf_counter()
    devices = jax.devices()
    print("# One core to two: jaxbill's batch against numba's")
    print()
    print(
        f"- python {platform.python_version()}, jax {jax.__version__} ({jax.default_backend()}), "
        f"numba {numba.__version__}, numpy {np.__version__}; {os.cpu_count()} logical CPUs, "
        f"{len(devices)} JAX devices ({jb.backend_settings()['cpu_devices']})"
    )
    print(f"- {args.rounds} interleaved rounds, medians; R = 2, float64, I = M ell^2")
    print(f"- load average at start: {load_average()}")
    print()
    if len(devices) < 2 or jax.default_backend() != "cpu":
        print(f"Needs two JAX CPU devices; this process has {len(devices)} {jax.default_backend()} device(s).")
        return
    speed_ups(args, devices)
    balance(args, devices)
    print(f"- load average at end: {load_average()}; total {time.perf_counter() - started:.0f} s")


if __name__ == "__main__":
    main(parse_arguments())
