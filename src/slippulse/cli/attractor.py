"""``slippulse dynamic attractor overlap|pairs|figure``: the steady line as attractor, mode by mode
(docs/stability.md §4; library: :mod:`slippulse.timedomain.attractor`)."""
from __future__ import annotations

import os

from ..core.errors import UsageError


def _fmt(row: dict, keys) -> str:
    return " ".join(f"{k}={row[k]:.5g}" if isinstance(row[k], float) else f"{k}={row[k]}"
                    for k in keys)


def _check_dirs(dirs, option: str) -> None:
    for d in dirs:
        if not os.path.isdir(d):
            raise UsageError(f"{option}={d!r}: no such directory (a scan's out_dir)")


def _line_scans(args):
    """The scans of --line-scans, loaded before any work (a bad file is refused at once)."""
    from ..timedomain.scan import load_scan
    for f in args.line_family:
        if not os.path.isfile(f):
            raise UsageError(f"--line-family={f!r}: no such file")
    return [load_scan(p) for p in args.line_scans]


def _line_points(scans, family) -> list[dict]:
    from ..timedomain.attractor import base_pair_departures
    from ..timedomain.perturbation import steady_curve
    curve = steady_curve(*family) if family else None
    out = []
    for scan in scans:
        r = base_pair_departures(scan, curve)
        if r is None:
            print(f"(no finished pair in {scan.name})")
            continue
        print(f"line: {scan.name} tau_d/tau_min={r['tau_d_ratio']:.4g} eps={r['eps']:g}: median "
              f"|c_p/c_p0(L) - 1| = {r['plus']:.3g} (+eps), {r['minus']:.3g} (-eps)")
        out.append(r)
    return out


def _sbi_points(dirs, rows=(), local_h=2e-3) -> list[dict]:
    from ..timedomain.attractor import sbi_departures
    pts = sbi_departures(dirs, rows, local_h=local_h)
    for p in pts:
        print(f"SBI pair {p['label']} ({os.path.basename(p['steady'])}, eps {p['eps']:g}): "
              f"departure fraction {p['departure_fraction']:.4g} (mode "
              f"{p['departure_fraction_mode']:.4g})")
    return pts


def cmd_overlap(args) -> int:
    from ..core.h5io import check_writable
    from ..plotting.stability import attractor_figure
    from ..timedomain.attractor import OVERLAP_COLUMNS, write_overlap_csv
    from ..timedomain.eigenmode import family_overlaps
    from .checks import check_figure, check_labels, finite
    if not os.path.isfile(args.family):
        raise UsageError(f"FAMILY={args.family!r}: no such file")
    if args.local_h is not None:
        finite(args.local_h, "--local-h", lo=0.0, hi=0.05, unit="(tau_d/tau_min)")
    if args.csv:
        check_writable(args.csv, "--csv")
    if args.figure:
        check_figure(args.figure, "--figure")
    _check_dirs(args.pairs, "--pairs")
    scans = _line_scans(args)
    if args.labels:
        check_labels(args.family, args.labels)
    rows = family_overlaps(args.family, local_h=args.local_h, labels=args.labels)
    if not rows:
        raise UsageError(f"{args.family}: no pulse with a stored unstable mode and a neighbour in "
                         f"tau_d (run 'slippulse steady stability {args.family}')")
    for r in rows:
        print(_fmt(r, OVERLAP_COLUMNS))
    if args.csv:
        print(f"table {write_overlap_csv(rows, args.csv)}")
    sbi = _sbi_points(args.pairs, rows, local_h=args.local_h or 2e-3)
    line = _line_points(scans, args.line_family or [args.family])
    if args.figure:
        name = os.path.basename(args.family)
        print(f"figure {attractor_figure([(name, rows)], args.figure, sbi=sbi, line=line)}")
    return 0


def cmd_pairs(args) -> int:
    from ..timedomain.attractor import mode_pairs, pair_analysis
    from .checks import finite
    finite(args.d_max, "--d-max", lo=0.0, hi=0.3)
    _check_dirs(args.dirs, "DIR")
    n = 0
    for d in args.dirs:
        for key, p, m in mode_pairs(d):
            try:
                row = pair_analysis(key, p, m, d_max=args.d_max)
            except ValueError as exc:
                print(f"{key[1]} ({os.path.basename(key[0])}, dx {key[2]:g}, eps {key[3]:g}): "
                      f"no rate: {exc}")
                continue
            print(_fmt(row, row))
            n += 1
    print(f"{n} eigenmode-seeded pairs analysed in {len(args.dirs)} directories")
    return 0


