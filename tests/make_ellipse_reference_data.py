"""Generate ``tests/data/ellipse_reference.json`` from the mpmath reference of the stick in an ellipse.

Run from the repository root (a few minutes)::

    python tests/make_ellipse_reference_data.py

Each case is a scene ``(a, b, ell, mass, inertia)`` and a float64 initial
state; the reference orbit (``DPS`` digits, ``tests/mpmath_ellipse_reference.py``)
starts from those float64 numbers taken exactly. Each case also gets its
*horizon*: the orbit is recomputed from two copies of the initial state with
every component multiplied by ``1 + 1e-15 * sign`` (two fixed sign patterns),
and the horizon is the number of leading collisions over which both stay
within ``HORIZON_TOL = 1e-11`` of the unperturbed orbit (``collision_errors``)
with the same contacts. A float64 code errs by about ``1e-16`` at every step,
so beyond the horizon it cannot be asked to agree; within it, ``1e-10``.
``sensitivity`` keeps, per collision, the larger of the two perturbed orbits'
errors (``inf`` once a contact differs): the orbit's conditioning. An
ill-conditioned collision (a grazing hit, where the contact time moves by
``dg / g'`` with ``g'`` small) may differ from float64 by up to ``SENSITIVITY_FACTOR``
times it; the tests allow ``max(1e-10, SENSITIVITY_FACTOR * sensitivity)``
where that is below ``1e-7``.

Grazing states are built at an exact tangency of an end's path with the wall
(the end's velocity along the wall, its path curving away from it), moved by
``depth`` along the wall's normal (outwards: a shallow hit; inwards: a near
miss) and flown back by ``tau``; the generator checks that both ends stay inside
on the way back.
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

import mpmath_ellipse_reference as ref

DPS = 45
N_COLLISIONS = 20
PERTURBATION = 1e-15
HORIZON_TOL = 1e-11
AGREEMENT_TOL = 1e-10
SENSITIVITY_FACTOR = 30.0
SENSITIVE_LIMIT = 1e-7
DATA_PATH = os.path.join(os.path.dirname(os.path.abspath(__file__)), "data", "ellipse_reference.json")
SIGNS = ((1, -1, 1, 1, -1, -1), (-1, -1, 1, -1, 1, 1))
STORE_DIGITS = 25
INF = float("inf")


# ---------------------------------------------------------------------------
# scales and the comparison metric (shared with the tests)
# ---------------------------------------------------------------------------
def scales(a, b, ell, mass, inertia, state0):
    """``(T, L, V, W)``: time ``L/V``, length ``L = sqrt(ab)``, speed ``sqrt(2E/M)`` and spin
    (``sqrt(2E/I)`` for a turning stick, else ``max(|omega0|, V/L)``), as floats."""
    with mp.workdps(30):
        a, b, ell, mass, inertia = ref.params(a, b, ell, mass, inertia)
        s = [mpf(v) for v in state0]
        e = ref.energy(mass, inertia, s)
        length = mpmath.sqrt(a * b)
        speed = mpmath.sqrt(2 * e / mass)
        if ell > 0 and not mpmath.isinf(inertia):
            spin = mpmath.sqrt(2 * e / inertia)
        else:
            spin = max(abs(s[5]), speed / length)
        return float(length / speed), float(length), float(speed), float(spin)


def _mp(x):
    """An mpf from an mpf, a string or any float-like (numpy scalars and 0-d arrays included), exactly."""
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
# constructed states
# ---------------------------------------------------------------------------
def _inside_all_along(a, b, ell, state, t_from, t_to, samples=600):
    """Both ends strictly inside at ``samples`` points of ``[t_from, t_to]``."""
    ends = (1,) if ell == 0 else (1, -1)
    for i in range(samples + 1):
        t = t_from + (t_to - t_from) * mpf(i) / samples
        for k in ends:
            if not ref.gap(a, b, ell, state, k, t)[0] > 0:
                return False
    return True


def graze_state(a, b, ell, theta, tilt, omega, slide, depth, tau):
    """A float64 state whose end P1 grazes the wall near ``(a cos theta, b sin theta)`` at time ``tau``.

    ``tilt``: the stick's angle from the inward normal at the touching point;
    ``slide``: P1's speed along the wall at the tangency; ``depth > 0`` moves the
    centre outwards (a hit about ``depth`` deep in length), ``< 0`` inwards (a miss).
    """
    with mp.workdps(40):
        a, b, ell, theta, tilt, omega, slide, depth, tau = (
            mpf(v) for v in (a, b, ell, theta, tilt, omega, slide, depth, tau)
        )
        wall = [a * mpmath.cos(theta), b * mpmath.sin(theta)]
        normal = [mpmath.cos(theta) / a, mpmath.sin(theta) / b]
        norm = mpmath.hypot(*normal)
        normal = [normal[0] / norm, normal[1] / norm]
        tangent = [-normal[1], normal[0]]
        alpha = mpmath.atan2(normal[1], normal[0]) + tilt  # u along the outward normal, tilted
        u = [mpmath.cos(alpha), mpmath.sin(alpha)]
        u_perp = [-u[1], u[0]]
        centre = [wall[i] - ell * u[i] + depth * normal[i] for i in range(2)]
        velocity = [slide * tangent[i] - ell * omega * u_perp[i] for i in range(2)]
        at_touch = [centre[0], centre[1], alpha, velocity[0], velocity[1], omega]
        start = ref.flow(at_touch, -tau)
        start = [float(v) for v in start]
        assert _inside_all_along(a, b, ell, [mpf(v) for v in start], 0, tau * (1 - mpf("1e-3"))), "not inside"
        return start


def chord_graze_state(a, b, ell, theta, tilt, incidence, speed=1.0, fraction=0.5):
    """A stick that never turns (or a point) whose end P1 meets the wall at ``(a cos theta, b sin theta)``
    at the small angle ``incidence`` (radians): a straight path cannot touch a convex wall
    tangentially from inside, so its grazing hit is a short chord. It starts ``fraction`` of
    the way back along that chord."""
    with mp.workdps(40):
        a, b, ell, theta, tilt, incidence = (mpf(v) for v in (a, b, ell, theta, tilt, incidence))
        wall = [a * mpmath.cos(theta), b * mpmath.sin(theta)]
        normal = [mpmath.cos(theta) / a, mpmath.sin(theta) / b]
        norm = mpmath.hypot(*normal)
        normal = [normal[0] / norm, normal[1] / norm]
        tangent = [-normal[1], normal[0]]
        d = [mpmath.cos(incidence) * tangent[i] + mpmath.sin(incidence) * normal[i] for i in range(2)]
        # the chord W - s d, 0 < s < s_end, inside the ellipse
        qa = d[0] ** 2 / a**2 + d[1] ** 2 / b**2
        qb = -2 * (wall[0] * d[0] / a**2 + wall[1] * d[1] / b**2)
        s_end = -qb / qa
        back = fraction * s_end
        alpha = mpmath.atan2(normal[1], normal[0]) + tilt
        u = [mpmath.cos(alpha), mpmath.sin(alpha)]
        centre = [wall[i] - ell * u[i] - back * d[i] for i in range(2)]
        start = [centre[0], centre[1], alpha, speed * d[0], speed * d[1], mpf(0)]
        start = [float(v) for v in start]
        tau = back / speed
        assert _inside_all_along(a, b, ell, [mpf(v) for v in start], 0, tau * (1 - mpf("1e-3"))), "not inside"
        return start


def corner_chord_centre(a, b, ell, alpha):
    """The centre of a stick at angle ``alpha`` with both ends on the wall (its chord, ``s > 0`` side)."""
    with mp.workdps(40):
        a, b, ell = mpf(a), mpf(b), mpf(ell)
        u = [mpmath.cos(alpha), mpmath.sin(alpha)]
        w = [-u[1], u[0]]
        qa = u[0] ** 2 / a**2 + u[1] ** 2 / b**2
        cross = w[0] * u[0] / a**2 + w[1] * u[1] / b**2
        qw = w[0] ** 2 / a**2 + w[1] ** 2 / b**2

        def half_chord(s):
            qb, qc = 2 * s * cross, s * s * qw - 1
            return mpmath.sqrt(qb * qb - 4 * qa * qc) / (2 * qa)

        s = mpmath.findroot(
            lambda s: half_chord(s) - ell, (mpf(0), 1 / mpmath.sqrt(qw) * (1 - mpf("1e-12"))), solver="anderson"
        )
        mid = -2 * s * cross / (2 * qa)
        return [s * w[0] + mid * u[0], s * w[1] + mid * u[1]]


def near_corner_state(a, b, ell, alpha, miss, tau=1.0):
    """A static stick at ``alpha`` whose centre flies from the origin at a corner, shifted by ``miss`` (length)."""
    with mp.workdps(40):
        corner = corner_chord_centre(a, b, ell, mpf(alpha))
        u = [mpmath.cos(alpha), mpmath.sin(alpha)]
        target = [corner[0] + miss * u[0], corner[1] + miss * u[1]]
        start = [mpf(0), mpf(0)]
        v = [(target[i] - start[i]) / tau for i in range(2)]
        return [float(start[0]), float(start[1]), float(alpha), float(v[0]), float(v[1]), 0.0]


# ---------------------------------------------------------------------------
# the cases
# ---------------------------------------------------------------------------
def _case(name, a, b, ell, state0, mass=1.0, inertia=None, note=""):
    return {
        "name": name,
        "a": a,
        "b": b,
        "ell": ell,
        "mass": mass,
        "inertia": inertia,
        "state0": [float(v) for v in state0],
        "note": note,
    }


CASES = [
    # a = b: StickInEllipse must equal StickInCircle collision by collision.
    _case("circle_rotor", 2.0, 2.0, 1.0, [0.1, 0.2, 0.3, 0.7, -0.4, 1.3], note="a = b"),
    _case("circle_static", 2.0, 2.0, 1.5, [0.05, -0.1, 0.7, -0.6, 0.5, 0.0], inertia=INF, note="a = b"),
    _case("circle_point", 2.0, 2.0, 0.0, [0.3, -0.5, 0.0, 0.8, 0.35, 0.0], note="a = b"),
    # a/b from 1.01 to 3, either axis the larger.
    _case("ratio_1.01", 2.02, 2.0, 1.0, [0.1, 0.2, 0.3, 0.7, -0.4, 1.3]),
    _case("ratio_1.1", 2.2, 2.0, 1.2, [-0.2, 0.1, 1.1, 0.5, 0.6, -0.9]),
    _case("ratio_1.5", 3.0, 2.0, 1.0, [0.4, -0.3, -0.5, -0.8, 0.3, 0.6]),
    _case("ratio_2", 2.0, 1.0, 0.6, [0.2, 0.1, 0.1, 0.9, 0.45, 0.8]),
    _case("ratio_3", 3.0, 1.0, 0.5, [-0.5, 0.2, 0.4, 0.7, -0.3, 1.5]),
    _case("ratio_1over2.5_b_major", 1.0, 2.5, 0.7, [0.1, -0.4, 1.4, 0.3, 0.9, -0.7]),
    _case("mass0.3_inertia0.05", 2.5, 1.5, 0.8, [0.3, 0.2, 2.0, -0.6, 0.8, 1.1], mass=0.3, inertia=0.05),
    # long sticks: nearly the minor axis, and longer than it (fits near the major axis only).
    _case("long_0.99_minor", 3.0, 1.5, 1.485, [0.2, 0.0, 0.05, 0.9, 0.2, 0.3]),
    _case("longer_than_minor", 3.0, 1.0, 1.6, [0.3, 0.0, 0.02, 0.8, 0.1, 0.05], inertia=4.0),
    _case("fast_spin", 2.0, 1.4, 0.6, [0.2, -0.1, 0.4, 0.6, 0.5, 40.0]),
    # grazing: an end's curved path tangent to the wall, shifted by 1e-8 (hit) or -1e-8 (miss);
    # for straight paths (static stick, point) a chord meeting the wall at 1e-4 rad.
    _case("graze_hit_rotor", 2.5, 1.5, 0.8, graze_state(2.5, 1.5, 0.8, 0.7, 0.3, 1.5, 1.0, 1e-8, 0.4)),
    _case("graze_miss_rotor", 2.5, 1.5, 0.8, graze_state(2.5, 1.5, 0.8, 0.7, 0.3, 1.5, 1.0, -1e-8, 0.4)),
    _case("graze_miss_rotor_b_major", 1.2, 2.0, 0.5, graze_state(1.2, 2.0, 0.5, 2.5, -0.2, 2.0, 0.8, -1e-9, 0.3)),
    _case("graze_hit_static", 2.0, 1.2, 0.7, chord_graze_state(2.0, 1.2, 0.7, 2.0, -0.3, 1e-4), inertia=INF),
    _case("graze_hit_point", 2.0, 1.2, 0.0, chord_graze_state(2.0, 1.2, 0.0, -1.0, 0.0, 1e-4)),
    # a stick that never turns, flying at a corner of its region (both ends on the wall).
    _case("static_near_corner_1e-7", 2.0, 1.3, 0.9, near_corner_state(2.0, 1.3, 0.9, 0.35, 1e-7), inertia=INF),
    _case("static_near_corner_-1e-5", 2.0, 1.3, 0.9, near_corner_state(2.0, 1.3, 0.9, 0.35, -1e-5), inertia=INF),
    _case("static_ratio_2", 2.0, 1.0, 0.5, [0.1, 0.2, 0.8, 0.6, -0.7, 0.0], inertia=INF),
    # the point particle (elliptic billiard) and a tiny, heavy stick near it.
    _case("point_ratio_2", 2.0, 1.0, 0.0, [0.3, 0.1, 0.0, 0.6, 0.8, 0.0]),
    _case("point_ratio_1.5_spinning", 1.5, 1.0, 0.0, [-0.2, 0.3, 0.5, 0.9, -0.2, 2.0]),
    _case("tiny_ell_heavy", 2.0, 1.2, 1e-3, [0.3, 0.1, 0.2, 0.6, 0.8, 0.3], inertia=10.0),
]


def _inertia_arg(inertia):
    return "inf" if inertia is not None and math.isinf(inertia) else inertia


def _args(case):
    return case["a"], case["b"], case["ell"], case["mass"], _inertia_arg(case["inertia"])


def _perturbed(state0, signs, eps=PERTURBATION):
    return [mpf(v) * (1 + mpf(eps) * s) for v, s in zip(state0, signs)]


def compute_case(case, n=N_COLLISIONS, dps=DPS):
    args = _args(case)
    times, states, contacts = ref.reference_orbit(*args, case["state0"], n, dps=dps)
    sc = scales(*args, case["state0"])
    horizon = n
    sensitivity = [0.0] * n
    with mp.workdps(dps):
        for signs in SIGNS:
            pt, ps, pk = ref.reference_orbit(*args, _perturbed(case["state0"], signs), n, dps=dps)
            errs = collision_errors(pt, ps, times, states, sc)
            for j in range(n):
                sensitivity[j] = max(sensitivity[j], errs[j] if pk[j] == contacts[j] else math.inf)
            bad = next((j for j in range(n) if errs[j] > HORIZON_TOL or pk[j] != contacts[j]), n)
            horizon = min(horizon, bad)
    with mp.workdps(STORE_DIGITS):
        return {
            **case,
            "inertia": _inertia_arg(case["inertia"]),
            "n": n,
            "horizon": horizon,
            "sensitivity": sensitivity,
            "times": [mpmath.nstr(t, STORE_DIGITS) for t in times],
            "states": [[mpmath.nstr(v, STORE_DIGITS) for v in s] for s in states],
            "contacts": contacts,
        }


def main():
    out = []
    for case in CASES:
        start = time.time()
        out.append(compute_case(case))
        print(
            f"{case['name']:32s} horizon {out[-1]['horizon']:3d}  contacts {out[-1]['contacts']}  "
            f"{time.time() - start:.1f} s",
            flush=True,
        )
    os.makedirs(os.path.dirname(DATA_PATH), exist_ok=True)
    with open(DATA_PATH, "w") as f:
        json.dump({"dps": DPS, "perturbation": PERTURBATION, "horizon_tol": HORIZON_TOL, "cases": out}, f, indent=1)


if __name__ == "__main__":
    main()
