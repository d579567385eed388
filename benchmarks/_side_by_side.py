"""Shared by the family benchmarks that run two settings as two processes at once
(bench_march_reuse.py, bench_march_warm.py, bench_march_hold.py): the launch, each process's
own wall time and output, the comparison of the two family files, and the two commands that
resume a seed."""
import os
import shutil
import subprocess
import sys
import threading
import time

from slippulse.core.h5io import list_pulses, read_pulse

#: one thread per process: two processes, one per core
ONE_THREAD = {"OMP_NUM_THREADS": "1", "OPENBLAS_NUM_THREADS": "1", "NUMBA_NUM_THREADS": "1",
              "MKL_NUM_THREADS": "1"}


def run_at_once(cmds, last_lines=1, name="reuse", threads=1):
    """Start every command of ``cmds`` (key → argv) at once, ``threads`` threads each (one: one
    process per core here); wait for all.
    Prints the load before and after and, per key, the exit status, its own wall time and the
    last ``last_lines`` non-empty lines of its output (headed ``name=key``). Returns
    {key: wall seconds}."""
    env = dict(os.environ, **{k: str(threads) for k in ONE_THREAD})
    print(f"load before: {os.getloadavg()}", flush=True)
    procs, t0 = {}, {}
    for key, cmd in cmds.items():
        t0[key] = time.perf_counter()
        procs[key] = subprocess.Popen(cmd, env=env, stdout=subprocess.PIPE,
                                      stderr=subprocess.STDOUT, text=True)
    walls, texts = {}, {}
    readers = {k: threading.Thread(target=lambda k=k: texts.__setitem__(k, procs[k].stdout.read()))
               for k in procs}
    for t in readers.values():
        t.start()
    while len(walls) < len(procs):              # each process's own end time
        for key, p in procs.items():
            if key not in walls and p.poll() is not None:
                walls[key] = time.perf_counter() - t0[key]
        time.sleep(0.5)
    for key, p in procs.items():
        readers[key].join()
        last = [ln for ln in texts[key].splitlines() if ln.strip()][-last_lines:]
        print(f"{name}={key}: exit {p.returncode}, wall {walls[key]:.0f} s; {' | '.join(last)}",
              flush=True)
    print(f"load after: {os.getloadavg()}")
    return walls


def compare_files(file_a, file_b, skip=()):
    """The labels both family files hold (less ``skip``, e.g. a seed's), sorted, and the largest
    |Δβ| and |ΔL|/L between them over those; prints the counts and the differences."""
    labs = [set(list_pulses(f)) - set(skip) for f in (file_a, file_b)]
    common = sorted(labs[0] & labs[1])
    db = dl = 0.0
    for lab in common:
        p0, p1 = read_pulse(file_a, lab)[0], read_pulse(file_b, lab)[0]
        db, dl = max(db, abs(p1.beta - p0.beta)), max(dl, abs(p1.L / p0.L - 1.0))
    print(f"pulses: {len(labs[0])} and {len(labs[1])}, {len(common)} common; over those, "
          f"max|dbeta| = {db:.1e}, max|dL|/L = {dl:.1e}")
    return common, db, dl


if __name__ == "__main__":
    sys.exit("a helper module of the benchmarks; run bench_march_reuse.py or bench_march_warm.py")


def resume_commands(run, seed, directory, stem, max_length, quiet=True):
    """The two deep marches of a seed benchmark (bench_march_warm.py, bench_march_hold.py): for
    ``new`` in (False, True), ``seed`` copied to ``directory/{stem}_{new}.h5`` and the command
    ``python -c run.format(new=new) steady family --from 1.2 --to 1.008 --out COPY --max-length
    max_length --ds-min 0.0002 --spacing 0.01`` (``-q`` when ``quiet``) that resumes it.
    Returns ({new: file}, {new: argv})."""
    os.makedirs(directory, exist_ok=True)
    files, cmds = {}, {}
    for new in (False, True):
        out = os.path.join(directory, f"{stem}_{new}.h5")
        shutil.copyfile(seed, out)
        files[new] = out
        cmds[new] = [sys.executable, "-c", run.format(new=new), "steady", "family", "--from",
                     "1.2", "--to", "1.008", "--out", out, "--max-length", str(max_length),
                     "--ds-min", "0.0002", "--spacing", "0.01"] + (["-q"] if quiet else [])
    return files, cmds
