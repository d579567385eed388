"""A steady pulse at any τ_d in (τ_min, τ_peak): the built-in guess, then continuation to τ_d.

The built-in guess (:func:`slippulse.steady.solver.default_guess`) converges only near
τ_d/τ_min = 1.2 (measured at N = 1000: 1.2, 1.22, 1.25 and 1.3 converge; 1.15, 1.18, 1.28 and 1.33
do not). :func:`reach_pulse` therefore solves at :data:`GUESS_RATIO` from the guess and walks to the
requested τ_d:

* below 1.2, with the family continuation itself (:func:`slippulse.steady.continuation.run_family`,
  written to a temporary file, with a step ≤ its default 0.005 that lands on the target exactly);
* above 1.2 (the family continuation only goes down), by steps of at most ``step`` in τ_d, each
  solved from the previous pulse (:func:`slippulse.steady.solver.solve_pulse` with that pulse as
  the guess), the step halved on failure down to ``min_step``;

then re-solves at the target on ``n_points`` points (adapted grid, requested method and
tolerance) from the pulse reached, so the result is the same discrete solution
``steady solve`` gives near 1.2, independent of the route up to the grid layout.
"""
from __future__ import annotations

import math
import os
import tempfile
import time

import numpy as np

from ..core.h5io import read_pulse
from ..core.params import Parameters
from .continuation import FamilyRun, run_family
from .newton import NEWTON_TOL
from .solver import SteadySolution, solve_pulse

#: τ_d/τ_min where the built-in guess converges; the walk to any other τ_d starts here.
GUESS_RATIO = 1.2
#: τ_d/τ_min that ``steady solve`` reaches (measured, docs/steady.md): down to where the family
#: continuation's default reaches (1.015; deeper pulses come from ``steady family``), up to
#: 1.32 (the walk upward stalls at 1.3269: the pulse fades, its length cannot be measured for the
#: next grid; τ_peak/τ_min = 1.33186; at 1.325 the walk arrives but the final solve cannot lay
#: its grid, as measured, so 1.325 is no longer advertised).
SOLVE_RANGE = (1.015, 1.32)
#: Targets this close to GUESS_RATIO are solved from the guess directly.
DIRECT = 1e-9


def route_targets(tau_d_ratio: float, step: float = 0.005) -> tuple[float, int]:
    """The walk from :data:`GUESS_RATIO` to ``tau_d_ratio``: (signed step, number of steps), the
    step of magnitude ≤ ``step`` that lands on ``tau_d_ratio`` exactly (0 steps at the guess
    itself)."""
    span = tau_d_ratio - GUESS_RATIO
    if abs(span) < DIRECT:
        return 0.0, 0
    n = max(1, math.ceil(abs(span) / step - 1e-9))
    return span / n, n


def _walk_up(params, tau_d_ratio, h, progress, n_points, min_step):
    """Natural continuation upward from the guess at GUESS_RATIO to ``tau_d_ratio``; returns the
    last (solution, message) pair, converged at ``tau_d_ratio`` or not."""
    sol = solve_pulse(params, GUESS_RATIO, n_points=n_points)
    if progress:
        progress(GUESS_RATIO, sol.to_pulse() if sol.stats.converged else None, sol.stats.message)
    if not sol.stats.converged:
        return None, f"the built-in guess at {GUESS_RATIO} failed ({sol.stats.message})"
    q, dq = GUESS_RATIO, h
    while q < tau_d_ratio - 1e-12:
        trial = min(tau_d_ratio, q + dq)
        guess = (sol.problem.xi, sol.x[:-1], sol.beta)
        try:
            new = solve_pulse(params, trial, n_points=n_points, guess=guess, passes=0, max_iter=30)
            ok, msg = new.stats.converged, new.stats.message
        except RuntimeError as exc:          # e.g. no measurable pulse length on the guess's grid
            new, ok, msg = sol, False, str(exc)
        if progress:
            progress(trial, new.to_pulse() if ok else None, msg)
        if not ok:
            dq *= 0.5
            if dq < min_step:
                return None, (f"continuation upward stalled at tau_d/tau_min={q:.5f}: the step "
                              f"to {trial:.5f} failed at the smallest step {2 * dq:.2g} ({msg})")
            continue
        sol, q, dq = new, trial, min(h, 2 * dq)
    return sol, "converged"


def reach_pulse(params: Parameters, tau_d_ratio: float, n_points: int = 2000,
                method: str = "newton", tol: float = NEWTON_TOL, step: float = 0.005,
                min_step: float = 1e-4, progress=None) -> tuple[SteadySolution | None, str]:
    """Solve the steady pulse at τ_d = ``tau_d_ratio`` τ_min from the built-in guess, continuing
    from τ_d/τ_min = 1.2 where the guess does not reach (module docstring).

    Parameters
    ----------
    tau_d_ratio : τ_d/τ_min, in (1, τ_peak/τ_min).
    n_points, method, tol : of the final solve at ``tau_d_ratio`` (as :func:`solve_pulse`).
    step : largest continuation step in τ_d/τ_min.
    min_step : upward walk: smallest step before giving up.
    progress : callable(tau_d_ratio, pulse_or_None, message), optional
        Told about every solve of the walk (None: a failed attempt), like the family's.

    Returns
    -------
    (SteadySolution or None, str)
        The final solution (``stats.converged`` says whether it converged) and how it was reached;
        None and the reason when the walk to ``tau_d_ratio`` stopped before it.
    """
    params.check_tau_d(tau_d_ratio * params.tau_min)
    h, n = route_targets(tau_d_ratio, step)
    if n == 0:
        return solve_pulse(params, tau_d_ratio, n_points=n_points, method=method, tol=tol), \
            "from the built-in guess"
    t0 = time.perf_counter()
    if h > 0:
        sol, why = _walk_up(params, tau_d_ratio, h, progress, min(n_points, 1000), min_step)
        if sol is None or not sol.stats.converged:
            return None, why
        guess = (sol.problem.xi, sol.x[:-1], sol.beta)
        route = f"continued up from {GUESS_RATIO} in {n} steps"
    else:
        with tempfile.TemporaryDirectory(prefix="slippulse-reach-") as tmp:
            out = os.path.join(tmp, "walk.h5")
            rep = run_family(params, out, FamilyRun(start=GUESS_RATIO, stop=tau_d_ratio, step=-h,
                                                    check=False), progress=progress)
            if rep.stopped_early or not rep.written:
                return None, (f"the family continuation from {GUESS_RATIO} stopped at "
                              f"tau_d/tau_min={rep.reached:.5f}: {rep.stop_reason}")
            last, _ = read_pulse(out, rep.written[-1])
        if abs(last.tau_d_ratio - tau_d_ratio) > 1e-9:
            return None, (f"the family continuation ended at tau_d/tau_min="
                          f"{last.tau_d_ratio:.6f}, not {tau_d_ratio}")
        guess = (last.xi, np.log(last.v), last.beta)
        route = f"continued down from {GUESS_RATIO} by the family continuation ({n} steps)"
    try:
        final = solve_pulse(params, tau_d_ratio, n_points=n_points, guess=guess, passes=0,
                            method=method, tol=tol)
    except RuntimeError as exc:     # e.g. no measurable pulse length to lay the N-point grid on
        return None, (f"{route} to tau_d/tau_min={tau_d_ratio}, but the final solve on "
                      f"{n_points} points could not start from that pulse ({exc})")
    final.wall_time = time.perf_counter() - t0
    return final, route
