"""Natural-parameter continuation of the pulse family in τ_d, with remeshing and step halving.

Each pulse is predicted from the previous converged one along the tangent of the family (from the
Jacobian of the steady equations with both β and τ_d free), on the previous grid while the pulse
length L stays within `regrid` of the L that grid was laid out for, otherwise on a new grid adapted
to the previous pulse (the domain follows L and the healing length c_p D/v_stick, so it grows as
the pulse grows); it is corrected by chord iterations with the LU of that Jacobian, and by Newton
when they stop contracting. A failed solve halves the step (down to `min_step`); every converged
pulse is appended atomically to one HDF5 file, so a rerun with the same output resumes from the
last converged pulse.
"""
from __future__ import annotations

import math
import os
import time
from dataclasses import dataclass, field

import numpy as np
import scipy.linalg as sla

from ..core.h5io import list_pulses, read_pulse, write_pulse
from ..core.params import ParameterError, Parameters
from .analysis import pulse_length
from .newton import newton
from .solver import GridSpec, SteadySolution, front_pin, fwhm, interpolate, regrid_guess, solve_pulse
from .equations import SteadyProblem


@dataclass
class FamilyReport:
    """What a continuation run did."""

    written: list = field(default_factory=list)      # labels written this run
    resumed_from: str | None = None
    failures: list = field(default_factory=list)     # (tau_d_ratio, message), every failed solve
    attempts: int = 0                                # solves attempted this run (failed included)
    reached: float = float("nan")                    # smallest τ_d/τ_min converged
    reached_beta: float = float("nan")               # β and L of that pulse
    reached_L: float = float("nan")
    stopped_early: bool = False
    stop_reason: str = ""                            # why the run stopped before `stop`
    hint: str = ""                                   # what would take it further
    wall_time: float = 0.0

    def record(self, ratio, ok, message):
        """Count one attempted solve; a failed one is kept with its τ_d/τ_min and message."""
        self.attempts += 1
        if not ok:
            self.failures.append((float(ratio), message))

    def wrote(self, pulse):
        """A converged pulse was written: the run has reached its τ_d."""
        self.written.append(pulse.label)
        if not (pulse.tau_d_ratio >= self.reached):         # NaN-safe: the first, or a deeper one
            self.reached, self.reached_beta, self.reached_L = pulse.tau_d_ratio, pulse.beta, pulse.L

    def stop(self, reason, hint):
        self.stopped_early, self.stop_reason, self.hint = True, reason, hint


def _targets(start, stop, step):
    n = int(round((start - stop) / step))
    return [round(start - k * step, 10) for k in range(n + 1)]


@dataclass
class _Base:
    """A converged pulse on its grid, the base of the next tangent step: ln v on ξ, β, q = τ_d/τ_min,
    the grid's Hilbert matrix (None: not built), the phase condition (pin node, ln v there) and
    the pulse length the grid was laid out for."""

    xi: np.ndarray
    y: np.ndarray
    beta: float
    q: float
    H: np.ndarray | None = None
    pin: int = 0
    y_pin: float = 0.0
    L_grid: float = math.nan

    @classmethod
    def of(cls, sol: SteadySolution, L_grid=math.nan):
        """The base of a converged solution (x = (y, β) at fixed τ_d or (y, q) at fixed β)."""
        prob = sol.problem
        q = float(sol.x[-1]) if prob.free == "tau_d" else float(prob.tau_d_ratio)
        return cls(prob.xi, sol.x[:-1].copy(), sol.beta, q, prob.H, prob.pin_index, prob.y_pin,
                   L_grid)


#: Re-lay the grid once L differs from the L it was laid out for by more than this fraction.
REGRID = 0.1


