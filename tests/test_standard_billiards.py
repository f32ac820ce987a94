"""The field's standard billiards: the numbers users check a billiard code against, against independent sources.

Each test compares jaxbill with what it did not compute: the independent ray
tracing and Dellago-Posch-Hoover tangent maps of ``standard_billiards_reference``
(numpy), closed forms (Santalo's mean free path, the mushroom's regular share of
phase space), a published figure (the hexagonal Lorentz gas's Lyapunov
exponents) and laws (linear growth of the mean-square displacement, the
identity map of a crossing). Tolerances come from the error bars of the
estimates, stated where they are used.
"""

from __future__ import annotations

import math
import os
import sys

import jax
import jax.numpy as jnp
import numpy as np
import pytest

import jaxbill as jb

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
import standard_billiards_reference as ref

POINT = jb.PointBody()


def scene_of(table):
    return jb.BodyInTable(POINT, table)


def as_states(q, v):
    """States ``[x, y, 0, vx, vy, 0]`` from positions and velocities ``(n, 2)``."""
    q, v = np.atleast_2d(q), np.atleast_2d(v)
    zero = np.zeros(len(q))
    return np.column_stack([q[:, 0], q[:, 1], zero, v[:, 0], v[:, 1], zero])


def boundary_starts(walls, count, seed):
    """``count`` starts drawn from the boundary map's invariant measure ``ds dp`` (uniform ``s`` on the perimeter,
    uniform ``p``), built by the reference from the walls alone."""
    rng = np.random.default_rng(seed)
    perimeter = sum(ref.wall_length(w) for w in walls)
    starts = [
        ref.boundary_start(walls, s, p) for s, p in zip(rng.uniform(0, perimeter, count), rng.uniform(-1, 1, count))
    ]
    return as_states(np.array([q for q, _ in starts]), np.array([v for _, v in starts]))


# -- tables and their closed forms -------------------------------------------------------------

R_CAP, W_STEM, H_STEM = 1.0, 1.0, 1.0
SINAI_RADIUS = 0.25
HEX_RADIUS, HEX_SPACING = 1.0, 2.2  # finite horizon: 2.2 < 4 / sqrt(3)
SQUARE_RADIUS, SQUARE_SPACING = 0.3, 1.0
STADIUM = (1.0, 0.5)
TRIANGLE = [(math.cos(2 * math.pi * j / 3), math.sin(2 * math.pi * j / 3)) for j in range(3)]


def mushroom():
    return jb.Mushroom(R_CAP, W_STEM, H_STEM)


def hexagonal_gas(spacing=HEX_SPACING):
    return jb.LorentzGas(HEX_RADIUS, spacing, "hexagonal")


# -- one run per table, shared by the tests that read it ---------------------------------------------

ORBITS, COLLISIONS = 2048, 256


def liouville_starts(inside, box, count, seed):
    """``count`` starts from the Liouville measure: uniform in the region ``inside(x, y)`` (rejection from
    ``box = (x_low, x_high, y_low, y_high)``) and uniform in direction, at unit speed."""
    rng = np.random.default_rng(seed)
    points = np.empty((0, 2))
    while len(points) < count:
        trial = rng.uniform(box[::2], box[1::2], (4 * count, 2))
        points = np.concatenate([points, trial[inside(trial[:, 0], trial[:, 1])]])
    angle = rng.uniform(-np.pi, np.pi, count)
    return as_states(points[:count], np.stack([np.cos(angle), np.sin(angle)], axis=1))


def in_mushroom(x, y):
    a = W_STEM / 2
    cap = (y >= 0) & (x * x + y * y < R_CAP**2)
    stem = (np.abs(x) < a) & (y > -H_STEM) & (y <= 0)
    return cap | stem


def in_hexagonal_cell(x, y, spacing=HEX_SPACING, radius=HEX_RADIUS):
    half = spacing / 2
    hexagon = (np.abs(x) < half) & (np.abs(x) / 2 + np.abs(y) * math.sqrt(3) / 2 < half)
    return hexagon & (x * x + y * y > radius**2)


