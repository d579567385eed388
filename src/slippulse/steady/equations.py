"""Steady-pulse residual and its analytic Jacobian (paper Eqs. S1–S5), on a fixed non-uniform grid.

Unknowns x = (y_1..y_N, β) with y_i = ln v_i. Equations (N + 1):

    Δ_i = [τ_d − σ f(v_i, φ_i) − μ F_III(β) (H (v − v_stick))_i] / τ_d = 0,   i = 1..N
    y_p − y_pin = 0                                  (phase condition: pins the translation)

The state φ_i(v, β) follows from −β c_s dφ/dξ = g(v, φ) = 1 − w(v) φ, w = √(v²+v*²)/D, integrated
from the rest state φ_N = φ_ss(v_stick) at the front end (ξ_N, ahead of the pulse) backward. A
material point crosses the cell [ξ_i, ξ_{i+1}] in the time h = (ξ_{i+1} − ξ_i)/(β c_s). Two
integrators (``SteadyProblem(state_order=...)``):

* order 4 (default, :func:`integrate_state_radau`): exactly φ_i = φ_{i+1} e^{−Ω} + (1 − e^{−Ω})/w_i
  + ψ(h), Ω = ∫w over the crossing, ψ' = −wψ + 1 − w/w_i from ψ = 0; ψ by one step of 3-stage
  Radau IIA (stage equations linear, solved exactly), w at the inner stages from the cubic of ln v
  through the four nodes around the cell;
* order 2 (:func:`integrate_state`): exact for w frozen at w_{i+1} over the first half of the
  crossing and at w_i over the second:

      φ_i = φ_{i+1} e^{−x_a − x_b} + (h/2) [E(x_a) e^{−x_b} + E(x_b)],   x_a = w_{i+1} h/2,
      x_b = w_i h/2,  E(x) = (1 − e^{−x})/x.

Both are exact at constant v, unconditionally stable and stiff-accurate (φ_i → 1/w_i when
w h → ∞), so under-resolved Newton iterates do not heal spuriously. See docs/steady.md §2 for the
derivation and the Jacobians.
"""
from __future__ import annotations

import math

import numpy as np
from numba import njit

from ..core import friction as fr
from .hilbert import hilbert_matrix


@njit(cache=True, inline="always")
def _E(x):
    """E(x) = (1 − e^{−x})/x and E'(x), series for small x."""
    if x < 1e-2:
        # E = Σ (−x)^n/(n+1)!,  E' = Σ_{n≥1} n (−x)^(n−1) (−1)/(n+1)!
        e = 1.0 - x / 2.0 + x * x / 6.0 - x ** 3 / 24.0 + x ** 4 / 120.0 - x ** 5 / 720.0 \
            + x ** 6 / 5040.0
        de = -0.5 + x / 3.0 - x * x / 8.0 + x ** 3 / 30.0 - x ** 4 / 144.0 + x ** 5 / 840.0
        return e, de
    em = math.exp(-x)
    e = -math.expm1(-x) / x
    return e, (em - e) / x


