"""Eigen-solvers of the nonlinear eigenproblem M(σ) V₁ = 0 (docs/spectrum.md): shift-invert Arnoldi on
the linearisation M(σ_a) + (σ − σ_a) M′(σ_a) for candidates, Newton on the bordered system (nonlinear
inverse iteration with the exact M′) to refine them, and the neutral (σ = 0) modes.
"""
from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np
from scipy.linalg import lu_factor, lu_solve


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


def relres(M, x, r=None):
    """Componentwise backward error max_i |r|_i / (|M| |x|)_i of the residual r (default M x; the
    rows of M span many decades: the leading edge is resolved with cells 10⁴× finer than the
    body)."""
    r = matvec(M, x) if r is None else r
    return float(np.max(np.abs(r) / (np.abs(M) @ np.abs(x))))


def real_if_real(*mats):
    """The matrices as real (C-contiguous) arrays where all of them have an exactly zero
    imaginary part, else as given. M(σ) and M′(σ) are real at real σ (M(σ̄) = conj M(σ); the
    assembly gives exactly 0 there), and a real LU costs a third of a complex one (N = 5009,
    one thread: 1.5 s against 4.9 s; docs/spectrum.md)."""
    if all(not np.iscomplexobj(A) or not np.any(A.imag) for A in mats):
        return tuple(np.ascontiguousarray(A.real) for A in mats)
    return mats


def matvec(A, x):
    """A x for a real or complex A and a complex x, without a complex copy of a real A."""
    if np.iscomplexobj(A) or not np.iscomplexobj(x):
        return A @ x
    return (A @ np.ascontiguousarray(x.real)) + 1j * (A @ np.ascontiguousarray(x.imag))


class Factor:
    """The LU factorisation of a real or complex N×N matrix, solving complex right-hand sides
    (a real factor solves their real and imaginary parts as two real columns)."""

    def __init__(self, A):
        self.real = not np.iscomplexobj(A)
        self.lu = lu_factor(A, check_finite=False)

    def solve(self, b):
        if self.real and np.iscomplexobj(b):
            y = lu_solve(self.lu, np.column_stack([b.real, b.imag]), check_finite=False)
            return y[:, 0] + 1j * y[:, 1]
        return lu_solve(self.lu, b, check_finite=False)


#: An imaginary part below this fraction of max(|σ|, c/L) is set to exactly 0 (see :func:`snap_real`).
REAL_SNAP = 1e-13


def snap_real(sigma, scale):
    """σ with its imaginary part set to exactly 0 where |Im σ| ≤ REAL_SNAP max(|σ|, scale).

    Newton converges quadratically onto a real eigenvalue, so an iterate's imaginary part is
    squared at each step: 1e-17, 1e-34, ... 1e-318 relative, and from there the tracked
    eigenvalue carries a subnormal imaginary part from pulse to pulse and level to level. Every
    complex operation of the kernel assembly with it then runs 20-25× slower (measured at
    1.03 τ_min, N = 1250: four Newton iterations in 165 s from 0.1829 + 1.1e-318j, in 8.2 s from
    0.0886 + 5.9e-14j). Below 1e-13 relative the imaginary part is rounding noise."""
    sigma = complex(sigma)
    if sigma.imag != 0.0 and abs(sigma.imag) <= REAL_SNAP * max(abs(sigma), scale):
        return complex(sigma.real, 0.0)
    return sigma


#: Solves with the factor of M(σ_k) that :func:`newton_eigen` spends on the vector once σ has
#: converged and the vector has not, before it assembles M again. Each is an inverse-iteration
#: step on the linearisation M(σ_k) + (σ − σ_k) M′(σ_k), which contracts the vector's error by
#: |σ* − σ_k|/|σ₂ − σ_k| (σ₂ the next pencil eigenvalue), so one or two suffice where σ_k is
#: within the step criterion of σ*; a solve costs O(N²) against the O(N²) assembly with its
#: kernel tables and the O(N³) LU (measured on the deep pulses, N = 3542–5009: one assembly
#: fewer per ladder level, BENCHMARKS.md).
FROZEN_SOLVES = 4


