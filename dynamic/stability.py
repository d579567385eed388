"""The instability study of docs/stability.md: steady family, one scan per τ_d, the report.

Run (from the repository root)::

    python dynamic/stability.py family     # the two families below (~1 min)
    slippulse steady family --from 1.2 --to 1.03 --step 0.005 --points 3000 --out runs/family_stab.h5
    slippulse steady family --from 1.3 --to 1.2 --step 0.01 --points 3000 --out runs/family_up.h5
    slippulse dynamic scan dynamic/scans/growth_td1.20.toml    # one command per row of the table
    slippulse dynamic scan dynamic/scans/growth_td1.10.toml
    slippulse dynamic scan dynamic/scans/growth_td1.05.toml
    slippulse dynamic scan dynamic/scans/growth_td1.03.toml
    python dynamic/stability.py report     # the table s(τ_d) and the figures of docs/stability.md

``family`` runs the two ``slippulse steady family`` commands (family_up.h5: the steady line's
other end; L has its minimum near 1.29 τ_min). ``report`` is ``slippulse dynamic growth-report``
on the four scans: the table of docs/stability.md and
docs/figures/stability_{growth,trajectories,modes,deviation}.png.
"""
from __future__ import annotations

import argparse
import os
import sys


FAMILY = "runs/family_stab.h5"
UPPER = "runs/family_up.h5"
SCANS = ("growth_td1.20", "growth_td1.10", "growth_td1.05", "growth_td1.03")
FIG_DIR = "docs/figures"


def family():
    from slippulse.cli.app import main
    for out, start, stop, step in ((FAMILY, "1.2", "1.03", "0.005"), (UPPER, "1.3", "1.2", "0.01")):
        rc = main(["steady", "family", "--from", start, "--to", stop, "--step", step,
                   "--points", "3000", "--out", out])
        if rc:
            return rc
    return 0


def report():
    from slippulse.cli.app import main
    return main(["dynamic", "growth-report", *(f"dynamic/scans/{n}.toml" for n in SCANS),
                 "--family", *[f for f in (FAMILY, UPPER) if os.path.exists(f)],
                 "--figdir", FIG_DIR])


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("what", choices=("family", "report"))
    a = ap.parse_args()
    return family() if a.what == "family" else report()


if __name__ == "__main__":
    sys.exit(main())
