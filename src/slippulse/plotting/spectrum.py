"""Figures of the stability spectrum: s(τ_d) over a family, the spectrum, the leading modes."""
from __future__ import annotations

import numpy as np

from ..core.atomic import save_figure
from ..spectrum.report import family_spectra  # noqa: F401  (the figures' input; moved to spectrum)


def front_position(xi, lnv0):
    """Leading edge: the first point ahead of the maximum where ln(v/v*+1) falls to half."""
    k = int(np.argmax(lnv0))
    half = 0.5 * lnv0[k]
    ahead = np.nonzero((np.arange(xi.size) > k) & (lnv0 < half))[0]
    return float(xi[ahead[0]]) if ahead.size else float(xi[k])


def front_frame_mode(xi, y0, y1, L):
    """A mode as a front-following observer (the SBI, docs/stability.md §1) sees it: the deviation
    of y = ln(v/v*+1) at fixed distance from the front. The mode at fixed ξ carries a displacement Δ
    of the steep front, y₁ ≈ −Δ y₀′ there; in the front's frame the deviation is y₁ + Δ y₀′, with Δ
    the least-squares displacement over |ξ − ξ_f| < 0.05 L. Returns (η = ξ − ξ_f, deviation)."""
    xf = front_position(xi, y0)
    dy0 = np.gradient(y0, xi)
    w = np.abs(xi - xf) < 0.05 * L
    d = -np.dot(y1[w], dy0[w]) / np.dot(dy0[w], dy0[w])
    return xi - xf, y1 + d * dy0


def plot_family_spectrum(path, out, mode_labels=None):
    """Four panels: s L/c_p and σ (1/s) against τ_d/τ_min (with the translation eigenvalue, the
    discretisation's error indicator), the eigenvalues in the complex plane, the leading modes."""
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    from ..core.h5io import read_pulse
    sp = family_spectra(path)
    if not sp:
        raise ValueError(f"{path}: no stored converged spectrum (run 'slippulse steady stability')")
    q = np.array([o["tau_d_ratio"] for o in sp])
    lead = np.array([o["sigma"][0] if o["sigma"].size else np.nan for o in sp])
    unit = np.array([o["rate_unit_c_over_L"] for o in sp])
    st = np.array([abs(o["translation_sigma"]) for o in sp])
    fig, ax = plt.subplots(2, 2, figsize=(11, 8))
    a = ax[0, 0]
    s_l = np.array([o.get("s_per_L", np.nan) for o in sp], float)
    e_l = np.array([o.get("s_err_per_L", np.nan) for o in sp], float)
    ok = np.isfinite(s_l) & (np.abs(s_l) >= 2 * e_l)
    a.plot(q - 1, lead.real / unit, "-", lw=0.8, color="C0", alpha=0.5,
           label="leading eigenvalue on the pulse's grid")
    if ok.any():
        a.errorbar(q[ok] - 1, s_l[ok], yerr=e_l[ok], fmt="o", ms=3, color="C0", capsize=2,
                   label=r"$s\,L/c_p \pm$ s_err (nested refinement)")
    unres = np.isfinite(s_l) & ~ok
    if unres.any():
        a.plot(q[unres] - 1, np.abs(s_l[unres]) + e_l[unres], "v", ms=5, color="C3",
               mfc="none", label="sign not resolved: |s| + s_err (upper bound)")
    a.plot(q - 1, st / unit, "x", ms=4, color="0.5",
           label="|translation eigenvalue| (exact 0: error indicator)")
    a.set_xscale("log")
    a.set_yscale("log")
    a.set_xlabel(r"$\tau_d/\tau_{min} - 1$")
    a.set_ylabel(r"$s\,L/c_p$ (e-folds per pulse length)")
    a.legend(fontsize=8)
    a.grid(alpha=0.3, which="both")
    a = ax[0, 1]
    a.plot(q, lead.real, "o-", ms=3)
    a.set_xlabel(r"$\tau_d/\tau_{min}$")
    a.set_ylabel(r"$s$ (1/s)")
    a.grid(alpha=0.3)
    a = ax[1, 0]
    picks = mode_labels or [sp[i]["label"] for i in
                            np.unique(np.linspace(0, len(sp) - 1, 5).round().astype(int))]
    for o in sp:
        if o["label"] in picks and o["sigma"].size:
            s = o["sigma"] / o["rate_unit_c_over_L"]
            a.plot(s.real, s.imag, "o", ms=5, label=o["label"])
    a.axvline(0, color="k", lw=0.8)
    top = max(1.0, float(np.nanmax(np.abs(lead.real / unit))))
    a.set_ylim(-0.3 * top, 0.3 * top)
    a.set_xlabel(r"Re $\sigma L/c_p$")
    a.set_ylabel(r"Im $\sigma L/c_p$")
    a.set_title("eigenvalues found (Re σ > 0); the imaginary axis is a continuum", fontsize=9)
    a.legend(fontsize=8)
    a.grid(alpha=0.3)
    a = ax[1, 1]
    for o in sp:
        if o["label"] in picks and o["sigma"].size:
            pulse, params = read_pulse(path, o["label"])
            y0 = np.log(pulse.v / params.v_star + 1.0)
            y1 = np.interp(pulse.xi, o["xi"], o["lnv"][0].real)   # modes may sit on a refinement
            eta, e = front_frame_mode(pulse.xi, y0, y1, pulse.L)
            x = eta / pulse.L
            sel = (x > -1.6) & (x < 0.6)
            body = sel & (np.abs(x) > 0.02)
            e = e / e[body][np.argmax(np.abs(e[body]))]
            a.plot(x[sel], np.clip(e[sel], -0.3, 1.3), lw=1.2, label=o["label"])
    a.set_xlabel(r"$(\xi - \xi_{front})/L$")
    a.set_ylabel(r"leading mode in the front frame: $\delta\ln(v/v_*+1)$")
    a.grid(alpha=0.3)
    a.legend(fontsize=8)
    fig.suptitle(f"Linear stability spectrum of the steady pulses ({path})", fontsize=10)
    fig.tight_layout()
    save_figure(fig, out, dpi=120)
    plt.close(fig)
    return out


