"""The family command, side by side: an old commit against this tree, in one run, and the pulses
of this tree against the committed deep tables.

    python benchmarks/continuation_speed.py [--old 7b59bbb] [--pairs 1] [--to 1.015]
        [--max-length L] [--workdir /tmp/contin_speed] [--tables steady/seeds/deep_family_*.csv]

Each pair runs ``slippulse steady family --from 1.2 --to TO [--max-length L] --out F -q`` once
with the old commit's source (``git archive``) and once with this tree's, one after the other,
each in a fresh process with its own numba cache (warmed by a first tiny run not timed). Prints
the wall time of each and their ratio, then the largest differences of β and L at matched τ_d
between the two files (the old file's β and ln L interpolated in τ_d onto the new pulses by cubic
splines), and, with --tables, of the new file against the committed tables (the same way).
One thread per process (OMP/NUMBA/OPENBLAS_NUM_THREADS=1). The shallow family (default --to
1.015) takes ~1 min per run on one core.
"""
import argparse
import csv
import glob
import os
import shutil
import subprocess
import sys
import time

import numpy as np

ROOT = os.path.abspath(os.path.join(os.path.dirname(__file__), os.pardir))


def export(ref, dest):
    """The source tree of ``ref`` under ``dest`` (git archive), or this tree for ``ref=None``."""
    if ref is None:
        return os.path.join(ROOT, "src")
    if not os.path.isdir(dest):
        os.makedirs(dest)
        arch = subprocess.run(["git", "-C", ROOT, "archive", ref], check=True,
                              capture_output=True).stdout
        subprocess.run(["tar", "-x", "-C", dest], input=arch, check=True)
    return os.path.join(dest, "src")


def family(src, out, to, max_length, cache):
    """Wall time (s) and return code of one family command with the source under ``src``."""
    env = dict(os.environ, PYTHONPATH=src, OMP_NUM_THREADS="1", NUMBA_NUM_THREADS="1",
               OPENBLAS_NUM_THREADS="1", NUMBA_CACHE_DIR=cache)
    args = [sys.executable, "-m", "slippulse.cli", "steady", "family", "--from", "1.2", "--to",
            str(to), "--out", out, "-q"]
    if max_length:
        args += ["--max-length", str(max_length)]
    t0 = time.perf_counter()
    r = subprocess.run(args, env=env, capture_output=True, text=True)
    wall = time.perf_counter() - t0
    return wall, r.returncode, (r.stdout.strip().splitlines() or [""])[-1][:200]


def curve(path):
    """(τ_d/τ_min, β, L, N) of the converged, grid-checked pulses of a family file, sorted."""
    from slippulse.core.h5io import list_pulses, read_pulse
    rows = []
    for lab in list_pulses(path):
        p, _ = read_pulse(path, lab)
        if p.converged and p.extra.get("grid_check_passed", True):
            rows.append((p.tau_d_ratio, p.beta, p.L, p.n_points))
    return np.array(sorted(rows))


def table(paths):
    """(τ_d/τ_min, β, L, N) of the converged, grid-checked rows of committed tables."""
    rows = []
    for path in paths:
        with open(path) as f:
            for r in csv.DictReader(f):
                if r["grid_check_passed"] == "True":
                    rows.append((float(r["tau_d_ratio"]), float(r["beta"]), float(r["L"]),
                                 int(r["n_points"])))
    rows = np.array(sorted(set(rows)))
    # the chained tables overlap (each resumed run starts from the last one's two pulses): keep
    # one row per τ_d, so the spline sees strictly increasing abscissae
    keep = np.r_[True, np.diff(rows[:, 0]) > 1e-7]
    return rows[keep]


