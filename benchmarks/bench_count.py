"""The contour count's two phase rules side by side: evaluations, wall time and count.

    python benchmarks/bench_count.py [FAMILY.h5 LABEL X0 X1 Y1 [N0]]
    OMP_NUM_THREADS=S python benchmarks/bench_count.py --workers K T FAMILY.h5 LABEL X0 X1 Y1 [N0]

Without arguments: operators with known zeros (tests/test_count.py's kind), with and without a
large smooth phase drift (det M × e^{60σ}, as the N far zeros give the deep pulses), and the
1.2 τ_min pulse of the built-in default (solved on N = 700, level 0 on its map at N = 300, as in
tests/test_count.py). With a family file: that pulse's count in
the box [X0, X1] × ±Y1 c_p/L on level 0 (its own grid, or N0 points on its map), by both rules.
'wrapped' is the rule before stop 31 (the wrapped change of arg det below 0.6 rad as well);
'trapezoid' is the product's (the branch from the trapezoid of d ln det M/dσ; docs/spectrum.md
§6), evaluated on both halves of the box or, for an operator with real coefficients
(M(σ̄) = conj M(σ): the pulse operators), on Im σ ≥ 0 only (the product since stop 31). Each
line is three walks: stop 30 (wrapped, both halves), the trapezoid rule on both halves, and the
product (trapezoid, mirrored halves); the ratio is the first's evaluations over the last's.

--workers: the product's walk on one pulse serially (S threads, from OMP_NUM_THREADS) and on K
worker processes of T threads each (``--count-workers``), side by side: evaluations (the same
points), wall times and their ratio.
"""
from __future__ import annotations

import os
import sys
import time

import numpy as np

from slippulse.core.executor import ExecutorSettings
from slippulse.spectrum.count import count_unstable


class Known:
    """M(σ) = e^{Tσ} Q diag(σ − λ_j) Q⁻¹ with known zeros λ_j."""

    rate_unit = 1.0

    def __init__(self, lams, T=0.0, n=12, seed=0):
        rng = np.random.default_rng(seed)
        self.lams = np.concatenate([lams, 50.0 + rng.uniform(1, 5, n - len(lams))])
        self.Q = rng.normal(size=(n, n)) + 1j * rng.normal(size=(n, n))
        self.Qi = np.linalg.inv(self.Q)
        self.T = T

    def matrices(self, z, deriv=False):
        M = self.Q @ np.diag(z - self.lams) @ self.Qi
        e = np.exp(self.T * z)
        dM = (np.eye(self.lams.size) + self.T * M) * e if deriv else None
        return M * e, dM


def pulse_operator(path, label, n0):
    from slippulse.core.h5io import read_pulse
    from slippulse.spectrum.pulse import order4_pulse
    from slippulse.spectrum.family import solve_level0
    from slippulse.spectrum.operators import StabilityOperator
    from slippulse.steady.grid import GridMap
    pulse, params = read_pulse(path, label)
    pulse = order4_pulse(pulse, params)
    if n0:
        pulse, why = solve_level0(pulse, params, GridMap(pulse.xi), n0)
        if why:
            raise SystemExit(f"{label}: level 0 on N = {n0} failed: {why}")
    return StabilityOperator(pulse, params, pin_translation=True)


class BothHalves:
    """The operator with its conjugate symmetry hidden (every point evaluated)."""

    conjugate_symmetric = False

    def __init__(self, op):
        self.op = op
        self.rate_unit = op.rate_unit

    def matrices(self, z, deriv=False):
        return self.op.matrices(z, deriv)


def row(name, op, box):
    out = []
    for rule, o in (("wrapped", BothHalves(op)), ("trapezoid", BothHalves(op)), ("trapezoid", op)):
        t0 = time.perf_counter()
        r = count_unstable(o, box, max_evals=20000, phase_rule=rule)
        out.append((r, time.perf_counter() - t0))
    counts = " / ".join(str(r.count) for r, _ in out)
    evals = " / ".join(str(r.n_evals) for r, _ in out)
    walls = " / ".join(f"{t:.1f}" for _, t in out)
    print(f"| {name} | {box} | {counts} | {evals} | {walls} | "
          f"{out[0][0].n_evals / out[-1][0].n_evals:.1f} |")


def workers_row(path, label, box, n0, workers, threads, serial_threads):
    """The product's walk on one pulse, serially (`serial_threads` threads in BLAS and numba,
    as the process was started) and on `workers` processes of `threads` threads each."""
    op = pulse_operator(path, label, n0)
    out = []
    for k, t in ((1, serial_threads), (workers, threads)):
        t0 = time.perf_counter()
        r = count_unstable(op, box, max_evals=20000, executor=ExecutorSettings(workers=k, threads=t))
        out.append((r, time.perf_counter() - t0))
    (a, ta), (b, tb) = out
    same = np.array_equal(a.points, b.points)
    print(f"| {label}, N = {op.n} | {box} | {a.count} / {b.count} | {a.n_evals} / {b.n_evals} "
          f"(same points: {same}) | {ta:.0f} / {tb:.0f} | 1 x {serial_threads} / {workers} x "
          f"{threads} | {ta / tb:.2f} |")


def main(argv):
    print(f"load average at start: {os.getloadavg()}")
    if argv and argv[0] == "--workers":
        # --workers K T FAMILY.h5 LABEL X0 X1 Y1 [N0]: serial against K workers of T threads
        k, t = int(argv[1]), int(argv[2])
        path, label, x0, x1, y1 = argv[3:8]
        n0 = int(argv[8]) if len(argv) > 8 else 0
        serial = int(os.environ.get("OMP_NUM_THREADS", "0") or 0)
        print("| pulse | box (c_p/L) | count (serial / workers) | evaluations | wall (s) | "
              "processes x threads | ratio |")
        print("|---|---|---|---|---|---|---|")
        workers_row(path, label, (float(x0), float(x1), float(y1)), n0, k, t, serial)
        return
    print("| operator | box (c_p/L) | count (stop 30 / trapezoid / product) | evaluations | "
          "wall (s) | ratio |")
    print("|---|---|---|---|---|---|")
    if argv:
        path, label, x0, x1, y1 = argv[:5]
        n0 = int(argv[5]) if len(argv) > 5 else 0
        row(f"{label}, N0 = {n0 or 'own'}", pulse_operator(path, label, n0),
            (float(x0), float(x1), float(y1)))
        return
    zeros = np.array([0.5, 2 + 1j, 2 - 1j, -1.0], complex)
    pair = np.array([0.0102 + 1.0j, 0.0102 + 1.0001j, 3.9], complex)
    row("3 zeros inside", Known(zeros), (0.01, 4.0, 4.0))
    row("3 zeros inside, drift e^{60 sigma}", Known(zeros, T=5.0), (0.01, 4.0, 4.0))
    row("close pair + 1, drift e^{60 sigma}", Known(pair, T=5.0), (0.01, 4.0, 4.0))
    from slippulse.core.h5io import write_pulse
    from slippulse.core.params import DEFAULT
    from slippulse.steady.solver import solve_pulse
    import tempfile
    sol = solve_pulse(DEFAULT, 1.2, n_points=700)     # tests/conftest.py's pulse12
    with tempfile.TemporaryDirectory() as d:
        f = os.path.join(d, "p.h5")
        write_pulse(f, sol.to_pulse(), DEFAULT)
        row("1.2 tau_min pulse, level 0 on N = 300", pulse_operator(f, "td1.2000", 300),
            (0.5, 34.0, 34.0))


if __name__ == "__main__":
    main(sys.argv[1:])
