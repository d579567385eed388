"""``slippulse steady ...``: solve steady pulses (and, later, families and their analysis)."""
from __future__ import annotations

import argparse
import dataclasses
import math
import os
import sys

from tqdm import tqdm

from ..core.errors import UsageError
from ..core.h5io import check_writable, pulse_label, stored_converged, write_pulse
from .checks import check_figure, check_outdir, check_tol, finite, plural  # noqa: F401
from ..steady.newton import SOLVERS
from ..core.params import DEFAULT, ParameterError
from .analyse import CD_CS_DEFAULTS
from .paramargs import add_params_args, check_files, params_for_output
from ..steady.solver import MAX_POINTS, check_points, solve_pulse
from ..core.executor import add_executor_options
from ..steady.continuation.family import SPACING
from ..steady.continuation.strategy import AUTO

def default_checks(cpus: int) -> str:
    """steady family's --checks default for a process that may use ``cpus`` CPUs: 'beside' with
    two or more (the checks of a second process give the inline march's pulses while the march
    goes on: from scratch to 10 km in 57 min on two cores, docs/steady.md "Checks beside the
    march"), 'inline' on one, where the second process only adds its start and hand-overs (the
    shallow family 29 s beside against 25–27 s inline on one core, BENCHMARKS.md "Family")."""
    return "beside" if cpus >= 2 else "inline"


def usable_cpus() -> int:
    """The CPUs this process may run on (its affinity where the system tells it)."""
    import os
    try:
        return len(os.sched_getaffinity(0))
    except AttributeError:                   # no affinity on this system
        return os.cpu_count() or 1


DEFAULT_CHECKS = default_checks(usable_cpus())


def summary_line(pulse, params) -> str:
    """One-line summary: β, c_p, L, L̃, v_max, τ_max/τ_min, τ_m/τ_min, max|Δ|, N, wall time, and
    that these numbers carry no error estimate (one grid)."""
    return (f"tau_d/tau_min={pulse.tau_d_ratio:.4f} beta={pulse.beta:.8g} c_p={pulse.c_p:.6g} m/s "
            f"L={pulse.L:.6g} m L~={pulse.L_tilde:.6g} v_max={pulse.v_max:.4e} m/s "
            f"tau_max/tau_min={pulse.tau.max() / pulse.tau_min:.6f} "
            f"tau_m/tau_min={pulse.tau.min() / pulse.tau_min:.6f} max|D|={pulse.max_residual:.2e} "
            f"N={pulse.n_points} wall={pulse.wall_time:.2f} s "
            f"{'converged' if pulse.converged else 'NOT CONVERGED'}; no error estimate (one grid; "
            "`steady family` grid-checks each pulse at 2N - 1)")


def _ratio(text: str, params=DEFAULT, option: str = "tau-d") -> float:
    """τ_d/τ_min given as ``option``: a finite number in (1, τ_peak/τ_min)."""
    hi = params.tau_peak / params.tau_min
    try:
        val = float(text)
    except ValueError:
        raise ParameterError(f"{option}={text} is invalid: must be a number (tau_d/tau_min) in "
                             f"(1, {hi:.4f})") from None
    if not (math.isfinite(val) and 1.0 < val < hi):
        raise ParameterError(f"{option}={text} is invalid: must be a finite number "
                             f"(tau_d/tau_min) in (1, {hi:.4f})")
    return val


def _check_out(out: str) -> None:
    """Refuse, before solving, an --out that could not take a pulse (not a directory, not an
    HDF5 steady file, a newer format version)."""
    from ..core.h5io import check_writable, format_version, open_h5

    check_writable(out, "out")
    if os.path.exists(out):
        with open_h5(out, "out") as h5:
            format_version(h5, out)


def _homotopy_guess(params, tau_d_ratio, progress):
    """--homotopy: the pulse of ``params`` reached from Table I's by continuation in the
    parameters (N = 500 along the path), as a guess; a path that stops is reported (exit 1)."""
    from ..steady.param_continuation import as_guess, continue_in_params
    sol, path = continue_in_params(DEFAULT, params, tau_d_ratio, n_points=500, progress=progress)
    if sol is None or not (path[-1][0] == 1.0 and path[-1][1]):
        reached = max([s for s, ok, _ in path if ok], default=0.0)
        raise SolverStop(f"continuation in the parameters from Table I stopped at s={reached:.3g} "
                         f"of the path (last: {path[-1][2]})")
    return as_guess(sol)


class SolverStop(RuntimeError):
    """A solve that failed before a pulse could be written (exit code 1)."""


