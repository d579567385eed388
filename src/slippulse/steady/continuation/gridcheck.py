"""Grid checks of a pulse: re-solved on a refined grid (2N adapted, 2N − 1 nested, or one region's
cells halved) on the line normal to the family tangent, the change expressed at fixed τ_d."""
from __future__ import annotations

import math
import time
import weakref
from dataclasses import dataclass

import numpy as np

from ..equations import SteadyProblem
from ..newton import NEWTON_TOL, KrylovLU, newton
from ..measures import pulse_length
from ..solver import MAX_POINTS, GridSpec, SteadySolution, front_pin, interpolate, regrid_guess
from .arclength import ArclengthProblem, family_tangent, unit_tangent
from .homotopy import solve_robust
from .strategy import NestedCheck, describe
from .tolerance import GRID_TOLERANCE


#: The grid checks' Newton reuses each full step's LU for chord iterations (newton(reuse=True)):
#: the same converged tolerance, fewer factorisations of the 2N − 1 Jacobian (a test counts
#: them: tests/test_continuation.py).
REUSE_LU = True


def check_grid_2n(params, sol: SteadySolution, n_points, spec=GridSpec(), max_iter=30,
                  nested=False, stages=0, cells=None, reuse=None, plain=True, warm=None,
                  linear="double"):
    """:func:`grid_change` as the family's criterion reads it: (fine, |Δβ|, |ΔL|/L)."""
    fine, dbeta, dL_rel = grid_change(params, sol, n_points, spec, max_iter, nested, stages, cells,
                                      reuse, plain, warm, linear)
    return fine, abs(dbeta), abs(dL_rel)


