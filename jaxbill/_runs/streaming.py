"""Runs of any length in bounded memory: ``jb.run``.

A run advances in *chunks* of collisions. Each chunk is one compiled call that
carries the orbits' states (and running statistics) on the device and records
only what was asked; between chunks the records go to the host (numpy arrays,
or ``.npy`` files in a run directory) and a checkpoint can be taken. Device
memory is therefore bounded by one chunk's records, whatever the run's length;
host memory by what is recorded (or by nothing, with a run directory).

Every chunk is a driver's chunk (``jaxbill._engine.chunks``), the code
``jb.orbit`` runs in one chunk, and a chunk boundary is invisible to the
arithmetic, so the records, final states and statistics of a run do not
depend on the chunk size, and a run resumed from a checkpoint continues bit for
bit as if it had never stopped. Batches run in lanes of the driver's width
split over the devices (``jaxbill._engine.drivers.Batch``). This module is
the host's side: the loop over chunks, the records, the checkpoints.
"""

from __future__ import annotations

import dataclasses
import os
import sys
import time
from collections.abc import Callable
from pathlib import Path

import jax
import jax.numpy as jnp
import numpy as np
from jaxtyping import ArrayLike, Float, Int

from jaxbill._engine.chunks import CONTACT_CODES, Carry, Plan
from jaxbill._engine.collision import check_eagerly
from jaxbill._engine.drivers import Batch
from jaxbill._engine.results import Result
from jaxbill._engine.sharding import DeviceChoice
from jaxbill._engine.validation import check_count
from jaxbill._runs import guard as _run_guard
from jaxbill._runs.files import (
    CHECKPOINT_NAME,
    SECTION_RECORD_NAMES,
    STATE_RECORD_NAMES,
    Checkpoint,
    GrowingNpy,
    open_record,
    scene_parameters,
    scene_signature,
)

# Default chunk: about this many collisions (all orbits together) per compiled
# call: at the rates a CPU reaches (the performance page), long enough that the host
# round trip between chunks costs little, short enough for a live progress bar.
COLLISIONS_PER_CHUNK = 1 << 22
# A run that records nothing per collision (``record="final"``, default chunk)
# quadruples its chunk after every call that took under a quarter of this: on a
# GPU, 2**22 collisions over 2**20 orbits are 4 collisions per orbit, too little
# work to pay for a call. The chunk is a traced argument there, so nothing recompiles.
SECONDS_PER_CHUNK = 1.0
# Default bound on one chunk's records on the device (states or section points).
RECORD_BYTES_PER_CHUNK = 1 << 26
# A run directory's checkpoint is rewritten at most this often (and at the end).
CHECKPOINT_INTERVAL_S = 60.0


@dataclasses.dataclass(frozen=True)
class Section:
    """Record only the collisions that pass a filter, and only a projection of them.

    Attributes:
        where: ``where(scene, state, contact) -> bool``: pure and traceable, for
            one state ``(S,)`` just after a collision and its contact code ``()``.
        project: ``project(scene, state) -> (P,)`` array, pure and traceable, e.g.
            ``jb.reduced_section`` or ``jb.birkhoff_section``; ``None`` keeps the
            whole state (``P = S``).
        capacity: points each orbit may record per chunk on the device (default:
            an eighth of the chunk, within ``RECORD_BYTES_PER_CHUNK``). When an
            orbit passes more, nothing is lost: the chunk is run again from its
            start with room for all of them (``Run.section_reruns`` counts these;
            the larger room is kept for later chunks).

    Use module-level functions (not fresh lambdas) to reuse the compiled code
    across calls: the functions are part of the compilation key.
    """

    where: Callable
    project: Callable | None = None
    capacity: int | None = None


@dataclasses.dataclass(frozen=True)
class SectionPoints:
    """Points recorded by a ``Section``, ordered by chunk, then orbit, then collision.

    Attributes:
        point: ``(m, P)`` the projections.
        t: ``(m,)`` absolute times of the collisions.
        collision: ``(m,)`` int64: which collision of its orbit (1 = the first).
        orbit: ``(m,)`` int64 index into the batch (``None`` for a single orbit);
            ``point[orbit == i]`` is orbit ``i``'s points in collision order.
    """

    point: Float[np.ndarray, "m P"]
    t: Float[np.ndarray, " m"]
    collision: Int[np.ndarray, " m"]
    orbit: Int[np.ndarray, " m"] | None


