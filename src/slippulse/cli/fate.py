"""``slippulse dynamic fate``: run an eigenmode-seeded pulse under the uniform load until its fate
(arrested, grew xG, near c_s, crack-like) and store the trajectory (timedomain/fate.py,
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
    finite(args.backward, "--backward", 0.0, 1.0, lo_open=False, unit="c_s")
    rule = FateRule(arrest=args.arrest, growth=args.growth, backward=args.backward)
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


def _profiles_title(r):
    """The profiles figure's title: the run, its fate, and L at the last sample; an undecided
    fate is named as what it is, a run stopped at its planned distance."""
    fate = r["fate"]
    if fate == "undecided":
        fate = "stopped at its --distance before any fate rule held"
    grown = float(r["L"][-1]) / float(r["L0"])
    return (f"{r['tau_d_ratio']:.4g} tau_min, eps = {r['eps']:+.0e}: {fate} "
            f"(L = {grown:.3g} L0 at the last sample)")


def register(sub) -> None:
    """Add ``fate`` to the ``dynamic`` sub-commands."""
    p = sub.add_parser("fate", help="run an eigenmode-seeded pulse under uniform load to its fate",
                       description="Seed the steady pulse LABEL of FILE with eps x its stored "
                                   "unstable eigenmode (and the mode's growing past), load it "
                                   "with tau_d at infinity, follow it and "
                                   "stop at its fate: arrested (v_max < v_max0/ARREST), grew xGROWTH "
                                   "(L > GROWTH L0), near c_s (c_p > 0.99 c_s), crack-like (the "
                                   "rear half-maximum edge runs backward, or the FWHM no longer "
                                   "closes behind a growing peak), or undecided "
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
    p.add_argument("--backward", type=float, default=0.1,
                   help="crack-like when the rear half-maximum edge runs backward faster than "
                        "BACKWARD c_s with v_max > v_max0 (default 0.1; 0: off)")
    p.add_argument("--arrest", type=float, default=10.0,
                   help="arrested when v_max < v_max0/ARREST (10)")
    p.add_argument("--samples-per-L", type=int, default=200,
                   help="measurements per pulse length of run time (default 200)")
    p.add_argument("--out", default=None, help="output HDF5 (default fate_<label>_eps<eps>.h5)")
    p.add_argument("--overwrite", action="store_true", help="replace --out if it exists")
    p.add_argument("--no-progress", action="store_true", help="no progress bar")
    p.set_defaults(func=cmd_fate)


def _row(r, line, c) -> str:
    """One markdown row: the run's description, its fate, and the model from the same L."""
    import math

    import numpy as np
    head = (f"| {r['tau_d_ratio']:.4g} | {r['eps']:+.0e} | {r.get('perturbation', '–')} | "
            f"{r['ahead']:g}+{r['behind']:g} | {r['far_field']} | {r['fate']} | "
            f"{r.get('distance_fate', math.nan):.3g} | ")
    if isinstance(c, str):
        return head + f"– | – | – | model not run: {c} | – | – | – |"
    cp = c.c_p[np.isfinite(c.c_p)]
    d = c.line_distance[np.isfinite(c.line_distance)]
    from ..timedomain.motion import smoothed_speed
    with np.errstate(invalid="ignore", divide="ignore"):
        q = smoothed_speed(c.t, c.L) / c.c_p              # dL/dt over c_p: measured
        qm = smoothed_speed(c.t, c.model.L) / c.model.c_p  # and in the model from the same L
    q, qm = q[c.skip:], qm[c.skip:]

    def span(a):
        a = a[np.isfinite(a)]
        return f"{a.min():.2g}–{a.max():.2g}" if a.size else "–"
    return head + (f"{np.nanmin(c.L):.4g}–{np.nanmax(c.L):.4g} | "
                   f"{cp.min() / line.c_s:.3g}–{cp.max() / line.c_s:.3g} | "
                   f"{c.x[c.skip] / c.L[0]:.3g} | {c.model.fate} | {c.distance_split_L:.3g}, "
                   f"{c.distance_split_c:.3g} | "
                   f"{np.median(np.abs(d)) if d.size else math.nan:.3g} | {span(q)}; {span(qm)} |")


