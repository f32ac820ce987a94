"""The serial and lockstep drivers: one orbit's loop of whole collisions, run orbit after orbit or vmapped.

``orbit_chunk`` is the chunk of one orbit (``jaxbill._engine.chunks``): a loop
whose every turn is one whole collision (``jaxbill._engine.step.advance_components``,
the root search a loop of its own) and its bookkeeping. ``jb.orbit`` of one
orbit is one such chunk; ``"serial"`` maps it over a batch, one orbit after
another, each bitwise the orbit alone; ``"lockstep"`` vmaps it over lanes of
orbits, each collision waiting for the lane's slowest search.
"""

from __future__ import annotations

import functools
from typing import Any

import jax
import jax.numpy as jnp

from jaxbill._engine.chunks import (
    Bookkeeping,
    Carry,
    Plan,
    empty_records,
    record_section_point,
    record_state,
    settled,
)
from jaxbill._engine.step import advance_components, components, orbit_constants, stacked, vmapped_over_lanes


def orbit_chunk(plan: Plan, scene, state0: jax.Array, carry: Carry, start: Any, steps: Any):
    """Collisions ``start + 1 .. start + steps`` of one orbit from ``carry``: ``(carry, records)``.

    ``start`` and ``steps`` may be traced (one compilation serves every chunk
    of a run, the last, shorter one included); ``plan`` is static. With both
    Python ints (``jb.orbit``) the loops are scans, which reverse-mode
    differentiation goes through.
    """
    constants = orbit_constants(scene, state0)
    books = Bookkeeping(plan, scene, state0)

    def collide(running):
        collision = books.held(running, advance_components(scene, running.state, constants))
        return books.after(running, collision), collision.contact

    def skip(running, count):
        return jax.lax.fori_loop(0, count, lambda _, running: collide(running)[0], running)

    # The state travels as its components: a loop that carries them never packs a state into an array
    # and slices it again at every collision.
    running = books.running(carry, components(carry.state))
    records = empty_records(plan, scene, state0.shape[-1])
    if plan.record == "final":
        running = skip(running, steps)
    elif plan.record == "states":
        running, records = _record_states(plan, collide, skip, running, records, start, steps)
    else:
        where = plan.where
        assert where is not None  # a "section" plan has its filter

        def record_if_kept(i, loop):
            running, records = loop
            held = books.ended(running)
            running, contact = collide(running)
            state = stacked(running.state)
            kept = jnp.asarray(where(scene, state, contact), dtype=bool) & ~held
            return running, record_section_point(plan, scene, records, kept, start + i + 1, state, running.time)

        running, records = jax.lax.fori_loop(0, steps, record_if_kept, (running, records))
    return settled(plan, scene, state0, books.carry(carry, running, steps, stacked(running.state)), records)


def _record_states(plan: Plan, collide, skip, running, records, start, steps):
    """The loop of a ``"states"`` chunk: the collisions numbered ``every``, ``2 every``, ... recorded."""

    def record(row, running, records):
        running, contact = collide(running)
        # The rows of a chunk's recorded collisions are 0, 1, ...: always in bounds.
        return running, record_state(records, row, stacked(running.state), running.time, contact, in_bounds=True)

    every = plan.every
    if every == 1:
        return jax.lax.fori_loop(0, steps, lambda i, loop: record(i, *loop), (running, records))
    # The collisions recorded are numbered from the start of the whole run, so a
    # chunk may begin anywhere between two of them: skip to just before the next
    # one, then record one and skip every - 1.
    head = jnp.minimum(steps, every - 1 - start % every)
    running = skip(running, head)
    rest = steps - head
    groups = (rest + every - 1) // every

    def record_group(g, loop):
        running, records = record(g, *loop)
        return skip(running, jnp.minimum(every - 1, rest - g * every - 1)), records

    return jax.lax.fori_loop(0, groups, record_group, (running, records))


def serial_chunk(plan: Plan):
    """``orbit_chunk`` for a batch, one orbit after another (the ``"serial"`` driver)."""
    one = functools.partial(orbit_chunk, plan)

    def run_serial(scene, states0, carry, start, steps):
        return jax.lax.map(lambda orbit: one(scene, orbit[0], orbit[1], start, steps), (states0, carry))

    return run_serial


def lockstep_chunk(plan: Plan, width: int):
    """``orbit_chunk`` for a batch whose size is a multiple of ``width``: lanes of ``width`` orbits,
    vectorised, run one after another (the ``"lockstep"`` driver)."""
    lane = vmapped_over_lanes(functools.partial(orbit_chunk, plan), in_axes=(None, 0, 0, None, None))

    def run_lanes(scene, states0, carry, start, steps):
        def as_lanes(a):
            return a.reshape(a.shape[0] // width, width, *a.shape[1:])

        out = jax.lax.map(
            lambda lane_args: lane(scene, lane_args[0], lane_args[1], start, steps),
            (as_lanes(states0), jax.tree.map(as_lanes, carry)),
        )
        return jax.tree.map(lambda a: a.reshape(a.shape[0] * a.shape[1], *a.shape[2:]), out)

    return run_lanes
