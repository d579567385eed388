"""Bad-input, concurrency, full-disk and kill probe of the command line; prints a Markdown table
(the case table of docs/robustness.md).

Usage (from the repository root, about 5 min; run as root to include the full-disk rows, which
mount a small tmpfs):

    python benchmarks/probe_robustness.py [--dir /tmp/probe] [--only GROUP ...] > probe.md

Each row runs one ``slippulse`` command in a fresh process and records the exit code, the last
line of stderr, whether a traceback was printed and whether an output was left behind. Expected:
exit 2 and one line ``slippulse: error: ...`` naming the option or the file for bad input, no
traceback anywhere, no output left by a refused command. The kill rows kill a writer at a point
of its own progress (inside its second commit through ``SLIPPULSE_KILL_AT``, core/killpoint.py,
or once its file holds a first pulse), never after a wall-clock delay, then check the file and
rerun. The concurrency row runs two writers and a reader on one padded file.
"""
from __future__ import annotations

import argparse
import hashlib
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
    p = subprocess.run(_cmd(args), capture_output=True, text=True, timeout=timeout)
    text = p.stderr if stream == "stderr" else p.stdout
    lines = [ln for ln in text.strip().splitlines() if ln.strip()]
    left = bool(out) and os.path.exists(out)
    return {"rc": p.returncode, "last": lines[-1] if lines else "", "tb": "Traceback" in p.stderr,
            "left": left, "wall": time.time() - t0}


def _md5(path: str) -> str:
    with open(path, "rb") as fh:
        return hashlib.md5(fh.read()).hexdigest()


def _cmd(args):
    return [sys.executable, "-m", "slippulse", *args]


def _killed_at(args, point, check, out=None):
    """Run ``args`` with ``SLIPPULSE_KILL_AT=point`` (the writer kills itself there); the row
    holds the exit code and ``check(out)``."""
    env = dict(os.environ, SLIPPULSE_KILL_AT=point)
    p = subprocess.run(_cmd(args), env=env, capture_output=True, text=True, timeout=600)
    return {"rc": p.returncode, "last": check(out), "tb": "Traceback" in p.stderr, "left": None}


def _kill_when(args, ready, check, out, timeout=300):
    """Start ``args``, SIGKILL it as soon as ``ready(out)`` holds (its own progress: a first
    pulse or checkpoint in the file), return the row with ``check(out)``."""
    p = subprocess.Popen(_cmd(args), stdout=subprocess.DEVNULL, stderr=subprocess.PIPE,
                         text=True)
    t0 = time.time()
    while p.poll() is None and time.time() - t0 < timeout and not ready(out):
        time.sleep(0.05)
    alive = p.poll() is None
    if alive:
        p.send_signal(signal.SIGKILL)
    _, err = p.communicate()
    note = "" if alive else " [the command had ended before the kill]"
    return {"rc": p.returncode, "last": check(out) + note, "tb": "Traceback" in err,
            "left": None}


def _pulses(path):
    """Labels of a pulse file read through the validating reader, or the error."""
    from slippulse.core import h5io
    try:
        labels = h5io.list_pulses(path)
        for lab in labels:
            h5io.read_pulse(path, lab)
        return labels
    except (h5io.SchemaError, OSError) as exc:
        return str(exc)


def _has_pulses(n):
    def ready(path):
        if not os.path.exists(path):
            return False
        got = _pulses(path)
        return isinstance(got, list) and len(got) >= n
    return ready