class Run:
    """A batch of orbits of one table from given starts: ``states (B, n, 6)``, ``contacts (B, n)``, ``times (B, n)``."""

    def __init__(self, table, starts, collisions=COLLISIONS):
        self.table, self.scene, self.starts = table, scene_of(table), starts
        orbit = jb.orbit(self.scene, starts, collisions)
        self.states, self.contacts, self.times = (np.asarray(x) for x in (orbit.state, orbit.contact, orbit.t))


@pytest.fixture(scope="module")
def runs():
    """The runs, made on first use."""
    cache = {}

    def run(name):
        if name not in cache:
            cache[name] = RUNS[name]()
        return cache[name]

    return run


RUNS = {
    "sinai": lambda: Run(jb.Sinai(SINAI_RADIUS), boundary_starts(ref.sinai_walls(SINAI_RADIUS), ORBITS, 1)),
    "mushroom": lambda: Run(mushroom(), boundary_starts(ref.mushroom_walls(R_CAP, W_STEM, H_STEM), 2 * ORBITS, 1)),
    "mushroom liouville": lambda: Run(
        mushroom(), liouville_starts(in_mushroom, (-R_CAP, R_CAP, -H_STEM, R_CAP), 2 * ORBITS, 2)
    ),
    "stadium": lambda: Run(jb.Stadium(*STADIUM), boundary_starts(ref.stadium_walls(*STADIUM), ORBITS, 1)),
    "triangle": lambda: Run(jb.Polygon.regular(3, 1.0), boundary_starts(ref.polygon_walls(TRIANGLE), ORBITS, 1)),
    "hexagonal Lorentz gas": lambda: Run(
        hexagonal_gas(), boundary_starts([ref.disc_obstacle((0, 0), HEX_RADIUS)], ORBITS, 1)
    ),
    "square Lorentz gas": lambda: Run(
        jb.LorentzGas(SQUARE_RADIUS, SQUARE_SPACING, "square"),
        boundary_starts([ref.disc_obstacle((0, 0), SQUARE_RADIUS)], ORBITS, 1),
    ),
}


# -- the orbits against independent ray tracing --------------------------------------------------


@pytest.mark.parametrize(
    ("name", "walls"),
    [
        ("sinai", lambda: ref.sinai_walls(SINAI_RADIUS)),
        ("mushroom", lambda: ref.mushroom_walls(R_CAP, W_STEM, H_STEM)),
    ],
)
def test_orbits_are_the_reference_ray_tracing(name, walls, runs):
    """A point in Sinai's billiard and in the mushroom: each of the first 60 collisions of 16 orbits is the
    reference's next bounce from jaxbill's state before it (one step at a time, so that chaos does not grow an
    earlier rounding), on the same wall, to 4e-12 of the table's size (both solve the same quadratics
    independently, each exact to a few ulps)."""
    run, walls = runs(name), walls()
    for states, contacts in zip(run.states[:16, :60], run.contacts[:16, :60]):
        for k in range(len(states) - 1):
            q, v = states[k, [0, 1]], states[k, [3, 4]]
            _, index, q_hit, v_out = ref.next_bounce(walls, q, v)
            assert contacts[k + 1] in (index + 3, 2)
            np.testing.assert_allclose(states[k + 1, [0, 1]], q_hit, rtol=0, atol=4e-12)
            np.testing.assert_allclose(states[k + 1, [3, 4]], v_out, rtol=0, atol=4e-12)


