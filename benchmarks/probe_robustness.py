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


def _run(args, out=None, timeout=120, stream="stderr"):
    t0 = time.time()
    p = subprocess.run([sys.executable, "-m", "slippulse.cli", *args], capture_output=True,
                       text=True, timeout=timeout)
    text = p.stderr if stream == "stderr" else p.stdout
    lines = [ln for ln in text.strip().splitlines() if ln.strip()]
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


def _unconverged_copy(steady: str, path: str) -> str:
    """A copy of ``steady`` whose pulse is marked converged=False."""
    shutil.copyfile(steady, path)
    with h5py.File(path, "r+") as h5:
        for grp in h5["pulses"].values():
            grp.attrs["converged"] = np.bool_(False)
    return path


def _sigint(args, delay, new_session=True):
    """Start ``args``, send SIGINT to its process group (as Ctrl-C in a terminal does) after
    ``delay`` s; returns (exit code, stderr)."""
    p = subprocess.Popen([sys.executable, "-m", "slippulse", *args], stdout=subprocess.DEVNULL,
                         stderr=subprocess.PIPE, text=True, start_new_session=new_session)
    time.sleep(delay)
    os.killpg(p.pid, signal.SIGINT)
    try:
        _, err = p.communicate(timeout=120)
    except subprocess.TimeoutExpired:
        # a run that ignored Ctrl-C: kill its whole group, so that no orphan keeps a core busy
        os.killpg(p.pid, signal.SIGKILL)
        p.communicate()
        return None, "did not stop within 120 s of SIGINT (killed)"
    return p.returncode, err


