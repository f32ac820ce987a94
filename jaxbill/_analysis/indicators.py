"""Fast chaos indicators of single orbits: the FLI and MEGNO, from one tangent vector.

Both indicators follow one tangent vector ``w`` along an orbit with the
autodiff tangent maps of ``jaxbill._engine.tangent`` (``push_forward``) and read
how fast its length grows: a regular (quasi-periodic) orbit stretches it
linearly in time, a chaotic one exponentially. They tell the two apart after
far fewer collisions than a converged Lyapunov exponent needs, which is what
makes maps of them over a grid of starts (Arnold webs) affordable.

Time
----
``per="collision"`` (default): time is the number of collisions ``k`` and
``w`` is carried by the Jacobian of the collision (section) map, ``DP``.
Every orbit of a grid is then compared at the same "time" ``n`` (a map's
pixels share one horizon), and the section map has no neutral time-shift
direction (``DP f = 0``), so the growth measured is the section dynamics'
alone: the setting of the maps studied by Froeschle, Lega and Gonczi and of
MEGNO for maps (Cincotta, Giordano, Simo 2003).

``per="time"``: time is the flight time ``t`` and ``w`` is carried by the
flow's fixed-time tangent maps (``flow=True``), the setting of the
continuous definitions. Each orbit then ends at its own time ``t_n`` after
``n`` collisions.

Definitions
-----------
``|w|`` is the Euclidean norm of ``w``'s coordinates in the scene's
dynamical frame (``jaxbill.dynamical_frame``; the state coordinates
themselves, restricted to the directions that carry the dynamics), and
``|w(0)| = 1``. ``L(tau) = log |w(tau)|`` is sampled just after each
collision, at ``tau_k = k`` or ``t_k``; ``tau_0 = 0``, ``L_0 = 0``.

* FLI (Froeschle, Lega, Gonczi 1997): ``FLI(tau) = max_{s <= tau} L(s)``,
  here the maximum over the samples ``L_0 .. L_k`` (so ``FLI >= 0``).
* MEGNO (Cincotta, Simo 2000): ``Y(tau) = (2/tau) int_0^tau s L'(s) ds``,
  and its running mean ``<Y>(tau) = (1/tau) int_0^tau Y(s) ds``. Both
  integrals are discretised by the trapezoid rule on the samples:
  ``int s dL ~ sum_k (tau_{k-1} + tau_k)/2 (L_k - L_{k-1})`` (which equals,
  summing by parts, ``tau_k L_k - trapezoid(int L)``), and
  ``int Y ~ sum_k (tau_k - tau_{k-1}) (Y_{k-1} + Y_k)/2`` with ``Y_0 = 0``.
  (Cincotta, Giordano and Simo weight ``L_k - L_{k-1}`` by ``k`` rather than
  ``k - 1/2``; the two ``Y`` differ by ``L_k / k``, which tends to 0 on a
  regular orbit and to ``lambda`` on a chaotic one.)

Known limits, derived from the definitions. Linear growth
``|w| = a + b tau``, ``x = b tau / a``: ``Y = 2 - (2/x) log(1 + x) -> 2``
and ``<Y> = 2 + 2 Li2(-x) / x = 2 - (log(x)^2 + pi^2/3) / x + O(1/x^2)
-> 2`` (slowly where the twist is weak, ``a/b`` large), and
``FLI = log(a + b tau) ~ log tau``. A bounded oscillation on
top of it, ``L = log(b tau) + g(tau)``, adds ``2 (g(tau) - mean g)`` to
``Y``, which the running mean averages away: ``<Y> -> 2`` still. Exponential
growth ``L = lambda tau``: ``Y = lambda tau`` (exactly, with the trapezoid
rule on ``k``), ``<Y> = lambda tau / 2`` asymptotically, ``FLI = lambda tau``.
A stable periodic orbit (bounded ``|w|``) gives ``<Y> -> 0``.

Overflow: ``w`` is renormalised to unit length after every collision and the
logarithms of the stretch factors are summed, so ``L`` is exact even where
``|w|`` itself would overflow float64.
"""

from __future__ import annotations

import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np
from jaxtyping import Array, ArrayLike, Float, Int

