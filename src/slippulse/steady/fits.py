"""Fits across a family of steady pulses (Pomyalov et al., PRE 2023): the effective fracture energy
G_c and cohesive slip δ_c (Figs. 4, S3), the scaling law of Eqs. 3–4 (τ̃*, a_v, a_G), and the
divergence laws of L and β near τ_min (docs/steady.md §4).
"""
from __future__ import annotations

import math

import numpy as np
from scipy.optimize import least_squares

from .measures import as_arrays

#: τ_d/τ_min window of the scaling fit (Eqs. 3–4): "near τ_*", both ends inclusive.
SCALING_WINDOW = (1.0, 1.05)
#: Pulses whose Ḡ(δ) curves enter the G_c / δ_c analysis (Fig. 4: τ_d close to τ_*), inclusive.
GC_WINDOW = (1.0, 1.05)
#: Local log-slope d ln Ḡ_med/d ln δ that marks the bend of the median Ḡ(δ) curve (δ_c, G_c), and
#: the two slopes whose bend points bound its uncertainty (docs/steady.md §4).
GC_SLOPE = 0.5
GC_SLOPE_BAND = (0.7, 0.3)
#: The ∝δ head: the slope must first reach this before a bend is looked for.
GC_HEAD_SLOPE = 0.8
#: Half-width in ln δ of the centred difference that gives the slope.
GC_SLOPE_STEP = 0.02
#: The head is looked for below this fraction of the largest Ḡ_med of the shared δ range.
GC_HEAD_FRACTION = 0.1


# --------------------------------------------------------------------------- family quantities

def _slope_crossing(lg, slope, level, start):
    """ln δ where ``slope`` first falls below ``level`` at or after index ``start`` (linear in
    ln δ between the two grid points around the crossing); None if it never does."""
    below = np.nonzero(slope[start:] < level)[0]
    if below.size == 0:
        return None
    j = start + int(below[0])
    if j == 0 or j == start:
        return float(lg[j])
    t = (slope[j - 1] - level) / (slope[j - 1] - slope[j])
    return float(lg[j - 1] + t * (lg[j] - lg[j - 1]))


def _clean_curves(family):
    """Each (δ, Ḡ) curve with its finite points at δ > 0, sorted and strictly increasing in δ
    (at least two curves)."""
    curves = []
    for delta, G in family:
        delta, G = as_arrays(delta, G)
        ok = np.isfinite(delta) & np.isfinite(G) & (delta > 0)
        d, g = delta[ok], G[ok]
        order = np.argsort(d)
        d, g = d[order], g[order]
        keep = np.concatenate([[True], np.diff(d) > 0])
        curves.append((d[keep], g[keep]))
    if len(curves) < 2:
        raise ValueError("need at least two Ḡ(δ) curves for a family G_c")
    return curves


def _median_curve(curves, n_grid):
    """(the log-spaced δ grid over the range all curves share, the median Ḡ on it), each curve
    interpolated linearly in Ḡ against ln δ."""
    lo = max(c[0][0] for c in curves)
    hi = min(c[0][-1] for c in curves)
    if not hi > lo:
        raise ValueError("the Ḡ(δ) curves share no range of δ")
    grid = np.geomspace(lo, hi, n_grid)
    lg = np.log(grid)
    Gs = np.array([np.interp(lg, np.log(d), g) for d, g in curves])
    return grid, np.median(Gs, axis=0)


def _log_slope(lg, Gmed):
    """p = d ln Ḡ_med/d ln δ by centred differences over ±GC_SLOPE_STEP in ln δ (nan within
    that step of the ends), not over one cell of the grid: the curves are interpolated between
    their pulses' nodes, and a one-cell slope would turn an interpolation error of 1e-5 in Ḡ into
    1e-2 in p."""
    with np.errstate(divide="ignore", invalid="ignore"):
        lnG = np.log(np.where(Gmed > 0, Gmed, np.nan))
    h = GC_SLOPE_STEP
    inside = (lg - h >= lg[0]) & (lg + h <= lg[-1])
    p = np.full(lg.size, np.nan)
    p[inside] = (np.interp(lg[inside] + h, lg, lnG) - np.interp(lg[inside] - h, lg, lnG)) / (2 * h)
    return p


