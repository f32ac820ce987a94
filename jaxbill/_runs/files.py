"""What a long run leaves on disk: its checkpoint and its records as ``.npy`` files.

A run directory holds

* ``checkpoint.npz``: everything needed to continue the run bit for bit (see
  ``Checkpoint``), replaced atomically, so a run killed at any moment leaves
  the last complete one;
* for ``record="states"``: ``t.npy``, ``contact.npy``, ``state.npy``, allocated
  at full size when the run starts and filled chunk by chunk (``np.load(path,
  mmap_mode="r")`` reads them without loading them);
* for a ``Section``: ``section_point.npy``, ``section_t.npy``,
  ``section_collision.npy`` (and ``section_orbit.npy`` for a batch), which grow
  by one block of rows per chunk.

Plain ``.npy`` files because they can be memory-mapped and grown in place; an
``.npz`` archive can be neither (``np.savez`` the arrays of a finished run if
one file is wanted).
"""

from __future__ import annotations

import dataclasses
import errno
import os
import struct
import zipfile
import zlib
from pathlib import Path

import jax
import numpy as np
from jaxtyping import Float, Int

CHECKPOINT_NAME = "checkpoint.npz"
STATE_RECORD_NAMES = ("t", "contact", "state")
SECTION_RECORD_NAMES = ("section_point", "section_t", "section_collision", "section_orbit")
_FORMAT_VERSION = 1
# What np.load raises on a damaged .npz or .npy: the file is cut short, its bytes
# changed, or it is not what its name says. (Not OSError: a file that cannot be
# opened, e.g. for want of permission, says so itself.)
_UNREADABLE = (zipfile.BadZipFile, zlib.error, struct.error, EOFError, KeyError, ValueError, SyntaxError)


def damaged(path: Path, problem: str) -> ValueError:
    """The error for a run directory's file that does not match its checkpoint."""
    return ValueError(
        f"{path}: {problem}. The run directory's files no longer match its {CHECKPOINT_NAME} (changed or "
        "damaged since it was written, or left by another run). Restore the file from a copy, or continue "
        f"into a new directory: jb.run(..., out=<new directory>, resume='{path.parent / CHECKPOINT_NAME}') "
        "(whose records then begin at the checkpoint's collision)"
    )


def scene_signature(scene) -> str:
    """The scene's type and static fields (its pytree structure), for checks on resume."""
    return str(jax.tree.structure(scene))


def scene_parameters(scene) -> list[np.ndarray]:
    return [np.asarray(leaf) for leaf in jax.tree.leaves(scene)]


