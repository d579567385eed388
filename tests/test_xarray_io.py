"""Every kind of output file opens with xarray (engine h5netcdf) with named dimensions, coordinates
and units; version-1 layouts stay readable; newer versions are refused."""
import os
import sys

import h5py
import numpy as np
import pytest

xr = pytest.importorskip("xarray")
pytest.importorskip("h5netcdf")

from slippulse.steady import analysis as an  # noqa: E402
from slippulse.core import h5io  # noqa: E402
from slippulse.cli.app import main  # noqa: E402
from slippulse.core.params import DEFAULT as P  # noqa: E402

TESTS = os.path.dirname(os.path.abspath(__file__))
sys.path.insert(0, TESTS)
from test_analysis import _synthetic_pulse  # noqa: E402

RUN_TOML = """
[grid]
n = 64
length = 0.5
[initial]
kind = "gaussian"
amplitude = 1e-3
width = 0.02
position = 0.25
[time]
t_end = 1e6
max_steps = 120
[output]
snapshot_every = 25
checkpoint_every = 40
"""


def _tree(path, **kw):
    """The whole file as an xarray DataTree, loaded into memory and the file closed."""
    tree = xr.open_datatree(path, engine="h5netcdf", **kw)
    tree.load()
    tree.close()
    return tree


def _units(da):
    return da.attrs["units"], bool(da.attrs.get("long_name"))


def test_steady_and_family_files_open_with_xarray(tmp_path):
    path = str(tmp_path / "fam.h5")
    specs = [(1.2, 0.02, 0.05), (1.05, 0.3, 0.2), (1.03, 0.6, 0.4)]
    for r, b, w in specs:
        h5io.write_pulse(path, _synthetic_pulse(r, b, w), P)
    an.analyse_family(path, write=True)
    tree = _tree(path)
    assert tree.attrs["format"] == "slippulse-steady" and tree.attrs["format_version"] == 2
    for r, b, w in specs:
        pulse = _synthetic_pulse(r, b, w)
        ds = tree[f"pulses/{h5io.pulse_label(r)}"].to_dataset()
        assert ds["v"].dims == ("xi",) and "xi" in ds.coords
        assert np.array_equal(ds["xi"].values, pulse.xi)
        assert np.array_equal(ds["v"].values, pulse.v)
        assert _units(ds["xi"]) == ("m", True) and _units(ds["v"]) == ("m/s", True)
        assert _units(ds["tau"]) == ("Pa", True) and _units(ds["phi"]) == ("s", True)
    fam = tree["family"].to_dataset()
    assert fam["L"].dims == ("tau_d_ratio",)
    assert np.allclose(fam["tau_d_ratio"].values, [s[0] for s in specs])
    assert np.allclose(fam["L"].values, [s[2] for s in specs], rtol=1e-4)
    assert _units(fam["L"]) == ("m", True)
    assert list(fam["label"].values) == [h5io.pulse_label(s[0]) for s in specs]
    k = sorted(tree["family/mode_ii"].children)[0]
    assert tree[f"family/mode_ii/{k}"]["L"].dims == ("tau_d_ratio",)


def test_version1_steady_file_is_read_and_upgraded(tmp_path):
    """A version-1 file (no scales, no format_version) reads; adding a pulse upgrades it."""
    path = str(tmp_path / "old.h5")
    p1 = _synthetic_pulse(1.1, 0.1, 0.1)
    with h5py.File(path, "w") as h5:                # the layout written before format_version
        h5io.write_parameters(h5, P)
        g = h5.create_group("pulses").create_group(p1.label)
        for name, unit in h5io.DATASETS.items():
            g.create_dataset(name, data=getattr(p1, name)).attrs["units"] = unit
        for name in h5io.ATTRS:
            g.attrs[name] = getattr(p1, name)
    q, _ = h5io.read_pulse(path)
    assert np.array_equal(q.v, p1.v) and q.label == "td1.1000"
    h5io.write_pulse(path, _synthetic_pulse(1.05, 0.3, 0.2), P)
    tree = _tree(path)
    assert tree.attrs["format_version"] == 2
    assert tree["pulses/td1.1000"]["v"].dims == ("xi",)
    assert np.array_equal(tree["pulses/td1.1000"]["v"].values, p1.v)


