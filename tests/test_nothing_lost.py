"""Nothing lost (no pulse overwritten without --overwrite, a failed solve never replaces a
converged pulse), nothing silently wrong (every reader refuses a pulse marked converged=False),
and the probes of the issue: each a one-line error naming the option (exit 2) or a correct
result."""
import os
import stat
import subprocess
import sys

import h5py
import numpy as np
import pytest

from slippulse.cli.app import main
from slippulse.core import h5io
from slippulse.core.params import DEFAULT as P

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
from test_analysis import _synthetic_pulse  # noqa: E402


def _one_error(capsys, *names):
    err = [ln for ln in capsys.readouterr().err.strip().splitlines() if ln.strip()]
    assert len(err) == 1 and err[0].startswith("slippulse: error: "), err
    for name in names:
        assert name in err[0], (name, err[0])
    return err[0]


@pytest.fixture(scope="module")
def real(tmp_path_factory):
    """A solved pulse at 1.2 (N = 500), converged, and the same pulse marked converged=False
    beside a converged one in a second file."""
    from slippulse.steady.solver import solve_pulse
    d = tmp_path_factory.mktemp("real")
    pulse = solve_pulse(P, 1.2, n_points=500).to_pulse()
    assert pulse.converged
    good = str(d / "good.h5")
    h5io.write_pulse(good, pulse, P)
    bad = str(d / "bad.h5")
    h5io.write_pulse(bad, _synthetic_pulse(1.1, 0.1, 0.1), P)
    pulse.converged = False
    h5io.write_pulse(bad, pulse, P)
    return {"good": good, "bad": bad, "dir": d}


# ------------------------------------------------------------------ no overwritten pulse

class _FakeSolution:
    def __init__(self, pulse, message):
        self._pulse = pulse
        self.stats = type("S", (), {"message": message, "converged": pulse.converged})()

    def to_pulse(self):
        return self._pulse


def _fake_solve(monkeypatch, converged, beta=0.2):
    import slippulse.cli.steady as cs
    p = _synthetic_pulse(1.2, beta, 0.1)
    p.converged = converged
    monkeypatch.setattr(cs, "solve_any",
                        lambda params, ratio, args: (_FakeSolution(p, "fake solve"), "fake"))
    return p


def test_solve_refuses_an_existing_label_without_overwrite(tmp_path, capsys, monkeypatch):
    out = str(tmp_path / "fam.h5")
    h5io.write_pulse(out, _synthetic_pulse(1.2, 0.1, 0.1), P)
    raw = open(out, "rb").read()
    _fake_solve(monkeypatch, True)
    rc = main(["steady", "solve", "--tau-d", "1.2", "--out", out, "--no-figure", "-q"])
    assert rc == 2
    _one_error(capsys, "td1.2000", "--overwrite", out)
    assert open(out, "rb").read() == raw                       # bit-identical
    # with --overwrite the converged solve replaces it
    assert main(["steady", "solve", "--tau-d", "1.2", "--out", out, "--no-figure", "-q",
                 "--overwrite"]) == 0
    assert h5io.read_pulse(out, "td1.2000")[0].beta == pytest.approx(0.2)


def test_failed_solve_never_replaces_a_converged_pulse(tmp_path, capsys, monkeypatch):
    out = str(tmp_path / "fam.h5")
    h5io.write_pulse(out, _synthetic_pulse(1.2, 0.1, 0.1), P)
    raw = open(out, "rb").read()
    _fake_solve(monkeypatch, False)
    rc = main(["steady", "solve", "--tau-d", "1.2", "--out", out, "--no-figure", "-q",
               "--overwrite"])
    assert rc == 1
    err = capsys.readouterr().err
    assert "did not converge" in err and "kept" in err and "td1.2000" in err
    assert open(out, "rb").read() == raw


def test_write_pulse_guards_labels(tmp_path):
    out = str(tmp_path / "f.h5")
    h5io.write_pulse(out, _synthetic_pulse(1.1, 0.1, 0.1), P)
    raw = open(out, "rb").read()
    with pytest.raises(h5io.PulseExistsError, match="already present"):
        h5io.write_pulse(out, _synthetic_pulse(1.1, 0.2, 0.1), P, overwrite=False)
    failed = _synthetic_pulse(1.1, 0.2, 0.1)
    failed.converged = False
    with pytest.raises(h5io.PulseExistsError, match="never replaces"):
        h5io.write_pulse(out, failed, P, overwrite=True)
    assert open(out, "rb").read() == raw
    # an unconverged pulse may be replaced, by anything
    other = str(tmp_path / "g.h5")
    h5io.write_pulse(other, failed, P)
    h5io.write_pulse(other, _synthetic_pulse(1.1, 0.3, 0.1), P)
    assert h5io.read_pulse(other)[0].converged


