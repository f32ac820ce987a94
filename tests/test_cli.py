"""The ``jaxbill`` console command (run as a subprocess, as a user would)."""

from __future__ import annotations

import os
import re
import subprocess
import sys

import jax.numpy as jnp
import numpy as np
import pytest

import jaxbill as jb
from jaxbill.cli import DEFAULT_DEMO_STATE

FLOAT = r"[-+]?(?:\d+\.?\d*|\.\d+)(?:[eE][-+]?\d+)?"


def _run(*args):
    env = dict(os.environ, JAX_PLATFORMS="cpu")
    return subprocess.run(
        [sys.executable, "-m", "jaxbill.cli", *args], capture_output=True, text=True, env=env, timeout=300
    )


@pytest.fixture(scope="module")
def demo():
    proc = _run("demo", "-n", "200", "--show", "3")
    output = f"stdout:\n{proc.stdout[-2000:]}\nstderr:\n{proc.stderr[-3000:]}"
    assert proc.returncode == 0, f"exit {proc.returncode}\n{output}"
    return proc.stdout


def _rows(out):
    rows = []
    for line in out.splitlines():
        fields = line.split()
        if len(fields) == 9 and fields[0].isdigit():
            rows.append((int(fields[0]), float(fields[1]), int(fields[2]), np.array([float(f) for f in fields[3:]])))
    return rows


def test_demo_prints_the_requested_collisions(demo):
    rows = _rows(demo)
    assert [r[0] for r in rows] == [1, 2, 3]
    assert all(r[2] in (1, -1, 2) for r in rows)
    times = [r[1] for r in rows]
    assert 0 < times[0] < times[1] < times[2]
    assert re.search(r"^200 collisions in " + FLOAT + r" s", demo, re.M)


def test_demo_collisions_match_collide(demo):
    """The printed rows are the collisions jb.collide gives from the default state
    (default scene R = 2, ell = 1.9); the printout has 6 decimals."""
    scene = jb.StickInCircle(R=2.0, ell=1.9)
    state = jnp.asarray(DEFAULT_DEMO_STATE, dtype=jnp.float64)
    t = 0.0
    for k, t_printed, contact_printed, state_printed in _rows(demo):
        state, dt, contact = jb.collide(scene, state)
        t += float(dt)
        assert abs(t_printed - t) <= 5.1e-7, f"collision {k}: printed t = {t_printed}, collide gives {t}"
        assert contact_printed == int(contact)
        np.testing.assert_allclose(state_printed, np.asarray(state), rtol=0, atol=5.1e-7)


def test_demo_prints_the_invariants_and_their_drift(demo):
    x, y, _, vx, vy, w = DEFAULT_DEMO_STATE
    ell = 1.9
    E = 0.5 * (vx**2 + vy**2) + 0.5 * ell**2 * w**2  # M = 1, I = M ell^2
    L = (x * vy - y * vx) + ell**2 * w
    m = re.search(r"energy E = (" + FLOAT + r"), worst relative drift (" + FLOAT + r")", demo)
    assert m, demo
    assert abs(float(m.group(1)) - E) <= 1e-14 * E
    assert 0.0 <= float(m.group(2)) < 1e-12
    m = re.search(r"angular momentum L = (" + FLOAT + r"), worst drift (" + FLOAT + r")", demo)
    assert m, demo
    assert abs(float(m.group(1)) - L) <= 1e-14 * abs(L)
    assert 0.0 <= float(m.group(2)) < 1e-12 * abs(L)


@pytest.mark.parametrize("ell", ["2.5", "2.0", "-0.5", "nan"])
def test_demo_bad_ell_exits_2_naming_ell(ell):
    proc = _run("demo", "-n", "5", f"--ell={ell}")
    assert proc.returncode == 2
    assert re.search(r"\bell\b", proc.stderr), proc.stderr
    assert "Traceback" not in proc.stderr
    assert not _rows(proc.stdout)
    # A scalar parameter is quoted as the number given, not as a list of one.
    assert re.search(rf"got {re.escape(str(float(ell)))}$", proc.stderr.strip()), proc.stderr


def test_version_prints_the_package_version():
    proc = _run("--version")
    assert proc.returncode == 0, proc.stderr
    assert proc.stdout.strip() == f"jaxbill {jb.__version__}"


@pytest.mark.parametrize("option", ["--help", "--version"])
def test_help_and_version_answer_without_loading_jax(option):
    """The command answers ``--help`` and ``--version`` without importing JAX or the library's
    numerical modules (which take about a second): ``import jaxbill`` loads them on first use."""
    probe = (
        "import sys\nfrom jaxbill.cli import main\n"
        f"try:\n    main([{option!r}])\nexcept SystemExit:\n    pass\n"
        "heavy = sorted(m for m in ('jax', 'numpy', 'diffrax', 'equinox', 'matplotlib') if m in sys.modules)\n"
        "print('loaded:', heavy)"
    )
    proc = subprocess.run([sys.executable, "-c", probe], capture_output=True, text=True, timeout=120)
    assert proc.returncode == 0, proc.stderr
    assert proc.stdout.strip().splitlines()[-1] == "loaded: []", proc.stdout[-500:]
    assert "demo" in proc.stdout or "jaxbill" in proc.stdout


def test_no_command_prints_the_help_and_exits_2():
    """Plain ``jaxbill`` runs nothing: it lists the commands and says to choose one."""
    proc = _run()
    assert proc.returncode == 2
    assert not _rows(proc.stdout) and "collisions in" not in proc.stdout
    for command in ("demo", "figures", "explore"):
        assert re.search(rf"^\s+{command}\s", proc.stderr, re.M), proc.stderr
    assert "choose a command" in proc.stderr


def test_demo_non_numeric_ell_is_a_usage_error():
    proc = _run("demo", "--ell", "long")
    assert proc.returncode == 2
    assert "--ell" in proc.stderr
