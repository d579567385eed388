"""The deep march resumed from a seed with this code's reuse (the corrector's LU kept for the next
tangent and corrector, ``DeepSettings.reuse_lu``; each grid check started from the last check's
fine pulse and LU, ``family.WARM_CHECKS``) and without (the code of stop 43), side by side: two
processes at once, one per core, one thread each.

    python benchmarks/bench_march_warm.py [SEED.h5] [--max-length 2700] [--dir /tmp/bmw]

Each process copies SEED.h5 (default: the committed steady/seeds/deep_seed_s43.h5, 2550 m) and
runs ``slippulse steady family --from 1.2 --to 1.008 --out COPY --max-length L --ds-min 0.0002
--spacing 0.01 -q`` on it, the two settings set before the command starts. Prints each one's
wall time, the machine load before and after, the ratio; compares the two files (the same labels,
the largest differences of β and L over the common pulses) and the grid checks' wall times per
pulse. About 10 min with the defaults.
"""
import argparse
import os
import shutil
import subprocess
import sys
import threading
import time

from slippulse.core.h5io import list_pulses, read_pulse

RUN = ("import sys, dataclasses; import slippulse.steady.continuation.family as f; "
       "f.WARM_CHECKS = {new}; f.AUTO_DEEP = dataclasses.replace(f.AUTO_DEEP, reuse_lu={new}); "
       "from slippulse.cli.app import main; sys.exit(main(sys.argv[1:]))")
SEED = os.path.join(os.path.dirname(__file__), "..", "steady", "seeds", "deep_seed_s43.h5")


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("seed", nargs="?", default=SEED)
    ap.add_argument("--max-length", default="2700")
    ap.add_argument("--dir", default="/tmp/bench_march_warm")
    a = ap.parse_args(argv)
    os.makedirs(a.dir, exist_ok=True)
    env = dict(os.environ, OMP_NUM_THREADS="1", OPENBLAS_NUM_THREADS="1", NUMBA_NUM_THREADS="1",
               MKL_NUM_THREADS="1")
    procs, files, t0 = {}, {}, {}
    old = list_pulses(a.seed)
    print(f"load before: {os.getloadavg()}", flush=True)
    for new in (False, True):
        out = os.path.join(a.dir, f"new_{new}.h5")
        shutil.copyfile(a.seed, out)
        files[new] = out
        cmd = [sys.executable, "-c", RUN.format(new=new), "steady", "family", "--from", "1.2",
               "--to", "1.008", "--out", out, "--max-length", a.max_length, "--ds-min", "0.0002",
               "--spacing", "0.01", "-q"]
        t0[new] = time.perf_counter()
        procs[new] = subprocess.Popen(cmd, env=env, stdout=subprocess.PIPE,
                                      stderr=subprocess.STDOUT, text=True)
    walls, texts = {}, {}
    readers = {r: threading.Thread(target=lambda r=r: texts.__setitem__(r, procs[r].stdout.read()))
               for r in procs}
    for t in readers.values():
        t.start()
    while len(walls) < len(procs):
        for new, p in procs.items():
            if new not in walls and p.poll() is not None:
                walls[new] = time.perf_counter() - t0[new]
        time.sleep(0.5)
    for new, p in procs.items():
        readers[new].join()
        last = [ln for ln in texts[new].splitlines() if ln.strip()][-2:]
        print(f"reuse={new}: exit {p.returncode}, wall {walls[new]:.0f} s; {' | '.join(last)}",
              flush=True)
    print(f"load after: {os.getloadavg()}")
    print(f"wall {walls[False]:.0f} s -> {walls[True]:.0f} s: {walls[False] / walls[True]:.2f}x")
    labs = [set(list_pulses(files[r])) - set(old) for r in (False, True)]
    common = sorted(labs[0] & labs[1])
    db = dl = 0.0
    for lab in common:
        p0, p1 = read_pulse(files[False], lab)[0], read_pulse(files[True], lab)[0]
        db, dl = max(db, abs(p1.beta - p0.beta)), max(dl, abs(p1.L / p0.L - 1.0))
    print(f"new pulses: {len(labs[0])} and {len(labs[1])}, {len(common)} common; over those, "
          f"max|dbeta| = {db:.1e}, max|dL|/L = {dl:.1e}")
    print("| label | L (m) | check s, old | check s, reuse | dL/L of the check, old | reuse |")
    print("|---|---|---|---|---|---|")
    for lab in sorted(common, reverse=True):
        p0, p1 = read_pulse(files[False], lab)[0], read_pulse(files[True], lab)[0]
        print(f"| {lab} | {p1.L:.1f} | {float(p0.extra['grid_check_wall_time']):.1f} | "
              f"{float(p1.extra['grid_check_wall_time']):.1f} | "
              f"{float(p0.extra['grid_check_dL_rel']):.2e} | "
              f"{float(p1.extra['grid_check_dL_rel']):.2e} |")
    return 0


if __name__ == "__main__":
    sys.exit(main())