def cmd_figure(args) -> int:
    from ..plotting.stability import attractor_figure
    from ..timedomain.attractor import read_overlap_csv
    from .checks import check_figure
    check_figure(args.out, "OUT")
    if len(args.names) > len(args.csv):
        raise UsageError(f"--names: {len(args.names)} names for {len(args.csv)} --csv tables")
    series = []
    for i, path in enumerate(args.csv):
        if not os.path.isfile(path):
            raise UsageError(f"--csv={path!r}: no such file")
        try:
            rows = read_overlap_csv(path)
        except ValueError as exc:
            raise UsageError(f"--csv={path!r}: {exc}") from None
        series.append((args.names[i] if i < len(args.names) else os.path.basename(path), rows))
    _check_dirs(args.pairs, "--pairs")
    scans = _line_scans(args)
    sbi = _sbi_points(args.pairs, [r for _, rows in series[:1] for r in rows])
    line = _line_points(scans, args.line_family)
    print(f"figure {attractor_figure(series, args.out, sbi=sbi, line=line)}")
    return 0


def _line_args(p) -> None:
    p.add_argument("--pairs", nargs="+", default=[], metavar="DIR",
                   help="scan directories of eigenmode-seeded +-eps pairs: the departure fraction "
                        "each pair measures is drawn beside the mode's")
    p.add_argument("--line-scans", nargs="+", default=[], metavar="SCAN.toml",
                   help="perturbation scans whose base +-eps runs are drawn by their median "
                        "|c_p/c_p0(L) - 1| along the whole trajectory")
    p.add_argument("--line-family", nargs="+", default=[], metavar="FILE",
                   help="steady family file(s) of the line c_p0(L) for --line-scans (default: "
                        "FAMILY for overlap, else the files the runs were seeded from)")


def register(sub) -> None:
    """Add ``attractor`` to the ``dynamic`` sub-commands."""
    a = sub.add_parser("attractor", help="the steady line as attractor: the unstable mode against "
                                         "the family tangent, and the SBI pairs",
                       description="Whether a perturbed pulse follows the steady line c_p0(L): "
                                   "the overlap of each pulse's unstable eigenmode with the family "
                                   "tangent d(y, ln phi)/dtau_d in the frame of the front, and "
                                   "the departure fraction f = 1 - slope_line/slope_mode (0: "
                                   "along the line, 1: c_p changes at fixed L), against what "
                                   "eigenmode-seeded SBI pairs measure (docs/stability.md "
                                   "section 4).")
    sub2 = a.add_subparsers(dest="attractor_command", metavar="WHAT")
    sub2.required = True
    o = sub2.add_parser("overlap", help="overlap and departure fraction at every pulse of a family",
                        description="At every pulse of FAMILY with a stored unstable mode "
                                    "('slippulse steady stability'), the overlap of the mode with "
                                    "the family tangent and the departure fraction; one line per "
                                    "pulse, optionally a CSV table and the figure.")
    o.add_argument("family", metavar="FAMILY.h5", help="steady family file with stored spectra")
    o.add_argument("--labels", nargs="+", default=None, metavar="LABEL",
                   help="only these pulses (default: all with a stored mode)")
    o.add_argument("--local-h", type=float, default=None, metavar="H",
                   help="tangent from the pulses at tau_d/tau_min +- H solved on each pulse's grid "
                        "(in (0, 0.05]; default: the family's neighbouring pulses)")
    o.add_argument("--csv", default=None, metavar="OUT.csv", help="write the table")
    o.add_argument("--figure", default=None, metavar="PNG", help="draw overlap and departure")
    _line_args(o)
    o.set_defaults(func=cmd_overlap)
    p = sub2.add_parser("pairs", help="eigenmode-seeded +-eps pairs against their mode",
                        description="For each eigenmode-seeded +-eps pair (perturbation mode or "
                                    "mode_front) in the DIRs, the growth rate (fit of the "
                                    "antisymmetric |v_max| response over the linear regime and its "
                                    "first third) against the stored eigenvalue, and the measured "
                                    "change of c_p and L per unit change of v_max against the "
                                    "mode's prediction. One line per pair.")
    p.add_argument("dirs", metavar="DIR", nargs="+", help="scan output directories")
    p.add_argument("--d-max", type=float, default=0.03,
                   help="end of the linear regime: either run's |v_max error| (default 0.03)")
    p.set_defaults(func=cmd_pairs)
    f = sub2.add_parser("figure", help="the figure from overlap tables (several series)",
                        description="Draw overlap and departure fraction against tau_d from one "
                                    "or more 'attractor overlap --csv' tables (one style each), "
                                    "with the SBI measurements of --pairs and --line-scans.")
    f.add_argument("out", metavar="OUT.png", help="figure file")
    f.add_argument("--csv", nargs="+", required=True, metavar="TABLE.csv",
                   help="tables of 'slippulse dynamic attractor overlap --csv'")
    f.add_argument("--names", nargs="+", default=[], metavar="NAME",
                   help="legend name of each table (default: its file name)")
    _line_args(f)
    f.set_defaults(func=cmd_figure)

