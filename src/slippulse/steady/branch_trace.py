"""Pseudo-arclength tracing of one branch of pulses in τ_d, with its test functions at every step.

Standalone (it uses only :class:`~slippulse.steady.equations.SteadyProblem` with ``free="both"``
and :mod:`.bifurcation`), for a branch other than the main family (e.g. the two-pulse bound state
that :mod:`.branch_search` finds). Unknowns x = (ln v, β, q); the arclength is measured in the
scalars z = (ln β, q/Q_SCALE), so a fold in τ_d (q turning while β moves on) is passed, and,
with :class:`ArcMetric`'s ``state`` > 0, in the nodal ln v as well, which follows a branch that
changes in shape at nearly fixed (β, q); the corrector is Newton on [F(x); τ·(z(x) − z₀) − ds]
with τ the unit tangent in z. The grid is the start pulse's, re-laid (adapted to the current
pulse, N points, re-solved on the hyperplane normal to the branch, else at fixed τ_d) whenever L
or the extent of the humps (:func:`extent`: a trailing hump that comes apart from the first moves
it, not L) has moved by more than ``regrid`` since the grid was laid. At every accepted step: β,
L, the hump count, sign det A, t_q (continuity-oriented) and sign det B (comparable between
re-lays only); a sign change of t_q is a fold, of det B on one grid a branch point.
"""
from __future__ import annotations

import math
import time
import warnings
from dataclasses import dataclass, field

import numpy as np
import scipy.linalg as sla

from .bifurcation import indicators, pulse_system
from .equations import SteadyProblem
from .measures import pulse_length
from .solver import (adapted_grid, count_humps, front_pin, interpolate, nested_grid,
                     solve_on_grid)

#: q = τ_d/τ_min enters the arclength as q/Q_SCALE (a step of 0.04 in q weighs as one in ln β).
Q_SCALE = 0.04


@dataclass
class TracePoint:
    q: float
    beta: float
    L: float
    humps: int
    fold_sign: int
    t_q: float
    bordered_sign: int
    grid: int            # index of the grid (re-lays counted); det B signs compare within one
    n_points: int
    extent: float = math.nan   # m, first to last node at or above half the maximum of ln(v/v*+1)


@dataclass
class Trace:
    points: list = field(default_factory=list)
    events: list = field(default_factory=list)     # (kind, index of the point after it, detail)
    stop_reason: str = ""
    out_of_steps: bool = False     # stopped by max_steps (a budget), not by the branch
    wall_time: float = 0.0
    pulses: list = field(default_factory=list, repr=False)   # the accepted solutions (Pulse)


def extent(xi, v, v_star) -> float:
    """Distance from the first to the last node where y = ln(v/v* + 1) is at least half its
    maximum: L where the region y ≥ max/2 is connected, and the span of all humps where a trailing
    hump has come apart from the first (there L, the width of the region that holds the
    maximum, no longer sees it)."""
    y = np.log(np.asarray(v, float) / v_star + 1.0)
    above = np.flatnonzero(y >= 0.5 * float(y.max()))
    return float(xi[above[-1]] - xi[above[0]])


@dataclass(frozen=True)
class ArcMetric:
    """What the pseudo-arclength measures, in the unknowns x = (ln v, β, q): the scalars
    z = (ln β, q/Q_SCALE), and with ``state`` > 0 the nodal ln v as well, as ``state`` times its
    root mean square over the nodes. The scalars alone cannot follow a branch that changes in
    shape at nearly fixed (β, q) (a trailing hump drifting away, a fold where β and q turn
    together): there the step stalls. With the state counted the step moves the shape, and the
    tangent's orientation by continuity keeps the trace from turning back on itself."""

    state: float = 0.0

    def __post_init__(self):
        if not (self.state >= 0.0 and math.isfinite(self.state)):
            raise ValueError(f"state={self.state!r} must be a finite number >= 0")

    def weights(self, x):
        """dz/dx, elementwise, in the layout of x."""
        w = np.full(x.size, self.state / math.sqrt(x.size - 2))
        w[-2], w[-1] = 1.0 / x[-2], 1.0 / Q_SCALE
        return w

    def z(self, x):
        """The measured coordinates, in the layout of x (ln v scaled, ln β, q/Q_SCALE)."""
        z = x * (self.state / math.sqrt(x.size - 2))
        z[-2], z[-1] = math.log(x[-2]), x[-1] / Q_SCALE
        return z

    def describe(self) -> str:
        return ("(ln beta, q/0.04)" if self.state == 0.0 else
                f"(ln beta, q/0.04, {self.state:g} x RMS ln v)")


