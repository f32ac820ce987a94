"""jaxbill's GPU drivers beside a numba CUDA kernel of the same method (``numba_cuda_baseline.py``).

Run:  python benchmarks/bench_gpu.py [--orbits 10000 100000 1000000] [--collisions 200] [--rounds 5]

Without a GPU it says so and exits 0 (CI never needs one).

On a GPU, float64, R = 2, I = M ell^2, for the stick in a circle at ell = 1.9
and 1.0, the lens (ell = 1.5), the stick between walls (h = 3, ell = 1) and
the stick in an ellipse (a = 2, b = 1.4, ell = 0.5; jaxbill only, the numba
kernel has no ellipse), for each batch size, in this one process:

- the numba CUDA kernel (one thread per orbit, state in registers): final states;
- ``jb.run(..., driver="pallas")``: final states and statistics, one Pallas kernel
  per compiled call (the calls it took in brackets: its chunk grows on short calls);
- ``jb.run(..., driver="lanes")``: the XLA state machine, final states;
- ``jb.run(..., record="states", every=100)`` (the lanes driver: Pallas records no states);
- ``jb.orbit`` of the batch (every state recorded; lanes driver), at the smallest size only;
- for scale, ``jb.run(..., driver="lockstep")`` at the smallest size;
- tangent collisions: ``jaxbill._engine.pallas.pallas_fli`` (one tangent vector carried
  in the kernel, as ``jb.fli_map`` runs on a GPU), against the plain kernel;
- a 1024 x 1024 FLI map of 1000 collisions (``jb.fli_map``) on the lens's section.

The last column checks each row against the numba CUDA kernel from the same
states (``agreement.py``): PASS, or FAIL with what disagreed, and the script then
exits with status 1.

Compile times are printed apart (the first call of each); timings are medians
of ``--rounds`` calls in alternation. Ratios are collisions per second over
the numba kernel's. Root steps per collision come from the numba kernel,
which takes the plain method's steps: for the stick in a circle, more than
jaxbill's sharper steps (``numba_baseline.check_against_jaxbill``).
"""

from __future__ import annotations

import argparse
import os
import statistics
import sys
import time

import jax
import numpy as np

HERE = os.path.dirname(os.path.abspath(__file__))


def gpu_present() -> bool:
    try:
        return any(d.platform == "gpu" for d in jax.devices())
    except RuntimeError:
        return False


def timed(function, rounds):
    """``(compile and first call, median of rounds)`` in seconds; ``(nan, nan)`` with the error printed
    if the call fails (one failing contender must not cost the rest of a GPU lease)."""
    try:
        return _timed(function, rounds)
    except Exception as error:  # reported, and the table goes on
        print(f"<!-- failed: {type(error).__name__}: {str(error)[:400]} -->", flush=True)
        return float("nan"), float("nan")


def _timed(function, rounds):
    started = time.perf_counter()
    function()
    compile_and_first = time.perf_counter() - started
    times = []
    for _ in range(rounds):
        started = time.perf_counter()
        function()
        times.append(time.perf_counter() - started)
    return compile_and_first, statistics.median(times)


