"""Atomic replacement of an output file: write beside it, flush to disk, rename over it.

Every writer of the package that replaces a file whole (the HDF5 writers of :mod:`.h5io`, the
count checkpoint, the scan tables, the perturbation results, the FFTW wisdom) goes through
:func:`replacing`: the content goes to a temporary file in the target's directory (so that the
rename stays on one file system), which is fsync'ed and then renamed over the target with
``os.replace`` (atomic on POSIX). A writer that raises, or is interrupted by Ctrl-C, leaves the
previous file as it was and removes its temporary file; after a kill -9 a hidden
``.tmp-NAME-*`` file may remain beside the target: nothing reads it, and the next locked writer
of the target removes it (:func:`remove_stale_temporaries`).
"""
from __future__ import annotations

import os
import tempfile
from contextlib import contextmanager

from .killpoint import kill_point


def output_mode(path: str) -> int:
    """Permission bits of a file written to ``path``: those of the file it replaces, else what
    ``open`` would give a new file (0o666 less the umask; ``mkstemp`` alone gives 0o600)."""
    try:
        return os.stat(path).st_mode & 0o7777
    except OSError:
        mask = os.umask(0)
        os.umask(mask)
        return 0o666 & ~mask


def temp_prefix(path: str) -> str:
    """Name prefix of the temporary files that replace ``path`` (``.tmp-NAME-``): a writer that
    holds the file's lock knows any such file is a killed writer's and removes it."""
    return f".tmp-{os.path.basename(path)}-"


def remove_stale_temporaries(path: str) -> None:
    """Remove the temporary files a killed writer of ``path`` left (call under its lock)."""
    d = os.path.dirname(os.path.abspath(path))
    prefix = temp_prefix(path)
    try:
        names = os.listdir(d)
    except OSError:
        return
    for name in names:
        if name.startswith(prefix):
            try:
                os.remove(os.path.join(d, name))
            except OSError:
                pass


@contextmanager
def replacing(path: str, suffix: str = ""):
    """Yield the path of a new, empty temporary file beside `path`; on a clean exit its content
    replaces `path` (fsync, permissions of the file replaced, ``os.replace``); on an exception
    the temporary file is removed and `path` is left as it was.

    `suffix` ends the temporary name (e.g. ``.h5``, for libraries that look at it).
    """
    path = os.path.abspath(path)
    fd, tmp = tempfile.mkstemp(prefix=temp_prefix(path), suffix=suffix,
                               dir=os.path.dirname(path))
    os.close(fd)
    try:
        yield tmp
        with open(tmp, "rb+") as fh:
            os.fsync(fh.fileno())
        kill_point("replacement_written")
        os.chmod(tmp, output_mode(path))
        os.replace(tmp, path)
    except BaseException:
        if os.path.exists(tmp):
            os.remove(tmp)
        raise


@contextmanager
def replacing_open(path: str, mode: str = "w", **kwargs):
    """``open`` on a temporary file that replaces `path` when the block ends without an
    exception (:func:`replacing`); `mode` is a writing mode ('w', 'wb')."""
    if not mode.startswith("w"):
        raise ValueError(f"mode={mode!r}: replacing_open writes a new file ('w' or 'wb')")
    with replacing(path) as tmp:
        with open(tmp, mode, **kwargs) as fh:
            yield fh


def read_only(path: str) -> bool:
    """Whether an existing file is read-only: no write permission for this process, or no write
    bit at all (a file its owner marked read-only is not replaced, even by root, who may
    write anything)."""
    try:
        mode = os.stat(path).st_mode
    except OSError:
        return False
    return not os.access(path, os.W_OK) or not mode & 0o222


def save_figure(fig, path: str, **kwargs) -> None:
    """``fig.savefig(path, **kwargs)`` through :func:`replacing`: a full disk or an interrupt
    leaves the previous figure (or none), never an empty or truncated one. The format is taken
    from the extension of ``path`` (the temporary file's name has the same one)."""
    ext = os.path.splitext(path)[1]
    kwargs.setdefault("format", ext.lstrip(".").lower() or None)
    with named_errors(path):
        with replacing(path, suffix=ext) as tmp:
            fig.savefig(tmp, **kwargs)


@contextmanager
def named_errors(path: str):
    """Re-raise an ``OSError`` of the block (a full disk, a permission) as one that names
    ``path``, the file the user asked for, rather than a temporary file or nothing."""
    try:
        yield
    except OSError as exc:
        if exc.filename == path:
            raise
        raise OSError(exc.errno, exc.strerror or str(exc), path) from None
