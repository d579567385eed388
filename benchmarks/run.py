"""The benchmark suite: this tree and a base commit, side by side in one run.

    python benchmarks/run.py [GROUP ...] [--base REV] [--quick] [--repeat R] [--no-base]

GROUPs (default all): steady, family, branch, deep, reach, continuation, spectrum, sbi, gpu
(benchmarks/suite.py). The base
commit (default ``main``) is checked out once into a git worktree under the cache directory
(``--cache``, default ``$TMPDIR/slippulse-bench``: its numba caches survive between runs), and
every benchmark of ``suite.py`` (this tree's) runs in a fresh process per tree, ``PYTHONPATH``
set to that tree's ``src``, one thread (``--threads``), base and this tree alternated ``--repeat``
times (base first, then this tree first, ...); each benchmark compiles its numba kernels before
its clock starts. Prints one table per benchmark: each figure for base and this tree (the median over the
repeats) and their ratio, and the load average before and after. ``--json FILE`` also writes the
rows. A benchmark the base cannot run (a command it does not have) shows its error instead.

Why a runner of our own and not airspeed velocity or pytest-benchmark: asv builds an environment
per commit from the package index (numba, pyfftw, h5py, Dask here: minutes per commit and a network
this machine does not always have) and times functions in-process, while several benchmarks here
are a command's own wall time; with ``environment_type = "existing"`` it cannot compare two
commits in one run. pytest-benchmark compares against saved runs of earlier sessions, not a base
commit in the same run, under the same load. What we need is two source trees of one
environment, which a git worktree and ``PYTHONPATH`` give in ~100 lines.
"""
from __future__ import annotations

import argparse
import json
import math
import os
import statistics
import subprocess
import sys
import tempfile
import time

HERE = os.path.dirname(os.path.abspath(__file__))
ROOT = os.path.dirname(HERE)
THREAD_VARS = ("OMP_NUM_THREADS", "NUMBA_NUM_THREADS", "OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS")


def base_tree(rev, cache):
    """A worktree of ``rev`` (detached) under ``cache``, made once per commit; its path."""
    sha = subprocess.run(["git", "rev-parse", "--verify", f"{rev}^{{commit}}"], cwd=ROOT,
                         capture_output=True, text=True, check=True).stdout.strip()
    path = os.path.join(cache, sha[:12])
    if not os.path.isdir(os.path.join(path, "src")):
        os.makedirs(cache, exist_ok=True)
        subprocess.run(["git", "worktree", "add", "--detach", "-f", path, sha], cwd=ROOT,
                       capture_output=True, check=True)
    return path, sha


def child(name, quick, tree, threads, timeout):
    """Run benchmark ``name`` in a fresh process against ``tree``'s src; (figures, error)."""
    env = dict(os.environ, PYTHONPATH=os.path.join(tree, "src"),
               **{k: str(threads) for k in THREAD_VARS})
    with tempfile.TemporaryDirectory(prefix="bench-") as work:
        cmd = [os.path.abspath(sys.executable), os.path.abspath(__file__), "--child", name, "--work", work] + (["--quick"] if quick else [])
        try:
            r = subprocess.run(cmd, env=env, cwd=tree, capture_output=True, text=True,
                               timeout=timeout)
        except subprocess.TimeoutExpired:
            return None, f"timed out after {timeout} s"
    lines = [ln for ln in r.stdout.splitlines() if ln.startswith("{")]
    if r.returncode != 0 or not lines:
        last = (r.stderr.strip() or r.stdout.strip() or "no output").splitlines()[-1]
        return None, last[:160]
    res = json.loads(lines[-1])
    return (res["figures"], None) if "figures" in res else (None, res["error"][:160])


def _fmt(v):
    if isinstance(v, str):
        return v
    if v is None or (isinstance(v, float) and math.isnan(v)):
        return "nan"
    if isinstance(v, int):
        return str(v)
    return f"{v:.4g}" if 1e-3 <= abs(v) < 1e5 else f"{v:.3e}"


def median_figures(runs):
    """Per figure, the median over the runs (numbers) or the first run's word."""
    keys = list(dict.fromkeys(k for r in runs for k in r))
    out = {}
    for k in keys:
        vals = [r[k] for r in runs if k in r]
        num = [v for v in vals if isinstance(v, (int, float))]
        out[k] = statistics.median(num) if len(num) == len(vals) and num else vals[0]
    return out


