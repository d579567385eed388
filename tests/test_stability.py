"""Instability measurement (timedomain/perturbation.py): growth fits on exact exponentials, the ±ε protocol on
real runs of the unstable 1.2 τ_min pulse, and a real perturbation scan through a Dask LocalCluster.

The 1.2 τ_min pulse of the shared fixture is coarse (steady N = 700, SBI Δx = 8 mm): cheap runs whose
growth rate is *not* the converged one (docs/stability.md has those); the tests check the protocol:
both signs depart in opposite directions, to opposite fates, at one rate.
"""
import math
import os

import h5py
import numpy as np
import pytest

from slippulse.core.params import ParameterError
from slippulse.timedomain.perturbation import (check_case, fit_growth, pair_growth, pair_rows, read_row,
                                 read_series, run_case)


def test_fit_growth_recovers_an_exponential_and_its_window():
    x = np.linspace(0, 1, 201)
    d = 1e-4 * np.exp(7.0 * x)           # crosses 1e-3 at x = 0.329, 3e-2 at x = 0.815
    f = fit_growth(x, d, lo=1e-3, hi=3e-2)
    assert f["s"] == pytest.approx(7.0, rel=1e-10)
    assert f["x0"] == pytest.approx(0.33, abs=0.006)
    assert f["x1"] <= 0.815 + 1e-12
    assert f["s_err"] < 1e-8
    assert f["sign"] == 1
    # a negative deviation grows the same way
    assert fit_growth(x, -d)["s"] == pytest.approx(7.0, rel=1e-10)
    # a bent curve (rate rising from 5 to 9) reports the bend in its uncertainty
    bent = 1e-4 * np.exp(5 * x + 2 * x ** 2)
    fb = fit_growth(x, bent, lo=1e-3, hi=3e-2)
    assert fb["s_err"] > 0.3


def test_fit_growth_with_lo_zero_skips_exact_zeros():
    """lo = 0 (the pair's decaying or neutral fit): a sample with d = 0 exactly has no ln|d|; it
    is left out (it once entered the fit as −inf, with a divide-by-zero warning)."""
    import warnings
    x = np.linspace(0, 1, 101)
    d = 1e-4 * np.exp(-3.0 * x)
    d[[10, 50]] = 0.0
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        f = fit_growth(x, d, lo=0.0, hi=np.inf)
    assert f["s"] == pytest.approx(-3.0, rel=1e-10) and f["n"] == 99
    assert math.isnan(fit_growth(x, np.zeros(101), lo=0.0, hi=np.inf)["s"])


def test_fit_growth_without_a_regime_is_nan():
    x = np.linspace(0, 1, 50)
    assert math.isnan(fit_growth(x, np.full(50, 1e-5))["s"])


def _series(t, d, L=1.0, c=1.0):
    return {"t": t, "v_max_error": d, "attrs": {"L": L, "c_p": c}}


def test_pair_growth_cancels_baseline_and_quadratic_terms():
    """d± = b(t) ± εA e^{st} + (εA e^{st})² : the antisymmetric part is exactly εA e^{st}."""
    t = np.linspace(0, 1, 400)
    s, eps = 6.0, 1e-3
    lin = eps * 2.0 * np.exp(s * t)
    base = 3e-4 * np.exp(s * t)                       # the unperturbed seed's own drift
    plus = _series(t, base + lin + 40 * lin ** 2)
    minus = _series(t + 1e-6, base - lin + 40 * lin ** 2)   # sampled slightly later
    g = pair_growth(plus, minus, eps)
    assert g["regime"] == "growth"
    assert g["s_per_s"] == pytest.approx(s, rel=2e-3)
    assert g["s_per_L"] == pytest.approx(s, rel=2e-3)   # L/c_p = 1
    # the window ends before max |d±| exceeds 0.03
    end = np.searchsorted(t, g["t1"])
    assert max(abs(plus["v_max_error"][end]), abs(minus["v_max_error"][end])) <= 0.03


def test_pair_growth_skips_the_start_up_transient():
    """r = εA e^{st} − εB e^{−st}: the local rate falls from 3s toward s (as measured at 1.2 τ_min);
    the plateau rule fits where it has settled."""
    t = np.linspace(0, 1, 500)
    s, eps = 8.0, 1e-4
    r = eps * (1.5 * np.exp(s * t) - 1.0 * np.exp(-s * t))
    g = pair_growth(_series(t, r), _series(t, -r), eps)
    assert g["regime"] == "growth"
    assert g["s_per_s"] == pytest.approx(s, rel=0.01)
    assert g["t0"] > 0.15                     # the transient (> 6 % of r before) is left out
    # a plain fit from the start is biased by the transient
    assert fit_growth(t, r, lo=0, hi=0.03)["s"] > 1.05 * s


