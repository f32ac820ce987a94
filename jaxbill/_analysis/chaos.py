"""Chaos indicators over a batch: finite-time largest Lyapunov exponents and the chaotic fraction.

``sample_energy_shell`` draws initial conditions with the microcanonical
(Liouville) measure restricted to fixed energy ``E`` and, for a spinning stick,
fixed total angular momentum ``L``; ``finite_time_lyapunov`` gives each one's
largest exponent after ``n`` collisions; ``chaotic_fraction`` is the weighted
fraction whose exponent exceeds a threshold, an estimate of the fraction of the
``(E, L)`` shell filled by chaotic orbits.
"""

from __future__ import annotations

import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np
from jaxtyping import Array, ArrayLike, Float, Int

from jaxbill._analysis.lyapunov import grown, log_of, no_growth
from jaxbill._engine.collision import check_eagerly, poison_if
from jaxbill._engine.drivers import map_over_orbits
from jaxbill._engine.results import first_failure, start_result
from jaxbill._engine.step import orbit_constants
from jaxbill._engine.tangent import dynamical_size, pushed_frame
from jaxbill._engine.validation import check_count
from jaxbill._scenes.protocols import SamplesStates, Scene


class FiniteTimeLyapunov(eqx.Module):
    """Finite-time largest Lyapunov exponents of a batch of orbits.

    Attributes:
        per_time: ``(B,)`` largest exponent per unit time after ``n`` collisions.
        per_collision: ``(B,)`` the same growth per collision.
        time: ``(B,)`` elapsed time over the ``n`` collisions.
        result: ``(B,)`` int32: why each orbit stopped, or what went wrong first
            (``jb.Result``; ``FINISHED`` when all went well).
        n: number of collisions (static).
    """

    per_time: Float[Array, " B"]
    per_collision: Float[Array, " B"]
    time: Float[Array, " B"]
    result: Int[Array, " B"]
    n: int = eqx.field(static=True)


def _ftle_one(scene, state0, n, vector0):
    constants = orbit_constants(scene, state0)

    def step(carry, _):
        state, v, growth, t, result = carry
        pushed = pushed_frame(scene, state, v[:, None], flow=True, constants=constants)
        v = pushed.frame[:, 0]
        norm = jnp.linalg.norm(v)
        return (pushed.state, v / norm, grown(growth, norm), t + pushed.dt, first_failure(result, pushed.status)), None

    valid = scene.is_valid(state0)
    init = (state0, vector0, no_growth(), jnp.zeros(()), start_result(valid))
    (_, _, growth, t, result), _ = jax.lax.scan(step, init, None, length=n)
    log_growth = log_of(growth)
    # Later states come from the map itself; only the start needs checking.
    return (*poison_if(~valid, log_growth / t, log_growth / n, t), result)


@eqx.filter_jit
def _ftle_jit(scene, states, n, vector0):
    per_time, per_collision, t, result = map_over_orbits(scene, _ftle_one, (None, 0, None, None))(
        scene, states, n, vector0
    )
    return FiniteTimeLyapunov(per_time=per_time, per_collision=per_collision, time=t, result=result, n=n)


def finite_time_lyapunov(
    scene: Scene, states: Float[ArrayLike, "B S"] | Float[ArrayLike, " S"], n: int
) -> FiniteTimeLyapunov:
    """The largest Lyapunov exponent of each orbit of a batch, after ``n`` collisions.

    One tangent vector (a fixed direction in general position) is carried by the
    flow's tangent maps and renormalised at every collision; memory does not grow
    with ``n``. Regular (quasi-periodic) orbits give exponents that decay like
    ``log(n) / n`` (tangent vectors grow linearly); chaotic ones converge to a
    positive value.

    Args:
        scene: any scene (the vector lives in its dynamical directions, see
            ``jaxbill.dynamical_frame``).
        states: shape ``(B, S)`` (or ``(S,)``, treated as a batch of one),
            ``S = scene.state_size``.
        n: number of collisions (Python int, static).
    """
    n = check_count("n", n, 1, "number of collisions")
    check_eagerly(scene, states)  # before any conversion: a bool or complex state is refused, not cast
    states = jnp.atleast_2d(jnp.asarray(states, jnp.float64))
    k = dynamical_size(scene)
    v0 = np.random.default_rng(7).standard_normal(k)
    return _ftle_jit(scene, states, n, jnp.asarray(v0 / np.linalg.norm(v0)))


