"""How long a click in the section explorer takes, for every scene.

Run:  python benchmarks/bench_explorer.py [--rounds N] [--results PATH]

For each scene ``jaxbill explore`` opens by default (the stick in a circle at
ell = 1.2, the static lens, the circle billiard, the stick in an ellipse
a = 2, b = 1.4, ell = 0.5, the sticks between walls in 2D and 3D), the
explorer with its defaults (a survey of 24 orbits x 1000 collisions, clicks of
4000 collisions in chunks of 500) under Agg; then ``--rounds`` rounds in
which each scene's explorer is clicked once, in turn (``interleaved.py``), at
the first of ``jaxbill._explorer.sample_clicks``'s points. A click is the
whole callback: the start state, the orbit chunk by chunk, its section points
and the configuration panel (no screen drawing under Agg). Prints a markdown
table (median and slowest click, collisions per second) and writes it, with
the machine, the date and the versions, to
``benchmarks/results/explorer_<UTC date and time>.json``.

The tests check what a click computes and that it compiles nothing
(``tests/test_explorer.py``); only this file times it.
"""

from __future__ import annotations

import argparse
import datetime
import json
import os
import platform
import sys
import time

import matplotlib

matplotlib.use("Agg")

import jax

import jaxbill as jb
from jaxbill._explorer import sample_clicks

HERE = os.path.dirname(os.path.abspath(__file__))
sys.path.insert(0, HERE)
from interleaved import interleaved, jaxbill_source, load_average  # noqa: E402

INF = float("inf")


def scenes():
    return {
        "circle rotor ell=1.2": jb.StickInCircle(2.0, 1.2),
        "lens ell=1.5": jb.StickInCircle(2.0, 1.5, inertia=INF),
        "circle billiard": jb.StickInCircle(2.0, 0.0),
        "ellipse 2x1.4 ell=0.5": jb.StickInEllipse(2.0, 1.4, 0.5),
        "walls 2D h=3 ell=1": jb.StickBetweenWalls2D(3.0, 1.0),
        "walls 3D h=3 ell=1": jb.StickBetweenWalls3D(3.0, 1.0),
    }


def main(argv=None) -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--rounds", type=int, default=9, help="timed clicks per scene (default 9)")
    parser.add_argument(
        "--results",
        default=None,
        metavar="PATH",
        help="JSON file for the figures (default benchmarks/results/explorer_<UTC date and time>.json; "
        "'none': do not write one)",
    )
    args = parser.parse_args(argv)
    when = datetime.datetime.now(datetime.UTC)
    load_at_start = load_average()
    print("# A click in the section explorer")
    print()
    print(
        f"- python {platform.python_version()}, jax {jax.__version__} ({jax.default_backend()}), jaxbill "
        f"{jb.__version__}; {platform.machine()}, {os.cpu_count()} logical CPUs"
    )
    print(f"- {when:%Y-%m-%d %H:%M} UTC; load average at start: {load_at_start}; {args.rounds} interleaved rounds")
    print()
    explorers, opened = {}, {}
    for label, scene in scenes().items():
        started = time.perf_counter()
        explorers[label] = jb.explore(scene)
        opened[label] = time.perf_counter() - started

    def clicker(explorer):
        point = sample_clicks(explorer, 1)[0]
        return lambda: explorer.click(*point)

    timings = interleaved({label: clicker(e) for label, e in explorers.items()}, args.rounds)
    print(
        "| scene | opening s (survey and compilation) | click collisions | median click s | slowest click s "
        "| collisions/s in a click |"
    )
    print("|---|---:|---:|---:|---:|---:|")
    rows = []
    for label, explorer in explorers.items():
        timing, collisions = timings[label], explorer.click_collisions
        print(
            f"| {label} | {opened[label]:.1f} | {collisions} | {timing.median:.3f} | {max(timing.round_seconds):.3f} "
            f"| {collisions / timing.median:.3g} |"
        )
        rows.append(
            {
                "scene": label,
                "opening_s": opened[label],
                "click_collisions": collisions,
                "median_click_s": timing.median,
                "slowest_click_s": max(timing.round_seconds),
                "click_s": list(timing.round_seconds),
                "rate": collisions / timing.median,
            }
        )
        explorer.close()
    load_at_end = load_average()
    print()
    print(f"- load average at end: {load_at_end}")
    if args.results != "none":
        path = args.results or os.path.join(HERE, "results", f"explorer_{when:%Y-%m-%dT%H%M}.json")
        report = {
            "benchmark": "bench_explorer.py",
            "date_utc": when.isoformat(timespec="seconds"),
            "rounds": args.rounds,
            "machine": platform.machine(),
            "logical_cpus": os.cpu_count(),
            "versions": {"python": platform.python_version(), "jax": jax.__version__, "jaxbill": jb.__version__},
            "jaxbill_from": jaxbill_source(os.path.dirname(os.path.abspath(jb.__file__))),
            "load_average": {"start": load_at_start, "end": load_at_end},
            "rows": rows,
        }
        with open(path, "w") as f:
            json.dump(report, f, indent=1)
            f.write("\n")
        print(f"- wrote {path}")


if __name__ == "__main__":
    main()