def cmd_solve(args) -> int:
    params = params_for_output(args)
    tau_d_ratio = _ratio(args.tau_d, params)
    params.check_tau_d(tau_d_ratio * params.tau_min)
    _check_solve_range(tau_d_ratio)
    check_points(args.points)
    check_tol(args.tol)
    out = args.out or os.path.join("runs", "steady", f"{pulse_label(tau_d_ratio)}.h5")
    _check_out(out)
    params = params_for_output(args, out)
    label = pulse_label(tau_d_ratio)
    before = stored_converged(out, label)
    if before is not None and not args.overwrite:
        raise UsageError(f"out={out!r}: pulse {label} already exists there "
                         f"({'converged' if before else 'not converged'}); --overwrite replaces it")
    png = None if args.no_figure else os.path.splitext(out)[0] + ".png"
    if png:
        check_figure(png, "out (its PNG)")
    sol, route = solve_any(params, tau_d_ratio, args)
    if sol is None:
        print(f"slippulse: solver did not converge: {route}; nothing written to {out}",
              file=sys.stderr)
        return 1
    pulse = sol.to_pulse()
    if pulse.converged and not pulse.max_residual <= args.tol:
        pulse.converged = False              # the solver stopped above the target: not converged
        pulse.extra["status"] = "failed"
        pulse.extra["message"] = (f"max|residual| {pulse.max_residual:.3g} above --tol "
                                  f"{args.tol:g}")
    if not pulse.converged and before:
        print(summary_line(pulse, params))
        print(f"slippulse: solver did not converge: {sol.stats.message}; the converged pulse "
              f"{label} in {out} is kept, nothing written", file=sys.stderr)
        return 1
    write_pulse(out, pulse, params, overwrite=args.overwrite)
    if png:
        from ..plotting.quicklook import plot_pulse
        plot_pulse(pulse, params, png)
    print(summary_line(pulse, params))
    if not pulse.converged:
        print(f"slippulse: solver did not converge: {sol.stats.message} "
              f"(written with converged=False to {out})", file=sys.stderr)
        return 1
    return 0


def _check_solve_range(tau_d_ratio: float) -> None:
    """Refuse a tau-d outside what ``steady solve`` reaches (reach.SOLVE_RANGE), saying what does."""
    from ..steady.reach import SOLVE_RANGE
    lo, hi = SOLVE_RANGE
    if not lo <= tau_d_ratio <= hi:
        raise ParameterError(
            f"tau-d={tau_d_ratio:g} is outside what steady solve reaches, [{lo}, {hi}]: "
            + (f"deeper pulses come from the family continuation (slippulse steady family --to "
               f"{tau_d_ratio:g})" if tau_d_ratio < lo else
               f"above {hi} the pulse fades toward tau_peak/tau_min = 1.3319 and the continuation "
               "from 1.2 cannot follow it"))


def solve_any(params, tau_d_ratio, args):
    """``steady solve``'s solve: from the built-in guess at 1.2, continued to ``tau_d_ratio``
    (with --homotopy: from Table I's pulse continued in the parameters, then solved at ``tau_d_ratio``)
    (:func:`slippulse.steady.reach.reach_pulse`) with a progress bar over the walk's steps.
    Returns (solution or None, route or reason)."""
    from ..steady.reach import GUESS_RATIO, reach_pulse, route_targets

    if getattr(args, "homotopy", False):
        # --homotopy: the guess is the pulse continued in the parameters from Table I's
        # at this tau_d; then one solve at the target from it
        bar = tqdm(total=3, desc=f"steady {pulse_label(tau_d_ratio)}", unit="pass", disable=args.quiet,
                   file=sys.stderr)

        def progress(msg):
            bar.set_postfix_str(msg[:60])
            bar.update(1)

        try:
            guess = _homotopy_guess(params, tau_d_ratio,
                                    lambda m: bar.set_postfix_str("path " + m[:55]))
            sol = solve_pulse(params, tau_d_ratio, n_points=args.points, method=args.method,
                              tol=args.tol, progress=progress, guess=guess)
        except SolverStop as exc:
            return None, str(exc)
        finally:
            bar.close()
        return sol, "by continuation in the parameters from Table I"
    h, n = route_targets(tau_d_ratio)
    if n == 0:
        bar = tqdm(total=3, desc=f"steady {pulse_label(tau_d_ratio)}", unit="pass", disable=args.quiet,
                   file=sys.stderr)

        def progress(msg):
            bar.set_postfix_str(msg[:60])
            bar.update(1)

        sol = solve_pulse(params, tau_d_ratio, n_points=args.points, method=args.method, tol=args.tol,
                          progress=progress)
        bar.close()
        return sol, "from the built-in guess"
    prog = FamilyProgress(GUESS_RATIO, tau_d_ratio, -h)
    bar = tqdm(total=prog.total, desc=f"steady {pulse_label(tau_d_ratio)} (from {GUESS_RATIO})",
               unit="step", disable=args.quiet, file=sys.stderr,
               bar_format="{l_bar}{bar}| {n}/{total} steps [{elapsed}<{remaining}{postfix}]")
    prog.bar = bar
    try:
        return reach_pulse(params, tau_d_ratio, n_points=args.points, method=args.method, tol=args.tol,
                           progress=prog)
    finally:
        bar.close()


class FamilyProgress:
    """Progress of a family run, in targets passed: a converged pulse at τ_d/τ_min = r puts the
    bar at 1 + (start − r)/step (fractional between targets, so β-steps move it too); it never
    moves back. Failed attempts are counted and shown."""

    def __init__(self, start, stop, step, bar=None):
        self.start, self.step = start, step
        self.total = int(round((start - stop) / step)) + 1
        self.position = 0.0
        self.failed = 0
        self.bar = bar

    def __call__(self, tau_d_ratio, pulse, msg):
        if pulse is None:
            self.failed += 1
            state = f"{tau_d_ratio:.5f} failed ({self.failed}): {msg[:40]}"
        else:
            self.position = max(self.position,
                                min(self.total, 1.0 + (self.start - pulse.tau_d_ratio) / self.step))
            state = f"{pulse.tau_d_ratio:.5f} beta={pulse.beta:.6f} L={pulse.L:.5g}m"
        if self.bar is not None:
            self.bar.n = int(self.position + 1e-9)   # targets passed (the postfix moves between)
            self.bar.set_postfix_str(state)     # refreshes the bar


