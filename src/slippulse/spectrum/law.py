"""Power laws of the leading growth rate along a family (docs/results.md §2).

Near τ_min the growth rates of record (``s ± s_err`` of each pulse's spectrum group) are fitted
by y = A x^n against x = τ_d/τ_min − 1, τ_d/τ_min − τ̃* or L, for y = s L/c_p or s, by weighted
least squares in log space (ln y = ln A + n ln x, standard deviation of ln y = s_err/s). The
parameter errors are those of the covariance, scaled by the Birge ratio √χ²_red where that is
above 1 (a law that does not fit within the error bars widens its own uncertainty). Local
exponents d ln y/d ln x between neighbouring pulses show whether one law holds over the range.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np


@dataclass
class PowerLaw:
    """y = A x^n fitted on m points; errors 1σ (Birge-scaled), χ²_red of the weighted fit."""

    n: float
    n_err: float
    A: float
    A_err: float
    chi2_red: float
    m: int
    x_range: tuple

    def __call__(self, x):
        return self.A * np.asarray(x, float) ** self.n

    def describe(self, xname="x", yname="y") -> str:
        return (f"{yname} = ({self.A:.3g} ± {self.A_err:.1g}) {xname}^({self.n:.3f} ± "
                f"{self.n_err:.3f}) on {self.m} pulses, {xname} in [{self.x_range[0]:.3g}, "
                f"{self.x_range[1]:.3g}], chi2_red = {self.chi2_red:.2g}")


def fit_power_law(x, y, y_err):
    """Weighted fit of y = A x^n (x, y > 0; y_err > 0 the 1σ error of y). Returns PowerLaw.

    Raises ValueError with fewer than 3 usable points (x > 0, y > 0, finite, y_err > 0)."""
    x, y, e = (np.asarray(a, float) for a in (x, y, y_err))
    ok = np.isfinite(x) & np.isfinite(y) & np.isfinite(e) & (x > 0) & (y > 0) & (e > 0)
    x, y, e = x[ok], y[ok], e[ok]
    if x.size < 3:
        raise ValueError(f"a power-law fit needs at least 3 points with x > 0, y > 0 and an "
                         f"error; got {x.size}")
    sl = e / y                                         # σ of ln y
    w = 1.0 / sl ** 2
    X = np.column_stack([np.ones_like(x), np.log(x)])
    Y = np.log(y)
    cov = np.linalg.inv(X.T @ (w[:, None] * X))
    p = cov @ (X.T @ (w * Y))
    r = Y - X @ p
    dof = max(x.size - 2, 1)
    chi2_red = float(np.sum(w * r ** 2) / dof)
    cov = cov * max(1.0, chi2_red)
    lnA, n = p
    A = float(np.exp(lnA))
    return PowerLaw(float(n), float(np.sqrt(cov[1, 1])), A, float(A * np.sqrt(cov[0, 0])),
                    chi2_red, int(x.size), (float(x.min()), float(x.max())))


def local_exponents(x, y):
    """d ln y / d ln x between neighbours (sorted by x): (x at the geometric midpoints, slopes)."""
    x, y = np.asarray(x, float), np.asarray(y, float)
    k = np.argsort(x)
    x, y = x[k], y[k]
    lx, ly = np.log(x), np.log(y)
    return np.exp(0.5 * (lx[1:] + lx[:-1])), np.diff(ly) / np.diff(lx)


#: Width in ln x of the windows of :func:`windowed_exponents` (a 10 % range of L per window).
EXPONENT_WINDOW = 0.1


def windowed_exponents(x, y, err, width=EXPONENT_WINDOW, min_points=3):
    """Local exponents d ln y/d ln x of dense, noisy data: the slope of a weighted straight line
    through (ln x, ln y) in consecutive, non-overlapping windows, each at least `width` wide in
    ln x and of at least `min_points` points (what is left after a window, if too little for
    another, joins it). Weights 1/(err/y)²; the slope's standard error is Birge-scaled
    (× √max(χ²_red, 1)), as in :func:`fit_power_law`. Neighbour differences
    (:func:`local_exponents`) of pulses 0.1 % apart in L with errors of 20 % of s swing by ± 5;
    a window of 10 % in L gives the trend with an error bar.

    Returns (x_mid, slope, slope_err, n): x_mid the geometric mean of each window's x."""
    x, y, err = (np.asarray(a, float) for a in (x, y, err))
    k = np.argsort(x)
    lx, ly = np.log(x[k]), np.log(y[k])
    w = (y[k] / err[k]) ** 2
    out = []
    i, n = 0, lx.size
    while n - i >= min_points:
        j = i + min_points - 1
        while j < n - 1 and lx[j] - lx[i] < width:
            j += 1
        if n - 1 - j < min_points or lx[n - 1] - lx[j + 1] < width:
            j = n - 1                             # too little left for a window: take it here
        sl = slice(i, j + 1)
        a, b, ww = lx[sl], ly[sl], w[sl]
        am = np.sum(ww * a) / np.sum(ww)
        bm = np.sum(ww * b) / np.sum(ww)
        sxx = np.sum(ww * (a - am) ** 2)
        if sxx <= 0.0:
            break
        slope = np.sum(ww * (a - am) * (b - bm)) / sxx
        dof = a.size - 2
        chi2 = np.sum(ww * (b - bm - slope * (a - am)) ** 2) / dof if dof > 0 else 1.0
        out.append((float(np.exp(np.mean(a))), float(slope),
                    float(np.sqrt(max(chi2, 1.0) / sxx)), int(a.size)))
        i = j + 1
    if not out:
        return (np.zeros(0),) * 3 + (np.zeros(0, int),)
    cols = list(zip(*out))
    return (np.array(cols[0]), np.array(cols[1]), np.array(cols[2]), np.array(cols[3]))