from jaxbill._engine import pallas
from jaxbill._engine.collision import check_eagerly, poison_if
from jaxbill._engine.drivers import map_over_orbits
from jaxbill._engine.results import first_failure, kept_where, start_result, tangent_held
from jaxbill._engine.step import orbit_constants, stops_orbits
from jaxbill._engine.tangent import dynamical_size, pushed_frame, to_dynamical, to_state_space
from jaxbill._engine.validation import (
    MAX_STORED_COUNT,
    check_count,
    check_last_axis,
    check_unbatched_scene,
    is_concrete,
    require_x64,
)
from jaxbill._scenes.protocols import Scene

PER = ("collision", "time")

# States per compiled batch in fli_map: one program for every chunk of a map.
MAP_CHUNK = 4096


class FastLyapunovIndicator(eqx.Module):
    """Fast Lyapunov indicators of an orbit (or a batch: a leading axis ``B`` on every array).

    Attributes:
        value: ``()`` the FLI after ``n`` collisions, ``max_{k <= n} log|w_k|``
            (dimensionless, ``>= 0``; ``|w_0| = 1``).
        log_norm: ``()`` the last ``log|w_n|`` (the FLI without the running max).
        history: ``(H,)`` the FLI at ``H`` checkpoints spread evenly over the run.
        collisions: ``(H,)`` int32, collisions at each checkpoint (the same for
            every orbit of a batch: no batch axis).
        times: ``(H,)`` elapsed flight time at each checkpoint.
        time: ``()`` elapsed flight time over the ``n`` collisions.
        result: ``()`` int32: why the orbit stopped, or what went wrong first
            (``jb.Result``; ``FINISHED`` when all went well).
            An orbit that ended for good (``ESCAPED``, ``STOPPED``) keeps the
            values of its last reflection (a crossing through a hole is none).
        n: number of collisions (static).
        per: ``"collision"`` or ``"time"``: the clock and tangent map used (static).
    """

    value: Float[Array, "*B"]
    log_norm: Float[Array, "*B"]
    history: Float[Array, "*B H"]
    collisions: Int[Array, " H"]
    times: Float[Array, "*B H"]
    time: Float[Array, "*B"]
    result: Int[Array, "*B"]
    n: int = eqx.field(static=True)
    per: str = eqx.field(static=True)


class Megno(eqx.Module):
    """MEGNO of an orbit (or a batch: a leading axis ``B`` on every array).

    Attributes:
        value: ``()`` the running mean ``<Y>`` after ``n`` collisions
            (dimensionless): tends to 2 on a regular orbit (linear growth of
            ``|w|``), 0 on a stable periodic one, and grows like
            ``lambda tau / 2`` on a chaotic one (``lambda`` per collision for
            ``per="collision"``, per unit time for ``per="time"``).
        instantaneous: ``()`` ``Y`` itself after ``n`` collisions (it
            oscillates about 2 on a regular orbit; ``~ lambda tau`` on a chaotic one).
        history: ``(H,)`` ``<Y>`` at ``H`` checkpoints spread evenly over the run.
        collisions: ``(H,)`` int32, collisions at each checkpoint (no batch axis).
        times: ``(H,)`` elapsed flight time at each checkpoint.
        time: ``()`` elapsed flight time over the ``n`` collisions.
        result: ``()`` int32: why the orbit stopped, or what went wrong first
            (``jb.Result``; ``FINISHED`` when all went well).
            An orbit that ended for good (``ESCAPED``, ``STOPPED``) keeps the
            values of its last reflection (a crossing through a hole is none).
        n: number of collisions (static).
        per: ``"collision"`` or ``"time"`` (static).
    """

    value: Float[Array, "*B"]
    instantaneous: Float[Array, "*B"]
    history: Float[Array, "*B H"]
    collisions: Int[Array, " H"]
    times: Float[Array, "*B H"]
    time: Float[Array, "*B"]
    result: Int[Array, "*B"]
    n: int = eqx.field(static=True)
    per: str = eqx.field(static=True)


def _generic_direction(k: int) -> np.ndarray:
    """A fixed direction in general position in ``k`` dynamical coordinates (seeded: the same every call)."""
    g = np.random.default_rng(19970101).standard_normal(k)
    return g / np.linalg.norm(g)