def final_status(rep, start, stop, out) -> str:
    """The family run's last line: what was reached, the failed attempts, and at an early stop
    where, why, and what would go further."""
    line = (f"family {start:.4f} -> {stop:.4f}: {len(rep.written)} pulses written to {out}, reached "
            f"tau_d/tau_min={rep.reached:.5f}, {rep.attempts} solves attempted, "
            f"{len(rep.failures)} failed, wall={rep.wall_time:.1f} s")
    if rep.checks:
        nf = len(rep.failed_checks)
        line += (f", {plural(rep.checks, 'grid check')}, "
                 + ("all passed" if not nf else f"{nf} failed (those pulses written, marked failed)")
                 + f", L={rep.reached_L:.5g} m")
    if rep.limit_reached:
        line += f"\nstopped at --max-length: {rep.stop_reason}"
    if rep.stopped_early:
        line += (f"\nSTOPPED EARLY at tau_d/tau_min={rep.reached:.5f} (beta={rep.reached_beta:.6f}, "
                 f"L={rep.reached_L:.5g} m), {stop:.4f} not reached: {rep.stop_reason}. "
                 f"To go further: {rep.hint}.")
    return line


#: Most targets a ``steady family`` run may have ((from - to)/step + 1): a step that needs more
#: could not finish (each target is a solve of seconds).
MAX_TARGETS = 10_000


def _check_targets(start: float, stop: float, step: float) -> None:
    """Refuse a --step that gives more than MAX_TARGETS targets (e.g. 1e-300: 1e299 targets)."""
    n = (start - stop) / step + 1
    if n > MAX_TARGETS:
        raise ParameterError(f"step={step:g} is invalid: it gives {n:.3g} targets from {start:g} to "
                             f"{stop:g}; at most {MAX_TARGETS} (step >= "
                             f"{(start - stop) / (MAX_TARGETS - 1):.3g})")


def family_run_args(args, params) -> dict:
    """The keyword arguments of :func:`~slippulse.steady.continuation.run_family` that the
    options of ``steady family`` set (every option changes one, or is refused here with a
    ParameterError naming it and its valid range)."""
    from ..steady.continuation import AUTO, FAMILY_POINTS, StrategyError
    from ..steady.continuation.family import DEEP_POINTS, check_family_args
    if args.from_pulse is not None:
        return from_pulse_run_args(args, params)
    start, stop = _ratio(args.from_, params, "--from"), _ratio(args.to, params, "--to")
    if not stop < start:
        raise ParameterError(f"--to={stop:g} is invalid: must be < --from={start:g} (the family "
                             "is continued downward in tau_d)")
    if not (math.isfinite(args.step) and args.step > 0):
        raise ParameterError(f"step={args.step} is invalid: must be a number > 0")
    check_family_args(params, start, stop, args.step)
    _check_targets(start, stop, args.step)
    if args.points is not None:
        check_points(args.points)
    n_deep = FAMILY_POINTS[1] if args.points is None else args.points
    need = max(n_deep, 2 * DEEP_POINTS - 1)
    if args.max_points < need:
        raise ParameterError(f"max-points={args.max_points} is invalid: must be >= {need} (the "
                             f"grid check of the deep pulses needs 2N - 1 = "
                             f"{2 * DEEP_POINTS - 1}, N = {DEEP_POINTS}, and >= points)")
    steps = AUTO.steps
    if not (0 < args.ds_min <= steps.ds):
        raise ParameterError(f"ds-min={args.ds_min} is invalid: must be in (0, {steps.ds:g}] "
                             f"(the deep march's first step) and below the held steps' cap")
    if not args.max_length > 0:
        raise ParameterError(f"max-length={args.max_length} is invalid: must be > 0 (m)")
    if not (0 <= args.spacing <= 0.5):
        raise ParameterError(f"spacing={args.spacing} is invalid: must be in [0, 0.5] (a fraction "
                             "of L)")
    try:
        strategy = AUTO.replace(steps=dataclasses.replace(steps, ds_min=args.ds_min))
    except StrategyError as exc:
        raise ParameterError(f"ds-min={args.ds_min} is invalid: {exc}") from None
    return dict(start=start, stop=stop, step=args.step, n_points=args.points,
                strategy=strategy, n_max=args.max_points, max_length=args.max_length,
                spacing=args.spacing, origin=None, checks=_checks(args))


def _checks(args) -> str:
    """--checks, checked: where the grid checks run (FamilyRun.checks)."""
    from ..steady.continuation.family import check_checks
    check_checks(args.checks)
    return args.checks


