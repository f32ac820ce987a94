"""What keeps a run directory whole under ordinary faults: one writer, space up front, stop signals.

``jb.run(..., out=D)`` promises that nothing is lost and that a resumed run is
bitwise the uninterrupted one. Three things outside the arithmetic can break
that promise, and this module guards against each:

* a second writer: ``DirectoryLock`` holds an OS lock (``fcntl.flock``) on a
  lock file in ``D`` for the whole call; the OS drops it when the process
  ends, however it ends, so a crashed run never leaves ``D`` locked;
* a full disk: ``check_space`` and ``reserve`` make the full-size records
  (memory maps, where a page that cannot be backed is a ``SIGBUS``, not an
  exception) take their disk blocks before the first collision;
* a stop signal: ``StopSignals`` turns ``SIGTERM`` and ``SIGINT`` into a request
  that the run loop honours at the next chunk boundary, after writing a
  checkpoint (``RunInterrupted`` for ``SIGTERM``, ``KeyboardInterrupt`` for ``SIGINT``).
"""

from __future__ import annotations

import errno
import inspect
import os
import shutil
import signal
import socket
import sys
import threading
from collections.abc import Callable
from pathlib import Path
from types import FrameType
from typing import Any

import jax
import numpy as np

try:
    import fcntl
except ImportError:  # not on Windows: runs there go unlocked (README, "Long runs")
    fcntl = None

LOCK_NAME = ".jaxbill.lock"
# Errors of posix_fallocate that mean "this filesystem cannot reserve", not "no room".
_CANNOT_RESERVE = {errno.EOPNOTSUPP, errno.ENOSYS, errno.EINVAL, getattr(errno, "ENOTSUP", errno.EOPNOTSUPP)}
_NO_ROOM = {errno.ENOSPC, errno.EFBIG, getattr(errno, "EDQUOT", errno.ENOSPC)}


class RunInterrupted(SystemExit):
    """``jb.run(..., out=D)`` was stopped by ``SIGTERM``; ``D/checkpoint.npz`` holds its last complete chunk.

    A subclass of ``SystemExit``, because a ``SIGTERM`` asks the process to end:
    ``except Exception`` (e.g. a loop that logs a failed run and goes on to the
    next) does not swallow it, ``finally`` blocks run, and uncaught it ends the
    process with status ``128 + SIGTERM = 143``, what a scheduler expects of a
    process it stopped. Catch it by name (``except jb.RunInterrupted``) to do
    something else; continue the run with ``jb.run(..., out=D, resume=True)``.

    Attributes:
        signal: the signal's number (``signal.SIGTERM``).
        out: the run directory ``D``.
        collisions: collisions per orbit that its checkpoint holds.
        message: what happened and what to do, as ``str(error)``.
    """

    def __init__(self, message: str, signal_number: int, out: Path, collisions: int):
        super().__init__(128 + signal_number)
        self.message, self.signal, self.out, self.collisions = message, signal_number, out, collisions

    def __str__(self) -> str:
        return self.message


# -- one writer ------------------------------------------------------------------------


class DirectoryLock:
    """An exclusive ``fcntl.flock`` on ``directory/.jaxbill.lock``, held until ``release``.

    The lock belongs to the open file, so the OS releases it when the process
    dies, even by ``SIGKILL``; the file left behind then locks nothing. The
    file records the holder (``pid <pid> on <host>``) for the error message of
    whoever finds the directory locked.
    """

    def __init__(self, directory: Path):
        self.directory, self.path, self.fd = directory, directory / LOCK_NAME, None

    def acquire(self) -> None:
        if fcntl is None:
            return
        while True:
            fd = os.open(self.path, os.O_RDWR | os.O_CREAT, 0o644)
            try:
                fcntl.flock(fd, fcntl.LOCK_EX | fcntl.LOCK_NB)
            except BlockingIOError:
                holder = os.pread(fd, 200, 0).decode("utf-8", "replace").strip()
                os.close(fd)
                raise ValueError(
                    f"{self.directory} is in use by another jb.run ({holder or 'a process that is starting'}, "
                    f"per its lock file {self.path}): one run directory takes one writer. Wait for that run "
                    "to end (resume=True then continues it, if it stopped early), or write into another "
                    "directory. Reading its files (np.load, jb.Checkpoint.load) needs no lock."
                ) from None
            except BaseException:
                os.close(fd)
                raise
            # The holder unlinks the file just before it lets go: if that happened
            # between our open and our flock, we hold a lock on a file nobody else
            # will open, so try again on the file that is there now.
            try:
                here = os.stat(self.path)
            except FileNotFoundError:
                here = None
            mine = os.fstat(fd)
            if here is not None and (here.st_dev, here.st_ino) == (mine.st_dev, mine.st_ino):
                break
            os.close(fd)
        os.ftruncate(fd, 0)
        os.pwrite(fd, f"pid {os.getpid()} on {socket.gethostname()}\n".encode(), 0)
        self.fd = fd

    def release(self) -> None:
        if self.fd is None:
            return
        # Unlink while still holding the lock (see acquire), so that a finished
        # run directory holds only its records and checkpoint.
        try:
            os.unlink(self.path)
        except OSError:
            pass
        os.close(self.fd)
        self.fd = None


