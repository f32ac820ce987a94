"""An independent check of ``jb.orbit`` for the sticks between two flat walls, with diffrax.

``jb.orbit`` flies the stick in closed form (the centre on a line, ``u`` turning
uniformly about ``w``) and finds each contact with a rigorous first-root search.
This checker uses neither: it *integrates* the reduced equations of motion of
the paper's "What's the Stick?" section with a diffrax solver, finds the walls
with a ``diffrax.Event`` and an ``optimistix.Newton`` root finder, and applies
each impulse as a reflection about ``jax.grad`` of the touching gap in
mass-weighted coordinates.

Reduced equations (general inertia ``I``)
-----------------------------------------
Orient the stick by ``u = (sin psi cos phi, sin psi sin phi, cos psi)``; ``psi``
is the polar angle of ``u`` from ``+z`` (the paper's ``theta``), ``phi`` its
azimuth. With ``|du/dt|^2 = psi'^2 + sin^2 psi phi'^2``,

    T = M (x'^2 + y'^2 + z'^2) / 2 + I (psi'^2 + sin^2 psi phi'^2) / 2.

``phi`` is cyclic: ``L_spin = I sin^2 psi phi' = I w_z`` is conserved in
flight (``w = u x u'``, ``(u x u')_z = sin^2 psi phi'``), and also at the
walls, whose impulse is vertical. Routh's reduction leaves, in ``(z, psi)``
with the metric ``diag(M, I)``,

    H = p_z^2 / (2 M) + p_psi^2 / (2 I) + L_spin^2 / (2 I sin^2 psi),

    z'' = 0,   psi'' = L_spin^2 cos psi / (I^2 sin^3 psi),
    phi' = L_spin / (I sin^2 psi)                          (passive),

and ``x, y`` move uniformly (integrated too). With ``I = M ell^2`` the
potential is the paper's ``L_z^2 / (2 M ell^2 sin^2 theta)`` (its ``L_z`` is
the stick's own spin ``I w_z``; jaxbill's ``L_z`` adds the centre's orbital
part ``M (x vy - y vx)``, constant by itself since ``vx, vy`` never change).

Singularities. ``sin psi = 0`` is where polar angles fail. With ``L_spin != 0``
the potential keeps the orbit away from it: the rotational energy
``I |w|^2 / 2`` bounds ``sin psi >= |w_z| / |w|`` on the whole flight (and at
the walls ``|w|`` changes, ``w_z`` does not). With ``L_spin = 0`` the motion
is planar (``w`` horizontal, ``u`` turning in the vertical plane normal to
``w``); the potential term is dropped *exactly* (not evaluated as ``0/0``),
``phi`` is the fixed azimuth of that plane and ``psi`` is the signed angle in
it, free to pass through the vertical: ``u = sin psi e + cos psi z``, ``e =
(cos phi, sin phi, 0)`` (the same formula as the polar one, with ``psi``
allowed to be negative). The 2D scene is this case with ``e = x``, ``psi =
theta``, ``psi' = omega``. So the formulation is regular on every orbit it
accepts; a flight with ``0 < sin psi_min < pole_tol`` (a nearly vertical
stick with almost no spin about ``z``: ``phi`` swings by nearly pi in a time
``~ psi_min / |w|``) would make the step sizes and the relative accuracy of
``psi`` collapse near the pole, and is *flagged* ("pole") rather than
integrated (see Accuracy).

The impulse
-----------
The gaps are ``g = [z + ell cos psi, z - ell cos psi, h - z - ell cos psi,
h - z + ell cos psi]`` (jaxbill's order: P1 floor, P2 floor, P1 ceiling, P2
ceiling). The impulse is a covector ``lambda dg`` with no ``phi`` part (``g``
does not depend on ``phi``; the full metric ``diag(M, I, I sin^2 psi)`` is
diagonal), so ``phi'`` and ``L_spin`` are untouched and the ``(z, psi)``
velocity changes along ``G^-1 dg``. Energy conservation then gives the
reflection ``q' -> q' - 2 (dg . q') / (dg . G^-1 dg) G^-1 dg``: in the
mass-weighted coordinates ``Q = (sqrt(M) z, sqrt(I) psi)``, a specular
reflection of ``Q'`` about ``grad_Q g`` (computed here with ``jax.grad``).
For ``g = z + e ell cos psi`` this is ``dz' = -2 w_end / (M (1/M + ell^2
sin^2 psi / I))`` with ``w_end = z' - e ell sin psi psi'``: the impulse of
the scenes' ``kick``, which this module never uses. A stick with ``I = inf`` keeps
``psi' = 0`` (the ``psi`` part of the normal is dropped).

What is certified
-----------------
As in ``jaxbill._check.checker``: the solver's steps are saved and, after each
solve, every gap is proven positive on every step from its values and slopes
at the step's ends and the bound ``|g''| <= K = ell |w|^2`` (the ends' heights
are ``z +- ell u_z`` with ``u_z'' = -|w|^2 u_z``; ``|w|^2 = psi'^2 +
L_spin^2 / (I sin psi)^2`` is a constant of the flight). This catches an even
number of sign changes of a gap inside one step, and an event root that is not
the first one (each gap is its own smooth ``Event``; when several cross in one
step diffrax locates the first listed, and the others, negative at that
event, fail the certification). A step that cannot be certified is redone
from the last certified point, over twice its length, with steps 8 times
smaller, and so on down to ``dtmax = sqrt(8 graze_tol h / K)``, small enough
that an excursion deeper than ``graze_tol h`` could not hide in a step; if
that fails too the checker stops and *flags* the collision ("graze"). A
failed event root find, or a root the polish below cannot confirm, is redone
the same way before it is flagged. Other flags: ``max_steps`` (no event
within ``max_steps`` steps: also a flight that never ends, which ``jb.orbit``
reports as contact 0), ``not_approaching``, ``corner`` (another end within
``corner_tol h`` of a wall at the event: ``jb.orbit`` merges them into
contact 2), ``pole`` (above), ``outside`` (a flight starts with an end
through a wall by more than ``corner_tol h``; in the one-collision comparison
that is jaxbill's state, and counts as a mismatch).

The event time from diffrax comes from the solver's dense interpolant, less
accurate than its steps. It is polished by Newton's method on the integrated
flow itself: from the start of the event step, ``tau <- tau -
g_k(flow(tau)) / g_k'(flow(tau))``, each ``flow`` a fresh diffrax solve
(three iterations).

Accuracy (defaults: ``Dopri8``, ``rtol = 1e-12``, ``atol = 1e-14``). One
flight restarted from jaxbill's state agrees with ``jb.collide`` to 1e-13
(time, in ``h / V``) and 4e-13 (state) on ordinary curved flights, 1e-11 for
a light stick (``I = M ell^2 / 100``) that turns 15 radians in a flight and
passes 0.035 rad from vertical, 3e-16 on planar (straight, ``L_spin = 0``)
flights. The error grows as the stick passes closer to the pole, about as
``1e-19 / sin^2 psi_min``: 1e-11 at ``sin psi_min = 1e-4``, 1e-9 at 1e-5,
7e-9 at 1e-6, 4e-6 at 1e-7 (and 400,000 steps for 60 collisions); hence
``pole_tol = 1e-5``. Energy
drifts by the solver's error (about 1e-12 relative over 60 collisions);
``L_z`` is a constant of the ODE and is kept to rounding.
"""

