"""jaxbill's method as plain numba loops, for speed comparisons.

Run:  python benchmarks/numba_baseline.py        (agreement with ``jb.orbit``, about 1 min)

Nothing in ``jaxbill`` imports this file. It implements, in scalar float64 code,
the method of the library, so that ``bench_vs_numba.py`` compares two
implementations of one algorithm, not two algorithms. For the spinning stick in
a circle it has two loops:

* ``ROTOR``, the loop a user would write from the paper's method: its safe
  steps use only the curvature bounds of the whole flight;
* ``ROTOR_SHARPER``, the same method as jaxbill's: its steps also use each
  gap's own curvature at the current time and a bound on the gaps' third
  derivative (``jaxbill._engine.first_root``, "sharper steps"), so it finds the
  same roots (to the time resolution) in fewer, dearer steps.

Every other scene has one loop, the method jaxbill uses for it.

* the spinning stick in a circle (``StickInCircle``, finite inertia): the quiet
  interval of ``_disc_crossing`` (radius ``R - ell``), the curvature bounds and
  time scale of ``_rotor_bounds``, the safe steps and stopping rule of
  ``jaxbill._engine.first_root`` (4 ulps of ``max(t, time_scale)``, at most 4096 steps),
  the impulse of ``StickInCircle.kick`` (normal scaled by ``sqrt(pi/2)/R``, one
  mass ratio ``M/I``), the corner rule (64 ulps of ``R^2``) and the angle wrap
  ``remainder(alpha + pi, 2 pi) - pi``;
* the static lens (``inertia = inf``) and the circle (``ell = 0``): the closed
  form ``_exit_time``;
* the stick between two flat walls (``StickBetweenWalls2D``, turning or
  static): the sinusoidal gaps, quiet band and curvature bound of
  ``jaxbill._scenes.walls.engine`` and the same safe-step search.

Scenes are described by ``params``, float64 of shape ``(5,)``:
``[kind, size, ell, mass, inertia]`` with ``kind`` one of the codes below and
``size`` the circle's radius ``R`` or the walls' distance ``h``. States are
laid out as in jaxbill (``[x, y, alpha, vx, vy, omega]`` in a circle,
``[x, z, theta, vx, vz, omega]`` between walls). Contact codes are jaxbill's.

The per-collision code is written once, in ``make_engine(jit)``, and compiled
by ``numba.njit`` here and by ``numba.cuda.jit(device=True)`` in
``numba_cuda_baseline.py``: every function works on scalars and returns tuples,
so that on a GPU the whole state stays in registers.
"""

from __future__ import annotations

import math
import sys
import types

import numba
import numpy as np

from agreement import relative_difference  # this script's folder, on sys.path when run

ROTOR, LENS, CIRCLE, WALLS_ROTOR, WALLS_STATIC, ROTOR_SHARPER = 0, 1, 2, 3, 4, 5
KIND_NAMES = {
    ROTOR: "rotor",
    LENS: "lens",
    CIRCLE: "circle",
    WALLS_ROTOR: "walls rotor",
    WALLS_STATIC: "walls static",
    ROTOR_SHARPER: "rotor, sharper steps",
}

# The constants of jaxbill's method (jaxbill._engine.first_root, _stick_in_circle, _flat_walls).
MAX_ROOT_STEPS = 4096
EPS = float(np.finfo(np.float64).eps)
RESOLUTION_ULPS = 4.0 * EPS
CORNER_ULPS = 64.0 * EPS
AMPLITUDE_PAD = 1.0 + 8.0 * EPS
CURVATURE_PAD = 16.0 * EPS  # first_root._CURVATURE_PAD_ULPS
KICK_NORMAL_SCALE = math.sqrt(math.pi / 2)
PI = math.pi
TWO_PI = 2.0 * math.pi
INF = math.inf
NAN = math.nan

NO_CONTACT, SEVERAL_CONTACTS = 0, 2


