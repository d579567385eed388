"""Exact solutions for the SBI tests (shared by tests/test_sbi_*.py and the sbi benchmarks of benchmarks/suite.py).

Everything here is computed independently of the SBI code path (closed forms, scipy special
functions and quadrature), so a test comparing the stepper against it can fail.
"""
from __future__ import annotations

import math

import numpy as np
from scipy import special


def kostrov_slip(x, t, v_r, c_s, dtau, mu, x0=0.0):
    """Kostrov (1964) self-similar mode-III crack between identical half-spaces, m:
    δ = (2Δτ/μ) √(v_r²t² − (x−x0)²) / E(√(1 − v_r²/c_s²)), E with parameter m = k² (scipy)."""
    a = v_r * t
    E = special.ellipe(1.0 - (v_r / c_s) ** 2)
    return (2.0 * dtau / mu) * np.sqrt(np.maximum(a * a - (x - x0) ** 2, 0.0)) / E


def periodic_distance(x, x0, lam):
    return (x - x0 + 0.5 * lam) % lam - 0.5 * lam


def pv_gaussian_periodic(xi, a, lam, images=60):
    """PV∫ Σ_n exp(−(z − nλ)²/a²) / (z − ξ) dz over the line (periodic images, symmetric sum).

    Single Gaussian: PV∫ e^{−z²/a²}/(z − ξ) dz = −2√π F(ξ/a), F = Dawson's integral.
    Images: F(x) = 1/(2x) + O(x^{−3}); the 1/(2x) parts sum in closed form,
    Σ_{n≠0} 1/(ξ + nλ) = (π/λ) cot(πξ/λ) − 1/ξ, the O(x^{−3}) remainders are summed directly.
    """
    xi = np.asarray(xi, dtype=float)
    s = special.dawsn(xi / a)
    for n in range(1, images + 1):
        for xn in (xi + n * lam, xi - n * lam):
            s = s + special.dawsn(xn / a) - a / (2.0 * xn)
    u = math.pi * xi / lam
    small = np.abs(u) < 1e-3
    with np.errstate(divide="ignore", invalid="ignore"):
        cotpart = np.where(small, -(math.pi / lam) * (u / 3.0 + u ** 3 / 45.0),
                           (math.pi / lam) / np.tan(u) - 1.0 / xi)
    return -2.0 * math.sqrt(math.pi) * s - math.sqrt(math.pi) * a * cotpart


def _j1_over_t(T):
    T = np.asarray(T, dtype=float)
    out = np.empty_like(T)
    small = T < 1e-8
    out[small] = 0.5
    out[~small] = special.j1(T[~small]) / T[~small]
    return out


def _gl_integral(beta, T0, order=16, panel=1.0):
    """∫_0^{T0} (J1(T)/T) e^{iβT} dT for an array of T0 (composite Gauss–Legendre)."""
    T0 = np.asarray(T0, dtype=float)
    xg, wg = np.polynomial.legendre.leggauss(order)
    npan = int(np.ceil(T0.max() / panel)) + 1
    lo = np.arange(npan) * panel
    nodes = lo[:, None] + 0.5 * panel * (xg[None, :] + 1.0)
    vals = _j1_over_t(nodes) * np.exp(1j * beta * nodes)
    per_panel = 0.5 * panel * (vals * wg[None, :]).sum(axis=1)
    cum = np.concatenate([[0.0], np.cumsum(per_panel)])
    m = np.floor(T0 / panel).astype(int)
    start = m * panel
    h = T0 - start
    nodes = start[:, None] + 0.5 * h[:, None] * (xg[None, :] + 1.0)
    part = 0.5 * h * (_j1_over_t(nodes) * np.exp(1j * beta * nodes) * wg[None, :]).sum(axis=1)
    return cum[m] + part


def kernel_tail(beta, T0):
    """G(T0, β) = ∫_{T0}^∞ K(T) e^{iβT} dT, 0 < β < 1, by parts and the Laplace transform of
    J1(T)/T (√(1+s²) − s at s = −iβ): G = [−K(T0)e^{iβT0} + √(1−β²) + iβ − ∫_0^{T0} (J1/T)e^{iβT}]/(iβ),
    K(T0) = ∫_{T0}^∞ J1/T = 1 − ∫_0^{T0} J1/T computed by the same quadrature (no SBI code used)."""
    T0 = np.asarray(T0, dtype=float)
    I_osc = _gl_integral(beta, T0)
    K0 = 1.0 - _gl_integral(0.0, T0).real
    return (-K0 * np.exp(1j * beta * T0) + math.sqrt(1.0 - beta * beta) + 1j * beta - I_osc) / (1j * beta)


