"""The family run: natural continuation from the built-in guess down in τ_d, then the deep
continuation driver, every pulse grid-checked and appended atomically to one HDF5 file (a rerun
resumes)."""
from __future__ import annotations

import math
import os
import time

import numpy as np

from ...core.h5io import list_pulses, read_pulse, unique_label, write_pulse
from ...core.params import ParameterError, Parameters
from ..solver import MAX_POINTS, GridSpec, solve_pulse
from .driver import Continuation
from .gridcheck import as_both, check_pulse
from .strategy import AUTO, Strategy
from .tolerance import GRID_TOLERANCE, GridTolerance
from .natural import (FAMILY_POINTS, FAMILY_POINTS_BETA, _Base, _beta_bridge, _judge, _targets,
                      tangent_step)
from .report import FamilyReport


def _hint_first(first, n_points):
    return (f"start nearer the built-in guess's pulse (--from 1.2) or use more points "
            f"(--points {2 * n_points})")


def run_family(params: Parameters, out: str, start: float = 1.2, stop: float = 1.015,
               step: float = 0.005, n_points: int | None = None, min_step: float | None = None,
               spec: GridSpec = GridSpec(), progress=None, max_iter: int = 12,
               beta_switch: float = 0.85, strategy: Strategy = AUTO,
               tolerance: GridTolerance = GRID_TOLERANCE, n_max: int = MAX_POINTS,
               max_length: float = math.inf, deep_points: int | None = None,
               spacing: float | None = None, log=None, monitor=None,
               check: bool = True) -> FamilyReport:
    """Solve the family from `start` down to `stop` (τ_d/τ_min) into `out`, every pulse
    grid-checked; a rerun resumes from the deepest converged pulse of `out`.

    Natural steps in τ_d (tangent predictor, chord corrector), halving on failure; in β (τ_d
    free) once β > ``beta_switch`` or two τ_d steps in a row failed; from β ≥ :data:`DEEP_BETA`
    the pseudo-arclength driver (:class:`~.driver.Continuation`) with ``strategy``. Every pulse is
    checked by :func:`check_pulse` (``tolerance``, grids up to ``n_max``) and written with the
    check's figures; one that cannot pass is written with ``converged=False``,
    ``status="failed"`` and the reason.

    Parameters
    ----------
    n_points : grid points of the natural steps; None: :data:`FAMILY_POINTS`.
    progress : callable(tau_d_ratio, pulse_or_None, message), optional; after every attempt.
    max_iter : Newton iterations allowed per natural step (converging steps take ≤ 6).
    strategy : the deep driver's :class:`~.strategy.Strategy` (default :data:`~.strategy.AUTO`).
    max_length : stop (cleanly, ``rep.limit_reached``) once a pulse is this long (m).
    deep_points : N of the adapted grid the deep driver starts on (default :data:`DEEP_POINTS`).
    spacing : the deep driver writes an accepted pulse once L has grown by this fraction since
        the last written one (0: every one; the last always); default :data:`SPACING`.
    log : callable(str), optional; one line per grid check, relay or recentring.
    monitor : callable(solution, pulse) → dict or None, optional: called on every checked pulse
        just before it is written; the dict's items are stored as the pulse's attributes (a
        per-pulse computation along the family, e.g. a bifurcation test function).
    check : False: write the pulses unchecked (for a walk whose pulses only guide a solve, as
        ``steady solve`` below 1.2; such a file is refused on resume by a checked run).
    """
    check_family_args(params, start, stop, step)
    deep_points = DEEP_POINTS if deep_points is None else deep_points
    spacing = SPACING if spacing is None else spacing
    _check_args(params, out, tolerance, n_max, deep_points, max_length, spacing, check)
    n_tau, n_deep = FAMILY_POINTS if n_points is None else (n_points, n_points)
    if min_step is None:
        min_step = 0.5 * step          # two failed τ_d steps in a row switch to stepping in β
    t0 = time.perf_counter()
    rep = FamilyReport()
    rep.strategy = str(strategy)
    write = (_CheckedWriter if check else _PlainWriter)(params, out, rep, tolerance, n_max, log,
                                                        monitor, strategy.check)

    def go_deep(start_sol, resolve, previous=None, held=False, cap=None):
        _deep(params, start_sol, stop, rep, progress, write, deep_points if resolve else None,
              max_length, spec, strategy, spacing, previous=previous, log=log, held=held,
              cap=cap)
        rep.wall_time = time.perf_counter() - t0
        return rep

    # resume: continue below the deepest converged pulse already in `out`
    base = _resume(params, out, rep)
    if base is not None and (rep.resumed_method == "arclength" or base.beta >= DEEP_BETA):
        if base.q > stop + 1e-12 and rep.reached_L < max_length:
            return go_deep((base.xi, base.y, base.beta, base.q),
                           resolve=rep.resumed_method != "arclength",
                           previous=rep.resumed_previous, held=rep.resumed_held,
                           cap=rep.resumed_cap)
        rep.wall_time = time.perf_counter() - t0
        return rep
    targets = [t for t in _targets(start, stop, step) if base is None or t < base.q - 1e-12]
    if base is None:
        # the first pulse from the built-in guess
        first = targets.pop(0)
        sol, pulse, ok, msg = _attempt(params, first, rep, progress, n_points=n_tau, spec=spec)
        if not ok:
            rep.stop(f"the first pulse, at tau_d/tau_min={first:.4f}, from the built-in guess "
                     f"failed ({msg})", _hint_first(first, n_tau))
            rep.wall_time = time.perf_counter() - t0
            return rep
        write(sol, pulse, "tau_d")
        base = _Base.of(sol, pulse.L)
    h = step
    tried = set()
    while targets:
        target = targets[0]
        if base.beta >= DEEP_BETA:
            return go_deep((base.xi, base.y, base.beta, base.q), resolve=True)
        if h < min_step - 1e-15 or base.beta > beta_switch:
            # natural continuation stalls near τ_min: step in β with τ_d free past the target,
            # then solve at the exact target from the β-solutions that bracket it
            why = {}
            res = _beta_bridge(params, out, base, target, n_deep, spec, max_iter, rep, progress,
                               why, write=write, beta_cap=DEEP_BETA)
            if res is None:
                # the β-steps reached DEEP_BETA (or stalled): the deep driver from the last pulse
                last = why.get("last")
                if last is not None:
                    return go_deep((last.xi, last.x[:-1], last.beta, float(last.x[-1])),
                                   resolve=True)
                return go_deep((base.xi, base.y, base.beta, base.q), resolve=True)
            sol, base = res
            targets.pop(0)
            h = step
            continue
        trial = max(target, round(base.q - h, 10))
        if (base.q, trial) in tried:
            h *= 0.5
            continue
        tried.add((base.q, trial))
        # predict along the family tangent (on the last grid while L is within REGRID of the
        # L it was laid out for), correct by chord and Newton iterations
        n_here = n_tau if base.beta <= FAMILY_POINTS_BETA else n_deep
        sol, new = tangent_step(params, base, trial, "tau_d", n_here, spec, max_iter=max_iter)
        pulse, ok, msg = _judge(sol)
        rep.record(trial, ok, msg)
        if progress:
            progress(trial, pulse if ok else None, msg)
        # accept, or halve the step and retry
        if not ok:
            h *= 0.5
            continue
        # write the accepted pulse; it becomes the base of the next step
        write(sol, pulse, "tau_d")
        base = new
        if abs(trial - target) < 1e-12:
            targets.pop(0)
        h = min(step, 2.0 * h)
    rep.wall_time = time.perf_counter() - t0
    return rep


