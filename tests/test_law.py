"""Power-law fits of the growth rate along a family (slippulse.spectrum.law), on data whose
law is known."""
import numpy as np
import pytest

from slippulse.spectrum.law import fit_power_law, local_exponents


def test_exact_power_law_is_recovered():
    x = np.geomspace(1e-3, 5e-2, 8)
    y = 8.8e3 * x ** 3.0
    fit = fit_power_law(x, y, 1e-3 * y)
    assert fit.n == pytest.approx(3.0, abs=1e-10) and fit.A == pytest.approx(8.8e3, rel=1e-9)
    xm, k = local_exponents(x, y)
    assert np.allclose(k, 3.0) and np.all(np.diff(xm) > 0)


def test_error_bars_cover_the_truth_and_a_bad_law_widens_them():
    rng = np.random.default_rng(3)
    x = np.geomspace(1e-3, 5e-2, 12)
    truth = 2.0 * x ** 2.5
    err = 0.02 * truth
    hits = 0
    for _ in range(200):
        y = truth * (1.0 + 0.02 * rng.standard_normal(x.size))
        f = fit_power_law(x, y, err)
        hits += abs(f.n - 2.5) < f.n_err
    assert 0.55 < hits / 200 < 0.85                     # ≈ 68 % within 1σ
    # data off the law (a kink) by far more than their error bars: χ²_red ≫ 1, and the
    # exponent's error grows by the Birge ratio
    y = np.where(x < 1e-2, truth, truth * (x / 1e-2) ** 0.5)
    bad = fit_power_law(x, y, err)
    good = fit_power_law(x, truth, err)
    assert bad.chi2_red > 10 and bad.n_err > 3 * good.n_err


def test_too_few_points_is_refused():
    with pytest.raises(ValueError, match="at least 3"):
        fit_power_law([1.0, 2.0, -1.0], [1.0, 2.0, 3.0], [0.1, 0.1, 0.1])


def test_shifted_law_finds_the_shift():
    from slippulse.spectrum.law import fit_shifted_power_law
    x = np.array([1.05, 1.04, 1.03, 1.025, 1.02, 1.015, 1.0125, 1.011])
    y = 8.8e3 * (x - 1.0077) ** 3.0
    rng = np.random.default_rng(5)
    yn = y * (1.0 + 0.01 * rng.standard_normal(x.size))
    f = fit_shifted_power_law(x, yn, 0.01 * y)
    assert abs(f.x_star - 1.0077) < 3 * f.x_star_err and f.x_star_err < 5e-4
    assert abs(f.law.n - 3.0) < 0.2
    with pytest.raises(ValueError, match="at least 4"):
        fit_shifted_power_law(x[:3], y[:3], y[:3])


def _family_with_rates(path, law, err_rel=0.01, unresolved=()):
    """A synthetic family file whose spectrum groups hold s ± s_err from `law`(τ_d/τ_min)."""
    import os
    import sys

    import h5py

    from slippulse.core import h5io
    from slippulse.core.params import DEFAULT as P
    sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
    from test_analysis import _synthetic_pulse
    ratios = [1.05, 1.04, 1.03, 1.025, 1.02, 1.015, 1.0125]
    for r in ratios:
        # β grows toward τ_min, as along the real family (the slope is taken along β)
        h5io.write_pulse(path, _synthetic_pulse(r, 0.9 - 8.0 * (r - 1.0125), 0.2 / (r - 1.0077)),
                         P)
    with h5py.File(path, "r+") as h5:
        for r in ratios:
            g = h5["pulses"][h5io.pulse_label(r)]
            sp = g.create_group("spectrum")
            unit = float(g.attrs["c_p"] / g.attrs["L"])
            y = law(r)
            e = (3.0 if r in unresolved else err_rel) * abs(y)
            sp.attrs.update(status="converged", s=y * unit, s_err=e * unit, s_per_L=y,
                            s_err_per_L=e, sign_resolved=int(abs(y) >= 2 * e))
    return ratios


def test_rates_command_fits_the_stored_law_and_draws_it(tmp_path):
    import subprocess
    import sys

    from slippulse.spectrum.law import family_rates, fit_shifted_power_law
    f = str(tmp_path / "fam.h5")
    _family_with_rates(f, lambda r: 8.8e3 * (r - 1.0077) ** 3, unresolved=(1.0125,))
    rates = family_rates(f)
    assert rates["tau_d_ratio"].size == 7 and rates["sign_resolved"].sum() == 6
    ok = rates["sign_resolved"] == 1
    fit = fit_shifted_power_law(rates["tau_d_ratio"][ok], rates["s_per_L"][ok],
                                rates["s_err_per_L"][ok], lo=1.0)
    assert abs(fit.x_star - 1.0077) < 1e-6 and abs(fit.law.n - 3.0) < 1e-6
    png = tmp_path / "rates.png"
    r = subprocess.run([sys.executable, "-m", "slippulse.cli", "steady", "rates", f, "--figure",
                        str(png)], capture_output=True, text=True)
    assert r.returncode == 0, r.stderr
    from matplotlib.image import imread
    img = imread(str(png))
    assert img.shape[1] > 1000 and img[..., :3].std() > 0.05      # drawn, not blank


