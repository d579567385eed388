"""The one-degree-of-freedom equation of motion along the steady line (timedomain.motion,
``slippulse steady motion``; docs/motion.md).

The references are independent of the model's formula: a synthetic family whose dynamics is
dL/dt = γ(L)(τ_d − τ⁰(L)) by construction, integrated directly from that law, and the linear
solution e^{st} about the family's own pulses."""
import math

import h5py
import numpy as np
import pytest
from scipy.integrate import solve_ivp

from cli_inproc import run as cli
from slippulse.core.h5io import Pulse, pulse_label, write_pulse
from slippulse.core.params import DEFAULT
from slippulse.timedomain.motion import MotionInputError, SteadyLine, integrate

C_S = 2739.0


def tau0(L):                      # a steady line falling with L, as the family's does
    return 1.02 + 0.18 / L ** 0.8


def dtau0(L):
    return -0.8 * 0.18 / L ** 1.8


def c0(L):
    return C_S * (1.0 - np.exp(-L / 6.0))


def gamma(L):                     # dL/dt = gamma (tau_d - tau0): a longer pulse grows
    return 400.0 * c0(L) / L


def exact_rate(L, tau_d):
    return gamma(L) * (tau_d - tau0(L))


def synthetic_line(n, s_err_rel=0.0, lo=1.0, hi=15.0):
    """The family sampled at n pulses (geometric in L); s = ∂_L F on the line = −γ τ⁰′."""
    L = np.geomspace(lo, hi, n)
    s = -gamma(L) * dtau0(L)
    return SteadyLine.from_arrays(L, tau0(L), c0(L), L, s, s_err_rel * s, tau_min=3.4e5,
                                  c_s=C_S, source="synthetic")


def exact_trajectory(tau_d, L0, t):
    sol = solve_ivp(lambda _, y: [exact_rate(y[0], tau_d)], (0, t[-1]), [L0], t_eval=t,
                    method="DOP853", rtol=1e-13, atol=1e-14)
    return sol.y[0]


@pytest.mark.parametrize("L_star, L0", [(4.0, 3.0), (4.0, 5.5), (2.0, 2.05)])
def test_exact_for_a_family_whose_dynamics_is_one_dimensional(L_star, L0):
    """The model is exact when the true dynamics is linear in τ_d at fixed L: only the
    interpolation of the family is left, and it converges with the number of pulses."""
    tau_d = float(tau0(L_star))
    dur = 10.0 / float(-gamma(L_star) * dtau0(L_star))
    errs = []
    for n in (15, 30, 60):
        line = synthetic_line(n)
        tr = integrate(line, tau_d, L0, duration=dur, n_out=400)
        ok = np.isfinite(tr.L)
        assert ok.sum() > 20
        ref = exact_trajectory(tau_d, L0, tr.t[ok])
        errs.append(np.max(np.abs(tr.L[ok] / ref[:ok.sum()] - 1.0)))
        cref = c0(ref[:ok.sum()])
        assert np.max(np.abs(tr.c_p[ok] / cref - 1.0)) < 20 * errs[-1] + 1e-9
    assert errs[-1] < 1e-5, errs
    assert errs[0] > 2 * errs[-1], errs          # the interpolation error falls with n


def test_exact_model_leaves_the_family_where_the_true_dynamics_does():
    tau_d = float(tau0(4.0))
    line = synthetic_line(40)
    tr = integrate(line, tau_d, 5.0, duration=0.1)
    assert tr.fate == "left the family (long end)"
    sol = solve_ivp(lambda _, y: [exact_rate(y[0], tau_d)], (0, 0.1), [5.0], rtol=1e-12,
                    atol=1e-14, events=lambda _, y: y[0] - 15.0)
    assert tr.t_fate == pytest.approx(sol.t_events[0][0], rel=1e-4)
    tr = integrate(line, tau_d, 3.0, duration=0.1)
    assert tr.fate == "left the family (short end)"


