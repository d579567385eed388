"""`slippulse dynamic scan`: TOML parsing and case expansion, the executor (this process, a local
Dask cluster, a scheduler's),
resume without rerunning finished cases, error rows, summary files, CLI.

The runner is tests/scan_fake_runner.py (sleeps 0.1 s, logs each call to case["log"]); workers
import it through scan.runner_path.
"""
import csv
import json
import math
import os

import h5py
import pytest

from slippulse.cli.app import UsageError, main
from slippulse.timedomain.scan import (Case, case_id, expand_cases, load_scan, parse_scan, read_summary_h5,
                            run_scan, scan_states)

TESTS = os.path.dirname(os.path.abspath(__file__))
RUNNER = "scan_fake_runner:run_case"


def _write_scan(tmp_path, grid='eps = [1e-3, -1e-3, 1e-2, -1e-2]', extra="", name="scan.toml",
                defaults=""):
    log = tmp_path / "calls.log"
    text = f"""
[scan]
name = "demo"
out_dir = "{tmp_path / 'out'}"
runner = "{RUNNER}"
runner_path = ["{TESTS}"]
[defaults]
log = "{log}"
dx = 4e-3
{defaults}
[grid]
label = ["td1.0500"]
{grid}
{extra}
"""
    path = tmp_path / name
    path.write_text(text)
    return str(path), log


def _calls(log):
    return log.read_text().splitlines() if log.exists() else []


def _csv(path):
    with open(path, newline="") as fh:
        return list(csv.DictReader(fh))


# --------------------------------------------------------------------------- parsing


def test_expand_cartesian_explicit_and_ids(tmp_path):
    cases = expand_cases({"dx": 4e-3, "steady": "runs/f.h5"},
                         {"label": ["td1.05", "td1.10"], "eps": [1e-3, -1e-3, 1e-2]},
                         [{"label": "td1.2", "eps": 1e-3}, {"dx": 2e-3}])
    assert len(cases) == 2 * 3 + 2
    # product in TOML order, the last key fastest, merged over defaults
    assert [(c.params["label"], c.params["eps"]) for c in cases[:4]] == [
        ("td1.05", 1e-3), ("td1.05", -1e-3), ("td1.05", 1e-2), ("td1.10", 1e-3)]
    assert all(c.params["steady"] == "runs/f.h5" for c in cases)
    assert cases[6].params == {"dx": 4e-3, "steady": "runs/f.h5", "label": "td1.2", "eps": 1e-3}
    assert cases[7].params["dx"] == 2e-3 and "eps" not in cases[7].params
    ids = [c.id for c in cases]
    assert len(set(ids)) == len(ids)
    assert ids[1].startswith("label=td1.05_eps=-0.001_") and len(ids[1].split("_")[-1]) == 8
    assert ids[7].startswith("dx=0.002_")
    assert all(set(i) <= set("abcdefghijklmnopqrstuvwxyzABCDEFGHIJKLMNOPQRSTUVWXYZ0123456789._=+-")
               for i in ids)
    # deterministic, and an id depends on its case only (adding cases renames nothing)
    again = expand_cases({"dx": 4e-3, "steady": "runs/f.h5"},
                         {"label": ["td1.05", "td1.10"], "eps": [1e-3, -1e-3, 1e-2]})
    assert [c.id for c in again] == ids[:6]
    # a changed default changes every hash
    other = expand_cases({"dx": 5e-3, "steady": "runs/f.h5"}, {"label": ["td1.05"], "eps": [1e-3]})
    assert other[0].id != ids[0] and other[0].id.split("_")[:-1] == ids[0].split("_")[:-1]
    # file-name sanitising
    assert case_id({"steady": "runs/a b.h5"}, ["steady"]).startswith("steady=runs-a-b.h5_")


