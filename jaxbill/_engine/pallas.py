"""The Pallas driver of the lane state machine: a block of orbits held in registers, one kernel.

The XLA driver (``jaxbill._engine.lanes``) runs a turn of the state machine as a few
kernels, each reading and writing every lane's values in memory; on a GPU that
traffic, not the arithmetic, sets the pace. Here one Pallas (Triton) kernel
runs the whole loop: each program holds ``block`` lanes in registers from the
first collision of a chunk to the last, and takes exactly the moves of the
other drivers (``jaxbill._engine.step.end_and_begin`` and ``search_step``, built from
the scene's own functions) and the same bookkeeping of each collision
(``jaxbill._engine.chunks.Bookkeeping``), so a scene gets the kernel without a
line of GPU code.

What the Triton backend lowers shapes this module: arrays of power-of-two
sizes only, no slicing of a value, no gather, no constants captured by the
kernel. So the state is laid out component-major (``(S, B)``, each component a
row, padded to a power of two), a lane's state is the tuple of its rows (the
engine's *components*), the scene's parameters come in as inputs, and every
per-lane value is a ``(block,)`` vector.

It records the final state, the run statistics and the result codes
(``record="final"``); records of states or sections go through the XLA driver. Derivatives are never
taken through it: they go through ``jaxbill._engine.step.advance``.

Without a GPU it runs in interpret mode (``interpret=True``) on the CPU, which
the tests use, and it lowers for CUDA (``lowering_platforms=("cuda",)``).
"""

from __future__ import annotations

import functools
from typing import Any

import jax
import jax.numpy as jnp

from jaxbill._engine.chunks import (
    CONTACT_CODES,
    Bookkeeping,
    Carry,
    Plan,
    add_tally_to_bins,
    fresh_carry,
    settled,
)
from jaxbill._engine.step import (
    begin_flight,
    end_and_begin,
    end_flight_tangent,
    search_step,
    where,
    without_conditionals,
)

# Orbits per kernel program: one orbit per thread, 32 lanes on one warp, is fastest in
# float64; larger blocks on more warps are no faster, several orbits per thread slower
# (``benchmarks/bench_gpu.py --variants``; the performance page, "On a GPU"). A batch is
# padded to whole blocks (``jaxbill._engine.drivers.lane_width``).
BLOCK = 32
NUM_WARPS = 1
# ``rarely``'s rare side (a corner) computed only in blocks where some lane needs it.
RARE_BY_BLOCK = True


def _padded(size: int) -> int:
    """The smallest power of two >= ``size`` (Triton's arrays have power-of-two sizes)."""
    return 1 << max(0, (size - 1).bit_length())


def _broadcast(tree, block: int):
    # A while loop's carry must keep its shapes: every lane value becomes a block.
    return jax.tree.map(lambda a: jnp.broadcast_to(a, (block,)), tree)


