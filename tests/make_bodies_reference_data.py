"""Generate ``tests/data/bodies_reference.json`` from the mpmath reference of a body in a table.

Run from the repository root (a minute or two)::

    python tests/make_bodies_reference_data.py

Four scenes, three orbits each: a triangle spinning in a stadium (one orbit
spinning fast), a dumbbell of mass ratio 1:3 spinning in an ellipse, a point
in an irregular convex pentagon (one orbit passing 1e-9 from a corner, hitting
both of its sides) and the coin spinning between two flat walls. Each orbit
(``DPS`` digits, ``tests/mpmath_bodies_reference.py``) starts from float64
numbers taken exactly.

Each orbit gets its *horizon*: it is recomputed from two copies of the initial
state with every component multiplied by ``1 + PERTURBATION * sign`` (two
fixed sign patterns), and the horizon is the number of leading collisions over
which both stay within ``HORIZON_TOL`` of the unperturbed orbit
(``collision_errors``) with the same contacts. A float64 code errs by about
``1e-16`` at every step, so within the horizon it must agree to
``AGREEMENT_TOL``, and not beyond. ``sensitivity`` keeps, per collision, the
larger of the two perturbed orbits' errors (``inf`` once a contact differs):
beyond the horizon a float64 code may differ by up to ``SENSITIVITY_FACTOR``
times it, where that is below ``SENSITIVE_LIMIT``.

So that no stored contact depends on how close two contacts must be to count
as one event, every collision of every run is checked: no second gap joins an
event, and every other approaching gap is at least ``APART_MIN`` (in units of
the table's length) from zero; a float64 code's 64-ulp rule classifies these
events identically.
"""

from __future__ import annotations

import json
import math
import os
import sys
import time

import mpmath
from mpmath import mp, mpf

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))

import mpmath_bodies_reference as ref

DPS = 45
PERTURBATION = 1e-15
HORIZON_TOL = 1e-11
AGREEMENT_TOL = 1e-10
SENSITIVITY_FACTOR = 30.0
SENSITIVE_LIMIT = 1e-7
APART_MIN = 1e-12
STORE_DIGITS = 34
DATA_PATH = os.path.join(os.path.dirname(os.path.abspath(__file__)), "data", "bodies_reference.json")
SIGNS = ((1, -1, 1, 1, -1, -1), (-1, -1, 1, -1, 1, 1))

TRIANGLE = {"type": "PolygonBody", "vertices": [[0.0, 0.0], [0.6, 0.0], [0.15, 0.4]]}
STADIUM = {"type": "Stadium", "half_length": 1.0, "radius": 0.8}
DUMBBELL = {"type": "Dumbbell", "l1": 0.6, "l2": 0.2}  # masses m1:m2 = l2:l1 = 1:3
ELLIPSE = {"type": "Ellipse", "a": 2.0, "b": 1.2}
POINT = {"type": "PointBody"}
PENTAGON = {"type": "Polygon", "vertices": [[1.1, -0.2], [0.7, 0.85], [-0.45, 0.95], [-1.05, 0.05], [-0.2, -0.95]]}
COIN = {"type": "EllipseBody", "a": 0.4, "b": 0.2}
STRIP = {"type": "Strip", "h": 1.0}


# ---------------------------------------------------------------------------
# scales and the comparison metric (shared with the tests)
# ---------------------------------------------------------------------------
def scales(body_spec, table_spec, state0):
    """``(T, L, V, W)`` as floats (``ref.scales``): the table's length, ``V = sqrt(2E/M)``, ``T = L/V``,
    the spin scale ``sqrt(2E/I)`` (``max(|omega0|, V/L)`` for a body that never turns)."""
    with mp.workdps(30):
        bd, tb = ref.body(body_spec), ref.table(table_spec)
        return tuple(float(v) for v in ref.scales(bd, tb, [mpf(v) for v in state0]))


def _mp(x):
    """An mpf from an mpf, a string or any float-like (numpy scalars included), exactly."""
    return mpf(x) if isinstance(x, (str, int, float, mpf)) else mpf(float(x))


def _angle_diff(x, y):
    d = _mp(x) - _mp(y)
    two_pi = 2 * mp.pi
    return d - two_pi * mpmath.floor((d + mp.pi) / two_pi)


