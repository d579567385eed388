"""The benchmarks, grouped by what they measure. Each is a function ``(quick, work) -> figures``
(a dict of numbers and words) run in a fresh process against one source tree (``PYTHONPATH``), so
that ``run.py`` can run the same function on a base commit and on this tree, side by side.

A benchmark uses only what both trees are likely to share: the command line (``python -m
slippulse``), the file readers of :mod:`slippulse.core.h5io`, the steady solver and the SBI
stepper. Its wall times are taken inside the process, after a warm-up that fills the numba caches.

Groups: steady (one pulse solved), family (the continuation 1.2 → 1.1 or → 1.015), branch
(another branch's march toward its fold), deep (the
deep march resumed from a committed seed), reach (the family from scratch to L = 300 m or
1.5 km), continuation (the family's pulses against the
committed deep tables), spectrum (the leading growth rate with its error), sbi
(the time step of the SBI stepper on the host, its errors on exact solutions, the cost of a
checkpoint), gpu (the same step on the device engine)."""
from __future__ import annotations

import glob
import math
import os
import shutil
import subprocess
import sys
import time

HERE = os.path.dirname(os.path.abspath(__file__))
ROOT = os.path.dirname(HERE)


def _cli(*args, timeout=3600):
    """Run ``python -m slippulse ARGS`` (this process's tree and threads); its wall seconds.
    A failure raises with the command's last line."""
    import importlib.util
    # ``python -m slippulse``; older trees (the flat layout) had no __main__: their slippulse.cli
    main = "slippulse" if importlib.util.find_spec("slippulse.__main__") else "slippulse.cli"
    t0 = time.perf_counter()
    r = subprocess.run([sys.executable, "-m", main, *args], capture_output=True, text=True,
                       timeout=timeout)
    wall = time.perf_counter() - t0
    if r.returncode != 0:
        last = (r.stderr.strip() or r.stdout.strip() or "no output").splitlines()[-1]
        raise RuntimeError(f"exit {r.returncode}: {last}")
    return wall


def _module(*names):
    """The first of the modules ``names`` that this tree has: the layout moved (``slippulse.h5io``
    before the subpackages, ``slippulse.core.h5io`` after), and a base commit may be older."""
    import importlib
    for name in names:
        try:
            return importlib.import_module(name)
        except ModuleNotFoundError:
            continue
    raise ModuleNotFoundError(f"none of {names}")


def _h5io():
    return _module("slippulse.core.h5io", "slippulse.h5io")


def _child_cpu():
    """User + system seconds of this process's finished children: the command's CPU time, which
    the load of a shared machine changes far less than its wall time."""
    import resource
    ru = resource.getrusage(resource.RUSAGE_CHILDREN)
    return ru.ru_utime + ru.ru_stime


def _warm_steady():
    """Compile (or load) the steady kernels before a clock starts."""
    DEFAULT = _module("slippulse.core.params", "slippulse.params").DEFAULT
    solve_pulse = _module("slippulse.steady.solver", "slippulse.solver").solve_pulse
    solve_pulse(DEFAULT, 1.2, n_points=300)


# ---------------------------------------------------------------- steady
def steady_solve(quick, work):
    """One pulse by Newton with adaptive grids (``solve_pulse``: coarse passes, then N), at
    τ_d = 1.2 τ_min (quick: N = 1000; full: also N = 4000, and 1.05 τ_min at N = 2000)."""
    from slippulse.core.params import DEFAULT
    from slippulse.steady.solver import solve_pulse
    _warm_steady()
    cases = [(1.2, 1000)] if quick else [(1.2, 1000), (1.2, 4000), (1.05, 2000)]
    out = {}
    for tau, n in cases:
        t0 = time.perf_counter()
        s = solve_pulse(DEFAULT, tau, n_points=n)
        wall = time.perf_counter() - t0
        p = s.to_pulse()
        key = f"{tau}/{n}"
        out[f"wall s ({key})"] = wall
        out[f"beta ({key})"] = p.beta
        out[f"L m ({key})"] = p.L
        out[f"max abs r ({key})"] = p.max_residual
    return out