def test_lorentz_gas_orbits_are_the_unfolded_plane(runs):
    """The hexagonal Lorentz gas run cell by cell is the plane of discs unfolded: each bounce off a disc is the
    reference's next disc (among all discs near the flight, no cells) from the state of the bounce before it;
    a crossing of a cell's side changes nothing (the velocity is the one before) and lies on the side
    (equidistant, to 1e-12, from the two nearest lattice points)."""
    run = runs("hexagonal Lorentz gas")
    a1, a2 = ref.lattice_vectors(HEX_SPACING, "hexagonal")
    basis = np.stack([a1, a2], 1)
    for start, states, contacts, times in zip(run.starts[:8], run.states[:8, :80], run.contacts[:8], run.times[:8]):
        previous, t_previous, bounces = start, 0.0, 0
        for state, contact, t in zip(states, contacts, times):
            if contact != 3:
                np.testing.assert_array_equal(state[3:5], previous[3:5])
                i, j = np.floor(np.linalg.solve(basis, state[:2]))
                near = [(i + di) * a1 + (j + dj) * a2 for di in (0, 1) for dj in (0, 1)]
                distances = np.sort([np.linalg.norm(state[:2] - c) for c in near])
                assert distances[1] - distances[0] < 1e-12 * HEX_SPACING
                continue
            dt, _, q_hit, v_out = ref.lorentz_bounce(previous[:2], previous[3:5], HEX_RADIUS, HEX_SPACING, "hexagonal")
            np.testing.assert_allclose(t - t_previous, dt, rtol=1e-12)
            np.testing.assert_allclose(state[:2], q_hit, rtol=0, atol=1e-12 * (1 + np.max(np.abs(q_hit))))
            np.testing.assert_allclose(state[3:5], v_out, rtol=0, atol=1e-12)
            previous, t_previous, bounces = state, t, bounces + 1
        assert bounces > 10


# -- Santalo's mean free path ------------------------------------------------------------------------

MEAN_FREE_PATHS = {
    # name: (the area the point moves in, the length of the walls it bounces off)
    "sinai": (1.0 - math.pi * SINAI_RADIUS**2, 4.0 + 2 * math.pi * SINAI_RADIUS),
    "mushroom": (math.pi * R_CAP**2 / 2 + W_STEM * H_STEM, math.pi * R_CAP + 2 * R_CAP + 2 * H_STEM),
    "stadium": (
        math.pi * STADIUM[1] ** 2 + 4 * STADIUM[0] * STADIUM[1],
        2 * math.pi * STADIUM[1] + 4 * STADIUM[0],
    ),
    "triangle": (3 * math.sqrt(3) / 4, 3 * math.sqrt(3)),
    "hexagonal Lorentz gas": (
        math.sqrt(3) / 2 * HEX_SPACING**2 - math.pi * HEX_RADIUS**2,
        2 * math.pi * HEX_RADIUS,
    ),
    "square Lorentz gas": (SQUARE_SPACING**2 - math.pi * SQUARE_RADIUS**2, 2 * math.pi * SQUARE_RADIUS),
}


@pytest.mark.parametrize("name", list(MEAN_FREE_PATHS))
def test_mean_free_path_is_santalos(name, runs):
    """Santalo: the mean flight between bounces of a point billiard, under the boundary map's invariant measure,
    is ``pi A / P``, ``A`` the area the point moves in and ``P`` the length of the walls it bounces off (in the
    Lorentz gas a cell less its disc, and the disc: crossings of the cells' sides are not bounces). From starts
    on that measure every flight is a draw from it, so ``sum t / sum bounces`` over the orbits estimates it
    without bias; within 4 standard errors (from 16 groups of independent orbits; the error below 1 % of the
    value)."""
    run = runs(name)
    periodic = any(type(p).periodic for p in run.table.pieces)
    bounces = np.sum(run.contacts == 3 if periodic else run.contacts != 0, axis=1)
    times = run.times[:, -1]
    groups = np.array_split(np.arange(len(times)), 16)
    means = np.array([times[g].sum() / bounces[g].sum() for g in groups])
    estimate, error = times.sum() / bounces.sum(), means.std(ddof=1) / math.sqrt(len(groups))
    exact = ref.santalo_mean_free_path(*MEAN_FREE_PATHS[name])
    assert error < 0.01 * exact
    assert abs(estimate - exact) < 4 * error, (estimate, error, exact)
    if hasattr(run.table, "mean_free_path"):
        np.testing.assert_allclose(float(run.table.mean_free_path), exact, rtol=1e-12)


# -- the mushroom's divided phase space ----------------------------------------------------------------

STEM_WALLS = (5, 6, 7)  # the contact codes of the stem's left side, foot and right side


