"""The paper's figures (Figs. 1–4, S1–S4 of Pomyalov et al., PRE 2023) from a family file.

Headless: figures are built with ``matplotlib.figure.Figure`` (Agg canvas, no pyplot state).
Every figure function takes a :class:`FamilyData` and returns a Figure; :func:`make_all` writes
each one as PNG and PDF. Which pulses are drawn when the file does not hold the paper's exact τ_d
values: the nearest available ones (the legend gives the τ_d actually drawn).
"""
from __future__ import annotations

import os
from dataclasses import dataclass, field

import numpy as np
from matplotlib.figure import Figure

from ..core.atomic import save_figure
from ..steady import analysis as an
from ..core import h5io
from ..steady import modeii
from ..core.friction import RateStateFriction
from ..core.params import Parameters
from ..core.reference import paper_scaling

#: τ_d/τ_min of the curves of Figs. 2 and S2 (nearest available are drawn).
FIG2_TARGETS = (1.015, 1.02, 1.03, 1.05, 1.1, 1.2)
#: τ_d/τ_min of the closed orbits of Fig. 1.
FIG1_TARGETS = (1.05, 1.20)
#: Constants of the paper's scaling fit (Eqs. 3–4), drawn for comparison; read from the data file
#: ``slippulse/data/paper_scaling.toml`` (with its source).
PAPER_SCALING = paper_scaling()
_STYLES = ("-", "--", "-.", ":", (0, (5, 1, 1, 1)), (0, (1, 1)))
#: Fig. 3 zooms in below this τ_d/τ_min (the deep part of the family) when it has pulses there.
DEEP_INSET = 1.0125
FIGURES = ("fig1", "fig2", "fig3", "fig4", "figS1", "figS2", "figS3", "figS4")


@dataclass
class FamilyData:
    """Everything the figures need: pulses by decreasing τ_d, the analysis rows and family fits."""

    path: str
    params: Parameters
    pulses: list
    rows: list
    fam: dict
    compare: list = field(default_factory=list)   # pulses of a second file (Fig. S1b domain size)

    @property
    def ratios(self):
        return np.array([p.tau_d_ratio for p in self.pulses])


def load_family(path, compare_path=None, cd_over_cs=None, skip=()):
    """Read a family file and analyse it (nothing is written); ``cd_over_cs``: c_d/c_s values of
    the mode-II figure (default ``modeii.CD_OVER_CS``); the labels ``skip`` are left out."""
    rows = an.analyse_family(path, write=False, cd_over_cs=cd_over_cs, skip=skip)
    pulses, params = [], None
    for lab in h5io.list_pulses(path):
        if lab in skip:
            continue
        p, params = h5io.read_pulse(path, lab)
        pulses.append(p)
    data = FamilyData(path=path, params=params, pulses=pulses, rows=rows, fam=rows[0]["family"])
    if compare_path is not None:
        for lab in h5io.list_pulses(compare_path):
            if not h5io.stored_converged(compare_path, lab):
                continue
            p, prm = h5io.read_pulse(compare_path, lab)
            if prm != params:
                from ..core.params import describe_difference
                raise h5io.SchemaError(f"{compare_path}: parameters differ from {path}: "
                                       + describe_difference(prm, params, compare_path, path))
            data.compare.append(p)
    return data


def _pick(data, targets):
    """Indices of the pulses nearest to each target τ_d/τ_min (no duplicates, in target order)."""
    r = data.ratios
    out = []
    for t in targets:
        i = int(np.argmin(np.abs(r - t)))
        if i not in out:
            out.append(i)
    return out


def _lab(p):
    r = f"{p.tau_d_ratio:.4f}"
    r = r[:-1] if r.endswith("0") else r
    return rf"$\tau_d/\tau_{{min}}={r}$"


