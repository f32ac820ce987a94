r"""Sections of a body in a table at its collisions, and their inverses (``jb.BodyInTable.section``).

Two sections, by the table (``Table.section_names``):

* ``"birkhoff"`` (a bounded table): at each collision, ``[s, p]`` with ``s`` the
  arc length of the contact point round the table's boundary (anticlockwise,
  from the table's own origin: ``(R, 0)`` on the circle, ``(a, 0)`` on the
  ellipse, ``(L + r, 0)`` on the stadium, the first corner of a polygon) and
  ``p = sqrt(M) (v . T) / sqrt(2 E)`` the centre's tangential momentum in units
  of ``sqrt(2 M E)`` (``T`` the unit tangent at the contact, anticlockwise), in
  ``[-1, 1]``. For a point particle these are Birkhoff's coordinates, in which
  the collision map preserves area (``ds dp``): the area-preserving section of
  the billiard. For a body they are a projection of a higher-dimensional
  section (areas in it mean nothing). The boundary is the table's walls in
  order, obstacles included (their arc length runs clockwise, the table on the
  left); the sides of a periodic cell are no part of it, and a crossing of one
  has no section point (NaN).
* ``"floor"`` (the strip between two flat walls, a turning body): at each
  collision with the floor, ``[alpha mod (2 pi / n), p]``, ``n`` the body's
  turn symmetry (``Body.turn_symmetry``: 2 for a symmetric stick or the coin),
  and ``p = (I omega - M vy (r_alpha)_y) / sqrt(2 I E')``, with ``r`` the
  touching contact's offset from the centre and ``E' = E - M vx^2 / 2`` the
  energy of the vertical motion and the turn (the horizontal motion is free
  and decoupled). With ``eta = sqrt(M / I) y``, the point ``(alpha, eta)``
  flies straight at the speed ``sqrt(2 E' / I)`` and reflects specularly off
  the floor's curve ``eta = sqrt(M/I) h(alpha)`` (``h`` the height of the
  centre when the body rests on the floor): ``p`` is the tangential momentum
  along it per unit ``alpha``, and ``(alpha, p)`` is area-preserving at fixed
  ``E'`` (the same argument as for the stick between walls, whose floor
  section this is for any body). Reachable: ``|p| <= sqrt(1 + (M/I) (r_alpha)_y^2)``.

The inverses (``birkhoff_state``, ``floor_state``) give the state just after
such a collision, NaN where none exists; the explorer's charts are built from
them.
"""

from __future__ import annotations

import functools

import jax
import jax.numpy as jnp
import numpy as np

from jaxbill._engine.validation import as_states
from jaxbill._scenes.protocols import WALL_TOLERANCE, SectionChart


def halton(index: np.ndarray, base: int) -> np.ndarray:
    """The radical-inverse (van der Corput) sequence in ``base`` at the positive integers ``index``."""
    result = np.zeros(len(index))
    fraction = 1.0 / base
    i = index.astype(np.int64).copy()
    while np.any(i > 0):
        result += fraction * (i % base)
        i //= base
        fraction /= base
    return result


def touching_gap(scene, states: jax.Array, contacts: jax.Array | None = None) -> jax.Array:
    """The index (int32, ``(...)``) of the gap that touched at each collision: from ``contacts`` (the scene's
    ``gap_codes``) where they name one gap, else the gap nearest zero."""
    gaps = jnp.abs(scene.gaps(states))
    nearest = jnp.argmin(gaps, axis=-1).astype(jnp.int32)
    if contacts is None:
        return nearest
    contacts = jnp.asarray(contacts)
    index = nearest
    for g, code in enumerate(scene.gap_codes):
        index = jnp.where(contacts == code, jnp.int32(g), index)
    return index


def _by_piece(table, piece_index, values) -> jax.Array:
    """``values[piece_index]`` for a static list of equal-shaped arrays and a traced index."""
    chosen = values[-1]
    for i in range(len(values) - 2, -1, -1):
        chosen = jnp.where(piece_index == i, values[i], chosen)
    return chosen


