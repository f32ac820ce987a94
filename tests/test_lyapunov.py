"""Lyapunov spectra by Benettin's repeated QR (jaxbill._analysis.lyapunov).

Tolerance on exponents that should vanish or cancel: ``tol(n) = 2 log(n) / T(n)``
per unit time (``T(n)`` the time of ``n`` collisions), the size of the
finite-time estimate of a zero exponent for a tangent vector growing
polynomially; it shrinks as ``n`` grows, and it is applied at every checkpoint of
the convergence history.
"""

from __future__ import annotations

from typing import ClassVar

import jax
import jax.numpy as jnp
import numpy as np
import pytest

import jaxbill as jb
from jaxbill._analysis.lyapunov import lyapunov_spectrum

N = 20000
# Chaotic orbits (checked: lambda_1 > 0.1 per unit time).
ROTOR = (dict(R=2.0, ell=1.0), [0.1, -0.2, 0.3, 0.6, 0.5, 0.7])
LENS = (dict(R=2.0, ell=1.5, inertia=float("inf")), [0.434, -0.323, -1.554, 0.991, -0.131, 0.0])
CIRCLE = (dict(R=2.0, ell=0.0), [0.1, -0.2, 0.3, 0.6, 0.5, 0.7])


def _tol(n, t):
    return 2.0 * np.log(n) / t


@pytest.fixture(scope="module")
def spectra():
    """Every vector carried (``paired=False``): the pairing and the zeros are measured."""
    out = {}
    for name, (params, s0) in {"rotor": ROTOR, "lens": LENS, "circle": CIRCLE}.items():
        scene = jb.StickInCircle(**params)
        out[name] = (
            scene,
            lyapunov_spectrum(scene, jnp.asarray(s0), N, n_history=10, paired=False),
            lyapunov_spectrum(scene, jnp.asarray(s0), N, per="collision", n_history=10, paired=False),
        )
    return out


@pytest.mark.parametrize("name,size,zeros", [("rotor", 6, 4), ("lens", 4, 2)])
def test_chaotic_spectrum_pairs_and_has_expected_zeros(spectra, name, size, zeros):
    _, sp, _ = spectra[name]
    assert sp.exponents.shape == (size,)
    assert sp.history.shape == (10, size)
    for n, t, est in zip(np.asarray(sp.collisions), np.asarray(sp.times), np.asarray(sp.history)):
        tol = _tol(n, t)
        pairing = est + est[::-1]
        assert np.max(np.abs(pairing)) <= tol, (n, pairing, tol)
        middle = est[1:-1]
        assert middle.size == zeros and np.max(np.abs(middle)) <= tol, (n, middle, tol)
    lam = np.asarray(sp.exponents)
    assert lam[0] > 0.1 and lam[-1] < -0.1
    # The pairing error shrinks as n grows (last checkpoint against the first).
    first, last = np.asarray(sp.history[0]), np.asarray(sp.history[-1])
    assert np.max(np.abs(last + last[::-1])) < np.max(np.abs(first + first[::-1]))


def test_circle_spectrum_is_zero_like_log_n_over_n(spectra):
    _, sp, sc = spectra["circle"]
    hist = np.abs(np.asarray(sp.history))
    times = np.asarray(sp.times)
    bounds = _tol(np.asarray(sp.collisions), times)
    assert np.all(np.max(hist, axis=1) <= bounds)
    # Decay: ten times more collisions, at least five times smaller.
    assert np.max(hist[-1]) < np.max(hist[0]) / 5
    assert np.max(np.abs(np.asarray(sc.exponents))) <= 2 * np.log(N) / N