@dataclasses.dataclass(frozen=True)
class Checkpoint:
    """Where a run stands after its last complete chunk: enough to continue it bit for bit.

    Attributes:
        state0: ``(S,)`` or ``(B, S)``: the run's initial states (every orbit, also
            under ``jax.distributed``); quantities fixed along an orbit are
            recomputed from them, exactly as in the uninterrupted run.
        state: ``(S,)`` or ``(B_local, S)``: each orbit's state just after its
            last collision (``B_local``: the orbits this process runs).
        time: ``()`` or ``(B_local,)``: absolute time of that collision (time 0 at ``state0``).
        max_energy_error: ``()`` or ``(B_local,)``: ``max |E - E0| / |E0|`` over the
            collisions so far (NaN once an orbit is NaN-poisoned).
        contact_counts: ``(C + 1,)`` or ``(B_local, C + 1)`` int64: collisions per
            contact code, in the order of ``contact_codes``, and (last) any other code.
        contact_codes: ``(C,)`` the codes counted.
        collisions: collisions done per orbit.
        orbit_index: ``(B_local,)`` which orbits of the batch ``state`` holds (``None``
            for a single orbit).
        scene_signature, scene_parameters: the scene, to refuse resuming with another.
        record: what the run records, e.g. ``"final"``, ``"states/every=10"``,
            ``"section/2"`` (points of 2 coordinates), to refuse mixing records in one directory.
        section_rows: section points written to the run directory so far.
        records_from: the collision count at which the run directory's records
            begin (0, unless the directory continues a checkpoint of another run).
        result: ``()`` or ``(B_local,)`` int32: each orbit's result code so far
            (``jb.Result``); ``None`` in a checkpoint written before runs kept them.
    """

    state0: Float[np.ndarray, "*batch S"]
    state: Float[np.ndarray, "*orbits S"]
    time: Float[np.ndarray, "*orbits"]
    max_energy_error: Float[np.ndarray, "*orbits"]
    contact_counts: Int[np.ndarray, "*orbits codes"]
    contact_codes: Int[np.ndarray, " C"]
    collisions: int
    orbit_index: Int[np.ndarray, " orbits"] | None
    scene_signature: str
    scene_parameters: tuple
    record: str
    section_rows: int = 0
    records_from: int = 0
    result: Int[np.ndarray, "*orbits"] | None = None

    def save(self, path: str | os.PathLike) -> None:
        """Write to ``path`` (an ``.npz``) atomically: a temporary file, then a rename."""
        path = Path(path)
        arrays = {
            "format_version": np.int64(_FORMAT_VERSION),
            "state0": self.state0,
            "state": self.state,
            "time": self.time,
            "max_energy_error": self.max_energy_error,
            "contact_counts": self.contact_counts,
            "contact_codes": self.contact_codes,
            "collisions": np.int64(self.collisions),
            "scene_signature": np.str_(self.scene_signature),
            "record": np.str_(self.record),
            "section_rows": np.int64(self.section_rows),
            "records_from": np.int64(self.records_from),
            "scene_parameter_count": np.int64(len(self.scene_parameters)),
        }
        if self.orbit_index is not None:
            arrays["orbit_index"] = self.orbit_index
        if self.result is not None:
            arrays["result"] = self.result
        for i, leaf in enumerate(self.scene_parameters):
            arrays[f"scene_parameter_{i}"] = leaf
        temporary = path.with_name(path.name + ".partial")
        try:
            with open(temporary, "wb") as f:
                np.savez(f, **arrays)
                f.flush()
                os.fsync(f.fileno())
            os.replace(temporary, path)
        except BaseException as error:
            # A full disk or a stop mid-write: the previous checkpoint stands, and
            # the half-written one must not hold on to the space.
            temporary.unlink(missing_ok=True)
            if isinstance(error, OSError) and error.filename is None:
                raise OSError(error.errno, error.strerror, str(temporary)) from error
            raise
        _sync_directory(path.parent)

    @classmethod
    def load(cls, path: str | os.PathLike) -> Checkpoint:
        """Read a checkpoint written by ``save`` (no lock needed: ``save`` replaces the file atomically).

        ``path``: the checkpoint file, or a run directory (``jb.run``'s ``out``),
        whose ``checkpoint.npz`` is read.

        Raises:
            FileNotFoundError: no file at ``path``, or a directory without
                ``checkpoint.npz`` (the message names the file it looked for).
            ValueError: naming ``path``, for a file that is cut short or damaged, is
                not a jaxbill checkpoint, or was written in another checkpoint format.
        """
        path = Path(path)
        if path.is_dir():
            inside = path / CHECKPOINT_NAME
            if not inside.is_file():
                processes = sorted(p.name for p in path.glob("process_*") if (p / CHECKPOINT_NAME).is_file())
                where = f" (each process of a distributed run wrote its own: {processes[0]}/...)" if processes else ""
                raise FileNotFoundError(
                    errno.ENOENT, f"{path} is a directory without a run's {CHECKPOINT_NAME}{where}", str(inside)
                )
            path = inside
        what = "a jaxbill checkpoint (an .npz archive written by jb.run)"
        try:
            with np.load(path, allow_pickle=False) as f:
                if not isinstance(f, np.lib.npyio.NpzFile):
                    raise ValueError(f"{path}: not {what}")
                arrays = {name: f[name] for name in f.files}
        except FileNotFoundError:
            raise
        except _UNREADABLE as error:
            if str(error).startswith(str(path)):
                raise
            raise ValueError(
                f"{path}: not a readable checkpoint ({type(error).__name__}: {error}): the file is cut short "
                f"or damaged, or is not {what}. A checkpoint is replaced atomically, so jb.run itself never "
                "leaves half of one: restore it from a copy, or start the run again in a new directory"
            ) from None
        version = arrays.get("format_version")
        if version is None or version.shape != ():
            raise ValueError(f"{path}: no format_version: not {what}")
        if int(version) != _FORMAT_VERSION:
            raise ValueError(
                f"{path}: checkpoint format {int(version)}, this jaxbill reads format {_FORMAT_VERSION}: "
                "resume it with the jaxbill version that wrote it"
            )
        try:
            count = int(arrays["scene_parameter_count"])
            return cls(
                state0=arrays["state0"],
                state=arrays["state"],
                time=arrays["time"],
                max_energy_error=arrays["max_energy_error"],
                contact_counts=arrays["contact_counts"],
                contact_codes=arrays["contact_codes"],
                collisions=int(arrays["collisions"]),
                orbit_index=arrays.get("orbit_index"),
                scene_signature=str(arrays["scene_signature"]),
                scene_parameters=tuple(arrays[f"scene_parameter_{i}"] for i in range(count)),
                record=str(arrays["record"]),
                section_rows=int(arrays["section_rows"]),
                records_from=int(arrays["records_from"]),
                result=arrays.get("result"),
            )
        except (KeyError, TypeError, ValueError) as error:
            raise ValueError(
                f"{path}: an incomplete checkpoint (missing or malformed {error}): not {what}, or damaged"
            ) from None


