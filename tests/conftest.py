import pytest

from slippulse.core.params import DEFAULT


@pytest.fixture(scope="session")
def params():
    return DEFAULT


@pytest.fixture(scope="session")
def pulse12():
    """The τ_d = 1.2 τ_min pulse on a coarse grid (N = 700), shared by several tests."""
    from slippulse.steady.solver import solve_pulse
    return solve_pulse(DEFAULT, 1.2, n_points=700)
