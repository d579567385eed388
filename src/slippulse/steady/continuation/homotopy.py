"""Residual homotopy F(x) = s F(x0), s: 1 → 0, where Newton from an interpolated guess creeps."""
from __future__ import annotations

import numpy as np

from ..newton import NEWTON_TOL, KrylovLU, as_linear, newton


class _Shifted:
    """F(x) − s r0: the residual homotopy's problem at stage s (same Jacobian)."""

    def __init__(self, prob, r0, s):
        self.prob, self.r0, self.s = prob, r0, s

    def valid(self, x):
        return self.prob.valid(x)

    def residual(self, x):
        return self.prob.residual(x) - self.s * self.r0

    def residual_and_jacobian(self, x):
        r, J = self.prob.residual_and_jacobian(x)
        return r - self.s * self.r0, J


#: the first, plain Newton solve of :func:`solve_robust` gives way to the homotopy once max|r|
#: has not halved over this many iterations (``newton(creep=...)``)
CREEP = 3


def solve_robust(problem, x0, stages=8, max_iter=15, tol=NEWTON_TOL, reuse=False, creep=None,
                 plain=True, linear="double", lu0=None):
    """Newton from x0; if it fails, the residual homotopy F(x) = s F(x0), s = 1 − k/stages.

    Notes
    -----
    Near τ_min the family is soft: a residual of 1e-5 (the interpolation error of a new grid)
    moves the healing edge by ~0.2 m, farther than Newton's linear model holds, so the damped
    iteration creeps (measured at 1.0125 τ_min, N = 2000: 3 % residual reduction per iteration,
    not converged after 40). Following s from 1 to 0 in `stages` equal steps, each a Newton
    solve from the last (tolerance 1e-10 on the way, `tol` at s = 0), converged there in 66–73
    iterations in all. Returns (x, stats) of the last solve, stats.iterations the total.
    ``reuse``: every Newton solve reuses each full step's LU for chord iterations
    (:func:`~slippulse.steady.newton.newton`). ``creep``: the plain solve stops once max|r| has
    not halved over that many iterations and the homotopy takes over (0: only after
    ``max_iter``; measured on a 2.4 km pulse's grid check, N = 7083: 15 creeping iterations,
    74 s, before the homotopy's 4 stages of 2 iterations each, 39 s); None: :data:`CREEP`, read
    at the call. ``plain=False``: no plain solve, the homotopy from the start (for a caller that
    has just seen a similar problem need it: the grid checks of a deep march, where beyond
    5.3 km every check's plain solve crept for 5 iterations of a 7085-point LU, 39 s, before the
    homotopy took over); where that homotopy fails, plain Newton runs after it (to ``max_iter``).
    ``linear``: every Newton solve's linear solve (:func:`newton`); one
    that solves on an earlier LU (:class:`~slippulse.steady.newton.KrylovLU`) is handed the
    LU of the solve before (each stage's Jacobian is the last one's at a nearby x).
    ``lu0``: an LU at a nearby point for the first solve of such a ``linear``.
    ``stats.homotopy`` says whether the homotopy ran.
    """
    creep = CREEP if creep is None else int(creep)
    linear = as_linear(linear)
    handed = isinstance(linear, KrylovLU)
    counts = [0, 0, 0]                  # iterations, factorizations, Krylov iterations
    lu = lu0 if handed else None        # one of another size is never used (KrylovLU.solve)

    def plain_solve(creep_stop):
        x, st = newton(problem, x0, tol=tol, max_iter=max_iter, reuse=reuse, creep=creep_stop,
                       linear=linear, lu=lu, keep=handed)
        _count(counts, st)
        return x, st

    if plain:
        x, st = plain_solve(creep)
        if st.converged:
            return x, st
        lu = st.lu if handed else None
    x, st = _homotopy(problem, x0, stages, max_iter, tol, reuse, linear, lu, handed, counts)
    if not (st.converged or plain):
        # the homotopy went first for speed and failed: plain Newton after all, to max_iter
        failed = st.message
        lu = st.lu if handed else None
        x, st = plain_solve(0)
        if not st.converged:
            st.message = f"{failed}; then plain Newton: {st.message}"
    st.iterations, st.factorizations, st.krylov_iterations = counts
    st.homotopy = True
    return x, st


def _count(counts, st):
    counts[0] += st.iterations
    counts[1] += st.factorizations
    counts[2] += st.krylov_iterations


#: Times a homotopy step that fails is halved (from the last converged stage) before the
#: homotopy gives up: a step of 1/stages can be too long where the equal steps of the others
#: are not (the 11.1 and 11.25 km pulses' checks: stage 2 of 4 crept to max|r| = 6.9e−5 in
#: 60 iterations; with steps of 1/8 the re-solve converges in 44 s and passes).
HALVINGS = 3


def _homotopy(problem, x0, stages, max_iter, tol, reuse, linear, lu, handed, counts):
    """s from 1 to 0 in steps of 1/stages along F(x) = s F(x0), each a Newton solve from the
    last (1e-10 on the way, ``tol`` at s = 0); a step whose solve fails is halved and made
    again from the last converged x, at most :data:`HALVINGS` times in a row. Returns (x,
    stats) of the last solve run."""
    r0 = problem.residual(np.asarray(x0, float))
    x = np.array(x0, float)
    s, h, halved, k = 1.0, 1.0 / stages, 0, 0
    while s > 0.0:
        s_k = s - h if s - h > 1e-12 else 0.0
        k += 1
        xt, st = newton(_Shifted(problem, r0, s_k), x, tol=tol if s_k == 0.0 else 1e-10,
                        max_iter=4 * max_iter, reuse=reuse, linear=linear, lu=lu, keep=handed)
        _count(counts, st)
        if st.converged:
            x, s, halved = xt, s_k, 0
            lu = st.lu if handed else None
            continue
        if halved == HALVINGS:
            st.message = (f"homotopy stage {k} (s = {s:.4g} -> {s_k:.4g}, step halved "
                          f"{halved} times) failed: {st.message}")
            return xt, st
        h, halved = 0.5 * h, halved + 1
    return x, st
