"""The batch drivers and a batch on the devices: what ``jb.orbit`` and ``jb.run`` call.

Four drivers run a batch, each by one chunk function of the same signature
(``jaxbill._engine.chunks``): ``"serial"`` and ``"lockstep"``
(``jaxbill._engine.serial``), ``"lanes"`` (``jaxbill._engine.lanes``) and
``"pallas"`` (``jaxbill._engine.pallas``). ``choose_driver`` picks one for a
scene and a platform; ``Batch`` splits a concrete batch over the devices,
padded to whole lanes, runs the chosen driver's chunks there and brings the
orbits back. ``jb.orbit`` of a batch is one ``Batch`` chunk that records every
state; ``jb.run`` streams them, so the two run the same compiled code.
"""

from __future__ import annotations

import functools
from collections.abc import Callable
from typing import Any

import jax
import jax.numpy as jnp
import numpy as np
from jax.sharding import Mesh, NamedSharding, PartitionSpec

from jaxbill._engine.chunks import Carry, Plan, host_fresh_carry
from jaxbill._engine.lanes import lanes_chunk
from jaxbill._engine.pallas import BLOCK as PALLAS_BLOCK
from jaxbill._engine.pallas import pallas_chunk
from jaxbill._engine.serial import lockstep_chunk, orbit_chunk, serial_chunk
from jaxbill._engine.sharding import (
    ORBIT_AXIS,
    held_rows,
    host_rows,
    orbit_mesh,
    pad_batch,
    padded_batch_size,
    shard_over_orbits,
    to_mesh,
)
from jaxbill._engine.step import vmapped_over_lanes

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
    serial (the walls; the ellipse, whose lockstep lanes were not bitwise its
    orbits alone), else lockstep in lanes of that many (a spinning stick in a
    circle: 16; the closed forms, the lens and the circle: 256;
    ``benchmarks/bench_drivers.py`` measures them). ``"lanes"``: the lane
    state machine (``jaxbill._engine.lanes``) in an XLA loop, in which no
    orbit waits for another. ``"pallas"``: the same state machine inside one
    Pallas kernel, a block of orbits in registers (``jaxbill._engine.pallas``):
    the default on a GPU; it records final states and statistics only, so
    records of states or sections take ``"lanes"``. On a CPU ``"pallas"``
    runs in Pallas's interpreter (slow: for tests). All give the same orbits
    to rounding, with the same contacts and result codes.
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


def lane_width(scene, driver: str) -> int:
    """Orbits per vectorised program for ``driver``: 1 for ``"serial"``, the kernel's block for
    ``"pallas"``, else ``scene.batch_chunk``.

    A batch is padded to whole lanes on every device (``jaxbill._engine.sharding``).
    """
    if driver == "pallas":
        return PALLAS_BLOCK
    return 1 if driver == "serial" else scene.batch_chunk


def chunk_function(plan: Plan, driver: str, width: int, interpret: bool) -> Callable[..., Any]:
    """``driver``'s chunk of a batch on one device, ``(scene, states0, carry, start, steps) -> (carry, records)``,
    for a batch of whole lanes of ``width`` orbits. ``interpret``: on a CPU (the Pallas kernel in Pallas's
    interpreter; the lane state machine in blocks of ``width`` lanes, where a GPU takes the whole batch)."""
    if driver == "serial":
        return serial_chunk(plan)
    if driver == "lockstep":
        return lockstep_chunk(plan, width)
    if driver == "lanes":
        return lanes_chunk(plan, width if interpret else None)
    if driver == "pallas":
        return pallas_chunk(plan, interpret)
    raise ValueError(f"driver must be one of {DRIVERS}; got {driver!r}")


@functools.lru_cache(maxsize=64)
def compiled_chunk(plan: Plan, width: int | None, mesh: Mesh | None, driver: str | None):
    """The compiled chunk of one orbit (``width = None``) or of a batch split over ``mesh``."""
    if width is None:
        return jax.jit(functools.partial(orbit_chunk, plan))
    assert mesh is not None and driver is not None  # a batch runs on a mesh, by a chosen driver
    batched = chunk_function(plan, driver, width, interpret=mesh.devices.flat[0].platform == "cpu")
    return shard_over_orbits(batched, mesh, (False, True, True, False, False))


