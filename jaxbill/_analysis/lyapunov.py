"""Lyapunov spectra by repeated QR (Benettin's method) on autodiff tangent maps."""

from __future__ import annotations

import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np
from jaxtyping import Array, ArrayLike, Float, Int

from jaxbill._engine.collision import check_eagerly, poison_if
from jaxbill._engine.drivers import map_over_orbits
from jaxbill._engine.results import first_failure, has_stopped, kept_where, start_result, tangent_held
from jaxbill._engine.step import orbit_constants, stops_orbits
from jaxbill._engine.tangent import dynamical_size, pushed_frame
from jaxbill._engine.validation import MAX_STORED_COUNT, check_count
from jaxbill._scenes.protocols import Scene

PER = ("time", "collision")

_LN2 = float(np.log(2.0))


def no_growth(shape: tuple[int, ...] = ()) -> tuple[jax.Array, jax.Array]:
    """A growth factor of 1, as ``(mantissa, exponent)``: see ``grown``."""
    return jnp.ones(shape, jnp.float64), jnp.zeros(shape, jnp.int64)


def grown(growth: tuple[jax.Array, jax.Array], factor: jax.Array) -> tuple[jax.Array, jax.Array]:
    """``growth * factor`` for a growth held as ``mantissa * 2**exponent`` (``mantissa`` in ``[0.5, 1)``).

    A product of stretch factors over any number of collisions that cannot
    overflow or underflow, whose log (``log_of``) is taken once at the end:
    a log at every collision cost as much as a QR factorisation, and more than
    an FTLE's tangent step (XLA:CPU evaluates a float64 log lane by lane).
    """
    mantissa, exponent = growth
    mantissa, doublings = jnp.frexp(mantissa * factor)
    return mantissa, exponent + doublings


def log_of(growth: tuple[jax.Array, jax.Array]) -> jax.Array:
    """The natural log of a growth held by ``grown``."""
    mantissa, exponent = growth
    return jnp.log(mantissa) + exponent * _LN2


class LyapunovSpectrum(eqx.Module):
    """A Lyapunov spectrum and how its estimate converged.

    For a batch of initial conditions every field has a leading batch axis.

    Attributes:
        exponents: ``(K,)`` the exponents, in descending order; per unit time
            (``per = "time"``) or per collision (``per = "collision"``).
        history: ``(H, K)`` the running estimates (descending) at ``H``
            checkpoints spread evenly over the run.
        collisions: ``(H,)`` int, number of collisions at each checkpoint.
        times: ``(H,)`` elapsed flight time at each checkpoint.
        time: ``()`` total elapsed time over the ``n`` collisions.
        result: ``()`` int32: why the orbit stopped, or what went wrong first
            (``jb.Result``; ``FINISHED`` when all went well).
            An orbit that ended for good (``ESCAPED``, ``STOPPED``) keeps the
            exponents of its reflections before its end (a crossing through a
            hole is none), NaN when it ended before its first.
        n: number of collisions (static).
        per: ``"time"`` or ``"collision"`` (static).
        paired: whether the lower half of the spectrum is the upper half's
            negatives (the pairing rule, assumed) rather than measured (static;
            see ``lyapunov_spectrum``'s ``paired``).

    ``n / time`` is the mean collision rate: per-time exponents times
    ``time / n`` are per-collision exponents and conversely.
    """

    exponents: Float[Array, "*batch K"]
    history: Float[Array, "*batch H K"]
    collisions: Int[Array, "*batch H"]
    times: Float[Array, "*batch H"]
    time: Float[Array, "*batch"]
    result: Int[Array, "*batch"]
    n: int = eqx.field(static=True)
    per: str = eqx.field(static=True)
    paired: bool = eqx.field(static=True)


def _initial_vectors(n_dim: int, k: int) -> jax.Array:
    """A fixed orthonormal frame in general position (seeded, the same every call)."""
    a = np.random.default_rng(20240601).standard_normal((n_dim, n_dim))
    q, _ = np.linalg.qr(a)
    return jnp.asarray(q[:, :k])


