"""Scale: collisions per second over 1 and 2 devices, and peak memory of long runs.

Run:  python benchmarks/bench_scale.py [--quick] [--repeats N]

Prints markdown tables:

1. collisions per second of ``jb.run(scene, states0, n)`` (``record="final"``)
   for a batch of 16384 orbits on 1 and on 2 JAX devices, and the scaling
   efficiency ``rate(2) / (2 rate(1))``. On CPU the two devices are the host's
   cores, split by ``XLA_FLAGS=--xla_force_host_platform_device_count=2``; each
   device count runs in its own subprocess, because the flag must be set before
   JAX starts. On a GPU machine with one GPU only the one-device row is run.
2. peak memory of one static-lens orbit of 1e8 collisions (``--quick``: 1e6)
   and of 1e6 orbits of a few collisions (``--quick``: 1e5), ``record="final"``,
   each in a fresh subprocess: the process's peak resident set (``ru_maxrss``)
   before and after the run, the peak of host allocations traced by
   ``tracemalloc`` during it (numpy arrays included), and the device's peak
   bytes in use where the backend reports it (GPUs; ``n/a`` on CPU).
3. root-finder steps per collision of the spinning stick (how long a vmapped
   lane waits for its slowest neighbour), from ``jaxbill._scenes.circle.scene``'s
   search run on the states of real orbits.

Timings are medians of ``--repeats`` runs after a compiling one; the machine may
be shared, so the load average is printed at the start and the end. Nothing
here asserts on timings.
"""

from __future__ import annotations

import argparse
import json
import os
import platform
import resource
import statistics
import subprocess
import sys
import time
import tracemalloc

import numpy as np

HERE = os.path.dirname(os.path.abspath(__file__))
BATCH = 16384
SCENES = {  # label -> (ell, inertia); R = 2, mass 1
    "rotor ell=1.9": (1.9, None),
    "lens ell=1.9": (1.9, float("inf")),
}
TARGETS = {"rotor ell=1.9": 1e7, "lens ell=1.9": 5e7}  # collisions/s, 16384 orbits
TARGET_EFFICIENCY = 0.8


def _states(ell, inertia, count, seed=0):
    sys.path.insert(0, HERE)
    from bench_collisions import random_states

    return random_states(2.0, ell, inertia, count, seed)


def _scene(jb, ell, inertia):
    return jb.StickInCircle(R=2.0, ell=ell, inertia=inertia)


# -- workers (each runs in its own subprocess) -------------------------------------


def worker_throughput(args) -> dict:
    import jax

    import jaxbill as jb

    ell, inertia = SCENES[args.scene]
    scene = _scene(jb, ell, inertia)
    states0 = _states(ell, inertia, args.batch)
    started = time.perf_counter()
    jb_run(jb, scene, states0, args.collisions)  # compiles
    first = time.perf_counter() - started
    runs, cores = [], []
    for _ in range(args.repeats):
        cpu, started = _cpu_seconds(), time.perf_counter()
        jb_run(jb, scene, states0, args.collisions)
        runs.append(time.perf_counter() - started)
        cores.append((_cpu_seconds() - cpu) / runs[-1])
    median = statistics.median(runs)
    return {
        "devices": len(jax.devices()),
        "backend": jax.default_backend(),
        "runs": runs,
        "median": median,
        "cores": statistics.median(cores),
        "compile": first - median,
        "rate": args.batch * args.collisions / median,
    }


def _cpu_seconds() -> float:
    usage = resource.getrusage(resource.RUSAGE_SELF)
    return usage.ru_utime + usage.ru_stime


def jb_run(jb, scene, states0, n):
    run = getattr(jb, "run", None)
    if run is None:  # until jaxbill/__init__.py exports it
        from jaxbill._runs.streaming import run
    return run(scene, states0, n, progress=False)


def _device_peak_bytes(jax):
    stats = jax.devices()[0].memory_stats()
    return None if not stats else stats.get("peak_bytes_in_use")


def _peak_rss() -> int:
    return resource.getrusage(resource.RUSAGE_SELF).ru_maxrss * 1024  # Linux reports kB