def birkhoff_section(scene, states, contacts=None) -> jax.Array:
    """``[s, p]`` ``(..., 2)`` of states ``(..., 6)`` at collisions (module docstring)."""
    states = as_states(scene, states)
    gap = touching_gap(scene, states, contacts)
    points = scene.contact_points(states)
    point = jnp.take_along_axis(points, gap[..., None, None], axis=-2)[..., 0, :]
    px, py = point[..., 0], point[..., 1]
    table = scene.table
    piece = gap // scene.body.contact_count
    arcs, tangents_x, tangents_y = [], [], []
    for i, wall in enumerate(table.pieces):
        arcs.append(table.boundary_coordinate(i, px, py))
        tx, ty = wall.tangent(px, py)
        tangents_x.append(tx)
        tangents_y.append(ty)
    s = jnp.mod(_by_piece(table, piece, arcs), table.boundary_length)
    tx, ty = _by_piece(table, piece, tangents_x), _by_piece(table, piece, tangents_y)
    p = jnp.sqrt(scene.mass) * (states[..., 3] * tx + states[..., 4] * ty) / jnp.sqrt(2.0 * scene.energy(states))
    point = jnp.stack([s, p], axis=-1)
    crossings = [i for i, wall in enumerate(table.pieces) if type(wall).periodic]
    if not crossings:
        return point
    # A crossing of a periodic cell's side is no collision with the boundary: no section point.
    crossed = functools.reduce(jnp.logical_or, [piece == i for i in crossings])
    return jnp.where(crossed[..., None], jnp.nan, point)


def _leaving_and_inside(scene, state, touching: int) -> jax.Array:
    """The contact ``touching`` (a gap index) is leaving its wall and every other contact is inside."""
    gaps, speeds = scene.gaps(state), scene.approach_speeds(state)
    others = jnp.concatenate([gaps[..., :touching], gaps[..., touching + 1 :]], axis=-1)
    inside = jnp.all(others >= -WALL_TOLERANCE * scene.gap_scale, axis=-1)
    return inside & (speeds[..., touching] < 0.0)


def birkhoff_state(scene, s, p, energy=0.5, arm_angle=0.0, spin=0.0) -> jax.Array:
    """The state ``(..., 6)`` just after the body's first contact hits the wall at arc length ``s`` with ``p``.

    Args:
        scene: a ``BodyInTable`` in a bounded table.
        s: the contact's arc length (length), any shape; ``p``: the tangential
            momentum ``sqrt(M) v_t / sqrt(2 E)`` in ``[-1, 1]``, the same shape.
        energy: ``E > 0``.
        arm_angle: the angle (radians) from the wall's outward normal to the
            body's first contact's offset from its centre (``Body.orientation_for``),
            anticlockwise; 0: the centre right behind the contact. Ignored for a point.
        spin: ``omega`` (radians per time; 0 for a body that does not turn).

    Returns:
        ``(..., 6)``; NaN where no such state exists: ``|p| > 1``, the spin takes
        more than the energy, another contact would be outside, or the touching
        one would not be leaving the wall.
    """
    s, p = jnp.broadcast_arrays(jnp.asarray(s, jnp.float64), jnp.asarray(p, jnp.float64))
    table, body = scene.table, scene.body
    x, y, piece = table.boundary_point(s)
    tangents = [wall.tangent(x, y) for wall in table.pieces]
    tx = _by_piece(table, piece, [t[0] for t in tangents])
    ty = _by_piece(table, piece, [t[1] for t in tangents])
    out_x, out_y = ty, -tx  # the outward normal: a quarter turn clockwise of the anticlockwise tangent
    direction = jnp.arctan2(out_y, out_x) + arm_angle
    turning = scene.body.kind == "rotor"
    alpha = body.orientation_for(direction) if scene.body.kind != "point" else jnp.zeros_like(s)
    offsets = scene.contact_offsets_at(alpha)  # per wall, the first contact's offset
    rx = _by_piece(table, piece, [wall[0][0] for wall in offsets])
    ry = _by_piece(table, piece, [wall[0][1] for wall in offsets])
    omega = jnp.zeros_like(s) + (spin if turning else 0.0)
    v_scale = jnp.sqrt(2.0 * energy / scene.mass)
    v_t = p * v_scale
    rotation = scene.inertia * omega**2 / scene.mass if turning else jnp.zeros_like(s)
    normal_squared = v_scale**2 - v_t**2 - rotation
    v_n = jnp.sqrt(jnp.where(normal_squared >= 0.0, normal_squared, jnp.nan))
    vx, vy = v_t * tx - v_n * out_x, v_t * ty - v_n * out_y
    state = jnp.stack([x - rx, y - ry, alpha, vx, vy, omega], axis=-1)
    ok = jnp.zeros(jnp.shape(s), bool)
    contacts = body.contact_count
    for i in range(len(table.pieces)):
        ok = jnp.where(piece == i, _leaving_and_inside(scene, state, i * contacts), ok)
    return jnp.where(ok[..., None], state, jnp.nan)


