"""Fate runs of eigenmode-seeded pulses under the uniform load (timedomain.fate,
``slippulse dynamic fate``; docs/motion.md)."""
import numpy as np
import pytest

from cli_inproc import run as cli
from slippulse.timedomain.fate import FateRule, fate_of


def _rows(L, vmax, X=None, t=None):
    n = len(L)
    t = np.arange(n, dtype=float) if t is None else t
    X = np.zeros(n) if X is None else X
    return [(t[i], X[i], L[i], vmax[i], 0.0, 0.0) for i in range(n)]


def test_the_rule_names_each_fate_at_its_threshold():
    r = FateRule()
    assert r.check(_rows([1, 1], [1.0, 0.11]), 1.0, 1.0, 10.0) is None
    assert r.check(_rows([1, 1], [1.0, 0.09]), 1.0, 1.0, 10.0) == "arrested"
    assert r.check(_rows([1, 2.9], [1, 1]), 1.0, 1.0, 10.0) is None
    assert r.check(_rows([1, 3.1], [1, 1]), 1.0, 1.0, 10.0) == "grew x3"
    X = 9.95 * np.arange(8.0)                      # c_p = 9.95 > 0.99 c_s
    assert r.check(_rows([1] * 8, [1] * 8, X=X), 1.0, 1.0, 10.0) == "near c_s"
    assert r.check(_rows([1] * 8, [1] * 8, X=9.85 * np.arange(8.0)), 1.0, 1.0, 10.0) is None
    assert FateRule(growth=10).check(_rows([1, 10.5], [1, 1]), 1.0, 1.0, 10.0) == "grew x10"
    # the rear edge X − L runs backward at 0.2 c_s (front at 0.5 c_s, L growing at 0.7 c_s)
    # while the peak grows: crack-like; not when the peak has fallen, nor at 0.05 c_s
    t = np.arange(8.0)
    grow = _rows(1 + 0.7 * t, [1.5] * 8, X=0.5 * t, t=t * 0.1)
    g = FateRule(growth=100)
    assert g.check(grow, 1.0, 1.0, 10.0) == "crack-like"
    assert g.check(_rows(1 + 0.7 * t, [0.9] * 8, X=0.5 * t, t=t * 0.1),
                   1.0, 1.0, 10.0) is None
    assert g.check(_rows(1 + 0.55 * t, [1.5] * 8, X=0.5 * t, t=t * 0.1),
                   1.0, 1.0, 10.0) is None
    assert FateRule(growth=100, backward=0).check(grow, 1.0, 1.0, 10.0) is None


def test_the_status_of_a_run_names_its_fate():
    assert fate_of("stopped: grew x3") == "grew x3"
    assert fate_of("stopped: grew x10") == "grew x10"
    assert fate_of("stopped: arrested") == "arrested"
    assert fate_of("pulse lost: grew: the FWHM ... at t = 1 s") == "crack-like"
    assert fate_of("pulse lost: arrested: max V < v_max0/1000 at t = 1 s") == "arrested"
    assert fate_of("pulse lost: grew: ln(v/v*+1) does not fall below half its maximum on both "
                   "sides: domain too short to measure the FWHM at t = 1 s") == "outgrew the domain"
    assert fate_of("finished") == "undecided"
    assert fate_of("failed: overflow").startswith("failed")


def test_command_refuses_eps_beyond_the_linear_bound(tmp_path, steady12_with_spectrum):
    out = tmp_path / "f.h5"
    r = cli(["dynamic", "fate", "--steady", steady12_with_spectrum, "--eps", "0.05",
             "--out", out, "--no-progress"])
    assert r.returncode == 2 and "eps" in r.stderr and len(r.stderr.strip().splitlines()) == 1
    assert not out.exists()


