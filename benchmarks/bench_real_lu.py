"""The spectrum of some pulses by this code and by a base commit, side by side in one run
(issue 17, item 5): stop 38's real arithmetic at real σ (base 3ee2570), stop 39's cheaper levels
(base acf0fdd; BENCHMARKS.md "Stop 39"), stop 40's line search and starts (base a7fa25c,
``--together``; BENCHMARKS.md "Stop 40").

    git worktree add --detach /tmp/base HEAD~1     # the code before the change
    python benchmarks/bench_real_lu.py FAMILY.h5 LABEL [LABEL ...] --base /tmp/base

Each pulse is run alone, as ``slippulse steady stability COPY --labels LABEL -q`` on a fresh copy
of the family file (so it is tracked from the stored spectrum above it, as in a resumed run), one
thread, first by the base code, then by this one (``PYTHONPATH`` set to each tree's ``src``).
Prints per pulse both wall times and their ratio, and both s L/c_p ± err with their difference
in units of the error: the same pulse on the same grids, so the values agree to rounding where
the change is exact. Report the machine's load (printed before and after) beside the figures.
"""
import argparse
import os
import shutil
import subprocess
import sys
import tempfile
import time

import h5py

HERE = os.path.join(os.path.dirname(os.path.abspath(__file__)), "..", "src")


def run(tree_src, family, label):
    """One command on a fresh copy of `family`: `label` (a str), or a list of labels run
    together (tracked from one to the next). Returns (wall, s L/c_p, s_err L/c_p, levels N),
    the last three of the last label."""
    labels = [label] if isinstance(label, str) else list(label)
    tmp = tempfile.mkdtemp(prefix="bench_real_lu_")
    try:
        path = os.path.join(tmp, "f.h5")
        shutil.copy(family, path)
        env = dict(os.environ, PYTHONPATH=tree_src, OMP_NUM_THREADS="1",
                   OPENBLAS_NUM_THREADS="1", MKL_NUM_THREADS="1", NUMBA_NUM_THREADS="1")
        t0 = time.perf_counter()
        r = subprocess.run([sys.executable, "-m", "slippulse", "steady", "stability", path,
                            "--labels", *labels, "--overwrite", "-q"], env=env,
                           capture_output=True, text=True)
        wall = time.perf_counter() - t0
        if r.returncode != 0:
            raise SystemExit(f"{tree_src}: {labels}: exit {r.returncode}: {r.stderr[-400:]}")
        with h5py.File(path, "r") as h5:
            a = h5[f"pulses/{labels[-1]}/spectrum"].attrs
            return wall, float(a["s_per_L"]), float(a["s_err_per_L"]), \
                [int(n) for n in a["refine_n_points"]]
    finally:
        shutil.rmtree(tmp, ignore_errors=True)


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("family")
    ap.add_argument("labels", nargs="+")
    ap.add_argument("--base", required=True, help="a worktree of the code to compare with")
    ap.add_argument("--together", action="store_true",
                    help="run all LABELs in one command instead of one by one (tracked from one to the next, as "
                         "in a family run: stop 40's starts extrapolated from two pulses need "
                         "that), by each code; the values printed are the last label's")
    a = ap.parse_args()
    print(f"load average before: {os.getloadavg()}")
    tb = tn = 0.0
    if a.together:
        wb, sb, eb, _ = run(os.path.join(a.base, "src"), a.family, a.labels)
        wn, sn, en, _ = run(HERE, a.family, a.labels)
        print(f"{len(a.labels)} pulses in one command: base {wb:.1f} s, new {wn:.1f} s, ratio "
              f"{wb / wn:.2f}x; last s L/c_p = {sb:.9g} ± {eb:.1g} | {sn:.9g} ± {en:.1g}; "
              f"difference {abs(sb - sn) / max(eb, 1e-300):.1e} err")
        print(f"load average after: {os.getloadavg()}")
        return
    for lab in a.labels:
        wb, sb, eb, nb = run(os.path.join(a.base, "src"), a.family, lab)
        wn, sn, en, nn = run(HERE, a.family, lab)
        tb, tn = tb + wb, tn + wn
        print(f"{lab}: base {wb:.1f} s, new {wn:.1f} s, ratio {wb / wn:.2f}x; s L/c_p = "
              f"{sb:.9g} ± {eb:.1g} | {sn:.9g} ± {en:.1g} (N = {'/'.join(map(str, nn))}"
              f"{'' if nn == nb else ' against ' + '/'.join(map(str, nb))}); difference "
              f"{abs(sb - sn) / max(eb, 1e-300):.1e} err")
    print(f"total: base {tb:.1f} s, new {tn:.1f} s, ratio {tb / tn:.2f}x")
    print(f"load average after: {os.getloadavg()}")


if __name__ == "__main__":
    main()
