"""Stiff and extreme cases, one named test each.

Every case runs the public collision map (``jb.collide`` for the checked
flights, ``jb.orbit`` or a ``lax.fori_loop`` over ``jb.collide`` for long
runs) and asserts, with the bounds stated here once:

* **finite**: no NaN or inf in any state or flight time, and a contact at every
  collision (a stick that moves always reaches the wall of a closed billiard).
* **no missed collision, no end outside the wall** (``min_flight_gap``): along
  every checked flight both gaps ``g_k(t) = R^2 - |P_k(t)|^2`` of the closed-form
  free flight (centre linear in ``t``, angle linear in ``t``), evaluated in
  80-bit long double from jaxbill's own float64 state, stay ``>= -tol_gap`` for
  all ``t`` in ``[0, dt]``. Certified, not just sampled: no end can touch while
  the centre is within ``R - ell`` of the origin, so only the rest of the flight
  is sampled (at least 2000 points and 64 per turn); between two samples
  ``h`` apart ``g_k >= min(ends) - C h^2 / 8`` with ``|g_k''| <= C = 2|v|^2 +
  2 ell (2 |omega| |v| + omega^2 max|c|)``, and every interval where that bound
  could reach ``-tol_gap`` is subdivided (32 parts, up to 6 times).
  ``tol_gap = 1e-12 R^2`` (the library's own "outside the wall" threshold) plus
  the rounding that the float64 flight itself must carry: the phase
  ``alpha + omega t`` (``8 eps (pi + |omega dt|)`` rad, moving an end by ``ell``
  times that, so the gap by ``2 R ell`` times it) and the centre
  (``4 eps (R + |v| dt)``, times ``2 R``).
* **real collisions**: at every returned contact the touching end is on the
  wall (``|g_k| <= tol_gap``) and was approaching it before the kick.
* **mpmath** (``tests/mpmath_reference.py``, 40 digits, independent): the first
  collisions, each restarted in the reference from jaxbill's own float64 state
  (so chaos does not enter), agree in contact and, in the scaled metric of
  ``make_reference_data.collision_errors``, to
  ``1e-10 + 10 eps (|omega dt| + R / ell) + 100 eps R^2 / (|g'| T)``: the
  agreement of ``tests/test_reference.py`` plus the float64 conditioning of the
  exact problem: the phase (as there), the stick's angle at the contact (a gap
  known to ``eps R^2`` fixes it to ``eps R^2 / (2 R ell)``), and the contact time
  (to ``eps R^2 / |g'|``, ``g'`` the exact gap's slope at the root: large for a
  grazing contact).
* **invariants**: energy ``E`` (and for a finite inertia ``L = M (x vy - y vx) +
  I omega``) change by at most ``1e-13`` (relative to ``E``, resp. to
  ``R sqrt(2 M E) + max |I omega|``, the largest ``|L|`` the orbit can reach)
  at any collision, and drift by at most half an ulp per collision over the run.
  The 1e7-collision test holds the energy to a random walk of rounding errors,
  ``10 eps sqrt(n)`` (the README: no systematic drift).

Cost and accuracy reached per case are reported in the README table, not
asserted here (no timed assertions).
"""

from __future__ import annotations

import json
import math
import os
import subprocess
import sys
import textwrap
from functools import partial

import jax
import jax.numpy as jnp
import numpy as np
import pytest
from mpmath import mp, mpf

import jaxbill as jb

_HERE = os.path.dirname(os.path.abspath(__file__))
if _HERE not in sys.path:
    sys.path.insert(0, _HERE)

import make_reference_data as gen  # noqa: E402
import mpmath_reference as ref  # noqa: E402

LD = np.longdouble
EPS = 2.0**-52
INF = float("inf")
R = 2.0
N_RUN = 20_000  # every long orbit in this file has this length (one compile per scene kind)
N_CHECKED = 30  # flights checked densely, collision by collision
N_REF = 4  # collisions compared with the mpmath reference
PER_COLLISION = 1e-13
WALL_TOL = 1e-12  # the library's "outside the wall" threshold, in units of R^2


# ---------------------------------------------------------------------------
# independent checks (numpy long double, mpmath)
# ---------------------------------------------------------------------------
def _gap(R, ell, s, t, end):
    """``R^2 - |P_end(t)|^2`` of the free flight from ``s``, in long double."""
    t = np.asarray(t, dtype=LD)
    x, y, a, vx, vy, w = (LD(float(v)) for v in s)
    phi = a + w * t
    px = x + vx * t + LD(end) * LD(ell) * np.cos(phi)
    py = y + vy * t + LD(end) * LD(ell) * np.sin(phi)
    return LD(R) * LD(R) - (px * px + py * py)


def _windows(R, ell, s, dt):
    """Parts of ``[0, dt]`` with ``|c(t)| >= R - ell`` (elsewhere no end can touch)."""
    x, y, _, vx, vy, _ = (LD(float(v)) for v in s)
    r = LD(R) - LD(ell)
    a = vx * vx + vy * vy
    b = x * vx + y * vy
    cc = x * x + y * y - r * r
    disc = b * b - a * cc
    if a == 0 or disc <= 0:
        return [(0.0, dt)]
    root = np.sqrt(disc)
    t_in, t_out = float((-b - root) / a), float((-b + root) / a)
    pad = 1e-9 * (t_out - t_in)  # shrink the quiet interval: rounding cannot hide its edges
    t_in, t_out = t_in + pad, t_out - pad
    if t_out <= 0.0 or t_in >= dt or t_in >= t_out:
        return [(0.0, dt)]
    out = [(0.0, t_in)] if t_in > 0.0 else []
    if t_out < dt:
        out.append((t_out, dt))
    return out


