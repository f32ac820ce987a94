"""Every speed figure the README and the docs publish comes from a file a benchmark wrote.

``benchmarks/results/`` holds what the benchmarks wrote, with the machine, the
date and the versions; ``benchmarks/published_figures.py`` turns the runs of
``bench_vs_numba.py`` into the table the README and the performance page show
(the range over every run, never the best one). These tests fail when a page's
table is not that table, or when the README or a docs page quotes a speed
figure (collisions or steps per second, a multiple of numba's speed, "N times
faster") that no results file holds at the precision quoted.
"""

from __future__ import annotations

import json
import pathlib
import re
import sys

import pytest

ROOT = pathlib.Path(__file__).resolve().parent.parent
sys.path.insert(0, str(ROOT / "benchmarks"))
import published_figures  # noqa: E402

PAGES = [ROOT / "README.md", *sorted((ROOT / "docs").rglob("*.md"))]

NUM = r"\d+(?:\.\d+)?(?:e[+-]?\d+)?"
# A rate: a number (or a range) and, at most three words later, a unit of collisions or steps per second.
RATE = re.compile(
    rf"(?<![\w.])({NUM})(?:-({NUM}))?(?:\s+[A-Za-z][\w-]*){{0,3}}?\s*(?:coll(?:isions|\.)?/s|steps/s|/s\b)"
)
# A multiple: "0.26x a numba kernel", "1.4-1.8x faster", "0.52-0.73x the rate", "160 times faster".
MULTIPLE = re.compile(
    rf"(?<![\w.])({NUM})(?:-({NUM}))?(?:x| times) (?:(?:a|the) )?(?:numba|faster|slower|the rate|as fast)"
)


def _prose(text: str) -> str:
    """The page without its fenced code blocks (code is not a claim)."""
    return re.sub(r"^```.*?^```", "", text, flags=re.M | re.S)


def quoted_figures(text: str) -> list[str]:
    figures = []
    for pattern in (RATE, MULTIPLE):
        for match in pattern.finditer(_prose(text)):
            low, high = match.groups()
            if high and "e" in high and "e" not in low:
                low += "e" + high.split("e")[1]  # "4.6-4.7e9": both ends times 1e9
            figures += [g for g in (low, high) if g]
    return figures


def _same_at_quoted_precision(quoted: str, value: float) -> bool:
    """Whether ``value`` rounds to ``quoted`` at the digits it shows (either way at an exact half)."""
    mantissa, _, exponent = quoted.partition("e")
    decimals = len(mantissa.split(".")[1]) if "." in mantissa else 0
    unit = 10.0 ** (int(exponent or 0) - decimals)
    return abs(value - float(quoted)) <= 0.5 * unit * (1 + 1e-9)


@pytest.fixture(scope="module")
def numbers():
    values = published_figures.result_numbers()
    assert len(values) > 100, "benchmarks/results/ holds almost nothing"
    return values


def test_the_figure_patterns_find_what_the_pages_quote():
    """The scanner itself: it finds rates, ranges and multiples as pages write them, and no accuracy figures."""
    text = (
        "a spinning stick 1.3e6 collisions/s, the lens 2.2e7/s; 7.8e8 spinning-stick collisions/s, 0.26x a numba "
        "kernel; 1.4-1.8x faster; 0.52-0.73x the rate; 160 times faster; 2.9e6 tangent steps/s; agree to `3e-13`\n"
        "```\n5.0e6 coll/s in code\n```\n"
    )
    assert quoted_figures(text) == ["1.3e6", "2.2e7", "7.8e8", "2.9e6", "0.26", "1.4", "1.8", "0.52", "0.73", "160"]
    assert quoted_figures("at 4.6-4.7e9/s") == ["4.6e9", "4.7e9"]
    assert _same_at_quoted_precision("7.8e8", 7.77e8) and not _same_at_quoted_precision("7.8e8", 7.74e8)
    assert _same_at_quoted_precision("2.1e9", 2.05e9) and _same_at_quoted_precision("11", 11.03)
    assert _same_at_quoted_precision("0.26", 0.2601) and not _same_at_quoted_precision("0.26", 0.27)


@pytest.mark.parametrize("page", PAGES, ids=lambda p: str(p.relative_to(ROOT)))
def test_every_quoted_speed_figure_is_in_a_results_file(page, numbers):
    missing = [
        figure
        for figure in quoted_figures(page.read_text())
        if not any(_same_at_quoted_precision(figure, value) for value in numbers)
    ]
    assert not missing, (
        f"{page.relative_to(ROOT)} quotes speed figures that no file in benchmarks/results/ holds: {missing}"
    )


@pytest.mark.parametrize("page", ["README.md", "docs/performance.md"])
def test_the_numba_table_is_the_range_over_every_run_on_file(page):
    """The table against numba, and where and when it was measured, are what the results files give now."""
    # Lines compared without their indentation (in the README the table sits in a list item).
    text = "\n".join(line.strip() for line in (ROOT / page).read_text().splitlines())
    runs = published_figures.numba_runs()
    assert len(runs) >= 2, "publish the range of at least two full runs of bench_vs_numba.py"
    for block in (
        published_figures.numba_table(runs),
        published_figures.root_steps_line(runs),
        published_figures.measured_on(runs),
    ):
        assert block in text, f"{page} does not hold, as printed by benchmarks/published_figures.py:\n{block}"


def test_every_results_file_says_where_when_and_with_what():
    for path in sorted((ROOT / "benchmarks" / "results").glob("*.json")):
        report = json.loads(path.read_text())
        described = json.dumps(report.get("meta", report))
        assert re.search(r"20\d\d-\d\d-\d\d", described), f"{path.name}: no date"
        assert "jax" in described and re.search(r"x86_64|arm|aarch64|cpu|gpu", described, re.I), path.name
