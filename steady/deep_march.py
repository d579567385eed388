"""Pseudo-arclength march of the deep family (τ_d → τ̃*), one npz per converged step.

    python steady/deep_march.py FAMILY.h5 LABEL [--steps K] [--outdir runs/deep]
        [--stretch] [--check] [--max-points M] [--max-length LMAX] [--check-only K1,K2]

Starts from pulse LABEL of a family file, on its grid (or resumes from the last step already in
OUTDIR/arc_*.npz) and takes up to K arclength steps in (ln(1−β), τ_d/τ_min)
(:func:`slippulse.steady.continuation.march_arclength`). Each step is written as arc_kkk.npz with the
grid xi, the unknowns x = (ln v, β, τ_d/τ_min), L and the solver statistics. Steps are not at
round τ_d (the family file's labels keep 4 decimals); `steady/divergence.py` reads them.

--stretch deforms the grid with the pulse every step (:func:`~slippulse.steady.continuation.stretch_grid`:
no interpolation, no regrid jumps). --check re-solves every step on
its grid with the midpoints inserted (N → 2N − 1, :func:`~slippulse.steady.continuation.check_grid_2n`,
differences at fixed τ_d stored as dbeta, dL_rel); while the criterion (|Δβ| ≤ 1e-5,
|ΔL|/L ≤ 1e-4) fails and 4N − 3 ≤ --max-points, the refined pulse replaces the march's and is
checked again; the step written is the pulse whose check passed (or the last one checked), and
the march goes on from it. --max-length stops once L exceeds it (m).
--refine starts from LABEL re-solved on its grid with the midpoints inserted (2N − 1 nodes): two
marches from the same pulse, with and without --refine, compare N and 2N − 1 along the branch.
--resolve N starts from LABEL re-solved at the label's round τ_d by this code (the state integrator of order 4
since the merge of issue11-state; the family file may hold order-2 pulses) on N adapted points.
--check-only K1,K2 grid-checks stored steps instead of marching (results into their npz).
Cost on the shared 2-core machine: ≈ 5–15 s per step at N = 2000, 20–80 s at N = 4000; a check at
N = 2000 → 3999 about 1–3 min. Interrupted runs resume from the last npz.
"""
import argparse
import glob
import math
import os
import sys
import time

import numpy as np

from slippulse.core.h5io import read_pulse
from slippulse.core.params import DEFAULT
from slippulse.steady.continuation import DeepSettings, check_grid_2n, march_arclength
from slippulse.steady.equations import SteadyProblem
from slippulse.steady.newton import SolveStats
from slippulse.steady.solver import SteadySolution, front_pin, solve_pulse

TOL_BETA, TOL_L = 1e-5, 1e-4


def rebuild(params, xi, x, pin_index, y_pin, state_order=4):
    """A SteadySolution of ``free="both"`` from stored grid and unknowns."""
    prob = SteadyProblem(params, float(x[-1]), xi, pin_index, y_pin, free="both",
                         state_order=state_order)
    x = np.asarray(x, float)
    r = float(np.abs(prob.residual(x)).max())
    return SteadySolution(prob, x, SolveStats(r <= 1e-13, "stored step", 0, r), 0.0, 0)


