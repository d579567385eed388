"""Figures of the divergence of a deep family (:mod:`slippulse.steady.divergence`): L and 1 − β
against τ_d/τ_min − τ̃* with the fits, and the local exponents against L."""
from __future__ import annotations

import numpy as np
from matplotlib.figure import Figure

from ..core.atomic import save_figure
from ..steady import divergence as dv
from ..steady.fits import scaling_law
from .steady import PAPER_SCALING


def _n_text(ns):
    ns = sorted({int(n) for n in ns})
    if not ns:
        return "?"
    return f"{ns[0]}" if ns[0] == ns[-1] else f"{ns[0]}–{ns[-1]}"


def plot_divergence(pts, fit, params, path, label):
    """L and 1 − β against d = τ_d/τ_min − τ̃* (τ̃* of ``fit``, a joint :func:`divergence_fit`
    named ``label``), the fitted power laws and the paper's Eqs. 3–4."""
    q, b, L = pts.q, pts.beta, pts.L
    ts = fit["tau_star"]
    fig = Figure(figsize=(9, 4))
    ax1, ax2 = fig.add_subplot(1, 2, 1), fig.add_subplot(1, 2, 2)
    arc = pts.arclength
    for sel, mk, lab in ((~arc, "o", f"family (τ_d- and β-steps), N = {_n_text(pts.n_points[~arc])}"),
                         (arc, "s", f"arclength march (deformed grid), N = "
                                    f"{_n_text(pts.n_points[arc])}")):
        s_ = sel & (q - ts > 0) & (q < 1.05)
        ax1.loglog(q[s_] - ts, L[s_], mk, ms=3, mfc="none", label=lab)
        ax2.loglog(q[s_] - ts, 1 - b[s_], mk, ms=3, mfc="none", label=lab)
    dd = np.geomspace(0.5 * (q.min() - ts), 0.04, 100)
    ax1.loglog(dd, np.exp(fit["ln_A"]) * dd ** (-fit["m_L"]), "k-",
               label=f"fit {label}: m_L = {fit['m_L']:.2f}, τ̃* = {ts:.5f}")
    ax2.loglog(dd, np.exp(fit["ln_B"]) * dd ** fit["m_beta"], "k-",
               label=f"fit: m_β = {fit['m_beta']:.2f}")
    xx = PAPER_SCALING["tau_star"] + np.geomspace(1e-5, 0.04, 200)
    bp, Lp = scaling_law(xx, PAPER_SCALING["tau_star"], PAPER_SCALING["a_v"],
                         PAPER_SCALING["a_G"], params)
    ok = xx - ts > 0
    ax1.loglog(xx[ok] - ts, Lp[ok] * params.L_Gc, "r--",
               label=f"paper Eqs. 3–4 (τ̃* = {PAPER_SCALING['tau_star']})")
    ax2.loglog(xx[ok] - ts, 1 - bp[ok], "r--", label="paper Eqs. 3–4")
    ax1.set_xlabel("τ_d/τ_min − τ̃*"), ax1.set_ylabel("L (m)")
    ax2.set_xlabel("τ_d/τ_min − τ̃*"), ax2.set_ylabel("1 − β")
    ax1.legend(fontsize=7), ax2.legend(fontsize=7)
    fig.suptitle(f"L and 1 − β against τ_d/τ_min − τ̃*, τ̃* = {ts:.5f} from the joint fit "
                 f"({label})", fontsize=9)
    fig.tight_layout()
    save_figure(fig, path, dpi=130)


def plot_local_exponents(pts, loc, tau_star, path, L_from=30.0):
    """The local exponents of :func:`~slippulse.steady.divergence.local_exponents` (with
    ``tau_star``) against L ≥ ``L_from``, and d ln L/d ln d with the paper's τ̃*."""
    fig = Figure(figsize=(9, 3.6))
    ax1, ax2 = fig.add_subplot(1, 2, 1), fig.add_subplot(1, 2, 2)
    ok = loc["L"] >= L_from
    ax1.semilogx(loc["L"][ok], loc["r"][ok], "o", ms=3, mfc="none", label="d ln L/d ln(1 − β)")
    ax1.semilogx(loc["L"][ok], 1.0 / loc["r"][ok], "s", ms=3, mfc="none",
                 label="d ln(1 − β)/d ln L")
    ax1.axhline(0.5, color="C0", ls="--", lw=1,
                label="paper's asymptote of d ln L/d ln(1 − β): 1/2")
    ax1.axhline(2.0, color="C1", ls="--", lw=1, label="and of d ln(1 − β)/d ln L: 2")
    ax1.set_xlabel("L (m)"), ax1.set_ylabel("local exponent"), ax1.legend(fontsize=7)
    ax2.semilogx(loc["L"][ok], loc["m"][ok], "o", ms=3, mfc="none",
                 label=f"τ̃* = {tau_star:.5f} (joint fit, deepest decade)")
    mp = dv.local_exponents(pts, PAPER_SCALING["tau_star"])["m"]
    ax2.semilogx(loc["L"][ok], mp[ok], "^", ms=3, mfc="none", color="r",
                 label=f"τ̃* = {PAPER_SCALING['tau_star']} (paper)")
    ax2.axhline(1.0, color="r", ls="--", lw=1, label="paper's asymptote m_L = 1")
    ax2.set_xlabel("L (m)"), ax2.set_ylabel("d ln L/d ln(τ_d/τ_min − τ̃*)")
    ax2.legend(fontsize=7)
    fig.suptitle(f"Local exponents along the family (deepest pulse L = {pts.L.max():.4g} m at "
                 f"τ_d/τ_min = {pts.q.min():.6f})", fontsize=9)
    fig.tight_layout()
    save_figure(fig, path, dpi=130)


