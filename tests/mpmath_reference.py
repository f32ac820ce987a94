"""Independent high-precision reference for the stick-in-a-circle collision map.

Written with mpmath only, from the physics (``physics.md``), without any jaxbill
code, so that the library's tests compare against something that can fail
differently.

Model
-----
Circle of radius ``R`` at the origin; stick of half-length ``ell``, mass ``M``,
moment of inertia ``I`` about its centre. State ``[x, y, alpha, vx, vy, omega]``;
``u = (cos alpha, sin alpha)``; ends ``P_k = c + k ell u`` with ``k = +1`` (P1)
and ``k = -1`` (P2). Free flight: ``c(t) = c + v t``, ``alpha(t) = alpha + omega t``.

Gap of end ``k``: ``g_k(t) = R^2 - |P_k(t)|^2``. A collision is the first
``t > 0`` where some ``g_k`` reaches zero while decreasing (end moving outward).

Impulse (derived from the mass-weighted specular reflection, configuration
``q = (x, y, alpha)``, ``Mq = diag(M, M, I)``): the gradient of ``g_k`` is
``-2 |P| (n, s_k)`` with ``n = P_k/|P_k|`` and ``s_k = k ell (u x n)``;
with ``v_n = v.n + omega s_k`` the reflection is
``J = 2 v_n / (1/M + s_k^2/I)``, ``v' = v - (J/M) n``, ``omega' = omega - (J/I) s_k``.

Root isolation (rigorous stepping)
----------------------------------
Along a flight ``P(t) = c + v t + k ell u(alpha + omega t)``:
``P' = v + k ell omega u_perp``, ``P'' = -k ell omega^2 u``, so
``g' = -2 P.P'`` and ``|g''| = 2 | |P'|^2 + P.P'' | <= A``,
``A = 2 ((|v| + ell|omega|)^2 + R ell omega^2)`` as long as ``|P| <= R``, i.e.
as long as ``g >= 0``.  From a time where ``g = g0 >= 0`` and ``g' = g1``,
Taylor with that bound gives ``g(t + s) >= g0 + g1 s - A s^2 / 2`` up to the
first zero of ``g``; therefore ``g`` has no zero before the positive root
``s* = (g1 + sqrt(g1^2 + 2 A g0)) / A`` of the right-hand side, and a step of
``s*`` cannot skip the first root (if ``g`` had a zero before ``s*``, at the
first one the bound would still hold and give ``g > 0``). The steps converge
to a simple root quadratically; once ``g`` is tiny the root is polished with
Newton's method. A second exclusion is used as a shortcut: while the centre is
inside the disc of radius ``R - ell`` no end can touch, so the stepper jumps to
the time the centre leaves that disc.

The end that just bounced sits at ``g = 0`` with ``g' > 0``; its search starts
from ``g0 = 0`` exactly (the rounding residue at the contact is discarded), so
the root at ``t = 0`` is excluded and a genuine re-collision of the same end
(chatter) is still found.

Both ends within ``SIMULTANEOUS_TOL`` (relative to the time scale ``R/V``): the
end with the larger approach speed is applied first, then the other one if it
still approaches, and so on alternately while either end approaches (with a
finite inertia the second impulse can make the first end approach again);
contact code 2.

Self-checks: energy and (for finite ``I``) the total angular momentum
``L = M (x vy - y vx) + I omega`` are asserted conserved to ``1e-45`` relative,
and ``|P_k| = R`` at every contact.
"""

from __future__ import annotations

import mpmath
from mpmath import mp, mpf

__all__ = ["reference_orbit", "flow", "energy", "angular_momentum", "gap"]

SIMULTANEOUS_TOL = mpf("1e-30")


def _is_inf(x):
    return x is not None and mpmath.isinf(x)


def _params(R, ell, mass, inertia):
    R = mpf(R)
    ell = mpf(ell)
    mass = mpf(mass)
    if inertia is None:
        inertia = mass * ell**2
    elif _is_inf(mpf(inertia)):
        inertia = mpmath.inf
    else:
        inertia = mpf(inertia)
    if not (R > 0):
        raise ValueError("R must be > 0")
    if not (0 <= ell < R):
        raise ValueError("ell must satisfy 0 <= ell < R")
    if not (mass > 0):
        raise ValueError("mass must be > 0")
    if ell > 0 and not (inertia > 0):
        raise ValueError("inertia must be > 0 (or inf) when ell > 0")
    return R, ell, mass, inertia


def energy(mass, inertia, state):
    """``M |v|^2 / 2 + I omega^2 / 2`` (the spin term is dropped for ``I = inf``)."""
    e = mass * (state[3] ** 2 + state[4] ** 2) / 2
    if not _is_inf(inertia):
        e += inertia * state[5] ** 2 / 2
    return e


