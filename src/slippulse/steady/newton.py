"""Nonlinear solvers for the steady equations: damped Newton (dense LU) and scipy's Levenberg–Marquardt.

Both drive the residual of a problem object (``residual(x)``, ``residual_and_jacobian(x)``) to
max|r| ≤ tol. Selected by name from :data:`SOLVERS`.
"""
from __future__ import annotations

import time
from dataclasses import dataclass, field

import numpy as np
import scipy.linalg as sla
from scipy.optimize import least_squares


@dataclass
class SolveStats:
    converged: bool
    message: str
    iterations: int
    max_residual: float
    history: list = field(default_factory=list)
    corrections: list = field(default_factory=list)   # ‖δ‖₂ of each Newton step J δ = −r
    t_jacobian: float = 0.0
    t_linear: float = 0.0
    t_residual: float = 0.0
    chord_iterations: int = 0
    krylov_iterations: int = 0      # GMRES iterations of the steps solved on an earlier LU
    factorizations: int = 0         # LUs formed
    homotopy: bool = False          # the solve went through the residual homotopy (solve_robust)
    lu: object = None               # keep=True: the last LU factorization (scipy lu_factor)
    jacobian: object = None         # keep=True: the Jacobian at the returned x, when formed there


#: Every Newton solve of the package (family steps, grid checks, re-solves) converges to max|r| ≤
#: this: the residual is relative to τ_d, and 1e−13 is ~100 times the floating-point floor of the
#: Hilbert sum at N ~ 5000 (:data:`ROUNDOFF`), tight enough that a grid check measures the grid,
#: not the solve.
NEWTON_TOL = 1e-13


#: Precisions of the LU of :func:`newton`: 'double' (LAPACK dgetrf) or 'single' (sgetrf on the
#: Jacobian rounded to float32: half the time at N = 2499; the residual, the iterate and every
#: test stay in double, so the converged tolerance is the same and only the Newton correction
#: carries the LU's relative error, ~cond(J)·6e-8; measured on the grid checks of the shallow
#: family and a 2.55 km pulse: the same max|r| per iteration as with 'double').
PRECISIONS = ("double", "single")


def lu_factor(J, precision="double", overwrite_a=False):
    """scipy ``lu_factor`` of J in ``precision`` (:data:`PRECISIONS`)."""
    if precision == "single":
        return sla.lu_factor(np.asarray(J, np.float32), overwrite_a=True, check_finite=False)
    return sla.lu_factor(J, overwrite_a=overwrite_a, check_finite=False)


def lu_solve(lu, r, trans=0):
    """J⁻¹ r (J⁻ᵀ r with ``trans=1``) from :func:`lu_factor`'s LU, in double; a single-precision
    LU solves in single (scipy would copy the LU to double on every solve)."""
    if lu[0].dtype == np.float32:
        return sla.lu_solve(lu, np.asarray(r, np.float32), trans=trans,
                            check_finite=False).astype(float)
    return sla.lu_solve(lu, r, trans=trans, check_finite=False)


def gmres_on_lu(J, b, lu, rtol, max_iter):
    """δ with ‖b − J δ‖₂ ≤ rtol ‖b‖₂ by GMRES right-preconditioned by ``lu``, the LU of a
    nearby matrix (J M⁻¹ u = b, δ = M⁻¹ u; Arnoldi by classical Gram–Schmidt applied twice),
    started from zero, so the first iterate is the chord step; (δ, iterations), or
    (None, max_iter) when it does not get there within ``max_iter`` iterations.

    Right preconditioning minimises the true residual b − J δ, whatever the LU's precision;
    scipy's ``gmres`` preconditions on the left and tests the preconditioned residual, which a
    float32 LU leaves far below the true one."""
    n = b.size
    nb = float(np.linalg.norm(b))
    if not (nb > 0 and np.isfinite(nb)):
        return (np.zeros(n), 0) if nb == 0 else (None, max_iter)
    V = np.empty((max_iter + 1, n))
    Z = np.empty((max_iter, n))
    H = np.zeros((max_iter + 1, max_iter))
    V[0] = b / nb
    e1 = np.zeros(max_iter + 1)
    e1[0] = nb
    for j in range(max_iter):
        Z[j] = lu_solve(lu, V[j])
        w = J @ Z[j]
        for _ in range(2):
            h = V[:j + 1] @ w
            w -= V[:j + 1].T @ h
            H[:j + 1, j] += h
        H[j + 1, j] = np.linalg.norm(w)
        y = np.linalg.lstsq(H[:j + 2, :j + 1], e1[:j + 2], rcond=None)[0]
        res = np.linalg.norm(e1[:j + 2] - H[:j + 2, :j + 1] @ y)
        if not np.isfinite(res):
            return None, max_iter
        if res <= rtol * nb or H[j + 1, j] == 0.0:
            x = Z[:j + 1].T @ y
            if np.linalg.norm(b - J @ x) <= 2.0 * rtol * nb:
                return x, j + 1
            return None, max_iter
        V[j + 1] = w / H[j + 1, j]
    return None, max_iter


