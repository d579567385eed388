"""In-place update of an existing file through a write-ahead journal: crash-safe, and costing
the bytes changed, not the size of the file.

:class:`JournaledFile` is the binary file object an HDF5 library writes through (h5py's
``fileobj`` driver): reads come from the file, every write goes to an in-memory overlay of
whole pages. :meth:`JournaledFile.commit` then

1. writes the changed pages and the new length to ``.NAME.journal`` beside the file, with a
   SHA-256 trailer, and fsyncs it (the commit point);
2. reserves the file's new length (``posix_fallocate``: a full disk fails here, before the file
   is touched), writes the pages into the file and fsyncs it;
3. removes the journal.

A kill before step 1 ends leaves the file as it was and a torn journal that :func:`recover`
deletes; a kill after it leaves a complete journal that :func:`recover` replays (the replay is
idempotent). Every opener calls :func:`recover` under the file's lock
(:mod:`slippulse.core.locking`) before it reads. Appending a pulse to a 200 MB file writes the
pulse and a few pages of metadata, not a 200 MB copy.
"""
from __future__ import annotations

import errno
import hashlib
import os
import struct

from .errors import SchemaError
from .killpoint import kill_point

#: Points of :meth:`JournaledFile.commit` where ``SLIPPULSE_KILL_AT`` (:mod:`.killpoint`) kills
#: the writer: inside the journal (torn), after it (committed, file untouched), half-way through
#: writing the file.
KILL_POINTS = ("journal_torn", "journal_written", "file_half_written")

PAGE = 4096
_MAGIC = b"SLPJRNL2"
_HEAD = struct.Struct("<8sQQQQ")    # magic, original size, kept prefix, new size, number of pages
_REC = struct.Struct("<Q")               # page index (followed by PAGE bytes)


def journal_path(path: str) -> str:
    full = os.path.abspath(path)
    d, name = os.path.split(full)
    return os.path.join(d, f".{name}.journal")


def _fsync_dir(d: str) -> None:
    try:
        fd = os.open(d, os.O_RDONLY)
    except OSError:
        return
    try:
        os.fsync(fd)
    except OSError:
        pass
    finally:
        os.close(fd)


class JournaledFile:
    """A file opened for update whose writes stay in memory until :meth:`commit` (module
    docstring). The target must be writable: it is opened ``r+b`` at once, so a read-only file
    fails here, before anything is done."""

    def __init__(self, path: str):
        self.path = path
        self._fh = open(path, "r+b")
        self._size = self._orig = os.fstat(self._fh.fileno()).st_size
        #: bytes of the original file still in use: a truncation below it zeroes what follows
        self._limit = self._orig
        self._pos = 0
        self._pages: dict[int, bytearray] = {}

    # -- the file-object protocol h5py's fileobj driver uses
    def readable(self):
        return True

    def writable(self):
        return True

    def seekable(self):
        return True

    def tell(self):
        return self._pos

    def seek(self, pos, whence=0):
        if whence == 0:
            self._pos = pos
        elif whence == 1:
            self._pos += pos
        else:
            self._pos = self._size + pos
        return self._pos

    def _page(self, k: int) -> bytes:
        got = self._pages.get(k)
        if got is not None:
            return got
        start = k * PAGE
        if start >= self._limit:
            return bytes(PAGE)
        data = os.pread(self._fh.fileno(), min(PAGE, self._limit - start), start)
        return data + bytes(PAGE - len(data))

    def readinto(self, buf) -> int:
        mv = memoryview(buf).cast("B")
        n = max(0, min(len(mv), self._size - self._pos))
        done = 0
        while done < n:
            k, off = divmod(self._pos + done, PAGE)
            take = min(PAGE - off, n - done)
            mv[done:done + take] = self._page(k)[off:off + take]
            done += take
        self._pos += n
        return n

    def read(self, size=-1) -> bytes:
        if size is None or size < 0:
            size = max(0, self._size - self._pos)
        buf = bytearray(size)
        n = self.readinto(buf)
        return bytes(buf[:n])

    def write(self, data) -> int:
        mv = memoryview(data).cast("B")
        done = 0
        while done < len(mv):
            k, off = divmod(self._pos + done, PAGE)
            take = min(PAGE - off, len(mv) - done)
            page = self._pages.get(k)
            if page is None:
                page = self._pages[k] = bytearray(self._page(k))
            page[off:off + take] = mv[done:done + take]
            done += take
        self._pos += len(mv)
        self._size = max(self._size, self._pos)
        return len(mv)

    def truncate(self, size=None):
        size = self._pos if size is None else size
        if size < self._size:
            last = size // PAGE
            for k in [k for k in self._pages if k > last]:
                del self._pages[k]
            tail = size - last * PAGE
            if tail or last in self._pages:
                page = self._pages.get(last)
                if page is None:
                    page = self._pages[last] = bytearray(self._page(last))
                page[tail:] = bytes(PAGE - tail)
            self._limit = min(self._limit, size)
        self._size = size
        return size

    def flush(self):
        pass

    @property
    def closed(self):
        return self._fh.closed

    def close(self):
        """Drop the overlay without writing it (a failed update)."""
        self._pages.clear()
        if not self._fh.closed:
            self._fh.close()

    # -- the commit
    def commit(self) -> int:
        """Write the overlay to the file through the journal (module docstring). Returns the
        bytes written to the journal. Any OSError leaves the file as it was (before the commit
        point) or with a complete journal that the next :func:`recover` replays."""
        if not self._pages and self._size == self._orig == self._limit:
            self.close()
            return 0
        jp = journal_path(self.path)
        body = bytearray(_HEAD.pack(_MAGIC, self._orig, self._limit, self._size,
                                    len(self._pages)))
        for k in sorted(self._pages):
            body += _REC.pack(k) + self._pages[k]
        body += hashlib.sha256(body).digest()
        try:
            with open(jp, "wb") as jf:
                half = len(body) // 2
                jf.write(body[:half])
                jf.flush()
                kill_point("journal_torn")
                jf.write(body[half:])
                jf.flush()
                os.fsync(jf.fileno())
        except BaseException:
            _remove(jp)
            self.close()
            raise
        _fsync_dir(os.path.dirname(jp))
        kill_point("journal_written")
        fd = self._fh.fileno()
        if self._size > self._orig:
            try:
                os.posix_fallocate(fd, self._orig, self._size - self._orig)
            except OSError as exc:
                if exc.errno not in (errno.EOPNOTSUPP, errno.EINVAL, errno.ENOSYS):
                    try:                              # nothing of the file written yet: undo
                        os.ftruncate(fd, self._orig)
                    finally:
                        _remove(jp)
                        self.close()
                    raise
        try:
            _apply(fd, self._pages.items(), self._limit, self._size)
        finally:
            self.close()
        _remove(jp)
        return len(body)


