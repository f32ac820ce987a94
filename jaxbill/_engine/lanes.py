"""The XLA driver of the lane state machine: a block of orbits in one loop, none waiting for another.

A batch runs in blocks of ``scene.batch_chunk`` lanes (one orbit each). Each
block is one ``while_loop`` whose every turn advances every lane by one root
step (``jaxbill._engine.step.lane_iteration``): a lane that has found its contact
applies the impulse and starts its next flight in the same turn, so a block
takes about as many turns as its busiest orbit has root steps *in all*, not
the sum over collisions of the slowest lane's steps (what a vmapped loop of
whole collisions costs).

The driver also keeps each orbit's running statistics and writes its records
(every ``k``-th state, or the points of a section) as the collisions happen.
``jb.orbit`` on a batch and ``jb.run`` both run it, so the two give bitwise the
same orbits.
"""

from __future__ import annotations

import dataclasses
from collections.abc import Callable
from typing import Any, NamedTuple

import jax
import jax.numpy as jnp
import numpy as np

from jaxbill._engine.sharding import orbit_mesh, shard_over_orbits
from jaxbill._engine.step import (
    MAX_ROOT_STEPS,
    begin_flight,
    components,
    end_and_begin,
    orbit_constants,
    search_step,
    stacked,
    vmapped_over_lanes,
    without_conditionals,
)

# Contact codes counted one by one in the running statistics: every scene's codes
# lie in -4..4 (StickInCircle: -1, 0, 1, 2; the wall scenes add -3, 3). Any other
# code (or one the scene does not list in ``contact_codes``) is counted in one
# extra bin, so no collision goes uncounted.
CONTACT_CODES = tuple(range(-4, 5))

# A block ends its lanes' flights once this share of its active lanes wait (see run_block).
FINISH_FRACTION = 4


class Carry(NamedTuple):
    """What one orbit carries from chunk to chunk (on the device)."""

    state: jax.Array  # (S,)
    time: jax.Array  # ()
    max_energy_error: jax.Array  # ()
    contact_counts: jax.Array  # (len(CONTACT_CODES) + 1,) int64


@dataclasses.dataclass(frozen=True)
class Plan:
    """The static shape of one compiled chunk (part of the compilation key).

    Attributes:
        record: ``"final"``, ``"states"`` or ``"section"``.
        every: ``"states"``: record the collisions whose number (from the start
            of the whole run, 1 = the first) is a multiple of this.
        rows: records per orbit per chunk on the device.
        where, project: ``"section"``: the filter and the projection (see
            ``jb.Section``).
    """

    record: str
    every: int = 1
    rows: int = 0
    where: Callable | None = None
    project: Callable | None = None


def tallied_codes(scene) -> tuple[int, ...]:
    """The contact codes a chunk counts one by one: those of ``CONTACT_CODES`` that ``scene``'s collisions
    can have (``scene.contact_codes``; all of them for a scene that does not say).

    Each code counted costs a comparison and an add per collision: counting
    all nine, the closed forms' batches spent a quarter of their time on it
    (the lens's ran 1.1x and the circle billiard's 1.2x faster counting their
    own four and two codes).
    """
    declared = getattr(scene, "contact_codes", CONTACT_CODES)
    return tuple(code for code in CONTACT_CODES if code in declared)


def empty_tally(codes: tuple[int, ...], shape: tuple[int, ...] = ()) -> tuple[jax.Array, ...]:
    """No collision yet of any of ``codes``: one int64 count of ``shape`` per code."""
    return tuple(jnp.zeros(shape, jnp.int64) for _ in codes)


def tally_contact(codes: tuple[int, ...], tally: tuple, contact: jax.Array, collided: Any = True) -> tuple:
    """``tally`` with one more collision of code ``contact`` where ``collided``.

    One count per code, each of the lanes' shape: under ``vmap`` every count
    is a contiguous row of lanes (a ``(lanes, codes)`` array made XLA:CPU
    broadcast each lane's contact across its row: the circle billiard's batch
    ran 1.1x slower so).
    """
    return tuple(count + (collided & (contact == code)).astype(jnp.int64) for count, code in zip(tally, codes))


def add_tally(
    contact_counts: jax.Array | np.ndarray, codes: tuple[int, ...], tally: tuple, collisions: Any
) -> jax.Array:
    """``contact_counts`` ``(..., len(CONTACT_CODES) + 1)`` plus a chunk's ``tally`` of ``codes``, and its
    ``collisions`` of any other code (``collisions`` less the tally) in the last bin."""
    bins = [contact_counts[..., k] for k in range(len(CONTACT_CODES) + 1)]
    return jnp.stack(add_tally_to_bins(bins, codes, tally, collisions), axis=-1)