def gap_tolerance(R, ell, s, dt):
    """``tol_gap`` of the module docstring for the flight of length ``dt`` from ``s``."""
    phase = 8 * EPS * (math.pi + abs(float(s[5]) * dt))
    centre = 4 * EPS * (R + math.hypot(float(s[3]), float(s[4])) * dt)
    return WALL_TOL * R * R + 2 * R * (ell * phase + centre)


def min_flight_gap(R, ell, s, dt, tol, levels=6, sub=32, cap=20_000):
    """Certified lower bound on ``min_k min_{0 <= t <= dt} g_k(t)`` where it is below
    ``-tol`` (module docstring); elsewhere a value ``>= -tol``."""
    x, y, _, vx, vy, w = (float(v) for v in s)
    speed = math.hypot(vx, vy)
    worst = math.inf
    for ta, tb in _windows(R, ell, s, dt):
        if tb <= ta:
            continue
        turns = abs(w) * (tb - ta) / (2 * math.pi)
        m = int(min(max(2000, 64 * turns), 400_000)) + 1
        cmax = max(math.hypot(x + vx * ta, y + vy * ta), math.hypot(x + vx * tb, y + vy * tb))
        C = LD(2 * speed**2 + 2 * ell * (2 * abs(w) * speed + w * w * cmax))
        for end in (1, -1):
            lo = np.linspace(ta, tb, m, dtype=LD)[:-1]
            h = LD(tb - ta) / LD(m - 1)
            for level in range(levels + 1):
                ga, gb = _gap(R, ell, s, lo, end), _gap(R, ell, s, lo + h, end)
                worst = min(worst, float(np.min(ga)), float(np.min(gb)))
                bound = np.minimum(ga, gb) - C * h * h / 8
                bad = np.nonzero(bound < -tol)[0]
                if bad.size == 0:
                    break
                if level == levels or bad.size > cap:
                    worst = min(worst, float(np.min(bound[bad])))
                    break
                lo = (lo[bad][:, None] + (h / sub) * np.arange(sub, dtype=LD)[None, :]).ravel()
                h = h / sub
    return worst


def _approach_speed(ell, s, end):
    """Normal velocity ``v . n + omega s_k`` of end ``end`` (positive: towards the wall)."""
    x, y, a, vx, vy, w = (float(v) for v in s)
    ux, uy = math.cos(a), math.sin(a)
    px, py = x + end * ell * ux, y + end * ell * uy
    return (px * (vx - end * ell * w * uy) + py * (vy + end * ell * w * ux)) / math.hypot(px, py)


def _params(scene):
    return float(scene.R), float(scene.ell), float(scene.mass), float(scene.inertia)


def _ref_inertia(scene):
    return INF if scene.kind == "lens" else float(scene.inertia)


def invariant_scales(scene, state0, states):
    """``E0`` and the ``L`` scale ``R sqrt(2 M E) + max |I omega|`` (module docstring)."""
    R_, _, M, I = _params(scene)
    E0 = float(jb.energy(scene, jnp.asarray(state0)))
    spin = 0.0
    if scene.kind == "rotor":
        spin = max(abs(I * float(state0[5])), float(np.max(np.abs(I * np.asarray(states)[..., 5]))))
    return E0, R_ * math.sqrt(2 * M * E0) + spin


# ---------------------------------------------------------------------------
# the three kinds of check
# ---------------------------------------------------------------------------
def check_flights(scene, state0, n=N_CHECKED):
    """``n`` collisions by ``jb.collide``, each flight checked (module docstring).

    Returns ``(states, dts, contacts, worst)``; ``worst`` is the smallest
    ``min gap / tol_gap`` seen (the accuracy reached, for the README table).
    """
    R_, ell, _, _ = _params(scene)
    s = np.asarray(state0, dtype=np.float64)
    states, dts, contacts = [], [], []
    worst = math.inf
    for j in range(n):
        new, dt, k = jb.collide(scene, jnp.asarray(s))
        new, dt, k = np.asarray(new), float(dt), int(k)
        assert np.all(np.isfinite(new)) and math.isfinite(dt), f"collision {j}: state {new}, dt {dt}"
        assert k in (1, -1, 2), f"collision {j}: contact {k} (dt {dt}) from {s.tolist()}"
        assert dt >= 0.0
        tol = gap_tolerance(R_, ell, s, dt)
        g = min_flight_gap(R_, ell, s, dt, tol) if ell > 0 else min_flight_gap(R_, 0.0, s, dt, tol)
        worst = min(worst, g / tol)
        assert g >= -tol, (
            f"collision {j}: an end is {-g:.3g} (> tol {tol:.3g}) outside the wall during the flight "
            f"of {dt!r} from {s.tolist()}: a collision was missed"
        )
        for end in (1, -1) if k == 2 else (k,):
            g_end = float(_gap(R_, ell, new, 0.0, end))
            assert abs(g_end) <= tol, f"collision {j}: end {end} is not on the wall (gap {g_end:.3g})"
            if k != 2 and dt > 0.0:
                before = np.concatenate([new[:3], s[3:]])
                assert _approach_speed(ell, before, end) > 0.0, f"collision {j}: end {end} was not approaching"
        states.append(new), dts.append(dt), contacts.append(k)
        s = new
    states = np.array(states)
    E0, L_scale = invariant_scales(scene, state0, states)
    E = np.concatenate([[E0], np.asarray(jb.energy(scene, jnp.asarray(states)))])
    step = float(np.max(np.abs(np.diff(E)))) / E0
    assert step <= PER_COLLISION, f"energy changed by {step:.3g} (relative) in one collision"
    if scene.kind == "rotor":
        L = np.concatenate(
            [
                [float(jb.angular_momentum(scene, jnp.asarray(state0)))],
                np.asarray(jb.angular_momentum(scene, jnp.asarray(states))),
            ]
        )
        step = float(np.max(np.abs(np.diff(L)))) / L_scale
        assert step <= PER_COLLISION, f"L changed by {step:.3g} (of its scale) in one collision"
    return states, np.array(dts), np.array(contacts), worst


