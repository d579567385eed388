"""The linearised operators of the stability spectrum (docs/spectrum.md): the elastic operator K_σ and the
full stability operator M(σ) of one steady pulse on its grid.

A perturbation ∝ e^{σt} at fixed ξ = x − c_p t of a steady pulse (v₀, φ₀, β) obeys

    V₁ = σ δ₁ − c δ₁′                                      (slip rate; c = β c_s)
    (σ − c ∂_ξ) φ₁ = −w φ₁ − w_v φ₀ V₁                      (ageing law g = 1 − w φ, linearised)
    σ_n (f_v V₁ + f_φ φ₁) = K_σ[δ₁]                         (friction = elastodynamics)

with K_σ of symbol −(μ/2)√(k² + (σ − ikc)²/c_s²) (Re √ > 0). On the grid the unknown is V₁;
δ₁ = D(σ)V₁ integrates (σ − c∂_ξ)δ₁ = V₁ from δ₁ = 0 far ahead (bounded ahead), φ₁ = Φ(σ)V₁ by the
exponential state recursion, and the problem is the nonlinear eigenproblem M(σ) V₁ = 0
(:meth:`StabilityOperator.matrices`; derivation in docs/spectrum.md). M is analytic for Re σ > 0
(the imaginary axis carries the continuous spectrum of radiated waves and of the rest state behind
the pulse), and M(0) is the linearised discrete steady problem: translation (V₁ = v₀′) is its null
vector up to the discretisation; uniform slip (δ₁ = 1, V₁ = 0) is checked in the δ₁ form
(:meth:`StabilityOperator.matrices_delta`), where it is exact. Eigenvalues are found by
shift-invert Arnoldi on the linearisation M(σ_a) + (σ − σ_a) M′(σ_a) and refined by Newton on the
bordered system (nonlinear inverse iteration with the exact M′).
"""
from __future__ import annotations

import math

import numpy as np

from ..core import friction as fr
from ..core.h5io import state_order_of
from ..steady.equations import RADAU_A, RADAU_C, integrate_state_radau, radau_stage_values
from ..steady.hilbert import add_times_slopes, hilbert_matrix, tail_columns
from .kernels import (SPLIT_PER_SIDE, KernelTables, assemble_w, slip_coefficients4,
                               stability_rows, state_rows4)


# ----------------------------------------------------------------------- spline helpers
def slope_matrix(xi):
    """Dense S with S u = slopes of the natural cubic spline through (ξ, u)."""
    n = xi.size
    return add_times_slopes(np.zeros((n, n)), np.eye(n), xi)