def test_write_pulses_writes_all_or_none(tmp_path):
    out = str(tmp_path / "f.h5")
    h5io.write_pulse(out, _synthetic_pulse(1.1, 0.1, 0.1), P)
    raw = open(out, "rb").read()
    failed = _synthetic_pulse(1.1, 0.2, 0.1)
    failed.converged = False
    # the first is new, the second may not replace the converged pulse: neither is written
    with pytest.raises(h5io.PulseExistsError, match="never replaces"):
        h5io.write_pulses(out, [_synthetic_pulse(1.2, 0.1, 0.1), failed], P)
    assert open(out, "rb").read() == raw
    h5io.write_pulses(out, [_synthetic_pulse(1.2, 0.1, 0.1), _synthetic_pulse(1.15, 0.1, 0.1)],
                      P, replace=True)
    assert sorted(h5io.list_pulses(out)) == ["td1.1500", "td1.2000"]
    assert sorted(os.listdir(tmp_path)) == [".f.h5.lock", "f.h5"]


# ------------------------------------------------------------------ unconverged refused

def test_every_reader_refuses_an_unconverged_pulse(real, tmp_path, capsys):
    bad = real["bad"]
    out = str(tmp_path / "o.h5")
    cmds = [
        ["dynamic", "seed", "--steady", bad, "--label", "td1.2000", "--out", out],
        ["dynamic", "verify", "--steady", bad, "--label", "td1.2000", "--out", out,
         "--no-progress", "--distance", "0.01"],
        ["steady", "analyse", bad],
        ["figures", bad, "--outdir", str(tmp_path / "figs")],
        ["steady", "stability", bad, "--labels", "td1.2000"],
    ]
    raw = open(bad, "rb").read()
    for argv in cmds:
        assert main(argv) == 2, argv
        _one_error(capsys, "td1.2000", "converged=False")
        assert not os.path.exists(out) and not os.path.exists(tmp_path / "figs")
    assert open(bad, "rb").read() == raw


def test_scan_runner_refuses_an_unconverged_pulse(real):
    from slippulse.timedomain.perturbation import run_perturbation
    with pytest.raises(h5io.UnconvergedPulseError, match="td1.2000"):
        run_perturbation({"steady": real["bad"], "label": "td1.2000", "distance": 0.01})


def test_allow_unconverged_marks_the_seed(real, tmp_path, capsys):
    out = str(tmp_path / "seed.h5")
    assert main(["dynamic", "seed", "--steady", real["bad"], "--label", "td1.2000", "--out", out,
                 "--dx", "0.02", "--allow-unconverged"]) == 0
    with h5py.File(out, "r") as h5:
        assert not bool(h5.attrs["steady_converged"])
    good = str(tmp_path / "seed_good.h5")
    assert main(["dynamic", "seed", "--steady", real["good"], "--out", good, "--dx", "0.02"]) == 0
    with h5py.File(good, "r") as h5:
        assert bool(h5.attrs["steady_converged"])


def test_analyse_skip_unconverged_names_them(real, tmp_path, capsys):
    path = str(tmp_path / "fam.h5")
    with open(real["bad"], "rb") as src, open(path, "wb") as dst:
        dst.write(src.read())
    assert main(["steady", "analyse", path, "--skip-unconverged"]) == 0
    with h5py.File(path, "r") as h5:
        assert h5["family"].attrs["skipped_unconverged"] == "td1.2000"
        assert "td1.2000" not in [s.decode() for s in h5["family/label"][...]]
        assert list(h5["family/label"].asstr()[...]) == ["td1.1000"]


# ------------------------------------------------------------------ the probes

def test_probes_one_line_errors(real, tmp_path, capsys):
    good = real["good"]
    cfg = tmp_path / "run.toml"
    cfg.write_text("[grid]\nn = 64\nlength = 0.5\n[time]\nmax_steps = 5\n")
    out = str(tmp_path / "o.h5")
    cases = [
        (["dynamic", "run", str(cfg), "--set", "fft.threads=0", "--out", out], "fft.threads"),
        (["dynamic", "run", str(cfg), "--set", "fft.threads=-3", "--out", out], "fft.threads"),
        (["dynamic", "run", str(cfg), "--set", "fft.planner='bogus'", "--out", out],
         "fft.planner"),
        (["dynamic", "run", str(cfg), "--out", str(tmp_path)], "is a directory"),
        (["steady", "stability", good, "--figure", str(tmp_path / "s.xyz")], "--figure"),
        (["steady", "family", "--step", "1e-300", "--out", out], "step=1e-300"),
        (["steady", "family", "--step", "inf", "--out", out], "step=inf"),
        (["dynamic", "verify", "--steady", good, "--distance", "inf", "--out", out,
          "--no-progress"], "--distance=inf"),
        (["dynamic", "verify", "--steady", good, "--distance", "1e9", "--out", out,
          "--no-progress"], "--distance=1000000000.0"),
        (["dynamic", "verify", "--steady", good, "--xi-stab", "nan", "--out", out,
          "--no-progress"], "--xi-stab"),
        (["dynamic", "seed", "--steady", good, "--dx", "1e9", "--out", out], "--dx=1e+09"),
        (["steady", "solve", "--tau-d", "1.01", "--out", out], "tau-d=1.01"),
        (["steady", "solve", "--tau-d", "1.33", "--out", out], "tau-d=1.33"),
        (["steady", "solve", "--out", "/sys/x.h5"], "/sys/x.h5"),
        (["dynamic", "seed", "--steady", good, "--out", "/sys/x.h5"], "/sys/x.h5"),
        (["figures", good, "--outdir", "/sys/figs"], "--outdir"),
    ]
    for argv, name in cases:
        assert main(argv) == 2, argv
        _one_error(capsys, name)
        assert not os.path.exists(out), argv