def worker_memory(args) -> dict:
    import jax

    import jaxbill as jb

    imported = _peak_rss()
    ell, inertia = SCENES["lens ell=1.9"]
    scene = _scene(jb, ell, inertia)
    states0 = _states(ell, inertia, args.batch)
    if args.batch == 1:
        states0 = states0[0]
    with_states = _peak_rss()
    # Compile (the same program serves any n) and touch everything once.
    jb_run(jb, scene, states0, min(args.collisions, 1000))
    warm = _peak_rss()
    tracemalloc.start()
    started = time.perf_counter()
    result = jb_run(jb, scene, states0, args.collisions)
    seconds = time.perf_counter() - started
    _, traced_peak = tracemalloc.get_traced_memory()
    tracemalloc.stop()
    return {
        "orbits": args.batch,
        "collisions": args.collisions,
        "seconds": seconds,
        "rate": args.batch * args.collisions / seconds,
        "chunks": result.chunks,
        "rss_imported": imported,
        "rss_states": with_states,
        "rss_warm": warm,
        "rss_peak": _peak_rss(),
        "traced_peak": traced_peak,
        "device_peak": _device_peak_bytes(jax),
        "energy_error": float(np.max(result.max_energy_error)),
        "result_bytes": int(
            sum(
                np.asarray(a).nbytes
                for a in (result.final_state, result.time, result.contact_counts, result.max_energy_error)
            )
        ),
    }


def _run_worker(kind: str, devices: int, timeout: float, **options) -> dict:
    env = dict(os.environ)
    flags = [f for f in env.get("XLA_FLAGS", "").split() if not f.startswith("--xla_force_host_platform_device_count")]
    if devices > 1:
        flags.append(f"--xla_force_host_platform_device_count={devices}")
    env["XLA_FLAGS"] = " ".join(flags)
    command = [sys.executable, os.path.abspath(__file__), "--worker", kind]
    for key, value in options.items():
        command += [f"--{key.replace('_', '-')}", str(value)]
    proc = subprocess.run(command, env=env, capture_output=True, text=True, timeout=timeout)
    if proc.returncode != 0:
        raise RuntimeError(f"worker {kind} failed:\n{proc.stderr[-3000:]}")
    line = next(ln for ln in proc.stdout.splitlines() if ln.startswith("RESULT"))
    return json.loads(line[len("RESULT") :])


# -- how many cores the machine gives us now -----------------------------------------

_CAPACITY_PROBE = """
import resource, threading, time
import numpy as np
a = np.random.default_rng(0).random((500, 500))
def busy():
    for _ in range(40):
        a @ a
threads = [threading.Thread(target=busy) for _ in range({threads})]
usage = resource.getrusage(resource.RUSAGE_SELF)
cpu, started = usage.ru_utime + usage.ru_stime, time.perf_counter()
[t.start() for t in threads]
[t.join() for t in threads]
usage = resource.getrusage(resource.RUSAGE_SELF)
print((usage.ru_utime + usage.ru_stime - cpu) / (time.perf_counter() - started))
"""


def cores_available(threads: int) -> float:
    """CPU time / wall time of ``threads`` busy threads (numpy matrix products, one
    BLAS thread each): the cores a process with that many threads gets right now."""
    env = dict(os.environ, OPENBLAS_NUM_THREADS="1", OMP_NUM_THREADS="1", MKL_NUM_THREADS="1")
    proc = subprocess.run(
        [sys.executable, "-c", _CAPACITY_PROBE.format(threads=threads)],
        env=env,
        capture_output=True,
        text=True,
        timeout=600,
    )
    return float(proc.stdout.strip())


# -- root-finder steps --------------------------------------------------------------


