"""Steady-pulse solver: built-in guess, solution-adapted grids, Newton/LM solves, the Pulse result.

The physics lives in :mod:`slippulse.steady.equations` (residual and Jacobian on a fixed grid); this module
decides grids and drives the iteration:

1. a guess on a guess-adapted grid (:func:`default_guess`),
2. a solve on a coarse grid, then ``remesh`` passes: a grid adapted to the current solution
   (:func:`adapted_grid`), the solution interpolated onto it (:func:`interpolate`), re-pinned
   and re-solved, the last pass with the requested number of points.
"""
from __future__ import annotations

import math
import time
from dataclasses import dataclass, field

import numpy as np
from scipy.interpolate import PchipInterpolator

from .grid import build_grid
from .measures import pulse_length
from ..core.h5io import STATE_ORDER, Pulse
from .newton import NEWTON_TOL, SOLVERS, SolveStats
from ..core.params import ParameterError, Parameters
from ..core import friction as fr
from .equations import SteadyProblem, integrate_state

MIN_POINTS = 64
#: Largest grid: the Newton solver holds several dense (N+1)² matrices, 2 GB each at N = 16000.
MAX_POINTS = 16000


@dataclass(frozen=True)
class GridSpec:
    """How a solution-adapted grid is laid out (lengths in units of the pulse length L).

    ahead : domain ahead of the leading edge, in L.
    behind_tail : healing-tail length behind the pulse, in units of c_p · D/v_stick (the distance
        the pulse travels during one healing time).
    body : maximal spacing inside the pulse, in L (1/320: near τ_min the pulse body, not the
        leading edge, limits accuracy; measured at 1.015 τ_min: L/40 → L/320 cuts the N=2000→4000
        change of L from 5.2e-3 to 8.7e-4 and of β from 3.0e-4 to 4.5e-5).
    gamma : geometric grading of the far field (ratio of neighbouring cells ≈ 1 + γ h/L-scaled).
    """

    ahead: float = 120.0
    behind_tail: float = 40.0
    body: float = 1.0 / 320.0
    gamma: float = 0.06


@dataclass
class SteadySolution:
    """A solved (or failed) pulse: unknowns, grid, problem and solver statistics; ``tangent``:
    the family tangent at x (``free="both"``), where the continuation has it (its grid check
    then solves none of its own); ``fold_lu``: scipy's LU of A = ∂(Δ, pin)/∂(ln v, β) at x,
    where the fold test factored it (the next natural step then factors no matrix of its own)."""

    problem: SteadyProblem
    x: np.ndarray
    stats: SolveStats
    wall_time: float
    passes: int
    tangent: np.ndarray | None = None
    fold_lu: tuple | None = field(default=None, repr=False)

    @property
    def xi(self):
        return self.problem.xi

    @property
    def beta(self):
        return float(self.problem.split(self.x)[1])

    def to_pulse(self) -> Pulse:
        prob = self.problem
        p = prob.params
        v, phi, tau, _ = prob.fields(self.x)
        res = prob.residual(self.x)[:-1]
        L = pulse_length(prob.xi, v, p.v_star, crossings=False)
        return Pulse(
            xi=prob.xi.copy(), v=v, phi=phi, tau=tau, residual=res,
            tau_d_ratio=prob.tau_d_ratio, tau_d=prob.tau_d, tau_min=p.tau_min,
            beta=self.beta, c_p=self.beta * p.c_s, L=L, L_tilde=L / p.L_Gc,
            v_stick=prob.v_stick, v_max=float(v.max()),
            max_residual=float(np.max(np.abs(res))), converged=bool(self.stats.converged),
            n_points=int(prob.n), wall_time=float(self.wall_time), mode="III",
            extra={"status": "converged" if self.stats.converged else "failed",
                   "message": self.stats.message, "iterations": int(self.stats.iterations),
                   "hilbert": prob.hilbert, "pin_index": int(prob.pin_index),
                   "state_order": int(prob.state_order),
                   "n_humps": int(count_humps(v)),
                   "y_pin": float(prob.y_pin)})


