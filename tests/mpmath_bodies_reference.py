"""Independent high-precision reference for a rigid body in a convex table.

Written with mpmath only, from the physics of a body in a table (the state,
bodies, tables, impulse and corner rule as specified for ``BodyInTable``),
using no jaxbill code, so that the library's tests compare against something
that can fail differently.

Model
-----
State ``[x, y, alpha, vx, vy, omega]``: centre of mass ``c``, orientation
``alpha``, their rates. A contact point fixed at ``b_k`` in the body frame sits
at ``P_k = c + R(alpha) b_k``. Free flight ``c + v t``, ``alpha + omega t``;
after every collision ``alpha`` is wrapped into ``[-pi, pi)``.

Bodies (``body(spec)``): the point (``b = 0``, its spin a free rotor), the
dumbbell (``b_1 = (l1, 0)``, ``b_2 = (-l2, 0)``, default ``I = M l1 l2``), the
convex polygon (contact points: its vertices, shifted so that the lamina's
area centroid, or the vertices' mean, is the origin; default ``I``: the uniform
lamina's, ``M J / A`` with ``J`` the polar second moment of area about the
centroid) and the coin (elliptic disc, semi-axes ``a`` along the body's x axis
and ``b``; default ``I = M (a^2 + b^2) / 4``; one rim contact per flat wall).

Tables (``table(spec)``), each piece with a *gap* ``G`` (a length, positive
inside, zero on the boundary), its gradient and a curvature constant
``kappa``:

* half-planes ``n . P <= d`` (a polygon's sides, the strip's floor and
  ceiling): ``G = d - n . P``, ``grad G = -n``, ``kappa = 0``;
* circle: ``G = (R^2 - |P|^2) / (2R)``, ``kappa = 1/R``;
* ellipse: ``G = (m/2) (1 - x^2/a^2 - y^2/b^2)``, ``m = min(a, b)``, ``kappa = 1/m``;
* stadium: ``G = (r^2 - D(P)) / (2r)`` with ``D`` the *squared* distance to the
  segment ``[-l, l] x {0}``, ``kappa = 1/r``. ``D`` switches formula where the
  foot of the perpendicular passes a segment end, but ``D`` (the squared
  distance to a convex set) is C^1 with ``grad D = 2 (P - proj P)`` and
  ``P - proj P`` 1-Lipschitz, so ``G`` is C^{1,1}: its second derivative along
  a path exists almost everywhere and obeys the bound below, which is all the
  Taylor step needs. (The distance itself, ``r - dist``, has a concave kink on
  the segment, which would break that bound.)

A body whose contact points are all inside a convex table is inside it (a
convex body is the hull of its vertices; a dumbbell is its segment), so for a
point or polygon body the collision is the first time some ``G(P_k(t))``
reaches zero while decreasing; for a point inside a convex polygon the first
exit is the first crossing of a side's line, the region being the
intersection of the sides' half-planes. The coin's gap to the wall ``n . P <=
d`` is ``d - n . c - h(alpha)``, ``h = sqrt(a^2 (n.u)^2 + b^2 (n.u_perp)^2)``
the support function, ``u = (cos alpha, sin alpha)``, ``u_perp = (-sin alpha,
cos alpha)``; the contact point is ``c + (a^2 (n.u) u + b^2 (n.u_perp) u_perp) / h``.
Gap ``g = i K + k``: contact point ``k`` (of ``K``) against piece ``i``.

Root isolation (rigorous stepping)
----------------------------------
Along a flight ``P' = v + omega J r`` (``r = R(alpha) b``, ``J`` the quarter
turn), so ``|P'| <= |v| + |omega| |b|``, and ``P'' = -omega^2 r``, ``|P''| =
omega^2 |b|``. ``G'' = P'^T Hess(G) P' + grad G . P''`` with ``|Hess| <= kappa``
and, while ``P`` is inside the table, ``|grad G| <= 1`` for every table above
(circle ``|P|/R``, ellipse ``m |(x/a^2, y/b^2)| <= 1`` inside, stadium
``dist / r``, half-plane 1). Hence, up to the first zero of any gap,
``|G''| <= A = kappa (|v| + |omega| |b|)^2 + omega^2 |b|``. For the coin,
``G'' = -omega^2 h''``; with ``h^2 = p + q cos 2 psi``, ``q = (a^2 - b^2)/2``,
``h >= m = min(a, b)``: ``|h''| <= 2 |q| / m + q^2 / m^3``. Every ``A`` gets a
relative margin of ``10^-(dps - 10)`` against rounding.

From a time where ``G = g0 >= 0``, ``G' = g1``, Taylor's bound gives ``G(t + s)
>= g0 + g1 s - A s^2 / 2``, positive on ``[0, s*)``, ``s* = (g1 + sqrt(g1^2 +
2 A g0)) / A`` (for ``g1 < 0`` written ``2 g0 / (sqrt(g1^2 + 2 A g0) - g1)``,
free of cancellation). So the step ``t <- t + s*`` cannot pass a zero of
``G``, transversal or grazing: near a positive local minimum the steps shrink
to about ``sqrt(2 g_min / A)`` and pass it; at a zero they converge to it from
the left (quadratically, for a simple root). Once ``g0 <= 10^-(dps - 6) L`` with
``g1 < 0`` the root is polished by Newton's method and accepted only if it is
bracketed (``G > 0`` a little before it) and falling (a grazing root, whose
small ``G'`` lets rounding stall Newton's step, when ``G`` is at rounding
level). A step that lands below ``-10^-(dps - 6) L`` (a wrong bound) is an
error. A gap with ``A = 0`` (a flat piece and a contact that does not turn:
the point, or ``omega = 0``) is linear in ``t`` and solved exactly. For a flat
piece a second exclusion serves as a shortcut: ``G(t) >= d - n . c(t) - rho``
(``rho = |b|``, the coin's ``max(a, b)``), linear in ``t``; while it is
positive the stepper may jump to its zero, and if the centre does not move
towards the wall it proves that the gap never closes (without it a wall the
body flies away from would be stepped to the time cap). Every gap's search is
capped at the earliest root found so far, so the event is the earliest root of
all gaps.

The gaps that just bounced sit at ``G = 0`` with ``G' > 0``; their search
starts from ``g0 = 0`` exactly (the rounding residue discarded), which
excludes the root at ``t = 0`` while a genuine re-collision is still found
(the first step is ``2 g1 / A > 0``).

Impulse and corners
-------------------
``N`` the piece's unit outward normal at the contact point ``P`` (``-grad G /
|grad G|``; for the coin the wall's ``n``), ``r = P - c``, ``s = r x N``,
``v_n = v . N + omega s`` (``> 0`` approaching), ``J = 2 v_n / (1/M + s^2/I)``,
``v' = v - (J/M) N``, ``omega' = omega - (J/I) s`` (``1/I = 0`` for the point
and for ``I = inf``). Then ``v_n' = -v_n``. At an event every other gap within
``SIMULTANEOUS_TOL L`` of zero and approaching joins it; the impulses are
applied in order of decreasing approach speed (taken before any impulse), each
only if its contact still approaches at that moment; a contact still
approaching after that pass is an error (the rule does not resolve it).

Self-checks at every collision: energy to ``10^-(dps - 5)`` relative, the
touching gaps zero to ``10^-(dps - 5) L``, and the gap's time derivative equal
to ``-|grad G| v_n`` (the gap and the impulse formulas agree on the normal and
the lever arm).
"""

