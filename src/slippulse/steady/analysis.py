"""What the paper measures on a steady pulse and on the family of pulses (Pomyalov et al., PRE 2023).

Per pulse: the length L (FWHM of ln(v/v*+1)), the slip profile δ(ξ), the breakdown energy Ḡ(δ)
(paper Eq. 5), the edge-singularity order ζ (joint fit of v behind and τ − τ_m ahead of the leading
edge), ln(1 − g) along the pulse. Across the family: the effective fracture energy G_c and the cohesive
slip δ_c (Figs. 4, S3) and the scaling law of Eqs. 3–4 (τ̃*, a_v, a_G).

Conventions (see docs/analysis.md): ξ ascending, the pulse travels toward +ξ, so the rest state ahead
is at large ξ and the healing tail at small ξ. Every integral is a trapezoid sum on the solver's
non-uniform grid; every interpolation is local and stated in the function's Notes.
"""
from __future__ import annotations

import math

import h5py
import numpy as np
from scipy.optimize import brentq, least_squares, minimize_scalar

from ..core import h5io
from ..core.friction import RateStateFriction

#: τ_d/τ_min window of the scaling fit (Eqs. 3–4): "near τ_*", both ends inclusive.
SCALING_WINDOW = (1.0, 1.05)
#: Pulses whose Ḡ(δ) curves enter the G_c / δ_c analysis (Fig. 4: τ_d close to τ_*), inclusive.
GC_WINDOW = (1.0, 1.05)
#: Relative spread of the Ḡ curves that counts as "fanned out".
GC_TOL = 0.02


# --------------------------------------------------------------------------- helpers
def _as_arrays(*arrays):
    out = [np.asarray(a, dtype=float) for a in arrays]
    n = out[0].shape
    for a in out:
        if a.ndim != 1 or a.shape != n:
            raise ValueError("arrays must be 1-D and of equal length")
    return out


def _check_grid(xi):
    if xi.size < 3 or np.any(np.diff(xi) <= 0):
        raise ValueError("xi must be strictly ascending with at least 3 points")


def _cross(x, y, i, level):
    """Abscissa in [x[i], x[i+1]] where the local cubic through nodes i−1..i+2 equals `level`.

    The cubic interpolates the nodes, so y − level keeps its sign change on [x[i], x[i+1]] and
    Brent's method brackets the crossing; near the array ends a straight line is used.
    """
    lo, hi = i - 1, i + 3
    if lo < 0 or hi > x.size:
        t = (level - y[i]) / (y[i + 1] - y[i])
        return x[i] + t * (x[i + 1] - x[i])
    xs = x[lo:hi]
    x0, h = xs[1], xs[2] - xs[1]
    s = (xs - x0) / h                       # scaled abscissae: a well-conditioned 4×4 fit
    coef = np.polyfit(s, y[lo:hi] - level, 3)
    s_root = brentq(lambda u: np.polyval(coef, u), 0.0, 1.0, xtol=1e-15, rtol=4 * np.finfo(float).eps)
    return x0 + s_root * h


def _cumtrapz_from_right(x, u):
    """I_i = ∫_{x_i}^{x_N} u dz by the trapezoid rule (I_N = 0)."""
    seg = 0.5 * (u[1:] + u[:-1]) * np.diff(x)
    out = np.zeros_like(x)
    out[:-1] = np.cumsum(seg[::-1])[::-1]
    return out


# --------------------------------------------------------------------------- per-pulse quantities
def pulse_length(xi, v, v_star):
    """Pulse length L: the full width at half maximum of y(ξ) = ln(v/v* + 1).

    Parameters
    ----------
    xi : array_like
        Co-moving coordinate ξ, m, strictly ascending (non-uniform allowed).
    v : array_like
        Slip rate v(ξ), m/s.
    v_star : float
        Regularisation velocity v*, m/s.

    Returns
    -------
    L : float
        ξ_R − ξ_L, m.
    xi_left, xi_right : float
        The two half-maximum crossings, m.

    Notes
    -----
    y = ln(v/v* + 1), h = max(y)/2 (half of the maximum itself, not of max − baseline: the
    paper's operational definition, SM "Solution procedure"). The crossings are the ones nearest to
    the maximum on either side, i.e. the edges of the connected region y ≥ h that holds the maximum.
    Each crossing is located inside its bracketing cell [ξ_i, ξ_{i+1}] as the root of the cubic
    through the four nodes i−1..i+2 (Lagrange interpolation on the non-uniform nodes, error
    O(Δξ⁴ y'''')), found by Brent's method; the cubic passes through the nodes, so the bracket is
    preserved. On a smooth profile this is accurate to a tiny fraction of the cell (tests: a
    Lorentzian with 30 cells across its width gives |ΔL|/Δξ < 1e-3, linear interpolation 3e-2).
    """
    xi, v = _as_arrays(xi, v)
    _check_grid(xi)
    y = np.log1p(v / v_star)
    imax = int(np.argmax(y))
    h = 0.5 * y[imax]
    left = np.nonzero(y[:imax] < h)[0]
    right = np.nonzero(y[imax + 1:] < h)[0]
    if left.size == 0 or right.size == 0:
        raise ValueError("ln(v/v*+1) does not fall below half its maximum on both sides: "
                         "domain too short to measure the FWHM")
    il = left[-1]                      # y[il] < h <= y[il+1]
    ir = imax + right[0]               # y[ir] >= h > y[ir+1]
    xl = _cross(xi, y, il, h)
    xr = _cross(xi, y, ir, h)
    return xr - xl, xl, xr


def slip_profile(xi, v, v_stick, beta, c_s):
    """Slip accumulated by the pulse, δ(ξ) = (βc_s)⁻¹ ∫_ξ^{ξ_max} [v(z) − v_stick] dz.

    Parameters
    ----------
    xi : array_like
        ξ, m, ascending; the pulse travels toward +ξ.
    v : array_like
        Slip rate, m/s.
    v_stick : float
        Rest slip rate, m/s (subtracted: δ is the slip *due to the pulse*).
    beta : float
        c_p/c_s.
    c_s : float
        Shear wave speed, m/s.

    Returns
    -------
    delta : ndarray
        δ at each node, m; δ(ξ_max) = 0 and δ grows backwards into the pulse.

    Notes
    -----
    A material point at ξ was reached by the front of the domain a time (ξ_max − ξ)/c_p ago, so
    δ(ξ) = ∫ (v − v_stick) dt = (βc_s)⁻¹ ∫_ξ^{ξ_max} (v − v_stick) dz (paper, text under Eq. 5, with
    s increasing from the leading edge backwards). Trapezoid rule on the non-uniform grid, O(Δξ²);
    for a positive integrand δ is monotone by construction.
    """
    xi, v = _as_arrays(xi, v)
    _check_grid(xi)
    return _cumtrapz_from_right(xi, v - v_stick) / (beta * c_s)


