"""A point particle in Sinai's billiard and in Bunimovich's stadium, as plain numba loops, for speed comparisons.

Run:  python benchmarks/numba_point_billiards.py        (agreement with ``jb.orbit``, under a minute)

Nothing in ``jaxbill`` imports this file. It implements, in scalar float64 code,
what jaxbill computes for a point in these two tables (``jb.Sinai``,
``jb.Stadium``), so that ``bench_standard.py`` compares two implementations of
one algorithm:

* Sinai's billiard (the square ``|x|, |y| <= side/2`` less the disc ``|P| < r``):
  the sides' exit times ``(d - n . P) / (n . v)`` (``HalfPlane.exit_time``), the
  disc's entry time ``g0 / (-b + sqrt(b^2 - |v|^2 g0))`` (``DiscObstacle``), the
  first smallest of them; the impulse about the normal scaled to ``|N|^2 = pi/2``;
  the corner rule of the square's sides (64 ulps of the side: both sides' impulses,
  the faster first, the second only if it still approaches);
* the stadium (the points within ``r`` of the segment from ``(-L, 0)`` to
  ``(L, 0)``): the latest exit from its three convex parts, two discs and a
  rectangle (``CapsuleWall.exit_time``), and the impulse about ``q = P - foot(P)``
  scaled by ``sqrt(pi/2) / r``.

States are jaxbill's ``[x, y, alpha, vx, vy, omega]`` (a point's ``alpha`` and
``omega`` are carried unchanged); contact codes are jaxbill's (``3 + i``).
"""

from __future__ import annotations

import math
import sys

import numba
import numpy as np

EPS = float(np.finfo(np.float64).eps)
CORNER_ULPS = 64.0 * EPS
KICK = math.sqrt(math.pi / 2.0)
INF = math.inf


@numba.njit(cache=False)
def _reflect(vx, vy, nx, ny):
    change = 2.0 * (vx * nx + vy * ny) / (nx * nx + ny * ny)
    return vx - change * nx, vy - change * ny


@numba.njit(cache=False)
def _side(j, half):
    """Side ``j`` of the square (bottom, right, top, left): its outward normal and offset ``n . P <= d``."""
    if j == 0:
        return 0.0, -1.0, half
    if j == 1:
        return 1.0, 0.0, half
    if j == 2:
        return 0.0, 1.0, half
    return -1.0, 0.0, half


@numba.njit(cache=False)
def sinai_collision(x, y, vx, vy, radius, side):
    """``(x, y, vx, vy, dt, contact)`` after the next collision of a point in Sinai's billiard."""
    half = 0.5 * side
    best, index = INF, -1
    for j in range(4):
        nx, ny, d = _side(j, half)
        closing = nx * vx + ny * vy
        if closing > 0.0:
            t = max(d - (nx * x + ny * y), 0.0) / closing
            if t < best:
                best, index = t, j
    b = x * vx + y * vy
    speed2 = vx * vx + vy * vy
    excess = (x * x + y * y) - radius * radius
    disc = b * b - speed2 * excess
    if b < 0.0 and disc >= 0.0:
        t = max(excess / (math.sqrt(disc) - b), 0.0)
        if t < best:
            best, index = t, 4
    x, y = x + vx * best, y + vy * best
    if index == 4:
        factor = -KICK / radius
        vx, vy = _reflect(vx, vy, factor * x, factor * y)
        return x, y, vx, vy, best, 7
    nx, ny, _ = _side(index, half)
    # The corner rule: another side on its wall (64 ulps of the side) and approaching.
    limit = CORNER_ULPS * side
    other = -1
    for j in range(4):
        if j != index:
            ox, oy, d = _side(j, half)
            if d - (ox * x + oy * y) <= limit and ox * vx + oy * vy > 0.0:
                other = j
    if other < 0:
        vx, vy = _reflect(vx, vy, KICK * nx, KICK * ny)
        return x, y, vx, vy, best, 3 + index
    ox, oy, _ = _side(other, half)
    first, second = (index, other) if nx * vx + ny * vy >= ox * vx + oy * vy else (other, index)
    fx, fy, _ = _side(first, half)
    vx, vy = _reflect(vx, vy, KICK * fx, KICK * fy)
    sx, sy, _ = _side(second, half)
    if sx * vx + sy * vy > 0.0:
        vx, vy = _reflect(vx, vy, KICK * sx, KICK * sy)
    return x, y, vx, vy, best, 2


@numba.njit(cache=False)
def _disc_exit(px, py, vx, vy, radius):
    """The time ``t >= 0`` the line leaves the disc of ``radius`` about the origin, or ``-1`` if it is never in it."""
    speed2 = vx * vx + vy * vy
    b = px * vx + py * vy
    excess = px * px + py * py - radius * radius
    disc = b * b - speed2 * excess
    if disc <= 0.0:
        return -1.0
    root = math.sqrt(disc)
    q = -(b + (-root if b < 0.0 else root))
    if q == 0.0:
        return -1.0
    t_out = max(q / speed2, excess / q)
    return t_out if t_out > 0.0 else -1.0