def test_pair_growth_of_a_decaying_response_uses_the_late_half():
    t = np.linspace(0, 2, 300)
    r = 1e-3 * np.exp(-1.5 * t)
    g = pair_growth(_series(t, r), _series(t, -r), 1e-3)
    assert g["regime"] == "late half"
    assert g["s_per_s"] == pytest.approx(-1.5, rel=1e-6)


def test_pair_growth_on_a_grid_integral():
    """F± = F₀(1 + b(t) ± εA e^{st}): the frame-free potency rate (verify.potency_rate) gives s,
    with the linear regime still ended by the v_max error; a missing or unknown one is refused."""
    t = np.linspace(0, 1, 400)
    s, eps = 5.0, 1e-3
    base, lin = 2e-4 * t, 0.3 * eps * np.exp(s * t)
    vmax = 2.0 * eps * np.exp(s * t)                    # |d±| > 0.03 after t ≈ 0.54
    plus = dict(_series(t, vmax), potency_rate=7.0 * (1 + base + lin))
    minus = dict(_series(t, -vmax), potency_rate=7.0 * (1 + base - lin))
    g = pair_growth(plus, minus, eps, observable="potency_rate")
    assert g["regime"] == "growth"
    assert g["s_per_s"] == pytest.approx(s, rel=1e-3)
    assert g["r"][0] == pytest.approx(0.3 * eps, rel=1e-9)   # relative to the mean F at t = 0
    assert g["t1"] < 0.55
    with pytest.raises(ValueError, match="potency_rate"):
        pair_growth(_series(t, vmax), _series(t, -vmax), eps, observable="potency_rate")
    with pytest.raises(ValueError, match="observable"):
        pair_growth(plus, minus, eps, observable="L")


def test_mode_pair_growth_fits_the_whole_regime_through_an_oscillation():
    """r = εA e^{st}(1 + 0.15 cos(2πt/0.1)) + a seed transient that dies within 0.05: the
    whole-regime fit after skip = 0.1 recovers s to 1 %; its error bar covers the truth; the
    samples before skip are left out."""
    from slippulse.timedomain.perturbation import mode_pair_growth
    t = np.linspace(0, 2, 81)
    s, eps = 0.66, 1e-2
    r = 1e-4 * np.exp(s * t) * (1 + 0.15 * np.cos(2 * np.pi * t / 0.1 + 0.3)) \
        + 3e-4 * np.exp(-60 * t)
    vmax = 5e-3 * np.exp(s * t)                          # stays below d_max = 0.03
    plus = dict(_series(t, vmax), potency_rate=2.0 * (1 + r))
    minus = dict(_series(t, -vmax), potency_rate=2.0 * (1 - r))
    g = mode_pair_growth(plus, minus, eps)
    assert g["s_per_L"] == pytest.approx(s, rel=0.01)
    assert abs(g["s_per_L"] - s) <= g["s_per_L_err"] + 1e-12
    assert g["t0"] >= 0.1 and g["n"] == np.count_nonzero(t >= 0.1)
    # too few samples after skip: no rate
    assert math.isnan(mode_pair_growth(plus, minus, eps, skip=1.95)["s_per_L"])


def test_offset_fit_recovers_an_integrated_exponential_that_the_log_fit_misses():
    """r = A e^{st} + B + an integrated oscillation: fit_growth_offset recovers s to 1e-5 and B;
    the log-linear fit of the same r (no offset) is off by more than 1 %."""
    from slippulse.timedomain.perturbation import fit_growth_offset
    t = np.linspace(0.0, 10.0, 801)
    s = 0.3
    r = 2.0 * np.exp(s * t) - 1.5 + 1e-3 * np.exp(s * t) * np.sin(2 * np.pi * t / 0.04)
    f = fit_growth_offset(t, r)
    assert f["s"] == pytest.approx(s, rel=1e-5)
    assert f["B"] == pytest.approx(-1.5, rel=1e-3)
    assert abs(f["s"] - s) <= f["s_err"] + 1e-12
    assert abs(fit_growth(t, r, lo=0.0, hi=np.inf)["s"] / s - 1) > 0.01
    assert math.isnan(fit_growth_offset(t[:4], r[:4])["s"])