@pytest.mark.parametrize(("name", "measure"), [("mushroom liouville", 0), ("mushroom", 1)])
def test_mushroom_regular_share_is_the_closed_form(name, measure, runs):
    """The share of the mushroom's phase space that never enters the stem, in the Liouville measure (starts
    uniform in the table and in direction) and on the boundary map (starts uniform in ``(s, p)``), is the closed
    form of ``ref.mushroom_regular_share`` (cap orbits with ``|L| > w/2``). An orbit is counted chaotic when it
    bounces off the stem within 256 collisions; a chaotic one in the cap with ``|L| = w/2 - delta`` finds the
    stem's mouth within about ``pi / (2 sqrt(2 delta / a))`` bounces, so those missed have ``delta < 1e-4 a``: a
    share near 1e-5, far below the binomial error of 4096 orbits (about 0.007). Within 4 of those errors."""
    run = runs(name)
    chaotic = np.any(np.isin(run.contacts, STEM_WALLS), axis=1)
    regular = 1.0 - chaotic.mean()
    expected = ref.mushroom_regular_share(R_CAP, W_STEM, H_STEM)[measure]
    error = math.sqrt(expected * (1 - expected) / len(chaotic))
    assert abs(regular - expected) < 4 * error, (regular, expected, error)


def test_fli_map_of_the_mushroom_shows_its_regular_cap():
    """The FLI map on the cap's arc, ``(s, p)`` in the Birkhoff section: the regular orbits (``|p| > w / (2R)``,
    their angular momentum keeps them out of the stem) grow their tangent vectors only linearly, the FLI a
    logarithm; the chaotic ones (``|p| < w / (2R)``) exponentially. A block: every regular pixel below every
    chaotic one, by a wide margin."""
    scene = scene_of(mushroom())
    s, p = np.meshgrid(np.linspace(0.2, math.pi - 0.2, 5), np.linspace(-0.9, 0.9, 10), indexing="ij")
    fli = jb.fli_map(scene, scene.section_state(np.stack([s, p], -1)), 150)
    edge = W_STEM / (2 * R_CAP)
    regular, chaotic = fli[np.abs(p) > edge + 0.05], fli[np.abs(p) < edge - 0.05]
    assert np.all(np.isfinite(fli))
    assert np.max(regular) < 12 and np.min(chaotic) > 3 * np.max(regular), (regular, chaotic)


# -- Lyapunov exponents ------------------------------------------------------------------------------

# DynamicalBilliards.jl's test of the hexagonal Lorentz gas (test/lyapunov.jl, "test_lyapunov_values": discs of
# radius 1, hexagonal cells with centres `space` apart, values "based on Gaspard et al (see docs)", the largest
# exponent of P. Gaspard and F. Baras, Phys. Rev. E 51, 5332 (1995), Fig. 7, read to one decimal).
GASPARD_BARAS = {2.0: 3.6, 2.5: 1.4, 3.0: 0.8, 3.5: 0.6, 4.0: 0.5}


def test_hexagonal_lorentz_gas_lyapunov_exponents_are_gaspard_and_baras():
    """The largest Lyapunov exponent per unit time (unit speed) of the hexagonal Lorentz gas against the distance
    between centres, from 8 orbits of 4096 collisions and crossings each (a standard error below 0.01), within 0.1
    of the published figure's values: they are read to one decimal (0.05) from a figure, the rest is their
    reading and our error bar. The spectrum pairs: ``lambda_4 = -lambda_1`` and two zeros."""
    for spacing, published in GASPARD_BARAS.items():
        scene = scene_of(hexagonal_gas(spacing))
        starts = liouville_starts(lambda x, y: in_hexagonal_cell(x, y, spacing), (-2.0, 2.0, -2.4, 2.4), 8, 4)
        exponents = np.asarray(jb.lyapunov_spectrum(scene, starts, 4096, paired=False).exponents)
        largest = exponents[:, 0]
        error = largest.std(ddof=1) / math.sqrt(len(largest))
        assert error < 0.02
        assert abs(largest.mean() - published) < 0.1, (spacing, largest.mean(), error, published)
        np.testing.assert_allclose(exponents[:, 3], -exponents[:, 0], atol=0.02 * published)
        assert np.all(np.abs(exponents[:, 1:3]) < 0.05 * published)


