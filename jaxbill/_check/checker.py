"""An independent check of ``jb.orbit``: the spiral-column billiard integrated with diffrax.

The stick's state ``[x, y, alpha, vx, vy, omega]`` is a point ``(x, y, z)``,
``z = sqrt(I/M) alpha``, with velocity ``(vx, vy, vz)``, ``vz = sqrt(I/M) omega``.
The kinetic energy is ``M |(vx, vy, vz)|^2 / 2``: in these coordinates the
metric is Euclidean, so the elastic impulse is a specular reflection. Between
collisions the point flies straight; here that flight is *integrated* as the
ODE ``d(x, y, z)/dt = v, dv/dt = 0`` with a diffrax solver, not evaluated in
closed form. The wall is the column ``W_k >= 0`` for both ends ``k = +1, -1``,
where ``W_k`` is the scene's own gap of end ``k`` as a function of position
(``ColumnFlight``, which the scene hands out as its ``checker_flight``):

    StickInCircle:   W_k(x, y, z) = R^2 - |P_k|^2,
    StickInEllipse:  W_k(x, y, z) = a b - P_k^T D P_k,   D = diag(b/a, a/b),

with ``P_k = c + k ell u(z / sqrt(I/M))``: one smooth sheet per end (their
intersection is the column's crease). A
``diffrax.Event`` on ``min(W_+, W_-)`` with an ``optimistix.Newton`` root
finder stops the solve at the wall; the velocity is reflected about
``N = grad W_k`` (``jax.grad``), and a new solve starts from there.

Nothing here uses jaxbill's collision times or impulse law. What diffrax cannot
promise is checked after every solve, step by step: an even number of sign
changes of ``W_k`` inside one solver step is invisible to the event, and so is a
root that is not the first one in the step. Along a straight flight
``|W_k''| <= K = 2 d_max ((|v| + ell |omega|)^2 + (|c|_max + ell) ell omega^2)``
(``d_max`` bounds the table's ``D``: 1 for the circle, ``max(a, b)/min(a, b)``
for the ellipse); from ``K`` and the values and slopes of ``W_k`` at each step's
ends a certified lower bound of ``W_k`` over the step follows. A step whose
bound is not positive (except at the event itself) is *flagged*: the checker
stops there and says so instead of returning a sequence that might have
skipped a collision. The default ``dtmax`` keeps such flags rare: it is chosen
so that a hidden excursion could be at most ``graze_tol`` times the gap's unit
(``R^2``, ``ab``) deep.

Accuracy. The flight is summed step by step, so the checker's own error grows
with the number of steps and with the angle turned: about ``ulp(alpha)`` per
step in ``alpha`` (``z`` is wrapped to one period at each solve to keep that
small). For ordinary orbits one flight agrees with ``jb.collide`` to 1e-12 or
better; for a short, fast-spinning stick (``ell / R = 1e-3``, thousands of
radians per flight) only to about 1e-8 (checked against the mpmath reference:
there the error is the checker's).
"""

from __future__ import annotations

import dataclasses
import math
import time
from typing import Any

import diffrax
import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np
import optimistix as optx
from jaxtyping import ArrayLike, Float, Int, Real

from jaxbill._engine.collision import collide as _collide
from jaxbill._engine.collision import orbit as _orbit
from jaxbill._engine.validation import MAX_STORED_COUNT, check_count
from jaxbill._scenes.protocols import Scene

__all__ = ["check", "CheckResult", "CheckReport", "CheckFlag", "ColumnFlight"]

_FLAG_NAMES = {
    1: "graze",  # a wall not certified positive inside a step: a collision may hide there
    2: "max_steps",  # the solve hit max_steps before any event
    3: "root_find",  # the event's root finder failed
    4: "not_approaching",  # the end at the event is not moving into the wall
    5: "corner",  # both ends at the wall at once (jb.orbit reports contact 2)
}


