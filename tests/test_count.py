"""The argument-principle count of eigenvalues (slippulse.stability.count) and the refinement's
error estimate (slippulse.stability.refine), on operators whose answers are known."""
import math

import numpy as np
import pytest

from slippulse.stability.count import arg_det, count_unstable
from slippulse.stability.refine import RefinedRate


class _Diag:
    """M(σ) = Q diag(σ − λ_j) Q⁻¹ with known zeros λ_j (a dense, non-normal-looking matrix)."""

    rate_unit = 1.0

    def __init__(self, lams, n=12, seed=0):
        rng = np.random.default_rng(seed)
        self.lams = np.concatenate([lams, 50.0 + rng.uniform(1, 5, n - len(lams))])
        self.Q = rng.normal(size=(n, n)) + 1j * rng.normal(size=(n, n))
        self.Qi = np.linalg.inv(self.Q)

    def matrices(self, z, deriv=False):
        return self.Q @ np.diag(z - self.lams) @ self.Qi, None


def test_arg_det_matches_numpy():
    rng = np.random.default_rng(3)
    M = rng.normal(size=(9, 9)) + 1j * rng.normal(size=(9, 9))
    _, a = arg_det(M)
    assert abs(math.remainder(a - np.angle(np.linalg.det(M)), 2 * math.pi)) < 1e-12


@pytest.mark.parametrize("lams, expected", [
    ([0.5, 2 + 1j, 2 - 1j, 5.0, -1.0, 0.3 + 6j], 3),     # 5 (right), -1 (left), 6i (above) outside
    ([-0.2, 4.5], 0),
    ([0.02 + 0.1j, 0.02 - 0.1j, 3.9], 3),                  # close to the left and right edges
])
def test_count_finds_the_zeros_inside_the_box(lams, expected):
    res = count_unstable(_Diag(np.array(lams, complex)), (0.01, 4.0, 4.0))
    assert res.status == "converged", res.message
    assert res.count == expected
    assert abs(res.winding - expected) < 0.05


def test_count_fails_honestly_when_the_budget_is_too_small():
    res = count_unstable(_Diag(np.array([0.02 + 0.1j, 0.02 - 0.1j], complex)), (0.01, 4.0, 4.0),
                         max_evals=26)
    assert res.status == "failed" and res.count is None
    assert "budget" in res.message


def test_count_box_must_lie_in_the_analytic_half_plane():
    with pytest.raises(ValueError, match="0 < x0 < x1"):
        count_unstable(_Diag(np.array([1.0], complex)), (0.0, 4.0, 4.0))


def test_refined_rate_sign_rule():
    r = RefinedRate(s=3.0, s_err=1.0, rate_unit=10.0)
    assert r.sign_resolved and r.describe().startswith("s L/c_p = 0.3")
    r = RefinedRate(s=3.0, s_err=2.0, rate_unit=10.0)
    assert not r.sign_resolved
    text = r.describe()
    assert text.startswith("sign not resolved") and "0.3 " not in text
    r = RefinedRate(s=-5.0, s_err=1.0, rate_unit=10.0)
    assert r.sign_resolved and r.per_length() == (-0.5, 0.1)
