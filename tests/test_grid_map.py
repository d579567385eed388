"""The smooth grid map (slippulse.steady.grid.GridMap) and the three-level error estimate of the
leading growth rate (slippulse.spectrum.refine.estimate), on inputs whose answers are known."""
import math

import numpy as np
import pytest

from slippulse.spectrum.refine import LEVEL_RATIO, SAFETY, estimate, level_points
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
    # the band is the Richardson correction (at an order no larger than the formal 4) times the
    # factor of safety, and covers the limit
    q = min(p, 4.0)
    assert err == pytest.approx(SAFETY * abs(d2) / (LEVEL_RATIO ** q - 1.0), rel=1e-12)
    assert abs(val - s_inf) < err
    if p <= 4.0:
        assert err < 1.3 * abs(val - s_inf)


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


def _fake_ladder(monkeypatch, s_inf, c, p):
    """refine_leading on stubs: level k of N points gives s = s_inf + c (N/1000)^−p (c/L = 1)."""
    from types import SimpleNamespace as NS

    import slippulse.spectrum.refine as refine

    def pulse(n):
        return NS(n_points=n, c_p=1.0, L=1.0, xi=np.linspace(0, 1, n))

    def mapped(params, p_, gmap, n, **kw):
        return NS(stats=NS(converged=True, message="ok"), problem=NS(n=n),
                  to_pulse=lambda: pulse(n))

    def spectrum(q, params, guesses=(), **kw):
        s = s_inf + c * (q.n_points / 1000.0) ** (-p)
        return NS(status="converged", sigmas=np.array([s + 0j]), leading=complex(s),
                  rate_unit=1.0, modes=[{"V": np.ones(q.n_points, complex)}],
                  neutral=np.zeros(2), message="")

    monkeypatch.setattr(refine, "mapped_pulse", mapped)
    monkeypatch.setattr(refine, "pulse_spectrum", spectrum)
    s0 = s_inf + c
    first = NS(leading=complex(s0), rate_unit=1.0, n_points=1000, neutral=np.zeros(2),
               modes=[{"V": np.ones(1000, complex)}])
    return refine, pulse(1000), first


def test_ladder_climbs_until_the_target_is_met(monkeypatch):
    refine, p0, first = _fake_ladder(monkeypatch, 0.0179, 0.08, 4.0)
    r = refine.refine_leading(p0, None, first, None, refine.Ladder(2, target=1e-4))
    assert r.status == "converged" and r.target_met and r.rule == "three-level"
    assert r.s_err <= 1e-4 and len(r.n_points) > 3
    # one level fewer would not have met it: the ladder stopped at the first level that did
    s_prev, e_prev, _, _ = estimate(r.s_levels[:-1])
    assert e_prev > 1e-4
    assert abs(r.s - 0.0179) < r.s_err


def test_ladder_says_when_the_target_is_out_of_reach(monkeypatch):
    refine, p0, first = _fake_ladder(monkeypatch, 0.0179, 0.08, 4.0)
    r = refine.refine_leading(p0, None, first, None,
                              refine.Ladder(2, target=1e-12, max_points=3000))
    assert r.status == "converged" and not r.target_met
    assert r.n_points == [1000, 1414, 2000, 2828] and "not reached" in r.message
    r = refine.refine_leading(p0, None, first, None, refine.Ladder(2))       # no target: fixed levels
    assert r.n_points == [1000, 1414, 2000] and r.target_met


def test_tracking_is_seeded_from_the_nearest_stored_spectrum_above(tmp_path):
    """A run on deep pulses only (whose rates are below the default search's MIN_RE) starts
    from the stored eigenvalue and mode of the nearest pulse above them."""
    import os
    import sys

    from slippulse.core import h5io
    from slippulse.core.params import DEFAULT as P
    from slippulse.spectrum.pulse import PulseSpectrum, write_spectrum
    from slippulse.spectrum.family import NO_TRACKING, seed_tracking
    sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
    from test_analysis import _synthetic_pulse
    f = str(tmp_path / "fam.h5")
    for r in (1.2, 1.1, 1.05):
        h5io.write_pulse(f, _synthetic_pulse(r, 0.3, 0.2), P)
    assert seed_tracking(f, ["td1.1000"]) is NO_TRACKING  # nothing stored above
    p = h5io.read_pulse(f, "td1.2000")[0]
    V = np.exp(-((p.xi / p.L) ** 2)) + 0j
    modes = [{k: V for k in ("delta", "V", "phi", "lnv")}]
    write_spectrum(f, PulseSpectrum("td1.2000", np.array([7.0 + 0j]), modes, np.zeros(2), 0.0,
                                    2.0, p.n_points, "converged", "", 0.0), {})
    tr = seed_tracking(f, ["td1.0500"])                   # the nearest stored one above
    assert tr.sigmas[0] == 7.0 and tr.rate_unit == 2.0
    assert np.allclose(tr.mode[0], p.xi / p.L) and np.allclose(tr.mode[1], V)
