"""Deep pulses whose N vs 2N − 1 check fails in L: refine the body, then check again.

    python steady/body_refine.py runs/deep4/arc_005.npz [arc_006.npz ...] [--out runs/deep4_body]

For a stored step of `steady/deep_march.py --check` (grid, unknowns (ln v, β, τ_d/τ_min), pin):
the cells of the body, (ξ_R − 0.9 L, ξ_R − 0.01 L] behind the leading-edge pin ξ_R, get their
midpoints inserted (up to --levels times, until the check passes; where `steady/locate_error.py` puts the L error of these pulses: at
L = 602 m, 1.67e-4 of the 1.78e-4 change N → 2N − 1); the pulse is re-solved on that grid on the
line through it normal to the family tangent (as in the grid check), and the refined pulse, with
N' = N + body cells nodes, is then checked at N' vs 2N' − 1 by
:func:`slippulse.steady.continuation.check_grid_2n` (nested: all midpoints inserted), the
differences converted to fixed τ_d. Each result goes to OUT/arc_kkk.npz (the refined pulse, with
dbeta, dL_rel, n_check as deep_march writes them) and one line of OUT/summary.txt; files that
passed are skipped, so an interrupted run resumes (a failed one is redone). ≈ 3–5 min per step on the 2-core machine
(dense LU at 2N' − 1 ≈ 11000).
"""
import argparse
import os
import sys
import time

import numpy as np

from deep_march import rebuild
from locate_error import regions
from slippulse.core.params import DEFAULT
from slippulse.steady.continuation import check_grid_2n

BODY = "body (−0.9 L, −0.01 L]"
TOL_BETA, TOL_L = 1e-5, 1e-4


def refine_body(P, xi, x0, k, y_pin, order):
    """The pulse (grid xi, unknowns x0 = (ln v, β, q), pin k at y_pin) re-solved with the body's
    midpoints inserted, on the line normal to the family tangent; (solution, cells added)."""
    sol = rebuild(P, xi, x0, k, y_pin, order)
    body = regions(sol, sol.to_pulse().L)[BODY]
    fine, _, _ = check_grid_2n(P, sol, xi.size, nested=True, cells=body, max_iter=20)
    return fine, int(body.sum())


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("steps", nargs="+", help="arc_kkk.npz of steady/deep_march.py")
    ap.add_argument("--out", default="runs/deep4_body")
    ap.add_argument("--levels", type=int, default=2,
                    help="body refinements at most, each followed by a check (default 2)")
    a = ap.parse_args(argv)
    P = DEFAULT
    os.makedirs(a.out, exist_ok=True)
    summary = os.path.join(a.out, "summary.txt")
    for path in a.steps:
        dest = os.path.join(a.out, os.path.basename(path))
        if os.path.exists(dest):
            d = np.load(dest)
            if float(d["dbeta"]) <= TOL_BETA and float(d["dL_rel"]) <= TOL_L:
                print(f"{dest}: done already", flush=True)
                continue
        z = dict(np.load(path))
        t0 = time.perf_counter()
        xi, x, k, y_pin = z["xi"], z["x"], int(z["pin_index"]), float(z["y_pin"])
        order = int(z["state_order"]) if "state_order" in z else 2
        added = 0
        for level in range(1, a.levels + 1):
            # body midpoints inserted once more, then N' vs 2N' - 1
            sol, more = refine_body(P, xi, x, k, y_pin, order)
            added += more
            if not sol.stats.converged:
                break
            fine, db, dl = check_grid_2n(P, sol, sol.xi.size, nested=True, stages=4)
            ok = db <= TOL_BETA and dl <= TOL_L
            if ok:
                break
            xi, x, k, y_pin = sol.xi, sol.x, sol.problem.pin_index, sol.problem.y_pin
        if not sol.stats.converged:
            line = f"{os.path.basename(path)}: body-refined solve failed ({sol.stats.message})"
            print(line, flush=True)
            with open(summary, "a") as fh:
                fh.write(line + "\n")
            continue
        p = sol.to_pulse()
        out = dict(xi=sol.xi, x=sol.x, pin_index=sol.problem.pin_index, y_pin=sol.problem.y_pin,
                   L=p.L, state_order=sol.problem.state_order, dbeta=db, dL_rel=dl,
                   n_check=fine.xi.size, n_body_added=added, source=os.path.abspath(path),
                   dbeta_coarse=float(z.get("dbeta", np.nan)),
                   dL_rel_coarse=float(z.get("dL_rel", np.nan)))
        tmp = dest + ".part.npz"
        np.savez(tmp, **out)
        os.replace(tmp, dest)
        line = (f"{os.path.basename(path)}: tau_d/tau_min={float(sol.x[-1]):.7f} "
                f"beta={p.beta:.7f} L={p.L:.1f} m N={z['x'].size - 2} -> N'={sol.xi.size} "
                f"(+{added} body, {level} level{'s' if level > 1 else ''}) vs {fine.xi.size}: dbeta={db:.2e} dL/L={dl:.2e} "
                f"({'passes' if ok else 'FAILS'}; at N: dL/L={float(z.get('dL_rel', np.nan)):.2e}) "
                f"{time.perf_counter() - t0:.0f} s")
        print(line, flush=True)
        with open(summary, "a") as fh:
            fh.write(line + "\n")
    return 0


if __name__ == "__main__":
    sys.exit(main())
