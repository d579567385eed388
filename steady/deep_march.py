"""Pseudo-arclength march of the deep family (τ_d → τ̃*), one npz per converged step.

    python steady/deep_march.py FAMILY.h5 LABEL --points N [--steps K] [--outdir runs/deep]

Starts from pulse LABEL of a family file (or resumes from the last step already in
OUTDIR/arc_N_*.npz) and takes up to K arclength steps in (ln(1−β), τ_d/τ_min) at N points
(:func:`slippulse.steady.continuation.march_arclength`). Each step is written as arc_N_kkk.npz with the
grid xi, the unknowns x = (ln v, β, τ_d/τ_min), L and the solver statistics. Steps are not at
round τ_d (the family file's labels keep 4 decimals); `steady/divergence.py` reads them.
Cost on the shared 2-core machine: ≈ 5–15 s per step at N = 2000, 20–80 s at N = 4000.
"""
import argparse
import glob
import os
import sys
import time

import numpy as np

from slippulse.steady.continuation import DeepSettings, march_arclength
from slippulse.core.h5io import read_pulse
from slippulse.core.params import DEFAULT


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("family")
    ap.add_argument("label")
    ap.add_argument("--points", type=int, default=2000)
    ap.add_argument("--steps", type=int, default=20)
    ap.add_argument("--ds-max", type=float, default=0.4)
    ap.add_argument("--outdir", default=os.path.join("runs", "deep"))
    a = ap.parse_args(argv)
    os.makedirs(a.outdir, exist_ok=True)
    done = sorted(glob.glob(os.path.join(a.outdir, f"arc_{a.points}_*.npz")))
    if done:
        z = np.load(done[-1])
        start = (z["xi"], z["x"][:-2], float(z["x"][-2]), float(z["x"][-1]))
        print(f"resuming from {done[-1]}", file=sys.stderr)
    else:
        pu, _ = read_pulse(a.family, a.label)
        start = (pu.xi, np.log(pu.v), pu.beta, pu.tau_d_ratio)
    k0 = len(done)
    t0 = time.perf_counter()

    def progress(ratio, pulse, msg):
        print(f"{time.perf_counter() - t0:8.1f} s  {ratio:.7f}  {msg[:110]}", file=sys.stderr,
              flush=True)

    deep = DeepSettings(ds_max=a.ds_max)
    for k, (sol, (t_a, t_Q)) in enumerate(march_arclength(DEFAULT, start, a.points, deep=deep,
                                                          progress=progress), start=k0 + 1):
        pu = sol.to_pulse()
        path = os.path.join(a.outdir, f"arc_{a.points}_{k:03d}.npz")
        np.savez(path + ".tmp.npz", xi=sol.xi, x=sol.x, L=pu.L, t_a=t_a, t_Q=t_Q,
                 max_residual=pu.max_residual, iterations=sol.stats.iterations,
                 pin_index=sol.problem.pin_index, y_pin=sol.problem.y_pin)
        os.replace(path + ".tmp.npz", path)
        print(f"step {k}: tau_d/tau_min={sol.x[-1]:.8f} beta={pu.beta:.8f} L={pu.L:.5g} m "
              f"t_Q={t_Q:+.3f} max|D|={pu.max_residual:.1e}", flush=True)
        if k - k0 >= a.steps:
            break
    return 0


if __name__ == "__main__":
    sys.exit(main())
