"""The unstable eigenmode in time — its SBI seed with a growing past, the refusals, the
verdict's eigenvalue, the front frame and the overlap with the family tangent."""
import dataclasses
import math

import h5py
import numpy as np
import pytest

from slippulse.core import friction as fr
from slippulse.core.h5io import write_pulse
from slippulse.timedomain.eigenmode import (EPS_MAX, Eigenmode, SpectrumError, check_same_pulse,
                                           front_response, leading_mode, mode_overlap,
                                           mode_on_grid, perturb_along_mode, pulse_overlap,
                                           stored_mode)
from slippulse.timedomain.seeding import DomainSpec, seed_pulse


def _imbalance(seed, params):
    st = seed.stepper
    return st.tau - params.sigma * fr.f(st.V, st.phi, *params.law_args)


def test_stored_mode_is_read_and_matches_its_pulse(steady12_with_spectrum, pulse12, params,
                                                  spectrum12):
    pu = pulse12.to_pulse()
    m = leading_mode(pu, params, path=steady12_with_spectrum, compute=False)
    assert m.source.startswith("stored in") and m.is_real
    assert m.sigma == pytest.approx(spectrum12.sigmas[0], rel=1e-12)
    assert m.s_per_L == pytest.approx(spectrum12.sigmas[0].real / spectrum12.rate_unit)
    assert np.max(np.abs(m.lnv)) == pytest.approx(1.0, rel=1e-12)
    # another pulse (c_p changed) is refused, naming both
    other = dataclasses.replace(pu, c_p=pu.c_p * 1.01)
    with pytest.raises(SpectrumError, match="belongs to another pulse"):
        check_same_pulse(m, other)
    other = dataclasses.replace(pu, xi=pu.xi * (1 + 1e-6))
    with pytest.raises(SpectrumError, match="grids differ"):
        check_same_pulse(m, other)


def test_mode_seed_past_balances_friction(steady12_with_spectrum, pulse12, params):
    """The seed's past grew as e^{σt} (docs/stability.md §2): the t = 0 stress of the
    perturbation is the mode's K_σ[δ₁], which balances its linearised friction. With the steady
    (σ = 0) past instead, the same fields are out of balance by ~100× more (measured at N = 2000,
    2 mm: 2.3e-4 ε τ_d against 2.3e-2 ε τ_d)."""
    pu = pulse12.to_pulse()
    m = leading_mode(pu, params, path=steady12_with_spectrum, compute=False)
    spec = DomainSpec(dx=4e-3, ahead=2.0, behind=3.0)
    base = seed_pulse(pu, params, spec)
    i0 = _imbalance(base, params)
    eps = 1e-3
    good = seed_pulse(pu, params, spec)
    perturb_along_mode(good, m, eps)
    # the same fields with the past of an eternal translation only
    bad = seed_pulse(pu, params, spec)
    st = bad.stepper
    rv, rphi = mode_on_grid(m, pu, st.x - bad.xi_shift)
    st.set_state(st.V * np.exp(eps * rv), st.phi * np.exp(eps * rphi))
    st.set_translating_past(pu.c_p)
    rel = (st.x - base.x_front0) / pu.L
    w = (rel > -1.5) & (rel < 0.5)
    dv = np.max(np.abs(good.stepper.V / base.stepper.V - 1)[w])
    assert dv == pytest.approx(eps, rel=0.6)                   # the perturbation is there
    e_good = np.max(np.abs(_imbalance(good, params) - i0)[w]) / pu.tau_d
    e_bad = np.max(np.abs(_imbalance(bad, params) - i0)[w]) / pu.tau_d
    assert e_good < 2e-3 * eps
    assert e_bad > 10 * e_good
    # the slip of the growing past is periodic, with the k = 0 part ⟨ΔV⟩/σ
    dk = good.stepper.delta_k - base.stepper.delta_k
    dV0 = np.fft.rfft(good.stepper.V - base.stepper.V)[0]
    assert dk[0] == pytest.approx(dV0 / m.sigma.real, rel=1e-9)


