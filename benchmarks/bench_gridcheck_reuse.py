"""The grid check's re-solve at 2N − 1 points with and without reusing each Newton step's LU,
side by side in one run.

    python benchmarks/bench_gridcheck_reuse.py FAMILY.h5 LABEL [LABEL ...] [--repeat 2]

For each pulse of the family file: the pulse re-solved on its own grid (converged already: one
Newton pass), then the nested check (:func:`slippulse.steady.continuation.gridcheck.grid_change`,
``nested=True``, ``stages=4``, ``max_iter=15``: as the family's check runs it) with ``reuse=False`` (the code before stop 34)
and ``reuse=True``, alternated ``--repeat`` times. Prints per run: wall, Newton iterations (LUs),
chord iterations, and Δβ, ΔL/L of the check; then the ratio of the median walls and the largest
difference between the two fine solutions (max|Δ ln v|, Δβ, Δq). Minutes at N ≈ 3500.
"""
import argparse
import sys
import time

import numpy as np

from slippulse.core.h5io import read_pulse
from slippulse.steady.continuation.gridcheck import as_both, grid_change
from slippulse.steady.solver import resolve_on_grid


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("family")
    ap.add_argument("labels", nargs="+")
    ap.add_argument("--repeat", type=int, default=2)
    a = ap.parse_args(argv)
    for lab in a.labels:
        pulse, params = read_pulse(a.family, lab)
        sol = as_both(params, resolve_on_grid(params, pulse, pulse.xi))
        print(f"{lab}: N = {pulse.xi.size}, L = {pulse.L:.5g} m, beta = {pulse.beta:.7f}; "
              f"pulse re-solved on its grid: {sol.stats.message}", flush=True)
        walls = {False: [], True: []}
        fines = {}
        for rep in range(a.repeat):
            for reuse in (False, True):
                t0 = time.perf_counter()
                fine, db, dl = grid_change(params, sol, pulse.xi.size, nested=True, max_iter=15,
                                           stages=4, reuse=reuse)
                w = time.perf_counter() - t0
                walls[reuse].append(w)
                fines[reuse] = fine
                st = fine.stats
                print(f"  reuse={reuse!s:5}: wall {w:7.1f} s, Newton iterations (LUs) "
                      f"{st.iterations}, chord iterations {st.chord_iterations}, converged "
                      f"{st.converged}, max|r| {st.max_residual:.1e}; dbeta {db:+.2e}, "
                      f"dL/L {dl:+.2e}", flush=True)
        x0, x1 = fines[False].x, fines[True].x
        print(f"  median wall {np.median(walls[False]):.1f} s -> {np.median(walls[True]):.1f} s: "
              f"{np.median(walls[False]) / np.median(walls[True]):.2f}x; fine solutions differ by "
              f"max|d ln v| {np.abs(x1[:-2] - x0[:-2]).max():.1e}, dbeta {abs(x1[-2] - x0[-2]):.1e}, "
              f"dq {abs(x1[-1] - x0[-1]):.1e}", flush=True)
    return 0


if __name__ == "__main__":
    sys.exit(main())