def main():
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--orbits", type=int, nargs="+", default=[10_000, 100_000, 1_000_000])
    parser.add_argument("--collisions", type=int, default=200)
    parser.add_argument("--rounds", type=int, default=5)
    parser.add_argument("--no-lockstep", action="store_true", help="leave out the lockstep driver (30 s a call)")
    parser.add_argument(
        "--variants",
        type=int,
        default=0,
        metavar="ORBITS",
        help="first, the bare kernel's tuning (block, warps, rare branch by block) on this many orbits",
    )
    parser.add_argument(
        "--breakdown",
        type=int,
        default=0,
        metavar="ORBITS",
        help="first, where jb.run's time goes (pallas driver) on this many orbits, and the raw transfers",
    )
    parser.add_argument("--skip-main", action="store_true", help="only the kernel variants and the breakdown")
    parser.add_argument(
        "--final-only", action="store_true", help="in the main table, only numba, jb.run (pallas) and the bare kernel"
    )
    parser.add_argument("--scenes", nargs="+", help="the main table's scenes (label prefixes, e.g. 'rotor ell=1.9')")
    args = parser.parse_args()
    if not gpu_present():
        print(
            "bench_gpu: no GPU visible to JAX (jax.devices() = "
            f"{[d.platform for d in jax.devices()]}); nothing to measure. Run it on a machine with a CUDA GPU."
        )
        return 0

    import jaxbill as jb

    sys.path.insert(0, HERE)
    import numba_baseline as baseline
    import numba_cuda_baseline as cuda_baseline

    n = args.collisions
    device = jax.devices()[0]
    print(f"# jaxbill on {device.device_kind} ({jax.__version__}), float64, {n} collisions per orbit")
    print()
    if args.variants:
        kernel_variants(jb, baseline, cuda_baseline, args.variants, n, args.rounds)
    if args.breakdown:
        run_breakdown(jb, baseline, args.breakdown, n, args.rounds)
    if args.skip_main:
        return 0
    scenes = {
        "rotor ell=1.9": baseline.circle_params(2.0, 1.9),
        "rotor ell=1.0": baseline.circle_params(2.0, 1.0),
        "lens ell=1.5": baseline.circle_params(2.0, 1.5, inertia=float("inf")),
        "walls h=3 ell=1": baseline.walls_params(3.0, 1.0),
        "ellipse 2x1.4 ell=0.5": None,
    }
    print(
        "| scene | orbits | what | compile + first s | median s | collisions/s | ratio to numba CUDA "
        "| root steps / collision | agrees with numba CUDA |"
    )
    print("|---|---:|---|---:|---:|---:|---:|---:|---|")
    failures = 0
    if args.scenes:
        scenes = {k: v for k, v in scenes.items() if any(k.startswith(prefix) for prefix in args.scenes)}
    for label, params in scenes.items():
        if params is None:
            scene = jb.StickInEllipse(2.0, 1.4, 0.5)
            make_states = _ellipse_states
        else:
            scene = baseline.jaxbill_scene(params)

            def make_states(count, params=params):
                return baseline.random_states(params, count, seed=5)

        for orbits in args.orbits:
            states = make_states(orbits)
            collisions = orbits * n
            rows = []
            steps = float("nan")
            peer = None
            if params is not None:
                result = []
                first, median = timed(
                    lambda: result.append(cuda_baseline.run_batch_cuda(params, states, n)), args.rounds
                )
                peer = collisions / median
                if result:
                    steps = result[-1][3].sum() / max(result[-1][2].sum(), 1)
                rows.append(("numba CUDA kernel", first, median))
            pallas_calls = []  # compiled calls (chunks) per jb.run: the chunk grows on short calls
            contenders = {
                "jb.run final, pallas": lambda: pallas_calls.append(
                    jb.run(scene, states, n, driver="pallas", progress=False).chunks
                ),
                "jb.run final, lanes": lambda: jb.run(scene, states, n, driver="lanes", progress=False),
                "jb.run states every 100": lambda: jb.run(scene, states, n, record="states", every=100, progress=False),
            }
            contenders["bare kernel, final (one call)"] = bare_kernel(scene, states, n)
            if args.final_only:
                contenders = {k: v for k, v in contenders.items() if "pallas" in k or "bare" in k}
            elif orbits == min(args.orbits):
                contenders["jb.orbit (every state)"] = lambda: jax.block_until_ready(jb.orbit(scene, states, n).state)
                if not args.no_lockstep:
                    contenders["jb.run final, lockstep"] = lambda: jb.run(
                        scene, states, n, driver="lockstep", progress=False
                    )
            if hasattr(scene, "dynamical_indices") and not args.final_only:  # tangent in state coordinates
                from jaxbill._engine import pallas as _pallas

                padded = whole_blocks(states)
                tangents = np.zeros_like(padded)
                dynamical = list(scene.dynamical_indices)
                tangents[:, dynamical] = 1.0 / np.sqrt(len(dynamical))
                device_states, device_tangents = jax.numpy.asarray(padded), jax.numpy.asarray(tangents)
                fli = jax.jit(lambda s, w: _pallas.pallas_fli(scene, s, w, n)[0])
                contenders["tangent collisions (pallas_fli)"] = lambda: jax.block_until_ready(
                    fli(device_states, device_tangents)
                )
            for name, function in contenders.items():
                # The lockstep driver is there for scale only: one timed call (about 30 s for a
                # spinning stick on an H200).
                rows.append((name, *timed(function, 1 if "lockstep" in name else args.rounds)))
            rows = [
                (f"{name} ({pallas_calls[-1]} calls)" if name.endswith("pallas") and pallas_calls else name, *times)
                for name, *times in rows
            ]
            finals = final_states_by_row(jb, scene)
            for name, first, median in rows:
                ratio = f"{collisions / median / peer:.2f}" if peer else "n/a"
                check = "n/a (no numba kernel)"
                if params is not None:
                    row_finals = next((f for prefix, f in finals.items() if name.startswith(prefix)), None)
                    check = row_verdict(jb, scene, params, states, n, name, row_finals, cuda_baseline)
                    failures += check.startswith("**FAIL")
                print(
                    f"| {label} | {orbits} | {name} | {first:.2f} | {median:.4f} | {collisions / median:.3g} "
                    f"| {ratio} | {steps:.2f} | {check} |",
                    flush=True,
                )
    try:
        fli_map_timing(jb, args.rounds)
    except Exception as error:  # reported at the end of the table
        print(f"FLI map failed: {type(error).__name__}: {str(error)[:400]}")
    if failures:
        print(f"\nFAIL: {failures} timed rows disagree with the numba CUDA kernel (the table's last column)")
        return 1
    return 0


