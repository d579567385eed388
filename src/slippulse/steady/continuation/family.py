"""The family run: natural continuation from the built-in guess down in τ_d, then the deep
continuation, every pulse appended atomically to one HDF5 file (a rerun resumes)."""
from __future__ import annotations

import math
import os
import time

import numpy as np

from ...core.h5io import list_pulses, read_pulse, write_pulse
from ...core.params import ParameterError, Parameters
from ..solver import GridSpec, solve_pulse
from .arclength import DeepSettings
from .deep import march_arclength
from .gridcheck import check_grid_2n
from .natural import (FAMILY_POINTS, FAMILY_POINTS_BETA, _Base, _beta_bridge, _judge, _targets,
                      tangent_step)
from .report import FamilyReport


def _hint_first(first, n_points):
    return (f"start nearer the built-in guess's pulse (--from 1.2) or use more points "
            f"(--points {2 * n_points})")


def _hint_deep(n_points):
    return (f"rerun with --deep arclength (pseudo-arclength; follows a fold) or more points per "
            f"pulse (--points {2 * n_points}); the run resumes from the pulses already in the file")


def _hint_arc(why, n_points, deep):
    if "grid check" in why.get("reason", ""):
        return ("skip the check (--no-grid-check; the pulses then carry their N-dependence, "
                "docs/analysis.md)")
    if "grid-converged" in why.get("reason", ""):
        return (f"allow larger grids (--max-points above {deep.n_max}) or skip the check "
                f"(--no-grid-check; pulses then carry their N-dependence)")
    if "fold" in why:
        return (f"check whether the family turns back: tau_d rose along the march at "
                f"tau_d/tau_min ~ {why['fold']:.6f} (a fold, or grid noise if the rise is below the "
                f"N-to-2N shift); more points (--points {2 * n_points}) or a smaller --ds-min")
    if "max_length" in why.get("reason", ""):
        return "raise --max-length"
    return (f"more points per pulse (--points {2 * n_points}; measured: N = 4000 went from 1.0109 "
            f"to 1.0106 where N = 2000 stopped) or smaller arclength steps (--ds-min below "
            f"{deep.ds_min}); the run resumes from the file")



def run_family(params: Parameters, out: str, start: float = 1.2, stop: float = 1.015,
               step: float = 0.005, n_points: int | None = None, min_step: float | None = None,
               spec: GridSpec = GridSpec(), progress=None, max_iter: int = 12,
               beta_switch: float = 0.85, deep: str = "beta",
               deep_settings: DeepSettings | None = None) -> FamilyReport:
    """Solve the family from `start` down to `stop` (τ_d/τ_min) and write it to `out`.

    Parameters
    ----------
    n_points : grid points of every pulse; None: :data:`FAMILY_POINTS` (fewer while β ≤
        :data:`FAMILY_POINTS_BETA`, more beyond, in the β-steps and the deep continuation).
    progress : callable(ratio, pulse_or_None, message), optional
        Called after every attempted solve.
    max_iter : Newton iterations allowed per predicted step (converging steps take ≤ 6).
    beta_switch : above this β, step in β (τ_d free) directly: there τ_d-steps of the family's
        size fail (measured: every τ_d step from β ≈ 0.9 on needed halving or failed).
    deep : how to continue where natural continuation stalls: "beta" (steps in β with τ_d free,
        bridged back to each target) or "arclength" (pseudo-arclength in (ln(1−β), τ_d), which
        follows a fold in τ_d, with pulses written at every multiple of ``deep_settings.fine`` and
        each grid-checked at N vs 2N; see :class:`DeepSettings`).
    """
    deep_settings = _check_family_args(params, start, stop, step, deep, deep_settings)
    n_tau, n_deep = FAMILY_POINTS if n_points is None else (n_points, n_points)
    if min_step is None:
        min_step = 0.5 * step          # two failed τ_d steps in a row switch to stepping in β
    t0 = time.perf_counter()
    rep = FamilyReport()
    # resume: continue below the deepest converged pulse already in `out`
    base = _resume(params, out, rep)
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
        _write(params, out, pulse, rep)
        base = _Base.of(sol, pulse.L)
    h = step
    tried = set()
    while targets:
        target = targets[0]
        if h < min_step - 1e-15 or base.beta > beta_switch:
            # natural continuation stalls near τ_min: step in β with τ_d free past the target,
            # then solve at the exact target from the β-solutions that bracket it
            why = {}
            if deep == "arclength":
                reached = _arc_bridge(params, out, (base.xi, base.y, base.beta), base.q, stop,
                                      n_deep, spec, deep_settings, rep, progress, why)
                if not reached:
                    rep.stop(why.get("reason", "arclength continuation failed"),
                             _hint_arc(why, n_deep, deep_settings))
                targets = []
                break
            res = _beta_bridge(params, out, base, target, n_deep, spec, max_iter, rep, progress,
                               why)
            if res is None:
                rep.stop(why.get("reason", "beta-stepping failed"), _hint_deep(n_deep))
                break
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
        _write(params, out, pulse, rep)
        base = new
        if abs(trial - target) < 1e-12:
            targets.pop(0)
        h = min(step, 2.0 * h)
    rep.wall_time = time.perf_counter() - t0
    return rep


