"""``slippulse steady rates``: the growth rates of record along a family, the laws fitted to them,
the family's slope and whether τ_d(L) folds (docs/results.md section 2).

The command runs in stages: check the options and files, read the rates and the family curve,
print the rated pulses, fit the laws, judge the folds, draw, and print the summary line."""
from __future__ import annotations

import math

import numpy as np

from ..core.errors import UsageError
from ..core.params import ParameterError
from .checks import check_figure, plural
from .paramargs import add_params_args, check_files

#: what each fit of s L/c_p is made against (named in the line of a fit that failed)
FIT_AGAINST = {"shift": "tau_d/tau_min - tau_star", "one": "tau_d/tau_min - 1", "L": "L"}


def _print_exponents(what, x, y, err, where):
    """One line of local exponents, each a weighted fit over a window of 10 % in x
    (:func:`slippulse.spectrum.law.windowed_exponents`), with its error bar."""
    from ..spectrum.law import EXPONENT_WINDOW, windowed_exponents
    xm, k, ke, n = windowed_exponents(x, y, err)
    if xm.size == 0:
        print(f"local exponents {what}: too few pulses (3 per window)")
        return
    print(f"local exponents {what} (windows of {EXPONENT_WINDOW:g} in ln x, >= 3 pulses): "
          + ", ".join(f"{b:.3f} ± {c:.2g} at {where(a)} ({m})"
                      for a, b, c, m in zip(xm, k, ke, n)))


def _check_rates_args(args) -> None:
    """--below in (1, 2], --tau-star in (0.9, 1.1), the figure's format, and files of one
    interface that agree with --params/--set (before anything is read for the fits)."""
    from ..spectrum.family import check_family_file
    if not (math.isfinite(args.below) and 1.0 < args.below <= 2.0):
        raise ParameterError(f"below={args.below!r} is invalid: must be in (1, 2] "
                             "(tau_d/tau_min)")
    if args.tau_star is not None and not (math.isfinite(args.tau_star)
                                          and 0.9 < args.tau_star < 1.1):
        raise ParameterError(f"tau-star={args.tau_star!r} is invalid: must be in (0.9, 1.1)")
    if args.figure:
        check_figure(args.figure, "--figure")
    prm = [check_family_file(f)[1] for f in args.file]
    for f, q in zip(args.file[1:], prm[1:]):
        if q != prm[0]:
            raise UsageError(f"{f}: its parameters differ from {args.file[0]}'s; rates of "
                             "different interfaces are not one family")
    check_files(args, args.file)


def _read_rates(files):
    """The stored rates (refused when none has an error estimate), the family curve of all
    converged pulses, and at each rated pulse the family's slope d τ_d/d ln L and the fold ratio
    R = s L/c_p / |d τ_d/d ln L| (docs/results.md section 2), each with its error."""
    from ..spectrum.law import family_curve, family_rates, family_slope, fold_ratio
    r = family_rates(files)
    if r["tau_d_ratio"].size == 0:
        raise UsageError(f"{' '.join(files)}: no growth rate with an error estimate stored; "
                         "run `slippulse steady stability FILE` first")
    curve = family_curve(files)
    slope, slope_err = family_slope(curve["tau_d_ratio"], curve["L"], curve["beta"],
                                    at_beta=r["beta"])
    R, R_err = fold_ratio(r["s_per_L"], r["s_err_per_L"], slope, slope_err)
    return r, curve, (slope, slope_err), (R, R_err)


def _print_rated(r, slope, R) -> None:
    """One line per rated pulse: L, s L/c_p and s with their errors, the sign's verdict, and
    where it is finite the slope and the fold ratio."""
    y, e = r["s_per_L"], r["s_err_per_L"]
    for k in range(y.size):
        sign = ("unstable" if y[k] > 2 * e[k] else "stable" if y[k] < -2 * e[k]
                else "sign not resolved")
        fold = (f"; d tau_d/d ln L = {slope[0][k]:.4g} ± {slope[1][k]:.1g}, R = {R[0][k]:.4g} ± "
                f"{R[1][k]:.1g}" if np.isfinite(R[0][k]) else "")
        print(f"{r['label'][k]}: L = {r['L'][k]:.4g} m, s L/c_p = {y[k]:.4g} ± {e[k]:.1g}, "
              f"s = {r['s'][k]:.4g} ± {r['s_err'][k]:.1g} 1/s: {sign}{fold}")