def final_states_by_row(jb, scene):
    """For each timed row (by its name's start): ``(states, collisions) -> (B, 6)`` the final states the
    row's own call computes, for ``agreement``."""
    from jaxbill._engine import pallas as _pallas

    def run_with(**options):
        return lambda states, n: jb.run(scene, states, n, progress=False, **options).final_state

    def tangent_final(states, n):
        padded = whole_blocks(states)
        tangents = np.zeros_like(padded)
        tangents[:, list(scene.dynamical_indices)] = 1.0 / np.sqrt(len(scene.dynamical_indices))
        return np.asarray(_pallas.pallas_fli(scene, jax.numpy.asarray(padded), jax.numpy.asarray(tangents), n)[2])[
            : len(states)
        ]

    return {
        "jb.run final, pallas": run_with(driver="pallas"),
        "jb.run final, lanes": run_with(driver="lanes"),
        "jb.run final, lockstep": run_with(driver="lockstep"),
        "jb.run states every 100": run_with(record="states", every=100),
        "bare kernel": lambda states, n: np.asarray(bare_kernel(scene, states, n)())[: len(states)],
        "jb.orbit": lambda states, n: np.asarray(jb.orbit(scene, states, n).state[:, -1]),
        "tangent collisions": tangent_final,
    }


def row_verdict(jb, scene, params, states, n, name, row_finals, cuda_baseline):
    """PASS or a loud FAIL (``agreement``) for one timed row; the contact sequences are checked once per
    scene and batch, on the pallas row (``jb.orbit``'s, on a sample)."""
    import agreement

    if name.startswith("numba"):
        return "(the reference)"
    if row_finals is None:
        return "**FAIL**: no agreement check for this row"
    if "lockstep" in name:  # about 30 s a call: its agreement is the drivers' tests'
        return "n/a (drivers' tests)"

    import numba_baseline as baseline

    def numba_finals(states, n):
        return cuda_baseline.run_batch_cuda(params, states, n)[0]

    def contacts_of(states, n):
        return jb.orbit(scene, states, n).contact

    def numba_contacts(states, n):
        return np.stack([baseline.orbit(params, state, n)[1] for state in states])

    try:
        contacts = (contacts_of, numba_contacts) if "pallas" in name else (None, None)
        problems = agreement.disagreements(row_finals, numba_finals, states, n, *contacts)
    except Exception as error:  # a check that cannot run is a failure, said as loudly
        problems = [f"the check raised {type(error).__name__}: {str(error)[:200]}"]
    return agreement.verdict(problems)