def test_load_scan_file(tmp_path, monkeypatch):
    path, _ = _write_scan(tmp_path, extra='[[case]]\nlabel = "td1.1000"\neps = 1e-3\n')
    scan = load_scan(path)
    assert scan.name == "demo" and scan.runner == RUNNER and scan.runner_path == (TESTS,)
    assert len(scan.cases) == 5 and scan.cases[-1].params["label"] == "td1.1000"
    assert scan.out_file(scan.cases[0]) == os.path.join(str(tmp_path / "out"),
                                                        scan.cases[0].id + ".h5")
    assert "eps = [1e-3" in scan.toml_text
    # relative out_dir is relative to the current directory; runner defaults to stability
    monkeypatch.chdir(tmp_path)
    s = parse_scan({"scan": {"name": "x", "out_dir": "rel"}, "grid": {"a": [1, 2]}})
    assert s.out_dir == str(tmp_path / "rel") and s.runner == "slippulse.timedomain.perturbation:run_case"


@pytest.mark.parametrize("data, words", [
    ({"scan": {"out_dir": "o"}, "grid": {"a": [1]}}, ["scan.name", "required"]),
    ({"scan": {"name": "n"}, "grid": {"a": [1]}}, ["scan.out_dir"]),
    ({"grid": {"a": [1]}}, ["[scan]"]),
    ({"scan": {"name": "n", "out_dir": "o"}, "grids": {"a": [1]}}, ["'grids'", "[grid]",
                                                                      "[[case]]"]),
    ({"scan": {"name": "n", "out_dir": "o", "runners": "x"}, "grid": {"a": [1]}},
     ["scan.runners", "runner"]),
    ({"scan": {"name": "n", "out_dir": "o", "runner": "nocolon"}, "grid": {"a": [1]}},
     ["scan.runner", "module:function"]),
    ({"scan": {"name": "n", "out_dir": "o"}, "defaults": {"x": [1, 2]}, "grid": {"a": [1]}},
     ["defaults.x", "scalar"]),
    ({"scan": {"name": "n", "out_dir": "o"}, "grid": {"a": [1, {"b": 2}]}}, ["grid.a[1]",
                                                                           "scalar"]),
    ({"scan": {"name": "n", "out_dir": "o"}, "grid": {"a": 3}}, ["grid.a", "list"]),
    ({"scan": {"name": "n", "out_dir": "o"}, "grid": {"a": []}}, ["grid.a", "non-empty"]),
    ({"scan": {"name": "n", "out_dir": "o"}, "case": [{"a": {"b": 1}}]}, ["case[0].a", "scalar"]),
    ({"scan": {"name": "n", "out_dir": "o"}, "case": {"a": 1}}, ["[[case]]"]),
    ({"scan": {"name": "n", "out_dir": "o"}, "defaults": {"a": 1}}, ["no cases"]),
    ({"scan": {"name": "n", "out_dir": "o"}, "grid": {}}, ["no cases"]),
    ({"scan": {"name": "n", "out_dir": "o"}, "grid": {"a": [1, 1]}}, ["identical"]),
    ({"scan": {"name": "n", "out_dir": "o"}, "grid": {"id": [1]}}, ["grid.id", "reserved"]),
    ({"scan": {"name": "n", "out_dir": "o"}, "grid": {"a": [math.nan]}}, ["grid.a[0]", "finite"]),
])
def test_bad_scans(data, words):
    with pytest.raises(UsageError) as err:
        parse_scan(data, origin="s.toml")
    msg = str(err.value)
    assert "\n" not in msg and msg.startswith("s.toml: ")
    for w in words:
        assert w in msg, (w, msg)


def test_load_scan_missing_and_invalid(tmp_path):
    with pytest.raises(UsageError, match="not found"):
        load_scan(str(tmp_path / "nope.toml"))
    bad = tmp_path / "bad.toml"
    bad.write_text("[scan\nname=")
    with pytest.raises(UsageError, match="invalid TOML"):
        load_scan(str(bad))


# --------------------------------------------------------------------------- execution


