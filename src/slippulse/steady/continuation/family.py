"""The family run: natural continuation from the built-in guess down in τ_d, then the deep
continuation, every pulse appended atomically to one HDF5 file (a rerun resumes)."""
from __future__ import annotations

import dataclasses
import math
import os
import time

import numpy as np

from ...core.h5io import list_pulses, read_pulse, unique_label, write_pulse
from ...core.params import ParameterError, Parameters
from ..solver import MAX_POINTS, GridSpec, solve_pulse
from .arclength import DeepSettings
from .deep import DeepMarch, march_arclength
from .relay import recentre, refine_front, zone_offset
from .gridcheck import as_both, check_grid_2n, check_pulse
from .tolerance import GRID_TOLERANCE, GridTolerance
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
               deep_settings: DeepSettings | None = None, tolerance: GridTolerance = GRID_TOLERANCE,
               n_max: int = MAX_POINTS, max_length: float = math.inf,
               deep_points: int | None = None, log=None) -> FamilyReport:
    """Solve the family from `start` down to `stop` (τ_d/τ_min) and write it to `out`.

    Parameters
    ----------
    n_points : grid points of every pulse; None: :data:`FAMILY_POINTS` (fewer while β ≤
        :data:`FAMILY_POINTS_BETA`, more beyond, in the β-steps and the deep continuation).
    progress : callable(tau_d_ratio, pulse_or_None, message), optional
        Called after every attempted solve.
    max_iter : Newton iterations allowed per predicted step (converging steps take ≤ 6).
    beta_switch : above this β, step in β (τ_d free) directly: there τ_d-steps of the family's
        size fail (measured: every τ_d step from β ≈ 0.9 on needed halving or failed).
    deep : how to continue where natural continuation stalls: "beta" (steps in β with τ_d free,
        bridged back to each target) or "arclength" (pseudo-arclength in (ln(1−β), τ_d), which
        follows a fold in τ_d, with pulses written at every multiple of ``deep_settings.fine`` and
        each grid-checked at N vs 2N; see :class:`DeepSettings`), or "auto" (the product's
        default, :func:`_auto_deep`): natural steps and β-steps until β ≥ :data:`DEEP_BETA` or a
        stall, then the pseudo-arclength march on a grid deformed with the pulse; in "auto" every
        pulse written is grid-checked by :func:`check_pulse` (``tolerance``, grids up to
        ``n_max``) and carries the check's figures as attributes; one that cannot pass is written
        with ``converged=False``, ``status="failed"`` and the reason.
    tolerance : the grid criterion ("auto" only); n_max : largest grid of a check.
    max_length : "auto": stop (cleanly, ``rep.limit_reached``) once a pulse is this long (m).
    deep_points : "auto": N of the grid the deep march starts on (default :data:`DEEP_POINTS`).
    log : callable(str), optional; one line per grid check ("auto").
    """
    deep_settings = _check_family_args(params, start, stop, step, deep, deep_settings)
    auto = deep == "auto"
    if auto:
        deep_points = DEEP_POINTS if deep_points is None else deep_points
        _check_auto_args(params, out, tolerance, n_max, deep_points, max_length)
    n_tau, n_deep = FAMILY_POINTS if n_points is None else (n_points, n_points)
    if min_step is None:
        min_step = 0.5 * step          # two failed τ_d steps in a row switch to stepping in β
    t0 = time.perf_counter()
    rep = FamilyReport()
    write = (_CheckedWriter(params, out, rep, tolerance, n_max, log) if auto else
             (lambda sol, pulse, method: _write(params, out, pulse, rep)))

    def go_deep(start_sol, resolve, previous=None, held=False, cap=None):
        _auto_deep(params, out, start_sol, stop, rep, progress, write, deep_points if resolve
                   else None, max_length, n_max, tolerance, spec,
                   settings=auto_deep_settings(deep_settings), previous=previous, log=log,
                   held=held, cap=cap)
        rep.wall_time = time.perf_counter() - t0
        return rep

    # resume: continue below the deepest converged pulse already in `out`
    base = _resume(params, out, rep)
    if auto and base is not None and (rep.resumed_method == "arclength"
                                      or base.beta >= DEEP_BETA):
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
        if auto and base.beta >= DEEP_BETA:
            return go_deep((base.xi, base.y, base.beta, base.q), resolve=True)
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
                               why, write=write, beta_cap=DEEP_BETA if auto else None)
            if res is None and auto:
                # the β-steps reached DEEP_BETA (or stalled): the deep march from the last pulse
                last = why.get("last")
                if last is not None:
                    return go_deep((last.xi, last.x[:-1], last.beta, float(last.x[-1])),
                                   resolve=True)
                return go_deep((base.xi, base.y, base.beta, base.q), resolve=True)
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
        write(sol, pulse, "tau_d")
        base = new
        if abs(trial - target) < 1e-12:
            targets.pop(0)
        h = min(step, 2.0 * h)
    rep.wall_time = time.perf_counter() - t0
    return rep


