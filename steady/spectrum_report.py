"""Report of the stability spectrum study (docs/results.md §2): table, fits, comparison figures.

    slippulse steady stability runs/steady/family.h5 --levels 1       # s ± s_err of every pulse
    python steady/spectrum_report.py runs/steady/family.h5              # seconds

Prints the markdown table of s(τ_d), the refined values (s ± s_err as the command stored them, with
the value of every level) and the fit of s L/c_p near τ_min (on the values whose sign is resolved),
the SBI
±ε rates of this study, and writes docs/figures/spectrum_growth.png and (when the SBI scans of
dynamic/scans/eigen_modes.toml are present) docs/figures/stability_modes.png.
"""
from __future__ import annotations

import argparse
import os
import tomllib

import numpy as np
from scipy.optimize import curve_fit

from slippulse.core.h5io import label_ratio

#: The SBI ±ε growth rates of docs/stability.md §3 (measured by dynamic/scans/growth_td*.toml, base
#: pairs, s per pulse length, plateau rule): a data file with its provenance.
SBI_RATES = os.path.join(os.path.dirname(os.path.abspath(__file__)), "..", "dynamic", "results",
                         "sbi_growth_rates.toml")


def sbi_table(path=SBI_RATES):
    """Rows (τ_d/τ_min, s per L, err, domain) of the SBI ±ε rates file (``[[rates]]`` tables)."""
    with open(path, "rb") as fh:
        data = tomllib.load(fh)
    return [(float(r["tau_d_ratio"]), float(r["s"]), float(r["err"]), str(r["domain"]))
            for r in data["rates"]]


def scan_pairs(name):
    """Pairs (τ_d, s per L, err, domain, mode, mode_xi) of a scan under runs/scans, if present."""
    from slippulse.timedomain.perturbation import pair_growth, pair_rows, read_series, scan_rows
    from slippulse.timedomain.scan import load_scan
    try:
        scan = load_scan(os.path.join("dynamic", "scans", name + ".toml"))
        rows = scan_rows(scan)
    except Exception:
        return []
    paths = {c.id: scan.out_file(c) for c in scan.cases}
    out = []
    for plus, minus in pair_rows(rows):
        g = pair_growth(read_series(paths[plus["id"]]), read_series(paths[minus["id"]]),
                        abs(plus["eps"]))
        if not np.isfinite(g.get("s_per_L", np.nan)):
            continue
        label = plus.get("label", "")
        out.append(dict(tau=label_ratio(label), s=g["s_per_L"], err=g["s_per_L_err"],
                        domain=f"{plus.get('behind', 3.0):g}+{plus.get('ahead', 2.0):g} L, "
                               f"ε = {abs(plus['eps']):g}",
                        mode=g.get("mode"), mode_xi=g.get("mode_xi")))
    return out