def _invalid_files(d: str, steady: str) -> dict:
    """Copies of ``steady`` made invalid in the ways a reader must refuse."""
    out = {}

    def make(name, edit):
        path = os.path.join(d, f"inv_{name}.h5")
        shutil.copyfile(steady, path)
        with h5py.File(path, "r+") as h5:
            edit(h5, h5["pulses/td1.2000"])
        out[name] = path

    def relink(target):
        def edit(h5, grp):
            del h5["pulses/td1.2000"]
            h5["pulses"]["td1.2000"] = target
        return edit

    def setarr(name, fn):
        def edit(h5, grp):
            a = grp[name][...]
            del grp[name]
            grp.create_dataset(name, data=fn(a))
        return edit

    def setattr_(name, val):
        def edit(h5, grp):
            grp.attrs[name] = val
        return edit

    def two_points(h5, grp):
        for n in ("xi", "v", "phi", "tau", "residual"):
            a = grp[n][...]
            del grp[n]
            grp.create_dataset(n, data=a[:2])

    def relabel(h5, grp):
        grp.attrs["tau_d_ratio"] = 1.1
        grp.attrs["tau_d"] = 1.1 * grp.attrs["tau_min"]

    make("dangling_link", relink(h5py.SoftLink("/nowhere")))
    make("external_link", relink(h5py.ExternalLink("other.h5", "/pulses/td1.2000")))
    make("nan_v", setarr("v", lambda a: np.where(np.arange(a.size) == 7, np.nan, a)))
    make("inf_tau", setarr("tau", lambda a: np.where(np.arange(a.size) == 3, np.inf, a)))
    make("v_negative", setarr("v", lambda a: np.where(np.arange(a.size) == 5, -1e-9, a)))
    make("complex_v", setarr("v", lambda a: a + 1j * a))
    make("two_points", two_points)
    make("nan_L", setattr_("L", np.nan))
    make("negative_L", setattr_("L", -1.0))
    make("beta_1.5", setattr_("beta", 1.5))
    make("converged_text", setattr_("converged", "False"))
    make("label_vs_attr", relabel)
    return out


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


def option_rows(d: str, steady: str, rows: list, row) -> None:
    """Bounds on options: each refused before any work (exit 2, one line naming the option)."""
    out = os.path.join(d, "out.h5")
    cfg = os.path.join(d, "run.toml")
    run = ["dynamic", "run", cfg, "--no-progress", "--out", out]
    for what, extra in (("fft.threads=0", ["--set", "fft.threads=0"]),
                        ("fft.threads=-3", ["--set", "fft.threads=-3"]),
                        ("fft.planner=bogus", ["--set", "fft.planner='bogus'"]),
                        ("grid.length=1e300", ["--set", "grid.length=1e300"]),
                        ("history.soe_h=0", ["--set", "history.soe_h=0"]),
                        ("history.soe_x_min=-1", ["--set", "history.soe_x_min=-1"]),
                        ("grid.n=2**40", ["--set", "grid.n=1099511627776"])):
        row(f"run --set {what}", run + extra, out)
    big = os.path.join(d, "big_sigma.toml")
    with open(big, "w") as fh:
        fh.write("[params]\nsigma = 1e308\n")
    row("solve --params sigma=1e308", ["steady", "solve", "--params", big, "--out", out, "-q",
                                       "--no-figure"], out)
    row("solve --tol 1e10", ["steady", "solve", "--points", "500", "--tol", "1e10", "--out", out,
                             "-q", "--no-figure"], out)
    row("solve --tol -1", ["steady", "solve", "--points", "300", "--tol", "-1", "--out", out,
                           "-q", "--no-figure"], out)
    row("solve --tau-d 1e308", ["steady", "solve", "--tau-d", "1e308", "--out", out, "-q"], out)
    row("solve --tau-d abc", ["steady", "solve", "--tau-d", "abc", "--out", out], out)
    row("solve --points 10**9", ["steady", "solve", "--points", "1000000000", "--out", out, "-q"],
        out)
    row("family --from nan", ["steady", "family", "--from", "nan", "--out", out, "-q"], out)
    row("family --step 1e-300", ["steady", "family", "--step", "1e-300", "--out", out, "-q"], out)
    row("family --step inf", ["steady", "family", "--step", "inf", "--out", out, "-q"], out)
    verify = ["dynamic", "verify", "--steady", steady, "--out", out, "--no-progress"]
    for what, extra in (("--points 10**9", ["--points", "1000000000"]),
                        ("--dx 1e-9", ["--dx", "1e-9"]), ("--dx nan", ["--dx", "nan"]),
                        ("--samples 0", ["--samples", "0", "--distance", "0.01"]),
                        ("--distance inf", ["--distance", "inf"]),
                        ("--distance 1e9", ["--distance", "1e9"]),
                        ("--ahead -1", ["--ahead", "-1"])):
        row(f"verify {what}", verify + extra, out)
    row("seed --dx 1e9", ["dynamic", "seed", "--steady", steady, "--dx", "1e9", "--out", out], out)
    row("stability --figure s.xyz", ["steady", "stability", steady, "--figure",
                                     os.path.join(d, "s.xyz")], os.path.join(d, "s.xyz"))
    scan = os.path.join(d, "bad_case.toml")
    with open(scan, "w") as fh:
        fh.write(f'[scan]\nname = "b"\nout_dir = "{os.path.join(d, "scan_b")}"\n'
                 f'[defaults]\nsteady = "{steady}"\nlabel = "td1.2000"\n'
                 '[[case]]\neps = "abc"\n')
    row("scan: case eps = \"abc\"", ["dynamic", "scan", scan])
    as_file = os.path.join(d, "scan_out_is_a_file")
    open(as_file, "w").close()
    scan2 = os.path.join(d, "outdir_file.toml")
    with open(scan2, "w") as fh:
        fh.write(f'[scan]\nname = "f"\nout_dir = "{as_file}"\n'
                 f'[defaults]\nsteady = "{steady}"\nlabel = "td1.2000"\n'
                 '[[case]]\neps = 1e-3\n')
    row("scan: out_dir is a file", ["dynamic", "scan", scan2])
    dangling = os.path.join(d, "scan_dangling.h5")
    shutil.copyfile(steady, dangling)
    with h5py.File(dangling, "r+") as h5:
        del h5["pulses/td1.2000"]
        h5["pulses"]["td1.2000"] = h5py.SoftLink("/nowhere")
    scan3 = os.path.join(d, "dangling_steady.toml")
    with open(scan3, "w") as fh:
        fh.write(f'[scan]\nname = "g"\nout_dir = "{os.path.join(d, "scan_g")}"\n'
                 f'[defaults]\nsteady = "{dangling}"\nlabel = "td1.2000"\n'
                 '[[case]]\neps = 1e-3\n')
    row("scan: steady file with a dangling link", ["dynamic", "scan", scan3])
    for what, cmd in (("run: config not TOML", ["dynamic", "run", os.path.join(d, "bad.toml")]),
                      ("run: config binary", ["dynamic", "run", os.path.join(d, "binary.toml")]),
                      ("run: config missing", ["dynamic", "run", os.path.join(d, "nope.toml")]),
                      ("scan: file not TOML", ["dynamic", "scan", os.path.join(d, "bad.toml")]),
                      ("scan: missing file", ["dynamic", "scan", os.path.join(d, "nope.toml")])):
        row(what, cmd + (["--out", out, "--no-progress"] if cmd[1] == "run" else []), out)


