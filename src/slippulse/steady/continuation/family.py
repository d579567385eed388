"""The family run: the continuation driver from the built-in guess down in τ_d — natural τ_d
steps, β steps where they stall, the pseudo-arclength march from β ≈ 0.99 — every pulse
grid-checked and appended atomically to one HDF5 file (a rerun resumes); or the march from a
stored pulse, in either direction."""
from __future__ import annotations

import dataclasses
import math
import os
import time

import numpy as np

from ...core.h5io import list_pulses, read_pulse, unique_label, write_pulse
from ...core.params import ParameterError, Parameters
from ..solver import MAX_POINTS, GridSpec, solve_pulse
from .driver import Accepted, Continuation
from .gridcheck import as_both, check_pulse, monitor_first
from .natural import PulseOnGrid, judge_pulse, round_targets
from .report import FamilyReport
from .strategy import (AUTO, BETA_STEPS, BRANCH, FAMILY_POINTS, FROM_PULSE, NATURAL, Strategy,
                       TargetSteps)
from .tolerance import GRID_TOLERANCE, GridTolerance


def _hint_first(first, n_points):
    return (f"start nearer the built-in guess's pulse (--from 1.2) or use more points "
            f"(--points {2 * n_points})")


@dataclasses.dataclass(frozen=True)
class FamilyRun:
    """The options of one family run (:func:`run_family`), one value, checked by
    :func:`run_family` before any solve (:func:`check_family_args` or :func:`check_origin`, and the
    grid-check limits); its ``strategy`` is printed in the report and stored with every deep pulse.

    start, stop, step : the natural τ_d targets (τ_d/τ_min), from the built-in guess's pulse down.
    n_points : grid points of the natural steps; None: :data:`~.strategy.FAMILY_POINTS`.
    min_step, beta_switch, max_iter : the natural steps' smallest step, the β at which they hand
    over to β steps, and Newton's iterations per step (converging steps take ≤ 6).
    strategy : the deep driver's :class:`~.strategy.Strategy` (default :data:`~.strategy.AUTO`).
    tolerance, n_max : the grid check's criterion and its largest grid.
    max_length : stop (cleanly, ``rep.limit_reached``) once a pulse is this long (m).
    deep_points : N of the adapted grid the deep driver starts on (default :data:`DEEP_POINTS`).
    spacing : the deep driver writes an accepted pulse once L has changed by this fraction since
    the last written one (0: every one; the last always); default :data:`SPACING`.
    check : False: write the pulses unchecked (for a walk whose pulses only guide a solve, as
    ``steady solve`` below 1.2; such a file is refused on resume by a checked run).
    checks : where the grid checks run: "inline" (in the march's process, each before the next
    step) or "beside" (a second process while the march goes on, :mod:`~.beside`; the monitor
    stays with the march; the same pulses, to the solver's tolerance).
    """
    start: float = 1.2
    stop: float = 1.015
    step: float = 0.005
    n_points: int | None = None
    min_step: float | None = None
    spec: GridSpec = dataclasses.field(default_factory=GridSpec)
    max_iter: int = 12
    beta_switch: float = 0.85
    strategy: Strategy = AUTO
    tolerance: GridTolerance = GRID_TOLERANCE
    n_max: int = MAX_POINTS
    max_length: float = math.inf
    deep_points: int | None = None
    spacing: float | None = None
    check: bool = True
    checks: str = "inline"

    def replace(self, **changes) -> "FamilyRun":
        return dataclasses.replace(self, **changes)