def add_tally_to_bins(bins: list, codes: tuple[int, ...], tally: tuple, collisions: Any) -> list:
    """``add_tally`` on the counts as a list of bins (one array per bin: a Pallas kernel's rows)."""
    bins = list(bins)
    for code, count in zip(codes, tally):
        bins[CONTACT_CODES.index(code)] = bins[CONTACT_CODES.index(code)] + count
    bins[-1] = bins[-1] + (collisions - sum(tally, jnp.zeros((), jnp.int64)))
    return bins


def energy_drift(scene, state0):
    """``state -> |E - E0| / |E0|`` for the orbit from ``state0`` (``|E - E0|`` when ``E0 = 0``).

    ``state0``: a state ``(..., S)`` or its components (orbits of a block at
    once); ``E0`` and its unit are computed here, once per chunk.
    """
    energy0 = scene.energy(state0)
    unit = jnp.where(energy0 == 0, 1.0, jnp.abs(energy0))
    return lambda state: jnp.abs(scene.energy(state) - energy0) / unit


def _empty_records(plan: Plan, scene, states0: jax.Array):
    width, size = states0.shape
    if plan.record == "final":
        return ()
    if plan.record == "states":
        return (
            jnp.zeros((width, plan.rows), jnp.float64),
            jnp.zeros((width, plan.rows), jnp.int32),
            jnp.zeros((width, plan.rows, size), jnp.float64),
        )
    shape = jax.eval_shape(_projection(plan), scene, states0[0])
    # One row past the end takes what does not fit; the count goes on, so the
    # host sees the overflow and runs the chunk again with more room.
    return (
        jnp.zeros((width, plan.rows + 1, *shape.shape), shape.dtype),
        jnp.zeros((width, plan.rows + 1), jnp.float64),
        jnp.zeros((width, plan.rows + 1), jnp.int64),
        jnp.zeros((width,), jnp.int64),
    )


def _projection(plan: Plan):
    return plan.project or (lambda scene, state: state)