from __future__ import annotations

import math
import time

import diffrax
import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np

from jaxbill._check.events import gaps_at_step_ends, solve_to_event
from jaxbill._check.report import CheckFlag, CheckResult, certified_positive, comparison_report, first_index, wrap_angle
from jaxbill._engine.collision import orbit as _orbit
from jaxbill._engine.validation import MAX_STORED_COUNT, check_count
from jaxbill._scenes.protocols import ReducedWalls

__all__ = ["check_walls"]

_FLAG_NAMES = {
    1: "graze",  # a gap not certified positive inside a step, even with fine steps
    2: "max_steps",  # no wall event within max_steps solver steps
    3: "root_find",  # the event (or its Newton polish) did not converge
    4: "not_approaching",  # the end at the event is not moving into the wall
    5: "corner",  # another end on a wall at the same event (jb.orbit: contact 2)
    6: "pole",  # 0 < sin(psi_min) < pole_tol: too close to the polar singularity
    7: "outside",  # the flight's start has an end through a wall (by more than corner_tol h)
}
_CONTACT_CODES = (1, -1, 3, -3)  # gap index -> contact code (P1/P2 floor, P1/P2 ceiling)


class _Reduced(eqx.Module):
    """The reduced ``(z, psi)`` problem of one flight, with ``x, y, phi`` carried along.

    The ODE state is ``y = [x, y, z, psi, phi, z', psi']``; the constants of
    the flight are ``vxy = (vx, vy)`` and ``spin = L_spin = I w_z``.
    """

    h: jax.Array
    ell: jax.Array
    mass: jax.Array
    inertia: jax.Array  # 1 (a placeholder) when frozen
    spin: jax.Array
    vxy: jax.Array
    frozen: bool = eqx.field(static=True)  # I = inf: psi' = 0 for ever

    def gaps(self, y: jax.Array) -> jax.Array:
        reach = self.ell * jnp.cos(y[3])
        z = y[2]
        return jnp.stack([z + reach, z - reach, self.h - z - reach, self.h - z + reach])

    def field(self, y: jax.Array) -> jax.Array:
        """``dy/dt``: the reduced Hamiltonian's equations (see the module docstring)."""
        psi, zdot, psidot = y[3], y[5], y[6]
        spinning = self.spin != 0.0
        s = jnp.where(spinning, jnp.sin(psi), 1.0)  # never 0/0 for L_spin = 0
        rate = self.spin / self.inertia
        phidot = jnp.where(spinning, rate / (s * s), 0.0)
        psiddot = jnp.where(spinning, rate * rate * jnp.cos(psi) / (s * s * s), 0.0)
        zero = jnp.zeros_like(zdot)
        return jnp.stack([self.vxy[0], self.vxy[1], zdot, psidot, phidot, zero, psiddot])

    def gaps_and_slopes(self, y: jax.Array):
        return jax.jvp(self.gaps, (y,), (self.field(y),))

    def turn_rate2(self, y: jax.Array) -> jax.Array:
        """``|w|^2 = psi'^2 + (L_spin / (I sin psi))^2``, constant along a flight."""
        spinning = self.spin != 0.0
        s = jnp.where(spinning, jnp.sin(y[3]), 1.0)
        return y[6] ** 2 + jnp.where(spinning, (self.spin / (self.inertia * s)) ** 2, 0.0)

    def reflect(self, k: jax.Array, y: jax.Array) -> jax.Array:
        """Elastic impulse at gap ``k``: specular reflection in ``Q = (sqrt(M) z, sqrt(I) psi)``."""
        sm, si = jnp.sqrt(self.mass), jnp.sqrt(self.inertia)

        def gap_k(q):
            return self.gaps(y.at[2].set(q[0] / sm).at[3].set(q[1] / si))[k]

        q = jnp.stack([sm * y[2], si * y[3]])
        qdot = jnp.stack([sm * y[5], si * y[6]])
        normal = jax.grad(gap_k)(q)
        if self.frozen:
            normal = normal.at[1].set(0.0)
        qdot = qdot - 2.0 * (normal @ qdot) / (normal @ normal) * normal
        return y.at[5].set(qdot[0] / sm).at[6].set(qdot[1] / si)