def frozen_solves(lu, M, dM, e, x, sigma, scale, step_tol, res_tol, hist, sig=None):
    """Inverse iteration on the pencil M + (σ − σ_k) M′ (M, M′ and the factor `lu` of M at
    σ_k = `sigma`), from the pair (sig, x) (sig: Newton's σ_{k+1}; None: σ_k): (σ, x,
    linearised residual, converged), the last pair. Stops unconverged once σ moves more than
    `step_tol` from σ_k (the linearisation's remainder, O(|σ − σ_k|²), is then no longer
    negligible against res_tol) or after :data:`FROZEN_SOLVES` solves."""
    sig, res = (sigma if sig is None else sig), float("inf")
    for _ in range(FROZEN_SOLVES):
        u = lu.solve(matvec(dM, x))
        eu = np.vdot(e, u)
        sig_new = snap_real(sigma - 1.0 / eu, scale)
        d = sig_new - sigma
        if abs(d) > step_tol:               # Newton goes on from this σ (a new assembly)
            return sig_new, u / eu, res, False
        sig, x = sig_new, u / eu
        hist.append(complex(sig))
        res = relres(M, x, matvec(M, x) + d * matvec(dM, x))
        if res < res_tol:
            return sig, x, res, True
    return sig, x, res, False


#: Inverse-iteration solves with the first factor, M(σ₀)⁻¹ M′(σ₀), that :func:`newton_eigen`
#: (``purify``) spends on a start vector taken from elsewhere (the neighbouring pulse's mode moved
#: over) before its first update of σ. Measured on the deep pulses at level 0 (N = 3542, L ≈
#: 3.5 km): from the neighbour's σ 2–5 % off and its mode, the first Newton step went
#: the wrong way (7.64 → 7.81 against 7.35, in 1e−5 c/L) and Newton needed 3–4 assemblies; the
#: vector's error along the other eigenvalues near the imaginary axis is what misleads the step.
#: Each solve is O(N²) against an assembly and an O(N³) LU.
PURIFY_SOLVES = 3


def newton_eigen(op, sigma0, x0, tol=1e-10, max_iter=12, min_re=None, res_tol=1e-6, purify=0):
    """Newton on the bordered system M(σ) x = 0, eᴴx = 1 (nonlinear inverse iteration with M′).

    u = M(σ_k)⁻¹ M′(σ_k) x_k,  σ_{k+1} = σ_k − 1/(eᴴu),  x_{k+1} = u/(eᴴu);  quadratic.
    Converged when |σ_{k+1} − σ_k| ≤ tol·max(|σ_k|, c/L) and the componentwise backward error of
    the new pair is below res_tol. That error is measured with the matrices already assembled,
    M(σ_{k+1}) x_{k+1} = [M(σ_k) + (σ_{k+1} − σ_k) M′(σ_k)] x_{k+1} + O(|σ_{k+1} − σ_k|²)
    (the O(tol²) remainder is far below res_tol), so a converged step needs no further
    iteration to judge its vector; where it fails, the iteration goes on. Leaving the analytic
    half-plane (Re σ ≤ min_re) is a failure.

    ``purify`` > 0: before the first update, up to that many further inverse-iteration solves
    x ← M(σ₀)⁻¹ M′(σ₀) x with the first factor (stopping once σ₀ − 1/(eᴴu) moves by less than
    the step criterion), so that σ₁ comes from the pencil's eigenvector nearest σ₀ rather than
    from the start vector: σ₁ − σ* is then O(|σ₀ − σ*|²) (see :data:`PURIFY_SOLVES`).
    """
    scale = op.rate_unit
    min_re = 1e-4 * scale if min_re is None else min_re
    x = np.asarray(x0, complex)
    e = x / np.vdot(x, x)                  # eᴴ x0 = 1, e fixed
    x = x / np.vdot(e, x)
    sigma = snap_real(sigma0, scale)
    hist = []
    res = float("nan")
    for it in range(1, max_iter + 1):
        if not sigma.real > min_re:
            return Eigen(sigma, x, False, it, res,
                         f"left the half-plane Re sigma > {min_re / scale:.0e} c/L "
                         f"(sigma L/c = {sigma / scale:.4g})", hist)
        M, dM = real_if_real(*op.matrices(sigma))      # real at real σ: a real LU
        res = relres(M, x)
        lu = Factor(M)
        u = lu.solve(matvec(dM, x))
        eu = np.vdot(e, u)
        if it == 1 and purify:
            est = sigma - 1.0 / eu
            for _ in range(int(purify)):
                u = lu.solve(matvec(dM, u / eu))
                eu = np.vdot(e, u)
                moved = abs(sigma - 1.0 / eu - est)
                est = sigma - 1.0 / eu
                if moved <= tol * max(abs(sigma), scale):
                    break
        step = 1.0 / eu
        sigma_new = snap_real(sigma - step, scale)
        step = sigma - sigma_new
        x = u / eu
        hist.append(complex(sigma_new))
        if abs(step) <= tol * max(abs(sigma), scale):
            # the new pair's residual, linearised about σ_k (see above)
            res_new = relres(M, x, matvec(M, x) - step * matvec(dM, x))
            if min(res, res_new) < res_tol:
                return Eigen(sigma_new, x, True, it, res_new if res_new < res_tol else res,
                             "converged", hist)
            # σ is already there but the vector is not (a start whose σ is good and whose
            # vector is not: a mode interpolated from a coarser level or moved over from the
            # neighbouring pulse): the vector by inverse iteration on the linearisation about
            # σ_k, with the factor in hand (see FROZEN_SOLVES), while σ stays within the step
            # criterion of σ_k
            sigma_new, x, res_new, ok = frozen_solves(lu, M, dM, e, x, sigma, scale,
                                                       tol * max(abs(sigma), scale), res_tol,
                                                       hist, sigma_new)
            if ok:
                return Eigen(sigma_new, x, True, it, res_new, "converged", hist)
            if it == max_iter:
                return Eigen(sigma_new, x, False, it, res_new,
                             f"step converged but residual {res_new:.1e}", hist)
            # not there with the frozen factor (σ moved beyond the criterion, or the vector
            # converges slowly, e.g. an Arnoldi candidate near a second eigenvalue): iterate on
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
    sigma_a = snap_real(sigma_a, op.rate_unit)
    M, dM = real_if_real(*op.matrices(sigma_a))
    lu = Factor(M)
    nu, vecs = _arnoldi(lambda v: lu.solve(matvec(dM, v)), op.n, k)
    sig = complex(sigma_a) - 1.0 / nu
    order = np.argsort(np.abs(sig - sigma_a))
    return sig[order], vecs[:, order]