def output_rows(d: str, steady: str, rows: list, row) -> None:
    """Outputs: an empty name, a directory, an input as output, unwritable places, a label
    already stored."""
    out = os.path.join(d, "out.h5")
    cfg = os.path.join(d, "run.toml")
    row("solve --out newdir/", ["steady", "solve", "--out", os.path.join(d, "newdir") + "/",
                                "-q", "--no-figure"], os.path.join(d, "newdir"))
    row("run --out \"\"", ["dynamic", "run", cfg, "--out", "", "--no-progress"],
        "dynamic_run.h5")
    row("run --out DIR", ["dynamic", "run", cfg, "--out", d, "--no-progress"])
    row("verify --out DIR", ["dynamic", "verify", "--steady", steady, "--out", d,
                             "--no-progress"])
    for cmd in ("seed", "verify"):
        copy = os.path.join(d, f"same_{cmd}.h5")
        shutil.copyfile(steady, copy)
        before = _md5(copy)
        row(f"{cmd} --steady X --out X --overwrite",
            ["dynamic", cmd, "--steady", copy, "--out", copy, "--overwrite"]
            + (["--no-progress"] if cmd == "verify" else []))
        rows[-1][2]["last"] += " [X unchanged]" if _md5(copy) == before else " [X CHANGED]"
    row("solve --out unwritable (/sys)", ["steady", "solve", "--out", "/sys/x.h5", "-q"])
    row("figures --outdir unwritable", ["figures", steady, "--outdir", "/sys/figs"])
    raw = _md5(steady)
    row("solve --tau-d 1.2 --out FILE holding td1.2000 (no --overwrite)",
        ["steady", "solve", "--tau-d", "1.2", "--points", "500", "--out", steady, "-q",
         "--no-figure"])
    rows[-1][2]["last"] += " [file bit-identical]" if _md5(steady) == raw else " [FILE CHANGED]"