def spectrum_growth_figure(rows, refined, out, fits=(), sbi=(), scans=(), dpi=120) -> str:
    """s L/c_p against τ_d/τ_min (left) and against τ_d/τ_min − 1 on log axes (right): the
    leading eigenvalue on the family's grids and |translation eigenvalue| (exact 0: the error
    indicator) (:func:`slippulse.spectrum.report.spectrum_rows`), the refined values ± s_err
    (``refined_rows``), the first power law of ``fits`` (``near_min_fits``), and the SBI's
    measured rates: ``sbi`` of a rates file (circles) and ``scans`` of finished scan pairs
    (diamonds) (:mod:`slippulse.timedomain.sbi_rates`). Rates ≤ 0 cannot sit on the log axis:
    the right panel counts them. Returns ``out``."""
    from matplotlib.figure import Figure
    fig = Figure(figsize=(11, 4.3))
    axes = fig.subplots(1, 2)
    q = np.array([r["tau_d_ratio"] for r in rows])
    s = np.array([r["s_per_L"] for r in rows])
    st = np.abs(np.array([r["translation_s_per_L"] for r in rows]))
    domains = sorted({r["domain"] for r in sbi})
    for a, logy in zip(axes, (False, True)):
        def xf(t):
            return np.asarray(t, float) - 1.0 if logy else np.asarray(t, float)
        a.plot(xf(q), s, ".-", color="C0", lw=1.5, ms=4, label="eigenvalue on the family grids")
        a.plot(xf(q), st, ":", color="0.5", lw=1,
               label="|translation eigenvalue| (exact 0: error indicator)")
        if refined:
            a.errorbar(xf([r["tau_d_ratio"] for r in refined]), [r["s_per_L"] for r in refined],
                       yerr=[r["s_err_per_L"] for r in refined], fmt="s", color="C0", ms=5,
                       capsize=3, label="eigenvalue ± s_err (slippulse steady stability)")
        for kind, pts, style, colour in (("rates file", sbi, "o", "C3"),
                                         ("scans", scans, "D", "C2")):
            shown = [r for r in pts if not (logy and r["s"] <= 0)]
            if shown:
                a.errorbar(xf([r["tau_d_ratio"] for r in shown]), [r["s"] for r in shown],
                           yerr=[r["err"] for r in shown], fmt=style, color=colour, ms=5,
                           capsize=2, mfc="none", ls="none",
                           label=f"SBI ±ε pairs ({kind}"
                                 + (f": {'; '.join(domains)})" if kind == "rates file" else ")"))
        a.grid(alpha=0.3, which="both")
        a.set_ylabel(r"$s\,L/c_p$ (e-folds per pulse length)")
        if logy:
            a.set_xscale("log")
            a.set_yscale("log")
            a.set_xlabel(r"$\tau_d/\tau_{min} - 1$")
            if fits:
                law = fits[0]["law"]
                xx = np.geomspace(*law.x_range, 50)
                a.plot(xx, law(xx), "--", color="k", lw=1,
                       label=f"fit {law.A:.2g} (τ_d/τ_min − 1)^({law.n:.2f} ± {law.n_err:.2f})")
            hidden = sum(r["s"] <= 0 for r in list(sbi) + list(scans))
            if hidden:
                a.set_title(f"{hidden} SBI rate(s) ≤ 0 not shown (log axis)", fontsize=8)
            a.legend(fontsize=6, loc="lower right")
        else:
            a.set_xlabel(r"$\tau_d/\tau_{min}$")
            a.legend(fontsize=6)
    fig.tight_layout()
    save_figure(fig, out, dpi=dpi)
    return out


