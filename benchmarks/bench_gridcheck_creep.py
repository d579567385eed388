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
import sys

import slippulse.steady.continuation.homotopy as homotopy
from _gridcheck_compare import compare, parse_args


def main(argv=None):
    a = parse_args(__doc__, argv, repeat=1)
    creep_now = homotopy.CREEP

    def creep(value):
        def setup():
            homotopy.CREEP = value
            return {}
        return setup

    try:
        compare(a.family, a.labels, a.repeat,
                [("creep=0", creep(0)), (f"creep={creep_now}", creep(creep_now))])
    finally:
        homotopy.CREEP = creep_now
    return 0


if __name__ == "__main__":
    sys.exit(main())
