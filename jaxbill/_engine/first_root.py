"""First root of a few smooth gap functions, found with steps that cannot skip a root.

The collision time of a spinning body is the first ``t > 0`` at which one of its
contact gaps ``g_k(t)`` (positive inside the wall) reaches zero while decreasing.
The gaps are transcendental (a line plus a rotation), may oscillate many times
before the first root (fast spin), and may touch zero tangentially (grazing), so
neither Newton's method nor a bracketing solver is safe: both can step over an
earlier root.

Method (a Taylor-model safe step). Given rigorous bounds on the second
derivative, ``lower <= g_k'' <= upper`` on the search interval, at the current
time ``t`` with ``g = g_k(t)`` and ``d = g_k'(t)``:

* ``g_k(t + s) >= g + d s - lower_curv s^2 / 2`` (with ``lower_curv = -lower``).
  The first positive root ``s_lo`` of that quadratic is a step along which
  ``g_k`` cannot vanish, so the iteration ``t <- t + min_k s_lo`` never passes
  the first root of any gap. Near a transversal root ``s_lo`` is a Newton step
  corrected downwards, so convergence is quadratic; near a double root (a
  grazing hit) it is linear with a fixed ratio; across a near miss the steps
  shrink to the gap's minimum and grow again.
* ``g_k(t + s) <= g + d s + upper_curv s^2 / 2``: its first root ``s_hi``
  bounds the root from above. The iteration stops once ``s_hi - s_lo`` is below
  the time resolution, and returns ``t + s_lo`` (the end is still inside the
  wall, by less than rounding).

A gap at or below zero whose slope is negative is a root at the current time
(the end is touching and approaching). A gap at zero with a positive slope is
the end that just bounced: it is departing, so it is not a root, and its step is
taken from ``max(g, 0)``; this is how the root at ``t = 0`` of the end that just
bounced is never found again.

Sharper steps from the gap's own curvature. The bounds above hold along the
whole flight, so each step is a Newton step corrected by the worst curvature
of the flight. A scene that can also give each gap's second derivative
``k = g_k''(t)`` at the current time, and a bound ``jerk >= |g_k'''|`` along
the flight, gets a local bound instead: on a window ``[t, t + S]``,
``g_k(t + s) >= g + d s + k s^2 / 2 - jerk s^3 / 6 >= g + d s - (-k + jerk S / 3) s^2 / 2``,
so ``-k + jerk S / 3`` (never more than the flight's bound) serves as the
lower curvature for steps up to ``S``, and ``k + jerk S / 3`` as the upper
one for an upper root before ``S``. A falling gap's window is ``S = 2 g / |d|``,
twice its Newton step, which always holds the flight-wide safe step (that
step is at most ``g / |d|``); its step is capped at ``S``. Near a root the
bracket then shrinks like ``s^3`` rather than ``s^2``, and a grazing root is
no longer approached at a fixed linear ratio: the stick in a circle takes
4.8 -> 3.3 steps per collision at ``ell = 1.9`` and 6.4 -> 4.9 at
``ell = 1.0`` (64 orbits of 2000 collisions, no quiet interval), each step a
division and a few products dearer. The roots found are the same to the
time resolution (and every one is still proved).

The loop is bounded by ``max_steps``; a search that hits the bound reports it
(``ok = False``) instead of returning a root it did not prove.

A scene may check its own bounds along the search (a user's table whose
curvature bounds were estimated): where one fails it returns that gap as NaN,
with a finite slope. The search then ends at once, as on any non-finite value,
and, asked to (``refusals``), reports the gap index ``REFUSED``, so that the
orbit's result says which it was.
"""

from __future__ import annotations

import functools
from collections.abc import Callable
from typing import NamedTuple

import jax
import jax.numpy as jnp

# Stop when the root is bracketed to this many ulps of the time scale.
_TIME_RESOLUTION_ULPS = 4.0

# The gap index of a search that a scene refused to continue (a NaN gap with a finite slope).
REFUSED = -1


