"""Test-wide setup: the public API's shape annotations are checked on every call the tests make.

``shape_checks.install`` wraps the public functions of ``jaxbill`` before any
test module imports them, so ``jb.orbit(...)`` and ``from jaxbill import orbit``
both get the checked version. ``test_shape_checks.py`` proves the checks are live.
"""

import os
import sys

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))

if os.environ.get("PYTEST_XDIST_WORKER"):
    # Workers share one GPU where there is one: each takes memory as it needs it,
    # where JAX's default takes three quarters of it for the first process.
    os.environ.setdefault("XLA_PYTHON_CLIENT_PREALLOCATE", "false")

import jaxbill
import shape_checks

UNRESOLVED_ANNOTATIONS = shape_checks.install(jaxbill)


import jax  # noqa: E402
import pytest  # noqa: E402

# Test files that take minutes in all, longest first (about 7 and 6 minutes of a
# worker's time on 2 cores). The workers take whole files in collection order
# (``--dist loadfile --no-loadscope-reorder``), so these start first: one left for
# the end would keep one worker busy while the others idle.
LONGEST_FIRST = ("test_drivers.py", "test_notebooks.py")


# Tests that read the built site or the API reference's hooks need the docs extra: they skip
# without it, and .ci/run's second stage, with the extra, runs them alone (``-m docs_extra``).
DOCS_EXTRA_FIXTURES = {"site", "hooks"}


def pytest_configure(config):
    config.addinivalue_line("markers", "docs_extra: needs the docs extra (mkdocs); marked by the fixtures it uses")


def pytest_collection_modifyitems(items):
    rank = {name: position for position, name in enumerate(LONGEST_FIRST)}
    items.sort(key=lambda item: rank.get(item.path.name, len(rank)))
    for item in items:
        if DOCS_EXTRA_FIXTURES & set(getattr(item, "fixturenames", ())):
            item.add_marker(pytest.mark.docs_extra)


@pytest.fixture(autouse=True, scope="module")
def _release_compiled_programs():
    """Drop JAX's compiled programs after each test module.

    The suite compiles thousands of programs in one process; kept, they grew
    it past 5 GB, and twice XLA crashed compiling a program late in the run
    (a segfault inside the compiler, never seen when the same module ran
    alone). Modules share almost no programs, so little is compiled twice.
    """
    yield
    jax.clear_caches()
