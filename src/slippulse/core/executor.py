"""One executor for independent work: in this process, on a local Dask cluster, or on a Dask
scheduler given by its address.

Every command that runs independent tasks (the family spectrum, the count's determinants, the
existence map's solves, a scan's cases) takes the same ``--workers N`` / ``--scheduler ADDRESS``
(:func:`add_executor_options`), turns them into :class:`ExecutorSettings`, and runs its tasks
through :class:`TaskPool`:

- ``workers = 1`` and no scheduler: the tasks run here, one after the other, in the order given
  (no process is started; a test or a debugger sees plain calls);
- ``workers = N > 1``: a ``distributed.LocalCluster`` of N worker processes, one task at a time
  each, with ``threads`` BLAS/OpenMP/numba threads per process;
- ``scheduler = ADDRESS``: a ``distributed.Client`` on that scheduler (its workers, whatever their
  number; ``workers`` is then not used).

Dask's futures interface (``Client.submit`` and ``distributed.as_completed``) is used, not
``dask.delayed`` or bags: the tasks are coarse (seconds to minutes each), their results are
written by this process as each arrives (one writer per file, so a kill loses at most the tasks
in flight and a rerun resumes from what was written), and some commands submit the next task from
the result of the last (the spectrum tracks each pulse from its neighbour). ``as_completed``
takes tasks added while it is iterated; cancelling the futures on exit stops a cluster's work.
"""
from __future__ import annotations

import collections
import logging
import sys
from dataclasses import dataclass

from .errors import UsageError

#: The thread variables a worker process reads when it imports numpy and numba.
THREAD_VARS = ("OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS", "NUMBA_NUM_THREADS")
#: Largest --workers and --threads accepted.
MAX_WORKERS = 256


@dataclass(frozen=True)
class ExecutorSettings:
    """Where independent tasks run (see the module notes).

    Attributes
    ----------
    workers : int
        Worker processes of a local cluster (1: in this process, no cluster).
    scheduler : str or None
        Address of a Dask scheduler ('tcp://host:8786'), or None for the local choice.
    threads : int
        BLAS/OpenMP/numba threads of each local worker process.
    processes : bool
        Local cluster of processes (default); False: worker threads of this process (cheap to
        start; for tests, or work that releases the GIL).
    """

    workers: int = 1
    scheduler: str | None = None
    threads: int = 1
    processes: bool = True

    def __post_init__(self):
        for name in ("workers", "threads"):
            v = getattr(self, name)
            if isinstance(v, bool) or not isinstance(v, int) or not 1 <= v <= MAX_WORKERS:
                raise UsageError(f"--{name}={v!r} is invalid: must be an integer in "
                                 f"[1, {MAX_WORKERS}]")
        if self.scheduler is not None and not (isinstance(self.scheduler, str)
                                               and self.scheduler.strip()):
            raise UsageError(f"--scheduler={self.scheduler!r} is invalid: must be a scheduler "
                             "address such as tcp://host:8786")

    @property
    def parallel(self) -> bool:
        """Whether the tasks leave this process's main thread (a cluster or a scheduler)."""
        return self.workers > 1 or self.scheduler is not None

    def __str__(self):
        if self.scheduler is not None:
            return f"Dask scheduler at {self.scheduler}"
        if self.workers == 1:
            return "serial (this process)"
        kind = "processes" if self.processes else "threads"
        return (f"local Dask cluster of {self.workers} {kind}"
                + (f" x {self.threads} threads" if self.processes else ""))


def add_executor_options(p, what="tasks") -> None:
    """The options ``--workers N``, ``--threads T`` and ``--scheduler ADDRESS`` on parser `p`."""
    p.add_argument("--workers", type=int, default=1, metavar="N",
                   help=f"run the {what} on a local Dask cluster of N worker processes "
                        "(default 1: in this process)")
    p.add_argument("--threads", type=int, default=1, metavar="T",
                   help="BLAS, OpenMP and numba threads of each local worker (default 1; keep "
                        "N x T within the cores)")
    p.add_argument("--scheduler", metavar="ADDRESS", default=None,
                   help=f"run the {what} on the Dask cluster of this scheduler (e.g. "
                        "tcp://host:8786; --workers and --threads are then the cluster's)")


def settings_from_args(args) -> ExecutorSettings:
    """:class:`ExecutorSettings` of the options of :func:`add_executor_options` (UsageError,
    naming the option and its range, on bad values)."""
    return ExecutorSettings(workers=args.workers, scheduler=args.scheduler,
                            threads=getattr(args, "threads", 1))


def progress_bar(total, desc, unit, initial=0, disable=False):
    """The progress bar of every parallel command: tqdm on stderr, refreshed at most every
    0.5 s on a terminal and every 10 s into a file or pipe (a log stays short)."""
    from tqdm import tqdm
    return tqdm(total=total, initial=initial, desc=desc, unit=unit, disable=disable,
                file=sys.stderr, mininterval=0.5 if sys.stderr.isatty() else 10.0)