def make_engine(jit, fmod):
    """The collision map of every scene, compiled with the decorator ``jit``.

    ``fmod``: C's ``fmod`` as a function the compiled code can call (CPU numba
    has ``np.fmod``, CUDA has ``math.fmod``).

    Returns a namespace whose ``collide(kind, size, ell, mass, inertia, ux, uy,
    x, y, a, vx, vy, om)`` gives ``(x, y, a, vx, vy, om, dt, contact,
    root_steps)``: the state just after the next collision, the flight time,
    the contact code and the safe steps the search took (0 for closed forms).
    ``(ux, uy)`` is the static lens's direction, fixed along an orbit
    (``orbit_direction``). Divisions are guarded by branches rather than left
    to produce inf, so that the same source also runs in plain Python (the
    CUDA simulator), where float division by zero raises.
    """

    # NaN-propagating, like jnp.maximum/minimum; numba 0.68's CUDA target fails to type the
    # builtins min/max of two floats.
    @jit
    def larger(a, b):
        return a if (a > b or a != a) else b

    @jit
    def smaller(a, b):
        return a if (a < b or a != a) else b

    @jit
    def wrap_angle(angle):
        # jnp.remainder(angle + pi, 2 pi) - pi: a C fmod moved into [0, 2 pi).
        r = fmod(angle + PI, TWO_PI)
        if r < 0.0:
            r += TWO_PI
        return r - PI

    @jit
    def orbit_direction(kind, a):
        # The lens never turns: one (cos, sin) serves its whole orbit. The
        # circle ignores the direction; the rotors compute their own.
        if kind == LENS:
            return math.cos(a), math.sin(a)
        return 1.0, 0.0

    # -- the safe step of jaxbill._engine.first_root, one gap at a time --------------

    @jit
    def step_below(g, slope, lower_curv):
        """First root of g + slope s - lower_curv s^2 / 2: a step that cannot pass a root."""
        root = math.sqrt(slope * slope + 2.0 * lower_curv * g)
        if slope < 0.0:
            s = 2.0 * g / (root - slope)
        else:
            inverse = 1.0 / lower_curv if lower_curv != 0.0 else INF
            s = (slope + root) * inverse
        if s != s:
            s = INF if g > 0.0 else 0.0
        return s

    @jit
    def step_above(g, slope, upper_curv):
        """First root of g + slope s + upper_curv s^2 / 2 (inf if none): the root lies before it."""
        disc = slope * slope - 2.0 * upper_curv * g
        if slope < 0.0 and disc >= 0.0:
            return 2.0 * g / (-slope + math.sqrt(disc))
        return INF

    # -- the stick in a circle -------------------------------------------------

    @jit
    def exit_time(px, py, vx, vy, radius):
        speed2 = vx * vx + vy * vy
        if not speed2 > 0.0:
            return INF
        b = px * vx + py * vy
        gap = radius * radius - (px * px + py * py)
        disc = b * b + speed2 * gap
        root = math.sqrt(larger(disc, 0.0))
        if b <= 0.0:
            # A point outside by rounding whose line misses the disc takes the
            # tangent chord, as jaxbill does.
            t = -2.0 * b / speed2 if disc < 0.0 else (root - b) / speed2
        else:
            t = gap / (b + root)
        return larger(t, 0.0)

    @jit
    def disc_crossing(px, py, vx, vy, radius):
        speed2 = vx * vx + vy * vy
        b = px * vx + py * vy
        excess = (px * px + py * py) - radius * radius
        disc = b * b - speed2 * excess
        if speed2 > 0.0 and disc > 0.0:
            q = -(b + math.copysign(math.sqrt(disc), b))
            t1, t2 = q / speed2, excess / q
            t_in, t_out = smaller(t1, t2), larger(t1, t2)
            if t_out > 0.0:
                return larger(t_in, 0.0), t_out
            return INF, INF
        if speed2 == 0.0 and excess < 0.0:
            return 0.0, INF
        return INF, INF

    @jit
    def rotor_gaps(R, ell, x, y, a, vx, vy, om, t):
        cx, cy = x + vx * t, y + vy * t
        phi = a + om * t
        cu, su = math.cos(phi), math.sin(phi)
        centre_gap = R * R - ell * ell - (cx * cx + cy * cy)
        centre_slope = -2.0 * (cx * vx + cy * vy)
        along = cx * cu + cy * su
        along_slope = vx * cu + vy * su + om * (cy * cu - cx * su)
        arm = 2.0 * ell
        return (
            centre_gap - arm * along,
            centre_gap + arm * along,
            centre_slope - arm * along_slope,
            centre_slope + arm * along_slope,
        )

    @jit
    def rotor_first_root(R, ell, x, y, a, vx, vy, om, lower_curv, upper_curv, quiet_in, quiet_out, time_scale):
        t = quiet_out if (quiet_in <= 0.0 and quiet_out > 0.0) else 0.0
        index = 0
        done = t == INF
        steps = 0
        while not done and steps < MAX_ROOT_STEPS:
            g1, g2, d1, d2 = rotor_gaps(R, ell, x, y, a, vx, vy, om, t)
            c1, c2 = larger(g1, 0.0), larger(g2, 0.0)
            s1, s2 = step_below(c1, d1, lower_curv), step_below(c2, d2, lower_curv)
            if s2 < s1:
                index, s, g, slope = 1, s2, c2, d2
            else:
                index, s, g, slope = 0, s1, c1, d1
            t_next = t + s
            if t_next >= quiet_in and t_next < quiet_out:
                t_next = quiet_out
            resolution = RESOLUTION_ULPS * larger(t, time_scale)
            converged = (step_above(g, slope, upper_curv) - s <= resolution) or (t_next == t and slope < 0.0)
            touching = True
            if c1 == 0.0 and d1 < 0.0:
                index = 0
            elif c2 == 0.0 and d2 < 0.0:
                index = 1
            else:
                touching = False
            if touching:
                t_next = t
            finite = math.isfinite(g1) and math.isfinite(g2) and math.isfinite(d1) and math.isfinite(d2)
            hopeless = not (math.isfinite(t_next) and finite)
            done = touching or converged or hopeless
            t = t_next
            steps += 1
        return t, index, steps, done

    @jit
    def rotor_contact_time(R, ell, x, y, a, vx, vy, om):
        speed = math.sqrt(vx * vx + vy * vy)
        spin = abs(om)
        centre_radius = math.sqrt(x * x + y * y)
        quiet_in, quiet_out = disc_crossing(x, y, vx, vy, R - ell)
        reach = larger(math.sqrt(R * R - ell * ell), centre_radius)
        wobble = 2.0 * ell * (2.0 * spin * speed + spin * spin * reach)
        lower_curv = 2.0 * speed * speed + wobble
        upper_curv = wobble - 2.0 * speed * speed
        rate = speed / R + spin
        time_scale = 1.0 / rate if rate > 0.0 else INF
        return rotor_first_root(R, ell, x, y, a, vx, vy, om, lower_curv, upper_curv, quiet_in, quiet_out, time_scale)

    # -- jaxbill's sharper steps (``jaxbill._engine.first_root``): each gap's own curvature, a jerk bound --

    @jit
    def rotor_curvatures(ell, x, y, a, vx, vy, om, t):
        """Both ends' ``g_k''`` after a flight of ``t``, as ``StickInCircle.gaps_along_flight`` gives them."""
        cx, cy = x + vx * t, y + vy * t
        phi = a + om * t
        cu, su = math.cos(phi), math.sin(phi)
        centre_curvature = -2.0 * (vx * vx + vy * vy)
        along_unit = cx * cu + cy * su
        along_curvature = 2.0 * ell * (om * (2.0 * (vy * cu - vx * su) - om * along_unit))
        return centre_curvature - along_curvature, centre_curvature + along_curvature

    @jit
    def local_step(g, slope, curvature, lower_curv, jerk_third, pad):
        """``(step, window, margin)`` of one gap: a falling gap's window ``S = 2 g / |d|``, what the
        window adds to its own curvature (``jerk S / 3`` and the rounding pad), and its safe step with
        the window's lower curvature bound, capped at ``S`` (``first_root._local_bounds``)."""
        if slope < 0.0:
            window = 2.0 * g / (-slope)
            margin = (jerk_third * window if jerk_third > 0.0 else 0.0) + pad
            lower = smaller(lower_curv, margin - curvature)
            return smaller(step_below(g, slope, lower), window), window, margin
        return step_below(g, slope, lower_curv), INF, INF  # no upper root on a rising gap

    @jit
    def rotor_first_root_sharper(R, ell, x, y, a, vx, vy, om, bounds, time_scale, jerk):
        lower_curv, upper_curv, quiet_in, quiet_out = bounds
        t = quiet_out if (quiet_in <= 0.0 and quiet_out > 0.0) else 0.0
        index = 0
        done = t == INF
        steps = 0
        jerk_third = jerk * (1.0 / 3.0)
        pad = CURVATURE_PAD * lower_curv
        while not done and steps < MAX_ROOT_STEPS:
            g1, g2, d1, d2 = rotor_gaps(R, ell, x, y, a, vx, vy, om, t)
            k1, k2 = rotor_curvatures(ell, x, y, a, vx, vy, om, t)
            c1, c2 = larger(g1, 0.0), larger(g2, 0.0)
            s1, w1, m1 = local_step(c1, d1, k1, lower_curv, jerk_third, pad)
            s2, w2, m2 = local_step(c2, d2, k2, lower_curv, jerk_third, pad)
            if s2 < s1:
                index, s, g, slope, curvature, window, margin = 1, s2, c2, d2, k2, w2, m2
            else:
                index, s, g, slope, curvature, window, margin = 0, s1, c1, d1, k1, w1, m1
            t_next = t + s
            if t_next >= quiet_in and t_next < quiet_out:
                t_next = quiet_out
            resolution = RESOLUTION_ULPS * larger(t, time_scale)
            s_hi = step_above(g, slope, smaller(upper_curv, curvature + margin))
            if not s_hi <= window:
                s_hi = INF  # past the window nothing is proven
            converged = (s_hi - s <= resolution) or (t_next == t and slope < 0.0)
            touching = True
            if c1 == 0.0 and d1 < 0.0:
                index = 0
            elif c2 == 0.0 and d2 < 0.0:
                index = 1
            else:
                touching = False
            if touching:
                t_next = t
            finite = math.isfinite(g1) and math.isfinite(g2) and math.isfinite(d1) and math.isfinite(d2)
            hopeless = not (math.isfinite(t_next) and finite)
            done = touching or converged or hopeless
            t = t_next
            steps += 1
        return t, index, steps, done

    @jit
    def rotor_contact_time_sharper(R, ell, x, y, a, vx, vy, om):
        speed = math.sqrt(vx * vx + vy * vy)
        spin = abs(om)
        centre_radius = math.sqrt(x * x + y * y)
        quiet_in, quiet_out = disc_crossing(x, y, vx, vy, R - ell)
        reach = larger(math.sqrt(R * R - ell * ell), centre_radius)
        wobble = 2.0 * ell * (2.0 * spin * speed + spin * spin * reach)
        lower_curv = 2.0 * speed * speed + wobble
        upper_curv = wobble - 2.0 * speed * speed
        # g_k''' = -2 k ell W''' with |W'''| <= 3 omega^2 |v| + |omega|^3 |c(t)| (_rotor_bounds).
        jerk = 2.0 * ell * (spin * spin * (3.0 * speed + spin * reach))
        rate = speed / R + spin
        time_scale = 1.0 / rate if rate > 0.0 else INF
        bounds = (lower_curv, upper_curv, quiet_in, quiet_out)
        return rotor_first_root_sharper(R, ell, x, y, a, vx, vy, om, bounds, time_scale, jerk)

    @jit
    def stick_end(R, ell, end, ux, uy, x, y, vx, vy, om):
        """Gap R^2 - |P|^2 of the end ``end`` (+1 or -1) and its speed towards the wall."""
        px, py = x + end * (ell * ux), y + end * (ell * uy)
        turn = ell * om
        evx, evy = vx - end * (turn * uy), vy + end * (turn * ux)
        gap = R * R - (px * px + py * py)
        return gap, (px * evx + py * evy) / math.sqrt(px * px + py * py)

    @jit
    def stick_kick(R, ell, ratio, end, ux, uy, x, y, vx, vy, om):
        arm = end * ell
        scale = KICK_NORMAL_SCALE / R
        nx, ny = scale * (x + arm * ux), scale * (y + arm * uy)
        s = arm * (ux * ny - uy * nx)
        v_n = vx * nx + vy * ny + om * s
        change = 2.0 * v_n / (nx * nx + ny * ny + ratio * (s * s))
        return vx - change * nx, vy - change * ny, om - (change * ratio) * s

    @jit
    def resolve_stick(R, ell, ratio, index, ux, uy, x, y, vx, vy, om):
        end = 1.0 if index == 0 else -1.0
        other_gap, other_speed = stick_end(R, ell, -end, ux, uy, x, y, vx, vy, om)
        corner = other_gap <= CORNER_ULPS * (R * R) and other_speed > 0.0
        first = end
        if corner:
            _, own_speed = stick_end(R, ell, end, ux, uy, x, y, vx, vy, om)
            if other_speed > own_speed:
                first = -end
        vx, vy, om = stick_kick(R, ell, ratio, first, ux, uy, x, y, vx, vy, om)
        if corner:
            _, still = stick_end(R, ell, -first, ux, uy, x, y, vx, vy, om)
            if still > 0.0:
                vx, vy, om = stick_kick(R, ell, ratio, -first, ux, uy, x, y, vx, vy, om)
            return vx, vy, om, SEVERAL_CONTACTS
        return vx, vy, om, (1 if index == 0 else -1)

    @jit
    def rotor_collide(sharper, R, ell, mass, inertia, x, y, a, vx, vy, om):
        if sharper:
            t, index, steps, ok = rotor_contact_time_sharper(R, ell, x, y, a, vx, vy, om)
        else:
            t, index, steps, ok = rotor_contact_time(R, ell, x, y, a, vx, vy, om)
        if not ok:
            return NAN, NAN, NAN, NAN, NAN, NAN, NAN, NO_CONTACT, steps
        if not math.isfinite(t):
            return x, y, a, vx, vy, om, t, NO_CONTACT, steps
        x, y, a = x + vx * t, y + vy * t, wrap_angle(a + om * t)
        ux, uy = math.cos(a), math.sin(a)
        ratio = mass * (1.0 / inertia)
        vx, vy, om, contact = resolve_stick(R, ell, ratio, index, ux, uy, x, y, vx, vy, om)
        return x, y, a, vx, vy, om, t, contact, steps

    @jit
    def lens_collide(R, ell, ux, uy, x, y, a, vx, vy, om):
        t1 = exit_time(x + ell * ux, y + ell * uy, vx, vy, R)
        t2 = exit_time(x - ell * ux, y - ell * uy, vx, vy, R)
        index, t = (1, t2) if t2 < t1 else (0, t1)
        if not math.isfinite(t):
            return x, y, a, vx, vy, om, t, NO_CONTACT, 0
        x, y = x + vx * t, y + vy * t
        vx, vy, om, contact = resolve_stick(R, ell, 0.0, index, ux, uy, x, y, vx, vy, om)
        return x, y, a, vx, vy, om, t, contact, 0

    @jit
    def circle_collide(R, x, y, a, vx, vy, om):
        t = exit_time(x, y, vx, vy, R)
        if not math.isfinite(t):
            return x, y, a, vx, vy, om, t, NO_CONTACT, 0
        x, y, a = x + vx * t, y + vy * t, wrap_angle(a + om * t)
        scale = KICK_NORMAL_SCALE / R
        nx, ny = scale * x, scale * y
        change = 2.0 * (vx * nx + vy * ny) / (nx * nx + ny * ny)
        return x, y, a, vx - change * nx, vy - change * ny, om, t, 1, 0

    # -- the stick between two flat walls ---------------------------------------
    # Gaps, in order: P1 floor, P2 floor, P1 ceiling, P2 ceiling (codes 1, -1, 3, -3).

    @jit
    def walls_gaps(h, ell, z0, vz, along, turn_rate, spin2, t):
        if spin2 > 0.0:
            spin = math.sqrt(spin2)
            cos, sinc = math.cos(spin * t), math.sin(spin * t) / spin
        else:
            cos, sinc = 1.0, t
        a = along * cos + turn_rate * sinc
        a_slope = turn_rate * cos - along * spin2 * sinc
        z = z0 + vz * t
        z1, z2 = z + ell * a, z - ell * a
        d1, d2 = vz + ell * a_slope, vz - ell * a_slope
        return z1, z2, h - z1, h - z2, d1, d2, -d1, -d2

    @jit
    def band_crossing(z0, vz, low, high):
        if low >= high:  # a stick too long to turn over
            return INF, -INF
        if vz == 0.0:
            if z0 > low and z0 < high:
                return 0.0, INF
            return INF, -INF
        t_low, t_high = (low - z0) / vz, (high - z0) / vz
        return larger(smaller(t_low, t_high), 0.0), larger(t_low, t_high)

    @jit
    def fold_min(best_index, best, k, s):
        # argmin keeping the first of equal values
        if s < best:
            return k, s
        return best_index, best

    @jit
    def walls_first_root(h, ell, z0, vz, along, turn_rate, spin2, curv, quiet_in, quiet_out, time_scale):
        t = quiet_out if (quiet_in <= 0.0 and quiet_out > 0.0) else 0.0
        index = 0
        done = t == INF
        steps = 0
        while not done and steps < MAX_ROOT_STEPS:
            g0, g1, g2, g3, d0, d1, d2, d3 = walls_gaps(h, ell, z0, vz, along, turn_rate, spin2, t)
            c0, c1, c2, c3 = larger(g0, 0.0), larger(g1, 0.0), larger(g2, 0.0), larger(g3, 0.0)
            index, s = 0, step_below(c0, d0, curv)
            index, s = fold_min(index, s, 1, step_below(c1, d1, curv))
            index, s = fold_min(index, s, 2, step_below(c2, d2, curv))
            index, s = fold_min(index, s, 3, step_below(c3, d3, curv))
            g, slope = (c0, d0) if index == 0 else ((c1, d1) if index == 1 else ((c2, d2) if index == 2 else (c3, d3)))
            t_next = t + s
            if t_next >= quiet_in and t_next < quiet_out:
                t_next = quiet_out
            resolution = RESOLUTION_ULPS * larger(t, time_scale)
            converged = (step_above(g, slope, curv) - s <= resolution) or (t_next == t and slope < 0.0)
            touching = True
            if c0 == 0.0 and d0 < 0.0:
                index = 0
            elif c1 == 0.0 and d1 < 0.0:
                index = 1
            elif c2 == 0.0 and d2 < 0.0:
                index = 2
            elif c3 == 0.0 and d3 < 0.0:
                index = 3
            else:
                touching = False
            if touching:
                t_next = t
            finite = (
                math.isfinite(g0)
                and math.isfinite(g1)
                and math.isfinite(g2)
                and math.isfinite(g3)
                and math.isfinite(d0)
                and math.isfinite(d1)
                and math.isfinite(d2)
                and math.isfinite(d3)
            )
            hopeless = not (math.isfinite(t_next) and finite)
            done = touching or converged or hopeless
            t = t_next
            steps += 1
        return t, index, steps, done

    @jit
    def walls_contact_time(h, ell, z, theta, vz, om):
        along, turn_rate, spin2 = math.cos(theta), -om * math.sin(theta), om * om
        if spin2 > 0.0:
            amp = math.sqrt(along * along + turn_rate * turn_rate / spin2)
        else:
            amp = math.sqrt(along * along + 0.0)
        amp = smaller(amp * AMPLITUDE_PAD, 1.0)
        reach = ell * amp
        curv = reach * spin2
        quiet_in, quiet_out = band_crossing(z, vz, reach, h - reach)
        rate = abs(vz) / h + math.sqrt(spin2)
        time_scale = 1.0 / rate if rate > 0.0 else INF
        return walls_first_root(h, ell, z, vz, along, turn_rate, spin2, curv, quiet_in, quiet_out, time_scale)

    @jit
    def walls_gap_and_speed(h, ell, k, z, theta, vz, om):
        """Gap ``k`` (0..3) at the state and its closing speed (> 0 approaching)."""
        reach = ell * math.cos(theta)
        turn = ell * math.sin(theta) * om
        if k % 2 == 0:
            height, rise = z + reach, vz - turn
        else:
            height, rise = z - reach, vz + turn
        if k < 2:
            return height, -rise
        return h - height, rise

    @jit
    def walls_kick(ell, inv_mass, inv_inertia, k, theta, vz, om):
        end = 1.0 if k % 2 == 0 else -1.0
        lever = -end * ell * math.sin(theta)
        impulse = -2.0 * (vz + lever * om) / (inv_mass + lever * lever * inv_inertia)
        return vz + impulse * inv_mass, om + impulse * inv_inertia * lever

    @jit
    def resolve_walls(h, ell, inv_mass, inv_inertia, index, z, theta, vz, om):
        other_end = 1 - index % 2
        near_floor, _ = walls_gap_and_speed(h, ell, other_end, z, theta, vz, om)
        near_ceiling, _ = walls_gap_and_speed(h, ell, other_end + 2, z, theta, vz, om)
        other = other_end if near_floor <= near_ceiling else other_end + 2
        other_gap, other_speed = walls_gap_and_speed(h, ell, other, z, theta, vz, om)
        several = other_gap <= CORNER_ULPS * h and other_speed > 0.0
        first = index
        if several:
            _, own_speed = walls_gap_and_speed(h, ell, index, z, theta, vz, om)
            if other_speed > own_speed:
                first = other
        second = other if first == index else index
        vz, om = walls_kick(ell, inv_mass, inv_inertia, first, theta, vz, om)
        if several:
            _, still = walls_gap_and_speed(h, ell, second, z, theta, vz, om)
            if still > 0.0:
                vz, om = walls_kick(ell, inv_mass, inv_inertia, second, theta, vz, om)
            return vz, om, SEVERAL_CONTACTS
        code = 1 if index % 2 == 0 else -1
        return vz, om, (code if index < 2 else 3 * code)

    @jit
    def walls_static_contact_time(h, ell, z, theta, vz, om):
        index, t = 0, INF
        for k in range(4):
            gap, speed = walls_gap_and_speed(h, ell, k, z, theta, vz, om)
            time = larger(gap, 0.0) / speed if speed > 0.0 else INF
            index, t = fold_min(index, t, k, time)
        return t, index

    @jit
    def walls_collide(turning, h, ell, mass, inertia, x, z, theta, vx, vz, om):
        if turning:
            t, index, steps, ok = walls_contact_time(h, ell, z, theta, vz, om)
        else:
            t, index = walls_static_contact_time(h, ell, z, theta, vz, om)
            steps, ok = 0, True
        if not ok:
            return NAN, NAN, NAN, NAN, NAN, NAN, NAN, NO_CONTACT, steps
        if not math.isfinite(t):
            return x, z, theta, vx, vz, om, t, NO_CONTACT, steps
        x, z = x + vx * t, z + vz * t
        if turning:
            theta = wrap_angle(theta + om * t)
        inv_inertia = 1.0 / inertia if turning else 0.0
        vz, om, contact = resolve_walls(h, ell, 1.0 / mass, inv_inertia, index, z, theta, vz, om)
        return x, z, theta, vx, vz, om, t, contact, steps

    @jit
    def collide(kind, size, ell, mass, inertia, ux, uy, x, y, a, vx, vy, om):
        if kind == ROTOR or kind == ROTOR_SHARPER:
            return rotor_collide(kind == ROTOR_SHARPER, size, ell, mass, inertia, x, y, a, vx, vy, om)
        if kind == LENS:
            return lens_collide(size, ell, ux, uy, x, y, a, vx, vy, om)
        if kind == CIRCLE:
            return circle_collide(size, x, y, a, vx, vy, om)
        return walls_collide(kind == WALLS_ROTOR, size, ell, mass, inertia, x, y, a, vx, vy, om)

    return types.SimpleNamespace(
        collide=collide,
        orbit_direction=orbit_direction,
        rotor_contact_time=rotor_contact_time,
        rotor_contact_time_sharper=rotor_contact_time_sharper,
        walls_contact_time=walls_contact_time,
    )


