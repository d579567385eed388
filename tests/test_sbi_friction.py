"""The friction solve at each point and the initial conditions of the SBI stepper."""

import numpy as np
import pytest

from slippulse.core import friction as fr
from slippulse.core.params import DEFAULT as P, ParameterError
from slippulse.dynamics.stepper import PredictorCorrector, RateStateInterface, solve_point

TAU_D = 1.2 * P.tau_min


@pytest.fixture(scope="module")
def law():
    return RateStateInterface(P, TAU_D)


def test_friction_solve_returns_strength_to_1e12(law):
    # V from 1e-12 to 10 m/s, states from 1e-6 to 1e3 s; guesses far off (1e-9 m/s)
    rng = np.random.default_rng(7)
    V = 10.0 ** np.linspace(-12.0, 1.0, 400)
    phi = 10.0 ** rng.uniform(-6.0, 3.0, V.size)
    tau_el = P.sigma * fr.f(V, phi, *P.law_args) + law.eta * V
    v, tau, it = law.solve(tau_el, phi, 0.0, None, np.full(V.size, 1e-9))
    strength = P.sigma * fr.f(v, phi, *P.law_args)
    assert np.max(np.abs(strength - tau) / tau) < 1e-12          # τ = σ f(V, φ)
    assert np.max(np.abs(tau + law.eta * v - tau_el) / tau_el) < 1e-14
    assert np.max(np.abs(v / V - 1.0)) < 1e-11
    assert it <= 15                                                 # a few Newton steps


def test_friction_solve_iterations_with_previous_rate_as_guess(law):
    # a jump of three orders of magnitude in V from the guess: Newton in ln V, a handful of steps
    V = np.array([1e-9, 1e-6, 1e-3, 1.0])
    phi = np.array([1.0, 1e-1, 1e-4, 1e-6])
    tau_el = P.sigma * fr.f(V, phi, *P.law_args) + law.eta * V
    for i in range(V.size):
        v, it = solve_point(tau_el[i], phi[i], V[i] * 1e-3, law.eta, P.sigma, *P.law_args)
        assert abs(v / V[i] - 1) < 1e-12
        assert it <= 12


def test_friction_solve_nonpositive_stress_gives_rest(law):
    v, it = solve_point(-1.0, 1.0, 1e-3, law.eta, P.sigma, *P.law_args)
    assert v == 0.0 and it == 0


def test_gaussian_initial_state_is_balanced(law):
    st = PredictorCorrector(P, 64, 0.5, law, history="soe")
    st.set_gaussian(amplitude=1e-3, width=0.02, position=0.25)
    # friction balances the t = 0 stress τ = τ_d − η(V − v_stick) at every point
    strength = P.sigma * fr.f(st.V, st.phi, *P.law_args)
    assert np.max(np.abs(strength / st.tau - 1)) < 1e-13
    assert st.V.max() == pytest.approx(law.v_stick + 1e-3, rel=1e-12)
    with pytest.raises(ParameterError, match="amplitude"):
        st.set_gaussian(amplitude=10.0, width=0.02, position=0.25)


def test_rate_state_interface_rejects_bad_tau_d():
    with pytest.raises(ParameterError):
        RateStateInterface(P, 0.9 * P.tau_min)