def file_rows(d: str, steady: str, f: dict, rows: list, row) -> None:
    """Bad and invalid input files, through every command that reads them."""
    out = os.path.join(d, "out.h5")
    figs = os.path.join(d, "figs")
    bad = _unconverged_copy(steady, os.path.join(d, "unconverged.h5"))
    inv = _invalid_files(d, steady)

    def readers(kind, path):
        row(f"verify --steady {kind}", ["dynamic", "verify", "--steady", path, "--out", out,
                                        "--no-progress", "--distance", "0.01"], out)
        row(f"seed --steady {kind}", ["dynamic", "seed", "--steady", path, "--out", out], out)
        row(f"analyse {kind}", ["steady", "analyse", path])
        row(f"figures {kind}", ["figures", path, "--outdir", figs], figs)
        row(f"stability {kind}", ["steady", "stability", path, "--labels", "td1.2000"])

    for kind in ("text", "empty", "trunc", "foreign", "foreign_pulses", "missing"):
        readers(kind, f[kind])
        row(f"run --resume --out {kind}", ["dynamic", "run", os.path.join(d, "run.toml"),
                                           "--out", f[kind], "--resume", "--no-progress"])
    readers("unconverged", bad)
    for kind, path in inv.items():
        readers(kind, path)
    for kind in ("dangling_link", "external_link"):
        row(f"solve --out {kind}", ["steady", "solve", "--tau-d", "1.15", "--out", inv[kind],
                                    "-q", "--no-figure"])
        row(f"family --out {kind}", ["steady", "family", "--from", "1.2", "--to", "1.19",
                                     "--out", inv[kind], "-q"])
    row("analyse DIR", ["steady", "analyse", d])
    row("stability DIR", ["steady", "stability", d])
    row("stability on a missing file under /sys", ["steady", "stability", "/sys/x.h5"])
    row("steady solve --out over a text file", ["steady", "solve", "--points", "300", "--out",
                                                f["text"], "-q", "--no-figure"])
    row("steady solve --out in a missing directory",
        ["steady", "solve", "--points", "300", "--out", os.path.join(f["text"], "x.h5"), "-q",
         "--no-figure"])
    for label in ("td9.9999", "../x"):
        row(f"verify --label {label}", ["dynamic", "verify", "--steady", steady, "--label",
                                        label, "--out", out, "--no-progress"], out)
    # a file locked by another process: the reader waits, then names the file and the lock
    holder = subprocess.Popen([sys.executable, "-c",
                               "import sys, time, filelock\n"
                               "from slippulse.core.locking import lock_path\n"
                               f"with filelock.FileLock(lock_path({steady!r})):\n"
                               "    print('held', flush=True); time.sleep(20)\n"],
                              stdout=subprocess.PIPE, text=True)
    holder.stdout.readline()
    env = dict(os.environ, SLIPPULSE_LOCK_TIMEOUT="2")
    p = subprocess.run(_cmd(["steady", "analyse", steady, "--no-write"]), env=env,
                       capture_output=True, text=True)
    holder.kill()
    holder.wait()
    lines = [ln for ln in p.stderr.strip().splitlines() if ln.strip()]
    rows.append(("analyse a file another process holds locked (timeout 2 s)",
                 "SLIPPULSE_LOCK_TIMEOUT=2 slippulse steady analyse good.h5",
                 {"rc": p.returncode, "last": lines[-1] if lines else "",
                  "tb": "Traceback" in p.stderr, "left": None}))


