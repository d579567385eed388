"""Redraw docs/figures/motion_trajectories.png (docs/results.md §3): the fate runs against the
equation of motion, by `slippulse dynamic fate-compare` (which also prints the table).

    python dynamic/motion.py --family family_up.h5 family.h5 --runs FATE.h5 [...] [--law ...]
"""
import sys

from slippulse.cli.app import main

if __name__ == "__main__":
    sys.exit(main(["dynamic", "fate-compare", "docs/figures/motion_trajectories.png",
                   *sys.argv[1:]]))