class ColumnFlight(eqx.Module):
    """The straight flight of a planar stick's point ``(x, y, z = scale alpha)`` in the column its gaps bound.

    What a scene whose state is ``[x, y, alpha, vx, vy, omega]`` and whose
    table is fixed and convex (``StickInCircle``, ``StickInEllipse``) hands the
    checker (``HasCheckerFlight``): in ``(x, y, z)`` with ``z = sqrt(I/M) alpha``
    the metric is Euclidean, so a collision is a specular reflection about the
    gradient of the touching end's gap, and between collisions the point flies
    straight. The walls are the scene's own gaps as functions of position
    (``scene.gaps`` at zero velocity): geometry only, never its collision
    times or impulse law.

    Attributes:
        scene: the scene (one, unbatched); only ``gaps`` and ``gap_scale`` are used.
        scale: ``sqrt(I/M)`` for a turning stick, 1 otherwise (``z = alpha``), length.
        length: the unit of length of the comparison (``R``; ``max(a, b)``).
        reach: a bound on ``|c|``, the centre's distance from the origin, inside the table.
        hessian_bound: ``d_max``: the gaps' Hessian in the contact point is
            ``-2 D`` with ``|D| <= d_max`` (1 for the circle).
        frozen: the stick never turns (infinite inertia): the impulse's z part is dropped.
        single_sheet: both ends are one point (``ell = 0``): no crease, no corner.
    """

    scene: Any
    scale: jax.Array
    length: jax.Array
    reach: jax.Array
    hessian_bound: jax.Array
    frozen: bool = eqx.field(static=True)
    single_sheet: bool = eqx.field(static=True)

    @property
    def ell(self) -> jax.Array:
        return self.scene.ell

    @property
    def gap_unit(self) -> jax.Array:
        return self.scene.gap_scale

    def _state(self, pos: jax.Array) -> jax.Array:
        zero = jnp.zeros((), pos.dtype)
        return jnp.stack([pos[0], pos[1], pos[2] / self.scale, zero, zero, zero])

    def wall(self, k: float, pos: jax.Array) -> jax.Array:
        """The gap of end ``k`` (+1: P1, -1: P2) at position ``pos = (x, y, z)``."""
        return self.walls(pos)[0 if k > 0 else 1]

    def walls(self, pos: jax.Array) -> jax.Array:
        return self.scene.gaps(self._state(pos))

    def walls_and_slopes(self, y: jax.Array):
        """``W_k`` and ``dW_k/dt`` along the flight (a JVP along the velocity)."""
        return jax.jvp(self.walls, (y[0:3],), (y[3:6],))

    def curvature_bound(self, y0: jax.Array, y1: jax.Array) -> jax.Array:
        """Bound on ``|W_k''|`` over the straight flight from ``y0`` to ``y1``.

        ``W = g(P)``, ``P = c + k ell u``: ``W'' = P'^T Hess g P' + grad g . P''``
        with ``|Hess g| <= 2 d_max``, ``|grad g| = 2 |D P| <= 2 d_max |P|``,
        ``|P'| <= |v| + ell |omega|`` and ``|P''| = ell omega^2``.
        """
        speed = jnp.linalg.norm(y0[3:5])
        spin = jnp.abs(y0[5] / self.scale)
        centre = jnp.maximum(jnp.linalg.norm(y0[0:2]), jnp.linalg.norm(y1[0:2]))
        return 2.0 * self.hessian_bound * ((speed + self.ell * spin) ** 2 + (centre + self.ell) * self.ell * spin**2)

    def reflect(self, k_index: jax.Array, y: jax.Array) -> jax.Array:
        """Specular reflection of the velocity about ``grad W_k`` (Euclidean metric)."""
        normal = jax.lax.switch(
            k_index,
            [jax.grad(lambda p: self.wall(1.0, p)), jax.grad(lambda p: self.wall(-1.0, p))],
            y[0:3],
        )
        if self.frozen:  # the infinitely heavy stick takes the z part of the impulse
            normal = normal.at[2].set(0.0)
        v = y[3:6]
        v = v - 2.0 * (v @ normal) / (normal @ normal) * normal
        return jnp.concatenate([y[0:3], v])

    def check(self, scene, state0, n: int, **options) -> CheckResult:
        """``jb.check`` for this flight (see ``check`` for the options)."""
        return _check_column(self, scene, state0, n, **options)


