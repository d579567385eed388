"""The grid check started with plain Newton or with the homotopy, side by side in one run.

    python benchmarks/bench_gridcheck_homotopy_first.py FAMILY.h5 LABEL [LABEL ...] [--repeat 1]

For each pulse of the family file: the nested check as the family runs it (:func:`grid_change`,
``nested=True``, ``stages=4``, ``max_iter=15``, LU reuse and the creep stop on) with
``plain=True`` (plain Newton first, the homotopy after it creeps) and ``plain=False`` (the
homotopy from the start: what the family asks for on the HOMOTOPY_FIRST checks after one that
crept, ``family._CheckedWriter``). Prints per run: wall, Newton iterations, chord iterations, the
check's Δβ and ΔL/L; then the ratio of the median walls and the largest difference between the
two fine solutions. Where the plain solve converges without creeping, plain first is the faster
(the ratio is below 1): the family tries it again every HOMOTOPY_FIRST + 1 checks. Minutes at
N ≈ 3500.
"""
import sys

from _gridcheck_compare import compare, parse_args


def main(argv=None):
    a = parse_args(__doc__, argv, repeat=1)
    compare(a.family, a.labels, a.repeat,
            [("plain first", lambda: {"plain": True}),
             ("homotopy first", lambda: {"plain": False})])
    return 0


if __name__ == "__main__":
    sys.exit(main())
