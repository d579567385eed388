"""A file object for an HDF5 library that is writing a large file directly (a dynamic run's
work file): a write the disk refuses is recorded, not returned to the library.

When a write fails inside HDF5 (a full disk), HDF5 is left with metadata it cannot flush, and
the objects that h5py frees afterwards raise in their finalizers and can crash the interpreter.
:class:`GuardedFile` keeps that failure out of HDF5: it reports success, remembers the first
``OSError`` (and drops every later write), and :meth:`GuardedFile.check` raises it, naming the
file, at the points where the writer can stop cleanly (after a snapshot, before a checkpoint is
published). The file is then discarded; what it holds after the failure is never used.
"""
from __future__ import annotations

import os


class GuardedFile:
    """``open(path, mode)`` (a binary update mode) for h5py's ``fileobj`` driver; see module
    docstring."""

    def __init__(self, path: str, mode: str = "w+b"):
        self.path = path
        self._fh = open(path, mode, buffering=0)
        self.error: OSError | None = None

    def _fail(self, exc: OSError) -> None:
        if self.error is None:
            self.error = exc

    def readable(self):
        return True

    def writable(self):
        return True

    def seekable(self):
        return True

    def seek(self, pos, whence=0):
        return self._fh.seek(pos, whence)

    def tell(self):
        return self._fh.tell()

    def readinto(self, buf):
        return self._fh.readinto(buf)

    def read(self, size=-1):
        return self._fh.read(size)

    def write(self, data):
        mv = memoryview(data).cast("B")
        n = mv.nbytes
        done = 0
        if self.error is None:
            try:
                while done < n:
                    got = self._fh.write(mv[done:])
                    if not got:
                        raise OSError(28, "No space left on device")
                    done += got
                return n
            except OSError as exc:
                self._fail(exc)
        self._fh.seek(n - done, 1)
        return n

    def truncate(self, size=None):
        if self.error is None:
            try:
                return self._fh.truncate(size)
            except OSError as exc:
                self._fail(exc)
        return size

    def flush(self):
        if self.error is None:
            try:
                self._fh.flush()
            except OSError as exc:
                self._fail(exc)

    @property
    def closed(self):
        return self._fh.closed

    def sync(self) -> None:
        """Flush and fsync (the data on disk before the file is published); failures recorded."""
        self.flush()
        if self.error is None:
            try:
                os.fsync(self._fh.fileno())
            except OSError as exc:
                self._fail(exc)

    def close(self):
        try:
            self._fh.close()
        except OSError as exc:
            self._fail(exc)

    def check(self) -> None:
        """Raise the recorded write failure as an ``OSError`` naming the file."""
        if self.error is not None:
            exc = self.error
            raise OSError(exc.errno, exc.strerror or str(exc), self.path)
