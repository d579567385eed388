"""Where the N-dependence of a deep pulse sits: refine one region at a time.

    python steady/locate_error.py FAMILY.h5 LABEL        (a pulse of the family file)
    python steady/locate_error.py runs/deep/arc_008.npz  (a step of steady/deep_march.py)

The cells of one region (:func:`slippulse.steady.continuation.gridcheck.regions`: ahead of the
front, the leading edge (−0.0005 L, +0.01 L] about the pin, the band
(−0.01 L, −0.0005 L] behind it, the body (−0.9 L, −0.01 L], the healing front
(−1.1 L, −0.9 L], the tail) get their midpoints inserted; the pulse is re-solved on that grid on
the line normal to the family tangent and the change converted to fixed τ_d
(:func:`~slippulse.steady.continuation.grid_change` with a cell mask). About 1 min at N = 4000.
"""
import argparse
import sys
import time

from deep_march import load_pulse
from slippulse.steady.continuation.gridcheck import AHEAD, INNER, TAIL, locate_error


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("source", help="family HDF5 file or arc_kkk.npz of steady/deep_march.py")
    ap.add_argument("label", nargs="?", default=None, help="pulse label (family file)")
    a = ap.parse_args(argv)
    P, sol = load_pulse(a.source, a.label)
    p0 = sol.to_pulse()
    print(f"tau_d/tau_min={float(sol.x[-1]):.7f} beta={p0.beta:.7f} L={p0.L:.2f} m "
          f"N={sol.xi.size} order {sol.problem.state_order}")
    print("| region | cells | Δβ at fixed τ_d | ΔL/L at fixed τ_d | Newton it. |")
    print("|---|---|---|---|---|")
    t0 = time.perf_counter()
    shares = locate_error(P, sol, names=(AHEAD,) + INNER + (TAIL,))
    for name, (db, dl, cells, fine) in shares.items():
        if not fine.stats.converged:
            print(f"| {name} | {cells} | – | – | {fine.stats.message} |")
            continue
        print(f"| {name} | {cells} | {db:+.2e} | {dl:+.2e} | {fine.stats.iterations} |")
    print(f"({time.perf_counter() - t0:.0f} s)")
    return 0


if __name__ == "__main__":
    sys.exit(main())
