"""Continuation in the parameters: a pulse of new parameters reached from a solved one.

The built-in guess (:func:`slippulse.steady.solver.default_guess`) is laid out in units of L0 with
β = 0.01; for laws far from Table I it is outside Newton's basin (docs/guide.md, Other parameters). From a
pulse of parameters p0, :func:`continue_in_params` walks to p1 along p0^(1−s) p1^s (each
parameter geometrically), each step solved from the previous pulse (its grid re-adapted by
:func:`solve_pulse`), the step in s grown on success and halved on failure. ``steady solve
--homotopy`` and the existence map (continuation in (b, α)) use it.
"""
from __future__ import annotations

import math

import numpy as np

from ..core.params import ParameterError, Parameters
from .solver import count_humps, solve_pulse

def judge(sol) -> tuple[bool, str]:
    """Whether a :class:`SteadySolution` is a found pulse, and why not."""
    if not sol.stats.converged:
        return False, f"newton: {sol.stats.message}"
    pulse = sol.to_pulse()
    humps = count_humps(pulse.v)
    if humps != 1:
        return False, f"humps={humps}"
    if not (0.0 < pulse.beta < 1.0):
        return False, f"beta={pulse.beta:.3g}"
    if not (math.isfinite(pulse.L) and pulse.L > 0):
        return False, "no length"
    return True, ""


#: Newton iterations per pass of each attempt (the solver's default is 60): the successful solves
#: of the existence map converge in 8-13 iterations from the built-in guess (measured at three
#: points), and a failure would otherwise cost 60 iterations.
MAX_ITER = 30


def attempt(params, tau_d_ratio, n_points, guess=None):
    """One solve; (solution or None, found, reason)."""
    try:
        sol = solve_pulse(params, tau_d_ratio, n_points=n_points, guess=guess, max_iter=MAX_ITER)
    except (RuntimeError, ValueError, FloatingPointError, np.linalg.LinAlgError) as exc:
        return None, False, f"{type(exc).__name__}: {str(exc).splitlines()[0][:80]}"
    ok, why = judge(sol)
    return sol, ok, why


def as_guess(sol):
    return (sol.problem.xi.copy(), sol.x[:-1].copy(), float(sol.x[-1]))


def geometric_path(p0: Parameters, p1: Parameters, s: float) -> Parameters:
    """Parameters p0^(1−s) p1^s, each parameter interpolated geometrically (s in [0, 1])."""
    a, b = p0.as_dict(), p1.as_dict()
    return Parameters(**{k: a[k] ** (1.0 - s) * b[k] ** s if a[k] != b[k] else a[k] for k in a})


def continue_in_params(p0: Parameters, p1: Parameters, tau_d_ratio: float, n_points: int = 500,
                       start=None, first_step: float = 0.25, min_step: float = 1.0 / 64,
                       progress=None):
    """Solve the pulse of ``p1`` at τ_d/τ_min by continuation from ``p0`` along
    :func:`geometric_path` (step in s grown ×1.5 on success, halved on failure).

    Parameters
    ----------
    start : SteadySolution, optional
        The pulse of ``p0`` (default: solved from the built-in guess).

    Returns
    -------
    (SteadySolution or None, list of (s, found, reason))
        The last solution (of ``p1`` when found) and the path taken.
    """
    path = []
    if start is None:
        start, ok, why = attempt(p0, tau_d_ratio, n_points)
        path.append((0.0, ok, why))
        if not ok:
            return None, path
    s, h, sol = 0.0, first_step, start
    while s < 1.0:
        t = min(1.0, s + h)
        p = geometric_path(p0, p1, t)
        try:
            if tau_d_ratio >= p.tau_peak / p.tau_min:
                raise ParameterError(f"tau_d/tau_min={tau_d_ratio:g} >= tau_peak/tau_min on the path")
            new, ok, why = attempt(p, tau_d_ratio, n_points, guess=as_guess(sol))
        except ParameterError as exc:
            new, ok, why = None, False, str(exc)
        path.append((t, ok, why))
        if progress:
            progress(f"s={t:.4f}: {'found' if ok else why}")
        if ok:
            s, sol, h = t, new, h * 1.5
        else:
            h *= 0.5
            if h < min_step:
                return sol, path
    return sol, path
