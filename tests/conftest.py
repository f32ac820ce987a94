"""Test-wide setup: the public API's shape annotations are checked on every call the tests make.

``shape_checks.install`` wraps the public functions of ``jaxbill`` before any
test module imports them, so ``jb.orbit(...)`` and ``from jaxbill import orbit``
both get the checked version. ``test_shape_checks.py`` proves the checks are live.
"""

import os
import shutil
import sys
import tempfile

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))

# One compilation cache on disk for the whole session. About a fifth of the suite's
# compilations repeat one made earlier: the same collision maps, validity checks and
# orbits in many modules, after the fixture below has emptied JAX's in-memory caches, and
# in every xdist worker, command-line subprocess and notebook kernel, each of which starts
# empty. With the cache each loads what another compiled. A hit is the same executable:
# its key covers the program, XLA's flags (jaxbill's included) and the devices. Programs
# that compile in under 0.1 s are not written: most of the writes, little of the time.
# Set here, before JAX is imported, so that the workers and subprocesses inherit it; the
# process that made the folder removes it at the end. A JAX_COMPILATION_CACHE_DIR of your
# own is used as it is and kept.
SESSION_COMPILATION_CACHE = None
if "JAX_COMPILATION_CACHE_DIR" not in os.environ:
    SESSION_COMPILATION_CACHE = tempfile.mkdtemp(prefix="jaxbill-tests-compiled-")
    os.environ["JAX_COMPILATION_CACHE_DIR"] = SESSION_COMPILATION_CACHE
    os.environ.setdefault("JAX_PERSISTENT_CACHE_MIN_COMPILE_TIME_SECS", "0.1")

if os.environ.get("PYTEST_XDIST_WORKER"):
    # Workers share one GPU where there is one: each takes memory as it needs it,
    # where JAX's default takes three quarters of it for the first process.
    os.environ.setdefault("XLA_PYTHON_CLIENT_PREALLOCATE", "false")

import jaxbill  # noqa: E402
import shape_checks  # noqa: E402

UNRESOLVED_ANNOTATIONS = shape_checks.install(jaxbill)


import jax  # noqa: E402
import pytest  # noqa: E402

# In case a plugin imported JAX before this file set the variables.
jax.config.update("jax_compilation_cache_dir", os.environ["JAX_COMPILATION_CACHE_DIR"])
if "JAX_PERSISTENT_CACHE_MIN_COMPILE_TIME_SECS" in os.environ:
    jax.config.update(
        "jax_persistent_cache_min_compile_time_secs", float(os.environ["JAX_PERSISTENT_CACHE_MIN_COMPILE_TIME_SECS"])
    )

# Test files that take minutes in all, longest first (about 7, 6 and 6 minutes of a
# worker's time on 2 cores). The workers take whole files in collection order
# (``--dist loadfile --no-loadscope-reorder``), so these start first: one left for
# the end would keep one worker busy while the others idle.
LONGEST_FIRST = ("test_drivers.py", "test_notebooks.py", "test_scene_contract.py")


# Tests that read the built site or the API reference's hooks need the docs extra: they skip
# without it, and .ci/run's second stage, with the extra, runs them alone (``-m docs_extra``).
DOCS_EXTRA_FIXTURES = {"site", "hooks"}


def pytest_configure(config):
    config.addinivalue_line("markers", "docs_extra: needs the docs extra (mkdocs); marked by the fixtures it uses")


def pytest_unconfigure(config):
    if SESSION_COMPILATION_CACHE is not None:
        shutil.rmtree(SESSION_COMPILATION_CACHE, ignore_errors=True)


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
