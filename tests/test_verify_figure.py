"""The verify figure and summary: the unstable mode's growth rate table, the
verdict on the drift, the three-panel PNG."""
import math

import numpy as np
import pytest

from slippulse.plotting.stability import plot_verify_result
from slippulse.timedomain.verify import (DEV_POINTS, GROWTH_TOLERANCE, VerifyResult, drift_verdict,
                                    growth_rate, mode_growth, summary)


def test_mode_growth_is_the_runs_eigenvalue_at_any_tau_d():
    """No table of measured rates: the eigenvalue the run carries (verify_pulse(eigen=...)), at any
    τ_d; none when the run has none."""
    for ratio, s in ((1.2, 22.63), (1.3, 30.0), (1.037, 0.25)):
        info = {"tau_d_ratio": ratio, "eigen_s_per_L": s, "eigen_source": "stored in f.h5",
                "eigen_translation_s_per_L": -2e-3}
        sv, err, how = mode_growth(info)
        assert sv == s and err == 2e-3 and how == "eigenvalue, stored in f.h5"
    assert mode_growth({"tau_d_ratio": 1.2}) is None
    assert mode_growth({"tau_d_ratio": 1.2, "eigen_s_per_L": float("nan")}) is None


def _result(ratio, s_true, travelled=0.2, n=101, a0=4e-5, seed=0, s_eig=None):
    """A VerifyResult whose v_max error grows as a0 e^{s d} (with 1 % noise); the run carries the
    eigenvalue s_eig (default: the eigenvalue of the pulses of that τ_d, none outside 1.05-1.2)."""
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
    if s_eig is None:
        s_eig = {1.2: 22.654, 1.1: 7.995, 1.05: 0.666}.get(ratio)
    if s_eig is not None:
        info.update(eigen_s_per_L=s_eig, eigen_source="stored in test.h5",
                    eigen_translation_s_per_L=1e-6)
    errors = {"c_p_error": err[-1], "v_max_error": err[-1], "L_error": -err[-1],
              "lnv_error": err[-1]}
    return VerifyResult(t=t, x_front=d * L, series=series, errors=errors, info=info,
                        snapshots=[(t[0], x, v), (t[-1], x, v * (1 + err[-1]))], x=x)


def test_drift_verdict():
    ok, text = drift_verdict(_result(1.2, 22.9))
    assert ok is True and "consistent with the unstable mode s = 22.65 ± 1e-06 (the " \
        "translation eigenvalue's size) per L (eigenvalue, stored in test.h5)" in text
    assert "not a numerical error" in text
    # a rate far outside the band: not the mode
    bad = 22.654 * (1 + 2 * GROWTH_TOLERANCE)
    ok, text = drift_verdict(_result(1.2, bad))
    assert ok is False and "NOT consistent" in text
    # any τ_d: the eigenvalue the run carries (1.3 τ_min, outside the old table)
    ok, text = drift_verdict(_result(1.3, 30.0, s_eig=29.5))
    assert ok is True and "s = 29.5 ± 1e-06" in text
    # no eigenvalue: not attributed
    ok, text = drift_verdict(_result(1.3, 23.5))
    assert ok is None and "no eigenvalue" in text
    # at 1.05 the mode grows by e^0.13 over 0.2 L: the drift is not attributed to it
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
    # without an eigenvalue no growth line is drawn
    res.info.pop("eigen_s_per_L")
    plot_verify_result(str(png), res, _P(), _Prm())
    assert seen["lines"][2] == 1
