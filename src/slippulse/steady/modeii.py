"""In-plane shear (mode II) pulses from the mode-III ones (paper SM, "The in-plane shear solutions").

The steady equations of the two modes differ only in the inertia factor F(β) multiplying the
Hilbert integral:

    F_III(β) = √(1−β²) / (2π β c_s),
    F_II(β)  = R(β) / (2π β³ √(1−β²) c_s),
    R(β)     = 4 √(1−β²) √(1 − β² c_s²/c_d²) − (2 − β²)²      (Rayleigh function).

The Hilbert integral is invariant under ξ → λξ while the state equation −βc_s dφ/dξ = g fixes β/λ,
so a mode-III pulse (β_III, v(ξ), φ(ξ)) is a mode-II pulse with β_II solving
F_II(β_II) = F_III(β_III) (sub-Rayleigh branch, β_II < c_R/c_s) on the stretched coordinate
ξ_II = ξ_III β_II/β_III; lengths scale the same way, L_II = L_III β_II/β_III.

c_d/c_s values used (:data:`CD_OVER_CS`): √3 (Poisson solid, ν = 1/4: the standard choice for
crustal rock in earthquake models), 2.0 (ν = 1/3, close to PMMA, the material of the laboratory
rupture experiments this line of work compares with) and 1.6 (ν ≈ 0.18, a stiff glassy/granitic
solid); c_d/c_s = √(2(1−ν)/(1−2ν)) in plane strain. They span the physical range of ν ≥ 0, where
c_R/c_s runs from 0.874 (ν = 0) to 0.955 (ν → 1/2).
"""
from __future__ import annotations

import math

import numpy as np
from scipy.optimize import brentq

#: c_d/c_s values of the mode-II mapping: ν ≈ 0.18, 1/4, 1/3 (see module docstring).
CD_OVER_CS = (1.6, math.sqrt(3.0), 2.0)


def _check_kappa(cd_over_cs):
    k = float(cd_over_cs)
    if not (math.isfinite(k) and k > 1.0):
        raise ValueError(f"cd_over_cs={cd_over_cs!r} is invalid: must be a finite number > 1")
    return k


def _P(s, k):
    """P(s) = 16(1 − 1/κ²) + (16/κ² − 24) s + 8 s² − s³, with R = s P / (4ab + (2−s)²)."""
    ik2 = 1.0 / (k * k)
    return 16.0 * (1.0 - ik2) + (16.0 * ik2 - 24.0) * s + 8.0 * s * s - s * s * s


def _Q(s, k):
    """Q(s) = 4 √(1−s) √(1−s/κ²) + (2 − s)² (> 0 for s < 1)."""
    return 4.0 * np.sqrt(1.0 - s) * np.sqrt(1.0 - s / (k * k)) + (2.0 - s) ** 2


def rayleigh_function(beta, cd_over_cs):
    """R(β) = 4√(1−β²)√(1−β²c_s²/c_d²) − (2−β²)², evaluated without cancellation.

    Notes
    -----
    With s = β², a = √(1−s), b = √(1−s/κ²) (κ = c_d/c_s): R = 4ab − (2−s)² =
    (16a²b² − (2−s)⁴)/(4ab + (2−s)²) = s P(s)/Q(s), P(s) = 16(1−1/κ²) + (16/κ² − 24)s + 8s² − s³.
    The direct form loses all digits as β → 0 (R ≈ 2β²(1 − 1/κ²) is a difference of two numbers
    ≈ 4); the factored form keeps full relative precision there.
    """
    k = _check_kappa(cd_over_cs)
    s = np.asarray(beta, dtype=float) ** 2
    return s * _P(s, k) / _Q(s, k)


def rayleigh_speed(cd_over_cs):
    """Rayleigh wave speed c_R/c_s: the root of R(β) on (0, 1).

    Notes
    -----
    The roots of R on (0, 1) are those of the cubic P(s), s = β² (Q > 0 there). P(0) =
    16(1 − 1/κ²) > 0 and P(1) = −1 < 0; the root in between is unique (the classical Rayleigh
    result) and found by Brent's method to full precision. For κ = √3, c_R/c_s = √(2 − 2/√3).
    """
    k = _check_kappa(cd_over_cs)
    s = brentq(lambda s: _P(s, k), 0.0, 1.0, xtol=1e-300, rtol=4 * np.finfo(float).eps,
               maxiter=200)
    return math.sqrt(s)