# -- disk space ------------------------------------------------------------------------


def free_bytes(directory: Path) -> int:
    """Bytes an unprivileged process may still write on ``directory``'s filesystem."""
    return shutil.disk_usage(directory).free


def unallocated_bytes(path: Path) -> int:
    """Bytes of ``path``'s length that have no disk blocks yet (a sparse file's holes)."""
    status = os.stat(path)
    return max(0, status.st_size - getattr(status, "st_blocks", status.st_size // 512) * 512)


def no_room(directory: Path, needed: int, free: int, what: str) -> OSError:
    return OSError(
        errno.ENOSPC,
        f"jb.run: {what} in {directory} needs {needed} bytes ({needed / 2**20:.1f} MiB) of disk, and "
        f"{free} bytes ({free / 2**20:.1f} MiB) are free there; nothing was run. Free some space, write "
        "into a directory on a larger filesystem, or record less (a larger every=, or record='final')",
        str(directory),
    )


def check_space(directory: Path, needed: int, what: str) -> None:
    """Raise ``OSError(ENOSPC)`` saying how much is needed and free if ``needed`` bytes do not fit."""
    free = free_bytes(directory)
    if needed > free:
        raise no_room(directory, needed, free, what)


def reserve(path: Path, size: int, what: str) -> None:
    """Give the first ``size`` bytes of ``path`` their disk blocks now (``posix_fallocate``).

    A memory-mapped record written into a hole when the disk is full kills the
    process with ``SIGBUS``; a reserved one cannot run out of room. Data already
    in the file is kept. Where the filesystem cannot reserve (no
    ``posix_fallocate``, or it answers ``EOPNOTSUPP``), the free-space check
    made before (``check_space``) is the only guard.
    """
    if not hasattr(os, "posix_fallocate") or size == 0:
        return
    fd = os.open(path, os.O_RDWR)
    try:
        os.posix_fallocate(fd, 0, size)
    except OSError as error:
        if error.errno in _CANNOT_RESERVE:
            return
        if error.errno in _NO_ROOM:
            raise no_room(path.parent, unallocated_bytes(path), free_bytes(path.parent), what) from error
        raise
    finally:
        os.close(fd)


# -- stop signals ----------------------------------------------------------------------


class StopSignals:
    """While active (a context manager), ``SIGTERM`` and ``SIGINT`` only ask the run to stop.

    The run loop reads ``requested`` at each chunk boundary and, if set, writes
    a checkpoint and calls ``stop``. Handlers are installed only from the main
    thread (Python allows no other) and only over a signal that is not ignored
    (``SIG_IGN`` stays as it was). A handler of the user's that was there
    before is called by ``stop``, once the checkpoint is written and the
    previous handlers are back, with the signal's number; if it raises, its
    exception ends the call. A second ``SIGINT`` (Ctrl-C twice) stops at once,
    without a new checkpoint.
    """

    SIGNALS = (signal.SIGINT, signal.SIGTERM)

    def __init__(self):
        # signal -> the handler before ours, as signal.getsignal gives it
        self.previous: dict[int, Callable[[int, FrameType | None], Any] | int | signal.Handlers | None] = {}
        self.active = False
        self.requested: int | None = None
        self.handled = False  # stop() has acted on the request

    def __enter__(self) -> StopSignals:
        if threading.current_thread() is not threading.main_thread():
            return self
        for number in self.SIGNALS:
            handler = signal.getsignal(number)
            if handler is signal.SIG_IGN or handler is None:
                continue
            self.previous[number] = handler
            signal.signal(number, self._handle)
        self.active = True
        return self

    def __exit__(self, *exc) -> None:
        self.restore()

    def restore(self) -> None:
        if self.active:
            for number, handler in self.previous.items():
                signal.signal(number, handler)
            self.active = False

    def _handle(self, number: int, frame) -> None:
        if self.requested == signal.SIGINT and number == signal.SIGINT:
            raise KeyboardInterrupt(
                "jb.run: Ctrl-C twice: stopped at once, without a new checkpoint; the run directory's "
                "checkpoint.npz still holds the last one written, and resume=True continues from it"
            )
        if self.requested is None:
            self.requested = number

    def stop(self, message: str, out: Path, collisions: int):
        """Restore the previous handlers, run the user's own one, then raise for the signal received."""
        number, self.handled = self.requested, True
        if number is None:
            raise RuntimeError("StopSignals.stop: no signal was received")
        self.restore()
        user = self.previous.get(number)
        if callable(user) and user is not signal.default_int_handler:
            user(number, inspect.currentframe())
        if number == signal.SIGINT:
            raise KeyboardInterrupt(message)
        raise RunInterrupted(message, number, out, collisions)


def agreed(*flags: bool) -> tuple[bool, ...]:
    """Each flag or-ed over the processes of a ``jax.distributed`` run (they run one
    program together, so all must stop, or checkpoint, after the same chunk)."""
    if jax.process_count() == 1:
        return tuple(bool(flag) for flag in flags)
    from jax.experimental import multihost_utils

    gathered = multihost_utils.process_allgather(np.asarray(flags, dtype=np.int32))
    return tuple(bool(value) for value in np.max(np.reshape(gathered, (-1, len(flags))), axis=0))


class RunGuard:
    """The lock and the stop-signal handlers of one ``jb.run(..., out=D)`` call (a
    context manager); with ``directory=None`` (no run directory) it does nothing."""

    def __init__(self, directory: Path | None):
        self.directory, self.lock, self.signals, self.created = directory, None, StopSignals(), False

    def __enter__(self) -> RunGuard:
        if self.directory is None:
            return self
        self.created = not self.directory.exists()
        self.directory.mkdir(parents=True, exist_ok=True)
        self.lock = DirectoryLock(self.directory)
        self.lock.acquire()
        try:
            self.signals.__enter__()
        except BaseException:
            self.lock.release()
            raise
        return self

    def __exit__(self, *exc) -> None:
        # A signal that came after the last chunk's check (during the final
        # checkpoint, say) was not acted on: deliver it to the previous handler.
        pending = self.signals.requested if not self.signals.handled else None
        self.signals.restore()
        if self.lock is not None:
            self.lock.release()
        if self.created and self.directory is not None:
            try:
                self.directory.rmdir()  # only if empty: a call that failed before writing leaves nothing
            except OSError:
                pass
        if pending is not None:
            signal.raise_signal(pending)

    def stop_requested(self) -> bool:
        return self.signals.requested is not None

    def stop(self, done: int, n: int, saved: Path):
        """End the call after a stop signal; ``saved``: the checkpoint just written at collision ``done``."""
        number = self.signals.requested
        if number is None:  # only another process of a jax.distributed run was signalled
            number, cause = signal.SIGTERM, "another process of this jax.distributed run was stopped"
        else:
            cause = f"stopped by {signal.Signals(number).name}"
        self.signals.requested = number
        message = (
            f"jb.run: {cause} after collision {done} of {n}; {saved} holds the run up to there. "
            "Continue it with the same arguments and resume=True: the result is bitwise the uninterrupted run"
        )
        if number == signal.SIGTERM:
            # Uncaught, RunInterrupted ends the process silently (status 143): say it in the log.
            print(message, file=sys.stderr, flush=True)
        # signals are caught only around a run directory (see __enter__)
        assert self.directory is not None
        self.signals.stop(message, self.directory, done)