def neutral_modes(op, k=2):
    """The pencil M(0) + σ M′(0⁺) near σ = 0, whose smallest eigenvalue is translation
    (V₁ = v₀′, exact in the continuum; here up to the discretisation). M′(0⁺) omits the
    O(σ ln σ) part of the kernel, which vanishes at 0. Returns (sigmas, vectors) by |σ|."""
    M0, dM0 = real_if_real(*op.matrices(0.0))
    shift = 1e-3 * op.rate_unit
    A0 = M0 + shift * dM0                   # shifted so that the factorisation is regular
    lu = Factor(A0)
    nu, vecs = _arnoldi(lambda v: lu.solve(matvec(dM0, v)), op.n, k, tol=1e-10, maxiter=100)
    sig = shift - 1.0 / nu
    order = np.argsort(np.abs(sig))
    return sig[order], vecs[:, order]


def det_sign(op, sigma):
    """(sign, ln|det|) of M(σ) at real σ, where M is real (M(σ̄) = conj M(σ))."""
    M = op.matrices(float(sigma), deriv=False)[0]
    sign, logdet = np.linalg.slogdet(M.real)
    return float(sign), float(logdet)


@dataclass
class Bracket:
    """Real eigenvalues of M(σ) located by sign changes of det M(σ) on a real interval."""

    roots: list                    # σ (1/s) where det M changes sign, by increasing σ
    points: np.ndarray             # σ of the scan (1/s)
    signs: np.ndarray              # sign of det M there
    evaluations: int


def real_eigenvalues(op, lo, hi, n_scan=8, xtol=1e-8):
    """Every real eigenvalue of M(σ) in [lo, hi] (0 < lo < hi, 1/s) that a sign change of
    det M(σ) reveals on a scan of `n_scan` points (geometric), each refined by Brent's method to
    ``xtol`` c/L.

    The sign of det M does not depend on the conditioning of the eigenproblem: two real
    eigenvalues close to each other (near τ_min the leading one and the translation mode, which
    the discretisation moves off 0) are separated as long as a scan point lies between them,
    where Newton on the bordered system, whose Jacobian is singular at a double eigenvalue,
    loses its way. An even number of eigenvalues between two scan points, or a complex pair,
    shows no sign change: the result is what the scan saw, not a count.
    """
    from scipy.optimize import brentq
    unit = op.rate_unit
    pts = np.geomspace(lo, hi, int(n_scan))
    vals = [det_sign(op, x) for x in pts]
    n_eval = len(pts)
    ref = max(v[1] for v in vals)
    roots = []
    for a, b, (sa, _), (sb, _) in zip(pts, pts[1:], vals, vals[1:]):
        if sa * sb >= 0:
            continue
        count = [0]

        def f(x):
            count[0] += 1
            sg, ld = det_sign(op, x)
            return sg * np.exp(np.clip(ld - ref, -700.0, 700.0))
        roots.append(float(brentq(f, a, b, xtol=xtol * unit, rtol=1e-12)))
        n_eval += count[0]
    return Bracket(roots, pts, np.array([v[0] for v in vals]), n_eval)