def test_rates_command_refuses_a_file_without_rates(tmp_path):
    import sys

    from slippulse.core import h5io
    from slippulse.core.params import DEFAULT as P
    sys.path.insert(0, __import__("os").path.dirname(__import__("os").path.abspath(__file__)))
    from test_analysis import _synthetic_pulse
    f = str(tmp_path / "fam.h5")
    h5io.write_pulse(f, _synthetic_pulse(1.05, 0.5, 1.0), P)
    import cli_inproc
    r = cli_inproc.run(["steady", "rates", f])
    assert r.returncode == 2 and "no growth rate" in r.stderr and "Traceback" not in r.stderr
    r = cli_inproc.run(["steady", "rates", f, "--below", "0.5"])
    assert r.returncode == 2 and "below=" in r.stderr and "Traceback" not in r.stderr


def test_shifted_fit_gives_a_nonzero_error_when_the_profile_is_narrower_than_its_grid():
    """With errors of 1e-6 (the deep rates' s_err are ~1e-3 of s) the χ² profile over x* is far
    narrower than the grid's spacing; the error of x* is still located (it was 0 before)."""
    from slippulse.spectrum.law import fit_shifted_power_law
    x = np.linspace(1.0092, 1.0115, 9)
    rng = np.random.default_rng(3)
    y = 1.5e3 * (x - 1.0067) ** 2.66 * (1 + 1e-6 * rng.normal(size=x.size))
    sh = fit_shifted_power_law(x, y, 1e-6 * y, lo=1.0)
    assert abs(sh.x_star - 1.0067) < 5 * sh.x_star_err
    assert 0 < sh.x_star_err < 1e-5


# ------------------------------------------------------------- the family's slope and folds
def _deep_family(n=40):
    """A family with β → 1: 1 − β = 0.3 L^−0.8, τ_d/τ_min = 1.0075 + 0.3 L^−0.4 (L in m), so
    dτ_d/d ln L = −0.12 L^−0.4."""
    L = np.geomspace(10.0, 4000.0, n)
    return 1.0075 + 0.3 * L ** -0.4, L, 1.0 - 0.3 * L ** -0.8


def test_family_slope_recovers_an_exact_law_with_a_covering_error():
    from slippulse.spectrum.law import family_slope
    tau, L, beta = _deep_family()
    exact = -0.12 * L ** -0.4
    g, e = family_slope(tau, L, beta)
    assert np.all(np.abs(g - exact) <= e + 1e-15)
    assert np.max(np.abs(g / exact - 1.0)) < 1e-4
    # the order of the pulses does not matter
    k = np.random.default_rng(2).permutation(L.size)
    g2, _ = family_slope(tau[k], L[k], beta[k])
    assert np.allclose(g2, g[k], rtol=1e-12)
    # without β (pulses known by τ_d and L alone) the parameter is ln L: the same slope
    g3, e3 = family_slope(tau, L)
    assert np.all(np.abs(g3 - exact) <= e3 + 1e-15) and np.max(np.abs(g3 / exact - 1.0)) < 1e-4
    # queried by L between the pulses, and outside the family's range: nan
    q = np.array([5.0, 123.4, 4000.0, 4001.0])
    g, e = family_slope(tau, L, beta, at_L=q)
    assert np.isnan(g[0]) and np.isnan(g[3]) and np.isnan(e[0])
    assert np.all(np.abs(g[1:3] - (-0.12 * q[1:3] ** -0.4)) <= e[1:3] + 1e-15)
    # a slope of the wrong sign or size would not be covered: the bar is small (one-sided at
    # the last pulse, hence larger there)
    assert np.all(e[1:3] < 3e-3 * np.abs(g[1:3]))


def test_family_slope_where_the_length_turns():
    """Above 1.3 τ_min the default family's L has a minimum while β keeps falling: the slope is
    taken along β, is infinite at the turn, and a query by L there is refused (nan)."""
    from slippulse.spectrum.law import family_slope
    beta = np.geomspace(1e-4, 1e-3, 41)
    u = np.log(beta / (1.0 - beta))
    lnL = (u - u[20]) ** 2                               # minimum of L at pulse 20
    tau = 1.3 - 0.01 * (u - u[0])                         # τ_d monotone in β: no fold
    g, e = family_slope(tau, np.exp(lnL), beta)
    with np.errstate(divide="ignore"):
        exact = -0.01 / (2.0 * (u - u[20]))
    fin = np.abs(u - u[20]) > 0.3
    assert np.all(np.abs(g[fin] - exact[fin]) <= e[fin] + 1e-12 * np.abs(exact[fin]))
    assert abs(g[20]) > 1e6 * np.abs(exact[fin]).max() or not np.isfinite(g[20])
    gL, _ = family_slope(tau, np.exp(lnL), beta, at_L=[np.exp(lnL[5])])
    assert np.isnan(gL[0])


