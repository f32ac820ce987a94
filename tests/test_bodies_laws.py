"""Physical laws of bodies in tables, and what bad input gets, against references independent of jaxbill.

Every expected value here is computed in this file, with numpy, from the geometry alone: closed forms,
conservation laws, symmetries and Monte Carlo estimates. jaxbill only produces the orbits (and, for the
ensemble of the mean free path, draws the Liouville starts that the law is about).

* A point in a rectangle keeps the size of its velocity's component along each pair of sides.
* Any body in a circle keeps its energy and its angular momentum ``M (x vy - y vx) + I omega`` (the
  wall's push is radial); the inertias are the closed forms of the lamina and the point masses.
* A point in an ellipse keeps Joachimsthal's integral (derived at ``joachimsthal``).
* Santalo's formula: the mean free path of the billiard map's invariant measure is ``pi A / P`` for a
  point, and ``4 |Q| / |dQ|`` in the mass-weighted configuration space of a rigid body (derived at
  ``test_body_mean_free_path_is_santalos``).
* Time reversal retraces a chaotic orbit within the float64 horizon.
* Dense sampling of flights: no contact point leaves the table between collisions.
* A regular n-gon approaches its circumcircle: the first flight like ``n^-2``, the bounce like ``n^-1``.
* Bad input: a ``ValueError`` naming the parameter and its range; inside ``jit``, NaN.
"""

from __future__ import annotations

import functools
import json
import math
import os

import jax
import jax.numpy as jnp
import numpy as np
import pytest
import scipy.special

import jaxbill as jb

EPS = float(np.finfo(np.float64).eps)
_DATA = os.path.join(os.path.dirname(os.path.abspath(__file__)), "data", "bodies_reference.json")

TRIANGLE = np.array([[0.0, 0.0], [0.6, 0.0], [0.15, 0.4]])  # sides 0.6, 0.52, 0.43
PENTAGON = np.array([[1.1, -0.2], [0.7, 0.85], [-0.45, 0.95], [-1.05, 0.05], [-0.2, -0.95]])
HEXAGON = np.array([[1.0, -0.3], [0.9, 0.6], [0.1, 1.0], [-0.8, 0.7], [-1.1, -0.2], [-0.2, -0.9]])  # irregular
ARMS = (0.6, 0.2)  # a dumbbell's arms l1, l2: point masses m1 : m2 = l2 : l1 = 1 : 3
STADIUM = (1.0, 0.8)  # half_length, radius
ELLIPSE = (2.0, 1.2)  # semi-axes a, b
COIN = (0.4, 0.2)  # the elliptic disc's semi-axes
STRIP = 1.0


def _regular(n: int, radius: float) -> np.ndarray:
    angle = 2.0 * np.pi * np.arange(n) / n
    return radius * np.stack([np.cos(angle), np.sin(angle)], axis=1)


# ---------------------------------------------------------------------------
# the geometry, written here from the description of the bodies and tables
# ---------------------------------------------------------------------------
def rotated(alpha, points: np.ndarray) -> np.ndarray:
    """``R(alpha) b`` for body-frame points ``b`` ``(K, 2)``: shape ``(..., K, 2)``."""
    c, s = np.cos(alpha)[..., None], np.sin(alpha)[..., None]
    return np.stack([c * points[:, 0] - s * points[:, 1], s * points[:, 0] + c * points[:, 1]], axis=-1)


def cross(r: np.ndarray, n: np.ndarray) -> np.ndarray:
    """The planar cross product ``r x n`` over the last axis."""
    return r[..., 0] * n[..., 1] - r[..., 1] * n[..., 0]


def triangle_lamina(vertices: np.ndarray, mass: float = 1.0) -> tuple[np.ndarray, float]:
    """Corners about the centroid (a triangle's is its corners' mean) and ``I = M (a^2 + b^2 + c^2) / 36``."""
    sides2 = np.sum((vertices - np.roll(vertices, -1, axis=0)) ** 2)
    return vertices - vertices.mean(axis=0), mass * sides2 / 36.0


def square_lamina(circumradius: float, mass: float = 1.0) -> tuple[np.ndarray, float]:
    """The square with its corners at ``circumradius`` on the axes; ``I = M s^2 / 6`` for the side ``s = sqrt(2) r``."""
    return _regular(4, circumradius), mass * (2.0 * circumradius**2) / 6.0


def dumbbell(l1: float, l2: float, mass: float = 1.0) -> tuple[np.ndarray, float]:
    """Ends ``(l1, 0)`` and ``(-l2, 0)`` with the masses ``m1 = M l2/(l1+l2)`` and ``m2 = M l1/(l1+l2)`` (the centre
    of mass at the origin): ``I = m1 l1^2 + m2 l2^2``."""
    m1, m2 = mass * l2 / (l1 + l2), mass * l1 / (l1 + l2)
    return np.array([[l1, 0.0], [-l2, 0.0]]), m1 * l1**2 + m2 * l2**2


# Depths: how far a point lies inside a table (a length; < 0 outside), to first order at the wall.
def ellipse_depth(a, b, px, py):
    level = 1.0 - (px / a) ** 2 - (py / b) ** 2
    return level / (2.0 * np.hypot(px / a**2, py / b**2))


def stadium_depth(half_length, radius, px, py):
    return radius - np.hypot(px - np.clip(px, -half_length, half_length), py)


def polygon_depth(vertices, px, py):
    depth = np.full(np.shape(px), np.inf)
    for j in range(len(vertices)):
        edge = vertices[(j + 1) % len(vertices)] - vertices[j]
        inward = np.array([-edge[1], edge[0]]) / np.hypot(*edge)
        depth = np.minimum(depth, inward[0] * (px - vertices[j][0]) + inward[1] * (py - vertices[j][1]))
    return depth


# Boundaries by arc length ``s`` (anticlockwise): points and unit outward normals.
def polygon_boundary(vertices, s):
    edges = np.roll(vertices, -1, axis=0) - vertices
    lengths = np.hypot(edges[:, 0], edges[:, 1])
    starts = np.concatenate([[0.0], np.cumsum(lengths)])
    s = np.mod(s, starts[-1])
    j = np.minimum(np.searchsorted(starts, s, side="right") - 1, len(vertices) - 1)
    point = vertices[j] + ((s - starts[j]) / lengths[j])[:, None] * edges[j]
    normal = np.stack([edges[j, 1], -edges[j, 0]], axis=-1) / lengths[j][:, None]
    return point, normal


def stadium_boundary(half_length, radius, s):
    """From ``(L + r, 0)``: the right cap's upper quarter, the top side, the left cap, the bottom, the rest."""
    L, r = half_length, radius
    s = np.mod(s, 4.0 * L + 2.0 * np.pi * r)
    quarter = 0.5 * np.pi * r
    ends = np.cumsum([quarter, 2.0 * L, 2.0 * quarter, 2.0 * L])
    part = np.searchsorted(ends, s, side="right")
    cap_x = np.where((part == 2), -L, L)
    angle = np.select(
        [part == 0, part == 2, part == 4],
        [s / r, (s - ends[1]) / r + 0.5 * np.pi, (s - ends[3]) / r - 0.5 * np.pi],
        0.0,
    )
    on_cap = (part == 0) | (part == 2) | (part == 4)
    normal = np.where(on_cap[:, None], np.stack([np.cos(angle), np.sin(angle)], -1), 0.0)
    normal[part == 1] = (0.0, 1.0)
    normal[part == 3] = (0.0, -1.0)
    x = np.select([on_cap, part == 1, part == 3], [cap_x + r * np.cos(angle), L - (s - ends[0]), s - ends[2] - L])
    y = np.select([on_cap, part == 1, part == 3], [r * np.sin(angle), np.full_like(s, r), np.full_like(s, -r)])
    return np.stack([x, y], axis=-1), normal