from __future__ import annotations

import mpmath
from mpmath import mp, mpf

__all__ = [
    "Body",
    "Table",
    "body",
    "table",
    "flow",
    "wrap",
    "energy",
    "angular_momentum",
    "gap",
    "gap_bound",
    "contact_point",
    "normal",
    "approach_speed",
    "impulse",
    "scales",
    "reference_orbit",
    "SIMULTANEOUS_TOL",
]

SIMULTANEOUS_TOL = mpf("1e-14")  # units of the table's length L: a second gap this close joins an event
BOUNCED_TOL = mpf("1e-10")  # units of L: a restart's bounced gaps must be this close to zero


def _num(x):
    """An mpf, floats taken exactly; ``"inf"`` and ``inf`` give mpmath's inf."""
    if isinstance(x, str) and x.strip().lower() in ("inf", "+inf", "infinity"):
        return mpmath.inf
    return mpf(x)


def _cross(a, b):
    return a[0] * b[1] - a[1] * b[0]


def _dot(a, b):
    return a[0] * b[0] + a[1] * b[1]


def _norm(a):
    return mpmath.sqrt(a[0] * a[0] + a[1] * a[1])


def _check_convex_anticlockwise(vertices, what):
    n = len(vertices)
    if n < 3:
        raise ValueError(f"{what}: vertices must have at least 3 rows")
    for j in range(n):
        p, q, r = vertices[j], vertices[(j + 1) % n], vertices[(j + 2) % n]
        if not _cross([q[0] - p[0], q[1] - p[1]], [r[0] - q[0], r[1] - q[1]]) > 0:
            raise ValueError(f"{what}: vertices must be a strictly convex polygon in anticlockwise order")