def _tangent(J, x, metric, orient=None):
    """Unit tangent in the metric's coordinates (layout of x) and the full tangent scaled to
    move them by one unit along it; oriented along ``orient`` (the last one, on the same nodes)
    where given."""
    from .bifurcation import null_vector
    t = null_vector(J)
    tz = t * metric.weights(x)
    nz = float(np.linalg.norm(tz))
    if nz < 1e-14:
        raise RuntimeError("the branch turns in ln v alone (tangent with no (beta, q) part)")
    if orient is not None and float(tz @ orient) < 0:
        t, tz = -t, -tz
    return tz / nz, t / nz


def _pulse(prob, x, params):
    from .solver import SteadySolution
    from .newton import SolveStats
    fixed = SteadyProblem(params, float(x[-1]), prob.xi, prob.pin_index, prob.y_pin, H=prob.H)
    st = SolveStats(True, "traced", 0, float(np.max(np.abs(fixed.residual(x[:-1])))))
    return SteadySolution(fixed, x[:-1].copy(), st, 0.0, 0).to_pulse()


@dataclass(frozen=True)
class TraceSettings:
    """How :func:`trace` walks a branch (refused when invalid).

    direction: −1 toward decreasing τ_d, +1 toward increasing; ds, ds_min, ds_max: the first,
    smallest and largest arclength step in z (halved on a failed corrector, ×1.5 after one that
    took at most 3 iterations); max_steps: accepted steps; n_points: points of a re-laid grid
    (None: the start pulse's); regrid: the relative change of L that re-lays the grid; q_min and
    L_max (m): where the trace stops; max_iter and tol: the corrector's iterations and its max|F|;
    stop_on_humps: stop when the hump count changes (always reported as an event 'humps');
    relay_start: first re-lay the grid on the start pulse (adapted, ``n_points``) and re-solve it
    at its τ_d (a stored pulse whose grid no longer fits it, e.g. the end of a trace); metric:
    what the arclength measures (:class:`ArcMetric`).
    """

    direction: int = -1
    ds: float = 0.1
    ds_min: float = 1e-3
    ds_max: float = 0.4
    max_steps: int = 80
    n_points: int | None = None
    regrid: float = 0.25
    q_min: float = 1.0005
    L_max: float = 1e3
    max_iter: int = 12
    tol: float = 1e-11
    stop_on_humps: bool = False
    relay_start: bool = False
    metric: ArcMetric = ArcMetric()

    def __post_init__(self):
        if self.direction not in (-1, 1):
            raise ValueError(f"direction={self.direction!r} must be -1 or +1")
        if not 0.0 < self.ds_min <= self.ds <= self.ds_max:
            raise ValueError(f"steps ds_min={self.ds_min!r} <= ds={self.ds!r} <= "
                             f"ds_max={self.ds_max!r} must be positive and ordered")
        for name in ("max_steps", "max_iter"):
            if getattr(self, name) < 1:
                raise ValueError(f"{name}={getattr(self, name)!r} must be >= 1")
        if self.n_points is not None and self.n_points < 10:
            raise ValueError(f"n_points={self.n_points!r} must be >= 10 (or None)")
        if not (self.regrid > 0 and self.q_min > 1.0 and self.L_max > 0 and self.tol > 0):
            raise ValueError("regrid, L_max and tol must be > 0 and q_min > 1")