def tangent_step(params, base: _Base, value, fixed, n_points, spec=GridSpec(), max_iter=12,
                 regrid=REGRID):
    """One continuation step from a converged pulse to τ_d/τ_min = value (fixed="tau_d"; unknowns
    y, β) or to β = value (fixed="beta"; unknowns y, q). Returns (SteadySolution, its _Base).

    Notes
    -----
    grid: the base's own (with its Hilbert matrix) while n_points is unchanged and
    |L/L_grid − 1| ≤ regrid, else a grid adapted to the base pulse with ln v interpolated onto it.
    tangent: J = ∂(Δ, pin)/∂(y, β, q) at the base (``SteadyProblem(free="both")``), split into the
    columns of the unknowns J_x and of the stepped parameter J_p; LU of J_x; t = −J_x⁻¹ J_p.
    predict: with dp = value − p_base, the scalar unknown + dp t; ln v stretched behind the pin by
    s = exp(dp d ln L/dp) (d ln L/dp from t by a finite difference of the FWHM) plus dp times the
    part of t_y that the stretch does not hold (t_y + (ξ − ξ_pin) y′ d ln L/dp behind the pin).
    correct: :func:`newton` with the LU of J_x (chord iterations, then Newton if they stall).
    """
    t0 = time.perf_counter()
    L = fwhm(base.xi, np.exp(base.y), params.v_star)
    keep = (base.H is not None and base.xi.size == n_points and abs(L / base.L_grid - 1) <= regrid)
    if keep:
        xi, y, H, k, ky, L_grid = base.xi, base.y, base.H, base.pin, base.y_pin, base.L_grid
    else:
        xi, y = regrid_guess(params, base.q, base.xi, base.y, base.beta, n_points, spec)
        k, _ = front_pin(xi, y, math.log(params.v_stick(base.q * params.tau_min)))
        H, ky, L_grid = None, float(y[k]), L
    # tangent: J_x t = −J_p at the base
    both = SteadyProblem(params, base.q, xi, k, ky, free="both", H=H)
    _, J = both.residual_and_jacobian(np.concatenate([y, [base.beta, base.q]]))
    n = xi.size
    if fixed == "tau_d":
        cols, p, dp = np.arange(n + 1), n + 1, value - base.q
    else:
        cols, p, dp = np.r_[np.arange(n), n + 1], n, value - base.beta
    lu = sla.lu_factor(J[:, cols], check_finite=False)
    t = -sla.lu_solve(lu, J[:, p], check_finite=False)
    # predict: ln v stretched behind the pin by s = e^{dp d ln L/dp} (near τ_min the healing edge
    # moves by many of its own widths per step, which the linear tangent cannot carry), plus the
    # part of the tangent the stretch does not hold; the scalar unknown along the tangent
    eps = 1e-3 / max(float(np.abs(t[:n]).max()), 1e-12)
    dlnL = (math.log(fwhm(xi, np.exp(y + eps * t[:n]), params.v_star)) -
            math.log(fwhm(xi, np.exp(y), params.v_star))) / eps
    if not math.isfinite(dlnL):            # FWHM not measurable on the perturbed profile
        dlnL = 0.0
    behind = xi < xi[k]
    t_stretch = np.zeros(n)
    t_stretch[behind] = -(xi[behind] - xi[k]) * np.gradient(y, xi)[behind] * dlnL
    y = _stretch(xi, y, xi[k], math.exp(dp * dlnL)) + dp * (t[:n] - t_stretch)
    t = t[n:]
    if fixed == "tau_d":
        x0 = np.concatenate([y, [base.beta]]) + np.r_[np.zeros(n), dp * t]
        x0[-1] = min(max(x0[-1], 0.5 * base.beta), 1.0 - 0.5 * (1.0 - base.beta))
        prob = SteadyProblem(params, value, xi, k, ky, H=both.H)
    else:
        x0 = np.concatenate([y, [base.q]]) + np.r_[np.zeros(n), dp * t]
        if not _valid_q(params, x0[-1]):
            x0[-1] = base.q
        prob = SteadyProblem(params, x0[-1], xi, k, ky, H=both.H, free="tau_d", beta=value)
    x, st = newton(prob, x0, tol=1e-13, max_iter=max_iter, lu=lu)
    sol = SteadySolution(prob, x, st, time.perf_counter() - t0, 0)
    return sol, _Base.of(sol, L_grid)


def _valid_q(params, q):
    """Whether τ_d = q τ_min lies in (τ_min, τ_peak)."""
    return params.tau_min < q * params.tau_min < params.tau_peak


def solve_at_beta(params, guess, q_guess, beta, n_points, spec=GridSpec(), max_iter=40):
    """Solve with β fixed and τ_d/τ_min unknown, on a grid adapted to the guess (xi, y)."""
    xi, y = guess
    t0 = time.perf_counter()
    xn, yn = regrid_guess(params, q_guess, xi, y, beta, n_points, spec)
    k, _ = front_pin(xn, yn, np.log(params.v_stick(q_guess * params.tau_min)))
    prob = SteadyProblem(params, q_guess, xn, k, float(yn[k]), free="tau_d", beta=beta)
    x, st = newton(prob, np.concatenate([yn, [q_guess]]), tol=1e-13, max_iter=max_iter)
    return SteadySolution(prob, x, st, time.perf_counter() - t0, 1)