class _Done:
    """A finished serial task: the handle :meth:`TaskPool.submit` returns without a cluster."""

    __slots__ = ("fn", "args", "kwargs")

    def __init__(self, fn, args, kwargs):
        self.fn, self.args, self.kwargs = fn, args, kwargs


class TaskPool:
    """Independent tasks on :class:`ExecutorSettings`' executor; a context manager.

    ``submit(fn, *args)`` returns a handle; ``completed()`` yields ``(handle, value, error)`` as
    tasks finish (``error`` the exception the task raised, else None), including tasks submitted
    while it is iterated. Serially the tasks run in submission order inside ``completed()``. On
    exit the tasks not finished are cancelled and a cluster started here is closed.

    ``client`` : an open ``distributed.Client`` to use instead (left open on exit).
    """

    def __init__(self, settings: ExecutorSettings | None = None, client=None):
        self.settings = settings if settings is not None else ExecutorSettings()
        self.client = client
        self._own = []                          # what __exit__ closes (client, cluster)
        self._queue = collections.deque()       # serial: tasks not yet run
        self._ac = None                         # Dask: distributed.as_completed
        self._futures = []

    @property
    def parallel(self) -> bool:
        return self.client is not None or self.settings.parallel

    @property
    def n_workers(self) -> int:
        """Tasks that run at once: 1 serially, else the cluster's workers (at least 1)."""
        if self.client is None:
            return 1
        try:
            return max(1, len(self.client.scheduler_info()["workers"]))
        except Exception:                       # noqa: BLE001 - a scheduler without info
            return max(1, self.settings.workers)

    def __enter__(self):
        if self.client is None and self.settings.parallel:
            self.client = _start_client(self.settings, self._own)
        if self.client is not None:
            from distributed import as_completed
            self._ac = as_completed()
        return self

    def __exit__(self, *exc):
        if self._futures and self.client is not None:
            pending = [f for f in self._futures if not f.done()]
            if pending:
                self.client.cancel(pending)
        self._futures = []
        self._queue.clear()
        for obj in reversed(self._own):
            try:
                obj.close()
            except Exception:                   # noqa: BLE001 - closing after an interrupt
                pass
        self._own = []
        return False

    def scatter(self, obj):
        """`obj` placed once on every worker (a large argument of many tasks); serially, itself."""
        if self.client is None:
            return obj
        return self.client.scatter(obj, broadcast=True, hash=False)

    def submit(self, fn, *args, **kwargs):
        """Queue ``fn(*args, **kwargs)``; returns its handle."""
        if self.client is None:
            task = _Done(fn, args, kwargs)
            self._queue.append(task)
            return task
        fut = self.client.submit(fn, *args, pure=False, **kwargs)
        self._futures.append(fut)
        self._ac.add(fut)
        return fut

    def completed(self):
        """Yield ``(handle, value, error)`` as the tasks finish (see the class notes)."""
        if self.client is None:
            while self._queue:
                task = self._queue.popleft()
                try:
                    value, err = task.fn(*task.args, **task.kwargs), None
                except Exception as exc:             # noqa: BLE001 - handed to the caller
                    value, err = None, exc
                yield task, value, err
            return
        for fut in self._ac:
            try:
                value, err = fut.result(), None
            except Exception as exc:                 # noqa: BLE001 - e.g. KilledWorker
                value, err = None, exc
            self._futures = [f for f in self._futures if f is not fut]
            yield fut, value, err

    def map(self, fn, items, *args):
        """``{item: fn(item, *args)}`` over `items` (the first error raised once all are done)."""
        handles = {self.submit(fn, item, *args): item for item in items}
        out, first = {}, None
        for h, value, err in self.completed():
            if err is not None and first is None:
                first = err
            out[handles.pop(h)] = value
        if first is not None:
            raise first
        return out


def _start_client(settings: ExecutorSettings, own: list):
    """A Client on the scheduler of `settings`, or on a local cluster started for it."""
    try:
        from distributed import Client, LocalCluster
    except ImportError:                               # pragma: no cover - a core dependency
        raise UsageError("--workers > 1 and --scheduler need dask.distributed: "
                         "pip install 'dask[distributed]'") from None
    if settings.scheduler is not None:
        try:
            client = Client(settings.scheduler, timeout="30s")
        except (OSError, TimeoutError) as exc:
            raise UsageError(f"--scheduler={settings.scheduler!r}: no Dask scheduler answers "
                             f"there ({type(exc).__name__}: {exc})") from None
        own.append(client)
        return client
    kwargs = dict(n_workers=settings.workers, threads_per_worker=1,
                  processes=settings.processes, dashboard_address=":0",   # any free port
                  silence_logs=logging.ERROR)
    if settings.processes:
        # each worker process reads its thread count when it imports numpy and numba
        kwargs["env"] = {k: str(settings.threads) for k in THREAD_VARS}
    cluster = LocalCluster(**kwargs)
    own.append(cluster)
    client = Client(cluster)
    own.append(client)
    return client