def test_outputs_get_the_usual_mode(tmp_path):
    old = os.umask(0o022)
    try:
        path = str(tmp_path / "f.h5")
        h5io.write_pulse(path, _synthetic_pulse(1.1, 0.1, 0.1), P)
        assert stat.S_IMODE(os.stat(path).st_mode) == 0o644
        os.chmod(path, 0o640)                            # an existing file keeps its mode
        h5io.write_pulse(path, _synthetic_pulse(1.05, 0.1, 0.1), P)
        assert stat.S_IMODE(os.stat(path).st_mode) == 0o640
    finally:
        os.umask(old)


def test_interrupted_run_records_its_status(tmp_path, monkeypatch, capsys):
    from slippulse.dynamics.runfile import RunFile
    cfg = tmp_path / "run.toml"
    cfg.write_text("[grid]\nn = 64\nlength = 0.5\n[time]\nmax_steps = 50\n"
                   "[output]\ncheckpoint_every = 5\n")
    out = str(tmp_path / "run.h5")
    real_record = RunFile.record_step

    def record(self, st):
        real_record(self, st)
        if st.nstep == 12:
            raise KeyboardInterrupt

    monkeypatch.setattr(RunFile, "record_step", record)
    assert main(["dynamic", "run", str(cfg), "--out", out, "--no-progress"]) == 130
    with h5py.File(out, "r") as h5:
        assert h5.attrs["status"] == "interrupted"
        assert int(h5["checkpoint/nstep"][()]) == 10
    monkeypatch.setattr(RunFile, "record_step", real_record)
    assert main(["dynamic", "run", str(cfg), "--out", out, "--no-progress", "--resume"]) == 0
    with h5py.File(out, "r") as h5:
        assert h5.attrs["status"] == "stopped"


def test_ctrl_c_is_taken_at_a_step_boundary(tmp_path, monkeypatch):
    """A real SIGINT in the middle of a step's bookkeeping does not tear it: the step finishes,
    the loop stops before the next one, the file is marked 'interrupted' at its last checkpoint,
    and SIGINT has the handler it had before the run again (the default one, or SIG_IGN where
    the tests run in the background under nohup)."""
    import signal
    from slippulse.dynamics.runfile import RunFile
    cfg = tmp_path / "run.toml"
    cfg.write_text("[grid]\nn = 64\nlength = 0.5\n[time]\nmax_steps = 50\n"
                   "[output]\ncheckpoint_every = 5\n")
    out = str(tmp_path / "run.h5")
    real_record = RunFile.record_step
    seen = []

    def record(self, st):
        if st.nstep == 12:
            os.kill(os.getpid(), signal.SIGINT)
            seen.append("after the signal")     # a KeyboardInterrupt here would skip this
        real_record(self, st)
        seen.append(st.nstep)

    monkeypatch.setattr(RunFile, "record_step", record)
    before = signal.getsignal(signal.SIGINT)     # default_int_handler, or SIG_IGN under nohup
    assert main(["dynamic", "run", str(cfg), "--out", out, "--no-progress"]) == 130
    assert seen[-2:] == ["after the signal", 12]        # step 12 recorded whole, no step 13
    assert signal.getsignal(signal.SIGINT) is before    # the handler of before the run again
    with h5py.File(out, "r") as h5:
        assert h5.attrs["status"] == "interrupted"
        assert int(h5["checkpoint/nstep"][()]) == 10


# ------------------------------------------------------------------ version and entry points

def test_version_and_python_dash_m():
    for cmd in (["slippulse", "--version"], [sys.executable, "-m", "slippulse", "--version"]):
        p = subprocess.run(cmd, capture_output=True, text=True)
        assert p.returncode == 0 and p.stdout.strip().startswith("slippulse 0."), (cmd, p)


def test_perturbation_scan_refuses_an_unconverged_pulse_before_running(real, tmp_path, capsys):
    toml = tmp_path / "s.toml"
    toml.write_text(f"""[scan]
name = "u"
out_dir = "{tmp_path / 'out'}"
[defaults]
steady = "{real['bad']}"
label = "td1.2000"
[grid]
eps = [1e-3, -1e-3]
""")
    assert main(["dynamic", "scan", str(toml), "--no-progress"]) == 2
    _one_error(capsys, "td1.2000", "converged=False")
    assert not os.path.exists(tmp_path / "out") or not os.listdir(tmp_path / "out")
