"""Figures of the stability spectrum: s(τ_d) over a family, the spectrum, the leading modes."""
from __future__ import annotations

import numpy as np

from ..core.atomic import save_figure


def family_spectra(path):
    """Stored spectra of a file, by decreasing τ_d: list of dicts (see spectrum.read_spectrum)."""
    from ..spectrum.pulse import read_spectrum
    from ..core.h5io import labels_in, open_h5
    with open_h5(path) as h5:
        labels = [k for k in labels_in(h5, path) if "spectrum" in h5["pulses"][k]]
    out = []
    for lab in labels:
        o = read_spectrum(path, lab)
        if o is not None and o.get("status") == "converged":
            o["label"] = lab                 # labelled before filtering: a failed pulse shifts none
            out.append(o)
    return sorted(out, key=lambda o: -o["tau_d_ratio"])


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