# ---------------------------------------------------------------------------
# bodies
# ---------------------------------------------------------------------------
class Body:
    """``kind`` (point, dumbbell, polygon, coin), ``mass``, ``inertia`` (inf: never turns),
    ``points`` (body-frame contact points, centre of mass at the origin) or ``axes`` (the coin)."""

    def __init__(self, kind, mass, inertia, points=(), axes=None):
        self.kind = kind
        self.mass = mass
        self.inertia = inertia
        self.points = [tuple(p) for p in points]
        self.axes = axes
        if not mass > 0:
            raise ValueError("mass must be > 0")
        if kind != "point" and not inertia > 0:
            raise ValueError("inertia must be > 0 (or inf)")

    @property
    def K(self):
        return 1 if self.kind == "coin" else len(self.points)

    @property
    def turns(self):
        """Whether impulses change the spin (not the point, not ``I = inf``)."""
        return self.kind != "point" and not mpmath.isinf(self.inertia)

    @property
    def inverse_inertia(self):
        return 1 / self.inertia if self.turns else mpf(0)


def body(spec):
    """A ``Body`` from ``{"type": "PointBody" | "Dumbbell" | "PolygonBody" | "EllipseBody", ...}``
    with the constructors' parameter names."""
    kind = spec["type"]
    mass = _num(spec.get("mass", 1.0))
    inertia = spec.get("inertia")
    if kind == "PointBody":
        return Body("point", mass, mpmath.inf, points=[(mpf(0), mpf(0))])
    if kind == "Dumbbell":
        l1 = _num(spec["l1"])
        l2 = l1 if spec.get("l2") is None else _num(spec["l2"])
        if not (l1 > 0 and l2 > 0):
            raise ValueError("l1 and l2 must be > 0")
        inertia = mass * l1 * l2 if inertia is None else _num(inertia)
        return Body("dumbbell", mass, inertia, points=[(l1, mpf(0)), (-l2, mpf(0))])
    if kind == "PolygonBody":
        vertices = [(_num(p[0]), _num(p[1])) for p in spec["vertices"]]
        _check_convex_anticlockwise(vertices, "PolygonBody")
        n = len(vertices)
        if inertia is None:
            inertia = "lamina"
        if inertia == "vertices":
            centre = (sum(p[0] for p in vertices) / n, sum(p[1] for p in vertices) / n)
        else:
            centre = polygon_centroid(vertices)
        shifted = [(p[0] - centre[0], p[1] - centre[1]) for p in vertices]
        if inertia == "lamina":
            inertia = mass * polar_moment(shifted) / polygon_area(shifted)
        elif inertia == "vertices":
            inertia = mass / n * sum(p[0] ** 2 + p[1] ** 2 for p in shifted)
        else:
            inertia = _num(inertia)
        return Body("polygon", mass, inertia, points=shifted)
    if kind == "EllipseBody":
        a, b = _num(spec["a"]), _num(spec["b"])
        if not (a > 0 and b > 0):
            raise ValueError("a and b must be > 0")
        inertia = mass * (a * a + b * b) / 4 if inertia is None else _num(inertia)
        return Body("coin", mass, inertia, axes=(a, b))
    raise ValueError(f"unknown body type {kind!r}")


