"""How far the deformed grid's zone about the healing front has drifted off the front's steep
drop, and what moving it back changes: the deepest converged pulse of a family file, moved back
onto its drop (``relay.recentre``), then, with ``--check``, its nested grid check.

    python steady/recentre_check.py FAMILY.h5 [--check]

Prints the offset before and after (``stretch.block_offset``), the re-solve's iterations and its
change at fixed τ_d, the largest |Δ ln v| per cell at the drop before and after, and with --check
the recentred pulse's ΔL/L and Δβ against 2N − 1 points (to compare with the check stored with
the pulse). Writes nothing. At N = 6614 (L ≈ 6.8 km): ≈ 30 s for the re-solve on one thread,
≈ 15 min more for the check.
"""
import argparse
import math
import os
import sys
import time

import numpy as np

sys.path.insert(0, os.path.join(os.path.dirname(os.path.abspath(__file__)), "..", "src"))

from slippulse.core.h5io import list_pulses, read_pulse  # noqa: E402
from slippulse.steady.continuation.gridcheck import check_grid_2n  # noqa: E402
from slippulse.steady.continuation.relay import recentre, zone_offset  # noqa: E402
from slippulse.steady.equations import SteadyProblem  # noqa: E402
from slippulse.steady.newton import SolveStats  # noqa: E402
from slippulse.steady.solver import SteadySolution, front_pin  # noqa: E402


def _drop(params, sol):
    """(offset, largest |Δ ln v| per cell within 30 m of the back crossing)."""
    off, x_back = zone_offset(params, sol)
    xi, y = sol.xi, np.asarray(sol.x[:-2], float)
    mid = 0.5 * (xi[1:] + xi[:-1])
    near = np.abs(mid - x_back) < 30.0
    return off, float(np.abs(np.diff(y))[near].max())


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("family", help="family file (slippulse steady family --out)")
    ap.add_argument("--check", action="store_true", help="also the recentred pulse's grid check")
    args = ap.parse_args(argv)
    rows = [read_pulse(args.family, lab) for lab in list_pulses(args.family)]
    good = [r for r in rows if r[0].converged]
    if not good:
        sys.exit(f"{args.family}: no converged pulse")
    p, P = min(good, key=lambda r: r[0].tau_d_ratio)
    y, q = np.log(p.v), p.tau_d_ratio
    k, _ = front_pin(p.xi, y, math.log(P.v_stick(q * P.tau_min)))
    base = SteadyProblem(P, q, p.xi, k, float(y[k]), free="both")
    sol = SteadySolution(base, np.concatenate([y, [p.beta, q]]),
                         SolveStats(True, "file", 0, 0.0), 0.0, 0)
    off0, dy0 = _drop(P, sol)
    print(f"{p.label}: L = {p.L:.1f} m, N = {p.xi.size}, offset {off0:+.2f} m, "
          f"max |d ln v| per cell at the drop {dy0:.3g}; stored check: "
          f"{p.extra.get('grid_check_message', 'none')}")
    t0 = time.perf_counter()
    new, dbeta, dL_rel, _, msg = recentre(P, sol)
    print(f"{msg} ({time.perf_counter() - t0:.0f} s)")
    if new is None:
        sys.exit(1)
    off1, dy1 = _drop(P, new)
    print(f"after: offset {off1:+.2f} m, max |d ln v| per cell at the drop {dy1:.3g}")
    if args.check:
        t0 = time.perf_counter()
        fine, db, dl = check_grid_2n(P, new, new.xi.size, nested=True, stages=4, max_iter=15)
        print(f"check of the recentred pulse: N={new.xi.size} vs {fine.xi.size}: dbeta={db:.2e} "
              f"dL/L={dl:.2e} ({fine.stats.message}; {time.perf_counter() - t0:.0f} s)")


if __name__ == "__main__":
    main()