def _record(plan: Plan, scene, records, collided, number, start, carry: Carry, contact):
    """One lane's records after a turn in which it may have completed collision ``number``."""
    if plan.record == "final" or (plan.record == "states" and plan.rows == 0):
        return records
    if plan.record == "states":
        t, codes, states = records
        every = plan.every
        kept = collided & (number % every == 0)
        # Collision number c lands in row c // every - start // every - 1 of
        # this chunk; rows past the end are dropped (never written).
        row = jnp.where(kept, number // every - start // every - 1, plan.rows)
        return (
            t.at[row].set(carry.time, mode="drop"),
            codes.at[row].set(contact, mode="drop"),
            states.at[row].set(carry.state, mode="drop"),
        )
    point, t, numbers, fill = records
    if plan.where is None:
        raise ValueError(f"a {plan.record!r} plan records every collision, not a section")
    kept = collided & jnp.asarray(plan.where(scene, carry.state, contact), dtype=bool)
    row = jnp.where(kept, jnp.minimum(fill, plan.rows), plan.rows + 1)
    return (
        point.at[row].set(_projection(plan)(scene, carry.state), mode="drop"),
        t.at[row].set(carry.time, mode="drop"),
        numbers.at[row].set(number.astype(jnp.int64), mode="drop"),
        fill + kept.astype(jnp.int64),
    )


def run_block(plan: Plan, scene, states0: jax.Array, carry: Carry, start: Any, steps: Any):
    """Collisions ``start + 1 .. start + steps`` of a block of orbits ``(W, S)`` from ``carry``.

    ``states0`` are the orbits' first states (for their constants and energy);
    ``carry`` holds where each orbit is now. ``start`` and ``steps`` may be
    traced. Returns the new carry and the block's records (per lane; see
    ``Plan``). Invalid first states are the caller's to poison.

    Each turn of the loop takes one root step in every lane still searching.
    Ending a flight (the impulse, the next flight's bounds, the statistics and
    records) costs several root steps, so it is done for the whole block at
    once, in the turns where at least ``1 / FINISH_FRACTION`` of the active
    lanes wait for it (or all of them do): a lane idles a turn or two rather
    than every lane paying for it every turn.
    """
    with without_conditionals():
        return _run_block(plan, scene, states0, carry, start, steps)


def _run_block(plan: Plan, scene, states0: jax.Array, carry: Carry, start: Any, steps: Any):
    """``run_block``'s loop, traced without conditionals (``jaxbill._engine.step.without_conditionals``)."""
    width = states0.shape[0]
    constants = jax.vmap(lambda s: orbit_constants(scene, s))(states0)
    drift = energy_drift(scene, states0)
    end_and_begin_lanes = jax.vmap(lambda lane, active, c: end_and_begin(scene, lane, active, c))
    step_lanes = jax.vmap(lambda lane: search_step(scene, lane))
    record = jax.vmap(
        lambda r, collided, number, carry, contact: _record(plan, scene, r, collided, number, start, carry, contact)
    )

    codes = tallied_codes(scene)

    def finish(loop):
        lanes, carry, done, records, tally = loop
        lanes, (collided, new_parts, dt, contact) = end_and_begin_lanes(lanes, done < steps, constants)
        new_state = stacked(new_parts)
        hit = collided[:, None]
        after = Carry(
            state=jnp.where(hit, new_state, carry.state),
            time=jnp.where(collided, carry.time + dt, carry.time),
            # jnp.maximum propagates NaN: a poisoned orbit keeps reporting NaN.
            max_energy_error=jnp.where(
                collided, jnp.maximum(carry.max_energy_error, drift(new_state)), carry.max_energy_error
            ),
            contact_counts=carry.contact_counts,  # the chunk's collisions are tallied apart
        )
        done = done + collided.astype(jnp.int32)
        tally = tally_contact(codes, tally, contact, collided)
        return lanes, after, done, record(records, collided, start + done, after, contact), tally

    def not_finished(loop):
        return jnp.min(loop[2]) < steps

    def one_turn(loop):
        if not scene.searches_for_roots:
            return finish(loop)  # every flight ends at once: a collision a turn
        lanes, _, done, _, _ = loop
        active = done < steps
        waiting = jnp.sum(active & (lanes.found | (lanes.steps >= MAX_ROOT_STEPS)))
        total = jnp.sum(active)
        loop = jax.lax.cond((FINISH_FRACTION * waiting >= total) | (waiting == total), finish, lambda loop: loop, loop)
        lanes, carry, done, records, tally = loop
        return step_lanes(lanes), carry, done, records, tally

    lanes = jax.vmap(lambda s, c: begin_flight(scene, components(s), c))(carry.state, constants)
    done, tally = jnp.zeros(width, jnp.int32), empty_tally(codes, (width,))
    loop = (lanes, carry, done, _empty_records(plan, scene, states0), tally)
    _, carry, done, records, tally = jax.lax.while_loop(not_finished, one_turn, loop)
    return carry._replace(contact_counts=add_tally(carry.contact_counts, codes, tally, done)), records


def fresh_carry(scene, states0: jax.Array) -> Carry:
    """The carry at the start of a run: no time, no drift, no collisions."""
    lead = states0.shape[:-1]
    return Carry(
        state=states0,
        time=jnp.zeros(lead, jnp.float64),
        max_energy_error=jnp.zeros(lead, jnp.float64),
        contact_counts=jnp.zeros((*lead, len(CONTACT_CODES) + 1), jnp.int64),
    )


def run_blocks(plan: Plan, width: int | None) -> Callable[..., Any]:
    """``run_block`` for a batch whose size is a multiple of ``width``: blocks of ``width`` lanes, one after another.

    ``width = None``: the whole batch in one block, as on a GPU, which needs
    every orbit at once to fill its threads (on a CPU, blocks of
    ``scene.batch_chunk`` lanes keep a block's working set in cache).
    """

    def run(scene, states0, carry, start, steps):
        if width is None:
            return run_block(plan, scene, states0, carry, start, steps)

        def as_blocks(a):
            return a.reshape(a.shape[0] // width, width, *a.shape[1:])

        out = jax.lax.map(
            lambda block: run_block(plan, scene, block[0], block[1], start, steps),
            (as_blocks(states0), jax.tree.map(as_blocks, carry)),
        )
        return jax.tree.map(lambda a: a.reshape(a.shape[0] * a.shape[1], *a.shape[2:]), out)

    return run


DRIVERS = ("serial", "lockstep", "lanes", "pallas")


def choose_driver(scene, platform: str, driver: str | None = None, record: str = "final") -> str:
    """The batch driver: ``driver`` if given, else the one measured fastest for ``scene`` on ``platform``
    (``"cpu"``, ``"gpu"``, ...).

    ``"serial"``: the orbits one after another, each the loop of a single
    orbit (``jax.lax.map``, no ``vmap``): an orbit waits for no other and
    takes a branch where a batch would compute both sides, and each orbit is
    bitwise the single orbit's. ``"lockstep"``: a vmapped loop of whole
    collisions, in lanes of ``scene.batch_chunk`` orbits: each root step waits
    for the lane's slowest orbit, but the lane's arithmetic is vectorised. On
    a CPU the scene chooses between them through its ``batch_chunk``: 1 for
    serial (the walls: 1.4x lockstep; the ellipse, whose lockstep lanes were
    not bitwise its orbits alone), else lockstep in lanes of that many (a
    spinning stick in a circle: 16, 1.1-1.15x serial; the closed forms, the
    lens and the circle: 256, 2-3x serial;
    ``benchmarks/bench_drivers.py``). ``"lanes"``: the state machine of this
    module in an XLA loop, in which no orbit waits for another. ``"pallas"``:
    the same state machine inside one Pallas kernel, a block of orbits in
    registers (``jaxbill._engine.pallas``): the default on a GPU; it records final
    states and statistics only, so records of states or sections take
    ``"lanes"``. On a CPU ``"pallas"`` runs in Pallas's interpreter (slow: for
    tests). All give the same orbits to rounding, with the same contacts.
    """
    if driver is None:
        if platform != "cpu":
            driver = "pallas"
        else:
            driver = "serial" if scene.batch_chunk == 1 else "lockstep"
    elif driver not in DRIVERS:
        raise ValueError(f"driver must be one of {DRIVERS} or None (the platform's default); got {driver!r}")
    if driver == "pallas" and record != "final":
        return "lanes"
    return driver


def map_over_orbits(scene, function: Callable[..., Any], in_axes: tuple) -> Callable[..., Any]:
    """``function`` of one orbit, mapped over a batch (``in_axes``: 0 or ``None`` per argument) as the
    platform runs ``scene`` fastest: the analyses' counterpart of ``choose_driver``.

    On a CPU the batch is split over every device of this process (one per
    core), and each device runs its orbits in lanes of ``scene.batch_chunk``,
    vectorised (``step.vmapped_over_lanes``), one lane after another; a width
    of 1 runs them one after another, each its own loop (FTLE steps of a
    spinning stick in lanes of 16: 2.6x one 1024-wide ``vmap``; of the walls
    one by one: 1.4x lanes of 16). Elsewhere the whole batch is one ``vmap``.
    Arguments that are not mapped are closed over (static values may be among
    them).
    """
    if jax.default_backend() != "cpu":
        return vmapped_over_lanes(function, in_axes)
    width = scene.batch_chunk
    devices = jax.local_devices() if jax.process_count() == 1 else jax.local_devices()[:1]

    def in_lanes(*args):
        mapped = [a for a, axis in zip(args, in_axes, strict=True) if axis is not None]
        batch = mapped[0].shape[0]
        unit = width * len(devices)
        padded = -(-batch // unit) * unit
        # Padding lanes repeat the first orbit: a valid start, computed and dropped.
        mapped = [jnp.concatenate([a, jnp.broadcast_to(a[:1], (padded - batch, *a.shape[1:]))]) for a in mapped]

        def with_fixed(orbit_args):
            given = iter(orbit_args)
            return tuple(next(given) if axis is not None else a for a, axis in zip(args, in_axes, strict=True))

        def one_device(*device_args):
            lanes = device_args[0].shape[0] // width

            def lane(lane_args):
                if width == 1:
                    return function(*with_fixed(tuple(a[0] for a in lane_args)))
                return vmapped_over_lanes(function, in_axes)(*with_fixed(lane_args))

            out = jax.lax.map(lane, tuple(a.reshape(lanes, width, *a.shape[1:]) for a in device_args))
            if width == 1:
                return out
            return jax.tree.map(lambda a: a.reshape(lanes * width, *a.shape[2:]), out)

        if len(devices) > 1:
            one_device = shard_over_orbits(one_device, orbit_mesh(devices), tuple(True for _ in mapped))
        return jax.tree.map(lambda a: a[:batch], one_device(*mapped))

    return in_lanes


# Orbits per program of the Pallas kernel (``jaxbill._engine.pallas``). Measured
# by a prototype on an H100 (float64, the spinning stick): 32 lanes on one warp
# were fastest; 64 on 2 warps reached 0.97x that, 128 on 4 0.94x, 256 on 8 0.82x.
PALLAS_BLOCK = 32


def lane_width(scene, driver: str) -> int:
    """Orbits per vectorised program for ``driver``: 1 for ``"serial"``, the kernel's block for
    ``"pallas"``, else ``scene.batch_chunk``.

    A batch is padded to whole lanes on every device (``jaxbill._engine.sharding``).
    """
    if driver == "pallas":
        return PALLAS_BLOCK
    return 1 if driver == "serial" else scene.batch_chunk