def _kernel(treedef, leaf_count: int, size: int, block: int, dynamical: tuple | None, *refs):
    """One program: ``block`` lanes from their carry to ``steps`` more collisions.

    ``dynamical``: ``None``, or the state coordinates a tangent vector lives in
    (the scene's ``dynamical_indices``): then each lane also carries a unit
    tangent vector, its log-stretch and its running maximum (the FLI).
    """
    leaves = [ref[0] for ref in refs[:leaf_count]]
    inputs = _CARRY_INPUTS + (3 if dynamical else 0)
    steps_ref, states0_ref, state_ref, time_ref, error_ref, counts_ref, result_ref = refs[
        leaf_count : leaf_count + _CARRY_INPUTS
    ]
    state_out, time_out, error_out, counts_out, result_out = refs[leaf_count + inputs : leaf_count + inputs + 5]
    scene = jax.tree.unflatten(treedef, leaves)
    steps = steps_ref[0]
    state0 = tuple(states0_ref[i, :] for i in range(size))
    constants = scene.orbit_constants(state0)
    books = Bookkeeping(Plan("final"), scene, state0)

    def not_finished(loop):
        return jnp.min(loop[2]) < steps

    def one_turn(loop):
        lane, running, done, tangent = loop
        if dynamical:
            # The tangent of this flight's collision, taken before the lane moves on.
            pushed = end_flight_tangent(scene, lane, constants, tangent[0])
            pushed = tuple(p if i in dynamical else jnp.zeros_like(p) for i, p in enumerate(pushed))
        lane, collided, collision = end_and_begin(scene, lane, done < steps, constants)
        lane = _broadcast(lane, block)
        running = books.after(running, books.held(running, collision), collided)
        done = done + collided.astype(jnp.int32)
        if dynamical:
            vector, log_norm, fli = tangent
            norm = jnp.sqrt(functools.reduce(jnp.add, [p * p for p in pushed]))
            vector = where(collided, tuple(p / norm for p in pushed), vector)
            log_norm = jnp.where(collided, log_norm + jnp.log(norm), log_norm)
            tangent = (_broadcast(vector, block), log_norm, jnp.where(collided, jnp.maximum(fli, log_norm), fli))
        return _broadcast(search_step(scene, lane), block), running, done, tangent

    state = tuple(state_ref[i, :] for i in range(size))
    lane = _broadcast(begin_flight(scene, state, constants), block)
    carry = Carry(state, time_ref[...], error_ref[...], None, result_ref[...])
    tangent: tuple = ()
    if dynamical:
        vector_ref, log_norm_ref, fli_ref = refs[leaf_count + _CARRY_INPUTS : leaf_count + inputs]
        tangent = (tuple(vector_ref[i, :] for i in range(size)), log_norm_ref[...], fli_ref[...])
    loop = (lane, books.running(carry, state, (block,)), jnp.zeros((block,), jnp.int32), tangent)
    _, running, done, tangent = jax.lax.while_loop(not_finished, one_turn, loop)
    for i in range(size):
        state_out[i, :] = running.state[i]
    time_out[...] = running.time
    error_out[...] = running.max_energy_error
    result_out[...] = books.result(running)
    so_far = [counts_ref[k, :] for k in range(len(CONTACT_CODES) + 1)]
    for k, row in enumerate(add_tally_to_bins(so_far, books.codes, running.tally, done.astype(jnp.int64))):
        counts_out[k, :] = row
    if dynamical:
        vector_out, log_norm_out, fli_out = refs[leaf_count + inputs + 5 :]
        for i in range(size):
            vector_out[i, :] = tangent[0][i]
        log_norm_out[...] = tangent[1]
        fli_out[...] = tangent[2]


# The kernel's inputs besides the scene's leaves and a tangent: steps, states0 and the carry's five fields.
_CARRY_INPUTS = 7