def _certified_positive(f0, p0, f1, p1, h, K):
    """True where ``f > 0`` on the open step ``(0, h)`` is proven.

    ``f0, p0`` (``f1, p1``) are value and slope at the step's start (end) and
    ``|f''| <= K``. Taylor bounds from the left and from the right prove
    positivity on ``(0, sL)`` and ``(h - sR, h)``; the interpolation bound
    ``f >= lin - K s (h - s) / 2`` covers what is left between them.
    """
    K = jnp.maximum(K, 1e-300)
    sL = jnp.where(f0 >= 0.0, (p0 + jnp.sqrt(jnp.maximum(p0 * p0 + 2.0 * K * f0, 0.0))) / K, 0.0)
    sR = jnp.where(f1 >= 0.0, (-p1 + jnp.sqrt(jnp.maximum(p1 * p1 + 2.0 * K * f1, 0.0))) / K, 0.0)
    covered = sL + sR > h
    lo, hi = jnp.minimum(sL, h), jnp.maximum(h - sR, 0.0)
    s = jnp.clip(0.5 * h - (f1 - f0) / (K * h), lo, hi)
    interp = f0 + (f1 - f0) * s / h - 0.5 * K * s * (h - s)
    return (f0 >= 0.0) & (f1 >= 0.0) & (covered | ((interp > 0.0) & (h > 0.0)) | (h == 0.0))


def _vector_field(t, y, args):
    return jnp.concatenate([y[3:6], jnp.zeros(3, y.dtype)])


@eqx.filter_jit
def _segment(column: ColumnFlight, y0, dtmax, solver, rtol, atol, root_tol, max_steps, corner_tol):
    """Integrate from ``y0`` to the next wall event (at most ``max_steps`` steps);
    certify the steps; reflect.

    Returns ``(t_event, y_after, contact_index, flag, flag_time, n_steps)``;
    flag 2 (out of steps, no event) returns the last state, unreflected.
    """

    def cond_fn(t, y, args, **kwargs):
        # At the start one wall is at zero (the end that just bounced), and
        # diffrax only sees a crossing from a positive value: start from +1 so
        # that the *other* end reaching the wall within the first step is seen.
        value = jnp.min(column.walls(y[0:3])) / column.gap_unit  # O(1), so root_tol is relative
        return jnp.where(t <= 0.0, 1.0, value)

    event = diffrax.Event(
        cond_fn,
        root_finder=optx.Newton(rtol=root_tol, atol=root_tol),
        direction=False,
    )
    sol = diffrax.diffeqsolve(
        diffrax.ODETerm(_vector_field),
        solver,
        t0=0.0,
        t1=jnp.inf,
        dt0=dtmax,
        y0=y0,
        stepsize_controller=diffrax.PIDController(rtol=rtol, atol=atol, dtmax=dtmax),
        saveat=diffrax.SaveAt(steps=True),
        event=event,
        max_steps=max_steps,
        throw=False,
    )
    ts, ys = sol.ts, sol.ys
    assert ts is not None and ys is not None  # SaveAt(steps=True) saves both
    valid = jnp.isfinite(ts)
    n_steps = jnp.sum(valid)
    last = jnp.maximum(n_steps - 1, 0)
    t_event, y_event = ts[last], ys[last]

    t_start = jnp.concatenate([jnp.zeros(1), ts[:-1]])
    y_start = jnp.concatenate([y0[None], ys[:-1]])
    t_end = jnp.where(valid, ts, 0.0)
    y_end = jnp.where(valid[:, None], ys, y0)
    f0, p0 = jax.vmap(column.walls_and_slopes)(y_start)
    f1, p1 = jax.vmap(column.walls_and_slopes)(y_end)
    K = jax.vmap(column.curvature_bound)(y_start, y_end)

    w_event, slope_event = column.walls_and_slopes(y_event)
    k_index = jnp.argmin(w_event)
    event_ok = sol.result == diffrax.RESULTS.event_occurred
    is_last = (jnp.arange(ts.shape[0]) == last) & event_ok
    # The wall that just bounced starts at zero to rounding (step 0).
    first = (jnp.arange(ts.shape[0]) == 0)[:, None]
    f0 = jnp.where(first & (f0 > -corner_tol * column.gap_unit), jnp.maximum(f0, 0.0), f0)
    # The event itself is a root of the contacting wall: certify up to it only.
    at_event = is_last[:, None] & ((jnp.arange(2)[None, :] == k_index) | column.single_sheet)
    f1 = jnp.where(at_event, jnp.maximum(f1, 0.0), f1)
    ok = _certified_positive(f0, p0, f1, p1, (t_end - t_start)[:, None], K[:, None])
    bad = valid[:, None] & ~ok
    bad_step = jnp.argmax(jnp.any(bad, axis=1))

    flag = jnp.where(jnp.any(bad), 1, 0)
    flag = jnp.where((flag == 0) & (sol.result == diffrax.RESULTS.max_steps_reached), 2, flag)
    flag = jnp.where((flag == 0) & ~event_ok, 3, flag)
    flag = jnp.where((flag == 0) & (slope_event[k_index] >= 0.0), 4, flag)
    other = w_event[1 - k_index]
    if not column.single_sheet:
        flag = jnp.where((flag == 0) & (other <= corner_tol * column.gap_unit), 5, flag)
    flag_time = jnp.where(flag == 1, t_start[bad_step], t_event)

    # A chunk that ran out of steps without an event hands back its last state unreflected.
    y_after = jnp.where(event_ok, column.reflect(k_index, y_event), y_event)
    return t_event, y_after, k_index, flag, flag_time, n_steps


