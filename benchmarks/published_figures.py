"""The speed figures the README and the docs publish, computed from the files the benchmarks wrote.

Run:  python benchmarks/published_figures.py          (prints the tables the README and the performance page hold)

Every published speed figure has one source: a file in ``benchmarks/results/``
that a benchmark wrote, with the machine, the date and the versions beside it.
A figure measured in several runs (or on several machines) is published as the
range of all of them, never as the best run. ``tests/test_published_figures.py``
checks that the README's and the performance page's tables are the ones printed
here, and that every speed figure quoted in the README or a docs page is in a
results file.

Nothing here imports jaxbill, JAX or numba: it reads JSON and markdown.
"""

from __future__ import annotations

import glob
import json
import math
import os
import re

HERE = os.path.dirname(os.path.abspath(__file__))
RESULTS = os.path.join(HERE, "results")

# The rows of the table against numba: (label, table, scene, jaxbill's contender, numba's suffix).
NUMBA_ROWS = (
    ("one orbit, spinning stick (ell = 1.9), every state recorded", "one orbit", "rotor ell=1.9", "jaxbill", ""),
    ("one orbit, spinning stick (ell = 1.0)", "one orbit", "rotor ell=1.0", "jaxbill", ""),
    ("one orbit, static lens", "one orbit", "lens ell=1.5", "jaxbill", ""),
    ("one orbit, circle billiard", "one orbit", "circle", "jaxbill", ""),
    ("one orbit, stick between walls", "one orbit", "walls h=3 ell=1", "jaxbill", ""),
    (
        "batch of 4096 x 200, one core, `jb.run`, spinning stick (ell = 1.9)",
        "batch",
        "rotor ell=1.9",
        "jb.run",
        " 1 core",
    ),
    ("batch, one core, spinning stick (ell = 1.0)", "batch", "rotor ell=1.0", "jb.run", " 1 core"),
    ("batch, one core, static lens", "batch", "lens ell=1.5", "jb.run", " 1 core"),
    ("batch, one core, circle billiard", "batch", "circle", "jb.run", " 1 core"),
    ("batch, one core, stick between walls", "batch", "walls h=3 ell=1", "jb.run", " 1 core"),
    ("batch, two cores, spinning stick (ell = 1.9)", "batch", "rotor ell=1.9", "jb.run", " 2 cores"),
    ("batch, two cores, static lens", "batch", "lens ell=1.5", "jb.run", " 2 cores"),
)
SPINNING = ("rotor ell=1.9", "rotor ell=1.0")


def _load(pattern: str) -> list[dict]:
    runs = []
    for path in sorted(glob.glob(os.path.join(RESULTS, pattern))):
        with open(path) as f:
            run = json.load(f)
        if not run.get("quick"):
            run["file"] = os.path.relpath(path, os.path.dirname(HERE))
            runs.append(run)
    return runs


def numba_runs() -> list[dict]:
    """Every full run of ``bench_vs_numba.py`` on file (``--quick`` runs are not published)."""
    return _load("vs_numba_*.json")


def _row(run: dict, table: str, scene: str) -> dict | None:
    return next((r for r in run["rows"] if r["table"] == table and r["scene"] == scene), None)


def _values(runs, table, scene, get) -> list[float]:
    out = []
    for run in runs:
        row = _row(run, table, scene)
        if row is not None:
            try:
                out.append(float(get(row)))
            except KeyError:
                pass
    return out


def scientific(x: float) -> str:
    """``x`` to 2 significant digits as the pages write it: ``1.7e6``."""
    mantissa, exponent = f"{x:.1e}".split("e")
    return f"{mantissa}e{int(exponent)}"


def _span(values, fmt) -> str:
    if not values:
        return "n/a"
    low, high = fmt(min(values)), fmt(max(values))
    return low if low == high else f"{low}-{high}"


def _ratio(x: float) -> str:
    return f"{x:.2f}"


