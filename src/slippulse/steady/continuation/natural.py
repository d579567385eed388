"""Natural-parameter continuation: tangent steps in τ_d (β unknown) or in β (τ_d unknown), the
β-march and the bridge back to a round τ_d target."""
from __future__ import annotations

import math
import time
from dataclasses import dataclass

import numpy as np
import scipy.linalg as sla

from ...core.h5io import write_pulse
from ..equations import SteadyProblem
from ..newton import NEWTON_TOL, newton
from ..measures import pulse_length
from ..solver import GridSpec, SteadySolution, front_pin, regrid_guess, solve_pulse
from .stretch import _stretch


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
    L = pulse_length(base.xi, np.exp(base.y), params.v_star, crossings=False)
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
    dlnL = (math.log(pulse_length(xi, np.exp(y + eps * t[:n]), params.v_star, crossings=False)) -
            math.log(pulse_length(xi, np.exp(y), params.v_star, crossings=False))) / eps
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
    x, st = newton(prob, x0, tol=NEWTON_TOL, max_iter=max_iter, lu=lu)
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
    x, st = newton(prob, np.concatenate([yn, [q_guess]]), tol=NEWTON_TOL, max_iter=max_iter)
    return SteadySolution(prob, x, st, time.perf_counter() - t0, 1)


def march_in_beta(params, start, target, n_points, spec=GridSpec(), shrink=0.92,
                  min_shrink=0.97, progress=None, rep=None, why=None, beta_cap=None):
    """From solution `start` (a :class:`_Base`), step β toward 1 (1−β ← shrink·(1−β)) with τ_d
    free, until τ_d/τ_min ≤ target. Yields converged SteadySolutions; stops when a step below
    `min_shrink` fails. Each step is a :func:`tangent_step` in β (tangent predictor, chord
    corrector).

    Every attempt is counted in `rep` (a :class:`FamilyReport`), failed ones with their message;
    when the march gives up, ``why["reason"]`` says where and why. ``beta_cap``: stop (with
    ``why["cap"] = True``) once β ≥ beta_cap, where the deep continuation takes over.
    """
    base = start
    f = shrink
    while base.q > target:
        if beta_cap is not None and base.beta >= beta_cap:
            if why is not None:
                why["cap"] = True
                why["reason"] = f"beta={base.beta:.6f} reached the deep continuation's {beta_cap}"
            return
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


def _beta_bridge(params, out, base, target, n_points, spec, max_iter, rep, progress, why,
                 write=None, beta_cap=None):
    """March in β from `base` (a :class:`_Base`) until τ_d passes `target`, writing the
    intermediate pulses, then solve at `target` by a tangent step in τ_d from the first pulse past
    it (if that fails, from the bracketing pair interpolated in τ_d). Returns (solution, its base)
    for the continuation, or None on failure (reason in `why`)."""
    hi, lo = None, None
    if write is None:
        def write(sol, pulse, method):
            write_pulse(out, pulse, params)
            rep.wrote(pulse)
    for bsol in march_in_beta(params, base, target, n_points, spec, progress=progress, rep=rep,
                              why=why, beta_cap=beta_cap):
        q = float(bsol.x[-1])
        if q > target:
            write(bsol, bsol.to_pulse(), "beta")
            hi = bsol
            why["last"] = bsol
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
    write(sol, pulse, "tau_d")
    return sol, new



#: Grid points per pulse of the family by default: (while β ≤ FAMILY_POINTS_BETA, beyond). With
#: the order-4 state both are within 1e-5 in β and 1e-4 in L of N = 4000 (docs/steady.md §3.3);
#: N = 1000 leaves ripples of 0.05 in ln v behind the peak near τ_min (20 "humps" at 1.015; τ_d
#: steps to 1.03 rejected as 11- and 2-hump solutions, measured); 1250 not (one hump at
#: 1.03–1.015, within 8.8e-7 in β and 1.2e-5 in L of N = 4000, BENCHMARKS.md), nor 1500.
FAMILY_POINTS = (1000, 1250)
FAMILY_POINTS_BETA = 0.7