def _vector_field(t, y, core):
    return core.field(y)


@eqx.filter_jit
def _segment(core: _Reduced, y0, t1, dtmax, solver, rtol, atol, root_tol, chunk_steps, corner_tol):
    """Integrate from ``y0`` until a wall event, ``t1`` or ``chunk_steps`` steps; certify the steps.

    Returns a dict: ``status`` 0 event, 1 a step not certified, 2 no event
    (``t1`` or ``chunk_steps`` reached), 3 the event's root finder failed;
    ``t_end, y_end`` (the event, or where the solve stopped); ``t_s, y_s`` the
    start of the last step; ``t_good, y_good, bad_len`` the start and length of
    the first uncertified step; ``n_steps``.
    """

    def gap_event(k):
        # One smooth event per gap (their minimum has kinks that upset Newton).
        # At a flight's start the gap that just bounced is zero and diffrax sees
        # only crossings from a positive value: +1 at t = 0 lets the first step's
        # end see any gap that closes within it.
        def cond_fn(t, y, args, **kwargs):
            return jnp.where(t <= 0.0, 1.0, core.gaps(y)[k] / core.h)

        return cond_fn

    # Several gaps crossing in one step: diffrax locates the first listed, which
    # may not be the earliest; the certification below then fails (the other gap
    # is negative at the event) and the step is redone finely.
    flight = solve_to_event(
        _vector_field,
        y0,
        t1=t1,
        dt0=jnp.minimum(dtmax, t1),
        dtmax=dtmax,
        solver=solver,
        rtol=rtol,
        atol=atol,
        root_tol=root_tol,
        max_steps=chunk_steps,
        conditions=[gap_event(k) for k in range(4)],
        args=core,
    )
    ts, ys, valid, n_steps, last = flight.ts, flight.ys, flight.valid, flight.n_steps, flight.last
    t_start, y_start, t_end, y_end = flight.t_start, flight.y_start, flight.t_end, flight.y_end
    f0, p0, f1, p1 = gaps_at_step_ends(core.gaps_and_slopes, flight, corner_tol * core.h)
    # |g''| <= ell |w|^2; |w|^2 is a flight constant, evaluated at both ends
    # (the integrated one drifts by the solver's error) and padded.
    K = core.ell * jnp.maximum(jax.vmap(core.turn_rate2)(y_start), jax.vmap(core.turn_rate2)(y_end))
    K = K * (1.0 + 1e-6)

    event_ok = flight.result == diffrax.RESULTS.event_occurred
    assert flight.event_mask is not None  # set whenever an Event is given
    k_index = jnp.argmax(jnp.stack(flight.event_mask))
    steps = jnp.arange(ts.shape[0])
    # The event is a root of the touching gap: certify up to it only. Another gap
    # within corner_tol h of zero there is a corner, flagged after the landing.
    at_event = ((steps == last) & event_ok)[:, None] & (
        (jnp.arange(4)[None, :] == k_index) | (f1 >= -corner_tol * core.h)
    )
    f1 = jnp.where(at_event, jnp.maximum(f1, 0.0), f1)
    ok = certified_positive(f0, p0, f1, p1, (t_end - t_start)[:, None], K[:, None])
    bad = valid & ~jnp.all(ok, axis=1)
    bad_step = jnp.argmax(bad)

    no_event = (flight.result == diffrax.RESULTS.max_steps_reached) | (flight.result == diffrax.RESULTS.successful)
    status = jnp.where(jnp.any(bad), 1, jnp.where(event_ok, 0, jnp.where(no_event, 2, 3)))
    return dict(
        status=status,
        t_end=ts[last],
        y_end=ys[last],
        k_index=k_index,
        t_s=t_start[last],
        y_s=y_start[last],
        t_good=t_start[bad_step],
        y_good=y_start[bad_step],
        bad_len=t_end[bad_step] - t_start[bad_step],
        n_steps=n_steps,
    )


