"""The grid check with and without the creep stop of its first Newton solve, side by side in one
run.

    python benchmarks/bench_gridcheck_creep.py FAMILY.h5 LABEL [LABEL ...] [--repeat 1]

For each pulse of the family file: the nested check as the family runs it
(:func:`slippulse.steady.continuation.gridcheck.grid_change`, ``nested=True``, ``stages=4``,
``max_iter=15``, LU reuse on) with ``homotopy.CREEP = 0`` (before: the plain Newton solve runs
its 15 iterations before the residual homotopy takes over) and with the default creep stop
(:data:`slippulse.steady.continuation.homotopy.CREEP`), alternated ``--repeat`` times. Prints
per run: wall, Newton iterations of all solves, the check's Δβ and ΔL/L; then the ratio of the
median walls and the largest difference between the two fine solutions. A pulse whose first
solve converges without creeping runs the same way in both (ratio ≈ 1). Minutes at N ≈ 3500.
"""
import argparse
import sys
import time

import numpy as np

from slippulse.core.h5io import read_pulse
import slippulse.steady.continuation.homotopy as homotopy
from slippulse.steady.continuation.gridcheck import as_both, grid_change
from slippulse.steady.solver import resolve_on_grid


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("family")
    ap.add_argument("labels", nargs="+")
    ap.add_argument("--repeat", type=int, default=1)
    a = ap.parse_args(argv)
    creep_now = homotopy.CREEP
    for lab in a.labels:
        pulse, params = read_pulse(a.family, lab)
        sol = as_both(params, resolve_on_grid(params, pulse, pulse.xi))
        print(f"{lab}: N = {pulse.xi.size}, L = {pulse.L:.5g} m, beta = {pulse.beta:.7f}; "
              f"pulse re-solved on its grid: {sol.stats.message}", flush=True)
        walls = {0: [], creep_now: []}
        fines = {}
        for _ in range(a.repeat):
            for creep in (0, creep_now):
                homotopy.CREEP = creep
                t0 = time.perf_counter()
                fine, db, dl = grid_change(params, sol, pulse.xi.size, nested=True, max_iter=15,
                                           stages=4)
                w = time.perf_counter() - t0
                walls[creep].append(w)
                fines[creep] = fine
                st = fine.stats
                print(f"  creep={creep}: wall {w:7.1f} s, Newton iterations {st.iterations} "
                      f"({st.message[:40]}), dbeta {db:+.3e}, dL/L {dl:+.4e}", flush=True)
        homotopy.CREEP = creep_now
        x0, x1 = fines[0].x, fines[creep_now].x
        print(f"  median wall {np.median(walls[0]):.1f} s -> {np.median(walls[creep_now]):.1f} s: "
              f"{np.median(walls[0]) / np.median(walls[creep_now]):.2f}x; fine solutions differ "
              f"by max|d ln v| {np.abs(x1[:-2] - x0[:-2]).max():.1e}, dbeta "
              f"{abs(x1[-2] - x0[-2]):.1e}, dq {abs(x1[-1] - x0[-1]):.1e}", flush=True)
    return 0


if __name__ == "__main__":
    sys.exit(main())
