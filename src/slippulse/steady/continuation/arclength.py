"""Pseudo-arclength continuation in (ln(1 − β), τ_d/τ_min): the closed problem and the family
tangent (the driver is :mod:`.driver`)."""
from __future__ import annotations

import math
import numpy as np

from ..bifurcation import lu_det, lu_sign
from ..equations import SteadyProblem
from ..newton import gmres_on_lu, lu_solve


class ArclengthProblem:
    """The steady equations with both β and q = τ_d/τ_min free, closed by the pseudo-arclength
    condition in the plane (a, q/κ), a = ln(1 − β):

        t_a (a − a_0) + t_Q (q − q_0)/κ − ds = 0,

    (t_a, t_Q) the unit tangent of the family at the last pulse (a_0, q_0). Unknowns (y, β, q);
    the Jacobian is the (N+1)×(N+2) one of ``SteadyProblem(free="both")`` with the row
    (0…0, −t_a/(1 − β), t_Q/κ) appended (written into the row ``base`` leaves for it,
    ``residual_and_jacobian(x, extra_rows=1)``: no copy of J). Square, so :func:`newton` drives
    it.
    """

    def __init__(self, base: SteadyProblem, a0, q0, t_a, t_Q, kappa, ds):
        self.base, self.a0, self.q0 = base, a0, q0
        self.t_a, self.t_Q, self.kappa, self.ds = t_a, t_Q, kappa, ds

    def _arc(self, x):
        a = math.log(1.0 - x[-2])
        return self.t_a * (a - self.a0) + self.t_Q * (x[-1] - self.q0) / self.kappa - self.ds

    def valid(self, x):
        return self.base.valid(x)

    def residual(self, x):
        if not self.valid(x):
            return np.full(x.size, np.inf)
        return np.concatenate([self.base.residual(x), [self._arc(x)]])

    def residual_and_jacobian(self, x):
        r, J = self.base.residual_and_jacobian(x, extra_rows=1)
        J[-1, -2] = -self.t_a / (1.0 - x[-2])
        J[-1, -1] = self.t_Q / self.kappa
        return np.concatenate([r, [self._arc(x)]]), J


def family_tangent(prob: SteadyProblem, x, orient):
    """Unit tangent of the solution curve at a converged x = (y, β, q) of ``free="both"``.

    Notes
    -----
    The tangent n spans the null space of the (N+1)×(N+2) Jacobian J: J n = 0. It is found from
    the square system [J; c] n = [0; 1] with c = (0…0, orient) the previous direction in (β, q)
    (so n points the same way along the curve), then scaled to unit length in (a, q/κ):
    n_a = −n_β/(1 − β). Returns n (full vector, in (y, β, q)) scaled so that n_a² + n_Q² = 1 with
    n_Q = n_q/κ, where κ is passed through ``orient = (c_β, c_q, κ)``.
    """
    rhs = np.zeros(x.size)
    rhs[-1] = 1.0
    return unit_tangent(np.linalg.solve(tangent_matrix(prob, x, orient), rhs), x[-2], orient[2])


def bordered_sign(A, lu=None) -> int:
    """sign det A of a square bordered matrix A = [J; r] (the corrector's arclength Jacobian, or
    :func:`tangent_matrix`), what :class:`~.strategy.SignGuard` compares between steps: constant
    along one branch on one discretisation. With ``lu``, the LU of a nearby matrix A₀ (the
    corrector's): where iterative refinement on it converges, A = A₀(I + E) with the spectral
    radius of E below one, so det(I + E) > 0 and sign det A = sign det A₀, read off ``lu`` (no
    factorisation); else one LU of A."""
    if lu is not None and lu[0].shape[0] == A.shape[0] and refined_solution(A, lu) is not None:
        return lu_sign(lu)
    return lu_det(A)[0]


def tangent_matrix(prob, x, orient):
    """[J; c] of :func:`family_tangent`: the (N+1)×(N+2) Jacobian of ``prob`` at x bordered by
    c = (0…0, c_β, c_q) from ``orient`` = (c_β, c_q, κ), written into the row J leaves for it."""
    _, A = prob.residual_and_jacobian(x, extra_rows=1)
    A[-1, -2], A[-1, -1] = orient[0], orient[1]
    return A


def unit_tangent(n, beta, kappa):
    """n scaled to unit length in (a, q/κ), a = ln(1 − β): n_a = −n_β/(1 − β), n_Q = n_q/κ."""
    return n / math.hypot(-n[-2] / (1.0 - beta), n[-1] / kappa)


def tangent_by_refinement(A, lu, max_iter=30, rtol=1e-11):
    """The solution n of A n = (0…0, 1) by iterative refinement with the LU of a nearby matrix
    (:func:`~slippulse.steady.newton.lu_factor`): n ← n + LU⁻¹ (e − A n); where a correction
    grows, or they do not fall below ``rtol`` ‖n‖ within ``max_iter`` refinements, GMRES on the
    LU (:func:`~slippulse.steady.newton.gmres_on_lu`); None when that fails too (then solve A
    directly).

    With A = [J; c], J the (N+1)×(N+2) Jacobian at a converged pulse and c any row with c·n ≠ 0,
    n spans J's null space: the family tangent (:func:`family_tangent` with c = orient). The
    corrector of an arclength step has factored such a matrix at most a few steps back (its last
    row is the arclength condition's), so the tangent costs back-substitutions and products with
    A (N² each) instead of an LU (N³). Each refinement shrinks the error by ‖LU⁻¹(A − A_LU)‖:
    measured ≈ 0.1 with an LU two steps of ds = 0.001 old at 1.2 τ_min (N = 500; 10 refinements
    to 3e−11). ``rtol`` bounds the tangent's relative error; it sets the predictor and the
    arclength condition's direction only, never the tolerance of the pulse.
    """
    n = refined_solution(A, lu, max_iter, rtol)
    if n is not None:
        return n
    # an LU too far from A for refinement (one of a Krylov corrector, several steps old):
    # GMRES on it, to the same relative residual
    e = np.zeros(A.shape[0])
    e[-1] = 1.0
    n, _ = gmres_on_lu(A, e, lu, rtol, max_iter)
    return n


def refined_solution(A, lu, max_iter=30, rtol=1e-11):
    """A⁻¹(0…0, 1) by iterative refinement on ``lu`` alone, or None where a correction grows or
    they do not fall below ``rtol`` ‖n‖ within ``max_iter`` (:func:`tangent_by_refinement`)."""
    e = np.zeros(A.shape[0])
    e[-1] = 1.0
    n = lu_solve(lu, e)
    last = math.inf
    for _ in range(max_iter):
        dn = lu_solve(lu, e - A @ n)
        n = n + dn
        size = np.linalg.norm(dn) / np.linalg.norm(n)
        if not (np.isfinite(size) and size < last):
            return None
        if size <= rtol:
            return n
        last = size
    return None
