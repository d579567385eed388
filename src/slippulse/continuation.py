"""Natural-parameter continuation of the pulse family in τ_d, with remeshing and step halving.

Each pulse is seeded by the previous converged one: its ln v is interpolated onto a grid adapted to
it (the domain follows the pulse length L and the healing length c_p D/v_stick, so it grows as the
pulse grows), solved, adapted again to the new solution and re-solved. A failed solve halves the
step (down to `min_step`); every converged pulse is appended atomically to one HDF5 file, so a
rerun with the same output resumes from the last converged pulse.
"""
from __future__ import annotations

import math
import os
import time
from dataclasses import dataclass, field

import numpy as np

from .h5io import list_pulses, read_pulse, write_pulse
from .params import ParameterError, Parameters
from .newton import newton
from .solver import GridSpec, SteadySolution, front_pin, regrid_guess, solve_pulse
from .steady import SteadyProblem


@dataclass
class FamilyReport:
    """What a continuation run did."""

    written: list = field(default_factory=list)      # labels written this run
    resumed_from: str | None = None
    failures: list = field(default_factory=list)     # (tau_d_ratio, message)
    reached: float = float("nan")                    # smallest τ_d/τ_min converged
    stopped_early: bool = False
    wall_time: float = 0.0


def _targets(start, stop, step):
    n = int(round((start - stop) / step))
    return [round(start - k * step, 10) for k in range(n + 1)]


def _predict(guess, prev, current, trial):
    """Secant predictor in τ_d: extrapolate ln v (on the current grid) and β from the last two pulses."""
    xi, y, beta = guess
    if prev is None:
        return guess
    r_prev, xi_p, y_p, beta_p = prev
    s = (trial - current) / (current - r_prev)
    if abs(s) > 3.0:               # neighbours too close for a safe extrapolation
        return guess
    y_prev_here = np.interp(xi, xi_p, y_p)
    y_new = y + s * (y - y_prev_here)
    b_new = beta + s * (beta - beta_p)
    b_new = min(b_new, 1.0 - 0.5 * (1.0 - beta))     # stay below c_s
    return xi, y_new, b_new


def solve_at_beta(params, guess, q_guess, beta, n_points, spec=GridSpec(), max_iter=40):
    """Solve with β fixed and τ_d/τ_min unknown, on a grid adapted to the guess (xi, y)."""
    xi, y = guess
    t0 = time.perf_counter()
    xn, yn = regrid_guess(params, q_guess, xi, y, beta, n_points, spec)
    k, _ = front_pin(xn, yn, np.log(params.v_stick(q_guess * params.tau_min)))
    prob = SteadyProblem(params, q_guess, xn, k, float(yn[k]), free="tau_d", beta=beta)
    x, st = newton(prob, np.concatenate([yn, [q_guess]]), tol=1e-13, max_iter=max_iter)
    return SteadySolution(prob, x, st, time.perf_counter() - t0, 1)


def march_in_beta(params, start, prev, target, n_points, spec=GridSpec(), shrink=0.92,
                  min_shrink=0.97, progress=None):
    """From solution `start` = (xi, y, beta, q), step β toward 1 (1−β ← shrink·(1−β)) with τ_d free,
    until τ_d/τ_min ≤ target. Yields converged SteadySolutions; stops when a step below
    `min_shrink` fails. Predictor: the last ln v (its shape: extrapolating it failed near β → 1,
    measured) and a secant in ln(1−β) for q."""
    xi, y, beta, q = start
    hist = prev
    f = shrink
    while q > target:
        bnew = 1.0 - (1.0 - beta) * f
        yg, qg = y, q
        if hist is not None:
            s_prev, xi_p, y_p, q_p = hist
            ds = (np.log(1 - bnew) - np.log(1 - beta)) / (np.log(1 - beta) - s_prev)
            qg = q + min(ds, 3.0) * (q - q_p)
        qg = max(qg, 1.0 + 1e-6)
        sol = solve_at_beta(params, (xi, yg), qg, bnew, n_points, spec)
        ok = sol.stats.converged
        if progress:
            progress(float(sol.x[-1]), sol.to_pulse() if ok else None,
                     f"beta-step to {bnew:.6f}: {sol.stats.message}")
        if not ok:
            f = 1.0 - 0.5 * (1.0 - f)
            if f > min_shrink:
                return
            continue
        hist = (np.log(1 - beta), xi, y, q)
        xi, y, beta, q = sol.xi, sol.x[:-1].copy(), bnew, float(sol.x[-1])
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