@dataclasses.dataclass(frozen=True)
class Run:
    """What ``jb.run`` returns: final states, running statistics and the records.

    Shapes are for a single orbit / a batch; ``B_local`` is the number of orbits
    this process ran (``B`` unless under ``jax.distributed``; see ``orbit_index``).

    Attributes:
        final_state: ``(S,)`` / ``(B_local, S)`` the state just after the last collision.
        time: ``()`` / ``(B_local,)`` absolute time of the last collision (0 at ``state0``); for an orbit
            that ended (``jb.Result.ESCAPED``, ``STOPPED``), the time it ended at.
        collisions: collisions per orbit done, in all (also before a resume).
        contact_codes: the contact codes counted.
        contact_counts: ``(C + 1,)`` / ``(B_local, C + 1)`` int64: collisions with each code
            of ``contact_codes``, and (last column) with any other code.
        max_energy_error: ``()`` / ``(B_local,)``: ``max |E - E0| / |E0|`` over all
            collisions (``|E - E0|`` if ``E0 = 0``; NaN for an orbit that was NaN-poisoned).
        result: ``()`` / ``(B_local,)`` int32: why each orbit stopped, or what went
            wrong first (``jb.Result``; ``FINISHED`` when all went well).
        t, contact, state: ``record="states"``: ``(R,)``, ``(R,)``, ``(R, S)`` (with a
            leading ``B_local`` axis for a batch): the collisions numbered ``every``,
            ``2 every``, ... In memory, those of this call (after ``resume``); with a
            run directory, read-only memory maps of the whole run's files. Else ``None``.
        section: ``SectionPoints`` for a ``Section`` record (same in memory / on disk rule).
        orbit_index: ``(B_local,)`` which orbits of the batch the batch fields hold
            (``arange(B)`` in one process), ``None`` for a single orbit.
        checkpoint: where the run stands: pass it as ``resume`` to run further.
        section_reruns: chunks run again because an orbit had more section points
            than its ``capacity``.
        chunks: chunks run by this call.
        out: the run directory of this process, or ``None``.
    """

    final_state: Float[np.ndarray, "*orbits S"]
    time: Float[np.ndarray, "*orbits"]
    collisions: int
    contact_codes: tuple[int, ...]
    contact_counts: Int[np.ndarray, "*orbits codes"]
    max_energy_error: Float[np.ndarray, "*orbits"]
    result: Int[np.ndarray, "*orbits"]
    t: Float[np.ndarray, "*orbits R"] | None
    contact: Int[np.ndarray, "*orbits R"] | None
    state: Float[np.ndarray, "*orbits R S"] | None
    section: SectionPoints | None
    orbit_index: Int[np.ndarray, " orbits"] | None
    checkpoint: Checkpoint
    section_reruns: int
    chunks: int
    out: Path | None


# -- one orbit or a batch, on the devices ------------------------------------------


class _Engine(Batch):
    """The run's orbits on the devices (``jaxbill._engine.drivers.Batch``), started from a checkpoint."""

    def initial_carry(self, checkpoint: Checkpoint | None) -> Carry:
        """The carry on the devices: fresh, or this process's orbits from ``checkpoint``."""
        return self.fresh_carry() if checkpoint is None else self.carry_of(_carry_of(checkpoint))


def _carry_of(checkpoint: Checkpoint) -> Carry:
    result = checkpoint.result
    if result is None:
        # A checkpoint written before runs kept result codes: what its times say.
        finite, forever = np.isfinite(checkpoint.time), np.isinf(checkpoint.time)
        result = np.where(finite, Result.FINISHED, np.where(forever, Result.NO_WALL, Result.NON_FINITE))
    return Carry(
        checkpoint.state,
        checkpoint.time,
        checkpoint.max_energy_error,
        checkpoint.contact_counts,
        np.asarray(result, np.int32),
    )


def _largest_everywhere(value: int) -> int:
    """The largest of ``value`` over all processes: every process must run the
    same sequence of compiled chunks, so a rerun is decided for all at once."""
    if jax.process_count() == 1:
        return value
    from jax.experimental import multihost_utils

    return int(np.max(multihost_utils.process_allgather(np.int64(value))))


# -- the host loop -------------------------------------------------------------------