def _starting_direction(scene, state0, tangent0, per):
    """The starting vector's coordinates in the dynamical frame at ``state0``, not normalised: ``(k,)``.

    ``tangent0`` ``(S,)`` in state coordinates is projected on the dynamical
    directions; ``None`` takes the fixed generic direction. The component
    along the flow ``f(state0)`` is removed from the generic direction (a
    shift along the flow is no perturbation of the orbit) and, for
    ``per="collision"``, from a given one too: the collision map's Jacobian
    annihilates it (``DP f = 0``), so keeping it would only rescale ``|w_0|``.
    """
    f = to_dynamical(scene, state0, scene.phase_velocity(state0)[:, None])[:, 0]
    if tangent0 is None:
        v = jnp.asarray(_generic_direction(dynamical_size(scene)))
    else:
        v = to_dynamical(scene, state0, tangent0[:, None])[:, 0]
    if tangent0 is None or per == "collision":
        v = v - f * (f @ v) / (f @ f)
    return v


def _initial_vector(scene, state0, tangent0, per):
    """The unit starting vector in the dynamical frame at ``state0``: ``(k,)``."""
    v = _starting_direction(scene, state0, tangent0, per)
    return v / jnp.linalg.norm(v)


def _accumulate(carry, log_stretch, tau, megno: bool):
    """One collision's update of the indicators' running sums (MEGNO's only when ``megno``, static: the FLI
    alone needs two of them, and for a cheap collision the other three weigh on the tangent run).

    ``carry = (L, fli, tau_prev, moment, Y, area)``: ``L = log|w|``, the FLI,
    the previous time, ``moment = int_0^tau s dL``, ``Y`` and
    ``area = int_0^tau Y ds``; ``log_stretch = log(|w_k| / |w_{k-1}|)`` and
    ``tau`` the new time (``k`` or ``t_k``). Trapezoid rules, see the module
    docstring.
    """
    log_norm, fli, tau_prev, moment, y, area = carry
    log_norm = log_norm + log_stretch
    fli = jnp.maximum(fli, log_norm)
    if not megno:
        return (log_norm, fli, tau, moment, y, area)
    moment = moment + 0.5 * (tau_prev + tau) * log_stretch
    positive = tau > 0
    safe_tau = jnp.where(positive, tau, 1.0)
    y_new = jnp.where(positive, 2.0 * moment / safe_tau, 0.0)
    area = area + 0.5 * (tau - tau_prev) * (y + y_new)
    return (log_norm, fli, tau, moment, y_new, area)


def _mean_megno(area, tau):
    return jnp.where(tau > 0, area / jnp.where(tau > 0, tau, 1.0), 0.0)


def _indicators_one(scene, state0, tangent0, n, per, n_history, megno):
    """FLI (and MEGNO when ``megno``) of one orbit from ``state0`` ``(S,)``; see ``fli``."""
    flow = per == "time"
    v0 = _initial_vector(scene, state0, tangent0, per)
    constants = orbit_constants(scene, state0)

    def collision(carry, _):
        state, v, t, k, sums, result = carry
        pushed = pushed_frame(scene, state, v[:, None], flow=flow, constants=constants)
        stretched = pushed.frame[:, 0]
        stretch = jnp.linalg.norm(stretched)
        tau = t + pushed.dt if flow else (k + 1).astype(jnp.float64)
        sums_after = _accumulate(sums, jnp.log(stretch), tau, megno)
        values = (pushed.state, stretched / stretch, t + pushed.dt, k + 1, sums_after)
        if stops_orbits(scene):
            # An orbit that ended (a hole, a stopping condition) keeps the indicators of its last reflection.
            values = kept_where(tangent_held(result, pushed.status), (state, v, t, k, sums), values)
        return (*values, first_failure(result, pushed.status)), None

    n_hist = max(1, min(n_history, n))
    stride = n // n_hist
    rest = n - n_hist * stride

    def checkpoint(carry, _):
        carry, _ = jax.lax.scan(collision, carry, None, length=stride)
        _, _, t, _, (_, fli, tau, _, _, area), _ = carry
        return carry, (fli, _mean_megno(area, tau), t)

    zero = jnp.zeros((), jnp.float64)
    valid = scene.is_valid(state0)
    carry = (state0, v0, zero, jnp.zeros((), jnp.int32), (zero, zero, zero, zero, zero, zero), start_result(valid))
    carry, (fli_hist, megno_hist, t_hist) = jax.lax.scan(checkpoint, carry, None, length=n_hist)
    carry, _ = jax.lax.scan(collision, carry, None, length=rest)
    _, _, t, _, (log_norm, fli, tau, _, y, area), result = carry
    # Later states come from the map itself; only the start needs checking.
    poisoned = poison_if(~valid, fli, log_norm, fli_hist, _mean_megno(area, tau), y, megno_hist, t_hist, t)
    return (*poisoned, result)