def run_family(params: Parameters, out: str, run: FamilyRun = FamilyRun(), *, origin=None,
               progress=None, log=None, monitor=None) -> FamilyReport:
    """Solve the family from `start` down to `stop` (τ_d/τ_min) into `out`, every pulse
    grid-checked; a rerun resumes from the deepest converged pulse of `out`.

    One driver (:class:`~.driver.Continuation`) with three strategies in turn: natural τ_d steps
    onto the targets (:data:`~.strategy.NATURAL` with ``step``, ``min_step``, ``beta_switch``,
    ``max_iter``, ``n_points``); where they stall, β steps past the next target and onto it
    (:data:`~.strategy.BETA_STEPS`), then τ_d steps again; from β ≥ :data:`DEEP_BETA` the
    pseudo-arclength march with ``strategy``. Every pulse is checked by :func:`check_pulse`
    (``tolerance``, grids up to ``n_max``) and written with the check's figures; one that cannot
    pass is written with ``converged=False``, ``status="failed"`` and the reason.

    Parameters
    ----------
    run : the run's options (:class:`FamilyRun`).
    progress : callable(tau_d_ratio, pulse_or_None, message), optional; after every attempt.
    log : callable(str), optional; one line per grid check, relay or recentring.
    monitor : callable(solution, pulse) → dict or None, optional: called on every checked pulse
        just before it is written; the dict's items are stored as the pulse's attributes (a
        per-pulse computation along the family, e.g. a bifurcation test function).
    origin : a converged :class:`~slippulse.core.h5io.Pulse` (e.g. of another branch): instead
        of the family from ``start``, continue it on its own grid by the pseudo-arclength march
        (``strategy``) toward ``stop``, above or below its τ_d, through folds; ``out`` must not
        hold pulses yet.
    """
    run = run.replace(deep_points=DEEP_POINTS if run.deep_points is None else run.deep_points,
                      spacing=SPACING if run.spacing is None else run.spacing)
    if origin is not None:
        check_origin(params, origin, run.stop, out)
    else:
        check_family_args(params, run.start, run.stop, run.step)
    _check_args(params, out, run.tolerance, run.n_max, run.deep_points, run.max_length,
                run.spacing, run.check)
    check_checks(run.checks, run.check)
    runner = _Runner(params, out, run, progress, log, monitor)
    try:
        if origin is not None:
            runner.from_origin(origin)
        else:
            runner.family()
    finally:
        runner.write.close()
    runner.rep.wall_time = time.perf_counter() - runner.t0
    return runner.rep


