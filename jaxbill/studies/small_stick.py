"""The small-stick law: the largest Lyapunov exponent of a short stick, measured and derived.

Three parts, each usable alone.

Measurement over an invariant ensemble
--------------------------------------
``ensemble_lyapunov`` carries one tangent vector along every orbit of an
ensemble (the flow's tangent map at each collision, renormalised) and reads
its log-stretch ``Lambda_i(t)`` at common times ``t_j`` of a window
``[0, T]``, counting each orbit's collisions in the same window (Kac's lemma). Started from an
invariant (Liouville) measure, totals over the ensemble then estimate the
invariant measure's averages::

    per unit time:      lambda_t = sum_i w_i [Lambda_i(T) - Lambda_i(T0)] / (sum_i w_i (T - T0))
    per collision:      lambda_c = sum_i w_i [Lambda_i(T) - Lambda_i(T0)] / sum_i w_i [N_i(T) - N_i(T0)]

with ``T0 = discard * T``: differencing removes the O(1) transient of
``Lambda`` (the tangent vector's alignment, the norm's units) and halves and
more the ``log(t) / t`` bias of orbits that stretch only linearly. Error bars
are the spread between ``n_sub`` independent sub-ensembles (standard error of
their mean). A fixed number of collisions per orbit would weight slow orbits
wrongly; a common time window does not.

The reduced kick map (fixed inertia, small ``ell``)
--------------------------------------------------
For ``ell << R`` the centre moves almost like a point in the billiard
(the circle: chord angle ``phi`` to the tangent, flight time
``tau = 2 R sin(phi) / |v|``, central angle ``2 phi`` per flight). Let
``psi = alpha - theta`` be the stick's angle to the wall normal ``n`` at the
contact (``theta`` the polar angle of the contact). The end that hits is the
one nearer the wall, ``k = sign(cos psi)``; its lever arm is
``s = k ell (u x n) = -ell sign(cos psi) sin psi``, and the impulse
``J = 2 v_n / (1/M + s^2/I) ~ 2 M (v . n)`` gives the spin kick::

    omega' = omega + (2 M ell (v . n) / I) g(psi),     g(psi) = sign(cos psi) sin psi

``g`` is pi-periodic, increasing with slope ``|cos psi|`` and jumps from +1 to
-1 where the stick is parallel to the wall (``psi = pi/2``): a sawtooth. With
``y = omega tau`` (the turn per flight) and ``x = psi``::

    y' = y + K g(x),   x' = x + y' - 2 phi,   K = 2 M ell (v . n) tau / I = 4 M R ell sin(phi)^2 / I

(circle; in any table ``K_n = 2 M ell v_n tau_n / I`` varies along the orbit).
Its Jacobian ``[[1 + K g', 1], [K g', 1]]`` has trace ``2 + K |cos x| >= 2``:
every matrix maps the positive quadrant into itself, so the map is hyperbolic
everywhere (no elliptic points, no KAM tori) for every ``K > 0``. For small
``K`` the tangent dynamics is ``d^2 dx/dn^2 = K g'(x_n) dx`` with ``x_n``
running fast over ``g'``'s period, whose mean is ``<|cos|> = 2/pi``::

    lambda_map = sqrt(2 K / pi)    per iteration (``reduced_map_exponent``)

``reduced_map_lyapunov`` simulates the map (plain numpy) to check it. For the
stick this gives, per orbit (speed ``v`` held, slow at small ``ell``)::

    per unit time:   lambda_t = |v| sqrt(4 M ell h / (pi I)),   h = sum_n sin(phi_n) / (path length)

(the circle: ``h = 1/(2R)`` for every orbit). ``predicted_small_stick_exponent``
averages it over the Liouville ensemble (``h`` from a point billiard in the
ellipse, simulated in numpy; closed form for the circle).

The paper's stick (``I = M ell^2``, spin energy of order one)
-------------------------------------------------------------
Then ``omega ~ |v| / ell``: in one flight the stick turns ``~ R / ell`` times,
and a change ``d psi`` at one wall visit changes the outgoing spin by
``~ |v| / ell`` times it, so the next visit's phase by ``~ chord / ell`` times
it. Per wall visit the stretch is ``log(1/ell) + O(1)``: the exponent grows
logarithmically, with slope ``d lambda_t / d log(1/ell)`` equal to the rate of
wall visits, ``<|v|> P / (pi A)`` (``visit_rate``), and per collision
``1 / nu``, ``nu`` the mean number of collisions per visit (the two ends can
hit in quick succession; ``EnsembleLyapunov.long_flights`` counts visits).

Units: lengths as the scene's, times in the same units as the scene's
velocities imply; exponents per unit time (1/time) or per collision.
"""

from __future__ import annotations

import dataclasses
import json
import math
import pathlib
import time as _time
from functools import partial

import jax
import jax.numpy as jnp
import numpy as np
from jax.typing import ArrayLike
from jaxtyping import Float

from jaxbill._analysis.chaos import sample_energy_shell
from jaxbill._engine.collision import collide
from jaxbill._engine.tangent import dynamical_indices, phase_velocity
from jaxbill._scenes.circle.scene import StickInCircle
from jaxbill._scenes.ellipse.scene import StickInEllipse

__all__ = [
    "EnsembleLyapunov",
    "ensemble_lyapunov",
    "sawtooth_kick",
    "circle_kick_strength",
    "reduced_map_exponent",
    "reduced_map_lyapunov",
    "circle_twist",
    "circle_reduced_exponents",
    "point_billiard_flux",
    "predicted_small_stick_exponent",
    "visit_rate",
    "measure_small_stick_law",
    "predicted_coefficients",
    "fit_power_law",
    "fit_log_law",
    "load_small_stick_data",
    "small_stick_figure",
    "study_scene",
    "SCENES",
    "SCALINGS",
]

