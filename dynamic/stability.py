"""The instability study of docs/stability.md: steady family, one scan per τ_d, the report.

Run (from the repository root)::

    python dynamic/stability.py family     # runs/family_stab.h5: 1.2 → 1.03 τ_min, N = 3000 (~1 min),
                                           # runs/family_up.h5: 1.3 → 1.2 (the steady line's other end)
    slippulse dynamic scan dynamic/scans/growth_td1.20.toml    # one command per row of the table
    slippulse dynamic scan dynamic/scans/growth_td1.10.toml
    slippulse dynamic scan dynamic/scans/growth_td1.05.toml
    slippulse dynamic scan dynamic/scans/growth_td1.03.toml
    python dynamic/stability.py report     # the table s(τ_d) and the figures of docs/stability.md

``report`` is ``slippulse dynamic growth-report`` on the four scans: the table of docs/stability.md
and docs/figures/stability_{growth,trajectories,modes,deviation}.png.
"""
from __future__ import annotations

import argparse
import os
import sys


FAMILY = "runs/family_stab.h5"
UPPER = "runs/family_up.h5"          # the branch 1.3 → 1.2 τ_min (L has its minimum near 1.29)
SCANS = ("growth_td1.20", "growth_td1.10", "growth_td1.05", "growth_td1.03")
FIG_DIR = "docs/figures"


def family():
    from slippulse.steady.continuation import run_family
    from slippulse.core.params import DEFAULT
    print(run_family(DEFAULT, FAMILY, start=1.2, stop=1.03, step=0.005, n_points=3000))
    print(run_family(DEFAULT, UPPER, start=1.3, stop=1.2, step=0.01, n_points=3000))


def report():
    from slippulse.cli.app import main
    return main(["dynamic", "growth-report", *(f"dynamic/scans/{n}.toml" for n in SCANS),
                 "--family", *[f for f in (FAMILY, UPPER) if os.path.exists(f)],
                 "--figdir", FIG_DIR])


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("what", choices=("family", "report"))
    a = ap.parse_args()
    if a.what == "family":
        family()
        return 0
    return report()


if __name__ == "__main__":
    sys.exit(main())