def angular_momentum(mass, inertia, state):
    """``M (x vy - y vx) + I omega`` (orbital part only for ``I = inf``)."""
    x, y, _, vx, vy, w = state
    lz = mass * (x * vy - y * vx)
    if not _is_inf(inertia):
        lz += inertia * w
    return lz


def flow(state, t):
    """Free flight of duration ``t`` (any sign)."""
    x, y, a, vx, vy, w = state
    return [x + vx * t, y + vy * t, a + w * t, vx, vy, w]


def _end_and_velocity(state, ell, k, t):
    x, y, a, vx, vy, w = state
    cs, sn = mp.cos_sin(a + w * t)
    px = x + vx * t + k * ell * cs
    py = y + vy * t + k * ell * sn
    dpx = vx - k * ell * w * sn
    dpy = vy + k * ell * w * cs
    return px, py, dpx, dpy


def gap(R, ell, state, k, t=0):
    """``g_k(t)`` and ``dg_k/dt`` along the free flight from ``state``."""
    px, py, dpx, dpy = _end_and_velocity(state, ell, k, t)
    return R * R - px * px - py * py, -2 * (px * dpx + py * dpy)


def _first_root(R, ell, state, k, t_cap, just_bounced, max_steps):
    """First ``t > 0`` where ``g_k`` reaches zero while decreasing, or ``None``
    if there is none before ``t_cap``."""
    x, y, _, vx, vy, w = state
    speed = mpmath.sqrt(vx * vx + vy * vy)
    A = 2 * ((speed + ell * abs(w)) ** 2 + R * ell * w * w)
    if A == 0:  # nothing moves
        return None
    eps = mpf(10) ** (-(mp.dps - 6))  # relative size of g at which we polish
    g_scale = R * R
    inner = R - ell
    t = mpf(0)
    g0, g1 = gap(R, ell, state, k, t)
    if just_bounced:
        if g1 <= 0:
            raise ArithmeticError(f"end {k} just bounced but is not moving inward (g'={g1})")
        g0 = mpf(0)
    steps = 0
    while True:
        if g0 <= eps * g_scale and g1 < 0:
            break  # near a decreasing root: polish below
        # centre-disc shortcut: |c(t)| < R - ell  =>  no contact possible
        cx, cy = x + vx * t, y + vy * t
        c2 = cx * cx + cy * cy
        jump = mpf(0)
        if inner > 0 and speed > 0 and c2 < inner * inner:
            b = cx * vx + cy * vy
            disc = b * b - speed**2 * (c2 - inner * inner)
            jump = (-b + mpmath.sqrt(disc)) / speed**2
        s = (g1 + mpmath.sqrt(g1 * g1 + 2 * A * max(g0, mpf(0)))) / A
        t = t + max(s, jump)
        if t >= t_cap:
            return None
        g0, g1 = gap(R, ell, state, k, t)
        steps += 1
        if steps > max_steps:
            raise ArithmeticError(f"root isolation did not converge (end {k})")
    # Newton polish from the left of the root
    for _ in range(8):
        dt = -g0 / g1
        t = t + dt
        g0, g1 = gap(R, ell, state, k, t)
        if abs(dt) <= mpf(10) ** (-(mp.dps - 2)) * (1 + abs(t)):
            break
    if not (g1 < 0):
        raise ArithmeticError(f"polished root is not approaching (end {k})")
    if t <= 0:
        raise ArithmeticError(f"root at t <= 0 (end {k})")
    return t if t < t_cap else None


def _impulse(ell, mass, inertia, state, k):
    """Elastic frictionless impulse at end ``k``; returns (new_state, v_n)."""
    x, y, a, vx, vy, w = state
    cs, sn = mp.cos_sin(a)
    px, py = x + k * ell * cs, y + k * ell * sn
    r = mpmath.sqrt(px * px + py * py)
    nx, ny = px / r, py / r
    s = k * ell * (cs * ny - sn * nx)  # k ell (u x n)
    vn = vx * nx + vy * ny + w * s
    if vn <= 0:
        return list(state), vn
    spin_term = 0 if (_is_inf(inertia) or ell == 0) else s * s / inertia
    J = 2 * vn / (1 / mass + spin_term)
    nvx = vx - J / mass * nx
    nvy = vy - J / mass * ny
    nw = w if (_is_inf(inertia) or ell == 0) else w - J / inertia * s
    return [x, y, a, nvx, nvy, nw], vn


def _approach_speed(ell, state, k):
    x, y, a, vx, vy, w = state
    cs, sn = mp.cos_sin(a)
    px, py = x + k * ell * cs, y + k * ell * sn
    r = mpmath.sqrt(px * px + py * py)
    nx, ny = px / r, py / r
    s = k * ell * (cs * ny - sn * nx)
    return vx * nx + vy * ny + w * s