def _sync_directory(directory: Path) -> None:
    """Make a rename in ``directory`` durable (a power cut then keeps the new checkpoint)."""
    try:
        fd = os.open(directory, os.O_RDONLY)
    except OSError:  # a platform that cannot open directories
        return
    try:
        os.fsync(fd)
    except OSError:
        pass
    finally:
        os.close(fd)


def read_npy_header(path: Path) -> tuple[np.dtype, tuple[int, ...], int]:
    """``(dtype, shape, data offset)`` from an ``.npy`` file's header.

    Raises ``ValueError`` naming the file (``damaged``) for a missing file, a
    header that does not parse, or Fortran order. Whether the file's length
    fits its header is left to the caller, which knows whether the file grows.
    """
    try:
        with open(path, "rb") as f:
            version = np.lib.format.read_magic(f)
            read = np.lib.format.read_array_header_1_0 if version == (1, 0) else np.lib.format.read_array_header_2_0
            shape, fortran_order, dtype = read(f)
            offset = f.tell()
    except FileNotFoundError:
        raise damaged(path, "missing") from None
    except _UNREADABLE as error:
        raise damaged(path, f"not a readable .npy file ({type(error).__name__}: {error})") from None
    if fortran_order:
        raise damaged(path, "in Fortran order; jb.run writes C order")
    return np.dtype(dtype), tuple(shape), offset


# -- growing .npy files ----------------------------------------------------------

# Room for the header of a growing .npy file: a fixed size, so that rewriting the
# shape as rows are appended never moves the data. A multiple of 64 bytes keeps
# the data aligned as numpy's own writer does.
_GROWING_HEADER_BYTES = 128


def _npy_header(dtype: np.dtype, shape: tuple[int, ...]) -> bytes:
    """The header of a version 1.0 ``.npy`` file, padded to ``_GROWING_HEADER_BYTES``."""
    fields = {"descr": np.lib.format.dtype_to_descr(dtype), "fortran_order": False, "shape": shape}
    text = repr(fields).encode("latin1")
    prefix = b"\x93NUMPY\x01\x00"
    length = _GROWING_HEADER_BYTES - len(prefix) - 2
    if len(text) + 1 > length:
        raise ValueError(f"shape {shape} does not fit a {_GROWING_HEADER_BYTES}-byte .npy header")
    return prefix + length.to_bytes(2, "little") + text.ljust(length - 1) + b"\n"