def breakdown_energy(xi, v, tau, v_stick, beta, c_s, tau_m, origin="front"):
    """Breakdown energy Ḡ(δ) = ∫_0^δ [τ(δ') − τ_m] dδ' along the pulse (paper Eq. 5).

    Parameters
    ----------
    xi, v, tau : array_like
        ξ (m, ascending), slip rate (m/s), shear stress τ = σ f (Pa).
    v_stick, beta, c_s : float
        Rest slip rate (m/s), c_p/c_s, shear wave speed (m/s).
    tau_m : float
        Reference stress τ_m, Pa (the family minimum of τ, see :func:`analyse_family`).
    origin : {"front", "peak"}
        Where δ = 0: "front" (default) at the front end ξ_max of the domain, in the rest state
        ahead of the pulse; "peak" at the stress peak (arg max τ): nodes ahead of it get NaN.

    Returns
    -------
    delta : ndarray
        δ(ξ), m, aligned with `xi` (decreasing with ξ).
    G_bar : ndarray
        Ḡ at each node, J/m².

    Notes
    -----
    The paper measures δ "from the leading edge backwards into the pulse interior". The default
    takes δ = 0 at the front end of the computational domain, which is still the rest state: there
    v − v_stick ≈ 0, so the slip accumulated ahead of the leading edge (creep under the stress
    concentration) is tiny, and no leading-edge detection enters the definition (it is the same for
    every τ_d and every grid). The amount it contributes is reported by :func:`analyse_pulse` as
    ``delta_ahead`` (δ at the stress peak), so it can be checked to be ≪ δ_c; ``origin="peak"``
    gives the alternative convention. The integral is the discrete Stieltjes sum

        Ḡ_i = Σ_{j ≥ i} ½ (τ_j + τ_{j+1} − 2τ_m)(δ_j − δ_{j+1}),

    with δ from :func:`slip_profile`: exact whenever τ is linear in δ between nodes (so a linear
    slip-weakening law is integrated exactly except in the cell holding its kink).
    """
    xi, v, tau = _as_arrays(xi, v, tau)
    delta = slip_profile(xi, v, v_stick, beta, c_s)
    if origin == "peak":
        k = int(np.argmax(tau))
        delta = delta - delta[k]
    elif origin != "front":
        raise ValueError(f"origin={origin!r}: must be 'front' or 'peak'")
    seg = 0.5 * (tau[1:] + tau[:-1] - 2.0 * tau_m) * (delta[:-1] - delta[1:])
    G = np.zeros_like(xi)
    G[:-1] = np.cumsum(seg[::-1])[::-1]
    if origin == "peak":
        G = G - G[k]
        delta[k + 1:] = np.nan
        G[k + 1:] = np.nan
    return delta, G


def ln_one_minus_g(v, phi, params):
    """ln(1 − g(v, φ)) along the pulse (SM Fig. S2): 0 where φ is in steady state with v.

    Parameters
    ----------
    v : array_like
        Slip rate, m/s.
    phi : array_like
        State φ, s.
    params : Parameters
        Friction parameters.

    Notes
    -----
    g = 1 − φ √(v² + v*²)/D = 1 − w(v) φ with the healing rate w = ``heal_rate`` of the friction law
    (the same law object the solver uses), so 1 − g = w φ and ln(1 − g) = ln(w φ). Evaluating the
    product rather than 1 − g avoids the cancellation where g → 1 (φ ≪ φ_ss).
    """
    fr = RateStateFriction(params)
    v, phi = _as_arrays(v, phi)
    return np.log(fr.heal_rate(v) * phi)


def _window_points(xi, y, centre, r_lo, r_hi, side, n):
    """Resample ln-field y at log-spaced distances r ∈ [r_lo, r_hi] from `centre` (side −1 or +1)."""
    r = np.geomspace(r_lo, r_hi, n)
    x = centre + side * r
    if x.min() < xi[0] or x.max() > xi[-1]:
        raise ValueError("edge-singularity window leaves the domain")
    return x, np.interp(x, xi, y)


def _edge_fit_once(xi, lnv, lntau, x_v, x_t, r_lo, r_hi, n):
    """One joint fit; returns (zeta, xi_p, ln a_v, ln a_tau, cov, rss, at_bound)."""
    xb, yb = _window_points(xi, lnv, x_v, r_lo, r_hi, -1, n)     # behind the v maximum
    xa, ya = _window_points(xi, lntau, x_t, r_lo, r_hi, +1, n)   # ahead of the τ maximum
    if not (np.all(np.isfinite(yb)) and np.all(np.isfinite(ya))):
        raise ValueError("non-positive field in the edge-singularity window")
    y = np.concatenate([yb, ya])
    nb = xb.size

    def design(xp):
        M = np.zeros((y.size, 3))
        M[:nb, 0] = np.log(xp - xb)
        M[nb:, 0] = np.log(xa - xp)
        M[:nb, 1] = 1.0
        M[nb:, 2] = 1.0
        return M

    def solve(xp):
        M = design(xp)
        c, *_ = np.linalg.lstsq(M, y, rcond=None)
        r = y - M @ c
        return c, float(r @ r)

    span = x_t - x_v
    res = minimize_scalar(lambda s: solve(x_v + s * span)[1], bounds=(0.0, 1.0),
                          method="bounded", options={"xatol": 1e-10})
    s = float(res.x)
    xp = x_v + s * span
    c, rss = solve(xp)
    zeta = c[0]
    # full 4-parameter Jacobian of the model at the optimum for the covariance
    M = design(xp)
    J = np.zeros((y.size, 4))
    J[:, :3] = M
    J[:nb, 3] = zeta / (xp - xb)
    J[nb:, 3] = -zeta / (xa - xp)
    dof = max(y.size - 4, 1)
    cov = rss / dof * np.linalg.pinv(J.T @ J)
    at_bound = s < 1e-6 or s > 1 - 1e-6
    return zeta, xp, c[1], c[2], cov, rss, at_bound


