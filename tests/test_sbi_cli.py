"""`slippulse dynamic run`: configs that refuse typos, HDF5 output, bit-exact --resume, kill safety."""
import os
import signal
import subprocess
import sys
import time

import h5py
import numpy as np
import pytest

from slippulse.cli.app import UsageError, main
from slippulse.dynamics.config import DEFAULTS, build_stepper, load_config, parse_set
from slippulse.core.params import ParameterError

CONFIG = """
[grid]
n = 64
length = 0.5
[load]
tau_d_ratio = 1.2
[initial]
kind = "gaussian"
amplitude = 1e-3
width = 0.02
position = 0.25
[time]
stepping = "adaptive"
t_end = 1e6
max_steps = 240
[history]
policy = "{policy}"
[output]
snapshot_every = 25
checkpoint_every = 40
"""


def _write(tmp_path, policy="soe", name="run.toml"):
    path = tmp_path / name
    path.write_text(CONFIG.format(policy=policy))
    return str(path)


def _datasets(path):
    out = {}
    with h5py.File(path, "r") as f:
        def visit(name, obj):
            if isinstance(obj, h5py.Dataset):
                out[name] = obj[()]
        f.visititems(visit)
        out["_status"] = f.attrs["status"]
    return out


def test_config_precedence_and_typos(tmp_path):
    cfg = load_config(_write(tmp_path), ["grid.n=128", "history.policy=window"])
    assert cfg["grid"]["n"] == 128 and cfg["history"]["policy"] == "window"
    assert cfg["grid"]["length"] == 0.5                        # from the file
    assert cfg["fft"]["threads"] == DEFAULTS["fft"]["threads"]  # default
    with pytest.raises(UsageError, match="unknown config key grid.nn"):
        load_config(None, ["grid.nn=3"])
    with pytest.raises(UsageError, match="unknown config section"):
        load_config(None, ["gird.n=3"])
    with pytest.raises(UsageError, match="wrong type"):
        load_config(None, ["grid.n=1.5"])
    bad = tmp_path / "bad.toml"
    bad.write_text("[time]\nt_ned = 1.0\n")
    with pytest.raises(UsageError, match="t_ned"):
        load_config(str(bad))
    assert parse_set("time.t_end=2e-3") == {"time": {"t_end": 2e-3}}


def test_cli_bad_input_exits_2(tmp_path):
    cfg = _write(tmp_path)
    assert main(["dynamic", "run", cfg, "--set", "grid.n=7", "--no-progress",
                 "--out", str(tmp_path / "x.h5")]) == 2
    with pytest.raises(ParameterError, match="grid.n"):
        build_stepper(load_config(cfg, ["grid.n=7"]))
    assert main(["dynamic", "run", cfg, "--set", "load.tau_d_ratio=0.9", "--no-progress",
                 "--out", str(tmp_path / "x.h5")]) == 2


def test_help_everywhere():
    for argv in (["dynamic", "--help"], ["dynamic", "run", "--help"]):
        with pytest.raises(SystemExit) as exc:
            main(argv)
        assert exc.value.code == 0