def test_mode_pair_growth_on_the_slip_potency():
    """S± = S₀(t) ± ε(A e^{st} + B), scaled by the potency of one transit: mode_pair_growth fits
    A e^{st} + B; pair_growth refuses the integrated observable; without potency_rate it says so."""
    from slippulse.timedomain.perturbation import mode_pair_growth
    t = np.linspace(0, 3, 121)
    s, eps = 0.3, 3e-3
    S0 = 5.0 * t + 0.2
    resp = eps * (0.4 * np.exp(s * t) - 0.3)
    vmax = 0.5 * eps * np.exp(s * t)
    pr = np.full_like(t, 5.0)
    plus = dict(_series(t, vmax, L=2.0, c=4.0), potency_rate=pr, slip_potency=S0 + resp)
    minus = dict(_series(t, -vmax, L=2.0, c=4.0), potency_rate=pr, slip_potency=S0 - resp)
    g = mode_pair_growth(plus, minus, eps, observable="slip_potency")
    assert g["s_per_s"] == pytest.approx(s, rel=1e-6)
    assert g["s_per_L"] == pytest.approx(s * 0.5, rel=1e-6)
    assert g["r"][-1] == pytest.approx(resp[-1] / (5.0 * 0.5), rel=1e-9)
    assert "A e^{st} + B" in g["regime"]
    with pytest.raises(ValueError, match="mode_pair_growth"):
        pair_growth(plus, minus, eps, observable="slip_potency")
    del plus["potency_rate"]
    with pytest.raises(ValueError, match="potency_rate"):
        mode_pair_growth(plus, minus, eps, observable="slip_potency")


def test_mode_pair_growth_ends_where_the_mean_state_drifts():
    """The pair's mean potency rate drifts (q = 1e-3 (e^{2t} − 1)) and the rate of r changes once
    |q| > 0.005 (t > ln 6/2 = 0.90): the regime ends there and s is the early one; with the bound
    lifted the fit takes in the late rate."""
    from slippulse.timedomain.perturbation import mode_pair_growth
    t = np.linspace(0, 2, 201)
    s, eps = 1.0, 1e-3
    drift = 1e-3 * np.expm1(2.0 * t)
    tc = np.log(6.0) / 2.0
    late = np.where(t > tc, 0.5 * (t - tc), 0.0)
    r = 1e-4 * np.exp(s * t + late)
    vmax = 1e-3 * np.exp(s * t)
    plus = dict(_series(t, vmax), potency_rate=3.0 * (1 + drift + r))
    minus = dict(_series(t, -vmax), potency_rate=3.0 * (1 + drift - r))
    g = mode_pair_growth(plus, minus, eps)
    assert tc - 0.02 <= g["t1"] <= tc + 1e-12
    assert g["s_per_s"] == pytest.approx(s, rel=1e-6)
    g = mode_pair_growth(plus, minus, eps, drift_max=1.0)
    assert g["t1"] == pytest.approx(2.0) and g["s_per_s"] > 1.05 * s