def test_newer_format_and_foreign_groups(tmp_path):
    path = str(tmp_path / "p.h5")
    h5io.write_pulse(path, _synthetic_pulse(1.1, 0.1, 0.1), P)
    # an extra subgroup in a pulse group (e.g. a spectrum) is tolerated by readers and writers
    with h5py.File(path, "a") as h5:
        sp = h5["pulses/td1.1000"].create_group("spectrum")
        sp.create_dataset("s", data=np.arange(3.0))
    p, _ = h5io.read_pulse(path, "td1.1000")
    assert p.label == "td1.1000"
    h5io.write_pulse(path, _synthetic_pulse(1.05, 0.3, 0.2), P)
    assert "spectrum" in _tree(path, phony_dims="sort")["pulses/td1.1000"].children
    with h5py.File(path, "a") as h5:
        h5.attrs["format_version"] = 3
    with pytest.raises(h5io.SchemaError, match="format_version 3 is newer"):
        h5io.read_pulse(path, "td1.1000")
    with pytest.raises(h5io.SchemaError, match="format_version 3"):
        h5io.write_pulse(path, _synthetic_pulse(1.02, 0.8, 0.8), P)


def test_dynamic_run_file_opens_with_xarray(tmp_path):
    cfg = tmp_path / "run.toml"
    cfg.write_text(RUN_TOML)
    out = str(tmp_path / "run.h5")
    assert main(["dynamic", "run", str(cfg), "--out", out, "--no-progress"]) == 0
    tree = _tree(out)
    assert tree.attrs["format"] == "slippulse-dynamic"
    assert _units(tree["x"]) == ("m", True) and tree["x"].size == 64
    snap = tree["snapshots"].to_dataset()
    assert snap["V"].dims == ("t", "x") and snap["V"].shape == (snap.sizes["t"], 64)
    assert _units(snap["t"]) == ("s", True) and _units(snap["V"]) == ("m/s", True)
    assert _units(snap["tau"]) == ("Pa", True) and _units(snap["delta"]) == ("m", True)
    assert list(snap["step"].values) == [0, 25, 50, 75, 100]     # every snapshot_every steps
    sc = tree["scalars"].to_dataset()
    assert sc["v_max"].dims == ("t",) and sc.sizes["t"] == 120
    assert np.all(np.diff(sc["t"].values) > 0)
    ck = tree["checkpoint"].to_dataset()
    assert ck["V"].dims == ("x",) and int(ck["nstep"]) == 120
    with h5py.File(out, "r") as h5:               # the same numbers as the h5py view
        assert np.array_equal(h5["snapshots/V"][...], snap["V"].values)


def test_version1_dynamic_run_resumes(tmp_path):
    """A run file in the version-1 layout (/grid/x, no scales) resumes and ends up version 2."""
    cfg = tmp_path / "run.toml"
    cfg.write_text(RUN_TOML)
    ref, old = str(tmp_path / "ref.h5"), str(tmp_path / "old.h5")
    assert main(["dynamic", "run", str(cfg), "--out", ref, "--no-progress"]) == 0
    assert main(["dynamic", "run", str(cfg), "--out", old, "--no-progress",
                 "--set", "time.max_steps=80"]) == 0
    with h5py.File(old, "a") as h5:                # rewrite as version 1
        x = h5["x"][...]
        for g in ("snapshots", "scalars"):
            for name in list(h5[g]):
                data = h5[g][name][...]
                units = h5[g][name].attrs["units"]
                del h5[g][name]
                h5[g].create_dataset(name, data=data, maxshape=(None,) + data.shape[1:],
                                     chunks=True).attrs["units"] = units
        st = {k: h5["checkpoint"][k][()] for k in ("t", "nstep", "dt_prev", "V", "phi", "tau",
                                                     "delta", "delta_k", "V_k")}
        st["history/Y"] = h5["checkpoint/history/Y"][()]
        st["history/count"] = h5["checkpoint/history/count"][()]
        del h5["checkpoint"], h5["x"]
        g = h5.create_group("checkpoint")
        for k, v in st.items():
            g.create_dataset(k, data=v)
        g.attrs["history_policy"] = "soe"
        h5.create_group("grid").create_dataset("x", data=x)
        del h5.attrs["format_version"], h5.attrs["format"]
    assert main(["dynamic", "run", str(cfg), "--out", old, "--no-progress", "--resume"]) == 0
    a, b = _tree(ref), _tree(old)
    assert b.attrs["format_version"] == 2
    assert b["checkpoint"]["V"].dims == ("x",) and b["snapshots"]["V"].dims == ("t", "x")
    for g in ("snapshots", "scalars", "checkpoint"):
        for name, da in a[g].to_dataset().data_vars.items():
            assert np.array_equal(da.values, b[g][name].values), (g, name)


