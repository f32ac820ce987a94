"""The analyses on compositions: what a body in a table adds to the contract every scene keeps.

The catalogue's compositions (points, a dumbbell of unequal masses, rigid
polygons, the coin; circles, ellipses, stadiums, polygons, the strip and a
user's convex function) already go through ``test_scene_contract.py`` (drivers,
kernels, tangent maps, sampler, section charts, bad input). Here: which of them
compile closed forms, Lyapunov spectra, MEGNO, the FLI map in the kernel, the
sampler at fixed angular momentum, the Birkhoff map's area and the periodic-orbit
search. Each test asserts a property that holds independently of the code under
test: the pairing of a symplectic flow's exponents, MEGNO's limits on regular and
chaotic orbits, the Birkhoff map's unit determinant, closed-form stability of a
billiard's periodic orbits.
"""

from __future__ import annotations

import jax
import jax.numpy as jnp
import numpy as np
import pytest

import jaxbill as jb
from scene_catalogue import compositions, squircle

SCENES = compositions()


@pytest.fixture(scope="module")
def starts():
    """Eight Liouville starts on the energy shell ``E = 1/2`` per composition."""
    return {name: jb.sample_energy_shell(scene, 8, seed=3)[0] for name, scene in SCENES.items()}


def test_closed_forms_compile_no_root_search():
    """A point or a body that never turns in a table of discs, ellipses, half-planes and capsules has
    closed-form contact times; a turning body, or any body in a user's table, searches."""
    assert not SCENES["point in stadium"].searches_for_roots
    assert not SCENES["point in pentagon"].searches_for_roots
    assert not SCENES["static triangle in pentagon"].searches_for_roots
    assert SCENES["triangle in stadium"].searches_for_roots
    assert jb.BodyInTable(jb.PointBody(), jb.ConvexTable(squircle, (-1.2, 1.2, -1.2, 1.2))).searches_for_roots


@pytest.mark.parametrize("name", ["triangle in stadium", "dumbbell 1:3 in ellipse", "point in stadium"])
def test_lyapunov_spectra_pair_and_the_stadium_is_chaotic(name, starts):
    """A symplectic flow's exponents come in pairs ``lambda, -lambda``; the flow direction and the energy
    give two zeros. The point in Bunimovich's stadium is chaotic: its largest exponent is positive."""
    scene = SCENES[name]
    spectrum = jb.lyapunov_spectrum(scene, starts[name][:2], 400, paired=False)
    exponents = np.asarray(spectrum.exponents)
    k = exponents.shape[-1]
    pairs = exponents + exponents[..., ::-1]
    scale = np.max(np.abs(exponents))
    assert np.all(np.abs(pairs) < 0.05 * scale), exponents
    middle = np.sort(np.abs(exponents), axis=-1)[..., :2]
    assert np.all(middle < 0.05 * scale), exponents
    assert k == len(scene.dynamical_indices)
    assert np.all(exponents[..., 0] > 0.1 * scale)


def test_megno_tells_the_regular_ellipse_from_the_chaotic_stadium():
    """MEGNO tends to 2 for a quasi-periodic orbit (a point in an ellipse is integrable) and grows without
    bound on a chaotic one (a point in the stadium)."""
    ellipse = jb.BodyInTable(jb.PointBody(), jb.Ellipse(2.0, 1.2))
    regular, _ = jb.sample_energy_shell(ellipse, 4, seed=5)
    chaotic, _ = jb.sample_energy_shell(SCENES["point in stadium"], 4, seed=5)
    y_regular = np.asarray(jb.megno(ellipse, regular, 2000).value)
    y_chaotic = np.asarray(jb.megno(SCENES["point in stadium"], chaotic, 2000).value)
    assert np.all(np.abs(y_regular - 2.0) < 0.5), y_regular
    assert np.all(y_chaotic > 10.0), y_chaotic


def test_fli_map_through_the_kernel_equals_autodiff():
    """The FLI carried inside the Pallas kernel equals autodiff's, pixel by pixel, on a composition."""
    scene = SCENES["point in stadium"]
    grid = np.asarray(jb.sample_energy_shell(scene, 12, seed=8)[0]).reshape(3, 4, 6)
    kernel = jb.fli_map(scene, grid, 20, driver="pallas")
    autodiff = jb.fli_map(scene, grid, 20, driver="autodiff")
    np.testing.assert_allclose(kernel, autodiff, rtol=1e-9, atol=1e-9)


def test_the_sampler_pins_the_angular_momentum_in_a_circle():
    scene = SCENES["square in circle"]
    states, weights = jb.sample_energy_shell(scene, 50, angular_momentum=0.3, seed=2)
    np.testing.assert_allclose(np.asarray(jb.angular_momentum(scene, states)), 0.3, rtol=1e-12, atol=1e-14)
    np.testing.assert_allclose(np.asarray(jb.energy(scene, states)), 0.5, rtol=1e-14)
    assert np.all(weights > 0)
    with pytest.raises(ValueError, match="angular_momentum"):
        jb.sample_energy_shell(SCENES["triangle in stadium"], 5, angular_momentum=0.3)


@pytest.mark.parametrize("name", ["point in stadium", "point in pentagon"])
def test_birkhoff_map_preserves_area_for_a_point(name):
    """For a point particle the Birkhoff coordinates ``(s, p)`` are canonical: the collision map's Jacobian in
    them has determinant 1."""
    scene = SCENES[name]
    point = jnp.array([0.7, 0.31])

    def section_map(xy):
        state = scene.section_state(xy)
        new_state, _, contact = jb.collide(scene, state)
        return scene.section(new_state, contact)

    jacobian = jax.jacfwd(section_map)(point)
    assert abs(float(jnp.linalg.det(jacobian)) - 1.0) < 1e-9


def test_periodic_orbits_of_the_stadium_have_their_closed_form_stability():
    """The bounce across the flat sides is parabolic (trace 2); the bounce along the long axis, between two
    mirrors of radius r a distance D = 2(L + r) apart, has the trace ``2 (2 (1 - D/r)^2 - 1)`` (98 here)."""
    scene = SCENES["point in stadium"]
    across = jb.find_periodic_orbit(scene, jnp.array([0.3, 0.0, 0.0, 0.02, 1.0, 0.0]), 2)
    assert bool(across.converged)
    assert abs(float(across.trace) - 2.0) < 1e-9
    np.testing.assert_allclose(float(across.period), 2.0 * 2 * 0.5 / float(jnp.hypot(*across.state[3:5])), rtol=1e-12)
    # Started on the axis itself: what is checked is its monodromy, from the scene's tangent maps.
    along = jb.find_periodic_orbit(scene, jnp.array([0.0, 0.0, 0.0, 1.0, 0.0, 0.0]), 2)
    assert bool(along.converged), along.residual
    assert abs(float(along.trace) - 98.0) < 1e-9 * 98.0
