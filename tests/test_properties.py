"""Property tests: no collision is ever missed, and every returned collision is real.

For random valid scenes and states (``helpers.scene_params``), each of the first
``N_COLLISIONS`` collisions returned by ``jb.collide`` is checked against an
independent description of the free flight (numpy, in 80-bit long double, with
its own search; jaxbill's root finder is not used):

* No end leaves the circle before the returned time: ``|P_k(t)| - R <= 1e-12 R``
  for all ``t`` in ``[0, dt]``. Certified, not just sampled:
  - while the centre is within ``R - ell`` of the origin no end can reach the
    wall (``|P_k| <= |c| + ell``), so only the rest of the flight is examined;
  - there ``f_k(t) = |P_k(t)|^2`` is sampled densely, and
    ``|f_k''| <= C = 2|v|^2 + 2 ell (2 |omega| |v| + omega^2 max|c|)`` (``max|c|``
    at an end of the window, ``|c(t)|`` being convex), so on a sampling
    interval of length ``h``, ``f_k <= max(f_k(ends)) + C h^2 / 8``; every
    interval where that bound is not already inside the tolerance is refined
    with a bounded scalar maximisation (scipy), which finds the interval's
    maximum (``f_k`` is unimodal on an interval far shorter than a turn).
  So no earlier root exists than the returned one.
* At the returned time the contacting end is on the wall
  (``| |P| - R | <= 1e-10 R``), was approaching (normal velocity ``> 0`` before
  the kick) and is receding after it (``< 0``); the kick reverses the contact
  point's normal velocity exactly (``v_n' = -v_n``: the impulse law's
  ``J (1/M + s^2/I) = 2 v_n``), and the returned configuration is the free
  flight to ``dt``.

Grazing is tested by construction (``test_grazing_*``): a state whose end P1 has
a tangential extremum of ``|P1|`` at radius ``R (1 +- eps)``.
"""

from __future__ import annotations

import math

import jax.numpy as jnp
import mpmath
import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st
from scipy.optimize import minimize_scalar

import jaxbill as jb
from helpers import kind_of, np_normal_speed, scene_params, state_from_unit, unit_six

LD = np.longdouble
N_COLLISIONS = 10
OUTSIDE_TOL = 1e-12  # |P| - R <= OUTSIDE_TOL * R during the flight
ON_WALL_TOL = 1e-10  # | |P| - R | <= ON_WALL_TOL * R at the returned contact
MIN_SAMPLES = 4000
SAMPLES_PER_TURN = 400
MAX_SAMPLES = 400_000


def _f(ell, s, t, end):
    """``|P_end(t)|^2`` in long double for the free flight from ``s`` (any shape of ``t``)."""
    t = np.asarray(t, dtype=LD)
    x, y, a, vx, vy, w = (LD(v) for v in s)
    phi = a + w * t
    px = x + vx * t + LD(end) * LD(ell) * np.cos(phi)
    py = y + vy * t + LD(end) * LD(ell) * np.sin(phi)
    return px * px + py * py


def _windows(R, ell, s, dt):
    """Parts of ``[0, dt]`` where ``|c(t)| >= R - ell`` (elsewhere no end can touch)."""
    x, y, _, vx, vy, _ = (LD(v) for v in s)
    r = LD(R) - LD(ell)
    a = vx * vx + vy * vy
    b = x * vx + y * vy
    cc = x * x + y * y - r * r
    disc = b * b - a * cc
    if a == 0 or disc <= 0:
        return [(0.0, dt)]
    root = np.sqrt(disc)
    t_in, t_out = float((-b - root) / a), float((-b + root) / a)
    # shrink the quiet interval by a relative 1e-9 so rounding cannot hide its edges
    pad = 1e-9 * (t_out - t_in)
    t_in, t_out = t_in + pad, t_out - pad
    if t_out <= 0.0 or t_in >= dt or t_in >= t_out:
        return [(0.0, dt)]
    out = []
    if t_in > 0.0:
        out.append((0.0, t_in))
    if t_out < dt:
        out.append((t_out, dt))
    return out


