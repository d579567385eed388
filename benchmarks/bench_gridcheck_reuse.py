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
import sys

from _gridcheck_compare import compare, parse_args


def main(argv=None):
    a = parse_args(__doc__, argv, repeat=2)
    compare(a.family, a.labels, a.repeat,
            [("reuse=False", lambda: {"reuse": False}), ("reuse=True", lambda: {"reuse": True})])
    return 0


if __name__ == "__main__":
    sys.exit(main())