@pytest.mark.parametrize("i", [3, 10, 20])
@pytest.mark.parametrize("sign", [1, -1])
def test_small_departures_at_the_family_pulses_grow_as_exp_st(i, sign):
    """L − L* = δ e^{s t} for δ ≪ L* at the family's own pulses (τ_d = τ⁰(L_i), s = s_i)."""
    line = synthetic_line(25)
    Li, si, taui = line.L[i], line.s[i], line.tau_ratio[i]
    d = sign * 1e-7 * Li
    tr = integrate(line, taui, Li + d, duration=4.0 / si, n_out=100)
    ratio = (tr.L - Li) / d
    assert np.allclose(ratio, np.exp(si * tr.t), rtol=2e-4)


def test_the_band_holds_the_trajectory_and_grows_with_s_err():
    tau_d = float(tau0(4.0))
    dur = 2.0 / float(-gamma(4.0) * dtau0(4.0))
    t0 = integrate(synthetic_line(20), tau_d, 4.3, duration=dur)
    t1 = integrate(synthetic_line(20, s_err_rel=0.05), tau_d, 4.3, duration=dur)
    ok = np.isfinite(t1.L)
    assert ok.sum() > 100
    assert np.all(t1.L_lo[ok] <= t1.L[ok]) and np.all(t1.L[ok] <= t1.L_hi[ok])
    w0, w1 = t0.L_hi[-1] - t0.L_lo[-1], t1.L_hi[-1] - t1.L_lo[-1]
    assert w1 > 10 * w0
    # s·(1 ± r) everywhere is time rescaled by 1 ± r: the band's edge is the trajectory at t(1 + r)
    hi = integrate(synthetic_line(20), tau_d, 4.3, duration=dur * 1.05)
    assert t1.L_hi[-1] == pytest.approx(max(hi.L[-1], hi.L_hi[-1]), rel=1e-6)


def test_refuses_what_it_cannot_model():
    line = synthetic_line(20)
    with pytest.raises(MotionInputError, match="tau-d"):
        integrate(line, 1.5, 4.0, 1.0)
    with pytest.raises(MotionInputError, match="length"):
        integrate(line, float(tau0(4.0)), 20.0, 1.0)
    L = np.geomspace(1, 15, 10)
    with pytest.raises(MotionInputError, match="growth rate"):
        SteadyLine.from_arrays(L, tau0(L), c0(L), L[:2], [1.0, 1.0], [0.0, 0.0])


# ------------------------------------------------------------------ the command
def _record(ratio, L):
    """A valid pulse record (the validating reader's checks) on the synthetic steady line:
    the line's L and c_p, a box of slip rate L long; not a solution of the steady equation."""
    P = DEFAULT
    xi = np.linspace(-3.0 * L, L, 200)
    v_st = 1e-7
    v = np.where((xi > -L) & (xi < 0.0), 1e-3, v_st)
    tau = np.full_like(xi, ratio * P.tau_min)
    return Pulse(xi=xi, v=v, phi=np.full_like(xi, 1e-3), tau=tau, residual=np.zeros_like(xi),
                 tau_d_ratio=ratio, tau_d=ratio * P.tau_min, tau_min=P.tau_min,
                 beta=c0(L) / P.c_s, c_p=c0(L), L=L, L_tilde=L / P.L_Gc, v_stick=v_st,
                 v_max=1e-3, max_residual=0.0, converged=True, n_points=xi.size, wall_time=0.0)


def _family_file(path, n=12, rated=True):
    L = np.geomspace(1.0, 15.0, n)
    s = -gamma(L) * dtau0(L)
    for Li in L:
        write_pulse(str(path), _record(float(tau0(Li)), Li), DEFAULT)
    with h5py.File(path, "a") as h5:
        for Li, si in zip(L, s):
            g = h5["pulses"][pulse_label(float(tau0(Li)))]
            if rated:
                sp = g.create_group("spectrum")
                sp.attrs.update({"status": "converged", "s": si, "s_err": 1e-3 * si,
                                 "s_per_L": si * Li / c0(Li), "s_err_per_L": 1e-3 * si * Li / c0(Li),
                                 "sign_resolved": 1})
    return path