def check_family_args(params, start, stop, step) -> None:
    """Bad input of :func:`run_family` as ParameterError naming the argument and its valid range."""
    for name, val in (("from", start), ("to", stop)):
        if not math.isfinite(val):
            raise ParameterError(f"{name}={val!r} is invalid: must be a finite tau_d/tau_min")
        try:
            params.check_tau_d(val * params.tau_min)
        except ParameterError as exc:
            raise ParameterError(f"{name}={val:g} is invalid: {exc}") from None
    if not (stop < start):
        raise ParameterError(f"to={stop} is invalid: must be < from={start} (continuation goes down)")
    if not (0 < step <= start - stop + 1e-12) or not math.isfinite(step):
        raise ParameterError(f"step={step} is invalid: must be in (0, from - to = {start - stop:.4g}]")


def _resume(params, out, rep: FamilyReport):
    """The deepest converged pulse already in ``out`` as a :class:`_Base` (no Hilbert matrix: the
    first step lays out a new grid), or None; a file of other parameters is an error."""
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
    return _Base(last.xi, np.log(last.v), last.beta, last.tau_d_ratio)


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
    pulse, ok, msg = _judge(sol)
    rep.record(tau_d_ratio, ok, msg)
    if progress:
        progress(tau_d_ratio, pulse if ok else None, msg)
    return sol, pulse, ok, msg


# ------------------------------------------------------------------ the deep family
#: Above this β the family goes on by the pseudo-arclength driver (τ_d ≈ 1.0125 τ_min, L ≈ 114 m);
#: below it the β-steps converge.
DEEP_BETA = 0.99
#: The deep driver writes (and grid-checks) a pulse once L has grown by this fraction since the
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