def reference_tolerance(R_, ell, prev, dt_ref, slope, T):
    """The mpmath agreement bound of the module docstring."""
    angle = abs(float(prev[5]) * dt_ref) + (R_ / ell if ell > 0 else 0.0)
    return 1e-10 + 10 * EPS * angle + 100 * EPS * R_ * R_ / (abs(slope) * T)


def _bounced_ends(contact) -> tuple:
    return (1, -1) if contact == 2 else (int(contact),)


def check_against_reference(scene, state0, states, dts, contacts, m=N_REF, t_max=1e10, bounced=()):
    """The first ``m`` collisions, each restarted in the mpmath reference from
    jaxbill's own previous state. ``bounced``: the ends on the wall at ``state0``
    (just after a collision). Returns the worst error / tolerance."""
    R_, ell, M, _ = _params(scene)
    inertia = _ref_inertia(scene)
    sc = gen.scales(R_, ell, M, inertia, [float(v) for v in state0])
    T = sc[0]
    prev, worst = [float(v) for v in state0], 0.0
    for j in range(m):
        with mp.workdps(40):
            rt, rs, rk = ref.reference_orbit(R_, ell, M, inertia, prev, 1, dps=40, bounced=bounced, t_max=t_max)
            end = 1 if rk[0] == 2 else rk[0]
            _, slope = ref.gap(mpf(R_), mpf(ell), [mpf(v) for v in prev], end, rt[0])
            e_t = float(abs(mpf(dts[j]) - rt[0])) / max(T, float(rt[0]))
            e_s = gen.collision_errors([0.0], [list(states[j])], [0.0], rs, sc)[0]
        tol = reference_tolerance(R_, ell, prev, float(rt[0]), float(slope), T)
        assert int(contacts[j]) == rk[0], f"collision {j}: contact {contacts[j]}, reference {rk[0]}"
        assert e_t <= tol and e_s <= tol, (
            f"collision {j}: dt error {e_t:.3g}, state error {e_s:.3g} > {tol:.3g} (reference)"
        )
        worst = max(worst, e_t / tol, e_s / tol)
        prev = [float(v) for v in states[j]]
        bounced = _bounced_ends(contacts[j])
    return worst


def check_long_run(scene, state0, n=N_RUN):
    """``n`` collisions by ``jb.orbit``: finite, inside, invariants within the bounds.
    Returns ``(energy drift, L drift)``."""
    R_ = float(scene.R)
    orb = jb.orbit(scene, jnp.asarray(state0), n)
    S, t, k = np.asarray(orb.state), np.asarray(orb.t), np.asarray(orb.contact)
    assert np.all(np.isfinite(S)) and np.all(np.isfinite(t)), "the orbit left the finite numbers"
    assert np.all(k != 0), "a collision without contact"
    assert np.all(np.diff(t) >= 0.0)
    gaps = np.asarray(scene.gaps(jnp.asarray(S)))
    assert np.min(gaps) >= -WALL_TOL * R_**2, f"an end is outside the wall by {-np.min(gaps):.3g}"
    E0, L_scale = invariant_scales(scene, state0, S)
    E = np.asarray(jb.energy(scene, jnp.asarray(S)))
    drift_E = float(np.max(np.abs(E - E0))) / E0
    assert drift_E <= 0.5 * EPS * n, f"energy drifted by {drift_E:.3g} over {n} collisions"
    drift_L = 0.0
    if scene.kind == "rotor":
        L = np.asarray(jb.angular_momentum(scene, jnp.asarray(S)))
        drift_L = float(np.max(np.abs(L - float(jb.angular_momentum(scene, jnp.asarray(state0)))))) / L_scale
        assert drift_L <= 0.5 * EPS * n, f"L drifted by {drift_L:.3g} (of its scale) over {n} collisions"
    return drift_E, drift_L


def full_check(scene, state0, n_checked=N_CHECKED, n_ref=N_REF, n_run=N_RUN, t_max=1e10):
    states, dts, contacts, worst_gap = check_flights(scene, state0, n_checked)
    worst_ref = check_against_reference(scene, state0, states, dts, contacts, n_ref, t_max) if n_ref else 0.0
    drift = check_long_run(scene, state0, n_run) if n_run else (0.0, 0.0)
    return states, dts, contacts, worst_gap, worst_ref, drift