def march_in_beta(params, start, target, n_points, spec=GridSpec(), shrink=0.92,
                  min_shrink=0.97, progress=None, rep=None, why=None):
    """From solution `start` (a :class:`_Base`), step β toward 1 (1−β ← shrink·(1−β)) with τ_d
    free, until τ_d/τ_min ≤ target. Yields converged SteadySolutions; stops when a step below
    `min_shrink` fails. Each step is a :func:`tangent_step` in β (tangent predictor, chord
    corrector).

    Every attempt is counted in `rep` (a :class:`FamilyReport`), failed ones with their message;
    when the march gives up, ``why["reason"]`` says where and why.
    """
    base = start
    f = shrink
    while base.q > target:
        bnew = 1.0 - (1.0 - base.beta) * f
        sol, new = tangent_step(params, base, bnew, "beta", n_points, spec, max_iter=40)
        ok = sol.stats.converged
        msg = f"beta-step to {bnew:.6f}: {sol.stats.message}"
        if rep is not None:
            rep.record(float(sol.x[-1]), ok, msg)
        if progress:
            progress(float(sol.x[-1]), sol.to_pulse() if ok else None, msg)
        if not ok:
            f = 1.0 - 0.5 * (1.0 - f)
            if f > min_shrink:
                if why is not None:
                    why["reason"] = (f"beta-steps stopped converging at beta={base.beta:.6f}: the "
                                     f"step 1-beta <- {1 - 2 * (1 - f):.4f}(1-beta), the smallest "
                                     f"allowed, failed ({sol.stats.message})")
                return
            continue
        base = new
        f = shrink
        yield sol


def _judge(sol):
    """(pulse, ok, message): a solve is accepted when it converged to a single-hump pulse."""
    pulse = sol.to_pulse()
    ok = pulse.converged and pulse.extra["n_humps"] == 1
    msg = sol.stats.message
    if pulse.converged and not ok:
        msg = f"converged to a {pulse.extra['n_humps']}-hump solution: rejected"
    return pulse, ok, msg


def _beta_bridge(params, out, base, target, n_points, spec, max_iter, rep, progress, why):
    """March in β from `base` (a :class:`_Base`) until τ_d passes `target`, writing the
    intermediate pulses, then solve at `target` by a tangent step in τ_d from the first pulse past
    it (if that fails, from the bracketing pair interpolated in τ_d). Returns (solution, its base)
    for the continuation, or None on failure (reason in `why`)."""
    hi, lo = None, None
    for bsol in march_in_beta(params, base, target, n_points, spec, progress=progress, rep=rep,
                              why=why):
        q = float(bsol.x[-1])
        if q > target:
            bp = bsol.to_pulse()
            write_pulse(out, bp, params)
            rep.wrote(bp)
            hi = bsol
        else:
            lo = bsol
    if lo is None:
        return None
    # tangent step in τ_d from the pulse just past the target
    sol, new = tangent_step(params, _Base.of(lo, math.inf), target, "tau_d", n_points, spec,
                            max_iter=max_iter, regrid=math.inf)
    pulse, ok, msg = _judge(sol)
    rep.record(target, ok, msg)
    if progress:
        progress(target, pulse if ok else None, msg)
    if not ok:
        # the bracketing pair interpolated in τ_d, solved on a grid adapted to it
        if hi is None:
            hi_xi, hi_y, hi_q, hi_b = base.xi, base.y, base.q, base.beta
        else:
            hi_xi, hi_y, hi_q, hi_b = hi.xi, hi.x[:-1], float(hi.x[-1]), hi.beta
        w = (hi_q - target) / (hi_q - float(lo.x[-1]))
        y_t = (1 - w) * np.interp(lo.xi, hi_xi, hi_y) + w * lo.x[:-1]
        b_t = (1 - w) * hi_b + w * lo.beta
        sol = solve_pulse(params, target, n_points=n_points, guess=(lo.xi, y_t, b_t), spec=spec,
                          passes=0, max_iter=max_iter)
        pulse, ok, msg = _judge(sol)
        rep.record(target, ok, msg)
        if progress:
            progress(target, pulse if ok else None, msg)
        new = _Base.of(sol, pulse.L)
    if not ok:
        why["reason"] = (f"the solve at the target tau_d/tau_min={target:.4f} from the two "
                         f"bracketing beta-step pulses failed ({msg})")
        return None
    write_pulse(out, pulse, params)
    rep.wrote(pulse)
    return sol, new


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