def whole_blocks(states, block=None):
    """``states`` padded to whole kernel blocks (the bare kernel takes no other batch) with copies of
    the first orbit, as ``jb.run`` pads it; rates count the real orbits alone."""
    from jaxbill._engine.pallas import BLOCK as PALLAS_BLOCK
    from jaxbill._engine.sharding import pad_batch

    block = block or PALLAS_BLOCK
    return pad_batch(states, -(-len(states) // block) * block)


def bare_kernel(scene, states, n, **tuning):
    """A function of no argument: ``pallas_final`` over ``states`` (padded to whole blocks, on the
    device already), ``n`` collisions in one call, waited for."""
    from jaxbill._engine.chunks import fresh_carry
    from jaxbill._engine.pallas import pallas_final

    padded = jax.numpy.asarray(whole_blocks(states, tuning.get("block")))
    carry = fresh_carry(scene, padded)
    kernel = jax.jit(lambda s, c: pallas_final(scene, s, c, n, **tuning).state)
    return lambda: jax.block_until_ready(kernel(padded, carry))


def kernel_variants(jb, baseline, cuda_baseline, orbits, n, rounds):
    """The bare kernel (``pallas_final``, one call) at several tunings, beside the numba CUDA kernel;
    and with its bookkeeping (energy drift, contact tally) left out, to see what that costs."""
    from jaxbill._engine import chunks

    tunings = [
        dict(block=32, num_warps=1, rare_by_block=False),
        dict(block=32, num_warps=1, rare_by_block=True),
        dict(block=64, num_warps=2, rare_by_block=False),
        dict(block=64, num_warps=1, rare_by_block=False),
        dict(block=128, num_warps=4, rare_by_block=False),
        dict(block=128, num_warps=2, rare_by_block=False),
        dict(block=16, num_warps=1, rare_by_block=False),
    ]
    print(f"## The bare kernel's tuning, {orbits} orbits x {n} collisions (medians of {rounds}; ratio to numba CUDA)")
    print()
    print("| scene | kernel | compile + first s | median s | collisions/s | ratio |")
    print("|---|---|---:|---:|---:|---:|")
    scenes = {
        "rotor ell=1.9": baseline.circle_params(2.0, 1.9),
        "lens ell=1.5": baseline.circle_params(2.0, 1.5, inertia=float("inf")),
        "walls h=3 ell=1": baseline.walls_params(3.0, 1.0),
    }
    for label, params in scenes.items():
        scene = baseline.jaxbill_scene(params)
        states = baseline.random_states(params, orbits, seed=5)
        collisions = orbits * n
        first, median = timed(lambda: cuda_baseline.run_batch_cuda(params, states, n), rounds)
        peer = collisions / median
        rows = [("numba CUDA kernel", first, median)]
        for tuning in tunings:
            name = ", ".join(f"{k} {v}" for k, v in tuning.items())
            rows.append((name, *timed(bare_kernel(scene, states, n, **tuning), rounds)))
        # The same kernel with its bookkeeping left out (its results then lack drift and tally).
        saved = chunks.energy_drift, chunks.tally_contact
        chunks.energy_drift = lambda scene, state0: lambda state: jax.numpy.zeros_like(state[0])
        chunks.tally_contact = lambda codes, counts, contact, collided: counts
        try:
            rows.append(("block 32, no drift or tally", *timed(bare_kernel(scene, states, n), rounds)))
        finally:
            chunks.energy_drift, chunks.tally_contact = saved
        for name, first, median in rows:
            rate = collisions / median
            print(f"| {label} | {name} | {first:.2f} | {median:.4f} | {rate:.3g} | {rate / peer:.2f} |", flush=True)
    print()


def run_breakdown(jb, baseline, orbits, n, rounds):
    """Where ``jb.run``'s time goes (pallas driver, final states) beside the raw transfers it makes."""
    import collections
    import functools

    from jaxbill._runs import streaming

    spent = collections.defaultdict(list)
    originals = {}

    def timer(owner, name, label, wait=False):
        function = getattr(owner, name)
        originals[owner, name] = function

        @functools.wraps(function)
        def timed_part(*args, **kwargs):
            started = time.perf_counter()
            result = function(*args, **kwargs)
            if wait:
                jax.block_until_ready(result)
            spent[label].append(time.perf_counter() - started)
            return result

        setattr(owner, name, timed_part)

    timer(streaming, "check_eagerly", "checks (state validation)")
    timer(streaming._Engine, "__init__", "engine: pad, states to the device")
    timer(streaming._Engine, "initial_carry", "initial carry")
    timer(streaming._Engine, "run_chunk", "chunks (kernel calls, waited for)", wait=True)
    timer(streaming._Engine, "to_host", "results to the host")
    print(f"## Where jb.run's time goes, {orbits} orbits x {n} collisions, pallas driver (medians of {rounds})")
    print()
    print("| scene | part | ms |")
    print("|---|---|---:|")
    try:
        for label, params in {
            "rotor ell=1.9": baseline.circle_params(2.0, 1.9),
            "lens ell=1.5": baseline.circle_params(2.0, 1.5, inertia=float("inf")),
        }.items():
            scene = baseline.jaxbill_scene(params)
            states = baseline.random_states(params, orbits, seed=5)
            jb.run(scene, states, n, driver="pallas", progress=False)
            spent.clear()
            totals = []
            for _ in range(rounds):
                started = time.perf_counter()
                jb.run(scene, states, n, driver="pallas", progress=False)
                totals.append(time.perf_counter() - started)
            for part, times in spent.items():
                calls = len(times) // rounds  # each run's calls, one run after another
                per_run = [sum(times[i * calls : (i + 1) * calls]) for i in range(rounds)]
                print(f"| {label} | {part} ({calls} calls) | {1e3 * statistics.median(per_run):.1f} |")
            print(f"| {label} | jb.run in all | {1e3 * statistics.median(totals):.1f} |", flush=True)
    finally:
        for (owner, name), function in originals.items():
            setattr(owner, name, function)
    host = np.random.default_rng(0).standard_normal((orbits, 6))
    device = jax.numpy.asarray(host)
    counts = jax.numpy.zeros((orbits, 10), jax.numpy.int64)
    for what, function in {
        f"device_put of ({orbits}, 6) float64": lambda: jax.block_until_ready(jax.device_put(host)),
        f"({orbits}, 6) float64 to the host": lambda: np.asarray(device + 0.0),
        f"({orbits}, 10) int64 to the host": lambda: np.asarray(counts + 1),
    }.items():
        print(f"| transfer | {what} | {1e3 * timed(function, rounds)[1]:.1f} |")
    print(flush=True)


def fli_map_timing(jb, rounds, side=1024, collisions=1000):
    """A ``side`` x ``side`` FLI map on the lens's section (the GPU path of ``jb.fli_map``)."""
    scene = jb.StickInCircle(2.0, 1.5, inertia=float("inf"))
    length = float(jb.wall_length(scene))
    s, p = np.meshgrid(np.linspace(0.0, length, side, endpoint=False), np.linspace(-0.95, 0.95, side))
    grid = np.asarray(jb.section_state(scene, s, p, energy=0.5))
    first, median = timed(lambda: jb.fli_map(scene, grid, collisions, chunk=side * side), rounds)
    print()
    print(
        f"FLI map {side} x {side}, {collisions} collisions, lens R=2 ell=1.5: first call {first:.2f} s, "
        f"then median {median:.3f} s ({side * side * collisions / median:.3g} tangent collisions/s)"
    )
    return grid


def _ellipse_states(count, seed=5):
    import jaxbill as jb

    rng = np.random.default_rng(seed)
    radius, angle = 0.3 * np.sqrt(rng.uniform(size=count)), rng.uniform(-np.pi, np.pi, count)
    v = rng.normal(size=(count, 2))
    states = np.stack(
        [
            radius * np.cos(angle),
            radius * np.sin(angle),
            rng.uniform(-np.pi, np.pi, count),
            v[:, 0],
            v[:, 1],
            rng.normal(size=count),
        ],
        axis=1,
    )
    return np.asarray(jb.orbit(jb.StickInEllipse(2.0, 1.4, 0.5), states, 2).state[:, -1])


if __name__ == "__main__":
    sys.exit(main())
