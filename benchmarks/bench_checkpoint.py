"""Cost of one checkpoint of a dynamic run against the size of its output file.

Usage (from the repository root; ≈ 1 min, writes ≈ 2× the largest size in a temporary directory):

    python benchmarks/bench_checkpoint.py --n 4096 --sizes 2 20 100 200 --repeat 3

Builds the default ``slippulse dynamic run`` stepper with N = ``--n`` points, opens a run file
(``dynio.RunFile``) in a temporary directory, appends snapshots of the current state until the file
holds about each size in ``--sizes`` (MB), and at each size times ``--repeat`` calls of
``RunFile.checkpoint`` (the time the run is paused: the state written and the file published).
Only the public ``RunFile`` API is used, so the same script measures any version of the run-file module (dynio.py, now dynamics/runfile.py).
Prints one JSON line per size: file size (MB), median and min seconds per checkpoint.
"""
from __future__ import annotations

import argparse
import json
import os
import statistics
import sys
import tempfile
import time


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--n", type=int, default=4096, help="grid points (default 4096)")
    ap.add_argument("--sizes", type=float, nargs="+", default=[2, 20, 100, 200],
                    help="file sizes in MB at which to time checkpoints")
    ap.add_argument("--repeat", type=int, default=3, help="checkpoints timed per size")
    ap.add_argument("--dir", default=None, help="directory for the run file (default: a temp dir)")
    args = ap.parse_args(argv)

    from slippulse import __version__
    from slippulse.dynamics.config import build_stepper, load_config
    from slippulse.dynamics.runfile import RunFile

    cfg = load_config(None, [f"grid.n={args.n}"])
    st = build_stepper(cfg)
    with tempfile.TemporaryDirectory(dir=args.dir) as tmp:
        path = os.path.join(tmp, "run.h5")
        out = RunFile.create(path, cfg, st.params, st)
        out.snapshot(st)
        out.checkpoint(st)
        for size in sorted(args.sizes):
            while os.path.getsize(out.work) < size * 1e6:
                for _ in range(16):
                    st.nstep += 1
                    st.t += 1e-6
                    out.record_step(st)
                    out.snapshot(st)
                out.h5.flush()
            times = []
            for _ in range(args.repeat):
                st.nstep += 1
                st.t += 1e-6
                out.record_step(st)
                t0 = time.perf_counter()
                out.checkpoint(st)
                times.append(time.perf_counter() - t0)
            print(json.dumps({"slippulse": __version__, "n": args.n,
                              "file_MB": round(os.path.getsize(path) / 1e6, 1),
                              "median_s": round(statistics.median(times), 4),
                              "min_s": round(min(times), 4),
                              "load_avg_1min": round(os.getloadavg()[0], 2)}), flush=True)
        out.close()
    return 0


if __name__ == "__main__":
    sys.exit(main())
