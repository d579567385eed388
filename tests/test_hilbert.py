"""The PV Hilbert matrix against exact transforms, with asserted convergence orders."""
import numpy as np
import pytest
from scipy.special import dawsn

from slippulse.steady.hilbert import hilbert_matrix, spline_slopes


def graded(n, half=12.0):
    s = np.linspace(-1.0, 1.0, n)
    return half * np.sinh(3.0 * s) / np.sinh(3.0)


def gauss_error(n, kind):
    x = graded(n)
    H = hilbert_matrix(x, kind=kind, tails=False)
    exact = -2.0 * np.sqrt(np.pi) * dawsn(x)       # PV∫ e^{−z²}/(z−ξ) dz
    return np.max(np.abs(H @ np.exp(-x * x) - exact))


def lorentz_error(n, kind, a=0.7):
    # smooth sinh mapping: spacing ∝ √(x² + 0.25), reaching |x| = 1e4 (graded, smoothly refined)
    s = np.linspace(-1.0, 1.0, n + 1)
    x = 0.5 * np.sinh(np.arcsinh(2e4) * s)
    H = hilbert_matrix(x, kind=kind, tails=True, center=0.0)
    exact = -np.pi * a * x / (x * x + a * a)        # PV∫ a²/(z²+a²)/(z−ξ) dz
    near = np.abs(x) < 50
    return np.max(np.abs(H @ (a * a / (x * x + a * a)) - exact)[near])


@pytest.mark.parametrize("kind,order", [("cubic", 3.7), ("linear", 1.9)])
@pytest.mark.parametrize("errfun", [gauss_error, lorentz_error])
def test_convergence_order_on_graded_grids(kind, order, errfun):
    e = [errfun(n, kind) for n in (200, 400, 800)]
    observed = np.log2(e[1] / e[2])
    assert observed > order, f"{kind}: errors {e}"
    if kind == "cubic":
        assert e[2] < 1e-6


def test_sign_stress_rises_ahead_of_slip():
    # slip-rate bump at the origin: PV integral is negative ahead (ξ > 0) → τ = τ_d − μF·PV > τ_d
    x = graded(200)
    hu = hilbert_matrix(x) @ np.exp(-x * x)
    assert np.all(hu[x > 0.5] < 0) and np.all(hu[x < -0.5] > 0)


def test_spline_reproduces_cubic_slopes():
    x = np.sort(np.random.default_rng(1).uniform(-3, 3, 40))
    u = 0.3 * x ** 3 - x ** 2 + 2
    m = spline_slopes(x, u)
    # the natural spline is not exact for a cubic at the ends, but is in the interior to O(h⁴)
    inner = slice(10, -10)
    assert np.max(np.abs(m[inner] - (0.9 * x ** 2 - 2 * x)[inner])) < 1e-2


def test_refuses_bad_grids():
    with pytest.raises(ValueError):
        hilbert_matrix(np.array([0.0, 1.0, 1.0, 2.0, 3.0]))
    with pytest.raises(ValueError):
        hilbert_matrix(np.linspace(0, 1, 10), kind="quintic")


def test_cache_returns_the_matrix_of_each_recent_grid_and_drops_the_oldest(monkeypatch):
    """hilbert_matrix keeps the latest matrices by grid (least recently used dropped beyond
    CACHE_BYTES, the last one always kept): a grid seen again gets its own matrix back, equal to
    a fresh assembly; beyond the budget the oldest is rebuilt."""
    from slippulse.steady import hilbert
    grids = [np.linspace(-1.25, 1.0, 40 + k) for k in range(3)]      # grids no other test uses
    first = [hilbert_matrix(g) for g in grids]
    again = [hilbert_matrix(g) for g in grids]
    assert all(a is b for a, b in zip(first, again))
    for g, H in zip(grids, again):
        assert np.array_equal(H, hilbert._hilbert_matrix(g, "cubic", True, None))
        assert not H.flags.writeable
    monkeypatch.setattr(hilbert, "CACHE_BYTES", first[2].nbytes + first[1].nbytes)
    hilbert_matrix(np.linspace(-1.25, 1.0, 30))          # over budget: the two oldest go
    assert hilbert_matrix(grids[2]) is first[2]
    assert hilbert_matrix(grids[0]) is not first[0]
    monkeypatch.setattr(hilbert, "CACHE_BYTES", 0)
    last = hilbert_matrix(grids[1])
    assert hilbert_matrix(grids[1]) is last               # the last one is always kept
    assert hilbert_matrix(grids[2]) is not first[2]       # nothing else
