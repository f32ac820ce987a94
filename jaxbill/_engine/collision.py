"""The collision map and the orbit scan."""

from __future__ import annotations

import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np
from jaxtyping import Array, ArrayLike, Float, Int

from jaxbill._engine.chunks import Plan, fresh_carry
from jaxbill._engine.drivers import Batch, choose_driver, chunk_function
from jaxbill._engine.interface import SEVERAL_CONTACTS, Scene
from jaxbill._engine.serial import orbit_chunk
from jaxbill._engine.sharding import DeviceChoice
from jaxbill._engine.step import advance, orbit_constants
from jaxbill._engine.validation import (
    check_orbit_length,
    check_scene,
    check_state,
    check_state_static,
    check_unbatched_scene,
    is_concrete,
    require_x64,
)

CORNER = SEVERAL_CONTACTS  # the stick in a circle's name for it: both ends at once


class Orbit(eqx.Module):
    """Collisions of one orbit (or a batch: then every field has a leading batch axis).

    Attributes:
        t: ``(n,)`` absolute time of each collision (time zero is ``state0``).
        contact: ``(n,)`` int32: which end touched which wall (the codes are
            the scene's; ``StickInCircle``: ``+1`` end P1, ``-1`` end P2), ``2``
            several contacts at once (a corner), ``0`` none (the flight never
            reaches a wall: ``t = inf`` from then on; or the orbit has ended:
            ``dt = 0`` from then on), ``-1`` an exit through a hole.
        state: ``(n, S)`` the state just after each collision
            (``S = scene.state_size``).
        result: ``()`` int32: why the orbit stopped, or what went wrong first
            (``jb.Result``: ``FINISHED``, ``INVALID_START``, ``NO_WALL``,
            ``ROOT_STEPS_EXHAUSTED``, ``NON_FINITE``, ``BOUND_VIOLATED``,
            ``ESCAPED``, ``STOPPED``).
    """

    t: Float[Array, "*batch n"]
    contact: Int[Array, "*batch n"]
    state: Float[Array, "*batch n S"]
    result: Int[Array, "*batch"]

    def first(self, count: int) -> Orbit:
        """The first ``count`` collisions of the orbit (of each orbit of a batch), its result code kept.

        ``jax.tree.map(lambda a: a[:count], orbit)`` would cut the result code
        too (a batch's orbits, or fail on one orbit's scalar code).
        """
        return Orbit(
            t=self.t[..., :count],
            contact=self.contact[..., :count],
            state=self.state[..., :count, :],
            result=self.result,
        )


def poison_if(bad, *arrays):
    """``arrays`` with NaN (floats) or 0 (integers) where ``bad``: how traced input too bad to run reports."""
    return tuple(
        jnp.where(bad, jnp.nan, a) if jnp.issubdtype(a.dtype, jnp.floating) else jnp.where(bad, 0, a) for a in arrays
    )


def collide_unchecked(scene: Scene, state: jax.Array):
    """``collide`` without its eager checks, for code that traces it (a tangent map, a periodic-orbit
    residual): an invalid state is poisoned, never refused."""
    state = jnp.asarray(state, dtype=jnp.float64)
    return poison_if(~scene.is_valid(state), *advance(scene, state, orbit_constants(scene, state)))


