"""``slippulse steady ...``: solve steady pulses (and, later, families and their analysis)."""
from __future__ import annotations

import math
import os
import sys

import numpy as np
from tqdm import tqdm

from .h5io import pulse_label, write_pulse
from .newton import SOLVERS
from .params import DEFAULT, ParameterError
from .solver import MIN_POINTS, solve_pulse


def summary_line(pulse, params) -> str:
    """One-line summary: β, c_p, L, L̃, v_max, τ_max/τ_min, τ_m/τ_min, max|Δ|, N, wall time."""
    return (f"tau_d/tau_min={pulse.tau_d_ratio:.4f} beta={pulse.beta:.8g} c_p={pulse.c_p:.6g} m/s "
            f"L={pulse.L:.6g} m L~={pulse.L_tilde:.6g} v_max={pulse.v_max:.4e} m/s "
            f"tau_max/tau_min={pulse.tau.max() / pulse.tau_min:.6f} "
            f"tau_m/tau_min={pulse.tau.min() / pulse.tau_min:.6f} max|D|={pulse.max_residual:.2e} "
            f"N={pulse.n_points} wall={pulse.wall_time:.2f} s "
            f"{'converged' if pulse.converged else 'NOT CONVERGED'}")


def _ratio(text: str) -> float:
    try:
        val = float(text)
    except ValueError:
        raise ParameterError(f"tau-d={text!r} is invalid: must be a number (tau_d/tau_min) in "
                             f"(1, {DEFAULT.tau_peak / DEFAULT.tau_min:.4f})") from None
    if not math.isfinite(val):
        raise ParameterError(f"tau-d={text!r} is invalid: must be finite, in "
                             f"(1, {DEFAULT.tau_peak / DEFAULT.tau_min:.4f})")
    return val


def cmd_solve(args) -> int:
    params = DEFAULT
    ratio = _ratio(args.tau_d)
    params.check_tau_d(ratio * params.tau_min)
    if args.points < MIN_POINTS:
        raise ParameterError(f"points={args.points} is invalid: must be an integer >= {MIN_POINTS}")
    out = args.out or os.path.join("runs", "steady", f"{pulse_label(ratio)}.h5")
    bar = tqdm(total=3, desc=f"steady {pulse_label(ratio)}", unit="pass", disable=args.quiet,
               file=sys.stderr)

    def progress(msg):
        bar.set_postfix_str(msg[:60])
        bar.update(1)

    sol = solve_pulse(params, ratio, n_points=args.points, method=args.method, tol=args.tol,
                      progress=progress)
    bar.close()
    pulse = sol.to_pulse()
    write_pulse(out, pulse, params)
    if not args.no_figure:
        from .quicklook import plot_pulse
        plot_pulse(pulse, params, os.path.splitext(out)[0] + ".png")
    print(summary_line(pulse, params))
    if not pulse.converged:
        print(f"slippulse: solver did not converge: {sol.stats.message} "
              f"(written with converged=False to {out})", file=sys.stderr)
        return 1
    return 0


def register(sub) -> None:
    p_steady = sub.add_parser("steady", help="steady pulse solutions",
                              description="Steady self-healing pulses (mode III).")
    ss = p_steady.add_subparsers(dest="steady_command", metavar="SUBCOMMAND")
    ss.required = True
    p = ss.add_parser("solve", help="solve one steady pulse",
                      description="Solve the steady pulse at one driving stress from the built-in "
                                  "guess; writes HDF5 (+ PNG) and prints a one-line summary.")
    p.add_argument("--tau-d", default="1.2", help="driving stress tau_d/tau_min (default 1.2)")
    p.add_argument("--points", type=int, default=2000, help="grid points N (default 2000)")
    p.add_argument("--out", default=None, help="output HDF5 (default runs/steady/tdX.XXXX.h5)")
    p.add_argument("--method", choices=sorted(SOLVERS), default="newton",
                   help="nonlinear solver (default newton)")
    p.add_argument("--tol", type=float, default=1e-13, help="max|residual| target (default 1e-13)")
    p.add_argument("--no-figure", action="store_true", help="do not write the PNG")
    p.add_argument("-q", "--quiet", action="store_true", help="no progress bar")
    p.set_defaults(func=cmd_solve)