# Division by zero gives inf/NaN as in numpy rather than raising: the guards
# above make it rare, but a poisoned (NaN) orbit must run on quietly.
@numba.njit
def _fmod(a, b):
    return np.fmod(a, b)


_cpu = make_engine(numba.njit(error_model="numpy"), _fmod)
_collide = _cpu.collide
_orbit_direction = _cpu.orbit_direction


@numba.njit(error_model="numpy")
def orbit(params, state0, n):
    """The first ``n`` collisions of one orbit.

    Args:
        params: ``(5,)`` float64 ``[kind, size, ell, mass, inertia]`` (module docstring).
        state0: ``(6,)`` float64 initial state.
        n: number of collisions.

    Returns:
        ``(t, contact, states, root_steps)``: ``(n,)`` absolute collision times,
        ``(n,)`` int32 contact codes, ``(n, 6)`` states just after each
        collision, ``(n,)`` int32 safe steps of each collision's root search.
    """
    kind, size, ell, mass, inertia = int(params[0]), params[1], params[2], params[3], params[4]
    times = np.empty(n)
    contacts = np.empty(n, np.int32)
    states = np.empty((n, 6))
    root_steps = np.empty(n, np.int32)
    x, y, a, vx, vy, om = state0[0], state0[1], state0[2], state0[3], state0[4], state0[5]
    ux, uy = _orbit_direction(kind, a)
    t = 0.0
    for i in range(n):
        x, y, a, vx, vy, om, dt, contact, steps = _collide(kind, size, ell, mass, inertia, ux, uy, x, y, a, vx, vy, om)
        t = t + dt
        times[i] = t
        contacts[i] = contact if t == t else NO_CONTACT
        states[i, 0], states[i, 1], states[i, 2] = x, y, a
        states[i, 3], states[i, 4], states[i, 5] = vx, vy, om
        root_steps[i] = steps
    return times, contacts, states, root_steps


