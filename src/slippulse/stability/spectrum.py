"""Linear stability spectrum of steady pulses on the steady solver's grid (docs/spectrum.md).

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
import time
from dataclasses import dataclass, field

import numpy as np
from scipy.linalg import lu_factor, lu_solve

from ..core import friction as fr
from ..core.h5io import UNSTORED_STATE_ORDER, state_order_of
from ..steady.equations import RADAU_A, RADAU_C, integrate_state_radau, radau_stage_values
from ..steady.hilbert import add_times_slopes, hilbert_matrix, tail_columns
from .spectrum_kernels import (KernelTables, assemble_w, slip_coefficients4, state_rows4,
                               times_D4)


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
    (:mod:`slippulse.stability.spectrum_kernels`). At σ = 0, K_0 = (λ/π) H S is the steady operator acting on
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
        """(𝒲̃(σ), ∂_σ𝒲̃(σ)): ∫ δ(z) W̃(ξ_i − z) dz for the cubic spline of δ, and its σ-derivative."""
        n = self.xi.size
        tab = KernelTables(sigma, self.beta, self.c_s, self.r_min, self.r_max)
        AW = np.zeros((n, n), complex)
        BW = np.zeros((n, n), complex)
        AS = np.zeros((n, n), complex)
        BS = np.zeros((n, n), complex)
        assemble_w(self.xi, *tab.args(), AW, BW, AS, BS)
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


# ------------------------------------------------------------------ full stability operator
class StabilityOperator:
    """M(σ) for one steady pulse on its own grid (see module notes).

    The pulse must have been solved with the order-4 state integrator (``state_order`` 4): M(0) is
    then exactly the Jacobian of the discrete steady problem in v, and the state and slip
    recursions of M(σ) are of the same order (docs/spectrum.md §2). :func:`order4_pulse`
    re-solves an older (order-2) pulse on its own grid first.
    """

    def __init__(self, pulse, params):
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
        Phi0 = self._state(0.0, np.eye(self.n, dtype=complex), False)[0]
        self.state_correction = P * self.inv_v[None, :] - Phi0.real
        self.phi_correction = self.fphi[:, None] * self.state_correction
        self.elastic = ElasticOperator(self.xi, self.beta, p.c_s, p.mu)
        self.S = slope_matrix(self.xi)
        self.length = float(pulse.L)
        self.rate_unit = self.c / self.length                      # c_p / L, 1/s

    def _state(self, sigma, Vm, deriv):
        """(Φ(σ) Vm, ∂_σΦ(σ) Vm) without the correction (the second only if deriv)."""
        hs, j0s, lws, ws, G, omegas, _ = self.cells
        Vm = np.ascontiguousarray(Vm, dtype=complex)
        Y = np.empty(Vm.shape, complex)
        dY = np.empty(Vm.shape if deriv else (1, 1), complex)
        state_rows4(hs, j0s, lws, ws, G, omegas, self.inv_v, RADAU_A, complex(sigma), Vm, Y, dY,
                    deriv)
        return Y, (dY if deriv else None)

    def _slip(self, sigma):
        hs, j0s, lws, _, _, _, vst = self.cells
        return slip_coefficients4(hs, j0s, lws, vst, self.inv_v, RADAU_A, complex(sigma))

    def matrices(self, sigma, deriv=True):
        """(M(σ), M′(σ)) acting on the slip-rate perturbation V₁ (rows divided by τ_d).

        δ₁ = D(σ) V₁ integrates (σ − c∂_ξ) δ₁ = V₁ from δ₁ = 0 far ahead (bounded ahead; behind it
        decays as e^{σξ/c}), φ₁ = Φ(σ) V₁, and with δ₁′ = (σ δ₁ − V₁)/c the elastic stress is
        K_σ δ₁ = X(σ) D(σ) V₁ − (λ/(πc)) H V₁,  X = (λσ/(πc)) H + (λγ/π) H₀ + λ 𝒲̃(σ).
        At σ = 0: M(0) = [σ_n (f_v + f_φ Φ(0)) + μF(β) H]/τ_d, the steady problem linearised in v.
        """
        sigma = complex(sigma)
        n = self.n
        el = self.elastic
        lam, c = el.lam, self.c
        Phi, dPhi = self._state(sigma, np.eye(n, dtype=complex), deriv)
        M = self.fphi[:, None] * Phi
        M += self.phi_correction
        M[np.diag_indices(n)] += self.fv
        M += (lam / (math.pi * c)) * el.H
        dM = self.fphi[:, None] * dPhi if deriv else None
        if sigma != 0.0:
            W, dW = el.kernel_matrices(sigma, deriv)
            X = lam * W
            X += (lam * sigma / (math.pi * c)) * el.H
            X += (lam * el.gamma(sigma) / math.pi) * el.H0
        else:
            X = np.zeros((n, n), complex)
            dW = np.zeros((n, n), complex) if deriv else None
        if deriv:
            dX = lam * dW
            dX += (lam / (math.pi * c)) * el.H
            dX += (lam * el.gamma(1.0) / math.pi) * el.H0
        else:
            dX = np.empty((1, 1), complex)
        a, B, da, dB = self._slip(sigma)
        XD = np.empty((n, n), complex)
        dXD = np.empty((n, n) if deriv else (1, 1), complex)
        times_D4(X, dX, a, B, self.cells[1], da, dB, XD, dXD, deriv)
        M -= XD
        M /= self.tau_d
        if deriv:
            dM -= dXD
            dM /= self.tau_d
        return M, dM

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
        sigma = complex(sigma)
        n = self.n
        Vm = -self.c * self.S.astype(complex)
        Vm[np.diag_indices(n)] += sigma
        Y = self._state(sigma, Vm, False)[0] + self.state_correction @ Vm
        K = self.elastic.matrices(sigma, deriv=False)[0]
        return (self.fv[:, None] * Vm + self.fphi[:, None] * Y - K) / self.tau_d


# ------------------------------------------------------------------------------ eigen-solvers
@dataclass
class Eigen:
    """One eigenvalue σ (1/s) with its mode V₁ (normalised: eᴴV₁ = 1) and how it was obtained."""

    sigma: complex
    V: np.ndarray
    converged: bool
    iterations: int
    residual: float
    message: str = ""
    history: list = field(default_factory=list)


def _relres(M, x):
    """Componentwise backward error max_i |M x|_i / (|M| |x|)_i (the rows of M span many decades:
    the leading edge is resolved with cells 10⁴× finer than the body)."""
    return float(np.max(np.abs(M @ x) / (np.abs(M) @ np.abs(x))))


def newton_eigen(op, sigma0, x0, tol=1e-10, max_iter=12, min_re=None, res_tol=1e-6):
    """Newton on the bordered system M(σ) x = 0, eᴴx = 1 (nonlinear inverse iteration with M′).

    u = M(σ_k)⁻¹ M′(σ_k) x_k,  σ_{k+1} = σ_k − 1/(eᴴu),  x_{k+1} = u/(eᴴu);  quadratic.
    Converged when |σ_{k+1} − σ_k| ≤ tol·max(|σ_k|, c/L) and the componentwise backward error of
    M(σ_k) x_k is below res_tol. Leaving the analytic half-plane (Re σ ≤ min_re) is a failure.
    """
    scale = op.rate_unit
    min_re = 1e-4 * scale if min_re is None else min_re
    x = np.asarray(x0, complex)
    e = x / np.vdot(x, x)                  # eᴴ x0 = 1, e fixed
    x = x / np.vdot(e, x)
    sigma = complex(sigma0)
    hist = []
    res = float("nan")
    for it in range(1, max_iter + 1):
        if not sigma.real > min_re:
            return Eigen(sigma, x, False, it, res,
                         f"left the half-plane Re sigma > {min_re / scale:.0e} c/L "
                         f"(sigma L/c = {sigma / scale:.4g})", hist)
        M, dM = op.matrices(sigma)
        res = _relres(M, x)
        lu = lu_factor(M, check_finite=False)
        u = lu_solve(lu, dM @ x, check_finite=False)
        eu = np.vdot(e, u)
        step = 1.0 / eu
        sigma_new = sigma - step
        x = u / eu
        hist.append(complex(sigma_new))
        if abs(step) <= tol * max(abs(sigma), scale):
            ok = res < res_tol
            return Eigen(sigma_new, x, ok, it, res,
                         "converged" if ok else f"step converged but residual {res:.1e}", hist)
        sigma = sigma_new
    return Eigen(sigma, x, False, max_iter, res,
                 f"no convergence in {max_iter} Newton iterations", hist)


def _arnoldi(matvec, n, k, tol=1e-8, maxiter=60):
    """k largest-modulus eigenpairs by ARPACK; those converged when ARPACK stops early (the
    continuum-like cluster near the imaginary axis converges slowly and is not wanted)."""
    from scipy.sparse.linalg import ArpackNoConvergence, LinearOperator, eigs
    A = LinearOperator((n, n), matvec=matvec, dtype=complex)
    try:
        return eigs(A, k=min(k, n - 2), which="LM", ncv=max(2 * k + 1, 20), tol=tol,
                    maxiter=maxiter)
    except ArpackNoConvergence as exc:
        return exc.eigenvalues, exc.eigenvectors


def linearised_candidates(op, sigma_a, k=1):
    """Eigenvalues of the pencil M(σ_a) + (σ − σ_a) M′(σ_a) nearest σ_a, with vectors.

    Shift-invert: M(σ_a)⁻¹ M′(σ_a) x = ν x  ⇒  σ = σ_a − 1/ν; the k largest |ν| by ARPACK.
    """
    M, dM = op.matrices(sigma_a)
    lu = lu_factor(M, check_finite=False)
    nu, vecs = _arnoldi(lambda v: lu_solve(lu, dM @ v, check_finite=False), op.n, k)
    sig = complex(sigma_a) - 1.0 / nu
    order = np.argsort(np.abs(sig - sigma_a))
    return sig[order], vecs[:, order]


def neutral_modes(op, k=2):
    """The pencil M(0) + σ M′(0⁺) near σ = 0, whose smallest eigenvalue is translation
    (V₁ = v₀′, exact in the continuum; here up to the discretisation). M′(0⁺) omits the
    O(σ ln σ) part of the kernel, which vanishes at 0. Returns (sigmas, vectors) by |σ|."""
    M0, dM0 = op.matrices(0.0)
    shift = 1e-3 * op.rate_unit
    A0 = M0 + shift * dM0                   # shifted so that the factorisation is regular
    lu = lu_factor(A0, check_finite=False)
    nu, vecs = _arnoldi(lambda v: lu_solve(lu, dM0 @ v, check_finite=False), op.n, k, tol=1e-10,
                        maxiter=100)
    sig = shift - 1.0 / nu
    order = np.argsort(np.abs(sig))
    return sig[order], vecs[:, order]


# ------------------------------------------------------------------------ one pulse, a family
DEFAULT_SHIFTS = (25.0, 8.0, 2.0, 0.5, 0.15, 0.05)   # first search shifts, in units of c_p/L
MIN_RE = 1e-3                              # eigenvalues with Re σ < MIN_RE c/L are not sought


@dataclass
class PulseSpectrum:
    """Eigenvalues of one pulse (sorted by decreasing Re σ), their modes, the neutral pair."""

    label: str
    sigmas: np.ndarray            # complex, 1/s
    modes: list                   # dicts of fields per eigenvalue (see StabilityOperator.fields)
    neutral: np.ndarray           # σ of uniform slip and translation (1/s)
    translation_error: float      # relative distance of the translation mode from δ₀′ (in V₁)
    rate_unit: float              # c_p / L, 1/s
    n_points: int
    status: str
    message: str
    wall_time: float
    newton_iterations: int = 0
    failures: list = field(default_factory=list)
    stage_times: dict = field(default_factory=dict)
    refined: object = None        # RefinedRate of the leading eigenvalue (stability.refine)
    count: object = None          # ContourCount (stability.count), if asked for
    operator: object = field(default=None, repr=False)   # the StabilityOperator (not stored)
    xi: object = None             # the grid of the modes (the pulse's, or a nested refinement)

    @property
    def n_unstable(self):
        return int(np.sum(self.sigmas.real > 0))

    @property
    def leading(self):
        return complex(self.sigmas[0]) if self.sigmas.size else complex("nan")


def _translation_check(op, sigs, vecs):
    """Pick the translation mode among the near-zero pencil modes: the one whose V₁ is closest
    to v₀′ (δ₁ = δ₀′ ⇒ V₁ = −c δ₀″ = v₀′). Returns (σ_t, relative distance, index)."""
    vp = op.S @ op.v0                                   # v₀′ on the grid (spline slopes)
    best = (complex("nan"), np.inf, -1)
    for j in range(len(sigs)):
        V = vecs[:, j]
        nv = np.linalg.norm(V)
        if nv == 0.0:
            continue
        a = np.vdot(vp, V) / np.vdot(vp, vp)
        d = float(np.linalg.norm(V - a * vp) / np.linalg.norm(a * vp))
        if d < best[1]:
            best = (complex(sigs[j]), d, j)
    return best


def order4_pulse(pulse, params):
    """The pulse itself if it was solved with the order-4 state integrator; otherwise (files
    before issue 11, ``state_order`` 2) re-solved at order 4 on its own grid from its own ln v
    and β. Raises UsageError if that re-solve does not converge."""
    try:
        order = state_order_of(pulse)
    except (TypeError, ValueError):
        order = UNSTORED_STATE_ORDER
    if order == 4:
        return pulse
    from ..core.errors import UsageError
    from ..steady.solver import SteadySolution, solve_on_grid
    t0 = time.perf_counter()
    v = np.asarray(pulse.v, float)
    if not (np.all(np.isfinite(v)) and np.all(v > 0) and np.all(np.isfinite(pulse.xi))):
        raise UsageError(f"pulse {pulse.label}: non-finite or non-positive slip rates or grid; "
                         "it cannot be re-solved at state order 4")
    try:
        prob, x, stats = solve_on_grid(params, pulse.tau_d_ratio, np.asarray(pulse.xi, float),
                                       np.log(v), pulse.beta, state_order=4)
    except (RuntimeError, ValueError, FloatingPointError, np.linalg.LinAlgError) as exc:
        raise UsageError(f"pulse {pulse.label} was solved with state order 2 and could not be "
                         f"re-solved at order 4 on its grid ({exc})") from None
    if not stats.converged:
        raise UsageError(f"pulse {pulse.label} was solved with state order 2 and could not be "
                         f"re-solved at order 4 on its grid ({stats.message}): re-solve it with "
                         "the current `slippulse steady solve`/`family`")
    return SteadySolution(prob, x, stats, time.perf_counter() - t0, 0).to_pulse()


def pulse_spectrum(pulse, params, guesses=(), extra=True, tol=1e-7, label="", guess_modes=None):
    """Leading eigenvalues and modes of one pulse.

    guesses : σ values (1/s) to start from (e.g. the neighbouring pulse's eigenvalues, rescaled);
        the shifts DEFAULT_SHIFTS·c/L are tried after them (or alone) until an eigenvalue is found.
    extra : after the leading eigenvalue, search below it (shift at 0.4 Re σ₁, 2 candidates).
    tol : Newton's step criterion, relative; the iteration converges quadratically, so the σ
        returned (after that step) is accurate to ~tol² (measured: steps 1e-3, 4e-8, 1e-12 c/L).
    guess_modes : V₁ on this pulse's grid for each guess (e.g. the neighbour's mode moved over in
        ξ/L); Newton starts from (guess, mode) directly and the Arnoldi stage is skipped when it
        converges.
    """
    t0 = time.perf_counter()
    op = StabilityOperator(order4_pulse(pulse, params), params)
    unit = op.rate_unit
    found, failures, iters = [], [], 0

    def add(cand_sig, cand_vec, max_iter=12):
        nonlocal iters
        if not cand_sig.real > MIN_RE * unit:
            return
        if any(abs(cand_sig - f.sigma) < 1e-3 * max(abs(f.sigma), unit) for f in found):
            return
        eig = newton_eigen(op, cand_sig, cand_vec, tol=tol, min_re=MIN_RE * unit,
                           max_iter=max_iter)
        iters += eig.iterations
        if not eig.converged:
            failures.append(f"from {cand_sig / unit:.4g} c/L: {eig.message}")
            return
        if eig.sigma.real > MIN_RE * unit and not any(
                abs(eig.sigma - f.sigma) < 1e-6 * max(abs(f.sigma), unit) for f in found):
            found.append(eig)

    tracked = [complex(g) for g in guesses]
    if guess_modes is not None:
        for g, v in zip(tracked, guess_modes):
            if v is not None and g.real > MIN_RE * unit:
                add(g, np.asarray(v, complex))
    # Arnoldi at the tracked shifts, then (if they gave nothing) at the default shifts
    for sa in tracked + [complex(q * unit) for q in DEFAULT_SHIFTS]:
        if found:
            break
        if not sa.real > MIN_RE * unit:
            continue
        sig, vec = linearised_candidates(op, sa, k=1)
        for j in range(len(sig)):
            add(complex(sig[j]), vec[:, j])
    t1 = time.perf_counter()
    if found and extra:
        lead = max(f.sigma.real for f in found)
        sig, vec = linearised_candidates(op, 0.4 * lead, k=2)
        for j in range(len(sig)):
            add(complex(sig[j]), vec[:, j], max_iter=8)
    # complex eigenvalues come in conjugate pairs (M(σ̄) = conj M(σ)): add the partner
    for f in list(found):
        if abs(f.sigma.imag) > 1e-8 * abs(f.sigma) and not any(
                abs(g.sigma - f.sigma.conjugate()) < 1e-6 * abs(f.sigma) for g in found):
            found.append(Eigen(f.sigma.conjugate(), f.V.conj(), True, 0, f.residual,
                               "conjugate"))
    found.sort(key=lambda f: -f.sigma.real)
    t2 = time.perf_counter()
    nsig, nvec = neutral_modes(op)
    sig_t, terr, _ = _translation_check(op, nsig, nvec)
    # uniform slip (δ₁ = 1, V₁ = 0) is outside the V₁ form; in the δ₁ form it is exact at σ = 0:
    Md = op.matrices_delta(0.0)
    one = np.ones(op.n)
    uniform = float(np.max(np.abs(Md @ one) / (np.abs(Md) @ one)))   # componentwise backward error
    neutral = np.array([uniform, sig_t])
    modes = [op.fields(f.sigma, f.V) for f in found]
    if found:
        status, msg = "converged", f"{len(found)} eigenvalue(s) with Re sigma > {MIN_RE:g} c/L"
    elif failures:
        status, msg = "failed", "; ".join(failures[:3])
    else:
        status, msg = "converged", f"no eigenvalue with Re sigma > {MIN_RE:g} c/L found"
    t3 = time.perf_counter()
    return PulseSpectrum(label or pulse.label, np.array([f.sigma for f in found], complex), modes,
                         neutral, terr, unit, op.n, status, msg, t3 - t0, iters, failures,
                         {"leading": t1 - t0, "extra": t2 - t1, "neutral": t3 - t2},
                         operator=op, xi=op.xi)


# ------------------------------------------------------------------------------- storage
SPECTRUM_GROUP = "spectrum"
MODE_FIELDS = {"delta": ("m", "slip perturbation delta_1 (mode normalised: max |lnv_1| = 1)"),
               "V": ("m/s", "slip-rate perturbation V_1"),
               "phi": ("s", "state perturbation phi_1"),
               "lnv": ("1", "perturbation of ln(v/v* + 1)")}


def write_spectrum(path, res: PulseSpectrum, settings: dict):
    """Store `res` as /pulses/<label>/spectrum (replacing an earlier one), atomically.

    Layout (xarray: ``open_datatree(path, engine="h5netcdf")``): coordinate ``eigenvalue`` (index,
    by decreasing Re σ); ``sigma_real``/``sigma_imag`` (1/s) and ``s_per_L_*`` on it; mode fields
    ``delta_*``, ``V_*``, ``phi_*``, ``lnv_*`` on (eigenvalue, xi), xi being the pulse's own
    coordinate in the parent group; scalars and the status as attributes.
    """
    from ..core.h5io import atomic_update, coordinate, describe, upgrade_steady

    def fill(h5):
        upgrade_steady(h5)                       # xi of every pulse group a dimension scale
        grp_p = h5["pulses"][res.label]
        if SPECTRUM_GROUP in grp_p:
            del grp_p[SPECTRUM_GROUP]
        g = grp_p.create_group(SPECTRUM_GROUP)
        g.attrs["status"] = res.status
        g.attrs["message"] = res.message
        g.attrs["n_eigenvalues"] = int(res.sigmas.size)
        g.attrs["n_unstable"] = res.n_unstable
        lead = res.leading
        g.attrs["leading_sigma_real"] = lead.real
        g.attrs["leading_sigma_imag"] = lead.imag
        g.attrs["leading_s_per_L"] = lead.real / res.rate_unit
        g.attrs["rate_unit_c_over_L"] = res.rate_unit
        g.attrs["uniform_slip_backward_error"] = float(res.neutral[0].real)
        g.attrs["translation_sigma"] = float(res.neutral[1].real)
        g.attrs["translation_s_per_L"] = float(res.neutral[1].real / res.rate_unit)
        g.attrs["translation_mode_error"] = float(res.translation_error)
        g.attrs["n_points"] = res.n_points
        g.attrs["wall_time"] = res.wall_time
        g.attrs["newton_iterations"] = res.newton_iterations
        g.attrs["failures"] = "; ".join(res.failures)
        ref = res.refined
        if ref is not None:
            # the leading growth rate of record: finest nested level, error = last correction
            g.attrs["refine_status"] = ref.status
            g.attrs["refine_message"] = ref.message
            g.attrs["refine_n_points"] = np.asarray(ref.n_points, dtype="i8")
            g.attrs["refine_s_levels"] = np.asarray(ref.s_levels, dtype=float)
            g.attrs["refine_imag_levels"] = np.asarray(ref.imag_levels, dtype=float)
            g.attrs["refine_translation_levels"] = np.asarray(ref.translation_levels, float)
            g.attrs["refine_order"] = ref.order
            if ref.status == "converged":
                g.attrs["s"] = ref.s
                g.attrs["s_err"] = ref.s_err
                g.attrs["s_per_L"] = ref.s / ref.rate_unit
                g.attrs["s_err_per_L"] = ref.s_err / ref.rate_unit
                g.attrs["sign_resolved"] = int(ref.sign_resolved)
        cnt = res.count
        if cnt is not None:
            g.attrs["count_status"] = cnt.status
            g.attrs["count_message"] = cnt.message
            g.attrs["count_box_c_over_L"] = np.asarray(cnt.box, dtype=float)
            g.attrs["count_evaluations"] = int(cnt.n_evals)
            g.attrs["count_winding"] = float(cnt.winding)
            g.attrs["count_max_step_rad"] = float(cnt.max_step)
            if cnt.count is not None:
                g.attrs["count"] = int(cnt.count)
        for k, v in settings.items():
            g.attrs[f"setting_{k}"] = v
        units = {"leading_sigma_real": "1/s", "leading_sigma_imag": "1/s",
                 "rate_unit_c_over_L": "1/s", "translation_sigma": "1/s", "wall_time": "s",
                 "s": "1/s", "s_err": "1/s", "refine_s_levels": "1/s",
                 "refine_imag_levels": "1/s", "refine_translation_levels": "1/s"}
        for k, u in units.items():
            if k in g.attrs:
                g.attrs[f"{k}_units"] = u
        nm = len(res.modes)
        eig = coordinate(g, "eigenvalue", np.arange(nm, dtype="i8"), units="1", dtype="i8",
                         long_name="eigenvalue index, by decreasing Re sigma")
        xi = grp_p["xi"]
        sel = slice(None)
        if res.xi is not None and np.asarray(res.xi).size != xi.shape[0]:
            rx, px = np.asarray(res.xi, float), xi[...]
            step = (rx.size - 1) // max(px.size - 1, 1)
            if step >= 1 and rx.size - 1 == step * (px.size - 1) and np.array_equal(rx[::step], px):
                sel = slice(None, None, step)      # a nested refinement: the pulse's own nodes
            else:
                xi = coordinate(g, "xi_mode", rx, units="m",
                                long_name="co-moving coordinate of the modes")
        for part in ("real", "imag"):
            describe(g.create_dataset(f"sigma_{part}", data=getattr(res.sigmas, part)), "1/s",
                     f"eigenvalue sigma ({part} part), perturbations ~ exp(sigma t)", (eig,))
            describe(g.create_dataset(f"s_per_L_{part}",
                                      data=getattr(res.sigmas, part) / res.rate_unit), "1",
                     f"sigma L / c_p ({part} part): e-folds per pulse length travelled", (eig,))
        for name, (unit, long) in MODE_FIELDS.items():
            arr = (np.stack([m[name][sel] for m in res.modes]) if nm
                   else np.zeros((0, xi.shape[0]), complex))
            for part in ("real", "imag"):
                describe(g.create_dataset(f"{name}_{part}", data=getattr(arr, part)), unit,
                         f"{long} ({part} part)", (eig, xi))

    atomic_update(path, fill)


def read_spectrum(path, label):
    """The stored spectrum of a pulse as a dict (attrs + arrays), or None if there is none."""
    import h5py
    with h5py.File(path, "r") as h5:
        grp = h5["pulses"].get(label)
        if grp is None or SPECTRUM_GROUP not in grp:
            return None
        g = grp[SPECTRUM_GROUP]
        out = {k: (v.decode() if isinstance(v, bytes) else v) for k, v in g.attrs.items()}
        out["sigma"] = g["sigma_real"][...] + 1j * g["sigma_imag"][...]
        for name in MODE_FIELDS:
            out[name] = g[f"{name}_real"][...] + 1j * g[f"{name}_imag"][...]
        out["xi"] = (g["xi_mode"] if "xi_mode" in g else grp["xi"])[...]
        out["tau_d_ratio"] = float(grp.attrs["tau_d_ratio"])
        out["L"] = float(grp.attrs["L"])
        out["c_p"] = float(grp.attrs["c_p"])
    return out