# ---------------------------------------------------------------- family
def family_continuation(quick, work):
    """``slippulse steady family`` from an empty file, every pulse grid-checked (the default
    strategy): quick 1.2 → 1.1 τ_min (step 0.01), full the defaults (1.2 → 1.015, 0.005). Runs on
    the flat layout of older commits too (the side-by-side record against 7b59bbb)."""
    io = _h5io()
    list_pulses, read_pulse = io.list_pulses, io.read_pulse
    _warm_steady()
    out_file = os.path.join(work, "family.h5")
    args = ["--to", "1.1", "--step", "0.01"] if quick else []
    cpu0 = _child_cpu()
    wall = _cli("steady", "family", "--out", out_file, "-q", *args)
    cpu = _child_cpu() - cpu0
    labels = list_pulses(out_file)
    pulses = [read_pulse(out_file, lab)[0] for lab in labels]
    deep = max(pulses, key=lambda p: p.L)
    return {"wall s": wall, "cpu s": cpu, "pulses": len(pulses), "beta (longest)": deep.beta,
            "L m (longest)": deep.L, "max abs r": max(p.max_residual for p in pulses)}


def branch_march(quick, work):
    """``slippulse steady family --from-pulse`` of the two-hump pulse at 1.0199 τ_min (N = 2006,
    tests/data/two_hump_fold_jump.h5) toward its first fold, checks inline: the march of another
    branch (``BRANCH``), quick to 1.0195, full to 1.0190. Measures what the sign guard costs (one
    LU of [J; c] per converged step, which also gives the next tangent) against a base without
    it."""
    io = _h5io()
    src = os.path.join(ROOT, "tests", "data", "two_hump_fold_jump.h5")
    _warm_steady()
    out_file = os.path.join(work, "branch.h5")
    cpu0 = _child_cpu()
    wall = _cli("steady", "family", "--from-pulse", f"{src}:td1.0199", "--to",
                "1.0195" if quick else "1.019", "--checks", "inline", "--out", out_file, "-q")
    cpu = _child_cpu() - cpu0
    pulses = [io.read_pulse(out_file, lab)[0] for lab in io.list_pulses(out_file)]
    last = min(pulses, key=lambda p: p.tau_d_ratio)
    return {"wall s": wall, "cpu s": cpu, "pulses": len(pulses),
            "tau_d/tau_min (last)": last.tau_d_ratio, "beta (last)": last.beta}


# ---------------------------------------------------------------- deep family
def _smallest_seed():
    """The committed deep seed of the shortest pulse (steady/seeds/*.h5 of this checkout) and its
    deepest pulse's L."""
    from slippulse.core.h5io import list_pulses, read_pulse
    best = None
    for path in glob.glob(os.path.join(ROOT, "steady", "seeds", "*.h5")):
        labs = list_pulses(path)
        if not labs:
            continue
        L = max(read_pulse(path, lab)[0].L for lab in labs)
        if best is None or L < best[1]:
            best = (path, L)
    return best


def deep_march(quick, work):
    """The deep march resumed from the committed seed of the shortest pulse (about 2.5 km):
    ``slippulse steady family --from 1.2 --to 1.008 --ds-min 0.0002 --spacing 0.01
    --max-length L`` on a copy, L the seed's + 1 % (quick) or + 5 % (full); every written pulse
    grid-checked. Figures: wall, pulses written, the last L, and the pace in m of L per minute."""
    from slippulse.core.h5io import list_pulses, read_pulse
    found = _smallest_seed()
    if found is None:
        return {"skipped": "no committed seed in steady/seeds"}
    seed, L0 = found
    copy = os.path.join(work, "deep.h5")
    shutil.copyfile(seed, copy)
    before = set(list_pulses(copy))
    _warm_steady()
    target = L0 * (1.01 if quick else 1.05)
    wall = _cli("steady", "family", "--from", "1.2", "--to", "1.008", "--ds-min", "0.0002",
                "--spacing", "0.01", "--max-length", f"{target:.1f}", "--out", copy, "-q")
    new = [read_pulse(copy, lab)[0] for lab in set(list_pulses(copy)) - before]
    L1 = max((p.L for p in new), default=L0)
    return {"wall s": wall, "seed L m": L0, "pulses written": len(new), "last L m": L1,
            "m of L per min": (L1 - L0) / (wall / 60.0)}