def _xlim_pulses(data, idx, L0, before=1.0, after=0.3):
    lo = min(data.rows[i]["xi_left"] - before * data.rows[i]["L"] for i in idx)
    hi = max(data.rows[i]["xi_right"] + after * data.rows[i]["L"] for i in idx)
    return lo / L0, hi / L0


# --------------------------------------------------------------------------- Fig. 1
def fig1(data):
    """τ_ss(v)/σ vs v/v_min with the closed (v, τ) orbits of two pulses."""
    prm = data.params
    fig = Figure(figsize=(6.4, 4.6))
    ax = fig.add_subplot()
    idx = _pick(data, FIG1_TARGETS)
    # the τ_d line and its three roots are drawn for the lower τ_d of the two orbits
    pd = data.pulses[max(idx, key=lambda i: -data.pulses[i].tau_d_ratio)]
    try:
        vss = prm.v_ss(pd.tau_d)
    except Exception:       # noqa: BLE001 - marker only
        vss = None
    vmin_plot = min(data.pulses[i].v.min() for i in idx) / 5
    vmax_plot = max([data.pulses[i].v.max() for i in idx] + [vss or 0.0]) * 5
    vv = np.geomspace(min(vmin_plot, prm.v_star * 1e-2), max(vmax_plot, 1e3 * prm.v_min), 800)
    ax.semilogx(vv / prm.v_min, prm.tau_ss(vv) / prm.sigma, "k-", lw=1.8, label=r"$\tau_{ss}(v)$")
    ax.plot([1.0], [prm.tau_min / prm.sigma], "ko", mfc="none", ms=8,
            label=r"$(v_{min},\tau_{min})$")
    styles = ("-.", "--")
    for k, i in enumerate(idx):
        p = data.pulses[i]
        ax.plot(p.v / prm.v_min, p.tau / prm.sigma, ls=styles[k % 2], color=f"C{k}", lw=1.3,
                label="orbit " + _lab(p))
    ax.axhline(pd.tau_d / prm.sigma, color="0.4", ls=(0, (6, 2, 1, 2)), lw=0.8,
               label=r"$\tau_d$ (" + _lab(pd) + ")")
    ax.plot([pd.v_stick / prm.v_min], [pd.tau_d / prm.sigma], "ks", mfc="none", ms=7,
            label=r"$v_{stick}$")
    if vss is not None:
        ax.plot([vss / prm.v_min], [pd.tau_d / prm.sigma], "k^", mfc="none", ms=7,
                label=r"$v_{ss}$")
    ax.set_xlabel(r"$v/v_{min}$  ($v_{min}$ = %.3g m/s)" % prm.v_min)
    ax.set_ylabel(r"$\tau/\sigma$  (dimensionless; $\sigma$ = %.3g MPa)" % (prm.sigma / 1e6))
    top = max(prm.tau_peak, max(data.pulses[i].tau.max() for i in idx)) / prm.sigma
    ax.set_ylim(0.8 * prm.tau_min / prm.sigma, 1.05 * top)
    ax.set_title("Fig. 1: steady friction curve and closed pulse orbits")
    ax.legend(fontsize=8, loc="upper left")
    return fig