def polygon_area(vertices):
    n = len(vertices)
    return sum(_cross(vertices[j], vertices[(j + 1) % n]) for j in range(n)) / 2


def polygon_centroid(vertices):
    """The area centroid (shoelace: each edge's triangle with the origin, weighted by its signed area)."""
    n = len(vertices)
    area = polygon_area(vertices)
    cx = cy = mpf(0)
    for j in range(n):
        p, q = vertices[j], vertices[(j + 1) % n]
        w = _cross(p, q)
        cx += (p[0] + q[0]) * w
        cy += (p[1] + q[1]) * w
    return (cx / (6 * area), cy / (6 * area))


def polar_moment(vertices):
    """``int (x^2 + y^2) dA`` over the polygon, about the origin (sum over the triangles origin-p-q)."""
    n = len(vertices)
    total = mpf(0)
    for j in range(n):
        (x0, y0), (x1, y1) = vertices[j], vertices[(j + 1) % n]
        total += (x0 * y1 - x1 * y0) * (x0 * x0 + x0 * x1 + x1 * x1 + y0 * y0 + y0 * y1 + y1 * y1)
    return total / 12


# ---------------------------------------------------------------------------
# tables
# ---------------------------------------------------------------------------
class Table:
    """``kind``, ``pieces`` (count), ``L`` (its length scale: the largest distance of its boundary
    from the origin, the strip's width), ``kappa`` (the pieces' curvature constant) and, for flat
    pieces, ``walls`` (outward unit normal ``n`` and offset ``d`` of ``n . P <= d``)."""

    def __init__(self, kind, pieces, L, kappa, walls=None, **params):
        self.kind = kind
        self.pieces = pieces
        self.L = L
        self.kappa = kappa
        self.walls = walls
        self.params = params

    @property
    def flat(self):
        return self.walls is not None

    def gap(self, i, P):
        """``(G, grad G)`` of piece ``i`` at the point ``P``."""
        if self.walls is not None:
            n, d = self.walls[i]
            return d - _dot(n, P), (-n[0], -n[1])
        p = self.params
        if self.kind == "circle":
            R = p["R"]
            return (R * R - _dot(P, P)) / (2 * R), (-P[0] / R, -P[1] / R)
        if self.kind == "ellipse":
            a, b, m = p["a"], p["b"], p["m"]
            return m / 2 * (1 - (P[0] / a) ** 2 - (P[1] / b) ** 2), (-m * P[0] / a**2, -m * P[1] / b**2)
        if self.kind == "stadium":
            half, r = p["half_length"], p["radius"]
            foot = min(max(P[0], -half), half)
            D = (P[0] - foot, P[1])
            return (r * r - _dot(D, D)) / (2 * r), (-D[0] / r, -D[1] / r)
        raise AssertionError(self.kind)