@dataclass(frozen=True)
class DirectLU:
    """Every Newton step factors its Jacobian (LAPACK getrf in ``precision``,
    :data:`PRECISIONS`) and solves by that LU."""

    precision: str = "double"
    name = "lu"
    #: an LU handed to :func:`newton` starts chord iterations (:class:`KrylovLU`: it preconditions)
    chord_start = True

    def __post_init__(self):
        if self.precision not in PRECISIONS:
            raise ValueError(f"{self.name}: precision={self.precision!r} is invalid: must be one "
                             f"of {PRECISIONS}")

    def solve(self, J, r, lu):
        """(J⁻¹ r, the LU it used, whether that LU is J's own (J is then overwritten by it),
        Krylov iterations)."""
        lu = lu_factor(J, self.precision, overwrite_a=True)
        return lu_solve(lu, r), lu, True, 0


@dataclass(frozen=True)
class KrylovLU(DirectLU):
    """A Newton step solves J δ = r by GMRES preconditioned by the LU in hand (of an earlier
    iteration, step, homotopy stage or grid check) to ‖r − J δ‖₂ ≤ ``rtol`` ‖r‖₂, and factors J
    (:class:`DirectLU`) only where that takes more than ``max_iter`` iterations. Why: an
    iteration is two N² operations against the LU's N³ (docs/steady.md "Linear solves"); an
    inexact step of relative error rtol keeps Newton converging to the same tolerance.

    The LU in hand preconditions and drives no chord iterations (neither at the start nor after
    a step solved on it): chord steps on an LU several steps old can leave the iterate where the
    damped Newton steps then creep."""

    max_iter: int = 30
    rtol: float = 1e-9
    name = "krylov"
    chord_start = False

    def __post_init__(self):
        super().__post_init__()
        if not (isinstance(self.max_iter, int) and self.max_iter >= 1 and 0 < self.rtol < 1):
            raise ValueError(f"krylov: max_iter={self.max_iter!r}, rtol={self.rtol!r} are "
                             f"invalid: need an integer max_iter >= 1 and 0 < rtol < 1")

    def solve(self, J, r, lu):
        if lu is not None and lu[0].shape[0] == r.size:
            d, k = gmres_on_lu(J, r, lu, self.rtol, self.max_iter)
            if d is not None:
                return d, lu, False, k
        return super().solve(J, r, None)


def as_linear(linear):
    """A linear-solve strategy from a precision name ('double' → ``DirectLU('double')``) or
    itself."""
    return DirectLU(linear) if isinstance(linear, str) else linear


def _max_abs(r):
    return float(np.max(np.abs(r))) if np.all(np.isfinite(r)) else np.inf