# ---------------------------------------------------------------------------
# results
# ---------------------------------------------------------------------------
@dataclasses.dataclass(frozen=True)
class CheckFlag:
    """Where the checker stopped trusting itself: collision ``index`` (0-based,
    the one that could not be certified), a ``kind`` from ``graze``,
    ``max_steps``, ``root_find``, ``not_approaching``, ``corner``, and a message."""

    index: int
    kind: str
    message: str


@dataclasses.dataclass(frozen=True)
class CheckReport:
    """Comparison of the checker's collisions with ``jb.orbit``.

    Deviations are the largest over the compared collisions, each in scaled
    units: time in ``R / V``, position in ``R``, ``alpha`` in radians (mod 2 pi),
    velocity in ``V`` and spin in ``V / sqrt(I/M)`` (``V / R`` for the circle),
    ``V = sqrt(2 E / M)`` the speed scale of the orbit.
    """

    n: int  # collisions asked for
    n_checked: int  # collisions the checker certified
    horizon: int  # collisions before a 1e-12-perturbed jb.orbit departs by > tol
    n_compared: int  # min(n_checked, horizon)
    tol: float
    max_time: float
    max_position: float
    max_angle: float
    max_velocity: float
    max_spin: float
    first_contact_mismatch: int | None
    first_deviation: int | None  # first index with a scaled deviation > tol
    # One-collision comparison over all certified collisions (no chaos horizon):
    # jb.collide from the checker's state i-1 against the checker's collision i.
    local_max_time: float
    local_max_state: float  # largest scaled position/angle/velocity/spin deviation
    local_first_mismatch: int | None  # first i with another contact or a deviation > tol
    flags: tuple
    n_steps: int
    seconds: float

    @property
    def agree(self) -> bool:
        """Contacts equal and every scaled deviation within ``tol`` up to ``n_compared``."""
        return (
            self.first_contact_mismatch is None and self.first_deviation is None and self.local_first_mismatch is None
        )

    @property
    def trusted(self) -> bool:
        """The checker certified all ``n`` collisions (no flag)."""
        return not self.flags

    def __str__(self) -> str:
        lines = [
            f"jaxbill.check: {self.n_checked}/{self.n} collisions certified, "
            f"{self.n_compared} compared (chaos horizon {self.horizon}), "
            f"{self.n_steps} solver steps, {self.seconds:.2f} s",
            f"  max deviation (scaled): time {self.max_time:.2e}  position {self.max_position:.2e}  "
            f"angle {self.max_angle:.2e}  velocity {self.max_velocity:.2e}  spin {self.max_spin:.2e}",
            f"  one collision at a time, all {self.n_checked}: time {self.local_max_time:.2e}  "
            f"state {self.local_max_state:.2e}"
            + ("" if self.local_first_mismatch is None else f"  MISMATCH from {self.local_first_mismatch}"),
            "  contacts: "
            + (
                "all equal"
                if self.first_contact_mismatch is None
                else f"first mismatch at {self.first_contact_mismatch}"
            ),
            "  verdict: "
            + ("AGREE" if self.agree else "DISAGREE")
            + f" within tol {self.tol:.1e}"
            + ("" if self.first_deviation is None else f" (first deviation > tol at {self.first_deviation})"),
        ]
        for f in self.flags:
            lines.append(f"  FLAG at collision {f.index} [{f.kind}]: {f.message}")
        return "\n".join(lines)


