"""Generate ``tests/data/walls_reference_orbits.json`` from the mpmath walls reference.

Run from the repository root::

    .venv/bin/python tests/make_walls_reference_data.py          # all cases
    .venv/bin/python tests/make_walls_reference_data.py --check  # recompute, compare with file
    .venv/bin/python tests/make_walls_reference_data.py --only 2D/generic_a

Each case is a scene (``kind`` 2D or 3D, ``h``, ``ell``, ``mass``, ``inertia``)
and a float64 initial state; the reference orbit (50 digits, ``N_COLLISIONS``
collisions) starts from those float64 numbers taken exactly. With each case
goes its *chaos horizon*:

    The orbit is recomputed from two copies of the initial state with every
    component multiplied by ``1 + PERTURBATION * sign`` (``1e-15``, two fixed
    sign patterns; zero components stay zero, so planar and symmetric orbits
    stay so). ``horizon`` is the number of leading collisions before the first
    one where either perturbed orbit differs from the unperturbed one by more
    than ``HORIZON_TOL = 1e-11`` (metric ``collision_errors``) or has another
    contact code. A float64 code makes errors of about the perturbation's size
    at every step, so agreement to ``AGREEMENT_TOL = 1e-10`` can be demanded on
    the first ``min(N_COLLISIONS, horizon)`` collisions, and not beyond.

Every case must have a horizon of at least ``MIN_HORIZON`` unless it carries an
``ill_conditioned`` reason (then at least 1).

Simultaneous contacts: the reference joins a second contact to an event when
its gap is below ``SIMULTANEOUS_TOL = 1e-14 h``. So that no stored contact code
depends on that choice, the generator asserts for every collision of every run
that a joined gap is below ``1e-15 h`` and that every other approaching gap is
above ``1e-12 h``: any tolerance in ``[1e-15, 1e-12] h`` (a float64 code's
``~64 ulp`` included) classifies these events identically.
"""

from __future__ import annotations

import argparse
import json
import math
import os
import sys
import time

import mpmath
from mpmath import mp, mpf

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))

import mpmath_walls_reference as ref

DPS = 50
N_COLLISIONS = 40
PERTURBATION = 1e-15
HORIZON_TOL = 1e-11
AGREEMENT_TOL = 1e-10
MIN_HORIZON = 5  # generic orbits amplify errors ~4x per collision: 1e-15 -> 1e-11 takes ~7
STORE_DIGITS = 25
JOINED_MAX = 1e-15  # a contact joined to an event: gap / h at most this
APART_MIN = 1e-12  # an approaching gap not joined: gap / h at least this
DATA_PATH = os.path.join(os.path.dirname(os.path.abspath(__file__)), "data", "walls_reference_orbits.json")
SIGNS = {
    "2D": ((1, -1, 1, 1, -1, -1), (-1, -1, 1, -1, 1, 1)),
    "3D": ((1, -1, 1, -1, 1, 1, -1, 1, 1, -1, -1, 1), (-1, 1, 1, 1, -1, 1, 1, -1, 1, 1, 1, -1)),
}
INF = float("inf")


# ---------------------------------------------------------------------------
# scales and the comparison metric (shared with tests/test_walls_reference.py)
# ---------------------------------------------------------------------------
def scales(kind, h, ell, mass, inertia, state0):
    """Natural scales ``(T, H, V, W)``: time ``h/V``, length ``h``, speed
    ``V = sqrt(2E/M)``, spin ``W = sqrt(2E/I)`` (``V/h`` for ``I = inf``). Floats."""
    kind = ref.kind_of(kind)
    with mp.workdps(30):
        hm, ellm, Mm, Im = ref.params(h, ell, mass, inertia)
        s = ref.normalize_state(kind, state0)
        E = ref.energy(kind, Mm, Im, s)
        V = mpmath.sqrt(2 * E / Mm)
        W = V / hm if mpmath.isinf(Im) else mpmath.sqrt(2 * E / Im)
        return float(hm / V), float(hm), float(V), float(W)