def _check_family_args(params, start, stop, step, deep, deep_settings) -> DeepSettings:
    """Bad input of :func:`run_family` as ParameterError naming the argument and its valid range."""
    if deep not in ("beta", "arclength", "auto"):
        raise ParameterError(f"deep={deep!r} is invalid: must be 'auto', 'beta' or 'arclength'")
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
            why["reason"] = f"pulse length L={pulse.L:.5g} m passed max_length={deep.max_length:g} m"
            return False
    return False


# ------------------------------------------------------------------ the product's deep family
#: "auto": above this β the family goes on by the deep march (τ_d ≈ 1.0125 τ_min, L ≈ 114 m,
#: where the deformed-grid march of docs/analysis.md started; below it the β-steps converge).
DEEP_BETA = 0.99
#: "auto": the most healing-front refinements in one run where the deep march's corrector stalls
#: (:func:`_relay`)
RELAYS = 20
#: "auto": points of the adapted grid the deep march starts on (then deformed with the pulse;
#: the per-pulse check refines the body or doubles N as needed).
DEEP_POINTS = 2000
#: "auto": the deep march's settings (those of ``steady/deep_march.py --stretch``, measured to
#: L = 1.56 km without a failed step, docs/analysis.md); where its corrector fails at ds_min, the
#: healing front's cells are refined and the march goes on (``relay``, issue 18 item 4); the
#: grid's front zone moved by the last step's change of L and ln v predicted along the secant
#: (``predictor="secant"``: 5-6 times the L per hour of "tangent" at 7.2 km, docs/steady.md §8).
#: Not ``creep``: it sped up 9 steps from the 2550 m seed 1.8×, but held the march at small ds,
#: where the check's error grew (5e-6 → 9e-5 in 250 m at 3.2 km), and from scratch it drove N to
#: 5374 by 1 km (stop 44, docs/steady.md §8). Once the march is held (``hold``, stop 45) ds sits
#: at its cap, and there the corrector starts with chord iterations (``chord_held``), stops
#: creeping after 4 iterations (``creep_held``), the cap lowers itself after failures near it
#: (``cap_shrink``) and the zone about the healing front is kept on its drop (``recentre``)
#: (stop 46), and the corrector's line search is the natural monotonicity test
#: (``natural_held``: the ‖r‖₂ test had held the corrector at λ ≤ 1/4 where its Jacobian is
#: nearly singular along the healing front's motion, stop 47); the march from scratch to
#: 1.5 km is never held, so none of these acts there.
AUTO_DEEP = DeepSettings(ds_max=0.4, stretch=True, max_iter=25, relay=RELAYS, predictor="secant",
                         hold=True, chord_held=True, creep_held=4, cap_shrink=0.8,
                         recentre=0.001, natural_held=True)