class _ProgressBar:
    """``jaxbill.run [#####.....] 4.2e+08/1e+09 collisions per orbit, 1.1e+07/s, ETA 52 s`` on stderr."""

    def __init__(self, total: int, done: int, orbits: int, enabled: bool):
        self.total, self.first, self.orbits, self.enabled = total, done, orbits, enabled
        self.started = time.perf_counter()
        self.tty = sys.stderr.isatty()

    def update(self, done: int) -> None:
        if not self.enabled:
            return
        elapsed = time.perf_counter() - self.started
        rate = (done - self.first) * self.orbits / max(elapsed, 1e-9)
        remaining = (self.total - done) * self.orbits / rate if rate > 0 else float("inf")
        width = 24
        filled = int(width * done / max(self.total, 1))
        line = (
            f"jaxbill.run [{'#' * filled}{'.' * (width - filled)}] {done:.3g}/{self.total:.3g} collisions"
            f"{' per orbit' if self.orbits > 1 else ''}, {rate:.3g}/s, {elapsed:.0f} s, ETA {remaining:.0f} s"
        )
        sys.stderr.write(("\r" + line) if self.tty else (line + "\n"))
        if self.tty and done >= self.total:
            sys.stderr.write("\n")
        sys.stderr.flush()


def _parse_record(record, every) -> tuple[str, Section | None, int]:
    every = check_count("every", every, 1, "record the collisions numbered every, 2 every, ...")
    section = record if isinstance(record, Section) else None
    if section is not None:
        kind = "section"
    elif record in ("final", "states"):
        kind = str(record)
    else:
        raise ValueError(f"record must be 'final', 'states' or a jb.Section; got {record!r}")
    if every != 1 and kind != "states":
        raise ValueError(f"every applies to record='states' only; got every={every} with record={record!r}")
    if section is not None:
        if not callable(section.where) or not (section.project is None or callable(section.project)):
            raise ValueError("Section: where and project must be functions (project may be None)")
        if section.capacity is not None:
            check_count("Section.capacity", section.capacity, 1, "section points per orbit per chunk")
    return kind, section, every


def _section_point_shape(scene, state0: np.ndarray, section: Section) -> jax.ShapeDtypeStruct:
    state = jax.ShapeDtypeStruct(state0.shape[-1:], jnp.float64)
    contact = jax.ShapeDtypeStruct((), jnp.int32)
    keep = jax.eval_shape(section.where, scene, state, contact)
    if keep.shape != ():
        raise ValueError(f"Section.where must return one bool per state; got shape {keep.shape}")
    if section.project is None:
        return state
    point = jax.eval_shape(section.project, scene, state)
    if point.ndim != 1:
        raise ValueError(f"Section.project must return a vector (P,) for one state; got shape {point.shape}")
    return point