def test_front_frame_seed_moves_the_body_and_carries_the_displacement_exactly(
        steady12_with_spectrum, pulse12, params):
    """frame="front" (docs/stability.md §2): at t = 0 the change of y = ln(v/v*+1) is ε times
    the front-frame field, at most ε, with no displacement spike; the slip of the past (the
    pulse on X(t) = ct + a(e^{σt} − 1), a = ε η, plus the growing body) equals the quadrature of
    ∫_{−∞}^0 ΔV_k(t) dt at low k, which checks the series of exponentials independently."""
    from slippulse.timedomain.eigenmode import front_frame_seed_fields
    pu = pulse12.to_pulse()
    m = leading_mode(pu, params, path=steady12_with_spectrum, compute=False)
    spec = DomainSpec(dx=4e-3, ahead=2.0, behind=3.0)
    base = seed_pulse(pu, params, spec)
    eps = 5e-3
    good = seed_pulse(pu, params, spec)
    perturb_along_mode(good, m, eps, frame="front")
    st0, st = base.stepper, good.stepper
    y = lambda v: np.log1p(v / params.v_star)
    dy = np.abs(y(st.V) - y(st0.V))
    assert 0.5 * eps < dy.max() <= 1.001 * eps
    # the lab seed with the same body change has the displacement spike at the front
    eta, rv, _, scale = front_frame_seed_fields(m, pu, params.v_star)
    lab = seed_pulse(pu, params, spec)
    perturb_along_mode(lab, m, eps / scale * 1e-2)    # 1 % of the same mode amplitude
    assert np.abs(y(lab.stepper.V) - y(st0.V)).max() > 2 * dy.max() * 1e-2
    # the slip of the past, mode by mode, against a quadrature in t
    sigma, c, a = m.sigma.real, pu.c_p, eps * eta
    V0k = np.fft.rfft(st0.V)
    bk = np.fft.rfft(st.V - st0.V)
    kk = st.kabs
    t = np.linspace(-60.0 / sigma, 0.0, 400_001)
    A = a * (np.exp(sigma * t) - 1.0)
    for j in (1, 2, 5, 20):
        k = kk[j]
        trans = V0k[j] * (np.exp(1j * k * a) - 1.0) / (-1j * k * c)      # the far past, exactly
        f = (V0k[j] * np.exp(-1j * k * c * t) * (np.exp(-1j * k * A) - np.exp(1j * k * a))
             + bk[j] * np.exp((sigma - 1j * k * c) * t) * np.exp(-1j * k * A))
        want = trans + np.trapezoid(f, t)
        got = st.delta_k[j] - st0.delta_k[j]
        assert got == pytest.approx(want, rel=1e-6, abs=1e-12 * abs(V0k[j]) / (k * c))


def test_cli_mode_seed_refuses_bad_input_and_writes_nothing(tmp_path, steady12_with_spectrum,
                                                            pulse12, spectrum12, params, capsys):
    from slippulse.cli.app import main
    from slippulse.spectrum.pulse import write_spectrum
    src = steady12_with_spectrum
    out = tmp_path / "seed.h5"
    base = ["dynamic", "seed", "--steady", src, "--dx", "8e-3", "--ahead", "2", "--behind", "2",
            "--perturb", "mode", "--out", str(out)]
    # ε beyond the linear-regime bound
    assert main(base + ["--eps", "0.05"]) == 2
    err = capsys.readouterr().err
    assert "--eps" in err or "eps=" in err
    assert f"{EPS_MAX:g}" in err and len(err.strip().splitlines()) == 1
    assert not out.exists()
    # a mode from another pulse (same label, other c_p)
    other = str(tmp_path / "other.h5")
    pu = pulse12.to_pulse()
    write_pulse(other, dataclasses.replace(pu, c_p=pu.c_p * 1.001), params)
    write_spectrum(other, spectrum12, {"tol": 1e-7})
    assert main(base + ["--mode-file", other]) == 2
    assert "belongs to another pulse" in capsys.readouterr().err
    assert not out.exists()
    # a stored spectrum that failed (no eigenvalue): no usable mode
    failed = str(tmp_path / "failed.h5")
    write_pulse(failed, pu, params)
    write_spectrum(failed, dataclasses.replace(spectrum12, sigmas=np.zeros(0, complex), modes=[],
                                               status="failed", message="no convergence"), {})
    bad = list(base)
    bad[3] = failed
    assert main(bad) == 2
    assert "status 'failed'" in capsys.readouterr().err
    assert not out.exists()
    # the good case: the seed file records the mode
    assert main(base + ["--eps", "1e-3"]) == 0
    with h5py.File(out) as h5:
        assert h5.attrs["perturbation"] == "mode" and h5.attrs["eps"] == 1e-3
        assert h5.attrs["eigen_s_per_L"] == pytest.approx(
            spectrum12.sigmas[0].real / spectrum12.rate_unit)


