"""Where steady pulses exist and where the solver finds them, over (b, α) at fixed τ_d/τ_min.

    python steady/existence_map.py [--b 0.04 0.055 ...] [--alpha 0.00125 ...] [--tau-d 1.2]
        [--points 500] [--params FILE.toml] [--out runs/steady/existence_map.h5]
        [--figure docs/figures/existence_map.png]

The logic is :func:`slippulse.steady.existence_map.existence_map`; this writes its HDF5 (xarray),
the chart (plotting/existence_map.py) and prints a summary line and the per-point log. Default
grid: 7 x 7 around Table I (b = 0.075, α = 0.005), ≈ 100 solves at N = 500 (docs/results.md §1,
cost in BENCHMARKS.md).
"""
import argparse
import os
import subprocess
import warnings

from slippulse.core.params import resolve_params
from slippulse.plotting.existence_map import plot_existence_map
from slippulse.steady.existence_map import existence_map, read_map, summary, write_map

B = [0.04, 0.055, 0.075, 0.1, 0.14, 0.2, 0.28]
ALPHA = [0.00125, 0.0025, 0.005, 0.0075, 0.01, 0.015, 0.02]


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--b", type=float, nargs="+", default=B)
    ap.add_argument("--alpha", type=float, nargs="+", default=ALPHA)
    ap.add_argument("--tau-d", type=float, default=1.2)
    ap.add_argument("--points", type=int, default=500)
    ap.add_argument("--params", default=None, help="[params] TOML for the other parameters")
    ap.add_argument("--out", default="runs/steady/existence_map.h5")
    ap.add_argument("--figure", default="runs/steady/existence_map.png")
    ap.add_argument("--replot", action="store_true", help="only redraw the figure from --out")
    a = ap.parse_args()
    if a.replot:
        plot_existence_map(read_map(a.out), a.figure)
        return
    base = resolve_params(a.params)
    warnings.simplefilter("ignore", RuntimeWarning)     # NaN inside failed Newton iterations
    m = existence_map(a.b, a.alpha, a.tau_d, base=base, n_points=a.points,
                      progress=lambda s: print(s, flush=True))
    for p in (a.out, a.figure):
        os.makedirs(os.path.dirname(p) or ".", exist_ok=True)
    write_map(a.out, m)
    plot_existence_map(m, a.figure)
    load = subprocess.run(["uptime"], capture_output=True, text=True).stdout.strip()
    print(summary(m))
    print(f"wrote {a.out} and {a.figure}; load: {load}")


if __name__ == "__main__":
    main()