# --------------------------------------------------------------------------- Fig. 2
def fig2(data):
    """(a) ln(v/v_stick+1) vs ξ/L0 (inset v/v_min, linear); (b) τ/τ_min vs ξ/L0."""
    prm = data.params
    L0 = prm.L0
    idx = _pick(data, FIG2_TARGETS)
    fig = Figure(figsize=(6.4, 8.0))
    ax1, ax2 = fig.subplots(2, 1)
    ins = ax1.inset_axes([0.06, 0.45, 0.36, 0.5])
    for k, i in enumerate(idx):
        p = data.pulses[i]
        ls = _STYLES[k % len(_STYLES)]
        ax1.plot(p.xi / L0, np.log(p.v / p.v_stick + 1), ls=ls, color=f"C{k}", label=_lab(p))
        ins.plot(p.xi / L0, p.v / prm.v_min, ls=ls, color=f"C{k}", lw=1)
        ax2.plot(p.xi / L0, p.tau / prm.tau_min, ls=ls, color=f"C{k}", label=_lab(p))
    xl = _xlim_pulses(data, idx, L0)
    for ax in (ax1, ax2, ins):
        ax.set_xlim(*xl)
    # inset: linear v/v_min, truncated as in the paper (the edge peak is off scale)
    body = max(np.percentile(data.pulses[i].v[data.pulses[i].v > 2 * data.pulses[i].v_stick]
                             / prm.v_min, 90) if np.any(data.pulses[i].v > 2 * data.pulses[i].v_stick)
               else 1.0 for i in idx)
    ins.set_ylim(0, 3 * body)
    ins.set_xlabel(r"$\xi/L_0$", fontsize=7)
    ins.set_ylabel(r"$v/v_{min}$", fontsize=7)
    ins.tick_params(labelsize=7)
    ax1.set_xlabel(r"$\xi/L_0$  ($L_0$ = %.3g m)" % L0)
    ax1.set_ylabel(r"$\ln(v/v_{stick}+1)$")
    ax1.set_title("Fig. 2(a): slip rate (pulses travel to the right)")
    ax1.legend(fontsize=7, loc="upper right")
    tm = data.fam["tau_m"]
    ax2.axhline(tm / prm.tau_min, color="0.3", ls=":", lw=1, label=r"$\tau_m$ (min $\tau$ at the smallest $\tau_d$)")
    if "scaling" in data.fam:
        ax2.axhline(data.fam["scaling"]["tau_star"], color="0.3", ls="-.", lw=1,
                    label=r"$\tilde\tau_*$ (fit)")
    taus = np.concatenate([data.pulses[i].tau for i in idx]) / prm.tau_min
    hi = min(float(taus.max()), 1.25 * max(p.tau_d_ratio for p in (data.pulses[i] for i in idx)))
    ax2.set_ylim(0.98 * min(float(taus.min()), tm / prm.tau_min), hi * 1.02)
    ax2.set_xlabel(r"$\xi/L_0$  ($L_0$ = %.3g m)" % L0)
    ax2.set_ylabel(r"$\tau/\tau_{min}$  ($\tau_{min}$ = %.4g MPa)" % (prm.tau_min / 1e6))
    ax2.set_title("Fig. 2(b): shear stress (peak truncated)")
    ax2.legend(fontsize=7, loc="best")
    fig.tight_layout()
    return fig