def _step_below(g, slope, lower_curv, rising_curv=None):
    """A lower bound ``s_lo`` on the distance to a gap's next root: a step along which it cannot vanish.

    ``g >= 0`` is the gap clamped at zero (an end through the wall by rounding
    is treated as on it). ``rising_curv``: the same ``lower_curv`` where the
    gap rises (``slope >= 0``), given where that is a flight constant and
    ``lower_curv`` is not (its reciprocal is then the same at every step).
    """
    disc_lo = slope * slope + 2.0 * lower_curv * g
    root_lo = jnp.sqrt(disc_lo)
    # Two algebraically equal forms of the quadratic's positive root; each is
    # free of cancellation on its side of slope = 0.
    falling = 2.0 * g / (root_lo - slope)
    # An explicit reciprocal: XLA turns division by a broadcast scalar into a
    # reciprocal multiply in some programs (one orbit) but not others (a
    # batch), which would make batched and single runs differ in the last bit.
    rising = (slope + root_lo) * (1.0 / (lower_curv if rising_curv is None else rising_curv))
    s_lo = jnp.where(slope < 0.0, falling, rising)
    # 0/0 arises only for slope == 0 with no curvature (a motionless gap, which
    # never vanishes) or with g == 0 (an end resting on the wall with no normal
    # motion, which no bound can resolve: it is left to the step cap).
    return jnp.where(jnp.isnan(s_lo), jnp.where(g > 0.0, jnp.inf, 0.0), s_lo)


def _step_above(g, slope, upper_curv):
    """An upper bound ``s_hi`` on the distance to a gap's next root (``inf``: none is proven)."""
    disc_hi = slope * slope - 2.0 * upper_curv * g
    has_upper_root = (slope < 0.0) & (disc_hi >= 0.0)
    return jnp.where(
        has_upper_root,
        2.0 * g / (-slope + jnp.sqrt(jnp.maximum(disc_hi, 0.0))),
        jnp.inf,
    )


class RootBounds(NamedTuple):
    """What the safe-step search needs to know of one flight, fixed along it.

    Attributes:
        lower_curv: bound ``>= -g_k''(t)`` for all k and all t up to the root.
        upper_curv: bound ``>= g_k''(t)`` likewise.
        quiet_in, quiet_out: a time interval in which no gap can vanish (empty
            when ``quiet_in >= quiet_out``); the search jumps over it. A search
            with ``quiet_out = inf`` that reaches it finds no root.
        time_scale: a characteristic flight time; the root is resolved to a few
            ulps of ``max(t, time_scale)``.
        jerk: bound ``>= |g_k'''(t)|`` for all k and all t up to the root, for a
            scene whose ``gaps_along_flight`` also gives the gaps' curvatures
            (``None``: the search uses the fixed curvature bounds alone).
    """

    lower_curv: jax.Array
    upper_curv: jax.Array
    quiet_in: jax.Array
    quiet_out: jax.Array
    time_scale: jax.Array
    jerk: jax.Array | None = None


def search_start(bounds: RootBounds) -> jax.Array:
    """Where the search starts: 0, or the end of a quiet interval that holds 0 (``inf``: no root ever)."""
    return jnp.where((bounds.quiet_in <= 0.0) & (bounds.quiet_out > 0.0), bounds.quiet_out, 0.0)


def select(values: tuple, index: jax.Array) -> jax.Array:
    """``values[index]`` for a tuple of same-shaped arrays and a traced ``index`` (no gather)."""
    chosen = values[-1]
    for k in range(len(values) - 2, -1, -1):
        chosen = jnp.where(index == k, values[k], chosen)
    return chosen


def first_smallest(values: tuple) -> jax.Array:
    """Index (int32) of the first smallest of a tuple of same-shaped arrays, as ``argmin`` (no NaN expected)."""
    best, index = values[0], jnp.zeros(jnp.shape(values[0]), jnp.int32)
    for k in range(1, len(values)):
        smaller = values[k] < best
        best = jnp.where(smaller, values[k], best)
        index = jnp.where(smaller, jnp.int32(k), index)
    return index


# Rounding of a gap's computed curvature, relative to the flight's curvature bound.
_CURVATURE_PAD_ULPS = 16.0