DATA_FILE = pathlib.Path(__file__).resolve().parents[2] / "notebooks" / "data" / "small_stick_law.npz"


# ---------------------------------------------------------------------------
# Ensemble Lyapunov exponent in a common time window
# ---------------------------------------------------------------------------


@dataclasses.dataclass(frozen=True)
class EnsembleLyapunov:
    """Largest Lyapunov exponent of an ensemble in a common time window ``[0, T]``.

    ``B`` orbits, ``J`` checkpoints ``times``; ``n_sub`` sub-ensembles.

    Attributes:
        per_time: estimate of the ensemble's exponent per unit time (1/time).
        per_time_err: its standard error from the sub-ensembles' spread.
        per_collision: estimate per collision (dimensionless).
        per_collision_err: its standard error.
        per_time_sub, per_collision_sub: ``(n_sub,)`` each sub-ensemble's estimate.
        times: ``(J,)`` checkpoint times ``T j / J``, ``j = 1..J``.
        log_stretch: ``(B, J)`` ``Lambda_i(t_j)``, the tangent vector's log-length
            just after the last collision at or before ``t_j`` (0 at ``t = 0``).
        collisions: ``(B, J)`` collisions of each orbit in ``[0, t_j]``.
        long_flights: ``(B, J)`` of those, collisions reached by a flight of the
            centre longer than ``long_flight`` (wall visits, for a short stick).
        weights: ``(B,)`` the ensemble's weights (1 for a Liouville sample on
            the energy shell alone).
        window: ``(T0, T)``, the differenced window.
        failed: orbits dropped because their state became NaN (should be 0).
        seconds: wall-clock time of the run, compilation included.
    """

    per_time: float
    per_time_err: float
    per_collision: float
    per_collision_err: float
    per_time_sub: np.ndarray
    per_collision_sub: np.ndarray
    times: np.ndarray
    log_stretch: np.ndarray
    collisions: np.ndarray
    long_flights: np.ndarray
    weights: np.ndarray
    window: tuple[float, float]
    failed: int
    seconds: float

    @property
    def mean_collisions(self) -> float:
        """Weighted mean collisions per orbit in ``[0, T]``."""
        return float(np.average(self.collisions[:, -1], weights=self.weights))

    @property
    def collisions_per_visit(self) -> float:
        """Total collisions over total long flights in ``[0, T]`` (``nu``)."""
        visits = np.sum(self.weights * self.long_flights[:, -1])
        return float(np.sum(self.weights * self.collisions[:, -1]) / visits) if visits > 0 else math.inf


def _metric(scene) -> jax.Array:
    """Weights of the state coordinates in the tangent norm: mass-weighted (sqrt(M), sqrt(I))."""
    m = jnp.sqrt(scene.mass)
    inertia = jnp.asarray(scene.inertia)
    i = jnp.where(jnp.isfinite(inertia) & (inertia > 0), jnp.sqrt(jnp.where(jnp.isfinite(inertia), inertia, 1.0)), 0.0)
    return jnp.stack([m, m, i, m, m, i])


@partial(jax.jit, static_argnames=("n",))
def _advance(scene, carry, checkpoints, horizon, long_flight, n):
    """``n`` collisions of every orbit of ``carry`` (vmapped), frozen once past ``horizon``."""
    metric = _metric(scene)

    def one(c):
        def body(c, _):
            state, w, t, logw, k, visits, done, cp_log, cp_k, cp_v = c
            (new, dt, _), (dnew, ddt, _) = jax.jvp(lambda s: collide(scene, s), (state,), (w,))
            dw = dnew - phase_velocity(scene, new) * ddt
            norm = jnp.linalg.norm(metric * dw)
            t_new = t + dt
            ok = (t_new <= horizon) & ~done
            path = jnp.hypot(state[3], state[4]) * dt
            state = jnp.where(ok, new, state)
            w = jnp.where(ok, dw / norm, w)
            logw = jnp.where(ok, logw + jnp.log(norm), logw)
            logw = jnp.where(jnp.isnan(t_new) & ~done, jnp.nan, logw)  # a poisoned collision: drop the orbit
            k = jnp.where(ok, k + 1, k)
            visits = jnp.where(ok & (path > long_flight), visits + 1, visits)
            t = jnp.where(ok, t_new, t)
            done = done | (t_new > horizon) | ~jnp.isfinite(t_new)
            within = ok & (t <= checkpoints)
            cp_log = jnp.where(within, logw, cp_log)
            cp_k = jnp.where(within, k, cp_k)
            cp_v = jnp.where(within, visits, cp_v)
            return (state, w, t, logw, k, visits, done, cp_log, cp_k, cp_v), None

        return jax.lax.scan(body, c, None, length=n)[0]

    return jax.vmap(one)(carry)


