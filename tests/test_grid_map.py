"""The smooth grid map (slippulse.steady.grid.GridMap) and the three-level error estimate of the
leading growth rate (slippulse.stability.refine.estimate), on inputs whose answers are known."""
import math

import numpy as np
import pytest

from slippulse.stability.refine import LEVEL_RATIO, SAFETY, estimate, level_points
from slippulse.steady.grid import GridMap


def _rough_grid():
    """A grid like the solver's adapted ones: spacing from 5 down to ~2e-3 at two dense spots
    (cells 250 and 400), with neighbouring cells differing at random by up to ≈ 20 %."""
    k = np.arange(599)
    lnh = (math.log(5.0) - 6.0 * np.exp(-((k - 250) / 40.0) ** 2)
           - 8.0 * np.exp(-((k - 400) / 40.0) ** 2))
    rng = np.random.default_rng(1)
    h = np.exp(lnh) * (1.0 + 0.2 * (rng.random(k.size) - 0.5))
    return np.concatenate([[0.0], np.cumsum(h)]) - 100.0


def test_width_zero_reproduces_the_grid_and_the_ends_are_kept():
    xi = _rough_grid()
    assert np.allclose(GridMap(xi, width=0.0)(xi.size), xi, rtol=0, atol=1e-9 * np.ptp(xi))
    g = GridMap(xi)(2 * xi.size)
    assert g[0] == xi[0] and g[-1] == xi[-1] and np.all(np.diff(g) > 0)


def test_mapped_grids_are_smooth_and_keep_the_resolution_where_it_was():
    xi = _rough_grid()
    h0 = np.diff(xi)
    jump0 = np.max(np.abs(np.diff(np.log(h0), 2)))   # roughness: Δ² ln h
    assert jump0 > 0.15                                 # the source is rough
    gmap = GridMap(xi)
    jumps = []
    for n in (1200, 2400, 4800):
        x = gmap(n)
        jumps.append(np.max(np.abs(np.diff(np.log(np.diff(x)), 2))))
        # resolution stays where the source had it: the finest cell is where the source's
        # was (within a few source cells), and as fine (×600/n) within the smoothing
        k0, k1 = np.argmin(h0), np.argmin(np.diff(x))
        assert abs(x[k1] - xi[k0]) < 5 * np.max(h0[k0 - 5:k0 + 5])
        assert 0.5 < np.diff(x)[k1] * n / 600 / h0[k0] < 2.0
    assert jumps[0] < 0.1 * jump0
    # the spacing of a smooth map is smooth: Δ² ln h falls as 1/n², ÷4 per doubling of n (measured ÷3.2, ÷3.5)
    assert jumps[1] < 0.4 * jumps[0] and jumps[2] < 0.4 * jumps[1]


def test_grid_map_refuses_bad_grids():
    with pytest.raises(ValueError, match="ascending"):
        GridMap(np.array([0.0, 1.0, 1.0, 2.0, 3.0]))
    with pytest.raises(ValueError, match="at least 4"):
        GridMap(np.array([0.0, 1.0, 2.0]))
    with pytest.raises(ValueError, match="width"):
        GridMap(np.linspace(0, 1, 10), width=-1.0)


def test_level_points_grow_by_sqrt2():
    assert level_points(2000, 2) == [2000, 2828, 4000]


@pytest.mark.parametrize("p", [2.0, 4.0, 6.0])
def test_three_level_estimate_recovers_the_order_and_covers_the_limit(p):
    s_inf, c = 0.0179, 0.3
    s = [s_inf + c * LEVEL_RATIO ** (-p * k) / 50 for k in range(3)]
    val, err, order, rule = estimate(s)
    assert rule == "three-level" and order == pytest.approx(p, rel=1e-9)
    assert val == s[-1]
    d2 = s[-1] - s[-2]
    # the band is the Richardson correction times the factor of safety, and covers the limit
    assert err == pytest.approx(SAFETY * abs(d2) / (LEVEL_RATIO ** p - 1.0), rel=1e-12)
    assert abs(val - s_inf) < err < 1.3 * abs(val - s_inf)


def test_estimate_falls_back_to_the_last_correction_without_an_observed_order():
    # corrections of opposite sign (the nested sequence at 1.05 τ_min: 0.7101, 0.6563, 0.6653)
    val, err, order, rule = estimate([0.7101, 0.6563, 0.6653])
    assert rule == "last correction" and math.isnan(order)
    assert val == 0.6653 and err == pytest.approx(0.009, abs=1e-12)
    # two levels
    assert estimate([1.0, 1.1])[3] == "last correction"
    assert estimate([1.0, 1.1])[1] == pytest.approx(0.1)
    # growing corrections (not converging)
    assert estimate([1.0, 1.1, 1.3])[3] == "last correction"
    # an order above 8 (a last correction that is small by coincidence) is not trusted
    assert estimate([1.0, 1.1, 1.1 + 0.1 / 2 ** 5])[3] == "last correction"
    with pytest.raises(ValueError):
        estimate([1.0])