def max_radius_excess(R, ell, s, dt):
    """Certified ``max_k max_{t in [0, dt]} (|P_k(t)| - R) / R`` (see the module docstring),
    returned as ``(excess, t_at, end)``; exact only where it exceeds ``-OUTSIDE_TOL``."""
    x, y, _, vx, vy, w = (float(v) for v in s)
    speed = math.hypot(vx, vy)
    limit = LD(R) ** 2 * (1 + LD(OUTSIDE_TOL)) ** 2
    worst = (-np.inf, 0.0, 0)
    ends = (1,) if ell == 0.0 else (1, -1)
    for ta, tb in _windows(R, ell, s, dt):
        turns = abs(w) * (tb - ta) / (2 * math.pi) if ell > 0 else 0.0
        m = int(min(max(MIN_SAMPLES, SAMPLES_PER_TURN * turns), MAX_SAMPLES))
        ts = np.linspace(ta, tb, m)
        h = (tb - ta) / (m - 1)
        cmax = max(math.hypot(x + vx * ta, y + vy * ta), math.hypot(x + vx * tb, y + vy * tb))
        C = 2 * speed**2 + 2 * ell * (2 * abs(w) * speed + w * w * cmax)
        for end in ends:
            f = _f(ell, s, ts, end)
            i = int(np.argmax(f))
            if f[i] > worst[0]:
                worst = (f[i], ts[i], end)
            bound = np.maximum(f[:-1], f[1:]) + LD(C * h * h / 8)
            for j in np.nonzero(bound > limit)[0][:2000]:
                res = minimize_scalar(
                    lambda t: -float(_f(ell, s, t, end)),
                    bounds=(ts[j], ts[j + 1]),
                    method="bounded",
                    options={"xatol": max(h * 1e-9, 1e-300)},
                )
                fv = _f(ell, s, res.x, end)
                if fv > worst[0]:
                    worst = (fv, float(res.x), end)
    excess = float((np.sqrt(LD(worst[0])) - LD(R)) / LD(R))
    return excess, worst[1], worst[2]


def check_collision(R, ell, mass, inertia, kind, s, new, dt, contact):
    """Everything asserted about one returned collision (module docstring)."""
    s, new = np.asarray(s, dtype=np.float64), np.asarray(new, dtype=np.float64)
    assert contact in (1, -1, 2), f"contact {contact}, dt {dt}"
    assert np.isfinite(dt) and dt >= 0.0 and np.all(np.isfinite(new))
    if kind == "circle":
        assert contact == 1

    # no end outside the circle during the flight (so no earlier root)
    excess, t_at, end_at = max_radius_excess(R, ell, s, dt)
    assert excess <= OUTSIDE_TOL, (
        f"end {end_at} is outside the circle by {excess:.3g} R at t = {t_at!r} < dt = {dt!r}: "
        f"an earlier collision was missed (state {s.tolist()})"
    )

    # the returned configuration is the free flight to dt
    pre = np.array(s)
    x, y, a, vx, vy, w = (LD(v) for v in s)
    T = LD(dt)
    pre[0], pre[1] = float(x + vx * T), float(y + vy * T)
    pos_tol = 1e-14 * (R + math.hypot(s[3], s[4]) * dt)
    assert abs(new[0] - pre[0]) <= pos_tol and abs(new[1] - pre[1]) <= pos_tol
    ang = float(np.remainder(a + w * T - LD(new[2]) + LD(math.pi), LD(2 * math.pi)) - LD(math.pi))
    assert abs(ang) <= 1e-14 * (math.pi + abs(s[5] * dt))
    pre[2] = new[2]  # the kick leaves the configuration alone; use the returned one

    ends = (1,) if (kind == "circle" or contact != 2) else (1, -1)
    if kind != "circle" and contact != 2:
        ends = (contact,)
    speed_scale = math.hypot(s[3], s[4]) + ell * abs(s[5])
    for end in ends:
        radius = float(np.sqrt(_f(ell, new, 0.0, end)))
        assert abs(radius - R) <= ON_WALL_TOL * R, f"end {end} at |P| = {radius!r}, R = {R}"
        before = np_normal_speed(ell, pre, end)
        after = np_normal_speed(ell, new, end)
        if contact != 2:
            assert before > 0.0, f"end {end} was not approaching the wall (v_n = {before:.3g})"
            assert after < 0.0, f"end {end} is not receding after the kick (v_n = {after:.3g})"
            assert abs(after + before) <= 1e-12 * speed_scale, "v_n' != -v_n"
        else:
            assert after <= 1e-12 * speed_scale


def run_and_check(R, ell, mass, inertia, state0, n=N_COLLISIONS):
    scene = jb.StickInCircle(R=R, ell=ell, mass=mass, inertia=inertia)
    kind = kind_of(ell, inertia)
    assert scene.kind == kind
    s = np.asarray(state0, dtype=np.float64)
    out = []
    for _ in range(n):
        new, dt, contact = jb.collide(scene, jnp.asarray(s))
        new, dt, contact = np.asarray(new), float(dt), int(contact)
        check_collision(R, ell, mass, inertia, kind, s, new, dt, contact)
        out.append((dt, contact, new))
        s = new
    return out