class GrowingNpy:
    """An ``.npy`` file of rows ``(m, *row_shape)`` that grows by appending blocks of rows."""

    def __init__(self, path: Path, dtype, row_shape: tuple[int, ...], rows: int = 0, create: bool | None = None):
        """Open ``path`` holding its first ``rows`` rows; later ones (from a run killed
        after writing them but before its checkpoint) are cut off. ``create``
        (default: ``rows == 0``) starts an empty file; else the file must be one
        this class wrote, with at least ``rows`` rows (``ValueError`` naming it if not)."""
        self.path, self.dtype, self.row_shape = path, np.dtype(dtype), tuple(row_shape)
        self.row_bytes = self.dtype.itemsize * int(np.prod(self.row_shape, dtype=np.int64))
        self.rows = rows
        if create if create is not None else rows == 0:
            path.write_bytes(_npy_header(self.dtype, (0, *self.row_shape)))
            return
        dtype_found, shape, offset = read_npy_header(path)
        if dtype_found != self.dtype or shape[1:] != self.row_shape or offset != _GROWING_HEADER_BYTES:
            raise damaged(path, f"holds {dtype_found}{shape}; this run writes rows {self.dtype}{self.row_shape}")
        # Rows past the header's count may be there (a run killed between writing
        # a block and its header); rows short of the checkpoint's may not.
        present = (path.stat().st_size - offset) // max(self.row_bytes, 1)
        if min(shape[0], present) < rows:
            raise damaged(path, f"holds {min(shape[0], present)} rows; the checkpoint counts {rows}")
        self.cut(rows)

    def cut(self, rows: int) -> None:
        """Keep the first ``rows`` rows only (giving their disk space back)."""
        with open(self.path, "r+b") as f:
            f.truncate(_GROWING_HEADER_BYTES + rows * self.row_bytes)
            f.seek(0)
            f.write(_npy_header(self.dtype, (rows, *self.row_shape)))
        self.rows = rows

    def append(self, block: np.ndarray) -> None:
        """Append ``block`` ``(m, *row_shape)``. An ``OSError`` (e.g. a full disk)
        names the file; the rows counted (``self.rows``) are then those before."""
        block = np.ascontiguousarray(block, dtype=self.dtype)
        if block.shape[1:] != self.row_shape:
            raise ValueError(f"{self.path.name}: rows of shape {block.shape[1:]}, expected {self.row_shape}")
        rows = self.rows + block.shape[0]
        try:
            with open(self.path, "r+b") as f:
                f.seek(_GROWING_HEADER_BYTES + self.rows * self.row_bytes)
                f.write(block.tobytes())
                f.seek(0)
                f.write(_npy_header(self.dtype, (rows, *self.row_shape)))
        except OSError as error:
            raise OSError(error.errno, error.strerror, str(self.path)) from error
        # Counted only once the file is closed: a full disk may first show when
        # the buffer is written out there, and then these rows are not in it.
        self.rows = rows


def open_record(path: Path, dtype, shape: tuple[int, ...], create: bool) -> np.memmap:
    """A full-size ``.npy`` record as a writable memory map (created, or reopened on resume).

    On reopening, the header must say ``dtype`` and ``shape`` and the file's
    length must be exactly what the header promises (``ValueError`` naming the
    file otherwise), so a damaged or foreign file is never written into.
    """
    if create:
        return np.lib.format.open_memmap(path, mode="w+", dtype=dtype, shape=shape)
    found, found_shape, offset = read_npy_header(path)
    if found_shape != shape or found != np.dtype(dtype):
        if found == np.dtype(dtype) and len(found_shape) == len(shape):
            raise ValueError(
                f"{path} holds {found}{found_shape}, this run would write {np.dtype(dtype)}{shape}: the records "
                "of a run directory are sized for its n (and batch); resume it with the same n and states0, "
                f"or continue into a new directory with resume='{path.parent / CHECKPOINT_NAME}'"
            )
        raise damaged(path, f"holds {found}{found_shape}; this run writes {np.dtype(dtype)}{shape}")
    expected = offset + np.dtype(dtype).itemsize * int(np.prod(shape, dtype=np.int64))
    size = path.stat().st_size
    if size != expected:
        cut = "cut short" if size < expected else "longer than its header says"
        raise damaged(path, f"{size} bytes, {cut} (its header promises {expected})")
    return np.lib.format.open_memmap(path, mode="r+")
