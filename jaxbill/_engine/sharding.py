"""Batches of orbits spread over every JAX device: the cores of one machine, its GPUs, or
the devices of many processes started with ``jax.distributed``.

Orbits are independent, so a batch is split along its first axis over a one-axis
device mesh (axis ``"orbits"``) and every device runs its slice through the same
batched code (``shard_map``); no device ever talks to another. Work is cut into
*lanes* of ``scene.batch_chunk`` orbits, each a vectorised program of that fixed
width. The width matters for bitwise reproducibility. On CPU, XLA vectorises each
operation over the lanes and computes the last few lanes of a chunk (measured:
the last 4; every lane of a chunk narrower than 16) in the vector loop's
epilogue, which contracts multiply-adds into fused multiply-adds differently
from the loop's body (as the scalar program of one orbit does); chaos amplifies
that last-bit difference within tens of collisions. So every batch is padded to
whole lanes on every device: orbit ``i`` always runs at position
``i % batch_chunk`` of a program of the same width, and its result does not depend
on the batch size or on the number of devices or processes.
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import TypeAlias

import jax
import numpy as np
from jax.sharding import Mesh, NamedSharding, PartitionSpec

ORBIT_AXIS = "orbits"


# What ``devices`` arguments accept. jax exports ``Device`` as a plain assignment, which
# pyright does not take as a type: this alias is the one place that says so.
DeviceChoice: TypeAlias = Mesh | Sequence[jax.Device] | None  # pyright: ignore[reportInvalidTypeForm]


def orbit_mesh(devices: DeviceChoice = None) -> Mesh:
    """The one-axis mesh (axis ``"orbits"``) a batch of orbits is split over.

    Args:
        devices: ``None`` for every device JAX sees (``jax.devices()``: under
            ``jax.distributed`` the devices of every process), a sequence of
            devices, or a ``Mesh`` with an ``"orbits"`` axis (returned as is).
    """
    if isinstance(devices, Mesh):
        if devices.axis_names != (ORBIT_AXIS,):
            raise ValueError(f"devices: a Mesh must have the single axis {ORBIT_AXIS!r}; got {devices.axis_names}")
        return devices
    found = jax.devices() if devices is None else list(devices)
    if not found or not all(isinstance(d, jax.Device) for d in found):
        raise ValueError(f"devices must be None, a non-empty sequence of jax devices, or a Mesh; got {devices!r}")
    return Mesh(np.array(found), (ORBIT_AXIS,))


def padded_batch_size(batch: int, lane_width: int, mesh: Mesh) -> int:
    """The batch rounded up so that every device runs whole lanes of ``lane_width`` orbits."""
    unit = lane_width * mesh.size
    return -(-batch // unit) * unit


def pad_batch(array: np.ndarray, size: int) -> np.ndarray:
    """``array`` ``(B, ...)`` extended to ``(size, ...)`` with copies of its first row.

    The copies are valid starts, so padded lanes compute (and are thrown away)
    like any other orbit instead of poisoning or stalling a lane chunk.
    """
    missing = size - array.shape[0]
    return np.concatenate([array, np.broadcast_to(array[:1], (missing, *array.shape[1:]))]) if missing else array


def to_mesh(array, mesh: Mesh, batched: bool) -> jax.Array:
    """A host array as a global array on ``mesh``: split along axis 0, or replicated.

    Every process passes the same full ``array`` and keeps the pieces that live
    on its own devices (``jax.make_array_from_callback``), so this works the
    same in one process and under ``jax.distributed``.
    """
    array = np.asarray(array)
    sharding = NamedSharding(mesh, PartitionSpec(ORBIT_AXIS) if batched else PartitionSpec())
    return jax.make_array_from_callback(array.shape, sharding, lambda index: array[index])


def _shards_by_first_row(array: jax.Array) -> dict[int, jax.Shard]:
    """This process's shards of a global array, one per first row (replicas along no other axis)."""
    shards = {}
    for shard in array.addressable_shards:
        rows = shard.index[0] if shard.index else slice(None)
        shards.setdefault(0 if rows.start is None else rows.start, shard)
    return dict(sorted(shards.items()))


def held_rows(array: jax.Array) -> np.ndarray:
    """The indices of the rows (axis 0) of a global array that this process holds, in ``host_rows``'s
    order, without reading them back (every row in one process)."""
    if array.is_fully_addressable:
        return np.arange(array.shape[0])
    ranges = []
    for shard in _shards_by_first_row(array).values():
        rows = shard.index[0] if shard.index else slice(None)
        start, stop, _ = rows.indices(array.shape[0])
        ranges.append(np.arange(start, stop))
    return np.concatenate(ranges)


def host_rows(array: jax.Array) -> tuple[np.ndarray, np.ndarray]:
    """The rows (axis 0) of a global array that this process holds, and their indices.

    In one process that is the whole array. Under ``jax.distributed`` each
    process gets back only the orbits its own devices ran: no data crosses
    machines, and each process writes its own results.
    """
    if array.is_fully_addressable:
        values = np.asarray(array)
        return values, np.arange(values.shape[0])
    values = np.concatenate([np.asarray(shard.data) for shard in _shards_by_first_row(array).values()])
    return values, held_rows(array)


def shard_over_orbits(batched_function, mesh: Mesh, batched_args: tuple[bool, ...]):
    """``jit(shard_map(batched_function))``: each device runs its slice of the batch.

    ``batched_args[i]`` says whether argument ``i`` is split along its first
    axis (a pytree: all its leaves) or replicated; every output is split.
    """
    specs = tuple(PartitionSpec(ORBIT_AXIS) if b else PartitionSpec() for b in batched_args)
    # check_vma=False: the orbit code mixes per-device values with loop
    # counters that start replicated (e.g. the root search's step count), which
    # the varying-axes checker rejects; there are no collectives to check here.
    sharded = jax.shard_map(
        batched_function, mesh=mesh, in_specs=specs, out_specs=PartitionSpec(ORBIT_AXIS), check_vma=False
    )
    return jax.jit(sharded)