class _Record:
    """The accepted points of a trace, their pulses and the events between them (a sign change
    of t_q: a fold; of det B on one grid: a branch point)."""

    def __init__(self, params, progress, on_pulse=None):
        self.params, self.progress, self.on_pulse = params, progress, on_pulse
        self.out = Trace()
        self.grid_id = 0

    def add(self, prob, x, J, tz_or, metric) -> TracePoint:
        out, params = self.out, self.params
        v = indicators(J, orient=None, singular_values=False)
        # orient the indicators' tangent like the march's (continuity)
        sgn = 1 if float((v.tangent * metric.weights(x)) @ tz_or) >= 0 else -1
        Lx = pulse_length(prob.xi, np.exp(x[:-2]), params.v_star, crossings=False)
        pt = TracePoint(float(x[-1]), float(x[-2]), float(Lx), count_humps(np.exp(x[:-2])),
                        v.fold_sign, sgn * v.t_param, sgn * v.bordered_sign, self.grid_id, prob.n,
                        extent(prob.xi, np.exp(x[:-2]), params.v_star))
        if out.points:
            a = out.points[-1]
            if a.t_q * pt.t_q < 0:
                out.events.append(("fold", len(out.points), f"t_q {a.t_q:+.2e} -> {pt.t_q:+.2e} "
                                   f"between q={a.q:.6f} and {pt.q:.6f}"))
            if a.grid == pt.grid and a.bordered_sign * pt.bordered_sign < 0:
                out.events.append(("branch point", len(out.points),
                                   f"det B {a.bordered_sign:+d} -> {pt.bordered_sign:+d} between "
                                   f"q={a.q:.6f} and {pt.q:.6f}"))
        out.points.append(pt)
        out.pulses.append(_pulse(prob, x, params))
        if self.on_pulse:
            self.on_pulse(pt, out.pulses[-1])
        if self.progress:
            self.progress(pt)
        return pt


def _correct(prob, x, t, tz, ds, max_iter, tol, metric):
    """The corrector from the predictor x + ds t: Newton on [F(x); τ·(z(x) − z₀) − ds], each step
    capped at 1 in ln v. Returns (converged, x, J, iterations)."""
    z0 = metric.z(x)
    xp = x + ds * t
    if not prob.valid(xp):
        return False, None, None, 0
    xc = xp.copy()
    for it in range(max_iter):
        rc, Jc = prob.residual_and_jacobian(xc)
        g = float(tz @ (metric.z(xc) - z0)) - ds
        if np.max(np.abs(rc)) <= tol and abs(g) <= 1e-10:
            return True, xc, Jc, it
        row = tz * metric.weights(xc)
        try:
            # where the branch turns in shape at nearly fixed (β, q) the bordered matrix is
            # singular to working precision; the residual test above judges the step, and the
            # trace stops at ds_min with its reason, instead of a warning per iteration
            with warnings.catch_warnings():
                warnings.simplefilter("ignore", sla.LinAlgWarning)
                step = sla.solve(np.vstack([Jc, row]), -np.concatenate([rc, [g]]),
                                 check_finite=False)
        except (ValueError, np.linalg.LinAlgError):
            break
        big = float(np.max(np.abs(step[:-2])))
        if big > 1.0:
            step *= 1.0 / big
        xc = xc + step
        if not prob.valid(xc):
            break
    return False, None, None, 0


def _relay(params, prob, x, pt, n_points, t, metric):
    """Re-lay the grid on the current pulse (adapted, ``n_points``) and re-solve it there on the
    hyperplane normal to the branch's tangent ``t`` (:func:`_onto_normal`), else at fixed τ_d
    (which fails where the shape moves at nearly fixed τ_d): (the problem on the new grid, its x)
    or (None, the failure's message)."""
    yv = x[:-2]
    vst = params.v_stick(pt.q * params.tau_min)
    fields = SteadyProblem(params, pt.q, prob.xi, prob.pin_index, prob.y_pin, H=prob.H)
    phi = fields.fields(x[:-1])[1]
    xi_new = adapted_grid(prob.xi, yv, phi, pt.beta, params, vst, n_points)
    new, xn = _onto_normal(params, prob, x, t, xi_new, metric)
    if new is not None:
        return new, xn
    y_new = interpolate(prob.xi, yv, xi_new, vst)
    p2, x2, st = solve_on_grid(params, pt.q, xi_new, y_new, pt.beta)
    if not st.converged:
        return None, f"re-lay of the grid at q={pt.q:.6f} failed: {st.message}"
    prob = SteadyProblem(params, pt.q, xi_new, p2.pin_index, p2.y_pin, free="both", H=p2.H)
    return prob, np.concatenate([x2, [pt.q]])


