"""Redraws docs/figures/spectrum_growth.png (and spectrum_modes.png when a scan's pairs have
finished) and prints the spectrum tables of a family beside the SBI's rates:

    python steady/spectrum_report.py runs/steady/family.h5          # seconds

is ``slippulse dynamic spectrum-report FAMILY.h5 --sbi-rates dynamic/results/sbi_growth_rates.toml
--scans SCAN.toml ... --figdir docs/figures`` on the scans of this study that exist
(dynamic/scans/growth_td1.04.toml, eigen_modes.toml, eigen_check_td1.20.toml).
"""
import os
import sys

from slippulse.cli.app import main

SCANS = [f"dynamic/scans/{n}.toml" for n in ("growth_td1.04", "eigen_modes", "eigen_check_td1.20")]

if __name__ == "__main__":
    scans = [s for s in SCANS if os.path.exists(s)]
    sys.exit(main(["dynamic", "spectrum-report", *sys.argv[1:],
                   "--sbi-rates", "dynamic/results/sbi_growth_rates.toml", "--figdir",
                   "docs/figures"] + (["--scans", *scans] if scans else [])))