@eqx.filter_jit
def _land(core: _Reduced, y_s, tau0, k_index, dtmax, solver, rtol, atol, corner_tol):
    """Polish the event time on the integrated flow, check it, reflect.

    Newton on ``tau -> g_k(flow(y_s, tau))`` from the interpolated event time
    ``tau0`` (each ``flow`` a diffrax solve from the event step's start ``y_s``).
    Returns ``(tau, y_after, flag)`` with flag 0, 3 (no convergence),
    4 (not approaching) or 5 (corner).
    """

    def flow(tau):
        sol = diffrax.diffeqsolve(
            diffrax.ODETerm(_vector_field),
            solver,
            t0=0.0,
            t1=tau,
            dt0=jnp.maximum(jnp.minimum(dtmax, tau), 1e-300),
            y0=y_s,
            args=core,
            stepsize_controller=diffrax.PIDController(rtol=rtol, atol=atol, dtmax=dtmax),
            saveat=diffrax.SaveAt(t1=True),
            max_steps=4096,
            throw=False,
        )
        assert sol.ys is not None  # SaveAt(t1=True) saves it
        return sol.ys[-1]

    def newton(i, tau):
        g, slope = core.gaps_and_slopes(flow(tau))
        return tau - g[k_index] / slope[k_index]

    tau = jax.lax.fori_loop(0, 3, newton, tau0)
    y = flow(tau)
    g, slope = core.gaps_and_slopes(y)
    # The polished root must be the interpolant's (which is off by the dense
    # output's error, far below 1e-3 of the step at any sensible rtol).
    converged = (jnp.abs(g[k_index]) <= 1e-13 * core.h) & (jnp.abs(tau - tau0) <= 1e-3 * tau0 + 1e-9 * dtmax)
    converged &= jnp.isfinite(tau) & (tau >= 0.0)
    others = jnp.where(jnp.arange(4) == k_index, jnp.inf, g)
    corner = jnp.min(others) <= corner_tol * core.h
    flag = jnp.where(~converged, 3, jnp.where(slope[k_index] >= 0.0, 4, jnp.where(corner, 5, 0)))
    return tau, core.reflect(k_index, y), flag


# ---------------------------------------------------------------------------
# scene states <-> the reduced state
# ---------------------------------------------------------------------------
def _from_3d(s: np.ndarray, inertia: float, frozen: bool):
    """``[x, y, z, u, v, w]`` -> ``(y, vxy, L_spin, sin_psi_min)``."""
    u, v, w = s[3:6], s[6:9], s[9:12]
    spin = 0.0 if frozen else inertia * float(w[2])
    horizontal = math.hypot(u[0], u[1])
    wnorm = float(np.linalg.norm(w))
    if frozen or wnorm == 0.0:
        psi, phi, psidot = math.atan2(horizontal, u[2]), math.atan2(u[1], u[0]), 0.0
        sin_min = 1.0
    elif spin != 0.0:
        psi, phi = math.atan2(horizontal, u[2]), math.atan2(u[1], u[0])
        e_psi = np.array([math.cos(psi) * math.cos(phi), math.cos(psi) * math.sin(phi), -math.sin(psi)])
        psidot = float(e_psi @ np.cross(w, u))
        sin_min = abs(float(w[2])) / wnorm  # the turning point of the potential
    else:  # planar: u turns in the vertical plane normal to w; e = w x z / |w|
        e = np.array([w[1], -w[0], 0.0]) / wnorm
        phi = math.atan2(e[1], e[0])
        psi = math.atan2(float(u @ e), u[2])
        psidot = wnorm
        sin_min = 1.0
    y = np.array([s[0], s[1], s[2], psi, phi, v[2], psidot])
    return y, np.array([v[0], v[1]]), spin, sin_min


def _to_3d(y: np.ndarray, vxy: np.ndarray, spin: float, inertia: float) -> np.ndarray:
    psi, phi, psidot = y[3], y[4], y[6]
    sp, cp, sf, cf = math.sin(psi), math.cos(psi), math.sin(phi), math.cos(phi)
    u = np.array([sp * cf, sp * sf, cp])
    e_psi = np.array([cp * cf, cp * sf, -sp])
    e_phi = np.array([-sf, cf, 0.0])
    # w = u x u', u' = psi' e_psi + sin psi phi' e_phi, sin psi phi' = L / (I sin psi).
    w = psidot * e_phi - (spin / (inertia * sp) if spin != 0.0 else 0.0) * e_psi
    return np.concatenate([y[0:3], u, [vxy[0], vxy[1], y[5]], w])


