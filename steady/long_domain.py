"""Re-solve one pulse of a family on a much longer domain (paper Fig. S1b robustness check).

Run:  python steady/long_domain.py FAMILY.h5 [--label td1.0500] [--factor 40] [--out FILE]
      slippulse figures FAMILY.h5 --compare FILE        # Fig. S1b overlays the two domains
Takes ≈ 10–30 s. The domain ahead (in pulse lengths) and the healing tail behind (in healing
lengths c_p D/v_stick) are both multiplied by --factor; N grows with log(factor) to keep the
near-field spacing.
"""
from __future__ import annotations

import argparse
import math
import os

import numpy as np

from slippulse.core.h5io import read_pulse, write_pulse
from slippulse.steady.solver import GridSpec, solve_pulse


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("family")
    ap.add_argument("--label", default="td1.0500")
    ap.add_argument("--factor", type=float, default=40.0)
    ap.add_argument("--out", default=None)
    args = ap.parse_args()
    pulse, params = read_pulse(args.family, args.label)
    base = GridSpec()
    spec = GridSpec(ahead=base.ahead * args.factor, behind_tail=base.behind_tail * args.factor,
                    body=base.body, gamma=base.gamma)
    n = int(pulse.n_points * (1.0 + 0.1 * math.log(args.factor)))
    sol = solve_pulse(params, pulse.tau_d_ratio, n_points=n,
                      guess=(pulse.xi, np.log(pulse.v), pulse.beta), passes=1, coarse_points=n,
                      spec=spec)
    long = sol.to_pulse()
    long.extra["domain_factor"] = args.factor
    out = args.out or os.path.join(os.path.dirname(os.path.abspath(args.family)),
                                   f"long_domain_{args.label}.h5")
    write_pulse(out, long, params)
    print(f"{args.label}: domain ({pulse.xi[0]:.4g}, {pulse.xi[-1]:.4g}) m -> "
          f"({long.xi[0]:.4g}, {long.xi[-1]:.4g}) m, N {pulse.n_points} -> {long.n_points}; "
          f"beta {pulse.beta:.8f} -> {long.beta:.8f}, L {pulse.L:.6f} -> {long.L:.6f} m, "
          f"converged={long.converged}; wrote {out}")
    return 0 if long.converged else 1


if __name__ == "__main__":
    raise SystemExit(main())
