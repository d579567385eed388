"""FFT Hilbert operator on a uniform grid: sign/normalisation against the exact Gaussian transform,
the wrap-around error of zero padding, the M → ∞ lattice limit, and the dispatch/registry."""
import numpy as np
import pytest
from scipy.special import dawsn

from slippulse.steady.hilbert import HILBERT_KINDS, hilbert_matrix, hilbert_matrix_fft


def _gauss_err(H, x):
    exact = -2.0 * np.sqrt(np.pi) * dawsn(x)          # PV∫ e^{−z²}/(z−ξ) dz
    return np.max(np.abs(H @ np.exp(-x * x) - exact))


def test_lattice_limit_is_spectrally_accurate():
    x = np.linspace(-12.0, 12.0, 241)
    assert _gauss_err(hilbert_matrix_fft(x, pad=None), x) < 1e-12


def test_padded_fft_sign_and_wraparound_error_decays_like_pad_squared():
    x = np.linspace(-12.0, 12.0, 241)
    e = [_gauss_err(hilbert_matrix_fft(x, pad=p), x) for p in (2, 8, 32)]
    assert e[0] < 0.05                                  # right sign and normalisation (else O(1))
    assert 12.0 < e[0] / e[1] < 20.0 and 12.0 < e[1] / e[2] < 20.0   # ≈ 16 per ×4 in pad


def test_padded_kernel_matches_closed_form_cotangent():
    n, pad = 50, 2
    x = np.arange(n, dtype=float)
    H = hilbert_matrix_fft(x, pad=pad)
    m = pad * n
    k = np.arange(1, n)
    ck = -(np.pi / m) * (1 - (-1.0) ** k) / np.tan(np.pi * k / m)
    assert np.allclose(H[1:, 0], ck, atol=1e-13)
    assert np.allclose(H[0, 1:], -ck, atol=1e-13)       # antisymmetric Toeplitz


def test_dispatch_registry_and_uniformity_check():
    assert "fft" in HILBERT_KINDS
    x = np.linspace(-5.0, 5.0, 64)
    assert np.allclose(hilbert_matrix(x, kind="fft", tails=False), hilbert_matrix_fft(x, pad=2))
    with pytest.raises(ValueError):
        hilbert_matrix_fft(np.sort(np.random.default_rng(0).uniform(-1, 1, 30)))
    # the interpolating kinds are unchanged by the dispatch wrapper
    g = np.sinh(np.linspace(-2, 2, 80))
    assert np.isfinite(hilbert_matrix(g, kind="cubic")).all()
