"""Carry the deep march from one machine (or session) to the next: the deepest converged pulses
of a family file copied into a small seed file, plus a table of every pulse of the family.

    python steady/deep_seed.py FAMILY.h5 SEED.h5 [--keep 2] [--table TABLE.csv]

The family command resumes below the deepest converged pulse of its --out file, with the pace,
the secant predictor and the held steps of the pulse above it (docs/steady.md §3), so a file holding only those two
pulses is enough to go on:

    cp SEED.h5 runs/deep.h5
    slippulse steady family --from 1.2 --to 1.0080 --out runs/deep.h5 --max-length 12000

The table (label, tau_d_ratio, beta, L in m, N, grid-check figures) keeps the rest of the family
for the divergence fits (steady/divergence.py reads family files; the table is for the record).
Seconds to run.
"""
import argparse
import csv
import os
import sys

sys.path.insert(0, os.path.join(os.path.dirname(os.path.abspath(__file__)), "..", "src"))

from slippulse.core.h5io import list_pulses, read_pulse, write_pulse  # noqa: E402

COLUMNS = ("label", "tau_d_ratio", "beta", "L", "n_points", "continuation", "grid_check_passed",
           "grid_check_n", "grid_check_n_fine", "grid_check_dbeta", "grid_check_dL_rel")


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("family")
    ap.add_argument("seed")
    ap.add_argument("--keep", type=int, default=2, help="deepest converged pulses to copy (default 2)")
    ap.add_argument("--table", default="", help="CSV of every pulse of FAMILY (default: none)")
    a = ap.parse_args(argv)
    if a.keep < 1:
        ap.error("--keep must be >= 1")
    if os.path.exists(a.seed):
        ap.error(f"{a.seed} exists; the seed is written to a new file")
    pulses = [read_pulse(a.family, lab) for lab in list_pulses(a.family)]
    done = [(p, par) for p, par in pulses if p.converged]
    if not done:
        ap.error(f"{a.family}: no converged pulse")
    deepest = sorted(done, key=lambda pp: pp[0].tau_d_ratio)[:a.keep]
    for p, par in reversed(deepest):
        write_pulse(a.seed, p, par)
    if a.table:
        with open(a.table, "w", newline="") as fh:
            w = csv.DictWriter(fh, fieldnames=list(COLUMNS), extrasaction="ignore")
            w.writeheader()
            for p, _ in pulses:
                row = {k: p.extra.get(k, "") for k in COLUMNS}
                row.update(label=p.label, tau_d_ratio=repr(float(p.tau_d_ratio)),
                           beta=repr(float(p.beta)), L=repr(float(p.L)), n_points=len(p.xi))
                w.writerow(row)
    p = deepest[0][0]
    print(f"{a.seed}: {len(deepest)} pulses, deepest {p.label} (L = {p.L:.1f} m, beta = "
          f"{p.beta:.7f}); {len(pulses)} pulses in {a.family}"
          + (f", table {a.table}" if a.table else ""))


if __name__ == "__main__":
    main()