def _beta_bridge(params, out, guess, prev, current, target, n_points, spec, max_iter, rep,
                 progress):
    """March in β from `guess` (at τ_d/τ_min = current) until τ_d passes `target`, writing the
    intermediate pulses, then solve at `target` from the interpolated bracketing solutions.
    Returns (prev, guess, solution) for the continuation, or None on failure."""
    start = (guess[0], guess[1], guess[2], current)
    prev_b = None if prev is None else (np.log(1 - prev[3]), prev[1], prev[2], prev[0])
    hi, lo = None, None
    for bsol in march_in_beta(params, start, prev_b, target, n_points, spec, progress=progress):
        q = float(bsol.x[-1])
        if q > target:
            bp = bsol.to_pulse()
            write_pulse(out, bp, params)
            rep.written.append(bp.label)
            rep.reached = q
            hi = bsol
        else:
            lo = bsol
    if lo is None:
        return None
    if hi is None:
        hi_xi, hi_y, hi_q, hi_b = guess[0], guess[1], current, guess[2]
    else:
        hi_xi, hi_y, hi_q, hi_b = hi.xi, hi.x[:-1], float(hi.x[-1]), hi.beta
    w = (hi_q - target) / (hi_q - float(lo.x[-1]))
    y_t = (1 - w) * np.interp(lo.xi, hi_xi, hi_y) + w * lo.x[:-1]
    b_t = (1 - w) * hi_b + w * lo.beta
    sol = solve_pulse(params, target, n_points=n_points, guess=(lo.xi, y_t, b_t), spec=spec,
                      passes=0, max_iter=max_iter)
    pulse, ok, msg = _judge(sol)
    if progress:
        progress(target, pulse if ok else None, msg)
    if not ok:
        rep.failures.append((target, msg))
        return None
    write_pulse(out, pulse, params)
    rep.written.append(pulse.label)
    return (hi_q, hi_xi, hi_y, hi_b), (sol.xi, sol.x[:-1].copy(), sol.beta), sol


def run_family(params: Parameters, out: str, start: float = 1.2, stop: float = 1.015,
               step: float = 0.005, n_points: int = 2000, min_step: float | None = None,
               spec: GridSpec = GridSpec(), progress=None, max_iter: int = 12,
               beta_switch: float = 0.85) -> FamilyReport:
    """Solve the family from `start` down to `stop` (τ_d/τ_min) and write it to `out`.

    Parameters
    ----------
    progress : callable(ratio, pulse_or_None, message), optional
        Called after every attempted solve.
    max_iter : Newton iterations allowed per predicted step (converging steps take ≤ 6).
    beta_switch : above this β, step in β (τ_d free) directly: there τ_d-steps of the family's
        size fail (measured: every τ_d step from β ≈ 0.9 on needed halving or failed).
    """
    for name, val in (("from", start), ("to", stop)):
        if not math.isfinite(val):
            raise ParameterError(f"{name}={val!r} is invalid: must be a finite tau_d/tau_min")
        params.check_tau_d(val * params.tau_min)
    if not (stop < start):
        raise ParameterError(f"to={stop} is invalid: must be < from={start} (continuation goes down)")
    if not (0 < step <= start - stop) or not math.isfinite(step):
        raise ParameterError(f"step={step} is invalid: must be in (0, from - to = {start - stop:.4g}]")
    if min_step is None:
        min_step = 0.5 * step          # two failed τ_d steps in a row switch to stepping in β
    t0 = time.perf_counter()
    rep = FamilyReport()
    guess = None
    current = None
    if os.path.exists(out):
        done = []
        for label in list_pulses(out):
            pu, p_file = read_pulse(out, label)
            if p_file != params:
                raise ParameterError(f"{out}: stored parameters differ from this run's; use another --out")
            if pu.converged:
                done.append(pu)
        if done:
            last = min(done, key=lambda p: p.tau_d_ratio)
            current = last.tau_d_ratio
            guess = (last.xi, np.log(last.v), last.beta)
            rep.resumed_from = last.label
            rep.reached = current
    targets = [t for t in _targets(start, stop, step) if current is None or t < current - 1e-12]
    if current is None:
        # the first pulse from the built-in guess
        first = targets.pop(0)
        sol = solve_pulse(params, first, n_points=n_points, spec=spec)
        pulse = sol.to_pulse()
        if progress:
            progress(first, pulse, sol.stats.message)
        if not pulse.converged:
            rep.failures.append((first, sol.stats.message))
            rep.stopped_early = True
            rep.wall_time = time.perf_counter() - t0
            return rep
        write_pulse(out, pulse, params)
        rep.written.append(pulse.label)
        current, rep.reached = first, first
        guess = (sol.xi, sol.x[:-1].copy(), sol.beta)
    h = step
    prev = None            # (ratio, xi, y, beta) of the pulse before `current`, for the predictor
    tried = set()
    while targets:
        target = targets[0]
        if h < min_step - 1e-15 or guess[2] > beta_switch:
            # natural continuation stalls near τ_min: step in β with τ_d free past the target,
            # then solve at the exact target from the two β-solutions that bracket it
            res = _beta_bridge(params, out, guess, prev, current, target, n_points, spec, max_iter,
                               rep, progress)
            if res is None:
                rep.stopped_early = True
                break
            prev, guess, sol = res
            current, rep.reached = target, target
            targets.pop(0)
            h = step
            continue
        trial = max(target, round(current - h, 10))
        if (current, trial) in tried:
            h *= 0.5
            continue
        tried.add((current, trial))
        sol = solve_pulse(params, trial, n_points=n_points, guess=_predict(guess, prev, current, trial),
                          spec=spec, passes=0, max_iter=max_iter)
        pulse, ok, msg = _judge(sol)
        if progress:
            progress(trial, pulse if ok else None, msg)
        if not ok:
            rep.failures.append((trial, msg))
            h *= 0.5
            continue
        write_pulse(out, pulse, params)
        rep.written.append(pulse.label)
        prev = (current, guess[0], guess[1], guess[2])
        current, rep.reached = trial, trial
        guess = (sol.xi, sol.x[:-1].copy(), sol.beta)
        if abs(trial - target) < 1e-12:
            targets.pop(0)
        h = min(step, 2.0 * h)
    rep.wall_time = time.perf_counter() - t0
    return rep
