"""Grid checks beside the march: the grid checks of a family run in a second process while the
march goes on; the test functions and the writes stay in the march's process, in order.

Why: beyond 2 km a written pulse's check at 2N − 1 points takes more than half of a one-core
march (about 50 s of a pulse's 85 s at N = 7647, docs/steady.md "Cost"), and the march needs
nothing from a check unless the check refines the grid. Then the march goes back to the refined
pulse and its steps beyond are dropped unwritten (:meth:`~.driver.Continuation.step`). One
worker process keeps the checks in order and holds the last check's LU (about 1 GB at
2N − 1 = 15 293) for the next one's warm start. A single stateful worker fed in order is a pipeline stage, not a parallel map,
so it is a ``concurrent.futures`` process pool of one rather than the Dask executor of the
commands that map over pulses. ``threadpoolctl`` gives each process an equal share of the BLAS
threads at run time (an environment variable acts only before numpy loads).
"""
from __future__ import annotations

import concurrent.futures as cf
import multiprocessing
import os
import signal
import threading
import time
from dataclasses import replace as dc_replace

import numpy as np

from ..equations import SteadyProblem
from ..solver import SteadySolution
from .driver import Accepted
from .gridcheck import monitor_first


def pack(sol: SteadySolution) -> tuple:
    """A solution without its N × N Hilbert matrix and LU (rebuilt by :func:`unpack`: 1.6 s at
    N = 7647, against 470 MB to send)."""
    pb = sol.problem
    return (pb.tau_d_ratio, np.asarray(pb.xi), pb.pin_index, pb.y_pin, pb.hilbert, pb.free,
            pb.beta_fixed, pb.state_order, np.asarray(sol.x),
            dc_replace(sol.stats, lu=None, jacobian=None), sol.wall_time, sol.passes,
            sol.tangent)


def unpack(params, packed) -> SteadySolution:
    q, xi, k, ypin, hil, free, beta, order, x, stats, wall, passes, tangent = packed
    prob = SteadyProblem(params, q, xi, k, ypin, hilbert=hil, free=free, beta=beta,
                         state_order=order)
    return SteadySolution(prob, x, stats, wall, passes, tangent)


# ------------------------------------------------------------------ the worker process
#: How the worker starts: forked where the platform can (it starts at once, with the parent's
#: modules and compiled kernels, and a caller's script needs no ``__main__`` guard), else spawned.
START = "fork" if "fork" in multiprocessing.get_all_start_methods() else "spawn"

_CHECKER = None


def _start_worker(checker, threads, parent):
    """The worker's initializer: its checker, its BLAS threads, and an exit when the march's
    process is gone (a killed run leaves no checker behind). Ctrl-C is the march's to handle
    (it stops the worker): the worker ignores SIGINT and prints no traceback of its own."""
    global _CHECKER
    _CHECKER = checker
    signal.signal(signal.SIGINT, signal.SIG_IGN)
    from threadpoolctl import threadpool_limits
    threadpool_limits(threads)

    def watch():
        while os.getppid() == parent:
            time.sleep(1.0)
        os._exit(0)
    threading.Thread(target=watch, daemon=True).start()


def _check(packed, method, extra):
    """One check in the worker: (passed, message, pulse to write, the refined solution packed
    or None, the log lines)."""
    lines = []
    ch = _CHECKER
    ch.log = lines.append
    sol = unpack(ch.params, packed)
    res, p = ch(sol, method, extra)
    # the pulse comes back only where the check replaced it (refined, or N doubled)
    return res.passed, res.message, p, pack(res.sol) if res.replaced else None, lines


# ------------------------------------------------------------------ the march's side
class Pending:
    """A pulse handed to the checks, not yet written. :meth:`result` waits for its check,
    writes it and returns :class:`~.driver.Accepted`; :meth:`discard` drops it unwritten (the
    march went back before it)."""

    def __init__(self, writer, future, sol, attrs, previous):
        self.writer, self.future, self.sol = writer, future, sol
        self.attrs, self.previous = attrs, previous     # the monitor's, and its neighbour

    def done(self) -> bool:
        return self.future.done()

    def result(self) -> Accepted:
        passed, message, p, refined, lines = self.future.result()
        w = self.writer
        for line in lines:
            if w.log:
                w.log(line)
        sol = self.sol if refined is None else unpack(w.params, refined)
        attrs = self.attrs
        if refined is not None and w.monitor is not None:
            # the check wrote another pulse than the one monitored: its own test functions,
            # after the same neighbour; it is the next pulse's neighbour
            if hasattr(w.monitor, "previous"):
                w.monitor.previous = self.previous
            attrs = w.monitor(sol, p)
        p.extra.update(attrs or {})
        w.put(p, message)
        return Accepted(bool(passed), sol, message)

    def discard(self) -> None:
        self.future.cancel()


class BesideWriter:
    """The checked writer of a family run with its :class:`~.family.Checker` in a second
    process: a call hands the pulse over and returns a :class:`Pending` at once. The monitor
    (the test functions) stays in the march's process, on the pulse handed, to share a written
    pulse's work more evenly (at N = 7647, one core each: 34–73 s of checking against two
    steps of 17 s and 15 s of test functions)."""

    def __init__(self, writer, threads=None):
        self.base = writer
        self.params, self.log = writer.params, writer.log
        cpus = os.cpu_count() or 1
        share = max(1, cpus // 2) if threads is None else int(threads)
        from threadpoolctl import threadpool_limits
        self._limits = threadpool_limits(share)
        checker = writer.check
        self.monitor, checker.monitor, checker.log = checker.monitor, None, None
        self.pool = cf.ProcessPoolExecutor(
            max_workers=1, mp_context=multiprocessing.get_context(START),
            initializer=_start_worker, initargs=(checker, share, os.getpid()))

    def put(self, p, message=""):
        self.base.put(p, message)

    def __call__(self, sol, pulse, method, extra=None) -> Pending:
        attrs, previous = monitor_first(self.monitor, sol, pulse)
        fut = self.pool.submit(_check, pack(sol), method, extra)
        if attrs is None:
            previous = getattr(self.monitor, "previous", None)
            attrs = self.monitor(sol, pulse) if self.monitor is not None else {}
        return Pending(self, fut, sol, attrs, previous)

    def close(self) -> None:
        """Stop the worker (queued checks are dropped) and give the BLAS threads back."""
        self.pool.shutdown(wait=True, cancel_futures=True)
        self._limits.restore_original_limits()