@numba.njit(error_model="numpy")
def collision_map(params, states):
    """One collision from each of ``m`` states ``(m, 6)``, independently.

    Returns ``(states_after (m, 6), dt (m,), contact (m,) int32, root_steps (m,)
    int32)``. The lens's direction is taken from each state's own angle (it
    never changes along an orbit).
    """
    kind, size, ell, mass, inertia = int(params[0]), params[1], params[2], params[3], params[4]
    m = states.shape[0]
    after = np.empty((m, 6))
    flights = np.empty(m)
    contacts = np.empty(m, np.int32)
    root_steps = np.empty(m, np.int32)
    for i in range(m):
        x, y, a, vx, vy, om = states[i, 0], states[i, 1], states[i, 2], states[i, 3], states[i, 4], states[i, 5]
        ux, uy = _orbit_direction(kind, a)
        x, y, a, vx, vy, om, dt, contact, steps = _collide(kind, size, ell, mass, inertia, ux, uy, x, y, a, vx, vy, om)
        after[i, 0], after[i, 1], after[i, 2], after[i, 3], after[i, 4], after[i, 5] = x, y, a, vx, vy, om
        flights[i], contacts[i], root_steps[i] = dt, contact, steps
    return after, flights, contacts, root_steps


@numba.njit(error_model="numpy")
def _final_state(params, states0, i, n, final_states, final_times, collisions, root_steps):
    kind, size, ell, mass, inertia = int(params[0]), params[1], params[2], params[3], params[4]
    x, y, a, vx, vy, om = states0[i, 0], states0[i, 1], states0[i, 2], states0[i, 3], states0[i, 4], states0[i, 5]
    ux, uy = _orbit_direction(kind, a)
    t = 0.0
    hits = 0
    steps_total = 0
    for _ in range(n):
        x, y, a, vx, vy, om, dt, contact, steps = _collide(kind, size, ell, mass, inertia, ux, uy, x, y, a, vx, vy, om)
        t = t + dt
        if contact != NO_CONTACT:
            hits += 1
        steps_total += steps
    final_states[i, 0], final_states[i, 1], final_states[i, 2] = x, y, a
    final_states[i, 3], final_states[i, 4], final_states[i, 5] = vx, vy, om
    final_times[i] = t
    collisions[i] = hits
    root_steps[i] = steps_total