#: Grid points per pulse of the family by default: (while β ≤ FAMILY_POINTS_BETA, beyond). With
#: the order-4 state both are within 1e-5 in β and 1e-4 in L of N = 4000 (docs/steady.md §3.3);
#: N = 1000 leaves ripples of 0.05 in ln v behind the peak near τ_min (20 "humps" at 1.015; τ_d
#: steps to 1.03 rejected as 11- and 2-hump solutions, measured); 1250 not (one hump at
#: 1.03–1.015, within 8.8e-7 in β and 1.2e-5 in L of N = 4000, BENCHMARKS.md), nor 1500.
FAMILY_POINTS = (1000, 1250)
FAMILY_POINTS_BETA = 0.7


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


# ---------------------------------------------------------------- pseudo-arclength (deep family)
class ArclengthProblem:
    """The steady equations with both β and q = τ_d/τ_min free, closed by the pseudo-arclength
    condition in the plane (a, q/κ), a = ln(1 − β):

        t_a (a − a_0) + t_Q (q − q_0)/κ − ds = 0,

    (t_a, t_Q) the unit tangent of the family at the last pulse (a_0, q_0). Unknowns (y, β, q);
    the Jacobian is the (N+1)×(N+2) one of ``SteadyProblem(free="both")`` with the row
    (0…0, −t_a/(1 − β), t_Q/κ) appended. Square, so :func:`newton` drives it.
    """

    def __init__(self, base: SteadyProblem, a0, q0, t_a, t_Q, kappa, ds):
        self.base, self.a0, self.q0 = base, a0, q0
        self.t_a, self.t_Q, self.kappa, self.ds = t_a, t_Q, kappa, ds

    def _arc(self, x):
        a = math.log(1.0 - x[-2])
        return self.t_a * (a - self.a0) + self.t_Q * (x[-1] - self.q0) / self.kappa - self.ds

    def valid(self, x):
        return self.base.valid(x)

    def residual(self, x):
        if not self.valid(x):
            return np.full(x.size, np.inf)
        return np.concatenate([self.base.residual(x), [self._arc(x)]])

    def residual_and_jacobian(self, x):
        r, J = self.base.residual_and_jacobian(x)
        row = np.zeros(x.size)
        row[-2] = -self.t_a / (1.0 - x[-2])
        row[-1] = self.t_Q / self.kappa
        return np.concatenate([r, [self._arc(x)]]), np.vstack([J, row])


def family_tangent(prob: SteadyProblem, x, orient):
    """Unit tangent of the solution curve at a converged x = (y, β, q) of ``free="both"``.

    Notes
    -----
    The tangent n spans the null space of the (N+1)×(N+2) Jacobian J: J n = 0. It is found from
    the square system [J; c] n = [0; 1] with c = (0…0, orient) the previous direction in (β, q)
    (so n points the same way along the curve), then scaled to unit length in (a, q/κ):
    n_a = −n_β/(1 − β). Returns n (full vector, in (y, β, q)) scaled so that n_a² + n_Q² = 1 with
    n_Q = n_q/κ, where κ is passed through ``orient = (c_β, c_q, κ)``.
    """
    c_b, c_q, kappa = orient
    _, J = prob.residual_and_jacobian(x)
    A = np.vstack([J, np.zeros(x.size)])
    A[-1, -2], A[-1, -1] = c_b, c_q
    rhs = np.zeros(x.size)
    rhs[-1] = 1.0
    n = np.linalg.solve(A, rhs)
    n_a = -n[-2] / (1.0 - x[-2])
    n_Q = n[-1] / kappa
    return n / math.hypot(n_a, n_Q)



