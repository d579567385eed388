"""Seeding the SBI with a steady pulse (slippulse.timedomain.seeding, docs/dynamic.md §3): the t = 0 state.

Measured at τ_d = 1.2 τ_min, domain 4 L ahead + 4 L behind (λ = 8.6 L), Δx = 2 mm:
* far field added (default): max|τ_SBI(0) − τ_steady|/τ_d over ξ − ξ_front ∈ [−2 L, 1 L] is
  4.5e-5 from the N = 1500 steady solution, 5.6e-4 from N = 700, 1e-6 from N = 3000 (the remainder is
  the steady solution's own discretisation error at the leading edge; it does not depend on Δx);
* bare periodic domain: the images of the pulse add a linear stress of slope −1.333e-3 τ_d per L
  (prediction (π/6)√(1−β²) μΔδ L/(λ² τ_d) = 1.329e-3; 3.33e-4 at λ = 17 L: ∝ 1/λ²);
* a wrap dislocation left in adds −(μΔδ/2λ)cot(π(x − x_w)/λ), reproduced to 7e-4 (relative to its
  maximum over the window, 1.0e-2 τ_d): 4× the image error, ~200× the seeded error.
"""
import math

import numpy as np
import pytest

from slippulse.core.h5io import read_pulse, write_pulse
from slippulse.timedomain.seeding import (DomainSpec, dislocated_slip, follow_pulse, interpolate_log,
                               periodic_slip, seed_from_file, seed_pulse, stress_mismatch)
from slippulse.dynamics.sbi import elastic_functional


@pytest.fixture(scope="module")
def pulse1500(params):
    from slippulse.steady.solver import solve_pulse
    return solve_pulse(params, 1.2, n_points=1500).to_pulse()


def test_t0_stress_equals_steady_stress(pulse1500, pulse12, params):
    s = seed_pulse(pulse1500, params, DomainSpec(dx=2e-3))
    m = stress_mismatch(s)
    assert m["stress"] < 1e-4                      # measured 4.5e-5
    # the friction law holds on the seeded state: τ_SBI(0) = σ f(V, φ) to the same level
    assert m["friction"] < 1e-4
    # the remainder is the steady solution's discretisation: coarser steady grid, larger error
    coarse = stress_mismatch(seed_pulse(pulse12.to_pulse(), params, DomainSpec(dx=2e-3)))
    assert coarse["stress"] > 3 * m["stress"]      # measured 5.6e-4 vs 4.5e-5


def test_images_of_the_periodic_domain_match_the_cot_expansion(pulse1500, params):
    """Without the far-field load the pulse feels its images: a stress gradient ∝ μΔδ/λ²."""
    slopes = []
    for a in (4.0, 8.0):
        s = seed_pulse(pulse1500, params, DomainSpec(dx=2e-3, ahead=a, behind=a), far_field="none")
        st, pu = s.stepper, s.pulse
        rel = (st.x - s.x_front0) / pu.L
        d = (st.tau - s.tau_steady) / pu.tau_d
        w = (rel > -1) & (rel < 0.5)
        slope = np.polyfit(rel[w], d[w], 1)[0]
        pred = -math.pi / 6 * math.sqrt(1 - pu.beta ** 2) * params.mu * s.net_slip \
            / st.length ** 2 * pu.L / pu.tau_d
        assert slope == pytest.approx(pred, rel=0.02)
        slopes.append(slope)
    assert slopes[0] / slopes[1] == pytest.approx(4.0, rel=0.03)   # λ doubled


def test_no_wrap_dislocation(pulse1500, params):
    """The periodic slip carries no dislocation; a jump left in at the wrap loads the pulse with
    exactly the screw-dislocation stress −(μΔδ/2λ) cot(π(x − x_w)/λ)."""
    spec = DomainSpec(dx=2e-3)
    good = seed_pulse(pulse1500, params, spec, far_field="none")
    bad = seed_pulse(pulse1500, params, spec, far_field="none", wrap_dislocation=True)
    st = good.stepper
    lam, xw = st.length, -0.5 * st.dx
    rel = (st.x - good.x_front0) / good.pulse.L
    w = (rel > -2) & (rel < 1)
    analytic = -(params.mu * good.net_slip / (2 * lam)) / np.tan(math.pi * (st.x - xw) / lam)
    diff = bad.stepper.tau - st.tau
    assert np.abs(diff - analytic)[w].max() < 5e-3 * np.abs(analytic[w]).max()   # measured 7e-4
    seeded = stress_mismatch(seed_pulse(pulse1500, params, spec))["stress"]
    assert stress_mismatch(bad)["stress"] > 50 * seeded
    assert stress_mismatch(bad)["stress"] > 2 * stress_mismatch(good)["stress"]