def _batch_outputs(batch):
    return np.empty((batch, 6)), np.empty(batch), np.empty(batch, np.int64), np.empty(batch, np.int64)


@numba.njit(error_model="numpy")
def _run_batch_serial(params, states0, n, final_states, final_times, collisions, root_steps):
    for i in range(states0.shape[0]):
        _final_state(params, states0, i, n, final_states, final_times, collisions, root_steps)


@numba.njit(error_model="numpy", parallel=True)
def _run_batch_parallel(params, states0, n, final_states, final_times, collisions, root_steps):
    for i in numba.prange(states0.shape[0]):
        _final_state(params, states0, i, n, final_states, final_times, collisions, root_steps)


def run_batch(params, states0, n):
    """``n`` collisions of each of ``B`` orbits on one core, keeping only the end.

    Args:
        params: ``(5,)`` scene (module docstring); states0: ``(B, 6)``; n: collisions per orbit.

    Returns:
        ``(final_states (B, 6), final_times (B,), collisions (B,) int64,
        root_steps (B,) int64)``: the state after the last collision, its
        absolute time, the collisions that reached a wall, the safe steps in all.
    """
    outputs = _batch_outputs(states0.shape[0])
    _run_batch_serial(params, states0, n, *outputs)
    return outputs


def run_batch_parallel(params, states0, n, threads=None):
    """``run_batch`` over ``threads`` cores (``numba.prange``; default: numba's thread count)."""
    if threads is not None:
        numba.set_num_threads(threads)
    outputs = _batch_outputs(states0.shape[0])
    _run_batch_parallel(params, states0, n, *outputs)
    return outputs


