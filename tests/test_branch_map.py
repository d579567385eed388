"""The branch map (plotting/branches.py, ``slippulse steady branch-map``) on synthetic branches."""
import dataclasses

import h5py
import numpy as np
import pytest

import cli_inproc
from slippulse.core.h5io import write_pulse
from slippulse.plotting.branches import (COUNT_COLORS, BranchSeries, branch_series, length_ratio,
                                        plot_branch_map)


def _has_colour(png, hexcol, tol=8):
    import matplotlib.image as mpimg
    img = (mpimg.imread(png)[..., :3] * 255).astype(int)
    rgb = np.array([int(hexcol[i:i + 2], 16) for i in (1, 3, 5)])
    return bool(np.any(np.all(np.abs(img - rgb) <= tol, axis=-1)))


def test_unstable_numbers_prefer_the_count_and_mark_missing_spectra():
    b = BranchSeries("b", np.array([1.2, 1.1, 1.0]), np.ones(3), np.array([2.0, np.nan, np.nan]),
                     np.array([1, 1, -1]))
    n, counted = b.unstable()
    assert n.tolist() == [2, 1, -1] and counted.tolist() == [True, False, False]


def test_the_figure_shows_a_colour_only_for_the_counts_present(tmp_path):
    a = BranchSeries("a", np.array([1.2, 1.1, 1.05]), np.array([1.0, 2.5, 7.3]),
                     np.array([1.0, 1.0, np.nan]), np.array([1, 1, -1]))
    b = BranchSeries("b", np.array([1.2, 1.1]), np.array([2.0, 3.4]), np.array([2.0, np.nan]),
                     np.array([2, 2]))
    one = plot_branch_map([a], str(tmp_path / "one.png"))
    both = plot_branch_map([a, b], str(tmp_path / "both.png"))
    assert _has_colour(one, COUNT_COLORS[1]) and not _has_colour(one, COUNT_COLORS[2])
    assert _has_colour(both, COUNT_COLORS[2])


def test_series_reads_counts_and_trace_order_and_the_cli_draws(tmp_path, params, pulse12):
    """Three copies of one pulse at made-up τ_d, traced out of τ_d order (a fold): the series
    keeps the trace order; a stored count wins over the search's number; no spectrum: −1."""
    path = str(tmp_path / "branch.h5")
    base = pulse12.to_pulse()
    for step, q in enumerate((1.2, 1.25, 1.22)):
        p = dataclasses.replace(base, tau_d_ratio=q, tau_d=q * base.tau_min,
                                extra=dict(base.extra, trace_position=step))
        write_pulse(path, p, params)
    with h5py.File(path, "r+") as h5:
        for lab, count in (("td1.2000", 3), ("td1.2500", None)):
            g = h5["pulses"][lab].create_group("spectrum")
            g.attrs["status"] = "converged"
            g.attrs["n_unstable"] = 1
            if count is not None:
                g.attrs["count"] = count
    s = branch_series(path)
    assert s.q.tolist() == [1.2, 1.25, 1.22]
    assert s.unstable()[0].tolist() == [3, 1, -1]
    # a count of 0 in [0.5, 4] c_p/L with an unstable eigenvalue found at 0.02, left of the box:
    # one unstable mode, not counted exactly (hollow), never "0 counted"
    with h5py.File(path, "r+") as h5:
        g = h5["pulses"]["td1.2200"].create_group("spectrum")
        g.attrs.update(status="converged", n_unstable=1, count=0,
                       count_box_c_over_L=np.array([0.5, 4.0, 4.0]))
        g["s_per_L_real"] = np.array([0.02, -0.3])
    n, counted = branch_series(path).unstable()
    assert n.tolist() == [3, 1, 1] and counted.tolist() == [True, False, False]
    with h5py.File(path, "r+") as h5:
        del h5["pulses"]["td1.2200"]["spectrum"]
    out = tmp_path / "map.png"
    r = cli_inproc.run(["steady", "branch-map", path, "--names", "synthetic", "--out", out])
    assert r.returncode == 0, r.stderr
    assert out.exists() and "synthetic: 3 pulses" in r.stdout and "1 counted (unstable: [3])" in r.stdout
    r = cli_inproc.run(["steady", "branch-map", path, "--names", "a", "b", "--out", out])
    assert r.returncode == 2 and "names" in r.stderr
    zoomed = tmp_path / "zoom.png"
    r = cli_inproc.run(["steady", "branch-map", path, "--zoom", "1.21", "1.26", "--out", zoomed])
    assert r.returncode == 0, r.stderr
    import matplotlib.image as mpimg
    assert mpimg.imread(zoomed).shape[1] > mpimg.imread(out).shape[1]     # the second panel
    r = cli_inproc.run(["steady", "branch-map", path, "--zoom", "1.26", "1.21", "--out", zoomed])
    assert r.returncode == 2 and "--zoom" in r.stderr


def test_two_files_make_one_branch_by_tau_d(tmp_path, params, pulse12):
    """A family in two files (no trace positions): one series by decreasing τ_d, a pulse stored
    in both taken once."""
    base = pulse12.to_pulse()
    a, b = str(tmp_path / "a.h5"), str(tmp_path / "b.h5")
    for path, qs in ((a, (1.2, 1.1)), (b, (1.3, 1.2))):
        for q in qs:
            write_pulse(path, dataclasses.replace(base, tau_d_ratio=q, tau_d=q * base.tau_min),
                        params)
    s = branch_series([a, b], "family")
    assert s.q.tolist() == [1.3, 1.2, 1.1]
    out = tmp_path / "m.png"
    r = cli_inproc.run(["steady", "branch-map", f"{a}+{b}", a, "--out", out])
    assert r.returncode == 0, r.stderr
    assert "family" not in r.stdout and "a: 2 pulses" in r.stdout
    assert "L / L(a) at equal tau_d = 1-1 over 2 pulses" in r.stdout


def test_length_ratio_at_equal_tau_d():
    """The reference's ln L is interpolated in τ_d: L = e^{−10 q} against twice it is 2 at any q
    inside the range, nan outside; a folded reference is refused."""
    qr = np.linspace(1.0, 1.3, 7)
    ref = BranchSeries("f", qr[::-1], np.exp(-10 * qr[::-1]), np.full(7, np.nan), np.full(7, -1))
    q = np.array([0.9, 1.02, 1.17, 1.31])
    b = BranchSeries("b", q, 2 * np.exp(-10 * q), np.full(4, np.nan), np.full(4, -1))
    r = length_ratio(b, ref)
    assert np.isnan(r[0]) and np.isnan(r[3]) and np.allclose(r[1:3], 2.0, rtol=1e-12)
    folded = BranchSeries("g", np.array([1.0, 1.2, 1.1]), np.ones(3), np.full(3, np.nan),
                          np.full(3, -1))
    with pytest.raises(ValueError):
        length_ratio(b, folded)