def _onto_normal(params, prob, x, t, xi_new, metric, pin=None, max_iter=20, tol=1e-11):
    """The solution x of ``prob`` (free="both") re-solved on the grid ``xi_new`` on the hyperplane
    through it normal to its tangent ``t`` in ``metric``'s coordinates (ln v and t's ln v part
    interpolated; the pin at node ``pin``, else where :func:`front_pin` puts it): (the problem,
    its x), or (None, None) where the corrector does not converge."""
    q = float(x[-1])
    yn = interpolate(prob.xi, x[:-2], xi_new, params.v_stick(q * params.tau_min))
    if pin is None:
        pin, _ = front_pin(xi_new, yn, math.log(params.v_stick(q * params.tau_min)))
    new = SteadyProblem(params, q, xi_new, pin, float(yn[pin]), free="both",
                        state_order=prob.state_order)
    xn = np.concatenate([yn, x[-2:]])
    tn = np.concatenate([np.interp(xi_new, prob.xi, t[:-2]), t[-2:]])
    tz = tn * metric.weights(xn)
    ok, xs, _, _ = _correct(new, xn, tn, tz / np.linalg.norm(tz), 0.0, max_iter, tol, metric)
    return (new, xs) if ok else (None, None)


def _stop(pt, s: TraceSettings, q_hi):
    """Why the trace stops at the accepted point ``pt`` ('' : it goes on)."""
    if not (s.q_min < pt.q < q_hi):
        return f"tau_d/tau_min={pt.q:.6f} left ({s.q_min}, {q_hi:.5f})"
    if pt.L > s.L_max:
        return f"L={pt.L:.4g} m above L_max={s.L_max:g} m"
    return ""


def _relay_start(params, pulse, n_points, metric):
    """The start pulse re-solved on a grid adapted to it (``n_points``), as the trace re-lays
    its grids (:func:`_relay`): on the hyperplane normal to its branch in ``metric``'s
    coordinates (where the shape moves at nearly fixed τ_d a fixed-τ_d re-solve fails: 60
    iterations past the upper two-hump fold at N = 8000), else at its τ_d: (xi, ln v, Pulse)."""
    prob, x, _ = pulse_system(pulse, params)
    xi, y = prob.xi, x[:-2]
    xi_new = adapted_grid(xi, y, np.asarray(pulse.phi, float), pulse.beta, params,
                          pulse.v_stick, n_points)
    _, t = _tangent(prob.residual_and_jacobian(x)[1], x, metric)
    new, xn = _onto_normal(params, prob, x, t, xi_new, metric)
    if new is not None:
        return xi_new, xn[:-2], _pulse(new, xn, params)
    p2, x2, st = solve_on_grid(params, pulse.tau_d_ratio, xi_new,
                               interpolate(xi, y, xi_new, pulse.v_stick), pulse.beta)
    if not st.converged:
        raise RuntimeError(f"re-lay of the start pulse's grid failed: {st.message}")
    pulse = _pulse(SteadyProblem(params, pulse.tau_d_ratio, xi_new, p2.pin_index, p2.y_pin,
                                 free="both", H=p2.H),
                   np.concatenate([x2, [pulse.tau_d_ratio]]), params)
    return xi_new, x2[:-1], pulse