def grid_change(params, sol: SteadySolution, n_points, spec=GridSpec(), max_iter=30,
                nested=False, stages=0, cells=None, reuse=None, plain=True, warm=None,
                linear="double"):
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
    their midpoints are inserted (one region refined: :func:`locate_error`). ``stages`` > 0: when Newton fails, :func:`solve_robust` with that
    many homotopy stages. ``reuse``: Newton reuses each full step's LU for chord iterations
    (the same tolerance); None: :data:`REUSE_LU`, read at the call. ``plain=False`` (with
    ``stages``): the homotopy from the start (:func:`solve_robust`). ``linear``: the re-solve's
    linear solve (:func:`~slippulse.steady.newton.newton`, :class:`~.strategy.NestedCheck`).
    """
    q, beta = float(sol.x[-1]), sol.beta
    reuse = REUSE_LU if reuse is None else bool(reuse)
    t0 = time.perf_counter()
    if nested:
        xi = sol.xi
        mid = 0.5 * (xi[1:] + xi[:-1])
        xn = np.sort(np.concatenate([xi, mid if cells is None else mid[cells]]))
        yn, k = _onto(params, sol, xn)
        y_pin = sol.problem.y_pin
    else:
        xn, yn = regrid_guess(params, q, sol.xi, sol.x[:-2], beta, 2 * n_points, spec)
        k, _ = front_pin(xn, yn, math.log(params.v_stick(q * params.tau_min)))
        y_pin = float(yn[k])
    n, base, arc = normal_line(params, sol, xn, k, y_pin)
    x_start = np.concatenate([yn, [beta, q]])
    xs, st = _warm_solve(arc, sol.x, x_start, warm, max_iter, reuse, linear) \
        if nested and cells is None and warm else (None, None)
    if st is None or not st.converged:
        lu_warm = st.lu if st is not None else None
        if stages > 0:
            xs, st = solve_robust(arc, x_start, stages=stages, max_iter=max_iter, reuse=reuse,
                                  plain=plain, linear=linear, lu0=lu_warm)
        else:
            xs, st = newton(arc, x_start, tol=NEWTON_TOL, max_iter=max_iter, reuse=reuse,
                            keep=warm is not None, linear=linear)
        if st.lu is None:               # the homotopy keeps none: the warm attempt's, if any
            st.lu = lu_warm
    fine = SteadySolution(base, xs, st, time.perf_counter() - t0, 1)
    if not st.converged or n[-1] == 0.0:
        return fine, math.inf, math.inf
    return (fine, *change_at_fixed_tau_d(params, sol, n, fine))


def resolve_on_normal_line(params, sol: SteadySolution, xn, stages=8, max_iter=15):
    """``sol`` (x = (y, β, q)) re-solved on the grid ``xn``, which holds its nodes (its pin's
    node kept, ln v interpolated onto the rest), on the line through it normal to its family
    tangent, by the residual homotopy from the start (:func:`solve_robust`, single-precision LU
    under GMRES). Why: near β → 1 a fixed-τ_d re-solve on a changed grid creeps (the 10.1 km
    pulse, its domain doubled ahead: max|Δ| = 1.1e−5 after 60 iterations, 502 s), where this
    one converges in 13 s, τ_d moving by 3e−8 τ_min. Returns the SteadySolution (free="both")."""
    q = float(sol.x[-1])
    yn, k = _onto(params, sol, xn)
    t0 = time.perf_counter()
    _, base, arc = normal_line(params, sol, xn, k, sol.problem.y_pin)
    xs, st = solve_robust(arc, np.concatenate([yn, [sol.x[-2], q]]), stages=stages,
                          max_iter=max_iter, reuse=True, plain=False, linear=KrylovLU("single"))
    return SteadySolution(base, xs, st, time.perf_counter() - t0, 1)


def _onto(params, sol: SteadySolution, xn):
    """(ln v of ``sol`` (x = (y, β, q)) interpolated onto ``xn``, which holds its nodes; the index
    in ``xn`` of its pin's node, which is kept)."""
    q = float(sol.x[-1])
    yn = interpolate(sol.xi, sol.x[:-2], xn, params.v_stick(q * params.tau_min))
    return yn, int(np.searchsorted(xn, sol.xi[sol.problem.pin_index]))


def normal_line(params, sol: SteadySolution, xn, pin, y_pin):
    """The re-solve of ``sol`` (x = (y, β, q)) on the grid ``xn`` (pin node ``pin`` held at
    ``y_pin``) on the line through it normal to its family tangent: (n, SteadyProblem with β and q
    free, its :class:`ArclengthProblem` with ds = 0, κ = 1), n the unit tangent at ``sol``
    (:func:`grid_change`, Notes; :func:`~.relay.refine_front` and :func:`~.relay.recentre`)."""
    q, beta = float(sol.x[-1]), sol.beta
    n = _coarse_tangent(sol)
    base = SteadyProblem(params, q, xn, pin, y_pin, free="both",
                         state_order=sol.problem.state_order)
    arc = ArclengthProblem(base, math.log(1.0 - beta), q, -n[-2] / (1.0 - beta), n[-1], 1.0,
                           0.0)
    return n, base, arc


#: The last pulse whose tangent :func:`normal_line` solved for, and that tangent: a failed check
#: re-solves one pulse once per region (:func:`locate_error`) and again refined, each on the
#: line normal to the same tangent (a dense solve at N each, 14 % of a march at 2.6 km).
_LAST_TANGENT = [None, None, None]


def _coarse_tangent(sol: SteadySolution):
    """The unit tangent of :func:`normal_line` at ``sol``: the continuation's (``sol.tangent``,
    oriented and scaled here), else :func:`family_tangent`, solved once per pulse (the same
    problem object and the same unknowns, bit for bit). The continuation's comes from the LU it
    keeps (to 1e−11), where a solve here is a dense LU at N (6.8 s at N = 7647 on one core)."""
    prob, x = sol.problem, np.asarray(sol.x)
    t = sol.tangent
    if t is not None and t.shape == x.shape:
        return unit_tangent(t if t[-2] >= 0 else -t, float(x[-2]), 1.0)
    last_ref, last_x, last_n = _LAST_TANGENT
    if (last_ref is not None and last_ref() is prob and last_x.shape == x.shape
            and np.array_equal(x, last_x)):
        return last_n
    n = family_tangent(prob, x, (1.0, 0.0, 1.0))
    _LAST_TANGENT[:] = [weakref.ref(prob), x.copy(), n]     # weak: keeps no Hilbert matrix alive
    return n


def change_at_fixed_tau_d(params, sol: SteadySolution, n, fine: SteadySolution):
    """(Δβ, ΔL/L) of ``fine``, solved on the line through ``sol`` normal to the family tangent
    ``n`` (both x = (y, β, q); n[-1] ≠ 0), from ``sol``, at ``sol``'s τ_d: to first order along
    the family, Δβ = β₁ − β₀ − (n_β/n_q) dq and ΔL = L₁ − L₀ − (dL/ds)/n_q dq, dq = q₁ − q₀, dL/ds
    by a finite difference of the FWHM along n (:func:`grid_change`, Notes)."""
    p0, p1 = sol.to_pulse(), fine.to_pulse()
    eps = 1e-3 / max(float(np.abs(n[:-2]).max()), 1e-12)
    dL_ds = (pulse_length(sol.xi, np.exp(sol.x[:-2] + eps * n[:-2]), params.v_star,
                          crossings=False) - p0.L) / eps
    dq = float(fine.x[-1]) - float(sol.x[-1])
    dbeta = p1.beta - p0.beta - (n[-2] / n[-1]) * dq
    dL = p1.L - p0.L - dL_ds / n[-1] * dq
    return dbeta, dL / p0.L


def _warm_solve(arc, x, x_start, warm, max_iter, reuse, linear="double"):
    """The warm re-solve of :func:`grid_change`: (x_fine, stats) from the transported start with
    the earlier check's LU, or (None, None) when ``warm`` does not fit this grid or its start is
    no better than ``x_start``. The stats carry the last LU (``keep``)."""
    x0, xf0, lu = warm
    n, nf = x.size - 2, x_start.size - 2
    if x0.size != x.size or xf0.size != x_start.size or nf != 2 * n - 1:
        return None, None
    d = x[:-2] - x0[:-2]
    xw = xf0.copy()
    xw[:-2][0::2] += d
    xw[:-2][1::2] += 0.5 * (d[:-1] + d[1:])
    xw[-2:] += x[-2:] - x0[-2:]
    rw, ri = arc.residual(xw), arc.residual(x_start)
    if not np.max(np.abs(rw)) < np.max(np.abs(ri)):      # also False for a non-finite rw
        return None, None
    if lu is not None and lu[0].shape[0] != xw.size:
        lu = None
    return newton(arc, xw, tol=NEWTON_TOL, max_iter=max_iter, lu=lu, reuse=reuse, creep=2, keep=True,
                  linear=linear)


def _as_both(params, sol: SteadySolution) -> SteadySolution:
    """A fixed-β solution (x = (y, q)) as a solution of ``free="both"`` (x = (y, β, q))."""
    prob = sol.problem
    both = SteadyProblem(params, prob.tau_d_ratio, prob.xi, prob.pin_index, prob.y_pin,
                         free="both", H=prob.H)
    x = np.concatenate([sol.x[:-1], [prob.beta_fixed, float(sol.x[-1])]])
    return SteadySolution(both, x, sol.stats, sol.wall_time, sol.passes, sol.tangent)



def as_both(params, sol: SteadySolution) -> SteadySolution:
    """Any solution (fixed τ_d: x = (y, β); fixed β: x = (y, q); both: x = (y, β, q)) as one of
    ``free="both"`` on the same grid, pin and Hilbert matrix, with its family tangent if any."""
    prob = sol.problem
    if prob.free == "both":
        return sol
    if prob.free == "tau_d":
        return _as_both(params, sol)
    both = SteadyProblem(params, prob.tau_d_ratio, prob.xi, prob.pin_index, prob.y_pin,
                         free="both", H=prob.H, state_order=prob.state_order)
    x = np.concatenate([sol.x, [prob.tau_d_ratio]])
    return SteadySolution(both, x, sol.stats, sol.wall_time, sol.passes, sol.tangent)


#: The regions of :func:`regions`. The body held most of the N-dependence on the deformed grid
#: at 600 m (docs/analysis.md: 1.67e-4 of 1.78e-4 at 602 m); beyond 2 km the zone ±0.01 L about
#: the leading edge, which the deformation keeps while the pulse lengthens, holds the largest part
#: (−1.26e-4 of ≈ −1.7e-4 at 2.43 km, :func:`locate_error`), and within it the band
#: (−0.01 L, −0.0005 L] behind the edge (at 2.06 km −8.6e-5 of the zone's −1.0e-4 from
#: 121 of its 620 cells, the steep edge itself −1.2e-5; at 4.08 km that band alone, 119 cells,
#: took the check from 9.1e-5 to 2.1e-5, the whole zone, 696 cells, to 7.4e-6).
AHEAD = "ahead (> +0.01 L)"
NEAR = "behind the edge (−0.01 L, −0.0005 L]"
LEADING = "leading edge (−0.0005 L, +0.01 L]"
BODY = "body (−0.9 L, −0.01 L]"
HEALING = "healing front (−1.1 L, −0.9 L]"
TAIL = "tail (< −1.1 L)"
#: the regions whose share of the error :func:`check_pulse` measures before refining (ahead of
#: the front and in the tail the share is ~1e-10: measured at 2.43 km)
INNER = (LEADING, NEAR, BODY, HEALING)


def regions(sol: SteadySolution, L: float) -> dict:
    """Boolean masks over the cells of ``sol``'s grid: ahead, leading edge, behind the edge, body,
    healing front, tail, relative to the pin ξ_R and the pulse length L."""
    xi = sol.xi
    xf = xi[sol.problem.pin_index]
    mid = 0.5 * (xi[1:] + xi[:-1])
    return {AHEAD: mid > xf + 0.01 * L,
            LEADING: (mid > xf - 0.0005 * L) & (mid <= xf + 0.01 * L),
            NEAR: (mid > xf - 0.01 * L) & (mid <= xf - 0.0005 * L),
            BODY: (mid > xf - 0.9 * L) & (mid <= xf - 0.01 * L),
            HEALING: (mid > xf - 1.1 * L) & (mid <= xf - 0.9 * L),
            TAIL: mid <= xf - 1.1 * L}


def refine_regions(params, sol: SteadySolution, names, max_iter=20, stages=0, linear="double"):
    """``sol`` (x = (y, β, q)) re-solved with the midpoints of the cells of the named regions
    (:func:`regions`) inserted, on the line normal to the family tangent. Returns (refined
    SteadySolution, cells added)."""
    masks = regions(sol, sol.to_pulse().L)
    sel = np.zeros(sol.xi.size - 1, bool)
    for name in names:
        sel |= masks[name]
    fine, _, _ = check_grid_2n(params, sol, sol.xi.size, nested=True, cells=sel,
                               max_iter=max_iter, stages=stages, linear=linear)
    return fine, int(sel.sum())


def refine_body(params, sol: SteadySolution, max_iter=20, stages=0):
    """:func:`refine_regions` of the body alone."""
    return refine_regions(params, sol, (BODY,), max_iter=max_iter, stages=stages)


def locate_error(params, sol: SteadySolution, names=INNER, max_iter=15, stages=0,
                 linear="double"):
    """Where the N-dependence of a pulse sits: each named region refined alone (its cells'
    midpoints inserted), the pulse re-solved, the change at fixed τ_d.

    Returns {region: (Δβ, ΔL/L, cells, SteadySolution)}, Δ = inf where the re-solve fails. The
    shares add up, to first order, to the full nested check's change (at 2.43 km, N = 5325:
    −1.26e-4 leading edge, −8.6e-5 body, +4.1e-5 healing front, sum −1.71e-4 against −1.6e-4
    all together); where a region has few cells the grid's jumps in spacing at its borders
    spoil that (1.6 times the full change at N = 500, 4 cells in the leading edge).
    """
    masks = regions(sol, sol.to_pulse().L)
    out = {}
    for name in names:
        fine, db, dl = grid_change(params, sol, sol.xi.size, nested=True, cells=masks[name],
                                   max_iter=max_iter, stages=stages, linear=linear)
        ok = bool(fine.stats.converged) and math.isfinite(db)
        out[name] = (db if ok else math.inf, dl if ok else math.inf, int(masks[name].sum()), fine)
    return out


def _to_refine(shares, tol, margin=0.8, cells=None, budget=None):
    """The regions to refine after a failed check: the fewest, largest shares first, whose
    removal leaves the sum of the others within `margin` × the tolerance (the shares are
    signed and add up to first order, so the rest may cancel).

    cells, budget: the cells of each region and the most cells the refinement may add (the
    refined pulse's check must fit in the largest grid). Regions beyond the budget are dropped,
    smallest share first, down to the largest share alone; that one is kept even beyond the
    budget (the caller then doubles N instead, or stops)."""
    def weight(v):
        return max(abs(v[0]) / tol.beta, abs(v[1]) / tol.L)
    order = sorted(shares, key=lambda k: weight(shares[k]), reverse=True)
    chosen = []
    for name in order:
        chosen.append(name)
        rest = [v for k, v in shares.items() if k not in chosen]
        if (abs(sum(v[0] for v in rest)) <= margin * tol.beta
                and abs(sum(v[1] for v in rest)) <= margin * tol.L):
            break
    if cells is not None and budget is not None:
        while len(chosen) > 1 and sum(cells[k] for k in chosen) > budget:
            chosen.pop()
    return chosen


@dataclass
class GridCheck:
    """Outcome of :func:`check_pulse`.

    Attributes
    ----------
    sol : the pulse to keep (x = (y, β, q)): the one whose check passed, else the last checked.
    passed : whether ``sol`` meets the tolerance against its nested refinement.
    n : grid points of ``sol``; n_fine : of the grid it was checked against (2n − 1).
    dbeta, dL_rel : signed N → 2N − 1 differences at fixed τ_d (inf: the check did not converge).
    body_levels : body refinements applied to reach ``sol``; doublings : nested doublings.
    message : what was tried, in one line.
    wall_time : seconds spent.
    homotopy : whether the first check's re-solve needed the residual homotopy.
    method : the :class:`~.strategy.NestedCheck` it was checked by, printed.
    warm : (x, x_fine, lu) of a check that passed at once (no refinement): the ``warm`` of the
        next pulse's check on the same deformed grid (:func:`grid_change`); None otherwise.
    """

    sol: SteadySolution
    passed: bool
    n: int
    n_fine: int
    dbeta: float
    dL_rel: float
    body_levels: int = 0
    doublings: int = 0
    message: str = ""
    wall_time: float = 0.0
    homotopy: bool = False
    warm: object = None
    method: str = ""

    @property
    def replaced(self) -> bool:
        """Whether the pulse kept is another than the one handed (refined, or N doubled)."""
        return bool(self.body_levels or self.doublings)

    def attrs(self, tol) -> dict:
        """The check's figures as pulse attributes (stored in the family file)."""
        return {"grid_check_passed": bool(self.passed), "grid_check_n": int(self.n),
                "grid_check_n_fine": int(self.n_fine), "grid_check_dbeta": float(self.dbeta),
                "grid_check_dL_rel": float(self.dL_rel),
                "grid_check_body_levels": int(self.body_levels),
                "grid_check_doublings": int(self.doublings),
                "grid_check_tol_beta": float(tol.beta), "grid_check_tol_L": float(tol.L),
                "grid_check_message": self.message, "grid_check_wall_time": float(self.wall_time),
                "grid_check_method": self.method}


def check_pulse(params, sol: SteadySolution, tol=GRID_TOLERANCE, n_max=MAX_POINTS, body_levels=2,
                max_iter=15, stages=4, log=None, locate=False, plain=True, warm=None,
                method=NestedCheck()) -> GridCheck:
    """Grid-check a pulse and refine it until it passes: N, or the body refinement, per pulse.

    Parameters
    ----------
    sol : a converged pulse (any ``free``; converted with :func:`as_both`).
    tol : :class:`GridTolerance` (β and L between N and 2N − 1 at fixed τ_d).
    n_max : largest grid a check may use (the 2N − 1 grid).
    body_levels : local refinements tried before doubling N.
    log : callable(str), optional; one line per check.
    locate : False: each local refinement is of the body (:func:`refine_body`). True: after a
        failed check the error is located first (:func:`locate_error` over the leading edge,
        the band behind it, the body and the healing front: one re-solve each, cheaper than the
        check) and the
        fewest regions whose shares leave the rest within 0.8 of the tolerance are refined
        together (:func:`_to_refine`), as many of them, largest share first, as keep the
        refined pulse's check within ``n_max``.
    plain : False: the first check's re-solve starts with the homotopy (:func:`solve_robust`
        ``plain=False``; a caller whose last check needed it, :attr:`GridCheck.homotopy`).
    warm : :attr:`GridCheck.warm` of the last pulse's check: the first re-solve starts from its
        fine pulse, transported (:func:`grid_change`); ignored when it does not fit.
    method : :class:`~.strategy.NestedCheck`, the linear solve of every re-solve.

    Notes
    -----
    Each check re-solves the pulse on its own grid with all midpoints inserted
    (:func:`check_grid_2n`, ``nested=True``). While it fails: first the body cells (where the error
    of the deformed grids sits, docs/analysis.md) get their midpoints inserted, up to
    ``body_levels`` times, each refined pulse checked in turn; then the nested 2N − 1 pulse replaces
    the pulse (N doubled) while its own check fits in ``n_max``. Returns the first pulse that passes,
    or the last one checked with ``passed=False`` and the reason in ``message``.
    """
    t0 = time.perf_counter()
    if not isinstance(method, NestedCheck):
        raise TypeError(f"method={method!r}: must be a NestedCheck")
    linear = method.linear
    cur = as_both(params, sol)
    levels = doublings = 0
    steps = []
    homotopy = None                 # whether the first check's re-solve needed the homotopy
    while True:
        n = cur.xi.size
        fine, db, dl = check_grid_2n(params, cur, n, nested=True, stages=stages,
                                     max_iter=max_iter, plain=plain,
                                     warm=warm if not steps else None, linear=linear)
        lu, fine.stats.lu = fine.stats.lu, None
        if homotopy is None:
            homotopy, plain = bool(fine.stats.homotopy), True   # later checks: plain first
        ok = bool(fine.stats.converged) and math.isfinite(db)
        line = (f"N={n} vs {fine.xi.size}: dbeta={db:.1e} dL/L={dl:.1e}" if ok else
                f"N={n} vs {fine.xi.size}: re-solve failed ({fine.stats.message})")
        steps.append(line)
        if log:
            log(f"grid check at tau_d/tau_min={float(cur.x[-1]):.7f}: {line}")
        res = GridCheck(cur, ok and tol.passes(db, dl), n, fine.xi.size, db, dl, levels,
                        doublings)
        if res.passed or not ok:
            if res.passed and len(steps) == 1 and warm is not None:
                res.warm = (np.array(cur.x), np.array(fine.x), lu)
            break
        if levels < body_levels:
            names, where = (BODY,), "body"
            shares = {}
            if locate:
                shares = locate_error(params, cur, max_iter=max_iter, stages=stages,
                                      linear=linear)
                names = tuple(_to_refine(shares, tol, cells={k: v[2] for k, v in shares.items()},
                                         budget=(n_max + 1) // 2 - n))
                where = "+".join(name.split(" (")[0] for name in names)
                located = ", ".join(f"{name.split(' (')[0]} {v[1]:+.1e}"
                                    for name, v in shares.items())
                steps.append(f"dL/L by region: {located}")
                if log:
                    log(f"grid check at tau_d/tau_min={float(cur.x[-1]):.7f}: dL/L by region "
                        f"{located}; refining {where}")
            if len(names) == 1 and shares.get(names[0], (math.inf,))[0] != math.inf:
                # one region: locate_error has already solved the pulse on exactly that grid
                _, _, added, nxt = shares[names[0]]
            else:
                nxt, added = refine_regions(params, cur, names, max_iter=max_iter + 5,
                                            stages=stages, linear=linear)
            if nxt.stats.converged and 2 * nxt.xi.size - 1 <= n_max:
                cur, levels = nxt, levels + 1
                steps.append(f"{where} +{added}")
                continue
            levels = body_levels            # the local refinement does not help: double N
        if 2 * fine.xi.size - 1 > n_max:
            steps.append(f"N={fine.xi.size} would need {2 * fine.xi.size - 1} > max points {n_max}")
            break
        cur, doublings, levels = fine, doublings + 1, 0
    res.message = "; ".join(steps)
    res.wall_time = time.perf_counter() - t0
    res.homotopy = homotopy
    res.method = describe(method)
    return res


def monitor_first(monitor, sol, pulse=None):
    """(the monitor's attributes, its ``previous`` before the call) where the monitor finds
    family tangents (``finds_tangent``) and ``sol`` has none, else (None, None). Why: the fold
    test factors the pinned Jacobian at the pulse and finds the tangent with it
    (:class:`~slippulse.steady.bifurcation.FamilyMonitor`), which the grid check's normal line
    would otherwise solve for (a dense LU at N). Other monitors see only the pulse written."""
    if not getattr(monitor, "finds_tangent", False) or sol.tangent is not None:
        return None, None
    previous = getattr(monitor, "previous", None)
    return monitor(sol, sol.to_pulse() if pulse is None else pulse) or {}, previous


@dataclass
class ConvergenceLevel:
    """One level of :func:`grid_convergence`: the pulse on ``n`` points (τ_d/τ_min, β, L in m)
    and its change from the level before at that level's τ_d (0 on level 0; inf where the
    re-solve did not converge)."""

    n: int
    tau_d_ratio: float
    beta: float
    L: float
    dbeta: float = 0.0
    dL_rel: float = 0.0
    converged: bool = True
    wall_time: float = 0.0


def grid_convergence(params, sol: SteadySolution, levels=2, stages=4, max_iter=15,
                     linear=None, log=None) -> list[ConvergenceLevel]:
    """The pulse ``sol`` re-solved on ``levels`` nested refinements (N → 2N − 1 → 4N − 3 …),
    each from the one before, as the grid check does it (:func:`grid_change`: on the normal
    line, the change at fixed τ_d). Why: one level is the check; two give the observed order
    and so whether the check's change bounds the pulse's own error (:func:`observed_order`).
    Stops at the first level that does not converge (its row ``converged=False``)."""
    linear = NestedCheck().linear if linear is None else linear
    cur = as_both(params, sol)
    p = cur.to_pulse()
    rows = [ConvergenceLevel(cur.xi.size, float(cur.x[-1]), p.beta, p.L)]
    for _ in range(levels):
        t0 = time.perf_counter()
        fine, db, dl = grid_change(params, cur, cur.xi.size, nested=True, stages=stages,
                                   max_iter=max_iter, linear=linear)
        ok = bool(fine.stats.converged) and math.isfinite(db)
        pf = fine.to_pulse()
        rows.append(ConvergenceLevel(fine.xi.size, float(fine.x[-1]), pf.beta, pf.L, db, dl, ok,
                                     time.perf_counter() - t0))
        if log:
            log(f"N={cur.xi.size} -> {fine.xi.size}: dbeta={db:.3e} dL/L={dl:.3e} "
                f"({'converged' if ok else 'not converged'}, {rows[-1].wall_time:.1f} s)")
        if not ok:
            break
        fine.stats.lu = None                 # the next level factors its own
        cur = fine
    return rows


def observed_order(rows) -> tuple[float, float]:
    """(p_β, p_L): log₂ of the ratio of two successive changes (:func:`grid_convergence`, three
    converged levels or more; nan otherwise or where a change is zero). Nested doubling halves
    every spacing, so p is the discretisation's order where the errors are asymptotic (4 for
    the state integration and the Hilbert operator, docs/steady.md)."""
    ok = [r for r in rows[1:] if r.converged]
    if len(ok) < 2:
        return math.nan, math.nan

    def p(a, b):
        return math.log2(abs(a) / abs(b)) if a and b else math.nan
    return p(ok[-2].dbeta, ok[-1].dbeta), p(ok[-2].dL_rel, ok[-1].dL_rel)