# ---------------------------------------------------------------------------
# random scenes and states
# ---------------------------------------------------------------------------
@settings(
    max_examples=100,
    deadline=None,
    derandomize=True,
    suppress_health_check=[HealthCheck.too_slow, HealthCheck.data_too_large],
)
@given(params=scene_params(), u=unit_six(), speed=st.floats(0.1, 10.0), spin=st.floats(0.0, 30.0))
def test_no_missed_collision_and_every_collision_is_real(params, u, speed, spin):
    R, ell, mass, inertia = params
    kind = kind_of(ell, inertia)
    state0 = state_from_unit(R, ell, kind, u, speed=speed, max_spin=spin)
    run_and_check(R, ell, mass, inertia, state0)


@pytest.mark.parametrize(
    "R, ell, mass, inertia, u, speed, spin",
    [
        (2.0, 1.9, 1.0, None, [0.1, 0.3, 0.7, 0.2, 0.9, 0.5], 1.0, 3.0),
        (2.0, 1.0, 1.0, 1e-4, [0.6, 0.1, 0.2, 0.8, 0.7, 0.1], 1.0, 3.0),  # I = M ell^2 1e-4
        (0.5, 0.5 * 0.9999, 3.0, None, [0.4, 0.9, 0.1, 0.3, 0.2, 0.6], 2.0, 5.0),  # ell/R = 0.9999
        (5.0, 5e-6, 0.2, None, [0.9, 0.5, 0.5, 0.1, 1.0, 0.3], 0.5, 30.0),  # ell/R = 1e-6
        (2.0, 1.5, 1.0, float("inf"), [0.2, 0.2, 0.2, 0.2, 0.5, 0.5], 1.0, 0.0),  # lens
        (1.0, 0.0, 1.0, None, [0.3, 0.8, 0.4, 0.6, 0.9, 0.9], 2.0, 10.0),  # circle
        (2.0, 1.0, 1.0, None, [0.5, 0.5, 0.5, 0.37, 1.0, 0.5], 1.0, 30.0),  # fast spin
    ],
    ids=["ell1.9", "tiny-I", "ell-0.9999R", "ell-1e-6R", "lens", "circle", "fast-spin"],
)
def test_edge_scenes(R, ell, mass, inertia, u, speed, spin):
    kind = kind_of(ell, inertia)
    run_and_check(R, ell, mass, inertia, state_from_unit(R, ell, kind, u, speed=speed, max_spin=spin))


# ---------------------------------------------------------------------------
# grazing: an end that just touches, or just misses, the wall tangentially
# ---------------------------------------------------------------------------
def _grazing_state(R, ell, w, vy, eps, tau):
    """State whose end P1 reaches its largest ``|P1|``, ``R (1 + eps)``, after a flight of ``tau``.

    At the extremum: ``alpha = 0``, ``c = (R' - ell, 0)``, ``v = (0, vy)``,
    spin ``w``; P1 = ``(R', 0)`` moves tangentially (``(0, vy + ell w)``) and
    ``d^2 |P1|^2 / dt^2 = 2 ((vy + ell w)^2 - ell w^2 R') < 0`` (a maximum) when
    ``(vy + ell w)^2 < ell w^2 R'``. The start is that state flown back by ``tau``.
    """
    Rp = R * (1.0 + eps)
    assert (vy + ell * w) ** 2 < ell * w * w * Rp
    return np.array([Rp - ell, -vy * tau, -w * tau, 0.0, vy, w])


def _reference_first_crossing(R, ell, s, t_hi):
    """mpmath: the unique root of ``R^2 - |P1(t)|^2`` in ``(0, t_hi)`` by bisection
    (the gap is positive at 0, negative at ``t_hi``, and ``|P1|^2`` increases on
    ``[0, t_hi]``), and ``|d gap / dt|`` there."""
    with mpmath.workdps(40):
        x, y, a, vx, vy, w = (mpmath.mpf(float(v)) for v in s)
        Rm, lm = mpmath.mpf(R), mpmath.mpf(ell)

        def gap(t):
            end_x = x + vx * t + lm * mpmath.cos(a + w * t)
            end_y = y + vy * t + lm * mpmath.sin(a + w * t)
            return Rm**2 - end_x**2 - end_y**2

        lo, hi = mpmath.mpf(0), mpmath.mpf(t_hi)
        assert gap(lo) > 0 and gap(hi) < 0
        for _ in range(120):
            mid = (lo + hi) / 2
            if gap(mid) > 0:
                lo = mid
            else:
                hi = mid
        slope = mpmath.diff(gap, lo)
        return float(lo), float(abs(slope))