def count_humps(v, rel=1e-2):
    """Number of local maxima of ln v that rise more than `rel` (in ln v) above the minima beside
    them: 1 for the fundamental pulse, 2 for a two-hump bound state."""
    y = np.log(v)
    humps, lo, hi = 0, y[0], -np.inf
    rising = True
    for val in y[1:]:
        if rising:
            if val > hi:
                hi = val
            elif val < hi - rel and hi > lo + rel:
                humps += 1
                rising, lo = False, val
        else:
            if val < lo:
                lo = val
            elif val > lo + rel:
                rising, hi = True, val
    if rising and hi > lo + rel and hi > y[-1] + rel:
        humps += 1
    return humps


def front_pin(xi, y, y_stick):
    """Index of the first node ahead of the maximum where y = ln v falls below mid-log level,
    and the level: the phase condition sits on the steep leading edge."""
    k = int(np.argmax(y))
    ymid = 0.5 * (y[k] + y_stick)
    ahead = np.nonzero((np.arange(y.size) > k) & (y < ymid))[0]
    if ahead.size == 0:
        raise RuntimeError("no leading edge found (slip rate does not fall ahead of its maximum)")
    return int(ahead[0]), ymid


#: Size of the built-in guess in units of the elasto-frictional length L0 = π μ D/(σ(f0 b − α)):
#: L = 0.7 m and ℓ_c = 5 mm for Table I (L0 = 0.88357 m), where they were chosen (orders of
#: magnitude from G_c ≈ 0.6 J/m²: π L ≈ μ G_c/Δτ²). Scaling with L0 makes the guess, like the
#: equations, invariant under the exact similarities (docs/steady.md §1).
GUESS_L_OVER_L0 = 0.7 / 0.8835729338221293
GUESS_LC_OVER_L0 = 5e-3 / 0.8835729338221293


def default_guess(params: Parameters, tau_d_ratio: float, n_points: int = 400, L: float = None,
                  beta: float = 0.01, lc: float = None):
    """Built-in guess: a classical (Freund) pulse regularised over a cohesive length.

    Notes
    -----
    v − v_stick = v0 √((ξ + L)/(ℓ_c − ξ)) on (−L, 0), decaying as e^{−ξ/ℓ_c} ahead, with the classical
    relation v0 = 2 β c_s Δτ/μ (paper, text above Eq. 3) for a stress drop Δτ = τ_d − 1.05 τ_min;
    L = 0.792 L0, β = 0.01, ℓ_c = 5.66e-3 L0 (L0 = π μ D/(σ(f0 b − α)); 0.7 m and 5 mm for Table I).
    Every length of the guess and its grid is a multiple of L0 or of c_p D/v_stick, every speed a
    multiple of c_s or v_stick: the guess depends on the dimensionless groups only.
    Returns (xi, y, beta).
    """
    L = GUESS_L_OVER_L0 * params.L0 if L is None else L
    lc = GUESS_LC_OVER_L0 * params.L0 if lc is None else lc
    tau_d = tau_d_ratio * params.tau_min
    v_st = params.v_stick(tau_d)
    dtau = max(tau_d - 1.05 * params.tau_min, 0.05 * params.tau_min)
    v0 = 2.0 * beta * params.c_s * dtau / params.mu
    hi, lo = 60.0 * L, -(L + 40.0 * beta * params.c_s * params.D / v_st)
    xs = np.array([-1.2 * L, -L, -L / 2, -5 * lc, 0.0, 5 * lc, L])
    hs = np.array([L / 50, L / 100, L / 100, lc / 8, lc / 8, lc / 8, L / 20])
    xi = build_grid(xs, hs, n_points, gamma=0.1, lo=lo, hi=hi)
    with np.errstate(invalid="ignore", over="ignore"):
        body = v0 * np.sqrt(np.clip(xi + L, 0.0, None) / (lc - np.minimum(xi, 0.0)))
        front = v0 * math.sqrt(L / lc) * np.exp(-np.maximum(xi, 0.0) / lc)
    v = v_st + np.where(xi < 0.0, body, front)
    return xi, np.log(v), beta


