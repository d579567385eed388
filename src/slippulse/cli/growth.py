"""``slippulse dynamic growth-report``: the ±ε pairs of perturbation scans (docs/stability.md):
the table of measured growth rates s(τ_d) with each pair's variant against its scan's base pair,
how closely the runs follow the steady line c_p⁰(L), and the figures."""
from __future__ import annotations

import os


def _table(pairs) -> None:
    print("| τ_d/τ_min | variant | s per L | s per second | window (ms) | fit pts | "
          "mode spread | fate +ε | fate −ε | wall of pair (s) |")
    print("|---|---|---|---|---|---|---|---|---|---|")
    for p in pairs:
        print(f"| {p['tau_d_ratio']:.4g} | {p['variant']} (Δx {float(p['dx']) * 1e3:g} mm, "
              f"ε {p['eps']:g}) | {p['s_per_L']:.3g} ± {p['s_per_L_err']:.2g} | "
              f"{p['s_per_s']:.4g} ± {p['s_per_s_err']:.2g} | "
              f"{1e3 * p['t0']:.3g}–{1e3 * p['t1']:.3g} | {p['n']} | {p['mode_spread']:.2g} | "
              f"{p['fate_plus']} | {p['fate_minus']} | {p['wall_time']:.0f} |")


def _line_table(by_scan, curve) -> None:
    """The base pair's runs and the ε ≥ 0.01 variants against the steady line c_p⁰(L)
    (:func:`slippulse.timedomain.attractor.line_departure`)."""
    from ..timedomain.attractor import line_departure
    from ..timedomain.perturbation import read_series
    print("\n| τ_d/τ_min | run | fate | L range (m) | c_p/c_s range | median of "
          "abs(c_p/c_p⁰(L) − 1) | max | fraction of samples in the line's L range |")
    print("|---|---|---|---|---|---|---|---|")
    for sel in by_scan.values():
        for tag, key in (("+ε", "_file_plus"), ("−ε", "_file_minus")):
            for p in sel[:1] + [q for q in sel if q["variant"].startswith("ε = ") and
                                q["eps"] >= 0.01 - 1e-12]:
                d = line_departure(read_series(p[key]), curve)
                print(f"| {p['tau_d_ratio']:.4g} | {tag}, ε = {p['eps']:g} | "
                      f"{p['fate_plus' if tag == '+ε' else 'fate_minus']} | "
                      f"{d['L_min']:.3g}–{d['L_max']:.3g} | "
                      f"{d['beta_min']:.3g}–{d['beta_max']:.3g} | {d['median']:.2g} | "
                      f"{d['max']:.2g} | {d['fraction']:.2f} |")


def cmd_growth_report(args) -> int:
    from ..core.h5io import check_writable
    from ..plotting.stability import growth_figure, stability_figures
    from ..timedomain.perturbation import pair_table, pair_variant, scan_rows, steady_curve
    from ..timedomain.scan import load_scan
    from ..core.errors import UsageError
    scans = [load_scan(p) for p in args.scans]
    for f in args.family:
        if not os.path.isfile(f):
            raise UsageError(f"--family={f!r}: no such file")
    check_writable(os.path.join(args.figdir, args.prefix + "growth.png"), "--figdir")
    all_rows, by_scan = [], {}
    for scan in scans:
        rows = scan_rows(scan)
        if not rows:
            print(f"(no results for {scan.name})")
            continue
        all_rows += rows
        pairs = pair_table(rows)
        for p in pairs:
            p["variant"] = pair_variant(p, pairs[0])
        if pairs:
            by_scan[scan.name] = pairs
    table = [p for sel in by_scan.values() for p in sel]
    _table(table)
    print()
    for name, sel in by_scan.items():
        if len(sel) > 1:
            b = sel[0]["s_per_L"]
            print(f"{name}: s = {b:.4g}/L (base); relative changes: " + ", ".join(
                f"{p['variant']}: {p['s_per_L'] / b - 1:+.1%}" for p in sel[1:]))
    if table and args.family:
        _line_table(by_scan, steady_curve(*args.family))
    if not table:                   # no figure replaced by an empty one
        print(f"0 pairs of {len(scans)} scans: no figures written")
        return 0
    paths = stability_figures(all_rows, table, args.figdir, prefix=args.prefix,
                              extra_steady=tuple(args.family[1:]))
    paths.append(growth_figure(table, os.path.join(args.figdir, args.prefix + "growth.png")))
    print(f"{len(table)} pairs of {len(scans)} scans; figures: {', '.join(paths)}")
    return 0


def register(sub) -> None:
    """Add ``growth-report`` to the ``dynamic`` sub-commands."""
    p = sub.add_parser("growth-report", help="the growth rates of perturbation scans: table, figures",
                       description="Pair the finished +-eps runs of each scan (`slippulse dynamic "
                                   "scan`), print the table of measured growth rates s(tau_d) "
                                   "with each pair's variant against its scan's base pair, how "
                                   "closely the runs follow the steady line c_p0(L) of --family, "
                                   "and write the figures (growth, trajectories, modes, "
                                   "deviation) to --figdir (docs/stability.md).")
    p.add_argument("scans", metavar="SCAN.toml", nargs="+", help="scan files, one per tau_d")
    p.add_argument("--family", nargs="*", default=[], metavar="FILE",
                   help="steady family file(s) of the line c_p0(L) (the first the scans' family, "
                        "the others further branches drawn beside it)")
    p.add_argument("--figdir", default=os.path.join("runs", "figures"),
                   help="directory of the figures (default runs/figures)")
    p.add_argument("--prefix", default="stability_", help="figure file prefix (stability_)")
    p.set_defaults(func=cmd_growth_report)
