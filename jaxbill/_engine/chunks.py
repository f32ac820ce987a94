"""What every driver shares: the plan of a chunk of collisions, the carry between chunks, and the
bookkeeping of each collision.

An orbit advances in *chunks*: each is one compiled call that takes the carry
(where each orbit is, and its running statistics) and returns the next carry
and the chunk's records. ``jb.orbit`` is one chunk that records every state;
``jb.run`` streams chunks to the host or to disk. Each driver supplies one
chunk function, of one signature::

    chunk(plan, scene, states0, carry, start, steps) -> (carry, records)

(collisions ``start + 1 .. start + steps``; ``start`` and ``steps`` may be
traced): the serial and lockstep drivers (``jaxbill._engine.serial``), the
lane state machine in XLA (``jaxbill._engine.lanes``) and in a Pallas kernel
(``jaxbill._engine.pallas``). What a collision does to the carry
(``Bookkeeping``), how a record is written (``record_state``,
``record_section_point``) and how a chunk's output is settled (``settled``:
invalid starts, contacts of unproven collisions) are defined here once, so
every driver gives the same orbits from the same per-collision code.
"""

from __future__ import annotations

import dataclasses
from collections.abc import Callable
from typing import Any, NamedTuple

import jax
import jax.numpy as jnp
import numpy as np

from jaxbill._engine.results import Result, collision_status, first_failure, has_stopped, start_result
from jaxbill._engine.step import NO_CONTACT, Collision, stops_orbits

# Contact codes counted one by one in the running statistics: every scene's codes
# lie in -4..4 (StickInCircle: -1, 0, 1, 2; the wall scenes add -3, 3). Any other
# code (or one the scene does not list in ``contact_codes``) is counted in one
# extra bin, so no collision goes uncounted.
CONTACT_CODES = tuple(range(-4, 5))


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
        statistics: keep the energy error and the contact tally (``jb.orbit``,
            which returns neither, does not).
    """

    record: str
    every: int = 1
    rows: int = 0
    where: Callable | None = None
    project: Callable | None = None
    statistics: bool = True


class Carry(NamedTuple):
    """What each orbit carries from chunk to chunk (on the device; a leading axis for a batch)."""

    state: Any  # (S,)
    time: Any  # ()
    max_energy_error: Any  # ()
    contact_counts: Any  # (len(CONTACT_CODES) + 1,) int64
    result: Any  # () int32: a jaxbill._engine.results.Result


def fresh_carry(scene, states0: jax.Array) -> Carry:
    """The carry at the start of a run: no time, no drift, no collisions, nothing wrong yet."""
    lead = states0.shape[:-1]
    return Carry(
        state=states0,
        time=jnp.zeros(lead, jnp.float64),
        max_energy_error=jnp.zeros(lead, jnp.float64),
        contact_counts=jnp.zeros((*lead, len(CONTACT_CODES) + 1), jnp.int64),
        result=jnp.zeros(lead, jnp.int32),
    )


def host_fresh_carry(states0: np.ndarray) -> Carry:
    """``fresh_carry`` as numpy arrays, built on the host."""
    lead = states0.shape[:-1]
    return Carry(
        state=states0,
        time=np.zeros(lead),
        max_energy_error=np.zeros(lead),
        contact_counts=np.zeros((*lead, len(CONTACT_CODES) + 1), np.int64),
        result=np.zeros(lead, np.int32),
    )


# -- the running statistics ------------------------------------------------------------


def tallied_codes(scene) -> tuple[int, ...]:
    """The contact codes a chunk counts one by one: those of ``CONTACT_CODES`` that ``scene``'s collisions
    can have (``scene.contact_codes``; all of them for a scene that does not say).

    Each code counted costs a comparison and an add per collision: counting
    all nine, the closed forms' batches spent a quarter of their time on it.
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
    broadcast each lane's contact across its row).
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


class Running(NamedTuple):
    """What each orbit carries from collision to collision inside a chunk: the carry, with the chunk's
    contacts in a tally (``tally_contact``) and the state as the driver keeps it (an array or its
    components)."""

    state: Any
    time: Any
    max_energy_error: Any
    tally: tuple
    result: Any


def _where(condition, if_true, if_false):
    """``jnp.where`` leaf by leaf, ``condition`` (one value per orbit) broadcast over each leaf's trailing axes."""

    def choose(a, b):
        extra = jnp.ndim(a) - jnp.ndim(condition)
        return jnp.where(jnp.reshape(condition, jnp.shape(condition) + (1,) * extra), a, b)

    return jax.tree.map(choose, if_true, if_false)