def edge_singularity(xi, v, tau, tau_m, c_s, sigma, window=None, L=None, n_per_side=40):
    """Edge-singularity order ζ by the paper's joint fit near the leading edge (Fig. 4 inset).

    Fits, with one exponent ζ and one edge position ξ_p,

        ln(v/c_s)            = ln a_v + ζ ln(ξ_p − ξ)    behind the edge,
        ln((τ − τ_m)/σ)      = ln a_τ + ζ ln(ξ − ξ_p)    ahead of it,

    with ξ_p constrained between the slip-rate maximum ξ_v and the stress maximum ξ_τ.

    Parameters
    ----------
    xi, v, tau : array_like
        ξ (m, ascending), slip rate (m/s), stress (Pa).
    tau_m : float
        Reference stress τ_m, Pa.
    c_s, sigma : float
        Shear wave speed (m/s) and normal stress (Pa) (they only scale the amplitudes).
    window : (float, float), optional
        Fit window (r_min, r_max) in m: distances behind ξ_v and ahead of ξ_τ. Default
        r_min = 2ℓ, r_max = min(20ℓ, 0.1 L) with ℓ = ξ_τ − ξ_v (the size of the edge region where
        both fields are bounded); the 0.1 L cap applies when `L` is given.
    L : float, optional
        Pulse length, m (caps the default window).
    n_per_side : int
        Points per side, log-spaced in distance (fields interpolated linearly in ln v / ln(τ−τ_m)).

    Returns
    -------
    dict
        zeta, xi_p (m), zeta_err (total), zeta_err_stat (covariance), zeta_err_window,
        xi_p_err (covariance), a_v, a_tau, window (r_min, r_max), ell (m), at_bound (bool),
        rms (rms log residual), variants (ζ for every window variant).

    Notes
    -----
    For fixed ξ_p the model is linear in (ζ, ln a_v, ln a_τ): it is solved by linear least
    squares and the residual sum is minimised over ξ_p ∈ [ξ_v, ξ_τ] (bounded Brent). The points are
    resampled log-uniformly in distance from the maxima, so the weighting does not depend on the
    grid. Uncertainty: (i) statistical, from the covariance s² (JᵀJ)⁻¹ of the 4-parameter model at
    the optimum (s² = RSS/(n − 4)); (ii) window, half the range of ζ over the 9 windows with r_min
    and r_max each scaled by 0.5, 1, 2 (variants with r_max/r_min < 3 or leaving the domain are
    skipped); ``zeta_err`` = √(stat² + window²). The residuals of a smooth field are correlated,
    so the statistical part alone understates the error; the window part usually dominates.
    """
    xi, v, tau = _as_arrays(xi, v, tau)
    _check_grid(xi)
    iv, it = int(np.argmax(v)), int(np.argmax(tau))
    x_v, x_t = xi[iv], xi[it]
    if not x_t > x_v:
        raise ValueError("the stress maximum is not ahead of the slip-rate maximum: "
                         "no leading edge to fit")
    ell = x_t - x_v
    with np.errstate(divide="ignore", invalid="ignore"):
        lnv = np.log(v / c_s)
        lntau = np.log((tau - tau_m) / sigma)
    if window is None:
        r_hi = 20.0 * ell if L is None else min(20.0 * ell, 0.1 * L)
        window = (2.0 * ell, r_hi)
    r_lo, r_hi = map(float, window)
    if not 0 < r_lo < r_hi:
        raise ValueError(f"edge-fit window (r_min, r_max) = ({r_lo:.3g}, {r_hi:.3g}) m is empty: "
                         "no power-law range between the edge region 2ℓ and 0.1 L")
    zeta, xp, lav, lat, cov, rss, at_bound = _edge_fit_once(xi, lnv, lntau, x_v, x_t,
                                                            r_lo, r_hi, n_per_side)
    variants = []
    for f_lo in (0.5, 1.0, 2.0):
        for f_hi in (0.5, 1.0, 2.0):
            a, b = r_lo * f_lo, r_hi * f_hi
            if b / a < 3.0:
                continue
            try:
                variants.append(_edge_fit_once(xi, lnv, lntau, x_v, x_t, a, b, n_per_side)[0])
            except ValueError:
                continue
    err_stat = float(math.sqrt(max(cov[0, 0], 0.0)))
    err_win = 0.5 * (max(variants) - min(variants)) if variants else float("nan")
    return {
        "zeta": float(zeta), "xi_p": float(xp),
        "zeta_err": float(math.hypot(err_stat, err_win)),
        "zeta_err_stat": err_stat, "zeta_err_window": float(err_win),
        "xi_p_err": float(math.sqrt(max(cov[3, 3], 0.0))),
        "a_v": float(math.exp(lav)), "a_tau": float(math.exp(lat)),
        "window": (r_lo, r_hi), "ell": float(ell), "at_bound": bool(at_bound),
        "rms": float(math.sqrt(rss / (2 * n_per_side))), "variants": variants,
        "x_v": float(x_v), "x_tau": float(x_t),
    }


# --------------------------------------------------------------------------- family quantities
def fracture_energy(family, tol=GC_TOL, n_grid=20000):
    """Effective fracture energy G_c and cohesive slip δ_c from a set of Ḡ(δ) curves (Figs. 4, S3).

    Parameters
    ----------
    family : sequence of (delta, G_bar)
        One pair of arrays per pulse (any order along δ), δ in m, Ḡ in J/m².
    tol : float
        Relative spread of the curves that counts as "fanned out".
    n_grid : int
        Points of the common log-spaced δ grid.

    Returns
    -------
    dict
        G_c (J/m²), G_c_err (J/m², half the range of G_c over tol/2, tol, 2 tol), G_c_threshold
        (the bare-threshold value Ḡ_med(δ_1), for comparison), delta_c (m), delta_fan (m),
        spread_min (relative), tol, n_curves, and the common grid ``delta_grid``, the median curve
        ``G_median`` and the relative spread ``spread``.

    Notes
    -----
    Rule (stated, reproducible):

    1. Each curve is interpolated (linear in Ḡ vs ln δ) on a common grid of ``n_grid`` log-spaced δ
       covering the range shared by all curves (δ > 0).
    2. Relative spread s(δ) = (max_k Ḡ_k − min_k Ḡ_k)/median_k Ḡ_k; absolute spread ΔḠ(δ).
    3. Best overlap: s_0 = min s, at δ_0 (first minimiser). Curves whose ∝δ heads have slightly
       different slopes (different peak stresses) overlap only up to this constant relative
       spread, so the fan-out is measured by the *excess* spread E(δ) = ΔḠ(δ) − s_0 Ḡ_med(δ).
    4. Fan-out: beyond δ_0 the spread first exceeds s_0 + tol at δ_1 and s_0 + 3 tol at δ_3. A
       straight line fitted to E(δ) on [δ_1, δ_3] is extrapolated back to E = 0; its crossing
       (clipped to [δ_0, δ_1]) is the fan-out point δ_f. (If [δ_1, δ_3] holds < 2 grid points,
       δ_f = δ_1.) This removes the O(tol) bias a bare threshold leaves and makes the result
       nearly independent of tol.
    5. G_c = Ḡ_med(δ_f); δ_c is the first δ where the median curve reaches G_c, i.e. the paper's
       definition Ḡ(δ_c) = G_c (SM, "The fracture energy G_c ..."): δ_c = δ_f when Ḡ_med is
       monotone, the end of the ∝δ-then-bending head shared by all curves.

    For curves that coincide up to δ_c and then separate linearly (linear slip weakening to τ_c,
    then constant stresses τ_m + a_k), steps 4–5 return G_c and δ_c exactly (up to interpolation).
    """
    curves = []
    for delta, G in family:
        delta, G = _as_arrays(delta, G)
        ok = np.isfinite(delta) & np.isfinite(G) & (delta > 0)
        d, g = delta[ok], G[ok]
        order = np.argsort(d)
        d, g = d[order], g[order]
        keep = np.concatenate([[True], np.diff(d) > 0])
        curves.append((d[keep], g[keep]))
    if len(curves) < 2:
        raise ValueError("need at least two Ḡ(δ) curves to see them fan out")
    lo = max(c[0][0] for c in curves)
    hi = min(c[0][-1] for c in curves)
    if not hi > lo:
        raise ValueError("the Ḡ(δ) curves share no range of δ")
    grid = np.geomspace(lo, hi, n_grid)
    lg = np.log(grid)
    Gs = np.array([np.interp(lg, np.log(d), g) for d, g in curves])
    Gmed = np.median(Gs, axis=0)
    dG = Gs.max(axis=0) - Gs.min(axis=0)
    with np.errstate(divide="ignore", invalid="ignore"):
        s = np.where(Gmed > 0, dG / Gmed, np.inf)
    i0 = int(np.argmin(s))
    s0 = float(s[i0])
    excess = dG - s0 * Gmed          # spread beyond the best-overlap relative spread

    def fan_out(t):
        above1 = np.nonzero(s[i0:] > s0 + t)[0]
        if above1.size == 0:
            raise ValueError(f"the Ḡ curves never fan out by more than tol={t} over the shared "
                             "δ range")
        i1 = i0 + int(above1[0])
        above3 = np.nonzero(s[i1:] > s0 + 3 * t)[0]
        i3 = i1 + int(above3[0]) if above3.size else n_grid - 1
        if i3 - i1 >= 1:
            p = np.polyfit(grid[i1:i3 + 1], excess[i1:i3 + 1], 1)
            d = -p[1] / p[0] if p[0] > 0 else grid[i1]
            d = float(np.clip(d, grid[i0], grid[i1]))
        else:
            d = float(grid[i1])
        return d, float(np.interp(math.log(d), lg, Gmed)), float(Gmed[i1])

    d_f, G_c, G_thr = fan_out(tol)
    G_var = [G_c]
    for t in (0.5 * tol, 2.0 * tol):
        try:
            G_var.append(fan_out(t)[1])
        except ValueError:
            pass
    G_c_err = 0.5 * (max(G_var) - min(G_var))
    reach = np.nonzero(Gmed >= G_c)[0]
    j = int(reach[0])
    if j == 0:
        delta_c = float(grid[0])
    else:   # linear root between grid[j-1] and grid[j] in ln δ
        t = (G_c - Gmed[j - 1]) / (Gmed[j] - Gmed[j - 1])
        delta_c = float(math.exp(lg[j - 1] + t * (lg[j] - lg[j - 1])))
    return {"G_c": G_c, "G_c_err": float(G_c_err), "G_c_threshold": G_thr, "delta_c": delta_c,
            "delta_fan": d_f, "spread_min": s0, "tol": tol, "n_curves": len(curves),
            "delta_grid": grid, "G_median": Gmed, "spread": s}


