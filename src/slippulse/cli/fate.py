"""``slippulse dynamic fate``: run an eigenmode-seeded pulse under the uniform load until its fate
(arrested, grew x3, near c_s, crack-like) and store the trajectory (timedomain/fate.py,
docs/motion.md)."""
from __future__ import annotations

import os

from ..core.errors import UsageError
from ..core.h5io import check_writable
from .checks import finite


def cmd_fate(args) -> int:
    from ..core.h5io import SchemaError, read_pulse, require_converged
    from ..core.params import ParameterError
    from ..timedomain.eigenmode import SpectrumError, check_eps, leading_mode
    from ..timedomain.fate import FateRule, run_fate, summary, write_fate
    from ..timedomain.seeding import DomainSpec, default_dx
    from ..dynamics.stepper import MAX_GRID_POINTS

    try:
        pulse, params = read_pulse(args.steady, args.label)
    except SchemaError as exc:
        raise UsageError(str(exc))
    require_converged(args.steady, [pulse.label])
    out = args.out or f"fate_{pulse.label}_eps{args.eps:+.0e}.h5"
    if os.path.exists(out) and not args.overwrite:
        raise UsageError(f"--out={out!r} exists: use --overwrite or another --out")
    check_writable(out, "--out")
    finite(args.distance, "--distance", 0.0, 1e4, unit="pulse lengths")
    finite(args.growth, "--growth", 1.0)
    finite(args.arrest, "--arrest", 1.0)
    dx = default_dx(params) if args.dx is None else args.dx
    for name, val in (("--dx", dx), ("--ahead", args.ahead), ("--behind", args.behind)):
        finite(val, name, 0.0)
    n = (args.ahead + args.behind) * pulse.L / dx
    if n > MAX_GRID_POINTS:
        raise UsageError(f"--dx={dx:g} gives {n:.0f} points over {args.ahead:g}+{args.behind:g} "
                         f"L; at most {MAX_GRID_POINTS}")
    if not 1 <= args.samples_per_L <= 10_000:
        raise UsageError(f"--samples-per-L={args.samples_per_L} must be in [1, 10000]")
    try:
        check_eps(args.eps)
        eigen = leading_mode(pulse, params, path=args.steady, compute=False)
    except (SpectrumError, ParameterError) as exc:
        raise UsageError(str(exc))
    rule = FateRule(arrest=args.arrest, growth=args.growth)
    try:
        fr = run_fate(pulse, params, eigen, args.eps,
                      DomainSpec(dx=dx, ahead=args.ahead, behind=args.behind), args.distance,
                      rule=rule, samples_per_L=args.samples_per_L,
                      progress=not args.no_progress, far_field=args.far_field,
                      frame=args.frame)
    except ParameterError as exc:
        raise UsageError(str(exc))
    write_fate(out, fr, params, source=os.path.abspath(args.steady), label=pulse.label)
    print(summary(fr) + f"; output {out}")
    return 0 if not fr.fate.startswith("failed") else 1


def register(sub) -> None:
    """Add ``fate`` to the ``dynamic`` sub-commands."""
    p = sub.add_parser("fate", help="run an eigenmode-seeded pulse under uniform load to its fate",
                       description="Seed the steady pulse LABEL of FILE with eps x its stored "
                                   "unstable eigenmode (and the mode's growing past), load it "
                                   "with tau_d at infinity, follow it and "
                                   "stop at its fate: arrested (v_max < v_max0/ARREST), grew x3 "
                                   "(L > GROWTH L0), near c_s (c_p > 0.99 c_s), crack-like (the "
                                   "FWHM no longer closes behind a growing peak), or undecided "
                                   "after DISTANCE pulse lengths. Writes the trajectory, the fate "
                                   "and the time to it (verify layout + fate attributes).")
    p.add_argument("--steady", required=True, metavar="FILE",
                   help="family file with the pulse's stored spectrum")
    p.add_argument("--label", default=None, help="pulse, e.g. td1.2000")
    p.add_argument("--eps", type=float, required=True,
                   help="mode amplitude (largest change of ln(v/v*+1)), 0 < |eps| <= 0.01")
    p.add_argument("--distance", type=float, default=20.0,
                   help="largest distance to run, in pulse lengths (default 20)")
    p.add_argument("--dx", type=float, default=None,
                   help="grid spacing, m (default 2.26e-3 L0: 2e-3 for Table I)")
    p.add_argument("--ahead", type=float, default=4.0, help="domain ahead of the front, in L (4)")
    p.add_argument("--behind", type=float, default=4.0, help="domain behind the front, in L (4)")
    p.add_argument("--far-field", choices=("steady", "none"), default="steady",
                   help="steady (default): the steady pulse's images on the period removed and "
                        "its tail beyond the window added, static in the frame of the front "
                        "(docs/dynamic.md section 3); none: the uniform tau_d on the periodic "
                        "domain, the pulse's images left in (at 1.2 tau_min they decide the "
                        "fate on a 5-10 L period: docs/motion.md)")
    p.add_argument("--frame", choices=("front", "lab"), default="front",
                   help="front (default): eps is the mode's largest change of ln(v/v*+1) in the "
                        "frame of the front (perturbation mode_front); lab: at fixed xi (mode), "
                        "where the front's displacement takes eps and the body gets far less "
                        "(docs/stability.md section 2)")
    p.add_argument("--growth", type=float, default=3.0, help="grew when L > GROWTH L0 (3)")
    p.add_argument("--arrest", type=float, default=10.0,
                   help="arrested when v_max < v_max0/ARREST (10)")
    p.add_argument("--samples-per-L", type=int, default=200,
                   help="measurements per pulse length of run time (default 200)")
    p.add_argument("--out", default=None, help="output HDF5 (default fate_<label>_eps<eps>.h5)")
    p.add_argument("--overwrite", action="store_true", help="replace --out if it exists")
    p.add_argument("--no-progress", action="store_true", help="no progress bar")
    p.set_defaults(func=cmd_fate)