class _Runner:
    """One family run's state: the options, the report, the checked writer and the callbacks;
    its stages (the march from a stored pulse; resume or the first pulse; the natural steps;
    the deep march) are its methods."""

    def __init__(self, params, out, run: FamilyRun, progress, log, monitor):
        self.params, self.out, self.run = params, out, run
        self.progress, self.log = progress, log
        self.t0 = time.perf_counter()
        self.rep = FamilyReport()
        self.rep.strategy = str(run.strategy)
        self.write = (_CheckedWriter if run.check else _PlainWriter)(
            params, out, self.rep, run.tolerance, run.n_max, log, monitor, run.strategy.check)
        if run.checks == "beside":
            from .beside import BesideWriter
            self.write = BesideWriter(self.write)
        self.n_tau, self.n_deep = (FAMILY_POINTS if run.n_points is None
                                   else (run.n_points, run.n_points))

    def on_attempt(self, r, p, m):
        self.rep.record(r, p is not None, m)
        if self.progress:
            self.progress(r, p, m)

    def from_origin(self, origin):
        """The pseudo-arclength march from a stored pulse, on its own grid, toward ``stop``."""
        rep = self.rep
        rep.direction = 1 if self.run.stop > origin.tau_d_ratio else -1
        self.deep((origin.xi, np.log(origin.v), origin.beta, origin.tau_d_ratio), resolve=False)
        if rep.stopped_early:
            rep.hint = ("smaller arclength steps (--ds-min); to go on, continue the last pulse "
                        "written with --from-pulse OUT:LABEL into a new --out")

    def family(self):
        """Resume below the deepest converged pulse of the file (or solve the first pulse from
        the built-in guess), then the natural steps, then the deep march."""
        params, run, rep = self.params, self.run, self.rep
        base = _resume(params, self.out, rep)
        if base is not None and (rep.resumed_method == "arclength" or base.beta >= DEEP_BETA):
            if base.q > run.stop + 1e-12 and rep.reached_L < run.max_length:
                self.deep(_as_tuple(base), resolve=rep.resumed_method != "arclength",
                          previous=rep.resumed_previous, held=rep.resumed_held,
                          cap=rep.resumed_cap)
            return
        targets = [t for t in round_targets(run.start, run.stop, run.step)
                   if base is None or t < base.q - 1e-12]
        if base is None:
            first = targets.pop(0)
            sol, pulse, ok, msg = _attempt(params, first, rep, self.progress,
                                           n_points=self.n_tau, spec=run.spec)
            if not ok:
                rep.stop(f"the first pulse, at tau_d/tau_min={first:.4f}, from the built-in "
                         f"guess failed ({msg})", _hint_first(first, self.n_tau))
                return
            res = self.write(sol, pulse, "tau_d")
            if hasattr(res, "discard"):        # checked beside: written once its check is back
                res.result()
            base = PulseOnGrid.of(sol, pulse.L)
        self.natural(base, targets)

    def march(self, strategy, start, targets):
        """One run of the driver with a natural ``strategy`` from ``start`` onto ``targets``."""
        m = Continuation(self.params, start, strategy, spec=self.run.spec, targets=targets,
                         beta_cap=DEEP_BETA, on_attempt=self.on_attempt, log=self.log,
                         on_accept=lambda sol, extra: self.write(
                             sol, sol.to_pulse(), extra["continuation"], extra=extra))
        m.run()
        return m

    def natural(self, base, targets):
        """τ_d steps onto the targets until they stall; then β steps with τ_d free past the
        next target and onto it; where they fail or reach DEEP_BETA, the deep march from their
        last pulse."""
        run = self.run
        tau_steps, beta_steps = natural_strategies(run.step, run.min_step, run.beta_switch,
                                                   run.max_iter, self.n_tau, self.n_deep)
        while targets:
            if base.beta >= DEEP_BETA:
                return self.deep(_as_tuple(base), resolve=True)
            m = self.march(tau_steps, base, targets)
            base, targets = m.current, m.targets
            if m.status != "stalled":
                continue
            m = self.march(beta_steps, base, targets[:1])
            base = m.current
            if m.status != "finished":
                return self.deep(_as_tuple(base), resolve=True)
            targets = targets[1:]
        return None

    def deep(self, start, resolve, previous=None, held=False, cap=None):
        """The deep family: from ``start`` = (xi, y, β, q) — re-solved at its τ_d on the deep
        grid when ``resolve``, else taken on its own grid — the :class:`Continuation` with the
        run's strategy, every pulse it hands over checked and written. Ends at ``stop``, at
        ``max_length`` (clean: ``rep.limit_reached``), or where the march fails (``rep.stop``).
        A resumed march goes on at its pace (``previous`` = (β, q, L) of the pulse before
        ``start``) and, if its pulse was written held, held at its ``cap``."""
        params, run, rep = self.params, self.run, self.rep
        xi, y, beta, q = start
        if resolve:
            n = run.deep_points
            sol = solve_pulse(params, q, n_points=n, guess=(xi, y, beta), passes=0,
                              max_iter=30, spec=run.spec)
            pulse, ok, msg = judge_pulse(sol)
            rep.record(q, ok, f"deep start re-solved at N={n}: {msg}")
            if self.progress:
                self.progress(q, pulse if ok else None, f"deep start N={n}: {msg}")
            start = as_both(params, sol) if ok else start
        march = Continuation(params, start, run.strategy, spec=run.spec, stop=run.stop,
                             max_length=run.max_length, spacing=run.spacing,
                             on_attempt=self.on_attempt, log=self.log,
                             on_accept=lambda s, extra: self.write(s, s.to_pulse(), "arclength",
                                                                   extra=extra))
        if previous is not None:              # a resumed march: go on at the pace it had
            march.resume_step(*previous)
        if held:
            march.hold(cap)
        march.run()
        _deep_outcome(rep, march)


def natural_strategies(step, min_step, beta_switch, max_iter, n_tau, n_deep):
    """The τ_d and β strategies of :func:`run_family` (:data:`~.strategy.NATURAL` and
    :data:`~.strategy.BETA_STEPS` with the run's step, switch, iterations and grid points)."""
    tau_corrector = dataclasses.replace(NATURAL.corrector, max_iter=max_iter)
    tau_steps = NATURAL.replace(
        corrector=tau_corrector,
        steps=TargetSteps(step=step, min_step=min_step, beta_switch=beta_switch),
        grid=dataclasses.replace(NATURAL.grid, n_points=n_tau, n_points_above=n_deep))
    beta_steps = BETA_STEPS.replace(
        steps=dataclasses.replace(BETA_STEPS.steps, landing=tau_corrector),
        grid=dataclasses.replace(BETA_STEPS.grid, n_points=n_deep))
    return tau_steps, beta_steps


def _as_tuple(p: PulseOnGrid):
    """(xi, y, β, q) of a pulse on its grid: the deep driver's start."""
    return p.xi, p.y, p.beta, p.q