def auto_deep_settings(deep_settings: DeepSettings | None = None) -> DeepSettings:
    """The "auto" deep march's settings: :data:`AUTO_DEEP` with the caller's smallest step
    ``deep_settings.ds_min`` (``--ds-min``) and write spacing ``deep_settings.spacing``
    (``--spacing``), the settings of the arclength march that "auto" takes from the user."""
    if deep_settings is None:
        return AUTO_DEEP
    return dataclasses.replace(AUTO_DEEP, ds_min=deep_settings.ds_min,
                               spacing=deep_settings.spacing)


def _check_auto_args(params, out, tol, n_max, deep_points, max_length):
    """Bad input of the "auto" family as ParameterError: a grid check that cannot fit in
    ``n_max``, a file of other parameters, of an older family format, or of another tolerance."""
    if not (isinstance(n_max, int) and n_max >= 2 * deep_points - 1):
        raise ParameterError(f"max-points={n_max} is invalid: the grid check of the deep pulses "
                             f"needs at least 2N - 1 = {2 * deep_points - 1} (N = {deep_points})")
    if not max_length > 0:
        raise ParameterError(f"max-length={max_length} is invalid: must be > 0 (m)")
    if not os.path.exists(out):
        return
    for label in list_pulses(out):
        pu, p_file = read_pulse(out, label)
        if p_file != params:
            raise ParameterError(f"out={out!r}: stored parameters differ from this run's; use "
                                 f"another --out")
        if "grid_check_passed" not in pu.extra:
            raise ParameterError(f"out={out!r}: pulse {label} carries no grid check (a family "
                                 f"file of an older format, or of --deep beta/arclength); use "
                                 f"another --out")
        t = (float(pu.extra.get("grid_check_tol_beta", math.nan)),
             float(pu.extra.get("grid_check_tol_L", math.nan)))
        if t != (tol.beta, tol.L):
            raise ParameterError(f"out={out!r}: pulse {label} was checked to beta {t[0]:g}, L "
                                 f"{t[1]:g}, not this run's {tol.beta:g}, {tol.L:g}; use "
                                 f"another --out")


#: The deep march's grid checks start from the last check's fine pulse, transported, and its LU
#: (check_pulse ``warm``; BENCHMARKS.md "Stop 44").
WARM_CHECKS = True

#: After a grid check whose plain Newton re-solve crept (and the homotopy finished it), this many
#: checks start with the homotopy before plain Newton is tried again (docs/steady.md, stop 36).
HOMOTOPY_FIRST = 4


class _CheckedWriter:
    """Write a pulse after :func:`check_pulse`: the checked pulse with the check's figures, or,
    when it cannot pass, the pulse marked failed with the reason. A label already taken by a
    pulse at another τ_d (closer than the label's six decimals) is never overwritten: the new
    pulse gets a longer label (:func:`unique_label`). Returns the :class:`GridCheck`."""

    def __init__(self, params, out, rep, tol, n_max, log):
        self.params, self.out, self.rep, self.tol, self.n_max, self.log = \
            params, out, rep, tol, n_max, log
        self.taken = {}
        # checks start with plain Newton; one whose plain re-solve crept and needed the homotopy
        # (beyond ≈ 5.3 km every one did: 5 iterations of a 2N − 1 LU, ≈ 39 s of ≈ 120 s) makes
        # the next HOMOTOPY_FIRST checks start with the homotopy (check_pulse(plain=False)); then
        # plain Newton is tried again
        self.homotopy_first = 0
        # the last deep check's (x, x_fine, LU): the next check's warm start (check_pulse)
        self.warm = ()
        if os.path.exists(out):
            for label in list_pulses(out):
                self.taken[label] = read_pulse(out, label)[0].tau_d_ratio

    def __call__(self, sol, pulse, method, extra=None):
        # the local refinements are for the deformed grids of the deep march (the error sits in
        # the stretched body, or, beyond 2 km, at the leading edge, which the deformation moves
        # rigidly while it steepens: located before refining); adapted grids are refined
        # everywhere (N doubled)
        res = check_pulse(self.params, sol, self.tol, self.n_max, log=self.log,
                          body_levels=2 if method == "arclength" else 0,
                          locate=method == "arclength", plain=self.homotopy_first == 0,
                          warm=self.warm if method == "arclength" and WARM_CHECKS else None)
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