# ---------------------------------------------------------------------------
# grazing and near-double roots
# ---------------------------------------------------------------------------
def grazing_state(R_, ell, w, vy, depth, tau):
    """End P1 reaches its largest ``|P1| = R (1 + depth)`` after a flight of ``tau``.

    At that instant ``alpha = 0``, ``c = (R' - ell, 0)``, ``v = (0, vy)``: P1 =
    ``(R', 0)`` moves along ``y`` at ``vy + ell w`` and ``d^2 |P1|^2/dt^2 =
    2 ((vy + ell w)^2 - ell w^2 R')``, negative (a maximum) for the values used.
    The state is that instant flown back by ``tau``.
    """
    Rp = R_ * (1.0 + depth)
    assert (vy + ell * w) ** 2 < ell * w * w * Rp
    return np.array([Rp - ell, -vy * tau, -w * tau, 0.0, vy, w])


GRAZE = dict(ell=1.0, w=1.0, vy=0.2, tau=0.5)


def check_either_side_of_a_zero_impulse_graze(scene, state0, states, dts, contacts):
    """Collision 0 is the reference's graze (a hit) or the reference's next collision (the graze
    passed as a miss), and the two collisions after it agree with the reference."""
    R_, ell, M, _ = _params(scene)
    inertia = _ref_inertia(scene)
    sc = gen.scales(R_, ell, M, inertia, [float(v) for v in state0])
    with mp.workdps(40):
        rt, rs, rk = ref.reference_orbit(R_, ell, M, inertia, [float(v) for v in state0], 2, dps=40)
        # The graze's impulse is zero to well below a float64 ulp of the speeds
        # (the reference's root is resolved to 40 digits, not exactly).
        speed_change = float(max(abs(rs[0][k] - mpf(float(state0[k]))) for k in (3, 4, 5)))
        assert speed_change < 1e-3 * EPS * sc[2], f"the reference's graze changed a velocity by {speed_change}"
        hit = int(contacts[0]) == rk[0]
        j = 0 if hit else 1
        assert int(contacts[0]) == rk[j], f"collision 0: contact {contacts[0]}, reference {rk[0]} then {rk[1]}"
        _, slope = ref.gap(mpf(R_), mpf(ell), [mpf(float(v)) for v in state0], abs(rk[j]), rt[j])
        e_t = float(abs(mpf(dts[0]) - rt[j])) / max(sc[0], float(rt[j]))
        e_s = gen.collision_errors([0.0], [list(states[0])], [0.0], [rs[j]], sc)[0]
    tol = reference_tolerance(R_, ell, state0, float(rt[j]), float(slope), sc[0])
    assert e_t <= tol and e_s <= tol, f"collision 0: dt error {e_t:.3g}, state error {e_s:.3g} > {tol:.3g}"
    # After a hit, the grazing end leaves the wall with zero normal speed (the
    # reference takes it as a start, not a bounce); after a miss, collision 0 was
    # an ordinary bounce.
    bounced = () if hit else _bounced_ends(contacts[0])
    check_against_reference(scene, states[0], states[1:], dts[1:], contacts[1:], m=2, bounced=bounced)


@pytest.mark.parametrize("depth", [1e-13, 1e-15, 0.0, -1e-15, -1e-13])
def test_grazing_near_double_root(depth):
    """P1 reaches ``R (1 + depth)`` tangentially: a near double root of its gap.

    ``depth = 1e-13`` pokes ``2e-13 R^2`` (about 900 ulps of ``R^2``) through the
    wall: the hit must be found, before the extremum, at the reference root to
    ``100 eps R^2 / |g'|``. ``-1e-13`` passes as far inside: no hit within the
    graze. ``|depth| <= 1e-15`` is below what a float64 gap resolves: either
    outcome is right, but nothing may go through the wall or become NaN, and
    the grazing departure that follows must be resolved within the step bound.
    ``depth = 0`` is an exact double root of the float64 state (P1 = (R, 0),
    moving along y, at t = tau exactly): the graze's impulse is zero, so a hit
    and a miss lead to the same next state, and whichever the search takes is
    checked against the reference (its graze, or the collision after it).
    """
    ell, w, vy, tau = GRAZE["ell"], GRAZE["w"], GRAZE["vy"], GRAZE["tau"]
    scene = jb.StickInCircle(R=R, ell=ell)
    s0 = grazing_state(R, ell, w, vy, depth, tau)
    exact_double_root = depth == 0.0
    states, dts, contacts, _, _, _ = full_check(scene, s0, n_ref=0 if exact_double_root else 3)
    if exact_double_root:
        check_either_side_of_a_zero_impulse_graze(scene, s0, states, dts, contacts)
    if depth >= 1e-13:
        assert contacts[0] == 1 and dts[0] < tau, f"grazing hit missed: dt {dts[0]!r}, contact {contacts[0]}"
        with mp.workdps(40):
            t_ref = ref.reference_orbit(R, ell, 1.0, None, list(s0), 1, dps=40)[0][0]
            _, slope = ref.gap(mpf(R), mpf(ell), [mpf(float(v)) for v in s0], 1, t_ref)
        assert abs(dts[0] - float(t_ref)) <= 100 * EPS * R * R / abs(float(slope))
    if depth <= -1e-13:
        assert dts[0] > tau + 0.05 / w, f"false hit at a near miss: dt {dts[0]!r}, graze at {tau}"


