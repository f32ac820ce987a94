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
  collision, ``lyapunov_spectrum(..., paired=False)`` on the batch,
* ``spectrum, paired``: the same spectrum from k / 2 vectors and their
  pairing partners, ``lyapunov_spectrum(..., paired=True)``: what
  ``lyapunov_spectrum`` runs by default for these scenes,

and a second table, the chaos indicators a user calls, for every kind of scene
(the spinning stick, the lens, the stick between walls, the stick in an ellipse,
a triangle in a stadium), on ``--indicator-batch`` orbits (2048) of
``--indicator-collisions`` collisions (500) for every contender: collisions per
second of ``jb.run`` (final states, the plain rate) beside ``jb.fli``, ``jb.fli_map`` (the same starts as a map),
``jb.megno`` and ``jb.lyapunov_spectrum`` (its default, counted per tangent
vector it carries), each as a ratio to the plain rate;

with the compile time (first call minus a steady run) apart ("cached" when a
scene of the same kind compiled it already) and the steady rate the median of
several rounds that alternate the four runs. Nothing asserts on timings.
Writes the figures, with the machine, the date and the versions, to
``benchmarks/results/tangent_<UTC date and time>.json`` (``--results``).
"""

from __future__ import annotations

import argparse
import datetime
import json
import math
import os
import platform

from interleaved import interleaved, jaxbill_source  # this script's folder, on sys.path when run

SCENES = [
    ("R=2 ell=1.9 I=M ell^2", 2.0, 1.9, None),
    ("R=2 ell=1.0 I=M ell^2", 2.0, 1.0, None),
    ("R=2 ell=1.9 I=inf", 2.0, 1.9, math.inf),
    ("R=2 ell=1.0 I=inf", 2.0, 1.0, math.inf),
]


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--quick", action="store_true", help="short runs (smoke test, < 1 min)")
    parser.add_argument("--batch", type=int, default=1024)
    parser.add_argument("--repeats", type=int, default=5, help="interleaved rounds")
    parser.add_argument(
        "--indicator-batch", type=int, default=2048, help="orbits of the indicators' table (both cores)"
    )
    parser.add_argument(
        "--indicator-collisions",
        type=int,
        default=500,
        help="collisions per orbit of the indicators' table, the same for jb.run and every indicator",
    )
    parser.add_argument("--indicators-only", action="store_true", help="only the indicators' table")
    parser.add_argument(
        "--results",
        default=None,
        metavar="PATH",
        help="JSON file for the figures (default benchmarks/results/tangent_<UTC date and time>.json; "
        "'none': do not write one)",
    )
    args = parser.parse_args()
    when = datetime.datetime.now(datetime.UTC)
    started_load = os.getloadavg()

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
        f"runs; steady rate = median of {args.repeats} interleaved rounds\n"
    )
    print(
        "| scene | orbit (coll/s) | FTLE, 1 vector (steps/s) | spectrum, k vectors + QR (steps/s) "
        "| spectrum, paired (steps/s) | rate vs orbit (1 vector / spectrum / paired) "
        "| compile s (orbit / FTLE / spectrum / paired) |"
    )
    print("|---|---|---|---|---|---|---|")
    rows = []
    for label, R, ell, inertia in [] if args.indicators_only else SCENES:
        scene = jb.StickInCircle(R=R, ell=ell, inertia=inertia)
        states, _ = sample_energy_shell(scene, args.batch, energy=0.5, seed=0)
        states = jnp.asarray(states)
        runs = {
            "orbit": lambda: jb.orbit(scene, states, n_plain).state,
            "ftle": lambda: finite_time_lyapunov(scene, states, n_tangent).per_time,
            "spectrum": lambda: lyapunov_spectrum(scene, states, n_tangent, paired=False).exponents,
            "paired": lambda: lyapunov_spectrum(scene, states, n_tangent, paired=True).exponents,
        }
        timings = interleaved(
            {name: lambda run=run: jax.block_until_ready(run()) for name, run in runs.items()}, args.repeats
        )
        # compile = first call minus a steady one
        (c_orbit, t_orbit), (c_ftle, t_ftle), (c_spec, t_spec), (c_pair, t_pair) = (
            (t.first - t.median, t.median) for t in timings.values()
        )
        r_orbit = args.batch * n_plain / t_orbit
        r_ftle, r_spec, r_pair = (args.batch * n_tangent / t for t in (t_ftle, t_spec, t_pair))
        compile_s = " / ".join(f"{c:.1f}" if c > 0.05 else "cached" for c in (c_orbit, c_ftle, c_spec, c_pair))
        ratios = " / ".join(f"{r / r_orbit:.2f}" for r in (r_ftle, r_spec, r_pair))
        print(f"| {label} | {r_orbit:.3g} | {r_ftle:.3g} | {r_spec:.3g} | {r_pair:.3g} | {ratios} | {compile_s} |")
        rows.append(
            {
                "scene": label,
                "orbit_rate": r_orbit,
                "ftle_rate": r_ftle,
                "spectrum_rate": r_spec,
                "paired_rate": r_pair,
                "ftle_over_orbit": r_ftle / r_orbit,
                "spectrum_over_orbit": r_spec / r_orbit,
                "paired_over_orbit": r_pair / r_orbit,
                "paired_over_spectrum": r_pair / r_spec,
            }
        )
    indicator_rows = indicators_beside_run(jb, jnp, args)
    if args.results != "none":
        path = args.results or os.path.join(
            os.path.dirname(os.path.abspath(__file__)),
            "results",
            f"tangent_{when:%Y-%m-%dT%H%M}{'_quick' if args.quick else ''}.json",
        )
        report = {
            "benchmark": "bench_tangent.py",
            "date_utc": when.isoformat(timespec="seconds"),
            "quick": args.quick,
            "batch": args.batch,
            "collisions": {"orbit": n_plain, "tangent": n_tangent},
            "rounds": args.repeats,
            "machine": platform.machine(),
            "processor": platform.processor() or platform.machine(),
            "logical_cpus": os.cpu_count(),
            "jax_devices": len(jax.devices()),
            "versions": {"python": platform.python_version(), "jax": jax.__version__, "jaxbill": jb.__version__},
            "jaxbill_from": jaxbill_source(os.path.dirname(os.path.abspath(jb.__file__))),
            "load_average": {"start": list(started_load), "end": list(os.getloadavg())},
            "rows": rows,
            "indicator_rows": indicator_rows,
        }
        with open(path, "w") as f:
            json.dump(report, f, indent=1)
            f.write("\n")
        print(f"\nwrote {path}")


def indicator_scenes(jb):
    return {
        "spinning stick, ell=1.9": jb.StickInCircle(2.0, 1.9),
        "spinning stick, ell=1.0": jb.StickInCircle(2.0, 1.0),
        "static lens, ell=1.5": jb.StickInCircle(2.0, 1.5, inertia=math.inf),
        "stick between walls, h=3 ell=1": jb.StickBetweenWalls2D(3.0, 1.0),
        "stick in an ellipse 2 x 1.4, ell=0.5": jb.StickInEllipse(2.0, 1.4, 0.5),
        "triangle in a stadium": jb.BodyInTable(
            jb.PolygonBody([(0.3, 0.0), (-0.15, 0.26), (-0.15, -0.26)]), jb.Stadium(1.0, 1.0)
        ),
    }


def indicators_beside_run(jb, jnp, args):
    """The indicators' collisions per second beside ``jb.run``'s, one scene after another, interleaved, the
    same orbits and collisions for each (a call's fixed cost then weighs alike)."""
    import jax

    batch, n = (64, 50) if args.quick else (args.indicator_batch, args.indicator_collisions)
    print(f"\nThe indicators beside jb.run: {batch} orbits x {n} collisions each, both cores")
    print(
        "\n| scene | jb.run (coll/s) | fli | fli_map | megno | spectrum, per vector "
        "| ratios to jb.run (fli / fli_map / megno / spectrum per vector) |"
    )
    print("|---|---|---|---|---|---|---|")
    rows = []
    for label, scene in indicator_scenes(jb).items():
        states = jnp.asarray(jb.sample_energy_shell(scene, batch, energy=0.5, seed=0)[0])
        vectors = int(jax.block_until_ready(jb.lyapunov_spectrum(scene, states[0], 2).exponents).shape[-1])
        paired = bool(jb.lyapunov_spectrum(scene, states[0], 2).paired)
        carried = vectors // 2 if paired else vectors
        runs = {
            "run": lambda: jb.run(scene, states, n, progress=False).final_state,
            "fli": lambda: jb.fli(scene, states, n, n_history=1).value,
            "fli_map": lambda: jb.fli_map(scene, states, n),
            "megno": lambda: jb.megno(scene, states, n, n_history=1).value,
            "spectrum": lambda: jb.lyapunov_spectrum(scene, states, n, n_history=1).exponents,
        }
        timings = interleaved(
            {name: lambda run=run: jax.block_until_ready(run()) for name, run in runs.items()}, args.repeats
        )
        rate = {name: batch * n / t.median for name, t in timings.items()}
        rate["spectrum"] *= carried  # tangent vectors carried, each a collision's worth of tangent work
        ratios = {name: rate[name] / rate["run"] for name in runs if name != "run"}
        print(
            f"| {label} | {rate['run']:.3g} | {rate['fli']:.3g} | {rate['fli_map']:.3g} | {rate['megno']:.3g} "
            f"| {rate['spectrum']:.3g} ({carried} vectors) | " + " / ".join(f"{r:.2f}" for r in ratios.values()) + " |",
            flush=True,
        )
        rows.append(
            {
                "scene": label,
                "orbits": batch,
                "collisions": n,
                "vectors_carried": carried,
                "rates": rate,
                "ratio_to_run": ratios,
            }
        )
    return rows


if __name__ == "__main__":
    main()