@pytest.mark.parametrize("name", ["rotor", "lens"])
def test_per_time_and_per_collision_agree_through_mean_collision_rate(spectra, name):
    _, per_time, per_coll = spectra[name]
    mean_flight = float(per_time.time) / N
    assert per_coll.exponents.shape[0] == per_time.exponents.shape[0] - 1
    lam_time = np.asarray(per_time.exponents)
    lam_coll = np.asarray(per_coll.exponents)
    np.testing.assert_allclose(lam_coll[0], lam_time[0] * mean_flight, rtol=1e-3)
    np.testing.assert_allclose(lam_coll[-1], lam_time[-1] * mean_flight, rtol=1e-3)
    # The section map's spectrum pairs as well.
    assert np.max(np.abs(lam_coll + lam_coll[::-1])) <= 2 * np.log(N) / N


@pytest.mark.parametrize("per", ["time", "collision"])
@pytest.mark.parametrize("name,params_and_start", [("rotor", ROTOR), ("lens", LENS)])
def test_paired_spectrum_agrees_with_the_full_run_as_far_as_the_run_has_converged(spectra, name, params_and_start, per):
    """``paired=True`` assumes the pairing the full run measures: at every checkpoint the two
    spectra agree within tol(n), the size of a finite-time estimate of a zero exponent (per
    collision ``2 log(n) / n``; a wrong mirror would miss by about 2 lambda, a lost middle zero
    by lambda); the orbit is the same to the bit (the vectors never touch it)."""
    scene, per_time, per_collision = spectra[name]
    full = per_time if per == "time" else per_collision
    paired = lyapunov_spectrum(scene, jnp.asarray(params_and_start[1]), N, per=per, n_history=10, paired=True)
    assert paired.exponents.shape == full.exponents.shape and paired.history.shape == full.history.shape
    np.testing.assert_array_equal(np.asarray(paired.times), np.asarray(full.times))
    for n, t, a, b in zip(
        np.asarray(full.collisions), np.asarray(full.times), np.asarray(paired.history), np.asarray(full.history)
    ):
        assert np.max(np.abs(a - b)) <= _tol(n, t if per == "time" else n), (n, a, b)
    assert np.all(np.diff(np.asarray(paired.exponents)) <= 0)


class WithLosses(jb.StickInCircle):
    """A stick in a circle that does not claim a symplectic flow (as one with losses would not)."""

    symplectic_flow: ClassVar[bool] = False


def test_paired_spectrum_refuses_what_does_not_pair():
    s = jnp.asarray(ROTOR[1])
    with pytest.raises(ValueError, match="symplectic"):
        lyapunov_spectrum(WithLosses(R=2.0, ell=1.0), s, 10, paired=True)
    with pytest.raises(ValueError, match="paired must be True, False or None"):
        lyapunov_spectrum(jb.StickInCircle(R=2.0, ell=1.0), s, 10, paired="yes")


@pytest.mark.parametrize("per", ["time", "collision"])
def test_by_default_the_scene_decides_whether_the_spectrum_is_paired(per):
    """``paired=None`` (the default) pairs where the scene declares a symplectic flow, and carries every
    vector where it does not: the same program, to the bit, as the explicit choice."""
    s = jnp.asarray(ROTOR[1])
    exponents = {}
    for scene, expected in ((jb.StickInCircle(**ROTOR[0]), True), (WithLosses(**ROTOR[0]), False)):
        default = lyapunov_spectrum(scene, s, 20, per=per, n_history=2)
        chosen = lyapunov_spectrum(scene, s, 20, per=per, n_history=2, paired=expected)
        assert default.paired is expected and chosen.paired is expected
        np.testing.assert_array_equal(np.asarray(default.history), np.asarray(chosen.history))
        exponents[expected] = np.asarray(default.exponents)
    # A paired spectrum's lower half is its upper half mirrored, exactly; a full one's is measured.
    paired, full = exponents[True], exponents[False]
    half = paired.size // 2
    np.testing.assert_array_equal(paired[::-1][:half], -paired[:half])
    assert np.all(full[::-1][:half] != -full[:half])