def _orthonormalised(frame: jax.Array) -> tuple[jax.Array, jax.Array]:
    """``(Q, diag R)`` of the QR factorisation of a frame ``(D, k)``, ``R_ii > 0``: modified Gram-Schmidt,
    each vector orthogonalised twice ("twice is enough": orthogonal to rounding unless the frame is
    numerically singular).

    Written out, not ``jnp.linalg.qr``: a factorisation this small is a few
    hundred flops, where LAPACK's call per orbit and collision cost more than
    the collision (the spinning stick's spectrum, measured both ways:
    ``benchmarks/HISTORY.md``).
    """
    basis: list[jax.Array] = []
    norms = []
    for j in range(frame.shape[1]):
        v = frame[:, j]
        for _ in range(2):
            for u in basis:
                v = v - jnp.dot(u, v) * u
        norm = jnp.sqrt(jnp.dot(v, v))
        basis.append(v / norm)
        norms.append(norm)
    return jnp.stack(basis, axis=1), jnp.stack(norms)


def _descending(values: jax.Array) -> jax.Array:
    """``values`` sorted along the last axis, largest first and NaN last, as ``-jnp.sort(-values)``.

    By compare-and-swap rounds (odd-even transposition, ``K`` rounds sort ``K``
    values; ties keep their order, as in ``jnp.sort``): elementwise work that
    XLA vectorises over the batch, where XLA:CPU's sort op, on the history of a
    batch, ``(B, H, K)``, was a large part of a static lens's spectrum over
    400 collisions with 100 checkpoints (``benchmarks/HISTORY.md``).
    """
    rows = [values[..., i] for i in range(values.shape[-1])]
    for first in [i % 2 for i in range(len(rows))]:
        for i in range(first, len(rows) - 1, 2):
            a, b = rows[i], rows[i + 1]
            swap = (b > a) | (jnp.isnan(a) & ~jnp.isnan(b))
            rows[i], rows[i + 1] = jnp.where(swap, b, a), jnp.where(swap, a, b)
    return jnp.stack(rows, axis=-1)


def _rate(logs, clock):
    return jnp.where(clock > 0, logs / jnp.where(clock > 0, clock, 1), jnp.nan)


def _with_partners(values: jax.Array, count: int) -> jax.Array:
    """``values`` ``(..., j)`` and the pairing partners ``-values`` of the first ``count``, ``(..., j + count)``
    (``_descending`` orders them)."""
    return jnp.concatenate([values, -values[..., :count]], axis=-1)


