"""Bodies in tables against the independent mpmath reference, and the reference checked on its own.

The reference (``tests/mpmath_bodies_reference.py``, 45 digits, its own
rigorous root isolation) is cached with each orbit's conditioning in
``tests/data/bodies_reference.json`` by ``tests/make_bodies_reference_data.py``:
a triangle spinning in a stadium, a dumbbell of masses 1:3 spinning in an
ellipse, a point in an irregular pentagon (one orbit passing 1e-9 from a
corner) and the coin spinning between two flat walls.

``test_jaxbill_*``: the library against the cache. Tolerances (scaled metric
``collision_errors``: time over ``L/V``, positions over the table's length
``L``, angle in radians, velocities over ``V``, spin over its scale):

* whole orbits: ``1e-10`` on the collisions within the horizon (where two exact
  orbits started ``1e-15`` apart stay within ``1e-11``), and beyond it ``30x``
  the measured spread of those perturbed orbits where that is below ``1e-7``;
* one collision from jaxbill's own float64 state (the reference restarted
  there), which carries only that collision's conditioning: ``1e-12``, some
  thousands of ulps (the stick in an ellipse, whose collisions are conditioned
  alike, measured up to 5e-15).

``test_reference_*``: the reference against what it does not use (closed
forms, conservation laws, time reversal, brute force, dense sampling,
constructed grazing hits and misses); these need nothing of jaxbill.
"""

from __future__ import annotations

import functools
import json
import math
import os
import sys

import jax.numpy as jnp
import mpmath
import numpy as np
import pytest
from mpmath import mp, mpf

import jaxbill as jb

_HERE = os.path.dirname(os.path.abspath(__file__))
if _HERE not in sys.path:
    sys.path.insert(0, _HERE)

import make_bodies_reference_data as gen  # noqa: E402
import mpmath_bodies_reference as ref  # noqa: E402

with open(gen.DATA_PATH) as _f:
    DATA = {c["name"]: c for c in json.load(_f)["cases"]}
NAMES = list(DATA)
SCENES = sorted({c["scene"] for c in DATA.values()})
FIRST_OF_SCENE = [next(n for n in NAMES if DATA[n]["scene"] == s) for s in SCENES]
TOL = gen.AGREEMENT_TOL
ONE_STEP_TOL = 1e-12


def _scales(c):
    return gen.scales(c["body"], c["table"], c["state0"])


def _reference(c):
    """Cached times, states (mpf with all the stored digits, whatever the caller's precision) and hits."""
    with mp.workdps(gen.STORE_DIGITS + 5):
        return [mpf(t) for t in c["times"]], [[mpf(v) for v in s] for s in c["states"]], c["hits"]


def _gaps_of(c, hits):
    """Gap indices ``i K + k`` of a cached collision's ``[k, i]`` pairs."""
    return tuple(i * c["K"] + k for k, i in hits)


# ---------------------------------------------------------------------------
# jaxbill against the cache
# ---------------------------------------------------------------------------
def _jaxbill_part(spec):
    """``jb.<type>(**parameters)``, vertices as an array."""
    kwargs = {key: (np.asarray(value, dtype=float) if key == "vertices" else value) for key, value in spec.items()}
    return getattr(jb, str(kwargs.pop("type")))(**kwargs)


def _scene(c):
    return jb.BodyInTable(_jaxbill_part(c["body"]), _jaxbill_part(c["table"]))


def _expected_codes(c, scene):
    return [2 if len(h) > 1 else int(scene.gap_codes[_gaps_of(c, h)[0]]) for h in c["hits"]]


@functools.cache
def _jaxbill_orbit(name):
    c = DATA[name]
    orb = jb.orbit(_scene(c), jnp.asarray(c["state0"]), c["n"])
    return np.asarray(orb.t), np.asarray(orb.state), np.asarray(orb.contact).astype(int)


def _allowed(c, j):
    if j < c["horizon"]:
        return TOL
    return max(TOL, gen.SENSITIVITY_FACTOR * c["sensitivity"][j])


@pytest.mark.parametrize("name", FIRST_OF_SCENE)
def test_jaxbill_gap_layout(name):
    """One code per gap, ``K`` contact points times the table's pieces, each naming its gap (distinct, and
    neither 'none' nor 'several'), so that an orbit's contacts say which point touched which piece."""
    c = DATA[name]
    codes = [int(code) for code in _scene(c).gap_codes]
    assert len(codes) == c["K"] * c["pieces"]
    assert len(set(codes)) == len(codes)
    assert not {0, 2} & set(codes)


