"""jaxbill against an earlier revision of itself, in one process: did a change make a scene slower?

Run:  python benchmarks/bench_revisions.py --before REV [--rounds N] [--orbit-collisions N]
                                           [--batch B] [--batch-collisions N] [--drivers]
                                           [--scenes SUBSTRING ...] [--results PATH]

The working tree's ``jaxbill`` and the package as it was at the git revision
``REV`` (extracted with ``git archive`` into a temporary folder and renamed
``jaxbill_before``, so that both import side by side) run the same workloads
from the same states, timed in alternating rounds (``interleaved.py``): the
noise of this shared machine falls on both alike, and the ratio of the medians
is the figure. The workloads are those of ``bench_vs_numba.py`` (R = 2, the
default inertia): one orbit of ``--orbit-collisions`` collisions, every state
recorded, for the spinning stick at ell = 1.9 and 1.0, the static lens, the
circle billiard, the stick between walls (h = 3, ell = 1) and the stick in an
ellipse; and a batch of ``--batch`` orbits of ``--batch-collisions``
collisions, final states only (``jb.run``), on one device. ``--drivers`` adds
the same batch run by each CPU driver (``serial``, ``lockstep``, ``lanes``)
and recording every 10th state (``record="states"``, the scene's default
driver); ``--scenes`` keeps the scenes whose name holds one of the words
given. Each pair must
also agree: the same contacts and states within the orbit's float64 horizon
(a change of arithmetic may change the last bits, and a chaotic orbit then
parts from its earlier self), which the report checks and prints.

Writes the table, with the machine, the date, the versions and both
revisions, to ``benchmarks/results/revisions_<UTC date and time>.json``.
"""

from __future__ import annotations

import argparse
import datetime
import importlib
import json
import os
import pathlib
import platform
import re
import subprocess
import sys
import tarfile
import tempfile

HERE = pathlib.Path(__file__).resolve().parent
ROOT = HERE.parent
sys.path.insert(0, str(HERE))

os.environ.setdefault("XLA_FLAGS", "--xla_force_host_platform_device_count=1")


def extract_revision(revision: str, folder: pathlib.Path) -> str:
    """The package at ``revision`` as the importable ``jaxbill_before`` under ``folder``; returns the full hash."""
    full = subprocess.run(["git", "rev-parse", revision], cwd=ROOT, capture_output=True, text=True, check=True)
    archive = folder / "before.tar"
    subprocess.run(["git", "archive", "-o", str(archive), revision, "jaxbill"], cwd=ROOT, check=True)
    with tarfile.open(archive) as tar:
        tar.extractall(folder, filter="data")
    (folder / "jaxbill").rename(folder / "jaxbill_before")
    for path in (folder / "jaxbill_before").rglob("*.py"):
        text = path.read_text()
        path.write_text(re.sub(r"\bjaxbill\b(?=[._ ])", "jaxbill_before", text))
    return full.stdout.strip()