def check_ratio(params, name, val) -> None:
    """A τ_d/τ_min option ``name`` that is not finite or outside (τ_min, τ_peak) as
    ParameterError naming it and the valid range."""
    if not math.isfinite(val):
        raise ParameterError(f"{name}={val!r} is invalid: must be a finite tau_d/tau_min")
    try:
        params.check_tau_d(val * params.tau_min)
    except ParameterError as exc:
        raise ParameterError(f"{name}={val:g} is invalid: {exc}") from None


def check_origin(params, origin, stop, out) -> None:
    """Bad input of :func:`run_family` from ``origin`` as ParameterError: a pulse that did not
    converge, a ``stop`` at its own τ_d or outside (τ_min, τ_peak), an ``out`` that already holds
    pulses."""
    if not origin.converged:
        raise ParameterError(f"from-pulse={origin.label} is invalid: the pulse did not converge")
    check_ratio(params, "to", stop)
    if abs(stop - origin.tau_d_ratio) < 1e-9:
        raise ParameterError(f"to={stop:g} is invalid: it is the pulse's own tau_d/tau_min")
    if os.path.exists(out) and list_pulses(out):
        raise ParameterError(f"out={out!r} is invalid: it holds pulses already; a --from-pulse "
                             f"run writes a new file")


def check_family_args(params, start, stop, step) -> None:
    """Bad input of :func:`run_family` as ParameterError naming the argument and its valid range."""
    for name, val in (("from", start), ("to", stop)):
        check_ratio(params, name, val)
    if not (stop < start):
        raise ParameterError(f"to={stop} is invalid: must be < from={start} (continuation goes down)")
    if not (0 < step <= start - stop + 1e-12) or not math.isfinite(step):
        raise ParameterError(f"step={step} is invalid: must be in (0, from - to = {start - stop:.4g}]")


def _resume(params, out, rep: FamilyReport):
    """The deepest converged pulse already in ``out`` as a :class:`~.natural.PulseOnGrid` (no
    Hilbert matrix: the first step lays out a new grid), or None; a file of other parameters is
    an error."""
    if not os.path.exists(out):
        return None
    done = []
    for label in list_pulses(out):
        pu, p_file = read_pulse(out, label)
        if p_file != params:
            raise ParameterError(f"{out}: stored parameters differ from this run's; use another --out")
        if pu.converged:
            done.append(pu)
    if not done:
        return None
    last = min(done, key=lambda p: p.tau_d_ratio)
    rep.resumed_from = last.label
    rep.resumed_method = str(last.extra.get("continuation", ""))
    rep.resumed_previous = _previous_arclength(done, last.tau_d_ratio)
    rep.resumed_held = bool(last.extra.get("march_held", False))
    rep.resumed_cap = float(last.extra.get("march_cap", math.nan))
    rep.reached, rep.reached_beta, rep.reached_L = last.tau_d_ratio, last.beta, last.L
    return PulseOnGrid(last.xi, np.log(last.v), last.beta, last.tau_d_ratio)


def _previous_arclength(pulses, q_last):
    """(β, τ_d/τ_min, L) of the deepest converged arclength pulse of ``pulses`` above ``q_last``
    (the step before the one a resumed march starts from), or None."""
    above = [p for p in pulses if p.converged and p.extra.get("continuation") == "arclength"
             and p.tau_d_ratio > q_last + 1e-12]
    if not above:
        return None
    p = min(above, key=lambda p: p.tau_d_ratio)
    return p.beta, p.tau_d_ratio, p.L


def _attempt(params, tau_d_ratio, rep: FamilyReport, progress, **solve_args):
    """Solve at τ_d/τ_min = ``tau_d_ratio`` and judge it; the attempt is counted in ``rep`` and
    shown by ``progress``. Returns (solution, pulse, ok, message)."""
    sol = solve_pulse(params, tau_d_ratio, **solve_args)
    pulse, ok, msg = judge_pulse(sol)
    rep.record(tau_d_ratio, ok, msg)
    if progress:
        progress(tau_d_ratio, pulse if ok else None, msg)
    return sol, pulse, ok, msg


# ------------------------------------------------------------------ the deep family
#: Above this β the family goes on by the pseudo-arclength driver (τ_d ≈ 1.0125 τ_min, L ≈ 114 m);
#: below it the β-steps converge.
DEEP_BETA = 0.99