#: After a grid check whose plain Newton re-solve crept (and the homotopy finished it), this many
#: checks start with the homotopy before plain Newton is tried again (beyond ≈ 5 km every plain
#: re-solve crept: 5 iterations of a 2N − 1 LU wasted per check).
HOMOTOPY_FIRST = 4


class _CheckedWriter:
    """Write a pulse after :func:`check_pulse`: the checked pulse with the check's figures (and
    the ``monitor``'s), or, when it cannot pass, the pulse marked failed with the reason. A label
    already taken by a pulse at another τ_d (closer than the label's six decimals) is never
    overwritten: the new pulse gets a longer label (:func:`unique_label`). Returns the
    :class:`GridCheck`."""

    def __init__(self, params, out, rep, tol, n_max, log, monitor=None, method=None):
        self.params, self.out, self.rep, self.tol, self.n_max, self.log = \
            params, out, rep, tol, n_max, log
        self.monitor = monitor
        self.method = AUTO.check if method is None else method      # the grid check
        self.taken = {}
        self.homotopy_first = 0
        # the last deep check's (x, x_fine, LU): the next check's warm start (check_pulse)
        self.warm = ()
        if os.path.exists(out):
            for label in list_pulses(out):
                self.taken[label] = read_pulse(out, label)[0].tau_d_ratio

    def __call__(self, sol, pulse, method, extra=None):
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
        if self.monitor is not None:
            p.extra.update(self.monitor(res.sol, p) or {})
        self.rep.checks += 1
        if not res.passed:
            p.converged = False
            p.extra["status"] = "failed"
            p.extra["message"] = f"grid check failed: {res.message}"
            self.rep.failed_checks.append((p.tau_d_ratio, res.message))
        base = p.label
        p.name = unique_label(p.tau_d_ratio, self.taken)
        if p.name != base and self.log:
            self.log(f"{base}: taken by the pulse at {self.taken[base]:.9f}; written as {p.name}")
        write_pulse(self.out, p, self.params)
        self.taken[p.label] = p.tau_d_ratio
        if res.passed:
            self.rep.wrote(p)
        return res


class _PlainWriter(_CheckedWriter):
    """Write a pulse as it is, unchecked (``run_family(check=False)``)."""

    def __call__(self, sol, pulse, method, extra=None):
        from .driver import Accepted
        p = as_both(self.params, sol).to_pulse() if method == "arclength" else pulse
        p.extra["continuation"] = method
        p.extra.update(extra or {})
        if self.monitor is not None:
            p.extra.update(self.monitor(sol, p) or {})
        p.name = unique_label(p.tau_d_ratio, self.taken)
        write_pulse(self.out, p, self.params)
        self.taken[p.label] = p.tau_d_ratio
        self.rep.wrote(p)
        return Accepted(True, sol)


def _deep(params, start, stop, rep, progress, write, resolve_n, max_length, spec, strategy,
          spacing, previous=None, log=None, held=False, cap=None):
    """The deep family: from ``start`` = (xi, y, β, q) — re-solved at its τ_d on ``resolve_n``
    adapted points unless None (then taken on its own grid) — the :class:`Continuation` with
    ``strategy``, every pulse it hands over checked and written by ``write``. Ends at ``stop``,
    at ``max_length`` (clean: ``rep.limit_reached``), or where the march fails (``rep.stop``).
    A resumed march goes on at its pace (``previous`` = (β, q, L) of the pulse before ``start``)
    and, if its pulse was written held, held at its ``cap``."""
    xi, y, beta, q = start
    if resolve_n is not None:
        sol = solve_pulse(params, q, n_points=resolve_n, guess=(xi, y, beta), passes=0,
                          max_iter=30, spec=spec)
        pulse, ok, msg = _judge(sol)
        rep.record(q, ok, f"deep start re-solved at N={resolve_n}: {msg}")
        if progress:
            progress(q, pulse if ok else None, f"deep start N={resolve_n}: {msg}")
        start = as_both(params, sol) if ok else start

    def on_attempt(r, p, m):
        rep.record(r, p is not None, m)
        if progress:
            progress(r, p, m)

    march = Continuation(params, start, strategy, spec=spec, stop=stop, max_length=max_length,
                         spacing=spacing, on_attempt=on_attempt, log=log,
                         on_accept=lambda s, extra: write(s, s.to_pulse(), "arclength",
                                                          extra=extra))
    if previous is not None:              # a resumed march: go on at the pace it had
        march.resume_step(*previous)
    if held:
        march.hold(cap)
    march.run()
    rep.deep_steps += march.n_steps
    if march.status == "failed":
        rep.stop(march.message, "smaller arclength steps (--ds-min) or more points; rerun the "
                                "same command to resume from the file")
    elif march.status == "stopped":
        rep.limit_reached = True
        rep.stop_reason = march.message