def turned(kind, state0, times, states):
    """Cumulative rotation angle of the reference orbit at each collision:
    ``Phi_j = |theta_0| + sum |omega| dt`` (2D), ``sum |w| dt`` (3D). The
    orientation of a float64 code carries about ``Phi * 2^-52`` of rounding
    (``theta + omega t`` or ``cos(|w| t)``), so orientation errors are
    measured relative to ``max(1, Phi)``."""
    kind = ref.kind_of(kind)
    with mp.workdps(30):
        prev_t = mpf(0)
        prev = [mpf(v) for v in state0]
        phi = abs(prev[2]) if kind == "2D" else mpf(0)
        out = []
        for t, s in zip(times, states):
            t = mpf(t)
            spin = abs(prev[5]) if kind == "2D" else mpmath.sqrt(sum(mpf(c) ** 2 for c in prev[9:12]))
            if mpmath.isfinite(t):
                phi += spin * (t - prev_t)
                prev_t = t
            out.append(float(phi))
            prev = [mpf(v) for v in s]
        return out


def _angle_diff(a, b):
    """``a - b`` wrapped into ``[-pi, pi]`` (mpf arithmetic)."""
    d = mpf(a) - mpf(b)
    return d - 2 * mp.pi * mpmath.nint(d / (2 * mp.pi))


def collision_errors(kind, times_a, states_a, times_b, states_b, sc, phi):
    """Per-collision scaled distance between two orbits; ``b`` is the reference.

    2D: ``max(|dt|/max(T,|t|), |dx|/max(h,|x|), |dz|/h, |dtheta mod 2pi|/max(1,Phi),
    |dvx|/V, |dvz|/V, |domega|/W)``; 3D: ``max(|dt|/max(T,|t|), |dx|/max(h,|x|),
    |dy|/max(h,|y|), |dz|/h, |du_i|/max(1,Phi), |dv_i|/V, |dw_i|/W)``.
    ``x`` and ``y`` drift freely (rounding grows with them); ``Phi`` is
    ``turned(...)`` of the reference. Differences are formed in mpf
    arithmetic, so mpf inputs keep their precision. Infinite times (contact
    0) must match exactly."""
    kind = ref.kind_of(kind)
    T, H, V, W = sc
    out = []
    for ta, sa, tb, sb, ph in zip(times_a, states_a, times_b, states_b, phi):
        ta, tb = mpf(ta), mpf(tb)
        if mpmath.isinf(ta) or mpmath.isinf(tb):
            e = [0.0 if ta == tb else math.inf]
        else:
            e = [float(abs(ta - tb)) / max(T, abs(float(tb)))]
        sa = [mpf(v) for v in sa]
        sb = [mpf(v) for v in sb]
        d = [abs(a - b) for a, b in zip(sa, sb)]
        rot = max(1.0, ph)
        if kind == "2D":
            e += [
                float(d[0]) / max(H, abs(float(sb[0]))),
                float(d[1]) / H,
                float(abs(_angle_diff(sa[2], sb[2]))) / rot,
                float(d[3]) / V,
                float(d[4]) / V,
                float(d[5]) / W,
            ]
        else:
            e += [
                float(d[0]) / max(H, abs(float(sb[0]))),
                float(d[1]) / max(H, abs(float(sb[1]))),
                float(d[2]) / H,
            ]
            e += [float(d[i]) / rot for i in range(3, 6)]
            e += [float(d[i]) / V for i in range(6, 9)]
            e += [float(d[i]) / W for i in range(9, 12)]
        out.append(max(e))
    return out


# ---------------------------------------------------------------------------
# case construction (mpmath at 60 digits, rounded to float64 at the end)
# ---------------------------------------------------------------------------
def _unit(v):
    n = mpmath.sqrt(sum(c * c for c in v))
    return [c / n for c in v]


def _cross(a, b):
    return [a[1] * b[2] - a[2] * b[1], a[2] * b[0] - a[0] * b[2], a[0] * b[1] - a[1] * b[0]]


def state3d(c, u, v, a):
    """3D float64 state with centre ``c``, orientation ``u`` (normalised),
    velocity ``v`` and angular velocity ``a`` minus its component along ``u``."""
    with mp.workdps(60):
        u = _unit([mpf(x) for x in u])
        a = [mpf(x) for x in a]
        au = sum(p * q for p, q in zip(a, u))
        w = [p - au * q for p, q in zip(a, u)]
        return [float(x) for x in list(map(mpf, c)) + u + list(map(mpf, v)) + w]


