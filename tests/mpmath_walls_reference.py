"""Independent high-precision reference for the stick between two flat walls (2D and 3D).

Written with mpmath only, from the physics (the state layouts and contact
codes of the README's "The stick between two flat walls", the laws derived
below), without any jaxbill code, so
that the library's tests compare against something that can fail differently.

Model
-----
No gravity; floor ``z = 0``, ceiling ``z = h``. Stick of half-length ``ell``,
mass ``M``, moment of inertia ``I`` about its centre (``None`` -> ``M ell^2``;
``inf``: the stick never turns, its angular velocity must be zero).

* 2D state ``[x, z, theta, vx, vz, omega]``; ``theta`` from ``+z`` towards
  ``+x``; ends ``z_k = z + e_k ell cos(theta)``, ``e = (+1, -1)`` for (P1, P2).
  Flight: ``x += vx t, z += vz t, theta += omega t`` (``theta`` is kept
  continuous here, never wrapped).
* 3D state ``[x, y, z, ux, uy, uz, vx, vy, vz, wx, wy, wz]``; ``u`` the unit
  vector from the centre to P1, ``w`` the angular velocity, ``w . u = 0``.
  Flight: ``c += v t``, ``u(t) = u cos(|w| t) + (w_hat x u) sin(|w| t)``, ``w``
  constant. Ends ``z_k = c_z + e_k ell u_z``. A start state is projected onto
  the constraints first (``u <- u/|u|``, ``w <- w - (w.u) u``), so float64
  inputs (``|u| = 1`` only to rounding) are accepted.

Gaps (index ``i``, contact code): ``0: z_1`` (+1, P1 floor), ``1: z_2`` (-1, P2
floor), ``2: h - z_1`` (+3, P1 ceiling), ``3: h - z_2`` (-3, P2 ceiling).

Impulse (derived from the mass-weighted specular reflection)
------------------------------------------------------------
2D, configuration ``q = (x, z, theta)``, kinetic metric ``diag(M, M, I)``.
The gap of end ``k`` (floor or ceiling, up to sign) is ``z + e ell cos(theta)``
with gradient ``G = (0, 1, -e ell sin(theta))``. Reflecting ``qdot`` in the
tangent plane of the gap with respect to the metric:
``qdot' = qdot - 2 (G.qdot) / (G.M^-1 G) M^-1 G``. Here ``G.qdot = vz - e ell
sin(theta) omega = w`` (the end's vertical velocity) and ``G.M^-1 G = 1/M +
ell^2 sin^2(theta) / I``, so with ``J = -2 w / (1/M + ell^2 sin^2/I)``:
``vz' = vz + J/M``, ``omega' = omega - e ell sin(theta) J / I``, ``vx' = vx``;
and ``w' = w + J (1/M + ell^2 sin^2/I) = -w``. The ceiling gap has gradient
``-G``, which gives the same reflection.

3D, configuration ``(c, orientation)``; a small rotation ``phi`` moves ``u`` by
``phi x u``, so the gap ``c_z + e ell u_z`` has gradient ``(zhat, r x zhat)``
in ``(c, phi)`` with ``r = e ell u`` (``(phi x r) . zhat = phi . (r x zhat)``).
The metric is ``diag(M, M, M, I, I, I)`` on ``(v, w)``; ``r x zhat`` is
perpendicular to ``u``, so ``w . u = 0`` is kept. The reflection gives
``J = -2 w_end / (1/M + |r x zhat|^2 / I)``, ``w_end = v_z + (w x r)_z``,
``v' = v + (J/M) zhat``, ``w' = w + (J/I) (r x zhat)``, and again
``w_end' = -w_end``.

Root isolation (rigorous stepping)
----------------------------------
Along a flight every gap is *linear plus a sinusoid*:
``g(t) = a + b t + s ell S(t)`` with ``s = +-1``, ``S(t) = cos(theta + omega t)``
(2D) or ``S(t) = u_z cos(Om t) + q_z sin(Om t)``, ``q = w_hat x u``,
``Om = |w|`` (3D). The sinusoid has amplitude ``rho = ell`` (2D) or
``rho = ell sqrt(u_z^2 + q_z^2) <= ell`` (3D), so ``|g''| <= A = rho Om^2``
everywhere (``<= ell |omega|^2``, ``<= ell |w|^2``). From a time where
``g = g0 >= 0`` and ``g' = g1``, Taylor with that bound gives
``g(t + s) >= g0 + g1 s - A s^2 / 2``; the right-hand side is positive on
``[0, s*)``, ``s* = (g1 + sqrt(g1^2 + 2 A g0)) / A``, so a step of ``s*`` cannot
skip a zero of ``g`` (for ``g1 < 0`` it is evaluated as
``2 g0 / (sqrt(g1^2 + 2 A g0) - g1)``, free of cancellation when ``A`` is
tiny). Near a simple root the step is Newton's step shortened by
``A g0^2 / (2 |g1|^3)``: the iteration approaches the root from the left with
quadratic convergence, and once ``g`` is below ``1e-44 h`` with ``g' < 0`` the
root is polished with Newton's method. Near a local minimum of ``g`` that stays
positive (grazing), the steps shrink to about ``sqrt(2 g_min / A)`` and pass it
in a bounded number of steps; they never step over a zero.

A second exclusion serves as a shortcut: ``g(t) >= a + b t - rho``; while that
lower bound is positive there is no root, so the stepper jumps to the time it
vanishes, and if ``b >= 0`` there it proves that this gap never closes. With
``Om = 0`` the gap is linear and solved exactly.

The gap(s) that just bounced sit at ``g = 0`` with ``g' > 0``; their search
starts from ``g0 = 0`` exactly (the rounding residue at the contact is
discarded), so the root at ``t = 0`` is excluded, while a genuine re-collision
of the same end is still found (the first Taylor step is ``2 g1 / A > 0``).

Simultaneous contacts (contact code 2)
--------------------------------------
At the earliest root ``t1`` (gap ``i``), every other gap that is within
``SIMULTANEOUS_TOL * h`` of zero and approaching its wall is part of the same
event. The impulses are applied one at a time, always at the gap of the event
that approaches fastest, while any of them approaches: for two contacts this is
"the faster-approaching first, then the other if it still approaches", and
alternately on if needed (with ``I < M ell^2``, or one end on the floor and the
other on the ceiling, the two mass-weighted normals make an obtuse angle and a
velocity may need more than two reflections to leave the corner). If two
approach speeds tie (``|difference| <= 1e-30 V``), both orders are computed and
must agree to ``1e-20 V`` (as they do for ``I = M ell^2`` on a flat landing,
where the two normals are orthogonal); otherwise the event is declared
ill-posed (``ArithmeticError``).

Self-checks at every collision: energy, ``vx`` (and ``vy`` and ``L_z = M (x vy
- y vx) + I w_z`` in 3D) to ``1e-45`` relative, ``|u| = 1`` and ``w . u = 0``
(3D), the contact gaps are zero.
"""