def test_periodic_slip_is_the_isolated_slip_plus_a_uniform_gradient():
    """−cδ' = V − ⟨V⟩: δ minus δ_∞ (cumulative integral of V − v_stick) is linear in x."""
    n, lam, c, v_stick = 512, 10.0, 3.0, 1e-3
    x = np.arange(n) * lam / n
    V = v_stick + np.exp(-((x - 5.0) / 0.4) ** 2)
    d = periodic_slip(V, lam / n, c)
    # δ_∞ exactly: (1/c)∫_x^∞ e^{−((z−5)/0.4)²} dz
    from scipy.special import erfc
    d_inf = 0.4 * math.sqrt(math.pi) / 2 * erfc((x - 5.0) / 0.4) / c
    resid = d - d_inf                    # δ = δ_∞ + (Δδ/λ) x + const
    fit = np.polyfit(x, resid, 1)
    assert fit[0] == pytest.approx(0.4 * math.sqrt(math.pi) / c / lam, rel=1e-6)   # Δδ/λ
    assert np.abs(resid - np.polyval(fit, x)).max() < 1e-9
    # the isolated slip on the period (jump at the wrap) differs from δ by the sawtooth only
    dd = dislocated_slip(V, lam / n, c, v_stick) - d
    assert np.ptp(np.diff(dd)) < 1e-12


def test_interpolation_keeps_v_positive_and_monotone():
    xs = np.array([0.0, 1.0, 1.1, 3.0])
    vs = np.array([1e-7, 1e-3, 1e-7, 1e-7])
    xn = np.linspace(0, 3, 301)
    v = interpolate_log(xs, vs, xn)
    assert np.all(v > 0) and v.max() <= 1e-3 * (1 + 1e-12) and v.min() >= 1e-7 * (1 - 1e-12)


def test_follow_pulse_is_an_exact_relabelling(pulse1500, params):
    """A whole-cell shift rotates δ_k, V_k and the SOE accumulators: the stress recomputed from
    them is the shifted stress (except at the reset cells)."""
    s = seed_pulse(pulse1500, params, DomainSpec(dx=4e-3), far_field="none")
    st = s.stepper

    def stress():
        f = st.fft.inverse(elastic_functional(params.mu, st.kabs, st.delta_k, st.history.value()))
        return st.law.tau_load - st.eta * st.V + f

    t0 = stress()
    m = follow_pulse(s, s.x_front0 + 7.5 * st.dx)
    assert m == 7
    d = np.abs(stress() - np.roll(t0, -m))[: -m - 50]
    assert d.max() < 1e-9 * params.sigma


def test_slip_potency_is_the_stepped_integral_of_the_potency_rate(pulse12, params):
    """Σ δ Δx (``slip_potency``) grows by the time integral of Σ V Δx as the scheme steps it
    (trapezoid of the step's end values, to O(Δt²)), and a frame roll permutes δ and keeps it."""
    s = seed_pulse(pulse12.to_pulse(), params, DomainSpec(dx=8e-3, ahead=2.0, behind=2.0))
    st = s.stepper
    S0, integral = st.slip_potency(), 0.0
    for _ in range(40):
        p0 = float(np.sum(st.V)) * st.dx
        dt = st.step()
        integral += 0.5 * dt * (p0 + float(np.sum(st.V)) * st.dx)
    assert st.slip_potency() - S0 == pytest.approx(integral, rel=1e-3)
    assert abs(st.slip_potency() - S0 - integral) > 0     # a different quadrature, not the same sum
    S1 = st.slip_potency()
    follow_pulse(s, s.x_front0 + 5.5 * st.dx)
    assert st.slip_potency() == pytest.approx(S1, rel=1e-13)


def test_seed_from_file_round_trip(tmp_path, pulse12, params):
    path = str(tmp_path / "fam.h5")
    pu = pulse12.to_pulse()
    write_pulse(path, pu, params)
    s = seed_from_file(path, pu.label, spec=DomainSpec(dx=4e-3))
    p2, _ = read_pulse(path, pu.label)
    assert s.pulse.c_p == p2.c_p
    assert s.stepper.law.tau_load.shape == (s.stepper.n,)


