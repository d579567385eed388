"""Numerical kernels of the linear stability operator of a steady pulse (docs/spectrum.md §2).

The elastodynamic operator for a perturbation e^{σt} at fixed ξ = x − c_p t has the symbol
−λ √((k − iγ)² + κ²), λ = μ√(1−β²)/2, κ = σ/(c_s(1−β²)), γ = βκ. In real space (derivation in
docs/spectrum.md §2) it is

    K_σ δ = (λ/π) H[δ′] + (λγ/π) H₀[δ] + λ ∫ δ(z) W̃(ξ − z) dz,

with H the PV Hilbert operator and the kernel (r = ξ − z, x = κ|r|, s = sign r)

    W̃(r) = [e^{−sβx} x K₁(x) − 1 + sβx] / (π r²)   = λ₀ ln|r| + (smooth),   λ₀ = κ²/(2π),

whose σ-derivative is ∂_σ W̃ = x F′(x)/(σ π r²), x F′ = sβx − x² e^{−sβx} (sβ K₁(x) + K₀(x)).

This module holds what is compiled: the kernel tables in u = ln|r| (series for |x| ≤ 2, scaled
Bessel functions beyond), the product integration of W̃ against the cubic-spline interpolant on a
non-uniform grid (log part of near segments exact, Gauss–Legendre elsewhere), and the state
recursion of the linearised ageing law. Orchestration lives in :mod:`slippulse.spectrum.pulse`.
"""
from __future__ import annotations

import math

import numpy as np
from numba import njit, prange
from scipy.special import kve

from ..steady.equations import adjugate3
from ..steady.hilbert import (GL_N as _GL_N, GL_NODES as _GL_NODES, GL_RMIN as _GL_RMIN,
                              GL_WEIGHTS as _GL_WEIGHTS)

X_SERIES = 2.0          # |x| ≤ X_SERIES: power series; beyond: scaled Bessel functions
DU = 0.005              # table step in u = ln|r| (cubic interpolation error ≲ 1e-10 relative)
N_SERIES = 40           # terms of the power series (|z| = |x|²/4 ≤ 1: last term < 1e-60)
EXP_CUT = 60.0          # Re((1 ± β)x) beyond which e^{−(1±β)x} is dropped (e^{−60} ≈ 1e-26)

_GL8_S, _GL8_W = np.polynomial.legendre.leggauss(8)
_GL8_S = 0.5 * (_GL8_S + 1.0)
_GL8_W = 0.5 * _GL8_W


# ------------------------------------------------------------------------------------ tables
def _series_AC(z):
    """A(z) = I₁(x)/x, C(z), and their z-derivatives, z = x²/4 (arrays, complex).

    x K₁(x) = 1 + x² [ln(x/2) A(z) + C(z)]  (Abramowitz & Stegun 9.6.11, n = 1), with
    A = ½ Σ z^k/(k!(k+1)!),  C = −¼ Σ [ψ(k+1) + ψ(k+2)] z^k/(k!(k+1)!).
    """
    from scipy.special import digamma
    A = np.zeros_like(z)
    C = np.zeros_like(z)
    dA = np.zeros_like(z)
    dC = np.zeros_like(z)
    for k in range(N_SERIES):
        fac = 1.0 / (math.factorial(k) * math.factorial(k + 1))
        psi = digamma(k + 1.0) + digamma(k + 2.0)
        zk = z ** k
        A += 0.5 * fac * zk
        C += -0.25 * psi * fac * zk
        if k >= 1:
            zk1 = k * z ** (k - 1)
            dA += 0.5 * fac * zk1
            dC += -0.25 * psi * fac * zk1
    return A, C, dA, dC


def _psi2(y):
    """(e^{−y} − 1 + y)/y² and E(y) = (1 − e^{−y})/y, series for |y| < 0.5."""
    y = np.asarray(y, dtype=complex)
    small = np.abs(y) < 0.5
    ys = np.where(small, y, 1.0)
    yl = np.where(small, 1.0, y)
    p2 = np.zeros_like(y)
    e1 = np.zeros_like(y)
    term = np.ones_like(y)                  # (−y)^n / n! accumulated
    for n in range(1, 30):
        term = term * (-ys) / n
        if n >= 2:
            p2 += term / ys ** 2
        e1 += -term / ys
    p2 = np.where(small, p2, (np.exp(-yl) - 1.0 + yl) / yl ** 2)
    e1 = np.where(small, e1, -np.expm1(-yl) / yl)
    return p2, e1


