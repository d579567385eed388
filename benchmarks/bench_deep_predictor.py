"""Deep-march predictors side by side: K arclength steps from the deepest pulse of a family file with
each predictor of the deformed grid (``DeepSettings.predictor``: "tangent", "length", "secant").

Run:  python benchmarks/bench_deep_predictor.py FAMILY.h5 [--steps 12] [--ds 0.0002]
          [--predictors tangent length secant]

The start is what a resumed ``slippulse steady family`` starts from (the deepest converged pulse of
the file, ``family._resume``), with the product's deep settings (``auto_deep_settings``, ds_min
0.0002) and the same first ds for every predictor (the history-free start: "length" and
"secant" take over after the first accepted step). Per predictor it prints, per step: ds, Newton
iterations, failed attempts, wall time, L; then the L gained, the iterations and the wall in all,
and the pace in km of L per hour, with the ratios to the first predictor. One process, the
predictors one after the other. Read-only on FAMILY.h5.
"""
from __future__ import annotations

import argparse
import dataclasses
import os
import time

from slippulse.core.params import DEFAULT as PARAMS
from slippulse.steady.continuation.arclength import DeepSettings
from slippulse.steady.continuation.deep import DeepMarch
from slippulse.steady.continuation.family import _resume, auto_deep_settings
from slippulse.steady.continuation.report import FamilyReport


def march(path, predictor, steps, ds0):
    start = _resume(PARAMS, path, FamilyReport())
    settings = dataclasses.replace(auto_deep_settings(DeepSettings(ds_min=0.0002)),
                                   predictor=predictor)
    m = DeepMarch(PARAMS, (start.xi, start.y, start.beta, start.q), settings=settings)
    m.ds = ds0
    L0, rows, t_all = m.L, [], time.perf_counter()
    for i in range(steps):
        a0, it0, t0, ds = m.n_attempts, m.n_iterations, time.perf_counter(), m.ds
        msg = m.step()
        rows.append((i + 1, ds, m.n_iterations - it0, m.n_attempts - a0 - 1,
                     time.perf_counter() - t0, m.L, m.last_predictor))
        if msg is not None:
            print(f"  {predictor}: failed: {msg}")
            break
    return L0, rows, time.perf_counter() - t_all, m


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("family")
    ap.add_argument("--steps", type=int, default=12)
    ap.add_argument("--ds", type=float, default=0.0002)
    ap.add_argument("--predictors", nargs="+", default=["tangent", "length", "secant"])
    a = ap.parse_args()
    print(f"load average at start: {os.getloadavg()}")
    summary = []
    for p in a.predictors:
        L0, rows, wall, m = march(a.family, p, a.steps, a.ds)
        print(f"\n{p}: start L = {L0:.1f} m, tau_d/tau_min = {m.q:.7f} at the end")
        print("| step | ds | iterations | failed | wall (s) | L (m) | predictor used |")
        print("|---|---|---|---|---|---|---|")
        for r in rows:
            print(f"| {r[0]} | {r[1]:.3g} | {r[2]} | {r[3]} | {r[4]:.1f} | {r[5]:.1f} | {r[6]} |")
        gain = m.L - L0
        summary.append((p, gain, m.n_iterations, m.n_failed, wall, gain / 1e3 / (wall / 3600)))
    print("\n| predictor | L gained (m) | iterations | failed attempts | wall (s) | km/h | pace ratio |")
    print("|---|---|---|---|---|---|---|")
    base = summary[0][5]
    for p, gain, its, nf, wall, pace in summary:
        print(f"| {p} | {gain:.1f} | {its} | {nf} | {wall:.0f} | {pace:.2f} | {pace / base:.2f} |")
    print(f"load average at end: {os.getloadavg()}")


if __name__ == "__main__":
    main()