@dataclass
class DeepSettings:
    """Pseudo-arclength continuation of the deep family (near τ_min).

    ds, ds_min, ds_max : arclength step in the plane (ln(1−β), q/κ) and its bounds.
    fine : smallest spacing in τ_d/τ_min between written pulses; an arclength pulse is written when
        its label (4 decimals, so `fine` ≥ 1e-4) is new and it lies ≥ fine/2 from the last one.
    check : re-solve every written pulse at 2N (fixed β; converted to fixed τ_d along the family
        tangent) and double N until |Δβ| ≤ tol_beta and |ΔL|/L ≤ tol_L; the 2N solution is written,
        with the N-vs-2N differences as attributes.
    n_max : largest N tried by the check.
    max_length : stop once L exceeds this (m).
    regrid : a new grid is laid out when L has changed by more than this fraction since the last.
    stretch : instead of laying out new grids, deform the current one every step with
        :func:`stretch_grid` (both edges kept, the body lengthened with L) and keep the nodal
        ln v: no interpolation, so no jump of the discrete family at a regrid (measured with the
        re-laid grids: each regrid moves τ_d/τ_min by ~1e-5 at β ≈ 0.995, comparable to a step).
    front_zone : width of the leading-edge zone kept by :func:`stretch_grid`, in L.
    back_zone : width of the zone about the healing front (the back half-maximum crossing) that
        :func:`stretch_grid` moves rigidly, in L.
    homotopy : stages of the residual homotopy (:func:`solve_robust`) when Newton fails from an
        interpolated guess (grid checks, new grids).
    """

    ds: float = 0.1
    ds_min: float = 0.004
    ds_max: float = 0.4
    fine: float = 1e-4
    check: bool = True
    tol_beta: float = 1e-5
    tol_L: float = 1e-4
    n_max: int = 16000
    max_length: float = math.inf
    max_iter: int = 15
    regrid: float = 0.05
    stretch: bool = False
    front_zone: float = 0.01
    back_zone: float = 0.05
    homotopy: int = 8


def _stretch(xi, y, x0, s):
    """ln v stretched by the factor s about x0 behind it: y_new(ξ) = y(x0 + (ξ − x0)/s) for ξ < x0."""
    out = y.copy()
    behind = xi < x0
    out[behind] = np.interp(x0 + (xi[behind] - x0) / s, xi, y)
    return out


def _smoothstep(t):
    t = np.clip(t, 0.0, 1.0)
    return t * t * (3.0 - 2.0 * t)


def stretch_grid(xi, x0, shift, a, x_back, w):
    """Grid with the pulse body lengthened by `shift` and both edges kept.

    Parameters
    ----------
    xi : grid (ascending); x0 : the leading edge (the pin node); shift : how much longer the
    body gets (m); a : width of the leading-edge zone kept fixed; x_back, w : the healing front
    and the width of the zone about it moved rigidly.

    Notes
    -----
    With u = x0 − ξ (distance behind the front) and the weight
    φ(u) = S((u − a)/a) · [1 − S((u − u_b + 2w)/w)], u_b = x0 − x_back, S the C¹ smoothstep
    3t² − 2t³ on [0, 1], the nodes move to ξ − shift · G(u)/G(∞), G(u) = ∫_0^u φ. So the nodes within
    a of the front stay, the healing front (from u_b − w on) and the tail behind it are shifted
    rigidly by −shift, and only the body between is stretched: the structures whose widths do not
    grow with L keep their nodes (measured: stretching the healing front with the body lost its
    resolution and stopped the march at L ≈ 540 m, N = 2000). The map is smooth and, for
    shift > −G(∞), monotone; node count and order are kept.
    """
    xi = np.asarray(xi, float)
    u = x0 - xi
    ub = x0 - x_back
    phi = _smoothstep((u - a) / a) * (1.0 - _smoothstep((u - ub + 2.0 * w) / w))
    # G(u) on the nodes by the trapezoid rule, from the front (largest ξ) backward
    seg = 0.5 * (phi[1:] + phi[:-1]) * np.diff(xi)
    G = np.concatenate([np.cumsum(seg[::-1])[::-1], [0.0]])
    G -= G[np.searchsorted(xi, x0)]
    G = np.maximum(G, 0.0)
    return xi - shift * G / G[0]


class _Shifted:
    """F(x) − s r0: the residual homotopy's problem at stage s (same Jacobian)."""

    def __init__(self, prob, r0, s):
        self.prob, self.r0, self.s = prob, r0, s

    def valid(self, x):
        return self.prob.valid(x)

    def residual(self, x):
        return self.prob.residual(x) - self.s * self.r0

    def residual_and_jacobian(self, x):
        r, J = self.prob.residual_and_jacobian(x)
        return r - self.s * self.r0, J


