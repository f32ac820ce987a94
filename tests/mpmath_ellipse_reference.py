"""Independent high-precision reference for the stick in an ellipse.

Written with mpmath only, from the physics (``physics.md``'s mass-metric
reflection applied to the table ``F(P) = x^2/a^2 + y^2/b^2 - 1 <= 0``), using
no jaxbill code and not its formulas: the gap here is ``h = -F`` itself
(dimensionless, not jaxbill's ``ab (1 - ...)``), the root isolation uses one
crude global bound per flight and no quiet region, and the impulse is the
generic reflection formula in the configuration ``q = (x, y, alpha)``.

Model
-----
Stick of half-length ``ell``, mass ``M``, moment of inertia ``I`` about its
centre (``None``: ``M ell^2``; ``inf``: it never turns). State
``[x, y, alpha, vx, vy, omega]``; ends ``P_k = c + k ell u``, ``u = (cos alpha,
sin alpha)``, ``k = +1`` (P1), ``-1`` (P2). Free flight ``c + v t``,
``alpha + omega t``. A collision is the first ``t > 0`` at which some
``h_k(t) = -F(P_k(t))`` reaches zero while decreasing.

Root isolation (rigorous stepping)
----------------------------------
``h = 1 - Px^2/a^2 - Py^2/b^2``,
``h' = -2 (Px P'x / a^2 + Py P'y / b^2)``,
``h'' = -2 (P'x^2/a^2 + P'y^2/b^2) - 2 (Px P''x / a^2 + Py P''y / b^2)``
with ``P' = v + k ell omega u_perp`` (``|P'| <= |v| + ell |omega|``) and
``P'' = -k ell omega^2 u`` (``|P''| = ell omega^2``). With ``m = min(a, b)``:
``P'x^2/a^2 + P'y^2/b^2 <= |P'|^2 / m^2``, and while ``P`` is inside the
ellipse ``|(Px/a^2, Py/b^2)|^2 = (Px/a)^2/a^2 + (Py/b)^2/b^2 <= 1/m^2``. So
``|h''| <= A = 2 (|v| + ell |omega|)^2 / m^2 + 2 ell omega^2 / m`` until the
first root. From ``t`` with ``h = h0 >= 0``, ``h' = h1``: ``h(t + s) >= h0 +
h1 s - A s^2 / 2`` up to the first zero, so ``h`` has no zero before the
positive root ``s*`` of the right side, and the step ``t <- t + s*`` cannot
pass the first root. Once ``h0`` is below ``10^-(dps - 6)`` and falling, the
root is polished with Newton's method; the polished root is accepted only if
``h`` is positive a little before it (``h(t* - 10^-(dps/2) T) > 0``: a
bracket) and ``h' < 0`` there.

The end that just bounced sits at ``h = 0`` moving inwards; its search starts
from ``h0 = 0`` exactly, so its root at ``t = 0`` is excluded.

Impulse: with ``G = grad_q F`` at the contact (``dF/dx = 2 Px/a^2``,
``dF/dy = 2 Py/b^2``, ``dF/dalpha = grad_P F . k ell u_perp``), ``W =
diag(1/M, 1/M, 1/I)`` (``1/I = 0`` for ``I = inf`` or ``ell = 0``),
``qdot' = qdot - 2 (G . qdot) / (G . W G) W G``: the specular reflection in
the mass-weighted configuration space.

Both ends within ``SIMULTANEOUS_TOL`` (relative to the time scale): the
faster-approaching end first (approach speed ``G . qdot / |grad_P F|``), then
alternately while either approaches; contact code 2.

Self-checks at every collision: energy to ``10^-(dps - 5)`` relative and
``|h_k| <= 10^-(dps - 5)`` at the touching end(s).
"""

from __future__ import annotations

import mpmath
from mpmath import mp, mpf

__all__ = ["reference_orbit", "flow", "energy", "gap", "focal_product", "angular_momentum", "impulse"]

SIMULTANEOUS_TOL = mpf("1e-28")


def _is_inf(x):
    return mpmath.isinf(x)


def params(a, b, ell, mass, inertia):
    a, b, ell, mass = mpf(a), mpf(b), mpf(ell), mpf(mass)
    if inertia is None:
        inertia = mass * ell**2
    elif inertia == "inf" or mpmath.isinf(mpf(inertia)):
        inertia = mpmath.inf
    else:
        inertia = mpf(inertia)
    if not (a > 0 and b > 0):
        raise ValueError("a and b must be > 0")
    if not (0 <= ell < max(a, b)):
        raise ValueError("ell must satisfy 0 <= ell < max(a, b)")
    if not (mass > 0):
        raise ValueError("mass must be > 0")
    if ell > 0 and not (inertia > 0):
        raise ValueError("inertia must be > 0 (or inf)")
    return a, b, ell, mass, inertia