def _first_groups(paths, keep):
    """(label, pulse group) of one or several family files for which ``keep(group)`` holds; a
    label kept in several files: the first file's. Yields inside the open file."""
    from ..core.h5io import check_pulse_group, labels_in, open_h5
    seen = set()
    for path in ([paths] if isinstance(paths, (str, bytes)) or hasattr(paths, "__fspath__")
                 else paths):
        with open_h5(path) as h5:
            for lab in labels_in(h5, path):
                grp = h5["pulses"][lab]
                if lab not in seen and keep(grp):
                    check_pulse_group(grp, path)
                    seen.add(lab)
                    yield lab, grp


def family_rates(paths):
    """The growth rates of record of one or several family files: dict of arrays (τ_d/τ_min, L,
    c_p, s, s_err, s_per_L, s_err_per_L, sign_resolved, β) and labels, over the pulses whose
    spectrum has ``s`` stored, by decreasing τ_d (a label present in several files: the first
    file's)."""
    def rated(grp):
        g = grp.get("spectrum")
        return g is not None and "s" in g.attrs and g.attrs.get("status") == "converged"

    rows = []
    for lab, grp in _first_groups(paths, rated):
        g, a = grp["spectrum"], grp.attrs
        rows.append((float(a["tau_d_ratio"]), float(a["L"]), float(a["c_p"]),
                     float(g.attrs["s"]), float(g.attrs["s_err"]),
                     float(g.attrs["s_per_L"]), float(g.attrs["s_err_per_L"]),
                     int(g.attrs["sign_resolved"]), float(a["beta"]), lab))
    rows.sort(key=lambda r: -r[0])
    names = ("tau_d_ratio", "L", "c_p", "s", "s_err", "s_per_L", "s_err_per_L", "sign_resolved",
             "beta")
    out = {k: np.array([r[i] for r in rows]) for i, k in enumerate(names)}
    out["label"] = [r[-1] for r in rows]
    return out


@dataclass
class ShiftedLaw:
    """y = A (x − x*)^n with x* fitted too (profile of χ² over x*); x*_err from Δχ² = 1 of the
    Birge-scaled profile."""

    x_star: float
    x_star_err: float
    law: PowerLaw                    # the fit at x* (n, A and their errors at fixed x*)

    def __call__(self, x):
        return self.law(np.asarray(x, float) - self.x_star)


