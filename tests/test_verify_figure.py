"""The verify figure and summary (issue 12, item 3): the unstable mode's growth rate table, the
verdict on the drift, the three-panel PNG."""
import math

import numpy as np
import pytest

from slippulse.plotting.stability import plot_verify_result
from slippulse.stability.verify import (DEV_POINTS, GROWTH_TOLERANCE, MODE_GROWTH, VerifyResult,
                                    drift_verdict, growth_rate, mode_growth, summary)


def test_mode_growth_table_and_interpolation():
    assert mode_growth(1.2) == (23.5, 0.8, "measured")
    assert mode_growth(1.1) == (8.0, 0.2, "measured")
    s, err, how = mode_growth(1.15)
    assert how == "interpolated" and 8.0 < s < 23.5
    assert s == pytest.approx(math.sqrt(8.0 * 23.5), rel=1e-12)     # linear in ln s, midpoint
    assert mode_growth(1.075)[0] == pytest.approx(math.sqrt(0.7 * 8.0), rel=1e-12)
    for r in (1.03, 1.049, 1.21, 1.5):                              # no extrapolation
        assert mode_growth(r) is None
    assert [row[0] for row in MODE_GROWTH] == sorted(row[0] for row in MODE_GROWTH)


def _result(ratio, s_true, travelled=0.2, n=101, a0=4e-5, seed=0):
    """A VerifyResult whose v_max error grows as a0 e^{s d} (with 1 % noise)."""
    rng = np.random.default_rng(seed)
    d = np.linspace(0.0, travelled, n)
    err = a0 * np.exp(s_true * d) * (1 + 0.01 * rng.standard_normal(n))
    L, c_p = 1.0, 20.0
    t = d * L / c_p
    rel = np.linspace(-1.5, 0.5, DEV_POINTS)
    dev = np.outer(err, np.exp(-((rel + 0.4) / 0.3) ** 2))
    x = np.linspace(-4, 4, 400)
    v = 1e-4 * np.exp(-x ** 2) + 1e-7
    series = {"c_p_error": err, "v_max_error": err, "L_error": -err, "lnv_error": err,
              "distance": d, "deviation": dev, "deviation_xi": rel}
    info = {"tau_d_ratio": ratio, "travelled": travelled, "status": "finished", "n_steps": 10,
            "wall_time": 1.0, "n": 400, "dx": 0.02, "L": L,
            "growth_rate_v_max": growth_rate(d, err)}
    errors = {"c_p_error": err[-1], "v_max_error": err[-1], "L_error": -err[-1],
              "lnv_error": err[-1]}
    return VerifyResult(t=t, x_front=d * L, series=series, errors=errors, info=info,
                        snapshots=[(t[0], x, v), (t[-1], x, v * (1 + err[-1]))], x=x)


def test_drift_verdict():
    ok, text = drift_verdict(_result(1.2, 23.5))
    assert ok is True and "consistent with the unstable mode s = 23.5" in text
    assert "not a numerical error" in text
    # a rate far outside the band: not the mode
    bad = 23.5 * (1 + 2 * GROWTH_TOLERANCE)
    ok, text = drift_verdict(_result(1.2, bad))
    assert ok is False and "NOT consistent" in text
    # s unknown outside 1.05-1.2
    ok, text = drift_verdict(_result(1.3, 23.5))
    assert ok is None and "no growth rate" in text
    # at 1.05 the mode grows by e^0.14 over 0.2 L: the drift is not attributed to it
    ok, text = drift_verdict(_result(1.05, 0.7))
    assert ok is None and "grows by only" in text
    assert "drift: " in summary(_result(1.2, 23.5))
    # a run lost before its third measurement is not judged
    lost = _result(1.2, 23.5, n=2)
    lost.info["status"] = "pulse lost: grew"
    ok, text = drift_verdict(lost)
    assert ok is None and "ended after 2 measurement(s) (pulse lost: grew)" in text


def test_plot_verify_result_writes_three_panels(tmp_path, monkeypatch):
    import matplotlib.figure

    res = _result(1.2, 23.5)

    class _P:                                      # the fields plot_verify_result reads
        xi = np.linspace(-4, 4, 400)
        v = 1e-4 * np.exp(-xi ** 2) + 1e-7
        L, c_p, tau_d_ratio = 1.0, 20.0, 1.2

    class _Prm:
        v_star = 1e-7

    seen = {}
    orig = matplotlib.figure.Figure.savefig

    def spy(self, *a, **k):
        seen["titles"] = [ax.get_title() for ax in self.axes]
        seen["lines"] = [len(ax.get_lines()) for ax in self.axes]
        return orig(self, *a, **k)

    monkeypatch.setattr(matplotlib.figure.Figure, "savefig", spy)
    png = tmp_path / "v.png"
    plot_verify_result(str(png), res, _P(), _Prm())
    assert png.stat().st_size > 10_000
    titles = [t for t in seen["titles"] if t]
    assert len(titles) == 3 and "drift = unstable mode" in titles[2]
    assert seen["lines"][2] == 2                    # the SBI errors and the e^{s d} line
    # outside the table no growth line is drawn
    res.info["tau_d_ratio"] = 1.3
    _P.tau_d_ratio = 1.3
    plot_verify_result(str(png), res, _P(), _Prm())
    assert seen["lines"][2] == 1