def embed_2d(state):
    """The documented embedding of a 2D state in the x-z plane (float64, sin/cos rounded)."""
    x, z, th, vx, vz, om = state
    return [x, 0.0, z, math.sin(th), 0.0, math.cos(th), vx, 0.0, vz, 0.0, om, 0.0]


def embed_2d_exact(state):
    """The same embedding in mpf (for the reference-only check)."""
    x, z, th, vx, vz, om = [mpf(v) for v in state]
    return [x, mpf(0), z, mpmath.sin(th), mpf(0), mpmath.cos(th), vx, mpf(0), vz, mpf(0), om, mpf(0)]


def graze_2d(ell, phi, omega, depth, tau, x=0.0, vx=0.0):
    """2D state whose end P1 reaches height ``depth`` above the floor at time
    ``tau`` with its height at a local minimum there (``depth > 0``: it turns
    back ``depth`` above the floor; ``< 0``: a shallow hit). At ``tau``:
    ``theta = phi`` with ``cos(phi) < 0`` (P1 below the centre), ``vz = ell
    omega sin(phi)`` (P1 momentarily horizontal), ``z = depth - ell cos(phi)``;
    then flown back by ``tau``. The height's second derivative there is
    ``-ell omega^2 cos(phi) > 0``."""
    with mp.workdps(60):
        ell, phi, omega, depth, tau = map(mpf, (ell, phi, omega, depth, tau))
        assert mpmath.cos(phi) < 0
        s = [mpf(x), depth - ell * mpmath.cos(phi), phi, mpf(vx), ell * omega * mpmath.sin(phi), omega]
        s = ref.flow("2D", s, -tau)
        return [float(v) for v in s]


def graze_3d(ell, u, a, depth, tau, c_xy=(0.0, 0.0), v_xy=(0.0, 0.0)):
    """3D analogue: at ``tau`` the orientation is ``u`` (``u_z < 0``), the
    angular velocity ``a`` made perpendicular to it, ``v_z = -ell (w x u)_z``
    so that P1 moves horizontally, and P1 is ``depth`` above the floor; then
    flown back by ``tau``."""
    with mp.workdps(60):
        ell, depth, tau = map(mpf, (ell, depth, tau))
        u = _unit([mpf(x) for x in u])
        assert u[2] < 0
        a = [mpf(x) for x in a]
        au = sum(p * q for p, q in zip(a, u))
        w = [p - au * q for p, q in zip(a, u)]
        vz = -ell * _cross(w, u)[2]
        s = [mpf(c_xy[0]), mpf(c_xy[1]), depth - ell * u[2]] + u + [mpf(v_xy[0]), mpf(v_xy[1]), vz] + w
        s = ref.flow("3D", s, -tau)
        return [float(v) for v in s]


def kink_rotating_2d(ell, omega, vz, tau, x=0.0, vx=0.0):
    """2D state that reaches the floor horizontal (``theta = pi/2``, ``z = 0``)
    at time ``tau`` while turning at ``omega``; both ends approach there if
    ``|vz| > ell |omega|``. Exact up to the rounding of ``theta_0 = pi/2 - omega tau``
    (choose dyadic ``vz``, ``tau`` so that ``z_0 = -vz tau`` is exact)."""
    assert vz < 0 and abs(vz) > ell * abs(omega)
    with mp.workdps(60):
        th0 = mp.pi / 2 - mpf(omega) * mpf(tau)
    return [x - vx * tau, -vz * tau, float(th0), vx, vz, omega]


def fast_spin_2d(ell, ratio, vz, z, theta, vx=0.0):
    """Spin ``omega = ratio |vz| / ell``: ``|omega| ell / |vz| = ratio``."""
    return [0.0, z, theta, vx, vz, ratio * abs(vz) / ell]


GENERIC_2D = [0.2, 1.4, 0.4, 0.3, 0.7, 0.9]