def fracture_energy(family, n_grid=20000, slope=GC_SLOPE, band=GC_SLOPE_BAND,
                    head=GC_HEAD_SLOPE):
    """Effective fracture energy G_c and cohesive slip δ_c from a set of Ḡ(δ) curves (Figs. 4, S3).

    Parameters
    ----------
    family : sequence of (delta, G_bar)
        One pair of arrays per pulse (any order along δ), δ in m, Ḡ in J/m².
    n_grid : int
        Points of the common log-spaced δ grid.
    slope : float
        The local slope p = d ln Ḡ_med/d ln δ that marks the bend (default 1/2, halfway between
        the ∝δ head, p = 1, and a flat tail, p = 0).
    band : (float, float)
        Two slopes, before and after ``slope``, whose bend points bound G_c (its uncertainty).
    head : float
        The slope the median curve must first reach (its ∝δ head) before a bend is looked for.

    Returns
    -------
    dict
        G_c (J/m²), G_c_err (J/m², half the range of Ḡ_med between the bend points of the two
        slopes of ``band``), G_c_lo and G_c_hi (Ḡ_med at them), delta_c (m), slope, band,
        n_curves, and the common grid ``delta_grid``, the median curve ``G_median`` and its local
        slope ``slope_median``.

    Notes
    -----
    The paper's definition (SM, "The fracture energy G_c"): Ḡ ∝ δ below δ_c, and G_c = Ḡ(δ_c);
    Fig. 4 reads G_c where the curves, which overlap at small δ, bend and fan out. Rule (stated,
    reproducible):

    1. Each curve is interpolated (linear in Ḡ vs ln δ) on a common grid of ``n_grid`` log-spaced δ
       covering the range shared by all curves (δ > 0); Ḡ_med is the median curve.
    2. p(δ) = d ln Ḡ_med/d ln δ, by centred differences over ±0.02 in ln δ
       (``GC_SLOPE_STEP``).
    3. The head: the last point where p ≥ ``head`` before Ḡ_med first reaches 0.1 of its largest
       value (``GC_HEAD_FRACTION``; below, the creeping start, at Ḡ ≈ 1e-6 J/m², bumps and dips
       in slope). From there, δ_c is the first δ where p falls below ``slope``;
       G_c = Ḡ_med(δ_c).
    4. The same for the two slopes of ``band``: G_c_err is half the range of Ḡ_med between them.

    For linear slip weakening from τ_0 to τ_c over δ_w, then constant stress (any level ≥ τ_m),
    Ḡ = k δ − K δ²/(2 δ_w) with k = τ_0 − τ_m, K = τ_0 − τ_c, so p = (k − K x)/(k − K x/2),
    x = δ/δ_w, and the bend at slope p lies at x = k (1 − p)/(K (1 − p/2)) while x < 1 (at δ_w,
    where p drops to ≈ 0, otherwise): the tests check this. The relative spread of the curves is
    not used: on the computed families the curves differ by 5–15 % from their creeping start on
    (different peak stresses and v_stick), and a rule that measured the fan-out by the spread's
    excess over its minimum (used before 2026-11-24) found that minimum at nanometre slips and
    returned G_c ≈ 0.002 J/m² where the curves bend at ≈ 0.6 J/m².
    """
    curves = _clean_curves(family)
    grid, Gmed = _median_curve(curves, n_grid)
    lg = np.log(grid)
    hi = grid[-1]
    p = _log_slope(lg, Gmed)
    # the head: the last point of slope >= head before Ḡ_med reaches GC_HEAD_FRACTION of its
    # largest value (the creeping start, at Ḡ ~ 1e-6 of G_c, dips and bumps in slope)
    i_ref = int(np.argmax(Gmed >= GC_HEAD_FRACTION * np.nanmax(Gmed)))
    in_head = np.nonzero(p[:i_ref + 1] >= head)[0]
    if in_head.size == 0:
        raise ValueError(f"the median Ḡ(δ) curve has no head of slope >= {head} (Ḡ ∝ δ) "
                         f"below {GC_HEAD_FRACTION:g} of its largest value")
    i_head = int(in_head[-1])

    def level_at(s_):
        x = _slope_crossing(lg, p, s_, i_head)
        if x is None:
            raise ValueError(f"the median Ḡ(δ) curve does not bend to slope {s_} within the "
                             f"shared δ range (up to {hi:.3g} m)")
        return x, float(np.interp(x, lg, Gmed))

    x_c, G_c = level_at(slope)
    G_band = [level_at(s_)[1] for s_ in band]
    return {"G_c": G_c, "G_c_err": 0.5 * abs(G_band[1] - G_band[0]),
            "G_c_lo": min(G_band), "G_c_hi": max(G_band), "delta_c": math.exp(x_c),
            "slope": slope, "band": tuple(band), "n_curves": len(curves),
            "delta_grid": grid, "G_median": Gmed, "slope_median": p}


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
    x, b, Lt = as_arrays(tau_d_ratio, beta, L_tilde)
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

    The paper's theory (Eqs. 3–4) has, as β → 1, √(1−β²) = β d/(a_v C) ≈ √(2(1−β)), i.e.
    m_β = 2, and L̃ = a_G √(1−β²)/(π d²) ≈ a_G/(π a_v C d), i.e. m_L = 1 (docs/steady.md §4,
    "The divergence law on the deep family"). Residuals in logarithms (the data span
    decades), equal weights; ``scipy.optimize.least_squares`` with τ̃* bounded below min τ_d/τ_min;
    covariance s² (JᵀJ)⁻¹, s² = RSS/(m − k). The statistical error ignores the correlated
    discretisation error of the pulses; the fit-window study and the N-comparison carry that.
    """
    if quantities not in ("both", "L", "beta"):
        raise ValueError(f"quantities={quantities!r}: must be 'both', 'L' or 'beta'")
    x, b, Lm = as_arrays(tau_d_ratio, beta, L)
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
    q, b, Lm = as_arrays(tau_d_ratio, beta, L)
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