def main(argv=None):
    from slippulse.plotting.spectrum import family_spectra
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("file")
    ap.add_argument("--figdir", default="docs/figures")
    args = ap.parse_args(argv)
    sp = family_spectra(args.file)
    q = np.array([o["tau_d_ratio"] for o in sp])
    lead = np.array([o["sigma"][0] if o["sigma"].size else np.nan for o in sp])
    unit = np.array([o["rate_unit_c_over_L"] for o in sp])
    sl = lead.real / unit
    st = np.array([o["translation_s_per_L"] for o in sp])
    nun = np.array([o["n_unstable"] for o in sp])
    print("| τ_d/τ_min | β | L (m) | s L/c_p | s (1/s) | Im s L/c_p | unstable | σ_t L/c_p |")
    print("|---|---|---|---|---|---|---|---|")
    for o, a, b, c, d, n in zip(sp, sl, lead, st, unit, nun):
        print(f"| {o['tau_d_ratio']:.4f} | {o['c_p'] / 2739.0:.5f} | {o['L']:.4g} | {a:.4f} | "
              f"{b.real:.4g} | {b.imag / d:.1e} | {n} | {c:.1e} |")
    # the refined values as `slippulse steady stability --levels K` stored them
    nested, allrows, fit = [], [], None
    for o in sp:
        if "s_per_L" not in o:
            continue
        u = o["rate_unit_c_over_L"]
        nested.append(dict(label=o["label"], extrapolated=float(o["s_per_L"]),
                           uncertainty=float(o["s_err_per_L"])))
        for n_, s_, t_ in zip(o["refine_n_points"], o["refine_s_levels"],
                              o["refine_translation_levels"]):
            allrows.append(dict(label=o["label"], N=int(n_), sL_c=s_ / u, translation=t_ / u))
    if nested:
        print("\n| τ_d/τ_min | N (levels) | s L/c_p per level | σ_t L/c_p per level | "
              "s L/c_p ± s_err | s (1/s) |")
        print("|---|---|---|---|---|---|")
        for r in nested:
            lv = [a for a in allrows if a["label"] == r["label"]]
            o = [x for x in sp if x["label"] == r["label"]]
            unit_r = o[0]["rate_unit_c_over_L"] if o else float("nan")
            levels = ", ".join(f"{a['sL_c']:.4f}" for a in lv)
            trans = ", ".join(f"{a['translation']:.1e}" for a in lv)
            print(f"| {r['label'][2:]} | {', '.join(str(a['N']) for a in lv)} | {levels} | {trans} | "
                  f"**{r['extrapolated']:.4f} ± {r['uncertainty']:.1e}** | "
                  f"{r['extrapolated'] * unit_r:.3g} |")
        # law near τ_min from the refined values: s L/c = A (q − 1)^p, weighted
        qn = np.array([label_ratio(r["label"]) for r in nested])
        sn = np.array([r["extrapolated"] for r in nested])
        en = np.array([max(r["uncertainty"], 1e-3 * abs(r["extrapolated"])) for r in nested])
        fit = None
        for lo, hi in [(1.0, 1.051), (1.0, 1.041), (1.019, 1.051)]:
            sel = (qn > lo) & (qn < hi) & (sn > 2 * en)
            if sel.sum() >= 3:
                f = lambda x, lnA, p: lnA + p * np.log(x - 1.0)
                popt, pcov = curve_fit(f, qn[sel], np.log(sn[sel]), sigma=en[sel] / sn[sel],
                                       absolute_sigma=True)
                perr = np.sqrt(np.diag(pcov))
                if fit is None:
                    fit = (float(np.exp(popt[0])), float(popt[1]))
                print(f"  refined, q in ({lo}, {hi}): s L/c_p = {np.exp(popt[0]):.3g} "
                      f"(τ_d/τ_min − 1)^({popt[1]:.2f} ± {perr[1]:.2f}) over {sel.sum()} points; "
                      f"residuals/σ = {np.round((np.log(sn[sel]) - f(qn[sel], *popt)) / (en[sel] / sn[sel]), 2)}")
    # figures
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    os.makedirs(args.figdir, exist_ok=True)
    new = (scan_pairs("growth_td1.04") + scan_pairs("eigen_modes")
           + scan_pairs("eigen_check_td1.20"))
    for r in new:
        print(f"SBI pair (this study): τ_d = {r['tau']:.2f}, {r['domain']}: s = {r['s']:.4f} ± "
              f"{r['err']:.4f} per L")
    fig, ax = plt.subplots(1, 2, figsize=(11, 4.3))
    for a, logy in zip(ax, (False, True)):
        x = (q - 1.0) if logy else q
        xf = (lambda t: t - 1.0) if logy else (lambda t: t)
        a.plot(x, sl, "-", color="C0", lw=1.5, label="eigenvalue on the family grids")
        a.plot(x, np.abs(st), ":", color="0.5", lw=1,
               label="|translation eigenvalue| (exact 0: error indicator)")
        if nested:
            a.errorbar([xf(label_ratio(r["label"])) for r in nested],
                       [r["extrapolated"] for r in nested],
                       yerr=[max(r["uncertainty"], 1e-4) for r in nested], fmt="s", color="C0",
                       ms=5, capsize=3, label="eigenvalue ± s_err (slippulse steady stability)")
        for t, sv, e, dom in sbi_table():
            if logy and sv <= 0:
                continue
            a.errorbar([xf(t)], [sv], yerr=[e], fmt="o", color="C3", ms=6, capsize=2, mfc="none")
        a.plot([], [], "o", color="C3", mfc="none", label="SBI ±ε pairs (docs/stability.md §3; periods 5–18 L)")
        for r in new:
            a.errorbar([xf(r["tau"])], [r["s"]], yerr=[r["err"]], fmt="D", color="C2", ms=4,
                       capsize=2)
        if new:
            a.plot([], [], "D", color="C2", ms=4, label="SBI ±ε pairs, rerun in this study")
        a.grid(alpha=0.3, which="both")
        a.set_ylabel(r"$s\,L/c_p$ (e-folds per pulse length)")
        if logy:
            a.set_xscale("log")
            a.set_yscale("log")
            a.set_ylim(1e-4, 60)
            a.set_xlabel(r"$\tau_d/\tau_{min} - 1$")
            if fit is not None:
                xx = np.geomspace(0.01, 0.06, 50)
                a.plot(xx, fit[0] * xx ** fit[1], "--", color="k", lw=1,
                       label=f"fit {fit[0]:.2g} (τ_d/τ_min − 1)^{fit[1]:.2f}")
            a.text(0.0105, 12.0, "SBI at 1.03, 2 mm: −0.024 ± 0.008 (not shown)", fontsize=7)
            a.legend(fontsize=7, loc="lower right")
        else:
            a.set_xlabel(r"$\tau_d/\tau_{min}$")
            a.legend(fontsize=7)
    fig.tight_layout()
    out = os.path.join(args.figdir, "spectrum_growth.png")
    fig.savefig(out, dpi=120)
    plt.close(fig)
    print(f"\nwrote {out}")
    modes = [r for r in new if r.get("mode") is not None]
    if modes:
        plot_modes(args.file, sp, modes, os.path.join(args.figdir, "stability_modes.png"))