def test_verify_cli_writes_errors_series_and_figure(tmp_path, pulse12, params, capsys,
                                                    steady12_with_spectrum):
    """`slippulse dynamic verify`: HDF5 attributes + time series, PNG beside it, one-line summary
    (the pulse's spectrum stored in its file: the verdict's eigenvalue is read, not computed)."""
    import h5py

    from slippulse.cli.app import main
    src = steady12_with_spectrum
    pu = pulse12.to_pulse()
    out = str(tmp_path / "v.h5")
    rc = main(["dynamic", "verify", "--steady", src, "--label", pu.label, "--distance", "0.01",
               "--dx", "4e-3", "--samples", "4", "--out", out, "--no-progress"])
    assert rc == 0
    line = capsys.readouterr().out.strip().splitlines()[-1]
    assert line.startswith("verify td1.2000: finished") and "lnv_error=" in line
    with h5py.File(out, "r") as h5:
        for key in ("c_p_error", "v_max_error", "L_error", "lnv_error"):
            assert np.isfinite(h5.attrs[key])
            assert h5["series"][key].shape == (5,)
        assert h5.attrs["travelled"] > 0.009
    assert (tmp_path / "v.png").stat().st_size > 1000
    # an existing output is not replaced without --overwrite
    assert main(["dynamic", "verify", "--steady", src, "--distance", "0.01", "--out", out]) == 2
    assert "exists" in capsys.readouterr().err


def test_quasi_dynamic_seed_has_static_stress_plus_radiation_damping(pulse12, params):
    """The quasi-dynamic policy (no history) on a translating profile: τ_QD − τ_full is
    F⁻¹[(−η − iμ sgn k/(2c_p) + iπμF_III(β) sgn k) V_k] for k ≠ 0 (docs/dynamic.md §1: the full
    kernel gives −iπμF_III sgn k V_k, static elasticity −(μ|k|/2)δ_k with δ_k = iV_k/(kc_p),
    plus the damping −ηV_k the full operator already contains)."""
    pu = pulse12.to_pulse()
    spec = DomainSpec(dx=8e-3, ahead=2.0, behind=2.0)
    full = seed_pulse(pu, params, spec, far_field="none")
    qd = seed_pulse(pu, params, spec, far_field="none", history="quasi_dynamic")
    st = full.stepper
    assert np.array_equal(st.V, qd.stepper.V)
    sgn = np.sign(st.kabs)
    mult = (-st.eta - 1j * params.mu * sgn / (2 * pu.c_p)
            + 1j * math.pi * params.mu * float(params.F3(pu.beta)) * sgn)
    mult[0] = 0.0
    want = np.fft.irfft(mult * np.fft.rfft(st.V), st.n)
    got = qd.stepper.tau - full.stepper.tau
    # to the accuracy of the full run's SOE history (36-node set, kernel integral error ≤ 2e-5;
    # measured 1.7e-5); a sign error in either operator would give O(1)
    assert np.max(np.abs(got - want)) < 1e-4 * np.max(np.abs(want))
    assert qd.stepper.history.nbytes == 0


def test_seed_cli_writes_state_and_mismatch(tmp_path, pulse12, params, capsys):
    from slippulse.cli.app import main
    src = str(tmp_path / "fam.h5")
    write_pulse(src, pulse12.to_pulse(), params)
    out = str(tmp_path / "seed.h5")
    assert main(["dynamic", "seed", "--steady", src, "--dx", "8e-3", "--ahead", "2",
                 "--behind", "2", "--out", out]) == 0
    line = capsys.readouterr().out
    assert "stress vs steady" in line
    import h5py
    with h5py.File(out) as h5:
        assert h5["V"].attrs["units"] == "m/s" and h5["tau"].attrs["units"] == "Pa"
        assert h5["x"].size == h5.attrs["n"]
        mis = np.max(np.abs(h5["tau"][...] - h5["tau_steady"][...])) / pulse12.to_pulse().tau_d
        assert h5.attrs["stress_mismatch_all"] == pytest.approx(mis, rel=1e-12)
        assert h5.attrs["stress_mismatch"] < 5e-3
    # refuses to overwrite, names the option
    assert main(["dynamic", "seed", "--steady", src, "--out", out]) == 2
    assert "--overwrite" in capsys.readouterr().err
