"""What the paper measures on one steady pulse (Pomyalov et al., PRE 2023): per-pulse quantities.

The length L (FWHM of ln(v/v*+1)), the slip profile δ(ξ), the breakdown energy Ḡ(δ) (paper Eq. 5),
the edge-singularity order ζ (joint fit of v behind and τ − τ_m ahead of the leading edge),
ln(1 − g) along the pulse, the structure of the edges and the distance between two profiles.

Conventions (see docs/steady.md §4): ξ ascending, the pulse travels toward +ξ, so the rest state ahead
is at large ξ and the healing tail at small ξ. Every integral is a trapezoid sum on the solver's
non-uniform grid; every interpolation is local and stated in the function's Notes.
"""
from __future__ import annotations

import math

import numpy as np
from scipy.optimize import brentq, minimize_scalar

from ..core.friction import RateStateFriction


# --------------------------------------------------------------------------- helpers
def as_arrays(*arrays):
    """The arrays as float 1-D arrays of one length (ValueError otherwise): the shared input check
    of the measures and the fits."""
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
def pulse_length(xi, v, v_star, crossings=True):
    """Pulse length L: the full width at half maximum of y(ξ) = ln(v/v* + 1). The one definition
    of L: the solvers, the analysis and the dynamic runs all call it.

    Parameters
    ----------
    xi : array_like
        Co-moving coordinate ξ, m, strictly ascending (non-uniform allowed).
    v : array_like
        Slip rate v(ξ), m/s.
    v_star : float
        Regularisation velocity v*, m/s.
    crossings : bool
        True (default): return (L, ξ_L, ξ_R), and raise ValueError where y does not fall below
        half its maximum on both sides. False: return L alone, NaN where it does not exist (what
        the solvers store).

    Returns
    -------
    L : float
        ξ_R − ξ_L, m.
    xi_left, xi_right : float
        The two half-maximum crossings, m (only with ``crossings``).

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
    if not crossings:
        try:
            return float(pulse_length(xi, v, v_star)[0])
        except ValueError:
            return float("nan")
    xi, v = as_arrays(xi, v)
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
    xi, v = as_arrays(xi, v)
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
    xi, v, tau = as_arrays(xi, v, tau)
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
    v, phi = as_arrays(v, phi)
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
    xi, v, tau = as_arrays(xi, v, tau)
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
    xi, v, tau = as_arrays(xi, v, tau)
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