def _check_summary(scan, rows_csv, rows_h5):
    assert [r["id"] for r in rows_csv] == [c.id for c in scan.cases]
    assert [r["id"] for r in rows_h5] == [c.id for c in scan.cases]
    for c, rc, rh in zip(scan.cases, rows_csv, rows_h5):
        eps = c.params["eps"]
        assert rc["status"] == "ok" and rh["status"] == "ok"
        assert float(rc["eps"]) == eps and rh["eps"] == eps and rh["label"] == "td1.0500"
        assert float(rc["growth"]) == pytest.approx(10 * eps) and rh["growth"] == pytest.approx(
            10 * eps)
        assert rh["fate"] == ("grows" if eps > 0 else "decays") == rc["fate"]
        assert rh["stable"] is (eps <= 0) and rh["n_steps"] == int(1000 * abs(eps)) + 1


def test_dask_scan_runs_and_resumes(tmp_path):
    distributed = pytest.importorskip("distributed")
    path, log = _write_scan(tmp_path)
    scan = load_scan(path)

    def cluster():
        return distributed.LocalCluster(n_workers=2, threads_per_worker=1, processes=True,
                                        dashboard_address=None)

    with cluster() as lc, distributed.Client(lc) as client:
        res = run_scan(scan, executor=client, progress=False)
    assert (res.n_run, res.n_reused, res.n_errors) == (4, 0, 0) and res.ok
    calls = _calls(log)
    assert sorted(float(c.split()[1]) for c in calls) == sorted(c.params["eps"] for c in scan.cases)
    assert len({c.split()[0] for c in calls}) <= 2          # ran in the cluster's worker processes
    assert str(os.getpid()) not in {c.split()[0] for c in calls}
    for c in scan.cases:
        with h5py.File(scan.out_file(c), "r") as h5:
            assert h5.attrs["complete"] and json.loads(h5.attrs["case_json"]) == c.params
    out = tmp_path / "out"
    rows_csv, rows_h5 = _csv(out / "summary.csv"), read_summary_h5(str(out / "summary.h5"))
    _check_summary(scan, rows_csv, rows_h5)
    with h5py.File(out / "summary.h5", "r") as h5:
        assert h5.attrs["scan_name"] == "demo" and h5.attrs["runner"] == RUNNER
        assert h5.attrs["scan_toml"] == scan.toml_text
        assert h5["growth"].dtype.kind == "f" and h5["fate"].dtype.kind == "O"
    assert res.figures == [str(out / "figure.txt")] and len(
        (out / "figure.txt").read_text().splitlines()) == 4
    csv_text = (out / "summary.csv").read_text()

    # a new cluster: nothing reruns, the same summary
    with cluster() as lc, distributed.Client(lc) as client:
        res2 = run_scan(load_scan(path), executor=client, progress=False)
        assert (res2.n_run, res2.n_reused) == (0, 4) and len(_calls(log)) == 4
        assert (out / "summary.csv").read_text() == csv_text
        assert read_summary_h5(str(out / "summary.h5")) == rows_h5

        # one output deleted, another truncated (corrupt): exactly those two rerun
        os.remove(scan.out_file(scan.cases[1]))
        with open(scan.out_file(scan.cases[2]), "r+b") as fh:
            fh.truncate(100)
        assert scan_states(scan) == ["done", "missing", "incomplete", "done"]
        # through the CLI, by scheduler address (the CLI connects its own Client)
        assert main(["dynamic", "scan", path, "--scheduler", lc.scheduler_address,
                     "--no-progress"]) == 0
    new = [float(c.split()[1]) for c in _calls(log)[4:]]
    assert sorted(new) == sorted([scan.cases[1].params["eps"], scan.cases[2].params["eps"]])
    assert (out / "summary.csv").read_text() == csv_text