def from_pulse_run_args(args, params) -> dict:
    """The keyword arguments of ``run_family`` for ``steady family --from-pulse FILE:LABEL``:
    the stored pulse (read and validated: the file, the label, its parameters those of the run,
    converged) continued by the deep march toward --to, above or below its τ_d. The options of
    the natural steps (--from, --step, --points) do not act on that march and are refused when
    given another value than their default."""
    from ..core.errors import SchemaError
    from ..core.h5io import read_pulse
    from ..core.params import describe_difference, differing
    from ..steady.continuation import StrategyError, from_pulse_strategy
    text = args.from_pulse
    path, sep, label = text.rpartition(":")
    if not (sep and path and label):
        raise ParameterError(f"from-pulse={text!r} is invalid: must be FILE:LABEL (e.g. "
                             f"family.h5:td1.2000)")
    try:
        origin, stored = read_pulse(path, label)
    except SchemaError as exc:
        raise ParameterError(f"from-pulse={text!r} is invalid: {exc}") from None
    if differing(stored, params):
        raise ParameterError(f"from-pulse={text!r} is invalid: {path} holds pulses of other "
                             f"parameters: "
                             f"{describe_difference(stored, params, 'in the file', 'given')}")
    if not origin.converged:
        raise ParameterError(f"from-pulse={text!r} is invalid: that pulse did not converge")
    for name, value, default in (("from", args.from_, "1.2"), ("step", args.step, 0.005),
                                 ("points", args.points, None)):
        if value != default:
            raise ParameterError(f"--{name}={value} is not used with --from-pulse (the march "
                                 f"starts at the pulse, on its grid, with arclength steps)")
    stop = _ratio(args.to, params, "--to")
    need = 2 * origin.n_points - 1
    if args.max_points < need:
        raise ParameterError(f"max-points={args.max_points} is invalid: the grid check of the "
                             f"pulse's grid (N = {origin.n_points}) needs at least 2N - 1 = {need}")
    march = from_pulse_strategy(origin)
    steps = march.steps
    if not (0 < args.ds_min <= steps.ds):
        raise ParameterError(f"ds-min={args.ds_min} is invalid: must be in (0, {steps.ds:g}] "
                             f"(the first arclength step) and below a held steps' cap")
    try:
        strategy = march.replace(steps=dataclasses.replace(steps, ds_min=args.ds_min))
    except StrategyError as exc:
        raise ParameterError(f"ds-min={args.ds_min} is invalid: {exc}") from None
    return dict(start=origin.tau_d_ratio, stop=stop, step=args.step, n_points=None,
                strategy=strategy, n_max=args.max_points, max_length=args.max_length,
                spacing=args.spacing, origin=origin, checks=_checks(args))


def cmd_family(args) -> int:
    from ..steady.bifurcation import FamilyMonitor, events, stored_rows
    from ..steady.continuation import FamilyRun, run_family
    from .branches import event_lines
    out = args.out or os.path.join("runs", "steady", "family.h5")
    params = params_for_output(args, out)
    kw = family_run_args(args, params)
    check_writable(out, "out")
    _check_out(out)
    start, stop = kw["start"], kw["stop"]
    prog = FamilyProgress(start, stop, math.copysign(args.step, start - stop))
    # the bar appears after a second of work: an input the run refuses at once leaves no stub
    bar = tqdm(total=prog.total, desc="family", unit="target", disable=args.quiet,
               file=sys.stderr, delay=1.0,
               bar_format="{l_bar}{bar}| {n}/{total} targets [{elapsed}<{remaining}{postfix}]")
    prog.bar = bar

    def log(msg):
        if not args.quiet:
            tqdm.write(msg, file=sys.stderr)

    try:
        origin = kw.pop("origin", None)
        rep = run_family(params, out, FamilyRun(**kw), origin=origin, progress=prog, log=log,
                         monitor=FamilyMonitor(params))
    finally:
        bar.close()
    if rep.resumed_from:
        print(f"resumed from {rep.resumed_from} in {out}", file=sys.stderr)
    print(final_status(rep, start, stop, out))
    if os.path.exists(out):
        rows = stored_rows(out)
        for line in event_lines(out, params, rows, events(rows), bridge=False):
            print(f"test functions: {line}")
    return 1 if rep.stopped_early else 0