def steady_translating_stress(x, t, *, V_amp, a, lam, c, c_s, mu, tau_d, v_stick, x0=0.0,
                              with_transient=True):
    """Stress of the imposed slip rate V = v_stick + V_amp exp(−(ξ/a)²), ξ = x − x0 − ct (periodic).

    Steady part (the steady solver's operator on the periodic line):
        τ_ss = τ_d − μ F_III(β) PV∫ (V − v_stick)/(z − ξ) dz − (μ/2c_s) ⟨V − v_stick⟩,
    where the last term is the uniform (k = 0) mode of a periodic domain (it vanishes as λ → ∞).
    Transient of a start from static equilibrium with the travelling slip profile at t = 0:
        Δτ_k(t) = −(μ|k|/2) V̂_k(t) G(ω_k t, β)/ω_k   for every Fourier mode k > 0.
    """
    beta = c / c_s
    xi = periodic_distance(x, x0 + c * t, lam)
    F3 = math.sqrt(1.0 - beta ** 2) / (2.0 * math.pi * beta * c_s)
    mean_dv = V_amp * a * math.sqrt(math.pi) / lam
    tau = tau_d - mu * F3 * V_amp * pv_gaussian_periodic(xi, a, lam) - mu / (2 * c_s) * mean_dv
    if with_transient and t > 0:
        n = x.size
        dv = V_amp * np.exp(-(xi / a) ** 2)
        vk = np.fft.rfft(dv)
        kap = 2 * math.pi / lam * np.arange(n // 2 + 1)
        om = kap * c_s
        dk = np.zeros_like(vk)
        G = kernel_tail(beta, om[1:] * t)
        dk[1:] = -0.5 * mu * kap[1:] * vk[1:] * G / om[1:]
        tau = tau + np.fft.irfft(dk, n=n)
    return tau


# ----------------------------------------------------------------------------- drivers
# (the SBI runs of the exact tests, shared with benchmarks/suite.py)

def run_kostrov(n, v_r_ratio, policy="full", lam=1.0, dtau=1e6, a_end=0.3, history_options=None,
                threads=1):
    """Kostrov crack from the centre of a periodic domain λ until its half-length is a_end·λ.

    Returns (relative error max|δ − δ_K| / max δ_K over |x − x0| < 0.8 a, stepper)."""
    from slippulse.core.params import DEFAULT as P
    from slippulse.dynamics.stepper import KostrovInterface, PredictorCorrector
    x0 = 0.5 * lam
    v_r = v_r_ratio * P.c_s
    law = KostrovInterface(P, v_r, dtau, x0)
    st = PredictorCorrector(P, n, lam, law, history=policy, history_options=history_options,
                            threads=threads)
    st.set_state(np.zeros(n))
    st.run(t_end=a_end * lam / v_r)
    exact = kostrov_slip(st.x, st.t, v_r, P.c_s, dtau, P.mu, x0)
    inner = np.abs(st.x - x0) < 0.8 * v_r * st.t
    return float(np.abs(st.delta - exact)[inner].max() / exact.max()), st


def run_steady(n, beta, policy="full", lam=1.0, V_amp=1e-3, a=0.03, t_end=None, rule=None,
               history_options=None, threads=1, tau_d_ratio=1.2, steady_past=False):
    """Impose V = v_stick + V_amp exp(−(ξ/a)²), ξ = x − x0 − βc_s t, starting from static equilibrium
    with the travelling slip profile (or, with ``steady_past``, from the infinite steady past held by
    the SOE history); compare τ at the end with ``steady_translating_stress``.

    Returns (error vs exact/​max|τ_ss − τ_d|, deviation from the steady operator alone/​same, stepper)."""
    from slippulse.core.params import DEFAULT as P
    from slippulse.dynamics.stepper import PredictorCorrector, PrescribedInterface, TimeStepRule
    tau_d = tau_d_ratio * P.tau_min
    vs = P.v_stick(tau_d)
    eta = P.mu / (2 * P.c_s)
    c = beta * P.c_s
    x0 = 0.3 * lam

    def vfun(x, t):
        return vs + V_amp * np.exp(-(periodic_distance(x, x0 + c * t, lam) / a) ** 2)

    law = PrescribedInterface(P, vfun, tau_load=tau_d + eta * vs)
    st = PredictorCorrector(P, n, lam, law, rule=rule or TimeStepRule(), history=policy,
                            history_options=history_options, threads=threads)
    x = st.x
    vk = np.fft.rfft(V_amp * np.exp(-(periodic_distance(x, x0, lam) / a) ** 2))
    kap = 2 * math.pi / lam * np.arange(n // 2 + 1)
    dk = np.zeros_like(vk)
    dk[1:] = 1j * vk[1:] / (kap[1:] * c)            # δ_k = i V_k/(kc): the travelling slip
    st.set_state(vfun(x, 0.0), delta=np.fft.irfft(dk, n=n))
    if steady_past:                                  # SOE history of the infinite steady past
        st.set_translating_past(c)
    st.run(t_end=t_end if t_end is not None else lam / P.c_s)
    kw = dict(V_amp=V_amp, a=a, lam=lam, c=c, c_s=P.c_s, mu=P.mu, tau_d=tau_d, v_stick=vs, x0=x0)
    exact = steady_translating_stress(x, st.t, **kw)
    steady = steady_translating_stress(x, st.t, with_transient=False, **kw)
    scale = np.abs(steady - tau_d).max()
    return (float(np.abs(st.tau - exact).max() / scale),
            float(np.abs(st.tau - steady).max() / scale), st)
