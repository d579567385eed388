"""Benchmark of the SBI time stepper: time and memory per step, and accuracy of each history policy.

Usage (from the repository root):

    python benchmarks/bench_sbi.py timing --n 4096 --policy soe --history 2000 --steps 20
    python benchmarks/bench_sbi.py accuracy            # exact tests per policy, ~1 min
    python benchmarks/bench_sbi.py all                 # everything in benchmarks/sbi_results.md

``timing`` builds a rate-and-state run (τ_d = 1.2 τ_min, Gaussian bump, fixed Δt = 0.5 Δx/c_s),
fills the history with ``--history`` steps of (random) step averages — the cost of a step does not
depend on the values — and times ``--steps`` steps with 1 thread, then with 2 threads (numba and
FFTW). It prints one JSON line: median and minimum ms/step, the history policy's bytes, the process
peak RSS. ``all`` runs each (N, policy) in a fresh process so that the peak RSS is that
configuration's, with OMP_WAIT_POLICY=passive and NUMBA_THREADING_LAYER=workqueue (with the default
spinning OpenMP layer, 2 threads on a machine whose 2 cores are already busy take ~8 ms per
parallel region; set these for `timing` by hand too).
"""
from __future__ import annotations

import argparse
import json
import os
import resource
import subprocess
import sys
import time

import numpy as np

HERE = os.path.dirname(os.path.abspath(__file__))
sys.path.insert(0, os.path.join(HERE, "..", "tests"))


def _prefill(st, nhist, rng):
    """Give the history policy ``nhist`` past steps (small random step averages, so that the run
    stays near its initial state; the cost does not depend on the values)."""
    h = st.history
    if st.history_name == "soe":
        h.Y[:] = 1e-12 * (rng.standard_normal(h.Y.shape) + 1j * rng.standard_normal(h.Y.shape))
        h.count = nhist
    elif st.history_name == "window":
        h.hist[:] = 1e-12 * rng.standard_normal(h.hist.size) * (1 + 1j)
        h.count = nhist
    else:
        if h.cap < nhist + 8:
            h._grow(nhist + 8)
        h.hist[:nhist] = 1e-12 * rng.standard_normal((nhist, h.nk)) * (1 + 1j)
        h.head, h.count = nhist % h.cap, nhist
        h._ensure_weights(nhist + 8)


#: a cheaper SOE: 36 nodes instead of 75 (|P_soe − P| ≤ 2e−5 instead of 1e−7)
SOE_LITE = {"x_min": 1e-6, "x_max": 1e6, "h": 0.8}


def _policy(name):
    """'soe-lite' → ('soe', SOE_LITE); other names → (name, None)."""
    return ("soe", SOE_LITE) if name == "soe-lite" else (name, None)


def timing(n, policy, nhist, steps):
    import numba

    from slippulse.dynamics.fft import RealFFT
    from slippulse.core.params import DEFAULT as P
    from slippulse.dynamics.stepper import PredictorCorrector, RateStateInterface, TimeStepRule

    law = RateStateInterface(P, 1.2 * P.tau_min)
    t0 = time.perf_counter()
    label = policy
    policy, opts = _policy(policy)
    st = PredictorCorrector(P, n, 0.5 * n * 1e-3, law, rule=TimeStepRule(), history=policy,
                            history_options=opts, threads=1)
    st.set_gaussian(1e-3, 0.05, 0.25 * n * 1e-3)
    _prefill(st, nhist, np.random.default_rng(0))
    setup = time.perf_counter() - t0
    out = {"n": n, "policy": label, "history_steps": nhist, "setup_s": round(setup, 2)}
    for threads in (1, 2):
        numba.set_num_threads(threads)
        st.fft = RealFFT(n, threads=threads)
        st.step()
        st.step()                       # warm-up (compilation, caches)
        ts = []
        for _ in range(steps):
            t1 = time.perf_counter()
            st.step()
            ts.append(time.perf_counter() - t1)
        out[f"ms_per_step_{threads}t"] = round(1e3 * float(np.median(ts)), 3)
        out[f"ms_min_{threads}t"] = round(1e3 * float(np.min(ts)), 3)
    out["history_MB"] = round(st.history.nbytes / 2 ** 20, 1)
    out["loadavg_1min"] = round(os.getloadavg()[0], 2)    # the machine is shared: record its load
    out["peak_rss_MB"] = round(resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024, 1)
    return out


def accuracy():
    """Errors of each policy on the exact tests (see tests/test_sbi_exact.py)."""
    from sbi_exact import run_kostrov, run_steady
    rows = []
    for label in ("full", "window", "soe", "soe-lite"):
        policy, opts = _policy(label)
        row = {"policy": label}
        for vr in (0.5, 0.9):
            row[f"kostrov_{vr}_N512"] = run_kostrov(512, vr, policy, history_options=opts)[0]
        for beta in (0.1, 0.5, 0.9):
            row[f"steady_{beta}_N256"] = run_steady(256, beta, policy, history_options=opts)[0]
        rows.append(row)
    return rows


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    sub = ap.add_subparsers(dest="cmd", required=True)
    t = sub.add_parser("timing")
    t.add_argument("--n", type=int, default=4096)
    t.add_argument("--policy", default="soe")
    t.add_argument("--history", type=int, default=2000)
    t.add_argument("--steps", type=int, default=20)
    sub.add_parser("accuracy")
    a = sub.add_parser("all")
    a.add_argument("--sizes", default="4096,16384,65536")
    a.add_argument("--policies", default="soe,soe-lite,window,full")
    args = ap.parse_args()
    if args.cmd == "timing":
        print(json.dumps(timing(args.n, args.policy, args.history, args.steps)))
    elif args.cmd == "accuracy":
        for row in accuracy():
            print(json.dumps({k: (f"{v:.3e}" if isinstance(v, float) else v) for k, v in row.items()}))
    else:
        for n in map(int, args.sizes.split(",")):
            for policy in args.policies.split(","):
                cmd = [sys.executable, __file__, "timing", "--n", str(n), "--policy", policy]
                env = dict(os.environ, OMP_WAIT_POLICY="passive", NUMBA_THREADING_LAYER="workqueue")
                res = subprocess.run(cmd, capture_output=True, text=True, env=env)
                print(res.stdout.strip() or res.stderr.strip().splitlines()[-1], flush=True)
        for row in accuracy():
            print(json.dumps({k: (f"{v:.3e}" if isinstance(v, float) else v) for k, v in row.items()}))


if __name__ == "__main__":
    main()