def chord(problem, x0, lu, tol=NEWTON_TOL, max_iter=30, rate=0.5, r0=None):
    """Chord iterations x ← x − J₀⁻¹ r(x) with a factored Jacobian J₀ (``lu``, from
    :func:`scipy.linalg.lu_factor`) taken at a nearby point; one residual per iteration
    (``r0``: the residual at x0 when the caller has it).

    Stops when max|r| ≤ tol, or as soon as an iteration does not contract max|r| by `rate`
    (J₀ too far from the Jacobian here) or leaves the valid region. Returns (x, max|r|, iterations)
    with x the best iterate.
    """
    x = np.array(x0, dtype=float)
    r = problem.residual(x) if r0 is None else r0
    m = _max_abs(r)
    for it in range(1, max_iter + 1):
        if m <= tol:
            return x, m, it - 1
        xt = x - lu_solve(lu, r)
        if not (np.all(np.isfinite(xt)) and problem.valid(xt)):
            return x, m, it
        rt = problem.residual(xt)
        mt = _max_abs(rt)
        if not mt < rate * m:
            return (xt, mt, it) if mt < m else (x, m, it)
        x, r, m = xt, rt, mt
    return x, m, max_iter


#: A Newton iteration whose line search finds no step that lowers ‖r‖₂ has converged when max|r|
#: is within this factor of its tolerance: the residual's floor in floating point. Measured on the
#: deep march at L = 6.77 km: an arclength step stopped at max|r| = 1.11e−13 against
#: tol = 1e−13, and its failure ended the march (ds halved below ds_min).
ROUNDOFF = 10.0


#: Line searches of :func:`newton`: 'residual' backtracks until ‖r‖₂ falls; 'natural' until the
#: simplified Newton correction J⁻¹ r(x + λδ) (the LU in hand, one back-substitution per trial)
#: is shorter than δ by the factor 1 − λ/4 (Deuflhard's natural monotonicity test, affine
#: invariant: it does not depend on how each equation is scaled).
LINE_SEARCHES = ("residual", "natural")


def newton(problem, x0, tol=NEWTON_TOL, max_iter=60, max_dy=2.0, callback=None, lu=None,
           reuse=False, creep=0, line_search="residual", keep=False, linear="double"):
    """Damped Newton: J δ = −r by LU, step limited to |δy| ≤ max_dy, kept valid, backtracking on ‖r‖₂
    (or on the natural monotonicity test, ``line_search='natural'``).

    Converges when max|r| ≤ tol. Stops (not converged) when the line search fails or after
    `max_iter` iterations; near round-off a full step that does not reduce ‖r‖₂ but keeps
    max|r| ≤ tol is accepted, and a line search that finds no lower ‖r‖₂ at max|r| ≤
    :data:`ROUNDOFF` · tol ends it as converged ("converged at round-off"). With ``lu`` (a
    factored Jacobian at a nearby point, e.g. the one the continuation's tangent came from)
    :func:`chord` iterations run first; Newton takes over from their best iterate when they stop
    contracting.

    ``reuse=True`` (the grid checks' re-solves, whose Jacobian and LU at 2N − 1 points cost far
    more than a residual): after every full (undamped) Newton step, :func:`chord` iterations
    with the LU of that step run before a new Jacobian is formed, for as long as each contracts
    max|r| by half. Near the solution a Jacobian one step old contracts by orders of magnitude
    per iteration, so one LU does the work of two or three. The converged tolerance is the same.

    ``creep`` > 0: stop (not converged) as soon as max|r| has not fallen by half over the last
    ``creep`` iterations. The damped iteration then creeps (measured on a 2.4 km pulse's grid
    check: max|r| 2.7e−4 → 2.4e−4 in 14 iterations of a 7083-point LU each) and a caller with
    another way on (:func:`~slippulse.steady.continuation.homotopy.solve_robust`'s homotopy)
    takes it sooner.

    ``line_search='natural'``: a trial step is accepted when its simplified correction is
    shorter, ‖J⁻¹ r(x + λδ)‖₂ ≤ (1 − λ/4) ‖δ‖₂, instead of when ‖r‖₂ falls. A re-solve on a
    finer grid starts with the healing front a few cm off; the few equations there, whose
    residual is steep in ln v, made the ‖r‖₂ test cut every step to λ = 1/8 for ten iterations
    of an LU each (measured at L = 3.8 km, N = 5009: 15 iterations with 'residual', 3 with
    'natural', the same solution). The converged tolerance on max|r|
    is the same.

    ``linear``: how a step solves J δ = −r, :class:`DirectLU` (an LU of J, in its precision,
    :data:`PRECISIONS`; a precision name means that) or :class:`KrylovLU` (GMRES preconditioned
    by the LU in hand, ``lu`` at first; an LU of J only where GMRES does not converge). A ``lu``
    passed in may be of either precision.

    ``keep=True``: the returned stats carry ``lu``, the last LU factorization used (the one
    passed in when none was formed), and ``jacobian``, the Jacobian at the returned x when it was
    formed there (None after chord iterations converged): a continuation reuses them for the
    next tangent and the next corrector's chord iterations
    (:class:`~.continuation.driver.Continuation`).
    """
    if line_search not in LINE_SEARCHES:
        raise ValueError(f"line_search={line_search!r}: must be one of {LINE_SEARCHES}")
    linear = as_linear(linear)
    x, st = _newton(problem, x0, tol, max_iter, max_dy, callback, lu, reuse, creep,
                    line_search == "natural", linear)
    if not keep:
        st.lu = st.jacobian = None
    return x, st