# --------------------------------------------------------------------------- Fig. 3
def fig3(data):
    """β (left) and L̃ (right, log) vs τ_d/τ_min, with the fitted scaling law (Eqs. 3–4)."""
    prm = data.params
    x = np.array([r["tau_d_ratio"] for r in data.rows])
    b = np.array([r["beta"] for r in data.rows])
    Lt = np.array([r["L_tilde"] for r in data.rows])
    fig = Figure(figsize=(6.4, 4.6))
    ax = fig.add_subplot()
    ax2 = ax.twinx()
    h1, = ax.plot(x, b, "o", color="C0", ms=5, label=r"$\beta$ (pulses)")
    h2, = ax2.semilogy(x, Lt, "s", color="C3", ms=5, mfc="none", label=r"$\tilde L$ (pulses)")
    handles = [h1, h2]
    if "scaling" in data.fam:
        s = data.fam["scaling"]
        xx = np.linspace(max(s["tau_star"] + 1e-4, x.min() - 0.002), x.max(), 400)
        bb, LL = an.scaling_law(xx, s["tau_star"], s["a_v"], s["a_G"], prm)
        h3, = ax.plot(xx, bb, "-", color="C0", lw=1.2,
                      label=(r"$\beta$, Eq. 3 fit: $\tilde\tau_*$=%.4f, $a_v$=%.2f (on shaded %g–%g)"
                             % (s["tau_star"], s["a_v"], s["window"][0], s["window"][1])))
        h3b, = ax2.semilogy(xx, LL, "-", color="C3", lw=1.2,
                            label=r"$\tilde L$, Eq. 4 fit: $a_G$=%.2f" % s["a_G"])
        handles += [h3, h3b]
        ax.axvspan(max(s["window"][0], xx[0]), min(s["window"][1], x.max()), color="0.92",
                   zorder=0)
    # the paper's constants, for a side-by-side comparison
    xp = np.linspace(max(PAPER_SCALING["tau_star"] + 1e-4, x.min() - 0.002), x.max(), 400)
    bp, Lp = an.scaling_law(xp, params=prm, **PAPER_SCALING)
    # one legend entry per curve: β (left axis) and L̃ (right axis) in their axes' colours
    h4, = ax.plot(xp, bp, ":", color="C0", lw=1.4,
                  label=(r"$\beta$, paper's constants: $\tilde\tau_*$=%.4f, $a_v$=%.2f"
                         % (PAPER_SCALING["tau_star"], PAPER_SCALING["a_v"])))
    h5, = ax2.semilogy(xp, Lp, ":", color="C3", lw=1.4,
                       label=r"$\tilde L$, paper's constants: $a_G$=%.2f" % PAPER_SCALING["a_G"])
    handles += [h4, h5]
    ax.set_xlabel(r"$\tau_d/\tau_{min}$")
    ax.set_ylabel(r"$\beta = c_p/c_s$", color="C0")
    ax2.set_ylabel(r"$\tilde L = \tau_{min}^2 L/(\mu G_c^*)$  ($G_c^*$ = 0.65 J/m$^2$)", color="C3")
    ax.set_ylim(0, 1)
    ax.set_title("Fig. 3: propagation speed and pulse length")
    ax.legend(handles=handles, fontsize=7, loc="upper right")
    deep = x < DEEP_INSET
    if deep.sum() >= 2:
        # the deep family (down to L ≥ 1.5 km) crowds at the left edge: zoomed in
        ins = ax.inset_axes([0.43, 0.40, 0.30, 0.30])
        near = x < DEEP_INSET + 0.004
        ins.semilogy(x[near], Lt[near], "s", color="C3", ms=3, mfc="none")
        ins.set_xlabel(r"$\tau_d/\tau_{min}$", fontsize=6, labelpad=1)
        ins.set_ylabel(r"$\tilde L$", fontsize=6, labelpad=1, color="C3")
        ins.tick_params(labelsize=5)
        ins.set_title(f"deep part: L up to {Lt[near].max() * prm.L_Gc:.0f} m", fontsize=6, pad=2)
    fig.tight_layout()
    return fig


# --------------------------------------------------------------------------- Fig. 4 and S3
def _gc_curves(data):
    lo, hi = an.GC_WINDOW
    idx = [i for i, p in enumerate(data.pulses) if lo <= p.tau_d_ratio <= hi]
    if len(idx) < 2:
        idx = list(range(len(data.pulses)))
    if len(idx) > 6:
        idx = [idx[int(round(k))] for k in np.linspace(0, len(idx) - 1, 6)]
    tm = data.fam["tau_m"]
    out = []
    for i in idx:
        p = data.pulses[i]
        d, G = an.breakdown_energy(p.xi, p.v, p.tau, p.v_stick, p.beta, data.params.c_s, tm)
        out.append((p, d, G))
    return out