class Batch:
    """One orbit, or a batch split over the devices, whose chunks run by one driver.

    A batch is padded to whole lanes of the driver's width on every device
    (``jaxbill._engine.sharding``), so an orbit's result depends neither on
    the batch around it nor on the number of devices; padding lanes are
    computed and never reported. ``record``: what the chunks record (a
    ``"pallas"`` driver records final states only; other records run
    ``"lanes"``, padded alike).
    """

    def __init__(self, scene, state0: np.ndarray, devices, driver: str | None = None, record: str = "final"):
        self.scene, self.state0 = scene, state0
        self.batched = state0.ndim == 2
        if not self.batched:
            self.width = self.mesh = None
            self.orbit_index = None
            self.lanes = 1
            return
        self.mesh = mesh = orbit_mesh(devices)
        self.platform = mesh.devices.flat[0].platform
        # an unknown driver fails here, before anything runs
        self.width = lane_width(scene, choose_driver(scene, self.platform, driver, record))
        self.driver = driver
        self.batch = state0.shape[0]
        self.lanes = padded_batch_size(self.batch, self.width, self.mesh)
        self.padded_state0 = pad_batch(state0, self.lanes)
        self.device_scene = jax.tree.map(lambda leaf: to_mesh(leaf, mesh, batched=False), scene)
        self.device_state0 = to_mesh(self.padded_state0, mesh, batched=True)
        index = held_rows(self.device_state0)
        self.local_rows = index < self.batch  # padding lanes are computed, never reported
        self.orbit_index = index[self.local_rows]
        self.padding_last = not np.any(self.local_rows[self.orbit_index.size :])

    def fresh_carry(self) -> Carry:
        """The carry of a run's start, on the devices."""
        if not self.batched:
            return Carry(*(jnp.asarray(a) for a in host_fresh_carry(self.state0)))
        assert self.mesh is not None  # set up for a batch
        # The start is already on the devices, and zeros are made there: sending
        # them from the host was a measurable part of every call (``benchmarks/HISTORY.md``).
        return Carry(self.device_state0, *_zero_statistics(self.lanes, self.mesh)())

    def carry_of(self, held: Carry) -> Carry:
        """The carry on the devices from ``held``, numpy fields of the orbits this process holds (in
        ``orbit_index`` order, as ``to_host`` returns them: e.g. a checkpoint's)."""
        if not self.batched:
            return Carry(*(jnp.asarray(a) for a in held))
        assert self.mesh is not None and self.orbit_index is not None  # set up for a batch
        # Every process builds the full padded batch but fills in only its
        # own orbits: to_mesh reads only the rows of this process's devices.
        fields = []
        for fresh_field, saved in zip(host_fresh_carry(self.padded_state0), held):
            field = np.array(fresh_field)
            field[self.orbit_index] = saved
            fields.append(field)
        return Carry(*(to_mesh(field, self.mesh, batched=True) for field in fields))

    def run_chunk(self, plan: Plan, carry: Carry, start: int, steps: int):
        """Collisions ``start + 1 .. start + steps`` from ``carry``: ``(carry, records)`` on the devices."""
        driver = choose_driver(self.scene, self.platform, self.driver, plan.record) if self.batched else None
        function = compiled_chunk(plan, self.width, self.mesh, driver)
        if self.batched:
            return function(self.device_scene, self.device_state0, carry, start, steps)
        return function(self.scene, jnp.asarray(self.state0), carry, start, steps)

    def to_host(self, array: jax.Array | np.ndarray) -> np.ndarray:
        """This process's orbits of a per-orbit device array, padding lanes dropped."""
        if not self.batched:
            return np.asarray(array)
        assert isinstance(array, jax.Array)  # a batch's results live on the mesh
        values = host_rows(array)[0]
        assert self.orbit_index is not None  # set up for a batch
        # The padding lanes come last: a slice (a view, no copy) drops them.
        return values[: self.orbit_index.size] if self.padding_last else values[self.local_rows]


@functools.lru_cache(maxsize=16)
def _zero_statistics(lanes: int, mesh: Mesh):
    """A compiled function of no argument: the fresh carry's zero fields after the state, for ``lanes``
    orbits split over ``mesh``."""
    return jax.jit(
        lambda: tuple(jnp.zeros(np.shape(a), a.dtype) for a in host_fresh_carry(np.zeros((lanes, 1)))[1:]),
        out_shardings=NamedSharding(mesh, PartitionSpec(ORBIT_AXIS)),
    )


def map_over_orbits(scene, function: Callable[..., Any], in_axes: tuple) -> Callable[..., Any]:
    """``function`` of one orbit, mapped over a batch (``in_axes``: 0 or ``None`` per argument) as the
    platform runs ``scene`` fastest: the analyses' counterpart of ``choose_driver``.

    On a CPU the batch is split over every device of this process (one per
    core), and each device runs its orbits in lanes of ``scene.batch_chunk``,
    vectorised (``step.vmapped_over_lanes``), one lane after another; a width
    of 1 runs them one after another, each its own loop (FTLE steps of a
    spinning stick ran faster in lanes of 16 than in one 1024-wide ``vmap``,
    those of the walls faster one by one than in lanes of 16: the widths that
    ``benchmarks/bench_drivers.py`` measures best for plain collisions). Elsewhere
    the whole batch is one ``vmap``.
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
