"""Natural-parameter steps, the maths of :class:`~.strategy.NaturalPredictor`: one tangent step
in τ_d (β unknown) or in β (τ_d unknown), the solve between two pulses that bracket a τ_d target,
and the test a natural step's pulse must pass (one hump). The driver is :mod:`.driver`."""
from __future__ import annotations

import math
import time
from dataclasses import dataclass, field

import numpy as np
import scipy.linalg as sla

from ..equations import SteadyProblem
from ..measures import pulse_length
from ..newton import NEWTON_TOL, KrylovLU, newton
from ..solver import GridSpec, SteadySolution, front_pin, regrid_guess, solve_pulse
from .strategy import REGRID, NewtonCorrector
from .stretch import stretch_profile


def round_targets(start, stop, step):
    """The τ_d/τ_min targets start, start − step, ..., stop (rounded to 10 decimals)."""
    n = int(round((start - stop) / step))
    return [round(start - k * step, 10) for k in range(n + 1)]


@dataclass
class PulseOnGrid:
    """A converged pulse on its grid, the base of the next natural step: ln v on ξ, β,
    q = τ_d/τ_min, the grid's Hilbert matrix (None: not built), the phase condition (pin node, ln v
    there), the pulse length the grid was laid out for, and scipy's LU of
    A = ∂(Δ, pin)/∂(ln v, β) there where one was factored (the fold test's: ``fold_lu``)."""

    xi: np.ndarray
    y: np.ndarray
    beta: float
    q: float
    H: np.ndarray | None = None
    pin: int = 0
    y_pin: float = 0.0
    L_grid: float = math.nan
    lu_a: tuple | None = field(default=None, repr=False)

    @classmethod
    def of(cls, sol: SteadySolution, L_grid=math.nan):
        """The base of a converged solution (x = (y, β) at fixed τ_d or (y, q) at fixed β)."""
        prob = sol.problem
        q = float(sol.x[-1]) if prob.free == "tau_d" else float(prob.tau_d_ratio)
        return cls(prob.xi, sol.x[:-1].copy(), sol.beta, q, prob.H, prob.pin_index, prob.y_pin,
                   L_grid, sol.fold_lu)


def tangent_step(params, base: PulseOnGrid, value, fixed, n_points, spec=GridSpec(), max_iter=12,
                 regrid=REGRID, corrector=None):
    """One natural step from a converged pulse to τ_d/τ_min = value (fixed="tau_d"; unknowns
    y, β) or to β = value (fixed="beta"; unknowns y, q): the predictor of
    :class:`~.strategy.NaturalPredictor`, then ``corrector`` (a
    :class:`~.strategy.NewtonCorrector`; None: chord start, ``max_iter`` iterations). Returns
    (SteadySolution, its :class:`PulseOnGrid`).

    Notes
    -----
    grid: the base's own (with its Hilbert matrix) while n_points is unchanged and
    |L/L_grid − 1| ≤ regrid, else a grid adapted to the base pulse with ln v interpolated onto it.
    tangent: J = ∂(Δ, pin)/∂(y, β, q) at the base (``SteadyProblem(free="both")``), split into the
    columns of the unknowns J_x and of the stepped parameter J_p; LU of J_x; t = −J_x⁻¹ J_p.
    On the base's own grid with its LU of A = J[:, (y, β)] (``base.lu_a``, the fold test's), no
    LU is formed: a τ_d step's J_x is A; a β step's tangent comes from A's null direction
    (−A⁻¹ J_q, 1) and its corrector's GMRES (:class:`~slippulse.steady.newton.KrylovLU`) is
    preconditioned by A's LU, which differs from J_x = J[:, (y, q)] in one column (one GMRES
    iteration more).
    predict: with dp = value − p_base, the scalar unknown + dp t; ln v stretched behind the pin by
    s = exp(dp d ln L/dp) (d ln L/dp from t by a finite difference of the FWHM) plus dp times the
    part of t_y that the stretch does not hold (t_y + (ξ − ξ_pin) y′ d ln L/dp behind the pin).
    A β step takes ln L linear in ln(1 − β) instead, as L grows near β → 1 (a power of 1 − β):
    the shallow family's last β steps then converge in 6 Newton iterations instead of 9.
    correct: the corrector (:func:`~slippulse.steady.newton.newton`) with the LU of J_x (chord iterations, then Newton if they stall).
    """
    if corrector is None:
        corrector = NewtonCorrector(max_iter=max_iter, chord=True, reuse_lu=False)
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
    lu = base.lu_a if keep and isinstance(corrector.linear, KrylovLU) else None
    if lu is None:
        lu = sla.lu_factor(J[:, cols], check_finite=False)
        t = -sla.lu_solve(lu, J[:, p], check_finite=False)
    elif fixed == "tau_d":
        t = -sla.lu_solve(lu, J[:, p], check_finite=False)
    else:
        w = sla.lu_solve(lu, J[:, n + 1], check_finite=False)     # the null direction (−w, 1)
        t = np.r_[w[:n], -1.0] / w[n]
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
    lnL_change = dp * dlnL
    if fixed == "beta":
        lnL_change = -(1.0 - base.beta) * dlnL * math.log((1.0 - value) / (1.0 - base.beta))
    y = stretch_profile(xi, y, xi[k], math.exp(lnL_change)) + dp * (t[:n] - t_stretch)
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
    x, st = corrector.solve(prob, x0, lu=lu)
    sol = SteadySolution(prob, x, st, time.perf_counter() - t0, 0)
    return sol, PulseOnGrid.of(sol, L_grid)


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


def judge_pulse(sol, humps=1):
    """(pulse, ok, message): a solve is accepted when it converged to a pulse of ``humps``
    humps, the count of the branch it continues (the main family's: one); a step can converge to
    a solution with ripples behind the peak, another branch."""
    pulse = sol.to_pulse()
    ok = pulse.converged and pulse.extra["n_humps"] == humps
    msg = sol.stats.message
    if pulse.converged and not ok:
        msg = f"converged to a {pulse.extra['n_humps']}-hump solution: rejected"
    return pulse, ok, msg


def solve_between(params, hi: PulseOnGrid, lo: SteadySolution, target, n_points, spec=GridSpec(),
                  max_iter=12):
    """Solve at τ_d/τ_min = ``target`` from the pair that brackets it, ``hi`` above and ``lo``
    (a fixed-β solution) below, interpolated linearly in τ_d (ln v onto ``lo``'s grid), on a
    grid of ``n_points`` adapted to the guess."""
    lo_q = float(lo.x[-1])
    w = (hi.q - target) / (hi.q - lo_q)
    y_t = (1 - w) * np.interp(lo.xi, hi.xi, hi.y) + w * lo.x[:-1]
    b_t = (1 - w) * hi.beta + w * lo.beta
    return solve_pulse(params, target, n_points=n_points, guess=(lo.xi, y_t, b_t), spec=spec,
                       passes=0, max_iter=max_iter)
