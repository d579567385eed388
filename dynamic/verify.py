"""Verify seeded steady pulses in time: τ_d = 1.2, 1.1, 1.05 τ_min, one pulse length, two resolutions.

Run (from the repository root)::

    python dynamic/verify.py                 # all cases, ~7 min
    python dynamic/verify.py --only td1.0500 # one pulse

1. Computes the steady family 1.2 → 1.05 τ_min at N = 3000 into runs/family_n3000.h5 if absent
   (``slippulse.steady.continuation.run_family``, ~70 s).
2. Runs ``slippulse dynamic verify`` for each case (outputs runs/verify_<label>_dx<mm>.h5 + .png) and
   prints a markdown table of the end-of-run errors, the growth rate of |v_max − v_max⁰| per pulse
   length and the wall time (the table in BENCHMARKS.md, "Seeded steady pulses" §1, comes from this script).

Wall times measured (2-core machine, one run at a time): 1.2 τ_min 1 mm 81 s and 2 mm 26 s (both stop
at ≈ 0.5 L, "pulse lost": an unstable mode, see BENCHMARKS.md ("Seeded steady pulses")); 1.1 τ_min 2 mm 81 s,
4 mm 20 s; 1.05 τ_min 2 mm 158 s, 4 mm 39 s. Total ≈ 7 min.
"""
import argparse
import os
import subprocess
import sys

import h5py

FAMILY = "runs/family_n3000.h5"
CASES = [  # (label, dx in m, distance in L)
    ("td1.2000", 1e-3, 1.0), ("td1.2000", 2e-3, 1.0),
    ("td1.1000", 2e-3, 1.0), ("td1.1000", 4e-3, 1.0),
    ("td1.0500", 2e-3, 1.0), ("td1.0500", 4e-3, 1.0),
]


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--only", help="run only this label")
    args = ap.parse_args()
    if not os.path.exists(FAMILY):
        from slippulse.steady.continuation import run_family
        from slippulse.core.params import DEFAULT
        run_family(DEFAULT, FAMILY, start=1.2, stop=1.05, step=0.005, n_points=3000)
    rows = []
    for label, dx, dist in CASES:
        if args.only and label != args.only:
            continue
        out = f"runs/verify_{label}_dx{dx * 1e3:g}mm.h5"
        cmd = ["slippulse", "dynamic", "verify", "--steady", FAMILY, "--label", label,
               "--distance", str(dist), "--dx", str(dx), "--out", out, "--overwrite",
               "--no-progress"]
        print(" ".join(cmd), flush=True)
        subprocess.run(cmd, check=False)
        with h5py.File(out, "r") as h5:
            a = dict(h5.attrs)
        rows.append((label, dx, a))
    print("\n| pulse | dx (mm) | N | travelled (L) | status | c_p_error | v_max_error | L_error | "
          "lnv_error | growth of v_max err (1/L) | steps | wall (s) |")
    print("|---|---|---|---|---|---|---|---|---|---|---|---|")
    for label, dx, a in rows:
        print(f"| {label} | {dx * 1e3:g} | {a['n']} | {a['travelled']:.3f} | {a['status'][:40]} | "
              f"{a['c_p_error']:.2e} | {a['v_max_error']:.2e} | {a['L_error']:.2e} | "
              f"{a['lnv_error']:.2e} | {a['growth_rate_v_max']:.1f} | {a['n_steps']} | "
              f"{a['wall_time']:.0f} |")
    return 0


if __name__ == "__main__":
    sys.exit(main())