@njit(cache=True)
def integrate_state(xi, v, beta_cs, phi_end, w, dw_dy, with_jacobian=True):
    """State φ_i, upper-triangular ∂φ_i/∂y_j (y = ln v), ∂φ_i/∂(β c_s) and ∂φ_i/∂φ_N.

    Parameters
    ----------
    xi : grid (ascending), v : slip rates, beta_cs : β c_s (m/s), phi_end : φ at ξ_N,
    w : healing rates √(v²+v*²)/D, dw_dy : v ∂w/∂v.
    """
    n = xi.size
    phi = np.empty(n)
    P = np.zeros((n, n) if with_jacobian else (1, 1))
    dphi_dc = np.zeros(n)
    G = np.empty(n)                                     # ∂φ_i/∂φ_N
    G[n - 1] = 1.0
    phi[n - 1] = phi_end
    for i in range(n - 2, -1, -1):
        h2 = 0.5 * (xi[i + 1] - xi[i]) / beta_cs      # half crossing time
        xa = w[i + 1] * h2
        xb = w[i] * h2
        ea, dea = _E(xa)
        eb, deb = _E(xb)
        exa = math.exp(-xa)
        exb = math.exp(-xb)
        phi_mid = phi[i + 1] * exa + h2 * ea
        phi[i] = phi_mid * exb + h2 * eb
        a = exa * exb                                   # ∂φ_i/∂φ_{i+1}
        dpa = (-phi[i + 1] * exa + h2 * dea) * exb      # ∂φ_i/∂x_a
        dpb = -phi_mid * exb + h2 * deb                 # ∂φ_i/∂x_b
        if with_jacobian:
            # row i of P: a · row i+1 plus the local dependence on y_{i+1} (via x_a) and y_i (via x_b)
            for j in range(i + 1, n):
                P[i, j] = a * P[i + 1, j]
            P[i, i + 1] += dpa * h2 * dw_dy[i + 1]
            P[i, i] += dpb * h2 * dw_dy[i]
        # ∂/∂c (c = β c_s): h2 ∝ 1/c, x_a, x_b ∝ 1/c ⇒ direct part = −(x_a dpa + x_b dpb + h2 ∂φ/∂h2)/c
        dphi_dh2 = ea * exb + eb
        direct = -(xa * dpa + xb * dpb + h2 * dphi_dh2) / beta_cs
        dphi_dc[i] = a * dphi_dc[i + 1] + direct
        G[i] = a * G[i + 1]
    return phi, P, dphi_dc, G


# ------------------------------------------------------------------ order 4: Radau IIA on the remainder
_S6 = math.sqrt(6.0)
#: Radau IIA, 3 stages (order 5, stage order 3, L-stable, stiffly accurate: the last row is b)
RADAU_C = np.array([(4.0 - _S6) / 10.0, (4.0 + _S6) / 10.0, 1.0])
RADAU_A = np.array([[(88.0 - 7.0 * _S6) / 360.0, (296.0 - 169.0 * _S6) / 1800.0, (-2.0 + 3.0 * _S6) / 225.0],
                    [(296.0 + 169.0 * _S6) / 1800.0, (88.0 + 7.0 * _S6) / 360.0, (-2.0 - 3.0 * _S6) / 225.0],
                    [(16.0 - _S6) / 36.0, (16.0 + _S6) / 36.0, 1.0 / 9.0]])


@njit(cache=True, inline="always")
def _lagrange(xi, j0, m, x, out):
    """Lagrange weights of the m nodes xi[j0:j0+m] at x (into out[:m])."""
    for k in range(m):
        lk = 1.0
        for l in range(m):
            if l != k:
                lk *= (x - xi[j0 + l]) / (xi[j0 + k] - xi[j0 + l])
        out[k] = lk


@njit(cache=True, inline="always")
def _radau_start(n, phi_end):
    """The sweep's arrays from the tail node: φ (φ_N set), ∂φ/∂(β c_s), ∂φ/∂φ_N (G_N = 1), the
    stencil width and the cell workspace."""
    phi = np.empty(n)
    dphi_dc = np.zeros(n)
    G = np.empty(n)
    G[n - 1] = 1.0
    phi[n - 1] = phi_end
    return phi, dphi_dc, G, (4 if n >= 4 else n), _radau_workspace()