def floor_section(scene, states, contacts=None) -> jax.Array:
    """``[alpha mod (2 pi / n), p]`` ``(..., 2)`` at collisions with the floor, NaN at others (module docstring)."""
    states = as_states(scene, states)
    if scene.body.kind != "rotor":
        raise ValueError("the floor section needs a turning body: one that does not turn only bounces")
    gap = touching_gap(scene, states, contacts)
    on_floor = gap < scene.body.contact_count
    offsets = scene.contact_offsets_at(states[..., 2])[0]  # the floor's contacts
    turn_y = jnp.stack([scene.body.turn_vector(rx, ry)[1] for rx, ry in offsets], axis=-1)
    lever = jnp.take_along_axis(turn_y, jnp.minimum(gap, scene.body.contact_count - 1)[..., None], axis=-1)[..., 0]
    mass, inertia = scene.mass, scene.inertia
    vx, vy, omega = states[..., 3], states[..., 4], states[..., 5]
    vertical = scene.energy(states) - 0.5 * mass * vx**2
    p = (inertia * omega - mass * vy * lever) / jnp.sqrt(2.0 * inertia * vertical)
    angle = jnp.mod(states[..., 2], 2.0 * jnp.pi / scene.body.turn_symmetry)
    return jnp.where(on_floor[..., None], jnp.stack([angle, p], axis=-1), jnp.nan)


def _resting(scene, alpha):
    """For a body at ``alpha`` on the floor: ``(index of its lowest contact, height of its centre, (r_alpha)_y)``."""
    offsets = scene.contact_offsets_at(alpha)[0]
    heights = jnp.stack([-ry for _, ry in offsets], axis=-1)
    lowest = jnp.argmax(heights, axis=-1).astype(jnp.int32)
    turn_y = jnp.stack([scene.body.turn_vector(rx, ry)[1] for rx, ry in offsets], axis=-1)
    pick = lowest[..., None]
    return lowest, jnp.take_along_axis(heights, pick, -1)[..., 0], jnp.take_along_axis(turn_y, pick, -1)[..., 0]


def floor_bound(scene, alpha) -> jax.Array:
    """The largest ``|p|`` of the floor section at ``alpha``: ``sqrt(1 + (M/I) (r_alpha)_y^2)``."""
    _, _, lever = _resting(scene, jnp.asarray(alpha, jnp.float64))
    return jnp.sqrt(1.0 + scene.mass / scene.inertia * lever**2)