from __future__ import annotations

import mpmath
from mpmath import mp, mpf

__all__ = [
    "reference_orbit",
    "flow",
    "gaps",
    "approach_speeds",
    "impulse",
    "energy",
    "angular_momentum_z",
    "normalize_state",
    "params",
    "CODES",
    "ENDS",
    "SIMULTANEOUS_TOL",
    "kind_of",
]

SIMULTANEOUS_TOL = mpf("1e-14")  # gap, in units of h, within which a second contact joins an event
CODES = (1, -1, 3, -3)  # contact code of gap index 0..3
ENDS = (1, -1, 1, -1)  # e_k of gap index 0..3
FLOOR = (True, True, False, False)
TIE_TOL = mpf("1e-30")  # approach speeds this close (units of V) are a tie
TIE_AGREE = mpf("1e-20")  # both orders of a tie must agree this well (units of V, W)


def kind_of(kind):
    k = str(kind).upper()
    if k in ("2", "2D"):
        return "2D"
    if k in ("3", "3D"):
        return "3D"
    raise ValueError("kind must be '2D' or '3D'")


def _is_inf(x):
    return x is not None and mpmath.isinf(x)


def params(h, ell, mass, inertia):
    """``(h, ell, M, I)`` as mpf, ``I = None`` -> ``M ell^2``, inf stays inf."""
    h, ell, mass = mpf(h), mpf(ell), mpf(mass)
    if inertia is None:
        inertia = mass * ell**2
    else:
        inertia = mpf(inertia)
        if mpmath.isinf(inertia):
            inertia = mpmath.inf
    if not (h > 0):
        raise ValueError("h must be > 0")
    if not (ell > 0):
        raise ValueError("ell must be > 0")
    if not (mass > 0):
        raise ValueError("mass must be > 0")
    if not (inertia > 0):
        raise ValueError("inertia must be > 0 (or inf)")
    return h, ell, mass, inertia


