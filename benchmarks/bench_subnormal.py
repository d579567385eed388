"""One assembly of the stability operator M(σ), M′(σ) at a real σ, at σ with a normal tiny
imaginary part and at σ with a subnormal one, side by side in one run (issue 17, item 5; stop 37).

    python benchmarks/bench_subnormal.py FAMILY.h5 LABEL [--s 0.1] [--repeat 2]

Before stop 37 Newton onto a real eigenvalue left Im σ at 1e-318 relative (each quadratic step
squares it), the spectrum command carried that σ from pulse to pulse and level to level, and every
assembly at it ran far slower: subnormal arithmetic in the kernel's complex exponentials and Bessel
tables. ``eigensolve.snap_real`` now sets such an imaginary part to exactly 0. This prints the
wall time of ``StabilityOperator.matrices`` at σ = s c/L times (1, 1 + 1e-14 i, 1 + 1e-318 i)
(best of --repeat), the ratios to the real one, and the largest difference of the matrices (they
must agree to rounding).
"""
import argparse
import os
import time

import h5py
import numpy as np

from slippulse.core.h5io import read_parameters, read_pulse
from slippulse.spectrum.pulse import StabilityOperator, order4_pulse


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("family")
    ap.add_argument("label")
    ap.add_argument("--s", type=float, default=0.1, help="σ in units of c_p/L (default 0.1)")
    ap.add_argument("--repeat", type=int, default=2)
    a = ap.parse_args()
    with h5py.File(a.family, "r") as h5:
        params = read_parameters(h5)
    pulse, _ = read_pulse(a.family, a.label)
    op = StabilityOperator(order4_pulse(pulse, params), params, pin_translation=True)
    s = a.s * op.rate_unit
    print(f"{a.label}: N = {op.n}, sigma = {a.s} c_p/L; load average {os.getloadavg()}")
    op.matrices(complex(s, 0.0))                      # compile and warm up
    walls, mats = {}, {}
    for name, z in (("real", complex(s, 0.0)), ("Im 1e-14 relative", complex(s, 1e-14 * s)),
                    ("Im 1e-318 relative (subnormal)", complex(s, 1e-318 * s))):
        best = np.inf
        for _ in range(a.repeat):
            t0 = time.perf_counter()
            M, dM = op.matrices(z)
            best = min(best, time.perf_counter() - t0)
        walls[name], mats[name] = best, M
        print(f"  {name:32s} {best:8.2f} s   x{best / walls['real']:.1f} of real   "
              f"max|M - M_real| / max|M_real| = "
              f"{np.abs(M - mats['real']).max() / np.abs(mats['real']).max():.1e}")
    print(f"load average after: {os.getloadavg()}")


if __name__ == "__main__":
    main()