def _ladder(size: int, total: int, smallest: int = 16) -> int:
    """The batch size for ``size`` active orbits of ``total``: ``total / 4^k`` rounded up, at least ``smallest``."""
    b = total
    while b > smallest and -(-b // 4) >= size:
        b = -(-b // 4)
    return max(b, min(smallest, total))


def _window_estimates(log_stretch, collisions, weights, j0, t0, t1):
    dl = log_stretch[:, -1] - (log_stretch[:, j0] if j0 >= 0 else 0.0)
    dn = collisions[:, -1] - (collisions[:, j0] if j0 >= 0 else 0)
    total_w = np.sum(weights)
    per_time = np.sum(weights * dl) / (total_w * (t1 - t0))
    per_collision = np.sum(weights * dl) / np.sum(weights * dn) if np.sum(weights * dn) > 0 else np.nan
    return float(per_time), float(per_collision)


def ensemble_lyapunov(
    scene: StickInCircle | StickInEllipse,
    states: Float[ArrayLike, "B 6"],
    T: float,
    *,
    weights: Float[ArrayLike, " B"] | None = None,
    n_sub: int = 8,
    n_checkpoints: int = 16,
    discard: float = 0.5,
    chunk: int = 256,
    long_flight: float | None = None,
    seed: int = 0,
) -> EnsembleLyapunov:
    """Largest Lyapunov exponent of an ensemble, per unit time and per collision, in a common window.

    Every orbit runs until its next collision would fall after ``T``; the
    tangent vector (start: random, in the dynamical directions, seeded) is
    pushed by the flow's tangent map at each collision (a JVP of
    ``collide`` minus the flow direction times the collision-time change)
    and renormalised in the mass-weighted norm
    ``|(sqrt(M) dx, sqrt(M) dy, sqrt(I) dalpha, sqrt(M) dvx, sqrt(M) dvy, sqrt(I) domega)|``.
    Orbits still running are re-batched to fewer lanes as others finish.
    See the module docstring for the estimators.

    Args:
        scene: a ``StickInCircle`` or ``StickInEllipse`` (state ``[x, y, alpha, vx, vy, omega]``).
        states: ``(B, 6)`` starts, from an invariant measure (e.g.
            ``sample_energy_shell``); ``B`` a multiple of ``n_sub``.
        T: the window's end (time units); the same for every orbit.
        weights: ``(B,)`` the starts' weights (``sample_energy_shell``'s second
            output); default all 1.
        n_sub: number of independent sub-ensembles (consecutive blocks of ``B / n_sub``).
        n_checkpoints: ``J``, checkpoints at ``T j / J``.
        discard: the estimators use ``[T0, T]`` with ``T0 = discard * T``
            rounded down to a checkpoint; 0 uses the whole window.
        chunk: collisions per compiled call.
        long_flight: a flight of the centre longer than this (length) counts as a
            wall visit (``long_flights``); default ``10 * ell`` (a fast stick's
            ends can hit in quick succession within one visit).
        seed: seed of the starting tangent vectors.

    Returns:
        ``EnsembleLyapunov``.

    Raises:
        ValueError: a scene without the planar stick's state, ``B`` not a multiple of ``n_sub``, ``T <= 0``.
    """
    states = np.asarray(states, dtype=np.float64)
    if states.ndim != 2 or states.shape[1] != 6 or not hasattr(scene, "inertia"):
        raise ValueError("ensemble_lyapunov takes a StickInCircle or StickInEllipse and states of shape (B, 6)")
    B = states.shape[0]
    if n_sub < 2 or B % n_sub:
        raise ValueError(f"the {B} orbits must split into n_sub = {n_sub} >= 2 equal sub-ensembles")
    if not T > 0:
        raise ValueError(f"T must be positive, got {T}")
    weights = np.ones(B) if weights is None else np.asarray(weights, dtype=np.float64)
    if long_flight is None:
        long_flight = 10.0 * float(scene.ell)
    started = _time.perf_counter()

    dyn = np.zeros(6)
    dyn[list(dynamical_indices(scene))] = 1.0
    w0 = np.random.default_rng(seed).normal(size=(B, 6)) * dyn
    w0 /= np.linalg.norm(w0 * np.asarray(_metric(scene)), axis=1, keepdims=True)
    J = int(n_checkpoints)
    checkpoints = jnp.asarray(T * np.arange(1, J + 1) / J)
    # state, tangent, time, log-stretch, collisions, long flights, done; checkpoint copies of the last three
    carry = [states.copy(), w0, np.zeros(B), np.zeros(B), np.zeros(B, np.int64), np.zeros(B, np.int64)]
    carry += [np.zeros(B, bool), np.zeros((B, J)), np.zeros((B, J), np.int64), np.zeros((B, J), np.int64)]

    while True:
        active = np.flatnonzero(~carry[6])
        if active.size == 0:
            break
        size = max(_ladder(active.size, B), active.size)
        idx = np.concatenate([active, np.full(size - active.size, active[0])])
        sub = tuple(jnp.asarray(c[idx]) for c in carry)
        out = _advance(scene, sub, checkpoints, float(T), float(long_flight), int(chunk))
        for c, o in zip(carry, out):
            c[active] = np.asarray(o)[: active.size]

    state, logw = carry[0], carry[3]
    good = np.isfinite(logw) & np.all(np.isfinite(state), axis=1)
    failed = int(B - good.sum())
    w_eff = np.where(good, weights, 0.0)
    log_stretch = np.where(good[:, None], carry[7], 0.0)
    collisions, long_flights = carry[8], carry[9]

    j0 = int(math.floor(discard * J)) - 1
    t0 = float(checkpoints[j0]) if j0 >= 0 else 0.0
    t1 = float(T)
    per_time, per_collision = _window_estimates(log_stretch, collisions, w_eff, j0, t0, t1)
    blocks = np.arange(B).reshape(n_sub, -1)
    subs = np.array([_window_estimates(log_stretch[b], collisions[b], w_eff[b], j0, t0, t1) for b in blocks])
    err = subs.std(axis=0, ddof=1) / math.sqrt(n_sub)
    return EnsembleLyapunov(
        per_time=per_time,
        per_time_err=float(err[0]),
        per_collision=per_collision,
        per_collision_err=float(err[1]),
        per_time_sub=subs[:, 0],
        per_collision_sub=subs[:, 1],
        times=np.asarray(checkpoints),
        log_stretch=log_stretch,
        collisions=collisions,
        long_flights=long_flights,
        weights=w_eff,
        window=(t0, t1),
        failed=failed,
        seconds=_time.perf_counter() - started,
    )


# ---------------------------------------------------------------------------
# The reduced sawtooth kick map
# ---------------------------------------------------------------------------


def sawtooth_kick(psi):
    """The spin-kick profile ``g(psi) = sign(cos psi) sin psi`` and its slope ``g'(psi) = |cos psi|``.

    ``psi``: the stick's angle to the wall normal at the contact (radians, any
    shape). A stick hitting the wall gets ``domega = (2 M ell v_n / I) g(psi)``
    to first order in ``ell`` (``v_n > 0`` the centre's speed into the wall).
    ``g`` is pi-periodic and jumps from +1 to -1 at ``psi = pi/2`` (stick
    parallel to the wall), where the other end becomes the nearer one.

    Returns:
        ``(g, g_prime)``, arrays of ``psi``'s shape.
    """
    psi = np.asarray(psi, dtype=np.float64)
    c = np.cos(psi)
    return np.where(c >= 0, 1.0, -1.0) * np.sin(psi), np.abs(c)


def circle_kick_strength(R, ell, sin_phi, *, mass=1.0, inertia=1.0):
    """Kick strength ``K = 2 M ell v_n tau / I = 4 M R ell sin(phi)^2 / I`` of the reduced map in a circle.

    ``v_n = |v| sin(phi)`` the normal speed, ``tau = 2 R sin(phi) / |v|`` the
    flight time of a chord at angle ``phi`` to the tangent; the speed cancels.
    Dimensionless (``y = omega tau`` is an angle). Broadcasts over arrays.
    """
    return 4.0 * mass * R * ell * np.asarray(sin_phi) ** 2 / inertia


def reduced_map_exponent(K):
    """Small-``K`` Lyapunov exponent of the sawtooth kick map, per iteration: ``sqrt(2 K / pi)``.

    From ``d^2 dx/dn^2 = K <g'> dx`` with ``<g'> = <|cos|> = 2/pi``. (A
    constant slope ``k`` would give ``arccosh(1 + k/2)`` exactly.)
    """
    return np.sqrt(2.0 * np.asarray(K, dtype=np.float64) / np.pi)


def reduced_map_lyapunov(K: float, n: int, *, n_orbits: int = 256, n_sub: int = 8, discard: float = 0.5, seed: int = 0):
    """Lyapunov exponent of the reduced kick map, simulated in plain numpy.

    The map on ``[0, pi)^2`` (area-preserving; its invariant measure is uniform)::

        y' = y + K g(x)  (mod pi),   x' = x + y'  (mod pi),   g = sawtooth_kick

    ``n_orbits`` orbits uniform on the torus, one tangent vector each,
    renormalised every iteration; the exponent is the mean growth over
    iterations ``[discard n, n]``, error from ``n_sub`` sub-ensembles.

    Returns:
        ``(lambda, error)`` per iteration.
    """
    rng = np.random.default_rng(seed)
    x, y = rng.uniform(0, np.pi, n_orbits), rng.uniform(0, np.pi, n_orbits)
    a = rng.uniform(0, 2 * np.pi, n_orbits)
    dx, dy = np.cos(a), np.sin(a)
    log_w = np.zeros(n_orbits)
    n0 = int(discard * n)
    log_w0 = log_w.copy()
    for i in range(n):
        g, gp = sawtooth_kick(x)
        dy = dy + K * gp * dx
        y = np.mod(y + K * g, np.pi)
        x = np.mod(x + y, np.pi)
        dx = dx + dy
        norm = np.hypot(dx, dy)
        dx, dy = dx / norm, dy / norm
        log_w += np.log(norm)
        if i + 1 == n0:
            log_w0 = log_w.copy()
    rates = (log_w - log_w0) / (n - n0)
    subs = rates.reshape(n_sub, -1).mean(axis=1)
    return float(rates.mean()), float(subs.std(ddof=1) / math.sqrt(n_sub))


def circle_twist(states, *, R: float, mass: float = 1.0, inertia: float = 1.0):
    """The reduced map's twist in the circle, where ``E`` and ``L`` fix the point's chord by ``omega``.

    In the circle ``E = M v^2/2 + I omega^2/2`` and ``L = M (x vy - y vx) + I omega``
    are conserved, so the centre's speed ``v(omega)`` and chord angle
    ``phi(omega) = arccos((L - I omega) / (M R v))`` are functions of the spin, and
    the reduced map is exactly a map of ``(psi, omega)``::

        omega' = omega + A g(psi),   psi' = psi + F(omega'),   F = omega tau - 2 phi,   tau = 2 R sin(phi) / v

    with ``A = 2 M ell v sin(phi) / I`` (per unit ``ell``: ``A / ell``). Its local
    kick strength is ``K = A F'(omega)``: ``F' = tau + omega dtau/domega - 2 dphi/domega``.
    The last two terms (the kick's recoil on the centre's chord) are of the same
    order as ``tau`` when ``I ~ M R^2``. ``F' > 0``: hyperbolic (chaotic, exponent
    ``sqrt(2 K / pi)`` per collision); ``F' < 0``: the sawtooth's elliptic side
    (orbits that look regular).

    Args:
        states: ``(B, 6)`` states ``[x, y, alpha, vx, vy, omega]`` (only ``v``, ``omega`` and ``L`` enter).
        R, mass, inertia: the circle's radius, ``M``, ``I``.

    Returns:
        ``(F_prime, tau, A_per_ell)``, each ``(B,)``: ``F'`` (time), the chord's
        flight time (time) and ``A / ell`` (1/(time length)).
    """
    x, y, _, vx, vy, om = np.asarray(states, dtype=np.float64).T
    E = 0.5 * mass * (vx**2 + vy**2) + 0.5 * inertia * om**2
    L = mass * (x * vy - y * vx) + inertia * om

    def advance(w):
        v = np.sqrt(np.maximum(2.0 * E - inertia * w**2, 0.0) / mass)
        phi = np.arccos(np.clip((L - inertia * w) / (mass * R * v), -1.0, 1.0))
        tau = 2.0 * R * np.sin(phi) / v
        return w * tau - 2.0 * phi, v, phi, tau

    h = 1e-6 * np.sqrt(2.0 * E / inertia)
    F_prime = (advance(om + h)[0] - advance(om - h)[0]) / (2.0 * h)
    _, v, phi, tau = advance(om)
    return F_prime, tau, 2.0 * mass * v * np.sin(phi) / inertia


def circle_reduced_exponents(states, ell, *, R: float, mass: float = 1.0, inertia: float = 1.0):
    """Per-orbit exponents the reduced ``(psi, omega)`` map predicts in the circle (fixed ``I``, small ``ell``).

    ``lambda_c = sqrt(2 A F' / pi)`` per collision where the twist ``F' > 0``
    (``circle_twist``), 0 where ``F' < 0``; ``lambda_t = lambda_c / tau``. Valid
    while ``v`` and ``phi`` barely move over the Lyapunov time (``ell`` small).

    Returns:
        ``(per_time, per_collision_ensemble, per_time_each, regular)``: the
        ensemble's exponent per unit time (mean of ``per_time_each``), per
        collision (``sum lambda_t / sum 1/tau``, the common-window ratio), the
        ``(B,)`` per-orbit exponents per unit time, and the ``(B,)`` mask ``F' < 0``.
    """
    F_prime, tau, a = circle_twist(states, R=R, mass=mass, inertia=inertia)
    lam_c = np.sqrt(2.0 * a * ell * np.maximum(F_prime, 0.0) / np.pi)
    lam_t = lam_c / tau
    return float(lam_t.mean()), float(lam_t.sum() / np.sum(1.0 / tau)), lam_t, F_prime < 0


def point_billiard_flux(a: float, b: float, *, n_orbits: int = 2000, n_collisions: int = 400, seed: int = 0):
    """Per-orbit wall flux ``h`` of a point in the ellipse ``x^2/a^2 + y^2/b^2 <= 1`` (plain numpy).

    Starts uniform in the ellipse with uniform directions (the Liouville
    measure; unit speed). For each orbit ``h = sum_n sin(phi_n) / (path length)``
    over its first ``n_collisions`` (``phi_n`` the angle to the tangent at
    collision ``n``): the normal speed delivered to the wall per unit time, per
    unit speed squared (1/length). The circle of radius ``R``: ``h = 1/(2R)``.

    Returns:
        ``(h, rate)``: ``h`` ``(n_orbits,)``, and ``rate``, the mean over the
        orbits of their collisions per unit path length, which estimates
        ``P / (pi A)`` (Santalo's mean free path ``pi A / P``). Pooling all
        chords instead (the same number of collisions per orbit) would weight
        orbits with long chords too much: in the integrable ellipse each
        orbit keeps its own mean chord.
    """
    rng = np.random.default_rng(seed)
    r, th = np.sqrt(rng.uniform(0, 1, n_orbits)), rng.uniform(0, 2 * np.pi, n_orbits)
    px, py = a * r * np.cos(th), b * r * np.sin(th)
    ang = rng.uniform(0, 2 * np.pi, n_orbits)
    dx, dy = np.cos(ang), np.sin(ang)
    sum_sin, path = np.zeros(n_orbits), np.zeros(n_orbits)
    for i in range(n_collisions + 1):
        qa = dx**2 / a**2 + dy**2 / b**2
        qb = px * dx / a**2 + py * dy / b**2
        qc = px**2 / a**2 + py**2 / b**2 - 1.0
        disc = np.sqrt(np.maximum(qb**2 - qa * qc, 0.0))
        with np.errstate(divide="ignore", invalid="ignore"):
            t = np.where(qb > 0, -qc / (qb + disc), (disc - qb) / qa)  # larger root, cancellation-free
        px, py = px + t * dx, py + t * dy
        nx, ny = px / a**2, py / b**2
        nn = np.hypot(nx, ny)
        nx, ny = nx / nn, ny / nn
        dn = dx * nx + dy * ny
        if i > 0:  # the start is inside: its first flight is not a chord
            sum_sin += dn
            path += t
        dx, dy = dx - 2 * dn * nx, dy - 2 * dn * ny
    h = sum_sin / path
    rate = np.mean(n_collisions / path)  # each orbit's own rate, averaged over the flow measure (Kac)
    return h, float(rate)


def predicted_small_stick_exponent(
    a: float, b: float, ell, *, mass: float = 1.0, inertia: float = 1.0, energy: float = 0.5, h=None, rate=None
):
    """The reduced map's prediction for a short stick at fixed inertia, over the Liouville ensemble.

    Per orbit ``lambda_t = |v| sqrt(4 M ell h / (pi I))`` (module docstring).
    On the energy shell ``(sqrt(M) v, sqrt(I) omega)`` is uniform on a sphere of
    radius ``sqrt(2E)``, so ``<|v|> = sqrt(2E/M) pi/4`` and ``|v|`` is
    independent of ``h``; the collision rate is ``<|v|> P / (pi A)``.

    Args:
        a, b: the table's semi-axes (``a = b = R``: the circle, closed form).
        ell: half-length(s) (array-like).
        mass, inertia, energy: ``M``, ``I`` (fixed), ``E``.
        h, rate: ``point_billiard_flux``'s output, to reuse (computed if ``None``).

    Returns:
        ``(per_time, per_collision)``, arrays of ``ell``'s shape. For the circle
        ``per_collision = sqrt(pi M R ell / (2 I))`` and
        ``per_time = sqrt(2E/M) (pi/4) sqrt(2 M ell / (pi I R))``.
    """
    ell = np.asarray(ell, dtype=np.float64)
    if a == b:
        mean_sqrt_h, rate = math.sqrt(1.0 / (2.0 * a)), 2.0 / (math.pi * a)
    else:
        if h is None or rate is None:
            h, rate = point_billiard_flux(a, b)
        mean_sqrt_h = float(np.mean(np.sqrt(h)))
    mean_speed = math.sqrt(2.0 * energy / mass) * math.pi / 4.0
    per_time = mean_speed * np.sqrt(4.0 * mass * ell / (math.pi * inertia)) * mean_sqrt_h
    return per_time, per_time / visit_rate(a, b, mass=mass, energy=energy)  # <|v|> P / (pi A), exact


def visit_rate(a: float, b: float, *, mass: float = 1.0, energy: float = 0.5) -> float:
    """Mean rate of wall visits of the centre over the Liouville ensemble: ``<|v|> P / (pi A)`` (1/time).

    The predicted slope of ``lambda_t`` against ``log(1/ell)`` for the paper's
    stick (``I = M ell^2``). ``P`` by Ramanujan's second formula for the
    ellipse (exact for the circle; relative error below 1e-9 at ``b/a = 0.7``).
    """
    h = ((a - b) / (a + b)) ** 2
    perimeter = math.pi * (a + b) * (1 + 3 * h / (10 + math.sqrt(4 - 3 * h)))
    mean_speed = math.sqrt(2.0 * energy / mass) * math.pi / 4.0
    return mean_speed * perimeter / (math.pi * math.pi * a * b)


# ---------------------------------------------------------------------------
# Fits
# ---------------------------------------------------------------------------


def fit_power_law(ell, lam, err):
    """Weighted least-squares fit ``lambda = c ell^p`` in log-log; returns ``(p, p_err, c, c_err, chi2_per_dof)``.

    Errors ``err`` are standard errors of ``lam``; the parameter errors are
    scaled by ``sqrt(chi2/dof)`` when that exceeds 1 (so they cover the scatter).
    """
    x, y = np.log(np.asarray(ell)), np.log(np.asarray(lam))
    s = np.asarray(err) / np.asarray(lam)
    (p, logc), cov, chi2 = _wls(x, y, s)
    return p, math.sqrt(cov[0, 0]), math.exp(logc), math.exp(logc) * math.sqrt(cov[1, 1]), chi2


def fit_log_law(ell, lam, err):
    """Weighted fit ``lambda = A log(1/ell) + C``; returns ``(A, A_err, C, C_err, chi2_per_dof)``."""
    x = np.log(1.0 / np.asarray(ell))
    (A, C), cov, chi2 = _wls(x, np.asarray(lam), np.asarray(err))
    return A, math.sqrt(cov[0, 0]), C, math.sqrt(cov[1, 1]), chi2


def _wls(x, y, s):
    X = np.stack([x, np.ones_like(x)], axis=1) / s[:, None]
    coef, *_ = np.linalg.lstsq(X, y / s, rcond=None)
    cov = np.linalg.inv(X.T @ X)
    dof = max(len(x) - 2, 1)
    chi2 = float(np.sum(((X @ coef) - y / s) ** 2) / dof)
    return coef, cov * max(chi2, 1.0), chi2


# ---------------------------------------------------------------------------
# The full measurement, its data file and its figure
# ---------------------------------------------------------------------------

SCENES = {"circle": dict(a=2.0, b=2.0), "ellipse": dict(a=2.0, b=1.4)}
"""The study's two tables by name, their semi-axes ``a, b`` (the circle: ``a = b = R``)."""
SCALINGS = ("fixed_I", "paper")
"""The study's two inertias: ``"fixed_I"``, ``I = 1``; ``"paper"``, ``I = M ell^2``."""


def study_scene(name: str, ell: float, scaling: str, mass: float = 1.0):
    """The study's stick of half-length ``ell`` in its table ``name``, with the inertia of ``scaling``.

    Args:
        name: ``"circle"`` (``R = 2``) or ``"ellipse"`` (``a = 2``, ``b = 1.4``): ``SCENES``.
        ell: half-length of the stick (length).
        scaling: ``"fixed_I"`` (``I = 1``: the spin's energy is not scaled) or
            ``"paper"`` (``I = M ell^2``, the paper's stick): ``SCALINGS``.
        mass: total mass ``M``.
    """
    if name not in SCENES:
        raise ValueError(f"name must be one of {sorted(SCENES)}; got {name!r}")
    if scaling not in SCALINGS:
        raise ValueError(f"scaling must be one of {SCALINGS}; got {scaling!r}")
    inertia = 1.0 if scaling == "fixed_I" else mass * ell**2
    a, b = SCENES[name]["a"], SCENES[name]["b"]
    if a == b:
        return StickInCircle(R=a, ell=ell, mass=mass, inertia=inertia)
    return StickInEllipse(a=a, b=b, ell=ell, mass=mass, inertia=inertia)


def _window(name: str, ell: float, scaling: str, growth: float, min_collisions: float) -> float:
    """A window ``T`` long enough for ``growth`` e-foldings (from the predictions) and ``min_collisions``."""
    g = SCENES[name]
    rate = visit_rate(g["a"], g["b"])
    if scaling == "fixed_I":
        lam_t = predicted_small_stick_exponent(g["a"], g["a"], ell)[0]  # the circle's closed form as a guide
    else:
        lam_t = rate * max(math.log(1.0 / ell), 1.0)
    return max(growth / float(lam_t), min_collisions / rate)


def measure_small_stick_law(
    ells=(1e-1, 3e-2, 1e-2, 3e-3, 1e-3, 3e-4, 1e-4, 3e-5, 1e-5, 3e-6, 1e-6),
    *,
    scenes=("circle", "ellipse"),
    scalings=SCALINGS,
    n_orbits: int = 512,
    n_sub: int = 8,
    growth: float = 60.0,
    min_collisions: float = 1000.0,
    energy: float = 0.5,
    seed: int = 0,
    log=print,
) -> dict:
    """Measure ``lambda(ell)`` for each scene and scaling; returns arrays ready for ``np.savez``.

    Each point: ``n_orbits`` starts from ``sample_energy_shell`` (Liouville
    on the shell ``E = energy``; energy only, weights 1), a window ``T`` from
    ``_window`` (about ``growth`` e-foldings by the predictions, at least
    ``min_collisions`` collisions per orbit on average), ``ensemble_lyapunov``
    with ``n_sub`` sub-ensembles. Keys ``"{scene}/{scaling}/{field}"`` with
    fields ``ell, per_time, per_time_err, per_collision, per_collision_err,
    T, mean_collisions, collisions_per_visit, failed, seconds`` (``(n_ell,)``),
    ``orbit_per_time`` (``(n_ell, n_orbits)``, each orbit's differenced
    exponent) and, for the circle at fixed ``I``, ``orbit_predicted`` and
    ``orbit_regular`` (``circle_reduced_exponents`` for the same starts);
    plus ``"meta"`` (a JSON string of the settings).
    """
    out: dict = {}
    for name in scenes:
        g = SCENES[name]
        for scaling in scalings:
            rows, per_orbit, predicted, regular = [], [], [], []
            for k, ell in enumerate(ells):
                scene = study_scene(name, ell, scaling)
                states, weights = sample_energy_shell(scene, n_orbits, energy=energy, seed=seed + 1000 * k)
                T = _window(name, ell, scaling, growth, min_collisions)
                r = ensemble_lyapunov(scene, states, T, weights=weights, n_sub=n_sub, seed=seed + k)
                j0 = int(math.floor(0.5 * r.log_stretch.shape[1])) - 1
                per_orbit.append((r.log_stretch[:, -1] - r.log_stretch[:, j0]) / (r.window[1] - r.window[0]))
                if name == "circle" and scaling == "fixed_I":
                    _, _, each, reg = circle_reduced_exponents(states, ell, R=g["a"])
                    predicted.append(each)
                    regular.append(reg)
                rows.append(
                    (ell, r.per_time, r.per_time_err, r.per_collision, r.per_collision_err, T)
                    + (r.mean_collisions, r.collisions_per_visit, r.failed, r.seconds)
                )
                log(
                    f"{name:8s} {scaling:8s} ell={ell:8.1e} T={T:10.4g} N={r.mean_collisions:9.1f} "
                    f"lam_t={r.per_time:.5g}+-{r.per_time_err:.2g} lam_c={r.per_collision:.5g}+-"
                    f"{r.per_collision_err:.2g} nu={r.collisions_per_visit:.3f} failed={r.failed} {r.seconds:.1f}s"
                )
            key = f"{name}/{scaling}"
            fields = ("ell", "per_time", "per_time_err", "per_collision", "per_collision_err", "T")
            fields += ("mean_collisions", "collisions_per_visit", "failed", "seconds")
            for i, f in enumerate(fields):
                out[f"{key}/{f}"] = np.array([row[i] for row in rows], dtype=np.float64)
            out[f"{key}/orbit_per_time"] = np.array(per_orbit)
            if predicted:
                out[f"{key}/orbit_predicted"] = np.array(predicted)
                out[f"{key}/orbit_regular"] = np.array(regular)
    meta = dict(n_orbits=n_orbits, n_sub=n_sub, growth=growth, min_collisions=min_collisions, energy=energy, seed=seed)
    meta |= dict(scenes={s: SCENES[s] for s in scenes}, mass=1.0, fixed_inertia=1.0, discard=0.5)
    out["meta"] = np.array(json.dumps(meta))
    return out


def predicted_coefficients(*, n_samples: int = 20000, energy: float = 0.5, seed: int = 7) -> dict:
    """Prefactors ``c`` of ``lambda = c sqrt(ell)`` (fixed ``I = 1``, ``M = 1``) from the reduced map.

    ``"{scene}/frozen/{per}"``: the frozen-point approximation (twist ``F' = tau``,
    ``predicted_small_stick_exponent``) for both scenes; ``"circle/twist/{per}"``:
    the circle's exact twist (``circle_reduced_exponents``) averaged over
    ``n_samples`` Liouville starts; ``"circle/twist/regular_fraction"``: the
    share of starts with ``F' < 0``. ``per`` is ``per_time`` or ``per_collision``.
    """
    out = {}
    for name, g in SCENES.items():
        t, c = predicted_small_stick_exponent(g["a"], g["b"], 1.0, energy=energy)
        out[f"{name}/frozen/per_time"], out[f"{name}/frozen/per_collision"] = float(t), float(c)
    states, _ = sample_energy_shell(study_scene("circle", 1e-3, "fixed_I"), n_samples, energy=energy, seed=seed)
    t, c, _, regular = circle_reduced_exponents(states, 1.0, R=SCENES["circle"]["a"])
    out["circle/twist/per_time"], out["circle/twist/per_collision"] = t, c
    out["circle/twist/regular_fraction"] = float(regular.mean())
    return out


def load_small_stick_data(path=None) -> dict:
    """The stored measurement (``notebooks/data/small_stick_law.npz`` by default) as a dict of arrays."""
    with np.load(DATA_FILE if path is None else path) as f:
        return {k: f[k] for k in f.files}


def small_stick_figure(out_dir, quick: bool = True, *, data=None) -> pathlib.Path:
    """Draw the small-stick law: ``lambda(ell)`` per collision and per unit time, both scenes, both scalings.

    Args:
        out_dir: folder to write ``small_stick_law.png`` into (created if needed).
        quick: ``True``: from the stored data (``load_small_stick_data``), or,
            when no data file exists, a small live measurement (three ``ell``,
            64 orbits, about 20 s); ``False``: the full measurement
            (``measure_small_stick_law``, about 10 minutes on two cores).
        data: a dict as ``load_small_stick_data`` returns, to draw instead.

    Returns:
        The path of the PNG. Measured points with sub-ensemble error bars, the
        fitted laws (dashed; ``ell <= 1e-3`` at fixed ``I``, ``ell <= 1e-2`` for
        the paper's stick) and the reduced map's prediction (fixed ``I``,
        dotted) or the visit-rate slope (``I = M ell^2``, dotted, through the
        smallest ``ell``).
    """
    from matplotlib.figure import Figure

    if data is None:
        if not quick:
            data = measure_small_stick_law(log=lambda *_: None)
        elif DATA_FILE.exists():
            data = load_small_stick_data()
        else:
            data = measure_small_stick_law((1e-2, 1e-3, 1e-4), n_orbits=64, growth=30.0, log=lambda *_: None)
    fig = Figure(figsize=(11, 8.5), constrained_layout=True)
    axes = fig.subplots(2, 2)
    colors = {"circle": "C0", "ellipse": "C3"}
    for row, per in enumerate(("per_collision", "per_time")):
        for col, scaling in enumerate(SCALINGS):
            ax = axes[row, col]
            for name in SCENES:
                key = f"{name}/{scaling}"
                if f"{key}/ell" not in data:
                    continue
                ell, lam, err = data[f"{key}/ell"], data[f"{key}/{per}"], data[f"{key}/{per}_err"]
                ax.errorbar(ell, lam, yerr=err, fmt="o", ms=4, color=colors[name], capsize=2, label=name)
                grid = np.geomspace(ell.min(), ell.max(), 50)
                g = SCENES[name]
                if scaling == "fixed_I":  # fits over the short sticks, where the reduced map applies
                    sel = ell <= 1e-3
                    p, p_err, c, _, _ = fit_power_law(ell[sel], lam[sel], err[sel])
                    ax.plot(grid, c * grid**p, "--", color=colors[name], lw=1, label=f"fit: p = {p:.3f} ± {p_err:.3f}")
                    twist = f"prediction/{name}/twist/{per}"
                    if twist in data:
                        pred, label = float(data[twist]) * np.sqrt(grid), "reduced map, exact twist"
                    else:
                        pred = predicted_small_stick_exponent(g["a"], g["b"], grid)[0 if per == "per_time" else 1]
                        label = "reduced map, frozen point (F' = tau)"
                    ax.plot(grid, pred, ":", color=colors[name], lw=1.5, label=label)
                    ax.set_yscale("log")
                else:
                    sel = ell <= 1e-2
                    A, A_err, C, _, _ = fit_log_law(ell[sel], lam[sel], err[sel])
                    ax.plot(
                        grid,
                        A * np.log(1 / grid) + C,
                        "--",
                        color=colors[name],
                        lw=1,
                        label=f"fit slope {A:.3f} ± {A_err:.3f}",
                    )
                    if per == "per_time":
                        slope, what = visit_rate(g["a"], g["b"]), "visit-rate slope"
                    else:  # one visit's log(1/ell) spread over nu collisions
                        slope, what = 1.0 / float(np.mean(data[f"{key}/collisions_per_visit"])), "1/nu slope"
                    ax.plot(grid, lam[-1] + slope * np.log(ell[-1] / grid), ":", color=colors[name], lw=1.5)
                    ax.lines[-1].set_label(f"{what} {slope:.3f}")
            ax.set_xscale("log")
            ax.set_xlabel("ell (half-length; R = 2 or a = 2, b = 1.4)")
            unit = "per collision" if per == "per_collision" else "per unit time"
            title = "fixed I = 1" if scaling == "fixed_I" else "paper's stick I = M ell^2"
            ax.set_title(f"{title}: lambda {unit}")
            ax.legend(fontsize=7)
    out = pathlib.Path(out_dir)
    out.mkdir(parents=True, exist_ok=True)
    path = out / "small_stick_law.png"
    fig.savefig(path, dpi=110)
    return path
