"""Shared by the grid-check benchmarks (bench_gridcheck_reuse.py, bench_gridcheck_creep.py,
bench_gridcheck_homotopy_first.py): their command line, and one pulse's nested check run under
two settings, alternated, side by side in one process."""
import argparse
import time

import numpy as np

from slippulse.core.h5io import read_pulse
from slippulse.steady.continuation.gridcheck import as_both, grid_change
from slippulse.steady.solver import resolve_on_grid


def parse_args(doc, argv=None, repeat=1):
    """The benchmarks' command line: FAMILY.h5 LABEL [LABEL ...] [--repeat N] (default `repeat`);
    the description is the first paragraph of `doc`."""
    ap = argparse.ArgumentParser(description=doc.split("\n\n")[0])
    ap.add_argument("family")
    ap.add_argument("labels", nargs="+")
    ap.add_argument("--repeat", type=int, default=repeat)
    return ap.parse_args(argv)


def compare(family, labels, repeat, variants):
    """For each pulse of ``family``: the check as the family runs it (:func:`grid_change`,
    ``nested=True``, ``stages=4``, ``max_iter=15``) under each of the two ``variants``, a list of
    (name, setup) with ``setup()`` → the extra keyword arguments of :func:`grid_change` (and any
    module setting it changes, which the caller restores), alternated ``repeat`` times. Prints per
    run: wall, Newton iterations (LUs), chord iterations, Δβ and ΔL/L; then the ratio of the
    median walls (first variant over second) and the largest difference between the two fine
    solutions (max|Δ ln v|, Δβ, Δq)."""
    (name0, _), (name1, _) = variants
    for lab in labels:
        pulse, params = read_pulse(family, lab)
        sol = as_both(params, resolve_on_grid(params, pulse, pulse.xi))
        print(f"{lab}: N = {pulse.xi.size}, L = {pulse.L:.5g} m, beta = {pulse.beta:.7f}; "
              f"pulse re-solved on its grid: {sol.stats.message}", flush=True)
        walls = {name0: [], name1: []}
        fines = {}
        for _ in range(repeat):
            for name, setup in variants:
                kw = setup()
                t0 = time.perf_counter()
                fine, db, dl = grid_change(params, sol, pulse.xi.size, nested=True, max_iter=15,
                                           stages=4, **kw)
                w = time.perf_counter() - t0
                walls[name].append(w)
                fines[name] = fine
                st = fine.stats
                print(f"  {name}: wall {w:7.1f} s, Newton iterations (LUs) {st.iterations}, "
                      f"chord iterations {st.chord_iterations}, converged {st.converged}, "
                      f"max|r| {st.max_residual:.1e}; dbeta {db:+.3e}, dL/L {dl:+.4e}",
                      flush=True)
        x0, x1 = fines[name0].x, fines[name1].x
        w0, w1 = np.median(walls[name0]), np.median(walls[name1])
        print(f"  median wall {w0:.1f} s -> {w1:.1f} s: {w0 / w1:.2f}x; fine solutions differ by "
              f"max|d ln v| {np.abs(x1[:-2] - x0[:-2]).max():.1e}, dbeta "
              f"{abs(x1[-2] - x0[-2]):.1e}, dq {abs(x1[-1] - x0[-1]):.1e}", flush=True)
