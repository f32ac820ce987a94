"""Independent references for the standard billiards (numpy only, no jaxbill code).

* Ray tracing of a point among finite walls: line segments (the table on their
  left), arcs of circles with the table inside (the mushroom's cap) and whole
  discs with the table outside (obstacles). Each flight's end is the earliest
  crossing, from inside to outside, of any wall at a time above a small ``eps``
  (the wall just left is crossed again only later), found from the textbook
  line-line and line-circle intersections.
* The periodic Lorentz gas in the plane, unfolded: the discs at the lattice
  points near the flight, no cells and no periodic walls.
* The Dellago-Posch-Hoover tangent map (C. Dellago, H. A. Posch and W. G.
  Hoover, Phys. Rev. E 53, 1485 (1996)) of a point's flight and specular
  reflection off a flat wall (curvature 0), a dispersing disc or a focusing
  arc, extending ``dph_reference.dph_flow_tangent`` (circles only) to every
  wall of these tables; a crossing of a periodic cell's side is a plain flight.
* Closed forms: Santalo's mean free path ``pi A / P`` and the regular share of
  the mushroom's phase space (derived in ``mushroom_regular_share``).
"""

from __future__ import annotations

import math

import numpy as np

# -- ray tracing among finite walls -----------------------------------------------------------


def segment(a, b) -> dict:
    """A flat wall from ``a`` to ``b`` with the table on its left."""
    a, b = np.asarray(a, float), np.asarray(b, float)
    e = (b - a) / np.linalg.norm(b - a)
    return {"kind": "segment", "a": a, "b": b, "e": e, "out": np.array([e[1], -e[0]]), "curvature": 0.0}


def disc_obstacle(centre, radius) -> dict:
    """The outside of a disc (a dispersing wall)."""
    return {"kind": "disc", "c": np.asarray(centre, float), "r": float(radius), "curvature": 1.0 / radius}


def arc(centre, radius, start, span) -> dict:
    """The arc of a circle from the angle ``start`` anticlockwise through ``span``, the table inside it (a focusing
    wall)."""
    return {
        "kind": "arc",
        "c": np.asarray(centre, float),
        "r": float(radius),
        "start": float(start),
        "span": float(span),
        "curvature": -1.0 / radius,
    }


def upper_arc(centre, radius) -> dict:
    """The upper half of a circle with the table inside it."""
    return arc(centre, radius, 0.0, math.pi)


def _circle_roots(q, v, c, r):
    d = q - c
    a, b, k = v @ v, d @ v, d @ d - r * r
    disc = b * b - a * k
    if disc < 0:
        return None
    root = math.sqrt(disc)
    return (-b - root) / a, (-b + root) / a


def crossing(wall: dict, q, v, eps: float):
    """``(t, outward normal at the hit)`` of the point ``q + v t`` leaving the table through ``wall`` (``t > eps``),
    or ``None``."""
    if wall["kind"] == "segment":
        closing = v @ wall["out"]
        if closing <= 0:
            return None
        t = ((wall["a"] - q) @ wall["out"]) / closing
        if t <= eps:
            return None
        along = (q + v * t - wall["a"]) @ wall["e"]
        if along < 0 or along > np.linalg.norm(wall["b"] - wall["a"]):
            return None
        return t, wall["out"]
    roots = _circle_roots(q, v, wall["c"], wall["r"])
    if roots is None:
        return None
    if wall["kind"] == "disc":  # entering the disc: the near root
        t = roots[0]
        if t <= eps:
            return None
        hit = q + v * t
        return t, -(hit - wall["c"]) / wall["r"]
    t = roots[1]  # leaving the circle: the far root, on the arc
    if t <= eps:
        return None
    hit = q + v * t
    angle = math.atan2(hit[1] - wall["c"][1], hit[0] - wall["c"][0])
    if (angle - wall["start"]) % (2 * math.pi) > wall["span"]:
        return None
    return t, (hit - wall["c"]) / wall["r"]


def next_bounce(walls: list, q, v, eps: float = 1e-9):
    """``(t, index, q_hit, v_out)``: the next wall a point at ``q`` with velocity ``v`` leaves through, and its
    specular reflection."""
    best = None
    for i, wall in enumerate(walls):
        hit = crossing(wall, q, v, eps)
        if hit is not None and (best is None or hit[0] < best[0]):
            best = (hit[0], i, hit[1])
    if best is None:
        raise RuntimeError(f"no wall ahead of {q}, {v}: the point has left the table")
    t, i, n = best
    return t, i, q + v * t, v - 2.0 * (v @ n) * n


