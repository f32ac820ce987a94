"""The XLA driver of the lane state machine: a block of orbits in one loop, none waiting for another.

A batch runs in blocks of ``scene.batch_chunk`` lanes (one orbit each). Each
block is one ``while_loop`` whose every turn advances every lane by one root
step (``jaxbill._engine.step.search_step``): a lane that has found its contact
applies the impulse and starts its next flight in the same turn, so a block
takes about as many turns as its busiest orbit has root steps *in all*, not
the sum over collisions of the slowest lane's steps (what a vmapped loop of
whole collisions costs).

A lane that completes a collision goes through the bookkeeping every driver
shares (``jaxbill._engine.chunks``): its running statistics and result code,
and its records (every ``k``-th state, or the points of a section), written as
the collisions happen.
"""

from __future__ import annotations

from collections.abc import Callable
from typing import Any

import jax
import jax.numpy as jnp

from jaxbill._engine.chunks import (
    CONTACT_CODES,
    Bookkeeping,
    Carry,
    Plan,
    empty_records,
    fresh_carry,
    record_collision,
    settled,
)
from jaxbill._engine.step import (
    MAX_ROOT_STEPS,
    begin_flight,
    components,
    end_and_begin,
    orbit_constants,
    search_step,
    stacked,
    without_conditionals,
)

# What a block's loop works with, named here for the tests and benchmarks that drive it.
__all__ = ["CONTACT_CODES", "Carry", "Plan", "fresh_carry", "MAX_ROOT_STEPS", "run_block", "run_blocks", "lanes_chunk"]

# A block ends its lanes' flights once this share of its active lanes wait (see run_block).
FINISH_FRACTION = 4


def run_block(plan: Plan, scene, states0: jax.Array, carry: Carry, start: Any, steps: Any):
    """Collisions ``start + 1 .. start + steps`` of a block of orbits ``(W, S)`` from ``carry``.

    ``states0`` are the orbits' first states (for their constants and energy);
    ``carry`` holds where each orbit is now. ``start`` and ``steps`` may be
    traced. Returns the new carry and the block's records (per lane; see
    ``Plan``), not yet ``settled``.

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
    books = Bookkeeping(plan, scene, states0)
    end_and_begin_lanes = jax.vmap(lambda lane, active, c: end_and_begin(scene, lane, active, c))
    step_lanes = jax.vmap(lambda lane: search_step(scene, lane))
    record = jax.vmap(
        lambda records, collided, held, number, state, time, contact: record_collision(
            plan, scene, records, collided, number, start, state, time, contact, held
        )
    )

    def finish(loop):
        lanes, running, done, records = loop
        lanes, collided, collision = end_and_begin_lanes(lanes, done < steps, constants)
        collision = books.held(running, collision._replace(state=stacked(collision.state)))
        held = books.ended(running)
        running = books.after(running, collision, collided)
        done = done + collided.astype(jnp.int32)
        records = record(records, collided, held, start + done, running.state, running.time, collision.contact)
        return lanes, running, done, records

    def not_finished(loop):
        return jnp.min(loop[2]) < steps

    def one_turn(loop):
        if not scene.searches_for_roots:
            return finish(loop)  # every flight ends at once: a collision a turn
        lanes, _, done, _ = loop
        active = done < steps
        waiting = jnp.sum(active & (lanes.found | (lanes.steps >= MAX_ROOT_STEPS)))
        total = jnp.sum(active)
        loop = jax.lax.cond((FINISH_FRACTION * waiting >= total) | (waiting == total), finish, lambda loop: loop, loop)
        lanes, running, done, records = loop
        return step_lanes(lanes), running, done, records

    lanes = jax.vmap(lambda s, c: begin_flight(scene, components(s), c))(carry.state, constants)
    running = books.running(carry, carry.state, (width,))
    loop = (lanes, running, jnp.zeros(width, jnp.int32), empty_records(plan, scene, states0.shape[-1], (width,)))
    _, running, done, records = jax.lax.while_loop(not_finished, one_turn, loop)
    return books.carry(carry, running, done, running.state), records


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


def lanes_chunk(plan: Plan, width: int | None):
    """The ``"lanes"`` driver's chunk of a batch (``jaxbill._engine.chunks``): ``run_blocks``, settled."""
    blocks = run_blocks(plan, width)

    def run_lanes(scene, states0, carry, start, steps):
        new_carry, records = blocks(scene, states0, carry, start, steps)
        return settled(plan, scene, states0, new_carry, records)

    return run_lanes