def numba_table(runs: list[dict] | None = None) -> str:
    """The README's table against numba: the range of every figure over every full run on file."""
    runs = numba_runs() if runs is None else runs
    lines = [
        "| | jaxbill | numba, the loop a user would write | numba, the same method | ratio to the user's loop "
        "| ratio to the same method |",
        "|---|---:|---:|---:|---:|---:|",
    ]
    for label, table, scene, ours, cores in NUMBA_ROWS:
        jaxbill = ours if table == "one orbit" else ours + cores
        user = "numba user loop" + cores
        same = "numba same method" + cores
        if table == "one orbit":
            ratio_user, ratio_same = "ratio to user loop", "ratio to same method"
        else:
            ratio_user, ratio_same = f"ratio {jaxbill} to user loop", f"ratio {jaxbill} to same method"
        rates = {
            name: _values(runs, table, scene, lambda r, name=name: r[name]["rate"]) for name in (jaxbill, user, same)
        }
        if not rates[jaxbill]:
            continue
        unit = " coll/s" if label.startswith("one orbit, spinning stick (ell = 1.9)") else ""
        two_loops = scene in SPINNING
        cells = [
            _span(rates[jaxbill], scientific) + unit,
            _span(rates[user], scientific),
            _span(rates[same], scientific) if two_loops else "the same loop",
            _span(_values(runs, table, scene, lambda r: r[ratio_user]), _ratio),
            _span(_values(runs, table, scene, lambda r: r[ratio_same]), _ratio) if two_loops else "the same",
        ]
        lines.append(f"| {label} | " + " | ".join(cells) + " |")
    return "\n".join(lines)


def root_steps_line(runs: list[dict] | None = None) -> str:
    """Root steps per collision of the spinning stick (ell = 1.9) on the benchmark's orbit, as the README says them."""
    runs = numba_runs() if runs is None else runs

    def steps(key):
        return _span(_values(runs, "one orbit", "rotor ell=1.9", lambda r: r["root steps per collision"][key]), _steps)

    return (
        f"Root steps per collision of the spinning stick (ell = 1.9): jaxbill {steps('jaxbill')}, the user's "
        f"loop {steps('numba user loop')}, the same method {steps('numba same method')}."
    )


def _steps(x: float) -> str:
    return f"{x:.1f}"


def measured_on(runs: list[dict] | None = None) -> str:
    """Where and when: the machines, dates, versions and load averages of the runs on file."""
    runs = numba_runs() if runs is None else runs
    machines = sorted({f"{r['processor']}, {r['logical_cpus']} logical CPUs" for r in runs})
    dates = sorted({r["date_utc"][:10] for r in runs})
    loads = [float(r["load_average"][when].split()[0]) for r in runs for when in ("start", "end")]
    versions = sorted({f"jax {r['versions']['jax']}, numba {r['versions']['numba']}" for r in runs})
    return (
        f"{len(runs)} runs of `benchmarks/bench_vs_numba.py` on {len(machines)} machine type"
        f"{'s' if len(machines) > 1 else ''} ({'; '.join(machines)}; 1-minute load average "
        f"{min(loads):.1f}-{max(loads):.1f}), {', '.join(dates)}; {'; '.join(versions)}; "
        "every figure is the range over the runs (`benchmarks/results/vs_numba_*.json`)"
    )


# -- every number a results file holds, for the check of quoted figures ----------------------

_NUMBER = re.compile(r"(?<![\w.])[-+]?(?:\d+\.?\d*|\.\d+)(?:[eE][-+]?\d+)?")


# The keys of a JSON results file under which speed figures are stored (rates, ratios, speed-ups, click times).
SPEED_KEY = re.compile(r"rate|ratio|speed-up|_over_|click")


def _numbers_in(value, speed: bool = False) -> list[float]:
    """The numbers of ``value``: under a speed key (``SPEED_KEY``) of a JSON tree only, so that a quoted
    figure cannot match an unrelated number (an error, a count) by chance."""
    if isinstance(value, bool):
        return []
    if isinstance(value, (int, float)):
        return [float(value)] if speed else []
    if isinstance(value, dict):
        return [x for k, v in value.items() for x in _numbers_in(v, speed or bool(SPEED_KEY.search(str(k))))]
    if isinstance(value, list):
        return [x for v in value for x in _numbers_in(v, speed)]
    return []


def result_numbers() -> list[float]:
    """Every speed figure in every results file: the numbers under a speed key of the JSON files, and every
    number of the markdown ones (raw benchmark output: tables of rates and ratios)."""
    numbers = []
    for path in sorted(glob.glob(os.path.join(RESULTS, "*"))):
        with open(path) as f:
            text = f.read()
        if path.endswith(".json"):
            numbers += _numbers_in(json.loads(text))
        else:
            numbers += [float(m) for m in _NUMBER.findall(text)]
    return [x for x in numbers if math.isfinite(x)]


def main() -> None:
    runs = numba_runs()
    print(numba_table(runs))
    print()
    print(root_steps_line(runs))
    print()
    print(measured_on(runs))


if __name__ == "__main__":
    main()