@njit(cache=True)
def integrate_state_radau(xi, y, beta_cs, phi_end, v_star, D, A, c, with_jacobian=True):
    """State φ_i of order 4: φ_i = φ_{i+1} e^{−Ω} + (1 − e^{−Ω})/w_i + ψ_i (see Notes).

    Parameters
    ----------
    xi : grid (ascending), m; y : ln v at the nodes; beta_cs : β c_s, m/s; phi_end : φ at ξ_N, s;
    v_star, D : friction constants (w = √(v² + v*²)/D); A, c : Radau IIA tableau (RADAU_A, RADAU_C).

    Returns
    -------
    φ, ∂φ_i/∂y_j (nonzero for j ≥ i − 1; 1×1 without the Jacobian), ∂φ/∂(β c_s), ∂φ/∂φ_N.

    Notes
    -----
    Across the cell a material point moves from ξ_{i+1} (s = 0) to ξ_i (s = h = Δξ/(β c_s)), with
    dφ/ds = 1 − w(s) φ. Exactly, with Ω = ∫₀ʰ w ds and p_i = 1/w_i,

        φ(h) = φ(0) e^{−Ω} + p_i (1 − e^{−Ω}) + ψ(h),   ψ' = −w ψ + (1 − w/w_i),  ψ(0) = 0.

    ψ is advanced by one step of 3-stage Radau IIA, whose stage equations are linear and solved
    exactly: (I + h A W) Ψ = h A f, f_k = 1 − w_k/w_i, W = diag(w_k), ψ(h) = Ψ_3; Ω = h Σ b_k w_k
    (b the last row of A). w at the interior stages s = c_k h comes from ln v interpolated by the
    cubic through the four nodes around the cell. Properties: exact at constant v (f = 0, ψ = 0);
    stiffly accurate (w h → ∞: e^{−Ω} → 0 and Ψ → W⁻¹ f, so ψ(h) → f_3/w_3 = 0 and φ_i → 1/w_i);
    unconditionally stable (Radau IIA is AN-stable); order 4 in h (the cubic interpolant of ln v;
    Radau alone is order 5).
    Derivatives: with λ = M⁻ᵀ e_3, μ = h Aᵀ λ: ∂ψ/∂w_k = −μ_k (1/w_3 + Ψ_k) (k < 3),
    ∂ψ/∂w_3 = (μ_1 w_1 + μ_2 w_2)/w_3² − μ_3 Ψ_3, ∂ψ/∂h = Σ_j μ_j (f_j − w_j Ψ_j)/h.
    """
    n = xi.size
    P = np.zeros((n, n) if with_jacobian else (1, 1))
    phi, dphi_dc, G, m, work = _radau_start(n, phi_end)
    lw = work[0]
    dwk = work[2]
    for i in range(n - 2, -1, -1):
        phi[i], a, dw0, dw1, dw2, dh, h, j0 = _radau_cell(xi, y, i, beta_cs, phi[i + 1], v_star,
                                                          D, A, c, m, work)
        dphi_dc[i] = a * dphi_dc[i + 1] - h * dh / beta_cs      # h ∝ 1/(β c_s)
        G[i] = a * G[i + 1]
        if with_jacobian:
            for j in range(max(i - 2, 0), n):       # row i+1 is nonzero from column i − 1 on
                P[i, j] = a * P[i + 1, j]
            for l in range(m):
                P[i, j0 + l] += (dw0 * dwk[0] * lw[0, l] + dw1 * dwk[1] * lw[1, l])
            P[i, i] += dw2 * dwk[2]
    return phi, P, dphi_dc, G


@njit(cache=True)
def radau_jacobian_into(xi, y, beta_cs, phi_end, v_star, D, table, H, terms, J):
    """The y-block of the steady Jacobian, written into J[:n, :n] in one sweep without the
    dense state Jacobian P = ∂φ/∂y (:func:`integrate_state_radau`, order 4; ``table`` = (A, c),
    its Radau table; ``terms`` = (cv, fphi, dv)):

        J_ij = H_ij cv_j − fphi_i P_ij − δ_ij dv_i.

    Row i of P is a · (row i + 1) plus the cell's local terms (the recursion of
    :func:`integrate_state_radau`), so one row of P is kept and each row of J is filled as soon
    as its row of P is known: one pass over J instead of filling P (N² zeros, then the band),
    H·cv and fphi·P as separate N² temporaries (the same operations in the same order, so the
    same numbers). Returns (∂φ/∂(β c_s), ∂φ/∂φ_N), as :func:`integrate_state_radau`.
    """
    A, c = table
    cv, fphi, dv = terms
    n = xi.size
    row = np.zeros(n)                                   # row i + 1 of P (row n − 1: zero)
    phi, dphi_dc, G, m, work = _radau_start(n, phi_end)
    lw = work[0]
    dwk = work[2]
    fi = fphi[n - 1]
    for j in range(n):
        J[n - 1, j] = H[n - 1, j] * cv[j] - fi * row[j]
    J[n - 1, n - 1] -= dv[n - 1]
    for i in range(n - 2, -1, -1):
        phi[i], a, dw0, dw1, dw2, dh, h, j0 = _radau_cell(xi, y, i, beta_cs, phi[i + 1], v_star,
                                                          D, A, c, m, work)
        dphi_dc[i] = a * dphi_dc[i + 1] - h * dh / beta_cs
        G[i] = a * G[i + 1]
        for j in range(max(i - 2, 0), n):
            row[j] = a * row[j]
        for l in range(m):
            row[j0 + l] += (dw0 * dwk[0] * lw[0, l] + dw1 * dwk[1] * lw[1, l])
        row[i] += dw2 * dwk[2]
        fi = fphi[i]
        for j in range(n):
            J[i, j] = H[i, j] * cv[j] - fi * row[j]
        J[i, i] -= dv[i]
    return dphi_dc, G


