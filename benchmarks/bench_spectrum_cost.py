"""The cost of the family's growth rates: today's `slippulse steady stability` against the code
and defaults before this change (issue 17, item 5), side by side on the same pulses.

    git worktree add --detach /work/base17 0190b52
    python benchmarks/bench_spectrum_cost.py FAMILY.h5 --base /work/base17 \
        --labels td1.2000 td1.0500 td1.0200 td1.012759 td1.009365 --reference REF.h5 [REF2.h5]

Three runs, each command as a subprocess from its own tree on its own copy of FAMILY.h5 (numba
caches warmed first, not timed):

* old code, old defaults (level 0 at N_0 = max(N, 2000), three levels; for pulses with N > 2828
  ``--points 2828``, as the rates of record were made);
* old code on the new ladder (``--levels 1 --min-points 1000``, ``--points 2828`` where N > 2828,
  ``--target 1e-4``): the same levels as the new defaults where no relative goal is at work, so
  the ratio to the new run is the code's own speedup;
* new code, new defaults.

Prints wall times per pulse and in all, their ratios, and s L/c_p ± err of each run; with
``--reference`` (a file whose pulses hold spectra of record) the distance of each run's value to
the reference's, and whether its error bar covers it.

    python benchmarks/bench_spectrum_cost.py FAMILY.h5 --compare --reference REF.h5 [REF2.h5]

only compares the spectra stored in FAMILY.h5 (e.g. after ``slippulse steady stability
FAMILY.h5``) with the references, pulse by pulse, and checks the goal of the defaults.
"""
from __future__ import annotations

import argparse
import os
import shutil
import sys
import tempfile

import h5py
from bench_spectrum_family import HERE, run as run_cli   # one subprocess runner for both


def run(cmd, src, cwd):
    """Wall time of `cmd` run with the package from `src` (bench_spectrum_family.run)."""
    return run_cli(cmd, src, cwd)[0]


def n_points(path, lab):
    with h5py.File(path, "r") as h5:
        return int(h5["pulses"][lab]["xi"].size)


def rate(path, lab):
    """(s L/c_p, err, levels) stored for `lab`, or None."""
    with h5py.File(path, "r") as h5:
        g = h5["pulses"][lab]
        if "spectrum" not in g or "s_per_L" not in g["spectrum"].attrs:
            return None
        a = g["spectrum"].attrs
        return (float(a["s_per_L"]), float(a["s_err_per_L"]),
                "/".join(str(int(n)) for n in a["refine_n_points"]))


def references(paths, labels=None):
    """{label: (s L/c_p, err, levels)} from the files (the first that has a pulse wins)."""
    ref = {}
    for path in reversed(paths):
        with h5py.File(path, "r") as h5:
            have = [lab for lab in h5["pulses"] if labels is None or lab in labels]
        ref.update({lab: r for lab in have if (r := rate(path, lab)) is not None})
    return ref


