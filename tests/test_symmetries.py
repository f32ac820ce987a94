"""Symmetries of the collision map: time reversal, rotation, reflection, and
the agreement of vectorized (vmap / batched) runs with single runs.

Reference values come from the symmetry itself: a forward orbit and its
transformed image must coincide; nothing is compared with a stored output.

Tolerances and horizons. A run commits ~1 ulp (~1e-16) of rounding per
operation; an exact symmetry is broken only by that rounding, amplified by the
dynamics. We compare orbits only over a horizon ``n`` short enough that the
dynamics has amplified a ``1e-14`` relative perturbation of the initial state
by at most ``1e4`` (``_assert_horizon_is_short`` checks this for every state
used, with two forward runs), so the rounding of ``n`` collisions can reach
at most ~``n * 1e-16 * 1e4 <~ 1e-10``; we then require agreement to
``TOL = 1e-9`` (positions in units of R, angles in radians, times in units of
the mean flight time). A wrong symmetry (a missed, extra or misplaced
collision) gives errors of order 1. The horizons: 20 collisions for the
near-regular ``ell = 1.9`` rotor, the lens at ``ell = 1.5`` and the circle;
fewer for the chaotic ``ell = 1.0`` and ``0.5`` rotors.
"""

from __future__ import annotations

import json
import math
import os
import subprocess
import sys
import textwrap

import jax
import jax.numpy as jnp
import numpy as np
import pytest

import jaxbill as jb
from helpers import (
    config_error,
    kind_of,
    make_scene,
    mirror_state,
    random_state,
    random_states,
    rotate_state,
)

R = 2.0
N = 20  # every orbit in this file has this length (one compile per scene kind)
TOL = 1e-9
INF = float("inf")

# (ell, inertia, horizon, seed)
CASES = [
    (1.9, None, 20, 1),
    (1.9, None, 20, 2),
    (1.0, None, 6, 3),
    (0.5, None, 5, 4),
    (1.0, 0.01, 8, 5),
    (1.5, INF, 20, 6),
    (1.0, INF, 10, 7),
    (0.0, None, 20, 8),
]
IDS = [f"ell={c[0]}-I={c[1]}-n={c[2]}-seed={c[3]}" for c in CASES]


def _setup(ell, inertia, seed):
    scene = make_scene(R, ell, 1.0, inertia)
    state0 = random_state(np.random.default_rng(seed), R, ell, kind_of(ell, inertia))
    return scene, state0


def _run(scene, state0):
    orb = jb.orbit(scene, jnp.asarray(state0), N)
    return np.asarray(orb.t), np.asarray(orb.contact), np.asarray(orb.state)


def _assert_horizon_is_short(scene, state0, horizon):
    """Two forward runs ``1e-14`` (relative) apart stay within ``1e-10`` for ``horizon`` collisions."""
    perturbed = state0 * (1.0 + 1e-14 * np.array([1.0, -1.0, 1.0, -1.0, 1.0, 1.0]))
    _, k1, s1 = _run(scene, state0)
    _, k2, s2 = _run(scene, perturbed)
    div = config_error(s1[:horizon], s2[:horizon], R)
    assert np.array_equal(k1[:horizon], k2[:horizon]) and div.max() < 1e-10, (
        f"horizon {horizon} too long for this state: divergence {div.max():.3g}"
    )


def _velocity_scale(state):
    return max(math.hypot(state[3], state[4]), 1e-300)