# -- scenes and valid random states ------------------------------------------------


def circle_params(R, ell, mass=1.0, inertia=None, sharper_steps=False):
    """``params`` of ``StickInCircle(R, ell, mass, inertia)`` (``inertia=None``: ``mass ell^2``).

    ``sharper_steps``: for the spinning stick, the loop with jaxbill's sharper
    steps (``ROTOR_SHARPER``) rather than the flight's curvature bounds alone.
    """
    if ell == 0.0:
        kind = CIRCLE
    elif inertia is not None and math.isinf(inertia):
        kind = LENS
    else:
        kind = ROTOR_SHARPER if sharper_steps else ROTOR
    inertia = mass * ell * ell if inertia is None else inertia
    return np.array([kind, R, ell, mass, inertia], dtype=np.float64)


def walls_params(h, ell, mass=1.0, inertia=None):
    """``params`` of ``StickBetweenWalls2D(h, ell, mass, inertia)``."""
    kind = WALLS_STATIC if inertia is not None and math.isinf(inertia) else WALLS_ROTOR
    inertia = mass * ell * ell if inertia is None else inertia
    return np.array([kind, h, ell, mass, inertia], dtype=np.float64)


def jaxbill_scene(params):
    """The jaxbill scene that ``params`` describes (imports jaxbill)."""
    import jaxbill as jb  # only the checks and the benchmark need it

    kind, size, ell, mass, inertia = int(params[0]), *map(float, params[1:])
    if kind in (WALLS_ROTOR, WALLS_STATIC):
        return jb.StickBetweenWalls2D(size, ell, mass, inertia)
    if kind == CIRCLE:
        return jb.StickInCircle(size, 0.0, mass)
    return jb.StickInCircle(size, ell, mass, inertia)