def fit_shifted_power_law(x, y, y_err, lo=None):
    """Fit y = A (x − x*)^n for x*, A, n (x* < min x, and ≥ lo if given).

    The profile χ²(x*) of the linear fit in logs is minimised over a fine grid of x* and refined
    by a bounded scalar minimisation; the error of x* is half the distance between the first
    points on either side where the profile exceeds its minimum by χ²_red (at least 1), located
    by Brent's method between the minimum and the first grid point beyond.
    Raises ValueError with fewer than 4 usable points."""
    x, y, e = (np.asarray(a, float) for a in (x, y, y_err))
    ok = np.isfinite(x) & np.isfinite(y) & np.isfinite(e) & (y > 0) & (e > 0)
    x, y, e = x[ok], y[ok], e[ok]
    if x.size < 4:
        raise ValueError(f"a shifted power-law fit needs at least 4 points; got {x.size}")
    xmin, span = float(x.min()), float(np.ptp(x))
    lo = xmin - 2.0 * span if lo is None else float(lo)
    # x* close to min x: a geometric grid of the gap min x − x*
    gaps = np.geomspace(1e-4 * span, xmin - lo, 400)

    def chi2(gap):
        f = fit_power_law(x - (xmin - gap), y, e)
        return f.chi2_red * max(x.size - 2, 1), f

    prof = np.array([chi2(g)[0] for g in gaps])
    k = int(np.argmin(prof))
    from scipy.optimize import minimize_scalar
    a, b = np.log(gaps[max(k - 1, 0)]), np.log(gaps[min(k + 1, gaps.size - 1)])
    opt = minimize_scalar(lambda lg: chi2(np.exp(lg))[0], bounds=(a, b), method="bounded",
                          options={"xatol": 1e-10})
    best_gap = float(np.exp(opt.x)) if opt.fun <= prof[k] else gaps[k]
    c2, law = chi2(best_gap)
    scale = max(1.0, c2 / max(x.size - 3, 1))
    target = c2 + scale
    # Δχ² = scale on each side of the minimum: bracketed by the first grid point beyond it,
    # then located by Brent's method (the profile can be narrower than the grid's spacing)
    from scipy.optimize import brentq

    def crossing(idx):
        for j in idx:
            if prof[j] > target:
                a, b = sorted((np.log(best_gap), np.log(gaps[j])))
                return float(np.exp(brentq(lambda lg: chi2(np.exp(lg))[0] - target, a, b,
                                           xtol=1e-12)))
        return float("nan")
    hi_gap = crossing(j for j in range(gaps.size) if gaps[j] > best_gap)
    lo_gap = crossing(j for j in range(gaps.size - 1, -1, -1) if gaps[j] < best_gap)
    err = 0.5 * (hi_gap - lo_gap) if np.isfinite(hi_gap) and np.isfinite(lo_gap) else float("nan")
    return ShiftedLaw(xmin - best_gap, float(err), law)


# ------------------------------------------------------------------ the family's slope
def family_curve(paths):
    """τ_d/τ_min, L and β of every converged pulse of one or several family files, in the order
    of the family (increasing β; a label present in several files: the first file's). Returns a
    dict of arrays and labels."""
    from ..core.h5io import pulse_converged
    rows = [(float(g.attrs["beta"]), float(g.attrs["L"]), float(g.attrs["tau_d_ratio"]), lab)
            for lab, g in _first_groups(paths, pulse_converged)]
    rows.sort()
    out = {k: np.array([r[i] for r in rows]) for i, k in enumerate(("beta", "L", "tau_d_ratio"))}
    out["label"] = [r[-1] for r in rows]
    return out


def _along(beta):
    """The family's parameter: u = ln(β/(1 − β)), monotone in β, resolving both β → 0 (the
    quasi-static end) and β → 1 (the deep end)."""
    b = np.asarray(beta, float)
    return np.log(b) - np.log1p(-b)


def _lagrange_slope(x, y, x0):
    """d/dx at x0 of the polynomial through (x, y) (degree len(x) − 1)."""
    c = np.polyfit(np.asarray(x, float) - x0, np.asarray(y, float), len(x) - 1)
    return float(c[-2])


def _derivative(u, y, u0):
    """dy/du at u0 from the quartic through the five points nearest in u, and its error: the
    difference from the quadratic through the three nearest (fewer points: lower degrees)."""
    order = np.argsort(np.abs(u - u0), kind="stable")
    hi_idx = np.sort(order[:min(5, u.size)])
    lo_idx = np.sort(order[:3])
    hi = _lagrange_slope(u[hi_idx], y[hi_idx], u0)
    lo = _lagrange_slope(u[lo_idx], y[lo_idx], u0)
    return hi, abs(hi - lo)