@dataclasses.dataclass(frozen=True)
class CheckResult:
    """The checker's own collision sequence (``t`` (m,), ``contact`` (m,),
    ``state`` (m, 6), the usual layout, state just after each collision, alpha
    wrapped into ``[-pi, pi)``; ``m <= n`` certified collisions), the reference
    ``orbit`` from ``jb.orbit`` and the comparison ``report``."""

    t: Float[np.ndarray, " m"]
    contact: Int[np.ndarray, " m"]
    state: Float[np.ndarray, "m S"]
    orbit: object
    report: CheckReport

    def __str__(self) -> str:
        return str(self.report)


# ---------------------------------------------------------------------------
# comparison helpers
# ---------------------------------------------------------------------------
def _scaled_deviation(a, b, scales):
    """Per-collision scaled deviations ``(time, position, angle, velocity, spin)``, shape (m, 5)."""
    (ta, sa), (tb, sb) = a, b
    t_s, r_s, v_s, w_s = scales
    dang = np.remainder(sa[:, 2] - sb[:, 2] + np.pi, 2 * np.pi) - np.pi
    return np.stack(
        [
            np.abs(ta - tb) / t_s,
            np.max(np.abs(sa[:, 0:2] - sb[:, 0:2]), axis=1) / r_s,
            np.abs(dang),
            np.max(np.abs(sa[:, 3:5] - sb[:, 3:5]), axis=1) / v_s,
            np.abs(sa[:, 5] - sb[:, 5]) / w_s,
        ],
        axis=1,
    )


def _comparison_report(n, contact, ref_contact, horizon, tol, dev, local_max, local_bad, flags, n_steps, start):
    """The ``CheckReport`` of a checker run: ``dev`` holds the scaled deviations
    ``(m, 5)`` of its first ``m = min(collisions checked, horizon)`` collisions."""
    m = len(dev)
    maxima = dev.max(axis=0) if m else np.zeros(5)
    return CheckReport(
        n=n,
        n_checked=len(contact),
        horizon=horizon,
        n_compared=m,
        tol=tol,
        max_time=float(maxima[0]),
        max_position=float(maxima[1]),
        max_angle=float(maxima[2]),
        max_velocity=float(maxima[3]),
        max_spin=float(maxima[4]),
        first_contact_mismatch=_first(contact[:m] != ref_contact[:m]),
        first_deviation=_first(np.any(dev > tol, axis=1)),
        local_max_time=float(local_max[0]),
        local_max_state=float(local_max[1:].max()),
        local_first_mismatch=_first(local_bad),
        flags=tuple(flags),
        n_steps=n_steps,
        seconds=time.perf_counter() - start,
    )