def adapted_grid(xi, y, phi, beta, params, v_stick, n_points, spec: GridSpec = GridSpec()):
    """Grid adapted to a solution: spacing ∝ min(1/|∂ξ ln v|, 1/|∂ξ ln φ|, body·L), graded far away."""
    L = pulse_length(xi, np.exp(y), params.v_star, crossings=False)
    if not np.isfinite(L) or L <= 0:
        raise RuntimeError("cannot measure the pulse length on this solution")
    k, _ = front_pin(xi, y, math.log(v_stick))
    x_front = xi[k]
    hi = x_front + spec.ahead * L
    lo = x_front - L - spec.behind_tail * beta * params.c_s * params.D / v_stick
    mid = 0.5 * (xi[1:] + xi[:-1])
    dy = np.abs(np.diff(y) / np.diff(xi))
    dl = np.abs(np.diff(np.log(phi)) / np.diff(xi))
    with np.errstate(divide="ignore"):
        h = np.minimum(1.0 / dy, 1.0 / dl)
    inside = (mid > x_front - 1.5 * L) & (mid < x_front + 0.2 * L)
    h = np.where(inside, np.minimum(h, spec.body * L), h)
    return build_grid(mid, h, n_points, gamma=spec.gamma, lo=lo, hi=hi)


def interpolate(xi_old, y_old, xi_new, v_stick, center=0.0):
    """ln v on a new grid: monotone cubic inside, far-field continuation u ∝ 1/(ξ − c) outside."""
    out = PchipInterpolator(xi_old, y_old, extrapolate=False)(xi_new)
    u_hi = math.exp(y_old[-1]) - v_stick
    u_lo = math.exp(y_old[0]) - v_stick
    ahead = xi_new > xi_old[-1]
    behind = xi_new < xi_old[0]
    out[ahead] = np.log(v_stick + u_hi * (xi_old[-1] - center) / (xi_new[ahead] - center))
    out[behind] = np.log(v_stick + u_lo * (center - xi_old[0]) / (center - xi_new[behind]))
    return out


def check_points(n_points: int, name: str = "points") -> None:
    """A grid size (the option ``name``): an integer in [MIN_POINTS, MAX_POINTS]."""
    if (not isinstance(n_points, (int, np.integer)) or n_points < MIN_POINTS
            or n_points > MAX_POINTS):
        raise ParameterError(f"{name}={n_points!r} is invalid: must be an integer in "
                             f"[{MIN_POINTS}, {MAX_POINTS}] (dense N x N Jacobian and Hilbert "
                             "matrices)")


@dataclass(frozen=True)
class SolveOptions:
    """How one solve on a fixed grid is made (refused when invalid).

    method: a solver of :data:`slippulse.steady.newton.SOLVERS`; tol: its max|residual| target;
    hilbert: the Hilbert assembly of :class:`slippulse.steady.equations.SteadyProblem`;
    max_iter: iterations; state_order: the state integrator. Newton only
    (:func:`slippulse.steady.newton.newton`): creep > 0 gives up once max|r| has not halved
    over `creep` iterations, for a caller that has another way on; reuse makes chord
    iterations with each full step's LU before a new Jacobian, for a guess already close (a
    re-solve); line_search is 'residual' or 'natural'.
    """

    method: str = "newton"
    tol: float = NEWTON_TOL
    hilbert: str = "cubic"
    max_iter: int = 60
    state_order: int = STATE_ORDER
    creep: int = 0
    reuse: bool = False
    line_search: str = "residual"

    def __post_init__(self):
        if self.method not in SOLVERS:
            raise ParameterError(f"method={self.method!r} is invalid: must be one of "
                                 f"{sorted(SOLVERS)}")
        if self.line_search not in ("residual", "natural"):
            raise ValueError(f"line_search={self.line_search!r} must be 'residual' or 'natural'")
        if not (self.tol > 0 and self.max_iter >= 1 and self.creep >= 0):
            raise ValueError(f"tol={self.tol!r} must be > 0, max_iter={self.max_iter!r} >= 1 "
                             f"and creep={self.creep!r} >= 0")

    def newton_extra(self) -> dict:
        """The Newton-only options that differ from Newton's defaults, as its keywords."""
        if self.method != "newton":
            return {}
        extra = {"creep": int(self.creep)} if self.creep else {}
        if self.reuse:
            extra["reuse"] = True
        if self.line_search != "residual":
            extra["line_search"] = self.line_search
        return extra