def cmd_fate_compare(args) -> int:
    """The fate runs against the equation of motion along the family's steady line: a table, the
    (L, c_p) figure, and with --law the time to the fate against ln|eps| beside -1/s."""
    import math

    import numpy as np
    from ..plotting.motion import motion_figure
    from ..timedomain.fate import departure_time, read_fate, time_law, time_law_offset
    from ..timedomain.motion import compare
    from .motion import steady_line
    start = finite(args.start, "--start", lo=0.0, unit="of L*")
    check_writable(args.figure, "FIGURE")
    if args.profiles:
        check_writable(args.profiles, "--profiles")
    line = steady_line(args.family, args.records)
    runs = [read_fate(p) for p in args.runs]
    law = [read_fate(p) for p in args.law]
    if law and len(law) < 3:
        raise UsageError(f"--law needs at least 3 runs; got {len(law)}")
    print("| tau_d/tau_min | eps | seed | domain (L) | far field | SBI fate | after (L0) | "
          "L range (m) | c_p/c_s range | model from (L0) | model fate | 5 % split after (L0): "
          "L, c_p | median abs(c_p/c_p0(L) - 1) | dL/dt / c_p from there: SBI; model |")
    print("|---|---|---|---|---|---|---|---|---|---|---|---|---|---|")
    cmps = {}
    for r in runs:
        try:
            c = compare(line, float(r["tau_d_ratio"]), r["t"], r["x_front"], r["L"], start=start)
        except ValueError as exc:
            c = str(exc)
        else:
            cmps[f"{r['tau_d_ratio']:.2f} eps={r['eps']:+.0e} {r.get('perturbation', '')} "
                 f"({r['ahead']:g}+{r['behind']:g} L, {r['far_field']})"] = c
        print(_row(r, line, c))
    if law:
        s = float(line.functions()[3](line.equilibrium(float(law[0]["tau_d_ratio"]))))
        fates = [r["fate"] for r in law]
        main_fate = max(set(fates), key=fates.count)      # the plain law: runs of one fate
        same = [r for r in law if r["fate"] == main_fate]
        if len(same) >= 3:
            A, B, E = time_law([r["eps"] for r in same], [r["t_fate"] for r in same])
            print(f"time to fate ({main_fate}) at {law[0]['tau_d_ratio']:.4g} tau_min, eps = "
                  f"{', '.join(format(r['eps'], '+.0e') for r in same)}: t = {A:.4g} + ({B:.4g} ± "
                  f"{E:.1g}) ln|eps| s; -1/s = {-1 / s:.4g} s (b s = {B * s:.3f} ± {E * s:.2g})")
        else:
            print(f"time to fate: fewer than 3 runs share a fate ({', '.join(fates)}); no plain law")
        # the linear stage alone: the time to a departure of --start from the steady L, for
        # runs of either fate, with the seed's own projection eps0 on the mode fitted
        dep = np.array([departure_time(r["t"], r["L"], float(r["L0"]), start) for r in law])
        e = np.array([r["eps"] for r in law])
        ok = np.isfinite(dep)
        rest = np.array([r["t_fate"] for r in law]) - dep
        print(f"time to |L/L0 - 1| = {start:g} (the linear stage), eps = "
              + ", ".join(f"{x:+.0e} ({r['fate']}, {d * 1e3:.4g} ms)" for x, r, d in zip(e, law, dep))
              + "; from there to the fate: " + ", ".join(f"{x * 1e3:.4g}" for x in rest) + " ms")
        for fixed in (s, None):
            try:
                f = time_law_offset(e[ok], dep[ok], fixed)
            except ValueError as exc:
                print(f"offset law ({'s fixed' if fixed else 's free'}): not fitted ({exc})")
                continue
            print(f"t_dep = a - ln|eps + eps0|/s' ({'s fixed at the eigenvalue' if fixed else 's free'}"
                  f"): eps0 = {f['eps0']:.3g} ± {f['eps0_err']:.1g}"
                  + (f", b s = -s/s' = {-s / f['rate']:.3f} ± "
                     f"{s * f['rate_err'] / f['rate'] ** 2:.2g}" if not fixed else "")
                  + f", rms {f['rms'] * 1e3:.3g} ms")
    motion_figure(args.figure, line, cmps, title="fate runs (SBI, load tau_d at infinity) and "
                                                 "the equation of motion from the same L")
    if args.profiles:
        from ..core.params import DEFAULT
        from ..plotting.motion import profiles_figure
        r = runs[0]
        profiles_figure(args.profiles, r, DEFAULT.v_star, line.c_s,
                        title=_profiles_title(r))
        print(f"profiles of {r['path']} -> {args.profiles}")
    print(f"{len(cmps)} of {len(runs)} runs against the model -> {args.figure}")
    return 0


def register_compare(sub) -> None:
    """Add ``fate-compare`` to the ``dynamic`` sub-commands."""
    p = sub.add_parser("fate-compare", help="fate runs against the equation of motion: table, figure",
                       description="Each fate run (`slippulse dynamic fate`) against the equation "
                                   "of motion along the steady line of --family (with stored "
                                   "growth rates), started where the measured L first departs "
                                   "from L* by --start: a markdown table (how far L and c_p stay "
                                   "within 5 % of the model) and the (L, c_p) figure "
                                   "(docs/motion.md).")
    p.add_argument("figure", metavar="FIGURE", help="output PNG")
    p.add_argument("--family", nargs="+", required=True, metavar="FILE",
                   help="HDF5 family file(s) with stored spectra, or the family's CSV tables "
                        "with --records")
    p.add_argument("--records", default=None, metavar="TOML",
                   help="with CSV tables as --family (steady/seeds/deep_family_*.csv): the "
                        "growth rates of record (e.g. docs/results/records.toml)")
    p.add_argument("--runs", nargs="+", required=True, metavar="FATE.h5", help="fate runs")
    p.add_argument("--profiles", default=None, metavar="PNG",
                   help="also draw the first run's slip-rate snapshots and its front and rear "
                        "edges in the lab frame (Table I's v*)")
    p.add_argument("--start", type=float, default=0.01,
                   help="start the model where L first departs from L* by this (default 0.01)")
    p.add_argument("--law", nargs="+", default=(), metavar="FATE.h5",
                   help="runs of one pulse at >= 3 eps: fit t_fate = a + b ln|eps| (b vs -1/s)")
    p.set_defaults(func=cmd_fate_compare)