def test_verify_verdict_quotes_the_stored_eigenvalue(tmp_path, steady12_with_spectrum,
                                                     spectrum12, capsys):
    from slippulse.cli.app import main
    out = str(tmp_path / "v.h5")
    assert main(["dynamic", "verify", "--steady", steady12_with_spectrum, "--distance", "0.01",
                 "--dx", "8e-3", "--samples", "4", "--out", out, "--no-progress"]) == 0
    s = spectrum12.sigmas[0].real / spectrum12.rate_unit
    with h5py.File(out) as h5:
        assert h5.attrs["eigen_s_per_L"] == pytest.approx(s, rel=1e-12)
        assert h5.attrs["eigen_source"].startswith("stored")       # not computed on the fly


def _synthetic_family(pu, v_star, dq, field_y, field_psi, c_slope):
    """Pulses at q₀ ± dq whose y = ln(v/v*+1) and ln φ are y₀ + (q − q₀) field at fixed ξ (so the
    family tangent at fixed ξ is ``field``), with ln c_p changing at ``c_slope`` per unit q."""
    out = []
    y0 = np.log1p(pu.v / v_star)
    for s in (-1, 1):
        y = y0 + s * dq * field_y
        phi = pu.phi * np.exp(s * dq * field_psi)
        v = v_star * np.expm1(y)
        from slippulse.steady.analysis import pulse_length
        L = pulse_length(pu.xi, v, v_star)[0]
        out.append(dataclasses.replace(pu, v=v, phi=phi, L=L, tau_d_ratio=pu.tau_d_ratio + s * dq,
                                       tau_d=(pu.tau_d_ratio + s * dq) * pu.tau_min,
                                       c_p=pu.c_p * math.exp(s * dq * c_slope)))
    return out


def test_overlap_is_one_when_mode_and_tangent_coincide(pulse12, params):
    """A synthetic family whose tangent at fixed ξ is the mode itself (y₁, φ₁/φ₀), with c_p
    changing as the mode moves the front (δc/c = σ η_R/c_p): in the common front frame the
    overlap is 1 and the mode moves along the line (departure 0, angle 0). A family along another
    field is not (overlap < 0.9)."""
    pu = pulse12.to_pulse()
    vs = params.v_star
    xi, L = pu.xi, pu.L
    from slippulse.steady.analysis import pulse_length
    _, xl, xr = pulse_length(xi, pu.v, vs)
    # a smooth bump at the healing edge (in y) and in ln φ: a pulse-lengthening field
    y1 = np.exp(-((xi - xl) / (0.2 * L)) ** 2)
    psi1 = -0.5 * np.exp(-((xi - xl) / (0.3 * L)) ** 2)
    sigma = 20.0 * pu.c_p / L
    m = Eigenmode(label=pu.label, sigma=complex(sigma), rate_unit=pu.c_p / L, xi=xi,
                  delta=np.zeros_like(xi, complex), V=(y1 * (pu.v + vs)).astype(complex),
                  phi=(psi1 * pu.phi).astype(complex), lnv=y1.astype(complex),
                  tau_d_ratio=pu.tau_d_ratio, L=L, c_p=pu.c_p, source="synthetic")
    fr_ = front_response(m, pu, vs)
    nb = _synthetic_family(pu, vs, 1e-4, y1, psi1, fr_["dc_over_c"])
    row = pulse_overlap(pu, m, nb, vs)
    assert row["overlap"] == pytest.approx(1.0, abs=1e-6)
    assert row["overlap_y"] == pytest.approx(1.0, abs=1e-6)
    assert row["angle_deg"] < 0.1
    assert abs(row["departure_per_dlnL"]) < 1e-3 * abs(row["line_slope"]) + 1e-6
    # the tangent of another field: a bump at the front instead of the healing edge
    y2 = np.exp(-((xi - xr + 0.3 * L) / (0.15 * L)) ** 2)
    nb2 = _synthetic_family(pu, vs, 1e-4, y2, 0 * psi1, 0.0)
    row2 = pulse_overlap(pu, m, nb2, vs)
    assert row2["overlap"] < 0.9
    # the inner product itself: proportional fields give 1 whatever the factor and sign
    z = np.linspace(-2 * L, L, 501)
    a = np.sin(z / L)
    assert mode_overlap(z, (a,), (-3 * a,), L) == pytest.approx(1.0, abs=1e-12)