def _spectrum_of_maps(maps, total_time, frame0):
    """Benettin's QR along a product of tangent maps from ``frame0``: the exponents per unit time, descending."""
    frame, logs = frame0, np.zeros(frame0.shape[1])
    for m in maps:
        frame, r = np.linalg.qr(m @ frame)
        logs += np.log(np.abs(np.diag(r)))
    return np.sort(logs / total_time)[::-1]


def _dph_maps(name, state0, states, contacts, times):
    """The reference's tangent map of each event of jaxbill's orbit, from the state before it: the wall from the
    reference's own ray tracing (Sinai) or the disc nearest the hit (the Lorentz gas; a crossing is a flight)."""
    maps, previous, t_previous = [], state0, 0.0
    a1, a2 = ref.lattice_vectors(HEX_SPACING, "hexagonal")
    basis = np.stack([a1, a2], 1)
    for state, contact, t in zip(states, contacts, times):
        dt, q, v = t - t_previous, previous[[0, 1]], previous[[3, 4]]
        hit = q + v * dt
        if name == "sinai":
            walls = ref.sinai_walls(SINAI_RADIUS)
            _, index, _, _ = ref.next_bounce(walls, q, v)
            assert contact == index + 3
            wall = walls[index]
            out = wall["out"] if wall["kind"] == "segment" else -(hit - wall["c"]) / wall["r"]
            maps.append(ref.dph_flow_tangent(q, v, dt, out, wall["curvature"]))
        elif contact == 3:
            i, j = np.floor(np.linalg.solve(basis, hit))
            corners = [(i + di) * a1 + (j + dj) * a2 for di in (0, 1) for dj in (0, 1)]
            centre = min(corners, key=lambda c: np.linalg.norm(hit - c))  # the disc the point is on
            maps.append(ref.dph_flow_tangent(q, v, dt, -(hit - centre) / HEX_RADIUS, 1.0 / HEX_RADIUS))
        else:
            maps.append(ref.free_flight(dt))
        previous, t_previous = state, t
    return maps


@pytest.mark.parametrize("name", ["sinai", "hexagonal Lorentz gas"])
def test_lyapunov_spectrum_is_the_dellago_posch_hoover_product(name):
    """The full spectrum by autodiff (``jb.lyapunov_spectrum``, per unit time) is the one of the reference's
    Dellago-Posch-Hoover tangent maps (flat walls, dispersing discs, free flights across a cell's side) multiplied
    along the same 512 events from the same start frame, to 1e-9 of the largest: every tangent map agrees. The
    spectrum pairs (``lambda_1 = -lambda_4``, two zeros) only as far as 512 events allow, which is not tested
    here."""
    from jaxbill._analysis.lyapunov import _initial_vectors  # the fixed start frame the library documents

    if name == "sinai":
        scene = scene_of(jb.Sinai(SINAI_RADIUS))
        state0 = boundary_starts(ref.sinai_walls(SINAI_RADIUS), 1, seed=7)[0]
    else:
        scene = scene_of(hexagonal_gas())
        state0 = boundary_starts([ref.disc_obstacle((0, 0), HEX_RADIUS)], 1, seed=7)[0]
    n = 512
    orbit = jb.orbit(scene, state0, n)
    states, contacts, times = (np.asarray(x) for x in (orbit.state, orbit.contact, orbit.t))
    maps = _dph_maps(name, state0, states, contacts, times)
    expected = _spectrum_of_maps(maps, times[-1], np.asarray(_initial_vectors(4, 4)))
    spectrum = np.asarray(jb.lyapunov_spectrum(scene, state0, n, paired=False).exponents)
    np.testing.assert_allclose(spectrum, expected, rtol=0, atol=1e-9 * expected[0])
    assert expected[0] > 0.5


# -- diffusion in the Lorentz gas -------------------------------------------------------------------