def _scaling_C(params):
    """C = v_min μ / (2 τ_min c_s), the prefactor of Eq. 3."""
    return params.v_min * params.mu / (2.0 * params.tau_min * params.c_s)


def scaling_law(tau_d_ratio, tau_star, a_v, a_G, params):
    """β and L̃ of the scaling theory (paper Eqs. 3–4), Eq. 3 solved explicitly for β.

    Notes
    -----
    Eq. 3, β = a_v C √(1−β²)/(x − τ̃*) with x = τ_d/τ_min and C = v_min μ/(2 τ_min c_s), is
    β/√(1−β²) = A ≡ a_v C/(x − τ̃*), hence β = A/√(1 + A²) (and √(1−β²) = 1/√(1+A²)).
    Eq. 4: L̃ = a_G √(1−β²)/(π (x − τ̃*)²). Valid for x > τ̃*; NaN elsewhere.
    """
    x = np.asarray(tau_d_ratio, dtype=float)
    dx = x - tau_star
    with np.errstate(divide="ignore", invalid="ignore"):
        A = np.where(dx > 0, a_v * _scaling_C(params) / dx, np.nan)
        beta = A / np.sqrt(1.0 + A * A)
        L_t = a_G / (np.sqrt(1.0 + A * A) * math.pi * dx * dx)
    return beta, L_t


def scaling_fit(tau_d_ratio, beta, L_tilde, params, window=SCALING_WINDOW, equations="both"):
    """Least-squares fit of the scaling theory (Eqs. 3–4) for τ̃*, a_v, a_G.

    Parameters
    ----------
    tau_d_ratio, beta, L_tilde : array_like
        τ_d/τ_min, c_p/c_s and L̃ = τ_min² L/(μ G_c*) of the pulses.
    params : Parameters
        Gives v_min, τ_min, μ, c_s.
    window : (float, float)
        Inclusive τ_d/τ_min range of the points fitted (default (1.0, 1.05): near τ_*).
    equations : {"both", "beta", "L"}
        "both" (default): the joint fit of Eqs. 3 and 4. Diagnostics: "beta" fits Eq. 3 alone for
        (τ̃*, a_v) (a_G = NaN); "L" fits Eq. 4 alone for (τ̃*, a_G) with the *measured* β in √(1−β²)
        (a_v = NaN). Whether the two τ̃* agree tests the theory's single τ_*.

    Returns
    -------
    dict
        tau_star, a_v, a_G, their 1σ errors (tau_star_err, a_v_err, a_G_err), cov (3×3, NaN rows
        for parameters not fitted), n (points used), window, equations, rms (rms relative
        residual), tau_d_ratio_used.

    Notes
    -----
    Model: :func:`scaling_law` (β from the explicit solution of Eq. 3, and L̃ from Eq. 4 with that
    model β, so the fitted curves depend on the three constants only). Residuals are relative,
    r = [ln β_model − ln β, ln L̃_model − ln L̃] over the n points in the window (2n residuals, equal
    weights: the data span decades in L̃). Solved by ``scipy.optimize.least_squares`` (trust region,
    τ̃* bounded below min x so that x − τ̃* > 0); covariance s² (JᵀJ)⁻¹ with s² = RSS/(m − k)
    (m residuals, k parameters; for noiseless data s → 0 and so do the errors). Needs n ≥ 2
    (n ≥ 3 for a single equation).
    """
    if equations not in ("both", "beta", "L"):
        raise ValueError(f"equations={equations!r}: must be 'both', 'beta' or 'L'")
    x, b, Lt = _as_arrays(tau_d_ratio, beta, L_tilde)
    sel = (x >= window[0]) & (x <= window[1]) & (b > 0) & (b < 1) & (Lt > 0)
    x, b, Lt = x[sel], b[sel], Lt[sel]
    free = {"both": [0, 1, 2], "beta": [0, 1], "L": [0, 2]}[equations]
    m = x.size * (2 if equations == "both" else 1)
    if x.size < 2 or m <= len(free):
        raise ValueError(f"scaling fit ({equations}) needs more pulses with tau_d/tau_min in "
                         f"{window}; found {x.size}")
    C = _scaling_C(params)
    xmin = float(x.min())
    # initial guess: τ̃* halfway between 1 and the lowest τ_d; a_v, a_G from the medians
    ts0 = 1.0 + 0.5 * (xmin - 1.0) if xmin > 1.0 else xmin - 0.01
    a_v0 = float(np.median(b / np.sqrt(1 - b * b) * (x - ts0) / C))
    a_G0 = float(np.median(Lt * math.pi * (x - ts0) ** 2 / np.sqrt(1 - b * b)))
    sq_b = np.sqrt(1.0 - b * b)

    def full(q):
        p = np.array([ts0, a_v0, a_G0])
        p[free] = q
        return p

    def resid(q):
        p = full(q)
        bm, Lm = scaling_law(x, p[0], p[1], p[2], params)
        if equations == "beta":
            return np.log(bm) - np.log(b)
        if equations == "L":
            Lm = p[2] * sq_b / (math.pi * (x - p[0]) ** 2)
            return np.log(Lm) - np.log(Lt)
        return np.concatenate([np.log(bm) - np.log(b), np.log(Lm) - np.log(Lt)])

    upper_ts = xmin - 1e-9 * max(xmin, 1.0)
    p0 = np.array([min(ts0, upper_ts - 1e-6), a_v0, a_G0])
    lo = np.array([0.5, 1e-12, 1e-12])
    hi = np.array([upper_ts, np.inf, np.inf])
    scale = np.array([1e-3, max(a_v0, 1e-12), max(a_G0, 1e-12)])
    res = least_squares(resid, p0[free], bounds=(lo[free], hi[free]), x_scale=scale[free],
                        xtol=1e-15, ftol=1e-15, gtol=1e-15, max_nfev=2000)
    p = np.full(3, np.nan)
    p[free] = res.x
    J = res.jac
    rss = float(res.fun @ res.fun)
    cov = np.full((3, 3), np.nan)
    cov[np.ix_(free, free)] = rss / max(m - len(free), 1) * np.linalg.pinv(J.T @ J)
    err = np.sqrt(np.clip(np.diag(cov), 0.0, None))
    return {"tau_star": float(p[0]), "a_v": float(p[1]), "a_G": float(p[2]),
            "tau_star_err": float(err[0]), "a_v_err": float(err[1]), "a_G_err": float(err[2]),
            "cov": cov, "n": int(x.size), "window": (float(window[0]), float(window[1])),
            "equations": equations, "rms": float(math.sqrt(rss / m)), "tau_d_ratio_used": x}


