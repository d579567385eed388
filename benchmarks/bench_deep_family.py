"""Deep-family benchmark: the product command from scratch to L ≥ 1.5 km, every pulse grid-checked.

Run:  python benchmarks/bench_deep_family.py [--out /tmp/bench_deep.h5] [--to 1.009]
          [--max-length 1500] [--reuse]

Times ``slippulse steady family --from 1.2 --to TO --max-length L --out OUT`` (a subprocess, as a
user runs it) from an empty file, records the machine load (``os.getloadavg``) before and after,
and prints from the file: pulses written, grid checks passed/failed, the deepest pulse (τ_d/τ_min,
β, L), the largest |Δβ| and |ΔL|/L of the checks, and the N used per deep pulse.

Side by side: the driver route of issue 11 (``slippulse steady family --to 1.010`` stopped near
1.0120, then ``steady/deep_march.py ... td1.0125 --resolve 2000 --stretch --check --max-points
8000 --max-length 1500`` and ``steady/body_refine.py`` on the 8 steps that missed the L
criterion) is not rerun here: its code is gone (body_refine.py) or now calls the same library.
Its measured times are in docs/analysis.md and BENCHMARKS.md (≈ 1 min family + 1272 s march at
"""
from __future__ import annotations

import argparse
import os
import subprocess
import sys
import time

import numpy as np

from slippulse.core.h5io import list_pulses, read_pulse


def summarise(path):
    """Numbers of a family file: pulses, checks passed/failed, deepest pulse, worst check."""
    rows = [read_pulse(path, lab)[0] for lab in list_pulses(path)]
    good = [p for p in rows if p.converged and p.extra.get("grid_check_passed", False)]
    failed = [p for p in rows if not p.converged]
    deep = [p for p in good if p.extra.get("continuation") == "arclength"]
    last = min(good, key=lambda p: p.tau_d_ratio) if good else None
    return {
        "pulses": len(rows), "passed": len(good), "failed": len(failed), "deep": len(deep),
        "deepest": (last.tau_d_ratio, last.beta, last.L) if last else None,
        "max_dbeta": max((abs(float(p.extra["grid_check_dbeta"])) for p in good), default=np.nan),
        "max_dL": max((abs(float(p.extra["grid_check_dL_rel"])) for p in good), default=np.nan),
        "deep_N": [(round(p.L, 1), p.n_points, int(p.extra["grid_check_body_levels"]))
                   for p in deep],
    }


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--out", default="/tmp/bench_deep.h5")
    ap.add_argument("--to", default="1.009")
    ap.add_argument("--max-length", type=float, default=1500.0)
    ap.add_argument("--reuse", action="store_true",
                    help="summarise an existing --out without running")
    a = ap.parse_args(argv)
    if not a.reuse:
        if os.path.exists(a.out):
            os.remove(a.out)
        cmd = ["slippulse", "steady", "family", "--from", "1.2", "--to", a.to, "--max-length",
               str(a.max_length), "--out", a.out, "-q"]
        load0 = os.getloadavg()
        t0 = time.perf_counter()
        r = subprocess.run(cmd, capture_output=True, text=True)
        wall = time.perf_counter() - t0
        load1 = os.getloadavg()
        print(" ".join(cmd))
        print(r.stdout.strip())
        if r.returncode != 0:
            print(r.stderr.strip()[-2000:], file=sys.stderr)
        print(f"exit {r.returncode}, wall {wall:.0f} s ({wall / 60:.1f} min), load average "
              f"{load0[0]:.1f} before, {load1[0]:.1f} after (1-min), {os.cpu_count()} cores")
    s = summarise(a.out)
    q, b, L = s["deepest"] if s["deepest"] else (np.nan, np.nan, np.nan)
    print(f"{s['pulses']} pulses: {s['passed']} grid-checked and passed ({s['deep']} from the "
          f"deep march), {s['failed']} written as failed; deepest tau_d/tau_min={q:.7f} "
          f"beta={b:.7f} L={L:.1f} m; worst check |dbeta|={s['max_dbeta']:.1e}, "
          f"|dL/L|={s['max_dL']:.1e}")
    print("deep pulses (L m, N, body refinements):", s["deep_N"])
    return 0


if __name__ == "__main__":
    sys.exit(main())