def normalize_state(kind, state):
    """mpf copy; in 3D ``u`` is normalised and ``w`` made perpendicular to it."""
    kind = kind_of(kind)
    s = [mpf(v) for v in state]
    if len(s) != (6 if kind == "2D" else 12):
        raise ValueError(f"state must have {6 if kind == '2D' else 12} components")
    if kind == "3D":
        n = mpmath.sqrt(s[3] ** 2 + s[4] ** 2 + s[5] ** 2)
        if not (n > 0):
            raise ValueError("u must be nonzero")
        u = [s[3] / n, s[4] / n, s[5] / n]
        wu = s[9] * u[0] + s[10] * u[1] + s[11] * u[2]
        s[3:6] = u
        s[9:12] = [s[9] - wu * u[0], s[10] - wu * u[1], s[11] - wu * u[2]]
    return s


def _cross(a, b):
    return [a[1] * b[2] - a[2] * b[1], a[2] * b[0] - a[0] * b[2], a[0] * b[1] - a[1] * b[0]]


def flow(kind, state, t):
    """Free flight of duration ``t`` (any sign)."""
    kind = kind_of(kind)
    if kind == "2D":
        x, z, th, vx, vz, om = state
        return [x + vx * t, z + vz * t, th + om * t, vx, vz, om]
    x, y, z, ux, uy, uz, vx, vy, vz, wx, wy, wz = state
    om = mpmath.sqrt(wx * wx + wy * wy + wz * wz)
    u = [ux, uy, uz]
    if om != 0:
        what = [wx / om, wy / om, wz / om]
        q = _cross(what, u)
        c, s = mp.cos_sin(om * t)
        u = [u[i] * c + q[i] * s for i in range(3)]
    return [x + vx * t, y + vy * t, z + vz * t, u[0], u[1], u[2], vx, vy, vz, wx, wy, wz]


def energy(kind, mass, inertia, state):
    """``M |v|^2 / 2 + I |w|^2 / 2`` (the spin term is dropped for ``I = inf``)."""
    if kind_of(kind) == "2D":
        e = mass * (state[3] ** 2 + state[4] ** 2) / 2
        spin2 = state[5] ** 2
    else:
        e = mass * (state[6] ** 2 + state[7] ** 2 + state[8] ** 2) / 2
        spin2 = state[9] ** 2 + state[10] ** 2 + state[11] ** 2
    if not _is_inf(inertia):
        e += inertia * spin2 / 2
    return e


def angular_momentum_z(mass, inertia, state):
    """3D: ``L_z = M (x vy - y vx) + I w_z`` (orbital part only for ``I = inf``)."""
    lz = mass * (state[0] * state[7] - state[1] * state[6])
    if not _is_inf(inertia):
        lz += inertia * state[11]
    return lz


