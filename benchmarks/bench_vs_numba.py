"""jaxbill against plain numba loops of its method (``numba_baseline.py``), on CPU.

Run:  python benchmarks/bench_vs_numba.py [--quick] [--rounds N] [--cpu-devices D] [--results PATH]
                                           [--orbit-collisions N] [--batch B] [--batch-collisions N]

Prints a markdown report, everything measured in this one process, R = 2,
float64, default inertia ``I = M ell^2``, and writes its figures, with the
machine, the date and the versions, to ``benchmarks/results/vs_numba_<UTC date
and time>.json`` (``--results``), the files the published figures come from.

Two numba loops: the loop a user would write ("user loop", the certified
safe-step method with the flight's curvature bounds alone), and, for the
spinning stick in a circle, the same method as jaxbill's ("same method":
jaxbill's sharper steps, each gap's own curvature and a third-derivative
bound; ``numba_baseline.ROTOR_SHARPER``). For every other scene the two are
one loop, jaxbill's method.

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
4. root steps per collision of each numba loop and of jaxbill, counted from
   the same states.

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
import datetime
import importlib.metadata
import json
import os
import platform
import subprocess
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
    parser.add_argument(
        "--results",
        default=None,
        metavar="PATH",
        help="JSON file for the figures, machine, date and versions (default "
        "benchmarks/results/vs_numba_<UTC date and time>.json; 'none': do not write one)",
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
from interleaved import interleaved, jaxbill_source, load_average  # noqa: E402

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


def sharper_params(params):
    """The numba loop with jaxbill's sharper steps for the same scene, or ``None`` where the loop a user
    would write is already jaxbill's method (every scene but the spinning stick in a circle)."""
    if int(params[0]) != baseline.ROTOR:
        return None
    sharper = params.copy()
    sharper[0] = baseline.ROTOR_SHARPER
    return sharper


def _timing(timing, collisions):
    return {
        "median_s": timing.median,
        "rate": collisions / timing.median,
        "cores": timing.cores,
        "first_s": timing.first,
        "round_s": list(timing.round_seconds),
    }


def single_orbits(args, results):
    print(f"## One orbit of {args.orbit_collisions} collisions, every state recorded")
    print()
    print(
        "numba's user loop is the method with the flight's curvature bounds alone; numba's same method adds "
        "jaxbill's sharper steps (the spinning stick only; elsewhere the two are one loop). Ratios are "
        "jaxbill's time over numba's."
    )
    print()
    print(
        "| scene | jb.orbit s | numba user loop s | numba same method s | ratio to user loop | ratio to same method "
        "| jb.orbit coll/s | numba user loop coll/s | numba same method coll/s | cores used (jb, numba) "
        "| root steps / collision (user loop, same method, jaxbill) |"
    )
    print("|---|---|---|---|---|---|---|---|---|---|---|")
    n = args.orbit_collisions
    for label, params in SCENES.items():
        scene = baseline.jaxbill_scene(params)
        state0 = baseline.random_states(params, 1, seed=7)[0]
        device_state0 = jnp.asarray(state0)
        sharper = sharper_params(params)
        numba_orbits = {}  # each loop's last call's (t, contact, states, root_steps)

        def run_jaxbill():
            jax.block_until_ready(jb.orbit(scene, device_state0, n))

        def run_numba(name, loop_params):
            def run():
                numba_orbits[name] = baseline.orbit(loop_params, state0, n)

            return run

        contenders = {"jaxbill": run_jaxbill, "numba": run_numba("numba", params)}
        if sharper is not None:
            contenders["numba_same"] = run_numba("numba_same", sharper)
        times = interleaved(contenders, args.rounds)
        same = "numba_same" if sharper is not None else "numba"
        # Every count from the same states, those of the user loop's orbit's first collisions.
        counted = min(n, 20_000)
        _, _, numba_states, _ = numba_orbits["numba"]
        before = np.concatenate([state0[None], numba_states[: counted - 1]])
        steps = {
            "numba": float(np.mean(baseline.collision_map(params, before)[3])),
            "numba_same": float(np.mean(baseline.collision_map(sharper if sharper is not None else params, before)[3])),
            "jaxbill": float(np.mean(baseline.jaxbill_root_steps(params, before))),
        }
        t_jb, t_nb, t_same = times["jaxbill"].median, times["numba"].median, times[same].median
        print(
            f"| {label} | {t_jb:.3f} | {t_nb:.3f} | {t_same:.3f} | {t_jb / t_nb:.2f} | {t_jb / t_same:.2f} "
            f"| {rate(n, t_jb)} | {rate(n, t_nb)} | {rate(n, t_same)} "
            f"| {times['jaxbill'].cores:.1f}, {times['numba'].cores:.1f} "
            f"| {steps['numba']:.2f}, {steps['numba_same']:.2f}, {steps['jaxbill']:.2f} |"
        )
        results.append(
            {
                "table": "one orbit",
                "scene": label,
                "collisions": n,
                "jaxbill": _timing(times["jaxbill"], n),
                "numba user loop": _timing(times["numba"], n),
                "numba same method": _timing(times[same], n),
                "ratio to user loop": t_jb / t_nb,
                "ratio to same method": t_jb / t_same,
                "root steps per collision": {
                    "numba user loop": steps["numba"],
                    "numba same method": steps["numba_same"],
                    "jaxbill": steps["jaxbill"],
                    "counted collisions": counted,
                },
            }
        )
    print()


