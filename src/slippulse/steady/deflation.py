"""Deflated Newton (Farrell, Birkisson & Funke, SIAM J. Sci. Comput. 37, A2026, 2015).

Solutions x_i already found are removed from the residual F by the deflation operator

    M(x) = Π_i (1/‖x − x_i‖^p + σ),      G(x) = M(x) F(x),

so that Newton on G, started from the same guess, cannot converge to any x_i again (G ≠ 0 near x_i
for p ≥ 1: F vanishes like ‖x − x_i‖, M blows up like ‖x − x_i‖^−p) and either finds another
root of F or fails. The Jacobian of G is M J + F ∇Mᵀ, a rank-one change of M J; by Sherman–Morrison
its Newton step is the undeflated step δ₀ (J δ₀ = −F) scaled by 1/(1 − ∇M·δ₀/M), so one LU of J
per iteration serves both. Far from the x_i, M → σ^k and the deflated iteration is Newton's (σ = 1
keeps the residual's scale there; σ = 0 would shrink it).

The norm is a weighted Euclidean one, ‖e‖² = Σ_j w_j e_j², given per deflated solution (for a
pulse: the RMS of ln v over the nodes and the relative speed, :func:`pulse_weights`).
"""
from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np
import scipy.linalg as sla


@dataclass
class Deflation:
    """The deflation operator M(x) of the solutions ``roots`` (each with its weight vector)."""
    p: float = 2.0
    sigma: float = 1.0
    roots: list = field(default_factory=list)
    weights: list = field(default_factory=list)

    def __post_init__(self):
        if not (self.p >= 1.0 and math.isfinite(self.p)):
            raise ValueError(f"p={self.p!r}: deflation needs a finite power p >= 1")
        if not (self.sigma >= 0.0 and math.isfinite(self.sigma)):
            raise ValueError(f"sigma={self.sigma!r}: the shift must be finite and >= 0")

    def add(self, root, weight):
        self.roots.append(np.asarray(root, float).copy())
        self.weights.append(np.asarray(weight, float).copy())

    def distance(self, x, i):
        e = x - self.roots[i]
        return math.sqrt(float(np.sum(self.weights[i] * e * e)))

    def __call__(self, x):
        """(M(x), ∇M(x))."""
        M = 1.0
        g = np.zeros_like(x, dtype=float)
        for r, w in zip(self.roots, self.weights):
            e = x - r
            d2 = float(np.sum(w * e * e))
            if d2 == 0.0:
                return math.inf, g
            d = math.sqrt(d2)
            m = d ** -self.p + self.sigma
            # ∇m = −p d^(−p−2) W e ; ∇M = M Σ ∇m/m
            g += (-self.p * d ** (-self.p - 2.0) / m) * (w * e)
            M *= m
        return M, M * g

    def describe(self) -> str:
        return f"M = prod_i (1/||x - x_i||^{self.p:g} + {self.sigma:g})"


@dataclass
class DeflatedResult:
    x: np.ndarray
    converged: bool
    iterations: int
    max_residual: float
    message: str


def deflated_newton(problem, x0, deflation: Deflation, tol=1e-12, max_iter=80, max_dy=2.0,
                    n_free=1, backtrack=8, monotone=False) -> DeflatedResult:
    """Newton on G = M F from x0 (``problem``: residual(x), residual_and_jacobian(x) square,
    valid(x)). Steps limited to max|δ| ≤ max_dy on the first len(x) − n_free unknowns (ln v),
    halved until the iterate is valid (and, with ``monotone``, until ‖G‖₂ decreases; at most
    ``backtrack`` times, then the shortest step is taken). Not monotone by default: ‖G‖ has local
    minima near each deflated root (M F with F ≠ 0 there), where a decrease test stalls (measured:
    the cubic of the tests stalls at x = 1.08 beside its deflated root 1, and reaches 2 without).
    Converged when max|F| ≤ tol (F, not G: the root of F is what counts)."""
    x = np.array(x0, dtype=float)
    n_u = x.size - n_free
    msg = "max_iter reached"
    for it in range(1, max_iter + 1):
        r, J = problem.residual_and_jacobian(x)
        m = float(np.max(np.abs(r)))
        if not math.isfinite(m):
            return DeflatedResult(x, False, it, m, "residual not finite")
        if m <= tol:
            return DeflatedResult(x, True, it - 1, m, f"converged in {it - 1} iterations")
        try:
            d0 = sla.lu_solve(sla.lu_factor(J, check_finite=False), -r, check_finite=False)
        except (ValueError, np.linalg.LinAlgError) as exc:
            return DeflatedResult(x, False, it, m, f"singular Jacobian ({exc})")
        M, g = deflation(x)
        if not math.isfinite(M):
            return DeflatedResult(x, False, it, m, "iterate on a deflated root")
        denom = 1.0 - float(g @ d0) / M
        step = d0 / denom if abs(denom) > 1e-14 else d0
        big = float(np.max(np.abs(step[:n_u]))) if n_u else 0.0
        if big > max_dy:
            step *= max_dy / big
        G0 = M * float(np.linalg.norm(r))
        lam = 1.0
        for _ in range(backtrack + 1):
            xt = x + lam * step
            if problem.valid(xt):
                rt = problem.residual(xt)
                if np.all(np.isfinite(rt)) and (
                        not monotone or deflation(xt)[0] * float(np.linalg.norm(rt)) < G0):
                    break
            lam *= 0.5
        else:
            if not problem.valid(xt):
                return DeflatedResult(x, False, it, m, "no valid step")
        x = xt
    r = problem.residual(x)
    m = float(np.max(np.abs(r)))
    return DeflatedResult(x, m <= tol, max_iter, m, msg if m > tol else "converged")
