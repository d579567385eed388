"""Where the N-dependence of a deep pulse sits: refine one region at a time.

    python steady/locate_error.py runs/deep4/arc_008.npz

For a stored step of `steady/deep_march.py` (grid, unknowns (ln v, β, τ_d/τ_min), pin), the cells
of one region — ahead of the front, the leading edge (±0.01 L about the pin), the body
(−0.9 L, −0.01 L], the healing front (−1.1 L, −0.9 L], the tail — get their midpoints inserted;
the pulse is re-solved on that grid on the line through it normal to the family tangent and the
change converted to fixed τ_d (:func:`slippulse.steady.continuation.grid_change` with a cell mask). The
region whose refinement moves β and L most holds the error. About 1 min at N = 4000.
"""
import argparse
import sys
import time

import numpy as np

from deep_march import rebuild
from slippulse.core.params import DEFAULT
from slippulse.steady.continuation import grid_change


def regions(sol, L):
    """Boolean masks over the cells of ``sol``'s grid: ahead, leading edge, body, healing front,
    tail, relative to the pin ξ_R and the length L."""
    xi = sol.xi
    xf = xi[sol.problem.pin_index]
    mid = 0.5 * (xi[1:] + xi[:-1])
    return {"ahead (> +0.01 L)": mid > xf + 0.01 * L,
            "leading edge (±0.01 L)": (mid > xf - 0.01 * L) & (mid <= xf + 0.01 * L),
            "body (−0.9 L, −0.01 L]": (mid > xf - 0.9 * L) & (mid <= xf - 0.01 * L),
            "healing front (−1.1 L, −0.9 L]": (mid > xf - 1.1 * L) & (mid <= xf - 0.9 * L),
            "tail (< −1.1 L)": mid <= xf - 1.1 * L}


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("step", help="arc_kkk.npz of steady/deep_march.py")
    a = ap.parse_args(argv)
    P = DEFAULT
    z = np.load(a.step)
    order = int(z["state_order"]) if "state_order" in z else 2
    sol = rebuild(P, z["xi"], z["x"], int(z["pin_index"]), float(z["y_pin"]), order)
    p0 = sol.to_pulse()
    print(f"tau_d/tau_min={float(sol.x[-1]):.7f} beta={p0.beta:.7f} L={p0.L:.2f} m "
          f"N={sol.xi.size} order {order}")
    print("| region | cells | Δβ at fixed τ_d | ΔL/L at fixed τ_d | Newton it. |")
    print("|---|---|---|---|---|")
    for name, sel in regions(sol, p0.L).items():
        t0 = time.perf_counter()
        fine, db, dl = grid_change(P, sol, sol.xi.size, nested=True, cells=sel, max_iter=15)
        if not fine.stats.converged:
            print(f"| {name} | {int(sel.sum())} | – | – | {fine.stats.message} |")
            continue
        print(f"| {name} | {int(sel.sum())} | {db:+.2e} | {dl:+.2e} | {fine.stats.iterations} "
              f"({time.perf_counter() - t0:.0f} s) |", flush=True)
    return 0


if __name__ == "__main__":
    sys.exit(main())
