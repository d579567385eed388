"""The deep family from scratch with the grid checks' Newton reusing its LU (this code) and not
(the code before stop 34), side by side: two processes at once, one per core, one thread each.

    python benchmarks/bench_march_reuse.py [--to 1.009] [--max-length 1500] [--dir /tmp/bmr]

Each process runs ``slippulse steady family --from 1.2 --to TO --max-length L -q`` from an empty
file, with ``slippulse.steady.continuation.gridcheck.REUSE_LU`` set to False or True before the
command starts. Prints each one's wall time, the machine load before and after, the ratio, and
compares the two files: the same labels, the largest differences of β and L over the common
pulses, and the deepest pulse of each. About 10 min with the defaults.
"""
import argparse
import os
import sys

from slippulse.core.h5io import list_pulses, read_pulse

from _side_by_side import compare_files, run_at_once

RUN = ("import sys; import slippulse.steady.continuation.gridcheck as g; g.REUSE_LU = {reuse}; "
       "from slippulse.cli.app import main; sys.exit(main(sys.argv[1:]))")


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--to", default="1.009")
    ap.add_argument("--max-length", default="1500")
    ap.add_argument("--dir", default="/tmp/bench_march_reuse")
    a = ap.parse_args(argv)
    os.makedirs(a.dir, exist_ok=True)
    files, cmds = {}, {}
    for reuse in (False, True):
        out = os.path.join(a.dir, f"reuse_{reuse}.h5")
        if os.path.exists(out):
            os.remove(out)
        files[reuse] = out
        cmds[reuse] = [sys.executable, "-c", RUN.format(reuse=reuse), "steady", "family",
                       "--from", "1.2", "--to", a.to, "--max-length", a.max_length, "--out", out,
                       "-q"]
    walls = run_at_once(cmds)
    print(f"wall {walls[False]:.0f} s -> {walls[True]:.0f} s: {walls[False] / walls[True]:.2f}x")
    compare_files(files[False], files[True])
    for r in (False, True):
        rows = [read_pulse(files[r], lab)[0] for lab in list_pulses(files[r])]
        by = {}
        for p in rows:
            a = by.setdefault(str(p.extra.get("continuation", "")), [0, 0.0, 0.0])
            a[0] += 1
            a[1] += float(p.wall_time)
            a[2] += float(p.extra.get("grid_check_wall_time", 0.0))
        print(f"reuse={r}: per stage (pulses, solves s, grid checks s): "
              + ", ".join(f"{k} ({v[0]}, {v[1]:.0f}, {v[2]:.0f})" for k, v in by.items()))
        deep = min((p for p in rows if p.converged), key=lambda p: p.tau_d_ratio)
        print(f"reuse={r}: deepest {deep.tau_d_ratio:.7f} tau_min, L = {deep.L:.1f} m, "
              f"N = {deep.xi.size}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
