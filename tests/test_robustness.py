"""Bad input and crashes (table in docs/robustness.md): every command fed a
file that is not HDF5, empty, truncated, foreign or missing, a bad label or a huge size exits with
code 2 and one line ``slippulse: error: ...`` naming the parameter or file, and leaves no output."""
import os
import subprocess
import sys

import h5py
import numpy as np
import pytest

from slippulse.core import h5io
from slippulse.cli.app import main
from slippulse.core.params import DEFAULT as P

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
from test_analysis import _synthetic_pulse  # noqa: E402


@pytest.fixture(scope="module")
def bad(tmp_path_factory):
    d = tmp_path_factory.mktemp("bad")
    good = str(d / "good.h5")
    h5io.write_pulse(good, _synthetic_pulse(1.1, 0.1, 0.1), P)
    f = {"good": good}
    (d / "text.h5").write_text("not an HDF5 file\n")
    (d / "empty.h5").write_bytes(b"")
    raw = open(good, "rb").read()
    (d / "trunc.h5").write_bytes(raw[: len(raw) // 3])
    with h5py.File(d / "foreign.h5", "w") as h5:
        h5.create_dataset("a", data=np.arange(3))
    with h5py.File(d / "foreign_pulses.h5", "w") as h5:
        h5.create_group("pulses").create_group("hello")
    newer = d / "newer.h5"
    newer.write_bytes(raw)
    with h5py.File(newer, "a") as h5:
        h5.attrs["format_version"] = 99
    for k in ("text", "empty", "trunc", "foreign", "foreign_pulses", "newer"):
        f[k] = str(d / f"{k}.h5")
    f["missing"] = str(d / "missing.h5")
    f["dir"] = str(d)
    return f


def _one_error(capsys, *names):
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and err[0].startswith("slippulse: error: "), err
    for name in names:
        assert name in err[0], (name, err[0])
    return err[0]


KINDS = ("text", "empty", "trunc", "foreign", "foreign_pulses", "missing", "newer")


@pytest.mark.parametrize("kind", KINDS)
def test_bad_steady_file_everywhere(bad, kind, capsys, tmp_path):
    out = str(tmp_path / "out.h5")
    name = os.path.basename(bad[kind])
    for argv in (["dynamic", "verify", "--steady", bad[kind], "--out", out, "--no-progress"],
                 ["dynamic", "seed", "--steady", bad[kind], "--out", out],
                 ["steady", "analyse", bad[kind]],
                 ["figures", bad[kind], "--outdir", str(tmp_path / "figs")]):
        assert main(argv) == 2, argv
        line = _one_error(capsys, name)
        if kind == "newer":
            assert "format_version 99" in line
    assert sorted(os.listdir(tmp_path)) == []             # no output of any kind


def test_bad_labels(bad, capsys, tmp_path):
    out = str(tmp_path / "out.h5")
    for label in ("td9.9999", "../x", ""):
        assert main(["dynamic", "verify", "--steady", bad["good"], "--label", label, "--out",
                     out, "--no-progress"]) == 2
        _one_error(capsys, "good.h5", f"label={label!r}")
    assert not os.path.exists(out)


@pytest.mark.parametrize("argv, names", [
    (["--points", "1000000000"], ["points=1000000000", "16000"]),
    (["--dx", "1e-9"], ["--dx=1e-09", "grid points"]),
    (["--dx", "nan"], ["--dx=nan"]),
    (["--dx", "inf"], ["--dx=inf"]),
    (["--samples", "0"], ["--samples=0"]),
    (["--ahead", "-1"], ["--ahead=-1"]),
])
def test_verify_sizes_refused_before_running(bad, argv, names, capsys, tmp_path):
    out = str(tmp_path / "out.h5")
    argv = ["dynamic", "verify", "--steady", bad["good"], "--out", out, "--no-progress", *argv]
    if argv[-2] == "--points":
        names = ["--points=1000000000"]
    assert main(argv) == 2
    _one_error(capsys, *names)
    assert sorted(os.listdir(tmp_path)) == []


def test_steady_solve_refuses_before_solving(bad, capsys, tmp_path):
    text_before = open(bad["text"], "rb").read()
    for argv, names in (
            (["--out", bad["text"]], ["out=", "text.h5"]),
            (["--out", os.path.join(bad["text"], "x.h5")], ["text.h5", "not a directory"]),
            (["--out", bad["newer"]], ["format_version 99"]),
            (["--points", "1000000000"], ["points=1000000000", "16000"]),
            (["--tol", "-1"], ["tol=-1"]),
            (["--tol", "nan"], ["tol=nan"])):
        out = [] if "--out" in argv else ["--out", str(tmp_path / "s.h5")]
        assert main(["steady", "solve", "-q", "--no-figure", *argv, *out]) == 2, argv
        _one_error(capsys, *names)
    assert open(bad["text"], "rb").read() == text_before
    assert sorted(os.listdir(tmp_path)) == []


def test_atomic_update_refuses_non_hdf5_target(bad):
    with pytest.raises(h5io.SchemaError, match="text.h5"):
        h5io.write_pulse(bad["text"], _synthetic_pulse(1.05, 0.3, 0.2), P)
    assert open(bad["text"]).read() == "not an HDF5 file\n"
    assert not [n for n in os.listdir(bad["dir"]) if n.startswith(".tmp-")]


def test_dynamic_run_bad_config_and_sizes(bad, capsys, tmp_path):
    out = str(tmp_path / "o.h5")
    binary = tmp_path / "binary.toml"
    binary.write_bytes(bytes(range(256)))
    assert main(["dynamic", "run", str(binary), "--out", out, "--no-progress"]) == 2
    _one_error(capsys, "binary.toml", "not valid TOML")
    cfg = tmp_path / "run.toml"
    cfg.write_text("[grid]\nn = 64\n")
    assert main(["dynamic", "run", str(cfg), "--set", "grid.n=1099511627776", "--out", out,
                 "--no-progress"]) == 2
    _one_error(capsys, "grid.n=1099511627776")
    for kind in ("text", "empty", "trunc", "foreign", "missing"):
        assert main(["dynamic", "run", str(cfg), "--out", bad[kind], "--resume",
                     "--no-progress"]) == 2
        _one_error(capsys, os.path.basename(bad[kind]))
    assert sorted(os.listdir(tmp_path)) == ["binary.toml", "run.toml"]


def test_python_dash_m_reports_usage_errors(bad):
    """``python -m slippulse.cli`` must catch the sub-commands' UsageError (one class)."""
    p = subprocess.run([sys.executable, "-m", "slippulse.cli", "figures", bad["missing"]],
                       capture_output=True, text=True, timeout=120)
    assert p.returncode == 2
    assert p.stderr.strip().startswith("slippulse: error: FILE=") and "Traceback" not in p.stderr


RUN_CFG = "[grid]\nn = 64\nlength = 0.5\n[time]\nmax_steps = 5\n"


@pytest.mark.parametrize("item, names", [
    ("grid.length=1e300", ["grid.length", "L0"]),
    ("grid.n=1099511627776", ["grid.n", "even integer"]),
    ("history.soe_h=0", ["history.soe_h", "(0, 2]"]),
    ("history.soe_x_min=-1", ["soe_x_min"]),
    ("history.soe_h=1e-9", ["nodes"]),
])
def test_dynamic_run_ranges_refused_before_work(tmp_path, capsys, item, names):
    cfg = tmp_path / "run.toml"
    cfg.write_text(RUN_CFG)
    out = tmp_path / "r.h5"
    assert main(["dynamic", "run", str(cfg), "--out", str(out), "--no-progress",
                 "--set", item]) == 2
    _one_error(capsys, *names)
    assert sorted(os.listdir(tmp_path)) == ["run.toml"]


@pytest.mark.parametrize("out, names", [("", ["--out=''", "empty"]),
                                        ("sub/", ["ends in a path separator"])])
def test_outputs_that_name_no_file_are_refused(bad, tmp_path, capsys, out, names):
    cfg = tmp_path / "run.toml"
    cfg.write_text(RUN_CFG)
    assert main(["dynamic", "run", str(cfg), "--out", out, "--no-progress"]) == 2
    _one_error(capsys, *names)
    assert main(["dynamic", "seed", "--steady", bad["good"], "--out", out]) == 2
    _one_error(capsys, *names)
    assert not os.path.exists("dynamic_run.h5") and not os.path.exists("sub")


@pytest.mark.parametrize("cmd", ["seed", "verify"])
def test_an_output_equal_to_its_input_is_refused(bad, tmp_path, capsys, cmd):
    same = str(tmp_path / "same.h5")
    open(same, "wb").write(open(bad["good"], "rb").read())
    raw = open(same, "rb").read()
    argv = ["dynamic", cmd, "--steady", same, "--out", same, "--overwrite"]
    assert main(argv + (["--no-progress"] if cmd == "verify" else [])) == 2
    _one_error(capsys, "--steady", same)
    assert open(same, "rb").read() == raw


def test_a_directory_given_as_a_file_is_named(bad, capsys):
    assert main(["steady", "analyse", bad["dir"]]) == 2
    _one_error(capsys, "is a directory")


def test_parameters_the_solver_cannot_represent_are_refused(tmp_path, capsys):
    params = tmp_path / "p.toml"
    params.write_text("[params]\nsigma = 1e308\n")
    out = tmp_path / "o.h5"
    assert main(["steady", "solve", "--params", str(params), "--out", str(out), "-q",
                 "--no-figure"]) == 2
    _one_error(capsys, "sigma=1e+308", "steady solver")
    assert not out.exists()


def test_tol_outside_its_range_is_refused(tmp_path, capsys):
    for tol in ("1e10", "1e-3", "0", "1e-20"):
        assert main(["steady", "solve", "--tol", tol, "--out", str(tmp_path / "o.h5"), "-q",
                     "--no-figure"]) == 2
        _one_error(capsys, "--tol", "1e-16")


def test_scan_case_values_and_out_dir_checked_before_work(bad, tmp_path, capsys):
    toml = tmp_path / "s.toml"
    toml.write_text(f'[scan]\nname = "s"\nout_dir = "{tmp_path / "o"}"\n[defaults]\n'
                    f'steady = "{bad["good"]}"\nlabel = "td1.1000"\n[[case]]\neps = "abc"\n')
    assert main(["dynamic", "scan", str(toml)]) == 2
    _one_error(capsys, "eps", "'abc'")
    as_file = tmp_path / "file"
    as_file.write_text("")
    toml.write_text(f'[scan]\nname = "s"\nout_dir = "{as_file}"\n[defaults]\n'
                    f'steady = "{bad["good"]}"\nlabel = "td1.1000"\n[[case]]\neps = 1e-3\n')
    assert main(["dynamic", "scan", str(toml)]) == 2
    _one_error(capsys, "is a file, not a directory")


def _tmpfs(path, size):
    """Mount a tmpfs of ``size`` at ``path`` (root only; the test is skipped otherwise)."""
    if os.geteuid() != 0:
        pytest.skip("mounting a tmpfs needs root")
    os.makedirs(path)
    if subprocess.run(["mount", "-t", "tmpfs", "-o", f"size={size}", "tmpfs", path],
                      capture_output=True).returncode:
        pytest.skip("cannot mount a tmpfs here")


def test_a_full_disk_stops_a_run_cleanly_and_keeps_its_last_checkpoint(tmp_path):
    """On a 3 MB tmpfs the run fills the disk: one line naming the file, exit 2, no segfault
    (HDF5 never sees the failed write), FILE complete at its last checkpoint, no work file."""
    mnt = str(tmp_path / "mnt")
    _tmpfs(mnt, "3m")
    try:
        cfg = tmp_path / "run.toml"
        cfg.write_text("[grid]\nn = 1024\nlength = 0.5\n[time]\nmax_steps = 4000\n"
                       "[output]\nsnapshot_every = 5\ncheckpoint_every = 100\n")
        out = os.path.join(mnt, "r.h5")
        p = subprocess.run([sys.executable, "-m", "slippulse", "dynamic", "run", str(cfg),
                            "--out", out, "--no-progress"], capture_output=True, text=True,
                           timeout=600)
        lines = [ln for ln in p.stderr.splitlines() if ln.strip()]
        assert p.returncode == 2 and len(lines) == 1, p.stderr[-2000:]
        assert "No space left on device" in lines[0] and out in lines[0]
        assert not os.path.exists(out + ".partial")
        with h5py.File(out, "r") as h5:
            n = int(h5["checkpoint/nstep"][()])
            assert h5["scalars/step"].shape[0] == n and n % 100 == 0
    finally:
        subprocess.run(["umount", mnt])


def test_a_full_disk_leaves_a_pulse_file_unchanged(bad, tmp_path, capsys):
    mnt = str(tmp_path / "mnt")
    _tmpfs(mnt, "1m")
    try:
        fam = os.path.join(mnt, "fam.h5")
        open(fam, "wb").write(open(bad["good"], "rb").read())
        with open(os.path.join(mnt, "fill"), "wb") as fh:
            try:
                fh.write(b"\0" * (2 << 20))
            except OSError:
                pass
        raw = open(fam, "rb").read()
        with pytest.raises(OSError) as exc:
            h5io.write_pulse(fam, _synthetic_pulse(1.05, 0.3, 0.2), P)
        assert exc.value.filename == fam
        assert open(fam, "rb").read() == raw
        assert sorted(os.listdir(mnt)) == [".fam.h5.lock", "fam.h5", "fill"]
    finally:
        subprocess.run(["umount", mnt])