def mushroom_walls(R, w, h) -> list:
    """The mushroom's six walls in jaxbill's order: the arc, the left rim, the stem's left side, foot, right
    side, the right rim."""
    a = w / 2
    return [
        upper_arc((0, 0), R),
        segment((-R, 0), (-a, 0)),
        segment((-a, 0), (-a, -h)),
        segment((-a, -h), (a, -h)),
        segment((a, -h), (a, 0)),
        segment((a, 0), (R, 0)),
    ]


def sinai_walls(radius, side=1.0) -> list:
    """The square's sides (bottom, right, top, left) and the disc, in jaxbill's order."""
    s = side / 2
    corners = [(-s, -s), (s, -s), (s, s), (-s, s)]
    return [segment(corners[j], corners[(j + 1) % 4]) for j in range(4)] + [disc_obstacle((0, 0), radius)]


def stadium_walls(half_length, radius) -> list:
    """The stadium's right half-disc, top side, left half-disc and bottom side."""
    L, r = half_length, radius
    return [
        arc((L, 0), r, -math.pi / 2, math.pi),
        segment((L, r), (-L, r)),
        arc((-L, 0), r, math.pi / 2, math.pi),
        segment((-L, -r), (L, -r)),
    ]


def polygon_walls(vertices) -> list:
    """The sides of a polygon with anticlockwise ``vertices``."""
    n = len(vertices)
    return [segment(vertices[j], vertices[(j + 1) % n]) for j in range(n)]


def wall_length(wall: dict) -> float:
    if wall["kind"] == "segment":
        return float(np.linalg.norm(wall["b"] - wall["a"]))
    if wall["kind"] == "disc":
        return 2 * math.pi * wall["r"]
    return wall["r"] * wall["span"]


def boundary_start(walls: list, s: float, p: float):
    """``(q, v)`` just after a bounce at arc length ``s`` along the walls in order (each wall anticlockwise round
    the table, an obstacle clockwise: the table on the left), with tangential velocity ``p`` (unit speed)."""
    for wall in walls:
        length = wall_length(wall)
        if s < length:
            break
        s -= length
    else:
        raise ValueError("s beyond the perimeter")
    if wall["kind"] == "segment":
        q, tangent = wall["a"] + s * wall["e"], wall["e"]
    elif wall["kind"] == "disc":
        angle = -s / wall["r"]
        q = wall["c"] + wall["r"] * np.array([math.cos(angle), math.sin(angle)])
        tangent = np.array([math.sin(angle), -math.cos(angle)])
    else:
        angle = wall["start"] + s / wall["r"]
        q = wall["c"] + wall["r"] * np.array([math.cos(angle), math.sin(angle)])
        tangent = np.array([-math.sin(angle), math.cos(angle)])
    inward = np.array([-tangent[1], tangent[0]])  # the table is on the left of the tangent
    return q, p * tangent + math.sqrt(1.0 - p * p) * inward


def bounces(walls: list, q, v, n: int, eps: float = 1e-9):
    """``n`` bounces from ``(q, v)``: times (n,), wall indices (n,), positions (n, 2) and velocities (n, 2)."""
    out = ([], [], [], [])
    q, v = np.asarray(q, float), np.asarray(v, float)
    for _ in range(n):
        t, i, q, v = next_bounce(walls, q, v, eps)
        for column, value in zip(out, (t, i, q, v)):
            column.append(value)
    return tuple(np.asarray(column) for column in out)


# -- the Lorentz gas in the plane --------------------------------------------------------------


def lattice_vectors(spacing, lattice):
    if lattice == "square":
        return np.array([spacing, 0.0]), np.array([0.0, spacing])
    return np.array([spacing, 0.0]), np.array([spacing / 2, spacing * math.sqrt(3) / 2])


def lorentz_bounce(q, v, radius, spacing, lattice, reach: int = 12, eps: float = 1e-9):
    """``(t, centre, q_hit, v_out)``: the next disc a point hits in the unfolded periodic Lorentz gas (discs at
    ``i a1 + j a2``, ``|i|, |j| <= reach`` about the lattice point nearest ``q``)."""
    a1, b1 = lattice_vectors(spacing, lattice)
    basis = np.stack([a1, b1], axis=1)
    i0, j0 = np.round(np.linalg.solve(basis, q))
    best = None
    for i in range(int(i0) - reach, int(i0) + reach + 1):
        for j in range(int(j0) - reach, int(j0) + reach + 1):
            c = i * a1 + j * b1
            roots = _circle_roots(q, v, c, radius)
            if roots is None or roots[0] <= eps:
                continue
            if best is None or roots[0] < best[0]:
                best = (roots[0], c)
    if best is None:
        raise RuntimeError("no disc within reach: widen it")
    t, c = best
    hit = q + v * t
    n = (hit - c) / radius
    return t, c, hit, v - 2.0 * (v @ n) * n