@pytest.mark.parametrize("name", NAMES)
def test_jaxbill_orbit_matches_reference(name):
    c = DATA[name]
    t, s, k = _jaxbill_orbit(name)
    rt, rs, _ = _reference(c)
    want = _expected_codes(c, _scene(c))
    with mp.workdps(30):
        errs = gen.collision_errors(list(t), list(s), rt, rs, _scales(c))
    checked = [j for j in range(c["n"]) if _allowed(c, j) <= gen.SENSITIVE_LIMIT]
    assert len(checked) >= c["horizon"] >= 4
    for j in checked:
        assert k[j] == want[j], f"collision {j}: contact {k[j]} != reference {want[j]}"
        assert errs[j] <= _allowed(c, j), f"collision {j}: scaled error {errs[j]:.3g} > {_allowed(c, j):.3g}"
    assert np.all((s[:, 2] >= -np.pi) & (s[:, 2] < np.pi)), "alpha not wrapped into [-pi, pi)"


def test_jaxbill_first_collisions_agree_to_1e_12():
    """The first three collisions of every orbit agree far below the 1e-10 bound."""
    worst = 0.0
    for name in NAMES:
        c = DATA[name]
        t, s, _ = _jaxbill_orbit(name)
        rt, rs, _ = _reference(c)
        with mp.workdps(30):
            worst = max(worst, *gen.collision_errors(list(t[:3]), list(s[:3]), rt[:3], rs[:3], _scales(c)))
    assert worst <= 1e-12


ONE_STEP = ["triangle_stadium_fast_spin", "dumbbell_ellipse_b", "point_pentagon_near_corner", "coin_strip_a"]


@pytest.mark.parametrize("name", ONE_STEP)
def test_jaxbill_one_step_map_matches_reference(name):
    """Every collision of the cached run, past the horizon too: the reference restarted from jaxbill's state."""
    c = DATA[name]
    t, s, k = _jaxbill_orbit(name)
    codes = [int(code) for code in _scene(c).gap_codes]
    sc = _scales(c)
    for j in range(min(c["n"], 30) - 1):
        assert k[j] != 2, "a corner in a case built without one"
        bounced = (codes.index(int(k[j])),)
        rt, rs, rh = ref.reference_orbit(c["body"], c["table"], list(s[j]), 1, dps=40, bounced=bounced)
        with mp.workdps(30):
            (err,) = gen.collision_errors([t[j + 1] - t[j]], [s[j + 1]], rt, rs, sc)
        assert k[j + 1] == codes[rh[0][0]], f"collision {j + 1}: contact {k[j + 1]} != {codes[rh[0][0]]}"
        assert err <= ONE_STEP_TOL, f"collision {j + 1}: scaled error {err:.3g}"


# ---------------------------------------------------------------------------
# the cache and its generator
# ---------------------------------------------------------------------------
def test_data_matches_the_generator():
    assert [c["name"] for c in gen.CASES] == NAMES, "data out of date: rerun tests/make_bodies_reference_data.py"
    for case in gen.CASES:
        c = DATA[case["name"]]
        for key in ("scene", "body", "table", "state0", "n"):
            assert c[key] == case[key], (case["name"], key)
        assert len(c["times"]) == len(c["states"]) == len(c["hits"]) == len(c["sensitivity"]) == c["n"]
    assert SCENES == ["coin_strip", "dumbbell_ellipse", "point_pentagon", "triangle_stadium"]
    for scene in SCENES:
        assert sum(c["scene"] == scene for c in DATA.values()) == 3
    assert os.path.getsize(gen.DATA_PATH) < 1_000_000


def test_cases_are_the_scenes_asked_for():
    """Non-equilateral triangle, masses 1:3, a != b, irregular pentagon, every body but the point spinning."""
    tri = DATA["triangle_stadium_a"]["body"]["vertices"]
    sides = [math.dist(tri[j], tri[(j + 1) % 3]) for j in range(3)]
    assert max(sides) - min(sides) > 0.1
    dumbbell = DATA["dumbbell_ellipse_a"]["body"]
    l1, l2 = dumbbell["l1"], dumbbell["l2"]
    assert l2 / (l1 + l2) * 3 == pytest.approx(l1 / (l1 + l2))  # m1 = M l2/(l1+l2), m2 = M l1/(l1+l2): 1:3
    ellipse = DATA["dumbbell_ellipse_a"]["table"]
    assert ellipse["a"] != ellipse["b"]
    pentagon = DATA["point_pentagon_a"]["table"]["vertices"]
    assert len(pentagon) == 5 and len({round(math.dist(pentagon[j], pentagon[j - 1]), 6) for j in range(5)}) == 5
    for c in DATA.values():
        if c["scene"] != "point_pentagon":
            assert c["state0"][5] != 0
    assert DATA["triangle_stadium_fast_spin"]["state0"][5] >= 20