def family_reach(quick, work):
    """``slippulse steady family --from 1.2 --to 1.008 --max-length L`` from an empty file, the
    default strategy, every pulse grid-checked: the time to reach L = 300 m (quick) or 1500 m
    (full) from scratch. Figures: wall, CPU, the L reached, pulses written."""
    from slippulse.core.h5io import list_pulses, read_pulse
    _warm_steady()
    out_file = os.path.join(work, "reach.h5")
    target = 300.0 if quick else 1500.0
    cpu0 = _child_cpu()
    wall = _cli("steady", "family", "--from", "1.2", "--to", "1.008", "--max-length",
                f"{target:g}", "--out", out_file, "-q", timeout=7200)
    cpu = _child_cpu() - cpu0
    pulses = [read_pulse(out_file, lab)[0] for lab in list_pulses(out_file)]
    return {"wall s": wall, "cpu s": cpu, "target L m": target,
            "L m reached": max(p.L for p in pulses if p.converged), "pulses": len(pulses)}


# ---------------------------------------------------------------- continuation against the tables
def _family_curve(path):
    """(τ_d/τ_min, β, L) of the converged, grid-checked pulses of a family file, sorted."""
    import numpy as np
    from slippulse.core.h5io import list_pulses, read_pulse
    rows = []
    for lab in list_pulses(path):
        p, _ = read_pulse(path, lab)
        if p.converged and p.extra.get("grid_check_passed", True):
            rows.append((p.tau_d_ratio, p.beta, p.L))
    return np.array(sorted(rows)).reshape(-1, 3)


def _committed_tables():
    """(τ_d/τ_min, β, L) of the grid-checked rows of steady/seeds/deep_family_*.csv, one row per
    τ_d (the chained tables overlap: each resumed run starts from the last one's two pulses)."""
    import csv
    import numpy as np
    rows = set()
    for path in glob.glob(os.path.join(ROOT, "steady", "seeds", "deep_family_*.csv")):
        with open(path) as f:
            rows.update((float(r["tau_d_ratio"]), float(r["beta"]), float(r["L"]))
                        for r in csv.DictReader(f) if r["grid_check_passed"] == "True")
    rows = np.array(sorted(rows)).reshape(-1, 3)
    return rows[np.r_[True, np.diff(rows[:, 0]) > 1e-7]] if len(rows) else rows


def _against(new, ref):
    """Largest |Δβ| and |ΔL|/L of ``new`` against ``ref`` at matched τ_d (within ref's span), and
    the number compared. β and ln L are interpolated in τ_d by cubic splines: L is so steep in
    τ_d near τ_min that linear interpolation between rows 100 m apart errs by 3e−3
    (leave-one-out on the tables at 1–3 km), the cubic by 6e−5."""
    import numpy as np
    from scipy.interpolate import CubicSpline
    q = new[:, 0]
    inside = (q >= ref[0, 0]) & (q <= ref[-1, 0])
    if not inside.any():
        return math.nan, math.nan, 0
    b = CubicSpline(ref[:, 0], ref[:, 1])(q[inside])
    L = np.exp(CubicSpline(ref[:, 0], np.log(ref[:, 2]))(q[inside]))
    return (float(np.max(np.abs(new[inside, 1] - b))),
            float(np.max(np.abs(new[inside, 2] / L - 1.0))), int(inside.sum()))


def continuation_tables(quick, work):
    """``slippulse steady family --from 1.2 --to TO`` from an empty file (quick: TO = 1.1, step
    0.01; full: TO = 1.015, the default step), and its pulses against the committed deep tables
    (steady/seeds/deep_family_*.csv of this checkout, the same reference for both trees): wall,
    pulses, and the largest |Δβ| and |ΔL/L| at matched τ_d."""
    ref = _committed_tables()
    if not len(ref):
        return {"skipped": "no committed tables in steady/seeds"}
    _warm_steady()
    out_file = os.path.join(work, "family.h5")
    args = ["--to", "1.1", "--step", "0.01"] if quick else ["--to", "1.015"]
    wall = _cli("steady", "family", "--from", "1.2", "--out", out_file, "-q", *args)
    new = _family_curve(out_file)
    db, dl, n = _against(new, ref)
    return {"wall s": wall, "pulses": len(new), "pulses compared": n,
            "max abs dbeta vs tables": db, "max abs dL/L vs tables": dl}