def table(spec):
    """A ``Table`` from ``{"type": "Circle" | "Ellipse" | "Strip" | "Stadium" | "Polygon", ...}``."""
    kind = spec["type"]
    if kind == "Circle":
        R = _num(spec["R"])
        if not R > 0:
            raise ValueError("R must be > 0")
        return Table("circle", 1, R, 1 / R, R=R)
    if kind == "Ellipse":
        a, b = _num(spec["a"]), _num(spec["b"])
        if not (a > 0 and b > 0):
            raise ValueError("a and b must be > 0")
        m = min(a, b)
        return Table("ellipse", 1, max(a, b), 1 / m, a=a, b=b, m=m)
    if kind == "Stadium":
        half, r = _num(spec["half_length"]), _num(spec["radius"])
        if not (half >= 0 and r > 0):
            raise ValueError("half_length must be >= 0 and radius > 0")
        return Table("stadium", 1, half + r, 1 / r, half_length=half, radius=r)
    if kind == "Strip":
        h = _num(spec["h"])
        if not h > 0:
            raise ValueError("h must be > 0")
        walls = [((mpf(0), mpf(-1)), mpf(0)), ((mpf(0), mpf(1)), h)]
        return Table("strip", 2, h, mpf(0), walls=walls, h=h)
    if kind == "Polygon":
        vertices = [(_num(p[0]), _num(p[1])) for p in spec["vertices"]]
        _check_convex_anticlockwise(vertices, "Polygon")
        n = len(vertices)
        walls = []
        for j in range(n):
            p, q = vertices[j], vertices[(j + 1) % n]
            edge = (q[0] - p[0], q[1] - p[1])
            length = _norm(edge)
            normal = (edge[1] / length, -edge[0] / length)  # outward for an anticlockwise polygon
            walls.append((normal, _dot(normal, p)))
        L = max(_norm(p) for p in vertices)
        return Table("polygon", n, L, mpf(0), walls=walls, vertices=vertices)
    raise ValueError(f"unknown table type {kind!r}")


def _check_pair(bd, tb):
    if bd.kind == "coin" and not tb.flat:
        raise ValueError("the coin needs a table of flat walls (Strip or Polygon)")


# ---------------------------------------------------------------------------
# kinematics
# ---------------------------------------------------------------------------
def flow(state, t):
    """Free flight of duration ``t`` (any sign); ``alpha`` not wrapped."""
    x, y, al, vx, vy, w = state
    return [x + vx * t, y + vy * t, al + w * t, vx, vy, w]


def wrap(alpha):
    """``alpha`` in ``[-pi, pi)``."""
    two_pi = 2 * mp.pi
    return alpha - two_pi * mpmath.floor((alpha + mp.pi) / two_pi)


def energy(bd, state):
    e = bd.mass * (state[3] ** 2 + state[4] ** 2) / 2
    if bd.turns:
        e += bd.inertia * state[5] ** 2 / 2
    return e


def angular_momentum(bd, state):
    """``M (x vy - y vx) + I omega`` about the origin (orbital part only for a body that never turns)."""
    x, y, _, vx, vy, w = state
    lz = bd.mass * (x * vy - y * vx)
    if bd.turns:
        lz += bd.inertia * w
    return lz


def scales(bd, tb, state0):
    """``(T, L, V, W)`` as mpf: ``L`` the table's length, ``V = sqrt(2E/M)``, ``T = L/V``, spin
    ``W = sqrt(2E/I)`` for a turning body, else ``max(|omega0|, V/L)``."""
    e = energy(bd, state0)
    V = mpmath.sqrt(2 * e / bd.mass)
    L = tb.L
    W = mpmath.sqrt(2 * e / bd.inertia) if bd.turns else max(abs(state0[5]), V / L)
    return L / V, L, V, W


def _coin_support(bd, n, cs, sn):
    """``(n.u, n.u_perp, h)`` of the coin at orientation ``(cos, sin)``."""
    a, b = bd.axes
    nu = n[0] * cs + n[1] * sn
    nup = -n[0] * sn + n[1] * cs
    return nu, nup, mpmath.sqrt(a * a * nu * nu + b * b * nup * nup)