class _LocalBounds(NamedTuple):
    """Per gap: the window ``S`` (``inf``: none), what it adds to the gap's own curvature in either
    direction (``jerk S / 3`` and the rounding pad), and the lower curvature bound that holds on it."""

    window: tuple
    margin: tuple
    lower_curv: tuple


def _local_bounds(clamped: tuple, slopes: tuple, curvatures: tuple, bounds: RootBounds) -> _LocalBounds:
    """The windows of the falling gaps and their local lower curvature bounds (module docstring)."""
    assert bounds.jerk is not None  # asked only of scenes that give curvatures
    jerk_third = bounds.jerk * (1.0 / 3.0)
    pad = _CURVATURE_PAD_ULPS * jnp.finfo(jnp.float64).eps * bounds.lower_curv
    windows, margins, lowers = [], [], []
    for g, d, k in zip(clamped, slopes, curvatures, strict=True):
        falling = d < 0.0
        window = jnp.where(falling, 2.0 * g / jnp.where(falling, -d, 1.0), jnp.inf)
        # jerk 0 (no spin) and an unbounded window: no third-order term at all, not 0 * inf.
        margin = jnp.where(jerk_third > 0.0, jerk_third * window, 0.0) + pad
        windows.append(window)
        margins.append(margin)
        lowers.append(jnp.where(falling, jnp.minimum(bounds.lower_curv, margin - k), bounds.lower_curv))
    return _LocalBounds(tuple(windows), tuple(margins), tuple(lowers))


def _upper_step(gap, slope, curvature, window, margin, bounds: RootBounds):
    """``_step_above`` of the approached gap with the tighter of the flight's and its window's upper
    curvature (``window``: ``inf`` for a gap that is not falling, which has no upper root anyway)."""
    s_hi = _step_above(gap, slope, jnp.minimum(bounds.upper_curv, curvature + margin))
    # Past the window nothing is proven: no bracket this step (rare: the window is twice the Newton step).
    return jnp.where(s_hi <= window, s_hi, jnp.inf)