def root_steps(ell, orbits, collisions) -> np.ndarray:
    """Steps of the first-root search for each collision of ``orbits`` orbits."""
    import jax
    import jax.numpy as jnp

    import jaxbill as jb
    from jaxbill._engine.first_root import first_root
    from jaxbill._engine.step import MAX_ROOT_STEPS, components

    scene = _scene(jb, ell, None)
    states0 = jnp.asarray(_states(ell, None, orbits, seed=1))
    orbit = jb.orbit(scene, states0, collisions)
    before = jnp.concatenate([states0[:, None], orbit.state[:, :-1]], axis=1).reshape(-1, 6)

    def steps_of(state):
        profile, bounds = scene.root_search(components(state))
        return first_root(lambda t: scene.gaps_along_flight(profile, t), bounds, MAX_ROOT_STEPS)[2]

    return np.asarray(jax.jit(jax.vmap(steps_of))(before))


# -- report ---------------------------------------------------------------------------


def _mb(x):
    return "n/a" if x is None else f"{x / 2**20:.0f} MB"


def _bytes(x):
    return f"{x} B" if x < 10_000 else (f"{x / 1024:.0f} kB" if x < 10_000_000 else _mb(x))


def report_throughput(args, quick, device_counts, collisions):
    # Rounds alternate the device counts, so that a change in the machine's load
    # during the benchmark affects both alike.
    rounds = 1 if quick else 3
    throughput = {}
    for label in SCENES:
        for _ in range(rounds):
            for devices in device_counts:
                r = _run_worker(
                    "throughput",
                    devices,
                    1200,
                    scene=label,
                    batch=BATCH,
                    collisions=collisions[label],
                    repeats=args.repeats,
                )
                print(f"  {label}, {devices} device(s): {r['rate']:.3g} collisions/s", file=sys.stderr, flush=True)
                merged = throughput.setdefault((label, devices), {"runs": [], "cores": [], "compile": []})
                merged["runs"] += r["runs"]
                merged["cores"].append(r["cores"])
                merged["compile"].append(r["compile"])
        for devices in device_counts:
            merged = throughput[label, devices]
            merged["median"] = statistics.median(merged["runs"])
            merged["rate"] = BATCH * collisions[label] / merged["median"]

    probe = [cores_available(2) for _ in range(3)]
    print(f"## Throughput: jb.run, record='final', {BATCH} orbits (float64)")
    print()
    print(
        f"Cores the machine gives a process with 2 busy threads (numpy, one BLAS thread each), "
        f"probed 3 times after the runs: {', '.join(f'{p:.2f}' for p in probe)}. "
        "Scaling to 2 devices cannot exceed what this allows."
    )
    print()
    print(
        f"collisions per run = {BATCH} x n; median of {rounds} x {args.repeats} runs, each set after a "
        f"compiling one, in {rounds} round(s) alternating the device counts. "
        "cores used = the process's CPU time / wall time during a run (the cores it actually got: "
        "on a shared machine fewer than its devices)."
    )
    print()
    print("| scene | n | devices | median (s) | collisions/s | efficiency | cores used | target | compile (s) |")
    print("|---|---:|---:|---:|---:|---:|---:|---:|---:|")
    for label in SCENES:
        one = throughput[label, 1]["rate"]
        for devices in device_counts:
            r = throughput[label, devices]
            efficiency = r["rate"] / (devices * one)
            target = f">= {TARGETS[label]:.0e}" if devices == 1 else f">= {TARGET_EFFICIENCY:.0%} eff."
            print(
                f"| {label} | {collisions[label]} | {devices} | {r['median']:.3f} | **{r['rate']:.3g}** "
                f"| {efficiency:.0%} | {statistics.median(r['cores']):.2f} | {target} "
                f"| {statistics.median(r['compile']):.2f} |"
            )
    print()