def check_step(params, path, stages, log):
    """Grid check of a stored step (nested N -> 2N − 1, differences at fixed τ_d), written into
    its npz (dbeta, dL_rel, n_check, and the fine pulse's q_fine, beta_fine, L_fine)."""
    z = dict(np.load(path))
    if np.isfinite(float(z.get("dbeta", np.nan))):
        log(f"{path}: checked already (dbeta={float(z['dbeta']):.2e})")
        return
    sol = rebuild(params, z["xi"], z["x"], int(z["pin_index"]), float(z["y_pin"]),
                  int(z.get("state_order", 2)))
    n = sol.xi.size
    fine, db, dl = check_grid_2n(params, sol, n, nested=True, stages=stages, max_iter=15)
    log(f"{path}: N={n} -> {fine.xi.size}: dbeta={db:.2e} dL/L={dl:.2e} "
        f"({fine.stats.iterations} it., {fine.stats.message[:60]})")
    if not fine.stats.converged:
        return
    pf = fine.to_pulse()
    z.update(dbeta=db, dL_rel=dl, n_check=n, passed=db <= TOL_BETA and dl <= TOL_L,
             q_fine=float(fine.x[-1]), beta_fine=pf.beta, L_fine=pf.L)
    np.savez(path + ".tmp.npz", **z)
    os.replace(path + ".tmp.npz", path)


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("family")
    ap.add_argument("label")
    ap.add_argument("--steps", type=int, default=20)
    ap.add_argument("--ds-max", type=float, default=0.4)
    ap.add_argument("--stretch", action="store_true")
    ap.add_argument("--check", action="store_true")
    ap.add_argument("--max-points", type=int, default=4000)
    ap.add_argument("--max-length", type=float, default=math.inf)
    ap.add_argument("--max-iter", type=int, default=25)
    ap.add_argument("--resolve", type=int, default=0, metavar="N",
                    help="re-solve the start pulse at its tau_d with this code's state "
                         "integrator on an adapted grid of N points")
    ap.add_argument("--refine", action="store_true",
                    help="start from the start pulse re-solved on its grid with the midpoints "
                         "inserted (2N - 1 nodes)")
    ap.add_argument("--check-only", default=None, metavar="K1,K2,...",
                    help="grid-check these steps already in OUTDIR (nested N -> 2N-1), no march")
    ap.add_argument("--outdir", default=os.path.join("runs", "deep"))
    a = ap.parse_args(argv)
    P = DEFAULT
    os.makedirs(a.outdir, exist_ok=True)
    deep = DeepSettings(ds_max=a.ds_max, stretch=a.stretch, max_iter=a.max_iter)
    done = sorted(glob.glob(os.path.join(a.outdir, "arc_*.npz")))
    t0 = time.perf_counter()

    def log(msg):
        print(f"{time.perf_counter() - t0:8.1f} s  {msg}", file=sys.stderr, flush=True)

    if a.check_only:
        for k in (int(t) for t in a.check_only.split(",")):
            check_step(P, os.path.join(a.outdir, f"arc_{k:03d}.npz"), deep.homotopy, log)
        return 0
    if done:
        z = np.load(done[-1])
        sol0 = rebuild(P, z["xi"], z["x"], int(z["pin_index"]), float(z["y_pin"]),
                       int(z["state_order"]) if "state_order" in z else 2)
        log(f"resuming from {done[-1]} (N={z['xi'].size})")
    else:
        pu, _ = read_pulse(a.family, a.label)
        y = np.log(pu.v)
        if a.resolve:
            # the stored pulse re-solved at its τ_d with this code's state integrator, on a grid
            # of `resolve` points adapted to it
            q0 = float(a.label[2:])          # the label's round τ_d (tdX.XXXX)
            s0 = solve_pulse(P, q0, n_points=a.resolve, guess=(pu.xi, y, pu.beta), passes=0,
                             max_iter=30)
            log(f"start re-solved at tau_d/tau_min={q0:.7f}, N={a.resolve}: "
                f"{s0.stats.message} ({s0.stats.iterations} it.)")
            if not s0.stats.converged:
                return 1
            sol0 = rebuild(P, s0.xi, np.concatenate([s0.x, [q0]]), s0.problem.pin_index,
                           s0.problem.y_pin)
        else:
            k, _ = front_pin(pu.xi, y, math.log(P.v_stick(pu.tau_d_ratio * P.tau_min)))
            sol0 = rebuild(P, pu.xi, np.concatenate([y, [pu.beta, pu.tau_d_ratio]]), k,
                           float(y[k]), int(pu.extra.get("state_order", 2)))
        if a.refine:
            fine, db, dl = check_grid_2n(P, sol0, sol0.xi.size, nested=True, stages=deep.homotopy,
                                         max_iter=15)
            log(f"start refined N={sol0.xi.size} -> {fine.xi.size}: dbeta={db:.2e} dL/L={dl:.2e}"
                f" ({fine.stats.iterations} it., {fine.stats.message[:60]})")
            if not fine.stats.converged:
                return 1
            sol0 = fine
    start = (sol0.xi, sol0.x[:-2], float(sol0.x[-2]), float(sol0.x[-1]))
    n0 = sol0.xi.size
    k0 = len(done)
    handoff = {}

    def progress(ratio, pulse, msg):
        log(f"{ratio:.8f}  {msg[:110]}")

    march = march_arclength(P, start, n0, deep=deep, progress=progress, handoff=handoff)
    for k, (sol, (t_a, t_Q)) in enumerate(march, start=k0 + 1):
        pu = sol.to_pulse()
        info = {"dbeta": np.nan, "dL_rel": np.nan, "n_check": 0, "passed": False}
        if a.check:
            cur = sol
            while True:
                n_c = cur.xi.size
                fine, db, dl = check_grid_2n(P, cur, n_c, nested=True, stages=deep.homotopy,
                                             max_iter=15)
                ok = bool(fine.stats.converged)
                log(f"check N={n_c} -> {fine.xi.size}: dbeta={db:.2e} dL/L={dl:.2e} "
                    f"({fine.stats.iterations} it., {fine.stats.message[:50]})")
                if not ok:
                    break
                info = {"dbeta": db, "dL_rel": dl, "n_check": n_c,
                        "passed": db <= TOL_BETA and dl <= TOL_L}
                if info["passed"] or 2 * fine.xi.size - 1 > a.max_points:
                    break
                cur = fine
            if cur is not sol:
                # the march and the written pulse go on from the pulse whose check passed
                handoff["sol"] = cur
                sol, pu = cur, cur.to_pulse()
        path = os.path.join(a.outdir, f"arc_{k:03d}.npz")
        np.savez(path + ".tmp.npz", xi=sol.xi, x=sol.x, L=pu.L, t_a=t_a, t_Q=t_Q,
                 max_residual=pu.max_residual, pin_index=sol.problem.pin_index,
                 y_pin=sol.problem.y_pin, state_order=sol.problem.state_order, **info)
        os.replace(path + ".tmp.npz", path)
        print(f"step {k}: N={sol.xi.size} tau_d/tau_min={sol.x[-1]:.8f} beta={pu.beta:.8f} "
              f"L={pu.L:.5g} m t_Q={t_Q:+.3f} max|D|={pu.max_residual:.1e} "
              f"dbeta={info['dbeta']:.1e} dL/L={info['dL_rel']:.1e} (N={info['n_check']})",
              flush=True)
        if k - k0 >= a.steps or pu.L >= a.max_length:
            break
    return 0


if __name__ == "__main__":
    sys.exit(main())