def test_horizons_are_not_vacuous():
    """Chaotic scenes keep some collisions within reach of float64; the pentagon (no chaos) all of them."""
    for c in DATA.values():
        assert c["horizon"] >= (c["n"] if c["scene"] == "point_pentagon" else 4), c["name"]


def test_near_corner_orbit_passes_the_corner():
    """Its first two hits are on the two sides of vertex 2, within 1e-8 of it, 2e-9 apart in time."""
    c = DATA["point_pentagon_near_corner"]
    corner = c["table"]["vertices"][2]
    assert c["hits"][:2] == [[[0, 2]], [[0, 1]]]
    for j in range(2):
        assert 0 < math.dist(corner, [float(v) for v in c["states"][j][:2]]) < 1e-8
    assert 0 < float(mpf(c["times"][1]) - mpf(c["times"][0])) < 1e-8


@pytest.mark.parametrize("name", FIRST_OF_SCENE)
def test_reference_recomputes_the_cache(name):
    """The first ten collisions, recomputed now, equal the cached ones (the cache cannot silently rot)."""
    c = DATA[name]
    m = 10
    times, states, hits = ref.reference_orbit(c["body"], c["table"], c["state0"], m, dps=gen.DPS)
    with mp.workdps(gen.DPS):
        rt, rs, rh = _reference(c)
        errs = gen.collision_errors(times, states, rt[:m], rs[:m], _scales(c))
        assert max(abs(s[2] - r[2]) for s, r in zip(states, rs)) < mpf("1e-28")  # alpha itself, not mod 2 pi
    assert max(errs) < 1e-28
    assert [_gaps_of(c, h) for h in rh[:m]] == [tuple(h) for h in hits]


# ---------------------------------------------------------------------------
# the reference against what it does not use
# ---------------------------------------------------------------------------
def _energy(c, s):
    with mp.workdps(gen.DPS):
        return ref.energy(ref.body(c["body"]), [mpf(v) for v in s])


@pytest.mark.parametrize("name", NAMES)
def test_reference_conserves_energy_and_wraps_alpha(name):
    c = DATA[name]
    with mp.workdps(gen.DPS):
        e0 = _energy(c, c["state0"])
        for s in c["states"]:
            assert abs(_energy(c, s) - e0) <= mpf("1e-30") * e0
            assert -mp.pi <= mpf(s[2]) < mp.pi


def test_reference_point_spin_is_a_free_rotor():
    """The point's spin is never kicked: alpha(t) = wrap(alpha0 + omega t) at every collision."""
    c = DATA["point_pentagon_a"]
    with mp.workdps(gen.DPS):
        a0, w0 = mpf(c["state0"][2]), mpf(c["state0"][5])
        assert w0 != 0
        for t, s in zip(c["times"], c["states"]):
            assert abs(mpf(s[5]) - w0) < mpf("1e-33")
            d = mpf(s[2]) - (a0 + w0 * mpf(t))
            assert abs(d - 2 * mp.pi * mpmath.nint(d / (2 * mp.pi))) < mpf("1e-30")


def _triangle_points(vertices):
    """Body-frame vertices about the centroid, which for a triangle is the vertices' mean."""
    mean = np.mean(np.asarray(vertices, dtype=float), axis=0)
    return np.asarray(vertices, dtype=float) - mean


def _body_points(c):
    """Body-frame contact points (float64), computed here without the reference."""
    b = c["body"]
    if b["type"] == "PolygonBody":
        return _triangle_points(b["vertices"])
    if b["type"] == "Dumbbell":
        return np.array([[b["l1"], 0.0], [-b["l2"], 0.0]])
    if b["type"] == "PointBody":
        return np.zeros((1, 2))
    theta = np.linspace(0, 2 * np.pi, 256, endpoint=False)  # the coin's rim
    return np.stack([b["a"] * np.cos(theta), b["b"] * np.sin(theta)], axis=-1)


