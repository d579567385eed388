"""Cost of adding one pulse to a pulse file against the size of the file, for two versions of
the code side by side.

Usage (from the repository root; about 1 min, writes about 2x the largest size in --dir):

    python benchmarks/bench_append.py --old /path/to/other/checkout/src --sizes 0 200 --repeat 3

For each size (MB of padding: a dataset ``pad`` added to a file holding one pulse) and each code
tree (``--old``, and this checkout's ``src``), a fresh process builds the file and times
``h5io.write_pulse`` of a 279-point pulse ``--repeat`` times (public API only, so any version of
h5io is measured the same way). Prints one JSON line per (tree, size): median and min seconds.
Put the directory on the disk the files live on in practice (``--dir``): a copy costs more there
than on a tmpfs.
"""
from __future__ import annotations

import argparse
import json
import os
import subprocess
import sys
import tempfile

CHILD = r"""
import json, os, statistics, sys, time
import numpy as np
sys.path.insert(0, {tests!r})
from test_analysis import _synthetic_pulse
from slippulse.core import h5io
from slippulse.core.params import DEFAULT as P
path = {path!r}
h5io.write_pulse(path, _synthetic_pulse(1.2, 0.1, 0.1), P)
if {mb} > 0:
    h5io.atomic_update(path, lambda h5: h5.create_dataset("pad", data=np.zeros(int({mb} * 125000))))
ts = []
for i in range({repeat}):
    p = _synthetic_pulse(1.1 - 0.01 * i, 0.1, 0.1)
    t = time.perf_counter()
    h5io.write_pulse(path, p, P)
    ts.append(time.perf_counter() - t)
print(json.dumps({{"n_points": int(p.xi.size), "size_MB": round(os.path.getsize(path) / 1e6, 1),
                  "median_s": statistics.median(ts), "min_s": min(ts)}}))
"""


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--old", required=True, help="src directory of the other code tree")
    ap.add_argument("--sizes", type=float, nargs="+", default=[0, 200])
    ap.add_argument("--repeat", type=int, default=3)
    ap.add_argument("--dir", default=None)
    args = ap.parse_args(argv)
    here = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
    trees = {"old": os.path.abspath(args.old), "new": os.path.join(here, "src")}
    with tempfile.TemporaryDirectory(dir=args.dir) as tmp:
        for mb in args.sizes:
            for name, src in trees.items():
                path = os.path.join(tmp, f"{name}_{mb:g}.h5")
                code = CHILD.format(tests=os.path.join(here, "tests"), path=path, mb=mb,
                                    repeat=args.repeat)
                env = dict(os.environ, PYTHONPATH=src)
                out = subprocess.run([sys.executable, "-c", code], env=env, capture_output=True,
                                     text=True, check=True).stdout.strip().splitlines()[-1]
                row = json.loads(out)
                row.update(tree=name, pad_MB=mb)
                print(json.dumps(row), flush=True)
                os.remove(path)
    return 0


if __name__ == "__main__":
    sys.exit(main())