CASES = [
    # =============================== 2D ===============================
    dict(name="2D/generic_a", kind="2D", h=3.0, ell=1.0, mass=1.0, inertia=None, state0=GENERIC_2D),
    dict(
        name="2D/generic_b_mass2_I0.7",
        kind="2D",
        h=2.5,
        ell=1.0,
        mass=2.0,
        inertia=0.7,
        state0=[-0.3, 1.1, 2.2, -0.4, -0.6, 1.3],
    ),
    dict(
        name="2D/scaled_h0.5_l0.2_mass3",
        kind="2D",
        h=0.5,
        ell=0.2,
        mass=3.0,
        inertia=0.05,
        state0=[0.01, 0.27, -0.8, 1.5, 2.0, -9.0],
    ),
    # a horizontal stick (theta = fl(pi/2), 6e-17 from horizontal) landing flat:
    # a kink of the (theta, eta) billiard, both ends at once, every event
    dict(
        name="2D/kink_flat",
        kind="2D",
        h=3.0,
        ell=1.0,
        mass=1.0,
        inertia=None,
        state0=[0.0, 1.5, math.pi / 2, 0.1, -0.5, 0.0],
    ),
    # the stick passes horizontal exactly at the floor while turning
    dict(
        name="2D/kink_rotating",
        kind="2D",
        h=3.0,
        ell=1.0,
        mass=1.0,
        inertia=None,
        state0=kink_rotating_2d(1.0, 0.5, -0.75, 1.0, x=0.1, vx=0.2),
    ),
    # h just above / below 2 ell (below: the stick can never pass vertical)
    dict(
        name="2D/h_just_above_2ell",
        kind="2D",
        h=2.002,
        ell=1.0,
        mass=1.0,
        inertia=None,
        state0=[0.0, 1.001, 0.3, 0.1, 0.05, 0.8],
    ),
    dict(
        name="2D/h_just_below_2ell",
        kind="2D",
        h=1.998,
        ell=1.0,
        mass=1.0,
        inertia=None,
        state0=[0.0, 0.999, 1.0, 0.1, 0.3, 0.7],
    ),
    # fast spin: |omega| ell / |vz| = 1e3; the spinning end is swept into the floor
    # within half a turn, then the impulse converts most of the spin
    dict(
        name="2D/fast_spin_1e3",
        kind="2D",
        h=3.0,
        ell=1.0,
        mass=1.0,
        inertia=None,
        state0=fast_spin_2d(1.0, 1e3, -0.002, 0.97, 0.3, vx=0.01),
    ),
    # the same spin drifting 250 time units (500 rad) before the first contact
    dict(
        name="2D/fast_spin_1e3_long_drift",
        kind="2D",
        h=3.0,
        ell=1.0,
        mass=1.0,
        inertia=None,
        state0=fast_spin_2d(1.0, 1e3, 0.002, 1.5, 0.3, vx=0.01),
        ill_conditioned="the stick turns 500 rad before the first contact: the contact "
        "angle carries ~500 x the relative rounding of omega, and the "
        "orbit is chaotic after the spin is converted",
    ),
    dict(
        name="2D/fast_spin_1e3_heavy_rotor",
        kind="2D",
        h=3.0,
        ell=1.0,
        mass=1.0,
        inertia=20.0,
        state0=fast_spin_2d(1.0, 1e3, -0.002, 1.5, -1.1, vx=0.01),
    ),
    # vertical bounce without turning: period 2 (h - 2 ell) / |vz|
    dict(
        name="2D/vertical_bounce",
        kind="2D",
        h=3.0,
        ell=1.0,
        mass=1.0,
        inertia=None,
        state0=[0.25, 1.5, 0.0, 0.125, 0.5, 0.0],
    ),
    # I = inf: the stick never turns
    dict(
        name="2D/inertia_inf", kind="2D", h=3.0, ell=1.0, mass=1.0, inertia=INF, state0=[0.0, 1.5, 0.7, 0.3, 0.8, 0.0]
    ),
    # light stick, I = M ell^2 / 100
    dict(name="2D/light_I_div100", kind="2D", h=3.0, ell=1.0, mass=1.0, inertia=0.01, state0=GENERIC_2D),
    # near-grazing: P1 turns back 1e-9 above the floor (miss) / dips 1e-9 below (hit)
    dict(
        name="2D/graze_miss_1e-9",
        kind="2D",
        h=3.0,
        ell=1.0,
        mass=1.0,
        inertia=None,
        state0=graze_2d(1.0, 2.6, 0.9, 1e-9, 0.4, x=0.1, vx=0.3),
    ),
    dict(
        name="2D/graze_hit_1e-7",
        kind="2D",
        h=3.0,
        ell=1.0,
        mass=1.0,
        inertia=None,
        state0=graze_2d(1.0, 2.6, 0.9, -1e-7, 0.4, x=0.1, vx=0.3),
        ill_conditioned="a 1e-7 deep tangential hit: the contact time moves by "
        "d(depth) / sqrt(2 |g''| depth), a condition number ~3e3 at the first "
        "collision, amplified by the chaos that follows",
    ),
    # =============================== 3D ===============================
    # zero vertical angular velocity in the x-z plane: the 2D case under the documented embedding
    dict(name="3D/xz_plane_generic_a", kind="3D", h=3.0, ell=1.0, mass=1.0, inertia=None, state0=embed_2d(GENERIC_2D)),
    # L_z != 0: curved flights of the reduced billiard
    dict(
        name="3D/generic_Lz_a",
        kind="3D",
        h=3.0,
        ell=1.0,
        mass=1.0,
        inertia=None,
        state0=state3d((0.2, -0.1, 1.4), (0.6, 0.0, 0.8), (0.3, -0.2, 0.7), (0.4, 0.5, -0.3)),
    ),
    dict(
        name="3D/generic_Lz_b_mass2_I0.7",
        kind="3D",
        h=2.5,
        ell=1.0,
        mass=2.0,
        inertia=0.7,
        state0=state3d((-0.3, 0.4, 1.1), (0.3, -0.5, 0.6), (-0.4, 0.1, -0.6), (1.1, -0.2, 0.9)),
    ),
    dict(
        name="3D/spin_about_vertical_Lz",
        kind="3D",
        h=3.0,
        ell=1.0,
        mass=1.0,
        inertia=None,
        state0=state3d((0.0, 0.0, 1.5), (0.8, 0.1, 0.3), (0.05, 0.0, 0.4), (0.0, 0.0, 2.0)),
    ),
    # nearly vertical stick (polar angles break at u = zhat) and exactly vertical, turning
    dict(
        name="3D/nearly_vertical",
        kind="3D",
        h=3.0,
        ell=1.0,
        mass=1.0,
        inertia=None,
        state0=state3d((0.1, 0.2, 1.5), (1e-7, -2e-7, 1.0), (0.1, 0.2, 0.6), (0.8, 0.3, 0.0)),
    ),
    dict(
        name="3D/vertical_turning",
        kind="3D",
        h=3.0,
        ell=1.0,
        mass=1.0,
        inertia=None,
        state0=[0.1, 0.2, 1.5, 0.0, 0.0, 1.0, 0.1, 0.2, 0.6, 0.6, -0.8, 0.0],
    ),
    # exact kink: a horizontal stick spinning about the vertical lands flat (both ends at once, exactly)
    dict(
        name="3D/kink_flat_spinning",
        kind="3D",
        h=3.0,
        ell=1.0,
        mass=1.0,
        inertia=None,
        state0=[0.0, 0.0, 1.5, 1.0, 0.0, 0.0, 0.3, 0.1, -0.5, 0.0, 0.0, 0.7],
    ),
    dict(
        name="3D/h_just_above_2ell",
        kind="3D",
        h=2.002,
        ell=1.0,
        mass=1.0,
        inertia=None,
        state0=state3d((0.0, 0.0, 1.001), (0.3, 0.2, 0.9), (0.1, 0.0, 0.05), (0.5, -0.6, 0.4)),
    ),
    dict(
        name="3D/h_just_below_2ell",
        kind="3D",
        h=1.998,
        ell=1.0,
        mass=1.0,
        inertia=None,
        state0=state3d((0.0, 0.0, 0.999), (0.7, 0.4, 0.5), (0.1, 0.0, 0.3), (0.2, 0.5, 0.6)),
    ),
    # fast spin |w| ell / |vz| = 1e3 (w = (0.96, 1.6, -0.72) is perpendicular to u, |w| = 2)
    dict(
        name="3D/fast_spin_1e3",
        kind="3D",
        h=3.0,
        ell=1.0,
        mass=1.0,
        inertia=None,
        state0=state3d((0.0, 0.0, 0.9), (0.6, 0.0, 0.8), (0.01, 0.0, -0.002), (0.96, 1.6, -0.72)),
    ),
    dict(
        name="3D/fast_spin_1e3_long_drift",
        kind="3D",
        h=3.0,
        ell=1.0,
        mass=1.0,
        inertia=None,
        state0=state3d((0.0, 0.0, 1.5), (0.6, 0.0, 0.8), (0.01, 0.0, 0.002), (0.96, 1.6, -0.72)),
        ill_conditioned="the stick turns ~500 rad before the first contact: the contact "
        "orientation carries ~500 x the relative rounding of w",
    ),
    dict(
        name="3D/vertical_bounce",
        kind="3D",
        h=3.0,
        ell=1.0,
        mass=1.0,
        inertia=None,
        state0=[0.25, -0.5, 1.5, 0.0, 0.0, 1.0, 0.125, 0.25, 0.5, 0.0, 0.0, 0.0],
    ),
    dict(
        name="3D/inertia_inf",
        kind="3D",
        h=3.0,
        ell=1.0,
        mass=1.0,
        inertia=INF,
        state0=state3d((0.0, 0.0, 1.5), (0.3, 0.5, 0.7), (0.3, -0.1, 0.8), (0.0, 0.0, 0.0)),
    ),
    dict(
        name="3D/light_I_div100",
        kind="3D",
        h=3.0,
        ell=1.0,
        mass=1.0,
        inertia=0.01,
        state0=state3d((0.2, -0.1, 1.4), (0.6, 0.0, 0.8), (0.3, -0.2, 0.7), (0.4, 0.5, -0.3)),
    ),
    dict(
        name="3D/graze_miss_1e-9",
        kind="3D",
        h=3.0,
        ell=1.0,
        mass=1.0,
        inertia=None,
        state0=graze_3d(1.0, (0.4, -0.3, -0.6), (0.7, 0.5, 0.6), 1e-9, 0.4, c_xy=(0.1, 0.2), v_xy=(0.3, -0.1)),
    ),
    dict(
        name="3D/graze_hit_1e-7",
        kind="3D",
        h=3.0,
        ell=1.0,
        mass=1.0,
        inertia=None,
        state0=graze_3d(1.0, (0.4, -0.3, -0.6), (0.7, 0.5, 0.6), -1e-7, 0.4, c_xy=(0.1, 0.2), v_xy=(0.3, -0.1)),
        ill_conditioned="a 1e-7 deep tangential hit: the contact time moves by "
        "d(depth) / sqrt(2 |g''| depth), a condition number ~3e3 at the first "
        "collision, amplified by the chaos that follows",
    ),
]