@njit(cache=True, inline="always")
def adjugate3(M, Mi):
    """Mi = adj(M) of a 3×3 M (real or complex); returns det M (so M⁻¹ = Mi/det)."""
    Mi[0, 0] = M[1, 1] * M[2, 2] - M[1, 2] * M[2, 1]
    Mi[0, 1] = M[0, 2] * M[2, 1] - M[0, 1] * M[2, 2]
    Mi[0, 2] = M[0, 1] * M[1, 2] - M[0, 2] * M[1, 1]
    Mi[1, 0] = M[1, 2] * M[2, 0] - M[1, 0] * M[2, 2]
    Mi[1, 1] = M[0, 0] * M[2, 2] - M[0, 2] * M[2, 0]
    Mi[1, 2] = M[0, 2] * M[1, 0] - M[0, 0] * M[1, 2]
    Mi[2, 0] = M[1, 0] * M[2, 1] - M[1, 1] * M[2, 0]
    Mi[2, 1] = M[0, 1] * M[2, 0] - M[0, 0] * M[2, 1]
    Mi[2, 2] = M[0, 0] * M[1, 1] - M[0, 1] * M[1, 0]
    return M[0, 0] * Mi[0, 0] + M[0, 1] * Mi[1, 0] + M[0, 2] * Mi[2, 0]


@njit(cache=True)
def _radau_workspace():
    """Scratch arrays of :func:`_radau_cell`: Lagrange weights (2×4), w and ∂w/∂y at the stages,
    f, M, M⁻¹ (adjugate), Ψ, μ, right-hand side."""
    return (np.empty((2, 4)), np.empty(3), np.empty(3), np.empty(3), np.empty((3, 3)),
            np.empty((3, 3)), np.empty(3), np.empty(3), np.empty(3))


@njit(cache=True, inline="always")
def _radau_cell(xi, y, i, beta_cs, phi_next, v_star, D, A, c, m, work):
    """One cell [ξ_i, ξ_{i+1}] of :func:`integrate_state_radau`: φ_i from φ_{i+1} and its local
    derivatives. Returns (φ_i, a = ∂φ_i/∂φ_{i+1}, ∂φ_i/∂w_1, ∂φ_i/∂w_2, ∂φ_i/∂w_3, ∂φ_i/∂h, h, j0);
    the Lagrange weights of the inner stages (nodes j0..j0+m−1) and ∂w/∂y at the stages are left in
    work[0] and work[2]."""
    lw, wk, dwk, f, M, Mi, psi, mu, rhs = work
    n = xi.size
    D2 = D * D
    vs2 = v_star * v_star
    dx = xi[i + 1] - xi[i]
    h = dx / beta_cs
    j0 = min(max(i - 1, 0), n - m)
    # w at the stages: interior ones from the cubic of ln v, the last one at node i
    for k in range(2):
        _lagrange(xi, j0, m, xi[i + 1] - c[k] * dx, lw[k])
        yk = 0.0
        for l in range(m):
            yk += lw[k, l] * y[j0 + l]
        v2 = math.exp(2.0 * yk)
        wk[k] = math.sqrt(v2 + vs2) / D
        dwk[k] = v2 / (D2 * wk[k])
    v2 = math.exp(2.0 * y[i])
    wk[2] = math.sqrt(v2 + vs2) / D
    dwk[2] = v2 / (D2 * wk[2])
    w3 = wk[2]
    for k in range(3):
        f[k] = 1.0 - wk[k] / w3
    f[2] = 0.0
    # M = I + h A W, rhs = h A f; Mi = M⁻¹ by the adjugate
    for r in range(3):
        rhs[r] = 0.0
        for k in range(3):
            M[r, k] = h * A[r, k] * wk[k] + (1.0 if r == k else 0.0)
            rhs[r] += h * A[r, k] * f[k]
    det = adjugate3(M, Mi)
    for r in range(3):
        psi[r] = (Mi[r, 0] * rhs[0] + Mi[r, 1] * rhs[1] + Mi[r, 2] * rhs[2]) / det
    omega = h * (A[2, 0] * wk[0] + A[2, 1] * wk[1] + A[2, 2] * wk[2])
    ex = math.exp(-omega)
    one_m = -math.expm1(-omega)
    phi_i = phi_next * ex + one_m / w3 + psi[2]
    # derivatives: λ = row 3 of M⁻¹, μ = h Aᵀ λ
    for k in range(3):
        mu[k] = h * (Mi[2, 0] * A[0, k] + Mi[2, 1] * A[1, k] + Mi[2, 2] * A[2, k]) / det
    d_om = ex * (1.0 / w3 - phi_next)                     # ∂φ_i/∂Ω
    dw0 = d_om * h * A[2, 0] - mu[0] * (1.0 / w3 + psi[0])
    dw1 = d_om * h * A[2, 1] - mu[1] * (1.0 / w3 + psi[1])
    dw2 = (d_om * h * A[2, 2] + (mu[0] * wk[0] + mu[1] * wk[1]) / (w3 * w3) - mu[2] * psi[2]
           - one_m / (w3 * w3))
    dh = d_om * omega / h
    for k in range(3):
        dh += mu[k] * (f[k] - wk[k] * psi[k]) / h
    return phi_i, ex, dw0, dw1, dw2, dh, h, j0


