"""At real σ the stability matrices are real (M(σ̄) = conj M(σ)), and the eigen-solvers factorise
them in real arithmetic: a third of the cost of a complex LU, the same answer."""
import numpy as np
import pytest

from slippulse.spectrum import eigensolve as es


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


def test_the_kernel_assembly_at_real_sigma_is_real_and_equals_the_complex_one(pulse12, params):
    """The product integration of W̃ runs in real arithmetic at real σ, with the same matrices as
    the complex assembly of the same σ + 0j (tables, Filon weights and all)."""
    from slippulse.spectrum.operators import ElasticOperator
    from slippulse.spectrum.kernels import KernelTables, assemble_w
    from slippulse.steady.hilbert import add_times_slopes
    p = pulse12.to_pulse()
    el = ElasticOperator(p.xi, p.beta, params.c_s, params.mu)
    for s_per_L in (22.65, 1e-3, 300.0):          # 300: far segments by Filon–Gauss
        sigma = s_per_L * p.beta * params.c_s / p.L
        tab = KernelTables(sigma, el.beta, el.c_s, el.r_min, el.r_max)
        assert tab.real and tab.GA.dtype == float
        W, dW = el.kernel_matrices(sigma)
        assert W.dtype == float and dW.dtype == float
        n = p.xi.size
        cargs = list(tab.args())
        for k in (0, 2, 3):                         # κ, σ, λ₀ as complex numbers
            cargs[k] = complex(cargs[k])
        cargs[6] = tab.GA.astype(complex)
        cargs[8] = tab.EB.astype(complex)
        A = [np.zeros((n, n), complex) for _ in range(4)]
        assemble_w(el.xi, tuple(cargs), tuple(A), el.split_per_side)
        Wc = add_times_slopes(A[0], A[1], el.xi)
        dWc = add_times_slopes(A[2], A[3], el.xi)
        assert np.abs(Wc.imag).max() == 0.0
        assert np.allclose(W, Wc.real, rtol=0, atol=1e-14 * np.abs(W).max())
        assert np.allclose(dW, dWc.real, rtol=0, atol=1e-14 * np.abs(dW).max())
    # complex σ: complex tables and matrices
    W, _ = el.kernel_matrices(complex(sigma, 0.1 * sigma))
    assert W.dtype == complex and np.abs(W.imag).max() > 0


def test_the_stability_matrices_at_real_sigma_are_real_and_equal_the_complex_ones(pulse12,
                                                                                   params):
    """M(σ), M′(σ) at real σ come out as real arrays (state, slip and kernel recursions in real
    arithmetic) and agree with the complex assembly at σ + 1e-300j to rounding."""
    from slippulse.spectrum.operators import StabilityOperator
    p = pulse12.to_pulse()
    op = StabilityOperator(p, params, pin_translation=True)
    assert op.matrices(0.0)[0].dtype == float
    for s_per_L in (22.65, 1e-4):
        sigma = s_per_L * op.rate_unit
        M, dM = op.matrices(sigma)
        Mc, dMc = op.matrices(complex(sigma, 1e-300))
        assert M.dtype == float and dM.dtype == float
        assert Mc.dtype == complex
        assert np.abs(M - Mc).max() <= 1e-14 * np.abs(M).max()
        assert np.abs(dM - dMc).max() <= 1e-14 * np.abs(dM).max()
