"""``slippulse steady existence-map``: where steady pulses exist, and where the solver finds them,
over a grid of (b, α) (:mod:`slippulse.steady.existence_map`), on the shared executor."""
from __future__ import annotations

import math
import os
import sys

from ..core.errors import UsageError
from ..core.executor import add_executor_options, progress_bar, settings_from_args
from .paramargs import add_params_args, params_for_output

#: The default grid: 7 x 7 around Table I (b = 0.075, α = 0.005).
DEFAULT_B = [0.04, 0.055, 0.075, 0.1, 0.14, 0.2, 0.28]
DEFAULT_ALPHA = [0.00125, 0.0025, 0.005, 0.0075, 0.01, 0.015, 0.02]


def register(ss) -> None:
    """Add ``existence-map`` to the ``slippulse steady`` sub-commands ``ss``."""
    p = ss.add_parser("existence-map", help="where pulses exist and are found over (b, alpha)",
                      description="Classify each (b, alpha) of a grid at fixed tau_d/tau_min: "
                                  "N shape of tau_ss, a solve from the built-in guess, a solve "
                                  "by continuation from a solved neighbour. Writes OUT (HDF5, "
                                  "xarray) and, with --figure, the chart. Each solve is kept in "
                                  "OUT.partial.json as it finishes: a rerun after a kill goes on "
                                  "from there.")
    p.add_argument("--b", type=float, nargs="+", default=DEFAULT_B, metavar="B",
                   help="values of the state coefficient b (default: 7 around Table I)")
    p.add_argument("--alpha", type=float, nargs="+", default=DEFAULT_ALPHA, metavar="ALPHA",
                   help="values of the rate coefficient alpha (default: 7 around Table I)")
    p.add_argument("--tau-d", type=float, default=1.2, metavar="RATIO",
                   help="tau_d/tau_min of every point (default 1.2)")
    p.add_argument("--points", type=int, default=500, metavar="N",
                   help="grid points of every solve (default 500)")
    p.add_argument("--out", default="existence_map.h5", help="output HDF5 file")
    p.add_argument("--figure", default=None, metavar="PNG", help="also draw the map")
    p.add_argument("-q", "--quiet", action="store_true", help="no progress bar")
    add_executor_options(p, "independent solves")
    add_params_args(p)
    p.set_defaults(func=cmd_existence_map)


def cmd_existence_map(args) -> int:
    from ..steady.existence_map import existence_map, summary, write_map
    from .checks import check_figure
    from ..core.h5io import check_writable
    for name, vals in (("b", args.b), ("alpha", args.alpha)):
        if not all(math.isfinite(v) and v > 0 for v in vals):
            raise UsageError(f"--{name}={vals!r} is invalid: every value must be a number > 0")
    if not (math.isfinite(args.tau_d) and 1.0 < args.tau_d < 10.0):
        raise UsageError(f"--tau-d={args.tau_d!r} is invalid: must be in (1, 10)")
    if not 100 <= args.points <= 8000:
        raise UsageError(f"--points={args.points!r} is invalid: must be an integer in "
                         "[100, 8000]")
    executor = settings_from_args(args)
    params = params_for_output(args)
    check_writable(args.out, "--out")
    if args.figure:
        check_figure(args.figure, "--figure")
    bar = progress_bar(None, "existence map", "solve", disable=args.quiet)

    def progress(msg):
        bar.update(1)
        bar.set_postfix_str(msg[:50], refresh=False)

    try:
        m = existence_map(args.b, args.alpha, args.tau_d, base=params, n_points=args.points,
                          progress=progress, executor=executor,
                          checkpoint=args.out + ".partial.json")
    finally:
        bar.close()
    write_map(args.out, m)
    if os.path.exists(args.out + ".partial.json"):
        os.remove(args.out + ".partial.json")
    if args.figure:
        from ..plotting.existence_map import plot_existence_map
        plot_existence_map(m, args.figure)
        print(f"figure: {args.figure}")
    print(summary(m) + f"; wrote {args.out}", file=sys.stdout)
    return 0