# ---------------------------------------------------------------- spectrum
def _stored_rate(path, label):
    """(s L/c_p, s_err L/c_p) stored for ``label`` by ``steady stability`` (read with h5py)."""
    import h5py
    with h5py.File(path, "r") as h5:
        found = {}

        def visit(name, obj):
            if label in name.split("/"):
                for key in ("s_per_L", "eigen_s_per_L", "leading_s_per_L"):
                    if key in obj.attrs and "s" not in found:
                        found["s"] = float(obj.attrs[key])
                for key in ("s_err_per_L", "eigen_s_err_per_L", "leading_s_err_per_L", "s_err"):
                    if key in obj.attrs and "e" not in found:
                        found["e"] = float(obj.attrs[key])
        h5.visititems(visit)
    return found.get("s", math.nan), found.get("e", math.nan)


def spectrum_rate(quick, work):
    """``slippulse steady stability FILE --no-extra``: the leading growth rate with its error
    from the ladder of grids, on a pulse solved (not timed) by ``steady solve``: quick 1.2 τ_min
    at N = 1000, full also 1.05 τ_min at N = 2000."""
    _warm_steady()
    from slippulse.core.h5io import list_pulses
    warm = os.path.join(work, "warm.h5")              # compile the spectrum's kernels, untimed
    _cli("steady", "solve", "--tau-d", "1.2", "--points", "700", "--out", warm)
    _cli("steady", "stability", warm, "--no-extra", "-q", "--levels", "0")
    cases = [(1.2, 1000)] if quick else [(1.2, 1000), (1.05, 2000)]
    out = {}
    for tau, n in cases:
        path = os.path.join(work, f"td{tau}.h5")
        _cli("steady", "solve", "--tau-d", str(tau), "--points", str(n), "--out", path)
        label = list_pulses(path)[0]
        wall = _cli("steady", "stability", path, "--no-extra", "-q")
        s, e = _stored_rate(path, label)
        key = f"{tau}/{n}"
        out[f"wall s ({key})"] = wall
        out[f"s L/c_p ({key})"] = s
        out[f"s_err L/c_p ({key})"] = e
    return out


# ---------------------------------------------------------------- SBI
def _stepper(n, history="soe", threads=1):
    """The rate-and-state SBI stepper at τ_d = 1.2 τ_min on N points, Δx = 1 mm, with a Gaussian
    bump, its history filled with 2000 small random steps (a step's cost does not depend on them)."""
    import numpy as np

    from slippulse.core.params import DEFAULT as P
    from slippulse.dynamics.stepper import PredictorCorrector, RateStateInterface, TimeStepRule
    law = RateStateInterface(P, 1.2 * P.tau_min)
    st = PredictorCorrector(P, n, n * 1e-3, law, rule=TimeStepRule(), history=history,
                            threads=threads)
    st.set_gaussian(1e-3, 0.05, 0.25 * n * 1e-3)
    h, rng, nhist = st.history, np.random.default_rng(0), 2000
    if history == "soe":
        h.Y[:] = 1e-12 * (rng.standard_normal(h.Y.shape) + 1j * rng.standard_normal(h.Y.shape))
        h.count = nhist
    elif history == "window":
        h.hist[:] = 1e-12 * rng.standard_normal(h.hist.size).reshape(h.hist.shape) * (1 + 1j)
        h.count = nhist
    else:                                          # the full convolution: a growing ring
        if h.cap < nhist + 8:
            h._grow(nhist + 8)
        h.hist[:nhist] = 1e-12 * rng.standard_normal((nhist, h.nk)) * (1 + 1j)
        h.head, h.count = nhist % h.cap, nhist
        h._ensure_weights(nhist + 8)
    return st


