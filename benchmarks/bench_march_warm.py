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
import sys

from slippulse.core.h5io import list_pulses, read_pulse

from _side_by_side import compare_files, resume_commands, run_at_once

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
    old = list_pulses(a.seed)
    files, cmds = resume_commands(RUN, a.seed, a.dir, "new", a.max_length, quiet=True)
    walls = run_at_once(cmds, last_lines=2)
    print(f"wall {walls[False]:.0f} s -> {walls[True]:.0f} s: {walls[False] / walls[True]:.2f}x")
    common, _, _ = compare_files(files[False], files[True], skip=old)
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