# ------------------------------------------------------------------- elastic operator
class ElasticOperator:
    """K_σ on a fixed grid: τ₁ = K_σ δ₁ for the two identical half-spaces (mode III).

    K_σ = (λ/π) H S + (λγ/π) H₀ + λ 𝒲̃(σ),  λ = μ√(1−β²)/2,  γ = βσ/(c_s(1−β²)),

    H: PV Hilbert matrix of the cubic spline with the algebraic far-field tails (the steady
    solver's operator), H₀: the same without tails, 𝒲̃: product integration of the kernel W̃
    (:mod:`slippulse.spectrum.kernels`). At σ = 0, K_0 = (λ/π) H S is the steady operator acting on
    V = −c δ′.
    """

    def __init__(self, xi, beta, c_s, mu, center=None, H=None):
        self.xi = np.ascontiguousarray(xi, dtype=float)
        self.beta = float(beta)
        self.c_s = float(c_s)
        self.mu = float(mu)
        if center is None:
            center = 0.0 if self.xi[0] < 0.0 < self.xi[-1] else 0.5 * (self.xi[0] + self.xi[-1])
        self.center = center
        H = hilbert_matrix(self.xi, center=center) if H is None else H
        self.H = H
        self._HS = None
        behind, ahead = tail_columns(self.xi, center)
        self.H0 = H.copy()
        self.H0[:, 0] -= behind
        self.H0[:, -1] -= ahead
        self.lam = self.mu * math.sqrt(1.0 - self.beta ** 2) / 2.0
        #: far segments of 𝒲̃ by each side's own exponential, Filon–Gauss where it turns fast
        #: (:func:`assemble_w`; False: the rule before, for benchmarks)
        self.split_per_side = SPLIT_PER_SIDE
        h = np.diff(self.xi)
        self.r_min = 0.005 * h.min()
        self.r_max = 1.01 * (self.xi[-1] - self.xi[0])

    @property
    def HS(self):
        """H S (the steady operator on δ′; only the δ₁ form and the tests use it), built once."""
        if self._HS is None:
            self._HS = add_times_slopes(np.zeros_like(self.H), self.H, self.xi)
        return self._HS

    def gamma(self, sigma):
        return self.beta * sigma / (self.c_s * (1.0 - self.beta ** 2))

    def matrices(self, sigma, deriv=True):
        """(K_σ, ∂K_σ/∂σ) as complex N×N arrays (∂K only if deriv)."""
        sigma = complex(sigma)
        lam = self.lam
        g_over_s = self.beta / (self.c_s * (1.0 - self.beta ** 2))
        K = (lam / math.pi) * self.HS.astype(complex)
        dK = (lam * g_over_s / math.pi) * self.H0.astype(complex) if deriv else None
        if sigma == 0.0:
            return K, dK
        K += (lam * self.gamma(sigma) / math.pi) * self.H0
        W, dW = self.kernel_matrices(sigma, deriv)
        K += lam * W
        if deriv:
            dK += lam * dW
        return K, dK

    def kernel_matrices(self, sigma, deriv=True):
        """(𝒲̃(σ), ∂_σ𝒲̃(σ)): ∫ δ(z) W̃(ξ_i − z) dz for the cubic spline of δ, and its σ-derivative
        (real arrays at real σ, where the kernel is real; complex otherwise)."""
        n = self.xi.size
        tab = KernelTables(sigma, self.beta, self.c_s, self.r_min, self.r_max)
        dt = tab.dtype                    # real at real σ (M(σ̄) = conj M(σ))
        AW = np.zeros((n, n), dt)
        BW = np.zeros((n, n), dt)
        AS = np.zeros((n, n), dt)
        BS = np.zeros((n, n), dt)
        assemble_w(self.xi, tab.args(), (AW, BW, AS, BS), self.split_per_side)
        W = add_times_slopes(AW, BW, self.xi, overwrite_b=True)
        dW = add_times_slopes(AS, BS, self.xi, overwrite_b=True) if deriv else None
        return W, dW

    def apply(self, sigma, delta):
        """K_σ δ (for tests)."""
        return self.matrices(sigma, deriv=False)[0] @ delta


def symbol(k, sigma, beta, c_s, mu):
    """Fourier symbol −(μ/2)√(k² + (σ − ikc)²/c_s²), principal root (Re ≥ 0); e^{ikξ} convention."""
    c = beta * c_s
    return -(mu / 2.0) * np.sqrt(k * k + (sigma - 1j * k * c) ** 2 / c_s ** 2 + 0j)


def _real_or_complex(sigma):
    """σ as a float where its imaginary part is exactly 0, else as a complex number (the
    compiled recursions then run in real arithmetic)."""
    sigma = complex(sigma)
    return sigma.real if sigma.imag == 0.0 else sigma