def from_pulse_strategy(pulse) -> Strategy:
    """The march of ``steady family --from-pulse``: :data:`~.strategy.FROM_PULSE` (the deep
    family's tuned :data:`~.strategy.AUTO`) from a one-hump pulse at β ≥ :data:`DEEP_BETA`, else
    :data:`~.strategy.BRANCH` (free steps: AUTO's held cap is the deep family's scale)."""
    deep = int(pulse.extra.get("n_humps", 1)) == 1 and pulse.beta >= DEEP_BETA
    return FROM_PULSE if deep else BRANCH


#: The deep driver writes (and grid-checks) a pulse once L has changed by this fraction since the
#: last written one: beyond 2 km a step moves L by 0.2–0.4 %, and a check at 2N − 1 costs several
#: steps, so checking every step spent about half the march on checks. The march goes on from
#: each checked pulse, so a wide spacing lets the deformed grid drift between checks (at 0.04 a
#: check at 2.5 km had to double N); 0.01 is what the family to 10 km was marched with.
SPACING = 0.01
#: Points of the adapted grid the deep driver starts on (then deformed with the pulse; the
#: per-pulse check refines the body or doubles N as needed).
DEEP_POINTS = 2000


def _check_args(params, out, tol, n_max, deep_points, max_length, spacing, check=True):
    """Bad input of the family as ParameterError: a grid check that cannot fit in ``n_max``, a
    bad ``max_length`` or ``spacing``, a file of other parameters, of an older family format, or
    of another tolerance."""
    if not (isinstance(n_max, int) and n_max >= 2 * deep_points - 1):
        raise ParameterError(f"max-points={n_max} is invalid: the grid check of the deep pulses "
                             f"needs at least 2N - 1 = {2 * deep_points - 1} (N = {deep_points})")
    if not max_length > 0:
        raise ParameterError(f"max-length={max_length} is invalid: must be > 0 (m)")
    if not (0 <= spacing <= 0.5):
        raise ParameterError(f"spacing={spacing} is invalid: must be in [0, 0.5] (a fraction of L)")
    if not os.path.exists(out):
        return
    for label in list_pulses(out):
        pu, p_file = read_pulse(out, label)
        if p_file != params:
            raise ParameterError(f"out={out!r}: stored parameters differ from this run's; use "
                                 f"another --out")
        if not check:
            continue
        if "grid_check_passed" not in pu.extra:
            raise ParameterError(f"out={out!r}: pulse {label} carries no grid check (a family "
                                 f"file of an older format); use another --out")
        t = (float(pu.extra.get("grid_check_tol_beta", math.nan)),
             float(pu.extra.get("grid_check_tol_L", math.nan)))
        if t != (tol.beta, tol.L):
            raise ParameterError(f"out={out!r}: pulse {label} was checked to beta {t[0]:g}, L "
                                 f"{t[1]:g}, not this run's {tol.beta:g}, {tol.L:g}; use "
                                 f"another --out")


#: Where the grid checks run (:attr:`FamilyRun.checks`).
CHECKS = ("inline", "beside")


def check_checks(checks, check=True) -> None:
    """Bad :attr:`FamilyRun.checks` as ParameterError: not one of :data:`CHECKS`, or 'beside'
    without grid checks."""
    if checks not in CHECKS or (checks == "beside" and not check):
        raise ParameterError(f"checks={checks!r} is invalid: must be one of {', '.join(CHECKS)}"
                             + ("" if check else "; 'beside' needs the grid checks on"))

#: After a grid check whose plain Newton re-solve crept (and the homotopy finished it), this many
#: checks start with the homotopy before plain Newton is tried again (beyond ≈ 5 km every plain
#: re-solve crept: 5 iterations of a 2N − 1 LU wasted per check).
HOMOTOPY_FIRST = 4