def concurrency_rows(d: str, steady: str, rows: list) -> None:
    """Four writers (a family and three solves) and a reader (analyse, in a loop) on one file
    padded with 200 MB, so that the writes overlap."""
    from slippulse.core import h5io
    path = os.path.join(d, "shared.h5")
    first = ["steady", "family", "--from", "1.2", "--to", "1.19", "--out", path, "-q"]
    subprocess.run(_cmd(first), check=True, capture_output=True)   # a family continues its own
    h5io.atomic_update(path, lambda h5: h5.create_dataset("pad", data=np.zeros(25_000_000)))
    t0 = time.time()
    fam = subprocess.Popen(_cmd(["steady", "family", "--from", "1.2", "--to", "1.16", "--step",
                                 "0.01", "--out", path, "-q"]),
                           stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    solves = [subprocess.Popen(_cmd(["steady", "solve", "--tau-d", q, "--points", "500",
                                     "--out", path, "-q", "--no-figure"]),
                               stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
              for q in ("1.155", "1.145", "1.135")]
    analyses, bad = 0, []
    while fam.poll() is None or any(s.poll() is None for s in solves):
        p = subprocess.run(_cmd(["steady", "analyse", path]), capture_output=True, text=True)
        analyses += 1
        if p.returncode not in (0, 2) or "Traceback" in p.stderr:
            bad.append(p.stderr.strip()[-200:])
    errs = [q.communicate()[1] for q in [fam] + solves]
    got = _pulses(path)
    want = {"td1.2000", "td1.1900", "td1.1800", "td1.1700", "td1.1600", "td1.1550", "td1.1450",
            "td1.1350"}
    ok = isinstance(got, list) and want <= set(got)
    rows.append(("family + 3 solves + analyse loop on one 200 MB file",
                 "slippulse steady family --out shared.h5 & steady solve ... & steady analyse",
                 {"rc": max([fam.returncode] + [s.returncode for s in solves]),
                  "last": (f"all {len(want)} pulses present and valid, {analyses} analyses "
                           f"ran alongside, {time.time() - t0:.0f} s" if ok
                           else f"MISSING {sorted(want - set(got if isinstance(got, list) else []))}"
                           f" ({got})") + (f" [ANALYSE FAILED: {bad[:1]}]" if bad else ""),
                  "tb": any("Traceback" in e for e in errs), "left": None}))


def disk_rows(d: str, steady: str, rows: list) -> None:
    """A full disk (a tmpfs of a few MB; root only) and a read-only file."""
    cfg = os.path.join(d, "run.toml")
    ro = os.path.join(d, "ro.h5")
    subprocess.run(_cmd(["dynamic", "run", cfg, "--out", ro, "--no-progress"]),
                   capture_output=True)
    os.chmod(ro, 0o444)
    before = _md5(ro)
    p = subprocess.run(_cmd(["dynamic", "run", cfg, "--out", ro, "--resume", "--no-progress",
                             "--set", "time.max_steps=100"]), capture_output=True, text=True)
    left = [n for n in os.listdir(d) if n.startswith("ro.h5.")]
    rows.append(("run --resume on a read-only (0444) run file", "slippulse dynamic run run.toml "
                 "--out ro.h5 --resume", {
                     "rc": p.returncode, "last": (p.stderr.strip().splitlines() or [""])[-1]
                     + (" [file unchanged, mode 0444]" if _md5(ro) == before
                        and os.stat(ro).st_mode & 0o777 == 0o444 else " [FILE CHANGED]"),
                     "tb": "Traceback" in p.stderr, "left": bool(left)}))
    os.chmod(ro, 0o644)
    with open(ro + ".partial", "wb") as fh:            # a killed run's work file, read-only
        fh.write(b"stale")
    os.chmod(ro + ".partial", 0o444)
    p = subprocess.run(_cmd(["dynamic", "run", cfg, "--out", ro, "--resume", "--no-progress",
                             "--set", "time.max_steps=100"]), capture_output=True, text=True)
    rows.append(("run --resume beside a stale read-only FILE.partial", "slippulse dynamic run "
                 "run.toml --out ro.h5 --resume", {
                     "rc": p.returncode, "last": (p.stderr.strip().splitlines() or
                                                  p.stdout.strip().splitlines() or [""])[-1][:60]
                     + f"... [{_run_state(ro)}]", "tb": "Traceback" in p.stderr,
                     "left": os.path.exists(ro + ".partial")}))
    if os.geteuid() != 0:
        rows.append(("full disk (tmpfs)", "needs root to mount a tmpfs", {
            "rc": "–", "last": "skipped", "tb": False, "left": None}))
        return
    mnt = os.path.join(d, "tmpfs")
    os.makedirs(mnt)
    subprocess.run(["mount", "-t", "tmpfs", "-o", "size=3m", "tmpfs", mnt], check=True)
    try:
        big = ["--set", "grid.n=1024", "--set", "time.max_steps=4000", "--set",
               "output.snapshot_every=5", "--set", "output.checkpoint_every=100"]
        run_out = os.path.join(mnt, "run.h5")
        p = subprocess.run(_cmd(["dynamic", "run", cfg, "--out", run_out, "--no-progress"] + big),
                           capture_output=True, text=True)
        state = _run_state(run_out)
        rows.append(("dynamic run on a 3 MB tmpfs", "slippulse dynamic run run.toml --set "
                     "grid.n=1024 ... --out tmpfs/run.h5", {
                         "rc": p.returncode,
                         "last": (p.stderr.strip().splitlines() or [""])[-1][:120]
                         + f" [{state}]", "tb": "Traceback" in p.stderr,
                         "left": os.path.exists(run_out + ".partial")}))
        fam = os.path.join(mnt, "fam.h5")
        shutil.copyfile(steady, fam)
        with open(os.path.join(mnt, "fill"), "wb") as fh:
            try:
                fh.write(b"\0" * (8 << 20))
            except OSError:
                pass
        before = _md5(fam)
        for what, cmd, target in (
                ("solve into a file on a full disk", ["steady", "solve", "--tau-d", "1.15",
                                                      "--points", "300", "--out", fam, "-q",
                                                      "--no-figure"], fam),
                ("seed onto a full disk", ["dynamic", "seed", "--steady", steady, "--out",
                                           os.path.join(mnt, "seed.h5")],
                 os.path.join(mnt, "seed.h5")),
                ("verify onto a full disk", ["dynamic", "verify", "--steady", steady, "--out",
                                             os.path.join(mnt, "v.h5"), "--distance", "0.01",
                                             "--points", "200", "--no-progress"],
                 os.path.join(mnt, "v.h5"))):
            p = subprocess.run(_cmd(cmd), capture_output=True, text=True, timeout=900)
            extra = (" [file unchanged]" if _md5(fam) == before else " [FILE CHANGED]") \
                if target == fam else ""
            left = [n for n in os.listdir(mnt) if n.startswith((".tmp-", "v.", "seed."))]
            rows.append((what, "slippulse " + " ".join(os.path.relpath(c, d) if c.startswith(d)
                                                       else c for c in cmd), {
                "rc": p.returncode, "last": (p.stderr.strip().splitlines() or [""])[-1] + extra,
                "tb": "Traceback" in p.stderr, "left": bool(left) if target != fam else None}))
    finally:
        subprocess.run(["umount", mnt])


def _run_state(path):
    try:
        with h5py.File(path, "r") as h5:
            n = int(h5["checkpoint/nstep"][()])
            ok = len(h5["scalars/step"]) == n
        return (f"complete file at checkpoint step {n}" if ok else "INCONSISTENT")
    except (OSError, KeyError) as exc:
        return f"NOT READABLE: {exc}" if os.path.exists(path) else "no file yet"


def kill_rows(d: str, steady: str, rows: list) -> None:
    """Kills at points of the command's own progress, each followed by a check and a rerun."""
    kdir = os.path.join(d, "kill")
    os.makedirs(kdir)
    fam_args = ["steady", "family", "--from", "1.2", "--to", "1.18", "--step", "0.01", "-q"]

    def family_after(path):
        got = _pulses(path)
        if not isinstance(got, list):
            return f"NOT VALID: {got}"
        p = subprocess.run(_cmd(fam_args + ["--out", path]), capture_output=True, text=True)
        final = _pulses(path)
        n = len(final) if isinstance(final, list) else final
        return (f"{len(got)} valid pulse(s) after the kill; the rerun (rc {p.returncode}) "
                f"completes: {n} of 3")

    for point in ("journal_torn:2", "journal_written:2", "file_half_written:2"):
        path = os.path.join(kdir, f"family_{point.split(':')[0]}.h5")
        rows.append((f"kill family inside its 2nd commit ({point})",
                     f"SLIPPULSE_KILL_AT={point} slippulse steady family ...",
                     _killed_at(fam_args + ["--out", path], point, family_after, path)))
    path = os.path.join(kdir, "family_sigkill.h5")
    rows.append(("SIGKILL family once its file holds a pulse",
                 "slippulse steady family ... (kill -9 when pulses >= 1)",
                 _kill_when(fam_args + ["--out", path], _has_pulses(1), family_after, path)))

    def no_output(path):
        left = [n for n in os.listdir(os.path.dirname(path)) if n.startswith(".tmp-")]
        return ("no output" + (f"; temporary left (removed by the next writer): {left}"
                               if left else ", no temporary file")
                if not os.path.exists(path) else "OUTPUT LEFT")

    path = os.path.join(kdir, "verify.h5")
    rows.append(("kill verify just before its output replaces the target",
                 "SLIPPULSE_KILL_AT=replacement_written slippulse dynamic verify ...",
                 _killed_at(["dynamic", "verify", "--steady", steady, "--out", path,
                             "--distance", "0.01", "--points", "200", "--no-progress"],
                            "replacement_written:1", no_output, path)))
    cfg = os.path.join(d, "run.toml")
    run_args = ["dynamic", "run", cfg, "--set", "time.max_steps=200", "--set",
                "output.checkpoint_every=7", "--no-progress"]

    def run_after(path):
        state = _run_state(path)
        p = subprocess.run(_cmd(run_args + ["--out", path, "--resume"]), capture_output=True,
                           text=True)
        return f"{state}; resume rc {p.returncode}: {_run_state(path)}"

    for point in ("state_written:2", "published:2", "rows_caught_up:2"):
        path = os.path.join(kdir, f"run_{point.split(':')[0]}.h5")
        rows.append((f"kill dynamic run at its 2nd checkpoint ({point})",
                     f"SLIPPULSE_KILL_AT={point} slippulse dynamic run ...",
                     _killed_at(run_args + ["--out", path], point, run_after, path)))


def interrupt_rows(d: str, rows: list) -> None:
    """Ctrl-C of a dynamic run and of a scan."""
    cfg = os.path.join(d, "run.toml")
    run_out = os.path.join(d, "int.h5")
    rc, err = _sigint(["dynamic", "run", cfg, "--set", "time.max_steps=1000000", "--set",
                       "time.t_end=1e6", "--set", "output.checkpoint_every=7", "--out", run_out,
                       "--no-progress"], 15.0)
    try:
        with h5py.File(run_out, "r") as h5:
            status = str(h5.attrs["status"])
    except (OSError, KeyError) as exc:
        status = f"NOT READABLE ({exc})"
    rows.append(("Ctrl-C dynamic run", "slippulse dynamic run run.toml --set time.t_end=1e6 ... "
                 "(SIGINT to the group)",
                 {"rc": rc, "last": f"status {status!r}", "tb": "Traceback" in err,
                  "left": None}))
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
    rows.append(("Ctrl-C dynamic scan (2 workers)",
                 "slippulse dynamic scan slow_scan.toml --workers 2 (SIGINT to the group)",
                 {"rc": rc, "last": (err.strip().splitlines() or [""])[-1]
                  + (f" [NOISE: {noise}]" if noise else " [no other output]"),
                  "tb": "Traceback" in err, "left": None}))


GROUPS = ("options", "outputs", "files", "concurrency", "disk", "kills", "interrupts")


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--dir", default=os.path.join("runs", "probe"))
    ap.add_argument("--only", nargs="+", choices=GROUPS, default=list(GROUPS),
                    help="run only these groups of rows")
    args = ap.parse_args(argv)
    d = os.path.abspath(args.dir)
    shutil.rmtree(d, ignore_errors=True)
    os.makedirs(d)
    steady = os.path.join(d, "good.h5")
    subprocess.run(_cmd(["steady", "solve", "--tau-d", "1.2", "--points", "500", "--out", steady,
                         "-q", "--no-figure"]), check=True, capture_output=True)
    f = _files(d, steady)
    rows = []

    def row(what, cmd, output=None, stream="stderr", timeout=600):
        if output and os.path.exists(output):
            if os.path.isdir(output):
                shutil.rmtree(output)
            else:
                os.remove(output)
        r = _run(cmd, output, stream=stream, timeout=timeout)
        rows.append((what, "slippulse " + " ".join(os.path.relpath(c, d) if c.startswith(d) else c
                                                  for c in cmd), r))

    groups = {"options": lambda: option_rows(d, steady, rows, row),
              "outputs": lambda: output_rows(d, steady, rows, row),
              "files": lambda: file_rows(d, steady, f, rows, row),
              "concurrency": lambda: concurrency_rows(d, steady, rows),
              "disk": lambda: disk_rows(d, steady, rows),
              "kills": lambda: kill_rows(d, steady, rows),
              "interrupts": lambda: interrupt_rows(d, rows)}
    for name in GROUPS:
        if name in args.only:
            groups[name]()
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