def floor_state(scene, alpha, p, energy=0.5) -> jax.Array:
    """The state ``(..., 6)`` at ``x = 0``, ``vx = 0`` just after the body at ``alpha`` bounces off the floor with
    ``p``, at the energy ``E'`` of the vertical motion and the turn; NaN where unreachable."""
    alpha, p = jnp.broadcast_arrays(jnp.asarray(alpha, jnp.float64), jnp.asarray(p, jnp.float64))
    _, height, lever = _resting(scene, alpha)
    mass, inertia = scene.mass, scene.inertia
    # In (a, b) = (sqrt(I) omega, sqrt(M) vy): the circle a^2 + b^2 = 2 E' cut by the line
    # (1, -sqrt(M/I) lever) . (a, b) = p sqrt(2 E'); the solution whose contact rises.
    radius = jnp.sqrt(2.0 * energy)
    w = jnp.sqrt(mass / inertia) * lever
    norm = jnp.sqrt(1.0 + w * w)
    along = p * radius / norm
    across = jnp.sqrt(jnp.where(radius**2 >= along**2, radius**2 - along**2, jnp.nan))
    unit_a, unit_b = 1.0 / norm, -w / norm
    solutions = []
    for sign in (1.0, -1.0):
        a = along * unit_a - sign * across * unit_b
        b = along * unit_b + sign * across * unit_a
        omega, vy = a / jnp.sqrt(inertia), b / jnp.sqrt(mass)
        solutions.append((omega, vy, vy + omega * lever > 0.0))
    (omega, vy, rising), (other_omega, other_vy, other_rising) = solutions
    omega, vy = jnp.where(rising, omega, other_omega), jnp.where(rising, vy, other_vy)
    zero = jnp.zeros_like(alpha)
    state = jnp.stack([zero, height, alpha, zero, vy, omega], axis=-1)
    lowest, _, _ = _resting(scene, alpha)
    ok = rising | other_rising
    for k in range(scene.body.contact_count):
        ok = jnp.where(lowest == k, ok & _leaving_and_inside(scene, state, k), ok)
    return jnp.where(ok[..., None], state, jnp.nan)


# -- the explorer's charts ------------------------------------------------------------------


def outline(scene, state) -> np.ndarray:
    """The body's outline ``(m, 2)`` at ``state`` ``(6,)``: its contact points joined (a dot for a point), or
    its rim."""
    state = np.asarray(state, dtype=np.float64)
    return state[:2] + np.asarray(scene.body.outline(state[2]))


def table_outline(scene, x_span=None) -> np.ndarray:
    """Points ``(m, 2)`` along the table's boundary (for a strip: its two walls over ``x_span``), NaN between
    separate walls."""
    table = scene.table
    if "floor" in table.section_names:
        low, high = x_span if x_span is not None else (-float(table.size), float(table.size))
        h = float(table.size)
        nan = np.array([[np.nan, np.nan]])
        return np.concatenate([[[low, 0.0], [high, 0.0]], nan, [[low, h], [high, h]]])
    s = np.linspace(0.0, float(table.boundary_length), 721)
    x, y, _ = table.boundary_point(jnp.asarray(s))
    points = np.stack([np.asarray(x), np.asarray(y)], axis=-1)
    # Where the boundary jumps (from the outer wall to an obstacle, or between obstacles) the line breaks: a
    # continuous boundary moves at most one arc-length step between samples.
    jumps = np.flatnonzero(np.linalg.norm(np.diff(points, axis=0), axis=-1) > 2.0 * (s[1] - s[0])) + 1
    return np.insert(points, jumps, np.nan, axis=0)


def draw_orbit(ax, scene, state0, orb, color, *, body_every: int = 1):
    """The table, the centre's path from ``state0`` through ``orb``'s collisions and the body at each one."""
    states = np.asarray(orb.state)
    path = np.concatenate([np.asarray(state0)[None, :2], states[:, :2]])
    span = (float(np.nanmin(path[:, 0])), float(np.nanmax(path[:, 0])))
    wall = table_outline(scene, (span[0] - 1.0, span[1] + 1.0))
    box = (*span, float(np.nanmin(path[:, 1])), float(np.nanmax(path[:, 1])))
    for ox, oy in scene.table.cells_covering(*box):  # a periodic table: the cells the path unfolds across
        ax.plot(wall[:, 0] + ox, wall[:, 1] + oy, color="k", lw=1.2)
    ax.plot(path[:, 0], path[:, 1], color=color, lw=0.8, alpha=0.9)
    if scene.body.kind != "point":
        for state in states[::body_every]:
            shape = outline(scene, state)
            ax.plot(shape[:, 0], shape[:, 1], color="0.3", lw=0.9, alpha=0.55)
    ax.plot(*path[0], "o", color=color, ms=5)
    ax.set_aspect("equal")
    ax.set_xlabel("x (length)")
    ax.set_ylabel("y (length)")


