"""``slippulse steady divergence`` and ``steady edges``: τ̃* and the local exponents of a deep
family (:mod:`slippulse.steady.divergence`), and its edges against L (:mod:`slippulse.steady.edges`)."""
from __future__ import annotations

from ..core.errors import UsageError
from ..core.params import DEFAULT
from ..steady import divergence as dv
from .checks import check_figure

#: Lengths (m) at which the summary quotes the local exponents (the nearest inner pulse).
QUOTE_L = (1000.0, 2000.0, 5000.0, 10000.0)


def cmd_divergence(args) -> int:
    if not args.file and not args.table:
        raise UsageError("FILE: give at least one family file or --table CSV")
    for opt, path in (("--figure", args.figure), ("--exponents-figure", args.exponents_figure)):
        if path:
            check_figure(path, opt)
    params = DEFAULT
    pts = dv.read_points(args.file, args.table)
    print(f"{len(pts)} pulses; deepest tau_d/tau_min = {pts.q.min():.7f} "
          f"(beta = {pts.beta[pts.q.argmin()]:.7f}, L = {pts.L[pts.q.argmin()]:.6g} m)")
    print("window study (power laws in d = tau_d/tau_min - tau_star: joint, L alone, "
          "1 - beta alone; the paper's Eqs. 3-4 refitted):")
    study = dv.window_study(pts, params)
    for name, fits in study:
        for key in ("both", "L", "beta", "eqs34"):
            print(f"  {name} [{key}]: {dv.fit_text(fits[key])}")
    try:
        dec = dv.deepest_decade(pts, params)
    except ValueError as exc:
        dec = None
        print(f"deepest decade: {exc}")
    loc = None
    if dec is not None:
        f = dec["fits"]
        print(f"deepest decade of L ({dec['L_lo']:.4g}-{dec['L_hi']:.4g} m, {dec['n']} pulses):")
        for key in ("both", "L", "beta"):
            print(f"  power laws [{key}]: {dv.fit_text(f[key])}")
        print(f"  Eqs. 3-4 [L >= {dv.EQS34_L_MIN:g} m]: {dv.fit_text(f['eqs34'])}")
        loc = dv.local_exponents(pts, f["both"]["tau_star"])
        print(f"local exponents (centred differences; tau_star = {f['both']['tau_star']:.5f}):")
        last = -1.0
        for k in range(loc["L"].size):
            if loc["L"][k] >= dec["L_lo"] and loc["L"][k] >= 1.15 * last:
                last = loc["L"][k]
                print(f"  L = {loc['L'][k]:.4g} m  tau_d/tau_min = {loc['q'][k]:.7f}  "
                      f"dlnL/dln(1-beta) = {loc['r'][k]:.3f}  "
                      f"dln(1-beta)/dlnL = {1.0 / loc['r'][k]:.4f}  "
                      f"dlnL/dln d = {loc['m'][k]:.3f}  -dq/dlnL = {loc['s'][k]:.2e}")
    if args.figure:
        from ..plotting.divergence import plot_divergence
        name = f"L >= {dv.L_MIN[0]:g} m"
        fit = dict(study)[name]["both"]
        if isinstance(fit, str):
            raise UsageError(f"--figure: no joint fit on {name} ({fit})")
        plot_divergence(pts, fit, params, args.figure, name.replace(">=", "≥"))
        print(f"figure: {args.figure}")
    if args.exponents_figure:
        if loc is None:
            raise UsageError("--exponents-figure: no deepest-decade fit to take tau_star from")
        from ..plotting.divergence import plot_local_exponents
        plot_local_exponents(pts, loc, dec["fits"]["both"]["tau_star"], args.exponents_figure)
        print(f"figure: {args.exponents_figure}")
    src = " ".join(list(args.file) + list(args.table))
    if dec is None:
        print(f"divergence {src}: {len(pts)} pulses; no tau_star: too few pulses in the deepest "
              "decade of L (no uncertainty to state)")
        return 0
    f = dec["fits"]
    quoted = []
    for Lq in QUOTE_L:
        if loc["L"].size and dec["L_lo"] <= Lq <= 1.05 * dec["L_hi"]:
            r, Lr = dv.nearest(loc, Lq, "r")
            m, _ = dv.nearest(loc, Lq, "m")
            quoted.append(f"{r:.3f}/{m:.3f} at {Lr:.4g} m")
    print(f"divergence {src}: {len(pts)} pulses, deepest decade {dec['L_lo']:.4g}-"
          f"{dec['L_hi']:.4g} m ({dec['n']}); tau_star = {dec['tau_star']:.4f} ± "
          f"{dec['tau_star_err']:.4f} (centre and half-spread of the joint "
          f"{f['both']['tau_star']:.5f} ± {f['both']['tau_star_err']:.5f}, L-alone "
          f"{f['L']['tau_star']:.5f} and 1-beta-alone {f['beta']['tau_star']:.5f} fits: no single "
          "power law holds, the spread is the uncertainty); below the deepest pulse: tau_star < "
          f"{pts.q.min():.7f}; local exponents dlnL/dln(1-beta) / dlnL/dln d: "
          + (", ".join(quoted) if quoted else "none quoted"))
    return 0