def solve_on_grid(params, tau_d_ratio, xi, y, beta, options: SolveOptions = SolveOptions()):
    """One solve on a fixed grid from (y, β) as ``options`` say; the phase condition is placed
    on the guess's front. Returns (problem, x, stats)."""
    v_st = params.v_stick(tau_d_ratio * params.tau_min)
    k, ymid = front_pin(xi, y, math.log(v_st))
    # pin at the node with the value the guess has there (keeps the pulse where it is)
    prob = SteadyProblem(params, tau_d_ratio, xi, k, float(y[k]), hilbert=options.hilbert,
                         state_order=options.state_order)
    x0 = np.concatenate([y, [beta]])
    x, stats = SOLVERS[options.method](prob, x0, tol=options.tol, max_iter=options.max_iter,
                                       **options.newton_extra())
    return prob, x, stats


def solve_pulse(params: Parameters, tau_d_ratio: float, n_points: int = 1500, guess=None,
                method: str = "newton", tol: float = NEWTON_TOL, hilbert: str = "cubic",
                spec: GridSpec = GridSpec(), passes: int = 2, coarse_points: int = 500,
                progress=None, max_iter: int = 60, adapt_guess: bool = True,
                state_order: int = STATE_ORDER) -> SteadySolution:
    """Solve the steady pulse at τ_d = tau_d_ratio τ_min.

    Parameters
    ----------
    guess : (xi, y, beta), optional
        Initial ln v on its grid and β (e.g. a neighbouring pulse); default: :func:`default_guess`.
    passes : number of adapt-and-resolve passes after the first solve; the last one uses n_points.
    coarse_points : points of the intermediate passes.
    adapt_guess : lay the first grid out from a given guess (with n_points when passes = 0);
        otherwise solve on the guess's own grid.
    progress : callable(str), optional, told about each pass.
    state_order : state integrator of every pass (:class:`slippulse.steady.equations.SteadyProblem`).
    """
    check_points(n_points)
    params.check_tau_d(tau_d_ratio * params.tau_min)
    options = SolveOptions(method, tol, hilbert, max_iter, state_order)
    t0 = time.perf_counter()
    v_st = params.v_stick(tau_d_ratio * params.tau_min)
    if guess is None:
        xi, y, beta = default_guess(params, tau_d_ratio, min(coarse_points, n_points))
    else:
        xi, y, beta = guess
        if adapt_guess:
            n0 = min(coarse_points, n_points) if passes > 0 else n_points
            xi, y = regrid_guess(params, tau_d_ratio, xi, y, beta, n0, spec)
    prob, x, stats = solve_on_grid(params, tau_d_ratio, xi, y, beta, options)
    if progress:
        progress(f"pass 0: N={xi.size} {stats.message}")
    npass = 0
    for k in range(passes):
        if not stats.converged:
            break
        n_k = n_points if k == passes - 1 else min(coarse_points, n_points)
        v, phi, _, _ = prob.fields(x)
        xi_new = adapted_grid(prob.xi, x[:-1], phi, x[-1], params, v_st, n_k, spec)
        y_new = interpolate(prob.xi, x[:-1], xi_new, v_st)
        prob, x, stats = solve_on_grid(params, tau_d_ratio, xi_new, y_new, float(x[-1]), options)
        npass += 1
        if progress:
            progress(f"pass {npass}: N={xi_new.size} {stats.message}")
    if passes > 0 and stats.converged and prob.n != n_points:
        stats.converged = False
        stats.message = f"internal error: final grid has {prob.n} points, not {n_points}"
    return SteadySolution(prob, x, stats, time.perf_counter() - t0, npass)