def batches(args, scenes, results):
    devices = jax.devices()
    two = len(devices) >= 2
    batch, n = args.batch, args.batch_collisions
    collisions = batch * n
    print(f"## A batch of {batch} orbits x {n} collisions, final states")
    print()
    print(
        "One core: `jb.run` on one JAX device, `jb.orbit` (batched; records every state) and numba `run_batch`. "
        "Two cores: `jb.run` over two JAX devices and numba `run_batch_parallel` with two threads. "
        "Times in seconds (collisions/s in brackets); ratios are jaxbill's time over numba's, "
        "numba's user loop first, then its same method (the spinning stick's sharper steps)."
    )
    print()
    print(
        "| scene | jb.run 1 core | jb.orbit 1 core | numba user loop 1 core | numba same method 1 core "
        "| ratio jb.run/numba (user, same) | ratio jb.orbit/numba (user, same) "
        "| jb.run 2 cores | numba user loop 2 cores | numba same method 2 cores | ratio 2 cores (user, same) "
        "| speed-up 1 -> 2 cores (jb.run, numba user, numba same) | cores used (jb.run 1/2, numba 1/2) "
        "| root steps / collision (user loop, same method) |"
    )
    print("|---|---|---|---|---|---|---|---|---|---|---|---|---|---|")
    for label in scenes:
        params = SCENES[label]
        sharper = sharper_params(params)
        scene = baseline.jaxbill_scene(params)
        states0 = baseline.random_states(params, batch, seed=11)
        steps = {}

        def run_numba(name, loop_params):
            def run():
                steps[name] = baseline.run_batch(loop_params, states0, n)[3]

            return run

        contenders = {
            "run1": lambda: jb.run(scene, states0, n, devices=devices[:1], progress=False),
            "orbit1": lambda: jax.block_until_ready(jb.orbit_sharded(scene, states0, n, devices=devices[:1])),
            "numba1": run_numba("numba1", params),
        }
        if sharper is not None:
            contenders["numba1_same"] = run_numba("numba1_same", sharper)
        if two:
            contenders["run2"] = lambda: jb.run(scene, states0, n, devices=devices[:2], progress=False)
            contenders["numba2"] = lambda: baseline.run_batch_parallel(params, states0, n, threads=2)
            if sharper is not None:
                contenders["numba2_same"] = lambda: baseline.run_batch_parallel(sharper, states0, n, threads=2)
        timings = interleaved(contenders, args.rounds)
        numba.set_num_threads(numba.config.NUMBA_NUM_THREADS)
        for name in ("numba1", "numba2"):  # one loop serves as both where there is no second one
            if name in timings and name + "_same" not in timings:
                timings[name + "_same"] = timings[name]
        if "numba1_same" not in steps:
            steps["numba1_same"] = steps["numba1"]
        times = {name: t.median for name, t in timings.items()}

        def cell(name):
            return f"{times[name]:.3f} ({rate(collisions, times[name])})" if name in times else "n/a"

        def ratios(a, b):
            if a not in times or b not in times:
                return "n/a"
            return f"{times[a] / times[b]:.2f}, {times[a] / times[b + '_same']:.2f}"

        def cores(name):
            return f"{timings[name].cores:.1f}" if name in timings else "n/a"

        speedups = (
            f"{times['run1'] / times['run2']:.2f}, {times['numba1'] / times['numba2']:.2f}, "
            f"{times['numba1_same'] / times['numba2_same']:.2f}"
            if two
            else "n/a"
        )
        user_steps = steps["numba1"].sum() / collisions
        same_steps = steps["numba1_same"].sum() / collisions
        print(
            f"| {label} | {cell('run1')} | {cell('orbit1')} | {cell('numba1')} | {cell('numba1_same')} "
            f"| {ratios('run1', 'numba1')} | {ratios('orbit1', 'numba1')} | {cell('run2')} | {cell('numba2')} "
            f"| {cell('numba2_same')} | {ratios('run2', 'numba2')} | {speedups} "
            f"| {cores('run1')}/{cores('run2')}, {cores('numba1')}/{cores('numba2')} "
            f"| {user_steps:.2f}, {same_steps:.2f} |"
        )
        row = {
            "table": "batch",
            "scene": label,
            "orbits": batch,
            "collisions per orbit": n,
            "root steps per collision": {"numba user loop": user_steps, "numba same method": same_steps},
        }
        names = {
            "run1": "jb.run 1 core",
            "orbit1": "jb.orbit 1 core",
            "numba1": "numba user loop 1 core",
            "numba1_same": "numba same method 1 core",
            "run2": "jb.run 2 cores",
            "numba2": "numba user loop 2 cores",
            "numba2_same": "numba same method 2 cores",
        }
        for name, key in names.items():
            if name in timings:
                row[key] = _timing(timings[name], collisions)
        for jaxbill_name, numba_name, key in (
            ("run1", "numba1", "jb.run 1 core"),
            ("orbit1", "numba1", "jb.orbit 1 core"),
            ("run2", "numba2", "jb.run 2 cores"),
        ):
            if jaxbill_name in times and numba_name in times:
                row[f"ratio {key} to user loop"] = times[jaxbill_name] / times[numba_name]
                row[f"ratio {key} to same method"] = times[jaxbill_name] / times[numba_name + "_same"]
        if two:
            row["speed-up 1 -> 2 cores"] = {
                "jb.run": times["run1"] / times["run2"],
                "numba user loop": times["numba1"] / times["numba2"],
                "numba same method": times["numba1_same"] / times["numba2_same"],
            }
        results.append(row)
    print()