def test_pair_rate_at_zero_drift_recovers_the_rate_of_the_undrifted_state():
    """The pair's mean state drifts (q = −2e−3 (e^{0.3t} − 1)) and the pair's rate moves with it,
    s(q) = s₀ + kq (rate +50 % at the end): the fit of A exp(s₀t + kQ) + B recovers s₀ and k,
    where the whole-run fit of A e^{st} + B is off by more than 10 %."""
    from slippulse.timedomain.perturbation import mode_pair_growth, pair_rate_at_zero_drift
    t = np.linspace(0.0, 6.0, 2401)                 # L/c_p = 0.5: 12 L of travel
    s0, k, eps = 0.4, -20.0, 3e-3
    q = -2e-3 * np.expm1(0.3 * t)
    Q = -2e-3 * (np.expm1(0.3 * t) / 0.3 - t)       # ∫ q dt
    R = np.exp(s0 * t + k * Q)                      # rate s0 + k q
    pr_p, pr_m = 5.0 * (1 + q), 5.0 * (1 + q)
    S0 = 5.0 * (t + Q)
    plus = dict(_series(t, 0.1 * eps * R, L=2.0, c=4.0), potency_rate=pr_p,
                slip_potency=S0 + eps * (R - 0.7))
    minus = dict(_series(t, -0.1 * eps * R, L=2.0, c=4.0), potency_rate=pr_m,
                 slip_potency=S0 - eps * (R - 0.7))
    z = pair_rate_at_zero_drift(plus, minus, start=1.0)
    assert z["x0"] == pytest.approx(1.0, abs=0.01) and z["x1"] == pytest.approx(12.0)
    assert z["s_per_L"] == pytest.approx(s0 * 0.5, rel=1e-6)
    assert z["slope_per_L"] == pytest.approx(k * 0.5, rel=1e-4)
    whole = mode_pair_growth(plus, minus, eps, observable="slip_potency", drift_max=1.0)
    assert abs(whole["s_per_L"] / (s0 * 0.5) - 1) > 0.10
    # the log-linear route for a rate observable: the same line
    pr = dict(plus, potency_rate=5.0 * (1 + q + eps * R)), dict(minus, potency_rate=5.0 * (1 + q - eps * R))
    zr = pair_rate_at_zero_drift(*pr, start=1.0, observable="potency_rate")
    assert zr["s_per_L"] == pytest.approx(s0 * 0.5, rel=1e-3)
    # without a spread of the drift, or with too few samples: no intercept
    flat = np.full_like(t, 5.0)
    assert math.isnan(pair_rate_at_zero_drift(dict(plus, potency_rate=flat),
                                              dict(minus, potency_rate=flat), start=1.0)["s_per_L"])
    assert math.isnan(pair_rate_at_zero_drift(plus, minus, start=11.99)["s_per_L"])
    with pytest.raises(ValueError, match="potency_rate"):
        pair_rate_at_zero_drift({k_: v for k_, v in plus.items() if k_ != "potency_rate"}, minus,
                                start=1.0)


def test_the_pair_table_carries_the_zero_drift_rate(monkeypatch):
    """pair_table: a mode-seeded pair gets the zero-drift columns from pair_rate_at_zero_drift
    (from ZERO_DRIFT_START), relative to the eigenvalue of its row."""
    from slippulse.timedomain import perturbation as pt
    t = np.linspace(0.0, 6.0, 2401)
    s0, k, eps = 0.4, -20.0, 3e-3
    q = -2e-3 * np.expm1(0.3 * t)
    Q = -2e-3 * (np.expm1(0.3 * t) / 0.3 - t)
    R = np.exp(s0 * t + k * Q)
    series = {f: dict(_series(t, sg * 0.1 * eps * R, L=2.0, c=4.0), potency_rate=5.0 * (1 + q),
                      slip_potency=5.0 * (t + Q) + sg * eps * (R - 0.7))
              for f, sg in (("p.h5", 1.0), ("m.h5", -1.0))}
    monkeypatch.setattr(pt, "read_series", lambda f: series[f])
    base = {"steady": "f.h5", "label": "td1.0400", "perturbation": "mode_front",
            "tau_d_ratio": 1.04, "eigen_s_per_L": 0.25, "wall_time": 1.0}
    rows = [dict(base, file="p.h5", eps=eps, fate="grew"),
            dict(base, file="m.h5", eps=-eps, fate="arrested")]
    (row,) = pt.pair_table(rows)
    z = pt.pair_rate_at_zero_drift(series["p.h5"], series["m.h5"], start=pt.ZERO_DRIFT_START)
    assert row["s_per_L_zero_drift"] == z["s_per_L"] == pytest.approx(0.2, rel=1e-6)
    assert row["rel_to_eigen_zero_drift"] == pytest.approx(0.2 / 0.25 - 1)
    assert set(pt.PAIR_COLUMNS) >= {"s_per_L_zero_drift", "s_per_L_err_zero_drift"}
    (generic,) = pt.pair_table([dict(r, perturbation="excess") for r in rows])
    assert math.isnan(generic["s_per_L_zero_drift"])


def test_potency_rate_does_not_see_whole_cell_shifts():
    """A whole-cell shift of the frame permutes the periodic grid: Σ V Δx is unchanged to
    rounding (no interpolation), and it is the integral of V."""
    from types import SimpleNamespace
    from slippulse.timedomain.verify import potency_rate
    x = np.arange(4096) * 1e-3
    V = 1e-9 + np.exp(-((x - 1.3) / 0.05) ** 2) * (1 + 0.3 * np.sin(40 * x))
    a = potency_rate(SimpleNamespace(V=V, dx=1e-3))
    b = potency_rate(SimpleNamespace(V=np.roll(V, 137), dx=1e-3))
    assert a == pytest.approx(np.trapezoid(V, x), rel=1e-9)
    assert b == pytest.approx(a, rel=1e-13)


