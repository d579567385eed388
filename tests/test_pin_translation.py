"""Translation pinned: the rank-one change that makes v₀′ an exact null vector of M(0),
the Newton stop on a converged σ with an unconverged vector, the det-sign bracket of real
eigenvalues, and the Richardson value of the translation eigenvalue (docs/spectrum.md §2)."""
import math

import numpy as np
import pytest

from slippulse.spectrum.eigensolve import newton_eigen, real_eigenvalues
from slippulse.spectrum.refine import richardson
from slippulse.spectrum.pulse import StabilityOperator


class _Pencil:
    """M(σ) = A − σ I with known eigenvalues (the diagonal of a triangular A)."""

    def __init__(self, A):
        self.A = np.asarray(A, float)
        self.n = self.A.shape[0]
        self.rate_unit = 1.0

    def matrices(self, sigma, deriv=True):
        M = self.A.astype(complex) - complex(sigma) * np.eye(self.n)
        return M, (-np.eye(self.n, dtype=complex) if deriv else None)


def _triangular(eigs, seed=0):
    rng = np.random.default_rng(seed)
    n = len(eigs)
    A = np.triu(rng.normal(size=(n, n)), 1)
    A[np.diag_indices(n)] = eigs
    Q, _ = np.linalg.qr(rng.normal(size=(n, n)))
    return Q @ A @ Q.T


def test_pinned_M0_has_translation_as_exact_null_vector(pulse12, params):
    p = pulse12.to_pulse()
    op = StabilityOperator(p, params)
    pin = StabilityOperator(p, params, pin_translation=True)
    t = op.S @ op.v0
    M0 = op.matrices(0.0, deriv=False)[0]
    P0 = pin.matrices(0.0, deriv=False)[0]
    r_before = np.linalg.norm(M0 @ t) / (np.linalg.norm(M0) * np.linalg.norm(t))
    r_after = np.linalg.norm(P0 @ t) / (np.linalg.norm(P0) * np.linalg.norm(t))
    assert r_after < 1e-15 < r_before                  # exact only after the change
    # a σ-independent rank-one change, of the size of the residual it removes
    s = 5.0 * op.rate_unit
    d0, ds = P0 - M0, pin.matrices(s, deriv=False)[0] - op.matrices(s, deriv=False)[0]
    assert np.max(np.abs(ds - d0)) <= 1e-12 * np.max(np.abs(M0))
    assert np.linalg.matrix_rank(d0, tol=1e-8 * np.linalg.norm(d0)) == 1
    assert np.linalg.norm(d0) <= 1.01 * np.linalg.norm(M0 @ t) / np.linalg.norm(t)
    # M′ is not changed
    assert np.array_equal(pin.matrices(s)[1], op.matrices(s)[1])


def test_newton_judges_the_new_vector_when_sigma_is_already_converged():
    """A start with σ on the eigenvalue and a poor vector: the σ step is below tol at once, but
    the residual of the start is not; the iteration goes on and converges (it stopped and
    reported failure before)."""
    op = _Pencil(_triangular([0.3, 1.0, 2.0, -1.5]))
    w, V = np.linalg.eig(op.A)
    k = int(np.argmin(abs(w - 0.3)))
    x0 = V[:, k] + 0.05 * np.random.default_rng(1).normal(size=4)
    eig = newton_eigen(op, w[k].real * (1 + 1e-12), x0, tol=1e-7, min_re=0.01)
    assert eig.converged, eig.message
    assert abs(eig.sigma - w[k]) < 1e-12 and eig.residual < 1e-6


def test_det_sign_bracket_separates_two_close_real_eigenvalues():
    eigs = [1e-3, 1.2e-3, 0.5, -0.2, 3.0]
    op = _Pencil(_triangular(eigs, seed=2))
    b = real_eigenvalues(op, 5e-4, 2e-3, n_scan=12, xtol=1e-12)
    assert len(b.roots) == 2
    assert np.allclose(b.roots, [1e-3, 1.2e-3], rtol=0, atol=1e-11)
    # a complex pair shows no sign change: the bracket sees nothing (it is not a count)
    A = _triangular([0.5, 3.0, -1.0, 2.0], seed=3)
    A[:2, :2] = [[1e-3, 1e-3], [-1e-3, 1e-3]]           # 1e-3 ± 1e-3 i
    assert real_eigenvalues(_Pencil(A), 5e-4, 2e-3, n_scan=12).roots == []


@pytest.mark.parametrize("p", [2.0, 4.0])
def test_richardson_recovers_the_limit_and_its_bar_covers_the_finest_error(p):
    n = 1000.0 * np.sqrt(2.0) ** np.arange(4)
    x = 0.5 + 3e3 * n ** -p
    val, err, order = richardson(x)
    assert abs(order - p) < 0.05
    assert abs(val - 0.5) < 1e-3 * abs(x[-1] - 0.5)
    assert abs(x[-1] - 0.5) <= err
    assert all(math.isnan(v) for v in richardson([1.0, 2.0]))        # two levels: no order


def test_pinned_ladder_in_the_product(tmp_path, pulse12, params):
    """`run_spectrum(pin_translation=True, level0_points=...)`: a ladder below the pulse's own N,
    σ_t = 0 by construction, the setting stored, s within 1e-3 of the rate of record."""
    from slippulse.core.h5io import write_pulse
    from slippulse.spectrum.pulse import read_spectrum
    from slippulse.spectrum.family import SpectrumSettings, run_spectrum
    f = str(tmp_path / "one.h5")
    write_pulse(f, pulse12.to_pulse(), params)
    rep = run_spectrum(f, SpectrumSettings(extra=False, levels=2, level0_points=400, pin_translation=True))
    assert rep.failed == []
    st = read_spectrum(f, "td1.2000")
    assert list(st["refine_n_points"]) == [400, 566, 800]
    assert st["setting_pin_translation"] == 1 and st["setting_level0_points"] == 400
    tl = np.asarray(st["refine_translation_levels"])
    # σ_t = 0 by construction (test_pinned_M0_has_translation_as_exact_null_vector): not
    # computed on any level (it was rounding, ≤ 1e-9 s, at a cost of 6 s of a
    # deep pulse's 30 s), stored as nan; uniform slip is still checked at level 0
    assert np.all(np.isnan(tl))
    assert st["uniform_slip_backward_error"] < 1e-12
    assert abs(st["s_per_L"] - 22.6536) < 1e-3 * 22.6536


def test_cli_points_out_of_range_is_one_line(tmp_path, pulse12, params):
    import cli_inproc
    from slippulse.core.h5io import write_pulse
    f = str(tmp_path / "one.h5")
    write_pulse(f, pulse12.to_pulse(), params)
    r = cli_inproc.run(["steady", "stability", f, "--points", "50"])
    assert r.returncode == 2
    assert r.stderr.strip().count("\n") == 0 and "points=50" in r.stderr