def ellipse_boundary(a, b, theta):
    """Points ``(a cos theta, b sin theta)``, unit outward normals and the speed ``ds / d theta``."""
    point = np.stack([a * np.cos(theta), b * np.sin(theta)], axis=-1)
    speed = np.hypot(a * np.sin(theta), b * np.cos(theta))
    normal = np.stack([b * np.cos(theta), a * np.sin(theta)], axis=-1) / speed[:, None]
    return point, normal, speed


def ellipse_perimeter(a, b, nodes: int = 4096) -> float:
    """``int_0^{2 pi} |W'(theta)| d theta`` by the trapezoidal rule: exponentially accurate for a periodic integrand."""
    theta = 2.0 * np.pi * np.arange(nodes) / nodes
    return float(2.0 * np.pi * np.mean(np.hypot(a * np.sin(theta), b * np.cos(theta))))


def polygon_area_and_perimeter(vertices) -> tuple[float, float]:
    following = np.roll(vertices, -1, axis=0)
    area = 0.5 * np.sum(vertices[:, 0] * following[:, 1] - following[:, 0] * vertices[:, 1])
    return float(area), float(np.sum(np.hypot(*(following - vertices).T)))


@pytest.mark.parametrize("wall", ["stadium", "ellipse", "hexagon"])
def test_the_reference_walls_are_the_tables(wall):
    """The boundaries used for Santalo's formula: on the wall (depth 0), the normal pointing where the depth
    falls, and ``ds`` the arc length (central differences); the ellipse's perimeter by quadrature equals
    ``4 a E(e^2)`` (scipy's complete elliptic integral)."""
    rng = np.random.default_rng(1)
    u, h = rng.uniform(0.0, 2.0 * np.pi, 2000), 1e-6
    if wall == "stadium":
        depth = functools.partial(stadium_depth, *STADIUM)

        def parametrised(u):
            return (*stadium_boundary(*STADIUM, u), np.ones_like(u))

    elif wall == "ellipse":
        depth = functools.partial(ellipse_depth, *ELLIPSE)
        parametrised = functools.partial(ellipse_boundary, *ELLIPSE)
        a, b = ELLIPSE
        assert ellipse_perimeter(a, b) == pytest.approx(4.0 * a * scipy.special.ellipe(1.0 - (b / a) ** 2), rel=1e-14)
    else:
        depth = functools.partial(polygon_depth, HEXAGON)

        def parametrised(u):
            return (*polygon_boundary(HEXAGON, u), np.ones_like(u))

    point, normal, speed = parametrised(u)
    assert np.max(np.abs(depth(point[:, 0], point[:, 1]))) <= 1e-15
    assert np.max(np.abs(np.hypot(normal[:, 0], normal[:, 1]) - 1.0)) <= 1e-15
    inside, outside = point - h * normal, point + h * normal
    assert np.allclose(depth(inside[:, 0], inside[:, 1]), h, rtol=1e-4)
    assert np.allclose(depth(outside[:, 0], outside[:, 1]), -h, rtol=1e-4)
    ahead, behind = parametrised(u + h)[0], parametrised(u - h)[0]
    chord = np.hypot(*(ahead - behind).T) / (2.0 * h)
    if wall == "hexagon":  # a chord across a corner is shorter than the arc: leave those out
        corners = np.cumsum(np.hypot(*(np.roll(HEXAGON, -1, axis=0) - HEXAGON).T))
        away = np.min(np.abs(np.mod(u, corners[-1])[:, None] - np.concatenate([[0.0], corners])), axis=1) > 2 * h
        chord, speed = chord[away], speed[away]
    assert np.max(np.abs(chord - speed)) <= 1e-9


# ---------------------------------------------------------------------------
# scenes and orbits shared by the tests (compilation dominates: each is built once)
# ---------------------------------------------------------------------------
@functools.cache
def scene(name: str) -> jb.BodyInTable:
    bodies = {
        "triangle": lambda: jb.PolygonBody(TRIANGLE),
        "dumbbell": lambda: jb.Dumbbell(*ARMS),
        "square": lambda: jb.PolygonBody.regular(4, 0.3),
        "small_square": lambda: jb.PolygonBody.regular(4, 0.25),
        "coin": lambda: jb.EllipseBody(*COIN),
        "point": lambda: jb.PointBody(),
    }
    tables = {
        "circle": lambda: jb.Circle(1.0),
        "stadium": lambda: jb.Stadium(*STADIUM),
        "ellipse": lambda: jb.Ellipse(*ELLIPSE),
        "strip": lambda: jb.Strip(STRIP),
        "pentagon": lambda: jb.Polygon(PENTAGON),
        "function": lambda: jb.ConvexTable(quartic_oval, (-2.0, 2.0, -1.5, 1.5)),
    }
    body, table = name.split("_in_")
    return jb.BodyInTable(bodies[body](), tables[table]())


# A smooth convex table for jb.ConvexTable: an ellipse pushed out along x by a quartic.
OVAL = (1.6, 1.1, 0.2)


def quartic_oval(x, y):
    a, b, c = OVAL
    return (x / a) ** 2 + (y / b) ** 2 + c * (x / a) ** 4 - 1.0


def quartic_oval_depth(px, py):
    a, b, c = OVAL
    level = (px / a) ** 2 + (py / b) ** 2 + c * (px / a) ** 4 - 1.0
    gradient = np.hypot(2.0 * px / a**2 + 4.0 * c * px**3 / a**4, 2.0 * py / b**2)
    return -level / gradient


LONG_RUN = 300
STARTS = {
    "triangle_in_stadium": [0.3, 0.1, 0.4, 0.8, 0.55, 1.7],
    "dumbbell_in_ellipse": [0.2, -0.1, 0.5, 0.9, 0.4, 1.9],
    "coin_in_strip": [0.0, 0.5, 0.3, 0.4, 0.9, 2.1],
    "small_square_in_strip": [0.0, 0.5, 0.2, 0.7, -0.4, 2.2],
    "dumbbell_in_function": [0.1, 0.1, 0.4, 0.8, 0.5, 1.5],
}


@functools.cache
def long_orbit(name: str, start: tuple | None = None):
    """``(t, states)`` of ``LONG_RUN`` collisions from ``start`` (default ``STARTS[name]``), as numpy."""
    state0 = jnp.asarray(STARTS[name] if start is None else start, dtype=jnp.float64)
    orbit = jb.orbit(scene(name), state0, LONG_RUN)
    return np.asarray(orbit.t), np.asarray(orbit.state)