@njit(cache=True)
def radau_stage_values(xi, y, beta_cs, phi, v_star, D, A, c):
    """The order-4 state map's stages, cell by cell, for the stability operator.

    For the converged state φ (of :func:`integrate_state_radau` on the same data) returns the
    crossing times h (n−1), the stencil start j0 (n−1) and Lagrange weights ℓ (n−1, 2, 4) of the
    inner stages (ln v at stage k = Σ_l ℓ_kl y_{j0+l}), w at the three stages (n−1, 3), φ at the three
    stages (n−1, 3): φ(c_k h) = φ_{i+1} e^{−W_k} + (1 − e^{−W_k})/w_i + Ψ_k with W_k = h Σ_j A_kj w_j
    (the Radau collocation values; the last one is φ_i), and Ω = ∫w over the crossing (n−1)."""
    n = xi.size
    m = 4 if n >= 4 else n
    lws = np.zeros((n - 1, 2, 4))
    j0s = np.empty(n - 1, np.int64)
    hs = np.empty(n - 1)
    ws = np.empty((n - 1, 3))
    phis = np.empty((n - 1, 3))
    omegas = np.empty(n - 1)
    work = _radau_workspace()
    lw, wk, psi = work[0], work[1], work[6]
    for i in range(n - 2, -1, -1):
        _, _, _, _, _, _, h, j0 = _radau_cell(xi, y, i, beta_cs, phi[i + 1], v_star, D, A, c, m,
                                              work)
        for k in range(2):
            for l in range(m):
                lws[i, k, l] = lw[k, l]
        j0s[i] = j0
        hs[i] = h
        w3 = wk[2]
        for k in range(3):
            ws[i, k] = wk[k]
            Wk = h * (A[k, 0] * wk[0] + A[k, 1] * wk[1] + A[k, 2] * wk[2])
            phis[i, k] = phi[i + 1] * math.exp(-Wk) - math.expm1(-Wk) / w3 + psi[k]
        phis[i, 2] = phi[i]
        omegas[i] = h * (A[2, 0] * wk[0] + A[2, 1] * wk[1] + A[2, 2] * wk[2])
    return hs, j0s, lws, ws, phis, omegas



#: State integrators by order: 2, the exponential update with w frozen on half cells
#: (:func:`integrate_state`); 4, Radau IIA on the remainder (:func:`integrate_state_radau`).
STATE_ORDERS = (2, 4)