def test_local_processes_and_error_rows(tmp_path, capsys):
    """A local Dask cluster of two processes; a failing case gives an error row, the others
    finish, exit 1."""
    path, log = _write_scan(tmp_path, grid="eps = [1e-3, -1e-3]",
                            extra='[[case]]\nlabel = "td1.1000"\neps = 5e-3\nfail = true\n')
    scan = load_scan(path)
    rc = main(["dynamic", "scan", path, "--workers", "2", "--no-progress"])
    assert rc == 1
    err = capsys.readouterr().err
    assert "RuntimeError: case with eps=0.005 asked to fail" in err
    assert "scan demo: 3 cases, 3 run, 0 reused, 1 errors" in err
    rows = _csv(tmp_path / "out" / "summary.csv")
    assert [r["id"] for r in rows] == [c.id for c in scan.cases]
    assert [r["status"] for r in rows[:2]] == ["ok", "ok"]
    assert rows[2]["status"] == "error: RuntimeError: case with eps=0.005 asked to fail"
    assert rows[2]["growth"] == "" and rows[2]["fail"] == "True" and rows[0]["fail"] == ""
    assert float(rows[0]["growth"]) == pytest.approx(1e-2)
    assert not os.path.exists(scan.out_file(scan.cases[2]))
    pids = {c.split()[0] for c in _calls(log)}
    assert len(_calls(log)) == 3 and str(os.getpid()) not in pids
    h5rows = read_summary_h5(str(tmp_path / "out" / "summary.h5"))
    assert math.isnan(h5rows[2]["growth"]) and h5rows[2]["status"].startswith("error: Runtime")

    # rerun: only the failed case is retried (and fails again)
    res = run_scan(scan, progress=False)
    assert (res.n_run, res.n_reused, res.n_errors) == (1, 2, 1) and not res.ok
    assert len(_calls(log)) == 4 and _calls(log)[-1].endswith("0.005")


def test_file_of_another_case(tmp_path, monkeypatch):
    monkeypatch.syspath_prepend(TESTS)
    path, log = _write_scan(tmp_path, grid="eps = [1e-3]", defaults="sleep = 0.0")
    scan = load_scan(path)
    other = tmp_path / "other.h5"
    import scan_fake_runner
    os.makedirs(scan.out_dir)
    scan_fake_runner.run_case({"eps": 9.0}, str(other))
    os.replace(other, scan.out_file(scan.cases[0]))
    assert scan_states(scan) == ["other"]
    with pytest.raises(UsageError, match=f"{scan.cases[0].id}.h5 holds another case.*--overwrite"):
        run_scan(scan, progress=False)
    assert _calls(log) == []
    res = run_scan(scan, overwrite=True, progress=False)
    assert res.n_run == 1 and res.ok and scan_states(scan) == ["done"]


# --------------------------------------------------------------------------- CLI