def _positions_at(start, times, states, at):
    """Unfolded positions ``(len(at), 2)`` of one orbit at the times ``at``: the flight from the last event
    before each."""
    event_times = np.concatenate([[0.0], times])
    events = np.concatenate([start[None], states])
    k = np.searchsorted(event_times, at, side="right") - 1
    return events[k, :2] + events[k, 3:5] * (at - event_times[k])[:, None]


def test_lorentz_gas_with_a_finite_horizon_diffuses():
    """The hexagonal Lorentz gas with a finite horizon (``spacing = 2.2 < 4 / sqrt(3)`` radii) diffuses: the
    mean-square displacement of 2048 Liouville starts grows linearly, ``<|r(t) - r(0)|^2> = 4 D t + c``: its
    slopes over ``t`` in ``[10, 25]`` and ``[25, 40]`` (past the collision time, 0.5) agree within 3 standard
    errors (from 16 independent groups), each known to 5 %."""
    run = Run(
        hexagonal_gas(), liouville_starts(in_hexagonal_cell, (-HEX_SPACING / 2, HEX_SPACING / 2, -1.3, 1.3), ORBITS, 2)
    )
    at = np.array([10.0, 25.0, 40.0])
    assert np.min(run.times[:, -1]) > at[-1]
    displacement = np.array([_positions_at(s, t, x, at) - s[:2] for s, t, x in zip(run.starts, run.times, run.states)])
    squared = np.sum(displacement**2, axis=-1)
    groups = np.array([squared[g].mean(axis=0) for g in np.array_split(np.arange(ORBITS), 16)])
    early = (groups[:, 1] - groups[:, 0]) / (4 * 15.0)
    late = (groups[:, 2] - groups[:, 1]) / (4 * 15.0)
    error = lambda x: x.std(ddof=1) / math.sqrt(len(x))  # noqa: E731
    assert error(early) < 0.05 * early.mean() and error(late) < 0.05 * late.mean()
    assert abs(early.mean() - late.mean()) < 3 * error(early - late), (early.mean(), late.mean())


@pytest.mark.parametrize(
    ("table", "state"),
    [
        (lambda: jb.Sinai(SINAI_RADIUS), [0.3, 0.3, 0.0, 0.6, 0.6, 0.0]),
        (lambda: mushroom(), [0.5, 0.5, 0.0, 0.5, -0.5, 0.0]),
        (lambda: mushroom(), [0.0, -0.5, 0.0, 0.5, -0.5, 0.0]),
    ],
    ids=["sinai square corner", "mushroom cap corner", "mushroom stem corner"],
)
def test_a_point_into_a_right_angled_corner_comes_straight_back(table, state):
    """A right-angled corner (the square's, where the cap's arc meets its rim, where the stem's side meets its
    foot) reflects a point aimed exactly at it straight back, the two walls' impulses in one event (contact code
    2), on the corner to rounding."""
    orbit = jb.orbit(scene_of(table()), np.asarray(state), 512)  # the length the spectrum tests compile
    new, dt, contact = np.asarray(orbit.state[0]), float(orbit.t[0]), int(orbit.contact[0])
    np.testing.assert_allclose(new[3:5], -np.asarray(state[3:5]), rtol=0, atol=1e-14)
    assert contact == 2
    corner = np.asarray(state[:2]) + dt * np.asarray(state[3:5])
    np.testing.assert_allclose(new[:2], corner, rtol=0, atol=1e-14)


# -- drivers, bad input ------------------------------------------------------------------------------


def test_the_lane_driver_takes_the_same_collisions_and_the_kernel_lowers_for_cuda():
    """The lane state machine (``driver="lanes"``) takes the hexagonal Lorentz gas's collisions and crossings
    as the serial driver does (the same contacts, states to rounding); the Pallas kernels of the gas and the
    mushroom (no gathers, no constants: the cell's fold and the finite walls are elementwise) lower for CUDA."""
    from jaxbill._engine import lanes as _lanes
    from jaxbill._engine import pallas as _pallas

    gas = scene_of(hexagonal_gas())
    starts = boundary_starts([ref.disc_obstacle((0, 0), HEX_RADIUS)], 8, seed=9)
    serial, lanes = jb.orbit(gas, starts, 64, driver="serial"), jb.orbit(gas, starts, 64, driver="lanes")
    np.testing.assert_array_equal(np.asarray(lanes.contact), np.asarray(serial.contact))
    np.testing.assert_allclose(np.asarray(lanes.state), np.asarray(serial.state), rtol=1e-12, atol=1e-12)
    for scene in (gas, scene_of(mushroom())):
        zeros = jnp.zeros((64, 6))
        final = jax.jit(lambda s, c, scene=scene: _pallas.pallas_final(scene, s, c, 10)).trace(
            zeros, _lanes.fresh_carry(scene, zeros)
        )
        assert "triton" in final.lower(lowering_platforms=("cuda",)).as_text().lower()