def _outside_by(table_spec, px, py):
    """How far (a length) each point lies outside the table; <= 0 inside."""
    kind = table_spec["type"]
    if kind == "Stadium":
        hl, r = table_spec["half_length"], table_spec["radius"]
        return np.hypot(px - np.clip(px, -hl, hl), py) - r
    if kind == "Ellipse":
        a, b = table_spec["a"], table_spec["b"]
        return min(a, b) * ((px / a) ** 2 + (py / b) ** 2 - 1) / 2
    if kind == "Strip":
        return np.maximum(-py, py - table_spec["h"])
    if kind == "Polygon":
        v = np.asarray(table_spec["vertices"], dtype=float)
        out = np.full(np.shape(px), -np.inf)
        for j in range(len(v)):
            edge = v[(j + 1) % len(v)] - v[j]
            n = np.array([edge[1], -edge[0]]) / np.hypot(*edge)
            out = np.maximum(out, n[0] * (px - v[j][0]) + n[1] * (py - v[j][1]))
        return out
    raise AssertionError(kind)


@pytest.mark.parametrize("name", NAMES)
def test_reference_misses_no_root(name):
    """Dense float64 sampling of every contact point along every flight: none outside the table."""
    c = DATA[name]
    pts = _body_points(c)
    times = [0.0] + [float(t) for t in c["times"]]
    states = [c["state0"]] + [[float(v) for v in s] for s in c["states"]]
    worst = -np.inf
    for j in range(len(times) - 1):
        dt = times[j + 1] - times[j]
        x, y, al, vx, vy, w = states[j]
        tt = np.linspace(0.0, dt, max(2000, int(200 * abs(w) * dt)))[1:-1, None]
        ang = al + w * tt
        px = x + vx * tt + np.cos(ang) * pts[:, 0] - np.sin(ang) * pts[:, 1]
        py = y + vy * tt + np.sin(ang) * pts[:, 0] + np.cos(ang) * pts[:, 1]
        worst = max(worst, float(np.max(_outside_by(c["table"], px, py))))
    assert worst <= 1e-12


@pytest.mark.parametrize("name", NAMES)
def test_reference_contact_lies_on_its_piece(name):
    """Just after each collision the touching gap, written here from the table's description, is zero,
    every other gap is not negative, and a polygon's contact lies between the ends of the side named."""
    c = DATA[name]
    with mp.workdps(40):
        pieces = [(k, i) for i in range(c["pieces"]) for k in range(c["K"])]
        for s, hits in zip(c["states"], c["hits"]):
            q = [mpf(v) for v in s[:3]]
            ((k, i),) = hits
            assert abs(_gap_in_configuration(c, k, i)(*q)) < mpf("1e-30")
            assert min(_gap_in_configuration(c, kk, ii)(*q) for kk, ii in pieces) > -mpf("1e-30")
            if c["table"]["type"] == "Polygon":
                v = [[mpf(x) for x in p] for p in c["table"]["vertices"]]
                a, b = v[i], v[(i + 1) % len(v)]
                along = ((q[0] - a[0]) * (b[0] - a[0]) + (q[1] - a[1]) * (b[1] - a[1])) / (
                    (b[0] - a[0]) ** 2 + (b[1] - a[1]) ** 2
                )
                assert 0 < along < 1


def test_reference_stadium_hits_both_the_flat_sides_and_the_caps():
    """The stadium's gap switches formula between flat sides and caps; the cached orbits exercise both."""
    pts = _triangle_points(DATA["triangle_stadium_a"]["body"]["vertices"])
    on_flat = on_cap = 0
    for name in NAMES:
        c = DATA[name]
        if c["scene"] != "triangle_stadium":
            continue
        for s, (((k, _),)) in zip(c["states"], c["hits"]):
            x, al = float(s[0]), float(s[2])
            px = x + np.cos(al) * pts[k, 0] - np.sin(al) * pts[k, 1]
            if abs(px) < c["table"]["half_length"]:
                on_flat += 1
            else:
                on_cap += 1
    assert on_flat >= 10 and on_cap >= 10


