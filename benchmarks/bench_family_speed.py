"""Family 1.2 → 1.015 (step 0.005): today's code against the old one, side by side (issue 11, item 4).

Run:  python benchmarks/bench_family_speed.py --base /path/to/old/src [--repeats 2]
           [--old-points 2000] [--new-points DEFAULT] [--ref /tmp/family_ref.json] [--workdir DIR]
`--base` is the `src` folder of a checkout of the old code (e.g. a detached worktree of 2f34b8f);
its numba cache goes to WORKDIR, so that checkout is only read. Each repeat runs the old family and
the new one, alternately, each in a fresh Python process (numba kernels warmed by one small solve
before the clock starts), and prints the wall times and the ratio old/new (medians over repeats).
Accuracy: β and L of every pulse written at a target τ_d (38 targets) are compared with a
reference solved by today's code at `--ref-points` (order-4 state, N = 4000 by default; its own
error at 1.015 τ_min is ≈ 4e-7 in L, docs/steady.md §3.3) on a grid adapted to the pulse; the
reference is cached in `--ref` and recomputed when missing. Takes ≈ 10 min on the 2-core machine
(the references ≈ 5 min once).
"""
from __future__ import annotations

import argparse
import json
import os
import statistics
import subprocess
import sys
import time

import numpy as np

HERE = os.path.dirname(os.path.abspath(__file__))
NEW_SRC = os.path.join(os.path.dirname(HERE), "src")

RUN = r"""
import json, os, sys, time
try:                                    # package layout of issue 13
    from slippulse.steady.continuation import run_family
    from slippulse.core.params import DEFAULT
    from slippulse.steady.solver import solve_pulse
except ImportError:                     # the flat layout before it
    from slippulse.continuation import run_family
    from slippulse.params import DEFAULT
    from slippulse.solver import solve_pulse
out, n = sys.argv[1], sys.argv[2]
if os.path.exists(out):
    os.remove(out)
solve_pulse(DEFAULT, 1.2, n_points=300)                  # warm the numba kernels
kw = {} if n == "default" else {"n_points": int(n)}
t0 = time.perf_counter()
rep = run_family(DEFAULT, out, 1.2, 1.015, 0.005, **kw)
wall = time.perf_counter() - t0
print(json.dumps({"wall": wall, "reached": rep.reached, "written": len(rep.written),
                  "failures": len(rep.failures), "attempts": rep.attempts}))
"""


def run_family_in(src, out, points, cache):
    env = dict(os.environ, PYTHONPATH=src, NUMBA_CACHE_DIR=cache, PYTHONDONTWRITEBYTECODE="1")
    r = subprocess.run([sys.executable, "-c", RUN, out, str(points)], env=env, capture_output=True,
                       text=True)
    if r.returncode != 0:
        raise RuntimeError(f"family run with {src} failed:\n{r.stderr[-3000:]}")
    return json.loads(r.stdout.strip().splitlines()[-1])


def targets():
    return [round(1.2 - 0.005 * k, 4) for k in range(38)]


def reference(family, path, n_ref):
    """β and L at every target from order-4 solves at n_ref points seeded by the family's pulses."""
    from slippulse.core.h5io import read_pulse
    from slippulse.core.params import DEFAULT
    from slippulse.steady.solver import solve_pulse
    ref = {}
    if os.path.exists(path):
        with open(path) as fh:
            ref = json.load(fh)
        if ref.get("n_points") == n_ref:
            return ref
    ref = {"n_points": n_ref, "pulses": {}}
    for r in targets():
        pu, _ = read_pulse(family, f"td{r:.4f}")
        s = solve_pulse(DEFAULT, r, n_points=n_ref, guess=(pu.xi, np.log(pu.v), pu.beta), passes=0,
                        state_order=4, max_iter=30)
        p = s.to_pulse()
        if not p.converged:
            raise RuntimeError(f"reference at {r} did not converge: {s.stats.message}")
        ref["pulses"][f"td{r:.4f}"] = {"beta": p.beta, "L": p.L}
        print(f"  reference td{r:.4f}: beta={p.beta:.9f} L={p.L:.6f}", flush=True)
    with open(path, "w") as fh:
        json.dump(ref, fh, indent=1)
    return ref


def errors(family, ref):
    from slippulse.core.h5io import read_pulse
    rows = []
    for lab, x in ref["pulses"].items():
        pu, _ = read_pulse(family, lab)
        rows.append((lab, abs(pu.beta / x["beta"] - 1), abs(pu.L / x["L"] - 1)))
    return rows


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--base", required=True, help="src folder of the old code")
    ap.add_argument("--repeats", type=int, default=2)
    ap.add_argument("--old-points", default="2000")
    ap.add_argument("--new-points", default="default")
    ap.add_argument("--ref", default="/tmp/family_ref.json")
    ap.add_argument("--ref-points", type=int, default=4000)
    ap.add_argument("--workdir", default="/tmp/bench_family_speed")
    args = ap.parse_args()
    os.makedirs(args.workdir, exist_ok=True)
    print(f"load at start: {os.getloadavg()}  ({time.strftime('%H:%M:%S')})", flush=True)
    runs = {"old": [], "new": []}
    files = {}
    for k in range(args.repeats):
        for name, src, pts in (("old", args.base, args.old_points),
                               ("new", NEW_SRC, args.new_points)):
            out = os.path.join(args.workdir, f"{name}.h5")
            res = run_family_in(src, out, pts, os.path.join(args.workdir, f"numba_{name}"))
            res["load"] = os.getloadavg()[0]
            runs[name].append(res)
            files[name] = out
            print(f"repeat {k + 1} {name:3s} (N={pts}): wall {res['wall']:.1f} s, reached "
                  f"{res['reached']:.4f}, {res['written']} pulses, {res['failures']} failed of "
                  f"{res['attempts']} attempts, load {res['load']:.1f}", flush=True)
    w_old = statistics.median(r["wall"] for r in runs["old"])
    w_new = statistics.median(r["wall"] for r in runs["new"])
    print(f"\nmedian wall: old {w_old:.1f} s, new {w_new:.1f} s, ratio old/new = {w_old / w_new:.2f}")
    print("per repeat ratio: " + ", ".join(f"{a['wall'] / b['wall']:.2f}"
                                           for a, b in zip(runs["old"], runs["new"])))
    ref = reference(files["new"], args.ref, args.ref_points)
    print(f"\naccuracy against the reference (order 4, N = {ref['n_points']}), relative:")
    print("| code | max dbeta (all 38) | at | max dL (all 38) | at | dbeta, dL at 1.2 / 1.1 / 1.05 / "
          "1.03 / 1.02 / 1.015 |")
    print("|---|---|---|---|---|---|")
    for name in ("old", "new"):
        rows = errors(files[name], ref)
        b = max(rows, key=lambda t: t[1])
        L = max(rows, key=lambda t: t[2])
        sel = {lab: (db, dl) for lab, db, dl in rows}
        pick = " / ".join(f"{sel[f'td{r:.4f}'][0]:.1e}, {sel[f'td{r:.4f}'][1]:.1e}"
                          for r in (1.2, 1.1, 1.05, 1.03, 1.02, 1.015))
        print(f"| {name} | {b[1]:.1e} | {b[0]} | {L[2]:.1e} | {L[0]} | {pick} |")
    print(f"\nload at end: {os.getloadavg()}  ({time.strftime('%H:%M:%S')})")


if __name__ == "__main__":
    main()