@numba.njit(cache=False)
def _band_exit(p, v, low, high):
    """The time the coordinate ``p + v t`` leaves ``(low, high)`` (``-1`` if never inside for ``t >= 0``)."""
    if v == 0.0:
        return INF if low < p < high else -1.0
    t_low, t_high = (low - p) / v, (high - p) / v
    t_out = max(t_low, t_high)
    return t_out if t_out > 0.0 else -1.0


@numba.njit(cache=False)
def stadium_collision(x, y, vx, vy, half_length, radius):
    """``(x, y, vx, vy, dt, contact)`` after the next collision of a point in the stadium."""
    t = 0.0
    for centre in (-half_length, half_length):
        t_out = _disc_exit(x - centre, y, vx, vy, radius)
        if t_out > t:
            t = t_out
    x_out = _band_exit(x, vx, -half_length, half_length)
    y_out = _band_exit(y, vy, -radius, radius)
    if x_out > 0.0 and y_out > 0.0:
        # the rectangle: the line is in it from the later entry to the earlier exit
        sx = (-half_length - x) / vx if vx != 0.0 else -INF
        tx = (half_length - x) / vx if vx != 0.0 else -INF
        sy = (-radius - y) / vy if vy != 0.0 else -INF
        ty = (radius - y) / vy if vy != 0.0 else -INF
        t_in = max(min(sx, tx), min(sy, ty), 0.0)
        t_rect = min(x_out, y_out)
        if t_in < t_rect and t_rect > t:
            t = t_rect
    x, y = x + vx * t, y + vy * t
    qx = x - min(max(x, -half_length), half_length)
    factor = KICK / radius
    vx, vy = _reflect(vx, vy, factor * qx, factor * y)
    return x, y, vx, vy, t, 3


@numba.njit(cache=False)
def run_one(kind, a, b, state, n):
    """``n`` collisions of one orbit (``kind`` 0: Sinai with ``(radius, side) = (a, b)``; 1: the stadium with
    ``(half_length, radius) = (a, b)``): ``(final state, total time)``."""
    x, y, vx, vy = state[0], state[1], state[3], state[4]
    total = 0.0
    for _ in range(n):
        if kind == 0:
            x, y, vx, vy, dt, _ = sinai_collision(x, y, vx, vy, a, b)
        else:
            x, y, vx, vy, dt, _ = stadium_collision(x, y, vx, vy, a, b)
        total += dt
    out = state.copy()
    out[0], out[1], out[3], out[4] = x, y, vx, vy
    return out, total


@numba.njit(cache=False)
def orbit(kind, a, b, state, n):
    """States ``(n, 6)``, times ``(n,)`` and contact codes ``(n,)`` of one orbit, as ``jb.orbit``."""
    states = np.empty((n, 6))
    times = np.empty(n)
    contacts = np.empty(n, np.int32)
    x, y, vx, vy = state[0], state[1], state[3], state[4]
    total = 0.0
    for k in range(n):
        if kind == 0:
            x, y, vx, vy, dt, c = sinai_collision(x, y, vx, vy, a, b)
        else:
            x, y, vx, vy, dt, c = stadium_collision(x, y, vx, vy, a, b)
        total += dt
        states[k] = state
        states[k, 0], states[k, 1], states[k, 3], states[k, 4] = x, y, vx, vy
        times[k], contacts[k] = total, c
    return states, times, contacts


@numba.njit(cache=False)
def run_batch(kind, a, b, states, n):
    """``run_one`` over a batch ``(B, 6)`` on one thread: final states and times."""
    out = np.empty_like(states)
    times = np.empty(len(states))
    for i in range(len(states)):
        out[i], times[i] = run_one(kind, a, b, states[i], n)
    return out, times


@numba.njit(parallel=True, cache=False)
def _run_batch_parallel(kind, a, b, states, n):
    out = np.empty_like(states)
    times = np.empty(len(states))
    for i in numba.prange(len(states)):
        out[i], times[i] = run_one(kind, a, b, states[i], n)
    return out, times


def run_batch_parallel(kind, a, b, states, n, threads):
    """``run_batch`` over ``threads`` numba threads."""
    numba.set_num_threads(threads)
    return _run_batch_parallel(kind, a, b, states, n)


SINAI, STADIUM = 0, 1


def agreement() -> int:
    """Compare with ``jb.orbit`` from Liouville starts: the same contacts and states to 1e-9 over 30 collisions."""
    import jaxbill as jb

    failures = 0
    for kind, a, b, table in ((SINAI, 0.25, 1.0, jb.Sinai(0.25, 1.0)), (STADIUM, 1.0, 1.0, jb.Stadium(1.0, 1.0))):
        scene = jb.BodyInTable(jb.PointBody(), table)
        starts, _ = jb.sample_energy_shell(scene, 16, seed=5)
        reference = jb.orbit(scene, starts, 30)
        agree = 0
        for i, start in enumerate(np.asarray(starts)):
            states, times, contacts = orbit(kind, a, b, start, 30)
            agree += np.array_equal(contacts, np.asarray(reference.contact[i])) and np.allclose(
                states, np.asarray(reference.state[i]), rtol=0, atol=1e-9
            )
        print(f"{type(table).__name__}: {agree} of 16 orbits agree over 30 collisions")
        failures += 16 - agree
    return failures


if __name__ == "__main__":
    sys.exit(1 if agreement() else 0)
