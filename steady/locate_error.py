"""Where the N-dependence of a deep pulse sits: refine one region at a time.

    python steady/locate_error.py runs/deep4/arc_008.npz

For a stored step of `steady/deep_march.py` (grid, unknowns (ln v, β, τ_d/τ_min), pin), the cells
of one region — ahead of the front, the leading edge (±0.01 L about the pin), the body
(−0.9 L, −0.01 L], the healing front (−1.1 L, −0.9 L], the tail — get their midpoints inserted;
the pulse is re-solved on that grid on the line through it normal to the family tangent and the
change converted to fixed τ_d as in :func:`slippulse.steady.continuation.check_grid_2n`. The
region whose refinement moves β and L most holds the error. About 1 min at N = 4000.
"""
import argparse
import math
import sys
import time

import numpy as np

from slippulse.core.params import DEFAULT
from slippulse.steady import analysis as an
from slippulse.steady.continuation import ArclengthProblem, family_tangent
from slippulse.steady.equations import SteadyProblem
from slippulse.steady.newton import newton
from slippulse.steady.solver import SteadySolution, fwhm, interpolate


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("step", help="arc_kkk.npz of steady/deep_march.py")
    a = ap.parse_args(argv)
    P = DEFAULT
    z = np.load(a.step)
    xi, x0 = z["xi"], z["x"]
    y, beta, q = x0[:-2], float(x0[-2]), float(x0[-1])
    order = int(z["state_order"]) if "state_order" in z else 2
    k = int(z["pin_index"])
    base = SteadyProblem(P, q, xi, k, float(z["y_pin"]), free="both", state_order=order)
    n = family_tangent(base, x0, (1.0, 0.0, 1.0))
    t_a, t_Q = -n[-2] / (1 - beta), n[-1]
    L0 = fwhm(xi, np.exp(y), P.v_star)
    eps = 1e-3 / np.abs(n[:-2]).max()
    dL_ds = (fwhm(xi, np.exp(y + eps * n[:-2]), P.v_star) - L0) / eps
    L = an.pulse_length(xi, np.exp(y), P.v_star)[0]
    xf = xi[k]
    mid = 0.5 * (xi[1:] + xi[:-1])
    regions = {"ahead (> +0.01 L)": mid > xf + 0.01 * L,
               "leading edge (±0.01 L)": (mid > xf - 0.01 * L) & (mid <= xf + 0.01 * L),
               "body (−0.9 L, −0.01 L]": (mid > xf - 0.9 * L) & (mid <= xf - 0.01 * L),
               "healing front (−1.1 L, −0.9 L]": (mid > xf - 1.1 * L) & (mid <= xf - 0.9 * L),
               "tail (< −1.1 L)": mid <= xf - 1.1 * L}
    print(f"tau_d/tau_min={q:.7f} beta={beta:.7f} L={L0:.2f} m N={xi.size} order {order}")
    print("| region | cells | Δβ at fixed τ_d | ΔL/L at fixed τ_d | Newton it. |")
    print("|---|---|---|---|---|")
    for name, sel in regions.items():
        t0 = time.perf_counter()
        xn = np.sort(np.concatenate([xi, mid[sel]]))
        yn = interpolate(xi, y, xn, P.v_stick(q * P.tau_min))
        kn = int(np.searchsorted(xn, xf))
        pb = SteadyProblem(P, q, xn, kn, float(yn[kn]), free="both", state_order=order)
        arc = ArclengthProblem(pb, math.log(1 - beta), q, t_a, t_Q, 1.0, 0.0)
        xs, st = newton(arc, np.concatenate([yn, [beta, q]]), tol=1e-13, max_iter=15)
        if not st.converged:
            print(f"| {name} | {int(sel.sum())} | – | – | {st.message} |")
            continue
        p1 = SteadySolution(pb, xs, st, 0.0, 0).to_pulse()
        dq = float(xs[-1]) - q
        db = p1.beta - beta - (n[-2] / n[-1]) * dq
        dL = (p1.L - L0 - dL_ds / n[-1] * dq) / L0
        print(f"| {name} | {int(sel.sum())} | {db:+.2e} | {dL:+.2e} | {st.iterations} "
              f"({time.perf_counter() - t0:.0f} s) |", flush=True)
    return 0


if __name__ == "__main__":
    sys.exit(main())