def random_states(params, count, seed=0, margin=1e-3):
    """``count`` valid states ``(count, 6)``: both ends inside by ``margin`` (times ``size``).

    Unit speed in a uniform direction; spin uniform in ``[-3, 3] / size`` (as the
    test helpers draw it), zero for the lens and the static walls.
    """
    kind, size, ell = int(params[0]), float(params[1]), float(params[2])
    rng = np.random.default_rng(seed)
    rows = []
    while sum(len(r) for r in rows) < count:
        m = 2 * count + 16
        angle = rng.uniform(-np.pi, np.pi, m)
        heading = rng.uniform(-np.pi, np.pi, m)
        spin = rng.uniform(-3.0, 3.0, m) / size
        if kind in (LENS, WALLS_STATIC):
            spin[:] = 0.0
        if kind in (WALLS_ROTOR, WALLS_STATIC):
            first = rng.uniform(-size, size, m)
            height = rng.uniform(0.0, size, m)
            reach = ell * np.abs(np.cos(angle))
            inside = (height - reach >= margin * size) & (height + reach <= (1.0 - margin) * size)
        else:
            radius = size * np.sqrt(rng.uniform(0.0, 1.0, m))
            polar = rng.uniform(-np.pi, np.pi, m)
            first, height = radius * np.cos(polar), radius * np.sin(polar)
            limit = (1.0 - margin) * size
            inside = (np.hypot(first + ell * np.cos(angle), height + ell * np.sin(angle)) <= limit) & (
                np.hypot(first - ell * np.cos(angle), height - ell * np.sin(angle)) <= limit
            )
        block = np.stack([first, height, angle, np.cos(heading), np.sin(heading), spin], axis=1)
        rows.append(block[inside])
    return np.ascontiguousarray(np.concatenate(rows)[:count])


# -- agreement with jaxbill -------------------------------------------------------

CHECK_SCENES = {
    "rotor R=2 ell=1.9": circle_params(2.0, 1.9),
    "rotor R=2 ell=1.0": circle_params(2.0, 1.0),
    "rotor R=2 ell=1.9, sharper steps": circle_params(2.0, 1.9, sharper_steps=True),
    "rotor R=2 ell=1.0, sharper steps": circle_params(2.0, 1.0, sharper_steps=True),
    "lens R=2 ell=1.5": circle_params(2.0, 1.5, inertia=math.inf),
    "circle R=2": circle_params(2.0, 0.0),
    "walls h=3 ell=1": walls_params(3.0, 1.0),
    "walls h=3 ell=1 static": walls_params(3.0, 1.0, inertia=math.inf),
}