def _spin_free(ell, inertia):
    return ell == 0 or _is_inf(inertia)


def energy(mass, inertia, state):
    e = mass * (state[3] ** 2 + state[4] ** 2) / 2
    if not _is_inf(inertia) and state[5] != 0:
        e += inertia * state[5] ** 2 / 2
    return e


def angular_momentum(mass, inertia, state):
    """``M (x vy - y vx) + I omega`` about the table's centre (orbital part only for ``I = inf``)."""
    x, y, _, vx, vy, w = state
    lz = mass * (x * vy - y * vx)
    if not _is_inf(inertia) and w != 0:
        lz += inertia * w
    return lz


def focal_product(a, b, mass, state):
    """Product of the centre's orbital angular momenta about the two foci."""
    x, y, _, vx, vy, _ = state
    f = mpmath.sqrt(abs(a * a - b * b))
    fx, fy = (f, 0) if a >= b else (0, f)
    l1 = mass * ((x - fx) * vy - (y - fy) * vx)
    l2 = mass * ((x + fx) * vy - (y + fy) * vx)
    return l1 * l2


def flow(state, t):
    x, y, al, vx, vy, w = state
    return [x + vx * t, y + vy * t, al + w * t, vx, vy, w]


def _end(state, ell, k, t):
    x, y, al, vx, vy, w = state
    cs, sn = mp.cos_sin(al + w * t)
    px, py = x + vx * t + k * ell * cs, y + vy * t + k * ell * sn
    dpx, dpy = vx - k * ell * w * sn, vy + k * ell * w * cs
    return px, py, dpx, dpy


def gap(a, b, ell, state, k, t=0):
    """``h_k(t) = 1 - Px^2/a^2 - Py^2/b^2`` and its time derivative."""
    px, py, dpx, dpy = _end(state, ell, k, t)
    return 1 - (px / a) ** 2 - (py / b) ** 2, -2 * (px * dpx / a**2 + py * dpy / b**2)


