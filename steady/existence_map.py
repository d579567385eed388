"""Redraw docs/figures/existence_map.png from a map file written by `slippulse steady
existence-map --out MAP.h5` (docs/results.md §1).

    python steady/existence_map.py MAP.h5
"""
import sys

from slippulse.plotting.existence_map import plot_existence_map
from slippulse.steady.existence_map import read_map

if __name__ == "__main__":
    plot_existence_map(read_map(sys.argv[1]), "docs/figures/existence_map.png")