@pytest.mark.parametrize("delta", [1e-5, 1e-8])
def test_lens_whispering_gallery(delta):
    """Static lens, the centre sliding along one arc at ``delta`` rad from the
    tangent: each chord of a circle of radius ``R`` subtends ``2 delta``, so its
    flight time is ``2 R sin(delta) / |v|`` (closed form) until the arc ends at a
    corner. The near double root of the lens's quadratic, resolved to the
    conditioning ``eps / delta^2`` of a chord whose sagitta is ``R delta^2``;
    at ``delta = 1e-8`` the sagitta is below the gap's rounding, so only
    finiteness, progress along the arc and the wall are asserted.

    Flights are straight lines, so ``|P_k|^2`` is convex along each: the gaps at
    the collision states bound every flight (no dense sampling needed).
    """
    ell = 1.5
    scene = jb.StickInCircle(R=R, ell=ell, inertia=INF)
    # arc of P1's wall: centre on the circle of radius R about -ell u (u = x axis),
    # start near one end of the arc (polar angle -0.7 about that point), moving
    # anticlockwise along it, turned inwards by delta
    theta = -0.7
    cx, cy = -ell + R * math.cos(theta), R * math.sin(theta)
    heading = theta + math.pi / 2 + delta
    s0 = np.array([cx, cy, 0.0, math.cos(heading), math.sin(heading), 0.0])
    assert abs(float(scene.gaps(jnp.asarray(s0))[0])) <= 4 * EPS * R * R
    n = 2000
    orb = jb.orbit(scene, jnp.asarray(s0), n)
    S, t, k = np.asarray(orb.state), np.asarray(orb.t), np.asarray(orb.contact)
    assert np.all(np.isfinite(S)) and np.all(np.isfinite(t)) and np.all(k != 0)
    gaps = np.asarray(scene.gaps(jnp.asarray(S)))
    assert np.min(gaps) >= -WALL_TOL * R * R
    E = np.asarray(jb.energy(scene, jnp.asarray(S)))
    assert np.max(np.abs(E - 0.5)) / 0.5 <= 0.5 * EPS * n
    dt = np.diff(np.concatenate([[0.0], t]))
    assert np.all(dt > 0.0), "a zero-length chord: the orbit stalls on the wall"
    # while on the arc (polar angle about -ell u below the arc's end at
    # +arccos(ell / R)), every hit is by P1 and the polar angle advances
    phi = np.arctan2(S[:, 1], S[:, 0] + ell)
    on_arc = phi < math.acos(ell / R) - 4 * delta
    m = int(np.argmin(on_arc)) if not np.all(on_arc) else n
    assert m >= min(n, 100)
    assert np.all(k[:m] == 1)
    assert np.all(np.diff(phi[:m]) > 0.0), "the centre went backwards along the arc"
    exact = 2 * R * math.sin(delta)  # |v| = 1
    if delta >= 1e-5:
        cond = EPS / delta**2  # a gap rounded to eps R^2 against the sagitta R delta^2
        err = np.max(np.abs(dt[1:m] / exact - 1.0))
        assert err <= 100 * cond, f"chord times off by {err:.3g} relative (conditioning {cond:.3g})"
        assert abs(phi[m - 1] - phi[0] - 2 * delta * (m - 1)) <= 100 * cond * 2 * delta * m


# ---------------------------------------------------------------------------
# both ends within 1e-9 of each other: lens corners
# ---------------------------------------------------------------------------
# R = 5, ell = 3, alpha = 0: a stick centred at (0, 4) has both ends exactly on
# the wall. From (-1 + d, 0) with velocity (0.25, 1) the centre passes (d, 4)
# at t = 4, where P1 = (3 + d, 4) reaches the wall first; P2 follows after the
# P1 kick has changed the velocity: (per the reference) 8.56 d later in the lens,
# 0.95 d later for the spinning stick (I = M ell^2). The offsets below put the
# two hits 1e-9 and 1e-12 apart (2e-10 and 2e-13 of the time scale R / |v|),
# and ~1e-16 apart, within the library's corner threshold (64 ulps of the gap).
CORNER_SCENES = {"lens": INF, "rotor": None}
CORNER_RATE = {"lens": 8.56, "rotor": 0.95}  # separation / d, from the reference
CORNER_SEPARATIONS = {"1e-9": 1e-9, "1e-12": 1e-12, "1e-16": None}