def _newton(problem, x0, tol, max_iter, max_dy, callback, lu, reuse, creep, natural, linear):
    x = np.array(x0, dtype=float)
    st = SolveStats(False, "", 0, np.inf)
    st.lu = lu
    if lu is not None and linear.chord_start:
        t0 = time.perf_counter()
        x, m, st.chord_iterations = chord(problem, x, lu, tol)
        st.t_residual += time.perf_counter() - t0
        if m <= tol:
            st.converged, st.max_residual, st.history = True, m, [m]
            st.message = f"converged: max|r|={m:.2e} ({st.chord_iterations} chord iterations)"
            return x, st
    t0 = time.perf_counter()
    r, J = problem.residual_and_jacobian(x)
    st.t_jacobian += time.perf_counter() - t0
    st.jacobian = J
    norm = np.linalg.norm(r)
    for it in range(1, max_iter + 1):
        st.max_residual = _max_abs(r)
        st.history.append(st.max_residual)
        if callback is not None:
            callback(it - 1, x, st.max_residual)
        if st.max_residual <= tol:
            st.converged, st.message, st.iterations = True, f"converged: max|r|={st.max_residual:.2e}", it - 1
            return x, st
        if (creep and not natural and len(st.history) > creep
                and st.max_residual > 0.5 * st.history[-1 - creep]):
            st.message = (f"creeping: max|r|={st.max_residual:.2e} after {it - 1} iterations, "
                          f"{st.history[-1 - creep]:.2e} {creep} iterations before")
            st.iterations = it - 1
            return x, st
        t0 = time.perf_counter()
        st.jacobian = None                      # overwritten by its LU
        try:
            d, lu, fresh, k = linear.solve(J, r, st.lu)
            st.lu = lu
            st.krylov_iterations += k
            st.factorizations += fresh
            dx = -d
        except (ValueError, np.linalg.LinAlgError) as exc:
            st.message = f"linear solve failed: {exc}"
            st.iterations = it
            return x, st
        st.t_linear += time.perf_counter() - t0
        if not np.all(np.isfinite(dx)):
            st.message, st.iterations = "singular Jacobian (non-finite Newton step)", it
            return x, st
        ndx = np.linalg.norm(dx)
        st.corrections.append(float(ndx))
        c = st.corrections
        if (creep and natural and len(st.history) > creep
                and st.max_residual > 0.5 * st.history[-1 - creep]
                and c[-1] > 0.5 * c[-1 - creep]):
            # natural: max|r| may rise on the way (its test makes the corrections fall, not
            # max|r|), so it creeps only when neither has halved over `creep` iterations
            st.message = (f"creeping: max|r|={st.max_residual:.2e} and Newton correction "
                          f"{ndx:.2e} after {it - 1} iterations, {st.history[-1 - creep]:.2e} and "
                          f"{c[-1 - creep]:.2e} {creep} iterations before")
            st.iterations = it - 1
            return x, st
        lam = 1.0
        big = np.max(np.abs(dx[:-1]))
        if big > max_dy:
            lam = max_dy / big
        while not problem.valid(x + lam * dx) and lam > 1e-12:
            lam *= 0.5
        accepted = False
        for _ in range(30):
            xt = x + lam * dx
            t0 = time.perf_counter()
            rt = problem.residual(xt)
            st.t_residual += time.perf_counter() - t0
            nt = np.linalg.norm(rt) if np.all(np.isfinite(rt)) else np.inf
            if lam == 1.0 and nt < np.inf and _max_abs(rt) <= tol:
                accepted = True
                break
            if natural:
                ok = nt < np.inf and (np.linalg.norm(_simplified(J, rt, lu, fresh, linear))
                                      <= (1.0 - 0.25 * lam) * ndx)
            else:
                ok = nt < (1.0 - 1e-4 * lam) * norm
            if ok:
                accepted = True
                break
            lam *= 0.5
        if not accepted:
            st.iterations = it
            if st.max_residual <= ROUNDOFF * tol:
                # no step along J⁻¹r lowers ‖r‖₂ and max|r| is within ROUNDOFF of tol: the floor
                # of the residual in floating point, not a failure to converge
                st.converged = True
                st.message = (f"converged at round-off: max|r|={st.max_residual:.2e} (tol "
                              f"{tol:.0e}; no step lowers it, iteration {it})")
                return x, st
            st.message = (f"line search failed at iteration {it} (max|r|={st.max_residual:.2e}); "
                          "the guess is outside Newton's basin or the grid cannot hold the pulse")
            return x, st
        x = xt
        if reuse and lam == 1.0 and fresh:
            t0 = time.perf_counter()
            x, m, k = chord(problem, x, lu, tol, r0=rt)      # rt: the line search's r(x)
            st.t_residual += time.perf_counter() - t0
            st.chord_iterations += k
            if m <= tol:
                st.max_residual = m
                st.history.append(m)      # x moved by chord iterations: no Jacobian at x
                st.converged, st.iterations = True, it
                st.message = (f"converged: max|r|={m:.2e} ({st.chord_iterations} chord "
                              "iterations)")
                return x, st
        t0 = time.perf_counter()
        r, J = problem.residual_and_jacobian(x)
        st.t_jacobian += time.perf_counter() - t0
        st.jacobian = J
        norm = np.linalg.norm(r)
    st.max_residual = _max_abs(r)
    st.converged = st.max_residual <= tol
    st.iterations = max_iter
    st.message = ("converged" if st.converged else "not converged") + \
        f" after {max_iter} iterations: max|r|={st.max_residual:.2e}"
    return x, st