def plot_modes(path, sp, modes, out):
    """SBI mode shapes (antisymmetric deviation of ln(v/v*+1) per unit v_max deviation, docs/stability.md §2)
    with the eigenmode of the same pulse drawn over them, both scaled to unit maximum modulus."""
    import matplotlib.pyplot as plt

    from slippulse.core.h5io import read_pulse
    from slippulse.plotting.spectrum import front_frame_mode
    by = {round(o["tau_d_ratio"], 4): o for o in sp}
    taus = sorted({r["tau"] for r in modes}, reverse=True)
    fig, ax = plt.subplots(1, len(taus), figsize=(4.2 * len(taus), 3.6), squeeze=False)
    for a, t in zip(ax[0], taus):
        for i, r in enumerate([m for m in modes if m["tau"] == t]):
            m = np.asarray(r["mode"])
            a.plot(r["mode_xi"], m / np.abs(m).max(), color=("C3", "C1", "C2")[i % 3], lw=2.5,
                   alpha=0.6, label=f"SBI pair ({r['domain']})")
        o = by.get(round(t, 4))
        if o is not None and o["sigma"].size:
            pulse, params = read_pulse(path, o["label"])
            y0 = np.log(pulse.v / params.v_star + 1.0)
            eta, e = front_frame_mode(pulse.xi, y0, o["lnv"][0].real, pulse.L)
            x = eta / pulse.L
            sel = (x > -1.6) & (x < 0.6)
            body = sel & (np.abs(x) > 0.02)        # scaled on the body: the front cells carry the
            norm = e[body][np.argmax(np.abs(e[body]))]   # unresolved remainder of the displacement
            a.plot(x[sel], np.clip(e[sel] / norm, -0.3, 1.3), color="k", lw=1,
                   label=f"eigenmode in the front frame, s L/c = {o['leading_s_per_L']:.3g}")
        a.set_title(f"τ_d = {t:.2f} τ_min", fontsize=10)
        a.set_xlabel(r"$(\xi - \xi_{front})/L$")
        a.grid(alpha=0.3)
        a.legend(fontsize=7)
    ax[0, 0].set_ylabel(r"mode of $\ln(v/v_*+1)$ (max |.| = 1)")
    fig.tight_layout()
    fig.savefig(out, dpi=120)
    plt.close(fig)
    print(f"wrote {out}")


if __name__ == "__main__":
    main()