def trace(params, pulse, settings: TraceSettings | None = None, progress=None,
          on_pulse=None) -> Trace:
    """Trace the branch of ``pulse`` (a converged Pulse) as ``settings`` say (default
    :class:`TraceSettings`: toward decreasing τ_d). Stops at ``max_steps``, when the step falls
    below ``ds_min``, when τ_d leaves (q_min, τ_peak/τ_min − 1e-4) or L exceeds ``L_max`` (m),
    and, with ``stop_on_humps``, when the hump count changes. ``progress(point)`` is called at
    each accepted point, ``on_pulse(point, pulse)`` with its pulse as it comes (a caller that
    writes them keeps what a long trace found if it is interrupted). Returns a :class:`Trace`."""
    s = settings if settings is not None else TraceSettings()
    t0 = time.perf_counter()
    n_points = s.n_points or int(pulse.n_points)
    if s.relay_start:
        xi, y, pulse = _relay_start(params, pulse, n_points, s.metric)
        k, _ = front_pin(xi, y, math.log(pulse.v_stick))
        prob = SteadyProblem(params, pulse.tau_d_ratio, xi, k, float(y[k]), free="both")
        x = np.concatenate([y, [pulse.beta, pulse.tau_d_ratio]])
    else:
        # the pulse's own discrete system, its stored pin included: a stored trace point goes on
        # in the system it was solved in (a resumed trace), not one pinned at another node
        prob, x, _ = pulse_system(pulse, params)
        xi, y = prob.xi, x[:-2]
    r, J = prob.residual_and_jacobian(x)
    m = s.metric
    tz, t = _tangent(J, x, m)
    if tz[-1] * s.direction < 0:
        tz, t = -tz, -t
    log = _Record(params, progress, on_pulse)
    out = log.out
    L_grid = pulse_length(xi, np.exp(y), params.v_star, crossings=False)
    E_grid = extent(xi, np.exp(y), params.v_star)
    humps0 = count_humps(np.exp(y))
    q_hi = params.tau_peak / params.tau_min - 1e-4
    ds = s.ds
    log.add(prob, x, J, tz, m)
    while len(out.points) <= s.max_steps:
        ok, xc, Jc, it = _correct(prob, x, t, tz, ds, s.max_iter, s.tol, m)
        if not ok:
            ds *= 0.5
            if ds < s.ds_min:
                out.stop_reason = f"step below ds_min={s.ds_min:g} at q={x[-1]:.6f}"
                break
            continue
        x, J = xc, Jc
        tz, t = _tangent(J, x, m, orient=tz)
        pt = log.add(prob, x, J, tz, m)
        if it <= 3:
            ds = min(ds * 1.5, s.ds_max)
        out.stop_reason = _stop(pt, s, q_hi)
        if out.stop_reason:
            break
        if pt.humps != humps0:
            out.events.append(("humps", len(out.points) - 1,
                               f"hump count {humps0} -> {pt.humps} at q={pt.q:.6f} "
                               f"(beta={pt.beta:.6g}, L={pt.L:.4g} m)"))
            humps0 = pt.humps
            if s.stop_on_humps:
                out.stop_reason = out.events[-1][2]
                break
        if abs(pt.L / L_grid - 1.0) > s.regrid or abs(pt.extent / E_grid - 1.0) > s.regrid:
            # re-lay the grid on the current pulse, re-solve it there (_relay), keep going
            xi_old = prob.xi
            prob, x = _relay(params, prob, x, pt, n_points, t, m)
            if prob is None:
                out.stop_reason = x
                break
            J = prob.residual_and_jacobian(x)[1]
            # the last tangent carried onto the new nodes orients the new one
            orient = np.concatenate([np.interp(prob.xi, xi_old, tz[:-2]), tz[-2:]])
            tz, t = _tangent(J, x, m, orient=orient)
            L_grid = pulse_length(prob.xi, np.exp(x[:-2]), params.v_star, crossings=False)
            E_grid = extent(prob.xi, np.exp(x[:-2]), params.v_star)
            log.grid_id += 1
    if not out.stop_reason:
        out.stop_reason = f"max_steps={s.max_steps} reached"
        out.out_of_steps = True
    out.wall_time = time.perf_counter() - t0
    return out


def check_on_normal(params, pulse, metric: ArcMetric = ArcMetric(), max_iter=20, tol=1e-11):
    """A traced pulse re-solved at 2N − 1 (its grid with the midpoints, its pin's node kept) on
    the hyperplane through it normal to the branch's tangent in ``metric``'s coordinates: the
    fine grid's point of the branch nearest it. Why not at fixed τ_d: near a fold in τ_d, and
    where the branch moves its shape at nearly fixed τ_d, the fine grid's branch may not pass
    through the pulse's τ_d at all, and the fixed-τ_d re-solve fails (60 iterations at the
    trailing hump's unbinding). Returns {'passed' (converged), 'n_fine', 'dbeta', 'dq',
    'dL_rel', 'wall'} or {'passed': False, 'message', 'wall'}."""
    t0 = time.perf_counter()
    prob, x, _ = pulse_system(pulse, params)
    _, t = _tangent(prob.residual_and_jacobian(x)[1], x, metric)
    xi = prob.xi
    xin = nested_grid(xi)
    q = float(x[-1])
    _, xs = _onto_normal(params, prob, x, t, xin, metric,
                         pin=int(np.searchsorted(xin, xi[prob.pin_index])), max_iter=max_iter,
                         tol=tol)
    ok = xs is not None
    wall = time.perf_counter() - t0
    if not ok:
        return {"passed": False, "message": f"the re-solve on the normal hyperplane did not "
                                            f"converge in {max_iter} iterations", "wall": wall}
    L = pulse_length(xin, np.exp(xs[:-2]), params.v_star, crossings=False)
    return {"passed": True, "n_fine": int(xin.size), "dbeta": float(xs[-2] - pulse.beta),
            "dq": float(xs[-1] - q), "dL_rel": float((L - pulse.L) / pulse.L), "wall": wall}
