"""Grid convergence of the family with the order-4 and order-2 state integrators (issue 11, item 3).

Run:  python benchmarks/bench_state_order.py --family FILE [--points 2000] [--orders 4 2]
           [--ratios 1.2 1.1 1.05 1.03 1.02 1.015] [--factors 1 2 4] [--json OUT]
FILE is a family file (e.g. from `slippulse steady family`); its pulses only seed the solves.
Each (τ_d, order, N) is one Newton solve on a grid of N points adapted to the seed pulse
(`solve_pulse(..., passes=0)`), so N, 2N, 4N halve every spacing of one grid layout: a clean
refinement. Prints, per τ_d and order, β and L at each N and the relative differences of β and L
from the finest N, and the observed order log2(|X_N − X_2N| / |X_2N − X_4N|) of the first three.
Takes ≈ 20–40 min on the 2-core machine (the N = 8000 solves dominate: dense LU).
"""
from __future__ import annotations

import argparse
import json
import math
import os
import time

import numpy as np

from slippulse.core.h5io import read_pulse
from slippulse.core.params import DEFAULT
from slippulse.steady.solver import solve_pulse


def solve_at(seed, ratio, n, order):
    t0 = time.perf_counter()
    s = solve_pulse(DEFAULT, ratio, n_points=n, guess=(seed.xi, np.log(seed.v), seed.beta),
                    passes=0, state_order=order, max_iter=30)
    pu = s.to_pulse()
    return {"N": n, "beta": pu.beta, "L": pu.L, "converged": pu.converged,
            "max_residual": pu.max_residual, "iterations": s.stats.iterations,
            "wall": time.perf_counter() - t0}


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--family", required=True)
    ap.add_argument("--points", type=int, default=2000)
    ap.add_argument("--orders", type=int, nargs="+", default=[4, 2])
    ap.add_argument("--ratios", type=float, nargs="+", default=[1.2, 1.1, 1.05, 1.03, 1.02, 1.015])
    ap.add_argument("--factors", type=int, nargs="+", default=[1, 2, 4])
    ap.add_argument("--json", default=None, help="also write the rows to this JSON file")
    args = ap.parse_args()
    print(f"load: {os.getloadavg()}", flush=True)
    solve_pulse(DEFAULT, 1.2, n_points=300)                   # warm the numba caches
    rows = []
    print("| τ_d/τ_min | order | N | β | L (m) | β rel. to finest | L rel. to finest | it. | wall (s) |")
    print("|---|---|---|---|---|---|---|---|---|")
    for r in args.ratios:
        seed, _ = read_pulse(args.family, f"td{r:.4f}")
        for order in args.orders:
            res = [solve_at(seed, r, f * args.points, order) for f in args.factors]
            ref = res[-1]
            for x in res:
                x.update(ratio=r, order=order, dbeta=abs(x["beta"] / ref["beta"] - 1),
                         dL=abs(x["L"] / ref["L"] - 1))
                rows.append(x)
                print(f"| {r:.4f} | {order} | {x['N']} | {x['beta']:.9f} | {x['L']:.6f} | "
                      f"{x['dbeta']:.1e} | {x['dL']:.1e} | {x['iterations']} | {x['wall']:.0f} |"
                      + ("" if x["converged"] else " NOT CONVERGED"), flush=True)
            if len(res) >= 3:
                p = [math.log2(abs(res[0][k] - res[1][k]) / abs(res[1][k] - res[2][k]))
                     if res[1][k] != res[2][k] else float("nan") for k in ("beta", "L")]
                print(f"|  | {order} | observed order | β {p[0]:.1f} | L {p[1]:.1f} | | | | |",
                      flush=True)
    print(f"load: {os.getloadavg()}")
    if args.json:
        with open(args.json, "w") as fh:
            json.dump(rows, fh, indent=1)


if __name__ == "__main__":
    main()
