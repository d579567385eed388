"""The growth rate of deep pulses with and without the creep stop of the clipped level 0, side by
side in one run (issue 17, item 5; stop 36).

    python benchmarks/bench_spectrum_level0.py FAMILY.h5 LABEL [LABEL ...] --guess S

For each pulse: ``run_spectrum`` as ``slippulse steady stability FILE --labels LABEL --no-extra
--guess S`` runs it (defaults: level 0 at N clipped to 2828, one level above, target 1e-4), on a
fresh copy of the family file each time, first with
``spectrum_family.LEVEL0_CREEP = 0`` (before: a clipped level-0 re-solve that cannot converge
runs its 60 Newton iterations before the pulse's own N is taken) and then with the default
(:data:`slippulse.spectrum.family.LEVEL0_CREEP`). Prints per run the wall time, the
level-0 and finest N, s L/c_p ± err; then the ratio of the walls and the largest difference of
the two rates (they must be equal: both runs end on the same levels). Pulses beyond L ≈ 2.8 km
(N = 3542) are the ones whose clipped re-solve fails; shallower ones run the same way in both.
About 2-2.5 min per run at 5 km on one thread.
"""
import argparse
import os
import shutil
import sys
import tempfile
import time

import slippulse.spectrum.family as sf


def one(family, label, guess, creep):
    tmp = tempfile.mkdtemp(prefix="bench_level0_")
    try:
        path = os.path.join(tmp, "f.h5")
        shutil.copy(family, path)
        sf.LEVEL0_CREEP = creep
        t0 = time.perf_counter()
        rep = sf.run_spectrum(path, sf.SpectrumSettings(extra=False), labels=[label], guess=guess)
        wall = time.perf_counter() - t0
    finally:
        shutil.rmtree(tmp, ignore_errors=True)
    res = rep.results[0]
    ref = res.refined
    return wall, res.status, ref


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("family")
    ap.add_argument("labels", nargs="+")
    ap.add_argument("--guess", type=float, required=True,
                    help="s L/c_p to start the search from (a deep pulse has none stored above)")
    a = ap.parse_args(argv)
    now = sf.LEVEL0_CREEP
    print(f"load: {os.getloadavg()[0]:.2f} (1 min), threads: "
          f"OMP={os.environ.get('OMP_NUM_THREADS', '-')}")
    try:
        for lab in a.labels:
            rows = []
            for creep in (0, now):
                wall, status, ref = one(a.family, lab, a.guess, creep)
                rows.append((wall, ref))
                print(f"{lab} LEVEL0_CREEP={creep}: {wall:7.1f} s  {status}  N={ref.n_points}  "
                      f"s L/c_p = {ref.s_per_L:.8e} +- {ref.s_err_per_L:.1e}", flush=True)
            (w0, r0), (w1, r1) = rows
            print(f"{lab}: ratio {w0 / w1:.2f}x, |difference of s L/c_p| = "
                  f"{abs(r0.s_per_L - r1.s_per_L):.1e}", flush=True)
    finally:
        sf.LEVEL0_CREEP = now
    return 0


if __name__ == "__main__":
    sys.exit(main())