def _apply(fd: int, pages, limit: int, size: int) -> None:
    """Write ``pages`` into the file: first cut it to the ``limit`` bytes still in use (what
    lies beyond was truncated and reads as zeros), then the pages, then the new ``size``."""
    pages = list(pages)
    if limit < os.fstat(fd).st_size:
        os.ftruncate(fd, limit)
    for i, (k, data) in enumerate(pages):
        if i == len(pages) // 2:
            kill_point("file_half_written")
        end = min(PAGE, max(0, size - k * PAGE))
        if end:
            os.pwrite(fd, bytes(data[:end]), k * PAGE)
    os.ftruncate(fd, size)
    os.fsync(fd)


def _remove(p: str) -> None:
    try:
        os.remove(p)
    except FileNotFoundError:
        pass


def recover(path: str) -> str:
    """Finish or discard an update of ``path`` that a kill interrupted (call it under the file's
    lock). Returns 'none', 'discarded' (a torn journal: the file was never touched) or
    'replayed'. A complete journal that cannot be replayed (read-only file, full disk) raises
    :class:`SchemaError` naming the file; the journal is kept for a later attempt."""
    jp = journal_path(path)
    if not os.path.exists(jp):
        return "none"
    try:
        with open(jp, "rb") as jf:
            body = jf.read()
    except OSError as exc:
        raise SchemaError(f"{path}: cannot read its journal {jp} ({exc.strerror})") from None
    ok = len(body) >= _HEAD.size + 32 and hashlib.sha256(body[:-32]).digest() == body[-32:]
    if ok:
        magic, _orig, limit, size, n = _HEAD.unpack_from(body)
        ok = magic == _MAGIC and len(body) == _HEAD.size + n * (_REC.size + PAGE) + 32
    if not ok:
        try:
            os.remove(jp)
        except OSError as exc:
            raise SchemaError(f"{path}: cannot remove the torn journal {jp} "
                              f"({exc.strerror})") from None
        return "discarded"
    pages = []
    at = _HEAD.size
    for _ in range(n):
        (k,) = _REC.unpack_from(body, at)
        pages.append((k, body[at + _REC.size:at + _REC.size + PAGE]))
        at += _REC.size + PAGE
    try:
        fd = os.open(path, os.O_RDWR)
    except OSError as exc:
        raise SchemaError(f"{path}: an interrupted update must be completed from {jp} but the "
                          f"file cannot be opened for writing ({exc.strerror})") from None
    try:
        _apply(fd, pages, limit, size)
    except OSError as exc:
        raise SchemaError(f"{path}: cannot complete an interrupted update from {jp} "
                          f"({exc.strerror})") from None
    finally:
        os.close(fd)
    os.remove(jp)
    return "replayed"
