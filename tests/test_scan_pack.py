"""``slippulse dynamic pack`` (timedomain.scan.pack_scan): a scan directory packed small to carry
off a lent machine."""
import tarfile

import h5py
import numpy as np

from cli_inproc import run as cli


def _scan_dir(d):
    d.mkdir()
    with h5py.File(d / "case_a.h5", "w") as h5:
        h5.attrs["tau_d_ratio"] = 1.05
        h5.create_group("series")["L"] = np.arange(5.0)
        g = h5.create_group("snapshots")
        g.attrs["every"] = 10
        g["t"] = np.arange(3.0)
        g["x_front"] = np.arange(3.0) * 2
        g["v"] = np.ones((3, 1000))
    with h5py.File(d / "summary.h5", "w") as h5:
        h5.create_group("snapshots")["v"] = np.ones(4)        # a summary goes as it is
    (d / "summary.csv").write_text("case,s\na,1\n")
    (d / "pairs.png").write_bytes(b"png")
    return d


def test_pack_keeps_the_cases_without_their_slip_rate_snapshots(tmp_path):
    d = _scan_dir(tmp_path / "scan_x")
    out = tmp_path / "x.tar.gz"
    r = cli(["dynamic", "pack", d, out])
    assert r.returncode == 0, r.stderr
    with tarfile.open(out) as tar:
        names = sorted(tar.getnames())
        assert names == ["scan_x/case_a.h5", "scan_x/summary.csv", "scan_x/summary.h5"]
        tar.extractall(tmp_path / "x")
    with h5py.File(tmp_path / "x" / "scan_x" / "case_a.h5") as h5:
        assert h5.attrs["tau_d_ratio"] == 1.05 and h5["snapshots"].attrs["every"] == 10
        assert list(h5["snapshots"]) == ["t", "x_front"]
        assert np.array_equal(h5["snapshots/x_front"][...], [0.0, 2.0, 4.0])
        assert np.array_equal(h5["series/L"][...], np.arange(5.0))
    with h5py.File(tmp_path / "x" / "scan_x" / "summary.h5") as h5:
        assert "v" in h5["snapshots"]
    assert not list(tmp_path.glob("*.part"))


def test_pack_refuses_a_missing_directory_with_one_line(tmp_path):
    out = tmp_path / "x.tar.gz"
    r = cli(["dynamic", "pack", tmp_path / "none", out])
    assert r.returncode == 2 and len(r.stderr.strip().splitlines()) == 1 and "SCAN_DIR" in r.stderr
    assert not out.exists() and not list(tmp_path.glob("*.part"))