def divergence_fit(tau_d_ratio, beta, L, window=(1.0, 1.02), quantities="both"):
    """Power-law divergence of L and of 1 − β at a common τ̃*, exponents free.

    Parameters
    ----------
    tau_d_ratio, beta, L : array_like
        τ_d/τ_min, c_p/c_s and the pulse length (m) of the pulses.
    window : (float, float)
        Inclusive τ_d/τ_min range fitted.
    quantities : {"both", "L", "beta"}
        Fit L and 1 − β jointly (one τ̃*), or one of them alone.

    Returns
    -------
    dict
        tau_star, m_L, m_beta, ln_A, ln_B and their 1σ errors (``_err``), cov, n, rms, window.

    Notes
    -----
    Model, with d = τ_d/τ_min − τ̃* > 0:

        L = A d^(−m_L),        1 − β = B d^(m_β).

    The paper's theory (Eqs. 3–4) has, as β → 1, √(1−β²) ≈ √(2(1−β)) = a_v C/d, i.e. m_β = 2,
    and L̃ = a_G √(1−β²)/(π d²) ∝ d^(−3), i.e. m_L = 3. Residuals in logarithms (the data span
    decades), equal weights; ``scipy.optimize.least_squares`` with τ̃* bounded below min τ_d/τ_min;
    covariance s² (JᵀJ)⁻¹, s² = RSS/(m − k). The statistical error ignores the correlated
    discretisation error of the pulses; the fit-window study and the N-comparison carry that.
    """
    if quantities not in ("both", "L", "beta"):
        raise ValueError(f"quantities={quantities!r}: must be 'both', 'L' or 'beta'")
    x, b, Lm = _as_arrays(tau_d_ratio, beta, L)
    sel = (x >= window[0]) & (x <= window[1]) & (b > 0) & (b < 1) & (Lm > 0)
    x, lnL, lnb = x[sel], np.log(Lm[sel]), np.log(1.0 - b[sel])
    use_L, use_b = quantities in ("both", "L"), quantities in ("both", "beta")
    k = 1 + 2 * use_L + 2 * use_b
    m = x.size * (use_L + use_b)
    if m <= k:
        raise ValueError(f"divergence fit ({quantities}) needs more pulses with tau_d/tau_min in "
                         f"{window}; found {x.size}")
    xmin = float(x.min())

    def unpack(p):
        ts, rest = p[0], list(p[1:])
        lA, mL = (rest.pop(0), rest.pop(0)) if use_L else (np.nan, np.nan)
        lB, mb = (rest.pop(0), rest.pop(0)) if use_b else (np.nan, np.nan)
        return ts, lA, mL, lB, mb

    def resid(p):
        ts, lA, mL, lB, mb = unpack(p)
        ld = np.log(x - ts)
        out = []
        if use_L:
            out.append(lA - mL * ld - lnL)
        if use_b:
            out.append(lB + mb * ld - lnb)
        return np.concatenate(out)

    ts0 = xmin - 0.3 * (xmin - 1.0)
    ld0 = np.log(x - ts0)
    p0 = [ts0]
    if use_L:
        c = np.polyfit(ld0, lnL, 1)
        p0 += [c[1], -c[0]]
    if use_b:
        c = np.polyfit(ld0, lnb, 1)
        p0 += [c[1], c[0]]
    upper = xmin - 1e-12
    lo = np.full(k, -np.inf)
    hi = np.full(k, np.inf)
    lo[0], hi[0] = 0.9, upper
    p0[0] = min(p0[0], upper - 1e-9)
    res = least_squares(resid, np.array(p0), bounds=(lo, hi), xtol=1e-15, ftol=1e-15, gtol=1e-15,
                        max_nfev=5000)
    rss = float(res.fun @ res.fun)
    cov_k = rss / (m - k) * np.linalg.pinv(res.jac.T @ res.jac)
    err_k = np.sqrt(np.clip(np.diag(cov_k), 0.0, None))
    names = ["tau_star"] + (["ln_A", "m_L"] if use_L else []) + (["ln_B", "m_beta"] if use_b else [])
    out = {nm: float("nan") for nm in ("tau_star", "ln_A", "m_L", "ln_B", "m_beta")}
    out.update({nm + "_err": float("nan") for nm in list(out)})
    for j, nm in enumerate(names):
        out[nm], out[nm + "_err"] = float(res.x[j]), float(err_k[j])
    out.update(cov=cov_k, names=names, n=int(x.size), rms=float(math.sqrt(rss / m)),
               window=(float(window[0]), float(window[1])), quantities=quantities,
               at_bound=bool(res.x[0] >= upper - 1e-9))
    return out


def beta_parametrised_fit(tau_d_ratio, beta, L, max_one_minus_beta=0.02):
    """The deep family parametrised by 1 − β: q = τ̃* + B (1 − β)^p and L = A (1 − β)^(−r).

    Parameters
    ----------
    tau_d_ratio, beta, L : array_like
        τ_d/τ_min, c_p/c_s and pulse length (m).
    max_one_minus_beta : float
        Fit the pulses with 1 − β ≤ this.

    Returns
    -------
    dict
        tau_star, B, p (with ``_err``, 1σ) of the q law; r, ln_A (with ``_err``) of the L law; n.

    Notes
    -----
    The L law holds no τ̃*, so its exponent r = d ln L / d ln(1/(1 − β)) does not trade off
    against τ̃* as m_L does in :func:`divergence_fit`. The paper's Eqs. 3–4 give, as β → 1,
    √(1−β²) = d/(a_v C) (d = q − τ̃*), hence 1 − β = d²/(2 a_v² C²): p = 1/2; and
    L̃ = a_G √(1−β²)/(π d²) = a_G/(π a_v C d) ∝ (1 − β)^(−1/2): r = 1/2 (m_L = 1, m_β = 2).
    q law: ``scipy.optimize.least_squares`` on q (absolute residuals); L law: straight line in
    logarithms; errors s² (JᵀJ)⁻¹.
    """
    q, b, Lm = _as_arrays(tau_d_ratio, beta, L)
    sel = (1.0 - b <= max_one_minus_beta) & (b < 1) & (Lm > 0)
    q, om, Lm = q[sel], 1.0 - b[sel], Lm[sel]
    if q.size < 5:
        raise ValueError(f"beta-parametrised fit needs >= 5 pulses with 1 - beta <= "
                         f"{max_one_minus_beta}; found {q.size}")

    def res_q(pp):
        return pp[0] + pp[1] * om ** pp[2] - q
    c = np.polyfit(np.sqrt(om), q, 1)
    fq = least_squares(res_q, [c[1], c[0], 0.5], xtol=1e-15, ftol=1e-15, gtol=1e-15,
                       max_nfev=5000)
    cov = np.linalg.pinv(fq.jac.T @ fq.jac) * (fq.fun @ fq.fun) / max(q.size - 3, 1)
    eq = np.sqrt(np.clip(np.diag(cov), 0.0, None))
    cL, covL = np.polyfit(np.log(om), np.log(Lm), 1, cov=True)
    return {"tau_star": float(fq.x[0]), "tau_star_err": float(eq[0]), "B": float(fq.x[1]),
            "B_err": float(eq[1]), "p": float(fq.x[2]), "p_err": float(eq[2]),
            "r": float(-cL[0]), "r_err": float(math.sqrt(covL[0, 0])), "ln_A": float(cL[1]),
            "ln_A_err": float(math.sqrt(covL[1, 1])), "n": int(q.size)}