@eqx.filter_jit
def _indicators_jit(scene, states, tangent0, n, per, n_history, megno):
    if states.ndim == 1:
        return _indicators_one(scene, states, tangent0, n, per, n_history, megno)
    tangent_axis = None if tangent0 is None or tangent0.ndim == 1 else 0
    return map_over_orbits(scene, _indicators_one, (None, 0, tangent_axis, None, None, None, None))(
        scene, states, tangent0, n, per, n_history, megno
    )


def _checked_tangent(scene, states, tangent0, per):
    """``tangent0`` as float64 ``(S,)`` or ``(B, S)`` matching ``states``, or ValueError naming it."""
    if tangent0 is None:
        return None
    raw = tangent0
    dtype = raw.dtype if hasattr(raw, "dtype") else np.asarray(raw).dtype
    if np.issubdtype(dtype, np.bool_) or not (np.issubdtype(dtype, np.floating) or np.issubdtype(dtype, np.integer)):
        raise ValueError(f"tangent0 must be a real array; got dtype {dtype}")
    tangent0 = jnp.asarray(raw, jnp.float64)
    size = scene.state_size
    if tangent0.shape not in ((size,), tuple(jnp.shape(states))):
        raise ValueError(
            f"tangent0 must have shape ({size},) or the states' shape {tuple(jnp.shape(states))} "
            f"(a tangent vector in state coordinates); got {tangent0.shape}"
        )
    if is_concrete(tangent0) and is_concrete(states):
        starts = jnp.atleast_2d(jnp.asarray(states, jnp.float64))
        directions = jax.vmap(lambda s, w: _starting_direction(scene, s, w, per))(
            starts, jnp.broadcast_to(tangent0, starts.shape)
        )
        norms = np.linalg.norm(np.asarray(directions), axis=-1)
        given = np.linalg.norm(np.broadcast_to(np.asarray(tangent0), starts.shape), axis=-1)
        # Relative: a vector along the flow leaves rounding noise, not a direction.
        if not np.all(np.isfinite(norms)) or np.any(norms <= 1e-10 * given):
            raise ValueError(
                "tangent0 must be finite with a nonzero component along the scene's dynamical directions "
                "(jaxbill.dynamical_frame), and for per='collision' off the flow direction (DP f = 0)"
            )
    return tangent0