class Bookkeeping:
    """The per-collision bookkeeping of a chunk of the orbits from ``states0``: time, energy error, contact
    tally and result code, the same in every driver.

    ``states0``: one orbit's first state, a block's ``(W, S)``, or its
    components (a Pallas kernel's rows); every method is elementwise over the
    orbits.
    """

    def __init__(self, plan: Plan, scene, states0):
        self.codes = tallied_codes(scene) if plan.statistics else ()
        self.drift_of = energy_drift(scene, states0) if plan.statistics else None
        self.statistics = plan.statistics
        # A closed-form contact time fails only as NaN (non-finite) or inf (no wall), and an orbit's time
        # keeps either from then on (a NaN absorbs every later flight, a flight with no wall repeats): its
        # result is read from its time once per chunk. A searched one may also run out of steps or be
        # refused, which only the collision knows.
        # An orbit that can end for good (a hole, a stopping condition) reads its result collision by collision
        # too, and is held from then on (``held``).
        self.stops = stops_orbits(scene)
        self.status_per_collision = scene.searches_for_roots or self.stops

    def running(self, carry: Carry, state: Any, shape: tuple[int, ...] = ()) -> Running:
        """The running values at the start of a chunk from ``carry``, the state as the driver keeps it
        (``shape``: the orbits' shape, for the tally)."""
        return Running(state, carry.time, carry.max_energy_error, empty_tally(self.codes, shape), carry.result)

    def held(self, running: Running, collision: Collision) -> Collision:
        """``collision``, or for an orbit that has ended for good (``Result.ESCAPED``, ``Result.STOPPED``) none:
        its state as it was, ``dt = 0``, contact ``0``.

        Every driver passes each collision through here before ``after`` and its
        records, so an ended orbit's time stays the time it ended at, exactly,
        and no later collision is counted against a wall.
        """
        if not self.stops:
            return collision
        ended = has_stopped(running.result)
        return Collision(
            state=_where(ended, running.state, collision.state),
            dt=jnp.where(ended, 0.0, collision.dt),
            contact=jnp.where(ended, jnp.int32(NO_CONTACT), collision.contact),
            status=jnp.where(ended, jnp.int32(Result.FINISHED), collision.status),
        )

    def ended(self, running: Running):
        """Whether each orbit had ended for good at ``running``, so that its next collision is held (``held``):
        a section records no held collision (an ended orbit's one state, over and over)."""
        return has_stopped(running.result) if self.stops else jnp.zeros(jnp.shape(running.time), bool)

    def after(self, running: Running, collision: Collision, collided: Any = None) -> Running:
        """``running`` after ``collision`` (where ``collided``; ``None``: every orbit collided)."""

        def chosen(new, old):
            return new if collided is None else _where(collided, new, old)

        error = running.max_energy_error
        if self.drift_of is not None:
            # jnp.maximum propagates NaN: a poisoned orbit keeps reporting NaN.
            error = chosen(jnp.maximum(error, self.drift_of(collision.state)), error)
        tally = tally_contact(self.codes, running.tally, collision.contact, True if collided is None else collided)
        return Running(
            state=chosen(collision.state, running.state),
            time=chosen(running.time + collision.dt, running.time),
            max_energy_error=error,
            tally=tally,
            result=first_failure(running.result, collision.status, collided)
            if self.status_per_collision
            else running.result,
        )

    def result(self, running: Running):
        """The orbits' result codes at the end of a chunk that ended at ``running``."""
        if self.status_per_collision:
            return running.result
        return first_failure(running.result, collision_status(running.time, True))

    def carry(self, carry: Carry, running: Running, collisions: Any, state: Any) -> Carry:
        """The carry after a chunk of ``collisions`` per orbit that ended at ``running`` (``state``: its
        state as an array)."""
        counts = carry.contact_counts
        if self.statistics:
            counts = add_tally(counts, self.codes, running.tally, collisions)
        return Carry(state, running.time, running.max_energy_error, counts, self.result(running))


# -- records ---------------------------------------------------------------------------


def projection(plan: Plan) -> Callable:
    """A section's projection of a state (the whole state when it gives none)."""
    return plan.project or (lambda scene, state: state)