# ---------------------------------------------------------------------------
# gaps along a flight: g(t) = a + b t + sgn * ell * S(t)
# ---------------------------------------------------------------------------
class _GapModel:
    """Gap ``i`` along the free flight from ``state``: value, derivative, the
    linear part ``a + b t``, the amplitude ``rho`` of the sinusoid and the
    bound ``A >= |g''|``."""

    def __init__(self, kind, h, ell, state, i):
        self.kind = kind
        e = ENDS[i]
        floor = FLOOR[i]
        self.sgn = e if floor else -e  # coefficient of ell * S(t)
        self.ell = ell
        if kind == "2D":
            _, z, th, _, vz, om = state
            self.th, self.om = th, om
            self.Om = abs(om)
            amp = mpf(1)
        else:
            z = state[2]
            vz = state[8]
            w = state[9:12]
            u = state[3:6]
            self.Om = mpmath.sqrt(w[0] ** 2 + w[1] ** 2 + w[2] ** 2)
            self.uz = u[2]
            if self.Om != 0:
                what = [wc / self.Om for wc in w]
                self.qz = _cross(what, u)[2]
            else:
                self.qz = mpf(0)
            amp = mpmath.sqrt(self.uz**2 + self.qz**2)
        self.a = z if floor else h - z
        self.b = vz if floor else -vz
        self.rho = ell * amp
        # |g''| = rho * Om^2 * |sin(...)| at most; a hair of margin against rounding
        self.A = self.rho * self.Om**2 * (1 + mpf(10) ** (-(mp.dps - 10)))

    def S(self, t):
        """``(S(t), S'(t))``."""
        if self.kind == "2D":
            c, s = mp.cos_sin(self.th + self.om * t)
            return c, -self.om * s
        if self.Om == 0:
            return self.uz, mpf(0)
        c, s = mp.cos_sin(self.Om * t)
        return self.uz * c + self.qz * s, self.Om * (self.qz * c - self.uz * s)

    def __call__(self, t):
        S, dS = self.S(t)
        return self.a + self.b * t + self.sgn * self.ell * S, self.b + self.sgn * self.ell * dS


def gaps(kind, h, ell, state, t=0):
    """The four gaps and their time derivatives at time ``t`` of the flight
    from ``state``: ``[(g_0, g_0'), ..., (g_3, g_3')]``."""
    kind = kind_of(kind)
    return [_GapModel(kind, mpf(h), mpf(ell), state, i)(mpf(t)) for i in range(4)]