def spectrum_line(label, res) -> str:
    """One line per pulse: the leading growth rate with its measured uncertainty (or 'sign not
    resolved'), whether it is real, the translation check per level, the count, the cost."""
    if res.status != "converged":
        return f"{label}: FAILED ({res.message}); nothing stored"
    if res.sigmas.size == 0 and "det M" in res.message:
        return (f"{label}: no eigenvalue with Re sigma > 1e-7 c_p/L found (the search above "
                f"0.001 c_p/L, the sign of det M below): stable, or a rate below 1e-7 c_p/L; "
                f"N={res.n_points}, {res.wall_time:.1f} s")
    if res.sigmas.size == 0:
        return (f"{label}: no eigenvalue with Re sigma > 0.001 c_p/L found (stable or below "
                f"resolution: the rates near tau_min, below ~0.002 c_p/L at L > 100 m, are found "
                f"only by tracking from the pulses above: run it on the family from the top, "
                f"from a label just below one with a stored spectrum, or with --guess S near "
                f"the expected s L/c_p); N={res.n_points}, "
                f"{res.wall_time:.1f} s")
    s = res.leading
    kind = "real" if abs(s.imag) <= 1e-8 * abs(s) else f"complex, Im {s.imag / res.rate_unit:.4g}"
    ref = res.refined
    if ref is None:
        rate = (f"s L/c_p = {s.real / res.rate_unit:.5g} on N={res.n_points} (no error estimate: "
                "--levels 0)")
        t = res.neutral[1].real / res.rate_unit
        trans = f"{t:.1e}" if math.isfinite(t) else "0 (pinned)"   # pinned: not computed
        levels = f"N={res.n_points}"
    else:
        rate = ref.describe()
        if not ref.target_met:
            rate += f" (target s_err L/c_p <= {ref.target:g} not reached)"
        if ref.sign_resolved:
            rate += f" (s = {ref.s:.4g} ± {ref.s_err:.1g} 1/s)"
        if ref.pinned:
            trans = "0 (pinned)"
        else:
            trans = "/".join(f"{t / u:.1e}" for t, u in zip(ref.translation_levels,
                                                             ref.unit_levels))
        if math.isfinite(ref.translation_extrapolated):
            # the check of the estimate against the known answer 0
            trans += (f", extrapolated {ref.translation_extrapolated / ref.rate_unit:.1e}, "
                      f"error bar {ref.translation_err / ref.rate_unit:.1e} "
                      + ("covers 0" if ref.translation_covered else "DOES NOT cover 0"))
        levels = "N=" + "/".join(str(n) for n in ref.n_points)
    line = f"{label}: {rate}, {kind}; translation sigma_t L/c_p = {trans} (exact 0); {levels}"
    if res.count is not None:
        c = res.count
        line += (f"; count: {c.count} in Re in [{c.box[0]:g}, {c.box[1]:.3g}], |Im| <= "
                 f"{c.box[2]:.3g} c_p/L ({c.n_evals} det"
                 + (f", {c.resumed} read back from its checkpoint" if c.resumed else "")
                 + f", {c.wall_time:.0f} s)"
                 if c.count is not None
                 else f"; count FAILED: {c.message}")
        if c.count is not None and s.real / res.rate_unit < c.box[0]:
            line += " (the leading eigenvalue lies left of the box: not in this count)"
        if c.count:
            loc = c.located
            line += (f"; {len(loc)} of them located" + (": " + ", ".join(
                f"{z.real:.4g}" + (f"{z.imag:+.3g}i" if z.imag else "") for z in loc[:6])
                if len(loc) else ""))
        if res.leading_from == "count":
            line += "; the leading eigenvalue found from the count's zeros, not the tracked start"
        if c.checkpoint_note:
            line += f" ({c.checkpoint_note})"
    return line + f"; {res.wall_time + (ref.wall_time if ref else 0.0):.1f} s"


def _integer(name, value, lo, hi, what) -> None:
    """A ParameterError naming option `name`, its range [lo, hi] and what it counts, unless
    `value` is an integer in that range."""
    if not (isinstance(value, int) and lo <= value <= hi):
        raise ParameterError(f"{name}={value!r} is invalid: must be an integer in [{lo}, {hi}] "
                             f"({what})")


def cmd_stability(args) -> int:
    from ..spectrum.refine import MIN_REFINE_POINTS
    from ..core.executor import progress_bar, settings_from_args
    from ..spectrum.family import (COUNT_EVALS, DEFAULT_LEVELS, DEFAULT_REL_TARGET,
                                   DEFAULT_TARGET, MAX_SPECTRUM_POINTS, MIN_SPECTRUM_POINTS,
                                   SpectrumSettings, check_family_file, run_spectrum)
    from ..core.memory import keep_freed_memory
    keep_freed_memory()          # N×N arrays reuse mapped pages (fewer page faults)
    labels = args.labels or None
    if args.count_evals is None:
        args.count_evals = COUNT_EVALS
    if args.levels is None:
        args.levels = DEFAULT_LEVELS
    if args.min_points is None:
        args.min_points = MIN_SPECTRUM_POINTS
    if args.max_points is None:           # a --min-points above the default raises it
        args.max_points = max(MAX_SPECTRUM_POINTS, args.min_points)
    if args.target is None:
        args.target = DEFAULT_TARGET
    if args.rel_target is None:
        args.rel_target = DEFAULT_REL_TARGET
    _integer("min-points", args.min_points, 0, 8000, "smallest N of the spectrum's first level")
    _integer("max-points", args.max_points, max(args.min_points, MIN_REFINE_POINTS), 8000,
             "largest N of the spectrum's first level, at least --min-points")
    if not (math.isfinite(args.rel_target) and 0.0 <= args.rel_target < 1.0):
        raise ParameterError(f"rel-target={args.rel_target!r} is invalid: must be a number in "
                             "[0, 1) (s_err as a fraction of |s|)")
    _integer("levels", args.levels, 0, 6,
             "levels N_0 sqrt(2)^k above level 0 for the error estimate")
    if args.points is not None:
        _integer("points", args.points, MIN_REFINE_POINTS, 8000,
                 "N of the spectrum's first level")
    if args.target is not None and not (math.isfinite(args.target) and args.target > 0):
        raise ParameterError(f"target={args.target!r} is invalid: must be a number > 0 "
                             "(s_err in units of c_p/L)")
    box = None
    if args.count is not None:
        box = tuple(args.count)
        if not (all(math.isfinite(b) for b in box) and 0.0 < box[0] < box[1] and box[2] > 0.0):
            raise ParameterError(f"count={list(box)!r} is invalid: need X0 X1 Y1 with "
                                 "0 < X0 < X1 and Y1 > 0 (units of c_p/L)")
    if args.guess is not None and not (math.isfinite(args.guess) and 0 < args.guess <= 100):
        raise ParameterError(f"guess={args.guess!r} is invalid: must be an s L/c_p in (0, 100]")
    executor = settings_from_args(args)
    _integer("count_evals", args.count_evals, 24, 20000, "det M evaluations of the count")
    if args.figure:
        check_figure(args.figure, "--figure")             # format and writability, before the work
    chosen, _ = check_family_file(args.file, labels)      # bad input fails here, before any work
    _check_file_params(args, args.file)
    check_writable(args.file, "FILE")                     # the spectra go into FILE
    if labels is None:                                    # all converged: name those left out
        from ..core.h5io import require_converged
        left = require_converged(args.file, allow=True)
        if left:
            print(f"left out (marked converged=False): {', '.join(left)}", file=sys.stderr)
    bar = progress_bar(len(chosen), "spectrum", "pulse", disable=args.quiet)

    def progress(label, res, stored):
        if res is not None:
            tqdm.write(spectrum_line(label, res), file=sys.stdout)
        else:
            tqdm.write(f"{label}: stored spectrum kept ({stored_rate(stored)})", file=sys.stdout)
        bar.set_postfix_str(label)
        bar.update(1)

    def level_progress(msg):
        bar.set_postfix_str(msg[:50])

    settings = SpectrumSettings(levels=args.levels, target=args.target,
                                rel_target=args.rel_target, min_points=args.min_points,
                                max_points=args.max_points, level0_points=args.points,
                                pin_translation=args.pin_translation, extra=not args.no_extra,
                                count_box=box, count_evals=args.count_evals)
    if not args.quiet:
        tqdm.write(f"spectrum settings: {settings}; executor: {executor}", file=sys.stderr)
    rep = run_spectrum(args.file, settings, labels, overwrite=args.overwrite, guess=args.guess,
                       executor=executor, progress=progress, level_progress=level_progress)
    bar.close()
    done = [r for r in rep.results if r.status == "converged"]
    print(family_summary(args.file, done, rep))
    if args.figure:
        from ..plotting.spectrum import plot_family_spectrum
        plot_family_spectrum(args.file, args.figure)
        print(f"figure: {args.figure}")
    return 1 if rep.failed else 0