def kernel_series(r, kappa, beta, sigma):
    """W̃(r) − λ₀ ln|r| and ∂_σW̃ − (2λ₀/σ) ln|r| for |κ r| ≤ X_SERIES (no cancellation at r → 0).

    With y = sβx, x = κ|r|, L = ln(x/2) = ln(κ/2) + ln|r|:
      W̃   = (κ²/π) [β² ψ₂(y) + e^{−y}(L A + C)],
      ∂_σW̃ = (κ²/(πσ)) [β² E(y) + e^{−y}((2 − y)(L A + C) + A + (x²/2)(L A′ + C′))].
    """
    r = np.asarray(r, dtype=float)
    s = np.sign(r)
    ar = np.abs(r)
    x = kappa * ar
    y = s * beta * x
    A, C, dA, dC = _series_AC(x * x / 4.0)
    lnr = np.log(ar)
    Lk = np.log(kappa / 2.0)
    p2, e1 = _psi2(y)
    ey = np.exp(-y)
    k2 = kappa * kappa / math.pi
    # ln|r| terms are collected separately so that the log coefficient can be subtracted exactly
    g = k2 * (beta ** 2 * p2 + ey * (Lk * A + C) + lnr * (ey * A - 0.5))
    inner_c = (2.0 - y) * (Lk * A + C) + A + 0.5 * x * x * (Lk * dA + dC)
    inner_l = (2.0 - y) * A + 0.5 * x * x * dA
    gs = k2 / sigma * (beta ** 2 * e1 + ey * inner_c + lnr * (ey * inner_l - 1.0))
    return g, gs


class KernelTables:
    """Tables of the kernel in u = ln|r| for one σ (complex allowed) and one pulse speed β.

    Region A, |κ r| ≤ 2: G = W̃ − λ₀ ln|r| and Gσ = ∂_σW̃ − (2λ₀/σ) ln|r| for r > 0 and r < 0.
    Region B, |κ r| > 2: E₁ = x K₁(x) eˣ and E₀ = x² K₀(x) eˣ (slowly varying), from which W̃ and
    ∂_σW̃ follow with the exact exponentials at evaluation time.
    """

    def __init__(self, sigma, beta, c_s, r_min, r_max):
        sigma = complex(sigma)
        if not sigma.real > 0.0:
            raise ValueError(f"sigma={sigma}: the kernel tables need Re sigma > 0")
        self.sigma = sigma
        self.beta = float(beta)
        self.kappa = sigma / (c_s * (1.0 - beta * beta))
        self.lam0 = self.kappa ** 2 / (2.0 * math.pi)
        ak = abs(self.kappa)
        u_lo = math.log(r_min) - 4 * DU
        u_hi = math.log(r_max) + 4 * DU
        u_a = min(math.log(X_SERIES / ak), u_hi)
        na = max(int(math.ceil((u_a - u_lo) / DU)) + 4, 8)
        self.ua0 = u_lo
        ua = u_lo + DU * np.arange(na)
        self.ua_max = u_lo + DU * (na - 4)       # region A is used up to here
        ga_p, gs_p = kernel_series(np.exp(ua), self.kappa, beta, sigma)
        ga_m, gs_m = kernel_series(-np.exp(ua), self.kappa, beta, sigma)
        self.GA = np.ascontiguousarray(np.stack([ga_p, ga_m, gs_p, gs_m]))
        ub0 = self.ua_max - 4 * DU
        nb = max(int(math.ceil((u_hi - ub0) / DU)) + 4, 8)
        self.ub0 = ub0
        x = self.kappa * np.exp(ub0 + DU * np.arange(nb))
        self.EB = np.ascontiguousarray(np.stack([x * kve(1, x), x * x * kve(0, x)]))

        #: at real σ the tables are real (exactly: zero imaginary parts), and the assembly runs
        #: in real arithmetic (2x faster than complex at N = 3542)
        self.real = (sigma.imag == 0.0 and not np.any(self.GA.imag)
                     and not np.any(self.EB.imag))
        if self.real:
            self.GA = np.ascontiguousarray(self.GA.real)
            self.EB = np.ascontiguousarray(self.EB.real)

    @property
    def dtype(self):
        return float if self.real else complex

    def args(self):
        if self.real:
            return (self.kappa.real, self.beta, self.sigma.real, self.lam0.real, self.ua0,
                    self.ua_max, self.GA, self.ub0, self.EB)
        return (self.kappa, self.beta, self.sigma, self.lam0, self.ua0, self.ua_max, self.GA,
                self.ub0, self.EB)

    def evaluate(self, r):
        """(W̃, ∂_σW̃) at the points r (array), through the compiled evaluator."""
        r = np.ascontiguousarray(r, dtype=float)
        out = np.empty((2, r.size), dtype=self.dtype)
        _eval_many(r, *self.args(), out)
        return out[0], out[1]