def collide(scene: Scene, state: Float[ArrayLike, " S"]) -> tuple[Float[Array, " S"], Float[Array, ""], Int[Array, ""]]:
    """The collision map: from ``state`` to the state just after the next collision.

    Args:
        scene: any scene: one of jaxbill's (``StickInCircle``,
            ``StickInEllipse``, ``StickBetweenWalls2D``, ``StickBetweenWalls3D``,
            ...) or one written for the engine.
        state: float64, shape ``(scene.state_size,)``, laid out as the
            scene's ``state_layout`` says (``StickInCircle``: ``[x, y, alpha,
            vx, vy, omega]``); both ends inside (an end on a wall must be
            moving inwards, as it is just after a collision).

    Returns:
        ``(new_state, dt, contact)``: the state just after the impulse, the
        flight time ``dt`` to the collision, and the contact, the scene's code
        of the end that hit: in a circle or an ellipse ``+1`` end P1, ``-1``
        end P2; between walls ``+1``/``-1`` P1/P2 on the floor and
        ``+3``/``-3`` on the ceiling; ``2`` several contacts at once, ``0``
        none. A flight that never reaches a wall (e.g. ``v = 0`` with ``|c| +
        ell < R``) returns ``dt = inf``, contact 0 and the state unchanged.
        A point that reaches a hole of a ``jb.BodyInTable`` (``holes=``)
        returns the state as it arrives there, the flight time and contact ``-1``.
        After a collision angles are wrapped into ``[-pi, pi)``.

    What follows describes ``StickInCircle``; every scene whose gaps are not
    quadratic in time takes the same safe-step search on its own gaps (its
    module docstring says which).

    The collision time. For the static lens (``inertia = inf``, ``omega = 0``)
    each end moves on a straight line and its contact time is the larger root
    of a quadratic, in a cancellation-free form; the same holds for the centre
    in the circle billiard (``ell = 0``). For a spinning stick the gaps
    ``g_k(t) = R^2 - |P_k(t)|^2`` are transcendental; the first root is found
    by steps that provably cannot pass it (``jaxbill._engine.first_root``): each step
    goes to the first root of a quadratic lower bound of ``g_k`` built from a
    rigorous bound on ``g_k''``, and the search stops once a matching upper
    bound brackets the root to a few ulps. So:

    * a near double root (grazing hit) is approached from below, never
      stepped over, and a near miss is walked past without a false hit;
    * fast spin (``|omega| ell / |v| >= 1e3``) only shortens the safe steps,
      and the search starts when the centre first reaches radius ``R - ell``
      (no end can touch before), so it covers about one turn of the stick;
    * both ends touching at once (a lens corner, to within 64 ulps of the
      gap): both impulses are applied, the faster-approaching end first and
      the other only if it still approaches; the contact is reported as ``2``;
    * the end that just bounced has a root at ``t = 0``, but it is moving
      inwards, and only a touching end that is *approaching* counts as a root
      at the current time, so it is never found again.

    Differentiation: the collision time of a spinning stick is differentiated
    implicitly (a custom JVP rule on the root finder, ``dt = -dg/dg_t`` at the
    root), never through the search iterations; the closed forms are
    differentiated directly.

    Invalid input inside ``jit`` (traced values cannot raise) poisons the
    result: ``new_state`` and ``dt`` are NaN and the contact is 0. This covers
    non-finite states, velocities whose squares overflow or underflow, an end
    outside the wall by more than ``1e-12 R^2`` in the gap or on it (gap
    ``<= 0``) without moving inwards, invalid traced parameters, nonzero spin
    for the static lens, and a root search that hit its step bound. Called with concrete values
    (outside ``jit``), bad input raises ``ValueError`` instead. The shape and
    dtype of ``state`` and an unbatched ``scene`` are checked under ``jit``
    too (``ValueError``); ``RuntimeError`` if ``jax_enable_x64`` is off.
    """
    check_eagerly(scene, state, single=True)
    new_state, dt, contact = _collide_jit(scene, jnp.asarray(state, dtype=jnp.float64))
    return new_state, dt, contact


_collide_jit = eqx.filter_jit(collide_unchecked)


def check_eagerly(scene, state, *, single: bool = False) -> None:
    """The checks at every public entry point, before anything is compiled.

    Static ones (float64 on, the state's shape and dtype, one scene rather
    than a batch of them) raise even at trace time, under ``jit``; the value
    checks run only on concrete input (``jit``/``vmap`` poison with NaN).
    ``single``: ``state`` must be one state ``(S,)``, not a batch ``(B, S)``.
    """
    require_x64()
    check_unbatched_scene(scene)
    check_state_static(scene, state, single=single)
    if all(is_concrete(x) for x in jax.tree_util.tree_leaves(scene)):
        check_scene(scene)
        if is_concrete(state):
            check_state(scene, state)


def _orbit_plan(n: int) -> Plan:
    """A chunk that records every collision of ``n`` (and keeps no statistics: an ``Orbit`` has none)."""
    return Plan("states", every=1, rows=n, statistics=False)


def _orbit_of(carry, records) -> Orbit:
    t, contact, states = records
    return Orbit(t=t, contact=contact, state=states, result=carry.result)


def _orbit_single(scene: Scene, state0: jax.Array, n: int) -> Orbit:
    """``jb.orbit`` of one orbit ``(S,)``: one chunk of ``n`` collisions (scans: differentiable both ways)."""
    return _orbit_of(*orbit_chunk(_orbit_plan(n), scene, state0, fresh_carry(scene, state0), 0, n))


def _orbit_batch(scene: Scene, states0: jax.Array, n: int, driver: str = "serial") -> Orbit:
    """``jb.orbit`` of a batch ``(B, S)`` on one device: one chunk of the driver, in lanes of at most
    ``scene.batch_chunk`` orbits (a smaller batch is one narrower lane)."""
    batch, size = states0.shape
    width = 1 if driver == "serial" else max(1, min(batch, scene.batch_chunk))
    padded = jnp.concatenate([states0, jnp.broadcast_to(states0[:1], ((-batch) % width, size))])
    chunk = chunk_function(_orbit_plan(n), driver, width, interpret=jax.default_backend() == "cpu")
    orbit = _orbit_of(*chunk(scene, padded, fresh_carry(scene, padded), 0, n))
    return jax.tree.map(lambda a: a[:batch], orbit)


@eqx.filter_jit
def _orbit_jit(scene, state0, n, driver="serial"):
    if state0.ndim == 1:
        return _orbit_single(scene, state0, n)
    return _orbit_batch(scene, state0, n, driver)