def root_step(
    gaps: tuple,
    slopes: tuple,
    bounds: RootBounds,
    t: jax.Array,
    curvatures: tuple | None = None,
    refusals: bool = False,
):
    """One safe step of the search from time ``t``, given the K gaps and their slopes there.

    ``gaps`` and ``slopes`` are tuples of K arrays of one shape (one lane's
    scalars, or a block of lanes): the step is elementwise, with no gather,
    reduction over K or argmin, so that it runs unchanged under ``vmap`` and
    inside a Pallas (Triton) kernel.

    Returns ``(t_next, index, done)``: the next time (which cannot pass the
    first root of any gap), the gap it approaches (or the first one touching
    now), and whether the search is over: a root at ``t_next`` (touching now,
    or bracketed to the time resolution) or a hopeless lane (non-finite
    values, which end at once rather than make a batch wait out the step bound).

    ``curvatures`` (with ``bounds.jerk``): the gaps' second derivatives at
    ``t``, for the sharper steps of the module docstring. ``refusals``
    (static): the index of a search the scene refused (a NaN gap, its slope
    finite) is ``REFUSED``.

    ``first_root`` and both drivers of the engine take exactly this step, so
    every path finds the same root in the same steps.
    """
    eps = jnp.finfo(jnp.float64).eps
    clamped = tuple(jnp.maximum(g, 0.0) for g in gaps)
    local = None if curvatures is None or bounds.jerk is None else _local_bounds(clamped, slopes, curvatures, bounds)
    if local is None:
        s_lo = tuple(_step_below(g, d, bounds.lower_curv) for g, d in zip(clamped, slopes, strict=True))
    else:
        s_lo = tuple(
            jnp.minimum(_step_below(g, d, lower, bounds.lower_curv), window)
            for g, d, lower, window in zip(clamped, slopes, local.lower_curv, local.window, strict=True)
        )
    index = first_smallest(s_lo)
    s = select(s_lo, index)
    t_next = t + s
    # A safe step that lands in the quiet interval may jump to its end.
    t_next = jnp.where((t_next >= bounds.quiet_in) & (t_next < bounds.quiet_out), bounds.quiet_out, t_next)
    resolution = _TIME_RESOLUTION_ULPS * eps * jnp.maximum(t, bounds.time_scale)
    # Bracketed to the resolution, or a step below one ulp of t on a
    # falling gap: either way the root is known as well as t can hold it.
    # The upper bound of the approached gap only (one square root and division
    # less per gap; select then bound is bitwise bound then select).
    slope = select(slopes, index)
    if local is None:
        s_hi = _step_above(select(clamped, index), slope, bounds.upper_curv)
    else:
        assert curvatures is not None  # local bounds come from them
        curvature, window, margin = (select(v, index) for v in (curvatures, local.window, local.margin))
        s_hi = _upper_step(select(clamped, index), slope, curvature, window, margin, bounds)
    converged = ((s_hi - s) <= resolution) | ((t_next == t) & (slope < 0.0))
    touching = [(g == 0.0) & (d < 0.0) for g, d in zip(clamped, slopes, strict=True)]
    touching_now, touching_index = touching[-1], jnp.int32(len(touching) - 1)
    for k in range(len(touching) - 2, -1, -1):
        touching_index = jnp.where(touching[k], jnp.int32(k), touching_index)
        touching_now = touching_now | touching[k]
    index = jnp.where(touching_now, touching_index, index)
    t_next = jnp.where(touching_now, t, t_next)
    finite = jnp.isfinite(t_next)
    for g, d in zip(gaps, slopes, strict=True):
        finite = finite & jnp.isfinite(g) & jnp.isfinite(d)
    # A hopeless lane proves no root: its time is NaN (an infinite one stays: no root ever).
    t_next = jnp.where(finite | jnp.isinf(t_next), t_next, jnp.nan)
    if refusals:
        refused = [jnp.isnan(g) & jnp.isfinite(d) for g, d in zip(gaps, slopes, strict=True)]
        index = jnp.where(functools.reduce(jnp.logical_or, refused), jnp.int32(REFUSED), index)
    return t_next, index, touching_now | converged | ~finite


def with_curvatures(evaluated: tuple) -> tuple:
    """A scene's ``gaps_along_flight`` result as ``(gaps, slopes, curvatures)`` (``None``: not given)."""
    return (*evaluated, None)[:3]


def first_root(
    gaps_and_slopes: Callable[[jax.Array], tuple],
    bounds: RootBounds,
    max_steps: int,
    refusals: bool = False,
):
    """First time ``t >= 0`` at which one of K gaps reaches zero while falling.

    Args:
        gaps_and_slopes: ``t -> (gaps, slopes)`` or ``(gaps, slopes, curvatures)``
            (a scene's ``gaps_along_flight``), each a tuple of K scalars: the
            gaps and their first (and second, or ``None``) time derivatives at
            time ``t``.
        bounds: the flight's curvature bounds, quiet interval and time scale.
        max_steps: static bound on the number of steps.
        refusals: static: report a refused search's index as ``REFUSED`` (``root_step``).

    Returns:
        ``(t_root, index, steps, ok)``: the root (``inf`` when no gap ever
        vanishes), the index of the gap that vanishes, the number of steps
        taken, and ``ok = False`` when the step bound was hit first.
    """

    def step(carry):
        t, _, _, steps = carry
        # One materialised evaluation: XLA may otherwise recompute the gaps in
        # each fusion that uses them, contracting to FMA differently, so that
        # the same gap could test as touching in one place and not in another.
        gap, slope, curvature = with_curvatures(jax.lax.optimization_barrier(gaps_and_slopes(t)))
        t_next, index, done = root_step(gap, slope, bounds, t, curvature, refusals)
        return t_next, index, done, steps + 1

    def keep_going(carry):
        _, _, done, steps = carry
        return (~done) & (steps < max_steps)

    t_start = search_start(bounds)
    init = (t_start, jnp.int32(0), jnp.isinf(t_start), jnp.int32(0))
    t, index, done, steps = jax.lax.while_loop(keep_going, step, init)
    return t, index, steps, done