def _from_2d(s: np.ndarray):
    return np.array([s[0], 0.0, s[1], s[2], 0.0, s[4], s[5]]), np.array([s[3], 0.0]), 0.0, 1.0


def _to_2d(y: np.ndarray, vxy: np.ndarray) -> np.ndarray:
    return np.array([y[0], y[2], wrap_angle(y[3]), vxy[0], y[5], y[6]])


# ---------------------------------------------------------------------------
# one flight
# ---------------------------------------------------------------------------
class _Settings(eqx.Module):
    solver: object
    rtol: float = eqx.field(static=True)
    atol: float = eqx.field(static=True)
    root_tol: float = eqx.field(static=True)
    chunk_steps: int = eqx.field(static=True)
    max_steps: int = eqx.field(static=True)
    corner_tol: float = eqx.field(static=True)
    graze_tol: float = eqx.field(static=True)
    coarse_turn: float = eqx.field(static=True)
    pole_tol: float = eqx.field(static=True)


def _flight(params, y, vxy, spin, sin_min, cfg: _Settings):
    """Integrate one flight from reduced state ``y`` to its collision.

    Returns ``(dt, y_after, contact, flag, message, n_steps)``; ``flag`` is 0
    or a key of ``_FLAG_NAMES``; ``contact = 0, dt = inf`` for a flight that
    can never reach a wall.
    """
    h, ell, mass, inertia, frozen = params
    if spin != 0.0 and sin_min < cfg.pole_tol:
        return None, None, None, 6, f"sin(psi_min) = |w_z|/|w| = {sin_min:.2e} < pole_tol = {cfg.pole_tol:g}", 0
    core = _Reduced(
        h=jnp.asarray(h),
        ell=jnp.asarray(ell),
        mass=jnp.asarray(mass),
        inertia=jnp.asarray(inertia),
        spin=jnp.asarray(spin),
        vxy=jnp.asarray(vxy),
        frozen=frozen,
    )
    start_gaps = np.asarray(core.gaps(jnp.asarray(y)))
    if np.min(start_gaps) < -cfg.corner_tol * h:
        k = int(np.argmin(start_gaps))
        return (
            None,
            None,
            None,
            7,
            (f"the start has gap {k} = {start_gaps[k]:.3g} < -corner_tol h: an end is through a wall"),
            0,
        )
    W2 = float(core.turn_rate2(jnp.asarray(y)))
    W = math.sqrt(W2)
    vz = abs(float(y[5]))
    if W == 0.0 and vz == 0.0:
        return math.inf, y, 0, 0, "", 0  # nothing moves vertically: no contact ever
    K = ell * W2
    coarse = cfg.coarse_turn / (W + vz / h)
    fine = math.sqrt(8.0 * cfg.graze_tol * h / K) if K > 0.0 else coarse
    fine = min(fine, coarse)
    # Refinement windows (until, dtmax): a step that cannot be certified is redone
    # from the last certified point over twice its length with steps 8 times
    # smaller, and so on down to the fine step; outside every window, coarse steps.
    t_flight, n_steps, windows = 0.0, 0, []
    while True:
        # Keep the angles small: the solver's rounding per step is ulp(angle).
        y = y.copy()
        y[4] = wrap_angle(y[4])
        if spin == 0.0:
            y[3] = wrap_angle(y[3])
        windows = [(until, d) for until, d in windows if until > t_flight + 1e-12 * max(until, 1e-300)]
        step = min([coarse] + [d for _, d in windows])
        t1 = min([math.inf] + [until for until, _ in windows]) - t_flight
        out = _segment(
            core,
            jnp.asarray(y),
            jnp.asarray(t1),
            jnp.asarray(step),
            cfg.solver,
            jnp.asarray(cfg.rtol),
            jnp.asarray(cfg.atol),
            jnp.asarray(cfg.root_tol),
            cfg.chunk_steps,
            jnp.asarray(cfg.corner_tol),
        )
        status = int(out["status"])
        n_steps += int(out["n_steps"])
        if status == 1:
            if step > fine:
                t_flight += float(out["t_good"])
                y = np.asarray(out["y_good"])
                finer = max(step / 8.0, fine)
                windows.append((t_flight + 2.0 * float(out["bad_len"]) + finer, finer))
                continue
            return (
                None,
                None,
                None,
                1,
                (
                    "a gap could dip below zero unseen in the step at flight time "
                    f"{t_flight + float(out['t_good']):.6g} "
                    f"(steps of {fine:.3g} rule out only excursions deeper than graze_tol h = {cfg.graze_tol * h:.2g})"
                ),
                n_steps,
            )
        if n_steps >= cfg.max_steps and status != 0:
            return None, None, None, 2, f"no wall event within max_steps = {cfg.max_steps} solver steps", n_steps
        if status == 2:
            t_flight += float(out["t_end"])
            y = np.asarray(out["y_end"])
            continue
        k = out["k_index"]
        t_s = float(out["t_s"])
        if status == 3:
            if step > fine and math.isfinite(t_s):
                # diffrax's event root finder failed in the last step: redo it finely.
                t_flight += t_s
                y = np.asarray(out["y_s"])
                finer = max(step / 8.0, fine)
                windows.append((t_flight + 2.0 * step + finer, finer))
                continue
            return None, None, None, 3, "the event root finder failed", n_steps
        tau, y_after, flag = _land(
            core,
            out["y_s"],
            out["t_end"] - out["t_s"],
            k,
            jnp.asarray(step),
            cfg.solver,
            jnp.asarray(cfg.rtol),
            jnp.asarray(cfg.atol),
            jnp.asarray(cfg.corner_tol),
        )
        flag = int(flag)
        if flag in (3, 4) and step > fine:
            # A root the polish cannot confirm, or one where the end is not
            # approaching: redo the event step with finer steps.
            t_flight += t_s
            y = np.asarray(out["y_s"])
            finer = max(step / 8.0, fine)
            windows.append((t_flight + 2.0 * step + finer, finer))
            continue
        if flag:
            what = {
                3: "Newton on the integrated flow did not converge at the event",
                4: "the end at the event is not moving into the wall",
                5: "another end is on a wall at the same event (jb.orbit reports contact 2 there)",
            }[flag]
            return None, None, None, flag, what, n_steps
        return t_flight + t_s + float(tau), np.asarray(y_after), _CONTACT_CODES[int(k)], 0, "", n_steps