def solve_robust(problem, x0, stages=8, max_iter=15, tol=1e-13):
    """Newton from x0; if it fails, the residual homotopy F(x) = s F(x0), s = 1 − k/stages.

    Notes
    -----
    Near τ_min the family is soft: a residual of 1e-5 (the interpolation error of a new grid)
    moves the healing edge by ~0.2 m, farther than Newton's linear model holds, so the damped
    iteration creeps (measured at 1.0125 τ_min, N = 2000: 3 % residual reduction per iteration,
    not converged after 40). Following s from 1 to 0 in `stages` equal steps, each a Newton
    solve from the last (tolerance 1e-10 on the way, `tol` at s = 0), converged there in 66–73
    iterations in all. Returns (x, stats) of the last solve, stats.iterations the total.
    """
    x, st = newton(problem, x0, tol=tol, max_iter=max_iter)
    if st.converged:
        return x, st
    r0 = problem.residual(np.asarray(x0, float))
    x, total = np.array(x0, float), st.iterations
    for k in range(1, stages + 1):
        s_k = 1.0 - k / stages
        x, st = newton(_Shifted(problem, r0, s_k), x, tol=tol if k == stages else 1e-10,
                       max_iter=4 * max_iter)
        total += st.iterations
        if not st.converged:
            st.message = f"homotopy stage {k}/{stages} failed: {st.message}"
            break
    st.iterations = total
    return x, st