def test_batch_and_vmap_agree_with_single_runs():
    """Short runs. On a CPU (no FMA: ``jaxbill._engine.backend``) the batched orbits are the single ones
    bit for bit; only the QR factorisations of a batch of frames and of one frame round differently,
    which moves the exponents by a few ulps (measured 3.5e-16 after 20 collisions). Where the compiler
    may contract multiply-adds differently in the two programs (a GPU), the orbits differ by an ulp,
    which chaos amplifies by about exp(0.75 per collision)."""
    scene = jb.StickInCircle(R=2.0, ell=1.0)
    states = jnp.asarray([ROTOR[1], [0.2, 0.1, -1.0, -0.3, 0.8, -0.4], [-0.3, 0.2, 2.0, 0.5, 0.5, 0.1]])
    n = 20
    batch = lyapunov_spectrum(scene, states, n, n_history=4)
    vmapped = jax.jit(jax.vmap(lambda s: lyapunov_spectrum(scene, s, n, n_history=4).exponents))(states)
    assert batch.exponents.shape == (3, 6) and batch.history.shape == (3, 4, 6)
    without_fma = jax.default_backend() == "cpu" and jb.backend_settings()["small_loops"].startswith("set")
    rtol, atol = (0.0, 1e-13) if without_fma else (1e-6, 1e-9)
    for k in range(3):
        single = lyapunov_spectrum(scene, states[k], n, n_history=4)
        np.testing.assert_allclose(batch.exponents[k], single.exponents, rtol=rtol, atol=atol)
        np.testing.assert_allclose(vmapped[k], single.exponents, rtol=rtol, atol=atol)


def test_qr_every_k_gives_the_same_exponents():
    scene = jb.StickInCircle(**ROTOR[0])
    a = lyapunov_spectrum(scene, jnp.asarray(ROTOR[1]), 1000)
    b = lyapunov_spectrum(scene, jnp.asarray(ROTOR[1]), 1000, qr_every=5)
    np.testing.assert_allclose(a.exponents, b.exponents, rtol=1e-8, atol=1e-10)


def test_memory_does_not_grow_with_n():
    from jaxbill._analysis.lyapunov import _initial_vectors, _spectrum

    scene = jb.StickInCircle(**ROTOR[0])
    frame = _initial_vectors(6, 6)
    sizes = []
    run = jax.jit(_spectrum, static_argnums=(2, 3, 4, 5))
    for n in (1000, 100000):
        compiled = run.lower(scene, jnp.asarray(ROTOR[1]), n, "time", 1, 10, frame).compile()
        analysis = compiled.memory_analysis()
        if analysis is None:
            pytest.skip("no memory analysis on this backend")
        sizes.append(analysis.temp_size_in_bytes + analysis.output_size_in_bytes)
    assert sizes[0] == sizes[1]


def test_bad_arguments():
    scene = jb.StickInCircle(R=2.0, ell=1.0)
    s = jnp.asarray(ROTOR[1])
    with pytest.raises(ValueError, match="per"):
        lyapunov_spectrum(scene, s, 10, per="orbit")
    with pytest.raises(ValueError, match="multiple"):
        lyapunov_spectrum(scene, s, 10, qr_every=3)
    with pytest.raises(ValueError, match="outside"):
        lyapunov_spectrum(scene, jnp.asarray([1.9, 0, 0, 1, 0, 0]), 10)