def _vertex(x, f, i):
    """Abscissa of the extremum of the parabola through (x, f) at nodes i−1, i, i+1 (i at the end:
    x[i])."""
    if i <= 0 or i >= x.size - 1:
        return float(x[i])
    x0, x1, x2 = x[i - 1:i + 2]
    f0, f1, f2 = f[i - 1:i + 2]
    d01, d12 = (f1 - f0) / (x1 - x0), (f2 - f1) / (x2 - x1)
    c = (d12 - d01) / (x2 - x0)
    if c == 0.0:
        return float(x1)
    # f ≈ f1 + b (x − x1) + c (x − x1)², b from the two divided differences
    b = d01 + c * (x1 - x0)
    return float(np.clip(x1 - b / (2.0 * c), x0, x2))


def edge_structure(xi, v, tau, v_star, v_stick):
    """Widths, positions and peaks of the leading and the healing edge of one pulse.

    Parameters
    ----------
    xi, v, tau : array_like
        ξ (m, ascending), slip rate (m/s), shear stress (Pa).
    v_star, v_stick : float
        Regularisation and rest slip rates (m/s).

    Returns
    -------
    dict (lengths in m)
        L, x_left, x_right (FWHM of ln(v/v*+1)); x_vmax, v_max; x_taumax, tau_max (the stress peak
        ahead); ell = x_taumax − x_vmax (the leading-edge region); front_efold, the smallest
        e-folding length of v − v_stick between the slip-rate and the stress peaks; x_front, the
        steepest point of ln v ahead of x_vmax; x_back, the steepest point of ln v in the back half
        of the pulse (the healing front); back_efold = 1/max ∂ξ ln v there; tau_back_min, the
        smallest stress behind x_vmax; heal_width, the distance over which ln(v/v*+1) falls from
        90 % to 10 % of its maximum behind x_left + L/4 (the tail behind the healing front).

    Notes
    -----
    Derivatives are centred differences on the non-uniform grid (``np.gradient``); the steepest
    points are located between nodes by the vertex of the parabola through the three nodes about
    the extreme slope, so that profiles can be aligned on them to a fraction of a cell. The back
    half is ξ < x_left + L/2.
    """
    xi, v, tau = _as_arrays(xi, v, tau)
    _check_grid(xi)
    L, xl, xr = pulse_length(xi, v, v_star)
    iv = int(np.argmax(v))
    ahead = np.arange(xi.size) >= iv
    it = int(np.nonzero(ahead)[0][np.argmax(tau[ahead])])
    u = np.log(np.maximum(v - v_stick, 1e-300))
    if it > iv + 2:
        seg = slice(iv, it + 1)
        front_efold = float(1.0 / np.max(np.abs(np.gradient(u[seg], xi[seg]))))
    else:
        front_efold = float("nan")
    y = np.log(v)
    dy = np.gradient(y, xi)
    front = np.nonzero(ahead)[0]
    i_f = int(front[np.argmin(dy[front])])
    back = np.nonzero(xi < xl + 0.5 * L)[0]
    ib = int(back[np.argmax(dy[back])])
    z = np.log1p(v / v_star)
    tail = xi < xl + 0.25 * L
    zb, xb = z[tail], xi[tail]
    order = np.argsort(zb)
    x90 = float(np.interp(0.9 * z.max(), zb[order], xb[order]))
    x10 = float(np.interp(0.1 * z.max(), zb[order], xb[order]))
    return {"L": float(L), "x_left": float(xl), "x_right": float(xr),
            "x_vmax": float(xi[iv]), "v_max": float(v[iv]),
            "x_taumax": float(xi[it]), "tau_max": float(tau[it]),
            "ell": float(xi[it] - xi[iv]), "front_efold": front_efold,
            "x_front": _vertex(xi, dy, i_f),
            "x_back": _vertex(xi, dy, ib), "back_efold": float(1.0 / dy[ib]),
            "tau_back_min": float(tau[:iv + 1].min()), "heal_width": x90 - x10}


def profile_distance(xi_a, y_a, x_a, xi_b, y_b, x_b, half_width, n=801):
    """max |y_a(x_a + s) − y_b(x_b + s)| over s ∈ [−half_width, half_width]: how far two edge
    profiles, each taken relative to its own edge position, are from one another (y linearly
    interpolated on n points)."""
    s = np.linspace(-half_width, half_width, n)
    ya = np.interp(x_a + s, xi_a, y_a)
    yb = np.interp(x_b + s, xi_b, y_b)
    return float(np.max(np.abs(ya - yb)))


# --------------------------------------------------------------------------- drivers
def analyse_pulse(pulse, params, tau_m=None, edge_window=None):
    """Scalar measures of one pulse.

    Parameters
    ----------
    pulse : h5io.Pulse
    params : Parameters
    tau_m : float, optional
        Reference stress for Ḡ and ζ, Pa; default: this pulse's own minimum of τ.
    edge_window : (float, float), optional
        Passed to :func:`edge_singularity`.

    Returns
    -------
    dict
        label, tau_d_ratio, beta, c_p (m/s), L (FWHM, m), L_tilde, xi_left, xi_right (m),
        L_solver (the solver's stored L, m), v_max (m/s), xi_vmax (m), tau_max (Pa), xi_taumax (m),
        tau_m_pulse (min τ, Pa), tau_m_used (Pa), total_slip (m), delta_ahead (m, slip accumulated
        ahead of the stress peak), G_bar_max (J/m²), max_residual, converged, and the edge fit
        zeta, zeta_err, xi_p (NaN when the fit is impossible, with ``zeta_note`` saying why).
    """
    p = pulse
    L, xl, xr = pulse_length(p.xi, p.v, params.v_star)
    tau_m_pulse = float(np.min(p.tau))
    tm = tau_m_pulse if tau_m is None else float(tau_m)
    delta, G = breakdown_energy(p.xi, p.v, p.tau, p.v_stick, p.beta, params.c_s, tm)
    iv, it = int(np.argmax(p.v)), int(np.argmax(p.tau))
    row = {
        "label": p.label, "tau_d_ratio": float(p.tau_d_ratio), "beta": float(p.beta),
        "c_p": float(p.beta * params.c_s), "L": float(L), "L_tilde": float(L / params.L_Gc),
        "xi_left": float(xl), "xi_right": float(xr), "L_solver": float(p.L),
        "v_max": float(p.v[iv]), "xi_vmax": float(p.xi[iv]),
        "tau_max": float(p.tau[it]), "xi_taumax": float(p.xi[it]),
        "tau_m_pulse": tau_m_pulse, "tau_m_used": tm,
        "total_slip": float(delta[0]), "delta_ahead": float(delta[it]),
        "G_bar_max": float(np.max(G)),
        "max_residual": float(p.max_residual), "converged": bool(p.converged),
    }
    try:
        es = edge_singularity(p.xi, p.v, p.tau, tm, params.c_s, params.sigma,
                              window=edge_window, L=L)
        row.update(zeta=es["zeta"], zeta_err=es["zeta_err"], xi_p=es["xi_p"],
                   zeta_at_bound=es["at_bound"], zeta_note="")
    except (ValueError, np.linalg.LinAlgError) as exc:
        row.update(zeta=float("nan"), zeta_err=float("nan"), xi_p=float("nan"),
                   zeta_at_bound=False, zeta_note=str(exc))
    return row


#: Per-pulse attributes written by :func:`analyse_family` (name → units).
PULSE_ATTRS = {
    "L_fwhm": "m", "tau_max": "Pa", "tau_m_pulse": "Pa", "total_slip": "m", "delta_ahead": "m",
    "G_bar_max": "J/m^2", "zeta": "1", "zeta_err": "1", "xi_p": "m",
}
#: Arrays of the ``family`` group (name → units).
FAMILY_ARRAYS = {
    "tau_d_ratio": "1", "beta": "1", "c_p": "m/s", "L": "m", "L_tilde": "1", "v_max": "m/s",
    "tau_max": "Pa", "tau_m_pulse": "Pa", "total_slip": "m", "G_bar_max": "J/m^2",
    "zeta": "1", "zeta_err": "1", "max_residual": "1",
}


