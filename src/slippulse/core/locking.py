"""The advisory lock every reader and writer of a slippulse file holds while it uses the file.

One exclusive lock per file, held on a hidden lock file beside it (``.NAME.lock``) through the
``filelock`` library (a maintained, cross-platform implementation of ``fcntl``/``msvcrt`` locks;
hand-written locking gets stale locks and forks wrong). A writer holds it for its whole
read-modify-write, so two writers never interleave and no update is lost; a reader holds it while
it reads, so it never sees a file half-way through a write. The lock is re-entrant within a
thread (a writer may read the file it is updating). In a directory where no lock file can be
created (read-only data), no process can write the file either, and readers go without.
"""
from __future__ import annotations

import os
from contextlib import contextmanager

import filelock

from .errors import SchemaError

#: Seconds a command waits for another process's lock before it gives up with an error naming
#: the file (``SLIPPULSE_LOCK_TIMEOUT`` overrides it).
LOCK_TIMEOUT = 600.0


def lock_path(path: str) -> str:
    """The lock file of ``path``: ``.NAME.lock`` in the same directory."""
    full = os.path.abspath(path)
    d, name = os.path.split(full)
    return os.path.join(d, f".{name}.lock")


def _timeout() -> float:
    try:
        return float(os.environ.get("SLIPPULSE_LOCK_TIMEOUT", LOCK_TIMEOUT))
    except ValueError:
        return LOCK_TIMEOUT


@contextmanager
def file_lock(path: str, *, required: bool = True):
    """Hold the exclusive lock of ``path`` for the block.

    ``required=False`` (readers): where the lock file cannot be created because the directory is
    not writable, go on without it (no writer can work there either). A lock held by another
    process longer than :data:`LOCK_TIMEOUT` raises :class:`SchemaError` naming the file.
    """
    lp = lock_path(path)
    d = os.path.dirname(lp)
    if not required and os.path.isdir(d) and not os.access(d, os.W_OK):
        yield
        return
    lock = filelock.FileLock(lp, timeout=_timeout(), is_singleton=True)
    try:
        lock.acquire()
    except filelock.Timeout:
        raise SchemaError(f"{path}: locked by another process for more than {_timeout():g} s "
                          f"(lock file {lp}); retry when it has finished") from None
    try:
        yield
    finally:
        lock.release()


def hold_exclusive(path: str, who: str) -> "filelock.BaseFileLock":
    """Take the lock of ``path`` without waiting and return it (release it with ``.release()``):
    for a writer that owns a file for a long time (a dynamic run owns its work file). A lock
    held by another process raises :class:`SchemaError` naming ``path`` and ``who`` holds it."""
    lock = filelock.FileLock(lock_path(path), timeout=0, is_singleton=True)
    try:
        lock.acquire()
    except filelock.Timeout:
        raise SchemaError(f"{path}: {who} is already writing it (lock {lock_path(path)}); "
                          "wait for it to finish") from None
    return lock