def birkhoff_seeds(scene, count: int, energy=0.5, arm_angle=0.0, spin=0.0):
    """``count`` states spread evenly (Halton) over the Birkhoff section ``[0, L) x (-1, 1)``; NaN where none."""
    index = np.arange(1, count + 1)
    s = halton(index, 2) * float(scene.table.boundary_length)
    p = 2.0 * halton(index, 3) - 1.0
    return birkhoff_state(scene, s, p, energy, arm_angle, spin)


def _first_contact_codes(scene, states):
    return jnp.asarray(scene.gap_codes)[touching_gap(scene, jnp.nan_to_num(states))]


def _birkhoff_start(scene, s, p, invariants):
    states = birkhoff_state(scene, s, p, invariants["energy"], invariants.get("arm_angle", 0.0))
    return states, _first_contact_codes(scene, states)


def _birkhoff_seeds(scene, count, invariants):
    states = birkhoff_seeds(scene, count, invariants["energy"], invariants.get("arm_angle", 0.0))
    return states, _first_contact_codes(scene, states)


def _unit_edge(scene, s, invariants):
    del invariants  # every p in [-1, 1] is reached with the body at rest
    ones = np.ones_like(np.asarray(s, dtype=np.float64))
    return np.stack([-ones, ones], axis=-1)


BIRKHOFF_CHART = SectionChart(
    title="Birkhoff section of the contact",
    axis_labels=(r"$s$: arc length of the contact round the table (length)", r"$p = \sqrt{M}\,v_t/\sqrt{2E}$"),
    invariant_symbols={"energy": "E"},
    default_invariants=lambda scene: {"energy": 0.5},
    x_range=lambda scene: (0.0, float(scene.table.boundary_length)),
    edge=_unit_edge,
    start=_birkhoff_start,
    seeds=_birkhoff_seeds,
    points=birkhoff_section,
    draw_configuration=draw_orbit,
)


def floor_seeds(scene, count: int, energy=0.5):
    """``count`` states spread evenly (Halton) over the floor section; NaN where unreachable."""
    index = np.arange(1, count + 1)
    period = 2.0 * np.pi / scene.body.turn_symmetry
    alpha = halton(index, 2) * period
    bound = np.asarray(floor_bound(scene, jnp.asarray(alpha)))
    p = (2.0 * halton(index, 3) - 1.0) * bound
    return floor_state(scene, alpha, p, energy)


def _floor_start(scene, alpha, p, invariants):
    states = floor_state(scene, alpha, p, invariants["energy"])
    return states, _first_contact_codes(scene, states)


def _floor_seeds(scene, count, invariants):
    states = floor_seeds(scene, count, invariants["energy"])
    return states, _first_contact_codes(scene, states)


def _floor_edge(scene, alpha, invariants):
    del invariants
    bound = np.asarray(floor_bound(scene, jnp.asarray(alpha, jnp.float64)))
    return np.stack([-bound, bound], axis=-1)


FLOOR_CHART = SectionChart(
    title="floor section",
    axis_labels=(
        r"$\alpha$ (radians, modulo the body's symmetry)",
        r"$p = (I\omega - M v_y r_{\alpha,y})/\sqrt{2IE'}$",
    ),
    invariant_symbols={"energy": "E'"},
    default_invariants=lambda scene: {"energy": 0.5},
    x_range=lambda scene: (0.0, 2.0 * np.pi / scene.body.turn_symmetry),
    edge=_floor_edge,
    start=_floor_start,
    seeds=_floor_seeds,
    points=floor_section,
    draw_configuration=draw_orbit,
)

CHARTS = {"birkhoff": BIRKHOFF_CHART, "floor": FLOOR_CHART}
SECTIONS = {"birkhoff": birkhoff_section, "floor": floor_section}