def march_arclength(params, start, n_points, spec=GridSpec(), deep=DeepSettings(), progress=None,
                    rep=None, why=None, n_of=None, handoff=None):
    """Pseudo-arclength continuation from `start` = (xi, y, beta, q) toward β → 1.

    Yields converged (solution, tangent-unit (t_a, t_Q)) pairs with ``solution.x = (y, β, q)``.
    Each step: tangent at the last pulse (:func:`family_tangent`), predictor x + ds·n (β through
    a = ln(1−β), so it stays below 1), grid adapted to the predicted pulse with ``n_of()`` points
    (the current N, which the grid check may raise), Newton on :class:`ArclengthProblem`. A failed
    step halves ds; a step that converges in ≤ 4 iterations lets ds grow by 1.5. It gives up below
    ``ds_min`` (``why["reason"]``). Because the arclength runs along the curve, q may turn back
    (a fold in τ_d): the sign of the tangent's q-component is reported with each pulse.

    With ``deep.stretch`` every step deforms the current grid (:func:`stretch_grid`: the body
    lengthened by (s − 1) L, s = exp(ds · d ln L/ds), both edges moved rigidly) and keeps the nodal ln v as the predictor; ``n_of`` is
    then ignored. `handoff` (a dict), when given, lets the caller replace the march's current
    pulse between steps: a solution put in ``handoff["sol"]`` (x = (y, β, q), e.g. the refined
    pulse of a grid check) becomes the base of the next step, grid included.
    """
    xi, y, beta, q = start
    n_cur = n_points if n_of is None else n_of()
    k, _ = front_pin(xi, y, math.log(params.v_stick(q * params.tau_min)))
    base = SteadyProblem(params, q, xi, k, float(y[k]), free="both")
    x = np.concatenate([y, [beta, q]])
    # κ: |dq/da| at the start, so that one unit of ds moves a and q/κ alike
    n0 = family_tangent(base, x, (1.0, 0.0, 1.0))
    kappa = max(abs(n0[-1] / (-n0[-2] / (1.0 - beta))), 1e-5)
    orient = (1.0, 0.0, kappa)
    ds = deep.ds
    L_grid = L_now = fwhm(xi, np.exp(y), params.v_star)
    while True:
        n = family_tangent(base, x, orient)
        t_a, t_Q = -n[-2] / (1.0 - beta), n[-1] / kappa
        orient = (n[-2], n[-1], kappa)
        # predict: a + ds t_a, q + ds κ t_Q; ln v by stretching the last pulse behind its leading
        # edge by s = exp(ds · d ln L/ds): the healing edge moves by many of its own widths per
        # step, which the linear tangent n_y cannot carry (measured: predictor residual 8e-3 at
        # ds = 0.01 near β = 0.9925); d ln L/ds from the tangent by a finite difference
        eps = 1e-4
        dlnL = (math.log(fwhm(base.xi, np.exp(x[:-2] + eps * n[:-2]), params.v_star)) -
                math.log(L_now)) / eps
        yp = _stretch(base.xi, x[:-2], base.xi[base.pin_index], math.exp(ds * dlnL))
        bp = 1.0 - (1.0 - beta) * math.exp(ds * t_a)
        qp = q + ds * kappa * t_Q
        n_cur = n_points if n_of is None else n_of()
        if deep.stretch:
            n_cur = base.n
        # keep the grid (and its Hilbert matrix) while L stays within `regrid` of the grid's L:
        # then the tangent predictor is exact to O(ds²) and no interpolation error enters
        same = (n_cur == base.n and abs(L_now / L_grid - 1.0) < deep.regrid)
        try:
            params.check_tau_d(qp * params.tau_min)
            if deep.stretch:
                # deform the grid with the pulse, nodal ln v kept (no interpolation)
                x_pin = base.xi[base.pin_index]
                x_left = pulse_length(base.xi, np.exp(x[:-2]), params.v_star)[1]
                xn = stretch_grid(base.xi, x_pin, math.expm1(ds * dlnL) * L_now,
                                  deep.front_zone * L_now, x_left, deep.back_zone * L_now)
                yn, k, ky, H = x[:-2].copy(), base.pin_index, base.y_pin, None
            elif same:
                xn, yn, H = base.xi, yp, base.H
                k, ky = base.pin_index, base.y_pin
            else:
                xn, yn = regrid_guess(params, qp, base.xi, yp, bp, n_cur, spec)
                k, _ = front_pin(xn, yn, math.log(params.v_stick(qp * params.tau_min)))
                H, ky = None, float(yn[k])
        except (RuntimeError, ValueError) as exc:
            sol_ok, msg, new = False, f"predictor unusable: {exc}", None
        else:
            nb = SteadyProblem(params, qp, xn, k, ky, free="both", H=H)
            arc = ArclengthProblem(nb, math.log(1.0 - beta), q, t_a, t_Q, kappa, ds)
            t0 = time.perf_counter()
            xs, st = newton(arc, np.concatenate([yn, [bp, qp]]), tol=1e-13, max_iter=deep.max_iter)
            new = SteadySolution(nb, xs, st, time.perf_counter() - t0, 1)
            sol_ok, msg = st.converged, st.message
            if sol_ok:
                sol_ok = _judge(new)[1]
                if not sol_ok:
                    msg = "converged to a multi-hump solution: rejected"
        qa = float(new.x[-1]) if new is not None else qp
        its = new.stats.iterations if new is not None else 0
        msg = f"arclength step ds={ds:.3g} (N={n_cur}, {its} it.) to beta~{bp:.6f}: {msg}"
        if rep is not None:
            rep.record(qa, sol_ok, msg)
        if progress:
            progress(qa, new.to_pulse() if sol_ok else None, msg)
        if not sol_ok:
            ds *= 0.5
            if ds < deep.ds_min:
                if why is not None:
                    why["reason"] = (f"arclength steps stopped converging at beta={beta:.6f}, "
                                     f"tau_d/tau_min={q:.6f}: ds fell below {deep.ds_min} "
                                     f"({msg})")
                return
            continue
        if new.problem.xi is not base.xi:
            L_grid = new.to_pulse().L
        base, x = new.problem, new.x.copy()
        beta, q = float(x[-2]), float(x[-1])
        L_now = new.to_pulse().L
        if new.stats.iterations <= 6:
            ds = min(1.5 * ds, deep.ds_max)
        elif new.stats.iterations > 10:
            ds = max(0.7 * ds, deep.ds_min)
        yield new, (t_a, t_Q)
        if handoff is not None and handoff.get("sol") is not None:
            new = handoff.pop("sol")
            base, x = new.problem, new.x.copy()
            beta, q = float(x[-2]), float(x[-1])
            L_grid = L_now = new.to_pulse().L


def check_grid_2n(params, sol: SteadySolution, n_points, spec=GridSpec(), max_iter=30,
                  nested=False, stages=0, cells=None):
    """:func:`grid_change` as the family's criterion reads it: (fine, |Δβ|, |ΔL|/L)."""
    fine, dbeta, dL_rel = grid_change(params, sol, n_points, spec, max_iter, nested, stages, cells)
    return fine, abs(dbeta), abs(dL_rel)