def test_command_writes_an_xarray_trajectory(tmp_path):
    xr = pytest.importorskip("xarray")
    fam = _family_file(tmp_path / "fam.h5")
    out = tmp_path / "m.h5"
    r = cli(["steady", "motion", fam, "--tau-d", f"{tau0(4.0):.10f}", "--length", "3.9",
             "--duration", "0.05", "--out", out])
    assert r.returncode == 0, r.stderr
    assert "left the family (short end)" in r.stdout
    ds = xr.open_dataset(out, engine="h5netcdf")
    assert ds["L"].attrs["units"] == "m" and ds["t"].attrs["units"] == "s"
    assert ds.attrs["tau_d_ratio"] == pytest.approx(tau0(4.0))
    assert ds["L"].values[0] == pytest.approx(3.9)
    assert np.nanmax(ds["L"].values) <= 3.9 + 1e-12          # it shrinks
    assert np.all(ds["L_lo"].values[np.isfinite(ds["L"].values)] <= ds["L"].values[
        np.isfinite(ds["L"].values)])


@pytest.mark.parametrize("args, word", [
    (["--tau-d", "1.5", "--length", "4"], "tau-d"),
    (["--tau-d", "1.05", "--length", "40"], "length"),
    (["--tau-d", "nan", "--length", "4"], "tau-d"),
    (["--tau-d", "1.05", "--length", "4", "--duration", "-1"], "duration"),
])
def test_command_refuses_bad_input_with_one_line_and_no_file(tmp_path, args, word):
    fam = _family_file(tmp_path / "fam.h5")
    out = tmp_path / "m.h5"
    r = cli(["steady", "motion", fam, *args, "--out", out])
    assert r.returncode == 2
    lines = r.stderr.strip().splitlines()
    assert len(lines) == 1 and word in lines[0], r.stderr
    assert not out.exists()


def test_command_refuses_a_family_without_a_spectrum(tmp_path):
    fam = _family_file(tmp_path / "fam.h5", rated=False)
    out = tmp_path / "m.h5"
    r = cli(["steady", "motion", fam, "--tau-d", "1.05", "--length", "4", "--out", out])
    assert r.returncode == 2 and "spectrum" in r.stderr and len(r.stderr.strip().splitlines()) == 1
    assert not out.exists()


def test_compare_finds_no_split_for_the_exact_dynamics_and_one_for_a_pulse_off_the_line():
    from slippulse.timedomain.motion import compare
    line = synthetic_line(60)
    tau_d = float(tau0(4.0))
    dur = 3.0 / float(-gamma(4.0) * dtau0(4.0))
    t = np.linspace(0, dur, 301)
    L = exact_trajectory(tau_d, 4.4, t)
    cp = c0(L)
    x = np.r_[0.0, np.cumsum(0.5 * (cp[1:] + cp[:-1]) * np.diff(t))]
    c = compare(line, tau_d, t, x, L, skip=0)
    assert math.isnan(c.t_split)
    assert np.nanmax(np.abs(c.line_distance[2:-2])) < 1e-3
    # the same lengths at a speed 10 % above the line: they split at once
    c = compare(line, tau_d, t, 1.1 * x, L, skip=0)
    assert c.t_split == t[0] and np.nanmedian(c.line_distance) == pytest.approx(0.1, abs=2e-3)