def _told(rep, progress, q, new, msg):
    """One re-solve of the march's pulse at τ_d/τ_min = ``q`` (``new``: the solution, or None
    when it failed) counted in ``rep`` and shown by ``progress``."""
    rep.record(float(new.x[-1]) if new is not None else q, new is not None, msg)
    if progress:
        progress(q, new.to_pulse() if new is not None else None, msg)


def _relay(params, march, settings, write, rep, progress, log=None) -> bool:
    """The fallback of the "auto" march where the corrector on the deformed grid failed at
    ``ds_min``: the march's current pulse re-solved with its healing front's steep cells split
    (:func:`~.relay.refine_front`, ``settings.relay_levels``), grid-checked and written by
    ``write`` like every deep pulse (with ``relaid`` and the change from the unrefined pulse at
    fixed τ_d, ``relay_dbeta``, ``relay_dL_rel``); if it passes, the march restarts from the
    checked pulse (its grid then deformed as before) with ds = 2 ``ds_min``. Returns whether the
    march goes on; otherwise ``march`` is left failed, its message saying why (a refined pulse
    that failed its check is written failed, as any other)."""
    sol = march.sol
    q = float(sol.x[-1])
    new, dbeta, dL_rel, msg = refine_front(params, sol, levels=settings.relay_levels)
    _told(rep, progress, q, new, msg)
    if log:
        log(f"corrector stalled at tau_d/tau_min={q:.7f} (L={march.L:.1f} m): {msg}")
    if new is None:
        march.message += f"; then {msg}"
        return False
    pulse = new.to_pulse()
    extra = {"relaid": True, "relay_dbeta": float(dbeta), "relay_dL_rel": float(dL_rel)}
    if settings.hold:
        extra.update(_held_state(march))
    res = write(new, pulse, "arclength", extra=extra)
    if not res.passed:
        march.message += (f"; then {msg}, but the refined pulse failed its grid check "
                          f"({res.message})")
        return False
    march.restart(res.sol, 2.0 * settings.ds_min)
    return True


def _held_state(march) -> dict:
    """What a resumed march needs of this one's step control: whether ds was held, and its cap
    (attributes ``march_held``, ``march_cap`` of every pulse the auto march writes)."""
    return {"march_held": bool(march.held), "march_cap": float(march.cap)}


def _recentre(params, march, settings, rep, progress, log=None) -> bool:
    """``settings.recentre``: once the march is held, where the finest cells of the zone about
    the healing front lie more than ``recentre`` · L from its steep drop
    (:func:`~.stretch.block_offset`), move the zone back onto it and go on from the re-solved
    pulse (:func:`~.relay.recentre`; not written: the next written pulse is grid-checked as
    every one). A re-solve that does not converge leaves the march as it was. Returns whether
    the grid moved."""
    if not (settings.recentre > 0 and settings.stretch and march.held
            and march.status == "running"):
        return False
    sol = march.sol
    try:
        offset = zone_offset(params, sol, settings.back_zone)
    except ValueError:
        return False
    if not abs(offset[0]) > settings.recentre * march.L:
        return False
    new, _, _, _, msg = recentre(params, sol, settings.front_zone, settings.back_zone,
                                 offset=offset)
    q = float(sol.x[-1])
    _told(rep, progress, q, new, msg)
    if log:
        log(f"at tau_d/tau_min={q:.7f} (L={march.L:.1f} m): {msg}")
    if new is None:
        return False
    march.replace(new)
    return True