@njit(cache=True, inline="always")
def _lagrange4(tab, row, u, u0):
    """Cubic (4-point Lagrange) interpolation of tab[row, :] (uniform step DU from u0) at u."""
    t = (u - u0) / DU
    k = int(math.floor(t)) - 1
    n = tab.shape[1]
    if k < 0:
        k = 0
    elif k > n - 4:
        k = n - 4
    f = t - (k + 1)
    w0 = -f * (f - 1.0) * (f - 2.0) / 6.0
    w1 = (f + 1.0) * (f - 1.0) * (f - 2.0) / 2.0
    w2 = -(f + 1.0) * f * (f - 2.0) / 2.0
    w3 = (f + 1.0) * f * (f - 1.0) / 6.0
    return w0 * tab[row, k] + w1 * tab[row, k + 1] + w2 * tab[row, k + 2] + w3 * tab[row, k + 3]


@njit(cache=True, inline="always")
def _exp_factors(u, sbx, r2, sigma, ub0, EB):
    """Region B (|κr| > X_SERIES): the factors of e^{−(1+sβ)κ|r|} in W̃ and ∂_σW̃,
    E₁/(πr²) and −(sβx E₁ + E₀)/(σπr²), from the tables at u = ln|r| (sbx = sβκ|r|, r2 = πr²).
    The rest of each, (sβx − 1)/(πr²) and sβx/(σπr²), has no exponential."""
    e1 = _lagrange4(EB, 0, u, ub0)
    e0 = _lagrange4(EB, 1, u, ub0)
    return e1 / r2, -(sbx * e1 + e0) / (sigma * r2)


@njit(cache=True)
def _kernel(r, kappa, beta, sigma, lam0, ua0, ua_max, GA, ub0, EB):
    """(W̃(r), ∂_σW̃(r)) for r ≠ 0."""
    ar = abs(r)
    u = math.log(ar)
    lnr = u
    if u <= ua_max:
        neg = 1 if r < 0.0 else 0
        ut = max(u, ua0 + DU)                   # below the table: G is continuous at r = 0
        g = _lagrange4(GA, neg, ut, ua0)
        gs = _lagrange4(GA, 2 + neg, ut, ua0)
        return g + lam0 * lnr, gs + 2.0 * lam0 / sigma * lnr
    s = 1.0 if r > 0.0 else -1.0
    x = kappa * ar
    sbx = s * beta * x
    dec = (1.0 + s * beta) * x
    r2 = math.pi * ar * ar
    if dec.real > EXP_CUT:
        return (sbx - 1.0) / r2, sbx / (sigma * r2)
    bw, bs = _exp_factors(u, sbx, r2, sigma, ub0, EB)
    e = np.exp(-dec)                     # real at real σ (the kernel is then real)
    return (sbx - 1.0) / r2 + e * bw, sbx / (sigma * r2) + e * bs



@njit(cache=True)
def _eval_many(r, kappa, beta, sigma, lam0, ua0, ua_max, GA, ub0, EB, out):
    for k in range(r.size):
        a, b = _kernel(r[k], kappa, beta, sigma, lam0, ua0, ua_max, GA, ub0, EB)
        out[0, k] = a
        out[1, k] = b


# ------------------------------------------------------------------------------ assembly
@njit(cache=True, inline="always")
def _log_moments(x0):
    """L_k = ∫₀¹ s^k ln|s − x0| ds, k = 0..3 (closed form, no principal value; 0·ln 0 = 0)."""
    a = 1.0 - x0
    la = math.log(abs(a)) if a != 0.0 else 0.0
    lb = math.log(abs(x0)) if x0 != 0.0 else 0.0
    out = np.empty(4)
    for k in range(4):
        p = x0 ** (k + 1)
        poly = 0.0
        for m in range(k + 1):
            poly += x0 ** (k - m) / (m + 1.0)
        out[k] = ((1.0 - p) * la + p * lb - poly) / (k + 1.0)
    return out


@njit(cache=True, inline="always")
def _hermite(s):
    s2 = s * s
    s3 = s2 * s
    return 2 * s3 - 3 * s2 + 1.0, -2 * s3 + 3 * s2, s3 - 2 * s2 + s, s3 - s2


#: Filon–Gauss rule of :func:`assemble_w` for far segments whose exponential turns fast:
#: ∫₀¹ f(t) e^{−αt} dt ≈ Σ_k w_k(α) f(t_k), exact for f of degree < FILON_N, at the Gauss–Legendre
#: nodes t_k: w_k = W_k Σ_j (2j + 1) P̃_j(t_k) M_j(α), M_j = ∫₀¹ P̃_j(t) e^{−αt} dt the Legendre
#: moments (P̃_j(t) = P_j(2t − 1)), by their upward recurrence J_{j+1} = J_{j−1} + (2j + 1) J_j/z,
#: z = α/2, M_j = J_j/2, stable for j < |z|: used where |α| ≥ 2 FILON_N. With the target at least
#: two sub-panel lengths away, f (the smooth factor of the kernel times the spline basis) is
#: integrated to ~3e-11 relative (measured against adaptive quadrature).
FILON_N = 12
_FG_X, _FG_W = np.polynomial.legendre.leggauss(FILON_N)
FILON_NODES = 0.5 * (_FG_X + 1.0)
_FG_W = 0.5 * _FG_W
_FG_P = np.array([np.polynomial.legendre.legval(_FG_X, [0.0] * j + [1.0])
                  for j in range(FILON_N)])                           # P_j at the nodes