def test_case_validation_names_the_key():
    with pytest.raises(ParameterError, match="unknown case key"):
        check_case({"steady": "f.h5", "label": "td1.2000", "epsilon": 1e-3})
    with pytest.raises(ParameterError, match="eps"):
        check_case({"steady": "f.h5", "label": "td1.2000", "eps": 0.7})
    with pytest.raises(ParameterError, match="history"):
        check_case({"steady": "f.h5", "label": "td1.2000", "history": "window"})
    with pytest.raises(ParameterError, match="label"):
        check_case({"steady": "f.h5"})
    with pytest.raises(ParameterError, match="wall_limit"):
        check_case({"steady": "f.h5", "label": "td1.2000", "wall_limit": -1})


@pytest.fixture(scope="module")
def steady12(pulse12, params, tmp_path_factory):
    from slippulse.core.h5io import write_pulse
    path = str(tmp_path_factory.mktemp("st") / "fam.h5")
    write_pulse(path, pulse12.to_pulse(), params)
    return path


TINY = {"dx": 8e-3, "ahead": 1.5, "behind": 2.0, "distance": 0.5, "samples_per_L": 400,
        "xi_stab": 0.5}


@pytest.fixture(scope="module")
def pair12(steady12, tmp_path_factory):
    d = tmp_path_factory.mktemp("pair")
    rows = []
    for eps in (3e-3, -3e-3):
        case = dict(TINY, steady=steady12, label="td1.2000", eps=eps)
        out = str(d / f"eps{eps}.h5")
        rows.append(dict(case, **run_case(case, out)))
    return rows


def test_a_wall_limited_run_stops_where_it_is_and_is_written(steady12, pair12, tmp_path):
    """wall_limit: the run stops at its first measurement past the limit (seeding counted), with
    its status saying so, and its file holds the series up to there, equal to the unlimited
    run's (the same steps)."""
    case = dict(TINY, steady=steady12, label="td1.2000", eps=3e-3, wall_limit=1e-9)
    out = str(tmp_path / "w.h5")
    row = run_case(case, out)
    assert row["status"].startswith("stopped: wall limit") and row["fate"] == "undecided"
    full = read_series(pair12[0]["file"])
    s = read_series(out)
    assert 1 <= s["distance"].size < 5 and row["travelled"] < 0.05
    assert np.array_equal(s["v_max_error"], full["v_max_error"][:s["distance"].size])


def test_perturbed_pair_departs_both_ways_at_one_rate(pair12):
    plus, minus = pair12
    sp, sm = read_series(plus["file"]), read_series(minus["file"])
    # opposite signs from the start, opposite fates
    assert plus["fate"] == "grew" and minus["fate"] in ("arrested", "undecided")
    k = np.searchsorted(sp["distance"], 0.1)
    assert sp["v_max_error"][k] > 3e-3 and sm["v_max_error"][k] < -3e-3
    g = pair_growth(sp, sm, 3e-3)
    assert g["regime"] == "growth" and g["n"] >= 5
    assert 10 < g["s_per_L"] < 40           # coarse grid; converged value 24 per L (docs)
    # the single-run fits agree with the pair within their scatter
    assert plus["s_per_L"] == pytest.approx(g["s_per_L"], rel=0.3)
    # the file carries the case, completion and units
    with h5py.File(plus["file"]) as h5:
        assert h5.attrs["complete"]
        assert "eps" in h5.attrs["case_json"]
        assert h5["series/L"].attrs["units"] == "m"
        assert h5["series/deviation"].shape[1] == h5["series/deviation_xi"].size
    assert read_row(plus["file"])["fate"] == plus["fate"]
    assert len(pair_rows(pair12)) == 1