def _wrap(angle: float) -> float:
    return (angle + math.pi) % (2 * math.pi) - math.pi


def _first(mask):
    idx = np.flatnonzero(mask)
    return int(idx[0]) if idx.size else None


# ---------------------------------------------------------------------------
# the checker
# ---------------------------------------------------------------------------
def check(
    scene: Scene,
    state0: Real[ArrayLike, " S"],
    n: int,
    *,
    tol: float = 1e-8,
    graze_tol: float = 1e-6,
    dtmax: float | None = None,
    solver=None,
    rtol: float = 1e-10,
    atol: float = 1e-12,
    root_tol: float = 1e-12,
    chunk_steps: int = 2048,
    max_steps: int = 2**20,
    corner_tol: float = 1e-12,
    horizon_eps: float = 1e-12,
) -> CheckResult:
    """Integrate the first ``n`` collisions with diffrax and compare with ``jb.orbit``.

    Args:
        scene: a single (unbatched) scene that answers ``checker_flight``
            (``jaxbill._scenes.protocols.HasCheckerFlight``). ``StickInCircle`` and
            ``StickInEllipse`` give a ``ColumnFlight`` (this module);
            ``StickBetweenWalls2D``/``3D`` a ``ReducedWallsFlight``
            (``jaxbill._check.walls``: the reduced ``(z, psi)`` flight with
            its centrifugal potential; it takes ``tol``, ``graze_tol``,
            ``max_steps``, ``corner_tol`` and ``solver``, the rest keep its
            defaults, and lengths are in units of ``h``).
        state0: the start, shape ``(S,)`` (``[x, y, alpha, vx, vy, omega]`` for the column flights).
        n: number of collisions.
        tol: scaled tolerance of the comparison (see ``CheckReport``) and of
            the chaos horizon.
        graze_tol: sets the default ``dtmax`` per flight: a wall excursion
            hidden inside one step is at most ``graze_tol * R^2`` deep. Any
            step that could hide one is flagged whatever ``dtmax`` is.
        dtmax: fixed largest solver step (time units) instead of the default.
        solver: a diffrax solver (default ``diffrax.Tsit5()``).
        rtol, atol: the PID controller's tolerances.
        root_tol: ``optimistix.Newton`` tolerances (on the event time and on
            ``W / R^2``); Newton converges quadratically, so the time it
            returns is far more accurate than this.
        chunk_steps: solver steps per diffrax solve (static: the size of the
            saved-steps buffer that is certified after each solve); a flight
            longer than that continues in a new solve from where it stopped.
        max_steps: solver steps allowed per flight, over all its solves.
        corner_tol: both ends within ``corner_tol * R^2`` of the wall at an
            event is a corner hit, flagged (``jb.orbit`` merges it into contact 2).
        horizon_eps: relative size of the perturbations that set the chaos
            horizon: ``jb.orbit`` from ``state0`` perturbed in four fixed
            directions (scaled as in ``CheckReport``); the horizon is the first
            collision at which any of them departs from ``jb.orbit(state0)`` by
            more than ``tol`` or in its contact. Past it the two orbits are
            compared one collision at a time only (``local_*`` in the report).

    Returns:
        ``CheckResult``: the checker's certified collisions and a ``CheckReport``
        (``print`` it). The checker stops at the first collision it cannot
        certify and records a ``CheckFlag``; it never returns collisions past it.

    Raises:
        NotImplementedError: for a batched scene or ``state0``.
        TypeError: for a scene without ``checker_flight``.
        ValueError: for ``n`` not a positive integer (at most ``2**31 - 1``),
            a complex or non-numeric ``state0``, or an invalid ``state0`` (as
            ``jb.orbit``).
    """
    n = check_count("n", n, 1, "number of collisions", MAX_STORED_COUNT)
    dtype = np.asarray(state0).dtype
    if not (np.issubdtype(dtype, np.floating) or np.issubdtype(dtype, np.integer)):
        raise ValueError(f"state0 must be real numbers; got dtype {dtype}")
    flight_of = getattr(scene, "checker_flight", None)
    if flight_of is None:
        raise TypeError(
            f"scene: {type(scene).__name__} gives no checker_flight (the HasCheckerFlight protocol of "
            "jaxbill._scenes.protocols): jb.check cannot integrate it"
        )
    options = dict(
        tol=tol,
        graze_tol=graze_tol,
        dtmax=dtmax,
        solver=solver,
        rtol=rtol,
        atol=atol,
        root_tol=root_tol,
        chunk_steps=chunk_steps,
        max_steps=max_steps,
        corner_tol=corner_tol,
        horizon_eps=horizon_eps,
    )
    state0 = np.asarray(state0, dtype=np.float64)
    if any(np.ndim(leaf) for leaf in jax.tree_util.tree_leaves(scene)):
        raise NotImplementedError("jaxbill.check takes one scene, not a batch; loop over a batch")
    scene.check()
    return flight_of().check(scene, state0, n, **options)