def test_the_frame_is_orthonormalised_as_lapack_does():
    """The QR written out (modified Gram-Schmidt, twice) against numpy's LAPACK QR: the same ``Q`` and
    ``|diag R|`` to rounding, on a random frame and on one whose columns are nearly parallel."""
    from jaxbill._analysis.lyapunov import _orthonormalised

    rng = np.random.default_rng(4)
    random = rng.standard_normal((6, 6))
    nearly_parallel = np.outer(rng.standard_normal(6), np.ones(4)) + 1e-9 * rng.standard_normal((6, 4))
    for frame in (random, nearly_parallel):
        q, diag = (np.asarray(a) for a in _orthonormalised(jnp.asarray(frame)))
        q_ref, r_ref = np.linalg.qr(frame)
        signs = np.sign(np.diag(r_ref))
        np.testing.assert_allclose(diag, np.abs(np.diag(r_ref)), rtol=1e-6 if frame is nearly_parallel else 1e-13)
        np.testing.assert_allclose(q, q_ref * signs, atol=1e-6 if frame is nearly_parallel else 1e-13)
        np.testing.assert_allclose(q.T @ q, np.eye(frame.shape[1]), atol=1e-15)


@pytest.mark.parametrize("paired", [False, True])
@pytest.mark.parametrize("name", ["rotor", "lens", "walls"])
def test_a_batch_gives_each_orbit_its_spectrum_alone(name, paired):
    """Orbit by orbit, a batch's spectrum is the orbit's alone: bitwise where the scene's orbits run one
    after another (``batch_chunk == 1``: the walls), to rounding where they run vectorised."""
    if name == "walls":
        scene = jb.StickBetweenWalls2D(h=3.0, ell=1.0)
        start = jnp.asarray([0.0, 1.5, 0.3, 0.4, 0.9, 1.1])
    else:
        params, s0 = {"rotor": ROTOR, "lens": LENS}[name]
        scene, start = jb.StickInCircle(**params), jnp.asarray(s0)
    states = jnp.concatenate([start[None], jnp.asarray(jb.orbit(scene, start, 3).state)])
    batch = np.asarray(lyapunov_spectrum(scene, states, 300, paired=paired).exponents)
    alone = np.stack([np.asarray(lyapunov_spectrum(scene, s, 300, paired=paired).exponents) for s in states])
    if scene.batch_chunk == 1:
        np.testing.assert_array_equal(batch, alone)
    else:
        np.testing.assert_allclose(batch, alone, rtol=0, atol=1e-13)


def test_growth_past_float64s_range_keeps_its_log():
    """A growth multiplied up by ``grown`` (what the spectrum and FTLE carry between logs) has the log
    of the exact product, here 1e1200 / 1e600 * 3, which float64 cannot hold: the sum of the logs."""
    from jaxbill._analysis.lyapunov import grown, log_of, no_growth

    factors = [1e300] * 4 + [1e-300] * 2 + [3.0, 0.25]
    growth = no_growth()
    for factor in factors:
        growth = grown(growth, jnp.asarray(factor))
    expected = sum(np.log(factors))  # 600 ln 10 + ln 0.75
    np.testing.assert_allclose(float(log_of(growth)), expected, rtol=1e-15)
    assert np.sum(np.log10(factors[:4])) > np.log10(np.finfo(np.float64).max)  # a plain product overflows


@pytest.mark.parametrize("k", range(1, 8))
def test_exponents_are_ordered_as_numpy_sorts_them(k):
    """The compare-and-swap sort of the exponents and history against numpy's sort, largest first and NaN
    last: with ties, signed zeros, infinities and NaNs (a poisoned orbit), for every length a scene has."""
    from jaxbill._analysis.lyapunov import _descending

    rng = np.random.default_rng(k)
    values = rng.standard_normal((400, k))
    for special, share in ((np.nan, 0.1), (0.0, 0.1), (-0.0, 0.05), (1.0, 0.1), (np.inf, 0.05), (-np.inf, 0.05)):
        values[rng.random(values.shape) < share] = special
    got = np.asarray(_descending(jnp.asarray(values)))
    expected = -np.sort(-values, axis=-1, kind="stable")  # NaN last; ties (0.0, -0.0) kept in order
    np.testing.assert_array_equal(got, expected)
    numbers = ~np.isnan(expected)  # a NaN's sign means nothing
    np.testing.assert_array_equal(np.signbit(got)[numbers], np.signbit(expected)[numbers])
