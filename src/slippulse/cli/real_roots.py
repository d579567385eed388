"""``slippulse steady real-roots``: the real eigenvalues of stored pulses on an interval, by the
sign of det M(σ) on each pulse's own grid (:func:`slippulse.spectrum.eigensolve.real_eigenvalues`;
docs/branches.md §4)."""
from __future__ import annotations

import time

from ..core.errors import UsageError
from .checks import finite, plural
from .paramargs import add_params_args, check_files

#: Most scan points per pulse (one det M each; 1–7 s at N = 3311–5000 on one core).
MAX_SCAN = 400


def cmd_real_roots(args) -> int:
    from ..spectrum.eigensolve import real_eigenvalues
    from ..spectrum.family import check_family_file
    from ..spectrum.pulse import StabilityOperator, order4_pulse
    from ..core.h5io import read_pulse

    lo, hi = (finite(v, "--between", lo=0.0) for v in args.between)
    if not hi > lo:
        raise UsageError(f"--between={args.between!r} is invalid: need 0 < LO < HI (units of "
                         "c_p/L)")
    if not (isinstance(args.scan, int) and 2 <= args.scan <= MAX_SCAN):
        raise UsageError(f"--scan={args.scan!r} is invalid: must be an integer in [2, "
                         f"{MAX_SCAN}] (scan points on [LO, HI])")
    finite(args.xtol, "--xtol", lo=0.0, hi=1e-2, unit="c_p/L")
    chosen, _ = check_family_file(args.file, args.labels)
    check_files(args, [args.file])
    found = 0
    for label in chosen:
        t0 = time.perf_counter()
        pulse, params = read_pulse(args.file, label)
        op = StabilityOperator(order4_pulse(pulse, params), params, pin_translation=True)
        unit = op.rate_unit
        b = real_eigenvalues(op, lo * unit, hi * unit, n_scan=args.scan, xtol=args.xtol)
        roots = [r / unit for r in b.roots]
        found += len(roots)
        signs = "".join("+" if s > 0 else "-" for s in b.signs)
        print(f"{label} (tau_d/tau_min={pulse.tau_d_ratio:.6f}, N={pulse.n_points}): "
              f"{plural(len(roots), 'real eigenvalue')} on [{lo:g}, {hi:g}] c_p/L"
              + (": " + ", ".join(f"{r:.6g}" for r in roots) if roots else "")
              + f"; det M signs at the scan points {signs}; {b.evaluations} det, "
              f"{time.perf_counter() - t0:.0f} s", flush=True)
    print(f"real-roots {args.file}: {plural(len(chosen), 'pulse')}, "
          f"{plural(found, 'real eigenvalue')} on [{lo:g}, {hi:g}] c_p/L, each to "
          f"{args.xtol:g} c_p/L on its pulse's own grid (no grid-error estimate: compare two "
          "grids); an even number between two scan points and every complex pair are not seen")
    return 0


def register(ss) -> None:
    p = ss.add_parser("real-roots", help="real eigenvalues of stored pulses on an interval",
                      description="The real eigenvalues sigma L/c_p in [LO, HI] of each pulse "
                                  "that a sign change of det M(sigma) shows on a geometric scan "
                                  "of --scan points, each refined by Brent's method, on the "
                                  "pulse's own grid with the translation mode pinned "
                                  "(docs/branches.md section 4). The fold rule's check: across "
                                  "a fold the sign of det M near 0+ changes, and the "
                                  "eigenvalue that crosses heads for zero.")
    p.add_argument("file", metavar="FILE", help="HDF5 pulse or family file")
    p.add_argument("--labels", nargs="+", default=None, metavar="LABEL",
                   help="pulses (default: all converged)")
    p.add_argument("--between", type=float, nargs=2, required=True, metavar=("LO", "HI"),
                   help="the interval, in c_p/L, 0 < LO < HI")
    p.add_argument("--scan", type=int, default=24,
                   help=f"scan points, geometric on [LO, HI] (default 24, at most {MAX_SCAN})")
    p.add_argument("--xtol", type=float, default=1e-6, metavar="X",
                   help="Brent's tolerance on each root, c_p/L (default 1e-6)")
    add_params_args(p)
    p.set_defaults(func=cmd_real_roots)