_FG_C = np.ascontiguousarray((2.0 * np.arange(FILON_N) + 1.0)[:, None] * _FG_P)


@njit(cache=True)
def filon_weights(alpha, out):
    """out[k] = w_k(α): ∫₀¹ f(t) e^{−αt} dt ≈ Σ_k out[k] f(FILON_NODES[k]) (module constants above);
    for |α| ≥ 2 FILON_N."""
    z = 0.5 * alpha
    e = np.exp(-2.0 * z)
    jm = (1.0 - e) / z
    jc = -(1.0 + e) / z + jm / z
    mom = np.empty(FILON_N, out.dtype)      # real α (real σ): real weights
    mom[0] = 0.5 * jm
    mom[1] = 0.5 * jc
    for j in range(1, FILON_N - 1):
        jn = jm + (2 * j + 1) * jc / z
        mom[j + 1] = 0.5 * jn
        jm = jc
        jc = jn
    for k in range(FILON_N):
        acc = z * 0.0
        for j in range(FILON_N):
            acc += _FG_C[j, k] * mom[j]
        out[k] = _FG_W[k] * acc


#: Sub-panel rule of :func:`assemble_w` for segments on one side of their target: True (default)
#: splits by the exponential of that side, e^{−(1+sβ)κ|r|}; False splits both sides as the fast one
#: (the rule before, kept for benchmarks/bench_assembly.py; no Filon–Gauss then).
SPLIT_PER_SIDE = True


@njit(cache=True, inline="always")
def _n_subpanels(x0, rr, dmin, h, kappa, beta, per_side, split_scale):
    """Sub-panels of a segment (rule of :func:`assemble_w`): 1/|κ| long on the side r > 0, or by
    the segment's own side's rate, while its exponential is not negligible."""
    ak = abs(kappa)
    m = 1
    if not per_side or rr <= 1.0:
        if ak * h > 1.0 and kappa.real * (1.0 - beta) * dmin < EXP_CUT:
            m = min(int(math.ceil(split_scale * ak * h)), int(512 * split_scale))
    else:
        side = 1.0 + beta if x0 > 0.5 else 1.0 - beta       # 1 + sβ, s = sign r
        if side * kappa.real * dmin < EXP_CUT:
            m = min(int(math.ceil(split_scale * side * ak * h / (1.0 + beta))),
                    int(512 * split_scale))
    return m


@njit(cache=True, inline="always")
def _add_filon(acc, x0, h, dmin, kappa, beta, sigma, ub0, EB, wf):
    """A far segment whose live exponential turns fast, by Filon–Gauss on mf ≤ 2 sub-panels,
    each at least two of its lengths from the target: (the entries added to ``acc``, True), or
    (``acc``, False) where the phase is below 2·FILON_N and Gauss–Legendre takes it."""
    a0, a1, b0, b1, c0, c1, d0, d1 = acc
    sgn = 1.0 if x0 > 0.5 else -1.0
    c = (1.0 + sgn * beta) * kappa
    mf = 1 if dmin >= 2.0 * h else 2
    alpha = c * (h / mf)
    if abs(alpha) < 2.0 * FILON_N:
        return acc, False
    filon_weights(alpha, wf)
    hs = h / mf
    for sub in range(mf):
        # near end of the sub-panel, t running away from the target
        s_n = (sub + 1.0) / mf if sgn > 0.0 else sub / (1.0 * mf)
        pref = np.exp(-c * (h * abs(x0 - s_n)))
        for kq in range(FILON_N):
            sg = s_n - sgn * FILON_NODES[kq] / mf
            r = h * (x0 - sg)
            ar = abs(r)
            x = kappa * ar
            sbx = sgn * beta * x
            r2 = math.pi * r * r
            bw, bs = _exp_factors(math.log(ar), sbx, r2, sigma, ub0, EB)
            wq = _FG_W[kq] * hs
            we = wf[kq] * hs * pref
            kw = wq * (sbx - 1.0) / r2 + we * bw
            ks = wq * sbx / (sigma * r2) + we * bs
            h00, h01, h10, h11 = _hermite(sg)
            a0 += h00 * kw
            a1 += h01 * kw
            b0 += h10 * kw
            b1 += h11 * kw
            c0 += h00 * ks
            c1 += h01 * ks
            d0 += h10 * ks
            d1 += h11 * ks
    return (a0, a1, b0, b1, c0, c1, d0, d1), True


