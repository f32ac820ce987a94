"""Contenders timed in alternation in one process, the way every table here is measured.

This machine is shared and noisy: timing one contender's runs and then the
next's lets a busy minute fall on one column. Rounds that call each contender
in turn spread the noise over all of them alike; the median of the rounds is
the figure quoted.
"""

from __future__ import annotations

import os
import statistics
import time
from collections.abc import Callable
from dataclasses import dataclass


@dataclass(frozen=True)
class Timing:
    first: float  # seconds of the first call (compilation included)
    median: float  # median wall seconds over the rounds
    cores: float  # this process's CPU seconds over wall seconds in the rounds
    round_seconds: tuple[float, ...]  # wall seconds of every timed call, in order


def interleaved(contenders: dict[str, Callable[[], object]], rounds: int) -> dict[str, Timing]:
    """Call each contender once, then ``rounds`` times in alternation; each call must wait for its work."""
    first = {}
    for name, function in contenders.items():
        started = time.perf_counter()
        function()
        first[name] = time.perf_counter() - started
    walls: dict[str, list[float]] = {name: [] for name in contenders}
    cpus: dict[str, list[float]] = {name: [] for name in contenders}
    for _ in range(rounds):
        for name, function in contenders.items():
            wall, cpu = time.perf_counter(), time.process_time()
            function()
            walls[name].append(time.perf_counter() - wall)
            cpus[name].append(time.process_time() - cpu)
    return {
        name: Timing(
            first[name], statistics.median(walls[name]), sum(cpus[name]) / sum(walls[name]), tuple(walls[name])
        )
        for name in contenders
    }


def load_average() -> str:
    """The machine's 1, 5 and 15 minute load averages, for a report's header and footer."""
    try:
        return " ".join(f"{x:.2f}" for x in os.getloadavg())
    except OSError:
        return "n/a"


def jaxbill_source(package_dir: str) -> str:
    """Which jaxbill a record timed, without naming this machine's folders: ``"this checkout"`` when the
    package imported is the one beside this script, else ``"another copy"`` (an install, a worktree)."""
    here = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
    same = os.path.realpath(package_dir) == os.path.realpath(os.path.join(here, "jaxbill"))
    return "this checkout" if same else "another copy"