def _check_column(
    column: ColumnFlight,
    scene,
    state0: np.ndarray,
    n: int,
    *,
    tol,
    graze_tol,
    dtmax,
    solver,
    rtol,
    atol,
    root_tol,
    chunk_steps,
    max_steps,
    corner_tol,
    horizon_eps,
) -> CheckResult:
    """``check`` for a ``ColumnFlight``: integrate flight by flight, certify each step, compare with ``jb.orbit``."""
    start = time.perf_counter()
    if state0.shape != (6,):
        raise NotImplementedError("jaxbill.check takes one scene and one state0 of shape (6,); loop over a batch")
    reference = _orbit(scene, state0, n)  # also validates state0 eagerly
    length, ell, mass = float(column.length), float(column.ell), float(scene.mass)
    gap_unit, scale = float(column.gap_unit), float(column.scale)
    reach_inside, d_max = float(column.reach), float(column.hessian_bound)
    solver = diffrax.Tsit5() if solver is None else solver

    y = jnp.asarray(
        [state0[0], state0[1], scale * state0[2], state0[3], state0[4], scale * state0[5]], dtype=jnp.float64
    )
    if column.frozen:
        y = y.at[5].set(0.0)
    t_abs = 0.0
    times, contacts, states, flags = [], [], [], []
    total_steps = 0
    for i in range(n):
        if dtmax is None:
            # |W''| bound for this flight (ColumnFlight.curvature_bound), |c| <= reach inside.
            reach = max(reach_inside, float(jnp.linalg.norm(y[0:2])))
            v, w = float(jnp.linalg.norm(y[3:5])), abs(float(y[5])) / scale
            K = 2.0 * d_max * ((v + ell * w) ** 2 + (reach + ell) * ell * w * w)
            step = math.sqrt(8.0 * graze_tol * gap_unit / K) if K > 0 else 1.0
        else:
            step = float(dtmax)
        flight_t, flight_steps = 0.0, 0
        while True:
            # The column is periodic in z (period 2 pi sqrt(I/M)): keeping z small
            # keeps the integrator's rounding per step at ulp(z) small.
            y = y.at[2].set(scale * _wrap(float(y[2]) / scale))
            t_ev, y_new, k_index, flag, flag_time, n_steps = _segment(
                column, y, jnp.asarray(step), solver, rtol, atol, root_tol, chunk_steps, corner_tol
            )
            flag, n_steps = int(flag), int(n_steps)
            total_steps += n_steps
            flight_steps += n_steps
            if flag == 2 and flight_steps < max_steps:  # out of steps, no event: go on
                flight_t += float(t_ev)
                y = y_new
                continue
            break
        flag_time = flight_t + float(flag_time)
        t_ev = flight_t + float(t_ev)
        if flag:
            kind = _FLAG_NAMES[flag]
            message = {
                "graze": f"a wall excursion could hide in the solver step from t = {t_abs + flag_time:.6g} "
                f"(dtmax {step:.3g}); collision {i} and later not certified",
                "max_steps": f"no wall event within max_steps = {max_steps} steps of {step:.3g} after t = {t_abs:.6g}",
                "root_find": f"event root finder failed near t = {t_abs + t_ev:.6g}",
                "not_approaching": f"the end at the event at t = {t_abs + t_ev:.6g} is not moving into the wall",
                "corner": f"both ends at the wall at t = {t_abs + t_ev:.6g} (a crease of the column)",
            }[kind]
            flags.append(CheckFlag(index=i, kind=kind, message=message))
            break
        t_abs += t_ev
        y = y_new
        if column.frozen:
            y = y.at[5].set(0.0)
        alpha = _wrap(float(y[2]) / scale)
        times.append(t_abs)
        contacts.append(1 if int(k_index) == 0 else -1)
        states.append([float(y[0]), float(y[1]), alpha, float(y[3]), float(y[4]), float(y[5]) / scale])

    t = np.asarray(times, dtype=np.float64)
    contact = np.asarray(contacts, dtype=np.int32)
    state = np.asarray(states, dtype=np.float64).reshape(-1, 6)

    # Scales and the chaos horizon.
    V = math.sqrt(2.0 * float(scene.energy(jnp.asarray(state0))) / mass) or 1.0
    spin_scale = V / length if column.frozen or column.single_sheet else V / scale
    scales = (length / V, length, V, spin_scale)
    ref_t, ref_c, ref_s = (np.asarray(a) for a in (reference.t, reference.contact, reference.state))
    # Several perturbation directions: one alone may lie along a weakly growing direction.
    directions = np.array(
        [
            [0.6, -0.8, 0.0, 0.3, -0.7, 0.0],
            [-0.2, 0.5, 0.7, -0.6, 0.1, 0.4],
            [0.9, 0.1, -0.3, 0.2, 0.8, -0.5],
            [-0.4, -0.3, 0.2, 0.9, 0.3, 0.8],
        ]
    )
    if column.frozen:
        directions[:, 5] = 0.0
    if float(jnp.min(scene.gaps(jnp.asarray(state0)))) <= 1e-9 * gap_unit:
        # A start on the wall (just after a collision): a moved end could be
        # pushed through it; perturbing the velocities alone keeps it valid.
        directions[:, 0:3] = 0.0
    bumps = horizon_eps * directions * np.array([length, length, 1.0, V, V, spin_scale])
    perturbed = _orbit(scene, state0 + bumps, n)
    departed = np.zeros(n, bool)
    for b in range(len(bumps)):
        mine = (np.asarray(perturbed.t[b]), np.asarray(perturbed.state[b]))
        pd = _scaled_deviation(mine, (ref_t, ref_s), scales)
        departed |= (np.asarray(perturbed.contact[b]) != ref_c) | np.any(pd > tol, axis=1)
    horizon = _first(departed)
    horizon = n if horizon is None else horizon

    m = min(len(t), horizon)
    dev = _scaled_deviation((t[:m], state[:m]), (ref_t[:m], ref_s[:m]), scales)
    # One collision at a time: jb.collide from each checker state (chaos-free).
    starts = np.concatenate([state0[None], state[:-1]]) if len(t) else np.zeros((0, 6))
    if len(t):
        one_state, one_dt, one_contact = jax.vmap(_collide, in_axes=(None, 0))(scene, jnp.asarray(starts))
        t_prev = np.concatenate([[0.0], t[:-1]])
        local = _scaled_deviation((np.asarray(one_dt), np.asarray(one_state)), (t - t_prev, state), scales)
        local_bad = (np.asarray(one_contact) != contact) | np.any(local > tol, axis=1)
        local_max = local.max(axis=0)
    else:
        local_bad, local_max = np.zeros(0, bool), np.zeros(5)
    report = _comparison_report(n, contact, ref_c, horizon, tol, dev, local_max, local_bad, flags, total_steps, start)
    return CheckResult(t=t, contact=contact, state=state, orbit=reference, report=report)