@njit(cache=True, inline="always")
def _add_log(acc, x0, h, lam0, ls):
    """λ₀ ∫ p(s) ln|h (x0 − s)| h ds of a near segment (and its σ-derivative, ``ls`` = 2λ₀/σ)
    with exact moments, added to ``acc``."""
    a0, a1, b0, b1, c0, c1, d0, d1 = acc
    L = _log_moments(x0)
    lh = math.log(h)
    i00 = 2 * L[3] - 3 * L[2] + L[0] + 0.5 * lh
    i01 = -2 * L[3] + 3 * L[2] + 0.5 * lh
    i10 = L[3] - 2 * L[2] + L[1] + lh / 12.0
    i11 = L[3] - L[2] - lh / 12.0
    a0 += lam0 * h * i00
    a1 += lam0 * h * i01
    b0 += lam0 * h * i10
    b1 += lam0 * h * i11
    c0 += ls * h * i00
    c1 += ls * h * i01
    d0 += ls * h * i10
    d1 += ls * h * i11
    return a0, a1, b0, b1, c0, c1, d0, d1


@njit(cache=True, inline="always")
def _add_gauss(acc, m, near, rr, x0, h, kern, ls):
    """Gauss–Legendre on ``m`` sub-panels (near: 8 points on the kernel less its λ₀ ln|r|;
    far: the order of the Hilbert assembly for the nearest sub-panel's distance), added to
    ``acc``."""
    kappa, beta, sigma, lam0, ua0, ua_max, GA, ub0, EB = kern
    a0, a1, b0, b1, c0, c1, d0, d1 = acc
    if near:
        q = -1
        nq = 8
    else:
        q = 0
        rsub = m * (rr - 1.0) + 1.0            # distance of the nearest sub-panel
        for kq in range(_GL_N.size):
            if rsub >= _GL_RMIN[kq]:
                q = kq
                break
        nq = _GL_N[q]
    for sub in range(m):
        for kq in range(nq):
            if q < 0:
                sl = _GL8_S[kq]
                wl = _GL8_W[kq]
            else:
                sl = _GL_NODES[q, kq]
                wl = _GL_WEIGHTS[q, kq]
            sg = (sub + sl) / m
            wg = wl / m * h
            r = h * (x0 - sg)
            kw, ks = _kernel(r, kappa, beta, sigma, lam0, ua0, ua_max, GA, ub0, EB)
            if near:
                lr = math.log(abs(r))
                kw -= lam0 * lr
                ks -= ls * lr
            h00, h01, h10, h11 = _hermite(sg)
            a0 += wg * h00 * kw
            a1 += wg * h01 * kw
            b0 += wg * h10 * kw
            b1 += wg * h11 * kw
            c0 += wg * h00 * ks
            c1 += wg * h01 * ks
            d0 += wg * h10 * ks
            d1 += wg * h11 * ks
    return a0, a1, b0, b1, c0, c1, d0, d1