# ---------------------------------------------------------------------------
# (a) time reversal
# ---------------------------------------------------------------------------
@pytest.mark.parametrize("ell, inertia, n, seed", CASES, ids=IDS)
def test_time_reversal_retraces_the_orbit(ell, inertia, n, seed):
    scene, state0 = _setup(ell, inertia, seed)
    _assert_horizon_is_short(scene, state0, n)
    t, k, s = _run(scene, state0)
    assert np.all(k[:n] != 0)
    # fly to the middle of the flight after collision n, then reverse v and omega
    _, dt_next, k_next = jb.collide(scene, jnp.asarray(s[n - 1]))
    dt_next = float(dt_next)
    assert int(k_next) != 0 and np.isfinite(dt_next)
    mid = np.asarray(scene.flight(jnp.asarray(s[n - 1]), dt_next / 2))
    back0 = mid.copy()
    back0[3:6] *= -1.0
    tb, kb, sb = _run(scene, back0)

    flight = t[n - 1] / n  # mean flight time: the unit of time errors
    # backward collision j (0-based) is forward collision n-1-j
    fwd = s[:n][::-1]
    t_expected = dt_next / 2 + (t[n - 1] - t[:n][::-1])
    np.testing.assert_array_equal(kb[:n], k[:n][::-1], err_msg="contacts do not retrace")
    time_err = np.max(np.abs(tb[:n] - t_expected)) / flight
    assert time_err < TOL, f"collision times do not retrace: {time_err:.3g}"
    cfg_err = config_error(sb[:n], fwd, R).max()
    assert cfg_err < TOL, f"configurations do not retrace: {cfg_err:.3g}"
    # velocities just after backward collision j = minus those just before
    # forward collision n-1-j = minus those just after forward collision n-2-j
    before = np.concatenate([state0[None], s[: n - 1]])[::-1]
    v_scale = _velocity_scale(state0)
    v_err = np.max(np.abs(sb[:n, 3:5] + before[:, 3:5])) / v_scale
    w_scale = max(np.max(np.abs(s[:n, 5])), np.abs(state0[5]), v_scale / R)
    w_err = np.max(np.abs(sb[:n, 5] + before[:, 5])) / w_scale
    assert v_err < TOL and w_err < TOL, f"velocities do not retrace: v {v_err:.3g}, omega {w_err:.3g}"
    # and after the last backward collision the stick flies back to state0
    home = np.asarray(scene.flight(jnp.asarray(sb[n - 1]), (dt_next / 2 + t[n - 1]) - tb[n - 1]))
    assert config_error(home, state0, R) < TOL
    assert np.max(np.abs(home[3:5] + state0[3:5])) / v_scale < TOL


# ---------------------------------------------------------------------------
# (b) rotation and (c) reflection
# ---------------------------------------------------------------------------
def _compare_images(scene, state0, image0, n, transform):
    t, k, s = _run(scene, state0)
    ti, ki, si = _run(scene, image0)
    np.testing.assert_array_equal(ki[:n], k[:n], err_msg="contacts differ")
    flight = t[n - 1] / n
    assert np.max(np.abs(ti[:n] - t[:n])) / flight < TOL, "collision times differ"
    expected = transform(s[:n])
    assert config_error(si[:n], expected, R).max() < TOL, "configurations differ"
    v_scale = _velocity_scale(state0)
    assert np.max(np.abs(si[:n, 3:5] - expected[:, 3:5])) / v_scale < TOL
    w_scale = max(np.max(np.abs(s[:n, 5])), v_scale / R)
    assert np.max(np.abs(si[:n, 5] - expected[:, 5])) / w_scale < TOL


@pytest.mark.parametrize("theta", [0.7, math.pi / 2, -2.9])
@pytest.mark.parametrize("ell, inertia, n, seed", CASES, ids=IDS)
def test_rotation_rotates_the_orbit(ell, inertia, n, seed, theta):
    scene, state0 = _setup(ell, inertia, seed)
    _assert_horizon_is_short(scene, state0, n)
    _compare_images(scene, state0, rotate_state(state0, theta), n, lambda s: rotate_state(s, theta))


@pytest.mark.parametrize("ell, inertia, n, seed", CASES, ids=IDS)
def test_reflection_mirrors_the_orbit(ell, inertia, n, seed):
    scene, state0 = _setup(ell, inertia, seed)
    _assert_horizon_is_short(scene, state0, n)
    _compare_images(scene, state0, mirror_state(state0), n, mirror_state)