def fig4(data):
    """Ḡ(δ) with the G_c line; inset: edge-singularity fit at the smallest τ_d."""
    prm = data.params
    fig = Figure(figsize=(6.4, 6.0))
    ax = fig.add_subplot()
    curves = _gc_curves(data)
    gmax = 0.0
    for k, (p, d, G) in enumerate(curves):
        ax.plot(d * 1e3, G, ls=_STYLES[k % len(_STYLES)], color=f"C{k}", label=_lab(p))
        gmax = max(gmax, float(np.nanmax(G)))
    fr = data.fam.get("fracture")
    if fr:
        ax.axhline(fr["G_c"], color="k", ls="-.", lw=1, label=r"$G_c$ = %.3g J/m$^2$" % fr["G_c"])
    ax.set_xlabel(r"$\delta$ (mm)")
    ax.set_ylabel(r"$\bar G(\delta)$ (J/m$^2$)")
    ax.set_xlim(0, None)
    ax.set_ylim(0, 1.9 * gmax)         # the curves fill the lower half, the inset the upper
    ax.set_title("Fig. 4: breakdown energy")
    ax.legend(fontsize=7, loc="lower right")
    # inset: the edge fit for the smallest τ_d
    p = data.pulses[-1]
    ins = ax.inset_axes([0.40, 0.62, 0.57, 0.30])
    tm = data.fam["tau_m"]
    try:
        es = an.edge_singularity(p.xi, p.v, p.tau, tm, prm.c_s, prm.sigma, L=data.rows[-1]["L"])
    except ValueError as exc:
        ins.text(0.5, 0.5, "edge fit failed:\n" + str(exc)[:60], ha="center", va="center",
                 fontsize=6, transform=ins.transAxes)
        ins.set_xticks([])
        ins.set_yticks([])
        return fig
    xp, z = es["xi_p"], es["zeta"]
    r_lo, r_hi = es["window"]
    behind = (p.xi < xp) & (xp - p.xi < 30 * r_hi)
    ahead = (p.xi > xp) & (p.xi - xp < 30 * r_hi) & (p.tau > tm)
    scale = es["a_tau"] / es["a_v"]          # brings v/c_s onto the stress curve (as the paper)
    ins.loglog((xp - p.xi[behind]) / prm.L0, scale * p.v[behind] / prm.c_s, "C0-", lw=1,
               label=r"$v/c_s$ (scaled), behind")
    ins.loglog((p.xi[ahead] - xp) / prm.L0, (p.tau[ahead] - tm) / prm.sigma, "C3-", lw=1,
               label=r"$(\tau-\tau_m)/\sigma$, ahead")
    ins.axvspan(r_lo / prm.L0, r_hi / prm.L0, color="0.9", zorder=0)
    rr = np.geomspace(r_lo, r_hi, 20)
    ins.loglog(rr / prm.L0, es["a_tau"] * rr ** z, "k--", lw=1.2,
               label=r"$\zeta$ = %.3f ± %.3f (shaded: window)" % (z, es["zeta_err"]))
    ins.set_xlabel(r"$|\xi-\xi_p|/L_0$", fontsize=7)
    ins.set_title(_lab(p), fontsize=7)
    ins.tick_params(labelsize=6)
    ins.legend(fontsize=5.5, loc="lower left")
    return fig


def figS3(data):
    """Ḡ(δ) log-log with the ∝δ line, the G_c and δ_c lines."""
    fig = Figure(figsize=(6.4, 4.6))
    ax = fig.add_subplot()
    curves = _gc_curves(data)
    for k, (p, d, G) in enumerate(curves):
        ok = (d > 0) & (G > 0)
        ax.loglog(d[ok], G[ok], ls=_STYLES[k % len(_STYLES)], color=f"C{k}", label=_lab(p))
    fr = data.fam.get("fracture")
    if fr:
        ax.axhline(fr["G_c"], color="k", ls="-.", lw=1, label=r"$G_c$ = %.3g J/m$^2$" % fr["G_c"])
        ax.axvline(fr["delta_c"], color="k", ls="-.", lw=1,
                   label=r"$\delta_c$ = %.3g µm" % (fr["delta_c"] * 1e6))
        # ∝δ guide through the median curve at δ_c/10, drawn up to δ_c
        lo = max(fr["delta_grid"][0], 1e-5 * fr["delta_c"])
        d_a = max(fr["delta_c"] / 10, lo)
        k_a = np.interp(np.log(d_a), np.log(fr["delta_grid"]), fr["G_median"]) / d_a
        dd = np.geomspace(lo, fr["delta_c"], 50)
        ax.loglog(dd, 2 * k_a * dd, "k--", lw=1, label=r"$\propto\delta$ (guide, ×2)")
        ax.set_xlim(lo, None)
        ax.set_ylim(0.3 * k_a * lo, None)
    ax.set_xlabel(r"$\delta$ (m)")
    ax.set_ylabel(r"$\bar G(\delta)$ (J/m$^2$)")
    ax.set_title("Fig. S3: breakdown energy, double-logarithmic")
    ax.legend(fontsize=7, loc="lower right")
    fig.tight_layout()
    return fig