def compare(new, ref, min_L=0.0):
    """Largest |Δβ| and |ΔL|/L of ``new`` against ``ref`` interpolated in τ_d (within its span),
    and the number of pulses compared; bands of L reported separately. β and ln L are
    interpolated by cubic splines in τ_d: L is so steep in τ_d near τ_min that linear
    interpolation between rows 100 m apart errs by 3e−3 (leave-one-out on the tables at
    1–3 km), the cubic by 6e−5."""
    from scipy.interpolate import CubicSpline
    q = new[:, 0]
    inside = (q >= ref[0, 0]) & (q <= ref[-1, 0]) & (new[:, 2] >= min_L)
    if not inside.any():
        return None
    b = CubicSpline(ref[:, 0], ref[:, 1])(q[inside])
    L = np.exp(CubicSpline(ref[:, 0], np.log(ref[:, 2]))(q[inside]))
    return (float(np.max(np.abs(new[inside, 1] - b))),
            float(np.max(np.abs(new[inside, 2] / L - 1.0))), int(inside.sum()),
            float(new[inside, 2].min()), float(new[inside, 2].max()))


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--old", default="7b59bbb")
    ap.add_argument("--pairs", type=int, default=1)
    ap.add_argument("--to", type=float, default=1.015)
    ap.add_argument("--max-length", type=float, default=None)
    ap.add_argument("--workdir", default="/tmp/contin_speed")
    ap.add_argument("--tables", nargs="*", default=[])
    ap.add_argument("--skip-old", action="store_true", help="time this tree only")
    a = ap.parse_args(argv)
    os.makedirs(a.workdir, exist_ok=True)
    trees = [("new", None)] if a.skip_old else [("old", a.old), ("new", None)]
    srcs = {name: export(ref, os.path.join(a.workdir, f"src_{ref}")) for name, ref in trees}
    for name, src in srcs.items():                      # warm each numba cache, untimed
        family(src, os.path.join(a.workdir, f"warm_{name}.h5"), 1.19, None,
               os.path.join(a.workdir, f"numba_{name}"))
    walls = {name: [] for name in srcs}
    for k in range(a.pairs):
        for name, src in srcs.items():
            out = os.path.join(a.workdir, f"{name}_{k}.h5")
            if os.path.exists(out):
                os.remove(out)
            wall, rc, last = family(src, out, a.to, a.max_length,
                                    os.path.join(a.workdir, f"numba_{name}"))
            walls[name].append(wall)
            load = os.getloadavg()[0]
            print(f"pair {k} {name}: {wall:.1f} s, rc={rc}, load {load:.2f}: {last}", flush=True)
    for name, w in walls.items():
        print(f"{name}: median {np.median(w):.1f} s over {len(w)}")
    if "old" in walls:
        print(f"old/new: {np.median(walls['old']) / np.median(walls['new']):.2f}x")
        new, old = (curve(os.path.join(a.workdir, f"{n}_0.h5")) for n in ("new", "old"))
        print(f"pulses: new {len(new)}, old {len(old)}")
        c = compare(new, old)
        if c:
            print(f"new vs old at matched tau_d: max|dbeta|={c[0]:.2e}, max|dL/L|={c[1]:.2e} "
                  f"({c[2]} pulses, L {c[3]:.3g}-{c[4]:.3g} m)")
    if a.tables:
        ref = table(sorted(set(p for t in a.tables for p in glob.glob(t))))
        new = curve(os.path.join(a.workdir, "new_0.h5"))
        for lo, hi in ((900, 1100), (1400, 1600), (2400, 2600), (4800, 5200), (9500, 10500),
                       (900, np.inf)):
            band = new[(new[:, 2] >= lo) & (new[:, 2] < hi)]
            c = compare(band, ref) if band.size else None
            if c:
                print(f"new vs tables, L in [{lo}, {hi}) m: max|dbeta|={c[0]:.2e}, "
                      f"max|dL/L|={c[1]:.2e} ({c[2]} pulses)")
    return 0


if __name__ == "__main__":
    shutil.which("git") or sys.exit("needs git")
    sys.exit(main())