def _check_file_params(args, path) -> None:
    """``--params``/``--set`` of a command that reads ``path`` must agree with its parameters."""
    check_files(args, [path])


def cmd_analyse(args) -> int:
    from .analyse import cmd_analyse as run
    if os.path.isfile(args.file):
        _check_file_params(args, args.file)
    return run(args)


def stored_rate(stored) -> str:
    """The stored leading rate as the summary line states it."""
    if "s_per_L" not in stored:
        return f"s L/c_p = {stored['leading_s_per_L']:.5g}, no error estimate"
    s, e = float(stored["s_per_L"]), float(stored["s_err_per_L"])
    if abs(s) < 2.0 * e:
        return f"sign not resolved, s L/c_p in [{s - e:.2g}, {s + e:.2g}]"
    return f"s L/c_p = {s:.4g} ± {e:.1g}"


def family_summary(path, done, rep) -> str:
    """The run's last line: how many pulses have a resolved sign, the range of the rates, the
    counts, failures and wall time. It names no count it did not make."""
    refined = [r for r in done if r.refined is not None and r.sigmas.size]
    unstable = [r.label for r in refined if r.refined.sign_resolved and r.refined.s > 0]
    stable = [r.label for r in refined if r.refined.sign_resolved and r.refined.s < 0]
    unresolved = [r.label for r in refined if not r.refined.sign_resolved]
    parts = [f"stability {path}: {plural(len(done), 'pulse')} solved"
             + (f", {len(rep.skipped)} kept (already stored)" if rep.skipped else "")
             + (f", {len(rep.failed)} failed" if rep.failed else ", none failed")]
    if refined:
        parts.append(f"unstable (s > 2 s_err) at {len(unstable)}, stable (s < -2 s_err) at "
                     f"{len(stable)}, sign not resolved at {len(unresolved)}"
                     + (f" ({', '.join(unresolved[:4])}{' ...' if len(unresolved) > 4 else ''})"
                        if unresolved else ""))
    missed = [r.label for r in refined if not r.refined.target_met]
    if missed:
        parts.append(f"target s_err not reached at {len(missed)} ({', '.join(missed[:4])}"
                     f"{' ...' if len(missed) > 4 else ''})")
    counted = [r.count.count for r in done if r.count is not None and r.count.count is not None]
    if counted:
        parts.append(f"contour counts {sorted(set(counted))} at {len(counted)} pulses")
    else:
        parts.append("unstable modes not counted (--count)")
    return "; ".join(parts) + f"; wall={rep.wall_time:.1f} s"