def _spectrum(scene, state0, n, per, qr_every, n_history, frame0, partners=0):
    flow = per == "time"
    constants = orbit_constants(scene, state0)

    def collision(carry, _):
        # The frame's coordinates in the dynamical directions at the current
        # state, carried to those at the next one (jaxbill._engine.tangent).
        state, q, t, count, result = carry
        pushed = pushed_frame(scene, state, q, flow=flow, constants=constants)
        values = (pushed.state, pushed.frame, t + pushed.dt, count + 1)
        if stops_orbits(scene):
            # An orbit that ended (a hole, a stopping condition) keeps the frame of its last reflection.
            values = kept_where(tangent_held(result, pushed.status), (state, q, t, count), values)
        return (*values, first_failure(result, pushed.status)), None

    def qr_step(carry, _):
        state, q, t, count, result, growth = carry
        (state, q, t, count, result), _ = jax.lax.scan(collision, (state, q, t, count, result), None, length=qr_every)
        q, diag = _orthonormalised(q)
        stepped = (state, q, t, count, result, grown(growth, diag))
        if stops_orbits(scene):
            # Past its end the frame is held: no rounding of further factorisations enters its growth.
            stepped = kept_where(has_stopped(carry[4]), carry, stepped)
        return stepped, None

    def qr_steps(carry, steps):
        """``steps`` (static) QR steps; their growth, logged once, added to the logs."""
        state, q, t, count, result, logs = carry
        start = (state, q, t, count, result, no_growth(logs.shape))
        (state, q, t, count, result, growth), _ = jax.lax.scan(qr_step, start, None, length=steps)
        return state, q, t, count, result, logs + log_of(growth)

    n_qr = n // qr_every
    n_hist = max(1, min(n_history, n_qr))
    stride = n_qr // n_hist
    rest = n_qr - n_hist * stride

    def checkpoint(carry, _):
        carry = qr_steps(carry, stride)
        _, _, t, count, _, logs = carry
        return carry, (logs, t, count)

    k = frame0.shape[1]
    valid = scene.is_valid(state0)
    time, count = jnp.zeros((), jnp.float64), jnp.zeros((), jnp.int32)
    carry = (state0, frame0, time, count, start_result(valid), jnp.zeros((k,), jnp.float64))
    carry, (logs_hist, t_hist, count_hist) = jax.lax.scan(checkpoint, carry, None, length=n_hist)
    if rest:
        carry = qr_steps(carry, rest)
    _, _, t, count, result, logs = carry
    counts = (jnp.arange(1, n_hist + 1) * stride * qr_every).astype(jnp.int32)
    # Per unit time, or per collision the frame went through (``counts`` and ``n``, or fewer for an orbit that
    # ended); an orbit that ended before its first reflection has no rate: NaN.
    clock_hist, clock = (t_hist, t) if flow else (count_hist, count)
    history = _rate(logs_hist, clock_hist[:, None])
    exponents = _rate(logs, clock)
    if partners:
        history, exponents = _with_partners(history, partners), _with_partners(exponents, partners)
    history = _descending(history)
    exponents = _descending(exponents)
    # Later states come from the map itself; only the start needs checking.
    exponents, history, t_hist, t = poison_if(~valid, exponents, history, t_hist, t)
    return LyapunovSpectrum(
        exponents=exponents,
        history=history,
        collisions=counts,
        times=t_hist,
        time=t,
        result=result,
        n=n,
        per=per,
        paired=partners > 0,
    )


@eqx.filter_jit
def _spectrum_jit(scene, state0, n, per, qr_every, n_history, frame0, partners):
    if state0.ndim == 1:
        return _spectrum(scene, state0, n, per, qr_every, n_history, frame0, partners)
    return map_over_orbits(scene, _spectrum, (None, 0, None, None, None, None, None, None))(
        scene, state0, n, per, qr_every, n_history, frame0, partners
    )