def machine_description() -> dict:
    """What the figures were measured on: the processor, its cores, the versions of everything timed."""
    processor = platform.processor() or platform.machine()
    try:
        with open("/proc/cpuinfo") as cpuinfo:
            models = [line.split(":", 1)[1].strip() for line in cpuinfo if line.startswith("model name")]
        processor = models[0] if models else processor
    except OSError:
        pass
    # The commit of the jaxbill that was imported and timed (not necessarily this script's checkout).
    package = os.path.dirname(os.path.abspath(jb.__file__))
    try:
        commit = subprocess.run(
            ["git", "rev-parse", "--short", "HEAD"], cwd=package, capture_output=True, text=True, check=True
        ).stdout.strip()
        dirty = subprocess.run(
            ["git", "status", "--porcelain", "--", "."], cwd=package, capture_output=True, text=True
        ).stdout
        commit += " (jaxbill/ with uncommitted changes)" if dirty.strip() else ""
    except (OSError, subprocess.CalledProcessError):
        commit = "unknown"
    return {
        "machine": platform.machine(),
        "processor": processor,
        "logical_cpus": os.cpu_count(),
        "system": platform.platform(),
        "jax_devices": len(jax.devices()),
        "jax_backend": jax.default_backend(),
        "versions": {
            "python": platform.python_version(),
            "jax": jax.__version__,
            "jaxlib": importlib.metadata.version("jaxlib"),
            "jaxbill": jb.__version__,
            "numba": numba.__version__,
            "numpy": np.__version__,
            "jaxbill_commit": commit,
        },
        "jaxbill_from": jaxbill_source(package),
        "numba_threads": numba.config.NUMBA_NUM_THREADS,
        "xla_flags": os.environ.get("XLA_FLAGS", ""),
    }


def main(args):
    started = time.perf_counter()
    when = datetime.datetime.now(datetime.UTC)
    machine = machine_description()
    print("# jaxbill vs plain numba loops: the loop a user would write, and the same method")
    print()
    versions = machine["versions"]
    print(
        f"- python {versions['python']}, jax {versions['jax']} ({machine['jax_backend']}), jaxbill "
        f"{versions['jaxbill']} ({versions['jaxbill_commit']}), numba {versions['numba']} "
        f"({machine['numba_threads']} threads), numpy {versions['numpy']}"
    )
    print(
        f"- machine: {machine['processor']} ({machine['machine']}), {machine['logical_cpus']} logical CPUs; "
        f"len(jax.devices()) = {machine['jax_devices']} (XLA_FLAGS={machine['xla_flags']!r})"
    )
    print(
        f"- sizes: orbit {args.orbit_collisions} collisions; batch {args.batch} x {args.batch_collisions}; "
        f"{args.rounds} interleaved rounds, medians; R = 2, float64, I = M ell^2"
    )
    load_at_start = load_average()
    print(f"- {when:%Y-%m-%d %H:%M} UTC; load average at start: {load_at_start}")
    print()
    rows: list[dict] = []
    single_orbits(args, rows)
    batches(args, QUICK_BATCH_SCENES if args.quick else tuple(SCENES), rows)
    load_at_end = load_average()
    seconds = time.perf_counter() - started
    print(f"- load average at end: {load_at_end}; total {seconds:.0f} s")
    if args.results != "none":
        path = args.results or os.path.join(
            HERE, "results", f"vs_numba_{when:%Y-%m-%dT%H%M}{'_quick' if args.quick else ''}.json"
        )
        report = {
            "benchmark": "bench_vs_numba.py",
            "date_utc": when.isoformat(timespec="seconds"),
            "quick": args.quick,
            "sizes": {
                "orbit_collisions": args.orbit_collisions,
                "batch": args.batch,
                "batch_collisions": args.batch_collisions,
                "rounds": args.rounds,
            },
            **machine,
            "load_average": {"start": load_at_start, "end": load_at_end},
            "total_s": seconds,
            "rows": rows,
        }
        with open(path, "w") as f:
            json.dump(report, f, indent=1)
            f.write("\n")
        print(f"- wrote {path}")


if __name__ == "__main__":
    main(ARGS)
