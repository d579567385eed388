"""Fate runs against the equation of motion (docs/motion.md §3, docs/results.md §3): the table and the (L, c_p)
figure.

    python dynamic/motion.py FIGURE.png --family FAMILY.h5 [MORE.h5] --runs FATE.h5 [...]
"""
import argparse
import math

import numpy as np

from slippulse.plotting.motion import motion_figure
from slippulse.timedomain.fate import read_fate, time_law
from slippulse.timedomain.motion import SteadyLine, compare

ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
ap.add_argument("figure")
ap.add_argument("--family", nargs="+", required=True)
ap.add_argument("--runs", nargs="+", required=True)
ap.add_argument("--start", type=float, default=0.01,
                help="start the model where L first departs from L* by this (0.01)")
ap.add_argument("--law", nargs="+", default=(),
                help="runs of one pulse at several eps: fit t_fate = a + b ln|eps| (b vs -1/s)")
a = ap.parse_args()
line = SteadyLine.from_family(a.family)
cmps = {}
print("| tau_d/tau_min | eps | seed | domain (L) | far field | SBI fate | after (L0) | L range (m) | "
      "c_p/c_s range | model from (L0) | model fate | 5 % split after (L0): L, c_p | "
      "median abs(c_p/c_p0(L) - 1) |")
print("|---|---|---|---|---|---|---|---|---|---|---|---|---|")
for p in a.runs:
    r = read_fate(p)
    try:
        c = compare(line, float(r["tau_d_ratio"]), r["t"], r["x_front"], r["L"], start=a.start)
    except ValueError as exc:
        print(f"| {r['tau_d_ratio']:.4g} | {r['eps']:+.0e} | {r['perturbation']} | "
              f"{r['ahead']:g}+{r['behind']:g} | {r['far_field']} | {r['fate']} | "
              f"{r.get('distance_fate', math.nan):.3g} | – | – | – | model not run: {exc} | – | – |")
        continue
    lab = (f"{r['tau_d_ratio']:.2f} eps={r['eps']:+.0e} {r['perturbation']} "
           f"({r['ahead']:g}+{r['behind']:g} L, {r['far_field']})")
    cmps[lab] = c
    cp = c.c_p[np.isfinite(c.c_p)]
    d = c.line_distance[np.isfinite(c.line_distance)]
    print(f"| {r['tau_d_ratio']:.4g} | {r['eps']:+.0e} | {r['perturbation']} | "
          f"{r['ahead']:g}+{r['behind']:g} | {r['far_field']} | {r['fate']} | {r.get('distance_fate', math.nan):.3g} | {np.nanmin(c.L):.4g}–"
          f"{np.nanmax(c.L):.4g} | {cp.min() / line.c_s:.3g}–{cp.max() / line.c_s:.3g} | "
          f"{c.x[c.skip] / c.L[0]:.3g} | {c.model.fate} | {c.distance_split_L:.3g}, "
          f"{c.distance_split_c:.3g} | "
          f"{np.median(np.abs(d)) if d.size else math.nan:.3g} |")
if a.law:
    rs = [read_fate(p) for p in a.law]
    A, B, E = time_law([r["eps"] for r in rs], [r["t_fate"] for r in rs])
    s = float(line.functions()[3](line.equilibrium(float(rs[0]["tau_d_ratio"]))))
    print(f"time to fate ({', '.join(sorted(set(r['fate'] for r in rs)))}) at "
          f"{rs[0]['tau_d_ratio']:.4g} tau_min, eps = {', '.join(format(r['eps'], '+.0e') for r in rs)}: "
          f"t = {A:.4g} + ({B:.4g} ± {E:.1g}) ln|eps| s; -1/s = {-1 / s:.4g} s "
          f"(b s = {-B * s:.3f})")
motion_figure(a.figure, line, cmps, title="fate runs (SBI, load tau_d at infinity) and the "
                                          "equation of motion from the same L")
print(f"figure {a.figure}")