# ---------------------------------------------------------------------------
def _args(case):
    return (case["kind"], case["h"], case["ell"], case["mass"], case["inertia"])


def _perturbed(state0, signs, eps=PERTURBATION):
    """Each component times ``1 + sign * eps`` (zeros stay zero)."""
    return [mpf(v) * (1 + s * mpf(eps)) for v, s in zip(state0, signs)]


def _check_simultaneity(name, info, joined_max=JOINED_MAX):
    for j, (sec, near) in enumerate(zip(info["second_gap"], info["nearest_other"])):
        if sec is not None and not sec <= joined_max:
            raise AssertionError(f"{name}: collision {j} joins a contact {sec:.3g} h away")
        if near is not None and not near >= APART_MIN:
            raise AssertionError(f"{name}: collision {j} leaves an approaching gap {near:.3g} h away")


def compute_case(case, n=N_COLLISIONS, dps=DPS):
    args = _args(case)
    kind = case["kind"]
    sc = scales(*args, case["state0"])
    t0 = time.perf_counter()
    with mp.workdps(dps):
        info = {}
        times, contacts, states = ref.reference_orbit(*args, case["state0"], n, dps=dps, info=info)
        _check_simultaneity(case["name"], info)
        cpu_ref = time.perf_counter() - t0
        phi = turned(kind, case["state0"], times, states)
        horizon = n
        for signs in SIGNS[kind]:
            pinfo = {}
            pt, pk, ps = ref.reference_orbit(*args, _perturbed(case["state0"], signs), n, dps=dps, info=pinfo)
            # a perturbed kink_flat joins its second end ~1e-15 h away (theta moved by
            # 1e-15 relative), still far inside SIMULTANEOUS_TOL; nothing may be near 1e-12
            _check_simultaneity(case["name"] + " (perturbed)", pinfo, joined_max=float(ref.SIMULTANEOUS_TOL) / 5)
            errs = collision_errors(kind, pt, ps, times, states, sc, phi)
            for j in range(n):
                if not errs[j] <= HORIZON_TOL or pk[j] != contacts[j]:
                    horizon = min(horizon, j)
                    break

        def to_s(v):
            return "inf" if mpmath.isinf(v) else mpmath.nstr(v, STORE_DIGITS, strip_zeros=False)

        inertia = case["inertia"]
        return dict(
            name=case["name"],
            kind=kind,
            h=case["h"],
            ell=case["ell"],
            mass=case["mass"],
            inertia=None if inertia is None else ("inf" if math.isinf(inertia) else inertia),
            state0=list(case["state0"]),
            n=n,
            horizon=horizon,
            times=[to_s(t) for t in times],
            contacts=list(contacts),
            states=[[to_s(v) for v in s] for s in states],
            impulses=list(info["impulses"]),
            ill_conditioned=case.get("ill_conditioned"),
            seconds_reference=round(cpu_ref, 3),
            seconds_total=round(time.perf_counter() - t0, 3),
        )