def orbit(scene: Scene, state0: Float[ArrayLike, "*batch S"], n: int, *, driver: str | None = None) -> Orbit:
    """The first ``n`` collisions of the orbit from ``state0``.

    Args:
        scene: any scene (``StickInCircle``, ``StickBetweenWalls2D``,
            ``StickBetweenWalls3D``).
        state0: initial state, shape ``(S,)`` (``S = scene.state_size``: 6, 6,
            12), or a batch of them, shape ``(B, S)``.
        n: number of collisions (a Python int, static: each new ``n`` compiles).
        driver: for a batch, ``"serial"``, ``"lockstep"`` or ``"lanes"`` (see
            ``jaxbill._engine.drivers.choose_driver``; ``"pallas"`` records no states
            and stands for ``"lanes"`` here); ``None``, the default, picks
            the fastest for the scene on the platform (on a CPU ``"serial"``
            or ``"lockstep"`` by the scene's ``batch_chunk``, ``"lanes"`` on a
            GPU). All give the same orbits to rounding.

    Returns:
        ``Orbit`` with ``t`` ``(n,)``, ``contact`` ``(n,)``, ``state`` ``(n, S)``
        and ``result`` ``()`` (with a leading ``B`` axis for a batch; ``B = 0``
        gives empty arrays). Equivalent to ``n`` applications of ``collide``
        under ``lax.scan``; ``jax.vmap(orbit, in_axes=(None, 0, None))`` gives
        orbit by orbit what single runs give. It is one chunk of ``jb.run``
        with ``record="states"``: the same orbits, bit for bit.

    A concrete batch is split over every device JAX shows (``jb.orbit_sharded``;
    on a CPU jaxbill shows one device per core), padded to whole lanes of the
    driver's width on each (1 orbit for ``"serial"``), so an orbit's result
    does not depend on the batch around it or on the number of devices. Inside ``jit`` or
    ``vmap`` a batch runs on one device.

    Raises:
        ValueError: for ``n`` not an integer in ``[0, 2**31 - 1]``, a bad
            ``state0`` (wrong shape or dtype, NaN/inf, velocities whose squares
            overflow or underflow, an end outside a wall or on it and moving
            outwards, spin for a stick that cannot turn) or a batch of scenes
            (use ``jax.vmap``). Inside ``jit``/``vmap`` the value checks cannot
            run; the result is poisoned with NaN instead (see ``collide``)
            and ``result`` says ``INVALID_START``.
        RuntimeError: with ``jax_enable_x64`` turned off.
    """
    n = check_orbit_length(n)
    check_eagerly(scene, state0)
    concrete = is_concrete(state0) and all(is_concrete(x) for x in jax.tree_util.tree_leaves(scene))
    if concrete and jnp.ndim(state0) == 2 and jax.process_count() == 1:
        return orbit_sharded(scene, state0, n, driver=driver)
    chosen = choose_driver(scene, jax.devices()[0].platform, driver, record="states")
    return _orbit_jit(scene, jnp.asarray(state0, dtype=jnp.float64), n, chosen)


def orbit_sharded(
    scene,
    states0: Float[ArrayLike, "B S"],
    n: int,
    devices: DeviceChoice = None,
    *,
    driver: str | None = None,
) -> Orbit:
    """``jb.orbit`` for a batch, split over several devices.

    Args:
        scene: a scene with scalar parameters (e.g. ``StickInCircle``).
        states0: ``(B, S)`` initial states (``S = scene.state_size``); under
            ``jax.distributed`` every process passes the same full batch.
        n: collisions per orbit (a Python int, static).
        devices: see ``orbit_mesh`` (default: every device of every process).
        driver: ``"serial"``, ``"lockstep"``, ``"lanes"`` or ``None`` (the platform's
            default): see ``jb.orbit``.

    Returns:
        ``Orbit`` with fields ``(B, n)``, ``(B, n)``, ``(B, n, S)`` and ``(B,)``, as global
        arrays split over the devices along the orbit axis (in one process
        ``np.asarray`` gathers them; under ``jax.distributed`` each process
        reads the orbits it holds with ``host_rows``, or all of them with
        ``jax.experimental.multihost_utils.process_allgather``).

    The batch is padded to whole lanes of ``scene.batch_chunk`` orbits on every
    device, so each orbit is bitwise the same for any number of devices and
    any batch size, and the same as ``jb.orbit`` whenever
    ``B >= scene.batch_chunk`` (``jb.orbit`` runs a smaller batch as one
    narrower program, which on CPU can round differently in the last bit).
    """
    n = check_orbit_length(n)
    states0 = np.asarray(states0, dtype=np.float64)
    if states0.ndim != 2:
        raise ValueError(f"states0 must be a batch of shape (B, {scene.state_size}); got shape {states0.shape}")
    check_eagerly(scene, states0)
    batch = Batch(scene, states0, devices, driver, record="states")
    orbit = _orbit_of(*batch.run_chunk(_orbit_plan(n), batch.fresh_carry(), 0, n))
    return jax.tree.map(lambda a: a[: batch.batch], orbit) if batch.lanes != batch.batch else orbit