# ------------------------------------------------------------------ full stability operator
class StabilityOperator:
    """M(σ) for one steady pulse on its own grid (see module notes).

    The pulse must have been solved with the order-4 state integrator (``state_order`` 4): M(0) is
    then exactly the Jacobian of the discrete steady problem in v, and the state and slip
    recursions of M(σ) are of the same order (docs/spectrum.md §2). :func:`order4_pulse`
    re-solves an older (order-2) pulse on its own grid first.
    """

    #: M(σ̄) = conj M(σ): the linearised equations have real coefficients (the steady pulse and
    #: the kernels are real at real σ), so the contour count evaluates Im σ ≥ 0 only
    #: (tests/test_count.py checks the identity on a pulse).
    conjugate_symmetric = True

    def __init__(self, pulse, params, pin_translation=False):
        p = params
        self.params = p
        self.pulse = pulse
        order = state_order_of(pulse)
        if order != 4:
            raise ValueError(f"pulse {pulse.label}: state_order={order}; the stability operator "
                             "needs an order-4 pulse (order4_pulse re-solves it)")
        self.xi = np.ascontiguousarray(pulse.xi, dtype=float)
        self.n = self.xi.size
        self.beta = float(pulse.beta)
        self.c = self.beta * p.c_s
        self.tau_d = float(pulse.tau_d)
        v = np.asarray(pulse.v, float)
        y = np.log(v)
        # the converged state of the order-4 map (bit for bit the steady solver's) and its
        # Jacobian ∂φ/∂y
        phi, P = integrate_state_radau(self.xi, y, self.c, float(pulse.phi[-1]), p.v_star, p.D,
                                       RADAU_A, RADAU_C, True)[:2]
        self.v0, self.phi0 = v, phi
        la = p.law_args
        self.fv = p.sigma * fr.df_dv(v, phi, *la)
        self.fphi = p.sigma * fr.df_dphi(v, phi, *la)
        self.inv_v = 1.0 / v
        # the order-4 map's stages: Φ(σ) and D(σ) are Radau IIA steps on the same stages
        hs, j0s, lws, ws, phis, omegas = radau_stage_values(self.xi, y, self.c, phi, p.v_star, p.D,
                                                            RADAU_A, RADAU_C)
        vst = np.empty_like(ws)
        vst[:, :2] = np.exp(np.einsum("ikl,il->ik", lws, y[j0s[:, None] + np.arange(4)]))
        vst[:, 2] = v[:-1]
        G = -phis * vst ** 2 / (p.D ** 2 * ws)                    # −φ₀ ∂w/∂ln v at the stages
        self.cells = (hs, j0s, lws, ws, G, omegas, vst)
        # Φ(σ) is corrected by the σ-independent O(h⁴) difference that makes Φ(0) the exact
        # derivative ∂φ/∂v of the steady map, so that M(0) is exactly the linearised discrete
        # steady problem (docs/spectrum.md §2)
        Phi0 = self._state(0.0, np.eye(self.n), False)[0]
        self.state_correction = P * self.inv_v[None, :] - Phi0.real
        self.phi_correction = self.fphi[:, None] * self.state_correction
        self.elastic = ElasticOperator(self.xi, self.beta, p.c_s, p.mu)
        self.S = slope_matrix(self.xi)
        self.length = float(pulse.L)
        self.rate_unit = self.c / self.length                      # c_p / L, 1/s
        self.pin = None
        if pin_translation:
            # M̃(σ) = M(σ) − r tᵀ/(tᵀt), r = M(0) t, t = v₀′: translation is an exact null
            # vector of M̃(0) (σ_t = 0 as in the continuum); the change is of the order of the
            # residual r, i.e. of the discretisation (docs/spectrum.md §2)
            t = self.S @ self.v0
            r = self.matrices(0.0, deriv=False)[0] @ t
            self.pin = (r, t / float(t @ t))

    def _state(self, sigma, Vm, deriv):
        """(Φ(σ) Vm, ∂_σΦ(σ) Vm) without the correction (the second only if deriv); real
        arrays where σ and Vm are real."""
        hs, j0s, lws, ws, G, omegas, _ = self.cells
        sg = _real_or_complex(sigma)
        dt = complex if (np.iscomplexobj(Vm) or isinstance(sg, complex)) else float
        Vm = np.ascontiguousarray(Vm, dtype=dt)
        Y = np.empty(Vm.shape, dt)
        dY = np.empty(Vm.shape if deriv else (1, 1), dt)
        state_rows4((hs, j0s, lws, ws, G, omegas), self.inv_v, RADAU_A, sg, Vm, (Y, dY), deriv)
        return Y, (dY if deriv else None)

    def _slip(self, sigma):
        hs, j0s, lws, _, _, _, vst = self.cells
        return slip_coefficients4(hs, j0s, lws, vst, self.inv_v, RADAU_A,
                                  _real_or_complex(sigma))

    def matrices(self, sigma, deriv=True):
        """(M(σ), M′(σ)) acting on the slip-rate perturbation V₁ (rows divided by τ_d); real
        arrays at real σ, complex otherwise.

        δ₁ = D(σ) V₁ integrates (σ − c∂_ξ) δ₁ = V₁ from δ₁ = 0 far ahead (bounded ahead; behind it
        decays as e^{σξ/c}), φ₁ = Φ(σ) V₁, and with δ₁′ = (σ δ₁ − V₁)/c the elastic stress is
        K_σ δ₁ = X(σ) D(σ) V₁ − (λ/(πc)) H V₁,  X = (λσ/(πc)) H + (λγ/π) H₀ + λ 𝒲̃(σ).
        At σ = 0: M(0) = [σ_n (f_v + f_φ Φ(0)) + μF(β) H]/τ_d, the steady problem linearised in v.
        """
        sigma = complex(sigma)
        n = self.n
        el = self.elastic
        lam, c = el.lam, self.c
        # at real σ every part is real (M(σ̄) = conj M(σ)) and is built in real arithmetic,
        # half the work and memory of the complex; W decides, being real only where
        # its tables came out exactly real
        if sigma != 0.0:
            W, dW = el.kernel_matrices(sigma, deriv)
        dt = complex if sigma.imag != 0.0 or (sigma != 0.0 and np.iscomplexobj(W)) else float
        s_ = sigma if dt is complex else sigma.real
        Phi, dPhi = self._state(s_, np.eye(n, dtype=dt), deriv)
        k_h = lam / (math.pi * c)
        cx = np.array([lam, k_h * s_, lam * el.gamma(s_) / math.pi], dt)
        cdx = np.array([lam, k_h, lam * el.gamma(1.0) / math.pi], dt)
        dummy = np.zeros((1, 1), dt)
        has_w = sigma != 0.0
        a, B, da, dB = self._slip(s_)
        pin_r, pin_t = self.pin if self.pin is not None else (np.zeros(1), np.zeros(1))
        # M over Phi and M′ over dPhi, row by row in one compiled pass
        stability_rows((W if has_w else dummy, dW if has_w and deriv else dummy, el.H, el.H0),
                       (cx, cdx, k_h, self.tau_d), (Phi, dPhi if deriv else dummy),
                       (self.phi_correction, self.fphi, self.fv), (a, B, self.cells[1], da, dB),
                       (pin_r, pin_t), has_w, self.pin is not None, deriv)
        return Phi, (dPhi if deriv else None)

    def slip(self, sigma, V):
        """δ₁ = D(σ) V₁ (the recursion of :func:`slip_coefficients4` applied to a vector)."""
        a, B, _, _ = self._slip(sigma)
        j0s = self.cells[1]
        V = np.asarray(V, complex)
        d = np.zeros(self.n, complex)
        for i in range(self.n - 2, -1, -1):
            j0 = j0s[i]
            d[i] = a[i] * d[i + 1] + B[i] @ V[j0:j0 + 4]
        return d

    def state(self, sigma, V):
        """φ₁ = Φ(σ) V₁ (with the correction of Φ(0))."""
        V = np.asarray(V, complex)
        return self._state(sigma, V[:, None], False)[0][:, 0] + self.state_correction @ V

    def fields(self, sigma, V):
        """Mode fields from the slip-rate perturbation V₁: δ₁, V₁, φ₁ and the perturbation of
        ln(v/v* + 1) = V₁/(v₀ + v*), scaled so that the last has modulus 1 and phase 0 at its
        largest modulus."""
        V = np.asarray(V, complex)
        lnv = V / (self.v0 + self.params.v_star)
        k = int(np.argmax(np.abs(lnv)))
        scale = 1.0 / lnv[k]
        V = V * scale
        return {"delta": self.slip(sigma, V), "V": V, "phi": self.state(sigma, V),
                "lnv": lnv * scale}

    def matrices_delta(self, sigma):
        """M(σ) acting on δ₁ with δ₁′ from its cubic spline (the form in which uniform slip,
        δ₁ = 1, is an exact null vector at σ = 0). Used to check that neutral mode."""
        s_ = _real_or_complex(sigma)
        n = self.n
        Vm = (-self.c) * self.S.astype(type(s_))
        Vm[np.diag_indices(n)] += s_
        # state_correction @ Vm with Vm = −c S + σ I: the product with S in O(N²)
        # (add_times_slopes), not as a dense N³ product (2 s at N = 3542)
        corr = (-self.c) * add_times_slopes(np.zeros((n, n)), self.state_correction, self.xi)
        corr = corr + s_ * self.state_correction
        Y = self._state(s_, Vm, False)[0] + corr
        if s_ == 0.0:                       # real: K_0 = (λ/π) H S
            K = (self.elastic.lam / math.pi) * self.elastic.HS
        else:
            K = self.elastic.matrices(s_, deriv=False)[0]
        return (self.fv[:, None] * Vm + self.fphi[:, None] * Y - K) / self.tau_d