@pytest.mark.slow
def test_seeded_mode_grows_at_its_eigenvalue_at_1p1(params, tmp_path):
    """A ±ε pair seeded along the eigenmode at 1.1 τ_min (ε = 1e−2 in the frame of the front)
    grows at the eigenvalue within 1 % over 0.4 L: the frame-free potency rate, least squares
    from 0.1 L (docs/stability.md §2). Steady pulse N = 2000 (continued from 1.2), its
    spectrum (the pinned ladder, ± 3e−5 per L), 4 mm SBI grid, 8+8 L domain (measured −0.5 %;
    on 4+4 L the mode's periodic images lower the rate by 1.4 %). ~2 min."""
    from slippulse.timedomain.perturbation import mode_pair_growth, read_series, run_case
    from slippulse.spectrum.family import SpectrumSettings, run_spectrum
    from slippulse.steady.continuation import FamilyRun, run_family
    path = str(tmp_path / "fam.h5")
    run_family(params, path, FamilyRun(start=1.2, stop=1.1, step=0.02, n_points=2000))
    run_spectrum(path, SpectrumSettings(extra=False), labels=["td1.1000"])
    rows = []
    for eps in (1e-2, -1e-2):
        case = {"steady": path, "label": "td1.1000", "perturbation": "mode_front", "eps": eps,
                "dx": 4e-3, "ahead": 8.0, "behind": 8.0, "distance": 0.4, "samples_per_L": 200}
        rows.append(run_case(case, str(tmp_path / f"m{eps}.h5")))
    g = mode_pair_growth(read_series(rows[0]["file"]), read_series(rows[1]["file"]), 1e-2)
    s_eig = rows[0]["eigen_s_per_L"]
    assert g["n"] >= 40
    assert g["s_per_L"] == pytest.approx(s_eig, rel=0.01)


def test_scan_case_with_mode_perturbation_is_checked():
    from slippulse.core.params import ParameterError
    from slippulse.timedomain.perturbation import check_case
    ok = check_case({"steady": "f.h5", "label": "td1.2000", "perturbation": "mode", "eps": -1e-3})
    assert ok["mode_file"] == ""
    with pytest.raises(ParameterError, match="0.01"):
        check_case({"steady": "f.h5", "label": "td1.2000", "perturbation": "mode", "eps": 0.05})
    with pytest.raises(ParameterError, match="'mode'"):
        check_case({"steady": "f.h5", "label": "td1.2000", "perturbation": "shape"})


def test_growing_past_in_the_soe_history_is_the_exact_integral():
    """prefill_translating(sigma=σ): Y = ∫₀^∞ e^{zωs} (Re, Im) V_k(−s) ds for V_k(t) =
    V̂ e^{(σ − ikc)t}, against quadrature; add=True adds it to what is there."""
    from slippulse.dynamics.sbi import SOEHistory
    omega = np.array([0.0, 3.0, 50.0])
    h = SOEHistory(omega, x_min=1e-2, x_max=1e2, h=1.0)
    kabs = omega / 2.0
    c, sigma = 0.7, 1.3
    vhat = np.array([0.0, 0.4 - 0.2j, -1.1 + 0.5j])
    h.Y[:] = 1.0
    h.prefill_translating(vhat, kabs, c, sigma=sigma, add=True)
    for k in (1, 2):
        for j in (0, h.p // 2, h.p - 1):
            zw = h.Z[j] * omega[k]
            rate = sigma - zw.real                       # decay of the integrand
            s = np.linspace(0.0, 40.0 / rate, 400_001)   # ≥ 60 points per oscillation
            V = vhat[k] * np.exp(-(sigma - 1j * kabs[k] * c) * s)
            for part, f in ((0, np.real), (1, np.imag)):
                want = np.trapezoid(np.exp(zw * s) * f(V), s)
                assert h.Y[k, j, part] - 1.0 == pytest.approx(want, rel=1e-6, abs=1e-12)
    assert np.all(h.Y[0] == 1.0)                     # k = 0 untouched (no elastic stress)