def test_reference_body_constants_closed_forms():
    """Triangle: centroid = vertex mean, I = M (a^2 + b^2 + c^2)/36; square lamina: I = M s^2/6;
    dumbbell: I = m1 l1^2 + m2 l2^2 with m1 = M l2/(l1 + l2)."""
    with mp.workdps(40):
        verts = DATA["triangle_stadium_a"]["body"]["vertices"]
        tri = ref.body({"type": "PolygonBody", "vertices": verts, "mass": 2.5})
        mean = [sum(mpf(p[j]) for p in verts) / 3 for j in range(2)]
        for p, q in zip(tri.points, verts):
            assert abs(p[0] - (q[0] - mean[0])) < mpf("1e-38") and abs(p[1] - (q[1] - mean[1])) < mpf("1e-38")
        sides2 = sum(
            (mpf(verts[j][0]) - verts[(j + 1) % 3][0]) ** 2 + (mpf(verts[j][1]) - verts[(j + 1) % 3][1]) ** 2
            for j in range(3)
        )
        assert abs(tri.inertia - mpf("2.5") * sides2 / 36) < mpf("1e-38")
        square = ref.body({"type": "PolygonBody", "vertices": [[1, 1], [3, 1], [3, 3], [1, 3]]})
        assert abs(square.inertia - mpf(4) / 6) < mpf("1e-38") and square.points[0] == (-1, -1)
        l1, l2, M = mpf("0.6"), mpf("0.2"), mpf("1.5")
        dumbbell = ref.body({"type": "Dumbbell", "l1": l1, "l2": l2, "mass": M})
        m1, m2 = M * l2 / (l1 + l2), M * l1 / (l1 + l2)
        assert abs(dumbbell.inertia - (m1 * l1**2 + m2 * l2**2)) < mpf("1e-38")
        assert m1 * l1 == m2 * l2  # the centre of mass is the origin
        a, b = mpf("0.4"), mpf("0.2")
        coin = ref.body({"type": "EllipseBody", "a": a, "b": b, "mass": M})
        # uniform elliptic disc: M/(pi a b) times the integral of r^2 over it, in polar coordinates
        polar = mpmath.quad(
            lambda th: (a * b) ** 4 / (a * a * mpmath.sin(th) ** 2 + b * b * mpmath.cos(th) ** 2) ** 2 / 4,
            [0, 2 * mp.pi],
        )
        assert abs(coin.inertia - M * polar / (mp.pi * a * b)) < mpf("1e-35")


def test_reference_wrap_is_into_minus_pi_to_pi():
    with mp.workdps(40):
        assert ref.wrap(mp.pi) == -mp.pi and ref.wrap(-mp.pi) == -mp.pi
        assert abs(ref.wrap(mpf("3.5")) - (mpf("3.5") - 2 * mp.pi)) < mpf("1e-38")
        assert abs(ref.wrap(mpf("-10")) - (mpf("-10") + 4 * mp.pi)) < mpf("1e-38")


def test_reference_coin_support_matches_brute_force():
    """The coin's gap to each wall and its contact point against the rim's extreme point (200k rim points)."""
    a, b, h = 0.4, 0.2, 1.0
    bd, tb = ref.body({"type": "EllipseBody", "a": a, "b": b}), ref.table({"type": "Strip", "h": h})
    theta = np.linspace(0, 2 * np.pi, 200_000, endpoint=False)
    for al in np.linspace(-3.1, 3.1, 23):
        x, y = 0.3, 0.47
        rim_x = x + a * np.cos(theta) * np.cos(al) - b * np.sin(theta) * np.sin(al)
        rim_y = y + a * np.cos(theta) * np.sin(al) + b * np.sin(theta) * np.cos(al)
        state = [mpf(x), mpf(y), mpf(al), mpf(0), mpf(0), mpf(0)]
        for i, (gap_brute, j) in enumerate(((rim_y.min(), rim_y.argmin()), (h - rim_y.max(), rim_y.argmax()))):
            assert abs(float(ref.gap(bd, tb, state, i)[0]) - gap_brute) < 1e-9
            cp = ref.contact_point(bd, tb, state, i)
            assert math.dist((float(cp[0]), float(cp[1])), (rim_x[j], rim_y[j])) < 1e-4


def test_reference_stadium_gap_matches_brute_force():
    """The stadium gap (r^2 - dist^2)/(2r) against the distance to 100k points of the segment; zero on the
    boundary, positive inside, negative outside."""
    rng = np.random.default_rng(3)
    hl, r = 1.0, 0.8
    tb = ref.table({"type": "Stadium", "half_length": hl, "radius": r})
    seg = np.linspace(-hl, hl, 100_001)
    for px, py in rng.uniform([-2.0, -1.0], [2.0, 1.0], size=(40, 2)):
        dist = np.min(np.hypot(px - seg, py))
        g, _ = tb.gap(0, (mpf(px), mpf(py)))
        assert abs(float(g) - (r * r - dist * dist) / (2 * r)) < 1e-9