@pytest.mark.parametrize("offset", list(CORNER_SEPARATIONS))
@pytest.mark.parametrize("kind", list(CORNER_SCENES))
def test_both_ends_hit_within_1e9(kind, offset):
    """Both ends reach the wall within ``Delta t`` of each other, in the static
    lens (its corner) and in the spinning stick's map (the corner of its
    rotating lens). Separated hits must come out as two collisions in the
    reference's order, ``Delta t`` apart; hits within the corner threshold as
    one event (contact 2) or two at the same instant; either way the states
    match the reference collision by collision."""
    R_, ell = 5.0, 3.0
    scene = jb.StickInCircle(R=R_, ell=ell, inertia=CORNER_SCENES[kind])
    target = CORNER_SEPARATIONS[offset]
    d = 1e-16 if target is None else target / CORNER_RATE[kind]
    s0 = np.array([-1.0 + d, 0.0, 0.0, 0.25, 1.0, 0.0])
    states, dts, contacts, _, _, _ = full_check(scene, s0, n_checked=12, n_ref=0)
    # the reference: full orbit from s0 (the separation is far above rounding for
    # 1e-9 and 1e-12; at 1e-16 the reference resolves two hits 1e-16 apart)
    with mp.workdps(40):
        rt, rs, rk = ref.reference_orbit(R_, ell, 1.0, CORNER_SCENES[kind], list(s0), 6, dps=40)
    assert rk[0] == 1 and abs(float(rt[0]) - 4.0) < 1e-8
    t_abs = np.cumsum(dts)
    if offset != "1e-16":
        assert contacts[0] == 1 and contacts[1] == -1, contacts[:3]
        assert rk[1] == -1
        sep_ref = float(rt[1] - rt[0])
        assert 0.5 * target < sep_ref < 2 * target  # the construction
        assert abs(dts[1] - sep_ref) <= 1e-10 * sep_ref + 100 * EPS * 4.0, (dts[1], sep_ref)
        jt, js, jk = list(t_abs), list(states), list(contacts)
        rt_, rs_, rk_ = rt, rs, rk
    else:
        # merge events at one instant (|dt| <= 1e-12 T) on both sides
        T = gen.scales(R_, ell, 1.0, CORNER_SCENES[kind], list(s0))[0]

        def merge(ts, ss, ks):
            out_t, out_s, out_k = [], [], []
            for tj, sj, kj in zip(ts, ss, ks):
                if out_t and abs(float(tj) - float(out_t[-1])) <= 1e-12 * T:
                    out_s[-1], out_k[-1] = sj, 2
                else:
                    out_t.append(tj), out_s.append(sj), out_k.append(int(kj))
            return out_t, out_s, out_k

        jt, js, jk = merge(t_abs, states, contacts)
        rt_, rs_, rk_ = merge(rt, rs, rk)
        assert jk[0] == 2 and rk_[0] == 2, (jk[:3], rk_[:3])
    m = 4
    sc = gen.scales(R_, ell, 1.0, CORNER_SCENES[kind], list(s0))
    assert jk[:m] == list(rk_[:m]), (jk[:m], rk_[:m])
    with mp.workdps(30):
        errs = gen.collision_errors(jt[:m], [list(s) for s in js[:m]], rt_[:m], rs_[:m], sc)
    assert max(errs) <= 1e-10, f"corner orbit differs from the reference: {errs}"


# ---------------------------------------------------------------------------
# extreme lengths and inertias
# ---------------------------------------------------------------------------
@pytest.mark.parametrize("inertia", [None, 1.0], ids=["I=M*ell^2=1e-16", "I=1"])
def test_tiny_stick_ell_1e8(inertia):
    """``ell = 1e-8`` (``5e-9 R``): nearly the circle billiard, but a stick. With the
    default ``I = M ell^2 = 1e-16`` the first impulse spins it to ``omega ~ 1e8``
    (the angle then carries ``eps |omega dt|``, and the contact angle
    ``eps R / ell``: both in the stated bounds)."""
    scene = jb.StickInCircle(R=R, ell=1e-8, inertia=inertia)
    s0 = np.array([0.3, -0.2, 0.5, 0.6, 0.45, 0.5])
    _, _, contacts, _, _, _ = full_check(scene, s0)
    assert set(np.unique(contacts)) <= {1, -1}


def test_stick_nearly_a_diameter():
    """``ell = R (1 - 1e-9)``: the centre lives in a lens ``2e-9 R`` wide along
    the stick and ``4.5e-5 R`` across; flights are ``1e-9 .. 1e-5`` time units."""
    ell = R * (1 - 1e-9)
    scene = jb.StickInCircle(R=R, ell=ell)
    alpha = 0.4
    a, b = 5e-10, 1e-5  # centre along and across the stick, inside (R - ell = 2e-9, ...)
    s0 = np.array(
        [a * math.cos(alpha) - b * math.sin(alpha), a * math.sin(alpha) + b * math.cos(alpha), alpha, 0.6, 0.25, 0.3]
    )
    full_check(scene, s0)


@pytest.mark.parametrize("ell", [1.0, 1.9])
def test_very_light_stick(ell):
    """``inertia = M ell^2 1e-6``: each impulse kicks ``omega`` by up to
    ``1e3 |v| / ell``; energy moves between spin and translation at every bounce."""
    scene = jb.StickInCircle(R=R, ell=ell, inertia=ell * ell * 1e-6)
    s0 = np.array([0.1, -0.2, 0.3, 0.7, 0.4, 0.5]) if ell == 1.0 else np.array([0.03, -0.02, 0.4, 0.6, 0.25, 0.3])
    states, _, _, _, _, _ = full_check(scene, s0)
    assert np.max(np.abs(states[:, 5])) * ell > 10 * 0.8, "the light stick was never spun up: not the extreme case"