def lyapunov_spectrum(
    scene: Scene,
    state0: Float[ArrayLike, "*batch S"],
    n: int,
    *,
    per: str = "time",
    qr_every: int = 1,
    n_history: int = 100,
    paired: bool | None = None,
) -> LyapunovSpectrum:
    """The Lyapunov spectrum of an orbit, by Benettin's repeated QR.

    A frame of tangent vectors is carried along ``n`` collisions by the
    autodiff tangent maps (``jaxbill.tangent_map``) and re-orthonormalised by a
    QR factorisation every ``qr_every`` collisions; the exponents are the
    averages of ``log |R_ii|``. Memory does not grow with ``n``: the run is one
    ``lax.scan`` that keeps ``n_history`` checkpoints. The frame lives in the
    directions that carry the dynamics (``jaxbill.dynamical_frame``), written
    in an orthonormal basis of them at each state.

    Args:
        scene: any scene (``StickInCircle``, ``StickInEllipse``,
            ``StickBetweenWalls2D``, ``StickBetweenWalls3D``, ...).
        state0: shape ``(S,)`` (``S = scene.state_size``), or a batch
            ``(B, S)`` (the run is vmapped; ``jax.vmap`` over this function works too).
        n: number of collisions (a Python int, static); a multiple of ``qr_every``.
        per: ``"time"`` (default): the flow's spectrum per unit time, from the
            fixed-time flow tangent maps, with one exponent per dynamical
            direction ``k``, the scene's (``jaxbill.dynamical_frame``): for
            instance 6 for a spinning stick in a circle or an ellipse, 4 =
            ``(x, y, vx, vy)`` for a stick there that never turns and for the
            point; 4 = ``(z, theta, vz, omega)`` for ``StickBetweenWalls2D``, 6
            for ``StickBetweenWalls3D`` (2 for a wall stick that never turns).
            ``"collision"``: the spectrum of the collision (section) map per
            collision, from its Jacobian restricted to the section: one exponent
            fewer (the flow direction is not part of the section), ``k - 1``.
        qr_every: collisions between QR factorisations (static). 1 is always
            safe; larger values are faster but overflow or lose the small
            exponents if the frame grows by more than ~1e150 between QRs.
        n_history: number of checkpoints kept in ``history`` (static).
        paired: ``True``: only the first half of the tangent vectors are
            carried (``k / 2`` per time; ``k / 2`` rounded up per collision,
            whose middle exponent is the energy's zero), and the lower half
            of the spectrum is the upper half's negatives, by the pairing
            rule of a symplectic flow (``HasSymplecticFlow``): the same upper
            half as the full run's leading vectors, in about half the
            work (the measured rates: the performance page, "Tangent
            steps"). ``False``: all
            ``k`` vectors are carried and the pairing is measured, a check
            of how far a run of this length has converged (the paired run
            still measures the zero exponents of its upper half, whose decay
            shows as much). ``None`` (default): ``True`` where the
            scene declares a symplectic flow with an even number of
            dynamical directions (every scene jaxbill ships), ``False``
            otherwise. The result's ``paired`` says which ran.

    Returns:
        ``LyapunovSpectrum`` (with a leading batch axis for a batch of states):
        ``exponents`` ``(k,)``, ``history`` ``(H, k)``.

    Expected spectra, from the flow's symmetries and invariants: a spinning stick ``{lam, 0, 0, 0, 0,
    -lam}`` (zeros: time shift, energy, angular momentum, rotation angle); the
    static lens ``{lam, 0, 0, -lam}``; the circle all zero. Between walls:
    2D ``{lam, 0, 0, -lam}`` (time shift, energy); 3D ``{lam, 0, 0, 0, 0,
    -lam}`` (time shift, energy, the vertical spin ``w_z`` and the rotation
    of the stick about the vertical). The section map's
    spectrum is the flow's without the time-shift zero, multiplied by the mean
    flight time ``time / n``. Finite-``n`` estimates of zero exponents decay like
    ``log(n) / n``.
    """
    if per not in PER:
        raise ValueError(f"per must be one of {PER}; got {per!r}")
    n = check_count("n", n, 1, "number of collisions")
    qr_every = check_count("qr_every", qr_every, 1, "collisions between QR factorisations")
    n_history = check_count("n_history", n_history, 1, "checkpoints kept", MAX_STORED_COUNT)
    if n < qr_every or n % qr_every:
        raise ValueError(f"n must be a positive multiple of qr_every = {qr_every}; got {n}")
    check_eagerly(scene, state0)
    n_dim = dynamical_size(scene)
    k = n_dim if per == "time" else n_dim - 1
    frame0 = _initial_vectors(n_dim, k)
    if paired is not None and not isinstance(paired, bool | np.bool_):
        raise ValueError(f"paired must be True, False or None (the scene decides); got {paired!r}")
    unpaired_because = _why_not_paired(scene, n_dim)
    if paired is None:
        paired = unpaired_because is None
    elif paired and unpaired_because is not None:
        raise ValueError(f"paired=True needs {unpaired_because}")
    partners = 0
    if paired:
        partners = k // 2
        frame0 = frame0[:, : k - partners]
    return _spectrum_jit(scene, jnp.asarray(state0, dtype=jnp.float64), n, per, qr_every, n_history, frame0, partners)


def _why_not_paired(scene: Scene, n_dim: int) -> str | None:
    """``None`` where the exponents of ``scene``'s flow (``n_dim`` of them) come in pairs ``lambda, -lambda``;
    else what is missing, for the error ``paired=True`` raises."""
    if getattr(scene, "symplectic_flow", False) is not True:
        return (
            f"a scene whose flow is symplectic (symplectic_flow = True, the HasSymplecticFlow protocol of "
            f"jaxbill._scenes.protocols); {type(scene).__name__} does not say so"
        )
    if n_dim % 2:
        return f"an even number of dynamical directions (a symplectic flow has one); {type(scene).__name__} has {n_dim}"
    return None