# ---------------------------------------------------------------------------
# comparison
# ---------------------------------------------------------------------------
def _scaled_deviation(a, b, scales, planar_scene: bool):
    """Per-collision scaled deviations ``(time, position, angle, velocity, spin)``, shape (m, 5)."""
    (ta, sa), (tb, sb) = a, b
    t_s, r_s, v_s, w_s = scales
    with np.errstate(invalid="ignore"):
        dt = np.where(np.isinf(ta) & np.isinf(tb), 0.0, np.abs(ta - tb))
    if planar_scene:  # [x, z, theta, vx, vz, omega]
        dang = np.abs(np.remainder(sa[:, 2] - sb[:, 2] + np.pi, 2 * np.pi) - np.pi)
        pos, vel, spin = (0, 1), (3, 4), (5, 6)
    else:  # [x, y, z, u, v, w]: the angle is |du| (the chord)
        dang = np.linalg.norm(sa[:, 3:6] - sb[:, 3:6], axis=1)
        pos, vel, spin = (0, 3), (6, 9), (9, 12)
    return np.stack(
        [
            dt / t_s,
            np.max(np.abs(sa[:, pos[0] : pos[1]] - sb[:, pos[0] : pos[1]]), axis=1) / r_s,
            dang,
            np.max(np.abs(sa[:, vel[0] : vel[1]] - sb[:, vel[0] : vel[1]]), axis=1) / v_s,
            np.max(np.abs(sa[:, spin[0] : spin[1]] - sb[:, spin[0] : spin[1]]), axis=1) / w_s,
        ],
        axis=1,
    )


def _perturbations(state0: np.ndarray, planar_scene: bool, eps, scales) -> np.ndarray:
    """Four valid states near ``state0``: scaled sizes ``eps = (position, angle,
    velocity, spin)`` in random fixed directions; |u| = 1 and w . u = 0 kept in 3D."""
    _, r_s, v_s, w_s = scales
    e_r, e_a, e_v, e_w = eps
    rng = np.random.default_rng(20240601)
    out = []
    for _ in range(4):
        d = rng.uniform(-1.0, 1.0, state0.shape)
        s = state0.copy()
        if planar_scene:
            s += d * np.array([e_r * r_s, e_r * r_s, e_a, e_v * v_s, e_v * v_s, e_w * w_s])
        else:
            s[0:3] += e_r * r_s * d[0:3]
            u = s[3:6] + e_a * d[3:6]
            u /= np.linalg.norm(u)
            w = s[9:12] + e_w * w_s * d[9:12] * (np.linalg.norm(s[9:12]) > 0)
            s[3:6], s[6:9], s[9:12] = u, s[6:9] + e_v * v_s * d[6:9], w - (w @ u) * u
        out.append(s)
    return np.stack(out)


# ---------------------------------------------------------------------------
# the checker
# ---------------------------------------------------------------------------
# The options of ``jb.check`` that this checker shares; the others keep its defaults.
_SHARED_OPTIONS = ("tol", "graze_tol", "max_steps", "corner_tol", "solver")


class ReducedWallsFlight(eqx.Module):
    """The flight of the sticks between walls that ``check_walls`` integrates (``HasCheckerFlight``).

    The reduced ``(z, psi)`` billiard with its centrifugal potential (the
    module docstring); ``planar``: the 2D scene (state ``(6,)``), else the 3D
    one (state ``(12,)``).
    """

    planar: bool = eqx.field(static=True)

    def check(self, scene, state0, n: int, **options) -> CheckResult:
        """``check_walls`` with the options of ``jb.check`` it shares (``solver=None``: its own default)."""
        shared = {name: options[name] for name in _SHARED_OPTIONS if options.get(name) is not None}
        return check_walls(scene, state0, n, **shared)