def contact_depths(name: str, states: np.ndarray) -> np.ndarray:
    """How deep inside the table each contact of the body is, ``(..., K)`` (own formulas)."""
    body, table = name.split("_in_")
    x, y, alpha = states[..., 0], states[..., 1], states[..., 2]
    if body == "coin":
        a, b = COIN
        reach = np.hypot(a * np.sin(alpha), b * np.cos(alpha))  # the disc's half height at alpha
        return np.stack([y - reach, STRIP - y - reach], axis=-1)
    points = {
        "triangle": lambda: triangle_lamina(TRIANGLE)[0],
        "dumbbell": lambda: dumbbell(*ARMS)[0],
        "small_square": lambda: square_lamina(0.25)[0],
        "point": lambda: np.zeros((1, 2)),
    }[body]()
    contact = rotated(alpha, points)
    px, py = x[..., None] + contact[..., 0], y[..., None] + contact[..., 1]
    return {
        "stadium": lambda: stadium_depth(*STADIUM, px, py),
        "ellipse": lambda: ellipse_depth(*ELLIPSE, px, py),
        "strip": lambda: np.minimum(py, STRIP - py),
        "function": lambda: quartic_oval_depth(px, py),
    }[table]()


TABLE_SIZE = {"stadium": sum(STADIUM), "ellipse": max(ELLIPSE), "strip": STRIP, "function": 2.0}


# ---------------------------------------------------------------------------
# 1. a point in a rectangle
# ---------------------------------------------------------------------------
RECTANGLE = np.array([[-1.3, -0.7], [1.3, -0.7], [1.3, 0.7], [-1.3, 0.7]])
RECTANGLE_RUN = 2000


@pytest.mark.parametrize("turn", [0.0, 0.37], ids=["along_axes", "turned"])
def test_point_in_a_rectangle_keeps_both_speed_components(turn):
    """Each bounce reverses the component normal to its side and keeps the other, so ``|v . u|`` and
    ``|v . w|`` (``u``, ``w`` along the sides) never change. Each reflection rounds the velocity by a few ulps
    of ``|v|``; over ``n`` collisions these add at worst linearly: tolerance ``8 n eps |v|`` (3.6e-12)."""
    u, w = np.array([math.cos(turn), math.sin(turn)]), np.array([-math.sin(turn), math.cos(turn)])
    corners = RECTANGLE @ np.stack([u, w])  # the rectangle turned by ``turn``
    rectangle = jb.BodyInTable(jb.PointBody(), jb.Polygon(corners))
    v0 = 0.6 * u + 0.8 * w
    start = jnp.asarray([*(0.1 * u + 0.2 * w), 0.0, *v0, 0.0])
    orbit = jb.orbit(rectangle, start, RECTANGLE_RUN)
    v, contact = np.asarray(orbit.state)[:, 3:5], np.asarray(orbit.contact)
    assert np.all(np.bincount(contact, minlength=7)[3:] >= 200), "every side hit often"
    drift = max(np.max(np.abs(np.abs(v @ u) - 0.6)), np.max(np.abs(np.abs(v @ w) - 0.8)))
    assert drift <= 8 * RECTANGLE_RUN * EPS
    # The law is not empty: the components do flip, and a wrong normal would mix them.
    assert np.ptp(np.sign(v @ u)) == 2 and np.ptp(np.sign(v @ w)) == 2


# ---------------------------------------------------------------------------
# 2. any body in a circle: energy and angular momentum
# ---------------------------------------------------------------------------
CIRCLE_RUN = 500
IN_CIRCLE = {
    "triangle_in_circle": (lambda: triangle_lamina(TRIANGLE)[1], [0.1, 0.05, 0.3, 0.7, -0.3, 2.0]),
    "dumbbell_in_circle": (lambda: dumbbell(*ARMS)[1], [0.2, -0.1, 0.5, 0.9, 0.4, 1.9]),
    "square_in_circle": (lambda: square_lamina(0.3)[1], [-0.2, 0.1, 0.1, -0.5, 0.8, -3.0]),
}


@pytest.mark.parametrize("name", list(IN_CIRCLE))
def test_body_in_a_circle_keeps_energy_and_angular_momentum(name):
    """The circle's wall pushes along the radius through the contact, so its torque about the centre of
    the circle vanishes: ``L = M (x vy - y vx) + I omega`` is conserved, as is ``E = M |v|^2/2 + I omega^2/2``
    (``M = 1``, ``I`` the closed form). Relative to the largest ``|L|`` at that energy,
    ``sqrt(2E (M R^2 + I))`` (Cauchy-Schwarz in the mass-weighted velocities), and to ``E``: a few ulps per
    collision, at worst linearly: ``4 n eps`` (4.4e-13)."""
    inertia_of, start = IN_CIRCLE[name]
    inertia = inertia_of()
    sc = scene(name)
    assert float(sc.inertia) == pytest.approx(inertia, rel=1e-14)
    s = np.vstack([start, np.asarray(jb.orbit(sc, jnp.asarray(start), CIRCLE_RUN).state)])
    x, y, vx, vy, omega = (s[:, i] for i in (0, 1, 3, 4, 5))
    momentum = (x * vy - y * vx) + inertia * omega
    energy = 0.5 * (vx**2 + vy**2) + 0.5 * inertia * omega**2
    scale = math.sqrt(2.0 * energy[0] * (1.0 + inertia))
    assert np.max(np.abs(momentum - momentum[0])) / scale <= 4 * CIRCLE_RUN * EPS
    assert np.max(np.abs(energy - energy[0])) / energy[0] <= 4 * CIRCLE_RUN * EPS
    # Not conserved piece by piece: the collisions trade spin for orbital motion.
    assert np.ptp(inertia * omega) > 0.1 * scale


# ---------------------------------------------------------------------------
# 3. a point in an ellipse: Joachimsthal's integral
# ---------------------------------------------------------------------------
def joachimsthal(a, b, states: np.ndarray) -> np.ndarray:
    """``F = <A^-1 v, v> (1 - <A^-1 x, x>) + <A^-1 x, v>^2`` with ``A = diag(a^2, b^2)``.

    Along a flight ``x + v t``: ``d/dt <A^-1 x, x> = 2 <A^-1 x, v>`` and ``d/dt <A^-1 x, v> = <A^-1 v, v>``,
    so ``dF/dt = -2 <A^-1 v, v> <A^-1 x, v> + 2 <A^-1 x, v> <A^-1 v, v> = 0``. At a bounce ``x`` is on the
    wall (``<A^-1 x, x> = 1``, ``F = <A^-1 x, v>^2``) and the normal there is ``n = A^-1 x / |A^-1 x|``:
    ``v' = v - 2 (v . n) n`` gives ``<A^-1 x, v'> = <A^-1 x, v> - 2 <A^-1 x, v> = -<A^-1 x, v>``: ``F``
    is unchanged. (For the ellipse's own ``A`` only: another ``A`` has another normal.)
    """
    x, y, vx, vy = states[..., 0], states[..., 1], states[..., 3], states[..., 4]
    vv = vx**2 / a**2 + vy**2 / b**2
    xx = x**2 / a**2 + y**2 / b**2
    xv = x * vx / a**2 + y * vy / b**2
    return vv * (1.0 - xx) + xv**2


ELLIPSE_RUN = 2000