def F2(beta, cd_over_cs, c_s):
    """Mode-II inertia factor F_II(β) = R(β)/(2π β³ √(1−β²) c_s), s/m (0 < β < 1).

    Evaluated as P(β²)/(2π β √(1−β²) Q(β²) c_s) (see :func:`rayleigh_function`).
    """
    k = _check_kappa(cd_over_cs)
    b = np.asarray(beta, dtype=float)
    s = b * b
    return _P(s, k) / (2.0 * math.pi * b * np.sqrt(1.0 - s) * _Q(s, k) * c_s)


def F3(beta, c_s):
    """Mode-III inertia factor F_III(β) = √(1−β²)/(2π β c_s), s/m."""
    b = np.asarray(beta, dtype=float)
    return np.sqrt(1.0 - b * b) / (2.0 * math.pi * b * c_s)


def beta_mode_ii(beta_iii, cd_over_cs):
    """β_II < c_R/c_s solving F_II(β_II) = F_III(β_III).

    Parameters
    ----------
    beta_iii : float
        Mode-III c_p/c_s, in (0, 1).
    cd_over_cs : float
        c_d/c_s > 1.

    Returns
    -------
    float
        β_II ∈ (0, c_R/c_s).

    Notes
    -----
    Multiplying out the denominators, F_II(β) = F_III(β_3) ⇔ q(β) = 0 with

        q(β) = β_3 P(β²) − β √(1−β²) Q(β²) √(1−β_3²),

    continuous on [0, β_R] (β_R = c_R/c_s), q(0) = 16(1−1/κ²) β_3 > 0 and q(β_R) =
    −β_R √(1−β_R²) Q √(1−β_3²) < 0, so Brent's method on [0, β_R] brackets a root. It is unique:
    F_III maps (0, 1) one-to-one onto (0, ∞) and F_II decreases strictly from +∞ at β = 0 to 0 at
    β_R (checked on 2·10⁵-point grids for κ ∈ {1.05, 1.6, √3, 2, 3, 10} in
    ``tests/test_modeii.py``, and for κ from 1.01 to 100 by hand), so each
    F_III value is taken exactly once. Limits: β_3 → 0 gives β_II ≈ 2(1 − 1/κ²) β_3 (F_II/F_III →
    2(1 − 1/κ²) at equal small β); β_3 → 1 gives β_II → β_R.
    """
    k = _check_kappa(cd_over_cs)
    b3 = float(beta_iii)
    if not 0.0 < b3 < 1.0:
        raise ValueError(f"beta_iii={beta_iii!r} is invalid: must be in (0, 1)")
    bR = rayleigh_speed(k)
    c3 = math.sqrt(1.0 - b3 * b3)

    def q(b):
        s = b * b
        return b3 * _P(s, k) - b * math.sqrt(1.0 - s) * _Q(s, k) * c3

    return brentq(q, 0.0, bR, xtol=1e-300, rtol=4 * np.finfo(float).eps, maxiter=500)


def map_pulse(xi, beta_iii, cd_over_cs):
    """Map a mode-III pulse coordinate to mode II: ξ_II = ξ_III β_II/β_III.

    Parameters
    ----------
    xi : array_like or float
        Mode-III coordinate(s) (or lengths such as L), m.
    beta_iii : float
        Mode-III c_p/c_s.
    cd_over_cs : float
        c_d/c_s.

    Returns
    -------
    xi_ii : ndarray or float
        Mode-II coordinate(s), m (v and φ keep their values node by node).
    beta_ii : float
        Mode-II c_p/c_s.

    Notes
    -----
    The state equation −βc_s dφ/dξ = g keeps its form under ξ_II = λ ξ_III only if
    β_II/λ = β_III, and the Hilbert integral PV∫ v(z)/(z − ξ) dz is scale invariant; with
    μ F_II(β_II) = μ F_III(β_III) the stress balance is unchanged. Lengths: L_II = L_III β_II/β_III.
    """
    b2 = beta_mode_ii(beta_iii, cd_over_cs)
    return np.asarray(xi, dtype=float) * (b2 / float(beta_iii)), b2


def map_family(beta_iii, L_iii, cd_over_cs):
    """β_II and L_II (m) for arrays of mode-III β and L."""
    b3 = np.asarray(beta_iii, dtype=float)
    b2 = np.array([beta_mode_ii(b, cd_over_cs) for b in b3.ravel()]).reshape(b3.shape)
    return b2, np.asarray(L_iii, dtype=float) * b2 / b3
