"""Every analysis on every composition: a body in a table runs through the whole library unchanged.

One catalogue of compositions (points, a dumbbell of unequal masses, rigid
polygons, the coin; circles, ellipses, stadiums, polygons, the strip and a
user's convex function) goes through the drivers (bitwise alike, the Pallas
kernel in interpret mode and lowered for CUDA), the tangent maps, the chaos
indicators, the energy-shell sampler, the sections and their inverses, the
explorer's chart and the periodic-orbit search. Each test asserts a property
that holds independently of the code under test: bitwise agreement between
independent drivers, the flow direction in the kernel of the collision map's
Jacobian, the pairing of a symplectic flow's exponents, closed-form stability
of a billiard's periodic orbits, invariants of the sampler's output.
"""

from __future__ import annotations

import jax
import jax.numpy as jnp
import numpy as np
import pytest

import jaxbill as jb
from jaxbill._engine import lanes as _lanes
from jaxbill._engine import pallas as _pallas

INF = float("inf")
TRIANGLE = [(0.0, 0.0), (0.6, 0.0), (0.15, 0.4)]
PENTAGON = [(1.1, -0.2), (0.7, 0.85), (-0.45, 0.95), (-1.05, 0.05), (-0.2, -0.95)]


def squircle(x, y):
    """A user's convex table: ``x^4 + y^4 <= 1``."""
    return x**4 + y**4 - 1.0


def catalogue():
    return {
        "point in stadium": jb.BodyInTable(jb.PointBody(), jb.Stadium(1.0, 0.5)),
        "triangle in stadium": jb.BodyInTable(jb.PolygonBody(TRIANGLE), jb.Stadium(1.0, 0.8)),
        "dumbbell 1:3 in ellipse": jb.BodyInTable(jb.Dumbbell.from_masses(1.0, 3.0, 0.8), jb.Ellipse(2.0, 1.2)),
        "square in circle": jb.BodyInTable(jb.PolygonBody.regular(4, 0.3), jb.Circle(1.0)),
        "point in pentagon": jb.BodyInTable(jb.PointBody(), jb.Polygon(PENTAGON)),
        "static triangle in pentagon": jb.BodyInTable(jb.PolygonBody(TRIANGLE, inertia=INF), jb.Polygon(PENTAGON)),
        "coin between walls": jb.BodyInTable(jb.EllipseBody(0.4, 0.2), jb.Strip(1.0)),
        "dumbbell in a user's table": jb.BodyInTable(
            jb.Dumbbell(0.3), jb.ConvexTable(squircle, (-1.2, 1.2, -1.2, 1.2))
        ),
    }


SCENES = catalogue()
NAMES = list(SCENES)


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


@pytest.mark.parametrize("name", NAMES)
def test_drivers_agree(name, starts):
    """Serial, lockstep, the lane state machine and the Pallas kernel take the same collisions: the same
    contacts, states equal to rounding (vectorised arithmetic and the kernel may round a last bit
    differently, which a chaotic orbit then grows), and bitwise where two calls run the same program:
    ``jb.run`` and ``jb.orbit`` one orbit after another."""
    scene, states = SCENES[name], starts[name]
    reference = jb.orbit(scene, states, 8, driver="serial")
    assert np.all(np.isfinite(np.asarray(reference.t)))
    lanes = jb.orbit(scene, states, 8, driver="lanes")
    for driver, other in (("lockstep", jb.orbit(scene, states, 8, driver="lockstep")), ("lanes", lanes)):
        np.testing.assert_array_equal(np.asarray(other.contact), np.asarray(reference.contact), err_msg=driver)
        scale = float(scene.length_scale) + np.abs(np.asarray(reference.state))
        assert np.all(np.abs(np.asarray(other.state) - np.asarray(reference.state)) <= 1e-10 * scale), driver
    serial = jb.run(scene, states, 8, driver="serial")
    np.testing.assert_array_equal(serial.final_state, np.asarray(reference.state[:, -1]))
    np.testing.assert_array_equal(serial.time, np.asarray(reference.t[:, -1]))
    kernel = jb.run(scene, states, 8, driver="pallas")
    scale = float(scene.length_scale) + np.abs(np.asarray(lanes.state[:, -1]))
    assert np.all(np.abs(kernel.final_state - np.asarray(lanes.state[:, -1])) <= 1e-10 * scale)
    codes = set(np.unique(np.asarray(reference.contact)).tolist())
    assert codes <= set(scene.contact_codes), codes