def test_infinite_inertia_and_its_limit():
    """``inertia = inf`` (the static lens, closed form) and ``inertia = 1e300``
    (the spinning-stick code at the edge of float64): the latter must follow
    the former, its spin stays ``~1e-300``, and ``L = M c x v + I omega``
    (whose spin part ``I omega`` is O(1)) stays conserved."""
    s0 = np.array([0.1, 0.05, 0.3, 0.7, -0.4, 0.0])
    lens = jb.StickInCircle(R=R, ell=1.5, inertia=INF)
    heavy = jb.StickInCircle(R=R, ell=1.5, inertia=1e300)
    assert heavy.kind == "rotor"
    ls, ldt, lk, _, _, _ = full_check(lens, s0)
    hs, hdt, hk, _, _, _ = full_check(heavy, s0, n_ref=0)
    # the same orbit (the lens's chaos horizon for this start is 50 collisions)
    m = 20
    assert np.array_equal(lk[:m], hk[:m])
    assert np.max(np.abs(ldt[:m] - hdt[:m])) <= 1e-12
    assert np.max(np.abs(ls[:m, [0, 1, 3, 4]] - hs[:m, [0, 1, 3, 4]])) <= 1e-12
    assert np.max(np.abs(hs[:, 5])) <= 1e-298


@pytest.mark.parametrize("inertia", [None, 100.0], ids=["I=M*ell^2", "I=100"])
def test_spin_1e6(inertia):
    """``|omega| ell / |v| = 1e6``: the stick turns ``~1e5`` times while the centre
    crosses the circle; the search skips the time the centre spends within
    ``R - ell`` of the origin and resolves about one turn."""
    v = 0.5
    s0 = np.array([0.2, -0.1, 0.3, v * math.cos(0.3), v * math.sin(0.3), 1e6 * v / 1.0])
    scene = jb.StickInCircle(R=R, ell=1.0, inertia=inertia)
    full_check(scene, s0, n_ref=2)


@pytest.mark.parametrize("start", ["near the wall", "drifting"])
def test_slow_translation_unit_spin(start):
    """``|v| = 1e-8``, ``omega = 1``. "near the wall": the spinning stick hits
    within a quarter turn. "drifting": the centre creeps ``~1`` unit to radius
    ``R - ell`` (``~8e7`` time units, skipped in one step) and the swept end then
    grazes the wall (depth ``~1e-8``); the angle then carries ``eps * 8e7``."""
    if start == "near the wall":
        scene = jb.StickInCircle(R=R, ell=1.5)
        s0 = np.array([0.9, 0.0, math.pi / 2, 1e-8, 0.0, 1.0])
    else:
        scene = jb.StickInCircle(R=R, ell=1.0)
        s0 = np.array([0.1, 0.2, 0.0, 0.6e-8, 0.8e-8, 1.0])
    states, dts, contacts, _, _, _ = full_check(scene, s0, n_ref=3, t_max=1e10)
    if start == "drifting":
        # the centre must have reached radius R - ell before any end can touch
        assert dts[0] >= (1.0 - math.hypot(0.1, 0.2)) / 1e-8 * (1 - 1e-6)


# ---------------------------------------------------------------------------
# a 1e7-collision run: drift and escape
# ---------------------------------------------------------------------------
@partial(jax.jit, static_argnums=2)
def _long_run(scene, state0, n):
    """``n`` collisions in a ``fori_loop`` over the jitted map, keeping only the
    worst energy and L deviations, the smallest end gap at any collision, and
    counts of non-finite results and contact-less collisions."""
    E0 = jb.energy(scene, state0)
    L0 = jb.angular_momentum(scene, state0)

    def body(_, carry):
        s, dE, dL, gmin, bad, stuck = carry
        new, dt, k = jb.collide(scene, s)
        dE = jnp.maximum(dE, jnp.abs(jb.energy(scene, new) - E0))
        dL = jnp.maximum(dL, jnp.abs(jb.angular_momentum(scene, new) - L0))
        gmin = jnp.minimum(gmin, jnp.min(scene.gaps(new)))
        bad = bad + (~jnp.all(jnp.isfinite(new)) | ~jnp.isfinite(dt) | (k == 0))
        stuck = stuck + (dt <= 0.0)
        return new, dE, dL, gmin, bad, stuck

    zero = jnp.zeros((), jnp.float64)
    init = (state0, zero, zero, jnp.min(scene.gaps(state0)), jnp.int32(0), jnp.int32(0))
    return jax.lax.fori_loop(0, n, body, init)