def issue19_rows(d: str, steady: str, rows: list, row) -> None:
    """The probes of issue 19 (docs/robustness.md, second table)."""
    out = os.path.join(d, "out.h5")
    bad = _unconverged_copy(steady, os.path.join(d, "unconverged.h5"))
    cfg = os.path.join(d, "run.toml")
    row("run --set fft.threads=0", ["dynamic", "run", cfg, "--set", "fft.threads=0", "--out", out,
                                    "--no-progress"], out)
    row("run --set fft.threads=-3", ["dynamic", "run", cfg, "--set", "fft.threads=-3", "--out",
                                     out, "--no-progress"], out)
    row("run --set fft.planner=bogus", ["dynamic", "run", cfg, "--set", "fft.planner='bogus'",
                                        "--out", out, "--no-progress"], out)
    row("run --out DIR", ["dynamic", "run", cfg, "--out", d, "--no-progress"])
    row("stability --figure s.xyz", ["steady", "stability", steady, "--figure",
                                     os.path.join(d, "s.xyz")], os.path.join(d, "s.xyz"))
    row("family --step 1e-300", ["steady", "family", "--step", "1e-300", "--out", out, "-q"], out)
    row("family --step inf", ["steady", "family", "--step", "inf", "--out", out, "-q"], out)
    row("verify --distance inf", ["dynamic", "verify", "--steady", steady, "--distance", "inf",
                                  "--out", out, "--no-progress"], out)
    row("verify --distance 1e9", ["dynamic", "verify", "--steady", steady, "--distance", "1e9",
                                  "--out", out, "--no-progress"], out)
    row("seed --dx 1e9", ["dynamic", "seed", "--steady", steady, "--dx", "1e9", "--out", out], out)
    row("solve --out unwritable (/sys)", ["steady", "solve", "--out", "/sys/x.h5", "-q"])
    row("stability on a missing file under /sys", ["steady", "stability", "/sys/x.h5"])
    row("figures --outdir unwritable", ["figures", steady, "--outdir", "/sys/figs"])
    raw = open(steady, "rb").read()
    row("solve --tau-d 1.2 --out FILE holding td1.2000 (no --overwrite)",
        ["steady", "solve", "--tau-d", "1.2", "--points", "500", "--out", steady, "-q",
         "--no-figure"])
    rows[-1][2]["last"] += (" [file bit-identical]" if open(steady, "rb").read() == raw
                            else " [FILE CHANGED]")
    for what, cmd in (
            ("seed unconverged", ["dynamic", "seed", "--steady", bad, "--out", out]),
            ("verify unconverged", ["dynamic", "verify", "--steady", bad, "--out", out,
                                    "--no-progress"]),
            ("analyse unconverged", ["steady", "analyse", bad]),
            ("figures unconverged", ["figures", bad, "--outdir", os.path.join(d, "figs")]),
            ("stability unconverged", ["steady", "stability", bad, "--labels", "td1.2000"])):
        row(what, cmd, out)
    row("analyse a one-pulse file (stdout, last line)", ["steady", "analyse", steady,
                                                          "--no-write"], stream="stdout")
    mode = oct(os.stat(steady).st_mode & 0o777)
    mask = os.umask(0)
    os.umask(mask)
    rows.append(("mode of an HDF5 output (umask " + oct(mask) + ")",
                 "stat good.h5", {"rc": 0, "last": mode, "tb": False, "left": None}))
    for what, cmd in (("--version", ["--version"]), ("python -m slippulse --version",
                                                     ["--version"])):
        p = subprocess.run([sys.executable, "-m", "slippulse", *cmd], capture_output=True,
                           text=True)
        rows.append((what, "python -m slippulse " + " ".join(cmd),
                     {"rc": p.returncode, "last": p.stdout.strip(), "tb": "Traceback" in p.stderr,
                      "left": None}))
    # Ctrl-C of a dynamic run: status 'interrupted'
    run_out = os.path.join(d, "int.h5")
    rc, err = _sigint(["dynamic", "run", cfg, "--set", "time.max_steps=1000000", "--set",
                       "time.t_end=1e6", "--set", "output.checkpoint_every=7", "--out", run_out,
                       "--no-progress"], 15.0)
    try:
        with h5py.File(run_out, "r") as h5:
            status = str(h5.attrs["status"])
    except (OSError, KeyError) as exc:
        status = f"NOT READABLE ({exc})"
    rows.append(("Ctrl-C dynamic run after 15 s", "slippulse dynamic run run.toml --set "
                 "time.t_end=1e6 ... (SIGINT to the group)",
                 {"rc": rc, "last": f"status {status!r}" + (f" [stderr: {err.strip()[-200:]}]"
                                                            if "Traceback" in err else ""),
                  "tb": "Traceback" in err, "left": None}))
    # Ctrl-C of a scan with 2 workers (a runner that sleeps 30 s per case)
    here = os.path.dirname(os.path.abspath(__file__))
    toml = os.path.join(d, "slow_scan.toml")
    with open(toml, "w") as fh:
        fh.write(f"""[scan]
name = "slow"
out_dir = "{os.path.join(d, 'scan_out')}"
runner = "scan_fake_runner:run_case"
runner_path = ["{os.path.join(os.path.dirname(here), 'tests')}"]
[defaults]
sleep = 30.0
[grid]
eps = [1e-3, -1e-3, 2e-3]
""")
    rc, err = _sigint(["dynamic", "scan", toml, "--workers", "2", "--no-progress"], 20.0)
    noise = [w for w in ("Exception ignored", "leaked semaphore", "KeyboardInterrupt", "Traceback")
             if w in err]
    rows.append(("Ctrl-C dynamic scan (2 workers) after 20 s",
                 "slippulse dynamic scan slow_scan.toml --workers 2 (SIGINT to the group)",
                 {"rc": rc, "last": (err.strip().splitlines() or [""])[-1]
                  + (f" [NOISE: {noise}]" if noise else " [no other output]"),
                  "tb": "Traceback" in err, "left": None}))
    row("solve --tau-d 1.15 (continuation from 1.2)", ["steady", "solve", "--tau-d", "1.15",
                                                       "--out", os.path.join(d, "td115.h5"), "-q",
                                                       "--no-figure"], stream="stdout",
        timeout=900)


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--dir", default=os.path.join("runs", "probe"))
    ap.add_argument("--only-issue19", action="store_true",
                    help="run only the probes added by issue 19")
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

    def row(what, cmd, output=None, stream="stderr", timeout=120):
        if output and os.path.exists(output):
            if os.path.isdir(output):
                shutil.rmtree(output)
            else:
                os.remove(output)
        r = _run(cmd, output, stream=stream, timeout=timeout)
        rows.append((what, "slippulse " + " ".join(os.path.relpath(c, d) if c.startswith(d) else c
                                                  for c in cmd), r))

    if args.only_issue19:
        issue19_rows(d, steady, rows, row)
        _table(rows)
        return 0
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

    issue19_rows(d, steady, rows, row)
    _table(rows)
    return 0


def _table(rows) -> None:
    print("| case | command | exit | stderr (last line) | traceback | output left |")
    print("|---|---|---|---|---|---|")
    for what, cmd, r in rows:
        last = r["last"].replace("|", "\\|")
        if len(last) > 160:
            last = last[:157] + "..."
        left = "–" if r["left"] is None else ("YES" if r["left"] else "no")
        print(f"| {what} | `{cmd}` | {r['rc']} | {last} | {'YES' if r['tb'] else 'no'} | {left} |")


if __name__ == "__main__":
    sys.exit(main())