# ---------------------------------------------------------------------------
# (d) vmap and batched orbits equal single runs
# ---------------------------------------------------------------------------
N_VMAP = 200
VMAP_CASES = [(1.9, None), (1.0, None), (1.0, INF), (0.0, None)]


@pytest.mark.parametrize("ell, inertia", VMAP_CASES)
def test_vmap_and_batch_equal_single_runs(ell, inertia):
    """On a CPU, with the settings ``import jaxbill`` makes (no FMA, ``jaxbill._engine.backend``), the
    scalar and the vectorized programs round alike: every orbit is bitwise the single run. Where the
    compiler may contract multiply-adds differently in the two programs (a GPU), agreement is to
    rounding at first, and the contact sequences are identical for as long as the orbits are still
    the same orbit (configurations within 1e-6; beyond that chaos has amplified the ulps and they
    legitimately part)."""
    scene = make_scene(R, ell, 1.0, inertia)
    states = random_states(np.random.default_rng(20), 3, R, ell, kind_of(ell, inertia))
    vm = jax.vmap(jb.orbit, in_axes=(None, 0, None))(scene, jnp.asarray(states), N_VMAP)
    bt = jb.orbit(scene, jnp.asarray(states), N_VMAP)
    bitwise = jax.default_backend() == "cpu" and jb.backend_settings()["small_loops"].startswith("set")
    for b in range(len(states)):
        one = jb.orbit(scene, jnp.asarray(states[b]), N_VMAP)
        for name, other in (("vmap", vm), ("batched", bt)):
            s1, s2 = np.asarray(one.state), np.asarray(other.state[b])
            t1, t2 = np.asarray(one.t), np.asarray(other.t[b])
            assert s2.shape == (N_VMAP, 6) and t2.shape == (N_VMAP,)
            if bitwise:
                np.testing.assert_array_equal(s2, s1, err_msg=f"{name}: states differ from the single run")
                np.testing.assert_array_equal(t2, t1, err_msg=f"{name}: times differ from the single run")
                np.testing.assert_array_equal(np.asarray(other.contact[b]), np.asarray(one.contact), err_msg=name)
                continue
            first = slice(0, 5)
            assert np.max(np.abs(s1[first] - s2[first])) <= 1e-12 * max(R, np.max(np.abs(s1[first])))
            assert np.max(np.abs(t1[first] - t2[first])) <= 1e-12 * t1[4]
            same = np.maximum.accumulate(config_error(s1, s2, R)) < 1e-6
            assert same[:5].all()
            np.testing.assert_array_equal(
                np.asarray(one.contact)[same],
                np.asarray(other.contact[b])[same],
                err_msg=f"{name}: contacts differ while the orbits still agree",
            )


_AVX_SCRIPT = textwrap.dedent(
    """
    import json, sys
    import numpy as np
    import jax, jax.numpy as jnp
    import jaxbill as jb
    sys.path.insert(0, sys.argv[1])
    from helpers import random_states, kind_of
    out = {}
    for ell, inertia in [(1.9, None), (1.0, float("inf")), (0.0, None)]:
        scene = jb.StickInCircle(R=2.0, ell=ell, inertia=inertia)
        states = jnp.asarray(random_states(np.random.default_rng(21), 3, 2.0, ell, kind_of(ell, inertia)))
        vm = jax.vmap(jb.orbit, in_axes=(None, 0, None))(scene, states, 200)
        bt = jb.orbit(scene, states, 200)
        res = []
        for b in range(3):
            one = jb.orbit(scene, states[b], 200)
            for other in (vm, bt):
                res.append(bool(
                    np.array_equal(np.asarray(one.state), np.asarray(other.state[b]))
                    and np.array_equal(np.asarray(one.t), np.asarray(other.t[b]))
                    and np.array_equal(np.asarray(one.contact), np.asarray(other.contact[b]))
                    and np.all(np.asarray(one.contact) != 0)
                ))
        out[scene.kind] = res
    # (e) batched scenes too
    ells = np.array([0.5, 1.0, 1.5, 1.9])
    scenes = jb.StickInCircle(R=2.0, ell=jnp.asarray(ells))
    st = jnp.asarray(np.stack([random_states(np.random.default_rng(22 + i), 1, 2.0, e, "rotor")[0]
                               for i, e in enumerate(ells)]))
    ns, dt, k = jax.vmap(jb.collide, in_axes=(0, 0))(scenes, st)
    res = []
    for i, e in enumerate(ells):
        a, b, c = jb.collide(jb.StickInCircle(R=2.0, ell=float(e)), st[i])
        res.append(bool(np.array_equal(np.asarray(a), np.asarray(ns[i])) and float(b) == float(dt[i])
                        and int(c) == int(k[i])))
    out["scenes"] = res
    print("RESULT" + json.dumps(out))
    """
)