# --------------------------------------------------------------------------- Fig. S1
def figS1(data):
    """(a) residual Δ(ξ) for two pulses; (b) the v/v_min – φ v_min/D plane (two domain sizes)."""
    prm = data.params
    fig = Figure(figsize=(6.4, 8.0))
    ax1, ax2 = fig.subplots(2, 1)
    idx = [len(data.pulses) - 1, 0] if len(data.pulses) > 1 else [0]
    for k, i in enumerate(idx):
        p = data.pulses[i]
        L = data.rows[i]["L"]
        ax1.plot(p.xi / L, p.residual, color=f"C{k}", lw=0.8,
                 label=_lab(p) + r", max$|\Delta|$=%.1e" % p.max_residual)
    ax1.set_xscale("symlog", linthresh=1.0)
    ax1.set_xlabel(r"$\xi/L$  (each pulse's own $L$; whole domain, symlog beyond $|\xi|=L$)")
    ax1.set_ylabel(r"$\Delta(\xi)$ (dimensionless)")
    ax1.ticklabel_format(axis="y", style="sci", scilimits=(0, 0))
    ax1.set_title("Fig. S1(a): residual of the steady equation")
    ax1.legend(fontsize=7)
    i = _pick(data, (1.05,))[0]
    p = data.pulses[i]
    sets = [(p, "this file")]
    if data.compare:
        c = min(data.compare, key=lambda q: abs(q.tau_d_ratio - p.tau_d_ratio))
        if abs(c.tau_d_ratio - p.tau_d_ratio) < 1e-6:
            sets.append((c, "comparison file"))
    for k, (q, src) in enumerate(sets):
        span = (q.xi[-1] - q.xi[0]) / prm.L0
        ax2.loglog(q.v / prm.v_min, q.phi * prm.v_min / prm.D, ls=("-", "--")[k], color=f"C{k}",
                   label=f"{src}: domain {span:.3g} $L_0$, N={q.xi.size}")
        ax2.plot([q.v[0] / prm.v_min], [q.phi[0] * prm.v_min / prm.D], "o", color=f"C{k}",
                 mfc="none", ms=8)
    ax2.plot([p.v_stick / prm.v_min], [RateStateFriction(prm).phi_ss(p.v_stick) * prm.v_min / prm.D],
             "ks", mfc="none", ms=8, label=r"rest state $(v_{stick}, \phi_{ss}(v_{stick}))$")
    ax2.set_xlabel(r"$v/v_{min}$")
    ax2.set_ylabel(r"$\phi\, v_{min}/D$")
    title = "Fig. S1(b): " + _lab(p) + " in the $v$–$\\phi$ plane"
    if len(sets) == 1:
        title += "\n(file holds one domain size only; circle: end of the tail)"
    ax2.set_title(title, fontsize=9)
    ax2.legend(fontsize=7, loc="lower left")
    fig.tight_layout()
    return fig