def test_verify_file_opens_with_xarray(tmp_path, pulse12):
    from slippulse.timedomain.verify import VerifySettings, verify_pulse, write_result
    from slippulse.timedomain.seeding import DomainSpec

    pulse = pulse12.to_pulse()
    res = verify_pulse(pulse, P, 0.01, DomainSpec(dx=1e-2),
                       VerifySettings(n_samples=5, n_snapshots=3), progress=False)
    path = str(tmp_path / "verify.h5")
    write_result(path, res, P, source="x.h5", label=pulse.label)
    tree = _tree(path)
    assert tree.attrs["format"] == "slippulse-verify"
    s = tree["series"].to_dataset()
    assert s["deviation"].dims == ("t", "xi_dev") and s.sizes["t"] == 6
    assert _units(s["t"]) == ("s", True) and _units(s["xi_dev"]) == ("m", True)
    assert np.allclose(s["xi_dev"].values, s["deviation_xi"].values * pulse.L, rtol=1e-14)
    assert np.array_equal(s["v_max_error"].values, res.series["v_max_error"])
    sn = tree["snapshots"].to_dataset()
    assert sn["v"].dims == ("t", "x") and sn.sizes["t"] == 3
    assert _units(sn["v"]) == ("m/s", True) and _units(sn["x"]) == ("m", True)
    for m, (t, rel, v) in enumerate(res.snapshots):
        assert sn["t"].values[m] == t
        assert np.array_equal(sn["v"].values[m], v)
        assert np.allclose(sn["xi_rel"].values[m], rel, rtol=0, atol=1e-12)
        assert np.allclose(sn["x"].values - sn["x_front"].values[m], rel, rtol=0, atol=1e-12)
    with h5py.File(path, "r") as h5:
        assert h5["snapshots/v"].maxshape == (None, res.x.size)


def test_scan_summary_opens_with_xarray(tmp_path):
    from test_scan import _write_scan

    from slippulse.timedomain.scan import load_scan, read_summary_h5, run_scan

    path, _ = _write_scan(tmp_path, grid="eps = [1e-3, -1e-3]", defaults="sleep = 0.0")
    res = run_scan(load_scan(path), progress=False)
    ds = xr.open_dataset(res.summary_h5, engine="h5netcdf")
    assert ds.attrs["format"] == "slippulse-scan-summary"
    assert "id" in ds.coords and ds.sizes["id"] == 2
    assert list(ds["id"].values) == [r["id"] for r in res.rows]
    assert ds["growth"].dims == ("id",) and _units(ds["growth"]) == ("1", True)
    assert list(ds["eps"].values) == [1e-3, -1e-3]
    rows = read_summary_h5(res.summary_h5)      # the package's reader sees the id column too
    assert [r["id"] for r in rows] == [r["id"] for r in res.rows]
    assert [r["growth"] for r in rows] == [r["growth"] for r in res.rows]


def test_seed_file_opens_with_xarray(tmp_path, pulse12):
    from slippulse.timedomain.seeding import DomainSpec, seed_pulse, write_seed

    seed = seed_pulse(pulse12.to_pulse(), P, DomainSpec(dx=1e-2, ahead=2.0, behind=2.0))
    path = str(tmp_path / "seed.h5")
    write_seed(path, seed)
    ds = xr.open_dataset(path, engine="h5netcdf")
    assert ds.attrs["format"] == "slippulse-seed"
    assert ds["V"].dims == ("x",) and _units(ds["x"]) == ("m", True)
    assert _units(ds["tau_load"]) == ("Pa", True)
    assert np.array_equal(ds["V"].values, seed.stepper.V)
    ds.close()