def test_point_in_an_ellipse_keeps_joachimsthals_integral():
    """``F`` at the start (inside) and just after each of 2000 bounces, relative to ``|v|^2 / b^2`` (its
    largest value): a few ulps per collision, at worst linearly: ``4 n eps`` (1.8e-12). The same ``F``
    written for an ellipse 0.1% wider is not conserved along the same orbit: the test can fail."""
    a, b = ELLIPSE
    start = np.array([0.3, -0.2, 0.0, math.cos(0.7), math.sin(0.7), 0.0])
    states = np.vstack([start, np.asarray(jb.orbit(scene("point_in_ellipse"), jnp.asarray(start), ELLIPSE_RUN).state)])
    scale = 1.0 / b**2
    drift = np.max(np.abs(joachimsthal(a, b, states) - joachimsthal(a, b, start))) / scale
    assert drift <= 4 * ELLIPSE_RUN * EPS
    wrong = joachimsthal(1.001 * a, b, states)
    assert np.ptp(wrong) / scale > 1e6 * 4 * ELLIPSE_RUN * EPS


# ---------------------------------------------------------------------------
# 4. Santalo's mean free path
# ---------------------------------------------------------------------------
FLIGHTS = 30_000  # starts per table: a standard error near 0.2% of the mean


def _outgoing(points, normals, p):
    """States leaving the wall at ``points`` with ``p = sin`` of the angle to the inward normal, speed 1."""
    tangent = np.stack([-normals[:, 1], normals[:, 0]], axis=-1)
    v = p[:, None] * tangent - np.sqrt(1.0 - p * p)[:, None] * normals
    zero = np.zeros(len(p))
    return np.column_stack([points, zero, v, zero])


def santalo_case(name: str, rng) -> tuple[jb.Table, np.ndarray, float]:
    """``(table, starts uniform in (s, p), pi A / P)`` with ``A`` and ``P`` from closed forms (the ellipse's
    perimeter by quadrature, the polygons' by their sides and the shoelace formula)."""
    p = rng.uniform(-1.0, 1.0, FLIGHTS)
    if name == "circle":
        phi = rng.uniform(0.0, 2.0 * np.pi, FLIGHTS)
        normals = np.stack([np.cos(phi), np.sin(phi)], axis=-1)
        return jb.Circle(1.0), _outgoing(normals, normals, p), math.pi * math.pi / (2.0 * math.pi)
    if name == "ellipse":
        a, b = ELLIPSE
        # Uniform in arc length: theta uniform, kept with probability |W'(theta)| / max(a, b).
        theta = rng.uniform(0.0, 2.0 * np.pi, 3 * FLIGHTS)
        keep = rng.uniform(0.0, max(a, b), 3 * FLIGHTS) < np.hypot(a * np.sin(theta), b * np.cos(theta))
        points, normals, _ = ellipse_boundary(a, b, theta[keep][:FLIGHTS])
        return jb.Ellipse(a, b), _outgoing(points, normals, p), math.pi * (math.pi * a * b) / ellipse_perimeter(a, b)
    if name == "stadium":
        L, r = STADIUM
        perimeter = 4.0 * L + 2.0 * math.pi * r
        points, normals = stadium_boundary(L, r, perimeter * rng.uniform(size=FLIGHTS))
        return jb.Stadium(L, r), _outgoing(points, normals, p), math.pi * (4 * L * r + math.pi * r * r) / perimeter
    corners = _regular(6, 1.0) if name == "regular_hexagon" else HEXAGON
    area, perimeter = polygon_area_and_perimeter(corners)
    points, normals = polygon_boundary(corners, perimeter * rng.uniform(size=FLIGHTS))
    return jb.Polygon(corners), _outgoing(points, normals, p), math.pi * area / perimeter


SANTALO_TABLES = ["circle", "ellipse", "stadium", "regular_hexagon", "hexagon"]


@pytest.mark.parametrize("name", SANTALO_TABLES)
def test_point_mean_free_path_is_santalos(name):
    """Starts uniform in the Birkhoff coordinates ``(s, p)`` (the billiard map's invariant measure
    ``ds dp``): their first flights average ``pi A / P`` (the formula is derived at
    ``test_body_mean_free_path_is_santalos``). Within 4 standard errors of the sample mean, which is below
    0.5% of it."""
    table, starts, expected = santalo_case(name, np.random.default_rng(SANTALO_TABLES.index(name) + 11))
    flights = np.asarray(jb.orbit(jb.BodyInTable(jb.PointBody(), table), jnp.asarray(starts), 1).t)[:, 0]
    assert np.all(np.isfinite(flights)) and np.all(flights > 0.0)
    mean, error = float(np.mean(flights)), float(np.std(flights, ddof=1)) / math.sqrt(len(flights))
    assert error < 0.005 * expected
    assert abs(mean - expected) <= 4.0 * error, f"{mean:.6g} vs pi A / P = {expected:.6g} ({error:.2g})"


ENSEMBLES = {  # orbits, and the window [0, T]: about five mean free times at E = 1/2
    "point_in_ellipse": (20_000, 12.0),
    "triangle_in_stadium": (8000, 6.0),
    "dumbbell_in_ellipse": (8000, 9.0),
}
WINDOW_CHUNK = 32  # collisions per run; an orbit still short of the window is run on
MC_SAMPLES = 500_000


def configuration_volume(points, depth, box, rng) -> tuple[float, float]:
    """The volume ``V`` of ``{(x, y, alpha) : every contact inside}`` (``alpha`` over ``2 pi``) and its error."""
    x_low, x_high, y_low, y_high = box
    x, y = rng.uniform(x_low, x_high, MC_SAMPLES), rng.uniform(y_low, y_high, MC_SAMPLES)
    contact = rotated(rng.uniform(-np.pi, np.pi, MC_SAMPLES), points)
    inside = np.all(depth(x[:, None] + contact[..., 0], y[:, None] + contact[..., 1]) >= 0.0, axis=1)
    whole = (x_high - x_low) * (y_high - y_low) * 2.0 * np.pi
    fraction = float(np.mean(inside))
    return whole * fraction, whole * math.sqrt(fraction * (1.0 - fraction) / MC_SAMPLES)


def configuration_boundary(points, mass, inertia, depth, wall, span, rng) -> tuple[float, float]:
    """``|dQ|``: the sum over the contacts ``k`` of ``int ds d alpha sqrt(M I + M^2 (r_k x N)^2)`` over the
    wall's points ``W`` (``wall(u) -> (W, N, ds/du)``, ``u`` over ``span``) and the orientations at which, with
    contact ``k`` at ``W``, every other contact is inside; and its error."""
    total, variance = 0.0, 0.0
    for k in range(len(points)):
        on_wall, normal, speed = wall(rng.uniform(0.0, span, MC_SAMPLES))
        contact = rotated(rng.uniform(-np.pi, np.pi, MC_SAMPLES), points)
        centre = on_wall - contact[:, k]
        others = [j for j in range(len(points)) if j != k]
        inside = np.all(
            depth(centre[:, 0, None] + contact[:, others, 0], centre[:, 1, None] + contact[:, others, 1]) >= 0.0, axis=1
        )
        lever = cross(contact[:, k], normal)
        weight = np.where(inside, speed * np.sqrt(mass * inertia + mass**2 * lever**2), 0.0)
        total += span * 2.0 * np.pi * float(np.mean(weight))
        variance += (span * 2.0 * np.pi) ** 2 * float(np.var(weight)) / MC_SAMPLES
    return total, math.sqrt(variance)


def _stadium_wall(half_length, radius, s):
    return (*stadium_boundary(half_length, radius, s), np.ones_like(s))


