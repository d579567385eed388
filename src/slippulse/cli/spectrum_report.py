"""``slippulse dynamic spectrum-report``: the linear spectrum of a family beside the SBI's measured
growth rates (library: :mod:`slippulse.spectrum.report`, :mod:`slippulse.timedomain.sbi_rates`,
figures :mod:`slippulse.plotting.spectrum`)."""
from __future__ import annotations

import os

from ..core.errors import UsageError


def _print_tables(rows, refined, fits) -> None:
    print("| τ_d/τ_min | β | L (m) | s L/c_p | s (1/s) | Im s L/c_p | unstable | σ_t L/c_p |")
    print("|---|---|---|---|---|---|---|---|")
    for r in rows:
        print(f"| {r['tau_d_ratio']:.4f} | {r['beta']:.5f} | {r['L']:.4g} | {r['s_per_L']:.4f} | "
              f"{r['s']:.4g} | {r['im_per_L']:.1e} | {r['n_unstable']} | "
              f"{r['translation_s_per_L']:.1e} |")
    if refined:
        print("\n| τ_d/τ_min | N (levels) | s L/c_p per level | σ_t L/c_p per level | "
              "s L/c_p ± s_err | s (1/s) |")
        print("|---|---|---|---|---|---|")
        for r in refined:
            print(f"| {r['tau_d_ratio']:.4f} | {', '.join(map(str, r['levels']))} | "
                  f"{', '.join(f'{v:.4f}' for v in r['s_levels'])} | "
                  f"{', '.join(f'{v:.1e}' for v in r['translation_levels'])} | "
                  f"**{r['s_per_L']:.4f} ± {r['s_err_per_L']:.1e}** | {r['s']:.3g} |")
    else:
        print("\nno refined rate stored (slippulse steady stability FILE --levels K): no fit")
    for f in fits:
        lo, hi = f["window"]
        print(f"fit, tau_d/tau_min in ({lo:g}, {hi:g}): "
              + f["law"].describe("(tau_d/tau_min - 1)", "s L/c_p")
              + f"; pulls {', '.join(f'{p:+.2f}' for p in f['pulls'])}")
    if refined and not fits:
        print("no power-law fit: fewer than 3 resolved refined rates in every window")


def cmd_spectrum_report(args) -> int:
    from ..core.h5io import open_h5, read_parameters
    from ..plotting.spectrum import sbi_modes_figure, spectrum_growth_figure
    from ..spectrum.report import family_spectra, near_min_fits, refined_rows, spectrum_rows
    from ..timedomain.sbi_rates import read_sbi_rates, scan_pair_rates
    from ..timedomain.scan import load_scan
    from .checks import check_outdir
    if not os.path.isfile(args.family):
        raise UsageError(f"FAMILY={args.family!r}: no such file")
    sbi = []
    if args.sbi_rates:
        if not os.path.isfile(args.sbi_rates):
            raise UsageError(f"--sbi-rates={args.sbi_rates!r}: no such file")
        try:
            sbi = read_sbi_rates(args.sbi_rates)
        except ValueError as exc:
            raise UsageError(f"--sbi-rates: {exc}") from None
    scans = [load_scan(p) for p in args.scans]
    check_outdir(args.figdir, "--figdir")
    spectra = family_spectra(args.family)
    if not spectra:
        raise UsageError(f"{args.family}: no converged spectrum stored (run 'slippulse steady "
                         f"stability {args.family}')")
    with open_h5(args.family) as h5:
        c_s = read_parameters(h5, args.family).c_s
    os.makedirs(args.figdir, exist_ok=True)
    rows, refined = spectrum_rows(spectra, c_s), refined_rows(spectra)
    fits = near_min_fits(refined)
    _print_tables(rows, refined, fits)
    pairs = [r for scan in scans for r in scan_pair_rates(scan)]
    for r in sbi:
        print(f"SBI rate ({os.path.basename(args.sbi_rates)}): tau_d = {r['tau_d_ratio']:.2f}, "
              f"{r['domain']}: s = {r['s']:.4g} ± {r['err']:.2g} per L")
    for r in pairs:
        print(f"SBI pair (scan): tau_d = {r['tau_d_ratio']:.2f}, {r['domain']}: s = {r['s']:.4f} "
              f"± {r['err']:.4f} per L")
    written = [spectrum_growth_figure(rows, refined, os.path.join(args.figdir,
                                                                  "spectrum_growth.png"),
                                      fits=fits, sbi=sbi, scans=pairs)]
    modes = [r for r in pairs if r["mode"] is not None]
    if modes:
        written.append(sbi_modes_figure(args.family, spectra, modes,
                                        os.path.join(args.figdir, "spectrum_modes.png")))
    print(f"{len(rows)} pulses ({len(refined)} refined), {len(sbi)} + {len(pairs)} SBI rates; "
          f"figures: {', '.join(written)}")
    return 0


def register(sub) -> None:
    """Add ``spectrum-report`` to the ``dynamic`` sub-commands."""
    p = sub.add_parser("spectrum-report", help="the linear spectrum of a family beside the SBI's "
                                               "growth rates: tables, fit, figures",
                       description="From the spectra stored in FAMILY (`slippulse steady "
                                   "stability`): the table of the leading eigenvalue of every "
                                   "pulse on its own grid, the refined rates s +- s_err with "
                                   "every level, and power-law fits s L/c_p = A (tau_d/tau_min - "
                                   "1)^n near tau_min on the resolved refined rates; beside them "
                                   "the SBI's rates, measured (--sbi-rates) or computed from "
                                   "finished scan pairs (--scans). Writes spectrum_growth.png "
                                   "and, when a scan pair has a mode shape, spectrum_modes.png "
                                   "(the SBI's modes over the eigenmodes) to --figdir.")
    p.add_argument("family", metavar="FAMILY.h5", help="family file with stored spectra")
    p.add_argument("--sbi-rates", default=None, metavar="TOML",
                   help="measured SBI rates with their provenance ([source] and [[rates]] tables, "
                        "e.g. dynamic/results/sbi_growth_rates.toml; default: none)")
    p.add_argument("--scans", nargs="+", default=[], metavar="SCAN.toml",
                   help="perturbation scans whose finished +-eps pairs are measured and drawn")
    p.add_argument("--figdir", default=os.path.join("runs", "figures"),
                   help="directory of the figures (default runs/figures)")
    p.set_defaults(func=cmd_spectrum_report)
