"""``slippulse steady seed``: the seed file and family table of a deep march
(:mod:`slippulse.steady.seed`)."""
from __future__ import annotations

from ..core.errors import UsageError


def cmd_seed(args) -> int:
    from ..core.h5io import check_writable
    from ..steady.seed import write_seed, write_table

    if args.keep < 1:
        raise UsageError(f"--keep={args.keep!r} is invalid: must be an integer >= 1")
    if args.table:
        check_writable(args.table, "--table")
    try:
        deepest = write_seed(args.family, args.seed, args.keep)
    except ValueError as exc:
        raise UsageError(f"SEED/FAMILY: {exc}") from None
    n = write_table(args.family, args.table) if args.table else None
    p = deepest[0]
    print(f"seed {args.seed}: {len(deepest)} pulses, deepest {p.label} (L = {p.L:.1f} m, beta = "
          f"{p.beta:.7f}, tau_d/tau_min = {p.tau_d_ratio:.7f}); copied, no new numbers"
          + (f"; table {args.table}: {n} pulses" if args.table else ""))
    return 0


def register(ss) -> None:
    p = ss.add_parser("seed", help="copy the deepest pulses of a family into a seed file",
                      description="Copies the --keep deepest converged pulses of FAMILY into the "
                                  "new file SEED: `slippulse steady family --out` a copy of SEED "
                                  "goes on from there (pace, secant predictor and held steps "
                                  "included). --table writes every pulse of FAMILY as a CSV row "
                                  "(label, tau_d_ratio, beta, L, n_points and the grid check), "
                                  "which `steady divergence --table` reads.")
    p.add_argument("family", metavar="FAMILY", help="HDF5 family file")
    p.add_argument("seed", metavar="SEED", help="new HDF5 file for the seed")
    p.add_argument("--keep", type=int, default=2, help="deepest converged pulses (default 2)")
    p.add_argument("--table", default=None, metavar="CSV", help="also table every pulse")
    p.set_defaults(func=cmd_seed)