def reference_orbit(
    R,
    ell,
    mass,
    inertia,
    state0,
    n,
    dps=50,
    max_steps=2_000_000,
    t_max=None,
    invariant_tol=None,
    bounced=(),
):
    """First ``n`` collisions of the stick in a circle, to ``dps`` digits.

    Parameters: ``R`` circle radius, ``ell`` half-length (``0 <= ell < R``),
    ``mass``, ``inertia`` (``None`` -> ``mass * ell**2``; ``mpmath.inf`` or
    ``float('inf')`` -> static lens, ``omega`` must be 0), ``state0`` six
    numbers ``[x, y, alpha, vx, vy, omega]`` (floats are taken exactly),
    ``n`` number of collisions.

    Returns ``(times, states, contacts)``: absolute collision times (mpf),
    states just after each collision (lists of 6 mpf), contact codes
    (+1 end P1, -1 end P2, 2 both ends at once). With ``ell == 0`` the two ends
    coincide and the contact code is +1.  Raises ``RuntimeError`` if no
    collision happens before ``t_max`` (default ``1e6 R / V``).

    ``bounced``: ends (subset of ``{1, -1}``) that start on the wall moving
    inward, as just after a collision (e.g. when restarting from a state
    produced by another code): their gap at ``t = 0`` is taken as exactly 0
    (it may be a rounding error away from it) and their root at ``t = 0`` is
    excluded. Other ends must start inside the circle.
    """
    with mp.workdps(dps):
        R, ell, mass, inertia = _params(R, ell, mass, inertia)
        state = [mpf(v) for v in state0]
        if len(state) != 6:
            raise ValueError("state0 must have 6 components")
        if _is_inf(inertia) and state[5] != 0:
            raise ValueError("static lens (inertia=inf) needs omega == 0")
        E0 = energy(mass, inertia, state)
        L0 = angular_momentum(mass, inertia, state)
        if E0 <= 0:
            raise ValueError("the stick must move")
        V = mpmath.sqrt(2 * E0 / mass)  # speed scale
        T = R / V  # time scale
        L_scale = mass * R * V
        if not _is_inf(inertia):
            L_scale += mpmath.sqrt(2 * E0 * inertia)
        if t_max is None:
            t_max = mpf(10) ** 6 * T
        if invariant_tol is None:
            invariant_tol = mpf(10) ** (-(dps - 5))
        ends = (1,) if ell == 0 else (1, -1)
        bounced = set(bounced) & set(ends)
        for k in ends:
            g0, g1 = gap(R, ell, state, k)
            if k in bounced:
                if abs(g0) > mpf("1e-10") * R * R or g1 <= 0:
                    raise ValueError(f"end {k} is not on the wall moving inward")
            elif g0 < 0:
                raise ValueError(f"end {k} starts outside the circle")

        times, states, contacts = [], [], []
        t_abs = mpf(0)
        for _ in range(n):
            roots = {}
            cap = t_max
            for k in ends:
                tk = _first_root(R, ell, state, k, cap, k in bounced, max_steps)
                if tk is not None:
                    roots[k] = tk
                    # the other end only needs to be searched up to here (+tol)
                    cap = min(cap, tk + 2 * SIMULTANEOUS_TOL * T)
            if not roots:
                raise RuntimeError("no collision before t_max")
            t_hit = min(roots.values())
            hit = [k for k in roots if roots[k] - t_hit <= SIMULTANEOUS_TOL * T]
            state = flow(state, t_hit)
            if len(hit) == 1:
                (k,) = hit
                state, vn = _impulse(ell, mass, inertia, state, k)
                if not (vn > 0):
                    raise ArithmeticError("contact without approach")
                contact = k
                bounced = {k}
            else:
                # the end approaching faster first, then the other one if it
                # still approaches, and so on alternately while either does
                # (the limit of two hits in that order, infinitesimally apart;
                # in mass-weighted coordinates these are reflections in two
                # planes, which end after finitely many)
                order = sorted(hit, key=lambda k: -_approach_speed(ell, state, k))
                state, vn = _impulse(ell, mass, inertia, state, order[0])
                n_impulses = 1
                while True:
                    k = order[n_impulses % 2]
                    if not (_approach_speed(ell, state, k) > 0):
                        break
                    state, _ = _impulse(ell, mass, inertia, state, k)
                    n_impulses += 1
                    if n_impulses > 1000:
                        raise ArithmeticError("corner impulses do not terminate")
                contact = 2
                bounced = set(hit)
            # self-checks
            for k in hit:
                g0, _ = gap(R, ell, state, k)
                assert abs(g0) <= invariant_tol * R * R, ("contact off the wall", g0)
            E = energy(mass, inertia, state)
            assert abs(E - E0) <= invariant_tol * E0, ("energy drift", E - E0)
            if not _is_inf(inertia):
                L = angular_momentum(mass, inertia, state)
                assert abs(L - L0) <= invariant_tol * L_scale, ("L drift", L - L0)
            t_abs += t_hit
            times.append(+t_abs)
            states.append(list(state))
            contacts.append(contact)
        return times, states, contacts