def test_cli_help_dry_run_and_errors(tmp_path, capsys):
    with pytest.raises(SystemExit) as ex:
        main(["dynamic", "scan", "--help"])
    assert ex.value.code == 0
    out = capsys.readouterr().out
    assert "--scheduler" in out and "--workers" in out and "--dry-run" in out

    path, log = _write_scan(tmp_path, grid="eps = [1e-3, -1e-3]")
    scan = load_scan(path)
    assert main(["dynamic", "scan", path, "--dry-run"]) == 0
    out = capsys.readouterr().out.splitlines()
    assert out[0].startswith("scan demo: 2 cases, runner scan_fake_runner:run_case")
    assert [line.split()[0] for line in out[1:3]] == [c.id for c in scan.cases]
    assert all(" todo " in line and line.endswith(".h5") for line in out[1:3])
    assert out[3] == "0 done, 2 to run" and _calls(log) == []

    assert main(["dynamic", "scan", str(tmp_path / "missing.toml")]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and err.startswith("slippulse: error: scan file ")
    assert "missing.toml not found" in err

    bad = tmp_path / "bad.toml"
    bad.write_text('[scan]\nname = "x"\nout_dir = "o"\n[grid]\neps = [[1]]\n')
    assert main(["dynamic", "scan", str(bad)]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "grid.eps[0]" in err and "scalar" in err

    assert main(["dynamic", "scan", path, "--workers", "0"]) == 2
    assert "--workers=0" in capsys.readouterr().err


def test_example_scan_parses():
    root = os.path.dirname(TESTS)
    scan = load_scan(os.path.join(root, "dynamic", "scans", "example.toml"))
    assert scan.runner == "slippulse.timedomain.perturbation:run_case" and len(scan.cases) >= 4
    assert all(isinstance(c, Case) for c in scan.cases)


def test_sigterm_stops_the_workers(tmp_path):
    """Killing `slippulse dynamic scan --workers 2` (SIGTERM) stops its local cluster's worker
    processes too: none keeps running its case and no output file of an unfinished case
    appears."""
    import signal
    import subprocess
    import sys
    import time
    log = tmp_path / "calls.log"
    toml = tmp_path / "slow.toml"
    toml.write_text(f"""
[scan]
name = "slow"
out_dir = "{tmp_path / 'out'}"
runner = "scan_fake_runner:run_case"
runner_path = ["{os.path.dirname(os.path.abspath(__file__))}"]
[defaults]
sleep = 30.0
log = "{log}"
[grid]
eps = [1e-3, -1e-3, 2e-3]
""")
    # Output goes to files, not pipes nobody reads: a full pipe would block the scan before
    # it starts its workers.
    err_path = tmp_path / "scan.err"
    with open(tmp_path / "scan.out", "wb") as out, open(err_path, "wb") as err:
        proc = subprocess.Popen([sys.executable, "-m", "slippulse.cli", "dynamic", "scan",
                                 str(toml), "--workers", "2", "--no-progress"],
                                stdout=out, stderr=err)
    deadline = time.time() + 180
    while time.time() < deadline and proc.poll() is None and not _children(proc.pid):
        time.sleep(0.2)
    kids = _children(proc.pid)
    assert kids, (f"the scan started no worker (exit {proc.poll()}): "
                  f"{err_path.read_text()[-2000:]}")
    time.sleep(1.0)
    proc.send_signal(signal.SIGTERM)
    proc.wait(timeout=30)
    assert proc.returncode != 0
    time.sleep(0.5)
    alive = [k for k in kids if _alive(k)]
    assert not alive, f"workers still running after SIGTERM: {alive}"
    assert not list((tmp_path / "out").glob("*.h5"))


def _children(pid):
    try:
        out = subprocess_check(["ps", "-o", "pid=", "--ppid", str(pid)])
    except Exception:
        return []
    return [int(x) for x in out.split() if x.strip()]


def _alive(pid):
    try:
        with open(f"/proc/{pid}/stat") as fh:
            return fh.read().split()[2] != "Z"
    except OSError:
        return False


def subprocess_check(cmd):
    import subprocess
    return subprocess.run(cmd, capture_output=True, text=True).stdout


def test_dry_run_names_a_bad_perturbation_case(tmp_path, capsys):
    """A dry run of a perturbation scan checks every case's keys and values (not its files,
    which need not exist yet): a bad case is named in one line, exit 2, instead of "todo"."""
    root = os.path.dirname(TESTS)
    good = os.path.join(root, "dynamic", "scans", "example.toml")
    assert main(["dynamic", "scan", good, "--dry-run"]) == 0       # its steady file is absent
    capsys.readouterr()
    text = open(good).read().replace("dx = 4e-3", "dx = -4e-3")
    bad = tmp_path / "bad.toml"
    bad.write_text(text)
    assert main(["dynamic", "scan", str(bad), "--dry-run"]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "case " in err and "dx=-0.004" in err and "> 0" in err
    bad.write_text(text.replace("dx = -4e-3", "dx = 4e-3\ndxx = 1"))
    assert main(["dynamic", "scan", str(bad), "--dry-run"]) == 2
    assert "unknown case key(s) ['dxx']" in capsys.readouterr().err
