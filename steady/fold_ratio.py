"""The growth rates of record against the slope of the family (docs/results.md §2).

    python steady/fold_ratio.py FAMILY.h5 [FAMILY2.h5 ...] [--records docs/results/records.toml]
        [--figure docs/figures/fold_ratio.png] [--from-length 100]

A real eigenvalue of a pulse crosses zero only at a fold of the family in τ_d (docs/spectrum.md §1); near one,
s L/c_p ≈ R |dτ_d/d ln L|. This driver takes the rates of record (the ``[spectrum."LABEL"]``
entries of the records file: s L/c_p ± err and L) and the family's slope dτ_d/d ln L at each
record's L from the converged pulses of the family files (:func:`slippulse.spectrum.law.family_slope`;
any march of the one family: the pulses need not be those the rates were measured on). Records
beyond the files' deepest pulse take the slope from the records' own (τ_d, L) points (marked
"records"; coarser). Prints, as Markdown, the table (L, τ_d, s L/c_p, the slope, R, the source of
the slope), whether τ_d(L) folds in the files, the power law R ∝ L^m on L ≥ --from-length and
the local exponents of R and of the slope; draws R and |dτ_d/d ln L| against L.
Seconds (reads the files; solves nothing). `slippulse steady rates FILE` gives the same columns
for the spectra stored in a family file.
"""
import argparse
import sys
import tomllib

import numpy as np

from slippulse.core.h5io import label_decimals, label_ratio
from slippulse.spectrum.law import (family_curve, family_slope, fit_power_law, fold_ratio,
                                     folds, local_exponents)


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("family", nargs="+", help="family HDF5 file(s): the slope dtau_d/d ln L")
    ap.add_argument("--records", default="docs/results/records.toml")
    ap.add_argument("--figure", default=None, help="PNG: R and |dtau_d/d ln L| against L")
    ap.add_argument("--from-length", type=float, default=100.0,
                    help="fit R = A L^m on the records with L >= this (m; default 100)")
    a = ap.parse_args(argv)
    with open(a.records, "rb") as fh:
        rec = tomllib.load(fh)["spectrum"]
    labels = sorted(rec, key=lambda k: rec[k]["L"])
    L = np.array([rec[k]["L"] for k in labels])
    tau = np.array([label_ratio(k) for k in labels])
    s = np.array([rec[k]["s_per_L"]["value"] for k in labels])
    se = np.array([rec[k]["s_per_L"]["err"] for k in labels])

    curve = family_curve(a.family)
    g, ge = family_slope(curve["tau_d_ratio"], curve["L"], curve["beta"], at_L=L)
    src = np.where(np.isfinite(g), "family", "records")
    g2, ge2 = family_slope(tau, L)                       # along ln L: no β in the records
    # the records' τ_d is their label's, rounded to its last decimal: that rounding, over the
    # spacing in ln L to the nearest record, adds to the error of a slope taken from them
    half = np.array([0.5 * 10.0 ** -label_decimals(k) for k in labels])
    dx = np.diff(np.log(L))
    near = np.minimum(np.r_[np.inf, dx], np.r_[dx, np.inf])
    ge2 = np.hypot(ge2, np.sqrt(2.0) * half / near)
    g, ge = np.where(np.isfinite(g), g, g2), np.where(np.isfinite(ge), ge, ge2)
    R, Re = fold_ratio(s, se, g, ge)

    turns = folds(curve["tau_d_ratio"], curve["beta"])
    print(f"Family files: {curve['L'].size} converged pulses, L = {curve['L'].min():.4g} to "
          f"{curve['L'].max():.5g} m; "
          + ("tau_d is monotone along the family (no fold)." if not turns
             else f"folds at beta = {turns}."))
    print()
    print("| L (m) | τ_d/τ_min | s L/c_p ± err | dτ_d/d ln L ± err | R ± err | slope from |")
    print("|---|---|---|---|---|---|")
    for k in range(L.size):
        print(f"| {L[k]:.4g} | {tau[k]:.6f} | {s[k]:.5g} ± {se[k]:.2g} | {g[k]:.4g} ± "
              f"{ge[k]:.1g} | {R[k]:.4g} ± {Re[k]:.1g} | {src[k]} |")
    m = L >= a.from_length
    fit = fit_power_law(L[m], R[m], Re[m])
    print()
    print("R = " + fit.describe("L/m", "R").split("R = ", 1)[1])
    xm, kR = local_exponents(L[m], R[m])
    xm, kg = local_exponents(L[m], np.abs(g[m]))
    print("local exponents at L (m) = " + ", ".join(f"{v:.3g}" for v in xm))
    print("  d ln R/d ln L:            " + ", ".join(f"{v:+.2f}" for v in kR))
    print("  d ln|dτ_d/d ln L|/d ln L: " + ", ".join(f"{v:+.2f}" for v in kg))
    if a.figure:
        from matplotlib.figure import Figure
        fig = Figure(figsize=(11, 4.3))
        ax = fig.subplots(1, 2)
        ok = np.isfinite(R) & (R > 0)
        for mk, lab in (("family", "slope from a march's pulses"),
                        ("records", "slope from the records' own pulses")):
            w = ok & (src == mk)
            if np.any(w):
                ax[0].errorbar(L[w], R[w], yerr=np.minimum(Re[w], 0.999 * R[w]),
                               fmt="o" if mk == "family" else "s", ms=4, capsize=2, label=lab)
                ax[1].errorbar(L[w], np.abs(g[w]), yerr=np.minimum(ge[w], 0.999 * np.abs(g[w])),
                               fmt="o" if mk == "family" else "s", ms=4, capsize=2, label=lab)
        xx = np.geomspace(*fit.x_range, 100)
        ax[0].plot(xx, fit(xx), "-", color="C3",
                   label=f"R ∝ L^({fit.n:.3f} ± {fit.n_err:.3f}), L ≥ {a.from_length:g} m")
        ax[1].plot(L[ok], s[ok], "^", ms=4, color="0.4", label="s L/c_p (rates of record)")
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
        fig.savefig(a.figure, dpi=130)
        print(f"\nfigure: {a.figure}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
