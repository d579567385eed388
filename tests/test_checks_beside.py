"""Grid checks beside the march (steady/continuation/beside.py): the same pulses as inline checks,
the march going back where a check refines the grid, and no worker left behind by a killed run."""
import multiprocessing
import os
import signal
import subprocess
import sys
import time

import pytest

from slippulse.core.h5io import list_pulses, read_pulse
from slippulse.steady.continuation import FamilyRun, run_family
from slippulse.steady.continuation.tolerance import GridTolerance


def _deep_run(params, out, checks, monkeypatch):
    import slippulse.steady.continuation.family as fam
    monkeypatch.setattr(fam, "DEEP_BETA", 0.0)          # the deep march from the first pulse
    # a tolerance the N = 500 deep grids miss: every deep check refines its pulse
    run = FamilyRun(start=1.2, stop=1.15, step=0.01, n_points=500, deep_points=500, n_max=4000,
                    tolerance=GridTolerance(1e-5, 3e-5), max_length=1.5, checks=checks)
    return run_family(params, out, run)


def test_checks_beside_write_the_pulses_of_inline_checks_and_go_back_where_they_refine(
        params, tmp_path, monkeypatch):
    inline, beside = str(tmp_path / "inline.h5"), str(tmp_path / "beside.h5")
    r_in = _deep_run(params, inline, "inline", monkeypatch)
    r_be = _deep_run(params, beside, "beside", monkeypatch)
    assert not multiprocessing.active_children()            # the worker is stopped
    labels = list_pulses(inline)
    assert list_pulses(beside) == labels and len(labels) >= 3
    refined = 0
    for lab in labels:
        a, b = read_pulse(inline, lab)[0], read_pulse(beside, lab)[0]
        assert b.extra["grid_check_passed"] and b.n_points == a.n_points
        assert b.beta == pytest.approx(a.beta, rel=1e-12, abs=0)
        assert b.L == pytest.approx(a.L, rel=1e-12, abs=0)
        refined += b.extra["grid_check_body_levels"] > 0 and b.extra["continuation"] == "arclength"
    assert refined >= 1                 # a check replaced its pulse: the march went back to it
    assert r_be.written == r_in.written and r_be.checks == r_in.checks
    assert r_be.deep_steps > r_in.deep_steps       # the step taken ahead of it was dropped


def test_checks_beside_refused_without_checks(params, tmp_path):
    from slippulse.core.params import ParameterError
    with pytest.raises(ParameterError, match="checks="):
        run_family(params, str(tmp_path / "x.h5"), FamilyRun(check=False, checks="beside"))
    with pytest.raises(ParameterError, match="checks='aside'"):
        run_family(params, str(tmp_path / "x.h5"), FamilyRun(checks="aside"))
    assert not os.path.exists(tmp_path / "x.h5")


def _children(pid):
    out = []
    for d in os.listdir("/proc"):
        if d.isdigit():
            try:
                with open(f"/proc/{d}/stat") as f:
                    if int(f.read().rsplit(")", 1)[1].split()[1]) == pid:
                        out.append(int(d))
            except (OSError, IndexError, ValueError):
                pass
    return out


@pytest.mark.skipif(not os.path.isdir("/proc"), reason="reads /proc")
def test_a_killed_family_run_leaves_no_checker_behind(tmp_path):
    """kill -9 of the family command while its checker process runs: the checker exits too."""
    out = str(tmp_path / "f.h5")
    err = tmp_path / "family.err"
    with open(err, "wb") as fh:
        proc = subprocess.Popen([sys.executable, "-m", "slippulse.cli", "steady", "family",
                                 "--from", "1.2", "--to", "1.15", "--checks", "beside", "--out",
                                 out, "-q"], stdout=subprocess.DEVNULL, stderr=fh)
    t0, kids = time.time(), []
    while time.time() - t0 < 120 and not kids and proc.poll() is None:
        time.sleep(0.2)
        kids = _children(proc.pid)
    assert kids, f"no checker process started (exit {proc.poll()}): {err.read_text()[-2000:]}"
    proc.send_signal(signal.SIGKILL)
    proc.wait()
    t0 = time.time()
    while time.time() - t0 < 10 and any(os.path.exists(f"/proc/{k}") for k in kids):
        time.sleep(0.2)
    alive = [k for k in kids if os.path.exists(f"/proc/{k}")
             and open(f"/proc/{k}/stat").read().rsplit(")", 1)[1].split()[0] != "Z"]
    assert not alive


def test_the_command_checks_beside_only_where_two_cpus_are_free():
    """`steady family --checks` defaults to beside with two or more usable CPUs and to inline on
    one (a second process on one core only adds its start and hand-overs): the rule, and the
    default a process pinned to one CPU gets."""
    from slippulse.cli.steady import default_checks
    assert default_checks(1) == "inline" and default_checks(2) == default_checks(16) == "beside"
    if not hasattr(os, "sched_setaffinity"):
        pytest.skip("no CPU affinity on this system")
    code = ("import os; os.sched_setaffinity(0, {min(os.sched_getaffinity(0))}); "
            "from slippulse.cli.steady import DEFAULT_CHECKS; print(DEFAULT_CHECKS)")
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True)
    assert out.stdout.strip() == "inline"