class SteadyProblem:
    """The discrete steady-pulse equations on a fixed grid (problem apart from solver).

    Parameters
    ----------
    params : Parameters
    tau_d_ratio : float
        Driving stress τ_d/τ_min (> 1, < τ_peak/τ_min); with ``free="tau_d"`` only the start value.
    xi : (N,) array
        Grid, m, ascending; the pulse travels toward +ξ; ξ_N is ahead (rest state).
    pin_index : int
        Node p of the phase condition y_p = y_pin.
    y_pin : float
        ln v imposed at the pin node.
    hilbert : str
        Interpolant of the Hilbert operator ("cubic" or "linear").
    free : {"beta", "tau_d", "both"}
        The scalar unknown appended to y: the speed β at fixed τ_d (default), or q = τ_d/τ_min at
        fixed β = `beta` (continuation in β near τ_min, where τ_d(β) flattens). With "both" the
        unknowns are (y, β, q) and the N + 1 equations are one short: the continuation adds the
        pseudo-arclength condition (:mod:`slippulse.steady.continuation`); the Jacobian is (N+1)×(N+2).
    beta : float
        The fixed speed when ``free="tau_d"``.
    state_order : {4, 2}
        State integrator (:data:`STATE_ORDERS`): 4, Radau IIA on the remainder
        (:func:`integrate_state_radau`, default); 2, the exponential update with w frozen on half
        cells (:func:`integrate_state`, the earlier scheme).
    """

    def __init__(self, params, tau_d_ratio, xi, pin_index, y_pin, hilbert="cubic", H=None,
                 free="beta", beta=None, state_order=4):
        if free not in ("beta", "tau_d", "both"):
            raise ValueError(f"free={free!r}: must be 'beta', 'tau_d' or 'both'")
        if state_order not in STATE_ORDERS:
            raise ValueError(f"state_order={state_order!r}: must be one of {STATE_ORDERS}")
        self.state_order = int(state_order)
        if free == "tau_d" and not (beta is not None and 0.0 < beta < 1.0):
            raise ValueError("free='tau_d' needs a fixed 0 < beta < 1")
        self.params = params
        self.free = free
        self.beta_fixed = beta
        self._set_tau_d(float(tau_d_ratio))
        self.xi = np.ascontiguousarray(xi, dtype=float)
        self.n = self.xi.size
        self.pin_index = int(pin_index)
        self.y_pin = float(y_pin)
        self.hilbert = hilbert
        center = 0.0 if self.xi[0] < 0.0 < self.xi[-1] else None
        self.H = hilbert_matrix(self.xi, kind=hilbert, center=center) if H is None else H
        self._H1 = None

    def _set_tau_d(self, ratio):
        p = self.params
        self.tau_d_ratio = ratio
        self.tau_d = ratio * p.tau_min
        p.check_tau_d(self.tau_d)
        self.v_stick = p.v_stick(self.tau_d)
        self.phi_end = float(fr.phi_ss(self.v_stick, p.v_star, p.D))

    # ------------------------------------------------------------------ pieces
    def split(self, x):
        """(v, β) of the unknowns; in τ_d mode also moves τ_d, v_stick, φ_N to x[-1]."""
        if self.free == "beta":
            return np.exp(x[:-1]), float(x[-1])
        if float(x[-1]) != self.tau_d_ratio:
            self._set_tau_d(float(x[-1]))
        if self.free == "both":
            return np.exp(x[:-2]), float(x[-2])
        return np.exp(x[:-1]), float(self.beta_fixed)

    def valid(self, x):
        if self.free == "beta":
            return 0.0 < x[-1] < 1.0
        p = self.params
        ok = p.tau_min < x[-1] * p.tau_min < p.tau_peak
        return ok and (self.free == "tau_d" or 0.0 < x[-2] < 1.0)

    def state(self, v, beta, with_jacobian=True):
        """(φ, ∂φ/∂y, ∂φ/∂(βc_s), ∂φ/∂φ_N); ∂φ/∂y is a 1×1 placeholder without the Jacobian."""
        p = self.params
        if self.state_order == 4:
            return integrate_state_radau(self.xi, np.log(v), beta * p.c_s, self.phi_end, p.v_star,
                                         p.D, RADAU_A, RADAU_C, with_jacobian)
        w = fr.heal_rate(v, p.v_star, p.D)
        dw_dy = v * v / (p.D * p.D * w)
        return integrate_state(self.xi, v, beta * p.c_s, self.phi_end, w, dw_dy, with_jacobian)

    def fields(self, x):
        """(v, φ, τ, Hu) for unknowns x: slip rate, state, friction stress and Hilbert integral."""
        v, beta = self.split(x)
        phi = self.state(v, beta, False)[0]
        tau = self.params.sigma * fr.f(v, phi, *self.params.law_args)
        return v, phi, tau, self.H @ (v - self.v_stick)

    def residual(self, x):
        """Δ (N values) followed by the phase condition."""
        if not self.valid(x):
            return np.full(self.n + 1, np.inf)
        p = self.params
        v, beta = self.split(x)
        phi = self.state(v, beta, False)[0]
        hu = self.H @ (v - self.v_stick)
        r = np.empty(self.n + 1)
        r[:-1] = (self.tau_d - p.sigma * fr.f(v, phi, *p.law_args) - p.mu * p.F3(beta) * hu) / self.tau_d
        r[-1] = x[self.pin_index] - self.y_pin
        return r

    def residual_and_jacobian(self, x, extra_rows=0):
        """Residual and its exact Jacobian ∂(Δ, pin)/∂(y, β or q), (N+1)×(N+1); with
        ``extra_rows`` zero rows below it, for a caller that borders it (no copy of J)."""
        p = self.params
        v, beta = self.split(x)
        n = self.n
        fused = self.state_order == 4
        if fused:
            # φ first (no Jacobian); the y-block below in one sweep (radau_jacobian_into)
            phi = self.state(v, beta, False)[0]
        else:
            phi, P, dphi_dc, G = self.state(v, beta)
        u = v - self.v_stick
        hu = self.H @ u
        F = float(p.F3(beta))
        s = 1.0 / self.tau_d
        la = p.law_args
        r = np.empty(n + 1)
        r[:-1] = (self.tau_d - p.sigma * fr.f(v, phi, *la) - p.mu * F * hu) * s
        r[-1] = x[self.pin_index] - self.y_pin
        J = np.empty((n + 1 + extra_rows, x.size))
        fphi = p.sigma * s * fr.df_dphi(v, phi, *la)
        # dΔ_i/dy_j = −(σ/τ_d)[f_v v_i δ_ij + f_φ,i P_ij] − (μF/τ_d) H_ij v_j
        dv = p.sigma * s * fr.df_dv(v, phi, *la) * v
        if fused:
            dphi_dc, G = radau_jacobian_into(self.xi, np.log(v), beta * p.c_s, self.phi_end,
                                             p.v_star, p.D, (RADAU_A, RADAU_C), self.H,
                                             ((-p.mu * F * s) * v, fphi, dv), J)
        else:
            Jy = J[:n, :n]
            np.multiply(self.H, (-p.mu * F * s) * v, out=Jy)
            Jy -= fphi[:, None] * P
            Jy[np.diag_indices(n)] -= dv
        if self.free in ("beta", "both"):
            # dΔ_i/dβ = −(σ/τ_d) f_φ,i c_s ∂φ_i/∂c − (μ F'(β)/τ_d) (H u)_i
            jb = -1 if self.free == "beta" else -2
            J[:n, jb] = -fphi * dphi_dc * p.c_s - p.mu * float(p.dF3_dbeta(beta)) * s * hu
        if self.free in ("tau_d", "both"):
            # Δ_i = N_i/τ_d: dΔ_i/dτ_d = [1 − σ f_φ,i G_i dφ_N/dτ_d + μF (H·1)_i dv_st/dτ_d]/τ_d − Δ_i/τ_d
            vs = self.v_stick
            dvs = vs / (p.sigma * float(fr.df_ss_dlnv(vs, *la)))           # 1/τ_ss'(v_stick)
            dphiN = -p.D * vs / (vs * vs + p.v_star ** 2) ** 1.5 * dvs
            if self._H1 is None:
                self._H1 = self.H.sum(axis=1)
            dN = 1.0 - fphi * self.tau_d * G * dphiN + p.mu * F * self._H1 * dvs
            J[:n, -1] = (dN * s - r[:-1] * s) * p.tau_min
        J[n:, :] = 0.0
        J[n, self.pin_index] = 1.0
        return r, J