def _strip(r):
    return {k: v for k, v in r.items() if not k.startswith("seconds")}


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--check", action="store_true", help="recompute and compare with the stored file")
    ap.add_argument("--only", nargs="*", help="case names")
    args = ap.parse_args(argv)
    cases = [c for c in CASES if not args.only or c["name"] in args.only]
    t_all = time.perf_counter()
    results = []
    for case in cases:
        r = compute_case(case)
        print(
            f"{r['name']:34s} horizon={r['horizon']:3d} t={r['seconds_total']:7.2f}s contacts={r['contacts'][:14]}",
            flush=True,
        )
        results.append(r)
    print(f"total {time.perf_counter() - t_all:.1f}s")
    if args.check:
        with open(DATA_PATH) as f:
            stored = {c["name"]: c for c in json.load(f)["cases"]}
        bad = [r["name"] for r in results if r["name"] not in stored or _strip(r) != _strip(stored[r["name"]])]
        print("mismatching cases:", bad)
        return 1 if bad else 0
    if args.only:
        print("(--only: file not written)")
        return 0
    for r in results:
        if r["ill_conditioned"]:
            assert r["horizon"] >= 1, r["name"]
        else:
            assert r["horizon"] >= MIN_HORIZON, (r["name"], r["horizon"])
    os.makedirs(os.path.dirname(DATA_PATH), exist_ok=True)
    meta = dict(
        generator="tests/make_walls_reference_data.py",
        reference="tests/mpmath_walls_reference.py",
        dps=DPS,
        n=N_COLLISIONS,
        perturbation=PERTURBATION,
        horizon_tol=HORIZON_TOL,
        agreement_tol=AGREEMENT_TOL,
        min_horizon=MIN_HORIZON,
        simultaneous_tol=float(ref.SIMULTANEOUS_TOL),
        digits_stored=STORE_DIGITS,
        mpmath=mpmath.__version__,
    )
    with open(DATA_PATH, "w") as f:
        json.dump(dict(meta=meta, cases=results), f, indent=1)
        f.write("\n")
    print("wrote", DATA_PATH)
    return 0


if __name__ == "__main__":
    sys.exit(main())