def gap(bd, tb, state, g, t=0):
    """``(G, G')`` of gap ``g = i K + k`` at time ``t`` of the free flight from ``state``."""
    i, k = divmod(g, bd.K)
    x, y, al, vx, vy, w = state
    cs, sn = mp.cos_sin(al + w * t)
    c = (x + vx * t, y + vy * t)
    if bd.kind == "coin":
        n, d = tb.walls[i]
        a, b = bd.axes
        nu, nup, h = _coin_support(bd, n, cs, sn)
        dh = (a * a - b * b) * nu * nup / h  # dh/dalpha
        return d - _dot(n, c) - h, -(n[0] * vx + n[1] * vy) - w * dh
    bx, by = bd.points[k]
    r = (cs * bx - sn * by, sn * bx + cs * by)
    P = (c[0] + r[0], c[1] + r[1])
    dP = (vx - w * r[1], vy + w * r[0])
    G, grad = tb.gap(i, P)
    return G, _dot(grad, dP)


def gap_bound(bd, tb, state, g):
    """``A >= |G''|`` along the whole flight from ``state`` (up to the first zero), with a rounding margin."""
    _, k = divmod(g, bd.K)
    speed = mpmath.sqrt(state[3] ** 2 + state[4] ** 2)
    w = abs(state[5])
    if bd.kind == "coin":
        a, b = bd.axes
        q = abs(a * a - b * b) / 2
        m = min(a, b)
        A = w * w * (2 * q / m + q * q / m**3)
    else:
        arm = _reach(bd, k)
        A = tb.kappa * (speed + w * arm) ** 2 + w * w * arm
    return A * (1 + mpf(10) ** (-(mp.dps - 10)))


def contact_point(bd, tb, state, g):
    """The contact point of gap ``g`` at ``state`` (a vertex, a dumbbell end, the centre, the coin's rim)."""
    i, k = divmod(g, bd.K)
    x, y, al = state[0], state[1], state[2]
    cs, sn = mp.cos_sin(al)
    if bd.kind == "coin":
        n, _ = tb.walls[i]
        a, b = bd.axes
        nu, nup, h = _coin_support(bd, n, cs, sn)
        u, up = (cs, sn), (-sn, cs)
        return (x + (a * a * nu * u[0] + b * b * nup * up[0]) / h, y + (a * a * nu * u[1] + b * b * nup * up[1]) / h)
    bx, by = bd.points[k]
    return (x + cs * bx - sn * by, y + sn * bx + cs * by)


def normal(bd, tb, state, g):
    """The unit outward normal of gap ``g``'s piece at its contact point."""
    i, _ = divmod(g, bd.K)
    if tb.flat:
        return tb.walls[i][0]
    _, grad = tb.gap(i, contact_point(bd, tb, state, g))
    size = _norm(grad)
    return (-grad[0] / size, -grad[1] / size)


def _lever(bd, tb, state, g):
    P = contact_point(bd, tb, state, g)
    N = normal(bd, tb, state, g)
    r = (P[0] - state[0], P[1] - state[1])
    return N, _cross(r, N)


def approach_speed(bd, tb, state, g):
    """``v_n = v . N + omega s`` (``> 0``: the contact point moves outwards through the piece)."""
    N, s = _lever(bd, tb, state, g)
    return state[3] * N[0] + state[4] * N[1] + state[5] * s


def impulse(bd, tb, state, g):
    """The elastic frictionless impulse at gap ``g``'s contact; returns the new state."""
    N, s = _lever(bd, tb, state, g)
    inv_m, inv_i = 1 / bd.mass, bd.inverse_inertia
    vn = state[3] * N[0] + state[4] * N[1] + state[5] * s
    J = 2 * vn / (inv_m + s * s * inv_i)
    return [
        state[0],
        state[1],
        state[2],
        state[3] - J * inv_m * N[0],
        state[4] - J * inv_m * N[1],
        state[5] - J * inv_i * s,
    ]