def test_vmap_and_batch_bitwise_equal_single_runs_without_fma_differences():
    """With the user's own ``XLA_FLAGS=--xla_cpu_max_isa=AVX`` (no FMA on CPU; jaxbill then leaves the
    flags alone) the vectorized and the scalar programs round identically: 200 collisions bitwise equal."""
    env = dict(os.environ)
    env["XLA_FLAGS"] = (env.get("XLA_FLAGS", "") + " --xla_cpu_max_isa=AVX").strip()
    env["JAX_PLATFORMS"] = "cpu"
    here = os.path.dirname(os.path.abspath(__file__))
    proc = subprocess.run(
        [sys.executable, "-c", _AVX_SCRIPT, here], env=env, capture_output=True, text=True, timeout=300
    )
    assert proc.returncode == 0, proc.stderr[-3000:]
    line = next(ln for ln in proc.stdout.splitlines() if ln.startswith("RESULT"))
    out = json.loads(line[len("RESULT") :])
    for kind in ("rotor", "lens", "circle"):
        assert out[kind] == [True] * 6, f"{kind}: vmap/batched vs single not bitwise equal: {out[kind]}"
    assert out["scenes"] == [True] * 4, out["scenes"]


# ---------------------------------------------------------------------------
# (e) vmap over a batch of scenes
# ---------------------------------------------------------------------------
@pytest.mark.parametrize(
    "make_batch, make_single, kind",
    [
        (lambda e: jb.StickInCircle(R=2.0, ell=jnp.asarray(e)), lambda e: jb.StickInCircle(R=2.0, ell=e), "rotor"),
        (
            lambda e: jb.StickInCircle(R=2.0, ell=jnp.asarray(e), mass=2.0, inertia=jnp.asarray(e) ** 2 / 100),
            lambda e: jb.StickInCircle(R=2.0, ell=e, mass=2.0, inertia=e**2 / 100),
            "rotor",
        ),
        (
            lambda e: jb.StickInCircle(R=2.0, ell=jnp.asarray(e), inertia=INF),
            lambda e: jb.StickInCircle(R=2.0, ell=e, inertia=INF),
            "lens",
        ),
    ],
    ids=["rotor-default", "rotor-I/100", "lens"],
)
def test_vmap_over_batched_scene_parameters(make_batch, make_single, kind):
    ells = np.array([0.5, 1.0, 1.5, 1.9])
    scenes = make_batch(ells)
    assert scenes.kind == kind and scenes.ell.shape == (4,) and scenes.R.shape == (4,)
    rng = np.random.default_rng(23)
    states = np.stack([random_state(rng, R, e, kind) for e in ells])
    new, dt, contact = jax.vmap(jb.collide, in_axes=(0, 0))(scenes, jnp.asarray(states))
    for i, e in enumerate(ells):
        s1, dt1, c1 = jb.collide(make_single(float(e)), jnp.asarray(states[i]))
        assert int(c1) == int(contact[i]) != 0
        assert abs(float(dt1) - float(dt[i])) <= 1e-12 * float(dt1)
        np.testing.assert_allclose(np.asarray(new[i]), np.asarray(s1), rtol=0, atol=1e-12 * R)
    # and the different ell really gave different collisions (not one scene broadcast)
    assert len({round(float(d), 12) for d in dt}) == 4