def santalo_reference(name: str, rng) -> tuple[float, float]:
    """``4 |Q| / |dQ|`` in the mass-weighted coordinates (``M = 1``), with its Monte Carlo error (for the
    point: ``pi A / P``, exact)."""
    if name == "point_in_ellipse":
        a, b = ELLIPSE
        return math.pi * (math.pi * a * b) / ellipse_perimeter(a, b), 0.0
    if name == "triangle_in_stadium":
        points, inertia = triangle_lamina(TRIANGLE)
        L, r = STADIUM
        box, span = (-L - r, L + r, -r, r), 4.0 * L + 2.0 * math.pi * r
        depth = functools.partial(stadium_depth, L, r)
        wall = functools.partial(_stadium_wall, L, r)
    else:
        points, inertia = dumbbell(*ARMS)
        a, b = ELLIPSE
        box, span = (-a, a, -b, b), 2.0 * math.pi
        depth = functools.partial(ellipse_depth, a, b)
        wall = functools.partial(ellipse_boundary, a, b)
    volume, volume_error = configuration_volume(points, depth, box, rng)
    area, area_error = configuration_boundary(points, 1.0, inertia, depth, wall, span, rng)
    path = 4.0 * math.sqrt(inertia) * volume / area  # |Q| = M sqrt(I) V
    return path, path * math.hypot(volume_error / volume, area_error / area)


def collisions_in_window(sc, states: np.ndarray, window: float) -> np.ndarray:
    """Per orbit, the number of collisions at times ``<= window``."""
    counts = np.zeros(len(states), int)
    elapsed = np.zeros(len(states))
    running = np.ones(len(states), bool)
    while np.any(running):
        orbit = jb.orbit(sc, jnp.asarray(states), WINDOW_CHUNK)
        times = elapsed[:, None] + np.asarray(orbit.t)
        assert np.all(np.isfinite(times))
        counts += np.sum((times <= window) & running[:, None], axis=1)
        running &= times[:, -1] <= window
        elapsed, states = times[:, -1], np.asarray(orbit.state)[:, -1]
    return counts


@pytest.mark.parametrize("name", list(ENSEMBLES))
def test_body_mean_free_path_is_santalos(name):
    r"""A rigid body's mean free path in its mass-weighted configuration space is Santalo's ``4 |Q| / |dQ|``
    (a point's, in the same ensemble: ``pi A / P``).

    Santalo's formula in ``d`` dimensions. A point flies at unit speed in a table ``Q`` of ``R^d`` and
    reflects specularly at ``dQ``. Liouville's measure ``dq d omega`` on ``Q x S^{d-1}`` is invariant, of
    total ``|Q| |S^{d-1}|``. Its flux through the wall, the billiard map's invariant measure on outgoing
    states ``(q on dQ, omega)``, is ``cos(theta) d sigma d omega`` (``theta`` the angle to the inward
    normal), of total ``|dQ| int_{hemisphere} cos(theta) d omega = |dQ| |B^{d-1}|`` (``cos(theta) d omega``
    is the area element of the hemisphere projected onto its equatorial unit ball). Each phase point is on
    one flight, at a time ``tau`` in ``[0, l)`` after its start, and ``dq d omega = cos(theta) d sigma d
    omega d tau`` (the flow box), so ``|Q| |S^{d-1}| = int l cos(theta) d sigma d omega``: the mean flight
    over the map's measure is

        <l> = |S^{d-1}| |Q| / (|B^{d-1}| |dQ|):    pi A / P in 2D,    4 V / S in 3D.

    A body. In ``q = (sqrt(M) x, sqrt(M) y, sqrt(I) alpha)`` the kinetic energy is ``|dq/dt|^2 / 2`` and the
    frictionless elastic impulse is the specular reflection of ``dq/dt`` about the gap's gradient in ``q``:
    the body is a point billiard in the 3D table ``Q = {every contact inside}`` (``alpha`` periodic), at
    the speed ``sqrt(2E)``. ``|Q| = M sqrt(I) V``, ``V`` its volume in ``(x, y, alpha)``. By the coarea
    formula the wall where contact ``k`` touches has the area ``M sqrt(I) int delta(g_k) |grad_q g_k|
    dx dy d alpha`` with ``|grad_q g|^2 = (g_x^2 + g_y^2) / M + g_alpha^2 / I`` (the metric
    ``diag(1/M, 1/M, 1/I)``). For ``g_k`` the contact's depth inside the wall, ``|grad_xy g_k| = 1`` and
    ``g_alpha = -N . dr_k/d alpha = -(r_k x N)``, and at fixed ``alpha`` the delta over the translations
    integrates to the arc length ``s`` of the wall: ``|dQ| = sum_k int ds d alpha sqrt(M I + M^2 (r_k x
    N)^2)``, over the ``(s, alpha)`` at which every other contact is inside. Both integrals are Monte Carlo
    estimates here (numpy, this file's own geometry).

    jaxbill. The same flow-box argument is Kac's lemma: for a stationary ensemble (Liouville's measure on
    the energy shell, ``jb.sample_energy_shell``) the expected number of collisions in ``[0, T]`` is
    ``T / tau`` exactly, ``tau`` the mean free time of the map's measure; so ``tau = T N_orbits /
    N_collisions`` and ``<l> = sqrt(2E) tau``. Both Monte Carlo errors enter the 4-sigma tolerance.
    """
    sc = scene(name)
    orbits, window = ENSEMBLES[name]
    seed = list(ENSEMBLES).index(name) + 21
    reference, reference_error = santalo_reference(name, np.random.default_rng(seed))
    states, _ = jb.sample_energy_shell(sc, orbits, energy=0.5, seed=seed)
    counts = collisions_in_window(sc, states, window)
    tau = window / float(np.mean(counts))
    tau_error = tau * float(np.std(counts, ddof=1)) / math.sqrt(len(counts)) / float(np.mean(counts))
    path = math.sqrt(2.0 * 0.5) * tau
    error = math.hypot(tau_error, reference_error)
    assert error < 0.008 * reference, "too few samples to test anything"
    assert abs(path - reference) <= 4.0 * error, f"{path:.5g} vs 4|Q|/|dQ| = {reference:.5g} ({error:.2g})"


# ---------------------------------------------------------------------------
# 5. time reversal
# ---------------------------------------------------------------------------
with open(_DATA) as _file:
    _CASES = {c["name"]: c for c in json.load(_file)["cases"]}
REVERSED = {
    "triangle_in_stadium": "triangle_stadium_a",
    "dumbbell_in_ellipse": "dumbbell_ellipse_a",
    "coin_in_strip": "coin_strip_a",
}


def _angle_gap(a, b):
    return np.abs(np.mod(a - b + np.pi, 2.0 * np.pi) - np.pi)


