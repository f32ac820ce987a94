"""Chaos indicators over a batch (jaxbill._analysis.chaos)."""

from __future__ import annotations

import jax
import jax.numpy as jnp
import numpy as np
import pytest

import jaxbill as jb
from jaxbill._analysis.chaos import chaos_threshold, chaotic_fraction, finite_time_lyapunov, sample_energy_shell
from jaxbill._analysis.lyapunov import lyapunov_spectrum


@pytest.mark.parametrize(
    "params,L",
    [
        (dict(R=2.0, ell=1.0), 0.3),
        (dict(R=2.0, ell=1.9, inertia=0.0361), 0.0),
        (dict(R=2.0, ell=1.0), None),
        (dict(R=2.0, ell=1.5, inertia=float("inf")), None),
        (dict(R=2.0, ell=0.0), None),
    ],
)
def test_shell_samples_have_the_energy_and_momentum_asked_for(params, L):
    scene = jb.StickInCircle(**params)
    states, weights = sample_energy_shell(scene, 500, energy=0.7, angular_momentum=L, seed=4)
    assert states.shape == (500, 6) and weights.shape == (500,)
    np.testing.assert_allclose(np.asarray(jb.energy(scene, states)), 0.7, rtol=1e-12)
    if L is not None:
        np.testing.assert_allclose(np.asarray(jb.angular_momentum(scene, states)), L, atol=1e-12)
    assert np.all(np.asarray(scene.gaps(jnp.asarray(states))) > 0)
    assert np.all(weights > 0) and abs(weights.mean() - 1) < 1e-12


def test_shell_weights_give_the_microcanonical_measure():
    """Weighted averages over the (E, L) shell sample match brute-force rejection
    sampling of thin shells |H - E| < d, |L - L0| < d from uniform momenta."""
    scene = jb.StickInCircle(R=2.0, ell=1.0)  # M = 1, I = 1
    E, L0 = 0.5, 0.3
    states, weights = sample_energy_shell(scene, 40000, energy=E, angular_momentum=L0, seed=5)
    r2 = states[:, 0] ** 2 + states[:, 1] ** 2
    spin2 = states[:, 5] ** 2
    weighted = [np.average(r2, weights=weights), np.average(spin2, weights=weights)]
    rng = np.random.default_rng(6)
    accepted = []
    d = 0.02
    for _ in range(8):
        m = 2_000_000
        c = rng.uniform(-2, 2, (m, 2))
        a = rng.uniform(-np.pi, np.pi, m)
        u = np.stack([np.cos(a), np.sin(a)], 1)
        inside = np.maximum(np.linalg.norm(c + u, axis=1), np.linalg.norm(c - u, axis=1)) < 2.0
        p = rng.uniform(-1.03, 1.03, (m, 3))
        h = 0.5 * np.sum(p * p, axis=1)
        ang = c[:, 0] * p[:, 1] - c[:, 1] * p[:, 0] + p[:, 2]
        keep = inside & (np.abs(h - E) < d) & (np.abs(ang - L0) < d)
        accepted.append(np.column_stack([np.sum(c[keep] ** 2, axis=1), p[keep, 2] ** 2]))
    brute = np.concatenate(accepted)
    assert len(brute) > 2000
    means, errors = brute.mean(axis=0), brute.std(axis=0) / np.sqrt(len(brute))
    for w, m, e in zip(weighted, means, errors):
        assert abs(w - m) < 4 * e + 0.01 * abs(m), (w, m, e)
    # The weights matter: unweighted averages are measurably off.
    assert abs(np.mean(r2) - means[0]) > 4 * errors[0]


def test_finite_time_exponent_matches_spectrum_and_fractions():
    scene = jb.StickInCircle(R=2.0, ell=1.0)
    s = jnp.asarray([[0.1, -0.2, 0.3, 0.6, 0.5, 0.7]])
    ftle = finite_time_lyapunov(scene, s, 4000)
    spec = lyapunov_spectrum(scene, s[0], 4000)
    # On a CPU where jaxbill compiles without FMA the batched orbit is the single one, bit for bit, and the
    # two estimates of the leading exponent differ only as estimators: one vector's growth against the
    # first QR diagonal, 1.2e-4 apart after 4000 collisions (the start vector's transient). Where the
    # compiler contracts multiply-adds (a GPU), the two orbits part after ~50 collisions: the same
    # statistics, not the same orbit.
    without_fma = jax.default_backend() == "cpu" and jb.backend_settings()["small_loops"].startswith("set")
    rtol = 1e-3 if without_fma else 2e-2
    np.testing.assert_allclose(float(ftle.per_time[0]), float(spec.exponents[0]), rtol=rtol)
    np.testing.assert_allclose(
        float(ftle.per_collision[0]), float(ftle.per_time[0]) * float(ftle.time[0]) / 4000, rtol=1e-12
    )
    # A short stick is chaotic everywhere; the circle nowhere.
    n = 400
    chaotic = jb.StickInCircle(R=2.0, ell=0.5)
    states, weights = sample_energy_shell(chaotic, 24, angular_momentum=0.0, seed=1)
    assert chaotic_fraction(finite_time_lyapunov(chaotic, states, n).per_collision, weights, n=n) == 1.0
    circle = jb.StickInCircle(R=2.0, ell=0.0)
    states, _ = sample_energy_shell(circle, 24, seed=1)
    e = np.asarray(finite_time_lyapunov(circle, states, n).per_collision)
    assert chaotic_fraction(e, n=n) == 0.0 and np.all(e < np.log(n) / n * 2)


def test_chaotic_fraction_weights_and_threshold():
    e = np.array([0.0, 0.5, 1.0, np.nan])
    assert chaotic_fraction(e, threshold=0.4) == pytest.approx(2 / 3)
    assert chaotic_fraction(e, np.array([3.0, 1.0, 0.0, 1.0]), threshold=0.4) == pytest.approx(0.25)
    assert chaos_threshold(1000) == pytest.approx(5 * np.log(1000) / 1000)
    with pytest.raises(ValueError, match="threshold"):
        chaotic_fraction(e)
