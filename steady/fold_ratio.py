"""Redraw docs/figures/fold_ratio.png (docs/results.md §2): the rates of record against the slope
of the family files given, by `slippulse steady fold-ratio`.

    python steady/fold_ratio.py FAMILY.h5 [MORE.h5 ...]
"""
import sys

from slippulse.cli.app import main

if __name__ == "__main__":
    sys.exit(main(["steady", "fold-ratio", *sys.argv[1:],
                   "--figure", "docs/figures/fold_ratio.png"]))