def report_memory(quick):
    single_n = 1_000_000 if quick else 100_000_000
    many = 100_000 if quick else 1_000_000
    memory = [
        _run_worker("memory", 1, 3600, batch=1, collisions=single_n),
        _run_worker("memory", 1, 1200, batch=many, collisions=4),
    ]
    print("## Peak memory: jb.run, record='final', static lens ell = 1.9 (one device)")
    print()
    print(
        "Peak resident set of the process (ru_maxrss, a high-water mark) after importing jax and jaxbill, "
        "after drawing the initial states (numpy, this benchmark's own cost), "
        "after a compiling warm-up run (n <= 1000), and after the measured run; traced = peak of host "
        "allocations during the measured run (tracemalloc, numpy arrays included); result = the "
        "returned final states and statistics; energy = the largest max |E - E0| / E0 over the orbits."
    )
    print()
    print(
        "| orbits | collisions per orbit | chunks | time (s) | collisions/s | RSS imported | RSS with states "
        "| RSS warm | RSS peak | traced host peak | device peak | result | energy |"
    )
    print("|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|")
    for m in memory:
        print(
            f"| {m['orbits']} | {m['collisions']:.0e} | {m['chunks']} | {m['seconds']:.1f} | {m['rate']:.3g} "
            f"| {_mb(m['rss_imported'])} | {_mb(m['rss_states'])} | {_mb(m['rss_warm'])} | {_mb(m['rss_peak'])} "
            f"| {_bytes(m['traced_peak'])} | {_mb(m['device_peak'])} | {_bytes(m['result_bytes'])} "
            f"| {m['energy_error']:.1e} |"
        )
    print()


def report_root_steps(quick):
    print("## Root-finder steps per collision, spinning stick (R = 2, I = M ell^2)")
    print()
    orbits, per_orbit = (64, 50) if quick else (256, 200)
    print(f"{orbits} orbits x {per_orbit} collisions from random states.")
    print()
    print("| ell | mean | median | p90 | p99 | max |")
    print("|---:|---:|---:|---:|---:|---:|")
    for ell in (1.9, 1.0):
        steps = root_steps(ell, orbits, per_orbit)
        print(
            f"| {ell} | {steps.mean():.2f} | {np.median(steps):.0f} | {np.percentile(steps, 90):.0f} "
            f"| {np.percentile(steps, 99):.0f} | {steps.max()} |"
        )
    print()


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--quick", action="store_true", help="small sizes (about 1 min)")
    ap.add_argument("--repeats", type=int, default=None, help="timed runs per configuration (default 5, quick 2)")
    ap.add_argument(
        "--part",
        choices=("all", "throughput", "memory", "steps"),
        default="all",
        help="run one part of the report only",
    )
    ap.add_argument("--worker", choices=("throughput", "memory"), help=argparse.SUPPRESS)
    ap.add_argument("--scene", default="lens ell=1.9", help=argparse.SUPPRESS)
    ap.add_argument("--batch", type=int, default=BATCH, help=argparse.SUPPRESS)
    ap.add_argument("--collisions", type=int, default=100, help=argparse.SUPPRESS)
    args = ap.parse_args(argv)
    args.repeats = max(1, args.repeats or (2 if args.quick else 5))
    if args.worker:
        out = worker_throughput(args) if args.worker == "throughput" else worker_memory(args)
        print("RESULT" + json.dumps(out))
        return

    import jax

    import jaxbill  # noqa: F401  (float64)

    quick = args.quick
    backend = jax.default_backend()
    device_counts = (1, 2) if backend == "cpu" else (1,)
    collisions = {"rotor ell=1.9": 10 if quick else 60, "lens ell=1.9": 100 if quick else 1000}
    load0 = os.getloadavg()
    print("# jaxbill scale benchmark" + (" (--quick)" if quick else ""))
    print()
    print(
        f"- python {platform.python_version()}, jax {jax.__version__}, backend {backend}, "
        f"{os.cpu_count()} CPUs, devices {[str(d) for d in jax.devices()]}"
    )
    print(f"- load average at start: {load0[0]:.2f} {load0[1]:.2f} {load0[2]:.2f}")
    print()
    sys.stdout.flush()

    if args.part in ("all", "throughput"):
        report_throughput(args, quick, device_counts, collisions)
    if args.part in ("all", "memory"):
        report_memory(quick)
    if args.part in ("all", "steps"):
        report_root_steps(quick)
    load1 = os.getloadavg()
    print(f"Load average at end: {load1[0]:.2f} {load1[1]:.2f} {load1[2]:.2f}.")


if __name__ == "__main__":
    main()