# -- the Dellago-Posch-Hoover tangent map ------------------------------------------------------


def dph_flow_tangent(q, v, t, normal_out, curvature):
    """The 4x4 flow tangent map on ``(dq, dp)`` (mass 1, rows and columns ``x, y, vx, vy``) over a flight of ``t``
    from ``(q, v)`` and a specular reflection off a wall of signed ``curvature`` (``1/r > 0`` dispersing, ``< 0``
    focusing, 0 flat) with the outward normal ``normal_out`` at the hit::

        dq' = dq - 2 (dq . n) n,
        dp' = dp - 2 (dp . n) n - 2 curvature (dq . t_in) / cos  t_out,

    ``n`` the unit normal into the table, ``cos = -n . v_in / |v|``, ``t_in`` and ``t_out`` the unit velocities
    before and after turned a quarter, and the curvature term scaled by the speed (Dellago, Posch and Hoover's
    form for a dispersing circle of radius ``r`` at unit speed: ``curvature = 1/r``)."""
    n = -np.asarray(normal_out, float)
    v_out = v - 2.0 * (v @ n) * n
    speed = np.linalg.norm(v)
    cos = -(n @ v) / speed
    t_in, t_out = np.array([-v[1], v[0]]) / speed, np.array([-v_out[1], v_out[0]]) / speed
    m = np.zeros((4, 4))
    for j in range(4):
        e = np.zeros(4)
        e[j] = 1.0
        dq, dp = e[:2] + t * e[2:], e[2:]
        dq_new = dq - 2.0 * (dq @ n) * n
        dp_new = dp - 2.0 * (dp @ n) * n - 2.0 * curvature * speed * (dq @ t_in) / cos * t_out
        m[:, j] = np.concatenate([dq_new, dp_new])
    return m


def free_flight(t):
    """The tangent map of a flight of ``t`` with no collision (a crossing of a periodic cell's side)."""
    m = np.eye(4)
    m[0, 2] = m[1, 3] = t
    return m


def spectrum_from_maps(maps, total_time):
    """The Lyapunov spectrum per unit time of a product of tangent maps, by repeated QR (Benettin)."""
    frame = np.eye(4)
    logs = np.zeros(4)
    for m in maps:
        frame, r = np.linalg.qr(m @ frame)
        signs = np.sign(np.diag(r))
        frame *= signs
        logs += np.log(np.abs(np.diag(r)))
    return logs / total_time


# -- closed forms ------------------------------------------------------------------------------


def santalo_mean_free_path(area, perimeter):
    """Santalo: the mean flight between bounces of a point billiard under the boundary map's invariant measure."""
    return math.pi * area / perimeter


def mushroom_regular_share(R, w, h):
    """``(Liouville share, boundary-map share)`` of the mushroom's regular orbits (cap radius ``R``, stem width
    ``w``, height ``h``).

    Regular orbits (Bunimovich): in the cap with ``|L| > a = w/2`` (unit speed), where the flat rim mirrors
    the half-disc into the disc and the chord's caustic of radius ``|L|`` misses the stem's mouth ``|x| < a``.

    Liouville measure ``dx dy dtheta``: in the disc a point at radius ``r > a`` has ``|L| = r |sin psi| > a``
    for a share ``1 - (2/pi) arcsin(a/r)`` of its directions; ``int_a^R 2 pi r (2 pi - 4 arcsin(a/r)) dr =
    2 pi^2 R^2 - 4 pi R^2 arcsin(a/R) - 4 pi a sqrt(R^2 - a^2)`` (using ``int r arcsin(a/r) dr = r^2/2
    arcsin(a/r) + a/2 sqrt(r^2 - a^2)``); half of it lies in the cap, over ``2 pi (pi R^2/2 + w h)``.

    Boundary map ``ds dp`` (``p = sin`` of the angle to the normal; total ``2 x perimeter``): on the arc
    ``|L| = R |p|``, a measure ``pi R . 2 (1 - a/R)``; on each flat rim ``a < |x| < R``, ``|L| = |x|
    sqrt(1 - p^2) > a`` for ``|p| < sqrt(1 - a^2/x^2)``, a measure ``2 (sqrt(R^2 - a^2) - a arccos(a/R))``;
    the perimeter is ``pi R + 2 R + 2 h``.
    """
    a = w / 2
    root = math.sqrt(R * R - a * a)
    liouville = (math.pi * R * R - 2 * R * R * math.asin(a / R) - 2 * a * root) / (math.pi * R * R + 2 * w * h)
    boundary = (2 * math.pi * (R - a) + 4 * (root - a * math.acos(a / R))) / (2 * (math.pi * R + 2 * R + 2 * h))
    return liouville, boundary