def table(name, base, head, rev):
    """The markdown table of one benchmark: figure | base | this tree | this/base."""
    rows = [f"\n### {name}", "", f"| figure | base {rev} | this tree | this/base |", "|---|---|---|---|"]
    (bfig, berr), (hfig, herr) = base, head
    if bfig is None and hfig is None:
        rows.append(f"| (error) | {berr} | {herr} | |")
        return "\n".join(rows)
    for k in list(dict.fromkeys(list((hfig or {}).keys()) + list((bfig or {}).keys()))):
        b = bfig.get(k) if bfig else None
        h = hfig.get(k) if hfig else None
        ratio = ""
        if isinstance(b, (int, float)) and isinstance(h, (int, float)) and b not in (0,) \
                and not math.isnan(b) and not math.isnan(h):
            ratio = f"{h / b:.3g}"
        rows.append(f"| {k} | {_fmt(b) if bfig else berr} | {_fmt(h) if hfig else herr} | {ratio} |")
    return "\n".join(rows)


def main(argv=None):
    sys.path.insert(0, HERE)
    from suite import BENCHMARKS, GROUPS

    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0],
                                 formatter_class=argparse.RawDescriptionHelpFormatter,
                                 epilog="\n".join(__doc__.splitlines()[2:]))
    ap.add_argument("groups", nargs="*", metavar="GROUP",
                    help=f"groups to run (default all): {', '.join(GROUPS)}")
    ap.add_argument("--base", default="main", help="the commit to compare with (default main)")
    ap.add_argument("--no-base", action="store_true", help="this tree only")
    ap.add_argument("--quick", action="store_true", help="the small cases (minutes in all)")
    ap.add_argument("--repeat", type=int, default=1, help="runs per tree, alternated (default 1)")
    ap.add_argument("--threads", type=int, default=1, help="threads per process (default 1)")
    ap.add_argument("--timeout", type=int, default=3600, help="seconds per run (default 3600)")
    ap.add_argument("--cache", default=os.path.join(tempfile.gettempdir(), "slippulse-bench"))
    ap.add_argument("--json", metavar="FILE", help="also write the figures to FILE")
    ap.add_argument("--child", help=argparse.SUPPRESS)
    ap.add_argument("--work", help=argparse.SUPPRESS)
    a = ap.parse_args(argv)

    if a.child:                                  # one benchmark, this process's tree
        try:
            figures = BENCHMARKS[a.child](a.quick, a.work)
            print(json.dumps({"figures": figures}))
        except Exception as exc:                 # noqa: BLE001 - reported in the table
            print(json.dumps({"error": f"{type(exc).__name__}: {exc}"}))
        return 0

    unknown = [g for g in a.groups if g not in GROUPS]
    if unknown:
        ap.error(f"unknown group(s) {', '.join(unknown)}: choose from {', '.join(GROUPS)}")
    if a.repeat < 1:
        ap.error("--repeat must be >= 1")
    names = [n for g in (a.groups or GROUPS) for n, _ in GROUPS[g]]
    trees = {"this": ROOT}
    rev = "-"
    if not a.no_base:
        trees["base"], sha = base_tree(a.base, a.cache)
        rev = f"{a.base} ({sha[:8]})"
    head = subprocess.run(["git", "describe", "--always", "--dirty"], cwd=ROOT,
                          capture_output=True, text=True).stdout.strip()
    print(f"# slippulse benchmarks: this tree {head} against base {rev}; "
          f"{'quick' if a.quick else 'full'}, {a.threads} thread(s) per process, "
          f"{a.repeat} run(s) per tree; {os.cpu_count()} CPUs; load {os.getloadavg()}", flush=True)
    report = {}
    for name in names:
        t0 = time.perf_counter()
        load0 = os.getloadavg()[0]
        runs = {k: [] for k in trees}
        errors = {k: None for k in trees}
        for rep in range(a.repeat):               # alternated, the order swapped each time
            for key in ("base", "this") if rep % 2 == 0 else ("this", "base"):
                if key in trees:
                    fig, err = child(name, a.quick, trees[key], a.threads, a.timeout)
                    runs[key].append(fig) if fig is not None else errors.__setitem__(key, err)
        res = {k: ((median_figures(runs[k]), None) if runs[k] else (None, errors[k])) for k in trees}
        print(table(name, res.get("base", (None, "-")), res["this"], a.base), flush=True)
        print(f"\n({time.perf_counter() - t0:.0f} s; load {load0:.2f} before, "
              f"{os.getloadavg()[0]:.2f} after)", flush=True)
        report[name] = {k: {"figures": v[0], "error": v[1]} for k, v in res.items()}
        report[name]["load"] = [load0, os.getloadavg()[0]]
    if a.json:
        with open(a.json, "w") as f:
            json.dump({"base": rev, "this": head, "quick": a.quick, "benchmarks": report}, f,
                      indent=1)
    return 0


if __name__ == "__main__":
    sys.exit(main())
