"""The growth rates of record along a family, on log axes, with their power-law fits
(``slippulse steady rates``; docs/results.md §2)."""
from __future__ import annotations

import numpy as np

from ..core.atomic import save_figure


def _loglog(a, xv, yv, ev, m, fit, var, color, label, xlabel, ylabel):
    """One log–log panel: the points m of (xv, yv ± ev), bars clipped above 0, and the fit."""
    a.errorbar(xv[m], yv[m], yerr=np.minimum(ev[m], 0.999 * yv[m]), fmt="o", ms=4, color=color,
               ecolor=color, capsize=2, label=label)
    if fit is not None:
        xx = np.geomspace(fit.x_range[0], fit.x_range[1], 100)
        a.plot(xx, fit(xx), "-", color="C3",
               label=f"fit: ∝ {var}^({fit.n:.2f} ± {fit.n_err:.2f})")
    a.set_xscale("log")
    a.set_yscale("log")
    a.set_xlabel(xlabel)
    a.set_ylabel(ylabel)
    a.grid(True, which="both", alpha=0.3)
    a.legend(fontsize=8, loc="best")


def plot_rates(rates, fits, out, tau_star, dpi=130, fold=None):
    """Three panels: s L/c_p against τ_d/τ_min − τ̃* and against L (log–log, error bars, fits),
    and s L/c_p against τ_d/τ_min (linear, the sign). `rates`: :func:`spectrum.law.family_rates`;
    `fits`: dict name → PowerLaw (keys 'shift', 'one', 'L', 'R') or None. ``tau_star`` None
    (too few rates to fit it): panel (a) is against τ_d/τ_min − 1 with the fit 'one'. ``fold`` = (R, R_err) of
    :func:`spectrum.law.fold_ratio` adds a fourth panel: R against L (docs/results.md §2)."""
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    x = rates["tau_d_ratio"]
    y, e = rates["s_per_L"], rates["s_err_per_L"]
    pos = y > 0
    panels = 3 if fold is None else 4
    fig, ax = plt.subplots(1, panels, figsize=(4.7 * panels, 4.3))
    first = ((x - tau_star, "shift", f"τ_d/τ_min − τ̃*  (τ̃* = {tau_star:.5f})")
             if tau_star is not None else
             (x - 1.0, "one", "τ_d/τ_min − 1  (no τ̃*: too few rates to fit it)"))
    for a, xv, name, xl in ((ax[0],) + first,
                            (ax[1], rates["L"], "L", "pulse length L (m)")):
        _loglog(a, xv, y, e, pos & (xv > 0), fits.get(name), "x", "C0",
                "s L/c_p ± s_err (spectrum)", xl, "growth per pulse length  s L/c_p")
    ax[0].set_title("(a) growth rate against the distance to τ̃*" if tau_star is not None
                    else "(a) growth rate against τ_d/τ_min − 1")
    ax[1].set_title("(b) against the pulse length")
    a = ax[2]
    a.axhline(0.0, color="0.4", lw=1)
    a.errorbar(x - 1.0, y, yerr=e, fmt="o", ms=4, color="C0", capsize=2)
    bad = rates["sign_resolved"] == 0
    if np.any(bad):
        a.errorbar(x[bad] - 1.0, y[bad], yerr=e[bad], fmt="x", ms=6, color="C1", capsize=2,
                   label="sign not resolved")
        a.legend(fontsize=8)
    if tau_star is not None:
        a.axvline(tau_star - 1.0, color="C3", ls="--", lw=1, label="τ̃*")
    a.set_xscale("log")
    a.set_yscale("symlog", linthresh=1e-4)
    a.set_xlabel("τ_d/τ_min − 1")
    a.set_ylabel("s L/c_p  (symmetric log, linear below 1e-4)")
    a.set_title("(c) the sign along the family (s > 0: unstable)")
    a.grid(True, which="both", alpha=0.3)
    if fold is not None:
        R, Re = (np.asarray(v, float) for v in fold)
        _loglog(ax[3], rates["L"], R, Re, np.isfinite(R) & (R > 0), fits.get("R"), "L", "C2",
                "R ± err", "pulse length L (m)", "R = s L/c_p / |dτ_d/d ln L|  (τ_d in τ_min)")
        ax[3].set_title("(d) growth rate per unit slope of the family")
    fig.tight_layout()
    save_figure(fig, out, dpi=dpi)
    plt.close(fig)
    return out


def plot_fold_ratio(fr, fit, from_length, out, dpi=130):
    """R = s L/c_p / |dτ_d/d ln L| and |dτ_d/d ln L| against L
    (:func:`slippulse.spectrum.records.records_fold_ratio`), with the power law ``fit`` of R."""
    from matplotlib.figure import Figure

    L, R, Re, g, ge = fr["L"], fr["R"], fr["R_err"], fr["slope"], fr["slope_err"]
    fig = Figure(figsize=(11, 4.3))
    ax = fig.subplots(1, 2)
    ok = np.isfinite(R) & (R > 0)
    for mk, lab in (("family", "slope from a march's pulses"),
                    ("records", "slope from the records' own pulses")):
        w = ok & (fr["source"] == mk)
        if np.any(w):
            ax[0].errorbar(L[w], R[w], yerr=np.minimum(Re[w], 0.999 * R[w]),
                           fmt="o" if mk == "family" else "s", ms=4, capsize=2, label=lab)
            ax[1].errorbar(L[w], np.abs(g[w]), yerr=np.minimum(ge[w], 0.999 * np.abs(g[w])),
                           fmt="o" if mk == "family" else "s", ms=4, capsize=2, label=lab)
    xx = np.geomspace(*fit.x_range, 100)
    ax[0].plot(xx, fit(xx), "-", color="C3",
               label=f"R ∝ L^({fit.n:.3f} ± {fit.n_err:.3f}), L ≥ {from_length:g} m")
    ax[1].plot(L[ok], fr["s"][ok], "^", ms=4, color="0.4", label="s L/c_p (rates of record)")
    ax[0].set_ylabel("R = s L/c_p / |dτ_d/d ln L|  (τ_d in τ_min)")
    ax[0].set_title("(a) growth rate per unit slope of the family")
    ax[1].set_ylabel("|dτ_d/d ln L|  (τ_min), and s L/c_p")
    ax[1].set_title("(b) the slope of the family → 0 as L → ∞")
    for x in ax:
        x.set_xscale("log")
        x.set_yscale("log")
        x.set_xlabel("pulse length L (m)")
        x.grid(True, which="both", alpha=0.3)
        x.legend(fontsize=8)
    fig.tight_layout()
    save_figure(fig, out, dpi=dpi)