def _first_root(a, b, ell, state, k, t_cap, just_bounced, time_scale, max_steps):
    """First ``t > 0`` at which ``h_k`` reaches zero while falling, or ``None`` before ``t_cap``."""
    vx, vy, w = state[3], state[4], state[5]
    m = min(a, b)
    reach = mpmath.sqrt(vx * vx + vy * vy) + ell * abs(w)
    A = 2 * reach**2 / m**2 + 2 * ell * w * w / m
    if A == 0:
        return None
    polish_below = mpf(10) ** (-(mp.dps - 6))
    t = mpf(0)
    h0, h1 = gap(a, b, ell, state, k, t)
    if just_bounced:
        if not h1 > 0:
            raise ArithmeticError(f"end {k} just bounced but is not moving inward (h' = {h1})")
        h0 = mpf(0)
    steps = 0
    while not (h0 <= polish_below and h1 < 0):
        s = (h1 + mpmath.sqrt(h1 * h1 + 2 * A * max(h0, mpf(0)))) / A
        t += s
        if t >= t_cap:
            return None
        h0, h1 = gap(a, b, ell, state, k, t)
        steps += 1
        if steps > max_steps:
            raise ArithmeticError(f"root isolation did not converge (end {k})")
    for _ in range(20):
        dt = -h0 / h1
        t += dt
        h0, h1 = gap(a, b, ell, state, k, t)
        if abs(dt) <= mpf(10) ** (-(mp.dps - 3)) * (time_scale + abs(t)):
            break
    before, slope_before = gap(a, b, ell, state, k, t - mpf(10) ** (-(mp.dps // 2)) * time_scale)
    if not (before > 0 and h1 < 0 and slope_before < 0 and t > 0):
        raise ArithmeticError(f"polished root of end {k} is not a bracketed falling root")
    return t if t < t_cap else None


def _configuration_gradient(a, b, ell, state, k):
    """``grad_q F`` at the state for end ``k`` and ``|grad_P F|``."""
    x, y, al = state[0], state[1], state[2]
    cs, sn = mp.cos_sin(al)
    px, py = x + k * ell * cs, y + k * ell * sn
    fx, fy = 2 * px / a**2, 2 * py / b**2
    falpha = fx * (-k * ell * sn) + fy * (k * ell * cs)
    return [fx, fy, falpha], mpmath.sqrt(fx * fx + fy * fy)


def approach_speed(a, b, ell, state, k):
    """Velocity of end ``k`` along the outward unit normal (``> 0`` approaching the wall)."""
    G, norm = _configuration_gradient(a, b, ell, state, k)
    return sum(g * q for g, q in zip(G, state[3:])) / norm


def impulse(a, b, ell, mass, inertia, state, k):
    """Mass-metric reflection of the velocities about ``grad_q F`` of end ``k``; returns the new state."""
    G, _ = _configuration_gradient(a, b, ell, state, k)
    weights = [1 / mass, 1 / mass, mpf(0) if _spin_free(ell, inertia) else 1 / inertia]
    qdot = state[3:]
    along = sum(g * q for g, q in zip(G, qdot))
    norm2 = sum(g * g * wt for g, wt in zip(G, weights))
    factor = 2 * along / norm2
    return state[:3] + [q - factor * wt * g for q, wt, g in zip(qdot, weights, G)]


def reference_orbit(a, b, ell, mass, inertia, state0, n, dps=45, max_steps=5_000_000, bounced=()):
    """First ``n`` collisions from ``state0`` (six numbers, floats taken exactly).

    Returns ``(times, states, contacts)``: absolute collision times, states just
    after each collision (lists of 6 mpf) and contact codes (+1 P1, -1 P2,
    2 both; +1 for a point). ``bounced``: ends that start on the wall moving
    inwards (their root at ``t = 0`` is excluded).
    """
    with mp.workdps(dps):
        a, b, ell, mass, inertia = params(a, b, ell, mass, inertia)
        state = [mpf(v) for v in state0]
        if _is_inf(inertia) and ell > 0 and state[5] != 0:
            raise ValueError("a stick that never turns needs omega == 0")
        e0 = energy(mass, inertia, state)
        speed = mpmath.sqrt(state[3] ** 2 + state[4] ** 2)
        time_scale = mpmath.sqrt(a * b) / (speed + mpmath.sqrt(a * b) * abs(state[5]) + mpf(10) ** -30)
        t_max = mpf(10) ** 6 * time_scale
        tol = mpf(10) ** (-(dps - 5))
        ends = (1,) if ell == 0 else (1, -1)
        bounced = set(bounced) & set(ends)
        for k in ends:
            h0, h1 = gap(a, b, ell, state, k)
            if k in bounced:
                if abs(h0) > mpf("1e-10") or h1 <= 0:
                    raise ValueError(f"end {k} is not on the wall moving inward")
            elif h0 < 0:
                raise ValueError(f"end {k} starts outside the ellipse")
        times, states, contacts = [], [], []
        t_abs = mpf(0)
        for _ in range(n):
            roots = {}
            cap = t_max
            for k in ends:
                tk = _first_root(a, b, ell, state, k, cap, k in bounced, time_scale, max_steps)
                if tk is not None:
                    roots[k] = tk
                    cap = min(cap, tk + 2 * SIMULTANEOUS_TOL * time_scale)
            if not roots:
                raise RuntimeError("no collision before t_max")
            t_hit = min(roots.values())
            hit = [k for k in roots if roots[k] - t_hit <= SIMULTANEOUS_TOL * time_scale]
            state = flow(state, t_hit)
            if len(hit) == 1:
                (k,) = hit
                if not approach_speed(a, b, ell, state, k) > 0:
                    raise ArithmeticError("contact without approach")
                state = impulse(a, b, ell, mass, inertia, state, k)
                contact = k
            else:
                order = sorted(hit, key=lambda k: -approach_speed(a, b, ell, state, k))
                state = impulse(a, b, ell, mass, inertia, state, order[0])
                count = 1
                while approach_speed(a, b, ell, state, order[count % 2]) > 0:
                    state = impulse(a, b, ell, mass, inertia, state, order[count % 2])
                    count += 1
                    if count > 1000:
                        raise ArithmeticError("corner impulses do not terminate")
                contact = 2
            bounced = set(hit)
            for k in hit:
                assert abs(gap(a, b, ell, state, k)[0]) <= tol, "contact off the wall"
            assert abs(energy(mass, inertia, state) - e0) <= tol * e0, "energy drift"
            t_abs += t_hit
            times.append(+t_abs)
            states.append(list(state))
            contacts.append(contact)
        return times, states, contacts