def sbi_modes_figure(path, spectra, modes, out, dpi=120) -> str:
    """One panel per τ_d: the mode shapes SBI pairs measured (``scan_pair_rates`` rows with a
    mode: antisymmetric deviation of ln(v/v*+1), docs/stability.md §2) with the eigenmode of the
    same pulse of ``path`` in the front's frame (:func:`front_frame_mode`) drawn over them, each
    scaled to unit largest modulus (the eigenmode on its body |ξ − ξ_f| > 0.02 L: the front cells
    carry the unresolved remainder of the displacement). Returns ``out``."""
    from matplotlib.figure import Figure

    from ..core.h5io import read_pulse
    by = {round(o["tau_d_ratio"], 4): o for o in spectra}
    taus = sorted({r["tau_d_ratio"] for r in modes}, reverse=True)
    fig = Figure(figsize=(4.2 * len(taus), 3.6))
    axes = np.atleast_1d(fig.subplots(1, len(taus)))
    for a, t in zip(axes, taus):
        for i, r in enumerate([m for m in modes if m["tau_d_ratio"] == t]):
            m = np.asarray(r["mode"])
            a.plot(r["mode_xi"], m / np.abs(m).max(), color=("C3", "C1", "C2")[i % 3], lw=2.5,
                   alpha=0.6, label=f"SBI pair ({r['domain']})")
        o = by.get(round(t, 4))
        if o is not None and o["sigma"].size:
            pulse, params = read_pulse(path, o["label"])
            y0 = np.log(pulse.v / params.v_star + 1.0)
            y1 = np.interp(pulse.xi, o["xi"], o["lnv"][0].real)
            eta, e = front_frame_mode(pulse.xi, y0, y1, pulse.L)
            x = eta / pulse.L
            sel = (x > -1.6) & (x < 0.6)
            body = sel & (np.abs(x) > 0.02)
            norm = e[body][np.argmax(np.abs(e[body]))]
            s = o["sigma"][0].real / o["rate_unit_c_over_L"]
            a.plot(x[sel], np.clip(e[sel] / norm, -0.3, 1.3), color="k", lw=1,
                   label=f"eigenmode in the front frame, s L/c = {s:.3g}")
        a.set_title(f"τ_d = {t:.2f} τ_min", fontsize=10)
        a.set_xlabel(r"$(\xi - \xi_{front})/L$")
        a.grid(alpha=0.3)
        a.legend(fontsize=7)
    axes[0].set_ylabel(r"mode of $\ln(v/v_*+1)$ (max |.| = 1)")
    fig.tight_layout()
    save_figure(fig, out, dpi=dpi)
    return out