FAMILY_LONG_NAMES = {
    "beta": "beta = c_p/c_s", "c_p": "pulse speed", "L": "pulse length (FWHM of ln(v/v*+1))",
    "L_tilde": "dimensionless pulse length tau_min^2 L/(mu G_c*)", "v_max": "peak slip rate",
    "tau_max": "peak shear stress", "tau_m_pulse": "minimum shear stress",
    "total_slip": "slip across the pulse", "G_bar_max": "breakdown energy at the tail",
    "zeta": "edge singularity exponent", "zeta_err": "uncertainty of zeta",
    "max_residual": "max |residual|",
}


def _atomic_update(path, fill):
    upd = h5io.atomic_update
    upd(path, fill)


#: The family results that need pulses near τ_*: (name in the family dict, the error key, what).
#: The scaling fit and G_c are read off the pulses down to τ_d/τ_min = SUPPORT_DEPTH (the
#: paper's family ends there; its Fig. 4 curves and Eq. 3-4 constants come from them). A family
#: that stops above it, or holds fewer than SUPPORT_MIN pulses in the window, gets the reason
#: instead of the number (issue 19: a 1.2 -> 1.02 family printed G_c = 0.0047 for the paper's 0.6).
SUPPORT_DEPTH = 1.015
SUPPORT_MIN = {"scaling": 5, "fracture": 3}


def support(ratios, window, what, need_min) -> str | None:
    """Why the converged pulses at ``ratios`` cannot support the family result ``what`` fitted
    over ``window`` (None: they can)."""
    inside = [r for r in ratios if window[0] <= r <= window[1]]
    if len(inside) < need_min:
        return (f"not supported by this family: {what} needs >= {need_min} converged pulses with "
                f"tau_d/tau_min in [{window[0]}, {window[1]}], it has {len(inside)}")
    if min(inside) > SUPPORT_DEPTH + 1e-9:
        return (f"not supported by this family: {what} needs pulses down to tau_d/tau_min = "
                f"{SUPPORT_DEPTH} (near tau_*), its deepest is {min(inside):.4f} "
                f"(slippulse steady family --to {SUPPORT_DEPTH})")
    return None


def analyse_family(path, write=True, scaling_window=SCALING_WINDOW, gc_window=GC_WINDOW,
                   skip=(), gc_tol=GC_TOL, cd_over_cs=None):
    """Analyse every pulse of a family file (but the labels ``skip``); optionally store the
    results in it. The scaling fit and G_c are left out, with the reason, where the family cannot
    support them (:func:`support`).

    Parameters
    ----------
    path : str
        Family HDF5 file (``pulses/tdX.XXXX`` groups).
    write : bool
        Add per-pulse attributes (:data:`PULSE_ATTRS`) and a ``family`` group, atomically (copy to
        a temporary file in the same directory, modify, ``os.replace``).
    scaling_window, gc_window : (float, float)
        τ_d/τ_min windows of the scaling fit and of the G_c/δ_c analysis.
    gc_tol : float
        Fan-out tolerance of :func:`fracture_energy`.
    cd_over_cs : sequence of float, optional
        c_d/c_s values of the mode-II mapping (default ``modeii.CD_OVER_CS``).

    Returns
    -------
    list of dict
        One row per pulse (:func:`analyse_pulse`), by decreasing τ_d. The family-level results
        are attached to the first row under ``"family"`` (dict: tau_m, scaling, fracture, mode_ii).

    Notes
    -----
    τ_m (used for Ḡ and ζ of every pulse) is min τ(ξ) of the pulse with the smallest τ_d: the
    paper's "minimum of τ(ξ) for τ_d close to τ_*", the value the minima converge to (Fig. 2b).
    (Pulses far from τ_min can dip slightly lower, by ~1e-4 τ_min; their Ḡ then has tiny
    negative increments there.)
    Failures of a family-level fit are recorded as the attribute ``*_error`` instead of raising;
    the family fits (scaling law, G_c) use the pulses with ``converged`` True only.
    """
    from . import modeii

    if cd_over_cs is None:
        cd_over_cs = modeii.CD_OVER_CS
    labels = [lab for lab in h5io.list_pulses(path) if lab not in set(skip)]
    if not labels:
        raise h5io.SchemaError(f"{path}: no pulses")
    pulses = []
    params = None
    for lab in labels:
        p, prm = h5io.read_pulse(path, lab)
        params = prm
        pulses.append(p)
    tau_m = float(np.min(pulses[-1].tau))        # smallest τ_d (list is by decreasing τ_d)
    rows = []
    for p in pulses:
        try:
            rows.append(analyse_pulse(p, params, tau_m=tau_m))
        except ValueError as exc:
            raise h5io.SchemaError(f"{path}: pulse {p.label} cannot be analysed: {exc}") from None
    fam = {"tau_m": tau_m}
    x = np.array([r["tau_d_ratio"] for r in rows])
    beta = np.array([r["beta"] for r in rows])
    Lt = np.array([r["L_tilde"] for r in rows])
    conv = np.array([r["converged"] for r in rows], dtype=bool)   # fits use converged pulses only
    try:
        fam["scaling"] = scaling_fit(x[conv], beta[conv], Lt[conv], params, window=scaling_window)
    except ValueError as exc:
        fam["scaling_error"] = str(exc)
    for eq in ("beta", "L"):          # single-equation diagnostics (does one τ̃* fit both?)
        try:
            fam[f"scaling_{eq}"] = scaling_fit(x[conv], beta[conv], Lt[conv], params,
                                              window=scaling_window, equations=eq)
        except ValueError:
            pass
    sel = [p for p in pulses
           if p.converged and gc_window[0] <= p.tau_d_ratio <= gc_window[1]]
    try:
        curves = [breakdown_energy(p.xi, p.v, p.tau, p.v_stick, p.beta, params.c_s, tau_m)
                  for p in sel]
        fam["fracture"] = fracture_energy(curves, tol=gc_tol)
    except ValueError as exc:
        fam["fracture_error"] = str(exc)
    for key, what, window in (("scaling", "the scaling fit (Eqs. 3-4)", scaling_window),
                              ("fracture", "G_c (fan-out of the G-bar curves)", gc_window)):
        why = support(x[conv], window, what, SUPPORT_MIN[key])
        if why:
            for k in ((key, "scaling_beta", "scaling_L") if key == "scaling" else (key,)):
                fam.pop(k, None)
            fam[f"{key}_error"] = why
    if skip:
        fam["skipped_unconverged"] = list(skip)
    fam["mode_ii"] = {}
    L = np.array([r["L"] for r in rows])
    for k in cd_over_cs:
        b2, L2 = modeii.map_family(beta, L, k)
        fam["mode_ii"][float(k)] = {"beta": b2, "L": L2}
    rows[0]["family"] = fam
    if write:
        _write_family(path, rows, fam, scaling_window, gc_window)
    return rows