def compare(path, ref_paths):
    """The stored rates of `path` against the references; the goal of the defaults."""
    from slippulse.core.h5io import label_ratio
    from slippulse.spectrum.refine import goal
    from slippulse.spectrum.family import DEFAULT_REL_TARGET, DEFAULT_TARGET
    ref = references(ref_paths)
    with h5py.File(path, "r") as h5:
        labels = sorted(h5["pulses"], key=lambda k: -label_ratio(k))
    print("| pulse | s L/c_p ± err (levels) | reference ± err (levels) | |diff| | |diff| / err "
          "| covered |")
    print("|---|---|---|---|---|---|")
    missed, bad, n = [], 0, 0
    for lab in labels:
        v = rate(path, lab)
        if v is None:
            print(f"| {lab} | no rate stored | | | | |")
            continue
        if v[1] > goal(DEFAULT_TARGET, DEFAULT_REL_TARGET, v[0]):
            missed.append(lab)
        r = ref.get(lab)
        if r is None:
            continue
        d = abs(v[0] - r[0])
        ok = d <= v[1] + r[1]
        n += 1
        bad += not ok
        print(f"| {lab} | {v[0]:.7g} ± {v[1]:.1g} ({v[2]}) | {r[0]:.7g} ± {r[1]:.1g} ({r[2]}) "
              f"| {d:.1g} | {d / v[1]:.2f} | {'yes' if ok else 'NO'} |")
    print(f"{n} pulses with a reference, {bad} not covered; {len(labels)} pulses, goal of the "
          f"defaults missed at {len(missed)} {missed[:5]}")
    return 0


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("family")
    ap.add_argument("--base", help="worktree of the code before this change")
    ap.add_argument("--labels", nargs="+")
    ap.add_argument("--compare", action="store_true",
                    help="only compare the spectra stored in FAMILY with --reference")
    ap.add_argument("--reference", nargs="+", default=None,
                    help="files with spectra of record (the first that has a pulse's wins)")
    ap.add_argument("--workdir", default=None)
    a = ap.parse_args(argv)
    if a.compare:
        return compare(a.family, a.reference or [])
    if not (a.base and a.labels):
        ap.error("--base and --labels are needed (or --compare)")
    work = a.workdir or tempfile.mkdtemp(prefix="bench_cost_")
    os.makedirs(work, exist_ok=True)
    new_src, old_src = os.path.join(HERE, "src"), os.path.join(a.base, "src")
    cli = [sys.executable, "-m", "slippulse.cli", "steady", "stability"]
    print(f"load average at start: {os.getloadavg()}")
    for src in (new_src, old_src):                       # warm the numba caches (not timed)
        f = os.path.join(work, "warm.h5")
        shutil.copy(a.family, f)
        run(cli + [f, "--labels", a.labels[0], "--levels", "0", "-q", "--overwrite"], src, work)
    runs = {"old code, old defaults": (old_src, lambda n: ["--points", "2828"] if n > 2828 else []),
            "old code, new ladder": (old_src, lambda n: ["--levels", "1", "--min-points", "1000",
                                                         "--target", "1e-4"]
                                     + (["--points", "2828"] if n > 2828 else [])),
            "new code, new defaults": (new_src, lambda n: [])}
    times, vals = {}, {}
    for name, (src, opts) in runs.items():
        f = os.path.join(work, name.replace(" ", "_").replace(",", "") + ".h5")
        shutil.copy(a.family, f)
        times[name] = {}
        for lab in a.labels:           # one pulse at a time: the first is tracked from the file
            times[name][lab] = run(cli + [f, "--labels", lab, "--overwrite", "-q"]
                                   + opts(n_points(f, lab)), src, work)
        vals[name] = {lab: rate(f, lab) for lab in a.labels}
    print(f"load average at end: {os.getloadavg()}")
    ref = references(a.reference or [], set(a.labels))
    names = list(runs)
    print("| pulse | " + " | ".join(f"{n}: s L/c_p ± err (levels), wall" for n in names)
          + (" | reference |" if ref else " |"))
    print("|---" * (len(names) + 1 + bool(ref)) + "|")
    for lab in a.labels:
        cells = []
        for n in names:
            v = vals[n][lab]
            if v is None:
                cells.append(f"failed, {times[n][lab]:.0f} s")
                continue
            c = f"{v[0]:.7g} ± {v[1]:.1g} ({v[2]}), {times[n][lab]:.0f} s"
            r = ref.get(lab)
            if r is not None and r:
                d = abs(v[0] - r[0])
                c += f"; off {d:.1g}, " + ("covered" if d <= v[1] + r[1] else "NOT covered")
            cells.append(c)
        r = ref.get(lab)
        print(f"| {lab} | " + " | ".join(cells)
              + ((f" | {r[0]:.7g} ± {r[1]:.1g} ({r[2]}) |" if r else " | – |") if ref
                 else " |"))
    tot = {n: sum(times[n].values()) for n in names}
    print("total wall: " + ", ".join(f"{n} {tot[n]:.0f} s" for n in names))
    print(f"ratio old defaults / new defaults: {tot[names[0]] / tot[names[2]]:.2f}; "
          f"same ladder, old code / new code: {tot[names[1]] / tot[names[2]]:.2f}")


if __name__ == "__main__":
    main()