def _fit_rates(r, win, below, tau_star):
    """The power laws of s L/c_p on the window ``win`` against τ_d/τ_min − τ_star (τ_star fitted
    unless given), τ_d/τ_min − 1 and L: (fits by name, τ_star or None, the lines that say what
    was fitted and what not)."""
    from ..spectrum.law import fit_power_law, fit_shifted_power_law
    x, y, e = r["tau_d_ratio"], r["s_per_L"], r["s_err_per_L"]
    fits, parts = {}, []
    n_win = int(np.sum(win))
    if n_win < x.size:                  # say what the window left out, not only "got 0"
        parts.append(f"{n_win} of the {plural(x.size, 'rated pulse')} are fitted (resolved, "
                     f"unstable, tau_d/tau_min <= --below {below:g})")

    def fit(name, make, describe):
        try:
            fits[name] = make()
            parts.append(describe(fits[name]))
        except ValueError as exc:
            parts.append(f"no fit against {FIT_AGAINST[name]}: {exc}")
    if n_win < 3:
        parts.append(f"no power-law fit: {plural(n_win, 'pulse')} to fit, a fit needs 3 (4 to "
                     "fit tau_star too)")
    elif tau_star is None:
        try:
            sh = fit_shifted_power_law(x[win], y[win], e[win], lo=1.0)
            tau_star = sh.x_star
            fits["shift"] = sh.law
            parts.append(f"tau_star = {sh.x_star:.5f} ± {sh.x_star_err:.1g} (fitted), "
                         + sh.law.describe("(tau_d/tau_min - tau_star)", "s L/c_p"))
        except ValueError as exc:
            parts.append(f"no tau_star: {exc}")
    else:
        fit("shift", lambda: fit_power_law(x[win] - tau_star, y[win], e[win]),
            lambda f: f"tau_star = {tau_star:.5f} (given), "
            + f.describe("(tau_d/tau_min - tau_star)", "s L/c_p"))
    if n_win >= 3:
        fit("one", lambda: fit_power_law(x[win] - 1.0, y[win], e[win]),
            lambda f: f.describe("(tau_d/tau_min - 1)", "s L/c_p"))
        fit("L", lambda: fit_power_law(r["L"][win], y[win], e[win]),
            lambda f: f.describe("L/m", "s L/c_p"))
    return fits, tau_star, parts


def _fold_line(curve):
    """(the folds of τ_d along the family, whether there were enough pulses to judge, the line
    that says so)."""
    from ..spectrum.law import folds
    turns = folds(curve["tau_d_ratio"], curve["beta"])
    judged = curve["L"].size >= 3
    if not judged:
        line = (f"{curve['L'].size} converged pulses: too few to tell whether tau_d folds "
                "along the family")
    elif turns:
        line = ("tau_d turns along the family (a fold) between beta = " + ", ".join(
            f"{a:.6g}-{b:.6g}" for a, b in turns) + ": a real eigenvalue may cross zero there")
    else:
        line = (f"no fold: tau_d is monotone along the family over its {curve['L'].size} "
                f"pulses (beta = {curve['beta'].min():.4g}-{curve['beta'].max():.7g}, L = "
                f"{curve['L'].min():.4g}-{curve['L'].max():.4g} m), so no real eigenvalue "
                "crosses zero there")
    return turns, judged, line


def _summary(files, r, res, turns, judged) -> str:
    """The last line: the sign counts, whether s crosses zero and down to which pulse, the folds."""
    x, y = r["tau_d_ratio"], r["s_per_L"]
    n_un, n_st = int(np.sum(res & (y > 0))), int(np.sum(res & (y < 0)))
    cross = ("s changes sign" if n_un and n_st else
             "s does not cross zero (unstable at every resolved pulse)" if n_un and not n_st else
             "no resolved unstable pulse")
    lo = x[res].min() if np.any(res) else float("nan")
    return (f"rates {' '.join(files)}: {x.size} pulses, unstable at {n_un}, stable at {n_st}, "
            f"sign not resolved at {x.size - n_un - n_st}; {cross} down to tau_d/tau_min = "
            f"{lo:.6f} (L = {r['L'][x == lo][0] if np.any(res) else float('nan'):.4g} m); "
            + ("folds not judged (fewer than 3 converged pulses)" if not judged else
               "no fold of tau_d along the family" if not turns else
               f"{len(turns)} fold(s) of tau_d along the family"))


