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
from .solver import GridSpec, solve_pulse


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
    y_prev_here = np.interp(xi, xi_p, y_p)
    y_new = y + s * (y - y_prev_here)
    b_new = beta + s * (beta - beta_p)
    b_new = min(b_new, 1.0 - 0.5 * (1.0 - beta))     # stay below c_s
    return xi, y_new, b_new


def run_family(params: Parameters, out: str, start: float = 1.2, stop: float = 1.015,
               step: float = 0.005, n_points: int = 2000, min_step: float = 1.25e-3,
               spec: GridSpec = GridSpec(), progress=None, max_iter: int = 25) -> FamilyReport:
    """Solve the family from `start` down to `stop` (τ_d/τ_min) and write it to `out`.

    Parameters
    ----------
    progress : callable(ratio, pulse_or_None, message), optional
        Called after every attempted solve.
    """
    for name, val in (("from", start), ("to", stop)):
        params.check_tau_d(val * params.tau_min) if math.isfinite(val) else None
        if not math.isfinite(val):
            raise ParameterError(f"{name}={val!r} is invalid: must be a finite tau_d/tau_min")
    if not (stop < start):
        raise ParameterError(f"to={stop} is invalid: must be < from={start} (continuation goes down)")
    if not (0 < step <= start - stop) or not math.isfinite(step):
        raise ParameterError(f"step={step} is invalid: must be in (0, from - to = {start - stop:.4g}]")
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
        trial = max(target, round(current - h, 10))
        if (current, trial) in tried:
            h *= 0.5
            if h < min_step - 1e-15:
                rep.stopped_early = True
                break
            continue
        tried.add((current, trial))
        sol = solve_pulse(params, trial, n_points=n_points, guess=_predict(guess, prev, current, trial),
                          spec=spec, passes=1, coarse_points=n_points, max_iter=max_iter)
        pulse = sol.to_pulse()
        ok = pulse.converged and pulse.extra["n_humps"] == 1
        msg = sol.stats.message
        if pulse.converged and not ok:
            msg = f"converged to a {pulse.extra['n_humps']}-hump solution: rejected"
        if progress:
            progress(trial, pulse if ok else None, msg)
        if not ok:
            rep.failures.append((trial, msg))
            h *= 0.5
            if h < min_step - 1e-15:
                rep.stopped_early = True
                break
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