def grid_change(params, sol: SteadySolution, n_points, spec=GridSpec(), max_iter=30,
                nested=False, stages=0, cells=None):
    """Grid check of an arclength pulse (x = (y, β, q)): re-solve on a grid of 2N adapted to it,
    on the line through it normal to the family tangent, and express the change at fixed τ_d.

    Returns (fine SteadySolution with x = (y, β, q), Δβ, ΔL/L): the signed N → 2N differences of β
    and L at the coarse pulse's τ_d (inf when the fine solve fails). The family's criterion is
    |Δβ| ≤ 1e-5 and |ΔL|/L ≤ 1e-4 (:func:`check_grid_2n`).

    Notes
    -----
    The fine pulse solves the steady equations with both β and q free, closed by the arclength
    condition with ds = 0 through the coarse pulse (t_a (a − a₀) + t_Q (q − q₀) = 0, κ = 1): as well
    conditioned as an arclength step, where fixed-τ_d and fixed-β re-solves stall near β → 1
    (measured at 1.0116: fixed β at 2N stops at max|Δ| = 6e-5 after 60 iterations). Along the fine
    family, to first order, β_f(q) = β₁ − (n_β/n_q)(q₁ − q) and L_f(q) = L₁ − (dL/ds)/n_q (q₁ − q),
    n the tangent at the coarse pulse (its N → 2N change is of higher order), dL/ds by a finite
    difference of the FWHM along n. Hence, with dq = q₁ − q₀:
    Δβ = β₁ − β₀ − (n_β/n_q) dq, ΔL = L₁ − L₀ − (dL/ds)/n_q dq.

    ``nested=True``: the fine grid is the pulse's own grid with the midpoints inserted (2N − 1
    nodes; errors then fall smoothly with the level, and the N-pulse's grid, e.g. a deformed
    one of :func:`stretch_grid`, is checked as it is); otherwise a grid of 2N adapted to the
    pulse (``spec``). ``cells`` (with ``nested``): a boolean mask over the N − 1 cells; only
    their midpoints are inserted (one region refined: ``steady/locate_error.py``,
    ``steady/body_refine.py``). ``stages`` > 0: when Newton fails, :func:`solve_robust` with that
    many homotopy stages.
    """
    p0 = sol.to_pulse()
    q, beta = float(sol.x[-1]), p0.beta
    n = family_tangent(sol.problem, sol.x, (1.0, 0.0, 1.0))
    t_a, t_Q = -n[-2] / (1.0 - beta), n[-1]
    t0 = time.perf_counter()
    if nested:
        xi = sol.xi
        mid = 0.5 * (xi[1:] + xi[:-1])
        xn = np.sort(np.concatenate([xi, mid if cells is None else mid[cells]]))
        yn = interpolate(xi, sol.x[:-2], xn, params.v_stick(q * params.tau_min))
        k = int(np.searchsorted(xn, xi[sol.problem.pin_index]))    # the pin's node, kept
        y_pin = sol.problem.y_pin
    else:
        xn, yn = regrid_guess(params, q, sol.xi, sol.x[:-2], beta, 2 * n_points, spec)
        k, _ = front_pin(xn, yn, math.log(params.v_stick(q * params.tau_min)))
        y_pin = float(yn[k])
    base = SteadyProblem(params, q, xn, k, y_pin, free="both",
                         state_order=sol.problem.state_order)
    arc = ArclengthProblem(base, math.log(1.0 - beta), q, t_a, t_Q, 1.0, 0.0)
    x_start = np.concatenate([yn, [beta, q]])
    if stages > 0:
        xs, st = solve_robust(arc, x_start, stages=stages, max_iter=max_iter)
    else:
        xs, st = newton(arc, x_start, tol=1e-13, max_iter=max_iter)
    fine = SteadySolution(base, xs, st, time.perf_counter() - t0, 1)
    if not st.converged or n[-1] == 0.0:
        return fine, math.inf, math.inf
    p1 = fine.to_pulse()
    eps = 1e-3 / max(float(np.abs(n[:-2]).max()), 1e-12)
    dL_ds = (fwhm(sol.xi, np.exp(sol.x[:-2] + eps * n[:-2]), params.v_star) - p0.L) / eps
    dq = float(xs[-1]) - q
    dbeta = p1.beta - beta - (n[-2] / n[-1]) * dq
    dL = p1.L - p0.L - dL_ds / n[-1] * dq
    return fine, dbeta, dL / p0.L


def _as_both(params, sol: SteadySolution) -> SteadySolution:
    """A fixed-β solution (x = (y, q)) as a solution of ``free="both"`` (x = (y, β, q))."""
    prob = sol.problem
    both = SteadyProblem(params, prob.tau_d_ratio, prob.xi, prob.pin_index, prob.y_pin,
                         free="both", H=prob.H)
    x = np.concatenate([sol.x[:-1], [prob.beta_fixed, float(sol.x[-1])]])
    return SteadySolution(both, x, sol.stats, sol.wall_time, sol.passes)


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
