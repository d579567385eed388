"""Steady solver work–precision table at τ_d = 1.2 τ_min (and the default CLI solve time).

Run:  python benchmarks/bench_steady.py [--tau-d 1.2] [--points 500 1000 2000 4000] [--methods newton lm]
Takes ≈ 1–2 min on the 2-core machine. Prints, per N: β, L, max|Δ|, wall time, relative change of β
and L against the previous N (≈2× coarser) and against the finest N, and the time split of the final
pass (Hilbert assembly, Jacobian, linear solves).
"""
from __future__ import annotations

import argparse
import time

import numpy as np

from slippulse.core.params import DEFAULT
from slippulse.steady.solver import solve_pulse


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--tau-d", type=float, default=1.2)
    ap.add_argument("--points", type=int, nargs="+", default=[500, 1000, 2000, 4000, 8000])
    ap.add_argument("--methods", nargs="+", default=["newton", "lm"])
    args = ap.parse_args()
    solve_pulse(DEFAULT, args.tau_d, n_points=300)            # warm the numba caches
    for method in args.methods:
        rows = []
        for n in args.points:
            t0 = time.perf_counter()
            s = solve_pulse(DEFAULT, args.tau_d, n_points=n, method=method)
            wall = time.perf_counter() - t0
            pu = s.to_pulse()
            t1 = time.perf_counter()
            from slippulse.steady.hilbert import hilbert_matrix
            hilbert_matrix(pu.xi, center=0.0)
            t_h = time.perf_counter() - t1
            rows.append((n, pu.beta, pu.L, pu.max_residual, wall, s.stats.iterations,
                         s.stats.t_jacobian, s.stats.t_linear, t_h, pu.converged))
        ref_b, ref_L = rows[-1][1], rows[-1][2]
        print(f"\n## method={method}  tau_d/tau_min={args.tau_d}")
        print("| N | beta | L (m) | max abs(Delta) | wall (s) | it (last pass) | dbeta vs N/2 | dL vs N/2 "
              "| dbeta vs finest | dL vs finest | t_H (s) | t_jac (s) | t_LU (s) |")
        print("|---|---|---|---|---|---|---|---|---|---|---|---|---|")
        prev = None
        for r in rows:
            n, b, L, mr, wall, it, tj, tl, th, ok = r
            db = f"{abs(b / prev[1] - 1):.1e}" if prev else "-"
            dL = f"{abs(L / prev[2] - 1):.1e}" if prev else "-"
            print(f"| {n} | {b:.10f} | {L:.8f} | {mr:.1e} | {wall:.2f} | {it} | {db} | {dL} | "
                  f"{abs(b / ref_b - 1):.1e} | {abs(L / ref_L - 1):.1e} | {th:.2f} | {tj:.2f} | {tl:.2f} |"
                  + ("" if ok else " NOT CONVERGED"))
            prev = r


if __name__ == "__main__":
    main()