def _fate_file(path, tau_d, L0, speedup=1.0, n=200):
    """A fate file (the layout :func:`timedomain.fate.read_fate` reads) whose pulse follows the
    synthetic family's exact dynamics dL/dt = γ(τ_d − τ⁰(L)), or ``speedup`` times it."""
    s = float(-gamma(4.0) * dtau0(4.0))
    t = np.linspace(0.0, 3.0 / s, n)
    sol = solve_ivp(lambda _, y: [speedup * exact_rate(y[0], tau_d)], (0, t[-1]), [L0], t_eval=t,
                    method="DOP853", rtol=1e-12, atol=1e-12)
    L = sol.y[0]
    c = c0(L)
    x = np.concatenate([[0.0], np.cumsum(0.5 * (c[1:] + c[:-1]) * np.diff(t))])
    with h5py.File(path, "w") as h5:
        h5.attrs.update({"tau_d_ratio": tau_d, "eps": 1e-2, "perturbation": "mode", "ahead": 4.0,
                         "behind": 4.0, "far_field": "steady", "fate": "grew x3",
                         "distance_fate": float("nan"), "t_fate": float("nan"), "L": 4.0})
        g = h5.create_group("series")
        for k, v in (("t", t), ("x_front", x), ("L", L), ("v_max", np.ones_like(t))):
            g[k] = v
    return str(path)


def test_fate_compare_follows_the_exact_dynamics_and_splits_from_a_pulse_off_the_line(tmp_path):
    """``slippulse dynamic fate-compare``: a run on the family's own dynamics stays within 5 % of
    the model to its end (no split); one growing twice as fast splits; the figure is written."""
    fam = _family_file(tmp_path / "fam.h5", n=40)
    tau_d = float(tau0(4.0))
    on = _fate_file(tmp_path / "on.h5", tau_d, 4.1)
    off = _fate_file(tmp_path / "off.h5", tau_d, 4.1, speedup=2.0)
    fig = tmp_path / "m.png"
    prof = tmp_path / "p.png"
    r = cli(["dynamic", "fate-compare", fig, "--family", fam, "--runs", on, off,
             "--profiles", prof])
    assert r.returncode == 0, r.stderr
    assert prof.exists() and prof.stat().st_size > 0
    rows = [ln.split("|")[1:-1] for ln in r.stdout.splitlines() if ln.startswith("| 1.")]
    assert len(rows) == 2
    split_on = [float(v) for v in rows[0][11].split(",")]
    split_off = [float(v) for v in rows[1][11].split(",")]
    assert all(math.isnan(v) for v in split_on)
    assert math.isfinite(split_off[0]) and split_off[0] > 0
    # dL/dt / c_p: on the family's own dynamics the run's range is the model's; twice as fast
    # it goes well beyond the model's
    spans = [[[float(x) for x in part.strip().split("–")] for part in row[13].split(";")]
             for row in rows]
    assert spans[0][0] == pytest.approx(spans[0][1], rel=0.02, abs=1e-3)
    assert spans[1][0][1] > 1.2 * spans[1][1][1]
    assert fig.exists() and fig.stat().st_size > 0


def test_fate_compare_refuses_a_missing_run_with_one_line(tmp_path):
    fam = _family_file(tmp_path / "fam.h5")
    r = cli(["dynamic", "fate-compare", tmp_path / "m.png", "--family", fam, "--runs",
             tmp_path / "none.h5"])
    assert r.returncode == 2 and len(r.stderr.strip().splitlines()) == 1, r.stderr
    assert not (tmp_path / "m.png").exists()


# ------------------------------------------------------------------ where the model ends
def _power_line(q, n=80, hi=1000.0):
    """The synthetic steady line with dynamics dL/dt = k L^q (τ_d − τ⁰(L)) (s = −k L^q τ⁰′):
    beyond L ≈ 100 τ⁰ is nearly flat and dL/dt ∝ L^q."""
    L = np.geomspace(1.0, hi, n)
    s = -0.5 * L ** q * dtau0(L)
    return SteadyLine.from_arrays(L, tau0(L), c0(L), L, s, 0 * s, tau_min=3.4e5, c_s=C_S)