def collision_errors(times_a, states_a, times_b, states_b, sc):
    """Per collision: the largest of ``|dt|/T``, ``|dx|/L``, ``|d alpha|`` (mod 2 pi), ``|dv|/V``, ``|d omega|/W``."""
    T, L, V, W = sc
    out = []
    for ta, sa, tb, sb in zip(times_a, states_a, times_b, states_b):
        sa, sb = [_mp(v) for v in sa], [_mp(v) for v in sb]
        e = abs(_mp(ta) - _mp(tb)) / T
        e = max(e, abs(sa[0] - sb[0]) / L, abs(sa[1] - sb[1]) / L)
        e = max(e, abs(_angle_diff(sa[2], sb[2])))
        e = max(e, abs(sa[3] - sb[3]) / V, abs(sa[4] - sb[4]) / V)
        e = max(e, abs(sa[5] - sb[5]) / W)
        out.append(float(e))
    return out


# ---------------------------------------------------------------------------
# a constructed state: the point passing near a corner of the polygon
# ---------------------------------------------------------------------------
def near_corner_state(polygon_spec, corner, miss, beta, back, speed=1.0, spin=0.0):
    """A point that hits side ``corner`` (from vertex ``corner`` to the next) at ``miss`` from vertex
    ``corner``, arriving at the angle ``beta`` to the side while moving towards that vertex (so that for
    ``beta`` below pi minus the corner's angle it next hits the previous side, as near the corner),
    having started ``back`` (a length) before, in float64."""
    with mp.workdps(40):
        vertices = [(mpf(p[0]), mpf(p[1])) for p in polygon_spec["vertices"]]
        n_sides = len(vertices)
        p, q = vertices[corner], vertices[(corner + 1) % n_sides]
        edge = (q[0] - p[0], q[1] - p[1])
        length = mpmath.hypot(*edge)
        e = (edge[0] / length, edge[1] / length)
        outward = (e[1], -e[0])
        target = (p[0] + miss * e[0], p[1] + miss * e[1])
        beta = mpf(beta)
        d = (
            -mpmath.cos(beta) * e[0] + mpmath.sin(beta) * outward[0],
            -mpmath.cos(beta) * e[1] + mpmath.sin(beta) * outward[1],
        )
        start = (target[0] - back * d[0], target[1] - back * d[1])
        return [float(start[0]), float(start[1]), 0.5, float(speed * d[0]), float(speed * d[1]), float(spin)]


# ---------------------------------------------------------------------------
# the cases
# ---------------------------------------------------------------------------
def _case(name, scene, body_spec, table_spec, state0, n, note=""):
    return {
        "name": name,
        "scene": scene,
        "body": body_spec,
        "table": table_spec,
        "state0": [float(v) for v in state0],
        "n": n,
        "note": note,
    }


NEAR_CORNER = near_corner_state(PENTAGON, corner=2, miss=1e-9, beta=0.6, back=1.2)

CASES = [
    _case("triangle_stadium_a", "triangle_stadium", TRIANGLE, STADIUM, [0.3, 0.1, 0.4, 0.8, 0.55, 1.7], 40),
    _case("triangle_stadium_b", "triangle_stadium", TRIANGLE, STADIUM, [-0.6, -0.2, -1.1, -0.5, 0.9, -2.3], 40),
    _case(
        "triangle_stadium_fast_spin",
        "triangle_stadium",
        TRIANGLE,
        STADIUM,
        [0.1, 0.05, 2.0, 0.7, -0.3, 25.0],
        40,
        note="spin energy 27 times the translational",
    ),
    _case("dumbbell_ellipse_a", "dumbbell_ellipse", DUMBBELL, ELLIPSE, [0.2, -0.1, 0.5, 0.9, 0.4, 1.9], 40),
    _case("dumbbell_ellipse_b", "dumbbell_ellipse", DUMBBELL, ELLIPSE, [-0.5, 0.3, 2.2, -0.3, -0.8, -1.2], 40),
    _case("dumbbell_ellipse_c", "dumbbell_ellipse", DUMBBELL, ELLIPSE, [0.8, 0.2, -0.7, 0.6, -0.6, 3.1], 40),
    _case("point_pentagon_a", "point_pentagon", POINT, PENTAGON, [0.1, 0.2, 0.3, 0.83, 0.41, 0.7], 100),
    _case("point_pentagon_b", "point_pentagon", POINT, PENTAGON, [-0.3, -0.1, 0.0, -0.35, 0.92, 0.0], 100),
    _case(
        "point_pentagon_near_corner",
        "point_pentagon",
        POINT,
        PENTAGON,
        NEAR_CORNER,
        100,
        note="first two hits on sides 2 and 1 within 1e-8 of their common vertex",
    ),
    _case("coin_strip_a", "coin_strip", COIN, STRIP, [0.0, 0.5, 0.3, 0.4, 0.9, 2.1], 40),
    _case("coin_strip_b", "coin_strip", COIN, STRIP, [1.0, 0.45, -2.0, -0.7, -0.5, -3.3], 40),
    _case("coin_strip_c", "coin_strip", COIN, STRIP, [0.0, 0.6, 1.0, 0.2, 1.3, 0.8], 40),
]


