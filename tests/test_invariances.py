"""The three exact similarities of the steady equations (docs/steady.md §1, physics.md): a solve
from the built-in guess with scaled parameters gives the same β, and L scaled as the similarity
says, to 1e-10 relative. Any length, speed, stress or time tuned to Table I in the guess, the grid,
the solver or its tolerances breaks this (checked: the guess with L = 0.7 m and ℓ_c = 5 mm fixed
makes the (D, φ*) solve at N = 500 fail to converge)."""
import dataclasses as dc

import numpy as np
import pytest

from slippulse.core.params import DEFAULT
from slippulse.steady.solver import default_guess, solve_pulse

K = 3.7          # not round: a hidden constant cannot cancel by accident
N = 500          # smallest N whose default solve converges at 1.2 τ_min (400 does not)
RATIO = 1.2

#: name → (scaled parameters, factor on L)
SIMILARITIES = {
    "mu_sigma": (dc.replace(DEFAULT, mu=K * DEFAULT.mu, sigma=K * DEFAULT.sigma), 1.0),
    "D_phi": (dc.replace(DEFAULT, D=K * DEFAULT.D, phi_star=K * DEFAULT.phi_star), K),
    "cs_vstar_phi": (dc.replace(DEFAULT, c_s=K * DEFAULT.c_s, v_star=K * DEFAULT.v_star,
                                phi_star=DEFAULT.phi_star / K), 1.0),
}


@pytest.fixture(scope="module")
def base():
    p = solve_pulse(DEFAULT, RATIO, n_points=N).to_pulse()
    assert p.converged
    return p


@pytest.mark.parametrize("name", list(SIMILARITIES))
def test_similarity_beta_and_L(base, name):
    params, fL = SIMILARITIES[name]
    p = solve_pulse(params, RATIO, n_points=N).to_pulse()
    assert p.converged
    assert abs(p.beta / base.beta - 1.0) <= 1e-10
    assert abs(p.L / (fL * base.L) - 1.0) <= 1e-10
    # the derived scales move with the similarity too
    assert abs(p.L_tilde / base.L_tilde - 1.0) <= 1e-10
    assert abs(params.v_stick(RATIO * params.tau_min) / DEFAULT.v_stick(RATIO * DEFAULT.tau_min)
               / (K if name == "cs_vstar_phi" else 1.0) - 1.0) <= 1e-12


@pytest.mark.parametrize("name", list(SIMILARITIES))
def test_guess_is_similar(name):
    """The built-in guess itself: ξ scaled by the length factor, ln v shifted by ln k (speeds)."""
    params, fL = SIMILARITIES[name]
    xi0, y0, b0 = default_guess(DEFAULT, RATIO, 300)
    xi1, y1, b1 = default_guess(params, RATIO, 300)
    np.testing.assert_allclose(xi1, fL * xi0, rtol=1e-12, atol=1e-12 * fL * np.abs(xi0).max())
    shift = np.log(K) if name == "cs_vstar_phi" else 0.0
    np.testing.assert_allclose(y1, y0 + shift, rtol=0, atol=1e-10)
    assert b1 == b0