def test_command_refuses_a_pulse_without_a_stored_mode(tmp_path, pulse12, params):
    from slippulse.core.h5io import write_pulse
    src = str(tmp_path / "bare.h5")
    write_pulse(src, pulse12.to_pulse(), params)
    out = tmp_path / "f.h5"
    r = cli(["dynamic", "fate", "--steady", src, "--eps", "0.01", "--out", out, "--no-progress"])
    assert r.returncode == 2 and "spectrum" in r.stderr and len(r.stderr.strip().splitlines()) == 1
    assert not out.exists()


@pytest.mark.parametrize("eps, fates", [(1e-2, ("crack-like", "grew x3", "outgrew the domain")), (-1e-2, ("arrested",))])
def test_the_two_signs_of_the_mode_go_to_opposite_fates(tmp_path, steady12_with_spectrum, eps,
                                                        fates):
    """1.2 tau_min on a coarse grid, the steady pulse's images removed: +eps runs away, -eps
    arrests, within two pulse lengths (with the images left in, both arrest on this domain)."""
    import h5py
    out = tmp_path / "f.h5"
    r = cli(["dynamic", "fate", "--steady", steady12_with_spectrum, "--eps", eps, "--dx", "8e-3",
             "--ahead", "2", "--behind", "3", "--distance", "2", "--samples-per-L", "100",
             "--far-field", "steady",
             "--out", out, "--no-progress"])
    assert r.returncode == 0, r.stderr
    with h5py.File(out) as h5:
        assert h5.attrs["fate"] in fates
        assert 0 < h5.attrs["distance_fate"] < 2
        assert h5.attrs["far_field"] == "steady"


def test_time_law_recovers_minus_one_over_s():
    from slippulse.timedomain.fate import time_law
    eps = np.array([1e-2, 3e-3, 1e-3, 3e-4])
    a, b, e = time_law(eps, 0.01 - np.log(eps) / 400.0)
    assert b == pytest.approx(-1 / 400.0, rel=1e-10) and e < 1e-12


def test_departure_time_is_the_linear_stage_of_a_mode_growing_as_exp_st():
    """L = L0 (1 + ε e^{st}) departs by 1 % at t = ln(0.01/ε)/s (interpolated between samples):
    the departure times of several ε follow −1/s exactly."""
    from slippulse.timedomain.fate import departure_time, time_law
    s, L0 = 800.0, 2.5
    t = np.linspace(0.0, 0.02, 2001)
    eps = np.array([1e-3, 3e-4, 1e-4, 3e-5])
    dep = [departure_time(t, L0 * (1 - e * np.exp(s * t)), L0, 0.01) for e in eps]
    assert np.allclose(dep, np.log(0.01 / eps) / s, rtol=1e-3)
    a, b, err = time_law(-eps, dep)
    assert b * s == pytest.approx(-1.0, abs=1e-3)
    assert np.isnan(departure_time(t, np.full_like(t, L0), L0, 0.01))


def test_offset_law_recovers_the_seed_projection_and_the_rate():
    """Departure times of runs whose mode amplitude is ε + ε₀ (the seed's own error): the plain
    law's slope is steeper than −1/s, an ε below |ε₀| meets the other fate; the offset law
    recovers ε₀ with s fixed, and s itself when it is free."""
    from slippulse.timedomain.fate import time_law, time_law_offset
    s, e0 = 850.0, 8e-4
    eps = -np.array([1e-2, 3e-3, 1e-3, 3e-4, 2e-3])
    t = 0.005 - np.log(np.abs(eps + e0)) / s
    a, b, _ = time_law(eps[:3], t[:3])
    assert b * s < -1.3
    f = time_law_offset(eps, t, s)
    assert f["eps0"] == pytest.approx(e0, rel=1e-4) and f["rms"] < 1e-8
    assert f["a"] == pytest.approx(0.005, rel=1e-6)
    f = time_law_offset(eps, t * 1.05 - 0.005 * 0.05)         # a rate 5 % lower: s' = s/1.05
    assert f["rate"] == pytest.approx(s / 1.05, rel=1e-4) and f["eps0"] == pytest.approx(e0, rel=1e-3)
    with pytest.raises(ValueError):
        time_law_offset(eps[:3], t[:3])
