"""Bad input and crashes (issue 12, item 5; table in docs/robustness.md): every command fed a
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