def _add_solve(ss) -> None:
    p = ss.add_parser("solve", help="solve one steady pulse",
                      description="Solve the steady pulse at one driving stress: from the "
                                  "built-in guess at 1.2, continued to --tau-d (the family "
                                  "continuation below 1.2, steps upward above); writes HDF5 "
                                  "(+ PNG) and prints a one-line summary.")
    p.add_argument("--tau-d", default="1.2",
                   help="driving stress tau_d/tau_min in [1.015, 1.32] (default 1.2; away from "
                        "1.2 the pulse is reached by continuation from 1.2, with a progress bar)")
    p.add_argument("--points", type=int, default=2000, help="grid points N (default 2000)")
    p.add_argument("--out", default=None, help="output HDF5 (default runs/steady/tdX.XXXX.h5)")
    p.add_argument("--method", choices=sorted(SOLVERS), default="newton",
                   help="nonlinear solver (default newton)")
    p.add_argument("--tol", type=float, default=1e-13, help="max|residual| target (default 1e-13)")
    p.add_argument("--no-figure", action="store_true", help="do not write the PNG")
    p.add_argument("--homotopy", action="store_true",
                   help="start from Table I's pulse and continue in the parameters to the given "
                        "ones (geometric path, N = 500; for laws where the built-in guess fails)")
    p.add_argument("--overwrite", action="store_true",
                   help="replace a pulse of the same label in --out (an unconverged solve never "
                        "replaces a converged pulse)")
    p.add_argument("-q", "--quiet", action="store_true", help="no progress bar")
    add_params_args(p)
    p.set_defaults(func=cmd_solve)


def _add_family(ss) -> None:
    p = ss.add_parser("family", help="continue the pulse family in tau_d",
                      description="Solve pulses from --from down to --to (tau_d/tau_min), each seeded "
                                  "by the previous one, halving the step on failure; all pulses go "
                                  "into one HDF5 file. Rerunning with the same --out resumes.")
    p.add_argument("--from", dest="from_", default="1.2", help="first tau_d/tau_min (default 1.2)")
    p.add_argument("--to", default="1.015", help="last tau_d/tau_min (default 1.015)")
    p.add_argument("--step", type=float, default=0.005, help="step in tau_d/tau_min (default 0.005)")
    p.add_argument("--points", type=int, default=None,
                   help="grid points per pulse (default: 1000 while beta <= 0.7, 1250 beyond)")
    p.add_argument("--out", default=None, help="output HDF5 (default runs/steady/family.h5)")
    p.add_argument("--max-points", type=int, default=MAX_POINTS,
                   help=f"largest grid a per-pulse grid check may use (default {MAX_POINTS}; "
                        "at least 3999)")
    p.add_argument("--ds-min", type=float, default=AUTO.steps.ds_min,
                   help="smallest arclength step of the deep march before it refines the "
                        f"healing front or stops (default {AUTO.steps.ds_min:g})")
    p.add_argument("--spacing", type=float, default=SPACING,
                   help="write (and grid-check) a deep-march pulse once L has changed by this "
                        f"fraction since the last one (default {SPACING:g}; 0: every arclength "
                        "step). The march goes on from each checked pulse, so a wide spacing "
                        "lets the deformed grid drift between checks")
    p.add_argument("--max-length", type=float, default=math.inf,
                   help="stop (exit 0) once the pulse length exceeds this (m; default no limit)")
    p.add_argument("--from-pulse", default=None, metavar="FILE:LABEL",
                   help="continue this stored pulse (e.g. of another branch) instead, on its own "
                        "grid, by the deep march's pseudo-arclength steps toward --to (above or "
                        "below its tau_d, through folds), into a new --out")
    p.add_argument("--checks", default=DEFAULT_CHECKS, metavar="{inline,beside}",
                   help="where the grid checks run: 'beside', in a second process while the "
                        "march goes on (the march goes back where a check refines the grid), "
                        "or 'inline', each before the next step, in one process; the same "
                        f"pulses (default: beside where two or more CPUs are free to this "
                        f"process, else inline; here {DEFAULT_CHECKS})")
    p.add_argument("-q", "--quiet", action="store_true", help="no progress bar")
    add_params_args(p)
    p.set_defaults(func=cmd_family)