def _check_family_args(params, start, stop, step, deep, deep_settings) -> DeepSettings:
    """Bad input of :func:`run_family` as ParameterError naming the argument and its valid range."""
    if deep not in ("beta", "arclength"):
        raise ParameterError(f"deep={deep!r} is invalid: must be 'beta' or 'arclength'")
    for name, val in (("from", start), ("to", stop)):
        if not math.isfinite(val):
            raise ParameterError(f"{name}={val!r} is invalid: must be a finite tau_d/tau_min")
        params.check_tau_d(val * params.tau_min)
    if not (stop < start):
        raise ParameterError(f"to={stop} is invalid: must be < from={start} (continuation goes down)")
    if not (0 < step <= start - stop + 1e-12) or not math.isfinite(step):
        raise ParameterError(f"step={step} is invalid: must be in (0, from - to = {start - stop:.4g}]")
    return DeepSettings() if deep_settings is None else deep_settings


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
    rep.reached, rep.reached_beta, rep.reached_L = last.tau_d_ratio, last.beta, last.L
    return _Base(last.xi, np.log(last.v), last.beta, last.tau_d_ratio)


def _attempt(params, ratio, rep: FamilyReport, progress, **solve_args):
    """Solve at τ_d/τ_min = ``ratio`` and judge it; the attempt is counted in ``rep`` and shown
    by ``progress``. Returns (solution, pulse, ok, message)."""
    sol = solve_pulse(params, ratio, **solve_args)
    pulse, ok, msg = _judge(sol)
    rep.record(ratio, ok, msg)
    if progress:
        progress(ratio, pulse if ok else None, msg)
    return sol, pulse, ok, msg


def _write(params, out, pulse, rep: FamilyReport) -> None:
    """Append a converged pulse to the family file (atomic per pulse) and count it."""
    write_pulse(out, pulse, params)
    rep.wrote(pulse)


def _deep_write(params, out, sol, labels, n_state, spec, deep, rep, progress):
    """Write an arclength pulse (after the grid check, N doubled until it passes). Returns None when
    written (or its label was taken by the check's 2N solution already), else the reason."""
    n = n_state["n"]
    pulse = sol.to_pulse()
    if deep.check:
        while True:
            fine, db, dl = check_grid_2n(params, sol, n, spec, 4 * deep.max_iter)
            fpulse, fok, fmsg = _judge(fine)
            msg = (f"grid check at {pulse.tau_d_ratio:.6f}: N={n} -> {2 * n}: dbeta={db:.2e}, "
                   f"dL/L={dl:.2e} ({fmsg})")
            passed = fok and db <= deep.tol_beta and dl <= deep.tol_L
            rep.record(float(fine.x[-1]), passed, msg)
            if progress:
                progress(float(fine.x[-1]), fpulse if fok else None, msg)
            if passed:
                pulse = fpulse
                pulse.extra.update({"grid_check_n": n, "grid_check_dbeta": db,
                                    "grid_check_dL_rel": dl})
                break
            if not fok:
                return (f"the grid check of the pulse at tau_d/tau_min="
                        f"{sol.to_pulse().tau_d_ratio:.6f} failed: the re-solve at N={2 * n} did "
                        f"not converge ({fmsg})")
            if 4 * n > deep.n_max:
                return (f"the pulse at tau_d/tau_min={sol.to_pulse().tau_d_ratio:.6f} is not "
                        f"grid-converged: N={n} -> {2 * n} changes beta by {db:.1e} and L by "
                        f"{dl:.1e} (rel), and N={4 * n} would exceed max points {deep.n_max}")
            n, sol = 2 * n, fine
            n_state["n"] = n
    if pulse.label in labels:
        return None
    write_pulse(out, pulse, params)
    rep.wrote(pulse)
    labels.add(pulse.label)
    return None


def _arc_bridge(params, out, guess, current, stop, n_points, spec, deep, rep, progress, why):
    """Continue from `guess` = (xi, y, β) at τ_d/τ_min = current by pseudo-arclength down to
    `stop`, writing an arclength pulse whenever its 4-decimal label is new and it lies at least
    fine/2 below the last one written. Returns True when `stop` was reached, else False with the
    reason in `why` ("fold" is set where τ_d first turns back up along the march)."""
    n_state = {"n": n_points}
    labels = set(list_pulses(out)) if os.path.exists(out) else set()
    last_q = current
    for sol, (t_a, t_Q) in march_arclength(params, (guess[0], guess[1], guess[2], current),
                                           n_points, spec, deep, progress, rep, why,
                                           n_of=lambda: n_state["n"]):
        q = float(sol.x[-1])
        if t_Q > 0 and "fold" not in why:
            why["fold"] = q
        pulse = sol.to_pulse()
        if pulse.label not in labels and q <= last_q - 0.5 * deep.fine:
            reason = _deep_write(params, out, sol, labels, n_state, spec, deep, rep, progress)
            if reason is not None:
                why["reason"] = reason
                return False
            last_q = q
        if q <= stop + 1e-12:
            return True
        if pulse.L >= deep.max_length:
            why["reason"] = f"pulse length L={pulse.L:.4g} m passed max_length={deep.max_length:g} m"
            return False
    return False