def guess_state(params, tau_d_ratio, xi, v, beta):
    """State φ(ξ) of a guessed slip rate v on xi at speed β, by the order-2 exponential update
    (:func:`slippulse.steady.equations.integrate_state`, w frozen on half cells) from the rest
    state ahead: robust on any guess; used to lay out grids, not to solve.

    Raises ParameterError when τ_d = tau_d_ratio τ_min is outside (τ_min, τ_peak).
    """
    tau_d = float(tau_d_ratio) * params.tau_min
    params.check_tau_d(tau_d)
    phi_end = float(fr.phi_ss(params.v_stick(tau_d), params.v_star, params.D))
    v = np.asarray(v, dtype=float)
    w = fr.heal_rate(v, params.v_star, params.D)
    dw_dy = v * v / (params.D * params.D * w)
    xi = np.ascontiguousarray(xi, dtype=float)
    return integrate_state(xi, v, beta * params.c_s, phi_end, w, dw_dy, False)[0]


def regrid_guess(params, tau_d_ratio, xi, y, beta, n_points, spec: GridSpec = GridSpec()):
    """Lay out a grid of n_points adapted to a guess (ln v on xi, speed β; its state follows from
    the steady state equation) and move ln v onto it. Returns (xi_new, y_new)."""
    v_st = params.v_stick(tau_d_ratio * params.tau_min)
    # φ only shapes the grid, from the robust order-2 update
    phi = guess_state(params, tau_d_ratio, xi, np.exp(y), beta)
    xi_new = adapted_grid(xi, y, phi, beta, params, v_st, n_points, spec)
    return xi_new, interpolate(xi, y, xi_new, v_st)


def resolve_on_grid(params, pulse, xi_new, method="newton", tol=NEWTON_TOL, state_order=STATE_ORDER,
                    creep=0, reuse=False, line_search="residual"):
    """The pulse re-solved on the grid `xi_new`, started from its ln v interpolated there and its
    β (creep, reuse, line_search: as :class:`SolveOptions`). Returns a :class:`SteadySolution`."""
    t0 = time.perf_counter()
    xi = np.asarray(pulse.xi, float)
    v_st = params.v_stick(pulse.tau_d_ratio * params.tau_min)
    y = interpolate(xi, np.log(np.asarray(pulse.v, float)), xi_new, v_st)
    options = SolveOptions(method, tol, state_order=state_order, creep=creep, reuse=reuse,
                           line_search=line_search)
    prob, x, stats = solve_on_grid(params, pulse.tau_d_ratio, xi_new, y, pulse.beta, options)
    return SteadySolution(prob, x, stats, time.perf_counter() - t0, 0)


def refine_nested(params, pulse, method="newton", tol=NEWTON_TOL, state_order=STATE_ORDER):
    """The pulse re-solved on its own grid with the midpoints inserted (N → 2N − 1), started from
    its ln v interpolated there: a nested refinement, for convergence studies (near τ_min it keeps
    the adapted grid's spacing jumps; :class:`slippulse.steady.grid.GridMap` does not). Returns a
    :class:`SteadySolution`."""
    return resolve_on_grid(params, pulse, nested_grid(pulse.xi), method, tol, state_order)