def test_tau_d_perturbation_changes_the_load_only(steady12):
    from slippulse.core.h5io import read_pulse
    from slippulse.timedomain.verify import perturb_seed
    from slippulse.timedomain.seeding import DomainSpec, seed_pulse
    pulse, params = read_pulse(steady12, "td1.2000")
    seed = seed_pulse(pulse, params, DomainSpec(dx=8e-3, ahead=1.5, behind=2.0))
    load0, V0 = np.array(seed.stepper.law.tau_load, copy=True), seed.stepper.V.copy()
    perturb_seed(seed, pulse, "tau_d", 2e-3)
    assert np.allclose(seed.stepper.law.tau_load - load0, 2e-3 * pulse.tau_d)
    assert np.array_equal(seed.stepper.V, V0)


def test_real_scan_through_dask_localcluster_resumes(steady12, tmp_path):
    """≥ 4 real perturbation runs (tiny settings) through a Dask LocalCluster; a rerun redoes none."""
    distributed = pytest.importorskip("distributed")
    from slippulse.timedomain.scan import load_scan, run_scan
    toml = tmp_path / "scan.toml"
    toml.write_text(f"""
[scan]
name = "tiny"
out_dir = "{tmp_path / 'out'}"
[defaults]
steady = "{steady12}"
label = "td1.2000"
dx = 0.016
ahead = 1.5
behind = 2.0
distance = 0.1
samples_per_L = 100
[grid]
eps = [1e-3, -1e-3, 3e-3, -3e-3]
""")
    scan = load_scan(str(toml))
    with distributed.LocalCluster(n_workers=2, threads_per_worker=1, processes=True,
                                  dashboard_address=None) as cluster, \
            distributed.Client(cluster) as client:
        res = run_scan(scan, executor=client, progress=False)
        assert res.ok and res.n_run == 4 and res.n_reused == 0
        mtimes = {p: os.path.getmtime(p) for p in (scan.out_file(c) for c in scan.cases)}
        again = run_scan(scan, executor=client, progress=False)
    assert again.n_run == 0 and again.n_reused == 4
    assert {p: os.path.getmtime(p) for p in mtimes} == mtimes
    assert os.path.exists(tmp_path / "out" / "summary.csv")
    assert os.path.exists(tmp_path / "out" / "growth_pairs.csv")
    rows = [r for r in res.rows]
    assert {round(float(r["eps"]), 6) for r in rows} == {1e-3, -1e-3, 3e-3, -3e-3}
    assert all(r["fate"] in ("grew", "arrested", "undecided") for r in rows)


@pytest.mark.slow
def test_growth_rate_at_1_2_converges_under_refinement(params, tmp_path):
    """The ±ε protocol at 1.2 τ_min, steady N = 3000: s at (Δx, ξ_s) = (2 mm, 0.5) and (1 mm, 0.25)
    agree within 5 % (docs/stability.md: 23.5 and 23.4 per L). ~4 min."""
    from slippulse.core.h5io import write_pulse
    from slippulse.steady.solver import solve_pulse
    steady = str(tmp_path / "st.h5")
    write_pulse(steady, solve_pulse(params, 1.2, n_points=3000).to_pulse(), params)
    rates = []
    for dx, xs in ((2e-3, 0.5), (1e-3, 0.25)):
        series = []
        for eps in (3e-4, -3e-4):
            case = dict(steady=steady, label="td1.2000", eps=eps, dx=dx, xi_stab=xs, ahead=2.0,
                        behind=3.0, distance=0.4, samples_per_L=400)
            out = str(tmp_path / f"r{dx}_{eps}.h5")
            run_case(case, out)
            series.append(read_series(out))
        g = pair_growth(series[0], series[1], 3e-4)
        assert g["regime"] == "growth"
        rates.append(g["s_per_L"])
    assert 20 < rates[0] < 27
    assert abs(rates[1] / rates[0] - 1) < 0.05


def test_pair_growth_refuses_a_window_shorter_than_half_an_e_fold():
    """A response that saturates (|d| > 0.03) right after its start-up jump gives no rate."""
    t = np.linspace(0, 1, 1000)
    # a start-up jump by 3 e-folds in 0.1, then growth at rate 8 that passes |d| = 0.03 after
    # 0.4 more e-folds (what a τ_d change of 1e-3 does at 1.05 τ_min)
    r = np.where(t < 0.1, 1e-3 * np.exp(30 * t), 1e-3 * np.exp(3.0) * np.exp(8 * (t - 0.1)))
    g = pair_growth(_series(t, r), _series(t, -r), 1e-3)
    assert g["regime"].startswith("too short")
    assert math.isnan(g["s_per_s"])
