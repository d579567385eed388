"""At real σ the stability matrices are real (M(σ̄) = conj M(σ)), and the eigen-solvers factorise
them in real arithmetic: a third of the cost of a complex LU, the same answer (stop 38)."""
import numpy as np
import pytest

from slippulse.stability import eigensolve as es


def test_real_if_real_only_where_every_imaginary_part_is_exactly_zero():
    a = np.arange(4.0).reshape(2, 2) + 0j
    b = np.eye(2) + 0j
    ra, rb = es.real_if_real(a, b)
    assert ra.dtype == float and rb.dtype == float and ra.flags.c_contiguous
    b[0, 1] = 1e-300j
    ra, rb = es.real_if_real(a, b)
    assert ra.dtype == complex and rb.dtype == complex


def test_a_real_factor_solves_complex_right_hand_sides():
    rng = np.random.default_rng(1)
    A = rng.standard_normal((30, 30)) + 5 * np.eye(30)
    b = rng.standard_normal(30) + 1j * rng.standard_normal(30)
    f = es.Factor(A)
    assert f.real
    x = f.solve(b)
    assert np.allclose(A @ x, b, atol=1e-12)
    assert np.allclose(x, es.Factor(A.astype(complex)).solve(b), atol=1e-13)
    assert np.allclose(es.matvec(A, b), A.astype(complex) @ b, atol=1e-13)


class _RealAtRealSigma:
    """M(σ) = A − σ B with real A, B: real at real σ, complex elsewhere (as the pulse's)."""

    def __init__(self, n=40, seed=2):
        rng = np.random.default_rng(seed)
        self.A = rng.standard_normal((n, n))
        self.B = np.eye(n) + 0.1 * rng.standard_normal((n, n))
        self.n = n
        self.rate_unit = 1.0

    def matrices(self, sigma, deriv=True):
        M = (self.A - sigma * self.B).astype(complex)
        return M, (-self.B).astype(complex)


def test_newton_onto_a_real_eigenvalue_factorises_real_matrices(monkeypatch):
    op = _RealAtRealSigma()
    lam = np.linalg.eigvals(np.linalg.solve(op.B, op.A))
    real = lam[np.abs(lam.imag) < 1e-12].real
    target = real[real > 0.2][0]
    dtypes = []
    real_lu = es.lu_factor

    def spy(a, **kw):
        dtypes.append(a.dtype)
        return real_lu(a, **kw)
    monkeypatch.setattr(es, "lu_factor", spy)
    x0 = np.ones(op.n) + 0.3j
    e = es.newton_eigen(op, target * (1 + 1e-3), x0, tol=1e-12, min_re=0.01)
    assert e.converged and e.sigma.imag == 0.0
    assert e.sigma.real == pytest.approx(target, rel=1e-10)
    assert dtypes and all(d == np.float64 for d in dtypes)
    # a complex iterate (a complex pair's) keeps complex arithmetic
    cplx = lam[lam.imag > 0.1][0]
    dtypes.clear()
    e = es.newton_eigen(op, cplx * (1 + 1e-4), x0, tol=1e-12, min_re=-1e9)
    assert e.converged and abs(e.sigma - cplx) < 1e-9 * abs(cplx)
    assert dtypes and all(d == np.complex128 for d in dtypes)