def _first_root(model, t_cap, just_bounced, h, T, max_steps):
    """First ``t > 0`` where the gap reaches zero while decreasing.

    Returns ``(t, never)``: ``t`` the root or ``None`` if there is none before
    ``t_cap``; ``never`` is True when it is proven that the gap never closes."""
    dps = mp.dps
    g0, g1 = model(mpf(0))
    if just_bounced:
        if not (g1 > 0):
            raise ArithmeticError(f"gap just bounced but is not opening (g'={g1})")
        g0 = mpf(0)
    if model.A == 0:  # linear gap (no spin, or a 3D end whose height does not oscillate)
        if g1 >= 0:
            return None, True
        t = -g0 / g1
        if t <= 0:
            raise ArithmeticError("linear gap closing at t <= 0")
        return (t if t < t_cap else None), False
    eps = mpf(10) ** (-(dps - 6)) * h
    A = model.A
    t = mpf(0)
    steps = 0
    while True:
        if g0 <= eps and g1 < 0:
            break  # next to a decreasing root: polish below
        lower = model.a + model.b * t - model.rho  # g(t + s) >= lower + b s
        jump = mpf(0)
        if lower > 0:
            if model.b >= 0:
                return None, True
            jump = lower / (-model.b)
        root = mpmath.sqrt(g1 * g1 + 2 * A * max(g0, mpf(0)))
        # s* = (g1 + root) / A, written without cancellation when g1 < 0
        s = (g1 + root) / A if g1 >= 0 else 2 * max(g0, mpf(0)) / (root - g1)
        t = t + max(s, jump)
        if t >= t_cap:
            return None, False
        g0, g1 = model(t)
        steps += 1
        if steps > max_steps:
            raise ArithmeticError(f"root isolation did not converge in {max_steps} steps")
    # Newton polish, starting just left of the root
    tol = mpf(10) ** (-(dps - 4)) * (T + abs(t))
    for _ in range(20):
        dt = -g0 / g1
        if abs(dt) > mpf(10) ** (-(dps // 3)) * (T + abs(t)):
            raise ArithmeticError("Newton polish left the root's neighbourhood")
        t = t + dt
        g0, g1 = model(t)
        if abs(dt) <= tol:
            break
    else:
        raise ArithmeticError("Newton polish did not converge")
    if not (g1 < 0):
        raise ArithmeticError("polished root is not approaching")
    if not (t > 0):
        raise ArithmeticError("root at t <= 0")
    return (t if t < t_cap else None), False


# ---------------------------------------------------------------------------
# impulses
# ---------------------------------------------------------------------------
def approach_speeds(kind, ell, state):
    """Rate at which each of the four gaps closes (``-g'``), > 0 when approaching."""
    kind = kind_of(kind)
    out = []
    for i in range(4):
        e = ENDS[i]
        if kind == "2D":
            w_end = state[4] - e * ell * mpmath.sin(state[2]) * state[5]
        else:
            r = [e * ell * c for c in state[3:6]]
            w_end = state[8] + _cross(state[9:12], r)[2]
        out.append(-w_end if FLOOR[i] else w_end)
    return out


def impulse(kind, ell, mass, inertia, state, i):
    """Elastic frictionless vertical impulse at the end of gap ``i``.
    Returns the new state (the end's vertical velocity reversed)."""
    kind = kind_of(kind)
    e = ENDS[i]
    s = list(state)
    inv_i = 0 if _is_inf(inertia) else 1 / inertia
    if kind == "2D":
        sn = mpmath.sin(s[2])
        w_end = s[4] - e * ell * sn * s[5]
        J = -2 * w_end / (1 / mass + ell**2 * sn**2 * inv_i)
        s[4] = s[4] + J / mass
        s[5] = s[5] - e * ell * sn * J * inv_i
        return s
    r = [e * ell * c for c in s[3:6]]
    w = s[9:12]
    w_end = s[8] + _cross(w, r)[2]
    rxz = [r[1], -r[0], mpf(0)]  # r x zhat
    J = -2 * w_end / (1 / mass + (rxz[0] ** 2 + rxz[1] ** 2) * inv_i)
    s[8] = s[8] + J / mass
    s[9:12] = [w[k] + J * inv_i * rxz[k] for k in range(3)]
    return s


def _resolve(kind, ell, mass, inertia, state, hit, V, prefer):
    """Apply impulses at the gaps in ``hit`` while any approaches, the fastest
    first; ties broken by ``prefer`` (a key on the gap index). Returns
    ``(state, n_impulses, tied)``."""
    n_imp = 0
    tied = False
    while True:
        sp = approach_speeds(kind, ell, state)
        cand = [j for j in hit if sp[j] > 0]
        if not cand:
            return state, n_imp, tied
        best = max(sp[j] for j in cand)
        top = [j for j in cand if best - sp[j] <= TIE_TOL * V]
        if len(top) > 1:
            tied = True
        j = min(top, key=prefer)
        state = impulse(kind, ell, mass, inertia, state, j)
        n_imp += 1
        if n_imp > 1000:
            raise ArithmeticError("corner impulses do not terminate")


# ---------------------------------------------------------------------------
# the orbit
# ---------------------------------------------------------------------------
def reference_orbit(
    kind,
    h,
    ell,
    mass,
    inertia,
    state0,
    n,
    dps=50,
    max_steps=1_000_000,
    t_max=None,
    invariant_tol=None,
    bounced=(),
    info=None,
):
    """First ``n`` collisions of the stick between the walls, to ``dps`` digits.

    ``kind``: ``"2D"`` (state of 6) or ``"3D"`` (state of 12). ``inertia``:
    ``None`` -> ``mass * ell**2``; ``inf`` -> never turns (the angular velocity
    must be zero). ``state0`` floats are taken exactly (mpf accepted).

    Returns ``(times, contacts, states)``: absolute collision times (mpf),
    contact codes (+1/-1 P1/P2 on the floor, +3/-3 P1/P2 on the ceiling, 2
    several contacts in one event, 0 none: the stick never reaches a wall
    again, proven; then ``t = inf`` and the state is unchanged) and the states
    just after each collision (lists of mpf; 2D ``theta`` continuous, never
    wrapped). Raises ``RuntimeError`` if no collision is found before ``t_max``
    (default ``1e6 h / V``) without a proof that there is none.

    ``bounced``: gap indices (0..3) that start on their wall moving away, as
    just after a collision (their root at ``t = 0`` is excluded), or
    ``"auto"``: every gap within ``1e-10 h`` of zero that is opening. A gap
    within ``1e-10 h`` of zero that is closing is rejected (that is a collision
    at ``t = 0``, which the caller must have resolved).

    ``info``: if a dict, filled with per-collision diagnostics: ``impulses``
    (impulses applied), ``second_gap`` (largest gap/h of a contact that joined
    an event other than the root's, else None) and ``nearest_other`` (smallest
    gap/h among the approaching gaps that did not join the event, else None).
    """
    kind = kind_of(kind)
    with mp.workdps(dps):
        h, ell, mass, inertia = params(h, ell, mass, inertia)
        state = normalize_state(kind, state0)
        spin = state[5:6] if kind == "2D" else state[9:12]
        if _is_inf(inertia) and any(c != 0 for c in spin):
            raise ValueError("a stick with inertia=inf cannot turn: its angular velocity must be 0")
        E0 = energy(kind, mass, inertia, state)
        if not (E0 > 0):
            raise ValueError("the stick must move")
        V = mpmath.sqrt(2 * E0 / mass)
        T = h / V
        W = V / h if _is_inf(inertia) else mpmath.sqrt(2 * E0 / inertia)
        if t_max is None:
            t_max = mpf(10) ** 6 * T
        t_max = mpf(t_max)
        if invariant_tol is None:
            invariant_tol = mpf(10) ** (-(dps - 5))
        if kind == "2D":
            cons = [(state[3], V)]
        else:
            L_scale = mass * V * (abs(state[0]) + abs(state[1]) + h) + (0 if _is_inf(inertia) else inertia * W)
            cons = [(state[6], V), (state[7], V), (angular_momentum_z(mass, inertia, state), L_scale)]

        g_now = gaps(kind, h, ell, state)
        if isinstance(bounced, str):
            if bounced != "auto":
                raise ValueError("bounced must be a collection of gap indices or 'auto'")
            bounced = {i for i in range(4) if abs(g_now[i][0]) <= mpf("1e-10") * h and g_now[i][1] > 0}
        bounced = set(bounced)
        for i in range(4):
            g0, g1 = g_now[i]
            if i in bounced:
                if abs(g0) > mpf("1e-10") * h or not (g1 > 0):
                    raise ValueError(f"gap {i} is not on its wall and opening")
            elif g0 < 0 or (g0 <= mpf("1e-10") * h and g1 < 0):
                g0_text, g1_text = mpmath.nstr(g0, 5), mpmath.nstr(g1, 5)
                raise ValueError(f"gap {i} is negative or closing on the wall at t = 0 (g={g0_text}, g'={g1_text})")

        def conserved(s):
            if kind == "2D":
                return [s[3]]
            return [s[6], s[7], angular_momentum_z(mass, inertia, s)]

        times, contacts, states = [], [], []
        if info is not None:
            info.update(impulses=[], second_gap=[], nearest_other=[])
        t_abs = mpf(0)
        finished = False
        for _ in range(n):
            if finished:
                times.append(mpmath.inf)
                contacts.append(0)
                states.append(list(state))
                if info is not None:
                    info["impulses"].append(0), info["second_gap"].append(None), info["nearest_other"].append(None)
                continue
            roots = {}
            never = []
            cap = t_max
            for i in range(4):
                model = _GapModel(kind, h, ell, state, i)
                ti, nev = _first_root(model, cap, i in bounced, h, T, max_steps)
                never.append(nev)
                if ti is not None:
                    roots[i] = ti
                    cap = min(cap, ti)
            if not roots:
                if all(never):
                    finished = True
                    times.append(mpmath.inf)
                    contacts.append(0)
                    states.append(list(state))
                    if info is not None:
                        info["impulses"].append(0), info["second_gap"].append(None), info["nearest_other"].append(None)
                    continue
                raise RuntimeError("no collision before t_max")
            t_hit = min(roots.values())
            first = min(i for i in roots if roots[i] == t_hit)
            state = flow(kind, state, t_hit)
            g_hit = gaps(kind, h, ell, state)
            hit = [first]
            second, nearest = None, None
            for j in range(4):
                if j == first:
                    continue
                gj, dgj = g_hit[j]
                if dgj < 0 and gj <= SIMULTANEOUS_TOL * h:
                    if gj < -(mpf(10) ** (-(dps - 8))) * h:
                        raise ArithmeticError(f"gap {j} is through its wall at the event")
                    hit.append(j)
                    second = max(second or 0, float(abs(gj) / h))
                elif dgj < 0:
                    nearest = float(gj / h) if nearest is None else min(nearest, float(gj / h))
            if len(hit) == 1:
                new = impulse(kind, ell, mass, inertia, state, first)
                n_imp = 1
                contact = CODES[first]
            else:
                new, n_imp, tied = _resolve(kind, ell, mass, inertia, state, hit, V, prefer=lambda j: j)
                if tied:
                    other, _, _ = _resolve(kind, ell, mass, inertia, state, hit, V, prefer=lambda j: -j)
                    sl = slice(3, 6) if kind == "2D" else slice(6, 12)
                    diff = max(abs(a - b) for a, b in zip(new[sl], other[sl]))
                    if diff > TIE_AGREE * (V + W * h):
                        raise ArithmeticError("tied corner whose outcome depends on the order")
                contact = 2
            sp = approach_speeds(kind, ell, new)
            for j in hit:
                if not (sp[j] < 0):
                    raise ArithmeticError(f"gap {j} still approaching after the event")
            state = new
            bounced = set(hit)
            # self-checks
            g_after = gaps(kind, h, ell, state)
            assert abs(g_after[first][0]) <= invariant_tol * h, ("contact off the wall", g_after[first][0])
            E = energy(kind, mass, inertia, state)
            assert abs(E - E0) <= invariant_tol * E0, ("energy drift", E - E0)
            for (c0, scale), c in zip(cons, conserved(state)):
                assert abs(c - c0) <= invariant_tol * scale, ("momentum drift", c - c0)
            if kind == "3D":
                u, w = state[3:6], state[9:12]
                assert abs(u[0] ** 2 + u[1] ** 2 + u[2] ** 2 - 1) <= invariant_tol
                assert abs(u[0] * w[0] + u[1] * w[1] + u[2] * w[2]) <= invariant_tol * W
            t_abs += t_hit
            times.append(+t_abs)
            contacts.append(contact)
            states.append(list(state))
            if info is not None:
                info["impulses"].append(n_imp)
                info["second_gap"].append(second)
                info["nearest_other"].append(nearest)
        return times, contacts, states