def _add_stability(ss) -> None:
    p = ss.add_parser("stability", help="linear stability spectrum of the pulses of a file",
                      description="Eigenvalues sigma (perturbations ~ exp(sigma t) in the co-moving "
                                  "frame) and modes of each converged pulse, from the steady "
                                  "solution alone (nonlinear eigenproblem on the pulse's grid, "
                                  "docs/spectrum.md; the rates of record: docs/results.md "
                                  "section 2). The leading growth rate s comes with an "
                                  "error s_err measured on a ladder of grids of one smooth map of "
                                  "the pulse's grid (N_0, sqrt(2) N_0, 2 N_0, ...; observed order "
                                  "and Roache's grid convergence index); where |s| < 2 s_err "
                                  "its sign is reported as not resolved. Results go into each "
                                  "pulse's group ('spectrum'); rerunning resumes.")
    p.add_argument("file", metavar="FILE", help="HDF5 pulse or family file")
    p.add_argument("--labels", nargs="+", default=None, metavar="LABEL",
                   help="pulses to analyse, e.g. td1.2000 td1.0500 (default: all converged)")
    p.add_argument("--overwrite", action="store_true", help="recompute stored spectra")
    p.add_argument("--no-extra", action="store_true",
                   help="only the leading eigenvalue (skip the search below it)")
    p.add_argument("--levels", type=int, default=None,
                   help="levels above level 0 (N_0 sqrt(2)^k points, the pulse re-solved on one "
                        "smooth map of its grid) for the error of the leading growth rate, at "
                        "least: more are added until --target is met; s is the finest level's; "
                        "s_err the last correction (2 levels) or from the observed order (3 or "
                        "more) (default 1; 0: no estimate; docs/spectrum.md section 4)")
    p.add_argument("--min-points", type=int, default=None,
                   help="level 0 has N_0 = N clipped to [MIN_POINTS, MAX_POINTS] (default 1000)")
    p.add_argument("--max-points", type=int, default=None,
                   help="the upper end of that clip (default 2828, or MIN_POINTS where larger: "
                        "enough down to L = 2 km, 1.0089 tau_min, where N = 2000 is not; a "
                        "pulse whose re-solve on the clipped N fails gets level 0 on its own N; "
                        "a level 0 below the pulse's own N climbs at least 2 levels, so that "
                        "its error comes from an observed order)")
    p.add_argument("--target", type=float, default=None, metavar="S_ERR",
                   help="add levels beyond --levels (up to N = 8000) until s_err L/c_p <= "
                        "max(S_ERR, REL |s L/c_p|) (default 1e-4)")
    p.add_argument("--rel-target", type=float, default=None, metavar="REL",
                   help="the relative part of that goal (default 1e-3; 0: absolute only)")
    p.add_argument("--points", type=int, default=None, metavar="N0",
                   help="level 0 has exactly N0 points on the pulse's map (overrides "
                        "--min-points and --max-points)")
    p.add_argument("--pin-translation", action=argparse.BooleanOptionalAction, default=True,
                   help="solve with the translation mode pinned at sigma = 0 (default; a "
                        "rank-one change of the size of the discretisation error that removes "
                        "its coupling to the leading mode, the largest error of s near tau_min; "
                        "--no-pin-translation: M(0) exactly the linearised discrete steady "
                        "problem; docs/spectrum.md section 4)")
    p.add_argument("--count", type=float, nargs=3, default=None, metavar=("X0", "X1", "Y1"),
                   help="also count the eigenvalues with X0 <= Re sigma L/c_p <= X1, "
                        "|Im sigma L/c_p| <= Y1 by the argument principle (X1, Y1 raised to 1.5 "
                        "times the leading rate), e.g. --count 0.01 4 4; its det M "
                        "evaluations are kept in FILE.count-LABEL.npz until it converges, so an "
                        "interrupted or out-of-budget count goes on from them when rerun; "
                        "the eigenvalues counted are located and polished, and where one lies "
                        "right of the search's leading eigenvalue the leading rate is taken "
                        "from it")
    p.add_argument("--count-evals", type=int, default=None, metavar="N",
                   help="budget of det M evaluations per count (default 400; a walk "
                        "that needs more is reported failed, with no count; near the "
                        "imaginary axis one evaluation takes 5-25 s at N = 1000-2000)")
    p.add_argument("--guess", type=float, default=None, metavar="S",
                   help="start the first pulse's eigenvalue search at s L/c_p = S instead of "
                        "from the spectrum stored above it (deep pulses, whose rates are below "
                        "the search's 0.001 c_p/L, with none computed above; e.g. the law of "
                        "`slippulse steady rates`); the pulses after it track from it. Without "
                        "it such a pulse is found by the sign of det M on [1e-7, 1e-3] c_p/L "
                        "after the default search (about 3 min more at N = 3542)")
    add_executor_options(p, "pulses (with one pulse to compute and --count, the count's "
                            "determinants)")
    p.add_argument("--figure", default=None, metavar="PNG",
                   help="also draw s(tau_d) and the leading modes into this file")
    p.add_argument("-q", "--quiet", action="store_true", help="no progress bar")
    add_params_args(p)
    p.set_defaults(func=cmd_stability)


def _add_analyse(ss) -> None:
    p = ss.add_parser("analyse", help="analyse a pulse family file",
                      description="Per-pulse L, c_p, v_max, tau_max, tau_m, slip, G-bar, edge "
                                  "singularity; family scaling fit, G_c, delta_c, mode II. Results "
                                  "are written into FILE (attributes + a 'family' group) and printed.")
    p.add_argument("file", metavar="FILE", help="HDF5 family file")
    p.add_argument("--no-write", action="store_true", help="print only; leave FILE unchanged")
    p.add_argument("--cd-cs", type=float, nargs="+", default=None, metavar="RATIO",
                   help=f"c_d/c_s of the mode-II mapping (default {CD_CS_DEFAULTS}); each > 1")
    p.add_argument("--skip-unconverged", action="store_true",
                   help="leave out the pulses marked converged=False (default: refuse the file); "
                        "they are named in the output")
    add_params_args(p)
    p.set_defaults(func=cmd_analyse)


def register(sub) -> None:
    """``slippulse steady`` and its subcommands, in the order ``--help`` lists them: those of this
    module, and those of the modules that define their own (each a ``register(ss)``, imported
    when the parser is built, not with this module). A new command module adds its
    ``register`` to the tuple below."""
    from . import branches, convergence, divergence, existence_map, fold_ratio, long_domain
    from . import motion, rates, real_roots, referee, seed
    p_steady = sub.add_parser("steady", help="steady pulse solutions",
                              description="Steady self-healing pulses (mode III).")
    ss = p_steady.add_subparsers(dest="steady_command", metavar="SUBCOMMAND")
    ss.required = True
    for add in (_add_solve, _add_family, _add_stability, rates.register, existence_map.register,
                divergence.register,          # steady divergence, steady edges
                referee.register, fold_ratio.register, seed.register, long_domain.register,
                convergence.register, real_roots.register,
                _add_analyse, branches.register_steady, motion.register):
        add(ss)