def _call(
    scene,
    states0,
    carry: Carry,
    steps,
    tangent,
    block: int,
    interpret: bool,
    num_warps: int = NUM_WARPS,
    rare_by_block: bool = RARE_BY_BLOCK,
) -> Any:
    """The kernel over the batch; ``tangent = (vectors (B, S), log_norm (B,), fli (B,))`` or ``None``."""
    from jax.experimental import pallas as pl

    batch, size = states0.shape
    if batch % block:
        raise ValueError(f"the batch ({batch}) must be a whole number of blocks of {block} orbits")
    leaves, treedef = jax.tree.flatten(scene)
    rows, count_rows = _padded(size), _padded(len(CONTACT_CODES) + 1)

    def component_major(a, height):
        return jnp.zeros((height, batch), a.dtype).at[: a.shape[1]].set(a.T)

    lane_rows = pl.BlockSpec((rows, block), lambda i: (0, i))
    count_spec = pl.BlockSpec((count_rows, block), lambda i: (0, i))
    lane_values = pl.BlockSpec((block,), lambda i: (i,))
    one = pl.BlockSpec((1,), lambda i: (0,))
    state_rows = jax.ShapeDtypeStruct((rows, batch), jnp.float64)
    per_lane = jax.ShapeDtypeStruct((batch,), jnp.float64)
    in_specs = [one] * (len(leaves) + 1) + [lane_rows, lane_rows, lane_values, lane_values, count_spec, lane_values]
    out_specs = [lane_rows, lane_values, lane_values, count_spec, lane_values]
    out_shape = [
        state_rows,
        per_lane,
        per_lane,
        jax.ShapeDtypeStruct((count_rows, batch), jnp.int64),
        jax.ShapeDtypeStruct((batch,), jnp.int32),
    ]
    arguments = [
        *(jnp.reshape(jnp.asarray(leaf, jnp.float64), (1,)) for leaf in leaves),
        jnp.reshape(jnp.asarray(steps, jnp.int32), (1,)),
        component_major(states0, rows),
        component_major(carry.state, rows),
        carry.time,
        carry.max_energy_error,
        component_major(carry.contact_counts, count_rows),
        carry.result,
    ]
    dynamical = None
    if tangent is not None:
        dynamical = tuple(scene.dynamical_indices)
        in_specs += [lane_rows, lane_values, lane_values]
        out_specs += [lane_rows, lane_values, lane_values]
        out_shape += [state_rows, per_lane, per_lane]
        vectors, log_norm, fli = tangent
        arguments += [component_major(vectors, rows), log_norm, fli]
    compiler_params = None
    if not interpret:
        from jax.experimental.pallas import triton as pl_triton

        compiler_params = pl_triton.CompilerParams(num_warps=num_warps)
    kernel = pl.pallas_call(
        functools.partial(_kernel, treedef, len(leaves), size, block, dynamical),
        grid=(batch // block,),
        in_specs=in_specs,
        out_specs=tuple(out_specs),
        out_shape=tuple(out_shape),
        interpret=interpret,
        compiler_params=compiler_params,
    )
    with without_conditionals(rare_by_block=rare_by_block):
        out = kernel(*arguments)
    carry = Carry(out[0][:size].T, out[1], out[2], out[3][: len(CONTACT_CODES) + 1].T, out[4])
    if tangent is None:
        return carry
    return carry, (out[5][:size].T, out[6], out[7])


def pallas_final(
    scene,
    states0: jax.Array,
    carry: Carry,
    steps,
    *,
    block: int = BLOCK,
    interpret: bool = False,
    num_warps: int = NUM_WARPS,
    rare_by_block: bool = RARE_BY_BLOCK,
):
    """``steps`` more collisions of every orbit, final states and statistics only, in one Pallas kernel.

    Args:
        scene: any scene (its engine functions on components, ``jaxbill._engine.step``).
        states0: ``(B, S)`` the orbits' first states (for their constants and
            energy); ``B`` a multiple of ``block``.
        carry: where each orbit is now (``jaxbill._engine.lanes.Carry``, leading axis ``B``).
        steps: collisions to add (may be traced).
        block: orbits per kernel program (a power of two).
        interpret: run the kernel in Pallas's interpreter (any backend, e.g. the CPU).
        num_warps, rare_by_block: the kernel's tuning (Triton warps per program;
            the rare side of ``rarely`` by block); results do not depend on them.

    Returns:
        The new ``Carry``. Equal, lane by lane, to ``jaxbill._engine.lanes.run_block``
        with ``record="final"``: the same collisions in the same root steps.
    """
    return _call(scene, states0, carry, steps, None, block, interpret, num_warps, rare_by_block)


def pallas_fli(scene, states0: jax.Array, tangents0: jax.Array, n, *, block: int = BLOCK, interpret: bool = False):
    """Fast Lyapunov indicators of ``n`` collisions per orbit, the tangent vector carried inside the kernel.

    Args:
        scene: a scene whose dynamical directions are state coordinates
            (``scene.dynamical_indices``: every scene but ``StickBetweenWalls3D``).
        states0: ``(B, S)`` valid starts; ``B`` a multiple of ``block``.
        tangents0: ``(B, S)`` unit starting vectors in state coordinates, zero
            outside the dynamical coordinates (``jb.fli``'s starting vectors).
        n: collisions (may be traced).

    Returns:
        ``(fli, log_norm, final_state)``: ``(B,)`` the running maximum of
        ``log |w|`` over the collisions (``jb.fli``'s ``value`` with
        ``per="collision"``), ``(B,)`` ``log |w|`` after the last one, and
        ``(B, S)`` the final states. The tangent is the collision map's
        (``jb.tangent_map``), pushed by ``jaxbill._engine.step.end_flight_tangent``
        and renormalised after every collision.
    """
    if not hasattr(scene, "dynamical_indices"):
        raise ValueError(
            f"{type(scene).__name__}: its dynamical directions are not state coordinates; "
            "use jb.fli, which works in its dynamical frame"
        )
    zeros = jnp.zeros((states0.shape[0],), jnp.float64)
    carry, (_, log_norm, fli) = _call(
        scene, states0, fresh_carry(scene, states0), n, (tangents0, zeros, zeros), block, interpret
    )
    return fli, log_norm, carry.state


def pallas_chunk(plan: Plan, interpret: bool):
    """The ``"pallas"`` driver's chunk of a batch (``jaxbill._engine.chunks``): final states and statistics
    (``plan.record == "final"``), settled. ``interpret``: the kernel in Pallas's interpreter (a CPU)."""
    if plan.record != "final":
        raise ValueError(f"the Pallas kernel records final states only, not {plan.record!r}")

    def run_kernel(scene, states0, carry, start, steps):
        return settled(plan, scene, states0, pallas_final(scene, states0, carry, steps, interpret=interpret), ())

    return run_kernel
