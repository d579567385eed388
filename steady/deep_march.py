"""Pseudo-arclength march of the deep family (τ_d → τ̃*), one npz per converged step.

    python steady/deep_march.py FAMILY.h5 LABEL [--steps K] [--outdir runs/deep]
        [--stretch] [--check] [--max-points M] [--max-length LMAX] [--resolve N]

The product command does the same into the family file, every pulse checked:
``slippulse steady family --from 1.2 --to 1.009`` (docs/steady.md §3). This script is the study
variant: it starts from pulse LABEL of a family file on its grid (or from LABEL re-solved at its
τ_d on N adapted points, ``--resolve N``; or resumes from the last OUTDIR/arc_*.npz) and takes up
to K steps of :class:`slippulse.steady.continuation.Continuation` (``--stretch``: the grid
deformed with the pulse). Each step goes to arc_kkk.npz (grid xi, unknowns x = (ln v, β, τ_d/τ_min), L,
pin, state order, and with ``--check`` the figures of
:func:`slippulse.steady.continuation.gridcheck.check_pulse`: the pulse whose check passed, N or
the body refinement chosen per step; the march goes on from it). The analysis (`slippulse steady divergence`, `steady
edges`) reads family files and tables, not these npz files.
"""
import argparse
import glob
import math
import os
import sys
import time

import numpy as np

from slippulse.core.h5io import STATE_ORDER, UNSTORED_STATE_ORDER, read_pulse, state_order_of
from slippulse.core.params import DEFAULT
from slippulse.steady.continuation import (GRID_TOLERANCE, Accepted, AdaptGrid, Continuation,
                                           FreeSteps, NewtonCorrector, Strategy, StretchGrid,
                                           TangentPredictor)
from slippulse.steady.continuation.gridcheck import as_both, check_pulse
from slippulse.steady.equations import SteadyProblem
from slippulse.steady.newton import NEWTON_TOL, SolveStats
from slippulse.steady.solver import MAX_POINTS, SteadySolution, front_pin, solve_pulse


def rebuild(params, xi, x, pin_index, y_pin, state_order=STATE_ORDER):
    """A SteadySolution of ``free="both"`` from stored grid and unknowns."""
    prob = SteadyProblem(params, float(x[-1]), xi, pin_index, y_pin, free="both",
                         state_order=state_order)
    x = np.asarray(x, float)
    r = float(np.abs(prob.residual(x)).max())
    return SteadySolution(prob, x, SolveStats(r <= NEWTON_TOL, "stored step", 0, r), 0.0, 0)


def load_pulse(source, label=None):
    """(parameters, SteadySolution of ``free="both"``) of a stored step (npz) or of a pulse of a
    family file (the pin at its leading edge)."""
    if source.endswith(".npz"):
        z = np.load(source)
        return DEFAULT, rebuild(DEFAULT, z["xi"], z["x"], int(z["pin_index"]), float(z["y_pin"]),
                                int(z["state_order"]) if "state_order" in z else UNSTORED_STATE_ORDER)
    pu, P = read_pulse(source, label)
    y = np.log(pu.v)
    k, _ = front_pin(pu.xi, y, math.log(P.v_stick(pu.tau_d_ratio * P.tau_min)))
    return P, rebuild(P, pu.xi, np.concatenate([y, [pu.beta, pu.tau_d_ratio]]), k, float(y[k]),
                      # a file without the attribute predates the order-4 state (order 2), read as the
                      # other readers do (core.h5io.state_order_of)
                      state_order_of(pu))


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("family")
    ap.add_argument("label")
    ap.add_argument("--steps", type=int, default=20)
    ap.add_argument("--ds-max", type=float, default=0.4)
    ap.add_argument("--stretch", action="store_true", help="deform the grid with the pulse")
    ap.add_argument("--check", action="store_true", help="grid-check every step")
    ap.add_argument("--max-points", type=int, default=MAX_POINTS)
    ap.add_argument("--max-length", type=float, default=math.inf)
    ap.add_argument("--max-iter", type=int, default=25)
    ap.add_argument("--resolve", type=int, default=0, metavar="N",
                    help="re-solve the start pulse at its tau_d on an adapted grid of N points")
    ap.add_argument("--outdir", default=os.path.join("runs", "deep"))
    a = ap.parse_args(argv)
    os.makedirs(a.outdir, exist_ok=True)
    done = sorted(glob.glob(os.path.join(a.outdir, "arc_*.npz")))
    t0 = time.perf_counter()

    def log(msg):
        print(f"{time.perf_counter() - t0:8.1f} s  {msg}", file=sys.stderr, flush=True)

    P, sol0 = load_pulse(done[-1] if done else a.family, None if done else a.label)
    if a.resolve and not done:
        s0 = solve_pulse(P, float(sol0.x[-1]), n_points=a.resolve,
                         guess=(sol0.xi, sol0.x[:-2], sol0.beta), passes=0, max_iter=30)
        log(f"start re-solved at N={a.resolve}: {s0.stats.message}")
        if not s0.stats.converged:
            return 1
        sol0 = as_both(P, s0)
    strategy = Strategy(TangentPredictor(), NewtonCorrector(max_iter=a.max_iter),
                        FreeSteps(ds=min(0.1, a.ds_max), ds_min=min(0.004, a.ds_max / 4),
                                  ds_max=a.ds_max),
                        StretchGrid(relay=0, recentre=0.0) if a.stretch else AdaptGrid())
    count = [len(done)]

    def on_accept(sol, extra):
        # check (the march goes on from the checked pulse), then one npz per step
        info, res = {"dbeta": np.nan, "dL_rel": np.nan, "n_check": 0, "passed": False}, None
        if a.check:
            res = check_pulse(P, sol, GRID_TOLERANCE, a.max_points, log=log)
            info = {"dbeta": res.dbeta, "dL_rel": res.dL_rel, "n_check": res.n,
                    "passed": res.passed, "n_body_levels": res.body_levels}
            sol = res.sol
        count[0] += 1
        pu = sol.to_pulse()
        path = os.path.join(a.outdir, f"arc_{count[0]:03d}.npz")
        np.savez(path + ".tmp.npz", xi=sol.xi, x=sol.x, L=pu.L, t_a=march.tangent[0],
                 t_Q=march.tangent[1], max_residual=pu.max_residual,
                 pin_index=sol.problem.pin_index, y_pin=sol.problem.y_pin,
                 state_order=sol.problem.state_order, **info)
        os.replace(path + ".tmp.npz", path)
        print(f"step {count[0]}: N={sol.xi.size} tau_d/tau_min={sol.x[-1]:.8f} "
              f"beta={pu.beta:.8f} L={pu.L:.5g} m dbeta={info['dbeta']:.1e} "
              f"dL/L={info['dL_rel']:.1e} (N={info['n_check']})", flush=True)
        return Accepted(True, sol)

    march = Continuation(P, sol0, strategy, max_length=a.max_length, on_accept=on_accept,
                         on_attempt=lambda r, p, m: log(f"{r:.8f}  {m[:110]}"))
    for _ in range(a.steps):
        if march.step() is not None:
            log(march.message)
            return 1
        if march.status != "running":
            break
    return 0


if __name__ == "__main__":
    sys.exit(main())