def empty_records(plan: Plan, scene, state_size: int, lead: tuple[int, ...] = ()) -> tuple:
    """A chunk's records before its first collision, per orbit of ``lead``.

    ``"states"``: ``(t, contact, state)`` of ``rows`` rows. ``"section"``:
    ``(point, t, number, fill)`` of ``rows + 1`` rows: the row past the end
    takes what is not kept or does not fit; ``fill`` counts on, so the host
    sees an overflow and runs the chunk again with more room.
    """
    rows = plan.rows
    if plan.record == "final":
        return ()
    if plan.record == "states":
        return (
            jnp.zeros((*lead, rows), jnp.float64),
            jnp.zeros((*lead, rows), jnp.int32),
            jnp.zeros((*lead, rows, state_size), jnp.float64),
        )
    state = jax.ShapeDtypeStruct((state_size,), jnp.float64)
    point = jax.eval_shape(projection(plan), scene, state)
    return (
        jnp.zeros((*lead, rows + 1, *point.shape), point.dtype),
        jnp.zeros((*lead, rows + 1), jnp.float64),
        jnp.zeros((*lead, rows + 1), jnp.int64),
        jnp.zeros(lead, jnp.int64),
    )


def record_state(
    records: tuple, row: Any, state: jax.Array, time: jax.Array, contact: jax.Array, in_bounds: bool = False
) -> tuple:
    """``"states"`` records with one orbit's collision in ``row``: a row past the end writes nothing, unless
    the driver promises there is none (``in_bounds``: then no bounds check at every collision)."""
    t, codes, states = records
    if t.shape[-1] == 0:
        return records  # no room at all (n = 0): nothing to index, even where nothing is written
    if in_bounds:
        # An update of a slice: a scatter would check the row's bounds at every collision.
        return tuple(
            jax.lax.dynamic_update_index_in_dim(record, jnp.asarray(value, record.dtype), row, 0)
            for record, value in zip(records, (time, contact, state))
        )
    return (
        t.at[row].set(time, mode="drop"),
        codes.at[row].set(contact, mode="drop"),
        states.at[row].set(state, mode="drop"),
    )


def record_section_point(plan: Plan, scene, records: tuple, kept: Any, number: Any, state, time) -> tuple:
    """``"section"`` records of one orbit, with its collision ``number`` if ``kept``."""
    point, t, numbers, fill = records
    row = jnp.where(kept, jnp.minimum(fill, plan.rows), plan.rows)
    return (
        point.at[row].set(projection(plan)(scene, state)),
        t.at[row].set(time),
        numbers.at[row].set(jnp.asarray(number).astype(jnp.int64)),
        fill + jnp.asarray(kept).astype(jnp.int64),
    )


def record_collision(
    plan: Plan, scene, records: tuple, collided, number, start, state, time, contact, held=False
) -> tuple:
    """One orbit's records after a turn of a lane driver in which it may have completed collision ``number``
    (``held``: one of an orbit that had ended, which a section does not record)."""
    if plan.record == "final":
        return records
    if plan.record == "states":
        every = plan.every
        kept = collided & (number % every == 0)
        # Collision number c lands in row c // every - start // every - 1 of
        # this chunk; rows past the end are dropped (never written).
        row = jnp.where(kept, number // every - start // every - 1, plan.rows)
        return record_state(records, row, state, time, contact)
    if plan.where is None:
        raise ValueError(f"a {plan.record!r} plan records every collision, not a section")
    kept = collided & ~held & jnp.asarray(plan.where(scene, state, contact), dtype=bool)
    return record_section_point(plan, scene, records, kept, number, state, time)


# -- a chunk's output ------------------------------------------------------------------


def settled(plan: Plan, scene, states0: jax.Array, carry: Carry, records: tuple) -> tuple[Carry, tuple]:
    """A chunk's carry and records as every driver returns them, for one orbit ``(S,)`` or a batch ``(B, S)``.

    An invalid start (``scene.is_valid``; later states come from the map
    itself) gets the result ``INVALID_START`` and NaN everywhere (contacts 0);
    a recorded collision whose time is NaN (a search that proved nothing, and
    what follows it) has no contact. A section's records lose their overflow row.
    """
    lead = states0.ndim - 1
    valid = jax.vmap(scene.is_valid)(states0) if lead else scene.is_valid(states0)
    invalid = ~valid

    def poisoned(a):
        return _where(invalid, jnp.full_like(a, jnp.nan), a)

    carry = Carry(
        poisoned(carry.state),
        poisoned(carry.time),
        poisoned(carry.max_energy_error),
        carry.contact_counts,
        jnp.where(invalid, start_result(valid), carry.result),
    )
    if plan.record == "states":
        t, contact, states = records
        t = poisoned(t)
        records = (t, jnp.where(jnp.isnan(t), jnp.int32(NO_CONTACT), contact), poisoned(states))
    elif plan.record == "section":
        point, t, number, fill = records

        def first_rows(a):
            return jax.lax.slice_in_dim(a, 0, plan.rows, axis=lead)

        records = (poisoned(first_rows(point)), poisoned(first_rows(t)), first_rows(number), fill)
    return carry, records