@pytest.mark.parametrize("name", ["triangle in stadium", "point in pentagon", "coin between walls"])
def test_pallas_kernels_lower_for_cuda(name):
    scene = SCENES[name]
    states = jnp.zeros((64, 6))
    final = (
        jax.jit(lambda s, c: _pallas.pallas_final(scene, s, c, 10))
        .trace(states, _lanes.fresh_carry(scene, states))
        .lower(lowering_platforms=("cuda",))
    )
    tangent = jax.jit(lambda s, w: _pallas.pallas_fli(scene, s, w, 10)).trace(states, states)
    assert "triton" in final.as_text().lower()
    assert "triton" in tangent.lower(lowering_platforms=("cuda",)).as_text().lower()


@pytest.mark.parametrize("name", NAMES)
def test_the_collision_map_annihilates_the_flow_direction(name, starts):
    """``DP f(s) = 0``: moving the start along its own flight changes nothing after the collision, and the
    flow's tangent map takes ``f(s)`` to ``f(s')``."""
    scene = SCENES[name]
    state = jnp.asarray(starts[name][0])
    new_state, _, _, section_jacobian = jb.tangent_map(scene, state)
    f = scene.phase_velocity(state)
    assert float(jnp.max(jnp.abs(section_jacobian @ f))) < 1e-9 * float(jnp.max(jnp.abs(section_jacobian)))
    *_, flow_jacobian = jb.tangent_map(scene, state, flow=True)
    np.testing.assert_allclose(np.asarray(flow_jacobian @ f), np.asarray(scene.phase_velocity(new_state)), atol=1e-9)


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


@pytest.mark.parametrize("name", NAMES)
def test_the_sampler_draws_valid_states_on_the_shell(name, starts):
    scene = SCENES[name]
    states = starts[name]
    np.testing.assert_allclose(np.asarray(jb.energy(scene, states)), 0.5, rtol=1e-14)
    assert np.all(np.asarray(scene.gaps(states)) > 0.0)
    if scene.kind != "rotor":
        assert np.all(states[:, 5] == 0.0)


def test_the_sampler_pins_the_angular_momentum_in_a_circle():
    scene = SCENES["square in circle"]
    states, weights = jb.sample_energy_shell(scene, 50, angular_momentum=0.3, seed=2)
    np.testing.assert_allclose(np.asarray(jb.angular_momentum(scene, states)), 0.3, rtol=1e-12, atol=1e-14)
    np.testing.assert_allclose(np.asarray(jb.energy(scene, states)), 0.5, rtol=1e-14)
    assert np.all(weights > 0)
    with pytest.raises(ValueError, match="angular_momentum"):
        jb.sample_energy_shell(SCENES["triangle in stadium"], 5, angular_momentum=0.3)


@pytest.mark.parametrize("name", NAMES)
def test_sections_invert_their_states(name):
    """``section(section_state(point)) == point`` wherever a state exists, and a state is just after a
    collision: the touching contact on its wall, leaving it."""
    scene = SCENES[name]
    if not scene.sections:
        with pytest.raises(ValueError, match="name"):
            scene.section(jnp.zeros((1, 6)))
        return
    chart = scene.section_chart
    x_low, x_high = chart.x_range(scene)
    rng = np.random.default_rng(4)
    x = rng.uniform(x_low, x_high, 40)
    edge = chart.edge(scene, x, chart.default_invariants(scene))
    y = edge[:, 0] + (edge[:, 1] - edge[:, 0]) * rng.uniform(0.05, 0.95, 40)
    states = np.asarray(scene.section_state(jnp.stack([x, y], axis=-1)))
    found = np.all(np.isfinite(states), axis=1)
    assert found.sum() >= 10, found.sum()
    points = np.asarray(scene.section(states[found]))
    np.testing.assert_allclose(points, np.stack([x, y], axis=-1)[found], atol=1e-10)
    touching = np.min(np.abs(np.asarray(scene.gaps(states[found]))), axis=-1)
    assert np.all(touching <= 1e-12 * float(scene.gap_scale))


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


def test_the_explorers_chart_seeds_and_reads_the_coin_between_walls():
    """The floor section's seeds are valid states; the points of their orbits stay within the chart's edge."""
    scene = SCENES["coin between walls"]
    chart = scene.section_chart
    states, contacts = chart.seeds(scene, 12, chart.default_invariants(scene))
    states = np.asarray(states)
    good = np.all(np.isfinite(states), axis=1)
    assert good.sum() >= 6
    orbit = jb.orbit(scene, states[good], 60)
    points = np.asarray(chart.points(scene, orbit.state, orbit.contact)).reshape(-1, 2)
    points = points[np.all(np.isfinite(points), axis=1)]
    bound = chart.edge(scene, points[:, 0], chart.default_invariants(scene))
    assert np.all(points[:, 1] <= bound[:, 1] * (1 + 1e-9)) and np.all(points[:, 1] >= bound[:, 0] * (1 + 1e-9))
    energy = np.asarray(jb.energy(scene, orbit.state)) - 0.5 * np.asarray(orbit.state[..., 3]) ** 2
    np.testing.assert_allclose(energy, 0.5, rtol=1e-12)


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
