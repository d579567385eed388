"""The deep march with and without reusing the corrector's LU (``DeepSettings.reuse_lu`` and
``chord``), side by side: K arclength steps from the deepest pulse of a family file, each way, at
the same fixed ds.

Run:  python benchmarks/bench_march_lu.py FAMILY.h5 [--steps 8] [--ds 0.0004]

The start is what a resumed ``slippulse steady family`` starts from (``family._resume``), with
the product's deep settings (``auto_deep_settings``, ds_min 0.0002). ds is reset to --ds before
every step, so both marches take the same arclength steps and their pulses can be compared one
by one (the only difference is how the tangent and the corrector's first iterations are
computed; the tolerance max|r| ≤ 1e-13 is the same). Prints per step: Newton iterations, chord
iterations, wall time, L; then the wall in all, the ratio, and the largest differences of β,
τ_d/τ_min and L/L between the two marches' pulses. One process, one after the other; read-only on
FAMILY.h5. Set OPENBLAS_NUM_THREADS to choose the threads of the LU.
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


def march(path, reuse, steps, ds):
    start = _resume(PARAMS, path, FamilyReport())
    settings = dataclasses.replace(auto_deep_settings(DeepSettings(ds_min=0.0002)), reuse_lu=reuse,
                                   chord=reuse)
    m = DeepMarch(PARAMS, (start.xi, start.y, start.beta, start.q), settings=settings)
    rows, t_all = [], time.perf_counter()
    for i in range(steps):
        m.ds = ds
        t0 = time.perf_counter()
        msg = m.step()
        st = m.sol.stats
        rows.append((i + 1, st.iterations, st.chord_iterations, time.perf_counter() - t0,
                     m.L, m.beta, m.q))
        if msg is not None:
            print(f"  reuse_lu={reuse}: failed: {msg}")
            break
    return rows, time.perf_counter() - t_all


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("family")
    ap.add_argument("--steps", type=int, default=8)
    ap.add_argument("--ds", type=float, default=0.0004)
    a = ap.parse_args()
    print(f"load average at start: {os.getloadavg()}; OPENBLAS_NUM_THREADS="
          f"{os.environ.get('OPENBLAS_NUM_THREADS', 'unset')}")
    out = {}
    for reuse in (False, True):
        rows, wall = march(a.family, reuse, a.steps, a.ds)
        out[reuse] = (rows, wall)
        print(f"\nreuse_lu={reuse}: {wall:.1f} s for {len(rows)} steps")
        print("| step | Newton it. | chord it. | wall (s) | L (m) |")
        print("|---|---|---|---|---|")
        for r in rows:
            print(f"| {r[0]} | {r[1]} | {r[2]} | {r[3]:.2f} | {r[4]:.2f} |")
    (r0, w0), (r1, w1) = out[False], out[True]
    k = min(len(r0), len(r1))
    db = max(abs(r0[i][5] - r1[i][5]) for i in range(k))
    dq = max(abs(r0[i][6] - r1[i][6]) for i in range(k))
    dL = max(abs(r0[i][4] / r1[i][4] - 1.0) for i in range(k))
    print(f"\nwall: {w0:.1f} s without, {w1:.1f} s with reuse: ratio {w0 / w1:.2f}")
    print(f"over {k} common steps: max |dbeta| = {db:.2e}, max |d tau_d/tau_min| = {dq:.2e}, "
          f"max |dL/L| = {dL:.2e}")
    print(f"load average at end: {os.getloadavg()}")


if __name__ == "__main__":
    main()