@pytest.mark.parametrize("kind, n", [("lens", 10_000_000), ("rotor", 2_000_000)], ids=["lens-1e7", "rotor-2e6"])
def test_long_run_drift_and_escape(kind, n):
    """The static lens (the cheapest meaningful scene: its map is a closed form,
    so 1e7 collisions take ~10 s) for 1e7 collisions, the spinning stick for 2e6.

    * escape: at every collision both ends are within ``1e-12 R^2`` of the
      inside (the library's own validity threshold: its output must be valid
      input). For the lens that bounds whole flights, since ``|P_k|^2`` is
      convex along a straight flight; never a NaN, a missing contact, or a
      flight of zero length (the stick sticking to the wall).
    * drift: ``|E - E0| / E0 <= 10 eps sqrt(n)``: unbiased rounding of a few
      ulps per collision is a random walk that stays below it; a bias of
      even 0.01 ulp per collision (1e-10 after 1e7: the impulse's rounding at
      ``R = 2`` before it was fixed gave 5e-10) does not. For the spinning
      stick ``L`` too, relative to its scale.
    """
    if kind == "lens":
        scene = jb.StickInCircle(R=R, ell=1.5, inertia=INF)
        s0 = jnp.asarray([0.1, 0.05, 0.3, 0.7, -0.4, 0.0])
    else:
        scene = jb.StickInCircle(R=R, ell=1.9)
        s0 = jnp.asarray([0.03, -0.02, 0.4, 0.6, 0.25, 0.3])
    s, dE, dL, gmin, bad, stuck = (np.asarray(v) for v in _long_run(scene, s0, n))
    assert int(bad) == 0, f"{int(bad)} collisions gave NaN/inf or no contact"
    assert int(stuck) == 0, f"{int(stuck)} flights of zero length"
    assert float(gmin) >= -WALL_TOL * R * R, f"an end went {-float(gmin):.3g} outside the wall"
    E0 = float(jb.energy(scene, s0))
    drift = float(dE) / E0
    random_walk = 10 * EPS * math.sqrt(n)
    assert drift <= random_walk, f"energy drifted by {drift:.3g} over {n} collisions ({drift / n:.2g} per collision)"
    if kind == "rotor":
        _, L_scale = invariant_scales(scene, np.asarray(s0), np.asarray(s0)[None])
        L_scale = max(L_scale, R * math.sqrt(2 * E0) + math.sqrt(2 * float(scene.inertia) * E0))
        assert float(dL) / L_scale <= random_walk, f"L drifted by {float(dL) / L_scale:.3g}"


# ---------------------------------------------------------------------------
# float32
# ---------------------------------------------------------------------------
def test_float32_input_is_computed_in_float64():
    """float32 arrays (state and parameters) are accepted and upcast: the result
    is float64 and bitwise the float64 orbit of the same (float32-exact) numbers."""
    s32 = np.array([0.1, -0.2, 0.3, 0.7, 0.4, 0.5], dtype=np.float32)
    scene32 = jb.StickInCircle(R=np.float32(2.0), ell=np.float32(1.9), mass=np.float32(1.5))
    scene64 = jb.StickInCircle(R=2.0, ell=float(np.float32(1.9)), mass=1.5)
    new32, dt32, k32 = jb.collide(scene32, jnp.asarray(s32))
    new64, dt64, k64 = jb.collide(scene64, jnp.asarray(s32.astype(np.float64)))
    assert new32.dtype == jnp.float64 and dt32.dtype == jnp.float64
    assert np.array_equal(np.asarray(new32), np.asarray(new64)) and float(dt32) == float(dt64) and int(k32) == int(k64)
    o32 = jb.orbit(scene32, jnp.asarray(s32), 50)
    o64 = jb.orbit(scene64, s32.astype(np.float64), 50)
    assert o32.state.dtype == jnp.float64
    assert np.array_equal(np.asarray(o32.state), np.asarray(o64.state))


_NO_X64_SCRIPT = textwrap.dedent(
    """
    import json, sys, warnings
    import numpy as np
    import jax
    import jaxbill as jb
    jax.config.update("jax_enable_x64", False)
    out = {}
    s = np.array([0.1, -0.2, 0.3, 0.7, 0.4, 0.5])
    def attempt(name, fn):
        try:
            with warnings.catch_warnings():
                warnings.simplefilter("ignore")
                r = fn()
            leaves = jax.tree_util.tree_leaves(r)
            out[name] = {"error": None, "dtypes": sorted({str(x.dtype) for x in leaves}),
                         "finite": bool(all(np.all(np.isfinite(np.asarray(x))) for x in leaves))}
        except Exception as e:
            out[name] = {"error": type(e).__name__, "message": str(e)}
    attempt("scene", lambda: jb.StickInCircle(R=2.0, ell=1.0).R)
    try:
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            scene = jb.StickInCircle(R=2.0, ell=1.0)
    except Exception:
        scene = None
    if scene is not None:
        attempt("collide", lambda: jb.collide(scene, s))
        attempt("orbit", lambda: jb.orbit(scene, s, 10))
        def chain():
            x = s
            for _ in range(20):
                x, dt, k = jb.collide(scene, x)
            return x
        attempt("collide_chain", chain)
    print("RESULT" + json.dumps(out))
    """
)


def test_float64_disabled_is_refused_clearly():
    """With ``jax_enable_x64`` turned off after import (JAX's default is float32),
    jaxbill cannot keep its float64 accuracy claims: its own wall tolerance
    (``1e-12 R^2``) is below float32 rounding, so a float32 orbit is neither
    accurate to a documented level nor even valid input to the next call. The
    required behaviour is a clear refusal: an exception whose message names
    ``jax_enable_x64`` (or float64), from the scene or from the first call."""
    proc = subprocess.run(
        [sys.executable, "-c", _NO_X64_SCRIPT],
        capture_output=True,
        text=True,
        timeout=300,
        env={**os.environ, "JAX_PLATFORMS": "cpu"},
    )
    assert proc.returncode == 0, proc.stderr[-3000:]
    out = json.loads(next(ln for ln in proc.stdout.splitlines() if ln.startswith("RESULT"))[6:])

    def refused(r):
        return r["error"] is not None and ("x64" in r["message"] or "float64" in r["message"])

    if refused(out["scene"]):
        return
    for name in ("collide", "orbit", "collide_chain"):
        assert refused(out[name]), (
            f"jb.{name} with jax_enable_x64 = False was not refused: {out[name]} (it computes silently in float32)"
        )