@pytest.mark.parametrize("policy", ["soe", "window", "full"])
def test_output_file_and_bit_exact_resume(tmp_path, policy):
    cfg = _write(tmp_path, policy)
    full, part = str(tmp_path / "full.h5"), str(tmp_path / "part.h5")
    if policy != "soe":         # fixed steps for the fixed-Δt policies
        extra = ["--set", 'time.stepping="fixed"']
    else:
        extra = []
    assert main(["dynamic", "run", cfg, "--out", full, "--no-progress", *extra]) == 0
    # interrupted run: stop at 100 steps (checkpoint there), then resume to the end
    assert main(["dynamic", "run", cfg, "--out", part, "--no-progress", *extra,
                 "--set", "time.max_steps=100"]) == 0
    assert _datasets(part)["_status"] == "stopped"
    assert main(["dynamic", "run", cfg, "--out", part, "--no-progress", *extra,
                 "--set", "time.max_steps=240", "--resume"]) == 0
    a, b = _datasets(full), _datasets(part)
    assert set(a) == set(b)
    for key in a:
        assert np.array_equal(a[key], b[key]), key             # to the last bit
    assert not os.path.exists(part + ".partial")
    # self-describing content
    with h5py.File(full, "r") as f:
        assert f.attrs["slippulse_version"] and f.attrs["created"]
        assert f["parameters"].attrs["units_mu"] == "Pa"
        assert f["config"].attrs["grid.n"] == 64
        assert f["snapshots/V"].shape == (len(f["snapshots/t"]), 64)
        assert f["snapshots/V"].maxshape == (None, 64)
        assert f["scalars/step"][-1] == 240 and len(f["scalars/step"]) == 240
        assert np.all(np.diff(f["scalars/t"][()]) > 0)
        assert f["snapshots/step"][0] == 0


def test_fixed_dt_policy_refuses_adaptive_steps(tmp_path):
    cfg = _write(tmp_path, "full")
    assert main(["dynamic", "run", cfg, "--out", str(tmp_path / "f.h5"), "--no-progress"]) == 2
    with pytest.raises(ParameterError, match="soe"):
        build_stepper(load_config(cfg))


def test_existing_output_is_not_overwritten_by_default(tmp_path):
    cfg = _write(tmp_path)
    out = str(tmp_path / "o.h5")
    args = ["dynamic", "run", cfg, "--out", out, "--no-progress", "--set", "time.max_steps=5"]
    assert main(args) == 0
    before = _datasets(out)
    assert main(args) == 2                                     # refused, file untouched
    after = _datasets(out)
    assert all(np.array_equal(before[k], after[k]) for k in before)
    assert main(args + ["--overwrite"]) == 0


def test_resume_refuses_changed_physics(tmp_path):
    cfg = _write(tmp_path)
    out = str(tmp_path / "r.h5")
    assert main(["dynamic", "run", cfg, "--out", out, "--no-progress",
                 "--set", "time.max_steps=20"]) == 0
    assert main(["dynamic", "run", cfg, "--out", out, "--no-progress", "--resume",
                 "--set", "grid.length=0.6"]) == 2


def test_killed_run_leaves_readable_file_and_resumes_bit_exact(tmp_path):
    cfg = _write(tmp_path)
    ref, killed = str(tmp_path / "ref.h5"), str(tmp_path / "killed.h5")
    long = ["--set", "time.max_steps=3000", "--set", "output.checkpoint_every=200"]
    assert main(["dynamic", "run", cfg, "--out", ref, "--no-progress", *long]) == 0
    proc = subprocess.Popen([sys.executable, "-m", "slippulse.cli", "dynamic", "run", cfg,
                             "--out", killed, "--no-progress", *long],
                            stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
    try:
        t0 = time.time()
        while time.time() - t0 < 60 and proc.poll() is None:   # wait for a checkpoint > 0
            time.sleep(0.05)
            if os.path.exists(killed):
                try:
                    with h5py.File(killed, "r") as f:
                        if f["checkpoint/nstep"][()] >= 200:
                            break
                except (OSError, KeyError):
                    pass
        time.sleep(0.1)
    finally:
        proc.send_signal(signal.SIGKILL)
        proc.wait()
    with h5py.File(killed, "r") as f:                         # never corrupt
        n_ck = int(f["checkpoint/nstep"][()])
        assert f.attrs["status"] == "running"
        assert len(f["scalars/step"]) == n_ck
    if n_ck == 3000:
        pytest.skip("the run finished before it could be killed")
    assert main(["dynamic", "run", cfg, "--out", killed, "--no-progress", "--resume", *long]) == 0
    a, b = _datasets(ref), _datasets(killed)
    for key in a:
        assert np.array_equal(a[key], b[key]), key
