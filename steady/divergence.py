"""Redraw the figures of the deep family in docs/figures: divergence_deep.png and
local_exponents_deep.png from the committed tables (and any family FILEs given), by
`slippulse steady divergence`; with FILEs, edges_deep.png and edge_profiles.png from their
pulses, by `slippulse steady edges`.

    python steady/divergence.py [FAMILY.h5 ...]
"""
import glob
import sys

from slippulse.cli.app import main

TABLES = sorted(glob.glob("steady/seeds/deep_family_*.csv"))
FIG = "docs/figures/"

if __name__ == "__main__":
    files = sys.argv[1:]
    rc = main(["steady", "divergence", *files, "--table", *TABLES,
               "--figure", FIG + "divergence_deep.png",
               "--exponents-figure", FIG + "local_exponents_deep.png"])
    if files and rc == 0:
        rc = main(["steady", "edges", *files, "--figure", FIG + "edges_deep.png",
                   "--profiles-figure", FIG + "edge_profiles.png"])
    sys.exit(rc)