def _perturbed(state0, signs, eps=PERTURBATION):
    return [mpf(v) * (1 + mpf(eps) * s) for v, s in zip(state0, signs)]


def _run(case, state0, n, dps=DPS):
    """The reference orbit with the event-separation checks of the module docstring."""
    info = {}
    times, states, hits = ref.reference_orbit(case["body"], case["table"], state0, n, dps=dps, info=info)
    for j in range(n):
        assert info["joined"][j] is None, f"{case['name']} collision {j}: a second contact joined"
        nearest = info["nearest_other"][j]
        assert nearest is None or nearest >= APART_MIN, f"{case['name']} collision {j}: another gap {nearest:.3g}"
    return times, states, hits


def point_and_piece(case, g):
    """``[k, i]`` of gap ``g = i K + k``."""
    K = ref.body(case["body"]).K
    return [g % K, g // K]


def compute_case(case, dps=DPS):
    n = case["n"]
    times, states, hits = _run(case, case["state0"], n, dps)
    sc = scales(case["body"], case["table"], case["state0"])
    horizon = n
    sensitivity = [0.0] * n
    with mp.workdps(dps):
        for signs in SIGNS:
            pt, ps, ph = _run(case, _perturbed(case["state0"], signs), n, dps)
            errs = collision_errors(pt, ps, times, states, sc)
            for j in range(n):
                sensitivity[j] = max(sensitivity[j], errs[j] if ph[j] == hits[j] else math.inf)
            bad = next((j for j in range(n) if errs[j] > HORIZON_TOL or ph[j] != hits[j]), n)
            horizon = min(horizon, bad)
    with mp.workdps(dps):
        bd, tb = ref.body(case["body"]), ref.table(case["table"])
    with mp.workdps(STORE_DIGITS):
        return {
            **case,
            "K": bd.K,
            "pieces": tb.pieces,
            "horizon": horizon,
            "sensitivity": [float(f"{v:.3g}") for v in sensitivity],
            "times": [mpmath.nstr(t, STORE_DIGITS) for t in times],
            "states": [[mpmath.nstr(v, STORE_DIGITS) for v in s] for s in states],
            "hits": [[point_and_piece(case, g) for g in h] for h in hits],
        }


def main():
    out = []
    begin = time.time()
    for case in CASES:
        start = time.time()
        out.append(compute_case(case))
        c = out[-1]
        beyond = [j for j in range(c["n"]) if SENSITIVITY_FACTOR * c["sensitivity"][j] <= SENSITIVE_LIMIT]
        print(
            f"{case['name']:30s} n {c['n']:3d}  horizon {c['horizon']:3d}  "
            f"checkable (30x sensitivity <= 1e-7) {len(beyond):3d}  {time.time() - start:5.1f} s",
            flush=True,
        )
    os.makedirs(os.path.dirname(DATA_PATH), exist_ok=True)
    with open(DATA_PATH, "w") as f:
        json.dump(
            {
                "dps": DPS,
                "perturbation": PERTURBATION,
                "horizon_tol": HORIZON_TOL,
                "store_digits": STORE_DIGITS,
                "cases": out,
            },
            f,
            indent=None,
            separators=(",", ":"),
        )
        f.write("\n")
    print(f"total {time.time() - begin:.1f} s, {os.path.getsize(DATA_PATH) / 1e3:.0f} kB")


if __name__ == "__main__":
    main()