def plot_edges(rows, params, path):
    """Edge measures of :func:`~slippulse.steady.edges.edge_study` against L: widths, peaks, Ḡ."""
    fig = Figure(figsize=(11, 3.4))
    axs = [fig.add_subplot(1, 3, k) for k in (1, 2, 3)]
    Ls = np.array([e["L"] for _, e in rows])
    gs = np.array([np.sqrt(1 - p.beta ** 2) for p, _ in rows])
    axs[0].loglog(Ls, 1e3 * np.array([e["ell"] for _, e in rows]) / gs, "o-",
                  label="ℓ/√(1−β²) (mm)")
    axs[0].loglog(Ls, 1e3 * np.array([e["front_efold"] for _, e in rows]) / gs, "s-",
                  label="front e-fold/√(1−β²) (mm)")
    axs[0].loglog(Ls, [e["back_efold"] for _, e in rows], "v-", label="back e-fold (m)")
    axs[0].loglog(Ls, [e["heal_width"] for _, e in rows], "^-", label="healing width (m)")
    axs[0].legend(fontsize=7), axs[0].set_xlabel("L (m)")
    axs[1].semilogx(Ls, [e["tau_max"] / params.tau_min for _, e in rows], "o-",
                    label="τ_max/τ_min")
    axs[1].semilogx(Ls, [e["tau_back_min"] / params.tau_min for _, e in rows], "s-",
                    label="τ_back,min/τ_min")
    axs[1].semilogx(Ls, [e["v_max"] * g for (_, e), g in zip(rows, gs)], "^-",
                    label="v_max√(1−β²) (m/s)")
    axs[1].legend(fontsize=7), axs[1].set_xlabel("L (m)")
    for k, lab in enumerate(("Ḡ(2 µm)", "Ḡ(5 µm)", "Ḡ(20 µm)")):
        axs[2].semilogx(Ls, [e["G"][k] for _, e in rows], "o-", label=lab)
    axs[2].semilogx(Ls, [e["G_max"] for _, e in rows], "k^-", label="Ḡ_max")
    axs[2].set_yscale("log"), axs[2].legend(fontsize=7), axs[2].set_xlabel("L (m)")
    axs[2].set_ylabel("J/m²")
    fig.tight_layout()
    save_figure(fig, path, dpi=130)


def plot_edge_profiles(rows, path):
    """The leading edges (Lorentz-contracted) and healing fronts of the pulses of ``rows``,
    each relative to its own edge, overlaid."""
    fig = Figure(figsize=(10, 3.6))
    ax1, ax2 = fig.add_subplot(1, 2, 1), fig.add_subplot(1, 2, 2)
    for p, e in rows[::max(1, len(rows) // 8)] + [rows[-1]]:
        g = np.sqrt(1 - p.beta ** 2)
        s1 = np.abs(p.xi - e["x_front"]) < 0.1 * g
        ax1.plot(1e3 * (p.xi[s1] - e["x_front"]) / g, np.log10(p.v[s1] * g), "-",
                 label=f"L = {p.L:.3g} m")
        s2 = np.abs(p.xi - e["x_back"]) < 10.0
        ax2.plot(p.xi[s2] - e["x_back"], np.log10(p.v[s2]), "-", label=f"L = {p.L:.3g} m")
    ax1.set_xlabel("(ξ − ξ_front)/√(1−β²) (mm)"), ax1.set_ylabel("log10(v√(1−β²)) (m/s)")
    ax1.set_title("leading edge", fontsize=9)
    ax2.set_xlabel("ξ − ξ_back (m)"), ax2.set_ylabel("log10 v (m/s)")
    ax2.set_title("healing front", fontsize=9)
    ax1.legend(fontsize=6), ax2.legend(fontsize=6)
    fig.tight_layout()
    save_figure(fig, path, dpi=130)
