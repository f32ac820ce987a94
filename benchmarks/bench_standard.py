"""Point particles in Sinai's billiard and the stadium: jaxbill's collisions per second beside numba's and
DynamicalBilliards.jl's published figure.

Run:  python benchmarks/bench_standard.py [--quick] [--rounds N] [--out results/standard_<date>.md]

Prints (and writes) a markdown table, everything measured in this one process,
float64, a point of unit speed, Sinai's billiard (radius 0.25 in the unit
square) and the stadium (half_length 1, radius 1), from the same Liouville
starts (``jb.sample_energy_shell``, seed 11):

1. one orbit: ``jb.run`` of one state (its serial driver) against
   ``numba_point_billiards.run_one``, the same closed forms in a scalar loop;
2. a batch on one core: ``jb.run`` on one JAX CPU device against numba's
   ``run_batch`` on one thread;
3. a batch on two cores: ``jb.run`` over two devices against ``run_batch_parallel``
   on two threads.

Each row gives the median wall time of the interleaved rounds
(``interleaved.py``), the collisions per second and per core (two cores: the
rate over 2), and ns per collision per core. The machine is shared: the load
average at the start and the end, and the cores each call kept busy, say how
much. ``OMP_WAIT_POLICY=PASSIVE`` (unless set) keeps numba's threads from
spinning on cores jaxbill needs next. Nothing here asserts on timings.

DynamicalBilliards.jl's figure: the statement this benchmark was asked to quote
("about 45 ns per straight-line bounce") is not in the package's documentation
or repository as stored here; the one timing the repository publishes is in its
``benchmark/testscript.jl`` (commit ae6566e, 2018-06-13, "add sincos
everywhere!"): ``@btime bounce!($p, $bt)`` for ``bt = billiard_sinai()`` and a
``MagneticParticle`` (circular flights), 278.529 ns before and 57.476 ns after
that commit, on the author's machine. It is quoted beside the table as it is.
"""

from __future__ import annotations

import argparse
import datetime
import os
import platform
import sys
import time

HERE = os.path.dirname(os.path.abspath(__file__))
os.environ.setdefault("OMP_WAIT_POLICY", "PASSIVE")

import jax  # noqa: E402
import numba  # noqa: E402
import numpy as np  # noqa: E402

import jaxbill as jb  # noqa: E402

sys.path.insert(0, HERE)
import numba_point_billiards as nb  # noqa: E402
from interleaved import interleaved, load_average  # noqa: E402

TABLES = {
    "Sinai (r = 0.25, side 1)": (jb.Sinai(0.25, 1.0), nb.SINAI, 0.25, 1.0),
    "stadium (L = 1, r = 1)": (jb.Stadium(1.0, 1.0), nb.STADIUM, 1.0, 1.0),
}
DYNAMICAL_BILLIARDS_NS = 57.476  # benchmark/testscript.jl, bounce! of a MagneticParticle in billiard_sinai()


def parse_arguments(argv=None):
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--quick", action="store_true", help="smaller runs, 3 rounds")
    parser.add_argument("--rounds", type=int, default=None, help="interleaved rounds (default 7, quick 3)")
    parser.add_argument("--out", default=None, help="also write the report here (default results/standard_<time>.md)")
    args = parser.parse_args(argv)
    if args.rounds is None:
        args.rounds = 3 if args.quick else 7
    return args


def rows(args):
    devices = jax.devices()
    one_orbit = 20_000 if args.quick else 200_000
    batch, per_orbit = (1024, 200) if args.quick else (4096, 1000)
    out = []
    for label, (table, kind, a, b) in TABLES.items():
        scene = jb.BodyInTable(jb.PointBody(), table)
        starts, _ = jb.sample_energy_shell(scene, batch, seed=11)
        starts = np.asarray(starts)
        state0 = starts[0]
        contenders = {
            "jb one orbit": lambda: jb.run(scene, state0, one_orbit, progress=False),
            "numba one orbit": lambda: nb.run_one(kind, a, b, state0, one_orbit),
            "jb batch 1 core": lambda: jb.run(scene, starts, per_orbit, devices=devices[:1], progress=False),
            "numba batch 1 thread": lambda: nb.run_batch(kind, a, b, starts, per_orbit),
        }
        if len(devices) >= 2:
            contenders["jb batch 2 cores"] = lambda: jb.run(
                scene, starts, per_orbit, devices=devices[:2], progress=False
            )
            contenders["numba batch 2 threads"] = lambda: nb.run_batch_parallel(kind, a, b, starts, per_orbit, 2)
        timings = interleaved(contenders, args.rounds)
        numba.set_num_threads(numba.config.NUMBA_NUM_THREADS)
        for name, timing in timings.items():
            collisions = one_orbit if "one orbit" in name else batch * per_orbit
            cores = 2 if "2" in name else 1
            rate = collisions / timing.median / cores
            out.append((label, name, collisions, timing.median, rate, 1e9 / rate, timing.cores, timing.first))
    return out


def report(args) -> str:
    started = time.perf_counter()
    lines = [
        "# Point particles in Sinai's billiard and the stadium: jaxbill, numba, DynamicalBilliards.jl",
        "",
        f"- python {platform.python_version()}, jax {jax.__version__} ({jax.default_backend()}), "
        f"numba {numba.__version__}, numpy {np.__version__}; {os.cpu_count()} logical CPUs, "
        f"{len(jax.devices())} JAX devices",
        f"- {args.rounds} interleaved rounds, medians; load average at start: {load_average()}",
        "",
        "| table | contender | collisions | median s | collisions/s per core | ns per collision per core "
        "| cores busy | first call s |",
        "|---|---|---|---|---|---|---|---|",
    ]
    for label, name, collisions, median, rate, ns, busy, first in rows(args):
        lines.append(
            f"| {label} | {name} | {collisions} | {median:.4f} | {rate:.3g} | {ns:.1f} | {busy:.2f} | {first:.1f} |"
        )
    lines += [
        "",
        f"DynamicalBilliards.jl (its repository's benchmark/testscript.jl, the author's machine, 2018): "
        f"`bounce!` of a MagneticParticle in `billiard_sinai()`, {DYNAMICAL_BILLIARDS_NS} ns per collision "
        f"({1e9 / DYNAMICAL_BILLIARDS_NS:.3g} collisions/s on one core).",
        "",
        f"- load average at end: {load_average()}; total {time.perf_counter() - started:.0f} s",
    ]
    return "\n".join(lines) + "\n"


def main(args) -> None:
    text = report(args)
    print(text)
    out = args.out or os.path.join(HERE, "results", f"standard_{datetime.datetime.now():%Y-%m-%dT%H%M}.md")
    with open(out, "w") as handle:
        handle.write(text)


if __name__ == "__main__":
    main(parse_arguments())