def _reflect_in_configuration(bd, gap_q, state):
    """Mass-metric reflection of (v, omega) about grad_q of the gap (by mpmath's numerical differentiation)."""
    q = state[:3]
    G = [mpmath.diff(gap_q, q, tuple(int(i == j) for i in range(3))) for j in range(3)]
    weights = [1 / bd.mass, 1 / bd.mass, bd.inverse_inertia]
    along = sum(g * v for g, v in zip(G, state[3:]))
    norm2 = sum(g * g * w for g, w in zip(G, weights))
    return [v - 2 * along / norm2 * w * g for v, w, g in zip(state[3:], weights, G)]


def _gap_in_configuration(c, k, i):
    """Gap of contact point ``k`` to piece ``i`` as a function of (x, y, alpha), from the table's own
    description (the distance inside, up to a positive factor), without the reference."""
    body, table = c["body"], c["table"]
    if body["type"] == "EllipseBody":
        a, b = mpf(body["a"]), mpf(body["b"])

        def lowest(al):  # min over theta of a cos(theta) sin(al) + b sin(theta) cos(al): the rim below the centre
            return -mpmath.sqrt((a * mpmath.sin(al)) ** 2 + (b * mpmath.cos(al)) ** 2)

        if i == 0:
            return lambda x, y, al: y + lowest(al)
        return lambda x, y, al: mpf(table["h"]) - y + lowest(al)
    if body["type"] == "PolygonBody":
        verts = body["vertices"]
        bx, by = (mpf(verts[k][j]) - sum(mpf(p[j]) for p in verts) / 3 for j in range(2))  # a triangle
    elif body["type"] == "Dumbbell":
        bx, by = (mpf(body["l1"]), mpf(0)) if k == 0 else (-mpf(body["l2"]), mpf(0))
    else:
        bx, by = mpf(0), mpf(0)

    def point(x, y, al):
        return x + mpmath.cos(al) * bx - mpmath.sin(al) * by, y + mpmath.sin(al) * bx + mpmath.cos(al) * by

    if table["type"] == "Stadium":
        hl, r = mpf(table["half_length"]), mpf(table["radius"])

        def stadium(x, y, al):
            px, py = point(x, y, al)
            return r - mpmath.hypot(px - min(max(px, -hl), hl), py)

        return stadium
    if table["type"] == "Polygon":
        v = [[mpf(x) for x in p] for p in table["vertices"]]
        a, b = v[i], v[(i + 1) % len(v)]

        def side(x, y, al):  # (b - a) x (P - a) / |b - a|: positive left of the side, inside
            px, py = point(x, y, al)
            return ((b[0] - a[0]) * (py - a[1]) - (b[1] - a[1]) * (px - a[0])) / mpmath.hypot(b[0] - a[0], b[1] - a[1])

        return side
    a, b = mpf(table["a"]), mpf(table["b"])
    return lambda x, y, al: 1 - (point(x, y, al)[0] / a) ** 2 - (point(x, y, al)[1] / b) ** 2


@pytest.mark.parametrize(
    "name", ["triangle_stadium_a", "triangle_stadium_fast_spin", "dumbbell_ellipse_a", "coin_strip_b"]
)
def test_reference_impulse_is_the_mass_metric_reflection(name):
    """Each cached impulse equals the reflection of (v, omega) in the metric diag(M, M, I) about the gradient
    of the touching gap in the configuration (x, y, alpha): no normal, lever arm or contact point used."""
    c = DATA[name]
    with mp.workdps(40):
        bd = ref.body(c["body"])
        times, states, hits = _reference(c)
        prev, t_prev = [mpf(v) for v in c["state0"]], mpf(0)
        for j in range(8):
            at_contact = ref.flow(prev, times[j] - t_prev)
            ((k, i),) = hits[j]
            want = _reflect_in_configuration(bd, _gap_in_configuration(c, k, i), at_contact)
            for got, expected in zip(states[j][3:], want):
                assert abs(got - expected) < mpf("1e-20")
            prev, t_prev = states[j], times[j]


