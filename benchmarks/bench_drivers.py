"""The batch drivers against each other on this machine, and every scene on the same engine.

Run:  python benchmarks/bench_drivers.py [--quick] [--rounds N] [--batch B] [--collisions N]

For each scene (the stick in a circle at ell = 1.9 and 1.0, the lens, the
circle, the walls in 2D and 3D, and the stick in an ellipse a = 2, b = 1.4 at
ell = 0.5 with its static and point limits), one JAX device, a batch of
``--batch`` orbits x ``--collisions`` collisions, final states
(``jb.run(..., driver=...)``): the serial driver (one orbit after another),
the lockstep driver (a vmapped loop of whole collisions) and the lane state
machine in one XLA loop, timed in alternation in this one process, medians;
"default" names the driver ``jb.run`` picks for the scene. The root steps per collision come from the
engine's own search (``jaxbill._engine.step``), counted on the first 256 orbits.
This is the evidence behind ``jaxbill._engine.drivers.choose_driver``'s default on a
CPU. The Pallas driver is for GPUs (``bench_gpu.py``); here it would run in
Pallas's interpreter.
"""

from __future__ import annotations

import argparse
import os
import statistics
import time

import jax
import jax.numpy as jnp
import numpy as np

import jaxbill as jb
from jaxbill._engine import step as _step
from jaxbill._engine.drivers import choose_driver

INF = float("inf")


def scenes():
    return {
        "circle rotor ell=1.9": jb.StickInCircle(2.0, 1.9),
        "circle rotor ell=1.0": jb.StickInCircle(2.0, 1.0),
        "lens ell=1.5": jb.StickInCircle(2.0, 1.5, inertia=INF),
        "circle billiard": jb.StickInCircle(2.0, 0.0),
        "walls 2D h=3 ell=1": jb.StickBetweenWalls2D(3.0, 1.0),
        "walls 3D h=3 ell=1": jb.StickBetweenWalls3D(3.0, 1.0),
        "ellipse 2x1.4 ell=0.5": jb.StickInEllipse(2.0, 1.4, 0.5),
        "ellipse static": jb.StickInEllipse(2.0, 1.4, 0.5, inertia=INF),
        "ellipse point": jb.StickInEllipse(2.0, 1.4, 0.0),
        "circle rotor ell=0.5 (for the ellipse)": jb.StickInCircle(2.0, 0.5),
    }


def start_states(scene, count, rng):
    """Valid starts: a few collisions after random states near the middle of the table."""
    if scene.state_size == 12:
        u = rng.normal(size=(count, 3))
        u /= np.linalg.norm(u, axis=1, keepdims=True)
        w = rng.normal(size=(count, 3))
        w -= np.sum(w * u, axis=1, keepdims=True) * u
        if scene.kind == "static":
            w[:] = 0.0
        c = np.stack([np.zeros(count), np.zeros(count), np.full(count, float(scene.h) / 2)], axis=1)
        s = np.concatenate([c, u, rng.normal(size=(count, 3)), w], axis=1)
    else:
        walls = isinstance(scene, jb.StickBetweenWalls2D)
        radius = 0.05 * np.sqrt(rng.uniform(size=count))
        angle = rng.uniform(-np.pi, np.pi, count)
        x, y = radius * np.cos(angle), radius * np.sin(angle) + (float(scene.h) / 2 if walls else 0.0)
        v = rng.normal(size=(count, 2))
        spins = scene.kind == "rotor"
        omega = rng.normal(size=count) if spins else np.zeros(count)
        # Any orientation fits at the middle of every table here (ell below the smallest half-width).
        s = np.stack([x, y, rng.uniform(-np.pi, np.pi, count), v[:, 0], v[:, 1], omega], axis=1)
    return np.asarray(jb.orbit(scene, s, 3, driver="lockstep").state[:, -1])


def root_steps_per_collision(scene, states, collisions):
    if not scene.searches_for_roots:
        return 0.0

    def steps_of_one(state):
        def one(carry, _):
            state, total = carry
            lane = _step.begin_flight(scene, _step.components(state), scene.orbit_constants(_step.components(state)))
            lane = jax.lax.while_loop(
                lambda l: ~l.found & (l.steps < _step.MAX_ROOT_STEPS), lambda l: _step.search_step(scene, l), lane
            )
            collision = _step.end_flight(scene, lane, None)
            return (_step.stacked(collision.state), total + lane.steps), None

        (_, total), _ = jax.lax.scan(one, (state, jnp.int32(0)), length=collisions)
        return total

    return float(jnp.mean(jax.jit(jax.vmap(steps_of_one))(jnp.asarray(states)))) / collisions


def main():
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--quick", action="store_true")
    parser.add_argument("--rounds", type=int, default=None)
    parser.add_argument("--batch", type=int, default=None)
    parser.add_argument("--collisions", type=int, default=None)
    args = parser.parse_args()
    rounds = args.rounds or (3 if args.quick else 7)
    batch = args.batch or (512 if args.quick else 4096)
    n = args.collisions or (50 if args.quick else 200)
    device = jax.devices()[:1]
    rng = np.random.default_rng(3)
    print(f"# Batch drivers: {batch} orbits x {n} collisions, final states, one {jax.default_backend()} device")
    print()
    load = os.getloadavg()[0]
    print(f"jax {jax.__version__}; {rounds} interleaved rounds, medians; load average {load:.2f} at start")
    print()
    drivers = ("serial", "lockstep", "lanes")
    print("| scene | serial coll/s | lockstep coll/s | lanes coll/s | default | root steps / collision |")
    print("|---|---:|---:|---:|---|---:|")
    for label, scene in scenes().items():
        states = start_states(scene, batch, rng)
        runs = {d: (lambda d=d: jb.run(scene, states, n, devices=device, driver=d, progress=False)) for d in drivers}
        for run in runs.values():
            run()
        times = {d: [] for d in runs}
        for _ in range(rounds):
            for d, run in runs.items():
                started = time.perf_counter()
                run()
                times[d].append(time.perf_counter() - started)
        rates = " | ".join(f"{batch * n / statistics.median(times[d]):.3g}" for d in drivers)
        steps = root_steps_per_collision(scene, states[:256], n)
        print(f"| {label} | {rates} | {choose_driver(scene, 'cpu')} | {steps:.2f} |")
    print()
    print(f"load average at end {os.getloadavg()[0]:.2f}")


if __name__ == "__main__":
    main()