def _auto_deep(params, out, start, stop, rep, progress, write, resolve_n, max_length, n_max,
               tol, spec, settings=AUTO_DEEP, previous=None, log=None, held=False, cap=None):
    """The deep part of the "auto" family: from ``start`` = (xi, y, β, q) — re-solved at its τ_d
    on ``resolve_n`` adapted points unless None (then taken on its own grid) — the
    pseudo-arclength march on the deformed grid (:class:`DeepMarch`, :data:`AUTO_DEEP`), every
    accepted pulse (with ``settings.spacing``: the first after L has grown by that fraction, and
    the last) grid-checked and written by ``write``; the march goes on from the checked
    (refined) pulse. Ends at ``stop``, at ``max_length`` (clean: ``rep.limit_reached``), or where
    the march fails (``rep.stop``). ``previous`` = (β, q, L) of the pulse before ``start`` (a resumed
    march): the first ds is that step's, its dL/ds the first predicted change of L
    (:meth:`DeepMarch.resume_step`). ``held``: the pulse resumed from was written by a march
    whose ds was held (``settings.hold``, its ``march_held`` attribute): the resumed march starts
    held instead of learning it again from a failed tangent step (≈ 2.5 min at N = 6614, stop 45).
    Every pulse written by a march with ``settings.hold`` carries ``march_held`` and
    ``march_cap`` (:attr:`DeepMarch.cap`); ``cap``, that of the pulse resumed from, is restored
    with ``held``."""
    xi, y, beta, q = start
    if resolve_n is not None:
        sol = solve_pulse(params, q, n_points=resolve_n, guess=(xi, y, beta), passes=0,
                          max_iter=30, spec=spec)
        pulse, ok, msg = _judge(sol)
        rep.record(q, ok, f"deep start re-solved at N={resolve_n}: {msg}")
        if progress:
            progress(q, pulse if ok else None, f"deep start N={resolve_n}: {msg}")
        start = as_both(params, sol) if ok else start
    march = DeepMarch(params, start, settings=settings, stop=stop, max_length=max_length,
                      on_attempt=lambda r, p, m: (rep.record(r, p is not None, m),
                                                  progress and progress(r, p, m)))
    if previous is not None:              # a resumed march: go on at the pace it had
        march.resume_step(*previous)
    march.held = bool(held and settings.hold and settings.stretch)
    if march.held and cap is not None and math.isfinite(cap):
        # the cap the march had (settings.cap_shrink), and the first step within it
        march.cap = min(max(float(cap), settings.ds_min), settings.predictor_ds_max)
        march.ds = min(march.ds, march.cap)
    _recentre(params, march, settings, rep, progress, log)
    last_L = march.L
    relays, relaid_at = 0, None
    while march.status == "running":
        if march.step() is not None:
            # the corrector on the deformed grid stalled at ds_min: refine the healing front (at
            # most settings.relay times, never twice without an accepted step between), go on
            if relays < settings.relay and relaid_at != march.n_steps:
                relays, relaid_at = relays + 1, march.n_steps
                if _relay(params, march, settings, write, rep, progress, log):
                    last_L = march.L
                    continue
            break
        if march.status == "running" and march.L < last_L * (1.0 + settings.spacing):
            continue                  # a continuation step, not written (settings.spacing)
        res = write(march.sol, march.sol.to_pulse(), "arclength",
                    extra=_held_state(march) if settings.hold else None)
        last_L = march.L
        if res.passed and res.sol is not march.sol:
            march.replace(res.sol)
        if res.passed:
            _recentre(params, march, settings, rep, progress, log)
    rep.deep_steps += march.n_steps
    if march.status == "failed":
        rep.stop(march.message, "smaller arclength steps or more points; rerun the same command "
                                "to resume from the file")
    elif march.status == "stopped":
        rep.limit_reached = True
        rep.stop_reason = march.message