def _default_chunk(kind: str, lanes: int, every: int, record_row_bytes: int) -> int:
    chunk = max(1, COLLISIONS_PER_CHUNK // lanes)
    if kind == "states":
        rows = max(1, RECORD_BYTES_PER_CHUNK // (lanes * record_row_bytes))
        chunk = min(chunk, rows * every)
    return chunk


def _resolve_out(out) -> Path | None:
    if out is None:
        return None
    if not isinstance(out, (str, os.PathLike)):
        raise ValueError(f"out must be a directory path (str or os.PathLike) or None; got {out!r}")
    path = Path(out)
    if path.exists() and not path.is_dir():
        raise ValueError(f"out must name a directory (records are .npy files in it); {path} is a file")
    if jax.process_count() > 1:
        # Each process writes the orbits it ran, into its own directory.
        path = path / f"process_{jax.process_index()}"
    return path


def _same_checkpoint(a: Checkpoint, b: Checkpoint) -> bool:
    """Whether two checkpoints are the same point of the same run, field by field (arrays bitwise)."""

    def same(x, y) -> bool:
        if isinstance(x, tuple) or isinstance(y, tuple):
            return isinstance(x, tuple) and isinstance(y, tuple) and len(x) == len(y) and all(map(same, x, y))
        if x is None or y is None:
            return x is None and y is None
        return bool(np.array_equal(np.asarray(x), np.asarray(y)))

    return all(same(getattr(a, f.name), getattr(b, f.name)) for f in dataclasses.fields(Checkpoint))


def _starting_checkpoint(resume, out_dir, scene, state0, n, record_signature, engine) -> tuple[Checkpoint | None, bool]:
    """The checkpoint a run starts from (``None``: collision 0) and whether it continues the run in ``out_dir``."""
    held = out_dir is not None and (out_dir / CHECKPOINT_NAME).exists()
    if resume is None or resume is False:
        if held:
            raise ValueError(
                f"{out_dir} already holds a run; pass resume=True to continue it, or choose another directory"
            )
        return None, False
    if resume is True:
        if out_dir is None or not held:
            raise ValueError(f"resume=True continues the run in out; there is no {CHECKPOINT_NAME} in {out_dir}")
        source = out_dir / CHECKPOINT_NAME
        checkpoint = Checkpoint.load(source)
    elif isinstance(resume, Checkpoint):
        source, checkpoint = "the checkpoint", resume
    elif isinstance(resume, (str, os.PathLike)):
        source, checkpoint = resume, Checkpoint.load(resume)
    else:
        raise ValueError(f"resume must be None, True, a Checkpoint or a checkpoint path; got {resume!r}")
    continues = resume is True
    if held and not continues and out_dir is not None:
        # A checkpoint passed into the directory of its own run continues that run, as resume=True would;
        # any other would mix two runs' records in one directory.
        own = Checkpoint.load(out_dir / CHECKPOINT_NAME)
        if not _same_checkpoint(own, checkpoint):
            raise ValueError(
                f"resume: {source} is not the checkpoint of the run in {out_dir} (that run is at collision "
                f"{own.collisions}, {source} at {checkpoint.collisions}): pass resume=True to continue the run "
                f"in {out_dir}, or choose another directory to continue from {source}"
            )
        continues = True
    if checkpoint.state0.shape != state0.shape or not np.array_equal(checkpoint.state0, state0):
        raise ValueError(f"resume: {source} belongs to a run from other initial states (state0 differs)")
    same_parameters = len(checkpoint.scene_parameters) == len(scene_parameters(scene)) and all(
        np.array_equal(a, b) for a, b in zip(checkpoint.scene_parameters, scene_parameters(scene))
    )
    if checkpoint.scene_signature != scene_signature(scene) or not same_parameters:
        raise ValueError(f"resume: {source} belongs to a run of another scene")
    if checkpoint.collisions > n:
        raise ValueError(f"resume: {source} is at collision {checkpoint.collisions}, beyond n = {n}")
    saved_orbits, engine_orbits = checkpoint.orbit_index, engine.orbit_index
    same_orbits = (saved_orbits is None and engine_orbits is None) or (
        saved_orbits is not None and engine_orbits is not None and np.array_equal(saved_orbits, engine_orbits)
    )
    if not same_orbits:
        raise ValueError(
            f"resume: {source} holds other orbits than this process runs "
            "(a checkpoint of one process of a jax.distributed run resumes only in the same layout)"
        )
    if out_dir is not None and checkpoint.record != record_signature:
        raise ValueError(
            f"resume: the run in {out_dir} records {checkpoint.record!r}; this call asks for {record_signature!r}"
        )
    return checkpoint, continues


class _Records:
    """Collects a run's records on the host: in numpy arrays, or in the run directory."""

    def __init__(self, kind, every, n, first, engine, point, out_dir, own_checkpoint, checkpoint_bytes=0):
        """``first``: collisions done before this call; ``own_checkpoint``: the run
        directory's checkpoint when continuing the run in it (else ``None``);
        ``checkpoint_bytes``: room the checkpoints need besides the records.

        In a run directory, the full-size ``record="states"`` files take all their
        disk blocks here, before the first collision, or the run fails here with
        ``OSError(ENOSPC)`` saying how many bytes it needs and how many are free
        (and leaves no files it created).
        """
        self.kind, self.every, self.engine, self.out_dir = kind, every, engine, out_dir
        checkpoint = own_checkpoint
        # Records begin where this directory (or, in memory, this call) began.
        self.records_from = checkpoint.records_from if checkpoint else first
        self.section_rows = checkpoint.section_rows if checkpoint else 0  # section points in out_dir
        self.section_blocks: list[tuple[np.ndarray, ...]] = []
        self.section_files: list[GrowingNpy] | None = None
        # np.memmap in a run directory, np.ndarray in memory
        self.states: list[np.ndarray] | None = None
        lead = (engine.orbit_index.size,) if engine.batched else ()
        if out_dir is not None:
            out_dir.mkdir(parents=True, exist_ok=True)
        if kind == "states":
            # Record r holds collision (self.base + r + 1) * every.
            self.base = self.records_from // every
            count = n // every - self.base
            size = engine.state0.shape[-1]
            specs = zip(
                STATE_RECORD_NAMES,
                (np.float64, np.int32, np.float64),
                ((*lead, count), (*lead, count), (*lead, count, size)),
            )
            if out_dir is None:
                self.states = [np.empty(shape, dtype) for _, dtype, shape in specs]
            else:
                self._open_states(specs, fresh=checkpoint is None, checkpoint_bytes=checkpoint_bytes)
        elif kind == "section" and out_dir is not None:
            specs = [(point.dtype, point.shape), (np.float64, ()), (np.int64, ())]
            if engine.batched:
                specs.append((np.int64, ()))
            self.section_files = [
                GrowingNpy(out_dir / f"{name}.npy", dtype, shape, self.section_rows, create=checkpoint is None)
                for name, (dtype, shape) in zip(SECTION_RECORD_NAMES, specs)
            ]
        if out_dir is not None and kind != "states":
            # Section files grow as points come (a full disk then stops the run
            # with its checkpoint, see run); only the checkpoint's room is known.
            _run_guard.check_space(out_dir, checkpoint_bytes, "the checkpoint")

    def _open_states(self, specs, fresh: bool, checkpoint_bytes: int) -> None:
        specs = list(specs)
        paths = [self.out_dir / f"{name}.npy" for name, _, _ in specs]
        what = "record='states' (" + ", ".join(path.name for path in paths) + ") with its checkpoint"
        try:
            self.states = [
                open_record(path, dtype, shape, create=fresh) for path, (_, dtype, shape) in zip(paths, specs)
            ]
            # The files are sparse so far: count the blocks they still lack.
            needed = sum(_run_guard.unallocated_bytes(path) for path in paths) + checkpoint_bytes
            _run_guard.check_space(self.out_dir, needed, what)
            for path in paths:
                _run_guard.reserve(path, path.stat().st_size, what)
        except BaseException:
            self.states = None
            if fresh:
                for path in paths:
                    path.unlink(missing_ok=True)
            raise

    def add_states(self, buffers, start: int, steps: int) -> None:
        # The collisions numbered every, 2 every, ... within (start, start + steps].
        first, last = start // self.every, (start + steps) // self.every
        if last == first:
            return
        rows = slice(first - self.base, last - self.base)
        assert self.states is not None  # opened for record="states"
        for record, buffer in zip(self.states, buffers):
            values = self.engine.to_host(buffer)
            if self.engine.batched:
                record[:, rows] = values[:, : last - first]
            else:
                record[rows] = values[: last - first]

    def add_section(self, point, t, number, fill) -> None:
        point, t, number, fill = (self.engine.to_host(a) for a in (point, t, number, fill))
        if self.engine.batched:
            kept = np.arange(point.shape[1])[None, :] < fill[:, None]  # orbit by orbit, in collision order
            orbit = np.broadcast_to(self.engine.orbit_index[:, None], kept.shape)[kept]
            block = (point[kept], t[kept], number[kept], orbit)
        else:
            block = (point[:fill], t[:fill], number[:fill])
        if self.section_files is None:
            self.section_blocks.append(block)
        else:
            try:
                for file, values in zip(self.section_files, block):
                    file.append(values)
            except OSError:
                # Give back what this chunk took of a full disk, so that the
                # checkpoint of the last complete chunk still fits.
                for file in self.section_files:
                    try:
                        file.cut(self.section_rows)
                    except OSError:
                        pass
                raise
        # Counted (and so in the next checkpoint) only once every file holds them.
        self.section_rows += block[0].shape[0]

    def flush(self) -> None:
        if self.out_dir is not None and self.states is not None:
            for name, record in zip(STATE_RECORD_NAMES, self.states):
                try:
                    if isinstance(record, np.memmap):  # always, in a run directory
                        record.flush()
                except OSError as error:  # e.g. EIO from the disk: say which file
                    raise OSError(error.errno, error.strerror, str(self.out_dir / f"{name}.npy")) from error

    def results(self, point) -> tuple:
        """``(t, contact, state, section)`` for ``Run``: numpy arrays, or read-only
        memory maps of the run directory's files."""
        if self.kind == "final":
            return None, None, None, None
        if self.kind == "states":
            if self.out_dir is None:
                assert self.states is not None  # made in memory for record="states"
                return (*self.states, None)
            return (*(np.load(self.out_dir / f"{name}.npy", mmap_mode="r") for name in STATE_RECORD_NAMES), None)
        batched = self.engine.batched
        if self.section_files is not None:
            columns = [np.load(file.path, mmap_mode="r") for file in self.section_files]
        else:
            empty = [np.zeros((0, *point.shape), point.dtype), np.zeros(0), np.zeros(0, np.int64)]
            if batched:
                empty.append(np.zeros(0, np.int64))
            blocks = self.section_blocks or [tuple(empty)]
            columns = [np.concatenate(column) for column in zip(*blocks)]
        return None, None, None, SectionPoints(*columns, *([] if batched else [None]))


def run(
    scene,
    state0: Float[ArrayLike, "*batch S"],
    n: int,
    *,
    record="final",
    every: int = 1,
    chunk: int | None = None,
    out: str | os.PathLike | None = None,
    resume=None,
    devices: DeviceChoice = None,
    progress: bool | None = None,
    driver: str | None = None,
) -> Run:
    """Run ``n`` collisions of one orbit or a batch in bounded memory, recording only what is asked.

    Args:
        scene: any scene (e.g. ``StickInCircle``), with scalar parameters.
        state0: ``(S,)`` one initial state or ``(B, S)`` a batch (``S = scene.state_size``;
            under ``jax.distributed`` every process passes the same full batch).
        n: collisions per orbit, in all (when resuming, the run's total, not the rest).
        record: ``"final"`` (nothing per collision: final states and running
            statistics only), ``"states"`` (time, contact and state after the
            collisions numbered ``every``, ``2 every``, ...; ``every=1``: all of
            them, exactly what ``jb.orbit`` returns), or a ``Section`` (the points
            of collisions that pass its filter).
        every: with ``record="states"``, record every ``every``-th collision.
        chunk: collisions per orbit per compiled call (default: about ``2**22``
            collisions over all orbits, with at most ``RECORD_BYTES_PER_CHUNK``
            of records; with ``record="final"`` it then quadruples after every
            call shorter than ``SECONDS_PER_CHUNK / 4``). Results do not depend on it.
        out: a directory to write the run into: ``.npy`` records (memory-mappable,
            written chunk by chunk, so host memory stays bounded) and
            ``checkpoint.npz`` (at the start, every ``CHECKPOINT_INTERVAL_S``, on
            a stop signal and at the end). Under ``jax.distributed`` each process
            writes ``out/process_<i>``. ``None``: records are returned as numpy arrays.
            The call holds a lock on the directory (one writer at a time), makes
            the ``record="states"`` files take their disk space before the first
            collision, and turns ``SIGTERM`` and ``SIGINT`` (Ctrl-C) into a stop at
            the end of the chunk in flight, after a checkpoint (README, "Long runs").
        resume: continue a run: ``True`` (the run in ``out``), a ``Checkpoint``
            (e.g. ``previous.checkpoint``), a checkpoint path or a run
            directory (its ``checkpoint.npz``). ``scene`` and ``state0`` must be
            the run's own. Into an ``out`` that holds a run, only that run's
            own checkpoint continues (as ``True`` does). The result is bitwise
            what the uninterrupted run gives.
        devices: where a batch runs: ``None`` (every JAX device, of every process),
            a list of devices, or a ``Mesh`` (see ``jb.orbit_mesh``). A single
            orbit runs on the default device.
        progress: a progress bar on stderr; ``None``: when stderr is a terminal,
            in process 0, for a run of several chunks.
        driver: for a batch, ``"serial"``, ``"lockstep"``, ``"lanes"`` or ``"pallas"``;
            ``None`` picks the fastest for the scene on the platform: on a
            CPU ``"serial"`` or ``"lockstep"`` by the scene's
            ``batch_chunk``, on a GPU ``"pallas"`` (``record="final"``; other
            records take ``"lanes"``). See ``jaxbill._engine.drivers.choose_driver``. All give
            the same orbits to rounding; a checkpoint resumes bitwise with the
            driver that wrote it. Derivatives never go through a driver:
            ``jb.collide``, ``jb.orbit`` of one orbit, ``jb.tangent_map`` and
            ``jb.lyapunov_spectrum`` differentiate ``jaxbill._engine.step.advance``.

    Returns:
        ``Run``: final states, running statistics, each orbit's result code
        (``jb.Result``), records and a checkpoint. A batch of no orbits
        ``(0, S)`` gives a run of no orbits.

    Raises:
        ValueError: for bad ``state0``/``n`` (as ``jb.orbit``), an unknown
            ``record``, ``every`` with a record other than ``"states"``,
            ``chunk < 1``, an ``out`` that is a file or already holds a run
            (unless ``resume`` continues it), an ``out`` another ``jb.run`` is writing (the
            message names the process), a checkpoint of another run, or a
            checkpoint or record file that is damaged (the message names it).
        OSError: (``ENOSPC``) before the first collision, if the records do
            not fit on the disk (the message says how many bytes are needed and
            free); during the run, if writing fails: the run stops with its
            checkpoint intact and the message says from which collision
            ``resume=True`` continues.
        RunInterrupted: after a ``SIGTERM``, with the checkpoint written.
        KeyboardInterrupt: after a ``SIGINT`` (Ctrl-C), with the checkpoint written.

    Memory: the device holds each orbit's carry (state and statistics, about
    ``(S + 12) * 8`` bytes) and one chunk's records; ``record="final"`` over a
    run of any length keeps nothing per collision.
    """
    n = check_count("n", n, 0, "collisions per orbit, in all")
    kind, section, every = _parse_record(record, every)
    if chunk is not None:
        chunk = check_count("chunk", chunk, 1, "collisions per orbit per compiled call")
    if progress not in (None, True, False):
        raise ValueError(f"progress must be None, True or False; got {progress!r}")
    check_eagerly(scene, state0)
    state0 = np.asarray(state0, dtype=np.float64)
    out_dir = _resolve_out(out)
    # The directory is locked before its checkpoint is read: two calls racing
    # for it would otherwise both find it empty and both write into it.
    with _run_guard.RunGuard(out_dir) as guard:
        return _run_chunks(
            scene, state0, n, kind, section, every, chunk, out_dir, resume, devices, progress, guard, driver
        )


def _run_chunks(
    scene, state0, n, kind, section, every, chunk, out_dir, resume, devices, progress, guard, driver
) -> Run:
    """``run`` once its arguments are checked and its directory (if any) is held by ``guard``."""
    engine = _Engine(scene, state0, devices, driver)

    point = _section_point_shape(scene, state0, section) if section else None
    if point is not None:
        record_signature = f"section/{point.shape}"
    else:
        record_signature = "final" if kind == "final" else f"states/every={every}"
    checkpoint, continues = _starting_checkpoint(resume, out_dir, scene, state0, n, record_signature, engine)
    first = checkpoint.collisions if checkpoint else 0

    row_bytes = (state0.shape[-1] + 2) * 8 if kind == "states" else ((point.size + 2) * 8 if point else 0)
    # Every process of a jax.distributed run must run the same chunks: no growth there.
    grows = chunk is None and kind == "final" and jax.process_count() == 1
    sized_lanes = max(engine.lanes, 1)  # an empty batch (no lanes, nothing to compute) is sized as one lane
    if chunk is None:
        chunk = _default_chunk(kind, sized_lanes, every, row_bytes)
    rows = -(-chunk // every)  # records per orbit per chunk, whatever the phase
    if kind == "section":
        fitting = max(1, RECORD_BYTES_PER_CHUNK // (sized_lanes * row_bytes))
        rows = min(chunk, section.capacity or min(fitting, max(1, chunk // 8)))
    plan = Plan(
        kind,
        every,
        rows,
        where=None if section is None else section.where,
        project=None if section is None else section.project,
    )

    carry = engine.initial_carry(checkpoint)
    own_checkpoint = checkpoint if continues else None
    lead = engine.orbit_index.size if engine.orbit_index is not None else 1  # set for a batch only
    # The old and the new checkpoint side by side while one replaces the other.
    checkpoint_bytes = 2 * (state0.nbytes + lead * (state0.shape[-1] + len(CONTACT_CODES) + 5) * 8) + (1 << 16)
    records = _Records(kind, every, n, first, engine, point, out_dir, own_checkpoint, checkpoint_bytes)

    show = (
        progress if progress is not None else (sys.stderr.isatty() and jax.process_index() == 0 and n - first > chunk)
    )
    bar = _ProgressBar(n, first, engine.batch if engine.batched else 1, show)
    done, chunks, reruns = first, 0, 0
    last_saved = time.perf_counter()

    def checkpoint_now() -> Checkpoint:
        state, time_, max_energy_error, contact_counts, result = (engine.to_host(a) for a in carry)
        return Checkpoint(
            state0=state0,
            state=state,
            time=time_,
            max_energy_error=max_energy_error,
            contact_counts=contact_counts,
            result=result,
            contact_codes=np.asarray(CONTACT_CODES),
            collisions=done,
            orbit_index=engine.orbit_index,
            scene_signature=scene_signature(scene),
            scene_parameters=tuple(scene_parameters(scene)),
            record=record_signature,
            section_rows=records.section_rows,
            records_from=records.records_from,
        )

    saved_at = first if own_checkpoint is not None else None  # collision of the checkpoint in out_dir

    def save_checkpoint() -> Checkpoint:
        nonlocal saved_at
        saved = checkpoint_now()
        records.flush()  # the records before the checkpoint that counts them
        saved.save(out_dir / CHECKPOINT_NAME)
        saved_at = done
        return saved

    def write_failed(error: OSError, checkpoint_again: bool) -> OSError:
        """The error that ends a run whose files could not be written: the
        checkpoint in ``out_dir`` (that of the last complete chunk, if it can still
        be written; else the one before) matches the records up to it."""
        if checkpoint_again:
            try:
                save_checkpoint()
            except OSError:
                pass  # the disk refuses even that: the checkpoint before stands
        where = (
            f"{out_dir / CHECKPOINT_NAME} holds collision {saved_at}, with the records up to it: free some "
            "space (or repair the disk) and continue with the same arguments and resume=True, bitwise the "
            "uninterrupted run"
            if saved_at is not None
            else "no checkpoint could be written: free some space (or repair the disk) and start the run again"
        )
        return OSError(
            error.errno,
            f"jb.run: writing {error.filename or out_dir} failed ({error.strerror or error}) after collision "
            f"{done} of {n}; the run stopped. {where}",
            error.filename,
        )

    if out_dir is not None and own_checkpoint is None:
        # From the start a crash leaves a checkpoint, so resume=True always applies.
        try:
            save_checkpoint()
        except OSError as error:
            raise write_failed(error, False) from error

    while done < n:
        steps = min(chunk, n - done)
        started = time.perf_counter()
        new_carry, out_buffers = engine.run_chunk(plan, carry, done, steps)
        try:
            if kind == "section":
                most = _largest_everywhere(int(np.max(engine.to_host(out_buffers[3]), initial=0)))
                if most > plan.rows:
                    # Too many points for the room: run this chunk again from its
                    # start (the carry is still there) with room for all of them.
                    plan = dataclasses.replace(plan, rows=min(chunk, 1 << (most - 1).bit_length()))
                    reruns += 1
                    continue
                records.add_section(*out_buffers)
            elif kind == "states":
                records.add_states(out_buffers, done, steps)
            else:
                jax.block_until_ready(new_carry)
        except OSError as error:
            # carry and done are still those of the last complete chunk.
            raise write_failed(error, True) from error
        carry, done, chunks = new_carry, done + steps, chunks + 1
        if grows and time.perf_counter() - started < SECONDS_PER_CHUNK / 4:
            chunk *= 4
        bar.update(done)
        if out_dir is None:
            continue
        # Processes of a jax.distributed run stop and checkpoint after the same chunk.
        stop, due = _run_guard.agreed(
            guard.stop_requested(), time.perf_counter() - last_saved > CHECKPOINT_INTERVAL_S and done < n
        )
        if stop or due:
            try:
                save_checkpoint()
            except OSError as error:
                raise write_failed(error, False) from error
            last_saved = time.perf_counter()
        if stop:
            guard.stop(done, n, out_dir / CHECKPOINT_NAME)

    final = checkpoint_now()
    if out_dir is not None:
        try:
            final = save_checkpoint()
        except OSError as error:
            raise write_failed(error, False) from error
    t, contact, states, points = records.results(point)
    assert final.result is not None  # a checkpoint this run wrote keeps its result codes
    return Run(
        final_state=final.state,
        time=final.time,
        collisions=done,
        contact_codes=CONTACT_CODES,
        contact_counts=final.contact_counts,
        max_energy_error=final.max_energy_error,
        result=final.result,
        t=t,
        contact=contact,
        state=states,
        section=points,
        orbit_index=engine.orbit_index,
        checkpoint=final,
        section_reruns=reruns,
        chunks=chunks,
        out=out_dir,
    )