def _simplified(J, r, lu, fresh, linear):
    """The simplified Newton correction J⁻¹ r of the natural line search: by the LU of J, or,
    where the step was solved on an earlier LU (J then intact), by the same GMRES."""
    if not fresh:
        d, _ = gmres_on_lu(J, r, lu, linear.rtol, linear.max_iter)
        if d is not None:
            return d
    return lu_solve(lu, r)


def levenberg_marquardt(problem, x0, tol=NEWTON_TOL, max_iter=200, **_):
    """scipy.optimize.least_squares (method 'lm', MINPACK) with the analytic Jacobian."""
    cache = {}

    def fun(x):
        r, J = problem.residual_and_jacobian(x)
        cache["x"], cache["J"] = x.copy(), J
        return r

    def jac(x):
        if "x" in cache and np.array_equal(cache["x"], x):
            return cache["J"]
        return problem.residual_and_jacobian(x)[1]

    res = least_squares(fun, np.array(x0, float), jac=jac, method="lm", xtol=1e-15, ftol=1e-15,
                        gtol=1e-15, max_nfev=max_iter, x_scale="jac")
    mr = _max_abs(problem.residual(res.x))
    ok = mr <= tol
    st = SolveStats(ok, ("converged" if ok else "not converged") + f": {res.message} max|r|={mr:.2e}",
                    int(res.nfev), mr)
    return res.x, st


SOLVERS = {"newton": newton, "lm": levenberg_marquardt}
