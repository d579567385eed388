"""Fits across a family of steady pulses (Pomyalov et al., PRE 2023): the effective fracture energy
G_c and cohesive slip δ_c (Figs. 4, S3), the scaling law of Eqs. 3–4 (τ̃*, a_v, a_G), and the
divergence laws of L and β near τ_min (docs/analysis.md).
"""
from __future__ import annotations

import math

import numpy as np
from scipy.optimize import least_squares

from .measures import _as_arrays

#: τ_d/τ_min window of the scaling fit (Eqs. 3–4): "near τ_*", both ends inclusive.
SCALING_WINDOW = (1.0, 1.05)
#: Pulses whose Ḡ(δ) curves enter the G_c / δ_c analysis (Fig. 4: τ_d close to τ_*), inclusive.
GC_WINDOW = (1.0, 1.05)
#: Relative spread of the Ḡ curves that counts as "fanned out".
GC_TOL = 0.02


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
