"""The family's growth rates with their uncertainties: today's command against the route before
issue 17, side by side on the same pulses (issue 17, item 5).

    python benchmarks/bench_spectrum_family.py FAMILY.h5 --base /work/base --labels td1.2000 ...

Before issue 17 a growth rate with an uncertainty took two steps: ``slippulse steady stability``
(the eigenvalue on the pulse's grid, no error) and ``steady/spectrum_convergence.py --nested 1``
(the pulse re-solved on the nested grid, the eigenvalue again, Richardson with an assumed order
2). Now one command does it: ``slippulse steady stability --levels 1``. Both run here on copies of
the same family file, each code as a subprocess from its own tree (``--base``: a worktree of the
old commit, e.g. ``git worktree add --detach /work/base 1318367``), numba caches warmed first.
Prints the wall times, their ratio, and both rates with their uncertainties.
"""
from __future__ import annotations

import argparse
import json
import os
import shutil
import subprocess
import sys
import tempfile
import time

import h5py

HERE = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))


def run(cmd, src, cwd):
    env = dict(os.environ, PYTHONPATH=src)
    t0 = time.perf_counter()
    r = subprocess.run(cmd, cwd=cwd, env=env, capture_output=True, text=True)
    if r.returncode not in (0, 1):
        sys.exit(f"failed: {' '.join(cmd)}\n{r.stderr[-2000:]}")
    return time.perf_counter() - t0, r.stdout


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("family")
    ap.add_argument("--base", required=True, help="worktree of the code before issue 17")
    ap.add_argument("--labels", nargs="+", required=True)
    ap.add_argument("--workdir", default=None)
    a = ap.parse_args(argv)
    work = a.workdir or tempfile.mkdtemp(prefix="bench_spec_")
    os.makedirs(work, exist_ok=True)
    new_src, old_src = os.path.join(HERE, "src"), os.path.join(a.base, "src")
    print(f"load average at start: {os.getloadavg()}")
    # warm both numba caches on one label (not timed)
    for src, tag in ((new_src, "new"), (old_src, "old")):
        f = os.path.join(work, f"warm_{tag}.h5")
        shutil.copy(a.family, f)
        run([sys.executable, "-m", "slippulse.cli", "steady", "stability", f, "--labels",
             a.labels[0], "--no-extra", "-q"] + (["--levels", "0"] if tag == "new" else []),
            src, work)
    f_old = os.path.join(work, "old.h5")
    f_new = os.path.join(work, "new.h5")
    shutil.copy(a.family, f_old)
    shutil.copy(a.family, f_new)
    t_old1, _ = run([sys.executable, "-m", "slippulse.cli", "steady", "stability", f_old,
                     "--labels", *a.labels, "--no-extra", "-q"], old_src, work)
    js = os.path.join(work, "nested.json")
    t_old2, _ = run([sys.executable, os.path.join(a.base, "steady", "spectrum_convergence.py"),
                     f_old, *a.labels, "--nested", "1", "--out", js], old_src, work)
    t_new, _ = run([sys.executable, "-m", "slippulse.cli", "steady", "stability", f_new,
                    "--labels", *a.labels, "--no-extra", "--levels", "1", "-q"], new_src, work)
    rows = {r["label"]: r for r in json.load(open(js)) if "extrapolated" in r}
    print(f"load average at end: {os.getloadavg()}")
    print(f"old route: stability {t_old1:.1f} s + nested refinement {t_old2:.1f} s = "
          f"{t_old1 + t_old2:.1f} s; new command (--levels 1): {t_new:.1f} s; "
          f"ratio {(t_old1 + t_old2) / t_new:.2f}")
    print("| pulse | old: s L/c_p ± (Richardson, order 2 assumed) | new: s L/c_p ± s_err |")
    print("|---|---|---|")
    with h5py.File(f_new, "r") as h5:
        for lab in a.labels:
            g = h5["pulses"][lab]["spectrum"].attrs
            new = (f"{g['s_per_L']:.5g} ± {g['s_err_per_L']:.1g}" if "s_per_L" in g
                   else str(g.get("message", "failed")))
            r = rows.get(lab)
            old = f"{r['extrapolated']:.5g} ± {r['uncertainty']:.1g}" if r else "failed"
            print(f"| {lab} | {old} | {new} |")


if __name__ == "__main__":
    main()
