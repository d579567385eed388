"""Family benchmark: wall time of the continuation 1.2 → 1.015 and grid convergence at selected τ_d.

Run:  python benchmarks/bench_family.py [--points 2000] [--out /tmp/bench_family.h5]
           [--ratios ...] [--n-at 1.02=3000 1.015=6000] [--reuse]
Takes ≈ 5–10 min on the 2-core machine. Prints the family wall time and, at τ_d/τ_min = 1.2, 1.1,
1.05, 1.03, 1.02, 1.015, β and L solved at N and 2N (each seeded by the family pulse, grid adapted
to it, one adapt-and-resolve pass) with their relative changes.
"""
from __future__ import annotations

import argparse
import os
import time

import numpy as np

from slippulse.steady.continuation import run_family
from slippulse.core.h5io import list_pulses, read_pulse
from slippulse.core.params import DEFAULT
from slippulse.steady.solver import solve_pulse


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--points", type=int, default=2000)
    ap.add_argument("--out", default="/tmp/bench_family.h5")
    ap.add_argument("--ratios", type=float, nargs="+", default=[1.2, 1.1, 1.05, 1.03, 1.02, 1.015])
    ap.add_argument("--n-at", nargs="*", default=[], metavar="RATIO=N",
                    help="grid size N of the convergence pair (N, 2N) at a ratio (default --points)")
    ap.add_argument("--reuse", action="store_true", help="keep an existing --out family file")
    args = ap.parse_args()
    n_at = {round(float(a.split("=")[0]), 4): int(a.split("=")[1]) for a in args.n_at}
    if os.path.exists(args.out) and not args.reuse:
        os.remove(args.out)
    solve_pulse(DEFAULT, 1.2, n_points=300)       # warm numba caches
    t0 = time.perf_counter()
    rep = run_family(DEFAULT, args.out, 1.2, 1.015, 0.005, n_points=args.points)
    wall = time.perf_counter() - t0
    if rep.resumed_from:
        print(f"(family file reused; resumed from {rep.resumed_from})")
    labels = list_pulses(args.out)
    pulses = [read_pulse(args.out, lab)[0] for lab in labels]
    worst = max(p.max_residual for p in pulses)
    print(f"family 1.2 -> 1.015 (step 0.005), N={args.points}: reached {rep.reached:.5f}, "
          f"{len(labels)} pulses written ({sum(p.converged for p in pulses)} converged), "
          f"max over pulses of max|Delta| = {worst:.1e}, {len(rep.failures)} failed attempts, "
          f"wall {wall:.1f} s")
    print("\n| tau_d/tau_min | N | beta (N) | beta (2N) | rel. change | L (N) m | L (2N) m | rel. change "
          "| max abs(Delta) | wall N, 2N (s) |")
    print("|---|---|---|---|---|---|---|---|---|---|")
    for r in args.ratios:
        n1 = n_at.get(round(r, 4), args.points)
        n2 = 2 * n1
        pu, _ = read_pulse(args.out, f"td{r:.4f}")
        g = (pu.xi, np.log(pu.v), pu.beta)
        a = solve_pulse(DEFAULT, r, n_points=n1, guess=g, passes=1, coarse_points=n1).to_pulse()
        b = solve_pulse(DEFAULT, r, n_points=n2, guess=g, passes=1, coarse_points=n2).to_pulse()
        print(f"| {r:.4f} | {n1} | {a.beta:.8f} | {b.beta:.8f} | {abs(a.beta / b.beta - 1):.1e} | "
              f"{a.L:.6f} | {b.L:.6f} | {abs(a.L / b.L - 1):.1e} | "
              f"{max(a.max_residual, b.max_residual):.1e} | {a.wall_time:.0f}, {b.wall_time:.0f} |",
              flush=True)


if __name__ == "__main__":
    main()
