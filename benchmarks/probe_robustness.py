"""Bad-input and crash probe of the command line (issue 12, item 5); prints a Markdown table.

Usage (from the repository root, ≈ 2 min; needs a steady file, made here if absent):

    python benchmarks/probe_robustness.py [--dir /tmp/probe] > probe.md

Each row runs one ``slippulse`` command in a fresh process on a bad input — a file that is not
HDF5, empty, truncated, foreign (HDF5 of another program), missing; a bad pulse label; a huge or
invalid size — and records the exit code, the last line of stderr, whether a traceback was
printed, and whether an output file was left behind. Expected for every row: exit code 2, one
line ``slippulse: error: ...`` naming the parameter or file, no traceback, no output file. The
kill rows start a command, kill it with SIGKILL while it writes, and check that no partial output
file is left (steady solve, verify) or that the file is still complete (dynamic run).
"""
from __future__ import annotations

import argparse
import os
import shutil
import signal
import subprocess
import sys
import time

import h5py
import numpy as np

CFG = """[grid]
n = 64
length = 0.5
[time]
max_steps = 50
"""


def _files(d: str, steady: str) -> dict:
    """The bad inputs (paths) in ``d``."""
    paths = {k: os.path.join(d, f"{k}.h5") for k in ("text", "empty", "trunc", "foreign",
                                                        "foreign_pulses", "missing")}
    with open(paths["text"], "w") as fh:
        fh.write("not an HDF5 file\n")
    open(paths["empty"], "w").close()
    with open(steady, "rb") as fh:
        data = fh.read()
    with open(paths["trunc"], "wb") as fh:
        fh.write(data[: len(data) // 3])
    with h5py.File(paths["foreign"], "w") as h5:
        h5.create_dataset("a", data=np.arange(3))
    with h5py.File(paths["foreign_pulses"], "w") as h5:
        h5.create_group("pulses").create_group("hello")
    with open(os.path.join(d, "bad.toml"), "w") as fh:
        fh.write("[grid\nn = = 3\n")
    with open(os.path.join(d, "run.toml"), "w") as fh:
        fh.write(CFG)
    with open(os.path.join(d, "binary.toml"), "wb") as fh:
        fh.write(bytes(range(256)))
    return paths


def _run(args, out=None, timeout=120):
    t0 = time.time()
    p = subprocess.run([sys.executable, "-m", "slippulse.cli", *args], capture_output=True,
                       text=True, timeout=timeout)
    lines = [ln for ln in p.stderr.strip().splitlines() if ln.strip()]
    left = bool(out) and os.path.exists(out)
    return {"rc": p.returncode, "last": lines[-1] if lines else "", "tb": "Traceback" in p.stderr,
            "left": left, "wall": time.time() - t0}


def _kill(args, out, delay, check):
    """Start ``args``, SIGKILL it after ``delay`` s, return the row with ``check(out)``."""
    p = subprocess.Popen([sys.executable, "-m", "slippulse.cli", *args],
                         stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
    time.sleep(delay)
    p.send_signal(signal.SIGKILL)
    p.wait()
    return {"rc": p.returncode, "last": check(out), "tb": False, "left": None, "wall": delay}


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--dir", default=os.path.join("runs", "probe"))
    args = ap.parse_args(argv)
    d = os.path.abspath(args.dir)
    shutil.rmtree(d, ignore_errors=True)
    os.makedirs(d)
    steady = os.path.join(d, "good.h5")
    subprocess.run([sys.executable, "-m", "slippulse.cli", "steady", "solve", "--tau-d", "1.2",
                    "--points", "500", "--out", steady, "-q", "--no-figure"], check=True,
                   capture_output=True)
    f = _files(d, steady)
    out = os.path.join(d, "out.h5")
    fam_out = os.path.join(d, "figs")
    rows = []

    def row(what, cmd, output=None):
        if output and os.path.exists(output):
            if os.path.isdir(output):
                shutil.rmtree(output)
            else:
                os.remove(output)
        r = _run(cmd, output)
        rows.append((what, "slippulse " + " ".join(os.path.relpath(c, d) if c.startswith(d) else c
                                                  for c in cmd), r))

    for kind in ("text", "empty", "trunc", "foreign", "foreign_pulses", "missing"):
        row(f"verify --steady {kind}", ["dynamic", "verify", "--steady", f[kind], "--out", out,
                                        "--no-progress", "--distance", "0.01"], out)
        row(f"seed --steady {kind}", ["dynamic", "seed", "--steady", f[kind], "--out", out], out)
        row(f"analyse {kind}", ["steady", "analyse", f[kind]])
        row(f"figures {kind}", ["figures", f[kind], "--outdir", fam_out], fam_out)
        row(f"run --resume --out {kind}", ["dynamic", "run", os.path.join(d, "run.toml"),
                                           "--out", f[kind], "--resume", "--no-progress"])
    row("steady solve --out over a text file", ["steady", "solve", "--points", "300", "--out",
                                                f["text"], "-q", "--no-figure"])
    row("steady solve --out in a missing directory",
        ["steady", "solve", "--points", "300", "--out", os.path.join(f["text"], "x.h5"), "-q",
         "--no-figure"])
    row("verify --label td9.9999", ["dynamic", "verify", "--steady", steady, "--label",
                                    "td9.9999", "--out", out, "--no-progress"], out)
    row("verify --label ../x", ["dynamic", "verify", "--steady", steady, "--label", "../x",
                                "--out", out, "--no-progress"], out)
    row("steady solve --tau-d abc", ["steady", "solve", "--tau-d", "abc", "--out", out], out)
    row("steady solve --points 10**9", ["steady", "solve", "--points", "1000000000", "--out",
                                        out, "-q"], out)
    row("steady solve --tol -1", ["steady", "solve", "--points", "300", "--tol", "-1", "--out",
                                  out, "-q", "--no-figure"], out)
    row("verify --points 10**9", ["dynamic", "verify", "--steady", steady, "--points",
                                  "1000000000", "--out", out, "--no-progress"], out)
    row("verify --dx 1e-9", ["dynamic", "verify", "--steady", steady, "--dx", "1e-9", "--out",
                             out, "--no-progress"], out)
    row("verify --dx nan", ["dynamic", "verify", "--steady", steady, "--dx", "nan", "--out",
                            out, "--no-progress"], out)
    row("verify --samples 0", ["dynamic", "verify", "--steady", steady, "--samples", "0",
                               "--distance", "0.01", "--out", out, "--no-progress"], out)
    row("verify --distance 1e9", ["dynamic", "verify", "--steady", steady, "--distance", "1e9",
                                  "--dx", "1e-2", "--samples", "10", "--out", out,
                                  "--no-progress"], out)
    row("verify --ahead -1", ["dynamic", "verify", "--steady", steady, "--ahead", "-1", "--out",
                              out, "--no-progress"], out)
    row("run: config not TOML", ["dynamic", "run", os.path.join(d, "bad.toml"), "--out", out,
                                 "--no-progress"], out)
    row("run: config binary", ["dynamic", "run", os.path.join(d, "binary.toml"), "--out", out,
                               "--no-progress"], out)
    row("run: config missing", ["dynamic", "run", os.path.join(d, "nope.toml"), "--out", out,
                                "--no-progress"], out)
    row("run --set grid.n=2**40", ["dynamic", "run", os.path.join(d, "run.toml"), "--set",
                                   "grid.n=1099511627776", "--out", out, "--no-progress"], out)
    row("scan: file not TOML", ["dynamic", "scan", os.path.join(d, "bad.toml")])
    row("scan: empty file", ["dynamic", "scan", f["empty"]])
    row("scan: missing file", ["dynamic", "scan", os.path.join(d, "nope.toml")])

    # kills while writing
    def no_output(path):
        left = [n for n in os.listdir(os.path.dirname(path)) if n.startswith(".tmp-")]
        return ("no output, no temp file" if not os.path.exists(path) and not left
                else f"LEFT: {os.path.exists(path)} {left}")

    def complete_run(path):
        try:
            with h5py.File(path, "r") as h5:
                n = int(h5["checkpoint/nstep"][()])
                ok = len(h5["scalars/step"]) == n
            return f"complete file at checkpoint step {n}" if ok else "INCONSISTENT"
        except (OSError, KeyError) as exc:
            return f"NOT READABLE: {exc}" if os.path.exists(path) else "no file yet"

    kdir = os.path.join(d, "kill")
    os.makedirs(kdir)
    for delay in (1.5, 3.0):
        p = os.path.join(kdir, f"steady_{delay}.h5")
        rows.append((f"kill steady solve after {delay} s",
                     f"slippulse steady solve --points 4000 --out kill/steady_{delay}.h5",
                     _kill(["steady", "solve", "--points", "4000", "--out", p, "-q"], p, delay,
                           no_output)))
        p = os.path.join(kdir, f"verify_{delay}.h5")
        rows.append((f"kill verify after {delay} s",
                     f"slippulse dynamic verify --steady good.h5 --out kill/verify_{delay}.h5",
                     _kill(["dynamic", "verify", "--steady", steady, "--out", p, "--distance",
                            "0.05", "--no-progress"], p, delay, no_output)))
        p = os.path.join(kdir, f"run_{delay}.h5")
        rows.append((f"kill dynamic run after {delay} s",
                     f"slippulse dynamic run run.toml --set time.max_steps=100000 "
                     f"--out kill/run_{delay}.h5",
                     _kill(["dynamic", "run", os.path.join(d, "run.toml"), "--set",
                            "time.max_steps=100000", "--set", "output.checkpoint_every=7",
                            "--out", p, "--no-progress"], p, delay, complete_run)))

    print("| case | command | exit | stderr (last line) | traceback | output left |")
    print("|---|---|---|---|---|---|")
    for what, cmd, r in rows:
        last = r["last"].replace("|", "\\|")
        if len(last) > 160:
            last = last[:157] + "..."
        left = "–" if r["left"] is None else ("YES" if r["left"] else "no")
        print(f"| {what} | `{cmd}` | {r['rc']} | {last} | {'YES' if r['tb'] else 'no'} | {left} |")
    return 0


if __name__ == "__main__":
    sys.exit(main())
