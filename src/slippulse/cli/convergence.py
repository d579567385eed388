"""``slippulse steady grid-convergence``: stored pulses re-solved on nested refinements
(:func:`slippulse.steady.continuation.gridcheck.grid_convergence`), with the observed order."""
from __future__ import annotations

import math
import sys

from tqdm import tqdm

from ..core.errors import UsageError
from .checks import check_labels


def cmd_grid_convergence(args) -> int:
    from ..core.h5io import atomic_update, read_pulse
    from ..steady.bifurcation import pulse_solution
    from ..steady.continuation.gridcheck import grid_convergence, observed_order
    from ..steady.solver import check_points

    if not (isinstance(args.levels, int) and 1 <= args.levels <= 4):
        raise UsageError(f"--levels={args.levels!r} is invalid: must be an integer in [1, 4]")
    if args.adapted is not None:
        check_points(args.adapted, "--adapted")
        if args.write:
            raise UsageError("--write with --adapted: the levels are of another grid than the "
                             "stored pulse's; nothing to store with it")
    check_labels(args.file, args.labels)
    print("label tau_d/tau_min N beta L(m) dbeta dL/L wall(s)")
    stored, failed = {}, 0
    for lab in tqdm(args.labels, desc="grid convergence", unit="pulse", disable=args.quiet,
                    file=sys.stderr):
        pulse, params = read_pulse(args.file, lab)
        if not pulse.converged:
            raise UsageError(f"--labels: {lab} is stored not converged; nothing to refine")
        if args.adapted is None:
            sol = pulse_solution(pulse, params)
        else:
            sol = relaid(params, pulse, args.adapted)
            if sol is None:
                print(f"{lab}: the re-solve on an adapted grid of {args.adapted} did not "
                      "converge; nothing refined")
                failed += 1
                continue
        rows = grid_convergence(params, sol, args.levels)
        for r in rows:
            print(f"{lab} {r.tau_d_ratio:.9f} {r.n} {r.beta:.10f} {r.L:.8g} {r.dbeta:+.3e} "
                  f"{r.dL_rel:+.3e} {r.wall_time:.1f}" + ("" if r.converged else " not converged"))
        p_beta, p_L = observed_order(rows)
        ok = all(r.converged for r in rows)
        failed += not ok
        print(f"{lab}: observed order {p_beta:.2f} (beta), {p_L:.2f} (L)"
              + ("" if ok else "; a level did not converge: its change is not an estimate")
              + ("" if math.isfinite(p_beta) else " (needs 2 converged levels)"))
        stored[lab] = {"grid_convergence_n": [r.n for r in rows],
                       "grid_convergence_beta": [r.beta for r in rows],
                       "grid_convergence_L": [r.L for r in rows],
                       "grid_convergence_dbeta": [r.dbeta for r in rows],
                       "grid_convergence_dL_rel": [r.dL_rel for r in rows],
                       "grid_convergence_converged": [r.converged for r in rows],
                       "grid_convergence_order_beta": p_beta, "grid_convergence_order_L": p_L}
    if args.write:
        def fill(h5):
            for lab, attrs in stored.items():
                h5["pulses"][lab].attrs.update(attrs)
        atomic_update(args.file, fill)
        print(f"stored as grid_convergence_* attributes of {len(stored)} pulse(s) in {args.file}")
    return 1 if failed else 0


def relaid(params, pulse, n_points):
    """``pulse`` re-solved at its τ_d on a grid of ``n_points`` adapted to it (the default
    layout, :class:`~slippulse.steady.solver.GridSpec`), or None when Newton does not converge:
    a discretisation independent of the stored one (e.g. a deformed grid's) to refine beside it."""
    import numpy as np
    from ..steady.solver import solve_pulse
    sol = solve_pulse(params, pulse.tau_d_ratio, n_points=n_points, passes=0,
                      guess=(pulse.xi, np.log(pulse.v), pulse.beta))
    return sol if sol.stats.converged else None


def register(ss) -> None:
    p = ss.add_parser("grid-convergence", help="stored pulses re-solved on nested refinements",
                      description="Re-solves each pulse --labels of FILE on its own grid with "
                                  "all midpoints inserted (N -> 2N - 1), --levels times, each "
                                  "level from the one before, as the family's grid check does "
                                  "(on the line normal to the family, the change at fixed "
                                  "tau_d), and prints beta, L and the change per level, and the "
                                  "observed order log2 of the ratio of the last two changes "
                                  "(4 where the errors are asymptotic). Exit 1 when a level "
                                  "does not converge.")
    p.add_argument("file", metavar="FILE", help="HDF5 family file")
    p.add_argument("--labels", nargs="+", required=True, metavar="LABEL", help="pulses to refine")
    p.add_argument("--levels", type=int, default=2,
                   help="nested refinements, an integer in [1, 4] (default 2: N, 2N - 1, 4N - 3)")
    p.add_argument("--adapted", type=int, default=None, metavar="N",
                   help="first re-solve each pulse at its tau_d on a grid of N points adapted to "
                        "it (the default layout), and refine that one: an independent "
                        "discretisation beside the stored grid's (not with --write)")
    p.add_argument("--write", action="store_true",
                   help="store the levels as grid_convergence_* attributes of each pulse")
    p.add_argument("-q", "--quiet", action="store_true", help="no progress bar")
    p.set_defaults(func=cmd_grid_convergence)