@pytest.mark.parametrize(
    "body_spec",
    [
        {"type": "PolygonBody", "vertices": [[0.0, 0.0], [0.6, 0.0], [0.15, 0.4]]},
        {"type": "Dumbbell", "l1": 0.6, "l2": 0.2},
        {"type": "PointBody"},
    ],
    ids=["triangle", "dumbbell", "point"],
)
def test_reference_conserves_angular_momentum_in_a_circle(body_spec):
    """Every normal of a circle passes through its centre, so M (x vy - y vx) + I omega about it is conserved."""
    circle = {"type": "Circle", "R": 1.2}
    state0 = [0.1, -0.2, 0.3, 0.7, 0.45, 2.3]
    with mp.workdps(gen.DPS):
        bd = ref.body(body_spec)
        l0 = ref.angular_momentum(bd, [mpf(v) for v in state0])
        _, states, hits = ref.reference_orbit(body_spec, circle, state0, 15, dps=gen.DPS)
        assert len({h[0] for h in hits}) == bd.K  # every contact point touched
        for s in states:
            assert abs(ref.angular_momentum(bd, s) - l0) < mpf("1e-35")


def test_reference_point_in_a_rectangle_closed_form():
    """The point in a rectangle: |vx| and |vy| kept, and the collision times are those of the two
    independent bouncings, x between -1.5 and 1.5, y between -0.7 and 0.7, merged."""
    rectangle = {"type": "Polygon", "vertices": [[-1.5, -0.7], [1.5, -0.7], [1.5, 0.7], [-1.5, 0.7]]}
    x0, y0, vx, vy = 0.2, 0.1, 0.83, 0.41
    n = 30
    with mp.workdps(gen.DPS):
        times, states, hits = ref.reference_orbit({"type": "PointBody"}, rectangle, [x0, y0, 0.5, vx, vy, 1.1], n)
        x_times = [(mpf(1.5) - x0) / vx + j * 3 / mpf(vx) for j in range(n)]  # the floats 1.5 and 0.7, exactly
        y_times = [(mpf(0.7) - y0) / vy + j * 2 * mpf(0.7) / vy for j in range(n)]
        want = sorted([(t, "x") for t in x_times] + [(t, "y") for t in y_times])[:n]
        for t, s, h, (t_want, axis) in zip(times, states, hits, want):
            assert abs(t - t_want) < mpf("1e-38")
            assert abs(abs(s[3]) - vx) < mpf("1e-40") and abs(abs(s[4]) - vy) < mpf("1e-40")
            assert h[0] in ((1, 3) if axis == "x" else (0, 2))  # sides 1, 3 vertical; 0, 2 horizontal


def test_reference_corner_rule():
    """A point flown exactly into a rectangle's corner: both sides in one event, the faster-approaching
    (x, side 1) first, then side 2, which still approaches: the velocity comes back reversed."""
    rectangle = {"type": "Polygon", "vertices": [[-1.5, -0.7], [1.5, -0.7], [1.5, 0.7], [-1.5, 0.7]]}
    times, states, hits = ref.reference_orbit({"type": "PointBody"}, rectangle, [0.0, 0.0, 0.0, 1.5, 0.7, 0.0], 1)
    assert times[0] == 1 and hits[0] == (1, 2)
    assert states[0][3:5] == [-1.5, -0.7]


def _reverse(s):
    return [s[0], s[1], s[2], -s[3], -s[4], -s[5]]


@pytest.mark.parametrize("name", FIRST_OF_SCENE)
def test_reference_time_reversal(name):
    """From the middle of the 8th flight, reversed, the orbit retraces the first 7 collisions backwards."""
    c = DATA[name]
    n = 8
    with mp.workdps(gen.DPS):
        times, states, hits = _reference(c)
        mid = ref.flow(states[n - 2], (times[n - 1] - times[n - 2]) / 2)
        t_mid = (times[n - 1] + times[n - 2]) / 2
        back_t, back_s, back_h = ref.reference_orbit(c["body"], c["table"], _reverse(mid), n - 1, dps=gen.DPS)
        for i in range(n - 1):
            j = n - 2 - i
            assert abs(t_mid - back_t[i] - times[j]) < mpf("1e-25")
            assert back_h[i] == _gaps_of(c, hits[j])
            assert abs(back_s[i][0] - states[j][0]) < mpf("1e-25") and abs(back_s[i][1] - states[j][1]) < mpf("1e-25")
            assert abs(gen._angle_diff(back_s[i][2], states[j][2])) < mpf("1e-25")


# ---------------------------------------------------------------------------
# grazing: a contact point's path tangent to its piece, shifted by +-1e-12
# ---------------------------------------------------------------------------
TRIANGLE, STADIUM = gen.TRIANGLE, gen.STADIUM