def scenes(jb):
    inf = float("inf")
    return {
        "spinning stick, ell = 1.9": jb.StickInCircle(2.0, 1.9),
        "spinning stick, ell = 1.0": jb.StickInCircle(2.0, 1.0),
        "static lens, ell = 1.5": jb.StickInCircle(2.0, 1.5, inertia=inf),
        "circle billiard": jb.StickInCircle(2.0, 0.0),
        "stick between walls": jb.StickBetweenWalls2D(3.0, 1.0),
        "stick in an ellipse": jb.StickInEllipse(2.0, 1.3, 0.6),
    }


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--before", required=True, help="the git revision to compare with")
    parser.add_argument("--rounds", type=int, default=7)
    parser.add_argument("--orbit-collisions", type=int, default=100_000)
    parser.add_argument("--batch", type=int, default=1024)
    parser.add_argument("--batch-collisions", type=int, default=200)
    parser.add_argument("--drivers", action="store_true", help="also time each CPU driver and a recorded run")
    parser.add_argument("--scenes", nargs="*", default=None, help="only scenes whose name holds one of these")
    parser.add_argument("--results", default=None)
    args = parser.parse_args()

    import jax
    import numpy as np

    from interleaved import interleaved, load_average

    with tempfile.TemporaryDirectory() as temporary:
        folder = pathlib.Path(temporary)
        before_hash = extract_revision(args.before, folder)
        sys.path.insert(0, str(folder))
        import jaxbill as after_jb

        before_jb = importlib.import_module("jaxbill_before")
        after_hash = subprocess.run(
            ["git", "rev-parse", "HEAD"], cwd=ROOT, capture_output=True, text=True, check=True
        ).stdout.strip()
        print(f"# jaxbill at {after_hash[:10]} (working tree) against {before_hash[:10]}")
        print(f"load average before: {load_average()}\n")
        print("| workload | after | before | after / before | same contacts | agree to 1e-10 over |")
        print("|---|---:|---:|---:|---:|---:|")
        rows = []
        after_scenes, before_scenes = scenes(after_jb), scenes(before_jb)
        for name in after_scenes:
            if args.scenes and not any(word in name for word in args.scenes):
                continue
            new, old = after_scenes[name], before_scenes[name]
            start = np.asarray(after_jb.sample_energy_shell(new, 1, seed=1)[0][0])
            starts = after_jb.sample_energy_shell(new, args.batch, seed=2)[0]
            n, nb = args.orbit_collisions, args.batch_collisions

            def one(jb, scene):
                return lambda: jax.block_until_ready(jb.orbit(scene, start, n))

            def batch(jb, scene):
                return lambda: jb.run(scene, starts, nb)

            def by_driver(driver):
                return lambda jb, scene: lambda: jb.run(scene, starts, nb, driver=driver)

            def recorded(jb, scene):
                return lambda: jb.run(scene, starts, nb, record="states", every=10)

            workloads = [("one orbit", one, n), ("batch", batch, nb * args.batch)]
            if args.drivers:
                workloads += [(f"batch, {d}", by_driver(d), nb * args.batch) for d in ("serial", "lockstep", "lanes")]
                workloads.append(("batch, every 10th state", recorded, nb * args.batch))
            for workload, maker, collisions in workloads:
                timing = interleaved({"after": maker(after_jb, new), "before": maker(before_jb, old)}, args.rounds)
                if workload == "one orbit":
                    a, b = after_jb.orbit(new, start, 400), before_jb.orbit(old, start, 400)
                    same = np.asarray(a.contact) == np.asarray(b.contact)
                    close = np.max(np.abs(np.asarray(a.state) - np.asarray(b.state)), axis=-1) <= 1e-10
                    agree = int(np.argmin(np.concatenate([close & same, [False]])))
                    same_count = int(np.argmin(np.concatenate([same, [False]])))
                else:
                    agree = same_count = -1
                after_rate = collisions / timing["after"].median
                before_rate = collisions / timing["before"].median
                ratio = timing["after"].median / timing["before"].median
                row = dict(
                    scene=name,
                    workload=workload,
                    after_collisions_per_second=after_rate,
                    before_collisions_per_second=before_rate,
                    time_ratio=ratio,
                    same_contacts_for=same_count,
                    agree_for=agree,
                )
                rows.append(row)
                shown = "" if agree < 0 else f"{same_count} | {agree}"
                print(f"| {name}, {workload} | {after_rate:.3g}/s | {before_rate:.3g}/s | {ratio:.3f} | {shown} |")
        print(f"\nload average after: {load_average()}")
        stamp = datetime.datetime.now(datetime.UTC)
        out = pathlib.Path(args.results or HERE / "results" / f"revisions_{stamp.strftime('%Y-%m-%dT%H%M%SZ')}.json")
        out.parent.mkdir(parents=True, exist_ok=True)
        out.write_text(
            json.dumps(
                dict(
                    date=stamp.isoformat(),
                    machine=dict(platform=platform.platform(), processor=platform.processor(), cpus=os.cpu_count()),
                    versions=dict(python=platform.python_version(), jax=jax.__version__),
                    after=after_hash,
                    before=before_hash,
                    rounds=args.rounds,
                    load_average=load_average(),
                    rows=rows,
                ),
                indent=1,
            )
        )
        print(f"written: {out}")


if __name__ == "__main__":
    main()