@pytest.mark.parametrize("name", list(REVERSED))
def test_time_reversal_retraces_the_orbit(name):
    """Run ``n`` collisions (``n`` the horizon within which the mpmath reference found two starts 1e-15
    apart to stay within 1e-11), fly half way to the next one, reverse ``v`` and ``omega`` and run ``n``
    again: collision ``k`` of the reversed run is where collision ``n + 1 - k`` of the forward run was, at
    the reversed time, leaving with the forward velocity that arrived there, reversed; a last flight of
    ``t_1`` brings the body back to its start. Tolerance ``1e-10`` of the table's size (velocities: of
    their scale): the forward run's rounding, amplified at most ``1e4`` within the horizon, twice."""
    case = _CASES[REVERSED[name]]
    assert case["state0"] == STARTS[name]
    n = case["horizon"]
    t, s = long_orbit(name)
    t, s = np.concatenate([[0.0], t]), np.vstack([STARTS[name], s])  # collision j at t[j], leaving as s[j]
    half = 0.5 * (t[n + 1] - t[n])
    middle = s[n] + half * np.concatenate([s[n, 3:], np.zeros(3)])
    tr, sr = long_orbit(name, tuple(middle * np.array([1, 1, 1, -1, -1, -1])))
    tr, sr = np.concatenate([[0.0], tr]), np.vstack([middle, sr])  # the same indexing
    size = TABLE_SIZE[name.split("_in_")[1]]
    speed = math.hypot(s[0, 3], s[0, 4])
    spin = math.sqrt(2.0 * float(scene(name).energy(jnp.asarray(s[0]))) / float(scene(name).inertia))
    for k in range(1, n + 1):
        there, arriving, got = s[n + 1 - k], s[n - k], sr[k]
        assert abs(tr[k] - (t[n] + half - t[n + 1 - k])) <= 1e-10 * size / speed, k
        assert np.max(np.abs(got[:2] - there[:2])) <= 1e-10 * size, k
        assert _angle_gap(got[2], there[2]) <= 1e-10, k
        assert np.max(np.abs(got[3:5] + arriving[3:5])) <= 1e-10 * speed, k
        assert abs(got[5] + arriving[5]) <= 1e-10 * spin, k
    home = sr[n, :3] + t[1] * sr[n, 3:]
    assert np.max(np.abs(home[:2] - s[0, :2])) <= 1e-10 * size
    assert _angle_gap(home[2], s[0, 2]) <= 1e-10


# ---------------------------------------------------------------------------
# 6. dense sampling of flights
# ---------------------------------------------------------------------------
SAMPLES_PER_FLIGHT = 50


@pytest.mark.parametrize("name", list(STARTS))
def test_no_contact_leaves_the_table_between_collisions(name):
    """50 points inside each of 300 flights, the contacts placed by this file's own geometry: none is
    outside the table by more than 1e-12 of its size. At each collision one contact is on the wall (to
    the same tolerance): the collisions are where this file's geometry puts the walls."""
    t, s = long_orbit(name)
    assert np.all(np.isfinite(t))
    starts = np.vstack([STARTS[name], s[:-1]])
    durations = np.diff(np.concatenate([[0.0], t]))
    times = durations[:, None] * ((np.arange(SAMPLES_PER_FLIGHT) + 0.5) / SAMPLES_PER_FLIGHT)
    many = np.broadcast_to(starts[:, None, :], (*times.shape, 6))
    moved = np.asarray(scene(name).flight(jnp.asarray(many), jnp.asarray(times)))
    straight = starts[:, None, :2] + times[..., None] * starts[:, None, 3:5]
    size = TABLE_SIZE[name.split("_in_")[1]]
    assert np.max(np.abs(moved[..., :2] - straight)) <= 1e-14 * size
    assert np.min(contact_depths(name, moved)) >= -1e-12 * size
    at_collisions = contact_depths(name, s)
    assert np.max(np.abs(np.min(at_collisions, axis=-1))) <= 1e-12 * size


# ---------------------------------------------------------------------------
# 7. the regular n-gon approaches its circumcircle
# ---------------------------------------------------------------------------
NGON_SIDES = (3, 6)
# The ray's polar angle: n angle / (2 pi) has the fractional part 1/3 or 2/3 for every n above, so the ray
# meets a side a third of the way along it, at the angle pi / (3n) to that side's normal.
RAY_ANGLE = 2.0 * math.pi / 9.0
GENERIC_START = (0.3, -0.2, 0.0, math.cos(1.0), math.sin(1.0), 0.0)


@functools.cache
def first_bounce(sides: int | None):
    """``(t (2,), state (2, 6))``: the first collision in the regular ``sides``-gon of circumradius 1 (``None``:
    the unit circle) from the centre along ``RAY_ANGLE`` and from ``GENERIC_START``."""
    table = jb.Circle(1.0) if sides is None else jb.Polygon.regular(sides, 1.0)
    starts = np.array([[0.0, 0.0, 0.0, math.cos(RAY_ANGLE), math.sin(RAY_ANGLE), 0.0], GENERIC_START])
    # As many as the mean free path's batches: the circle's and the hexagon's programs are compiled once.
    starts = starts[np.arange(FLIGHTS) % 2]
    orbit = jb.orbit(jb.BodyInTable(jb.PointBody(), table), jnp.asarray(starts), 1)
    return np.asarray(orbit.t)[:2, 0], np.asarray(orbit.state)[:2, 0]


def test_regular_polygon_approaches_the_circle():
    """From the centre, the side met a third of the way along lies at ``cos(pi/n)`` from the centre and
    turns by ``pi/(3n)`` from the ray: the flight is ``cos(pi/n) / cos(pi/(3n))`` (the circle's: 1) and the
    bounce turns the ray back ``2 pi/(3n)`` off its own line (the circle sends it straight back). With
    ``a = pi/n`` the flight's deficit is ``(4/9) a^2 (1 - a^2/27 + O(a^4))``: it falls like ``n^-2``, by
    ``4 (1 - pi^2/(36 n^2))`` from ``n`` to ``2n``, up to ``O(n^-4)`` terms, which for ``n >= 3`` (``a^2 < 1.1``)
    stay within 10% of that correction; the bounce's deviation falls like ``n^-1``, halving exactly."""
    circle_t, circle_state = first_bounce(None)
    assert circle_t[0] == pytest.approx(1.0, rel=1e-15)
    ray = np.array([math.cos(RAY_ANGLE), math.sin(RAY_ANGLE)])
    assert np.max(np.abs(circle_state[0, 3:5] + ray)) <= 4 * EPS
    deficits, deviations = [], []
    for n in NGON_SIDES:
        t, state = first_bounce(n)
        assert t[0] == pytest.approx(math.cos(math.pi / n) / math.cos(math.pi / (3 * n)), rel=1e-14)
        deficits.append(circle_t[0] - t[0])
        back = state[0, 3:5]
        deviations.append(math.atan2(abs(cross(back, -ray)), -(back @ ray)))
        assert deviations[-1] == pytest.approx(2.0 * math.pi / (3 * n), rel=1e-13)
    for (n, shrink), halving in zip(
        zip(NGON_SIDES, np.divide(deficits[:-1], deficits[1:])), np.divide(deviations[:-1], deviations[1:])
    ):
        correction = 4.0 * math.pi**2 / (36.0 * n**2)
        assert 0.9 * correction <= 4.0 - shrink <= 1.1 * correction, (n, shrink)
        assert halving == pytest.approx(2.0, rel=1e-13)