@njit(parallel=True, cache=True)
def assemble_w(xi, kern, out, per_side=SPLIT_PER_SIDE, split_scale=1.0):
    """Product integration of W̃ (into AW, BW) and ∂_σW̃ (into AS, BS) against the cubic spline;
    ``kern`` = :meth:`KernelTables.args`, ``out`` = (AW, BW, AS, BS).

    Row i, target ξ_i: ∫ p(z) W̃(ξ_i − z) dz = Σ_j AW[i, j] u_j + BW[i, j] m_j (m: spline slopes).
    Near segments (|2x0 − 1| ≤ 3): λ₀ ln|r| exactly through log moments, the rest with 8-point
    Gauss–Legendre; far segments: Gauss–Legendre with the order of the Hilbert assembly.

    Segments where the exponential part of the kernel, e^{−(1+sβ)κ|r|} (s = sign r), is not
    negligible are split into sub-panels of length 1/|κ| on the side r > 0. A segment wholly on
    one side (|2x0 − 1| > 1) is split by its own side's rate: (1 + sβ)|κ| h/(1 + β) sub-panels
    while (1 + sβ) Re κ times its distance is below EXP_CUT. On the side r < 0 the rate is
    (1 − β)|κ|, ≈ 1e-3 |κ| at the deep pulses, so those segments need no split
    (``per_side=False``: every segment split as the side r > 0 and kept while (1 − β) Re κ times
    its distance is below EXP_CUT, as before; 2–3× the evaluations at |σ| ~ c_p/L there).
    ``split_scale`` multiplies every sub-panel count (> 1: a finer reference, for tests).

    With ``per_side``, a far segment (|2x0 − 1| > 3) that the rule above would split,
    with a phase (1 + sβ)κ h of at least 2·FILON_N over one or two sub-panels, is integrated by
    Filon–Gauss instead (:func:`filon_weights`): W̃ = (sβx − 1)/(πr²) + e^{−(1+sβ)x} E₁(x)/(πr²),
    x = κ|r|; the first part by Gauss–Legendre, the exponential against the smooth rest exactly,
    on the FILON_N nodes of each sub-panel. The segments of the graded tail behind a pulse reach
    |κ| h ~ 10⁴ at |σ| ~ c_p/L, where the split stopped at 512 sub-panels and left ∂_σW̃ a few %
    off (1e-12 now, against adaptive quadrature), at 10–100 times the cost.
    """
    kappa, beta, sigma, lam0 = kern[0], kern[1], kern[2], kern[3]
    AW, BW, AS, BS = out
    n = xi.size
    ls = 2.0 * lam0 / sigma
    zero = kappa * 0.0                          # real or complex, as κ (and AW) are
    for i in prange(n):
        wf = np.empty(FILON_N, AW.dtype)
        xt = xi[i]
        for j in range(n - 1):
            h = xi[j + 1] - xi[j]
            x0 = (xt - xi[j]) / h
            rr = abs(2.0 * x0 - 1.0)
            dmin = 0.0 if rr <= 1.0 else 0.5 * h * (rr - 1.0)
            m = _n_subpanels(x0, rr, dmin, h, kappa, beta, per_side, split_scale)
            acc = (zero, zero, zero, zero, zero, zero, zero, zero)
            near = rr <= 3.0
            if per_side and not near and m > 1:
                acc, done = _add_filon(acc, x0, h, dmin, kappa, beta, sigma, kern[7], kern[8],
                                       wf)
                if done:
                    m = 0                       # no Gauss–Legendre sub-panels below
            if near:
                acc = _add_log(acc, x0, h, lam0, ls)
            acc = _add_gauss(acc, m, near, rr, x0, h, kern, ls)
            a0, a1, b0, b1, c0, c1, d0, d1 = acc
            AW[i, j] += a0
            AW[i, j + 1] += a1
            BW[i, j] += h * b0
            BW[i, j + 1] += h * b1
            AS[i, j] += c0
            AS[i, j + 1] += c1
            BS[i, j] += h * d0
            BS[i, j + 1] += h * d1


# ---------------------------------------------------- order 4: state and slip recursions (Radau IIA)
@njit(cache=True, inline="always")
def _inv3(M, Mi):
    """Mi = M⁻¹ for a 3×3 M, real or complex (adjugate / determinant)."""
    det = adjugate3(M, Mi)
    for r in range(3):
        for k in range(3):
            Mi[r, k] /= det


@njit(cache=True)
def _radau_scratch(zero):
    """Scratch arrays of :func:`_radau_row`: M, M⁻¹, M⁻¹A (3×3), r, ∂r/∂σ, the rates (3), of the
    type of `zero` (real at real σ, complex otherwise)."""
    return (np.full((3, 3), zero), np.full((3, 3), zero), np.full((3, 3), zero),
            np.full(3, zero), np.full(3, zero), np.full(3, zero))


@njit(cache=True, inline="always")
def _radau_row(A, h, rates, M, Mi, T, r, dr):
    """r = h e₃ᵀ (I + h A R)⁻¹ A and dr = ∂r/∂σ for R = diag(rates) (rates = w_k + σ, or σ):
    the weights of the stage sources in the last stage of one Radau IIA step for
    y' = −R(s) y + g(s) from y = 0; ∂(I + hAR)/∂σ = hA, so dr = −h e₃ᵀ M⁻¹ (hA) M⁻¹ A."""
    for a_ in range(3):
        for k in range(3):
            M[a_, k] = h * A[a_, k] * rates[k] + (1.0 if a_ == k else 0.0)
    _inv3(M, Mi)
    for k in range(3):                              # T = M⁻¹ A
        for a_ in range(3):
            T[a_, k] = Mi[a_, 0] * A[0, k] + Mi[a_, 1] * A[1, k] + Mi[a_, 2] * A[2, k]
    for k in range(3):
        r[k] = h * T[2, k]
        dr[k] = -h * h * (T[2, 0] * T[0, k] + T[2, 1] * T[1, k] + T[2, 2] * T[2, k])