@pytest.mark.parametrize(
    ("make", "match"),
    [
        (lambda: jb.Sinai(0.5), "radius"),
        (lambda: jb.Sinai(0.2, side=-1.0), "side"),
        (lambda: jb.LorentzGas(0.6, 1.0), "radius"),
        (lambda: jb.LorentzGas(0.3, float("nan")), "spacing"),
        (lambda: jb.LorentzGas(0.3, 1.0, "triangular"), "lattice"),
        (lambda: jb.Mushroom(1.0, 2.0, 1.0), "stem_width"),
        (lambda: jb.Mushroom(1.0, 0.5, 0.0), "stem_height"),
        (lambda: jb.Mushroom(float("inf"), 0.5, 1.0), "cap_radius"),
        (lambda: jb.DiscObstacle((0.0, 0.0), -1.0).check(), "radius"),
        (lambda: jb.WithObstacles(jb.Circle(1.0), [jb.DiscObstacle((0.8, 0.0), 0.3)]), "obstacle 1 reaches"),
        (
            lambda: jb.WithObstacles(
                jb.Circle(1.0), [jb.DiscObstacle((0.2, 0.0), 0.2), jb.EllipseObstacle((-0.1, 0), 0.2, 0.1)]
            ),
            "overlap",
        ),
        (lambda: jb.BodyInTable(jb.Dumbbell(0.1), jb.Sinai(0.2)), "only jb.PointBody"),
        (lambda: jb.BodyInTable(jb.PolygonBody.regular(3, 0.1), mushroom()), "re-entrant corner"),
        (lambda: jb.orbit(scene_of(mushroom()), np.array([0.9, -0.5, 0.0, 1.0, 0.0, 0.0]), 3), "outside the mushroom"),
        (lambda: jb.orbit(scene_of(jb.Sinai(0.25)), np.array([0.1, 0.0, 0.0, 1.0, 0.0, 0.0]), 3), "outside"),
    ],
)
def test_bad_input_is_a_value_error_naming_it(make, match):
    with pytest.raises(ValueError, match=match):
        make()


def test_bad_parameters_under_jit_poison_the_orbit_with_nan():
    """Traced parameters skip the eager checks; the scene's validity poisons the result with NaN instead."""

    def first_state(radius):
        return jb.collide(scene_of(jb.Sinai(radius)), jnp.array([0.4, 0.0, 0.0, 0.6, 0.8, 0.0]))[0]

    assert np.all(np.isfinite(np.asarray(jax.jit(first_state)(0.25))))
    assert np.all(np.isnan(np.asarray(jax.jit(first_state)(0.7))))


def test_a_table_outline_breaks_between_separate_walls():
    """The picture of a table with an obstacle joins no wall to another: every drawn segment is one step of
    the boundary, and the outline breaks (NaN) where it passes to the disc."""
    from jaxbill._scenes.body_sections import table_outline

    table = jb.Sinai(0.25)
    points = table_outline(jb.BodyInTable(jb.PointBody(), table))
    step = float(table.boundary_length) / 720
    segments = np.linalg.norm(np.diff(points, axis=0), axis=-1)
    assert np.isnan(points[:, 0]).any()
    assert np.nanmax(segments) <= 2.0 * step
    on_disc = np.isclose(np.hypot(points[:, 0], points[:, 1]), 0.25, atol=1e-12)
    assert on_disc.sum() > 100  # the disc is drawn, not left out