def _write_family(path, rows, fam, scaling_window, gc_window):
    def fill(h5):
        for r in rows:
            grp = h5["pulses"][r["label"]]
            for name in PULSE_ATTRS:
                key = "L" if name == "L_fwhm" else name
                grp.attrs[name] = float(r[key])
        if "family" in h5:
            del h5["family"]
        h5io.upgrade_steady(h5)
        g = h5.create_group("family")
        # dimension tau_d_ratio (one entry per pulse, decreasing): the coordinate of every array
        dim = h5io.coordinate(g, "tau_d_ratio", np.array([r["tau_d_ratio"] for r in rows]),
                              units="1", long_name="tau_d/tau_min")
        for name, unit in FAMILY_ARRAYS.items():
            if name != "tau_d_ratio":
                h5io.describe(g.create_dataset(name, data=np.array([r[name] for r in rows],
                                                                   dtype=float)),
                              unit, FAMILY_LONG_NAMES.get(name, name), dims=(dim,))
        h5io.describe(g.create_dataset("label", data=[r["label"] for r in rows],
                                       dtype=h5py.string_dtype()),
                      "1", "pulse group name (pulses/<label>)", dims=(dim,))
        g.attrs["tau_m"] = fam["tau_m"]
        g.attrs["tau_m_units"] = "Pa"
        g.attrs["scaling_window"] = np.array(scaling_window, dtype=float)
        g.attrs["gc_window"] = np.array(gc_window, dtype=float)
        if fam.get("skipped_unconverged"):
            g.attrs["skipped_unconverged"] = ", ".join(fam["skipped_unconverged"])
        if "scaling" in fam:
            s = fam["scaling"]
            for k in ("tau_star", "a_v", "a_G", "tau_star_err", "a_v_err", "a_G_err"):
                g.attrs[k] = s[k]
            g.attrs["scaling_rms"] = s["rms"]
            g.attrs["scaling_n"] = s["n"]
            g.attrs["scaling_cov"] = s["cov"]
            for eq, k in (("beta", "a_v"), ("L", "a_G")):
                if f"scaling_{eq}" in fam:
                    d = fam[f"scaling_{eq}"]
                    for name in ("tau_star", k):
                        g.attrs[f"{eq}_only_{name}"] = d[name]
                        g.attrs[f"{eq}_only_{name}_err"] = d[name + "_err"]
        else:
            g.attrs["scaling_error"] = fam["scaling_error"]
        if "fracture" in fam:
            f = fam["fracture"]
            g.attrs["G_c"] = f["G_c"]
            g.attrs["G_c_err"] = f["G_c_err"]
            g.attrs["G_c_threshold"] = f["G_c_threshold"]
            g.attrs["G_c_units"] = "J/m^2"
            g.attrs["delta_c"] = f["delta_c"]
            g.attrs["delta_c_units"] = "m"
            g.attrs["G_c_tol"] = f["tol"]
            g.attrs["G_c_n_curves"] = f["n_curves"]
        else:
            g.attrs["fracture_error"] = fam["fracture_error"]
        m2 = g.create_group("mode_ii")
        for k, d in fam["mode_ii"].items():
            sub = m2.create_group(f"cd_over_cs_{k:.4f}")
            sub.attrs["cd_over_cs"] = k
            h5io.describe(sub.create_dataset("beta", data=d["beta"]), "1",
                          "beta = c_p/c_s of the mode-II pulse", dims=(dim,))
            h5io.describe(sub.create_dataset("L", data=d["L"]), "m",
                          "pulse length of the mode-II pulse", dims=(dim,))

    _atomic_update(path, fill)


def format_table(rows):
    """Plain-text table of the per-pulse results (and the family fits if attached)."""
    cols = [("label", "{:>9s}"), ("beta", "{:9.5f}"), ("c_p", "{:10.2f}"), ("L", "{:10.4g}"),
            ("L_tilde", "{:9.4g}"), ("v_max", "{:10.3e}"), ("tau_max", "{:10.4e}"),
            ("tau_m_pulse", "{:11.5e}"), ("total_slip", "{:10.3e}"), ("G_bar_max", "{:9.3g}"),
            ("zeta", "{:7.3f}"), ("zeta_err", "{:8.3f}"), ("max_residual", "{:9.1e}")]
    heads = {"c_p": "c_p[m/s]", "L": "L[m]", "v_max": "v_max[m/s]", "tau_max": "tau_max[Pa]",
             "tau_m_pulse": "min_tau[Pa]", "total_slip": "slip[m]", "G_bar_max": "Gmax[J/m2]",
             "max_residual": "max|res|"}
    widths = [len(fmt.format("x" if "s}" in fmt else 0.0)) for _, fmt in cols]
    lines = [" ".join(f"{heads.get(c, c):>{w}s}" for (c, _), w in zip(cols, widths))]
    for r in rows:
        lines.append(" ".join(fmt.format(r[c]) for c, fmt in cols))
    fam = rows[0].get("family") if rows else None
    if fam:
        if fam.get("skipped_unconverged"):
            lines.append("left out (marked converged=False): "
                         + ", ".join(fam["skipped_unconverged"]))
        lines.append(f"tau_m = {fam['tau_m']:.6e} Pa (min tau of the smallest tau_d)")
        if "scaling" in fam:
            s = fam["scaling"]
            lines.append(
                f"scaling fit on tau_d/tau_min in [{s['window'][0]}, {s['window'][1]}] ({s['n']} pulses): "
                f"tau*~ = {s['tau_star']:.5f} ± {s['tau_star_err']:.1g}, a_v = {s['a_v']:.4f} ± "
                f"{s['a_v_err']:.1g}, a_G = {s['a_G']:.4f} ± {s['a_G_err']:.1g} "
                f"(paper: 1.0087, 1.15, 0.69)")
            for eq, k in (("beta", "a_v"), ("L", "a_G")):
                d = fam.get(f"scaling_{eq}")
                if d:
                    lines.append(f"  Eq. {3 if eq == 'beta' else 4} alone: tau*~ = {d['tau_star']:.5f} ± "
                                 f"{d['tau_star_err']:.1g}, {k} = {d[k]:.4f} ± {d[k + '_err']:.1g}")
        else:
            lines.append(f"scaling fit: not done ({fam['scaling_error']})")
        if "fracture" in fam:
            f = fam["fracture"]
            lines.append(f"G_c = {f['G_c']:.4g} ± {f['G_c_err']:.2g} J/m^2 (paper ~0.6; bare threshold "
                         f"{f['G_c_threshold']:.4g}), delta_c = {f['delta_c']:.4g} m "
                         f"({f['n_curves']} curves, tol {f['tol']})")
        else:
            lines.append(f"G_c: not done ({fam['fracture_error']})")
    return "\n".join(lines)


def check_cd_over_cs(values):
    """c_d/c_s values of the mode-II mapping from the command line (None: the default set),
    each a finite number > 1; else ParameterError naming ``cd-cs``."""
    import math
    from ..core.params import ParameterError

    if values is None:
        return None
    for v in values:
        if not (math.isfinite(v) and v > 1.0):
            raise ParameterError(f"cd-cs={v!r} is invalid: c_d/c_s must be a finite number > 1 "
                                 "(sqrt(3) for a Poisson solid)")
    return tuple(float(v) for v in values)


def cmd_analyse(args):
    """CLI action for ``slippulse steady analyse FILE [--no-write]`` (argparse namespace with
    ``file`` and optional ``no_write``): analyse, store the results in FILE, print the table."""
    import os

    if not os.path.isfile(args.file):
        raise h5io.SchemaError(f"FILE={args.file!r} does not exist")
    cd = check_cd_over_cs(getattr(args, "cd_cs", None))
    skip = h5io.require_converged(args.file, allow=getattr(args, "skip_unconverged", False),
                                  hint="--skip-unconverged leaves them out")
    write = not getattr(args, "no_write", False)
    if write:
        h5io.check_writable(args.file, "FILE")
    rows = analyse_family(args.file, write=write, skip=skip, cd_over_cs=cd)
    print(format_table(rows))
    return 0