# --------------------------------------------------------------------------- Fig. S2
def figS2(data):
    """ln(1 − g) vs ξ/L0."""
    prm = data.params
    idx = _pick(data, FIG2_TARGETS)
    fig = Figure(figsize=(6.4, 4.6))
    ax = fig.add_subplot()
    for k, i in enumerate(idx):
        p = data.pulses[i]
        ax.plot(p.xi / prm.L0, an.ln_one_minus_g(p.v, p.phi, prm), ls=_STYLES[k % len(_STYLES)],
                color=f"C{k}", label=_lab(p))
    ax.axhline(0, color="0.5", lw=0.6)
    ax.set_xlim(*_xlim_pulses(data, idx, prm.L0))
    ax.set_xlabel(r"$\xi/L_0$  ($L_0$ = %.3g m)" % prm.L0)
    ax.set_ylabel(r"$\ln(1-g[v,\phi])$")
    ax.set_title(r"Fig. S2: distance of $\phi$ from steady state with $v$")
    ax.legend(fontsize=7)
    fig.tight_layout()
    return fig


# --------------------------------------------------------------------------- Fig. S4
def figS4(data):
    """Mode-II β and L̃ for the chosen c_d/c_s, with mode III."""
    x = np.array([r["tau_d_ratio"] for r in data.rows])
    b3 = np.array([r["beta"] for r in data.rows])
    L3 = np.array([r["L_tilde"] for r in data.rows])
    fig = Figure(figsize=(6.4, 8.0))
    ax1, ax2 = fig.subplots(2, 1)
    ax1.plot(x, b3, "ko-", ms=4, label=r"$\beta_{III}$")
    ax2.semilogy(x, L3, "ko-", ms=4, label=r"mode III")
    for k, (kap, d) in enumerate(sorted(data.fam["mode_ii"].items())):
        bR = modeii.rayleigh_speed(kap)
        ax1.plot(x, d["beta"], "s--", color=f"C{k}", ms=3.5, mfc="none",
                 label=r"$\beta_{II}$, $c_d/c_s$=%.3f ($c_R/c_s$=%.3f)" % (kap, bR))
        ax1.axhline(bR, color=f"C{k}", ls=":", lw=0.8)
        ax2.semilogy(x, d["L"] / data.params.L_Gc, "s--", color=f"C{k}", ms=3.5, mfc="none",
                     label=r"mode II, $c_d/c_s$=%.3f" % kap)
    ax1.set_xlabel(r"$\tau_d/\tau_{min}$")
    ax1.set_ylabel(r"$\beta = c_p/c_s$")
    ax1.set_ylim(0, 1)
    ax1.set_title("Fig. S4(a): mode II vs mode III propagation speed (dotted: $c_R/c_s$)")
    ax1.legend(fontsize=7)
    ax2.set_xlabel(r"$\tau_d/\tau_{min}$")
    ax2.set_ylabel(r"$\tilde L = \tau_{min}^2 L/(\mu G_c^*)$")
    ax2.set_title("Fig. S4(b): pulse length")
    ax2.legend(fontsize=7)
    fig.tight_layout()
    return fig


_FUNCS = {"fig1": fig1, "fig2": fig2, "fig3": fig3, "fig4": fig4, "figS1": figS1,
          "figS2": figS2, "figS3": figS3, "figS4": figS4}


def make_all(path, outdir, formats=("png", "pdf"), compare_path=None, dpi=150):
    """Write every figure of the paper for the family in `path` to `outdir`; return the paths."""
    return save_all(load_family(path, compare_path=compare_path), outdir, formats, dpi)


def save_all(data, outdir, formats=("png", "pdf"), dpi=150):
    """Write every figure for an already loaded :class:`FamilyData`; return the paths."""
    os.makedirs(outdir, exist_ok=True)
    written = []
    from .metadata import params_metadata
    for name in FIGURES:
        fig = _FUNCS[name](data)
        for ext in formats:
            out = os.path.join(outdir, f"{name}.{ext}")
            save_figure(fig, out, dpi=dpi, metadata=params_metadata(data.params, out))
            written.append(out)
    return written


def matplotlib_cmap(name):
    """A colormap by name (without pyplot)."""
    import matplotlib
    return matplotlib.colormaps[name]
