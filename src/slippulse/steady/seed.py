"""Carry a deep march from one machine or session to the next (docs/steady.md §3): the deepest
converged pulses of a family file copied into a small seed file, and a CSV table of every pulse.

`slippulse steady family` resumes below the deepest converged pulse of its --out file with the
pace, secant predictor and held steps of the pulse above it, so a file of those two pulses is
enough to go on; the table (read back by :func:`.divergence.read_points`) keeps the rest of the
family for the fits.
"""
from __future__ import annotations

import csv
import os

from ..core.h5io import list_pulses, read_pulse, write_pulse

#: Columns of a family table.
COLUMNS = ("label", "tau_d_ratio", "beta", "L", "n_points", "continuation", "grid_check_passed",
           "grid_check_n", "grid_check_n_fine", "grid_check_dbeta", "grid_check_dL_rel")


def write_seed(family, seed, keep=2):
    """Copy the ``keep`` deepest converged pulses of ``family`` into the new file ``seed``;
    return them (deepest first). ValueError if ``seed`` exists or there is no converged pulse."""
    if keep < 1:
        raise ValueError(f"keep={keep!r}: must be >= 1")
    if os.path.exists(seed):
        raise ValueError(f"{seed!r} exists; the seed is written to a new file")
    done = [(p, par) for p, par in (read_pulse(family, lab) for lab in list_pulses(family))
            if p.converged]
    if not done:
        raise ValueError(f"{family!r} holds no converged pulse")
    deepest = sorted(done, key=lambda pp: pp[0].tau_d_ratio)[:keep]
    for p, par in reversed(deepest):
        write_pulse(seed, p, par)
    return [p for p, _ in deepest]


def write_table(family, path):
    """Write every pulse of ``family`` as a row of :data:`COLUMNS` to the CSV ``path``; return
    the number of rows."""
    pulses = [read_pulse(family, lab)[0] for lab in list_pulses(family)]
    with open(path, "w", newline="") as fh:
        w = csv.DictWriter(fh, fieldnames=list(COLUMNS), extrasaction="ignore")
        w.writeheader()
        for p in pulses:
            row = {k: p.extra.get(k, "") for k in COLUMNS}
            row.update(label=p.label, tau_d_ratio=repr(float(p.tau_d_ratio)),
                       beta=repr(float(p.beta)), L=repr(float(p.L)), n_points=len(p.xi))
            w.writerow(row)
    return len(pulses)