@njit(cache=True)
def state_rows4(stages, inv_v, A, sigma, Vm, out, deriv):
    """Rows of Y = Φ(σ) Vm and dY = ∂_σΦ(σ) Vm (Vm independent of σ), order 4, into
    ``out`` = (Y, dY); ``stages`` = (hs, j0s, lws, ws, G, omegas), the crossing times, the
    stencils and the steady stage values of the cells.

    Φ(σ) maps a slip-rate perturbation V to the state perturbation φ₁ of
    dφ₁/ds = −(w + σ) φ₁ + G(s) (V/v₀)(s) along a material point (G = −φ₀ ∂w/∂ln v), from φ₁ = 0
    at ξ_N. Over the crossing of cell i (time h), the homogeneous part exactly and the forced
    part by one step of 3-stage Radau IIA:

        φ₁,i = e^{−Ω − σh} φ₁,i+1 + Σ_k r_k G_k (V/v₀)(s_k),   r = h e₃ᵀ (I + hA(W + σ))⁻¹ A,

    with w and φ₀ at the stages from the steady order-4 map (``ws``; G from its stage values) and
    V/v₀ at the inner stages from the cubic through nodes j0..j0+3 (``lws``), at the last from
    node i. Stiffly accurate for any (w + σ)h (φ₁,i → G_3 (V/v₀)_i/(w_i + σ)); order 4.
    """
    hs, j0s, lws, ws, G, omegas = stages
    Y, dY = out
    n = hs.size + 1
    ncol = Vm.shape[1]
    zero = sigma * 0.0                  # real σ: real arithmetic throughout (Y, dY real)
    cl = np.full(4, zero)
    dcl = np.full(4, zero)
    M, Mi, T, r, dr, rates = _radau_scratch(zero)
    for col in range(ncol):
        Y[n - 1, col] = 0.0
        if deriv:
            dY[n - 1, col] = 0.0
    for i in range(n - 2, -1, -1):
        h = hs[i]
        for k in range(3):
            rates[k] = ws[i, k] + sigma
        _radau_row(A, h, rates, M, Mi, T, r, dr)
        e0 = np.exp(-omegas[i] - sigma * h)
        j0 = j0s[i]
        for l in range(4):
            cl[l] = (r[0] * G[i, 0] * lws[i, 0, l] + r[1] * G[i, 1] * lws[i, 1, l]) * inv_v[j0 + l]
            dcl[l] = (dr[0] * G[i, 0] * lws[i, 0, l] + dr[1] * G[i, 1] * lws[i, 1, l]) \
                * inv_v[j0 + l]
        cl[i - j0] += r[2] * G[i, 2] * inv_v[i]
        dcl[i - j0] += dr[2] * G[i, 2] * inv_v[i]
        for col in range(ncol):
            y1 = Y[i + 1, col]
            acc = e0 * y1
            for l in range(4):
                acc += cl[l] * Vm[j0 + l, col]
            Y[i, col] = acc
            if deriv:
                dacc = e0 * dY[i + 1, col] - h * e0 * y1
                for l in range(4):
                    dacc += dcl[l] * Vm[j0 + l, col]
                dY[i, col] = dacc


@njit(cache=True)
def slip_coefficients4(hs, j0s, lws, vst, inv_v, A, sigma):
    """Order-4 recursion δ_i = a_i δ_{i+1} + Σ_l B_il V_{j0+l} for (σ − c∂_ξ) δ = V, bounded ahead
    (δ = 0 at ξ_N), and the σ-derivatives (da, dB).

    Along a material point dδ/ds = V − σδ over the crossing time h: a_i = e^{−σh} exactly, the
    forced part by one step of 3-stage Radau IIA, r = h e₃ᵀ (I + σhA)⁻¹ A, with V at the stages
    = v₀(s_k) (V/v₀)(s_k) (v₀ from the cubic of ln v, ``vst``; V/v₀ from the cubic of the nodal
    values; the last stage is node i). Stiffly accurate (σh → ∞: δ_i → V_i/σ); order 4.
    """
    n1 = hs.size
    zero = sigma * 0.0                  # real σ: real coefficients
    a = np.full(n1, zero)
    da = np.full(n1, zero)
    B = np.full((n1, 4), zero)
    dB = np.full((n1, 4), zero)
    M, Mi, T, r, dr, rates = _radau_scratch(zero)
    for k in range(3):
        rates[k] = sigma
    for i in range(n1):
        h = hs[i]
        a[i] = np.exp(-sigma * h)
        da[i] = -h * a[i]
        _radau_row(A, h, rates, M, Mi, T, r, dr)
        j0 = j0s[i]
        for l in range(4):
            s0 = vst[i, 0] * lws[i, 0, l] * inv_v[j0 + l]
            s1 = vst[i, 1] * lws[i, 1, l] * inv_v[j0 + l]
            B[i, l] = r[0] * s0 + r[1] * s1
            dB[i, l] = dr[0] * s0 + dr[1] * s1
        B[i, i - j0] += r[2]
        dB[i, i - j0] += dr[2]
    return a, B, da, dB


@njit(cache=True, inline="always")
def _row_times_D4(x, a, B, j0s, z, out):
    """out = x D for one row x, D = (I − U)⁻¹ B (U[i, i+1] = a_i; row i of B: B[i, l] at column
    j0_i + l; last row zero); z = x (I − U)⁻¹ is left in z."""
    n = x.size
    z[0] = x[0]
    for j in range(1, n):
        z[j] = x[j] + a[j - 1] * z[j - 1]
    for k in range(n):
        out[k] = 0.0
    for i in range(n - 1):
        zi = z[i]
        j0 = j0s[i]
        for l in range(4):
            out[j0 + l] += zi * B[i, l]