GRAZING = [
    # (R, ell, w, vy, tau)
    (2.0, 1.0, 1.0, 0.2, 0.5),
    (1.0, 0.3, 20.0, 0.01, 0.02),
    (3.0, 2.9, 0.5, -0.1, 1.0),
]


@pytest.mark.parametrize("eps", [1e-9, 1e-11])
@pytest.mark.parametrize("R, ell, w, vy, tau", GRAZING)
def test_grazing_hit_is_found(R, ell, w, vy, tau, eps):
    """P1 pokes ``eps R`` beyond the wall: jaxbill must stop at the first crossing,
    just before the extremum, not step over the near-double root."""
    s0 = _grazing_state(R, ell, w, vy, eps, tau)
    ((dt, contact, _),) = run_and_check(R, ell, 1.0, None, s0, n=1)
    assert contact == 1
    t_ref, slope = _reference_first_crossing(R, ell, s0, tau)
    # a gap known to ~100 ulps of R^2 fixes the root to 100 eps R^2 / |gap'|
    tol = 100 * 2.0**-52 * R * R / slope
    assert abs(dt - t_ref) <= tol, f"dt = {dt!r}, reference {t_ref!r}, tolerance {tol:.3g}"
    assert dt < tau


@pytest.mark.parametrize("eps", [-1e-9, -1e-11])
@pytest.mark.parametrize("R, ell, w, vy, tau", GRAZING)
def test_grazing_miss_is_walked_past(R, ell, w, vy, tau, eps):
    """P1 comes within ``|eps| R`` of the wall and turns back: no collision there."""
    s0 = _grazing_state(R, ell, w, vy, eps, tau)
    # sanity of the construction: the closest approach really is |eps| R inside
    f_peak = float(np.sqrt(_f(ell, s0, tau, 1)))
    assert abs(f_peak - R * (1 + eps)) < 1e-14 * R
    ((dt, _, _),) = run_and_check(R, ell, 1.0, None, s0, n=1)
    # no collision within the graze: past the extremum P1 recedes, so the next
    # collision is at least a fraction of a turn later
    assert dt > tau + 0.05 / w, f"false hit at the near miss: dt = {dt!r}, graze at {tau}"


# ---------------------------------------------------------------------------
# the checker itself has teeth
# ---------------------------------------------------------------------------
def test_checker_certifies_a_graze_between_samples():
    """A 1e-11 R excursion lasting a tiny fraction of a sampling interval is found."""
    R, ell, w, vy, tau = GRAZING[0]
    s0 = _grazing_state(R, ell, w, vy, 1e-11, tau)
    excess, t_at, end = max_radius_excess(R, ell, s0, 1.3 * tau)
    assert end == 1 and abs(t_at - tau) < 1e-3 * tau
    assert 0.9e-11 < excess < 1.1e-11


def test_checker_rejects_skipped_and_fake_collisions():
    R, ell = 2.0, 1.0
    s0 = state_from_unit(R, ell, "rotor", [0.1, 0.3, 0.7, 0.2, 0.9, 0.5], speed=1.0, max_spin=3.0)
    scene = jb.StickInCircle(R=R, ell=ell)
    new, dt, contact = (np.asarray(v) for v in jb.collide(scene, jnp.asarray(s0)))
    dt, contact = float(dt), int(contact)
    check_collision(R, ell, 1.0, None, "rotor", s0, new, dt, contact)  # the real one passes
    # a collision reported later than the real one: the end has gone through the wall
    assert max_radius_excess(R, ell, s0, 1.05 * dt)[0] > 1e-4
    # the right time but no kick: the end is not receding
    unkicked = new.copy()
    unkicked[3:6] = s0[3:6]
    with pytest.raises(AssertionError):
        check_collision(R, ell, 1.0, None, "rotor", s0, unkicked, dt, contact)
    # the wrong end reported
    with pytest.raises(AssertionError):
        check_collision(R, ell, 1.0, None, "rotor", s0, new, dt, -contact)
    # a collision reported early: the end is not on the wall
    early = np.asarray(scene.flight(jnp.asarray(s0), 0.99 * dt))
    with pytest.raises(AssertionError):
        check_collision(R, ell, 1.0, None, "rotor", s0, early, 0.99 * dt, contact)