def jaxbill_root_steps(params, states_before):
    """Steps of jaxbill's own root search from each state ``(m, 6)`` (private API; 0 for closed forms).

    Uses the scene's own ``root_search``/``gaps_along_flight`` (``jaxbill._engine.step``).
    """
    import jax
    import jax.numpy as jnp

    from jaxbill._engine.first_root import first_root
    from jaxbill._engine.step import MAX_ROOT_STEPS as jaxbill_max_steps
    from jaxbill._engine.step import components

    scene = jaxbill_scene(params)
    kind = int(params[0])
    if kind not in (ROTOR, ROTOR_SHARPER, WALLS_ROTOR):
        return np.zeros(len(states_before), np.int64)

    def steps(state):
        profile, bounds = scene.root_search(components(state))
        return first_root(lambda t: scene.gaps_along_flight(profile, t), bounds, jaxbill_max_steps)[2]

    return np.asarray(jax.jit(jax.vmap(steps))(jnp.asarray(states_before)))


def check_against_jaxbill(collisions=20, orbits=8, long_collisions=2000, seed=1, show=True):
    """Run the numba loop and ``jb.orbit`` from identical states, collision by collision.

    For each scene of ``CHECK_SCENES`` and ``orbits`` random states, over the
    first ``collisions`` collisions:

    * one step: numba's collision map applied to jaxbill's state before each
      collision, against jaxbill's state after it (the two implementations'
      own difference, free of chaotic growth): the largest relative state
      difference (``agreement.relative_difference``) and flight-time difference, whether
      the contact codes are the same, and the root steps per collision of each
      (jaxbill's counted with its private search);
    * orbits: the largest relative state difference of the two orbits run
      independently (rounding differences grow with the Lyapunov exponent),
      whether their contact codes agree, and the first collision at which they
      are more than 1e-6 apart in ``long_collisions`` (the chaos horizon);
    * numba's root steps per collision (mean and largest) along its orbits.

    Returns a list of dicts, one per scene; prints a markdown table if ``show``.
    """
    import jax.numpy as jnp

    import jaxbill as jb

    rows = []
    for label, params in CHECK_SCENES.items():
        scene = jaxbill_scene(params)
        row = {
            "scene": label,
            "step_state_diff": 0.0,
            "step_time_diff": 0.0,
            "same_step_contacts": True,
            "numba_one_step_root_steps": 0,
            "jaxbill_one_step_root_steps": 0,
            "orbit_state_diff": 0.0,
            "same_orbit_contacts": True,
        }
        numba_steps, horizons = [], []
        for state0 in random_states(params, orbits, seed=seed):
            reference = jb.orbit(scene, jnp.asarray(state0), long_collisions)
            ref_t, ref_contact = np.asarray(reference.t), np.asarray(reference.contact)
            ref_state = np.asarray(reference.state)
            before = np.concatenate([state0[None], ref_state[: collisions - 1]])
            ref_dt = np.diff(np.concatenate([[0.0], ref_t[:collisions]]))
            after, dt, contact, steps = collision_map(params, before)
            state_diff = float(relative_difference(after, ref_state[:collisions]).max())
            row["step_state_diff"] = max(row["step_state_diff"], state_diff)
            row["step_time_diff"] = max(row["step_time_diff"], float((np.abs(dt - ref_dt) / np.abs(ref_dt)).max()))
            row["same_step_contacts"] &= bool(np.array_equal(contact, ref_contact[:collisions]))
            row["numba_one_step_root_steps"] += int(steps.sum())
            row["jaxbill_one_step_root_steps"] += int(jaxbill_root_steps(params, before).sum())

            _, contact, states, root_steps = orbit(params, state0, long_collisions)
            diff = relative_difference(states, ref_state)
            row["orbit_state_diff"] = max(row["orbit_state_diff"], float(diff[:collisions].max()))
            row["same_orbit_contacts"] &= bool(np.array_equal(contact[:collisions], ref_contact[:collisions]))
            apart = np.nonzero((diff > 1e-6) | (contact != ref_contact))[0]
            horizons.append(int(apart[0]) + 1 if len(apart) else long_collisions + 1)
            numba_steps.append(root_steps)
        numba_steps = np.concatenate(numba_steps)
        row["root_steps_per_collision"] = float(numba_steps.mean())
        row["max_root_steps"] = int(numba_steps.max())
        row["horizon"] = min(horizons)
        rows.append(row)
    if show:
        print(f"numba loop vs jb.orbit: {orbits} random orbits per scene, first {collisions} collisions")
        print()
        print(
            "| scene | one step: rel. state diff | one step: rel. flight-time diff | same contacts "
            "| one step: root steps / collision (numba, jaxbill) "
            f"| orbits: rel. state diff | same contacts | first collision > 1e-6 apart (of {long_collisions}) "
            "| numba root steps / collision (max) |"
        )
        print("|---|---|---|---|---|---|---|---|---|")
        checked = orbits * collisions
        for r in rows:
            horizon = "none" if r["horizon"] > long_collisions else str(r["horizon"])
            print(
                f"| {r['scene']} | {r['step_state_diff']:.1e} | {r['step_time_diff']:.1e} "
                f"| {r['same_step_contacts']} "
                f"| {r['numba_one_step_root_steps'] / checked:.2f}, {r['jaxbill_one_step_root_steps'] / checked:.2f} "
                f"| {r['orbit_state_diff']:.1e} | {r['same_orbit_contacts']} | {horizon} "
                f"| {r['root_steps_per_collision']:.2f} ({r['max_root_steps']}) |"
            )
    return rows


if __name__ == "__main__":
    rows = check_against_jaxbill()
    ok = all(r["same_step_contacts"] and r["same_orbit_contacts"] and r["step_state_diff"] < 1e-13 for r in rows)
    sys.exit(0 if ok else 1)
