"""Tangent-map throughput beside plain collision steps, for a batch of orbits.

Run:  python benchmarks/bench_tangent.py [--quick] [--batch B] [--repeats N]

For each scene, on a batch of B = 1024 seeded random states (float64), prints a
markdown table of steps per second (orbit-collisions per second, summed over the
batch) for

* ``orbit``: plain collision steps, ``jb.orbit(scene, states, n)``; it and the tangent runs
  use every core (one JAX device per core);
* ``FTLE (1 vector)``: one collision plus one tangent vector carried by the
  flow's tangent map (one forward-mode JVP) and renormalised,
  ``finite_time_lyapunov``;
* ``spectrum (k vectors + QR)``: the full Benettin step, k tangent vectors
  (6 for the spinning stick, 4 for the lens) and a QR factorisation at every
  collision, ``lyapunov_spectrum`` on the batch,

with the compile time (first call minus a steady run) apart ("cached" when a
scene of the same kind compiled it already) and the steady rate the median of
several runs. Nothing asserts on timings.
"""

from __future__ import annotations

import argparse
import math
import os
import platform
import statistics
import time

SCENES = [
    ("R=2 ell=1.9 I=M ell^2", 2.0, 1.9, None),
    ("R=2 ell=1.0 I=M ell^2", 2.0, 1.0, None),
    ("R=2 ell=1.9 I=inf", 2.0, 1.9, math.inf),
    ("R=2 ell=1.0 I=inf", 2.0, 1.0, math.inf),
]


def timed(jax, fn, repeats):
    start = time.perf_counter()
    jax.block_until_ready(fn())
    first = time.perf_counter() - start
    runs = []
    for _ in range(repeats):
        start = time.perf_counter()
        jax.block_until_ready(fn())
        runs.append(time.perf_counter() - start)
    steady = statistics.median(runs)
    return first - steady, steady


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--quick", action="store_true", help="short runs (smoke test, < 1 min)")
    parser.add_argument("--batch", type=int, default=1024)
    parser.add_argument("--repeats", type=int, default=3)
    args = parser.parse_args()

    import jax
    import jax.numpy as jnp

    import jaxbill as jb
    from jaxbill._analysis.chaos import finite_time_lyapunov, sample_energy_shell
    from jaxbill._analysis.lyapunov import lyapunov_spectrum

    n_plain, n_tangent = (200, 50) if args.quick else (2000, 400)
    print(
        f"jaxbill {jb.__version__}, jax {jax.__version__} on {jax.devices()[0].platform} "
        f"({platform.processor() or platform.machine()}, {os.cpu_count()} CPUs), float64"
    )
    print(
        f"batch B = {args.batch}; n = {n_plain} collisions per orbit for `orbit`, {n_tangent} for the tangent "
        f"runs; steady rate = median of {args.repeats} runs\n"
    )
    print(
        "| scene | orbit (coll/s) | FTLE, 1 vector (steps/s) | spectrum, k vectors + QR (steps/s) "
        "| cost vs orbit (1 vector / spectrum) | compile s (orbit / FTLE / spectrum) |"
    )
    print("|---|---|---|---|---|---|")
    for label, R, ell, inertia in SCENES:
        scene = jb.StickInCircle(R=R, ell=ell, inertia=inertia)
        states, _ = sample_energy_shell(scene, args.batch, energy=0.5, seed=0)
        states = jnp.asarray(states)
        c_orbit, t_orbit = timed(jax, lambda: jb.orbit(scene, states, n_plain).state, args.repeats)
        c_ftle, t_ftle = timed(jax, lambda: finite_time_lyapunov(scene, states, n_tangent).per_time, args.repeats)
        c_spec, t_spec = timed(jax, lambda: lyapunov_spectrum(scene, states, n_tangent).exponents, args.repeats)
        r_orbit = args.batch * n_plain / t_orbit
        r_ftle = args.batch * n_tangent / t_ftle
        r_spec = args.batch * n_tangent / t_spec
        compile_s = " / ".join(f"{c:.1f}" if c > 0.05 else "cached" for c in (c_orbit, c_ftle, c_spec))
        cost = f"{r_orbit / r_ftle:.1f}x / {r_orbit / r_spec:.1f}x"
        print(f"| {label} | {r_orbit:.3g} | {r_ftle:.3g} | {r_spec:.3g} | {cost} | {compile_s} |")


if __name__ == "__main__":
    main()
