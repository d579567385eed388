"""Closed-form checks of the mode-III SBI kernel, its step weights, the SOE approximation, the FFTs."""

import numpy as np
import pytest
from scipy import integrate, special

from slippulse.dynamics.fft import RealFFT
from slippulse.dynamics.sbi import kernel_K, kernel_P, soe_nodes, step_weights


def _K_quad(T):
    return 1.0 - integrate.quad(lambda s: special.j1(s) / s if s > 0 else 0.5, 0.0, T,
                                limit=5000, epsabs=1e-15, epsrel=1e-13)[0]


# 25.76536449: scipy's struve(0, ·) returns NaN there (found at N = 2^16); 20: itj0y0's switch
@pytest.mark.parametrize("T", [0.0, 0.3, 2.0, 7.5, 19.99, 20.0, 20.1, 25.76536449, 40.0, 300.0])
def test_kernel_K_matches_quadrature(T):
    # K(T) = ∫_T^∞ J1(s)/s ds = 1 − ∫_0^T J1(s)/s ds
    assert abs(kernel_K(T) - _K_quad(T)) < 1e-12


def test_kernel_limits():
    # K(0) = 1; ∫_0^∞ K = P(∞) = 1 (static limit of the displacement kernel J1(T)/T)
    assert kernel_K(0.0) == pytest.approx(1.0, abs=1e-15)
    assert kernel_P(0.0) == 0.0
    assert abs(kernel_P(1e5) - 1.0) < 1e-6
    # P' = K (central difference)
    T, h = np.array([0.5, 3.0, 20.0, 45.0]), 1e-5
    assert np.allclose((kernel_P(T + h) - kernel_P(T - h)) / (2 * h), kernel_K(T), atol=1e-9)


def test_step_weights_are_interval_integrals():
    omega, dt = np.array([0.0, 1.0, 37.0]), 0.05
    W = step_weights(omega, dt, 0, 40)
    for m in (0, 3, 39):
        for j in (1, 2):
            ref = integrate.quad(lambda s: kernel_K(omega[j] * s), m * dt, (m + 1) * dt,
                                 epsabs=1e-16)[0]
            assert abs(W[m, j] - ref) < 1e-14
    assert np.all(W[:, 0] == dt)         # k = 0: K ≡ 1


def test_soe_reproduces_kernel_integral():
    # P_soe(T) = Re Σ a (e^{zT} − 1)/z against P(T) on T ∈ [1e-6, 1e5]
    z, a = soe_nodes()
    T = np.concatenate([np.geomspace(1e-6, 1.0, 200), np.linspace(1.0, 2000.0, 20000),
                        np.geomspace(2000.0, 1e5, 500)])
    Psoe = np.real(np.expm1(np.outer(T, z)) / z[None, :] @ a)
    err = np.abs(Psoe - kernel_P(T)).max()
    assert err < 2e-7
    # and pointwise K away from T = 0
    Ksoe = np.real(np.exp(np.outer(T[T > 1e-3], z)) @ a)
    assert np.abs(Ksoe - kernel_K(T[T > 1e-3])).max() < 1e-6
    assert np.all(z.real < 0)           # every exponential decays: the recursion is stable


def test_soe_converges_with_node_spacing():
    T = np.linspace(0.5, 500.0, 5000)
    errs = []
    for h in (1.0, 0.7, 0.5):
        z, a = soe_nodes(h=h)
        errs.append(np.abs(np.real(np.exp(np.outer(T, z)) @ a) - kernel_K(T)).max())
    assert errs[0] > 10 * errs[1] > 100 * errs[2] * 0.1


@pytest.mark.parametrize("threads", [1, 2])
def test_real_fft_matches_numpy(threads):
    rng = np.random.default_rng(1)
    u = rng.standard_normal(96)
    F = RealFFT(96, threads=threads)
    uk = F.forward(u).copy()
    assert np.abs(uk - np.fft.rfft(u)).max() < 1e-12
    assert np.abs(F.inverse(uk) - u).max() < 1e-14


def test_real_fft_numpy_backend():
    u = np.arange(8.0)
    F = RealFFT(8, backend="numpy")
    assert np.allclose(F.inverse(F.forward(u)), u, atol=1e-14)
    with pytest.raises(ValueError):
        RealFFT(7)


def test_fft_wisdom_is_cached(tmp_path, monkeypatch):
    import slippulse.dynamics.fft as sfft
    monkeypatch.setenv("XDG_CACHE_HOME", str(tmp_path))
    F = RealFFT(128, planner="measure")
    assert F.backend == "pyfftw"
    assert (tmp_path / "slippulse" / "fftw_wisdom.pkl").exists()
    u = np.linspace(0.0, 1.0, 128)
    assert np.abs(F.forward(u) - np.fft.rfft(u)).max() < 1e-12
    assert sfft.wisdom_path().startswith(str(tmp_path))


def test_fft_falls_back_to_numpy_with_a_warning(monkeypatch):
    import slippulse.dynamics.fft as sfft
    monkeypatch.setattr(sfft, "HAVE_PYFFTW", False)
    with pytest.warns(RuntimeWarning, match="numpy.fft"):
        F = sfft.RealFFT(16)
    assert F.backend == "numpy"
    u = np.arange(16.0)
    assert np.allclose(F.inverse(F.forward(u)), u, atol=1e-13)