def chaos_threshold(n: int, factor: float = 5.0) -> float:
    """Default threshold on the per-collision exponent: ``factor * log(n) / n``.

    A regular orbit's tangent vector grows at most polynomially (linearly for a
    twist), so its finite-time exponent per collision is about ``log(n) / n``;
    ``factor`` leaves room for the prefactor.
    """
    return factor * float(np.log(n)) / n


def chaotic_fraction(
    exponents: Float[ArrayLike, " B"],
    weights: Float[ArrayLike, " B"] | None = None,
    threshold: float | None = None,
    n: int | None = None,
) -> float:
    """Weighted fraction of orbits whose finite-time exponent exceeds ``threshold``.

    Args:
        exponents: ``(B,)`` per-collision finite-time exponents (e.g.
            ``finite_time_lyapunov(...).per_collision``).
        weights: ``(B,)`` sample weights (from ``sample_energy_shell``); default equal.
        threshold: default ``chaos_threshold(n)``.
        n: the number of collisions behind the exponents (for the default threshold).
    """
    e = np.asarray(exponents, dtype=np.float64)
    w = np.ones_like(e) if weights is None else np.asarray(weights, dtype=np.float64)
    if threshold is None:
        if n is None:
            raise ValueError("give threshold, or n for the default threshold 5 log(n)/n")
        threshold = chaos_threshold(n)
    ok = np.isfinite(e)
    return float(np.sum(w[ok] * (e[ok] > threshold)) / np.sum(w[ok]))


def sample_energy_shell(
    scene: Scene,
    size: int,
    *,
    energy: float = 0.5,
    angular_momentum: float | None = None,
    seed: int = 0,
    margin: float = 1e-9,
) -> tuple[Float[np.ndarray, "size S"], Float[np.ndarray, " size"]]:
    """Initial conditions with the Liouville measure on a shell of fixed ``E`` (and ``L``).

    The scene draws them (``sample_states``, the ``SamplesStates`` protocol);
    this loops until ``size`` are kept. What follows is ``StickInCircle``'s
    sampler (a body in another table, ``StickInEllipse`` among them: energy only; see
    ``jaxbill._scenes.shell_sampling``).

    Configurations ``(x, y, alpha)`` are drawn uniformly among those with both
    ends inside the circle (by ``margin``, relative to ``R``). Velocities, in the
    mass-weighted coordinates ``pi = (sqrt(M) vx, sqrt(M) vy, sqrt(I) omega)``
    where the kinetic energy is ``|pi|^2 / 2``:

    * energy only (static lens, circle, or ``angular_momentum=None``):
      ``pi`` uniform on its sphere ``|pi|^2 = 2E`` (a circle for the lens and
      the circle billiard, whose spin is zero); all weights are 1.
    * energy and angular momentum (spinning stick): ``L = b(q) . pi`` with
      ``b = (-sqrt(M) y, sqrt(M) x, sqrt(I))`` is linear in ``pi``, so the shell
      over a configuration is a circle, the sphere cut by a plane at distance
      ``L / |b|``, drawn uniformly. Integrating ``delta(H - E) delta(L - b.pi)``
      over ``pi`` gives ``2 pi / |b(q)|`` when the plane cuts the sphere and 0
      otherwise: that is each sample's weight (normalised to mean 1 over the
      samples kept).

    Returns:
        ``(states, weights)``: numpy arrays of shapes ``(size, 6)`` and ``(size,)``.
        Weighted averages over them are microcanonical averages.
    """
    if not isinstance(scene, SamplesStates):
        raise TypeError(
            f"scene: {type(scene).__name__} cannot draw states on an energy shell (no sample_states: "
            "every body in a table, jb.BodyInTable and the sticks built on it, has one)"
        )
    rng = np.random.default_rng(seed)
    states, weights = [], []
    count = 0
    while count < size:
        m = 2 * (size - count) + 16
        batch, w = scene.sample_states(rng, m, energy, angular_momentum=angular_momentum, margin=margin)
        states.append(batch)
        weights.append(w)
        count += len(w)
    states = np.concatenate(states)[:size]
    weights = np.concatenate(weights)[:size]
    return states, weights / weights.mean()
