"""The held deep march's corrector with the two line searches, side by side.

    python benchmarks/bench_line_search_held.py [--seed SEED.h5]

(default seed: the committed seed in steady/seeds/ whose deepest pulse is 9.47 km long)

Resumes the "auto" march from the committed 9.47 km seed (held, N = 6614) as
``slippulse steady family --from 1.2 --to 1.0080 --ds-min 0.0002 --spacing 0.03`` does, without
the recentre at the start (it changes nothing here), and stops at the corrector of its second
step, the attempt at ds = 0.00064 that failed after 25 iterations with the ‖r‖₂ line search
(≈ 2 min to get there). From that attempt's guess it runs both line searches on the same
arclength problem (25 iterations at most, no creep), one after the other, and prints iterations,
max|r|, ‖δ‖₂ and wall time for each, the smallest singular value of the Jacobian at the guess
(inverse iteration), the machine load before and after. About 6 min on two
threads here.
"""
from __future__ import annotations

import argparse
import os
import shutil
import sys
import tempfile
import time

import numpy as np
import scipy.linalg as sla

import slippulse.steady.continuation.deep as deep
import slippulse.steady.continuation.family as family
from slippulse.core.params import Parameters
from slippulse.steady.continuation.arclength import DeepSettings
from slippulse.steady.newton import newton

ROOT = os.path.join(os.path.dirname(__file__), os.pardir)


class _Got(Exception):
    pass


def capture(seed: str, which: int = 3):
    """The arclength problem and guess of the march's ``which``-th corrector call."""
    real, calls, box = deep.newton, [], {}

    def spy(problem, x0, **kw):
        calls.append(1)
        if len(calls) == which:
            box.update(problem=problem, x0=np.array(x0), kw=kw)
            raise _Got
        return real(problem, x0, **kw)

    tmp = tempfile.mkdtemp()
    out = os.path.join(tmp, "deep.h5")
    shutil.copy(seed, out)
    deep.newton, rec = spy, family._recentre
    family._recentre = lambda *a, **k: False
    try:
        family.run_family(Parameters(), out, start=1.2, stop=1.008, deep="auto", max_length=9700,
                          deep_settings=DeepSettings(ds_min=0.0002, spacing=0.03,
                                                     max_length=9700))
    except _Got:
        pass
    finally:
        deep.newton, family._recentre = real, rec
        shutil.rmtree(tmp, ignore_errors=True)
    if "problem" not in box:
        sys.exit("the march did not reach the corrector to measure")
    return box


def sigma_min(problem, x, iters=30):
    _, J = problem.residual_and_jacobian(x)
    lu = sla.lu_factor(J)
    v = np.random.default_rng(0).standard_normal(J.shape[0])
    s = np.nan
    for _ in range(iters):
        w = sla.lu_solve(lu, v)
        w /= np.linalg.norm(w)
        v = sla.lu_solve(lu, w, trans=1)
        s = 1.0 / np.linalg.norm(v)
        v /= np.linalg.norm(v)
    return s, float(np.abs(J).max())


def seed_of_length(length=9473.0):
    """The committed seed (steady/seeds/*.h5) whose deepest pulse is nearest ``length`` m."""
    import glob

    from slippulse.core.h5io import list_pulses, read_pulse
    best = None
    for path in glob.glob(os.path.join(ROOT, "steady", "seeds", "*.h5")):
        L = max(read_pulse(path, lab)[0].L for lab in list_pulses(path))
        if best is None or abs(L - length) < best[1]:
            best = (path, abs(L - length))
    return best[0] if best else None


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--seed", default=None, help="seed file (default: the 9.47 km seed)")
    a = ap.parse_args(argv)
    a.seed = a.seed or seed_of_length()
    load0 = os.getloadavg()
    t0 = time.perf_counter()
    box = capture(a.seed)
    print(f"captured the corrector of the 2nd step (ds = {box['problem'].ds:.3g}, "
          f"N = {box['problem'].base.n}) in {time.perf_counter() - t0:.0f} s")
    rows = []
    for ls in ("residual", "natural"):
        t = time.perf_counter()
        x, st = newton(box["problem"], box["x0"], tol=1e-13, max_iter=25, line_search=ls)
        rows.append((ls, st, time.perf_counter() - t))
    print("| line search | converged | iterations | max|r| | ‖δ‖₂ first → last | wall (s) |")
    print("|---|---|---|---|---|---|")
    for ls, st, w in rows:
        c = st.corrections
        print(f"| {ls} | {st.converged} | {st.iterations} | {st.max_residual:.1e} | "
              f"{c[0]:.2g} → {c[-1]:.2g} | {w:.0f} |")
    ratio = rows[0][2] / rows[1][2]
    print(f"residual / natural wall time: {ratio:.2f}")
    s, jmax = sigma_min(box["problem"], box["x0"])
    print(f"smallest singular value of the Jacobian at the guess ≈ {s:.1e} (max|J| = {jmax:.0f})")
    print(f"load average before {load0[0]:.2f}, after {os.getloadavg()[0]:.2f}")


if __name__ == "__main__":
    main()