@pytest.mark.parametrize("q", [2.2, 0.5])
def test_limits_time_and_exponent_match_the_exact_dynamics(q):
    """Time to the long end against the exact dynamics' own event time; the exponent of dL/dt at
    the end, and the time left to L = ∞, finite only for q > 1 (∫ dL/(k L^q Δτ))."""
    from scipy.integrate import quad
    from slippulse.timedomain.motion import limits
    tau_d = float(tau0(4.0))
    line = _power_line(q)
    lim = limits(line, tau_d, start=0.01)

    def exact(L):
        return 0.5 * L ** q * (tau_d - tau0(L))
    ref = quad(lambda L: 1.0 / exact(L), 4.04, 1000.0, limit=200, epsrel=1e-10)[0]
    assert lim.L[0] == pytest.approx(4.04, rel=1e-6)
    assert lim.t_end == pytest.approx(ref, rel=2e-3)
    assert lim.exponent_end == pytest.approx(q, abs=0.03)
    assert lim.finite_time_divergence == (q > 1)
    if q > 1:
        rest = quad(lambda L: 1.0 / exact(L), 1000.0, np.inf, epsrel=1e-8)[0]
        assert lim.t_rest == pytest.approx(rest, rel=0.05)
    else:
        assert math.isinf(lim.t_rest)


def test_limits_find_where_the_rear_front_stops():
    """The rear front's speed c_p⁰ − dL/dt against the exact dynamics; its first zero by root
    finding on the exact law (the synthetic line's rate exceeds c_p⁰ over a window)."""
    from scipy.optimize import brentq
    from slippulse.timedomain.motion import limits
    tau_d = float(tau0(4.0))
    line = synthetic_line(60)
    lim = limits(line, tau_d, start=0.01, n=20000)
    heal = c0(lim.L) - exact_rate(lim.L, tau_d)
    assert np.allclose(lim.healing_speed, heal, rtol=1e-3, atol=1e-3 * C_S)
    assert heal[0] > 0 and heal.min() < 0                  # the case is a real test
    root = brentq(lambda L: c0(L) - exact_rate(L, tau_d), lim.L[0], lim.L[np.argmin(heal)])
    assert lim.L_heal_stops == pytest.approx(root, rel=2e-3)
    # R c_p (τ_d − τ⁰) is the rate: R = s L/c_p / |dτ⁰/d ln L| = γ/c_p here
    assert np.allclose(lim.mobility, gamma(lim.L) / c0(lim.L), rtol=1e-3)


def test_line_from_the_committed_tables_and_the_rates_of_record():
    """The family's tables (1 m – 10 km) and the rates of record give a line on which s at
    1.1 τ_min is s L/c_p × c_p/L of record, and τ⁰ falls with L."""
    import glob
    from pathlib import Path
    from slippulse.timedomain.motion import line_from_tables
    root = Path(__file__).resolve().parents[1]
    tables = sorted(glob.glob(str(root / "steady" / "seeds" / "deep_family_*.csv")))
    line = line_from_tables(tables, root / "docs" / "results" / "records.toml")
    assert np.all(np.diff(line.tau_ratio) < 0) and line.L[-1] > 1e4
    k = np.argmin(np.abs(line.L_rated - 2.50144))
    assert line.s[k] == pytest.approx(7.994885 * 0.096902318 * C_S / 2.50144, rel=1e-4)


def test_command_takes_the_tables_only_with_the_rates_of_record(tmp_path):
    from pathlib import Path
    root = Path(__file__).resolve().parents[1]
    table = root / "steady" / "seeds" / "deep_family_1m-2550m.csv"
    out = tmp_path / "m.h5"
    r = cli(["steady", "motion", table, "--tau-d", "1.1", "--length", "2.6", "--out", out])
    assert r.returncode == 2 and "--records" in r.stderr and len(r.stderr.strip().splitlines()) == 1
    assert not out.exists()
    r = cli(["steady", "motion", table, "--records", root / "docs" / "results" / "records.toml",
             "--tau-d", "1.1", "--length", "2.6", "--duration", "1e-3", "--out", out])
    assert r.returncode == 0, r.stderr
    assert out.exists() and "model limits: growing side" in r.stdout