def cmd_edges(args) -> int:
    import math

    from ..core.h5io import list_pulses, read_pulse
    from ..steady.edges import edge_study

    for opt, path in (("--figure", args.figure), ("--profiles-figure", args.profiles_figure)):
        if path:
            check_figure(path, opt)
    pulses, params = [], DEFAULT
    for fn in args.file:
        for lab in list_pulses(fn):
            pu, params = read_pulse(fn, lab)
            if pu.converged:
                pulses.append(pu)
    try:
        rows = edge_study(pulses, params)
    except ValueError as exc:
        raise UsageError(f"FILE: {exc}") from None
    print("tau_d/tau_min N L/m sqrt(1-b^2) v_max*sqrt(1-b^2) tau_max/tau_min ell/sqrt(1-b^2)/mm "
          "front_efold/sqrt(1-b^2)/mm back_efold/m tau_back_min/tau_min heal_width/m "
          "G(2um) G(5um) G(20um) G_max (J/m^2) front_dist back_dist")
    for p, e in rows:
        g = math.sqrt(1 - p.beta ** 2)
        print(f"{p.tau_d_ratio:.5f} {p.n_points} {p.L:.4g} {g:.4f} {e['v_max'] * g:.4f} "
              f"{e['tau_max'] / params.tau_min:.5f} {1e3 * e['ell'] / g:.4g} "
              f"{1e3 * e['front_efold'] / g:.4g} {e['back_efold']:.4g} "
              f"{e['tau_back_min'] / params.tau_min:.5f} {e['heal_width']:.4g} "
              f"{e['G'][0]:.4g} {e['G'][1]:.4g} {e['G'][2]:.4g} {e['G_max']:.4g} "
              f"{e['front_dist']:.3f} {e['back_dist']:.3f}")
    if args.figure:
        from ..plotting.divergence import plot_edges
        plot_edges(rows, params, args.figure)
        print(f"figure: {args.figure}")
    if args.profiles_figure:
        from ..plotting.divergence import plot_edge_profiles
        plot_edge_profiles(rows, args.profiles_figure)
        print(f"figure: {args.profiles_figure}")
    p, e = rows[-1]
    g = math.sqrt(1 - p.beta ** 2)
    print(f"edges {' '.join(args.file)}: {len(rows)} pulses, L = {rows[0][1]['L']:.4g}-"
          f"{e['L']:.4g} m; at the longest: leading width ell/sqrt(1-beta^2) = "
          f"{1e3 * e['ell'] / g:.3g} mm, v_max*sqrt(1-beta^2) = {e['v_max'] * g:.4f} m/s, "
          f"healing e-fold {e['back_efold']:.3g} m, G-bar(20 um) = {e['G'][2]:.3g} J/m^2; "
          "one grid per pulse, no error estimate")
    return 0


def register(ss) -> None:
    p = ss.add_parser("divergence", help="where L diverges on a deep family: tau_star, local "
                                         "exponents",
                      description="Reads the converged pulses of family FILEs and the grid-checked "
                                  "rows of --table CSVs (one point per tau_d) and fits power laws "
                                  "L = A d^-m_L, 1 - beta = B d^m_beta, d = tau_d/tau_min - "
                                  "tau_star (jointly and singly) and the paper's Eqs. 3-4 over "
                                  "windows in tau_d and L, then on the deepest decade of L; "
                                  "tau_star of record is the centre and half-spread of the "
                                  "joint, L-alone and (1 - beta)-alone fits of that decade. "
                                  "Prints the local exponents d ln L/d ln(1 - beta) and "
                                  "d ln L/d ln d against L (docs/results.md, 'Where L diverges').")
    p.add_argument("file", metavar="FILE", nargs="*", help="HDF5 family file(s)")
    p.add_argument("--table", nargs="+", default=[], metavar="CSV",
                   help="tables of a family (columns label, tau_d_ratio, beta, L, n_points, "
                        "continuation, grid_check_passed, ...; e.g. steady/seeds/deep_family_*.csv)")
    p.add_argument("--figure", default=None, metavar="PNG",
                   help="draw L and 1 - beta against tau_d/tau_min - tau_star with the fits")
    p.add_argument("--exponents-figure", default=None, metavar="PNG",
                   help="draw the local exponents against L")
    p.set_defaults(func=cmd_divergence)

    p = ss.add_parser("edges", help="the edges of the pulses of a deep family against L",
                      description="Edge measures (leading-edge width and e-fold length, "
                                  "Lorentz-contracted; healing-front e-fold length and width; "
                                  "tau_max, v_max; G-bar at 2, 5, 20 um slip) of the converged "
                                  "pulses of FILEs with tau_d/tau_min < 1.06, one per 10 % in L, "
                                  "and each edge profile's distance from that of the longest "
                                  "pulse (docs/results.md, 'The edges become fixed structures'). "
                                  "One grid per pulse: the measures carry no error estimate.")
    p.add_argument("file", metavar="FILE", nargs="+", help="HDF5 family file(s)")
    p.add_argument("--figure", default=None, metavar="PNG", help="draw the edge measures against L")
    p.add_argument("--profiles-figure", default=None, metavar="PNG",
                   help="draw the edge profiles overlaid")
    p.set_defaults(func=cmd_edges)