# ---------------------------------------------------------------------------
# root isolation
# ---------------------------------------------------------------------------
def _flat_floor(bd, tb, state, g):
    """For a flat piece: ``(l0, rate)`` with ``G(t) >= l0 - rate t`` along the flight, else None.

    ``G = d - n . c(t) - n . r(t)`` with ``n . r <= |r|`` (a vertex, an end) or ``h <= max(a, b)`` (the coin).
    """
    if not tb.flat:
        return None
    i, k = divmod(g, bd.K)
    n, d = tb.walls[i]
    return d - _dot(n, state[:2]) - _reach(bd, k), n[0] * state[3] + n[1] * state[4]


def _reach(bd, k):
    """Distance of contact point ``k`` from the centre (the coin: its major semi-axis, the most its support reaches)."""
    return max(bd.axes) if bd.kind == "coin" else _norm(bd.points[k])


def _first_root(bd, tb, state, g, t_cap, just_bounced, L, T, max_steps):
    """First ``t > 0`` at which gap ``g`` reaches zero while falling, or ``None`` before ``t_cap``."""
    g0, g1 = gap(bd, tb, state, g)
    if just_bounced:
        if not g1 > 0:
            raise ArithmeticError(f"gap {g} just bounced but is not opening (G' = {g1})")
        g0 = mpf(0)
    A = gap_bound(bd, tb, state, g)
    if A == 0:  # linear in t: exact
        if g1 >= 0:
            return None
        t = -g0 / g1
        return t if t < t_cap else None
    polish_below = mpf(10) ** (-(mp.dps - 6)) * L
    floor = _flat_floor(bd, tb, state, g)
    t = mpf(0)
    steps = 0
    while not (g0 <= polish_below and g1 < 0):
        root = mpmath.sqrt(g1 * g1 + 2 * A * max(g0, mpf(0)))
        s = (g1 + root) / A if g1 >= 0 else 2 * max(g0, mpf(0)) / (root - g1)
        if floor is not None:
            level, rate = floor[0] - floor[1] * t, floor[1]  # G(t + u) >= level - rate u
            if level > 0:
                if rate <= 0:
                    return None  # proven: this gap never closes
                s = max(s, level / rate)
        t += s
        if t >= t_cap:
            return None
        g0, g1 = gap(bd, tb, state, g, t)
        steps += 1
        if steps > max_steps:
            raise ArithmeticError(f"root isolation of gap {g} did not converge in {max_steps} steps")
        if g0 < -polish_below:
            raise ArithmeticError(f"gap {g} stepped through a root (a bound is wrong)")
    for _ in range(30):
        dt = -g0 / g1
        t += dt
        g0, g1 = gap(bd, tb, state, g, t)
        if abs(dt) <= mpf(10) ** (-(mp.dps - 3)) * (T + abs(t)):
            break
    else:
        # A shallow (grazing) root: G' is small, so the rounding of G moves Newton's step above the time
        # tolerance; the root is then as good as the working precision allows if G is at rounding level.
        if not abs(g0) <= mpf(10) ** (-(mp.dps - 8)) * L:
            raise ArithmeticError(f"Newton polish of gap {g} did not converge")
    before, slope_before = gap(bd, tb, state, g, t - mpf(10) ** (-(mp.dps // 2)) * T)
    if not (before > 0 and g1 < 0 and slope_before < 0 and t > 0):
        raise ArithmeticError(f"polished root of gap {g} is not a bracketed falling root")
    return t if t < t_cap else None


# ---------------------------------------------------------------------------
# the orbit
# ---------------------------------------------------------------------------
def reference_orbit(body_spec, table_spec, state0, n, dps=45, bounced=(), max_steps=2_000_000, info=None):
    """First ``n`` collisions from ``state0`` (six numbers; floats taken exactly).

    Returns ``(times, states, hits)``: absolute collision times (mpf), the states
    just after each collision (lists of 6 mpf, ``alpha`` wrapped into ``[-pi,
    pi)``) and, per collision, the gaps of the event (``g = i K + k``) in the
    order their impulses were considered (decreasing approach speed).
    ``bounced``: gaps that start on their piece moving inwards, as just after a
    collision (their root at ``t = 0`` is excluded). ``info``: a dict filled
    per collision with ``nearest_other`` (smallest gap / L of an approaching gap
    that did not join the event, or None) and ``joined`` (largest |gap| / L of a
    gap that joined an event other than its root's, or None).
    """
    with mp.workdps(dps):
        bd, tb = body(body_spec), table(table_spec)
        _check_pair(bd, tb)
        K, gaps = bd.K, bd.K * tb.pieces
        state = [_num(v) for v in state0]
        if len(state) != 6:
            raise ValueError("state0 must have 6 components")
        T, L, V, _ = scales(bd, tb, state)
        if not V > 0 and not (bd.turns and state[5] != 0):
            raise ValueError("the body must move")
        if not V > 0:
            T = 1 / abs(state[5])
        t_max = mpf(10) ** 6 * T
        tol = mpf(10) ** (-(dps - 5))
        e0 = energy(bd, state)
        bounced = set(bounced)
        for g in range(gaps):
            g0, g1 = gap(bd, tb, state, g)
            if g in bounced:
                if abs(g0) > BOUNCED_TOL * L or not g1 > 0:
                    raise ValueError(f"gap {g} is not on its piece moving inwards")
            elif g0 < 0 or (g0 <= BOUNCED_TOL * L and g1 < 0):
                raise ValueError(f"gap {g} (point {g % K}, piece {g // K}) is outside or closing at t = 0")
        if info is not None:
            info.update(nearest_other=[], joined=[])
        times, states, hits = [], [], []
        t_abs = mpf(0)
        for _ in range(n):
            roots = {}
            cap = t_max
            for g in range(gaps):
                tg = _first_root(bd, tb, state, g, cap, g in bounced, L, T, max_steps)
                if tg is not None:
                    roots[g] = tg
                    cap = min(cap, tg)
            if not roots:
                raise RuntimeError("no collision before t_max")
            t_hit = min(roots.values())
            first = min(g for g in roots if roots[g] == t_hit)
            state = flow(state, t_hit)
            event, nearest, joined = [first], None, None
            for g in range(gaps):
                if g == first:
                    continue
                gv, dg = gap(bd, tb, state, g)
                if gv < -tol * L:
                    raise ArithmeticError(f"gap {g} is through its piece at the event")
                if dg < 0 and gv <= SIMULTANEOUS_TOL * L:
                    event.append(g)
                    joined = max(joined or 0.0, float(abs(gv) / L))
                elif dg < 0:
                    nearest = float(gv / L) if nearest is None else min(nearest, float(gv / L))
            for g in event:
                dg = gap(bd, tb, state, g)[1]
                grad_size = mpf(1) if tb.flat else _norm(tb.gap(g // K, contact_point(bd, tb, state, g))[1])
                slip = dg + grad_size * approach_speed(bd, tb, state, g)
                assert abs(slip) <= tol * (V + L * abs(state[5])), "gap derivative and impulse disagree"
            order = sorted(event, key=lambda g: -approach_speed(bd, tb, state, g))
            for g in order:
                if approach_speed(bd, tb, state, g) > 0:
                    state = impulse(bd, tb, state, g)
            for g in order:
                if not approach_speed(bd, tb, state, g) < 0:
                    raise ArithmeticError(f"gap {g} still approaches after the event")
                assert abs(gap(bd, tb, state, g)[0]) <= tol * L, "contact off its piece"
            assert abs(energy(bd, state) - e0) <= tol * e0, "energy drift"
            state[2] = wrap(state[2])
            bounced = set(event)
            t_abs += t_hit
            times.append(+t_abs)
            states.append(list(state))
            hits.append(tuple(order))
            if info is not None:
                info["nearest_other"].append(nearest)
                info["joined"].append(joined)
        return times, states, hits