def nested_grid(xi):
    """``xi`` with the midpoint of every cell inserted (N → 2N − 1): every old node kept."""
    xi = np.asarray(xi, float)
    return np.sort(np.concatenate([xi, 0.5 * (xi[1:] + xi[:-1])]))


def extended_grid(xi, lead, ahead=1.0, behind=1.0, max_ratio=1.3):
    """``xi`` with nodes appended at its ends so that the front end lies ``ahead`` times and the
    back end ``behind`` times as far from ``lead`` (the leading edge) as before. Every node of
    ``xi`` is kept, so the pulse's discretisation is unchanged where it was; the new cells
    continue the end cell's geometric growth (ratio of the last two cells, clipped to
    [1, max_ratio]), so the far field is graded as the grid already grades it."""
    xi = np.asarray(xi, float)
    for name, f in (("ahead", ahead), ("behind", behind)):
        if not (math.isfinite(f) and f >= 1.0):
            raise ValueError(f"{name}={f!r}: must be a finite number >= 1")
    if not xi[0] < lead < xi[-1]:
        raise ValueError(f"lead={lead!r}: must lie inside the grid ({xi[0]}, {xi[-1]})")

    def grow(end, h, r, target):
        # the fewest cells h r, h r², ... that reach the target, scaled down to end on it
        dist = abs(target - end)
        cells = []
        while sum(cells) < dist * (1.0 - 1e-12):
            cells.append(h * r ** (len(cells) + 1))
        cells = np.asarray(cells) * (dist / sum(cells)) if cells else np.empty(0)
        return list(end + np.sign(target - end) * np.cumsum(cells))

    def ratio(h1, h0):
        return min(max(h1 / h0, 1.0), max_ratio)

    h = np.diff(xi)
    front = grow(xi[-1], h[-1], ratio(h[-1], h[-2]), lead + ahead * (xi[-1] - lead))
    back = grow(xi[0], h[0], ratio(h[0], h[1]), lead - behind * (lead - xi[0]))
    return np.concatenate([back[::-1], xi, front])


def resolve_on_extended_domain(params, pulse, ahead=1.0, behind=1.0):
    """``pulse`` solved again on its own grid extended ahead and behind of its leading edge (the
    node of largest v) by the factors ``ahead`` and ``behind`` (:func:`extended_grid`): a
    one-sided domain check that keeps the near field's discretisation, unlike
    :func:`resolve_on_longer_domain`, which re-adapts the grid. Newton stops once max|r| has not
    halved over 4 iterations (near β → 1 it creeps: 502 s at 10 km; ``steady long-domain`` then
    re-solves on the normal line). Returns a :class:`SteadySolution`."""
    xi = np.asarray(pulse.xi, float)
    lead = float(xi[int(np.argmax(pulse.v))])
    return resolve_on_grid(params, pulse, extended_grid(xi, lead, ahead, behind), creep=4)


def resolve_on_longer_domain(params, pulse, factor):
    """``pulse`` solved again on a domain ``factor`` times longer (paper Fig. S1b: the pulse does
    not depend on the domain): the domain ahead (in pulse lengths) and the healing tail behind
    (in healing lengths) both multiplied by ``factor``, N grown by 1 + 0.1 ln(factor) to keep the
    near-field spacing. Returns a :class:`SteadySolution`."""
    if not (math.isfinite(factor) and factor >= 1.0):
        raise ValueError(f"factor={factor!r}: must be a finite number >= 1")
    base = GridSpec()
    spec = GridSpec(ahead=base.ahead * factor, behind_tail=base.behind_tail * factor,
                    body=base.body, gamma=base.gamma)
    n = int(pulse.n_points * (1.0 + 0.1 * math.log(factor)))
    return solve_pulse(params, pulse.tau_d_ratio, n_points=n,
                       guess=(pulse.xi, np.log(pulse.v), pulse.beta), passes=1, coarse_points=n,
                       spec=spec)
