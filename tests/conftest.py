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


@pytest.fixture(scope="session")
def spectrum12(pulse12):
    """The leading eigenvalue and mode of ``pulse12`` (``pulse_spectrum``, no extra search; ~10 s),
    shared by the tests that need a stored spectrum."""
    from slippulse.spectrum.pulse import pulse_spectrum
    return pulse_spectrum(pulse12.to_pulse(), DEFAULT, extra=False)


@pytest.fixture
def steady12_with_spectrum(tmp_path, pulse12, spectrum12):
    """A pulse file holding ``pulse12`` and its stored spectrum."""
    from slippulse.core.h5io import write_pulse
    from slippulse.spectrum.pulse import write_spectrum
    path = str(tmp_path / "td12.h5")
    write_pulse(path, pulse12.to_pulse(), DEFAULT)
    write_spectrum(path, spectrum12, {"tol": 1e-7, "extra": 0, "min_re_c_over_L": 1e-3})
    return path