@pytest.mark.parametrize("sides", NGON_SIDES)
def test_regular_polygon_first_bounce_from_anywhere(sides):
    """From a generic start the flight ends where the ray meets the nearest side's line (this file's own
    intersection), between the exits from the inscribed and the circumscribed circles
    (``cos(pi/n) <= |P| <= 1`` on the polygon), and leaves reflected about that side's normal."""
    corners = _regular(sides, 1.0)
    start = np.array(GENERIC_START)
    x, v = start[:2], start[3:5]
    edges = np.roll(corners, -1, axis=0) - corners
    normals = np.stack([edges[:, 1], -edges[:, 0]], axis=-1) / np.hypot(edges[:, 0], edges[:, 1])[:, None]
    closing = normals @ v
    reach = np.where(
        closing > 0, np.einsum("jd,jd->j", normals, corners - x) / np.where(closing > 0, closing, 1), np.inf
    )
    side = int(np.argmin(reach))
    t, state = first_bounce(sides)
    assert t[1] == pytest.approx(reach[side], rel=1e-14)
    reflected = v - 2.0 * (v @ normals[side]) * normals[side]
    assert np.max(np.abs(state[1, 3:5] - reflected)) <= 1e-14
    along = x @ v

    def exit_from_disc(radius):
        return -along + math.sqrt(along**2 + radius**2 - x @ x)

    assert exit_from_disc(math.cos(math.pi / sides)) <= t[1] <= exit_from_disc(1.0)
    assert first_bounce(None)[0][1] == pytest.approx(exit_from_disc(1.0), rel=1e-14)


# ---------------------------------------------------------------------------
# 8. bad input
# ---------------------------------------------------------------------------
UNIT_SQUARE = np.array([[0.0, 0.0], [1.0, 0.0], [1.0, 1.0], [0.0, 1.0]])
BAD_VERTICES = {
    "not_convex": (
        np.array([[0.0, 0.0], [2.0, 0.0], [1.0, 0.3], [2.0, 2.0], [0.0, 2.0]]),
        r"vertices must be the corners of a convex polygon in anticlockwise order; the corner 2 .* is reflex",
    ),
    "clockwise": (UNIT_SQUARE[::-1], r"vertices must go round the polygon anticlockwise; these go clockwise"),
    "repeated": (np.insert(UNIT_SQUARE, 2, UNIT_SQUARE[1], axis=0), r"vertices must not repeat a corner"),
    "two": (UNIT_SQUARE[:2], r"vertices must be an array of shape \(n, 2\) with n >= 3 .*got \(2, 2\)"),
}


@pytest.mark.parametrize("make", [jb.Polygon, jb.PolygonBody], ids=["table", "body"])
@pytest.mark.parametrize("bad", list(BAD_VERTICES))
def test_bad_polygon_vertices_are_refused(make, bad):
    vertices, message = BAD_VERTICES[bad]
    with pytest.raises(ValueError, match=message):
        make(vertices)


def test_a_body_that_fits_nowhere_is_refused():
    """Longer than the circle's diameter, or wider in every direction than the strip: refused by name,
    with the limit; just inside either limit, accepted."""
    with pytest.raises(ValueError, match=r"body: its length 2\.02 is not below the longest chord of the circle, 2"):
        jb.BodyInTable(jb.Dumbbell(1.01), jb.Circle(1.0))
    # The square with its corners 0.75 from its centre is 0.75 sqrt 2 = 1.06 wide in every direction.
    with pytest.raises(ValueError, match=r"body: its smallest width 1\.06066 is not below the width of the walls, 1"):
        jb.BodyInTable(jb.PolygonBody.regular(4, 0.75), jb.Strip(1.0))
    jb.BodyInTable(jb.Dumbbell(0.99), jb.Circle(1.0))
    jb.BodyInTable(jb.PolygonBody.regular(4, 0.7), jb.Strip(1.0))


@pytest.mark.parametrize(
    "table, wall",
    [
        (lambda: jb.Circle(1.0), "the circle"),
        (lambda: jb.Ellipse(*ELLIPSE), "the ellipse"),
        (lambda: jb.Stadium(*STADIUM), "the stadium"),
        (lambda: jb.ConvexTable(quartic_oval, (-2.0, 2.0, -1.5, 1.5)), "the table"),
    ],
    ids=["circle", "ellipse", "stadium", "function"],
)
def test_the_coin_in_a_curved_table_is_refused(table, wall):
    with pytest.raises(ValueError, match=rf"body: a EllipseBody cannot touch {wall} .*flat walls only"):
        jb.BodyInTable(jb.EllipseBody(*COIN), table())


BODIES = {
    "point": lambda **kw: jb.PointBody(**kw),
    "dumbbell": lambda **kw: jb.Dumbbell(*ARMS, **kw),
    "polygon": lambda **kw: jb.PolygonBody(TRIANGLE, **kw),
    "coin": lambda **kw: jb.EllipseBody(*COIN, **kw),
}


@pytest.mark.parametrize("body", list(BODIES))
@pytest.mark.parametrize("mass", [0.0, -1.0, math.nan, math.inf])
def test_mass_must_be_positive_and_finite(body, mass):
    with pytest.raises(ValueError, match=r"mass must be > 0 and finite"):
        BODIES[body](mass=mass)


@pytest.mark.parametrize("body", ["dumbbell", "polygon", "coin"])
@pytest.mark.parametrize(
    "inertia, message",
    [(0.0, r"inertia must be > 0 \(or inf"), (-1.0, r"inertia must be > 0 \(or inf"), (math.nan, r"not NaN")],
)
def test_inertia_must_be_positive(body, inertia, message):
    with pytest.raises(ValueError, match=message):
        BODIES[body](inertia=inertia)


def test_a_point_spin_inertia_must_not_be_negative():
    with pytest.raises(ValueError, match=r"inertia must be >= 0"):
        jb.PointBody(inertia=-1.0)


@pytest.mark.parametrize(
    "table, message",
    [
        (lambda: jb.Circle(-1.0), r"R must be > 0 and finite"),
        (lambda: jb.Ellipse(2.0, -1.0), r"b must be > 0 and finite"),
        (lambda: jb.Stadium(-1.0, 0.8), r"half_length must be >= 0 and finite"),
        (lambda: jb.Strip(0.0), r"h must be > 0 and finite"),
    ],
    ids=["circle", "ellipse", "stadium", "strip"],
)
def test_bad_table_parameters_are_named(table, message):
    """The table's own parameter, not the body's fit, is named."""
    with pytest.raises(ValueError, match=message):
        jb.BodyInTable(jb.PointBody(), table())


def test_a_function_that_is_not_convex_or_not_smooth_is_refused():
    box = (-2.0, 2.0, -2.0, 2.0)
    # d^2/dx^2 of 0.5 cos(3x) is -4.5 cos(3x): below -2 near x = 0, inside the table.
    with pytest.raises(ValueError, match=r"function must be convex: its Hessian has the eigenvalue -2\.5 < 0"):
        jb.ConvexTable(lambda x, y: x * x + y * y - 1.0 + 0.5 * jnp.cos(3.0 * x), box)
    # |P| - 1 is convex but has no gradient at the centre (a kink: no Hessian bound to step by).
    with pytest.raises(ValueError, match=r"function must be twice differentiable .* not finite at \(0, 0\)"):
        jb.ConvexTable(lambda x, y: jnp.sqrt(x * x + y * y) - 1.0, box)


# A wall whose curvature lives in a thin band: F = w softplus((r - r0)/w) - c, r = sqrt(x^2 + y^2 + d^2),
# zero at |P| = 1, flat (no curvature) well inside and well outside. Convex: a convex increasing function of
# the convex r. |grad F| <= 1 and the Hessian's largest eigenvalue is about 1/(4w) = 12.5.
SOFT = (0.02, 0.9, 0.1)  # w, r0, d
SOFT_BOX = (-1.5, 1.5, -1.5, 1.5)


