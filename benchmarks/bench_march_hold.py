"""The deep march resumed from a seed with the "auto" march's settings of stop 45 and with those of
stop 44, side by side: two processes at once, one per core, one thread each (``--threads``: more
each, on a machine with more cores). Stop 45 added ``DeepSettings.hold`` (ds kept at or below
``predictor_ds_max`` once a tangent step above it has failed and a secant step below it has
passed; a resume starts there) and ``DeepSettings.chord_held`` (chord iterations on the last LU
once held).

    python benchmarks/bench_march_hold.py [SEED.h5] [--max-length 5000] [--dir /tmp/bmh]
        [--threads 1]

Each process copies SEED.h5 (default: the committed steady/seeds/deep_seed_s44.h5, 4892 m,
N = 5062) and runs ``slippulse steady family --from 1.2 --to 1.008 --out COPY --max-length L
--ds-min 0.0002 --spacing 0.01`` on it, the setting set before the command starts. Prints
each one's wall time, the machine load before and after, the ratio, each command's summary line
(with its failed attempts: the failed steps are what hold removes), and compares the two
files (the labels both hold, the largest differences of β and L over them). About 15 min with
the defaults.
"""
import argparse
import os
import sys

from slippulse.core.h5io import list_pulses, read_pulse

from _side_by_side import compare_files, resume_commands, run_at_once

RUN = ("import sys, dataclasses; import slippulse.steady.continuation.family as f; "
       "f.AUTO_DEEP = dataclasses.replace(f.AUTO_DEEP, hold={new}, chord_held={new}); "
       "from slippulse.cli.app import main; sys.exit(main(sys.argv[1:]))")
SEED = os.path.join(os.path.dirname(__file__), "..", "steady", "seeds", "deep_seed_s44.h5")


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("seed", nargs="?", default=SEED)
    ap.add_argument("--max-length", default="5000")
    ap.add_argument("--dir", default="/tmp/bench_march_hold")
    ap.add_argument("--threads", type=int, default=1, help="threads per process (default 1)")
    a = ap.parse_args(argv)
    old = list_pulses(a.seed)
    files, cmds = resume_commands(RUN, a.seed, a.dir, "hold", a.max_length, quiet=False)
    walls = run_at_once(cmds, last_lines=1, name="hold", threads=a.threads)
    print(f"wall {walls[False]:.0f} s -> {walls[True]:.0f} s: {walls[False] / walls[True]:.2f}x")
    common, _, _ = compare_files(files[False], files[True], skip=old)
    for new in (False, True):
        labs = [lab for lab in list_pulses(files[new]) if lab not in old]
        deep = max((read_pulse(files[new], lab)[0].L for lab in labs), default=float("nan"))
        print(f"hold={new}: {len(labs)} pulses written, deepest L = {deep:.1f} m")
    return 0


if __name__ == "__main__":
    sys.exit(main())
