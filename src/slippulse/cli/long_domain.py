"""``slippulse steady long-domain``: a pulse re-solved on a longer domain (paper Fig. S1b;
:func:`slippulse.steady.solver.resolve_on_longer_domain`)."""
from __future__ import annotations

from ..core.errors import UsageError


def cmd_long_domain(args) -> int:
    import os

    from ..core.h5io import list_pulses, read_pulse, write_pulse
    from ..steady.solver import resolve_on_extended_domain, resolve_on_longer_domain
    from .checks import finite

    finite(args.factor, "--factor", lo=1.0, hi=1000.0, lo_open=False)
    labels = list_pulses(args.file)
    if args.label not in labels:
        raise UsageError(f"--label={args.label!r} is invalid: not in {args.file!r} (labels "
                         f"{', '.join(labels[:6])}{' ...' if len(labels) > 6 else ''})")
    out = args.out or os.path.join(os.path.dirname(os.path.abspath(args.file)),
                                   f"long_domain_{args.label}.h5")
    pulse, params = read_pulse(args.file, args.label)
    how = ""
    if args.side == "both":
        long = resolve_on_longer_domain(params, pulse, args.factor).to_pulse()
    else:
        long = resolve_on_extended_domain(params, pulse, **{args.side: args.factor}).to_pulse()
        if not long.converged:
            long = _on_normal_line(params, pulse, long.xi)
            how = (f"; at fixed tau_d Newton did not converge, so on the line normal to the "
                   f"family (tau_d/tau_min {pulse.tau_d_ratio:.9f} -> {long.tau_d_ratio:.9f})")
    long.extra["domain_factor"] = args.factor
    long.extra["domain_side"] = args.side
    if not long.converged:
        print(f"long-domain {args.label}: NOT CONVERGED on the {args.factor:g}x domain "
              f"({args.side}) "
              f"(max|D| = {long.max_residual:.2e}); nothing written")
        return 1
    write_pulse(out, long, params)
    print(f"long-domain {args.label}: domain ({pulse.xi[0]:.4g}, {pulse.xi[-1]:.4g}) m -> "
          f"({long.xi[0]:.4g}, {long.xi[-1]:.4g}) m, N {pulse.n_points} -> {long.n_points}; "
          f"beta {pulse.beta:.8f} -> {long.beta:.8f}, L {pulse.L:.6f} -> {long.L:.6f} m "
          f"(the differences are the domain's effect plus the two grids' discretisation "
          f"errors, no separate error estimate){how}; wrote {out}")
    return 0


def _on_normal_line(params, pulse, xi_new):
    """``pulse`` re-solved on ``xi_new`` (its grid extended) on the line normal to its family
    (:func:`~slippulse.steady.continuation.gridcheck.resolve_on_normal_line`), as a Pulse."""
    from ..steady.bifurcation import pulse_solution
    from ..steady.continuation.gridcheck import resolve_on_normal_line
    return resolve_on_normal_line(params, pulse_solution(pulse, params), xi_new).to_pulse()


def register(ss) -> None:
    p = ss.add_parser("long-domain", help="re-solve one pulse on a much longer domain (Fig. S1b)",
                      description="Solves pulse --label of FILE again on a domain --factor times "
                                  "longer ahead and behind (N grown by 1 + 0.1 ln factor) and "
                                  "writes it to --out; with --side ahead or behind, on its own "
                                  "grid extended on that side only (the distance from the "
                                  "leading edge to that end times --factor, every node kept: "
                                  "a domain check at unchanged near-field resolution, e.g. for "
                                  "`slippulse steady stability`); "
                                  "`slippulse figures FILE --compare OUT` "
                                  "overlays the two (paper Fig. S1b). A solve that does not "
                                  "converge writes nothing (exit 1).")
    p.add_argument("file", metavar="FILE", help="HDF5 family file")
    p.add_argument("--label", default="td1.0500", help="pulse label (default td1.0500)")
    p.add_argument("--factor", type=float, default=40.0,
                   help="domain length factor, in [1, 1000] (default 40)")
    p.add_argument("--side", choices=("both", "ahead", "behind"), default="both",
                   help="both (default): a grid re-adapted to the longer domain; ahead or "
                        "behind: the pulse's own grid extended on that side only")
    p.add_argument("--out", default=None,
                   help="output HDF5 (default: long_domain_LABEL.h5 beside FILE)")
    p.set_defaults(func=cmd_long_domain)