def check_walls(
    scene,
    state0,
    n: int,
    *,
    tol: float = 1e-8,
    local: str = "restart",
    graze_tol: float = 1e-6,
    coarse_turn: float = 0.5,
    solver=None,
    rtol: float = 1e-12,
    atol: float = 1e-14,
    root_tol: float = 1e-12,
    chunk_steps: int = 1024,
    max_steps: int = 2**20,
    corner_tol: float = 1e-12,
    pole_tol: float = 1e-5,
    horizon_eps: float | None = None,
) -> CheckResult:
    """Integrate the first ``n`` collisions of a wall scene with diffrax; compare with ``jb.orbit``.

    Args:
        scene: one (unbatched) ``StickBetweenWalls3D`` or ``StickBetweenWalls2D``.
        state0: the scene's state, shape ``(12,)`` or ``(6,)``.
        n: number of collisions.
        tol: scaled tolerance of the comparison and of the chaos horizon. Units:
            time ``h / V``, position ``h``, angle radians (3D: ``|u - u_ref|``),
            velocity ``V``, angular velocity ``V / sqrt(I/M)``, where
            ``V = sqrt(2 E / M)``.
        local: the one-collision comparison (``local_*`` in the report, no
            chaos horizon): ``"restart"`` restarts the checker from each state
            of ``jb.orbit`` and compares its next collision with jaxbill's;
            ``"none"`` skips it (half the cost).
        graze_tol: a step that cannot be certified is redone with steps so
            small that an excursion deeper than ``graze_tol * h`` could not hide
            in one; a step still not certified is flagged.
        coarse_turn: largest ordinary step, as the angle the stick turns
            (radians at the flight's ``|w| + |z'|/h``).
        solver, rtol, atol: the diffrax solver (default ``diffrax.Dopri8()``:
            at ``rtol = 1e-12`` about 6 times fewer steps than ``Tsit5`` and
            100 times smaller errors) and its PID controller's tolerances.
        root_tol: ``optimistix.Newton`` tolerances of the event (on the time
            and on ``g / h``); the event is then polished on the flow itself.
        chunk_steps: solver steps per diffrax solve (static; the buffer that is
            certified after each solve).
        max_steps: solver steps allowed per flight, over all its solves.
        corner_tol: another gap within ``corner_tol * h`` of zero at an event
            is a corner, flagged.
        pole_tol: flag a flight with ``0 < sin(psi_min) = |w_z| / |w| < pole_tol``.
        horizon_eps: size (scaled) of the four perturbations of ``state0`` that
            set the chaos horizon (``CheckReport.horizon``: the first collision
            at which any of them departs from ``jb.orbit(state0)`` by more than
            ``tol`` or in its contact). Default: the checker's own error, the
            largest one-collision deviation of positions, angles, velocities
            and spins, each apart (``10 rtol`` with ``local="none"``), clipped
            to ``[1e-12, tol/10]``: the two orbits are compared only as far as
            an error of that size stays below ``tol``.

    Returns:
        ``CheckResult`` (``state`` in the scene's layout) with a ``CheckReport``.
        The checker stops at the first collision it cannot certify and records
        a ``CheckFlag``; flags of the restarted one-collision runs are
        recorded with kinds ``"local <kind>"``.
    """
    start = time.perf_counter()
    flight = scene.checker_flight() if hasattr(scene, "checker_flight") else None
    if not isinstance(flight, ReducedWalls):
        raise TypeError(
            f"check_walls takes a scene whose checker flight is the ReducedWalls "
            f"(StickBetweenWalls2D or 3D), not {type(scene).__name__}"
        )
    n = check_count("n", n, 1, "number of collisions", MAX_STORED_COUNT)
    planar_scene = flight.planar
    size = scene.state_size
    dtype = state0.dtype if hasattr(state0, "dtype") else np.asarray(state0).dtype
    if not (np.issubdtype(dtype, np.floating) or np.issubdtype(dtype, np.integer)):
        raise ValueError(f"state0 must be real numbers; got dtype {dtype}")
    state0 = np.asarray(state0, dtype=np.float64)
    if state0.shape != (size,) or np.ndim(scene.h) != 0:
        raise NotImplementedError(f"check_walls takes one scene and one state0 of shape ({size},); loop over a batch")
    if local not in ("restart", "none"):
        raise ValueError(f"local must be 'restart' or 'none', not {local!r}")
    scene.check()
    reference = _orbit(scene, state0, n)  # also validates state0 eagerly
    frozen = not scene.body_turns
    h, ell, mass = (float(v) for v in (scene.h, scene.ell, scene.mass))
    inertia = 1.0 if frozen else float(scene.inertia)
    params = (h, ell, mass, inertia, frozen)
    cfg = _Settings(
        solver=diffrax.Dopri8() if solver is None else solver,
        rtol=rtol,
        atol=atol,
        root_tol=root_tol,
        chunk_steps=chunk_steps,
        max_steps=max_steps,
        corner_tol=corner_tol,
        graze_tol=graze_tol,
        coarse_turn=coarse_turn,
        pole_tol=pole_tol,
    )

    def to_reduced(s):
        return _from_2d(s) if planar_scene else _from_3d(s, inertia, frozen)

    def to_scene(y, vxy, spin):
        return _to_2d(y, vxy) if planar_scene else _to_3d(y, vxy, spin, inertia)

    def one_flight(s):
        y, vxy, spin, sin_min = to_reduced(s)
        dt, y_after, contact, flag, message, steps = _flight(params, y, vxy, spin, sin_min, cfg)
        if flag:
            return None, None, None, flag, message, steps
        return dt, to_scene(y_after, vxy, spin), contact, 0, "", steps

    # The chained run: the checker's own orbit from state0.
    times, contacts, states, flags = [], [], [], []
    total_steps = 0
    s, t_abs = state0, 0.0
    for i in range(n):
        dt, s_new, contact, flag, message, steps = one_flight(s)
        total_steps += steps
        if flag:
            flags.append(CheckFlag(index=i, kind=_FLAG_NAMES[flag], message=f"after t = {t_abs:.6g}: {message}"))
            break
        assert dt is not None  # a flight without a flag has its time and state
        t_abs += dt
        s = s_new
        times.append(t_abs)
        contacts.append(contact)
        states.append(s)
    t = np.asarray(times, dtype=np.float64)
    contact = np.asarray(contacts, dtype=np.int32)
    state = np.asarray(states, dtype=np.float64).reshape(-1, size)

    # Scales.
    V = math.sqrt(2.0 * float(scene.energy(jnp.asarray(state0))) / mass) or 1.0
    spin_scale = V / math.sqrt(inertia / mass) if not frozen else V / h
    scales = (h / V, h, V, spin_scale)
    ref_t, ref_c, ref_s = (np.asarray(a) for a in (reference.t, reference.contact, reference.state))

    # One collision at a time: the checker restarted from each of jaxbill's states.
    local_max, local_bad = np.zeros(5), np.zeros(0, bool)
    if local == "restart":
        starts = np.concatenate([state0[None], ref_s[:-1]])
        t_prev = np.concatenate([[0.0], ref_t[:-1]])
        rows, bad = [], []
        for i in range(n):
            if not np.isfinite(t_prev[i]):
                break
            dt, s_new, c_new, flag, message, steps = one_flight(starts[i])
            total_steps += steps
            if flag:
                # Not verified: the flag makes the report untrusted. A start through a
                # wall is jaxbill's previous collision placing an end off its wall: a
                # disagreement too.
                flags.append(CheckFlag(index=i, kind="local " + _FLAG_NAMES[flag], message=message))
                bad.append(flag == 7)
                continue
            assert s_new is not None  # a flight without a flag has its time and state
            d = _scaled_deviation(
                (np.array([dt]), s_new[None]), (np.array([ref_t[i] - t_prev[i]]), ref_s[i][None]), scales, planar_scene
            )[0]
            rows.append(d)
            bad.append(bool(c_new != ref_c[i] or np.any(d > tol)))
        local_bad = np.asarray(bad, bool)
        if rows:
            local_max = np.max(np.asarray(rows), axis=0)

    # The chaos horizon: jb.orbit from four starts perturbed by the checker's own
    # one-collision error in each part of the state (measured above; 10 rtol
    # without it), at least 1e-12.
    if horizon_eps is None:
        own = local_max[1:] if local == "restart" else np.full(4, 10.0 * rtol)
        eps = np.clip(own, 1e-12, 0.1 * tol)
    else:
        eps = np.full(4, float(horizon_eps))
    bumps = _perturbations(state0, planar_scene, eps, scales)
    try:
        perturbed = _orbit(scene, bumps, n)
    except ValueError:  # state0 on a wall: perturb the velocities only
        bumps = state0 + (bumps - state0) * (np.arange(size) >= size // 2)
        perturbed = _orbit(scene, bumps, n)
    departed = np.zeros(n, bool)
    for b in range(len(bumps)):
        mine = (np.asarray(perturbed.t[b]), np.asarray(perturbed.state[b]))
        pd = _scaled_deviation(mine, (ref_t, ref_s), scales, planar_scene)
        departed |= (np.asarray(perturbed.contact[b]) != ref_c) | np.any(pd > tol, axis=1)
    horizon = first_index(departed)
    horizon = n if horizon is None else horizon

    m = min(len(t), horizon)
    dev = _scaled_deviation((t[:m], state[:m]), (ref_t[:m], ref_s[:m]), scales, planar_scene)

    report = comparison_report(n, contact, ref_c, horizon, tol, dev, local_max, local_bad, flags, total_steps, start)
    return CheckResult(t=t, contact=contact, state=state, orbit=reference, report=report)
