"""``slippulse steady branch-map``: the branches of steady pulses in (τ_d/τ_min, L), coloured by
their number of unstable eigenvalues (:mod:`slippulse.plotting.branches`)."""
from __future__ import annotations

import sys

import numpy as np

from ..core.errors import UsageError


def cmd_branch_map(args) -> int:
    from ..core.h5io import check_pulses, open_h5, read_parameters
    from ..core.params import differing, describe_difference
    from ..plotting.branches import branch_series, plot_branch_map
    from .checks import check_figure

    if args.names and len(args.names) != len(args.files):
        raise UsageError(f"names: {len(args.names)} given for {len(args.files)} files; give one "
                         "per file or none")
    check_figure(args.out, "--out")
    groups = [a.split("+") for a in args.files]
    params = None
    for path in (p for g in groups for p in g):
        check_pulses(path)
        with open_h5(path, "FILE") as h5:
            p = read_parameters(h5, path)
        if params is not None and differing(params, p):
            raise UsageError(f"{path} holds pulses of other parameters than {args.files[0]}: "
                             f"{describe_difference(params, p, args.files[0], path)}")
        params = p
    series = []
    for i, paths in enumerate(groups):
        try:
            series.append(branch_series(paths, args.names[i] if args.names else None))
        except ValueError as exc:
            raise UsageError(str(exc)) from None
    if args.zoom is not None and not (1.0 < args.zoom[0] < args.zoom[1]):
        raise UsageError(f"--zoom {args.zoom[0]:g} {args.zoom[1]:g}: need 1 < Q0 < Q1 "
                         "(tau_d/tau_min)")
    plot_branch_map(series, args.out, params=params, title=args.title,
                    zoom=tuple(args.zoom) if args.zoom else None)
    for b in series:
        n, counted = b.unstable()
        with_spec = n >= 0
        counts = sorted({int(k) for k in n[counted]})
        found = sorted({int(k) for k in n[with_spec & ~counted]})
        print(f"{b.name}: {b.q.size} pulses, tau_d/tau_min {b.q.min():.5f}-{b.q.max():.5f}, "
              f"L {b.L.min():.4g}-{b.L.max():.4g} m; {int(counted.sum())} counted "
              f"(unstable: {counts or '-'}), {int((with_spec & ~counted).sum())} with a "
              f"spectrum but no count (found: {found or '-'}), {int((~with_spec).sum())} "
              "without a spectrum", file=sys.stdout)
    if len(series) > 1:
        from ..plotting.branches import length_ratio
        ref = series[0]
        for b in series[1:]:
            try:
                r = length_ratio(b, ref)
            except ValueError as exc:
                print(f"{b.name}: no length ratio ({exc})")
                continue
            ok = np.isfinite(r)
            if not ok.any():
                print(f"{b.name}: no pulse inside {ref.name}'s tau_d range")
                continue
            short = ok & (r < 1)
            print(f"{b.name}: L / L({ref.name}) at equal tau_d = {np.nanmin(r):.4g}-"
                  f"{np.nanmax(r):.4g} over {int(ok.sum())} pulses"
                  + (f"; below 1 at tau_d/tau_min = "
                     + ", ".join(f"{q:.5f} ({x:.4f})" for q, x in zip(b.q[short], r[short]))
                     if short.any() else f"; longer than {ref.name} at every one"))
    print(f"figure: {args.out}")
    return 0


def register(ss) -> None:
    """Add ``branch-map`` to the ``slippulse steady`` sub-commands ``ss``."""
    p = ss.add_parser("branch-map", help="all branches in (tau_d/tau_min, L), coloured by their "
                                         "number of unstable modes",
                      description="One line per FILE (A.h5+B.h5: one branch from two files; a "
                                  "branch: its pulses in trace order, or by "
                                  "decreasing tau_d), log L against tau_d/tau_min; each pulse "
                                  "with a stored spectrum is marked in the colour of its number "
                                  "of unstable eigenvalues: filled where counted by the argument "
                                  "principle (steady stability --count), hollow where only the "
                                  "eigen-search's (a lower bound). Prints per branch what was "
                                  "counted and, for each FILE after the first, its L over the "
                                  "first's at equal tau_d (the first: a single-valued family).")
    p.add_argument("files", metavar="FILE", nargs="+",
                   help="HDF5 pulse files, one per branch (A.h5+B.h5: two files as one branch)")
    p.add_argument("--out", required=True, metavar="PNG", help="the figure")
    p.add_argument("--names", nargs="+", default=None, metavar="NAME",
                   help="the branches' names in the legend (default: the file names)")
    p.add_argument("--title", default=None, help="a title")
    p.add_argument("--zoom", nargs=2, type=float, default=None, metavar=("Q0", "Q1"),
                   help="a second panel with tau_d/tau_min in [Q0, Q1] (1 < Q0 < Q1), where "
                        "branches crowd")
    p.set_defaults(func=cmd_branch_map)
