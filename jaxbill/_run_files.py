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
import os
from pathlib import Path

import jax
import numpy as np

CHECKPOINT_NAME = "checkpoint.npz"
STATE_RECORD_NAMES = ("t", "contact", "state")
SECTION_RECORD_NAMES = ("section_point", "section_t", "section_collision", "section_orbit")
_FORMAT_VERSION = 1


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
    """

    state0: np.ndarray
    state: np.ndarray
    time: np.ndarray
    max_energy_error: np.ndarray
    contact_counts: np.ndarray
    contact_codes: np.ndarray
    collisions: int
    orbit_index: np.ndarray | None
    scene_signature: str
    scene_parameters: tuple
    record: str
    section_rows: int = 0
    records_from: int = 0

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
        for i, leaf in enumerate(self.scene_parameters):
            arrays[f"scene_parameter_{i}"] = leaf
        temporary = path.with_name(path.name + ".partial")
        with open(temporary, "wb") as f:
            np.savez(f, **arrays)
            f.flush()
            os.fsync(f.fileno())
        os.replace(temporary, path)

    @classmethod
    def load(cls, path: str | os.PathLike) -> Checkpoint:
        with np.load(path, allow_pickle=False) as f:
            if int(f["format_version"]) != _FORMAT_VERSION:
                raise ValueError(f"{path}: checkpoint format {int(f['format_version'])}, expected {_FORMAT_VERSION}")
            return cls(
                state0=f["state0"],
                state=f["state"],
                time=f["time"],
                max_energy_error=f["max_energy_error"],
                contact_counts=f["contact_counts"],
                contact_codes=f["contact_codes"],
                collisions=int(f["collisions"]),
                orbit_index=f["orbit_index"] if "orbit_index" in f.files else None,
                scene_signature=str(f["scene_signature"]),
                scene_parameters=tuple(f[f"scene_parameter_{i}"] for i in range(int(f["scene_parameter_count"]))),
                record=str(f["record"]),
                section_rows=int(f["section_rows"]),
                records_from=int(f["records_from"]),
            )


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

    def __init__(self, path: Path, dtype, row_shape: tuple[int, ...], rows: int = 0):
        """Open ``path`` holding its first ``rows`` rows; later ones (from a run killed
        after writing them but before its checkpoint) are cut off. ``rows = 0``
        starts an empty file."""
        self.path, self.dtype, self.row_shape = path, np.dtype(dtype), tuple(row_shape)
        self.row_bytes = self.dtype.itemsize * int(np.prod(self.row_shape, dtype=np.int64))
        self.rows = rows
        if rows == 0:
            path.write_bytes(_npy_header(self.dtype, (0, *self.row_shape)))
        else:
            with open(path, "r+b") as f:
                f.truncate(_GROWING_HEADER_BYTES + rows * self.row_bytes)
                f.seek(0)
                f.write(_npy_header(self.dtype, (rows, *self.row_shape)))

    def append(self, block: np.ndarray) -> None:
        block = np.ascontiguousarray(block, dtype=self.dtype)
        if block.shape[1:] != self.row_shape:
            raise ValueError(f"{self.path.name}: rows of shape {block.shape[1:]}, expected {self.row_shape}")
        with open(self.path, "r+b") as f:
            f.seek(_GROWING_HEADER_BYTES + self.rows * self.row_bytes)
            f.write(block.tobytes())
            self.rows += block.shape[0]
            f.seek(0)
            f.write(_npy_header(self.dtype, (self.rows, *self.row_shape)))


def open_record(path: Path, dtype, shape: tuple[int, ...], create: bool) -> np.memmap:
    """A full-size ``.npy`` record as a writable memory map (created, or reopened on resume)."""
    if create:
        return np.lib.format.open_memmap(path, mode="w+", dtype=dtype, shape=shape)
    record = np.lib.format.open_memmap(path, mode="r+")
    if record.shape != shape or record.dtype != np.dtype(dtype):
        raise ValueError(
            f"{path} holds {record.dtype}{record.shape}, this run would write {np.dtype(dtype)}{shape}: the records "
            "of a run directory are sized for its n; resume it with the same n, or continue into a new "
            "directory with resume=<old directory>/checkpoint.npz"
        )
    return record
