"""``slippulse steady fold-ratio``: the growth rates of record against the slope of the family
(:mod:`slippulse.spectrum.records`; docs/results.md §2)."""
from __future__ import annotations

import os

import numpy as np

from ..core.errors import UsageError
from .checks import check_figure, finite


def cmd_fold_ratio(args) -> int:
    from ..spectrum.law import fit_power_law, folds, local_exponents
    from ..spectrum.records import read_rates, records_fold_ratio

    finite(args.from_length, "--from-length", lo=0.0)
    if args.figure:
        check_figure(args.figure, "--figure")
    if not os.path.isfile(args.records):
        raise UsageError(f"--records={args.records!r} is invalid: no such file (a records TOML, "
                         "e.g. docs/results/records.toml)")
    try:
        rates = read_rates(args.records)
    except ValueError as exc:
        raise UsageError(f"--records={args.records!r} is invalid: {exc}") from None
    fr = records_fold_ratio(rates, args.file)
    curve = fr["curve"]
    L, R, Re, g, ge = fr["L"], fr["R"], fr["R_err"], fr["slope"], fr["slope_err"]
    turns = folds(curve["tau_d_ratio"], curve["beta"])
    print(f"family files: {curve['L'].size} converged pulses, L = {curve['L'].min():.4g} to "
          f"{curve['L'].max():.5g} m; " + ("tau_d is monotone along the family (no fold)"
                                          if not turns else f"folds at beta = {turns}"))
    print("L(m) tau_d/tau_min sL/c_p +- err dtau_d/dlnL +- err R +- err slope_from")
    for k in range(L.size):
        print(f"{L[k]:.4g} {fr['tau_d_ratio'][k]:.6f} {fr['s'][k]:.5g} {fr['s_err'][k]:.2g} "
              f"{g[k]:.4g} {ge[k]:.1g} {R[k]:.4g} {Re[k]:.1g} {fr['source'][k]}")
    m = (L >= args.from_length) & np.isfinite(R) & (R > 0)
    if m.sum() < 3:
        raise UsageError(f"--from-length={args.from_length!r}: {int(m.sum())} rates of record "
                         "with L at or above it; the power law of R needs >= 3")
    fit = fit_power_law(L[m], R[m], Re[m])
    print("fit: R = " + fit.describe("L/m", "R").split("R = ", 1)[1])
    xm, kR = local_exponents(L[m], R[m])
    _, kg = local_exponents(L[m], np.abs(g[m]))
    print("local exponents at L (m) = " + ", ".join(f"{v:.3g}" for v in xm))
    print("  d ln R/d ln L:            " + ", ".join(f"{v:+.2f}" for v in kR))
    print("  d ln|dtau_d/d ln L|/d ln L: " + ", ".join(f"{v:+.2f}" for v in kg))
    if args.figure:
        from ..plotting.rates import plot_fold_ratio
        plot_fold_ratio(fr, fit, args.from_length, args.figure)
        print(f"figure: {args.figure}")
    print(f"fold-ratio {args.records}: {L.size} rates of record, L = {L.min():.4g}-{L.max():.5g} m; "
          f"R = s L/c_p / |dtau_d/d ln L| in {np.nanmin(R):.3g}-{np.nanmax(R):.3g}; "
          f"R ∝ L^({fit.n:.3f} ± {fit.n_err:.3f}) on L >= {args.from_length:g} m "
          f"({int(m.sum())} rates; errors from the rates' and the slopes' errors); "
          + ("no fold of tau_d in the family files" if not turns else
             f"{len(turns)} fold(s) of tau_d in the family files"))
    return 0


def register(ss) -> None:
    p = ss.add_parser("fold-ratio", help="the growth rates of record against the family's slope",
                      description="A real eigenvalue crosses zero only at a fold of the family "
                                  "in tau_d; near one s L/c_p ~ R |dtau_d/d ln L|. Takes the "
                                  "rates of record ([spectrum.\"LABEL\"] of --records: s L/c_p "
                                  "+- err, L) and the family's slope at each record's L from "
                                  "the converged pulses of FILEs (beyond their deepest pulse: "
                                  "from the records' own points, coarser), prints R +- err, "
                                  "whether tau_d(L) folds in the files, the power law R ~ L^m "
                                  "on L >= --from-length and the local exponents "
                                  "(docs/results.md section 2).")
    p.add_argument("file", metavar="FILE", nargs="+",
                   help="HDF5 family file(s) for the slope (any march of the one family)")
    p.add_argument("--records", default="docs/results/records.toml", metavar="TOML",
                   help="records file with the rates (default docs/results/records.toml)")
    p.add_argument("--from-length", type=float, default=100.0, metavar="M",
                   help="fit R = A L^m on the rates with L >= M (m; default 100)")
    p.add_argument("--figure", default=None, metavar="PNG",
                   help="draw R and |dtau_d/d ln L| against L")
    p.set_defaults(func=cmd_fold_ratio)