class Checker:
    """The grid check of one pulse and its monitor's attributes (:func:`check_pulse`), with the
    state one check hands the next: the last deep check's fine pulse and LU (its warm start)
    and whether the homotopy was needed lately. Returns (:class:`GridCheck`, the
    :class:`~slippulse.core.h5io.Pulse` to write, its attributes set)."""

    def __init__(self, params, tol, n_max, log=None, monitor=None, method=None):
        self.params, self.tol, self.n_max, self.log = params, tol, n_max, log
        self.monitor = monitor
        self.method = AUTO.check if method is None else method      # the grid check
        self.homotopy_first = 0
        # the last deep check's (x, x_fine, LU): the next check's warm start (check_pulse)
        self.warm = ()

    def __call__(self, sol, method, extra=None, pulse=None):
        # the monitor first where the pulse has no family tangent: its fold test finds one,
        # which the check's normal line then takes (monitor_first; ``pulse``: sol's, if in hand)
        first, previous = monitor_first(self.monitor, sol, pulse)
        # the deformed grids of the deep driver are refined where the error sits (located
        # first); adapted grids everywhere (N doubled)
        deep = method == "arclength"
        res = check_pulse(self.params, sol, self.tol, self.n_max, log=self.log,
                          body_levels=2 if deep else 0, locate=deep,
                          plain=self.homotopy_first == 0, warm=self.warm if deep else None,
                          method=self.method)
        self.warm = res.warm if res.warm is not None else ()
        if self.homotopy_first:
            self.homotopy_first -= 1
        elif res.homotopy:
            self.homotopy_first = HOMOTOPY_FIRST
        p = res.sol.to_pulse()
        p.extra.update(res.attrs(self.tol))
        p.extra["continuation"] = method
        if extra:
            p.extra.update(extra)
        if first is not None and not res.replaced:
            p.extra.update(first)
        elif self.monitor is not None:
            if first is not None and hasattr(self.monitor, "previous"):
                self.monitor.previous = previous      # the pulse monitored is not the one kept
            p.extra.update(self.monitor(res.sol, p) or {})
        if not res.passed:
            p.converged = False
            p.extra["status"] = "failed"
            p.extra["message"] = f"grid check failed: {res.message}"
        return res, p


class _CheckedWriter:
    """Write a pulse after its :class:`Checker`: the checked pulse with the check's figures (and
    the ``monitor``'s), or, when it cannot pass, the pulse marked failed with the reason. A label
    already taken by a pulse at another τ_d (closer than the label's six decimals) is never
    overwritten: the new pulse gets a longer label (:func:`unique_label`). Returns the
    :class:`GridCheck`."""

    def __init__(self, params, out, rep, tol, n_max, log, monitor=None, method=None):
        self.params, self.out, self.rep, self.log = params, out, rep, log
        self.check = Checker(params, tol, n_max, log, monitor, method)
        self.taken = {}
        if os.path.exists(out):
            for label in list_pulses(out):
                self.taken[label] = read_pulse(out, label)[0].tau_d_ratio

    def __call__(self, sol, pulse, method, extra=None):
        res, p = self.check(sol, method, extra, pulse)
        self.put(p, res.message)
        return res

    def put(self, p, message=""):
        """Write the checked pulse ``p`` under a free label and count it in the report."""
        self.rep.checks += 1
        if not p.converged:
            self.rep.failed_checks.append((p.tau_d_ratio, message))
        base = p.label
        p.name = unique_label(p.tau_d_ratio, self.taken)
        if p.name != base and self.log:
            self.log(f"{base}: taken by the pulse at {self.taken[base]:.9f}; written as {p.name}")
        write_pulse(self.out, p, self.params)
        self.taken[p.label] = p.tau_d_ratio
        if p.converged:
            self.rep.wrote(p)

    def close(self):
        """Nothing to release (:class:`~.beside.BesideWriter` stops its process)."""


class _PlainWriter(_CheckedWriter):
    """Write a pulse as it is, unchecked (``run_family(check=False)``)."""

    def __call__(self, sol, pulse, method, extra=None):
        p = as_both(self.params, sol).to_pulse() if method == "arclength" else pulse
        p.extra["continuation"] = method
        p.extra.update(extra or {})
        if self.check.monitor is not None:
            p.extra.update(self.check.monitor(sol, p) or {})
        p.name = unique_label(p.tau_d_ratio, self.taken)
        write_pulse(self.out, p, self.params)
        self.taken[p.label] = p.tau_d_ratio
        self.rep.wrote(p)
        return Accepted(True, sol)


def _deep_outcome(rep, march) -> None:
    """The deep march's end in the report: its steps, a failure (with the hint), or the clean
    stop at the length limit."""
    rep.deep_steps += march.n_steps
    if march.status == "failed":
        rep.stop(march.message, "smaller arclength steps (--ds-min) or more points; rerun the "
                                "same command to resume from the file")
    elif march.status == "stopped":
        rep.limit_reached = True
        rep.stop_reason = march.message