def family_slope(tau, L, beta=None, at_beta=None, at_L=None):
    """dτ_d/d ln L along a family given by its pulses (τ_d/τ_min, L, β), with an error estimate.

    The family is parametrised by u = ln(β/(1 − β)) (β is monotone along it, where L need not
    be: above 1.3 τ_min L has a minimum); dτ_d/du and d ln L/du come from the quartic through
    the five pulses nearest in u, their errors from the difference with the quadratic through the
    three nearest, and slope = (dτ_d/du)/(d ln L/du) with the relative errors added in
    quadrature. Queries: ``at_beta`` (default the pulses' own β), or ``at_L`` where ln L is
    monotone in u over the family (otherwise, and outside the family's range, nan). Returns
    (slope, err) arrays; infinite where L turns (d ln L/du = 0). Without ``beta`` (pulses known
    by τ_d and L alone, e.g. the records) the parameter is u = ln L itself, which needs L
    monotone along the family (true below 1.2 τ_min)."""
    tau, L = np.asarray(tau, float), np.asarray(L, float)
    if beta is None:
        if at_beta is not None:
            raise ValueError("at_beta needs the pulses' beta")
        k = np.argsort(L)
        u = np.log(L[k])
        at_L = L if at_L is None else at_L
    else:
        k = np.argsort(beta)
        u = _along(np.asarray(beta, float)[k])
    y, z = tau[k], np.log(L[k])
    keep = np.concatenate([[True], np.diff(u) > 0])
    u, y, z = u[keep], y[keep], z[keep]
    if beta is None:
        q = np.log(np.asarray(at_L, float))
    elif at_L is not None:
        q_L = np.log(np.asarray(at_L, float))
        dz = np.diff(z)
        if u.size >= 2 and (np.all(dz > 0) or np.all(dz < 0)):
            o = np.argsort(z)
            q = np.interp(q_L, z[o], u[o], left=np.nan, right=np.nan)
        else:
            q = np.full(q_L.size, np.nan)
    else:
        q = _along(beta if at_beta is None else at_beta)     # the input's order
    q = np.atleast_1d(q)
    slope, err = np.full(q.size, np.nan), np.full(q.size, np.nan)
    if u.size < 3:
        return slope, err
    tol = 1e-12 * max(1.0, float(np.abs(u).max()))
    for i, u0 in enumerate(q):
        if not (np.isfinite(u0) and u[0] - tol <= u0 <= u[-1] + tol):
            continue
        dt, et = _derivative(u, y, u0)
        dl, el = (1.0, 0.0) if beta is None else _derivative(u, z, u0)
        slope[i] = dt / dl if dl != 0.0 else np.inf
        err[i] = np.hypot(et, abs(slope[i]) * el) / abs(dl) if dl != 0.0 else np.inf
    return slope, err


def folds(tau, beta):
    """Where τ_d turns along the family (a fold in τ_d), the family ordered by β: for each change
    of sign of Δτ_d between neighbours, the β of the pulses on either side of the turning one.
    Empty when τ_d is monotone along the family."""
    tau, beta = np.asarray(tau, float), np.asarray(beta, float)
    k = np.argsort(beta)
    b, d = beta[k], np.diff(tau[k])
    nz = np.flatnonzero(d != 0.0)
    out = []
    for a, c in zip(nz[:-1], nz[1:]):
        if np.sign(d[a]) != np.sign(d[c]):
            out.append((float(b[a]), float(b[c + 1])))
    return out


def fold_ratio(s_per_L, s_err_per_L, slope, slope_err):
    """R = (s L/c_p)/|dτ_d/d ln L| and its 1σ error (relative errors added in quadrature).

    A real eigenvalue of the pulse operator passes through σ = 0 only at a fold of the family in
    τ_d (docs/results.md §2): near one, s L/c_p ≈ R |dτ_d/d ln L|. A bounded R along a
    family whose τ_d tends to a limit (|dτ_d/d ln L| → 0) means s L/c_p → 0 there."""
    s, e, g, ge = (np.asarray(a, float) for a in (s_per_L, s_err_per_L, slope, slope_err))
    with np.errstate(divide="ignore", invalid="ignore"):
        R = s / np.abs(g)
        return R, np.abs(R) * np.hypot(e / s, ge / g)
