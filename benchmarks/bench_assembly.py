"""The kernel assembly of M(σ) by the sub-panel rule before stop 33 and by the product's, side by
side: wall time per evaluation, the change of M and M′, and a contour count with each.

    python benchmarks/bench_assembly.py FAMILY.h5 LABEL [--count X0 X1 Y1] [--reference]

The kernel 𝒲̃(σ) of the stability operator has an exponential part e^{−(1+sβ)κ|r|}, s = sign r,
κ = σ/(c_s(1 − β²)). Before stop 33 every segment longer than 1/|κ| was split into ⌈|κ| h⌉
sub-panels on both sides while the slower decay, (1 − β) Re κ, left it alive. On the side r < 0
the exponential turns at (1 − β)|κ| only, ≈ 2e-3 |κ| at the deep pulses: the product splits each
side by its own rate (``split_per_side``, :func:`slippulse.spectrum.kernels.assemble_w`).

For each σ on the contour of a count (units c_p/L): the seconds of M(σ), M′(σ) by each rule
(one thread: run with OMP_NUM_THREADS=1 NUMBA_NUM_THREADS=1), their ratio, and the relative
Frobenius change of M and M′ between the rules. With ``--reference`` also each rule's distance
to the old rule with 3× the sub-panels, on the columns of segments with |κ| h ≤ 100 (the tail
segments beyond that are under-resolved by both: docs/spectrum.md §8). With ``--count``: the
count in [X0, X1] × ±Y1 on the pulse's own grid by each rule (count, winding, evaluations, wall
time, ratio).
"""
from __future__ import annotations

import argparse
import time

import numpy as np

from slippulse.core.h5io import read_pulse
from slippulse.spectrum.count import count_unstable
from slippulse.spectrum.operators import StabilityOperator
from slippulse.spectrum.pulse import order4_pulse
from slippulse.spectrum.kernels import KernelTables, assemble_w

POINTS = (1e-4 + 0.01j, 1e-4 + 1j, 1e-4 + 4j, 0.5 + 0.5j, 2 + 4j, 4 + 4j, 4 + 0j)


def _rel(a, b, cols=slice(None)):
    return np.linalg.norm((a - b)[:, cols]) / np.linalg.norm(b[:, cols])


def _w(el, tab, per_side, scale):
    n = el.xi.size
    arrs = [np.zeros((n, n), complex) for _ in range(4)]
    assemble_w(el.xi, *tab.args(), *arrs, per_side, scale)
    return arrs


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("family")
    ap.add_argument("label")
    ap.add_argument("--count", nargs=3, type=float, metavar=("X0", "X1", "Y1"))
    ap.add_argument("--reference", action="store_true")
    a = ap.parse_args(argv)
    pulse, params = read_pulse(a.family, a.label)
    pulse = order4_pulse(pulse, params)
    op = StabilityOperator(pulse, params, pin_translation=True)
    el = op.elastic
    unit = op.rate_unit
    print(f"{a.label}: N={pulse.n_points}, beta={pulse.beta:.6f}, L={pulse.L:.4g} m")
    op.matrices(1e-3 * unit)                                   # compile
    tot = [0.0, 0.0]
    for z in POINTS:
        res = []
        for rule in (False, True):
            el.split_per_side = rule
            t = time.perf_counter()
            M, dM = op.matrices(z * unit)
            res.append((M, dM, time.perf_counter() - t))
        (M0, d0, t0), (M1, d1, t1) = res
        tot[0] += t0
        tot[1] += t1
        line = (f"sigma L/c_p = {z:<12}: old {t0:6.2f} s  new {t1:6.2f} s  ratio {t0 / t1:5.2f}  "
                f"|dM|/|M| {_rel(M1, M0):.1e}  |dM'|/|M'| {_rel(d1, d0):.1e}")
        if a.reference:
            tab = KernelTables(z * unit, el.beta, el.c_s, el.r_min, el.r_max)
            ref = _w(el, tab, False, 3.0)
            h = np.diff(el.xi)
            bad = np.flatnonzero(abs(tab.kappa) * h > 100.0)
            keep = np.setdiff1d(np.arange(el.xi.size), np.concatenate([bad, bad + 1]))
            errs = [[_rel(x, y, keep) for x, y in zip(_w(el, tab, rule, 1.0), ref)]
                    for rule in (False, True)]
            line += ("\n    to 3x sub-panels (W, dW/dsigma; cols |kappa| h <= 100): old "
                     f"{errs[0][0]:.1e} {errs[0][2]:.1e}  new {errs[1][0]:.1e} {errs[1][2]:.1e}"
                     f"  ({bad.size} segments beyond)")
        print(line, flush=True)
    print(f"all points: old {tot[0]:.1f} s, new {tot[1]:.1f} s, ratio {tot[0] / tot[1]:.2f}")
    if a.count:
        out = []
        for rule in (False, True):
            el.split_per_side = rule
            r = count_unstable(op, tuple(a.count), max_evals=1500)
            out.append(r)
            print(f"count {'new' if rule else 'old'}: {r.count} ({r.status}), winding "
                  f"{r.winding:.10f}, {r.n_evals} evaluations, {r.wall_time:.0f} s", flush=True)
        print(f"count wall-time ratio old/new: {out[0].wall_time / out[1].wall_time:.2f}")


if __name__ == "__main__":
    main()
