"""Redraws docs/figures/attractor_overlap.png (docs/stability.md §4) from overlap tables:

    slippulse dynamic attractor overlap FAMILY.h5 --local-h 2e-3 --csv OUT.csv     # per family
    python dynamic/attractor.py OUT.csv [...] [--names NAME ...] [--pairs SCAN_DIR ...]

is ``slippulse dynamic attractor figure docs/figures/attractor_overlap.png --csv OUT.csv ...``
(``slippulse dynamic attractor --help``: the pairs against their mode, the runs' distance from
the steady line).
"""
import sys

from slippulse.cli.app import main

if __name__ == "__main__":
    sys.exit(main(["dynamic", "attractor", "figure", "docs/figures/attractor_overlap.png",
                   "--csv", *sys.argv[1:]]))