def soft_wall(x, y):
    w, r0, d = SOFT
    return w * jax.nn.softplus((jnp.sqrt(x * x + y * y + d * d) - r0) / w) - w * jax.nn.softplus(
        (math.sqrt(1.0 + d * d) - r0) / w
    )


def _soft_value(r):
    w, r0, d = SOFT
    return w * np.logaddexp(0.0, (math.sqrt(r * r + d * d) - r0) / w) - w * np.logaddexp(
        0.0, (math.sqrt(1.0 + d * d) - r0) / w
    )


@functools.cache
def soft_scenes(body: str):
    """The body in the soft wall with its bounds estimated, and with a Hessian bound 12 times too small."""
    make = {"point": jb.PointBody, "dumbbell": lambda: jb.Dumbbell(0.3)}[body]
    right = jb.ConvexTable(soft_wall, SOFT_BOX)
    wrong = jb.ConvexTable(soft_wall, SOFT_BOX, gradient_bound=2.0, hessian_bound=1.0)
    return jb.BodyInTable(make(), right), jb.BodyInTable(make(), wrong)


def test_too_small_bounds_poison_a_run_instead_of_stepping_over_the_wall():
    """A point from the centre along x meets the wall at t = 1. With the Hessian bound 1e-3 the search's
    first safe step, ``sqrt(2 g(0) / (H |v|^2))`` with ``g(0) = -F(0)``, is 14: past the wall, into the flat
    outside where every curvature it can see is within the bound. The run is NaN, not a collision there."""
    start = jnp.asarray([0.0, 0.0, 0.0, 1.0, 0.0, 0.0])
    right, _ = soft_scenes("point")
    assert float(jb.orbit(right, start, 1).t[0]) == pytest.approx(1.0, rel=1e-12)
    step = math.sqrt(2.0 * -_soft_value(0.0) / 1e-3)
    assert step > 10.0
    tiny = jb.ConvexTable(soft_wall, SOFT_BOX, gradient_bound=2.0, hessian_bound=1e-3)
    orbit = jb.orbit(jb.BodyInTable(jb.PointBody(), tiny), start, 2)
    assert np.all(np.isnan(np.asarray(orbit.t))) and np.all(np.isnan(np.asarray(orbit.state)))


@pytest.mark.parametrize("body", ["point", "dumbbell"])
def test_too_small_bounds_never_give_a_wrong_answer(body):
    """300 starts, three collisions each, with a Hessian bound 12 times too small: every collision is either
    the one the estimated bounds find or NaN (and some are NaN: the bound does bite)."""
    rng = np.random.default_rng(5)
    count = 300
    radius = 0.9 if body == "point" else 0.6  # the dumbbell's ends within 0.9 of the centre
    centre = radius * np.sqrt(rng.uniform(size=count))[:, None] * _unit(rng.uniform(0, 2 * np.pi, count))
    heading = _unit(rng.uniform(0, 2 * np.pi, count))
    spin = rng.uniform(-3.0, 3.0, count) if body == "dumbbell" else np.zeros(count)
    starts = jnp.asarray(np.column_stack([centre, rng.uniform(-np.pi, np.pi, count), heading, spin]))
    right, wrong = soft_scenes(body)
    expected, got = np.asarray(jb.orbit(right, starts, 3).t), np.asarray(jb.orbit(wrong, starts, 3).t)
    assert np.all(np.isfinite(expected))
    finite = np.isfinite(got)
    assert np.sum(~finite) > 0.1 * got.size
    assert np.allclose(got[finite], expected[finite], rtol=1e-9, atol=0.0)


def _unit(angle):
    return np.stack([np.cos(angle), np.sin(angle)], axis=-1)


@pytest.mark.parametrize(
    "name, state, contact",
    [
        ("triangle_in_stadium", [0.0, 0.7, 0.0, 1.0, 0.0, 0.0], "corner 3 on the stadium"),
        ("dumbbell_in_ellipse", [1.6, 0.0, 0.0, 1.0, 0.0, 0.0], "end P1 on the ellipse"),
        ("coin_in_strip", [0.0, 0.15, 0.0, 1.0, 0.0, 0.0], "the rim on the floor"),
        ("point_in_pentagon", [1.2, 0.0, 0.0, 1.0, 0.0, 0.0], "the point on side 1"),
    ],
)
def test_a_start_outside_the_table_is_refused_by_its_contact(name, state, contact):
    """The triangle's third corner at y = 0.97 (the stadium's side at 0.8), the dumbbell's end at x = 2.2
    (the ellipse's end at 2), the coin's rim at y = -0.05, the point right of the pentagon's first side."""
    with pytest.raises(ValueError, match=rf"state puts {contact} outside"):
        jb.orbit(scene(name), jnp.asarray(state), 1)


TRACED_START = jnp.asarray([0.1, 0.05, 0.3, 0.7, -0.3, 2.0])


@jax.jit
def _traced_dumbbell_run(radius, mass, inertia, arm):
    sc = jb.BodyInTable(jb.Dumbbell(arm, mass=mass, inertia=inertia), jb.Circle(radius))
    orbit = jb.orbit(sc, TRACED_START, 3)
    return orbit.t, orbit.state


@jax.jit
def _traced_polygon_run(vertices):
    orbit = jb.orbit(jb.BodyInTable(jb.PointBody(), jb.Polygon(vertices)), jnp.asarray([0.2, 0.2, 0, 0.6, 0.8, 0]), 3)
    return orbit.t, orbit.state


def test_invalid_parameters_inside_jit_poison_with_nan():
    """Built from traced parameters the scene cannot raise; a bad radius, mass, inertia or arm, a dumbbell
    longer than the circle's diameter, a triangle's corners clockwise or on one line give NaN everywhere, and
    good parameters the eager run's numbers."""
    good = (1.0, 1.0, 0.09, 0.3)
    t, state = _traced_dumbbell_run(*good)
    eager = jb.orbit(jb.BodyInTable(jb.Dumbbell(0.3, mass=1.0, inertia=0.09), jb.Circle(1.0)), TRACED_START, 3)
    np.testing.assert_allclose(np.asarray(t), np.asarray(eager.t), rtol=1e-14)
    np.testing.assert_allclose(np.asarray(state), np.asarray(eager.state), rtol=1e-13, atol=1e-15)
    for bad in [
        (-1.0, 1.0, 0.09, 0.3),
        (1.0, -1.0, 0.09, 0.3),
        (1.0, math.nan, 0.09, 0.3),
        (1.0, 1.0, -0.09, 0.3),
        (1.0, 1.0, 0.09, -0.3),
        (1.0, 1.0, 0.09, 1.2),
    ]:
        t, state = _traced_dumbbell_run(*bad)
        assert np.all(np.isnan(np.asarray(t))) and np.all(np.isnan(np.asarray(state))), bad
    triangle = np.array([[0.0, 0.0], [1.0, 0.0], [0.0, 1.0]])
    assert np.all(np.isfinite(np.asarray(_traced_polygon_run(triangle)[0])))
    for vertices in (triangle[::-1], np.array([[0.0, 0.0], [1.0, 0.0], [2.0, 0.0]])):
        t, state = _traced_polygon_run(vertices)
        assert np.all(np.isnan(np.asarray(t))) and np.all(np.isnan(np.asarray(state)))