def _time_steps(st, steps, sync=lambda: None):
    for _ in range(3):
        st.step()                                  # compiles, plans, Δt coefficients
    sync()
    ts = []
    for _ in range(steps):
        t0 = time.perf_counter()
        st.step()
        sync()
        ts.append(time.perf_counter() - t0)
    ts.sort()
    return 1e3 * ts[len(ts) // 2], 1e3 * ts[0]


def sbi_step(quick, work):
    """Milliseconds per step of the host SBI stepper (predictor–corrector), one thread, median and
    best of 20 steps (the best is the less sensitive to the machine's load): the sum-of-exponentials history (the default) at N = 4096 (quick) and 4096, 16384,
    65536 (full); full also the truncated-window and full-convolution histories at N = 4096."""
    out = {}
    cases = [(4096, "soe")] if quick else [(4096, "soe"), (16384, "soe"), (65536, "soe"),
                                           (4096, "window"), (4096, "full")]
    for n, history in cases:
        st = _stepper(n, history)
        med, best = _time_steps(st, 20)
        out[f"ms/step median ({history}, N={n})"] = med
        out[f"ms/step best ({history}, N={n})"] = best
        out[f"history MB ({history}, N={n})"] = st.history.nbytes / 2 ** 20
    return out


def sbi_checkpoint(quick, work):
    """Seconds of one checkpoint of ``slippulse dynamic run``'s output file (the run is paused
    while the state is written and the file published) against the file's size: the default
    stepper at N = 4096, snapshots appended until the file holds 20 MB (quick) or 20 and 200 MB
    (full); median of 3 checkpoints per size."""
    import statistics

    from slippulse.dynamics.config import build_stepper, load_config
    from slippulse.dynamics.runfile import RunFile
    cfg = load_config(None, ["grid.n=4096"])
    st = build_stepper(cfg)
    out = {}
    path = os.path.join(work, "run.h5")
    rf = RunFile.create(path, cfg, st.params, st)
    rf.snapshot(st)
    rf.checkpoint(st)
    for size in (20,) if quick else (20, 200):
        while os.path.getsize(rf.work) < size * 1e6:
            for _ in range(16):
                st.nstep += 1
                st.t += 1e-6
                rf.record_step(st)
                rf.snapshot(st)
            rf.h5.flush()
        times = []
        for _ in range(3):
            st.nstep += 1
            st.t += 1e-6
            rf.record_step(st)
            t0 = time.perf_counter()
            rf.checkpoint(st)
            times.append(time.perf_counter() - t0)
        out[f"s/checkpoint ({size} MB)"] = statistics.median(times)
    rf.close()
    return out


def sbi_exact(quick, work):
    """Errors of the SBI stepper against exact solutions (tests/sbi_exact.py): Kostrov's
    self-similar crack at v_r = 0.9 c_s (N = 512) and a steady pulse at β = 0.5 (N = 256)."""
    sys.path.insert(0, os.path.join(ROOT, "tests"))
    from sbi_exact import run_kostrov, run_steady
    t0 = time.perf_counter()
    k = run_kostrov(512, 0.9, "soe")[0]
    s = run_steady(256, 0.5, "soe")[0]
    return {"Kostrov error": k, "steady error": s, "wall s": time.perf_counter() - t0}


# ---------------------------------------------------------------- GPU
def gpu_step(quick, work):
    """Milliseconds per step of the device engine (``DeviceStepper``, CuPy) on the stepper of
    ``sbi_step``, N = 65536 (quick) and 2^20 (full); skipped where no GPU is usable."""
    from slippulse.dynamics import device
    why = device.cupy_unavailable()
    if why:
        return {"skipped": f"no GPU: {why}"}
    import cupy
    out = {}
    for n in (65536,) if quick else (65536, 2 ** 20):
        st = device.DeviceStepper.from_host(_stepper(n), "cupy")
        med, best = _time_steps(st, 50, cupy.cuda.Device().synchronize)
        out[f"ms/step median (N={n})"] = med
        out[f"ms/step best (N={n})"] = best
    return out


#: group → [(name, function)], in the order they run
GROUPS = {
    "steady": [("steady.solve", steady_solve)],
    "family": [("family.continuation", family_continuation)],
    "branch": [("branch.march", branch_march)],
    "deep": [("deep.march", deep_march)],
    "reach": [("family.reach", family_reach)],
    "continuation": [("continuation.tables", continuation_tables)],
    "spectrum": [("spectrum.rate", spectrum_rate)],
    "sbi": [("sbi.step", sbi_step), ("sbi.exact", sbi_exact),
            ("sbi.checkpoint", sbi_checkpoint)],
    "gpu": [("gpu.step", gpu_step)],
}
BENCHMARKS = {name: fn for group in GROUPS.values() for name, fn in group}