def _run(scene, states, n, per, tangent0, n_history, megno):
    if per not in PER:
        raise ValueError(f"per must be one of {PER}; got {per!r}")
    n = check_count("n", n, 1, "number of collisions")
    n_history = check_count("n_history", n_history, 1, "checkpoints kept", MAX_STORED_COUNT)
    check_eagerly(scene, states)  # before any conversion: a bool or complex state is refused, not cast
    states = jnp.asarray(states, jnp.float64)
    tangent0 = _checked_tangent(scene, states, tangent0, per)
    n_hist = max(1, min(n_history, n))
    counts = (jnp.arange(1, n_hist + 1) * (n // n_hist)).astype(jnp.int32)
    return n, counts, _indicators_jit(scene, states, tangent0, n, per, n_history, megno)


_ARGS_DOC = """
    Args:
        scene: any scene (``StickInCircle``, ``StickInEllipse``,
            ``StickBetweenWalls2D``, ``StickBetweenWalls3D``).
        states: ``(S,)`` one start, or ``(B, S)`` a batch (run vmapped;
            ``jax.vmap`` over this function works too), ``S =
            scene.state_size``. Valid starts (ValueError otherwise).
        n: number of collisions (a positive Python int, static).
        per: ``"collision"`` (default): time is the collision count and the
            vector is carried by the collision map's Jacobian; ``"time"``:
            time is the flight time and the vector is carried by the flow's
            tangent maps (see the module docstring for why the default).
        tangent0: the starting tangent vector in state coordinates, ``(S,)``
            (for every start) or ``(B, S)``; only its components along the
            dynamical directions count (and for ``per="collision"`` only
            those off the flow direction, which the collision map
            annihilates), and it is normalised to length 1. Default: a fixed
            direction in general position in the dynamical frame with its
            component along the flow removed.
        n_history: number of checkpoints kept in ``history`` (static).
"""


def fli(
    scene: Scene,
    states: Float[ArrayLike, "*B S"],
    n: int,
    *,
    per: str = "collision",
    tangent0: Float[ArrayLike, "*#B S"] | None = None,
    n_history: int = 100,
) -> FastLyapunovIndicator:
    """The fast Lyapunov indicator (Froeschle, Lega, Gonczi 1997) of each orbit after ``n`` collisions.

    ``FLI = max_{k <= n} log|w_k|``: the running maximum of the log-length of
    one tangent vector, started at length 1 and carried by the tangent maps
    (``jaxbill.tangent_map``), renormalised at every collision so that it
    never overflows. Regular orbits: ``FLI ~ log n`` (linear stretching);
    chaotic: ``FLI ~ lambda n`` (``lambda`` the largest Lyapunov exponent per
    collision, or per unit time with ``per="time"`` and ``n`` read as time).
    Definitions and discretisation: ``jaxbill._analysis.indicators``.
    {args}
    Returns:
        ``FastLyapunovIndicator``: ``value`` ``()`` or ``(B,)``, ``history``
        ``(H,)`` or ``(B, H)``.

    Raises:
        ValueError: ``n``, ``n_history``, ``per`` or ``tangent0`` invalid (the
            message names the parameter), or ``states`` of the wrong shape or
            not valid starts.
    """
    n, counts, out = _run(scene, states, n, per, tangent0, n_history, megno=False)
    value, log_norm, fli_hist, _, _, _, t_hist, t, result = out
    return FastLyapunovIndicator(
        value=value,
        log_norm=log_norm,
        history=fli_hist,
        collisions=counts,
        times=t_hist,
        time=t,
        result=result,
        n=n,
        per=per,
    )


def megno(
    scene: Scene,
    states: Float[ArrayLike, "*B S"],
    n: int,
    *,
    per: str = "collision",
    tangent0: Float[ArrayLike, "*#B S"] | None = None,
    n_history: int = 100,
) -> Megno:
    """MEGNO (Cincotta, Simo 2000) of each orbit after ``n`` collisions.

    ``Y(tau) = (2/tau) int_0^tau s (|w|'/|w|)(s) ds`` and its running mean
    ``<Y>``, for one tangent vector ``w`` carried by the tangent maps
    (renormalised at every collision; the same vector as ``fli``). ``<Y> -> 2``
    on a regular orbit, ``-> 0`` on a stable periodic one, ``~ lambda tau / 2``
    on a chaotic one (``tau = n`` collisions, or the flight time with
    ``per="time"``). Definitions and discretisation: ``jaxbill._analysis.indicators``.
    {args}
    Returns:
        ``Megno``: ``value`` (``<Y>``) and ``instantaneous`` (``Y``) ``()`` or
        ``(B,)``, ``history`` ``(H,)`` or ``(B, H)``.

    Raises:
        ValueError: as ``fli``.
    """
    n, counts, out = _run(scene, states, n, per, tangent0, n_history, megno=True)
    _, _, _, value, y, megno_hist, t_hist, t, result = out
    return Megno(
        value=value,
        instantaneous=y,
        history=megno_hist,
        collisions=counts,
        times=t_hist,
        time=t,
        result=result,
        n=n,
        per=per,
    )


# Docstrings are None under ``python -OO``: only fill in the ones that are there.
for _documented in (fli, megno):
    if _documented.__doc__ is not None:
        _documented.__doc__ = _documented.__doc__.replace("    {args}\n", _ARGS_DOC)


# The starts' validity in one compiled call, kept across calls: run eagerly, the trigonometry's
# conditionals were traced anew for every call, a fixed cost far above the map's collisions.
_valid_starts = eqx.filter_jit(lambda scene, states: jax.vmap(scene.is_valid)(states))


def fli_map(
    scene: Scene,
    states_grid: Float[ArrayLike, "*grid S"],
    n: int,
    *,
    per: str = "collision",
    tangent0: Float[ArrayLike, " S"] | None = None,
    chunk: int = MAP_CHUNK,
    driver: str | None = None,
) -> Float[np.ndarray, "*grid"]:
    """The FLI after ``n`` collisions over a grid of starts: an array of the grid's shape.

    Args:
        scene: any scene.
        states_grid: ``(..., S)`` starts (for instance ``jaxbill.section_state``
            on a ``meshgrid`` of section coordinates). Starts that are not
            valid (outside the table, NaN where a section point is
            unreachable) give NaN pixels instead of an error.
        n: number of collisions (a positive Python int).
        per: ``"collision"`` (default) or ``"time"``, as in ``fli``.
        tangent0: ``(S,)`` starting tangent vector for every pixel, as in
            ``fli`` (default: the generic direction orthogonal to the flow).
        chunk: pixels per compiled batch (one program serves every chunk;
            memory grows with it, not with the grid).
        driver: ``"autodiff"``: ``fli``'s scan of autodiff tangent maps;
            ``"pallas"``: the tangent vector carried inside the Pallas kernel
            of the lane state machine (``jaxbill._engine.pallas.pallas_fli``; the
            same values to rounding; ``per="collision"`` and scenes whose
            dynamical directions are state coordinates, without holes or a
            stopping condition). ``None``: ``"pallas"``
            on a GPU where it applies, else ``"autodiff"``. On a CPU the
            kernel runs in Pallas's interpreter (slow: for tests).

    Returns:
        numpy float64 array of shape ``states_grid.shape[:-1]``: the FLI
        (``FastLyapunovIndicator.value``) of each start, NaN for invalid starts.
        Draw it with ``jaxbill.plotting.plot_fli_map``.
    """
    if per not in PER:
        raise ValueError(f"per must be one of {PER}; got {per!r}")
    # The kernel's tangent vector runs on through a hole; fli's scan keeps an ended orbit's values.
    kernel_applies = per == "collision" and hasattr(scene, "dynamical_indices") and not stops_orbits(scene)
    if driver is None:
        driver = "pallas" if kernel_applies and jax.default_backend() != "cpu" else "autodiff"
    if driver not in ("autodiff", "pallas"):
        raise ValueError(f"driver must be 'autodiff', 'pallas' or None; got {driver!r}")
    if driver == "pallas" and not kernel_applies:
        raise ValueError(
            "driver='pallas' needs per='collision' and a scene whose dynamical directions are "
            f"state coordinates, without holes or a stopping condition ({type(scene).__name__} with "
            f"per={per!r}: use driver='autodiff')"
        )
    n = check_count("n", n, 1, "number of collisions")
    chunk = check_count("chunk", chunk, 1, "pixels per compiled batch")
    require_x64()
    check_unbatched_scene(scene)
    scene.check()
    check_last_axis(scene, states_grid, name="states_grid")
    grid = np.asarray(states_grid, dtype=np.float64)
    shape = grid.shape[:-1]
    flat = grid.reshape(-1, scene.state_size)
    if tangent0 is not None:
        tangent0 = np.asarray(tangent0, dtype=np.float64)
        if tangent0.shape != (scene.state_size,):
            raise ValueError(f"tangent0 must have shape ({scene.state_size},) for a map; got {tangent0.shape}")
    finite = np.all(np.isfinite(flat), axis=-1)
    valid = finite.copy()
    valid[finite] = np.asarray(_valid_starts(scene, jnp.asarray(flat[finite])), dtype=bool)
    out = np.full(flat.shape[0], np.nan)
    starts = flat[valid]
    if len(starts) == 0:
        return out.reshape(shape)
    size = min(chunk, len(starts))
    if driver == "pallas":
        size = -(-size // pallas.BLOCK) * pallas.BLOCK  # whole blocks of the kernel
    for begin in range(0, len(starts), size):
        block = starts[begin : begin + size]
        count = len(block)
        # Pad the last chunk with copies of a valid start: one compiled shape.
        padded = np.concatenate([block, np.repeat(block[:1], size - count, axis=0)])
        if driver == "pallas":
            values = _kernel_fli(
                scene,
                jnp.asarray(padded),
                None if tangent0 is None else jnp.asarray(tangent0),
                n,
                jax.default_backend() == "cpu",
            )
        else:
            values = fli(scene, padded, n, per=per, tangent0=tangent0, n_history=1).value
        out[np.flatnonzero(valid)[begin : begin + count]] = np.asarray(values)[:count]
    return out.reshape(shape)


@eqx.filter_jit
def _kernel_fli(scene, states, tangent0, n, interpret):
    """``fli``'s value (``per="collision"``) from the same starting vectors, by the Pallas kernel."""

    def starting_vector(state):
        return to_state_space(scene, state, _initial_vector(scene, state, tangent0, "collision")[:, None])[:, 0]

    return pallas.pallas_fli(scene, states, jax.vmap(starting_vector)(states), n, interpret=interpret)[0]