def _stadium_graze(phi, depth, omega, slide, tau, centre_x=0.0):
    """A triangle whose top-most vertex touches the stadium tangentially at time ``tau``: on the cap at the
    angle ``phi`` (about the right cap's centre), or on the upper flat side above ``centre_x`` if ``phi`` is
    None; the body then shifted by ``depth`` along the outward normal (> 0: a hit, < 0: a miss)."""
    with mp.workdps(40):
        bd = ref.body(TRIANGLE)
        hl, r = mpf(STADIUM["half_length"]), mpf(STADIUM["radius"])
        N = (mpf(0), mpf(1)) if phi is None else (mpmath.cos(phi), mpmath.sin(phi))
        tangent = (-N[1], N[0])
        k = 1  # the vertex at (0.6, 0), farthest from the centroid
        bx, by = bd.points[k]
        arm = mpmath.hypot(bx, by)
        alpha = mpmath.atan2(N[1], N[0]) - mpmath.atan2(by, bx)  # vertex k straight along N
        r_vec = (arm * N[0], arm * N[1])
        touch = (centre_x + r_vec[0], r) if phi is None else (hl + r * N[0], r * N[1])
        centre = (touch[0] - r_vec[0] + depth * N[0], touch[1] - r_vec[1] + depth * N[1])
        # the vertex's velocity v + omega J r_vec along the tangent
        v = (slide * tangent[0] + omega * r_vec[1], slide * tangent[1] - omega * r_vec[0])
        at_touch = [centre[0], centre[1], alpha, v[0], v[1], mpf(omega)]
        return [float(x) for x in ref.flow(at_touch, -mpf(tau))], k


@pytest.mark.parametrize("where", ["flat", "cap", "cap_end"])
def test_reference_finds_a_grazing_hit_and_passes_a_near_miss(where):
    """The vertex's path dips 1e-12 through the wall for about 1e-6 of a flight: the hit is found at the
    tangency; shifted 1e-12 the other way, the reference passes it. On the flat side, on the cap, and where
    cap and flat side meet (the gap's formula switching inside the dip)."""
    phi = {"flat": None, "cap": 0.5, "cap_end": math.pi / 2}[where]
    tau = 0.2
    for depth in (1e-12, -1e-12):
        state0, k = _stadium_graze(phi, depth, omega=3.0, slide=0.3, tau=tau)
        times, _, hits = ref.reference_orbit(TRIANGLE, STADIUM, state0, 1, dps=gen.DPS)
        if depth > 0:
            assert hits[0] == (k,) and abs(times[0] - tau) < 1e-5
        else:
            assert times[0] > tau + 1e-2


def test_reference_coin_grazing_hit_and_near_miss():
    """The coin's gap to the floor, y - h(alpha), with a local minimum of -1e-12 (hit) or +1e-12 (miss)."""
    a, b, omega, tau, alpha_touch = 0.4, 0.2, 2.0, 0.3, 1.3
    for depth in (1e-12, -1e-12):
        with mp.workdps(40):
            al = mpf(alpha_touch)
            h = mpmath.sqrt((a * mpmath.sin(al)) ** 2 + (b * mpmath.cos(al)) ** 2)
            dh = (a * a - b * b) * mpmath.sin(al) * mpmath.cos(al) / h
            at_touch = [mpf(0), h - depth, al, mpf("0.3"), omega * dh, mpf(omega)]
            state0 = [float(v) for v in ref.flow(at_touch, -mpf(tau))]
        times, _, hits = ref.reference_orbit(gen.COIN, gen.STRIP, state0, 1, dps=gen.DPS)
        if depth > 0:
            assert hits[0] == (0,) and abs(times[0] - tau) < 1e-5
        else:
            assert times[0] > tau + 1e-2


def test_reference_rejects_bad_input():
    with pytest.raises(ValueError, match="convex"):
        ref.table({"type": "Polygon", "vertices": [[0, 0], [0, 1], [1, 1], [1, 0]]})  # clockwise
    with pytest.raises(ValueError, match="convex"):
        ref.body({"type": "PolygonBody", "vertices": [[0, 0], [2, 0], [1, 0.2], [1, 1]]})
    with pytest.raises(ValueError, match="flat walls"):
        ref.reference_orbit(gen.COIN, gen.ELLIPSE, [0, 0, 0, 1, 0, 0], 1)
    with pytest.raises(ValueError, match="outside"):
        ref.reference_orbit(TRIANGLE, STADIUM, [1.7, 0.0, 0.0, 1.0, 0.0, 0.0], 1)
