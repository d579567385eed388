"""Power-law fits of the growth rate along a family (slippulse.stability.law), on data whose
law is known."""
import numpy as np
import pytest

from slippulse.stability.law import fit_power_law, local_exponents


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
    from slippulse.stability.law import fit_shifted_power_law
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
        h5io.write_pulse(path, _synthetic_pulse(r, 0.5, 0.2 / (r - 1.0077)), P)
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

    from slippulse.stability.law import family_rates, fit_shifted_power_law
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
    import subprocess
    import sys

    from slippulse.core import h5io
    from slippulse.core.params import DEFAULT as P
    sys.path.insert(0, __import__("os").path.dirname(__import__("os").path.abspath(__file__)))
    from test_analysis import _synthetic_pulse
    f = str(tmp_path / "fam.h5")
    h5io.write_pulse(f, _synthetic_pulse(1.05, 0.5, 1.0), P)
    r = subprocess.run([sys.executable, "-m", "slippulse.cli", "steady", "rates", f],
                       capture_output=True, text=True)
    assert r.returncode == 2 and "no growth rate" in r.stderr and "Traceback" not in r.stderr
    r = subprocess.run([sys.executable, "-m", "slippulse.cli", "steady", "rates", f, "--below",
                        "0.5"], capture_output=True, text=True)
    assert r.returncode == 2 and "below=" in r.stderr and "Traceback" not in r.stderr


def test_shifted_fit_gives_a_nonzero_error_when_the_profile_is_narrower_than_its_grid():
    """With errors of 1e-6 (the deep rates' s_err are ~1e-3 of s) the χ² profile over x* is far
    narrower than the grid's spacing; the error of x* is still located (it was 0 before)."""
    from slippulse.stability.law import fit_shifted_power_law
    x = np.linspace(1.0092, 1.0115, 9)
    rng = np.random.default_rng(3)
    y = 1.5e3 * (x - 1.0067) ** 2.66 * (1 + 1e-6 * rng.normal(size=x.size))
    sh = fit_shifted_power_law(x, y, 1e-6 * y, lo=1.0)
    assert abs(sh.x_star - 1.0067) < 5 * sh.x_star_err
    assert 0 < sh.x_star_err < 1e-5
