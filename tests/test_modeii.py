"""Mode-II mapping: inversion of F_II, the Rayleigh speed, limits, uniqueness, rescaling."""
import math

import numpy as np
import pytest

from slippulse.steady import modeii
from slippulse.core.params import DEFAULT

C_S = DEFAULT.c_s
KAPPAS = modeii.CD_OVER_CS + (1.05, 3.0, 10.0)


def _R_direct(b, k):
    return 4 * np.sqrt(1 - b * b) * np.sqrt(1 - b * b / k ** 2) - (2 - b * b) ** 2


def test_rayleigh_speed_poisson_solid_closed_form():
    # ν = 1/4 (c_d/c_s = √3): c_R/c_s = √(2 − 2/√3) exactly
    assert modeii.rayleigh_speed(math.sqrt(3.0)) == pytest.approx(math.sqrt(2 - 2 / math.sqrt(3)),
                                                                  rel=1e-15, abs=0)


@pytest.mark.parametrize("k", KAPPAS)
def test_rayleigh_speed_is_root_of_direct_R(k):
    bR = modeii.rayleigh_speed(k)
    assert 0 < bR < 1
    # the direct form changes sign across bR within a few ulps
    assert _R_direct(bR * (1 - 1e-12), k) > 0 > _R_direct(bR * (1 + 1e-12), k)


@pytest.mark.parametrize("k", KAPPAS)
def test_factored_rayleigh_function_matches_direct_form(k):
    b = np.linspace(0.2, 0.99, 50)
    assert np.allclose(modeii.rayleigh_function(b, k), _R_direct(b, k), rtol=0, atol=1e-14)


@pytest.mark.parametrize("k", modeii.CD_OVER_CS)
@pytest.mark.parametrize("b3", [1e-6, 1e-3, 0.01, 0.05, 0.2, 0.5, 0.8, 0.9, 0.99, 0.999])
def test_beta_ii_inverts_F_II_to_machine_precision(b3, k):
    b2 = modeii.beta_mode_ii(b3, k)
    assert 0 < b2 < modeii.rayleigh_speed(k)
    F2 = modeii.F2(b2, k, C_S)
    F3 = modeii.F3(b3, C_S)
    assert F2 == pytest.approx(F3, rel=1e-12)
    # F3 of the module is the project's F_III
    assert F3 == pytest.approx(float(DEFAULT.F3(b3)), rel=1e-15)


@pytest.mark.parametrize("k", KAPPAS)
def test_F_II_strictly_decreasing_below_rayleigh_speed(k):
    """Uniqueness of β_II: F_II decreases strictly from +∞ to 0 on (0, c_R/c_s)."""
    bR = modeii.rayleigh_speed(k)
    b = np.linspace(1e-4, bR, 200_001)[:-1]
    F = modeii.F2(b, k, C_S)
    assert np.all(np.diff(F) < 0)
    assert F[-1] > 0 and abs(modeii.F2(bR, k, C_S)) < 1e-12 * F[0]


@pytest.mark.parametrize("k", modeii.CD_OVER_CS)
def test_small_beta_limit(k):
    # F_II/F_III → 2(1 − 1/κ²) at equal β → 0, hence β_II/β_III → 2(1 − 1/κ²)
    ratio = 2 * (1 - 1 / k ** 2)
    assert modeii.F2(1e-5, k, C_S) / modeii.F3(1e-5, C_S) == pytest.approx(ratio, rel=1e-9)
    assert modeii.beta_mode_ii(1e-7, k) / 1e-7 == pytest.approx(ratio, rel=1e-12)


@pytest.mark.parametrize("k", modeii.CD_OVER_CS)
def test_beta_iii_to_one_gives_rayleigh_speed(k):
    bR = modeii.rayleigh_speed(k)
    gaps = [bR - modeii.beta_mode_ii(1 - e, k) for e in (1e-2, 1e-4, 1e-6, 1e-8, 1e-10)]
    assert all(g > 0 for g in gaps)
    assert np.all(np.diff(gaps) < 0)
    assert gaps[-1] < 1e-4 * bR


def test_map_pulse_rescales_coordinates_and_lengths():
    xi = np.array([-3.0, -1.0, 0.0, 0.5, 2.0])
    b3, k = 0.6, math.sqrt(3.0)
    xi2, b2 = modeii.map_pulse(xi, b3, k)
    assert b2 == modeii.beta_mode_ii(b3, k)
    assert np.allclose(xi2, xi * b2 / b3, rtol=1e-15, atol=0)
    b2s, L2 = modeii.map_family([0.1, 0.6], [2.0, 5.0], k)
    assert L2[1] == pytest.approx(5.0 * b2 / b3, rel=1e-15)
    # the state equation −β c_s dφ/dξ keeps its coefficient: β_II/λ = β_III
    assert b2 / (xi2[-1] / xi[-1]) == pytest.approx(b3, rel=1e-14)


def test_bad_input_rejected():
    with pytest.raises(ValueError):
        modeii.beta_mode_ii(1.0, 2.0)
    with pytest.raises(ValueError):
        modeii.beta_mode_ii(0.5, 1.0)
