"""The spectrum of several pulses on one process and on K worker processes, side by side in one
run (issue 17, item 5; stop 37).

    python benchmarks/bench_spectrum_workers.py FAMILY.h5 LABEL [LABEL ...] [--workers K]
        [--guess S]

``run_spectrum`` as ``slippulse steady stability FILE --labels ... [--guess S]`` runs it, on a
fresh copy of the family file each time: first with one process (the pulses one after another,
each tracked from the one above), then with ``--workers K`` (K contiguous runs at once, one
thread each; the runs after the first start from the default search, below 1e-3 c_p/L by the sign
of det M). Prints the wall time of each, their ratio, and per pulse the two rates s L/c_p ± err
and their difference in units of the error (the same pulse on the same grids: equal to Newton's
tolerance where both find the same eigenvalue). The ratio is at most K, less the cost of the
runs' starts without tracking, and needs K free cores: report the machine's load beside it.
"""
import argparse
import os
import shutil
import tempfile
import time

from slippulse.core.executor import ExecutorSettings
from slippulse.spectrum.family import SpectrumSettings, run_spectrum


def one(family, labels, guess, workers):
    tmp = tempfile.mkdtemp(prefix="bench_workers_")
    try:
        path = os.path.join(tmp, "f.h5")
        shutil.copy(family, path)
        t0 = time.perf_counter()
        rep = run_spectrum(path, SpectrumSettings(extra=False), labels=labels, guess=guess, executor=ExecutorSettings(workers=workers))
        wall = time.perf_counter() - t0
    finally:
        shutil.rmtree(tmp, ignore_errors=True)
    return wall, {r.label: r for r in rep.results}


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("family")
    ap.add_argument("labels", nargs="+")
    ap.add_argument("--workers", type=int, default=2)
    ap.add_argument("--guess", type=float, default=None)
    a = ap.parse_args()
    print(f"load average before: {os.getloadavg()}")
    w1, r1 = one(a.family, a.labels, a.guess, 1)
    print(f"1 process: {w1:.1f} s")
    wk, rk = one(a.family, a.labels, a.guess, a.workers)
    print(f"{a.workers} workers: {wk:.1f} s")
    print(f"ratio (1 process / {a.workers} workers): {w1 / wk:.2f}x")
    for lab in a.labels:
        x, y = r1.get(lab), rk.get(lab)
        if x is None or y is None or x.refined is None or y.refined is None:
            print(f"{lab}: {getattr(x, 'status', '-')} / {getattr(y, 'status', '-')}")
            continue
        u1, uk = x.refined.s / x.refined.rate_unit, y.refined.s / y.refined.rate_unit
        e = max(x.refined.s_err / x.refined.rate_unit, 1e-300)
        print(f"{lab}: s L/c_p = {u1:.7g} ± {e:.1g} | {uk:.7g}; difference "
              f"{abs(u1 - uk) / e:.1e} err")
    print(f"load average after: {os.getloadavg()}")


if __name__ == "__main__":
    main()