def cmd_rates(args) -> int:
    from ..spectrum.law import fit_power_law
    _check_rates_args(args)
    r, curve, slope, (R, R_err) = _read_rates(args.file)
    _print_rated(r, slope, (R, R_err))
    x, y, e = r["tau_d_ratio"], r["s_per_L"], r["s_err_per_L"]
    res = r["sign_resolved"] == 1
    win = (x <= args.below) & res & (y > 0)
    fits, tau_star, parts = _fit_rates(r, win, args.below, args.tau_star)
    for line in parts:
        print("fit: " + line)
    if tau_star is not None and np.sum(win & (x > tau_star)) >= 2:
        m = win & (x > tau_star)
        _print_exponents("d ln(s L/c_p)/d ln(tau_d/tau_min - tau_star)", x[m] - tau_star, y[m],
                         e[m], lambda a: f"{a + tau_star:.5f}")
        _print_exponents("d ln(s L/c_p)/d ln L", r["L"][m], y[m], e[m],
                         lambda a: f"L = {a:.3g} m")
    turns, judged, fold_line = _fold_line(curve)
    print("family: " + fold_line + " (docs/results.md section 2)")
    mR = win & np.isfinite(R) & (R > 0)
    if np.sum(mR) >= 3:
        fits["R"] = fit_power_law(r["L"][mR], R[mR], R_err[mR])
        print("fit: " + fits["R"].describe("L/m", "R = s L/c_p / |d tau_d/d ln L|"))
        _print_exponents("d ln R/d ln L", r["L"][mR], R[mR], R_err[mR],
                         lambda a: f"L = {a:.3g} m")
    if args.figure:
        from ..plotting.rates import plot_rates
        plot_rates(r, fits, args.figure, tau_star, fold=(R, R_err))
        print(f"figure: {args.figure}" + ("" if tau_star is not None else
              " (no tau_star fitted or given: panel (a) is drawn against tau_d/tau_min - 1)"))
    print(_summary(args.file, r, res, turns, judged))
    return 0


def register(ss) -> None:
    """``steady rates`` on the ``steady`` subparsers ``ss``."""
    p = ss.add_parser("rates", help="growth rates of record along a family, and their laws",
                      description="Reads the growth rates s +- s_err stored by `slippulse steady "
                                  "stability` in FILE, states where the sign is resolved and "
                                  "whether s crosses zero, and fits s L/c_p = A x^n (weighted, "
                                  "in log space; errors Birge-scaled) against x = tau_d/tau_min - "
                                  "tau_star (tau_star fitted too unless given) and against L, on "
                                  "the pulses with tau_d/tau_min <= --below (docs/results.md "
                                  "section 2). It also gives the family's slope d tau_d/d ln L "
                                  "at each rated pulse (from all converged pulses of the files), "
                                  "the ratio R = s L/c_p / |d tau_d/d ln L| and its law, and "
                                  "whether tau_d(L) folds: a real eigenvalue crosses zero only "
                                  "at a fold (docs/results.md section 2).")
    p.add_argument("file", metavar="FILE", nargs="+",
                   help="HDF5 family file(s) with stored spectra (several: their pulses are "
                        "taken together, e.g. a family and its deep continuation)")
    p.add_argument("--below", type=float, default=1.05,
                   help="fit the pulses with tau_d/tau_min <= BELOW (default 1.05)")
    p.add_argument("--tau-star", type=float, default=None,
                   help="tau_star (tau_d/tau_min where L diverges) to use instead of fitting it")
    p.add_argument("--figure", default=None, metavar="PNG", help="draw the rates and the fits")
    add_params_args(p)
    p.set_defaults(func=cmd_rates)