def test_folds_are_found_where_tau_d_turns_and_only_there():
    from slippulse.spectrum.law import folds
    tau, L, beta = _deep_family()
    assert folds(tau, beta) == []
    turned = tau.copy()
    turned[25:] = 2.0 * tau[24] - tau[25:]               # τ_d rises again beyond pulse 24
    f = folds(turned, beta)
    assert len(f) == 1 and f[0][0] < beta[24] < f[0][1]
    # the order of the pulses in the input does not matter
    k = np.random.default_rng(1).permutation(L.size)
    assert folds(turned[k], beta[k]) == f
    # a turn of L alone (τ_d monotone in β) is not a fold
    u = np.log(beta / (1.0 - beta))
    assert folds(1.3 - 0.01 * u, beta) == []


def test_fold_ratio_of_rates_proportional_to_the_slope():
    from slippulse.spectrum.law import fold_ratio
    slope = np.array([-2e-3, -5e-4, -1e-4])
    R, e = fold_ratio(0.3 * np.abs(slope), 0.003 * np.abs(slope), slope, 0.02 * np.abs(slope))
    assert np.allclose(R, 0.3) and np.allclose(e, 0.3 * np.hypot(0.01, 0.02))


def test_rates_command_gives_the_slope_the_ratio_and_no_fold(tmp_path):
    """The synthetic family has L = 0.2/(τ_d/τ_min − 1.0077), so dτ_d/d ln L = −(τ_d/τ_min −
    1.0077), and s L/c_p = 8.8e3 (τ_d/τ_min − 1.0077)³: R = 8.8e3 (τ_d/τ_min − 1.0077)²."""
    import re
    import subprocess
    import sys
    f = str(tmp_path / "fam.h5")
    ratios = _family_with_rates(f, lambda r: 8.8e3 * (r - 1.0077) ** 3)
    r = subprocess.run([sys.executable, "-m", "slippulse.cli", "steady", "rates", f],
                       capture_output=True, text=True)
    assert r.returncode == 0, r.stderr
    seen = 0
    for q in ratios:
        m = re.search(rf"td{q:.4f}: .*d tau_d/d ln L = (\S+) ± (\S+), R = (\S+) ± (\S+)",
                      r.stdout)
        assert m, r.stdout
        g, ge, R, Re = (float(v) for v in m.groups())
        assert abs(g + (q - 1.0077)) <= ge + 1e-4 * abs(g)
        assert abs(R - 8.8e3 * (q - 1.0077) ** 2) <= Re + 1e-3 * R
        seen += 1
    assert seen == len(ratios)
    assert "family: no fold" in r.stdout
    assert "no fold of tau_d along the family" in r.stdout.splitlines()[-1]
    assert "R = s L/c_p / |d tau_d/d ln L|" in r.stdout      # its law is fitted


def test_windowed_exponents_follow_a_curving_law_with_covering_errors():
    """Dense data (0.2 % apart) with 1 % noise on a law whose exponent runs from -1.0 to -0.5:
    each window's slope within 3 of its error of the local exponent at its centre, the windows
    disjoint, ordered and covering every point; neighbour differences are useless there."""
    from slippulse.spectrum.law import windowed_exponents
    rng = np.random.default_rng(11)
    L = np.exp(np.arange(np.log(400.0), np.log(6700.0), 0.002))
    a0, a1 = -1.0, -0.5                    # exponent linear in ln L between the ends
    u = (np.log(L) - np.log(L[0])) / (np.log(L[-1]) - np.log(L[0]))
    span = np.log(L[-1]) - np.log(L[0])
    lny = a0 * (np.log(L) - np.log(L[0])) + 0.5 * (a1 - a0) * span * u ** 2
    y = np.exp(lny) * (1.0 + 0.01 * rng.standard_normal(L.size))
    xm, k, ke, n = windowed_exponents(L, y, 0.01 * np.abs(y))
    assert n.sum() == L.size and np.all(np.diff(xm) > 0) and np.all(n >= 3)
    um = (np.log(xm) - np.log(L[0])) / span
    truth = a0 + (a1 - a0) * um
    assert np.all(np.abs(k - truth) < 3.0 * ke + 0.01)
    # 1 % over 50 points spread over 0.1 in ln L: 0.01/(√50 · 0.1/√12) = 0.049
    assert np.all(ke < 0.08) and len(xm) >= 25
    _, kn = local_exponents(L, y)
    assert np.std(kn) > 3.0                                      # why windows are needed