@njit(cache=True, inline="always")
def _row_times_dD4(dx, z, a, B, j0s, da, dB, u, out):
    """out = x′ D + x D′ for one row (D′ = (I−U)⁻¹(U′ D + B′)), with z = x (I − U)⁻¹ left by
    :func:`_row_times_D4` on x; u is scratch of the row's length."""
    n = dx.size
    _row_times_D4(dx, a, B, j0s, u, out)                # X′ D
    u[0] = 0.0                                          # Z U′, then · D
    for j in range(1, n):
        u[j] = z[j - 1] * da[j - 1]
    zz = np.empty(n, out.dtype)
    w = np.empty(n, out.dtype)
    _row_times_D4(u, a, B, j0s, zz, w)
    for i in range(n - 1):                              # + Z B′
        zi = z[i]
        j0 = j0s[i]
        for l in range(4):
            w[j0 + l] += zi * dB[i, l]
    for k in range(n):
        out[k] += w[k]


@njit(parallel=True, cache=True)
def times_D4(X, dX, a, B, j0s, da, dB, XD, dXD, deriv):
    """XD = X D(σ) and, if deriv, dXD = X′ D + X D′ (D′ = (I−U)⁻¹(U′ D + B′)), row by row, O(N²),
    for the banded B of the order-4 slip recursion."""
    m, n = X.shape
    for r in prange(m):
        z = np.empty(n, XD.dtype)
        t = np.empty(n, XD.dtype)
        u = np.empty(n, XD.dtype)
        _row_times_D4(X[r], a, B, j0s, z, t)
        XD[r] = t
        if deriv:
            _row_times_dD4(dX[r], z, a, B, j0s, da, dB, u, t)
            dXD[r] = t


@njit(parallel=True, cache=True)
def stability_rows(elastic, coef, out, friction, slip, pin, has_w, pinned, deriv):
    """M(σ) and M′(σ) of :meth:`slippulse.spectrum.operators.StabilityOperator.matrices`, row by
    row in one pass, written over ``out`` = (Phi, dPhi) (which hold Φ(σ) and ∂_σΦ on entry);
    ``elastic`` = (W, dW, H, H0), ``coef`` = (cx, cdx, ch, τ), ``friction`` = (corr, fφ, f_v),
    ``slip`` = (a, B, j0s, da, dB) of the slip recursion, ``pin`` = (pin_r, pin_t):

        X  = cx[0] W + cx[1] H + cx[2] H0,      X′ = cdx[0] W′ + cdx[1] H + cdx[2] H0,
        M  = (fφ Φ + corr + diag(f_v) + ch H − X D)/τ − pin_r pin_tᵀ,
        M′ = (fφ Φ′ − (X′ D + X D′))/τ,

    with X D and X′ D + X D′ as in :func:`times_D4`. has_w False: the W terms are absent (σ = 0;
    W, dW are not read); pinned False: no rank-one term. Each row of X is formed, multiplied by
    D and combined while it is in cache: the numpy passes and the X, XD temporaries it replaces
    cost 1.1 s of a 4.4 s assembly at N = 3542."""
    W, dW, H, H0 = elastic
    cx, cdx, ch, tau = coef
    Phi, dPhi = out
    corr, fphi, fv = friction
    a, B, j0s, da, dB = slip
    pin_r, pin_t = pin
    m, n = Phi.shape
    for r in prange(m):
        x = np.empty(n, Phi.dtype)
        z = np.empty(n, Phi.dtype)
        t = np.empty(n, Phi.dtype)
        for k in range(n):
            x[k] = cx[1] * H[r, k] + cx[2] * H0[r, k]
        if has_w:
            for k in range(n):
                x[k] += cx[0] * W[r, k]
        _row_times_D4(x, a, B, j0s, z, t)
        fr = fphi[r]
        for k in range(n):
            val = fr * Phi[r, k] + corr[r, k] + ch * H[r, k]
            if k == r:
                val += fv[r]
            val = (val - t[k]) / tau
            if pinned:
                val -= pin_r[r] * pin_t[k]
            Phi[r, k] = val
        if deriv:
            u = np.empty(n, Phi.dtype)
            for k in range(n):
                x[k] = cdx[1] * H[r, k] + cdx[2] * H0[r, k]
            if has_w:
                for k in range(n):
                    x[k] += cdx[0] * dW[r, k]
            _row_times_dD4(x, z, a, B, j0s, da, dB, u, t)
            for k in range(n):
                dPhi[r, k] = (fr * dPhi[r, k] - t[k]) / tau
